//! scene.toml (scene-format.md), read and validated into a [`SceneDesc`].
//!
//! Every problem is an [`Error`] naming the file and the line (and column) of the offending
//! value: unknown keys, missing keys, wrong types, out-of-range numbers, duplicate names, an
//! object in two places. Paths are resolved against the scene file's folder. Whether the
//! named objects exist in the OBJ files is checked afterwards by [`check_objects`].
//!
//! Choices beyond the spec (documented here, each tested):
//! - `hide`, `[[light]]` and `[[group]]` may be absent (empty); at least one `[[view]]` is
//!   required, as is a non-empty `geometry` list.
//! - A hidden object may also be in a group or be a light (hiding removes it from the scene
//!   without editing the groups); listing it twice in `hide` is an error.
//! - A view's `size` is at most [`MAX_VIEW_SIDE`] pixels per side (the core's limit);
//!   `direction` must not be zero and `up` must not be parallel to it.
//! - View and group names are identifiers (ASCII letters, digits, `_`, `-` and `.`, not
//!   starting with `.` or `-`): they name output files (`views/<view>.exr`,
//!   `textures/<group>.exr`) and RADIANCE primitives in materials.rad, so a name like
//!   `../x` or one with a space would write outside `--out` or break the .rad file.

use std::path::{Path, PathBuf};

use crate::error::Error;
use crate::fsutil;

mod load;
mod obj_check;
mod raw;
pub mod toml_src;
mod views;

use load::load;
pub use obj_check::check_objects;
pub use raw::{hide_error, view_error, ViewKey};
pub use toml_src::TomlFile;

/// Largest width or height of a view, in pixels: the core's.
pub const MAX_VIEW_SIDE: i64 = relume_core::config::MAX_VIEW_SIDE as i64;

/// The material type of a group, assigned in preprocessing (`kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroupKind {
    Plastic,
    Metal,
    /// Let recovery decide between plastic and metal.
    Auto,
}

impl GroupKind {
    /// The kind scene.toml gives (`None` for "auto").
    pub fn given(self) -> Option<relume_core::material::Kind> {
        match self {
            GroupKind::Plastic => Some(relume_core::material::Kind::Plastic),
            GroupKind::Metal => Some(relume_core::material::Kind::Metal),
            GroupKind::Auto => None,
        }
    }
}

/// One calibrated view of the panorama.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewDesc {
    pub name: String,
    /// The view's image, resolved against the scene file's folder (input of `recover`).
    pub image: Option<PathBuf>,
    /// Read in 64 bits, as the OBJ vertices are: a view far from the origin is moved with
    /// the scene before it is rounded to 32 (`assemble::far_scene_centre`).
    pub position: [f64; 3],
    pub direction: [f32; 3],
    pub up: [f32; 3],
    /// Full horizontal and vertical angles, in degrees.
    pub fov_deg: [f32; 2],
    /// Width, height in pixels.
    pub size: [u32; 2],
    /// File value * exposure = radiance (default 1).
    pub exposure: f32,
}

/// An OBJ object whose faces emit.
#[derive(Clone, Debug, PartialEq)]
pub struct LightDesc {
    pub object: String,
    pub radiance: [f32; 3],
}

/// Objects that share one material.
#[derive(Clone, Debug, PartialEq)]
pub struct GroupDesc {
    pub name: String,
    pub kind: GroupKind,
    pub objects: Vec<String>,
    /// The line of its `name` in scene.toml, for messages about the group.
    pub line: usize,
}

/// A validated scene.toml.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneDesc {
    /// The scene file itself.
    pub path: PathBuf,
    pub name: String,
    /// OBJ files, resolved against the scene file's folder.
    pub geometry: Vec<PathBuf>,
    pub hide: Vec<String>,
    pub views: Vec<ViewDesc>,
    pub lights: Vec<LightDesc>,
    pub groups: Vec<GroupDesc>,
}

