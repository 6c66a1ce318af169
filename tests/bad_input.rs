//! Bad inputs through the real binary: `relume render` on a tiny scene broken in one place
//! must exit with the input (3) or I/O (4) code, name the file and the line, pixel or object
//! on stderr, never panic, and leave no output behind.

#[path = "common/mod.rs"]
mod common;

use std::path::{Path, PathBuf};

use common::{files_and_bytes, files_in, path_str, relume};

const SCENE: &str = r#"format = 1
name = "tiny"
geometry = ["geo.obj"]
hide = []

[[view]]
name = "front"
position = [0.5, -1.5, 0.5]
direction = [0.0, 1.0, 0.0]
up = [0.0, 0.0, 1.0]
fov_deg = [90.0, 90.0]
size = [4, 4]
exposure = 1.0

[[light]]
object = "lamp"
radiance = [10.0, 10.0, 10.0]

[[group]]
name = "floor"
kind = "plastic"
objects = ["quad"]
"#;

/// A unit quad (with texture coordinates) facing up, and a light triangle above it facing down.
const OBJ: &str = "o quad
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
f 1/1 2/2 3/3 4/4
o lamp
v 0.2 0.2 1
v 0.8 0.2 1
v 0.5 0.8 1
f 5 7 6
";

const MATERIALS: &str = "format = 1

[[material]]
group = \"floor\"
model = \"diffuse\"
color = [0.5, 0.5, 0.5]
";

/// A scene folder in a fresh temp dir: scene.toml, geo.obj, m.toml (less those left out).
struct Case {
    dir: tempfile::TempDir,
    scene: String,
    obj: String,
    materials: String,
    missing: Vec<&'static str>,
}

impl Case {
    fn new() -> Case {
        Case {
            dir: tempfile::tempdir().unwrap(),
            scene: SCENE.into(),
            obj: OBJ.into(),
            materials: MATERIALS.into(),
            missing: Vec::new(),
        }
    }

    /// The case with input file `name` not written.
    fn without(mut self, name: &'static str) -> Case {
        self.missing.push(name);
        self
    }

    fn scene(mut self, from: &str, to: &str) -> Case {
        assert!(
            self.scene.contains(from),
            "test setup: {from:?} not in scene.toml"
        );
        self.scene = self.scene.replacen(from, to, 1);
        self
    }

    fn obj(mut self, from: &str, to: &str) -> Case {
        assert!(
            self.obj.contains(from),
            "test setup: {from:?} not in geo.obj"
        );
        self.obj = self.obj.replacen(from, to, 1);
        self
    }

    fn materials(mut self, from: &str, to: &str) -> Case {
        assert!(
            self.materials.contains(from),
            "test setup: {from:?} not in m.toml"
        );
        self.materials = self.materials.replacen(from, to, 1);
        self
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// Runs `relume render scene.toml --materials m.toml --out <out> [--spp <spp>]` on the
    /// files as they are (see [`Case::write`]).
    fn render(&self, out: &str, spp: Option<u32>) -> std::process::Output {
        let (scene, materials, out) =
            (self.path("scene.toml"), self.path("m.toml"), self.path(out));
        let spp = spp.map(|n| n.to_string());
        let mut args = vec![
            "render",
            path_str(&scene),
            "--materials",
            path_str(&materials),
            "--out",
            path_str(&out),
        ];
        if let Some(n) = &spp {
            args.extend(["--spp", n.as_str()]);
        }
        relume(self.dir.path(), &args)
    }

    fn write(&self) {
        for (name, text) in [
            ("scene.toml", &self.scene),
            ("geo.obj", &self.obj),
            ("m.toml", &self.materials),
        ] {
            if !self.missing.contains(&name) {
                std::fs::write(self.path(name), text).unwrap();
            }
        }
    }

    /// Runs `relume render scene.toml --materials m.toml --out out`; returns stderr after
    /// checking the exit code, the absence of a panic and of any output.
    fn fails(&self, code: i32, stderr_has: &[&str]) -> String {
        self.write();
        let before = files_in(self.dir.path());
        let out = self.render("out", Some(1));
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        let show = format!(
            "status {:?}\n--- stdout\n{}\n--- stderr\n{stderr}",
            out.status,
            String::from_utf8_lossy(&out.stdout)
        );
        assert_eq!(out.status.code(), Some(code), "exit code\n{show}");
        assert!(!stderr.contains("panicked"), "a panic\n{show}");
        for s in stderr_has {
            assert!(stderr.contains(s), "expected {s:?} on stderr\n{show}");
        }
        let out_dir = self.path("out");
        assert!(
            !out_dir.exists() || files_in(&out_dir).is_empty(),
            "output left behind: {:?}\n{show}",
            files_in(&out_dir)
        );
        assert_eq!(
            files_in(self.dir.path()),
            before,
            "files appeared beside the inputs\n{show}"
        );
        stderr
    }
}

const INPUT: i32 = 3;
const IO: i32 = 4;
/// A scene beyond the core's capacities.
const CAPACITY: i32 = 5;

#[test]
fn the_tiny_scene_itself_renders() {
    let case = Case::new();
    case.write();
    let out = case.render("out", Some(1));
    assert!(
        out.status.success(),
        "stderr:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(case.path("out/front.exr").is_file());
}

#[test]
fn scene_unknown_key() {
    Case::new()
        .scene("exposure = 1.0", "exposure = 1.0\nexposre = 2.0")
        .fails(INPUT, &["scene.toml:14", "unknown key `exposre`"]);
}

#[test]
fn scene_wrong_format() {
    Case::new()
        .scene("format = 1", "format = 2")
        .fails(INPUT, &["scene.toml:1", "format 2 is not supported"]);
}

#[test]
fn scene_syntax_error() {
    Case::new()
        .scene("name = \"front\"", "name = \"front")
        .fails(INPUT, &["scene.toml:7"]);
}

#[test]
fn scene_missing_key() {
    Case::new()
        .scene("size = [4, 4]\n", "")
        .fails(INPUT, &["scene.toml:6", "missing key `size`"]);
}

#[test]
fn scene_negative_radiance() {
    Case::new()
        .scene(
            "radiance = [10.0, 10.0, 10.0]",
            "radiance = [10.0, -1.0, 10.0]",
        )
        .fails(
            INPUT,
            &["scene.toml:17", "light 'lamp'", "radiance must be >= 0"],
        );
}

#[test]
fn scene_non_finite_number() {
    Case::new()
        .scene("position = [0.5, -1.5, 0.5]", "position = [0.5, nan, 0.5]")
        .fails(INPUT, &["scene.toml:8", "`position`", "finite"]);
}

#[test]
fn scene_bad_fov_size_exposure() {
    Case::new()
        .scene("fov_deg = [90.0, 90.0]", "fov_deg = [90.0, 180.0]")
        .fails(INPUT, &["scene.toml:11", "fov_deg"]);
    Case::new()
        .scene("size = [4, 4]", "size = [0, 4]")
        .fails(INPUT, &["scene.toml:12", "size"]);
    Case::new()
        .scene("exposure = 1.0", "exposure = 0.0")
        .fails(INPUT, &["scene.toml:13", "exposure must be > 0"]);
}

#[test]
fn scene_duplicate_group() {
    Case::new()
        .scene("objects = [\"quad\"]\n", "objects = [\"quad\"]\n\n[[group]]\nname = \"floor\"\nkind = \"metal\"\nobjects = [\"x\"]\n")
        .fails(INPUT, &["scene.toml:25", "duplicate group name 'floor'"]);
}

/// View and group names name output files and RADIANCE primitives: a path or a space in
/// one would write outside `--out` or break materials.rad, and a group named `void` would
/// have no material there.
#[test]
fn scene_names_that_are_not_identifiers() {
    Case::new()
        .scene("name = \"front\"", "name = \"../escaped\"")
        .fails(
            INPUT,
            &["scene.toml:7", "view name \"../escaped\"", "output files"],
        );
    Case::new()
        .scene("name = \"floor\"", "name = \"my floor\"")
        .fails(INPUT, &["scene.toml:20", "group name \"my floor\""]);
    // A group's name is its material's modifier in materials.rad, where `void` is none.
    Case::new()
        .scene("name = \"floor\"", "name = \"void\"")
        .fails(
            INPUT,
            &[
                "scene.toml:20",
                "group name \"void\" is RADIANCE's word for no material",
            ],
        );
    Case::new()
        .materials("group = \"floor\"", "group = \"void\"")
        .fails(INPUT, &["m.toml", "group \"void\" is RADIANCE's word"]);
    // A name too long for the files it names (a recovery failed writing its map at the
    // end), and a materials file's group that no scene could have, told briefly.
    let long = "f".repeat(201);
    Case::new()
        .scene("name = \"floor\"", &format!("name = \"{long}\""))
        .fails(
            INPUT,
            &[
                "scene.toml:20",
                "group name is 201 bytes long, more than MAX_NAME_LEN 200",
            ],
        );
    let huge = format!("{}\\u0000", "x".repeat(100_000));
    let stderr = Case::new()
        .materials("group = \"floor\"", &format!("group = \"{huge}\""))
        .fails(INPUT, &["m.toml", "group is 100001 bytes long"]);
    assert!(stderr.len() < 1000, "{} bytes of stderr", stderr.len());
}

#[test]
fn scene_object_in_a_group_and_a_light() {
    Case::new()
        .scene("objects = [\"quad\"]", "objects = [\"quad\", \"lamp\"]")
        .fails(INPUT, &["scene.toml:22", "'lamp'", "also a light"]);
}

/// A light whose faces are all degenerate emits nothing: said, with the light and the
/// line where its object starts, rather than an all-black render whose warning could not
/// say why.
#[test]
fn a_light_without_area_is_named() {
    Case::new()
        .obj("f 5 7 6", "f 5 5 6")
        .fails(INPUT, &["geo.obj:11", "light 'lamp'", "no area"]);
}

/// Rays leave a surface 1e-4 of the scene's size off it: a floor 100,000 wide under a
/// lamp 0.6 across moved them past the lamp, and the view rendered black with a warning
/// that blamed the light. Said, with the light and the object that makes the scene large.
#[test]
fn a_scene_too_large_for_its_light_is_refused() {
    Case::new().obj("v 1 1 0\n", "v 1e5 1e5 0\n").fails(
        INPUT,
        &[
            "scene.toml",
            "spans 100000 units",
            "light 'lamp' (0.6 across)",
            "object 'quad' of",
        ],
    );
}

/// A lamp a million units long passes the light's test, but the rays' offset (100 units)
/// is still far larger than the view's distance to the floor.
#[test]
fn a_scene_too_large_for_its_views_is_refused() {
    Case::new().obj("v 0.5 0.8 1\n", "v 0.5 1e6 1\n").fails(
        INPUT,
        &[
            "scene.toml",
            "spans 1e6 units",
            "view 'front' sees the scene",
        ],
    );
}

/// More views than the core's MAX_VIEWS, which a caller on a small target sizes by.
#[test]
fn views_beyond_capacity_are_refused() {
    let view = SCENE
        .split("[[view]]")
        .nth(1)
        .and_then(|rest| rest.split("[[light]]").next())
        .unwrap()
        .to_string();
    let extra: String = (0..relume_core::config::MAX_VIEWS)
        .map(|i| {
            format!(
                "[[view]]{}",
                view.replace("\"front\"", &format!("\"v{i}\""))
            )
        })
        .collect();
    Case::new()
        .scene("[[light]]", &format!("{extra}[[light]]"))
        .fails(CAPACITY, &["scene.toml", "MAX_VIEWS is 64", "needs 65"]);
}

#[test]
fn scene_object_not_in_the_geometry() {
    Case::new()
        .scene("objects = [\"quad\"]", "objects = [\"quad\", \"chair\"]")
        .fails(
            INPUT,
            &["scene.toml:22", "object 'chair'", "not in the geometry"],
        );
}

#[test]
fn obj_object_in_no_group() {
    Case::new()
        .scene(
            "[[light]]\nobject = \"lamp\"\nradiance = [10.0, 10.0, 10.0]\n",
            "",
        )
        .fails(INPUT, &["geo.obj:11", "object 'lamp' is in no group"]);
}

#[test]
fn obj_missing_file() {
    Case::new()
        .scene("geometry = [\"geo.obj\"]", "geometry = [\"absent.obj\"]")
        .fails(INPUT, &["scene.toml:3", "absent.obj"]);
}

#[test]
fn obj_bad_vertex() {
    Case::new()
        .obj("v 1 0 0\n", "v 1 0\n")
        .fails(INPUT, &["geo.obj:3", "`v` needs 3 numbers"]);
    Case::new()
        .obj("v 1 0 0\n", "v 1 nan 0\n")
        .fails(INPUT, &["geo.obj:3", "non-finite"]);
}

#[test]
fn obj_bad_face() {
    Case::new()
        .obj("f 5 7 6", "f 5 7 9")
        .fails(INPUT, &["geo.obj:15", "vertex index 9 is out of range"]);
    Case::new()
        .obj("f 5 7 6", "f 5 7")
        .fails(INPUT, &["geo.obj:15", "at least 3 vertices"]);
    Case::new()
        .obj("o quad\n", "")
        .fails(INPUT, &["geo.obj:9", "face outside any object"]);
}

#[test]
fn obj_unknown_statement() {
    Case::new()
        .obj("o lamp\n", "o lamp\nbevel 1\n")
        .fails(INPUT, &["geo.obj:12", "unknown OBJ statement 'bevel'"]);
}

#[test]
fn obj_duplicate_object() {
    Case::new()
        .obj("o lamp", "o quad")
        .fails(INPUT, &["geo.obj:11", "object 'quad' appears twice"]);
}

#[test]
fn materials_unknown_model() {
    Case::new()
        .materials("model = \"diffuse\"", "model = \"velvet\"")
        .fails(INPUT, &["m.toml:5", "unknown model 'velvet'"]);
}

#[test]
fn materials_missing_and_forbidden_keys() {
    Case::new()
        .materials("color = [0.5, 0.5, 0.5]\n", "")
        .fails(INPUT, &["m.toml:3", "needs `color`"]);
    Case::new()
        .materials(
            "color = [0.5, 0.5, 0.5]\n",
            "color = [0.5, 0.5, 0.5]\nroughness_u = 0.1\n",
        )
        .fails(INPUT, &["m.toml:7", "takes no `roughness_u`"]);
}

#[test]
fn materials_out_of_range() {
    Case::new()
        .materials("color = [0.5, 0.5, 0.5]", "color = [0.5, 1.5, 0.5]")
        .fails(INPUT, &["m.toml:6", "color components must be in [0, 1]"]);
    Case::new()
        .materials(
            "model = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]",
            "model = \"isotropic\"\ncolor = [0.5, 0.5, 0.5]\nspecularity = 0.1\nroughness = 0.0",
        )
        .fails(INPUT, &["m.toml:8", "roughness must be in (0, 1]"]);
}

#[test]
fn materials_duplicate_group() {
    let two = format!("{MATERIALS}\n[[material]]\ngroup = \"floor\"\nmodel = \"mirror\"\ncolor = [1.0, 1.0, 1.0]\n");
    Case::new()
        .materials(MATERIALS, &two)
        .fails(INPUT, &["m.toml:9", "group 'floor' has a second material"]);
}

#[test]
fn materials_for_a_group_the_scene_lacks() {
    Case::new()
        .materials("group = \"floor\"", "group = \"flor\"")
        .fails(INPUT, &["m.toml", "flor"]);
}

#[test]
fn materials_missing_file() {
    Case::new().without("m.toml").fails(IO, &["m.toml"]);
}

#[test]
fn texture_with_a_nan_pixel() {
    let case = Case::new().materials(
        "model = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]",
        "model = \"textured-diffuse\"\ndiffuse_map = \"tex.exr\"",
    );
    // Written by the exr crate itself: relume writes no image with a NaN.
    exr::prelude::write_rgb_file(case.path("tex.exr"), 2, 2, |x, y| {
        let g = if (x, y) == (1, 0) { f32::NAN } else { 0.5 };
        (0.5f32, g, 0.5f32)
    })
    .unwrap();
    case.fails(INPUT, &["tex.exr", "pixel (x 1, y 0)", "channel G", "NaN"]);
}

/// A diffuse map holds reflectances: above 1 is as wrong as a `color` above 1.
#[test]
fn texture_above_one() {
    let case = Case::new().materials(
        "model = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]",
        "model = \"textured-diffuse\"\ndiffuse_map = \"tex.exr\"",
    );
    let pixels = vec![[0.5; 3], [0.5; 3], [0.5, 0.5, 5.0], [0.5; 3]];
    relume::images::write_exr(
        &case.path("tex.exr"),
        &relume::images::Image {
            width: 2,
            height: 2,
            pixels,
        },
    )
    .unwrap();
    case.fails(
        INPUT,
        &["tex.exr", "pixel (x 0, y 1)", "channel B", "above 1"],
    );
}

/// A map is read at the OBJ texture coordinates: a textured group needs them.
#[test]
fn texture_on_an_object_without_texture_coordinates() {
    let case = Case::new()
        .materials(
            "model = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]",
            "model = \"textured-diffuse\"\ndiffuse_map = \"tex.exr\"",
        )
        .obj("f 1/1 2/2 3/3 4/4", "f 1 2 3 4");
    relume::images::write_exr(
        &case.path("tex.exr"),
        &relume::images::Image {
            width: 2,
            height: 2,
            pixels: vec![[0.5; 3]; 4],
        },
    )
    .unwrap();
    case.fails(
        INPUT,
        &[
            "geo.obj:1",
            "object 'quad' of group 'floor' has no texture coordinates",
        ],
    );
}

#[test]
fn texture_missing() {
    Case::new()
        .materials(
            "model = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]",
            "model = \"textured-diffuse\"\ndiffuse_map = \"none.exr\"",
        )
        .fails(INPUT, &["m.toml:6", "none.exr does not exist"]);
}

#[test]
fn scene_file_missing() {
    Case::new().without("scene.toml").fails(IO, &["scene.toml"]);
}

/// A light that adds nothing is not an error, but the all-black result is said.
#[test]
fn a_scene_whose_light_adds_nothing_renders_black_with_a_warning() {
    let render = |case: &Case| {
        case.write();
        case.render("out", Some(64))
    };
    let case = Case::new().scene(
        "radiance = [10.0, 10.0, 10.0]",
        "radiance = [0.0, 0.0, 0.0]",
    );
    let out = render(&case);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("warning: every pixel is black"), "{stderr}");
    let json = std::fs::read_to_string(case.path("out/render.json")).unwrap();
    assert!(json.contains("every pixel is black"), "{json}");
    // The same scene lit: no warning (at 64 spp, its 16 pixels find the small quad and lamp).
    let out = render(&Case::new());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && !stderr.contains("warning"),
        "{stderr}"
    );
    // Lit, with a second view looking away from everything: that view is named.
    let away = Case::new().scene(
        "[[light]]",
        "[[view]]\nname = \"away\"\nposition = [0.5, -1.5, 0.5]\ndirection = [0.0, -1.0, 0.0]\nup = [0.0, 0.0, 1.0]\nfov_deg = [90.0, 90.0]\nsize = [4, 4]\n\n[[light]]",
    );
    let out = render(&away);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: view 'away': every pixel is black while other views are not")
            && !stderr.contains("view 'front'")
            && !stderr.contains("every pixel is black: no light"),
        "{stderr}"
    );
}

