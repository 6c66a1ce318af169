//! Bad inputs to `relume compare` and `relume bench` through the real binary: each is
//! refused before the work with the input (3) or usage (2) code, names the file and what
//! is wrong, never panics, and leaves every file as it was; figures that mean nothing are
//! said to, never printed as NaN.

#[path = "common/mod.rs"]
mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{copy_cornell, files_and_bytes, relume};

const INPUT: i32 = 3;
const USAGE: i32 = 2;

/// A copy of the bundled scene in a fresh temp dir: `c/` (scene.toml, geometry.obj,
/// materials.toml, views/), `B/` (a copy of its views, to compare with), `rep.json` (a
/// report for one group), `x.rays` (three unit rays from inside the room) and `other.toml`
/// (materials of another scene: groups sofa and desk).
struct Case {
    dir: tempfile::TempDir,
}

impl Case {
    fn new() -> Case {
        let dir = tempfile::tempdir().unwrap();
        copy_cornell(&dir.path().join("c"));
        std::fs::create_dir_all(dir.path().join("B")).unwrap();
        for view in ["px", "nx", "py", "ny", "pz", "nz"] {
            let file = format!("{view}.exr");
            std::fs::copy(
                dir.path().join("c/views").join(&file),
                dir.path().join("B").join(&file),
            )
            .unwrap();
        }
        std::fs::write(
            dir.path().join("rep.json"),
            r#"{"groups": [{"group": "floor", "model": "diffuse", "uncertainty": [{"parameter": "color_r", "value": 0.5, "sigma": 0.01}, {"parameter": "color_g", "value": 0.5, "sigma": 0.01}, {"parameter": "color_b", "value": 0.5, "sigma": 0.01}]}]}"#,
        )
        .unwrap();
        write_rays(
            &dir.path().join("x.rays"),
            &[[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
        );
        std::fs::write(
            dir.path().join("other.toml"),
            "format = 1\n\n[[material]]\ngroup = \"sofa\"\nmodel = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]\n\n[[material]]\ngroup = \"desk\"\nmodel = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]\n",
        )
        .unwrap();
        Case { dir }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// Runs relume in the case's folder.
    fn run(&self, args: &[&str]) -> Output {
        relume(self.dir.path(), args)
    }

    /// Writes an edit of the scene, `<name>/scene.toml`, whose references are its views.
    fn edit(&self, name: &str) -> String {
        let text = std::fs::read_to_string(self.path("c/scene.toml"))
            .unwrap()
            .replace("\"geometry.obj\"", "\"../c/geometry.obj\"")
            .replace("\"views/", "\"../c/views/");
        std::fs::create_dir_all(self.path(name)).unwrap();
        std::fs::write(self.path(name).join("scene.toml"), text).unwrap();
        format!("{name}/scene.toml")
    }
}

/// A ray file: `u64 count`, then origin and direction as six f32, all from the room's
/// middle.
fn write_rays(path: &Path, directions: &[[f32; 3]]) {
    let mut bytes = (directions.len() as u64).to_le_bytes().to_vec();
    for d in directions {
        for v in [1.5, 0.9, 1.3, d[0], d[1], d[2]] {
            bytes.extend_from_slice(&f32::to_le_bytes(v));
        }
    }
    std::fs::write(path, bytes).unwrap();
}

/// Checks that `run` exited with `code`, did not panic and said every one of `has` on
/// stderr; returns stderr.
fn fails(run: &Output, code: i32, has: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert_eq!(run.status.code(), Some(code), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    for h in has {
        assert!(stderr.contains(h), "{h:?} not in: {stderr}");
    }
    stderr
}

/// `--json` and `--hits` outputs, and the files a bench writes, that would replace an
/// input of the run (the scene's files, the images compared, a materials file, a report,
/// the rays, the truth) are refused before the work, naming the file and what it is;
/// they were written over the input with exit 0. The truth put where a bench's first
/// recovery, or its JSON, would go was replaced after minutes of work.
#[test]
fn compare_and_bench_outputs_never_replace_their_inputs() {
    let case = Case::new();
    let edit = case.edit("e");
    for dir in ["out/runs/effort-fast", "out/runs/seed_1"] {
        std::fs::create_dir_all(case.path(dir)).unwrap();
        std::fs::copy(
            case.path("c/materials.toml"),
            case.path(&format!("{dir}/materials.toml")),
        )
        .unwrap();
    }
    std::fs::copy(case.path("c/materials.toml"), case.path("out/edits.json")).unwrap();
    let before = files_and_bytes(case.dir.path());
    let views = ["compare", "views", "c/scene.toml", "c/views", "B", "--json"];
    let rays = ["bench", "rays", "c/scene.toml", "--rays", "x.rays"];
    let runs: Vec<(Vec<&str>, &str, &str)> = vec![
        (
            [&views[..], &["c/geometry.obj"]].concat(),
            "c/geometry.obj",
            "the scene's geometry",
        ),
        (
            [&views[..], &["c/scene.toml"]].concat(),
            "c/scene.toml",
            "the scene file",
        ),
        (
            [&views[..], &["c/views/px.exr"]].concat(),
            "c/views/px.exr",
            "the image of view 'px'",
        ),
        (
            [&views[..], &["B/nz.exr"]].concat(),
            "B/nz.exr",
            "the compared image of view 'nz' (B)",
        ),
        (
            vec![
                "compare",
                "materials",
                "c/materials.toml",
                "other.toml",
                "--json",
                "c/materials.toml",
            ],
            "c/materials.toml",
            "a materials file",
        ),
        (
            vec![
                "compare",
                "uncertainty",
                "c/materials.toml",
                "rep.json",
                "--json",
                "rep.json",
            ],
            "rep.json",
            "a report",
        ),
        (
            [&rays[..], &["--hits", "x.rays"]].concat(),
            "x.rays",
            "the ray file",
        ),
        (
            [&rays[..], &["--json", "x.rays"]].concat(),
            "x.rays",
            "the ray file",
        ),
        (
            [&rays[..], &["--json", "c/geometry.obj"]].concat(),
            "c/geometry.obj",
            "the scene's geometry",
        ),
        (
            vec![
                "bench",
                "tradeoff",
                "c/scene.toml",
                "--truth",
                "out/runs/effort-fast/materials.toml",
                "--out",
                "out",
                "--quick",
            ],
            "out/runs/effort-fast/materials.toml",
            "a materials file",
        ),
        (
            vec![
                "bench",
                "stability",
                "c/scene.toml",
                "--truth",
                "out/runs/seed_1/materials.toml",
                "--out",
                "out",
                "--quick",
            ],
            "out/runs/seed_1/materials.toml",
            "a materials file",
        ),
        (
            vec![
                "bench",
                "edits",
                &edit,
                "--recovered",
                "c/materials.toml",
                "--truth",
                "out/edits.json",
                "--out",
                "out",
                "--spp",
                "1",
            ],
            "out/edits.json",
            "a materials file",
        ),
    ];
    for (args, file, what) in runs {
        let run = case.run(&args);
        let expected = format!("{file}: this output would replace {what}, an input of this run");
        fails(&run, INPUT, &[&expected]);
        assert!(
            files_and_bytes(case.dir.path()) == before,
            "{args:?} changed the files"
        );
    }
    // Two outputs of one name: the second replaced the first.
    let run = case.run(&[&rays[..], &["--hits", "o.bin", "--json", "o.bin"]].concat());
    fails(&run, USAGE, &["--hits and --json both name o.bin"]);
    assert!(!case.path("o.bin").exists());
}

/// A truth of another scene ran a bench for minutes (edits failed only after its first
/// render) and judged every recovery against groups it does not have. It is refused at
/// once, naming the groups missing on each side, and nothing is written.
#[test]
fn a_bench_given_the_truth_of_another_scene_refuses_it_before_any_work() {
    let case = Case::new();
    let edit = case.edit("e");
    let runs: [Vec<&str>; 3] = [
        vec![
            "bench",
            "tradeoff",
            "c/scene.toml",
            "--truth",
            "other.toml",
            "--out",
            "out",
            "--quick",
        ],
        vec![
            "bench",
            "stability",
            "c/scene.toml",
            "--truth",
            "other.toml",
            "--out",
            "out",
            "--quick",
        ],
        vec![
            "bench",
            "edits",
            &edit,
            "--recovered",
            "c/materials.toml",
            "--truth",
            "other.toml",
            "--out",
            "out",
            "--spp",
            "1",
        ],
    ];
    for args in runs {
        let start = std::time::Instant::now();
        let run = case.run(&args);
        let stderr = fails(
            &run,
            INPUT,
            &[
                "other.toml: its groups are not those of the",
                "only in this file: 'sofa', 'desk'",
                "'floor', 'ceiling', 'wall_red'",
            ],
        );
        assert!(
            start.elapsed().as_secs() < 60,
            "{args:?} worked before it refused: {stderr}"
        );
        assert!(!case.path("out").exists(), "{args:?} wrote outputs");
    }
}

/// `compare materials` dropped the groups only the compared file has, and gave "2 of 11"
/// with exit 0 for a file of another scene. Such a file is refused naming the groups on
/// each side, and so is the truth given as the file compared; a recovery that left a group
/// out (none is written for an unseen group) is still judged, that group `(missing)`.
#[test]
fn compare_materials_refuses_a_file_of_another_scene_and_judges_a_partial_one() {
    let case = Case::new();
    let run = case.run(&["compare", "materials", "c/materials.toml", "other.toml"]);
    fails(
        &run,
        INPUT,
        &[
            "other.toml: its groups are not those of the truth c/materials.toml",
            "only in this file: 'sofa', 'desk'; only in the truth: 'floor', 'ceiling'",
        ],
    );
    assert!(
        run.stdout.is_empty(),
        "no table for a file of another scene"
    );
    // The truth compared with itself read 0% on every row.
    let run = case.run(&[
        "compare",
        "materials",
        "c/materials.toml",
        "./c/../c/materials.toml",
    ]);
    fails(
        &run,
        USAGE,
        &["are the same file (./c/../c/materials.toml)"],
    );
    assert!(run.stdout.is_empty());
    let truth = std::fs::read_to_string(case.path("c/materials.toml")).unwrap();
    let at = truth.find("[[material]]\ngroup = \"mirror\"").unwrap();
    std::fs::write(case.path("partial.toml"), &truth[..at]).unwrap();
    let run = case.run(&["compare", "materials", "c/materials.toml", "partial.toml"]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{stdout}");
    assert!(
        stdout.contains("(missing)") && stdout.contains("classes right: 8 of 9 (wrong: mirror)"),
        "{stdout}"
    );
}

/// `--scene` judges the kinds of the recovered lobes against the truth's scene: the
/// truth against itself has every kind right; a lobe whose material says another kind (as
/// a recovery of a group of kind "auto" writes) is named; a scene whose groups are not
/// the truth's is refused, naming them.
#[test]
fn compare_materials_judges_kinds_against_the_truths_scene() {
    let case = Case::new();
    let args = |materials: &str, scene: &str| {
        [
            "compare",
            "materials",
            "c/materials.toml",
            materials,
            "--scene",
            scene,
        ]
        .map(str::to_string)
    };
    let stdout = |materials: &str, scene: &str| {
        let a = args(materials, scene);
        let run = case.run(&a.iter().map(String::as_str).collect::<Vec<_>>());
        let out = String::from_utf8_lossy(&run.stdout).into_owned();
        assert!(
            run.status.success(),
            "{out}{}",
            String::from_utf8_lossy(&run.stderr)
        );
        out
    };
    // A copy: the truth given as its own compared file is refused.
    std::fs::copy(case.path("c/materials.toml"), case.path("c/same.toml")).unwrap();
    let out = stdout("c/same.toml", "c/scene.toml");
    assert!(
        out.contains("kinds right: 3 of 3 (groups with a lobe in both)"),
        "{out}"
    );
    let truth = std::fs::read_to_string(case.path("c/materials.toml")).unwrap();
    let sphere = "group = \"sphere\"\nmodel = \"isotropic\"\n";
    assert!(truth.contains(sphere));
    let plastic = truth.replace(sphere, &format!("{sphere}kind = \"plastic\"\n"));
    std::fs::write(case.path("auto.toml"), plastic).unwrap();
    let out = stdout("auto.toml", "c/scene.toml");
    assert!(
        out.contains("kinds right: 2 of 3 (groups with a lobe in both) (wrong: sphere: plastic, truth metal)"),
        "{out}"
    );
    // The same numbers as a plastic reflect s, white, where the metal reflects c s: the
    // specularity agrees, the specular reflectance is off by the mean of 1/c - 1 over the
    // sphere's colour (0.9, 0.72, 0.4), 2/3.
    let a = args("auto.toml", "c/scene.toml");
    let a: Vec<&str> = a
        .iter()
        .map(String::as_str)
        .chain(["--json", "auto.json"])
        .collect();
    assert!(case.run(&a).status.success());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(case.path("auto.json")).unwrap()).unwrap();
    let sphere = json
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["group"] == "sphere")
        .unwrap();
    assert_eq!(sphere["specularity_rel_err"].as_f64(), Some(0.0));
    let reflectance = sphere["specular_reflectance_rel_err"].as_f64().unwrap();
    assert!((reflectance - 2.0 / 3.0).abs() < 1e-6, "{sphere}");
    // The truth's scene edited (`from` replaced by `to`) is refused, the error naming it
    // and saying `what`.
    let refused_scene = |name: &str, (from, to): (&str, &str), what: &[&str]| {
        let scene = case.edit(name);
        let text = std::fs::read_to_string(case.path(&scene)).unwrap();
        assert!(text.contains(from));
        std::fs::write(case.path(&scene), text.replace(from, to)).unwrap();
        let a = args("c/same.toml", &scene);
        let run = case.run(&a.iter().map(String::as_str).collect::<Vec<_>>());
        fails(&run, INPUT, &[&[scene.as_str()][..], what].concat());
    };
    // A scene that leaves a lobe's kind to the recovery cannot judge it: refused, naming
    // the groups, rather than left out of the count.
    refused_scene(
        "auto",
        ("kind = \"metal\"", "kind = \"auto\""),
        &["groups 'sphere', 'plate' of kind \"auto\""],
    );
    refused_scene(
        "odd",
        ("name = \"floor\"", "name = \"floor2\""),
        &["only in this file: 'floor2'", "only in the truth: 'floor'"],
    );
}

/// The same report twice pooled its parameters twice, claiming a coverage over two
/// recoveries: refused, naming it, under any spelling of its path.
#[test]
fn compare_uncertainty_refuses_a_report_given_twice() {
    let case = Case::new();
    for second in ["rep.json", "./c/../rep.json"] {
        let run = case.run(&[
            "compare",
            "uncertainty",
            "c/materials.toml",
            "rep.json",
            second,
        ]);
        fails(
            &run,
            USAGE,
            &[&format!(
                "{second} is given twice as a report (also as rep.json)"
            )],
        );
        assert!(run.stdout.is_empty());
    }
    let run = case.run(&["compare", "uncertainty", "c/materials.toml", "rep.json"]);
    assert!(run.status.success());
}

/// A file given where a folder of view images goes is bad input saying so (it was "Not a
/// directory" of a path made up of both), for `compare views` and `panorama join`.
#[test]
fn a_file_where_a_folder_of_views_goes_is_named() {
    let case = Case::new();
    for args in [
        &["compare", "views", "c/scene.toml", "c/views/px.exr", "B"][..],
        &["compare", "views", "c/scene.toml", "c/views", "B/px.exr"],
        &[
            "panorama",
            "join",
            "c/scene.toml",
            "B/px.exr",
            "--out",
            "j.exr",
        ],
    ] {
        let run = case.run(args);
        fails(
            &run,
            INPUT,
            &["px.exr: is a file, not a folder of <view>.exr images"],
        );
        assert!(!case.path("j.exr").exists());
    }
}

/// A `--json` that names a folder is refused before the work, as a file over an input is:
/// the whole table was printed, and the run failed only when the JSON was written. One
/// into a folder not made yet makes it.
#[test]
fn a_json_that_names_a_folder_is_refused_before_the_work() {
    let case = Case::new();
    std::fs::create_dir(case.path("D")).unwrap();
    // `compare views` of the case's views against B's, its JSON at `json`.
    let views_json = |json: &'static str| {
        [
            "compare",
            "views",
            "c/scene.toml",
            "c/views",
            "B",
            "--json",
            json,
        ]
    };
    for args in [
        &[
            "compare",
            "materials",
            "c/materials.toml",
            "other.toml",
            "--json",
            "D",
        ][..],
        &[
            "compare",
            "uncertainty",
            "c/materials.toml",
            "rep.json",
            "--json",
            "D",
        ],
        &views_json("D"),
        &["check", "c/scene.toml", "--json", "D"],
        &[
            "bench",
            "rays",
            "c/scene.toml",
            "--rays",
            "x.rays",
            "--json",
            "D",
        ],
    ] {
        let run = case.run(args);
        fails(&run, 4, &["D: a folder is in the way of this output file"]);
        assert!(run.stdout.is_empty(), "{args:?}");
    }
    // A folder not made yet is made, as `--out`'s is: the JSON failed "No such file or
    // directory" after the whole table was printed.
    let run = case.run(&views_json("new/sub/views.json"));
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json = std::fs::read_to_string(case.path("new/sub/views.json")).unwrap();
    assert!(json.contains("\"views\""), "{json}");
    // A run that fails leaves no folder behind.
    let run = case.run(&[
        "compare",
        "materials",
        "c/materials.toml",
        "other.toml",
        "--json",
        "gone/m.json",
    ]);
    fails(&run, INPUT, &["other.toml"]);
    assert!(!case.path("gone").exists());
}

/// A report that gives a group's parameters in part was judged on those left (a colour
/// channel alone read "100% within 1 sigma"), and one that gives none for any group
/// recovered in its class printed percentages of nothing: both refused, naming the file.
#[test]
fn compare_uncertainty_refuses_parameters_in_part_and_nothing_to_judge() {
    let case = Case::new();
    std::fs::write(
        case.path("part.json"),
        r#"{"groups": [{"group": "sphere", "model": "isotropic", "uncertainty": [{"parameter": "color_r", "value": 0.9, "sigma": 0.01}]}]}"#,
    )
    .unwrap();
    let run = case.run(&["compare", "uncertainty", "c/materials.toml", "part.json"]);
    fails(
        &run,
        INPUT,
        &[
            "part.json",
            "group 'sphere': model 'isotropic' has no uncertainty for color_g, color_b, specularity, roughness",
        ],
    );
    assert!(run.stdout.is_empty());
    std::fs::write(
        case.path("none.json"),
        r#"{"groups": [{"group": "floor", "model": "diffuse", "uncertainty": []}, {"group": "sphere", "model": "diffuse", "uncertainty": [{"parameter": "color_r", "value": 0.9, "sigma": 0.01}, {"parameter": "color_g", "value": 0.9, "sigma": 0.01}, {"parameter": "color_b", "value": 0.9, "sigma": 0.01}]}]}"#,
    )
    .unwrap();
    let run = case.run(&["compare", "uncertainty", "c/materials.toml", "none.json"]);
    fails(
        &run,
        INPUT,
        &["none.json: gives no uncertainty for a group recovered in its true class"],
    );
    assert!(run.stdout.is_empty());
}

/// `--repeats 0` printed figures of no timed run, and so did a ray file of no ray ("0.000
/// Mrays/s"); a ray whose direction is not of unit length (the format's) gave distances
/// that cannot agree with the reference's.
#[test]
fn bench_rays_refuses_no_repeats_no_rays_and_directions_that_are_not_unit() {
    let case = Case::new();
    let run = case.run(&[
        "bench",
        "rays",
        "c/scene.toml",
        "--rays",
        "x.rays",
        "--repeats",
        "0",
    ]);
    fails(&run, USAGE, &["--repeats"]);
    assert!(run.stdout.is_empty());
    write_rays(
        &case.path("long.rays"),
        &[[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 3.0, 4.0]],
    );
    let run = case.run(&["bench", "rays", "c/scene.toml", "--rays", "long.rays"]);
    fails(
        &run,
        INPUT,
        &["long.rays: ray 2 has a direction of length 5, not 1"],
    );
    assert!(run.stdout.is_empty());
    write_rays(&case.path("none.rays"), &[]);
    let run = case.run(&["bench", "rays", "c/scene.toml", "--rays", "none.rays"]);
    fails(&run, INPUT, &["none.rays: holds no ray (its count is 0)"]);
    assert!(run.stdout.is_empty());
    let run = case.run(&[
        "bench",
        "rays",
        "c/scene.toml",
        "--rays",
        "x.rays",
        "--repeats",
        "1",
    ]);
    assert!(run.status.success());
}

/// Two quads, `floor` and `shelf`, each seen alone by a view from above (`a`, `b`), and a
/// lamp that neither view sees.
const TWO_VIEWS: &str = r#"format = 1
name = "two"
geometry = ["geo.obj"]
hide = []

[[view]]
name = "a"
position = [0.5, 0.5, 1.0]
direction = [0.0, 0.0, -1.0]
up = [0.0, 1.0, 0.0]
fov_deg = [50.0, 50.0]
size = [8, 8]

[[view]]
name = "b"
position = [5.5, 0.5, 1.0]
direction = [0.0, 0.0, -1.0]
up = [0.0, 1.0, 0.0]
fov_deg = [50.0, 50.0]
size = [8, 8]

[[light]]
object = "lamp"
radiance = [1.0, 1.0, 1.0]

[[group]]
name = "floor"
kind = "plastic"
objects = ["floor"]

[[group]]
name = "shelf"
kind = "plastic"
objects = ["shelf"]
"#;

const TWO_QUADS: &str = "o floor
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
f 1 2 3 4
o shelf
v 5 0 0
v 6 0 0
v 6 1 0
v 5 1 0
f 5 6 7 8
o lamp
v 20 0 5
v 21 0 5
v 20 1 5
f 9 11 10
";

/// An 8x8 image of one value.
fn flat(path: &Path, value: f32) {
    let image = relume::images::Image {
        width: 8,
        height: 8,
        pixels: vec![[value; 3]; 64],
    };
    relume::images::write_exr(path, &image).unwrap();
}

/// A temp folder with the [`TWO_VIEWS`] scene, the `folders` made in it, and each of
/// `images` (a path in it and a value) a flat image of that value.
fn two_views_with(folders: &[&str], images: &[(&str, f32)]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.toml"), TWO_VIEWS).unwrap();
    std::fs::write(dir.path().join("geo.obj"), TWO_QUADS).unwrap();
    for sub in folders {
        std::fs::create_dir(dir.path().join(sub)).unwrap();
    }
    for (path, value) in images {
        flat(&dir.path().join(path), *value);
    }
    dir
}

/// A reference whose mean over a group and a view is 0 printed `NaN%` (JSON null, no
/// word why) with exit 0. The table has `-` there and a note naming the group and the
/// view; the JSON has null and the same reason; a reference black over every pixel
/// compared is an error naming it.
#[test]
fn compare_views_says_where_the_reference_is_zero_instead_of_printing_nan() {
    let dir = two_views_with(
        &["A", "B", "black"],
        &[
            ("A/a.exr", 0.0),
            ("A/b.exr", 1.0),
            ("B/a.exr", 0.5),
            ("B/b.exr", 1.1),
            ("black/a.exr", 0.0),
            ("black/b.exr", 0.0),
        ],
    );
    let run = relume(
        dir.path(),
        &[
            "compare",
            "views",
            "scene.toml",
            "A",
            "B",
            "--json",
            "out.json",
        ],
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{stdout}");
    assert!(!stdout.to_lowercase().contains("nan"), "{stdout}");
    let floor = stdout.lines().find(|l| l.starts_with("floor ")).unwrap();
    let last: Vec<&str> = floor.split_whitespace().rev().take(2).collect();
    assert_eq!(last, ["-", "-"], "{floor}");
    assert!(
        stdout.contains(
            "note: group 'floor' (in views a): the reference (A) is 0 over its 64 pure pixels"
        ) && stdout.contains("note: view 'a': the reference (A) is 0"),
        "{stdout}"
    );
    let shelf = stdout.lines().find(|l| l.starts_with("shelf ")).unwrap();
    assert!(shelf.contains("+10.00%"), "{shelf}");
    let text = std::fs::read_to_string(dir.path().join("out.json")).unwrap();
    assert!(!text.contains("NaN"), "{text}");
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let floor = &json["groups"][0];
    assert!(floor["rel_mean_diff"].is_null() && floor["rel_rms"].is_null());
    assert!(
        floor["undefined"]
            .as_str()
            .unwrap()
            .contains("the reference (A) is 0"),
        "{floor}"
    );
    assert!(json["groups"][1].get("undefined").is_none());

    let run = relume(
        dir.path(),
        &["compare", "views", "scene.toml", "black", "B"],
    );
    fails(
        &run,
        INPUT,
        &["black: the reference (A) is 0 over all 128 pure pixels"],
    );
    assert!(run.stdout.is_empty());
}

/// `--independent B2` adds each row's misfit, the relative RMS with two renders' noise
/// taken out, and its mean bias, the same for the mean: flat renders 10% bright read +10%
/// and +10% (their errors agree), a B2 10% dark against them -10% and 0 (under the noise);
/// a group whose reference is 0 has neither, as it has no RMS; the JSON has them beside the
/// RMS, and leaves them out without B2. B's own folder given as
/// B2 (which would read the RMS as the misfit), A's (a misfit of 0), A's folder as B, and
/// a B2 missing a view's image are refused, naming them. A B2 image of the same bytes as
/// B's (two renders on one seed) is warned of.
#[test]
fn compare_views_with_an_independent_render_gives_the_misfit() {
    let dir = two_views_with(
        &["A", "B", "same", "dark"],
        &[
            ("A/a.exr", 0.0),
            ("A/b.exr", 1.0),
            ("B/a.exr", 0.5),
            ("B/b.exr", 1.1),
            ("same/a.exr", 0.5),
            ("same/b.exr", 1.1),
            ("dark/a.exr", 0.5),
            ("dark/b.exr", 0.9),
        ],
    );
    // `compare views scene.toml A B`, then `more`.
    let views = |more: &[&str]| {
        let args = [&["compare", "views", "scene.toml", "A", "B"][..], more].concat();
        relume(dir.path(), &args)
    };
    let compare = |b2: &str| {
        let run = views(&["--independent", b2, "--json", &format!("{b2}.json")]);
        let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
        let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
        assert!(run.status.success(), "{stdout}");
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join(format!("{b2}.json"))).unwrap(),
        )
        .unwrap();
        (stdout, json, stderr)
    };
    // The last three figures of a group's line: its relative RMS, misfit and mean bias.
    let last_three = |stdout: &str, group: &str| -> Vec<String> {
        let line = stdout.lines().find(|l| l.starts_with(group)).unwrap();
        let mut words: Vec<String> = line
            .split_whitespace()
            .rev()
            .take(3)
            .map(String::from)
            .collect();
        words.reverse();
        words
    };
    // B2 the same bytes as B, as two renders on one seed are: the misfit is the RMS (right
    // for these noise-free images), and the run says so of each view.
    let (stdout, json, stderr) = compare("same");
    for view in ["a", "b"] {
        assert!(
            stderr.contains(&format!(
                "warning: view '{view}': same{}{view}.exr holds the same bytes as B{}{view}.exr",
                std::path::MAIN_SEPARATOR,
                std::path::MAIN_SEPARATOR
            )),
            "{stderr}"
        );
    }
    assert!(
        stdout
            .lines()
            .next()
            .unwrap()
            .ends_with("misfit  mean bias"),
        "{stdout}"
    );
    assert_eq!(
        last_three(&stdout, "shelf "),
        ["10.00%", "+10.00%", "+10.00%"],
        "{stdout}"
    );
    assert_eq!(last_three(&stdout, "floor "), ["-", "-", "-"], "{stdout}");
    let shelf = &json["groups"][1];
    for figure in ["rel_misfit", "rel_mean_bias"] {
        assert!(
            (shelf[figure].as_f64().unwrap() - 0.1).abs() < 1e-6,
            "{figure}: {shelf}"
        );
        assert!(json["groups"][0][figure].is_null());
    }

    let (stdout, _, stderr) = compare("dark");
    // Its view b differs from B's; its view a is B's flat 0.5 again.
    assert!(!stderr.contains("view 'b'"), "{stderr}");
    assert!(stderr.contains("warning: view 'a'"), "{stderr}");
    assert_eq!(
        last_three(&stdout, "shelf "),
        ["10.00%", "-10.00%", "+0.00%"],
        "{stdout}"
    );

    let run = views(&["--json", "plain.json"]);
    assert!(run.status.success());
    let text = std::fs::read_to_string(dir.path().join("plain.json")).unwrap();
    assert!(
        !text.contains("rel_misfit") && !text.contains("rel_mean_bias"),
        "{text}"
    );
    assert!(!String::from_utf8_lossy(&run.stdout).contains("misfit"));

    let run = views(&["--independent", "./B/"]);
    fails(&run, USAGE, &["--independent ./B/ is B's folder"]);
    // A's folder read a misfit of exactly 0 on every row.
    let run = views(&["--independent", "A"]);
    fails(
        &run,
        USAGE,
        &["--independent A is A's, the reference folder"],
    );

    // A folder compared with itself read 0 on every row, as a perfect fit would.
    let run = relume(dir.path(), &["compare", "views", "scene.toml", "A", "./A/"]);
    fails(&run, USAGE, &["A and B are the same folder (./A/)"]);
    assert!(run.stdout.is_empty());

    std::fs::remove_file(dir.path().join("dark/b.exr")).unwrap();
    // A file that cannot be read is an I/O error (4), as for A's and B's images.
    fails(
        &views(&["--independent", "dark"]),
        4,
        &["dark/b.exr: no image of view 'b' in dark"],
    );
}

/// `compare views --view NAME` compares those views alone, as `render --view` renders
/// them: the folders need no image of the other views, and the table has no row for
/// them. Without the flag the missing image is named; a name that is no view of the
/// scene lists the views it has.
#[test]
fn compare_views_of_some_views_needs_only_their_images() {
    let dir = two_views_with(
        &["A", "B"],
        &[("A/a.exr", 1.0), ("A/b.exr", 1.0), ("B/b.exr", 1.1)],
    );
    let views = |more: &[&str]| {
        let args = [&["compare", "views", "scene.toml", "A", "B"][..], more].concat();
        relume(dir.path(), &args)
    };

    let run = views(&["--view", "b"]);
    let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
    assert!(run.status.success(), "{stdout}");
    let shelf = stdout.lines().find(|l| l.starts_with("shelf ")).unwrap();
    assert!(shelf.contains("+10.00%"), "{shelf}");
    assert!(
        !stdout.lines().any(|l| l.starts_with("a ")),
        "view a has a row: {stdout}"
    );
    let image = stdout.lines().find(|l| l.starts_with("image ")).unwrap();
    assert!(image.contains("+10.00%"), "{image}");

    fails(&views(&[]), 4, &["B/a.exr"]);
    fails(
        &views(&["--view", "c"]),
        USAGE,
        &["--view c: scene.toml has no such view (its views: a, b)"],
    );
}

/// The scene's own panorama folder given as A (the README's `compare views scene.toml
/// views out` of a reference) is read with its views' exposure, as check and recover read
/// the panorama: read at exposure 1, a view of exposure 2 compared +100% off a render of
/// the very radiance it holds, without a word. Given as B, the same.
#[test]
fn compare_views_reads_the_scenes_own_images_with_their_exposure() {
    let dir = tempfile::tempdir().unwrap();
    let scene = TWO_VIEWS
        .replace(
            "name = \"a\"\n",
            "name = \"a\"\nimage = \"pano/a.exr\"\nexposure = 2.0\n",
        )
        .replace("name = \"b\"\n", "name = \"b\"\nimage = \"pano/b.exr\"\n");
    std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
    std::fs::write(dir.path().join("geo.obj"), TWO_QUADS).unwrap();
    for sub in ["pano", "render"] {
        std::fs::create_dir(dir.path().join(sub)).unwrap();
    }
    flat(&dir.path().join("pano/a.exr"), 0.5);
    flat(&dir.path().join("pano/b.exr"), 1.0);
    flat(&dir.path().join("render/a.exr"), 1.0);
    flat(&dir.path().join("render/b.exr"), 1.0);
    for (a, b) in [("pano", "render"), ("render", "./pano/")] {
        let run = relume(dir.path(), &["compare", "views", "scene.toml", a, b]);
        let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
        assert!(run.status.success(), "{stdout}");
        for row in ["floor ", "shelf ", "a ", "image "] {
            let line = stdout.lines().find(|l| l.starts_with(row)).unwrap();
            assert!(line.contains("+0.00%"), "{a} against {b}: {line}");
        }
    }
}

/// An image linked into both folders (or hard-linked) compared with itself as the folders
/// are refused for: its view read 0 on every row, and B's image as B2's gave its whole RMS
/// as the misfit. Refused, naming the view and both files.
#[test]
fn compare_views_refuses_one_image_in_both_folders() {
    let dir = two_views_with(
        &["A", "B", "B2"],
        &[("A/a.exr", 1.0), ("A/b.exr", 1.0), ("B/a.exr", 1.1)],
    );
    std::os::unix::fs::symlink("../A/b.exr", dir.path().join("B/b.exr")).unwrap();
    let run = relume(dir.path(), &["compare", "views", "scene.toml", "A", "B"]);
    fails(&run, USAGE, &["A/b.exr and B/b.exr are one file: view 'b'"]);
    assert!(run.stdout.is_empty());

    std::fs::remove_file(dir.path().join("B/b.exr")).unwrap();
    flat(&dir.path().join("B/b.exr"), 1.1);
    std::fs::hard_link(dir.path().join("B/a.exr"), dir.path().join("B2/a.exr")).unwrap();
    flat(&dir.path().join("B2/b.exr"), 1.2);
    let with_b2 = || {
        let args = [
            "compare",
            "views",
            "scene.toml",
            "A",
            "B",
            "--independent",
            "B2",
        ];
        relume(dir.path(), &args)
    };
    let run = with_b2();
    fails(
        &run,
        USAGE,
        &["--independent's image of view 'a', B2/a.exr, is B's (B/a.exr)"],
    );
    std::fs::remove_file(dir.path().join("B2/a.exr")).unwrap();
    flat(&dir.path().join("B2/a.exr"), 1.2);
    let run = with_b2();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}
