//! `relume compare`: how far a rendering is from a reference, group by group, and how far
//! recovered materials are from the truth. These are the user's yardsticks (and ours).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use relume_core::geometry::Surface;
use relume_core::material::texture::{TextureGrid, Wrap};
use relume_core::material::Kind;
use relume_core::math::{luminance, Vec3};
use relume_core::render;
use serde::Serialize;

use crate::assemble::{self, MaterialSource};
use crate::error::Error;
use crate::fsutil::{self, OutputSet};
use crate::images::{self, Image};
use crate::materials_file::{self, MaterialDesc, MaterialsDesc, Model};
use crate::parallel;
use crate::scene_file::{self, SceneDesc, ViewDesc};
use crate::text::counted;

/// Sub-rays per pixel side used to decide that a pixel's whole footprint sees one group.
pub const LABEL_RAYS_PER_SIDE: u32 = 4;

/// Running sums over pixels (per-channel values pooled).
#[derive(Default, Clone, Copy)]
struct Sums {
    pixels: u64,
    sum_a: f64,
    sum_b: f64,
    /// `sum B2`, with an independent render B2; `None` without one.
    sum_b2: Option<f64>,
    sum_sq_diff: f64,
    /// `sum (B - A).(B2 - A)` over the pixels, with `B2` an independent render of B's
    /// materials; `None` without one.
    sum_cross: Option<f64>,
}

impl Sums {
    /// Adds one pixel of A and B, and of B2 when the comparison has one (for every pixel
    /// or for none).
    fn add(&mut self, a: [f32; 3], b: [f32; 3], b2: Option<[f32; 3]>) {
        self.pixels += 1;
        for c in 0..3 {
            let (a, b) = (a[c] as f64, b[c] as f64);
            self.sum_a += a;
            self.sum_b += b;
            self.sum_sq_diff += (b - a) * (b - a);
            if let Some(b2) = b2 {
                let b2 = b2[c] as f64;
                *self.sum_b2.get_or_insert(0.0) += b2;
                *self.sum_cross.get_or_insert(0.0) += (b - a) * (b2 - a);
            }
        }
    }

    /// The row named `name`; `what` names it for a reader ("group 'floor' (views px,
    /// nx)") where its relative figures mean nothing: no pixel, or a reference of 0 over
    /// them, which divided by 0 and printed `NaN%`.
    fn row(&self, name: &str, what: &str) -> ViewsRow {
        let n = (self.pixels * 3).max(1) as f64;
        let mean_a = self.sum_a / n;
        let mean_b = self.sum_b / n;
        let undefined = if self.pixels == 0 {
            Some(format!("{what}: no pure pixel, nothing to compare"))
        } else if mean_a > 0.0 {
            None
        } else {
            Some(format!(
                "{what}: the reference (A) is 0 over its {}: no difference relative to it",
                counted(self.pixels, "pure pixel")
            ))
        };
        let relative = |v: f64| if undefined.is_none() { v } else { f64::NAN };
        ViewsRow {
            name: name.to_string(),
            pixels: self.pixels,
            mean_a,
            mean_b,
            rel_mean_diff: relative((mean_b - mean_a) / mean_a),
            rel_rms: relative((self.sum_sq_diff / n).sqrt() / mean_a),
            rel_misfit: self.sum_cross.map(|cross| {
                let mean = cross / n;
                relative(mean.abs().sqrt().copysign(mean) / mean_a)
            }),
            rel_mean_bias: self.sum_b2.map(|sum_b2| {
                let (d, d2) = (mean_b - mean_a, sum_b2 / n - mean_a);
                let agreed = if d * d2 > 0.0 {
                    (d * d2).sqrt().copysign(d)
                } else {
                    0.0
                };
                relative(agreed / mean_a)
            }),
            undefined,
        }
    }
}

/// One line of the views table: `rel_mean_diff = (mean B - mean A) / mean A`,
/// `rel_rms = RMS(B - A) / mean A` (the reference READMEs' definitions). The relative
/// figures are NaN (`null` in JSON, `-` in the table) where they mean nothing, and
/// `undefined` says why.
#[derive(Serialize, Clone, Debug)]
pub struct ViewsRow {
    pub name: String,
    pub pixels: u64,
    pub mean_a: f64,
    pub mean_b: f64,
    #[serde(serialize_with = "finite_or_null")]
    pub rel_mean_diff: f64,
    #[serde(serialize_with = "finite_or_null")]
    pub rel_rms: f64,
    /// With an independent render B2 of B's materials (`--independent`): the relative RMS
    /// with the render noise taken out, `sqrt(mean (B - A).(B2 - A)) / mean A`, since the
    /// two renders' noises do not multiply to anything on average. What is left is B's
    /// misfit and A's own noise. Negative (the root of the magnitude, signed) where the two
    /// renders err in opposite directions more than together: a misfit under the renders'
    /// noise. Absent without B2, and on a row with no pixel.
    #[serde(
        skip_serializing_if = "Option::is_none",
        serialize_with = "finite_or_null_option"
    )]
    pub rel_misfit: Option<f64>,
    /// With B2: the relative difference of the means with the render noise taken out,
    /// `sqrt((mean B - mean A) (mean B2 - mean A)) / mean A` with their common sign, or 0
    /// where the two renders' means fall on opposite sides of A's (the difference is under
    /// their noise). A 20-pixel group's mean carries a few percent of render noise at
    /// 1024 spp, which `rel_mean_diff` adds to its bias. Not where the noise has a heavy
    /// tail (a sharp metal's rare bright paths): both renders of a pair then read low, and
    /// so does this. Absent without B2.
    #[serde(
        skip_serializing_if = "Option::is_none",
        serialize_with = "finite_or_null_option"
    )]
    pub rel_mean_bias: Option<f64>,
    /// Why the relative figures are undefined (no pure pixel, or a reference of 0 over
    /// them); absent when they are defined.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub undefined: Option<String>,
}

/// A number as JSON, `null` when it is not finite: serde_json would write `null` for NaN
/// anyway; said here so that a reader of the code sees it.
fn finite_or_null<S: serde::Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    if v.is_finite() {
        s.serialize_f64(*v)
    } else {
        s.serialize_none()
    }
}

/// [`finite_or_null`] for a figure that may be absent (then skipped, not serialized).
fn finite_or_null_option<S: serde::Serializer>(v: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
    finite_or_null(&v.unwrap_or(f64::NAN), s)
}

#[derive(Serialize, Clone, Debug)]
pub struct ViewsReport {
    pub groups: Vec<ViewsRow>,
    pub views: Vec<ViewsRow>,
    pub all: ViewsRow,
}

/// Where a set of view images comes from.
#[derive(Clone, Copy, Debug)]
pub enum ViewImages<'a> {
    /// `<folder>/<view>.exr`, as `relume render` writes them (exposure 1); the scene's own
    /// image of a view with the view's exposure.
    Folder(&'a Path),
    /// The images the scene file names for its views (the panorama), with their exposure.
    Scene,
}

