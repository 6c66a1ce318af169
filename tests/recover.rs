//! `relume recover` end to end: determinism across thread counts, the golden
//! materials.toml of our bundled scene, the all-diffuse reference coming out diffuse, and
//! weak lobes, textures and a large group's lobe found on the references, and kind "auto"
//! on the bundled scene.

#[path = "common/mod.rs"]
mod common;

use common::{copy_cornell, path_str, relume_ok, shared, workspace};

fn recover(scene: &std::path::Path, out: &std::path::Path, extra: &[&str]) -> Vec<u8> {
    let mut args = vec!["recover", path_str(scene), "--out", path_str(out)];
    args.extend_from_slice(extra);
    relume_ok(out.parent().unwrap(), &args);
    std::fs::read(out.join("materials.toml")).unwrap()
}

/// A recovered reference: the temporary folder (kept alive by the caller), the output
/// folder, and its materials compared with the truth.
type RecoveredReference = (
    tempfile::TempDir,
    std::path::PathBuf,
    Vec<relume::compare::MaterialRow>,
);

/// A reference's small scene (`bench/<name>/scene-small.toml`, 64x64 per face) recovered
/// at effort fast, seed 1 (see [`recover_reference`]).
fn recover_small_reference(name: &str) -> RecoveredReference {
    recover_reference(name, "scene-small.toml", "1")
}

/// Reference `name`'s `scene` (`scene.toml` at 256 px per face, or `scene-small.toml`)
/// recovered at effort fast on `seed` into a temporary folder, its materials compared with
/// the truth (printed, for failures).
fn recover_reference(name: &str, scene: &str, seed: &str) -> RecoveredReference {
    recover_reference_at(name, scene, seed, "fast")
}

/// [`recover_reference`] at effort `effort`.
fn recover_reference_at(name: &str, scene: &str, seed: &str, effort: &str) -> RecoveredReference {
    let bench = shared().join("bench").join(name);
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rec");
    recover(
        &bench.join(scene),
        &out,
        &["--effort", effort, "--seed", seed],
    );
    let rows =
        relume::compare::materials_report(&bench.join("truth.toml"), &out.join("materials.toml"))
            .unwrap();
    for r in &rows {
        println!("{r:?}");
    }
    (tmp, out, rows)
}

/// A reference's 64-px scene recovered at effort fast on a seed, once for the tests that
/// read it (into the integration tests' scratch folder): the output folder and its
/// materials compared with the truth.
type SharedRecovery = (std::path::PathBuf, Vec<relume::compare::MaterialRow>);

fn small_reference_once(
    name: &str,
    seed: &str,
    cell: &'static std::sync::OnceLock<SharedRecovery>,
) -> &'static SharedRecovery {
    cell.get_or_init(|| {
        let bench = shared().join("bench").join(name);
        let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("{name}-small-fast-{seed}"));
        if out.exists() {
            std::fs::remove_dir_all(&out).unwrap();
        }
        recover(
            &bench.join("scene-small.toml"),
            &out,
            &["--effort", "fast", "--seed", seed],
        );
        let rows = relume::compare::materials_report(
            &bench.join("truth.toml"),
            &out.join("materials.toml"),
        )
        .unwrap();
        for r in &rows {
            println!("{r:?}");
        }
        (out, rows)
    })
}

/// The living room at 64 px, seed 1 (see [`small_reference_once`]).
fn living_room_small() -> &'static SharedRecovery {
    static RECOVERED: std::sync::OnceLock<SharedRecovery> = std::sync::OnceLock::new();
    small_reference_once("living-room", "1", &RECOVERED)
}

/// Glossy at 64 px, seed 1 (see [`small_reference_once`]).
fn glossy_small() -> &'static SharedRecovery {
    static RECOVERED: std::sync::OnceLock<SharedRecovery> = std::sync::OnceLock::new();
    small_reference_once("glossy", "1", &RECOVERED)
}

/// Glossy at 64 px, seed 4 (see [`small_reference_once`]).
fn glossy_small_seed_4() -> &'static SharedRecovery {
    static RECOVERED: std::sync::OnceLock<SharedRecovery> = std::sync::OnceLock::new();
    small_reference_once("glossy", "4", &RECOVERED)
}

/// Glossy at 64 px, seed 24 (see [`small_reference_once`]).
fn glossy_small_seed_24() -> &'static SharedRecovery {
    static RECOVERED: std::sync::OnceLock<SharedRecovery> = std::sync::OnceLock::new();
    small_reference_once("glossy", "24", &RECOVERED)
}

/// Asserts that group `name` is recovered in its true class with its specularity and
/// roughness within the given relative errors of the truth.
fn assert_lobe_near_truth(
    rows: &[relume::compare::MaterialRow],
    name: &str,
    max_specularity_err: f64,
    max_roughness_err: f64,
) {
    let row = rows
        .iter()
        .find(|r| r.group == name)
        .unwrap_or_else(|| panic!("no group {name} in the comparison"));
    assert!(row.class_ok, "{row:?}");
    assert!(
        row.specularity_rel_err.unwrap() <= max_specularity_err,
        "{row:?}"
    );
    assert!(
        row.roughness_rel_err.unwrap() <= max_roughness_err,
        "{row:?}"
    );
}

/// The report.json of the recovery in `out`.
fn report_json(out: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

/// Group `name`'s entry in the report.json of the recovery in `out`.
fn group_report(out: &std::path::Path, name: &str) -> serde_json::Value {
    report_json(out)["groups"]
        .as_array()
        .unwrap()
        .iter()
        .find(|g| g["group"] == name)
        .unwrap_or_else(|| panic!("no group {name} in the report"))
        .clone()
}

/// The evaluations a group's report (`group_report`) charges it in `stage`.
fn stage_evaluations(report: &serde_json::Value, stage: &str) -> u64 {
    report["work"]
        .as_array()
        .unwrap()
        .iter()
        .find(|w| w["stage"] == stage)
        .and_then(|w| w["evaluations"].as_u64())
        .unwrap_or_else(|| panic!("no {stage} work in {report}"))
}

/// What report.json charges each group (`work`) adds up, stage by stage, to no more than
/// the stage's own evaluations and time; every group with a lobe was charged stage 2 and
/// the colour polish, and every group the uncertainty stage.
fn assert_group_work_within_its_stages(out: &std::path::Path) {
    let report = report_json(out);
    let groups = report["groups"].as_array().unwrap();
    for stage in report["stages"].as_array().unwrap() {
        let name = stage["stage"].as_str().unwrap();
        let charged: Vec<&serde_json::Value> = groups
            .iter()
            .flat_map(|g| g["work"].as_array().unwrap())
            .filter(|w| w["stage"] == name)
            .collect();
        let evaluations: u64 = charged
            .iter()
            .map(|w| w["evaluations"].as_u64().unwrap())
            .sum();
        let seconds: f64 = charged.iter().map(|w| w["seconds"].as_f64().unwrap()).sum();
        assert!(
            evaluations <= stage["evaluations"].as_u64().unwrap()
                && seconds <= stage["seconds"].as_f64().unwrap(),
            "{name}: groups charged {evaluations} evaluations in {seconds} s: {stage}"
        );
    }
    for g in groups {
        let stages = stage_names(&g["work"]);
        assert!(stages.contains(&"uncertainty"), "{g}");
        if !matches!(g["model"].as_str().unwrap(), "diffuse" | "unseen") {
            assert!(
                stages.contains(&"2 isotropic"),
                "{}: {stages:?}",
                g["group"]
            );
        }
    }
}

/// The `stage` of each entry of a report's array (its `stages`, or a group's `work`), in
/// order.
fn stage_names(entries: &serde_json::Value) -> Vec<&str> {
    entries
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["stage"].as_str().unwrap())
        .collect()
}

