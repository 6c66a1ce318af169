//! What `report.json` says: per stage and per group, every decision with its threshold and
//! statistic, the errors before and after, evaluations and time.

use std::time::Instant;

use relume_core::fit;
use serde::Serialize;

use super::model::GroupModel;
use super::{uncertainty, Budget};

/// What the report says of one group.
#[derive(Serialize, Clone, Debug)]
pub struct GroupReport {
    pub group: String,
    pub kind: String,
    pub pure_pixels: u32,
    pub model: String,
    /// Every decision taken for the group, in order, with the threshold and statistic.
    pub decisions: Vec<String>,
    /// Error of the first all-diffuse render (on the diffuse iteration's pixels, at most
    /// `DIFFUSE_GROUP_PIXELS` of the group).
    pub error_initial: Option<f64>,
    /// Bias-only error after stage 1 (diffuse), which decides whether the group goes on.
    pub error_diffuse: Option<f64>,
    /// Its standard error.
    pub error_diffuse_sigma: Option<f64>,
    /// Relative error of the diffuse and the Ward fit on the group's transport cache.
    pub cache_error_diffuse: Option<f64>,
    pub cache_error_specular: Option<f64>,
    /// Error of the final render of the recovered model.
    pub error_final: Option<f64>,
    /// Stage 3's texture feature on the final render's difference image (see
    /// `relume_core::stages::texture`), for groups with enough pixels.
    pub texture_feature: Option<f64>,
    /// Stage 3's decision statistic (`relume_core::stages::texture::cross_contrast`) under
    /// the best untextured model, for the groups tested: stage 4's anisotropic lobe where
    /// stage 3 tested a group again under it.
    pub texture_contrast: Option<f64>,
    /// The bias-only error of the group's model when stage 2 or 5 decided (see
    /// `pixels::evaluate_cross`; for a group stage 2 left diffuse, stage 1's measurement
    /// where it is the more precise, see `more_precise`).
    pub error_decided: Option<f64>,
    /// Its standard error.
    pub error_decided_sigma: Option<f64>,
    /// The latest measurement of the error of the group's model: stage 1's of its diffuse
    /// fit, then `error_decided`'s (kept by `set_diffuse` and `set_decided` alone).
    #[serde(skip)]
    pub latest_error: Option<fit::ErrorEstimate>,
    /// Every measurement of a model's bias-only error on the group's pixels (stages 1, 2
    /// and 4): each bounds the panorama's noise from above.
    #[serde(skip)]
    pub error_measurements: Vec<fit::ErrorEstimate>,
    /// Every comparison of a simpler with a more complex model (stages 2 and 4).
    pub comparisons: Vec<ComparisonReport>,
    /// Whether stage 2 kept a lobe from its ladder of roughnesses (see `ladder`), whose
    /// shape is coarse.
    pub lobe_from_ladder: bool,
    /// The standard errors of stage 2's lobe's roughness and specularity beyond the
    /// sandwich's (`uncertainty`): the rungs a ladder could not tell from its choice
    /// (`ladder::Spread::sigmas`), or how the cache's proposal moves with the cache's size
    /// (`uncertainty::proposal_size_dependence`).
    #[serde(skip)]
    pub lobe_sigmas: Vec<(&'static str, f64)>,
    /// Pixel samples in all of the render whose mean last set the group's colour (the
    /// colour polish, the diffuse refinement's step); `None` where the loop's renders set
    /// it. The colour's noise is counted at these (`uncertainty::EstimateSamples`).
    #[serde(skip)]
    pub colour_samples: Option<u64>,
    /// For a textured group, the share of its panorama light that the lobe under its map
    /// renders (`texture::lobe_share`): what the map's level depends on.
    pub map_lobe_share: Option<f64>,
    /// For a group of kind "auto": the last choice of its lobe's kind (`kind::choose`).
    pub kind_choice: Option<KindChoice>,
    /// For a group of kind "auto" whose lobe was chosen plastic: the metal proposal it was
    /// chosen over, which stage 4 puts up again under the scene as then known
    /// (`kind::choose_again`).
    #[serde(skip)]
    pub metal_passed_over: Option<GroupModel>,
    /// For a textured group: the anisotropic fit of its stand-in that a render favoured and
    /// only the pattern test turned down, under which stage 3 tests it again
    /// (`stage3::test_again_under_anisotropic_lobes`).
    #[serde(skip)]
    pub anisotropic_turned_down: Option<GroupModel>,
    /// Each recovered parameter with its standard error (see `uncertainty`).
    pub uncertainty: Vec<uncertainty::ParameterUncertainty>,
    /// What the stages that work group by group spent on this group, in the order they
    /// ran: where a stage's time went (see `Laps`).
    pub work: Vec<GroupWork>,
}

/// The evaluations and wall time one stage spent on one group.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct GroupWork {
    pub stage: String,
    pub evaluations: u32,
    pub seconds: f64,
}

