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

use std::cell::Cell;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use image::error::{DecodingError, ImageFormatHint};
use image::{DynamicImage, ImageDecoder, ImageError, ImageFormat, ImageReader};
use relume_core::math;

use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::scene_file::ViewDesc;
use crate::text;

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
fn read_image_and_header(
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

/// A Radiance RGBE pixel as RADIANCE reads it (`colr_color`: `(mantissa + 0.5) * 2^(e - 136)`),
/// from the image crate's reading (`mantissa * 2^(e - 136)`, no half step): a writer
/// truncates (`setcolr`, and the image crate's encoder), so the half step is the unbiased
/// reading, and without it every `.hdr` view and map read 0.2-0.4% dark against RADIANCE.
/// The step is found from the brightest channel, whose mantissa every writer normalises to
/// 128-255; black (exponent 0) stays black.
fn rgbe_half_step(pixel: [f32; 3]) -> [f32; 3] {
    let brightest = pixel.iter().copied().fold(0.0f32, f32::max);
    if brightest <= 0.0 || !brightest.is_finite() {
        return pixel;
    }
    // floor(log2(brightest)), exactly, from the f64 exponent (subnormal f32s included).
    let log2 = ((f64::from(brightest).to_bits() >> 52) & 0x7ff) as i32 - 1023;
    // A mantissa of 128-255 puts the step at 2^(log2 - 7); half of it is 2^(log2 - 8).
    let half_step = f64::from_bits(((log2 - 8 + 1023) as u64) << 52);
    pixel.map(|v| (f64::from(v) + half_step) as f32)
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

/// An error of the exr crate as the image crate reports it when it decodes an EXR.
fn exr_to_image_error(error: exr::error::Error) -> ImageError {
    match error {
        exr::error::Error::Io(io) => ImageError::IoError(io),
        other => ImageError::Decoding(DecodingError::new(
            ImageFormatHint::Exact(ImageFormat::OpenExr),
            other.to_string(),
        )),
    }
}

/// Refuses an EXR whose data window (the pixels stored) does not cover its display window
/// (the image): the image crate fills the uncovered pixels with 0, a black that was never
/// measured. The layer checked is the one the image crate decodes, the first flat one with
/// R, G and B; a file without one is left for it to refuse. A data window larger than the
/// display window (overscan) is cropped, as EXR intends. `unreadable` reports a header that
/// cannot be read.
fn check_exr_windows(
    path: &Path,
    reader: &mut impl Read,
    unreadable: impl Fn(ImageError) -> Error,
) -> Result<(), Error> {
    use exr::meta::{attribute::IntegerBounds, header::Header};
    let meta = exr::meta::MetaData::read_from_buffered(reader, false)
        .map_err(|e| unreadable(exr_to_image_error(e)))?;
    let has_rgb = |h: &&Header| {
        !h.deep
            && ["R", "G", "B"].iter().all(|&c| {
                h.channels
                    .find_index_of_channel(&exr::prelude::Text::from(c))
                    .is_some()
            })
    };
    let Some(header) = meta.headers.iter().find(has_rgb) else {
        return Ok(());
    };
    // Inclusive corners in i64: a window's end may pass i32's range.
    let corners = |w: IntegerBounds| {
        let (x, y) = (i64::from(w.position.x()), i64::from(w.position.y()));
        [
            x,
            y,
            x + w.size.width() as i64 - 1,
            y + w.size.height() as i64 - 1,
        ]
    };
    let data = corners(header.data_window());
    let display = corners(header.shared_attributes.display_window);
    if data[0] <= display[0]
        && data[1] <= display[1]
        && data[2] >= display[2]
        && data[3] >= display[3]
    {
        return Ok(());
    }
    let show = |c: [i64; 4]| format!("({},{})-({},{})", c[0], c[1], c[2], c[3]);
    Err(Error::input(
        path,
        format!(
            "data window {} does not cover the display window {}: pixels outside it have no value",
            show(data),
            show(display)
        ),
    ))
}

/// Refuses an EXR whose table of block offsets is corrupt: two blocks at one offset, or
/// one outside the file. The image crate reads such a file without a word, the block
/// named twice in the place of both and the other left black (a row of zeros where a
/// row's offset pointed at the next row's block). `reader` is at the file's start.
fn check_exr_offsets(
    path: &Path,
    reader: &mut (impl Read + Seek),
    unreadable: &impl Fn(ImageError) -> Error,
) -> Result<(), Error> {
    let blocks = exr::block::read(reader, false).map_err(|e| unreadable(exr_to_image_error(e)))?;
    match blocks.filter_chunks(true, |_, _, _| true) {
        Ok(_) => Ok(()),
        Err(exr::error::Error::Io(io)) => Err(unreadable(ImageError::IoError(io))),
        Err(e) => Err(Error::input(
            path,
            format!("its table of block offsets is corrupt ({e}): blocks would be read twice or not at all"),
        )),
    }
}

/// The header lines of a Radiance picture, numbered from 1 (the `#?RADIANCE` line), up to
/// the empty line that ends the header (or the file's end, which the decoder then refuses).
/// No lines for a file without the signature, also left for the decoder to refuse.
fn hdr_header_lines(reader: &mut impl BufRead) -> std::io::Result<Vec<(usize, String)>> {
    let mut lines = Vec::new();
    if !reader.fill_buf()?.starts_with(b"#?RADIANCE") {
        return Ok(lines);
    }
    let mut line = Vec::new();
    loop {
        line.clear();
        // Lines end at '\n' alone, as the decoder reads them.
        if reader.read_until(b'\n', &mut line)? == 0 {
            return Ok(lines);
        }
        if line.last() == Some(&b'\n') {
            line.pop();
        }
        if line.is_empty() {
            return Ok(lines);
        }
        lines.push((lines.len() + 1, String::from_utf8_lossy(&line).into_owned()));
    }
}

/// What a Radiance picture's header says its stored values were multiplied by, per
/// channel: every `EXPOSURE=` line, times every `COLORCORR=` line's factor for the
/// channel (Radiance's convention: `pfilt -e 2`, for one, doubles the pixels and adds
/// `EXPOSURE=2`), so radiance is the stored value divided by it. None when there are no
/// such lines, so such files read bit for bit as before. A value that is not a finite
/// positive number is an error at its line.
fn hdr_header_scale(path: &Path, lines: &[(usize, String)]) -> Result<Option<[f64; 3]>, Error> {
    let mut scale = None;
    for (number, line) in lines {
        // Keys as the decoder reads them: before the first '=', trimmed; '#' comments.
        let Some((key, value)) = line.split_once('=') else {
            continue;
        };
        let key = key.trim();
        if line.starts_with('#') || !(key == "EXPOSURE" || key == "COLORCORR") {
            continue;
        }
        let numbers: Vec<&str> = value.split_whitespace().collect();
        let expected = if key == "EXPOSURE" { 1 } else { 3 };
        if numbers.len() != expected {
            return Err(Error::at_line(
                path,
                *number,
                format!(
                    "{key}= needs {expected} number{}, got '{}'",
                    if expected == 1 {
                        ""
                    } else {
                        "s (red, green, blue)"
                    },
                    value.trim()
                ),
            ));
        }
        let mut factors = [1.0f64; 3];
        for (i, text) in numbers.iter().enumerate() {
            let v = text.parse::<f64>().map_err(|_| {
                Error::at_line(
                    path,
                    *number,
                    format!("{key} value '{text}' is not a number"),
                )
            })?;
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::at_line(
                    path,
                    *number,
                    format!("{key} value {v} must be finite and > 0"),
                ));
            }
            factors[i] = v;
        }
        if key == "EXPOSURE" {
            factors = [factors[0]; 3];
        }
        let s: &mut [f64; 3] = scale.get_or_insert([1.0; 3]);
        for (s, f) in s.iter_mut().zip(factors) {
            *s *= f;
        }
    }
    if let Some(s) = scale {
        if s.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(Error::input(
                path,
                format!(
                    "the header's EXPOSURE and COLORCORR lines multiply to {s:?}, past a double's range"
                ),
            ));
        }
    }
    Ok(scale)
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

