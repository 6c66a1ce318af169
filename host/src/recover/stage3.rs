//! Stage 3: texture detection on the plastic groups a uniform model leaves measurably
//! unexplained: the noise-free step contrast of `ln(real / rendered)`
//! (`relume_core::stages::texture`), against `TEXTURE_CONTRAST_THRESHOLD`; and the same
//! test again after stage 4 for a textured group whose stand-in took an anisotropic lobe.

use std::time::Instant;

use relume_core::fit;
use relume_core::material::Kind;
use relume_core::stages::texture as texture_stage;

use super::model::GroupModel;
use super::{progress_bar, texture, GroupReport, Recovery, StageReport};
use crate::error::Error;
use crate::scene_file::GroupKind;

/// Stage 3's outcome.
pub(super) struct Stage3 {
    pub report: StageReport,
    /// Which groups are textured (and get a map in stage 5).
    pub textured: Vec<bool>,
    /// The panorama's noise bound the contrasts were corrected by.
    pub noise_bound: f64,
    /// Groups that show a texture no map can be laid over (`unfit_for_a_map`), or that
    /// stage 3 could only judge against their own error.
    pub warnings: Vec<String>,
}

/// What the groups' texture coordinates allow a map, per group (`inspect::Input`).
#[derive(Clone, Copy)]
pub(super) struct Coordinates<'a> {
    /// Every object has them.
    pub mapped: &'a [bool],
    /// Why no map can be laid over them (over no area), if so.
    pub unfit_for_a_map: &'a [Option<String>],
    /// Where its faces lie over the same texels, if they do.
    pub overlapping: &'a [Option<String>],
}

/// Why a group without texture coordinates is not tested for texture.
const NO_COORDINATES: &str =
    "some of its objects have no texture coordinates (vt on every face), which a diffuse map needs";

/// Why stage 3 does not test a group for texture.
enum NotTested {
    /// A plastic with texture coordinates seen in fewer pure pixels than the step
    /// statistic needs (none at all: unseen, which the report's pixel count says).
    FewPixels(u32),
    /// Its model is not one a map lies under (a mirror), said by the stage that set it.
    OtherModel,
    /// Textured models apply to plastic groups (reflectance.md).
    Metal,
    /// A map lies over the OBJ texture coordinates.
    NoCoordinates,
    /// Its error, if measured, is not above `SPECULAR_GAIN_THRESHOLD`: a map can explain
    /// no more error than there is.
    SmallError(Option<fit::ErrorEstimate>),
}

/// Why stage 3 does not test group `g` for texture; `None` when it does. The one place
/// the test's conditions are written: `run` takes the groups it tests from it, and the
/// report's words for the others.
fn why_not_tested(
    rec: &Recovery,
    r: &GroupReport,
    g: usize,
    kinds: &[GroupKind],
    mapped: &[bool],
) -> Option<NotTested> {
    let few = r.pure_pixels < fit::MIN_PIXELS_FOR_TEXTURE;
    // Seen in too few pixels for the statistic, a texture cannot be told from a lobe or
    // a colour: such a group keeps a uniform model (whatever error a picture leaves goes
    // to stage 4's lobe).
    if few && mapped[g] && kinds[g] != GroupKind::Metal {
        return Some(NotTested::FewPixels(r.pure_pixels));
    }
    // A textured group is a plastic; one of kind "auto" is tested whatever kind stage 2
    // gave its lobe: a picture's colours can pass for a metal's tinted highlight
    // (textured's checker at 64 px, seed 1: metal by 0.0034 +- 0.0006, z 5.7), and stage
    // 4 fits it again as a plastic.
    let lobe_kind = match rec.models[g] {
        GroupModel::Isotropic { kind, .. } if kinds[g] != GroupKind::Auto => Some(kind),
        GroupModel::Isotropic { .. } | GroupModel::Diffuse { .. } => None,
        _ => return Some(NotTested::OtherModel),
    };
    if kinds[g] == GroupKind::Metal || lobe_kind == Some(Kind::Metal) {
        return Some(NotTested::Metal);
    }
    if !mapped[g] {
        return Some(NotTested::NoCoordinates);
    }
    // As stage 1 sends a group on: a texture, like a lobe, cannot remove more error than
    // there is (the living room's desk, 0.0141 +- 0.0026 after stage 1, read its missed
    // weak lobe's highlight as a texture).
    let error = r.latest_error;
    if !error.is_some_and(|e| e.exceeds(fit::SPECULAR_GAIN_THRESHOLD)) {
        return Some(NotTested::SmallError(error));
    }
    None
}

