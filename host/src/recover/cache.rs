//! The transport cache of one group, built in parallel: for each of its pure pixels,
//! `samples` pixel samples' incident light (`relume_core::transport`), in pixel order.

use glam::Vec3;
use rayon::prelude::*;
use relume_core::geometry::View;
use relume_core::material::{Kind, Material};
use relume_core::render::RenderSettings;
use relume_core::scene::Scene;
use relume_core::stages::isotropic::{self, LinearSums, WardFit};
use relume_core::transport::{self, IncidentSample, LobePoint, MAX_INCIDENT_PER_SAMPLE};

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
    /// The same from each half of a pixel's samples (for [`linear_sums_across_halves`]):
    /// the diffuse parts, and where pixel `i`'s second half of points starts.
    diffuse_halves: Vec<[Vec3; 2]>,
    point_half: Vec<usize>,
}

impl GroupCache {
    /// A cache of `samples` pixel samples per pixel, whose incident samples are
    /// `entries` (`samples * per_sample` per pixel, in pixel order; `per_sample` is
    /// [`transport::incident_per_sample`] of the scene traced).
    pub fn new(
        pixels: Vec<PurePixel>,
        real: Vec<Vec3>,
        entries: Vec<IncidentSample>,
        samples: u32,
        per_sample: usize,
    ) -> GroupCache {
        let per_pixel = samples as usize * per_sample;
        let of_pixel = |i: usize| &entries[i * per_pixel..(i + 1) * per_pixel];
        let diffuse = (0..pixels.len())
            .map(|i| transport::diffuse_part(of_pixel(i), samples))
            .collect();
        let first_half = (samples / 2) as usize * per_sample;
        let diffuse_halves = (0..pixels.len())
            .map(|i| {
                let (a, b) = of_pixel(i).split_at(first_half);
                [
                    transport::diffuse_part(a, samples / 2),
                    transport::diffuse_part(b, samples - samples / 2),
                ]
            })
            .collect();
        let mut lobe_points = Vec::new();
        let mut point_start = Vec::with_capacity(pixels.len() + 1);
        let mut point_half = Vec::with_capacity(pixels.len());
        for i in 0..pixels.len() {
            let (a, b) = of_pixel(i).split_at(first_half);
            point_start.push(lobe_points.len());
            lobe_points.extend(a.iter().filter_map(transport::lobe_point));
            point_half.push(lobe_points.len());
            lobe_points.extend(b.iter().filter_map(transport::lobe_point));
        }
        point_start.push(lobe_points.len());
        GroupCache {
            pixels,
            real,
            samples,
            diffuse,
            lobe_points,
            point_start,
            diffuse_halves,
            point_half,
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

    /// [`GroupCache::linear_parts`] from each half of pixel `i`'s samples, two independent
    /// estimates (`samples / 2` and the rest; the first is empty for a one-sample cache).
    pub fn linear_parts_halves(&self, i: usize, lobe: &Material) -> ([Vec3; 2], [Vec3; 2]) {
        let first = self.samples / 2;
        let halves = [
            (
                &self.lobe_points[self.point_start[i]..self.point_half[i]],
                first,
            ),
            (
                &self.lobe_points[self.point_half[i]..self.point_start[i + 1]],
                self.samples - first,
            ),
        ];
        (
            self.diffuse_halves[i],
            halves.map(|(points, n)| transport::specular_part(points, n, lobe)),
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
    let per_sample = transport::incident_per_sample(scene);
    let per_pixel = settings.spp as usize * per_sample;
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
                    let mut buf = [IncidentSample::default(); MAX_INCIDENT_PER_SAMPLE];
                    let n = transport::trace_pixel_sample(
                        scene, view, p.view, p.x, p.y, s, group, settings, &mut buf,
                    );
                    let at = s as usize * per_sample;
                    slot[at..at + n].copy_from_slice(&buf[..n]);
                }
            });
    });
    let real = pixels.iter().map(|p| real_value(real, views, p)).collect();
    GroupCache::new(pixels, real, entries, settings.spp, per_sample)
}

/// The normal-equation sums of the group's pixels for a unit specular `lobe`. Each
/// pixel's parts are evaluated in parallel, pixel by pixel; the sums run in one thread,
/// in fixed chunks of [`CHUNK`] pixels merged in order: the same sums for any thread count.
pub fn linear_sums(pool: &rayon::ThreadPool, cache: &GroupCache, lobe: &Material) -> LinearSums {
    sums_in_order(
        pool,
        cache,
        |i| cache.linear_parts(i, lobe),
        |sums, (d, b), t| sums.add(d.to_array(), b.to_array(), t),
    )
}

