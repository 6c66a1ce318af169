//! `relume bench tradeoff` end to end on the bundled scene (--quick): the CSV has one row
//! per point of the sweep with figures that make sense, points with the same knobs share
//! one run, and the chart is an SVG with a curve per knob. Bad input names the file.

#[path = "common/mod.rs"]
mod common;

use std::path::PathBuf;

use common::{path_str, relume, relume_ok, workspace};

/// The arguments of `relume bench <command>` on the bundled scene, judged against
/// `truth` (a path as given), into `out`, then `extra`.
fn bench_on_cornell(
    command: &str,
    truth: &str,
    out: &std::path::Path,
    extra: &[&str],
) -> Vec<String> {
    let scene = workspace().join("scenes/cornell/scene.toml");
    let mut args: Vec<String> = [
        "bench",
        command,
        path_str(&scene),
        "--truth",
        truth,
        "--out",
        path_str(out),
    ]
    .map(String::from)
    .to_vec();
    args.extend(extra.iter().map(|a| a.to_string()));
    args
}

/// [`bench_on_cornell`] judged against the scene's own materials.
fn bench_on_cornell_truth(command: &str, out: &std::path::Path, extra: &[&str]) -> Vec<String> {
    let truth = workspace().join("scenes/cornell/materials.toml");
    bench_on_cornell(command, path_str(&truth), out, extra)
}

fn strs(args: &[String]) -> Vec<&str> {
    args.iter().map(String::as_str).collect()
}

#[test]
fn quick_tradeoff_writes_a_row_per_point_and_a_chart() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("tradeoff");
    let args = bench_on_cornell_truth("tradeoff", &out, &["--quick", "--threads", "2"]);
    let output = relume_ok(tmp.path(), &strs(&args));
    let text = std::fs::read_to_string(out.join("tradeoff.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    for r in &rows {
        assert_eq!(r.len(), header.len(), "{r:?}");
    }
    let points: Vec<(&str, &str)> = rows.iter().map(|r| (r[0], r[1])).collect();
    // The quick sweep from `fast` (levels 4, loop spp 8) on 32 px views: half and base.
    assert_eq!(
        points,
        [
            ("effort", "fast"),
            ("anneal-levels", "2"),
            ("anneal-levels", "4"),
            ("nelder-mead", "2"),
            ("nelder-mead", "4"),
            ("loop-spp", "4"),
            ("loop-spp", "8"),
            ("resolution", "16"),
            ("resolution", "32"),
        ]
    );
    let num = |r: &Vec<&str>, name: &str| -> f64 { r[col(name)].parse().unwrap() };
    for r in &rows {
        assert!(num(r, "seconds") > 0.0);
        let cpu = r[col("cpu_seconds")];
        assert!(cpu.is_empty() || cpu.parse::<f64>().unwrap() > 0.0, "{cpu}");
        assert_eq!(num(r, "groups"), 9.0, "every group of the truth is judged");
        let accuracy = num(r, "class_accuracy");
        assert!((0.0..=1.0).contains(&accuracy));
        assert!((accuracy * 9.0 - num(r, "classes_right")).abs() < 1e-3);
        for e in [
            "param_err",
            "image_err",
            "image_err_weighted",
            "diffuse_err",
        ] {
            assert!(num(r, e).is_finite() && num(r, e) >= 0.0, "{e} in {r:?}");
        }
        assert!(out.join(r[col("run")]).join("materials.toml").is_file());
    }
    let optimiser = |i: usize| rows[i][col("optimiser")];
    assert_eq!((optimiser(2), optimiser(4)), ("annealing", "nelder-mead"));
    assert_eq!(rows[7][col("px_per_side")], "16");
    // The base point (effort fast = levels 4 = loop spp 8 = 32 px) runs once.
    let base: Vec<&Vec<&str>> = [0, 2, 6, 8].iter().map(|&i| &rows[i]).collect();
    assert!(base.iter().all(|r| r[col("run")] == base[0][col("run")]));
    assert!(base
        .iter()
        .all(|r| r[col("param_err")] == base[0][col("param_err")]));
    assert_ne!(rows[3][col("run")], rows[4][col("run")]);

    let svg = std::fs::read_to_string(out.join("tradeoff.svg")).unwrap();
    assert!(svg.starts_with("<svg ") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.matches("<polyline").count() >= 4, "a curve per knob");
    for knob in [
        "effort",
        "anneal-levels",
        "nelder-mead",
        "loop-spp",
        "resolution",
    ] {
        assert!(
            svg.contains(&format!(">{knob}</text>")),
            "legend lacks {knob}"
        );
    }
    // The same chart as PNG, of the SVG's size.
    let png = image::open(out.join("tradeoff.png")).unwrap();
    let size = |attribute: &str| -> u32 {
        let at = svg.find(&format!(" {attribute}=\"")).unwrap() + attribute.len() + 3;
        svg[at..].split('"').next().unwrap().parse().unwrap()
    };
    assert_eq!((png.width(), png.height()), (size("width"), size("height")));
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(stdout.contains("nelder-mead") && stdout.contains("tradeoff.png"));
}

