//! Stage 1: every group diffuse, `rho_d <- rho_d * mean(real) / mean(rendered)` per group
//! and channel until converged; then each group's bias-only error decides whether it is
//! unseen, barely seen, diffuse, or goes on to stage 2 (`diffuse::verdict`).

use std::time::Instant;

use relume_core::fit;
use relume_core::stages::diffuse::{self, DiffuseVerdict};

use super::ladder;
use super::model::{GroupModel, NEUTRAL_STAND_IN};
use super::warnings::brighter_at_bound;
use super::{
    min_samples_spp, pixels, progress_bar, DiffuseStep, GroupReport, Recovery, StageReport,
    CACHE_MIN_SAMPLES, POLISH_MIN_SAMPLES, POLISH_NEWTON_MAX_GROUPS, POLISH_SPP_FACTOR,
};
use crate::error::Error;
use crate::text::counted;

/// What stage 1 hands on.
pub(super) struct Stage1 {
    pub report: StageReport,
    /// The groups that go on to stage 2, each with its error.
    pub candidates: Vec<(usize, fit::ErrorEstimate)>,
    /// The iteration's steps, for the recovery's report.
    pub steps: Vec<DiffuseStep>,
}

/// Runs stage 1 at `spp` samples per pixel, recording each group's error and verdict in
/// `reports` (and a warning in `warnings` for a group unseen or barely seen).
pub(super) fn run(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    names: &[String],
    spp: u32,
    warnings: &mut Vec<String>,
) -> Result<Stage1, Error> {
    let n_groups = reports.len();
    let stage_start = Instant::now();
    let bar = progress_bar(fit::DIFFUSE_MAX_STEPS as u64, "1 diffuse");
    let all = vec![true; n_groups];
    let iteration = rec.diffuse_iteration(spp, &all, &bar)?;
    let (first, evaluations) = (&iteration.first, iteration.evaluations);
    let pure_pixels = pixels::group_counts(&rec.pure, n_groups);
    let unlit = unlit_groups(rec, first, spp)?;
    refuse_unlit_or_black(rec, first, &unlit, &pure_pixels)?;
    // Which groups go on is decided on the bias-only error, at the decisions' samples and
    // seed: the loop's variance-subtracted error at a few samples per pixel misjudges its
    // own noise (heavy-tailed paths), by whole percents either way.
    let mut decided = rec.error_estimates(4 * spp)?;
    // A group whose error straddles the gate is measured again alone, with more samples,
    // while it still does: at the loop's samples its standard error (0.024 on glossy's
    // 492-pixel yellow box, 0.0055 on the living room's 3742-pixel desk at 256 px) hides
    // a weak lobe either way.
    let mut measured_again = vec![None; n_groups];
    for (g, estimate) in decided.iter_mut().enumerate() {
        if pure_pixels[g] < fit::MIN_PIXELS_FOR_MODEL_CHOICE {
            continue;
        }
        let error = estimate.map_or(0.0, |e| e.error);
        if let Some(first_spp) = first_remeasure_spp(4 * spp, pure_pixels[g], error) {
            (*estimate, measured_again[g]) =
                measured_until_it_sides(rec, g, pure_pixels[g], first_spp, *estimate)?;
        }
    }
    bar.finish_and_clear();
    let report = StageReport {
        stage: "1 diffuse".into(),
        evaluations: evaluations + 1,
        samples_per_pixel: spp,
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![format!(
            "rho_d <- rho_d * mean(real) / mean(rendered) per group and channel at the first step, then Broyden's joint secant step (per channel, over all groups, in log space: it learns how each group's render responds to every colour), until the largest relative change <= {} or, after {} steps, stops shrinking (the render's noise floor)",
            fit::DIFFUSE_CONVERGED,
            diffuse::MIN_STEPS
        )],
    };
    let mut candidates = Vec::new();
    for g in 0..n_groups {
        let r = &mut reports[g];
        r.pure_pixels = pure_pixels[g];
        r.error_initial = first[g].relative_error();
        r.set_diffuse(decided[g]);
        let e = decided[g].map_or(0.0, |e| e.error);
        let sigma = decided[g].map_or(0.0, |e| e.sigma);
        let again = measured_again[g].map_or(String::new(), |spp| {
            format!(" (measured again alone at {spp} spp, as it straddled the gate)")
        });
        if let Some(unlit) = &unlit[g] {
            rec.models[g] = GroupModel::Unseen {
                stand_in: NEUTRAL_STAND_IN,
            };
            r.decisions.push(format!(
                "unlit: {}; material not recovered",
                unlit.describe()
            ));
            warnings.push(unlit.warning(&names[g]));
            continue;
        }
        match diffuse::verdict(pure_pixels[g], decided[g]) {
            DiffuseVerdict::Unseen => {
                rec.models[g] = GroupModel::Unseen {
                    stand_in: NEUTRAL_STAND_IN,
                };
                r.decisions
                    .push("unseen: no pure pixel in any view; material not recovered".into());
                warnings.push(format!(
                    "group '{}': no pure pixel in any view; its material is not recovered",
                    names[g]
                ));
            }
            DiffuseVerdict::Black => {
                // What the iteration comes to from any start: every step scales by 0.
                rec.models[g] = GroupModel::Diffuse { color: [0.0; 3] };
                r.decisions.push(format!(
                    "diffuse, black: its {} are 0 in the panorama though light reaches them (no relative error: nothing to compare with)",
                    counted(pure_pixels[g], "pure pixel")
                ));
                warnings.push(format!(
                    "group '{}': its {} are 0 in the panorama, though light reaches them: recovered as black diffuse (is the panorama right there?)",
                    names[g],
                    counted(pure_pixels[g], "pure pixel")
                ));
            }
            DiffuseVerdict::BarelySeen => {
                r.decisions.push(format!(
                    "diffuse, barely seen: {} < MIN_PIXELS_FOR_MODEL_CHOICE {}; no more complex model is tried",
                    counted(pure_pixels[g], "pure pixel"),
                    fit::MIN_PIXELS_FOR_MODEL_CHOICE
                ));
                // Its colour is fitted to the mean of what the pixels show, highlights
                // included: with much error left, a lobe there went into the colour (the
                // living room's frames, 15 pixels, came out 2.5-4x too bright at 0.46).
                let unexplained = match decided[g] {
                    Some(e) if e.exceeds(fit::DIFFUSE_THRESHOLD) => format!(
                        ", yet its diffuse fit leaves {:.0}% of error (> DIFFUSE_THRESHOLD {:.0}%): its colour likely holds a specular part and may be far off",
                        100.0 * e.error,
                        100.0 * fit::DIFFUSE_THRESHOLD
                    ),
                    _ => String::new(),
                };
                warnings.push(format!(
                    "group '{}': only {}; kept diffuse{unexplained}",
                    names[g],
                    counted(pure_pixels[g], "pure pixel")
                ));
            }
            DiffuseVerdict::Diffuse => {
                // A specular lobe cannot remove more error than there is.
                r.decisions.push(format!(
                    "stage 1: diffuse, error {e:.4} +- {sigma:.4}{again} not above SPECULAR_GAIN_THRESHOLD {} by EXCEEDS_SIGMAS {} standard errors: no specular model could gain more",
                    fit::SPECULAR_GAIN_THRESHOLD,
                    fit::EXCEEDS_SIGMAS
                ));
            }
            DiffuseVerdict::NeedsSpecular => {
                // The verdict is only given on a measured error.
                let Some(estimate) = decided[g] else {
                    continue;
                };
                let (side, route) = if ladder::applies(&estimate) {
                    ("not above", "tested for a weak specular")
                } else {
                    ("above", "on to isotropic")
                };
                r.decisions.push(format!(
                    "stage 1: diffuse error {e:.4} +- {sigma:.4}{again} > SPECULAR_GAIN_THRESHOLD {} by more than EXCEEDS_SIGMAS {} standard errors ({side} DIFFUSE_THRESHOLD {} by them): {route}",
                    fit::SPECULAR_GAIN_THRESHOLD,
                    fit::EXCEEDS_SIGMAS,
                    fit::DIFFUSE_THRESHOLD
                ));
                candidates.push((g, estimate));
            }
        }
    }
    Ok(Stage1 {
        report,
        candidates,
        steps: iteration.steps,
    })
}