impl NotTested {
    /// Stage 3's decision for a group it does not test, if it records one: not for a
    /// group stage 1 settled (stage 1's decision says why), an unseen one, or one whose
    /// model another stage set.
    fn decision(&self, r: &GroupReport) -> Option<String> {
        let decided = r.error_decided.is_some();
        let why = match self {
            NotTested::FewPixels(0) | NotTested::OtherModel => return None,
            NotTested::FewPixels(pixels) => format!(
                "{pixels} pure pixels, fewer than MIN_PIXELS_FOR_TEXTURE {} that the step statistic needs; it keeps a uniform model",
                fit::MIN_PIXELS_FOR_TEXTURE
            ),
            NotTested::Metal if decided => {
                "a metal: textured models apply to plastic groups (reflectance.md)".to_string()
            }
            NotTested::NoCoordinates if decided => NO_COORDINATES.to_string(),
            NotTested::SmallError(Some(e)) if decided => format!(
                "its error {:.4} +- {:.4} is not above SPECULAR_GAIN_THRESHOLD {} by EXCEEDS_SIGMAS {} standard errors, and a map can explain no more error than there is",
                e.error,
                e.sigma,
                fit::SPECULAR_GAIN_THRESHOLD,
                fit::EXCEEDS_SIGMAS
            ),
            _ => return None,
        };
        Some(format!("stage 3: not tested for texture: {why}"))
    }
}

