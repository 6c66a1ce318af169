//! How well a rendering explains the panorama, group by group: the one definition of the
//! fit error, and every threshold of the staged recovery, in one place.
//!
//! The paper's error is `chi^2 = sum_i |I_render,i - I_real,i|^2` over a group's pixels,
//! with thresholds in percent; we make it relative and take our own Monte Carlo noise out:
//!
//! ```text
//! error = sqrt( max(0, sum_i |R_i - T_i|^2 - sum_i var(R_i)) / sum_i |T_i|^2 )
//! ```
//!
//! over the group's pure pixels (whole footprint on the group), RGB pooled, where `R_i` is
//! our render, `T_i` the panorama and `var(R_i)` the variance of our pixel estimate (summed
//! over channels). `E|R - T|^2 = |bias|^2 + var(R) + var(T)`, so subtracting `var(R)` leaves
//! the model's systematic error plus the panorama's own noise (0.3-2% on the references):
//! a low-sample render in the loop does not inflate the error.

use crate::math::Vec3;

/// The sums of one comparison of a group's pure pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GroupFit {
    pub pixels: u32,
    pub sum_real: [f64; 3],
    pub sum_rendered: [f64; 3],
    pub sum_sq_diff: f64,
    pub sum_sq_real: f64,
    pub sum_render_variance: f64,
}

impl GroupFit {
    /// `sqrt(max(0, sum_sq_diff) / sum_sq_real)`: the relative error of a fit whose
    /// `sum_sq_diff` holds cross products of two independent renders (host
    /// `pixels::evaluate_cross`), in which noise has no part. `None` without real signal.
    pub fn bias_only_error(&self) -> Option<f64> {
        (self.sum_sq_real > 0.0).then(|| libm::sqrt(self.sum_sq_diff.max(0.0) / self.sum_sq_real))
    }

    /// Adds one pixel: the panorama's value, our render and its variance.
    pub fn add(&mut self, real: Vec3, rendered: Vec3, render_variance: Vec3) {
        self.pixels = self.pixels.saturating_add(1);
        let d = rendered - real;
        for c in 0..3 {
            self.sum_real[c] += real[c] as f64;
            self.sum_rendered[c] += rendered[c] as f64;
        }
        self.sum_sq_diff += d.dot(d) as f64;
        self.sum_sq_real += real.dot(real) as f64;
        self.sum_render_variance +=
            (render_variance.x + render_variance.y + render_variance.z) as f64;
    }

    /// Merges the sums of another part of the same group (fixed order keeps bits stable).
    pub fn merge(&mut self, other: &GroupFit) {
        self.pixels = self.pixels.saturating_add(other.pixels);
        for c in 0..3 {
            self.sum_real[c] += other.sum_real[c];
            self.sum_rendered[c] += other.sum_rendered[c];
        }
        self.sum_sq_diff += other.sum_sq_diff;
        self.sum_sq_real += other.sum_sq_real;
        self.sum_render_variance += other.sum_render_variance;
    }

    /// The relative, noise-corrected error defined above; `None` without pixels or light.
    pub fn relative_error(&self) -> Option<f64> {
        if self.pixels == 0 || !(self.sum_sq_real > 0.0) {
            return None;
        }
        let systematic = (self.sum_sq_diff - self.sum_render_variance).max(0.0);
        Some(libm::sqrt(systematic / self.sum_sq_real))
    }

    /// The mean rendered value per channel (0 without pixels).
    pub fn mean_rendered(&self) -> [f64; 3] {
        core::array::from_fn(|c| self.sum_rendered[c] / self.pixels.max(1) as f64)
    }

    /// `mean(real) / mean(rendered)` per channel (1 where the render is black).
    pub fn mean_ratio(&self) -> [f64; 3] {
        core::array::from_fn(|c| {
            if self.sum_rendered[c] > 0.0 {
                self.sum_real[c] / self.sum_rendered[c]
            } else {
                1.0
            }
        })
    }
}

/// Two models of one group compared on the same pixels: is the more complex model
/// measurably better, or could another render's noise say otherwise?
///
/// Each pixel `i` is rendered four times with independent samples (the same samples for
/// both models, so their noises largely cancel in the difference), and its bias-only
/// squared error is measured twice, `q_i = (A_i - T_i) . (B_i - T_i)` from renders 1, 2
/// and from 3, 4 (see [`GroupFit::bias_only_error`]). The gain in squared relative error
/// is `G = sum_i (q_simple,i - q_complex,i) / sum_i |T_i|^2` over the mean of both
/// measurements; the two independent measurements of each pixel's difference give the
/// render noise of `G` pixel by pixel, `var = sum_i (d_i,1 - d_i,2)^2 / 4`, with as many
/// degrees of freedom as pixels. It is the noise alone: how unevenly a real gain falls
/// over the pixels (a highlight) is signal, not uncertainty.
///
/// The effect a threshold is held against is [`ModelComparison::effect`], `sqrt(G)`: the
/// relative error the complex model's extra part accounts for. A least-squares fit's
/// misfits add in quadrature, so a lobe missing from the simple model leaves
/// `e_s^2 = e_c^2 + g^2`, while `e_s - e_c` shrinks as the misfit both models share grows:
/// textured's stripes, on a uniform stand-in whose error is the picture (0.447), read a lobe
/// accounting for 0.08 as `e_s - e_c` = 0.0075.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelComparison {
    pub pixels: u32,
    /// Bias-only relative errors of the two models.
    pub error_simple: f64,
    pub error_complex: f64,
    /// The standard errors of their squares, each from its own model's two measurements
    /// (as in [`ErrorEstimate`]).
    pub squared_sigma_simple: f64,
    pub squared_sigma_complex: f64,
    /// `error_simple - error_complex`.
    pub gain: f64,
    /// The standard error of `gain` (from the squared gain's, by the delta method).
    pub gain_sigma: f64,
    /// The gain in squared relative error, `G` above, as measured: unlike `gain` it is
    /// not cut at 0 where noise outweighs an error, so it ranks models that are measured
    /// too coarsely for their errors to show.
    pub squared_gain: f64,
    /// The standard error of `squared_gain`.
    pub squared_gain_sigma: f64,
}

