//! Radiance RGBE pictures (.hdr): a pixel read as RADIANCE reads it, the header's `EXPOSURE`
//! and `COLORCORR` lines (divided out of the pixels, and told in messages), and writing one.

use std::io::{BufRead, Read};
use std::path::Path;

use super::{check_buffer, check_finite, Image};
use crate::error::Error;
use crate::text;

/// A Radiance RGBE pixel as RADIANCE reads it (`colr_color`: `(mantissa + 0.5) * 2^(e - 136)`),
/// from the image crate's reading (`mantissa * 2^(e - 136)`, no half step): a writer
/// truncates (`setcolr`, and the image crate's encoder), so the half step is the unbiased
/// reading, and without it every `.hdr` view and map read 0.2-0.4% dark against RADIANCE.
/// The step is found from the brightest channel, whose mantissa every writer normalises to
/// 128-255; black (exponent 0) stays black.
pub(super) fn rgbe_half_step(pixel: [f32; 3]) -> [f32; 3] {
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

/// The header lines of a Radiance picture, numbered from 1 (the `#?RADIANCE` line), up to
/// the empty line that ends the header (or the file's end, which the decoder then refuses).
/// No lines for a file without the signature, also left for the decoder to refuse.
pub(super) fn hdr_header_lines(reader: &mut impl BufRead) -> std::io::Result<Vec<(usize, String)>> {
    const SIGNATURE: &[u8] = b"#?RADIANCE";
    let mut lines = Vec::new();
    // The signature's bytes, however many pieces the reader hands them over in, and no
    // further: a file without it is left for the decoder to refuse as it would.
    let mut line = Vec::new();
    reader
        .by_ref()
        .take(SIGNATURE.len() as u64)
        .read_to_end(&mut line)?;
    if line != SIGNATURE {
        return Ok(lines);
    }
    loop {
        // Lines end at '\n' alone, as the decoder reads them.
        if reader.read_until(b'\n', &mut line)? == 0 && line.is_empty() {
            return Ok(lines);
        }
        if line.last() == Some(&b'\n') {
            line.pop();
        }
        if line.is_empty() {
            return Ok(lines);
        }
        lines.push((lines.len() + 1, String::from_utf8_lossy(&line).into_owned()));
        line.clear();
    }
}

/// What a Radiance picture's header says its stored values were multiplied by, per
/// channel: every `EXPOSURE=` line, times every `COLORCORR=` line's factor for the
/// channel (Radiance's convention: `pfilt -e 2`, for one, doubles the pixels and adds
/// `EXPOSURE=2`), so radiance is the stored value divided by it. None when there are no
/// such lines, so such files read bit for bit as before. A value that is not a finite
/// positive number is an error at its line.
pub(super) fn hdr_header_scale(
    path: &Path,
    lines: &[(usize, String)],
) -> Result<Option<[f64; 3]>, Error> {
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

/// What a header's divisor
/// ([`read_view_image_and_header`](super::read_view_image_and_header)) did to an image,
/// for messages about its scale: "" without one, else ", its header's EXPOSURE and
/// COLORCORR dividing its stored values by 1e300" (per channel where they differ).
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::images::tests::sized;
    use crate::images::{read_image, read_view_image, read_view_image_and_header};

    /// The header is read line by line whatever pieces the reader hands its bytes over in:
    /// it once looked for the signature in the first buffer alone, and a reader that gave
    /// fewer than its ten bytes would have skipped the header's EXPOSURE silently.
    #[test]
    fn hdr_header_lines_do_not_hang_on_the_readers_buffer() {
        let bytes = b"#?RADIANCE\nEXPOSURE=2\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 1\n";
        let whole = hdr_header_lines(&mut &bytes[..]).unwrap();
        let mut byte_by_byte = std::io::BufReader::with_capacity(1, &bytes[..]);
        let in_pieces = hdr_header_lines(&mut byte_by_byte).unwrap();
        assert_eq!(whole.len(), 3);
        assert_eq!(whole[1], (2, "EXPOSURE=2".to_string()));
        assert_eq!(in_pieces, whole);
        // No signature, no lines; an empty first line is no signature either.
        assert!(hdr_header_lines(&mut &b"P6\n1 1\n255\n"[..])
            .unwrap()
            .is_empty());
        assert!(hdr_header_lines(&mut &b"\n#?RADIANCE\n\n"[..])
            .unwrap()
            .is_empty());
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
}