/// A group report's decisions, in order.
fn decisions(group_report: &serde_json::Value) -> Vec<&str> {
    group_report["decisions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d.as_str().unwrap())
        .collect()
}

/// Group `group`'s material in the recovered materials.toml under `out`.
fn recovered_material(out: &std::path::Path, group: &str) -> relume::materials_file::MaterialDesc {
    let recovered = relume::materials_file::load_materials(&out.join("materials.toml")).unwrap();
    recovered
        .materials
        .into_iter()
        .find(|m| m.group == group)
        .unwrap()
}

/// The first of a group report's comparisons that `matches`.
fn comparison(
    group: &serde_json::Value,
    matches: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    group["comparisons"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| matches(c))
        .unwrap_or_else(|| panic!("no such comparison in {group}"))
        .clone()
}

/// The same scene and seed give the same materials.toml bytes on 1 and 2 threads, and the
/// committed golden (regenerate with RELUME_UPDATE_GOLDEN=1, and say why in the commit).
#[test]
fn cornell_recovery_is_deterministic_and_matches_its_golden() {
    let root = workspace();
    let scene = root.join("scenes/cornell/scene.toml");
    let tmp = tempfile::tempdir().unwrap();
    let fast = ["--effort", "fast", "--seed", "3"];
    let one = recover(
        &scene,
        &tmp.path().join("t1"),
        &[&fast[..], &["--threads", "1"]].concat(),
    );
    let two = recover(
        &scene,
        &tmp.path().join("t2"),
        &[&fast[..], &["--threads", "2"]].concat(),
    );
    assert!(one == two, "materials.toml differs between 1 and 2 threads");

    let golden = root.join("tests/golden/cornell-recover/materials.toml");
    if std::env::var_os("RELUME_UPDATE_GOLDEN").is_some() {
        std::fs::create_dir_all(golden.parent().unwrap()).unwrap();
        std::fs::write(&golden, &one).unwrap();
        return;
    }
    let expected = std::fs::read(&golden).unwrap_or_default();
    if expected != one {
        let new = golden.with_extension("new.toml");
        std::fs::write(&new, &one).unwrap();
        panic!(
            "recovered materials differ from {} (new: {}).\nIf intended: RELUME_UPDATE_GOLDEN=1 cargo test --test recover, and explain it in the commit.",
            golden.display(),
            new.display()
        );
    }
    for file in ["materials.rad", "materials.map", "report.json"] {
        assert!(tmp.path().join("t1").join(file).is_file(), "{file} missing");
    }
    // materials.rad with obj2rad's rules is a whole RADIANCE scene: each object named
    // after its group's primitive (obj2rad named every face "white" without them), and
    // the light as declared.
    let map = std::fs::read_to_string(tmp.path().join("t1/materials.map")).unwrap();
    let rad = std::fs::read_to_string(tmp.path().join("t1/materials.rad")).unwrap();
    for rule in [
        "wall_red (Object \"wall_left\") ;",
        "walls_white (Object \"wall_front\") ;",
        "light_light (Object \"light\") ;",
    ] {
        assert!(map.contains(rule), "{rule}: {map}");
    }
    assert!(
        rad.contains("\nvoid light light_light\n0\n0\n3 30 28 24\n"),
        "{rad}"
    );
    assert_group_work_within_its_stages(&tmp.path().join("t1"));
    // Walls and floor pass stage 4's gate (DIFFUSE_THRESHOLD) on stage 1's errors, read
    // before stage 2 found the mirror and the metals (the floor and the green wall at
    // 0.062 and 0.065 here; which walls do depends on stage 1's noise). Measured again
    // under the scene as stage 4 finds it (0.02-0.03), they stay diffuse without its
    // search: no cache, no anisotropic fit, no comparison.
    let report = report_json(&tmp.path().join("t1"));
    let through_the_gate: Vec<&serde_json::Value> = report["groups"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|g| g["model"] == "diffuse")
        .filter(|g| g["error_decided"].as_f64().unwrap() > relume_core::fit::DIFFUSE_THRESHOLD)
        .collect();
    assert!(
        through_the_gate.len() >= 2,
        "no longer two diffuse groups reach stage 4's gate: {report}"
    );
    for group in through_the_gate {
        let name = &group["group"];
        assert!(
            decisions(group)
                .iter()
                .any(|d| d.starts_with("stage 4: stays diffuse without a search")),
            "{name}: {group}"
        );
        let comparisons = group["comparisons"].as_array().unwrap();
        assert!(
            comparisons.iter().all(|c| c["stage"] != "4 anisotropic"),
            "{name}: {group}"
        );
    }
    // Beside the bytes, what they mean: every group in its true class, the anisotropic
    // plate included (its lobe found on stage 4's cache), its direction near the truth's.
    let rows = relume::compare::materials_report(
        &root.join("scenes/cornell/materials.toml"),
        &tmp.path().join("t1/materials.toml"),
    )
    .unwrap();
    for row in &rows {
        println!("{row:?}");
        assert!(row.class_ok, "{}: wrong class", row.group);
    }
    let plate = rows.iter().find(|r| r.group == "plate").unwrap();
    assert!(plate.direction_err_deg.unwrap() < 20.0, "{plate:?}");
    // The plastic box's colour is polished on its diffuse part beside its lobe, and again
    // under the final scene, where it has settled: the second polish moves it by under 1%
    // (0.2-0.8% over seeds 1-6). How far the colour is from the truth follows its weak
    // lobe's error, which varies with the seed (0-10% off over seeds 1-6, 2.7% here with
    // the lobe's specularity 25% off), so it is not asserted at one seed.
    let plastic_box = group_report(&tmp.path().join("t1"), "box");
    let polishes: Vec<f64> = decisions(&plastic_box)
        .iter()
        .filter(|d| d.starts_with("colour polish"))
        .map(|d| {
            let change = d.rsplit("largest change ").next().unwrap();
            change.trim_end_matches('%').parse::<f64>().unwrap() / 100.0
        })
        .collect();
    assert_eq!(polishes.len(), 2, "{plastic_box}");
    assert!(polishes[1] < 0.01, "{polishes:?}");
    // Every group in its true class renders about as well as the truth materials do: the
    // truth's own misfit against this panorama is 2.4-6.2% per group (`compare views
    // --independent`, 1024 spp). The final error is bias-only, so a sharp metal's
    // heavy-tailed noise does not pass for misfit: from one 32-spp render minus its
    // variance estimate the sphere read 35% and the box 0%. Its noise is the two renders'
    // products: a group of a few dozen pixels can read 0 where they outweigh its misfit
    // (the mirror's 42 pixels since the pixels' samples are stratified, whose truth reads
    // 4.6% at 1024 spp), so the floor is asked of groups of 100 pixels or more.
    for group in report_json(&tmp.path().join("t1"))["groups"]
        .as_array()
        .unwrap()
    {
        let error = group["error_final"].as_f64().unwrap();
        let floor = if group["pure_pixels"].as_u64().unwrap() >= 100 {
            0.01
        } else {
            0.0
        };
        assert!(
            (floor..0.08).contains(&error),
            "{}: final error {error}",
            group["group"]
        );
    }
}

/// Glossy's steel box (colour 0.62-0.66, s 0.95, roughness 0.14) with its kind left to
/// the recovery. Its near-grey highlight does not tell the kinds apart in stage 2 (metal
/// 0.0001 +- 0.0005 better), so it stays plastic there; stage 4 then bends the plastic
/// into a broad lobe over a blue diffuse part (s 0.70, roughness 0.27, its specular
/// reflectance 15% off), where stage 2's metal proposal, its colour levelled under the
/// scene as now known, renders better by 0.0304 +- 0.0050 (z 6.1) and is kept: within
/// 1.5% and 4.5% of the truth, as with the kind given.
#[test]
fn glossy_small_finds_its_steel_box_metal_when_stage_4_chooses_the_kind_again() {
    let tmp = tempfile::tempdir().unwrap();
    let bench = shared().join("bench").join("glossy");
    let text = std::fs::read_to_string(bench.join("scene-small.toml")).unwrap();
    let steel = "name = \"metal_steel\"\nkind = \"metal\"";
    assert!(text.contains(steel));
    let auto = text
        .replace(steel, "name = \"metal_steel\"\nkind = \"auto\"")
        .replace(
            "\"geometry.obj\"",
            &format!("{:?}", bench.join("geometry.obj")),
        )
        .replace(
            "\"views-small/",
            &format!("\"{}/views-small/", bench.display()),
        );
    let scene = tmp.path().join("scene.toml");
    std::fs::write(&scene, auto).unwrap();
    let out = tmp.path().join("rec");
    recover(&scene, &out, &["--effort", "fast", "--seed", "1"]);

    let steel = recovered_material(&out, "metal_steel");
    assert_eq!(
        steel.kind,
        Some(relume_core::material::Kind::Metal),
        "{steel:?}"
    );
    let rows =
        relume::compare::materials_report(&bench.join("truth.toml"), &out.join("materials.toml"))
            .unwrap();
    assert_lobe_near_truth(&rows, "metal_steel", 0.05, 0.1);
    let report = group_report(&out, "metal_steel");
    let again = report["decisions"].as_array().unwrap().iter().any(|d| {
        d.as_str()
            .unwrap()
            .starts_with("stage 4: kind auto: metal: again, for the plastic lobe stage 4 kept")
    });
    assert!(again, "{report}");
    assert_eq!(report["kind_choice"]["stage"], 4, "{report}");
}

/// Kind "auto" (a group's material type left to the recovery, a feature the paper does
/// not have): the bundled scene with every group "auto" comes out in its true classes,
/// the gold sphere metal and the blue box plastic. Their highlights' colour tells the
/// kinds apart; the near-grey plate (0.8, 0.8, 0.82) may be either, and a tie goes to
/// plastic. materials.toml says which kind each lobe took, where scene.toml cannot, so
/// the recovered model renders with its own scene: before, `relume render` refused it
/// ("a specular material needs the kind").
#[test]
fn cornell_with_every_kind_auto_finds_its_classes_and_kinds() {
    let tmp = tempfile::tempdir().unwrap();
    let scene_dir = tmp.path().join("auto");
    copy_cornell(&scene_dir);
    let scene = scene_dir.join("scene.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    let auto = text
        .replace("kind = \"plastic\"", "kind = \"auto\"")
        .replace("kind = \"metal\"", "kind = \"auto\"");
    assert_eq!(auto.matches("kind = \"auto\"").count(), 9);
    std::fs::write(&scene, auto).unwrap();
    let out = tmp.path().join("rec");
    recover(&scene, &out, &["--effort", "fast", "--seed", "3"]);

    let rows = relume::compare::materials_report(
        &workspace().join("scenes/cornell/materials.toml"),
        &out.join("materials.toml"),
    )
    .unwrap();
    for row in &rows {
        println!("{row:?}");
        assert!(row.class_ok, "{}: wrong class", row.group);
    }
    let recovered = relume::materials_file::load_materials(&out.join("materials.toml")).unwrap();
    let kind_of = |group: &str| {
        let m = recovered
            .materials
            .iter()
            .find(|m| m.group == group)
            .unwrap();
        m.kind.map(relume::materials_file::kind_name)
    };
    assert_eq!(kind_of("sphere"), Some("metal"));
    assert_eq!(kind_of("box"), Some("plastic"));
    assert!(kind_of("plate").is_some());
    for no_lobe in [
        "floor",
        "ceiling",
        "wall_red",
        "wall_green",
        "walls_white",
        "mirror",
    ] {
        assert_eq!(kind_of(no_lobe), None, "{no_lobe}");
    }
    // The sphere's metal, which a render showed, is not warned of as a kind its panorama
    // does not decide.
    let warnings = report_json(&out)["warnings"].clone();
    assert!(!warnings
        .as_array()
        .unwrap()
        .iter()
        .any(|w| w.as_str().unwrap().starts_with("group 'sphere': kind auto")));
    relume_ok(
        tmp.path(),
        &[
            "render",
            path_str(&scene),
            "--materials",
            path_str(&out.join("materials.toml")),
            "--out",
            path_str(&tmp.path().join("rendered")),
            "--spp",
            "1",
        ],
    );
}

/// An all-diffuse room must come out all diffuse, with every reflectance within 1% of
/// the truth (box-diffuse, 64x64 per face, default effort).
#[test]
fn box_diffuse_small_comes_out_diffuse() {
    let bench = shared().join("bench/box-diffuse");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rec");
    recover(&bench.join("scene-small.toml"), &out, &[]);
    let rows =
        relume::compare::materials_report(&bench.join("truth.toml"), &out.join("materials.toml"))
            .unwrap();
    assert_eq!(rows.len(), 6);
    for row in &rows {
        println!("{row:?}");
        assert!(row.class_ok, "{}: not diffuse", row.group);
        let err = row.diffuse_rel_err.unwrap();
        assert!(
            err <= 0.01,
            "{}: diffuse reflectance off by {:.2}%",
            row.group,
            100.0 * err
        );
    }
    // The reported standard errors cover the truth about as often as they claim: every
    // reflectance has one, none is more than 3 sigma off, and most are within 2.
    let coverage =
        relume::coverage::coverage_rows(&bench.join("truth.toml"), &out.join("report.json"))
            .unwrap();
    assert_eq!(coverage.len(), 18, "{coverage:?}");
    for row in &coverage {
        assert!(row.sigma > 0.0 && row.z <= 3.0, "{row:?}");
    }
    let (_, within_two) = relume::coverage::fractions(&coverage);
    assert!(within_two >= 0.8, "{within_two}");
    // RADIANCE's own render reads its lamp's radiance (to 0.26%, its README): the
    // calibration check finds the lamp in the upward view and warns of nothing.
    let report = report_json(&out);
    let readings = report["light_readings"].as_array().unwrap();
    assert_eq!(readings.len(), 1, "{readings:?}");
    assert_eq!(readings[0]["light"], "ceiling_lamp");
    assert_eq!(readings[0]["view"], "pz");
    for q in readings[0]["ratio"].as_array().unwrap() {
        assert!((q.as_f64().unwrap() - 1.0).abs() < 0.005, "{readings:?}");
    }
    assert!(!report["warnings"].to_string().contains("declared radiance"));
    // Nor does any view's residual lie apart from the others' (at effort fast they lie
    // within 0.8% of the others' median here: docs/stability.md).
    assert!(!report["warnings"]
        .to_string()
        .contains("exposure may be off"));
    // No group has a lobe, so there is no colour to polish under the final scene.
    assert!(!report["stages"]
        .to_string()
        .contains("colour polish under the final scene"));
    // The report traces stage 1 step by step, in time order, and its last step has come
    // within the same 1% of the truth (before the refinement polishes it).
    let steps = report["diffuse_steps"].as_array().unwrap();
    assert!(steps.len() >= 2, "{steps:?}");
    let seconds: Vec<f64> = steps
        .iter()
        .map(|s| s["seconds"].as_f64().unwrap())
        .collect();
    assert!(seconds.windows(2).all(|w| w[0] < w[1]), "{seconds:?}");
    let last = steps.last().unwrap()["reflectances"].as_array().unwrap();
    let truth: toml::Value =
        toml::from_str(&std::fs::read_to_string(bench.join("truth.toml")).unwrap()).unwrap();
    let groups = report["groups"].as_array().unwrap();
    assert_eq!(last.len(), groups.len());
    let mut errors = Vec::new();
    for (group, got) in groups.iter().zip(last) {
        let material = truth["material"]
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["group"].as_str() == group["group"].as_str())
            .unwrap();
        for (c, t) in material["color"].as_array().unwrap().iter().enumerate() {
            let t = t.as_float().unwrap();
            errors.push((got[c].as_f64().unwrap() - t).abs() / t);
        }
    }
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    assert!(mean <= 0.01, "stage 1 ends {:.2}% off", 100.0 * mean);
}

/// A group no view sees whole is not recovered, but rendered as a colour measured on the
/// pixels it shares with its neighbours: with every pure pixel of box-diffuse's walls_ew
/// withheld, that colour lands within 3% of its truth (1.3% at seed 1; 6.3% off in red
/// with its neighbours as stage 1 fitted them beside a grey stand-in, before they were
/// refined and it measured again), and the other groups stay within 1%.
#[test]
fn box_diffuse_small_measures_a_withheld_wall_from_the_pixels_it_shares() {
    let bench = shared().join("bench/box-diffuse");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rec");
    recover(
        &bench.join("scene-small.toml"),
        &out,
        &["--effort", "fast", "--limit-group-pixels", "walls_ew=0"],
    );
    let walls = group_report(&out, "walls_ew");
    assert_eq!(walls["model"], "unseen");
    let decisions = decisions(&walls);
    let last = decisions
        .iter()
        .rev()
        .find_map(|d| d.strip_prefix("stand-in: rendered as the diffuse ["))
        .unwrap_or_else(|| panic!("{decisions:?}"));
    let measured: Vec<f64> = last[..last.find(']').unwrap()]
        .split(", ")
        .map(|v| v.parse().unwrap())
        .collect();
    for (m, truth) in measured.iter().zip([0.35, 0.42, 0.55]) {
        assert!((m / truth - 1.0).abs() < 0.03, "{measured:?}");
    }
    let rows =
        relume::compare::materials_report(&bench.join("truth.toml"), &out.join("materials.toml"))
            .unwrap();
    for row in rows.iter().filter(|r| r.group != "walls_ew") {
        let err = row.diffuse_rel_err.unwrap();
        assert!(err < 0.01, "{}: {:.2}%", row.group, 100.0 * err);
    }
    // The stand-in is written apart from the recovered materials, for a render of the
    // whole scene; a later recovery into the same folder that sees every group removes it.
    let unseen = relume::materials_file::load_materials(&out.join("unseen.toml")).unwrap();
    let groups: Vec<&str> = unseen.materials.iter().map(|m| m.group.as_str()).collect();
    assert_eq!(groups, ["walls_ew"]);
    let written = unseen.materials[0].color.unwrap();
    for (w, m) in written.iter().zip(&measured) {
        assert!((*w as f64 - m).abs() < 1e-4, "{written:?} {measured:?}");
    }
    recover(&bench.join("scene-small.toml"), &out, &["--effort", "fast"]);
    assert!(!out.join("unseen.toml").exists());
}

/// A view of the bundled scene 10% too bright is named in a warning from the lamp it sees,
/// and in one from its residual against the other views' (before these checks nothing in
/// the recovery showed a calibration error: docs/stability.md).
#[test]
fn a_view_too_bright_is_found_from_the_light_it_sees() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("cornell");
    copy_cornell(&scene);
    let text = std::fs::read_to_string(scene.join("scene.toml")).unwrap();
    let pz = text.find("name = \"pz\"").unwrap();
    let exposure = pz + text[pz..].find("exposure = 1.0").unwrap();
    let text = format!(
        "{}exposure = 1.1{}",
        &text[..exposure],
        &text[exposure + "exposure = 1.0".len()..]
    );
    std::fs::write(scene.join("scene.toml"), text).unwrap();
    let out = tmp.path().join("rec");
    let run = relume_ok(
        tmp.path(),
        &[
            "recover",
            path_str(&scene.join("scene.toml")),
            "--out",
            path_str(&out),
            "--effort",
            "fast",
            "--seed",
            "3",
        ],
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        stdout.contains("calibration: light 'light' in view 'pz' reads 1.100 1.100 1.100 x"),
        "{stdout}"
    );
    let report = report_json(&out);
    let warnings_where = |keep: fn(&str) -> bool| -> Vec<&str> {
        let all = report["warnings"].as_array().unwrap().iter();
        all.filter_map(|w| w.as_str()).filter(|w| keep(w)).collect()
    };
    let calibration = warnings_where(|w| w.contains("declared radiance"));
    assert_eq!(calibration.len(), 1, "{calibration:?}");
    // A warning about the input is printed once, before the work, not again at the end.
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(
        stderr.matches("light 'light' reads 1.100x").count(),
        1,
        "{stderr}"
    );
    assert!(
        calibration[0].contains("light 'light' reads 1.100x")
            && calibration[0].contains("in view 'pz'"),
        "{calibration:?}"
    );
    // Every view with enough boundaries between groups is read for its orientation, each
    // the right way round (no "view '...'" warning but pz's, below).
    let orientations = report["orientation_readings"].as_array().unwrap();
    let judged: Vec<&str> = orientations
        .iter()
        .map(|r| r["view"].as_str().unwrap())
        .collect();
    assert_eq!(judged, ["px", "nx", "py", "nz"], "{orientations:?}");
    // The view check, which needs no light, finds the same view apart from the others
    // (its residual -5.7% +- 1.0% against a median of +0.1% at seed 3), and no other.
    let views = warnings_where(|w| w.starts_with("view '"));
    assert_eq!(views.len(), 1, "{views:?}");
    assert!(
        views[0].starts_with("view 'pz'") && views[0].contains("exposure may be off"),
        "{views:?}"
    );
}

