//! What recovery re-uses between evaluations: the light arriving at the first surface a
//! pixel sample sees, traced once with full global illumination and fixed random numbers.
//!
//! A pixel sample's radiance is `integral f(wo, wi) L_in(wi) cos dwi` at its first vertex.
//! We estimate that integral with two MIS-weighted samples (one on a light, one from a
//! mixture of a cosine lobe and Ward lobes of several roughnesses), and one on the light's
//! image in each planar mirror as the renderer has (light by way of a mirror is otherwise
//! found by the mixture alone: heavy-tailed noise), and store each as an
//! [`IncidentSample`]: directions and `L_in cos w / pdf`. For *any* BRDF of the group the
//! pixel's value is then `sum f(wo, wi) * weight`, unbiased while the mixture covers the
//! BRDF. So a new material costs a few BRDF evaluations per sample, not a render; the cache
//! is refreshed (re-traced) when the rest of the scene's materials change.

use crate::config;
use crate::geometry::{Surface, View};
use crate::material::{self, Bsdf, Material};
use crate::math::{self, Vec3, INV_PI};
use crate::render::{self, RenderSettings};
use crate::scene::Scene;

/// Roughnesses of the Ward lobes in the sampling mixture (beside a cosine lobe): they span
/// the roughness range that recovery searches, so every candidate lobe is well covered.
pub const MIXTURE_ROUGHNESSES: [f32; 4] = [0.01, 0.03, 0.08, 0.2];
/// Probability of the cosine lobe in the mixture; the rest is shared by the Ward lobes.
pub const MIXTURE_COSINE: f32 = 0.2;

/// Light arriving at a first vertex from one direction, already divided by its pdf.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IncidentSample {
    /// Unit direction towards the viewer.
    pub wo: Vec3,
    /// Unit normal, turned towards `wo`.
    pub n: Vec3,
    /// Unit direction towards where the light comes from.
    pub wi: Vec3,
    /// `L_in(wi) * cos(n, wi) * w_mis / pdf`; multiply by `f(wo, wi)` to get radiance.
    pub weight: Vec3,
    /// Texture coordinate of the first vertex (for diffuse maps).
    pub uv: [f32; 2],
}

/// Incident samples per pixel sample in a scene without planar mirrors: one on a light, one
/// from the mixture.
pub const INCIDENT_PER_SAMPLE: usize = 2;

/// Incident samples per pixel sample at most: [`INCIDENT_PER_SAMPLE`] and one on the
/// light's image in each planar mirror.
pub const MAX_INCIDENT_PER_SAMPLE: usize = INCIDENT_PER_SAMPLE + config::MAX_MIRROR_PLANES;

/// Incident samples per pixel sample in `scene`: [`INCIDENT_PER_SAMPLE`] and one on the
/// light's image in each of its planar mirrors, the layout of [`trace_pixel_sample`]'s
/// output.
pub fn incident_per_sample(scene: &Scene) -> usize {
    INCIDENT_PER_SAMPLE + scene.mirror_planes().as_slice().len()
}

/// The unit isotropic specular lobe of roughness `alpha` (`rho_d = 0`, `rho_s = 1`): the
/// lobe whose part of a pixel the linear fits scale by the specular reflectance.
pub fn unit_isotropic_lobe(alpha: f32) -> Material {
    Material::Ward {
        rho_d: Vec3::ZERO,
        rho_s: Vec3::ONE,
        alpha,
    }
}

/// Solid-angle pdf of the sampling mixture at `wi`.
fn mixture_pdf(n: Vec3, wo: Vec3, wi: Vec3) -> f32 {
    let cos = n.dot(wi);
    if !(cos > 0.0) {
        return 0.0;
    }
    let p_lobe = (1.0 - MIXTURE_COSINE) / MIXTURE_ROUGHNESSES.len() as f32;
    let mut pdf = MIXTURE_COSINE * cos * INV_PI;
    for &a in &MIXTURE_ROUGHNESSES {
        pdf += p_lobe * Bsdf::new(&unit_isotropic_lobe(a), None, n).pdf(wo, wi);
    }
    pdf
}

