//! The pixels recovery works on: each group's pure pixels (whole footprint on the group),
//! and their evaluation against the panorama, in a fixed partition so that the sums do not
//! depend on the thread count.

use std::collections::HashSet;

use glam::Vec3;
use rayon::prelude::*;
use relume_core::bvh::Hit;
use relume_core::fit::GroupFit;
use relume_core::geometry::{Surface, Triangle, View};
use relume_core::render::{self, RenderSettings};
use relume_core::scene::Scene;
use relume_core::stages::texture_map::{FOOTPRINT_OFFSETS, FOOTPRINT_SAMPLES};

use crate::compare::LABEL_RAYS_PER_SIDE;
use crate::images::Image;
use crate::parallel;

/// Pixels per unit of parallel work (fixed: it decides the order of float sums).
pub const CHUNK: usize = 256;

/// A pixel whose whole footprint sees one group.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PurePixel {
    pub view: u32,
    pub x: u32,
    pub y: u32,
    pub group: u16,
}

/// Keeps `limit` of `count` items met one by one, evenly over their order: item `seen`
/// when it crosses the next multiple of `count / limit` (the first item always); all of
/// them when `count <= limit`.
#[derive(Clone, Copy)]
struct EvenPick {
    count: usize,
    limit: usize,
    seen: usize,
    kept: usize,
}

impl EvenPick {
    fn new(count: usize, limit: usize) -> Self {
        EvenPick {
            count,
            limit: limit.min(count),
            seen: 0,
            kept: 0,
        }
    }

    /// Whether the next item is kept.
    fn next(&mut self) -> bool {
        let keep = self.kept < self.limit && self.seen * self.limit >= self.kept * self.count;
        self.seen += 1;
        self.kept += keep as usize;
        keep
    }
}

/// `pure` with group `g` thinned to at most `limit` pixels, evenly over its pixel order
/// (the other groups untouched).
pub fn limit_group(pure: Vec<PurePixel>, g: u16, limit: usize) -> Vec<PurePixel> {
    let count = pure.iter().filter(|p| p.group == g).count();
    if count <= limit {
        return pure;
    }
    let mut pick = EvenPick::new(count, limit);
    pure.into_iter()
        .filter(|p| p.group != g || pick.next())
        .collect()
}

/// At most `limit` pure pixels of each group, evenly over the group's pixel order (views,
/// then rows, then columns), so spread over every view and row in proportion to the
/// group's pixels there; a group of `limit` pixels or fewer is kept whole. The pixels keep
/// their order in `pure`, so when no group is larger than `limit` the result is `pure`
/// itself and every sum over it has the same bits. Deterministic: no seed.
pub fn spread_subset(pure: &[PurePixel], n_groups: usize, limit: usize) -> Vec<PurePixel> {
    let mut picks: Vec<EvenPick> = group_counts(pure, n_groups)
        .into_iter()
        .map(|count| EvenPick::new(count as usize, limit))
        .collect();
    pure.iter()
        .filter(|p| picks[p.group as usize].next())
        .copied()
        .collect()
}

/// The pixels of at most `limit` of the `tile` x `tile` tiles that `pixels` fall in,
/// whole tiles kept evenly over their order (view, tile row, tile column), the pixels in
/// their order; and the share of the tiles kept (1 when they are no more than `limit`,
/// and then the pixels are `pixels` itself). For an estimate that clusters by tile: a
/// sum over the kept tiles over the share estimates the sum over all of them.
pub fn whole_tiles(pixels: Vec<PurePixel>, tile: u32, limit: usize) -> (Vec<PurePixel>, f64) {
    let key = |p: &PurePixel| (p.view, p.y / tile, p.x / tile);
    let tiles: std::collections::BTreeSet<(u32, u32, u32)> = pixels.iter().map(key).collect();
    if tiles.len() <= limit {
        return (pixels, 1.0);
    }
    let mut pick = EvenPick::new(tiles.len(), limit);
    let kept: std::collections::BTreeSet<(u32, u32, u32)> =
        tiles.iter().copied().filter(|_| pick.next()).collect();
    let share = kept.len() as f64 / tiles.len() as f64;
    let pixels = pixels
        .into_iter()
        .filter(|p| kept.contains(&key(p)))
        .collect();
    (pixels, share)
}

/// Every k-th of `pixels`, from the first, with k the smallest stride that leaves at most
/// `at_most` (all of them when they are no more).
pub fn every_kth(pixels: Vec<PurePixel>, at_most: usize) -> Vec<PurePixel> {
    let stride = pixels.len().div_ceil(at_most.max(1)).max(1);
    pixels.into_iter().step_by(stride).collect()
}

/// A pixel whose whole footprint, and the footprints of its four neighbours, see the
/// emitting side of one light: its value is the light's radiance, untouched by the blur of
/// a camera or a filter at the light's edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LightPixel {
    pub view: u32,
    pub x: u32,
    pub y: u32,
    pub light: u16,
}

/// What the label pass over every view finds.
pub struct Labels {
    /// Every pure pixel of every view, in view and row order.
    pub pure: Vec<PurePixel>,
    /// Every light pixel (interior to a light), in view and row order.
    pub lights: Vec<LightPixel>,
    /// Pixels wholly on a light's emitting side but beside its edge (a neighbour is not):
    /// not read, since blur at the edge may reach them, but told of where no pixel is
    /// interior ([`super::calibration::unchecked_warning`]).
    pub light_edges: Vec<LightPixel>,
    /// Every pixel interior to a light's back (black as declared), in view and row order.
    pub light_backs: Vec<LightPixel>,
    /// The views with no pure pixel.
    pub empty_views: Vec<usize>,
}

