//! A view's image (and other radiance, such as a 360-degree capture): read at the view's
//! size and exposure, within [`MAX_RADIANCE`], with what its header divided it by; written
//! as an EXR with its PNG preview.

use std::path::{Path, PathBuf};

use super::read::read_image_and_header;
use super::{
    add_exr, header_note, reject_value, value_text, write_png_preview, Image, MAX_RADIANCE,
};
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::scene_file::ViewDesc;

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

/// [`read_image`](super::read_image) of `view`'s image at `path`, read at `exposure`; its
/// size must be the view's.
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

/// [`read_image_sized`](super::read_image_sized) of radiance (a view, a 360-degree
/// capture): no value above [`MAX_RADIANCE`] after exposure, and what the file's header
/// divided its stored values by, per channel (`None` without `EXPOSURE` or `COLORCORR`
/// lines).
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::images::tests::{raw_exr, sized};

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
}