#[test]
fn a_missing_truth_is_an_error_naming_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    for command in ["tradeoff", "stability"] {
        let args = bench_on_cornell(command, "no-such-truth.toml", &tmp.path().join("out"), &[]);
        let output = relume(tmp.path(), &strs(&args));
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(4), "{stderr}");
        assert!(stderr.contains("no-such-truth.toml"), "{stderr}");
    }
    // A flag's value that names nothing is a usage error (2), as `render --view` is, and
    // makes no folder; a family that is none lists the families.
    let refused = |flags: &[&str], told: &[&str]| {
        let args = bench_on_cornell_truth("stability", &tmp.path().join("out"), flags);
        let output = relume(tmp.path(), &strs(&args));
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{stderr}");
        assert!(told.iter().all(|t| stderr.contains(t)), "{stderr}");
        assert!(!tmp.path().join("out").exists());
    };
    refused(
        &["--group", "no_such_group"],
        &["scene.toml", "no_such_group", "its groups: floor"],
    );
    refused(
        &["--families", "seed,exposures"],
        &[
            "exposures",
            "seed, noise, exposure, light, resolution, pixels",
        ],
    );
}

#[test]
fn a_thread_count_out_of_range_is_refused_before_the_output_folder_is_made() {
    // Tradeoff told its first run and stability made --out before the pool refused it.
    let tmp = tempfile::tempdir().unwrap();
    for command in ["tradeoff", "stability"] {
        let out = tmp.path().join(command);
        let args = bench_on_cornell_truth(command, &out, &["--quick", "--threads", "0"]);
        let output = relume(tmp.path(), &strs(&args));
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{command}: {stderr}");
        assert!(stderr.contains("--threads"), "{command}: {stderr}");
        assert!(!stderr.contains("recovering"), "{command}: {stderr}");
        assert!(!out.exists(), "{command}: {} was made", out.display());
    }
}

/// Writes an edit of the bundled scene into `dir/<name>/scene.toml`: its geometry plus
/// `extra_obj`, its panorama as the reference images, and `extra_group` appended.
fn cornell_edit(dir: &std::path::Path, name: &str, extra_obj: &str, extra_group: &str) -> PathBuf {
    let cornell = workspace().join("scenes/cornell");
    let mut text = std::fs::read_to_string(cornell.join("scene.toml")).unwrap();
    let geometry = cornell.join("geometry.obj");
    let mut files = vec![format!("\"{}\"", path_str(&geometry))];
    if !extra_obj.is_empty() {
        files.push(format!("\"{extra_obj}\""));
    }
    text = text.replace(
        "geometry = [\"geometry.obj\"]",
        &format!("geometry = [{}]", files.join(", ")),
    );
    text = text.replace(
        "image = \"views/",
        &format!("image = \"{}/", path_str(&cornell.join("views"))),
    );
    text.push_str(extra_group);
    let edit = dir.join(name);
    std::fs::create_dir_all(&edit).unwrap();
    std::fs::write(edit.join("scene.toml"), text).unwrap();
    edit.join("scene.toml")
}

/// The edits.csv rows as (edit, column -> value).
fn edits_csv(out: &std::path::Path) -> Vec<std::collections::BTreeMap<String, String>> {
    let text = std::fs::read_to_string(out.join("edits.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(String::from))
                .collect()
        })
        .collect()
}

