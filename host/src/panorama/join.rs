//! `relume panorama join`: a scene's views from one position joined into one
//! equirectangular image, each texel its footprint's mean over the view that sees it most
//! centrally.

use std::path::{Path, PathBuf};

use relume_core::geometry::View;
use relume_core::math::Vec3;

use super::{common_position, in_view, texel_at, Frame, MAX_SAMPLES_PER_SIDE};
use crate::assemble;
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::images::{self, Image};
use crate::parallel;

pub struct JoinArgs {
    /// The scene whose views the images are.
    pub scene: PathBuf,
    /// The folder of `<view>.exr`, as `relume render` writes them.
    pub dir: PathBuf,
    /// The equirectangular image to write (.exr; its PNG preview goes beside it).
    pub out: PathBuf,
    /// Its width (twice its height); `None`: four times the widest view's side, about a
    /// texel per view pixel on the horizon.
    pub width: Option<u32>,
    pub forward: [f32; 3],
    pub up: [f32; 3],
    pub threads: Option<usize>,
}

/// Joins the scene's views, all at one position, into one equirectangular image: each
/// texel the mean of lookups on a grid over its footprint, each lookup in the view that
/// sees its direction most centrally. Every direction must be seen by some view.
/// What [`join`] made: the panorama's width, the samples per texel side, and warnings.
pub struct Joined {
    pub width: u32,
    pub samples_per_side: u32,
    pub warnings: Vec<String>,
}

/// Views in `dir` that its `render.json` (written by `relume render`) does not list: left
/// by an earlier render, where a later one with `--view` rendered only some, and joined
/// with the new ones without a word. Nothing where the folder has no render.json.
fn views_not_of_the_last_render(dir: &Path, names: &[&str]) -> Option<String> {
    let text = std::fs::read_to_string(dir.join("render.json")).ok()?;
    let info: serde_json::Value = serde_json::from_str(&text).ok()?;
    let listed: Vec<&str> = info["views"]
        .as_array()?
        .iter()
        .filter_map(|v| v.as_str())
        .collect();
    let older: Vec<&str> = names
        .iter()
        .copied()
        .filter(|n| !listed.contains(n))
        .collect();
    (!older.is_empty()).then(|| {
        format!(
            "{}: views {} are not of the last render into this folder (its render.json lists {}): they are joined as they are, from an earlier render",
            dir.display(),
            older.join(", "),
            listed.join(", ")
        )
    })
}

pub fn join(args: &JoinArgs) -> Result<Joined, Error> {
    let frame = Frame::new(args.forward, args.up)?;
    let (desc, objects) = assemble::load_scene(&args.scene)?;
    common_position(&desc, &objects)?;
    let widest = widest_side(desc.views.iter().map(|v| v.size));
    let width = args.width.unwrap_or(4 * widest);
    let max = relume_core::config::MAX_VIEW_SIDE;
    if width < 2 || !width.is_multiple_of(2) || width > max {
        return Err(Error::Usage(format!(
            "--width {width}: an equirectangular image's width must be even, 2 to {max} (config::MAX_VIEW_SIDE)"
        )));
    }
    if args.out.extension().and_then(|e| e.to_str()) != Some("exr") {
        return Err(Error::Usage(format!(
            "--out {}: the joined panorama is written as EXR (and a PNG preview beside it): name it <name>.exr",
            args.out.display()
        )));
    }
    let mut views = Vec::new();
    let mut inputs = desc.input_files();
    for v in &desc.views {
        let view = v
            .view()
            .map_err(|e| Error::core(format!("{}: view '{}'", args.scene.display(), v.name), e))?;
        let path = args.dir.join(format!("{}.exr", v.name));
        let image = images::read_folder_view_image(&args.dir, v)?;
        inputs.push((path, format!("the image of view '{}'", v.name)));
        views.push((view, image));
    }
    let preview = args.out.with_extension("png");
    let mut set = OutputSet::keeping(inputs);
    set.check_targets([args.out.clone(), preview.clone()])?;
    if let Some(folder) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        set.create_dir(folder)?;
    }
    let pool = parallel::thread_pool(args.threads)?;
    let (image, k) = equirect_from_views(&pool, &frame, &views, width).map_err(|d| {
        Error::input(
            &args.scene,
            format!(
                "no view sees the direction [{:.3}, {:.3}, {:.3}]: join needs views that see every direction from their position, as the six faces of `relume panorama split` do",
                d.x, d.y, d.z
            ),
        )
    })?;
    images::add_exr(&mut set, &args.out, &image)?;
    // Exposed as the views' own previews would be, pooled: the equirectangular image
    // stretches what is near the poles (a ceiling lamp across its top rows), and its own
    // percentile would then be the lamp's.
    let pooled: Vec<[f32; 3]> = views
        .iter()
        .flat_map(|(_, v)| v.pixels.iter().copied())
        .collect();
    let exposure = images::auto_exposure(&Image {
        width: pooled.len() as u32,
        height: 1,
        pixels: pooled,
    });
    set.add_written(&preview, |file| {
        images::write_png_preview(&preview, &image, Some(exposure), file)
    })?;
    set.commit()?;
    let names: Vec<&str> = desc.views.iter().map(|v| v.name.as_str()).collect();
    Ok(Joined {
        width,
        samples_per_side: k,
        warnings: views_not_of_the_last_render(&args.dir, &names)
            .into_iter()
            .collect(),
    })
}