/// A group's bias-only relative error with its standard error, from each pixel's two
/// independent measurements of `(A - T) . (B - T)` (as in [`ModelComparison`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorEstimate {
    pub error: f64,
    pub sigma: f64,
    /// The standard error of the squared relative error, which `sigma` derives from.
    pub squared_sigma: f64,
}

impl ErrorEstimate {
    /// `None` without pixels or light.
    pub fn from_cross_terms(
        terms: impl Iterator<Item = [f64; 2]>,
        sum_sq_real: f64,
    ) -> Option<Self> {
        if !(sum_sq_real > 0.0) {
            return None;
        }
        let (mut n, mut q, mut variance) = (0u32, 0.0f64, 0.0f64);
        for t in terms {
            n = n.saturating_add(1);
            q += 0.5 * (t[0] + t[1]);
            variance += 0.25 * (t[0] - t[1]) * (t[0] - t[1]);
        }
        if n == 0 {
            return None;
        }
        Some(Self::from_squared(
            q / sum_sq_real,
            libm::sqrt(variance) / sum_sq_real,
        ))
    }

    /// [`ErrorEstimate::from_cross_terms`] over an even sample of a group's `population`
    /// pixels, each term with the pixel's `|T|^2` beside it: the sample's estimate, whose
    /// standard error also counts how far the sample's ratio of sums may lie from the whole
    /// group's (a ratio estimator's variance with the finite-population correction, as for
    /// a simple random sample: an even spread over a smooth surface does no worse). Its
    /// residuals hold the terms' own render noise as well, so the widening errs on the
    /// safe side. With every pixel measured it is `from_cross_terms`, to the bit.
    pub fn from_sampled_cross_terms(terms: &[([f64; 2], f64)], population: usize) -> Option<Self> {
        let sum_sq_real: f64 = terms.iter().map(|t| t.1).sum();
        let estimate = Self::from_cross_terms(terms.iter().map(|t| t.0), sum_sq_real)?;
        let m = terms.len();
        if m >= population || m < 2 {
            return Some(estimate);
        }
        let q = |t: &([f64; 2], f64)| 0.5 * (t.0[0] + t.0[1]);
        let ratio = terms.iter().map(q).sum::<f64>() / sum_sq_real;
        let residuals: f64 = terms
            .iter()
            .map(|t| {
                let d = q(t) - ratio * t.1;
                d * d
            })
            .sum();
        let (m, n) = (m as f64, population as f64);
        let sampling_variance =
            (1.0 - m / n) * m / (m - 1.0) * residuals / (sum_sq_real * sum_sq_real);
        let sigma = libm::sqrt(estimate.squared_sigma * estimate.squared_sigma + sampling_variance);
        Some(Self::from_squared(ratio, sigma))
    }

    /// From a measured squared relative error (negative when noise outweighs it, read as
    /// 0) and its standard error.
    pub fn from_squared(squared_error: f64, squared_sigma: f64) -> Self {
        let error = libm::sqrt(squared_error.max(0.0));
        ErrorEstimate {
            error,
            // d sqrt(x) = dx / (2 sqrt x), and `delta_sigma` divides by its second argument.
            sigma: delta_sigma(squared_sigma, 2.0 * error),
            squared_sigma,
        }
    }

    /// An upper confidence bound on the true error, `z` standard errors above the measured
    /// squared error. Taken on the square, where the noise is, it stays tight for an error
    /// measured near 0, where `error + z sigma` doubles.
    pub fn upper_bound(&self, z: f64) -> f64 {
        libm::sqrt(self.error * self.error + z * self.squared_sigma)
    }

    /// Whether the error is more than [`EXCEEDS_SIGMAS`] standard errors above `threshold`.
    ///
    /// Taken on the root, with `sigma` by the delta method: near 0 that passes errors the
    /// square (where [`ErrorEstimate::upper_bound`] is taken) would not. Kept so on
    /// purpose where it sends a group on to a test: a false go-on costs a test, a false
    /// stop a weak lobe (docs/tradeoff.md, box-diffuse at 4 loop spp).
    pub fn exceeds(&self, threshold: f64) -> bool {
        self.error - EXCEEDS_SIGMAS * self.sigma > threshold
    }

    /// Whether `threshold` lies within [`EXCEEDS_SIGMAS`] standard errors of the error:
    /// the measurement cannot tell which side the error is on.
    pub fn straddles(&self, threshold: f64) -> bool {
        libm::fabs(self.error - threshold) < EXCEEDS_SIGMAS * self.sigma
    }
}

/// The standard error of `sum_errors`, a sum of square roots of squared errors, from the
/// standard error of the squared quantity by the delta method (`d sqrt(x) = dx / 2 sqrt(x)`
/// per term); near zero the squared quantity's own root is the safe bound.
fn delta_sigma(sigma_squared: f64, sum_errors: f64) -> f64 {
    if sum_errors > libm::sqrt(sigma_squared) {
        sigma_squared / sum_errors
    } else {
        libm::sqrt(sigma_squared)
    }
}

/// One pixel's two measurements of each model's bias-only squared error (see
/// [`ModelComparison`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairedTerms {
    pub simple: [f64; 2],
    pub complex: [f64; 2],
}