fn cosine_direction(n: Vec3, u: [f32; 2]) -> Vec3 {
    let frame = math::Frame::from_normal(n);
    let r = math::sqrt(u[0]);
    let phi = 2.0 * math::PI * u[1];
    let z = math::sqrt((1.0 - u[0]).max(0.0));
    frame.to_world(Vec3::new(r * math::cos(phi), r * math::sin(phi), z))
}

#[inline]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// Traces one pixel sample of pixel `(x, y)` and writes its incident samples into `out`
/// when the first hit is on `group`: the light sample, the mixture's, then the light
/// sample's image in each planar mirror ([`incident_per_sample`] in all; an image that
/// does not reach the point is left as the default, which every sum skips). Returns how
/// many were written (0 when the sample sees something else, e.g. at the edge of a pure
/// pixel by rounding).
#[allow(clippy::too_many_arguments)]
pub fn trace_pixel_sample(
    scene: &Scene,
    view: &View,
    view_index: u32,
    x: u32,
    y: u32,
    sample: u32,
    group: u16,
    settings: &RenderSettings,
    out: &mut [IncidentSample; MAX_INCIDENT_PER_SAMPLE],
) -> usize {
    let (ray, mut sampler) = render::camera_sample(view, view_index, x, y, settings, sample);
    let Some(hit) = scene.intersect(&ray, f32::INFINITY) else {
        return 0;
    };
    let Some(tri) = scene.triangles.get(hit.triangle as usize) else {
        return 0;
    };
    if tri.surface != Surface::Group(group) {
        return 0;
    }
    let n2 = tri.normal_area2();
    let len = n2.length();
    if !(len > 0.0) {
        return 0;
    }
    let ng = n2 / len;
    let n = if ng.dot(ray.direction) < 0.0 { ng } else { -ng };
    let wo = -ray.direction;
    let p = ray.at(hit.t);
    let origin = render::offset_origin(p, n, scene.size());
    let uv = tri.uv_at(hit.b1, hit.b2).to_array();
    let mut written = 0;

    // 1. A point on a light.
    let u_light = sampler.next_f32();
    let u_point = sampler.next_2d();
    let mut light_entry = IncidentSample {
        wo,
        n,
        wi: n,
        weight: Vec3::ZERO,
        uv,
    };
    let light_sample = scene.sample_light(u_light, u_point);
    if let Some(ls) = light_sample {
        // Measured from the surface, the shadow ray traced from `origin`, as the renderer
        // does (`render::towards_light`).
        if let Some((wi, dist2, cos_light)) = render::towards_light(p, &ls) {
            let cos_surface = n.dot(wi);
            if cos_light > 0.0 && cos_surface > 0.0 && ls.pdf_area > 0.0 {
                light_entry.wi = wi;
                if !render::occluded_on_the_way(scene, origin, ls.point) {
                    let pdf_light = ls.pdf_area * dist2 / cos_light;
                    let w = power_heuristic(pdf_light, mixture_pdf(n, wo, wi));
                    light_entry.weight = ls.radiance * (cos_surface * w / pdf_light);
                }
            }
        }
    }
    out[written] = light_entry;
    written += 1;

    // 2. A direction from the mixture, and the light arriving along it (full GI).
    let u_pick = sampler.next_f32();
    let u_dir = sampler.next_2d();
    let wi = if u_pick < MIXTURE_COSINE {
        Some(cosine_direction(n, u_dir))
    } else {
        let k = (((u_pick - MIXTURE_COSINE) / (1.0 - MIXTURE_COSINE))
            * MIXTURE_ROUGHNESSES.len() as f32) as usize;
        let a = MIXTURE_ROUGHNESSES[k.min(MIXTURE_ROUGHNESSES.len() - 1)];
        Bsdf::new(&unit_isotropic_lobe(a), None, n)
            .sample(wo, 1.0, u_dir)
            .map(|s| s.wi)
    };
    let mut indirect = IncidentSample {
        wo,
        n,
        wi: n,
        weight: Vec3::ZERO,
        uv,
    };
    if let Some(wi) = wi {
        let pdf = mixture_pdf(n, wo, wi);
        let cos = n.dot(wi);
        if pdf > 0.0 && cos > 0.0 {
            indirect.wi = wi;
            let next = crate::geometry::Ray::new(origin, wi);
            if let Some(h2) = scene.intersect(&next, f32::INFINITY) {
                if let Some(t2) = scene.triangles.get(h2.triangle as usize) {
                    let l_in = match t2.surface {
                        Surface::Light(l) => {
                            let ln2 = t2.normal_area2();
                            let cos_l = -ln2.dot(wi) / ln2.length().max(f32::MIN_POSITIVE);
                            if cos_l > 0.0 {
                                let le = scene
                                    .light_radiance
                                    .get(l as usize)
                                    .copied()
                                    .unwrap_or(Vec3::ZERO);
                                let pdf_light =
                                    scene.light_pdf_area(h2.triangle) * h2.t * h2.t / cos_l;
                                le * power_heuristic(pdf, pdf_light)
                            } else {
                                Vec3::ZERO
                            }
                        }
                        Surface::Group(_) => {
                            render::radiance_after_sample(scene, next, &mut sampler, settings, pdf)
                        }
                    };
                    indirect.weight = l_in * (cos / pdf);
                }
            }
        }
    }
    out[written] = indirect;
    written += 1;

    // 3. The light sample's image in each planar mirror, MIS-weighted against the
    // mixture's sample that reaches the light by way of the mirror (which
    // `radiance_after_sample` weighs). It reuses the light sample: a scene without planar
    // mirrors draws the same random numbers.
    for mirror in scene.mirror_planes().as_slice() {
        let mut entry = IncidentSample::default();
        if let Some(ls) = &light_sample {
            if let Some(image) =
                render::light_image_in_mirror(scene, mirror, p, origin, n, ls, |_| true)
            {
                let w = power_heuristic(image.pdf, mixture_pdf(n, wo, image.wi));
                entry = IncidentSample {
                    wo,
                    n,
                    wi: image.wi,
                    weight: mirror.rho * ls.radiance * (image.cos_surface * w / image.pdf),
                    uv,
                };
            }
        }
        if let Some(slot) = out.get_mut(written) {
            *slot = entry;
            written += 1;
        }
    }
    written
}

