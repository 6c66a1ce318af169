//! What recovery reads of its input before any render: the scene assembled with its
//! geometry only, the panorama, each view's pure pixels and light pixels, the panorama's
//! calibration against the lights it sees, each view's orientation, and the views that
//! see no group. `relume recover` warns of these before its long work; `relume check`
//! stops there, after a preview of stage 1 at a few samples (each group's first diffuse
//! colour, and whether light reaches it), so that a panorama can be judged in a second
//! before a run of minutes.

mod check;
mod coordinates;
mod image_warnings;

pub use check::{check, CheckReport, GroupSight};
use coordinates::{
    coordinates_unfit_for_a_map, has_area, overlapping_coordinates, shown_objects,
    tiled_coordinates,
};
use image_warnings::{clipped_warnings, greyscale_warnings, repeated_view_warnings};

use std::path::{Path, PathBuf};

use relume_core::geometry::View;

use super::calibration::{self, LightReading};
use super::orientation::{self, OrientationReading};
use super::pixels::{self, PurePixel};
use super::too_bright;
use crate::assemble::{self, MaterialSource, OwnedScene};
use crate::error::Error;
use crate::images::{self, Image};
use crate::scene_file::GroupKind;
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
