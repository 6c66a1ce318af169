//! The checks of a scene's lights as assembled: a light must have an area, give each
//! triangle once, not overlap itself, and lie where the rays' offsets from surfaces
//! cannot hide it (an offset larger than the light, or far against the views).

use std::collections::HashMap;

use glam::Vec3;
use relume_core::geometry::{longest_side, Surface, Triangle, View};
use relume_core::render::RAY_EPSILON;
use relume_core::scene::Scene;

use crate::error::Error;
use crate::obj::ObjObject;
use crate::scene_file::SceneDesc;
use crate::text::significant;

use super::moved;

/// An error when every face of the light `object` is degenerate: a light of no area
/// emits nothing, and rendered only black with a warning that could not say why.
pub(super) fn refuse_a_light_without_area(object: &ObjObject) -> Result<(), Error> {
    // In 32 bits relative to the first vertex: the shape's, not the place's, precision.
    let area: f32 = object
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|p| moved(p, t[0]));
            (b - a).cross(c - a).length() / 2.0
        })
        .sum();
    if area > 0.0 {
        return Ok(());
    }
    let msg = format!(
        "light '{}': its faces have no area (every triangle degenerate), so it emits nothing",
        object.name
    );
    Err(match crate::obj::object_line(&object.file, &object.name) {
        Some(line) => Error::at_line(&object.file, line, msg),
        None => Error::input(&object.file, msg),
    })
}

/// A light triangle's corners as bits, turned to start at the least: the key under which
/// a face given twice is found. The turn keeps the winding, so the same triangle facing
/// the other way (a panel lit on both sides) is another key.
type CornerKey = [[u64; 3]; 3];

/// An error when a triangle of light `object` is one that a light already has (the same
/// three corners in the same turn, in this object or an earlier light's, `seen`): both
/// emit the same way, so its light is counted twice. A lamp's face given twice made every
/// group of the cornell room 87-99% brighter, and recovery put it into the colours
/// without a word.
pub(super) fn refuse_a_light_triangle_twice<'o>(
    object: &'o ObjObject,
    seen: &mut HashMap<CornerKey, (&'o str, usize)>,
) -> Result<(), Error> {
    for (i, t) in object.triangles.iter().enumerate() {
        let mut key: CornerKey = t.map(|p| p.map(f64::to_bits));
        let least = (0..3).min_by_key(|&k| key[k]).unwrap_or(0);
        key.rotate_left(least);
        if let Some(&(first, at)) = seen.get(&key) {
            let corners: Vec<String> = t
                .iter()
                .map(|p| format!("({}, {}, {})", p[0], p[1], p[2]))
                .collect();
            return Err(Error::input(
                &object.file,
                format!(
                    "light '{}': its triangle {} (in file order; corners {}) is also triangle {} of light '{first}', facing the same way: both would emit, and the light be counted twice; give each face once",
                    object.name,
                    i + 1,
                    corners.join(", "),
                    at + 1
                ),
            ));
        }
        seen.insert(key, (object.name.as_str(), i));
    }
    Ok(())
}

/// An error when two light triangles overlap in one plane (or within the renderer's ray
/// slack of it) facing the same way: both emit there, as an exact copy would
/// ([`refuse_a_light_triangle_twice`]), but a lamp's quad given again split along its other
/// diagonal is no copy. `light_objects` gives where each light object's triangles start
/// in `triangles`, which are placed relative to `origin`.
pub(super) fn refuse_overlapping_light_faces(
    triangles: &[Triangle],
    light_objects: &[(usize, &ObjObject)],
    origin: [f64; 3],
) -> Result<(), Error> {
    if light_objects.is_empty() {
        return Ok(());
    }
    let slack = f64::from(
        crate::light_placement::SLACK_IN_EPSILONS * RAY_EPSILON * longest_side(triangles),
    );
    let Some((i, j, point)) = crate::overlapping_faces::overlapping_light_faces(triangles, slack)
    else {
        return Ok(());
    };
    let object_of = |t: usize| {
        let k = light_objects.partition_point(|&(start, _)| start <= t);
        light_objects
            .get(k.saturating_sub(1))
            .map(|&(start, o)| (o, t - start))
    };
    let (Some((later, at)), Some((earlier, first))) = (object_of(j), object_of(i)) else {
        return Ok(());
    };
    let corners: Vec<String> = later.triangles[at]
        .iter()
        .map(|p| format!("({}, {}, {})", p[0], p[1], p[2]))
        .collect();
    let near: Vec<String> = (0..3)
        .map(|k| crate::text::significant(point[k] + origin[k]))
        .collect();
    Err(Error::input(
        &later.file,
        format!(
            "light '{}': its triangle {} (in file order; corners {}) overlaps triangle {} of light '{}' in one plane, facing the same way (near ({})): both would emit there, and that part of the light be counted twice; give each part of a light's surface once",
            later.name,
            at + 1,
            corners.join(", "),
            first + 1,
            earlier.name,
            near.join(", ")
        ),
    ))
}

