//! Bad inputs to `relume render` and the scene-deriving benches through the real binary, on
//! a copy of the bundled scene (scenes/cornell) broken in one place: the same materials
//! file given twice, a diffuse map that is a folder, `hide` naming a group, an object
//! defined again in an extra OBJ, `--view` naming no view, a name TOML must escape in a
//! downsampled scene, an edit's own materials file given as `--truth`, and a lobe's kind
//! missing where scene.toml says "auto" or against what it says, a lamp hidden. Each is refused
//! with its exit code and a message that names the file (and line) and what is wrong,
//! never a panic, and leaves no output; the downsampled scene is one that can be read back.

#[path = "common/mod.rs"]
mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{copy_cornell, files_and_bytes, relume, relume_ok};

const USAGE: i32 = 2;
const INPUT: i32 = 3;

/// A copy of the bundled scene (scene.toml, geometry.obj, materials.toml, views/) in
/// `sub` of a fresh temp dir.
struct Case {
    dir: tempfile::TempDir,
    sub: String,
}

impl Case {
    fn new() -> Case {
        Case::in_folder("c")
    }

    fn in_folder(sub: &str) -> Case {
        let dir = tempfile::tempdir().unwrap();
        copy_cornell(&dir.path().join(sub));
        Case {
            dir,
            sub: sub.to_string(),
        }
    }

    /// `name` in the scene's folder.
    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(&self.sub).join(name)
    }

    /// Replaces the first `from` by `to` in the scene's file `name`.
    fn edit(&self, name: &str, from: &str, to: &str) -> &Case {
        let text = std::fs::read_to_string(self.path(name)).unwrap();
        assert!(text.contains(from), "test setup: {from:?} not in {name}");
        std::fs::write(self.path(name), text.replacen(from, to, 1)).unwrap();
        self
    }

    /// Runs relume in the scene's folder.
    fn run(&self, args: &[&str]) -> Output {
        relume(&self.path(""), args)
    }

    /// Runs relume in the scene's folder, expects exit `code`, no panic, every string of
    /// `has` on stderr and every file as it was; returns stderr.
    fn fails(&self, args: &[&str], code: i32, has: &[&str]) -> String {
        let before = files_and_bytes(self.dir.path());
        let run = self.run(args);
        let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
        let show = format!("relume {args:?}: status {:?}\n{stderr}", run.status);
        assert_eq!(run.status.code(), Some(code), "{show}");
        assert!(!stderr.contains("panicked"), "{show}");
        for s in has {
            assert!(stderr.contains(s), "expected {s:?} on stderr\n{show}");
        }
        assert!(
            files_and_bytes(self.dir.path()) == before,
            "{show}\nthe run changed the files"
        );
        stderr
    }
}

/// `bench downsample` of the case's scene by 2 into `half/`.
const DOWNSAMPLE: [&str; 7] = [
    "bench",
    "downsample",
    "scene.toml",
    "--factor",
    "2",
    "--out",
    "half",
];

/// `render scene.toml --materials <materials...> --out out --spp 1`.
fn render_args<'a>(materials: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["render", "scene.toml", "--materials"];
    args.extend(materials);
    args.extend(["--out", "out", "--spp", "1"]);
    args
}

/// The scene's materials split in two files, `a.toml` (the first four groups) and
/// `b.toml` (the rest).
fn split_materials(case: &Case) {
    let text = std::fs::read_to_string(case.path("materials.toml")).unwrap();
    let entries: Vec<&str> = text.split("[[material]]").skip(1).collect();
    let file = |part: &[&str]| {
        let body: String = part.iter().map(|e| format!("[[material]]{e}")).collect();
        format!("format = 1\n\n{body}")
    };
    std::fs::write(case.path("a.toml"), file(&entries[..4])).unwrap();
    std::fs::write(case.path("b.toml"), file(&entries[4..])).unwrap();
}