/// Views that look away from the whole scene (as a scene in other units than its views'
/// positions does) render black: the warning says they see no geometry rather than blame
/// the lights.
#[test]
fn views_that_see_no_geometry_render_black_and_say_so() {
    let case = Case::new().scene(
        "direction = [0.0, 1.0, 0.0]",
        "direction = [0.0, -1.0, 0.0]",
    );
    case.write();
    let out = case.render("out", Some(4));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: every pixel is black: the views of")
            && stderr.contains("see no geometry")
            && !stderr.contains("no light"),
        "{stderr}"
    );
}

/// An anisotropic direction along a flat group's normal has no projection on the surface:
/// the lobe renders isotropic there (reflectance.md), which the render says, naming the
/// group; a direction along the surface renders without a word.
#[test]
fn an_anisotropic_direction_along_the_normal_renders_isotropic_with_a_warning() {
    let anisotropic = |direction: &str| {
        let case = Case::new().materials(
            "model = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]\n",
            &format!(
                "model = \"anisotropic\"\ncolor = [0.5, 0.5, 0.5]\nspecularity = 0.2\nroughness_u = 0.05\nroughness_v = 0.2\ndirection_u = {direction}\n"
            ),
        );
        case.write();
        // At 64 spp the view's 16 pixels find the small quad and lamp (no black warning).
        let out = case.render("out", Some(64));
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{stderr}");
        stderr
    };
    let stderr = anisotropic("[0.0, 0.0, -2.0]");
    assert!(
        stderr.contains(
            "warning: group 'floor': its direction_u is parallel to the surface normal over 100% of its area"
        ),
        "{stderr}"
    );
    let stderr = anisotropic("[1.0, 0.0, 0.5]");
    assert!(!stderr.contains("warning"), "{stderr}");
}

/// A folder where one output file should go (here the last one written): the command fails
/// naming it, and writes none of its other outputs, so the folder never mixes two runs.
#[test]
fn a_folder_in_the_way_of_one_output_leaves_none_of_the_others() {
    let case = Case::new();
    std::fs::create_dir_all(case.path("out/render.json")).unwrap();
    let stderr = case.fails(IO, &["render.json", "folder"]);
    assert!(!case.path("out/front.exr").exists(), "{stderr}");

    // A recovery that runs to its end (the tiny scene's own view sees no group whole).
    let dir = lit_and_unlit(LIT_AND_UNLIT);
    let recovered = dir.path().join("recovered");
    std::fs::create_dir_all(recovered.join("report.json")).unwrap();
    let run = relume(
        dir.path(),
        &[
            "recover",
            "scene.toml",
            "--out",
            "recovered",
            "--effort",
            "fast",
        ],
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(IO), "{stderr}");
    assert!(
        stderr.contains("report.json") && !stderr.contains("panicked"),
        "{stderr}"
    );
    assert_eq!(files_in(&recovered), Vec::<PathBuf>::new());
}

/// The tiny scene with its own render (4 spp) as its panorama, for `recover`.
fn case_with_panorama() -> Case {
    case_with_panorama_in("panorama")
}

/// [`case_with_panorama`] with the panorama in `folder` (relative to the scene).
fn case_with_panorama_in(folder: &str) -> Case {
    let case = Case::new().scene(
        "name = \"front\"\n",
        &format!("name = \"front\"\nimage = \"{folder}/front.exr\"\n"),
    );
    case.write();
    assert!(case.render(folder, Some(4)).status.success());
    case
}

/// The error a recovery of the tiny scene meets only after it has traced its views: its
/// view sees the quad edge-on, so no pixel falls wholly on a group. An error of such a run
/// without it came before the work.
const LATE_ERROR: &str = "no view sees any group in whole pixels";