/// Runs stage 3 with renders at [`contrast_spp`] on `seed`, recording each tested group's
/// contrast and decision in `reports`. Groups without texture coordinates (`mapped`
/// false) are not tested; one that shows a texture over coordinates no map can be laid
/// over (`unfit_for_a_map`: over no area) keeps its uniform model, and is warned of.
pub(super) fn run(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    kinds: &[GroupKind],
    coordinates: &Coordinates,
    verify_spp: u32,
    seed: u64,
) -> Result<Stage3, Error> {
    let Coordinates {
        mapped,
        unfit_for_a_map,
        overlapping,
    } = *coordinates;
    let n_groups = reports.len();
    let stage_start = Instant::now();
    let mut evaluations = 0;
    let mut notes = Vec::new();
    let mut tested = Vec::new();
    for (g, r) in reports.iter_mut().enumerate() {
        match why_not_tested(rec, r, g, kinds, mapped) {
            None => tested.push(g),
            Some(why) => r.decisions.extend(why.decision(r)),
        }
    }
    // Each well-seen group's own bound on the panorama's noise; the tightest is the bound.
    let bound_of: Vec<Option<f64>> = reports
        .iter()
        .map(|r| {
            let seen = r.pure_pixels >= fit::MIN_PIXELS_FOR_TEXTURE;
            let measured = r.error_measurements.iter().copied().filter(|_| seen);
            texture_stage::panorama_noise_bound(measured)
        })
        .collect();
    let noise_bound = bound_of
        .iter()
        .flatten()
        .copied()
        .reduce(f64::min)
        .unwrap_or(0.0);
    // Whether group `g`'s own error gives the bound, no other group's as tight: a texture
    // there is then in the bound it is corrected by.
    let bound_is_own = |g: usize| {
        let others = (bound_of.iter().enumerate())
            .filter(|&(h, _)| h != g)
            .filter_map(|(_, b)| *b)
            .reduce(f64::min);
        bound_of[g] == Some(noise_bound) && others.is_none_or(|b| b > noise_bound)
    };
    let mut textured = vec![false; n_groups];
    let mut warnings = Vec::new();
    let bar = progress_bar(tested.len() as u64, "3 textures");
    for g in tested {
        let raw = texture::texture_contrast(rec, g, contrast_spp(verify_spp), contrast_seed(seed))?;
        evaluations += 1;
        bar.inc(1);
        let r = &mut reports[g];
        let Some(raw) = raw else {
            r.decisions
                .push("stage 3: no pair of lit pixels 3 apart; texture not tested".into());
            continue;
        };
        let contrast = texture_stage::noise_corrected_contrast(raw, noise_bound);
        r.texture_contrast = Some(contrast);
        let measured = format!(
            "step contrast {contrast:.4} (measured {raw:.4}, less the panorama's noise bound {noise_bound:.4})"
        );
        if !texture_stage::has_texture_contrast(contrast) {
            let own = texture_stage::has_texture_contrast(raw) && bound_is_own(g);
            r.decisions.push(format!(
                "stage 3: untextured: {measured} <= TEXTURE_CONTRAST_THRESHOLD {}{}",
                fit::TEXTURE_CONTRAST_THRESHOLD,
                if own {
                    "; the bound is this group's own error"
                } else {
                    ""
                }
            ));
            if own {
                warnings.push(format!(
                    "group '{}': its step contrast {raw:.4} would read as a texture (> TEXTURE_CONTRAST_THRESHOLD {}), but the panorama's noise bound it is corrected by is its own error {noise_bound:.4}, no other group of at least MIN_PIXELS_FOR_TEXTURE {} pixels measured lower: stage 3 cannot tell a texture of it from the panorama's noise, and it keeps a uniform model; uniform groups in the views (a wall, a ceiling) give the bound",
                    r.group,
                    fit::TEXTURE_CONTRAST_THRESHOLD,
                    fit::MIN_PIXELS_FOR_TEXTURE
                ));
            }
            continue;
        }
        let decision = format!(
            "stage 3: textured: {measured} > TEXTURE_CONTRAST_THRESHOLD {}",
            fit::TEXTURE_CONTRAST_THRESHOLD
        );
        // A map read at one point (coordinates over no area) would be wrong: the texture
        // is told rather than modelled wrong. Coordinates past [0, 1] are tiles, mapped.
        if let Some(why) = &unfit_for_a_map[g] {
            r.decisions.push(format!(
                "{decision}, but {why}: no map is recovered, and its uniform model stays"
            ));
            warnings.push(format!(
                "group '{}': its pixels show a texture (stage 3's step contrast {contrast:.4} > TEXTURE_CONTRAST_THRESHOLD {}), but {why}: no map is recovered, so its uniform model stays and the texture is left in its error; give it texture coordinates that lay its texture once over [0, 1] for a map",
                r.group,
                fit::TEXTURE_CONTRAST_THRESHOLD
            ));
            continue;
        }
        if let Some(why) = &overlapping[g] {
            warnings.push(format!(
                "group '{}': its pixels show a texture, and {why}",
                r.group
            ));
        }
        textured[g] = true;
        r.decisions.push(decision);
    }
    bar.finish_and_clear();
    notes.push(format!(
        "plastic groups with more than SPECULAR_GAIN_THRESHOLD {} of error left (by EXCEEDS_SIGMAS {} standard errors): textured when the noise-free step contrast of ln(real / rendered) exceeds TEXTURE_CONTRAST_THRESHOLD {}",
        fit::SPECULAR_GAIN_THRESHOLD,
        fit::EXCEEDS_SIGMAS,
        fit::TEXTURE_CONTRAST_THRESHOLD
    ));
    notes.push(format!(
        "the panorama's noise bound {noise_bound:.4}: the tightest upper bound, NOISE_BOUND_SIGNIFICANCE {} standard errors above the measured square, of any error measured on a group of at least MIN_PIXELS_FOR_TEXTURE {} pixels",
        fit::NOISE_BOUND_SIGNIFICANCE,
        fit::MIN_PIXELS_FOR_TEXTURE
    ));
    let report = StageReport {
        stage: "3 texture detection".into(),
        evaluations,
        samples_per_pixel: contrast_spp(verify_spp),
        seconds: stage_start.elapsed().as_secs_f64(),
        notes,
    };
    Ok(Stage3 {
        report,
        textured,
        noise_bound,
        warnings,
    })
}