/// The pixel value a material gives over a pixel's incident samples (`n_samples` pixel
/// samples, whose incident samples are `entries`): `sum f(wo, wi) weight / n_samples`.
pub fn shade(
    entries: &[IncidentSample],
    n_samples: u32,
    material: &Material,
    rho_d: Option<Vec3>,
) -> Vec3 {
    let mut sum = Vec3::ZERO;
    let mut bsdf = ReusedBsdf::new(material, rho_d);
    for e in entries {
        let f = bsdf.at(e.n).eval(e.wo, e.wi);
        sum += f * e.weight;
    }
    sum / n_samples.max(1) as f32
}

/// The BSDF of one material at a normal, built again only when the normal changes: a
/// pixel's incident samples share their first vertex's normal (all of them on a flat
/// group), and building the shading frame is a fair part of a cache evaluation. The BSDF
/// is a function of the material and the normal alone, so the values are the same bits.
struct ReusedBsdf<'a> {
    material: &'a Material,
    rho_d: Option<Vec3>,
    at: Option<(Vec3, Bsdf)>,
}

impl<'a> ReusedBsdf<'a> {
    fn new(material: &'a Material, rho_d: Option<Vec3>) -> Self {
        ReusedBsdf {
            material,
            rho_d,
            at: None,
        }
    }

    #[inline]
    fn at(&mut self, n: Vec3) -> &Bsdf {
        // Bitwise equality: -0.0 and 0.0, or two NaNs, are built again, never confused.
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        if !matches!(self.at, Some((m, _)) if bits(m) == bits(n)) {
            self.at = None;
        }
        let (material, rho_d) = (self.material, self.rho_d);
        &self
            .at
            .get_or_insert_with(|| (n, Bsdf::new(material, rho_d, n)))
            .1
    }
}

/// The two linear parts of a pixel under a Ward-type material: `diffuse` is the value for
/// `rho_d = 1, S = 0` (irradiance / pi) and `specular` the value for `rho_d = 0, S = 1`, so
/// that the pixel is `rho_d * diffuse + S * specular` (per channel).
///
/// This is the definition, straight from the entries; recovery's caches evaluate it as
/// [`diffuse_part`] and [`specular_part`] over [`LobePoint`]s, which the tests check give
/// the same bits.
pub fn linear_parts(
    entries: &[IncidentSample],
    n_samples: u32,
    specular_lobe: &Material,
) -> (Vec3, Vec3) {
    let mut diffuse = Vec3::ZERO;
    let mut specular = Vec3::ZERO;
    let mut bsdf = ReusedBsdf::new(specular_lobe, None);
    for e in entries {
        if e.n.dot(e.wi) > 0.0 {
            diffuse += e.weight * INV_PI;
        }
        let f = bsdf.at(e.n).eval(e.wo, e.wi);
        specular += f * e.weight;
    }
    let k = 1.0 / n_samples.max(1) as f32;
    (diffuse * k, specular * k)
}

