//! What a group's texture coordinates allow a diffuse map: faces without them or without
//! area, faces laid over the same texels, and coordinates past [0, 1] that lay a map as
//! tiles.

use std::collections::HashSet;

use crate::assemble;
use crate::obj::ObjObject;
use crate::scene_file::{GroupDesc, SceneDesc};

/// The objects of `group` that the scene does not hide. (Looked up in sets: searched in
/// the group's list for every object of the scene, 30,000 objects in one group took
/// `check` 1.5 s here.)
pub(super) fn shown_objects<'a>(
    desc: &'a SceneDesc,
    objects: &'a [ObjObject],
    group: &'a GroupDesc,
) -> impl Iterator<Item = &'a ObjObject> {
    let names = |list: &'a [String]| list.iter().map(String::as_str).collect::<HashSet<_>>();
    let (listed, hidden) = (names(&group.objects), names(&desc.hide));
    objects
        .iter()
        .filter(move |o| listed.contains(o.name.as_str()) && !hidden.contains(o.name.as_str()))
}

/// The first object of `group` (not hidden) whose OBJ texture coordinates no map can be
/// laid over, and why: coordinates that cover no area (an exporter's `vt 0 0` at every
/// corner), where every pixel would read one texel, or one line of them. Coordinates past
/// [0, 1] are tiles, and the map is read repeated there (`texture::map_wrap`).
pub(super) fn coordinates_unfit_for_a_map(
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
pub(super) fn overlapping_coordinates(
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
pub(super) fn tiled_coordinates(
    desc: &SceneDesc,
    objects: &[ObjObject],
    group: &GroupDesc,
) -> Option<String> {
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
pub(super) fn has_area(object: &ObjObject) -> bool {
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