/// Runs `relume recover` of `case` into `out` (relative to the case) at effort fast, with
/// `extra` arguments. Returns the exit code and stderr.
fn recover_tiny(case: &Case, out: &str, extra: &[&str]) -> (Option<i32>, String) {
    let scene = case.path("scene.toml");
    let args = [
        "recover",
        path_str(&scene),
        "--out",
        out,
        "--effort",
        "fast",
    ];
    let run = relume(case.dir.path(), &[&args[..], extra].concat());
    (
        run.status.code(),
        String::from_utf8_lossy(&run.stderr).into_owned(),
    )
}

/// `--limit-group-pixels` naming a group the scene does not have fails with the scene
/// read, naming the scene file, the group and the groups it has; once it failed only after
/// the inspection's renders. Nothing is written.
#[test]
fn a_pixel_limit_on_a_group_the_scene_lacks_fails_before_the_work() {
    let case = case_with_panorama();
    let (code, stderr) = recover_tiny(&case, "rec", &[]);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(stderr.contains(LATE_ERROR), "{stderr}");
    let before = files_and_bytes(case.dir.path());
    let (code, stderr) = recover_tiny(&case, "rec", &["--limit-group-pixels", "nosuch=10"]);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("scene.toml: --limit-group-pixels names group 'nosuch', which the scene does not have (its groups: 'floor')")
            && !stderr.contains(LATE_ERROR),
        "{stderr}"
    );
    assert!(files_and_bytes(case.dir.path()) == before);
}

/// An output folder that cannot be made (under a file) fails at the start of a recovery,
/// before its minutes of work, naming the file in the way (bad input: once the system's
/// bare "Not a directory", an I/O error); nothing is written.
#[test]
fn a_recovery_whose_output_folder_cannot_be_made_fails_at_once() {
    let case = case_with_panorama();
    let (code, stderr) = recover_tiny(&case, "m.toml/recovered", &[]);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("m.toml: is a file, not a folder") && !stderr.contains(LATE_ERROR),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_to_string(case.path("m.toml")).unwrap(),
        MATERIALS
    );
}

/// Output folders that hold the run's own inputs: a recovery into the folder whose
/// `views/` is its panorama, a render into that `views/`, a downsampled scene into the
/// scene's folder. Each would have replaced an input (the recovery with its re-rendered
/// views, after its whole run); each fails at once with the input code, naming the file
/// and what it is, and leaves every file as it was.
#[test]
fn no_output_replaces_an_input_of_its_run() {
    let case = case_with_panorama_in("rec/views");
    let before = files_and_bytes(case.dir.path());
    let scene = case.path("scene.toml");
    let runs: [(Vec<&str>, &str, &str); 3] = [
        (
            vec![
                "recover",
                path_str(&scene),
                "--out",
                "rec",
                "--effort",
                "fast",
            ],
            "rec/views/front.exr",
            "the image of view 'front'",
        ),
        (
            vec![
                "render",
                path_str(&scene),
                "--materials",
                "m.toml",
                "--out",
                "rec/views",
            ],
            "rec/views/front.exr",
            "the image of view 'front'",
        ),
        (
            vec![
                "bench",
                "downsample",
                path_str(&scene),
                "--factor",
                "1",
                "--out",
                ".",
            ],
            "scene.toml",
            "the scene file",
        ),
    ];
    for (args, file, what) in runs {
        let run = relume(case.dir.path(), &args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(INPUT), "{args:?}: {stderr}");
        assert!(
            stderr.contains(file)
                && stderr.contains(&format!("would replace {what}, an input of this run")),
            "{args:?}: {stderr}"
        );
        assert!(
            !stderr.contains("panicked") && !stderr.contains(LATE_ERROR),
            "{stderr}"
        );
        assert!(
            files_and_bytes(case.dir.path()) == before,
            "{args:?} changed the files"
        );
    }
}

/// Which groups get a map is known only after a recovery, so a panorama image where a
/// group's map would go (`textures/<group>.exr`) was refused only after the whole run: now
/// every group's map files are checked before it (before [`LATE_ERROR`]).
#[test]
fn a_panorama_where_a_groups_map_would_go_is_refused_before_the_recovery() {
    let case = Case::new().scene(
        "name = \"front\"\n",
        "name = \"front\"\nimage = \"rec/textures/floor.exr\"\n",
    );
    case.write();
    assert!(case.render("rec/textures", Some(4)).status.success());
    std::fs::rename(
        case.path("rec/textures/front.exr"),
        case.path("rec/textures/floor.exr"),
    )
    .unwrap();
    let before = files_and_bytes(case.dir.path());
    let (code, stderr) = recover_tiny(&case, "rec", &[]);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("rec/textures/floor.exr")
            && stderr.contains("would replace the image of view 'front', an input of this run")
            && !stderr.contains(LATE_ERROR),
        "{stderr}"
    );
    assert!(files_and_bytes(case.dir.path()) == before);
}

/// A floor under a lamp, and a cellar under the floor that no light reaches, each seen by
/// its own view from above (the panorama: the scene's own render, `views/`).
const LIT_AND_UNLIT: &str = r#"format = 1
name = "cellar"
geometry = ["geo.obj"]
hide = []

[[view]]
name = "floor"
image = "views/floor.exr"
position = [0.5, 0.5, 0.9]
direction = [0.0, 0.0, -1.0]
up = [0.0, 1.0, 0.0]
fov_deg = [50.0, 50.0]
size = [8, 8]

[[view]]
name = "cellar"
image = "views/cellar.exr"
position = [0.5, 0.5, -0.1]
direction = [0.0, 0.0, -1.0]
up = [0.0, 1.0, 0.0]
fov_deg = [50.0, 50.0]
size = [8, 8]

[[light]]
object = "lamp"
radiance = [10.0, 10.0, 10.0]

[[group]]
name = "floor"
kind = "plastic"
objects = ["quad"]

[[group]]
name = "cellar"
kind = "plastic"
objects = ["cellar"]
"#;

/// A fresh folder with LIT_AND_UNLIT's geometry (the tiny scene and the cellar), its
/// materials in m.toml, `scene` as scene.toml and that scene's own render (4 spp) in
/// `views/`, its panorama.
fn lit_and_unlit(scene: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let obj = format!(
        "{}o cellar\nv 0 0 -1\nv 1 0 -1\nv 1 1 -1\nv 0 1 -1\nf 8 9 10 11\n",
        OBJ
    );
    std::fs::write(dir.path().join("geo.obj"), obj).unwrap();
    std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
    let materials = format!("{MATERIALS}\n[[material]]\ngroup = \"cellar\"\nmodel = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]\n");
    std::fs::write(dir.path().join("m.toml"), materials).unwrap();
    common::relume_ok(
        dir.path(),
        &[
            "render",
            "scene.toml",
            "--materials",
            "m.toml",
            "--out",
            "views",
            "--spp",
            "4",
        ],
    );
    dir
}

/// LIT_AND_UNLIT with its lamp hidden and no light declared: nothing lights what the
/// views see.
fn without_light() -> String {
    LIT_AND_UNLIT
        .replace("hide = []", "hide = [\"lamp\"]")
        .replace(
            "[[light]]\nobject = \"lamp\"\nradiance = [10.0, 10.0, 10.0]\n",
            "",
        )
}

