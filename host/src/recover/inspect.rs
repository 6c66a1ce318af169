//! What recovery reads of its input before any render: the scene assembled with its
//! geometry only, the panorama, each view's pure pixels and light pixels, the panorama's
//! calibration against the lights it sees, each view's orientation, and the views that
//! see no group. `relume recover` warns of these before its long work; `relume check`
//! stops there, after a preview of stage 1 at a few samples (each group's first diffuse
//! colour, and whether light reaches it), so that a panorama can be judged in a second
//! before a run of minutes.

use std::path::{Path, PathBuf};
use std::time::Instant;

use relume_core::geometry::View;
use serde::Serialize;

use super::calibration::{self, LightReading, ViewReading};
use super::model::GroupModel;
use super::orientation::{self, OrientationReading};
use super::pixels::{self, PurePixel};
use super::{stage1, too_bright, warnings, Recovery};
use crate::assemble::{self, MaterialSource, OwnedScene};
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::images::{self, Image};
use crate::obj::ObjObject;
use crate::parallel;
use crate::scene_file::{GroupDesc, GroupKind, SceneDesc, ViewDesc};
use crate::text::counted;

/// A scene read for recovery: its geometry assembled (no materials yet) and its panorama.
pub(super) struct Input {
    pub owned: OwnedScene,
    pub real: Vec<Image>,
    /// Every file the run was given (the scene, its geometry, its views' images), which no
    /// output may replace.
    pub inputs: Vec<(PathBuf, String)>,
    pub view_names: Vec<String>,
    /// What each view's image header divided its stored values by (see
    /// [`calibration::ImageHeaders`]).
    pub header_divisors: Vec<Option<[f64; 3]>>,
    /// The value a PNG view's pixels are clipped at (its largest code times the view's
    /// exposure); `None` for a high-dynamic-range image.
    pub clipped_at: Vec<Option<f32>>,
    pub kinds: Vec<GroupKind>,
    /// Whether every object of a group has texture coordinates, as a diffuse map needs.
    pub mapped: Vec<bool>,
    /// For a group with texture coordinates no map can be laid over, which object and why
    /// ([`coordinates_unfit_for_a_map`]).
    pub unfit_for_a_map: Vec<Option<String>>,
    /// Per group, where its faces lie over the same texels of a map
    /// ([`overlapping_coordinates`]).
    pub overlapping_uv: Vec<Option<String>>,
    /// For a group whose texture coordinates reach past [0, 1], their span
    /// ([`tiled_coordinates`]): a map recovered for it repeats.
    pub tiled: Vec<Option<String>>,
    /// Whether every object of a group is hidden (`hide`): it is not in the scene.
    pub hidden: Vec<bool>,
    /// Whether a group's faces (those not hidden) have no area, every triangle degenerate:
    /// no view can see it.
    pub no_area: Vec<bool>,
    /// How RADIANCE's obj2rad names the objects, for materials.map.
    pub obj2rad: super::output::Obj2radNames,
    /// The objects obj2rad cannot name, told with the input's warnings.
    pub obj2rad_warnings: Vec<String>,
}