/// One file given twice to `--materials` (by one spelling or two) gave "group 'floor' has
/// two materials: here and at a.toml:4", naming one line as both: now the file is named
/// as given twice, a usage error.
#[test]
fn a_materials_file_given_twice_is_named_as_such() {
    let case = Case::new();
    split_materials(&case);
    // The split files render: the error below is the repetition's.
    relume_ok(&case.path(""), &render_args(&["a.toml", "b.toml"]));
    std::fs::remove_dir_all(case.path("out")).unwrap();
    for again in ["a.toml", "./a.toml"] {
        let stderr = case.fails(
            &render_args(&["a.toml", "b.toml", again]),
            USAGE,
            &[&format!(
                "{again} is given twice to --materials (also as a.toml)"
            )],
        );
        assert!(!stderr.contains("has two materials"), "{stderr}");
    }
}

/// A materials file with no `[[material]]` among several was accepted without a word:
/// the render goes on (the others give every group its material) and says the file
/// changes nothing, on stderr and in render.json.
#[test]
fn a_materials_file_without_materials_is_named_in_a_warning() {
    let case = Case::new();
    split_materials(&case);
    std::fs::write(case.path("empty.toml"), "format = 1\n").unwrap();
    let out = relume_ok(
        &case.path(""),
        &render_args(&["a.toml", "empty.toml", "b.toml"]),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    let warning = "empty.toml has no [[material]]: it changes nothing";
    assert!(stderr.contains(warning), "{stderr}");
    let summary = std::fs::read_to_string(case.path("out/render.json")).unwrap();
    assert!(summary.contains(warning), "{summary}");
    // Files that each give materials draw no such warning.
    let out = relume_ok(&case.path(""), &render_args(&["a.toml", "b.toml"]));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("has no [[material]]"), "{stderr}");
}

/// A `diffuse_map` that names a folder was said not to exist.
#[test]
fn a_diffuse_map_that_is_a_folder_is_named_as_a_folder() {
    let case = Case::new();
    case.edit(
        "materials.toml",
        "model = \"diffuse\"\ncolor = [0.5, 0.42, 0.32]",
        "model = \"textured-diffuse\"\ndiffuse_map = \"maps\"",
    );
    std::fs::create_dir(case.path("maps")).unwrap();
    let stderr = case.fails(
        &render_args(&["materials.toml"]),
        INPUT,
        &[
            "materials.toml:7",
            "group 'floor': diffuse_map maps is a folder, not an image",
        ],
    );
    assert!(!stderr.contains("does not exist"), "{stderr}");
}

/// `hide` lists OBJ objects: a group's name there was "not in the geometry", which reads as
/// if the group were missing; now the message says it is a group and which objects to list.
#[test]
fn a_group_named_in_hide_is_said_to_be_a_group() {
    let case = Case::new();
    case.edit("scene.toml", "hide = []", "hide = [\"walls_white\"]");
    case.fails(
        &render_args(&["materials.toml"]),
        INPUT,
        &[
            "scene.toml:4",
            "'walls_white' in `hide` is a group, not an object",
            "list its objects 'wall_back', 'wall_front'",
        ],
    );
    // An unknown name is still "not in the geometry".
    case.edit(
        "scene.toml",
        "hide = [\"walls_white\"]",
        "hide = [\"chair\"]",
    );
    case.fails(
        &render_args(&["materials.toml"]),
        INPUT,
        &[
            "scene.toml:4",
            "object 'chair' (in `hide`) is not in the geometry",
        ],
    );
}

/// An extra OBJ that defines an object again was refused naming both files but no line:
/// now each definition's `o` line.
#[test]
fn an_object_defined_again_in_an_extra_obj_is_named_at_both_lines() {
    let case = Case::new();
    std::fs::write(
        case.path("extra.obj"),
        "# a second box\no box\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    case.edit(
        "scene.toml",
        "geometry = [\"geometry.obj\"]",
        "geometry = [\"geometry.obj\", \"extra.obj\"]",
    );
    let box_line = std::fs::read_to_string(case.path("geometry.obj"))
        .unwrap()
        .lines()
        .position(|l| l == "o box")
        .unwrap()
        + 1;
    case.fails(
        &render_args(&["materials.toml"]),
        INPUT,
        &[
            "extra.obj:2:",
            &format!(
                "object 'box' is defined twice: in geometry.obj:{box_line} and in extra.obj:2"
            ),
        ],
    );
}

