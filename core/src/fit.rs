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
        self.pixels += 1;
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
        self.pixels += other.pixels;
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

/// A group whose diffuse fit has an error below this is diffuse (the paper's 5%).
pub const DIFFUSE_THRESHOLD: f64 = 0.05;
/// The diffuse iteration stops when no group's reflectance changes by more than this
/// (relative, per channel) in one step.
pub const DIFFUSE_CONVERGED: f64 = 2e-4;
/// The diffuse iteration stops after this many steps at the most.
pub const DIFFUSE_MAX_STEPS: u32 = 30;
/// A specular model is kept only when a render of the group shows it removes more than this
/// much relative error compared with the diffuse model (host `recover`, stage 2); a group
/// whose diffuse error is already below it is not tried.
pub const SPECULAR_GAIN_THRESHOLD: f64 = 0.01;
/// A fitted isotropic metal whose specular part is above this fraction of its reflectance,
/// with a roughness at most [`MIRROR_MAX_ROUGHNESS`], is tested as a mirror (the paper's 90%).
pub const MIRROR_SPECULAR_FRACTION: f64 = 0.9;
pub const MIRROR_MAX_ROUGHNESS: f64 = 0.02;
/// Largest relative spread of the mirror's specular colour over the channels (the paper's
/// "reflected colour close to the incident colour").
pub const MIRROR_MAX_TINT: f64 = 0.1;
/// Fewer pure pixels than this: the group is reported as barely seen, and its fit is not
/// trusted to pick a more complex model.
pub const MIN_PIXELS_FOR_MODEL_CHOICE: u32 = 16;

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

    #[test]
    fn no_pixels_no_error() {
        assert_eq!(GroupFit::default().relative_error(), None);
    }
}