impl ViewImages<'_> {
    /// Where the images are, for an error about all of them: the folder, or the scene
    /// file that names them.
    fn origin(&self, scene_path: &Path) -> PathBuf {
        match self {
            ViewImages::Folder(dir) => dir.to_path_buf(),
            ViewImages::Scene => scene_path.to_path_buf(),
        }
    }

    /// The image of view `desc` of the scene at `scene_path`, checked as every view is.
    pub(crate) fn read(&self, desc: &ViewDesc, scene_path: &Path) -> Result<images::Image, Error> {
        match self {
            ViewImages::Folder(dir) => images::read_folder_view_image(dir, desc),
            ViewImages::Scene => {
                let path = desc.image.as_ref().ok_or_else(|| {
                    Error::input(scene_path, format!("view '{}' names no image", desc.name))
                })?;
                images::read_view_image(path, desc, desc.exposure)
            }
        }
    }
}

/// Compares `dir_a/<view>.exr` with `dir_b/<view>.exr` for the views of the scene named
/// in `views` (every view when it is empty) over pure pixels (whole footprint on one
/// group; lights and silhouettes left out). With `dir_b2` (an independent render of B's
/// materials, on another seed), each row also has its misfit with the render noise taken
/// out (`ViewsRow::rel_misfit`).
pub fn views_report(
    scene_path: &Path,
    dir_a: &Path,
    dir_b: &Path,
    dir_b2: Option<&Path>,
    views: &[String],
    threads: Option<usize>,
) -> Result<ViewsReport, Error> {
    views_report_of(
        scene_path,
        ViewImages::Folder(dir_a),
        ViewImages::Folder(dir_b),
        dir_b2.map(ViewImages::Folder),
        views,
        threads,
    )
}

/// [`views_report`] for images from anywhere: A is the reference.
pub fn views_report_of(
    scene_path: &Path,
    a: ViewImages<'_>,
    b: ViewImages<'_>,
    b2: Option<ViewImages<'_>>,
    selected: &[String],
    threads: Option<usize>,
) -> Result<ViewsReport, Error> {
    let mut owned = assemble::load_and_assemble(scene_path, MaterialSource::GeometryOnly)?;
    owned.select_views(selected)?;
    let pool = parallel::thread_pool(threads)?;
    let descs = owned.desc.views.clone();
    let views = owned.views.clone();
    let group_names = owned.group_names.clone();
    let scene = owned.build()?;

    let mut groups = vec![Sums::default(); group_names.len()];
    // The views each group has pure pixels in, to name them where its figures are undefined.
    let mut seen_in: Vec<Vec<&str>> = vec![Vec::new(); group_names.len()];
    let mut per_view = Vec::new();
    let mut all = Sums::default();
    for (desc, view) in descs
        .iter()
        .zip(&views)
        .filter(|(d, _)| SceneDesc::view_selected(selected, &d.name))
    {
        let a = a.read(desc, scene_path)?;
        let b = b.read(desc, scene_path)?;
        let b2 = b2.map(|b2| b2.read(desc, scene_path)).transpose()?;
        let labels = parallel::map_pixels(&pool, view, |x, y| {
            render::pixel_surface(&scene, view, x, y, LABEL_RAYS_PER_SIDE)
        });
        let mut sums = Sums::default();
        for (i, label) in labels.iter().enumerate() {
            if let Some(Surface::Group(g)) = label {
                let g = *g as usize;
                let (a, b, b2) = (a.pixels[i], b.pixels[i], b2.as_ref().map(|b2| b2.pixels[i]));
                groups[g].add(a, b, b2);
                sums.add(a, b, b2);
                all.add(a, b, b2);
                if seen_in[g].last() != Some(&desc.name.as_str()) {
                    seen_in[g].push(&desc.name);
                }
            }
        }
        per_view.push(sums.row(&desc.name, &format!("view '{}'", desc.name)));
    }
    // Nothing at all to compare is an error, not a table of undefined figures.
    let all = all.row("image", "every view");
    if all.pixels == 0 {
        return Err(Error::input(
            scene_path,
            "no pixel of any view sees one group over its whole footprint: nothing to compare",
        ));
    }
    if all.undefined.is_some() {
        return Err(Error::input(
            a.origin(scene_path),
            format!(
                "the reference (A) is 0 over all {} pure pixels of the views: no difference can be given relative to it",
                all.pixels
            ),
        ));
    }
    let groups = groups
        .iter()
        .zip(&group_names)
        .zip(&seen_in)
        .map(|((s, name), views)| {
            let what = match views.as_slice() {
                [] => format!("group '{name}'"),
                views => format!("group '{name}' (in views {})", views.join(", ")),
            };
            s.row(name, &what)
        })
        .collect();
    Ok(ViewsReport {
        groups,
        views: per_view,
        all,
    })
}

impl ViewsReport {
    /// Why some rows have no relative figures, one line per row (groups, then views).
    pub fn undefined(&self) -> Vec<&str> {
        self.groups
            .iter()
            .chain(&self.views)
            .filter_map(|r| r.undefined.as_deref())
            .collect()
    }
}

/// The table, with `-` for the relative figures a row does not have and a note under it
/// for each such row, saying why.
fn print_views_table(report: &ViewsReport) {
    let with_misfit = report.all.rel_misfit.is_some();
    println!(
        "{:<16} {:>8} {:>11} {:>11} {:>10} {:>9}{}",
        "group",
        "pixels",
        "mean A",
        "mean B",
        "rel mean",
        "rel RMS",
        if with_misfit {
            "    misfit  mean bias"
        } else {
            ""
        }
    );
    let percent = |v: f64, sign: bool| match (v.is_finite(), sign) {
        (false, _) => "-".to_string(),
        (true, true) => format!("{:+.2}%", 100.0 * v),
        (true, false) => format!("{:.2}%", 100.0 * v),
    };
    let line = |r: &ViewsRow| {
        println!(
            "{:<16} {:>8} {:>11.5} {:>11.5} {:>10} {:>9}{}",
            r.name,
            r.pixels,
            r.mean_a,
            r.mean_b,
            percent(r.rel_mean_diff, true),
            percent(r.rel_rms, false),
            // A row with no pixel has no B2 sums either: `-`, as for its RMS.
            if with_misfit {
                format!(
                    " {:>9} {:>10}",
                    percent(r.rel_misfit.unwrap_or(f64::NAN), true),
                    percent(r.rel_mean_bias.unwrap_or(f64::NAN), true)
                )
            } else {
                String::new()
            }
        )
    };
    report.groups.iter().for_each(line);
    println!("{:<16}", "-- views");
    report.views.iter().for_each(line);
    line(&report.all);
    for note in report.undefined() {
        println!("note: {note}");
    }
}

