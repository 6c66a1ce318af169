//! The pure pixels rendered and summed against the panorama, group by group, in a fixed
//! partition (`CHUNK`s in order) so that the sums do not depend on the thread count:
//! plain fits, with the lobe's part, with colour gradients, and bias-only from two
//! independent renders.

use glam::Vec3;
use rayon::prelude::*;
use relume_core::fit::GroupFit;
use relume_core::geometry::View;
use relume_core::render::{self, RenderSettings};
use relume_core::scene::Scene;

use crate::images::Image;

use super::{PurePixel, CHUNK};

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
