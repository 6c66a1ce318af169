//! `relume render`: renders every view of a scene with given materials, writing one
//! linear EXR and one tone-mapped PNG preview per view, and `render.json` with the
//! settings and timing.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use glam::Vec3;
use relume_core::geometry::View;
use relume_core::render::RenderSettings;
use relume_core::scene::Scene;

use crate::assemble::{self, MaterialSource};
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::images::{self, Image};
use crate::materials_file;
use crate::parallel;
use crate::scene_file::SceneDesc;

/// The settings and timing of a render, beside its views.
const RENDER_JSON: &str = "render.json";

#[derive(clap::Args)]
pub struct RenderArgs {
    /// The scene.toml to render.
    pub scene: PathBuf,
    /// materials.toml file(s); every group must get exactly one material.
    #[arg(long, required = true, num_args = 1..)]
    pub materials: Vec<PathBuf>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Random seed: the same seed gives the same bytes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default: all cores); the result does not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Render only these views (by name).
    #[arg(long = "view")]
    pub views: Vec<String>,
}

/// Timing of a render, for the summary line and render.json.
pub struct RenderSummary {
    pub samples: u64,
    pub seconds: f64,
    /// What a user should look at although the render succeeded.
    pub warnings: Vec<String>,
}

/// The files a render of `views` into `out` writes: each view's EXR and preview, and
/// render.json.
pub fn output_files<'a>(out: &Path, views: impl IntoIterator<Item = &'a str>) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = views
        .into_iter()
        .flat_map(|name| images::exr_and_preview_paths(out, name))
        .collect();
    files.push(out.join(RENDER_JSON));
    files
}

/// From this many samples a pixel a render first times a pilot ([`estimate_time`]).
const PILOT_FROM_SPP: u32 = 64;

/// A pilot renders at least this many samples, so that starting its threads does not
/// count for much of its time.
const PILOT_SAMPLES: u64 = 1 << 16;

/// A render estimated to take this long is announced with its estimate.
const ANNOUNCE_PAST_SECONDS: f64 = 60.0;

/// How long a render will take, from a pilot.
struct Estimate {
    seconds: f64,
    samples: u64,
    pilot_spp: u32,
}

/// Times every selected view at a fraction of the samples (at most 1/64 of them, at least
/// [`PILOT_SAMPLES`] in all) and scales by the render's samples: the bar's estimate comes
/// only as rows are done, and a view of one row at 4e9 samples a pixel gave none. Every
/// view, since views differ in cost (one looking away from the room took the first view's
/// pilot to say nothing of a render of 83 s). `None` below [`PILOT_FROM_SPP`], and where
/// the pilot would be smaller than [`PILOT_SAMPLES`] (it would time starting its threads;
/// such a render is over in seconds). The pilot's pixels are dropped, so the render's are
/// the same.
fn estimate_time(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    views: &[View],
    selected: &[usize],
    settings: &RenderSettings,
) -> Option<Estimate> {
    if settings.spp < PILOT_FROM_SPP {
        return None;
    }
    let pixels: u64 = selected.iter().map(|&i| views[i].n_pixels() as u64).sum();
    let wanted = PILOT_SAMPLES.div_ceil(pixels.max(1));
    let pilot_spp = wanted.min((settings.spp / PILOT_FROM_SPP) as u64) as u32;
    if pixels * (pilot_spp as u64) < PILOT_SAMPLES {
        return None;
    }
    let pilot = RenderSettings {
        spp: pilot_spp,
        ..*settings
    };
    let hidden = indicatif::ProgressBar::hidden();
    let start = Instant::now();
    for &i in selected {
        parallel::render_view(pool, scene, &views[i], i as u32, &pilot, &hidden);
    }
    let per_sample = start.elapsed().as_secs_f64() / (pixels * pilot_spp as u64) as f64;
    let samples = pixels * settings.spp as u64;
    Some(Estimate {
        seconds: per_sample * samples as f64,
        samples,
        pilot_spp,
    })
}

