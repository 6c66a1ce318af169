//! The panorama's calibration, read off the lights it sees. A light reflects nothing, so a
//! pixel wholly inside one shows its radiance and nothing else: the panorama's value there
//! over the declared radiance is the view's exposure error times the light's radiance error.
//! Every recovered reflectance scales with that factor, and nothing else in the input shows
//! it: the interreflections absorb part of it, so a panorama 2x too bright was recovered
//! with every colour below 1 and lobes on diffuse walls (docs/stability.md).

use glam::Vec3;
use serde::Serialize;

use super::pixels::LightPixel;
use crate::images::Image;

/// The largest relative difference, in any channel, between a light's pixels and its
/// declared radiance before recovery warns. The references' light pixels equal the
/// radiance to 0.26-0.42% (their READMEs); bench stability saw a 2% exposure error put
/// box-diffuse's reflectances about 1% off (the target), and 10% change a class.
pub const CALIBRATION_TOLERANCE: f64 = 0.02;

/// The panorama over one light in one view.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct LightReading {
    pub light: String,
    pub view: String,
    /// Pixels wholly inside the light, with their four neighbours.
    pub pixels: u32,
    pub declared: [f64; 3],
    /// The panorama's mean over those pixels (exposure applied).
    pub measured: [f64; 3],
    /// `measured / declared` per channel; `null` where the light is declared dark.
    pub ratio: [Option<f64>; 3],
}

impl LightReading {
    /// One line for a reader: the light, the view, and the panorama over the declared
    /// radiance per channel.
    pub fn describe(&self) -> String {
        format!(
            "light '{}' in view '{}' reads {} x its declared radiance (R G B, {} pixels)",
            self.light,
            self.view,
            self.ratios_text(),
            self.pixels
        )
    }

    /// The ratios as `R G B`, `-` for a channel declared dark.
    fn ratios_text(&self) -> String {
        let ratios: Vec<String> = self
            .ratio
            .iter()
            .map(|q| q.map_or("-".into(), |q| format!("{q:.3}")))
            .collect();
        ratios.join(" ")
    }

    /// The channel furthest from its declared radiance, as `measured / declared`.
    fn worst_ratio(&self) -> Option<f64> {
        self.ratio
            .iter()
            .flatten()
            .copied()
            .max_by(|a, b| (a - 1.0).abs().total_cmp(&(b - 1.0).abs()))
    }
}

/// One reading per light and view that sees it, lights in scene order, then views.
/// `pixels` are in view and row order; sums run in that order (no thread-dependent bits).
pub fn read_lights(
    pixels: &[LightPixel],
    real: &[Image],
    light_names: &[String],
    light_radiance: &[Vec3],
    view_names: &[String],
) -> Vec<LightReading> {
    let mut readings = Vec::new();
    for (l, (name, radiance)) in light_names.iter().zip(light_radiance).enumerate() {
        for (v, view) in view_names.iter().enumerate() {
            let mut sum = [0.0f64; 3];
            let mut count = 0u32;
            for p in pixels
                .iter()
                .filter(|p| p.light as usize == l && p.view as usize == v)
            {
                let image = &real[v];
                let value = image.pixels[(p.y * image.width + p.x) as usize];
                for c in 0..3 {
                    sum[c] += value[c] as f64;
                }
                count += 1;
            }
            if count == 0 {
                continue;
            }
            let declared = radiance.to_array().map(f64::from);
            let measured = sum.map(|s| s / count as f64);
            let mut ratio = [None; 3];
            for c in 0..3 {
                if declared[c] > 0.0 {
                    ratio[c] = Some(measured[c] / declared[c]);
                }
            }
            readings.push(LightReading {
                light: name.clone(),
                view: view.clone(),
                pixels: count,
                declared,
                measured,
                ratio,
            });
        }
    }
    readings
}

/// A light declared dark (radiance 0) whose pixels read more than this fraction of the
/// brightest light's radiance: far brighter than a lamp's glass or shade lit by the room
/// (the references' groups read 0.2-1.5% of their lamp's radiance on average), so most likely a lamp
/// that was on when the panorama was taken.
pub const DARK_LIGHT_LIT: f64 = 0.1;

