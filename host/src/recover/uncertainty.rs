//! The uncertainty of every recovered parameter: a cluster-robust ("sandwich") standard
//! error of the least-squares fit of the group's pure pixels, with pixels clustered in
//! tiles of `TILE` x `TILE` pixels of a view.
//!
//! With `J` the derivative of the rendered pixels by the parameters (finite differences
//! on common random numbers) and `r` the residual `R - T`,
//! `cov = A^-1 M A^-1`, `A = sum_i J_i^T J_i`, `M = sum_tiles g g^T`, `g = sum_{i in tile} J_i^T r_i`.
//! Unlike the textbook `s^2 A^-1`, it does not assume the residuals independent: a misfit
//! that spans a region (a highlight's shape, an interreflection the model gets wrong) moves
//! the estimate as one tile, not as many independent pixels, and the parameters' mutual
//! dependence (a lobe's specularity against its diffuse colour) is in `A^-1`. What it
//! cannot see is an error common to every pixel (the light's radiance, the camera's
//! exposure, our renderer against RADIANCE): the colours carry our renderer's as a floor
//! ([`RENDERER_COMMON_ERROR`]); docs/stability.md measures the input's separately.

use std::time::Instant;

use glam::Vec3;
use relume_core::material::Kind;
use relume_core::render::RenderSettings;
use relume_core::stages::isotropic::WardFit;
use serde::Serialize;

use super::cache::{self, GroupCache};
use super::model::{GroupModel, MapLobe};
use super::report::Laps;
use super::{fit_ward_by, pattern, pixels, Budget, GroupReport, Recovery, StageReport};
use crate::error::Error;

/// Side of the square tiles of pixels that are taken to share their misfit.
pub const TILE: u32 = 8;
/// Relative step of the finite differences, taken downward (a parameter times `1 -
/// STEP`), so that a metal's specularity of 0.95 or a colour of 0.99 stays a reflectance.
/// The two renders share their random numbers, but a perturbation that changes which paths
/// are sampled (a lobe's roughness its sampled directions, a colour Russian roulette's
/// choices) leaves their difference noisy, and the noise inflates `A = sum J^T J`, which
/// shrinks the standard errors. Measured on glossy at 64 px (`A`'s diagonal from two
/// independent derivative renders, `sum J_a J_b`, over the one from a single one): at a
/// step of 5% the spheres' roughness kept 0.41-0.85 of it and metal_steel's colour 0.82;
/// at 20%, 0.94-0.99 and 0.95 (docs/stability.md, "A larger step").
const STEP: f64 = 0.2;
/// Each render of a group takes at least this many pixel samples (more per pixel for a
/// small group). The derivatives are differences of two renders, and their noise adds to
/// `A = sum J^T J`: at 16 samples per pixel glossy's metal_steel (387 pixels) claimed a
/// roughness sigma of 0.0001 on one seed and 0.0045 on another.
const MIN_SAMPLES: u64 = 1 << 17;
/// A group seen in more tiles is measured on this many of them, whole and spread evenly,
/// and its variances scaled by the share kept (the sandwich's sums are over tiles, so a
/// share of the tiles estimates them; `pixels::whole_tiles`). 256 clusters fix a standard
/// error to a few percent, and groups of 100,000 pixels at 256 px per face rendered 1,700
/// tiles five times over: the stage took 30% of box-diffuse's recovery there. Stage 5
/// decides a picture's lobe on this sigma too (`stage5::run`), so a picture in more tiles
/// is decided on the subset's; no reference picture is (the largest, textured's checker,
/// 4,500 pixels at 256 px: the same bytes).
pub const MAX_TILES: usize = 256;

/// One recovered parameter with its standard error.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct ParameterUncertainty {
    /// The name of the field in materials.toml (`color` is given per channel).
    pub parameter: String,
    pub value: f64,
    pub sigma: f64,
}

