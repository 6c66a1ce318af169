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

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::error::Error;
use crate::fsutil;
use crate::obj::ObjObject;

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

impl ViewDesc {
    /// The core's view (its frame checked and precomputed).
    pub fn view(&self) -> Result<relume_core::geometry::View, relume_core::Error> {
        use glam::Vec3;
        relume_core::geometry::View::new(
            Vec3::from(self.position.map(|x| x as f32)),
            Vec3::from(self.direction),
            Vec3::from(self.up),
            self.fov_deg,
            self.size,
        )
    }
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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    #[allow(dead_code)] // checked first, by TomlFile::check_format
    format: toml::Value,
    name: Spanned<String>,
    geometry: Spanned<Vec<Spanned<String>>>,
    #[serde(default)]
    hide: Vec<Spanned<String>>,
    #[serde(default, rename = "view")]
    views: Vec<Spanned<RawView>>,
    #[serde(default, rename = "light")]
    lights: Vec<Spanned<RawLight>>,
    #[serde(default, rename = "group")]
    groups: Vec<Spanned<RawGroup>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawView {
    name: Spanned<String>,
    image: Option<Spanned<String>>,
    position: Spanned<Vec<f64>>,
    direction: Spanned<Vec<f64>>,
    up: Spanned<Vec<f64>>,
    fov_deg: Spanned<Vec<f64>>,
    size: Spanned<Vec<i64>>,
    exposure: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLight {
    object: Spanned<String>,
    radiance: Spanned<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGroup {
    name: Spanned<String>,
    kind: Spanned<String>,
    objects: Spanned<Vec<Spanned<String>>>,
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

fn load(path: &Path, needs_views: bool) -> Result<SceneDesc, Error> {
    let file = TomlFile::read(path)?;
    file.check_format()?;
    let raw: RawScene = file.parse()?;

    let name = file.name(&raw.name, "name")?;
    if raw.geometry.get_ref().is_empty() {
        return Err(file.at(raw.geometry.span(), "`geometry` lists no OBJ file"));
    }
    let mut geometry: Vec<PathBuf> = Vec::new();
    // The files as the file system knows them, so that `a.obj` and `./a.obj` are one file
    // from whichever folder relume runs.
    let mut canonical: Vec<PathBuf> = Vec::new();
    for g in raw.geometry.get_ref() {
        let p = file.resolve(&file.name(g, "geometry file")?);
        if let Some(why) = fsutil::not_a_file(&p, "an OBJ file") {
            return Err(file.at(g.span(), format!("geometry file {why}")));
        }
        let c = std::fs::canonicalize(&p).unwrap_or_else(|_| p.clone());
        if canonical.contains(&c) {
            return Err(file.at(
                g.span(),
                format!("geometry file '{}' is listed twice", g.get_ref()),
            ));
        }
        canonical.push(c);
        geometry.push(p);
    }

    let mut hide = Vec::new();
    for h in &raw.hide {
        let n = file.name(h, "hidden object")?;
        if hide.contains(&n) {
            return Err(file.at(h.span(), format!("object '{n}' is listed twice in `hide`")));
        }
        hide.push(n);
    }

    if needs_views && raw.views.is_empty() {
        return Err(Error::input(
            path,
            "no [[view]]: a scene needs at least one view",
        ));
    }
    let mut views: Vec<ViewDesc> = Vec::new();
    let mut view_lines: HashMap<String, usize> = HashMap::new();
    for v in &raw.views {
        let view = check_view(&file, v.get_ref())?;
        if let Some(first) = view_lines.get(&view.name) {
            return Err(file.at(
                v.get_ref().name.span(),
                format!(
                    "duplicate view name '{}' (first at line {first})",
                    view.name
                ),
            ));
        }
        view_lines.insert(
            view.name.clone(),
            file.line_of(v.get_ref().name.span().start),
        );
        views.push(view);
    }

    // Where each object is used: "group 'g'" or "a light", with its line.
    let mut used: HashMap<String, (String, usize)> = HashMap::new();
    let mut lights = Vec::new();
    for l in &raw.lights {
        let l = l.get_ref();
        let object = file.name(&l.object, "light object")?;
        let line = file.line_of(l.object.span().start);
        if let Some((_, first)) = used.get(&object) {
            return Err(file.at(
                l.object.span(),
                format!("light object '{object}' is listed twice (first at line {first})"),
            ));
        }
        let radiance: [f32; 3] = file.vector(&l.radiance, "radiance")?;
        if radiance.iter().any(|&c| c < 0.0) {
            return Err(file.at(
                l.radiance.span(),
                format!("light '{object}': radiance must be >= 0, got {radiance:?}"),
            ));
        }
        if radiance.iter().any(|&c| c > crate::images::MAX_RADIANCE) {
            return Err(file.at(
                l.radiance.span(),
                format!(
                    "light '{object}': radiance must be at most {:e}, the largest relume computes with, got {radiance:?}",
                    crate::images::MAX_RADIANCE
                ),
            ));
        }
        used.insert(object.clone(), ("a light".to_string(), line));
        lights.push(LightDesc { object, radiance });
    }

    let mut groups: Vec<GroupDesc> = Vec::new();
    let mut group_lines: HashMap<String, usize> = HashMap::new();
    for g in &raw.groups {
        let g = g.get_ref();
        let name = file.group_identifier(&g.name, "group name")?;
        if let Some(first) = group_lines.get(&name) {
            return Err(file.at(
                g.name.span(),
                format!("duplicate group name '{name}' (first at line {first})"),
            ));
        }
        group_lines.insert(name.clone(), file.line_of(g.name.span().start));
        let kind = match g.kind.get_ref().as_str() {
            "plastic" => GroupKind::Plastic,
            "metal" => GroupKind::Metal,
            "auto" => GroupKind::Auto,
            other => {
                return Err(file.at(
                    g.kind.span(),
                    format!(
                        "group '{name}': unknown kind '{other}' (expected plastic, metal or auto)"
                    ),
                ))
            }
        };
        if g.objects.get_ref().is_empty() {
            return Err(file.at(g.objects.span(), format!("group '{name}' lists no objects")));
        }
        let mut objects = Vec::new();
        for o in g.objects.get_ref() {
            let object = file.name(o, "object")?;
            let line = file.line_of(o.span().start);
            if let Some((where_, first)) = used.get(&object) {
                let msg = if where_ == &format!("group '{name}'") {
                    format!("object '{object}' is listed twice in group '{name}'")
                } else {
                    format!(
                        "object '{object}' is in group '{name}' and also {where_} (line {first}): \
                         an object belongs to exactly one group or light"
                    )
                };
                return Err(file.at(o.span(), msg));
            }
            used.insert(object.clone(), (format!("group '{name}'"), line));
            objects.push(object);
        }
        groups.push(GroupDesc {
            line: group_lines[&name],
            name,
            kind,
            objects,
        });
    }

    Ok(SceneDesc {
        path: path.to_path_buf(),
        name,
        geometry,
        hide,
        views,
        lights,
        groups,
    })
}

fn check_view(file: &TomlFile, v: &RawView) -> Result<ViewDesc, Error> {
    let name = file.identifier(&v.name, "view name")?;
    let image = match &v.image {
        Some(i) => Some(file.resolve(&file.name(i, "image")?)),
        None => None,
    };
    let position: [f64; 3] = file.vector64(&v.position, "position")?;
    let direction: [f32; 3] = file.direction(&v.direction, "direction")?;
    let up: [f32; 3] = file.direction(&v.up, "up")?;
    let fov_deg: [f32; 2] = file.vector(&v.fov_deg, "fov_deg")?;
    let d = direction.map(f64::from);
    let u = up.map(f64::from);
    let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    if dd == 0.0 {
        return Err(file.at(
            v.direction.span(),
            format!("view '{name}': direction is zero"),
        ));
    }
    let c = [
        d[1] * u[2] - d[2] * u[1],
        d[2] * u[0] - d[0] * u[2],
        d[0] * u[1] - d[1] * u[0],
    ];
    if c[0] * c[0] + c[1] * c[1] + c[2] * c[2] <= 1e-12 * dd * uu {
        return Err(file.at(
            v.up.span(),
            format!("view '{name}': up {up:?} is zero or parallel to direction {direction:?}"),
        ));
    }
    if fov_deg.iter().any(|&f| !(f > 0.0 && f < 180.0)) {
        return Err(file.at(
            v.fov_deg.span(),
            format!("view '{name}': fov_deg must be in (0, 180) degrees, got {fov_deg:?}"),
        ));
    }
    let s = v.size.get_ref();
    if s.len() != 2 {
        return Err(file.at(
            v.size.span(),
            format!(
                "view '{name}': size must have 2 integers (width, height), found {}",
                s.len()
            ),
        ));
    }
    if s.iter().any(|&x| !(1..=MAX_VIEW_SIDE).contains(&x)) {
        return Err(file.at(
            v.size.span(),
            format!("view '{name}': size must be between 1 and {MAX_VIEW_SIDE} pixels, got {s:?}"),
        ));
    }
    let size = [s[0] as u32, s[1] as u32];
    let exposure = match &v.exposure {
        Some(e) => {
            let x = file.number(e, "exposure")?;
            if x <= 0.0 {
                return Err(file.at(
                    e.span(),
                    format!("view '{name}': exposure must be > 0, got {x}"),
                ));
            }
            x
        }
        None => 1.0,
    };
    Ok(ViewDesc {
        name,
        image,
        position,
        direction,
        up,
        fov_deg,
        size,
        exposure,
    })
}

/// Checks the scene's object names against the objects of its OBJ files: no object is defined
/// twice; every object named in a group, a light or `hide` exists; every OBJ object is in a
/// group, is a light, or is hidden.
pub fn check_objects(desc: &SceneDesc, objects: &[ObjObject]) -> Result<(), Error> {
    let mut defined: HashMap<&str, &Path> = HashMap::new();
    for o in objects {
        if let Some(first) = defined.get(o.name.as_str()) {
            // Each definition at its `o` (or `g`) line, so that either can be found.
            let at = |file: &Path| match crate::obj::object_line(file, &o.name) {
                Some(line) => format!("{}:{line}", file.display()),
                None => file.display().to_string(),
            };
            let msg = format!(
                "object '{}' is defined twice: in {} and in {}",
                o.name,
                at(first),
                at(&o.file)
            );
            return Err(match crate::obj::object_line(&o.file, &o.name) {
                Some(line) => Error::at_line(&o.file, line, msg),
                None => Error::input(&o.file, msg),
            });
        }
        defined.insert(&o.name, &o.file);
    }
    let files = desc
        .geometry
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ");
    let lines = SceneLines::read(&desc.path);
    let missing = |object: &str, role: String, line: Option<usize>| {
        // An `o` line with no faces after it is named in the file but is no object of the
        // geometry: say where it is, since "not in the geometry" would look wrong there.
        let empty_at = desc.geometry.iter().find_map(|file| {
            crate::obj::object_line(file, object).map(|l| format!("{}:{l}", file.display()))
        });
        // `g floor extra` names one object, "floor extra": tell it where a word of a
        // name is the object asked for.
        let spaced = defined
            .keys()
            .filter(|name| name.contains(' ') && name.split_whitespace().any(|w| w == object))
            .min()
            .map(|name| format!("; the geometry has object '{name}': OBJ reads all that follows `o` or `g` as one name"))
            .unwrap_or_default();
        // `g floor` in a file of `o` statements is a group within an object, no object.
        let under_o = desc.geometry.iter().find_map(|file| {
            crate::obj::group_line_under_o(file, object).map(|l| {
                format!("; {}:{l} has `g {object}`, but that file names its objects by `o`, and a `g` there is a group within an object, not an object: list the `o` names", file.display())
            })
        });
        let msg = match empty_at {
            Some(at) => format!("object '{object}' ({role}) has no faces in the geometry ({at})"),
            None => format!(
                "object '{object}' ({role}) is not in the geometry ({files}){spaced}{}",
                under_o.unwrap_or_default()
            ),
        };
        match line {
            Some(l) => Error::at_line(&desc.path, l, msg),
            None => Error::input(&desc.path, msg),
        }
    };
    for (gi, g) in desc.groups.iter().enumerate() {
        for (oi, o) in g.objects.iter().enumerate() {
            if !defined.contains_key(o.as_str()) {
                return Err(missing(
                    o,
                    format!("in group '{}'", g.name),
                    lines.group_object(gi, oi),
                ));
            }
        }
    }
    for (li, l) in desc.lights.iter().enumerate() {
        if !defined.contains_key(l.object.as_str()) {
            return Err(missing(&l.object, "a light".into(), lines.light(li)));
        }
    }
    for (hi, h) in desc.hide.iter().enumerate() {
        if !defined.contains_key(h.as_str()) {
            // `hide` lists objects: a group's name there hides nothing, say which to list.
            if let Some(g) = desc.groups.iter().find(|g| &g.name == h) {
                let objects: Vec<String> = g.objects.iter().map(|o| format!("'{o}'")).collect();
                let msg = format!(
                    "'{h}' in `hide` is a group, not an object: `hide` lists OBJ objects (to hide group '{h}', list its objects {})",
                    objects.join(", ")
                );
                return Err(match lines.hide(hi) {
                    Some(l) => Error::at_line(&desc.path, l, msg),
                    None => Error::input(&desc.path, msg),
                });
            }
            return Err(missing(h, "in `hide`".into(), lines.hide(hi)));
        }
    }
    for o in objects {
        let assigned = desc.hide.contains(&o.name)
            || desc.lights.iter().any(|l| l.object == o.name)
            || desc.groups.iter().any(|g| g.objects.contains(&o.name));
        if !assigned {
            let msg = format!(
                "object '{}' is in no group, is no light and is not hidden in {}",
                o.name,
                desc.path.display()
            );
            return Err(match crate::obj::object_line(&o.file, &o.name) {
                Some(l) => Error::at_line(&o.file, l, msg),
                None => Error::input(&o.file, msg),
            });
        }
    }
    Ok(())
}

/// Lines of names in a scene file, found by parsing it again (for errors found after
/// loading). Empty when the file can no longer be read.
struct SceneLines {
    file: Option<TomlFile>,
    raw: Option<RawScene>,
}

impl SceneLines {
    fn read(path: &Path) -> SceneLines {
        let file = TomlFile::read(path).ok();
        let raw = file.as_ref().and_then(|f| f.parse::<RawScene>().ok());
        SceneLines { file, raw }
    }
    fn line<T>(&self, s: Option<&Spanned<T>>) -> Option<usize> {
        Some(self.file.as_ref()?.line_of(s?.span().start))
    }
    fn group_object(&self, g: usize, o: usize) -> Option<usize> {
        let raw = self.raw.as_ref()?;
        self.line(raw.groups.get(g)?.get_ref().objects.get_ref().get(o))
    }
    fn light(&self, l: usize) -> Option<usize> {
        self.line(
            self.raw
                .as_ref()?
                .lights
                .get(l)
                .map(|l| &l.get_ref().object),
        )
    }
    fn hide(&self, h: usize) -> Option<usize> {
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

/// Reading TOML with positions, shared by scene.toml and materials.toml: byte spans to
/// 1-based lines and columns, numbers checked finite and within f32, fixed-length vectors.
pub mod toml_src {
    use std::ops::Range;
    use std::path::{Path, PathBuf};

    use serde::de::DeserializeOwned;
    use serde::Deserialize;
    use toml::Spanned;

    use crate::error::{Error, Location};

    /// The text of one TOML file and its path.
    pub struct TomlFile {
        pub path: PathBuf,
        pub text: String,
    }

    #[derive(Deserialize)]
    struct FormatOnly {
        format: Option<Spanned<toml::Value>>,
    }

    /// The longest name of a group or a view: it names output files (`<view>.exr`,
    /// `textures/<group>.exr`, and their temp files `.<name>.tmp-<pid>`), and a file name
    /// may be 255 bytes long.
    pub const MAX_NAME_LEN: usize = 200;

    /// The name of a table header line, `[name]` (not a list's `[[name]]`).
    fn table_header(line: &str) -> Option<&str> {
        let inner = line.strip_prefix('[').filter(|t| !t.starts_with('['))?;
        Some(inner.split(']').next()?.trim())
    }

    /// The name of a list entry's header line, `[[name]]`.
    fn list_header(line: &str) -> Option<&str> {
        Some(line.strip_prefix("[[")?.split("]]").next()?.trim())
    }

    impl TomlFile {
        /// Reads the file (an I/O error names it).
        pub fn read(path: &Path) -> Result<TomlFile, Error> {
            let text = crate::fsutil::read_text(path)?;
            Ok(TomlFile {
                path: path.to_path_buf(),
                text,
            })
        }

        /// 1-based line and column (in characters) of a byte offset.
        pub fn line_col(&self, offset: usize) -> (usize, usize) {
            let offset = offset.min(self.text.len());
            let before = self.text.get(..offset).unwrap_or(&self.text);
            let line = before.matches('\n').count() + 1;
            let start = before.rfind('\n').map_or(0, |i| i + 1);
            (line, before[start..].chars().count() + 1)
        }

        pub fn line_of(&self, offset: usize) -> usize {
            self.line_col(offset).0
        }

        /// An input error at the start of `span`.
        pub fn at(&self, span: Range<usize>, message: impl Into<String>) -> Error {
            let (line, column) = self.line_col(span.start);
            Error::Input {
                file: self.path.clone(),
                location: Some(Location::Line {
                    line,
                    column: Some(column),
                }),
                message: message.into(),
            }
        }

        /// Parses the whole file (syntax, types, missing and unknown keys).
        pub fn parse<T: DeserializeOwned>(&self) -> Result<T, Error> {
            toml::from_str(&self.text).map_err(|e| self.de_error(&e))
        }

        fn de_error(&self, e: &toml::de::Error) -> Error {
            let message = e
                .message()
                .replace("missing field", "missing key")
                .replace("unknown field", "unknown key")
                .replace("expected one of", "expected one of the keys")
                .replace("expected f64", "expected a number")
                .replace("expected i64", "expected an integer");
            // An integer past TOML's 64 bits: "invalid type: integer `<20 digits>` as i128,
            // expected an integer" said the type was wrong.
            let message = match message.strip_suffix("` as i128, expected an integer") {
                Some(head) => format!(
                    "{}` is out of range: TOML's integers are 64-bit",
                    head.replacen("invalid type: integer `", "integer `", 1)
                ),
                None => message,
            };
            match e.span() {
                Some(span) => self.with_hint(message, span),
                None => Error::input(&self.path, message),
            }
        }

        /// The toml crate's error at `span`, with what it means where a table header
        /// `[view]` was written for a list's `[[view]]`: a "duplicate key" at the second
        /// `[view]` or at a `[[view]]` after it (then said at the `[view]`), an "invalid
        /// type: map" at a lone one. A bare "duplicate key" is a key given twice.
        fn with_hint(&self, message: String, span: Range<usize>) -> Error {
            let line = self.line_of(span.start);
            let text = |line: usize| self.text.lines().nth(line - 1).unwrap_or("").trim();
            let list_entry = |name: &str| format!("each entry of a list is written [[{name}]]");
            let duplicate = message.contains("duplicate key");
            if let Some(name) = table_header(text(line)) {
                let hint = if duplicate {
                    format!(": a table [{name}] may appear once; {}", list_entry(name))
                } else if message.contains("invalid type: map, expected a sequence") {
                    format!(
                        ": [{name}] is a table, where a list is expected; {}",
                        list_entry(name)
                    )
                } else {
                    String::new()
                };
                return self.at(span, message + &hint);
            }
            if let Some(name) = list_header(text(line)).filter(|_| duplicate) {
                let earlier = self.text.lines().take(line - 1);
                if let Some(table) = earlier
                    .map(str::trim)
                    .position(|t| table_header(t) == Some(name))
                    .map(|i| i + 1)
                {
                    return Error::at_line(
                        &self.path,
                        table,
                        format!(
                            "[{name}] is a table, but [[{name}]] at line {line} makes a list; {}",
                            list_entry(name)
                        ),
                    );
                }
            }
            let hint = match text(line).split('=').next().map(str::trim) {
                Some(key) if duplicate && !key.is_empty() => format!(": `{key}` is given twice"),
                _ => String::new(),
            };
            self.at(span, message + &hint)
        }

        /// `format` must be present and be the integer 1; checked before anything else so a
        /// newer file gets that error rather than one about its new keys.
        pub fn check_format(&self) -> Result<(), Error> {
            let f: FormatOnly = self.parse()?;
            match f.format {
                // A `format` line after a table header belongs to that table, in TOML:
                // the file had one, and the error named no line.
                None => match self.text.lines().position(|l| {
                    l.split('=').next().map(str::trim) == Some("format") && l.contains('=')
                }) {
                    Some(at) => Err(Error::at_line(
                        &self.path,
                        at + 1,
                        "`format` is given here, after a table header, so TOML reads it as a key of that table: put it at the top of the file, before the first [table] or [[list]] (this tool reads format = 1)",
                    )),
                    None => Err(Error::input(
                        &self.path,
                        "missing key `format` (this tool reads format = 1)",
                    )),
                },
                Some(v) => match v.get_ref() {
                    toml::Value::Integer(1) => Ok(()),
                    other => Err(self.at(
                        v.span(),
                        format!("format {other} is not supported: this tool reads format = 1"),
                    )),
                },
            }
        }

        /// A non-empty string.
        pub fn name(&self, s: &Spanned<String>, what: &str) -> Result<String, Error> {
            if s.get_ref().trim().is_empty() {
                return Err(self.at(s.span(), format!("{what} is empty")));
            }
            Ok(s.get_ref().clone())
        }

        /// A name that is also a file name and a RADIANCE identifier: ASCII letters,
        /// digits, `_`, `-` and `.`, not starting with `.` or `-`, and at most
        /// [`MAX_NAME_LEN`] long.
        pub fn identifier(&self, s: &Spanned<String>, what: &str) -> Result<String, Error> {
            let name = self.name(s, what)?;
            if name.len() > MAX_NAME_LEN {
                return Err(self.at(
                    s.span(),
                    format!(
                        "{what} is {} bytes long, more than MAX_NAME_LEN {MAX_NAME_LEN}: it names output files ('{}...')",
                        name.len(),
                        name.chars().take(40).collect::<String>().escape_debug()
                    ),
                ));
            }
            if !name.chars().all(super::identifier_char) || name.starts_with(['.', '-']) {
                return Err(self.at(
                    s.span(),
                    format!(
                        "{what} {name:?} may hold only ASCII letters, digits, '_', '-' and '.', and must not start with '.' or '-': it names output files and RADIANCE primitives"
                    ),
                ));
            }
            Ok(name)
        }

        /// [`TomlFile::identifier`] for a group, whose name is also its material's RADIANCE
        /// modifier in materials.rad: `void` there means no material at all, and a group so
        /// named rendered with none.
        pub fn group_identifier(&self, s: &Spanned<String>, what: &str) -> Result<String, Error> {
            let name = self.identifier(s, what)?;
            if name == "void" {
                return Err(self.at(
                    s.span(),
                    format!("{what} \"void\" is RADIANCE's word for no material: the group's material in materials.rad would be none"),
                ));
            }
            Ok(name)
        }

        /// A path relative to this file's folder (absolute paths stay as they are).
        pub fn resolve(&self, rel: &str) -> PathBuf {
            match self.path.parent() {
                Some(dir) => dir.join(rel),
                None => PathBuf::from(rel),
            }
        }

        /// A finite number that fits an f32.
        pub fn number(&self, v: &Spanned<f64>, what: &str) -> Result<f32, Error> {
            to_f32(*v.get_ref()).map_err(|m| self.at(v.span(), format!("`{what}` {m}")))
        }

        /// Exactly `N` finite numbers that fit an f32.
        pub fn vector<const N: usize>(
            &self,
            v: &Spanned<Vec<f64>>,
            what: &str,
        ) -> Result<[f32; N], Error> {
            self.numbers(v, what, to_f32)
        }

        /// Three finite numbers that give a direction, whose length does not matter: one
        /// whose squares would leave f32's range (`[1e-300, 0, 0]` read as zero, `[1e300,
        /// 0, 0]` as out of range) is first scaled by a power of two, exactly, to a largest
        /// component in [1, 2). Ordinary directions are kept as written.
        pub fn direction(&self, v: &Spanned<Vec<f64>>, what: &str) -> Result<[f32; 3], Error> {
            let d: [f64; 3] = self.numbers(v, what, |x| match x.is_finite() {
                true => Ok(x),
                false => Err(format!("must be a finite number, got {x}")),
            })?;
            let largest = d.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            if largest == 0.0 || (1e-18..=1e18).contains(&largest) {
                return Ok(d.map(|x| x as f32));
            }
            // 2^600 lifts an f64 subnormal to a normal number, whose exponent field is
            // then floor(log2); the scale 2^-exponent is built from its bits.
            let lift = if largest < f64::MIN_POSITIVE {
                f64::from_bits((1023 + 600) << 52)
            } else {
                1.0
            };
            let exponent = (((largest * lift).to_bits() >> 52) & 0x7ff) as i64 - 1023;
            let scale = f64::from_bits(((1023 - exponent) as u64) << 52);
            Ok(d.map(|x| (x * lift * scale) as f32))
        }

        /// Exactly `N` finite numbers that fit an f32, kept in 64 bits.
        pub fn vector64<const N: usize>(
            &self,
            v: &Spanned<Vec<f64>>,
            what: &str,
        ) -> Result<[f64; N], Error> {
            self.numbers(v, what, |x| to_f32(x).map(|_| x))
        }

        fn numbers<T: Copy + Default, const N: usize>(
            &self,
            v: &Spanned<Vec<f64>>,
            what: &str,
            convert: fn(f64) -> Result<T, String>,
        ) -> Result<[T; N], Error> {
            let xs = v.get_ref();
            if xs.len() != N {
                return Err(self.at(
                    v.span(),
                    format!("`{what}` must have {N} numbers, found {}", xs.len()),
                ));
            }
            let mut out = [T::default(); N];
            for (o, &x) in out.iter_mut().zip(xs) {
                *o = convert(x).map_err(|m| self.at(v.span(), format!("`{what}` {m}")))?;
            }
            Ok(out)
        }
    }

    fn to_f32(x: f64) -> Result<f32, String> {
        if !x.is_finite() {
            return Err(format!("must be a finite number, got {x}"));
        }
        let y = x as f32;
        if !y.is_finite() {
            return Err(format!("is out of range for a 32-bit float: {x:e}"));
        }
        if y == 0.0 && x != 0.0 {
            return Err(format!(
                "is too small for a 32-bit float, which reads {x:e} as 0 (write 0 if 0 is meant)"
            ));
        }
        Ok(y)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::obj::load_obj;

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
    fn write(from: &str, to: &str) -> (tempfile::TempDir, PathBuf) {
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
    fn bad(from: &str, to: &str, line: usize, what: &[&str]) -> String {
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

    fn objects_of(desc: &SceneDesc) -> Vec<ObjObject> {
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
    fn kinds_metal_and_auto() {
        let (_dir, path) = write("kind = \"plastic\"", "kind = \"metal\"");
        assert_eq!(load_scene(&path).unwrap().groups[0].kind, GroupKind::Metal);
        let (_dir, path) = write("kind = \"plastic\"", "kind = \"auto\"");
        assert_eq!(load_scene(&path).unwrap().groups[0].kind, GroupKind::Auto);
    }

    #[test]
    fn format_must_be_1() {
        bad(
            "format = 1",
            "format = 2",
            1,
            &["format 2 is not supported", "format = 1"],
        );
        bad("format = 1", "format = \"1\"", 1, &["is not supported"]);
        bad("format = 1", "format = 1.0", 1, &["is not supported"]);
        // A newer format is reported as such, not as its unknown keys.
        let (_dir, path) = write("format = 1", "format = 2\nshiny = true");
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(e.contains("format 2"), "{e}");
    }

    #[test]
    fn missing_format_is_an_error() {
        let (_dir, path) = write("format = 1\n", "");
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(
            e.contains("scene.toml") && e.contains("missing key `format`"),
            "{e}"
        );
    }

    /// `format = 1` after a table header is a key of that table in TOML: the file had
    /// one, and was told it had none, at no line.
    #[test]
    fn a_format_line_after_a_table_is_named_at_its_line() {
        let (_dir, path) = write("", "");
        let text = std::fs::read_to_string(&path).unwrap();
        let moved = format!("{}\nformat = 1\n", text.replacen("format = 1\n", "", 1));
        std::fs::write(&path, &moved).unwrap();
        let line = moved.lines().count();
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "scene.toml:{line}: `format` is given here, after a table header"
            )),
            "{e}"
        );
    }

    #[test]
    fn syntax_errors_give_the_line() {
        bad("name = \"front\"", "name = \"front", 7, &["scene.toml:7:"]);
    }

    #[test]
    fn a_duplicate_key_says_which_and_a_table_written_twice_says_how_to_write_a_list() {
        bad(
            "format = 1",
            "format = 1\nformat = 1",
            2,
            &["duplicate key", "`format` is given twice"],
        );
        // Two views written [view] instead of [[view]].
        bad(
            "[[view]]",
            "[view]\nname = \"x\"\n\n[view]",
            9,
            &[
                "duplicate key",
                "a table [view] may appear once; each entry of a list is written [[view]]",
            ],
        );
        // A lone [view], and a [light] before a [[light]]: the toml crate's errors were
        // "invalid type: map, expected a sequence", and "duplicate key" at the [[light]].
        bad(
            "[[view]]",
            "[view]",
            6,
            &["[view] is a table, where a list is expected; each entry of a list is written [[view]]"],
        );
        bad(
            "[[light]]",
            "[light]\nobject = \"lamp\"\nradiance = [5.0, 5.0, 5.0]\n\n[[light]]",
            16,
            &["[light] is a table, but [[light]] at line 20 makes a list; each entry of a list is written [[light]]"],
        );
    }

    #[test]
    fn unknown_keys_are_errors() {
        bad(
            "hide = []",
            "hide = []\nnmae = \"x\"",
            5,
            &["unknown key `nmae`"],
        );
        bad(
            "exposure = 1.0",
            "exposure = 1.0\nexposre = 2.0",
            15,
            &["unknown key `exposre`"],
        );
        bad(
            "radiance = [5.0, 5.0, 5.0]",
            "radiance = [5.0, 5.0, 5.0]\ncolor = 1",
            19,
            &["unknown key `color`"],
        );
        bad(
            "objects = [\"quad\"]",
            "objects = [\"quad\"]\nobject = \"x\"",
            24,
            &["unknown key `object`"],
        );
    }

    #[test]
    fn missing_keys_are_errors() {
        bad("size = [8, 8]\n", "", 6, &["missing key `size`"]);
        bad(
            "position = [0.0, -2.0, 0.5]\n",
            "",
            6,
            &["missing key `position`"],
        );
        bad(
            "radiance = [5.0, 5.0, 5.0]\n",
            "",
            16,
            &["missing key `radiance`"],
        );
        bad("kind = \"plastic\"\n", "", 20, &["missing key `kind`"]);
        let (_dir, path) = write("name = \"t\"\n", "");
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(
            e.contains("scene.toml") && e.contains("missing key `name`"),
            "{e}"
        );
        let (_dir, path) = write("geometry = [\"geo.obj\"]\n", "");
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(e.contains("missing key `geometry`"), "{e}");
    }

    #[test]
    fn wrong_types_are_errors() {
        bad(
            "size = [8, 8]",
            "size = [8.5, 8]",
            13,
            &["expected an integer"],
        );
        bad(
            "exposure = 1.0",
            "exposure = \"bright\"",
            14,
            &["invalid type", "expected a number"],
        );
        bad(
            "objects = [\"quad\"]",
            "objects = \"quad\"",
            23,
            &["invalid type"],
        );
    }

    #[test]
    fn numbers_must_be_finite() {
        bad(
            "position = [0.0, -2.0, 0.5]",
            "position = [0.0, nan, 0.5]",
            9,
            &["`position`", "finite"],
        );
        bad(
            "direction = [0.0, 1.0, 0.0]",
            "direction = [0.0, inf, 0.0]",
            10,
            &["`direction`", "finite"],
        );
        bad(
            "exposure = 1.0",
            "exposure = -inf",
            14,
            &["`exposure`", "finite"],
        );
        bad(
            "radiance = [5.0, 5.0, 5.0]",
            "radiance = [5.0, nan, 5.0]",
            18,
            &["`radiance`", "finite"],
        );
        bad(
            "position = [0.0, -2.0, 0.5]",
            "position = [0.0, 1e40, 0.5]",
            9,
            &["out of range for a 32-bit float: 1e40"],
        );
        // Not silently 0: the number the file gives is named.
        bad(
            "radiance = [5.0, 5.0, 5.0]",
            "radiance = [5.0, 1e-50, 5.0]",
            18,
            &["`radiance` is too small for a 32-bit float, which reads 1e-50 as 0"],
        );
    }

    /// A direction's length does not matter: a tiny or huge one whose squares leave f32's
    /// range was read as zero or refused as out of range. Kept as written otherwise.
    #[test]
    fn tiny_and_huge_directions_are_directions() {
        let (_dir, path) = write(
            "direction = [0.0, 1.0, 0.0]\nup = [0.0, 0.0, 1.0]",
            "direction = [0.0, 1e-300, 0.0]\nup = [0.0, 0.0, 3e300]",
        );
        let in_unit_range = |v: [f32; 3], k: usize| {
            (1.0..2.0).contains(&v[k]) && (0..3).all(|i| i == k || v[i] == 0.0)
        };
        let desc = load_scene(&path).unwrap();
        assert!(
            in_unit_range(desc.views[0].direction, 1),
            "{:?}",
            desc.views[0]
        );
        assert!(in_unit_range(desc.views[0].up, 2), "{:?}", desc.views[0]);
        let (_dir, path) = write(
            "direction = [0.0, 1.0, 0.0]",
            "direction = [0.0, 5e-320, 0.0]",
        );
        let desc = load_scene(&path).unwrap();
        assert!(
            in_unit_range(desc.views[0].direction, 1),
            "{:?}",
            desc.views[0]
        );
        let (_dir, path) = write("up = [0.0, 0.0, 1.0]", "up = [0.0, 0.0, 2.5]");
        assert_eq!(load_scene(&path).unwrap().views[0].up, [0.0, 0.0, 2.5]);
        bad(
            "direction = [0.0, 1.0, 0.0]",
            "direction = [0.0, 0.0, 0.0]",
            10,
            &["direction is zero"],
        );
    }

    #[test]
    fn an_integer_past_64_bits_is_out_of_range() {
        bad(
            "size = [8, 8]",
            "size = [99999999999999999999, 8]",
            13,
            &["integer `99999999999999999999` is out of range: TOML's integers are 64-bit"],
        );
    }

    #[test]
    fn vectors_must_have_the_right_length() {
        bad(
            "position = [0.0, -2.0, 0.5]",
            "position = [0.0, -2.0]",
            9,
            &["`position` must have 3 numbers, found 2"],
        );
        bad(
            "up = [0.0, 0.0, 1.0]",
            "up = [0.0, 0.0, 1.0, 0.0]",
            11,
            &["`up` must have 3 numbers, found 4"],
        );
        bad(
            "fov_deg = [60.0, 60.0]",
            "fov_deg = [60.0]",
            12,
            &["`fov_deg` must have 2 numbers"],
        );
        bad(
            "size = [8, 8]",
            "size = [8, 8, 8]",
            13,
            &["size must have 2 integers"],
        );
        bad(
            "radiance = [5.0, 5.0, 5.0]",
            "radiance = [5.0]",
            18,
            &["`radiance` must have 3"],
        );
    }

    #[test]
    fn radiance_must_not_be_negative() {
        bad(
            "radiance = [5.0, 5.0, 5.0]",
            "radiance = [5.0, -0.1, 5.0]",
            18,
            &["light 'lamp'", "radiance must be >= 0"],
        );
        // Zero is a switched-off light.
        let (_dir, path) = write("radiance = [5.0, 5.0, 5.0]", "radiance = [0.0, 0.0, 0.0]");
        assert_eq!(load_scene(&path).unwrap().lights[0].radiance, [0.0; 3]);
        // Nor so large that errors overflow 32-bit floats.
        bad(
            "radiance = [5.0, 5.0, 5.0]",
            "radiance = [5.0, 5.0, 1e30]",
            18,
            &["light 'lamp'", "radiance must be at most 1e18"],
        );
    }

    #[test]
    fn exposure_must_be_positive() {
        bad(
            "exposure = 1.0",
            "exposure = 0.0",
            14,
            &["view 'front'", "exposure must be > 0"],
        );
        bad(
            "exposure = 1.0",
            "exposure = -2",
            14,
            &["exposure must be > 0"],
        );
        // Below f32's range the value written is not the value meant: say so.
        bad(
            "exposure = 1.0",
            "exposure = 1e-50",
            14,
            &["`exposure` is too small for a 32-bit float, which reads 1e-50 as 0"],
        );
    }

    #[test]
    fn size_must_be_at_least_1() {
        bad(
            "size = [8, 8]",
            "size = [0, 8]",
            13,
            &["view 'front'", "size must be between 1 and"],
        );
        bad(
            "size = [8, 8]",
            "size = [8, -1]",
            13,
            &["size must be between 1 and"],
        );
        bad(
            "size = [8, 8]",
            "size = [8, 16385]",
            13,
            &["size must be between 1 and 16384"],
        );
    }

    #[test]
    fn fov_must_be_in_0_180() {
        for fov in [
            "[0.0, 60.0]",
            "[60.0, 180.0]",
            "[-10.0, 60.0]",
            "[60.0, 200.0]",
        ] {
            bad(
                "fov_deg = [60.0, 60.0]",
                &format!("fov_deg = {fov}"),
                12,
                &["fov_deg must be in (0, 180)"],
            );
        }
    }

    #[test]
    fn direction_and_up_must_make_a_frame() {
        bad(
            "direction = [0.0, 1.0, 0.0]",
            "direction = [0.0, 0.0, 0.0]",
            10,
            &["direction is zero"],
        );
        bad(
            "up = [0.0, 0.0, 1.0]",
            "up = [0.0, 2.0, 0.0]",
            11,
            &["parallel to direction"],
        );
        bad(
            "up = [0.0, 0.0, 1.0]",
            "up = [0.0, 0.0, 0.0]",
            11,
            &["zero or parallel"],
        );
    }

    #[test]
    fn duplicate_view_names_are_errors() {
        let second = "[[light]]";
        let view =
            "[[view]]\nname = \"front\"\nposition = [0.0, 0.0, 0.0]\ndirection = [1.0, 0.0, 0.0]\n\
                    up = [0.0, 0.0, 1.0]\nfov_deg = [90.0, 90.0]\nsize = [4, 4]\n\n[[light]]";
        bad(
            second,
            view,
            17,
            &["duplicate view name 'front'", "first at line 7"],
        );
    }

    #[test]
    fn a_scene_needs_a_view() {
        let (_dir, path) = write("", "");
        let text = std::fs::read_to_string(&path).unwrap();
        let start = text.find("[[view]]").unwrap();
        let end = text.find("[[light]]").unwrap();
        std::fs::write(&path, format!("{}{}", &text[..start], &text[end..])).unwrap();
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(
            e.contains("scene.toml") && e.contains("at least one view"),
            "{e}"
        );
    }

    #[test]
    fn duplicate_group_names_are_errors() {
        let extra = "objects = [\"quad\"]\n\n[[group]]\nname = \"floor\"\nkind = \"metal\"\nobjects = [\"other\"]\n";
        bad(
            "objects = [\"quad\"]\n",
            extra,
            26,
            &["duplicate group name 'floor'", "first at line 21"],
        );
    }

    #[test]
    fn an_object_in_two_groups_is_an_error() {
        let extra = "objects = [\"quad\"]\n\n[[group]]\nname = \"rug\"\nkind = \"plastic\"\nobjects = [\"quad\"]\n";
        bad(
            "objects = [\"quad\"]\n",
            extra,
            28,
            &["object 'quad' is in group 'rug' and also group 'floor' (line 23)"],
        );
    }

    #[test]
    fn an_object_twice_in_one_group_is_an_error() {
        bad(
            "objects = [\"quad\"]",
            "objects = [\"quad\", \"quad\"]",
            23,
            &["'quad' is listed twice in group 'floor'"],
        );
    }

    #[test]
    fn an_object_in_a_group_and_a_light_is_an_error() {
        bad(
            "objects = [\"quad\"]",
            "objects = [\"quad\", \"lamp\"]",
            23,
            &["'lamp' is in group 'floor' and also a light (line 17)"],
        );
    }

    #[test]
    fn a_light_listed_twice_is_an_error() {
        let extra = "radiance = [5.0, 5.0, 5.0]\n\n[[light]]\nobject = \"lamp\"\nradiance = [1.0, 1.0, 1.0]\n";
        bad(
            "radiance = [5.0, 5.0, 5.0]\n",
            extra,
            21,
            &["light object 'lamp' is listed twice (first at line 17)"],
        );
    }

    #[test]
    fn unknown_group_kind_is_an_error() {
        bad(
            "kind = \"plastic\"",
            "kind = \"glass\"",
            22,
            &["group 'floor'", "unknown kind 'glass'"],
        );
    }

    #[test]
    fn empty_names_and_lists_are_errors() {
        bad(
            "name = \"front\"",
            "name = \"\"",
            7,
            &["view name is empty"],
        );
        bad(
            "objects = [\"quad\"]",
            "objects = []",
            23,
            &["group 'floor' lists no objects"],
        );
        bad(
            "objects = [\"quad\"]",
            "objects = [\" \"]",
            23,
            &["object is empty"],
        );
        bad(
            "geometry = [\"geo.obj\"]",
            "geometry = []",
            3,
            &["lists no OBJ file"],
        );
    }

    #[test]
    fn geometry_files_must_exist_once() {
        bad(
            "geometry = [\"geo.obj\"]",
            "geometry = [\"nope.obj\"]",
            3,
            &["nope.obj does not exist"],
        );
        bad(
            "geometry = [\"geo.obj\"]",
            "geometry = [\".\"]",
            3,
            &["is a folder, not an OBJ file"],
        );
        bad(
            "geometry = [\"geo.obj\"]",
            "geometry = [\"geo.obj\", \"./geo.obj\"]",
            3,
            &["is listed twice"],
        );
    }

    #[test]
    fn hiding_an_object_twice_is_an_error() {
        bad(
            "hide = []",
            "hide = [\"quad\", \"quad\"]",
            4,
            &["object 'quad' is listed twice in `hide`"],
        );
    }

    #[test]
    fn a_missing_scene_file_is_an_io_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let e = load_scene(&dir.path().join("absent.toml")).unwrap_err();
        assert!(matches!(e, Error::Io { .. }));
        assert!(e.to_string().contains("absent.toml"), "{e}");
    }

    fn check_err(from: &str, to: &str) -> String {
        let (_dir, path) = write(from, to);
        let d = load_scene(&path).unwrap();
        check_objects(&d, &objects_of(&d))
            .expect_err("check_objects should refuse")
            .to_string()
    }

    #[test]
    fn an_object_named_in_the_obj_without_faces_is_reported_where_it_is() {
        let (_dir, path) = write("hide = []", "hide = [\"chair\"]");
        let obj = path.with_file_name("geo.obj");
        std::fs::write(&obj, format!("{OBJ}o chair\n")).unwrap();
        let d = load_scene(&path).unwrap();
        let e = check_objects(&d, &objects_of(&d))
            .expect_err("check_objects should refuse")
            .to_string();
        let line = OBJ.lines().count() + 1;
        assert!(
            e.contains("scene.toml:4")
                && e.contains("'chair' (in `hide`) has no faces in the geometry")
                && e.contains(&format!("geo.obj:{line})")),
            "{e}"
        );
    }

    /// `g quad extra` is one object, "quad extra": the error for 'quad' says so.
    #[test]
    fn an_object_whose_name_holds_a_space_is_pointed_to() {
        let (_dir, path) = write("", "");
        let obj = path.with_file_name("geo.obj");
        std::fs::write(
            &obj,
            OBJ.replace("o quad\n", "g quad extra\n")
                .replace("o lamp", "g lamp"),
        )
        .unwrap();
        let d = load_scene(&path).unwrap();
        let e = check_objects(&d, &objects_of(&d)).unwrap_err().to_string();
        assert!(
            e.contains("object 'quad' (in group 'floor') is not in the geometry")
                && e.contains("; the geometry has object 'quad extra': OBJ reads all that follows `o` or `g` as one name"),
            "{e}"
        );
    }

    /// A file of `o` objects with `g` groups inside them (as Blender writes): the scene
    /// named a `g` and was told only that it was not in the geometry.
    #[test]
    fn a_group_within_an_object_named_as_an_object_is_pointed_to() {
        let (_dir, path) = write("", "");
        let obj = path.with_file_name("geo.obj");
        std::fs::write(&obj, OBJ.replace("o quad\n", "o world\ng quad\n")).unwrap();
        let d = load_scene(&path).unwrap();
        let e = check_objects(&d, &objects_of(&d)).unwrap_err().to_string();
        assert!(
            e.contains("object 'quad' (in group 'floor') is not in the geometry")
                && e.contains("geo.obj:2 has `g quad`, but that file names its objects by `o`"),
            "{e}"
        );
    }

    #[test]
    fn named_objects_must_exist_in_the_geometry() {
        let e = check_err("objects = [\"quad\"]", "objects = [\"quad\", \"chair\"]");
        assert!(
            e.contains("scene.toml:23")
                && e.contains("object 'chair' (in group 'floor') is not in the geometry"),
            "{e}"
        );
        assert!(e.contains("geo.obj"), "{e}");
        let e = check_err("object = \"lamp\"", "object = \"lampe\"");
        assert!(
            e.contains("scene.toml:17") && e.contains("'lampe' (a light) is not in the geometry"),
            "{e}"
        );
        let e = check_err("hide = []", "hide = [\"ghost\"]");
        assert!(
            e.contains("scene.toml:4") && e.contains("'ghost' (in `hide`) is not in the geometry"),
            "{e}"
        );
    }

    #[test]
    fn every_obj_object_must_be_assigned() {
        let e = check_err(
            "[[light]]\nobject = \"lamp\"\nradiance = [5.0, 5.0, 5.0]\n",
            "",
        );
        assert!(e.contains("geo.obj:7"), "{e}");
        assert!(
            e.contains("object 'lamp' is in no group, is no light and is not hidden in"),
            "{e}"
        );
        assert!(e.contains("scene.toml"), "{e}");
    }

    #[test]
    fn hidden_objects_need_no_group_and_may_keep_one() {
        let (_dir, path) = write("hide = []", "hide = [\"lamp\", \"quad\"]");
        let text = std::fs::read_to_string(&path).unwrap();
        let start = text.find("[[light]]").unwrap();
        let end = text.find("[[group]]").unwrap();
        std::fs::write(&path, format!("{}{}", &text[..start], &text[end..])).unwrap();
        let d = load_scene(&path).unwrap();
        check_objects(&d, &objects_of(&d)).unwrap();
    }

    #[test]
    fn an_object_defined_in_two_files_is_an_error_naming_both() {
        let (dir, path) = write(
            "geometry = [\"geo.obj\"]",
            "geometry = [\"geo.obj\", \"more.obj\"]",
        );
        std::fs::write(
            dir.path().join("more.obj"),
            "o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n",
        )
        .unwrap();
        let d = load_scene(&path).unwrap();
        let e = check_objects(&d, &objects_of(&d)).unwrap_err().to_string();
        assert!(
            e.contains("object 'quad' is defined twice")
                && e.contains("geo.obj")
                && e.contains("more.obj"),
            "{e}"
        );
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

    #[test]
    fn every_bench_scene_passes_check_objects() {
        let Some(bench) = bench() else { return };
        let mut n = 0;
        for entry in std::fs::read_dir(&bench).unwrap() {
            let dir = entry.unwrap().path();
            for name in ["scene.toml", "scene-small.toml"] {
                let p = dir.join(name);
                if p.is_file() {
                    let d = load_scene(&p).unwrap_or_else(|e| panic!("{e}"));
                    check_objects(&d, &objects_of(&d)).unwrap_or_else(|e| panic!("{e}"));
                    n += 1;
                }
            }
        }
        assert!(n >= 8, "found only {n} scene files");
    }

    #[test]
    fn line_and_column_of_offsets() {
        let f = TomlFile {
            path: "x.toml".into(),
            text: "ab\ncdé\nf".into(),
        };
        assert_eq!(f.line_col(0), (1, 1));
        assert_eq!(f.line_col(3), (2, 1));
        assert_eq!(f.line_col(7), (2, 4));
        assert_eq!(f.line_col(8), (3, 1));
        assert_eq!(f.line_col(1000), (3, 2));
    }
}