pub fn run(args: &RenderArgs) -> Result<RenderSummary, Error> {
    if args.spp == 0 {
        return Err(Error::Usage("--spp must be at least 1".into()));
    }
    // Read and check every input before writing anything.
    if let Some((m, first)) = crate::fsutil::given_twice(&args.materials) {
        return Err(Error::Usage(format!(
            "{} is given twice to --materials (also as {}): each of its groups would have two materials",
            m.display(),
            first.display()
        )));
    }
    let mut files = Vec::new();
    for m in &args.materials {
        files.push(materials_file::load_materials(m)?);
    }
    let mut owned = assemble::load_and_assemble(&args.scene, MaterialSource::Files(&files))?;
    owned.select_views(&args.views)?;
    let mut placement = owned.crossing_face_warnings.clone();
    placement.extend(crate::light_placement::lights_against_surfaces(&mut owned)?);
    placement.extend(crate::repeated_triangles::repeated_triangle_warnings(
        owned.triangles(),
        &owned.group_names,
    ));
    placement.extend(crate::overlapping_faces::overlapping_face_warnings(
        &mut owned,
    )?);
    let fallbacks: Vec<String> = owned
        .isotropic_fallbacks()
        .into_iter()
        .map(|(g, share)| {
            format!(
                "group '{}': its direction_u is parallel to the surface normal over {:.0}% of its area, where the anisotropic lobe renders isotropic (reflectance.md): give a direction along the surface",
                owned.group_names[g],
                100.0 * share
            )
        })
        .collect();
    let clamped_tiles = owned.clamped_tile_warnings();
    let map_energy = owned.map_energy_warnings(&files);
    let mut inputs = owned.desc.input_files();
    inputs.extend(files.iter().flat_map(|f| f.input_files()));
    let pool = parallel::thread_pool(args.threads)?;
    let view_descs = owned.desc.views.clone();
    let views = owned.views.clone();
    let (light_names, group_names) = (owned.light_names.clone(), owned.group_names.clone());
    let scene = owned.build()?;
    let settings = RenderSettings {
        spp: args.spp,
        seed: args.seed,
        ..RenderSettings::default()
    };

    let selected: Vec<usize> = (0..views.len())
        .filter(|&i| SceneDesc::view_selected(&args.views, &view_descs[i].name))
        .collect();
    // One set: a failure on any file leaves none of this render's outputs. Each view is
    // staged as soon as it is rendered, so that only one view's pixels are held at a time.
    // Before a long render, not after: no output may replace an input (a render into
    // the panorama's folder would put itself over the views' images), and the folder must
    // be made.
    let mut set = OutputSet::keeping(inputs);
    set.check_targets(output_files(
        &args.out,
        selected.iter().map(|&i| view_descs[i].name.as_str()),
    ))?;
    set.create_dir(&args.out)?;
    // Timed once the outputs are known to be writable, before the bar is drawn.
    if let Some(estimate) = estimate_time(&pool, &scene, &views, &selected, &settings) {
        if estimate.seconds >= ANNOUNCE_PAST_SECONDS {
            eprintln!(
                "relume: render: {} samples, about {} (timed on {} samples a pixel)",
                estimate.samples,
                indicatif::HumanDuration(Duration::from_secs_f64(estimate.seconds.min(1e12))),
                estimate.pilot_spp,
            );
        }
    }
    let total_rows: u64 = selected.iter().map(|&i| views[i].height as u64).sum();
    let progress = crate::progress::bar(total_rows, "render", "rows");
    let mut seconds = 0.0;
    let mut samples = 0u64;
    let mut black_views = Vec::new();
    for &i in &selected {
        progress.set_message(format!("render {}", view_descs[i].name));
        let start = Instant::now();
        let pixels =
            parallel::render_view(&pool, &scene, &views[i], i as u32, &settings, &progress);
        // Rendering alone, so that samples per second measure the renderer.
        seconds += start.elapsed().as_secs_f64();
        samples += views[i].n_pixels() as u64 * settings.spp as u64;
        if pixels.iter().all(|p| *p == Vec3::ZERO) {
            black_views.push(i);
        }
        let image = Image {
            width: views[i].width,
            height: views[i].height,
            // The same layout: collected in place, not copied.
            pixels: pixels.into_iter().map(<[f32; 3]>::from).collect(),
        };
        images::add_exr_and_preview(&mut set, &args.out, &view_descs[i].name, &image)?;
    }
    progress.finish_and_clear();
    let mut warnings = placement;
    warnings.extend(fallbacks);
    warnings.extend(clamped_tiles);
    warnings.extend(files.iter().flat_map(|f| f.roughness_warnings()));
    warnings.extend(map_energy);
    // A file that gives no material changes nothing: most likely the wrong file was given.
    warnings.extend(
        args.materials
            .iter()
            .zip(&files)
            .filter(|(_, file)| file.materials.is_empty())
            .map(|(path, _)| {
                format!(
                    "{} has no [[material]]: it changes nothing (the wrong file?)",
                    path.display()
                )
            }),
    );
    let all_black = black_views.len() == selected.len();
    if all_black
        && !black_views
            .iter()
            .any(|&i| sees_geometry(&scene, &views[i]))
    {
        // A scene in other units than its views, or cameras outside it: not the lights.
        warnings.push(format!(
            "every pixel is black: the views of {} see no geometry (a ray through each pixel's centre escapes the scene): are the cameras inside the scene and facing it, and the OBJ in the units of the views' positions?",
            args.scene.display()
        ));
    } else if all_black {
        let enclosed = crate::enclosed_views::enclosed_lights_said(
            scene.triangles,
            &views,
            &light_names,
            &group_names,
        );
        warnings.push(format!(
            "every pixel is black: no light of {} reaches what the views see (a light hidden, of radiance 0, or facing away? Or the cameras outside the room or inside an object, seeing the backs of surfaces no light reaches?){enclosed}",
            args.scene.display()
        ));
    } else {
        // One view black among lit ones is a camera outside the scene or facing nothing.
        warnings.extend(black_views.iter().map(|&i| {
            let name = &view_descs[i].name;
            format!("view '{name}': every pixel is black while other views are not: is its camera outside the scene or looking at nothing?")
        }));
    }
    // Views of earlier renders into the same folder (`--view`) stay: say which are this one's.
    let rendered: Vec<&str> = selected
        .iter()
        .map(|&i| view_descs[i].name.as_str())
        .collect();
    let earlier: Vec<&str> = (view_descs.iter())
        .map(|v| v.name.as_str())
        .filter(|n| !rendered.contains(n) && args.out.join(format!("{n}.exr")).is_file())
        .collect();
    if !earlier.is_empty() {
        warnings.push(format!(
            "{} also holds views {} from an earlier render, which this one (--view) leaves as they were; render.json lists this render's, and `panorama join` of the folder would join both",
            args.out.display(),
            earlier.join(", ")
        ));
    }

    let info = serde_json::json!({
        "scene": args.scene.display().to_string(),
        "materials": args.materials.iter().map(|m| m.display().to_string()).collect::<Vec<_>>(),
        "spp": args.spp,
        "seed": args.seed,
        "views": rendered,
        "threads": pool.current_num_threads(),
        "samples": samples,
        "seconds": seconds,
        "samples_per_second": samples as f64 / seconds.max(1e-9),
        "warnings": warnings,
    });
    let text = serde_json::to_string_pretty(&info).map_err(|e| Error::Usage(e.to_string()))?;
    set.add(&args.out.join(RENDER_JSON), text.as_bytes())?;
    set.commit()?;
    Ok(RenderSummary {
        samples,
        seconds,
        warnings,
    })
}

