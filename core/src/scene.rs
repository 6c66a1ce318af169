//! The assembled scene: triangles, their BVH, one material per group, light sources and
//! textures, all over storage lent by the caller and checked against [`crate::config`].

use crate::bvh::{Bvh, BvhBuffers, BvhNode, Hit, PackedTriangle};
use crate::config;
use crate::error::{check_capacity, Error};
use crate::geometry::{longest_side, Ray, Surface, Triangle};
use crate::material::{Material, SurfaceMaterial, Textures};
use crate::math::{self, Vec3};

/// One emitting triangle in the light-sampling table.
#[derive(Clone, Copy, Debug, Default)]
pub struct LightTriangle {
    /// Index into the scene's triangles.
    pub triangle: u32,
    /// Cumulative selection probability up to and including this entry (last is 1).
    pub cdf: f32,
    /// Probability of selecting this entry.
    pub pick_pdf: f32,
}

/// A point sampled on a light source.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    pub point: Vec3,
    /// Unit front normal of the emitting triangle.
    pub normal: Vec3,
    pub radiance: Vec3,
    /// Area pdf of the sample (selection probability / triangle area).
    pub pdf_area: f32,
}

/// A mirror group whose triangles lie in one plane. Light that reaches a surface by way of
/// it is sampled through the light's image in that plane (RADIANCE's virtual light
/// sources), where BSDF sampling alone finds it only when a bounce happens to hit the
/// light: heavy-tailed noise wherever a room has a mirror.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MirrorPlane {
    pub group: u16,
    /// Unit normal of the plane (the mirror reflects on both sides).
    pub normal: Vec3,
    /// `normal . x` for the plane's points `x`.
    pub offset: f32,
    /// The mirror's reflectance, as its BSDF applies it.
    pub rho: Vec3,
    /// Bounds of the mirror's triangles, padded by the flatness tolerance: a ray that
    /// crosses the plane outside them cannot meet the mirror, and needs no tracing.
    pub bounds: (Vec3, Vec3),
}

/// The scene's planar mirrors (at most [`config::MAX_MIRROR_PLANES`]; the groups after
/// those are left to BSDF sampling).
#[derive(Clone, Copy, Debug, Default)]
pub struct MirrorPlanes {
    planes: [MirrorPlane; config::MAX_MIRROR_PLANES],
    len: usize,
}

impl MirrorPlanes {
    /// The groups with a mirror material whose triangles (the degenerate ones aside) share
    /// one plane, in group order: of the first [`config::MAX_MIRROR_PLANES`] mirror groups
    /// that reflect, those that `planes` (from [`GroupPlane::find_all`]) finds planar.
    fn find(materials: &[SurfaceMaterial], planes: &[GroupPlane], scene_size: f32) -> MirrorPlanes {
        let mut kept = MirrorPlanes::default();
        let mut candidates = 0usize;
        for (g, m) in materials.iter().enumerate() {
            let Material::Mirror { rho } = m.material else {
                continue;
            };
            let rho = rho.max(Vec3::ZERO);
            if candidates >= config::MAX_MIRROR_PLANES || !(rho.max_element() > 0.0) {
                continue;
            }
            candidates += 1;
            let Some(plane) = planes.get(g).filter(|p| p.planar && p.normal != Vec3::ZERO) else {
                continue;
            };
            let (lo, hi) = plane.bounds;
            let pad = PLANE_TOLERANCE * lo.abs().max(hi.abs()).max_element().max(scene_size);
            kept.planes[kept.len] = MirrorPlane {
                group: g as u16,
                normal: plane.normal,
                offset: plane.offset,
                rho,
                bounds: (lo - Vec3::splat(pad), hi + Vec3::splat(pad)),
            };
            kept.len += 1;
        }
        kept
    }

    pub fn as_slice(&self) -> &[MirrorPlane] {
        &self.planes[..self.len]
    }

    /// True when `group` is one of the planar mirrors sampled through.
    pub fn contains(&self, group: u16) -> bool {
        self.as_slice().iter().any(|p| p.group == group)
    }
}

