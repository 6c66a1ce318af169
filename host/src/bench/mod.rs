//! `relume bench`: figures for people.
//!
//! - [`rays`]: the tracer's speed on a fixed ray file.
//! - [`tradeoff`]: recovery's accuracy against its wall time, one knob at a time.
//! - [`stability`]: recovery under controlled perturbations of its input.
//! - [`edits`]: edited scenes rendered from a recovered model against reference renders.
//!
//! The recovery benches share [`recover_and_judge`] (one recovery, judged against the
//! truth), [`Csv`] and the SVG writer in [`chart`]; [`perturb`] writes the perturbed scenes.

pub mod chart;
pub mod edits;
pub mod perturb;
pub mod rays;
pub mod stability;
pub mod tradeoff;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::compare::{self, Groups};
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::materials_file::{self, MaterialDesc, MaterialsDesc};
use crate::recover::{self, RecoverArgs};
use crate::scene_file::SceneDesc;

/// One group of one recovery, against the truth.
#[derive(Clone, Debug)]
pub struct GroupOutcome {
    pub group: String,
    pub true_model: String,
    /// The recovered model's name; `None` when the group was not recovered (unseen).
    pub model: Option<String>,
    pub class_ok: bool,
    pub diffuse_err: Option<f64>,
    pub specularity_err: Option<f64>,
    pub roughness_err: Option<f64>,
    /// The report's error of the final render over the group's pure pixels.
    pub error_final: Option<f64>,
    pub pure_pixels: u32,
    /// The recovered material as written to materials.toml (for spreads over seeds).
    pub recovered: Option<MaterialDesc>,
}

impl GroupOutcome {
    /// The mean of the parameter errors defined for this group.
    pub fn param_err(&self) -> Option<f64> {
        mean([self.diffuse_err, self.specularity_err, self.roughness_err])
    }
}

/// One recovery judged against the truth.
#[derive(Clone, Debug)]
pub struct Judged {
    /// Wall time of `recover::run`, outputs included.
    pub seconds: f64,
    /// CPU time of the same (all threads): the cost of the run, which another load on a
    /// shared machine does not inflate as it does the wall time.
    pub cpu_seconds: Option<f64>,
    pub groups: Vec<GroupOutcome>,
    /// The recovery report's warnings.
    pub warnings: Vec<String>,
}

/// The figures of one recovery over all groups of the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    pub groups: usize,
    pub classes_right: usize,
    /// `classes_right / groups`.
    pub class_accuracy: f64,
    /// Means over the groups where the error is defined (both sides have the parameter).
    pub diffuse_err: Option<f64>,
    pub specularity_err: Option<f64>,
    pub roughness_err: Option<f64>,
    /// Mean over groups of each group's mean parameter error: one number per recovery.
    pub param_err: Option<f64>,
    /// Mean of the final render's error over groups.
    pub image_err: Option<f64>,
    /// The same, weighted by each group's pure pixels.
    pub image_err_weighted: Option<f64>,
}

/// The mean of the values that are present; `None` if none is.
pub fn mean<I: IntoIterator<Item = Option<f64>>>(values: I) -> Option<f64> {
    let (sum, n) = values
        .into_iter()
        .flatten()
        .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    (n > 0).then(|| sum / n as f64)
}

impl Judged {
    pub fn summary(&self) -> Summary {
        let g = &self.groups;
        let classes_right = g.iter().filter(|o| o.class_ok).count();
        let (weighted, weight) = g
            .iter()
            .filter_map(|o| {
                o.error_final
                    .map(|e| (e * o.pure_pixels as f64, o.pure_pixels))
            })
            .fold((0.0, 0u64), |(s, w), (e, n)| (s + e, w + n as u64));
        Summary {
            groups: g.len(),
            classes_right,
            class_accuracy: classes_right as f64 / g.len().max(1) as f64,
            diffuse_err: mean(g.iter().map(|o| o.diffuse_err)),
            specularity_err: mean(g.iter().map(|o| o.specularity_err)),
            roughness_err: mean(g.iter().map(|o| o.roughness_err)),
            param_err: mean(g.iter().map(GroupOutcome::param_err)),
            image_err: mean(g.iter().map(|o| o.error_final)),
            image_err_weighted: (weight > 0).then(|| weighted / weight as f64),
        }
    }

