//! Reading any image into an [`Image`]: the format from the extension; the size, asked of
//! the caller and of [`MAX_IMAGE_PIXELS`] from the header before any pixel is decoded; each
//! format's own checks (`exr`, `hdr`, `png`); the decoding; the alpha, refused unless fully
//! opaque; and the values, checked and scaled by the exposure. A file cut short is bad input.

use std::cell::Cell;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use image::{DynamicImage, ImageDecoder, ImageError, ImageFormat, ImageReader};

use super::exr::{check_exr_offsets, check_exr_windows};
use super::hdr::{hdr_header_lines, hdr_header_scale, rgbe_half_step};
use super::png::{
    check_png_palette, png_error, png_header_size, png_to_linear, png_transfer, PngTransfer,
};
use super::{check_and_scale, Image};
use crate::error::Error;

/// The most pixels relume decodes from one image, whatever asks for it: 2^28, a 16K x 16K
/// square or a 23K x 11.5K capture (3 GB as float RGB, and as much again while decoding).
/// The decoder's own limit is off (a view is as large as its scene says), so without this
/// a header claiming 200000 x 100000 pixels (a corrupt or hand-made file) was allocated as
/// it said, 240 GB, and the process aborted. Each caller's own bound on the size (a view's,
/// the maps' `config::MAX_TEXELS`) is asked first.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 28;

/// Reads an image as linear radiance times `exposure`.
pub fn read_image(path: &Path, exposure: f32) -> Result<Image, Error> {
    read_image_sized(path, exposure, |_, _| Ok(()))
}

/// [`read_image`], with `size_fits(width, height)` asked from the file's header before its
/// pixels are decoded: a 16384x16384 map given where a small one fits took 6 GB and 24 s
/// to decode before its size was refused.
pub fn read_image_sized(
    path: &Path,
    exposure: f32,
    size_fits: impl FnOnce(u32, u32) -> Result<(), Error>,
) -> Result<Image, Error> {
    read_image_and_header(path, exposure, size_fits).map(|(image, _)| image)
}

/// A diffuse map (reflectances, exposure 1), refused before it is decoded where, after
/// `texels_before` texels of other maps, it would pass `config::MAX_TEXELS`, the texels of
/// all maps a scene holds; `given_at` says where it was named, for that message.
pub fn read_map(
    path: &Path,
    texels_before: usize,
    given_at: impl FnOnce() -> String,
) -> Result<Image, Error> {
    read_image_sized(path, 1.0, |width, height| {
        let needed = texels_before.saturating_add(width as usize * height as usize);
        if needed <= relume_core::config::MAX_TEXELS {
            return Ok(());
        }
        Err(Error::core(
            format!(
                "{}: diffuse_map {} is {width}x{height}",
                given_at(),
                path.display()
            ),
            relume_core::Error::Capacity {
                what: "config::MAX_TEXELS (the texels of all maps)",
                max: relume_core::config::MAX_TEXELS,
                needed,
            },
        ))
    })
}

