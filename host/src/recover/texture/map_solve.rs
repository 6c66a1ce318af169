//! Stage 5 on the host: a textured group's diffuse map, `T = (I_real - I_specular) / E`,
//! solved under its untextured stand-in's lobe from one render of the group under a
//! constant map, over its pure pixels and those on its border.

use glam::{Vec2, Vec3};
use relume_core::fit;
use relume_core::geometry::{Surface, Triangle};
use relume_core::material::{TextureGrid, Wrap};
use relume_core::math::luminance;
use relume_core::render::RenderSettings;
use relume_core::stages::diffuse::MAX_DIFFUSE_REFLECTANCE;
use relume_core::stages::texture_map::{self, MapObservation, FOOTPRINT_SAMPLES};

use super::super::model::{GroupModel, MapLobe};
use super::super::pixels::{self, PurePixel};
use super::super::Recovery;
use super::lobe_refit::lobe_with_map;
use super::{lobe_share, map_wrap, median, MapSummary, RecoveredMap};
use crate::error::Error;

/// A pixel on a textured group's border joins its map when at least this many of its
/// [`FOOTPRINT_SAMPLES`] see the group: half its footprint. One whose footprint is mostly
/// another surface would bring that surface's misfit into the map.
const BORDER_MIN_ON: usize = 2;

/// Stage 5: the diffuse map of group `g` under its untextured stand-in's lobe (the group's
/// current model: a diffuse, isotropic or anisotropic plastic, whose diffuse colour starts
/// the map), `T = (I_real - I_specular) / E`, with E from full global-illumination renders
/// of the recovered scene. Under an isotropic lobe a first map is solved without the
/// highlights, the lobe fitted again with it there ([`lobe_with_map`]), and the map solved
/// once more under the lobe it ends with, from every pixel. Sets the group's model to the
/// textured one and returns what was done.
pub fn recover_map(
    rec: &mut Recovery,
    g: usize,
    spp: u32,
    seed: u64,
    cache_settings: &RenderSettings,
) -> Result<MapSummary, Error> {
    // The pure pixels, then the border's: a picture's edge (the references' grey margins)
    // lies under pixels that also see its frame, and without them the map's outer texels
    // are guessed from the inner ones.
    let mut pixels = pixels::of_group(&rec.pure, g);
    let pure_count = pixels.len();
    let counts = pixels::group_counts(&rec.pure, rec.n_groups());
    let (mut uvs, border): (Vec<Option<[Vec2; FOOTPRINT_SAMPLES]>>, _) =
        rec.with_scene(1, seed, |_, scene, observed, _| {
            let uvs = pixels
                .iter()
                .map(|p| pixels::pixel_uvs(scene, observed.views, p))
                .collect();
            let border = pixels::border_pixels(
                scene,
                observed.views,
                &pixels,
                g as u16,
                BORDER_MIN_ON,
                |h| counts[h as usize] > 0,
            );
            (uvs, border)
        })?;
    for (p, uv) in border {
        pixels.push(p);
        uvs.push(Some(uv));
    }
    // The stand-in's diffuse reflectance, as a constant map to render E against.
    let (rho_d, _) = rec.models[g].reflectances();
    let start = Vec3::new(rho_d[0] as f32, rho_d[1] as f32, rho_d[2] as f32).clamp(
        Vec3::splat(0.02),
        Vec3::splat(MAX_DIFFUSE_REFLECTANCE as f32),
    );
    let map = rec.maps.len();
    let wrap = map_wrap(rec, g);
    rec.maps.push(RecoveredMap {
        side: 1,
        texels: vec![start],
        wrap,
    });
    rec.models[g] = GroupModel::Textured {
        map,
        lobe: MapLobe::of_stand_in(&rec.models[g]),
    };
    let solve = MapSolve {
        g,
        map,
        pure_count,
        uv_coverage: uv_coverage(rec.owned.triangles(), g as u16),
        pixels: &pixels,
        uvs: &uvs,
        start,
        spp,
        seed,
    };
    let mut observed = solve.observe(rec)?;
    let mut lobe_refit = None;
    if let GroupModel::Textured {
        lobe: stand_in @ MapLobe::Isotropic { .. },
        ..
    } = rec.models[g]
    {
        let first = solve.solve(rec, &observed, Highlights::LeftOut)?;
        let refit = lobe_with_map(rec, &solve, &first.highlight, stand_in, cache_settings)?;
        if let Some(refit) = refit {
            let [specularity, roughness] = refit.after;
            rec.models[g] = GroupModel::Textured {
                map,
                lobe: MapLobe::isotropic(specularity, roughness),
            };
            // E and the lobe's part under the new lobe.
            observed = solve.observe(rec)?;
            lobe_refit = Some(refit);
        }
    }
    let solved = solve.solve(rec, &observed, Highlights::Kept)?;
    let pure = &pixels[..pure_count];
    let real: Vec<Vec3> = pure
        .iter()
        .map(|p| pixels::real_value(&rec.real, &rec.views, p))
        .collect();
    Ok(MapSummary {
        side: solved.side,
        wrap,
        pixels: pure_count,
        border_pixels: solved.border_used,
        highlights: solved.highlight[..pure_count]
            .iter()
            .filter(|&&h| h)
            .count(),
        shadows: solved.shadows,
        unseen_texels: solved.unseen_texels,
        lobe_refit,
        lobe_share: lobe_share(&rec.models[g], &observed.specular[..pure_count], &real),
    })
}

