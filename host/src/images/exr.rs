//! OpenEXR: what is checked before the image crate decodes one (its data window covers its
//! display window, its table of block offsets is sound), and writing linear float EXR.

use std::io::{Read, Seek, Write};
use std::path::Path;

use image::error::{DecodingError, ImageFormatHint};
use image::{ImageError, ImageFormat};

use super::{check_buffer, check_finite, Image};
use crate::error::Error;
use crate::fsutil::OutputSet;

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
pub(super) fn check_exr_windows(
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
pub(super) fn check_exr_offsets(
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

/// Writes linear float32 RGB (ZIP compressed), atomically; [`read_image`](super::read_image)
/// gives back the same floats.
pub fn write_exr(path: &Path, image: &Image) -> Result<(), Error> {
    let mut set = OutputSet::default();
    add_exr(&mut set, path, image)?;
    set.commit()
}

/// Encodes `image` as EXR into `out` (`path` is named in errors), without the finite check
/// (tests write bad files as another program might). The pixels are read as the encoder
/// goes, block by block: no second copy of the image is made.
pub(super) fn encode_exr(path: &Path, image: &Image, out: impl Write + Seek) -> Result<(), Error> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::images::tests::{err, image, sized};
    use crate::images::{read_image, read_view_image};

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
}
