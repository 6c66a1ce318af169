//! Stages 3 and 5 on the host: the renders that texture detection and the diffuse-map
//! solve need. The statistic and the solver are the core's (`relume_core::stages::texture`
//! and `texture_map`).

use std::collections::HashMap;

use glam::{Vec2, Vec3};
use relume_core::fit;
use relume_core::geometry::{longest_side, Surface, Triangle};
use relume_core::material::{Material, TextureGrid, Wrap};
use relume_core::math::luminance;
use relume_core::render::RenderSettings;
use relume_core::stages::diffuse::MAX_DIFFUSE_REFLECTANCE;
use relume_core::stages::isotropic;
use relume_core::stages::texture;
use relume_core::stages::texture_map::{self, MapObservation, FOOTPRINT_SAMPLES};

use super::model::{GroupModel, MapLobe};
use super::pixels::{self, PurePixel};
use super::Recovery;
use crate::error::Error;

/// A pixel on a textured group's border joins its map when at least this many of its
/// [`FOOTPRINT_SAMPLES`] see the group: half its footprint. One whose footprint is mostly
/// another surface would bring that surface's misfit into the map.
const BORDER_MIN_ON: usize = 2;

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
        lobe_share: lobe_share(&observed.specular[..pure_count], &real),
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

/// The share of the light of `real` (luminance, summed over a group's pixels) that a lobe
/// renders, `specular` per pixel: 0 without light.
///
/// A map is solved so that map and lobe together give each pixel its panorama value, and
/// the panorama sees each texel from one direction only, so a lobe that sends too much
/// light that way leaves its map too dark by as much, which shows from another viewpoint
/// or under another light (the living room's picture_2 at 64 px: a lobe 26% broad, a
/// map 4-7% dark, the picture -5.5% in the novel view; docs/edits.md).
pub fn lobe_share(specular: &[Vec3], real: &[Vec3]) -> f64 {
    let total: f64 = real.iter().map(|v| luminance(*v) as f64).sum();
    if total.is_nan() || total <= 0.0 {
        return 0.0;
    }
    specular.iter().map(|v| luminance(*v) as f64).sum::<f64>() / total
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
struct MapSolve<'a> {
    g: usize,
    /// The map's index in `Recovery::maps`.
    map: usize,
    /// `pixels` holds the group's pure pixels first, this many, then its border's.
    pure_count: usize,
    /// How much of the map's [0, 1]^2 the group lies over ([`uv_coverage`]).
    uv_coverage: f64,
    pixels: &'a [PurePixel],
    uvs: &'a [Option<[Vec2; FOOTPRINT_SAMPLES]>],
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
fn lobe_with_map(
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

/// The texture coordinates of group `g` as an affine function of the surface point,
/// `uv = (grad_u . (P - origin) + u0, grad_v . (P - origin) + v0)`, when every vertex of
/// the group obeys it (a planar, affinely mapped group); what RADIANCE needs to place a
/// `colorpict`. `None` for a curved or non-affinely mapped group.
pub struct UvAffine {
    pub origin: Vec3,
    pub uv0: [f32; 2],
    pub grad_u: Vec3,
    pub grad_v: Vec3,
}

pub fn uv_affine(rec: &Recovery, g: usize) -> Option<UvAffine> {
    let triangles: Vec<_> = rec
        .owned
        .triangles()
        .iter()
        .filter(|t| t.surface == Surface::Group(g as u16))
        .collect();
    affine_map(&triangles)
}

/// [`uv_affine`] of these triangles.
fn affine_map(triangles: &[&Triangle]) -> Option<UvAffine> {
    let largest = triangles
        .iter()
        .max_by(|a, b| a.area().total_cmp(&b.area()))?;
    let p = largest.v.map(|v| v);
    let uv = largest.uv.map(|t| [t.x, t.y]);
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    // Tolerances relative to the group's size, so that a picture in millimetres or
    // kilometres is placed as one in metres: the largest triangle no sliver (sin^2 of its
    // angle above 1e-10), every vertex within 1e-4 of the group's size of its plane.
    let det = a * c - b * b;
    if det.is_nan() || det <= 1e-10 * a * c {
        return None;
    }
    let off_plane = 1e-4 * longest_side(triangles.iter().copied());
    // The in-plane gradient x e1 + y e2 whose products with the edges give the uv steps.
    let gradient = |d1: f32, d2: f32| {
        let x = (c * d1 - b * d2) / det;
        let y = (a * d2 - b * d1) / det;
        e1 * x + e2 * y
    };
    let affine = UvAffine {
        origin: p[0],
        uv0: uv[0],
        grad_u: gradient(uv[1][0] - uv[0][0], uv[2][0] - uv[0][0]),
        grad_v: gradient(uv[1][1] - uv[0][1], uv[2][1] - uv[0][1]),
    };
    let normal = e1.cross(e2).normalize();
    let fits = triangles.iter().all(|t| {
        (0..3).all(|k| {
            let q = t.v[k] - affine.origin;
            let u = affine.grad_u.dot(q) + affine.uv0[0];
            let v = affine.grad_v.dot(q) + affine.uv0[1];
            (u - t.uv[k].x).abs() < 1e-3
                && (v - t.uv[k].y).abs() < 1e-3
                && normal.dot(q).abs() <= off_plane
        })
    });
    fits.then_some(affine)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A picture as one quad in the plane x = 1 (uv over y and z), its second triangle
    /// lifted off the plane by `bend`, all scaled by `scale`.
    fn picture(scale: f32, bend: f32) -> Vec<Triangle> {
        let corner = |y: f32, z: f32, x: f32| Vec3::new(1.0 + x, y, z) * scale;
        let uv = |y: f32, z: f32| Vec2::new(y, z);
        vec![
            Triangle {
                v: [corner(0., 0., 0.), corner(1., 0., 0.), corner(1., 1., 0.)],
                uv: [uv(0., 0.), uv(1., 0.), uv(1., 1.)],
                surface: Surface::Group(0),
            },
            Triangle {
                v: [corner(0., 0., 0.), corner(1., 1., 0.), corner(0., 1., bend)],
                uv: [uv(0., 0.), uv(1., 1.), uv(0., 1.)],
                surface: Surface::Group(0),
            },
        ]
    }

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

    /// A flat picture is placed for RADIANCE in millimetres as in kilometres (its sliver
    /// and flatness tests were in absolute lengths), and a bent one at no scale.
    #[test]
    fn a_pictures_affine_map_does_not_depend_on_its_unit() {
        for scale in [1e-3f32, 1.0, 1e3] {
            let flat = picture(scale, 0.0);
            let map = affine_map(&flat.iter().collect::<Vec<_>>());
            let map = map.unwrap_or_else(|| panic!("scale {scale}: no affine map"));
            let at = Vec3::new(1.0, 0.25, 0.75) * scale - map.origin;
            let uv = [
                map.grad_u.dot(at) + map.uv0[0],
                map.grad_v.dot(at) + map.uv0[1],
            ];
            assert!(
                (uv[0] - 0.25).abs() < 1e-4 && (uv[1] - 0.75).abs() < 1e-4,
                "{uv:?}"
            );
            let bent = picture(scale, 0.01);
            assert!(
                affine_map(&bent.iter().collect::<Vec<_>>()).is_none(),
                "{scale}"
            );
        }
    }
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

    /// The lobe's share is its light over the panorama's, summed over the pixels before
    /// dividing (a bright pixel counts for more), and 0 where the group has no light.
    #[test]
    fn a_lobes_share_is_its_light_over_the_panoramas() {
        let grey = |v: f32| Vec3::splat(v);
        let share = lobe_share(&[grey(0.1), grey(0.0)], &[grey(0.2), grey(0.6)]);
        assert!((share - 0.125).abs() < 1e-6, "{share}");
        assert_eq!(lobe_share(&[grey(0.1)], &[grey(0.0)]), 0.0);
        assert_eq!(lobe_share(&[], &[]), 0.0);
    }
}