/// Labels every pixel of every view by what its whole footprint sees.
pub fn label_views(pool: &rayon::ThreadPool, scene: &Scene, views: &[View]) -> Labels {
    let mut found = Labels {
        pure: Vec::new(),
        lights: Vec::new(),
        light_edges: Vec::new(),
        light_backs: Vec::new(),
        empty_views: Vec::new(),
    };
    for (vi, view) in views.iter().enumerate() {
        let labels = parallel::map_pixels(pool, view, |x, y| {
            render::pixel_surface(scene, view, x, y, LABEL_RAYS_PER_SIDE)
        });
        let (w, h) = (view.width, view.height);
        let label = |x: u32, y: u32| labels[(y * w + x) as usize];
        // Whether the four neighbours of (x, y) are in the view and all see `surface`.
        let neighbours_see = |x: u32, y: u32, surface: Surface| {
            x > 0
                && y > 0
                && x + 1 < w
                && y + 1 < h
                && [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)]
                    .iter()
                    .all(|&(nx, ny)| label(nx, ny) == Some(surface))
        };
        // Light backs among the pixels of no surface (few: silhouettes, the sky), held to
        // the same interior as light pixels.
        let backs = parallel::map_pixels(pool, view, |x, y| match label(x, y) {
            None => render::pixel_light_back(scene, view, x, y, LABEL_RAYS_PER_SIDE),
            Some(_) => None,
        });
        let back = |x: u32, y: u32| backs[(y * w + x) as usize];
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                if let Some(light) = back(x, y) {
                    let around = [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)];
                    if around.iter().all(|&(nx, ny)| back(nx, ny) == Some(light)) {
                        found.light_backs.push(LightPixel {
                            view: vi as u32,
                            x,
                            y,
                            light,
                        });
                    }
                }
            }
        }
        let before = found.pure.len();
        for y in 0..h {
            for x in 0..w {
                match label(x, y) {
                    Some(Surface::Group(group)) => found.pure.push(PurePixel {
                        view: vi as u32,
                        x,
                        y,
                        group,
                    }),
                    Some(Surface::Light(light)) => {
                        let pixel = LightPixel {
                            view: vi as u32,
                            x,
                            y,
                            light,
                        };
                        match neighbours_see(x, y, Surface::Light(light)) {
                            true => found.lights.push(pixel),
                            false => found.light_edges.push(pixel),
                        }
                    }
                    _ => {}
                }
            }
        }
        if found.pure.len() == before {
            found.empty_views.push(vi);
        }
    }
    found
}

/// What a view's pixels see, each pixel counted once by the rays that label it: told to a
/// user whose views hold no pure pixel, so the cause (views outside the geometry, an OBJ
/// in other units, groups hidden, views too coarse) can be told from the counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sight {
    /// Pixels whose every ray escapes the scene.
    pub nothing: u32,
    /// Pixels whose rays meet lights (or escape) and no group.
    pub lights_only: u32,
    /// Pixels with a group in part of their footprint.
    pub groups_in_part: u32,
}

impl Sight {
    /// "8x8 pixels: 64 see nothing, 0 only lights, 0 a group in part".
    pub fn describe(&self, view: &View) -> String {
        format!(
            "{}x{} pixels: {} see nothing, {} only lights, {} a group in part",
            view.width, view.height, self.nothing, self.lights_only, self.groups_in_part
        )
    }
}

/// Counts what the pixels of `view` see (see [`Sight`]).
pub fn sight(pool: &rayon::ThreadPool, scene: &Scene, view: &View) -> Sight {
    let seen = parallel::map_pixels(pool, view, |x, y| {
        let (mut light, mut group) = (false, false);
        for surface in label_ray_surfaces(scene, view, x, y) {
            match surface {
                Some(Surface::Group(_)) => group = true,
                Some(Surface::Light(_)) => light = true,
                None => {}
            }
        }
        (light, group)
    });
    let mut sight = Sight::default();
    for (light, group) in seen {
        match (light, group) {
            (_, true) => sight.groups_in_part += 1,
            (true, false) => sight.lights_only += 1,
            (false, false) => sight.nothing += 1,
        }
    }
    sight
}