/// One group's triangles as a mirror would be sampled through them: the plane of its first
/// triangle of any area, whether every other one lies in it, and their bounds. Found for
/// every group when the scene is built, so that new materials (a group made a mirror) cost
/// no pass over the triangles: on a scene of 600,000 triangles that pass took 1.3% of a
/// recovery's CPU time, on one thread, at every evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroupPlane {
    normal: Vec3,
    offset: f32,
    bounds: (Vec3, Vec3),
    planar: bool,
}

impl Default for GroupPlane {
    /// A group of no triangles: no plane, bounds that anything grows.
    fn default() -> GroupPlane {
        GroupPlane {
            normal: Vec3::ZERO,
            offset: 0.0,
            bounds: (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            planar: true,
        }
    }
}

impl GroupPlane {
    /// Fills `planes[g]` for every group `g` of `triangles` (`planes` as long as the
    /// groups), in the triangles' order.
    fn find_all(
        triangles: &[Triangle],
        scene_size: f32,
        planes: &mut [GroupPlane],
    ) -> Result<(), Error> {
        planes.fill(GroupPlane::default());
        let len = planes.len();
        for t in triangles {
            let Surface::Group(g) = t.surface else {
                continue;
            };
            let Some(plane) = planes.get_mut(g as usize) else {
                return Err(Error::BufferTooSmall {
                    what: "group_planes",
                    needed: g as usize + 1,
                    got: len,
                });
            };
            let n2 = t.normal_area2();
            let area2 = n2.length();
            if !(area2 > 0.0) {
                continue;
            }
            let (lo, hi) = t.bounds();
            plane.bounds = (plane.bounds.0.min(lo), plane.bounds.1.max(hi));
            if plane.normal == Vec3::ZERO {
                plane.normal = n2 / area2;
                plane.offset = plane.normal.dot(t.v[0]);
                continue;
            }
            let scale =
                t.v.iter()
                    .fold(scene_size, |m, v| m.max(v.abs().max_element()));
            let tolerance = PLANE_TOLERANCE * scale;
            let parallel = math::abs(plane.normal.dot(n2 / area2)) >= 1.0 - PLANE_TOLERANCE;
            let on_plane =
                t.v.iter()
                    .all(|v| math::abs(plane.normal.dot(*v) - plane.offset) <= tolerance);
            if !(parallel && on_plane) {
                plane.planar = false;
            }
        }
        Ok(())
    }
}

/// Relative tolerance of a mirror's flatness: normals within it of parallel, vertices
/// within it (times the scene's size, or the coordinates' where larger) of the plane.
const PLANE_TOLERANCE: f32 = 1e-5;

/// The buffers a [`Scene`] is built over, lent by the caller.
pub struct SceneStorage<'a> {
    pub bvh: BvhBuffers<'a>,
    /// At least as long as the number of emitting triangles.
    pub light_table: &'a mut [LightTriangle],
    /// One per group (as long as the materials).
    pub group_planes: &'a mut [GroupPlane],
}

/// Everything the renderer needs, read-only.
#[derive(Clone, Copy)]
pub struct Scene<'a> {
    pub triangles: &'a [Triangle],
    pub materials: &'a [SurfaceMaterial],
    /// Radiance of each light source, indexed by `Surface::Light`.
    pub light_radiance: &'a [Vec3],
    pub textures: Textures<'a>,
    bvh: Bvh<'a>,
    light_table: &'a [LightTriangle],
    light_guide: LightGuide,
    /// The groups and lights the triangles name ([`BuiltCounts::groups_named`]).
    named: (usize, usize),
    mirrors: MirrorPlanes,
    size: f32,
}

/// What [`Scene::build`] filled in its storage: with [`Scene::from_built`], the same
/// geometry and lights can be given new materials without building again.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuiltCounts {
    /// BVH nodes in use.
    pub nodes: usize,
    /// Entries of the light table in use.
    pub lights: usize,
    /// The groups and the lights the triangles name (the largest index + 1 of each): the
    /// materials and radiances given later must cover them.
    pub groups_named: usize,
    pub lights_named: usize,
    /// The scene's size ([`Scene::size`]).
    pub size: f32,
}