/// [`linear_sums`] with the squares and products taken across two independent halves of
/// each pixel's samples ([`LinearSums::add_halves`]), free of the bias the parts' sampling
/// noise puts into the plain sums (which is largest where a large group's cache holds few
/// samples per pixel), at the price of more noise of their own.
pub fn linear_sums_across_halves(
    pool: &rayon::ThreadPool,
    cache: &GroupCache,
    lobe: &Material,
) -> LinearSums {
    sums_in_order(
        pool,
        cache,
        |i| cache.linear_parts_halves(i, lobe),
        |sums, (d, b), t| {
            sums.add_halves(d.map(|v| v.to_array()), b.map(|v| v.to_array()), t);
        },
    )
}

/// [`linear_sums`] from one half of each pixel's samples (`half` 0 or 1, as
/// [`GroupCache::linear_parts_halves`] splits them): a cache of half the size, for how its
/// fit depends on its size.
pub fn linear_sums_of_half(
    pool: &rayon::ThreadPool,
    cache: &GroupCache,
    lobe: &Material,
    half: usize,
) -> LinearSums {
    sums_in_order(
        pool,
        cache,
        |i| {
            let (d, b) = cache.linear_parts_halves(i, lobe);
            (d[half], b[half])
        },
        |sums, (d, b), t| sums.add(d.to_array(), b.to_array(), t),
    )
}

/// Each pixel's parts evaluated in parallel, pixel by pixel; the sums in one thread, in
/// fixed chunks of [`CHUNK`] pixels merged in order: the same sums for any thread count.
fn sums_in_order<P: Send>(
    pool: &rayon::ThreadPool,
    cache: &GroupCache,
    parts_of: impl Fn(usize) -> P + Sync,
    add: impl Fn(&mut LinearSums, &P, [f32; 3]),
) -> LinearSums {
    let parts: Vec<P> = pool.install(|| {
        (0..cache.pixels.len())
            .into_par_iter()
            .map(&parts_of)
            .collect()
    });
    let mut total = LinearSums::default();
    for (first, chunk) in (0..parts.len()).step_by(CHUNK).zip(parts.chunks(CHUNK)) {
        let mut sums = LinearSums::default();
        for (i, part) in (first..).zip(chunk) {
            add(&mut sums, part, cache.real[i].to_array());
        }
        total.merge(&sums);
    }
    total
}

/// The best reflectances of a `kind` lobe of isotropic roughness `alpha`, in closed form
/// from the normal-equation sums `sums_for` gives for its unit lobe.
fn isotropic_fit_from(
    kind: Kind,
    alpha: f64,
    sums_for: impl FnOnce(&Material) -> LinearSums,
) -> WardFit {
    isotropic::solve(
        kind,
        &sums_for(&transport::unit_isotropic_lobe(alpha as f32)),
    )
}

/// The best reflectances of a `kind` lobe of isotropic roughness `alpha` on the group's
/// cache, in closed form.
pub fn isotropic_fit(
    pool: &rayon::ThreadPool,
    cache: &GroupCache,
    kind: Kind,
    alpha: f64,
) -> WardFit {
    isotropic_fit_from(kind, alpha, |lobe| linear_sums(pool, cache, lobe))
}

/// [`isotropic_fit`] on one half of each pixel's samples ([`linear_sums_of_half`]).
pub fn isotropic_fit_of_half(
    pool: &rayon::ThreadPool,
    cache: &GroupCache,
    kind: Kind,
    alpha: f64,
    half: usize,
) -> WardFit {
    isotropic_fit_from(kind, alpha, |lobe| {
        linear_sums_of_half(pool, cache, lobe, half)
    })
}