impl GroupReport {
    /// An empty report for group `group` of kind `kind`, filled in as the stages run.
    pub(super) fn new(group: &str, kind: &str) -> Self {
        GroupReport {
            group: group.into(),
            kind: kind.into(),
            pure_pixels: 0,
            model: String::new(),
            decisions: Vec::new(),
            error_initial: None,
            error_diffuse: None,
            error_diffuse_sigma: None,
            cache_error_diffuse: None,
            cache_error_specular: None,
            error_final: None,
            texture_feature: None,
            texture_contrast: None,
            error_decided: None,
            error_decided_sigma: None,
            latest_error: None,
            error_measurements: Vec::new(),
            comparisons: Vec::new(),
            lobe_from_ladder: false,
            lobe_sigmas: Vec::new(),
            colour_samples: None,
            map_lobe_share: None,
            kind_choice: None,
            metal_passed_over: None,
            anisotropic_turned_down: None,
            uncertainty: Vec::new(),
            work: Vec::new(),
        }
    }

    /// Adds work of `stage` on this group to what the stage has already spent on it.
    fn add_work(&mut self, stage: &str, evaluations: u32, seconds: f64) {
        match self.work.iter_mut().find(|w| w.stage == stage) {
            Some(w) => {
                w.evaluations += evaluations;
                w.seconds += seconds;
            }
            None => self.work.push(GroupWork {
                stage: stage.into(),
                evaluations,
                seconds,
            }),
        }
    }

    /// Records stage 1's measurement of the diffuse fit's error.
    pub(super) fn set_diffuse(&mut self, estimate: Option<fit::ErrorEstimate>) {
        self.error_diffuse = estimate.map(|e| e.error);
        self.error_diffuse_sigma = estimate.map(|e| e.sigma);
        self.error_measurements.extend(estimate);
        self.latest_error = estimate;
    }

    /// Records the bias-only error of the model a stage decided on.
    pub(super) fn set_decided(&mut self, estimate: fit::ErrorEstimate) {
        self.error_decided = Some(estimate.error);
        self.error_decided_sigma = Some(estimate.sigma);
        self.latest_error = Some(estimate);
    }

    /// The decision that settled the group's model, for a one-line summary: the last one
    /// of a stage that sets models (1, 2, 4 and 5; stage 3 only sends groups on to 4 and
    /// 5, and a stage's search, ladder or race and the colour polish are steps within or
    /// after one). The last decision when there is none.
    pub fn settling_decision(&self) -> Option<&str> {
        const SETTING: [&str; 4] = ["stage 1:", "stage 2:", "stage 4:", "stage 5:"];
        self.decisions
            .iter()
            .rev()
            .find(|d| SETTING.iter().any(|stage| d.starts_with(stage)))
            .or(self.decisions.last())
            .map(String::as_str)
    }

    /// Records a comparison of two models, and both errors it measured.
    pub(super) fn add_comparison(&mut self, report: ComparisonReport, c: &fit::ModelComparison) {
        self.comparisons.push(report);
        self.error_measurements
            .extend([c.simple_estimate(), c.complex_estimate()]);
    }
}

/// Where a group of kind "auto" had its lobe's kind chosen: the stage (2 or 4) and the
/// relative errors of its best plastic and metal fits on its transport cache there.
#[derive(Serialize, Clone, Copy, Debug, PartialEq)]
pub struct KindChoice {
    pub stage: u32,
    pub cache_errors: [f64; 2],
}

