//! Stage 5: a group's diffuse map, `T = (I_real - I_specular) / E`, solved at the map's
//! resolution rather than pixel by pixel.
//!
//! The host renders each pure pixel `p` of the group twice with the current map (the
//! group's full model, and its specular part alone) and so knows, per channel, how much
//! radiance one unit of diffuse reflectance sends to the camera there: `e_p`, the
//! irradiance over pi, which carries the full global illumination. The renderer samples
//! the map bilinearly (`material::texture::TextureGrid::taps`), so the observation is
//! `e_p * sum_k a_pk T_k = I_p - S_p`. Dividing pixel by pixel and splatting would blur
//! the map by that bilinear kernel; instead the weighted least-squares problem over the
//! texels is solved by SIRT (simultaneous iterative reconstruction: each texel moves by
//! its observations' residuals over their summed weights), which converges monotonically
//! without a step size to tune. Texels no pixel sees are filled from their neighbours.
//!
//! Pixels are removed by the weights the host gives: one that receives little light says
//! little about `T`, and the host leaves out highlights where the map must not depend on
//! the lobe.

use crate::error::{check_capacity, Error};
use crate::material::texture::{TextureGrid, Wrap};
use crate::math::{Vec2, Vec3};

/// The smallest and largest side of a recovered map.
pub const MIN_SIDE: u32 = 4;
pub const MAX_SIDE: u32 = 1024;

/// Texels per pixel the map is solved from (its group's pure pixels and those on its
/// border): two, about 1.4 per pixel along each side. The pixels fall on the texel grid
/// at every offset; at one texel per pixel the two grids beat, and a map of the pixels'
/// own resolution is a poor sampling of what they saw. Above one, the extra texels are
/// underdetermined, but the solver starts from a uniform map and stops after
/// [`SOLVER_ITERATIONS`], which keeps what the pixels do not pin smooth. Simulated on the
/// references' pictures (ideal pixels of a picture 59 pixels wide at three angles),
/// 1.5-2.25 texels per pixel read best and one the worst (docs/recovery.md, "Map PSNR").
/// Counted over the pure pixels alone, a picture at 64 px (a third of its pixels on its
/// border) had 1.3 a pixel ("The map's side counts its border").
pub const TEXELS_PER_PIXEL: f64 = 2.0;

/// Iterations of the solver: enough for the bilinear kernel's coupling to settle (the
/// residual stops changing in the fourth digit on the references well before this).
pub const SOLVER_ITERATIONS: u32 = 60;

/// Points per pixel at which the map is sampled: a pixel's value is the map averaged over
/// its footprint (the renderer's box filter), which one centre lookup would misplace by up
/// to a texel wherever the map has detail; a 2x2 grid at the quarter points follows it.
pub const FOOTPRINT_SAMPLES: usize = 4;

/// Sub-pixel offsets (in pixels, from the pixel's corner) of the footprint samples.
pub const FOOTPRINT_OFFSETS: [[f32; 2]; FOOTPRINT_SAMPLES] =
    [[0.25, 0.25], [0.75, 0.25], [0.25, 0.75], [0.75, 0.75]];

/// What the map must explain at one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapObservation {
    /// Texture coordinates at the pixel's [`FOOTPRINT_OFFSETS`].
    pub uv: [Vec2; FOOTPRINT_SAMPLES],
    /// Radiance per unit of diffuse reflectance, per channel (`E / pi`).
    pub gain: Vec3,
    /// The diffuse radiance to explain: `I_real - I_specular`.
    pub target: Vec3,
    /// Confidence in `[0, 1]` (0 removes the pixel: a shadow, a highlight).
    pub weight: f32,
}