/// Reads the scene, its geometry and its panorama's images (each view's exposure applied).
pub(super) fn read(scene: &Path) -> Result<Input, Error> {
    let (desc, objects) = assemble::load_scene(scene)?;
    let mut real = Vec::with_capacity(desc.views.len());
    let mut header_divisors = Vec::with_capacity(desc.views.len());
    let mut clipped_at = Vec::with_capacity(desc.views.len());
    for (vi, v) in desc.views.iter().enumerate() {
        let path = desc.view_image(vi, "recover needs the panorama")?;
        let (image, divisor) = images::read_view_image_and_header(path, v, v.exposure)?;
        real.push(image);
        header_divisors.push(divisor);
        // A PNG's largest code reads as 1 before the exposure, exactly (the sRGB curve's
        // end), and holds every radiance from there up.
        let png = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"));
        clipped_at.push(png.then_some(v.exposure));
    }
    let inputs = desc.input_files();
    let view_names: Vec<String> = desc.views.iter().map(|v| v.name.clone()).collect();
    let kinds: Vec<GroupKind> = desc.groups.iter().map(|g| g.kind).collect();
    let mapped: Vec<bool> = desc
        .groups
        .iter()
        .map(|g| assemble::unmapped_object(&desc, &objects, g).is_none())
        .collect();
    let unfit_for_a_map: Vec<Option<String>> = desc
        .groups
        .iter()
        .map(|g| coordinates_unfit_for_a_map(&desc, &objects, g))
        .collect();
    let overlapping_uv: Vec<Option<String>> = desc
        .groups
        .iter()
        .map(|g| overlapping_coordinates(&desc, &objects, g))
        .collect();
    let tiled: Vec<Option<String>> = desc
        .groups
        .iter()
        .map(|g| tiled_coordinates(&desc, &objects, g))
        .collect();
    let hidden: Vec<bool> = desc
        .groups
        .iter()
        .map(|g| g.objects.iter().all(|o| desc.hide.contains(o)))
        .collect();
    let no_area: Vec<bool> = desc
        .groups
        .iter()
        .zip(&hidden)
        .map(|(g, &hidden)| !hidden && shown_objects(&desc, &objects, g).all(|o| !has_area(o)))
        .collect();
    let (obj2rad, obj2rad_warnings) = super::output::Obj2radNames::new(&desc, &objects);
    let owned = assemble::assemble(desc, &objects, MaterialSource::GeometryOnly)?;
    Ok(Input {
        owned,
        real,
        inputs,
        view_names,
        header_divisors,
        clipped_at,
        kinds,
        mapped,
        unfit_for_a_map,
        overlapping_uv,
        tiled,
        hidden,
        no_area,
        obj2rad,
        obj2rad_warnings,
    })
}

/// The objects of `group` that the scene does not hide.
fn shown_objects<'a>(
    desc: &'a SceneDesc,
    objects: &'a [ObjObject],
    group: &'a GroupDesc,
) -> impl Iterator<Item = &'a ObjObject> {
    objects
        .iter()
        .filter(|o| group.objects.contains(&o.name) && !desc.hide.contains(&o.name))
}

/// The first object of `group` (not hidden) whose OBJ texture coordinates no map can be
/// laid over, and why: coordinates that cover no area (an exporter's `vt 0 0` at every
/// corner), where every pixel would read one texel, or one line of them. Coordinates past
/// [0, 1] are tiles, and the map is read repeated there (`texture::map_wrap`).
fn coordinates_unfit_for_a_map(
    desc: &SceneDesc,
    objects: &[ObjObject],
    group: &GroupDesc,
) -> Option<String> {
    shown_objects(desc, objects, group).find_map(|o| {
        let faces = o.uvs.as_deref()?;
        let area: f64 = faces
            .iter()
            .map(|[a, b, c]| {
                let (e1, e2) = (
                    [(b[0] - a[0]) as f64, (b[1] - a[1]) as f64],
                    [(c[0] - a[0]) as f64, (c[1] - a[1]) as f64],
                );
                0.5 * (e1[0] * e2[1] - e1[1] * e2[0]).abs()
            })
            .sum();
        (area.is_nan() || area <= 0.0).then(|| {
            format!(
                "object '{}' has texture coordinates that cover no area of a map ({}: every face's corners on one point or line), so all its pixels would read one texel or one line of them",
                o.name,
                uv_span(faces)
            )
        })
    })
}

/// The side of the grid over [0, 1]^2 on which [`overlapping_coordinates`] lays faces.
const OVERLAP_GRID: usize = 128;

/// A group is told of from this share of the texels its faces cover being covered twice.
pub const OVERLAP_SHARE: f64 = 0.1;

