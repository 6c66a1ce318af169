//! Diffuse maps: RGB texels in one lent pool, looked up by bilinear interpolation between
//! texel centres, clamped at the border (bench/README.md, "Texture sampling"): texel
//! `(i, j)` has its centre at `u = (i + 0.5) / W`, `v = 1 - (j + 0.5) / H`; row 0 is v = 1.
//! Texture coordinates outside [0, 1] are clamped to it ([`Wrap::Clamp`], the format's
//! lookup), so beyond the outer texel centres a lookup returns the border texels; a map
//! laid over its group as tiles ([`Wrap::Repeat`]) reads coordinate `u` at `u - floor(u)`
//! and blends its last column with its first. NaN coordinates count as 0.
//!
//! OWNER: material helper.

use crate::config;
use crate::error::{check_capacity, Error};
use crate::math::{self, Vec2, Vec3};

/// Index into [`Textures`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureId(pub u16);

/// How a texture reads coordinates outside [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    /// Held to [0, 1]: past the outer texel centres, the border texels (scene-format.md).
    #[default]
    Clamp,
    /// Tiled: `u` reads as `u - floor(u)`, and the last texel blends into the first, so
    /// that a texture repeated over a floor by coordinates from 0 to 4 has no seam.
    Repeat,
}

/// A texture's texel grid and how it reads coordinates outside [0, 1]: what a lookup
/// needs, and what the recovery of a map (stage 5) must invert.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureGrid {
    pub width: u32,
    pub height: u32,
    pub wrap: Wrap,
}

/// Where one texture lies in the texel pool.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureInfo {
    pub grid: TextureGrid,
    /// First texel (row 0, column 0) in the pool; rows follow each other.
    pub offset: usize,
}

/// All textures of a scene, over lent slices.
#[derive(Clone, Copy, Debug, Default)]
pub struct Textures<'a> {
    infos: &'a [TextureInfo],
    texels: &'a [Vec3],
}

/// A texture coordinate forced into [0, 1] (NaN to 0).
#[inline]
fn clamp_unit(x: f32) -> f32 {
    if x >= 0.0 {
        x.min(1.0)
    } else {
        0.0
    }
}

/// The fractional part of a texture coordinate, in [0, 1) (NaN and infinities to 0).
#[inline]
fn repeat_unit(x: f32) -> f32 {
    let f = x - math::floor(x);
    if (0.0..1.0).contains(&f) {
        f
    } else {
        0.0
    }
}

/// The two texel indices around continuous texel coordinate `x` (texel centres at
/// integers) and the weight of the second, clamped to `[0, n - 1]`.
#[inline]
fn axis(x: f32, n: u32) -> (usize, usize, f32) {
    let last = n.saturating_sub(1) as usize;
    let f = math::floor(x);
    let t = x - f;
    if f < 0.0 {
        return (0, 0, 0.0);
    }
    let i0 = (f as usize).min(last);
    let i1 = (i0 + 1).min(last);
    (i0, i1, t)
}

/// [`axis`] for a tiled texture: `x` in `[-0.5, n - 0.5)`, and the texel after the last
/// is the first (before the first, the last).
#[inline]
fn axis_repeat(x: f32, n: u32) -> (usize, usize, f32) {
    let n = n.max(1) as usize;
    let f = math::floor(x);
    let t = x - f;
    let i0 = if f < 0.0 {
        n - 1
    } else {
        (f as usize).min(n - 1)
    };
    (i0, (i0 + 1) % n, t)
}

