//! Images (scene-format.md, "Images"): reading `.exr` (half or float), `.hdr` (RGBE) and
//! `.png` (8 or 16 bit, sRGB) into linear RGB radiance; writing linear float EXR and
//! tone-mapped PNG previews.
//!
//! Reading checks every value: a NaN, infinite or negative channel is an error naming the file,
//! the pixel and the channel. Alpha channels are dropped (a view is opaque radiance); a grey
//! image gives three equal channels. PNG decoding uses the sRGB curve through the core's libm
//! math, so it is deterministic across machines.

use std::io::{BufReader, Seek, Write};
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageError, ImageFormat, ImageReader};
use relume_core::math;

use crate::error::Error;
use crate::fsutil::OutputSet;

/// A linear RGB image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

/// The luminance percentile that [`write_png_preview`]'s auto-exposure maps to
/// [`PREVIEW_TARGET`].
pub const PREVIEW_PERCENTILE: f64 = 0.99;
/// Display value (before sRGB encoding) of the auto-exposure percentile.
pub const PREVIEW_TARGET: f32 = 0.9;

const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// Reads an image as linear radiance times `exposure`.
pub fn read_image(path: &Path, exposure: f32) -> Result<Image, Error> {
    if !(exposure.is_finite() && exposure > 0.0) {
        return Err(Error::input(
            path,
            format!("exposure must be finite and > 0, got {exposure}"),
        ));
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let format = match ext.as_deref() {
        Some("exr") => ImageFormat::OpenExr,
        Some("hdr") => ImageFormat::Hdr,
        Some("png") => ImageFormat::Png,
        _ => {
            return Err(Error::input(
                path,
                format!(
                    "unknown image type '{}' (expected .exr, .hdr or .png)",
                    ext.as_deref().map_or(String::new(), |e| format!(".{e}"))
                ),
            ))
        }
    };
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let decoded = ImageReader::with_format(BufReader::new(file), format)
        .decode()
        .map_err(|e| match e {
            ImageError::IoError(io) => Error::io(path, io),
            other => Error::input(path, format!("cannot read as {format:?}: {other}")),
        })?;
    let (width, height) = (decoded.width(), decoded.height());
    if width == 0 || height == 0 {
        return Err(Error::input(
            path,
            format!("image is empty ({width}x{height})"),
        ));
    }
    let pixels = match format {
        ImageFormat::Png => png_to_linear(decoded),
        _ => decoded.into_rgb32f().pixels().map(|p| p.0).collect(),
    };
    let mut image = Image {
        width,
        height,
        pixels,
    };
    check_and_scale(path, &mut image, exposure)?;
    Ok(image)
}

/// [`read_image`], and the size must be the view's `[width, height]`.
pub fn read_view_image(path: &Path, exposure: f32, expected: [u32; 2]) -> Result<Image, Error> {
    let image = read_image(path, exposure)?;
    if [image.width, image.height] != expected {
        return Err(Error::input(
            path,
            format!(
                "image is {}x{} but the view says {}x{}",
                image.width, image.height, expected[0], expected[1]
            ),
        ));
    }
    reject_value(
        path,
        &image,
        |v| v > MAX_RADIANCE,
        &format!(
            "after exposure {exposure} is above the largest radiance relume computes with, {MAX_RADIANCE:e} (is the exposure right?)"
        ),
    )?;
    Ok(image)
}

fn png_to_linear(decoded: DynamicImage) -> Vec<[f32; 3]> {
    let bits = decoded.color().bits_per_pixel() / u16::from(decoded.color().channel_count());
    if bits > 8 {
        decoded
            .into_rgb16()
            .pixels()
            .map(|p| p.0.map(|c| srgb_to_linear(f32::from(c) / 65535.0)))
            .collect()
    } else {
        let table: Vec<f32> = (0..256).map(|c| srgb_to_linear(c as f32 / 255.0)).collect();
        decoded
            .into_rgb8()
            .pixels()
            .map(|p| p.0.map(|c| table[c as usize]))
            .collect()
    }
}

/// The largest radiance a scene may hold (a panorama's pixel times its view's exposure, a
/// light's radiance): recovery's errors square differences of radiances in 32-bit floats,
/// summed over three channels, which stays below f32's largest (3.4e38) up to here. A
/// panorama 1e30 times too bright read as NaN errors and reflectances at their bound.
pub const MAX_RADIANCE: f32 = 1e18;

/// Rejects NaN, infinite and negative values, then multiplies by `exposure` (and rejects an
/// overflow to infinity).
fn check_and_scale(path: &Path, image: &mut Image, exposure: f32) -> Result<(), Error> {
    let w = image.width as usize;
    for (i, p) in image.pixels.iter_mut().enumerate() {
        let (x, y) = ((i % w) as u32, (i / w) as u32);
        for (c, v) in p.iter_mut().enumerate() {
            let what = if v.is_nan() {
                Some("is NaN")
            } else if v.is_infinite() {
                Some("is infinite")
            } else if *v < 0.0 {
                Some("is negative")
            } else {
                None
            };
            if let Some(what) = what {
                return Err(Error::at_pixel(
                    path,
                    x,
                    y,
                    format!("channel {} value {} {what}", CHANNELS[c], v),
                ));
            }
            let scaled = *v * exposure;
            if !scaled.is_finite() {
                return Err(Error::at_pixel(
                    path,
                    x,
                    y,
                    format!(
                        "channel {} value {} times exposure {exposure} overflows",
                        CHANNELS[c], v
                    ),
                ));
            }
            *v = scaled;
        }
    }
    Ok(())
}

fn check_buffer(path: &Path, image: &Image) -> Result<(), Error> {
    let n = image.width as u64 * image.height as u64;
    if n == 0 || n != image.pixels.len() as u64 {
        return Err(Error::input(
            path,
            format!(
                "cannot write a {}x{} image from {} pixels",
                image.width,
                image.height,
                image.pixels.len()
            ),
        ));
    }
    Ok(())
}

/// The first value of `image` for which `bad` holds, as an error at its pixel naming its
/// channel and value after `why` (the caller's rule).
pub fn reject_value(
    path: &Path,
    image: &Image,
    bad: impl Fn(f32) -> bool,
    why: &str,
) -> Result<(), Error> {
    let w = image.width.max(1) as usize;
    for (i, p) in image.pixels.iter().enumerate() {
        if let Some(c) = p.iter().position(|&v| bad(v)) {
            return Err(Error::at_pixel(
                path,
                (i % w) as u32,
                (i / w) as u32,
                format!("channel {} value {} {why}", CHANNELS[c], p[c]),
            ));
        }
    }
    Ok(())
}

/// A data image (EXR, HDR) is written only when every value is finite: relume reads no
/// image with an infinite or NaN value, and would not read its own output back (a light's
/// radiance near f32's largest overflows in a render).
fn check_finite(path: &Path, image: &Image) -> Result<(), Error> {
    reject_value(
        path,
        image,
        |v| !v.is_finite(),
        "is not finite: not written (the scene's radiances overflow 32-bit floats)",
    )
}

/// Writes linear float32 RGB (ZIP compressed), atomically; [`read_image`] gives back the
/// same floats.
pub fn write_exr(path: &Path, image: &Image) -> Result<(), Error> {
    let mut set = OutputSet::default();
    add_exr(&mut set, path, image)?;
    set.commit()
}

/// Encodes `image` as EXR into `out` (`path` is named in errors), without the finite check
/// (tests write bad files as another program might). The pixels are read as the encoder
/// goes, block by block: no second copy of the image is made.
fn encode_exr(path: &Path, image: &Image, out: impl Write + Seek) -> Result<(), Error> {
    use exr::prelude::{Encoding, SpecificChannels, Vec2, WritableImage};
    let w = image.width as usize;
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let p = image.pixels[pos.y() * w + pos.x()];
        (p[0], p[1], p[2])
    });
    let exr_image = exr::prelude::Image::from_encoded_channels(
        (w, image.height as usize),
        Encoding::SMALL_LOSSLESS,
        channels,
    );
    exr_image
        .write()
        .non_parallel()
        .to_buffered(out)
        .map_err(|e| Error::input(path, format!("cannot encode EXR: {e}")))
}