/// Where the faces of group `group` (its objects not hidden, all with texture coordinates
/// inside [0, 1]: a tiled group repeats by design) lie over the same texels of a map, on
/// [`OVERLAP_GRID`] cells a side, past [`OVERLAP_SHARE`] of the cells they cover: which
/// objects, and how much. A map holds one value a texel, so two pictures in one group, or
/// a picture's faces laid over one region, are recovered as their mean, with nothing said
/// (two pictures gave one map at error 0.13 and a lobe neither has); a mirrored half that
/// shows the same is right, so this is told, not refused.
fn overlapping_coordinates(
    desc: &SceneDesc,
    objects: &[ObjObject],
    group: &GroupDesc,
) -> Option<String> {
    let shown: Vec<&ObjObject> = shown_objects(desc, objects, group).collect();
    let faces: Vec<(usize, [[f32; 2]; 3])> = (shown.iter().enumerate())
        .filter_map(|(k, o)| Some((k, o.uvs.as_deref()?)))
        .flat_map(|(k, uvs)| uvs.iter().map(move |uv| (k, *uv)))
        .collect();
    if faces.is_empty()
        || faces
            .iter()
            .any(|(_, uv)| uv.iter().any(|&p| assemble::past_the_unit_square(p)))
    {
        return None;
    }
    // Per cell: the object of the first face over it, and whether a second lies over it.
    let mut first: Vec<Option<usize>> = vec![None; OVERLAP_GRID * OVERLAP_GRID];
    let mut twice = vec![false; OVERLAP_GRID * OVERLAP_GRID];
    let mut pair: Option<(usize, usize)> = None;
    for &(object, uv) in &faces {
        for cell in cells_inside(uv) {
            match first[cell] {
                None => first[cell] = Some(object),
                Some(other) => {
                    twice[cell] = true;
                    pair.get_or_insert((other, object));
                }
            }
        }
    }
    let covered = first.iter().filter(|c| c.is_some()).count();
    let shared = twice.iter().filter(|&&t| t).count();
    let share = shared as f64 / covered.max(1) as f64;
    let (a, b) = pair?;
    (share > OVERLAP_SHARE).then(|| {
        let whose = if a == b {
            format!("faces of object '{}'", shown[a].name)
        } else {
            format!("objects '{}' and '{}'", shown[a].name, shown[b].name)
        };
        format!(
            "{whose} lie over the same texture coordinates ({:.0}% of the texels the group covers), so one texel of its map holds what both show there: their mean, where they show different pictures (a mirrored half that shows the same is right); give each picture a region of [0, 1]^2 of its own, or a group of its own",
            100.0 * share
        )
    })
}

/// The cells of the [`OVERLAP_GRID`] grid over [0, 1]^2 whose centres lie strictly inside
/// the triangle `uv` (so that two faces sharing an edge share no cell), in row order.
fn cells_inside(uv: [[f32; 2]; 3]) -> Vec<usize> {
    let [a, b, c] = uv.map(|p| [p[0] as f64, p[1] as f64]);
    let cross = crate::polygon::cross;
    let turn = cross(a, b, c);
    if turn.is_nan() || turn == 0.0 {
        return Vec::new();
    }
    let n = OVERLAP_GRID as f64;
    let range = |k: usize| {
        let lo = a[k].min(b[k]).min(c[k]);
        let hi = a[k].max(b[k]).max(c[k]);
        let first = ((lo * n - 0.5).ceil().max(0.0)) as usize;
        let last = ((hi * n - 0.5).floor().min(n - 1.0)).max(-1.0);
        first..(last + 1.0) as usize
    };
    let mut cells = Vec::new();
    for j in range(1) {
        for i in range(0) {
            let p = [(i as f64 + 0.5) / n, (j as f64 + 0.5) / n];
            let inside = [cross(a, b, p), cross(b, c, p), cross(c, a, p)]
                .iter()
                .all(|&s| s * turn > 0.0);
            if inside {
                cells.push(j * OVERLAP_GRID + i);
            }
        }
    }
    cells
}

/// The span of group `group`'s texture coordinates (its objects not hidden) when some lie
/// past [0, 1] (`assemble::past_the_unit_square`): its texture is tiled over it, and a
/// map recovered for it repeats (`OwnedScene::tiles_its_map`, from the same coordinates).
fn tiled_coordinates(desc: &SceneDesc, objects: &[ObjObject], group: &GroupDesc) -> Option<String> {
    let faces: Vec<[[f32; 2]; 3]> = shown_objects(desc, objects, group)
        .filter_map(|o| o.uvs.as_deref())
        .flatten()
        .copied()
        .collect();
    faces
        .iter()
        .flatten()
        .any(|&uv| assemble::past_the_unit_square(uv))
        .then(|| uv_span(&faces))
}