/// The side of the square map for a group seen in `pixels` pixels (pure or on its
/// border) whose texture coordinates cover `uv_coverage` of the map's [0, 1]^2 (its
/// faces' areas in (u, v), taken as 1 above 1 and as [`MIN_UV_COVERAGE`] below it):
/// [`TEXELS_PER_PIXEL`] texels a pixel where the group lies. A group laid over a corner
/// of its map (a texture atlas) needs a finer map for as many: over a quarter of [0, 1]^2
/// it had a quarter of the texels. Square, so that RADIANCE's `colorpict` (which scales a
/// picture's shorter side to 1) maps it as the truth maps are mapped, with one remapping
/// for both axes.
pub fn map_side(pixels: usize, uv_coverage: f64) -> u32 {
    let coverage = if uv_coverage >= 1.0 {
        1.0
    } else {
        uv_coverage.max(MIN_UV_COVERAGE)
    };
    let texels = (pixels as f64 * TEXELS_PER_PIXEL / coverage).max(1.0);
    (libm::round(libm::sqrt(texels)) as u32).clamp(MIN_SIDE, MAX_SIDE)
}

/// The side of a tiled map ([`Wrap::Repeat`]) over `repeats` tiles (its group's area in
/// (u, v); at least 1, NaN as 1), seen in `pixels` pure pixels. Each repeat is seen at
/// other sub-pixel offsets, so the repeats add detail, but not as much as a picture
/// `repeats` times larger: [`map_side`] over all the pixels assumes they do, over one
/// repeat's pixels that they add none. The side between the two (their geometric mean,
/// `pixels / sqrt(repeats)`) read best of the three on a picture tiled 2x2 and 4x4 (26.7
/// and 24.7 dB, against 26.0 / 22.6 and 26.5 / 23.1; docs/recovery.md, "Tiled textures").
pub fn tiled_map_side(pixels: usize, repeats: f64) -> u32 {
    let repeats = if repeats >= 1.0 { repeats } else { 1.0 };
    map_side((pixels as f64 / libm::sqrt(repeats)) as usize, 1.0)
}

/// The least coverage [`map_side`] counts with (a NaN too): below it the map would reach
/// `MAX_SIDE` from a handful of pixels.
pub const MIN_UV_COVERAGE: f64 = 1e-4;

