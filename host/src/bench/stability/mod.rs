//! `relume bench stability`: recovery under controlled perturbations of its input, to show
//! how far each stage can be trusted: other seeds, multiplicative image noise, an exposure
//! error, an error in the brightest light's radiance, smaller views, and one group seen in
//! fewer and fewer pixels. Each run is judged against the truth and against the
//! unperturbed run (the baseline: the first seed), and the targets are checked:
//! parameter spread over seeds <= [`SEED_SPREAD_TARGET`], classes unchanged under 1% noise
//! and 5% exposure error.
//!
//! Its parts: `families` (the perturbation families, their sizes and the runs they
//! make), `spread` (the recovered parameters' spread over seeds), `verdict` (a run
//! judged against the truth and the baseline, and the verdicts on the targets) and
//! `report` (the CSVs, the chart and the table of runs). Here: the arguments, the
//! targets, one run of the study and the study itself.

mod families;
mod report;
mod spread;
mod verdict;

use std::path::PathBuf;

use super::perturb::{self, Perturbation};
use super::{
    check_truth_of, pct, prepare_outputs, recover_and_judge, recover_derived_and_judge, Judged,
};
use crate::error::Error;
use crate::fsutil;
use crate::materials_file;
use crate::recover::{Effort, RecoverArgs};
use crate::scene_file;

pub use families::{limited_group, sizes, Family};
pub use spread::{
    class_flips, seed_spread, spread_by_kind, spread_of, KindSpread, Spread, SPREAD_KINDS,
};
pub use verdict::class_changes;

use families::{outputs, plan, run_id};
use report::{chart, print_runs, runs_csv, spread_csv, ChartContext};
use verdict::print_verdict;

/// The target for the relative spread of a recovered parameter over seeds.
pub const SEED_SPREAD_TARGET: f64 = 0.005;
/// Noise, in percent of each pixel's value (the noise family's sizes), up to which classes
/// must not change.
pub const NOISE_TARGET: f64 = 1.0;
/// Exposure error (percent, either sign) up to which classes must not change.
pub const EXPOSURE_TARGET: f64 = 5.0;

#[derive(clap::Args)]
pub struct StabilityArgs {
    /// The scene.toml to recover, whose views carry the panorama's images.
    pub scene: PathBuf,
    /// The true materials (truth.toml) the recoveries are judged against.
    #[arg(long)]
    pub truth: PathBuf,
    /// Output folder: the perturbed scenes, the runs, the CSVs and the chart.
    #[arg(long)]
    pub out: PathBuf,
    /// The first seed; the seed family runs ten from here (three with --quick).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default: all cores); the materials do not depend on it, the
    /// wall times do.
    #[arg(long)]
    pub threads: Option<usize>,
    /// The effort level of every recovery.
    #[arg(long, value_enum, default_value_t = Effort::Fast)]
    pub effort: Effort,
    /// Fewer points per family.
    #[arg(long)]
    pub quick: bool,
    /// The group seen in fewer and fewer pixels (default: the largest one that is not
    /// diffuse in the truth).
    #[arg(long)]
    pub group: Option<String>,
    /// The families to run, comma-separated (default: all). The first seed, the
    /// baseline, runs always; the other seeds (nine, two with --quick) with `seed`.
    // Empty: all. The baseline runs whatever they are, since every other family is
    // judged against it. (At 256 px per side a whole study takes hours; one family, less.)
    #[arg(long, value_enum, value_delimiter = ',')]
    pub families: Vec<Family>,
}

impl StabilityArgs {
    fn runs_family(&self, family: Family) -> bool {
        self.families.is_empty() || self.families.contains(&family)
    }

    /// The families run, in the study's order.
    fn families_run(&self) -> Vec<Family> {
        Family::ALL
            .into_iter()
            .filter(|&f| self.runs_family(f))
            .collect()
    }
}

/// One recovery of the study.
#[derive(Clone, Debug)]
pub struct StabilityRun {
    pub family: Family,
    /// The perturbation's size in the family's unit (seed, %, pixels).
    pub size: f64,
    pub seed: u64,
    /// The run folder, relative to the output.
    pub run: String,
    pub judged: Judged,
}