/// The largest ray offset a light's size allows, as a share of the light's longest side.
/// The references' offsets are 0.04-0.36% of their smallest light's (the living room's
/// desk lamp bulb, 0.14 units in a room of 5).
const MAX_OFFSET_PER_LIGHT_SIZE: f32 = 0.1;

/// An error when the scene is so large against one of its lights that the rays leaving a
/// surface start a visible part of that light's size away from it. Secondary rays start
/// [`RAY_EPSILON`] of the scene's size off the surface (`render::offset_origin`): a ground
/// plane 100,000 units wide under a lamp 0.6 across moved them 14 units, past the lamp 1
/// unit above the floor, and the views rendered black with a warning that blamed the
/// light.
pub(super) fn refuse_offsets_larger_than_a_light(
    desc: &SceneDesc,
    triangles: &[Triangle],
    light_names: &[String],
    objects: &[ObjObject],
) -> Result<(), Error> {
    let size = longest_side(triangles);
    let offset = RAY_EPSILON * size;
    // Each light's bounds in one pass (a pass per light was lights x triangles).
    let mut light_bounds =
        vec![(Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)); light_names.len()];
    for t in triangles {
        if let Surface::Light(l) = t.surface {
            if let Some((lo, hi)) = light_bounds.get_mut(l as usize) {
                let (a, b) = t.bounds();
                (*lo, *hi) = (lo.min(a), hi.max(b));
            }
        }
    }
    for (name, (lo, hi)) in light_names.iter().zip(light_bounds) {
        // A light of no triangles (all hidden: `hide` removes a lamp as it removes any
        // object) emits nothing, and no offset can miss it; measured as 0 across, it was
        // refused as a scene too large for it.
        if lo.x > hi.x {
            continue;
        }
        let extent = (hi - lo).max_element().max(0.0);
        if offset <= MAX_OFFSET_PER_LIGHT_SIZE * extent {
            continue;
        }
        let hint = what_to_crop(desc, objects);
        return Err(Error::input(
            &desc.path,
            format!(
                "{}: more than {MAX_OFFSET_PER_LIGHT_SIZE} of the size of light '{name}' ({} across), whose light would be lost or misplaced. Give the light at least {} across (its radiance scaled down for the same power), or {CROP}{hint}",
                offset_said(size),
                significant(extent.into()),
                significant((offset / MAX_OFFSET_PER_LIGHT_SIZE).into())
            ),
        ));
    }
    Ok(())
}

