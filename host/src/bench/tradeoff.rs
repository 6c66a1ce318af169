//! `relume bench tradeoff`: recovery's accuracy against its wall time, sweeping one knob at
//! a time from a base effort level: the effort level itself, the annealing's length, the
//! samples per evaluation inside the loops, the samples of the lobes' transport caches,
//! the views' resolution, and the Nelder-Mead arm at the same evaluation counts as the
//! annealing (where the global search pays).
//!
//! Every point is a full `recover::run` judged against the truth; points with the same
//! knobs (the base appears in several sweeps) run once. Results other than the times are
//! deterministic for a seed, whatever the thread count.

use std::collections::BTreeMap;
use std::path::PathBuf;

use super::chart::{Axis, Chart, ChartPoint, Panel, Series};
use super::perturb::{self, Perturbation};
use super::{
    check_truth_of, derived_scene_outputs, field, pct, prepare_outputs, recover_and_judge,
    recover_derived_and_judge, recovery_outputs, Csv, Summary,
};
use crate::error::Error;
use crate::fsutil;
use crate::materials_file;
use crate::recover::{Budget, Effort, Optimiser, RecoverArgs};
use crate::scene_file::{self, SceneDesc};

#[derive(clap::Args)]
pub struct TradeoffArgs {
    /// The scene.toml to recover, whose views carry the panorama's images.
    pub scene: PathBuf,
    /// The true materials (truth.toml) the recoveries are judged against.
    #[arg(long)]
    pub truth: PathBuf,
    /// Output folder: the runs, the CSV and the chart.
    #[arg(long)]
    pub out: PathBuf,
    /// The seed of every recovery.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default: all cores); the materials do not depend on it, the
    /// wall times do.
    #[arg(long)]
    pub threads: Option<usize>,
    /// The base effort level the knobs are swept from.
    #[arg(long, value_enum, default_value_t = Effort::Fast)]
    pub effort: Effort,
    /// Two points per knob and no effort sweep (a first look, and the tests).
    #[arg(long)]
    pub quick: bool,
}

/// One point of the sweep: the base with one knob changed.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepPoint {
    pub knob: &'static str,
    pub value: String,
    pub budget: Budget,
    /// Box-average the views by this factor before recovering.
    pub factor: u32,
}

impl SweepPoint {
    /// The folder name of the point's run.
    pub fn id(&self) -> String {
        format!("{}-{}", self.knob, self.value)
    }
}

fn effort_name(e: Effort) -> &'static str {
    match e {
        Effort::Fast => "fast",
        Effort::Default => "default",
        Effort::Thorough => "thorough",
    }
}

/// `values`, with `base` added if missing, ascending.
fn with_base(mut values: Vec<u32>, base: u32) -> Vec<u32> {
    if !values.contains(&base) {
        values.push(base);
    }
    values.sort_unstable();
    values
}

/// A budget with one knob of samples per pixel set to a value.
type SetSamples = fn(Budget, u32) -> Budget;

