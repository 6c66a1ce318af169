//! Stage 3 on the host: a group's step contrast, from two renders with independent samples
//! of the pixels it is judged on (all its pure pixels, or an even subset of a large group's
//! pairs).

use glam::Vec3;
use relume_core::fit;
use relume_core::math::luminance;
use relume_core::stages::texture;

use super::super::pixels::{self, PurePixel};
use super::super::Recovery;
use super::median;
use crate::error::Error;

/// Renders `pixels` twice with independent samples (`spp / 2` each,
/// `pixels::cross_settings`) under the current models: the two renders that noise-free
/// statistics need.
fn render_twice(
    rec: &mut Recovery,
    pixels: &[PurePixel],
    spp: u32,
    seed: u64,
) -> Result<(Vec<Vec3>, Vec<Vec3>), Error> {
    rec.with_scene(spp, seed, |pool, scene, observed, settings| {
        let (a, b) = pixels::cross_settings(settings);
        (
            pixels::render_pixels(pool, scene, observed.views, pixels, &a),
            pixels::render_pixels(pool, scene, observed.views, pixels, &b),
        )
    })
}

/// Pure pixels of one group that stage 3 renders at most: a larger group is judged on an
/// even subset of its pixel pairs (every `k`-th, `TEXTURE_GROUP_PIXELS / 2` of them),
/// rendering only their pixels. The contrast
/// is a root mean square over pairs, and 2^14 pixels give thousands of pairs: its
/// standard error is a small fraction of `TEXTURE_CONTRAST_THRESHOLD`. Every group at 64
/// px per face is under it (the living room's largest, the ceiling, has 6648); at 256 px
/// the floor and walls, with 60000-130000 pixels, took 8 s of renders in all.
const TEXTURE_GROUP_PIXELS: usize = 1 << 14;

/// The pixels stage 3 renders of `all` (one group's pure pixels) and the pairs
/// `TEXTURE_STEP` apart among them, as indices into those pixels (see
/// [`TEXTURE_GROUP_PIXELS`]).
fn contrast_pixels(
    views: &[relume_core::geometry::View],
    all: Vec<PurePixel>,
) -> (Vec<PurePixel>, Vec<(usize, usize)>) {
    let pairs = pixels::step_pairs(views, &all, fit::TEXTURE_STEP);
    if all.len() <= TEXTURE_GROUP_PIXELS {
        return (all, pairs);
    }
    // Two pixels a pair at most.
    let stride = pairs.len().div_ceil(TEXTURE_GROUP_PIXELS / 2).max(1);
    let chosen: Vec<(usize, usize)> = pairs.into_iter().step_by(stride).collect();
    let mut used: Vec<usize> = chosen.iter().flat_map(|&(i, j)| [i, j]).collect();
    used.sort_unstable();
    used.dedup();
    let at = |i: usize| used.binary_search(&i).unwrap_or_default();
    let renumbered = chosen.iter().map(|&(i, j)| (at(i), at(j))).collect();
    (used.iter().map(|&i| all[i]).collect(), renumbered)
}

/// Stage 3: the cross contrast (`texture::cross_contrast`) of group `g` under its current
/// model; `None` when the group has no pair of lit pixels `TEXTURE_STEP` apart.
pub fn texture_contrast(
    rec: &mut Recovery,
    g: usize,
    spp: u32,
    seed: u64,
) -> Result<Option<f64>, Error> {
    let (pixels, pairs) = contrast_pixels(&rec.views, pixels::of_group(&rec.pure, g));
    let (a, b) = render_twice(rec, &pixels, spp, seed)?;
    let lum = |v: Vec3| luminance(v) as f64;
    let rendered: Vec<f64> = a
        .iter()
        .zip(&b)
        .map(|(a, b)| 0.5 * (lum(*a) + lum(*b)))
        .collect();
    // Pixels in shadow carry mostly noise in a log-ratio; they are left out.
    let floor = fit::SHADOW_FRACTION * median(rendered.clone());
    let log_ratio = |i: usize, r: Vec3| {
        let real = lum(pixels::real_value(&rec.real, &rec.views, &pixels[i]));
        if rendered[i] > floor && real > 0.0 && lum(r) > 0.0 {
            Some(libm::log(real / lum(r)))
        } else {
            None
        }
    };
    let la: Vec<Option<f64>> = (0..pixels.len()).map(|i| log_ratio(i, a[i])).collect();
    let lb: Vec<Option<f64>> = (0..pixels.len()).map(|i| log_ratio(i, b[i])).collect();
    Ok(texture::cross_contrast(pairs.iter().filter_map(
        |&(i, j)| Some((la[i]? - la[j]?, lb[i]? - lb[j]?)),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    use glam::Vec3;
    use relume_core::geometry::View;

    fn view(side: u32) -> View {
        View {
            position: Vec3::ZERO,
            forward: Vec3::Z,
            right_span: Vec3::X,
            up_span: Vec3::Y,
            width: side,
            height: side,
        }
    }

    fn group(side: u32) -> Vec<PurePixel> {
        (0..side * side)
            .map(|i| PurePixel {
                view: 0,
                x: i % side,
                y: i / side,
                group: 0,
            })
            .collect()
    }

    /// A group over the cap is judged on at most the cap's pixels, pairs still a step
    /// apart; one under it keeps every pixel and pair.
    #[test]
    fn a_large_group_is_judged_on_a_subset_of_its_pairs() {
        let views = [view(200)];
        let (pixels, pairs) = contrast_pixels(&views, group(200));
        assert!(pixels.len() <= TEXTURE_GROUP_PIXELS, "{}", pixels.len());
        assert!(pairs.len() >= TEXTURE_GROUP_PIXELS / 4, "{}", pairs.len());
        for &(i, j) in &pairs {
            let (p, q) = (pixels[i], pixels[j]);
            let apart = (q.x - p.x, q.y - p.y);
            assert!(
                apart == (fit::TEXTURE_STEP, 0) || apart == (0, fit::TEXTURE_STEP),
                "{p:?} {q:?}"
            );
        }

        let small = group(100);
        let (pixels, pairs) = contrast_pixels(&[view(100)], small.clone());
        assert_eq!(pixels, small);
        assert_eq!(
            pairs,
            pixels::step_pairs(&[view(100)], &small, fit::TEXTURE_STEP)
        );
    }
}
