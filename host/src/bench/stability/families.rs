//! The perturbation families of the study and the runs they make: each family's sizes,
//! the plan of every run (the first seed, the baseline, first), each run's folder and the
//! files the study may write, and the group the pixel family limits.

use std::path::PathBuf;

use super::StabilityArgs;
use crate::bench::chart::Axis;
use crate::bench::perturb::Perturbation;
use crate::bench::{derived_scene_outputs, recovery_outputs, GroupOutcome, Judged};
use crate::materials_file::{MaterialDesc, Model};
use crate::scene_file::SceneDesc;

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
    pub(super) fn severity(self, size: f64) -> f64 {
        match self {
            Family::Resolution | Family::Pixels => -size,
            Family::Seed | Family::Noise | Family::Exposure | Family::Light => size.abs(),
        }
    }

    pub(super) fn x_axis(self) -> Axis {
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

/// The folder name of a run (under runs/) and of its perturbed scene (under scenes/). A
/// seed's run is named by the seed itself: past 2^53 its size (a 64-bit float) gives
/// neighbouring seeds one folder.
pub(super) fn run_id(family: Family, size: f64, seed: u64) -> String {
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
pub(super) struct Point {
    pub(super) family: Family,
    pub(super) size: f64,
    pub(super) seed: u64,
    pub(super) perturbation: Option<Perturbation>,
}

/// Every recovery the study may make, in order, the seeds first (the first is the
/// baseline). The pixel family's points are all listed: which of them run depends on the
/// baseline's pixels of the limited group. [`run`](super::run) recovers them and
/// [`outputs`] checks their files before the first, so the two cannot disagree.
pub(super) fn plan(args: &StabilityArgs, desc: &SceneDesc) -> Vec<Point> {
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
pub(super) fn outputs(args: &StabilityArgs, desc: &SceneDesc) -> Vec<PathBuf> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::stability::tests::{cornell_study, material, outcome};
    use crate::scene_file;

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
