//! Stage 4: an anisotropic Ward lobe for the untextured groups left with more than
//! `DIFFUSE_THRESHOLD` of error after stage 2, and for the uniform stand-ins of textured
//! groups (the paper's textured-anisotropic step). Found as stage 2 finds the isotropic one
//! (`anisotropic`), decided against the best isotropic alternative by a render; a textured
//! group's lobe must also explain a highlight rather than the picture (`pattern`).

use std::time::Instant;

use glam::Vec3;
use relume_core::fit;
use relume_core::material::Kind;
use relume_core::render::RenderSettings;
use relume_core::stages::anisotropic::Proposal;

use super::cache::GroupCache;
use super::kind::{self, KindFit};
use super::model::GroupModel;
use super::pixels::PurePixel;
use super::refine::RACE_SIGNIFICANCE;
use super::report::Laps;
use super::{
    anisotropic, cache, fit_ward, fit_ward_by, keep_rule, lobe_kinds, pattern, polish,
    progress_bar, uncertainty, Budget, ComparisonReport, GroupReport, Recovery, StageReport,
    CACHE_MIN_SAMPLES, POLISH_MIN_SAMPLES,
};
use crate::error::Error;
use crate::scene_file::GroupKind;

/// The stage's name in report.json.
const STAGE: &str = "4 anisotropic";

/// What an isotropic alternative to a group's isotropic model (or diffuse one) is worth.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Alternative {
    /// No better: the rival stands.
    Worse,
    /// Better, but not by enough to replace the model kept: only the rival the
    /// anisotropic fit must beat.
    Rival,
    /// Better by enough to replace the model kept, too.
    Replaces,
}

/// The worth of an isotropic alternative to `rival` by their comparison `c`. Against a
/// diffuse rival it needs what stage 2's lobes need (and `explains_highlight`, a picture's
/// pattern test); against an isotropic one any gain makes it the rival, and a gain at
/// `RACE_SIGNIFICANCE` replaces the model kept.
fn isotropic_alternative(
    rival: &GroupModel,
    c: &fit::ModelComparison,
    explains_highlight: impl FnOnce() -> bool,
) -> Alternative {
    match rival {
        GroupModel::Diffuse { .. } if c.favours_complex() && explains_highlight() => {
            Alternative::Replaces
        }
        GroupModel::Diffuse { .. } => Alternative::Worse,
        _ if c.gain > 0.0 && c.z() >= RACE_SIGNIFICANCE => Alternative::Replaces,
        _ if c.gain > 0.0 => Alternative::Rival,
        _ => Alternative::Worse,
    }
}