/// Whether `c` may stand in a name that is also a file name and a RADIANCE identifier
/// (view and group names, materials.rad's primitives): ASCII letters, digits, `_`, `-`, `.`.
pub fn identifier_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.')
}

impl SceneDesc {
    /// Checks the names a `--view` flag gave (an empty list selects every view): each must
    /// be one of this scene's views, or the error lists them.
    pub fn check_view_names(&self, names: &[String]) -> Result<(), Error> {
        for name in names {
            if !self.views.iter().any(|v| &v.name == name) {
                let all: Vec<&str> = self.views.iter().map(|v| v.name.as_str()).collect();
                return Err(Error::Usage(format!(
                    "--view {name}: {} has no such view (its views: {})",
                    self.path.display(),
                    all.join(", ")
                )));
            }
        }
        Ok(())
    }

    /// Whether view `name` is among those a `--view` flag selected (all when it gave none).
    pub fn view_selected(names: &[String], name: &str) -> bool {
        names.is_empty() || names.iter().any(|n| n == name)
    }

    /// The files this scene reads (path, and what it is): the scene file, its geometry and
    /// its views' images. No output of a run may replace them (`OutputSet::keeping`).
    pub fn input_files(&self) -> Vec<(PathBuf, String)> {
        let mut files = vec![(self.path.clone(), "the scene file".to_string())];
        files.extend(
            self.geometry
                .iter()
                .map(|g| (g.clone(), "the scene's geometry".to_string())),
        );
        files.extend(
            self.views.iter().filter_map(|v| {
                Some((v.image.clone()?, format!("the image of view '{}'", v.name)))
            }),
        );
        files
    }

    /// View `v`'s image, for a command that reads it (`needed`: why it needs one, said
    /// when the view has none). An image that is missing or no file is bad input at its
    /// `image` line, as a missing OBJ is at its `geometry` line.
    pub fn view_image(&self, v: usize, needed: &str) -> Result<&Path, Error> {
        let view = &self.views[v];
        let Some(image) = &view.image else {
            return Err(view_error(
                &self.path,
                v,
                ViewKey::Image,
                format!("view '{}' has no image: {needed}", view.name),
            ));
        };
        match fsutil::not_a_file(image, "an image") {
            Some(why) => Err(view_error(
                &self.path,
                v,
                ViewKey::Image,
                format!("view '{}': image {why}", view.name),
            )),
            None => Ok(image),
        }
    }
}

/// Reads and validates a scene.toml.
pub fn load_scene(path: &Path) -> Result<SceneDesc, Error> {
    load(path, true)
}

