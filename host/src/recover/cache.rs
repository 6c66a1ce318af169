//! The transport cache of one group, built in parallel: for each of its pure pixels,
//! `samples` pixel samples' incident light (`relume_core::transport`), in pixel order.

use glam::Vec3;
use rayon::prelude::*;
use relume_core::geometry::View;
use relume_core::material::{Kind, Material};
use relume_core::render::RenderSettings;
use relume_core::scene::Scene;
use relume_core::stages::isotropic::{self, LinearSums, WardFit};
use relume_core::transport::{self, IncidentSample, LobePoint, INCIDENT_PER_SAMPLE};

use super::pixels::{real_value, PurePixel, CHUNK};
use crate::images::Image;

/// The cached incident light of one group's pure pixels.
pub struct GroupCache {
    /// The pixels, in the order of `entries`.
    pub pixels: Vec<PurePixel>,
    /// The panorama's values of `pixels`.
    pub real: Vec<Vec3>,
    /// Pixel samples per pixel.
    pub samples: u32,
    /// What the fits' many lobes need of the traced incident samples: each pixel's
    /// diffuse part, and the samples a lobe can reflect as [`LobePoint`]s (those of pixel
    /// `i` at `point_start[i]..point_start[i + 1]`).
    diffuse: Vec<Vec3>,
    lobe_points: Vec<LobePoint>,
    point_start: Vec<usize>,
}

impl GroupCache {
    /// A cache of `samples` pixel samples per pixel, whose incident samples are
    /// `entries` (`samples * INCIDENT_PER_SAMPLE` per pixel, in pixel order).
    pub fn new(
        pixels: Vec<PurePixel>,
        real: Vec<Vec3>,
        entries: Vec<IncidentSample>,
        samples: u32,
    ) -> GroupCache {
        let per_pixel = samples as usize * INCIDENT_PER_SAMPLE;
        let of_pixel = |i: usize| &entries[i * per_pixel..(i + 1) * per_pixel];
        let diffuse = (0..pixels.len())
            .map(|i| transport::diffuse_part(of_pixel(i), samples))
            .collect();
        let mut lobe_points = Vec::new();
        let mut point_start = Vec::with_capacity(pixels.len() + 1);
        for i in 0..pixels.len() {
            point_start.push(lobe_points.len());
            lobe_points.extend(of_pixel(i).iter().filter_map(transport::lobe_point));
        }
        point_start.push(lobe_points.len());
        GroupCache {
            pixels,
            real,
            samples,
            diffuse,
            lobe_points,
            point_start,
        }
    }

    /// Pixel `i`'s linear parts under the specular `lobe`, as [`transport::linear_parts`]
    /// gives them (the same bits), from what the cache keeps for the fits' many lobes.
    pub fn linear_parts(&self, i: usize, lobe: &Material) -> (Vec3, Vec3) {
        let points = &self.lobe_points[self.point_start[i]..self.point_start[i + 1]];
        (
            self.diffuse[i],
            transport::specular_part(points, self.samples, lobe),
        )
    }
}

/// Traces the cache of `group` (its pure pixels among `pure`).
pub fn build(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    views: &[View],
    pure: &[PurePixel],
    real: &[Image],
    group: u16,
    settings: &RenderSettings,
) -> GroupCache {
    let pixels: Vec<PurePixel> = pure.iter().copied().filter(|p| p.group == group).collect();
    let per_pixel = settings.spp as usize * INCIDENT_PER_SAMPLE;
    let mut entries = vec![IncidentSample::default(); pixels.len() * per_pixel];
    pool.install(|| {
        // Pixel by pixel: each writes its own slot, so the split changes only the balance
        // between threads (a small group is a handful of pixels at many samples each).
        entries
            .par_chunks_mut(per_pixel)
            .zip(pixels.par_iter())
            .for_each(|(slot, p)| {
                let view = &views[p.view as usize];
                for s in 0..settings.spp {
                    let mut buf = [IncidentSample::default(); INCIDENT_PER_SAMPLE];
                    let n = transport::trace_pixel_sample(
                        scene, view, p.view, p.x, p.y, s, group, settings, &mut buf,
                    );
                    let at = s as usize * INCIDENT_PER_SAMPLE;
                    slot[at..at + n].copy_from_slice(&buf[..n]);
                }
            });
    });
    let real = pixels.iter().map(|p| real_value(real, views, p)).collect();
    GroupCache::new(pixels, real, entries, settings.spp)
}

/// The normal-equation sums of the group's pixels for a unit specular `lobe`. Each
/// pixel's parts are evaluated in parallel, pixel by pixel; the sums run in one thread,
/// in fixed chunks of [`CHUNK`] pixels merged in order: the same sums for any thread count.
pub fn linear_sums(pool: &rayon::ThreadPool, cache: &GroupCache, lobe: &Material) -> LinearSums {
    let parts: Vec<(Vec3, Vec3)> = pool.install(|| {
        (0..cache.pixels.len())
            .into_par_iter()
            .map(|i| cache.linear_parts(i, lobe))
            .collect()
    });
    let mut total = LinearSums::default();
    for (first, chunk) in (0..parts.len()).step_by(CHUNK).zip(parts.chunks(CHUNK)) {
        let mut sums = LinearSums::default();
        for (i, (d, b)) in (first..).zip(chunk) {
            sums.add(d.to_array(), b.to_array(), cache.real[i].to_array());
        }
        total.merge(&sums);
    }
    total
}

/// The best reflectances of a `kind` lobe of isotropic roughness `alpha` on the group's
/// cache, in closed form.
pub fn isotropic_fit(
    pool: &rayon::ThreadPool,
    cache: &GroupCache,
    kind: Kind,
    alpha: f64,
) -> WardFit {
    let lobe = Material::Ward {
        rho_d: Vec3::ZERO,
        rho_s: Vec3::ONE,
        alpha: alpha as f32,
    };
    isotropic::solve(kind, &linear_sums(pool, cache, &lobe))
}
