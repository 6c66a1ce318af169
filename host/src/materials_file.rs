//! materials.toml and truth.toml: one schema (scene-format.md), read and validated into a
//! [`MaterialsDesc`], and written back in the same schema.
//!
//! Keys per model (R required, Z optional but must be 0 when present, - forbidden):
//!
//! | model                 | color | specularity | roughness | roughness_u/v, direction_u | diffuse_map |
//! | ---                   | ---   | ---         | ---       | ---                        | ---         |
//! | diffuse               | R     | Z           | Z         | -                          | -           |
//! | isotropic             | R     | R           | R         | -                          | -           |
//! | anisotropic           | R     | R           | -         | R                          | -           |
//! | mirror                | R     | -           | -         | -                          | -           |
//! | textured-diffuse      | -     | Z           | Z         | -                          | R           |
//! | textured-isotropic    | -     | R           | R         | -                          | R           |
//! | textured-anisotropic  | -     | R           | -         | R                          | R           |
//!
//! `kind` ("plastic" or "metal") is optional on the models with a lobe (isotropic,
//! anisotropic and, as "plastic" only, their textured forms) and forbidden on the others,
//! whose reflectance does not depend on it. scene-format.md gives the kind in scene.toml
//! alone; a recovery of a group of kind "auto" writes the kind it chose here, so that its
//! materials.toml renders with the scene it came from.
//!
//! Ranges: colour components and specularity in [0, 1]; roughness, roughness_u and roughness_v
//! in (0, 1] (reflectance.md keeps Ward's model to (0, 0.3]; larger values are accepted so
//! that a recovery can report them, the core checks what it renders, and `render` warns of
//! them); direction_u is
//! finite and not zero. A diffuse map must exist (relative to the file's folder) and be a
//! file, not a folder. Each group has at most one material per file.
//!
//! `diffuse_map_wrap`, a relume extension, is optional beside a `diffuse_map` and forbidden
//! without one: `"clamp"` (the default, scene-format.md's lookup) or `"repeat"`, a map
//! tiled over its group by texture coordinates past [0, 1] (`material::texture::Wrap`).
//! It is written only when it is `"repeat"`, so files without tiles keep the schema.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use relume_core::material::{Kind, Params, Wrap};
use serde::Deserialize;
use toml::Spanned;

use crate::error::Error;
use crate::fsutil;
use crate::scene_file::TomlFile;

/// The reflectance model of a group.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    Diffuse,
    Isotropic,
    Anisotropic,
    Mirror,
    TexturedDiffuse,
    TexturedIsotropic,
    TexturedAnisotropic,
}

impl Model {
    pub const ALL: [Model; 7] = [
        Model::Diffuse,
        Model::Isotropic,
        Model::Anisotropic,
        Model::Mirror,
        Model::TexturedDiffuse,
        Model::TexturedIsotropic,
        Model::TexturedAnisotropic,
    ];

    /// The name in the file.
    pub fn name(self) -> &'static str {
        match self {
            Model::Diffuse => "diffuse",
            Model::Isotropic => "isotropic",
            Model::Anisotropic => "anisotropic",
            Model::Mirror => "mirror",
            Model::TexturedDiffuse => "textured-diffuse",
            Model::TexturedIsotropic => "textured-isotropic",
            Model::TexturedAnisotropic => "textured-anisotropic",
        }
    }

    pub fn from_name(s: &str) -> Option<Model> {
        Model::ALL.into_iter().find(|m| m.name() == s)
    }

    /// Whether a material of this model must give `key` (a materials.toml key, "color",
    /// "roughness_u", ...): the parameters it has.
    pub fn requires(self, key: &str) -> bool {
        KEYS.iter()
            .position(|k| *k == key)
            .is_some_and(|i| self.rules()[i] == Rule::Required)
    }

    /// Whether the model has a specular lobe, whose colour the kind decides.
    pub fn has_lobe(self) -> bool {
        matches!(
            self,
            Model::Isotropic
                | Model::Anisotropic
                | Model::TexturedIsotropic
                | Model::TexturedAnisotropic
        )
    }

    pub fn is_textured(self) -> bool {
        matches!(
            self,
            Model::TexturedDiffuse | Model::TexturedIsotropic | Model::TexturedAnisotropic
        )
    }

    /// The rule for each key, in [`KEYS`] order.
    fn rules(self) -> [Rule; 7] {
        use Rule::{Forbidden as F, Required as R, Zero as Z};
        match self {
            //                          color spec rough ru rv dir map
            Model::Diffuse => [R, Z, Z, F, F, F, F],
            Model::Isotropic => [R, R, R, F, F, F, F],
            Model::Anisotropic => [R, R, F, R, R, R, F],
            Model::Mirror => [R, F, F, F, F, F, F],
            Model::TexturedDiffuse => [F, Z, Z, F, F, F, R],
            Model::TexturedIsotropic => [F, R, R, F, F, F, R],
            Model::TexturedAnisotropic => [F, R, F, R, R, R, R],
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Rule {
    Required,
    /// Optional, and 0 when present.
    Zero,
    Forbidden,
}

/// The model-dependent keys, in the order they are written.
const KEYS: [&str; 7] = [
    "color",
    "specularity",
    "roughness",
    "roughness_u",
    "roughness_v",
    "direction_u",
    "diffuse_map",
];

/// One group's material.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDesc {
    pub group: String,
    pub model: Model,
    pub color: Option<[f32; 3]>,
    pub specularity: Option<f32>,
    pub roughness: Option<f32>,
    pub roughness_u: Option<f32>,
    pub roughness_v: Option<f32>,
    pub direction_u: Option<[f32; 3]>,
    /// Resolved against the materials file's folder.
    pub diffuse_map: Option<PathBuf>,
    /// How the diffuse map reads coordinates past [0, 1]: clamped unless the file says
    /// `diffuse_map_wrap = "repeat"`.
    pub map_wrap: Wrap,
    /// The kind of its lobe, where the file gives it (see the module's comment); else the
    /// scene's.
    pub kind: Option<Kind>,
    /// Line of its `[[material]]` in the file (0 when not read from a file).
    pub line: usize,
}

/// A materials.toml (or truth.toml).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialsDesc {
    pub path: PathBuf,
    pub materials: Vec<MaterialDesc>,
}

