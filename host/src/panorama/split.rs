//! `relume panorama split`: an equirectangular panorama into the six cube faces, each
//! face pixel its footprint's mean, with the `[[view]]` tables that place them in a scene.

use std::path::{Path, PathBuf};

use relume_core::geometry::View;
use relume_core::math::{self, Vec3};

use super::{common_position, in_view, texel_at, Frame, MAX_SAMPLES_PER_SIDE};
use crate::assemble::{self, MaterialSource};
use crate::downsample;
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::images::{self, Image};
use crate::parallel;
use crate::scene_file::ViewDesc;

/// Where the faces go under `--out`, and the views' file beside it.
pub const FACES_DIR: &str = "views";
pub const VIEWS_TOML: &str = "views.toml";

/// An equirectangular image's texels per face pixel, across, below which a face pixel's
/// mean is mostly interpolation: the faces are then finer than what the capture holds.
pub const MIN_TEXELS_PER_PIXEL: f64 = 2.0;

pub struct PanoramaArgs {
    /// The equirectangular image (.exr, .hdr or .png), twice as wide as high.
    pub image: PathBuf,
    /// Where the panorama was taken, in the scene's coordinates; `None`: where the views
    /// of `scene` all are.
    pub position: Option<[f64; 3]>,
    /// The scene direction at the image's centre column, on the horizon.
    pub forward: [f32; 3],
    /// The scene's up: the image's top edge.
    pub up: [f32; 3],
    /// Pixels per face side; `None`: a quarter of the texels per quarter turn.
    pub size: Option<u32>,
    /// A scene whose geometry, lights and groups the faces join in `<out>/scene.toml`
    /// (its own views left out).
    pub scene: Option<PathBuf>,
    pub out: PathBuf,
    pub threads: Option<usize>,
    /// Print each warning on stderr as soon as it is found, before the work (as `recover`
    /// tells its input's): a --size far past the capture's took minutes before its warning.
    pub tell_warnings: bool,
}

/// What was written.
pub struct PanoramaSummary {
    pub size: u32,
    /// Footprint samples per face pixel side.
    pub samples_per_side: u32,
    /// Every warning (already printed when `tell_warnings`).
    pub warnings: Vec<String>,
}

/// Footprint samples per face pixel side: two per equirectangular texel the pixel spans
/// at its face's centre (where a face pixel is widest), at least 2.
fn samples_per_side(width: u32, size: u32) -> u32 {
    let texels = width as f64 / (4.0 * size as f64);
    ((2.0 * texels).ceil() as u32).clamp(2, MAX_SAMPLES_PER_SIDE)
}

/// One face: each pixel the mean of `k x k` lookups on a grid over its footprint, of the
/// texels that lie wholly inside it. A texel across the footprint's edge holds what lies
/// beyond it too: beside a light, a hundred times the ceiling's radiance, which would
/// turn a pure pixel of the ceiling into a pixel of neither (the bundled scene's ceiling
/// read 4.7% bright through a round trip at four texels per face pixel). A pixel that
/// holds no whole texel (a capture coarser than the faces) takes every lookup.
fn face(pool: &rayon::ThreadPool, image: &Image, frame: &Frame, view: &View, k: u32) -> Image {
    let (w, h) = (image.width as f32, image.height as f32);
    let pixels = parallel::map_pixels(pool, view, |x, y| {
        // Whether texel (i, j)'s corners and centre fall in pixel (x, y)'s square.
        let wholly_inside = |i: f32, j: f32| {
            [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)]
                .iter()
                .all(|&(di, dj)| {
                    in_view(view, frame.direction((i + di) / w, (j + dj) / h)).is_some_and(
                        |(px, py, _)| {
                            (x as f32..=(x + 1) as f32).contains(&px)
                                && (y as f32..=(y + 1) as f32).contains(&py)
                        },
                    )
                })
        };
        let (mut inside, mut n_inside, mut all) = (Vec3::ZERO, 0u32, Vec3::ZERO);
        for b in 0..k {
            for a in 0..k {
                let sx = x as f32 + (a as f32 + 0.5) / k as f32;
                let sy = y as f32 + (b as f32 + 0.5) / k as f32;
                let (u, v) = frame.image_position(view.ray(sx, sy).direction);
                let (tx, ty) = (u * w, v * h);
                let value = texel_at(image, tx, ty, true);
                all += value;
                if wholly_inside(math::floor(tx), math::floor(ty).clamp(0.0, h - 1.0)) {
                    inside += value;
                    n_inside += 1;
                }
            }
        }
        let mean = match n_inside {
            0 => all / (k * k) as f32,
            n => inside / n as f32,
        };
        mean.to_array()
    });
    Image {
        width: view.width,
        height: view.height,
        pixels,
    }
}

