//! PNG reading: the transfer function its chunks declare (sRGB, or `gAMA`'s power law), its
//! size from the header alone, an indexed PNG's palette, and its samples to linear; the
//! sRGB curves both ways.

use std::io::{BufRead, Seek};
use std::path::Path;

use image::{DynamicImage, ImageError, ImageFormat};
use relume_core::math;

use crate::error::Error;

/// How a PNG's samples encode light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum PngTransfer {
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
pub(super) fn png_transfer(
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

/// A PNG's width and height from its header alone (the IHDR chunk).
pub(super) fn png_header_size(
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
pub(super) fn png_error(e: png::DecodingError, unreadable: &impl Fn(ImageError) -> Error) -> Error {
    unreadable(ImageError::Decoding(image::error::DecodingError::new(
        ImageFormat::Png.into(),
        e,
    )))
}

/// Refuses an indexed PNG whose palette is not whole RGB entries (1 to 256 of 3 bytes;
/// the png crate panics on some others where it expands them), or one of whose pixels
/// names an entry past the palette's end (which it decodes as black, a radiance never
/// measured). The pixels are read as their indices, unexpanded.
pub(super) fn check_png_palette<R: BufRead + Seek>(
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

pub(super) fn png_to_linear(decoded: DynamicImage, transfer: PngTransfer) -> Vec<[f32; 3]> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::images::read_image;
    use crate::images::tests::err;

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