/// The largest roughness for which reflectance.md keeps Ward's model: past it the
/// model's normalisation no longer holds (its lobe can reflect more than it receives).
/// Larger values are read, with a warning from `render`.
pub const WARD_MAX_ROUGHNESS: f32 = 0.3;

impl MaterialsDesc {
    /// A warning for each roughness past [`WARD_MAX_ROUGHNESS`], naming its line.
    pub fn roughness_warnings(&self) -> Vec<String> {
        let mut warnings = Vec::new();
        for m in &self.materials {
            let given = [
                ("roughness", m.roughness),
                ("roughness_u", m.roughness_u),
                ("roughness_v", m.roughness_v),
            ];
            for (key, value) in given {
                if let Some(r) = value.filter(|&r| r > WARD_MAX_ROUGHNESS) {
                    warnings.push(format!(
                        "{}:{}: group '{}': {key} {r} is above {WARD_MAX_ROUGHNESS}, where reflectance.md keeps Ward's model (past it the lobe's normalisation no longer holds); rendered as given",
                        self.path.display(),
                        m.line,
                        m.group
                    ));
                }
            }
        }
        warnings
    }

    /// The files these materials read (path, and what it is): the materials file and its
    /// diffuse maps. No output of a run may replace them (`OutputSet::keeping`).
    pub fn input_files(&self) -> Vec<(PathBuf, String)> {
        let mut files = vec![(self.path.clone(), "a materials file".to_string())];
        files.extend(self.materials.iter().filter_map(|m| {
            Some((
                m.diffuse_map.clone()?,
                format!("the diffuse map of group '{}'", m.group),
            ))
        }));
        files
    }
}

impl MaterialDesc {
    /// An entry of `model` for `group` with no parameter set yet (for writers).
    pub fn new(group: &str, model: Model) -> MaterialDesc {
        MaterialDesc {
            group: group.to_string(),
            model,
            color: None,
            specularity: None,
            roughness: None,
            roughness_u: None,
            roughness_v: None,
            direction_u: None,
            diffuse_map: None,
            map_wrap: Wrap::Clamp,
            kind: None,
            line: 0,
        }
    }

    /// The core's parameters; a textured model maps to its untextured counterpart
    /// (textured-diffuse to diffuse).
    pub fn params(&self) -> Params {
        let s = self.specularity.unwrap_or(0.0);
        match self.model {
            Model::Diffuse | Model::TexturedDiffuse => Params::Diffuse,
            Model::Isotropic | Model::TexturedIsotropic => Params::Isotropic {
                specularity: s,
                roughness: self.roughness.unwrap_or(0.0),
            },
            Model::Anisotropic | Model::TexturedAnisotropic => Params::Anisotropic {
                specularity: s,
                roughness_u: self.roughness_u.unwrap_or(0.0),
                roughness_v: self.roughness_v.unwrap_or(0.0),
                direction: glam::Vec3::from(self.direction_u.unwrap_or([0.0; 3])),
            },
            Model::Mirror => Params::Mirror,
        }
    }

    /// `color`, or white for the textured models (whose colour is in the diffuse map).
    pub fn color_or_white(&self) -> [f32; 3] {
        self.color.unwrap_or([1.0; 3])
    }

    /// Which keys are present, in [`KEYS`] order.
    fn present(&self) -> [bool; 7] {
        [
            self.color.is_some(),
            self.specularity.is_some(),
            self.roughness.is_some(),
            self.roughness_u.is_some(),
            self.roughness_v.is_some(),
            self.direction_u.is_some(),
            self.diffuse_map.is_some(),
        ]
    }

