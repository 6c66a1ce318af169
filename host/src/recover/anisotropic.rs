//! Stage 4's fit: the anisotropic Ward lobe of one group, found as stage 2 finds the
//! isotropic one. The group's transport cache proposes (colour and specularity in closed
//! form for each lobe shape, the shape (log roughness_u, log roughness_v, direction angle)
//! by a grid and Nelder-Mead); simulated annealing over the shape refines on full
//! global-illumination renders of the group's pure pixels (a fixed subset of at most
//! `refine::MAX_SEARCH_PIXELS`, on one seed, with stage 2's cost
//! `refine::pessimistic_cost`); its best points then race the proposal on fresh samples,
//! and the proposal stands unless one renders better (`refine::race`).
//!
//! The direction is an angle in the plane of the group's largest triangle: reflectance.md
//! projects any direction onto each surface, so one angle covers a planar group exactly
//! and a curved one as its main face sees it.

use glam::Vec3;
use rayon::prelude::*;
use relume_core::anneal::Annealer;
use relume_core::geometry::Surface;
use relume_core::material::{Kind, Material};
use relume_core::nelder_mead::NelderMead;
use relume_core::stages::isotropic::{self, WardFit, ROUGHNESS_MAX, ROUGHNESS_MIN};

use super::cache::{self, GroupCache};
use super::model::GroupModel;
use super::refine::{
    pessimistic_cost, race, schedule, search_subset, Finalists, RaceOutcome, Refined,
    RACE_SPP_FACTOR,
};
use super::Recovery;
use crate::error::Error;

/// Two unit tangents of the group's largest triangle (`None` for a group of no area).
pub fn tangent_basis(rec: &Recovery, g: usize) -> Option<(Vec3, Vec3)> {
    let largest = rec
        .owned
        .triangles
        .iter()
        .filter(|t| t.surface == Surface::Group(g as u16))
        .max_by(|a, b| a.area().total_cmp(&b.area()))?;
    let n = largest.normal_area2().try_normalize()?;
    let t = (largest.v[1] - largest.v[0]).try_normalize()?;
    Some((t, n.cross(t)))
}

/// Log-spaced roughness levels of the cache proposal's grid (pairs with u <= v).
const PROPOSAL_ROUGHNESS_GRID: usize = 6;
/// Direction angles of the grid, over [0, pi).
const PROPOSAL_ANGLE_GRID: usize = 8;
/// Nelder-Mead evaluations after the grid.
const PROPOSAL_REFINE_EVALUATIONS: u32 = 80;

/// Bounds of a lobe shape's search (log roughness_u, log roughness_v, angle): the angle
/// may leave [0, pi) by up to a half turn, so that no search stalls at 0.
fn shape_bounds() -> ([f64; 3], [f64; 3]) {
    let (lo, hi) = (ROUGHNESS_MIN.ln(), ROUGHNESS_MAX.ln());
    (
        [lo, lo, -std::f64::consts::FRAC_PI_2],
        [hi, hi, 1.5 * std::f64::consts::PI],
    )
}

/// The shapes of the cache proposal's grid: log-spaced roughness levels with `u <= v` (a
/// shape with `u > v` is the same lobe turned by pi/2) at every angle. The first angle's
/// `u == v` points are the isotropic lobes of the same levels.
pub fn proposal_grid() -> Vec<[f64; 3]> {
    let (lo, hi) = (ROUGHNESS_MIN.ln(), ROUGHNESS_MAX.ln());
    let level = |i: usize| lo + (hi - lo) * i as f64 / (PROPOSAL_ROUGHNESS_GRID - 1) as f64;
    let angle = |k: usize| std::f64::consts::PI * k as f64 / PROPOSAL_ANGLE_GRID as f64;
    let mut grid = Vec::new();
    for i in 0..PROPOSAL_ROUGHNESS_GRID {
        for j in i..PROPOSAL_ROUGHNESS_GRID {
            for k in 0..PROPOSAL_ANGLE_GRID {
                grid.push([level(i), level(j), angle(k)]);
            }
        }
    }
    grid
}

