//! How much work the recovery spends: the effort levels and the knobs they stand for
//! ([`Budget`]), and the floors of samples and caps of pixels that the stages' renders
//! take whatever the effort (a small group gets more samples per pixel, a large one is
//! measured on an even subset of its pixels).

use relume_core::fit;
use serde::Serialize;

/// How much work the recovery may spend: samples per pixel of the renders and caches in
/// the loop, and of the final render that the report's errors come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Effort {
    Fast,
    Default,
    Thorough,
}

impl Effort {
    /// The knobs this effort level stands for.
    pub fn budget(self) -> Budget {
        let (loop_spp, cache_spp, anneal_levels, final_spp) = match self {
            Effort::Fast => (8, 16, 4, 32),
            Effort::Default => (32, 64, 8, 128),
            Effort::Thorough => (128, 256, 16, 512),
        };
        Budget {
            loop_spp,
            cache_spp,
            anneal_levels,
            final_spp,
            optimiser: Optimiser::Annealing,
        }
    }
}

/// The search that refines stage 2's proposal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Optimiser {
    /// Simulated annealing (the paper's global search).
    Annealing,
    /// Nelder-Mead from the same start (a local search, as Boivin & Gagalowicz used).
    NelderMead,
}

/// The knobs that trade time for accuracy. An [`Effort`] level names one setting of them;
/// `relume bench tradeoff` sweeps them one at a time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Budget {
    /// Samples per pixel of the renders inside the loops (stage 1, the searches).
    pub loop_spp: u32,
    /// Samples per pixel of a group's transport cache (stage 2's proposal), and with them
    /// the cache's floor ([`cache_min_samples`]).
    pub cache_spp: u32,
    /// Temperature levels of the annealing (10 proposals each); for Nelder-Mead, the same
    /// number of evaluations.
    pub anneal_levels: u32,
    /// Samples per pixel of the final render that the report's errors come from.
    pub final_spp: u32,
    pub optimiser: Optimiser,
}

/// Stage 5 renders the irradiance at this many times the final render's samples, and at
/// least [`MAP_MIN_SPP`]: a map takes the render's noise into its texels (T = I / E, pixel
/// by pixel), where the final render averages it away; textured groups are small, so this
/// costs little.
pub(super) const MAP_SPP_FACTOR: u32 = 8;

/// The fewest samples per pixel of stage 5's renders. At effort fast (8 x 32 = 256 spp)
/// the irradiance's noise cost the textured scene's maps at 256 px up to 0.6 dB of PSNR;
/// this costs 6 s there (docs/recovery.md, "Map PSNR"). Default and thorough render at
/// least as many already.
pub(super) const MAP_MIN_SPP: u32 = 1024;

/// The diffuse refinement's last step renders at this many times the loop's samples.
pub(super) const POLISH_SPP_FACTOR: u32 = 8;

/// Both polishes set each colour from at least this many samples in all (more per pixel
/// for small groups). A mirror's pixels carry the heavy-tailed noise of the light paths it
/// reflects: the living room's 192-pixel mirror took 10-15% colour errors from the
/// search's renders without it, and +1.9, -1.7, +0.2, -0.9% (seeds 1-4, 64 px) at 2^16
/// samples; at 2^19 +1.1, -0.6, -0.1, -0.3%, for about 0.4 s per small group. A small
/// diffuse group under a metal is as noisy (the living room's pedestal, 138 pixels).
pub(super) const POLISH_MIN_SAMPLES: u64 = 1 << 19;

/// The final views are rendered with at least this many samples per view. The view check
/// (`calibration::view_warnings`) holds each view's mean residual against the others', and
/// at 32 spp a 64-px view's mean carries heavy-tailed noise that the spread of its pixels
/// underestimates: the living room's view px (seed 8, effort fast) read +2.0% +- 0.8%, a
/// false warning, where 256-spp renders of the same model read -0.4% to +0.5%. Over 8
/// seeds that view's mean spreads by 0.75% at 32 spp and 0.4% at 2^19 samples (128 spp).
/// The error images show more of the fit and less of the noise too. At 256 px the
/// effort's samples are already more; about 1 s at 64 px.
pub(super) const VIEW_MIN_SAMPLES: u64 = 1 << 19;

/// The diffuse refinement's last step is a Newton step: besides its render at
/// [`POLISH_SPP_FACTOR`] times the samples, it renders once at the loop's samples with
/// every pixel's derivative with respect to every diffuse group's log colour
/// (`render::radiance_with_colour_gradient`), for the matrix of how every group's mean
/// responds to every colour (`stage1::newton_steps`). The plain ratio step treats each
/// group alone, but groups light each other: on textured at 256 px the iteration ended
/// with the floor, walls and ceiling all 0.1-0.3% bright, each of their renders moved
/// 1.7-2.7 times as much as the colours did together, and the ratio step left them
/// 0.2-0.6% dark (every view of the final render 0.15-0.5% dark, 4-6 standard errors;
/// docs/recovery.md, "The diffuse polish"). The matrix took a render per group, each
/// colour raised 5% on the same samples, before "Colour gradients in one render".
///
/// The most diffuse groups the polish takes a Newton step for: past them, the ratio step.
/// The matrix has a row and a column per group, each measured on the group's share of the
/// polish's pixels; the references have 4-7 diffuse groups, and larger matrices were
/// measured only by finite differences, when a render per group made them costly.
pub(super) const POLISH_NEWTON_MAX_GROUPS: usize = 32;

