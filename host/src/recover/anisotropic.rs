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
use relume_core::material::Kind;
use relume_core::stages::anisotropic::{
    self as stage, lobe_at, shape_bounds, unit_lobe, Proposal, Shape,
};
use relume_core::stages::isotropic::{self, WardFit};

use super::cache::{self, GroupCache};
use super::model::GroupModel;
use super::refine::{
    pessimistic_cost, race, schedule, search_subset, Finalists, RaceOutcome, Refined,
    RACE_SPP_FACTOR,
};
use super::Recovery;
use crate::error::Error;

/// Two unit tangents of the group's largest triangle (`None` for a group of no area): the
/// plane its lobe directions turn in.
pub fn tangent_basis(rec: &Recovery, g: usize) -> Option<(Vec3, Vec3)> {
    let largest = rec
        .owned
        .triangles()
        .iter()
        .filter(|t| t.surface == Surface::Group(g as u16))
        .max_by(|a, b| a.area().total_cmp(&b.area()))?;
    stage::tangent_basis(largest)
}

/// Stage 4's proposal from the group's transport cache (`stage::propose`): every shape's
/// colour and specularity in closed form on the cache, the grid's shapes measured in
/// parallel. Returns the proposal and the evaluations spent.
pub fn propose_from_cache(
    pool: &rayon::ThreadPool,
    cache: &GroupCache,
    kind: Kind,
    basis: (Vec3, Vec3),
) -> Result<(Proposal, u32), Error> {
    let fit_at =
        |x: Shape| isotropic::solve(kind, &cache::linear_sums(pool, cache, &unit_lobe(x, basis)));
    let grid = stage::proposal_grid();
    // A point's sums split a small group's few pixels no further than pixel by pixel, so
    // the grid's points run in parallel too; each fit is the same as one at a time.
    let mut grid_fits = [WardFit::default(); stage::GRID_SHAPES];
    pool.install(|| {
        grid_fits
            .par_iter_mut()
            .zip(grid.par_iter())
            .for_each(|(fit, &x)| *fit = fit_at(x))
    });
    stage::propose(&grid_fits, fit_at).map_err(|e| Error::core("stage 4 proposal", e))
}

/// The anisotropic model a cache's `proposal` of `kind` stands for.
pub fn proposed_model(kind: Kind, proposal: &Proposal, basis: (Vec3, Vec3)) -> GroupModel {
    model_at(kind, &proposal.fit, proposal.x, basis)
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
    use relume_core::material::Material;
    use relume_core::rng::Sampler;
    use relume_core::transport::{self, IncidentSample, INCIDENT_PER_SAMPLE};

    /// A flat group (normal +z) lit by a bright patch, viewed from scattered directions
    /// around its mirror direction, the incident samples at random in a cone about it;
    /// the pixels rendered exactly under an anisotropic metal.
    fn synthetic_cache() -> GroupCache {
        let truth = Material::WardAnisotropic {
            rho_d: Vec3::splat(0.07),
            rho_s: Vec3::new(0.7, 0.65, 0.5),
            alpha_u: 0.04,
            alpha_v: 0.15,
            direction: Vec3::new(0.8, 0.6, 0.0),
        };
        let source = Vec3::new(-0.2, 0.4, 1.0).normalize();
        let samples = 48u32;
        let (mut pixels, mut real, mut entries) = (Vec::new(), Vec::new(), Vec::new());
        for p in 0..150u32 {
            let mut rng = Sampler::from_key(0x5EED ^ p as u64);
            let [x, y] = rng.next_2d();
            let wo = Vec3::new(
                -source.x + 0.6 * (x - 0.5),
                -source.y + 0.6 * (y - 0.5),
                source.z,
            )
            .normalize();
            let pixel: Vec<IncidentSample> = (0..samples as usize * INCIDENT_PER_SAMPLE)
                .map(|_| {
                    let [a, b] = rng.next_2d();
                    let wi =
                        (source + Vec3::new(0.5 * (a - 0.5), 0.5 * (b - 0.5), 0.0)).normalize();
                    let bright = if (wi - source).length() < 0.08 {
                        6.0
                    } else {
                        0.3
                    };
                    IncidentSample {
                        wo,
                        n: Vec3::Z,
                        wi,
                        weight: Vec3::splat(bright),
                        uv: [0.0, 0.0],
                    }
                })
                .collect();
            real.push(transport::shade(&pixel, samples, &truth, None));
            entries.extend(pixel);
            pixels.push(PurePixel {
                view: 0,
                x: p,
                y: 0,
                group: 0,
            });
        }
        GroupCache::new(pixels, real, entries, samples, INCIDENT_PER_SAMPLE)
    }

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    }

    #[test]
    fn the_cache_proposal_is_the_cores_on_the_caches_sums_for_any_thread_count() {
        let cache = synthetic_cache();
        let basis = (Vec3::X, Vec3::Y);
        let one = propose_from_cache(&pool(1), &cache, Kind::Metal, basis).unwrap();
        let two = propose_from_cache(&pool(2), &cache, Kind::Metal, basis).unwrap();
        assert_eq!(one, two);
        // The same, one shape at a time through the core.
        let sequential = pool(1);
        let fit_at = |x: Shape| {
            isotropic::solve(
                Kind::Metal,
                &cache::linear_sums(&sequential, &cache, &unit_lobe(x, basis)),
            )
        };
        let grid = stage::proposal_grid();
        let grid_fits = std::array::from_fn(|i| fit_at(grid[i]));
        assert_eq!(one, stage::propose(&grid_fits, fit_at).unwrap());
        // And it found the lobe: far below the diffuse model's error.
        let diffuse = isotropic::solve_diffuse(&cache::linear_sums(
            &sequential,
            &cache,
            &unit_lobe(grid[0], basis),
        ));
        assert!(
            one.0.fit.relative_error < 0.1 * diffuse.relative_error,
            "{one:?} against {diffuse:?}"
        );
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
        assert_eq!(
            isotropic_projection(GroupModel::Unseen {
                stand_in: crate::recover::model::NEUTRAL_STAND_IN
            }),
            None
        );
    }
}
