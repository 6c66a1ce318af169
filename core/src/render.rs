//! The path tracer: unidirectional paths from the camera with next-event estimation
//! (light sampling) and multiple importance sampling (power heuristic) against BSDF
//! sampling, Russian roulette, perfect mirrors, and box-filtered pixels whose samples are
//! stratified over the pixel ([`crate::strata`]). Light reaching a
//! surface by way of a planar mirror is also sampled through the light's image in the
//! mirror (RADIANCE's virtual sources), weighed by MIS against the BSDF sample that
//! bounces off the mirror into the light; by way of a curved mirror, or of two, BSDF
//! sampling alone finds it.
//!
//! Every sample draws its path from its own stream `(seed, view, pixel, sample)`, and its
//! point in the pixel from its half's scrambled sequence, so a pixel's value does not
//! depend on which thread renders it, or when.

use crate::config;
use crate::geometry::{Ray, Surface, View};
use crate::material::Bsdf;
use crate::math::{self, Vec3};
use crate::rng::Sampler;
use crate::scene::{LightSample, MirrorPlane, Scene};
use crate::strata;

/// How a render samples.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    /// Samples per pixel, spread over the pixel's square (a box filter) in two
    /// independently stratified halves ([`strata`]).
    pub spp: u32,
    pub seed: u64,
    /// Path vertices before Russian roulette may end a path.
    pub rr_depth: u32,
    /// Hard limit on path vertices (at most [`config::MAX_PATH_DEPTH`]).
    pub max_depth: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            spp: 64,
            seed: 1,
            rr_depth: 3,
            max_depth: config::MAX_PATH_DEPTH,
        }
    }
}

/// Relative offset of secondary ray origins from the surface, against self-intersection.
pub const RAY_EPSILON: f32 = 1e-4;

/// A secondary ray's origin: `p` moved off the surface along `n` by [`RAY_EPSILON`] of
/// the scene's size (`scene_size`, [`Scene::size`]), or of `p`'s largest coordinate where
/// that is larger (a hit point's rounding error grows with its coordinates). Relative to
/// the scene, not to a unit of length: the same scene in millimetres or kilometres gets
/// the same offsets, where a floor of one unit moved rays a visible fraction of a room a
/// few units small (the cornell room at a thousandth of its size read 9% bright).
#[inline]
pub fn offset_origin(p: Vec3, n: Vec3, scene_size: f32) -> Vec3 {
    let scale = p.abs().max_element().max(scene_size);
    p + n * (RAY_EPSILON * scale)
}

/// The power heuristic (beta = 2) weight of the strategy with pdf `a` against `b`.
#[inline]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    let b2 = b * b;
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// The box-filtered radiance of pixel `(x, y)` of `view` (the `view_index`-th view).
pub fn render_pixel(
    scene: &Scene,
    view: &View,
    view_index: u32,
    x: u32,
    y: u32,
    settings: &RenderSettings,
) -> Vec3 {
    pixel_moments(scene, view, view_index, x, y, settings, None).0
}

/// The box-filtered radiance of a pixel and the variance of that estimate, per channel,
/// from the difference of its two halves' means (see `pixel_moments`), which the fit uses
/// to take render noise out of `error_initial`.
pub fn render_pixel_with_variance(
    scene: &Scene,
    view: &View,
    view_index: u32,
    x: u32,
    y: u32,
    settings: &RenderSettings,
) -> (Vec3, Vec3) {
    let (mean, variance, _) = pixel_moments(scene, view, view_index, x, y, settings, None);
    (mean, variance)
}

/// [`render_pixel_with_variance`], the same bits, and the part of the pixel's radiance
/// that comes by way of `group`'s diffuse lobe, from the same samples (see
/// [`radiance_with_diffuse_part`]): `(mean, variance, diffuse part's mean)`.
pub fn render_pixel_with_diffuse_part(
    scene: &Scene,
    view: &View,
    view_index: u32,
    x: u32,
    y: u32,
    settings: &RenderSettings,
    group: u16,
) -> (Vec3, Vec3, Vec3) {
    pixel_moments(scene, view, view_index, x, y, settings, Some(group))
}

/// A pixel's mean radiance, its variance and, with `split`, `split`'s diffuse part's
/// mean (zero otherwise).
///
/// The variance is the squared difference of the means of the pixel's two halves, which
/// are stratified independently ([`strata`]): `(mean_a - mean_b)^2 n_a n_b / n^2` is
/// unbiased for the variance of the whole mean (for an odd count, nearly), where the
/// sample variance over `n` is not (strata make the mean steadier than independent samples
/// would). One degree of freedom
/// a pixel, so it is meant to be summed over many (as the fit's error does).
fn pixel_moments(
    scene: &Scene,
    view: &View,
    view_index: u32,
    x: u32,
    y: u32,
    settings: &RenderSettings,
    split: Option<u16>,
) -> (Vec3, Vec3, Vec3) {
    let mut half_sums = [Vec3::ZERO; 2];
    let mut sum_diffuse = Vec3::ZERO;
    for s in 0..settings.spp {
        let (ray, mut sampler) = camera_sample(view, view_index, x, y, settings, s);
        let l = match split {
            Some(group) => {
                let (l, diffuse) =
                    radiance_with_diffuse_part(scene, ray, &mut sampler, settings, group);
                sum_diffuse += diffuse;
                l
            }
            None => radiance(scene, ray, &mut sampler, settings),
        };
        half_sums[strata::half_of(s, settings.spp).0 as usize] += l;
    }
    let n = settings.spp.max(1) as f32;
    let mean = (half_sums[0] + half_sums[1]) / n;
    let (n_a, n_b) = (
        (settings.spp / 2) as f32,
        (settings.spp - settings.spp / 2) as f32,
    );
    let variance = if n_a > 0.0 {
        let d = half_sums[0] / n_a - half_sums[1] / n_b;
        d * d * (n_a * n_b / (n * n))
    } else {
        Vec3::ZERO
    };
    (mean, variance, sum_diffuse / n)
}

/// Sample `s` of `spp` of pixel `(x, y)`: its ray through its stratified point of the
/// pixel ([`strata::pixel_point`]), and the sampler the rest of its path draws from.
pub(crate) fn camera_sample(
    view: &View,
    view_index: u32,
    x: u32,
    y: u32,
    settings: &RenderSettings,
    s: u32,
) -> (Ray, Sampler) {
    let pixel = view.pixel_index(x, y);
    let [jx, jy] = strata::pixel_point(settings.seed, view_index, pixel, s, settings.spp);
    let sampler = Sampler::for_pixel_sample(settings.seed, view_index, pixel, s);
    (view.ray(x as f32 + jx, y as f32 + jy), sampler)
}

/// [`render_pixel`], the same bits, and into `gradient` (one entry per group, which it
/// overwrites) the derivative of the pixel's radiance with respect to the log of each
/// group's diffuse colour, from the same samples ([`radiance_with_colour_gradient`]).
pub fn render_pixel_with_colour_gradient(
    scene: &Scene,
    view: &View,
    view_index: u32,
    x: u32,
    y: u32,
    settings: &RenderSettings,
    gradient: &mut [Vec3],
) -> Vec3 {
    gradient.fill(Vec3::ZERO);
    let mut sum = Vec3::ZERO;
    for s in 0..settings.spp {
        let (ray, mut sampler) = camera_sample(view, view_index, x, y, settings, s);
        sum += radiance_with_colour_gradient(scene, ray, &mut sampler, settings, gradient);
    }
    let n = settings.spp.max(1) as f32;
    for d in gradient.iter_mut() {
        *d /= n;
    }
    sum / n
}

/// Renders rows `rows` of a view into `out` (row-major, `width` pixels a row).
pub fn render_rows(
    scene: &Scene,
    view: &View,
    view_index: u32,
    rows: core::ops::Range<u32>,
    settings: &RenderSettings,
    out: &mut [Vec3],
) {
    let width = view.width as usize;
    for (row_offset, y) in rows.enumerate() {
        let Some(line) = out.get_mut(row_offset * width..(row_offset + 1) * width) else {
            return;
        };
        for (x, value) in line.iter_mut().enumerate() {
            *value = render_pixel(scene, view, view_index, x as u32, y, settings);
        }
    }
}

/// Radiance arriving along `ray`, estimated with one path.
pub fn radiance(scene: &Scene, ray: Ray, sampler: &mut Sampler, settings: &RenderSettings) -> Vec3 {
    path_radiance(scene, ray, sampler, settings, None, None, None)
}

/// [`radiance`], the same bits, and added to `gradient[h]` the derivative of this sample
/// with respect to `ln rho_h`, the log of group `h`'s diffuse colour (a map's scale, for a
/// textured group), for every group `h < gradient.len()`. A reflection's `f` responds to
/// it by its diffuse share (`d ln f / d ln rho_d = (rho_d / pi) / f`,
/// [`Bsdf::diffuse_share`]), so each contribution adds itself times the diffuse share of
/// every vertex on `h` it came by. The sampling is held as it is, which leaves the
/// estimate unbiased: its mean is the derivative of the pixel's mean. One render gives the
/// response of every pixel to every colour, where finite differences took a render per
/// colour.
pub fn radiance_with_colour_gradient(
    scene: &Scene,
    ray: Ray,
    sampler: &mut Sampler,
    settings: &RenderSettings,
    gradient: &mut [Vec3],
) -> Vec3 {
    let mut path = GradientPath {
        gradient,
        vertices: [(0, Vec3::ZERO); config::MAX_PATH_DEPTH as usize],
        len: 0,
    };
    path_radiance(scene, ray, sampler, settings, None, None, Some(&mut path))
}