/// The six faces as a scene's views, their images `<images>/<face>.exr`.
fn face_views(position: [f64; 3], frame: &Frame, size: u32, images: &Path) -> Vec<ViewDesc> {
    frame
        .faces()
        .iter()
        .map(|&(name, direction, up)| ViewDesc {
            name: name.into(),
            image: Some(images.join(format!("{name}.exr"))),
            position,
            direction: direction.to_array(),
            up: up.to_array(),
            fov_deg: [90.0, 90.0],
            size: [size, size],
            exposure: 1.0,
        })
        .collect()
}

/// Splits the panorama into `out/views/<face>.exr` and writes `out/views.toml`, all or
/// nothing.
pub fn split(args: &PanoramaArgs) -> Result<PanoramaSummary, Error> {
    let frame = Frame::new(args.forward, args.up)?;
    // The template checked as `check` would check it (its OBJ, groups and lights), less
    // its views' images, which the faces replace: else the scene written was refused only
    // when it was used.
    let template = args
        .scene
        .as_ref()
        .map(|scene| {
            let (desc, objects) = assemble::load_template(scene)?;
            assemble::assemble(desc.clone(), &objects, MaterialSource::GeometryOnly)?;
            Ok::<_, Error>((desc, objects))
        })
        .transpose()?;
    let position = match (args.position, &template) {
        (Some(p), _) if p.iter().all(|x| x.is_finite()) => p,
        (Some(_), _) => return Err(Error::Usage("--position must be finite".into())),
        (None, Some((desc, objects))) => common_position(desc, objects)?,
        (None, None) => {
            return Err(Error::Usage(
                "--position is needed: where the panorama was taken (or a --scene whose views are all there)".into(),
            ))
        }
    };
    let (image, divisor) = images::read_radiance_sized(&args.image, 1.0, |w, h| {
        // In u64: twice a header's height may pass u32.
        if u64::from(w) == 2 * u64::from(h) {
            Ok(())
        } else {
            Err(Error::input(
                &args.image,
                format!(
                    "is {w}x{h}: an equirectangular panorama is twice as wide as high (360 x 180 degrees)"
                ),
            ))
        }
    })?;
    let size = args.size.unwrap_or((image.width / 16).max(1));
    let max = relume_core::config::MAX_VIEW_SIDE;
    if size == 0 || size > max {
        return Err(Error::Usage(format!(
            "--size {size}: a face's side must be 1 to {max} pixels (config::MAX_VIEW_SIDE)"
        )));
    }
    let mut warnings: Vec<String> = frame.tilt_warning(args.forward).into_iter().collect();
    if image.pixels.iter().all(|p| *p == [0.0; 3]) {
        warnings.push(format!(
            "{}: every texel is 0{}: the faces are black",
            args.image.display(),
            images::header_note(divisor)
        ));
    }
    let texels = image.width as f64 / (4.0 * size as f64);
    if texels < MIN_TEXELS_PER_PIXEL {
        let largest = (image.width as f64 / (4.0 * MIN_TEXELS_PER_PIXEL)).floor();
        let within = if largest >= 1.0 {
            format!("a --size of {largest} or less keeps within it")
        } else {
            "the capture is too small for any face to keep within it".into()
        };
        warnings.push(format!(
            "{} holds {texels:.2} texels across a face pixel (fewer than MIN_TEXELS_PER_PIXEL {MIN_TEXELS_PER_PIXEL}): the faces are finer than the capture, and their pixels at a group's edge mix in more than their footprint; {within}",
            args.image.display()
        ));
    }
    if args.tell_warnings {
        for w in &warnings {
            eprintln!("relume: warning: {w}");
        }
    }
    let k = samples_per_side(image.width, size);
    let pool = parallel::thread_pool(args.threads)?;
    let mut inputs = vec![(args.image.clone(), "the panorama".to_string())];
    if let Some((desc, _)) = &template {
        inputs.extend(desc.input_files());
    }
    let mut set = OutputSet::keeping(inputs);
    let faces_dir = args.out.join(FACES_DIR);
    let views_toml = args.out.join(VIEWS_TOML);
    let scene_toml = args.out.join("scene.toml");
    let relative = face_views(position, &frame, size, Path::new(FACES_DIR));
    set.check_targets(
        relative
            .iter()
            .map(|v| {
                args.out
                    .join(v.image.as_ref().expect("every face has its image"))
            })
            .chain([views_toml.clone()])
            .chain(template.as_ref().map(|_| scene_toml.clone())),
    )?;
    set.create_dir(&faces_dir)?;
    for v in &relative {
        let view = v
            .view()
            .map_err(|e| Error::core(format!("face '{}'", v.name), e))?;
        let pixels = face(&pool, &image, &frame, &view, k);
        images::add_exr(
            &mut set,
            &faces_dir.join(format!("{}.exr", v.name)),
            &pixels,
        )?;
    }
    let header = format!(
        "# The six cube faces of {:?}, written by `relume panorama split`: paste these tables\n# into the scene.toml beside this file (image paths are relative to it).\n",
        args.image.display().to_string()
    );
    let tables = downsample::view_tables(&views_toml, &relative)?;
    set.add(&views_toml, format!("{header}{tables}").as_bytes())?;
    // An earlier run's scene, which this one does not write again, would be read with
    // these faces (of another size, position or frame).
    if template.is_none() && scene_toml.is_file() {
        set.remove_on_commit(&scene_toml)?;
    }
    if let Some((mut desc, _)) = template {
        // The template's own views give way to the faces; its paths and the faces' are
        // made absolute, as a derived scene's are (`bench downsample`).
        let faces_absolute =
            std::fs::canonicalize(&faces_dir).map_err(|e| Error::io(&faces_dir, e))?;
        desc.views = face_views(position, &frame, size, &faces_absolute);
        desc.geometry = desc
            .geometry
            .iter()
            .map(|g| std::fs::canonicalize(g).map_err(|e| Error::io(g, e)))
            .collect::<Result<_, _>>()?;
        set.add(&scene_toml, downsample::scene_toml(&desc)?.as_bytes())?;
    }
    set.commit()?;
    Ok(PanoramaSummary {
        size,
        samples_per_side: k,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::super::tests::z_up;
    use super::*;

    /// A panorama whose radiance is linear in the direction is split into faces whose
    /// pixels are that function's mean over their footprints, within what taking only the
    /// texels wholly inside a footprint leaves: the function's change across one texel
    /// (0.008 at most here).
    #[test]
    fn each_face_pixel_is_the_mean_over_its_footprint() {
        let (w, h) = (256u32, 128u32);
        let frame = z_up();
        let radiance = |d: Vec3| Vec3::new(1.0 + 0.5 * d.x, 1.0 + 0.5 * d.y, 1.0 + 0.5 * d.z);
        let pixels = (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| {
                let d = frame.direction((i as f32 + 0.5) / w as f32, (j as f32 + 0.5) / h as f32);
                radiance(d).to_array()
            })
            .collect();
        let image = Image {
            width: w,
            height: h,
            pixels,
        };
        let pool = parallel::thread_pool(Some(1)).unwrap();
        for (name, direction, up) in frame.faces() {
            let view = View::new(Vec3::ZERO, direction, up, [90.0, 90.0], [8, 8]).unwrap();
            let k = samples_per_side(w, 8);
            let got = face(&pool, &image, &frame, &view, k);
            // The radiance changes by at most 0.5 per radian; a texel is 2 pi / 256 across.
            let texel_change = 0.5 * 2.0 * math::PI / w as f32;
            for y in 0..8 {
                for x in 0..8 {
                    // The footprint's mean, from a finer grid over the pixel.
                    let mut want = Vec3::ZERO;
                    for b in 0..16 {
                        for a in 0..16 {
                            let d = view
                                .ray(
                                    x as f32 + (a as f32 + 0.5) / 16.0,
                                    y as f32 + (b as f32 + 0.5) / 16.0,
                                )
                                .direction;
                            want += radiance(d) / 256.0;
                        }
                    }
                    let got = Vec3::from(got.pixels[(y * 8 + x) as usize]);
                    assert!(
                        (got - want).abs().max_element() < texel_change,
                        "face {name} pixel ({x}, {y}): {got} against {want}"
                    );
                }
            }
        }
    }

    /// A light a hundred times the wall around it, captured as a camera would (each texel
    /// the mean of its own footprint, so texels on the light's edge are part light), reaches
    /// no face pixel whose footprint does not meet the light, though texels across that
    /// footprint's edge hold some of it: pure pixels beside a light stay the wall's. Every
    /// lookup's texel (not only whole ones) gave 4 of them 1.2% more than the wall.
    #[test]
    fn a_lights_texels_stay_out_of_the_pixels_beside_it() {
        let frame = z_up();
        let (w, h) = (512u32, 256u32);
        // The light: the directions within 10 degrees of straight ahead; the wall 1.
        let lit = |d: Vec3| d.dot(frame.forward) > math::cos(math::radians(10.0));
        let radiance = |d: Vec3| if lit(d) { 100.0 } else { 1.0 };
        let image = Image {
            width: w,
            height: h,
            pixels: (0..w * h)
                .map(|p| {
                    let (i, j) = ((p % w) as f32, (p / w) as f32);
                    let mean = (0..64)
                        .map(|s| {
                            let u = (i + ((s % 8) as f32 + 0.5) / 8.0) / w as f32;
                            let v = (j + ((s / 8) as f32 + 0.5) / 8.0) / h as f32;
                            radiance(frame.direction(u, v))
                        })
                        .sum::<f32>()
                        / 64.0;
                    [mean; 3]
                })
                .collect(),
        };
        let pool = parallel::thread_pool(Some(1)).unwrap();
        let view = View::new(Vec3::ZERO, frame.forward, frame.up, [90.0, 90.0], [16, 16]).unwrap();
        let got = face(&pool, &image, &frame, &view, samples_per_side(w, 16));
        let (mut wall, mut mixed) = (0, 0);
        for y in 0..16 {
            for x in 0..16 {
                // Whether the pixel's footprint meets the light, on a fine grid over it.
                let meets_light = (0..128 * 128).any(|s| {
                    let (a, b) = ((s % 128) as f32, (s / 128) as f32);
                    lit(view
                        .ray(x as f32 + (a + 0.5) / 128.0, y as f32 + (b + 0.5) / 128.0)
                        .direction)
                });
                let value = got.pixels[(y * 16 + x) as usize][0];
                if meets_light {
                    mixed += u32::from(value > 1.0 && value < 100.0);
                } else {
                    wall += 1;
                    assert_eq!(value, 1.0, "pixel ({x}, {y}) beside the light");
                }
            }
        }
        assert!(
            wall > 200 && mixed > 0,
            "{wall} wall pixels, {mixed} on the light's edge"
        );
    }

    /// A Radiance picture's header may claim any u32 height: one of 3,000,000,000 rows
    /// doubled overflowed u32 (a panic in a debug build; in a release build the width
    /// 1705032704, what twice that wraps to, passed as twice the height, and was refused
    /// only for its pixel count). It is refused for its shape, before any pixel is read.
    #[test]
    fn a_header_whose_doubled_height_overflows_is_refused_for_its_shape() {
        let dir = tempfile::tempdir().unwrap();
        let image = dir.path().join("tall.hdr");
        std::fs::write(
            &image,
            b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 3000000000 +X 1705032704\n",
        )
        .unwrap();
        let args = PanoramaArgs {
            image,
            position: Some([0.0; 3]),
            forward: [1.0, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            size: None,
            scene: None,
            out: dir.path().join("out"),
            threads: Some(1),
            tell_warnings: false,
        };
        let e = split(&args)
            .err()
            .expect("a panorama of that shape is refused");
        assert_eq!(e.exit_code(), 3, "{e}");
        let said = e.to_string();
        assert!(
            said.contains("tall.hdr: is 1705032704x3000000000: an equirectangular panorama is twice as wide as high"),
            "{said}"
        );
        assert!(!dir.path().join("out").exists());
    }

    #[test]
    fn the_footprint_takes_two_samples_per_texel_it_spans() {
        assert_eq!(samples_per_side(4096, 256), 8);
        assert_eq!(samples_per_side(1024, 256), 2);
        assert_eq!(samples_per_side(512, 256), 2);
        assert_eq!(samples_per_side(65536, 64), MAX_SAMPLES_PER_SIDE);
    }
}