/// The refusals of a scene whose first render says that nothing can be recovered: no light
/// reaches what its views see, or the panorama is 0 over every lit group (`first`: the
/// iteration's first fits; `unlit`: [`unlit_groups`] of them).
fn refuse_unlit_or_black(
    rec: &Recovery,
    first: &[fit::GroupFit],
    unlit: &[Option<Unlit>],
    pure_pixels: &[u32],
) -> Result<(), Error> {
    let n_groups = unlit.len();
    // (A scene whose views see no group whole is a different matter: every group unseen.)
    let lit = (0..n_groups).any(|g| pure_pixels[g] > 0 && unlit[g].is_none());
    if !lit && unlit.iter().any(Option::is_some) {
        let enclosed = crate::enclosed_views::enclosed_lights_said(
            rec.owned.triangles(),
            &rec.views,
            &rec.owned.light_names,
            &rec.owned.group_names,
        );
        return Err(Error::input(
            &rec.owned.desc.path,
            format!("no light of the scene reaches what its views see: every group's pure pixels render black, so no material can be recovered (a light hidden, of radiance 0, facing away, or none? Or the views outside the room or inside an object, seeing the backs of surfaces no light reaches?){enclosed}"),
        ));
    }
    // A panorama that is 0 over every lit group's pure pixels is not a room of black
    // materials but an image or exposure gone wrong.
    let seen_lit: Vec<usize> = (0..n_groups)
        .filter(|&g| pure_pixels[g] > 0 && unlit[g].is_none())
        .collect();
    if !seen_lit.is_empty() && seen_lit.iter().all(|&g| first[g].sum_real == [0.0; 3]) {
        return Err(Error::input(
            &rec.owned.desc.path,
            "the panorama is 0 over every group's pure pixels, though the scene's light reaches them: no material can be recovered (are the views' images black, or their exposure wrong?)",
        ));
    }
    Ok(())
}

