//! From validated descriptions (scene.toml, OBJ, materials.toml) to the buffers the core
//! borrows. [`OwnedScene`] owns every buffer; [`OwnedScene::build`] lends them to
//! `relume_core::scene::Scene::build`.
//!
//! `lights` checks the lights as placed (an area, no face twice, no offset that hides
//! one); `materials` resolves each group's material and diffuse map from the materials
//! files.

use std::collections::HashMap;
use std::path::Path;

use glam::{Vec2, Vec3};
use relume_core::bvh::{Bvh, BvhBuffers, BvhNode, PackedTriangle};
use relume_core::geometry::{Surface, Triangle, View};
use relume_core::material::{Material, SurfaceMaterial, TextureInfo, Textures, Wrap};
use relume_core::scene::{
    BuiltCounts, BuiltStorage, GroupPlane, LightTriangle, Scene, SceneStorage,
};

use crate::error::Error;
use crate::materials_file::MaterialsDesc;
use crate::obj::{self, ObjObject};
use crate::scene_file::{self, SceneDesc};

mod lights;
mod materials;

use lights::{
    bounds, refuse_a_light_triangle_twice, refuse_a_light_without_area,
    refuse_offsets_far_against_the_views, refuse_offsets_larger_than_a_light,
    refuse_overlapping_light_faces,
};
use materials::{check_texture_coordinates, resolve_materials};
pub use materials::{past_the_unit_square, unmapped_object};

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