/// The longest side of views of these sizes (1 for none).
fn widest_side(sizes: impl Iterator<Item = [u32; 2]>) -> u32 {
    sizes.map(|[w, h]| w.max(h)).max().unwrap_or(1)
}

/// The equirectangular image `width` texels wide of what `views` see: each texel the mean
/// of lookups on a grid over its footprint (two per view pixel it spans at a view's centre,
/// where pixels are widest), each in the view that sees the direction most centrally.
/// Returns the grid's side too, or a direction no view sees.
fn equirect_from_views(
    pool: &rayon::ThreadPool,
    frame: &Frame,
    views: &[(View, Image)],
    width: u32,
) -> Result<(Image, u32), Vec3> {
    let height = width / 2;
    let widest = widest_side(views.iter().map(|(v, _)| [v.width, v.height]));
    let k = ((8.0 * widest as f64 / width as f64).ceil() as u32).clamp(2, MAX_SAMPLES_PER_SIDE);
    let texels = parallel::map_grid(pool, width, height, |i, j| {
        let mut sum = Vec3::ZERO;
        for b in 0..k {
            for a in 0..k {
                let u = (i as f32 + (a as f32 + 0.5) / k as f32) / width as f32;
                let v = (j as f32 + (b as f32 + 0.5) / k as f32) / height as f32;
                let d = frame.direction(u, v);
                let seen = views
                    .iter()
                    .filter_map(|(view, image)| in_view(view, d).map(|p| (p, image)))
                    .max_by(|a, b| a.0 .2.total_cmp(&b.0 .2));
                match seen {
                    Some(((x, y, _), image)) => sum += texel_at(image, x, y, false),
                    None => return Err(d),
                }
            }
        }
        Ok((sum / (k * k) as f32).to_array())
    });
    let pixels = texels.into_iter().collect::<Result<Vec<_>, _>>()?;
    Ok((
        Image {
            width,
            height,
            pixels,
        },
        k,
    ))
}

#[cfg(test)]
mod tests {
    use super::super::tests::z_up;
    use super::*;
    use relume_core::math;

    /// A radiance linear in the direction, which a texel's or a pixel's footprint mean
    /// holds to within the footprint's curvature.
    fn linear_radiance(d: Vec3) -> Vec3 {
        Vec3::new(1.0 + 0.5 * d.x, 1.0 + 0.5 * d.y, 1.0 + 0.5 * d.z)
    }

    /// Views from the origin (direction, up, field of view, size) whose pixels are each
    /// the mean of [`linear_radiance`] over the pixel's footprint.
    fn views_of_linear_radiance(specs: &[(Vec3, Vec3, [f32; 2], [u32; 2])]) -> Vec<(View, Image)> {
        specs
            .iter()
            .map(|&(direction, up, fov, [w, h])| {
                let view = View::new(Vec3::ZERO, direction, up, fov, [w, h]).unwrap();
                let pixels = (0..w * h)
                    .map(|p| {
                        let (x, y) = ((p % w) as f32, (p / w) as f32);
                        let mut sum = Vec3::ZERO;
                        for b in 0..8 {
                            for a in 0..8 {
                                let d = view
                                    .ray(x + (a as f32 + 0.5) / 8.0, y + (b as f32 + 0.5) / 8.0)
                                    .direction;
                                sum += linear_radiance(d) / 64.0;
                            }
                        }
                        sum.to_array()
                    })
                    .collect();
                let image = Image {
                    width: w,
                    height: h,
                    pixels,
                };
                (view, image)
            })
            .collect()
    }

