//! `relume bench downsample`: a scene's panorama box-averaged by an integer factor, with a
//! scene.toml that points at it. A pixel of the result is exactly the mean of its
//! `factor x factor` pixels, which is what a render of the same footprint gives (the
//! references' `views-small/` are made this way), so recovery can be timed and judged at
//! several resolutions from one panorama.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::assemble::{self, MaterialSource};
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::images::{self, Image};
use crate::scene_file::{self, GroupKind, SceneDesc, ViewDesc, ViewKey};

/// Box-averages `image` by `factor` (its size must be a multiple of it).
pub fn box_average(image: &Image, factor: u32) -> Image {
    let (w, h) = (image.width / factor, image.height / factor);
    let n = (factor * factor) as f64;
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f64; 3];
            for dy in 0..factor {
                for dx in 0..factor {
                    let p =
                        image.pixels[((y * factor + dy) * image.width + x * factor + dx) as usize];
                    for c in 0..3 {
                        sum[c] += p[c] as f64;
                    }
                }
            }
            pixels.push(sum.map(|s| (s / n) as f32));
        }
    }
    Image {
        width: w,
        height: h,
        pixels,
    }
}

fn list<T: std::fmt::Debug>(v: &[T]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", items.join(", "))
}

/// `s` as a TOML string. (Rust's `{:?}` is not TOML: it writes `\u{200b}` for a zero-width
/// space, which TOML reads as an error, so a derived scene.toml could not be read back.)
fn quoted(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

/// `path` as a TOML string; a path that is not UTF-8 cannot be written in scene.toml (its
/// display form would name another file).
fn quoted_path(scene: &Path, path: &Path) -> Result<String, Error> {
    match path.to_str() {
        Some(s) => Ok(quoted(s)),
        None => Err(Error::input(
            scene,
            format!(
                "{} is not valid UTF-8: a derived scene.toml cannot name it",
                path.display()
            ),
        )),
    }
}

/// scene.toml text for `desc`, with absolute paths (the file lives elsewhere).
pub(crate) fn scene_toml(desc: &SceneDesc) -> Result<String, Error> {
    let mut t = String::new();
    let paths: Vec<String> = desc
        .geometry
        .iter()
        .map(|p| quoted_path(&desc.path, p))
        .collect::<Result<_, _>>()?;
    let hide: Vec<String> = desc.hide.iter().map(|h| quoted(h)).collect();
    let _ = writeln!(
        t,
        "format = 1\nname = {}\ngeometry = [{}]\nhide = [{}]",
        quoted(&desc.name),
        paths.join(", "),
        hide.join(", ")
    );
    t.push_str(&view_tables(&desc.path, &desc.views)?);
    for l in &desc.lights {
        let _ = writeln!(
            t,
            "\n[[light]]\nobject = {}\nradiance = {}",
            quoted(&l.object),
            list(&l.radiance)
        );
    }
    for g in &desc.groups {
        let kind = match g.kind {
            GroupKind::Plastic => "plastic",
            GroupKind::Metal => "metal",
            GroupKind::Auto => "auto",
        };
        let objects: Vec<String> = g.objects.iter().map(|o| quoted(o)).collect();
        let _ = writeln!(
            t,
            "\n[[group]]\nname = {}\nkind = \"{kind}\"\nobjects = [{}]",
            quoted(&g.name),
            objects.join(", ")
        );
    }
    Ok(t)
}

/// The `[[view]]` tables of `views`, each after a blank line, their images' paths as given
/// (`scene` names the file in an error).
pub(crate) fn view_tables(scene: &Path, views: &[ViewDesc]) -> Result<String, Error> {
    let mut t = String::new();
    for v in views {
        let _ = writeln!(t, "\n[[view]]\nname = {}", quoted(&v.name));
        if let Some(image) = &v.image {
            let _ = writeln!(t, "image = {}", quoted_path(scene, image)?);
        }
        let _ = writeln!(
            t,
            "position = {}\ndirection = {}\nup = {}\nfov_deg = {}\nsize = [{}, {}]\nexposure = {:?}",
            list(&v.position),
            list(&v.direction),
            list(&v.up),
            list(&v.fov_deg),
            v.size[0],
            v.size[1],
            v.exposure
        );
    }
    Ok(t)
}

/// Writes `out/scene.toml` and `out/views/<view>.exr`, the panorama of `scene` box-averaged
/// by `factor`. Errors: a factor of 0, a view without image, a size not divisible.
/// Returns its warnings: the PNG views with clipped pixels.
pub fn downsample(scene: &Path, factor: u32, out: &Path) -> Result<Vec<String>, Error> {
    if factor == 0 {
        return Err(Error::Usage("--factor must be at least 1".into()));
    }
    // Its geometry checked as `check` would, else the scene written was refused only when
    // it was used.
    assemble::load_and_assemble(scene, MaterialSource::GeometryOnly)?;
    let desc = scene_file::load_scene(scene)?;
    // A PNG's largest code reads as the view's exposure and holds every radiance from
    // there up (clipped): `check` and `recover` tell such pixels, but averaged into the
    // EXR written they read as radiance, and nothing told them.
    let mut warnings = Vec::new();
    for (vi, v) in desc.views.iter().enumerate() {
        let Some(path) = v.image.as_ref() else {
            continue;
        };
        if !path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        {
            continue;
        }
        let path = desc.view_image(vi, "nothing to downsample")?;
        let image = images::read_view_image(path, v, v.exposure)?;
        let clipped = image
            .pixels
            .iter()
            .filter(|p| p.iter().any(|&c| c >= v.exposure))
            .count();
        if clipped > 0 {
            warnings.push(format!(
                "view '{}': {} of {} are at the PNG's largest value in some channel (clipped): averaged into {}, they read as radiance, and check and recover of the derived scene cannot tell them (its colours there come out dark)",
                v.name,
                crate::text::counted(clipped as u64, "pixel"),
                path.display(),
                out.join("views").join(format!("{}.exr", v.name)).display()
            ));
        }
    }
    write_derived_scene(scene, desc, factor, out, "downsample", |_, _| {})?;
    Ok(warnings)
}

/// Writes `desc` (read from `scene`) as `out/scene.toml`, every view's panorama read with
/// its exposure applied, box-averaged by `factor`, passed through `edit(view index, image)`
/// and written to `out/views/<view>.exr` at exposure 1 (radiance in, radiance out); the
/// geometry paths made absolute, all as one output set (a failure leaves none of them).
/// `doing` names the operation in errors. Returns the scene file's path. Errors: a view
/// without image, a size not divisible by `factor`, an output that would replace one of
/// the scene's own files.
pub fn write_derived_scene(
    scene: &Path,
    mut desc: SceneDesc,
    factor: u32,
    out: &Path,
    doing: &str,
    mut edit: impl FnMut(usize, &mut Image),
) -> Result<PathBuf, Error> {
    let views_dir = out.join("views");
    let scene_path = out.join("scene.toml");
    // One set, which may replace none of the scene's own files: derived into the scene's
    // folder, the panorama's views and scene.toml would be overwritten.
    let mut set = OutputSet::keeping(desc.input_files());
    set.check_targets(
        std::iter::once(scene_path.clone()).chain(
            desc.views
                .iter()
                .map(|v| views_dir.join(format!("{}.exr", v.name))),
        ),
    )?;
    set.create_dir(&views_dir)?;
    // The views' paths as the derived scene gives them: absolute, in a folder that exists.
    let views_dir_absolute =
        std::fs::canonicalize(&views_dir).map_err(|e| Error::io(&views_dir, e))?;
    for vi in 0..desc.views.len() {
        let path = desc
            .view_image(vi, &format!("nothing to {doing}"))?
            .to_path_buf();
        let v = &mut desc.views[vi];
        if !(v.size[0].is_multiple_of(factor) && v.size[1].is_multiple_of(factor)) {
            return Err(scene_file::view_error(
                scene,
                vi,
                ViewKey::Size,
                format!(
                    "view '{}' is {}x{}, not a multiple of factor {factor}",
                    v.name, v.size[0], v.size[1]
                ),
            ));
        }
        let mut image = images::read_view_image(&path, v, v.exposure)?;
        if factor > 1 {
            image = box_average(&image, factor);
        }
        edit(vi, &mut image);
        let file = format!("{}.exr", v.name);
        images::add_exr(&mut set, &views_dir.join(&file), &image)?;
        v.image = Some(views_dir_absolute.join(file));
        v.size = [v.size[0] / factor, v.size[1] / factor];
        v.exposure = 1.0;
    }
    desc.geometry = desc
        .geometry
        .iter()
        .map(|g| std::fs::canonicalize(g).map_err(|e| Error::io(g, e)))
        .collect::<Result<_, _>>()?;
    set.add(&scene_path, scene_toml(&desc)?.as_bytes())?;
    set.commit()?;
    Ok(scene_path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_average_is_the_mean_of_each_block() {
        let image = Image {
            width: 4,
            height: 2,
            pixels: (0..8).map(|i| [i as f32, 1.0, 2.0 * i as f32]).collect(),
        };
        let small = box_average(&image, 2);
        assert_eq!((small.width, small.height), (2, 1));
        // Block 0: pixels 0, 1, 4, 5 -> mean 2.5; block 1: 2, 3, 6, 7 -> 4.5.
        assert_eq!(small.pixels, vec![[2.5, 1.0, 5.0], [4.5, 1.0, 9.0]]);
    }
}