/// `relume compare views`: the table (with a misfit column given `dir_b2`, an independent
/// render of B's materials), and `json` if given. The JSON may replace none of the run's
/// inputs (the scene's files, the images compared), checked before the work.
pub fn compare_views(
    scene: &Path,
    dir_a: &Path,
    dir_b: &Path,
    dir_b2: Option<&Path>,
    views: &[String],
    json: Option<&Path>,
    threads: Option<usize>,
) -> Result<(), Error> {
    // A render compared with itself reads 0 on every row, which looks like a perfect fit.
    if fsutil::same_file(dir_a, dir_b) {
        return Err(Error::Usage(format!(
            "A and B are the same folder ({}): the comparison would read 0 everywhere; give the reference images as A and the render to judge as B",
            dir_b.display()
        )));
    }
    // B's own render as its independent one would give its whole RMS as the misfit, and
    // A's a misfit of exactly 0 on every row.
    for (other, whose) in [(dir_b, "B's"), (dir_a, "A's, the reference")] {
        if let Some(dir_b2) = dir_b2.filter(|b2| fsutil::same_file(b2, other)) {
            return Err(Error::Usage(format!(
                "--independent {} is {whose} folder: the misfit needs a render of B's materials on another seed",
                dir_b2.display()
            )));
        }
    }
    let desc = scene_file::load_scene(scene)?;
    let mut inputs = desc.input_files();
    for v in desc
        .views
        .iter()
        .filter(|v| SceneDesc::view_selected(views, &v.name))
    {
        let image = format!("{}.exr", v.name);
        // As for the folders, image by image: one linked into both read 0 on its rows.
        let (a, b) = (dir_a.join(&image), dir_b.join(&image));
        if fsutil::same_file(&a, &b) {
            return Err(Error::Usage(format!(
                "{} and {} are one file: view '{}' would read 0 everywhere; give the reference images as A and the render to judge as B",
                a.display(),
                b.display(),
                v.name
            )));
        }
        for (other, whose) in [(&b, "B's"), (&a, "A's, the reference")] {
            if let Some(b2) = dir_b2
                .map(|d| d.join(&image))
                .filter(|b2| fsutil::same_file(b2, other))
            {
                return Err(Error::Usage(format!(
                    "--independent's image of view '{}', {}, is {whose} ({}): the misfit needs a render of B's materials on another seed",
                    v.name,
                    b2.display(),
                    other.display()
                )));
            }
        }
        // Two renders on one seed are the same bytes, and their "independent" noise is one.
        if let Some(b2) = dir_b2.map(|d| d.join(&image)) {
            if let (Ok(x), Ok(y)) = (std::fs::read(&b), std::fs::read(&b2)) {
                if x == y {
                    eprintln!(
                        "relume: warning: view '{}': {} holds the same bytes as {}: renders on one seed are identical, and the misfit of such a pair is their whole RMS; render B2 with another --seed",
                        v.name,
                        b2.display(),
                        b.display()
                    );
                }
            }
        }
        inputs.push((
            dir_a.join(&image),
            format!("the reference image of view '{}' (A)", v.name),
        ));
        inputs.push((
            dir_b.join(&image),
            format!("the compared image of view '{}' (B)", v.name),
        ));
        if let Some(dir_b2) = dir_b2 {
            inputs.push((
                dir_b2.join(&image),
                format!("the independent image of view '{}' (B2)", v.name),
            ));
        }
    }
    let mut set = OutputSet::keeping(inputs);
    if let Some(path) = json {
        set.check_target(path)?;
    }
    let report = views_report(scene, dir_a, dir_b, dir_b2, views, threads)?;
    print_views_table(&report);
    if let Some(path) = json {
        let text =
            serde_json::to_string_pretty(&report).map_err(|e| Error::Usage(e.to_string()))?;
        set.add(path, text.as_bytes())?;
    }
    set.commit()
}

/// Errors of one recovered material against the truth; `None` where the parameter does not
/// apply to both.
#[derive(Serialize, Debug, Default)]
pub struct MaterialRow {
    pub group: String,
    pub true_model: String,
    pub model: Option<String>,
    pub class_ok: bool,
    /// Mean over channels of |rho_d - rho_d true| / rho_d true, with rho_d = color (1 - s).
    pub diffuse_rel_err: Option<f64>,
    pub specularity_rel_err: Option<f64>,
    pub roughness_rel_err: Option<f64>,
    pub roughness_u_rel_err: Option<f64>,
    pub roughness_v_rel_err: Option<f64>,
    /// Angle between the u directions, sign ignored (d and -d are the same material).
    pub direction_err_deg: Option<f64>,
    /// PSNR of the diffuse map over all texels, peak = the truth's maximum. Infinite for a
    /// map equal to the truth's, written `"inf"` in JSON.
    #[serde(serialize_with = "psnr_json")]
    pub diffuse_map_psnr_db: Option<f64>,
    /// The same PSNR for the truth area-averaged to the recovered map's size: the most a
    /// map of that resolution can reach.
    #[serde(serialize_with = "psnr_json")]
    pub diffuse_map_psnr_ceiling_db: Option<f64>,
    /// The recovered map's mean luminance over the truth's, less 1 (signed): its level,
    /// which the panorama sees only through the lobe beside it (a lobe sending too much
    /// light towards the views leaves its map too dark; docs/edits.md).
    pub diffuse_map_level_err: Option<f64>,
    /// With `--scene`, where both models have a lobe: the kind of the recovered lobe (its
    /// material's `kind`, written for a group of kind "auto", else the scene's) and the
    /// truth's (the scene's).
    pub kind: Option<String>,
    pub true_kind: Option<String>,
    /// With `--scene`, where both models have a lobe: mean over channels of
    /// |S - S true| / S true, with S = s for plastic and c s for metal (reflectance.md).
    /// Where the kinds differ, `specularity` means different things on the two sides; this
    /// compares the light the lobes reflect.
    pub specular_reflectance_rel_err: Option<f64>,
}

/// A PSNR in JSON: a number, `"inf"` for a map equal to the truth's (JSON has no
/// infinity, and serde_json would write `null`, which here means "no map"), `"-inf"` for
/// a map that is not black against a black truth (a peak of 0; the table's `-infdB`),
/// `null` when there is no map to compare.
fn psnr_json<S: serde::Serializer>(psnr: &Option<f64>, out: S) -> Result<S::Ok, S::Error> {
    match psnr {
        Some(db) if db.is_infinite() && *db > 0.0 => out.serialize_str("inf"),
        Some(db) if db.is_infinite() => out.serialize_str("-inf"),
        Some(db) => out.serialize_f64(*db),
        None => out.serialize_none(),
    }
}

fn rel(a: f64, truth: f64) -> f64 {
    if truth != 0.0 {
        (a - truth).abs() / truth.abs()
    } else {
        a.abs()
    }
}