/// What stage 1 reads of the scene at a few samples per pixel, for `relume check`: each
/// group's diffuse colour after the iteration (`None` where no pixel sees it or no light
/// reaches it), and the warnings recover would give of its light: groups unlit, and
/// colours held at their bound under a panorama brighter than the lights can make them.
pub(super) struct LightPreview {
    pub colours: Vec<Option<[f64; 3]>>,
    pub warnings: Vec<String>,
    /// Renders spent, the iteration's and the bound's check.
    pub evaluations: u32,
}

/// Runs stage 1's diffuse iteration at `spp` from every group at 0.5 grey and judges the
/// light it finds. Refuses the scene as stage 1 would (no light reaches what the views
/// see; a panorama black over every lit group).
pub(super) fn preview_light(
    rec: &mut Recovery,
    names: &[String],
    spp: u32,
) -> Result<LightPreview, Error> {
    let n_groups = rec.n_groups();
    let all = vec![true; n_groups];
    let iteration = rec.diffuse_iteration(spp, &all, &indicatif::ProgressBar::hidden())?;
    let (first, mut evaluations) = (iteration.first, iteration.evaluations);
    let pure_pixels = pixels::group_counts(&rec.pure, n_groups);
    let unlit = unlit_groups(rec, &first, spp)?;
    refuse_unlit_or_black(rec, &first, &unlit, &pure_pixels)?;
    // The colours' own render, for the bound's check: the iteration's last render was of
    // the colours before its last update.
    let subset = rec.diffuse_subset();
    let fits = rec.evaluate_pixels(&subset, spp, rec.seed, &|_| true)?;
    evaluations += 1;
    let mut colours = vec![None; n_groups];
    let mut warnings = Vec::new();
    let mut too_bright = Vec::new();
    for g in 0..n_groups {
        if let Some(unlit) = &unlit[g] {
            warnings.push(unlit.warning(&names[g]));
        } else if let (true, GroupModel::Diffuse { color }) = (pure_pixels[g] > 0, rec.models[g]) {
            colours[g] = Some(color);
            if let Some((_, worst)) = brighter_at_bound(&rec.models[g], &fits[g]) {
                too_bright.push(format!("'{}' {worst:.2}x", names[g]));
            }
        }
    }
    if !too_bright.is_empty() {
        warnings.push(format!(
            "{} brighter in the panorama than any diffuse colour renders under the scene's lights ({}, with the colour at its bound {}): recover gives a group a lobe where one explains it; for groups that are not glossy, a light's radiance or a view's exposure is likely too low, or a light faces away from the room (its triangles wound the other way)",
            if too_bright.len() == 1 { "1 group reads".to_string() } else { format!("{} groups read", too_bright.len()) },
            too_bright.join(", "),
            diffuse::MAX_DIFFUSE_REFLECTANCE
        ));
    }
    Ok(LightPreview {
        colours,
        warnings,
        evaluations,
    })
}

