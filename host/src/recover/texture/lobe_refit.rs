//! Stage 5's lobe refit: a textured group's isotropic lobe fitted again on its highlights
//! with the map it now has, on the group's transport cache.

use std::collections::HashMap;

use glam::{Vec2, Vec3};
use relume_core::fit;
use relume_core::material::Material;
use relume_core::render::RenderSettings;
use relume_core::stages::isotropic;
use relume_core::stages::texture_map::{self, FOOTPRINT_SAMPLES};

use super::super::model::MapLobe;
use super::super::Recovery;
use super::map_solve::MapSolve;
use crate::error::Error;

/// A textured group's isotropic lobe fitted again with its map.
#[derive(Clone, Copy, Debug)]
pub struct LobeRefit {
    /// (specularity, roughness) of the stand-in's lobe and of the refitted one.
    pub before: [f64; 2],
    pub after: [f64; 2],
    /// The highlight pixels of the group's cache it was fitted on.
    pub pixels: u32,
    /// The sum of squared residuals there under each.
    pub sse_before: f64,
    pub sse_after: f64,
}

/// The isotropic lobe of group `g` fitted on its highlights with the map it now has. The
/// stand-in's lobe was fitted with a uniform colour where the picture varies, and took
/// part of the picture for the lobe (the living room's picture_2 at 64 px: specularity
/// 0.063, roughness 0.12, against 0.05 and 0.08). Its highlights are the pixels the map
/// was not solved from (filled from their neighbours), so there the map gives the diffuse
/// part independently of the lobe, and the lobe is fitted to what is left: specularity in
/// closed form for each roughness, the roughness by stage 2's 1-D search, on the group's
/// transport cache. Elsewhere the map was solved to leave exactly the stand-in's lobe, and
/// would only return it. `None` for a lobe that is not isotropic, or where the cache holds
/// fewer than `MIN_PIXELS_FOR_MODEL_CHOICE` highlight pixels.
pub(super) fn lobe_with_map(
    rec: &mut Recovery,
    solve: &MapSolve,
    highlight: &[bool],
    stand_in: MapLobe,
    cache_settings: &RenderSettings,
) -> Result<Option<LobeRefit>, Error> {
    let MapLobe::Isotropic {
        specularity,
        roughness,
    } = stand_in
    else {
        return Ok(None);
    };
    let footprints: HashMap<(u32, u32, u32), [Vec2; FOOTPRINT_SAMPLES]> = solve
        .pixels
        .iter()
        .zip(solve.uvs)
        .zip(highlight)
        .filter(|(_, &h)| h)
        .filter_map(|((p, uv), _)| Some(((p.view, p.x, p.y), (*uv)?)))
        .collect();
    let cache = rec.group_cache(solve.g, cache_settings)?;
    let map = &rec.maps[solve.map];
    // Each cached highlight pixel with the map's value there.
    let rows: Vec<(usize, Vec3)> = cache
        .pixels
        .iter()
        .enumerate()
        .filter_map(|(i, p)| {
            let uv = footprints.get(&(p.view, p.x, p.y))?;
            Some((i, texture_map::footprint_value(&map.texels, map.grid(), uv)))
        })
        .collect();
    if rows.len() < fit::MIN_PIXELS_FOR_MODEL_CHOICE as usize {
        return Ok(None);
    }
    let sums_at = |alpha: f64| {
        let lobe = Material::Ward {
            rho_d: Vec3::ZERO,
            rho_s: Vec3::ONE,
            alpha: alpha as f32,
        };
        let mut sums = texture_map::LobeScaleSums::default();
        for &(i, texel) in &rows {
            let (diffuse, specular) = cache.linear_parts(i, &lobe);
            sums.add(cache.real[i] - texel * diffuse, specular);
        }
        sums
    };
    let (alpha, sse_after) = isotropic::minimise_1d(
        |alpha| sums_at(alpha).best().1,
        isotropic::ROUGHNESS_MIN,
        isotropic::ROUGHNESS_MAX,
        isotropic::ROUGHNESS_GRID,
        isotropic::ROUGHNESS_REFINE_STEPS,
        true,
    );
    let (s, _) = sums_at(alpha).best();
    Ok(Some(LobeRefit {
        before: [specularity, roughness],
        after: [s, alpha],
        pixels: rows.len() as u32,
        sse_before: sums_at(roughness).sse(specularity),
        sse_after,
    }))
}
