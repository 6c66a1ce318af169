//! Diffuse maps: RGB texels in one lent pool, looked up by bilinear interpolation between
//! texel centres, clamped at the border (bench/README.md, "Texture sampling"): texel
//! `(i, j)` has its centre at `u = (i + 0.5) / W`, `v = 1 - (j + 0.5) / H`; row 0 is v = 1.
//!
//! OWNER: material helper.

use crate::error::Error;
use crate::math::{Vec2, Vec3};

/// Index into [`Textures`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureId(pub u16);

/// Where one texture lies in the texel pool.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureInfo {
    pub width: u32,
    pub height: u32,
    /// First texel (row 0, column 0) in the pool; rows follow each other.
    pub offset: usize,
}

/// All textures of a scene, over lent slices.
#[derive(Clone, Copy, Debug, Default)]
pub struct Textures<'a> {
    infos: &'a [TextureInfo],
    texels: &'a [Vec3],
}

impl<'a> Textures<'a> {
    /// Checks that every texture fits in the pool and the capacities.
    pub fn new(infos: &'a [TextureInfo], texels: &'a [Vec3]) -> Result<Textures<'a>, Error> {
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
        let _ = (id, uv, self.texels);
        Vec3::ZERO
    }
}