/// A perturbation of the model, and the parameters whose derivative it gives.
enum Perturbation {
    /// All colour channels scaled together: rendering is channel by channel, so channel
    /// `c` of the change is the derivative by `color[c]` alone.
    Colour([f64; 3]),
    Scalar(&'static str, f64),
}

fn perturbations(model: &GroupModel) -> Vec<Perturbation> {
    use Perturbation::*;
    match *model {
        GroupModel::Diffuse { color } | GroupModel::Mirror { color } => vec![Colour(color)],
        GroupModel::Isotropic {
            color,
            specularity,
            roughness,
            ..
        } => vec![
            Colour(color),
            Scalar("specularity", specularity),
            Scalar("roughness", roughness),
        ],
        GroupModel::Anisotropic {
            color,
            specularity,
            roughness_u,
            roughness_v,
            ..
        } => vec![
            Colour(color),
            Scalar("specularity", specularity),
            Scalar("roughness_u", roughness_u),
            Scalar("roughness_v", roughness_v),
        ],
        // The lobe's parameters; the colour is the map's.
        GroupModel::Textured { lobe, .. } => perturbations(&lobe.white())
            .into_iter()
            .filter(|p| !matches!(p, Colour(_)))
            .collect(),
        GroupModel::Unseen { .. } => Vec::new(),
    }
}

/// `model` with the parameter(s) of `perturbation` scaled by `1 - STEP`.
fn perturbed(model: GroupModel, perturbation: &Perturbation) -> GroupModel {
    if let GroupModel::Textured { map, lobe } = model {
        let stand_in = perturbed(lobe.white(), perturbation);
        return GroupModel::Textured {
            map,
            lobe: MapLobe::of_stand_in(&stand_in),
        };
    }
    let down = 1.0 - STEP;
    let mut m = model;
    match (perturbation, &mut m) {
        (
            Perturbation::Colour(_),
            GroupModel::Diffuse { color }
            | GroupModel::Mirror { color }
            | GroupModel::Isotropic { color, .. }
            | GroupModel::Anisotropic { color, .. },
        ) => *color = color.map(|c| c * down),
        (
            Perturbation::Scalar("specularity", _),
            GroupModel::Isotropic { specularity, .. } | GroupModel::Anisotropic { specularity, .. },
        ) => *specularity *= down,
        (Perturbation::Scalar("roughness", _), GroupModel::Isotropic { roughness, .. }) => {
            *roughness *= down
        }
        (Perturbation::Scalar("roughness_u", _), GroupModel::Anisotropic { roughness_u, .. }) => {
            *roughness_u *= down
        }
        (Perturbation::Scalar("roughness_v", _), GroupModel::Anisotropic { roughness_v, .. }) => {
            *roughness_v *= down
        }
        _ => {}
    }
    m
}

/// How many samples the estimates of a group's parameters saw.
#[derive(Clone, Copy, Debug)]
pub struct EstimateSamples {
    /// Pixel samples in all of the render whose mean set the colour: the colour polish's
    /// or the diffuse refinement's (`GroupReport::colour_samples`), or the loop's over
    /// every pure pixel where neither set it.
    pub colour_samples: u64,
    /// Pixel samples in all of the transport cache that the lobe's shape and
    /// specularity are fitted on (`Recovery::cache_samples`).
    pub lobe_samples: u64,
}

/// The error common to every pixel of a group that our renderer makes against an
/// independent physically based renderer, relative: the RMS over the four references'
/// diffuse groups of the per-group mean difference against RADIANCE
/// (docs/renderer-vs-radiance.md; the ceilings read 0.4-0.55% low). No statistic of our
/// own renders sees it, and a colour set by matching a group's mean radiance takes it
/// whole (box-diffuse's ceiling 0.25-0.36% high at 64 px, over seeds), so it is a floor on
/// every colour's relative standard error. A real capture adds its own calibration
/// error, which the report cannot know (docs/stability.md, exposure and light radiance).
pub const RENDERER_COMMON_ERROR: f64 = 0.0024;

/// The standard errors of group `g`'s parameters under its current model, from renders of
/// its pure pixels at `spp` samples (at least [`MIN_SAMPLES`] in all) on `seed` (the same
/// samples for every perturbation), in at most [`MAX_TILES`] of its tiles.
///
/// Every parameter also carries the Monte Carlo noise of its own estimate, which the
/// misfit does not show, measured from two independent half-renders and added in
/// quadrature:
/// - the colours: the noise of a render's mean at `samples.colour_samples`;
/// - a lobe's specularity and roughnesses: they are the least-squares fit to the group's
///   transport cache, whose pixels carry `samples.lobe_samples` samples in all; the noise
///   moves the fit by `A^-1 sum J^T e`. Without it glossy's metal_steel, whose highlight
///   pins the roughness to 0.0001 in the misfit, claimed 60 sigma less than its seeds vary.
///
/// A lobe's error from outside the misfit (that noise, and `lobe_sigmas`: the ladder's or
/// the cache size's spread) is carried into its colour too: the colour is a ratio step
/// under the lobe, so it moves by `dc/dθ = -(sum dR/dθ) / (sum dR/dc)` per channel (glossy's
/// metal_gold is 3.0% low in colour and 2.7% in specularity). Last, each colour carries
/// the [`RENDERER_COMMON_ERROR`] floor.
pub fn parameter_uncertainty(
    rec: &mut Recovery,
    g: usize,
    spp: u32,
    samples: EstimateSamples,
    lobe_sigmas: &[(&str, f64)],
    seed: u64,
) -> Result<Vec<ParameterUncertainty>, Error> {
    let model = rec.models[g];
    let steps = perturbations(&model);
    let all_pixels = pixels::of_group(&rec.pure, g);
    let n = all_pixels.len() as f64;
    let (group_pixels, share) = pixels::whole_tiles(all_pixels, TILE, MAX_TILES);
    if steps.is_empty() || group_pixels.len() < 2 {
        return Ok(Vec::new());
    }
    let spp = super::min_samples_spp(spp, group_pixels.len() as u32, MIN_SAMPLES);
    let half_spp = (spp / 2).max(1);
    let render = |rec: &mut Recovery, m: GroupModel, seed: u64| {
        rec.models[g] = m;
        rec.with_scene(half_spp, seed, |pool, scene, observed, settings| {
            pixels::render_pixels(pool, scene, observed.views, &group_pixels, settings)
        })
    };
    let first = render(rec, model, seed);
    let second = render(rec, model, seed ^ 0x2D_2D2D);
    let changed: Result<Vec<Vec<Vec3>>, Error> = steps
        .iter()
        .map(|p| render(rec, perturbed(model, p), seed))
        .collect();
    rec.models[g] = model;
    let (first, second, changed) = (first?, second?, changed?);
    let base: Vec<Vec3> = first
        .iter()
        .zip(&second)
        .map(|(a, b)| 0.5 * (*a + *b))
        .collect();
    // Noise of the group's mean radiance per channel at the colour's samples, relative:
    // the mean over all `n` pixels of `half_spp` samples has the variance `half_variance /
    // sum^2`; over `colour_samples` samples, `n half_spp / colour_samples` times that. Over
    // a `share` of the tiles both sums are `share` times the whole's.
    let colour_noise: [f64; 3] = std::array::from_fn(|c| {
        let half_variance: f64 = first
            .iter()
            .zip(&second)
            .map(|(a, b)| {
                let d = (a[c] - b[c]) as f64;
                0.5 * d * d
            })
            .sum();
        let sum: f64 = base.iter().map(|v| v[c] as f64).sum();
        let variance = half_variance * n * half_spp as f64 / samples.colour_samples.max(1) as f64;
        if sum > 0.0 {
            (variance * share).sqrt() / sum
        } else {
            0.0
        }
    });

    // Parameter names and values, and per pixel the derivative (per unit of the
    // parameter) of the pixel's RGB by each.
    let mut names = Vec::new();
    let mut values = Vec::new();
    for p in &steps {
        match p {
            Perturbation::Colour(c) => {
                for (ch, name) in ["color_r", "color_g", "color_b"].into_iter().enumerate() {
                    names.push(name.to_string());
                    values.push(c[ch]);
                }
            }
            Perturbation::Scalar(name, v) => {
                names.push(name.to_string());
                values.push(*v);
            }
        }
    }
    let n_params = names.len();
    let jacobian = |i: usize| -> Vec<Vec3> {
        let mut columns = Vec::with_capacity(n_params);
        for (p, after) in steps.iter().zip(&changed) {
            // Against the render on the same samples: common random numbers.
            let delta = after[i] - first[i];
            match p {
                Perturbation::Colour(c) => {
                    for ch in 0..3 {
                        let mut column = Vec3::ZERO;
                        // The step is downward: a change of -STEP c.
                        let h = (STEP * c[ch]) as f32;
                        if h > 0.0 {
                            column[ch] = -delta[ch] / h;
                        }
                        columns.push(column);
                    }
                }
                Perturbation::Scalar(_, v) => {
                    let h = (STEP * v) as f32;
                    columns.push(if h > 0.0 { -delta / h } else { Vec3::ZERO });
                }
            }
        }
        columns
    };

    // A pixel's noise at the lobe's estimate: one draw of the half-renders' difference,
    // (a - b) / sqrt 2 at `half_spp`, scaled to the samples per pixel the cache had.
    let lobe_spp = samples.lobe_samples as f64 / n;
    let noise_scale = (half_spp as f64 / (2.0 * lobe_spp.max(1.0))).sqrt() as f32;
    let mut normal = vec![vec![0.0f64; n_params]; n_params];
    let mut tiles: std::collections::BTreeMap<(u32, u32, u32), Vec<f64>> = Default::default();
    let mut noise_scores = Vec::with_capacity(group_pixels.len());
    // Per parameter, the derivative of the group's summed RGB.
    let mut summed_jacobian = vec![Vec3::ZERO; n_params];
    for (i, p) in group_pixels.iter().enumerate() {
        let j = jacobian(i);
        for (sum, jk) in summed_jacobian.iter_mut().zip(&j) {
            *sum += *jk;
        }
        let residual = base[i] - pixels::real_value(&rec.real, &rec.views, p);
        let noise = (first[i] - second[i]) * noise_scale;
        let score = tiles
            .entry((p.view, p.x / TILE, p.y / TILE))
            .or_insert_with(|| vec![0.0; n_params]);
        for k in 0..n_params {
            score[k] += j[k].dot(residual) as f64;
            for l in 0..n_params {
                normal[k][l] += j[k].dot(j[l]) as f64;
            }
        }
        noise_scores.push(j.iter().map(|jk| jk.dot(noise) as f64).collect::<Vec<_>>());
    }
    let Some(inverse) = invert(&normal) else {
        return Ok(Vec::new());
    };
    let colour_channel = |name: &str| {
        ["color_r", "color_g", "color_b"]
            .iter()
            .position(|c| *c == name)
    };
    // Each lobe parameter's standard error from outside the misfit: its estimate's noise
    // (pixels' noise is independent: summed over pixels, not tiles) and `lobe_sigmas`.
    let outside_misfit: Vec<f64> = (0..n_params)
        .map(|k| {
            if colour_channel(&names[k]).is_some() {
                return 0.0;
            }
            let noise = (share * projected_sum_of_squares(&inverse, k, &noise_scores)).sqrt();
            lobe_sigmas
                .iter()
                .filter(|(name, _)| *name == names[k])
                .fold(noise, |s, (_, extra)| libm::hypot(s, *extra))
        })
        .collect();
    Ok((0..n_params)
        .map(|k| {
            // (A^-1 M A^-1)_kk = sum_tiles ((A^-1 g)_k)^2; over a `share` of the tiles,
            // A and M are `share` times the whole's, and so this `1 / share` times.
            let misfit = share * projected_sum_of_squares(&inverse, k, tiles.values());
            let outside = match colour_channel(&names[k]) {
                Some(c) => {
                    let noise = values[k] * colour_noise[c];
                    let by_colour = summed_jacobian[k][c] as f64;
                    let lobe: f64 = (0..n_params)
                        .filter(|&l| outside_misfit[l] > 0.0 && by_colour != 0.0)
                        .map(|l| {
                            let moved =
                                summed_jacobian[l][c] as f64 / by_colour * outside_misfit[l];
                            moved * moved
                        })
                        .sum();
                    let floor = values[k] * RENDERER_COMMON_ERROR;
                    noise * noise + lobe + floor * floor
                }
                None => outside_misfit[k] * outside_misfit[k],
            };
            ParameterUncertainty {
                parameter: names[k].clone(),
                value: values[k],
                sigma: (misfit + outside).sqrt(),
            }
        })
        .collect())
}

/// How far the cache's proposal for a lobe of `kind` (`specularity`, `roughness`: the fit
/// of the whole `cache`) moves with the cache's size, as standard errors of the two: the
/// jackknife's estimate of its bias, the mean of the same fit on each half of every
/// pixel's samples less the whole's (a bias that falls as one over the samples is twice
/// as large in a half; docs/recovery.md, "The cache's proposal depends on the cache's
/// size"). Not corrected for, since the correction overshoots the truth where the
/// surroundings stage 1 left bias the cache the other way (glossy's steel box, 0.156
/// against 0.14), but claimed: the sandwich sees only the pixels' pull at the point
/// chosen, and the steel box's proposal spread 15% over seeds with a sigma of 1.5%.
pub fn proposal_size_dependence(
    pool: &rayon::ThreadPool,
    cache: &GroupCache,
    kind: Kind,
    specularity: f64,
    roughness: f64,
) -> [(&'static str, f64); 2] {
    let halves = [0, 1].map(|half| {
        fit_ward_by(|alpha| cache::isotropic_fit_of_half(pool, cache, kind, alpha, half))
    });
    let mean = |f: fn(&(WardFit, f64, u32)) -> f64| (f(&halves[0]) + f(&halves[1])) / 2.0;
    [
        (
            "specularity",
            (mean(|h| h.0.specularity) - specularity).abs(),
        ),
        ("roughness", (mean(|h| h.1) - roughness).abs()),
    ]
}

/// `sum_s ((A^-1 s)_k)^2` over the score vectors `s`: parameter `k`'s variance when
/// the scores are independent.
fn projected_sum_of_squares<'a>(
    inverse: &[Vec<f64>],
    k: usize,
    scores: impl IntoIterator<Item = &'a Vec<f64>>,
) -> f64 {
    scores
        .into_iter()
        .map(|s| {
            let projected: f64 = inverse[k].iter().zip(s).map(|(a, b)| a * b).sum();
            projected * projected
        })
        .sum()
}

/// The inverse of a small matrix by Gauss-Jordan elimination with partial pivoting; `None`
/// when it is singular (for the sandwich's normal matrix: a parameter the pixels do not
/// see).
pub(super) fn invert(a: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let n = a.len();
    let scale = (0..n).map(|i| a[i][i].abs()).fold(0.0, f64::max);
    if !scale.is_finite() || scale <= 0.0 {
        return None;
    }
    let mut m: Vec<Vec<f64>> = a
        .iter()
        .enumerate()
        .map(|(i, row)| {
            let mut r = row.clone();
            r.extend((0..n).map(|j| if i == j { 1.0 } else { 0.0 }));
            r
        })
        .collect();
    for col in 0..n {
        let pivot = (col..n).max_by(|&x, &y| m[x][col].abs().total_cmp(&m[y][col].abs()))?;
        if m[pivot][col].abs() <= 1e-12 * scale {
            return None;
        }
        m.swap(col, pivot);
        let p = m[col][col];
        m[col].iter_mut().for_each(|v| *v /= p);
        for row in 0..n {
            if row != col {
                let f = m[row][col];
                if f != 0.0 {
                    let pivot_row = m[col].clone();
                    m[row]
                        .iter_mut()
                        .zip(&pivot_row)
                        .for_each(|(v, pv)| *v -= f * pv);
                }
            }
        }
    }
    Some(m.into_iter().map(|r| r[n..].to_vec()).collect())
}

/// Samples per pixel of the renders the standard errors come from: 4x the loop's.
fn uncertainty_spp(budget: &Budget) -> u32 {
    4 * budget.loop_spp
}

/// Group `g`'s parameters under its current model with their standard errors (`report`
/// gives the samples its colour and lobe were set from, and stage 2's extra spread).
pub(super) fn group_uncertainty(
    rec: &mut Recovery,
    g: usize,
    report: &GroupReport,
    budget: &Budget,
    cache_settings: &RenderSettings,
    seed: u64,
) -> Result<Vec<ParameterUncertainty>, Error> {
    let samples = EstimateSamples {
        colour_samples: report
            .colour_samples
            .unwrap_or(budget.loop_spp as u64 * report.pure_pixels as u64),
        lobe_samples: rec.cache_samples(g, cache_settings.spp),
    };
    // Stage 2's lobe carries what its fit's own spread adds: the ladder's rungs it could
    // not tell apart, or the cache proposal's dependence on the cache's size.
    let lobe_sigmas: &[(&str, f64)] = match rec.models[g] {
        GroupModel::Isotropic { .. } => &report.lobe_sigmas,
        _ => &[],
    };
    let mut uncertainty = parameter_uncertainty(
        rec,
        g,
        uncertainty_spp(budget),
        samples,
        lobe_sigmas,
        seed ^ 0x5160,
    )?;
    // A textured group's lobe also carries the picture's share (`pattern::lobe_spread`).
    if let GroupModel::Textured { lobe, .. } = rec.models[g] {
        if lobe.specularity() > 0.0 {
            let cache = rec.group_cache(g, cache_settings)?;
            for (name, sigma) in pattern::lobe_spread(rec, &cache, &lobe)? {
                if let Some(u) = uncertainty.iter_mut().find(|u| u.parameter == name) {
                    u.sigma = libm::hypot(u.sigma, sigma);
                }
            }
        }
    }
    Ok(uncertainty)
}

/// The uncertainty stage, after the final render: every group's parameters with their
/// standard errors in `reports`; a ladder's lobe and a textured group's lobe carry their
/// extra spread too.
pub(super) fn run(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    budget: &Budget,
    cache_settings: &RenderSettings,
    seed: u64,
) -> Result<StageReport, Error> {
    const STAGE: &str = "uncertainty";
    let stage_start = Instant::now();
    let mut laps = Laps::new(STAGE);
    for g in 0..reports.len() {
        laps.start(g, g as u32, reports);
        reports[g].uncertainty =
            group_uncertainty(rec, g, &reports[g], budget, cache_settings, seed)?;
    }
    laps.close(reports.len() as u32, reports);
    Ok(StageReport {
        stage: STAGE.into(),
        evaluations: reports.len() as u32,
        samples_per_pixel: uncertainty_spp(budget),
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![format!(
            "standard error of every parameter: cluster-robust least squares over tiles of {0}x{0} pixels, derivatives by finite differences on common random numbers",
            TILE
        )],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recover::model::NEUTRAL_STAND_IN;

    #[test]
    fn inverting_a_small_matrix() {
        let a = vec![
            vec![4.0, 1.0, 0.0],
            vec![1.0, 3.0, 1.0],
            vec![0.0, 1.0, 2.0],
        ];
        let inv = invert(&a).unwrap();
        let product = |i: usize, j: usize| -> f64 { (0..3).map(|k| a[i][k] * inv[k][j]).sum() };
        for (i, j) in (0..3).flat_map(|i| (0..3).map(move |j| (i, j))) {
            let expected = if i == j { 1.0 } else { 0.0 };
            assert!((product(i, j) - expected).abs() < 1e-12, "{i} {j}");
        }
        assert!(invert(&[vec![1.0, 2.0], vec![2.0, 4.0]]).is_none());
        assert!(invert(&[vec![0.0]]).is_none());
    }

    /// The jackknife over the halves of each pixel's samples: nothing when the halves are
    /// the same samples (a fit that does not depend on the cache's size), something when
    /// they differ.
    #[test]
    fn a_proposal_moves_with_its_cache_only_when_its_halves_differ() {
        use super::super::cache::tests::{cache_of, entries, repeated};
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        // The panorama as a plastic lobe renders on the cache's own samples: the whole
        // cache's fit is exact, each half's only as near as its samples agree.
        let lit = |mut cache: GroupCache| {
            let lobe = relume_core::transport::unit_isotropic_lobe(0.05);
            cache.real = (0..cache.pixels.len())
                .map(|i| {
                    let (d, b) = cache.linear_parts(i, &lobe);
                    0.3 * d + 0.1 * b
                })
                .collect();
            cache
        };
        let dependence = |cache: &GroupCache| {
            let (fit, alpha, _) = super::super::fit_ward(&pool, cache, Kind::Plastic);
            assert!(fit.specularity > 0.0, "a lobe is fitted");
            proposal_size_dependence(&pool, cache, Kind::Plastic, fit.specularity, alpha)
        };
        let same_halves = lit(cache_of(repeated(&entries(4), 4), 8));
        for (name, sigma) in dependence(&same_halves) {
            // The parts are sums in f32: the same up to rounding.
            assert!(sigma.abs() < 1e-5, "{name} {sigma}");
        }
        let other_halves = lit(cache_of(entries(8), 8));
        let moved = dependence(&other_halves);
        assert!(moved.iter().any(|(_, sigma)| *sigma > 1e-4), "{moved:?}");
    }

    #[test]
    fn every_model_parameter_is_perturbed_and_only_it() {
        let model = GroupModel::Anisotropic {
            kind: relume_core::material::Kind::Plastic,
            color: [0.2, 0.4, 0.6],
            specularity: 0.1,
            roughness_u: 0.05,
            roughness_v: 0.2,
            direction: [1.0, 0.0, 0.0],
        };
        let steps = perturbations(&model);
        assert_eq!(steps.len(), 4);
        let changed: Vec<GroupModel> = steps.iter().map(|p| perturbed(model, p)).collect();
        for (i, m) in changed.iter().enumerate() {
            assert_ne!(*m, model, "perturbation {i} changed nothing");
            for (j, other) in changed.iter().enumerate() {
                assert!(i == j || m != other);
            }
        }
        assert!(perturbations(&GroupModel::Unseen {
            stand_in: NEUTRAL_STAND_IN
        })
        .is_empty());
    }
}
