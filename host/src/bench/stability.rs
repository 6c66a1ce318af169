//! `relume bench stability`: recovery under controlled perturbations of its input, to show
//! how far each stage can be trusted: other seeds, multiplicative image noise, an exposure
//! error, an error in the brightest light's radiance, smaller views, and one group seen in
//! fewer and fewer pixels. Each run is judged against the truth and against the
//! unperturbed run (the baseline: the first seed), and the targets are checked:
//! parameter spread over seeds <= [`SEED_SPREAD_TARGET`], classes unchanged under 1% noise
//! and 5% exposure error.

use std::collections::BTreeMap;
use std::path::PathBuf;

use super::chart::{Axis, Chart, ChartPoint, Panel, Series};
use super::perturb::{self, Perturbation};
use super::{
    check_truth_of, derived_scene_outputs, field, pct, prepare_outputs, recover_and_judge,
    recover_derived_and_judge, recovery_outputs, Csv, GroupOutcome, Judged,
};
use crate::error::Error;
use crate::fsutil;
use crate::materials_file::{self, MaterialDesc, Model};
use crate::recover::{Effort, RecoverArgs};
use crate::scene_file::{self, SceneDesc};

/// The target for the relative spread of a recovered parameter over seeds.
pub const SEED_SPREAD_TARGET: f64 = 0.005;
/// Noise (relative) up to which classes must not change.
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
    /// The first seed; the seed family runs ten from here.
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
    /// baseline, runs always; the other nine seeds with `seed`.
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

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum Family {
    Seed,
    Noise,
    Exposure,
    Light,
    Resolution,
    Pixels,
}

impl Family {
    pub const ALL: [Family; 6] = [
        Family::Seed,
        Family::Noise,
        Family::Exposure,
        Family::Light,
        Family::Resolution,
        Family::Pixels,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Family::Seed => "seed",
            Family::Noise => "noise",
            Family::Exposure => "exposure",
            Family::Light => "light",
            Family::Resolution => "resolution",
            Family::Pixels => "pixels",
        }
    }

    /// How harsh a perturbation of `size` is, to order a family's runs from the mildest:
    /// noise, exposure and light errors grow with `|size|`, while fewer pixels per side
    /// or fewer pixels of a group are harsher the smaller they are.
    fn severity(self, size: f64) -> f64 {
        match self {
            Family::Resolution | Family::Pixels => -size,
            Family::Seed | Family::Noise | Family::Exposure | Family::Light => size.abs(),
        }
    }

    fn x_axis(self) -> Axis {
        let (label, log) = match self {
            Family::Seed => ("seed", false),
            Family::Noise => ("image noise, relative sd (%)", false),
            Family::Exposure => ("exposure error (%)", false),
            Family::Light => ("brightest light's radiance error (%)", false),
            Family::Resolution => ("view pixels per side", true),
            Family::Pixels => ("pure pixels of the limited group", true),
        };
        Axis {
            label: label.into(),
            log,
            ..Axis::default()
        }
    }
}

/// The perturbation sizes of each family (before filtering by the scene).
pub fn sizes(family: Family, quick: bool) -> Vec<f64> {
    match (family, quick) {
        (Family::Seed, false) => (0..10).map(f64::from).collect(),
        (Family::Seed, true) => (0..3).map(f64::from).collect(),
        (Family::Noise, false) => vec![0.5, 1.0, 2.0, 5.0, 10.0],
        (Family::Noise, true) => vec![1.0, 5.0],
        (Family::Exposure, false) => vec![-10.0, -5.0, -2.0, 2.0, 5.0, 10.0],
        (Family::Light, false) => vec![-10.0, -5.0, 5.0, 10.0],
        (Family::Exposure | Family::Light, true) => vec![-5.0, 5.0],
        (Family::Resolution, false) => vec![16.0, 32.0, 64.0, 128.0, 256.0],
        (Family::Resolution, true) => vec![16.0],
        (Family::Pixels, false) => vec![4096.0, 1024.0, 256.0, 64.0, 16.0],
        (Family::Pixels, true) => vec![256.0, 16.0],
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

/// Whether each group's recovered class equals the baseline's.
fn same_class(run: &Judged, baseline: &Judged) -> Vec<bool> {
    run.groups
        .iter()
        .map(|g| baseline.group(&g.group).map(|b| &b.model) == Some(&g.model))
        .collect()
}

/// The warnings about its whole input in `run`'s report that the baseline's report does
/// not have: what the report said of the perturbed input. A group's warnings (each begins
/// `group '<name>'`) are left out: borderline decisions come and go with the seed.
fn new_input_warnings<'a>(run: &'a Judged, baseline: &Judged) -> Vec<&'a str> {
    run.warnings
        .iter()
        .filter(|w| !w.starts_with("group '") && !baseline.warnings.contains(w))
        .map(String::as_str)
        .collect()
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

/// The folder name of a run (under runs/) and of its perturbed scene (under scenes/). A
/// seed's run is named by the seed itself: past 2^53 its size (a 64-bit float) gives
/// neighbouring seeds one folder.
fn run_id(family: Family, size: f64, seed: u64) -> String {
    match family {
        Family::Seed => format!("{}_{seed}", family.name()),
        _ => format!("{}_{}", family.name(), size),
    }
}

/// Whether the resolution family has a point at `side` pixels: smaller than the first
/// view's width and dividing it, by a factor that divides every view's width and height,
/// as box-averaging needs. (Views divisible by `side` itself passed: views of 48 and 32
/// at 16 took factor 3, which 32 refused, after the other families' runs.)
fn resolution_applies(desc: &SceneDesc, side: u32) -> bool {
    let view_side = desc.views.first().map_or(0, |v| v.size[0]);
    side > 0
        && side < view_side
        && view_side.is_multiple_of(side)
        && desc.views.iter().all(|v| {
            let factor = view_side / side;
            v.size[0].is_multiple_of(factor) && v.size[1].is_multiple_of(factor)
        })
}

/// One recovery of the study: its family and size (the x of its chart), its seed, and
/// how its scene differs from the study's (`None`: the scene itself).
struct Point {
    family: Family,
    size: f64,
    seed: u64,
    perturbation: Option<Perturbation>,
}

/// Every recovery the study may make, in order, the seeds first (the first is the
/// baseline). The pixel family's points are all listed: which of them run depends on the
/// baseline's pixels of the limited group. [`run`] recovers them and [`outputs`] checks
/// their files before the first, so the two cannot disagree.
fn plan(args: &StabilityArgs, desc: &SceneDesc) -> Vec<Point> {
    let point = |family, size, seed, perturbation| Point {
        family,
        size,
        seed,
        perturbation,
    };
    let seeds = match args.runs_family(Family::Seed) {
        true => sizes(Family::Seed, args.quick),
        false => vec![0.0],
    };
    let mut points: Vec<Point> = seeds
        .into_iter()
        // Any seed starts a family, as any seed is a recovery's: past u64::MAX it wraps.
        .map(|k| args.seed.wrapping_add(k as u64))
        .map(|seed| point(Family::Seed, seed as f64, seed, None))
        .collect();
    let chosen = |family: Family| match args.runs_family(family) {
        true => sizes(family, args.quick),
        false => Vec::new(),
    };
    for family in [Family::Noise, Family::Exposure, Family::Light] {
        for size in chosen(family) {
            let mut p = Perturbation::NONE;
            match family {
                Family::Noise => {
                    p.noise = size / 100.0;
                    p.noise_seed = args.seed;
                }
                Family::Exposure => p.exposure = (1.0 + size / 100.0) as f32,
                _ => p.light = (1.0 + size / 100.0) as f32,
            }
            points.push(point(family, size, args.seed, Some(p)));
        }
    }
    let view_side = desc.views.first().map_or(0, |v| v.size[0]);
    for size in chosen(Family::Resolution) {
        let side = size as u32;
        if resolution_applies(desc, side) {
            let p = Perturbation {
                factor: view_side / side,
                ..Perturbation::NONE
            };
            points.push(point(Family::Resolution, size, args.seed, Some(p)));
        }
    }
    for size in chosen(Family::Pixels) {
        points.push(point(Family::Pixels, size, args.seed, None));
    }
    points
}

/// Every file the study may write: each point's run and perturbed scene, the CSVs and the
/// chart.
fn outputs(args: &StabilityArgs, desc: &SceneDesc) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for point in plan(args, desc) {
        let id = run_id(point.family, point.size, point.seed);
        files.extend(recovery_outputs(&args.out.join("runs").join(&id), desc));
        if point.perturbation.is_some() {
            files.extend(derived_scene_outputs(
                &args.out.join("scenes").join(&id),
                desc,
            ));
        }
    }
    files.extend(
        [
            "stability.csv",
            "seed-spread.csv",
            "stability.svg",
            "stability.png",
        ]
        .map(|f| args.out.join(f)),
    );
    files
}

