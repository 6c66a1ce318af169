//! The scene's object names checked against the objects of its OBJ files
//! ([`check_objects`]), each error at the line that names the object.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use crate::error::Error;
use crate::obj::ObjObject;

use super::raw::SceneLines;
use super::SceneDesc;

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
    // Every name the scene assigns, so that each object is looked up once, not searched
    // for in every list.
    let assigned: HashSet<&str> = desc
        .hide
        .iter()
        .chain(desc.lights.iter().map(|l| &l.object))
        .chain(desc.groups.iter().flat_map(|g| &g.objects))
        .map(String::as_str)
        .collect();
    for o in objects {
        if !assigned.contains(o.name.as_str()) {
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

#[cfg(test)]
mod tests {
    use crate::scene_file::tests::{bench, objects_of, write, OBJ};
    use crate::scene_file::{check_objects, load_scene};

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
}