/// The textured reference at 64x64 per face (effort fast): the three pictures found
/// textured, the checker's anisotropic lobe found on its untextured stand-in (the paper's
/// textured-anisotropic step) with its direction and roughnesses near the truth, the
/// stripes' pattern not taken for an anisotropic lobe (stage 4's pattern test), every map
/// within 2 dB of the ceiling that its size allows (finer detail is not in the views), and
/// every picture's own pixels explained by its map and lobe.
#[test]
fn textured_small_finds_the_textured_anisotropic_picture() {
    let (_tmp, out, rows) = recover_small_reference("textured");
    let row = |g: &str| rows.iter().find(|r| r.group == g).unwrap();
    let checker = row("picture_checker");
    assert_eq!(
        checker.model.as_deref(),
        Some("textured-anisotropic"),
        "{checker:?}"
    );
    assert!(checker.direction_err_deg.unwrap() < 10.0, "{checker:?}");
    assert!(checker.roughness_u_rel_err.unwrap() < 0.25, "{checker:?}");
    assert!(checker.roughness_v_rel_err.unwrap() < 0.25, "{checker:?}");
    assert!(row("picture_flowers").class_ok);
    // The stripes' pattern lines up with an anisotropic lobe on the stand-in: a render
    // shows a significant gain (z 4.2 at seed 1), which the pattern test finds as large
    // when the stripes are shifted over the picture ("but its gain ..." is said only of a
    // gain the render comparison accepted); the checker's highlight passes it.
    let report = report_json(&out);
    // A group's list `field` in the report.
    let listed = |g: &str, field: &str| -> Vec<serde_json::Value> {
        let groups = report["groups"].as_array().unwrap();
        let group = groups.iter().find(|r| r["group"] == g).unwrap();
        group[field].as_array().unwrap().clone()
    };
    let decisions = |g: &str| -> Vec<String> {
        listed(g, "decisions")
            .iter()
            .map(|d| d.as_str().unwrap().to_string())
            .collect()
    };
    assert_ne!(
        row("picture_stripes").model.as_deref(),
        Some("textured-anisotropic")
    );
    // Whether group `g`'s report has a decision that says `phrase`.
    let says = |g: &str, phrase: &str| decisions(g).iter().any(|d| d.contains(phrase));
    assert!(
        says("picture_stripes", "but its gain follows the picture"),
        "{:?}",
        decisions("picture_stripes")
    );
    // ... and its comparison is reported as rejected, not as kept.
    let stripes_stage4: Vec<serde_json::Value> = listed("picture_stripes", "comparisons")
        .into_iter()
        .filter(|c| c["stage"] == "4 anisotropic")
        .collect();
    assert!(
        !stripes_stage4.is_empty() && stripes_stage4.iter().all(|c| c["kept_complex"] == false),
        "{stripes_stage4:?}"
    );
    assert!(
        says("picture_checker", "anisotropic gain explains a highlight"),
        "{:?}",
        decisions("picture_checker")
    );
    for picture in ["picture_flowers", "picture_stripes", "picture_checker"] {
        let r = row(picture);
        let (psnr, ceiling) = (
            r.diffuse_map_psnr_db.unwrap(),
            r.diffuse_map_psnr_ceiling_db.unwrap(),
        );
        assert!(
            psnr > ceiling - 2.0,
            "{picture}: {psnr} dB, ceiling {ceiling} dB"
        );
    }
    for diffuse in ["floor", "ceiling", "walls", "sphere", "stand"] {
        assert!(row(diffuse).class_ok, "{diffuse}");
    }
    // A picture with no lobe has nothing beside its map to take its light: the map's mean
    // is the picture's (-0.4% on seed 1), where the checker's lobe leaves its map 8% dark.
    let flowers = row("picture_flowers").diffuse_map_level_err.unwrap();
    assert!(flowers.abs() < 0.02, "flowers' map level {flowers}");
    // Each picture's map under its lobe explains its own pixels (the final render against
    // the panorama) to within 10%. The checker's dark squares are mostly lobe: left out of
    // its map as highlights and filled from the light squares, they left 14.3% (seed 1).
    for picture in ["picture_flowers", "picture_stripes", "picture_checker"] {
        let groups = report["groups"].as_array().unwrap();
        let group = groups.iter().find(|r| r["group"] == picture).unwrap();
        let error = group["error_final"].as_f64().unwrap();
        assert!(error < 0.10, "{picture}: final error {error}");
    }
    // The RADIANCE primitive of the checker: its map under a white plastic2 lobe.
    let rad = std::fs::read_to_string(out.join("materials.rad")).unwrap();
    assert!(
        rad.contains("pict_picture_checker plastic2 picture_checker\n"),
        "{rad}"
    );
    // At 64 px no pixel sees the frames whole: their material is not recovered, so no
    // pixel on a picture's border, which sees a frame too, joins its map.
    assert_eq!(group_report(&out, "frames")["model"], "unseen");
    // But their light is: they are rendered as a colour measured on the pixels they share
    // with the walls (not the pictures, whose maps are extrapolated there). As a neutral
    // grey they lit the ceiling 3.4% more than the truth, and its colour came out 1.7%
    // dark (0.5% with the stand-in).
    assert!(
        says("frames", "stand-in: rendered as the diffuse"),
        "{:?}",
        decisions("frames")
    );
    // Written as that stand-in too, so that RADIANCE's oconv loads the file: a group of no
    // primitive stopped it at "undefined modifier".
    assert!(
        rad.contains("# frames: unseen, not recovered; the diffuse stand-in [")
            && rad.contains("\nvoid plastic frames\n0\n0\n5 "),
        "{rad}"
    );
    // The picture's coordinates are held to it, as relume's lookup clamps: RADIANCE
    // extrapolated its outer half-texels (1.5-3.8% off there, up to 50%).
    let cal = std::fs::read_to_string(out.join("textures/picture_checker.cal")).unwrap();
    assert!(
        cal.contains("pic_u = unit((obj_u*N - .5)/(N - 1));")
            && cal.contains("unit(x) = if(x, if(x - 1, 1, x), 0);"),
        "{cal}"
    );
    for diffuse in ["ceiling", "walls"] {
        let err = row(diffuse).diffuse_rel_err.unwrap();
        assert!(err < 0.01, "{diffuse}: {:.2}%", 100.0 * err);
    }
    // The stand has 29 pixels: the diffuse polish's 64 spp gave its mean 1856 samples, and
    // its colour came out 2.0% off. Measured again with at least POLISH_MIN_SAMPLES in
    // all, 0.16%.
    let stand = row("stand").diffuse_rel_err.unwrap();
    assert!(stand < 0.01, "stand: {:.2}%", 100.0 * stand);
    for picture in ["picture_flowers", "picture_stripes", "picture_checker"] {
        assert_eq!(map_border_pixels(&out, picture), 0, "{picture}");
    }
}

