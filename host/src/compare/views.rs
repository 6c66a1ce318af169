//! `relume compare views`: a rendering against a reference over pure pixels (a pixel's
//! whole footprint on one group), group by group and view by view: the relative difference
//! of the means, the relative RMS, and with an independent render the misfit and mean bias
//! with the render noise taken out.

use std::path::{Path, PathBuf};

use relume_core::geometry::Surface;
use relume_core::render;
use serde::Serialize;

use crate::assemble::{self, MaterialSource};
use crate::error::Error;
use crate::fsutil::{self, OutputSet};
use crate::images;
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
}
