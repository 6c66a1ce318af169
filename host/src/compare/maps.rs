//! A recovered diffuse map against the truth's (`relume compare materials`): its PSNR, the
//! ceiling of that PSNR for a map of its size (the truth area-averaged to it), its level
//! (mean luminance), and how a PSNR is written in JSON.

use std::path::Path;

use relume_core::material::texture::{TextureGrid, Wrap};
use relume_core::math::{luminance, Vec3};

use super::materials::MaterialRow;
use crate::error::Error;
use crate::images::{self, Image};

/// A PSNR in JSON: a number, `"inf"` for a map equal to the truth's (JSON has no
/// infinity, and serde_json would write `null`, which here means "no map"), `"-inf"` for
/// a map that is not black against a black truth (a peak of 0; the table's `-infdB`),
/// `null` when there is no map to compare.
pub(super) fn psnr_json<S: serde::Serializer>(
    psnr: &Option<f64>,
    out: S,
) -> Result<S::Ok, S::Error> {
    match psnr {
        Some(db) if db.is_infinite() && *db > 0.0 => out.serialize_str("inf"),
        Some(db) if db.is_infinite() => out.serialize_str("-inf"),
        Some(db) => out.serialize_f64(*db),
        None => out.serialize_none(),
    }
}

/// PSNR of a recovered map against the truth's, peak = the truth's maximum. The recovered
/// map may have another size: it is sampled as the renderer samples it (bilinear between
/// texel centres, clamped) at the truth's texel centres; at the truth's own size that is
/// its texels, taken as they are (the centres in f32 are not exact at every size, and a
/// map equal to the truth's read 130-136 dB rather than infinite). `None` for an empty
/// image.
fn map_psnr(truth: &Image, recovered: &Image, wrap: Wrap) -> Option<f64> {
    let (t, r) = (truth, recovered);
    if t.pixels.is_empty() || r.pixels.is_empty() {
        return None;
    }
    let same_size = (r.width, r.height) == (t.width, t.height);
    let sample = |i: u32, j: u32, u: f32, v: f32| {
        if same_size {
            return r.pixels[(j * r.width + i) as usize].map(f64::from);
        }
        let grid = TextureGrid {
            width: r.width,
            height: r.height,
            wrap,
        };
        grid.taps(glam::Vec2::new(u, v))
            .iter()
            .fold([0.0f64; 3], |mut sum, &(k, a)| {
                for (s, c) in sum.iter_mut().zip(r.pixels[k]) {
                    *s += a as f64 * c as f64;
                }
                sum
            })
    };
    let peak = t
        .pixels
        .iter()
        .flatten()
        .fold(0.0f64, |m, &v| m.max(v as f64));
    let mut sum_sq = 0.0f64;
    for j in 0..t.height {
        for i in 0..t.width {
            let u = (i as f32 + 0.5) / t.width as f32;
            let v = 1.0 - (j as f32 + 0.5) / t.height as f32;
            let ours = sample(i, j, u, v);
            let theirs = t.pixels[(j * t.width + i) as usize];
            sum_sq += (0..3)
                .map(|c| {
                    let d = ours[c] - theirs[c] as f64;
                    d * d
                })
                .sum::<f64>();
        }
    }
    let mse = sum_sq / (3 * t.pixels.len()) as f64;
    Some(if mse > 0.0 {
        10.0 * libm::log10(peak * peak / mse)
    } else {
        f64::INFINITY
    })
}

/// For each of `to` cells over `from` texels: the texels it covers and the fraction of
/// each it covers, normalised to sum to one (area averaging along one axis).
fn area_weights(from: u32, to: u32) -> Vec<Vec<(usize, f64)>> {
    let scale = from as f64 / to as f64;
    (0..to)
        .map(|i| {
            let (a, b) = (i as f64 * scale, (i + 1) as f64 * scale);
            let covered: Vec<(usize, f64)> = (a.floor() as usize
                ..(b.ceil() as usize).min(from as usize))
                .map(|k| (k, b.min(k as f64 + 1.0) - a.max(k as f64)))
                .filter(|&(_, w)| w > 0.0)
                .collect();
            let total: f64 = covered.iter().map(|c| c.1).sum();
            covered.into_iter().map(|(k, w)| (k, w / total)).collect()
        })
        .collect()
}