/// Storage that [`Scene::build`] filled, read-only.
pub struct BuiltStorage<'a> {
    pub nodes: &'a [BvhNode],
    pub packed: &'a [PackedTriangle],
    pub light_table: &'a [LightTriangle],
    pub group_planes: &'a [GroupPlane],
    pub counts: BuiltCounts,
}

/// Checks the tables against the capacities and each other, but for the groups and lights
/// the triangles name ([`named_by`], [`check_named`]).
fn check_tables(
    n_triangles: usize,
    materials: &[SurfaceMaterial],
    light_radiance: &[Vec3],
    textures: &Textures,
) -> Result<(), Error> {
    check_capacity("MAX_TRIANGLES", config::MAX_TRIANGLES, n_triangles)?;
    check_capacity("MAX_GROUPS", config::MAX_GROUPS, materials.len())?;
    check_capacity("MAX_LIGHTS", config::MAX_LIGHTS, light_radiance.len())?;
    for m in materials {
        if let Some(id) = m.diffuse_map {
            if id.0 as usize >= textures.len() {
                return Err(Error::BadIndex {
                    what: "texture",
                    index: id.0 as usize,
                    len: textures.len(),
                });
            }
        }
    }
    for r in light_radiance {
        if !math::is_finite(*r) || r.min_element() < 0.0 {
            return Err(Error::InvalidValue {
                what: "light radiance must be finite and >= 0",
            });
        }
    }
    Ok(())
}

/// The groups and the lights `triangles` name: the largest index + 1 of each (0 for none).
fn named_by(triangles: &[Triangle]) -> (usize, usize) {
    let (mut groups, mut lights) = (0usize, 0usize);
    for t in triangles {
        match t.surface {
            Surface::Group(g) => groups = groups.max(g as usize + 1),
            Surface::Light(l) => lights = lights.max(l as usize + 1),
        }
    }
    (groups, lights)
}

/// An error unless `materials` and `light_radiance` cover the groups and lights named.
fn check_named(
    (groups, lights): (usize, usize),
    materials: &[SurfaceMaterial],
    light_radiance: &[Vec3],
) -> Result<(), Error> {
    if groups > materials.len() {
        return Err(Error::BadIndex {
            what: "group",
            index: groups - 1,
            len: materials.len(),
        });
    }
    if lights > light_radiance.len() {
        return Err(Error::BadIndex {
            what: "light",
            index: lights - 1,
            len: light_radiance.len(),
        });
    }
    Ok(())
}

/// Buckets of the light table's cdf: where a search for `u` may start and end. A binary
/// search over the whole table cost a scene whose lamps were 8,000 triangles 5.7% of a
/// recovery's CPU time, a chain of dependent loads that mostly missed the cache.
#[derive(Clone, Copy, Debug)]
struct LightGuide {
    /// `starts[j]`: how many entries have a cdf of at most `j / LIGHT_GUIDE_BUCKETS`.
    starts: [u32; LIGHT_GUIDE_BUCKETS + 1],
}

/// A power of two, so that `u * LIGHT_GUIDE_BUCKETS` and `j / LIGHT_GUIDE_BUCKETS` are
/// exact and a bucket holds exactly the `u` it should.
const LIGHT_GUIDE_BUCKETS: usize = 256;
const _: () = assert!(LIGHT_GUIDE_BUCKETS.is_power_of_two());

impl LightGuide {
    fn new(table: &[LightTriangle]) -> LightGuide {
        let mut starts = [0u32; LIGHT_GUIDE_BUCKETS + 1];
        for (j, start) in starts.iter_mut().enumerate() {
            let t = j as f32 / LIGHT_GUIDE_BUCKETS as f32;
            *start = table.partition_point(|e| e.cdf <= t) as u32;
        }
        LightGuide { starts }
    }