#[test]
fn edits_judge_a_model_by_the_error_it_adds_to_the_true_materials() {
    let root = workspace();
    let tmp = tempfile::tempdir().unwrap();
    let truth = root.join("scenes/cornell/materials.toml");
    // The identity edit (the panorama itself), and one that puts the vase in, whose
    // material comes from a materials.toml beside its scene.toml.
    let same = cornell_edit(tmp.path(), "same", "", "");
    let vase = root.join("scenes/cornell-insert/vase.obj");
    let insert = cornell_edit(
        tmp.path(),
        "insert",
        path_str(&vase),
        "\n[[group]]\nname = \"vase\"\nkind = \"plastic\"\nobjects = [\"vase\"]\n",
    );
    // Without the vase's material the edit is an input error naming the group.
    let missing = relume(
        tmp.path(),
        &[
            "bench",
            "edits",
            path_str(&insert),
            "--recovered",
            path_str(&truth),
            "--truth",
            path_str(&truth),
            "--out",
            "out-missing",
            "--spp",
            "4",
        ],
    );
    assert_eq!(missing.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("'vase'"));
    std::fs::copy(
        root.join("scenes/cornell-insert/inserted-materials.toml"),
        tmp.path().join("insert/materials.toml"),
    )
    .unwrap();

    // A model whose red wall is 30% too bright.
    let text = std::fs::read_to_string(&truth).unwrap();
    let bright = text.replace("color = [0.63, 0.12, 0.1]", "color = [0.819, 0.156, 0.13]");
    assert_ne!(bright, text, "the red wall's colour is in the truth file");
    let wrong = tmp.path().join("bright-red.toml");
    std::fs::write(&wrong, bright).unwrap();

    let run = |recovered: &std::path::Path, out: &str| {
        let output = relume_ok(
            tmp.path(),
            &[
                "bench",
                "edits",
                path_str(&same),
                path_str(&insert),
                "--recovered",
                path_str(recovered),
                "--truth",
                path_str(&truth),
                "--out",
                out,
                "--spp",
                "16",
                "--threads",
                "2",
            ],
        );
        (
            edits_csv(&tmp.path().join(out)),
            String::from_utf8_lossy(&output.stdout).to_string(),
        )
    };

    // The true materials as the "recovered" model: the same renders, a ratio of 1, as
    // the errors are and with the render noise taken out (a second render on seed + 1),
    // which is less than the noise left in.
    let (rows, _) = run(&truth, "out-truth");
    assert_eq!(rows.len(), 2);
    for row in &rows {
        assert_eq!(row["rms_ratio"], "1.000000", "{row:?}");
        assert_eq!(row["within_goal"], "true", "{row:?}");
        assert_eq!(row["misfit_ratio"], "1.000000", "{row:?}");
        assert_eq!(row["group_mean_bias_ratio"], "1.000000", "{row:?}");
        assert_eq!(row["within_goal_noise_out"], "true", "{row:?}");
        let figure = |column: &str| row[column].parse::<f64>().unwrap();
        assert!(figure("rel_rms_truth") > 0.0, "{row:?}");
        // At 16 spp the renders' noise is most of the RMS.
        assert!(figure("misfit_truth") < figure("rel_rms_truth"), "{row:?}");
    }
    for arm in ["recovered", "recovered-independent"] {
        let image = tmp.path().join("out-truth/insert").join(arm).join("px.exr");
        assert!(image.is_file(), "{}", image.display());
    }

    // The bright wall adds error in both edits, with the noise in and out, and the table
    // names the wall.
    let (rows, table) = run(&wrong, "out-wrong");
    for row in &rows {
        for ratio in ["group_mean_ratio", "group_mean_bias_ratio", "misfit_ratio"] {
            let value: f64 = row[ratio].parse().unwrap();
            assert!(value > 1.2, "{ratio}: {row:?}");
        }
        assert_eq!(row["within_goal"], "false", "{row:?}");
        assert_eq!(row["within_goal_noise_out"], "false", "{row:?}");
    }
    assert!(
        table.contains("most added bias (noise out) in wall_red"),
        "{table}"
    );
}