/// The largest group (by pure pixels in the baseline) that is not diffuse in the truth, or
/// the largest of all when every group is diffuse.
pub fn limited_group(baseline: &Judged, truth: &[MaterialDesc]) -> String {
    let diffuse = |g: &GroupOutcome| {
        truth
            .iter()
            .any(|t| t.group == g.group && t.model == Model::Diffuse)
    };
    let largest = |candidates: &mut dyn Iterator<Item = &GroupOutcome>| {
        candidates
            .max_by(|a, b| {
                a.pure_pixels
                    .cmp(&b.pure_pixels)
                    .then(b.group.cmp(&a.group))
            })
            .map(|g| g.group.clone())
    };
    largest(&mut baseline.groups.iter().filter(|g| !diffuse(g)))
        .or_else(|| largest(&mut baseline.groups.iter()))
        .unwrap_or_default()
}

/// The spread over seeds of one recovered parameter of one group.
#[derive(Clone, Debug, PartialEq)]
pub struct Spread {
    pub group: String,
    /// The model most seeds recovered (ties: the first seed's), and in how many seeds.
    pub model: String,
    pub seeds_with_model: usize,
    pub seeds: usize,
    pub parameter: &'static str,
    pub truth: Option<f64>,
    pub mean: f64,
    /// Sample standard deviation over the seeds that recovered `model`.
    pub std: f64,
    /// `std / |mean|`; `None` when the mean is 0.
    pub rel_std: Option<f64>,
}

/// Mean, sample standard deviation and relative standard deviation; `None` for fewer than
/// two values.
pub fn spread_of(values: &[f64]) -> Option<(f64, f64, Option<f64>)> {
    if values.len() < 2 {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0);
    let std = var.sqrt();
    Some((mean, std, (mean != 0.0).then(|| std / mean.abs())))
}

/// The scalar parameters a material of `model` carries, as written in materials.toml: the
/// colour (none for a textured model, whose colour is its map), and a lobe's specularity
/// and roughness or roughnesses, textured or not. (A lobe's direction is a vector, left
/// out.)
fn parameters(m: &MaterialDesc) -> Vec<(&'static str, Option<f64>)> {
    let c = m.color.map(|c| c.map(f64::from));
    let mut p = vec![
        ("color_r", c.map(|c| c[0])),
        ("color_g", c.map(|c| c[1])),
        ("color_b", c.map(|c| c[2])),
    ];
    let scalar = |v: Option<f32>| v.map(f64::from);
    match m.model {
        Model::Isotropic | Model::TexturedIsotropic => {
            p.push(("specularity", scalar(m.specularity)));
            p.push(("roughness", scalar(m.roughness)));
        }
        Model::Anisotropic | Model::TexturedAnisotropic => {
            p.push(("specularity", scalar(m.specularity)));
            p.push(("roughness_u", scalar(m.roughness_u)));
            p.push(("roughness_v", scalar(m.roughness_v)));
        }
        Model::Diffuse | Model::Mirror | Model::TexturedDiffuse => {}
    }
    p
}

/// The seed runs' judgements, in order.
fn seed_runs(runs: &[StabilityRun]) -> Vec<&Judged> {
    runs.iter()
        .filter(|r| r.family == Family::Seed)
        .map(|r| &r.judged)
        .collect()
}