/// The unit specular lobe (`rho_s = 1`, no diffuse part) of shape `x` (see [`lobe_at`]),
/// for the cache's linear parts.
pub fn unit_lobe(x: [f64; 3], basis: (Vec3, Vec3)) -> Material {
    let (alpha_u, alpha_v, direction) = lobe_at(x, basis);
    Material::WardAnisotropic {
        rho_d: Vec3::ZERO,
        rho_s: Vec3::ONE,
        alpha_u: alpha_u as f32,
        alpha_v: alpha_v as f32,
        direction,
    }
}

/// The anisotropic lobe of roughnesses `(exp x0, exp x1)`, `x2` the angle of its `u`
/// direction from `t` towards `b`.
fn lobe_at(x: [f64; 3], (t, b): (Vec3, Vec3)) -> (f64, f64, Vec3) {
    let (sin, cos) = x[2].sin_cos();
    (x[0].exp(), x[1].exp(), t * cos as f32 + b * sin as f32)
}

/// Stage 4's proposal from the group's transport cache, as stage 2's is: for each lobe
/// shape (log roughness_u, log roughness_v, angle) the best colour and specularity in
/// closed form (`isotropic::solve_plastic` / `solve_metal`, which hold for any unit lobe),
/// the shape by a grid (u <= v: a shape with u > v is the same lobe turned by pi/2), then
/// Nelder-Mead from the best grid point. Unlike the paper, colour and specularity are not
/// kept from stage 2: an isotropic lobe fitted to an anisotropic highlight takes a biased
/// specularity (the living room's brushed plate: 0.44 against a true 0.9), under which no
/// anisotropic shape fits. Returns the proposal and the evaluations spent.
pub fn propose_from_cache(
    pool: &rayon::ThreadPool,
    cache: &GroupCache,
    kind: Kind,
    basis: (Vec3, Vec3),
) -> Result<(Proposal, u32), Error> {
    let fit_at = |x: [f64; 3]| {
        let sums = cache::linear_sums(pool, cache, &unit_lobe(x, basis));
        let fit = isotropic::solve(kind, &sums);
        Proposal { fit, x }
    };
    let grid = proposal_grid();
    // The grid's points in parallel (a point's sums split a small group's few pixels no
    // further than pixel by pixel), chosen in grid order: the same proposal as one at a
    // time.
    let fits: Vec<Proposal> = pool.install(|| grid.par_iter().map(|&x| fit_at(x)).collect());
    let mut evaluations = fits.len() as u32;
    let offer = |p: Proposal, best: &mut Proposal| {
        if p.fit.sse < best.fit.sse {
            *best = p;
        }
    };
    let mut best = fits[0];
    for &p in &fits[1..] {
        offer(p, &mut best);
    }
    let (lower, upper) = shape_bounds();
    let mut search = NelderMead::new(
        lower,
        upper,
        best.x,
        best.fit.sse,
        PROPOSAL_REFINE_EVALUATIONS,
        0.05,
    )
    .map_err(|e| Error::core("stage 4 proposal", e))?;
    while !search.is_done() {
        evaluations += 1;
        let p = fit_at(search.propose());
        search.tell(p.fit.sse);
        offer(p, &mut best);
    }
    Ok((best, evaluations))
}

/// A lobe shape on the cache and its closed-form reflectances.
#[derive(Clone, Copy, Debug)]
pub struct Proposal {
    pub fit: WardFit,
    /// (log roughness_u, log roughness_v, angle of `u` from the basis' first tangent).
    pub x: [f64; 3],
}

/// The anisotropic model of `proposal`'s reflectances and lobe `x`.
fn model_at(kind: Kind, fit: &WardFit, x: [f64; 3], basis: (Vec3, Vec3)) -> GroupModel {
    let (roughness_u, roughness_v, d) = lobe_at(x, basis);
    GroupModel::Anisotropic {
        kind,
        color: fit.color,
        specularity: fit.specularity,
        roughness_u,
        roughness_v,
        direction: [d.x as f64, d.y as f64, d.z as f64],
    }
}

