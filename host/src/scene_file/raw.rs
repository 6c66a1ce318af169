//! scene.toml as serde reads it, each value with its span (the `Raw*` schema, unknown keys
//! refused), and that schema read again to give the line of a name or key for an error
//! found after loading ([`SceneLines`], [`hide_error`], [`view_error`]).

use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use crate::error::Error;

use super::TomlFile;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawScene {
    #[allow(dead_code)] // checked first, by TomlFile::check_format
    format: toml::Value,
    pub(super) name: Spanned<String>,
    pub(super) geometry: Spanned<Vec<Spanned<String>>>,
    #[serde(default)]
    pub(super) hide: Vec<Spanned<String>>,
    #[serde(default, rename = "view")]
    pub(super) views: Vec<Spanned<RawView>>,
    #[serde(default, rename = "light")]
    pub(super) lights: Vec<Spanned<RawLight>>,
    #[serde(default, rename = "group")]
    pub(super) groups: Vec<Spanned<RawGroup>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawView {
    pub(super) name: Spanned<String>,
    pub(super) image: Option<Spanned<String>>,
    pub(super) position: Spanned<Vec<f64>>,
    pub(super) direction: Spanned<Vec<f64>>,
    pub(super) up: Spanned<Vec<f64>>,
    pub(super) fov_deg: Spanned<Vec<f64>>,
    pub(super) size: Spanned<Vec<i64>>,
    pub(super) exposure: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawLight {
    pub(super) object: Spanned<String>,
    pub(super) radiance: Spanned<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawGroup {
    pub(super) name: Spanned<String>,
    pub(super) kind: Spanned<String>,
    pub(super) objects: Spanned<Vec<Spanned<String>>>,
}

/// Lines of names in a scene file, found by parsing it again (for errors found after
/// loading). Empty when the file can no longer be read.
pub(super) struct SceneLines {
    file: Option<TomlFile>,
    raw: Option<RawScene>,
}

impl SceneLines {
    pub(super) fn read(path: &Path) -> SceneLines {
        let file = TomlFile::read(path).ok();
        let raw = file.as_ref().and_then(|f| f.parse::<RawScene>().ok());
        SceneLines { file, raw }
    }
    fn line<T>(&self, s: Option<&Spanned<T>>) -> Option<usize> {
        Some(self.file.as_ref()?.line_of(s?.span().start))
    }
    pub(super) fn group_object(&self, g: usize, o: usize) -> Option<usize> {
        let raw = self.raw.as_ref()?;
        self.line(raw.groups.get(g)?.get_ref().objects.get_ref().get(o))
    }
    pub(super) fn light(&self, l: usize) -> Option<usize> {
        self.line(
            self.raw
                .as_ref()?
                .lights
                .get(l)
                .map(|l| &l.get_ref().object),
        )
    }
    pub(super) fn hide(&self, h: usize) -> Option<usize> {
        self.line(self.raw.as_ref()?.hide.get(h))
    }
    /// View `v`'s `size` or `image` line, else its `name` line (an `image` it lacks).
    fn view(&self, v: usize, key: ViewKey) -> Option<usize> {
        let view = self.raw.as_ref()?.views.get(v)?.get_ref();
        match key {
            ViewKey::Size => self.line(Some(&view.size)),
            ViewKey::Image => self.line(view.image.as_ref()),
        }
        .or_else(|| self.line(Some(&view.name)))
    }
}

/// An input error about the scene file `scene`'s `hide`, at the line of its first object:
/// for a command that needs the geometry whole (bench rays).
pub fn hide_error(scene: &Path, msg: String) -> Error {
    match SceneLines::read(scene).hide(0) {
        Some(line) => Error::at_line(scene, line, msg),
        None => Error::input(scene, msg),
    }
}

/// Which line of a view an error found after loading points at.
#[derive(Clone, Copy)]
pub enum ViewKey {
    Size,
    /// Its `image`, or its `name` when it has none.
    Image,
}

/// An input error about view `v` (its index in the file) of the scene file `scene`, at
/// the line of its `key`: for the commands that check views after loading (recover, bench
/// downsample and edits).
pub fn view_error(scene: &Path, v: usize, key: ViewKey, msg: String) -> Error {
    match SceneLines::read(scene).view(v, key) {
        Some(line) => Error::at_line(scene, line, msg),
        None => Error::input(scene, msg),
    }
}