    pub fn group(&self, name: &str) -> Option<&GroupOutcome> {
        self.groups.iter().find(|o| o.group == name)
    }
}

/// CPU seconds (user + system, all threads) this process has used so far, from
/// `/proc/self/stat` (Linux, whose user-space clock tick is 1/100 s); `None` elsewhere.
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name is in parentheses and may hold spaces: count fields after it.
    let rest = stat.get(stat.rfind(')')? + 1..)?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the line, 12th and 13th after the name.
    let ticks: u64 = fields.get(11)?.parse::<u64>().ok()? + fields.get(12)?.parse::<u64>().ok()?;
    Some(ticks as f64 / 100.0)
}

/// [`recover_and_judge`] on a scene the bench derived from the one it was given (views
/// box-averaged, noise added, a light's radiance changed): there a refusal of the derived
/// scene's input is a finding of the bench, not its failure (views box-averaged until no
/// pixel falls wholly on a group leave nothing to recover). It is judged as a recovery of
/// nothing, every group of the truth unrecovered, the refusal its one warning.
pub fn recover_derived_and_judge(args: &RecoverArgs, truth: &Path) -> Result<Judged, Error> {
    let start = Instant::now();
    match recover_and_judge(args, truth) {
        Err(Error::Input { file, message, .. }) if file == args.scene => {
            eprintln!(
                "relume: {}: recovery refused, judged as a recovery of nothing: {message}",
                file.display()
            );
            let truth = materials_file::load_materials(truth)?;
            Ok(Judged {
                seconds: start.elapsed().as_secs_f64(),
                cpu_seconds: None,
                groups: truth
                    .materials
                    .iter()
                    .map(|m| GroupOutcome {
                        group: m.group.clone(),
                        true_model: m.model.name().into(),
                        model: None,
                        class_ok: false,
                        diffuse_err: None,
                        specularity_err: None,
                        roughness_err: None,
                        error_final: None,
                        pure_pixels: 0,
                        recovered: None,
                    })
                    .collect(),
                warnings: vec![format!("recovery refused: {message}")],
            })
        }
        judged => judged,
    }
}

/// Runs one recovery and judges its materials.toml against `truth`.
pub fn recover_and_judge(args: &RecoverArgs, truth: &Path) -> Result<Judged, Error> {
    let start = Instant::now();
    let cpu_start = process_cpu_seconds();
    let report = recover::run(args)?;
    let seconds = start.elapsed().as_secs_f64();
    let cpu_seconds = match (cpu_start, process_cpu_seconds()) {
        (Some(a), Some(b)) => Some(b - a),
        _ => None,
    };
    let materials = args.out.join("materials.toml");
    let rows = compare::materials_report(truth, &materials)?;
    let recovered: BTreeMap<String, MaterialDesc> = materials_file::load_materials(&materials)?
        .materials
        .into_iter()
        .map(|m| (m.group.clone(), m))
        .collect();
    let groups = rows
        .into_iter()
        .map(|row| {
            let reported = report.groups.iter().find(|g| g.group == row.group);
            GroupOutcome {
                recovered: recovered.get(&row.group).cloned(),
                true_model: row.true_model,
                model: row.model,
                class_ok: row.class_ok,
                diffuse_err: row.diffuse_rel_err,
                specularity_err: row.specularity_rel_err,
                roughness_err: row.roughness_rel_err,
                error_final: reported.and_then(|g| g.error_final),
                pure_pixels: reported.map_or(0, |g| g.pure_pixels),
                group: row.group,
            }
        })
        .collect();
    Ok(Judged {
        seconds,
        cpu_seconds,
        groups,
        warnings: report.warnings,
    })
}

/// An input error on the truth unless its groups are exactly the scene's: a truth of
/// another scene ran for minutes and judged its recoveries against nothing.
pub fn check_truth_of(scene: &SceneDesc, truth: &MaterialsDesc) -> Result<(), Error> {
    let groups: Vec<&str> = truth.materials.iter().map(|m| m.group.as_str()).collect();
    let theirs: Vec<&str> = scene.groups.iter().map(|g| g.name.as_str()).collect();
    compare::check_groups(
        &truth.path,
        &groups,
        "the scene",
        &scene.path,
        &theirs,
        Groups::Same,
        "a truth of another scene?",
    )
}