/// Per group for which `wanted` is true, the pixels of every view whose footprint sees it
/// in part, in at least `min_share` of the [`LABEL_RAYS_PER_SIDE`]^2 rays that label a pixel (a grid
/// over the pixel's square, edges included, as `render::pixel_surface`'s), and sees in the
/// others only groups that `known` accepts: no light, no void, no group whose material is
/// not known. Each with the group's share of the rays. In view and row order.
pub fn mixed_pixels(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    views: &[View],
    n_groups: usize,
    min_share: f64,
    wanted: impl Fn(u16) -> bool + Sync,
    known: impl Fn(u16) -> bool + Sync,
) -> Vec<Vec<(PurePixel, f64)>> {
    let mut found = vec![Vec::new(); n_groups];
    for (vi, view) in views.iter().enumerate() {
        let shares = parallel::map_pixels(pool, view, |x, y| {
            let mut on: Option<(u16, u32)> = None;
            let mut rays = 0;
            for surface in label_ray_surfaces(scene, view, x, y) {
                rays += 1;
                match surface {
                    Some(Surface::Group(h)) if wanted(h) => match on {
                        None => on = Some((h, 1)),
                        Some((g, count)) if g == h => on = Some((g, count + 1)),
                        // Two groups of unknown material: neither can be told apart.
                        Some(_) => return None,
                    },
                    Some(Surface::Group(h)) if known(h) => {}
                    _ => return None,
                }
            }
            let (g, count) = on?;
            let share = count as f64 / rays as f64;
            // A pixel it covers whole is a pure pixel, left out of the recovery's on
            // purpose where there are any (`--limit-group-pixels`).
            (share >= min_share && count < rays).then_some((g, share))
        });
        for (i, share) in shares.into_iter().enumerate() {
            if let Some((g, share)) = share {
                let pixel = PurePixel {
                    view: vi as u32,
                    x: i as u32 % view.width,
                    y: i as u32 / view.width,
                    group: g,
                };
                found[g as usize].push((pixel, share));
            }
        }
    }
    found
}

/// The pure pixels of group `g`, in their order.
pub fn of_group(pure: &[PurePixel], g: usize) -> Vec<PurePixel> {
    pure.iter()
        .filter(|p| p.group as usize == g)
        .copied()
        .collect()
}

/// The number of pure pixels of each of `n_groups` groups.
pub fn group_counts(pure: &[PurePixel], n_groups: usize) -> Vec<u32> {
    let mut counts = vec![0u32; n_groups];
    for p in pure {
        counts[p.group as usize] += 1;
    }
    counts
}

/// `f` of each of `pixels`, in order, in parallel (each pixel's value is its own: the
/// same values for any thread count and any split). Split finely: a small group at many
/// samples per pixel is a handful of costly pixels, which chunks of [`CHUNK`] would leave
/// to one thread.
fn map_in_order<T: Send>(
    pool: &rayon::ThreadPool,
    pixels: &[PurePixel],
    f: impl Fn(&PurePixel) -> T + Sync,
) -> Vec<T> {
    pool.install(|| pixels.par_iter().map(&f).collect())
}

/// The panorama's value at a pure pixel.
pub fn real_value(real: &[Image], views: &[View], p: &PurePixel) -> Vec3 {
    let view = &views[p.view as usize];
    Vec3::from(real[p.view as usize].pixels[(p.y * view.width + p.x) as usize])
}

/// What the panorama shows: its views, their images, and the pixels that see one group.
#[derive(Clone, Copy)]
pub struct Observed<'a> {
    pub views: &'a [View],
    pub real: &'a [Image],
    pub pure: &'a [PurePixel],
}

/// Renders the pure pixels (full global illumination) and compares them with the panorama,
/// group by group. Only pixels of groups for which `wanted` is true are rendered.
pub fn evaluate(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    observed: Observed,
    settings: &RenderSettings,
    n_groups: usize,
    wanted: &(dyn Fn(u16) -> bool + Sync),
) -> Vec<GroupFit> {
    let Observed { views, real, pure } = observed;
    sum_by_group(
        pool,
        pure,
        n_groups,
        wanted,
        |p| {
            let view = &views[p.view as usize];
            let (value, variance) =
                render::render_pixel_with_variance(scene, view, p.view, p.x, p.y, settings);
            (real_value(real, views, p), value, variance)
        },
        |(t, value, variance), fit: &mut GroupFit| fit.add(t, value, variance),
    )
}

/// Like [`evaluate`], the same fits to the bit, and beside them the fits of the part of
/// each pixel's radiance that does not come by way of its group's diffuse lobe, from the
/// same samples (the radiance less that diffuse part,
/// [`render::render_pixel_with_diffuse_part`]): what the lobe reflects there.
pub fn evaluate_with_lobe_part(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    observed: Observed,
    settings: &RenderSettings,
    n_groups: usize,
    wanted: &(dyn Fn(u16) -> bool + Sync),
) -> (Vec<GroupFit>, Vec<GroupFit>) {
    let Observed { views, real, pure } = observed;
    let both = sum_by_group(
        pool,
        pure,
        n_groups,
        wanted,
        |p| {
            let view = &views[p.view as usize];
            let (value, variance, diffuse) = render::render_pixel_with_diffuse_part(
                scene, view, p.view, p.x, p.y, settings, p.group,
            );
            (real_value(real, views, p), value, variance, value - diffuse)
        },
        |(t, value, variance, lobe), fit: &mut (GroupFit, GroupFit)| {
            fit.0.add(t, value, variance);
            fit.1.add(t, lobe, Vec3::ZERO);
        },
    );
    both.into_iter().unzip()
}

/// A group's fit (its render without variance) and, per group `h`, the sum over its
/// pixels of the derivative of the rendered value with respect to `ln rho_h`, the log of
/// `h`'s diffuse colour ([`evaluate_with_colour_gradients`]).
#[derive(Clone, Debug, Default)]
pub struct GradientFit {
    pub fit: GroupFit,
    /// Per group `h`, per channel; empty for a group with no pixel.
    pub gradient: Vec<[f64; 3]>,
}

impl GradientFit {
    fn add_gradient(&mut self, gradient: &[[f64; 3]]) {
        if self.gradient.len() < gradient.len() {
            self.gradient.resize(gradient.len(), [0.0; 3]);
        }
        for (sum, d) in self.gradient.iter_mut().zip(gradient) {
            for c in 0..3 {
                sum[c] += d[c];
            }
        }
    }
}

