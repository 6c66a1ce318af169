//! `relume recover`: the staged recovery of every group's material from the panorama.
//!
//! The host's part: read the scene and the panorama, find each group's pure pixels, run
//! the renders and caches each stage asks for (in parallel, in a fixed partition, so results
//! do not depend on the thread count) and write the results atomically. The decisions and
//! the math are the core's (`relume_core::stages`, `relume_core::fit`).
//!
//! The stages, in order (each its own module here, its decisions in the core's):
//!
//! 1. `stage1`: every group diffuse, `rho_d <- rho_d mean(real) / mean(rendered)`; which
//!    groups are unseen, diffuse, or go on.
//! 2. `stage2`: an isotropic lobe per group that went on, worst-explained first (mirrors
//!    first, so that a mirror is found before it corrupts the others), proposed by its
//!    transport cache and refined on renders; kept only when a render shows it removes
//!    measurably more error than the diffuse model; the mirror test; `ladder` for weak lobes.
//! 3. `stage3`: is what the uniform model leaves a picture?
//! 4. `stage4`: an anisotropic lobe for the groups still poorly explained and for textured
//!    groups' stand-ins (`anisotropic`, `pattern`); then `polish`, the colours of the
//!    groups with a lobe.
//! 5. `texture`: the textured groups' diffuse maps. Diffuse groups are then refined again
//!    under everything found, the scene rendered once more and `output` writes the results
//!    with `report` and `uncertainty`.
//!
//! `pipeline::run` holds that order, step by step.

mod anisotropic;
mod budget;
mod cache;
mod calibration;
mod inspect;
mod joint_step;
mod kind;
mod ladder;
mod model;
mod orientation;
mod output;
mod pattern;
mod pipeline;
mod pixels;
mod polish;
mod recovery;
mod refine;
mod report;
mod seen_outside;
mod stage1;
mod stage2;
mod stage3;
mod stage4;
mod stage5;
mod terms_memo;
mod texture;
mod too_bright;
mod uncertainty;
mod unseen;
mod warnings;

use std::path::PathBuf;

use indicatif::ProgressBar;
use relume_core::fit;
use relume_core::material::Kind;
use relume_core::stages::isotropic::{self, WardFit};

use crate::scene_file::GroupKind;
use budget::{
    cache_min_samples, min_samples_spp, CACHE_FLOOR_PIXELS, CACHE_MIN_SAMPLES, POLISH_MIN_SAMPLES,
    POLISH_NEWTON_MAX_GROUPS, POLISH_SPP_FACTOR,
};
pub use budget::{Budget, Effort, Optimiser};
pub use calibration::NOT_CHECKED as CALIBRATION_NOT_CHECKED;
pub use inspect::{check, CheckReport, GroupSight};
pub use model::GroupModel;
pub use output::{output_files, UNSEEN_TOML};
pub use pipeline::run;
use recovery::{paired_comparison, Recovery};
use report::keep_rule;
pub use report::{ComparisonReport, DiffuseStep, GroupReport, RecoverReport, StageReport};
pub use warnings::FEW_PIXELS;

pub struct RecoverArgs {
    pub scene: PathBuf,
    pub out: PathBuf,
    pub seed: u64,
    pub threads: Option<usize>,
    pub budget: Budget,
    /// Keep at most this many pure pixels of the named group (an even subset): for
    /// studying how recovery degrades as a group is seen in fewer pixels.
    pub limit_group_pixels: Option<(String, u32)>,
    /// Print the warnings about the input (calibration, a view's orientation, views that
    /// see no group) as soon as they are known, before the long work, so that a user can
    /// stop a run on a bad panorama: the command line does; the benches, which perturb the
    /// input on purpose, do not. [`RecoverReport::warnings_told`] counts them.
    pub tell_input_warnings: bool,
}

fn progress_bar(len: u64, what: &str) -> ProgressBar {
    crate::progress::bar(len, what, "")
}

/// The best isotropic Ward fit of a group's cache for one kind: roughness searched
/// globally, reflectances in closed form.
fn fit_ward(
    pool: &rayon::ThreadPool,
    cache: &cache::GroupCache,
    kind: Kind,
) -> (WardFit, f64, u32) {
    fit_ward_by(|alpha| cache::isotropic_fit(pool, cache, kind, alpha))
}

/// [`fit_ward`] with the reflectances at each roughness from `fit_at`.
fn fit_ward_by(mut fit_at: impl FnMut(f64) -> WardFit) -> (WardFit, f64, u32) {
    let mut evaluations = 0;
    let mut best: Option<(WardFit, f64)> = None;
    let mut solve = |alpha: f64| {
        evaluations += 1;
        let fit = fit_at(alpha);
        let sse = fit.sse;
        if best.as_ref().is_none_or(|(b, _)| sse < b.sse) {
            best = Some((fit, alpha));
        }
        sse
    };
    isotropic::minimise_1d(
        &mut solve,
        isotropic::ROUGHNESS_MIN,
        isotropic::ROUGHNESS_MAX,
        isotropic::ROUGHNESS_GRID,
        isotropic::ROUGHNESS_REFINE_STEPS,
        true,
    );
    let (fit, alpha) = best.unwrap_or((
        isotropic::solve_diffuse(&relume_core::stages::isotropic::LinearSums::default()),
        isotropic::ROUGHNESS_MAX,
    ));
    (fit, alpha, evaluations)
}

/// Every group's diffuse colour before stage 1's first step, in each channel. A channel
/// no light of the scene emits in keeps it (`too_bright::unlit_channel_warnings`).
pub(super) const START_COLOR: f64 = 0.5;

/// The kinds of lobe a group of `kind` is fitted with, simpler first.
fn lobe_kinds(kind: GroupKind) -> &'static [Kind] {
    match kind {
        GroupKind::Plastic => &[Kind::Plastic],
        GroupKind::Metal => &[Kind::Metal],
        GroupKind::Auto => &[Kind::Plastic, Kind::Metal],
    }
}

/// The paper's mirror test on an isotropic model: specular part above
/// `MIRROR_SPECULAR_FRACTION` of the reflectance, a sharp lobe, and a reflected colour close
/// to the incident one (an untinted specular reflectance).
fn mirror_test(model: &GroupModel) -> Option<String> {
    let GroupModel::Isotropic { roughness, .. } = *model else {
        return None;
    };
    let (rho_d, rho_s) = model.reflectances();
    let total: f64 = (0..3).map(|c| rho_d[c] + rho_s[c]).sum();
    let spec: f64 = rho_s.iter().sum();
    let fraction = if total > 0.0 { spec / total } else { 0.0 };
    let tint = model::tint(rho_s);
    if fraction > fit::MIRROR_SPECULAR_FRACTION
        && roughness <= fit::MIRROR_MAX_ROUGHNESS
        && tint <= fit::MIRROR_MAX_TINT
    {
        Some(format!(
            "mirror: specular fraction {fraction:.3} > MIRROR_SPECULAR_FRACTION {}, roughness {roughness:.4} <= MIRROR_MAX_ROUGHNESS {}, tint {tint:.3} <= MIRROR_MAX_TINT {}",
            fit::MIRROR_SPECULAR_FRACTION,
            fit::MIRROR_MAX_ROUGHNESS,
            fit::MIRROR_MAX_TINT
        ))
    } else {
        None
    }
}
