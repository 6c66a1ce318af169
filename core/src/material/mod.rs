//! The closed set of reflectance models (reflectance.md): diffuse, Ward isotropic
//! (RADIANCE plastic/metal), Ward anisotropic (plastic2/metal2), mirror; and diffuse maps.
//!
//! A [`Material`] holds resolved reflectances (the file's `color`/`specularity` already
//! turned into `rho_d` and `rho_s` by the group's kind, see [`Material::from_params`]).
//! At a hit, [`Bsdf::new`] builds the shading frame; `eval` / `sample` / `pdf` take world
//! directions and never own a random generator: the caller hands in uniform numbers.
//!
//! OWNER: material helper. The public API below is what the rest of the code relies on.

pub mod texture;

use crate::error::Error;
use crate::math::{Frame, Vec3};

pub use texture::{TextureId, TextureInfo, Textures};

/// The group's material type, assigned in preprocessing (scene.toml `kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Plastic,
    Metal,
}

/// A reflectance model with resolved reflectances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    /// Lambertian: `f = rho_d / pi`.
    Diffuse { rho_d: Vec3 },
    /// RADIANCE plastic/metal: Lambertian plus the W-G-M-D Ward lobe of roughness `alpha`.
    Ward { rho_d: Vec3, rho_s: Vec3, alpha: f32 },
    /// RADIANCE plastic2/metal2: `alpha_u` along `direction` projected on the surface.
    WardAnisotropic {
        rho_d: Vec3,
        rho_s: Vec3,
        alpha_u: f32,
        alpha_v: f32,
        direction: Vec3,
    },
    /// Perfect specular reflection of reflectance `rho`.
    Mirror { rho: Vec3 },
}

/// The model of a file, before resolution by the group's kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Params {
    Diffuse,
    Isotropic { specularity: f32, roughness: f32 },
    Anisotropic { specularity: f32, roughness_u: f32, roughness_v: f32, direction: Vec3 },
    Mirror,
}

/// A group's material as the renderer uses it: the model, and optionally a diffuse map
/// that replaces `rho_d` point by point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceMaterial {
    pub material: Material,
    pub diffuse_map: Option<TextureId>,
}

impl Material {
    /// Resolves a file's `color` and parameters by the group's kind (scene-format.md):
    /// `rho_d = color (1 - s)`; `rho_s = s` (plastic) or `color s` (metal); a mirror
    /// reflects `color`. Errors on values outside their ranges (reflectance.md: roughness
    /// in (0, 0.3]... checked as > 0 and finite; colour and specularity in [0, 1]).
    pub fn from_params(kind: Kind, color: Vec3, params: Params) -> Result<Material, Error> {
        let _ = (kind, color, params);
        Err(Error::InvalidValue { what: "material: not implemented" })
    }

    /// Diffuse reflectance (zero for a mirror).
    pub fn rho_d(&self) -> Vec3 {
        match *self {
            Material::Diffuse { rho_d }
            | Material::Ward { rho_d, .. }
            | Material::WardAnisotropic { rho_d, .. } => rho_d,
            Material::Mirror { .. } => Vec3::ZERO,
        }
    }
}

/// A sampled incoming direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// World direction towards where the light comes from.
    pub wi: Vec3,
    /// `f(wo, wi) * |cos(n, wi)| / pdf`: the factor the path throughput is multiplied by.
    pub weight: Vec3,
    /// Solid-angle pdf of `wi` (meaningless for a delta sample).
    pub pdf: f32,
    /// True for a mirror (Dirac) sample: no MIS, no light sampling.
    pub delta: bool,
}

/// A material at one surface point, with its shading frame.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    frame: Frame,
    material: Material,
}

impl Bsdf {
    /// `n` is the unit geometric normal already turned towards `wo` (surfaces reflect on
    /// both sides); `rho_d` overrides the material's diffuse reflectance (a diffuse map).
    pub fn new(material: &Material, rho_d: Option<Vec3>, n: Vec3) -> Bsdf {
        let _ = rho_d;
        Bsdf { frame: Frame::from_normal(n), material: *material }
    }

    /// True when the material has no diffuse or glossy part (a mirror): light sampling
    /// is pointless there.
    pub fn is_delta(&self) -> bool {
        matches!(self.material, Material::Mirror { .. })
    }

    /// `f(wo, wi)` (without the cosine); zero when `wi` is below the surface.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let _ = (wo, wi, self.frame);
        Vec3::ZERO
    }

    /// Solid-angle pdf with which [`Bsdf::sample`] picks `wi` (zero for a mirror).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let _ = (wo, wi);
        0.0
    }

    /// Samples `wi` from a mixture of the cosine lobe and the specular lobe, with `u`
    /// picking the lobe and `u2` the direction. `None` when the sample is absorbed or falls
    /// below the surface.
    pub fn sample(&self, wo: Vec3, u: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let _ = (wo, u, u2);
        None
    }
}
