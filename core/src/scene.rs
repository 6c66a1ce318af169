//! The assembled scene: triangles, their BVH, one material per group, light sources and
//! textures, all over storage lent by the caller and checked against [`crate::config`].

use crate::bvh::{Bvh, BvhBuffers, Hit};
use crate::config;
use crate::error::{check_capacity, Error};
use crate::geometry::{Ray, Surface, Triangle};
use crate::material::{SurfaceMaterial, Textures};
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

/// The buffers a [`Scene`] is built over, lent by the caller.
pub struct SceneStorage<'a> {
    pub bvh: BvhBuffers<'a>,
    /// At least as long as the number of emitting triangles.
    pub light_table: &'a mut [LightTriangle],
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
        check_capacity("MAX_TRIANGLES", config::MAX_TRIANGLES, triangles.len())?;
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
        let mut total_power = 0.0f64;
        let mut n_emitting = 0usize;
        for (i, t) in triangles.iter().enumerate() {
            match t.surface {
                Surface::Group(g) if g as usize >= materials.len() => {
                    return Err(Error::BadIndex {
                        what: "group",
                        index: g as usize,
                        len: materials.len(),
                    });
                }
                Surface::Light(l) => {
                    let Some(radiance) = light_radiance.get(l as usize) else {
                        return Err(Error::BadIndex {
                            what: "light",
                            index: l as usize,
                            len: light_radiance.len(),
                        });
                    };
                    let power = t.area() * math::luminance(*radiance);
                    if power > 0.0 {
                        let Some(slot) = storage.light_table.get_mut(n_emitting) else {
                            return Err(Error::BufferTooSmall {
                                what: "light_table",
                                needed: n_emitting + 1,
                                got: storage.light_table.len(),
                            });
                        };
                        *slot = LightTriangle {
                            triangle: i as u32,
                            cdf: power,
                            pick_pdf: 0.0,
                        };
                        n_emitting += 1;
                        total_power += power as f64;
                    }
                }
                Surface::Group(_) => {}
            }
        }
        let light_table = &mut storage.light_table[..n_emitting];
        let mut running = 0.0f64;
        for entry in light_table.iter_mut() {
            let power = entry.cdf as f64;
            running += power;
            entry.pick_pdf = (power / total_power) as f32;
            entry.cdf = (running / total_power) as f32;
        }
        if let Some(last) = light_table.last_mut() {
            last.cdf = 1.0;
        }
        let bvh = Bvh::build(triangles, storage.bvh)?;
        Ok(Scene {
            triangles,
            materials,
            light_radiance,
            textures,
            bvh,
            light_table,
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
        let index = table.partition_point(|e| e.cdf <= u).min(table.len() - 1);
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
