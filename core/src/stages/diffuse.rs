//! Stage 1: every group diffuse, `rho_d <- rho_d * mean(real) / mean(rendered)` per group
//! and channel, repeated (each step a full global-illumination render) until no
//! reflectance moves by more than [`crate::fit::DIFFUSE_CONVERGED`].

use crate::fit::{GroupFit, DIFFUSE_THRESHOLD, MIN_PIXELS_FOR_MODEL_CHOICE};

/// Reflectances are kept below this: a diffuse reflectance of 1 or more is unphysical and
/// would make the global illumination diverge while the iteration overshoots.
pub const MAX_DIFFUSE_REFLECTANCE: f64 = 0.99;

/// One step of the update for one group. Groups without pixels keep their value.
/// Returns the new reflectance and the largest relative change over the channels.
pub fn update(rho_d: [f64; 3], fit: &GroupFit) -> ([f64; 3], f64) {
    if fit.pixels == 0 {
        return (rho_d, 0.0);
    }
    let ratio = fit.mean_ratio();
    let mut out = rho_d;
    let mut change = 0.0f64;
    for c in 0..3 {
        let next = (rho_d[c] * ratio[c]).clamp(0.0, MAX_DIFFUSE_REFLECTANCE);
        if rho_d[c] > 0.0 {
            change = change.max(((next - rho_d[c]) / rho_d[c]).abs());
        } else if next > 0.0 {
            change = f64::INFINITY;
        }
        out[c] = next;
    }
    (out, change)
}

/// What stage 1 concludes about a group.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DiffuseVerdict {
    /// The diffuse model explains the group within [`DIFFUSE_THRESHOLD`].
    Diffuse,
    /// The error stays above the threshold: the group goes on to the isotropic stage.
    NeedsSpecular,
    /// Too few pure pixels to choose a model: kept diffuse, and reported.
    BarelySeen,
    /// No pure pixel at all: nothing can be said.
    Unseen,
}

pub fn verdict(fit: &GroupFit) -> DiffuseVerdict {
    if fit.pixels == 0 {
        return DiffuseVerdict::Unseen;
    }
    if fit.pixels < MIN_PIXELS_FOR_MODEL_CHOICE {
        return DiffuseVerdict::BarelySeen;
    }
    match fit.relative_error() {
        Some(e) if e > DIFFUSE_THRESHOLD => DiffuseVerdict::NeedsSpecular,
        Some(_) => DiffuseVerdict::Diffuse,
        None => DiffuseVerdict::Unseen,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    fn fit_of(real: f32, rendered: f32, n: u32) -> GroupFit {
        let mut f = GroupFit::default();
        for _ in 0..n {
            f.add(Vec3::splat(real), Vec3::splat(rendered), Vec3::ZERO);
        }
        f
    }

    #[test]
    fn update_scales_by_the_ratio_of_means() {
        let (rho, change) = update([0.5, 0.4, 0.2], &fit_of(0.3, 0.6, 10));
        assert_eq!(rho, [0.25, 0.2, 0.1]);
        assert!((change - 0.5).abs() < 1e-12);
    }

    #[test]
    fn update_never_leaves_the_physical_range_and_ignores_unseen_groups() {
        let (rho, _) = update([0.9, 0.9, 0.9], &fit_of(1.0, 0.1, 10));
        assert!(rho.iter().all(|&r| r <= MAX_DIFFUSE_REFLECTANCE));
        assert_eq!(update([0.3; 3], &GroupFit::default()), ([0.3; 3], 0.0));
    }

    #[test]
    fn fixed_point_iteration_converges_for_a_linear_transport() {
        // Rendered mean = 0.8 * rho + 0.1 (direct plus indirect that grows with rho):
        // the truth rho = 0.6 gives 0.58.
        let mut rho = [0.5; 3];
        for _ in 0..40 {
            let rendered = (0.8 * rho[0] + 0.1) as f32;
            rho = update(rho, &fit_of(0.58, rendered, 100)).0;
        }
        assert!((rho[0] - 0.6).abs() < 1e-4, "{rho:?}");
    }

    #[test]
    fn verdicts_follow_the_threshold_and_pixel_counts() {
        assert_eq!(verdict(&fit_of(1.0, 1.01, 100)), DiffuseVerdict::Diffuse);
        assert_eq!(
            verdict(&fit_of(1.0, 1.2, 100)),
            DiffuseVerdict::NeedsSpecular
        );
        assert_eq!(verdict(&fit_of(1.0, 1.2, 3)), DiffuseVerdict::BarelySeen);
        assert_eq!(verdict(&GroupFit::default()), DiffuseVerdict::Unseen);
    }
}
