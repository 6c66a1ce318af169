//! Images (scene-format.md, "Images"): reading `.exr` (half or float), `.hdr` (RGBE) and
//! `.png` (8 or 16 bit, sRGB) into linear RGB radiance; writing linear float EXR and
//! tone-mapped PNG previews.
//!
//! Reading checks every value: a NaN, infinite or negative channel is an error naming the file,
//! the pixel and the channel. An alpha channel must be fully opaque, and is then dropped (a
//! view is opaque radiance); a grey image gives three equal channels. An EXR's data window
//! must cover its display window, and a Radiance picture's `EXPOSURE` and `COLORCORR` header
//! lines are divided out. A file cut short is bad input, not an I/O failure. PNG decoding
//! uses the sRGB curve through the core's libm math, so it is deterministic across machines,
//! unless the file's `gAMA` chunk declares another (a linear PNG says gamma 1): the PNG
//! standard's power law then applies. An ICC profile is not read.
//!
//! The parts: `read` (any file to an [`Image`]: its format, its size before its pixels, its
//! alpha), `exr`, `hdr` and `png` (what each format needs beyond the image crate's reading,
//! and the EXR and RGBE writers), `preview` (tone-mapped PNG previews) and `views` (a view's
//! image, read at its size and within [`MAX_RADIANCE`], written with its preview); here, the
//! image type and the checks of its values.

mod exr;
mod hdr;
mod png;
mod preview;
mod read;
mod views;

use std::path::Path;

pub use self::exr::{add_exr, write_exr};
pub use self::hdr::{hdr_bytes, header_note};
pub use self::png::{linear_to_srgb, srgb_to_linear};
pub use self::preview::{auto_exposure, write_png_preview, PREVIEW_PERCENTILE, PREVIEW_TARGET};
pub use self::read::{read_image, read_image_sized, read_map, MAX_IMAGE_PIXELS};
pub use self::views::{
    add_exr_and_preview, exr_and_preview_paths, read_folder_view_image, read_radiance_sized,
    read_view_image, read_view_image_and_header,
};
use crate::error::Error;

/// A linear RGB image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// The largest radiance a scene may hold (a panorama's pixel times its view's exposure, a
/// light's radiance): recovery's errors square differences of radiances in 32-bit floats,
/// summed over three channels, which stays below f32's largest (3.4e38) up to here. A
/// panorama 1e30 times too bright read as NaN errors and reflectances at their bound.
pub const MAX_RADIANCE: f32 = 1e18;

/// Rejects NaN, infinite and negative values, then multiplies by `exposure` and divides by
/// `header` (a Radiance picture's [`hdr_header_scale`](hdr::hdr_header_scale), per
/// channel), and rejects an overflow to infinity. Without a header the product is f32's,
/// as it always was.
fn check_and_scale(
    path: &Path,
    image: &mut Image,
    exposure: f32,
    header: Option<&[f64; 3]>,
) -> Result<(), Error> {
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
            let scaled = match header {
                None => *v * exposure,
                Some(h) => (f64::from(*v) * f64::from(exposure) / h[c]) as f32,
            };
            if !scaled.is_finite() {
                let header_note = header.map_or(String::new(), |h| {
                    format!(
                        " divided by the header's EXPOSURE and COLORCORR, {}",
                        crate::text::significant(h[c])
                    )
                });
                return Err(Error::at_pixel(
                    path,
                    x,
                    y,
                    format!(
                        "channel {} value {} times exposure {}{header_note} overflows",
                        CHANNELS[c],
                        value_text(*v),
                        value_text(exposure)
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
                format!("channel {} value {} {why}", CHANNELS[c], value_text(p[c])),
            ));
        }
    }
    Ok(())
}

/// A pixel's value in a message, exactly, with an exponent from a million up (a texel of
/// 1e30 was given in 31 digits).
fn value_text(v: f32) -> String {
    if v.abs() >= 1e6 {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
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

#[cfg(test)]
mod tests {
    use super::exr::encode_exr;
    use super::*;
    use crate::scene_file::ViewDesc;
    use std::io::Cursor;

    pub(super) fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> Image {
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
    pub(super) fn raw_exr(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) {
        let file = std::fs::File::create(path).unwrap();
        encode_exr(path, &image(w, h, f), std::io::BufWriter::new(file)).unwrap();
    }

    /// A view of `width` x `height` pixels, named "v", for the reads that check a size.
    pub(super) fn sized(width: u32, height: u32) -> ViewDesc {
        ViewDesc {
            name: "v".into(),
            image: None,
            position: [0.0; 3],
            direction: [1.0, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            fov_deg: [90.0, 90.0],
            size: [width, height],
            exposure: 1.0,
        }
    }

    pub(super) fn err(path: &Path) -> String {
        read_image(path, 1.0)
            .expect_err("the image should be refused")
            .to_string()
    }

    /// A disk that fills under a write is an I/O failure (exit 4), not bad input (3): the
    /// encoders' I/O errors were reported as "cannot encode EXR: No space left on device".
    #[test]
    fn a_full_disk_is_an_io_error_not_bad_input() {
        let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
            return; // not a Linux machine
        };
        let image = Image {
            width: 64,
            height: 64,
            pixels: vec![[0.5, 0.25, 0.125]; 64 * 64],
        };
        let path = Path::new("out/px.exr");
        let exr = encode_exr(path, &image, std::io::BufWriter::new(&full));
        assert!(matches!(exr, Err(Error::Io { .. })), "{exr:?}");
        let png = write_png_preview(path, &image, None, &full);
        assert!(matches!(png, Err(Error::Io { .. })), "{png:?}");
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
                && e.contains("channel B value 2 times exposure 3.4028235e38 overflows"),
            "{e}"
        );
        // A panorama's radiance (times exposure) stays within MAX_RADIANCE.
        let e = read_view_image(&big, &sized(2, 1), 1e18)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("big.exr: pixel (x 1, y 0)")
                && e.contains("channel B value 2e18 after exposure 1e18")
                && e.contains("above the largest radiance relume computes with, 1e18"),
            "{e}"
        );
        read_view_image(&big, &sized(2, 1), 5e17).unwrap();
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
}