    /// Checks keys against the model and values against their ranges; the message names the
    /// group and the key.
    pub(crate) fn check(&self) -> Result<(), (usize, String)> {
        let g = &self.group;
        let model = self.model.name();
        let present = self.present();
        for (k, rule) in self.model.rules().into_iter().enumerate() {
            match (rule, present[k]) {
                (Rule::Required, false) => {
                    return Err((
                        k,
                        format!("group '{g}': model \"{model}\" needs `{}`", KEYS[k]),
                    ))
                }
                (Rule::Forbidden, true) => {
                    let why = if k == 0 && self.model.is_textured() {
                        " (a textured model stores the colour in diffuse_map)"
                    } else {
                        ""
                    };
                    return Err((
                        k,
                        format!("group '{g}': model \"{model}\" takes no `{}`{why}", KEYS[k]),
                    ));
                }
                _ => {}
            }
        }
        let zero = |k: usize, v: Option<f32>| {
            match (self.model.rules()[k], v) {
            (Rule::Zero, Some(x)) if x != 0.0 => Err((
                k,
                format!("group '{g}': model \"{model}\" has no specular part, so `{}` must be 0, got {x:?}", KEYS[k]),
            )),
            _ => Ok(()),
        }
        };
        zero(1, self.specularity)?;
        zero(2, self.roughness)?;
        if let Some(c) = self.color {
            if c.iter()
                .any(|x| !(x.is_finite() && (0.0..=1.0).contains(x)))
            {
                return Err((
                    0,
                    format!("group '{g}': color components must be in [0, 1], got {c:?}"),
                ));
            }
        }
        if let Some(s) = self.specularity {
            if !(s.is_finite() && (0.0..=1.0).contains(&s)) {
                return Err((
                    1,
                    format!("group '{g}': specularity must be in [0, 1], got {s:?}"),
                ));
            }
        }
        let rough = [
            (2, self.roughness),
            (3, self.roughness_u),
            (4, self.roughness_v),
        ];
        for (k, r) in rough {
            if let Some(r) = r {
                let must_be_zero = self.model.rules()[k] == Rule::Zero;
                let in_range = r.is_finite() && r > 0.0 && r <= 1.0;
                if !must_be_zero && !in_range {
                    return Err((
                        k,
                        format!("group '{g}': {} must be in (0, 1], got {r:?}", KEYS[k]),
                    ));
                }
            }
        }
        if let Some(d) = self.direction_u {
            if d.iter().any(|x| !x.is_finite()) || d == [0.0; 3] {
                return Err((
                    5,
                    format!("group '{g}': direction_u must be finite and not zero, got {d:?}"),
                ));
            }
        }
        match self.kind {
            Some(_) if !self.model.has_lobe() => Err((
                KIND_KEY,
                format!("group '{g}': model \"{model}\" has no lobe, so it takes no `kind`"),
            )),
            Some(Kind::Metal) if self.model.is_textured() => Err((
                KIND_KEY,
                format!(
                    "group '{g}': model \"{model}\" takes kind \"plastic\" only: textured models apply to plastic groups"
                ),
            )),
            _ => Ok(()),
        }
    }
}

/// The index that [`MaterialDesc::check`] gives a fault of `kind` (after [`KEYS`]).
const KIND_KEY: usize = KEYS.len();

/// `kind`'s value in the file.
pub fn kind_name(kind: Kind) -> &'static str {
    match kind {
        Kind::Plastic => "plastic",
        Kind::Metal => "metal",
    }
}

fn kind_from_name(name: &str) -> Option<Kind> {
    [Kind::Plastic, Kind::Metal]
        .into_iter()
        .find(|&k| kind_name(k) == name)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    #[allow(dead_code)] // checked first, by TomlFile::check_format
    format: toml::Value,
    #[serde(default, rename = "material")]
    materials: Vec<Spanned<RawMaterial>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    group: Spanned<String>,
    model: Spanned<String>,
    color: Option<Spanned<Vec<f64>>>,
    specularity: Option<Spanned<f64>>,
    roughness: Option<Spanned<f64>>,
    roughness_u: Option<Spanned<f64>>,
    roughness_v: Option<Spanned<f64>>,
    direction_u: Option<Spanned<Vec<f64>>>,
    diffuse_map: Option<Spanned<String>>,
    diffuse_map_wrap: Option<Spanned<String>>,
    kind: Option<Spanned<String>>,
}

impl RawMaterial {
    /// The span of key `k` (in [`KEYS`] order), if present.
    fn span(&self, k: usize) -> Option<std::ops::Range<usize>> {
        match k {
            0 => self.color.as_ref().map(|v| v.span()),
            1 => self.specularity.as_ref().map(|v| v.span()),
            2 => self.roughness.as_ref().map(|v| v.span()),
            3 => self.roughness_u.as_ref().map(|v| v.span()),
            4 => self.roughness_v.as_ref().map(|v| v.span()),
            5 => self.direction_u.as_ref().map(|v| v.span()),
            6 => self.diffuse_map.as_ref().map(|v| v.span()),
            _ => self.kind.as_ref().map(|v| v.span()),
        }
    }
}

/// Reads and validates a materials file.
pub fn load_materials(path: &Path) -> Result<MaterialsDesc, Error> {
    let file = TomlFile::read(path)?;
    file.check_format()?;
    let raw: RawFile = file.parse()?;
    let mut materials: Vec<MaterialDesc> = Vec::new();
    let mut lines: HashMap<String, usize> = HashMap::new();
    for m in &raw.materials {
        let header = m.span();
        let line = file.line_of(header.start);
        let m = m.get_ref();
        // A group's name in the scene is an identifier, so one that is not names no group.
        let group = file.group_identifier(&m.group, "group")?;
        if let Some(first) = lines.get(&group) {
            return Err(file.at(
                m.group.span(),
                format!("group '{group}' has a second material (first at line {first})"),
            ));
        }
        lines.insert(group.clone(), line);
        let Some(model) = Model::from_name(m.model.get_ref()) else {
            let names: Vec<&str> = Model::ALL.iter().map(|m| m.name()).collect();
            return Err(file.at(
                m.model.span(),
                format!(
                    "group '{group}': unknown model '{}' (expected {})",
                    m.model.get_ref(),
                    names.join(", ")
                ),
            ));
        };
        let num = |v: &Option<Spanned<f64>>, what: &str| {
            v.as_ref().map(|v| file.number(v, what)).transpose()
        };
        let vec3 = |v: &Option<Spanned<Vec<f64>>>, what: &str| {
            v.as_ref().map(|v| file.vector::<3>(v, what)).transpose()
        };
        let diffuse_map = match &m.diffuse_map {
            Some(s) => Some(file.resolve(&file.name(s, "diffuse_map")?)),
            None => None,
        };
        let map_wrap = match &m.diffuse_map_wrap {
            None => Wrap::Clamp,
            Some(w) if m.diffuse_map.is_none() => {
                return Err(file.at(
                    w.span(),
                    format!(
                        "group '{group}': diffuse_map_wrap says how a diffuse_map is read, and the material has none"
                    ),
                ))
            }
            Some(w) => wrap_from_name(w.get_ref()).ok_or_else(|| {
                file.at(
                    w.span(),
                    format!(
                        "group '{group}': unknown diffuse_map_wrap '{}' (expected clamp or repeat)",
                        w.get_ref()
                    ),
                )
            })?,
        };
        let kind = match &m.kind {
            Some(k) => Some(kind_from_name(k.get_ref()).ok_or_else(|| {
                file.at(
                    k.span(),
                    match k.get_ref().as_str() {
                        "auto" => format!(
                            "group '{group}': kind \"auto\" belongs in scene.toml; a \
                             material's kind is the one its lobe has, plastic or metal"
                        ),
                        other => format!(
                            "group '{group}': unknown kind '{other}' (expected plastic or metal)"
                        ),
                    },
                )
            })?),
            None => None,
        };
        let desc = MaterialDesc {
            group,
            model,
            color: vec3(&m.color, "color")?,
            specularity: num(&m.specularity, "specularity")?,
            roughness: num(&m.roughness, "roughness")?,
            roughness_u: num(&m.roughness_u, "roughness_u")?,
            roughness_v: num(&m.roughness_v, "roughness_v")?,
            direction_u: m
                .direction_u
                .as_ref()
                .map(|v| file.direction(v, "direction_u"))
                .transpose()?,
            diffuse_map,
            map_wrap,
            kind,
            line,
        };
        if let Err((k, msg)) = desc.check() {
            return Err(file.at(m.span(k).unwrap_or(header), msg));
        }
        if let (Some(p), Some(s)) = (&desc.diffuse_map, &m.diffuse_map) {
            if let Some(why) = fsutil::not_a_file(p, "an image") {
                return Err(file.at(
                    s.span(),
                    format!("group '{}': diffuse_map {why}", desc.group),
                ));
            }
        }
        materials.push(desc);
    }
    Ok(MaterialsDesc {
        path: path.to_path_buf(),
        materials,
    })
}