/// Solves for the `width x height` map in `texels` (row 0 = v 1), starting from its
/// content, clamped to reflectances in `[0, max_reflectance]`. `numerator` and
/// `denominator` are scratch of the same length. Returns how many texels no observation
/// touched (filled from their neighbours). An empty map or a bound that is not a finite
/// non-negative reflectance is an error.
pub fn solve_map(
    observations: &[MapObservation],
    grid: TextureGrid,
    max_reflectance: f32,
    texels: &mut [Vec3],
    numerator: &mut [Vec3],
    denominator: &mut [Vec3],
) -> Result<usize, Error> {
    let (width, height) = (grid.width, grid.height);
    if width == 0 || height == 0 {
        return Err(Error::InvalidValue {
            what: "texture map: a side is 0",
        });
    }
    if !(max_reflectance.is_finite() && max_reflectance >= 0.0) {
        return Err(Error::InvalidValue {
            what: "texture map: the largest reflectance is not finite and non-negative",
        });
    }
    let n = (width as usize)
        .checked_mul(height as usize)
        .ok_or(Error::InvalidValue {
            what: "texture map: width x height overflows",
        })?;
    check_capacity("config::MAX_TEXELS", crate::config::MAX_TEXELS, n)?;
    for (what, len) in [
        ("texture map texels", texels.len()),
        ("texture map numerator scratch", numerator.len()),
        ("texture map denominator scratch", denominator.len()),
    ] {
        if len < n {
            return Err(Error::BufferTooSmall {
                what,
                needed: n,
                got: len,
            });
        }
    }
    let (texels, numerator, denominator) =
        (&mut texels[..n], &mut numerator[..n], &mut denominator[..n]);
    // The start within the bound too (NaN as 0): a texel no observation steps keeps it, and
    // a NaN start would make every residual NaN.
    for t in texels.iter_mut() {
        *t = Vec3::from_array(t.to_array().map(
            |x| {
                if x > 0.0 {
                    x.min(max_reflectance)
                } else {
                    0.0
                }
            },
        ));
    }
    let usable = |o: &MapObservation| {
        o.weight > 0.0
            && o.weight.is_finite()
            && o.uv.iter().all(|uv| uv.is_finite())
            && o.gain.is_finite()
            && o.target.is_finite()
    };
    // The taps of the footprint average: each sample's bilinear taps at a quarter weight.
    let taps = |o: &MapObservation| {
        let mut all = [(0usize, 0.0f32); 4 * FOOTPRINT_SAMPLES];
        for (s, uv) in o.uv.iter().enumerate() {
            for (t, (k, a)) in grid.taps(*uv).into_iter().enumerate() {
                all[4 * s + t] = (k, a / FOOTPRINT_SAMPLES as f32);
            }
        }
        all
    };

    // The summed weights of each texel do not change between iterations.
    denominator.fill(Vec3::ZERO);
    for o in observations.iter().filter(|o| usable(o)) {
        for (k, a) in taps(o) {
            denominator[k] += o.gain * o.gain * (a * o.weight);
        }
    }
    for _ in 0..SOLVER_ITERATIONS {
        numerator.fill(Vec3::ZERO);
        for o in observations.iter().filter(|o| usable(o)) {
            let taps = taps(o);
            let predicted = taps
                .iter()
                .fold(Vec3::ZERO, |sum, &(k, a)| sum + texels[k] * a)
                * o.gain;
            let residual = (o.target - predicted) * o.gain * o.weight;
            for (k, a) in taps {
                numerator[k] += residual * a;
            }
        }
        for k in 0..n {
            for c in 0..3 {
                // Past f32's range (a gain of 1e20 squares to infinity) the step is NaN,
                // which a clamp lets through: such a texel keeps its value.
                let step = numerator[k][c] / denominator[k][c];
                if denominator[k][c] > 0.0 && step.is_finite() {
                    texels[k][c] = (texels[k][c] + step).clamp(0.0, max_reflectance);
                }
            }
        }
    }
    Ok(fill_unseen(grid, texels, denominator))
}

/// A `width x height` map's value at a pixel as [`solve_map`] models it: the mean of its
/// bilinear lookups at the pixel's [`FOOTPRINT_OFFSETS`] (`uv`).
pub fn footprint_value(texels: &[Vec3], grid: TextureGrid, uv: &[Vec2; FOOTPRINT_SAMPLES]) -> Vec3 {
    let mut value = Vec3::ZERO;
    for &p in uv {
        for (k, a) in grid.taps(p) {
            value += texels.get(k).copied().unwrap_or(Vec3::ZERO) * (a / FOOTPRINT_SAMPLES as f32);
        }
    }
    value
}

/// The sums that scale a unit specular lobe to what a map leaves unexplained: per pixel the
/// residual `r = I_real - T E` and the unit lobe's part `b`, summed over channels. The
/// best white specularity is `s = sum r.b / sum b.b` (at least 0).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LobeScaleSums {
    pub rb: f64,
    pub bb: f64,
    pub rr: f64,
    pub pixels: u32,
}

impl LobeScaleSums {
    pub fn add(&mut self, residual: Vec3, lobe: Vec3) {
        for c in 0..3 {
            let (r, b) = (residual[c] as f64, lobe[c] as f64);
            self.rb += r * b;
            self.bb += b * b;
            self.rr += r * r;
        }
        self.pixels = self.pixels.saturating_add(1);
    }

    /// The best specularity (0 where the lobe cannot help) and the sum of squared
    /// residuals it leaves.
    pub fn best(&self) -> (f64, f64) {
        let s = if self.bb > 0.0 {
            (self.rb / self.bb).max(0.0)
        } else {
            0.0
        };
        (s, self.sse(s))
    }