/// Adds `image` to `set` as an EXR at `path` (what [`write_exr`] would write there),
/// encoded straight into the staged file.
pub fn add_exr(set: &mut OutputSet, path: &Path, image: &Image) -> Result<(), Error> {
    check_buffer(path, image)?;
    check_finite(path, image)?;
    set.add_written(path, |file| encode_exr(path, image, file))
}

/// Adds `<dir>/<name>.exr` and its PNG preview (`<dir>/<name>.png`) to `set`: how a view
/// is written.
pub fn add_exr_and_preview(
    set: &mut OutputSet,
    dir: &Path,
    name: &str,
    image: &Image,
) -> Result<(), Error> {
    let [exr, png] = exr_and_preview_paths(dir, name);
    add_exr(set, &exr, image)?;
    set.add_written(&png, |file| write_png_preview(&png, image, None, file))
}

/// Where [`add_exr_and_preview`] writes image `name` in `dir`: the EXR, then the PNG.
pub fn exr_and_preview_paths(dir: &Path, name: &str) -> [PathBuf; 2] {
    [
        dir.join(format!("{name}.exr")),
        dir.join(format!("{name}.png")),
    ]
}

/// A Radiance RGBE picture (.hdr) to be written at `path` (named in errors): how a
/// RADIANCE `colorpict` reads a recovered diffuse map.
pub fn hdr_bytes(path: &Path, image: &Image) -> Result<Vec<u8>, Error> {
    check_buffer(path, image)?;
    check_finite(path, image)?;
    let pixels: Vec<image::Rgb<f32>> = image.pixels.iter().map(|p| image::Rgb(*p)).collect();
    let mut bytes = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut bytes)
        .encode(&pixels, image.width as usize, image.height as usize)
        .map_err(|e| Error::input(path, format!("cannot encode HDR: {e}")))?;
    Ok(bytes)
}