/// Renders the pure pixels of the groups `wanted` once, each with the derivative of its
/// value with respect to every group's log colour from the same samples
/// ([`render::render_pixel_with_colour_gradient`]), and sums both by group: how each
/// group's render responds to each colour, where a render per colour took finite
/// differences.
pub fn evaluate_with_colour_gradients(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    observed: Observed,
    settings: &RenderSettings,
    n_groups: usize,
    wanted: &(dyn Fn(u16) -> bool + Sync),
) -> Vec<GradientFit> {
    let Observed { views, real, pure } = observed;
    sum_by_group(
        pool,
        pure,
        n_groups,
        wanted,
        |p| {
            let view = &views[p.view as usize];
            let mut gradient = vec![Vec3::ZERO; n_groups];
            let value = render::render_pixel_with_colour_gradient(
                scene,
                view,
                p.view,
                p.x,
                p.y,
                settings,
                &mut gradient,
            );
            let gradient: Vec<[f64; 3]> = gradient
                .iter()
                .map(|d| d.to_array().map(f64::from))
                .collect();
            (real_value(real, views, p), value, gradient)
        },
        |(t, value, gradient), fit: &mut GradientFit| {
            fit.fit.add(t, value, Vec3::ZERO);
            fit.add_gradient(&gradient);
        },
    )
}

/// A group's sums, which [`sum_by_group`] adds up part by part in a fixed order.
trait Sums: Default + Clone {
    fn merge(&mut self, other: &Self);
}

impl Sums for GroupFit {
    fn merge(&mut self, other: &Self) {
        GroupFit::merge(self, other);
    }
}

impl Sums for GradientFit {
    fn merge(&mut self, other: &Self) {
        self.fit.merge(&other.fit);
        self.add_gradient(&other.gradient);
    }
}

/// A render's fit and its lobe part's ([`evaluate_with_lobe_part`]).
impl Sums for (GroupFit, GroupFit) {
    fn merge(&mut self, other: &Self) {
        self.0.merge(&other.0);
        self.1.merge(&other.1);
    }
}

/// Sums `add(measure(pixel), fit of its group)` over the pure pixels of the groups
/// `wanted`. The measures (the renders) run in parallel, split finely (see
/// [`map_in_order`]); the sums then run in one thread, in fixed chunks of [`CHUNK`] pixels
/// of `pure` merged in order: the same sums for any thread count.
fn sum_by_group<M: Send, F: Sums>(
    pool: &rayon::ThreadPool,
    pure: &[PurePixel],
    n_groups: usize,
    wanted: &(dyn Fn(u16) -> bool + Sync),
    measure: impl Fn(&PurePixel) -> M + Sync,
    add: impl Fn(M, &mut F),
) -> Vec<F> {
    let chosen: Vec<PurePixel> = pure.iter().filter(|p| wanted(p.group)).copied().collect();
    let mut measures = map_in_order(pool, &chosen, measure).into_iter();
    let mut total = vec![F::default(); n_groups];
    for chunk in pure.chunks(CHUNK) {
        let mut fits = vec![F::default(); n_groups];
        for p in chunk.iter().filter(|p| wanted(p.group)) {
            // One measure per chosen pixel, in the same order.
            if let Some(m) = measures.next() {
                add(m, &mut fits[p.group as usize]);
            }
        }
        for (t, part) in total.iter_mut().zip(&fits) {
            t.merge(part);
        }
    }
    total
}

/// Like [`evaluate`], but with an error that noise cannot lower or raise:
/// each pixel is rendered twice with independent samples (`spp / 2` each) and
/// `sum_sq_diff` holds `sum (A - T) . (B - T)`, whose expectation is the squared bias alone
/// (the two renders' noises are independent). `sum_rendered` is the mean of both renders;
/// `sum_render_variance` is zero. The search compares models on it: a noisy model (a sharp
/// lobe) is neither rewarded, as a subtracted variance estimate would, nor punished.
pub fn evaluate_cross(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    observed: Observed,
    settings: &RenderSettings,
    n_groups: usize,
    wanted: &(dyn Fn(u16) -> bool + Sync),
) -> Vec<GroupFit> {
    let Observed { views, real, pure } = observed;
    let (a, b) = cross_settings(settings);
    let measure = |p: &PurePixel| {
        let view = &views[p.view as usize];
        let ra = render::render_pixel(scene, view, p.view, p.x, p.y, &a);
        let rb = render::render_pixel(scene, view, p.view, p.x, p.y, &b);
        (real_value(real, views, p), ra, rb)
    };
    sum_by_group(pool, pure, n_groups, wanted, measure, |(t, ra, rb), fit| {
        add_cross(fit, t, ra, rb)
    })
}

/// Adds one pixel to a bias-only fit: the panorama's value `t` and two renders of it with
/// independent samples.
fn add_cross(fit: &mut GroupFit, t: Vec3, ra: Vec3, rb: Vec3) {
    fit.pixels += 1;
    for c in 0..3 {
        fit.sum_real[c] += t[c] as f64;
        fit.sum_rendered[c] += 0.5 * (ra[c] as f64 + rb[c] as f64);
    }
    fit.sum_sq_diff += (ra - t).dot(rb - t) as f64;
    fit.sum_sq_real += t.dot(t) as f64;
}