/// The points to run, knob by knob; `view_sizes` are the scene's views' sizes in pixels:
/// the resolution knob's values are what box-averaging gives the first view's width, by
/// the factors that divide every view's width and height (a factor checked against the
/// first view alone stopped the sweep at its resolution point, after the other runs).
pub fn sweep(base: Effort, quick: bool, view_sizes: &[[u32; 2]]) -> Vec<SweepPoint> {
    let view_side = view_sizes.first().map_or(0, |s| s[0]);
    let b = base.budget();
    let mut points = Vec::new();
    let efforts = if quick {
        vec![base]
    } else {
        vec![Effort::Fast, Effort::Default, Effort::Thorough]
    };
    for e in efforts {
        points.push(SweepPoint {
            knob: "effort",
            value: effort_name(e).into(),
            budget: e.budget(),
            factor: 1,
        });
    }
    let (levels, spp, cache_spp, factors) = if quick {
        (
            with_base(vec![(b.anneal_levels / 2).max(1)], b.anneal_levels),
            with_base(vec![(b.loop_spp / 2).max(1)], b.loop_spp),
            // No cache knob in a first look: its samples change only the lobes' caches.
            Vec::new(),
            vec![2, 1],
        )
    } else {
        (
            with_base(vec![2, 4, 8, 16], b.anneal_levels),
            with_base(vec![4, 8, 16, 32, 64], b.loop_spp),
            with_base(vec![16, 64, 256], b.cache_spp),
            vec![4, 2, 1],
        )
    };
    for (knob, optimiser) in [
        ("anneal-levels", Optimiser::Annealing),
        ("nelder-mead", Optimiser::NelderMead),
    ] {
        for &l in &levels {
            points.push(SweepPoint {
                knob,
                value: l.to_string(),
                budget: Budget {
                    anneal_levels: l,
                    optimiser,
                    ..b
                },
                factor: 1,
            });
        }
    }
    // The samples-per-pixel knobs: each value set on the base alone.
    let samples: [(&str, &[u32], SetSamples); 2] = [
        ("loop-spp", &spp, |b, s| Budget { loop_spp: s, ..b }),
        ("cache-spp", &cache_spp, |b, s| Budget { cache_spp: s, ..b }),
    ];
    for (knob, values, with) in samples {
        for &s in values {
            points.push(SweepPoint {
                knob,
                value: s.to_string(),
                budget: with(b, s),
                factor: 1,
            });
        }
    }
    for f in factors {
        if view_sizes
            .iter()
            .all(|s| s[0].is_multiple_of(f) && s[1].is_multiple_of(f))
        {
            points.push(SweepPoint {
                knob: "resolution",
                value: (view_side / f).to_string(),
                budget: b,
                factor: f,
            });
        }
    }
    points
}

/// One measured point.
#[derive(Clone, Debug)]
pub struct TradeoffRow {
    pub point: SweepPoint,
    pub px_per_side: u32,
    /// The run folder (shared by points with the same knobs), relative to the output.
    pub run: String,
    pub seconds: f64,
    /// CPU seconds of the run (all threads), where the system tells.
    pub cpu_seconds: Option<f64>,
    pub summary: Summary,
}

/// Runs the sweep, writes `tradeoff.csv` and `tradeoff.svg` (and `.png`) under `args.out`, prints the
/// table and returns the rows.
pub fn run(args: &TradeoffArgs) -> Result<Vec<TradeoffRow>, Error> {
    // Before the output folder is made and the first run told: the runs start the pool.
    crate::parallel::check_threads(args.threads)?;
    let desc = scene_file::load_scene(&args.scene)?;
    let truth = materials_file::load_materials(&args.truth)?;
    check_truth_of(&desc, &truth)?;
    let view_side = desc.views.first().map_or(0, |v| v.size[0]);
    if view_side == 0 {
        return Err(Error::input(&args.scene, "has no view to recover from"));
    }
    let sizes: Vec<[u32; 2]> = desc.views.iter().map(|v| v.size).collect();
    let points = sweep(args.effort, args.quick, &sizes);
    let mut set = prepare_outputs(&desc, &truth, outputs(args, &desc, &points))?;
    fsutil::create_dir(&args.out)?;
    // Points with the same knobs share one run.
    let mut done: BTreeMap<String, (String, f64, Option<f64>, Summary)> = BTreeMap::new();
    let mut rows = Vec::new();
    for (i, point) in points.iter().enumerate() {
        let key = format!("{:?} {}", point.budget, point.factor);
        let (run, seconds, cpu_seconds, summary) = match done.get(&key) {
            Some(found) => found.clone(),
            None => {
                eprintln!(
                    "tradeoff [{}/{}] {} = {}: recovering",
                    i + 1,
                    points.len(),
                    point.knob,
                    point.value
                );
                let scene = scene_for(args, point.factor)?;
                let run = run_dir(point);
                let recover = if point.factor == 1 {
                    recover_and_judge
                } else {
                    recover_derived_and_judge
                };
                let judged = recover(
                    &RecoverArgs {
                        scene,
                        out: args.out.join(&run),
                        seed: args.seed,
                        threads: args.threads,
                        budget: point.budget,
                        limit_group_pixels: None,
                        tell_input_warnings: false,
                    },
                    &args.truth,
                )?;
                let found = (run, judged.seconds, judged.cpu_seconds, judged.summary());
                done.insert(key, found.clone());
                found
            }
        };
        eprintln!(
            "tradeoff [{}/{}] {} = {}: {:.1} s, classes {}/{}, parameter error {}, image error {}",
            i + 1,
            points.len(),
            point.knob,
            point.value,
            seconds,
            summary.classes_right,
            summary.groups,
            pct(summary.param_err),
            pct(summary.image_err)
        );
        rows.push(TradeoffRow {
            point: point.clone(),
            px_per_side: view_side / point.factor,
            run,
            seconds,
            cpu_seconds,
            summary,
        });
    }
    set.add(
        &args.out.join("tradeoff.csv"),
        csv(&rows).to_text().as_bytes(),
    )?;
    let title = format!(
        "relume bench tradeoff: {} (base effort {}, seed {})",
        desc.name,
        effort_name(args.effort),
        args.seed
    );
    chart(&rows, &title).add_to(&mut set, &args.out.join("tradeoff.svg"))?;
    set.commit()?;
    print_table(&rows);
    Ok(rows)
}

