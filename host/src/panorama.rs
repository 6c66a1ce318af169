//! `relume panorama split` and `join`: an equirectangular panorama (a 360° capture, an
//! HDRI) split into the six cube faces that a scene's views are, each face pixel the mean radiance over its
//! square footprint as scene-format.md defines a pixel, with the `[[view]]` tables that
//! place them in the scene ([`split`]); and the way back, a scene's views rendered from
//! one position (a relit room, say) joined into one equirectangular image, an environment
//! map for other tools ([`join`]).
//!
//! The equirectangular convention, seen from inside as a 360° photo is: the image's centre
//! column looks along `forward`, columns run left to right as a viewer turning to the
//! right (towards `forward x up`), across the whole turn; rows run from straight up (the
//! top edge) to straight down. The faces are views of 90 x 90 degrees as `rpict -vtv`
//! renders them, so what this writes, recovery reads the right way round.

use std::path::{Path, PathBuf};

use relume_core::geometry::View;
use relume_core::math::{self, Vec3};

use crate::assemble::{self, MaterialSource};
use crate::downsample;
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::images::{self, Image};
use crate::obj::ObjObject;
use crate::parallel;
use crate::scene_file::{SceneDesc, ViewDesc};

/// Where the faces go under `--out`, and the views' file beside it.
pub const FACES_DIR: &str = "views";
pub const VIEWS_TOML: &str = "views.toml";

/// An equirectangular image's texels per face pixel, across, below which a face pixel's
/// mean is mostly interpolation: the faces are then finer than what the capture holds.
pub const MIN_TEXELS_PER_PIXEL: f64 = 2.0;

/// At most this many footprint samples per face pixel side.
const MAX_SAMPLES_PER_SIDE: u32 = 32;

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

/// The largest tilt of `--forward` off the horizon taken without a word: a vector typed
/// by hand, or read off a model, is seldom exactly level.
const MAX_FORWARD_TILT_DEG: f32 = 1.0;

/// The scene frame of the panorama: `forward` on the horizon, `right = forward x up`.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
}

/// `v` (finite, non-zero) scaled by a power of two so that its largest component lies in
/// [1, 2): exactly, so a vector already there keeps its bits and its normalised value.
/// A tiny one (`1e-30,0,1e-30`) has a squared length below f32's range, and was called
/// zero or parallel.
fn to_unit_range(v: Vec3) -> Vec3 {
    // In f64 every f32 is normal: its exponent field is floor(log2), and 2^-exponent is
    // built from its bits.
    let largest = f64::from(v.abs().max_element());
    let exponent = ((largest.to_bits() >> 52) & 0x7ff) as i64 - 1023;
    let scale = f64::from_bits(((1023 - exponent) as u64) << 52);
    let exact = |c: f32| (f64::from(c) * scale) as f32;
    Vec3::new(exact(v.x), exact(v.y), exact(v.z))
}

impl Frame {
    /// `up` as given (normalised) and `forward` made perpendicular to it; a zero, non-finite
    /// or parallel pair is a usage error.
    pub fn new(forward: [f32; 3], up: [f32; 3]) -> Result<Frame, Error> {
        let (f, u) = (Vec3::from(forward), Vec3::from(up));
        if !(math::is_finite(f) && math::is_finite(u)) {
            return Err(Error::Usage(
                "--forward and --up must be finite vectors".into(),
            ));
        }
        for (v, name, given) in [(f, "--forward", forward), (u, "--up", up)] {
            if v == Vec3::ZERO {
                return Err(Error::Usage(format!("{name} {given:?} must not be zero")));
            }
        }
        let u = to_unit_range(u).normalize_or_zero();
        let f = to_unit_range(f);
        let f = (f - u * f.dot(u)).normalize_or_zero();
        if u == Vec3::ZERO || f == Vec3::ZERO {
            return Err(Error::Usage(format!(
                "--forward {forward:?} and --up {up:?} must not be parallel"
            )));
        }
        Ok(Frame {
            forward: f,
            right: f.cross(u),
            up: u,
        })
    }