/// The pixels on a textured group's border its map was also solved from, as its stage-5
/// decision gives them ("from N pure pixels and M on its border").
fn map_border_pixels(out: &std::path::Path, group: &str) -> u32 {
    map_pixel_count(out, group, " on its border")
}

/// The pure pixels a group's final map was solved from, as its report says.
fn map_pure_pixels(out: &std::path::Path, group: &str) -> u32 {
    map_pixel_count(out, group, " pure pixels")
}

/// The count just before `what` in group `group`'s final map decision.
fn map_pixel_count(out: &std::path::Path, group: &str, what: &str) -> u32 {
    let stage5 = map_decision(out, group);
    let before = stage5.split(what).next().unwrap();
    before.rsplit(' ').next().unwrap().parse().unwrap()
}

/// Group `group`'s report line on its final map ("stage 5: textured-... map NxN from ...").
fn map_decision(out: &std::path::Path, group: &str) -> String {
    let report = group_report(out, group);
    let decisions = report["decisions"].as_array().unwrap();
    decisions
        .iter()
        .filter_map(|d| d.as_str())
        .rfind(|d| d.starts_with("stage 5: textured"))
        .unwrap_or_else(|| panic!("{group}: no stage-5 map decision in {decisions:?}"))
        .to_string()
}

/// A uniform anisotropic panel is not a picture. Textured's checker given its map's mean
/// colour and its stripes a brushed metal of kind "auto", the panorama rendered by relume
/// from those materials: stage 3 reads each isotropic lobe's misfit of the narrow highlight
/// as a texture (step contrasts 0.15 and 0.30 at seed 1); its test again under stage 4's
/// anisotropic lobes finds neither textured, and the metal, which stage 4 fitted as a
/// textured plastic stand-in, is fitted again with its kind free.
#[test]
fn textured_small_with_uniform_anisotropic_panels_finds_them_without_maps() {
    let bench = shared().join("bench").join("textured");
    let tmp = tempfile::tempdir().unwrap();
    let at = |p: &str| path_str(&bench.join(p)).to_string();
    let truth = std::fs::read_to_string(bench.join("truth.toml")).unwrap();
    let checker =
        "model = \"textured-anisotropic\"\ndiffuse_map = \"textures/picture_checker.exr\"";
    let stripes = "model = \"textured-isotropic\"\ndiffuse_map = \"textures/picture_stripes.exr\"\nspecularity = 0.05\nroughness = 0.08";
    assert!(
        truth.contains(checker) && truth.contains(stripes),
        "the truth as this test knows it"
    );
    let panels = truth
        .replace(checker, "model = \"anisotropic\"\ncolor = [0.3447, 0.2964, 0.4469]")
        .replace(
            stripes,
            "model = \"anisotropic\"\nkind = \"metal\"\ncolor = [0.8, 0.72, 0.6]\nspecularity = 0.9\nroughness_u = 0.05\nroughness_v = 0.2\ndirection_u = [0.0, 1.0, 0.0]",
        )
        .replace("\"textures/", &format!("\"{}/", at("textures")));
    let materials = tmp.path().join("panels.toml");
    std::fs::write(&materials, panels).unwrap();
    let views = tmp.path().join("views");
    let stripes_kind = "name = \"picture_stripes\"\nkind = \"plastic\"";
    let scene_with = |kind: &str| {
        let small = std::fs::read_to_string(bench.join("scene-small.toml")).unwrap();
        assert!(small.contains(stripes_kind));
        small
            .replace(
                stripes_kind,
                &format!("name = \"picture_stripes\"\nkind = \"{kind}\""),
            )
            .replace(
                "geometry = [\"",
                &format!("geometry = [\"{}/", path_str(&bench)),
            )
            .replace(
                "image = \"views-small/",
                &format!("image = \"{}/", path_str(&views)),
            )
    };
    let (rendered, recovered) = (tmp.path().join("metal.toml"), tmp.path().join("auto.toml"));
    std::fs::write(&rendered, scene_with("metal")).unwrap();
    std::fs::write(&recovered, scene_with("auto")).unwrap();
    relume_ok(
        tmp.path(),
        &[
            "render",
            path_str(&rendered),
            "--materials",
            path_str(&materials),
            "--out",
            path_str(&views),
            "--spp",
            "1024",
            "--seed",
            "77",
        ],
    );
    let out = tmp.path().join("rec");
    recover(&recovered, &out, &["--effort", "fast", "--seed", "1"]);
    let rows = relume::compare::materials_report(&materials, &out.join("materials.toml")).unwrap();
    for r in &rows {
        println!("{r:?}");
    }
    let row = |g: &str| rows.iter().find(|r| r.group == g).unwrap();
    for panel in ["picture_checker", "picture_stripes"] {
        let r = row(panel);
        let decided = decisions(&group_report(&out, panel)).join("\n");
        assert_eq!(r.model.as_deref(), Some("anisotropic"), "{r:?}\n{decided}");
        assert!(!out.join(format!("textures/{panel}.exr")).exists());
        assert!(r.direction_err_deg.unwrap() < 10.0, "{r:?}");
        assert!(r.roughness_u_rel_err.unwrap() < 0.25, "{r:?}");
        assert!(r.roughness_v_rel_err.unwrap() < 0.25, "{r:?}");
    }
    let stripes = recovered_material(&out, "picture_stripes");
    assert_eq!(
        stripes.kind.map(relume::materials_file::kind_name),
        Some("metal")
    );
    // The flowers keep their map.
    assert!(
        row("picture_flowers").class_ok,
        "{:?}",
        row("picture_flowers")
    );
    // Stage 4's second pass is its own stage in the report, its work charged to it.
    assert!(stage_names(&report_json(&out)["stages"]).contains(&"4 anisotropic again"));
    assert_group_work_within_its_stages(&out);
}

/// Glossy at 64x64 per face (effort fast, seed 24): the yellow box's weak, broad lobe
/// (specularity 0.1, roughness 0.2) is proposed by its cache at s 0.137, which a render
/// shows removes almost none of its error (z 1.2); stage 2's ladder of roughnesses finds
/// a broad lobe that does (roughness 0.3, z 4.9), says how loosely its shape is known,
/// and no diffuse group is given one on the way. This is one seed's path: over glossy's
/// 64-px seeds 1-24 (docs/recovery.md, "The ladder") the yellow box's lobe comes from the
/// ladder on 19, within the half-rung resolution of the truth's roughness on 8 of those,
/// and its claimed roughness covers the truth at two standard errors on 18. (Seed 1 took
/// this path until the tracer's tie fix, aa69da6, moved glossy's bytes; it now keeps the
/// cache's proposal, which the lobe-claim test below reads.)
#[test]
fn glossy_small_finds_the_yellow_boxs_weak_broad_lobe() {
    let (out, rows) = glossy_small_seed_24();
    let row = |g: &str| rows.iter().find(|r| r.group == g).unwrap();
    let yellow = row("box_yellow");
    assert!(yellow.class_ok, "{yellow:?}");
    // Within the ladder's half-rung resolution (a factor of 1.5) of the truth's 0.2; the
    // proposal's 0.047 is 77% off.
    assert!(
        yellow.roughness_rel_err.unwrap() <= 0.5 + 1e-6,
        "{yellow:?}"
    );
    assert!(yellow.specularity_rel_err.unwrap() <= 0.5, "{yellow:?}");
    let yellow_report = group_report(out, "box_yellow");
    assert_eq!(
        yellow_report["lobe_from_ladder"], true,
        "{:?}",
        yellow_report["decisions"]
    );
    // Its reported roughness carries the spread of the rungs the ladder could not tell
    // apart, and covers the truth at two standard errors (the sandwich alone claimed a
    // few percent: 0.3 +- 0.012 against a true 0.2).
    let roughness = yellow_report["uncertainty"]
        .as_array()
        .unwrap()
        .iter()
        .find(|u| u["parameter"] == "roughness")
        .unwrap();
    let (value, sigma) = (
        roughness["value"].as_f64().unwrap(),
        roughness["sigma"].as_f64().unwrap(),
    );
    assert!((value - 0.2).abs() <= 2.0 * sigma, "{roughness:?}");
    for diffuse in ["floor", "ceiling", "walls_warm", "walls_cool"] {
        assert!(row(diffuse).class_ok, "{:?}", row(diffuse));
    }
}

/// Glossy at 64 px, seed 1: every lobe parameter of a group in its true class lies within
/// 3 of its claimed standard errors of the truth. A weak lobe kept as its cache proposed
/// it claims what the ladder's rungs measured beside it show, not the sandwich's or the
/// cache size's figure alone: the teal box's (s 0.04, roughness 0.08), kept on seed 1 at
/// roughness 0.020, was claimed +- 0.0015 (39 sigma off) until the rungs showed that the
/// pixels read as much gain at rungs far broader (+- 0.14). Since the pixels' samples
/// are stratified, seed 1's teal box comes from the ladder itself; since the tracer's tie
/// rule holds on a floor at zero (aa69da6), which moved glossy's bytes as another seed
/// would, the yellow box (s 0.1, roughness 0.2) is kept on seed 1 as proposed (s 0.128,
/// roughness 0.062) and claims roughness +- 0.119 from its rungs (z 1.1). (Seed 4 showed
/// this before the tie fix; after it, seed 4 keeps no lobe as proposed.)
#[test]
fn glossy_small_claims_no_lobe_shape_more_precisely_than_its_pixels_show() {
    let (out, _) = glossy_small();
    let truth = shared().join("bench").join("glossy").join("truth.toml");
    let coverage = relume::coverage::coverage_rows(&truth, &out.join("report.json")).unwrap();
    let lobes: Vec<_> = coverage
        .iter()
        .filter(|r| !r.parameter.starts_with("color"))
        .collect();
    assert!(lobes.len() >= 12, "{lobes:?}");
    for row in &lobes {
        assert!(row.z <= 3.0, "{row:?}");
    }
    let yellow = group_report(out, "box_yellow");
    assert!(
        yellow["decisions"]
            .to_string()
            .contains("a weak lobe's uncertainty"),
        "{:?}",
        yellow["decisions"]
    );
}

/// Glossy's steel box (s 0.95, roughness 0.14) on seed 4 took stage 4's plain cache fit,
/// s 0.806 and roughness 0.088 (15% and 37% off): the plain sums' specularity is diluted
/// by the samples' noise and the fit makes up for it with a sharper lobe. The same cache's
/// fit across halves of its samples (s 0.918, roughness 0.113) renders better at z 4.8 and
/// now replaces it; its claimed roughness sigma covers the truth.
#[test]
fn glossy_small_seed_4_keeps_the_steel_boxs_undiluted_fit() {
    let (out, rows) = glossy_small_seed_4();
    assert_lobe_near_truth(rows, "metal_steel", 0.05, 0.25);
    let truth = shared().join("bench").join("glossy").join("truth.toml");
    let coverage = relume::coverage::coverage_rows(&truth, &out.join("report.json")).unwrap();
    let roughness = coverage
        .iter()
        .find(|r| r.group == "metal_steel" && r.parameter == "roughness")
        .unwrap();
    assert!(roughness.z <= 2.0, "{roughness:?}");
}