/// `image` area-averaged to `width` x `height`: what a map of that size holds at best when
/// each of its texels is the mean of the surface it covers.
fn area_average(image: &Image, width: u32, height: u32) -> Image {
    let (wx, wy) = (
        area_weights(image.width, width),
        area_weights(image.height, height),
    );
    let mut pixels = Vec::with_capacity((width * height) as usize);
    for row in &wy {
        for column in &wx {
            let mut sum = [0.0f64; 3];
            for &(y, a) in row {
                for &(x, b) in column {
                    let p = image.pixels[y * image.width as usize + x];
                    for (s, c) in sum.iter_mut().zip(p) {
                        *s += a * b * c as f64;
                    }
                }
            }
            pixels.push(sum.map(|s| s as f32));
        }
    }
    Image {
        width,
        height,
        pixels,
    }
}

/// Sets `row`'s map figures: the recovered map's PSNR, the PSNR of the truth itself
/// area-averaged to the recovered map's size (the ceiling of any map of that size: a map
/// has about one texel per pixel that sees it, and finer detail of the truth is not in
/// the views), and its level ([`map_level_err`]). None for an empty recovered map.
/// `given_at` names each map's file and line, for a map too large to read.
pub(super) fn set_map_measures(
    row: &mut MaterialRow,
    (truth, truth_at): (&Path, String),
    (recovered, recovered_at): (&Path, String),
    wrap: Wrap,
) -> Result<(), Error> {
    let t = images::read_map(truth, 0, || truth_at)?;
    let r = images::read_map(recovered, 0, || recovered_at)?;
    if r.pixels.is_empty() {
        return Ok(());
    }
    row.diffuse_map_psnr_db = map_psnr(&t, &r, wrap);
    row.diffuse_map_psnr_ceiling_db = map_psnr(&t, &area_average(&t, r.width, r.height), wrap);
    row.diffuse_map_level_err = map_level_err(&t, &r);
    Ok(())
}