/// The span of some faces' texture coordinates, as a message gives it.
fn uv_span(faces: &[[[f32; 2]; 3]]) -> String {
    let (mut low, mut high) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    for uv in faces.iter().flatten() {
        for k in 0..2 {
            low[k] = low[k].min(uv[k]);
            high[k] = high[k].max(uv[k]);
        }
    }
    format!(
        "u {}..{}, v {}..{}",
        crate::text::significant(low[0] as f64),
        crate::text::significant(high[0] as f64),
        crate::text::significant(low[1] as f64),
        crate::text::significant(high[1] as f64)
    )
}

/// Whether some triangle of `object` has an area, in 64 bits relative to its first corner.
fn has_area(object: &ObjObject) -> bool {
    object.triangles.iter().any(|[a, b, c]| {
        let u: [f64; 3] = std::array::from_fn(|k| b[k] - a[k]);
        let v: [f64; 3] = std::array::from_fn(|k| c[k] - a[k]);
        let cross = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        cross.iter().any(|&x| x != 0.0)
    })
}

/// A view whose pixels all hold equal R, G and B, and not all 0: a greyscale capture (a
/// grey PNG is read as three equal channels), from which every colour comes out grey. A
/// colour capture of the greyest room differs between its channels somewhere, if only by
/// noise. (A grey PNG of a red wall gave a grey wall without a word.)
fn greyscale_warnings(real: &[Image], view_names: &[String]) -> Vec<String> {
    real.iter()
        .zip(view_names)
        .filter(|(image, _)| {
            image.pixels.iter().all(|&[r, g, b]| r == g && g == b)
                && image.pixels.iter().any(|p| p[0] > 0.0)
        })
        .map(|(_, name)| {
            format!(
                "view '{name}' holds equal R, G and B in every pixel (a greyscale image?): the groups it sees are fitted to grey, and come out grey where no colour view sees them"
            )
        })
        .collect()
}

/// A view that looks from the same place, the same way, over the same field and pixels
/// as an earlier one: every fit counts its pixels twice (a copied `[[view]]` table lifted
/// a 2-pixel plate to 4, and it came out glossy). Told, naming both.
fn repeated_view_warnings(views: &[ViewDesc]) -> Vec<String> {
    let same = |a: &ViewDesc, b: &ViewDesc| {
        a.position == b.position
            && a.direction == b.direction
            && a.up == b.up
            && a.fov_deg == b.fov_deg
            && a.size == b.size
    };
    views
        .iter()
        .enumerate()
        .filter_map(|(i, v)| {
            let first = views[..i].iter().find(|u| same(u, v))?;
            Some(format!(
                "view '{}' looks from where view '{}' does, the same way, over the same field and pixels: every fit counts these pixels twice, weighing what they see double; leave one out (or merge their images)",
                v.name, first.name
            ))
        })
        .collect()
}

/// A PNG view's pure pixels clipped at its largest code are at least that bright, not
/// that: counted per view, and told where there are any. (A capture's 6 pixels at 65535
/// were taken as radiance without a word.)
fn clipped_warnings(
    pure: &[PurePixel],
    real: &[Image],
    clipped_at: &[Option<f32>],
    view_names: &[String],
) -> Vec<String> {
    let mut clipped = vec![0u32; real.len()];
    let mut seen = vec![0u32; real.len()];
    for p in pure {
        let v = p.view as usize;
        seen[v] += 1;
        if let Some(level) = clipped_at[v] {
            let image = &real[v];
            if image.pixels[(p.y * image.width + p.x) as usize]
                .iter()
                .any(|&c| c >= level)
            {
                clipped[v] += 1;
            }
        }
    }
    (0..real.len())
        .filter(|&v| clipped[v] > 0)
        .map(|v| {
            format!(
                "view '{}': {} of {} pure pixels are at its PNG's largest value in some channel (clipped): their radiance is at least that, and the colours fitted to them come out dark; a high-dynamic-range capture (.exr, .hdr) or a shorter exposure keeps them",
                view_names[v],
                clipped[v],
                seen[v]
            )
        })
        .collect()
}