/// A group no light reaches renders black whatever its material: recovery says so and
/// leaves it unrecovered (it kept its starting colour, 0.5, as a "diffuse" result with
/// an error of 100%), and recovers the rest. With the lamp hidden too, no group is lit
/// and recovery refuses the scene rather than write a file of starting colours.
#[test]
fn a_group_no_light_reaches_is_not_recovered_and_a_scene_without_light_is_refused() {
    let dir = lit_and_unlit(LIT_AND_UNLIT);
    let run = common::relume_ok(
        dir.path(),
        &["recover", "scene.toml", "--out", "rec", "--effort", "fast"],
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("group 'cellar': no light of the scene reaches it")
            && stderr.contains("its material is not recovered"),
        "{stderr}"
    );
    let recovered = std::fs::read_to_string(dir.path().join("rec/materials.toml")).unwrap();
    assert!(
        recovered.contains("group = \"floor\"") && !recovered.contains("group = \"cellar\""),
        "{recovered}"
    );
    // The recovered model against its own panorama (the scene as an edit): without the
    // cellar's stand-in, unseen.toml, the groups do not add up and the error says where
    // the missing one is; with it the bench runs.
    let edits = |recovered: &[&str]| {
        let mut args = vec!["bench", "edits", "scene.toml", "--recovered"];
        args.extend(recovered);
        args.extend(["--truth", "m.toml", "--out", "edits", "--spp", "4"]);
        relume(dir.path(), &args)
    };
    let run = edits(&["rec/materials.toml"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("only in the edit: 'cellar'")
            && stderr.contains("has its stand-in in rec/unseen.toml: give it to --recovered too"),
        "{stderr}"
    );
    let run = edits(&["rec/materials.toml", "./rec/materials.toml"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("./rec/materials.toml is given twice to --recovered"),
        "{stderr}"
    );
    let run = edits(&["rec/materials.toml", "rec/unseen.toml"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(dir.path().join("edits/edits.csv").is_file());

    std::fs::write(dir.path().join("scene.toml"), without_light()).unwrap();
    let run = relume(
        dir.path(),
        &["recover", "scene.toml", "--out", "dark", "--effort", "fast"],
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("scene.toml: no light of the scene reaches what its views see"),
        "{stderr}"
    );
    assert!(!dir.path().join("dark").exists());
}

/// A lit group whose pixels are all 0 in the panorama is a black surface: recovery gives
/// it a black diffuse colour and says so (its relative error is undefined: it was called
/// unseen, "no pure pixel in any view", and left out of materials.toml). A panorama that is
/// 0 over every lit group is refused: an image or exposure gone wrong, not a black room.
#[test]
fn a_group_black_in_the_panorama_is_black_diffuse_and_a_black_panorama_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    // The floor's quad in two halves, each its own group, under the lamp.
    let obj = "o left\nv 0 0 0\nv 0.5 0 0\nv 0.5 1 0\nv 0 1 0\nf 1 2 3 4\no right\nv 0.5 0 0\nv 1 0 0\nv 1 1 0\nv 0.5 1 0\nf 5 6 7 8\no lamp\nv 0.2 0.2 1\nv 0.8 0.2 1\nv 0.5 0.8 1\nf 9 11 10\n";
    std::fs::write(dir.path().join("geo.obj"), obj).unwrap();
    let scene = LIT_AND_UNLIT
        .split("[[view]]\nname = \"cellar\"")
        .next()
        .unwrap()
        .to_string()
        + "[[light]]\nobject = \"lamp\"\nradiance = [10.0, 10.0, 10.0]\n\n[[group]]\nname = \"left\"\nkind = \"plastic\"\nobjects = [\"left\"]\n\n[[group]]\nname = \"right\"\nkind = \"plastic\"\nobjects = [\"right\"]\n";
    std::fs::write(dir.path().join("scene.toml"), &scene).unwrap();
    let material = |group: &str, grey: f32| {
        format!("[[material]]\ngroup = \"{group}\"\nmodel = \"diffuse\"\ncolor = [{grey}, {grey}, {grey}]\n\n")
    };
    let recover = |left: f32, right: f32| {
        let materials = format!(
            "format = 1\n\n{}{}",
            material("left", left),
            material("right", right)
        );
        std::fs::write(dir.path().join("m.toml"), materials).unwrap();
        let render = [
            "render",
            "scene.toml",
            "--materials",
            "m.toml",
            "--out",
            "views",
            "--spp",
            "16",
        ];
        // A render may not replace its scene's panorama: the last one goes first.
        let _ = std::fs::remove_dir_all(dir.path().join("views"));
        common::relume_ok(dir.path(), &render);
        let _ = std::fs::remove_dir_all(dir.path().join("rec"));
        relume(
            dir.path(),
            &["recover", "scene.toml", "--out", "rec", "--effort", "fast"],
        )
    };

    let run = recover(0.5, 0.0);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(
        stderr.contains("group 'right': its")
            && stderr.contains("pure pixels are 0 in the panorama, though light reaches them: recovered as black diffuse")
            && !stderr.contains("no pure pixel"),
        "{stderr}"
    );
    let recovered = materials_file(&dir.path().join("rec/materials.toml"));
    assert_eq!(recovered["right"], ("diffuse".to_string(), [0.0; 3]));
    let (model, left) = &recovered["left"];
    assert_eq!(model, "diffuse");
    assert!(left.iter().all(|c| (c - 0.5).abs() < 0.05), "{left:?}");

    let run = recover(0.0, 0.0);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("scene.toml: the panorama is 0 over every group's pure pixels, though the scene's light reaches them"),
        "{stderr}"
    );
    assert!(!dir.path().join("rec").exists());
}

/// Each material of a materials.toml by group: its model and colour.
fn materials_file(path: &Path) -> std::collections::HashMap<String, (String, [f64; 3])> {
    let text = std::fs::read_to_string(path).unwrap();
    let file: toml::Value = toml::from_str(&text).unwrap();
    file["material"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            let colour: Vec<f64> = m["color"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| c.as_float().unwrap())
                .collect();
            (
                m["group"].as_str().unwrap().to_string(),
                (
                    m["model"].as_str().unwrap().to_string(),
                    [colour[0], colour[1], colour[2]],
                ),
            )
        })
        .collect()
}

/// Views that see no group in whole pixels (one looks up at the lamp, one down into the
/// void below the cellar): there is nothing to recover. Recovery ran on and wrote an
/// empty materials.toml with exit 0; it now refuses the scene, says what each view's
/// pixels see, and writes nothing.
/// LIT_AND_UNLIT with one view looking up at the lamp and one into the void below the
/// cellar: no pixel of either falls wholly on a group.
fn looking_away() -> String {
    LIT_AND_UNLIT
        .replacen(
            "direction = [0.0, 0.0, -1.0]",
            "direction = [0.0, 0.0, 1.0]",
            1,
        )
        .replace("position = [0.5, 0.5, 0.9]", "position = [0.5, 0.5, 0.5]")
        .replace("position = [0.5, 0.5, -0.1]", "position = [0.5, 0.5, -1.5]")
}

#[test]
fn a_panorama_that_sees_no_group_whole_is_refused() {
    let dir = lit_and_unlit(&looking_away());
    let run = relume(
        dir.path(),
        &["recover", "scene.toml", "--out", "rec", "--effort", "fast"],
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("scene.toml: no view sees any group in whole pixels")
            && stderr.contains(
                "view 'cellar', 8x8 pixels: 64 see nothing, 0 only lights, 0 a group in part"
            )
            && !stderr.contains("panicked"),
        "{stderr}"
    );
    // The view looking up sees the lamp's emitting side in some pixels and the void around it.
    let floor = stderr
        .split("view 'floor', 8x8 pixels: ")
        .nth(1)
        .and_then(|rest| rest.split(';').next())
        .unwrap_or_else(|| panic!("{stderr}"));
    let counts: Vec<u32> = floor
        .split(", ")
        .map(|part| part.split(' ').next().unwrap().parse().unwrap())
        .collect();
    assert!(
        counts.len() == 3 && counts[0] > 0 && counts[1] > 0 && counts[2] == 0,
        "{floor}"
    );
    assert_eq!(counts.iter().sum::<u32>(), 64, "{floor}");
    assert!(!dir.path().join("rec").exists());
}

/// A bench's derived scene (views box-averaged, say) that recovery refuses is judged as a
/// recovery of nothing, every group of the truth wrong, the refusal its warning: the point
/// goes into the chart instead of stopping the bench. The scene a bench was given is not
/// excused.
#[test]
fn a_derived_scene_that_recovery_refuses_is_judged_as_nothing_recovered() {
    let dir = lit_and_unlit(&looking_away());
    let args = |out: &str| relume::recover::RecoverArgs {
        scene: dir.path().join("scene.toml"),
        out: dir.path().join(out),
        seed: 1,
        threads: Some(1),
        budget: relume::recover::Effort::Fast.budget(),
        limit_group_pixels: None,
        tell_input_warnings: false,
    };
    let truth = dir.path().join("m.toml");
    let judged = relume::bench::recover_derived_and_judge(&args("derived"), &truth).unwrap();
    let groups: Vec<(&str, bool, Option<&String>)> = judged
        .groups
        .iter()
        .map(|g| (g.group.as_str(), g.class_ok, g.model.as_ref()))
        .collect();
    assert_eq!(groups, [("floor", false, None), ("cellar", false, None)]);
    let summary = judged.summary();
    assert_eq!((summary.groups, summary.classes_right), (2, 0));
    assert_eq!(summary.param_err, None);
    assert_eq!(judged.warnings.len(), 1);
    assert!(
        judged.warnings[0].starts_with("recovery refused: no view sees any group in whole pixels"),
        "{:?}",
        judged.warnings
    );
    assert!(!dir.path().join("derived").exists());
    let given = relume::bench::recover_and_judge(&args("given"), &truth);
    assert!(
        matches!(&given, Err(relume::error::Error::Input { message, .. }) if message.starts_with("no view sees any group")),
        "{:?}",
        given.err()
    );
}

/// `relume compare uncertainty m.toml <report>` in the case's folder: exit code, stderr.
fn compare_uncertainty(case: &Case, report: &Path) -> (Option<i32>, String) {
    let out = relume(
        case.dir.path(),
        &[
            "compare",
            "uncertainty",
            path_str(&case.path("m.toml")),
            path_str(report),
        ],
    );
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn uncertainty_of_a_file_that_is_not_a_report() {
    let case = Case::new();
    case.write();
    let not_a_report = case.path("report.json");
    std::fs::write(&not_a_report, "{\"groups\": 3}").unwrap();
    let (code, stderr) = compare_uncertainty(&case, &not_a_report);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("report.json")
            && stderr.contains("not a recover report.json")
            && !stderr.contains("panicked"),
        "{stderr}"
    );
}

/// A report whose groups, models, parameters, values or sigmas a recovery never writes
/// would be judged wrongly (a sigma of -1 gave a z of its own sign; an unknown group or
/// model was dropped; a parameter given twice counted twice, as did a copy of the report).
#[test]
fn uncertainty_of_a_report_that_does_not_fit_the_truth() {
    let case = Case::new();
    case.write();
    let report = case.path("report.json");
    let group = |name: &str, parameter: &str, sigma: &str| {
        format!(
            "{{\"group\": \"{name}\", \"model\": \"diffuse\", \"uncertainty\": [{{\"parameter\": \"{parameter}\", \"value\": 0.5, \"sigma\": {sigma}}}]}}"
        )
    };
    for (groups, expected) in [
        (group("floor", "color_r", "-1.0"), "sigma -1"),
        (
            group("floor", "colour_r", "0.01"),
            "unknown parameter 'colour_r'",
        ),
        (
            group("sofa", "color_r", "0.01"),
            "only in this file: 'sofa'; only in the truth: 'floor' (a report of another scene?)",
        ),
        (
            format!(
                "{}, {}",
                group("floor", "color_r", "0.01"),
                group("floor", "color_g", "0.01")
            ),
            "group 'floor' appears twice",
        ),
        // Values no recovery writes, each accepted in silence before.
        (
            group("floor", "color_r", "0.01").replace("diffuse", "glass"),
            "unknown model 'glass'",
        ),
        (
            r#"{"group": "floor", "model": "diffuse"}"#.to_string(),
            "missing field `uncertainty`",
        ),
        (
            group("floor", "roughness", "0.01"),
            "model 'diffuse' has no parameter 'roughness'",
        ),
        (
            group("floor", "color_r", "0.01").replace(
                "}]",
                r#"}, {"parameter": "color_r", "value": 0.9, "sigma": 0.01}]"#,
            ),
            "parameter 'color_r' is given twice",
        ),
        (
            group("floor", "color_r", "0.01").replace("0.5", "-0.5"),
            "value -0.5 and sigma 0.01: a value in [0, 1]",
        ),
        (
            group("floor", "color_r", "0.01").replace("0.5", "1e300"),
            "has value 1e300 and sigma 0.01: a value in [0, 1]",
        ),
    ] {
        std::fs::write(&report, format!("{{\"groups\": [{groups}]}}")).unwrap();
        let (code, stderr) = compare_uncertainty(&case, &report);
        assert_eq!(code, Some(INPUT), "{stderr}");
        assert!(
            stderr.contains("report.json") && stderr.contains(expected),
            "{expected}: {stderr}"
        );
    }
    // The well-formed report is read: every parameter of the model.
    let whole = group("floor", "color_r", "0.01").replace(
        "}]",
        r#"}, {"parameter": "color_g", "value": 0.5, "sigma": 0.01}, {"parameter": "color_b", "value": 0.5, "sigma": 0.01}]"#,
    );
    std::fs::write(&report, format!("{{\"groups\": [{whole}]}}")).unwrap();
    let (code, stderr) = compare_uncertainty(&case, &report);
    assert_eq!(code, Some(0), "{stderr}");
    // A copy of it under another name would be pooled as a second run.
    let copy = case.path("copy.json");
    std::fs::copy(&report, &copy).unwrap();
    let out = relume(
        case.dir.path(),
        &[
            "compare",
            "uncertainty",
            "m.toml",
            "report.json",
            "copy.json",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("copy.json: holds the same bytes as report.json"),
        "{stderr}"
    );
}

/// Runs a render of `case` at a million samples per pixel, sends it SIGINT once relume
/// catches the signal and `ready` holds, and returns what it printed, having checked that
/// it said it was interrupted, exited with 130 rather than dying on the signal, and left
/// no output in `out` (nor a hidden temp file beside the inputs).
#[cfg(target_os = "linux")]
fn interrupt_render(case: &Case, ready: impl Fn() -> bool) -> String {
    case.write();
    let out = case.path("out");
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_relume"))
        .args([
            "render",
            "scene.toml",
            "--materials",
            "m.toml",
            "--out",
            "out",
        ])
        .args(["--spp", "1000000", "--threads", "1"])
        .current_dir(case.dir.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until relume catches SIGINT (bit 1 of SigCgt), so the signal meets the handler
    // and not the default action.
    let catches_sigint = || {
        let status =
            std::fs::read_to_string(format!("/proc/{}/status", child.id())).unwrap_or_default();
        status
            .lines()
            .find_map(|l| l.strip_prefix("SigCgt:"))
            .and_then(|mask| u64::from_str_radix(mask.trim(), 16).ok())
            .is_some_and(|mask| mask & (1 << (libc::SIGINT - 1)) != 0)
    };
    let start = std::time::Instant::now();
    while !(catches_sigint() && ready()) {
        assert!(
            start.elapsed().as_secs() < 120,
            "relume never got ready to be interrupted"
        );
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    // SAFETY: a plain kill(2) of our own child process.
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGINT) }, 0);
    let result = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr).into_owned();
    assert_eq!(result.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains("interrupted") && !stderr.contains("panicked"),
        "{stderr}"
    );
    assert!(
        !out.exists(),
        "an interrupted render wrote {}",
        out.display()
    );
    let left: Vec<_> = std::fs::read_dir(case.dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n.to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(left.is_empty(), "temp files left: {left:?}");
    stderr
}

/// Ctrl-C during a long render, before any output is staged.
#[cfg(target_os = "linux")]
#[test]
fn an_interrupted_render_exits_130_and_writes_nothing() {
    let case = Case::new().scene("size = [4, 4]", "size = [64, 64]");
    let stderr = interrupt_render(&case, || true);
    assert!(stderr.contains("0 unfinished output file(s)"), "{stderr}");
}

/// Ctrl-C while the second view renders: the first view's files, staged as soon as it was
/// rendered so as not to hold every view's pixels at once, and the output folder made for
/// them go too.
#[cfg(target_os = "linux")]
#[test]
fn an_interrupt_after_a_view_was_staged_removes_its_files_and_folder() {
    let second_view = "exposure = 1.0

[[view]]
name = \"back\"
position = [0.5, 2.5, 0.5]
direction = [0.0, -1.0, 0.0]
up = [0.0, 0.0, 1.0]
fov_deg = [90.0, 90.0]
size = [64, 64]
exposure = 1.0
";
    let case = Case::new()
        .scene("size = [4, 4]", "size = [1, 1]")
        .scene("exposure = 1.0\n", second_view);
    let out = case.path("out");
    let front_staged = || {
        std::fs::read_dir(&out).is_ok_and(|entries| {
            entries.filter_map(|e| e.ok()).any(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with(".front.png.tmp-")
            })
        })
    };
    let stderr = interrupt_render(&case, front_staged);
    assert!(stderr.contains("2 unfinished output file(s)"), "{stderr}");
}

