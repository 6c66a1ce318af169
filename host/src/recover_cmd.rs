//! `relume recover`: the staged recovery of every group's material from the panorama.
//!
//! The host's part: read the scene and the panorama, find each group's pure pixels, run
//! the renders each stage asks for (in parallel, in a fixed partition, so results do not
//! depend on the thread count) and write the results atomically. The decisions are the
//! core's (`relume_core::stages`, `relume_core::fit`).

use std::path::PathBuf;
use std::time::Instant;

use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use relume_core::fit::{self, GroupFit};
use relume_core::geometry::{Surface, View};
use relume_core::material::{Material, SurfaceMaterial};
use relume_core::render::{self, RenderSettings};
use relume_core::scene::Scene;
use relume_core::stages::diffuse::{self, DiffuseVerdict};
use serde::Serialize;

use crate::assemble::{self, MaterialSource, OwnedScene};
use crate::compare::LABEL_RAYS_PER_SIDE;
use crate::error::Error;
use crate::images::{self, Image};
use crate::materials_file::{MaterialDesc, MaterialsDesc, Model};
use crate::{fsutil, parallel};

/// How much work the recovery may spend: samples per pixel of the renders in the loop, and
/// of the final render that the report's errors come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Effort {
    Fast,
    Default,
    Thorough,
}

impl Effort {
    fn loop_spp(self) -> u32 {
        match self {
            Effort::Fast => 8,
            Effort::Default => 32,
            Effort::Thorough => 128,
        }
    }

    fn final_spp(self) -> u32 {
        match self {
            Effort::Fast => 32,
            Effort::Default => 128,
            Effort::Thorough => 512,
        }
    }
}

pub struct RecoverArgs {
    pub scene: PathBuf,
    pub out: PathBuf,
    pub seed: u64,
    pub threads: Option<usize>,
    pub effort: Effort,
}

/// A pixel whose whole footprint sees one group.
#[derive(Clone, Copy)]
struct PurePixel {
    view: u32,
    x: u32,
    y: u32,
    group: u16,
}

/// What the report says of one group.
#[derive(Serialize, Clone, Debug)]
pub struct GroupReport {
    pub group: String,
    pub pure_pixels: u32,
    pub model: String,
    pub decision: String,
    pub diffuse_error_before: Option<f64>,
    pub diffuse_error_after: Option<f64>,
    pub final_error: Option<f64>,
    pub color: [f64; 3],
}

#[derive(Serialize, Debug)]
pub struct StageReport {
    pub stage: String,
    pub evaluations: u32,
    pub samples_per_pixel: u32,
    pub seconds: f64,
    pub notes: Vec<String>,
}

#[derive(Serialize, Debug)]
pub struct RecoverReport {
    pub scene: String,
    pub seed: u64,
    pub effort: String,
    pub error_definition: &'static str,
    pub thresholds: serde_json::Value,
    pub stages: Vec<StageReport>,
    pub groups: Vec<GroupReport>,
    pub warnings: Vec<String>,
    pub seconds: f64,
}

/// Renders the pure pixels and compares them with the panorama, group by group.
fn evaluate(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    views: &[View],
    pure: &[PurePixel],
    real: &[Image],
    settings: &RenderSettings,
    n_groups: usize,
) -> Vec<GroupFit> {
    const CHUNK: usize = 256;
    let partials: Vec<Vec<GroupFit>> = pool.install(|| {
        pure.par_chunks(CHUNK)
            .map(|chunk| {
                let mut fits = vec![GroupFit::default(); n_groups];
                for p in chunk {
                    let view = &views[p.view as usize];
                    let (value, variance) =
                        render::render_pixel_with_variance(scene, view, p.view, p.x, p.y, settings);
                    let t = real[p.view as usize].pixels[(p.y * view.width + p.x) as usize];
                    fits[p.group as usize].add(Vec3::from(t), value, variance);
                }
                fits
            })
            .collect()
    });
    let mut total = vec![GroupFit::default(); n_groups];
    for part in &partials {
        for (t, p) in total.iter_mut().zip(part) {
            t.merge(p);
        }
    }
    total
}

fn set_diffuse(owned: &mut OwnedScene, rho: &[[f64; 3]]) {
    for (m, r) in owned.materials.iter_mut().zip(rho) {
        *m = SurfaceMaterial {
            material: Material::Diffuse { rho_d: Vec3::new(r[0] as f32, r[1] as f32, r[2] as f32) },
            diffuse_map: None,
        };
    }
}

fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len).with_style(
        ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} {eta} left")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_message(what.to_string());
    bar
}