/// One keep-or-reject comparison of two models of a group ([`fit::ModelComparison`]).
#[derive(Serialize, Clone, Debug)]
pub struct ComparisonReport {
    pub stage: String,
    pub simple: String,
    pub complex: String,
    pub error_simple: f64,
    pub error_complex: f64,
    /// `error_simple - error_complex`.
    pub gain: f64,
    /// The gain's standard error.
    pub gain_sigma: f64,
    /// The relative error the complex model accounts for, `sqrt(error_simple^2 -
    /// error_complex^2)` as measured: what the threshold is held against.
    pub effect: f64,
    pub z: f64,
    /// The z the gain needed: `fit::gain_significance` of the pixels compared.
    pub z_needed: f64,
    /// What the measurement said: the complex model passed the keep rule.
    pub passed_test: bool,
    /// What was kept: `passed_test`, unless something after it took the complex model
    /// off (stage 4's pattern test: a picture's lobe that follows the picture).
    pub kept_complex: bool,
    /// Samples per pixel of the measurement that decided.
    pub samples_per_pixel: u32,
}

/// What the keep-or-reject test asks of comparison `c`, for the decisions' text: the gain
/// threshold and the z its pixels need (`fit::gain_significance`).
pub(super) fn keep_rule(c: &fit::ModelComparison) -> String {
    format!(
        "to account for > SPECULAR_GAIN_THRESHOLD {} of relative error and z >= {:.2} (GAIN_SIGNIFICANCE {}'s level over {} pixels)",
        fit::SPECULAR_GAIN_THRESHOLD,
        c.significance(),
        fit::GAIN_SIGNIFICANCE,
        c.pixels
    )
}

impl ComparisonReport {
    pub(super) fn new(
        stage: &str,
        simple: &str,
        complex: &str,
        c: &fit::ModelComparison,
        samples_per_pixel: u32,
    ) -> Self {
        ComparisonReport {
            stage: stage.into(),
            simple: simple.into(),
            complex: complex.into(),
            error_simple: c.error_simple,
            error_complex: c.error_complex,
            gain: c.gain,
            gain_sigma: c.gain_sigma,
            effect: c.effect(),
            z: c.z(),
            z_needed: c.significance(),
            passed_test: c.favours_complex(),
            kept_complex: c.favours_complex(),
            samples_per_pixel,
        }
    }
}

/// A stage's work group by group, in a loop over the groups: each group's lap runs from
/// its start to the next group's (or to [`Laps::close`]), so it is counted whichever way
/// the group's turn ends. `evaluations` is the stage's running count.
pub(super) struct Laps {
    stage: &'static str,
    open: Option<(usize, Instant, u32)>,
}

impl Laps {
    pub fn new(stage: &'static str) -> Self {
        Laps { stage, open: None }
    }

    /// Ends the open lap and starts group `g`'s.
    pub fn start(&mut self, g: usize, evaluations: u32, reports: &mut [GroupReport]) {
        self.close(evaluations, reports);
        self.open = Some((g, Instant::now(), evaluations));
    }

    /// Ends the open lap, adding its work to its group's report.
    pub fn close(&mut self, evaluations: u32, reports: &mut [GroupReport]) {
        if let Some((g, start, before)) = self.open.take() {
            reports[g].add_work(
                self.stage,
                evaluations.saturating_sub(before),
                start.elapsed().as_secs_f64(),
            );
        }
    }
}

#[derive(Serialize, Debug)]
pub struct StageReport {
    pub stage: String,
    pub evaluations: u32,
    pub samples_per_pixel: u32,
    pub seconds: f64,
    pub notes: Vec<String>,
}

/// One step of stage 1's iteration, so that a reader sees how fast the colours settle
/// (and can time the estimate against a peer's optimiser by the same rule: when it first
/// comes within a given error of the truth).
#[derive(Serialize, Debug, Clone, PartialEq)]
pub struct DiffuseStep {
    /// When the step's update was made, in seconds since the recovery began (reading the
    /// scene and its inspection included).
    pub seconds: f64,
    /// The largest relative change of a colour in the step.
    pub largest_change: f64,
    /// Every group's diffuse reflectance after the step, in the order of `groups`
    /// (`None` for a group the iteration does not move).
    pub reflectances: Vec<Option<[f64; 3]>>,
}

