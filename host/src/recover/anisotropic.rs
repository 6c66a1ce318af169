//! Stage 4's fit: simulated annealing over (log roughness_u, log roughness_v, direction
//! angle) of one group, keeping stage 2's colour and specularity as the paper does. Every
//! cost is a full global-illumination render of the group's pure pixels (a fixed subset
//! of at most `refine::MAX_SEARCH_PIXELS`), on one seed, with stage 2's cost
//! (`refine::pessimistic_cost`).
//!
//! The direction is an angle in the plane of the group's largest triangle: reflectance.md
//! projects any direction onto each surface, so one angle covers a planar group exactly
//! and a curved one as its main face sees it.

use glam::Vec3;
use relume_core::anneal::Annealer;
use relume_core::geometry::Surface;
use relume_core::stages::isotropic::{ROUGHNESS_MAX, ROUGHNESS_MIN};

use super::model::GroupModel;
use super::refine::{
    pessimistic_cost, race, schedule, search_subset, Finalists, Refined, RACE_SPP_FACTOR,
};
use super::Recovery;
use crate::error::Error;

/// Two unit tangents of the group's largest triangle (`None` for a group of no area).
fn tangent_basis(rec: &Recovery, g: usize) -> Option<(Vec3, Vec3)> {
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

/// Anneals group `g` from the isotropic model `start` (any other is returned as it is).
pub fn anneal_anisotropic(
    rec: &mut Recovery,
    g: usize,
    start: GroupModel,
    spp: u32,
    levels: u32,
) -> Result<Refined, Error> {
    let (
        GroupModel::Isotropic {
            kind,
            color,
            specularity,
            roughness,
        },
        Some((t, b)),
    ) = (start, tangent_basis(rec, g))
    else {
        return Ok(Refined::unchanged(start));
    };
    let model_at = |x: [f64; 3]| {
        let (sin, cos) = x[2].sin_cos();
        let d = t * cos as f32 + b * sin as f32;
        GroupModel::Anisotropic {
            kind,
            color,
            specularity,
            roughness_u: x[0].exp(),
            roughness_v: x[1].exp(),
            direction: [d.x as f64, d.y as f64, d.z as f64],
        }
    };
    let log_r = roughness.clamp(ROUGHNESS_MIN, ROUGHNESS_MAX).ln();
    let lower = [ROUGHNESS_MIN.ln(), ROUGHNESS_MIN.ln(), 0.0];
    let upper = [ROUGHNESS_MAX.ln(), ROUGHNESS_MAX.ln(), std::f64::consts::PI];
    // Start slightly anisotropic, so that the direction matters from the first step.
    let x0 = [log_r - 0.2, log_r + 0.2, 0.5 * std::f64::consts::PI];
    let seed = rec.seed ^ 0xA1507 ^ g as u64;
    anneal_model(rec, g, spp, levels, seed, (lower, upper, x0), model_at)
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

/// The best isotropic roughness of group `g` for `start`'s colour and specularity, by the
/// same search, cost and budget as [`anneal_anisotropic`]: the fair alternative for stage
/// 4's decision. Stage 2 chose its roughness together with a colour and specularity that
/// stage 4 keeps fixed; against that point, any anisotropic fit can gain merely by moving
/// the roughness (glossy's metal_gold turned anisotropic so in 2 of 6 seeds).
pub fn refit_isotropic_roughness(
    rec: &mut Recovery,
    g: usize,
    start: GroupModel,
    spp: u32,
    levels: u32,
) -> Result<Refined, Error> {
    let GroupModel::Isotropic {
        kind,
        color,
        specularity,
        roughness,
    } = start
    else {
        return Ok(Refined::unchanged(start));
    };
    let model_at = |x: [f64; 1]| GroupModel::Isotropic {
        kind,
        color,
        specularity,
        roughness: x[0].exp(),
    };
    let bounds = (
        [ROUGHNESS_MIN.ln()],
        [ROUGHNESS_MAX.ln()],
        [roughness.clamp(ROUGHNESS_MIN, ROUGHNESS_MAX).ln()],
    );
    let seed = rec.seed ^ 0x1507_1507 ^ g as u64;
    anneal_model(rec, g, spp, levels, seed, bounds, model_at)
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
    let (model, evaluations) = result?;
    rec.models[g] = model;
    Ok(Refined { model, evaluations })
}

/// [`anneal_model`] on the pixels in `rec.pure`: the race's winner and the evaluations.
fn search_and_race<const D: usize>(
    rec: &mut Recovery,
    g: usize,
    spp: u32,
    levels: u32,
    seed: u64,
    (lower, upper, x0): ([f64; D], [f64; D], [f64; D]),
    model_at: &impl Fn([f64; D]) -> GroupModel,
) -> Result<(GroupModel, u32), Error> {
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
    let mut annealer = Annealer::new(lower, upper, x0, cost0, schedule(levels), seed)
        .map_err(|e| Error::core("annealing", e))?;
    while !annealer.is_done() {
        let x = annealer.propose();
        let cost = cost_of(rec, x)?;
        annealer.tell(cost);
    }
    let (winner, raced) = race(
        rec,
        g,
        &finalists.models(),
        RACE_SPP_FACTOR * spp,
        seed ^ 0x2ACE_0004,
    )?;
    Ok((winner, evaluations + raced))
}

#[cfg(test)]
mod tests {
    use super::*;
    use relume_core::material::Kind;

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
