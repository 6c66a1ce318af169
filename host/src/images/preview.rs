//! Tone-mapped 8-bit sRGB PNG previews of linear images, for people: at a given exposure or
//! at one that shows a percentile of luminance at a set display value.

use std::io::Write;
use std::path::Path;

use relume_core::math;

use super::{check_buffer, linear_to_srgb, Image};
use crate::error::Error;

/// The luminance percentile that [`write_png_preview`]'s auto-exposure maps to
/// [`PREVIEW_TARGET`].
pub const PREVIEW_PERCENTILE: f64 = 0.99;

/// Display value (before sRGB encoding) of the auto-exposure percentile.
pub const PREVIEW_TARGET: f32 = 0.9;

/// Encodes into `out` an 8-bit sRGB preview for people, to be written at `path` (named
/// in errors): radiance times `exposure`, or by default scaled so that the
/// [`PREVIEW_PERCENTILE`] of luminance shows as [`PREVIEW_TARGET`]; clamped to [0, 1]
/// (NaN and negative values show black). Encoded row by row, so that a large view needs
/// no 8-bit copy of itself.
pub fn write_png_preview(
    path: &Path,
    image: &Image,
    exposure: Option<f64>,
    out: impl Write,
) -> Result<(), Error> {
    check_buffer(path, image)?;
    let scale = match exposure {
        Some(e) if e.is_finite() && e > 0.0 => e,
        Some(e) => {
            return Err(Error::Usage(format!(
                "preview exposure must be finite and > 0, got {e}"
            )))
        }
        None => auto_exposure(image),
    };
    let png_error = |e: png::EncodingError| match e {
        png::EncodingError::IoError(io) => Error::io(path, io),
        other => Error::input(path, format!("cannot encode PNG: {other}")),
    };
    // The settings of image's PNG encoder by default.
    let mut encoder = png::Encoder::new(out, image.width, image.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Balanced);
    encoder.set_filter(png::Filter::Adaptive);
    let mut writer = encoder.write_header().map_err(png_error)?;
    let mut rows = writer.stream_writer().map_err(png_error)?;
    let mut row = Vec::with_capacity(3 * image.width as usize);
    for pixels in image.pixels.chunks_exact(image.width as usize) {
        row.clear();
        row.extend(
            pixels
                .iter()
                .flat_map(|p| p.map(|v| encode_8bit((f64::from(v) * scale) as f32))),
        );
        rows.write_all(&row).map_err(|e| Error::io(path, e))?;
    }
    rows.finish().map_err(png_error)?;
    writer.finish().map_err(png_error)
}

/// The scale that maps the [`PREVIEW_PERCENTILE`] of luminance to [`PREVIEW_TARGET`] (the
/// maximum when the percentile is black; 1 for a black image). In f64: the scale of a
/// view whose radiance is near the smallest f32 (1e-38) overflows f32, and its preview
/// would show black.
pub fn auto_exposure(image: &Image) -> f64 {
    // The positive luminances by their bits, whose order is the values' order: a
    // histogram of the high 16 bits finds the percentile's bin, one of the low 16 bits
    // within it the value, exactly, in two passes over the image and no copy of it.
    let positive_bits = || {
        image.pixels.iter().filter_map(|p| {
            let l = math::luminance(glam::Vec3::from(*p));
            (l.is_finite() && l > 0.0).then(|| l.to_bits())
        })
    };
    let mut high = vec![0u64; 1 << 16];
    let mut n_positive = 0;
    for bits in positive_bits() {
        high[(bits >> 16) as usize] += 1;
        n_positive += 1;
    }
    if n_positive == 0 {
        return 1.0;
    }
    // Percentile over all pixels, black ones included.
    let n_black = image.pixels.len() - n_positive;
    let k = (PREVIEW_PERCENTILE * (image.pixels.len() - 1) as f64) as usize;
    let rank = match k.checked_sub(n_black) {
        Some(i) => i.min(n_positive - 1),
        None => n_positive - 1,
    };
    let (high_bits, rank_in_bin) = nth_counted(&high, rank);
    let mut low = vec![0u64; 1 << 16];
    for bits in positive_bits().filter(|b| (b >> 16) as usize == high_bits) {
        low[(bits & 0xFFFF) as usize] += 1;
    }
    let (low_bits, _) = nth_counted(&low, rank_in_bin);
    let p = f32::from_bits(((high_bits << 16) | low_bits) as u32);
    f64::from(PREVIEW_TARGET) / f64::from(p)
}

/// The bin of a histogram (`counts` per bin) that holds its `rank`-th value (0-based, in
/// bin order), and that value's rank within the bin; the last bin past the total.
fn nth_counted(counts: &[u64], rank: usize) -> (usize, usize) {
    let mut before = 0;
    for (bin, &count) in counts.iter().enumerate() {
        if (rank as u64) < before + count {
            return (bin, (rank as u64 - before) as usize);
        }
        before += count;
    }
    (counts.len() - 1, 0)
}