    /// `table.partition_point(|e| e.cdf <= u)`, the same index, searched in `u`'s bucket
    /// only: for `j / B <= u < (j + 1) / B` every entry before `starts[j]` has a cdf of at
    /// most `u` and none from `starts[j + 1]` on does.
    #[inline]
    fn pick(&self, table: &[LightTriangle], u: f32) -> usize {
        let at_most_u = |e: &LightTriangle| e.cdf <= u;
        if !(0.0..1.0).contains(&u) {
            return table.partition_point(at_most_u);
        }
        let j = ((u * LIGHT_GUIDE_BUCKETS as f32) as usize).min(LIGHT_GUIDE_BUCKETS - 1);
        let (lo, hi) = (self.starts[j] as usize, self.starts[j + 1] as usize);
        match table.get(lo..hi) {
            Some(bucket) => lo + bucket.partition_point(at_most_u),
            None => table.partition_point(at_most_u),
        }
    }
}

/// A light triangle's power, area times luminance, as the table weighs it: the f32
/// product where f32 holds it, else the product in f64 (a radiance the scene accepts on a
/// large triangle: 1e37 over 50 square units is 5e38, which overflowed to infinity and
/// made every pick probability inf / inf).
fn light_power(t: &Triangle, radiance: Vec3) -> f64 {
    let area = t.area();
    let luminance = math::luminance(radiance);
    let power = area * luminance;
    if power.is_finite() {
        return power as f64;
    }
    let [a, b, c] = t.v.map(|v| v.to_array().map(f64::from));
    let (e1, e2): ([f64; 3], [f64; 3]) = (
        core::array::from_fn(|k| b[k] - a[k]),
        core::array::from_fn(|k| c[k] - a[k]),
    );
    let n = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let area = 0.5 * libm::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    let [r, g, bl] = radiance.to_array().map(f64::from);
    area * (0.2126 * r + 0.7152 * g + 0.0722 * bl)
}

/// Fills the light-sampling table (emitting triangles picked in proportion to area times
/// luminance; switched-off lights are never picked). Returns the entries used.
fn fill_light_table(
    triangles: &[Triangle],
    light_radiance: &[Vec3],
    table: &mut [LightTriangle],
) -> Result<usize, Error> {
    let radiance_of = |l: u16| {
        light_radiance
            .get(l as usize)
            .copied()
            .unwrap_or(Vec3::ZERO)
    };
    let mut total_power = 0.0f64;
    let mut n_emitting = 0usize;
    for (i, t) in triangles.iter().enumerate() {
        let Surface::Light(l) = t.surface else {
            continue;
        };
        let power = light_power(t, radiance_of(l));
        if power > 0.0 {
            let Some(slot) = table.get_mut(n_emitting) else {
                return Err(Error::BufferTooSmall {
                    what: "light_table",
                    needed: n_emitting + 1,
                    got: table.len(),
                });
            };
            *slot = LightTriangle {
                triangle: i as u32,
                cdf: 0.0,
                pick_pdf: 0.0,
            };
            n_emitting += 1;
            total_power += power;
        }
    }
    let table = &mut table[..n_emitting];
    let mut running = 0.0f64;
    for entry in table.iter_mut() {
        let Some(t) = triangles.get(entry.triangle as usize) else {
            continue;
        };
        let Surface::Light(l) = t.surface else {
            continue;
        };
        let power = light_power(t, radiance_of(l));
        running += power;
        entry.pick_pdf = (power / total_power) as f32;
        entry.cdf = (running / total_power) as f32;
    }
    if let Some(last) = table.last_mut() {
        last.cdf = 1.0;
    }
    Ok(n_emitting)
}