/// Every file the sweep of `points` may write: each point's run and box-averaged scene
/// (points that share a run write one of these), the CSV and the chart.
fn outputs(args: &TradeoffArgs, desc: &SceneDesc, points: &[SweepPoint]) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for point in points {
        files.extend(recovery_outputs(&args.out.join(run_dir(point)), desc));
        if point.factor != 1 {
            files.extend(derived_scene_outputs(&scene_dir(args, point.factor), desc));
        }
    }
    files.extend(["tradeoff.csv", "tradeoff.svg", "tradeoff.png"].map(|f| args.out.join(f)));
    files
}

/// A point's run folder, relative to the output.
fn run_dir(point: &SweepPoint) -> String {
    format!("runs/{}", point.id())
}

/// The folder of the scene box-averaged by `factor`.
fn scene_dir(args: &TradeoffArgs, factor: u32) -> PathBuf {
    args.out.join(format!("scenes/factor-{factor}"))
}

/// The scene a point recovers from: the given one, or its box-averaged copy under out/.
fn scene_for(args: &TradeoffArgs, factor: u32) -> Result<PathBuf, Error> {
    if factor == 1 {
        return Ok(args.scene.clone());
    }
    let dir = scene_dir(args, factor);
    perturb::write_perturbed(
        &args.scene,
        &Perturbation {
            factor,
            ..Perturbation::NONE
        },
        &dir,
    )
}

pub const CSV_HEADER: [&str; 20] = [
    "knob",
    "value",
    "loop_spp",
    "cache_spp",
    "anneal_levels",
    "final_spp",
    "optimiser",
    "px_per_side",
    "seconds",
    "cpu_seconds",
    "groups",
    "classes_right",
    "class_accuracy",
    "diffuse_err",
    "specularity_err",
    "roughness_err",
    "param_err",
    "image_err",
    "image_err_weighted",
    "run",
];

fn optimiser_name(o: Optimiser) -> &'static str {
    match o {
        Optimiser::Annealing => "annealing",
        Optimiser::NelderMead => "nelder-mead",
    }
}

fn csv(rows: &[TradeoffRow]) -> Csv {
    let mut csv = Csv::new(&CSV_HEADER);
    for r in rows {
        let (b, s) = (&r.point.budget, &r.summary);
        csv.push(vec![
            r.point.knob.into(),
            r.point.value.clone(),
            b.loop_spp.to_string(),
            b.cache_spp.to_string(),
            b.anneal_levels.to_string(),
            b.final_spp.to_string(),
            optimiser_name(b.optimiser).into(),
            r.px_per_side.to_string(),
            format!("{:.3}", r.seconds),
            field(r.cpu_seconds),
            s.groups.to_string(),
            s.classes_right.to_string(),
            format!("{:.4}", s.class_accuracy),
            field(s.diffuse_err),
            field(s.specularity_err),
            field(s.roughness_err),
            field(s.param_err),
            field(s.image_err),
            field(s.image_err_weighted),
            r.run.clone(),
        ]);
    }
    csv
}