/// The colour gradient of one path ([`radiance_with_colour_gradient`]): the vertices so
/// far whose diffuse lobe carries the light that follows them, each with its group and
/// the diffuse share of the direction the path went on in.
struct GradientPath<'g> {
    gradient: &'g mut [Vec3],
    vertices: [(u16, Vec3); config::MAX_PATH_DEPTH as usize],
    len: usize,
}

impl GradientPath<'_> {
    /// Adds `light`, which came by way of the vertices so far and, when `last` is given,
    /// a last reflection at a vertex of that group and diffuse share.
    fn add(&mut self, light: Vec3, last: Option<(u16, Vec3)>) {
        let vertices = self.vertices.get(..self.len).unwrap_or_default();
        for &(group, share) in vertices.iter().chain(last.iter()) {
            if let Some(d) = self.gradient.get_mut(group as usize) {
                *d += light * share;
            }
        }
    }

    /// The path went on from a vertex of `group` whose diffuse lobe carries `share` of
    /// what follows.
    fn push(&mut self, group: u16, share: Vec3) {
        if let Some(v) = self.vertices.get_mut(self.len) {
            *v = (group, share);
            self.len += 1;
        }
    }
}

/// [`radiance`] and the part of it that comes by way of `group`'s diffuse lobe, at any of
/// the path's vertices: the rest is what the same path carries with the group's colour
/// black, each vertex on the group weighing what it reflects by `1 -`
/// [`Bsdf::diffuse_share`] of the direction it arrives from. Its mean is a render with
/// that colour black, as the two renders it replaces had it: the group's light sent back
/// to itself by way of other surfaces (a sphere lit by what it reflected onto the floor,
/// a picture by its frame) is the colour's. The path is [`radiance`]'s, to the bit.
pub fn radiance_with_diffuse_part(
    scene: &Scene,
    ray: Ray,
    sampler: &mut Sampler,
    settings: &RenderSettings,
    group: u16,
) -> (Vec3, Vec3) {
    let mut diffuse = Vec3::ZERO;
    let total = path_radiance(
        scene,
        ray,
        sampler,
        settings,
        None,
        Some((group, &mut diffuse)),
        None,
    );
    (total, diffuse)
}

/// [`radiance`] along `ray`, a sample of solid-angle pdf `pdf` taken at a non-delta vertex
/// where the lights were also sampled directly and through each planar mirror (as
/// [`crate::transport`] samples a first vertex): a light that `ray` meets, at once or by
/// way of a planar mirror, is MIS-weighted against those samples, as at the renderer's own
/// vertices.
pub fn radiance_after_sample(
    scene: &Scene,
    ray: Ray,
    sampler: &mut Sampler,
    settings: &RenderSettings,
    pdf: f32,
) -> Vec3 {
    path_radiance(scene, ray, sampler, settings, Some(pdf), None, None)
}

/// One path's radiance along `ray`; `after_sample` is the pdf of the non-delta sample
/// that produced `ray`, `None` for a camera ray. With `diffuse_first = (group, part)`,
/// the part of it that the first vertex's diffuse lobe reflects, when that vertex is on
/// `group`, is added to `part` (see [`radiance_with_diffuse_part`]); the path is the same
/// either way.
fn path_radiance(
    scene: &Scene,
    mut ray: Ray,
    sampler: &mut Sampler,
    settings: &RenderSettings,
    after_sample: Option<f32>,
    diffuse_of: Option<(u16, &mut Vec3)>,
    mut gradient: Option<&mut GradientPath>,
) -> Vec3 {
    // With `diffuse_of`, the light that does not come by way of that group's diffuse lobe
    // (`lobe_total`): each contribution times `lobe_fraction`, the product over the
    // path's vertices on the group so far of `1 - diffuse share` of the direction the
    // path went on in (the share of the direction a light sample arrives from, for that
    // sample). Its mean is a render of the same scene with the group's colour black.
    let split_group = diffuse_of.as_ref().map(|(g, _)| *g);
    let mut lobe_total = Vec3::ZERO;
    let mut lobe_fraction = Vec3::ONE;
    let mut total = Vec3::ZERO;
    let mut throughput = Vec3::ONE;
    // The pdf of the BSDF sample that produced `ray`, and whether it was a Dirac sample
    // (camera rays count as one: emission seen directly is not light-sampled).
    let (mut bsdf_pdf, mut delta) = match after_sample {
        Some(pdf) => (pdf, false),
        None => (0.0f32, true),
    };
    // When `ray` leaves a planar mirror that a BSDF sample from a non-delta vertex reached:
    // that sample's pdf and its length. A light at the end of `ray` is then also sampled
    // through the mirror, and MIS weighs the two.
    let mut via_mirror: Option<(f32, f32)> = None;
    let max_depth = settings.max_depth.min(config::MAX_PATH_DEPTH);

    for depth in 0..max_depth {
        let Some(hit) = scene.intersect(&ray, f32::INFINITY) else {
            break;
        };
        let Some(tri) = scene.triangles.get(hit.triangle as usize) else {
            break;
        };
        let n_area2 = tri.normal_area2();
        let area2 = n_area2.length();
        if !(area2 > 0.0) {
            break;
        }
        let ng = n_area2 / area2;
        let cos_hit = -ng.dot(ray.direction);

        let group = match tri.surface {
            Surface::Light(light) => {
                // Lights emit from their front side only and reflect nothing.
                if cos_hit > 0.0 {
                    let le = scene
                        .light_radiance
                        .get(light as usize)
                        .copied()
                        .unwrap_or(Vec3::ZERO);
                    let weight = match (delta, via_mirror) {
                        (false, _) => {
                            let pdf_light =
                                scene.light_pdf_area(hit.triangle) * hit.t * hit.t / cos_hit;
                            power_heuristic(bsdf_pdf, pdf_light)
                        }
                        (true, Some((pdf_before, t_before))) => {
                            let d = t_before + hit.t;
                            let pdf_image = scene.light_pdf_area(hit.triangle) * d * d / cos_hit;
                            power_heuristic(pdf_before, pdf_image)
                        }
                        (true, None) => 1.0,
                    };
                    let light = throughput * le * weight;
                    total += light;
                    if split_group.is_some() {
                        lobe_total += light * lobe_fraction;
                    }
                    if let Some(path) = gradient.as_deref_mut() {
                        path.add(light, None);
                    }
                }
                break;
            }
            Surface::Group(g) => g,
        };
        let on_split_group = split_group == Some(group);
        let Some(surface) = scene.materials.get(group as usize) else {
            break;
        };

        let p = ray.at(hit.t);
        let n = if cos_hit > 0.0 { ng } else { -ng };
        let wo = -ray.direction;
        let rho_d = surface
            .diffuse_map
            .map(|id| scene.textures.lookup(id, tri.uv_at(hit.b1, hit.b2)));
        let bsdf = Bsdf::new(&surface.material, rho_d, n);
        let origin = offset_origin(p, n, scene.size());

        // Next-event estimation: one point on one light, seen directly and in each
        // planar mirror.
        let u_light = sampler.next_f32();
        let u_point = sampler.next_2d();
        if !bsdf.is_delta() {
            if let Some(ls) = scene.sample_light(u_light, u_point) {
                let at = Vertex {
                    bsdf: &bsdf,
                    wo,
                    n,
                    point: p,
                    origin,
                    throughput,
                };
                let mut gather = |light: Vec3, wi: Vec3| {
                    total += light;
                    if split_group.is_some() {
                        lobe_total +=
                            light * lobe_fraction * lobe_share(&bsdf, on_split_group, wo, wi);
                    }
                    if let Some(path) = gradient.as_deref_mut() {
                        path.add(light, Some((group, bsdf.diffuse_share(wo, wi))));
                    }
                };
                if let Some((light, wi)) = direct_light(scene, &at, &ls) {
                    gather(light, wi);
                }
                for mirror in scene.mirror_planes().as_slice() {
                    if let Some((light, wi)) = light_in_mirror(scene, mirror, &at, &ls) {
                        gather(light, wi);
                    }
                }
            }
        }

        // Continue the path by sampling the BSDF.
        let u_lobe = sampler.next_f32();
        let u_dir = sampler.next_2d();
        let Some(sample) = bsdf.sample(wo, u_lobe, u_dir) else {
            break;
        };
        if on_split_group {
            lobe_fraction *= lobe_share(&bsdf, true, wo, sample.wi);
        }
        if let Some(path) = gradient.as_deref_mut() {
            let share = bsdf.diffuse_share(wo, sample.wi);
            if share != Vec3::ZERO {
                path.push(group, share);
            }
        }
        via_mirror = if sample.delta && !delta && scene.mirror_planes().contains(group) {
            Some((bsdf_pdf, hit.t))
        } else {
            None
        };
        throughput *= sample.weight;
        bsdf_pdf = sample.pdf;
        delta = sample.delta;
        if !math::is_finite(throughput) {
            break;
        }

        if depth + 1 >= settings.rr_depth {
            let survive = throughput.max_element().min(0.95);
            if !(sampler.next_f32() < survive) {
                break;
            }
            throughput /= survive;
        }
        ray = Ray::new(origin, sample.wi);
    }
    if let Some((_, d)) = diffuse_of {
        *d += total - lobe_total;
    }
    total
}