/// The image of `view` in `dir`, a folder of `<view>.exr` as `relume render` writes them
/// (exposure 1), of the view's size. The scene's own image of the view (its panorama's
/// folder given as `dir`) is read with the view's exposure, as every command reads the
/// panorama: read at 1 it was compared and joined off by that factor, without a word. A
/// `dir` that is a file is bad input, and a missing image names its view ("rA/px.exr/px.exr:
/// Not a directory", "miss/nz.exr: No such file" were all that was said).
pub fn read_folder_view_image(dir: &Path, view: &ViewDesc) -> Result<Image, Error> {
    let name = &view.name;
    if dir.is_file() {
        return Err(Error::input(
            dir,
            "is a file, not a folder of <view>.exr images (as `relume render --out` writes)",
        ));
    }
    let path = dir.join(format!("{name}.exr"));
    if !path.exists() && dir.is_dir() {
        return Err(Error::io(
            &path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("no image of view '{name}' in {}", dir.display()),
            ),
        ));
    }
    let own = view
        .image
        .as_ref()
        .is_some_and(|image| crate::fsutil::same_file(image, &path));
    read_view_image(&path, view, if own { view.exposure } else { 1.0 })
}

/// [`read_image`] of `view`'s image at `path`, read at `exposure`; its size must be the
/// view's.
pub fn read_view_image(path: &Path, view: &ViewDesc, exposure: f32) -> Result<Image, Error> {
    read_view_image_and_header(path, view, exposure).map(|(image, _)| image)
}