/// Two panels, parameter error and image error against wall time (both log), one curve
/// per knob with each point labelled by the knob's value.
pub fn chart(rows: &[TradeoffRow], title: &str) -> Chart {
    let mut knobs: Vec<&str> = Vec::new();
    for r in rows {
        if !knobs.contains(&r.point.knob) {
            knobs.push(r.point.knob);
        }
    }
    // A run shared by several knobs (the base) is labelled once, as the base.
    let label = |r: &TradeoffRow| {
        let first = rows.iter().position(|o| o.run == r.run);
        let shared = rows.iter().filter(|o| o.run == r.run).count() > 1;
        match (shared, first.map(|i| std::ptr::eq(&rows[i], r))) {
            (false, _) => r.point.value.clone(),
            (true, Some(true)) => format!("base ({} {})", r.point.knob, r.point.value),
            (true, _) => String::new(),
        }
    };
    let panel = |title: &str, y_label: &str, y: fn(&Summary) -> Option<f64>| Panel {
        title: title.into(),
        x: Axis {
            label: "wall time (s)".into(),
            log: true,
            ..Axis::default()
        },
        y: Axis {
            label: y_label.into(),
            log: true,
            percent: true,
            range: None,
        },
        series: knobs
            .iter()
            .map(|&knob| Series {
                name: knob.into(),
                points: rows
                    .iter()
                    .filter(|r| r.point.knob == knob)
                    .filter_map(|r| {
                        Some(ChartPoint {
                            x: r.seconds,
                            y: y(&r.summary)?,
                            label: label(r),
                        })
                    })
                    .collect(),
            })
            .collect(),
    };
    Chart {
        title: title.into(),
        columns: 2,
        panels: vec![
            panel(
                "parameter error against time",
                "mean relative parameter error",
                |s| s.param_err,
            ),
            panel(
                "image error against time",
                "mean relative image error (final render)",
                |s| s.image_err,
            ),
        ],
    }
}