/// The samples per pixel of a group's step-contrast renders: four times the loop's, and at
/// least `TEXTURE_MIN_SPP` (the log's bias on a noisy highlight).
fn contrast_spp(verify_spp: u32) -> u32 {
    (4 * verify_spp).max(fit::TEXTURE_MIN_SPP)
}

/// The seed of a group's step-contrast renders: the same for stage 3 and for its test
/// again after stage 4, so that the two contrasts differ by the model alone.
fn contrast_seed(seed: u64) -> u64 {
    seed ^ 0x7E57
}

/// Stage 3's test again for every group it called textured whose uniform stand-in stage 4
/// found an anisotropic lobe for (kept, or turned down by the pattern test alone), under
/// that lobe: its best untextured model, which stage 3 could not know. A uniform
/// anisotropic panel reads as a texture under stage 2's isotropic lobe, whose misfit of a
/// narrow anisotropic highlight changes within a few pixels (textured's checker given its
/// mean colour for a map, 64 px: step contrast 0.14 under the isotropic lobe, and it got a
/// 22x22 map). With stage 3's samples, seed and noise bound. Returns the groups no longer
/// textured, whose contrast is not above `TEXTURE_CONTRAST_THRESHOLD` there, and the
/// report of this step when it tested any group. Leaves every model as it was.
pub(super) fn test_again_under_anisotropic_lobes(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    textured: &mut [bool],
    noise_bound: f64,
    verify_spp: u32,
    seed: u64,
) -> Result<(Vec<usize>, Option<StageReport>), Error> {
    let lobe_of = |g: usize, r: &GroupReport| match rec.models[g] {
        m @ GroupModel::Anisotropic { .. } => Some(m),
        _ => r.anisotropic_turned_down,
    };
    let again: Vec<(usize, GroupModel)> = (reports.iter().enumerate())
        .filter(|&(g, _)| textured[g])
        .filter_map(|(g, r)| Some((g, lobe_of(g, r)?)))
        .collect();
    if again.is_empty() {
        return Ok((Vec::new(), None));
    }
    let stage_start = Instant::now();
    let spp = contrast_spp(verify_spp);
    let mut untextured = Vec::new();
    for &(g, lobe) in &again {
        let kept = std::mem::replace(&mut rec.models[g], lobe);
        let raw = texture::texture_contrast(rec, g, spp, contrast_seed(seed));
        rec.models[g] = kept;
        let Some(raw) = raw? else {
            continue;
        };
        let r = &mut reports[g];
        let contrast = texture_stage::noise_corrected_contrast(raw, noise_bound);
        r.texture_contrast = Some(contrast);
        let measured = format!(
            "step contrast {contrast:.4} (measured {raw:.4}, less the panorama's noise bound {noise_bound:.4}) under stage 4's anisotropic lobe{}",
            if kept == lobe { "" } else { ", which the pattern test turned down" }
        );
        if texture_stage::has_texture_contrast(contrast) {
            r.decisions.push(format!(
                "stage 3 again: textured: {measured} > TEXTURE_CONTRAST_THRESHOLD {}",
                fit::TEXTURE_CONTRAST_THRESHOLD
            ));
        } else {
            r.decisions.push(format!(
                "stage 3 again: untextured: {measured} <= TEXTURE_CONTRAST_THRESHOLD {}: what stage 3 read was the anisotropic highlight that the isotropic lobe missed; no map",
                fit::TEXTURE_CONTRAST_THRESHOLD
            ));
            textured[g] = false;
            untextured.push(g);
        }
    }
    let report = StageReport {
        stage: "3 texture detection again".into(),
        evaluations: again.len() as u32,
        samples_per_pixel: spp,
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![format!(
            "the groups stage 3 called textured whose uniform stand-in stage 4 found an anisotropic lobe for (kept, or turned down by the pattern test alone), tested again under it (their best untextured model) with stage 3's samples, seed and noise bound: untextured when the step contrast is no longer above TEXTURE_CONTRAST_THRESHOLD {}",
            fit::TEXTURE_CONTRAST_THRESHOLD
        )],
    };
    Ok((untextured, Some(report)))
}