/// What of the light a vertex reflects from `wi` towards `wo` is not its diffuse lobe's:
/// `1 - Bsdf::diffuse_share` at a vertex on the group being split (`on_group`), all of
/// it elsewhere.
fn lobe_share(bsdf: &Bsdf, on_group: bool, wo: Vec3, wi: Vec3) -> Vec3 {
    if on_group {
        (Vec3::ONE - bsdf.diffuse_share(wo, wi)).max(Vec3::ZERO)
    } else {
        Vec3::ONE
    }
}

/// A non-delta path vertex where next-event estimation happens.
struct Vertex<'b> {
    bsdf: &'b Bsdf,
    /// Unit direction towards the previous vertex.
    wo: Vec3,
    /// Unit shading normal, turned towards `wo`.
    n: Vec3,
    /// The point on the surface: where light is measured.
    point: Vec3,
    /// The vertex moved off the surface: where shadow rays start.
    origin: Vec3,
    /// The path's throughput up to this vertex.
    throughput: Vec3,
}

/// Light from the point `ls` arriving straight at the vertex, times the path's throughput:
/// `f L cos w / pdf`, MIS-weighted against the BSDF sample, and the direction it arrives
/// from. `None` when none arrives.
fn direct_light(scene: &Scene, at: &Vertex, ls: &LightSample) -> Option<(Vec3, Vec3)> {
    let (bsdf, wo, n) = (at.bsdf, at.wo, at.n);
    let (wi, dist2, cos_light) = towards_light(at.point, ls)?;
    let cos_surface = n.dot(wi);
    if !(cos_light > 0.0 && cos_surface > 0.0 && ls.pdf_area > 0.0) {
        return None;
    }
    let f = bsdf.eval(wo, wi);
    if !(f.max_element() > 0.0) || occluded_on_the_way(scene, at.origin, ls.point) {
        return None;
    }
    let pdf_light = ls.pdf_area * dist2 / cos_light;
    let weight = power_heuristic(pdf_light, bsdf.pdf(wo, wi));
    Some((
        at.throughput * f * ls.radiance * (cos_surface * weight / pdf_light),
        wi,
    ))
}

/// The direction from `point` to the light sample `ls`, its squared length and the cosine
/// at the light. Measured from the surface, not from a shadow ray's origin: that origin is
/// [`RAY_EPSILON`] of the scene's size nearer the light, and a wall lit from the side read
/// 0.07-0.26% bright measured from there (`a_wall_lit_from_the_side_matches_lamberts_formula`).
#[inline]
pub fn towards_light(point: Vec3, ls: &LightSample) -> Option<(Vec3, f32, f32)> {
    let to_light = ls.point - point;
    let dist2 = to_light.length_squared();
    let dist = math::sqrt(dist2);
    if !(dist > 0.0) {
        return None;
    }
    let wi = to_light / dist;
    Some((wi, dist2, -ls.normal.dot(wi)))
}

/// Whether something stands between a shadow ray's `origin` and the light sample at
/// `light_point` (the light itself excepted: the ray stops short of it).
#[inline]
pub fn occluded_on_the_way(scene: &Scene, origin: Vec3, light_point: Vec3) -> bool {
    let to_light = light_point - origin;
    let dist = to_light.length();
    !(dist > 0.0)
        || scene.occluded(
            &Ray::new(origin, to_light / dist),
            dist * (1.0 - RAY_EPSILON),
        )
}

/// Light from the point `ls` arriving at the vertex by way of the planar `mirror`, times
/// the path's throughput, and the direction it arrives from. The same path's pdf as a
/// BSDF sample is the BSDF's at the vertex (the mirror bounce is a delta), so the MIS
/// weight is against it, with the unfolded length.
fn light_in_mirror(
    scene: &Scene,
    mirror: &MirrorPlane,
    at: &Vertex,
    ls: &LightSample,
) -> Option<(Vec3, Vec3)> {
    let (bsdf, wo) = (at.bsdf, at.wo);
    let mut f = Vec3::ZERO;
    let image = light_image_in_mirror(scene, mirror, at.point, at.origin, at.n, ls, |wi| {
        f = bsdf.eval(wo, wi);
        f.max_element() > 0.0
    })?;
    let weight = power_heuristic(image.pdf, bsdf.pdf(wo, image.wi));
    Some((
        at.throughput * f * mirror.rho * ls.radiance * (image.cos_surface * weight / image.pdf),
        image.wi,
    ))
}

/// A light point's image in a planar mirror, seen from a surface point: the direction the
/// light arrives from, and that direction's pdf as a light sample.
#[derive(Clone, Copy, Debug)]
pub struct MirrorImage {
    /// Unit direction from the surface point towards the mirror (and the image behind it).
    pub wi: Vec3,
    /// Cosine between the surface normal and `wi`.
    pub cos_surface: f32,
    /// Solid-angle pdf of `wi` as the light sample: the light's area pdf over the unfolded
    /// path length squared and the light's cosine.
    pub pdf: f32,
}

/// Where the light point `ls` reaches the surface point `point` (normal `n`) by way of
/// the planar `mirror`, when it does: aimed at the point's image behind the mirror, the
/// ray (from `origin`, the point moved off the surface) must meet the mirror first and
/// the light from there. The light arriving is `mirror.rho * ls.radiance`. The direction,
/// path length and cosines are measured from `point`, as in [`towards_light`].
/// `worth_tracing(wi)` is asked before any ray is traced, so that a direction the surface
/// does not reflect costs none.
pub fn light_image_in_mirror(
    scene: &Scene,
    mirror: &MirrorPlane,
    point: Vec3,
    origin: Vec3,
    n: Vec3,
    ls: &LightSample,
    worth_tracing: impl FnOnce(Vec3) -> bool,
) -> Option<MirrorImage> {
    let side_origin = mirror.normal.dot(origin) - mirror.offset;
    let side_light = mirror.normal.dot(ls.point) - mirror.offset;
    if !(side_origin * side_light > 0.0 && ls.pdf_area > 0.0) {
        return None;
    }
    let image = ls.point - mirror.normal * (2.0 * side_light);
    // The light's path unfolded through the mirror: a straight line from the point to
    // the image, as long as the path.
    let to_image = image - point;
    let unfolded = to_image.length();
    if !(unfolded > 0.0) {
        return None;
    }
    let wi = to_image / unfolded;
    let cos_surface = n.dot(wi);
    // `wi` reflected in the mirror's plane: from the mirror on to the light.
    let reflected = wi - mirror.normal * (2.0 * mirror.normal.dot(wi));
    let cos_light = -ls.normal.dot(reflected);
    if !(cos_surface > 0.0 && cos_light > 0.0) {
        return None;
    }
    let to_image = image - origin;
    let dist_image = to_image.length();
    if !(dist_image > 0.0) {
        return None;
    }
    // The first thing the ray meets is the mirror, about where it crosses the plane
    // (outside the mirror's bounds it cannot: most vertices see most lights' images
    // beside a mirror, and these need neither the BSDF nor a ray).
    let t_plane = dist_image * side_origin / (side_origin + side_light);
    let to_mirror = Ray::new(origin, to_image / dist_image);
    let crossing = to_mirror.at(t_plane);
    let (lo, hi) = mirror.bounds;
    if !(crossing.cmpge(lo).all() && crossing.cmple(hi).all()) {
        return None;
    }
    if !worth_tracing(wi) {
        return None;
    }
    let hit = scene.intersect(&to_mirror, t_plane * (1.0 + MIRROR_HIT_SLACK))?;
    let on_mirror = scene
        .triangles
        .get(hit.triangle as usize)
        .is_some_and(|t| t.surface == Surface::Group(mirror.group));
    if !on_mirror {
        return None;
    }
    let facing = if side_origin > 0.0 {
        mirror.normal
    } else {
        -mirror.normal
    };
    let from_mirror = offset_origin(to_mirror.at(hit.t), facing, scene.size());
    if occluded_on_the_way(scene, from_mirror, ls.point) {
        return None;
    }
    Some(MirrorImage {
        wi,
        cos_surface,
        pdf: ls.pdf_area * unfolded * unfolded / cos_light,
    })
}

/// How far past the mirror's plane (relative) a ray aimed at a light's image may meet the
/// mirror: rounding only, a planar mirror is met at the plane.
const MIRROR_HIT_SLACK: f32 = 1e-3;

/// What the whole footprint of pixel `(x, y)` sees, tested with `n_sub x n_sub` rays on a
/// grid over the pixel's square (edges included): `Some(surface)` when every ray hits the
/// same group, or the emitting (front) side of the same light; `None` on silhouettes, where
/// a ray escapes and where a ray sees a light's back, which is black: such a pixel does
/// not show the light's radiance.
pub fn pixel_surface(scene: &Scene, view: &View, x: u32, y: u32, n_sub: u32) -> Option<Surface> {
    footprint_sees(scene, view, x, y, n_sub, false)
}

/// The light whose back (non-emitting) side the whole footprint of pixel `(x, y)` sees,
/// tested as [`pixel_surface`] tests a front: such a pixel is black in a panorama of the
/// scene as declared, and one that reads bright tells of a light whose triangles face away
/// from where it shines.
pub fn pixel_light_back(scene: &Scene, view: &View, x: u32, y: u32, n_sub: u32) -> Option<u16> {
    match footprint_sees(scene, view, x, y, n_sub, true)? {
        Surface::Light(light) => Some(light),
        Surface::Group(_) => None,
    }
}