/// `group`'s most common model over `seeds` (a tie goes to the first seed's) and the
/// materials recovered with it; `None` where no seed recovered the group.
fn common_model<'a>(
    seeds: &[&'a Judged],
    group: &str,
) -> Option<(&'static str, Vec<&'a MaterialDesc>)> {
    let recovered: Vec<&MaterialDesc> = seeds
        .iter()
        .filter_map(|j| j.group(group)?.recovered.as_ref())
        .collect();
    let mut counts: BTreeMap<&'static str, usize> = BTreeMap::new();
    for m in &recovered {
        *counts.entry(m.model.name()).or_default() += 1;
    }
    let first_model = recovered.first()?.model.name();
    let top = counts.values().copied().max().unwrap_or(0);
    let model = if counts[first_model] == top {
        first_model
    } else {
        counts
            .iter()
            .find(|(_, &n)| n == top)
            .map_or(first_model, |(m, _)| *m)
    };
    let same = recovered
        .into_iter()
        .filter(|m| m.model.name() == model)
        .collect();
    Some((model, same))
}

/// The groups whose model is not the same on every seed, as "group (model in n/N)" with
/// the most common model: from the classes themselves, so that a group whose model has
/// no parameter to spread (textured-diffuse) is counted too.
pub fn class_flips(runs: &[StabilityRun]) -> Vec<String> {
    let seeds = seed_runs(runs);
    let Some(first) = seeds.first() else {
        return Vec::new();
    };
    first
        .groups
        .iter()
        .filter_map(|g| {
            let (model, same) = common_model(&seeds, &g.group)?;
            (same.len() < seeds.len())
                .then(|| format!("{} ({model} in {}/{})", g.group, same.len(), seeds.len()))
        })
        .collect()
}

/// Per group and parameter, the spread over the seed family's runs (those that recovered
/// the group's most common model).
pub fn seed_spread(runs: &[StabilityRun], truth: &[MaterialDesc]) -> Vec<Spread> {
    let seeds = seed_runs(runs);
    let Some(first) = seeds.first() else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for g in &first.groups {
        let Some((model, same)) = common_model(&seeds, &g.group) else {
            continue;
        };
        let true_m = truth.iter().find(|t| t.group == g.group);
        let true_params: Vec<(&'static str, Option<f64>)> =
            true_m.map(parameters).unwrap_or_default();
        for (i, (name, _)) in parameters(same[0]).into_iter().enumerate() {
            let values: Vec<f64> = same.iter().filter_map(|m| parameters(m)[i].1).collect();
            let Some((mean, std, rel_std)) = spread_of(&values) else {
                continue;
            };
            out.push(Spread {
                group: g.group.clone(),
                model: model.into(),
                seeds_with_model: same.len(),
                seeds: seeds.len(),
                parameter: name,
                truth: true_params
                    .iter()
                    .find(|(n, _)| *n == name)
                    .and_then(|(_, v)| *v),
                mean,
                std,
                rel_std,
            });
        }
    }
    out
}

/// The seed spread of one kind of parameter: the diffuse groups' colours, the colours
/// under a lobe (or a map), the lobes' own parameters. The target weighs them alike, but
/// they part by orders of magnitude: a weak lobe's roughness is loose in its pixels.
#[derive(Debug, PartialEq)]
pub struct KindSpread {
    pub kind: &'static str,
    pub largest: f64,
    pub above: usize,
    pub parameters: usize,
}

/// The kinds of [`spread_by_kind`], in its order.
pub const SPREAD_KINDS: [&str; 3] = [
    "diffuse groups' colours",
    "colours under a lobe",
    "lobe parameters",
];

/// [`Spread`]s gathered by kind, the kinds that have any, in [`SPREAD_KINDS`]' order.
pub fn spread_by_kind(spread: &[Spread]) -> Vec<KindSpread> {
    let kind_of = |s: &Spread| match (s.parameter.starts_with("color_"), s.model.as_str()) {
        (true, "diffuse") => SPREAD_KINDS[0],
        (true, _) => SPREAD_KINDS[1],
        (false, _) => SPREAD_KINDS[2],
    };
    SPREAD_KINDS
        .into_iter()
        .filter_map(|kind| {
            let rel: Vec<f64> = spread
                .iter()
                .filter(|s| kind_of(s) == kind)
                .filter_map(|s| s.rel_std)
                .collect();
            (!rel.is_empty()).then(|| KindSpread {
                kind,
                largest: rel.iter().copied().fold(0.0, f64::max),
                above: rel.iter().filter(|&&r| r > SEED_SPREAD_TARGET).count(),
                parameters: rel.len(),
            })
        })
        .collect()
}

fn runs_csv(runs: &[StabilityRun], baseline: &Judged) -> Csv {
    let mut csv = Csv::new(&[
        "family",
        "size",
        "seed",
        "group",
        "true_model",
        "model",
        "class_ok",
        "class_as_baseline",
        "diffuse_err",
        "specularity_err",
        "roughness_err",
        "param_err",
        "error_final",
        "pure_pixels",
        "input_warnings",
        "seconds",
        "cpu_seconds",
        "run",
    ]);
    for r in runs {
        let same = same_class(&r.judged, baseline);
        let warned = new_input_warnings(&r.judged, baseline).len();
        for (g, same) in r.judged.groups.iter().zip(same) {
            csv.push(vec![
                r.family.name().into(),
                r.size.to_string(),
                r.seed.to_string(),
                g.group.clone(),
                g.true_model.clone(),
                g.model.clone().unwrap_or_default(),
                g.class_ok.to_string(),
                same.to_string(),
                field(g.diffuse_err),
                field(g.specularity_err),
                field(g.roughness_err),
                field(g.param_err()),
                field(g.error_final),
                g.pure_pixels.to_string(),
                warned.to_string(),
                format!("{:.3}", r.judged.seconds),
                field(r.judged.cpu_seconds),
                r.run.clone(),
            ]);
        }
    }
    csv
}

fn spread_csv(spread: &[Spread]) -> Csv {
    let mut csv = Csv::new(&[
        "group",
        "model",
        "seeds_with_model",
        "seeds",
        "parameter",
        "truth",
        "mean",
        "std",
        "rel_std",
    ]);
    for s in spread {
        csv.push(vec![
            s.group.clone(),
            s.model.clone(),
            s.seeds_with_model.to_string(),
            s.seeds.to_string(),
            s.parameter.into(),
            field(s.truth),
            field(Some(s.mean)),
            field(Some(s.std)),
            field(s.rel_std),
        ]);
    }
    csv
}

struct ChartContext<'a> {
    view_side: u32,
    group: &'a str,
    group_pixels: u32,
    /// The families run, in the study's order: one column of panels each.
    families: &'a [Family],
}