/// The table as Markdown (readable in a terminal, pasted as is into docs/).
fn print_table(rows: &[TradeoffRow]) {
    println!("| knob | value | px | wall s | CPU s | classes | diffuse | spec | rough | param | image | image (px-weighted) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let s = &r.summary;
        println!(
            "| {} | {} | {} | {:.1} | {} | {}/{} | {} | {} | {} | {} | {} | {} |",
            r.point.knob,
            r.point.value,
            r.px_per_side,
            r.seconds,
            r.cpu_seconds.map_or("-".into(), |c| format!("{c:.1}")),
            s.classes_right,
            s.groups,
            pct(s.diffuse_err),
            pct(s.specularity_err),
            pct(s.roughness_err),
            pct(s.param_err),
            pct(s.image_err),
            pct(s.image_err_weighted)
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The values a sweep gives one knob, in order.
    fn values_of(points: &[SweepPoint], knob: &str) -> Vec<String> {
        points
            .iter()
            .filter(|p| p.knob == knob)
            .map(|p| p.value.clone())
            .collect()
    }

    #[test]
    fn each_point_changes_one_knob_of_the_base() {
        let base = Effort::Fast.budget();
        let points = sweep(Effort::Fast, false, &[[64, 64]]);
        for p in &points {
            let b = p.budget;
            let changed = [
                b.loop_spp != base.loop_spp,
                b.cache_spp != base.cache_spp,
                b.anneal_levels != base.anneal_levels,
                b.optimiser != base.optimiser,
                p.factor != 1,
            ]
            .iter()
            .filter(|&&c| c)
            .count();
            match p.knob {
                "effort" => assert_eq!(p.factor, 1),
                // The Nelder-Mead arm changes the optimiser and, along its curve, the
                // evaluation count it is matched to.
                "nelder-mead" => assert!(b.optimiser == Optimiser::NelderMead && changed <= 2),
                _ => assert!(changed <= 1, "{p:?}"),
            }
        }
        let values = |knob: &str| values_of(&points, knob);
        assert_eq!(values("effort"), ["fast", "default", "thorough"]);
        assert_eq!(values("anneal-levels"), ["2", "4", "8", "16"]);
        assert_eq!(values("nelder-mead"), values("anneal-levels"));
        assert_eq!(values("loop-spp"), ["4", "8", "16", "32", "64"]);
        assert_eq!(values("cache-spp"), ["16", "64", "256"]);
        assert_eq!(values("resolution"), ["16", "32", "64"]);
    }

    fn row(knob: &'static str, value: &str, run: &str, seconds: f64) -> TradeoffRow {
        TradeoffRow {
            point: SweepPoint {
                knob,
                value: value.into(),
                budget: Effort::Fast.budget(),
                factor: 1,
            },
            px_per_side: 64,
            run: run.into(),
            seconds,
            cpu_seconds: None,
            summary: Summary {
                groups: 1,
                classes_right: 1,
                class_accuracy: 1.0,
                diffuse_err: Some(0.01),
                specularity_err: None,
                roughness_err: None,
                param_err: Some(0.01),
                image_err: Some(0.02),
                image_err_weighted: Some(0.02),
            },
        }
    }

    #[test]
    fn the_chart_has_a_curve_per_knob_and_labels_the_shared_base_once() {
        let rows = [
            row("effort", "fast", "runs/base", 2.0),
            row("loop-spp", "4", "runs/spp-4", 1.5),
            row("loop-spp", "8", "runs/base", 2.0),
        ];
        let chart = chart(&rows, "t");
        assert_eq!(chart.panels.len(), 2);
        let names: Vec<&str> = chart.panels[0]
            .series
            .iter()
            .map(|s| s.name.as_str())
            .collect();
        assert_eq!(names, ["effort", "loop-spp"]);
        let labels: Vec<&str> = chart.panels[0]
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.label.as_str()))
            .collect();
        assert_eq!(labels, ["base (effort fast)", "4", ""]);
    }

    #[test]
    fn quick_sweeps_keep_the_base_and_skip_factors_that_do_not_divide() {
        let points = sweep(Effort::Default, true, &[[30, 30]]);
        let values = |knob: &str| values_of(&points, knob);
        assert_eq!(values("effort"), ["default"]);
        assert_eq!(values("anneal-levels"), ["4", "8"]);
        assert_eq!(values("loop-spp"), ["16", "32"]);
        assert!(values("cache-spp").is_empty());
        assert_eq!(values("resolution"), ["15", "30"]);
        let odd = sweep(Effort::Fast, true, &[[33, 33]]);
        assert!(odd
            .iter()
            .filter(|p| p.knob == "resolution")
            .all(|p| p.factor == 1));
        // A factor must divide every view, not the first alone: a 31x31 view or a first
        // view 32x9 gives no box-averaged point.
        for sizes in [&[[32, 32], [31, 31]][..], &[[32, 9], [32, 32]]] {
            let points = sweep(Effort::Fast, true, sizes);
            assert_eq!(values_of(&points, "resolution"), ["32"], "{sizes:?}");
        }
        let points = sweep(Effort::Fast, true, &[[32, 8], [16, 16]]);
        assert_eq!(values_of(&points, "resolution"), ["16", "32"]);
    }

    #[test]
    fn the_outputs_checked_before_the_sweep_cover_every_run_and_scaled_scene() {
        let cornell = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
        let args = TradeoffArgs {
            scene: cornell.join("scene.toml"),
            truth: cornell.join("materials.toml"),
            out: PathBuf::from("out"),
            seed: 1,
            threads: None,
            effort: Effort::Fast,
            quick: true,
        };
        let desc = scene_file::load_scene(&args.scene).unwrap();
        let points = sweep(args.effort, args.quick, &[[32, 32]]);
        let files = outputs(&args, &desc, &points);
        for file in [
            "out/runs/effort-fast/materials.toml",
            "out/runs/resolution-16/views/px.exr",
            "out/scenes/factor-2/scene.toml",
            "out/scenes/factor-2/views/nz.exr",
            "out/tradeoff.png",
        ] {
            assert!(files.contains(&PathBuf::from(file)), "{file} not checked");
        }
        assert!(!files.contains(&PathBuf::from("out/scenes/factor-1/scene.toml")));
    }
}