/// `m` as the text of a materials file at `path`: keys in a fixed order, floats in the
/// shortest form that reads back to the same f32, `diffuse_map` relative to the file's
/// folder. Refuses materials that [`load_materials`] would refuse (except that a diffuse map
/// need not exist yet).
pub fn materials_text(path: &Path, m: &MaterialsDesc) -> Result<String, Error> {
    let mut seen: HashMap<&str, ()> = HashMap::new();
    let mut out = String::from("format = 1\n");
    for d in &m.materials {
        if d.group.trim().is_empty() {
            return Err(Error::input(
                path,
                "cannot write a material with an empty group name",
            ));
        }
        if seen.insert(&d.group, ()).is_some() {
            return Err(Error::input(
                path,
                format!("cannot write two materials for group '{}'", d.group),
            ));
        }
        d.check()
            .map_err(|(_, msg)| Error::input(path, format!("cannot write: {msg}")))?;
        out.push_str("\n[[material]]\n");
        let _ = writeln!(out, "group = {}", toml_string(&d.group));
        let _ = writeln!(out, "model = {}", toml_string(d.model.name()));
        if let Some(kind) = d.kind {
            let _ = writeln!(out, "kind = {}", toml_string(kind_name(kind)));
        }
        if let Some(c) = d.color {
            let _ = writeln!(out, "color = {}", float_array(&c));
        }
        let scalars = [
            ("specularity", d.specularity),
            ("roughness", d.roughness),
            ("roughness_u", d.roughness_u),
            ("roughness_v", d.roughness_v),
        ];
        for (key, v) in scalars {
            if let Some(v) = v {
                let _ = writeln!(out, "{key} = {}", float(v));
            }
        }
        if let Some(dir) = d.direction_u {
            let _ = writeln!(out, "direction_u = {}", float_array(&dir));
        }
        if let Some(map) = &d.diffuse_map {
            let rel = relative_to_folder_of(path, map);
            let Some(s) = rel.to_str() else {
                return Err(Error::input(
                    path,
                    format!(
                        "group '{}': diffuse_map {} is not valid UTF-8",
                        d.group,
                        map.display()
                    ),
                ));
            };
            let _ = writeln!(out, "diffuse_map = {}", toml_string(s));
            if d.map_wrap == Wrap::Repeat {
                let _ = writeln!(out, "diffuse_map_wrap = {}", toml_string("repeat"));
            }
        } else if d.map_wrap != Wrap::Clamp {
            return Err(Error::input(
                path,
                format!(
                    "cannot write group '{}': a diffuse_map_wrap without a diffuse_map",
                    d.group
                ),
            ));
        }
    }
    Ok(out)
}

/// The wrap a `diffuse_map_wrap` value names.
fn wrap_from_name(name: &str) -> Option<Wrap> {
    match name {
        "clamp" => Some(Wrap::Clamp),
        "repeat" => Some(Wrap::Repeat),
        _ => None,
    }
}

