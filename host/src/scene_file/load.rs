//! The loading of a scene.toml: its values checked, in the file's order (geometry, `hide`,
//! views, lights, groups), into a [`SceneDesc`]; each object in at most one group or light.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::error::Error;
use crate::fsutil;

use super::raw::RawScene;
use super::views::check_view;
use super::{GroupDesc, GroupKind, LightDesc, SceneDesc, TomlFile, ViewDesc};

pub(super) fn load(path: &Path, needs_views: bool) -> Result<SceneDesc, Error> {
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

    // Where each object is used: "group 'g'" or "a light", with the offset of its name
    // (its line is counted only for a message: counted for every object, from the
    // file's start, 30,000 objects took a second).
    let mut used: HashMap<String, (String, usize)> = HashMap::new();
    let mut lights = Vec::new();
    for l in &raw.lights {
        let l = l.get_ref();
        let object = file.name(&l.object, "light object")?;
        if let Some((_, first)) = used.get(&object) {
            let first = file.line_of(*first);
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
        used.insert(
            object.clone(),
            ("a light".to_string(), l.object.span().start),
        );
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
            if let Some((where_, first)) = used.get(&object) {
                let first = file.line_of(*first);
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
            used.insert(object.clone(), (format!("group '{name}'"), o.span().start));
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

#[cfg(test)]
mod tests {
    use crate::scene_file::tests::{bad, write};
    use crate::scene_file::{load_scene, GroupKind};

    #[test]
    fn kinds_metal_and_auto() {
        let (_dir, path) = write("kind = \"plastic\"", "kind = \"metal\"");
        assert_eq!(load_scene(&path).unwrap().groups[0].kind, GroupKind::Metal);
        let (_dir, path) = write("kind = \"plastic\"", "kind = \"auto\"");
        assert_eq!(load_scene(&path).unwrap().groups[0].kind, GroupKind::Auto);
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
}
