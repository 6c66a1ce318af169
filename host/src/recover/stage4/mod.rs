//! Stage 4: an anisotropic Ward lobe for the untextured groups left with more than
//! `DIFFUSE_THRESHOLD` of error after stage 2, and for the uniform stand-ins of textured
//! groups (the paper's textured-anisotropic step). Found as stage 2 finds the isotropic one
//! (`anisotropic`), decided against the best isotropic alternative by a render; a textured
//! group's lobe must also explain a highlight rather than the picture (`pattern`).
//!
//! `run` takes the groups in turn; for each, [`Stage::search`] passes the `gate`, fits the
//! anisotropic lobe, finds the `isotropic_side` it must beat, and `decide`s.

use std::time::Instant;

use glam::Vec3;
use relume_core::fit;
use relume_core::material::Kind;
use relume_core::render::RenderSettings;
use relume_core::stages::anisotropic::Proposal;

use super::cache::GroupCache;
use super::kind::{self, KindFit};
use super::model::GroupModel;
use super::report::Laps;
use super::{
    anisotropic, cache_min_samples, fit_ward, lobe_kinds, pattern, progress_bar, Budget,
    GroupReport, Recovery, StageReport, CACHE_FLOOR_PIXELS, CACHE_MIN_SAMPLES,
};
use crate::error::Error;
use crate::scene_file::GroupKind;
use gate::{diffuse_goes_on, say_why_not_tried, GATE};
use isotropic_side::lobe_of_this_cache;

mod decide;
mod gate;
mod isotropic_side;

/// The stage's name in report.json.
const STAGE: &str = "4 anisotropic";
/// The name in report.json of stage 4 again, for the groups stage 3's test again found
/// untextured (`again_untextured`).
const STAGE_AGAIN: &str = "4 anisotropic again";

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
    let stage = Stage::new(textured, kinds, budget, cache_settings);
    let groups = groups_in(rec, reports, textured);
    say_why_not_tried(rec, reports, textured, &groups);
    let evaluations = stage.search_each(rec, reports, &groups, STAGE)?;
    Ok(StageReport {
        stage: STAGE.into(),
        evaluations,
        samples_per_pixel: stage.verify_spp,
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![format!(
            "untextured groups with more than DIFFUSE_THRESHOLD {} of error left (those stage 2 left diffuse measured again with their colour levelled under the scene as now known, and going on unless below it by EXCEEDS_SIGMAS {} standard errors), and textured groups' isotropic stand-ins: each fitted on a transport cache of at least {} samples (cache_min_samples: CACHE_FLOOR_PIXELS {CACHE_FLOOR_PIXELS} pixels at the effort's cache samples per pixel, and at least CACHE_MIN_SAMPLES {CACHE_MIN_SAMPLES}): colour and specularity in closed form, the lobe (log roughness_u, log roughness_v, direction angle) by a grid and Nelder-Mead, then annealing on renders; decided against the best isotropic fit, and kept anisotropic only if it also beats its own isotropic shadow (the roughnesses' geometric mean), else the shadow is kept",
            fit::DIFFUSE_THRESHOLD,
            fit::EXCEEDS_SIGMAS,
            cache_min_samples(cache_settings.spp),
        )],
    })
}

/// Stage 4 again for `groups`, each back at its model after stage 2 (`after_stage2`): the
/// groups that stage 3's test again found untextured, fitted now as untextured groups.
/// Stage 4 fitted them as textured stand-ins: plastics, whose anisotropic lobe must also
/// pass the pattern test. A brushed metal of kind auto came out an anisotropic plastic
/// (its colour 0.71 / 0.32 / 0), and with another panorama textured-isotropic, its
/// anisotropic fit turned down by the pattern test alone. `textured` no longer holds them.
pub(super) fn again_untextured(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    groups: &[usize],
    after_stage2: &[GroupModel],
    (textured, kinds): (&[bool], &[GroupKind]),
    budget: &Budget,
    cache_settings: &RenderSettings,
) -> Result<Option<StageReport>, Error> {
    if groups.is_empty() {
        return Ok(None);
    }
    let stage_start = Instant::now();
    let stage = Stage::new(textured, kinds, budget, cache_settings);
    for &g in groups {
        rec.models[g] = after_stage2[g];
        reports[g].decisions.push(
            "stage 4 again: untextured: fitted again from stage 2's model as an untextured group"
                .into(),
        );
    }
    let evaluations = stage.search_each(rec, reports, groups, STAGE_AGAIN)?;
    Ok(Some(StageReport {
        stage: STAGE_AGAIN.into(),
        evaluations,
        samples_per_pixel: stage.verify_spp,
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec!["the groups that stage 3's test again found untextured, fitted again from stage 2's model as untextured groups (stage 4 fits a textured stand-in as a plastic, and its anisotropic lobe must pass the pattern test)".into()],
    }))
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

impl<'a> Stage<'a> {
    /// The settings every group's search shares, the loop's samples from `budget`.
    fn new(
        textured: &'a [bool],
        kinds: &'a [GroupKind],
        budget: &'a Budget,
        cache_settings: &'a RenderSettings,
    ) -> Self {
        Stage {
            textured,
            kinds,
            budget,
            cache_settings,
            verify_spp: budget.loop_spp,
        }
    }

    /// [`Stage::search`] for each of `groups` in turn, with a progress bar and each
    /// group's work charged to it under the report's stage `name`; returns the evaluations
    /// spent.
    fn search_each(
        &self,
        rec: &mut Recovery,
        reports: &mut [GroupReport],
        groups: &[usize],
        name: &'static str,
    ) -> Result<u32, Error> {
        let bar = progress_bar(groups.len() as u64, name);
        let mut laps = Laps::new(name);
        let mut evaluations = 0;
        for &g in groups {
            laps.start(g, evaluations, reports);
            evaluations += self.search(rec, &mut reports[g], g)?;
            bar.inc(1);
        }
        laps.close(evaluations, reports);
        bar.finish_and_clear();
        Ok(evaluations)
    }

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