fn diffuse_of(m: &MaterialDesc) -> Option<[f64; 3]> {
    let c = m.color?;
    let s = m.specularity.unwrap_or(0.0) as f64;
    match m.model {
        Model::Mirror => None,
        _ => Some(c.map(|c| c as f64 * (1.0 - s))),
    }
}

/// The specular reflectance S of a lobe of `kind` (reflectance.md): s, white, for
/// plastic; c s for metal. `None` without a specularity or, for metal, a colour.
fn specular_reflectance_of(m: &MaterialDesc, kind: Kind) -> Option<[f64; 3]> {
    let s = m.specularity? as f64;
    match kind {
        Kind::Plastic => Some([s; 3]),
        Kind::Metal => Some(m.color?.map(|c| c as f64 * s)),
    }
}

/// PSNR of a recovered map against the truth's, peak = the truth's maximum. The recovered
/// map may have another size: it is sampled as the renderer samples it (bilinear between
/// texel centres, clamped) at the truth's texel centres; at the truth's own size that is
/// its texels, taken as they are (the centres in f32 are not exact at every size, and a
/// map equal to the truth's read 130-136 dB rather than infinite). `None` for an empty
/// image.
fn map_psnr(truth: &Image, recovered: &Image, wrap: Wrap) -> Option<f64> {
    let (t, r) = (truth, recovered);
    if t.pixels.is_empty() || r.pixels.is_empty() {
        return None;
    }
    let same_size = (r.width, r.height) == (t.width, t.height);
    let sample = |i: u32, j: u32, u: f32, v: f32| {
        if same_size {
            return r.pixels[(j * r.width + i) as usize].map(f64::from);
        }
        let grid = TextureGrid {
            width: r.width,
            height: r.height,
            wrap,
        };
        grid.taps(glam::Vec2::new(u, v))
            .iter()
            .fold([0.0f64; 3], |mut sum, &(k, a)| {
                for (s, c) in sum.iter_mut().zip(r.pixels[k]) {
                    *s += a as f64 * c as f64;
                }
                sum
            })
    };
    let peak = t
        .pixels
        .iter()
        .flatten()
        .fold(0.0f64, |m, &v| m.max(v as f64));
    let mut sum_sq = 0.0f64;
    for j in 0..t.height {
        for i in 0..t.width {
            let u = (i as f32 + 0.5) / t.width as f32;
            let v = 1.0 - (j as f32 + 0.5) / t.height as f32;
            let ours = sample(i, j, u, v);
            let theirs = t.pixels[(j * t.width + i) as usize];
            sum_sq += (0..3)
                .map(|c| {
                    let d = ours[c] - theirs[c] as f64;
                    d * d
                })
                .sum::<f64>();
        }
    }
    let mse = sum_sq / (3 * t.pixels.len()) as f64;
    Some(if mse > 0.0 {
        10.0 * libm::log10(peak * peak / mse)
    } else {
        f64::INFINITY
    })
}

/// For each of `to` cells over `from` texels: the texels it covers and the fraction of
/// each it covers, normalised to sum to one (area averaging along one axis).
fn area_weights(from: u32, to: u32) -> Vec<Vec<(usize, f64)>> {
    let scale = from as f64 / to as f64;
    (0..to)
        .map(|i| {
            let (a, b) = (i as f64 * scale, (i + 1) as f64 * scale);
            let covered: Vec<(usize, f64)> = (a.floor() as usize
                ..(b.ceil() as usize).min(from as usize))
                .map(|k| (k, b.min(k as f64 + 1.0) - a.max(k as f64)))
                .filter(|&(_, w)| w > 0.0)
                .collect();
            let total: f64 = covered.iter().map(|c| c.1).sum();
            covered.into_iter().map(|(k, w)| (k, w / total)).collect()
        })
        .collect()
}

/// `image` area-averaged to `width` x `height`: what a map of that size holds at best when
/// each of its texels is the mean of the surface it covers.
fn area_average(image: &Image, width: u32, height: u32) -> Image {
    let (wx, wy) = (
        area_weights(image.width, width),
        area_weights(image.height, height),
    );
    let mut pixels = Vec::with_capacity((width * height) as usize);
    for row in &wy {
        for column in &wx {
            let mut sum = [0.0f64; 3];
            for &(y, a) in row {
                for &(x, b) in column {
                    let p = image.pixels[y * image.width as usize + x];
                    for (s, c) in sum.iter_mut().zip(p) {
                        *s += a * b * c as f64;
                    }
                }
            }
            pixels.push(sum.map(|s| s as f32));
        }
    }
    Image {
        width,
        height,
        pixels,
    }
}

/// Sets `row`'s map figures: the recovered map's PSNR, the PSNR of the truth itself
/// area-averaged to the recovered map's size (the ceiling of any map of that size: a map
/// has about one texel per pixel that sees it, and finer detail of the truth is not in
/// the views), and its level ([`map_level_err`]). None for an empty recovered map.
/// `given_at` names each map's file and line, for a map too large to read.
fn set_map_measures(
    row: &mut MaterialRow,
    (truth, truth_at): (&Path, String),
    (recovered, recovered_at): (&Path, String),
    wrap: Wrap,
) -> Result<(), Error> {
    let t = images::read_map(truth, 0, || truth_at)?;
    let r = images::read_map(recovered, 0, || recovered_at)?;
    if r.pixels.is_empty() {
        return Ok(());
    }
    row.diffuse_map_psnr_db = map_psnr(&t, &r, wrap);
    row.diffuse_map_psnr_ceiling_db = map_psnr(&t, &area_average(&t, r.width, r.height), wrap);
    row.diffuse_map_level_err = map_level_err(&t, &r);
    Ok(())
}

/// The recovered map's mean luminance over the truth's, less 1. Both maps span the same
/// texture square, whatever their sizes, so the mean over texels is the mean over the
/// picture. `None` for an empty map or a black truth.
fn map_level_err(truth: &Image, recovered: &Image) -> Option<f64> {
    let mean = |i: &Image| {
        let sum: f64 = i
            .pixels
            .iter()
            .map(|p| luminance(Vec3::from_array(*p)) as f64)
            .sum();
        (!i.pixels.is_empty()).then(|| sum / i.pixels.len() as f64)
    };
    let (t, r) = (mean(truth)?, mean(recovered)?);
    (t > 0.0).then(|| r / t - 1.0)
}

/// Each group of the truth against `materials` (its row `(missing)` where `materials` has
/// no entry for it). Errors: a file that does not parse, and one whose groups do not fit
/// the truth's ([`check_groups`], [`Groups::Within`]).
pub fn materials_report(truth: &Path, materials: &Path) -> Result<Vec<MaterialRow>, Error> {
    let t = materials_file::load_materials(truth)?;
    let m = materials_file::load_materials(materials)?;
    materials_rows(&t, &m)
}