    /// Where `--forward` (as given) leaves the horizon by more than
    /// `MAX_FORWARD_TILT_DEG`: the panorama's centre column is taken on the horizon, which
    /// a tilted `--forward` does not say (1,0,1 with up 0,0,1 gave a front face along x).
    pub fn tilt_warning(&self, forward: [f32; 3]) -> Option<String> {
        let given = to_unit_range(Vec3::from(forward)).normalize_or_zero();
        let tilt = given.dot(self.up).clamp(-1.0, 1.0).asin().to_degrees();
        (tilt.abs() > MAX_FORWARD_TILT_DEG).then(|| {
            let f = self.forward;
            format!(
                "--forward {forward:?} is {:.1} degrees off the horizon of --up: the panorama's centre column looks along the horizon, [{:.3}, {:.3}, {:.3}], which the front face's direction follows",
                tilt, f.x, f.y, f.z
            )
        })
    }

    /// The six faces: name, view direction, view up (the top of the face's image).
    pub fn faces(&self) -> [(&'static str, Vec3, Vec3); 6] {
        let (f, r, u) = (self.forward, self.right, self.up);
        [
            ("front", f, u),
            ("right", r, u),
            ("back", -f, u),
            ("left", -r, u),
            ("up", u, -f),
            ("down", -u, f),
        ]
    }

    /// The unit direction at `(u, v)` of the equirectangular image (the inverse of
    /// [`Frame::image_position`]).
    pub fn direction(&self, u: f32, v: f32) -> Vec3 {
        let azimuth = (u - 0.5) * 2.0 * math::PI;
        let elevation = (0.5 - v) * math::PI;
        (self.forward * math::cos(azimuth) + self.right * math::sin(azimuth)) * math::cos(elevation)
            + self.up * math::sin(elevation)
    }

    /// A unit direction's position in the equirectangular image, both in [0, 1]: `u` from
    /// the left edge, `v` from the top.
    pub fn image_position(&self, d: Vec3) -> (f32, f32) {
        let (x, y, z) = (d.dot(self.forward), d.dot(self.right), d.dot(self.up));
        let azimuth = math::atan2(y, x);
        let elevation = math::atan2(z, math::sqrt(x * x + y * y));
        (0.5 + azimuth / (2.0 * math::PI), 0.5 - elevation / math::PI)
    }
}

/// `image`'s radiance at pixel position `(x, y)` (pixel units, as [`View::ray`] takes
/// them): the texel there, the image taken as constant over each texel, as a camera's
/// pixel is its footprint's mean. Columns wrap around where `wrap` (an equirectangular
/// image's turn) and are clamped otherwise; rows are clamped (at a view's edge, at the
/// poles). Bilinear lookups were tried and dropped: they spread each texel over its
/// neighbours, and a light's texels, a hundred times the ceiling around them, into the
/// pure pixels beside it (the bundled scene's ceiling read 18% bright through a round trip).
fn texel_at(image: &Image, x: f32, y: f32, wrap: bool) -> Vec3 {
    let (w, h) = (image.width as i64, image.height as i64);
    let (i, j) = (math::floor(x) as i64, math::floor(y) as i64);
    let i = if wrap {
        i.rem_euclid(w)
    } else {
        i.clamp(0, w - 1)
    };
    Vec3::from(image.pixels[(j.clamp(0, h - 1) * w + i) as usize])
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

/// Where direction `d` falls in `view`'s image, in pixel units (as [`View::ray`] takes
/// them), and how central it is there (its cosine to the view's direction); `None` outside
/// the view.
fn in_view(view: &View, d: Vec3) -> Option<(f32, f32, f32)> {
    let along = d.dot(view.forward);
    // (NaN falls out here too.)
    if along.is_nan() || along <= 0.0 {
        return None;
    }
    let sx = d.dot(view.right_span) / (along * view.right_span.length_squared());
    let sy = d.dot(view.up_span) / (along * view.up_span.length_squared());
    let inside = |s: f32| (-0.5..=0.5).contains(&s);
    (inside(sx) && inside(sy)).then_some((
        (sx + 0.5) * view.width as f32,
        (0.5 - sy) * view.height as f32,
        along,
    ))
}

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

/// Where every view of `desc` is, as a panorama's views are: an error naming two views
/// apart (or a scene with none).
fn common_position(desc: &SceneDesc, objects: &[ObjObject]) -> Result<[f64; 3], Error> {
    let Some(first) = desc.views.first() else {
        return Err(Error::input(
            &desc.path,
            "has no view to take the panorama's position from: give --position",
        ));
    };
    let size = geometry_size(objects);
    match desc
        .views
        .iter()
        .find(|v| apart(v.position, first.position, size))
    {
        Some(v) => Err(Error::input(
            &desc.path,
            format!(
                "view '{}' is at {:?} and view '{}' at {:?}: a panorama is seen from one position",
                v.name, v.position, first.name, first.position
            ),
        )),
        None => Ok(first.position),
    }
}

/// The longest side of the objects' bounding box, in their files' 64-bit coordinates (0
/// without a vertex).
fn geometry_size(objects: &[ObjObject]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in objects.iter().flat_map(|o| o.triangles.iter().flatten()) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)
}

/// Whether two view positions are apart by more than rounding: by 1e-5 of the scene's
/// `size`, in whatever unit and wherever the scene is (positions are read in 64 bits). Of
/// their distance from the origin, as it was, views 2.7 units apart in a room 3 across
/// 270 km from its origin were one position. A scene of no size falls back to that.
fn apart(a: [f64; 3], b: [f64; 3], size: f64) -> bool {
    let length = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let scale = match size.is_finite() && size > 0.0 {
        true => size,
        false => length(a).max(length(b)),
    };
    length(std::array::from_fn(|k| a[k] - b[k])) > 1e-5 * scale
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
        if w == 2 * h {
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
    use super::*;

    fn z_up() -> Frame {
        Frame::new([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]).unwrap()
    }

    /// Views a thousandth of a unit apart in a scene a few units across are apart, and so
    /// they are in the same scene scaled by 1e-3 or 1e3; rounding is not.
    #[test]
    fn view_positions_are_apart_relative_to_their_size() {
        for scale in [1e-3f64, 1.0, 1e3] {
            let p = [1.5 * scale, 0.9 * scale, 1.3 * scale];
            let moved = |d: f64| [p[0] + d * scale, p[1], p[2]];
            assert!(apart(p, moved(1e-3), 3.0 * scale), "{scale}");
            assert!(!apart(p, moved(1e-7), 3.0 * scale), "{scale}");
        }
        assert!(!apart([0.0; 3], [0.0; 3], 3.0));
        // A scene of no size: relative to the positions, as if they were its size.
        assert!(apart([0.0; 3], [1e-6, 0.0, 0.0], 0.0));
        assert!(!apart([1.0, 0.0, 0.0], [1.0 + 1e-7, 0.0, 0.0], 0.0));
        // A room 3 across, 270 km from its origin: a unit apart is apart.
        let far = [100_001.5, -249_999.1, 30_001.3];
        assert!(apart(far, [far[0] - 1.0, far[1], far[2]], 3.0));
        assert!(!apart(far, [far[0] + 1e-6, far[1], far[2]], 3.0));
    }

    /// A `--forward` off the horizon is projected onto it, and said so past a degree.
    #[test]
    fn a_forward_off_the_horizon_is_told_of() {
        let up = [0.0, 0.0, 1.0];
        let tilted = Frame::new([1.0, 0.0, 1.0], up).unwrap();
        assert_eq!(tilted.forward, Vec3::X);
        let said = tilted.tilt_warning([1.0, 0.0, 1.0]).unwrap();
        assert!(
            said.contains("--forward [1.0, 0.0, 1.0] is 45.0 degrees off the horizon")
                && said.contains("[1.000, 0.000, 0.000]"),
            "{said}"
        );
        let level = [1.0, 0.0, 0.01];
        assert_eq!(Frame::new(level, up).unwrap().tilt_warning(level), None);
    }

    #[test]
    fn the_centre_column_looks_forward_and_the_image_turns_to_the_right() {
        let f = z_up();
        let at = |d: [f32; 3]| f.image_position(Vec3::from(d).normalize());
        let close = |(u, v): (f32, f32), (eu, ev): (f32, f32)| {
            assert!((u - eu).abs() < 1e-6 && (v - ev).abs() < 1e-6, "{u} {v}");
        };
        close(at([1.0, 0.0, 0.0]), (0.5, 0.5));
        // Z up, forward +X: the right is -Y, a quarter turn to the right of the centre.
        assert_eq!(f.right, Vec3::new(0.0, -1.0, 0.0));
        close(at([0.0, -1.0, 0.0]), (0.75, 0.5));
        close(at([0.0, 1.0, 0.0]), (0.25, 0.5));
        close(at([0.0, 0.0, 1.0]), (0.5, 0.0));
        close(at([0.0, 0.0, -1.0]), (0.5, 1.0));
        close(at([1.0, 0.0, 1.0]), (0.5, 0.25));
        // Behind: either edge of the turn.
        let (u, v) = at([-1.0, 1e-7, 0.0]);
        assert!((u.min(1.0 - u)) < 1e-6 && (v - 0.5).abs() < 1e-6, "{u}");
    }

    #[test]
    fn a_forward_off_the_horizon_is_levelled_and_a_parallel_pair_refused() {
        let f = Frame::new([1.0, 0.0, 0.5], [0.0, 0.0, 2.0]).unwrap();
        assert!((f.forward - Vec3::X).length() < 1e-6 && (f.up - Vec3::Z).length() < 1e-6);
        for (forward, up) in [
            ([0.0, 0.0, 1.0], [0.0, 0.0, 1.0]),
            ([1.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
            ([f32::NAN, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ] {
            assert!(matches!(Frame::new(forward, up), Err(Error::Usage(_))));
        }
        // Tiny and huge vectors are directions like any other: their squared lengths
        // leave f32's range, which made a valid pair read "parallel or zero".
        for (forward, up) in [
            ([1e-30, 0.0, 1e-30], [1e-30, 1e-30, 1e-30]),
            ([1e30, 0.0, 0.0], [0.0, 0.0, 3e38]),
            ([f32::from_bits(1), 0.0, 0.0], [0.0, 0.0, 1.0]),
        ] {
            let f = Frame::new(forward, up).unwrap();
            assert!((f.up.length() - 1.0).abs() < 1e-6 && f.forward.dot(f.up).abs() < 1e-6);
        }
        let f = Frame::new([1e-30, 0.0, 0.0], [0.0, 0.0, 1e-30]).unwrap();
        assert_eq!((f.forward, f.up), (Vec3::X, Vec3::Z));
        // The scaling is exact: a pair already of unit size keeps its bits.
        let (forward, up) = ([0.3f32, -0.7, 0.2], [0.1f32, 0.2, 0.9]);
        let (plain_u, f) = (Vec3::from(up).normalize_or_zero(), Vec3::from(forward));
        let plain_f = (f - plain_u * f.dot(plain_u)).normalize_or_zero();
        let frame = Frame::new(forward, up).unwrap();
        assert_eq!((frame.forward, frame.up), (plain_f, plain_u));
    }

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

    #[test]
    fn the_footprint_takes_two_samples_per_texel_it_spans() {
        assert_eq!(samples_per_side(4096, 256), 8);
        assert_eq!(samples_per_side(1024, 256), 2);
        assert_eq!(samples_per_side(512, 256), 2);
        assert_eq!(samples_per_side(65536, 64), MAX_SAMPLES_PER_SIDE);
    }
}
