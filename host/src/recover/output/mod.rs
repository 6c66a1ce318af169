//! Everything `recover` writes, as one [`OutputSet`]: materials.toml, materials.rad,
//! report.json, the diffuse maps, the re-rendered views and per-view error images, and
//! unseen.toml when some group is not recovered. A failure on any file leaves none of
//! them, so a folder never mixes two runs' outputs. What RADIANCE is given is `radiance`'s.

use std::path::{Path, PathBuf};

use glam::Vec3;

use super::model::GroupModel;
use super::{RecoverReport, Recovery};
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::images::{self, Image};
use crate::materials_file::{self, MaterialsDesc};
use crate::parallel;
use crate::scene_file::GroupKind;

mod radiance;

pub(super) use radiance::Obj2radNames;
use radiance::{add_maps_and_radiance, mesh_path};

/// The final views, rendered twice with independent samples: what the views and error
/// images show is their mean; the two halves give each group's bias-only error
/// ([`pixels::fits_of_halves`](super::pixels::fits_of_halves)), in which the render's noise
/// has no part.
pub(super) struct FinalRenders {
    /// Per view, the mean of the two halves.
    pub mean: Vec<Vec<Vec3>>,
    /// Per half, per view, its pixels.
    pub halves: [Vec<Vec<Vec3>>; 2],
    /// Samples per pixel of each half.
    pub spp_per_half: u32,
}

/// Renders every view with the current models at `spp` samples per pixel in all, as two
/// independent halves of `spp / 2` (rounded up) each ([`FinalRenders`]).
pub(super) fn render_views(rec: &mut Recovery, spp: u32, seed: u64) -> Result<FinalRenders, Error> {
    rec.apply_models();
    let spp_per_half = spp.div_ceil(2);
    let (a, b) = super::pixels::cross_settings(&relume_core::render::RenderSettings {
        spp: spp_per_half.saturating_mul(2),
        seed,
        ..Default::default()
    });
    let total_rows: u64 = rec.views.iter().map(|v| v.height as u64).sum();
    let bar = super::progress_bar(2 * total_rows, "final render");
    let views = rec.views.clone();
    let scene = rec.owned.build()?;
    let halves = [a, b].map(|settings| {
        views
            .iter()
            .enumerate()
            .map(|(vi, view)| {
                parallel::render_view(&rec.pool, &scene, view, vi as u32, &settings, &bar)
            })
            .collect::<Vec<_>>()
    });
    bar.finish_and_clear();
    let mean = halves[0]
        .iter()
        .zip(&halves[1])
        .map(|(a, b)| a.iter().zip(b).map(|(a, b)| 0.5 * (*a + *b)).collect())
        .collect();
    Ok(FinalRenders {
        mean,
        halves,
        spp_per_half,
    })
}

/// The output set of a recovery into `out`, with its folders made: called before the
/// recovery, so that an output folder that cannot be made fails in a moment rather than
/// after minutes of work (the set removes the folders again if the run fails or is
/// interrupted).
pub(super) fn prepare(
    out: &Path,
    inputs: Vec<(PathBuf, String)>,
    view_names: &[String],
    group_names: &[String],
) -> Result<OutputSet, Error> {
    let mut set = OutputSet::keeping(inputs);
    // None of the files it may write or remove may replace an input (the set checks again
    // as each is written).
    set.check_targets(output_files(out, view_names, group_names))?;
    set.create_dir(&out.join(VIEWS_DIR))?;
    set.create_dir(&out.join(ERRORS_DIR))?;
    Ok(set)
}

/// Every file a recovery into `out` may write or remove: its materials and report, each
/// view's render and error image with their previews, and every group's map files (which
/// groups get maps depends on the recovery; an earlier run's are removed).
pub fn output_files(out: &Path, view_names: &[String], group_names: &[String]) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = [
        MATERIALS_TOML,
        MATERIALS_RAD,
        MATERIALS_MAP,
        REPORT_JSON,
        UNSEEN_TOML,
    ]
    .map(|f| out.join(f))
    .into();
    for dir in [VIEWS_DIR, ERRORS_DIR] {
        for name in view_names {
            files.extend(images::exr_and_preview_paths(&out.join(dir), name));
        }
    }
    files.extend(group_names.iter().flat_map(|name| map_files(out, name)));
    files
}