/// One incident sample a lobe can reflect, with what does not depend on the lobe: what
/// [`specular_part`] needs to evaluate the many lobes a closed-form fit tries over the
/// same samples (some sixty roughnesses per group, some 250 anisotropic shapes).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LobePoint {
    /// The sample's normal.
    pub n: Vec3,
    /// The half vector `wo + wi`.
    pub h: Vec3,
    /// `h` in [`Frame::from_normal`]'s frame of `n`: an isotropic lobe's, kept so that the
    /// fits' many roughnesses need no frame (a curved group's changes with every sample).
    ///
    /// [`Frame::from_normal`]: crate::math::Frame::from_normal
    pub h_local: Vec3,
    /// `tan^2` of the half vector's angle to the normal, to skip the samples where a lobe
    /// vanishes ([`Bsdf::vanishes_at`]).
    pub tan2: f32,
    /// The sample's weight.
    pub weight: Vec3,
}

/// The [`LobePoint`] of an incident sample, or `None` where no material reflects it (`wo`
/// or `wi` below the surface: [`Bsdf::eval`] is zero there).
pub fn lobe_point(e: &IncidentSample) -> Option<LobePoint> {
    let n = e.n;
    if !(n.dot(e.wo) > 0.0 && n.dot(e.wi) > 0.0) {
        return None;
    }
    let h = e.wo + e.wi;
    let hl = math::Frame::from_normal(n).to_local(h);
    Some(LobePoint {
        n,
        h,
        h_local: hl,
        tan2: (hl.x * hl.x + hl.y * hl.y) / (hl.z * hl.z),
        weight: e.weight,
    })
}

/// The diffuse part of [`linear_parts`], which no lobe changes: the value for `rho_d = 1`.
pub fn diffuse_part(entries: &[IncidentSample], n_samples: u32) -> Vec3 {
    let mut diffuse = Vec3::ZERO;
    for e in entries {
        if e.n.dot(e.wi) > 0.0 {
            diffuse += e.weight * INV_PI;
        }
    }
    diffuse * (1.0 / n_samples.max(1) as f32)
}

/// The specular part of [`linear_parts`] under `specular_lobe`, from the pixel's
/// [`LobePoint`]s in entry order: the same bits, since every sample it leaves out adds
/// exactly zero there (for finite weights, which the tracer's are).
///
/// A Ward lobe alone, what the fits try by the dozen, is evaluated [`math::LANES`] samples
/// at a time (`LobeQueue`); any other material one sample at a time.
pub fn specular_part(points: &[LobePoint], n_samples: u32, specular_lobe: &Material) -> Vec3 {
    let scale = 1.0 / n_samples.max(1) as f32;
    // Whether the material is a Ward lobe alone depends on its diffuse colour only, not on
    // the normal; an isotropic lobe's roughness does not either.
    let at_any_normal = Bsdf::new(specular_lobe, None, Vec3::Z);
    let mut bsdf = ReusedBsdf::new(specular_lobe, None);
    let mut queue = LobeQueue::default();
    match (*specular_lobe, at_any_normal.lobe_alone()) {
        // An isotropic lobe's BSDF differs from normal to normal only in its frame, the
        // one `h_local` is in.
        (Material::Ward { .. }, Some(lobe)) => {
            queue.set_lobe(lobe);
            for p in points {
                if !at_any_normal.vanishes_at(p.tan2) {
                    queue.push(p.h_local, p.h.length_squared(), p.weight);
                }
            }
            queue.sum() * scale
        }
        // An anisotropic lobe's frame follows its direction, and its roughnesses change
        // where that direction meets the normal (`Bsdf::new`'s isotropic fallback).
        (Material::WardAnisotropic { .. }, Some(_)) => {
            for p in points {
                let bsdf = bsdf.at(p.n);
                if let (Some(lobe), false) = (bsdf.lobe_alone(), bsdf.vanishes_at(p.tan2)) {
                    queue.set_lobe(lobe);
                    queue.push(bsdf.to_local(p.h), p.h.length_squared(), p.weight);
                }
            }
            queue.sum() * scale
        }
        _ => {
            let mut specular = Vec3::ZERO;
            for p in points {
                let bsdf = bsdf.at(p.n);
                if !bsdf.vanishes_at(p.tan2) {
                    specular += bsdf.eval_above(p.h) * p.weight;
                }
            }
            specular * scale
        }
    }
}

