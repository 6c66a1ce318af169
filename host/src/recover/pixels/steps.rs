//! Pairs of a group's pixels a step apart in their view, and their differences: the
//! statistic stage 3's texture test reads.

use glam::Vec3;
use relume_core::geometry::View;

use super::{Observed, PurePixel};

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
