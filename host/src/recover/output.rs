//! Everything `recover` writes, as one [`OutputSet`]: materials.toml, materials.rad,
//! report.json, the diffuse maps, the re-rendered views and per-view error images, and
//! unseen.toml when some group is not recovered. A failure on any file leaves none of
//! them, so a folder never mixes two runs' outputs.

use std::path::{Path, PathBuf};

use glam::Vec3;

use super::model::GroupModel;
use super::{texture, RecoverReport, Recovery};
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::images::{self, Image};
use crate::materials_file::{self, MaterialsDesc};
use crate::parallel;
use crate::scene_file::{GroupKind, SceneDesc};

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

/// Writes everything into `set` (from [`prepare`]) and commits it.
pub(super) fn write_all(
    mut set: OutputSet,
    out: &Path,
    rec: &Recovery,
    renders: &[Vec<Vec3>],
    report: &RecoverReport,
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
    let mut rad = String::from("# relume: recovered materials as RADIANCE primitives\n");
    for (g, model) in rec.models.iter().enumerate() {
        let name = &names[g];
        // What RADIANCE is given: the model itself, under the modifier of its map when
        // it has one it can place.
        let mut primitive = (*model, String::from("void"));
        if let GroupModel::Textured { map, lobe } = *model {
            let specularity = lobe.specularity();
            set.create_dir(&out.join(TEXTURES_DIR))?;
            let map = &rec.maps[map];
            let image = Image {
                width: map.side,
                height: map.side,
                pixels: map.texels.iter().map(|t| t.to_array()).collect(),
            };
            images::add_exr(&mut set, &map_path(g), &image)?;
            match texture::uv_affine(rec, g) {
                Some(affine) => {
                    add_radiance_picture(&mut set, out, name, &image, specularity, &affine)?;
                    primitive.1 = pattern_name(name, names);
                    rad.push_str(&format!(
                        "\nvoid colorpict {}\n7 red green blue textures/{name}.hdr textures/{name}.cal pic_u pic_v\n0\n0\n",
                        primitive.1
                    ));
                }
                None => {
                    rad.push_str(&format!(
                        "\n# {name}: its texture coordinates are not an affine function of the surface point (a curved group), which a RADIANCE colorpict on polygons cannot reproduce; the map's mean colour is used\n"
                    ));
                    let mean = map.texels.iter().fold(Vec3::ZERO, |a, b| a + *b)
                        / map.texels.len().max(1) as f32;
                    let color = mean / (1.0 - specularity as f32).max(1e-3);
                    primitive.0 = lobe.with_color(color.to_array().map(f64::from));
                }
            }
        }
        // Unseen: the stand-in the recovery rendered it with (unseen.toml), so that the
        // scene loads (oconv stopped at "undefined modifier" for a group of no primitive).
        if let GroupModel::Unseen { stand_in } = primitive.0 {
            let [r, g, b] = stand_in;
            rad.push_str(&format!(
                "\n# {name}: unseen, not recovered; the diffuse stand-in [{r:.4} {g:.4} {b:.4}] the recovery rendered it with (unseen.toml, report.json)\n"
            ));
            primitive.0 = GroupModel::Diffuse { color: stand_in };
        }
        if let GroupModel::Mirror { .. } = primitive.0 {
            rad.push_str(&format!(
                "\n# {name}: RADIANCE's mirror reflects from its front only (where its vertices turn counter-clockwise) and is black from behind; relume's from both sides\n"
            ));
        }
        // Every model has a primitive now (an unseen group's stand-in is a diffuse).
        if let Some(p) = primitive.0.radiance_primitive(name, &primitive.1) {
            rad.push('\n');
            rad.push_str(&p);
        }
    }
    // An earlier recovery's map of a group this one did not map, and its renders of views
    // this scene lacks (an earlier run of another scene), are no outputs of this run.
    for path in stale_outputs(&set, out) {
        set.remove_on_commit(&path)?;
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
    rad.push_str(&light_primitives(&rec.owned.desc, names));
    set.add(&out.join(MATERIALS_RAD), rad.as_bytes())?;
    set.add(
        &out.join(MATERIALS_MAP),
        obj2rad_map(&rec.owned.desc, names).as_bytes(),
    )?;
    let text = serde_json::to_string_pretty(report).map_err(|e| Error::Usage(e.to_string()))?;
    set.add(&out.join(REPORT_JSON), text.as_bytes())?;
    set.commit()
}

/// The name of light object `object`'s primitive in materials.rad: `light_<object>`, made
/// longer while a group has that name.
fn light_name(object: &str, groups: &[String]) -> String {
    let mut name = format!("light_{object}");
    while groups.contains(&name) {
        name.insert(0, '_');
    }
    name
}

/// The scene's lights as RADIANCE `light` primitives (radiance in W sr^-1 m^-2 per channel,
/// as scene.toml gives it), so that materials.rad with the geometry is a whole scene.
fn light_primitives(desc: &SceneDesc, groups: &[String]) -> String {
    let mut text = String::new();
    for light in desc
        .lights
        .iter()
        .filter(|l| !desc.hide.contains(&l.object))
    {
        let [r, g, b] = light.radiance;
        text.push_str(&format!(
            "\n# light '{}' as scene.toml declares it\nvoid light {}\n0\n0\n3 {r} {g} {b}\n",
            light.object,
            light_name(&light.object, groups)
        ));
    }
    text
}

/// obj2rad's mapping rules: `obj2rad -m materials.map geometry.obj > geometry.rad` names
/// each object's faces after its group's primitive in materials.rad, or its light's
/// (without it, obj2rad names faces by `usemtl`, `g`, or "white"). Hidden objects are
/// no part of the recovered scene and get no rule.
fn obj2rad_map(desc: &SceneDesc, groups: &[String]) -> String {
    let mut text = String::from(
        "# relume: obj2rad -m materials.map <geometry.obj> > geometry.rad names each object's faces\n\
         # after its group's material in materials.rad; then oconv materials.rad geometry.rad\n",
    );
    let shown = |object: &&String| !desc.hide.contains(*object);
    for group in &desc.groups {
        for object in group.objects.iter().filter(shown) {
            text.push_str(&format!("{} (Object \"{object}\") ;\n", group.name));
        }
    }
    for light in desc.lights.iter().filter(|l| shown(&&l.object)) {
        text.push_str(&format!(
            "{} (Object \"{}\") ;\n",
            light_name(&light.object, groups),
            light.object
        ));
    }
    text
}

/// The name of group `name`'s picture pattern in materials.rad: `pict_<name>`, made longer
/// while a group has that name (RADIANCE binds a name to its last definition, and the
/// group `pict_X` rendered X's surfaces invisible).
fn pattern_name(name: &str, groups: &[String]) -> String {
    let mut pattern = format!("pict_{name}");
    while groups.contains(&pattern) {
        pattern.insert(0, '_');
    }
    pattern
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

/// The files of `out/views`, `out/errors` (`.exr`, `.png`) and `out/textures` (`.exr`,
/// `.hdr`, `.cal`) that `set` does not write: an earlier recovery's renders of views this
/// scene lacks and maps this recovery did not make, which its materials do not name.
/// Files of other kinds, and the run's inputs, are left alone.
fn stale_outputs(set: &OutputSet, out: &Path) -> Vec<PathBuf> {
    let written = [
        (VIEWS_DIR, &["exr", "png"][..]),
        (ERRORS_DIR, &["exr", "png"]),
        (TEXTURES_DIR, &["exr", "hdr", "cal"]),
    ];
    let mut stale = Vec::new();
    for (dir, extensions) in written {
        let Ok(entries) = std::fs::read_dir(out.join(dir)) else {
            continue;
        };
        let mut found: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| extensions.contains(&e))
            })
            // An input of this run (a panorama kept there under other names) stays.
            .filter(|p| p.is_file() && !set.stages(p) && set.check_target(p).is_ok())
            .collect();
        found.sort();
        stale.extend(found);
    }
    stale
}