/// Runs the study, writes stability.csv, seed-spread.csv and stability.svg (and .png) under
/// `args.out`, prints the runs and the verdict on the targets.
pub fn run(args: &StabilityArgs) -> Result<Vec<StabilityRun>, Error> {
    // Before the output folder is made: the runs start the pool.
    crate::parallel::check_threads(args.threads)?;
    let desc = scene_file::load_scene(&args.scene)?;
    let truth = materials_file::load_materials(&args.truth)?;
    let view_side = desc.views.first().map_or(0, |v| v.size[0]);
    if view_side == 0 {
        return Err(Error::input(&args.scene, "has no view to recover from"));
    }
    if let Some(g) = &args.group {
        // A flag's value that names nothing, as `render --view` is: a usage error.
        if !desc.groups.iter().any(|d| &d.name == g) {
            let names: Vec<&str> = desc.groups.iter().map(|d| d.name.as_str()).collect();
            return Err(Error::Usage(format!(
                "--group names '{g}', which {} does not have (its groups: {})",
                args.scene.display(),
                names.join(", ")
            )));
        }
    }
    check_truth_of(&desc, &truth)?;
    let mut set = prepare_outputs(&desc, &truth, outputs(args, &desc))?;
    fsutil::create_dir(&args.out)?;
    let budget = args.effort.budget();
    let mut runs: Vec<StabilityRun> = Vec::new();
    let recover = |family: Family,
                   size: f64,
                   seed: u64,
                   perturbation: Option<Perturbation>,
                   limit: Option<(String, u32)>|
     -> Result<StabilityRun, Error> {
        let id = run_id(family, size, seed);
        let scene = match perturbation {
            Some(p) => {
                perturb::write_perturbed(&args.scene, &p, &args.out.join("scenes").join(&id))?
            }
            None => args.scene.clone(),
        };
        let run = format!("runs/{id}");
        let recover = match perturbation {
            Some(_) => recover_derived_and_judge,
            None => recover_and_judge,
        };
        let judged = recover(
            &RecoverArgs {
                scene,
                out: args.out.join(&run),
                seed,
                threads: args.threads,
                budget,
                limit_group_pixels: limit,
                tell_input_warnings: false,
            },
            &args.truth,
        )?;
        let s = judged.summary();
        eprintln!(
            "stability {} {}: {:.1} s, classes right {}/{}, parameter error {}",
            family.name(),
            size,
            judged.seconds,
            s.classes_right,
            s.groups,
            pct(s.param_err)
        );
        Ok(StabilityRun {
            family,
            size,
            seed,
            run,
            judged,
        })
    };

    // The group the pixel family limits, chosen on the baseline (the first seed's run).
    let limited = |baseline: &Judged| {
        let group = match &args.group {
            Some(g) => g.clone(),
            None => limited_group(baseline, &truth.materials),
        };
        let pixels = baseline.group(&group).map_or(0, |g| g.pure_pixels);
        (group, pixels)
    };
    let mut limit_of_pixels: Option<(String, u32)> = None;
    for point in plan(args, &desc) {
        let mut limit = None;
        if point.family == Family::Pixels {
            let (group, pixels) = limit_of_pixels.get_or_insert_with(|| limited(&runs[0].judged));
            if point.size as u32 >= *pixels {
                continue;
            }
            limit = Some((group.clone(), point.size as u32));
        }
        let run = recover(
            point.family,
            point.size,
            point.seed,
            point.perturbation,
            limit,
        )?;
        runs.push(run);
    }
    let baseline = runs[0].judged.clone();
    let (group, group_pixels) = limit_of_pixels.unwrap_or_else(|| limited(&baseline));

    let spread = seed_spread(&runs, &truth.materials);
    set.add(
        &args.out.join("stability.csv"),
        runs_csv(&runs, &baseline).to_text().as_bytes(),
    )?;
    set.add(
        &args.out.join("seed-spread.csv"),
        spread_csv(&spread).to_text().as_bytes(),
    )?;
    let title = format!(
        "relume bench stability: {} ({} px per side, effort {:?}, seed {})",
        desc.name, view_side, args.effort, args.seed
    )
    .to_lowercase();
    let families = args.families_run();
    let context = ChartContext {
        view_side,
        group: &group,
        group_pixels,
        families: &families,
    };
    chart(&runs, &baseline, &context, &title).add_to(&mut set, &args.out.join("stability.svg"))?;
    set.commit()?;
    print_runs(&runs, &baseline, &group);
    print_verdict(&runs, &baseline, &spread, &families);
    Ok(runs)
}