/// Pure pixels per group that the renders of the diffuse iteration and its polish step
/// take at most: a larger group is rendered on that many, spread evenly over it
/// (`pixels::spread_subset`), at the effort's samples per pixel.
///
/// The update `rho <- rho * mean(real) / mean(rendered)` needs the group's mean, and the
/// mean of `N` pixel samples whose relative deviation per sample is `sigma` has a relative
/// standard error of `sigma / sqrt(N)`. The renders of box-diffuse's groups measured
/// `sigma` 0.33-0.87 at effort fast (a pixel's variance times its samples, over its mean).
/// At `sigma = 1` and effort fast (8 samples per pixel, 2^17 per step) this gives each step
/// of the iteration 0.28% and the polish, from which the colours come (2^20 samples), 0.10%:
/// a third of the 0.3% asked of box-diffuse, and less than its smallest group at 256 px
/// (8407 pixels, under the cap) gets from all its pixels (0.14%); a higher effort takes
/// more samples per pixel on the same pixels. The panorama's own noise averages over the
/// 16384 pixels.
///
/// Groups of up to 16384 pixels (box-diffuse's at 64 px per face have at most 7865) keep
/// every pixel, and their sums keep their bits; at 256 px, where its walls and floor have
/// 60000-130000 pixels, a step costs about a quarter.
pub(super) const DIFFUSE_GROUP_PIXELS: usize = 1 << 14;

/// Pure pixels per group that a measurement of a whole group renders at most, spread
/// evenly over a larger group (`pixels::spread_subset`): stage 1's bias-only errors
/// ([`Recovery::error_estimates`](super::Recovery::error_estimates)) and stage 2's re-fit
/// of a diffuse alternative's colour (`stage2::refit_diffuse`). Without a cap their cost grew with the panorama: at 512 px a
/// face the living room's floor, ceiling, walls and accent wall (213,479-434,499 pixels)
/// made half of stage 1's 40 s, and at 1024 px the re-fit took 25 s for the floor alone.
///
/// Stage 1's error is a ratio of sums over the group's pixels. Spread over 131072 of
/// their pixels, those four groups' errors moved by 0.5-1.6% of themselves (0.0502 to
/// 0.0508 on the floor), a few of the render noise's standard errors; the estimate's
/// standard error counts that part too (`fit::ErrorEstimate::from_sampled_cross_terms`).
/// The re-fit needs a mean, which far fewer pixels would give, as the diffuse iteration's
/// [`DIFFUSE_GROUP_PIXELS`] do; but on those the walls' colours moved enough during stage
/// 2 to turn glossy's white sphere, a weak lobe at the 1% rule, diffuse at 256 px (effort
/// default, seed 1). Every group of the references at 256 px but textured's walls
/// (193,735 pixels, diffuse after stage 1) is under this cap and keeps its bits
/// (docs/recovery.md, "Stage 1's gate on large groups").
pub(super) const MEASURED_GROUP_PIXELS: usize = 1 << 17;

/// A group's transport cache holds at least this many pixel samples whatever the effort
/// (effort fast's floor, [`cache_min_samples`]): a small group's lobe is seen in a few
/// pixels, and a cache of the effort level's samples per pixel alone (16 at fast) cannot
/// tell its specularity and shape from noise (the living room's 20-pixel statue:
/// specularity 0.85 and roughness 0.15 against a true 0.9 and 0.1; 0.92 and 0.10 at this
/// many samples).
pub(super) const CACHE_MIN_SAMPLES: u64 = 1 << 16;

/// A group's transport cache holds at least as many pixel samples as a group of this many
/// pixels would at the effort's cache samples per pixel ([`cache_min_samples`]). At
/// effort fast (16) that is [`CACHE_MIN_SAMPLES`], 2^18 at default (64) and 2^20 at
/// thorough (256).
///
/// Why: a cache holds at most [`MAX_CACHE_PIXELS`], at 128 samples a pixel or more to
/// reach [`CACHE_MIN_SAMPLES`], so a floor that did not grow with the effort left every
/// lobe's cache the same at fast and default (only thorough's 256 spp passed it, on
/// groups of more than 256 pixels). The cache's noise is much of what spreads a strong
/// lobe over the seeds: glossy at 64 px, effort default, seeds 1-5, the gold sphere's
/// specularity spread 2.3% -> 0.9% and the steel box's 3.3% -> 1.6% with this floor
/// (docs/stability.md, "The cache's samples follow the effort").
pub(super) const CACHE_FLOOR_PIXELS: u64 = 1 << 12;