/// A --size far past the capture's texels is warned of before the work, as recover tells
/// its input's: the warning came only once the faces were written (minutes and gigabytes
/// for --size 16384 of a 64x32 capture), and not at all from a run that failed before.
#[test]
fn a_split_finer_than_its_capture_is_warned_of_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let capture = dir.path().join("capture.exr");
    relume::images::write_exr(
        &capture,
        &relume::images::Image {
            width: 16,
            height: 8,
            pixels: vec![[0.5; 3]; 128],
        },
    )
    .unwrap();
    // Its faces' folder under a file: the run fails as it writes, after its checks.
    std::fs::write(dir.path().join("taken"), "a file").unwrap();
    let run = relume(
        dir.path(),
        &[
            "panorama",
            "split",
            path_str(&capture),
            "--position",
            "0,0,1",
            "--size",
            "64",
            "--out",
            "taken/faces",
        ],
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(INPUT), "{stderr}");
    let warned = stderr
        .find("relume: warning: ")
        .unwrap_or_else(|| panic!("no warning: {stderr}"));
    assert!(
        stderr[warned..].contains("capture.exr holds 0.06 texels across a face pixel")
            && stderr.contains("taken: is a file"),
        "{stderr}"
    );
    assert!(warned < stderr.find("relume: error").unwrap(), "{stderr}");
}

/// `relume panorama`'s bad input: an image not twice as wide as high is bad input naming
/// it and its size; a zero or oversized face, an up along the forward direction or a
/// position that is not three numbers is a usage error; an output over the image is
/// refused. None writes anything.
#[test]
fn a_panorama_of_the_wrong_shape_or_frame_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let image = |name: &str, w: u32, h: u32| {
        let path = dir.path().join(name);
        relume::images::write_exr(
            &path,
            &relume::images::Image {
                width: w,
                height: h,
                pixels: vec![[0.5; 3]; (w * h) as usize],
            },
        )
        .unwrap();
        path
    };
    let square = image("square.exr", 16, 16);
    let good = image("good.exr", 32, 16);
    let split = |image: &Path, extra: &[&str]| {
        let mut args = vec![
            "panorama",
            "split",
            path_str(image),
            "--position",
            "0,0,1",
            "--out",
            "out",
        ];
        args.extend_from_slice(extra);
        let run = relume(dir.path(), &args);
        (
            run.status.code(),
            String::from_utf8_lossy(&run.stderr).to_string(),
        )
    };
    let (code, stderr) = split(&square, &[]);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr
            .contains("square.exr: is 16x16: an equirectangular panorama is twice as wide as high"),
        "{stderr}"
    );
    for extra in [
        &["--size", "0"][..],
        &["--size", "100000"],
        &["--up", "1,0,0"],
        &["--forward", "0,0,0"],
        &["--position", "1,2"],
        &["--position", "nan,0,0"],
    ] {
        let (code, stderr) = split(&good, extra);
        assert_eq!(code, Some(2), "{extra:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    // Split into the folder where its front face would go.
    let split_into_itself = || {
        let args = [
            "panorama",
            "split",
            "views/front.exr",
            "--position",
            "0,0,1",
            "--out",
            ".",
        ];
        relume(dir.path(), &args)
    };
    assert_eq!(
        split_into_itself().status.code(),
        Some(IO),
        "a missing image is named"
    );
    std::fs::create_dir(dir.path().join("views")).unwrap();
    std::fs::copy(&good, dir.path().join("views/front.exr")).unwrap();
    let run = split_into_itself();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(INPUT), "{stderr}");
    assert!(stderr.contains("would replace the panorama"), "{stderr}");
    assert!(!dir.path().join("out").exists() && !dir.path().join("views.toml").exists());
    // Nor over the scene given as the template.
    common::copy_cornell(&dir.path().join("room"));
    let args = [
        "panorama",
        "split",
        "good.exr",
        "--position",
        "0,0,1",
        "--scene",
        "room/scene.toml",
        "--out",
        "room",
    ];
    let run = relume(dir.path(), &args);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(INPUT), "{stderr}");
    assert!(stderr.contains("would replace the scene file"), "{stderr}");
    assert!(!dir.path().join("room/views.toml").exists());
    // Without --position, the template's views give it, when they are all at one place.
    let run = relume(
        dir.path(),
        &["panorama", "split", "good.exr", "--out", "nowhere"],
    );
    assert_eq!(run.status.code(), Some(2));
    let insert = common::workspace().join("scenes/cornell-insert/insert.toml");
    let args = [
        "panorama",
        "split",
        "good.exr",
        "--scene",
        path_str(&insert),
        "--out",
        "apart",
    ];
    let run = relume(dir.path(), &args);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("a panorama is seen from one position"),
        "{stderr}"
    );
    let args = [
        "panorama",
        "split",
        "good.exr",
        "--scene",
        "room/scene.toml",
        "--out",
        "placed",
    ];
    common::relume_ok(dir.path(), &args);
    let views = std::fs::read_to_string(dir.path().join("placed/views.toml")).unwrap();
    assert_eq!(
        views.matches("position = [1.5, 0.9, 1.3]").count(),
        6,
        "{views}"
    );
    assert!(!dir.path().join("nowhere").exists() && !dir.path().join("apart").exists());
    // The good image at last, split into faces of 8x8: written, and warned of as finer
    // than the capture (32 / (4 x 8) = 1 texel across a face pixel, under the floor of 2).
    let run = relume(
        dir.path(),
        &[
            "panorama",
            "split",
            path_str(&good),
            "--position",
            "0,0,1",
            "--out",
            "out",
            "--size",
            "8",
        ],
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("holds 1.00 texels across a face pixel")
            && stderr.contains("a --size of 4 or less"),
        "{stderr}"
    );
    assert_eq!(common::files_in(&dir.path().join("out")).len(), 7);
}

/// `relume panorama split`'s capture and template are checked as the scene they make
/// will be: a texel past the largest radiance is refused naming the capture's pixel (not
/// the face it would land in, when `check` read it), a capture all 0 is warned of, a
/// template whose OBJ is bad is refused before a face is written, and a position beyond
/// 32-bit floats is a usage error. A split without a template into the folder of one with
/// it removes that run's scene.toml, which would have read the new faces at the old size.
#[test]
fn a_splits_capture_and_template_are_checked_and_no_earlier_scene_is_left() {
    let dir = tempfile::tempdir().unwrap();
    let image = |name: &str, value: f32| {
        let path = dir.path().join(name);
        let mut pixels = vec![[0.5; 3]; 32 * 16];
        // One texel of `value`, at column 5 of the last row.
        pixels[15 * 32 + 5] = [value; 3];
        relume::images::write_exr(
            &path,
            &relume::images::Image {
                width: 32,
                height: 16,
                pixels,
            },
        )
        .unwrap();
        path
    };
    let split = |image: &Path, extra: &[&str]| {
        let mut args = vec!["panorama", "split", path_str(image), "--out", "out"];
        args.extend_from_slice(extra);
        let run = relume(dir.path(), &args);
        (
            run.status.code(),
            String::from_utf8_lossy(&run.stderr).to_string(),
        )
    };
    let at = ["--position", "1.5,0.9,1.3", "--size", "4"];
    let (code, stderr) = split(&image("bright.exr", 1e30), &at);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("bright.exr: pixel (x 5, y 15): channel R value 1e30")
            && stderr.contains("above the largest radiance relume computes with, 1e18"),
        "{stderr}"
    );
    let (code, stderr) = split(&image("good.exr", 0.5), &["--position", "1e39,0,0"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("out of range for 32-bit floats"),
        "{stderr}"
    );
    common::copy_cornell(&dir.path().join("room"));
    let obj = dir.path().join("room/geometry.obj");
    let mut text = std::fs::read_to_string(&obj).unwrap();
    text.push_str("f 1 2 99999\n");
    std::fs::write(dir.path().join("room/broken.obj"), text).unwrap();
    let scene = std::fs::read_to_string(dir.path().join("room/scene.toml")).unwrap();
    std::fs::write(
        dir.path().join("room/broken.toml"),
        scene.replace("\"geometry.obj\"", "\"broken.obj\""),
    )
    .unwrap();
    let (code, stderr) = split(&image("good.exr", 0.5), &["--scene", "room/broken.toml"]);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(stderr.contains("broken.obj:"), "{stderr}");
    assert!(!dir.path().join("out").exists(), "nothing written");
    // A split with the template, then one without it into the same folder.
    let good = image("good.exr", 0.5);
    let (code, stderr) = split(&good, &["--scene", "room/scene.toml", "--size", "8"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(dir.path().join("out/scene.toml").is_file());
    let (code, stderr) = split(&good, &at);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        !dir.path().join("out/scene.toml").exists(),
        "the earlier scene"
    );
    // A template with no `[[view]]`: its views are replaced anyway, so it is taken, with
    // --position; without it, the position is asked for.
    let skeleton = scene
        .split("[[view]]")
        .enumerate()
        .map(|(i, part)| match i {
            0 => part.to_string(),
            // Each view table runs to the next table: keep what follows the view's keys.
            _ => part
                .split_once("\n\n[")
                .map_or(String::new(), |(_, rest)| format!("\n\n[{rest}")),
        })
        .collect::<String>();
    assert!(!skeleton.contains("[[view]]") && skeleton.contains("[[group]]"));
    std::fs::write(dir.path().join("room/skeleton.toml"), &skeleton).unwrap();
    let (code, stderr) = split(
        &good,
        &[
            "--scene",
            "room/skeleton.toml",
            "--position",
            "1.5,0.9,1.3",
            "--size",
            "4",
        ],
    );
    assert_eq!(code, Some(0), "{stderr}");
    let made = std::fs::read_to_string(dir.path().join("out/scene.toml")).unwrap();
    assert_eq!(made.matches("[[view]]").count(), 6, "{made}");
    let (code, stderr) = split(&good, &["--scene", "room/skeleton.toml", "--size", "4"]);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains(
            "skeleton.toml: has no view to take the panorama's position from: give --position"
        ),
        "{stderr}"
    );
    let (code, stderr) = split(&image("one-zero.exr", 0.0), &at);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        !stderr.contains("every texel is 0"),
        "one texel of 0 is no black capture"
    );
    let black = dir.path().join("all-black.exr");
    relume::images::write_exr(
        &black,
        &relume::images::Image {
            width: 32,
            height: 16,
            pixels: vec![[0.0; 3]; 32 * 16],
        },
    )
    .unwrap();
    let (code, stderr) = split(&black, &at);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("all-black.exr: every texel is 0: the faces are black"),
        "{stderr}"
    );
}