pub fn run(args: &RecoverArgs) -> Result<RecoverReport, Error> {
    let start = Instant::now();
    let (desc, objects) = assemble::load_scene(&args.scene)?;
    let mut real = Vec::with_capacity(desc.views.len());
    for v in &desc.views {
        let Some(path) = &v.image else {
            return Err(Error::input(
                &desc.path,
                format!("view '{}' has no image: recover needs the panorama", v.name),
            ));
        };
        real.push(images::read_view_image(path, v.exposure, v.size)?);
    }
    let mut owned = assemble::assemble(desc, &objects, MaterialSource::GeometryOnly)?;
    let pool = parallel::thread_pool(args.threads)?;
    let views = owned.views.clone();
    let n_groups = owned.group_names.len();
    let mut warnings = Vec::new();

    // Pure pixels of every group, in view and row order.
    let mut pure = Vec::new();
    {
        let scene = owned.build()?;
        for (vi, view) in views.iter().enumerate() {
            let labels = parallel::map_pixels(&pool, view, |x, y| {
                render::pixel_surface(&scene, view, x, y, LABEL_RAYS_PER_SIDE)
            });
            let mut n = 0;
            for (i, label) in labels.iter().enumerate() {
                if let Some(Surface::Group(g)) = label {
                    n += 1;
                    pure.push(PurePixel { view: vi as u32, x: i as u32 % view.width, y: i as u32 / view.width, group: *g });
                }
            }
            if n == 0 {
                warnings.push(format!(
                    "view '{}' sees no group in whole pixels (only lights, silhouettes or nothing): it adds nothing to the fit",
                    owned.desc.views[vi].name
                ));
            }
        }
    }

    // Stage 1: all diffuse.
    let stage_start = Instant::now();
    let settings = RenderSettings { spp: args.effort.loop_spp(), seed: args.seed, ..RenderSettings::default() };
    let mut rho = vec![[0.5f64; 3]; n_groups];
    let mut first_fit: Option<Vec<GroupFit>> = None;
    let mut fits;
    let mut evaluations = 0u32;
    let bar = progress_bar(fit::DIFFUSE_MAX_STEPS as u64, "diffuse");
    loop {
        set_diffuse(&mut owned, &rho);
        let scene = owned.build()?;
        fits = evaluate(&pool, &scene, &views, &pure, &real, &settings, n_groups);
        evaluations += 1;
        bar.inc(1);
        if first_fit.is_none() {
            first_fit = Some(fits.clone());
        }
        let mut max_change = 0.0f64;
        for (r, f) in rho.iter_mut().zip(&fits) {
            let (next, change) = diffuse::update(*r, f);
            *r = next;
            max_change = max_change.max(change);
        }
        if max_change <= fit::DIFFUSE_CONVERGED || evaluations >= fit::DIFFUSE_MAX_STEPS {
            break;
        }
    }
    // The fit of the final reflectances.
    set_diffuse(&mut owned, &rho);
    {
        let scene = owned.build()?;
        fits = evaluate(&pool, &scene, &views, &pure, &real, &settings, n_groups);
        evaluations += 1;
    }
    bar.finish_and_clear();
    let mut stages = vec![StageReport {
        stage: "diffuse".into(),
        evaluations,
        samples_per_pixel: settings.spp,
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![format!(
            "rho_d <- rho_d * mean(real) / mean(rendered), until the largest relative change <= {}",
            fit::DIFFUSE_CONVERGED
        )],
    }];

    let first_fit = first_fit.unwrap_or_default();
    let mut groups = Vec::with_capacity(n_groups);
    for g in 0..n_groups {
        let name = owned.group_names[g].clone();
        let verdict = diffuse::verdict(&fits[g]);
        let decision = match verdict {
            DiffuseVerdict::Diffuse => format!(
                "diffuse: error {:.4} <= DIFFUSE_THRESHOLD {}",
                fits[g].relative_error().unwrap_or(0.0),
                fit::DIFFUSE_THRESHOLD
            ),
            DiffuseVerdict::NeedsSpecular => {
                warnings.push(format!(
                    "group '{name}': the diffuse model leaves an error above the threshold; the specular stages are not implemented yet, so it is reported as diffuse"
                ));
                format!(
                    "needs a specular model: error {:.4} > DIFFUSE_THRESHOLD {} (specular stages not implemented yet)",
                    fits[g].relative_error().unwrap_or(0.0),
                    fit::DIFFUSE_THRESHOLD
                )
            }
            DiffuseVerdict::BarelySeen => {
                warnings.push(format!("group '{name}': only {} pure pixels; kept diffuse", fits[g].pixels));
                format!("barely seen: {} < MIN_PIXELS_FOR_MODEL_CHOICE {}", fits[g].pixels, fit::MIN_PIXELS_FOR_MODEL_CHOICE)
            }
            DiffuseVerdict::Unseen => {
                warnings.push(format!("group '{name}': no pure pixel in any view; its material is not recovered"));
                "unseen: no pure pixel in any view; material not recovered".into()
            }
        };
        groups.push(GroupReport {
            group: name,
            pure_pixels: fits[g].pixels,
            model: if verdict == DiffuseVerdict::Unseen { "unseen".into() } else { "diffuse".into() },
            decision,
            diffuse_error_before: first_fit.get(g).and_then(|f| f.relative_error()),
            diffuse_error_after: fits[g].relative_error(),
            final_error: None,
            color: rho[g],
        });
    }

    // Final render of every view with the recovered model: the views, and error images.
    let final_start = Instant::now();
    let final_settings = RenderSettings { spp: args.effort.final_spp(), seed: args.seed ^ 0xF1A1, ..RenderSettings::default() };
    let scene = owned.build()?;
    let final_fits = evaluate(&pool, &scene, &views, &pure, &real, &final_settings, n_groups);
    for (g, f) in groups.iter_mut().zip(&final_fits) {
        g.final_error = f.relative_error();
    }
    let total_rows: u64 = views.iter().map(|v| v.height as u64).sum();
    let bar = progress_bar(total_rows, "final render");
    let mut renders = Vec::new();
    for (vi, view) in views.iter().enumerate() {
        renders.push(parallel::render_view(&pool, &scene, view, vi as u32, &final_settings, &bar));
    }
    bar.finish_and_clear();
    stages.push(StageReport {
        stage: "final render".into(),
        evaluations: 1,
        samples_per_pixel: final_settings.spp,
        seconds: final_start.elapsed().as_secs_f64(),
        notes: vec!["every view rendered with the recovered model; final_error comes from it".into()],
    });

    // Write everything, each file atomically.
    let out = &args.out;
    fsutil::create_dir(&out.join("views"))?;
    fsutil::create_dir(&out.join("errors"))?;
    for (vi, pixels) in renders.iter().enumerate() {
        let name = &owned.desc.views[vi].name;
        let view = &views[vi];
        let image = Image { width: view.width, height: view.height, pixels: pixels.iter().map(|p| p.to_array()).collect() };
        images::write_exr(&out.join("views").join(format!("{name}.exr")), &image)?;
        images::write_png_preview(&out.join("views").join(format!("{name}.png")), &image, None)?;
        // |render - real| per channel: where the fit is poor.
        let diff = Image {
            width: view.width,
            height: view.height,
            pixels: image
                .pixels
                .iter()
                .zip(&real[vi].pixels)
                .map(|(a, b)| [(a[0] - b[0]).abs(), (a[1] - b[1]).abs(), (a[2] - b[2]).abs()])
                .collect(),
        };
        images::write_exr(&out.join("errors").join(format!("{name}.exr")), &diff)?;
        images::write_png_preview(&out.join("errors").join(format!("{name}.png")), &diff, None)?;
    }
    let materials_path = out.join("materials.toml");
    let materials = MaterialsDesc {
        path: materials_path.clone(),
        materials: groups
            .iter()
            .filter(|g| g.model != "unseen")
            .map(|g| MaterialDesc {
                group: g.group.clone(),
                model: Model::Diffuse,
                color: Some(g.color.map(|c| c as f32)),
                specularity: Some(0.0),
                roughness: Some(0.0),
                roughness_u: None,
                roughness_v: None,
                direction_u: None,
                diffuse_map: None,
                line: 0,
            })
            .collect(),
    };
    crate::materials_file::write_materials(&materials_path, &materials)?;
    fsutil::write_atomic(&out.join("materials.rad"), materials_rad(&materials).as_bytes())?;

    let report = RecoverReport {
        scene: args.scene.display().to_string(),
        seed: args.seed,
        effort: format!("{:?}", args.effort).to_lowercase(),
        error_definition: "sqrt(max(0, sum |R-T|^2 - sum var(R)) / sum |T|^2) over the group's pure pixels, RGB pooled (relume_core::fit)",
        thresholds: serde_json::json!({
            "DIFFUSE_THRESHOLD": fit::DIFFUSE_THRESHOLD,
            "DIFFUSE_CONVERGED": fit::DIFFUSE_CONVERGED,
            "MIN_PIXELS_FOR_MODEL_CHOICE": fit::MIN_PIXELS_FOR_MODEL_CHOICE,
        }),
        stages,
        groups,
        warnings,
        seconds: start.elapsed().as_secs_f64(),
    };
    let text = serde_json::to_string_pretty(&report).map_err(|e| Error::Usage(e.to_string()))?;
    fsutil::write_atomic(&out.join("report.json"), text.as_bytes())?;
    Ok(report)
}

/// The materials as RADIANCE primitives (`void plastic <group> 0 0 5 r g b spec rough`...).
pub fn materials_rad(m: &MaterialsDesc) -> String {
    let mut s = String::from("# relume: recovered materials as RADIANCE primitives\n");
    for d in &m.materials {
        let c = d.color.unwrap_or([1.0; 3]);
        match d.model {
            Model::Diffuse => s.push_str(&format!(
                "\nvoid plastic {}\n0\n0\n5 {} {} {} 0 0\n",
                d.group, c[0], c[1], c[2]
            )),
            _ => s.push_str(&format!("\n# {}: model not expressible yet\n", d.group)),
        }
    }
    s
}