/// What the input shows before any render.
pub(super) struct Inspection {
    /// Every pure pixel of every view, in view and row order.
    pub pure: Vec<PurePixel>,
    pub light_readings: Vec<LightReading>,
    pub orientation_readings: Vec<OrientationReading>,
    /// The warnings about the input, in the order they are told.
    pub warnings: Vec<String>,
}

/// Labels every view's pixels and reads the panorama against the scene. A panorama none
/// of whose pixels falls wholly on a group is refused: there is nothing to recover.
pub(super) fn inspect(
    scene_file: &Path,
    pool: &rayon::ThreadPool,
    input: &mut Input,
) -> Result<Inspection, Error> {
    let views = input.owned.views.clone();
    let mut enclosed_warnings = Vec::new();
    let outside_warnings;
    let pixels::Labels {
        pure,
        lights: light_pixels,
        light_edges,
        light_backs,
        empty_views,
    } = {
        let group_names = input.owned.group_names.clone();
        let scene = input.owned.build()?;
        let mut labels = pixels::label_views(pool, &scene, &views);
        outside_warnings = super::seen_outside::bright_outside_warnings(
            pool,
            &scene,
            &views,
            &input.real,
            &input.view_names,
        );
        for enclosed in crate::enclosed_views::enclosed_views(scene.triangles, &views) {
            let view = enclosed.view as u32;
            let before = labels.pure.len();
            labels.pure.retain(|p| p.view != view);
            enclosed_warnings.push(format!(
                "view '{}' is inside group '{}', a closed surface no light shines into: no light reaches what the view sees, whatever the materials, so its {} are left out of the fit (is the view's position right, or does a light face away?)",
                input.view_names[enclosed.view],
                group_names[enclosed.group as usize],
                counted((before - labels.pure.len()) as u64, "pure pixel")
            ));
        }
        if labels.pure.is_empty() && !enclosed_warnings.is_empty() {
            return Err(Error::input(
                scene_file,
                format!(
                    "no view is left to recover from: {}",
                    enclosed_warnings.join("; ")
                ),
            ));
        }
        if labels.pure.is_empty() {
            return Err(no_pure_pixel(
                scene_file,
                pool,
                &scene,
                &views,
                &input.view_names,
            ));
        }
        labels
    };
    let mut warnings = enclosed_warnings;
    warnings.extend(outside_warnings);
    warnings.extend(input.owned.crossing_face_warnings.iter().cloned());
    warnings.extend(crate::light_placement::lights_against_surfaces(
        &mut input.owned,
    )?);
    warnings.extend(crate::repeated_triangles::repeated_triangle_warnings(
        input.owned.triangles(),
        &input.owned.group_names,
    ));
    warnings.extend(crate::overlapping_faces::overlapping_face_warnings(
        &mut input.owned,
    )?);
    let owned = &input.owned;
    let names = too_bright::Names {
        views: &input.view_names,
        groups: &owned.group_names,
        lights: &owned.light_names,
    };
    let (pure, too_bright) = too_bright::leave_out_too_bright(
        scene_file,
        pure,
        &input.real,
        &names,
        owned.light_radiance(),
    )?;
    let light_readings = calibration::read_lights(
        &light_pixels,
        &input.real,
        &owned.light_names,
        owned.light_radiance(),
        &input.view_names,
    );
    warnings.extend(calibration::calibration_warnings(
        &light_readings,
        owned.light_radiance(),
    ));
    warnings.extend(calibration::unchecked_warning(
        &light_pixels,
        &light_edges,
        &owned.light_names,
        &input.view_names,
    ));
    let back_readings = calibration::read_lights(
        &light_backs,
        &input.real,
        &owned.light_names,
        owned.light_radiance(),
        &input.view_names,
    );
    warnings.extend(calibration::facing_away_warnings(&back_readings));
    warnings.extend(too_bright::unlit_channel_warnings(
        owned.light_radiance(),
        super::START_COLOR,
    ));
    warnings.extend(too_bright);
    warnings.extend(std::mem::take(&mut input.obj2rad_warnings));
    warnings.extend(greyscale_warnings(&input.real, &input.view_names));
    warnings.extend(repeated_view_warnings(&owned.desc.views));
    warnings.extend(clipped_warnings(
        &pure,
        &input.real,
        &input.clipped_at,
        &input.view_names,
    ));
    // Groups no view can see for a reason of the scene's, not of the views'.
    for (flags, why) in [
        (
            &input.hidden,
            "every object of it is hidden (`hide` in the scene): it is not in the scene",
        ),
        (
            &input.no_area,
            "its faces have no area (every triangle degenerate: corners repeated or in a line)",
        ),
    ] {
        for (name, _) in owned.group_names.iter().zip(flags).filter(|(_, &f)| f) {
            warnings.push(format!(
                "group '{name}': {why}, so no view sees it and its material is not recovered"
            ));
        }
    }
    let orientation_readings =
        orientation::read_orientations(&pure, &input.real, &input.view_names);
    warnings.extend(orientation::orientation_warnings(&orientation_readings));
    for vi in empty_views {
        warnings.push(format!(
            "view '{}' sees no group in whole pixels (only lights, silhouettes or nothing): it adds nothing to the fit",
            input.view_names[vi]
        ));
    }
    Ok(Inspection {
        pure,
        light_readings,
        orientation_readings,
        warnings,
    })
}