/// The output set of a recovery bench (`scene` judged against `truth`), once no file in
/// `outputs` would replace an input of the bench: the scene's files or the truth's. Each
/// recovery keeps its own scene's files only; the truth, its to judge by, is the bench's.
/// Checked before the first run, not when a run or the final tables meet it.
pub fn prepare_outputs(
    scene: &SceneDesc,
    truth: &MaterialsDesc,
    outputs: Vec<PathBuf>,
) -> Result<OutputSet, Error> {
    let set = OutputSet::keeping([scene.input_files(), truth.input_files()].concat());
    set.check_targets(outputs)?;
    Ok(set)
}

/// The files a recovery of `scene` into `out` writes or may remove (an earlier run's
/// maps), as `recover` names them.
pub fn recovery_outputs(out: &Path, scene: &SceneDesc) -> Vec<PathBuf> {
    let views: Vec<String> = scene.views.iter().map(|v| v.name.clone()).collect();
    let groups: Vec<String> = scene.groups.iter().map(|g| g.name.clone()).collect();
    recover::output_files(out, &views, &groups)
}

/// The files a copy of `scene` derived into `out` (perturbed, box-averaged) writes, as
/// `downsample::write_derived_scene` names them.
pub fn derived_scene_outputs(out: &Path, scene: &SceneDesc) -> Vec<PathBuf> {
    let mut files = vec![out.join("scene.toml")];
    files.extend(
        scene
            .views
            .iter()
            .map(|v| out.join("views").join(format!("{}.exr", v.name))),
    );
    files
}

/// A CSV table: a header and rows of already formatted fields.
pub struct Csv {
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl Csv {
    pub fn new(header: &[&str]) -> Csv {
        Csv {
            header: header.iter().map(|h| h.to_string()).collect(),
            rows: Vec::new(),
        }
    }

    pub fn push(&mut self, row: Vec<String>) {
        debug_assert_eq!(row.len(), self.header.len(), "CSV row width");
        self.rows.push(row);
    }

    /// RFC 4180 text: fields with a comma, quote or line break are quoted.
    pub fn to_text(&self) -> String {
        let line = |fields: &[String]| {
            let quoted: Vec<String> = fields
                .iter()
                .map(|f| {
                    if f.contains([',', '"', '\n', '\r']) {
                        format!("\"{}\"", f.replace('"', "\"\""))
                    } else {
                        f.clone()
                    }
                })
                .collect();
            quoted.join(",") + "\n"
        };
        let mut text = line(&self.header);
        for r in &self.rows {
            text.push_str(&line(r));
        }
        text
    }
}

/// A CSV field for an optional number: empty when absent or undefined (not finite), never
/// `NaN`.
pub fn field(v: Option<f64>) -> String {
    v.filter(|v| v.is_finite())
        .map_or(String::new(), |v| format!("{v:.6}"))
}

/// A table cell for an optional fraction, as a percentage.
pub fn pct(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{:.2}%", 100.0 * v))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The process's CPU time grows as it works. Spun until it has grown, not for a time
    /// on the clock: on a shared machine 0.3 s of wall time spun gave 0.11 s of CPU, and
    /// other tests' threads in the process add theirs.
    #[test]
    fn cpu_time_grows_with_work() {
        let Some(before) = process_cpu_seconds() else {
            return; // not Linux: nothing to measure
        };
        let start = Instant::now();
        let mut x = 0u64;
        let mut used = 0.0;
        while used < 0.2 {
            for _ in 0..1_000_000 {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
            }
            std::hint::black_box(x);
            used = process_cpu_seconds().unwrap() - before;
            assert!(
                start.elapsed().as_secs() < 120,
                "the CPU time read {used} s after 2 minutes of spinning"
            );
        }
    }

    #[test]
    fn csv_quotes_only_what_needs_it() {
        let mut csv = Csv::new(&["knob", "value"]);
        csv.push(vec!["a,b".into(), "say \"hi\"".into()]);
        csv.push(vec!["plain".into(), field(Some(0.25))]);
        csv.push(vec!["none".into(), field(None)]);
        assert_eq!(
            csv.to_text(),
            "knob,value\n\"a,b\",\"say \"\"hi\"\"\"\nplain,0.250000\nnone,\n"
        );
    }

    fn outcome(class_ok: bool, d: Option<f64>, s: Option<f64>, e: f64, px: u32) -> GroupOutcome {
        GroupOutcome {
            group: "g".into(),
            true_model: "diffuse".into(),
            model: Some("diffuse".into()),
            class_ok,
            diffuse_err: d,
            specularity_err: s,
            roughness_err: None,
            error_final: Some(e),
            pure_pixels: px,
            recovered: None,
        }
    }

    #[test]
    fn summary_means_skip_undefined_errors_and_weight_by_pixels() {
        let judged = Judged {
            seconds: 1.0,
            cpu_seconds: None,
            groups: vec![
                outcome(true, Some(0.02), None, 0.01, 300),
                outcome(false, Some(0.04), Some(0.5), 0.05, 100),
            ],
            warnings: Vec::new(),
        };
        let s = judged.summary();
        assert_eq!((s.groups, s.classes_right), (2, 1));
        assert_eq!(s.class_accuracy, 0.5);
        assert!((s.diffuse_err.unwrap() - 0.03).abs() < 1e-12);
        assert_eq!(s.specularity_err, Some(0.5));
        assert_eq!(s.roughness_err, None);
        // Group means 0.02 and 0.27, then their mean.
        assert!((s.param_err.unwrap() - 0.145).abs() < 1e-12);
        assert!((s.image_err.unwrap() - 0.03).abs() < 1e-12);
        assert!((s.image_err_weighted.unwrap() - 0.02).abs() < 1e-12);
    }

    #[test]
    fn csv_fields_of_undefined_numbers_are_empty() {
        assert_eq!(field(Some(f64::NAN)), "");
        assert_eq!(field(Some(f64::INFINITY)), "");
    }

    fn cornell() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell")
    }