impl<'a> Scene<'a> {
    /// Checks the tables against each other and the capacities, builds the BVH and the
    /// light-sampling table (emitting triangles picked in proportion to area times
    /// luminance; switched-off lights are never picked).
    pub fn build(
        triangles: &'a [Triangle],
        materials: &'a [SurfaceMaterial],
        light_radiance: &'a [Vec3],
        textures: Textures<'a>,
        storage: SceneStorage<'a>,
    ) -> Result<Scene<'a>, Error> {
        check_tables(triangles.len(), materials, light_radiance, &textures)?;
        let named = named_by(triangles);
        check_named(named, materials, light_radiance)?;
        let n_emitting = fill_light_table(triangles, light_radiance, storage.light_table)?;
        let light_table: &'a [LightTriangle] = storage.light_table;
        let bvh = Bvh::build(triangles, storage.bvh)?;
        let size = longest_side(triangles);
        GroupPlane::find_all(triangles, size, storage.group_planes)?;
        let group_planes: &'a [GroupPlane] = storage.group_planes;
        Ok(Scene {
            triangles,
            materials,
            light_radiance,
            textures,
            bvh,
            light_table: &light_table[..n_emitting],
            light_guide: LightGuide::new(&light_table[..n_emitting]),
            named,
            mirrors: MirrorPlanes::find(materials, group_planes, size),
            size,
        })
    }

    /// What this scene's build filled in its storage, for [`Scene::from_built`].
    pub fn built_counts(&self) -> BuiltCounts {
        BuiltCounts {
            nodes: self.bvh.node_count(),
            lights: self.light_table.len(),
            groups_named: self.named.0,
            lights_named: self.named.1,
            size: self.size,
        }
    }

    /// The scene over storage that [`Scene::build`] filled for the same `triangles` and
    /// `light_radiance`, with (new) `materials` and `textures`: the tables are checked
    /// again, the BVH, the light table, the groups' planes and the scene's size are not
    /// found again (see [`Bvh::from_built`]), and no pass over the triangles is made
    /// (where a recovery builds its scene at every evaluation, such passes took 4% of its
    /// CPU time on one thread at 600,000 triangles).
    pub fn from_built(
        triangles: &'a [Triangle],
        materials: &'a [SurfaceMaterial],
        light_radiance: &'a [Vec3],
        textures: Textures<'a>,
        built: BuiltStorage<'a>,
    ) -> Result<Scene<'a>, Error> {
        let counts = built.counts;
        check_tables(triangles.len(), materials, light_radiance, &textures)?;
        let named = (counts.groups_named, counts.lights_named);
        check_named(named, materials, light_radiance)?;
        let Some(light_table) = built.light_table.get(..counts.lights) else {
            return Err(Error::BufferTooSmall {
                what: "built light_table",
                needed: counts.lights,
                got: built.light_table.len(),
            });
        };
        let bvh = Bvh::from_built(triangles, built.nodes, built.packed, counts.nodes)?;
        Ok(Scene {
            triangles,
            materials,
            light_radiance,
            textures,
            bvh,
            light_table,
            light_guide: LightGuide::new(light_table),
            named,
            mirrors: MirrorPlanes::find(materials, built.group_planes, counts.size),
            size: counts.size,
        })
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        self.bvh.intersect(ray, t_max)
    }

    #[inline]
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.bvh.occluded(ray, t_max)
    }

    pub fn bvh(&self) -> &Bvh<'a> {
        &self.bvh
    }

    /// The longest side of the geometry's bounding box: the length that the offset of a
    /// secondary ray's origin is measured in ([`crate::render::offset_origin`]), so that
    /// a scene renders the same in millimetres as in metres.
    pub fn size(&self) -> f32 {
        self.size
    }

    /// The planar mirrors that light is sampled through.
    pub fn mirror_planes(&self) -> &MirrorPlanes {
        &self.mirrors
    }

    /// True when some light emits.
    pub fn has_lights(&self) -> bool {
        !self.light_table.is_empty()
    }

    /// Picks an emitting triangle with `u` and a point on it with `u2`.
    pub fn sample_light(&self, u: f32, u2: [f32; 2]) -> Option<LightSample> {
        let table = self.light_table;
        if table.is_empty() {
            return None;
        }
        let index = self.light_guide.pick(table, u).min(table.len() - 1);
        let entry = table[index];
        let tri = self.triangles.get(entry.triangle as usize)?;
        let Surface::Light(light) = tri.surface else {
            return None;
        };
        let radiance = *self.light_radiance.get(light as usize)?;
        // Uniform point on the triangle (square-root parametrisation).
        let su = math::sqrt(u2[0]);
        let b1 = su * (1.0 - u2[1]);
        let b2 = su * u2[1];
        let n2 = tri.normal_area2();
        let area2 = n2.length();
        if !(area2 > 0.0) {
            return None;
        }
        Some(LightSample {
            point: tri.point(b1, b2),
            normal: n2 / area2,
            radiance,
            pdf_area: entry.pick_pdf * 2.0 / area2,
        })
    }

    /// Area pdf with which [`Scene::sample_light`] would pick a point on `triangle`.
    pub fn light_pdf_area(&self, triangle: u32) -> f32 {
        let Some(tri) = self.triangles.get(triangle as usize) else {
            return 0.0;
        };
        let Surface::Light(light) = tri.surface else {
            return 0.0;
        };
        let Some(radiance) = self.light_radiance.get(light as usize) else {
            return 0.0;
        };
        let area = tri.area();
        let power = area * math::luminance(*radiance);
        if !(power > 0.0) {
            return 0.0;
        }
        match self
            .light_table
            .binary_search_by_key(&triangle, |e| e.triangle)
        {
            Ok(i) => self.light_table[i].pick_pdf / area,
            Err(_) => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::{BvhNode, PackedTriangle};
    use crate::math::Vec2;

    fn tri(v: [[f32; 3]; 3], group: u16) -> Triangle {
        Triangle {
            v: v.map(Vec3::from_array),
            uv: [Vec2::ZERO; 3],
            surface: Surface::Group(group),
        }
    }

    fn material(material: Material) -> SurfaceMaterial {
        SurfaceMaterial {
            material,
            diffuse_map: None,
        }
    }

    /// The guide's pick is the whole table's binary search, for tables of one entry to
    /// thousands, uneven and with runs of equal cdfs, at `u` on and around every bucket's
    /// edges and at random, and for `u` outside [0, 1) and NaN.
    #[test]
    fn the_light_guide_picks_what_a_search_of_the_whole_table_picks() {
        let mut sampler = crate::rng::Sampler::for_pixel_sample(3, 0, 0, 0);
        for n in [1usize, 2, 3, 7, 100, 5000] {
            let powers: std::vec::Vec<f32> = (0..n)
                .map(|i| {
                    let u = sampler.next_f32();
                    // Uneven: a few entries hold most of the power, some share a cdf.
                    if i % 13 == 0 {
                        50.0 * u + 1.0
                    } else {
                        u * u + 1e-6
                    }
                })
                .collect();
            let total: f64 = powers.iter().map(|&p| p as f64).sum();
            let mut running = 0.0f64;
            let mut table: std::vec::Vec<LightTriangle> = powers
                .iter()
                .map(|p| {
                    running += *p as f64;
                    LightTriangle {
                        triangle: 0,
                        cdf: (running / total) as f32,
                        pick_pdf: 0.0,
                    }
                })
                .collect();
            table.last_mut().unwrap().cdf = 1.0;
            if n > 3 {
                table[2].cdf = table[1].cdf;
            }
            let guide = LightGuide::new(&table);
            let mut us: std::vec::Vec<f32> = (0..2000).map(|_| sampler.next_f32()).collect();
            for j in 0..=LIGHT_GUIDE_BUCKETS {
                let edge = j as f32 / LIGHT_GUIDE_BUCKETS as f32;
                us.extend([
                    edge,
                    f32::from_bits(edge.to_bits().saturating_sub(1)),
                    f32::from_bits(edge.to_bits() + 1),
                ]);
            }
            us.extend(table.iter().map(|e| e.cdf));
            us.extend([0.0, -0.0, 1.0, 1.5, -1.0, f32::NAN, 0.99999994]);
            for u in us {
                let whole = table.partition_point(|e| e.cdf <= u);
                assert_eq!(guide.pick(&table, u), whole, "n {n}, u {u:e}");
            }
        }
    }

    /// A light whose power (area times luminance) f32 cannot hold, of a finite radiance
    /// that the scene accepts, is picked by its power like any other. Its power, 5e38,
    /// once overflowed to infinity and made its probability inf / inf: a NaN pdf, which
    /// next-event estimation skipped and MIS weighed as 0 where a path hit the light, so
    /// the brightest light in the scene lit nothing.
    #[test]
    fn a_light_of_more_power_than_f32_holds_is_sampled_by_its_power() {
        let light = |v: [[f32; 3]; 3], l: u16| Triangle {
            v: v.map(Vec3::from_array),
            uv: [Vec2::ZERO; 3],
            surface: Surface::Light(l),
        };
        let triangles = [
            tri([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], 0),
            // Area 50, facing down; radiance 1e37: power 5e38, past f32's 3.4e38.
            light([[0.0, 0.0, 1.0], [0.0, 10.0, 1.0], [10.0, 0.0, 1.0]], 0),
            // Area 0.5, radiance 1: power 0.5.
            light([[5.0, 5.0, 1.0], [5.0, 6.0, 1.0], [6.0, 5.0, 1.0]], 1),
        ];
        let materials = [material(Material::Diffuse {
            rho_d: Vec3::splat(0.5),
        })];
        let radiance = [Vec3::splat(1e37), Vec3::ONE];
        let (n_nodes, n_packed) = Bvh::buffer_sizes(triangles.len());
        let mut nodes = std::vec![BvhNode::default(); n_nodes];
        let mut packed = std::vec![PackedTriangle::default(); n_packed];
        let mut table = [LightTriangle::default(); 3];
        let mut planes = [GroupPlane::default(); 1];
        let scene = Scene::build(
            &triangles,
            &materials,
            &radiance,
            Textures::default(),
            SceneStorage {
                bvh: BvhBuffers {
                    nodes: &mut nodes,
                    packed: &mut packed,
                },
                light_table: &mut table,
                group_planes: &mut planes,
            },
        )
        .unwrap();
        // The bright light holds all but 1e-39 of the power: its area pdf is 1 / 50.
        let sample = scene.sample_light(0.5, [0.3, 0.3]).unwrap();
        assert_eq!(sample.radiance, radiance[0]);
        assert!((sample.pdf_area - 0.02).abs() <= 1e-6 * 0.02, "{sample:?}");
        let pdf = scene.light_pdf_area(1);
        assert!((pdf - 0.02).abs() <= 1e-6 * 0.02, "{pdf}");
        // The dim one keeps its share, which f32 holds as a subnormal, or 0.
        let dim = scene.light_pdf_area(2);
        assert!(dim.is_finite() && (0.0..1e-37).contains(&dim), "{dim}");
        // And the floor under it is lit: below the light, at most rho_d L = 5e36 on
        // average (the light fills less than its hemisphere), where it rendered 0.
        let settings = crate::render::RenderSettings::default();
        let mean = (0..16u32)
            .map(|k| {
                let mut sampler = crate::rng::Sampler::for_pixel_sample(1, 0, k, 0);
                let ray = Ray::new(Vec3::new(0.2, 0.2, 0.5), Vec3::NEG_Z);
                crate::render::radiance(&scene, ray, &mut sampler, &settings).y as f64
            })
            .sum::<f64>()
            / 16.0;
        assert!(mean > 1e36 && mean < 1e37, "{mean:e}");
    }

    /// A mirror as a scanned mesh gives it, a tilted quad far from the origin split into
    /// 512 small triangles, is still one plane, and bending one of its corners by a
    /// hundredth of its size is not.
    #[test]
    fn a_finely_split_mirror_is_one_plane() {
        fn split(t: [Vec3; 3], k: u32, out: &mut std::vec::Vec<Triangle>) {
            if k == 0 {
                out.push(Triangle {
                    v: t,
                    uv: [Vec2::ZERO; 3],
                    surface: Surface::Group(0),
                });
                return;
            }
            let [a, b, c] = t;
            let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
            for part in [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]] {
                split(part, k - 1, out);
            }
        }
        let origin = Vec3::new(40.0, -25.0, 3.0);
        let (u, w) = (Vec3::new(0.8, 0.6, 0.0), Vec3::new(-0.36, 0.48, 0.8));
        let corners = [origin, origin + u, origin + u + w, origin + w];
        let mirror_of = |corners: [Vec3; 4]| {
            let mut triangles = std::vec::Vec::new();
            split([corners[0], corners[1], corners[2]], 4, &mut triangles);
            split([corners[0], corners[2], corners[3]], 4, &mut triangles);
            let size = longest_side(&triangles).max(10.0);
            let mut planes = [GroupPlane::default(); 1];
            GroupPlane::find_all(&triangles, size, &mut planes).unwrap();
            let mirror = [material(Material::Mirror {
                rho: Vec3::splat(0.9),
            })];
            (triangles.len(), MirrorPlanes::find(&mirror, &planes, size))
        };
        let (n, flat) = mirror_of(corners);
        assert_eq!(n, 512);
        assert_eq!(flat.as_slice().len(), 1);
        let normal = u.cross(w).normalize();
        assert!(math::abs(flat.as_slice()[0].normal.dot(normal)) > 1.0 - 1e-6);
        let mut bent = corners;
        bent[3] += normal * 0.01;
        assert!(mirror_of(bent).1.as_slice().is_empty());
    }

    /// Only mirrors whose triangles share a plane are sampled through: a flat mirror
    /// (its triangles wound either way, a degenerate one beside them), not a bent one,
    /// not a black one, and not a flat group of another material.
    #[test]
    fn the_planar_mirrors_are_the_flat_mirror_groups() {
        let mirror = |rho: f32| {
            material(Material::Mirror {
                rho: Vec3::splat(rho),
            })
        };
        let materials = [
            mirror(0.9),
            mirror(0.9),
            mirror(0.0),
            material(Material::Diffuse {
                rho_d: Vec3::splat(0.5),
            }),
        ];
        let triangles = [
            // Group 0: the plane x = 1, one triangle wound the other way, one degenerate.
            tri([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 1.0, 1.0]], 0),
            tri([[1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0]], 0),
            tri([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 2.0, 5.0]], 0),
            // Group 1: two triangles at a right angle.
            tri([[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]], 1),
            tri([[0.0, 0.0, 2.0], [0.0, 1.0, 2.0], [0.0, 0.0, 3.0]], 1),
            // Group 2: flat, but black; group 3: flat, but diffuse.
            tri([[0.0, 0.0, 4.0], [1.0, 0.0, 4.0], [0.0, 1.0, 4.0]], 2),
            tri([[0.0, 0.0, 5.0], [1.0, 0.0, 5.0], [0.0, 1.0, 5.0]], 3),
        ];
        let size = longest_side(&triangles);
        let mut planes = [GroupPlane::default(); 4];
        GroupPlane::find_all(&triangles, size, &mut planes).unwrap();
        let found = MirrorPlanes::find(&materials, &planes, size);
        assert_eq!(found.as_slice().len(), 1);
        let plane = found.as_slice()[0];
        assert_eq!(plane.group, 0);
        assert!((plane.normal.x.abs() - 1.0).abs() < 1e-6);
        assert!((plane.offset * plane.normal.x - 1.0).abs() < 1e-6);
        assert_eq!(plane.rho, Vec3::splat(0.9));
        assert!(found.contains(0) && !found.contains(1) && !found.contains(3));
        // The planes are the geometry's, found for every group whatever its material: the
        // diffuse group made a mirror later is sampled through with its own plane.
        let mut later = materials;
        later[3] = mirror(0.5);
        let found = MirrorPlanes::find(&later, &planes, size);
        let groups: std::vec::Vec<u16> = found.as_slice().iter().map(|p| p.group).collect();
        assert_eq!(groups, [0, 3]);
        assert_eq!(
            found.as_slice()[1].offset * found.as_slice()[1].normal.z,
            5.0
        );
        // Fewer planes than the triangles' groups is an error, not a panic.
        let mut short = [GroupPlane::default(); 3];
        assert!(GroupPlane::find_all(&triangles, size, &mut short).is_err());
    }
}