/// The refusal of a panorama none of whose pixels falls wholly on a group: every group
/// would be unseen, so there is nothing to recover, and a run that wrote an empty
/// materials.toml and exited 0 would hide a scene that does not match its views. Says what
/// each view's pixels see, from which the likely cause can be told.
fn no_pure_pixel(
    scene_file: &Path,
    pool: &rayon::ThreadPool,
    scene: &relume_core::scene::Scene,
    views: &[View],
    names: &[String],
) -> Error {
    let seen: Vec<String> = views
        .iter()
        .zip(names)
        .map(|(view, name)| {
            let sight = pixels::sight(pool, scene, view);
            format!("view '{name}', {}", sight.describe(view))
        })
        .collect();
    Error::input(
        scene_file,
        format!(
            "no view sees any group in whole pixels, so no material can be recovered ({}); are the views inside the geometry and facing it, the OBJ in the units of the views' positions, the groups' objects not hidden, and the views fine enough for a pixel to fall wholly on one group?",
            seen.join("; ")
        ),
    )
}

/// One group as the panorama sees it.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct GroupSight {
    pub group: String,
    pub kind: String,
    /// Its pure pixels in each view, in the scene's order of views.
    pub pure_pixels: Vec<u32>,
    /// Its diffuse colour after stage 1's iteration at `PREVIEW_SPP` samples per pixel:
    /// a first reading, before any lobe is tried (`null` where no pixel sees the group or
    /// no light reaches it).
    pub preview_colour: Option<[f64; 3]>,
}

impl GroupSight {
    pub fn total(&self) -> u32 {
        self.pure_pixels.iter().sum()
    }
}

/// What `relume check` found.
#[derive(Serialize, Clone, Debug)]
pub struct CheckReport {
    pub views: Vec<String>,
    pub groups: Vec<GroupSight>,
    pub light_readings: Vec<LightReading>,
    pub orientation_readings: Vec<OrientationReading>,
    /// The warnings `relume recover` would print before its work, and those of its input
    /// that it prints after: a group that no view sees whole, views too small.
    pub warnings: Vec<String>,
    /// The groups seen, but in fewer than `warnings::FEW_PIXELS` pure pixels: a lobe
    /// recovered on them was seen to change with the seed.
    pub few_pixels: Vec<(String, u32)>,
    /// The groups whose texture coordinates no map can be laid over, and why
    /// (`coordinates_unfit_for_a_map`): a texture they show is told, not mapped.
    pub unfit_for_a_map: Vec<(String, String)>,
    /// The groups whose texture coordinates reach past [0, 1], and their span: a texture
    /// is tiled over them, and a map recovered for one repeats.
    pub tiled: Vec<(String, String)>,
    /// Each view's pixels of the preview rendered under its colours against the
    /// panorama: a view off the others by more than `VIEW_GROSS_FACTOR` is warned of.
    pub view_readings: Vec<ViewReading>,
    /// Samples per pixel of the colours' preview, and the renders it took.
    pub preview_spp: u32,
    pub preview_renders: u32,
    pub seconds: f64,
}