/// Per family, two panels: the fraction of classes right (against the truth) and
/// unchanged (against the baseline), and the mean parameter error; the pixels family also
/// shows the limited group alone.
fn chart(runs: &[StabilityRun], baseline: &Judged, ctx: &ChartContext, title: &str) -> Chart {
    let mut class_panels = Vec::new();
    let mut error_panels = Vec::new();
    for &family in ctx.families {
        // The family's runs plus the baseline at its natural place, sorted along x.
        let mut points: Vec<(f64, &Judged)> = runs
            .iter()
            .filter(|r| r.family == family)
            .map(|r| (r.size, &r.judged))
            .collect();
        let baseline_x = match family {
            Family::Seed => None,
            Family::Resolution => Some(ctx.view_side as f64),
            Family::Pixels => Some(ctx.group_pixels as f64),
            _ => Some(0.0),
        };
        if let Some(x) = baseline_x {
            points.push((x, baseline));
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let series = |name: String, y: &dyn Fn(&Judged) -> Option<f64>| Series {
            name,
            points: points
                .iter()
                .filter_map(|(x, j)| {
                    Some(ChartPoint {
                        x: *x,
                        y: y(j)?,
                        label: String::new(),
                    })
                })
                .collect(),
        };
        let right = |j: &Judged| Some(j.summary().class_accuracy);
        let unchanged = |j: &Judged| {
            let same = same_class(j, baseline);
            Some(same.iter().filter(|&&s| s).count() as f64 / same.len().max(1) as f64)
        };
        let mut class_series = vec![
            series("right (vs truth)".into(), &right),
            series("as baseline".into(), &unchanged),
        ];
        let mut error_series = vec![series("all groups".into(), &|j: &Judged| {
            j.summary().param_err
        })];
        if family == Family::Pixels {
            let own = |j: &Judged| j.group(ctx.group).map(|g| f64::from(u8::from(g.class_ok)));
            class_series.push(series(format!("{} right", ctx.group), &own));
            let own_err = |j: &Judged| j.group(ctx.group).and_then(GroupOutcome::param_err);
            error_series.push(series(ctx.group.to_string(), &own_err));
        }
        let title = match family {
            Family::Pixels => format!("pixels of {}", ctx.group),
            f => f.name().to_string(),
        };
        class_panels.push(Panel {
            title: format!("{title}: classes"),
            x: family.x_axis(),
            y: Axis {
                label: "fraction of groups".into(),
                log: false,
                percent: false,
                range: Some((0.0, 1.0)),
            },
            series: class_series,
        });
        error_panels.push(Panel {
            title: format!("{title}: parameter error"),
            x: family.x_axis(),
            y: Axis {
                label: "mean relative parameter error".into(),
                log: true,
                percent: true,
                range: None,
            },
            series: error_series,
        });
    }
    // Three families per row band: their class panels above their error panels.
    let columns = band_width(ctx.families.len());
    let mut panels = Vec::new();
    for (classes, errors) in class_panels
        .chunks(columns)
        .zip(error_panels.chunks(columns))
    {
        panels.extend_from_slice(classes);
        panels.extend_from_slice(errors);
    }
    Chart {
        title: title.into(),
        columns,
        panels,
    }
}

/// How many families share a band of the chart (their class panels above their error
/// panels): a width that divides their count, so that every band is full and a class
/// panel never sits beside another family's error panel; three for the whole study.
fn band_width(families: usize) -> usize {
    match families {
        n if n % 3 == 0 => 3,
        n if n % 2 == 0 => 2,
        n => n.max(1),
    }
}

/// The runs as a Markdown table (readable in a terminal, pasted as is into docs/).
fn print_runs(runs: &[StabilityRun], baseline: &Judged, group: &str) {
    println!("| family | size | wall s | classes right | as baseline | param | image | input warnings | changed classes |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for r in runs {
        let s = r.judged.summary();
        let same = same_class(&r.judged, baseline);
        let mut notes: Vec<String> = r
            .judged
            .groups
            .iter()
            .zip(&same)
            .filter(|(_, &s)| !s)
            .map(|(g, _)| format!("{} {}", g.group, g.model.as_deref().unwrap_or("none")))
            .collect();
        if r.family == Family::Pixels {
            if let Some(g) = r.judged.group(group) {
                notes.insert(
                    0,
                    format!(
                        "({group}: {}, param {})",
                        g.model.as_deref().unwrap_or("none"),
                        pct(g.param_err())
                    ),
                );
            }
        }
        println!(
            "| {} | {} | {:.1} | {}/{} | {}/{} | {} | {} | {} | {} |",
            r.family.name(),
            r.size,
            r.judged.seconds,
            s.classes_right,
            s.groups,
            same.iter().filter(|&&x| x).count(),
            same.len(),
            pct(s.param_err),
            pct(s.image_err),
            new_input_warnings(&r.judged, baseline).len(),
            notes.join(", ")
        );
    }
}

/// The groups whose class differs from the baseline in any run of `family` with
/// `|size| <= limit`, each said to turn to or from its true class where it does (a weak
/// lobe at the 1% rule turns either way: glossy's white sphere, diffuse on the baseline,
/// is found under an exposure error); `None` when no such run was made.
pub fn class_changes(
    runs: &[StabilityRun],
    baseline: &Judged,
    family: Family,
    limit: f64,
) -> Option<Vec<String>> {
    let chosen: Vec<&StabilityRun> = runs
        .iter()
        .filter(|r| r.family == family && r.size.abs() <= limit)
        .collect();
    if chosen.is_empty() {
        return None;
    }
    let mut changed = Vec::new();
    for r in chosen {
        for (g, same) in r.judged.groups.iter().zip(same_class(&r.judged, baseline)) {
            if same {
                continue;
            }
            let was_right = baseline.group(&g.group).is_some_and(|b| b.class_ok);
            let turn = match (was_right, g.class_ok) {
                (false, true) => " (to its true class)",
                (true, false) => " (from its true class)",
                _ => "",
            };
            changed.push(format!("{} at {}{turn}", g.group, r.size));
        }
    }
    Some(changed)
}

/// The mildest perturbation of `family` under which some class differs from the
/// baseline's, and how many groups changed there (`None`: no run of it changed a class).
fn first_class_change(
    runs: &[StabilityRun],
    baseline: &Judged,
    family: Family,
) -> Option<(f64, usize)> {
    runs.iter()
        .filter(|r| r.family == family)
        .map(|r| {
            let changed = same_class(&r.judged, baseline)
                .iter()
                .filter(|&&same| !same)
                .count();
            (r.size, changed)
        })
        .filter(|&(_, n)| n > 0)
        .min_by(|a, b| family.severity(a.0).total_cmp(&family.severity(b.0)))
}

/// Where `family`'s perturbations first change a class; "not run" where none of its sizes
/// applied (views of 16 px have no smaller resolution that divides them), which read "no
/// class changes in the tested range" although nothing was tested.
fn family_verdict(
    runs: &[StabilityRun],
    baseline: &Judged,
    family: Family,
    families: &[Family],
) -> String {
    if !families.contains(&family) {
        return format!("{}: not run (not among --families)", family.name());
    }
    if !runs.iter().any(|r| r.family == family) {
        return format!(
            "{}: not run (none of its perturbations applies to this scene)",
            family.name()
        );
    }
    match first_class_change(runs, baseline, family) {
        Some((size, n)) => format!(
            "{}: classes first change at {} ({} group(s))",
            family.name(),
            size,
            n
        ),
        None => format!("{}: no class changes in the tested range", family.name()),
    }
}

/// Classes right against the truth over all runs, and per family run: the studies'
/// headline count, which docs/stability.md once summed by hand.
fn classes_right_line(runs: &[StabilityRun]) -> String {
    let (right, all) = classes_right(runs.iter());
    let per_family: Vec<String> = Family::ALL
        .into_iter()
        .filter(|&f| runs.iter().any(|r| r.family == f))
        .map(|f| {
            let (right, all) = classes_right(runs.iter().filter(|r| r.family == f));
            format!("{} {right}/{all}", f.name())
        })
        .collect();
    format!(
        "classes right over all {} runs: {right}/{all} ({})",
        runs.len(),
        per_family.join(", ")
    )
}

/// The classes right, and the groups judged, over `runs`.
fn classes_right<'a>(runs: impl Iterator<Item = &'a StabilityRun>) -> (usize, usize) {
    runs.map(|r| r.judged.summary())
        .fold((0, 0), |(right, all), s| {
            (right + s.classes_right, all + s.groups)
        })
}