/// Which object to leave out or crop, said for [`CROP`]: the one without which the
/// geometry's bounding box shrinks the most (a speck a million units off stretched it,
/// and the hint named the room's largest wall), else, where no one object stretches it,
/// the one that spans the most.
fn what_to_crop(desc: &SceneDesc, objects: &[ObjObject]) -> String {
    let shown: Vec<&ObjObject> = objects
        .iter()
        .filter(|o| !desc.hide.contains(&o.name))
        .collect();
    let boxes: Vec<([f64; 3], [f64; 3])> =
        shown.iter().map(|o| bounds(std::iter::once(*o))).collect();
    let union = |a: ([f64; 3], [f64; 3]), b: ([f64; 3], [f64; 3])| {
        (
            std::array::from_fn(|k| a.0[k].min(b.0[k])),
            std::array::from_fn(|k| a.1[k].max(b.1[k])),
        )
    };
    let empty = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let side = |(lo, hi): ([f64; 3], [f64; 3])| (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    // The box of all objects before i and of all after it, for each i.
    let mut before = vec![empty; boxes.len() + 1];
    let mut after = vec![empty; boxes.len() + 1];
    for i in 0..boxes.len() {
        before[i + 1] = union(before[i], boxes[i]);
        let j = boxes.len() - 1 - i;
        after[j] = union(after[j + 1], boxes[j]);
    }
    let whole = side(before[boxes.len()]);
    let without = (0..boxes.len())
        .map(|i| (i, side(union(before[i], after[i + 1]))))
        .filter(|&(_, s)| s.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1));
    match without {
        Some((i, rest)) if rest < 0.5 * whole => format!(
            " (without object '{}' of {}, the geometry would span {} units)",
            shown[i].name,
            shown[i].file.display(),
            significant(rest)
        ),
        _ => shown
            .iter()
            .map(|o| (o, object_extent(o)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(o, e)| {
                format!(
                    " (the largest is object '{}' of {}, {} across)",
                    o.name,
                    o.file.display(),
                    significant(e)
                )
            })
            .unwrap_or_default(),
    }
}

/// What to do about a scene too large for its details.
const CROP: &str = "leave out or crop the geometry far from what the views see";

/// The ray offset of a scene of `size`, in words.
fn offset_said(size: f32) -> String {
    format!(
        "the geometry spans {} units (its bounding box's longest side), and rays leaving a surface start {RAY_EPSILON} of that, {} units, off it",
        significant(size.into()),
        significant((RAY_EPSILON * size).into())
    )
}

/// The largest ray offset against the distance at which a view sees the scene (the
/// median over a grid of its pixels). The references' are 0.013-0.04% (the living
/// room's novel view the most).
const MAX_OFFSET_PER_VIEW_DISTANCE: f32 = 0.01;

/// Pixels per side of the grid whose distances [`refuse_offsets_far_against_the_views`]
/// reads.
const DISTANCE_GRID: u32 = 9;

/// An error when the ray offset (see [`refuse_offsets_larger_than_a_light`]) is a visible
/// part of the distance at which a view sees the scene: shadows and contacts would move
/// by it, and past an offset as large as the distance everything renders black.
pub(super) fn refuse_offsets_far_against_the_views(
    desc: &SceneDesc,
    scene: &Scene,
    views: &[View],
    selected: &[String],
    group_names: &[String],
    light_names: &[String],
) -> Result<(), Error> {
    let offset = RAY_EPSILON * scene.size();
    let chosen = views
        .iter()
        .zip(&desc.views)
        .filter(|(_, d)| SceneDesc::view_selected(selected, &d.name));
    for (view, view_desc) in chosen {
        let grid = |n: u32| {
            (0..DISTANCE_GRID.min(n))
                .map(move |i| (i as f32 + 0.5) * n as f32 / DISTANCE_GRID.min(n) as f32)
        };
        let mut hits: Vec<(f32, Surface)> = grid(view.height)
            .flat_map(|y| grid(view.width).map(move |x| (x, y)))
            .filter_map(|(x, y)| scene.intersect(&view.ray(x, y), f32::INFINITY))
            .filter_map(|hit| {
                let triangle = scene.triangles.get(hit.triangle as usize)?;
                Some((hit.t, triangle.surface))
            })
            .collect();
        if hits.is_empty() {
            continue; // A view that sees nothing is warned of where it renders black.
        }
        hits.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (distance, surface) = hits[hits.len() / 2];
        if offset > MAX_OFFSET_PER_VIEW_DISTANCE * distance {
            let what = match surface {
                Surface::Group(g) => format!("group '{}'", group_names[g as usize]),
                Surface::Light(l) => format!("light '{}'", light_names[l as usize]),
            };
            return Err(Error::input(
                &desc.path,
                format!(
                    "{}: more than {MAX_OFFSET_PER_VIEW_DISTANCE} of the distance at which view '{}' sees the scene ({}, the median over {} of its pixels, on {what}), so its shadows and contacts would move by it. Move the view away from what it sees, or {CROP}",
                    offset_said(scene.size()),
                    view_desc.name,
                    significant(distance.into()),
                    hits.len()
                ),
            ));
        }
    }
    Ok(())
}

/// The longest side of an object's bounding box, in its file's 64-bit coordinates.
fn object_extent(object: &ObjObject) -> f64 {
    let (lo, hi) = bounds(std::iter::once(object));
    (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)
}

/// The objects' bounding box `(lo, hi)` in their files' 64-bit coordinates (inverted,
/// infinite, without vertices).
pub(super) fn bounds<'a>(objects: impl Iterator<Item = &'a ObjObject>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in objects.flat_map(|o| o.triangles.iter().flatten()) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}
