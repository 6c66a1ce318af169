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
//!
//! The parts: `model` (the models and the keys each takes, the names of a lobe's kind),
//! `check` (a material checked against its model and the ranges), `load` (the file read
//! and each material checked, at its line) and `write` (materials as a file's text); here,
//! the materials themselves and what their users ask of them.

use std::path::PathBuf;

use relume_core::material::{Kind, Params, Wrap};

mod check;
mod load;
mod model;
mod write;

pub use load::load_materials;
pub use model::{kind_name, Model};
pub use write::materials_text;

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
}

#[cfg(test)]
mod tests {
    use super::model::{Rule, KEYS};
    use super::*;

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
    pub(super) fn body(model: Model, skip: Option<usize>, add: Option<usize>) -> String {
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

    pub(super) fn file_text(model: Model, body: &str) -> String {
        format!(
            "format = 1\n\n[[material]]\ngroup = \"g\"\nmodel = \"{}\"\n{body}",
            model.name()
        )
    }

    pub(super) fn write(text: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("tex.exr"), b"exists").unwrap();
        let path = dir.path().join("m.toml");
        std::fs::write(&path, text).unwrap();
        (dir, path)
    }

    pub(super) fn bad(text: &str, line: usize, what: &[&str]) -> String {
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
    pub(super) fn line_of(text: &str, key: &str) -> usize {
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
}