/// [`read_view_image`], and what the file's header divided its stored values by, per
/// channel (`None` without `EXPOSURE` or `COLORCORR` lines): a warning that blames the
/// view's exposure names it, since a header's factor is applied without a word.
pub fn read_view_image_and_header(
    path: &Path,
    view: &ViewDesc,
    exposure: f32,
) -> Result<(Image, Option<[f64; 3]>), Error> {
    let expected = view.size;
    read_radiance_sized(path, exposure, |width, height| {
        if [width, height] == expected {
            return Ok(());
        }
        Err(Error::input(
            path,
            format!(
                "image is {width}x{height} but view '{}' says size = [{}, {}]",
                view.name, expected[0], expected[1]
            ),
        ))
    })
}

/// [`read_image_sized`] of radiance (a view, a 360-degree capture): no value above
/// [`MAX_RADIANCE`] after exposure, and what the file's header divided its stored values
/// by, per channel (`None` without `EXPOSURE` or `COLORCORR` lines).
pub fn read_radiance_sized(
    path: &Path,
    exposure: f32,
    size_fits: impl FnOnce(u32, u32) -> Result<(), Error>,
) -> Result<(Image, Option<[f64; 3]>), Error> {
    let (image, header) = read_image_and_header(path, exposure, size_fits)?;
    reject_value(
        path,
        &image,
        |v| v > MAX_RADIANCE,
        &format!(
            "after exposure {}{} is above the largest radiance relume computes with, {MAX_RADIANCE:e} (is the exposure right?)",
            value_text(exposure),
            header_note(header)
        ),
    )?;
    Ok((image, header))
}

/// What a header's divisor ([`read_view_image_and_header`]) did to an image, for
/// messages about its scale: "" without one, else ", its header's EXPOSURE and COLORCORR
/// dividing its stored values by 1e300" (per channel where they differ).
pub fn header_note(divisor: Option<[f64; 3]>) -> String {
    let Some(d) = divisor else {
        return String::new();
    };
    let by = if d[0] == d[1] && d[1] == d[2] {
        text::significant(d[0])
    } else {
        format!(
            "{}, {} and {} (R, G, B)",
            text::significant(d[0]),
            text::significant(d[1]),
            text::significant(d[2])
        )
    };
    format!(", its header's EXPOSURE and COLORCORR dividing its stored values by {by}")
}

/// How a PNG's samples encode light.
#[derive(Clone, Copy, Debug, PartialEq)]
enum PngTransfer {
    /// The sRGB curve: scene-format.md's PNG, and what an `sRGB` chunk, a `gAMA` of
    /// 1/2.2 (how writers declare sRGB without that chunk) or no `gAMA` at all say.
    Srgb,
    /// `linear = sample^exponent`, the PNG standard's reading of any other `gAMA` (its
    /// value is `1 / exponent`): 1 for a linear PNG, as raw converters write 16-bit ones.
    Power(f32),
}

/// The `gAMA` values read as sRGB: 1/2.2 (45455 in the file), within rounding of writers.
const PNG_SRGB_GAMMA: core::ops::RangeInclusive<u32> = 45_400..=45_500;