/// A folder given where a text input goes (a materials file, the scene) gave the system's
/// "Is a directory (os error 21)" with exit 4, as if the machine were at fault: now it is
/// bad input, named as a folder.
#[test]
fn a_folder_given_as_a_text_input_is_named_as_a_folder() {
    let case = Case::new();
    case.fails(
        &render_args(&["views"]),
        INPUT,
        &["views: is a folder, not a file"],
    );
    case.fails(
        &[
            "render",
            "views",
            "--materials",
            "materials.toml",
            "--out",
            "out",
        ],
        INPUT,
        &["views: is a folder, not a file"],
    );
}

/// A view's image that is a folder was the system's "Is a directory (os error 21)" with
/// exit 4 in `recover` and `bench downsample`, and a missing one "No such file or
/// directory" with exit 4 and no line: now both are bad input at the view's `image` line,
/// as a missing OBJ is at its `geometry` line.
#[test]
fn a_view_image_that_is_missing_or_a_folder_is_named_at_its_line() {
    let case = Case::new();
    let recover = ["recover", "scene.toml", "--out", "out"];
    std::fs::remove_file(case.path("views/px.exr")).unwrap();
    for args in [&recover[..], &DOWNSAMPLE[..]] {
        case.fails(
            args,
            INPUT,
            &[
                "scene.toml:8:",
                "view 'px': image ",
                "px.exr does not exist",
            ],
        );
    }
    std::fs::create_dir(case.path("views/px.exr")).unwrap();
    for args in [&recover[..], &DOWNSAMPLE[..]] {
        case.fails(
            args,
            INPUT,
            &["scene.toml:8:", "px.exr is a folder, not an image"],
        );
    }
    assert!(!case.path("out").exists());
}

/// Errors about a view found after the scene is read (a size the downsampling factor does
/// not divide, no image where the panorama is needed) named the scene and the view but
/// not the line: now the line of the view's `size`, or of its `name` where it has no
/// `image`.
#[test]
fn errors_about_a_view_name_its_line() {
    let case = Case::new();
    let factor_3 = [
        "bench",
        "downsample",
        "scene.toml",
        "--factor",
        "3",
        "--out",
        "third",
    ];
    case.fails(
        &factor_3,
        INPUT,
        &[
            "scene.toml:13:",
            "view 'px' is 32x32, not a multiple of factor 3",
        ],
    );
    case.edit("scene.toml", "image = \"views/nx.exr\"\n", "");
    case.fails(
        &["recover", "scene.toml", "--out", "out"],
        INPUT,
        &[
            "scene.toml:17:",
            "view 'nx' has no image: recover needs the panorama",
        ],
    );
    case.fails(
        &DOWNSAMPLE,
        INPUT,
        &["scene.toml:17:", "view 'nx' has no image"],
    );
}

/// `bench downsample` checks the scene's geometry as `check` would: a face naming a vertex
/// past those defined was written into the derived scene, refused only when it was used.
#[test]
fn a_downsample_of_a_scene_whose_obj_is_bad_is_refused() {
    let case = Case::new();
    let obj = std::fs::read_to_string(case.path("geometry.obj")).unwrap();
    std::fs::write(case.path("geometry.obj"), format!("{obj}f 1 2 99999\n")).unwrap();
    case.fails(
        &DOWNSAMPLE,
        INPUT,
        &["geometry.obj:", "vertex index 99999 is out of range"],
    );
    assert!(!case.path("half").exists());
}