/// `relume panorama join`'s bad input: views at two positions (the insertion example's
/// new viewpoint beside the cube) and a view image missing are refused naming them; views
/// that leave a direction unseen (the cube without its floor face) name the direction.
#[test]
fn a_join_of_views_that_are_no_panorama_is_refused() {
    let root = common::workspace();
    let dir = tempfile::tempdir().unwrap();
    let join = |scene: &Path, images: &Path, out: &str| {
        let run = relume(
            dir.path(),
            &[
                "panorama",
                "join",
                path_str(scene),
                path_str(images),
                "--out",
                out,
            ],
        );
        (
            run.status.code(),
            String::from_utf8_lossy(&run.stderr).to_string(),
        )
    };
    let views = root.join("scenes/cornell/views");
    let (code, stderr) = join(
        &root.join("scenes/cornell-insert/insert.toml"),
        &views,
        "made/pano.exr",
    );
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("view 'front' at [1.6, 0.25, 0.85]") && stderr.contains("one position"),
        "{stderr}"
    );
    let cornell = root.join("scenes/cornell/scene.toml");
    let (code, stderr) = join(&cornell, dir.path(), "made/pano.exr");
    assert_eq!(code, Some(IO), "{stderr}");
    assert!(stderr.contains("px.exr"), "{stderr}");
    // Without its nz face the cube does not see straight down.
    let text = std::fs::read_to_string(&cornell).unwrap();
    let nz = text.find("[[view]]\nname = \"nz\"").unwrap();
    let end = nz + text[nz..].find("[[light]]").unwrap();
    let scene = dir.path().join("five.toml");
    std::fs::write(
        &scene,
        format!("{}{}", &text[..nz], &text[end..]).replace(
            "geometry = [\"geometry.obj\"]",
            &format!(
                "geometry = [\"{}\"]",
                root.join("scenes/cornell/geometry.obj").display()
            ),
        ),
    )
    .unwrap();
    let (code, stderr) = join(&scene, &views, "made/pano.exr");
    assert_eq!(code, Some(INPUT), "{stderr}");
    let seen: Vec<f32> = stderr
        .split("no view sees the direction [")
        .nth(1)
        .and_then(|rest| rest.split(']').next())
        .unwrap_or_else(|| panic!("{stderr}"))
        .split(", ")
        .map(|n| n.parse().unwrap())
        .collect();
    assert!(
        seen.len() == 3 && seen[2] < -0.5,
        "below the cube's sides: {stderr}"
    );
    assert!(
        !dir.path().join("made").exists(),
        "a refused join leaves no folder"
    );
    // The whole cube joins, into a folder it makes.
    let (code, stderr) = join(&cornell, &views, "made/pano.exr");
    assert_eq!(code, Some(0), "{stderr}");
    let pano = relume::images::read_image(&dir.path().join("made/pano.exr"), 1.0).unwrap();
    assert_eq!((pano.width, pano.height), (128, 64));
    let preview = image::open(dir.path().join("made/pano.png")).unwrap();
    assert_eq!((preview.width(), preview.height()), (128, 64));
    // Only as EXR.
    assert_eq!(join(&cornell, &views, "pano.hdr").0, Some(2));
    assert!(!dir.path().join("pano.hdr").exists());
}

/// Views a unit apart in a room 3 across are at two positions wherever the room is: moved
/// 270 km from its origin, join took them for one (within 1e-5 of their distance from the
/// origin, 2.7 units) and split --scene split the capture at the first view's position.
#[test]
fn views_apart_in_a_scene_far_from_its_origin_are_not_one_position() {
    let root = common::workspace();
    let cornell = root.join("scenes/cornell");
    let dir = tempfile::tempdir().unwrap();
    let offset = [1e5f64, -2.5e5, 3e4];
    let moved =
        |numbers: &str, dx: f64| common::shifted(numbers, [offset[0] + dx, offset[1], offset[2]]);
    let obj = std::fs::read_to_string(cornell.join("geometry.obj")).unwrap();
    std::fs::write(
        dir.path().join("geometry.obj"),
        common::shifted_obj(&obj, offset),
    )
    .unwrap();
    let text = std::fs::read_to_string(cornell.join("scene.toml")).unwrap();
    let write_scene = |name: &str, px_dx: f64| -> std::path::PathBuf {
        let mut first = true;
        let lines: Vec<String> = text
            .lines()
            .map(|l| match l.strip_prefix("position = [") {
                Some(rest) => {
                    // The first view, px, moved by px_dx along x.
                    let dx = if std::mem::take(&mut first) {
                        px_dx
                    } else {
                        0.0
                    };
                    format!("position = [{}]", moved(rest.trim_end_matches(']'), dx))
                }
                None => l.replace("\"views/", &format!("\"{}/views/", path_str(&cornell))),
            })
            .collect();
        let path = dir.path().join(name);
        std::fs::write(&path, lines.join("\n")).unwrap();
        path
    };
    let apart = write_scene("apart.toml", 1.0);
    let together = write_scene("together.toml", 0.0);
    let views = cornell.join("views");
    let run = |args: &[&str]| {
        let run = relume(dir.path(), args);
        (
            run.status.code(),
            String::from_utf8_lossy(&run.stderr).to_string(),
        )
    };
    let join = |scene: &Path, out: &str| {
        run(&[
            "panorama",
            "join",
            path_str(scene),
            path_str(&views),
            "--out",
            out,
        ])
    };
    let (code, stderr) = join(&apart, "apart.exr");
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("view 'nx' is at [100001.5, -249999.1, 30001.3]")
            && stderr.contains("view 'px' at [100002.5, -249999.1, 30001.3]")
            && stderr.contains("one position"),
        "{stderr}"
    );
    assert!(!dir.path().join("apart.exr").exists());
    let (code, stderr) = join(&together, "together.exr");
    assert_eq!(code, Some(0), "{stderr}");
    // Split the joined capture with the apart scene as template: no one position to split at.
    let (code, stderr) = run(&[
        "panorama",
        "split",
        "together.exr",
        "--scene",
        path_str(&apart),
        "--out",
        "faces",
    ]);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(stderr.contains("one position"), "{stderr}");
    assert!(!dir.path().join("faces").exists());
}

/// `relume check` tells a view whose exposure is off by orders of magnitude from its
/// preview, in a second, where recover tells it after its work: cornell with view px's
/// exposure given as 0.01 (its render under the first look's colours reads 42x the
/// panorama), or with its image black. The scene as it is gets no such warning, and each
/// view has its reading.
#[test]
fn check_tells_a_view_whose_exposure_is_off_by_orders_of_magnitude() {
    let text = cornell_scene_text();
    let check = |text: &str| {
        let (code, stderr, report) = check_scene(text);
        assert_eq!(code, Some(0), "{stderr}");
        (stderr, report.unwrap())
    };
    let (stderr, report) = check(&text);
    assert!(!stderr.contains("may be off by about"), "{stderr}");
    assert_eq!(report["view_readings"].as_array().unwrap().len(), 6);
    // The first view's exposure: px's.
    let dim = text.replacen("exposure = 1.0", "exposure = 0.01", 1);
    let (stderr, report) = check(&dim);
    assert!(
        stderr.contains("view 'px': the first look's diffuse colours render its")
            && stderr.contains("its exposure or image may be off by about"),
        "{stderr}"
    );
    let px = &report["view_readings"][0];
    assert_eq!(px["view"], "px", "{px}");
    assert!(px["rel_mean_diff"].as_f64().unwrap() > 10.0, "{px}");
    // A view black in the panorama has no ratio to compare, and is told as such.
    let black = tempfile::tempdir().unwrap();
    let black_png = black.path().join("px.png");
    image::RgbImage::new(32, 32).save(&black_png).unwrap();
    let black_px = with_image(&text, "px.exr", &black_png);
    let (stderr, _) = check(&black_px);
    assert!(
        stderr.contains("view 'px': its")
            && stderr.contains("pure pixels are all 0 in the panorama, where the first look's diffuse colours render them at"),
        "{stderr}"
    );
}

/// A PNG view's pixels at its largest code are clipped: their radiance is at least that.
/// Cornell's floor face written as an 8-bit PNG at a gain that clips its brightest pixels
/// is told, with their count; at a gain that clips none, nothing is said.
#[test]
fn a_png_views_clipped_pixels_are_told() {
    let text = cornell_scene_text();
    let floor = cornell_floor_view();
    let dir = tempfile::tempdir().unwrap();
    let as_png = |gain: f32| {
        let png = dir.path().join(format!("nz-{gain}.png"));
        let encoded = image::RgbImage::from_fn(floor.width(), floor.height(), |x, y| {
            let p = floor.get_pixel(x, y).0;
            let code = |v: f32| {
                (relume::images::linear_to_srgb((v * gain).min(1.0)) * 255.0).round() as u8
            };
            image::Rgb(p.map(code))
        });
        encoded.save(&png).unwrap();
        // The exposure that takes the codes back to radiance.
        let scene = with_image(&text, "nz.exr", &png);
        let at = scene.find(path_str(&png)).unwrap();
        let exposure = at + scene[at..].find("exposure = 1.0").unwrap();
        format!(
            "{}exposure = {}{}",
            &scene[..exposure],
            1.0 / gain,
            &scene[exposure + "exposure = 1.0".len()..]
        )
    };
    let brightest = floor.pixels().flat_map(|p| p.0).fold(0.0f32, f32::max);
    let (code, stderr, _) = check_scene(&as_png(0.5 / brightest));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(!stderr.contains("clipped"), "{stderr}");
    let (code, stderr, _) = check_scene(&as_png(4.0 / brightest));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("view 'nz': ")
            && stderr
                .contains("pure pixels are at its PNG's largest value in some channel (clipped)"),
        "{stderr}"
    );
}

/// A greyscale view (a grey PNG reads as three equal channels) is told: the colours fitted
/// to it come out grey. Cornell's floor face written as a grey 16-bit PNG is named; the
/// same face in colour is not.
#[test]
fn a_greyscale_view_is_told() {
    let text = cornell_scene_text();
    let floor = cornell_floor_view();
    let brightest = floor.pixels().flat_map(|p| p.0).fold(0.0f32, f32::max);
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("nz.png");
    image::ImageBuffer::<image::Luma<u16>, _>::from_fn(floor.width(), floor.height(), |x, y| {
        let [r, g, b] = floor.get_pixel(x, y).0;
        let grey = (r + g + b) / (3.0 * brightest);
        image::Luma([(relume::images::linear_to_srgb(grey) * 65535.0).round() as u16])
    })
    .save(&png)
    .unwrap();
    let scene = with_image(&text, "nz.exr", &png);
    let (code, stderr, _) = check_scene(&scene);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("view 'nz' holds equal R, G and B in every pixel (a greyscale image?)"),
        "{stderr}"
    );
    assert!(!stderr.contains("view 'px' holds equal"), "{stderr}");
    let (_, stderr, _) = check_scene(&text);
    assert!(!stderr.contains("holds equal R, G and B"), "{stderr}");
}

