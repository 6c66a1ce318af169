//! Stage 3: texture detection by the paper's statistic on a group's difference image.
//!
//! Exact definition. Let `D(p) = lum(real(p)) - lum(rendered(p))` over the group's pure
//! pixels, `rendered` being the best untextured model. For every pair of pure pixels of the
//! group `TEXTURE_STEP` apart along a row or a column of one view, take `|D(p) - D(q)|`.
//! With `m` the largest of these, keep those above `TEXTURE_FLOOR * m`; the feature is
//! their mean divided by `m`, in (0, 1]. A texture left unexplained puts many strong
//! differences all over the group (feature high); a missed anisotropic highlight or render
//! noise puts few large ones among many small ones (feature low). The group is textured
//! when the feature exceeds `TEXTURE_THRESHOLD`.

use crate::fit::{ErrorEstimate, NOISE_BOUND_SIGNIFICANCE, TEXTURE_FLOOR, TEXTURE_THRESHOLD};

/// The feature of the absolute step differences `diffs` (any order); `None` when there is
/// no difference at all (no pairs, or a perfect fit).
pub fn texture_feature(diffs: &[f32]) -> Option<f64> {
    let max = diffs
        .iter()
        .filter(|d| d.is_finite())
        .fold(0.0f64, |m, &d| m.max(libm::fabs(d as f64)));
    if !(max > 0.0) {
        return None;
    }
    let floor = TEXTURE_FLOOR * max;
    let (sum, n) = diffs
        .iter()
        .filter(|d| d.is_finite())
        .map(|&d| libm::fabs(d as f64))
        .filter(|&d| d > floor)
        .fold((0.0f64, 0u64), |(s, n), d| (s + d, n + 1));
    Some(sum / n.max(1) as f64 / max)
}

/// The statistic recovery decides on: the RMS change of the unexplained log-radiance over
/// `TEXTURE_STEP` pixels, with render noise removed. Each item is one pixel pair's change
/// `(delta_a, delta_b)` of `ln(real / rendered)` measured against two independent renders
/// A and B of the same model: the mean of `delta_a * delta_b` is the mean squared change
/// of `ln(real / truth-of-the-model)` alone, as the renders' noises are independent. So
/// the statistic needs neither a noise estimate nor a maximum (the paper's feature's
/// outlier-driven normalisation, which did not separate on our references; docs/recovery.md).
/// `None` without pairs.
pub fn cross_contrast(pairs: impl Iterator<Item = (f64, f64)>) -> Option<f64> {
    let (sum, n) = pairs
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .fold((0.0f64, 0u64), |(s, n), (a, b)| (s + a * b, n + 1));
    (n > 0).then(|| libm::sqrt((sum / n as f64).max(0.0)))
}

/// The cross contrast with the panorama's own noise taken out. The two renders' noises
/// cancel in [`cross_contrast`], the panorama's does not: it is in both log-ratios, and
/// adds `2 sigma^2` to the squared contrast for a relative pixel noise `sigma`. With
/// `panorama_noise` an upper bound on `sigma`, what is left is texture (or misfit) that
/// noise cannot explain.
pub fn noise_corrected_contrast(contrast: f64, panorama_noise: f64) -> f64 {
    libm::sqrt((contrast * contrast - 2.0 * panorama_noise * panorama_noise).max(0.0))
}

/// An upper bound on the panorama's relative pixel noise from the groups' bias-only
/// errors. A group's bias-only squared error is its model's squared bias plus the
/// panorama's noise variance (both pooled over its pixels), so no group's true error is
/// below the noise; a measured one is, by its standard error. Each measurement bounds the
/// noise by its upper confidence bound at `NOISE_BOUND_SIGNIFICANCE`, and the bound is the
/// tightest of these: a group measured precisely decides, one measured as 0 +- 0.1 does
/// not. `None` without measurements.
pub fn panorama_noise_bound(errors: impl Iterator<Item = ErrorEstimate>) -> Option<f64> {
    errors
        .map(|e| e.upper_bound(NOISE_BOUND_SIGNIFICANCE))
        .filter(|b| b.is_finite())
        .reduce(f64::min)
}

/// Whether the cross contrast says "textured".
pub fn has_texture_contrast(contrast: f64) -> bool {
    contrast > crate::fit::TEXTURE_CONTRAST_THRESHOLD
}