    /// The sum of squared residuals under specularity `s`.
    pub fn sse(&self, s: f64) -> f64 {
        (self.rr - 2.0 * s * self.rb + s * s * self.bb).max(0.0)
    }
}

/// Gives every texel no observation touched (zero weight in `seen`) the mean of its
/// already known 4-neighbours, growing inwards from the known texels ring by ring.
fn fill_unseen(grid: TextureGrid, texels: &mut [Vec3], seen: &mut [Vec3]) -> usize {
    let (w, h) = (grid.width as usize, grid.height as usize);
    // A tiled map's edges are neighbours across its seam.
    let tiled = grid.wrap == Wrap::Repeat;
    let known = |s: &Vec3| s.max_element() > 0.0;
    let unseen = seen.iter().filter(|s| !known(s)).count();
    if unseen == texels.len() {
        return unseen;
    }
    loop {
        let mut changed = false;
        // Mark texels filled in this ring with a negative weight so that they do not
        // feed the same ring (the result would depend on the scan order).
        for j in 0..h {
            for i in 0..w {
                let k = j * w + i;
                if known(&seen[k]) || seen[k].x < 0.0 {
                    continue;
                }
                let mut sum = Vec3::ZERO;
                let mut count = 0.0f32;
                let neighbours = [
                    if i > 0 {
                        Some(k - 1)
                    } else {
                        tiled.then(|| k + w - 1)
                    },
                    if i + 1 < w {
                        Some(k + 1)
                    } else {
                        tiled.then(|| k + 1 - w)
                    },
                    if j > 0 {
                        Some(k - w)
                    } else {
                        tiled.then(|| k + (h - 1) * w)
                    },
                    if j + 1 < h {
                        Some(k + w)
                    } else {
                        tiled.then_some(i)
                    },
                ];
                for m in neighbours.into_iter().flatten() {
                    if known(&seen[m]) {
                        sum += texels[m];
                        count += 1.0;
                    }
                }
                if count > 0.0 {
                    texels[k] = sum / count;
                    seen[k] = Vec3::splat(-1.0);
                    changed = true;
                }
            }
        }
        if !changed {
            return unseen;
        }
        for s in seen.iter_mut().filter(|s| s.x < 0.0) {
            *s = Vec3::ONE;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Sampler;
    use std::vec;
    use std::vec::Vec;

    fn truth_map(w: u32, h: u32) -> Vec<Vec3> {
        (0..w * h)
            .map(|k| {
                let (i, j) = (k % w, k / w);
                Vec3::new(
                    0.1 + 0.8 * ((i + j) % 2) as f32,
                    0.2 + 0.05 * i as f32,
                    0.7 - 0.04 * j as f32,
                )
            })
            .collect()
    }

    /// A `w x h` grid read as the format reads maps, clamped.
    fn grid(width: u32, height: u32) -> TextureGrid {
        TextureGrid {
            width,
            height,
            wrap: Wrap::Clamp,
        }
    }

    fn lookup(map: &[Vec3], grid: TextureGrid, uv: Vec2) -> Vec3 {
        grid.taps(uv)
            .iter()
            .fold(Vec3::ZERO, |s, &(k, a)| s + map[k] * a)
    }

    /// Observations of `map` at `count` random points of `[lo, hi]^2` with random gains.
    fn observe(map: &[Vec3], w: u32, h: u32, count: u32, lo: f32, hi: f32) -> Vec<MapObservation> {
        observe_on(map, grid(w, h), count, lo, hi)
    }

    /// [`observe`] on any grid (a tiled one reads `[lo, hi]^2` past [0, 1]).
    fn observe_on(
        map: &[Vec3],
        g: TextureGrid,
        count: u32,
        lo: f32,
        hi: f32,
    ) -> Vec<MapObservation> {
        let mut rng = Sampler::for_pixel_sample(7, 0, 0, 0);
        (0..count)
            .map(|_| {
                let [a, b] = rng.next_2d();
                let uv = Vec2::new(lo + (hi - lo - 0.1) * a, lo + (hi - lo - 0.1) * b);
                let [g0, g1] = rng.next_2d();
                let gain = Vec3::new(0.2 + g0, 0.3 + g1, 0.5 + 0.5 * g0);
                // A pixel a tenth of the map wide.
                let uvs = FOOTPRINT_OFFSETS.map(|[dx, dy]| uv + Vec2::new(dx, dy) * 0.1);
                let seen = uvs.iter().fold(Vec3::ZERO, |s, uv| s + lookup(map, g, *uv))
                    / FOOTPRINT_SAMPLES as f32;
                MapObservation {
                    uv: uvs,
                    gain,
                    target: gain * seen,
                    weight: 1.0,
                }
            })
            .collect()
    }

    fn solve(obs: &[MapObservation], w: u32, h: u32) -> (Vec<Vec3>, usize) {
        solve_on(obs, grid(w, h))
    }

    fn solve_on(obs: &[MapObservation], g: TextureGrid) -> (Vec<Vec3>, usize) {
        let n = (g.width * g.height) as usize;
        let mut map = vec![Vec3::splat(0.5); n];
        let (mut a, mut b) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
        let unseen = solve_map(obs, g, 1.0, &mut map, &mut a, &mut b).unwrap();
        (map, unseen)
    }

    fn worst_texel(map: &[Vec3], truth: &[Vec3]) -> f32 {
        map.iter()
            .zip(truth)
            .map(|(a, b)| (*a - *b).abs().max_element())
            .fold(0.0f32, f32::max)
    }

    /// A texture tiled over three repeats each way is one map seen nine times: every
    /// observation lands on its tile's texels, the seam's included.
    #[test]
    fn a_tiled_map_pools_its_repeats() {
        let (w, h) = (8, 6);
        let truth = truth_map(w, h);
        let tiled = TextureGrid {
            wrap: Wrap::Repeat,
            ..grid(w, h)
        };
        let obs = observe_on(&truth, tiled, 4000, 0.0, 3.0);
        let (map, unseen) = solve_on(&obs, tiled);
        assert_eq!(unseen, 0);
        let worst = worst_texel(&map, &truth);
        assert!(worst < 0.02, "worst texel error {worst}");
        // The same pixels read as one clamped picture over [0, 3]^2 fit no map.
        let (clamped, _) = solve(&obs, w, h);
        assert!(worst_texel(&clamped, &truth) > 0.1);
    }

    /// A tiled map's unseen texels are filled across its seam too: an unseen column at
    /// the left edge takes the right edge's values, its neighbour there.
    #[test]
    fn a_tiled_maps_unseen_texels_fill_across_its_seam() {
        let (w, h) = (4u32, 2u32);
        let tiled = TextureGrid {
            wrap: Wrap::Repeat,
            ..grid(w, h)
        };
        let mut texels = vec![Vec3::ZERO; 8];
        let mut seen = vec![Vec3::ZERO; 8];
        for j in 0..h as usize {
            // Columns 2 and 3 seen: column 3 is 0.9, column 2 0.1.
            for (i, value) in [(2usize, 0.1f32), (3, 0.9)] {
                texels[j * 4 + i] = Vec3::splat(value);
                seen[j * 4 + i] = Vec3::ONE;
            }
        }
        assert_eq!(fill_unseen(tiled, &mut texels, &mut seen), 4);
        // Column 0 borders column 3 across the seam, column 1 column 2.
        assert_eq!(texels[0], Vec3::splat(0.9));
        assert_eq!(texels[1], Vec3::splat(0.1));
    }

    #[test]
    fn recovers_a_map_that_the_observations_determine() {
        let (w, h) = (8, 6);
        let truth = truth_map(w, h);
        let obs = observe(&truth, w, h, 4000, 0.0, 1.0);
        let (map, unseen) = solve(&obs, w, h);
        assert_eq!(unseen, 0);
        let worst = worst_texel(&map, &truth);
        assert!(worst < 0.02, "worst texel error {worst}");
    }

    #[test]
    fn zero_weight_pixels_are_ignored_and_unseen_texels_filled_from_neighbours() {
        let (w, h) = (8, 8);
        let truth = vec![Vec3::splat(0.3); 64];
        // Only the left half is observed; a "highlight" pixel with weight 0 lies there too.
        let mut obs = observe(&truth, w, h, 3000, 0.0, 0.45);
        obs.push(MapObservation {
            uv: [Vec2::new(0.2, 0.2); FOOTPRINT_SAMPLES],
            gain: Vec3::ONE,
            target: Vec3::splat(50.0),
            weight: 0.0,
        });
        let (map, unseen) = solve(&obs, w, h);
        assert!(unseen > 20, "{unseen}");
        for t in &map {
            assert!((*t - Vec3::splat(0.3)).abs().max_element() < 0.01, "{t}");
        }
    }

    #[test]
    fn sides_follow_the_pixel_count_within_bounds() {
        assert_eq!(map_side(5_000, 1.0), 100);
        assert_eq!(map_side(3, 1.0), MIN_SIDE);
        assert_eq!(map_side(usize::MAX / 2, 1.0), MAX_SIDE);
    }

    #[test]
    fn a_group_over_part_of_its_map_gets_as_many_texels_where_it_lies() {
        // Over a quarter of [0, 1]^2: twice the side, the same texels over the group.
        assert_eq!(map_side(5_000, 0.25), 200);
        // Faces given twice over one region count once; no coverage counts as the least.
        assert_eq!(map_side(5_000, 2.0), 100);
        assert_eq!(map_side(5_000, f64::NAN), map_side(5_000, MIN_UV_COVERAGE));
        assert_eq!(map_side(5_000, 0.0), MAX_SIDE);
    }

    #[test]
    fn a_tiled_map_takes_the_side_between_all_its_pixels_and_one_repeats() {
        // 4 x 4 repeats of 5,000 pixels: between 100 (all) and 25 (one repeat's).
        assert_eq!(tiled_map_side(5_000, 16.0), 50);
        assert_eq!(tiled_map_side(5_000, 4.0), 71);
        // One repeat or less, or none known: the map over all the pixels.
        for repeats in [1.0, 0.5, 0.0, f64::NAN] {
            assert_eq!(
                tiled_map_side(5_000, repeats),
                map_side(5_000, 1.0),
                "{repeats}"
            );
        }
    }

    #[test]
    fn short_buffers_are_an_error() {
        let mut small = vec![Vec3::ZERO; 3];
        let mut a = vec![Vec3::ZERO; 16];
        let mut b = vec![Vec3::ZERO; 16];
        assert!(solve_map(&[], grid(4, 4), 1.0, &mut small, &mut a, &mut b).is_err());
    }

    #[test]
    fn an_empty_map_or_a_bad_bound_is_an_error_not_a_panic() {
        let obs = observe(&truth_map(4, 4), 4, 4, 50, 0.0, 1.0);
        let mut buffers = [
            vec![Vec3::splat(0.5); 16],
            vec![Vec3::ZERO; 16],
            vec![Vec3::ZERO; 16],
        ];
        let [map, a, b] = &mut buffers;
        // A side of 0 once indexed an empty buffer; a NaN bound once reached `clamp`.
        assert!(solve_map(&obs, grid(0, 4), 1.0, map, a, b).is_err());
        assert!(solve_map(&obs, grid(4, 0), 1.0, map, a, b).is_err());
        for bound in [f32::NAN, -0.5, f32::INFINITY] {
            assert!(
                solve_map(&obs, grid(4, 4), bound, map, a, b).is_err(),
                "{bound}"
            );
        }
        assert!(solve_map(&obs, grid(4, 4), 1.0, map, a, b).is_ok());
    }

    #[test]
    fn gains_and_weights_past_f32s_range_leave_no_nan() {
        // A finite gain of 1e20 squared to infinity and a weight of infinity once made
        // every texel NaN, past the clamp the doc promises (fuzzing the core, 2026-12-06).
        let observation = |gain: f32, weight: f32| MapObservation {
            uv: [Vec2::splat(0.5); FOOTPRINT_SAMPLES],
            gain: Vec3::splat(gain),
            target: Vec3::ONE,
            weight,
        };
        for o in [observation(1e20, 1.0), observation(1.0, f32::INFINITY)] {
            let mut map = vec![Vec3::splat(0.5); 4];
            let (mut a, mut b) = (vec![Vec3::ZERO; 4], vec![Vec3::ZERO; 4]);
            assert!(solve_map(&[o], grid(2, 2), 1.0, &mut map, &mut a, &mut b).is_ok());
            assert!(
                map.iter()
                    .flat_map(|t| t.to_array())
                    .all(|x| (0.0..=1.0).contains(&x)),
                "{o:?}: {map:?}"
            );
        }
    }

    /// The map comes back within `[0, max_reflectance]` whatever it starts from: a start
    /// above the bound (or NaN) was kept by every texel no usable observation stepped, and
    /// a NaN start made every observation's residual NaN, so that no texel moved at all.
    #[test]
    fn the_map_is_within_its_bound_whatever_it_starts_from() {
        let obs = observe(&truth_map(4, 4), 4, 4, 200, 0.0, 1.0);
        let unusable = [MapObservation {
            weight: 0.0,
            ..obs[0]
        }];
        for (observations, start) in [
            (&obs[..], f32::NAN),
            (&unusable[..], 2.0),
            (&unusable[..], f32::NAN),
            (&[][..], -1.0),
        ] {
            let mut map = vec![Vec3::splat(start); 16];
            let (mut a, mut b) = (vec![Vec3::ZERO; 16], vec![Vec3::ZERO; 16]);
            solve_map(observations, grid(4, 4), 0.9, &mut map, &mut a, &mut b).unwrap();
            assert!(
                map.iter()
                    .flat_map(|t| t.to_array())
                    .all(|x| (0.0..=0.9).contains(&x)),
                "start {start}, {} observations: {map:?}",
                observations.len()
            );
        }
    }

    /// A picture with detail at every scale the pixels can hold: a checker of 7 x 7
    /// squares with a disc over it.
    fn picture(u: f32, v: f32) -> Vec3 {
        let square = ((u * 7.0) as i32 + (v * 7.0) as i32) % 2 == 0;
        let (du, dv) = (u - 0.4, v - 0.6);
        if du * du + dv * dv < 0.06 {
            Vec3::new(0.8, 0.3, 0.2)
        } else if square {
            Vec3::splat(0.7)
        } else {
            Vec3::splat(0.15)
        }
    }

    /// The RMS error against [`picture`] of a map solved from the pure pixels of a
    /// `pixels x pixels` grid of box-filtered pixels that see it turned by `angle`, with
    /// `side(pure pixels)` texels a side.
    fn map_error_from_pixels(pixels: u32, angle: f32, side: impl Fn(usize) -> u32) -> f32 {
        let (c, s) = (libm::cosf(angle), libm::sinf(angle));
        let n = pixels as f32;
        let uv_at = |x: f32, y: f32| {
            let (a, b) = (x / n - 0.5, y / n - 0.5);
            Vec2::new(0.5 + c * a - s * b, 0.5 - (s * a + c * b))
        };
        let inside = |uv: Vec2| (0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y);
        let mut obs = Vec::new();
        for y in 0..pixels {
            for x in 0..pixels {
                let (x, y) = (x as f32, y as f32);
                let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)];
                if !corners.iter().all(|(a, b)| inside(uv_at(x + a, y + b))) {
                    continue;
                }
                // The pixel's box filter, by 8 x 8 lookups of the picture.
                let mut seen = Vec3::ZERO;
                for k in 0..64 {
                    let (a, b) = ((k % 8) as f32 + 0.5, (k / 8) as f32 + 0.5);
                    let uv = uv_at(x + a / 8.0, y + b / 8.0);
                    seen += picture(uv.x, uv.y);
                }
                obs.push(MapObservation {
                    uv: FOOTPRINT_OFFSETS.map(|[dx, dy]| uv_at(x + dx, y + dy)),
                    gain: Vec3::ONE,
                    target: seen / 64.0,
                    weight: 1.0,
                });
            }
        }
        let side = side(obs.len());
        let (map, _) = solve(&obs, side, side);
        let fine = 200;
        let mut sum = 0.0;
        for k in 0..fine * fine {
            let uv = Vec2::new(
                ((k % fine) as f32 + 0.5) / fine as f32,
                ((k / fine) as f32 + 0.5) / fine as f32,
            );
            sum +=
                (lookup(&map, grid(side, side), uv) - picture(uv.x, uv.y)).length_squared() / 3.0;
        }
        libm::sqrtf(sum / (fine * fine) as f32)
    }

    #[test]
    fn two_texels_per_pixel_hold_more_of_a_picture_than_one() {
        let one_per_pixel = |pure: usize| libm::roundf(libm::sqrtf(pure as f32)) as u32;
        // The picture covers the map's whole square.
        let map_side = |pure: usize| map_side(pure, 1.0);
        let error = |angle, side: &dyn Fn(usize) -> u32| map_error_from_pixels(40, angle, side);
        // The picture turned against the pixels: the texel and pixel grids beat.
        for angle in [0.13, 0.4] {
            let (one, two) = (error(angle, &one_per_pixel), error(angle, &map_side));
            assert!(two < 0.95 * one, "angle {angle}: {two} against {one}");
        }
        // Square to the pixels, its texels on them one for one: the one case where a map
        // of the pixels' own resolution is the better sampling, and not by much.
        let (one, two) = (error(0.0, &one_per_pixel), error(0.0, &map_side));
        assert!(two < 1.05 * one, "square: {two} against {one}");
    }

    #[test]
    fn a_pixels_footprint_value_is_its_lookups_mean() {
        // Columns 0 and 1 of a 2x1 map, dark and bright: a footprint over the middle
        // takes their mean; a uniform map gives its value anywhere.
        let texels = [Vec3::splat(0.2), Vec3::splat(0.6)];
        let middle = [Vec2::new(0.5, 0.5); FOOTPRINT_SAMPLES];
        assert!((footprint_value(&texels, grid(2, 1), &middle) - Vec3::splat(0.4)).length() < 1e-6);
        let uniform = [Vec3::splat(0.3); 4];
        let corner = [Vec2::new(0.9, 0.1); FOOTPRINT_SAMPLES];
        assert!(
            (footprint_value(&uniform, grid(2, 2), &corner) - Vec3::splat(0.3)).length() < 1e-6
        );
    }

    #[test]
    fn the_lobe_scale_recovers_the_specularity_and_never_goes_negative() {
        let mut sums = LobeScaleSums::default();
        for i in 0..20 {
            let b = Vec3::new(1.0, 0.9, 1.1) * (0.5 + i as f32 * 0.1);
            sums.add(b * 0.05, b);
        }
        let (s, sse) = sums.best();
        assert!((s - 0.05).abs() < 1e-6 && sse < 1e-9, "{s} {sse}");
        let mut against = LobeScaleSums::default();
        against.add(Vec3::splat(-0.1), Vec3::splat(1.0));
        assert_eq!(against.best(), (0.0, against.sse(0.0)));
        assert!((against.sse(0.0) - 0.03).abs() < 1e-9);
    }
}