#[cfg(test)]
mod tests {
    use super::verdict::family_verdict;
    use super::*;
    use crate::bench::GroupOutcome;
    use crate::materials_file::{MaterialDesc, Model};

    pub(super) fn material(group: &str, model: Model, color: f32, s: f32) -> MaterialDesc {
        let mut m = MaterialDesc::new(group, model);
        m.color = Some([color, color, 2.0 * color]);
        if model == Model::Isotropic {
            m.specularity = Some(s);
            m.roughness = Some(0.1);
        }
        m
    }

    pub(super) fn outcome(group: &str, m: MaterialDesc, pixels: u32) -> GroupOutcome {
        GroupOutcome {
            group: group.into(),
            true_model: "diffuse".into(),
            model: Some(m.model.name().into()),
            class_ok: true,
            diffuse_err: None,
            specularity_err: None,
            roughness_err: None,
            error_final: None,
            pure_pixels: pixels,
            recovered: Some(m),
        }
    }

    pub(super) fn seed_run(seed: u64, groups: Vec<GroupOutcome>) -> StabilityRun {
        StabilityRun {
            family: Family::Seed,
            size: seed as f64,
            seed,
            run: String::new(),
            judged: Judged {
                seconds: 1.0,
                cpu_seconds: None,
                groups,
                warnings: Vec::new(),
            },
        }
    }

    /// A study of the bundled cornell scene (for its plan; nothing is run).
    pub(super) fn cornell_study(seed: u64, quick: bool, families: Vec<Family>) -> StabilityArgs {
        let cornell = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
        StabilityArgs {
            scene: cornell.join("scene.toml"),
            truth: cornell.join("materials.toml"),
            out: PathBuf::from("out"),
            seed,
            threads: None,
            effort: Effort::Fast,
            quick,
            group: None,
            families,
        }
    }

    /// `--families noise`: the baseline (the first seed) and the noise family, nothing else;
    /// the chart draws that family alone, its class panel above its error panel.
    #[test]
    fn chosen_families_run_alone_beside_the_baseline() {
        let args = cornell_study(4, false, vec![Family::Noise]);
        let desc = scene_file::load_scene(&args.scene).unwrap();
        let points = plan(&args, &desc);
        let planned: Vec<(Family, f64)> = points.iter().map(|p| (p.family, p.size)).collect();
        let mut expected = vec![(Family::Seed, 4.0)];
        expected.extend(
            sizes(Family::Noise, false)
                .into_iter()
                .map(|s| (Family::Noise, s)),
        );
        assert_eq!(planned, expected);
        // The files checked before the study are the plan's: no other seed's run.
        let files = outputs(&args, &desc);
        assert!(files.contains(&PathBuf::from("out/runs/noise_0.5/materials.toml")));
        assert!(!files.contains(&PathBuf::from("out/runs/seed_5/materials.toml")));
        assert!(!files.contains(&PathBuf::from("out/scenes/exposure_-5/scene.toml")));

        let judged = |seconds| Judged {
            seconds,
            cpu_seconds: None,
            groups: vec![outcome(
                "floor",
                material("floor", Model::Diffuse, 0.5, 0.0),
                100,
            )],
            warnings: Vec::new(),
        };
        let runs: Vec<StabilityRun> = points
            .iter()
            .map(|p| StabilityRun {
                family: p.family,
                size: p.size,
                seed: p.seed,
                run: String::new(),
                judged: judged(1.0),
            })
            .collect();
        let families = args.families_run();
        assert_eq!(families, [Family::Noise]);
        let ctx = ChartContext {
            view_side: 32,
            group: "floor",
            group_pixels: 100,
            families: &families,
        };
        let chart = chart(&runs, &runs[0].judged, &ctx, "t");
        let titles: Vec<&str> = chart.panels.iter().map(|p| p.title.as_str()).collect();
        assert_eq!(
            titles,
            ["noise: classes", "noise: parameter error"],
            "one family, one column"
        );
        assert_eq!(chart.columns, 1);
        assert_eq!(
            family_verdict(&runs, &runs[0].judged, Family::Exposure, &families),
            "exposure: not run (not among --families)"
        );
    }
}