/// The files and folders of a recovery's output folder.
const MATERIALS_TOML: &str = "materials.toml";
const MATERIALS_RAD: &str = "materials.rad";
/// obj2rad's mapping rules (`obj2rad -m`): each OBJ object's faces named after its
/// group's (or light's) primitive in materials.rad.
const MATERIALS_MAP: &str = "materials.map";
const REPORT_JSON: &str = "report.json";
/// The stand-ins of the unseen groups, apart from materials.toml, which holds only what
/// was recovered.
pub const UNSEEN_TOML: &str = "unseen.toml";
const VIEWS_DIR: &str = "views";
const ERRORS_DIR: &str = "errors";
const TEXTURES_DIR: &str = "textures";
/// Curved textured groups' faces, for obj2mesh (`add_maps_and_radiance`).
const MESHES_DIR: &str = "meshes";

/// Writes everything into `set` (from [`prepare`]) and commits it.
pub(super) fn write_all(
    mut set: OutputSet,
    out: &Path,
    rec: &Recovery,
    renders: &[Vec<Vec3>],
    report: &RecoverReport,
    obj2rad: &Obj2radNames,
) -> Result<(), Error> {
    for (vi, pixels) in renders.iter().enumerate() {
        let name = &rec.owned.desc.views[vi].name;
        let view = &rec.views[vi];
        let image = Image {
            width: view.width,
            height: view.height,
            pixels: pixels.iter().map(|p| p.to_array()).collect(),
        };
        images::add_exr_and_preview(&mut set, &out.join(VIEWS_DIR), name, &image)?;
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
        images::add_exr_and_preview(&mut set, &out.join(ERRORS_DIR), name, &diff)?;
    }
    let names = &rec.owned.group_names;
    let map_path = |g: usize| out.join(TEXTURES_DIR).join(format!("{}.exr", names[g]));
    add_maps_and_radiance(&mut set, out, rec, obj2rad)?;
    // An earlier recovery's map of a group this one did not map, and its renders of views
    // this scene lacks (an earlier run of another scene), are no outputs of this run.
    for (dir, extensions) in WRITTEN {
        set.remove_unwritten_on_commit(&out.join(dir), extensions);
    }
    let materials_path = out.join(MATERIALS_TOML);
    let materials = MaterialsDesc {
        path: materials_path.clone(),
        materials: rec
            .models
            .iter()
            .enumerate()
            .filter_map(|(g, m)| {
                let path = matches!(m, GroupModel::Textured { .. }).then(|| map_path(g));
                let mut d = m.material_desc(&names[g], path.as_deref())?;
                if let GroupModel::Textured { map, .. } = m {
                    d.map_wrap = rec.maps[*map].wrap;
                }
                // scene.toml does not say which kind a group of kind "auto" turned out.
                if rec.owned.desc.groups[g].kind == GroupKind::Auto {
                    d.kind = m.lobe_kind();
                }
                Some(d)
            })
            .collect(),
    };
    let toml = materials_file::materials_text(&materials_path, &materials)?;
    set.add(&materials_path, toml.as_bytes())?;
    add_unseen_stand_ins(&mut set, &out.join(UNSEEN_TOML), &rec.models, names)?;
    let text = serde_json::to_string_pretty(report).map_err(|e| Error::Usage(e.to_string()))?;
    set.add(&out.join(REPORT_JSON), text.as_bytes())?;
    set.commit()
}

/// Writes `path` with the diffuse stand-in every unseen group was rendered with, so that
/// the recovered scene can be rendered again at once (`--materials materials.toml
/// unseen.toml`), or removes an earlier run's file when no group is unseen. Kept apart
/// from materials.toml: these materials are not recovered.
fn add_unseen_stand_ins(
    set: &mut OutputSet,
    path: &Path,
    models: &[GroupModel],
    group_names: &[String],
) -> Result<(), Error> {
    let materials: Vec<_> = models
        .iter()
        .zip(group_names)
        .filter_map(|(m, name)| match *m {
            GroupModel::Unseen { stand_in } => {
                GroupModel::Diffuse { color: stand_in }.material_desc(name, None)
            }
            _ => None,
        })
        .collect();
    if materials.is_empty() {
        if path.is_file() {
            set.remove_on_commit(path)?;
        }
        return Ok(());
    }
    let desc = MaterialsDesc {
        path: path.to_path_buf(),
        materials,
    };
    let text = format!(
        "# relume: NOT recovered. The groups that no view sees whole or no light reaches,\n\
         # as the diffuse stand-ins the recovery rendered them with: a colour measured on\n\
         # the pixels each shares with groups of known material, or a neutral grey where\n\
         # none could be (report.json says which). Render the scene with\n\
         # `--materials materials.toml unseen.toml`.\n{}",
        materials_file::materials_text(path, &desc)?
    );
    set.add(path, text.as_bytes())
}