/// A warning for each reading off by more than [`CALIBRATION_TOLERANCE`] in some channel,
/// and for each light declared dark that reads more than [`DARK_LIGHT_LIT`] of
/// `brightest`, the largest channel of any light's declared radiance.
pub fn calibration_warnings(readings: &[LightReading], brightest: f64) -> Vec<String> {
    let mut warnings = Vec::new();
    for r in readings {
        let Some(worst) = r.worst_ratio() else {
            let reads = r.measured.iter().copied().fold(0.0, f64::max);
            if r.declared == [0.0; 3] && brightest > 0.0 && reads > DARK_LIGHT_LIT * brightest {
                warnings.push(format!(
                    "light '{}' is declared dark (radiance 0) but reads [{:.3}, {:.3}, {:.3}] in view '{}' over {} pixels wholly inside it, {:.0}% of the brightest light's radiance: if it was on when the panorama was taken, give its radiance; recovery explains the light it sheds with the materials",
                    r.light,
                    r.measured[0],
                    r.measured[1],
                    r.measured[2],
                    r.view,
                    r.pixels,
                    100.0 * reads / brightest
                ));
            }
            continue;
        };
        if (worst - 1.0).abs() <= CALIBRATION_TOLERANCE {
            continue;
        }
        warnings.push(format!(
            "light '{}' reads {worst:.3}x its declared radiance in view '{}' (R G B {} over {} pixels wholly inside it): the view's exposure or the light's radiance is off by that factor, and every recovered reflectance with it; where calibration was off by 10%, diffuse reflectances came out 5-6% off and a class changed (docs/stability.md)",
            r.light,
            r.view,
            r.ratios_text(),
            r.pixels
        ));
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: u32, height: u32, value: [f32; 3]) -> Image {
        Image {
            width,
            height,
            pixels: vec![value; (width * height) as usize],
        }
    }

    fn pixel(view: u32, x: u32, light: u16) -> LightPixel {
        LightPixel {
            view,
            x,
            y: 1,
            light,
        }
    }

    #[test]
    fn a_reading_per_light_and_view_with_the_mean_over_its_pixels() {
        let mut first = image(4, 4, [0.1; 3]);
        first.pixels[4 + 1] = [10.0, 20.0, 30.0];
        first.pixels[4 + 2] = [12.0, 22.0, 32.0];
        let second = image(4, 4, [24.0, 0.0, 5.0]);
        let readings = read_lights(
            &[
                pixel(0, 1, 1),
                pixel(0, 2, 1),
                pixel(1, 1, 1),
                pixel(1, 2, 0),
            ],
            &[first, second],
            &["bulb".into(), "lamp".into()],
            &[Vec3::ZERO, Vec3::new(11.0, 20.0, 31.0)],
            &["a".into(), "b".into()],
        );
        let names: Vec<(&str, &str, u32)> = readings
            .iter()
            .map(|r| (r.light.as_str(), r.view.as_str(), r.pixels))
            .collect();
        assert_eq!(
            names,
            [("bulb", "b", 1), ("lamp", "a", 2), ("lamp", "b", 1)]
        );
        // A dark light has no ratio: it cannot be off by a factor.
        assert_eq!(readings[0].ratio, [None; 3]);
        assert_eq!(readings[1].measured, [11.0, 21.0, 31.0]);
        assert_eq!(readings[1].ratio, [Some(1.0), Some(21.0 / 20.0), Some(1.0)]);
        assert_eq!(readings[2].ratio[0], Some(24.0 / 11.0));
    }

    #[test]
    fn readings_off_by_more_than_the_tolerance_are_warned_of_with_their_factor() {
        let reading = |ratio: [Option<f64>; 3]| LightReading {
            light: "lamp".into(),
            view: "up".into(),
            pixels: 7,
            declared: [1.0; 3],
            measured: ratio.map(|q| q.unwrap_or(0.0)),
            ratio,
        };
        let within = 1.0 + 0.9 * CALIBRATION_TOLERANCE;
        let beyond = 1.0 - 1.1 * CALIBRATION_TOLERANCE;
        let warnings = calibration_warnings(
            &[
                reading([Some(within), Some(1.0), Some(2.0 - within)]),
                reading([None; 3]),
                reading([Some(1.0), Some(beyond), None]),
                reading([Some(2.0), Some(2.0), Some(2.0)]),
            ],
            1.0,
        );
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(warnings[0].contains(
            "reads 0.978x its declared radiance in view 'up' (R G B 1.000 0.978 - over 7 pixels"
        ));
        assert!(warnings[1].contains("reads 2.000x"), "{}", warnings[1]);
        assert!(warnings[1].contains("exposure or the light's radiance"));
    }

    #[test]
    fn a_light_declared_dark_is_warned_of_only_when_it_reads_bright() {
        let dark = |measured: [f64; 3]| LightReading {
            light: "bulb".into(),
            view: "down".into(),
            pixels: 3,
            declared: [0.0; 3],
            measured,
            ratio: [None; 3],
        };
        let brightest = 50.0;
        let lit = [0.5, 1.2 * DARK_LIGHT_LIT * brightest, 0.5];
        let warnings = calibration_warnings(
            &[
                dark([0.2, 0.3, 0.2]),
                dark(lit),
                dark([0.9 * DARK_LIGHT_LIT * brightest; 3]),
            ],
            brightest,
        );
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains("light 'bulb' is declared dark")
                && warnings[0].contains("in view 'down'")
                && warnings[0].contains("12% of the brightest"),
            "{}",
            warnings[0]
        );
        // With no light declared bright there is nothing to measure against.
        assert!(calibration_warnings(&[dark(lit)], 0.0).is_empty());
    }
}