/// The groups of a materials file, in its order.
pub(crate) fn groups_of(m: &MaterialsDesc) -> Vec<&str> {
    m.materials.iter().map(|d| d.group.as_str()).collect()
}

/// [`materials_report`] of files already read.
fn materials_rows(t: &MaterialsDesc, m: &MaterialsDesc) -> Result<Vec<MaterialRow>, Error> {
    // A recovery writes no entry for a group no pixel sees: the truth may have more
    // groups, but a group the truth lacks means a file of another scene, whose groups
    // were dropped in silence ("2 of 11 classes right").
    check_groups(
        &m.path,
        &groups_of(m),
        "the truth",
        &t.path,
        &groups_of(t),
        Groups::Within,
        "a file of another scene?",
    )?;
    let by_group: BTreeMap<&str, &MaterialDesc> =
        m.materials.iter().map(|d| (d.group.as_str(), d)).collect();
    let mut rows = Vec::new();
    for tm in &t.materials {
        let mut row = MaterialRow {
            group: tm.group.clone(),
            true_model: tm.model.name().into(),
            ..MaterialRow::default()
        };
        if let Some(rm) = by_group.get(tm.group.as_str()) {
            row.model = Some(rm.model.name().into());
            row.class_ok = rm.model == tm.model;
            if let (Some(a), Some(b)) = (diffuse_of(rm), diffuse_of(tm)) {
                row.diffuse_rel_err = Some((0..3).map(|c| rel(a[c], b[c])).sum::<f64>() / 3.0);
            }
            if tm.model == Model::Mirror {
                if let (Some(a), Some(b)) = (rm.color, tm.color) {
                    row.diffuse_rel_err =
                        Some((0..3).map(|c| rel(a[c] as f64, b[c] as f64)).sum::<f64>() / 3.0);
                }
            }
            let pair = |a: Option<f32>, b: Option<f32>| match (a, b) {
                (Some(a), Some(b)) if b > 0.0 => Some(rel(a as f64, b as f64)),
                _ => None,
            };
            row.specularity_rel_err = pair(rm.specularity, tm.specularity);
            row.roughness_rel_err = pair(rm.roughness, tm.roughness);
            row.roughness_u_rel_err = pair(rm.roughness_u, tm.roughness_u);
            row.roughness_v_rel_err = pair(rm.roughness_v, tm.roughness_v);
            if let (Some(a), Some(b)) = (rm.direction_u, tm.direction_u) {
                row.direction_err_deg = Some(angle_between_axes_deg(a, b));
            }
            if let (Some(a), Some(b)) = (&rm.diffuse_map, &tm.diffuse_map) {
                let at = |file: &MaterialsDesc, m: &MaterialDesc| {
                    format!("{}:{}: group '{}'", file.path.display(), m.line, m.group)
                };
                set_map_measures(&mut row, (b, at(t, tm)), (a, at(m, rm)), rm.map_wrap)?;
            }
        }
        rows.push(row);
    }
    Ok(rows)
}

/// The angle between two axes (a direction and its opposite are the same axis), degrees.
fn angle_between_axes_deg(a: [f32; 3], b: [f32; 3]) -> f64 {
    let dot: f64 = (0..3).map(|i| a[i] as f64 * b[i] as f64).sum();
    let norm = |v: [f32; 3]| v.iter().map(|&x| x as f64 * x as f64).sum::<f64>().sqrt();
    let cos = dot.abs() / (norm(a) * norm(b)).max(f64::MIN_POSITIVE);
    libm::acos(cos.min(1.0)).to_degrees()
}

/// Each row's `kind`, `true_kind` and `specular_reflectance_rel_err` (see [`MaterialRow`])
/// from `scene`, the scene whose kinds the truth has: a recovery of kind "auto" groups is
/// judged on the kinds it chose.
/// A scene whose groups are not the truth's is an error.
fn set_kinds<'a>(
    rows: &mut [MaterialRow],
    scene: &SceneDesc,
    t: &'a MaterialsDesc,
    m: &'a MaterialsDesc,
) -> Result<(), Error> {
    let scene_groups: Vec<&str> = scene.groups.iter().map(|g| g.name.as_str()).collect();
    check_groups(
        &scene.path,
        &scene_groups,
        "the truth",
        &t.path,
        &groups_of(t),
        Groups::Same,
        "the truth's own scene.toml gives its kinds",
    )?;
    let scene_kind = |group: &str| scene.groups.iter().find(|g| g.name == group)?.kind.given();
    // A truth's lobe whose kind the scene leaves to "auto" could not be judged: refused
    // rather than left out of the count in silence.
    let undecided: Vec<String> = t
        .materials
        .iter()
        .filter(|x| x.model.has_lobe() && scene_kind(&x.group).is_none())
        .map(|x| format!("'{}'", x.group))
        .collect();
    if !undecided.is_empty() {
        return Err(Error::input(
            &scene.path,
            format!(
                "{} {} of kind \"auto\", whose truth has a lobe: the truth's own scene.toml \
                 gives each lobe's kind, \"plastic\" or \"metal\"",
                if undecided.len() == 1 {
                    "group"
                } else {
                    "groups"
                },
                undecided.join(", ")
            ),
        ));
    }
    let lobe = |d: &'a MaterialsDesc, group: &str| {
        d.materials
            .iter()
            .find(|x| x.group == group && x.model.has_lobe())
    };
    for row in rows.iter_mut() {
        if let (Some(recovered), Some(truth)) = (lobe(m, &row.group), lobe(t, &row.group)) {
            let name = |k: Option<Kind>| k.map(|k| materials_file::kind_name(k).to_string());
            let given = scene_kind(&row.group);
            let kind = recovered.kind.or(given);
            row.kind = name(kind);
            row.true_kind = name(given);
            let reflectance = |d: &MaterialDesc, k: Option<Kind>| specular_reflectance_of(d, k?);
            if let (Some(a), Some(b)) = (reflectance(recovered, kind), reflectance(truth, given)) {
                row.specular_reflectance_rel_err = (0..3)
                    .all(|c| b[c] > 0.0)
                    .then(|| (0..3).map(|c| rel(a[c], b[c])).sum::<f64>() / 3.0);
            }
        }
    }
    Ok(())
}

/// The line that counts the kinds right (where [`set_kinds`] gave both).
fn kind_summary(rows: &[MaterialRow]) -> String {
    let judged: Vec<&MaterialRow> = rows
        .iter()
        .filter(|r| r.kind.is_some() && r.true_kind.is_some())
        .collect();
    let wrong: Vec<String> = judged
        .iter()
        .filter(|r| r.kind != r.true_kind)
        .map(|r| {
            format!(
                "{}: {}, truth {}",
                r.group,
                r.kind.as_deref().unwrap_or("-"),
                r.true_kind.as_deref().unwrap_or("-")
            )
        })
        .collect();
    count_right(
        "kinds right",
        judged.len(),
        " (groups with a lobe in both)",
        &wrong,
        "; ",
    )
}