impl ModelComparison {
    /// From each pixel's [`PairedTerms`] and the sum of `|T|^2` over the same pixels.
    /// `None` without pixels or light.
    pub fn from_cross_terms(
        terms: impl Iterator<Item = PairedTerms>,
        sum_sq_real: f64,
    ) -> Option<Self> {
        if !(sum_sq_real > 0.0) {
            return None;
        }
        let (mut n, mut q_simple, mut q_complex, mut variance) = (0u32, 0.0, 0.0, 0.0f64);
        let (mut variance_simple, mut variance_complex) = (0.0f64, 0.0f64);
        for t in terms {
            n = n.saturating_add(1);
            q_simple += 0.5 * (t.simple[0] + t.simple[1]);
            q_complex += 0.5 * (t.complex[0] + t.complex[1]);
            let spread = (t.simple[0] - t.complex[0]) - (t.simple[1] - t.complex[1]);
            variance += 0.25 * spread * spread;
            variance_simple += 0.25 * (t.simple[0] - t.simple[1]) * (t.simple[0] - t.simple[1]);
            variance_complex +=
                0.25 * (t.complex[0] - t.complex[1]) * (t.complex[0] - t.complex[1]);
        }
        if n == 0 {
            return None;
        }
        let sigma_squared_gain = libm::sqrt(variance) / sum_sq_real;
        let error_simple = libm::sqrt(q_simple.max(0.0) / sum_sq_real);
        let error_complex = libm::sqrt(q_complex.max(0.0) / sum_sq_real);
        // d(e_s - e_c) = dG / (e_s + e_c).
        let gain_sigma = delta_sigma(sigma_squared_gain, error_simple + error_complex);
        Some(ModelComparison {
            pixels: n,
            error_simple,
            error_complex,
            squared_sigma_simple: libm::sqrt(variance_simple) / sum_sq_real,
            squared_sigma_complex: libm::sqrt(variance_complex) / sum_sq_real,
            gain: error_simple - error_complex,
            gain_sigma,
            squared_gain: (q_simple - q_complex) / sum_sq_real,
            squared_gain_sigma: sigma_squared_gain,
        })
    }

    /// The simpler model's error with its standard error.
    pub fn simple_estimate(&self) -> ErrorEstimate {
        ErrorEstimate::from_squared(
            self.error_simple * self.error_simple,
            self.squared_sigma_simple,
        )
    }

    /// The more complex model's error with its standard error.
    pub fn complex_estimate(&self) -> ErrorEstimate {
        ErrorEstimate::from_squared(
            self.error_complex * self.error_complex,
            self.squared_sigma_complex,
        )
    }

    /// The gain in standard errors.
    pub fn z(&self) -> f64 {
        if self.gain_sigma > 0.0 {
            self.gain / self.gain_sigma
        } else if self.gain > 0.0 {
            f64::INFINITY
        } else {
            0.0
        }
    }

    /// The relative error the complex model's extra part accounts for, `sqrt(G)` (0 where
    /// it measures no better): what [`SPECULAR_GAIN_THRESHOLD`] is held against.
    pub fn effect(&self) -> f64 {
        libm::sqrt(self.squared_gain.max(0.0))
    }

    /// Whether the complex model is not yet shown better but its gain is at least one
    /// standard error and its effect within one standard error of the threshold or above
    /// it: worth measuring again with more samples. (Above the threshold only, as it was, a
    /// gain read just under it was final however noisy: glossy's yellow box at 64 px,
    /// 0.0096 +- 0.0076 at 67 spp, where 268 spp read 0.0195.)
    pub fn is_promising(&self) -> bool {
        !self.favours_complex()
            && libm::sqrt((self.squared_gain + self.squared_gain_sigma).max(0.0))
                > SPECULAR_GAIN_THRESHOLD
            && self.z() >= 1.0
    }

    /// Whether the measurement was too noisy to have shown an effect of the threshold's
    /// size (the squared gain's standard error above the threshold's square), and is not
    /// already against the complex model by [`EXCEEDS_SIGMAS`] standard errors, the level
    /// at which an error counts as above a threshold (the living room's 20-pixel statue
    /// measured 0.11 +- 0.26 at 32 spp): worth measuring again while that is cheap
    /// ([`UNRESOLVED_MAX_SAMPLES`]). Until 2026-12-07 "against" was z <= -1: glossy's
    /// steel box (roughness 0.14) on seed 14 at 64 px read its lobe against a perfect
    /// mirror as -0.112 +- 0.095 at 32 spp (z -1.2) and became a mirror; measured again,
    /// the lobe wins at z 37.
    pub fn is_unresolved(&self) -> bool {
        !self.favours_complex()
            && !self.is_promising()
            && self.squared_gain_sigma > SPECULAR_GAIN_THRESHOLD * SPECULAR_GAIN_THRESHOLD
            && self.z() > -EXCEEDS_SIGMAS
    }

    /// Whether this comparison passes, but at its first look and by less than
    /// [`FIRST_LOOK_MARGIN`] times the z it needs: worth one more look before the
    /// complex model is kept.
    pub fn is_marginal_first_look(&self, round: u32) -> bool {
        round == 0 && self.favours_complex() && self.z() < FIRST_LOOK_MARGIN * self.significance()
    }

    /// The cap in pixel samples per model of the next measurement of a decision that read
    /// this comparison in `round` (0 for the first look), or `None` when this one decides:
    /// a promising comparison within [`DECISION_MAX_SAMPLES`], an unresolved one within
    /// [`UNRESOLVED_MAX_SAMPLES`], a marginal first look's pass within
    /// [`DECISION_MAX_SAMPLES`] ([`ModelComparison::is_marginal_first_look`]).
    pub fn next_look_cap(&self, round: u32) -> Option<u64> {
        if self.is_promising() || self.is_marginal_first_look(round) {
            Some(DECISION_MAX_SAMPLES)
        } else if self.is_unresolved() {
            Some(UNRESOLVED_MAX_SAMPLES)
        } else {
            None
        }
    }

    /// The z this comparison's gain needs: [`gain_significance`] of its pixels.
    pub fn significance(&self) -> f64 {
        gain_significance(self.pixels)
    }

    /// Whether the complex model is worth its parameters: it accounts for more than
    /// [`SPECULAR_GAIN_THRESHOLD`] of relative error ([`ModelComparison::effect`]), and its
    /// gain is at least [`gain_significance`] standard errors.
    pub fn favours_complex(&self) -> bool {
        self.effect() > SPECULAR_GAIN_THRESHOLD && self.z() >= self.significance()
    }
}

/// A measured error counts as above a threshold ([`ErrorEstimate::exceeds`]) when it is
/// more than this many standard errors above it: one-sided, about 2% to pass on noise.
/// (Until the error's standard error was corrected to the delta method's `dQ / 2e` it read
/// twice too large and the rule said one; the decisions are where they were.)
pub const EXCEEDS_SIGMAS: f64 = 2.0;