fn encode_8bit(v: f32) -> u8 {
    (linear_to_srgb(v) * 255.0 + 0.5).clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::images::tests::image;
    use std::io::Cursor;

    fn preview(img: &Image, exposure: Option<f64>) -> image::RgbImage {
        let mut png = Cursor::new(Vec::new());
        write_png_preview(Path::new("p.png"), img, exposure, &mut png).unwrap();
        image::load_from_memory(png.get_ref()).unwrap().into_rgb8()
    }

    #[test]
    fn preview_auto_exposure_maps_the_99th_percentile_to_0_9() {
        // 100 pixels of luminance 1..=100 (grey): the 99th percentile is 99.
        let img = image(10, 10, |x, y| [(y * 10 + x + 1) as f32; 3]);
        let png = preview(&img, None);
        assert_eq!(png.dimensions(), (10, 10));
        let at_p99 = png.get_pixel(8, 9).0[0];
        assert_eq!(at_p99, encode_8bit(0.9), "{at_p99}");
        assert_eq!(png.get_pixel(9, 9).0, [encode_8bit(0.9 * 100.0 / 99.0); 3]);
        assert!(png.get_pixel(0, 0).0[0] > 0);
    }

    /// The histogram's percentile is the value a selection over a copy finds, bit for bit,
    /// on images with repeated, tiny and huge values.
    #[test]
    fn the_previews_percentile_is_the_selected_luminance() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        // Spread over the whole range of floats, or within one bin of the high bits
        // ([1, 1.0078)), where the low bits decide.
        for ((w, h), narrow) in [(1, 1), (3, 2), (17, 13), (64, 64)]
            .into_iter()
            .flat_map(|size| [(size, false), (size, true)])
        {
            let values: Vec<f32> = (0..w * h)
                .map(|_| {
                    let r = next();
                    match (r % 5, narrow) {
                        (0, _) => 0.0,
                        (_, true) => 1.0 + (r >> 40) as f32 * 4e-10,
                        (1, false) => 0.25,
                        (2, false) => f32::from_bits((r >> 8) as u32 & 0x7F7F_FFFF),
                        _ => (r >> 40) as f32 * 1e-6,
                    }
                })
                .collect();
            let img = image(w, h, |x, y| {
                let v = values[(y * w + x) as usize];
                [v, v * 0.5, v]
            });
            let mut lum: Vec<f32> = img
                .pixels
                .iter()
                .map(|p| math::luminance(glam::Vec3::from(*p)))
                .filter(|l| l.is_finite() && *l > 0.0)
                .collect();
            let expected = if lum.is_empty() {
                1.0
            } else {
                let n_black = img.pixels.len() - lum.len();
                let k = (PREVIEW_PERCENTILE * (img.pixels.len() - 1) as f64) as usize;
                let rank = k
                    .checked_sub(n_black)
                    .map_or(lum.len() - 1, |i| i.min(lum.len() - 1));
                let p = *lum.select_nth_unstable_by(rank, f32::total_cmp).1;
                f64::from(PREVIEW_TARGET) / f64::from(p)
            };
            assert_eq!(
                auto_exposure(&img).to_bits(),
                expected.to_bits(),
                "{w}x{h}, narrow {narrow}"
            );
        }
    }

    /// A view near the smallest f32 (a light of radiance 1e-38) is exposed as any other:
    /// its scale, past f32's range, showed it black.
    #[test]
    fn preview_of_radiance_near_the_smallest_float_is_exposed() {
        for scale in [1e-38f32, 1e-42, 1e30] {
            let img = image(10, 10, |x, y| [(y * 10 + x + 1) as f32 * scale; 3]);
            let png = preview(&img, None);
            assert_eq!(png.get_pixel(8, 9).0[0], encode_8bit(0.9), "{scale:e}");
            assert!(png.get_pixel(0, 0).0[0] > 0, "{scale:e}");
        }
    }

    #[test]
    fn preview_with_exposure_nan_and_black() {
        let img = image(2, 2, |x, y| match (x, y) {
            (0, 0) => [f32::NAN, 0.5, -1.0],
            (1, 0) => [f32::INFINITY, 0.0, 0.0],
            _ => [0.25, 0.25, 0.25],
        });
        let png = preview(&img, Some(2.0));
        assert_eq!(png.get_pixel(0, 0).0, [0, encode_8bit(1.0), 0]);
        assert_eq!(png.get_pixel(1, 0).0, [255, 0, 0]);
        assert_eq!(png.get_pixel(0, 1).0, [encode_8bit(0.5); 3]);
        let black = preview(&image(3, 3, |_, _| [0.0; 3]), None);
        assert!(black.pixels().all(|p| p.0 == [0; 3]));
        // Mostly black: the brightest pixel sets the scale.
        let spot = preview(
            &image(
                20,
                20,
                |x, y| if (x, y) == (3, 3) { [4.0; 3] } else { [0.0; 3] },
            ),
            None,
        );
        assert_eq!(spot.get_pixel(3, 3).0, [encode_8bit(0.9); 3]);
    }
}