/// Samples per pixel of `relume check`'s preview of stage 1. At 4, on at most
/// [`PREVIEW_GROUP_PIXELS`] a group, the references' diffuse groups at 256 px read within
/// 6% of their true colours (the living room's floor +3%, its pedestal +5%: the glossy
/// groups around them taken for diffuse), in 1.0 s on 2 cores (0.3 s without it).
pub const PREVIEW_SPP: u32 = 4;

/// Pixels of each group (at most, spread over it) that `relume check`'s preview renders.
const PREVIEW_GROUP_PIXELS: usize = 2048;

/// The seed of `relume check`'s preview: check takes none, and its findings are the same
/// from run to run.
const PREVIEW_SEED: u64 = 0xC4EC_0001;

/// Each view's reading under the preview's colours: its pixels of the preview rendered
/// again (one render per view with pixels, at the preview's samples and seed) against the
/// panorama; and the renders that took.
fn preview_view_readings(
    rec: &mut Recovery,
    view_names: &[String],
) -> Result<(Vec<ViewReading>, u32), Error> {
    let mut readings = Vec::with_capacity(view_names.len());
    let mut renders = 0;
    for (v, name) in view_names.iter().enumerate() {
        let pixels: Vec<PurePixel> = rec
            .pure
            .iter()
            .filter(|p| p.view as usize == v)
            .copied()
            .collect();
        let fits = match pixels.is_empty() {
            true => Vec::new(),
            false => {
                renders += 1;
                rec.evaluate_pixels(&pixels, PREVIEW_SPP, rec.seed, &|_| true)?
            }
        };
        readings.push(calibration::read_view_fits(name, &fits));
    }
    Ok((readings, renders))
}

