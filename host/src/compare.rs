//! `relume compare`: how far a rendering is from a reference, group by group, and how far
//! recovered materials are from the truth. These are the user's yardsticks (and ours).

use std::collections::BTreeMap;
use std::path::Path;

use relume_core::geometry::Surface;
use relume_core::material::texture::bilinear_taps;
use relume_core::render;
use serde::Serialize;

use crate::assemble::{self, MaterialSource};
use crate::error::Error;
use crate::images::{self, Image};
use crate::materials_file::{self, MaterialDesc, Model};
use crate::scene_file::ViewDesc;
use crate::{fsutil, parallel};

/// Sub-rays per pixel side used to decide that a pixel's whole footprint sees one group.
pub const LABEL_RAYS_PER_SIDE: u32 = 4;

/// Running sums over pixels (per-channel values pooled).
#[derive(Default, Clone, Copy)]
struct Sums {
    pixels: u64,
    sum_a: f64,
    sum_b: f64,
    sum_sq_diff: f64,
}

impl Sums {
    fn add(&mut self, a: [f32; 3], b: [f32; 3]) {
        self.pixels += 1;
        for c in 0..3 {
            let (a, b) = (a[c] as f64, b[c] as f64);
            self.sum_a += a;
            self.sum_b += b;
            self.sum_sq_diff += (b - a) * (b - a);
        }
    }

    fn row(&self, name: &str) -> ViewsRow {
        let n = (self.pixels * 3).max(1) as f64;
        let mean_a = self.sum_a / n;
        let mean_b = self.sum_b / n;
        ViewsRow {
            name: name.to_string(),
            pixels: self.pixels,
            mean_a,
            mean_b,
            rel_mean_diff: if mean_a > 0.0 {
                (mean_b - mean_a) / mean_a
            } else {
                f64::NAN
            },
            rel_rms: if mean_a > 0.0 {
                (self.sum_sq_diff / n).sqrt() / mean_a
            } else {
                f64::NAN
            },
        }
    }
}

/// One line of the views table: `rel_mean_diff = (mean B - mean A) / mean A`,
/// `rel_rms = RMS(B - A) / mean A` (the reference READMEs' definitions).
#[derive(Serialize, Clone, Debug)]
pub struct ViewsRow {
    pub name: String,
    pub pixels: u64,
    pub mean_a: f64,
    pub mean_b: f64,
    pub rel_mean_diff: f64,
    pub rel_rms: f64,
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
    /// `<folder>/<view>.exr`, as `relume render` writes them (exposure 1).
    Folder(&'a Path),
    /// The images the scene file names for its views (the panorama), with their exposure.
    Scene,
}

impl ViewImages<'_> {
    fn read(&self, desc: &ViewDesc, scene_path: &Path) -> Result<images::Image, Error> {
        match self {
            ViewImages::Folder(dir) => {
                images::read_view_image(&dir.join(format!("{}.exr", desc.name)), 1.0, desc.size)
            }
            ViewImages::Scene => {
                let path = desc.image.as_ref().ok_or_else(|| {
                    Error::input(scene_path, format!("view '{}' names no image", desc.name))
                })?;
                images::read_view_image(path, desc.exposure, desc.size)
            }
        }
    }
}

/// Compares `dir_a/<view>.exr` with `dir_b/<view>.exr` for every view of the scene over
/// pure pixels (whole footprint on one group; lights and silhouettes left out).
pub fn views_report(
    scene_path: &Path,
    dir_a: &Path,
    dir_b: &Path,
    threads: Option<usize>,
) -> Result<ViewsReport, Error> {
    views_report_of(
        scene_path,
        ViewImages::Folder(dir_a),
        ViewImages::Folder(dir_b),
        threads,
    )
}

/// [`views_report`] for images from anywhere: A is the reference.
pub fn views_report_of(
    scene_path: &Path,
    a: ViewImages<'_>,
    b: ViewImages<'_>,
    threads: Option<usize>,
) -> Result<ViewsReport, Error> {
    let mut owned = assemble::load_and_assemble(scene_path, MaterialSource::GeometryOnly)?;
    let pool = parallel::thread_pool(threads)?;
    let descs = owned.desc.views.clone();
    let views = owned.views.clone();
    let group_names = owned.group_names.clone();
    let scene = owned.build()?;

    let mut groups = vec![Sums::default(); group_names.len()];
    let mut per_view = Vec::new();
    let mut all = Sums::default();
    for (desc, view) in descs.iter().zip(&views) {
        let a = a.read(desc, scene_path)?;
        let b = b.read(desc, scene_path)?;
        let labels = parallel::map_pixels(&pool, view, |x, y| {
            render::pixel_surface(&scene, view, x, y, LABEL_RAYS_PER_SIDE)
        });
        let mut sums = Sums::default();
        for (i, label) in labels.iter().enumerate() {
            if let Some(Surface::Group(g)) = label {
                groups[*g as usize].add(a.pixels[i], b.pixels[i]);
                sums.add(a.pixels[i], b.pixels[i]);
                all.add(a.pixels[i], b.pixels[i]);
            }
        }
        per_view.push(sums.row(&desc.name));
    }
    Ok(ViewsReport {
        groups: groups
            .iter()
            .zip(&group_names)
            .map(|(s, n)| s.row(n))
            .collect(),
        views: per_view,
        all: all.row("image"),
    })
}