fn print_verdict(runs: &[StabilityRun], baseline: &Judged, spread: &[Spread], families: &[Family]) {
    println!();
    println!("{}", classes_right_line(runs));
    let worst = spread
        .iter()
        .filter_map(|s| Some((s.rel_std?, s)))
        .max_by(|a, b| a.0.total_cmp(&b.0));
    let over: Vec<String> = spread
        .iter()
        .filter(|s| s.rel_std.is_some_and(|r| r > SEED_SPREAD_TARGET))
        .map(|s| format!("{}.{}", s.group, s.parameter))
        .collect();
    let flips = class_flips(runs);
    match worst {
        Some((w, s)) => println!(
            "target seed spread <= {}: {} (largest {} on {}.{}; {} of {} parameters above; classes varying over seeds: {})",
            pct(Some(SEED_SPREAD_TARGET)),
            if over.is_empty() && flips.is_empty() { "MET" } else { "MISSED" },
            pct(Some(w)),
            s.group,
            s.parameter,
            over.len(),
            spread.len(),
            if flips.is_empty() { "none".into() } else { flips.join(", ") }
        ),
        None => println!("target seed spread: not measured (fewer than two seeds)"),
    }
    let kinds: Vec<String> = spread_by_kind(spread)
        .into_iter()
        .map(|k| {
            format!(
                "{} largest {} ({} of {} above)",
                k.kind,
                pct(Some(k.largest)),
                k.above,
                k.parameters
            )
        })
        .collect();
    if !kinds.is_empty() {
        println!("  seed spread by kind: {}", kinds.join("; "));
    }
    for (family, limit, what) in [
        (
            Family::Noise,
            NOISE_TARGET,
            "classes unchanged under 1% noise",
        ),
        (
            Family::Exposure,
            EXPOSURE_TARGET,
            "classes unchanged under 5% exposure error",
        ),
    ] {
        match class_changes(runs, baseline, family, limit) {
            Some(c) if c.is_empty() => println!("target {what}: MET"),
            Some(c) => println!("target {what}: MISSED ({})", c.join(", ")),
            None => println!("target {what}: not measured"),
        }
    }
    for family in Family::ALL {
        println!("{}", family_verdict(runs, baseline, family, families));
    }
    // Whether a user would have been told: the runs whose report warned of its input (the
    // pixel family's input is whole; its warnings are the limited group's own).
    for family in Family::ALL
        .into_iter()
        .filter(|f| ![Family::Seed, Family::Pixels].contains(f))
    {
        let of_family: Vec<&StabilityRun> = runs.iter().filter(|r| r.family == family).collect();
        if of_family.is_empty() {
            continue;
        }
        let warned: Vec<String> = of_family
            .iter()
            .filter(|r| !new_input_warnings(&r.judged, baseline).is_empty())
            .map(|r| r.size.to_string())
            .collect();
        println!(
            "{}: the report warned of its input in {} of {} runs{}",
            family.name(),
            warned.len(),
            of_family.len(),
            match warned.is_empty() {
                true => String::new(),
                false => format!(" (at {})", warned.join(", ")),
            }
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn material(group: &str, model: Model, color: f32, s: f32) -> MaterialDesc {
        let mut m = MaterialDesc::new(group, model);
        m.color = Some([color, color, 2.0 * color]);
        if model == Model::Isotropic {
            m.specularity = Some(s);
            m.roughness = Some(0.1);
        }
        m
    }

    fn outcome(group: &str, m: MaterialDesc, pixels: u32) -> GroupOutcome {
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

    fn seed_run(seed: u64, groups: Vec<GroupOutcome>) -> StabilityRun {
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
    fn cornell_study(seed: u64, quick: bool, families: Vec<Family>) -> StabilityArgs {
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

    #[test]
    fn spread_is_the_sample_deviation_relative_to_the_mean() {
        let (mean, std, rel) = spread_of(&[1.0, 2.0, 3.0]).unwrap();
        assert_eq!((mean, std), (2.0, 1.0));
        assert_eq!(rel, Some(0.5));
        assert_eq!(spread_of(&[1.0]), None);
        assert_eq!(spread_of(&[0.0, 0.0]).unwrap().2, None);
    }

    #[test]
    fn seed_spread_uses_the_common_model_and_counts_the_others() {
        let runs: Vec<StabilityRun> = [0.5f32, 0.51, 0.49]
            .iter()
            .enumerate()
            .map(|(i, &c)| {
                let model = if i == 2 {
                    Model::Diffuse
                } else {
                    Model::Isotropic
                };
                seed_run(
                    i as u64,
                    vec![
                        outcome("a", material("a", Model::Diffuse, c, 0.0), 100),
                        outcome("b", material("b", model, c, 0.1 + 0.01 * i as f32), 50),
                    ],
                )
            })
            .collect();
        let truth = [material("a", Model::Diffuse, 0.5, 0.0)];
        let spread = seed_spread(&runs, &truth);
        let a_r = spread
            .iter()
            .find(|s| s.group == "a" && s.parameter == "color_r")
            .unwrap();
        assert_eq!((a_r.seeds_with_model, a_r.seeds), (3, 3));
        assert_eq!(a_r.truth, Some(0.5));
        assert!((a_r.rel_std.unwrap() - 0.01 / 0.5).abs() < 1e-6);
        // Diffuse "a" has no specularity to spread; "b" is isotropic in 2 of 3 seeds.
        assert!(!spread
            .iter()
            .any(|s| s.group == "a" && s.parameter == "specularity"));
        let b_s = spread
            .iter()
            .find(|s| s.group == "b" && s.parameter == "specularity")
            .unwrap();
        assert_eq!((b_s.model.as_str(), b_s.seeds_with_model), ("isotropic", 2));
        assert!((b_s.mean - 0.105).abs() < 1e-6);
    }

    /// A group whose common model has no parameter to spread still counts as varying: the
    /// living room's picture_3, textured-diffuse on 9 seeds of 10 at 256 px and
    /// textured-anisotropic on one, was not named (2026-12-06).
    #[test]
    fn a_class_that_varies_over_seeds_is_named_whatever_its_parameters() {
        let picture = |model: Model| {
            let mut m = MaterialDesc::new("p", model);
            if model == Model::TexturedAnisotropic {
                m.specularity = Some(0.05);
                m.roughness_u = Some(0.05);
                m.roughness_v = Some(0.1);
            }
            outcome("p", m, 50)
        };
        let runs: Vec<StabilityRun> = [
            Model::TexturedDiffuse,
            Model::TexturedAnisotropic,
            Model::TexturedDiffuse,
        ]
        .into_iter()
        .enumerate()
        .map(|(i, m)| seed_run(i as u64, vec![picture(m)]))
        .collect();
        assert!(seed_spread(&runs, &[]).is_empty());
        assert_eq!(class_flips(&runs), ["p (textured-diffuse in 2/3)"]);
        assert!(class_flips(&runs[..1]).is_empty());
    }

    /// A textured or anisotropic lobe's parameters spread too: the textured study's seed
    /// spread held the diffuse groups' colours alone, not the checker's lobe (2026-12-01).
    #[test]
    fn seed_spread_covers_anisotropic_and_textured_lobes() {
        let lobe = |model: Model, s: f32| {
            let mut m = MaterialDesc::new("p", model);
            m.specularity = Some(s);
            m.roughness_u = Some(0.05);
            m.roughness_v = Some(2.0 * s);
            m
        };
        let runs: Vec<StabilityRun> = [0.06f32, 0.07]
            .iter()
            .enumerate()
            .map(|(i, &s)| {
                let picture = outcome("p", lobe(Model::TexturedAnisotropic, s), 50);
                seed_run(i as u64, vec![picture])
            })
            .collect();
        let spread = seed_spread(&runs, &[lobe(Model::TexturedAnisotropic, 0.06)]);
        let names: Vec<&str> = spread.iter().map(|s| s.parameter).collect();
        assert_eq!(names, ["specularity", "roughness_u", "roughness_v"]);
        let v = spread
            .iter()
            .find(|s| s.parameter == "roughness_v")
            .unwrap();
        assert_eq!(v.truth, Some(f64::from(0.12f32)));
        assert!((v.mean - 0.13).abs() < 1e-6, "{v:?}");
    }

    /// Fewer pixels are the harsher perturbation: the glossy study's 32-px run changed
    /// two classes and its 16-px run two others, and the verdict named 16 (2026-12-01).
    #[test]
    fn the_first_class_change_is_the_mildest_perturbation_that_changes_one() {
        let base = seed_run(
            0,
            vec![outcome("a", material("a", Model::Diffuse, 0.5, 0.0), 10)],
        );
        let run = |family: Family, size: f64, model: Model| StabilityRun {
            family,
            size,
            ..seed_run(0, vec![outcome("a", material("a", model, 0.5, 0.1), 10)])
        };
        let runs = vec![
            base.clone(),
            run(Family::Resolution, 16.0, Model::Isotropic),
            run(Family::Resolution, 32.0, Model::Isotropic),
            run(Family::Resolution, 128.0, Model::Diffuse),
            run(Family::Pixels, 1024.0, Model::Diffuse),
            run(Family::Pixels, 16.0, Model::Isotropic),
            run(Family::Pixels, 64.0, Model::Isotropic),
            run(Family::Exposure, -2.0, Model::Diffuse),
            run(Family::Exposure, 10.0, Model::Isotropic),
            run(Family::Exposure, -5.0, Model::Isotropic),
        ];
        let first = |f| first_class_change(&runs, &base.judged, f);
        assert_eq!(first(Family::Resolution), Some((32.0, 1)));
        assert_eq!(first(Family::Pixels), Some((64.0, 1)));
        assert_eq!(first(Family::Exposure), Some((-5.0, 1)));
        assert_eq!(first(Family::Noise), None);
        // Noise was not run at all: not "no class changes".
        let verdict = |f| family_verdict(&runs, &base.judged, f, &Family::ALL);
        assert_eq!(
            verdict(Family::Noise),
            "noise: not run (none of its perturbations applies to this scene)"
        );
        assert!(verdict(Family::Resolution).contains("first change at 32"));
        let unchanged = vec![base.clone(), run(Family::Noise, 1.0, Model::Diffuse)];
        assert_eq!(
            family_verdict(&unchanged, &base.judged, Family::Noise, &Family::ALL),
            "noise: no class changes in the tested range"
        );
    }

    #[test]
    fn classes_right_are_counted_over_all_runs_and_per_family() {
        // Each group's truth is diffuse: a run's isotropic groups are wrong.
        let judged = |model: Model| GroupOutcome {
            class_ok: model == Model::Diffuse,
            ..outcome("a", material("a", model, 0.5, 0.1), 10)
        };
        let run = |family: Family, size: f64, models: [Model; 2]| StabilityRun {
            family,
            size,
            ..seed_run(0, models.into_iter().map(judged).collect())
        };
        let runs = vec![
            run(Family::Seed, 1.0, [Model::Diffuse, Model::Isotropic]),
            run(Family::Seed, 2.0, [Model::Isotropic, Model::Isotropic]),
            run(Family::Noise, 1.0, [Model::Diffuse, Model::Diffuse]),
        ];
        assert_eq!(
            classes_right_line(&runs),
            "classes right over all 3 runs: 3/6 (seed 1/4, noise 2/2)"
        );
    }

    #[test]
    fn class_changes_are_found_within_the_limit_only() {
        let base = seed_run(
            0,
            vec![outcome("a", material("a", Model::Diffuse, 0.5, 0.0), 10)],
        );
        let flipped = |size: f64, model: Model| StabilityRun {
            family: Family::Exposure,
            size,
            ..seed_run(0, vec![outcome("a", material("a", model, 0.5, 0.1), 10)])
        };
        let runs = vec![
            base.clone(),
            flipped(-2.0, Model::Diffuse),
            flipped(10.0, Model::Isotropic),
        ];
        assert_eq!(
            class_changes(&runs, &base.judged, Family::Exposure, 5.0),
            Some(vec![])
        );
        assert_eq!(
            class_changes(&runs, &base.judged, Family::Exposure, 10.0),
            Some(vec!["a at 10".to_string()])
        );
        assert_eq!(class_changes(&runs, &base.judged, Family::Noise, 1.0), None);
    }

    /// A change is told to turn to or from the group's true class: the target counts both,
    /// and a reader weighs them differently.
    #[test]
    fn class_changes_say_whether_they_turn_to_or_from_the_true_class() {
        let judged = |model: Model, class_ok: bool| GroupOutcome {
            class_ok,
            ..outcome("a", material("a", model, 0.5, 0.1), 10)
        };
        let run = |size: f64, model: Model, class_ok: bool| StabilityRun {
            family: Family::Exposure,
            size,
            ..seed_run(0, vec![judged(model, class_ok)])
        };
        let changes = |base_right: bool, run_right: bool| {
            let base = run(0.0, Model::Diffuse, base_right);
            let runs = vec![base.clone(), run(5.0, Model::Isotropic, run_right)];
            class_changes(&runs, &base.judged, Family::Exposure, 5.0).unwrap()
        };
        assert_eq!(changes(false, true), ["a at 5 (to its true class)"]);
        assert_eq!(changes(true, false), ["a at 5 (from its true class)"]);
        assert_eq!(changes(false, false), ["a at 5"]);
    }

    #[test]
    fn input_warnings_are_those_the_baseline_lacks_leaving_out_groups() {
        let judged = |warnings: &[&str]| Judged {
            seconds: 1.0,
            cpu_seconds: None,
            groups: Vec::new(),
            warnings: warnings.iter().map(|w| w.to_string()).collect(),
        };
        let baseline = judged(&["8 samples per pixel in the loop", "group 'a': weak lobe"]);
        let run = judged(&[
            "light 'lamp' reads 1.050x its declared radiance",
            "8 samples per pixel in the loop",
            "group 'b': borderline",
        ]);
        assert_eq!(
            new_input_warnings(&run, &baseline),
            ["light 'lamp' reads 1.050x its declared radiance"]
        );
        assert!(new_input_warnings(&baseline, &baseline).is_empty());
    }

    #[test]
    fn the_limited_group_is_the_largest_not_diffuse_in_the_truth() {
        let judged = Judged {
            seconds: 1.0,
            cpu_seconds: None,
            groups: vec![
                outcome("floor", material("floor", Model::Diffuse, 0.5, 0.0), 900),
                outcome("ball", material("ball", Model::Diffuse, 0.5, 0.0), 300),
                outcome("cup", material("cup", Model::Diffuse, 0.5, 0.0), 200),
            ],
            warnings: Vec::new(),
        };
        let truth = [
            material("floor", Model::Diffuse, 0.5, 0.0),
            material("ball", Model::Isotropic, 0.5, 0.1),
            material("cup", Model::Mirror, 0.5, 0.0),
        ];
        assert_eq!(limited_group(&judged, &truth), "ball");
        let all_diffuse = [
            material("floor", Model::Diffuse, 0.5, 0.0),
            material("ball", Model::Diffuse, 0.5, 0.0),
            material("cup", Model::Diffuse, 0.5, 0.0),
        ];
        assert_eq!(limited_group(&judged, &all_diffuse), "floor");
    }

    #[test]
    fn the_outputs_checked_before_the_study_cover_every_run_and_perturbed_scene() {
        let args = cornell_study(4, true, Vec::new());
        let desc = scene_file::load_scene(&args.scene).unwrap();
        let files = outputs(&args, &desc);
        for file in [
            "out/runs/seed_4/report.json",
            "out/runs/seed_6/materials.toml",
            "out/runs/noise_1/materials.toml",
            "out/scenes/noise_1/scene.toml",
            "out/scenes/exposure_-5/views/px.exr",
            "out/scenes/resolution_16/scene.toml",
            "out/runs/pixels_16/materials.toml",
            "out/seed-spread.csv",
        ] {
            assert!(files.contains(&PathBuf::from(file)), "{file} not checked");
        }
        // The seed and pixel families recover from the scene itself: no scene of theirs.
        assert!(!files.contains(&PathBuf::from("out/scenes/seed_4/scene.toml")));
        // The run loop walks the same plan; its first point is the baseline, the first seed
        // on the scene itself, which the pixel family's limited group is chosen on.
        let points = plan(&args, &desc);
        let first = &points[0];
        assert_eq!((first.family, first.seed), (Family::Seed, 4));
        assert!(first.perturbation.is_none());
        let last = points.last().unwrap();
        assert_eq!(last.family, Family::Pixels);
        assert_eq!(run_id(Family::Exposure, -5.0, 4), "exposure_-5");
    }

    /// The spread parts by kind: the diffuse groups' colours, the colours under a lobe,
    /// the lobes' parameters.
    #[test]
    fn seed_spread_by_kind_parts_colours_from_lobes() {
        let spread = |group: &str, model: &str, parameter, rel| Spread {
            group: group.into(),
            model: model.into(),
            seeds_with_model: 10,
            seeds: 10,
            parameter,
            truth: None,
            mean: 1.0,
            std: rel,
            rel_std: Some(rel),
        };
        let all = [
            spread("wall", "diffuse", "color_r", 0.001),
            spread("wall", "diffuse", "color_g", 0.002),
            spread("ball", "isotropic", "color_r", 0.01),
            spread("ball", "isotropic", "specularity", 0.2),
            spread("ball", "isotropic", "roughness", 0.004),
        ];
        assert_eq!(
            spread_by_kind(&all),
            [
                KindSpread {
                    kind: "diffuse groups' colours",
                    largest: 0.002,
                    above: 0,
                    parameters: 2
                },
                KindSpread {
                    kind: "colours under a lobe",
                    largest: 0.01,
                    above: 1,
                    parameters: 1
                },
                KindSpread {
                    kind: "lobe parameters",
                    largest: 0.2,
                    above: 1,
                    parameters: 2
                },
            ]
        );
        assert_eq!(spread_by_kind(&all[..2]).len(), 1);
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

    /// Every band of the chart is full: a family's class panel is always above its own
    /// error panel, whatever the number of families.
    #[test]
    fn the_chart_bands_divide_the_families() {
        for n in 1..=Family::ALL.len() {
            let width = band_width(n);
            assert_eq!(n % width, 0, "{n} families in bands of {width}");
            assert!(width <= 5);
        }
        assert_eq!(band_width(Family::ALL.len()), 3);
    }

    /// A resolution point is one box-averaging can make: the first view's width over
    /// `side` divides every view.
    #[test]
    fn a_resolution_point_takes_a_factor_that_divides_every_view() {
        let cornell = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
        let mut desc = scene_file::load_scene(&cornell.join("scene.toml")).unwrap();
        let mut with_sizes = |sizes: [[u32; 2]; 2]| {
            desc.views.truncate(2);
            desc.views[0].size = sizes[0];
            desc.views[1].size = sizes[1];
            [8, 16, 24].map(|side| resolution_applies(&desc, side))
        };
        assert_eq!(with_sizes([[32, 32], [32, 32]]), [true, true, false]);
        // 48 by 3 to 16, which 32 is not a multiple of; by 2 to 24, which it is.
        assert_eq!(with_sizes([[48, 48], [32, 32]]), [false, false, true]);
        assert_eq!(with_sizes([[32, 8], [32, 32]]), [true, true, false]);
    }

    /// A seed family from any first seed: one folder per seed past 2^53, where the seeds'
    /// sizes round to one float (three runs shared runs/seed_1152921504606846976), and no
    /// overflow from u64::MAX (a panic in a debug build).
    #[test]
    fn a_seed_family_from_a_large_seed_has_a_folder_per_seed() {
        let cornell = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
        let desc = scene_file::load_scene(&cornell.join("scene.toml")).unwrap();
        for (first, seeds) in [
            (1u64 << 60, vec![1u64 << 60, (1 << 60) + 1, (1 << 60) + 2]),
            (u64::MAX, vec![u64::MAX, 0, 1]),
        ] {
            let args = cornell_study(first, true, Vec::new());
            let points: Vec<Point> = plan(&args, &desc)
                .into_iter()
                .filter(|p| p.family == Family::Seed)
                .collect();
            assert_eq!(points.iter().map(|p| p.seed).collect::<Vec<_>>(), seeds);
            let ids: std::collections::BTreeSet<String> = points
                .iter()
                .map(|p| run_id(p.family, p.size, p.seed))
                .collect();
            assert_eq!(ids.len(), seeds.len(), "{ids:?}");
            assert!(ids.contains(&format!("seed_{}", seeds[1])), "{ids:?}");
        }
    }
}