/// Records that group `g`'s isotropic lobe (`kind`, `specularity`, `roughness`) is one
/// of stage 4's cache's fits: its spread is that cache's proposal's, not stage 2's
/// ladder's.
fn lobe_of_this_cache(
    report: &mut GroupReport,
    rec: &Recovery,
    cache: &GroupCache,
    kind: Kind,
    specularity: f64,
    roughness: f64,
) {
    report.lobe_from_ladder = false;
    report.lobe_sigmas = Vec::from(uncertainty::proposal_size_dependence(
        &rec.pool,
        cache,
        kind,
        specularity,
        roughness,
    ));
}

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
fn levelled_colour(
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
struct Levelled {
    color: [f64; 3],
    /// The pixels its render took (`None`: all the group's) and their samples per pixel.
    subset: Option<Vec<PurePixel>>,
    spp: u32,
    /// What the report says of it.
    said: String,
}

/// How the report names a note on the stage's gate: not `"stage 4:"`, which marks a
/// decision that set the group's model (`GroupReport::settling_decision`).
const GATE: &str = "stage 4 gate";

/// Says, for every untextured group that stage 2 decided and this stage leaves alone, why:
/// its decided error is not above `DIFFUSE_THRESHOLD`, the error left for an anisotropic
/// lobe to explain. Without it a group's route ends at stage 2 with no word on stage 4 (the
/// living room's brushed plate: isotropic, 0.035 left, and anisotropic in truth).
fn say_why_not_tried(
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
fn diffuse_goes_on(
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

/// The groups stage 4 takes, in order: every textured group's stand-in, and every
/// untextured group that stage 2 tried and left above `DIFFUSE_THRESHOLD`.
fn groups_in(rec: &Recovery, reports: &[GroupReport], textured: &[bool]) -> Vec<usize> {
    (0..reports.len())
        .filter(|&g| match rec.models[g] {
            // The paper's textured-anisotropic step, on the untextured stand-in as stage 2
            // fitted it, lobed or not. Its error is the picture's, so no error threshold
            // can say whether it goes on; the comparison's significance decides, on a
            // uniform colour for both sides (a map of one texel per pixel would absorb
            // either lobe's misfit), and the pattern test (`pattern`) that the lobe explains
            // a highlight rather than follows the picture.
            GroupModel::Isotropic { .. } | GroupModel::Diffuse { .. } if textured[g] => true,
            // As the stages: every untextured group that stage 2 tried and left
            // above the threshold, whether it kept the isotropic lobe or stayed diffuse
            // (an anisotropic highlight can be one no isotropic lobe explains better than
            // a colour: cornell's plate, 64 pixels, gains 0.003 from its isotropic fit).
            GroupModel::Isotropic { .. } | GroupModel::Diffuse { .. } => {
                !textured[g] && reports[g].error_decided.unwrap_or(0.0) > fit::DIFFUSE_THRESHOLD
            }
            _ => false,
        })
        .collect()
}

/// Runs stage 4 on the groups it applies to (`textured` from stage 3), recording in
/// `reports` what each group became and why; every cache is traced with
/// `cache_settings`. Leaves each group's model as decided.
pub(super) fn run(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    textured: &[bool],
    kinds: &[GroupKind],
    budget: &Budget,
    cache_settings: &RenderSettings,
) -> Result<StageReport, Error> {
    let stage_start = Instant::now();
    let stage = Stage {
        textured,
        kinds,
        budget,
        cache_settings,
        verify_spp: budget.loop_spp,
    };
    let groups = groups_in(rec, reports, textured);
    say_why_not_tried(rec, reports, textured, &groups);
    let bar = progress_bar(groups.len() as u64, STAGE);
    let mut laps = Laps::new(STAGE);
    let mut evaluations = 0;
    for g in groups {
        laps.start(g, evaluations, reports);
        evaluations += stage.search(rec, &mut reports[g], g)?;
        bar.inc(1);
    }
    laps.close(evaluations, reports);
    bar.finish_and_clear();
    Ok(StageReport {
        stage: STAGE.into(),
        evaluations,
        samples_per_pixel: stage.verify_spp,
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![format!(
            "untextured groups with more than DIFFUSE_THRESHOLD {} of error left (those stage 2 left diffuse measured again with their colour levelled under the scene as now known, and going on unless below it by EXCEEDS_SIGMAS {} standard errors), and textured groups' isotropic stand-ins: each fitted on a transport cache of at least CACHE_MIN_SAMPLES {CACHE_MIN_SAMPLES} samples: colour and specularity in closed form, the lobe (log roughness_u, log roughness_v, direction angle) by a grid and Nelder-Mead, then annealing on renders; decided against the best isotropic fit, and kept anisotropic only if it also beats its own isotropic shadow (the roughnesses' geometric mean), else the shadow is kept",
            fit::DIFFUSE_THRESHOLD,
            fit::EXCEEDS_SIGMAS
        )],
    })
}

/// What every group's search in this stage shares.
struct Stage<'a> {
    textured: &'a [bool],
    kinds: &'a [GroupKind],
    budget: &'a Budget,
    cache_settings: &'a RenderSettings,
    /// Samples per pixel of the loop's renders (`Budget::loop_spp`); the decisions' renders
    /// start at four times as many.
    verify_spp: u32,
}

/// A group whose anisotropic fit is weighed, once the kind of its lobe is chosen.
#[derive(Clone, Copy)]
struct Searched<'c> {
    g: usize,
    cache: &'c GroupCache,
    kind: Kind,
    /// A textured group's picture, which its lobes must explain a highlight over.
    pictured: Option<&'c pattern::TexturedGroup>,
}

/// The isotropic side an anisotropic fit is weighed against.
#[derive(Clone, Copy)]
struct IsotropicSide {
    /// The best isotropic (or diffuse) explanation found, however slight its edge: what
    /// the anisotropic fit must beat.
    rival: GroupModel,
    /// The model the group keeps if the anisotropic fit loses: stage 2's, unless an
    /// alternative measured better at `RACE_SIGNIFICANCE`.
    kept: GroupModel,
    /// Whether `kept` is one of this stage's fits rather than stage 2's.
    replaced: bool,
}

impl Stage<'_> {
    /// Stage 4 for group `g`: whether it goes on, its anisotropic fit, the isotropic side
    /// that fit is weighed against, and the decision, each said in `r`. Leaves the group's
    /// model as decided; returns the evaluations spent.
    fn search(&self, rec: &mut Recovery, r: &mut GroupReport, g: usize) -> Result<u32, Error> {
        let textured = self.textured[g];
        let mut evaluations = 0;
        let mut stage2 = rec.models[g];
        let Some(basis) = anisotropic::tangent_basis(rec, g) else {
            r.decisions.push(format!(
                "{GATE}: not tried: its largest triangle has no tangent plane to orient a lobe in"
            ));
            return Ok(evaluations);
        };
        // A group stage 2 left diffuse is levelled under the scene as now known, and goes
        // on only if its error stays above the threshold there (`diffuse_goes_on`).
        let levelled = match (stage2, textured) {
            (GroupModel::Diffuse { color }, false) => {
                let (levelled, goes_on, n) = diffuse_goes_on(rec, r, g, color, self.verify_spp)?;
                evaluations += n;
                if !goes_on {
                    return Ok(evaluations);
                }
                Some(levelled)
            }
            _ => None,
        };
        let cache = rec.group_cache(g, self.cache_settings)?;
        if textured {
            let (plastic, n) = textured_stand_in_as_plastic(rec, r, g, &cache, stage2);
            evaluations += n;
            stage2 = plastic;
        }
        let kinds_to_try = match stage2 {
            GroupModel::Isotropic { kind, .. } => vec![kind],
            _ if textured => vec![Kind::Plastic],
            _ => lobe_kinds(self.kinds[g]).to_vec(),
        };
        // A textured group's lobe is fitted on a uniform stand-in, whose misfit is the
        // picture: the lobe must explain a highlight, not follow the picture.
        let pictured = match textured {
            true => Some(pattern::TexturedGroup::new(rec, &cache, basis)?),
            false => None,
        };
        if let Some(pictured) = &pictured {
            evaluations += pictured.lobes();
            stage2 = stand_in_lobe_tested(rec, r, g, pictured, stage2);
        }
        // The anisotropic side as stage 2 found the isotropic one: the cache proposes
        // (reflectances in closed form, the lobe by grid and simplex), annealing on
        // renders refines, a race on fresh samples chooses.
        let (chosen, n) = self.propose(rec, r, g, &cache, basis, &kinds_to_try)?;
        evaluations += n;
        let Some(KindFit {
            kind,
            fit: proposal,
            ..
        }) = chosen
        else {
            return Ok(evaluations);
        };
        let refined = anisotropic::anneal_anisotropic(
            rec,
            g,
            kind,
            &proposal,
            basis,
            (self.verify_spp, self.budget.anneal_levels),
        )?;
        evaluations += refined.evaluations;
        if let Some(race) = &refined.race {
            r.decisions
                .push(format!("stage 4 search: {}", race.describe()));
        }
        // A diffuse rival's colour is stage 1's, before any polish, and each fit on the
        // cache brings a level of its own: cornell's ceiling (seed 3), its stage-1 colour
        // 3.6% dark, took a weak lobe at the bound (s 0.035, roughness 0.3) on its level
        // alone. So the lobes are weighed against the diffuse model levelled by the colour
        // polish's step (`diffuse_goes_on`, at the top); the colour kept is still stage
        // 1's, which the diffuse refinement after stage 5 takes up.
        let start = IsotropicSide {
            rival: levelled.map_or(stage2, |color| GroupModel::Diffuse { color }),
            kept: stage2,
            replaced: false,
        };
        let searched = Searched {
            g,
            cache: &cache,
            kind,
            pictured: pictured.as_ref(),
        };
        let isotropic = self.isotropic_side(rec, r, &searched, start, refined.model)?;
        evaluations += isotropic.evaluations;
        let mut side = isotropic.side;
        if let Some((metal, n)) = self.metal_again(rec, r, g, &cache, side.kept, isotropic.error)? {
            evaluations += n;
            if let Some(metal) = metal {
                side = IsotropicSide {
                    rival: metal,
                    kept: metal,
                    replaced: true,
                };
            }
        }
        if let (
            true,
            GroupModel::Isotropic {
                kind,
                specularity,
                roughness,
                ..
            },
        ) = (side.replaced, side.kept)
        {
            // The lobe kept is one of this cache's fits (or the anisotropic fit's, on the
            // same cache).
            lobe_of_this_cache(r, rec, &cache, kind, specularity, roughness);
        }
        let comparison = rec.compare_models(
            g,
            (side.rival, refined.model),
            4 * self.verify_spp,
            &mut evaluations,
        )?;
        rec.models[g] = side.kept;
        let Some(comparison) = comparison else {
            return Ok(evaluations);
        };
        let n = self.decide(rec, r, &searched, side, refined.model, comparison)?;
        Ok(evaluations + n)
    }

    /// The anisotropic lobe the cache proposes for each kind in `kinds`, and the one
    /// chosen to go on (`kind::choose`; `None`: none); also the evaluations spent.
    fn propose(
        &self,
        rec: &mut Recovery,
        r: &mut GroupReport,
        g: usize,
        cache: &GroupCache,
        basis: (Vec3, Vec3),
        kinds: &[Kind],
    ) -> Result<(Option<KindFit<Proposal>>, u32), Error> {
        let mut evaluations = 0;
        let mut fits = Vec::new();
        for &kind in kinds {
            let (proposal, n) = anisotropic::propose_from_cache(&rec.pool, cache, kind, basis)?;
            evaluations += n;
            fits.push(KindFit {
                kind,
                cache_error: proposal.fit.relative_error,
                model: anisotropic::proposed_model(kind, &proposal, basis),
                fit: proposal,
            });
        }
        let (chosen, n) = kind::choose(rec, g, fits, (4, 4 * self.verify_spp), r)?;
        Ok((chosen, evaluations + n))
    }

    /// The isotropic side, from `start`: stage 2's fit, unless one of this cache's
    /// isotropic fits (the scene's other materials are better known now) or the
    /// anisotropic fit's own shadow (roughness sqrt(u v)) measures better. The anisotropic
    /// fit is weighed against the better of them (`rival`) however slight its edge, so
    /// that it wins only over the best isotropic explanation; but if it loses, the
    /// isotropic model kept (`kept`) changes only when a render shows the alternative
    /// better at `RACE_SIGNIFICANCE`, as the race's incumbent does: glossy's steel box on
    /// seed 4 took the shadow's s 0.80, roughness 0.086 (truth 0.95, 0.14) over stage 2's
    /// 0.90, 0.10 on a gain of 0.0015 +- 0.0020.
    fn isotropic_side(
        &self,
        rec: &mut Recovery,
        r: &mut GroupReport,
        searched: &Searched,
        start: IsotropicSide,
        anisotropic_fit: GroupModel,
    ) -> Result<IsotropicFits, Error> {
        let Searched {
            g,
            cache,
            kind,
            pictured,
        } = *searched;
        let mut evaluations = 0;
        let (iso, alpha, n) = fit_ward(&rec.pool, cache, kind);
        evaluations += n;
        let on_cache = GroupModel::Isotropic {
            kind,
            color: iso.color,
            specularity: iso.specularity,
            roughness: alpha,
        };
        // The same fit on the sums across two halves of each pixel's samples: free of the
        // dilution the samples' noise puts into the plain sums (which trades specularity
        // for a sharper lobe), but no sum of squares, so where a lobe is weak it can run
        // to a bound; only ever a challenger, which a render must show better. Glossy's
        // steel box on seed 4 (64 px): the plain fit s 0.80, roughness 0.087, this one
        // 0.92, 0.113 at z 4.8 over it (truth 0.95, 0.14).
        let (across, across_alpha, n) =
            fit_ward_by(|alpha| cache::isotropic_fit_across_halves(&rec.pool, cache, kind, alpha));
        evaluations += n;
        let across_halves = (across.specularity > 0.0 && across.specularity <= 1.0).then_some(
            GroupModel::Isotropic {
                kind,
                color: across.color,
                specularity: across.specularity,
                roughness: across_alpha,
            },
        );
        let mut side = start;
        for (what, alternative) in [
            ("the isotropic fit on this cache", Some(on_cache)),
            (
                "the isotropic fit across the halves of this cache's samples",
                across_halves,
            ),
            (
                "the anisotropic fit's isotropic shadow",
                anisotropic::isotropic_projection(anisotropic_fit),
            ),
        ] {
            // A fit of no lobe (specularity 0) is the diffuse model of its colour.
            let Some(alternative) = alternative.filter(GroupModel::has_lobe) else {
                continue;
            };
            let Some((c, spp)) = rec.compare_models(
                g,
                (side.rival, alternative),
                4 * self.verify_spp,
                &mut evaluations,
            )?
            else {
                continue;
            };
            // Between two isotropic fits the better one; a group stage 2 left diffuse
            // takes a lobe here only as stage 2 would have kept one (significance).
            // A picture's lobe must also explain a highlight rather than the picture.
            let verdict = isotropic_alternative(&side.rival, &c, || {
                pictured
                    .and_then(|p| p.isotropic(&rec.pool, kind))
                    .is_none_or(|t| t.passes())
            });
            if verdict == Alternative::Worse {
                continue;
            }
            let measured = format!(
                "{what} measures better than the {} model: it removes {:.4} +- {:.4} more relative error in a render at {spp} spp (z {:.1})",
                side.rival.name(),
                c.gain,
                c.gain_sigma,
                c.z()
            );
            side.rival = alternative;
            let decision = match (verdict, alternative) {
                (
                    Alternative::Replaces,
                    GroupModel::Isotropic {
                        specularity,
                        roughness,
                        ..
                    },
                ) => {
                    side.kept = alternative;
                    side.replaced = true;
                    format!("stage 4: {measured}, and replaces it (s {specularity:.4}, roughness {roughness:.4})")
                }
                _ => format!(
                    "stage 4: {measured}: the anisotropic fit is weighed against it, but short of RACE_SIGNIFICANCE {RACE_SIGNIFICANCE} it does not replace the model kept"
                ),
            };
            r.decisions.push(decision);
        }
        Ok(IsotropicFits {
            side,
            error: iso.relative_error,
            evaluations,
        })
    }

    /// Kind "auto": a plastic lobe whose group came on to this stage (more than
    /// DIFFUSE_THRESHOLD of error left) may be a metal's highlight that stage 2 could not
    /// tell apart on its proposals, whose colours were fitted under the scene as it was
    /// then (glossy's steel box: 10% bright). So the metal stage 2 passed over, its colour
    /// levelled, is weighed against `kept` once more (`kind::choose_again`, with the
    /// cache's `plastic_error` beside the metal's). `None` where that does not apply, else
    /// the metal when it is chosen, and the evaluations spent.
    fn metal_again(
        &self,
        rec: &mut Recovery,
        r: &mut GroupReport,
        g: usize,
        cache: &GroupCache,
        kept: GroupModel,
        plastic_error: f64,
    ) -> Result<Option<(Option<GroupModel>, u32)>, Error> {
        let (
            GroupKind::Auto,
            false,
            GroupModel::Isotropic {
                kind: Kind::Plastic,
                ..
            },
            Some(GroupModel::Isotropic {
                kind: Kind::Metal,
                color,
                specularity,
                roughness,
            }),
        ) = (self.kinds[g], self.textured[g], kept, r.metal_passed_over)
        else {
            return Ok(None);
        };
        let mut evaluations = 0;
        let (metal_fit, _, n) = fit_ward(&rec.pool, cache, Kind::Metal);
        evaluations += n;
        let metal = |color| GroupModel::Isotropic {
            kind: Kind::Metal,
            color,
            specularity,
            roughness,
        };
        let Levelled {
            color: levelled,
            said: levelling,
            ..
        } = levelled_colour(
            rec,
            g,
            metal(color),
            color,
            (self.verify_spp, r.pure_pixels),
        )?;
        evaluations += 1;
        let levelled_by = format!("its colour {levelling}");
        let (chosen, n) = kind::choose_again(
            rec,
            g,
            (kept, metal(levelled)),
            [plastic_error, metal_fit.relative_error],
            (4 * self.verify_spp, &levelled_by),
            r,
        )?;
        Ok(Some((chosen, evaluations + n)))
    }

    /// The decision between the isotropic side and the anisotropic fit `refined`, by their
    /// comparison `(c, decision_spp)` (a render at `decision_spp`): for a textured group the
    /// anisotropic gain must also come from a highlight, and a fit that beats the rival
    /// must also beat its own isotropic shadow. Sets the group's model where the decision
    /// changes it from `side.kept`, says why in `r`; returns the evaluations spent.
    fn decide(
        &self,
        rec: &mut Recovery,
        r: &mut GroupReport,
        searched: &Searched,
        side: IsotropicSide,
        refined: GroupModel,
        (c, decision_spp): (fit::ModelComparison, u32),
    ) -> Result<u32, Error> {
        let Searched {
            g,
            cache,
            kind,
            pictured,
        } = *searched;
        let IsotropicSide { rival, kept, .. } = side;
        let mut evaluations = 0;
        // For a textured group, the anisotropic gain must also come from a highlight.
        let over_isotropic = matches!(rival, GroupModel::Isotropic { .. });
        let pattern = match (pictured, c.favours_complex()) {
            (Some(p), true) => p.anisotropic(&rec.pool, kind, over_isotropic),
            _ => None,
        };
        // An anisotropic fit that beats the rival must also beat its own isotropic shadow
        // (the same colour and specularity, the roughnesses' geometric mean): otherwise
        // its gain is the lobe's size and colour, not its shape (glossy's gold sphere at
        // 64 px, seed 4: roughness_u 0.0803 against roughness_v 0.0794, kept
        // anisotropic at z 7.1 over stage 2's lobe).
        let passes =
            c.favours_complex() && refined.has_lobe() && pattern.is_none_or(|t| t.passes());
        let shape = match anisotropic::isotropic_projection(refined) {
            Some(shadow) if passes => rec
                .compare_models(g, (shadow, refined), 4 * self.verify_spp, &mut evaluations)?
                .map(|(s, spp)| (shadow, s, spp)),
            _ => None,
        };
        let shape_shown = shape.is_none_or(|(_, s, _)| s.favours_complex());
        let mut report = ComparisonReport::new(
            "4 anisotropic",
            rival.name(),
            refined.name(),
            &c,
            decision_spp,
        );
        report.kept_complex &= passes && shape_shown;
        r.add_comparison(report, &c);
        if let Some((_, s, spp)) = shape {
            let mut report =
                ComparisonReport::new("4 anisotropic shape", "isotropic", "anisotropic", &s, spp);
            report.kept_complex &= shape_shown;
            r.add_comparison(report, &s);
        }
        let measured = format!(
            "accounts for {:.4} of relative error (removes {:.4} +- {:.4}) in a render at {decision_spp} spp (z {:.1}; {} {:.4}, anisotropic {:.4})",
            c.effect(),
            c.gain,
            c.gain_sigma,
            c.z(),
            rival.name(),
            c.error_simple,
            c.error_complex
        );
        if let Some(test) = pattern.filter(|t| !t.passes()) {
            r.decisions.push(format!(
                "stage 4: stays {}: the anisotropic fit {measured}, but its gain follows the picture, not a highlight: {}",
                kept.name(),
                test.describe()
            ));
        } else if let (true, Some((shadow, s, spp))) = (passes && !shape_shown, shape) {
            let GroupModel::Isotropic {
                kind,
                specularity,
                roughness,
                ..
            } = shadow
            else {
                return Ok(evaluations);
            };
            r.decisions.push(format!(
                "stage 4: isotropic (s {specularity:.4}, roughness {roughness:.4}), the anisotropic fit's shadow: the anisotropic fit {measured}, but not for its shape: against its isotropic shadow it removes {:.4} +- {:.4} in a render at {spp} spp (z {:.1}; needs {})",
                s.gain,
                s.gain_sigma,
                s.z(),
                keep_rule(&s),
            ));
            rec.models[g] = shadow;
            r.set_decided(s.simple_estimate());
            lobe_of_this_cache(r, rec, cache, kind, specularity, roughness);
        } else if let (
            true,
            GroupModel::Anisotropic {
                roughness_u,
                roughness_v,
                direction: d,
                ..
            },
        ) = (passes, refined)
        {
            if let Some(test) = pattern {
                r.decisions.push(format!(
                    "stage 4: the anisotropic gain explains a highlight: {}",
                    test.describe()
                ));
            }
            let shape_said = shape.map_or(String::new(), |(_, s, spp)| {
                format!(
                    "; and for its shape: against its isotropic shadow it removes {:.4} +- {:.4} in a render at {spp} spp (z {:.1})",
                    s.gain,
                    s.gain_sigma,
                    s.z()
                )
            });
            r.decisions.push(format!(
                "stage 4: anisotropic (roughness_u {roughness_u:.4}, roughness_v {roughness_v:.4}, direction [{:.3}, {:.3}, {:.3}]) {measured}: {}{shape_said}",
                d[0], d[1], d[2],
                keep_rule(&c),
            ));
            rec.models[g] = refined;
            r.set_decided(c.complex_estimate());
        } else if c.favours_complex() && !refined.has_lobe() {
            r.decisions.push(format!(
                "stage 4: stays {}: the best anisotropic fit {measured}, but it has no lobe (specularity 0): its gain is its colour's, which the colour polish takes up",
                kept.name(),
            ));
        } else {
            r.decisions.push(format!(
                "stage 4: stays {}: the best anisotropic fit {measured}: needs {}",
                kept.name(),
                keep_rule(&c),
            ));
        }
        Ok(evaluations)
    }
}