/// Whether a feature says "textured".
pub fn is_textured(feature: f64) -> bool {
    feature > TEXTURE_THRESHOLD
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    #[test]
    fn a_pattern_all_over_the_group_is_textured() {
        // A checker: every step difference is either 0 or the full contrast.
        let diffs: Vec<f32> = (0..1000)
            .map(|i| if i % 2 == 0 { 0.3 } else { 0.0 })
            .collect();
        let f = texture_feature(&diffs).unwrap();
        assert!((f - 1.0).abs() < 1e-9 && is_textured(f));
    }

    #[test]
    fn one_highlight_among_small_differences_is_not_textured() {
        let mut diffs: Vec<f32> = (0..1000).map(|i| 0.01 + 0.01 * ((i % 7) as f32)).collect();
        diffs.extend([1.0, 0.8, 0.6]);
        let f = texture_feature(&diffs).unwrap();
        assert!(f < 0.1 && !is_textured(f), "{f}");
    }

    #[test]
    fn the_panoramas_noise_is_taken_out_of_the_contrast() {
        // A uniform group under a panorama with 10% relative noise: its log-ratio steps
        // have a contrast of sqrt(2) * 10% from the noise alone.
        let noisy_uniform = 0.1 * libm::sqrt(2.0);
        assert!(has_texture_contrast(noisy_uniform));
        assert!(!has_texture_contrast(noise_corrected_contrast(
            noisy_uniform,
            0.1
        )));
        // A picture's contrast of 0.3 under the same noise keeps most of it.
        let noisy_picture = libm::sqrt(0.3 * 0.3 + 2.0 * 0.1 * 0.1);
        let corrected = noise_corrected_contrast(noisy_picture, 0.1);
        assert!((corrected - 0.3).abs() < 1e-9 && has_texture_contrast(corrected));
        // A clean panorama: nothing to take out.
        assert_eq!(noise_corrected_contrast(0.2, 0.0), 0.2);
    }

    #[test]
    fn the_noise_bound_is_the_tightest_upper_confidence_bound() {
        // Glossy at 10% noise: a mirror measured at 0 +- 0.1 beside a wall measured at
        // 0.0535 +- 0.002 and a badly fitted sphere. The mirror's bare zero would say the
        // panorama has no noise; its upper bound, sqrt(2) 0.1, is looser than the wall's.
        let mirror = ErrorEstimate::from_squared(-0.0004, 0.1 * 0.1);
        let wall = ErrorEstimate::from_squared(0.0535 * 0.0535, 2.0 * 0.0535 * 0.002);
        let sphere = ErrorEstimate::from_squared(0.09, 0.001);
        let bound = panorama_noise_bound([sphere, mirror, wall].into_iter()).unwrap();
        let expected = libm::sqrt(0.0535 * 0.0535 + NOISE_BOUND_SIGNIFICANCE * 0.000214);
        assert!((bound - expected).abs() < 1e-12, "{bound} {expected}");
        assert!(bound > 0.0535 && bound < 0.06);
        // When the imprecise group is the only one, it still bounds the noise.
        let alone = panorama_noise_bound([mirror].into_iter()).unwrap();
        assert!((alone - libm::sqrt(NOISE_BOUND_SIGNIFICANCE) * 0.1).abs() < 1e-12);
        assert_eq!(panorama_noise_bound(core::iter::empty()), None);
    }

    #[test]
    fn cross_contrast_removes_independent_noise() {
        // A true contrast of 0.3 seen through two renders with independent noise of 0.2.
        let mut rng = crate::rng::Sampler::for_pixel_sample(3, 0, 0, 0);
        let mut noise = || {
            let [a, b] = rng.next_2d();
            0.2 * 1.732 * (2.0 * a as f64 - 1.0) + 0.0 * b as f64
        };
        let pairs: Vec<(f64, f64)> = (0..20000)
            .map(|i| {
                let truth = if i % 2 == 0 { 0.3 } else { -0.3 };
                (truth + noise(), truth + noise())
            })
            .collect();
        let c = cross_contrast(pairs.iter().copied()).unwrap();
        assert!((c - 0.3).abs() < 0.01, "{c}");
        assert!(has_texture_contrast(c));
        // Noise alone: no contrast left.
        let noise_only: Vec<(f64, f64)> = (0..20000).map(|_| (noise(), noise())).collect();
        let c = cross_contrast(noise_only.iter().copied()).unwrap();
        assert!(c < 0.03 && !has_texture_contrast(c), "{c}");
        assert_eq!(cross_contrast(core::iter::empty()), None);
    }

    #[test]
    fn no_difference_gives_no_feature() {
        assert_eq!(texture_feature(&[]), None);
        assert_eq!(texture_feature(&[0.0, 0.0]), None);
        assert_eq!(texture_feature(&[f32::NAN]), None);
    }
}