fn toml_string(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

/// The shortest decimal that reads back (through TOML's f64, then f32) to exactly `x`;
/// always with a `.` or exponent so TOML reads a float.
fn float(x: f32) -> String {
    let short = format!("{x:?}");
    if short.parse::<f64>().map(|y| y as f32) == Ok(x) {
        short
    } else {
        format!("{:?}", f64::from(x))
    }
}

fn float_array(xs: &[f32]) -> String {
    let parts: Vec<String> = xs.iter().map(|&x| float(x)).collect();
    format!("[{}]", parts.join(", "))
}

/// `target` relative to the folder of `file` (with `..` where needed); absolute when the
/// two share no root.
fn relative_to_folder_of(file: &Path, target: &Path) -> PathBuf {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let dir = abs(file)
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let target = abs(target);
    let d: Vec<Component> = dir
        .components()
        .filter(|c| *c != Component::CurDir)
        .collect();
    let t: Vec<Component> = target
        .components()
        .filter(|c| *c != Component::CurDir)
        .collect();
    let common = d.iter().zip(&t).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return target.clone();
    }
    let mut rel = PathBuf::new();
    for _ in common..d.len() {
        rel.push("..");
    }
    for c in &t[common..] {
        rel.push(c.as_os_str());
    }
    rel
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fsutil;

    /// `m` written at `path` as `recover` writes it (its `OutputSet` holds the same text).
    fn write_materials(path: &Path, m: &MaterialsDesc) -> Result<(), Error> {
        fsutil::write_atomic(path, materials_text(path, m)?.as_bytes())
    }

    const VALUES: [&str; 7] = [
        "[0.5, 0.4, 0.3]",
        "0.05",
        "0.1",
        "0.05",
        "0.2",
        "[1.0, 0.0, 0.0]",
        "\"tex.exr\"",
    ];

    /// A valid `[[material]]` body (lines after `model`) for `model`, skipping key `skip`
    /// and adding key `add` with its usual value.
    fn body(model: Model, skip: Option<usize>, add: Option<usize>) -> String {
        let mut out = String::new();
        for (k, rule) in model.rules().into_iter().enumerate() {
            let present = match rule {
                Rule::Required => skip != Some(k),
                Rule::Zero => skip != Some(k),
                Rule::Forbidden => add == Some(k),
            };
            if present {
                let v = if rule == Rule::Zero { "0.0" } else { VALUES[k] };
                out.push_str(&format!("{} = {v}\n", KEYS[k]));
            }
        }
        out
    }

    fn file_text(model: Model, body: &str) -> String {
        format!(
            "format = 1\n\n[[material]]\ngroup = \"g\"\nmodel = \"{}\"\n{body}",
            model.name()
        )
    }

    fn write(text: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("tex.exr"), b"exists").unwrap();
        let path = dir.path().join("m.toml");
        std::fs::write(&path, text).unwrap();
        (dir, path)
    }

    fn bad(text: &str, line: usize, what: &[&str]) -> String {
        let (_dir, path) = write(text);
        let e = load_materials(&path)
            .expect_err("should be refused")
            .to_string();
        eprintln!("{e}");
        assert!(
            e.contains(&format!("m.toml:{line}:")),
            "expected m.toml:{line} in: {e}\n--- file\n{text}"
        );
        for w in what {
            assert!(e.contains(w), "expected {w:?} in: {e}\n--- file\n{text}");
        }
        e
    }

    /// The line of `key = ` in `text`.
    fn line_of(text: &str, key: &str) -> usize {
        text.lines()
            .position(|l| l.starts_with(&format!("{key} =")))
            .unwrap()
            + 1
    }

    #[test]
    fn every_model_loads_and_maps_to_params() {
        for model in Model::ALL {
            let (dir, path) = write(&file_text(model, &body(model, None, None)));
            let m = load_materials(&path).unwrap_or_else(|e| panic!("{e}"));
            let d = &m.materials[0];
            assert_eq!((d.group.as_str(), d.model, d.line), ("g", model, 3));
            let expected = match model {
                Model::Diffuse | Model::TexturedDiffuse => Params::Diffuse,
                Model::Isotropic | Model::TexturedIsotropic => Params::Isotropic {
                    specularity: 0.05,
                    roughness: 0.1,
                },
                Model::Anisotropic | Model::TexturedAnisotropic => Params::Anisotropic {
                    specularity: 0.05,
                    roughness_u: 0.05,
                    roughness_v: 0.2,
                    direction: glam::Vec3::X,
                },
                Model::Mirror => Params::Mirror,
            };
            assert_eq!(d.params(), expected, "{model:?}");
            if model.is_textured() {
                assert_eq!(d.color_or_white(), [1.0; 3]);
                assert_eq!(d.diffuse_map, Some(dir.path().join("tex.exr")));
            } else {
                assert_eq!(d.color_or_white(), [0.5, 0.4, 0.3]);
            }
        }
    }

    /// `diffuse_map_wrap` tiles a map, is clamp when absent, round-trips (written only
    /// when it repeats), and is refused at its line with any other value or without a
    /// map.
    #[test]
    fn a_maps_wrap_is_read_written_and_checked() {
        let model = Model::TexturedDiffuse;
        let with = |wrap: &str| {
            file_text(
                model,
                &format!("{}diffuse_map_wrap = {wrap}\n", body(model, None, None)),
            )
        };
        let (_dir, path) = write(&file_text(model, &body(model, None, None)));
        let plain = load_materials(&path).unwrap();
        assert_eq!(plain.materials[0].map_wrap, Wrap::Clamp);
        assert!(!materials_text(&path, &plain).unwrap().contains("wrap"));
        for (value, wrap) in [("\"clamp\"", Wrap::Clamp), ("\"repeat\"", Wrap::Repeat)] {
            let (_dir, path) = write(&with(value));
            let m = load_materials(&path).unwrap();
            assert_eq!(m.materials[0].map_wrap, wrap);
            let text = materials_text(&path, &m).unwrap();
            assert_eq!(
                text.contains("diffuse_map_wrap = \"repeat\"\n"),
                wrap == Wrap::Repeat,
                "{text}"
            );
            std::fs::write(&path, &text).unwrap();
            assert_eq!(load_materials(&path).unwrap(), m);
        }
        let text = with("\"mirror\"");
        bad(
            &text,
            line_of(&text, "diffuse_map_wrap"),
            &["unknown diffuse_map_wrap 'mirror' (expected clamp or repeat)"],
        );
        let text = file_text(
            Model::Diffuse,
            &format!(
                "{}diffuse_map_wrap = \"repeat\"\n",
                body(Model::Diffuse, None, None)
            ),
        );
        bad(
            &text,
            line_of(&text, "diffuse_map_wrap"),
            &["diffuse_map_wrap says how a diffuse_map is read, and the material has none"],
        );
        let mut tiled_colour = MaterialDesc::new("g", Model::Diffuse);
        tiled_colour.color = Some([0.5; 3]);
        tiled_colour.map_wrap = Wrap::Repeat;
        let e = materials_text(
            &path,
            &MaterialsDesc {
                path: path.clone(),
                materials: vec![tiled_colour],
            },
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("a diffuse_map_wrap without a diffuse_map"),
            "{e}"
        );
    }

    /// A lobe's kind loads where the model has a lobe (a textured one as plastic only),
    /// and is refused, at its line, on the others and when it is neither kind.
    #[test]
    fn kind_is_given_only_to_a_lobe() {
        for model in Model::ALL {
            for kind in [Kind::Plastic, Kind::Metal] {
                let line = format!("kind = \"{}\"\n", kind_name(kind));
                let text = file_text(model, &format!("{line}{}", body(model, None, None)));
                if model.has_lobe() && !(model.is_textured() && kind == Kind::Metal) {
                    let (_dir, path) = write(&text);
                    let m = load_materials(&path).unwrap_or_else(|e| panic!("{e}\n{text}"));
                    assert_eq!(m.materials[0].kind, Some(kind), "{model:?}");
                } else if model.has_lobe() {
                    bad(&text, 6, &["group 'g'", "takes kind \"plastic\" only"]);
                } else {
                    bad(&text, 6, &["group 'g'", model.name(), "takes no `kind`"]);
                }
            }
        }
        let text = file_text(
            Model::Isotropic,
            &format!("kind = \"gold\"\n{}", body(Model::Isotropic, None, None)),
        );
        bad(
            &text,
            6,
            &["group 'g'", "unknown kind 'gold'", "plastic or metal"],
        );
        let text = file_text(
            Model::Isotropic,
            &format!("kind = \"auto\"\n{}", body(Model::Isotropic, None, None)),
        );
        bad(
            &text,
            6,
            &[
                "group 'g'",
                "\"auto\" belongs in scene.toml",
                "plastic or metal",
            ],
        );
        let (_dir, path) = write(&file_text(
            Model::Isotropic,
            &body(Model::Isotropic, None, None),
        ));
        assert_eq!(load_materials(&path).unwrap().materials[0].kind, None);
    }

    #[test]
    fn required_keys_per_model() {
        for model in Model::ALL {
            for (k, rule) in model.rules().into_iter().enumerate() {
                if rule == Rule::Required {
                    let text = file_text(model, &body(model, Some(k), None));
                    bad(
                        &text,
                        3,
                        &["group 'g'", model.name(), &format!("needs `{}`", KEYS[k])],
                    );
                }
            }
        }
    }

    #[test]
    fn forbidden_keys_per_model() {
        for model in Model::ALL {
            for (k, rule) in model.rules().into_iter().enumerate() {
                if rule == Rule::Forbidden {
                    let text = file_text(model, &body(model, None, Some(k)));
                    bad(
                        &text,
                        line_of(&text, KEYS[k]),
                        &["group 'g'", &format!("takes no `{}`", KEYS[k])],
                    );
                }
            }
        }
        let text = file_text(
            Model::TexturedDiffuse,
            &body(Model::TexturedDiffuse, None, Some(0)),
        );
        bad(
            &text,
            6,
            &["textured model stores the colour in diffuse_map"],
        );
    }

    #[test]
    fn zero_keys_are_optional_and_must_be_zero() {
        for model in [Model::Diffuse, Model::TexturedDiffuse] {
            let text = file_text(model, &body(model, Some(1), None));
            let (_dir, path) = write(&text);
            load_materials(&path).unwrap();
            let text = text.replace("roughness = 0.0", "roughness = 0.1");
            bad(
                &text,
                line_of(&text, "roughness"),
                &["has no specular part", "`roughness` must be 0, got 0.1"],
            );
            // A value far from 1 is written with its exponent, not 47 digits.
            let tiny = text.replace("roughness = 0.1", "roughness = 1e-45");
            bad(
                &tiny,
                line_of(&tiny, "roughness"),
                &["`roughness` must be 0, got 1e-45"],
            );
            let text = file_text(model, &body(model, None, None))
                .replace("specularity = 0.0", "specularity = 0.2");
            bad(
                &text,
                line_of(&text, "specularity"),
                &["`specularity` must be 0"],
            );
        }
    }

    #[test]
    fn ranges() {
        let iso = file_text(Model::Isotropic, &body(Model::Isotropic, None, None));
        let aniso = file_text(Model::Anisotropic, &body(Model::Anisotropic, None, None));
        let cases: [(&str, &str, &str, &str); 12] = [
            (
                &iso,
                "color = [0.5, 0.4, 0.3]",
                "color = [0.5, 1.2, 0.3]",
                "color components must be in [0, 1]",
            ),
            (
                &iso,
                "color = [0.5, 0.4, 0.3]",
                "color = [-0.1, 0.4, 0.3]",
                "color components must be in [0, 1]",
            ),
            (
                &iso,
                "specularity = 0.05",
                "specularity = 1.5",
                "specularity must be in [0, 1], got 1.5",
            ),
            (
                &iso,
                "specularity = 0.05",
                "specularity = -0.5",
                "specularity must be in [0, 1]",
            ),
            (
                &iso,
                "roughness = 0.1",
                "roughness = 0.0",
                "roughness must be in (0, 1], got 0",
            ),
            (
                &iso,
                "roughness = 0.1",
                "roughness = 1e-50",
                "`roughness` is too small for a 32-bit float, which reads 1e-50 as 0",
            ),
            (
                &iso,
                "roughness = 0.1",
                "roughness = 1.5",
                "roughness must be in (0, 1]",
            ),
            (
                &aniso,
                "roughness_u = 0.05",
                "roughness_u = 0",
                "roughness_u must be in (0, 1]",
            ),
            (
                &aniso,
                "roughness_v = 0.2",
                "roughness_v = -1",
                "roughness_v must be in (0, 1]",
            ),
            (
                &aniso,
                "direction_u = [1.0, 0.0, 0.0]",
                "direction_u = [0, 0, 0]",
                "direction_u must be finite and not zero",
            ),
            (
                &iso,
                "roughness = 0.1",
                "roughness = nan",
                "`roughness` must be a finite number",
            ),
            (
                &aniso,
                "direction_u = [1.0, 0.0, 0.0]",
                "direction_u = [1.0, 0.0]",
                "`direction_u` must have 3 numbers",
            ),
        ];
        for (base, from, to, what) in cases {
            assert!(base.contains(from), "{from}");
            let text = base.replace(from, to);
            let key = to.split(' ').next().unwrap();
            bad(&text, line_of(&text, key), &[what]);
        }
        // Integers are numbers; roughness 1 is the upper end.
        let (_dir, path) = write(
            &iso.replace("roughness = 0.1", "roughness = 1")
                .replace("color = [0.5, 0.4, 0.3]", "color = [1, 0, 0]"),
        );
        let m = load_materials(&path).unwrap();
        assert_eq!(
            (m.materials[0].roughness, m.materials[0].color),
            (Some(1.0), Some([1.0, 0.0, 0.0]))
        );
        // A direction of any length is a direction: 1e-50 underflowed f32 and was refused
        // as zero.
        let (_dir, path) = write(&aniso.replace(
            "direction_u = [1.0, 0.0, 0.0]",
            "direction_u = [1e-50, 0.0, 0.0]",
        ));
        let d = load_materials(&path).unwrap().materials[0]
            .direction_u
            .unwrap();
        assert!((1.0..2.0).contains(&d[0]) && d[1..] == [0.0, 0.0], "{d:?}");
    }

    #[test]
    fn duplicate_groups_are_errors() {
        let one = body(Model::Mirror, None, None);
        let text = format!(
            "{}\n[[material]]\ngroup = \"g\"\nmodel = \"mirror\"\n{one}",
            file_text(Model::Mirror, &one)
        );
        bad(
            &text,
            9,
            &["group 'g' has a second material (first at line 3)"],
        );
    }

    #[test]
    fn format_keys_and_models() {
        let good = file_text(Model::Mirror, &body(Model::Mirror, None, None));
        bad(
            &good.replace("format = 1", "format = 3"),
            1,
            &["format 3 is not supported"],
        );
        bad(
            &good.replace("model = \"mirror\"", "model = \"glass\""),
            5,
            &["unknown model 'glass'", "textured-anisotropic"],
        );
        bad(
            &good.replace("model = \"mirror\"", "model = \"mirror\"\nshininess = 3"),
            6,
            &["unknown key `shininess`"],
        );
        bad(
            &good.replace("group = \"g\"\n", ""),
            3,
            &["missing key `group`"],
        );
        bad(
            &good.replace("group = \"g\"", "group = \"\""),
            4,
            &["group is empty"],
        );
        bad(
            &good.replace("[[material]]", "[[materials]]"),
            3,
            &["unknown key `materials`"],
        );
        let (_dir, path) = write(&good.replace("format = 1\n", ""));
        let e = load_materials(&path).unwrap_err().to_string();
        assert!(
            e.contains("m.toml") && e.contains("missing key `format`"),
            "{e}"
        );
        let (_dir, path) = write("format = 1\n");
        assert!(load_materials(&path).unwrap().materials.is_empty());
    }

    /// A textured material whose `diffuse_map` is `map` is refused at that line, saying
    /// `what`.
    fn map_refused(map: &str, what: &[&str]) {
        let text = file_text(
            Model::TexturedIsotropic,
            &body(Model::TexturedIsotropic, None, None),
        )
        .replace("tex.exr", map);
        bad(&text, line_of(&text, "diffuse_map"), what);
    }

    #[test]
    fn a_missing_diffuse_map_is_an_error() {
        map_refused(
            "textures/none.exr",
            &["group 'g'", "diffuse_map", "none.exr does not exist"],
        );
    }

    /// A device exists but is no image: said so, not "does not exist".
    #[cfg(unix)]
    #[test]
    fn a_diffuse_map_that_is_a_device_is_named_as_such() {
        map_refused(
            "/dev/null",
            &["diffuse_map /dev/null is not a regular file"],
        );
    }

    #[test]
    fn a_missing_file_is_an_io_error() {
        let dir = tempfile::tempdir().unwrap();
        let e = load_materials(&dir.path().join("absent.toml")).unwrap_err();
        assert!(
            matches!(e, Error::Io { .. }) && e.to_string().contains("absent.toml"),
            "{e}"
        );
    }

    fn desc(group: &str, model: Model) -> MaterialDesc {
        MaterialDesc::new(group, model)
    }

    #[test]
    fn a_roughness_past_wards_range_is_read_with_a_warning_naming_its_line() {
        let lobe = |roughness_v: &str| {
            let body = body(Model::Anisotropic, None, None)
                .replace("roughness_v = 0.2", &format!("roughness_v = {roughness_v}"));
            file_text(Model::Anisotropic, &body)
        };
        let (_dir, path) = write(&lobe("0.3"));
        assert!(load_materials(&path)
            .unwrap()
            .roughness_warnings()
            .is_empty());
        let (_dir, path) = write(&lobe("0.5"));
        let warnings = load_materials(&path).unwrap().roughness_warnings();
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains("m.toml:3: group 'g': roughness_v 0.5 is above 0.3"),
            "{warnings:?}"
        );
    }

    #[test]
    fn write_then_load_round_trips_exactly() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("maps")).unwrap();
        std::fs::write(dir.path().join("maps/t.exr"), b"x").unwrap();
        let path = dir.path().join("out/materials.toml");
        std::fs::create_dir(dir.path().join("out")).unwrap();
        // Awkward floats: a simple xorshift over the bits of (0, 1].
        let mut state = 0x9e3779b9u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            f32::from_bits(0x3000_0000 + state % 0x0f00_0000).min(1.0)
        };
        let mut materials = Vec::new();
        for i in 0..200 {
            // Every character a group's name may hold (an identifier, as in the scene).
            let mut d = desc(&format!("g{i}.a-b_C"), Model::Isotropic);
            d.color = Some([next(), next(), next()]);
            d.specularity = Some(next());
            d.roughness = Some(next());
            d.kind = [None, Some(Kind::Plastic), Some(Kind::Metal)][i % 3];
            materials.push(d);
        }
        let mut a = desc("plate", Model::TexturedAnisotropic);
        a.specularity = Some(0.9);
        a.roughness_u = Some(1e-7);
        a.roughness_v = Some(0.2);
        a.direction_u = Some([0.0, -1.0, 1e-30]);
        a.diffuse_map = Some(dir.path().join("maps/t.exr"));
        materials.push(a);
        let mut d = desc("wall", Model::Diffuse);
        d.color = Some([0.45, 0.36, 0.26]);
        d.specularity = Some(0.0);
        d.roughness = Some(0.0);
        materials.push(d);
        let m = MaterialsDesc {
            path: path.clone(),
            materials,
        };
        write_materials(&path, &m).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("diffuse_map = \"../maps/t.exr\""), "{text}");
        assert!(
            text.contains("model = \"isotropic\"\nkind = \"metal\"\ncolor = "),
            "{text}"
        );
        assert!(
            text.contains("color = [0.45, 0.36, 0.26]\nspecularity = 0.0\nroughness = 0.0\n"),
            "{text}"
        );
        let back = load_materials(&path).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(back.materials.len(), m.materials.len());
        for (a, b) in m.materials.iter().zip(&back.materials) {
            let b = MaterialDesc {
                line: 0,
                diffuse_map: a.diffuse_map.clone(),
                ..b.clone()
            };
            assert_eq!(a, &b);
        }
        let resolved = back.materials[200].diffuse_map.clone().unwrap();
        assert_eq!(
            std::fs::canonicalize(resolved).unwrap(),
            std::fs::canonicalize(dir.path().join("maps/t.exr")).unwrap()
        );
        // Writing again gives the same bytes.
        write_materials(&path, &back).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
    }

    #[test]
    fn written_layout_is_stable() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.toml");
        let mut d = desc("walls", Model::Mirror);
        d.color = Some([0.9, 1.0, 0.0]);
        write_materials(
            &path,
            &MaterialsDesc {
                path: path.clone(),
                materials: vec![d],
            },
        )
        .unwrap();
        let expected = "format = 1\n\n[[material]]\ngroup = \"walls\"\nmodel = \"mirror\"\ncolor = [0.9, 1.0, 0.0]\n";
        assert_eq!(std::fs::read_to_string(&path).unwrap(), expected);
    }

    #[test]
    fn writing_refuses_what_loading_would_refuse() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.toml");
        let mut d = desc("g", Model::Isotropic);
        d.color = Some([0.5; 3]);
        d.specularity = Some(f32::NAN);
        d.roughness = Some(0.1);
        let e = write_materials(
            &path,
            &MaterialsDesc {
                path: path.clone(),
                materials: vec![d.clone()],
            },
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("m.toml") && e.to_string().contains("specularity"),
            "{e}"
        );
        d.specularity = Some(0.1);
        let two = MaterialsDesc {
            path: path.clone(),
            materials: vec![d.clone(), d],
        };
        let e = write_materials(&path, &two).unwrap_err().to_string();
        assert!(e.contains("two materials for group 'g'"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn float_format_round_trips_through_f64() {
        for x in [
            0.1f32,
            1.0,
            1e-7,
            16777217.0,
            f32::MIN_POSITIVE,
            1e-45,
            0.3,
            3.4e38,
        ] {
            let s = float(x);
            assert!(s.contains('.') || s.contains('e'), "{s}");
            assert_eq!(s.parse::<f64>().unwrap() as f32, x, "{s}");
        }
    }

    #[test]
    fn every_bench_truth_loads_and_matches_its_scene() {
        let Some(bench) = crate::scene_file::tests::bench() else {
            return;
        };
        let mut n = 0;
        for entry in std::fs::read_dir(&bench).unwrap() {
            let dir = entry.unwrap().path();
            let truth = dir.join("truth.toml");
            if !truth.is_file() {
                continue;
            }
            let m = load_materials(&truth).unwrap_or_else(|e| panic!("{e}"));
            let scene = crate::scene_file::load_scene(&dir.join("scene.toml")).unwrap();
            let mut a: Vec<&str> = m.materials.iter().map(|d| d.group.as_str()).collect();
            let mut b: Vec<&str> = scene.groups.iter().map(|g| g.name.as_str()).collect();
            a.sort();
            b.sort();
            assert_eq!(a, b, "{}", truth.display());
            for d in &m.materials {
                if let Some(map) = &d.diffuse_map {
                    assert!(map.is_file(), "{}", map.display());
                }
            }
            n += 1;
        }
        assert!(n >= 4, "found {n} truth files");
    }
}