/// [`isotropic_fit`] from the sums across halves ([`linear_sums_across_halves`]): for a
/// roughness chosen elsewhere (by render), where the fit's own noise picks nothing.
pub fn isotropic_fit_across_halves(
    pool: &rayon::ThreadPool,
    cache: &GroupCache,
    kind: Kind,
    alpha: f64,
) -> WardFit {
    isotropic_fit_from(kind, alpha, |lobe| {
        linear_sums_across_halves(pool, cache, lobe)
    })
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::recover::pixels::PurePixel;
    use relume_core::transport::INCIDENT_PER_SAMPLE;

    /// Two pixels of `samples` samples each: every other incident direction spread widely
    /// (some below the surface, which the parts leave out), the rest near the mirror
    /// direction of `wo`, where a lobe reflects them.
    fn cache(samples: u32) -> GroupCache {
        cache_of(entries(samples), samples)
    }

    /// The incident samples of [`cache`], pixel after pixel.
    pub(crate) fn entries(samples: u32) -> Vec<IncidentSample> {
        let n = Vec3::Z;
        let wo = Vec3::new(0.3, 0.1, 1.0).normalize();
        (0..2 * samples as usize * INCIDENT_PER_SAMPLE)
            .map(|k| {
                let t = k as f32 * 0.37;
                // Every other sample near the mirror direction of `wo`, where a lobe is.
                let spread = if k % 2 == 0 { 1.0 } else { 0.15 };
                let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
                let offset = Vec3::new(libm::sinf(t), libm::cosf(1.3 * t), libm::cosf(t) - 0.1);
                IncidentSample {
                    wo,
                    n,
                    wi: (mirror * (1.0 - spread) + offset * spread).normalize(),
                    weight: Vec3::new(1.0 + (k % 3) as f32, 0.5, 0.25 * (k % 5) as f32),
                    uv: [0.0; 2],
                }
            })
            .collect()
    }

    /// The cache of two pixels whose incident samples are `entries` (`samples` per pixel).
    pub(crate) fn cache_of(entries: Vec<IncidentSample>, samples: u32) -> GroupCache {
        let pixels: Vec<PurePixel> = (0..2)
            .map(|x| PurePixel {
                view: 0,
                x,
                y: 0,
                group: 0,
            })
            .collect();
        GroupCache::new(
            pixels,
            vec![Vec3::splat(0.2); 2],
            entries,
            samples,
            INCIDENT_PER_SAMPLE,
        )
    }

    /// `entries` of `samples` per pixel with each pixel's samples repeated once: a cache
    /// whose second half of every pixel is its first.
    pub(crate) fn repeated(entries: &[IncidentSample], samples: u32) -> Vec<IncidentSample> {
        entries
            .chunks(samples as usize * INCIDENT_PER_SAMPLE)
            .flat_map(|pixel| pixel.iter().chain(pixel).copied())
            .collect()
    }

    /// A cache whose second half repeats its first: each half's sums are the whole's.
    #[test]
    fn a_half_of_a_cache_that_repeats_itself_sums_as_the_whole() {
        let twice = cache_of(repeated(&entries(4), 4), 8);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let lobe = transport::unit_isotropic_lobe(0.05);
        let whole = linear_sums(&pool, &twice, &lobe);
        assert!(whole.bb[0] > 0.0, "the lobe reflects some samples");
        for half in [0, 1] {
            let part = linear_sums_of_half(&pool, &twice, &lobe, half);
            for c in 0..3 {
                for (a, b) in [
                    (part.dd[c], whole.dd[c]),
                    (part.db[c], whole.db[c]),
                    (part.bb[c], whole.bb[c]),
                    (part.dt[c], whole.dt[c]),
                ] {
                    assert!((a - b).abs() <= 1e-6 * b.abs().max(1e-9), "{a} {b}");
                }
            }
        }
    }

    /// The halves split each pixel's samples, each counted once: their mean is the whole
    /// pixel's parts, for an even and an odd count (`samples / 2` and the rest).
    #[test]
    fn the_halves_of_a_pixel_are_its_samples_split_in_two() {
        for (samples, weights) in [(6u32, [0.5f32, 0.5]), (7, [3.0 / 7.0, 4.0 / 7.0])] {
            let cache = cache(samples);
            for alpha in [0.02f32, 0.2] {
                let lobe = transport::unit_isotropic_lobe(alpha);
                for i in 0..2 {
                    let (d, b) = cache.linear_parts(i, &lobe);
                    let (dh, bh) = cache.linear_parts_halves(i, &lobe);
                    let d_mean = dh[0] * weights[0] + dh[1] * weights[1];
                    let b_mean = bh[0] * weights[0] + bh[1] * weights[1];
                    assert!((d_mean - d).abs().max_element() < 1e-5, "{d_mean} {d}");
                    assert!((b_mean - b).abs().max_element() < 1e-5, "{b_mean} {b}");
                    assert!(dh[0] != dh[1], "the halves hold different samples");
                    assert!(b.max_element() > 0.0, "the lobe reflects some samples");
                }
            }
        }
    }
}