/// Glossy at 64 px, seed 24: the teal box's cache proposal and the ladder's best rung
/// both fall short of the keep test, and the search's point that rendered best against
/// the proposal in the race is tested in their place (the second look). Here it falls
/// short too (z 2.4), and the teal box stays diffuse: a weak lobe missed, with each
/// test's figures in its report, not a lobe kept on no evidence. No diffuse group is
/// given a lobe on the way. (Until 48b2516 moved the render noise, seed 2's race point
/// was kept at z 3.3, s 0.051 and roughness 0.086 against 0.04 and 0.08. Since the tie
/// fix (aa69da6) moved glossy's bytes, 2 of seeds 1-24 reach the second look: seed 9,
/// which keeps the race's point at z 4.9 with s 0.046 and roughness 0.0069, and seed 24,
/// which is the path tested here; docs/recovery.md.)
#[test]
fn glossy_small_seed_24_tests_the_races_point_where_proposal_and_ladder_fall_short() {
    let (out, rows) = glossy_small_seed_24();
    let teal = group_report(out, "box_teal");
    let decided = decisions(&teal);
    let ladder_short = decided
        .iter()
        .any(|d| d.starts_with("stage 2 ladder") && d.contains("short of the test"));
    assert!(ladder_short, "{decided:?}");
    let look = decided
        .iter()
        .find(|d| d.starts_with("stage 2 second look"))
        .unwrap_or_else(|| panic!("no second look: {decided:?}"));
    let row = rows.iter().find(|r| r.group == "box_teal").unwrap();
    if look.ends_with("taken in its place") {
        assert_lobe_near_truth(rows, "box_teal", 0.3, 0.15);
    } else {
        assert!(look.ends_with("short of the test too"), "{look}");
        assert_eq!(row.model.as_deref(), Some("diffuse"), "{row:?}");
        assert!(
            decided
                .iter()
                .any(|d| d.starts_with("stage 2: stays diffuse")),
            "{decided:?}"
        );
    }
    for diffuse in ["floor", "ceiling", "walls_warm", "walls_cool"] {
        let row = rows.iter().find(|r| r.group == diffuse).unwrap();
        assert!(row.class_ok, "{row:?}");
    }
}

/// Glossy at 256 px, effort default, seed 1: every class right but, it may be, the white
/// sphere's, whose true lobe (s 0.03, roughness 0.02) accounts for about the 1% its test
/// asks, and is found or lost on the noise of its cache and its renders. Until a813d39,
/// whose tie rule for shared edges moved the bits, the test also asked the three weak
/// lobes to come from the ladder, and the sphere's was (its rung tested from the
/// proposal's samples up, z 9.0 at 1296 spp; the yellow box's rung measured again at its
/// cap, 1152 spp, z 15.6). Since, on seed 1 the sphere is diffuse (its cache reads
/// 0.0064 of relative error, under the rule) and a box's lobe passes as the cache
/// proposed it (s 0.13, roughness 0.08, z 5.2): the same classes by another route. On
/// seeds 2 and 3 the sphere was lost before a813d39 and after it. Lost, it must stay
/// diffuse, not take another model. Four minutes in release on 2 cores: run with
/// `--ignored`.
#[test]
#[ignore = "256 px at effort default, about four minutes: cargo test --release --test recover -- --ignored glossy_256"]
fn glossy_256_default_seed_1_finds_every_class_but_the_white_spheres_1_percent_lobe() {
    let (_tmp, out, rows) = recover_reference_at("glossy", "scene.toml", "1", "default");
    let wrong: Vec<&str> = rows
        .iter()
        .filter(|r| !r.class_ok)
        .map(|r| r.group.as_str())
        .collect();
    assert!(
        wrong.iter().all(|&g| g == "sphere_white"),
        "wrong: {wrong:?}"
    );
    let sphere = group_report(&out, "sphere_white");
    let found = wrong.is_empty();
    assert_eq!(
        sphere["model"],
        if found { "isotropic" } else { "diffuse" },
        "{:?}",
        sphere["decisions"]
    );
}

/// A full render of the recovered model agrees with the panorama as well as the truth
/// materials do, within the issue's 1.2x on both errors (glossy at 64 px, rendered by
/// relume at 256 spp, both models on one seed; measured 1.02 and 0.96, and 1.03 on
/// group means before the diffuse polish became a Newton step). With the render noise
/// taken out (a second render on seed 2), 4.8 of the truth's 4.9 points of rel RMS in
/// quadrature, the misfits are 1.06% and 1.06% and the group biases 0.09% and 0.27%.
#[test]
fn glossy_small_renders_its_panorama_as_well_as_the_truth_does() {
    let (out, _) = glossy_small();
    assert_renders_its_panorama_as_well_as_the_truth("glossy", out);
}

/// Reference `name`'s 64-px scene rendered by relume at 256 spp on seed 1 from the
/// materials recovered into `out` and from the truth: both errors against the panorama
/// (rel RMS, group means), and their ratios, recovered over truth.
fn renders_of_its_panorama(name: &str, out: &std::path::Path) -> relume::bench::edits::EditOutcome {
    let bench = shared().join("bench").join(name);
    let tmp = tempfile::tempdir().unwrap();
    let mut outcomes = relume::bench::edits::run(&relume::bench::edits::EditsArgs {
        edits: vec![bench.join("scene-small.toml")],
        recovered: vec![out.join("materials.toml")],
        truth: bench.join("truth.toml"),
        out: tmp.path().join("original"),
        spp: 256,
        seed: 1,
        threads: None,
    })
    .unwrap();
    let o = outcomes.remove(0);
    let (rec, truth) = (&o.recovered, &o.truth);
    println!(
        "{name}: rel RMS {:.4} / {:.4}, group mean {:.4} / {:.4}; noise out: misfit {:.4} / {:.4}, group bias {:.4} / {:.4}",
        rec.rel_rms,
        truth.rel_rms,
        rec.group_mean_err,
        truth.group_mean_err,
        rec.misfit,
        truth.misfit,
        rec.group_mean_bias,
        truth.group_mean_bias
    );
    o
}

/// Both errors of [`renders_of_its_panorama`] within `RATIO_GOAL` of the truth's.
fn assert_renders_its_panorama_as_well_as_the_truth(name: &str, out: &std::path::Path) {
    let o = renders_of_its_panorama(name, out);
    assert_rms_within_goal(&o);
    assert_group_means_within_goal(&o);
}

/// The recovered model's rel RMS within `RATIO_GOAL` of the truth's, as it is and with
/// the render noise taken out (the misfit): the noise, the same in both, pulls the first
/// ratio towards 1.
fn assert_rms_within_goal(o: &relume::bench::edits::EditOutcome) {
    let goal = relume::bench::edits::RATIO_GOAL;
    assert!(o.rms_ratio <= goal, "rel RMS ratio {}", o.rms_ratio);
    assert!(o.misfit_ratio <= goal, "misfit ratio {}", o.misfit_ratio);
}

/// The recovered model's group-mean error within `RATIO_GOAL` of the truth's, as it is
/// and with the render noise taken out.
fn assert_group_means_within_goal(o: &relume::bench::edits::EditOutcome) {
    let goal = relume::bench::edits::RATIO_GOAL;
    assert!(
        o.group_mean_ratio <= goal,
        "group-mean ratio {}",
        o.group_mean_ratio
    );
    assert!(
        o.group_mean_bias_ratio <= goal,
        "group-bias ratio {}",
        o.group_mean_bias_ratio
    );
}

/// The living room's frames are 15 pure pixels at 64 px, a dark plastic (s 0.04) whose
/// diffuse fit leaves 46% of error. So few pixels get a model choice, tested at the z that
/// t with 15 degrees of freedom needs (3.59, not 3): the lobe is found, near the truth,
/// where a fixed floor of 16 pixels kept the frames diffuse and 2.5-4x too bright.
#[test]
fn living_room_small_gives_its_15_pixel_frames_their_lobe() {
    let (out, rows) = living_room_small();
    assert_lobe_near_truth(rows, "frames", 0.25, 0.25);
    let frames_report = group_report(out, "frames");
    assert_eq!(frames_report["pure_pixels"], 15);
    let kept = comparison(&frames_report, |c| c["kept_complex"] == true);
    let needed = kept["z_needed"].as_f64().unwrap();
    assert!((needed - 3.59).abs() < 0.01, "{kept:?}");
    assert!(kept["z"].as_f64().unwrap() >= needed, "{kept:?}");
}

/// A small group's stage-1 error that straddles the gate (1% within two standard errors)
/// is measured again alone at 4x while it straddles, within the decisions' cap: the living
/// room's sofa at 64 px (1476 pixels, diffuse in the truth) read 0.0000 +- 0.0142 at its
/// first measurement alone and ended stage 1 there; it now reads about 0.02 +- 0.001 and
/// goes on (to stay diffuse). No group small enough to be measured alone ends straddling.
/// Each decision so taken says at how many samples.
#[test]
fn living_room_small_measures_a_straddling_stage_1_error_again_until_it_sides() {
    use relume_core::fit;
    let (out, rows) = living_room_small();
    let report = report_json(out);
    let loop_spp = report["budget"]["loop_spp"].as_u64().unwrap();
    let straddles = |g: &serde_json::Value| {
        let e = g["error_diffuse"].as_f64().unwrap();
        let sigma = g["error_diffuse_sigma"].as_f64().unwrap();
        (e - fit::SPECULAR_GAIN_THRESHOLD).abs() < fit::EXCEEDS_SIGMAS * sigma
    };
    let sofa = group_report(out, "sofa");
    assert!(
        !straddles(&sofa) && sofa["error_diffuse_sigma"].as_f64().unwrap() < 0.005,
        "{sofa}"
    );
    assert!(
        decisions(&sofa)
            .iter()
            .any(|d| d.starts_with("stage 1: diffuse error")
                && d.contains("tested for a weak specular")),
        "{sofa}"
    );
    for g in report["groups"].as_array().unwrap() {
        let pixels = g["pure_pixels"].as_u64().unwrap();
        // Measured alone: at least CACHE_MIN_SAMPLES (2^16) samples take more than the
        // decisions' 4x the loop's samples per pixel.
        let alone = pixels >= u64::from(fit::MIN_PIXELS_FOR_MODEL_CHOICE)
            && (1u64 << 16).div_ceil(pixels) > 4 * loop_spp;
        if alone && !g["error_diffuse"].is_null() {
            assert!(!straddles(g), "{g}");
        }
    }
    // A larger group is measured again too when its error reads above the gate, within
    // the decisions' cap a round: the ceiling (6648 pixels) and the walls (4656) read
    // 0.024 +- 0.011 and 0.015 +- 0.008 at the decisions' samples on this seed.
    let measured_again_at = |g: &serde_json::Value| -> Option<u64> {
        let d = decisions(g)
            .into_iter()
            .find(|d| d.starts_with("stage 1: diffuse"))?;
        let (_, after) = d.split_once("measured again alone at ")?;
        after.split_once(" spp")?.0.parse().ok()
    };
    for group in ["sofa", "ceiling", "walls"] {
        let g = group_report(out, group);
        let spp = measured_again_at(&g).unwrap_or_else(|| panic!("{g}"));
        let pixels = g["pure_pixels"].as_u64().unwrap();
        assert!(spp > 4 * loop_spp, "{g}");
        if group != "sofa" {
            assert!(spp * pixels <= fit::DECISION_MAX_SAMPLES, "{g}");
            assert!(g["error_diffuse_sigma"].as_f64().unwrap() < 0.006, "{g}");
        }
    }
    let row = rows.iter().find(|r| r.group == "sofa").unwrap();
    assert!(row.class_ok, "{row:?}");
}

