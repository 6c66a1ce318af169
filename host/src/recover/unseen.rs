//! Stand-ins for the groups no view sees whole. Their material is not recovered (no pure
//! pixel says what it is), but their light reaches the groups that are, and a neutral grey
//! in its place put light the panorama does not hold into every render: the textured
//! reference's dark frames (colour 0.12, 0.09, 0.07), unseen at 64 px, rendered as grey
//! made the ceiling 3.4% and the walls 1.3% brighter than the truth materials do, and the
//! recovery took it out of their colours. So an unseen group is rendered as a diffuse
//! colour measured on the pixels it shares with groups whose materials are known, by the
//! colour step of a plastic's diffuse part (`diffuse::update_beside_lobe`): the pixels'
//! render less their render with the group black is the group's part. It is measured
//! after stage 1, and again after the diffuse refinement, which then runs once more: the
//! stand-in and its neighbours' colours depend on each other.

use std::time::Instant;

use relume_core::fit;
use relume_core::stages::diffuse;

use super::model::GroupModel;
use super::{min_samples_spp, pixels, GroupReport, Recovery, StageReport};
use crate::error::Error;
use crate::text::counted;

/// The smallest share of a pixel's label rays on the unseen group for the pixel to
/// measure it: the rest of the pixel is rendered under the known groups' materials, whose
/// errors the group's part takes whole, scaled up by the inverse of its share.
pub const MIN_SHARE: f64 = 0.5;
/// The fewest such pixels that a stand-in is measured on; with fewer the group keeps the
/// neutral grey.
pub const MIN_PIXELS: usize = 4;
/// Pixel samples, in all, of each render of a measurement (all on the same samples, so
/// that their differences hold little noise).
const MIN_SAMPLES: u64 = 1 << 18;
/// Colour steps of a measurement at the most; it stops sooner when a step changes no
/// channel by more than `fit::DIFFUSE_CONVERGED`.
pub const MAX_STEPS: u32 = 6;

/// Measures the stand-in of every group that no view sees whole (and that is not unlit:
/// it has no pure pixel), on the pixels it shares with untextured groups as they are now
/// modelled, at `spp` samples per pixel or more. `None` when no group is unseen.
pub(super) fn measure_stand_ins(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    spp: u32,
    key: u64,
) -> Result<Option<StageReport>, Error> {
    let stage_start = Instant::now();
    let n_groups = rec.n_groups();
    let unseen: Vec<bool> = (0..n_groups)
        .map(|g| matches!(rec.models[g], GroupModel::Unseen { .. }) && reports[g].pure_pixels == 0)
        .collect();
    if !unseen.contains(&true) {
        return Ok(None);
    }
    // The groups whose render beside an unseen group can be trusted: not a textured one,
    // whose map is extrapolated where it meets the unseen group (its border pixels that
    // see one are left out of its solve, `pixels::border_pixels`). Textured's frames
    // measured 0.160, 0.128, 0.106 beside the pictures' maps too, 0.155, 0.125, 0.105
    // without (the truth's diffuse and specular parts: 0.155, 0.126, 0.107).
    let known: Vec<bool> = rec
        .models
        .iter()
        .map(|m| !matches!(m, GroupModel::Unseen { .. } | GroupModel::Textured { .. }))
        .collect();
    // Rays only: the render settings (spp 1, seed 0) are not used.
    let mixed = rec.with_scene(1, 0, |pool, scene, observed, _| {
        pixels::mixed_pixels(
            pool,
            scene,
            observed.views,
            n_groups,
            MIN_SHARE,
            |h| unseen[h as usize],
            |h| known[h as usize],
        )
    })?;
    let mut evaluations = 0;
    for g in (0..n_groups).filter(|&g| unseen[g]) {
        let GroupModel::Unseen { stand_in } = rec.models[g] else {
            continue;
        };
        let shared: Vec<pixels::PurePixel> = mixed[g].iter().map(|&(p, _)| p).collect();
        let share: f64 = mixed[g].iter().map(|&(_, s)| s).sum();
        if shared.len() < MIN_PIXELS {
            reports[g].decisions.push(format!(
                "stand-in: {} {} it over at least MIN_SHARE {MIN_SHARE} of their footprint beside known groups (< MIN_PIXELS {MIN_PIXELS}): rendered as [{:.3}, {:.3}, {:.3}]",
                counted(shared.len() as u64, "pixel"),
                if shared.len() == 1 { "sees" } else { "see" },
                stand_in[0],
                stand_in[1],
                stand_in[2]
            ));
            continue;
        }
        let group_spp = min_samples_spp(spp, shared.len() as u32, MIN_SAMPLES);
        let seed = rec.seed ^ key ^ g as u64;
        let only_g = |h: u16| h as usize == g;
        // The render with the group black is the rest of each pixel, whatever its colour.
        rec.models[g] = GroupModel::Unseen { stand_in: [0.0; 3] };
        let black = rec.evaluate_pixels(&shared, group_spp, seed, &only_g);
        rec.models[g] = GroupModel::Unseen { stand_in };
        let black = black?[g];
        evaluations += 1;
        // The steps, each from a render on the same samples, until the colour settles: a
        // group that lights itself (two facing walls) renders more than in proportion to
        // its colour, and one step from the grey falls short.
        let mut steps = 0;
        let mut measured = None;
        while steps < MAX_STEPS {
            let current = measured.unwrap_or(stand_in);
            let with_current = rec.evaluate_pixels(&shared, group_spp, seed, &only_g)?[g];
            evaluations += 1;
            steps += 1;
            let Some((next, change)) = diffuse::update_beside_lobe(current, &with_current, &black)
            else {
                break;
            };
            rec.models[g] = GroupModel::Unseen { stand_in: next };
            measured = Some(next);
            if change <= fit::DIFFUSE_CONVERGED {
                break;
            }
        }
        let decision = match measured {
            Some(measured) => format!(
                "stand-in: rendered as the diffuse [{:.4}, {:.4}, {:.4}], measured in {steps} steps on {} pixels that see it over at least MIN_SHARE {MIN_SHARE} of their footprint beside known groups ({share:.1} pixels' worth) at {group_spp} spp; not written as its material",
                measured[0],
                measured[1],
                measured[2],
                shared.len()
            ),
            None => format!(
                "stand-in: kept [{:.3}, {:.3}, {:.3}]: on the {} pixels that see it beside known groups, the panorama is no brighter than their render with it black in some channel",
                stand_in[0],
                stand_in[1],
                stand_in[2],
                shared.len()
            ),
        };
        reports[g].decisions.push(decision);
    }
    Ok(Some(StageReport {
        stage: "unseen stand-ins".into(),
        evaluations,
        samples_per_pixel: spp,
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![format!(
            "groups with no pure pixel: a diffuse stand-in for the light they pass on, measured on the pixels they cover over at least MIN_SHARE {MIN_SHARE} of the footprint beside untextured groups of known material (colour steps of a plastic's diffuse part against a render with the group black, until settled or MAX_STEPS {MAX_STEPS})"
        )],
    }))
}