/// Lobe points waiting to be evaluated [`math::LANES`] at a time under one Ward lobe
/// ([`material::ward_lobes`]), and the sum of what they reflect so far, added in the
/// points' order: the same sum, to the bit, as evaluating them one at a time.
#[derive(Default)]
struct LobeQueue {
    h: material::HalfVectorLanes,
    weights: [Vec3; math::LANES],
    len: usize,
    /// The queued points' lobe: [`Bsdf::lobe_alone`]'s reflectance and roughnesses.
    lobe: (Vec3, f32, f32),
    sum: Vec3,
}

impl LobeQueue {
    /// The lobe of the points pushed from now on.
    #[inline]
    fn set_lobe(&mut self, lobe: (Vec3, f32, f32)) {
        if lobe != self.lobe {
            self.flush();
            self.lobe = lobe;
        }
    }

    /// Queues a point's half vector `h_local` in the lobe's frame, its squared length `h2`
    /// and its weight.
    #[inline]
    fn push(&mut self, h_local: Vec3, h2: f32, weight: Vec3) {
        let j = self.len;
        self.h.x[j] = h_local.x;
        self.h.y[j] = h_local.y;
        self.h.z[j] = h_local.z;
        self.h.length_squared[j] = h2;
        self.weights[j] = weight;
        self.len += 1;
        if self.len == math::LANES {
            self.flush();
        }
    }

    /// Evaluates the queued points and adds them to the sum: `Bsdf::eval_above`'s
    /// `rho_s * lobe` (its `rho_d / pi` is zero) times each weight.
    fn flush(&mut self) {
        if self.len == 0 {
            return;
        }
        let (rho_s, alpha_u, alpha_v) = self.lobe;
        let lobe = material::ward_lobes(&self.h, alpha_u, alpha_v);
        for (value, weight) in lobe.iter().zip(&self.weights).take(self.len) {
            self.sum += (rho_s * *value) * *weight;
        }
        self.len = 0;
    }