/// Encodes into `out` an 8-bit sRGB preview for people, to be written at `path` (named
/// in errors): radiance times `exposure`, or by default scaled so that the
/// [`PREVIEW_PERCENTILE`] of luminance shows as [`PREVIEW_TARGET`]; clamped to [0, 1]
/// (NaN and negative values show black). Encoded row by row, so that a large view needs
/// no 8-bit copy of itself.
pub fn write_png_preview(
    path: &Path,
    image: &Image,
    exposure: Option<f32>,
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
    let png_error = |e: png::EncodingError| Error::input(path, format!("cannot encode PNG: {e}"));
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
                .flat_map(|p| p.map(|v| encode_8bit(v * scale))),
        );
        rows.write_all(&row).map_err(|e| Error::io(path, e))?;
    }
    rows.finish().map_err(png_error)?;
    writer.finish().map_err(png_error)
}

/// The scale that maps the [`PREVIEW_PERCENTILE`] of luminance to [`PREVIEW_TARGET`] (the
/// maximum when the percentile is black; 1 for a black image).
fn auto_exposure(image: &Image) -> f32 {
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
    let s = PREVIEW_TARGET / p;
    if s.is_finite() {
        s
    } else {
        1.0
    }
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

/// The sRGB transfer function, decoding: display value in [0, 1] to linear.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        math::powf((c + 0.055) / 1.055, 2.4)
    }
}

/// The sRGB transfer function, encoding: linear to display value (clamped to [0, 1]).
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    if v <= 0.0031308 {
        v * 12.92
    } else {
        1.055 * math::powf(v, 1.0 / 2.4) - 0.055
    }
}