/// `relume compare materials`: the table, and `json` if given. The JSON may replace none
/// of the run's inputs (either materials file or their maps), checked before the work.
/// With `scene` (the truth's scene.toml), each group with a lobe in both is judged on its
/// kind too.
pub fn compare_materials(
    truth: &Path,
    materials: &Path,
    scene: Option<&Path>,
    json: Option<&Path>,
) -> Result<(), Error> {
    if fsutil::same_file(truth, materials) {
        return Err(Error::Usage(format!(
            "the truth and the materials compared are the same file ({}): every error would read 0",
            materials.display()
        )));
    }
    let t = materials_file::load_materials(truth)?;
    let m = materials_file::load_materials(materials)?;
    let scene = scene.map(scene_file::load_scene).transpose()?;
    let mut inputs = [t.input_files(), m.input_files()].concat();
    if let Some(scene) = &scene {
        inputs.push((scene.path.clone(), "the scene".to_string()));
    }
    let mut set = OutputSet::keeping(inputs);
    if let Some(path) = json {
        set.check_target(path)?;
    }
    let mut rows = materials_rows(&t, &m)?;
    if let Some(scene) = &scene {
        set_kinds(&mut rows, scene, &t, &m)?;
    }
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{:.2}%", 100.0 * v));
    let db = |v: Option<f64>| v.map_or("-".to_string(), |p| format!("{p:.1}dB"));
    println!(
        "{:<16} {:<22} {:<22} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7} {:>8} {:>8} {:>9}",
        "group",
        "true model",
        "model",
        "class",
        "diffuse",
        "spec",
        "S refl",
        "rough",
        "rough_u",
        "rough_v",
        "dir",
        "map PSNR",
        "ceiling",
        "map level"
    );
    for r in &rows {
        println!(
            "{:<16} {:<22} {:<22} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7} {:>8} {:>8} {:>9}",
            r.group,
            r.true_model,
            r.model.as_deref().unwrap_or("(missing)"),
            if r.class_ok { "ok" } else { "WRONG" },
            pct(r.diffuse_rel_err),
            pct(r.specularity_rel_err),
            pct(r.specular_reflectance_rel_err),
            pct(r.roughness_rel_err),
            pct(r.roughness_u_rel_err),
            pct(r.roughness_v_rel_err),
            r.direction_err_deg
                .map_or("-".to_string(), |d| format!("{d:.1}deg")),
            db(r.diffuse_map_psnr_db),
            db(r.diffuse_map_psnr_ceiling_db),
            r.diffuse_map_level_err
                .map_or("-".to_string(), |v| format!("{:+.2}%", 100.0 * v)),
        );
    }
    println!("{}", class_summary(&rows));
    if scene.is_some() {
        println!("{}", kind_summary(&rows));
    }
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(&rows).map_err(|e| Error::Usage(e.to_string()))?;
        set.add(path, text.as_bytes())?;
    }
    set.commit()
}

/// How the groups of a file must match those it is judged against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Groups {
    /// Exactly the same groups: a truth and the scene it is the truth of.
    Same,
    /// Some or all of them, and no other: a recovery's materials (none is written for a
    /// group no pixel sees) against the truth.
    Within,
}