/// The isotropic side a stage-4 search found ([`Stage::isotropic_side`]).
struct IsotropicFits {
    side: IsotropicSide,
    /// The relative error of the isotropic fit on the cache, of the kind searched.
    error: f64,
    evaluations: u32,
}

/// A textured group is a plastic (reflectance.md, "Textures"): where stage 2 gave a group
/// of kind "auto" a metal lobe, it is fitted again as a plastic's on its cache. Returns the
/// stand-in's model (set as the group's) and the evaluations spent.
fn textured_stand_in_as_plastic(
    rec: &mut Recovery,
    r: &mut GroupReport,
    g: usize,
    cache: &GroupCache,
    stage2: GroupModel,
) -> (GroupModel, u32) {
    let GroupModel::Isotropic {
        kind: Kind::Metal, ..
    } = stage2
    else {
        return (stage2, 0);
    };
    let (iso, alpha, n) = fit_ward(&rec.pool, cache, Kind::Plastic);
    let plastic = GroupModel::Isotropic {
        kind: Kind::Plastic,
        color: iso.color,
        specularity: iso.specularity,
        roughness: alpha,
    };
    rec.models[g] = plastic;
    r.decisions.push(format!(
        "stage 4: textured, so a plastic: stage 2's metal lobe fitted again as a plastic's on its cache (s {:.4}, roughness {alpha:.4})",
        iso.specularity
    ));
    (plastic, n)
}