/// The one surface every ray of the footprint grid hits: light fronts and groups
/// (`backs` false), or light backs only (`backs` true).
fn footprint_sees(
    scene: &Scene,
    view: &View,
    x: u32,
    y: u32,
    n_sub: u32,
    backs: bool,
) -> Option<Surface> {
    let n = n_sub.max(2);
    let mut seen: Option<Surface> = None;
    for j in 0..n {
        for i in 0..n {
            let fx = x as f32 + i as f32 / (n - 1) as f32;
            let fy = y as f32 + j as f32 / (n - 1) as f32;
            let ray = view.ray(fx, fy);
            let hit = scene.intersect(&ray, f32::INFINITY)?;
            let tri = scene.triangles.get(hit.triangle as usize)?;
            let surface = tri.surface;
            let light_back = matches!(surface, Surface::Light(_))
                && tri.normal_area2().dot(ray.direction) >= 0.0;
            if light_back != backs {
                return None;
            }
            match seen {
                None => seen = Some(surface),
                Some(s) if s != surface => return None,
                Some(_) => {}
            }
        }
    }
    seen
}

#[cfg(test)]
pub(crate) mod tests {
    //! Analytic checks of the path tracer: scenes whose radiance is known in closed form.

    use super::*;
    use crate::bvh::{Bvh, BvhBuffers, BvhNode, PackedTriangle};
    use crate::geometry::Triangle;
    use crate::material::{Material, SurfaceMaterial, Textures};
    use crate::math::Vec2;
    use crate::scene::{BuiltCounts, BuiltStorage, GroupPlane, LightTriangle, SceneStorage};
    use std::vec;
    use std::vec::Vec;

    /// A unit sphere of `rings x segments` quads (two triangles each). Quads whose centre
    /// lies above `cos(cap) ` in z emit (`Surface::Light(0)`, front side facing the centre);
    /// the rest are group 0.
    fn furnace_sphere(rings: u32, segments: u32, cap_deg: f32) -> Vec<Triangle> {
        let point = |i: u32, j: u32| {
            let theta = math::PI * i as f32 / rings as f32;
            let phi = 2.0 * math::PI * j as f32 / segments as f32;
            Vec3::new(
                math::sin(theta) * math::cos(phi),
                math::sin(theta) * math::sin(phi),
                math::cos(theta),
            )
        };
        let cap_cos = math::cos(math::radians(cap_deg));
        let mut tris = Vec::new();
        for i in 0..rings {
            for j in 0..segments {
                let (a, b, c, d) = (
                    point(i, j),
                    point(i + 1, j),
                    point(i + 1, j + 1),
                    point(i, j + 1),
                );
                let centre = (a + b + c + d) * 0.25;
                let surface = if centre.normalize().z > cap_cos {
                    Surface::Light(0)
                } else {
                    Surface::Group(0)
                };
                // Wound so that the front normal points inwards (lights emit to the centre).
                for v in [[a, c, b], [a, d, c]] {
                    if (v[1] - v[0]).cross(v[2] - v[0]).length_squared() > 0.0 {
                        tris.push(Triangle {
                            v,
                            uv: [Vec2::ZERO; 3],
                            surface,
                        });
                    }
                }
            }
        }
        tris
    }

    /// A one-group scene's material: diffuse of albedo `a`.
    fn diffuse(a: f32) -> [SurfaceMaterial; 1] {
        [SurfaceMaterial {
            material: Material::Diffuse {
                rho_d: Vec3::splat(a),
            },
            diffuse_map: None,
        }]
    }

    /// The storage a test lends its scene, sized for `triangles` triangles.
    pub(crate) struct LentStorage {
        nodes: Vec<BvhNode>,
        packed: Vec<PackedTriangle>,
        lights: Vec<LightTriangle>,
        planes: Vec<GroupPlane>,
    }

    impl LentStorage {
        fn new(triangles: usize) -> Self {
            let (n_nodes, n_packed) = Bvh::buffer_sizes(triangles);
            LentStorage {
                nodes: vec![BvhNode::default(); n_nodes],
                packed: vec![PackedTriangle::default(); n_packed],
                lights: vec![LightTriangle::default(); triangles],
                planes: Vec::new(),
            }
        }