/// Pixel samples (at least) at which a group that rendered black in the iteration's first
/// step is rendered again before it is called unlit: at the loop's few samples a dim group
/// of a few pixels, lit only by light reflected off other groups, could miss every path.
const UNLIT_CHECK_SAMPLES: u64 = CACHE_MIN_SAMPLES;

/// A group that the scene's lights do not reach: whatever its material, its pixels render
/// black, and the diffuse update, a ratio to the rendered mean, has nothing to scale (it
/// kept its starting colour and went on with an error of 100%).
struct Unlit {
    /// Pixels rendered (the iteration's, at most `DIFFUSE_GROUP_PIXELS`).
    pixels: u32,
    spp: u32,
    /// The panorama's mean over the pixels.
    real_mean: [f64; 3],
}

impl Unlit {
    fn describe(&self) -> String {
        let [r, g, b] = self.real_mean;
        format!(
            "no light of the scene reaches it: its pure pixels render black ({} of them at {} samples per pixel), where the panorama's mean is [{r:.4}, {g:.4}, {b:.4}]",
            self.pixels, self.spp
        )
    }

    fn warning(&self, group: &str) -> String {
        format!(
            "group '{group}': {}; its material is not recovered (are the scene's lights right?)",
            self.describe()
        )
    }
}

/// The samples per pixel at which a group of `pixels` pure pixels, whose error read
/// `error` at `decided_spp`, is first measured again while that error straddles the gate:
/// enough for [`CACHE_MIN_SAMPLES`] in all when that is more (a small group, cheap to
/// measure again either way); for a larger group, only when the error reads above the
/// gate, the next round of a decision within `DECISION_MAX_SAMPLES`
/// ([`fit::next_decision_spp`]). `None` where no round is taken: below the gate the
/// best estimate leaves a lobe less than the gate to gain, and a wall's rounds would only
/// cost (rooms' walls and ceilings at 64 px read 0 +- 0.01-0.04 at stage 1's samples and
/// about 0.01 at 4x: box-diffuse took 5.8 -> 7.5 s measuring them); and where the cap
/// leaves no larger round (a wall at 256 px per face).
///
/// Once only small groups were measured again. At 5% exposure over its lights the living
/// room's desk at 256 px read 0.0188 +- 0.0055 at 32 spp and stayed diffuse on 5 seeds of
/// 6; at 128 spp it reads 0.0183 +- 0.0016 and goes on to stage 2, which finds its lobe
/// (docs/stability.md, "A straddling group measured again").
fn first_remeasure_spp(decided_spp: u32, pixels: u32, error: f64) -> Option<u32> {
    let small = min_samples_spp(decided_spp, pixels, CACHE_MIN_SAMPLES);
    if small > decided_spp {
        return Some(small);
    }
    if error > fit::SPECULAR_GAIN_THRESHOLD {
        fit::next_decision_spp(decided_spp, pixels as usize, fit::DECISION_MAX_SAMPLES)
    } else {
        None
    }
}