/// A textured group's stand-in with an isotropic lobe keeps it only if the lobe explains a
/// highlight rather than follows the picture (`pattern`); otherwise the stand-in goes on
/// diffuse, as one stage 2 left diffuse. Returns the stand-in's model (set as the group's).
fn stand_in_lobe_tested(
    rec: &mut Recovery,
    r: &mut GroupReport,
    g: usize,
    pictured: &pattern::TexturedGroup,
    stage2: GroupModel,
) -> GroupModel {
    let GroupModel::Isotropic { kind, .. } = stage2 else {
        return stage2;
    };
    let Some(test) = pictured.isotropic(&rec.pool, kind) else {
        return stage2;
    };
    if test.passes() {
        r.decisions.push(format!(
            "stage 4: the stand-in's isotropic lobe explains a highlight: {}",
            test.describe()
        ));
        return stage2;
    }
    let diffuse = GroupModel::Diffuse {
        color: pictured.diffuse_color(),
    };
    rec.models[g] = diffuse;
    // Stage 2's comparison kept a lobe that is no longer there.
    for c in r
        .comparisons
        .iter_mut()
        .filter(|c| c.stage.starts_with('2'))
    {
        c.kept_complex = false;
    }
    r.decisions.push(format!(
        "stage 4: the stand-in's isotropic lobe follows the picture, not a highlight; the stand-in is diffuse: {}",
        test.describe()
    ));
    diffuse
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A comparison of errors 0.1 and `0.1 - gain`, its squared gain and sigma consistent.
    fn comparison(gain: f64, gain_sigma: f64) -> fit::ModelComparison {
        let (simple, complex) = (0.1, 0.1 - gain);
        fit::ModelComparison {
            pixels: 400,
            error_simple: simple,
            error_complex: complex,
            squared_sigma_simple: 0.0,
            squared_sigma_complex: 0.0,
            gain,
            gain_sigma,
            squared_gain: simple * simple - complex * complex,
            squared_gain_sigma: gain_sigma * (simple + complex),
        }
    }

    #[test]
    fn an_isotropic_alternative_replaces_the_model_kept_only_at_race_significance() {
        let lobe = GroupModel::Isotropic {
            kind: Kind::Metal,
            color: [0.6; 3],
            specularity: 0.9,
            roughness: 0.1,
        };
        // Glossy's steel box on seed 4: 0.0015 +- 0.0020 made the shadow the rival only.
        let noise = comparison(0.0015, 0.0020);
        assert_eq!(
            isotropic_alternative(&lobe, &noise, || true),
            Alternative::Rival
        );
        let clear = comparison(0.0850, 0.0109);
        assert_eq!(
            isotropic_alternative(&lobe, &clear, || true),
            Alternative::Replaces
        );
        let worse = comparison(-0.001, 0.002);
        assert_eq!(
            isotropic_alternative(&lobe, &worse, || true),
            Alternative::Worse
        );

        // A diffuse group takes a lobe only as stage 2 would, and a picture's lobe only
        // where it explains a highlight.
        let diffuse = GroupModel::Diffuse { color: [0.5; 3] };
        assert_eq!(
            isotropic_alternative(&diffuse, &noise, || true),
            Alternative::Worse
        );
        assert_eq!(
            isotropic_alternative(&diffuse, &clear, || true),
            Alternative::Replaces
        );
        assert_eq!(
            isotropic_alternative(&diffuse, &clear, || false),
            Alternative::Worse
        );
    }
}