/// The transfer function a PNG's chunks declare ([`PngTransfer`]); `reader` is at its
/// start. An ICC profile (`iCCP`) is not read: such a file is taken as sRGB, as most are.
fn png_transfer(
    reader: &mut (impl BufRead + Seek),
    unreadable: impl Fn(ImageError) -> Error,
) -> Result<PngTransfer, Error> {
    let decoder = png::Decoder::new(reader);
    let info_reader = decoder.read_info().map_err(|e| png_error(e, &unreadable))?;
    // `gamma()` is the gAMA chunk's value, or sRGB's 1/2.2 where an sRGB chunk overrides
    // it. A gAMA of 0 is invalid, and the decoder ignores it, as the PNG standard says.
    match info_reader
        .info()
        .gamma()
        .map(png::ScaledFloat::into_scaled)
    {
        None => Ok(PngTransfer::Srgb),
        Some(g) if PNG_SRGB_GAMMA.contains(&g) => Ok(PngTransfer::Srgb),
        Some(g) => Ok(PngTransfer::Power(100_000.0 / g as f32)),
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

/// A PNG's width and height from its header alone (the IHDR chunk).
fn png_header_size(
    reader: &mut (impl BufRead + Seek),
    unreadable: &impl Fn(ImageError) -> Error,
) -> Result<(u32, u32), Error> {
    let mut decoder = png::Decoder::new(reader);
    let info = decoder
        .read_header_info()
        .map_err(|e| png_error(e, unreadable))?;
    Ok((info.width, info.height))
}

/// A png crate's decoding error as `unreadable` reports an image crate's.
fn png_error(e: png::DecodingError, unreadable: &impl Fn(ImageError) -> Error) -> Error {
    unreadable(ImageError::Decoding(image::error::DecodingError::new(
        ImageFormat::Png.into(),
        e,
    )))
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

/// Refuses an indexed PNG whose palette is not whole RGB entries (1 to 256 of 3 bytes;
/// the png crate panics on some others where it expands them), or one of whose pixels
/// names an entry past the palette's end (which it decodes as black, a radiance never
/// measured). The pixels are read as their indices, unexpanded.
fn check_png_palette<R: BufRead + Seek>(
    path: &Path,
    info_reader: &mut png::Reader<R>,
    png_error: impl Fn(png::DecodingError) -> Error,
) -> Result<(), Error> {
    let bytes = info_reader.info().palette.as_ref().map_or(0, |p| p.len());
    if bytes == 0 || !bytes.is_multiple_of(3) || bytes > 3 * 256 {
        return Err(Error::input(
            path,
            format!("its palette (PLTE chunk) is {bytes} bytes: an indexed PNG needs 1 to 256 entries of 3 bytes"),
        ));
    }
    let entries = bytes / 3;
    let Some(size) = info_reader.output_buffer_size() else {
        return Err(png_error(png::DecodingError::LimitsExceeded));
    };
    let mut indices = vec![0u8; size];
    let frame = info_reader.next_frame(&mut indices).map_err(png_error)?;
    let bits = frame.bit_depth as usize;
    for (y, row) in indices
        .chunks(frame.line_size)
        .take(frame.height as usize)
        .enumerate()
    {
        for x in 0..frame.width as usize {
            let bit = x * bits;
            let byte = row.get(bit / 8).copied().unwrap_or(0);
            let index = (byte >> (8 - bits - bit % 8)) & ((1u16 << bits) - 1) as u8;
            if index as usize >= entries {
                return Err(Error::input(
                    path,
                    format!("pixel ({x}, {y}) names palette entry {index}, past the palette's {entries}"),
                ));
            }
        }
    }
    Ok(())
}

fn png_to_linear(decoded: DynamicImage, transfer: PngTransfer) -> Vec<[f32; 3]> {
    let decode = |c: f32| match transfer {
        PngTransfer::Srgb => srgb_to_linear(c),
        PngTransfer::Power(1.0) => c,
        PngTransfer::Power(exponent) => math::powf(c, exponent),
    };
    let bits = decoded.color().bits_per_pixel() / u16::from(decoded.color().channel_count());
    if bits > 8 {
        decoded
            .into_rgb16()
            .pixels()
            .map(|p| p.0.map(|c| decode(f32::from(c) / 65535.0)))
            .collect()
    } else {
        let table: Vec<f32> = (0..256).map(|c| decode(c as f32 / 255.0)).collect();
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

/// Rejects NaN, infinite and negative values, then multiplies by `exposure` and divides by
/// `header` (a Radiance picture's [`hdr_header_scale`], per channel), and rejects an overflow
/// to infinity. Without a header the product is f32's, as it always was.
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
                        "channel {} value {} times exposure {exposure}{header_note} overflows",
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
        .map_err(|e| match e {
            // A write that fails (a disk full) is an I/O failure (exit 4), not bad input.
            exr::error::Error::Io(io) => Error::io(path, io),
            other => Error::input(path, format!("cannot encode EXR: {other}")),
        })
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

    /// A view of `width` x `height` pixels, named "v", for the reads that check a size.
    fn sized(width: u32, height: u32) -> ViewDesc {
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

    fn err(path: &Path) -> String {
        read_image(path, 1.0)
            .expect_err("the image should be refused")
            .to_string()
    }

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
        read_view_image(&p, &sized(4, 2), 1.0).unwrap();
        let e = read_view_image(&p, &sized(256, 256), 1.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("v.exr") && e.contains("is 4x2 but view 'v' says size = [256, 256]"),
            "{e}"
        );
        // The size is refused from the header, before the pixels are decoded: a file
        // whose pixels are cut short is refused for its size, not as truncated.
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 16]).unwrap();
        let e = read_view_image(&p, &sized(4, 2), 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("truncated"), "{e}");
        let e = read_view_image(&p, &sized(256, 256), 1.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("is 4x2 but view 'v' says size = [256, 256]"),
            "{e}"
        );
    }

    /// A 16-bit RGB PNG of one pixel with the given `gAMA` (scaled by 100000) and sRGB
    /// chunk.
    fn png_with_chunks(path: &Path, gamma: Option<u32>, srgb: bool, value: [u16; 3]) {
        let file = std::fs::File::create(path).unwrap();
        let mut encoder = png::Encoder::new(file, 1, 1);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Sixteen);
        if let Some(g) = gamma {
            encoder.set_source_gamma(png::ScaledFloat::from_scaled(g));
        }
        if srgb {
            encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        }
        let bytes: Vec<u8> = value.iter().flat_map(|c| c.to_be_bytes()).collect();
        let mut writer = encoder.write_header().unwrap();
        writer.write_image_data(&bytes).unwrap();
    }

    /// An indexed PNG of `w` x 1 pixels at `depth` bits whose palette is `palette` (the
    /// PLTE chunk's bytes, as given) and whose row is `row` (packed indices).
    fn indexed_png(path: &Path, w: u32, depth: png::BitDepth, palette: &[u8], row: &[u8]) {
        let file = std::fs::File::create(path).unwrap();
        let mut encoder = png::Encoder::new(file, w, 1);
        encoder.set_color(png::ColorType::Indexed);
        encoder.set_depth(depth);
        encoder.set_palette(palette.to_vec());
        let mut writer = encoder.write_header().unwrap();
        writer.write_image_data(row).unwrap();
    }

    /// An indexed PNG reads through its palette; one whose palette is not whole RGB
    /// entries (the png crate panicked expanding a 4-byte one) or whose pixel names an
    /// entry past it (read as black before) is refused, naming the pixel.
    #[test]
    fn an_indexed_png_reads_through_a_whole_palette_and_no_further() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("i.png");
        // Two entries, black and white, at one bit a pixel: 0b0100_0000 is black, white.
        indexed_png(
            &p,
            2,
            png::BitDepth::One,
            &[0, 0, 0, 255, 255, 255],
            &[0b0100_0000],
        );
        let image = read_image(&p, 1.0).unwrap();
        assert_eq!(image.pixels, vec![[0.0; 3], [1.0; 3]]);
        // The second pixel at entry 1 of a one-entry palette.
        indexed_png(&p, 2, png::BitDepth::One, &[9, 9, 9], &[0b0100_0000]);
        let e = err(&p);
        assert!(
            e.contains("i.png: pixel (1, 0) names palette entry 1, past the palette's 1"),
            "{e}"
        );
        indexed_png(
            &p,
            3,
            png::BitDepth::Eight,
            &[9, 9, 9, 7, 7, 7],
            &[1, 0, 200],
        );
        let e = err(&p);
        assert!(
            e.contains("pixel (2, 0) names palette entry 200, past the palette's 2"),
            "{e}"
        );
        for bytes in [4, 5, 10] {
            indexed_png(&p, 1, png::BitDepth::Eight, &vec![9; bytes], &[0]);
            let e = err(&p);
            assert!(
                e.contains(&format!("its palette (PLTE chunk) is {bytes} bytes: an indexed PNG needs 1 to 256 entries of 3 bytes")),
                "{e}"
            );
        }
    }

    /// An indexed PNG whose header claims 200000 x 100000 pixels is refused by the
    /// capacity, before its indices are read (20 GB of them).
    #[test]
    fn an_indexed_png_of_too_many_pixels_is_refused_before_its_indices_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("huge.png");
        indexed_png(&p, 1, png::BitDepth::Eight, &[9, 9, 9], &[0]);
        let mut bytes = std::fs::read(&p).unwrap();
        // IHDR follows the 8-byte signature: length, type, width, height, ..., CRC.
        bytes[16..20].copy_from_slice(&200_000u32.to_be_bytes());
        bytes[20..24].copy_from_slice(&100_000u32.to_be_bytes());
        let crc = crc32(&bytes[12..29]);
        bytes[29..33].copy_from_slice(&crc.to_be_bytes());
        std::fs::write(&p, &bytes).unwrap();
        let e = read_image(&p, 1.0).unwrap_err();
        assert_eq!(e.exit_code(), 5, "{e}");
        assert!(e.to_string().contains("image is 200000x100000"), "{e}");
    }

    /// The PNG chunks' CRC-32 (ISO 3309), bit by bit.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }

    /// An uncompressed scanline EXR whose block offset for row 1 is row 2's: the image
    /// crate read row 2 in its place and left row 1 black, without a word.
    #[test]
    fn an_exr_whose_block_offsets_repeat_is_refused() {
        use exr::prelude::{Encoding, SpecificChannels, Vec2, WritableImage};
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.exr");
        let ch = SpecificChannels::rgb(|pos: Vec2<usize>| (0.5f32, pos.y() as f32, 0.25f32));
        exr::prelude::Image::from_encoded_channels((2, 4), Encoding::UNCOMPRESSED, ch)
            .write()
            .to_file(&p)
            .unwrap();
        assert_eq!(read_image(&p, 1.0).unwrap().pixels[2], [0.5, 1.0, 0.25]);
        // The table of four offsets ends where the first block starts: find it so.
        let mut bytes = std::fs::read(&p).unwrap();
        let at = |i: usize| u64::from_le_bytes(bytes[i..i + 8].try_into().unwrap());
        let table = (0..bytes.len() - 32)
            .find(|&i| at(i) == (i + 32) as u64)
            .expect("the offset table");
        let third = at(table + 16);
        bytes[table + 8..table + 16].copy_from_slice(&third.to_le_bytes());
        std::fs::write(&p, &bytes).unwrap();
        let e = err(&p);
        assert!(
            e.contains("o.exr: its table of block offsets is corrupt"),
            "{e}"
        );
    }

    /// A PNG's gAMA chunk is honoured (the PNG standard's `linear = sample^(1/gamma)`);
    /// an sRGB chunk, a gAMA of 1/2.2 or none mean the sRGB curve.
    #[test]
    fn png_gamma_chunk_decides_the_transfer() {
        let dir = tempfile::tempdir().unwrap();
        let half = [32768u16; 3];
        let read = |gamma: Option<u32>, srgb: bool| {
            let p = dir.path().join("g.png");
            png_with_chunks(&p, gamma, srgb, half);
            read_image(&p, 1.0).unwrap().pixels[0][0]
        };
        let c = 32768.0f32 / 65535.0;
        let srgb = srgb_to_linear(c);
        assert_eq!(read(None, false), srgb);
        assert_eq!(read(Some(45455), false), srgb);
        assert_eq!(read(Some(100_000), true), srgb, "the sRGB chunk wins");
        assert_eq!(read(Some(100_000), false), c, "a linear PNG");
        assert_eq!(
            read(Some(50_000), false),
            math::powf(c, 2.0),
            "gamma 1/2: light = sample^2"
        );
    }

    #[test]
    fn png_8_and_16_bit_decode_srgb() {
        let dir = tempfile::tempdir().unwrap();
        let p8 = dir.path().join("a.png");
        image::RgbaImage::from_raw(
            3,
            1,
            vec![0, 128, 255, 255, 255, 255, 255, 255, 10, 20, 30, 255],
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

    /// RGBE is read as RADIANCE reads it, `(mantissa + 0.5) * 2^(e - 136)` with black at
    /// exponent 0: the image crate leaves out the half step, and every `.hdr` view and map
    /// read 0.2-0.4% dark against RADIANCE.
    #[test]
    fn hdr_reads_rgbe_as_radiance_does() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.hdr");
        let texels: [[u8; 4]; 4] = [
            [128, 128, 128, 129],
            [255, 0, 64, 130],
            [0, 0, 0, 0],
            [200, 150, 100, 1],
        ];
        let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 4\n".to_vec();
        bytes.extend(texels.iter().flatten());
        std::fs::write(&p, bytes).unwrap();
        let back = read_image(&p, 1.0).unwrap();
        // (128.5) 2^-7; (255.5, 0.5, 64.5) 2^-6; black; (200.5, 150.5, 100.5) 2^-135.
        let two_to_minus_135 = f64::from_bits((1023 - 135) << 52);
        let tiny = |m: f32| (f64::from(m) * two_to_minus_135) as f32;
        assert_eq!(
            back.pixels,
            vec![
                [1.003_906_3; 3],
                [3.992_187_5, 0.007_812_5, 1.007_812_5],
                [0.0; 3],
                [tiny(200.5), tiny(150.5), tiny(100.5)],
            ]
        );
        // What the image crate's encoder wrote (by truncation, as RADIANCE's `setcolr`, which
        // loses up to a step) comes back within half a step of its value.
        let px = [image::Rgb([1.0f32, 0.5, 2.0]), image::Rgb([0.0, 0.3, 8.0])];
        let mut bytes = Vec::new();
        image::codecs::hdr::HdrEncoder::new(&mut bytes)
            .encode(&px, 2, 1)
            .unwrap();
        std::fs::write(&p, bytes).unwrap();
        let back = read_image(&p, 1.0).unwrap();
        for (read, written) in back.pixels.iter().zip(&px) {
            let step = written.0[2] / 128.0;
            for (r, w) in read.iter().zip(written.0) {
                assert!((*r - w).abs() <= step / 2.0, "{read:?} {written:?}");
            }
        }
    }

    /// Writes an EXR of grey 0.5 whose data window is `data` (corner, size) within the
    /// display window `display`.
    fn windowed_exr(
        path: &Path,
        display: ((i32, i32), (usize, usize)),
        data: ((i32, i32), (usize, usize)),
    ) {
        use exr::prelude::{
            Encoding, ImageAttributes, IntegerBounds, Layer, LayerAttributes, SpecificChannels,
            Vec2, WritableImage,
        };
        let attributes = LayerAttributes {
            layer_position: Vec2(data.0 .0, data.0 .1),
            ..LayerAttributes::default()
        };
        let channels = SpecificChannels::rgb(|_: Vec2<usize>| (0.5f32, 0.5f32, 0.5f32));
        let layer = Layer::new(data.1, attributes, Encoding::UNCOMPRESSED, channels);
        let display = IntegerBounds::new(display.0, display.1);
        exr::prelude::Image::new(ImageAttributes::new(display), layer)
            .write()
            .to_file(path)
            .unwrap();
    }

    #[test]
    fn an_exr_whose_data_window_does_not_cover_the_display_window_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let cases = [
            // An 8x8 data window in a 16x16 image: 3/4 of it would read black.
            (
                ((0, 0), (16, 16)),
                ((0, 0), (8, 8)),
                "(0,0)-(7,7)",
                "(0,0)-(15,15)",
            ),
            // The right size, offset.
            (
                ((0, 0), (16, 16)),
                ((4, 4), (16, 16)),
                "(4,4)-(19,19)",
                "(0,0)-(15,15)",
            ),
            (
                ((-2, 3), (4, 4)),
                ((-2, 3), (4, 3)),
                "(-2,3)-(1,5)",
                "(-2,3)-(1,6)",
            ),
        ];
        for (i, (display, data, data_text, display_text)) in cases.into_iter().enumerate() {
            let p = dir.path().join(format!("w{i}.exr"));
            windowed_exr(&p, display, data);
            let e = read_view_image(&p, &sized(display.1 .0 as u32, display.1 .1 as u32), 1.0)
                .expect_err("the uncovered pixels have no value");
            assert_eq!(e.exit_code(), 3, "{e}");
            let e = e.to_string();
            assert!(
                e.contains(&format!(
                    "w{i}.exr: data window {data_text} does not cover the display window \
                     {display_text}: pixels outside it have no value"
                )),
                "{e}"
            );
        }
        // Equal windows (here away from the origin) read as before, and a larger data
        // window (overscan) is cropped to the display window.
        for (i, (display, data)) in [
            (((-3, -2), (4, 3)), ((-3, -2), (4, 3))),
            (((0, 0), (4, 3)), ((-1, -1), (6, 5))),
        ]
        .into_iter()
        .enumerate()
        {
            let p = dir.path().join(format!("ok{i}.exr"));
            windowed_exr(&p, display, data);
            let img = read_view_image(&p, &sized(4, 3), 1.0).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(img.pixels, vec![[0.5; 3]; 12]);
        }
    }

    /// An RGBE file of `pixels` (one row) with `lines` added to its header after the
    /// signature (so the first added line is line 2).
    fn hdr_with_header(path: &Path, lines: &str, pixels: &[[f32; 3]]) {
        let px: Vec<image::Rgb<f32>> = pixels.iter().map(|p| image::Rgb(*p)).collect();
        let mut bytes = Vec::new();
        image::codecs::hdr::HdrEncoder::new(&mut bytes)
            .encode(&px, px.len(), 1)
            .unwrap();
        let first_line_end = bytes.iter().position(|&b| b == b'\n').unwrap() + 1;
        bytes.splice(first_line_end..first_line_end, lines.bytes());
        std::fs::write(path, bytes).unwrap();
    }

    /// The divisor a view's header applied comes back with the image, for the warnings
    /// that blame the view's exposure; none without such lines or for other formats.
    #[test]
    fn a_views_header_divisor_is_returned_and_told() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.hdr");
        let stored = [[1.0, 0.5, 2.0], [0.0, 0.25, 8.0]];
        hdr_with_header(&p, "EXPOSURE=1e300\nEXPOSURE=10\n", &stored);
        let (image, divisor) = read_view_image_and_header(&p, &sized(2, 1), 1.0).unwrap();
        assert_eq!(divisor, Some([1e301; 3]));
        assert_eq!(image.pixels, vec![[0.0; 3]; 2]);
        assert_eq!(
            header_note(divisor),
            ", its header's EXPOSURE and COLORCORR dividing its stored values by 1e301"
        );
        hdr_with_header(&p, "COLORCORR=1 2 0.5\n", &stored);
        let (_, divisor) = read_view_image_and_header(&p, &sized(2, 1), 1.0).unwrap();
        assert_eq!(
            header_note(divisor),
            ", its header's EXPOSURE and COLORCORR dividing its stored values by 1, 2 and 0.5 (R, G, B)"
        );
        hdr_with_header(&p, "SOFTWARE=test\n", &stored);
        assert_eq!(
            read_view_image_and_header(&p, &sized(2, 1), 1.0).unwrap().1,
            None
        );
        assert_eq!(header_note(None), "");
    }

    #[test]
    fn hdr_header_exposure_and_colorcorr_are_divided_out() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.hdr");
        let stored = [[1.0, 0.5, 2.0], [0.0, 0.25, 8.0]];
        // Several EXPOSURE lines multiply, COLORCORR is per channel: stored / [8, 16, 4].
        hdr_with_header(
            &p,
            "EXPOSURE=2\n# EXPOSURE=100 is a comment\nEXPOSURE= 4\nCOLORCORR=1 2 0.5\n",
            &stored,
        );
        // Each stored value is read with RADIANCE's half step: 2^-7 on the first pixel
        // (brightest 2.0), 2^-5 on the second (brightest 8.0).
        let back = read_image(&p, 2.0).unwrap();
        assert_eq!(
            back.pixels,
            vec![
                [0.251_953_13, 0.063_476_56, 1.003_906_3],
                [0.007_812_5, 0.035_156_25, 4.015_625]
            ]
        );
        hdr_with_header(&p, "EXPOSURE=2\n", &stored);
        let back = read_view_image(&p, &sized(2, 1), 1.0).unwrap();
        assert_eq!(
            back.pixels,
            vec![
                [0.503_906_25, 0.253_906_25, 1.003_906_3],
                [0.015_625, 0.140_625, 4.015_625]
            ]
        );
        // Without such lines the stored values, bit for bit.
        let odd = [[1.0e-30, 0.1, 3.0e30], [1.0 / 3.0, 7.0, 0.0]];
        hdr_with_header(&p, "", &odd);
        let expected: Vec<[f32; 3]> = (read_image(&p, 1.0).unwrap().pixels.iter())
            .map(|p| p.map(|v| v * 1.5))
            .collect();
        hdr_with_header(&p, "SOFTWARE=test\n", &odd);
        assert_eq!(read_image(&p, 1.5).unwrap().pixels, expected);
        // A tiny EXPOSURE can take a stored value past f32's range.
        hdr_with_header(&p, "EXPOSURE=1e-40\n", &stored);
        let e = read_image(&p, 1.0).unwrap_err().to_string();
        assert!(
            e.contains("a.hdr: pixel (x 0, y 0): channel R value 1.0078125 times exposure 1 divided by the header's EXPOSURE and COLORCORR, 1e-40 overflows")
                && e.contains("overflows"),
            "{e}"
        );
        for (line, what) in [
            ("EXPOSURE=0", "EXPOSURE value 0 must be finite and > 0"),
            ("EXPOSURE=-2", "EXPOSURE value -2 must be finite and > 0"),
            ("EXPOSURE=inf", "EXPOSURE value inf must be finite and > 0"),
            ("EXPOSURE=NaN", "EXPOSURE value NaN must be finite and > 0"),
            ("EXPOSURE=two", "EXPOSURE value 'two' is not a number"),
            ("EXPOSURE=", "EXPOSURE= needs 1 number, got ''"),
            (
                "COLORCORR=1 2",
                "COLORCORR= needs 3 numbers (red, green, blue), got '1 2'",
            ),
            (
                "COLORCORR=1 0 1",
                "COLORCORR value 0 must be finite and > 0",
            ),
        ] {
            hdr_with_header(&p, &format!("FORMAT=32-bit_rle_rgbe\n{line}\n"), &stored);
            let e = read_image(&p, 1.0).expect_err(line);
            assert_eq!(e.exit_code(), 3, "{e}");
            let e = e.to_string();
            assert!(e.contains(&format!("a.hdr:3: {what}")), "{line}: {e}");
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
    fn box_diffuse_small_views_load() {
        let Some(bench) = crate::scene_file::tests::bench() else {
            return;
        };
        for v in ["px", "nx", "py", "ny", "pz", "nz"] {
            let p = bench.join(format!("box-diffuse/views-small/{v}.exr"));
            let img = read_view_image(&p, &sized(64, 64), 1.0).unwrap_or_else(|e| panic!("{e}"));
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