/// Group `g`'s stage-1 error `estimate` (of `pixels` pure pixels), measured again alone
/// while it straddles the gate (`SPECULAR_GAIN_THRESHOLD` within `EXCEEDS_SIGMAS` standard
/// errors): first at `first_spp`, then at `fit::next_decision_spp`'s 4x within
/// `DECISION_MAX_SAMPLES`, for at most `DECISION_MAX_ROUNDS` more rounds, each on a fresh
/// seed; the last measurement decides, as a keep-or-reject test's does. Returns it, and
/// its samples per pixel when it is not `estimate` itself. The living room's desk at 128
/// px (836 pixels; s 0.05, roughness 0.06) read 0.0185 +- 0.0048 at 79 spp and stopped at
/// stage 1, where at 64 and 256 px its weak lobe is found.
fn measured_until_it_sides(
    rec: &mut Recovery,
    g: usize,
    pixels: u32,
    first_spp: u32,
    mut estimate: Option<fit::ErrorEstimate>,
) -> Result<(Option<fit::ErrorEstimate>, Option<u32>), Error> {
    let gate = fit::SPECULAR_GAIN_THRESHOLD;
    let mut spp = Some(first_spp);
    let mut measured_at = None;
    for round in 0..=fit::DECISION_MAX_ROUNDS {
        let (Some(e), Some(at)) = (estimate, spp) else {
            break;
        };
        if !e.straddles(gate) {
            break;
        }
        let seed = rec.decision_seed() ^ 0x5A3E ^ ((round as u64) << 32);
        estimate = rec.error_estimate(g, at, seed)?;
        measured_at = Some(at);
        spp = fit::next_decision_spp(at, pixels as usize, fit::DECISION_MAX_SAMPLES);
    }
    Ok((estimate, measured_at))
}

/// The groups that rendered black in `first` (the iteration's first step, at `spp`) and
/// again at [`UNLIT_CHECK_SAMPLES`] pixel samples or more, on the pixels of the iteration.
fn unlit_groups(
    rec: &mut Recovery,
    first: &[fit::GroupFit],
    spp: u32,
) -> Result<Vec<Option<Unlit>>, Error> {
    let black = |f: &fit::GroupFit| f.pixels > 0 && f.sum_rendered == [0.0; 3];
    let suspects: Vec<bool> = first.iter().map(black).collect();
    if !suspects.contains(&true) {
        return Ok(first.iter().map(|_| None).collect());
    }
    let subset: Vec<_> = rec
        .diffuse_subset()
        .into_iter()
        .filter(|p| suspects[p.group as usize])
        .collect();
    let check_spp = min_samples_spp(spp, subset.len() as u32, UNLIT_CHECK_SAMPLES);
    let seed = rec.seed ^ 0x0B1A_C4ED;
    let fits = rec.evaluate_pixels(&subset, check_spp, seed, &|g| suspects[g as usize])?;
    Ok(fits
        .iter()
        .zip(&suspects)
        .map(|(f, &suspect)| {
            (suspect && black(f)).then(|| Unlit {
                pixels: f.pixels,
                spp: check_spp,
                real_mean: f.sum_real.map(|v| v / f.pixels as f64),
            })
        })
        .collect())
}