impl<'a> Textures<'a> {
    /// Checks that every texture fits in the pool and the capacities, and that every
    /// texel is a finite, non-negative reflectance (an infinite one rendered NaN pixels).
    pub fn new(infos: &'a [TextureInfo], texels: &'a [Vec3]) -> Result<Textures<'a>, Error> {
        check_capacity("config::MAX_TEXTURES", config::MAX_TEXTURES, infos.len())?;
        check_capacity("config::MAX_TEXELS", config::MAX_TEXELS, texels.len())?;
        if !texels
            .iter()
            .all(|t| math::is_finite(*t) && t.min_element() >= 0.0)
        {
            return Err(Error::InvalidValue {
                what: "texture: a texel is not a finite reflectance >= 0",
            });
        }
        for info in infos {
            let TextureGrid { width, height, .. } = info.grid;
            if width == 0 || height == 0 {
                return Err(Error::InvalidValue {
                    what: "texture: width and height must be at least 1 texel",
                });
            }
            let needed = (width as usize)
                .checked_mul(height as usize)
                .and_then(|count| count.checked_add(info.offset))
                .unwrap_or(usize::MAX);
            if needed > texels.len() {
                return Err(Error::BufferTooSmall {
                    what: "texture texels (offset + width * height)",
                    needed,
                    got: texels.len(),
                });
            }
        }
        Ok(Textures { infos, texels })
    }

    pub fn len(&self) -> usize {
        self.infos.len()
    }

    pub fn is_empty(&self) -> bool {
        self.infos.is_empty()
    }

    /// Bilinear lookup at texture coordinate `uv` (black for an unknown id).
    pub fn lookup(&self, id: TextureId, uv: Vec2) -> Vec3 {
        let Some(info) = self.infos.get(id.0 as usize) else {
            return Vec3::ZERO;
        };
        info.grid
            .taps(uv)
            .iter()
            .map(|&(index, weight)| {
                self.texels
                    .get(info.offset + index)
                    .copied()
                    .unwrap_or(Vec3::ZERO)
                    * weight
            })
            .fold(Vec3::ZERO, |a, b| a + b)
    }
}

