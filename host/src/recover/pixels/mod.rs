//! The pixels recovery works on: each group's pure pixels (whole footprint on the group),
//! and their evaluation against the panorama, in a fixed partition so that the sums do not
//! depend on the thread count.
//!
//! `labels`: what each pixel sees (pure, on a light, mixed; a group's border); `subsets`:
//! which pixels a measurement takes; `evaluate`: the renders and their sums against the
//! panorama; `steps`: stage 3's pixel pairs a step apart.

mod evaluate;
mod labels;
mod steps;
mod subsets;

pub use evaluate::{
    cross_settings, evaluate, evaluate_cross, evaluate_with_colour_gradients,
    evaluate_with_lobe_part, fits_of_halves, paired_cross_terms, real_value, render_pixels,
    render_pixels_with_diffuse_part, GradientFit, Observed,
};
pub use labels::{border_pixels, label_views, mixed_pixels, pixel_uvs, sight, Labels, LightPixel};
pub use steps::{step_differences, step_pairs};
pub use subsets::{every_kth, limit_group, spread_subset, whole_tiles};

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
