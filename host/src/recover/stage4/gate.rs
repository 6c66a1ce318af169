//! Stage 4's gate: which groups that stage 2 left go on to the search, said in the report;
//! a group stage 2 left diffuse is measured again with its colour levelled under the scene
//! as now known.

use relume_core::fit;

use super::super::model::GroupModel;
use super::super::pixels::PurePixel;
use super::super::{polish, GroupReport, Recovery, POLISH_MIN_SAMPLES};
use crate::error::Error;

/// The seed key of the render that levels a diffuse rival's colour.
const LEVEL_KEY: u64 = 0x57A6_E4D1;

/// The seed key (beside the decisions' seed) of the measurement of a diffuse group's error
/// under the scene as now known.
const GATE_KEY: u64 = 0x6A7E_0004;

/// Group `g`'s `color` under `model` (the group's model for the render, restored after)
/// levelled by one colour-polish step (`polish::colour_step` at `polish::group_spp` for
/// the loop's `verify_spp` and the group's `pixels`, at least `POLISH_MIN_SAMPLES`
/// samples; a large group's on its subset with those samples in all, within
/// `fit::DECISION_MAX_SAMPLES`, `Recovery::mean_pixels`): the new colour, the pixels and
/// samples per pixel the step rendered, and what the report says of it.
pub(super) fn levelled_colour(
    rec: &mut Recovery,
    g: usize,
    model: GroupModel,
    color: [f64; 3],
    (verify_spp, pixels): (u32, u32),
) -> Result<Levelled, Error> {
    let (subset, spp) = rec.mean_pixels(g, polish::group_spp(verify_spp, pixels));
    let found = rec.models[g];
    rec.models[g] = model;
    let step = polish::colour_step_on(rec, g, color, (subset.as_deref(), spp), LEVEL_KEY);
    rec.models[g] = found;
    let (levelled, change) = step?;
    let on = match &subset {
        Some(subset) => format!(" on {} of its {pixels} pixels", subset.len()),
        None => String::new(),
    };
    let said = format!(
        "levelled by a render at {spp} spp{on} (at least POLISH_MIN_SAMPLES {POLISH_MIN_SAMPLES} samples): largest change {:.2}%",
        100.0 * change
    );
    Ok(Levelled {
        color: levelled,
        subset,
        spp,
        said,
    })
}

/// A colour levelled by [`levelled_colour`].
pub(super) struct Levelled {
    pub(super) color: [f64; 3],
    /// The pixels its render took (`None`: all the group's) and their samples per pixel.
    pub(super) subset: Option<Vec<PurePixel>>,
    pub(super) spp: u32,
    /// What the report says of it.
    pub(super) said: String,
}

/// How the report names a note on the stage's gate: not `"stage 4:"`, which marks a
/// decision that set the group's model (`GroupReport::settling_decision`).
pub(super) const GATE: &str = "stage 4 gate";

/// Says, for every untextured group that stage 2 decided and this stage leaves alone, why:
/// its decided error is not above `DIFFUSE_THRESHOLD`, the error left for an anisotropic
/// lobe to explain. Without it a group's route ends at stage 2 with no word on stage 4 (the
/// living room's brushed plate: isotropic, 0.035 left, and anisotropic in truth).
pub(super) fn say_why_not_tried(
    rec: &Recovery,
    reports: &mut [GroupReport],
    textured: &[bool],
    tried: &[usize],
) {
    for (g, r) in reports.iter_mut().enumerate() {
        let model = match rec.models[g] {
            GroupModel::Isotropic { .. } => "isotropic",
            GroupModel::Diffuse { .. } => "diffuse",
            _ => continue,
        };
        let Some(error) = r.error_decided else {
            continue;
        };
        if textured[g] || tried.contains(&g) {
            continue;
        }
        r.decisions.push(format!(
            "{GATE}: not tried: its {model} model leaves {error:.4} of relative error as stage 2 decided, not above DIFFUSE_THRESHOLD {}, the error an anisotropic lobe is sought for",
            fit::DIFFUSE_THRESHOLD
        ));
    }
}

/// Whether a group that stage 2 left diffuse goes on to this stage's search, and its
/// colour levelled by the colour polish's step (`polish::colour_step`, at least
/// `POLISH_MIN_SAMPLES` samples), against which the lobes are weighed.
///
/// The gate (its decided error above `DIFFUSE_THRESHOLD`) read stage 1's measurement,
/// taken before stage 2 gave the other groups their lobes and mirrors: cornell's ceiling
/// read 0.18 there, lit without the mirror it sees, and 0.045 in the final render. So the
/// error is measured again here, with the levelled colour, and a group goes on unless the
/// error's upper bound at `EXCEEDS_SIGMAS` standard errors is below the threshold (the
/// search, race and comparisons are the stage's cost: 7 of cornell's 27 s on three walls
/// that stayed diffuse). Also returns the evaluations spent.
pub(super) fn diffuse_goes_on(
    rec: &mut Recovery,
    report: &mut GroupReport,
    g: usize,
    color: [f64; 3],
    verify_spp: u32,
) -> Result<([f64; 3], bool, u32), Error> {
    let stage2 = rec.models[g];
    let Levelled {
        color: levelled,
        subset,
        spp,
        said: levelling,
    } = levelled_colour(rec, g, stage2, color, (verify_spp, report.pure_pixels))?;
    rec.models[g] = GroupModel::Diffuse { color: levelled };
    // On the pixels and samples the colour was levelled on.
    let seed = rec.decision_seed() ^ GATE_KEY;
    let now = match &subset {
        Some(subset) => rec.error_estimate_on(subset, spp, seed),
        None => rec.error_estimate(g, spp, seed),
    };
    rec.models[g] = stage2;
    let Some(now) = now? else {
        report.decisions.push(format!(
            "stage 4: the lobes are weighed against the diffuse model {levelling}"
        ));
        return Ok((levelled, true, 1));
    };
    let bound = now.upper_bound(fit::EXCEEDS_SIGMAS);
    let goes_on = bound > fit::DIFFUSE_THRESHOLD;
    let measured = format!(
        "its error under the scene as now known, with its colour {levelling}, is {:.4} +- {:.4} (upper bound {bound:.4} at EXCEEDS_SIGMAS {})",
        now.error,
        now.sigma,
        fit::EXCEEDS_SIGMAS
    );
    report.decisions.push(match goes_on {
        true => format!(
            "stage 4: goes on: {measured}, not below DIFFUSE_THRESHOLD {}; the lobes are weighed against that levelled diffuse model",
            fit::DIFFUSE_THRESHOLD
        ),
        false => format!(
            "stage 4: stays diffuse without a search: {measured}, below DIFFUSE_THRESHOLD {} (the gate read {:.4}, measured under the scene as it was known then)",
            fit::DIFFUSE_THRESHOLD,
            report.error_decided.unwrap_or(0.0)
        ),
    });
    Ok((levelled, goes_on, 2))
}