/// An input error on `file` when its `groups` do not match `their`, the groups of `what`
/// (`"the truth"`, `"the scene"`) at `other`: a file of another scene would be judged
/// against the wrong groups, or for a few groups only, and give meaningless figures. The
/// error names the groups missing on each side and ends with `hint`.
pub fn check_groups(
    file: &Path,
    groups: &[&str],
    what: &str,
    other: &Path,
    their: &[&str],
    rule: Groups,
    hint: &str,
) -> Result<(), Error> {
    let only_here: Vec<&str> = groups
        .iter()
        .filter(|g| !their.contains(g))
        .copied()
        .collect();
    let only_there: Vec<&str> = their
        .iter()
        .filter(|g| !groups.contains(g))
        .copied()
        .collect();
    let fits = only_here.is_empty()
        && match rule {
            Groups::Same => only_there.is_empty(),
            Groups::Within => !groups.is_empty() || their.is_empty(),
        };
    if fits {
        return Ok(());
    }
    let list = |names: &[&str]| {
        names
            .iter()
            .map(|g| format!("'{g}'"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut sides = Vec::new();
    if !only_here.is_empty() {
        sides.push(format!("only in this file: {}", list(&only_here)));
    }
    if !only_there.is_empty() {
        sides.push(format!("only in {what}: {}", list(&only_there)));
    }
    Err(Error::input(
        file,
        format!(
            "its groups are not those of {what} {}: {} ({hint})",
            other.display(),
            sides.join("; ")
        ),
    ))
}

/// The checks `relume compare uncertainty` makes before its work (its comparison is
/// `coverage::compare_uncertainty`): no report given twice, which would pool its
/// parameters twice and claim a coverage over more recoveries than were made; and no
/// `json` that would replace an input (the truth, its maps, a report).
pub fn check_uncertainty_run(
    truth: &Path,
    reports: &[PathBuf],
    json: Option<&Path>,
) -> Result<(), Error> {
    if let Some((report, first)) = fsutil::given_twice(reports) {
        return Err(Error::Usage(format!(
            "{} is given twice as a report (also as {}): its parameters would be pooled twice",
            report.display(),
            first.display()
        )));
    }
    if let Some(path) = json {
        let mut inputs = materials_file::load_materials(truth)?.input_files();
        inputs.extend(reports.iter().map(|r| (r.clone(), "a report".to_string())));
        OutputSet::keeping(inputs).check_target(path)?;
    }
    Ok(())
}

/// The table's closing line: how many groups have their true model, and which do not (the
/// first of the targets, and what a reader of a long table looks for first).
fn class_summary(rows: &[MaterialRow]) -> String {
    let wrong: Vec<String> = rows
        .iter()
        .filter(|r| !r.class_ok)
        .map(|r| r.group.clone())
        .collect();
    count_right("classes right", rows.len(), "", &wrong, ", ")
}

/// `"<what>: <right> of <total><note>"`, then ` (wrong: ...)` listing `wrong` with `sep`
/// unless it is empty.
fn count_right(what: &str, total: usize, note: &str, wrong: &[String], sep: &str) -> String {
    let mut line = format!("{what}: {} of {total}{note}", total - wrong.len());
    if !wrong.is_empty() {
        line += &format!(" (wrong: {})", wrong.join(sep));
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Four pixels of A = 1 whose renders B and B2 are off by a bias of 0.1 plus noises of
    /// +-0.2, in all four pairings: the RMS holds the noise (sqrt(0.1^2 + 0.2^2)); the
    /// misfit is the bias alone. Renders that err in opposite directions more than
    /// together read a negative misfit; without B2 there is none.
    #[test]
    fn the_misfit_takes_the_renders_noise_out_of_the_rms() {
        let mut sums = Sums::default();
        for (n1, n2) in [(0.2, 0.2), (0.2, -0.2), (-0.2, 0.2), (-0.2, -0.2)] {
            sums.add([1.0; 3], [1.1 + n1; 3], Some([1.1 + n2; 3]));
        }
        let row = sums.row("g", "group 'g'");
        assert!(
            (row.rel_rms - libm::sqrt(0.05)).abs() < 1e-6,
            "{}",
            row.rel_rms
        );
        let misfit = row.rel_misfit.unwrap();
        assert!((misfit - 0.1).abs() < 1e-6, "{misfit}");

        let mut opposite = Sums::default();
        opposite.add([1.0; 3], [1.1; 3], Some([0.9; 3]));
        let misfit = opposite.row("g", "group 'g'").rel_misfit.unwrap();
        assert!((misfit + 0.1).abs() < 1e-6, "{misfit}");

        let mut without = Sums::default();
        without.add([1.0; 3], [1.1; 3], None);
        assert_eq!(without.row("g", "group 'g'").rel_misfit, None);
        assert_eq!(without.row("g", "group 'g'").rel_mean_bias, None);
    }

    /// Two renders' means off by a bias of -0.1 and noises of +-0.05 read -0.15 and -0.05
    /// alone; together, the geometric mean of the two (the product's mean over the noises
    /// is the bias squared), with their sign. Means on either side of the reference are a
    /// difference under the noise: 0.
    #[test]
    fn the_mean_bias_takes_the_renders_noise_out_of_the_mean() {
        let group = |b: f32, b2: f32| {
            let mut sums = Sums::default();
            sums.add([2.0; 3], [2.0 * b; 3], Some([2.0 * b2; 3]));
            sums.row("g", "group 'g'")
        };
        let row = group(0.85, 0.95);
        assert!((row.rel_mean_diff + 0.15).abs() < 1e-6);
        let bias = row.rel_mean_bias.unwrap();
        assert!((bias + libm::sqrt(0.15 * 0.05)).abs() < 1e-6, "{bias}");
        let bias = group(1.1, 1.1).rel_mean_bias.unwrap();
        assert!((bias - 0.1).abs() < 1e-6, "{bias}");
        assert_eq!(group(1.05, 0.97).rel_mean_bias, Some(0.0));
    }

    fn image(width: u32, height: u32, value: impl Fn(u32, u32) -> f32) -> Image {
        let pixels = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| [value(x, y); 3])
            .collect();
        Image {
            width,
            height,
            pixels,
        }
    }

    #[test]
    fn the_summary_counts_the_classes_right_and_names_the_wrong_ones() {
        let row = |group: &str, class_ok| MaterialRow {
            group: group.into(),
            class_ok,
            ..MaterialRow::default()
        };
        assert_eq!(
            class_summary(&[row("floor", true), row("desk", false), row("lamp", false)]),
            "classes right: 1 of 3 (wrong: desk, lamp)"
        );
        assert_eq!(
            class_summary(&[row("floor", true)]),
            "classes right: 1 of 1"
        );
    }

    #[test]
    fn area_average_keeps_the_mean_and_covers_partial_texels() {
        let t = image(5, 3, |x, y| (x + 7 * y) as f32);
        let a = area_average(&t, 2, 2);
        let mean =
            |i: &Image| i.pixels.iter().map(|p| p[0] as f64).sum::<f64>() / i.pixels.len() as f64;
        assert!((mean(&a) - mean(&t)).abs() < 1e-5);
        // The first cell covers columns 0, 1 and half of 2, rows 0 and half of 1.
        let expected = (0.0 + 1.0 + 0.5 * 2.0) / 2.5 + 7.0 * (0.5 / 1.5);
        assert!((a.pixels[0][0] as f64 - expected).abs() < 1e-5);
    }

    #[test]
    fn a_map_of_the_truths_own_size_has_no_ceiling_and_a_coarse_one_has_one() {
        let checker = image(8, 8, |x, y| if (x + y) % 2 == 0 { 0.8 } else { 0.2 });
        assert_eq!(
            map_psnr(&checker, &area_average(&checker, 8, 8), Wrap::Clamp),
            Some(f64::INFINITY)
        );
        // At a size whose texel centres are not exact in f32 (the textured reference's
        // 192 x 192 maps read 136 dB against themselves).
        let varied = image(192, 37, |x, y| ((x * 7 + y * 13) % 17) as f32 / 17.0);
        assert_eq!(map_psnr(&varied, &varied, Wrap::Clamp), Some(f64::INFINITY));
        assert_eq!(
            map_psnr(&varied, &area_average(&varied, 192, 37), Wrap::Clamp),
            Some(f64::INFINITY)
        );
        // A texel-sized checker averages to grey at any coarser size: the ceiling is the
        // PSNR of the grey map, 20 log10(0.8 / 0.3).
        let ceiling = map_psnr(&checker, &area_average(&checker, 4, 4), Wrap::Clamp).unwrap();
        assert!(
            (ceiling - 20.0 * libm::log10(0.8f64 / 0.3)).abs() < 1e-4,
            "{ceiling}"
        );
        let grey = image(4, 4, |_, _| 0.5);
        assert!((map_psnr(&checker, &grey, Wrap::Clamp).unwrap() - ceiling).abs() < 1e-4);
    }

    #[test]
    fn a_maps_level_is_its_mean_luminance_over_the_truths_whatever_its_size() {
        let checker = image(8, 8, |x, y| if (x + y) % 2 == 0 { 0.8 } else { 0.2 });
        // A grey of the checker's mean is level with it, at a quarter of its texels.
        let level = map_level_err(&checker, &image(4, 4, |_, _| 0.5)).unwrap();
        assert!(level.abs() < 1e-6, "{level}");
        let dark = map_level_err(&checker, &image(2, 2, |_, _| 0.475)).unwrap();
        assert!((dark + 0.05).abs() < 1e-6, "{dark}");
        assert_eq!(map_level_err(&image(2, 2, |_, _| 0.0), &checker), None);
        assert_eq!(map_level_err(&checker, &image(0, 0, |_, _| 0.5)), None);
    }

    #[test]
    fn a_map_equal_to_the_truths_is_written_inf_in_json_not_the_null_of_no_map() {
        let row = |psnr, ceiling| MaterialRow {
            diffuse_map_psnr_db: psnr,
            diffuse_map_psnr_ceiling_db: ceiling,
            ..MaterialRow::default()
        };
        let json = |r: MaterialRow| serde_json::to_value(r).unwrap();
        let exact = json(row(Some(f64::INFINITY), Some(f64::INFINITY)));
        assert_eq!(exact["diffuse_map_psnr_db"], "inf");
        assert_eq!(exact["diffuse_map_psnr_ceiling_db"], "inf");
        let coarse = json(row(Some(22.5), Some(25.75)));
        assert_eq!(coarse["diffuse_map_psnr_db"], 22.5);
        assert_eq!(coarse["diffuse_map_psnr_ceiling_db"], 25.75);
        assert!(json(row(None, None))["diffuse_map_psnr_db"].is_null());
    }

    /// A black truth map (a peak of 0) against one that is not reads -inf dB, as the table
    /// says; the JSON wrote null, which there means that the group has no map.
    #[test]
    fn a_map_against_a_black_truth_is_written_minus_inf_in_json_not_the_null_of_no_map() {
        let black = image(4, 4, |_, _| 0.0);
        let psnr = map_psnr(&black, &image(4, 4, |_, _| 0.5), Wrap::Clamp);
        assert_eq!(psnr, Some(f64::NEG_INFINITY));
        assert_eq!(map_psnr(&black, &black, Wrap::Clamp), Some(f64::INFINITY));
        let row = MaterialRow {
            diffuse_map_psnr_db: psnr,
            diffuse_map_psnr_ceiling_db: Some(f64::INFINITY),
            ..MaterialRow::default()
        };
        let json = serde_json::to_value(row).unwrap();
        assert_eq!(json["diffuse_map_psnr_db"], "-inf");
        assert_eq!(json["diffuse_map_psnr_ceiling_db"], "inf");
    }

    #[test]
    fn a_row_without_pixels_or_with_a_black_reference_has_no_relative_figures_and_says_why() {
        let mut sums = Sums::default();
        let empty = sums.row("lamp", "group 'lamp'");
        assert!(empty.rel_mean_diff.is_nan() && empty.rel_rms.is_nan());
        assert_eq!(
            empty.undefined.as_deref(),
            Some("group 'lamp': no pure pixel, nothing to compare")
        );
        sums.add([0.0; 3], [0.5; 3], None);
        sums.add([0.0; 3], [0.25; 3], None);
        let black = sums.row("floor", "group 'floor' (in views px)");
        assert!(black.rel_mean_diff.is_nan(), "{black:?}");
        let why = black.undefined.clone().unwrap();
        assert!(
            why.starts_with("group 'floor' (in views px): the reference (A) is 0 over its 2"),
            "{why}"
        );
        // In JSON: null and the reason, never NaN; a defined row has no reason.
        let json = serde_json::to_string(&black).unwrap();
        assert!(
            json.contains("\"rel_mean_diff\":null") && json.contains("\"undefined\":"),
            "{json}"
        );
        let mut lit = Sums::default();
        lit.add([1.0; 3], [1.5; 3], None);
        let row = lit.row("floor", "group 'floor'");
        assert_eq!((row.rel_mean_diff, row.rel_rms), (0.5, 0.5));
        let json = serde_json::to_string(&row).unwrap();
        assert!(
            json.contains("\"rel_mean_diff\":0.5") && !json.contains("undefined"),
            "{json}"
        );
    }

    #[test]
    fn groups_that_do_not_match_are_named_on_each_side() {
        let (file, truth) = (Path::new("m.toml"), Path::new("t.toml"));
        let check = |groups: &[&str], rule| {
            check_groups(
                file,
                groups,
                "the truth",
                truth,
                &["floor", "walls", "desk"],
                rule,
                "a file of another scene?",
            )
            .map_err(|e| e.to_string())
        };
        assert!(check(&["desk", "floor", "walls"], Groups::Same).is_ok());
        // A recovery that left a group out is judged; as the truth of a scene it is not.
        assert!(check(&["floor", "desk"], Groups::Within).is_ok());
        let e = check(&["floor", "desk"], Groups::Same).unwrap_err();
        assert_eq!(
            e,
            "m.toml: its groups are not those of the truth t.toml: only in the truth: 'walls' (a file of another scene?)"
        );
        let e = check(&["floor", "sofa", "lamp"], Groups::Within).unwrap_err();
        assert!(
            e.contains("only in this file: 'sofa', 'lamp'; only in the truth: 'walls', 'desk'"),
            "{e}"
        );
        // A file with no group at all has nothing to judge.
        let e = check(&[], Groups::Within).unwrap_err();
        assert!(
            e.contains("only in the truth: 'floor', 'walls', 'desk'"),
            "{e}"
        );
    }

    /// A materials file of `groups`, all diffuse grey, in `dir`.
    fn materials_file_of(dir: &Path, name: &str, groups: &[&str]) -> PathBuf {
        let mut text = String::from("format = 1\n");
        for g in groups {
            text += &format!(
                "\n[[material]]\ngroup = \"{g}\"\nmodel = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]\n"
            );
        }
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn materials_of_another_scene_are_refused_and_a_partial_recovery_is_judged() {
        let dir = tempfile::tempdir().unwrap();
        let truth = materials_file_of(dir.path(), "t.toml", &["floor", "walls"]);
        let other = materials_file_of(dir.path(), "o.toml", &["floor", "sofa"]);
        let e = materials_report(&truth, &other).unwrap_err().to_string();
        assert!(
            e.contains("o.toml")
                && e.contains("only in this file: 'sofa'")
                && e.contains("only in the truth: 'walls'"),
            "{e}"
        );
        let partial = materials_file_of(dir.path(), "p.toml", &["walls"]);
        let rows = materials_report(&truth, &partial).unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!((rows[0].model.as_deref(), rows[0].class_ok), (None, false));
        assert!(rows[1].class_ok);
    }

    #[test]
    fn compare_json_that_would_replace_an_input_is_refused_before_the_work() {
        let dir = tempfile::tempdir().unwrap();
        let truth = materials_file_of(dir.path(), "t.toml", &["floor"]);
        let recovered = materials_file_of(dir.path(), "r.toml", &["floor"]);
        let before = std::fs::read(&truth).unwrap();
        let e = compare_materials(&truth, &recovered, None, Some(&truth))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.toml")
                && e.contains("would replace a materials file, an input of this run"),
            "{e}"
        );
        assert_eq!(std::fs::read(&truth).unwrap(), before);
        // compare uncertainty: a report as the JSON, and a report given twice.
        let report = dir.path().join("report.json");
        std::fs::write(&report, "{\"groups\": []}").unwrap();
        let reports = [report.clone()];
        let e = check_uncertainty_run(&truth, &reports, Some(&report))
            .unwrap_err()
            .to_string();
        assert!(e.contains("would replace a report"), "{e}");
        let twice = [report.clone(), dir.path().join(".").join("report.json")];
        let e = check_uncertainty_run(&truth, &twice, None).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().contains("given twice as a report"), "{e}");
        check_uncertainty_run(&truth, &reports, Some(&dir.path().join("out.json"))).unwrap();
    }
}