/// [`load_scene`] of a scene that may have no `[[view]]`: a template whose views are to be
/// replaced (`panorama split --scene`), where a view written only to be dropped was asked for.
pub fn load_template(path: &Path) -> Result<SceneDesc, Error> {
    load(path, false)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::obj::{load_obj, ObjObject};

    pub(crate) const SCENE: &str = r#"format = 1
name = "t"
geometry = ["geo.obj"]
hide = []

[[view]]
name = "front"
image = "views/front.exr"
position = [0.0, -2.0, 0.5]
direction = [0.0, 1.0, 0.0]
up = [0.0, 0.0, 1.0]
fov_deg = [60.0, 60.0]
size = [8, 8]
exposure = 1.0

[[light]]
object = "lamp"
radiance = [5.0, 5.0, 5.0]

[[group]]
name = "floor"
kind = "plastic"
objects = ["quad"]
"#;

    pub(crate) const OBJ: &str = "o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n\
                                  o lamp\nv 0 0 2\nv 1 0 2\nv 1 1 2\nf 5 7 6\n";

    /// The shared reference scenes, or None (with a note) when they are not here.
    pub(crate) fn bench() -> Option<PathBuf> {
        let dir = std::env::var_os("RELUME_SHARED")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared"))
            .join("bench");
        if dir.is_dir() {
            Some(dir)
        } else {
            eprintln!(
                "note: {} not found, skipping the reference-scene checks",
                dir.display()
            );
            None
        }
    }

    /// Writes scene.toml (SCENE with `from` replaced by `to`) and geo.obj into a fresh temp dir.
    pub(super) fn write(from: &str, to: &str) -> (tempfile::TempDir, PathBuf) {
        assert!(
            from.is_empty() || SCENE.contains(from),
            "test setup: {from:?} not in SCENE"
        );
        let dir = tempfile::tempdir().unwrap();
        let text = if from.is_empty() {
            SCENE.to_string()
        } else {
            SCENE.replacen(from, to, 1)
        };
        let path = dir.path().join("scene.toml");
        std::fs::write(&path, text).unwrap();
        std::fs::write(dir.path().join("geo.obj"), OBJ).unwrap();
        (dir, path)
    }

    /// The error of loading SCENE with one replacement; checks that it names the file and
    /// `line` and contains every one of `what`.
    pub(super) fn bad(from: &str, to: &str, line: usize, what: &[&str]) -> String {
        let (_dir, path) = write(from, to);
        let e = load_scene(&path)
            .expect_err("the scene should be refused")
            .to_string();
        eprintln!("{e}");
        assert!(
            e.contains(&format!("scene.toml:{line}")),
            "expected scene.toml:{line} in: {e}"
        );
        for w in what {
            assert!(e.contains(w), "expected {w:?} in: {e}");
        }
        e
    }

    pub(super) fn objects_of(desc: &SceneDesc) -> Vec<ObjObject> {
        desc.geometry
            .iter()
            .flat_map(|g| load_obj(g).unwrap())
            .collect()
    }

    #[test]
    fn good_scene_loads_with_resolved_paths() {
        let (dir, path) = write("", "");
        let d = load_scene(&path).unwrap();
        assert_eq!(d.name, "t");
        assert_eq!(d.geometry, vec![dir.path().join("geo.obj")]);
        assert_eq!(d.views[0].image, Some(dir.path().join("views/front.exr")));
        assert_eq!(d.views[0].size, [8, 8]);
        assert_eq!(d.views[0].fov_deg, [60.0, 60.0]);
        assert_eq!(
            d.lights,
            vec![LightDesc {
                object: "lamp".into(),
                radiance: [5.0; 3]
            }]
        );
        assert_eq!(d.groups[0].kind, GroupKind::Plastic);
        check_objects(&d, &objects_of(&d)).unwrap();
    }

    #[test]
    fn optional_keys_take_their_defaults() {
        let (_dir, path) = write("exposure = 1.0\n", "");
        let d = load_scene(&path).unwrap();
        assert_eq!(d.views[0].exposure, 1.0);
        let (_dir, path) = write("image = \"views/front.exr\"\n", "");
        assert_eq!(load_scene(&path).unwrap().views[0].image, None);
        let (_dir, path) = write("hide = []\n", "");
        assert!(load_scene(&path).unwrap().hide.is_empty());
    }

    #[test]
    fn box_diffuse_scene_loads() {
        let Some(bench) = bench() else { return };
        let d = load_scene(&bench.join("box-diffuse/scene.toml")).unwrap();
        assert_eq!(d.name, "box-diffuse");
        assert_eq!(d.views.len(), 6);
        assert_eq!(d.groups.len(), 6);
        assert_eq!(d.lights.len(), 1);
        assert_eq!(d.lights[0].radiance, [60.0, 55.0, 48.0]);
        assert_eq!(d.views[4].up, [0.0, -1.0, 0.0]);
        assert!(d
            .views
            .iter()
            .all(|v| v.size == [256, 256] && v.exposure == 1.0));
        assert!(d
            .views
            .iter()
            .all(|v| v.image.as_ref().is_some_and(|p| p.is_file())));
        let objects = objects_of(&d);
        assert_eq!(objects.len(), 9);
        assert_eq!(objects.iter().map(|o| o.triangles.len()).sum::<usize>(), 38);
    }
}