/// [`read_image_sized`], and what the file's header divided its stored values by, per
/// channel (a Radiance picture's `EXPOSURE` and `COLORCORR`, [`hdr_header_scale`]).
pub(super) fn read_image_and_header(
    path: &Path,
    exposure: f32,
    size_fits: impl FnOnce(u32, u32) -> Result<(), Error>,
) -> Result<(Image, Option<[f64; 3]>), Error> {
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
    // A folder is bad input (a path that names the wrong thing), as for text inputs; a
    // missing file stays an I/O error naming it, as for every input.
    if path.is_dir() {
        return Err(Error::input(path, "is a folder, not an image"));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let metadata = file.metadata().map_err(|e| Error::io(path, e))?;
    if metadata.is_file() && metadata.len() == 0 {
        return Err(Error::input(path, "the file is empty: not an image"));
    }
    let hit_end = Cell::new(false);
    let mut reader = BufReader::new(EndWatch {
        inner: file,
        hit_end: &hit_end,
    });
    let unreadable = |e| decode_error(path, format, e, hit_end.get());
    let header_scale = match format {
        ImageFormat::OpenExr => {
            check_exr_windows(path, &mut reader, unreadable)?;
            None
        }
        ImageFormat::Hdr => {
            let lines =
                hdr_header_lines(&mut reader).map_err(|e| unreadable(ImageError::IoError(e)))?;
            hdr_header_scale(path, &lines)?
        }
        _ => None,
    };
    let mut size_fits = Some(size_fits);
    let png_transfer = match format {
        ImageFormat::Png => {
            // The size first, from the header alone: the png crate sizes its buffer as it
            // reads the rest, and on a 32-bit target refused a header of 200000 x 100000
            // pixels as "limits are exceeded" before relume's capacity could name it.
            let (width, height) = png_header_size(&mut reader, &unreadable)?;
            check_size(path, width, height, size_fits.take())?;
            reader
                .seek(SeekFrom::Start(0))
                .map_err(|e| Error::io(path, e))?;
            png_transfer(&mut reader, unreadable)?
        }
        _ => PngTransfer::Srgb,
    };
    reader
        .seek(SeekFrom::Start(0))
        .map_err(|e| Error::io(path, e))?;
    let mut reader = ImageReader::with_format(reader, format);
    // The image crate's default 512 MiB cap refused a float view past about 6500x6500,
    // which `render` writes; the size a view may have is the scene's to bound.
    reader.no_limits();
    let decoder = reader.into_decoder().map_err(unreadable)?;
    let (width, height) = decoder.dimensions();
    check_size(path, width, height, size_fits)?;
    // Within the capacity, what the decoder would read wrong without a word (or panic on).
    check_blocks_and_palette(path, format, &unreadable)?;
    let decoded = DynamicImage::from_decoder(decoder).map_err(unreadable)?;
    reject_transparent(path, &decoded)?;
    let pixels = match format {
        ImageFormat::Png => png_to_linear(decoded, png_transfer),
        ImageFormat::Hdr => (decoded.into_rgb32f().pixels())
            .map(|p| rgbe_half_step(p.0))
            .collect(),
        _ => decoded.into_rgb32f().pixels().map(|p| p.0).collect(),
    };
    let mut image = Image {
        width,
        height,
        pixels,
    };
    check_and_scale(path, &mut image, exposure, header_scale.as_ref())?;
    Ok((image, header_scale))
}

/// A reader that notes when the file ended under a read (a read of 0 bytes): a decoder that
/// then fails was given a file cut short.
struct EndWatch<'a, R> {
    inner: R,
    hit_end: &'a Cell<bool>,
}

impl<R: Read> Read for EndWatch<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if n == 0 && !buf.is_empty() {
            self.hit_end.set(true);
        }
        Ok(n)
    }
}

impl<R: Seek> Seek for EndWatch<'_, R> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.inner.seek(pos)
    }
}

/// A decoder's failure as relume reports it: a file that ends early is bad input (exit 3)
/// saying so, as is any content the decoder refuses, while a failed read of an existing
/// file (a disk error, a folder) stays an I/O error (exit 4). `hit_end`: the file ended
/// under a read.
fn decode_error(path: &Path, format: ImageFormat, error: ImageError, hit_end: bool) -> Error {
    use std::io::ErrorKind::{InvalidData, UnexpectedEof};
    let truncated = |what: &dyn std::fmt::Display| {
        Error::input(path, format!("the image is truncated or corrupt ({what})"))
    };
    match error {
        ImageError::IoError(io) if matches!(io.kind(), UnexpectedEof | InvalidData) => {
            truncated(&io)
        }
        ImageError::IoError(io) => Error::io(path, io),
        other if hit_end => truncated(&other),
        other => Error::input(path, format!("cannot read as {format:?}: {other}")),
    }
}

/// Refuses an image of `width` x `height` that is empty, past the caller's bound
/// (`size_fits`, asked once: `None` when it was) or past [`MAX_IMAGE_PIXELS`], before its
/// pixels are allocated.
fn check_size(
    path: &Path,
    width: u32,
    height: u32,
    size_fits: Option<impl FnOnce(u32, u32) -> Result<(), Error>>,
) -> Result<(), Error> {
    if width == 0 || height == 0 {
        return Err(Error::input(
            path,
            format!("image is empty ({width}x{height})"),
        ));
    }
    if let Some(size_fits) = size_fits {
        size_fits(width, height)?;
    }
    let pixels = width as u64 * height as u64;
    if pixels > MAX_IMAGE_PIXELS {
        return Err(Error::core(
            format!("{}: image is {width}x{height}", path.display()),
            relume_core::Error::Capacity {
                what: "images::MAX_IMAGE_PIXELS (the pixels of one image)",
                max: MAX_IMAGE_PIXELS as usize,
                needed: pixels.min(usize::MAX as u64) as usize,
            },
        ));
    }
    Ok(())
}