    /// How far the joined `image`'s texels are from [`linear_radiance`]'s mean over their
    /// footprints: the worst within 67.5 degrees of the horizon, and the worst nearer the
    /// poles.
    fn worst_texels(frame: &Frame, image: &Image) -> (f32, f32) {
        let (width, height) = (image.width, image.height);
        let mut worst = 0.0f32;
        let mut worst_pole = 0.0f32;
        for j in 0..height {
            for i in 0..width {
                let mut want = Vec3::ZERO;
                for b in 0..16 {
                    for a in 0..16 {
                        let u = (i as f32 + (a as f32 + 0.5) / 16.0) / width as f32;
                        let v = (j as f32 + (b as f32 + 0.5) / 16.0) / height as f32;
                        want += linear_radiance(frame.direction(u, v)) / 256.0;
                    }
                }
                let got = Vec3::from(image.pixels[(j * width + i) as usize]);
                let off = (got - want).abs().max_element();
                if (height / 8..height - height / 8).contains(&j) {
                    worst = worst.max(off);
                } else {
                    worst_pole = worst_pole.max(off);
                }
            }
        }
        (worst, worst_pole)
    }

    /// Six faces of a radiance linear in the direction (each pixel its footprint's mean),
    /// joined: each texel is the function's mean over the texel's footprint, within what
    /// the faces' pixels resolve.
    #[test]
    fn joined_faces_give_each_texel_the_mean_over_its_footprint() {
        let frame = z_up();
        let n = 32u32;
        let specs: Vec<_> = frame
            .faces()
            .iter()
            .map(|&(_, direction, up)| (direction, up, [90.0, 90.0], [n, n]))
            .collect();
        let views = views_of_linear_radiance(&specs);
        let pool = parallel::thread_pool(Some(2)).unwrap();
        let width = 32;
        let (image, k) = equirect_from_views(&pool, &frame, &views, width).unwrap();
        assert_eq!((image.width, image.height, k), (32, 16, 8));
        let (worst, worst_pole) = worst_texels(&frame, &image);
        // Within 67.5 degrees of the horizon a texel spans several face pixels (0.003 left);
        // nearer the poles it is narrower than one, and takes what a face pixel holds: at
        // most half the function's change across a face pixel, 0.5 x 0.5 x (pi / 2) / 32.
        assert!(worst < 0.005, "worst texel off by {worst}");
        assert!(
            worst_pole < 0.0123,
            "worst texel near the poles off by {worst_pole}"
        );
        // Five faces leave a hole: the direction is named.
        let hole = equirect_from_views(&pool, &frame, &views[..5], width).unwrap_err();
        assert!(hole.dot(-frame.up) > 0.5, "{hole}");
    }

    /// Views that are not a cube: a ring of six around the horizon, turned 15 degrees off
    /// the frame's forward, 70 x 100 degrees and 24 x 32 pixels each, overlapping one
    /// another and the two of 120 degrees (40 pixels) that look up and down, their up
    /// vectors turned too. Joined, the texels are the function's footprint means as from
    /// the cube.
    #[test]
    fn joined_views_of_any_layout_that_sees_every_direction_agree_with_the_function() {
        let frame = z_up();
        let mut specs: Vec<_> = (0..6)
            .map(|k| {
                let yaw = (15.0 + 60.0 * k as f32).to_radians();
                let direction = Vec3::new(math::cos(yaw), math::sin(yaw), 0.0);
                (direction, Vec3::Z, [70.0, 100.0], [24, 32])
            })
            .collect();
        let turned = Vec3::new(0.6, 0.8, 0.0);
        specs.push((Vec3::Z, turned, [120.0, 120.0], [40, 40]));
        specs.push((-Vec3::Z, -turned, [120.0, 120.0], [40, 40]));
        let views = views_of_linear_radiance(&specs);
        let pool = parallel::thread_pool(Some(2)).unwrap();
        let width = 32;
        let (image, _) = equirect_from_views(&pool, &frame, &views, width).unwrap();
        let (worst, worst_pole) = worst_texels(&frame, &image);
        // The widest pixel is at the up and down views' centres, 2 tan(60 deg) / 40 = 0.087
        // radians: half the function's change across it is 0.5 x 0.5 x 0.087 = 0.022.
        assert!(worst < 0.005, "worst texel off by {worst}");
        assert!(
            worst_pole < 0.022,
            "worst texel near the poles off by {worst_pole}"
        );
        // Without the view that looks down, the nadir is seen by none.
        let hole = equirect_from_views(&pool, &frame, &views[..7], width).unwrap_err();
        assert!(hole.dot(-frame.up) > 0.5, "{hole}");
    }
}
