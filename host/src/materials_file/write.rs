//! Writing materials back as a materials file: keys in a fixed order, floats in the
//! shortest form that reads back to the same f32, a diffuse map relative to the file.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use relume_core::material::Wrap;

use super::model::kind_name;
use super::MaterialsDesc;
use crate::error::Error;

/// `m` as the text of a materials file at `path`: keys in a fixed order, floats in the
/// shortest form that reads back to the same f32, `diffuse_map` relative to the file's
/// folder. Refuses materials that [`load_materials`](super::load_materials) would refuse
/// (except that a diffuse map need not exist yet).
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
    use relume_core::material::Kind;

    use super::*;
    use crate::fsutil;
    use crate::materials_file::{load_materials, MaterialDesc, Model};

    /// `m` written at `path` as `recover` writes it (its `OutputSet` holds the same text).
    fn write_materials(path: &Path, m: &MaterialsDesc) -> Result<(), Error> {
        fsutil::write_atomic(path, materials_text(path, m)?.as_bytes())
    }

    fn desc(group: &str, model: Model) -> MaterialDesc {
        MaterialDesc::new(group, model)
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
}