impl TextureGrid {
    /// The four texels (row-major index into the `width x height` grid) and weights that
    /// a bilinear lookup at `uv` blends; the weights sum to 1. Shared by the lookup and by
    /// the recovery of a map (stage 5), which must invert exactly this sampling.
    pub fn taps(&self, uv: Vec2) -> [(usize, f32); 4] {
        let TextureGrid {
            width,
            height,
            wrap,
        } = *self;
        // Continuous texel coordinates: texel (i, j)'s centre is at (i, j).
        let ((i0, i1, tx), (j0, j1, ty)) = match wrap {
            Wrap::Clamp => (
                axis(clamp_unit(uv.x) * width as f32 - 0.5, width),
                axis((1.0 - clamp_unit(uv.y)) * height as f32 - 0.5, height),
            ),
            // At a whole u or v both sides of the seam read the same: half the last texel,
            // half the first.
            Wrap::Repeat => (
                axis_repeat(repeat_unit(uv.x) * width as f32 - 0.5, width),
                axis_repeat((1.0 - repeat_unit(uv.y)) * height as f32 - 0.5, height),
            ),
        };
        // Saturating: a grid too large for the target's addresses (70,000 texels a side
        // on 32 bits) gives indices past any texel pool, which lookups refuse, rather
        // than an overflow or another texel's index.
        let w = width as usize;
        let at = |j: usize, i: usize| j.saturating_mul(w).saturating_add(i);
        [
            (at(j0, i0), (1.0 - tx) * (1.0 - ty)),
            (at(j0, i1), tx * (1.0 - ty)),
            (at(j1, i0), (1.0 - tx) * ty),
            (at(j1, i1), tx * ty),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// A 3 x 2 texture after a 1-texel padding of 99: texel (i, j) = (i, j, 10 + i + 3 j).
    fn pool() -> (Vec<TextureInfo>, Vec<Vec3>) {
        let mut texels = std::vec![Vec3::splat(99.0)];
        for j in 0..2 {
            for i in 0..3 {
                texels.push(Vec3::new(i as f32, j as f32, (10 + i + 3 * j) as f32));
            }
        }
        let infos = std::vec![
            TextureInfo {
                grid: TextureGrid {
                    width: 3,
                    height: 2,
                    wrap: Wrap::Clamp,
                },
                offset: 1,
            },
            TextureInfo {
                grid: TextureGrid {
                    width: 1,
                    height: 1,
                    wrap: Wrap::Clamp,
                },
                offset: 0,
            },
        ];
        (infos, texels)
    }

    fn centre(i: u32, j: u32, w: u32, h: u32) -> Vec2 {
        Vec2::new(
            (i as f32 + 0.5) / w as f32,
            1.0 - (j as f32 + 0.5) / h as f32,
        )
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-5
    }

    #[test]
    fn texel_centres_return_texels() {
        let (infos, texels) = pool();
        let t = Textures::new(&infos, &texels).unwrap();
        assert_eq!(t.len(), 2);
        assert!(!t.is_empty());
        for j in 0..2 {
            for i in 0..3 {
                let got = t.lookup(TextureId(0), centre(i, j, 3, 2));
                let want = Vec3::new(i as f32, j as f32, (10 + i + 3 * j) as f32);
                assert!(close(got, want), "({i}, {j}): {got} != {want}");
            }
        }
        // Row 0 is the top of the picture (v near 1).
        assert!(close(
            t.lookup(TextureId(0), Vec2::new(0.5, 0.75)),
            Vec3::new(1.0, 0.0, 11.0)
        ));
        assert!(close(
            t.lookup(TextureId(0), Vec2::new(0.5, 0.25)),
            Vec3::new(1.0, 1.0, 14.0)
        ));
        // A 1 x 1 texture is constant.
        for uv in [Vec2::ZERO, Vec2::ONE, Vec2::new(0.3, 0.8)] {
            assert_eq!(t.lookup(TextureId(1), uv), Vec3::splat(99.0));
        }
    }

    #[test]
    fn bilinear_between_centres() {
        let (infos, texels) = pool();
        let t = Textures::new(&infos, &texels).unwrap();
        // Halfway between (0, 0) and (1, 0): u = 1/3, v = 0.75.
        let got = t.lookup(TextureId(0), Vec2::new(1.0 / 3.0, 0.75));
        assert!(close(got, Vec3::new(0.5, 0.0, 10.5)), "{got}");
        // Halfway between rows 0 and 1: v = 0.5.
        let got = t.lookup(TextureId(0), Vec2::new(5.0 / 6.0, 0.5));
        assert!(close(got, Vec3::new(2.0, 0.5, 13.5)), "{got}");
        // The middle of four centres is their mean.
        let got = t.lookup(TextureId(0), Vec2::new(1.0 / 3.0, 0.5));
        assert!(close(got, Vec3::new(0.5, 0.5, 12.0)), "{got}");
        // A quarter of the way along u.
        let got = t.lookup(TextureId(0), Vec2::new(1.0 / 6.0 + 1.0 / 12.0, 0.75));
        assert!(close(got, Vec3::new(0.25, 0.0, 10.25)), "{got}");
    }

    #[test]
    fn clamped_at_the_border() {
        let (infos, texels) = pool();
        let t = Textures::new(&infos, &texels).unwrap();
        let id = TextureId(0);
        let top_left = Vec3::new(0.0, 0.0, 10.0);
        let bottom_right = Vec3::new(2.0, 1.0, 15.0);
        for uv in [
            Vec2::new(0.0, 1.0),
            Vec2::new(0.1, 0.9),
            Vec2::new(-3.0, 7.0),
        ] {
            assert!(close(t.lookup(id, uv), top_left), "{uv}");
        }
        for uv in [
            Vec2::new(1.0, 0.0),
            Vec2::new(0.95, 0.1),
            Vec2::new(4.0, -2.0),
        ] {
            assert!(close(t.lookup(id, uv), bottom_right), "{uv}");
        }
        // Clamped, not wrapped: u = 1.2 is the right column, not u = 0.2.
        let got = t.lookup(id, Vec2::new(1.2, 0.75));
        assert!(close(got, Vec3::new(2.0, 0.0, 12.0)), "{got}");
        // Along the left edge only v interpolates.
        let got = t.lookup(id, Vec2::new(0.0, 0.5));
        assert!(close(got, Vec3::new(0.0, 0.5, 11.5)), "{got}");
        // NaN and infinite coordinates never panic and stay inside the texture.
        for uv in [
            Vec2::new(f32::NAN, 0.5),
            Vec2::new(0.5, f32::NAN),
            Vec2::new(f32::INFINITY, f32::NEG_INFINITY),
        ] {
            let v = t.lookup(id, uv);
            assert!(v.is_finite() && v.z >= 10.0 && v.z <= 15.0, "{uv}: {v}");
        }
        // Unknown id: black.
        assert_eq!(t.lookup(TextureId(2), Vec2::splat(0.5)), Vec3::ZERO);
        assert_eq!(
            Textures::default().lookup(TextureId(0), Vec2::ZERO),
            Vec3::ZERO
        );
    }

    /// A tiled texture reads a whole tile away as here, and across its seam blends the
    /// last texel into the first: no border held, no jump.
    #[test]
    fn repeated_across_tiles_without_a_seam() {
        let (mut infos, texels) = pool();
        infos[0].grid.wrap = Wrap::Repeat;
        let t = Textures::new(&infos, &texels).unwrap();
        let id = TextureId(0);
        for (i, j) in [(0, 0), (2, 0), (1, 1)] {
            let c = centre(i, j, 3, 2);
            let want = t.lookup(id, c);
            for shift in [
                Vec2::new(1.0, 0.0),
                Vec2::new(-2.0, 3.0),
                Vec2::new(4.0, -1.0),
            ] {
                let got = t.lookup(id, c + shift);
                assert!(close(got, want), "({i}, {j}) + {shift}: {got} != {want}");
            }
        }
        // u = 0 (or 1, or 2) on row 0: half the last column, half the first.
        let (first, last) = (Vec3::new(0.0, 0.0, 10.0), Vec3::new(2.0, 0.0, 12.0));
        for u in [0.0, 1.0, 2.0, -1.0] {
            let got = t.lookup(id, Vec2::new(u, 0.75));
            assert!(close(got, (first + last) * 0.5), "u {u}: {got}");
        }
        // Just past 1 is the first column's side of the seam, not the last column held.
        let got = t.lookup(id, Vec2::new(1.0 + 1.0 / 6.0, 0.75));
        assert!(close(got, first), "{got}");
        // v across its seam: rows 1 and 0 blend at v = 0.
        let got = t.lookup(id, Vec2::new(0.5, 0.0));
        assert!(close(got, Vec3::new(1.0, 0.5, 12.5)), "{got}");
        // The taps' weights sum to 1 and their indices stay in the texture.
        for uv in [
            Vec2::new(-0.01, 7.99),
            Vec2::new(123.456, -0.0001),
            Vec2::new(f32::NAN, f32::INFINITY),
        ] {
            let grid = TextureGrid {
                width: 3,
                height: 2,
                wrap: Wrap::Repeat,
            };
            let taps = grid.taps(uv);
            let sum: f32 = taps.iter().map(|&(_, a)| a).sum();
            assert!(
                (sum - 1.0).abs() < 1e-5 && taps.iter().all(|&(k, _)| k < 6),
                "{uv}"
            );
        }
    }

    #[test]
    fn new_checks_the_pool() {
        let texels = std::vec![Vec3::ONE; 12];
        let info = |width, height, offset| TextureInfo {
            grid: TextureGrid {
                width,
                height,
                wrap: Wrap::Clamp,
            },
            offset,
        };
        assert!(Textures::new(&[info(4, 3, 0)], &texels).is_ok());
        assert!(Textures::new(&[info(2, 3, 6), info(1, 1, 11)], &texels).is_ok());
        assert!(Textures::new(&[], &[]).unwrap().is_empty());
        assert_eq!(
            Textures::new(&[info(4, 3, 1)], &texels).unwrap_err(),
            Error::BufferTooSmall {
                what: "texture texels (offset + width * height)",
                needed: 13,
                got: 12,
            }
        );
        assert!(matches!(
            Textures::new(&[info(u32::MAX, u32::MAX, usize::MAX)], &texels),
            Err(Error::BufferTooSmall { .. })
        ));
        for bad in [info(0, 3, 0), info(3, 0, 0)] {
            assert!(matches!(
                Textures::new(&[bad], &texels),
                Err(Error::InvalidValue { .. })
            ));
        }
        let many = std::vec![info(1, 1, 0); config::MAX_TEXTURES + 1];
        assert_eq!(
            Textures::new(&many, &texels).unwrap_err(),
            Error::Capacity {
                what: "config::MAX_TEXTURES",
                max: config::MAX_TEXTURES,
                needed: config::MAX_TEXTURES + 1,
            }
        );
        assert!(Textures::new(&many[..config::MAX_TEXTURES], &texels).is_ok());
        // A texel of infinity rendered NaN pixels (fuzzing the core, 2026-12-06).
        for bad in [f32::INFINITY, f32::NAN, -0.1] {
            let mut pool = texels.clone();
            pool[5] = Vec3::new(0.5, bad, 0.5);
            assert_eq!(
                Textures::new(&[info(4, 3, 0)], &pool).unwrap_err(),
                Error::InvalidValue {
                    what: "texture: a texel is not a finite reflectance >= 0"
                },
                "{bad}"
            );
        }
    }
}