/// A weak candidate whose best lobe on its own transport cache cannot account for 1% of
/// relative error stays diffuse without its lobe rendered: the living room's floor and
/// accent wall at 64 px (0.0016 and 0.0009 on seed 1, a third of stage 2's time before),
/// while the desk and lamp_body, whose weak lobes are there (0.016 and 0.020), are still
/// rendered and kept. Each group's report charges stage 2 accordingly.
#[test]
fn living_room_small_renders_no_lobe_its_cache_rules_out() {
    let (out, rows) = living_room_small();
    for (group, ruled_out) in [
        ("floor", true),
        ("wall_accent", true),
        ("desk", false),
        ("lamp_body", false),
    ] {
        let report = group_report(out, group);
        let decisions = decisions(&report);
        let skipped = decisions
            .iter()
            .any(|d| d.starts_with("stage 2: stays diffuse, its lobe not rendered"));
        assert_eq!(skipped, ruled_out, "{group}: {decisions:?}");
        if ruled_out {
            let row = rows.iter().find(|r| r.group == group).unwrap();
            assert!(row.class_ok, "{row:?}");
            // The cache's fits and the colour's re-fit, no search, test or ladder.
            assert!(
                report["comparisons"].as_array().unwrap().is_empty(),
                "{group}"
            );
            assert!(
                stage_evaluations(&report, "2 isotropic") < 100,
                "{group}: {report}"
            );
        } else {
            assert!(
                !report["comparisons"].as_array().unwrap().is_empty(),
                "{group}"
            );
        }
    }
}

/// Every untextured group that stage 2 decided has a word from stages 3 and 4, whether it
/// went on or not. The brushed plate (isotropic here, anisotropic in truth) is left with less
/// than `DIFFUSE_THRESHOLD` by its isotropic lobe, so stage 4 does not try it: the report
/// says so with the error the gate read, and that note does not pass for the decision
/// that set its model, which stays stage 2's.
#[test]
fn living_room_small_says_why_stage_4_leaves_a_group_alone() {
    let (out, _) = living_room_small();
    let report = report_json(out);
    for group in report["groups"].as_array().unwrap() {
        let name = group["group"].as_str().unwrap();
        let model = group["model"].as_str().unwrap();
        if group["error_decided"].is_null() || !matches!(model, "diffuse" | "isotropic") {
            continue;
        }
        let decisions = decisions(group);
        for stage in ["stage 3", "stage 4"] {
            assert!(
                decisions.iter().any(|d| d.starts_with(stage)),
                "{name}, {stage}: {decisions:?}"
            );
        }
    }
    let plate = group_report(out, "brushed_plate");
    assert_eq!(plate["model"], "isotropic", "{plate}");
    let decided = plate["error_decided"].as_f64().unwrap();
    assert!(decided <= relume_core::fit::DIFFUSE_THRESHOLD, "{plate}");
    let decisions = decisions(&plate);
    let gate = decisions
        .iter()
        .find(|d| d.starts_with("stage 4 gate: not tried"))
        .unwrap_or_else(|| panic!("{decisions:?}"));
    assert!(
        gate.contains(&format!("leaves {decided:.4} of relative error")),
        "{gate}"
    );
    assert!(gate.contains("DIFFUSE_THRESHOLD 0.05"), "{gate}");
    assert!(
        !decisions.iter().any(|d| d.starts_with("stage 4:")),
        "{decisions:?}"
    );
    // Nor is a metal tested for texture, and the report says so too.
    assert!(
        decisions
            .iter()
            .any(|d| d.starts_with("stage 3: not tested for texture: a metal")),
        "{decisions:?}"
    );
}

/// Glossy at 64 px, seed 4: the teal box's ladder (s 0.04, roughness 0.08 in the truth;
/// 426 pixels) has not chosen at its first round's 77 spp, where no rung gains at its lower
/// bound and the best there is the sharpest (0.005). Its three rungs of most gain are
/// measured again at 4x, and there a broader rung (0.0387) removes most; it is kept at
/// z 5.0. Chosen from the first round, the lobe would have had roughness 0.005 (94% off);
/// the second round's is 52% off, nearer, but not near: its pixels do not fix the teal
/// box's roughness (every rung measured is within 2 standard errors of the best), as on
/// the other seeds (10-275% off on seeds 1-10, docs/recovery.md). Until 48b2516 moved the
/// render noise this seed's second round landed on 0.088, within 15%.
#[test]
fn glossy_small_seed_4_chooses_the_teal_boxs_rung_in_a_second_round() {
    let (out, rows) = glossy_small_seed_4();
    let teal_row = rows.iter().find(|r| r.group == "box_teal").unwrap();
    assert!(teal_row.class_ok, "{teal_row:?}");
    let teal = group_report(out, "box_teal");
    assert_eq!(teal["lobe_from_ladder"], true, "{:?}", teal["decisions"]);
    let decided = decisions(&teal);
    let ladder = decided
        .iter()
        .find(|d| d.starts_with("stage 2 ladder") && d.contains("measured again"))
        .unwrap_or_else(|| panic!("no second round: {decided:?}"));
    // The first round's best, and the rung the second round kept.
    let number_after = |text: &str| -> f64 {
        let at = ladder
            .find(text)
            .unwrap_or_else(|| panic!("{text}: {ladder}"))
            + text.len();
        let digits: String = ladder[at..]
            .chars()
            .take_while(|c| c.is_ascii_digit() || *c == '.')
            .collect();
        digits.parse().unwrap()
    };
    let first = number_after("the best there roughness ");
    let kept = number_after("half-rungs around the best, ");
    let truth = 0.08f64;
    let off = |roughness: f64| libm::log(roughness / truth).abs();
    assert!(
        off(kept) < off(first),
        "the second round's rung {kept} is no nearer the truth's {truth} than the first's {first}: {ladder}"
    );
    for diffuse in ["floor", "ceiling", "walls_warm", "walls_cool"] {
        let row = rows.iter().find(|r| r.group == diffuse).unwrap();
        assert!(row.class_ok, "{row:?}");
    }
}

/// Glossy's floor reads 0.062 of error after stage 1, above `DIFFUSE_THRESHOLD`: the light
/// the spheres and boxes reflect onto it, whose lobes stage 1 does not know. Its best lobe
/// on its own cache accounts for 0.0008, so stage 2 renders none (as for a weak
/// candidate), and stage 4, measuring it again under the scene as stage 2 left it, does
/// not search it: no comparison anywhere, and diffuse. The metals, strong candidates with
/// lobes, are still rendered and tested.
#[test]
fn glossy_small_renders_no_lobe_for_a_floor_its_cache_and_the_scene_as_known_rule_out() {
    let (out, rows) = glossy_small();
    let floor = group_report(out, "floor");
    assert!(
        floor["error_diffuse"].as_f64().unwrap() > 0.05,
        "the floor no longer enters as a strong candidate: {floor}"
    );
    let decided = decisions(&floor);
    for expected in [
        "stage 2: stays diffuse, its lobe not rendered",
        "stage 4: stays diffuse without a search",
    ] {
        assert!(
            decided.iter().any(|d| d.starts_with(expected)),
            "{expected}: {decided:?}"
        );
    }
    assert!(
        floor["comparisons"].as_array().unwrap().is_empty(),
        "{floor}"
    );
    let row = rows.iter().find(|r| r.group == "floor").unwrap();
    assert!(
        row.class_ok && row.diffuse_rel_err.unwrap() < 0.01,
        "{row:?}"
    );
    for metal in ["metal_gold", "metal_steel"] {
        let report = group_report(out, metal);
        let stage2 = comparison(&report, |c| c["stage"] == "2 isotropic");
        assert_eq!(stage2["kept_complex"], true, "{metal}: {stage2}");
    }
}

/// A mirror's colour scales the room it reflects, and stage 5's maps and the diffuse
/// refinement change that room after the first colour polish. The living room's mirror
/// came out 1.12% bright at 64 px, seed 1, from the first polish alone; polished once more
/// under the final scene it is 0.08% off (the test allows 0.5%). Seed 2 reads 0.8% either
/// way: what a seed's noise leaves, which the second polish does not add to.
#[test]
fn living_room_small_polishes_its_mirror_again_under_the_final_scene() {
    let (out, rows) = living_room_small();
    let mirror = rows.iter().find(|r| r.group == "mirror").unwrap();
    assert!(mirror.class_ok, "{mirror:?}");
    assert!(mirror.diffuse_rel_err.unwrap() <= 0.005, "{mirror:?}");

    let report = report_json(out);
    let stages = stage_names(&report["stages"]);
    let last_refinement = stages.iter().rposition(|s| *s == "diffuse refinement");
    let final_polish = stages
        .iter()
        .position(|s| *s == "colour polish under the final scene");
    assert!(
        final_polish.is_some() && final_polish > last_refinement,
        "{stages:?}"
    );
    let decisions = group_report(out, "mirror")["decisions"].clone();
    let polished = decisions.as_array().unwrap().iter().any(|d| {
        d.as_str()
            .unwrap()
            .starts_with("colour polish under the final scene: colour scaled")
    });
    assert!(polished, "{decisions}");
}

/// The living room's 64-px model renders its panorama as well as the truth materials do,
/// within the issue's 1.2x (relume at 256 spp, both models on one seed): rel RMS 4.06%
/// against 4.03%, group means 0.36% against 0.38%, and with the render noise taken out (a
/// second render on seed 2) group biases 0.31% against 0.31%. Until the pixels' samples
/// were stratified the group means missed (1.31x) by the statue's heavy-tailed render
/// noise (20 pixels, 35% rel RMS a pixel at 256 spp, now half that), which moved its
/// mean by 2-6 points from seed to seed.
#[test]
fn living_room_small_renders_its_panorama_as_well_as_the_truth_does() {
    let (out, _) = living_room_small();
    let o = renders_of_its_panorama("living-room", out);
    let goal = relume::bench::edits::RATIO_GOAL;
    assert!(o.rms_ratio <= goal, "rel RMS ratio {}", o.rms_ratio);
    assert_group_means_within_goal(&o);
}

/// The same pixel by pixel with the render noise taken out: 1.26% against 1.13% (1.11x).
/// The strata halved the truth's misfit (the statue's heavy tail), and left the recovered
/// model's at 1.39% (1.23x), most of it picture_3's (12.1% against 1.3%): its 64-px map
/// could not follow its pixels, at 1.3 texels a pixel where a third of them lie on its
/// border. With the border counted in the map's side, 7.6% (docs/recovery.md, "The map's
/// side counts its border").
#[test]
fn living_room_small_misfit_is_within_the_goal_of_the_truths() {
    let (out, _) = living_room_small();
    assert_rms_within_goal(&renders_of_its_panorama("living-room", out));
}

/// The living room at 64 px, seed 8: no view is warned of, and every view's final render
/// is within 1.5% of the panorama over its pure pixels. With the views rendered at the
/// effort's 32 spp, view px read +2.0% +- 0.8% against the other views' median of -0.5%,
/// a false warning that its exposure was off, where 256-spp renders of the same model read
/// it at -0.4% to +0.5%; the views now take at least 2^19 samples each (+0.7% +- 0.4%).
#[test]
fn living_room_small_seed_8_warns_of_no_view() {
    let (_tmp, out, _) = recover_reference("living-room", "scene-small.toml", "8");
    let report = report_json(&out);
    let readings = report["view_readings"].as_array().unwrap();
    assert_eq!(readings.len(), 6, "{readings:?}");
    for r in readings {
        assert!(r["rel_mean_diff"].as_f64().unwrap().abs() < 0.015, "{r}");
    }
    assert!(!report["warnings"]
        .to_string()
        .contains("exposure may be off"));
}

/// A picture's edge lies under pixels that see its frame too. The living room's frames
/// are recovered at 64 px (the test above), so every picture's map is also solved from
/// pixels on its border, rendered under the frames' material, where before its edge
/// texels were guessed from the inner ones. Its texels are counted over them too: two a
/// pixel it is solved from (picture_3: 14 x 14 from 63 pure pixels and 36 on its border,
/// where the pure pixels alone gave 11 x 11).
#[test]
fn living_room_small_solves_its_pictures_maps_from_their_borders_too() {
    let (out, rows) = living_room_small();
    for picture in ["picture_1", "picture_2", "picture_3"] {
        let row = rows.iter().find(|r| r.group == picture).unwrap();
        assert!(row.diffuse_map_psnr_db.is_some(), "{row:?}");
        let (pure, border) = (
            map_pure_pixels(out, picture),
            map_border_pixels(out, picture),
        );
        assert!(border > 0, "{picture}");
        let side = relume_core::stages::texture_map::map_side((pure + border) as usize, 1.0);
        assert!(
            side > relume_core::stages::texture_map::map_side(pure as usize, 1.0),
            "{picture}: {pure} pure and {border} border pixels"
        );
        let map = format!("map {side}x{side} from {pure} pure pixels and {border} on its border");
        assert!(
            map_decision(out, picture).contains(&map),
            "{picture}: {map}"
        );
    }
}