/// The recovered map's mean luminance over the truth's, less 1. Both maps span the same
/// texture square, whatever their sizes, so the mean over texels is the mean over the
/// picture. `None` for an empty map or a black truth.
fn map_level_err(truth: &Image, recovered: &Image) -> Option<f64> {
    let mean = |i: &Image| {
        let sum: f64 = i
            .pixels
            .iter()
            .map(|p| luminance(Vec3::from_array(*p)) as f64)
            .sum();
        (!i.pixels.is_empty()).then(|| sum / i.pixels.len() as f64)
    };
    let (t, r) = (mean(truth)?, mean(recovered)?);
    (t > 0.0).then(|| r / t - 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: u32, height: u32, value: impl Fn(u32, u32) -> f32) -> Image {
        let pixels = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| [value(x, y); 3])
            .collect();
        Image {
            width,
            height,
            pixels,
        }
    }

    #[test]
    fn area_average_keeps_the_mean_and_covers_partial_texels() {
        let t = image(5, 3, |x, y| (x + 7 * y) as f32);
        let a = area_average(&t, 2, 2);
        let mean =
            |i: &Image| i.pixels.iter().map(|p| p[0] as f64).sum::<f64>() / i.pixels.len() as f64;
        assert!((mean(&a) - mean(&t)).abs() < 1e-5);
        // The first cell covers columns 0, 1 and half of 2, rows 0 and half of 1.
        let expected = (0.0 + 1.0 + 0.5 * 2.0) / 2.5 + 7.0 * (0.5 / 1.5);
        assert!((a.pixels[0][0] as f64 - expected).abs() < 1e-5);
    }

    #[test]
    fn a_map_of_the_truths_own_size_has_no_ceiling_and_a_coarse_one_has_one() {
        let checker = image(8, 8, |x, y| if (x + y) % 2 == 0 { 0.8 } else { 0.2 });
        assert_eq!(
            map_psnr(&checker, &area_average(&checker, 8, 8), Wrap::Clamp),
            Some(f64::INFINITY)
        );
        // At a size whose texel centres are not exact in f32 (the textured reference's
        // 192 x 192 maps read 136 dB against themselves).
        let varied = image(192, 37, |x, y| ((x * 7 + y * 13) % 17) as f32 / 17.0);
        assert_eq!(map_psnr(&varied, &varied, Wrap::Clamp), Some(f64::INFINITY));
        assert_eq!(
            map_psnr(&varied, &area_average(&varied, 192, 37), Wrap::Clamp),
            Some(f64::INFINITY)
        );
        // A texel-sized checker averages to grey at any coarser size: the ceiling is the
        // PSNR of the grey map, 20 log10(0.8 / 0.3).
        let ceiling = map_psnr(&checker, &area_average(&checker, 4, 4), Wrap::Clamp).unwrap();
        assert!(
            (ceiling - 20.0 * libm::log10(0.8f64 / 0.3)).abs() < 1e-4,
            "{ceiling}"
        );
        let grey = image(4, 4, |_, _| 0.5);
        assert!((map_psnr(&checker, &grey, Wrap::Clamp).unwrap() - ceiling).abs() < 1e-4);
    }

    #[test]
    fn a_maps_level_is_its_mean_luminance_over_the_truths_whatever_its_size() {
        let checker = image(8, 8, |x, y| if (x + y) % 2 == 0 { 0.8 } else { 0.2 });
        // A grey of the checker's mean is level with it, at a quarter of its texels.
        let level = map_level_err(&checker, &image(4, 4, |_, _| 0.5)).unwrap();
        assert!(level.abs() < 1e-6, "{level}");
        let dark = map_level_err(&checker, &image(2, 2, |_, _| 0.475)).unwrap();
        assert!((dark + 0.05).abs() < 1e-6, "{dark}");
        assert_eq!(map_level_err(&image(2, 2, |_, _| 0.0), &checker), None);
        assert_eq!(map_level_err(&checker, &image(0, 0, |_, _| 0.5)), None);
    }

    #[test]
    fn a_map_equal_to_the_truths_is_written_inf_in_json_not_the_null_of_no_map() {
        let row = |psnr, ceiling| MaterialRow {
            diffuse_map_psnr_db: psnr,
            diffuse_map_psnr_ceiling_db: ceiling,
            ..MaterialRow::default()
        };
        let json = |r: MaterialRow| serde_json::to_value(r).unwrap();
        let exact = json(row(Some(f64::INFINITY), Some(f64::INFINITY)));
        assert_eq!(exact["diffuse_map_psnr_db"], "inf");
        assert_eq!(exact["diffuse_map_psnr_ceiling_db"], "inf");
        let coarse = json(row(Some(22.5), Some(25.75)));
        assert_eq!(coarse["diffuse_map_psnr_db"], 22.5);
        assert_eq!(coarse["diffuse_map_psnr_ceiling_db"], 25.75);
        assert!(json(row(None, None))["diffuse_map_psnr_db"].is_null());
    }

    /// A black truth map (a peak of 0) against one that is not reads -inf dB, as the table
    /// says; the JSON wrote null, which there means that the group has no map.
    #[test]
    fn a_map_against_a_black_truth_is_written_minus_inf_in_json_not_the_null_of_no_map() {
        let black = image(4, 4, |_, _| 0.0);
        let psnr = map_psnr(&black, &image(4, 4, |_, _| 0.5), Wrap::Clamp);
        assert_eq!(psnr, Some(f64::NEG_INFINITY));
        assert_eq!(map_psnr(&black, &black, Wrap::Clamp), Some(f64::INFINITY));
        let row = MaterialRow {
            diffuse_map_psnr_db: psnr,
            diffuse_map_psnr_ceiling_db: Some(f64::INFINITY),
            ..MaterialRow::default()
        };
        let json = serde_json::to_value(row).unwrap();
        assert_eq!(json["diffuse_map_psnr_db"], "-inf");
        assert_eq!(json["diffuse_map_psnr_ceiling_db"], "inf");
    }
}