/// Anneals group `g`'s lobe shape from the cache's `proposal`, keeping its colour and
/// specularity, on renders of the group's pixels.
pub fn anneal_anisotropic(
    rec: &mut Recovery,
    g: usize,
    kind: Kind,
    proposal: &Proposal,
    basis: (Vec3, Vec3),
    (spp, levels): (u32, u32),
) -> Result<Refined, Error> {
    let fit = proposal.fit;
    let (lower, upper) = shape_bounds();
    let seed = rec.seed ^ 0xA1507 ^ g as u64;
    anneal_model(rec, g, spp, levels, seed, (lower, upper, proposal.x), |x| {
        model_at(kind, &fit, x, basis)
    })
}

/// The isotropic model with an anisotropic one's colour, specularity and the geometric
/// mean of its roughnesses (`None` for any other model).
pub fn isotropic_projection(model: GroupModel) -> Option<GroupModel> {
    match model {
        GroupModel::Anisotropic {
            kind,
            color,
            specularity,
            roughness_u,
            roughness_v,
            ..
        } => Some(GroupModel::Isotropic {
            kind,
            color,
            specularity,
            roughness: (roughness_u * roughness_v).sqrt(),
        }),
        _ => None,
    }
}

/// Anneals `model_at(x)` for group `g` within `(lower, upper)` from `x0`, every cost a
/// render of a fixed subset of the group's pixels on one seed, then races the best few
/// points on fresh samples as stage 2 does (`refine::race`): the lowest cost on the
/// search's own samples is partly the point those samples favour, and both sides of stage
/// 4's comparison should be chosen alike.
fn anneal_model<const D: usize>(
    rec: &mut Recovery,
    g: usize,
    spp: u32,
    levels: u32,
    seed: u64,
    (lower, upper, x0): ([f64; D], [f64; D], [f64; D]),
    model_at: impl Fn([f64; D]) -> GroupModel,
) -> Result<Refined, Error> {
    let subset = search_subset(&rec.pure, g);
    let all_pixels = std::mem::replace(&mut rec.pure, subset);
    let result = search_and_race(rec, g, spp, levels, seed, (lower, upper, x0), &model_at);
    rec.pure = all_pixels;
    let (race, evaluations) = result?;
    rec.models[g] = race.winner;
    Ok(Refined {
        model: race.winner,
        evaluations,
        race: Some(race),
        mirror: None,
    })
}