/// Each group's bias-only fit (as [`evaluate_cross`]'s) from two whole renders of every
/// view with independent samples (`halves[h][view][pixel]`), over its pure pixels in
/// order: the same sums for any thread count.
pub fn fits_of_halves(
    observed: Observed,
    halves: [&[Vec<Vec3>]; 2],
    n_groups: usize,
) -> Vec<GroupFit> {
    let Observed { views, real, pure } = observed;
    let mut fits = vec![GroupFit::default(); n_groups];
    for p in pure {
        let i = (p.y * views[p.view as usize].width + p.x) as usize;
        let [ra, rb] = halves.map(|h| h[p.view as usize][i]);
        let t = real_value(real, views, p);
        add_cross(&mut fits[p.group as usize], t, ra, rb);
    }
    fits
}

/// Per pixel of `pixels`, in order: two independent measurements of the bias-only squared
/// error, `(A - T) . (B - T)` from four quarter-renders (1, 2 and 3, 4; see
/// `relume_core::fit::ModelComparison`), and `|T|^2`. The same seeds for every model, and a
/// fixed partition: the same values for any thread count.
pub fn paired_cross_terms(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    observed: Observed,
    pixels: &[PurePixel],
    settings: &RenderSettings,
) -> Vec<([f64; 2], f64)> {
    let Observed { views, real, .. } = observed;
    // Four independent quarter-renders: the two halves of `cross_settings`, each split
    // again on a seed of its own.
    let (half_a, half_b) = cross_settings(settings);
    let quarter = |half: &RenderSettings, key: u64| {
        let (first, _) = cross_settings(half);
        let second = RenderSettings {
            seed: half.seed ^ key,
            ..first
        };
        (first, second)
    };
    let (a1, a2) = quarter(&half_a, 0x0A0A_5EED);
    let (b1, b2) = quarter(&half_b, 0x0B0B_5EED);
    map_in_order(pool, pixels, |p| {
        let view = &views[p.view as usize];
        let t = real_value(real, views, p);
        let render = |s: &RenderSettings| render::render_pixel(scene, view, p.view, p.x, p.y, s);
        let cross =
            |s: &RenderSettings, u: &RenderSettings| (render(s) - t).dot(render(u) - t) as f64;
        ([cross(&a1, &a2), cross(&b1, &b2)], t.dot(t) as f64)
    })
}

/// The settings of the two independent half-renders that bias-only statistics compare:
/// `spp / 2` samples each, on `settings.seed` and on a seed derived from it.
pub fn cross_settings(settings: &RenderSettings) -> (RenderSettings, RenderSettings) {
    let half = |seed: u64| RenderSettings {
        spp: (settings.spp / 2).max(1),
        seed,
        ..*settings
    };
    (half(settings.seed), half(settings.seed ^ 0xC055_C055))
}

/// The rendered value of each of `pixels`, in order (a fixed partition: the same bytes
/// for any thread count).
pub fn render_pixels(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    views: &[View],
    pixels: &[PurePixel],
    settings: &RenderSettings,
) -> Vec<Vec3> {
    map_in_order(pool, pixels, |p| {
        let view = &views[p.view as usize];
        render::render_pixel(scene, view, p.view, p.x, p.y, settings)
    })
}

/// Each of `pixels`, in order, rendered as [`render_pixels`] renders it (the same bits),
/// and beside it the part of its radiance that comes by way of group `g`'s diffuse lobe
/// ([`render::render_pixel_with_diffuse_part`]): what scales with `g`'s colour, where the
/// pixel sees `g` (on `g`'s border, the share of the footprint `g` covers) and where it
/// sees what `g` lights.
pub fn render_pixels_with_diffuse_part(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    views: &[View],
    pixels: &[PurePixel],
    settings: &RenderSettings,
    g: u16,
) -> Vec<(Vec3, Vec3)> {
    map_in_order(pool, pixels, |p| {
        let view = &views[p.view as usize];
        let (value, _, diffuse) =
            render::render_pixel_with_diffuse_part(scene, view, p.view, p.x, p.y, settings, g);
        (value, diffuse)
    })
}

/// The texture coordinates where the rays through pixel `p` at its footprint samples
/// (`texture_map::FOOTPRINT_OFFSETS`) hit.
pub fn pixel_uvs(
    scene: &Scene,
    views: &[View],
    p: &PurePixel,
) -> Option<[glam::Vec2; FOOTPRINT_SAMPLES]> {
    let mut uvs = [glam::Vec2::ZERO; FOOTPRINT_SAMPLES];
    for (uv, [dx, dy]) in uvs.iter_mut().zip(FOOTPRINT_OFFSETS) {
        let (hit, triangle) = first_hit(
            scene,
            &views[p.view as usize],
            p.x as f32 + dx,
            p.y as f32 + dy,
        )?;
        *uv = triangle.uv_at(hit.b1, hit.b2);
    }
    Some(uvs)
}

/// What each of the [`LABEL_RAYS_PER_SIDE`]^2 rays that label pixel `(x, y)` of `view`
/// meets first: the grid over the pixel's square, edges included, of
/// `render::pixel_surface`.
fn label_ray_surfaces<'s>(
    scene: &'s Scene,
    view: &'s View,
    x: u32,
    y: u32,
) -> impl Iterator<Item = Option<Surface>> + 's {
    let n = LABEL_RAYS_PER_SIDE.max(2);
    let sub = move |k: u32| k as f32 / (n - 1) as f32;
    (0..n * n).map(move |k| {
        first_hit(scene, view, x as f32 + sub(k % n), y as f32 + sub(k / n)).map(|(_, t)| t.surface)
    })
}