#[derive(Serialize, Debug)]
pub struct RecoverReport {
    pub scene: String,
    pub seed: u64,
    pub budget: Budget,
    pub error_definition: &'static str,
    pub thresholds: serde_json::Value,
    /// An upper bound on the panorama's relative pixel noise: the tightest upper confidence
    /// bound on any well-seen group's bias-only error
    /// (`relume_core::stages::texture::panorama_noise_bound`).
    pub panorama_noise_bound: f64,
    /// The panorama over each light it sees, against the light's declared radiance: the
    /// check of the views' exposure and the lights' radiance (empty where no view sees the
    /// emitting side of a light over a pixel and its four neighbours).
    pub light_readings: Vec<super::calibration::LightReading>,
    /// The final render against the panorama over each view's pure pixels: a view whose
    /// residual lies apart from the others' may have its exposure off.
    pub view_readings: Vec<super::calibration::ViewReading>,
    /// Each view's image against the geometry's groups, as it is and in the other
    /// orientation that fits best: a view in another cube-face convention.
    pub orientation_readings: Vec<super::orientation::OrientationReading>,
    pub stages: Vec<StageReport>,
    /// Stage 1's iteration, step by step.
    pub diffuse_steps: Vec<DiffuseStep>,
    pub groups: Vec<GroupReport>,
    pub warnings: Vec<String>,
    /// The first of `warnings` already printed, before the work (`tell_input_warnings`).
    #[serde(skip)]
    pub warnings_told: usize,
    pub seconds: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_names_the_stage_that_settled_the_model_not_a_later_note() {
        let mut r = GroupReport::new("desk", "plastic");
        assert_eq!(r.settling_decision(), None);
        r.decisions = [
            "stage 1: diffuse error 0.0257 > SPECULAR_GAIN_THRESHOLD: tested for a weak specular",
            "stage 2 search: the cache's proposal stands",
            "stage 2 ladder: the proposal removes -0.0113",
            "stage 2: stays diffuse: the best isotropic fit accounts for 0.0000",
            "stage 3: not tested for texture: some of its objects have no texture coordinates",
            "colour polish: colour scaled by the mean ratio",
        ]
        .map(String::from)
        .to_vec();
        assert_eq!(
            r.settling_decision(),
            Some("stage 2: stays diffuse: the best isotropic fit accounts for 0.0000")
        );
        r.decisions = vec!["uncertainty: no pixel".into()];
        assert_eq!(r.settling_decision(), Some("uncertainty: no pixel"));
    }

    /// Each group is charged the evaluations spent from its start to the next group's,
    /// whichever way its turn ended; two loops of one stage (stage 2's pre-pass and its
    /// fits) add up under the stage's name.
    #[test]
    fn laps_charge_each_group_its_share_of_a_stage() {
        let mut reports = vec![
            GroupReport::new("mirror", "metal"),
            GroupReport::new("desk", "plastic"),
            GroupReport::new("wall", "plastic"),
        ];
        let mut pre_pass = Laps::new("2 isotropic");
        pre_pass.start(0, 0, &mut reports);
        pre_pass.close(3, &mut reports);
        let mut fits = Laps::new("2 isotropic");
        fits.start(1, 3, &mut reports);
        fits.start(0, 10, &mut reports);
        fits.close(14, &mut reports);
        fits.close(20, &mut reports);
        fn spent(r: &GroupReport) -> Vec<(&str, u32)> {
            r.work
                .iter()
                .map(|w| (w.stage.as_str(), w.evaluations))
                .collect()
        }
        assert_eq!(spent(&reports[0]), [("2 isotropic", 3 + 4)]);
        assert_eq!(spent(&reports[1]), [("2 isotropic", 7)]);
        assert!(reports[2].work.is_empty());
        let mut later = Laps::new("uncertainty");
        later.start(1, 0, &mut reports);
        later.close(1, &mut reports);
        assert_eq!(spent(&reports[1]), [("2 isotropic", 7), ("uncertainty", 1)]);
        assert!(reports
            .iter()
            .flat_map(|r| &r.work)
            .all(|w| w.seconds >= 0.0));
    }
}