fn encode_8bit(v: f32) -> u8 {
    (linear_to_srgb(v) * 255.0 + 0.5).clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> Image {
        let pixels = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        Image {
            width: w,
            height: h,
            pixels,
        }
    }

    /// Writes `pixels` as an EXR without any checks, as another program might.
    fn raw_exr(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) {
        let file = std::fs::File::create(path).unwrap();
        encode_exr(path, &image(w, h, f), std::io::BufWriter::new(file)).unwrap();
    }

    fn err(path: &Path) -> String {
        read_image(path, 1.0)
            .expect_err("the image should be refused")
            .to_string()
    }

    #[test]
    fn exr_round_trips_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.exr");
        let specials = [
            0.0,
            1e-42,
            f32::MIN_POSITIVE,
            0.1,
            1.0 / 3.0,
            1e-7,
            12345.678,
            3.0e38,
        ];
        let img = image(5, 3, |x, y| {
            let i = (y * 5 + x) as usize;
            [specials[i % 8], specials[(i + 3) % 8], (i as f32) * 0.37]
        });
        write_exr(&p, &img).unwrap();
        let back = read_image(&p, 1.0).unwrap();
        assert_eq!(back, img);
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no temp files left"
        );
    }

    #[test]
    fn exposure_multiplies() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.exr");
        raw_exr(&p, 2, 1, |x, _| [x as f32, 0.5, 1.0]);
        let back = read_image(&p, 2.0).unwrap();
        assert_eq!(back.pixels, vec![[0.0, 1.0, 2.0], [2.0, 1.0, 2.0]]);
        let e = read_image(&p, 0.0).unwrap_err().to_string();
        assert!(
            e.contains("a.exr") && e.contains("exposure must be finite and > 0"),
            "{e}"
        );
        let big = dir.path().join("big.exr");
        raw_exr(&big, 2, 1, |x, _| [1.0, 1.0, 1.0 + x as f32]);
        let e = read_image(&big, f32::MAX).unwrap_err().to_string();
        assert!(
            e.contains("big.exr: pixel (x 1, y 0)")
                && e.contains("channel B value 2")
                && e.contains("overflows"),
            "{e}"
        );
        // A panorama's radiance (times exposure) stays within MAX_RADIANCE.
        let e = read_view_image(&big, 1e18, [2, 1]).unwrap_err().to_string();
        assert!(
            e.contains("big.exr: pixel (x 1, y 0)")
                && e.contains(
                    "channel B value 2000000000000000000 after exposure 1000000000000000000"
                )
                && e.contains("above the largest radiance relume computes with, 1e18"),
            "{e}"
        );
        read_view_image(&big, 5e17, [2, 1]).unwrap();
    }

    #[test]
    fn half_float_exr_reads() {
        use exr::prelude::{f16, Encoding, SpecificChannels, Vec2, WritableImage};
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("h.exr");
        let ch = SpecificChannels::rgb(|pos: Vec2<usize>| {
            (
                f16::from_f32(0.5),
                f16::from_f32(pos.x() as f32),
                f16::from_f32(0.25),
            )
        });
        exr::prelude::Image::from_encoded_channels((3, 2), Encoding::FAST_LOSSLESS, ch)
            .write()
            .to_file(&p)
            .unwrap();
        let back = read_image(&p, 1.0).unwrap();
        assert_eq!((back.width, back.height), (3, 2));
        assert_eq!(back.pixels[5], [0.5, 2.0, 0.25]);
    }

    #[test]
    fn a_data_image_with_a_non_finite_value_is_not_written() {
        let dir = tempfile::tempdir().unwrap();
        let image = Image {
            width: 2,
            height: 1,
            pixels: vec![[0.5; 3], [0.5, f32::INFINITY, 0.5]],
        };
        for name in ["a.exr", "a.hdr"] {
            let path = dir.path().join(name);
            let result = if name.ends_with("exr") {
                write_exr(&path, &image)
            } else {
                hdr_bytes(&path, &image).map(|_| ())
            };
            let err = result
                .expect_err("an infinite value must not be written")
                .to_string();
            assert!(
                err.contains("pixel (x 1, y 0)") && err.contains("channel G"),
                "{err}"
            );
            assert!(!path.exists(), "{name} written");
        }
    }

    #[test]
    fn nan_inf_and_negative_pixels_name_the_pixel_and_channel() {
        let dir = tempfile::tempdir().unwrap();
        let cases: [(f32, &str); 4] = [
            (f32::NAN, "is NaN"),
            (f32::INFINITY, "is infinite"),
            (f32::NEG_INFINITY, "is infinite"),
            (-0.25, "is negative"),
        ];
        for (i, (bad, what)) in cases.into_iter().enumerate() {
            let p = dir.path().join(format!("bad{i}.exr"));
            raw_exr(&p, 4, 3, |x, y| {
                if (x, y) == (2, 1) {
                    [0.5, bad, 0.5]
                } else {
                    [0.5; 3]
                }
            });
            let e = err(&p);
            assert!(e.contains(&format!("bad{i}.exr")), "{e}");
            assert!(
                e.contains("pixel (x 2, y 1)") && e.contains("channel G") && e.contains(what),
                "{e}"
            );
        }
        // Negative zero is zero.
        let p = dir.path().join("nz.exr");
        raw_exr(&p, 1, 1, |_, _| [-0.0, 0.0, 0.0]);
        read_image(&p, 1.0).unwrap();
    }

    #[test]
    fn unknown_extension_missing_file_and_garbage() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.jpg");
        std::fs::write(&p, b"xx").unwrap();
        let e = err(&p);
        assert!(
            e.contains("a.jpg") && e.contains("unknown image type '.jpg'"),
            "{e}"
        );
        let p = dir.path().join("noext");
        std::fs::write(&p, b"xx").unwrap();
        assert!(err(&p).contains("unknown image type ''"));
        let p = dir.path().join("absent.exr");
        let e = read_image(&p, 1.0).unwrap_err();
        assert!(
            matches!(e, Error::Io { .. }) && e.to_string().contains("absent.exr"),
            "{e}"
        );
        for name in ["junk.exr", "junk.hdr", "junk.png"] {
            let p = dir.path().join(name);
            std::fs::write(&p, b"this is not an image").unwrap();
            let e = err(&p);
            assert!(e.contains(name) && e.contains("cannot read as"), "{e}");
        }
    }

    #[test]
    fn view_images_must_have_the_view_size() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("v.exr");
        raw_exr(&p, 4, 2, |_, _| [1.0; 3]);
        read_view_image(&p, 1.0, [4, 2]).unwrap();
        let e = read_view_image(&p, 1.0, [256, 256])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("v.exr") && e.contains("is 4x2 but the view says 256x256"),
            "{e}"
        );
    }

    #[test]
    fn png_8_and_16_bit_decode_srgb() {
        let dir = tempfile::tempdir().unwrap();
        let p8 = dir.path().join("a.png");
        image::RgbaImage::from_raw(
            3,
            1,
            vec![0, 128, 255, 7, 255, 255, 255, 0, 10, 20, 30, 255],
        )
        .unwrap()
        .save(&p8)
        .unwrap();
        let a = read_image(&p8, 2.0).unwrap();
        assert_eq!(a.pixels[0][0], 0.0);
        assert!(
            (a.pixels[0][1] - 2.0 * 0.2158605).abs() < 1e-6,
            "{:?}",
            a.pixels[0]
        );
        assert_eq!(a.pixels[1], [2.0; 3]);
        assert!((a.pixels[2][0] - 2.0 * 10.0 / 255.0 / 12.92).abs() < 1e-7);
        let p16 = dir.path().join("b.png");
        image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(1, 1, vec![0u16, 32768, 65535])
            .unwrap()
            .save(&p16)
            .unwrap();
        let b = read_image(&p16, 1.0).unwrap();
        assert_eq!(b.pixels[0][0], 0.0);
        assert!(
            (b.pixels[0][1] - 0.2140482).abs() < 1e-6,
            "{:?}",
            b.pixels[0]
        );
        assert_eq!(b.pixels[0][2], 1.0);
        let pg = dir.path().join("g.png");
        image::GrayImage::from_raw(2, 1, vec![255, 0])
            .unwrap()
            .save(&pg)
            .unwrap();
        assert_eq!(
            read_image(&pg, 1.0).unwrap().pixels,
            vec![[1.0; 3], [0.0; 3]]
        );
    }

    #[test]
    fn hdr_reads_rgbe() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.hdr");
        let px = [image::Rgb([1.0f32, 0.5, 2.0]), image::Rgb([0.0, 0.25, 8.0])];
        let mut bytes = Vec::new();
        image::codecs::hdr::HdrEncoder::new(&mut bytes)
            .encode(&px, 2, 1)
            .unwrap();
        std::fs::write(&p, bytes).unwrap();
        let back = read_image(&p, 1.0).unwrap();
        assert_eq!(back.pixels, vec![[1.0, 0.5, 2.0], [0.0, 0.25, 8.0]]);
    }

    #[test]
    fn box_diffuse_small_views_load() {
        let Some(bench) = crate::scene_file::tests::bench() else {
            return;
        };
        for v in ["px", "nx", "py", "ny", "pz", "nz"] {
            let p = bench.join(format!("box-diffuse/views-small/{v}.exr"));
            let img = read_view_image(&p, 1.0, [64, 64]).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(img.pixels.len(), 64 * 64);
            assert!(img
                .pixels
                .iter()
                .flatten()
                .all(|c| c.is_finite() && *c >= 0.0));
            assert!(img.pixels.iter().flatten().any(|c| *c > 0.0));
        }
    }

    #[test]
    fn bench_textures_load() {
        let Some(bench) = crate::scene_file::tests::bench() else {
            return;
        };
        for i in 1..=3 {
            let p = bench.join(format!("living-room/textures/picture_{i}.exr"));
            let img = read_image(&p, 1.0).unwrap_or_else(|e| panic!("{e}"));
            assert!(img.width > 0 && img.pixels.iter().flatten().all(|c| (0.0..=1.0).contains(c)));
        }
    }

    fn preview(img: &Image, exposure: Option<f32>) -> image::RgbImage {
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
                let s = PREVIEW_TARGET / *lum.select_nth_unstable_by(rank, f32::total_cmp).1;
                if s.is_finite() {
                    s
                } else {
                    1.0
                }
            };
            assert_eq!(
                auto_exposure(&img).to_bits(),
                expected.to_bits(),
                "{w}x{h}, narrow {narrow}"
            );
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

    #[test]
    fn writing_refuses_inconsistent_buffers_and_bad_exposure() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.exr");
        let bad = Image {
            width: 2,
            height: 2,
            pixels: vec![[0.0; 3]; 3],
        };
        let e = write_exr(&p, &bad).unwrap_err().to_string();
        assert!(
            e.contains("x.exr") && e.contains("2x2 image from 3 pixels"),
            "{e}"
        );
        let empty = Image {
            width: 0,
            height: 0,
            pixels: vec![],
        };
        assert!(write_exr(&p, &empty).is_err());
        let png = |image: &Image, exposure| {
            let path = dir.path().join("x.png");
            write_png_preview(&path, image, exposure, Cursor::new(Vec::new()))
        };
        assert!(png(&bad, None).is_err());
        assert!(png(&image(1, 1, |_, _| [1.0; 3]), Some(-1.0)).is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn srgb_curves_invert() {
        for i in 0..=255u32 {
            let c = i as f32 / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-5, "{c}");
        }
        assert_eq!(linear_to_srgb(f32::NAN), 0.0);
        assert_eq!(linear_to_srgb(2.0), linear_to_srgb(1.0));
    }
}