/// The diffuse refinement, after stage 5: the diffuse groups' colours again, under the
/// specular materials now known, then one Newton step at `POLISH_SPP_FACTOR` times the
/// samples; each colour's samples go to its report (`GroupReport::colour_samples`).
pub(super) fn refine_diffuse_groups(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    spp: u32,
) -> Result<StageReport, Error> {
    let stage_start = Instant::now();
    let active: Vec<bool> = rec
        .models
        .iter()
        .map(|m| matches!(m, GroupModel::Diffuse { .. }))
        .collect();
    let bar = progress_bar(fit::DIFFUSE_MAX_STEPS as u64, "diffuse again");
    // With no group other than diffuse (and no unseen group's stand-in measured since)
    // the scene is stage 1's, whose iteration already stopped at its noise floor: only
    // the polish step below is new (box-diffuse at 256 px: 18 more renders, 35 s, for
    // nothing).
    let all_diffuse = rec.models.iter().all(|m| match m {
        GroupModel::Diffuse { .. } => true,
        GroupModel::Unseen { stand_in } => *stand_in == NEUTRAL_STAND_IN,
        _ => false,
    });
    let mut evaluations = 0;
    if !all_diffuse {
        evaluations += rec.diffuse_iteration(spp, &active, &bar)?.evaluations;
    }
    // The iteration stops at its own noise floor, so each colour carries the noise of one
    // render at the loop's samples (on box-diffuse at effort fast, up to 0.94% between
    // seeds on the smallest group). One more step at POLISH_SPP_FACTOR times the samples,
    // on a fresh seed, replaces most of it.
    // On the iteration's pixels (`DIFFUSE_GROUP_PIXELS` at most per group).
    let polish_spp = POLISH_SPP_FACTOR * spp;
    let polish_seed = rec.seed ^ 0x9011_5400;
    let subset = rec.diffuse_subset();
    let wanted = |g: u16| active[g as usize];
    let (fits, group_spp, renders) = polish_fits(rec, &subset, polish_spp, polish_seed, &active)?;
    evaluations += renders;
    // A Newton step on how every group's render responds to each group's colour (see
    // POLISH_NEWTON_MAX_GROUPS, past which the ratio step is taken).
    // The diffuse groups the polish renders, with their colours.
    let groups: Vec<(usize, [f64; 3])> = (0..fits.len())
        .filter_map(|g| match rec.models[g] {
            GroupModel::Diffuse { color } if active[g] && fits[g].pixels > 0 => Some((g, color)),
            _ => None,
        })
        .collect();
    let indices: Vec<usize> = groups.iter().map(|&(g, _)| g).collect();
    let newton = groups.len() <= POLISH_NEWTON_MAX_GROUPS;
    let steps = if newton {
        let gradients = colour_gradients(rec, &subset, spp, polish_seed, &wanted)?;
        evaluations += 1;
        newton_steps(&indices, &fits, &gradients)
    } else {
        [None, None, None]
    };
    for (k, &(g, color)) in groups.iter().enumerate() {
        let next = core::array::from_fn(|c| match steps[c] {
            Some(ref step) => {
                (color[c] * libm::exp(step[k])).clamp(0.0, diffuse::MAX_DIFFUSE_REFLECTANCE)
            }
            None => diffuse::update(color, &fits[g]).0[c],
        });
        rec.models[g] = GroupModel::Diffuse { color: next };
        reports[g].colour_samples = Some(fits[g].pixels as u64 * group_spp[g] as u64);
    }
    bar.finish_and_clear();
    let step = if newton {
        "Newton step (the groups' responses to each colour measured on common samples)".to_string()
    } else {
        format!("ratio step (more than POLISH_NEWTON_MAX_GROUPS {POLISH_NEWTON_MAX_GROUPS} diffuse groups for a Newton step)")
    };
    Ok(StageReport {
        stage: "diffuse refinement".into(),
        evaluations,
        samples_per_pixel: spp,
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![if all_diffuse {
            format!("every group diffuse, the scene is stage 1's: one {step} at {POLISH_SPP_FACTOR}x the samples, each group's mean from at least POLISH_MIN_SAMPLES {POLISH_MIN_SAMPLES}")
        } else {
            format!("diffuse groups updated again with the specular groups' materials in the scene, then one {step} at {POLISH_SPP_FACTOR}x the samples, each group's mean from at least POLISH_MIN_SAMPLES {POLISH_MIN_SAMPLES}")
        }],
    })
}

/// Every active group's fit for the polish step, over its pixels of `subset` at `spp` on
/// `seed`, the samples per pixel each fit has, and how many renders it took. A small
/// group's mean at the polish's samples per pixel carries the noise of few samples: the
/// living room's 138-pixel pedestal, lit by way of the metal statue above it, had 8832 at
/// effort fast and 64 px, and came out 0.4, 1.1 and 1.9% off on seeds 1-3. So a group
/// with fewer than `POLISH_MIN_SAMPLES` there is rendered alone on its pixels with at
/// least that many, on a seed of its own, as a lobe's colour is polished, and left out of
/// the render of the others (each pixel's samples are its own, so theirs are the same
/// either way). That render counts only when it holds a group.
fn polish_fits(
    rec: &mut Recovery,
    subset: &[pixels::PurePixel],
    spp: u32,
    seed: u64,
    active: &[bool],
) -> Result<(Vec<fit::GroupFit>, Vec<u32>, u32), Error> {
    let subset_pixels = pixels::group_counts(subset, active.len());
    let group_spp: Vec<u32> = (0..active.len())
        .map(|g| {
            if active[g] && subset_pixels[g] > 0 {
                min_samples_spp(spp, subset_pixels[g], POLISH_MIN_SAMPLES)
            } else {
                spp
            }
        })
        .collect();
    let small = |g: usize| group_spp[g] > spp;
    let shared = |g: usize| active[g] && subset_pixels[g] > 0 && !small(g);
    let mut fits = rec.evaluate_pixels(subset, spp, seed, &|h| shared(h as usize))?;
    let mut renders = u32::from((0..active.len()).any(shared));
    for g in (0..active.len()).filter(|&g| small(g)) {
        let seed = rec.seed ^ 0x9011_5A11 ^ g as u64;
        fits[g] = rec.evaluate_pixels(subset, group_spp[g], seed, &|h| h as usize == g)?[g];
        renders += 1;
    }
    Ok((fits, group_spp, renders))
}