/// The fewest pixel samples a group's transport cache holds when the effort asks
/// `cache_spp` samples per pixel of it: [`CACHE_FLOOR_PIXELS`] pixels' worth, and never
/// fewer than [`CACHE_MIN_SAMPLES`].
pub(super) fn cache_min_samples(cache_spp: u32) -> u64 {
    CACHE_MIN_SAMPLES.max(CACHE_FLOOR_PIXELS.saturating_mul(u64::from(cache_spp)))
}

/// Samples per pixel of a transport cache over `pixels` pixels when the effort asks
/// `cache_spp`: that many, or more so that it holds [`cache_min_samples`].
pub(super) fn cache_pixel_spp(cache_spp: u32, pixels: u32) -> u32 {
    min_samples_spp(cache_spp, pixels, cache_min_samples(cache_spp))
}

/// A group's transport cache holds at most this many of its pixels, so that its
/// [`CACHE_MIN_SAMPLES`] are at least 128 per pixel (512 at default effort's floor). The
/// cache's fits are least squares through the origin on each pixel's estimated parts, and
/// a part's sampling noise biases them (a noisy regressor's coefficient comes out scaled
/// by about `1 / (1 + var / D^2)`): on 1024 pixels at 64 spp, at 256 px per face, glossy's
/// metals were proposed 7-13% off in specularity and the living room's floor, walls and
/// ceiling came out 2.5-8% dark. At 512 pixels and 128 spp the metals are 3-4% off; at 256
/// pixels and 256 spp 1-2%, but a quarter of the pixels loses what only some of them show
/// (the textured checker's anisotropy at 256 px, the steel box's roughness at 64 px).
/// docs/recovery.md, "The cache on fewer pixels".
pub(super) const MAX_CACHE_PIXELS: usize = 512;

/// Samples per pixel on `subset` of a group's `all` pixels for as many samples in all as
/// `spp` on every pixel, within `fit::DECISION_MAX_SAMPLES`
/// ([`Recovery::decision_pixels`](super::Recovery::decision_pixels)) and never below `spp`.
pub(super) fn concentrated_spp(all: usize, subset: usize, spp: u32) -> u32 {
    let samples = (all as u64)
        .saturating_mul(spp as u64)
        .min(fit::DECISION_MAX_SAMPLES);
    samples
        .div_ceil(subset.max(1) as u64)
        .clamp(spp as u64, u32::MAX as u64) as u32
}

/// Samples per pixel for a group of `pixels`: `spp`, or more so that the group gets at
/// least `min_samples` pixel samples.
pub(super) fn min_samples_spp(spp: u32, pixels: u32, min_samples: u64) -> u32 {
    (spp as u64)
        .max(min_samples.div_ceil(pixels.max(1) as u64))
        .min(u32::MAX as u64) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_caches_floor_grows_with_the_effort_and_keeps_fasts() {
        let floor = |effort: Effort| cache_min_samples(effort.budget().cache_spp);
        // Effort fast keeps the floor its recoveries' bytes were made with.
        assert_eq!(floor(Effort::Fast), CACHE_MIN_SAMPLES);
        assert_eq!(floor(Effort::Default), 4 * CACHE_MIN_SAMPLES);
        assert_eq!(floor(Effort::Thorough), 16 * CACHE_MIN_SAMPLES);
        // A cache asked for fewer samples than fast's still holds CACHE_MIN_SAMPLES.
        assert_eq!(cache_min_samples(1), CACHE_MIN_SAMPLES);
        assert_eq!(
            cache_min_samples(u32::MAX),
            CACHE_FLOOR_PIXELS * u64::from(u32::MAX)
        );
        // A small group's cache at default effort: the floor over its pixels, not the
        // effort's 64 spp.
        let statue = 20;
        let default_spp = Effort::Default.budget().cache_spp;
        let spp = cache_pixel_spp(default_spp, statue);
        assert_eq!(spp, (4 * CACHE_MIN_SAMPLES).div_ceil(20) as u32);
    }

    #[test]
    fn a_decisions_samples_are_concentrated_on_its_subset_within_the_cap() {
        // A group of up to 1024 pixels is its own subset: its samples as asked, even past
        // the cap (a small group at a ladder's or a late round's samples).
        assert_eq!(concentrated_spp(938, 938, 32), 32);
        assert_eq!(concentrated_spp(1024, 1024, 4096), 4096);
        // Glossy's steel box at 256 px: 6472 pixels at 32 spp, on 925 of them.
        assert_eq!(concentrated_spp(6472, 925, 32), 224);
        // A wall of 112,446 pixels, on 1023: 3518 spp before the cap, now within it.
        let spp = concentrated_spp(112_446, 1023, 32);
        assert_eq!(spp, 1026);
        assert!(spp as u64 * 1023 <= fit::DECISION_MAX_SAMPLES + 1023);
        // Never fewer than asked per pixel, and no overflow or division by zero.
        assert_eq!(concentrated_spp(5_000_000, 1000, 2048), 2048);
        assert_eq!(concentrated_spp(0, 0, 8), 8);
        assert_eq!(concentrated_spp(usize::MAX / 2, 1, u32::MAX), u32::MAX);
    }
}