        /// A scene built afresh into this storage.
        fn build<'a>(
            &'a mut self,
            triangles: &'a [Triangle],
            materials: &'a [SurfaceMaterial],
            radiance: &'a [Vec3],
        ) -> Scene<'a> {
            self.planes = vec![GroupPlane::default(); materials.len()];
            Scene::build(
                triangles,
                materials,
                radiance,
                Textures::default(),
                SceneStorage {
                    bvh: BvhBuffers {
                        nodes: &mut self.nodes,
                        packed: &mut self.packed,
                    },
                    light_table: &mut self.lights,
                    group_planes: &mut self.planes,
                },
            )
            .unwrap()
        }
    }

    /// Mean and standard error of the mean of `values`.
    pub(crate) fn mean_and_standard_error(values: impl Iterator<Item = f64>) -> (f64, f64) {
        let (mut sum, mut sum2, mut count) = (0.0f64, 0.0f64, 0u32);
        for l in values {
            sum += l;
            sum2 += l * l;
            count += 1;
        }
        let mean = sum / count as f64;
        let var = (sum2 / count as f64 - mean * mean).max(0.0);
        (mean, (var / count as f64).sqrt())
    }

    /// A direction spread uniformly over the sphere, from the sampler's next two numbers.
    fn uniform_direction(sampler: &mut Sampler) -> Vec3 {
        let [u1, u2] = sampler.next_2d();
        let z = 1.0 - 2.0 * u1;
        let r = math::sqrt((1.0 - z * z).max(0.0));
        let phi = 2.0 * math::PI * u2;
        Vec3::new(r * math::cos(phi), r * math::sin(phi), z)
    }

    /// Mean and standard error of the radiance seen from the sphere's centre along
    /// uniformly spread directions that meet the diffuse part.
    fn mean_radiance_from_centre(scene: &Scene, n: u32, settings: &RenderSettings) -> (f64, f64) {
        mean_and_standard_error((0..n).filter_map(|k| {
            let mut sampler = Sampler::for_pixel_sample(settings.seed, 0, k, 0);
            let ray = Ray::new(Vec3::ZERO, uniform_direction(&mut sampler));
            let hit = scene.intersect(&ray, f32::INFINITY)?;
            if scene.triangles[hit.triangle as usize].surface != Surface::Group(0) {
                return None;
            }
            Some(radiance(scene, ray, &mut sampler, settings).y as f64)
        }))
    }

    /// Furnace test. In a sphere every surface element sees every other with the same
    /// form factor, so with a non-reflecting emitter of radiance `Le` over a fraction `f`
    /// of the area and diffuse albedo `a` elsewhere, the diffuse radiance is uniform:
    /// `L = a (f Le + (1 - f) L)`, i.e. `L = a f Le / (1 - a (1 - f))`. (With `f = 1`
    /// reflecting this is the classic `Le / (1 - a)` furnace; our lights do not reflect.)
    /// High albedos make the answer depend on every bounce and on Russian roulette.
    #[test]
    fn furnace_sphere_matches_the_closed_form() {
        let triangles = furnace_sphere(64, 128, 25.0);
        let (area_light, area_total) = triangles.iter().fold((0.0f64, 0.0f64), |(l, t), tri| {
            let a = tri.area() as f64;
            match tri.surface {
                Surface::Light(_) => (l + a, t + a),
                Surface::Group(_) => (l, t + a),
            }
        });
        let f = area_light / area_total;
        let le = 2.0f64;
        for albedo in [0.3f32, 0.8] {
            let materials = diffuse(albedo);
            let radiance = [Vec3::splat(le as f32)];
            let mut storage = LentStorage::new(triangles.len());
            let scene = storage.build(&triangles, &materials, &radiance);
            let settings = RenderSettings {
                seed: 11,
                ..RenderSettings::default()
            };
            let (mean, se) = mean_radiance_from_centre(&scene, 40_000, &settings);
            let a = albedo as f64;
            let expected = a * f * le / (1.0 - a * (1.0 - f));
            // 4 standard errors of Monte Carlo noise, plus 0.5% for the tessellated sphere
            // (its facets are not exactly on the sphere, so form factors are not exactly equal).
            let tolerance = 4.0 * se + 0.005 * expected;
            assert!(
                (mean - expected).abs() <= tolerance,
                "albedo {albedo}: mean {mean:.5} +- {se:.5}, expected {expected:.5} (f = {f:.4})"
            );
        }
    }

    /// A closed unit cube, corner at the origin, scaled by `scale`: its six faces group 0
    /// and a square light facing down just under the ceiling.
    fn room(scale: f32) -> Vec<Triangle> {
        let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z) * scale;
        let faces = [
            [v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)],
            [v(0., 0., 1.), v(0., 1., 1.), v(1., 1., 1.), v(1., 0., 1.)],
            [v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 1.), v(1., 0., 0.)],
            [v(0., 1., 0.), v(1., 1., 0.), v(1., 1., 1.), v(0., 1., 1.)],
            [v(0., 0., 0.), v(0., 1., 0.), v(0., 1., 1.), v(0., 0., 1.)],
            [v(1., 0., 0.), v(1., 0., 1.), v(1., 1., 1.), v(1., 1., 0.)],
        ];
        let mut triangles: Vec<Triangle> = faces
            .iter()
            .flat_map(|&f| quad(f, Surface::Group(0)))
            .collect();
        let (lo, hi, h) = (0.4, 0.6, 0.99);
        let light = [v(lo, lo, h), v(lo, hi, h), v(hi, hi, h), v(hi, lo, h)];
        triangles.extend(quad(light, Surface::Light(0)));
        triangles
    }

    /// The same room in millimetres, metres or kilometres renders the same: secondary rays
    /// leave a surface by a fraction of the scene's size, not of a unit of length. (With
    /// a floor of one unit, the room a thousandth of a unit across read 17% bright.) The
    /// paths share their random numbers, so the renders differ only by rounding; their
    /// paired difference is held to its own noise and 0.1%.
    #[test]
    fn a_room_renders_the_same_at_any_scale() {
        let (materials, light) = (diffuse(0.7), [Vec3::splat(5.0)]);
        let settings = RenderSettings {
            seed: 7,
            ..RenderSettings::default()
        };
        let render = |scale: f32| -> Vec<f64> {
            let triangles = room(scale);
            let mut storage = LentStorage::new(triangles.len());
            let scene = storage.build(&triangles, &materials, &light);
            let centre = Vec3::splat(0.5 * scale);
            (0..20_000)
                .map(|k| {
                    let mut sampler = Sampler::for_pixel_sample(settings.seed, 0, k, 0);
                    let ray = Ray::new(centre, uniform_direction(&mut sampler));
                    radiance(&scene, ray, &mut sampler, &settings).y as f64
                })
                .collect()
        };
        let metres = render(1.0);
        let (mean, _) = mean_and_standard_error(metres.iter().copied());
        for scale in [1e-3f32, 1e3] {
            let other = render(scale);
            let (diff, se) = mean_and_standard_error(other.iter().zip(&metres).map(|(a, b)| a - b));
            assert!(
                diff.abs() <= 4.0 * se + 1e-3 * mean,
                "scale {scale}: mean radiance {:.5} against {mean:.5} in metres (+- {se:.5})",
                mean + diff
            );
        }
    }

    /// A pixel's variance comes from the difference of its two halves: over pixels that
    /// straddle a light's edge, where the sample's place in the pixel is most of the
    /// noise, it matches the spread of the pixel's value across seeds. (The sample
    /// variance over `n`, as independent samples would have it, read it 2.4x too high.)
    #[test]
    fn a_pixels_variance_is_the_spread_of_its_value_across_seeds() {
        let triangles = room(1.0);
        let (materials, light) = (diffuse(0.05), [Vec3::splat(5.0)]);
        let mut storage = LentStorage::new(triangles.len());
        let scene = storage.build(&triangles, &materials, &light);
        // Looking up at the light (0.4..0.6 at height 0.99) from 0.69 below it, the view
        // turned by 30 degrees: a pixel is 0.05 across there, and the light's edges cross
        // pixels at every fraction. A dark room, so the edges are most of the noise.
        let up = Vec3::new(0.5, 0.866, 0.0);
        let view = View::new(
            Vec3::new(0.5, 0.5, 0.3),
            Vec3::Z,
            up,
            [40.0, 40.0],
            [10, 10],
        )
        .unwrap();
        let (seeds, spp) = (300u64, 8u32);
        let (mut spread, mut predicted) = (0.0f64, 0.0f64);
        for y in 0..10 {
            for x in 0..10 {
                let (mut sum, mut sum_sq, mut variance) = (0.0f64, 0.0f64, 0.0f64);
                for seed in 0..seeds {
                    let settings = RenderSettings {
                        spp,
                        seed,
                        ..RenderSettings::default()
                    };
                    let (mean, var) = render_pixel_with_variance(&scene, &view, 0, x, y, &settings);
                    let value = mean.y as f64;
                    sum += value;
                    sum_sq += value * value;
                    variance += var.y as f64;
                }
                let n = seeds as f64;
                spread += (sum_sq - sum * sum / n) / (n - 1.0);
                predicted += variance / n;
            }
        }
        let ratio = predicted / spread;
        assert!(
            (0.85..1.15).contains(&ratio),
            "predicted / observed variance {ratio:.3}"
        );
    }

    /// A pixel wholly on a light is labelled with it only from the emitting side: from
    /// behind the light is black, so the pixel shows nothing of its radiance.
    #[test]
    fn a_light_is_a_pixels_surface_only_from_its_front() {
        let triangles = furnace_sphere(16, 32, 40.0);
        let (materials, radiance) = (diffuse(0.5), [Vec3::splat(1.0)]);
        let mut storage = LentStorage::new(triangles.len());
        let scene = storage.build(&triangles, &materials, &radiance);
        // Narrow views of the cap around +z: from the centre (its front), from above the
        // sphere looking down (its back), and from the centre looking down (a group).
        let view = |position: Vec3, direction: Vec3| {
            View::new(position, direction, Vec3::X, [2.0, 2.0], [3, 3]).unwrap()
        };
        let from_inside = view(Vec3::ZERO, Vec3::Z);
        let from_outside = view(Vec3::new(0.0, 0.0, 3.0), -Vec3::Z);
        let floor = view(Vec3::ZERO, -Vec3::Z);
        assert_eq!(
            pixel_surface(&scene, &from_inside, 1, 1, 4),
            Some(Surface::Light(0))
        );
        assert_eq!(pixel_surface(&scene, &from_outside, 1, 1, 4), None);
        assert_eq!(
            pixel_surface(&scene, &floor, 1, 1, 4),
            Some(Surface::Group(0))
        );
        // The light's back is what `pixel_light_back` finds, and only there.
        assert_eq!(pixel_light_back(&scene, &from_outside, 1, 1, 4), Some(0));
        assert_eq!(pixel_light_back(&scene, &from_inside, 1, 1, 4), None);
        assert_eq!(pixel_light_back(&scene, &floor, 1, 1, 4), None);
    }

    /// A pixel past the view's edge has a ray like any other; its index into the random
    /// streams once overflowed (`y * width + x`) and panicked in debug builds (fuzzing the
    /// core, 2026-12-06). Inside the view the index is the row-major one.
    #[test]
    fn a_pixel_outside_the_view_renders_without_overflow() {
        use crate::transport::{trace_pixel_sample, IncidentSample, MAX_INCIDENT_PER_SAMPLE};
        let triangles = furnace_sphere(8, 16, 40.0);
        let (materials, radiance) = (diffuse(0.5), [Vec3::splat(1.0)]);
        let mut storage = LentStorage::new(triangles.len());
        let scene = storage.build(&triangles, &materials, &radiance);
        let view = View::new(Vec3::ZERO, -Vec3::Z, Vec3::X, [60.0, 60.0], [2, 2]).unwrap();
        let settings = RenderSettings {
            spp: 2,
            ..RenderSettings::default()
        };
        for (x, y) in [(0, u32::MAX), (u32::MAX, 1), (u32::MAX, u32::MAX)] {
            assert!(math::is_finite(render_pixel(
                &scene, &view, 0, x, y, &settings
            )));
            let mut out = [IncidentSample::default(); MAX_INCIDENT_PER_SAMPLE];
            trace_pixel_sample(&scene, &view, 0, x, y, 0, 0, &settings, &mut out);
        }
        assert_eq!(view.pixel_index(1, 1), 3);
    }

    /// A quad `a b c d` (counter-clockwise seen from its front) as two triangles.
    fn quad(corners: [Vec3; 4], surface: Surface) -> [Triangle; 2] {
        let [a, b, c, d] = corners;
        let uv = [Vec2::ZERO; 3];
        [
            Triangle {
                v: [a, b, c],
                uv,
                surface,
            },
            Triangle {
                v: [a, c, d],
                uv,
                surface,
            },
        ]
    }

    /// Irradiance at `p` (normal `n`) from a Lambertian polygon of unit radiance wholly
    /// above `p`'s horizon: Lambert's contour formula, `1/2 sum theta_i (u_i x u_i+1)^ . n`.
    fn polygon_irradiance(p: [f64; 3], n: [f64; 3], polygon: &[[f64; 3]]) -> f64 {
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let unit = |a: [f64; 3]| {
            let l = libm::sqrt(dot(a, a));
            [a[0] / l, a[1] / l, a[2] / l]
        };
        let mut sum = 0.0;
        for i in 0..polygon.len() {
            let u = unit(sub(polygon[i], p));
            let v = unit(sub(polygon[(i + 1) % polygon.len()], p));
            sum += libm::acos(dot(u, v).clamp(-1.0, 1.0)) * dot(unit(cross(u, v)), n);
        }
        0.5 * sum.abs()
    }

    /// A small tile at the origin facing up (group 0, of `tile`), under a square light of
    /// unit radiance facing down, beside a wall mirror of reflectance 0.8 (group 1) at
    /// x = -0.5. With `bent`, the mirror's group has one tiny triangle far off its plane:
    /// the same light by way of the mirror, but no planar mirror to sample it through.
    pub(crate) struct TileBesideAMirror {
        pub(crate) triangles: Vec<Triangle>,
        pub(crate) materials: [SurfaceMaterial; 2],
        pub(crate) light_radiance: [Vec3; 1],
    }

    impl TileBesideAMirror {
        pub(crate) fn new(tile: Material, bent: bool) -> Self {
            let mut triangles = Vec::new();
            triangles.extend(quad(
                [
                    v(-0.05, -0.05, 0.0),
                    v(0.05, -0.05, 0.0),
                    v(0.05, 0.05, 0.0),
                    v(-0.05, 0.05, 0.0),
                ],
                Surface::Group(0),
            ));
            // The light faces down (its corners run clockwise seen from above).
            triangles.extend(quad(Self::LIGHT, Surface::Light(0)));
            triangles.extend(quad(
                [
                    v(-0.5, -2.0, -1.0),
                    v(-0.5, 2.0, -1.0),
                    v(-0.5, 2.0, 3.0),
                    v(-0.5, -2.0, 3.0),
                ],
                Surface::Group(1),
            ));
            if bent {
                triangles.push(Triangle {
                    v: [v(-3.0, 5.0, 5.0), v(-3.0, 5.01, 5.0), v(-3.0, 5.0, 5.01)],
                    uv: [Vec2::ZERO; 3],
                    surface: Surface::Group(1),
                });
            }
            let materials = [
                SurfaceMaterial {
                    material: tile,
                    diffuse_map: None,
                },
                SurfaceMaterial {
                    material: Material::Mirror {
                        rho: Vec3::splat(0.8),
                    },
                    diffuse_map: None,
                },
            ];
            TileBesideAMirror {
                triangles,
                materials,
                light_radiance: [Vec3::ONE],
            }
        }

        /// Storage for the scene's triangles, to build it into with [`Self::scene`].
        pub(crate) fn storage(&self) -> LentStorage {
            LentStorage::new(self.triangles.len())
        }

        /// The scene, built into `storage`.
        pub(crate) fn scene<'a>(&'a self, storage: &'a mut LentStorage) -> Scene<'a> {
            storage.build(&self.triangles, &self.materials, &self.light_radiance)
        }

        const LIGHT: [Vec3; 4] = [
            Vec3::new(0.2, -0.1, 1.0),
            Vec3::new(0.2, 0.1, 1.0),
            Vec3::new(0.4, 0.1, 1.0),
            Vec3::new(0.4, -0.1, 1.0),
        ];

        /// The tile's radiance at its centre when it is diffuse of albedo `albedo`:
        /// nothing else reflects, so it is `albedo / pi (E_light + 0.8 E_image)`, both
        /// irradiances exact by Lambert's formula (the image: the light mirrored in the
        /// wall).
        pub(crate) fn diffuse_radiance(albedo: f64) -> f64 {
            let corners: Vec<[f64; 3]> = Self::LIGHT
                .iter()
                .map(|c| [c.x as f64, c.y as f64, c.z as f64])
                .collect();
            let image: Vec<[f64; 3]> = corners.iter().map(|c| [-1.0 - c[0], c[1], c[2]]).collect();
            let (p, up) = ([0.0; 3], [0.0, 0.0, 1.0]);
            albedo / core::f64::consts::PI
                * (polygon_irradiance(p, up, &corners) + 0.8 * polygon_irradiance(p, up, &image))
        }
    }

    fn v(x: f32, y: f32, z: f32) -> Vec3 {
        Vec3::new(x, y, z)
    }

    /// Light by way of a planar mirror: [`TileBesideAMirror`]'s diffuse tile rendered with
    /// the mirror sampled through (the mirror flat) and by BSDF sampling alone (bent) must
    /// both give the closed form; sampling through the mirror with far less noise.
    #[test]
    fn light_by_way_of_a_planar_mirror_matches_the_closed_form() {
        let tile = Material::Diffuse {
            rho_d: Vec3::splat(0.5),
        };
        let expected = TileBesideAMirror::diffuse_radiance(0.5);

        let settings = RenderSettings {
            seed: 11,
            ..RenderSettings::default()
        };
        let estimate = |scene: &Scene, n: u32| {
            mean_and_standard_error((0..n).map(|k| {
                let mut sampler = Sampler::for_pixel_sample(settings.seed, 0, k, 0);
                let ray = Ray::new(v(0.0, 0.0, 0.5), -Vec3::Z);
                radiance(scene, ray, &mut sampler, &settings).y as f64
            }))
        };
        let n = 100_000;

        let flat_parts = TileBesideAMirror::new(tile, false);
        let mut storage = flat_parts.storage();
        let flat = flat_parts.scene(&mut storage);
        assert_eq!(flat.mirror_planes().as_slice().len(), 1);
        let (through, through_se) = estimate(&flat, n);

        let bent_parts = TileBesideAMirror::new(tile, true);
        let mut bent_storage = bent_parts.storage();
        let curved = bent_parts.scene(&mut bent_storage);
        assert!(curved.mirror_planes().as_slice().is_empty());
        let (bsdf_only, bsdf_only_se) = estimate(&curved, n);

        for (what, mean, se) in [
            ("through the mirror", through, through_se),
            ("BSDF sampling alone", bsdf_only, bsdf_only_se),
        ] {
            assert!(
                (mean - expected).abs() < 4.0 * se + 1e-4 * expected,
                "{what}: {mean} +- {se}, expected {expected}"
            );
        }
        assert!(
            through_se < 0.002 * expected,
            "through the mirror: standard error {through_se} of {expected}"
        );
        assert!(
            through_se * 3.0 < bsdf_only_se,
            "standard errors: {through_se} through the mirror, {bsdf_only_se} without"
        );
    }

    /// The diffuse part split from a path ([`radiance_with_diffuse_part`]): on
    /// [`TileBesideAMirror`] with a glossy tile, which sees nothing of itself, it must be
    /// the diffuse lobe's closed form, the rest what the tile renders with its diffuse
    /// colour black (the two renders the colour polish took before), and the path's
    /// radiance the same bits as [`radiance`]'s.
    #[test]
    fn the_diffuse_part_of_a_path_is_the_diffuse_lobes_light() {
        let glossy = |rho_d: f32| ward_tile(rho_d, 0.1);
        let settings = RenderSettings {
            seed: 17,
            ..RenderSettings::default()
        };
        // The tile's centre seen from above, a little off the normal: the highlight is in
        // view, but not the whole of what the tile reflects.
        let ray = || Ray::new(v(-0.01, 0.0, 0.5), v(0.01, 0.0, -0.5).normalize());
        let n = 100_000;

        let parts = TileBesideAMirror::new(glossy(0.4), false);
        let mut storage = parts.storage();
        let scene = parts.scene(&mut storage);
        let (mut diffuse, mut rest) = (Vec::new(), Vec::new());
        for k in 0..n {
            let mut sampler = Sampler::for_pixel_sample(settings.seed, 0, k, 0);
            let (total, part) =
                radiance_with_diffuse_part(&scene, ray(), &mut sampler, &settings, 0);
            let mut again = Sampler::for_pixel_sample(settings.seed, 0, k, 0);
            let plain = radiance(&scene, ray(), &mut again, &settings);
            assert_eq!(
                total.to_array().map(f32::to_bits),
                plain.to_array().map(f32::to_bits)
            );
            // Another group asked for: nothing of this path is its diffuse light.
            let mut other = Sampler::for_pixel_sample(settings.seed, 0, k, 0);
            assert_eq!(
                radiance_with_diffuse_part(&scene, ray(), &mut other, &settings, 1).1,
                Vec3::ZERO
            );
            diffuse.push(part.y as f64);
            rest.push((total - part).y as f64);
        }
        let (diffuse, diffuse_se) = mean_and_standard_error(diffuse.into_iter());
        let expected = TileBesideAMirror::diffuse_radiance(0.4);
        assert!(
            (diffuse - expected).abs() < 4.0 * diffuse_se + 1e-4 * expected,
            "diffuse part {diffuse} +- {diffuse_se}, closed form {expected}"
        );

        let black_parts = TileBesideAMirror::new(glossy(0.0), false);
        let mut black_storage = black_parts.storage();
        let black = black_parts.scene(&mut black_storage);
        let (lobe, lobe_se) = mean_and_standard_error((0..n).map(|k| {
            let mut sampler = Sampler::for_pixel_sample(settings.seed + 1, 0, k, 0);
            let (total, part) =
                radiance_with_diffuse_part(&black, ray(), &mut sampler, &settings, 0);
            assert_eq!(part, Vec3::ZERO, "a black diffuse lobe reflects nothing");
            total.y as f64
        }));
        let (rest, rest_se) = mean_and_standard_error(rest.into_iter());
        assert!(lobe > 0.05 * expected, "the lobe must be in view: {lobe}");
        assert!(
            (rest - lobe).abs() < 4.0 * libm::sqrt(rest_se * rest_se + lobe_se * lobe_se),
            "the rest {rest} +- {rest_se}, the tile with a black colour {lobe} +- {lobe_se}"
        );
    }

    /// The Ward lobe of reflectance.md, written out again so that the quadrature below
    /// does not share the renderer's code: `f_s(l, v) = S (h.h) / (pi a^2 (h.n)^4) exp(-((h.h)
    /// - (h.n)^2) / ((h.n)^2 a^2))`, `h = l + v` unnormalised, `n` the z axis.
    fn ward_lobe_by_the_formula(specularity: f64, alpha: f64, l: [f64; 3], view: [f64; 3]) -> f64 {
        let h = [l[0] + view[0], l[1] + view[1], l[2] + view[2]];
        let hh = h[0] * h[0] + h[1] * h[1] + h[2] * h[2];
        let hn2 = h[2] * h[2];
        let a2 = alpha * alpha;
        specularity * hh / (core::f64::consts::PI * a2 * hn2 * hn2)
            * libm::exp(-(hh - hn2) / (hn2 * a2))
    }

    /// A centimetre-wide glossy tile at the origin facing up (group 0: black diffuse, a
    /// Ward lobe of specularity 0.08 and roughness 0.15, as glossy's blue sphere), a
    /// diffuse wall of albedo 0.8 at x = -0.5 facing it (group 1), and a square light of
    /// unit radiance facing down beside the tile, which lights the wall from the side
    /// and below z = 1 only. The tile is small so that the light it sends to the wall (a
    /// caustic) is below a thousandth of the wall's.
    struct TileBeforeALitWall {
        triangles: Vec<Triangle>,
        materials: [SurfaceMaterial; 2],
    }

    impl TileBeforeALitWall {
        const SPECULARITY: f64 = 0.08;
        const ALPHA: f64 = 0.15;
        const ALBEDO: f64 = 0.8;
        const WALL_X: f64 = -0.5;
        const LIGHT: [[f64; 3]; 4] = [
            [0.2, -0.1, 1.0],
            [0.2, 0.1, 1.0],
            [0.4, 0.1, 1.0],
            [0.4, -0.1, 1.0],
        ];

        fn new() -> Self {
            let mut triangles = Vec::new();
            let half = 0.005;
            triangles.extend(quad(
                [
                    v(-half, -half, 0.0),
                    v(half, -half, 0.0),
                    v(half, half, 0.0),
                    v(-half, half, 0.0),
                ],
                Surface::Group(0),
            ));
            let light = Self::LIGHT.map(|c| v(c[0] as f32, c[1] as f32, c[2] as f32));
            triangles.extend(quad(light, Surface::Light(0)));
            let x = Self::WALL_X as f32;
            triangles.extend(quad(
                [
                    v(x, -3.0, -1.0),
                    v(x, 3.0, -1.0),
                    v(x, 3.0, 3.0),
                    v(x, -3.0, 3.0),
                ],
                Surface::Group(1),
            ));
            let materials = [
                SurfaceMaterial {
                    material: Material::Ward {
                        rho_d: Vec3::ZERO,
                        rho_s: Vec3::splat(Self::SPECULARITY as f32),
                        alpha: Self::ALPHA as f32,
                    },
                    diffuse_map: None,
                },
                SurfaceMaterial {
                    material: Material::Diffuse {
                        rho_d: Vec3::splat(Self::ALBEDO as f32),
                    },
                    diffuse_map: None,
                },
            ];
            TileBeforeALitWall {
                triangles,
                materials,
            }
        }

        /// The wall's radiance at `p` on it, exact: `albedo / pi` times the light's
        /// irradiance by Lambert's formula (zero above the light's plane, which it faces
        /// away from).
        fn wall_radiance(p: [f64; 3]) -> f64 {
            if p[2] >= Self::LIGHT[0][2] {
                return 0.0;
            }
            Self::ALBEDO / core::f64::consts::PI
                * polygon_irradiance(p, [1.0, 0.0, 0.0], &Self::LIGHT)
        }

        /// Mean and standard error of the green radiance along `ray` over `n` paths.
        fn render(&self, ray: Ray, seed: u64, n: u32) -> (f64, f64) {
            let mut storage = LentStorage::new(self.triangles.len());
            let scene = storage.build(&self.triangles, &self.materials, &[Vec3::ONE]);
            let settings = RenderSettings {
                seed,
                ..RenderSettings::default()
            };
            mean_and_standard_error((0..n).map(|k| {
                let mut sampler = Sampler::for_pixel_sample(seed, 0, k, 0);
                radiance(&scene, ray, &mut sampler, &settings).y as f64
            }))
        }
    }

    /// Direct light at a point of the wall, lit from the side: Lambert's formula. Shadow
    /// rays leave a surface [`RAY_EPSILON`] of the scene's size off it, and the light
    /// was measured from there too until it was measured from the surface; at 1e-4 of the
    /// scene's 6 m that is 0.6 mm nearer this light, and the wall read 0.07% bright at z
    /// = 0.1 and 0.26% at z = 0.9, as Lambert's formula 0.6 mm off the wall gives.
    #[test]
    fn a_wall_lit_from_the_side_matches_lamberts_formula() {
        let parts = TileBeforeALitWall::new();
        for (z, seed) in [(0.1f32, 31), (0.5, 32), (0.9, 33)] {
            let expected = TileBeforeALitWall::wall_radiance([-0.5, 0.0, z as f64]);
            let (mean, se) = parts.render(Ray::new(v(0.0, 0.0, z), -Vec3::X), seed, 400_000);
            assert!(
                (mean - expected).abs() < 4.0 * se + 2e-4 * expected,
                "z = {z}: rendered {mean} +- {se}, Lambert's formula {expected}"
            );
        }
    }

    /// A glossy reflection of a surface that only reflects: [`TileBeforeALitWall`]'s tile
    /// seen at 45 degrees, whose lobe looks at the wall. Nothing but the lobe carries light
    /// to the camera, so the pixel is two integrals over the lobe, computed here by
    /// quadrature: of the light, and of the wall, whose radiance is exact. The path tracer
    /// reaches the wall only by sampling the lobe (the wall does not emit), which
    /// RADIANCE's references do with their own specular samples
    /// (docs/renderer-vs-radiance.md, "Glossy lobes and RADIANCE's specular samples").
    #[test]
    fn a_glossy_reflection_of_a_lit_wall_matches_the_quadrature() {
        type T = TileBeforeALitWall;
        // The camera looks at the tile's centre from (0.5, 0, 0.5): the mirror direction
        // meets the wall at (-0.5, 0, 0.5), under the light's plane, where it is lit.
        let view = [
            core::f64::consts::FRAC_1_SQRT_2,
            0.0,
            core::f64::consts::FRAC_1_SQRT_2,
        ];
        // Radiance reflected to the camera by way of a small patch at `p`, of radiance
        // `radiance`, whose plane has the unit normal `normal`: `f cos_tile cos_patch / r^2`.
        let reflected = |p: [f64; 3], normal: [f64; 3], radiance: f64| {
            let r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
            let r = libm::sqrt(r2);
            let l = [p[0] / r, p[1] / r, p[2] / r];
            let cos_patch = -(l[0] * normal[0] + l[1] * normal[1] + l[2] * normal[2]);
            if l[2] <= 0.0 || cos_patch <= 0.0 {
                return 0.0;
            }
            ward_lobe_by_the_formula(T::SPECULARITY, T::ALPHA, l, view)
                * radiance
                * l[2]
                * cos_patch
                / r2
        };
        let from_light =
            midpoint_quadrature(T::LIGHT[0], [0.2, 0.0, 0.0], [0.0, 0.2, 0.0], 200, |p| {
                reflected(p, [0.0, 0.0, -1.0], 1.0)
            });
        // The tile sees the wall above its own plane, and the light lights it below z = 1.
        let from_wall = midpoint_quadrature(
            [T::WALL_X, -3.0, 0.0],
            [0.0, 6.0, 0.0],
            [0.0, 0.0, 1.0],
            1200,
            |p| reflected(p, [1.0, 0.0, 0.0], T::wall_radiance(p)),
        );
        assert!(
            from_wall > 5.0 * from_light,
            "the wall must be most of the lobe's light: {from_wall} and {from_light}"
        );
        let expected = from_light + from_wall;
        let ray = Ray::new(v(0.5, 0.0, 0.5), v(-0.5, 0.0, -0.5).normalize());
        let (mean, se) = TileBeforeALitWall::new().render(ray, 29, 1_000_000);
        assert!(
            (mean - expected).abs() < 4.0 * se + 5e-4 * expected,
            "rendered {mean} +- {se}, quadrature {expected} ({from_light} of it the light's)"
        );
    }

    /// The midpoint rule over the parallelogram `origin + s e1 + t e2`, s and t in [0, 1],
    /// on an `n x n` grid: the integral of `f` over its area.
    fn midpoint_quadrature(
        origin: [f64; 3],
        e1: [f64; 3],
        e2: [f64; 3],
        n: u32,
        f: impl Fn([f64; 3]) -> f64,
    ) -> f64 {
        let c = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let area = libm::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let (s, t) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                sum += f(core::array::from_fn(|k| origin[k] + s * e1[k] + t * e2[k]));
            }
        }
        sum * area / (n as f64 * n as f64)
    }

    /// A Ward plastic of diffuse colour `rho_d` and specularity `rho_s`, roughness 0.15.
    fn ward_tile(rho_d: f32, rho_s: f32) -> Material {
        Material::Ward {
            rho_d: Vec3::splat(rho_d),
            rho_s: Vec3::splat(rho_s),
            alpha: 0.15,
        }
    }

    /// A camera ray at the tile's centre, 45 degrees from the light's side: the tile's
    /// highlight is the wall.
    fn tile_at_45_degrees() -> Ray {
        Ray::new(v(0.5, 0.0, 0.5), v(-0.5, 0.0, -0.5).normalize())
    }

    /// The mean green radiance along `ray` in `parts`' scene over `n` paths drawn on
    /// `seed`, and its standard error.
    fn mean_radiance(
        parts: &TileBesideAMirror,
        ray: Ray,
        settings: &RenderSettings,
        seed: u64,
        n: u32,
    ) -> (f64, f64) {
        let mut storage = parts.storage();
        let scene = parts.scene(&mut storage);
        mean_and_standard_error((0..n).map(|k| {
            let mut sampler = Sampler::for_pixel_sample(seed, 0, k, 0);
            radiance(&scene, ray, &mut sampler, settings).y as f64
        }))
    }

    /// Light the group sends back to itself is its colour's: with the wall beside the tile
    /// made part of the tile's group (a diffuse wall now, where it was a mirror), what a
    /// path carries less its diffuse part matches a render with the group's colour black,
    /// which darkens the wall too. A split at the first vertex alone left the wall's light
    /// in the lobe's part, 38% over the black render's here.
    #[test]
    fn the_diffuse_part_holds_the_light_the_group_sends_back_to_itself() {
        let glossy = |rho_d: f32| ward_tile(rho_d, 0.3);
        let settings = RenderSettings {
            seed: 23,
            ..RenderSettings::default()
        };
        let ray = tile_at_45_degrees;
        let n = 100_000;
        let tile_and_wall = |rho_d: f32| {
            let mut parts = TileBesideAMirror::new(glossy(rho_d), false);
            for t in parts.triangles.iter_mut() {
                if t.surface == Surface::Group(1) {
                    t.surface = Surface::Group(0);
                }
            }
            parts
        };
        let parts = tile_and_wall(0.6);
        let mut storage = parts.storage();
        let scene = parts.scene(&mut storage);
        let (mut totals, mut rest) = (Vec::new(), Vec::new());
        for k in 0..n {
            let mut sampler = Sampler::for_pixel_sample(settings.seed, 0, k, 0);
            let (total, part) =
                radiance_with_diffuse_part(&scene, ray(), &mut sampler, &settings, 0);
            totals.push(total.y as f64);
            rest.push((total - part).y as f64);
        }
        let (lobe, lobe_se) =
            mean_radiance(&tile_and_wall(0.0), ray(), &settings, settings.seed + 1, n);
        let (rest, rest_se) = mean_and_standard_error(rest.into_iter());
        let (total, _) = mean_and_standard_error(totals.into_iter());
        assert!(
            lobe > 0.05 * total,
            "the lobe must be in view: {lobe} of {total}"
        );
        assert!(
            (rest - lobe).abs() < 4.0 * libm::sqrt(rest_se * rest_se + lobe_se * lobe_se),
            "the rest {rest} +- {rest_se}, the group with a black colour {lobe} +- {lobe_se}"
        );

        // What the tile's lobe reflects of the wall's colour: the light a split at the
        // first vertex alone counted in the lobe's part. It must stand well above the
        // noise, or the test above could not tell the two splits apart.
        let mut lit_wall = TileBesideAMirror::new(glossy(0.0), false);
        lit_wall.materials[1].material = glossy(0.6);
        let (with_wall, with_wall_se) =
            mean_radiance(&lit_wall, ray(), &settings, settings.seed + 2, n);
        let wall = with_wall - lobe;
        assert!(
            wall > 8.0 * libm::sqrt(with_wall_se * with_wall_se + lobe_se * lobe_se),
            "the wall's light by way of the tile's lobe {wall}, tile {total}"
        );
    }

    /// The colour gradient is each colour's derivative. The tile (glossy) beside a diffuse
    /// wall (group 1, where the mirror was): neither sees itself, so the pixel is linear in
    /// the wall's colour and nearly so in the tile's, and `d R / d ln rho` of each is the
    /// pixel less the pixel with that colour black, rendered on independent samples.
    #[test]
    fn the_colour_gradient_is_what_each_colour_adds() {
        let settings = RenderSettings {
            seed: 29,
            ..RenderSettings::default()
        };
        let ray = tile_at_45_degrees;
        let n = 100_000;
        let tile_by_a_wall = |tile: f32, wall: f32| {
            let mut parts = TileBesideAMirror::new(ward_tile(tile, 0.1), false);
            parts.materials[1].material = Material::Diffuse {
                rho_d: Vec3::splat(wall),
            };
            parts
        };
        let parts = tile_by_a_wall(0.4, 0.6);
        let mut storage = parts.storage();
        let scene = parts.scene(&mut storage);
        let mut per_group: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
        for k in 0..n {
            // Two entries: group 1 is the wall; a third would stay zero.
            let mut gradient = [Vec3::ZERO; 3];
            let mut sampler = Sampler::for_pixel_sample(settings.seed, 0, k, 0);
            let total = radiance_with_colour_gradient(
                &scene,
                ray(),
                &mut sampler,
                &settings,
                &mut gradient,
            );
            let mut again = Sampler::for_pixel_sample(settings.seed, 0, k, 0);
            let plain = radiance(&scene, ray(), &mut again, &settings);
            assert_eq!(
                total.to_array().map(f32::to_bits),
                plain.to_array().map(f32::to_bits)
            );
            assert_eq!(gradient[2], Vec3::ZERO);
            for (g, values) in per_group.iter_mut().enumerate() {
                values.push(gradient[g].y as f64);
            }
        }
        let (all, all_se) = mean_radiance(&parts, ray(), &settings, settings.seed + 1, n);
        for (g, black) in [tile_by_a_wall(0.0, 0.6), tile_by_a_wall(0.4, 0.0)]
            .iter()
            .enumerate()
        {
            let (gradient, gradient_se) =
                mean_and_standard_error(core::mem::take(&mut per_group[g]).into_iter());
            let (without, without_se) =
                mean_radiance(black, ray(), &settings, settings.seed + 2 + g as u64, n);
            let added = all - without;
            let se =
                libm::sqrt(gradient_se * gradient_se + all_se * all_se + without_se * without_se);
            assert!(
                added > 10.0 * se,
                "group {g} must add light: {added} +- {se}"
            );
            assert!(
                (gradient - added).abs() < 4.0 * se,
                "group {g}: gradient {gradient} +- {gradient_se}, what its colour adds {added} +- {se}"
            );
        }
    }

    /// A group made a mirror over storage built while it was diffuse is sampled through
    /// as a planar mirror, and renders exactly as a scene built afresh with the mirror:
    /// the groups' planes are found at build for every group, whatever its material.
    #[test]
    fn a_mirror_given_over_built_storage_renders_as_a_fresh_build() {
        let parts = TileBesideAMirror::new(diffuse(0.5)[0].material, false);
        let settings = RenderSettings {
            seed: 11,
            ..RenderSettings::default()
        };
        let tile_radiance = |scene: &Scene| -> std::vec::Vec<Vec3> {
            (0..400)
                .map(|k| {
                    let mut sampler = Sampler::for_pixel_sample(settings.seed, 0, k, 0);
                    let ray = Ray::new(v(0.0, 0.0, 0.5), v(0.01, -0.02, -1.0).normalize());
                    radiance(scene, ray, &mut sampler, &settings)
                })
                .collect()
        };
        let mut fresh_storage = parts.storage();
        let fresh = parts.scene(&mut fresh_storage);
        assert_eq!(fresh.mirror_planes().as_slice().len(), 1);
        let expected = tile_radiance(&fresh);

        let mut as_diffuse = [parts.materials[0], parts.materials[0]];
        as_diffuse[1].material = Material::Diffuse {
            rho_d: Vec3::splat(0.8),
        };
        let mut reused_storage = parts.storage();
        let as_built = reused_storage.build(&parts.triangles, &as_diffuse, &parts.light_radiance);
        assert!(as_built.mirror_planes().as_slice().is_empty());
        assert_ne!(
            tile_radiance(&as_built),
            expected,
            "the mirror must be in view"
        );
        let counts = as_built.built_counts();
        let reused = Scene::from_built(
            &parts.triangles,
            &parts.materials,
            &parts.light_radiance,
            Textures::default(),
            BuiltStorage {
                nodes: &reused_storage.nodes,
                packed: &reused_storage.packed,
                light_table: &reused_storage.lights,
                group_planes: &reused_storage.planes,
                counts,
            },
        )
        .unwrap();
        assert_eq!(
            reused.mirror_planes().as_slice(),
            fresh.mirror_planes().as_slice()
        );
        assert_eq!(tile_radiance(&reused), expected);
    }

    /// A scene given new materials over its built storage renders exactly as one built
    /// afresh with them (recovery builds the BVH once and swaps materials).
    #[test]
    fn new_materials_over_built_storage_render_as_a_fresh_build() {
        let triangles = furnace_sphere(16, 32, 25.0);
        let (first, second) = (diffuse(0.3), diffuse(0.8));
        let radiance = [Vec3::splat(2.0)];
        let settings = RenderSettings {
            seed: 5,
            ..RenderSettings::default()
        };
        // A fresh build with the second materials: the figure its own scene renders.
        let mut fresh_storage = LentStorage::new(triangles.len());
        let fresh = fresh_storage.build(&triangles, &second, &radiance);
        let expected = mean_radiance_from_centre(&fresh, 2000, &settings);
        // A build with the first, whose counts the reused storage keeps.
        let mut reused_storage = LentStorage::new(triangles.len());
        let counts = reused_storage
            .build(&triangles, &first, &radiance)
            .built_counts();
        fn over<'a>(
            triangles: &'a [Triangle],
            materials: &'a [SurfaceMaterial],
            radiance: &'a [Vec3],
            s: &'a LentStorage,
            counts: BuiltCounts,
        ) -> Result<Scene<'a>, crate::error::Error> {
            Scene::from_built(
                triangles,
                materials,
                radiance,
                Textures::default(),
                BuiltStorage {
                    nodes: &s.nodes,
                    packed: &s.packed,
                    light_table: &s.lights,
                    group_planes: &s.planes,
                    counts,
                },
            )
        }
        let reused = over(&triangles, &second, &radiance, &reused_storage, counts).unwrap();
        assert_eq!(
            mean_radiance_from_centre(&reused, 2000, &settings),
            expected
        );
        // Counts beyond the buffers are an error, not a panic.
        let too_many = BuiltStorage {
            nodes: &reused_storage.nodes,
            packed: &reused_storage.packed,
            light_table: &reused_storage.lights,
            group_planes: &reused_storage.planes,
            counts: BuiltCounts {
                nodes: reused_storage.nodes.len() + 1,
                ..counts
            },
        };
        assert!(Scene::from_built(
            &triangles,
            &second,
            &radiance,
            Textures::default(),
            too_many
        )
        .is_err());
    }
}