/// A group whose diffuse fit has an error below this is diffuse (the paper's 5%).
pub const DIFFUSE_THRESHOLD: f64 = 0.05;
/// The diffuse iteration stops when no group's reflectance changes by more than this
/// (relative, per channel) in one step.
pub const DIFFUSE_CONVERGED: f64 = 2e-4;
/// The diffuse iteration stops after this many steps at the most.
pub const DIFFUSE_MAX_STEPS: u32 = 30;
/// A specular model is kept only when a render of the group shows it accounts for more than
/// this much of the relative error the diffuse model leaves ([`ModelComparison::effect`];
/// host `recover`, stage 2); a group whose diffuse error is already below it is not tried,
/// since no model could account for more.
pub const SPECULAR_GAIN_THRESHOLD: f64 = 0.01;

/// The relative error a lobe accounts for on a group's transport cache, in quadrature
/// as a render comparison's [`ModelComparison::effect`]: `sqrt(e_diffuse^2 - e_lobe^2)`
/// between the cache's least-squares fits with and without the lobe. The lobe's fit there
/// also takes in the cache's noise and the spikes of its finite incident samples, which
/// read as more gain, not less (the weak lobes found on the references read 0.0136 and
/// more; groups diffuse in the truth 0.0009-0.0093 where under the threshold), so a lobe
/// at most [`SPECULAR_GAIN_THRESHOLD`] here is not one a render would keep. The exception
/// is a lobe on the threshold itself: glossy's white sphere (s 0.03, roughness 0.02),
/// whose true lobe accounts for about 0.01, reads 0.0000-0.0064 on some seeds and
/// 0.013-0.028 on others (docs/recovery.md, "The ladder's second round").
pub fn cache_effect(diffuse_error: f64, lobe_error: f64) -> f64 {
    libm::sqrt((diffuse_error * diffuse_error - lobe_error * lobe_error).max(0.0))
}

/// A more complex model is kept only when its gain is significant at the level a normal z
/// of this many standard errors has ([`ModelComparison`]): one-sided, about one chance in
/// a thousand that a model with no real gain passes on noise alone.
pub const GAIN_SIGNIFICANCE: f64 = 3.0;

/// The z a gain measured over `pixels` pixels needs: the gain's standard error is
/// estimated from as many squared differences as pixels, so its z is Student's t with that
/// many degrees of freedom, and this is t's critical value at the level of a normal z of
/// [`GAIN_SIGNIFICANCE`] (0.135%, one-sided). 6.62 at 4 pixels, 3.59 at 15, 3.10 at 80,
/// 3.01 at 1000: a group of a few pixels can still show a lobe, when its gain stands far enough
/// above the noise that so few pixels measure (the living room's frames at 64 px: 15
/// pixels, 46% of error left diffuse). Infinite without pixels.
pub fn gain_significance(pixels: u32) -> f64 {
    if pixels == 0 {
        return f64::INFINITY;
    }
    crate::student_t::critical_value(
        crate::student_t::normal_upper_tail(GAIN_SIGNIFICANCE),
        pixels,
    )
}
/// A promising comparison ([`ModelComparison::is_promising`]) is measured again with this
/// many times the samples per pixel, at most [`DECISION_MAX_ROUNDS`] more times and while
/// the pixels measured times the samples stay within [`DECISION_MAX_SAMPLES`] per model:
/// small groups and weak lobes get the samples they need, large groups are not rendered
/// for minutes. A large group's first measurement keeps to that cap too (the host's
/// `Recovery::decision_pixels`). The next measurement is fresh (new seeds) and decides
/// alone; a first look's marginal pass is measured again the same way
/// ([`FIRST_LOOK_MARGIN`], [`ModelComparison::next_look_cap`]).
pub const DECISION_SPP_GROWTH: u32 = 4;
pub const DECISION_MAX_ROUNDS: u32 = 3;
pub const DECISION_MAX_SAMPLES: u64 = 1 << 20;
/// The least growth of a round held to its cap ([`next_decision_spp`]): a look at much the
/// same samples would be a second chance, not a better measurement.
pub const DECISION_MIN_GROWTH: u32 = 2;

/// The samples per pixel of the next round of a decision on `pixels` pixels measured at
/// `spp`, within `cap` pixel samples per model: [`DECISION_SPP_GROWTH`] times as many, or
/// as many as the cap allows when that is less but still [`DECISION_MIN_GROWTH`] times as
/// many; `None` when the cap leaves no such round. Without the cap's own round a decision's
/// last look depended on where its first fell: glossy's yellow box at 256 px (938 pixels)
/// stopped at 288 spp, its lobe at z 2.6, since 4x was 3% over the cap, where the teal box
/// (940 pixels) started at 256 and was measured again at 1024.
pub fn next_decision_spp(spp: u32, pixels: usize, cap: u64) -> Option<u32> {
    let grown = spp.saturating_mul(DECISION_SPP_GROWTH) as u64;
    let allowed = cap / (pixels.max(1) as u64);
    let next = grown.min(allowed);
    (next >= spp as u64 * DECISION_MIN_GROWTH as u64).then_some(next.min(u32::MAX as u64) as u32)
}
/// An unresolved comparison ([`ModelComparison::is_unresolved`]) is measured again only
/// within this many pixel samples per model, as a promising one is. A large group is
/// decided on at most 1024 of its pixels (the host's `Recovery::decision_pixels`), so a
/// round costs at most this much whatever the group's size: every group of up to 512
/// pixels gets all its rounds, one of up to 1024 two more, one of a few thousand one more,
/// and the largest (walls and floors at 256 px per face, whose first measurement is held
/// to [`DECISION_MAX_SAMPLES`] too) none. At 2^19, glossy's steel box at 256 px (6472
/// pixels, measured on 925) read its lobe against a perfect mirror as 0.036 +- 0.044 on
/// seed 3 and was left a mirror; one more round keeps its lobe.
pub const UNRESOLVED_MAX_SAMPLES: u64 = 1 << 20;
/// A first look that passes by less than this many times the z it needs
/// ([`gain_significance`]) is measured once more, fresh and with more samples, and that
/// measurement decides. A first look has the fewest samples per pixel (32 at effort fast),
/// and render noise is heavy-tailed: the rare samples that reach a light by a sharp lobe
/// are the ones a few samples miss, so its standard error reads low. The living room's
/// statue (20 pixels, an isotropic metal) read its anisotropic fit at 0.139 +- 0.036 at
/// 32 spp on seed 9 (z 3.9 against the 3.42 it needs) and was kept anisotropic, where
/// seeds 3, 5 and 8 read the same test at 2048 spp as 0.000 +- 0.023, 0.000 +- 0.013 and
/// -0.106 +- 0.015. A pass twice as far out survives a standard error read half its size;
/// a nearer one is looked at again (within [`DECISION_MAX_SAMPLES`], like a promising
/// one), not taken on the cheapest look alone.
pub const FIRST_LOOK_MARGIN: f64 = 2.0;
/// A fitted isotropic metal whose specular part is above this fraction of its reflectance,
/// with a roughness at most [`MIRROR_MAX_ROUGHNESS`], is tested as a mirror (the paper's 90%).
pub const MIRROR_SPECULAR_FRACTION: f64 = 0.9;
pub const MIRROR_MAX_ROUGHNESS: f64 = 0.02;
/// Largest relative spread of the mirror's specular colour over the channels (the paper's
/// "reflected colour close to the incident colour").
pub const MIRROR_MAX_TINT: f64 = 0.1;
/// Fewer pure pixels than this: the group is reported as barely seen, and kept diffuse.
/// From this many the keep-or-reject test decides, at [`gain_significance`] of the
/// group's pixels (6.6 standard errors at 4 pixels, 3.6 at 15); below it the gain's
/// standard error would rest on two or three squared differences of heavy-tailed render
/// noise, which no critical value makes trustworthy. (It was 16, with a normal z of 3 above
/// it: the living room's frames, 15 pixels at 64 px and 46% of error left diffuse, were
/// kept diffuse and came out 2.5-4x too bright.)
pub const MIN_PIXELS_FOR_MODEL_CHOICE: u32 = 4;
/// Fewer pure pixels than this: a group is not tested for texture (stage 3), and its
/// errors do not bound the panorama's noise: a step contrast over pixels 3 apart has only a
/// few pairs to go on.
pub const MIN_PIXELS_FOR_TEXTURE: u32 = 16;

