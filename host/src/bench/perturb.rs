//! Perturbed copies of a scene for `relume bench stability`: the panorama box-averaged,
//! scaled (an exposure error) and given multiplicative Gaussian noise, and the brightest
//! light's radiance scaled (a calibration error), written as a new scene.toml beside new
//! views, in the style of `relume bench downsample`.

use std::path::{Path, PathBuf};

use relume_core::rng::{stream_key, Sampler};

use crate::downsample;
use crate::error::Error;
use crate::images::Image;
use crate::scene_file;

/// What to change; [`Perturbation::NONE`] copies the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Perturbation {
    /// Box-average the views by this integer factor.
    pub factor: u32,
    /// Multiply every pixel by this (an exposure error: 1.05 is 5% too bright).
    pub exposure: f32,
    /// Relative standard deviation of the multiplicative Gaussian noise (0.01 is 1%).
    pub noise: f64,
    /// The noise's seed: the same seed gives the same noise, scaled by `noise`.
    pub noise_seed: u64,
    /// Multiply the brightest light's radiance in the scene file by this (the first light
    /// can be switched off: the living room's desk lamp is).
    pub light: f32,
}

impl Perturbation {
    pub const NONE: Perturbation = Perturbation {
        factor: 1,
        exposure: 1.0,
        noise: 0.0,
        noise_seed: 0,
        light: 1.0,
    };
}