/// Whether a ray through the centre of any pixel of `view` meets the scene.
fn sees_geometry(scene: &Scene, view: &View) -> bool {
    (0..view.height).any(|y| {
        (0..view.width).any(|x| {
            let ray = view.ray(x as f32 + 0.5, y as f32 + 0.5);
            scene.intersect(&ray, f32::INFINITY).is_some()
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Below [`PILOT_FROM_SPP`] no pilot; above it, one over every selected view of at most
    /// 1/64 of the samples a pixel and at least [`PILOT_SAMPLES`] in all, and none where
    /// that is not enough samples to time.
    #[test]
    fn a_long_render_is_estimated_from_a_small_pilot() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.toml");
        let mut owned = assemble::load_and_assemble(&path, MaterialSource::GeometryOnly).unwrap();
        let views = owned.views.clone();
        let scene = owned.build().unwrap();
        let pool = parallel::thread_pool(Some(2)).unwrap();
        let at = |spp: u32, selected: &[usize]| {
            let settings = RenderSettings {
                spp,
                ..RenderSettings::default()
            };
            estimate_time(&pool, &scene, &views, selected, &settings)
        };
        assert!(at(PILOT_FROM_SPP - 1, &[0]).is_none());
        let pixels = views[0].n_pixels() as u64;
        // 1024 pixels a view: 64 samples a pixel give 1 for the pilot, too few to time.
        assert!(at(PILOT_FROM_SPP, &[0, 1]).is_none());
        let spp = 64 * PILOT_FROM_SPP;
        let e = at(spp, &[0, 1]).unwrap();
        assert_eq!(e.pilot_spp as u64, PILOT_SAMPLES.div_ceil(2 * pixels));
        assert_eq!(e.samples, 2 * pixels * spp as u64);
        let e = at(u32::MAX, &[2]).unwrap();
        assert_eq!(e.pilot_spp as u64, PILOT_SAMPLES.div_ceil(pixels));
        assert_eq!(e.samples, pixels * u32::MAX as u64);
        assert!(e.seconds > 0.0 && e.seconds.is_finite(), "{}", e.seconds);
    }
}