/// A view given twice (a copied `[[view]]` table, renamed) counts its pixels twice in
/// every fit: told, naming both; cornell's six distinct views are not.
#[test]
fn a_view_given_twice_is_told() {
    let text = cornell_scene_text();
    let start = text.find("[[view]]").unwrap();
    let end = start + 8 + text[start + 8..].find("[[view]]").unwrap();
    let again = text[start..end].replace("name = \"px\"", "name = \"px_again\"");
    let doubled = format!("{text}\n{again}");
    let (code, stderr, _) = check_scene(&doubled);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("view 'px_again' looks from where view 'px' does, the same way, over the same field and pixels"),
        "{stderr}"
    );
    let (_, stderr, _) = check_scene(&text);
    assert!(!stderr.contains("looks from where"), "{stderr}");
}

/// No surface is brighter in a channel than the lights are there (it reflects at most
/// what reaches it): a hot pixel in cornell's floor view is left out of the fit and named,
/// where before it put the floor at its bound; a light declared 100x too dim, which makes
/// a third of the pure pixels too bright, is refused before any work; and a light declared
/// without blue is warned of.
#[test]
fn a_pixel_brighter_than_the_lights_is_left_out_and_many_are_refused() {
    let text = cornell_scene_text();
    let dir = tempfile::tempdir().unwrap();
    let mut floor = cornell_floor_view();
    floor.put_pixel(20, 15, image::Rgb([1e17; 3]));
    let hot = dir.path().join("nz.exr");
    floor.save(&hot).unwrap();
    let hot_floor = with_image(&text, "nz.exr", &hot);
    let (code, stderr, _) = check_scene(&hot_floor);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("warning: 1 pure pixel of")
            && stderr.contains("is brighter in channel R than 2x the lights' radiance there (30.0, light 'light')")
            && stderr.contains("view 'nz' pixel (x 20, y 15) on group 'floor' reads [1e17, 1e17, 1e17]: left out of the fit"),
        "{stderr}"
    );
    let dim_light = text.replace(
        "radiance = [30.0, 28.0, 24.0]",
        "radiance = [0.3, 0.28, 0.24]",
    );
    assert_ne!(dim_light, text);
    let (code, stderr, report) = check_scene(&dim_light);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("scene.toml: ")
            && stderr.contains("than 2x the lights' radiance there (0.")
            && stderr.contains("a light's radiance declared too low"),
        "{stderr}"
    );
    assert!(report.is_none());
    // A light declared without blue over a capture lit in blue: every colour's blue was
    // left at its start without a word. Its brightest surfaces are past the floor of the
    // missing channel, and the channel itself is warned of.
    let no_blue = text.replace(
        "radiance = [30.0, 28.0, 24.0]",
        "radiance = [30.0, 28.0, 0.0]",
    );
    let (code, stderr, _) = check_scene(&no_blue);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("no light of the scene emits in channel B: no reflectance can be measured in it, and every recovered colour keeps its start, 0.5, there")
            && stderr.contains("are brighter in channel B than 2x the lights' radiance there (no light emits there, at least CHANNEL_FLOOR 0.01 of their brightest channel)"),
        "{stderr}"
    );
}

/// The bundled cornell scene's floor view (`nz`), for tests that write it in another form.
fn cornell_floor_view() -> image::Rgb32FImage {
    let cornell = common::workspace().join("scenes/cornell");
    image::open(cornell.join("views/nz.exr"))
        .unwrap()
        .into_rgb32f()
}

/// cornell's scene.toml with its geometry and images named by absolute paths, so that a
/// variant of it can be written in any folder.
fn cornell_scene_text() -> String {
    let cornell = common::workspace().join("scenes/cornell");
    let text = std::fs::read_to_string(cornell.join("scene.toml")).unwrap();
    let at = |name: &str| format!("\"{}", path_str(&cornell.join(name)));
    text.replace("\"geometry.obj", &at("geometry.obj"))
        .replace("\"views/", &at("views/"))
}

/// [`cornell_scene_text`] `text` with the view image `name` (in cornell's views/) replaced
/// by `image`.
fn with_image(text: &str, name: &str, image: &Path) -> String {
    let views = common::workspace().join("scenes/cornell/views");
    let changed = text.replacen(path_str(&views.join(name)), path_str(image), 1);
    assert_ne!(changed, text);
    changed
}

/// Cameras outside the room (cornell's views moved 2 m behind its red wall, seeing the
/// walls' backs) or inside an object (the box) see nothing a light reaches: check refuses
/// the scene as recover does, and the message names that cause among a light's, where it
/// named only lights hidden, dark, facing away or missing.
#[test]
fn views_outside_the_room_or_inside_an_object_are_named_as_a_cause_of_no_light() {
    for position in ["[-2.0, 0.9, 1.3]", "[0.85, 2.15, 0.45]"] {
        let text = cornell_scene_text().replace("[1.5, 0.9, 1.3]", position);
        let (code, stderr, report) = check_scene(&text);
        assert_eq!(code, Some(INPUT), "{position}: {stderr}");
        assert!(
            stderr.contains("no light of the scene reaches what its views see")
                && stderr.contains("views outside the room or inside an object"),
            "{position}: {stderr}"
        );
        assert!(
            report.is_none(),
            "{position}: a refused check writes no JSON"
        );
    }
}

/// A group whose every triangle is degenerate (corners in a line, or repeated) is told
/// as such: check said only "no pure pixel in any view", which sends a user to the views.
/// A group with an area that no view sees keeps that warning.
#[test]
fn a_group_of_no_area_is_told_as_such() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = common::workspace().join("scenes/cornell");
    let obj = std::fs::read_to_string(cornell.join("geometry.obj")).unwrap();
    let n = obj.lines().filter(|l| l.starts_with("v ")).count();
    let extra = format!(
        "\no flat\nv 2 2 0.5\nv 2.1 2 0.5\nv 2.2 2 0.5\nf {a} {b} {c}\nf {a} {a} {b}\no speck\nv 1 2 0.5\nv 1.001 2 0.5\nv 1 2.001 0.5\nf {d} {e} {f}\n",
        a = n + 1,
        b = n + 2,
        c = n + 3,
        d = n + 4,
        e = n + 5,
        f = n + 6
    );
    let geometry = dir.path().join("geometry.obj");
    std::fs::write(&geometry, format!("{obj}{extra}")).unwrap();
    let text = cornell_scene_text().replace(
        path_str(&cornell.join("geometry.obj")),
        path_str(&geometry),
    ) + "\n[[group]]\nname = \"flat\"\nkind = \"plastic\"\nobjects = [\"flat\"]\n\n[[group]]\nname = \"speck\"\nkind = \"plastic\"\nobjects = [\"speck\"]\n";
    let (code, stderr, _) = check_scene(&text);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("group 'flat': its faces have no area (every triangle degenerate"),
        "{stderr}"
    );
    assert!(!stderr.contains("group 'flat': no pure pixel"), "{stderr}");
    assert!(
        stderr.contains("group 'speck': no pure pixel in any view"),
        "{stderr}"
    );
    assert!(!stderr.contains("group 'speck': its faces"), "{stderr}");
}

/// A PNG view's clipped pixels (at its largest code) are told as `bench downsample`
/// averages them into the EXR it writes, where check and recover can no longer tell them;
/// a PNG with none is not warned of.
#[test]
fn downsample_tells_a_png_views_clipped_pixels() {
    let dir = tempfile::tempdir().unwrap();
    for (name, clipped) in [("clipped", true), ("unclipped", false)] {
        let png = dir.path().join(format!("{name}.png"));
        let mut image = image::RgbImage::from_pixel(32, 32, image::Rgb([100, 100, 100]));
        if clipped {
            image.put_pixel(3, 4, image::Rgb([255, 10, 10]));
        }
        image.save(&png).unwrap();
        let scene = dir.path().join(format!("{name}.toml"));
        std::fs::write(&scene, with_image(&cornell_scene_text(), "px.exr", &png)).unwrap();
        let run = relume(
            dir.path(),
            &[
                "bench",
                "downsample",
                path_str(&scene),
                "--factor",
                "2",
                "--out",
                name,
            ],
        );
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(0), "{stderr}");
        let told = stderr.contains("view 'px': 1 pixel of")
            && stderr.contains("clipped")
            && stderr.contains("px.exr");
        assert_eq!(told, clipped, "{name}: {stderr}");
    }
}

/// `relume check` of a scene.toml `text` written in a folder of its own: its exit code,
/// its stderr and its JSON report (`None` where it wrote none).
fn check_scene(text: &str) -> (Option<i32>, String, Option<serde_json::Value>) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.toml"), text).unwrap();
    let run = relume(dir.path(), &["check", "scene.toml", "--json", "check.json"]);
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    let json = std::fs::read_to_string(dir.path().join("check.json")).ok();
    let report = json.map(|j| serde_json::from_str(&j).unwrap());
    (run.status.code(), stderr, report)
}