/// The living room's picture_1, a picture with no lobe, took a broad one at 64 px on its
/// uniform stand-in (past the pattern test) and rendered 13.5% dark from the edits' novel
/// viewpoint. Under its map that lobe's specularity is 1.7 standard errors from none, so
/// stage 5 drops it and solves the map again; picture_2's true lobe reads 2.7 and stays.
#[test]
fn living_room_small_keeps_no_lobe_its_pictures_pixels_do_not_establish() {
    let (out, rows) = living_room_small();
    let row = |g: &str| rows.iter().find(|r| r.group == g).unwrap();
    assert!(row("picture_1").class_ok, "{:?}", row("picture_1"));
    assert!(row("picture_2").class_ok, "{:?}", row("picture_2"));
    let stage5 = |g: &str| group_report(out, g)["decisions"].to_string();
    assert!(
        stage5("picture_1").contains("stage 5: the lobe dropped"),
        "{}",
        stage5("picture_1")
    );
    assert!(
        stage5("picture_2").contains("stage 5: the lobe kept"),
        "{}",
        stage5("picture_2")
    );
}

/// The living room's picture_2 (a picture under a lobe of s 0.05, roughness 0.08) has its
/// lobe fitted on a uniform stand-in, where the picture passes for part of the lobe (s
/// 0.063, roughness 0.12 at 64 px). Fitted again with the map on its highlights, where the
/// map was filled from neighbours rather than solved, it comes within 4.4% and 29% (the
/// test allows 10% and 40%, which the stand-in's 27% and 56% fail); its own view then
/// renders +0.7% where it rendered +2.3%.
#[test]
fn living_room_small_fits_picture_2s_lobe_again_with_its_map() {
    let (out, rows) = living_room_small();
    assert_lobe_near_truth(rows, "picture_2", 0.1, 0.4);
    let report = group_report(out, "picture_2");
    let refit = report["decisions"].as_array().unwrap().iter().any(|d| {
        d.as_str()
            .unwrap()
            .contains("fitted again with a first map")
    });
    assert!(refit, "{report}");
    // Its stage-5 work counts the render under the refitted lobe too: one under the
    // stand-in's lobe (a constant map, split into the map's light and the rest), one
    // under the new one, and the lobe's uncertainty, which decides whether it stays.
    assert_eq!(stage_evaluations(&report, "5 diffuse maps"), 3, "{report}");
}

/// At 256 px glossy's steel box (roughness 0.14) has 6472 pure pixels. Measured on all of
/// them at the test's 32 spp, its lobe against a perfect mirror read -0.064 +- 0.073 on
/// seed 1 and the box became a mirror by default; a large group is now decided on its
/// search subset with the same samples concentrated there, where the noise of a specular
/// render, a product of two renders' noises per pixel, falls with the square of the
/// samples per pixel. On seed 3 that still read 0.036 +- 0.044, and the box stayed a
/// mirror until an unresolved test could take one more round on the subset
/// (`fit::UNRESOLVED_MAX_SAMPLES`). The default suite recovers seed 3, the harder case;
/// seed 1 is behind `--ignored` below: each 256-px recovery takes about 3 minutes on 2
/// cores, and the two were 35% of tests/recover.rs's time (643 of 1,860 s of test
/// threads, on a machine of 6.6-9.7 Mrays/s in `bench rays`).
#[test]
fn glossy_at_256_px_decides_its_steel_box_on_a_subset_and_keeps_its_lobe() {
    steel_box_at_256_px_keeps_its_lobe("3");
}

#[test]
#[ignore = "a second 256-px recovery, about 3 minutes: cargo test --release --test recover -- --ignored steel_box_lobe_on_seed_1"]
fn glossy_at_256_px_keeps_its_steel_box_lobe_on_seed_1_too() {
    steel_box_at_256_px_keeps_its_lobe("1");
}

fn steel_box_at_256_px_keeps_its_lobe(seed: &str) {
    let (_tmp, out, rows) = recover_reference("glossy", "scene.toml", seed);
    let steel = rows.iter().find(|r| r.group == "metal_steel").unwrap();
    assert!(steel.class_ok, "seed {seed}: {steel:?}");
    assert!(
        steel.specularity_rel_err.unwrap() <= 0.25,
        "seed {seed}: {steel:?}"
    );
    assert!(
        steel.roughness_rel_err.unwrap() <= 0.5,
        "seed {seed}: {steel:?}"
    );
    let steel_report = group_report(&out, "metal_steel");
    assert_eq!(steel_report["pure_pixels"], 6472);
    let kept = comparison(&steel_report, |c| c["stage"] == "2 isotropic");
    // On the subset (t's critical value for at most 1024 pixels is above 3.005), at the
    // samples all 6472 pixels would have had at 32 spp, and steady.
    assert!(
        kept["z_needed"].as_f64().unwrap() > 3.005,
        "seed {seed}: {kept:?}"
    );
    let spp = kept["samples_per_pixel"].as_u64().unwrap();
    assert!(spp * 925 >= 32 * 6472, "seed {seed}: {kept:?}");
    assert!(
        kept["gain_sigma"].as_f64().unwrap() < 0.01,
        "seed {seed}: {kept:?}"
    );
    for diffuse in ["floor", "ceiling", "walls_warm", "walls_cool"] {
        let row = rows.iter().find(|r| r.group == diffuse).unwrap();
        assert!(row.class_ok, "seed {seed}: {row:?}");
    }
    // A wall's test renders no more than a decision's cap (DECISION_MAX_SAMPLES per
    // model) on its subset of some 1022 of its 112,354 pixels: 1027 spp, where its size
    // alone asked 3518 and took 4.5 s a test. (112,446 pixels and a subset of 1023 while a
    // closest hit shared by two triangles went to the one the BVH met first: the
    // footprint's corner rays meet the wall's edges exactly, and the lower index is now
    // taken, whatever the tree.)
    let wall = group_report(&out, "walls_warm");
    assert_eq!(wall["pure_pixels"], 112_354);
    let tested = comparison(&wall, |c| c["stage"] == "2 isotropic");
    let spp = tested["samples_per_pixel"].as_u64().unwrap();
    let cap = report_json(&out)["thresholds"]["DECISION_MAX_SAMPLES"]
        .as_u64()
        .unwrap();
    let decided = decisions(&wall)
        .into_iter()
        .find(|d| d.starts_with("stage 2: stays diffuse"))
        .unwrap_or_else(|| panic!("seed {seed}: {wall:?}"));
    let subset = number_after(decided, "GAIN_SIGNIFICANCE 3's level over ");
    assert!((1000..=1024).contains(&subset), "seed {seed}: {decided}");
    assert!(spp * subset <= cap + subset, "seed {seed}: {tested:?}");
    assert!(
        tested["z"].as_f64().unwrap() < 0.0,
        "seed {seed}: {tested:?}"
    );
    // The floor (85,604 pixels) comes on to stage 4's gate on seeds 1 and 3: its colour
    // is levelled and its error measured on its subset within the same cap, where its
    // size alone asked 64 spp on every pixel, twice (8 of the stage's 8 s).
    let floor = group_report(&out, "floor");
    let levelled = decisions(&floor)
        .into_iter()
        .find(|d| d.starts_with("stage 4") && d.contains("levelled by a render at"))
        .unwrap_or_else(|| panic!("seed {seed}: no stage-4 gate in {floor:?}"));
    let (spp, subset) = levelled_on(levelled);
    assert!(subset <= 1024, "seed {seed}: {levelled}");
    assert!(spp * subset <= cap + subset, "seed {seed}: {levelled}");
}

/// The samples per pixel and the pixels of a stage-4 levelling on a subset, from its
/// decision: "levelled by a render at {spp} spp on {subset} of its {all} pixels".
fn levelled_on(decision: &str) -> (u64, u64) {
    let spp = number_after(decision, "levelled by a render at ");
    let subset = number_after(decision, " spp on ");
    (spp, subset)
}

/// The whole number that follows `marker` in `text`.
fn number_after(text: &str, marker: &str) -> u64 {
    let start = text.find(marker).unwrap_or_else(|| panic!("{text}")) + marker.len();
    let digits: String = text[start..]
        .chars()
        .take_while(char::is_ascii_digit)
        .collect();
    digits.parse().unwrap_or_else(|_| panic!("{text}"))
}

/// A picture (textured's flowers) on a floor tile beside a uniform one, under a lamp, seen
/// from above; the picture's corners have texture coordinates `vt` (counter-clockwise from
/// its corner at the origin).
fn picture_scene(dir: &std::path::Path, vt: [[f32; 2]; 4]) {
    let scene = r#"format = 1
name = "a picture beside a floor tile"
geometry = ["geo.obj"]
hide = []

[[view]]
name = "down"
image = "views/down.exr"
position = [1.0, 0.5, 0.9]
direction = [0.0, 0.0, -1.0]
up = [0.0, 1.0, 0.0]
fov_deg = [90.0, 60.0]
size = [48, 24]
exposure = 1.0

[[light]]
object = "lamp"
radiance = [10.0, 10.0, 10.0]

[[group]]
name = "picture"
kind = "plastic"
objects = ["picture"]

[[group]]
name = "floor"
kind = "plastic"
objects = ["floor"]
"#;
    let vt: String = vt.iter().map(|[u, v]| format!("vt {u} {v}\n")).collect();
    let obj = format!(
        "o picture\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n{vt}f 1/1 2/2 3/3 4/4\n\
         o floor\nv 1 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nf 5 6 7 8\n\
         o lamp\nv 0.7 0.2 1\nv 1.3 0.2 1\nv 1.0 0.8 1\nf 9 11 10\n"
    );
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    std::fs::write(dir.join("geo.obj"), obj).unwrap();
}