    /// The sum over every point pushed.
    fn sum(mut self) -> Vec3 {
        self.flush();
        self.sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// Entries whose normals change now and then, as a curved group's do: the reused BSDF
    /// gives the same bits as one built for every entry.
    #[test]
    fn reusing_the_bsdf_across_a_normal_gives_the_same_bits() {
        let normals = [
            Vec3::Z,
            Vec3::Z,
            Vec3::new(0.0, 0.6, 0.8),
            Vec3::new(0.0, 0.6, 0.8),
            Vec3::Z,
            Vec3::new(-0.0, 0.0, 1.0),
        ];
        let entries: [IncidentSample; 6] = core::array::from_fn(|i| IncidentSample {
            wo: Vec3::new(0.3, -0.2, 0.9).normalize(),
            n: normals[i],
            wi: Vec3::new(-0.25 + 0.1 * i as f32, 0.15, 0.95).normalize(),
            weight: Vec3::new(1.0, 0.5 + 0.1 * i as f32, 0.25),
            uv: [0.0; 2],
        });
        let material = Material::WardAnisotropic {
            rho_d: Vec3::splat(0.4),
            rho_s: Vec3::splat(0.2),
            alpha_u: 0.05,
            alpha_v: 0.2,
            direction: Vec3::X,
        };
        let naive = entries.iter().fold(Vec3::ZERO, |sum, e| {
            sum + Bsdf::new(&material, None, e.n).eval(e.wo, e.wi) * e.weight
        }) / 3.0;
        let reused = shade(&entries, 3, &material, None);
        assert_eq!(
            reused.to_array().map(f32::to_bits),
            naive.to_array().map(f32::to_bits)
        );
        assert!(reused.x > 0.0);

        let (mut diffuse, mut specular) = (Vec3::ZERO, Vec3::ZERO);
        for e in &entries {
            if e.n.dot(e.wi) > 0.0 {
                diffuse += e.weight * INV_PI;
            }
            specular += Bsdf::new(&material, None, e.n).eval(e.wo, e.wi) * e.weight;
        }
        let (d, s) = linear_parts(&entries, 3, &material);
        assert_eq!(
            d.to_array().map(f32::to_bits),
            (diffuse * (1.0 / 3.0)).to_array().map(f32::to_bits)
        );
        assert_eq!(
            s.to_array().map(f32::to_bits),
            (specular * (1.0 / 3.0)).to_array().map(f32::to_bits)
        );
    }

    /// Entries in every direction over a few normals (below the horizon, grazing, near
    /// and far from the mirror direction): the lobe points give the same bits as
    /// `linear_parts`, for isotropic roughnesses from below the guard to 1 and for
    /// anisotropic lobes, turned and along the normal (isotropic then).
    #[test]
    fn lobe_points_give_linear_parts_bits_for_every_lobe() {
        let mut sampler = crate::rng::Sampler::from_key(7);
        let mut u = || sampler.next_f32() * 2.0 - 1.0;
        let normals = [
            Vec3::Z,
            Vec3::new(0.0, 0.6, 0.8),
            Vec3::new(-0.48, 0.6, -0.64),
        ];
        let entries: Vec<IncidentSample> = (0..600)
            .map(|i| {
                let n = normals[i / 200];
                let wo = (n + Vec3::new(u(), u(), u()) * 0.9).normalize();
                IncidentSample {
                    wo,
                    n,
                    // Every fourth near the mirror direction, where sharp lobes live.
                    wi: match i % 4 {
                        0 => {
                            (2.0 * n.dot(wo) * n - wo + Vec3::new(u(), u(), u()) * 0.02).normalize()
                        }
                        _ => Vec3::new(u(), u(), u()).normalize(),
                    },
                    weight: Vec3::new(u().abs(), 0.5, u()) * 3.0,
                    uv: [0.0; 2],
                }
            })
            .collect();
        let points: Vec<LobePoint> = entries.iter().filter_map(lobe_point).collect();
        assert!(points.len() > 100 && points.len() < entries.len());
        let ward = |alpha| Material::Ward {
            rho_d: Vec3::ZERO,
            rho_s: Vec3::ONE,
            alpha,
        };
        let turned = |alpha_u, alpha_v, direction| Material::WardAnisotropic {
            rho_d: Vec3::ZERO,
            rho_s: Vec3::ONE,
            alpha_u,
            alpha_v,
            direction,
        };
        let lobes = [
            ward(1e-6),
            ward(0.005),
            ward(0.0173),
            ward(0.1),
            ward(0.3),
            ward(1.0),
            turned(0.005, 0.05, Vec3::new(1.0, 0.3, 0.0)),
            turned(0.2, 0.01, Vec3::new(0.0, 1.0, 1.0)),
            turned(0.02, 0.3, Vec3::Z),
            // Metals: a coloured lobe alone.
            Material::Ward {
                rho_d: Vec3::ZERO,
                rho_s: Vec3::new(0.9, 0.6, 0.2),
                alpha: 0.05,
            },
            Material::WardAnisotropic {
                rho_d: Vec3::ZERO,
                rho_s: Vec3::new(0.2, 0.7, 0.5),
                alpha_u: 0.03,
                alpha_v: 0.12,
                direction: Vec3::Z,
            },
            Material::Ward {
                rho_d: Vec3::splat(0.3),
                rho_s: Vec3::new(0.1, 0.2, 0.3),
                alpha: 0.01,
            },
        ];
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        for lobe in &lobes {
            let (d, s) = linear_parts(&entries, 3, lobe);
            assert_eq!(bits(diffuse_part(&entries, 3)), bits(d));
            assert_eq!(bits(specular_part(&points, 3, lobe)), bits(s), "{lobe:?}");
            assert!(s.x > 0.0, "{lobe:?}");
        }

        // A lone sample whose exponent is just inside the underflow bound, and one just
        // past it: the first is not skipped, the second is zero either way.
        let alpha = 0.05f32;
        for (exponent, reflects) in [(79.0f32, true), (80.5, false)] {
            let delta = libm::atanf(libm::sqrtf(exponent) * alpha);
            let h = Vec3::new(libm::sinf(delta), 0.0, libm::cosf(delta));
            let wo = Vec3::Z;
            let lone = [IncidentSample {
                wo,
                n: Vec3::Z,
                wi: 2.0 * wo.dot(h) * h - wo,
                weight: Vec3::ONE,
                uv: [0.0; 2],
            }];
            let points: Vec<LobePoint> = lone.iter().filter_map(lobe_point).collect();
            let (_, s) = linear_parts(&lone, 1, &ward(alpha));
            assert_eq!(bits(specular_part(&points, 1, &ward(alpha))), bits(s));
            assert_eq!(s.x > 0.0, reflects, "{exponent}: {s}");
        }
    }

    /// Light by way of a planar mirror reaches the incident samples. Over
    /// [`TileBesideAMirror`]'s tile, seen straight down, they give the diffuse tile the
    /// closed form and a glossy tile what the renderer gives it, with the mirror flat (its
    /// image sampled, MIS against the mixture's sample through it) and bent (the mixture
    /// alone); flat with far less noise.
    #[test]
    fn light_by_way_of_a_planar_mirror_reaches_the_incident_samples() {
        use crate::render::tests::{mean_and_standard_error, TileBesideAMirror};
        let diffuse = Material::Diffuse {
            rho_d: Vec3::splat(0.5),
        };
        let glossy = Material::Ward {
            rho_d: Vec3::splat(0.2),
            rho_s: Vec3::splat(0.3),
            alpha: 0.25,
        };
        let settings = RenderSettings {
            seed: 5,
            ..RenderSettings::default()
        };
        let view = View::new(
            Vec3::new(0.0, 0.0, 0.5),
            -Vec3::Z,
            Vec3::Y,
            [1.0, 1.0],
            [1, 1],
        )
        .unwrap();
        let n = 40_000u32;
        // The tile's pixel under `material` from the incident samples, and as rendered.
        let cached = |scene: &Scene, material: &Material| {
            let per_sample = incident_per_sample(scene);
            mean_and_standard_error((0..n).map(|k| {
                let mut out = [IncidentSample::default(); MAX_INCIDENT_PER_SAMPLE];
                let written = trace_pixel_sample(scene, &view, 0, 0, 0, k, 0, &settings, &mut out);
                assert_eq!(written, per_sample);
                shade(&out[..written], 1, material, None).y as f64
            }))
        };
        let rendered = |scene: &Scene| {
            mean_and_standard_error((0..n).map(|k| {
                render::render_pixel(
                    scene,
                    &view,
                    1,
                    0,
                    0,
                    &RenderSettings {
                        spp: 1,
                        seed: 1000 + k as u64,
                        ..settings
                    },
                )
                .y as f64
            }))
        };

        let expected = TileBesideAMirror::diffuse_radiance(0.5);
        let mut errors = Vec::new();
        for (bent, planes) in [(false, 1), (true, 0)] {
            let parts = TileBesideAMirror::new(glossy, bent);
            let mut storage = parts.storage();
            let scene = parts.scene(&mut storage);
            assert_eq!(scene.mirror_planes().as_slice().len(), planes);
            assert_eq!(incident_per_sample(&scene), INCIDENT_PER_SAMPLE + planes);

            let (mean, se) = cached(&scene, &diffuse);
            assert!(
                (mean - expected).abs() < 4.0 * se + 1e-4 * expected,
                "diffuse, bent {bent}: {mean} +- {se}, expected {expected}"
            );
            errors.push(se);

            let (mean, se) = cached(&scene, &glossy);
            let (render_mean, render_se) = rendered(&scene);
            let both = libm::sqrt(se * se + render_se * render_se);
            assert!(
                (mean - render_mean).abs() < 4.0 * both,
                "glossy, bent {bent}: {mean} +- {se} cached, {render_mean} +- {render_se} rendered"
            );
        }
        assert!(
            errors[0] * 3.0 < errors[1],
            "standard errors: {} through the mirror, {} without",
            errors[0],
            errors[1]
        );
    }
}
