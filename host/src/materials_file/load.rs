//! Reading a materials file: its TOML schema (`RawFile`, `RawMaterial`, with the span of
//! each value), and each material's values read, named at their line, and checked.

use std::collections::HashMap;
use std::path::Path;

use relume_core::material::Wrap;
use serde::Deserialize;
use toml::Spanned;

use super::model::kind_from_name;
use super::{MaterialDesc, MaterialsDesc, Model};
use crate::error::Error;
use crate::fsutil;
use crate::scene_file::TomlFile;

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
    /// The span of key `k` (in [`KEYS`](super::model::KEYS) order), if present.
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

/// The wrap a `diffuse_map_wrap` value names.
fn wrap_from_name(name: &str) -> Option<Wrap> {
    match name {
        "clamp" => Some(Wrap::Clamp),
        "repeat" => Some(Wrap::Repeat),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials_file::materials_text;
    use crate::materials_file::tests::{bad, body, file_text, line_of, write};

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