/// The largest texel a textured `model`'s map may hold: a plastic's map is its diffuse
/// reflectance, so with its white lobe it reflects at most all the light it receives
/// (`1 - specularity`), and never past the diffuse colours' own bound.
fn map_bound(model: &GroupModel) -> f32 {
    let specularity = match model {
        GroupModel::Textured { lobe, .. } => lobe.specularity(),
        _ => 0.0,
    };
    (1.0 - specularity).clamp(0.0, MAX_DIFFUSE_REFLECTANCE) as f32
}

/// The area in (u, v) of group `g`'s faces among `triangles`: how much of its map's
/// [0, 1]^2 the group lies over (past 1 where faces share a region of it).
fn uv_coverage(triangles: &[Triangle], g: u16) -> f64 {
    triangles
        .iter()
        .filter(|t| t.surface == Surface::Group(g))
        .map(|t| {
            let [a, b, c] = t.uv.map(|p| [p.x as f64, p.y as f64]);
            let (e1, e2) = ([b[0] - a[0], b[1] - a[1]], [c[0] - a[0], c[1] - a[1]]);
            0.5 * (e1[0] * e2[1] - e1[1] * e2[0]).abs()
        })
        .sum()
}

/// One solve of a group's map under its current lobe: what [`MapSolve::observe`] and
/// [`MapSolve::solve`] need.
pub(super) struct MapSolve<'a> {
    pub(super) g: usize,
    /// The map's index in `Recovery::maps`.
    pub(super) map: usize,
    /// `pixels` holds the group's pure pixels first, this many, then its border's.
    pure_count: usize,
    /// How much of the map's [0, 1]^2 the group lies over ([`uv_coverage`]).
    uv_coverage: f64,
    pub(super) pixels: &'a [PurePixel],
    pub(super) uvs: &'a [Option<[Vec2; FOOTPRINT_SAMPLES]>],
    /// The constant map E is rendered against.
    start: Vec3,
    spp: u32,
    seed: u64,
}

/// Whether a solve reads the pixels whose light is mostly the lobe's.
///
/// The final map keeps them: `(I_real - I_specular) / E` is the map there as anywhere,
/// and where a picture's dark parts reflect the room (the textured scene's checker, whose
/// dark squares are mostly lobe) leaving them out left a quarter of its pixels unsolved and
/// filled from the light squares beside them. The first map of a lobe refit leaves them
/// out, so that the map there does not depend on the lobe being refitted.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Highlights {
    LeftOut,
    Kept,
}

/// The render a map is solved from, per pixel of `MapSolve::pixels`: the group under a
/// constant map (`MapSolve::start`), and the part of it that is not the map's (the lobe's,
/// and whatever else the pixel sees), from the same samples.
struct Observed {
    full: Vec<Vec3>,
    specular: Vec<Vec3>,
}

/// What a solve found besides the map.
struct Solved {
    side: u32,
    /// Per pixel of `MapSolve::pixels`: removed as a highlight (its light mostly the lobe's).
    highlight: Vec<bool>,
    /// Pure pixels left out as shadows, and border pixels the map was solved from.
    shadows: usize,
    border_used: usize,
    unseen_texels: usize,
}