/// What the image crate would decode wrong without a word, or panic on, read from the
/// file anew (its decoder holds the first reader): an EXR's block offsets
/// ([`check_exr_offsets`]) and an indexed PNG's palette ([`check_png_palette`]). Called
/// once the header's size is known to be within the capacity, so that neither reads
/// tables or pixels for a size no image has.
fn check_blocks_and_palette(
    path: &Path,
    format: ImageFormat,
    unreadable: &impl Fn(ImageError) -> Error,
) -> Result<(), Error> {
    if !matches!(format, ImageFormat::OpenExr | ImageFormat::Png) {
        return Ok(());
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut reader = BufReader::new(file);
    if format == ImageFormat::OpenExr {
        return check_exr_offsets(path, &mut reader, unreadable);
    }
    let mut decoder = png::Decoder::new(reader);
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut info_reader = decoder.read_info().map_err(|e| png_error(e, unreadable))?;
    if info_reader.info().color_type == png::ColorType::Indexed {
        check_png_palette(path, &mut info_reader, |e| png_error(e, unreadable))?;
    }
    Ok(())
}

/// Refuses a pixel whose alpha is not fully opaque (the type's largest value, 1 in float):
/// a radiance image with transparency is not a calibrated capture, and dropping the alpha
/// would keep colours that were meant to be blended away.
fn reject_transparent(path: &Path, decoded: &DynamicImage) -> Result<(), Error> {
    fn first<T: PartialEq + std::fmt::Display>(
        alphas: impl Iterator<Item = T>,
        opaque: T,
    ) -> Option<(usize, String)> {
        alphas
            .enumerate()
            .find(|(_, a)| *a != opaque)
            .map(|(i, a)| (i, format!("alpha {a} is not fully opaque ({opaque})")))
    }
    let found = match decoded {
        DynamicImage::ImageLumaA8(b) => first(b.pixels().map(|p| p.0[1]), u8::MAX),
        DynamicImage::ImageLumaA16(b) => first(b.pixels().map(|p| p.0[1]), u16::MAX),
        DynamicImage::ImageRgba8(b) => first(b.pixels().map(|p| p.0[3]), u8::MAX),
        DynamicImage::ImageRgba16(b) => first(b.pixels().map(|p| p.0[3]), u16::MAX),
        DynamicImage::ImageRgba32F(b) => first(b.pixels().map(|p| p.0[3]), 1.0f32),
        _ => None,
    };
    match found {
        None => Ok(()),
        Some((i, what)) => {
            let w = decoded.width().max(1) as usize;
            Err(Error::at_pixel(
                path,
                (i % w) as u32,
                (i / w) as u32,
                format!("{what}: an image with transparency is neither a calibrated capture nor a map of reflectances (relume reads opaque images)"),
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::images::tests::{err, image};
    use crate::images::{hdr_bytes, write_exr};

    /// A header that claims more pixels than any image relume reads is refused before a
    /// byte of them is allocated (a 200000 x 100000 Radiance picture of 400 bytes aborted
    /// `panorama split` asking for 240 GB), and a map past the maps' capacity names where
    /// it was given; both are the capacity's error (exit 5).
    #[test]
    fn a_header_claiming_too_many_pixels_is_refused_before_decoding() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("huge.hdr");
        let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 200000\n".to_vec();
        bytes.extend([0u8; 400]);
        std::fs::write(&p, bytes).unwrap();
        let e = read_image(&p, 1.0).unwrap_err();
        assert_eq!(e.exit_code(), 5, "{e}");
        let said = e.to_string();
        assert!(
            said.contains("huge.hdr: image is 200000x100000") && said.contains("MAX_IMAGE_PIXELS"),
            "{said}"
        );
        let e = read_map(&p, 0, || "m.toml:7: group 'g'".into()).unwrap_err();
        assert_eq!(e.exit_code(), 5, "{e}");
        let said = e.to_string();
        assert!(
            said.contains("m.toml:7: group 'g': diffuse_map")
                && said.contains("is 200000x100000")
                && said.contains("MAX_TEXELS"),
            "{said}"
        );
        // Within both, the same file is read as far as its pixels, which it lacks.
        let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n".to_vec();
        bytes.extend([0u8; 3]);
        std::fs::write(&p, bytes).unwrap();
        assert_eq!(read_image(&p, 1.0).unwrap_err().exit_code(), 3);
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
    fn truncated_and_empty_images_are_bad_input() {
        let dir = tempfile::tempdir().unwrap();
        let img = image(16, 16, |x, y| [x as f32 * 0.37, y as f32, 1.0]);
        let exr = dir.path().join("t.exr");
        write_exr(&exr, &img).unwrap();
        let hdr = dir.path().join("t.hdr");
        std::fs::write(&hdr, hdr_bytes(&hdr, &img).unwrap()).unwrap();
        let png = dir.path().join("t.png");
        image::RgbImage::from_fn(16, 16, |x, y| image::Rgb([x as u8 * 9, y as u8 * 7, 3]))
            .save(&png)
            .unwrap();
        for path in [exr, hdr, png] {
            let bytes = std::fs::read(&path).unwrap();
            let name = path.file_name().unwrap().to_str().unwrap();
            for cut in [0, 5, 11, 30, bytes.len() / 2] {
                std::fs::write(&path, &bytes[..cut]).unwrap();
                let e = read_image(&path, 1.0).expect_err("a cut file is refused");
                assert!(matches!(e, Error::Input { .. }), "{name} cut at {cut}: {e}");
                let e = e.to_string();
                let what = if cut == 0 {
                    "the file is empty: not an image"
                } else {
                    "the image is truncated or corrupt ("
                };
                assert!(
                    e.contains(&format!("{name}: {what}")),
                    "{name} cut at {cut}: {e}"
                );
            }
        }
        // A folder is named as one, as bad input.
        let folder = dir.path().join("folder.exr");
        std::fs::create_dir(&folder).unwrap();
        let e = read_image(&folder, 1.0).unwrap_err();
        assert!(matches!(e, Error::Input { .. }), "{e}");
        assert!(e
            .to_string()
            .contains("folder.exr: is a folder, not an image"));
    }

    #[test]
    fn alpha_must_be_fully_opaque() {
        use exr::prelude::{Encoding, SpecificChannels, Vec2, WritableImage};
        let dir = tempfile::tempdir().unwrap();
        let rgba_exr = |name: &str, alpha_at_2_1: f32| {
            let p = dir.path().join(name);
            let ch = SpecificChannels::rgba(|pos: Vec2<usize>| {
                let a = if (pos.x(), pos.y()) == (2, 1) {
                    alpha_at_2_1
                } else {
                    1.0
                };
                (0.5f32, pos.x() as f32, 0.25f32, a)
            });
            exr::prelude::Image::from_encoded_channels((3, 2), Encoding::UNCOMPRESSED, ch)
                .write()
                .to_file(&p)
                .unwrap();
            p
        };
        let opaque = read_image(&rgba_exr("opaque.exr", 1.0), 1.0).unwrap();
        assert_eq!(opaque.pixels[5], [0.5, 2.0, 0.25]);
        let e = err(&rgba_exr("half.exr", 0.5));
        assert!(
            e.contains("half.exr: pixel (x 2, y 1): alpha 0.5 is not fully opaque (1)"),
            "{e}"
        );
        let rgba_png = image::RgbaImage::from_fn(3, 2, |x, y| {
            image::Rgba([10, 20, 30, if (x, y) == (1, 1) { 7 } else { 255 }])
        });
        let p = dir.path().join("rgba.png");
        rgba_png.save(&p).unwrap();
        let e = err(&p);
        assert!(
            e.contains("rgba.png: pixel (x 1, y 1): alpha 7 is not fully opaque (255)")
                && e.contains(
                    "with transparency is neither a calibrated capture nor a map of reflectances"
                ),
            "{e}"
        );
        let p = dir.path().join("la16.png");
        image::ImageBuffer::<image::LumaA<u16>, _>::from_raw(2, 1, vec![100u16, 65535, 200, 65534])
            .unwrap()
            .save(&p)
            .unwrap();
        let e = err(&p);
        assert!(
            e.contains("la16.png: pixel (x 1, y 0): alpha 65534 is not fully opaque (65535)"),
            "{e}"
        );
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
}