/// Every group's fit over `subset` at `spp` on `seed`, with how its render responds to
/// each group's colour, from one render ([`pixels::evaluate_with_colour_gradients`]).
fn colour_gradients(
    rec: &mut Recovery,
    subset: &[pixels::PurePixel],
    spp: u32,
    seed: u64,
    wanted: &(dyn Fn(u16) -> bool + Sync),
) -> Result<Vec<pixels::GradientFit>, Error> {
    let n = rec.n_groups();
    rec.with_pixels(subset, spp, seed, |pool, scene, observed, settings| {
        pixels::evaluate_with_colour_gradients(pool, scene, observed, settings, n, wanted)
    })
}

/// The polish's Newton step per channel: the change of each group's log colour (in the
/// order of `groups`) that brings every group's rendered mean to the panorama's, from the
/// log ratios of `fits` and the response matrix `J[g][h] = d ln R_g / d ln rho_h` of
/// `gradients` (group `g`'s summed derivatives over its summed render). `None` for a
/// channel whose matrix cannot be inverted or whose step is not finite; the caller then
/// takes the plain ratio step.
fn newton_steps(
    groups: &[usize],
    fits: &[fit::GroupFit],
    gradients: &[pixels::GradientFit],
) -> [Option<Vec<f64>>; 3] {
    core::array::from_fn(|c| {
        let log = |v: f64| (v > 0.0).then(|| libm::log(v));
        let mut jacobian = vec![vec![0.0; groups.len()]; groups.len()];
        for (row, &g) in groups.iter().enumerate() {
            let at = gradients.get(g)?;
            let rendered = at.fit.sum_rendered[c];
            if rendered.is_nan() || rendered <= 0.0 {
                return None;
            }
            for (col, &h) in groups.iter().enumerate() {
                jacobian[row][col] = at.gradient.get(h)?[c] / rendered;
            }
        }
        let inverse = super::uncertainty::invert(&jacobian)?;
        let ratios: Vec<f64> = groups
            .iter()
            .map(|&g| log(fits[g].mean_ratio()[c]))
            .collect::<Option<_>>()?;
        let step: Vec<f64> = inverse
            .iter()
            .map(|row| row.iter().zip(&ratios).map(|(a, b)| a * b).sum())
            .collect();
        step.iter().all(|v: &f64| v.is_finite()).then_some(step)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_straddling_group_is_measured_again_with_more_samples_within_the_cap() {
        let above = 0.0188;
        // A small group: enough samples in all for its cache, many times stage 1's, on
        // either side of the gate.
        let small = first_remeasure_spp(32, 161, above).unwrap();
        assert_eq!(small, CACHE_MIN_SAMPLES.div_ceil(161) as u32);
        assert!(small as u64 * 161 >= CACHE_MIN_SAMPLES);
        assert_eq!(first_remeasure_spp(32, 161, 0.0), Some(small));
        // A larger one (the desk at 256 px): the next decision round, 4x, within the cap,
        // when its error reads above the gate; none when it reads at or below it.
        let desk = first_remeasure_spp(32, 3742, above).unwrap();
        assert_eq!(desk, 32 * fit::DECISION_SPP_GROWTH);
        assert!(desk as u64 * 3742 <= fit::DECISION_MAX_SAMPLES);
        assert_eq!(first_remeasure_spp(32, 3742, 0.0), None);
        let gate = fit::SPECULAR_GAIN_THRESHOLD;
        assert_eq!(first_remeasure_spp(32, 3742, gate), None);
        // Where 4x passes the cap, as many as it allows, if that still doubles them.
        let capped = first_remeasure_spp(32, 8406, above).unwrap();
        assert_eq!(capped as u64, fit::DECISION_MAX_SAMPLES / 8406);
        assert!(capped >= 2 * 32);
        // A wall, whose first measurement already holds about as many as the cap: none.
        assert_eq!(first_remeasure_spp(32, 129_043, above), None);
    }

    /// A group's fit over one pixel: the panorama's value and the render's, grey.
    fn fit_of(real: f64, rendered: f64) -> fit::GroupFit {
        fit::GroupFit {
            pixels: 1,
            sum_real: [real; 3],
            sum_rendered: [rendered; 3],
            ..Default::default()
        }
    }

    /// Two groups that light each other, each rendering `R_g = a_g rho_0^J[g][0]
    /// rho_1^J[g][1]` with J = [[1.5, 0.8], [0.6, 1.2]], both colours 2% too high: the
    /// Newton step finds the true colours exactly, where the ratio step, group by group,
    /// overshoots to 2.5% and 1.6% too low.
    #[test]
    fn the_polish_step_accounts_for_the_light_groups_pass_each_other() {
        let j = [[1.5, 0.8], [0.6, 1.2]];
        let a = [0.7, 0.4];
        let truth = [0.5, 0.3];
        let render = |rho: [f64; 2], g: usize| {
            a[g] * libm::pow(rho[0], j[g][0]) * libm::pow(rho[1], j[g][1])
        };
        let colour = [truth[0] * 1.02, truth[1] * 1.02];
        let real = [render(truth, 0), render(truth, 1)];
        let fits: Vec<fit::GroupFit> = (0..2).map(|g| fit_of(real[g], render(colour, g))).collect();
        // d R_g / d ln rho_h = J[g][h] R_g, as a render's colour gradient measures it.
        let gradients: Vec<pixels::GradientFit> = (0..2)
            .map(|g| pixels::GradientFit {
                fit: fits[g],
                gradient: (0..2).map(|h| [j[g][h] * render(colour, g); 3]).collect(),
            })
            .collect();
        let steps = newton_steps(&[0, 1], &fits, &gradients);
        for channel in &steps {
            let step = channel.as_ref().expect("an invertible response");
            for g in 0..2 {
                let newton = colour[g] * libm::exp(step[g]);
                assert!(
                    (newton / truth[g] - 1.0).abs() < 1e-9,
                    "group {g}: {newton} for {}",
                    truth[g]
                );
            }
        }
        let plain: Vec<f64> = (0..2)
            .map(|g| diffuse::update([colour[g]; 3], &fits[g]).0[0] / truth[g] - 1.0)
            .collect();
        assert!(
            plain[0] < -0.02 && plain[1] < -0.015,
            "the ratio step: {plain:?}"
        );
    }

    /// A response that tells the groups' colours apart nowhere (a singular matrix), or a
    /// group with no measured response, leaves the caller the ratio step rather than a
    /// step to infinity.
    #[test]
    fn a_singular_response_falls_back_to_the_ratio_step() {
        let fits = vec![fit_of(1.0, 1.1), fit_of(2.0, 2.1)];
        let alike: Vec<pixels::GradientFit> = fits
            .iter()
            .map(|f| pixels::GradientFit {
                fit: *f,
                gradient: vec![f.sum_rendered; 2],
            })
            .collect();
        assert_eq!(newton_steps(&[0, 1], &fits, &alike), [None, None, None]);
        let mut unmeasured = alike.clone();
        unmeasured[0].gradient.clear();
        unmeasured[1].gradient = vec![[2.1, 0.0, 0.0], [0.0; 3]];
        assert_eq!(
            newton_steps(&[0, 1], &fits, &unmeasured),
            [None, None, None]
        );
    }
}