/// The files a recovery into `out` writes for a mapped group `name`: its map, and its
/// RADIANCE picture and mapping.
fn map_files(out: &Path, name: &str) -> [PathBuf; 3] {
    ["exr", "hdr", "cal"].map(|ext| out.join(TEXTURES_DIR).join(format!("{name}.{ext}")))
}

/// The RADIANCE picture and mapping of a textured group: `textures/<group>.hdr` holds the
/// map over (1 - s) (RADIANCE's plastic multiplies the picture by its colour and (1 - s));
/// `textures/<group>.cal` turns the hit point into the OBJ (u, v) and remaps it so that
/// RADIANCE, which interpolates between the first and last texel over [0, 1], samples the
/// texel centres where the OBJ convention puts them (as in the references' tex_*.cal).
fn add_radiance_picture(
    set: &mut OutputSet,
    out: &Path,
    name: &str,
    map: &Image,
    specularity: f64,
    affine: &texture::UvAffine,
) -> Result<(), Error> {
    let scale = 1.0 / (1.0 - specularity as f32).max(1e-3);
    let picture = Image {
        width: map.width,
        height: map.height,
        pixels: map.pixels.iter().map(|p| p.map(|c| c * scale)).collect(),
    };
    let hdr = out.join(TEXTURES_DIR).join(format!("{name}.hdr"));
    set.add(&hdr, &images::hdr_bytes(&hdr, &picture)?)?;
    let (o, gu, gv) = (affine.origin, affine.grad_u, affine.grad_v);
    let cal = format!(
        "{{ relume: OBJ (u, v) of group {name} as an affine function of the hit point }}\n\
         N = {n};\n\
         obj_u = {u0} + (Px-({ox}))*({gux}) + (Py-({oy}))*({guy}) + (Pz-({oz}))*({guz});\n\
         obj_v = {v0} + (Px-({ox}))*({gvx}) + (Py-({oy}))*({gvy}) + (Pz-({oz}))*({gvz});\n\
         {{ held to the picture, as relume's lookup clamps at the border: RADIANCE\n\
            extrapolates a picture past its edge, then tapers it to black }}\n\
         unit(x) = if(x, if(x - 1, 1, x), 0);\n\
         pic_u = unit((obj_u*N - .5)/(N - 1));\n\
         pic_v = unit((obj_v*N - .5)/(N - 1));\n",
        n = map.width,
        u0 = affine.uv0[0],
        v0 = affine.uv0[1],
        ox = o.x,
        oy = o.y,
        oz = o.z,
        gux = gu.x,
        guy = gu.y,
        guz = gu.z,
        gvx = gv.x,
        gvy = gv.y,
        gvz = gv.z,
    );
    set.add(
        &out.join(TEXTURES_DIR).join(format!("{name}.cal")),
        cal.as_bytes(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_light_primitive_takes_no_groups_name() {
        let groups = ["light_lamp".to_string()];
        assert_eq!(light_name("lamp", &groups), "_light_lamp");
        assert_eq!(light_name("bulb", &groups), "light_bulb");
    }

    /// A group named `pict_X` took the name of X's picture pattern, and RADIANCE, binding
    /// a name to its last definition, rendered X's surfaces invisible.
    #[test]
    fn a_picture_pattern_takes_no_groups_name() {
        let groups = ["wall", "pict_wall", "_pict_wall"].map(String::from);
        assert_eq!(pattern_name("wall", &groups), "__pict_wall");
        assert_eq!(pattern_name("pict_wall", &groups), "pict_pict_wall");
        assert_eq!(pattern_name("floor", &groups[..1]), "pict_floor");
    }

    /// Of an earlier run's outputs, those this run does not write again are stale: maps
    /// of groups it did not map, of this scene or another's, and the renders and error
    /// images of views it lacks (a recovery of another scene into the same folder left
    /// them beside this one's). A file of another kind in those folders, and an input of
    /// the run, are not the recovery's to remove.
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
        let stale = stale_outputs(&set, dir.path());
        let expected: Vec<PathBuf> = [
            "views/lamp.exr",
            "views/lamp.png",
            "errors/lamp.exr",
            "errors/lamp.png",
            "textures/picture.cal",
            "textures/picture.exr",
            "textures/picture.hdr",
            "textures/statue.exr",
        ]
        .iter()
        .map(|f| dir.path().join(f))
        .collect();
        assert_eq!(stale, expected);
    }
}