/// What the ray through the point `(x, y)` of `view` (in pixels) meets first.
fn first_hit<'s>(scene: &'s Scene, view: &View, x: f32, y: f32) -> Option<(Hit, &'s Triangle)> {
    let hit = scene.intersect(&view.ray(x, y), f32::INFINITY)?;
    Some((hit, scene.triangles.get(hit.triangle as usize)?))
}

/// The pixels around `pure` (group `g`'s pure pixels) that see the group over part of
/// their footprint, each with the texture coordinates of its footprint samples: a sample
/// that misses the group takes the coordinates of one that hits it, so that the mean over
/// the samples is the mean over those on the group. Pixels with fewer than `min_on` of
/// the [`FOOTPRINT_SAMPLES`] on the group are left out, and so are those where any of
/// the [`LABEL_RAYS_PER_SIDE`]^2 rays that labelled the pixel meets neither the group nor
/// a group that `known` accepts: the rest of such a pixel is rendered under the materials
/// recovery has, and a light, the void or a group it could not recover (no pure pixel)
/// would put a radiance it does not know into the map. A pixel whose rays all meet the
/// group is not a border pixel. In the order of `pure`'s neighbours, each pixel once.
pub fn border_pixels(
    scene: &Scene,
    views: &[View],
    pure: &[PurePixel],
    g: u16,
    min_on: usize,
    known: impl Fn(u16) -> bool,
) -> Vec<(PurePixel, [glam::Vec2; FOOTPRINT_SAMPLES])> {
    let of_group: HashSet<(u32, u32, u32)> = pure.iter().map(|p| (p.view, p.x, p.y)).collect();
    let mut tried = HashSet::new();
    let mut found = Vec::new();
    for p in pure {
        let view = &views[p.view as usize];
        let neighbours = (-1i64..=1).flat_map(|dy| (-1i64..=1).map(move |dx| (dx, dy)));
        for (dx, dy) in neighbours {
            let (x, y) = (i64::from(p.x) + dx, i64::from(p.y) + dy);
            if x < 0 || y < 0 || x >= i64::from(view.width) || y >= i64::from(view.height) {
                continue;
            }
            let (x, y) = (x as u32, y as u32);
            if of_group.contains(&(p.view, x, y)) || !tried.insert((p.view, x, y)) {
                continue;
            }
            // The rays that decided that the pixel is not pure.
            let surfaces: Vec<Option<Surface>> = label_ray_surfaces(scene, view, x, y).collect();
            let all_known = surfaces
                .iter()
                .all(|s| matches!(s, Some(Surface::Group(h)) if *h == g || known(*h)));
            // A pixel all on the group is one `pure` left out on purpose (a subset, as
            // the stability study's cut groups are), not a border.
            let on_border = surfaces.iter().any(|s| *s != Some(Surface::Group(g)));
            if !(all_known && on_border) {
                continue;
            }
            let mut uvs = [None; FOOTPRINT_SAMPLES];
            for (uv, [ox, oy]) in uvs.iter_mut().zip(FOOTPRINT_OFFSETS) {
                let on = first_hit(scene, view, x as f32 + ox, y as f32 + oy)
                    .filter(|(_, t)| t.surface == Surface::Group(g));
                *uv = on.map(|(hit, t)| t.uv_at(hit.b1, hit.b2));
            }
            let on: Vec<glam::Vec2> = uvs.iter().flatten().copied().collect();
            if on.len() < min_on.max(1) {
                continue;
            }
            let border = PurePixel {
                view: p.view,
                x,
                y,
                group: g,
            };
            let uvs = std::array::from_fn(|k| uvs[k].unwrap_or(on[k % on.len()]));
            found.push((border, uvs));
        }
    }
    found
}

/// Pairs of indices into `pixels` (one group's pure pixels) that are `step` apart along a
/// row or a column of one view.
pub fn step_pairs(views: &[View], pixels: &[PurePixel], step: u32) -> Vec<(usize, usize)> {
    let mut index = std::collections::HashMap::with_capacity(pixels.len());
    for (i, p) in pixels.iter().enumerate() {
        index.insert((p.view, p.x, p.y), i);
    }
    let mut pairs = Vec::new();
    for (i, p) in pixels.iter().enumerate() {
        let view = &views[p.view as usize];
        let right = (p.x + step < view.width).then(|| (p.view, p.x + step, p.y));
        let down = (p.y + step < view.height).then(|| (p.view, p.x, p.y + step));
        for key in [right, down].into_iter().flatten() {
            if let Some(&j) = index.get(&key) {
                pairs.push((i, j));
            }
        }
    }
    pairs
}