/// A standard normal variate (Box-Muller) from the stream of one pixel and channel, so
/// the noise depends on the seed and the pixel only.
fn standard_normal(seed: u64, view: usize, pixel: usize, channel: usize) -> f64 {
    let mut rng = Sampler::from_key(stream_key(&[
        seed,
        0x0015_E000,
        view as u64,
        pixel as u64,
        channel as u64,
    ]));
    let bits = |rng: &mut Sampler| ((rng.next_u32() as u64) << 32) | rng.next_u32() as u64;
    // u1 in (0, 1] so that its log is finite; u2 in [0, 1).
    let u1 = ((bits(&mut rng) >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
    let u2 = (bits(&mut rng) >> 11) as f64 / (1u64 << 53) as f64;
    libm::sqrt(-2.0 * libm::log(u1)) * libm::cos(2.0 * core::f64::consts::PI * u2)
}

/// Multiplies each channel of each pixel by `1 + sigma z`, `z` standard normal, clamped
/// at 0 (radiance is never negative).
pub fn add_noise(image: &mut Image, sigma: f64, seed: u64, view: usize) {
    if sigma == 0.0 {
        return;
    }
    for (i, p) in image.pixels.iter_mut().enumerate() {
        for (c, v) in p.iter_mut().enumerate() {
            let factor = (1.0 + sigma * standard_normal(seed, view, i, c)).max(0.0);
            *v = (*v as f64 * factor) as f32;
        }
    }
}

/// Multiplies every channel by `factor`.
pub fn scale(image: &mut Image, factor: f32) {
    for v in image.pixels.iter_mut().flatten() {
        *v *= factor;
    }
}

/// Writes `out/scene.toml` and `out/views/<view>.exr`: `scene` with `p` applied. Returns
/// the new scene file. Errors name the scene file: no lit light to change, a view without
/// an image, a view size not divisible by the factor.
pub fn write_perturbed(scene: &Path, p: &Perturbation, out: &Path) -> Result<PathBuf, Error> {
    if p.factor == 0 || !(p.exposure > 0.0 && p.light > 0.0 && p.noise >= 0.0) {
        return Err(Error::Usage(format!(
            "perturbation needs factor >= 1, exposure and light > 0, noise >= 0: {p:?}"
        )));
    }
    let mut desc = scene_file::load_scene(scene)?;
    if p.light != 1.0 {
        let brightest = desc
            .lights
            .iter_mut()
            .filter(|l| l.radiance.iter().sum::<f32>() > 0.0)
            .max_by(|a, b| {
                let sum = |l: &scene_file::LightDesc| l.radiance.iter().sum::<f32>();
                sum(a).total_cmp(&sum(b))
            });
        let Some(light) = brightest else {
            return Err(Error::input(
                scene,
                "has no [[light]] with a radiance above 0 to perturb",
            ));
        };
        light.radiance = light.radiance.map(|r| r * p.light);
    }
    downsample::write_derived_scene(scene, desc, p.factor, out, "perturb", |vi, image| {
        if p.exposure != 1.0 {
            scale(image, p.exposure);
        }
        add_noise(image, p.noise, p.noise_seed, vi);
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::images;

    fn flat(n: u32, v: f32) -> Image {
        Image {
            width: n,
            height: n,
            pixels: vec![[v, 2.0 * v, 0.5 * v]; (n * n) as usize],
        }
    }

    #[test]
    fn noise_is_deterministic_per_seed_and_of_the_requested_size() {
        let mut a = flat(64, 1.0);
        let mut b = flat(64, 1.0);
        let mut c = flat(64, 1.0);
        add_noise(&mut a, 0.02, 7, 0);
        add_noise(&mut b, 0.02, 7, 0);
        add_noise(&mut c, 0.02, 8, 0);
        assert_eq!(a, b);
        assert_ne!(a, c);
        let rel: Vec<f64> = a
            .pixels
            .iter()
            .flat_map(|p| [p[0] as f64 - 1.0, p[1] as f64 / 2.0 - 1.0])
            .collect();
        let n = rel.len() as f64;
        let mean = rel.iter().sum::<f64>() / n;
        let sd = (rel.iter().map(|r| (r - mean) * (r - mean)).sum::<f64>() / n).sqrt();
        // 8192 draws: the mean is within 4 standard errors of 0, the deviation within 5%.
        assert!(mean.abs() < 4.0 * 0.02 / n.sqrt(), "mean {mean}");
        assert!((sd / 0.02 - 1.0).abs() < 0.05, "sd {sd}");
        // Another view draws other noise; a larger sigma scales the same draws.
        let mut other_view = flat(64, 1.0);
        add_noise(&mut other_view, 0.02, 7, 1);
        assert_ne!(a, other_view);
        let mut twice = flat(64, 1.0);
        add_noise(&mut twice, 0.04, 7, 0);
        let (x, y) = (a.pixels[5][0] as f64 - 1.0, twice.pixels[5][0] as f64 - 1.0);
        assert!((y - 2.0 * x).abs() < 1e-6, "{x} {y}");
    }

    #[test]
    fn exposure_scales_every_channel_exactly() {
        let mut image = Image {
            width: 2,
            height: 1,
            pixels: vec![[0.1, 0.2, 0.3], [1.5, 0.0, 7.25]],
        };
        let original = image.clone();
        scale(&mut image, 1.05);
        for (p, q) in image.pixels.iter().zip(&original.pixels) {
            for c in 0..3 {
                assert_eq!(p[c], q[c] * 1.05f32);
            }
        }
    }

    fn cornell() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.toml")
    }

    #[test]
    fn a_perturbed_scene_has_the_changed_light_views_and_sizes() {
        let dir = tempfile::tempdir().unwrap();
        let original = scene_file::load_scene(&cornell()).unwrap();
        let p = Perturbation {
            factor: 2,
            exposure: 0.9,
            light: 1.1,
            ..Perturbation::NONE
        };
        let path = write_perturbed(&cornell(), &p, dir.path()).unwrap();
        let desc = scene_file::load_scene(&path).unwrap();
        assert_eq!(desc.groups, original.groups);
        assert_eq!(
            desc.lights[0].radiance,
            original.lights[0].radiance.map(|r| r * 1.1)
        );
        let v = &original.views[0];
        let real = images::read_view_image(v.image.as_ref().unwrap(), v, v.exposure).unwrap();
        let mut expected = downsample::box_average(&real, 2);
        scale(&mut expected, 0.9);
        let w = &desc.views[0];
        assert_eq!(w.size, [v.size[0] / 2, v.size[1] / 2]);
        let got = images::read_view_image(w.image.as_ref().unwrap(), w, w.exposure).unwrap();
        assert_eq!(got, expected);
    }

    #[test]
    fn the_light_changed_is_the_brightest_even_when_the_first_is_off() {
        let dir = tempfile::tempdir().unwrap();
        let mut desc = scene_file::load_scene(&cornell()).unwrap();
        let lit = desc.lights[0].clone();
        desc.lights.insert(
            0,
            scene_file::LightDesc {
                object: "lamp_off".into(),
                radiance: [0.0; 3],
            },
        );
        desc.lights.push(scene_file::LightDesc {
            object: "lamp_dim".into(),
            radiance: lit.radiance.map(|r| 0.5 * r),
        });
        let scene = dir.path().join("two-lights.toml");
        std::fs::write(&scene, downsample::scene_toml(&desc).unwrap()).unwrap();
        let p = Perturbation {
            light: 1.1,
            ..Perturbation::NONE
        };
        let out = write_perturbed(&scene, &p, &dir.path().join("out")).unwrap();
        let lights = scene_file::load_scene(&out).unwrap().lights;
        assert_eq!(lights[0].radiance, [0.0; 3]);
        assert_eq!(lights[1].radiance, lit.radiance.map(|r| r * 1.1));
        assert_eq!(lights[2].radiance, lit.radiance.map(|r| 0.5 * r));
    }

    #[test]
    fn bad_perturbations_are_errors_naming_the_scene() {
        let dir = tempfile::tempdir().unwrap();
        let p = Perturbation {
            factor: 3,
            ..Perturbation::NONE
        };
        let e = write_perturbed(&cornell(), &p, dir.path()).unwrap_err();
        assert!(
            e.to_string().contains("scene.toml") && e.to_string().contains("factor 3"),
            "{e}"
        );
        let p = Perturbation {
            exposure: 0.0,
            ..Perturbation::NONE
        };
        assert!(write_perturbed(&cornell(), &p, dir.path()).is_err());
    }
}