/// Texture detection (stage 3): pixel step of the differences of the difference image.
pub const TEXTURE_STEP: u32 = 3;
/// Texture detection: differences below this fraction of the largest are left out.
pub const TEXTURE_FLOOR: f64 = 0.01;
/// Texture detection: a group whose feature exceeds this is textured (the paper's 40%).
pub const TEXTURE_THRESHOLD: f64 = 0.4;
/// Texture detection as decided (stages::texture::cross_contrast): a plastic group whose
/// unexplained log-radiance changes by more than this RMS over `TEXTURE_STEP` pixels, noise
/// removed, is textured. A uniform material's residual varies smoothly (a misfit lobe
/// spans many pixels) and the references' own noise is 0.6-1.7%; a picture's contrast is
/// tens of percent.
pub const TEXTURE_CONTRAST_THRESHOLD: f64 = 0.1;
/// Texture detection: the step contrast's renders take at least this many samples per
/// pixel. The log of a noisy render is biased low by about half its relative variance
/// (the log's curvature), a bias both renders share and their cross products keep; a
/// sharp highlight's pixels carry more of it than their neighbours, which reads as a step.
/// A uniform anisotropic panel (textured's checker given its mean colour, 64 px) read
/// 0.124 under its anisotropic lobe at 32 samples a pixel, 0 at 256.
pub const TEXTURE_MIN_SPP: u32 = 256;
/// Texture detection: each group's bias-only error bounds the panorama's relative noise
/// from above, but only up to its own measurement noise. A group's bound is its squared
/// error plus this many standard errors (one-sided, about 2% to fall below the noise): a
/// mirror rendered at a few samples reads 0 +- 0.1, and its bare 0 would say "no noise"
/// (stages::texture::panorama_noise_bound, fit::ErrorEstimate::upper_bound).
pub const NOISE_BOUND_SIGNIFICANCE: f64 = 2.0;
/// Stage 5: a pixel whose rendered specular part is above this fraction of its observed
/// radiance is a highlight and says nothing about the map.
pub const HIGHLIGHT_FRACTION: f64 = 0.5;
/// Stage 5: a pixel receiving less than this fraction of the group's median irradiance is
/// in shadow and says little about the map.
pub const SHADOW_FRACTION: f64 = 0.1;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_decisions_next_round_grows_fourfold_or_to_its_cap() {
        let cap = 1 << 20;
        // Well within the cap: four times the samples.
        assert_eq!(next_decision_spp(64, 940, cap), Some(256));
        assert_eq!(next_decision_spp(256, 940, cap), Some(1024));
        // 4x past the cap: the cap's own round, 1117 spp on 938 pixels.
        assert_eq!(next_decision_spp(288, 938, cap), Some(1117));
        // The cap leaves less than twice the samples: no round.
        assert_eq!(next_decision_spp(600, 938, cap), None);
        assert_eq!(next_decision_spp(1117, 938, cap), None);
        // No pixels, or spp at its limit, do not overflow.
        assert_eq!(next_decision_spp(u32::MAX, 0, u64::MAX), None);
        assert_eq!(next_decision_spp(8, 0, cap), Some(32));
    }

    /// A comparison of 1000 pixels whose simple model's error is 5% and whose squared gain
    /// is `squared_gain +- squared_gain_sigma`.
    fn comparison(squared_gain: f64, squared_gain_sigma: f64) -> ModelComparison {
        let error_simple = 0.05;
        let error_complex = libm::sqrt(error_simple * error_simple - squared_gain);
        let sum = error_simple + error_complex;
        ModelComparison {
            pixels: 1000,
            error_simple,
            error_complex,
            squared_sigma_simple: squared_gain_sigma,
            squared_sigma_complex: squared_gain_sigma,
            gain: error_simple - error_complex,
            gain_sigma: squared_gain_sigma / sum,
            squared_gain,
            squared_gain_sigma,
        }
    }

    #[test]
    fn a_comparison_is_decided_promising_or_unresolved_by_its_gain_and_noise() {
        // Shown: an effect of 2% (squared 4e-4) at z 4.
        let shown = comparison(4e-4, 1e-4);
        assert!((shown.effect() - 0.02).abs() < 1e-12);
        assert!(shown.favours_complex() && !shown.is_promising() && !shown.is_unresolved());
        // 2% at z 2: promising.
        let promising = comparison(4e-4, 2e-4);
        assert!(promising.is_promising() && !promising.is_unresolved());
        // Just under the threshold (0.0096) at z 1.3: it may be above it, so promising too.
        assert!(comparison(0.0096 * 0.0096, 0.0096 * 0.0096 / 1.3).is_promising());
        // Under it by more than its standard error (0.006 at z 2): final.
        assert!(!comparison(3.6e-5, 1.8e-5).is_promising());
        // Nothing seen, but the noise could hide a 1% effect: unresolved.
        let unresolved = comparison(0.0, 2e-4);
        assert!(!unresolved.is_promising() && unresolved.is_unresolved());
        // Precise enough to rule out a 1% effect, or already against the complex model.
        assert!(!comparison(0.0, 2.5e-5).is_unresolved());
        assert!(!comparison(-2.5e-3, 4e-4).is_unresolved());
        // Against it, but by fewer than EXCEEDS_SIGMAS standard errors (z -1.2): noise
        // of this size says nothing yet, so measured again; at z -2.5 it has spoken.
        assert!(comparison(-4.8e-4, 4e-4).is_unresolved());
        assert!(!comparison(-1e-3, 4e-4).is_unresolved());
    }

    #[test]
    fn a_marginal_pass_is_looked_at_again_once_and_a_clear_one_decides() {
        // z 4 against the 3.01 that 1000 pixels need: a pass, but under twice that.
        let marginal = comparison(4e-4, 1e-4);
        assert!(
            marginal.favours_complex()
                && marginal.z() < FIRST_LOOK_MARGIN * marginal.significance()
        );
        assert!(marginal.is_marginal_first_look(0));
        assert_eq!(marginal.next_look_cap(0), Some(DECISION_MAX_SAMPLES));
        // The look after it decides, whatever it reads.
        assert!(!marginal.is_marginal_first_look(1));
        assert_eq!(marginal.next_look_cap(1), None);
        // z 8: clear at the first look.
        let clear = comparison(4e-4, 0.5e-4);
        assert!(clear.favours_complex() && !clear.is_marginal_first_look(0));
        assert_eq!(clear.next_look_cap(0), None);
        // The other rounds as they were: promising and unresolved go on, in any round.
        assert_eq!(
            comparison(4e-4, 2e-4).next_look_cap(2),
            Some(DECISION_MAX_SAMPLES)
        );
        assert_eq!(
            comparison(0.0, 2e-4).next_look_cap(2),
            Some(UNRESOLVED_MAX_SAMPLES)
        );
        assert_eq!(comparison(3.6e-5, 1.8e-5).next_look_cap(0), None);
        // A first look against the complex model is not marginal.
        assert!(!comparison(-2.5e-3, 4e-4).is_marginal_first_look(0));
    }

    /// A lobe beside a large misfit both models share (a picture on a uniform stand-in):
    /// the errors' difference is under the threshold, the error the lobe accounts for is
    /// far above it, and it is that which decides.
    #[test]
    fn a_lobe_beside_a_large_shared_misfit_is_judged_by_its_own_share() {
        let mut rng = crate::rng::Sampler::from_key(9);
        let terms: std::vec::Vec<PairedTerms> = (0..2000)
            .map(|_| paired(&mut rng, 0.447, 0.4397, 0.05))
            .collect();
        let c = ModelComparison::from_cross_terms(terms.into_iter(), 2000.0).unwrap();
        assert!(c.gain < SPECULAR_GAIN_THRESHOLD, "{c:?}");
        let own_share = libm::sqrt(0.447 * 0.447 - 0.4397 * 0.4397);
        assert!((c.effect() - own_share).abs() < 0.01, "{c:?}");
        assert!(c.favours_complex(), "{c:?}");
    }

    #[test]
    fn an_error_estimates_standard_error_matches_its_spread() {
        // Pixels of radiance 1 rendered with a bias of 0.1 and uniform render noise of sd
        // 0.3, measured as the recovery does: two renders per measurement, two
        // measurements per pixel. Over many trials the reported standard error must be
        // the spread of the error itself (the delta method's dQ / 2e).
        let (trials, pixels) = (400u32, 500u32);
        let mut errors = std::vec::Vec::new();
        let mut sigmas = 0.0;
        for trial in 0..trials {
            let mut rng = crate::rng::Sampler::for_pixel_sample(11, trial, 0, 0);
            let mut noise = || {
                let [a, _] = rng.next_2d();
                0.3 * 1.732_050_8 * (2.0 * a as f64 - 1.0)
            };
            let terms: std::vec::Vec<[f64; 2]> = (0..pixels)
                .map(|_| {
                    let mut q = || (0.1 + noise()) * (0.1 + noise());
                    [q(), q()]
                })
                .collect();
            let e = ErrorEstimate::from_cross_terms(terms.into_iter(), pixels as f64).unwrap();
            errors.push(e.error);
            sigmas += e.sigma;
        }
        let n = trials as f64;
        let mean = errors.iter().sum::<f64>() / n;
        let spread =
            libm::sqrt(errors.iter().map(|e| (e - mean) * (e - mean)).sum::<f64>() / (n - 1.0));
        let reported = sigmas / n;
        assert!((mean - 0.1).abs() < 0.01, "mean error {mean}");
        assert!(
            (reported / spread - 1.0).abs() < 0.15,
            "reported {reported}, spread {spread}"
        );
    }

    #[test]
    fn a_sampled_error_estimates_standard_error_covers_the_whole_groups_error() {
        // A group of 6000 pixels whose bias varies over it (a lobe on some of them, none
        // on others), measured on every third pixel. The sample's standard error must
        // account for how far the sample's error lies from the whole group's: over many
        // groups, the sampled and the whole errors differ by about that much, where the
        // render noise's part alone covers a fraction of it.
        let (trials, pixels) = (300u32, 6000usize);
        let (mut z2_full, mut z2_noise) = (0.0, 0.0);
        for trial in 0..trials {
            let mut rng = crate::rng::Sampler::for_pixel_sample(12, trial, 0, 0);
            let terms: std::vec::Vec<([f64; 2], f64)> = (0..pixels)
                .map(|_| {
                    let [a, b] = rng.next_2d();
                    let bias = if a < 0.2 { 0.4 * b as f64 } else { 0.02 };
                    let [c, d] = rng.next_2d();
                    let noise = |u: f32| 0.01 * (2.0 * u as f64 - 1.0);
                    let t = 0.5 + a as f64;
                    ([bias * bias * t + noise(c), bias * bias * t + noise(d)], t)
                })
                .collect();
            let whole = ErrorEstimate::from_sampled_cross_terms(&terms, pixels).unwrap();
            let every_third: std::vec::Vec<_> = terms.iter().copied().step_by(3).collect();
            let sampled = ErrorEstimate::from_sampled_cross_terms(&every_third, pixels).unwrap();
            let noise_only = ErrorEstimate::from_cross_terms(
                every_third.iter().map(|t| t.0),
                every_third.iter().map(|t| t.1).sum(),
            )
            .unwrap();
            assert_eq!(sampled.error, noise_only.error);
            let d = sampled.error - whole.error;
            z2_full += d * d / (sampled.sigma * sampled.sigma);
            z2_noise += d * d / (noise_only.sigma * noise_only.sigma);
        }
        let rms_full = libm::sqrt(z2_full / trials as f64);
        let rms_noise = libm::sqrt(z2_noise / trials as f64);
        // The difference from the whole group's estimate is what the finite-population
        // correction measures, so its z has a spread of about 1 (0.96 here).
        assert!((0.8..1.2).contains(&rms_full), "z with sampling {rms_full}");
        assert!(rms_noise > 2.0, "z with render noise only {rms_noise}");
    }

    #[test]
    fn a_sampled_error_estimate_of_every_pixel_is_the_plain_one() {
        let terms: std::vec::Vec<([f64; 2], f64)> = (0..50)
            .map(|i| {
                let x = i as f64 * 0.01;
                ([x * x + 0.001, x * x - 0.001], 1.0 + x)
            })
            .collect();
        let plain = ErrorEstimate::from_cross_terms(
            terms.iter().map(|t| t.0),
            terms.iter().map(|t| t.1).sum(),
        );
        assert_eq!(ErrorEstimate::from_sampled_cross_terms(&terms, 50), plain);
    }

    #[test]
    fn perfect_fit_has_zero_error_and_unit_ratio() {
        let mut f = GroupFit::default();
        for i in 0..10 {
            let v = Vec3::splat(0.1 * i as f32 + 0.1);
            f.add(v, v, Vec3::ZERO);
        }
        assert_eq!(f.relative_error(), Some(0.0));
        assert_eq!(f.mean_ratio(), [1.0; 3]);
    }

    #[test]
    fn a_uniform_ten_percent_offset_is_a_ten_percent_error() {
        let mut f = GroupFit::default();
        for _ in 0..100 {
            f.add(Vec3::splat(1.0), Vec3::splat(1.1), Vec3::ZERO);
        }
        let e = f.relative_error().unwrap();
        assert!((e - 0.1).abs() < 1e-6, "{e}");
        assert!((f.mean_ratio()[0] - 1.0 / 1.1).abs() < 1e-6);
    }

    #[test]
    fn render_noise_is_taken_out_of_the_error() {
        // Render = truth + noise of known variance: the corrected error is near zero, the
        // raw RMS is not.
        let mut rng = crate::rng::Sampler::from_key(3);
        let sigma = 0.2f32;
        let mut f = GroupFit::default();
        for _ in 0..20_000 {
            // Uniform noise of variance sigma^2 per channel.
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - Vec3::splat(0.5);
            let noise = u * (sigma * crate::math::sqrt(12.0));
            f.add(Vec3::ONE, Vec3::ONE + noise, Vec3::splat(sigma * sigma));
        }
        let raw = libm::sqrt(f.sum_sq_diff / f.sum_sq_real);
        assert!(raw > 0.15, "raw {raw}");
        assert!(
            f.relative_error().unwrap() < 0.02,
            "{:?}",
            f.relative_error()
        );
    }

    /// `pixels` pixels' terms for two models of the same relative `bias`, each under its own
    /// independent noise: no real gain, and the worst case for the pairing.
    fn equal_models(
        rng: &mut crate::rng::Sampler,
        pixels: usize,
        bias: f64,
        noise: f64,
    ) -> std::vec::Vec<PairedTerms> {
        independent_models(rng, pixels, bias, bias, noise)
    }

    /// `pixels` pixels' terms for models of relative bias `simple` and `complex`, each
    /// under its own independent noise (the pairing cancels nothing).
    fn independent_models(
        rng: &mut crate::rng::Sampler,
        pixels: usize,
        simple: f64,
        complex: f64,
        noise: f64,
    ) -> std::vec::Vec<PairedTerms> {
        (0..pixels)
            .map(|_| {
                let mut t = paired(rng, simple, complex, noise);
                t.complex = paired(rng, simple, complex, noise).complex;
                t
            })
            .collect()
    }

    /// One pixel's terms for two models of relative bias `simple` and `complex`, on a
    /// panorama value of 1, each seen through four renders of relative noise `noise`
    /// (shared between the models, as the host renders them on the same samples).
    fn paired(rng: &mut crate::rng::Sampler, simple: f64, complex: f64, noise: f64) -> PairedTerms {
        let mut draw = || (rng.next_f32() as f64 - 0.5) * noise * libm::sqrt(12.0);
        let n: [f64; 4] = [draw(), draw(), draw(), draw()];
        let q = |bias: f64, i: usize| (bias + n[i]) * (bias + n[i + 1]);
        PairedTerms {
            simple: [q(simple, 0), q(simple, 2)],
            complex: [q(complex, 0), q(complex, 2)],
        }
    }

    /// A comparison's noise is a product of two renders' noises per pixel, whose variance
    /// falls with the square of the samples per pixel: at the same pixel samples in all,
    /// fewer pixels at more samples each read a gain far more steadily. (Why a large
    /// group's decisions render an even subset of it, the host's
    /// `Recovery::decision_pixels`.)
    #[test]
    fn fewer_pixels_at_more_samples_each_read_a_gain_more_steadily_at_the_same_cost() {
        let mut rng = crate::rng::Sampler::from_key(9);
        let mut measure = |pixels: usize, noise: f64| {
            let terms = independent_models(&mut rng, pixels, 0.20, 0.10, noise);
            ModelComparison::from_cross_terms(terms.into_iter(), pixels as f64).unwrap()
        };
        // 6400 pixels whose quarter-renders have a relative noise of 1, against 800 of
        // them at 8 times the samples (noise 1 / sqrt 8).
        let all = measure(6400, 1.0);
        let subset = measure(800, 1.0 / libm::sqrt(8.0));
        assert!(
            subset.squared_gain_sigma < all.squared_gain_sigma / 2.0,
            "{subset:?} against {all:?}"
        );
        let true_squared_gain = 0.20 * 0.20 - 0.10 * 0.10;
        assert!(
            (subset.squared_gain - true_squared_gain).abs() < 3.0 * subset.squared_gain_sigma,
            "{subset:?}"
        );
        assert!(subset.favours_complex(), "{subset:?}");
        assert!(!all.favours_complex(), "{all:?}");
    }

    #[test]
    fn a_gain_on_every_pixel_is_significant() {
        // Diffuse 5% off everywhere, the lobe 2% off: a 3% gain under 10% render noise.
        let mut rng = crate::rng::Sampler::from_key(5);
        let terms: std::vec::Vec<PairedTerms> = (0..2000)
            .map(|_| paired(&mut rng, 0.05, 0.02, 0.1))
            .collect();
        let c = ModelComparison::from_cross_terms(terms.into_iter(), 2000.0).unwrap();
        assert!((c.gain - 0.03).abs() < 0.01, "{c:?}");
        assert!(c.z() > 5.0 && c.favours_complex(), "{c:?}");
    }

    #[test]
    fn noise_alone_is_no_gain() {
        // Both models equally good under independent noise: whatever gain the noise shows
        // is not significant, and its sigma says how large such gains are.
        let mut rng = crate::rng::Sampler::from_key(6);
        let mut rejected = 0;
        let mut gains = std::vec::Vec::new();
        for _ in 0..200 {
            let terms = equal_models(&mut rng, 300, 0.03, 0.2);
            let c = ModelComparison::from_cross_terms(terms.into_iter(), 300.0).unwrap();
            rejected += !c.favours_complex() as u32;
            gains.push(c.gain / c.gain_sigma);
        }
        assert_eq!(rejected, 200);
        // The z scores of pure noise have a spread of about one: sigma is calibrated.
        let mean = gains.iter().sum::<f64>() / 200.0;
        let sd = libm::sqrt(gains.iter().map(|z| (z - mean) * (z - mean)).sum::<f64>() / 199.0);
        assert!(
            mean.abs() < 0.3 && (sd - 1.0).abs() < 0.25,
            "mean {mean}, sd {sd}"
        );
    }

    #[test]
    fn a_small_group_needs_a_larger_z_to_keep_noise_out() {
        // Two equally good models under independent noise, compared over 6 pixels: the
        // gain's sigma rests on 6 squared differences, so its z is t with 6 degrees of
        // freedom, which passes a normal 3 about 1.2% of the time (0.94% here);
        // gain_significance(6) (4.9) keeps noise to the 0.135% a z of 3 claims.
        let mut rng = crate::rng::Sampler::from_key(8);
        let trials = 20_000;
        let (mut at_normal_z, mut kept) = (0u32, 0u32);
        for _ in 0..trials {
            let terms = equal_models(&mut rng, 6, 0.3, 0.3);
            let c = ModelComparison::from_cross_terms(terms.into_iter(), 6.0).unwrap();
            at_normal_z += (c.gain > SPECULAR_GAIN_THRESHOLD && c.z() >= GAIN_SIGNIFICANCE) as u32;
            kept += c.favours_complex() as u32;
        }
        let rate = |n: u32| n as f64 / trials as f64;
        assert!(rate(at_normal_z) > 0.006, "{}", rate(at_normal_z));
        assert!(rate(kept) < 0.003, "{}", rate(kept));
        assert!((gain_significance(6) - 4.90).abs() < 0.01);
        assert!(gain_significance(0).is_infinite());
    }

    #[test]
    fn a_real_gain_on_few_pixels_is_significant_a_noisy_one_is_not() {
        // A highlight: 20 of 1000 pixels much better explained, with little noise.
        let mut rng = crate::rng::Sampler::from_key(7);
        let terms = |rng: &mut crate::rng::Sampler, noise: f64| {
            (0..1000)
                .map(|i| {
                    let simple = if i % 50 == 0 { 0.8 } else { 0.01 };
                    paired(rng, simple, 0.01, noise)
                })
                .collect::<std::vec::Vec<_>>()
        };
        let c =
            ModelComparison::from_cross_terms(terms(&mut rng, 0.05).into_iter(), 1000.0).unwrap();
        assert!(c.gain > 0.05 && c.favours_complex(), "{c:?}");
        // The same gain seen through renders whose noise swamps it.
        let c =
            ModelComparison::from_cross_terms(terms(&mut rng, 3.0).into_iter(), 1000.0).unwrap();
        assert!(!c.favours_complex(), "{c:?}");
    }

    #[test]
    fn a_comparison_needs_pixels_and_light() {
        let t = PairedTerms {
            simple: [1.0, 1.0],
            complex: [0.5, 0.5],
        };
        assert!(ModelComparison::from_cross_terms(core::iter::empty(), 1.0).is_none());
        assert!(ModelComparison::from_cross_terms([t; 3].into_iter(), 0.0).is_none());
    }

    #[test]
    fn no_pixels_no_error() {
        assert_eq!(GroupFit::default().relative_error(), None);
    }

    /// In quadrature, as a comparison's effect: a misfit the lobe leaves shrinks what it
    /// accounts for, and a lobe that fits worse accounts for none.
    #[test]
    fn a_lobe_accounts_for_its_share_of_the_error_in_quadrature() {
        assert!((cache_effect(0.05, 0.03) - 0.04).abs() < 1e-12);
        assert!(cache_effect(0.1046, 0.1042) < SPECULAR_GAIN_THRESHOLD);
        assert_eq!(cache_effect(0.03, 0.05), 0.0);
    }
}
