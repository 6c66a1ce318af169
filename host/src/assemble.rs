//! From validated descriptions (scene.toml, OBJ, materials.toml) to the buffers the core
//! borrows. [`OwnedScene`] owns every buffer; [`OwnedScene::build`] lends them to
//! `relume_core::scene::Scene::build`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};
use relume_core::bvh::{Bvh, BvhBuffers, BvhNode, PackedTriangle};
use relume_core::geometry::{longest_side, Surface, Triangle, View};
use relume_core::material::{
    Kind, Material, SurfaceMaterial, TextureGrid, TextureId, TextureInfo, Textures, Wrap,
};
use relume_core::render::RAY_EPSILON;
use relume_core::scene::{
    BuiltCounts, BuiltStorage, GroupPlane, LightTriangle, Scene, SceneStorage,
};

use crate::error::Error;
use crate::fsutil;
use crate::images;
use crate::materials_file::{self, MaterialDesc, MaterialsDesc, Model};
use crate::obj::{self, ObjObject};
use crate::scene_file::{self, GroupDesc, GroupKind, SceneDesc};
use crate::text::significant;

/// Where the materials of the groups come from.
pub enum MaterialSource<'a> {
    /// One or more materials files; every group must get exactly one material.
    Files(&'a [MaterialsDesc]),
    /// A neutral grey diffuse for every group: for work that needs geometry only
    /// (ray benchmarks, pixel labels).
    GeometryOnly,
}

/// A scene with all of its buffers, ready to lend to the core.
pub struct OwnedScene {
    pub desc: SceneDesc,
    /// Fixed once assembled (read with [`OwnedScene::triangles`]): the BVH and the light
    /// table are built for them once, whatever the materials do.
    triangles: Vec<Triangle>,
    /// Group names, indexed by `Surface::Group`.
    pub group_names: Vec<String>,
    /// Light object names, indexed by `Surface::Light`.
    pub light_names: Vec<String>,
    pub views: Vec<View>,
    /// The point of the scene's own coordinates that `triangles` and `views` are placed
    /// relative to (`far_scene_centre`): zero unless the scene lies far from its origin.
    pub origin: [f64; 3],
    pub materials: Vec<SurfaceMaterial>,
    /// Fixed once assembled, as the triangles are ([`OwnedScene::light_radiance`]).
    light_radiance: Vec<Vec3>,
    pub texture_infos: Vec<TextureInfo>,
    pub texels: Vec<Vec3>,
    bvh_nodes: Vec<BvhNode>,
    bvh_packed: Vec<PackedTriangle>,
    light_table: Vec<LightTriangle>,
    group_planes: Vec<GroupPlane>,
    /// What the first build filled in the buffers; every later build reuses it.
    built: Option<BuiltCounts>,
    /// The views a `--view` flag selected ([`OwnedScene::select_views`]; all when empty):
    /// the checks at build look at these alone, so an unselected view does not refuse a
    /// render of the others.
    selected_views: Vec<String>,
    /// Faces of the shown objects that cross themselves, one warning per OBJ file
    /// ([`crate::obj::crossing_face_warnings`]).
    pub crossing_face_warnings: Vec<String>,
}

