//! Everything `recover` writes, each file atomically: materials.toml, materials.rad,
//! report.json, the re-rendered views and per-view error images.

use std::path::Path;

use glam::Vec3;

use super::{RecoverReport, Recovery};
use crate::error::Error;
use crate::images::{self, Image};
use crate::materials_file::{self, MaterialsDesc};
use crate::{fsutil, parallel};

/// Renders every view with the current models.
pub(super) fn render_views(
    rec: &mut Recovery,
    spp: u32,
    seed: u64,
) -> Result<Vec<Vec<Vec3>>, Error> {
    rec.apply_models();
    let settings = relume_core::render::RenderSettings {
        spp,
        seed,
        ..Default::default()
    };
    let total_rows: u64 = rec.views.iter().map(|v| v.height as u64).sum();
    let bar = super::progress_bar(total_rows, "final render");
    let views = rec.views.clone();
    let scene = rec.owned.build()?;
    let renders = views
        .iter()
        .enumerate()
        .map(|(vi, view)| {
            parallel::render_view(&rec.pool, &scene, view, vi as u32, &settings, &bar)
        })
        .collect();
    bar.finish_and_clear();
    Ok(renders)
}

pub(super) fn write_all(
    out: &Path,
    rec: &Recovery,
    renders: &[Vec<Vec3>],
    report: &RecoverReport,
) -> Result<(), Error> {
    fsutil::create_dir(&out.join("views"))?;
    fsutil::create_dir(&out.join("errors"))?;
    for (vi, pixels) in renders.iter().enumerate() {
        let name = &rec.owned.desc.views[vi].name;
        let view = &rec.views[vi];
        let image = Image {
            width: view.width,
            height: view.height,
            pixels: pixels.iter().map(|p| p.to_array()).collect(),
        };
        images::write_exr(&out.join("views").join(format!("{name}.exr")), &image)?;
        images::write_png_preview(&out.join("views").join(format!("{name}.png")), &image, None)?;
        // |render - real| per channel: where the fit is poor.
        let diff = Image {
            width: view.width,
            height: view.height,
            pixels: image
                .pixels
                .iter()
                .zip(&rec.real[vi].pixels)
                .map(|(a, b)| {
                    [
                        (a[0] - b[0]).abs(),
                        (a[1] - b[1]).abs(),
                        (a[2] - b[2]).abs(),
                    ]
                })
                .collect(),
        };
        images::write_exr(&out.join("errors").join(format!("{name}.exr")), &diff)?;
        images::write_png_preview(&out.join("errors").join(format!("{name}.png")), &diff, None)?;
    }
    let names = &rec.owned.group_names;
    let materials_path = out.join("materials.toml");
    let materials = MaterialsDesc {
        path: materials_path.clone(),
        materials: rec
            .models
            .iter()
            .zip(names)
            .filter_map(|(m, n)| m.material_desc(n))
            .collect(),
    };
    materials_file::write_materials(&materials_path, &materials)?;
    let mut rad = String::from("# relume: recovered materials as RADIANCE primitives\n");
    for (m, n) in rec.models.iter().zip(names) {
        match m.radiance_primitive(n) {
            Some(p) => {
                rad.push('\n');
                rad.push_str(&p);
            }
            None => rad.push_str(&format!("\n# {n}: unseen, not recovered\n")),
        }
    }
    fsutil::write_atomic(&out.join("materials.rad"), rad.as_bytes())?;
    let text = serde_json::to_string_pretty(report).map_err(|e| Error::Usage(e.to_string()))?;
    fsutil::write_atomic(&out.join("report.json"), text.as_bytes())?;
    Ok(())
}