/// The input checks of `relume recover` and a preview of its first stage: each group's
/// diffuse colour at a few samples per pixel, and whether light reaches it. No output but
/// `json` if given (the report as JSON, which may replace none of the run's inputs).
pub fn check(
    scene: &Path,
    threads: Option<usize>,
    json: Option<&Path>,
) -> Result<CheckReport, Error> {
    let start = Instant::now();
    let mut input = read(scene)?;
    let mut set = OutputSet::keeping(std::mem::take(&mut input.inputs));
    if let Some(path) = json {
        set.check_target(path)?;
    }
    let pool = parallel::thread_pool(threads)?;
    let Inspection {
        pure,
        light_readings,
        orientation_readings,
        mut warnings,
    } = inspect(scene, &pool, &mut input)?;
    let n_views = input.view_names.len();
    let mut groups: Vec<GroupSight> = input
        .owned
        .group_names
        .iter()
        .zip(&input.kinds)
        .map(|(name, kind)| GroupSight {
            group: name.clone(),
            kind: format!("{kind:?}").to_lowercase(),
            pure_pixels: vec![0; n_views],
            preview_colour: None,
        })
        .collect();
    for p in &pure {
        groups[p.group as usize].pure_pixels[p.view as usize] += 1;
    }
    let mut rec = Recovery {
        views: input.owned.views.clone(),
        models: vec![
            GroupModel::Diffuse {
                color: [super::START_COLOR; 3]
            };
            groups.len()
        ],
        owned: input.owned,
        real: input.real,
        // A group's mean over a few thousand pixels is as good a first reading as over all.
        pure: pixels::spread_subset(&pure, groups.len(), PREVIEW_GROUP_PIXELS),
        maps: Vec::new(),
        pool,
        seed: PREVIEW_SEED,
        terms_memo: Default::default(),
        started: start,
    };
    let names = rec.owned.group_names.clone();
    let preview = stage1::preview_light(&mut rec, &names, PREVIEW_SPP)?;
    for (g, colour) in groups.iter_mut().zip(preview.colours) {
        g.preview_colour = colour;
    }
    warnings.extend(preview.warnings);
    let (view_readings, view_renders) = preview_view_readings(&mut rec, &input.view_names)?;
    warnings.extend(calibration::preview_view_warnings(
        &view_readings,
        calibration::ImageHeaders {
            views: &input.view_names,
            divisors: &input.header_divisors,
        },
    ));
    // A group all hidden, or of no area, was told of by `inspect`, with its cause.
    let hidden = |g: &&GroupSight| {
        let at = names.iter().position(|n| *n == g.group);
        at.is_some_and(|i| input.hidden[i] || input.no_area[i])
    };
    for g in groups.iter().filter(|g| g.total() == 0 && !hidden(g)) {
        warnings.push(format!(
            "group '{}': no pure pixel in any view; recover will not recover its material",
            g.group
        ));
    }
    let sides: Vec<(String, u32)> = (input.view_names.iter().cloned())
        .zip(rec.views.iter().map(|v| v.width.min(v.height)))
        .collect();
    warnings.extend(warnings::small_views(&sides));
    let few_pixels = groups
        .iter()
        .filter(|g| (1..warnings::FEW_PIXELS).contains(&g.total()))
        .map(|g| (g.group.clone(), g.total()))
        .collect();
    let unfit_for_a_map = (names.iter().zip(&input.unfit_for_a_map))
        .filter_map(|(name, why)| Some((name.clone(), why.clone()?)))
        .collect();
    let tiled = (names.iter().zip(&input.tiled))
        .filter_map(|(name, span)| Some((name.clone(), span.clone()?)))
        .collect();
    let report = CheckReport {
        views: input.view_names,
        groups,
        light_readings,
        orientation_readings,
        warnings,
        few_pixels,
        unfit_for_a_map,
        tiled,
        view_readings,
        preview_spp: PREVIEW_SPP,
        preview_renders: preview.evaluations + view_renders,
        seconds: start.elapsed().as_secs_f64(),
    };
    if let Some(path) = json {
        let text =
            serde_json::to_string_pretty(&report).map_err(|e| Error::Usage(e.to_string()))?;
        set.add(path, text.as_bytes())?;
    }
    set.commit()?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No group of the references has faces over the same texels; two of textured's
    /// pictures put in one group do, each over all of [0, 1]^2, and are named.
    #[test]
    fn faces_over_the_same_texels_are_found_and_none_in_the_references() {
        let Some(bench) = crate::scene_file::tests::bench() else {
            return;
        };
        for scene in ["textured", "living-room"] {
            let (desc, objects) =
                assemble::load_scene(&bench.join(scene).join("scene-small.toml")).unwrap();
            for g in &desc.groups {
                let found = overlapping_coordinates(&desc, &objects, g);
                assert_eq!(found, None, "{scene}: group {}", g.name);
            }
        }
        let (mut desc, objects) =
            assemble::load_scene(&bench.join("textured/scene-small.toml")).unwrap();
        let flowers = desc.groups.iter().position(|g| g.name == "picture_flowers");
        let flowers = &mut desc.groups[flowers.unwrap()];
        flowers.objects.push("picture_stripes".into());
        let group = flowers.clone();
        let found = overlapping_coordinates(&desc, &objects, &group).unwrap();
        assert!(
            found.starts_with("objects 'picture_flowers' and 'picture_stripes' lie over the same texture coordinates (100% of the texels"),
            "{found}"
        );
    }

    /// Two triangles that share an edge share no cell; a cell's centre on the edge is in
    /// neither.
    #[test]
    fn faces_sharing_an_edge_share_no_cell() {
        let lower = cells_inside([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]);
        let upper = cells_inside([[0.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
        assert!(lower.iter().all(|c| !upper.contains(c)));
        let diagonal = OVERLAP_GRID;
        assert_eq!(
            lower.len() + upper.len() + diagonal,
            OVERLAP_GRID * OVERLAP_GRID
        );
    }
}