fn print_views_table(report: &ViewsReport) {
    println!(
        "{:<16} {:>8} {:>11} {:>11} {:>10} {:>9}",
        "group", "pixels", "mean A", "mean B", "rel mean", "rel RMS"
    );
    let line = |r: &ViewsRow| {
        println!(
            "{:<16} {:>8} {:>11.5} {:>11.5} {:>+9.2}% {:>8.2}%",
            r.name,
            r.pixels,
            r.mean_a,
            r.mean_b,
            100.0 * r.rel_mean_diff,
            100.0 * r.rel_rms
        )
    };
    report.groups.iter().for_each(line);
    println!("{:<16}", "-- views");
    report.views.iter().for_each(line);
    line(&report.all);
}

pub fn compare_views(
    scene: &Path,
    dir_a: &Path,
    dir_b: &Path,
    json: Option<&Path>,
    threads: Option<usize>,
) -> Result<(), Error> {
    let report = views_report(scene, dir_a, dir_b, threads)?;
    print_views_table(&report);
    if let Some(path) = json {
        let text =
            serde_json::to_string_pretty(&report).map_err(|e| Error::Usage(e.to_string()))?;
        fsutil::write_atomic(path, text.as_bytes())?;
    }
    Ok(())
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
    /// PSNR of the diffuse map over all texels, peak = the truth's maximum.
    pub diffuse_map_psnr_db: Option<f64>,
    /// The same PSNR for the truth area-averaged to the recovered map's size: the most a
    /// map of that resolution can reach.
    pub diffuse_map_psnr_ceiling_db: Option<f64>,
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

/// PSNR of a recovered map against the truth's, peak = the truth's maximum. The recovered
/// map may have another size: it is sampled as the renderer samples it (bilinear between
/// texel centres, clamped) at the truth's texel centres. `None` for an empty image.
fn map_psnr(truth: &Image, recovered: &Image) -> Option<f64> {
    let (t, r) = (truth, recovered);
    if t.pixels.is_empty() || r.pixels.is_empty() {
        return None;
    }
    let sample = |u: f32, v: f32| {
        bilinear_taps(r.width, r.height, glam::Vec2::new(u, v))
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
            let ours = sample(u, v);
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

/// The recovered map's PSNR, and the PSNR of the truth itself area-averaged to the
/// recovered map's size: the ceiling of any map of that size. A map has about one texel
/// per pixel that sees it; finer detail of the truth is not in the views.
fn map_psnrs(truth: &Path, recovered: &Path) -> Result<(Option<f64>, Option<f64>), Error> {
    let t = images::read_image(truth, 1.0)?;
    let r = images::read_image(recovered, 1.0)?;
    if r.pixels.is_empty() {
        return Ok((None, None));
    }
    let ceiling = map_psnr(&t, &area_average(&t, r.width, r.height));
    Ok((map_psnr(&t, &r), ceiling))
}

pub fn materials_report(truth: &Path, materials: &Path) -> Result<Vec<MaterialRow>, Error> {
    let t = materials_file::load_materials(truth)?;
    let m = materials_file::load_materials(materials)?;
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
                (row.diffuse_map_psnr_db, row.diffuse_map_psnr_ceiling_db) = map_psnrs(b, a)?;
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

pub fn compare_materials(truth: &Path, materials: &Path, json: Option<&Path>) -> Result<(), Error> {
    let rows = materials_report(truth, materials)?;
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{:.2}%", 100.0 * v));
    let db = |v: Option<f64>| v.map_or("-".to_string(), |p| format!("{p:.1}dB"));
    println!(
        "{:<16} {:<22} {:<22} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7} {:>8} {:>8}",
        "group",
        "true model",
        "model",
        "class",
        "diffuse",
        "spec",
        "rough",
        "rough_u",
        "rough_v",
        "dir",
        "map PSNR",
        "ceiling"
    );
    for r in &rows {
        println!(
            "{:<16} {:<22} {:<22} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7} {:>8} {:>8}",
            r.group,
            r.true_model,
            r.model.as_deref().unwrap_or("(missing)"),
            if r.class_ok { "ok" } else { "WRONG" },
            pct(r.diffuse_rel_err),
            pct(r.specularity_rel_err),
            pct(r.roughness_rel_err),
            pct(r.roughness_u_rel_err),
            pct(r.roughness_v_rel_err),
            r.direction_err_deg
                .map_or("-".to_string(), |d| format!("{d:.1}deg")),
            db(r.diffuse_map_psnr_db),
            db(r.diffuse_map_psnr_ceiling_db),
        );
    }
    println!("{}", class_summary(&rows));
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(&rows).map_err(|e| Error::Usage(e.to_string()))?;
        fsutil::write_atomic(path, text.as_bytes())?;
    }
    Ok(())
}

/// The table's closing line: how many groups have their true model, and which do not (the
/// first of the targets, and what a reader of a long table looks for first).
fn class_summary(rows: &[MaterialRow]) -> String {
    let wrong: Vec<&str> = rows
        .iter()
        .filter(|r| !r.class_ok)
        .map(|r| r.group.as_str())
        .collect();
    let mut line = format!(
        "classes right: {} of {}",
        rows.len() - wrong.len(),
        rows.len()
    );
    if !wrong.is_empty() {
        line += &format!(" (wrong: {})", wrong.join(", "));
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

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
            map_psnr(&checker, &area_average(&checker, 8, 8)),
            Some(f64::INFINITY)
        );
        // A texel-sized checker averages to grey at any coarser size: the ceiling is the
        // PSNR of the grey map, 20 log10(0.8 / 0.3).
        let ceiling = map_psnr(&checker, &area_average(&checker, 4, 4)).unwrap();
        assert!(
            (ceiling - 20.0 * libm::log10(0.8f64 / 0.3)).abs() < 1e-4,
            "{ceiling}"
        );
        let grey = image(4, 4, |_, _| 0.5);
        assert!((map_psnr(&checker, &grey).unwrap() - ceiling).abs() < 1e-4);
    }
}