impl MapSolve<'_> {
    /// Renders the group under the constant map, splitting each pixel's light into what
    /// comes by way of the map (at any vertex on the group: the frame a picture lights
    /// lights it back) and the rest (its lobe's, and the light of whatever else the pixel
    /// sees): what E and the specular part come from, for the lobe the group has now. One
    /// render, where a second of the same pixels with a black map took as long again
    /// (docs/recovery.md, "Stage 5 from one render").
    fn observe(&self, rec: &mut Recovery) -> Result<Observed, Error> {
        let (map, pixels) = (self.map, self.pixels);
        rec.maps[map] = RecoveredMap {
            side: 1,
            texels: vec![self.start],
            wrap: rec.maps[map].wrap,
        };
        let g = self.g as u16;
        let split = rec.with_scene(
            self.spp,
            self.seed ^ 0x7E47,
            |pool, scene, observed, settings| {
                pixels::render_pixels_with_diffuse_part(
                    pool,
                    scene,
                    observed.views,
                    pixels,
                    settings,
                    g,
                )
            },
        )?;
        let (full, specular) = split
            .into_iter()
            .map(|(value, diffuse)| (value, (value - diffuse).max(Vec3::ZERO)))
            .unzip();
        Ok(Observed { full, specular })
    }

    /// Solves the map (stored in `rec.maps`) from `observed`, over the pixels that are not
    /// in shadow (and not highlights, when `highlights` says so).
    fn solve(
        &self,
        rec: &mut Recovery,
        observed: &Observed,
        highlights: Highlights,
    ) -> Result<Solved, Error> {
        let (map, pixels) = (self.map, self.pixels);
        let (full, specular) = (&observed.full, &observed.specular);
        let gains: Vec<Vec3> = full
            .iter()
            .zip(specular)
            .map(|(f, s)| ((*f - *s) / self.start).max(Vec3::ZERO))
            .collect();
        // The floor is the pure pixels' own: a border pixel's E holds how much of its
        // footprint the group covers, and one that covers too little to read falls under it.
        let gain_floor = fit::SHADOW_FRACTION
            * median(
                gains[..self.pure_count]
                    .iter()
                    .map(|v| luminance(*v) as f64)
                    .collect(),
            );
        let mut highlight = vec![false; pixels.len()];
        let (mut shadows, mut border_used) = (0, 0);
        let observations: Vec<MapObservation> = pixels
            .iter()
            .enumerate()
            .filter_map(|(i, p)| {
                let uv = self.uvs[i]?;
                let real = pixels::real_value(&rec.real, &rec.views, p);
                highlight[i] = luminance(specular[i]) as f64
                    > fit::HIGHLIGHT_FRACTION * luminance(real) as f64;
                let dark = (luminance(gains[i]) as f64) <= gain_floor;
                let left_out = dark || (highlight[i] && highlights == Highlights::LeftOut);
                if i < self.pure_count {
                    shadows += dark as usize;
                } else {
                    border_used += !left_out as usize;
                }
                Some(MapObservation {
                    uv,
                    gain: gains[i],
                    target: real - specular[i],
                    weight: if left_out { 0.0 } else { 1.0 },
                })
            })
            .collect();
        // The map's texels are counted over every pixel it is solved from, its border's
        // too: a small picture's border is a large share of it (the living room's
        // picture_3 at 64 px: 63 pure pixels, 36 on its border), and two texels a pure
        // pixel left it barely more than one a pixel, the worst sampling ("Map PSNR").
        let solved_from = observations.len();
        let side = match rec.maps[map].wrap {
            Wrap::Clamp => texture_map::map_side(solved_from, self.uv_coverage),
            // The coordinates' area in (u, v) is the number of repeats.
            Wrap::Repeat => texture_map::tiled_map_side(solved_from, self.uv_coverage),
        };
        let n = (side * side) as usize;
        let mut texels = vec![self.start; n];
        let (mut numerator, mut denominator) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
        let wrap = rec.maps[map].wrap;
        let grid = TextureGrid {
            width: side,
            height: side,
            wrap,
        };
        let unseen_texels = texture_map::solve_map(
            &observations,
            grid,
            map_bound(&rec.models[self.g]),
            &mut texels,
            &mut numerator,
            &mut denominator,
        )
        .map_err(|e| Error::core(format!("recovering the map of group {}", self.g), e))?;
        rec.maps[map] = RecoveredMap { side, texels, wrap };
        Ok(Solved {
            side,
            highlight,
            shadows,
            border_used,
            unseen_texels,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A white picture under a lobe: its map may not reflect, with the lobe, more than the
    /// light it receives, which `render` would warn of.
    #[test]
    fn a_map_is_bounded_by_what_its_lobe_leaves() {
        let textured = |lobe| GroupModel::Textured { map: 0, lobe };
        let bound = |lobe| map_bound(&textured(lobe));
        assert_eq!(bound(MapLobe::None), MAX_DIFFUSE_REFLECTANCE as f32);
        assert_eq!(
            bound(MapLobe::isotropic(0.005, 0.1)),
            MAX_DIFFUSE_REFLECTANCE as f32
        );
        assert_eq!(bound(MapLobe::isotropic(0.05, 0.1)), 0.95);
        let anisotropic = MapLobe::Anisotropic {
            specularity: 0.2,
            roughness_u: 0.1,
            roughness_v: 0.2,
            direction: [1.0, 0.0, 0.0],
        };
        assert_eq!(bound(anisotropic), 0.8);
    }
}
