//! Stages 3 and 5 on the host: the renders that texture detection and the diffuse-map
//! solve need. The statistic and the solver are the core's (`relume_core::stages::texture`
//! and `texture_map`).
//!
//! The parts: `contrast` (stage 3: a group's step contrast from two independent renders),
//! `map_solve` (stage 5: a textured group's diffuse map, solved under its stand-in's lobe),
//! `lobe_refit` (stage 5: an isotropic lobe fitted again with the map) and `uv_affine` (a
//! flat group's (u, v) as an affine function of the point, for RADIANCE). Here: the
//! [`RecoveredMap`] they make, how it is read ([`map_wrap`]), and the [`MapSummary`] of its
//! recovery that the report takes, with the lobe's share of the group's light
//! ([`lobe_share`]).

use glam::Vec3;
use relume_core::material::{TextureGrid, Wrap};
use relume_core::math::luminance;

use super::model::GroupModel;
use super::Recovery;

mod contrast;
mod lobe_refit;
mod map_solve;
mod uv_affine;

pub use contrast::texture_contrast;
pub use lobe_refit::LobeRefit;
pub use map_solve::recover_map;
pub use uv_affine::{uv_affine, UvAffine};

/// A recovered diffuse map (row 0 = v 1), square.
#[derive(Clone, Debug, PartialEq)]
pub struct RecoveredMap {
    pub side: u32,
    pub texels: Vec<Vec3>,
    /// Repeated where its group's coordinates reach past [0, 1] ([`map_wrap`]).
    pub wrap: Wrap,
}

impl RecoveredMap {
    /// Its texel grid, as the renderer and the solver read it.
    pub fn grid(&self) -> TextureGrid {
        TextureGrid {
            width: self.side,
            height: self.side,
            wrap: self.wrap,
        }
    }
}

/// How group `g`'s map is read: repeated when some coordinate of its faces reaches past
/// [0, 1] (`OwnedScene::tiles_its_map`: a texture tiled over a floor by coordinates from 0
/// to 4), else clamped, the format's lookup. A clamped map over tiles would give every
/// pixel past 1 its last column.
pub fn map_wrap(rec: &Recovery, g: usize) -> Wrap {
    if rec.owned.tiles_its_map(g) {
        Wrap::Repeat
    } else {
        Wrap::Clamp
    }
}

/// How a map was recovered, for the report.
pub struct MapSummary {
    pub side: u32,
    pub wrap: Wrap,
    /// Pure pixels, and pixels on the group's border that the map was also solved from.
    pub pixels: usize,
    pub border_pixels: usize,
    /// Pixels whose light is mostly the lobe's: kept in the final map, left out of the
    /// first one that a lobe refit reads.
    pub highlights: usize,
    pub shadows: usize,
    pub unseen_texels: usize,
    /// The isotropic lobe fitted again with the map, where it was.
    pub lobe_refit: Option<LobeRefit>,
    /// The share of the group's light in the panorama (over its pure pixels) that the
    /// lobe renders: the map holds the rest, so an error of the lobe's there is the map's
    /// too, with the opposite sign ([`lobe_share`]).
    pub lobe_share: f64,
}

fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// The share of the light of `real` (luminance, summed over a group's pixels) that a lobe
/// renders, `specular` per pixel: 0 without light, and 0 for a `model` without a lobe,
/// whose `specular` is what rounding leaves of a pixel's light less its diffuse part
/// (textured's pictures without a lobe read 2e-7).
///
/// A map is solved so that map and lobe together give each pixel its panorama value, and
/// the panorama sees each texel from one direction only, so a lobe that sends too much
/// light that way leaves its map too dark by as much, which shows from another viewpoint
/// or under another light (the living room's picture_2 at 64 px: a lobe 26% broad, a
/// map 4-7% dark, the picture -5.5% in the novel view; docs/edits.md).
pub fn lobe_share(model: &GroupModel, specular: &[Vec3], real: &[Vec3]) -> f64 {
    if !model.has_lobe() {
        return 0.0;
    }
    let total: f64 = real.iter().map(|v| luminance(*v) as f64).sum();
    if total.is_nan() || total <= 0.0 {
        return 0.0;
    }
    specular.iter().map(|v| luminance(*v) as f64).sum::<f64>() / total
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recover::model::MapLobe;

    /// The lobe's share is its light over the panorama's, summed over the pixels before
    /// dividing (a bright pixel counts for more), and 0 where the group has no light.
    #[test]
    fn a_lobes_share_is_its_light_over_the_panoramas() {
        let grey = |v: f32| Vec3::splat(v);
        let textured = |lobe| GroupModel::Textured { map: 0, lobe };
        let lobe = textured(MapLobe::isotropic(0.05, 0.1));
        let share = lobe_share(&lobe, &[grey(0.1), grey(0.0)], &[grey(0.2), grey(0.6)]);
        assert!((share - 0.125).abs() < 1e-6, "{share}");
        assert_eq!(lobe_share(&lobe, &[grey(0.1)], &[grey(0.0)]), 0.0);
        assert_eq!(lobe_share(&lobe, &[], &[]), 0.0);
        // Without a lobe, what the split leaves is rounding: no share.
        let residue = [grey(3e-8), grey(0.0)];
        let real = [grey(0.2), grey(0.6)];
        assert_eq!(lobe_share(&textured(MapLobe::None), &residue, &real), 0.0);
    }
}