/// An error when every face of the light `object` is degenerate: a light of no area
/// emits nothing, and rendered only black with a warning that could not say why.
fn refuse_a_light_without_area(object: &ObjObject) -> Result<(), Error> {
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
fn refuse_a_light_triangle_twice<'o>(
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
fn refuse_overlapping_light_faces(
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
fn refuse_offsets_larger_than_a_light(
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
fn refuse_offsets_far_against_the_views(
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
fn bounds<'a>(objects: impl Iterator<Item = &'a ObjObject>) -> ([f64; 3], [f64; 3]) {
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

/// Reads scene.toml and its OBJ files and checks that objects, groups and lights agree.
pub fn load_scene(scene_path: &Path) -> Result<(SceneDesc, Vec<ObjObject>), Error> {
    with_objects(scene_file::load_scene(scene_path)?)
}

/// [`load_scene`] of a template, which may have no `[[view]]`
/// ([`scene_file::load_template`]).
pub fn load_template(scene_path: &Path) -> Result<(SceneDesc, Vec<ObjObject>), Error> {
    with_objects(scene_file::load_template(scene_path)?)
}

/// The scene's OBJ objects, read and checked against it.
fn with_objects(desc: SceneDesc) -> Result<(SceneDesc, Vec<ObjObject>), Error> {
    let mut objects = Vec::new();
    for file in &desc.geometry {
        objects.extend(obj::load_obj(file)?);
    }
    scene_file::check_objects(&desc, &objects)?;
    Ok((desc, objects))
}

/// Reads a scene and assembles it with the given materials.
pub fn load_and_assemble(
    scene_path: &Path,
    materials: MaterialSource,
) -> Result<OwnedScene, Error> {
    let (desc, objects) = load_scene(scene_path)?;
    assemble(desc, &objects, materials)
}

fn kind_of(desc: &SceneDesc, group: &str) -> Option<GroupKind> {
    desc.groups.iter().find(|g| g.name == group).map(|g| g.kind)
}

/// Builds the buffers: triangles tagged with their group or light, views, materials and
/// textures. Objects listed in `hide` are left out.
pub fn assemble(
    desc: SceneDesc,
    objects: &[ObjObject],
    materials: MaterialSource,
) -> Result<OwnedScene, Error> {
    let scene_path = desc.path.clone();
    let core_err = |what: &str, e| Error::core(format!("{}: {what}", scene_path.display()), e);

    let group_names: Vec<String> = desc.groups.iter().map(|g| g.name.clone()).collect();
    let light_names: Vec<String> = desc.lights.iter().map(|l| l.object.clone()).collect();
    let mut surface_of: HashMap<&str, Surface> = HashMap::new();
    for (gi, g) in desc.groups.iter().enumerate() {
        for o in &g.objects {
            surface_of.insert(o.as_str(), Surface::Group(gi as u16));
        }
    }
    for (li, l) in desc.lights.iter().enumerate() {
        surface_of.insert(l.object.as_str(), Surface::Light(li as u16));
    }
    if group_names.len() > relume_core::config::MAX_GROUPS {
        return Err(core_err(
            "groups",
            relume_core::Error::Capacity {
                what: "MAX_GROUPS",
                max: relume_core::config::MAX_GROUPS,
                needed: group_names.len(),
            },
        ));
    }

    if desc.views.len() > relume_core::config::MAX_VIEWS {
        return Err(core_err(
            "views",
            relume_core::Error::Capacity {
                what: "MAX_VIEWS",
                max: relume_core::config::MAX_VIEWS,
                needed: desc.views.len(),
            },
        ));
    }

    let origin = far_scene_centre(
        objects
            .iter()
            .filter(|o| !desc.hide.iter().any(|h| h == &o.name)),
    );
    let mut triangles = Vec::new();
    let mut light_triangles = HashMap::new();
    // Where each light object's triangles start in `triangles`.
    let mut light_objects: Vec<(usize, &ObjObject)> = Vec::new();
    for object in objects {
        if desc.hide.iter().any(|h| h == &object.name) {
            continue;
        }
        let Some(&surface) = surface_of.get(object.name.as_str()) else {
            return Err(Error::input(
                &object.file,
                format!(
                    "object '{}' is in no group, is no light and is not hidden",
                    object.name
                ),
            ));
        };
        if let Surface::Light(_) = surface {
            refuse_a_light_without_area(object)?;
            refuse_a_light_triangle_twice(object, &mut light_triangles)?;
            light_objects.push((triangles.len(), object));
        }
        for (i, v) in object.triangles.iter().enumerate() {
            let uv = match &object.uvs {
                Some(uvs) => uvs[i].map(Vec2::from),
                None => [Vec2::ZERO; 3],
            };
            triangles.push(Triangle {
                v: v.map(|p| moved(p, origin)),
                uv,
                surface,
            });
        }
    }
    relume_core::error::check_capacity(
        "MAX_TRIANGLES",
        relume_core::config::MAX_TRIANGLES,
        triangles.len(),
    )
    .map_err(|e| core_err("triangles", e))?;
    refuse_overlapping_light_faces(&triangles, &light_objects, origin)?;
    refuse_offsets_larger_than_a_light(&desc, &triangles, &light_names, objects)?;

    let mut views = Vec::with_capacity(desc.views.len());
    for v in &desc.views {
        let view = v
            .view()
            .map_err(|e| core_err(&format!("view '{}'", v.name), e))?;
        views.push(View {
            position: moved(v.position, origin),
            ..view
        });
    }

    let light_radiance: Vec<Vec3> = desc.lights.iter().map(|l| Vec3::from(l.radiance)).collect();

    let mut texture_infos = Vec::new();
    let mut texels = Vec::new();
    let materials = match materials {
        MaterialSource::GeometryOnly => vec![
            SurfaceMaterial {
                material: Material::Diffuse {
                    rho_d: Vec3::splat(0.5)
                },
                diffuse_map: None
            };
            group_names.len()
        ],
        MaterialSource::Files(files) => {
            resolve_materials(&desc, files, &mut texture_infos, &mut texels)?
        }
    };

    check_texture_coordinates(&desc, objects, &materials)?;

    let (n_nodes, n_packed) = Bvh::buffer_sizes(triangles.len());
    let n_light_tris = triangles
        .iter()
        .filter(|t| matches!(t.surface, Surface::Light(_)))
        .count();
    let group_count = materials.len();
    let crossing_face_warnings =
        crate::obj::crossing_face_warnings(objects.iter().filter(|o| !desc.hide.contains(&o.name)));
    Ok(OwnedScene {
        desc,
        triangles,
        group_names,
        light_names,
        views,
        origin,
        materials,
        light_radiance,
        texture_infos,
        texels,
        bvh_nodes: vec![BvhNode::default(); n_nodes],
        bvh_packed: vec![PackedTriangle::default(); n_packed],
        light_table: vec![LightTriangle::default(); n_light_tris],
        group_planes: vec![GroupPlane::default(); group_count],
        built: None,
        selected_views: Vec::new(),
        crossing_face_warnings,
    })
}

/// The point a scene is moved to the origin by: the centre of its bounding box where the
/// scene lies farther from its origin than it is large (the centre's largest coordinate
/// beyond the box's longest side), else zero (the scene stays where it is). In 32-bit
/// floats a point's rounding, and with it every ray's offset from the surface it leaves,
/// grows with its distance from the origin: the cornell room moved 100 units off it
/// rendered 1% bright, 1000 units off 8%, 10000 off twice as bright, and 1e5 off black (a
/// building in site or map coordinates is that far). The vertices are read in 64 bits and
/// rounded to 32 only after the move, and the views move with them: what is rendered does
/// not change, only where the arithmetic happens.
fn far_scene_centre<'a>(objects: impl Iterator<Item = &'a ObjObject>) -> [f64; 3] {
    let (lo, hi) = bounds(objects);
    let centre: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
    let size = (0..3)
        .map(|k| hi[k] - lo[k])
        .fold(f64::NEG_INFINITY, f64::max);
    let distance = centre.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    // Without vertices the size is negative: no move.
    if size < 0.0 || distance <= size {
        return [0.0; 3];
    }
    centre
}

/// `p - origin`, in 64 bits, rounded to 32.
fn moved(p: [f64; 3], origin: [f64; 3]) -> Vec3 {
    Vec3::new(
        (p[0] - origin[0]) as f32,
        (p[1] - origin[1]) as f32,
        (p[2] - origin[2]) as f32,
    )
}

/// The first object of `group` in the scene (not hidden) without texture coordinates on
/// every face, which a diffuse map needs: without them every point would read the map at
/// (0, 0), one texel for the whole object.
pub fn unmapped_object<'a>(
    desc: &SceneDesc,
    objects: &'a [ObjObject],
    group: &GroupDesc,
) -> Option<&'a ObjObject> {
    objects.iter().find(|o| {
        o.uvs.is_none() && !desc.hide.contains(&o.name) && group.objects.contains(&o.name)
    })
}

/// A group whose material has a diffuse map is mapped by its OBJ texture coordinates: each
/// of its objects must have them ([`unmapped_object`]).
fn check_texture_coordinates(
    desc: &SceneDesc,
    objects: &[ObjObject],
    materials: &[SurfaceMaterial],
) -> Result<(), Error> {
    for (g, material) in desc.groups.iter().zip(materials) {
        if material.diffuse_map.is_none() {
            continue;
        }
        if let Some(o) = unmapped_object(desc, objects, g) {
            let what = format!(
                "object '{}' of group '{}' has no texture coordinates (vt on every face), but the group's material has a diffuse_map",
                o.name, g.name
            );
            return Err(match crate::obj::object_line(&o.file, &o.name) {
                Some(line) => Error::at_line(&o.file, line, what),
                None => Error::input(&o.file, what),
            });
        }
    }
    Ok(())
}

/// The kind a group's material `m` (from `file`) is rendered with: the scene's, or for a
/// group of kind "auto" the one the material gives (a recovery writes the kind it chose);
/// either without a lobe, whose reflectance does not depend on it. A material whose kind
/// contradicts the scene's, or a lobe with no kind from either, is an error at its line.
fn material_kind(desc: &SceneDesc, file: &MaterialsDesc, m: &MaterialDesc) -> Result<Kind, Error> {
    let scene_kind = kind_of(desc, &m.group).and_then(GroupKind::given);
    match (scene_kind, m.kind) {
        (Some(s), Some(k)) if s != k => Err(Error::at_line(
            &file.path,
            m.line,
            format!(
                "group '{}' is kind \"{}\" in {}, but its material says kind \"{}\"",
                m.group,
                materials_file::kind_name(s),
                desc.path.display(),
                materials_file::kind_name(k)
            ),
        )),
        (Some(kind), _) | (None, Some(kind)) => Ok(kind),
        (None, None) if !m.model.has_lobe() => Ok(Kind::Plastic),
        (None, None) => Err(Error::at_line(
            &file.path,
            m.line,
            format!(
                "group '{}' has kind \"auto\" in {}: a material with a lobe needs its kind, `kind = \"plastic\"` or `kind = \"metal\"` in the material (a recovery writes the kind it chose)",
                m.group,
                desc.path.display()
            ),
        )),
    }
}

/// The texture of the diffuse map `map` (`context` names the material that gives it, for
/// a capacity error): read, checked and appended to `texture_infos` and `texels` the first
/// time, and found in `maps_read` after that. A map that groups share is held once: a
/// 6000x6000 map on the floor and the ceiling was counted twice against MAX_TEXELS, and
/// refused.
fn map_texture(
    map: &Path,
    wrap: Wrap,
    context: impl Fn() -> String,
    maps_read: &mut Vec<(PathBuf, TextureId)>,
    texture_infos: &mut Vec<TextureInfo>,
    texels: &mut Vec<Vec3>,
) -> Result<TextureId, Error> {
    let info_of = |id: &TextureId| texture_infos[id.0 as usize];
    if let Some(&(_, id)) = maps_read
        .iter()
        .find(|(p, id)| fsutil::same_file(p, map) && info_of(id).grid.wrap == wrap)
    {
        return Ok(id);
    }
    // Read before with the other wrap (tiled on one group, clamped on another): the same
    // texels, read another way.
    if let Some((_, read)) = maps_read.iter().find(|(p, _)| fsutil::same_file(p, map)) {
        let first = info_of(read);
        let info = TextureInfo {
            grid: TextureGrid { wrap, ..first.grid },
            ..first
        };
        let id = push_texture_info(info, &context, map, texture_infos)?;
        maps_read.push((map.to_path_buf(), id));
        return Ok(id);
    }
    // Its size is weighed against the texels left before it is decoded.
    let image = images::read_map(map, texels.len(), &context)?;
    // A map holds diffuse reflectances, which `color` bounds by 1 as well.
    images::reject_value(
        map,
        &image,
        |v| v > 1.0,
        "is above 1: a diffuse map holds reflectances in [0, 1]",
    )?;
    let info = TextureInfo {
        grid: TextureGrid {
            width: image.width,
            height: image.height,
            wrap,
        },
        offset: texels.len(),
    };
    let id = push_texture_info(info, &context, map, texture_infos)?;
    texels.extend(image.pixels.iter().map(|p| Vec3::from(*p)));
    maps_read.push((map.to_path_buf(), id));
    Ok(id)
}

/// Appends `info` to `texture_infos`, within the core's `MAX_TEXTURES`.
fn push_texture_info(
    info: TextureInfo,
    context: impl Fn() -> String,
    map: &Path,
    texture_infos: &mut Vec<TextureInfo>,
) -> Result<TextureId, Error> {
    if texture_infos.len() >= relume_core::config::MAX_TEXTURES {
        return Err(Error::core(
            format!("{}: {}", context(), map.display()),
            relume_core::Error::Capacity {
                what: "MAX_TEXTURES",
                max: relume_core::config::MAX_TEXTURES,
                needed: texture_infos.len() + 1,
            },
        ));
    }
    texture_infos.push(info);
    Ok(TextureId((texture_infos.len() - 1) as u16))
}

/// One material per group, from one or more files: an error names the group and the
/// file(s) when a group has none or two, or when a file names a group the scene lacks.
fn resolve_materials(
    desc: &SceneDesc,
    files: &[MaterialsDesc],
    texture_infos: &mut Vec<TextureInfo>,
    texels: &mut Vec<Vec3>,
) -> Result<Vec<SurfaceMaterial>, Error> {
    // The maps read so far, by the file they came from.
    let mut maps_read: Vec<(PathBuf, TextureId)> = Vec::new();
    let mut found: Vec<Option<(PathBuf, usize, SurfaceMaterial)>> = vec![None; desc.groups.len()];
    for file in files {
        for m in &file.materials {
            let Some(gi) = desc.groups.iter().position(|g| g.name == m.group) else {
                return Err(Error::at_line(
                    &file.path,
                    m.line,
                    format!(
                        "material for group '{}', which scene {} does not have",
                        m.group,
                        desc.path.display()
                    ),
                ));
            };
            if let Some((other, other_line, _)) = &found[gi] {
                return Err(Error::at_line(
                    &file.path,
                    m.line,
                    format!(
                        "group '{}' has two materials: here and at {}:{}",
                        m.group,
                        other.display(),
                        other_line
                    ),
                ));
            }
            let kind = material_kind(desc, file, m)?;
            let textured = matches!(
                m.model,
                Model::TexturedDiffuse | Model::TexturedIsotropic | Model::TexturedAnisotropic
            );
            let diffuse_map = if textured {
                let Some(map) = &m.diffuse_map else {
                    return Err(Error::at_line(
                        &file.path,
                        m.line,
                        "textured material without diffuse_map",
                    ));
                };
                if kind == Kind::Metal {
                    return Err(Error::at_line(
                        &file.path,
                        m.line,
                        format!(
                            "group '{}' is metal: textured models apply to plastic groups",
                            m.group
                        ),
                    ));
                }
                Some(map_texture(
                    map,
                    m.map_wrap,
                    || format!("{}:{}: group '{}'", file.path.display(), m.line, m.group),
                    &mut maps_read,
                    texture_infos,
                    texels,
                )?)
            } else {
                None
            };
            let material = Material::from_params(kind, Vec3::from(m.color_or_white()), m.params())
                .map_err(|e| {
                    Error::at_line(&file.path, m.line, format!("group '{}': {e}", m.group))
                })?;
            found[gi] = Some((
                file.path.clone(),
                m.line,
                SurfaceMaterial {
                    material,
                    diffuse_map,
                },
            ));
        }
    }
    let mut out = Vec::with_capacity(found.len());
    for (gi, f) in found.into_iter().enumerate() {
        match f {
            Some((_, _, m)) => out.push(m),
            None => {
                let names: Vec<String> =
                    files.iter().map(|f| f.path.display().to_string()).collect();
                let group = &desc.groups[gi];
                return Err(Error::at_line(
                    &desc.path,
                    group.line,
                    format!(
                        "group '{}' has no material in {}",
                        group.name,
                        names.join(", ")
                    ),
                ));
            }
        }
    }
    Ok(out)
}

/// How far past [0, 1] a texture coordinate may reach, from an exporter's rounding,
/// before it is taken to mean tiles.
const UV_SLACK: f32 = 1e-3;

/// Whether texture coordinate `(u, v)` lies past [0, 1]^2 by more than `UV_SLACK`: a
/// texture laid over its face as tiles (OpenGL's and the exporters' reading).
pub fn past_the_unit_square([u, v]: [f32; 2]) -> bool {
    let past = |x: f32| !(-UV_SLACK..=1.0 + UV_SLACK).contains(&x);
    past(u) || past(v)
}

impl OwnedScene {
    /// The scene's triangles, fixed once assembled.
    pub fn triangles(&self) -> &[Triangle] {
        &self.triangles
    }

    /// Whether some texture coordinate of group `g`'s faces lies past [0, 1]^2
    /// ([`past_the_unit_square`]): its texture is laid over it as tiles, which a map read
    /// clamped cannot show.
    pub fn tiles_its_map(&self, g: usize) -> bool {
        self.triangles
            .iter()
            .filter(|t| t.surface == Surface::Group(g as u16))
            .flat_map(|t| t.uv)
            .any(|uv| past_the_unit_square(uv.to_array()))
    }

    /// A warning for each group whose map is read clamped (no `diffuse_map_wrap =
    /// "repeat"`) over coordinates that reach past [0, 1] ([`Self::tiles_its_map`]):
    /// every point past 1 reads the map's border texels, where the coordinates most
    /// likely mean tiles.
    pub fn clamped_tile_warnings(&self) -> Vec<String> {
        (self.materials.iter().enumerate())
            .filter_map(|(g, m)| {
                let info = self.texture_infos.get(m.diffuse_map?.0 as usize)?;
                (info.grid.wrap == Wrap::Clamp && self.tiles_its_map(g)).then(|| {
                    format!(
                        "group '{}': its texture coordinates reach past [0, 1], where its diffuse_map is read clamped (every point past 1 reads the map's border texels); if the texture is tiled over it, say diffuse_map_wrap = \"repeat\" in its material",
                        self.group_names[g]
                    )
                })
            })
            .collect()
    }

    /// Each light's radiance, fixed once assembled.
    pub fn light_radiance(&self) -> &[Vec3] {
        &self.light_radiance
    }

    /// Lends the buffers to the core and builds the scene. Recovery builds the scene for
    /// every evaluation with new materials only, so the BVH and the light table are built
    /// on the first call alone: the triangles and lights cannot change after assembly.
    /// (They were compared with a copy at every call, which on a scene of 600,000
    /// triangles took 3.6% of a recovery's CPU time on one thread, docs/renderer-vs-radiance.md.)
    /// A warning for each textured plastic of `files` whose diffuse map, with its
    /// specularity, reflects more than the light it receives somewhere (a texel plus the
    /// specularity above 1): the map holds the diffuse reflectance, at most 1 - specularity
    /// there; a map of 1.0 under a specularity of 0.05 was rendered without a word.
    pub fn map_energy_warnings(&self, files: &[MaterialsDesc]) -> Vec<String> {
        let mut warnings = Vec::new();
        for file in files {
            for m in &file.materials {
                let s = m.specularity.unwrap_or(0.0);
                let group = self.group_names.iter().position(|n| *n == m.group);
                let map = group.and_then(|g| self.materials.get(g)?.diffuse_map);
                let (Some(map), true) = (map, s > 0.0) else {
                    continue;
                };
                let info = self.texture_infos[map.0 as usize];
                let (w, h) = (info.grid.width as usize, info.grid.height as usize);
                let texels = &self.texels[info.offset..info.offset + w * h];
                let over = texels.iter().enumerate().find_map(|(i, t)| {
                    let c = (0..3).find(|&c| t[c] + s > 1.0)?;
                    Some((i, c, t[c]))
                });
                if let Some((i, c, v)) = over {
                    warnings.push(format!(
                        "{}:{}: group '{}': its diffuse map reaches {v} in channel {} at texel (x {}, y {}), which with specularity {s} reflects {} of the light it receives, more than all of it (a map holds the diffuse reflectance, at most 1 - specularity); rendered as given",
                        file.path.display(),
                        m.line,
                        m.group,
                        ["R", "G", "B"][c],
                        i % w,
                        i / w,
                        v + s
                    ));
                }
            }
        }
        warnings
    }

    /// Selects the views a `--view` flag names (all when `names` is empty), refusing a
    /// name the scene does not have; to be called before the first [`OwnedScene::build`].
    pub fn select_views(&mut self, names: &[String]) -> Result<(), Error> {
        self.desc.check_view_names(names)?;
        self.selected_views = names.to_vec();
        Ok(())
    }

    pub fn build(&mut self) -> Result<Scene<'_>, Error> {
        let path = self.desc.path.display().to_string();
        let counts = match self.built {
            Some(counts) => counts,
            None => {
                let textures = Textures::new(&self.texture_infos, &self.texels)
                    .map_err(|e| Error::core(format!("{path}: textures"), e))?;
                let counts = Scene::build(
                    &self.triangles,
                    &self.materials,
                    &self.light_radiance,
                    textures,
                    SceneStorage {
                        bvh: BvhBuffers {
                            nodes: &mut self.bvh_nodes,
                            packed: &mut self.bvh_packed,
                        },
                        light_table: &mut self.light_table,
                        group_planes: &mut self.group_planes,
                    },
                )
                .map_err(|e| Error::core(format!("{path}: building the scene"), e))
                .and_then(|scene| {
                    refuse_offsets_far_against_the_views(
                        &self.desc,
                        &scene,
                        &self.views,
                        &self.selected_views,
                        &self.group_names,
                        &self.light_names,
                    )?;
                    Ok(scene.built_counts())
                })?;
                self.built = Some(counts);
                counts
            }
        };
        let textures = Textures::new(&self.texture_infos, &self.texels)
            .map_err(|e| Error::core(format!("{path}: textures"), e))?;
        Scene::from_built(
            &self.triangles,
            &self.materials,
            &self.light_radiance,
            textures,
            BuiltStorage {
                nodes: &self.bvh_nodes,
                packed: &self.bvh_packed,
                light_table: &self.light_table,
                group_planes: &self.group_planes,
                counts,
            },
        )
        .map_err(|e| Error::core(format!("{path}: building the scene"), e))
    }

    /// Per group with an anisotropic material, the share of its area where the material's
    /// direction is parallel to the surface normal, where the lobe renders isotropic
    /// (reflectance.md): `(group, share)` for the groups where the share is not zero. A
    /// direction given along a flat group's normal is a mistake the renderer cannot see.
    pub fn isotropic_fallbacks(&self) -> Vec<(usize, f64)> {
        let mut areas = vec![(0.0f64, 0.0f64); self.materials.len()];
        for t in &self.triangles {
            let Surface::Group(g) = t.surface else {
                continue;
            };
            let Some(SurfaceMaterial {
                material: Material::WardAnisotropic { direction, .. },
                ..
            }) = self.materials.get(g as usize)
            else {
                continue;
            };
            let n = t.normal_area2();
            let area = n.length() as f64;
            if area.is_nan() || area <= 0.0 {
                continue;
            }
            let entry = &mut areas[g as usize];
            entry.0 += area;
            if relume_core::material::anisotropic_falls_back(n.normalize(), *direction) {
                entry.1 += area;
            }
        }
        areas
            .iter()
            .enumerate()
            .filter(|(_, (_, fallback))| *fallback > 0.0)
            .map(|(g, (total, fallback))| (g, fallback / total))
            .collect()
    }

    /// The name of a surface, for reports.
    pub fn surface_name(&self, surface: Surface) -> &str {
        match surface {
            Surface::Group(g) => self.group_names.get(g as usize).map_or("?", |s| s.as_str()),
            Surface::Light(l) => self.light_names.get(l as usize).map_or("?", |s| s.as_str()),
        }
    }
}