/// [`anneal_model`] on the pixels in `rec.pure`: the race and the evaluations in all.
fn search_and_race<const D: usize>(
    rec: &mut Recovery,
    g: usize,
    spp: u32,
    levels: u32,
    seed: u64,
    (lower, upper, x0): ([f64; D], [f64; D], [f64; D]),
    model_at: &impl Fn([f64; D]) -> GroupModel,
) -> Result<(RaceOutcome, u32), Error> {
    let mut finalists = Finalists::new();
    let mut evaluations = 0u32;
    let mut cost_of = |rec: &mut Recovery, x: [f64; D]| -> Result<f64, Error> {
        rec.models[g] = model_at(x);
        evaluations += 1;
        let cost = pessimistic_cost(rec.error_estimate(g, spp, seed)?);
        finalists.offer(cost, model_at(x));
        Ok(cost)
    };
    let cost0 = cost_of(rec, x0)?;
    let start = model_at(x0);
    let mut annealer = Annealer::new(lower, upper, x0, cost0, schedule(levels), seed)
        .map_err(|e| Error::core("annealing", e))?;
    while !annealer.is_done() {
        let x = annealer.propose();
        let cost = cost_of(rec, x)?;
        annealer.tell(cost);
    }
    // The start (the cache's proposal) is the race's incumbent, as in stage 2
    // (`refine::anneal_isotropic`).
    let race = race(
        rec,
        g,
        start,
        &finalists.models(),
        RACE_SPP_FACTOR * spp,
        seed ^ 0x2ACE_0004,
    )?;
    let evaluations = evaluations + race.evaluations;
    Ok((race, evaluations))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recover::pixels::PurePixel;
    use relume_core::transport::{self, IncidentSample};

    /// A flat group (normal +z) whose pixels see a small bright source from many
    /// viewing directions: its highlight's shape is what tells the lobe apart.
    fn synthetic_cache(truth: &Material) -> GroupCache {
        let n = Vec3::Z;
        let source = Vec3::new(0.3, -0.2, 1.0).normalize();
        let samples = 64u32;
        let (mut pixels, mut real, mut entries) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..12u32 {
            for j in 0..12u32 {
                let (x, y) = (i as f32 / 11.0 - 0.5, j as f32 / 11.0 - 0.5);
                // Viewed around the mirror direction of the source.
                let wo = Vec3::new(-source.x + 0.5 * x, -source.y + 0.5 * y, source.z).normalize();
                let mut pixel = Vec::new();
                for k in 0..samples * 2 {
                    let (a, b) = ((k % 16) as f32 / 15.0 - 0.5, (k / 16) as f32 / 7.0 - 0.5);
                    let wi = (source + Vec3::new(0.4 * a, 0.4 * b, 0.0)).normalize();
                    let spot = libm::expf(-(wi - source).length_squared() / 0.01);
                    pixel.push(IncidentSample {
                        wo,
                        n,
                        wi,
                        weight: Vec3::splat(0.2 + 5.0 * spot),
                        uv: [0.0, 0.0],
                    });
                }
                real.push(transport::shade(&pixel, samples, truth, None));
                entries.extend(pixel);
                pixels.push(PurePixel {
                    view: 0,
                    x: i,
                    y: j,
                    group: 0,
                });
            }
        }
        GroupCache::new(pixels, real, entries, samples)
    }

    #[test]
    fn the_cache_proposal_recovers_an_anisotropic_metal_lobe_and_its_direction() {
        let (color, s) = (Vec3::new(0.75, 0.76, 0.78), 0.9);
        let direction = Vec3::new(1.0, 1.0, 0.0).normalize();
        let truth = Material::WardAnisotropic {
            rho_d: color * (1.0 - s),
            rho_s: color * s,
            alpha_u: 0.05,
            alpha_v: 0.2,
            direction,
        };
        let cache = synthetic_cache(&truth);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let (p, evaluations) =
            propose_from_cache(&pool, &cache, Kind::Metal, (Vec3::X, Vec3::Y)).unwrap();
        assert!(evaluations > 100);
        let (u, v, d) = lobe_at(p.x, (Vec3::X, Vec3::Y));
        // The proposal may name the lobe with u and v swapped and d turned by 90 degrees.
        let (u, v, d) = if u <= v {
            (u, v, d)
        } else {
            (v, u, Vec3::Z.cross(d))
        };
        assert!((u / 0.05 - 1.0).abs() < 0.05, "{p:?}");
        assert!((v / 0.2 - 1.0).abs() < 0.05, "{p:?}");
        let off = libm::acosf(d.dot(direction).abs().min(1.0)).to_degrees();
        assert!(off < 3.0, "direction {off} degrees off: {p:?}");
        assert!((p.fit.specularity - 0.9).abs() < 0.02, "{p:?}");
        assert!(p.fit.relative_error < 0.01, "{p:?}");
    }

    #[test]
    fn the_isotropic_shadow_keeps_colour_and_takes_the_mean_roughness() {
        let aniso = GroupModel::Anisotropic {
            kind: Kind::Metal,
            color: [0.8, 0.7, 0.3],
            specularity: 0.9,
            roughness_u: 0.05,
            roughness_v: 0.2,
            direction: [1.0, 0.0, 0.0],
        };
        let Some(GroupModel::Isotropic {
            kind,
            color,
            specularity,
            roughness,
        }) = isotropic_projection(aniso)
        else {
            panic!("an anisotropic model has an isotropic shadow");
        };
        assert_eq!(
            (kind, color, specularity),
            (Kind::Metal, [0.8, 0.7, 0.3], 0.9)
        );
        assert!((roughness - 0.1).abs() < 1e-12, "{roughness}");
        assert_eq!(isotropic_projection(GroupModel::Unseen), None);
    }
}