/// Texture coordinates that cover no area of a map (an exporter's `vt 0 0` at every
/// corner): every pixel would read one texel. A picture whose panorama shows its texture
/// is then told so, naming the object and its coordinates, and keeps a uniform model,
/// where the same picture with coordinates over [0, 1] gets its map. (Once it got a map
/// solved over one point without a word.)
#[test]
fn a_texture_over_coordinates_no_map_fits_is_told_not_mapped() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    picture_scene(dir, [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    render_picture_panorama(dir, Tiles::No);
    let model_of_picture = |materials: &[u8]| model_of(materials, "picture");
    let mapped = recover(
        &dir.join("scene.toml"),
        &dir.join("mapped"),
        &["--effort", "fast"],
    );
    assert_eq!(model_of_picture(&mapped), "textured-diffuse");

    // `check` names them before any recovery, and names none over [0, 1].
    let check = || {
        let run = relume_ok(dir, &["check", "scene.toml"]);
        String::from_utf8_lossy(&run.stdout).into_owned()
    };
    assert!(!check().contains("texture coordinates:") && !check().contains("tiles:"));
    let why = "texture coordinates that cover no area of a map (u 0..0, v 0..0";
    picture_scene(dir, [[0.0, 0.0]; 4]);
    let stdout = check();
    assert!(
        stdout.contains(&format!(
            "texture coordinates: group 'picture': object 'picture' has {why}"
        )),
        "{stdout}"
    );
    let out = dir.join("unfit");
    let run = relume_ok(
        dir,
        &[
            "recover",
            "scene.toml",
            "--out",
            "unfit",
            "--effort",
            "fast",
        ],
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    let materials = std::fs::read(out.join("materials.toml")).unwrap();
    assert!(
        !model_of_picture(&materials).starts_with("textured"),
        "{}",
        String::from_utf8_lossy(&materials)
    );
    assert!(
        stderr.contains("warning: group 'picture': its pixels show a texture")
            && stderr.contains(&format!("object 'picture' has {why}")),
        "{stderr}"
    );
    let picture = group_report(&out, "picture");
    assert!(
        decisions(&picture)
            .iter()
            .any(|d| d.starts_with("stage 3: textured:") && d.contains("no map is recovered")),
        "{picture}"
    );
    assert!(!out.join("textures/picture.exr").exists());
}

/// A texture tiled twice each way over the picture by coordinates from 0 to 2: its
/// repeats are one map, read wrapped (`diffuse_map_wrap = "repeat"`). Recovered from a
/// panorama of the tiles, the map holds the picture about as well as the same picture
/// laid once over [0, 1] (the repeats' pixels fall on the texels at other offsets), and
/// its render matches the panorama; read clamped, as every map was, the same map misses
/// it by far. (Before, a texture past [0, 1] was told and kept uniform: 22% error.)
#[test]
fn a_texture_tiled_past_the_unit_square_is_mapped_as_tiles() {
    let psnr = |dir: &std::path::Path| {
        let rows = relume::compare::materials_report(
            &dir.join("truth.toml"),
            &dir.join("rec/materials.toml"),
        )
        .unwrap();
        let row = rows.iter().find(|r| r.group == "picture").unwrap();
        row.diffuse_map_psnr_db.unwrap()
    };
    let once = tempfile::tempdir().unwrap();
    picture_scene(
        once.path(),
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
    );
    render_picture_panorama(once.path(), Tiles::No);
    recover(
        &once.path().join("scene.toml"),
        &once.path().join("rec"),
        &["--effort", "fast"],
    );

    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    picture_scene(dir, [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]);
    render_picture_panorama(dir, Tiles::Repeat);
    // Tiles are no fault of the input: `check` says how they will be read.
    let run = relume_ok(dir, &["check", "scene.toml"]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        !stdout.contains("texture coordinates:")
            && stdout.contains(
                "tiles: group 'picture': texture coordinates u 0..2, v 0..2, past [0, 1]"
            ),
        "{stdout}"
    );
    let materials = recover(
        &dir.join("scene.toml"),
        &dir.join("rec"),
        &["--effort", "fast"],
    );
    let text = String::from_utf8_lossy(&materials);
    assert_eq!(model_of(&materials, "picture"), "textured-diffuse");
    assert!(text.contains("diffuse_map_wrap = \"repeat\""), "{text}");
    let picture = group_report(&dir.join("rec"), "picture");
    assert!(
        decisions(&picture)
            .iter()
            .any(|d| d.starts_with("stage 5:") && d.contains("tiled")),
        "{picture}"
    );
    let (tiled, single) = (psnr(dir), psnr(once.path()));
    assert!(tiled > single - 1.0, "{tiled} dB tiled, {single} dB once");

    // Rendered with its map read as tiles it matches the panorama; read clamped, not.
    // The relative RMS of the picture rendered with `materials`, and what render said.
    let rel_rms = |materials: &str, out: &str| {
        let render = relume_ok(
            dir,
            &[
                "render",
                "scene.toml",
                "--materials",
                materials,
                "--out",
                out,
            ],
        );
        let run = relume_ok(
            dir,
            &[
                "compare",
                "views",
                "scene.toml",
                "views",
                out,
                "--json",
                "c.json",
            ],
        );
        assert!(run.status.success());
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("c.json")).unwrap()).unwrap();
        let groups = report["groups"].as_array().unwrap().clone();
        let picture = groups.iter().find(|g| g["name"] == "picture").unwrap();
        let said = String::from_utf8_lossy(&render.stderr).into_owned();
        (picture["rel_rms"].as_f64().unwrap(), said)
    };
    let clamped = text.replace(
        "diffuse_map_wrap = \"repeat\"",
        "diffuse_map_wrap = \"clamp\"",
    );
    std::fs::write(dir.join("rec/clamped.toml"), clamped).unwrap();
    let ((as_tiles, tiles_said), (as_clamped, clamped_said)) = (
        rel_rms("rec/materials.toml", "as_tiles"),
        rel_rms("rec/clamped.toml", "as_clamped"),
    );
    // Render says where a map is read clamped over coordinates that mean tiles.
    let warning = "group 'picture': its texture coordinates reach past [0, 1], where its diffuse_map is read clamped";
    assert!(clamped_said.contains(warning), "{clamped_said}");
    assert!(!tiles_said.contains(warning), "{tiles_said}");
    assert!(
        as_tiles < 0.06 && as_clamped > 3.0 * as_tiles,
        "relative RMS as tiles {as_tiles}, clamped {as_clamped}"
    );
}

/// Whether [`render_picture_panorama`]'s truth tiles the picture's map.
#[derive(Clone, Copy, PartialEq)]
enum Tiles {
    No,
    Repeat,
}

/// Renders `dir`'s scene.toml ([`picture_scene`]) into `views/` with the picture's true
/// map (textured's flowers), read as `tiles` says, and a uniform floor.
fn render_picture_panorama(dir: &std::path::Path, tiles: Tiles) {
    let flowers = shared().join("bench/textured/textures/picture_flowers.exr");
    let wrap = match tiles {
        Tiles::No => "",
        Tiles::Repeat => "diffuse_map_wrap = \"repeat\"\n",
    };
    let truth = format!(
        "format = 1\n\n[[material]]\ngroup = \"picture\"\nmodel = \"textured-diffuse\"\ndiffuse_map = {:?}\n{wrap}\n[[material]]\ngroup = \"floor\"\nmodel = \"diffuse\"\ncolor = [0.5, 0.4, 0.3]\n",
        path_str(&flowers)
    );
    std::fs::write(dir.join("truth.toml"), truth).unwrap();
    let args = ["render", "scene.toml", "--materials", "truth.toml"];
    relume_ok(
        dir,
        &[&args[..], &["--out", "views", "--spp", "256"]].concat(),
    );
}

/// The model materials.toml text `materials` gives `group`.
fn model_of(materials: &[u8], group: &str) -> String {
    let table: toml::Table = String::from_utf8_lossy(materials).parse().unwrap();
    let material = table["material"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["group"].as_str() == Some(group))
        .unwrap()
        .clone();
    material["model"].as_str().unwrap().to_string()
}

/// A picture frame's worth of plain glossy plastic, with texture coordinates: stage 2 finds
/// its lobe, and what the lobe leaves is not established above `SPECULAR_GAIN_THRESHOLD`,
/// so stage 3 does not test it for texture and stage 4 does not try it. Both say so, with
/// the error they read (before, its route ended at stage 2 without a word on either).
#[test]
fn a_plain_glossy_group_with_coordinates_says_why_stages_3_and_4_pass_it_by() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    picture_scene(dir, [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    let truth = "format = 1\n\n[[material]]\ngroup = \"picture\"\nmodel = \"isotropic\"\nkind = \"plastic\"\ncolor = [0.6, 0.5, 0.4]\nspecularity = 0.08\nroughness = 0.1\n\n[[material]]\ngroup = \"floor\"\nmodel = \"diffuse\"\ncolor = [0.5, 0.4, 0.3]\n";
    std::fs::write(dir.join("truth.toml"), truth).unwrap();
    let args = ["render", "scene.toml", "--materials", "truth.toml"];
    relume_ok(
        dir,
        &[&args[..], &["--out", "views", "--spp", "256"]].concat(),
    );
    let out = dir.join("rec");
    recover(&dir.join("scene.toml"), &out, &["--effort", "fast"]);
    let picture = group_report(&out, "picture");
    assert_eq!(picture["model"], "isotropic", "{picture}");
    let decided = picture["error_decided"].as_f64().unwrap();
    let decisions = decisions(&picture);
    let said = |start: &str| {
        decisions
            .iter()
            .find(|d| d.starts_with(start))
            .unwrap_or_else(|| panic!("no {start:?} in {decisions:?}"))
            .to_string()
    };
    let stage3 = said("stage 3: not tested for texture: its error ");
    assert!(
        stage3.contains(&format!("its error {decided:.4} +- ")),
        "{stage3}"
    );
    assert!(
        stage3.contains("not above SPECULAR_GAIN_THRESHOLD 0.01"),
        "{stage3}"
    );
    let stage4 = said("stage 4 gate: not tried: its isotropic model leaves ");
    assert!(
        stage4.contains(&format!("leaves {decided:.4} of")),
        "{stage4}"
    );
    assert!(!out.join("textures/picture.exr").exists());
}

/// The panorama's noise bound, which stage 3 corrects contrasts by, is the tightest of the
/// groups' errors: when it is the tested group's own (here the only group seen), a
/// texture is in the bound it is corrected by, and stage 3 cannot tell it from noise. The
/// picture keeps a uniform model, and the decision and a warning say why, where before a
/// contrast of twice the threshold came out "untextured" and nothing said more.
#[test]
fn a_texture_judged_against_its_own_error_is_told() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    picture_scene(dir, [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    // The view sees the picture alone.
    let scene = std::fs::read_to_string(dir.join("scene.toml")).unwrap();
    let scene = scene
        .replace("position = [1.0, 0.5, 0.9]", "position = [0.5, 0.5, 0.9]")
        .replace("fov_deg = [90.0, 60.0]", "fov_deg = [50.0, 50.0]")
        .replace("size = [48, 24]", "size = [32, 32]");
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    render_picture_panorama(dir, Tiles::No);
    let run = relume_ok(
        dir,
        &["recover", "scene.toml", "--out", "rec", "--effort", "fast"],
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    let materials = std::fs::read(dir.join("rec/materials.toml")).unwrap();
    assert!(!model_of(&materials, "picture").starts_with("textured"));
    assert!(
        stderr.contains("warning: group 'picture': its step contrast")
            && stderr.contains("the panorama's noise bound it is corrected by is its own error"),
        "{stderr}"
    );
    let picture = group_report(&dir.join("rec"), "picture");
    assert!(
        decisions(&picture)
            .iter()
            .any(|d| d.starts_with("stage 3: untextured:")
                && d.ends_with("the bound is this group's own error")),
        "{picture}"
    );
}

/// A picture laid over a quarter of its map's [0, 1]^2 (a corner of a texture atlas) gets
/// a map twice as fine, as many texels where it lies (two a pixel) as one over the whole
/// square, and its map explains its pixels as well: before, the map's side followed the
/// pixel count alone, the picture had a quarter of the texels, and its final error was
/// 8.3% where the same picture over the whole square left 1.7% (1.2% now).
#[test]
fn a_picture_over_a_corner_of_its_map_gets_a_map_as_fine_where_it_lies() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    picture_scene(dir, [[0.0, 0.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]]);
    render_picture_panorama(dir, Tiles::No);
    let materials = recover(
        &dir.join("scene.toml"),
        &dir.join("rec"),
        &["--effort", "fast"],
    );
    assert_eq!(model_of(&materials, "picture"), "textured-diffuse");
    let picture = group_report(&dir.join("rec"), "picture");
    let pure = picture["pure_pixels"].as_f64().unwrap();
    let side = libm::round(libm::sqrt(2.0 * pure / 0.25)) as u32;
    let map = format!("map {side}x{side} from {pure} pure pixels");
    assert!(
        decisions(&picture).iter().any(|d| d.contains(&map)),
        "{map}: {picture}"
    );
    let error = picture["error_final"].as_f64().unwrap();
    assert!(error < 0.03, "final error {error}");
}