/// cornell without its back wall (hidden here, as an OBJ that lacks it), while its
/// panorama shows the wall: view py sees out of the room where the panorama is bright,
/// which every render leaves black whatever the materials. Told, naming the view; the
/// whole cornell tells nothing.
#[test]
fn check_tells_of_views_that_see_out_of_the_scene_where_the_panorama_is_bright() {
    let cornell = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
    let scene = std::fs::read_to_string(cornell.join("scene.toml"))
        .unwrap()
        .replace(
            "geometry = [\"geometry.obj\"]",
            &format!("geometry = [{:?}]", cornell.join("geometry.obj")),
        )
        .replace(
            "image = \"views/",
            &format!("image = \"{}/views/", cornell.display()),
        );
    let told = "of its 1024 pixels see out of the scene (no geometry there, so every render is black) where the panorama is bright";
    let (code, stderr, _) = check_scene(&scene);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(!stderr.contains("see out of the scene"), "{stderr}");
    let (code, stderr, _) = check_scene(&scene.replace("hide = []", "hide = [\"wall_back\"]"));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("view 'py': ") && stderr.contains(told),
        "{stderr}"
    );
    assert_eq!(
        stderr.matches("see out of the scene").count(),
        1,
        "{stderr}"
    );
    // A panorama of the open box itself (rendered by relume) is black where the views see
    // out of it, and bright on the rim of the opening, where pixels see the rim over part
    // of their footprint: nothing to tell.
    let open = scene.replace("hide = []", "hide = [\"wall_back\"]");
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.toml"), &open).unwrap();
    let materials = cornell.join("materials.toml");
    let args = [
        "render",
        "scene.toml",
        "--materials",
        path_str(&materials),
        "--out",
        "views",
        "--spp",
        "16",
    ];
    common::relume_ok(dir.path(), &args);
    let own = open.replace(&format!("{}/views/", cornell.display()), "views/");
    std::fs::write(dir.path().join("scene.toml"), own).unwrap();
    let run = relume(dir.path(), &["check", "scene.toml"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{stderr}");
    assert!(!stderr.contains("see out of the scene"), "{stderr}");
}

/// `relume check` on small scenes: views of 8 pixels are warned of as recover warns after
/// its work, and a panorama that sees no group whole is refused as recover refuses it,
/// before any render, writing nothing.
#[test]
fn check_warns_of_small_views_and_refuses_a_panorama_that_sees_no_group() {
    let dir = lit_and_unlit(LIT_AND_UNLIT);
    let run = relume(dir.path(), &["check", "scene.toml", "--json", "check.json"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains(
            "view 'floor' is only 8 pixels on a side (and 1 more view: 'cellar' 8): below 32"
        ),
        "{stderr}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("check.json")).unwrap())
            .unwrap();
    let few = report["few_pixels"].as_array().unwrap();
    assert_eq!(few.len(), 2, "both groups seen, in a few pixels: {few:?}");
    // Its preview of stage 1 finds the cellar unlit, as recover does, and gives it no colour.
    assert!(
        stderr.contains("group 'cellar': no light of the scene reaches it")
            && stderr.contains("its material is not recovered"),
        "{stderr}"
    );
    let cellar = report["groups"]
        .as_array()
        .unwrap()
        .iter()
        .find(|g| g["group"] == "cellar")
        .unwrap();
    assert!(cellar["preview_colour"].is_null(), "{cellar}");
    let seen: u64 = cellar["pure_pixels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_u64().unwrap())
        .sum();
    assert!(seen > 0, "{cellar}");

    // Refused, naming why, and nothing written.
    let refused = |dir: &tempfile::TempDir, why: &str| {
        let run = relume(dir.path(), &["check", "scene.toml", "--json", "check.json"]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(INPUT), "{stderr}");
        assert!(stderr.contains(why), "{stderr}");
        assert!(!dir.path().join("check.json").exists());
    };
    refused(
        &lit_and_unlit(&looking_away()),
        "no view sees any group in whole pixels",
    );
    // With the lamp hidden too, no light reaches what the views see: refused, as recover
    // refuses it.
    let dir = lit_and_unlit(LIT_AND_UNLIT);
    std::fs::write(dir.path().join("scene.toml"), without_light()).unwrap();
    refused(
        &dir,
        "scene.toml: no light of the scene reaches what its views see",
    );
}

/// A light whose triangles face away from the room (an OBJ of the other winding order)
/// lit the room only by way of the ceiling above it, and `check` said only that every
/// group read too bright for the lights, blaming their radiance or the exposure. The view
/// that sees the light's back, which reads its radiance where a back is black, now names
/// the light and the cause; the bundled scene, its light turned right, gets no such word.
#[test]
fn a_light_facing_away_is_named_by_the_view_that_sees_its_back_shine() {
    let cornell = common::workspace().join("scenes/cornell");
    let obj = std::fs::read_to_string(cornell.join("geometry.obj")).unwrap();
    let mut in_light = false;
    let flipped: Vec<String> = obj
        .lines()
        .map(|line| {
            if line.starts_with("o ") {
                in_light = line == "o light";
            }
            match line.strip_prefix("f ") {
                Some(face) if in_light => {
                    let mut corners: Vec<&str> = face.split_whitespace().collect();
                    corners.reverse();
                    format!("f {}", corners.join(" "))
                }
                _ => line.to_string(),
            }
        })
        .collect();
    assert_ne!(flipped.join("\n"), obj.trim_end());
    let dir = tempfile::tempdir().unwrap();
    let geometry = dir.path().join("flipped.obj");
    std::fs::write(&geometry, flipped.join("\n")).unwrap();
    let text =
        cornell_scene_text().replace(path_str(&cornell.join("geometry.obj")), path_str(&geometry));
    let (code, stderr, _) = check_scene(&text);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("light 'light' is seen from behind in view 'pz' (64 pixels wholly on its back), yet reads 1.000x its declared radiance")
            && stderr.contains("its triangles likely face away from where it shines"),
        "{stderr}"
    );
    let (code, stderr, _) = check_scene(&cornell_scene_text());
    assert_eq!(code, Some(0), "{stderr}");
    assert!(!stderr.contains("seen from behind"), "{stderr}");
}

/// A view placed inside cornell's sphere sees only its inside, which no light reaches:
/// its pixels counted as the sphere's, and the sphere came out an anisotropic metal. The
/// view is named and its pixels left out; with every view inside, the scene is refused.
#[test]
fn a_view_inside_a_closed_group_no_light_reaches_is_left_out() {
    let text = cornell_scene_text();
    let centre = "position = [2.1, 1.2, 0.35]";
    let one_inside = text.replacen("position = [1.5, 0.9, 1.3]", centre, 1);
    assert_ne!(one_inside, text);
    let (code, stderr, report) = check_scene(&one_inside);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr
            .contains("view 'px' is inside group 'sphere', a closed surface no light shines into")
            && stderr.contains("so its 1024 pure pixels are left out of the fit"),
        "{stderr}"
    );
    let report = report.unwrap();
    let views = report["views"].as_array().unwrap();
    let px = views.iter().position(|v| v == "px").unwrap();
    for g in report["groups"].as_array().unwrap() {
        assert_eq!(g["pure_pixels"][px], 0, "{g}");
    }
    // The bundled scene: no view is inside anything but the room, which holds the light.
    let (_, stderr, _) = check_scene(&text);
    assert!(!stderr.contains("is inside group"), "{stderr}");
    // Every view inside: nothing is left to recover from.
    let all_inside = text.replace("position = [1.5, 0.9, 1.3]", centre);
    let (code, stderr, report) = check_scene(&all_inside);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("no view is left to recover from: view 'px' is inside group 'sphere'"),
        "{stderr}"
    );
    assert!(report.is_none());
}

/// A closed box around cornell's light: no light leaves it, and the refusal listed every
/// cause but that one. It now names the light and the box.
#[test]
fn a_light_inside_a_closed_group_is_named_where_no_light_reaches() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = common::workspace().join("scenes/cornell");
    let obj = std::fs::read_to_string(cornell.join("geometry.obj")).unwrap();
    // A box from 1.0 to 2.0 in x and y, from 2.0 up to just under the ceiling (2.5),
    // around the light at 2.49: its six faces share every edge.
    let cube = "o cover\nv 1 1 2\nv 2 1 2\nv 2 2 2\nv 1 2 2\nv 1 1 2.495\nv 2 1 2.495\nv 2 2 2.495\nv 1 2 2.495\n\
                f -8 -5 -6 -7\nf -4 -3 -2 -1\nf -8 -7 -3 -4\nf -7 -6 -2 -3\nf -6 -5 -1 -2\nf -5 -8 -4 -1\n";
    let geometry = dir.path().join("covered.obj");
    std::fs::write(&geometry, format!("{obj}\n{cube}")).unwrap();
    let text = cornell_scene_text()
        .replace(path_str(&cornell.join("geometry.obj")), path_str(&geometry))
        + "\n[[group]]\nname = \"cover\"\nkind = \"plastic\"\nobjects = [\"cover\"]\n";
    let (code, stderr, _) = check_scene(&text);
    assert_eq!(code, Some(INPUT), "{stderr}");
    assert!(
        stderr.contains("no light of the scene reaches what its views see")
            && stderr.contains(
                "light 'light' is inside group 'cover', a closed surface that no view is inside"
            ),
        "{stderr}"
    );
}

/// A group whose every object is hidden is not in the scene: `check` said only that no
/// view saw it in whole pixels, which sent a user looking at the views; it now names
/// `hide` as the cause, and says no more of that group.
#[test]
fn a_group_all_hidden_is_told_as_hidden() {
    let text = cornell_scene_text();
    assert!(text.contains("hide = []"));
    let (code, stderr, _) = check_scene(&text.replace("hide = []", "hide = [\"sphere\"]"));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("group 'sphere': every object of it is hidden (`hide` in the scene)"),
        "{stderr}"
    );
    assert!(
        !stderr.contains("group 'sphere': no pure pixel"),
        "{stderr}"
    );
    let (_, stderr, _) = check_scene(&text);
    assert!(!stderr.contains("is hidden"), "{stderr}");
}

/// A textured plastic's map holds its diffuse reflectance, which with the specularity may
/// reach 1 at most: a map of 1.0 under a specularity of 0.05 was rendered without a word.
/// `render` warns, naming the file's line, the texel and the sum; within the bound, not.
#[test]
fn a_map_that_with_its_lobe_reflects_more_than_all_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.toml"), SCENE).unwrap();
    std::fs::write(dir.path().join("geo.obj"), OBJ).unwrap();
    relume::images::write_exr(
        &dir.path().join("tex.exr"),
        &relume::images::Image {
            width: 2,
            height: 2,
            pixels: vec![[0.5; 3], [0.5, 0.97, 0.5], [0.9; 3], [0.2; 3]],
        },
    )
    .unwrap();
    let warnings = |specularity: f32| {
        let materials = format!("format = 1\n\n[[material]]\ngroup = \"floor\"\nmodel = \"textured-isotropic\"\ndiffuse_map = \"tex.exr\"\nspecularity = {specularity}\nroughness = 0.1\n");
        std::fs::write(dir.path().join("m.toml"), materials).unwrap();
        let files = [relume::materials_file::load_materials(&dir.path().join("m.toml")).unwrap()];
        let owned = relume::assemble::load_and_assemble(
            &dir.path().join("scene.toml"),
            relume::assemble::MaterialSource::Files(&files),
        )
        .unwrap();
        owned.map_energy_warnings(&files)
    };
    let told = warnings(0.05);
    assert_eq!(told.len(), 1, "{told:?}");
    assert!(
        told[0].contains("m.toml:3: group 'floor': its diffuse map reaches 0.97 in channel G at texel (x 1, y 0), which with specularity 0.05 reflects 1.02"),
        "{told:?}"
    );
    assert_eq!(warnings(0.03), Vec::<String>::new());
    // `render` says it.
    warnings(0.05);
    let run = common::relume_ok(
        dir.path(),
        &[
            "render",
            "scene.toml",
            "--materials",
            "m.toml",
            "--out",
            "r",
            "--spp",
            "1",
        ],
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("relume: warning: ") && stderr.contains("its diffuse map reaches 0.97"),
        "{stderr}"
    );
}

/// A diffuse map that two groups share is read and held once: a 6000x6000 map on the
/// floor and the ceiling was counted twice against MAX_TEXELS, and refused.
#[test]
fn a_map_two_groups_share_is_held_once() {
    let dir = tempfile::tempdir().unwrap();
    let scene = SCENE.replace(
        "objects = [\"quad\"]",
        "objects = [\"quad\"]\n\n[[group]]\nname = \"shelf\"\nkind = \"plastic\"\nobjects = [\"quad2\"]",
    );
    let obj = format!(
        "{OBJ}o quad2\nv 0 0 0.5\nv 1 0 0.5\nv 1 1 0.5\nv 0 1 0.5\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 8/5 9/6 10/7 11/8\n"
    );
    let materials = "format = 1\n\n[[material]]\ngroup = \"floor\"\nmodel = \"textured-diffuse\"\ndiffuse_map = \"tex.exr\"\n\n[[material]]\ngroup = \"shelf\"\nmodel = \"textured-diffuse\"\ndiffuse_map = \"./tex.exr\"\n";
    for (name, text) in [
        ("scene.toml", scene.as_str()),
        ("geo.obj", obj.as_str()),
        ("m.toml", materials),
    ] {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    relume::images::write_exr(
        &dir.path().join("tex.exr"),
        &relume::images::Image {
            width: 2,
            height: 2,
            pixels: vec![[0.5; 3]; 4],
        },
    )
    .unwrap();
    let files = [relume::materials_file::load_materials(&dir.path().join("m.toml")).unwrap()];
    let owned = relume::assemble::load_and_assemble(
        &dir.path().join("scene.toml"),
        relume::assemble::MaterialSource::Files(&files),
    )
    .unwrap();
    assert_eq!((owned.texture_infos.len(), owned.texels.len()), (1, 4));
    let maps: Vec<_> = owned.materials.iter().map(|m| m.diffuse_map).collect();
    assert!(maps[0].is_some() && maps[0] == maps[1], "{maps:?}");
}