/// A lamp hidden (`hide` removes any object) is a light of no surface: it emits nothing,
/// and a scene lit by it alone is refused as unlit, naming a hidden light among the
/// causes. It was refused as a scene too large for a light "0 across", which sent the
/// user to crop the geometry.
#[test]
fn a_hidden_light_is_a_light_switched_off() {
    let case = Case::new();
    case.edit("scene.toml", "hide = []", "hide = [\"light\"]");
    let stderr = case.fails(
        &["check", "scene.toml"],
        INPUT,
        &[
            "scene.toml: no light of the scene reaches what its views see",
            "a light hidden",
        ],
    );
    assert!(!stderr.contains("across"), "{stderr}");
    let run = case.run(&[
        "render",
        "scene.toml",
        "--materials",
        "materials.toml",
        "--out",
        "r",
        "--spp",
        "1",
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(stderr.contains("every pixel is black"), "{stderr}");
}

/// A view a few millimetres from the back wall is refused, naming what it sees there and
/// that moving it away helps; `--view` of another view renders, and `compare views
/// --view` compares, where both were refused because of the view not selected.
#[test]
fn a_view_too_close_to_a_wall_refuses_only_what_selects_it() {
    let case = Case::new();
    case.edit(
        "scene.toml",
        "name = \"py\"\nimage = \"views/py.exr\"\nposition = [1.5, 0.9, 1.3]",
        "name = \"py\"\nimage = \"views/py.exr\"\nposition = [1.5, 2.995, 1.3]",
    );
    case.fails(
        &render_args(&["materials.toml"]),
        INPUT,
        &[
            "of the distance at which view 'py' sees the scene",
            "on group 'walls_white'",
            "Move the view away from what it sees",
        ],
    );
    let mut px = render_args(&["materials.toml"]);
    px.extend(["--view", "px"]);
    let run = case.run(&px);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let run = case.run(&[
        "compare",
        "views",
        "scene.toml",
        "views",
        "out",
        "--view",
        "px",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let mut py = render_args(&["materials.toml"]);
    py.extend(["--view", "py"]);
    case.fails(&py, INPUT, &["view 'py' sees the scene"]);
}

/// `render --view px` into a folder of an earlier full render left the other five views
/// there, and `panorama join` joined them with the new one without a word: both say so.
#[test]
fn views_of_an_earlier_render_left_in_the_folder_are_told_of() {
    let case = Case::new();
    let run = case.run(&render_args(&["materials.toml"]));
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(!String::from_utf8_lossy(&run.stderr).contains("earlier render"));
    let mut px = render_args(&["materials.toml"]);
    px.extend(["--view", "px", "--seed", "2"]);
    let run = case.run(&px);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(
        stderr.contains("out also holds views nx, py, ny, pz, nz from an earlier render"),
        "{stderr}"
    );
    let run = case.run(&["panorama", "join", "scene.toml", "out", "--out", "pano.exr"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(
        stderr.contains("views nx, py, ny, pz, nz are not of the last render into this folder (its render.json lists px)"),
        "{stderr}"
    );
}

/// `--view` naming no view of the scene says which views it has.
#[test]
fn a_view_flag_naming_no_view_lists_the_views() {
    let case = Case::new();
    let mut args = render_args(&["materials.toml"]);
    args.extend(["--view", "front"]);
    case.fails(
        &args,
        USAGE,
        &["--view front: scene.toml has no such view (its views: px, nx, py, ny, pz, nz)"],
    );
}

/// `bench downsample` wrote the derived scene.toml's strings with Rust's escapes, which
/// are not TOML's: a zero-width space (U+200B) in the scene's name or folder came out as
/// `\u{200b}`, and the scene it wrote could not be read back. Now it can, and names the
/// same files.
#[test]
fn a_downsampled_scene_with_a_name_toml_must_escape_reads_back() {
    let case = Case::in_folder("cornell\u{200b}copy");
    case.edit(
        "scene.toml",
        "name = \"cornell\"",
        "name = \"cornell\\u200bcopy\\u0001\"",
    );
    relume_ok(&case.path(""), &DOWNSAMPLE);
    let derived = case.path("half/scene.toml");
    let text = std::fs::read_to_string(&derived).unwrap();
    assert!(!text.contains("\\u{"), "{text}");
    let out = relume_ok(
        &case.path(""),
        &[
            "render",
            "half/scene.toml",
            "--materials",
            "materials.toml",
            "--out",
            "half-render",
            "--spp",
            "1",
        ],
    );
    assert!(out.status.success());
    assert!(case.path("half-render/px.exr").is_file());
    // The derived scene names the folder's files by their true names.
    let geometry = std::fs::canonicalize(case.path("geometry.obj")).unwrap();
    assert!(text.contains(geometry.to_str().unwrap()), "{text}");
}

/// An edit's own materials file (beside its scene.toml, for the objects it adds) given
/// also as `--truth` was refused as "a file of another scene", listing every group as
/// only in this file: now the repetition is named.
#[test]
fn an_edits_own_materials_given_as_truth_is_named() {
    let case = Case::new();
    let text = std::fs::read_to_string(case.path("scene.toml"))
        .unwrap()
        .replace("\"geometry.obj\"", "\"../geometry.obj\"")
        .replace("\"views/", "\"../views/");
    std::fs::create_dir(case.path("e")).unwrap();
    std::fs::write(case.path("e/scene.toml"), text).unwrap();
    std::fs::copy(case.path("materials.toml"), case.path("e/materials.toml")).unwrap();
    let args = [
        "bench",
        "edits",
        "e/scene.toml",
        "--recovered",
        "materials.toml",
        "--truth",
        "e/materials.toml",
        "--out",
        "out",
        "--spp",
        "1",
    ];
    let stderr = case.fails(
        &args,
        USAGE,
        &["--truth e/materials.toml is also e/materials.toml, which gives the materials of the objects edit e/scene.toml adds"],
    );
    assert!(!stderr.contains("only in this file"), "{stderr}");
}

/// The views `render` wrote into `out` (every EXR, with its bytes).
fn rendered_views(case: &Case, out: &str) -> Vec<(PathBuf, Vec<u8>)> {
    files_and_bytes(&case.path(out))
        .into_iter()
        .filter(|(p, _)| p.extension().is_some_and(|e| e == "exr"))
        .collect()
}

/// The line of `group = "<group>"`'s `[[material]]` in the case's materials.toml.
fn material_line(case: &Case, group: &str) -> usize {
    let text = std::fs::read_to_string(case.path("materials.toml")).unwrap();
    let at = format!("group = \"{group}\"");
    text.lines().position(|l| l == at).unwrap()
}

/// A group of kind "auto" takes its lobe's kind from its material, where a recovery of it
/// writes the kind it chose: given there, the scene renders as with the kind in
/// scene.toml, to the byte. Missing, or against the kind scene.toml gives, it is refused
/// at the material's line. (Before, a recovery of an "auto" group could not be rendered
/// with its own scene: materials.toml had no place for the kind.)
#[test]
fn a_lobes_kind_comes_from_the_scene_or_else_its_material() {
    let case = Case::new();
    let line = material_line(&case, "sphere");
    let at_line = format!("materials.toml:{line}");
    relume_ok(&case.path(""), &render_args(&["materials.toml"]));
    let as_given = rendered_views(&case, "out");
    assert!(!as_given.is_empty());

    case.edit(
        "scene.toml",
        "name = \"sphere\"\nkind = \"metal\"",
        "name = \"sphere\"\nkind = \"auto\"",
    );
    case.fails(
        &render_args(&["materials.toml"]),
        INPUT,
        &[
            &at_line,
            "group 'sphere' has kind \"auto\"",
            "kind = \"metal\"",
        ],
    );
    case.edit(
        "materials.toml",
        "group = \"sphere\"\nmodel = \"isotropic\"\n",
        "group = \"sphere\"\nmodel = \"isotropic\"\nkind = \"metal\"\n",
    );
    std::fs::remove_dir_all(case.path("out")).unwrap();
    relume_ok(&case.path(""), &render_args(&["materials.toml"]));
    assert!(
        rendered_views(&case, "out") == as_given,
        "the kind from the material differs"
    );

    case.edit(
        "scene.toml",
        "name = \"sphere\"\nkind = \"auto\"",
        "name = \"sphere\"\nkind = \"plastic\"",
    );
    case.fails(
        &render_args(&["materials.toml"]),
        INPUT,
        &[
            &at_line,
            "group 'sphere' is kind \"plastic\" in",
            "but its material says kind \"metal\"",
        ],
    );
}

/// The helper's own check: a case's files are where the tests expect them.
#[test]
fn the_case_renders_as_it_is() {
    let case = Case::new();
    relume_ok(&case.path(""), &render_args(&["materials.toml"]));
    assert!(Path::new(&case.path("out/render.json")).is_file());
}

/// A scene too large for its light names the object to leave out: the one that stretches
/// the bounding box. A speck a million units off was refused naming the room's largest
/// wall.
#[test]
fn a_scene_stretched_by_one_far_object_names_it() {
    let case = Case::new();
    let obj = std::fs::read_to_string(case.path("geometry.obj")).unwrap();
    let speck = "o speck\nv 1000000 0 0\nv 1000000 0.01 0\nv 1000000 0 0.01\nf -3 -2 -1\n";
    std::fs::write(case.path("geometry.obj"), format!("{obj}{speck}")).unwrap();
    case.edit(
        "scene.toml",
        "objects = [\"box\"]",
        "objects = [\"box\", \"speck\"]",
    );
    let stderr = case.fails(
        &["check", "scene.toml"],
        INPUT,
        &[
            "the geometry spans 1e6 units",
            "of the size of light 'light' (0.8 across)",
            "Give the light at least 1000 across",
            "(without object 'speck' of geometry.obj, the geometry would span 3 units)",
        ],
    );
    assert!(!stderr.contains("the largest is object"), "{stderr}");
}

/// A light's face given twice emits twice: every group of the room came out 87-99%
/// brighter, and `check` and `recover` said nothing. It is refused, naming the light and
/// the triangle, and so is the face given again along its other diagonal; the same face
/// turned the other way (a panel lit on both sides) is not.
#[test]
fn a_light_face_given_twice_is_refused_and_one_turned_over_is_not() {
    let case = Case::new();
    let obj = std::fs::read_to_string(case.path("geometry.obj")).unwrap();
    assert!(obj.contains("\nf 25 26 27 28\n"));
    let twice = obj.replace("\nf 25 26 27 28\n", "\nf 25 26 27 28\nf 25 26 27 28\n");
    std::fs::write(case.path("geometry.obj"), twice).unwrap();
    case.fails(
        &["check", "scene.toml"],
        INPUT,
        &[
            "geometry.obj: light 'light': its triangle 3 (in file order; corners (1.1, 1.1, 2.49)",
            "is also triangle 1 of light 'light', facing the same way",
        ],
    );
    // The same quad split along its other diagonal is no copy, but emits twice as much.
    let other_diagonal = obj.replace("\nf 25 26 27 28\n", "\nf 25 26 27 28\nf 26 27 28 25\n");
    std::fs::write(case.path("geometry.obj"), other_diagonal).unwrap();
    case.fails(
        &["check", "scene.toml"],
        INPUT,
        &[
            "geometry.obj: light 'light': its triangle 3 (in file order; corners (1.1, 1.9, 2.49), (1.9, 1.9, 2.49), (1.9, 1.1, 2.49))",
            "overlaps triangle 1 of light 'light' in one plane, facing the same way (near (1.6, 1.8, 2.49))",
        ],
    );
    for both_sides in ["f 28 27 26 25", "f 27 26 25 28"] {
        let lit_twice = obj.replace(
            "\nf 25 26 27 28\n",
            &format!("\nf 25 26 27 28\n{both_sides}\n"),
        );
        std::fs::write(case.path("geometry.obj"), lit_twice).unwrap();
        relume_ok(&case.path(""), &["check", "scene.toml"]);
    }
}

/// A lamp in the ceiling's plane, or a hair behind it, is hidden from the views by the
/// ceiling and lit the room as before, through the renderer's ray slack, without a word:
/// `check` blamed the exposure. `check` and `render` now name the light and the group;
/// the lamp a centimetre below the ceiling, as the bundled scene has it, is not named.
#[test]
fn a_light_flush_with_a_surface_is_named() {
    let case = Case::new();
    let obj = std::fs::read_to_string(case.path("geometry.obj")).unwrap();
    assert_eq!(obj.matches(" 2.490000\n").count(), 4);
    for z in ["2.500000", "2.500100"] {
        let moved = obj.replace(" 2.490000\n", &format!(" {z}\n"));
        std::fs::write(case.path("geometry.obj"), moved).unwrap();
        let named = "light 'light' lies against group 'ceiling': at 2 of 2 points on it";
        let check = relume_ok(&case.path(""), &["check", "scene.toml"]);
        let stderr = String::from_utf8_lossy(&check.stderr);
        assert!(stderr.contains(named), "z {z}: {stderr}");
        let render = relume_ok(&case.path(""), &render_args(&["materials.toml"]));
        let stderr = String::from_utf8_lossy(&render.stderr);
        assert!(stderr.contains(named), "z {z}: {stderr}");
    }
    std::fs::write(case.path("geometry.obj"), obj).unwrap();
    let check = relume_ok(&case.path(""), &["check", "scene.toml"]);
    assert!(!String::from_utf8_lossy(&check.stderr).contains("lies against"));
}

/// A rug modelled as a quad in the floor's plane, of another group, leaves it to the
/// tracer's tie rule which of the two a view sees there. `check` and `render` name both groups,
/// the view that sees it and a point on it; a rug within the ray slack is told as apart,
/// one a centimetre up is not told, and the box standing on the floor (its bottom in the
/// floor's plane, closed over) never is.
#[test]
fn a_rug_in_the_floors_plane_is_told() {
    let case = Case::new();
    let obj = std::fs::read_to_string(case.path("geometry.obj")).unwrap();
    let scene = std::fs::read_to_string(case.path("scene.toml")).unwrap();
    let with_rug = scene.replace(r#"objects = ["plate"]"#, r#"objects = ["plate", "rug"]"#);
    assert_ne!(with_rug, scene);
    std::fs::write(case.path("scene.toml"), with_rug).unwrap();
    let rug = |z: &str| {
        let n = obj.lines().filter(|l| l.starts_with("v ")).count();
        let corners = [(0.8, 0.4), (1.6, 0.4), (1.6, 1.2), (0.8, 1.2)]
            .map(|(x, y)| format!("v {x} {y} {z}\n"))
            .concat();
        format!(
            "{obj}o rug\n{corners}f {} {} {} {}\n",
            n + 1,
            n + 2,
            n + 3,
            n + 4
        )
    };
    let told = |z: &str| {
        std::fs::write(case.path("geometry.obj"), rug(z)).unwrap();
        let check = relume_ok(&case.path(""), &["check", "scene.toml"]);
        String::from_utf8_lossy(&check.stderr).into_owned()
    };
    let stderr = told("0");
    assert!(
        stderr.contains("groups 'floor' and 'plate' overlap in one plane (3 pairs of triangles, seen from view 'nz' at ("),
        "{stderr}"
    );
    assert!(stderr.contains("is left to chance"), "{stderr}");
    assert!(!stderr.contains("'box'"), "{stderr}");
    let render = relume_ok(&case.path(""), &render_args(&["materials.toml"]));
    let stderr = String::from_utf8_lossy(&render.stderr);
    assert!(
        stderr.contains("groups 'floor' and 'plate' overlap in one plane"),
        "{stderr}"
    );
    // The slack is 2e-4 of the room's 3 units.
    let stderr = told("0.0003");
    assert!(
        stderr.contains("groups 'floor' and 'plate' overlap 0.0003 units apart"),
        "{stderr}"
    );
    let stderr = told("0.01");
    assert!(!stderr.contains("overlap"), "{stderr}");
}

/// Triangles given twice are told by `check` and `render`: the floor's face twice (it
/// renders as one, at a cost per copy), and the floor's face given to the ceiling too
/// (which of the two a view sees there was left to chance).
#[test]
fn triangles_given_twice_are_told() {
    let case = Case::new();
    let obj = std::fs::read_to_string(case.path("geometry.obj")).unwrap();
    assert!(obj.contains("\nf 1 2 3 4\no ceiling\n"));
    let twice = obj.replace("\nf 1 2 3 4\n", "\nf 1 2 3 4\nf 1 2 3 4\n");
    std::fs::write(case.path("geometry.obj"), twice).unwrap();
    let copies = "group 'floor' has 2 triangles given again (the same corners)";
    for args in [
        &["check", "scene.toml"][..],
        &render_args(&["materials.toml"]),
    ] {
        let run = relume_ok(&case.path(""), args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(stderr.contains(copies), "{args:?}: {stderr}");
    }
    let shared = obj.replace("\no ceiling\n", "\no ceiling\nf 1 2 3 4\n");
    std::fs::write(case.path("geometry.obj"), shared).unwrap();
    let run = relume_ok(&case.path(""), &["check", "scene.toml"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("groups 'floor' and 'ceiling' share 2 triangles (the same corners)"),
        "{stderr}"
    );
    assert!(!stderr.contains("given again"), "{stderr}");
}