/// The folders of a recovery's outputs and the kinds of file it writes there: of these,
/// the files a recovery does not write are stale ([`OutputSet::remove_unwritten_on_commit`])
/// — an earlier recovery's renders of views this scene lacks and maps this recovery did
/// not make, which its materials do not name, and every mesh obj2mesh made (`.rtm`),
/// which holds the materials of the run it was made from. Files of other kinds, and the
/// run's inputs, are left alone.
const WRITTEN: [(&str, &[&str]); 4] = [
    (VIEWS_DIR, &["exr", "png"]),
    (ERRORS_DIR, &["exr", "png"]),
    (TEXTURES_DIR, &["exr", "hdr", "cal"]),
    (MESHES_DIR, &["obj", "rtm"]),
];

/// The files a recovery into `out` writes (or removes) for a mapped group `name`: its
/// map, its RADIANCE picture and mapping, and a curved group's mesh faces and an earlier
/// run's mesh of them.
fn map_files(out: &Path, name: &str) -> Vec<PathBuf> {
    let pictures =
        ["exr", "hdr", "cal"].map(|ext| out.join(TEXTURES_DIR).join(format!("{name}.{ext}")));
    let meshes = ["obj", "rtm"].map(|ext| mesh_path(out, name, ext));
    pictures.into_iter().chain(meshes).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Of an earlier run's outputs, those this run does not write again are stale and
    /// removed at its commit: maps of groups it did not map, of this scene or another's,
    /// and the renders and error images of views it lacks (a recovery of another scene
    /// into the same folder left them beside this one's). A file of another kind in those
    /// folders, and an input of the run, are not the recovery's to remove.
    #[test]
    fn an_earlier_runs_outputs_that_this_run_does_not_write_are_stale() {
        let dir = tempfile::tempdir().unwrap();
        let files = [
            "textures/picture.exr",
            "textures/picture.hdr",
            "textures/picture.cal",
            "textures/statue.exr",
            "textures/wall.exr",
            "textures/notes.txt",
            "views/px.exr",
            "views/px.png",
            "views/lamp.exr",
            "views/lamp.png",
            "views/pano_nz.exr",
            "errors/lamp.exr",
            "errors/lamp.png",
        ];
        for file in files {
            let path = dir.path().join(file);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, b"earlier run").unwrap();
        }
        let panorama = dir.path().join("views/pano_nz.exr");
        let mut set = OutputSet::keeping(vec![(panorama, "the panorama".into())]);
        for file in ["textures/wall.exr", "views/px.exr", "views/px.png"] {
            set.add(&dir.path().join(file), b"this run").unwrap();
        }
        for (folder, extensions) in WRITTEN {
            set.remove_unwritten_on_commit(&dir.path().join(folder), extensions);
        }
        // Found at the commit: a map another run wrote meanwhile goes too.
        std::fs::write(dir.path().join("textures/door.exr"), b"another run").unwrap();
        set.commit().unwrap();
        let mut left: Vec<String> = files
            .iter()
            .chain(&["textures/door.exr"])
            .filter(|f| dir.path().join(f).exists())
            .map(|f| f.to_string())
            .collect();
        left.sort();
        assert_eq!(
            left,
            [
                "textures/notes.txt",
                "textures/wall.exr",
                "views/pano_nz.exr",
                "views/px.exr",
                "views/px.png"
            ]
        );
        assert_eq!(
            std::fs::read(dir.path().join("views/px.exr")).unwrap(),
            b"this run"
        );
    }
}