    #[test]
    fn a_truth_of_another_scene_is_refused_naming_the_groups_on_each_side() {
        let scene = crate::scene_file::load_scene(&cornell().join("scene.toml")).unwrap();
        let mut truth = materials_file::load_materials(&cornell().join("materials.toml")).unwrap();
        check_truth_of(&scene, &truth).unwrap();
        truth.materials.retain(|m| m.group != "box");
        truth.materials[0].group = "sofa".into();
        let e = check_truth_of(&scene, &truth).unwrap_err().to_string();
        assert!(
            e.contains("materials.toml: its groups are not those of the scene")
                && e.contains("only in this file: 'sofa'; only in the scene: 'floor', 'box'"),
            "{e}"
        );
    }

    #[test]
    fn a_bench_output_over_its_truth_is_refused_before_the_first_run() {
        let dir = tempfile::tempdir().unwrap();
        let scene = crate::scene_file::load_scene(&cornell().join("scene.toml")).unwrap();
        // The truth where a run's materials.toml, or a map of its, would go.
        let run = dir.path().join("runs/a");
        std::fs::create_dir_all(run.join("textures")).unwrap();
        std::fs::copy(cornell().join("materials.toml"), run.join("materials.toml")).unwrap();
        let truth = materials_file::load_materials(&run.join("materials.toml")).unwrap();
        let e = prepare_outputs(&scene, &truth, recovery_outputs(&run, &scene))
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("runs/a/materials.toml") && e.contains("a materials file"),
            "{e}"
        );
        let elsewhere = recovery_outputs(&dir.path().join("runs/b"), &scene);
        assert!(elsewhere.contains(&dir.path().join("runs/b/textures/box.cal")));
        assert!(elsewhere.contains(&dir.path().join("runs/b/errors/px.png")));
        prepare_outputs(&scene, &truth, elsewhere).unwrap();
        let e = prepare_outputs(&scene, &truth, derived_scene_outputs(&cornell(), &scene))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("would replace the scene file"), "{e}");
    }
}