/// For stage 3 (texture detection): per group, `|D(p) - D(q)|` for every pair of the
/// group's pure pixels `step` apart along a row or a column of one view, where `D(p)` is
/// `difference(real(p), rendered(p))` (see `relume_core::stages::texture`).
pub fn step_differences(
    observed: Observed,
    renders: &[Vec<Vec3>],
    n_groups: usize,
    step: u32,
    difference: impl Fn(Vec3, Vec3) -> f32,
) -> Vec<Vec<f32>> {
    let Observed { views, real, pure } = observed;
    let mut out = vec![Vec::new(); n_groups];
    for (vi, view) in views.iter().enumerate() {
        let (w, h) = (view.width, view.height);
        // The group of each pure pixel of this view, and its difference D.
        let mut label = vec![None; (w * h) as usize];
        for p in pure.iter().filter(|p| p.view as usize == vi) {
            label[(p.y * w + p.x) as usize] = Some(p.group);
        }
        let d = |i: usize| difference(Vec3::from(real[vi].pixels[i]), renders[vi][i]);
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                let Some(g) = label[i] else { continue };
                let right = (x + step < w).then(|| i + step as usize);
                let down = (y + step < h).then(|| i + (step * w) as usize);
                for j in [right, down].into_iter().flatten() {
                    if label[j] == Some(g) {
                        out[g as usize].push((d(i) - d(j)).abs());
                    }
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whole tiles or none: every tile kept holds all its pixels, the tiles are spread
    /// over the views and rows, the share is the tiles' (not the pixels'), and a group in
    /// no more tiles than the limit is kept as it is.
    #[test]
    fn a_group_in_many_tiles_keeps_whole_tiles_spread_evenly() {
        // Two views of 16 x 8 pixels, tiles of 4: 4 x 2 tiles each, 16 in all; the last
        // column of view 1 left out, so its right tiles hold 12 pixels.
        let pixels: Vec<PurePixel> = (0..2)
            .flat_map(|view| {
                (0..8).flat_map(move |y| {
                    (0..16)
                        .filter(move |&x| !(view == 1 && x == 15))
                        .map(move |x| PurePixel {
                            view,
                            x,
                            y,
                            group: 3,
                        })
                })
            })
            .collect();
        let (same, share) = whole_tiles(pixels.clone(), 4, 16);
        assert_eq!((same, share), (pixels.clone(), 1.0));
        let (kept, share) = whole_tiles(pixels.clone(), 4, 6);
        assert_eq!(share, 6.0 / 16.0);
        let mut tiles = std::collections::BTreeMap::new();
        for p in &kept {
            *tiles.entry((p.view, p.y / 4, p.x / 4)).or_insert(0) += 1;
        }
        // Tiles 0, 3, 6, 8, 11 and 14 of 16: both views, both rows, and the short one.
        let expected = [
            ((0, 0, 0), 16),
            ((0, 0, 3), 16),
            ((0, 1, 2), 16),
            ((1, 0, 0), 16),
            ((1, 0, 3), 12),
            ((1, 1, 2), 16),
        ];
        assert_eq!(tiles.into_iter().collect::<Vec<_>>(), expected);
        // In their order.
        assert!(kept
            .windows(2)
            .all(|w| (w[0].view, w[0].y, w[0].x) < (w[1].view, w[1].y, w[1].x)));
        let (_, share) = whole_tiles(pixels, 4, 15);
        assert_eq!(share, 15.0 / 16.0);
    }

    /// On the bundled cornell box, with the floor taken as unseen: every pixel found sees
    /// it over the share given (counted again here ray by ray) and only known groups
    /// beside it, none is one of its pure pixels, and a lower share finds more.
    #[test]
    fn mixed_pixels_see_the_group_over_their_share_and_known_groups_beside() {
        use crate::assemble::{load_and_assemble, MaterialSource};
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.toml");
        let mut owned = load_and_assemble(&path, MaterialSource::GeometryOnly).unwrap();
        let views = owned.views.clone();
        let n_groups = owned.group_names.len();
        let scene = owned.build().unwrap();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let pure = label_views(&pool, &scene, &views).pure;
        let unseen = 0u16;
        let find = |min_share: f64| {
            mixed_pixels(
                &pool,
                &scene,
                &views,
                n_groups,
                min_share,
                |h| h == unseen,
                |h| h != unseen,
            )
        };
        let half = find(0.5);
        let any = find(0.01);
        assert!(half
            .iter()
            .enumerate()
            .all(|(g, found)| g == 0 || found.is_empty()));
        assert!(
            !half[0].is_empty() && any[0].len() > half[0].len(),
            "{} {}",
            half[0].len(),
            any[0].len()
        );
        let n = LABEL_RAYS_PER_SIDE;
        for &(p, share) in &any[0] {
            let is_pure = pure
                .iter()
                .any(|q| (q.view, q.x, q.y) == (p.view, p.x, p.y));
            let view = &views[p.view as usize];
            let mut on = 0;
            for k in 0..n * n {
                let (fx, fy) = (
                    (k % n) as f32 / (n - 1) as f32,
                    (k / n) as f32 / (n - 1) as f32,
                );
                match first_hit(&scene, view, p.x as f32 + fx, p.y as f32 + fy)
                    .map(|(_, t)| t.surface)
                {
                    Some(Surface::Group(h)) if h == unseen => on += 1,
                    Some(Surface::Group(_)) => {}
                    other => panic!("{p:?} sees {other:?}"),
                }
            }
            assert_eq!(share, on as f64 / (n * n) as f64, "{p:?}");
            assert!(!is_pure && share < 1.0, "{p:?}");
            if share >= 0.5 {
                assert!(half[0].contains(&(p, share)), "{p:?}");
            }
        }
    }

    /// Cornell's light at 32 px per face holds pixels interior to it; at 8 px only four
    /// lie wholly on it, each beside its edge: those are kept apart, not read and not lost.
    #[test]
    fn pixels_wholly_on_a_light_beside_its_edge_are_kept_apart_from_interior_ones() {
        use crate::assemble::{load_and_assemble, MaterialSource};
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.toml");
        let mut owned = load_and_assemble(&path, MaterialSource::GeometryOnly).unwrap();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let fine = owned.views.clone();
        let coarse: Vec<View> = (fine.iter())
            .map(|v| View {
                width: 8,
                height: 8,
                ..*v
            })
            .collect();
        let scene = owned.build().unwrap();
        let at_32 = label_views(&pool, &scene, &fine);
        let at_8 = label_views(&pool, &scene, &coarse);
        assert!(!at_32.lights.is_empty() && !at_32.light_edges.is_empty());
        assert!(at_8.lights.is_empty());
        assert_eq!(at_8.light_edges.len(), 4, "{:?}", at_8.light_edges);
        // An edge pixel has a neighbour off the light; an interior one has none.
        for labels in [&at_32, &at_8] {
            for p in &labels.light_edges {
                assert!(!labels.lights.contains(p), "{p:?}");
            }
        }
    }

    #[test]
    fn limiting_a_group_keeps_an_even_subset_and_the_other_groups() {
        let pure: Vec<PurePixel> = (0..100)
            .map(|i| PurePixel {
                view: 0,
                x: i,
                y: 0,
                group: (i % 2) as u16,
            })
            .collect();
        let limited = limit_group(pure.clone(), 1, 10);
        let ones: Vec<u32> = limited
            .iter()
            .filter(|p| p.group == 1)
            .map(|p| p.x)
            .collect();
        assert_eq!(ones.len(), 10);
        assert!(ones.windows(2).all(|w| w[1] - w[0] == 10), "{ones:?}");
        assert_eq!(limited.iter().filter(|p| p.group == 0).count(), 50);
        assert_eq!(limit_group(pure.clone(), 1, 80), pure);
    }

    /// Two views of 40 x 30 pixels: group 0 the whole first view and the left half of the
    /// second, group 1 the second's right half, group 2 a 4 x 4 patch cut out of group 0.
    fn two_views() -> Vec<PurePixel> {
        let mut pure = Vec::new();
        for view in 0..2 {
            for y in 0..30 {
                for x in 0..40 {
                    let group = match (view, x, y) {
                        (0, 10..14, 10..14) => 2,
                        (1, 20.., _) => 1,
                        _ => 0,
                    };
                    pure.push(PurePixel { view, x, y, group });
                }
            }
        }
        pure
    }

    #[test]
    fn the_spread_subset_caps_large_groups_keeps_small_ones_whole_and_is_deterministic() {
        let pure = two_views();
        let counts = group_counts(&pure, 3);
        assert_eq!(counts, vec![1784, 600, 16]);
        let subset = spread_subset(&pure, 3, 100);
        assert_eq!(group_counts(&subset, 3), vec![100, 100, 16]);
        // Small groups whole, every pixel from `pure`, in `pure`'s order.
        assert_eq!(of_group(&subset, 2), of_group(&pure, 2));
        let position = |p: &PurePixel| pure.iter().position(|q| q == p).unwrap();
        let positions: Vec<usize> = subset.iter().map(position).collect();
        assert!(positions.windows(2).all(|w| w[0] < w[1]));
        // Deterministic, and the identity when no group is over the cap.
        assert_eq!(spread_subset(&pure, 3, 100), subset);
        assert_eq!(spread_subset(&pure, 3, 1784), pure);
        // A cap of one keeps one pixel per group.
        assert_eq!(group_counts(&spread_subset(&pure, 3, 1), 3), vec![1, 1, 1]);
    }

    #[test]
    fn the_spread_subset_covers_the_group_evenly() {
        let pure = two_views();
        let subset = spread_subset(&pure, 3, 100);
        // Group 0: 1184 of its 1784 pixels in view 0 and 600 in view 1, so about 66 and 34
        // of the 100; in every band of 5 rows of each view about a sixth of those.
        let group0 = of_group(&subset, 0);
        let in_view = |v: u32| group0.iter().filter(|p| p.view == v).count();
        assert!((65..=67).contains(&in_view(0)), "{}", in_view(0));
        assert!((33..=35).contains(&in_view(1)), "{}", in_view(1));
        for view in 0..2 {
            let per_band = in_view(view) as f64 / 6.0;
            for band in 0..6 {
                let n = group0
                    .iter()
                    .filter(|p| p.view == view && p.y / 5 == band)
                    .count() as f64;
                assert!((n - per_band).abs() <= 1.5, "view {view} band {band}: {n}");
            }
        }
        // Columns too: a quarter of group 1's pixels lie in each 5-column band of its 20.
        let group1 = of_group(&subset, 1);
        for band in 0..4 {
            let n = group1.iter().filter(|p| (p.x - 20) / 5 == band).count();
            assert!((15..=35).contains(&n), "band {band}: {n}");
        }
        // The group's mean of any smooth quantity (here x + y) is kept within a pixel.
        let mean = |pixels: &[PurePixel]| {
            pixels.iter().map(|p| (p.x + p.y) as f64).sum::<f64>() / pixels.len() as f64
        };
        assert!((mean(&group1) - mean(&of_group(&pure, 1))).abs() < 1.0);
    }
}
