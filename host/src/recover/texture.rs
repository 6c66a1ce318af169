//! Stages 3 and 5 on the host: the renders that texture detection and the diffuse-map
//! solve need. The statistic and the solver are the core's (`relume_core::stages::texture`
//! and `texture_map`).

use glam::{Vec2, Vec3};
use relume_core::fit;
use relume_core::geometry::Surface;
use relume_core::math::luminance;
use relume_core::stages::diffuse::MAX_DIFFUSE_REFLECTANCE;
use relume_core::stages::texture;
use relume_core::stages::texture_map::{self, MapObservation, FOOTPRINT_SAMPLES};

use super::model::{GroupModel, MapLobe};
use super::pixels::{self, PurePixel};
use super::Recovery;
use crate::error::Error;

/// A recovered diffuse map (row 0 = v 1), square.
#[derive(Clone, Debug)]
pub struct RecoveredMap {
    pub side: u32,
    pub texels: Vec<Vec3>,
}

/// How a map was recovered, for the report.
pub struct MapSummary {
    pub side: u32,
    pub pixels: usize,
    pub highlights: usize,
    pub shadows: usize,
    pub unseen_texels: usize,
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
/// of the recovered scene. Sets the group's model to the textured one and returns what was
/// done.
pub fn recover_map(rec: &mut Recovery, g: usize, spp: u32, seed: u64) -> Result<MapSummary, Error> {
    let pixels = pixels::of_group(&rec.pure, g);
    let uvs: Vec<Option<[Vec2; FOOTPRINT_SAMPLES]>> =
        rec.with_scene(1, seed, |_, scene, observed, _| {
            pixels
                .iter()
                .map(|p| pixels::pixel_uvs(scene, observed.views, p))
                .collect()
        })?;
    // The stand-in's diffuse reflectance, as a constant map to render E against.
    let (rho_d, _) = rec.models[g].reflectances();
    let start = Vec3::new(rho_d[0] as f32, rho_d[1] as f32, rho_d[2] as f32).clamp(
        Vec3::splat(0.02),
        Vec3::splat(MAX_DIFFUSE_REFLECTANCE as f32),
    );
    let map = rec.maps.len();
    rec.maps.push(RecoveredMap {
        side: 1,
        texels: vec![start],
    });
    rec.models[g] = GroupModel::Textured {
        map,
        lobe: MapLobe::of_stand_in(&rec.models[g]),
    };
    let settings_seed = seed ^ 0x7E47;
    let full = render_once(rec, &pixels, spp, settings_seed)?;
    // The specular part alone: the same paths (same seed) with a black map.
    rec.maps[map].texels[0] = Vec3::ZERO;
    let specular = render_once(rec, &pixels, spp, settings_seed)?;

    let gains: Vec<Vec3> = full
        .iter()
        .zip(&specular)
        .map(|(f, s)| ((*f - *s) / start).max(Vec3::ZERO))
        .collect();
    let gain_floor =
        fit::SHADOW_FRACTION * median(gains.iter().map(|v| luminance(*v) as f64).collect());
    let (mut highlights, mut shadows) = (0, 0);
    let observations: Vec<MapObservation> = pixels
        .iter()
        .enumerate()
        .filter_map(|(i, p)| {
            let uv = uvs[i]?;
            let real = pixels::real_value(&rec.real, &rec.views, p);
            let highlight =
                luminance(specular[i]) as f64 > fit::HIGHLIGHT_FRACTION * luminance(real) as f64;
            let shadow = (luminance(gains[i]) as f64) <= gain_floor;
            highlights += highlight as usize;
            shadows += (shadow && !highlight) as usize;
            Some(MapObservation {
                uv,
                gain: gains[i],
                target: real - specular[i],
                weight: if highlight || shadow { 0.0 } else { 1.0 },
            })
        })
        .collect();
    let side = texture_map::map_side(pixels.len());
    let n = (side * side) as usize;
    let mut texels = vec![start; n];
    let (mut numerator, mut denominator) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
    let unseen_texels = texture_map::solve_map(
        &observations,
        side,
        side,
        MAX_DIFFUSE_REFLECTANCE as f32,
        &mut texels,
        &mut numerator,
        &mut denominator,
    )
    .map_err(|e| Error::core(format!("recovering the map of group {g}"), e))?;
    rec.maps[map] = RecoveredMap { side, texels };
    Ok(MapSummary {
        side,
        pixels: pixels.len(),
        highlights,
        shadows,
        unseen_texels,
    })
}

fn render_once(
    rec: &mut Recovery,
    pixels: &[PurePixel],
    spp: u32,
    seed: u64,
) -> Result<Vec<Vec3>, Error> {
    rec.with_scene(spp, seed, |pool, scene, observed, settings| {
        pixels::render_pixels(pool, scene, observed.views, pixels, settings)
    })
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
        .triangles
        .iter()
        .filter(|t| t.surface == Surface::Group(g as u16))
        .collect();
    let largest = triangles
        .iter()
        .max_by(|a, b| a.area().total_cmp(&b.area()))?;
    let p = largest.v.map(|v| v);
    let uv = largest.uv.map(|t| [t.x, t.y]);
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = a * c - b * b;
    if det.abs() <= 1e-10 || det.is_nan() {
        return None;
    }
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
                && normal.dot(q).abs() < 1e-4
        })
    });
    fits.then_some(affine)
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
