//! The closed set of reflectance models (reflectance.md): diffuse, Ward isotropic
//! (RADIANCE plastic/metal), Ward anisotropic (plastic2/metal2), mirror; and diffuse maps.
//!
//! A [`Material`] holds resolved reflectances (the file's `color`/`specularity` already
//! turned into `rho_d` and `rho_s` by the group's kind, see [`Material::from_params`]).
//! At a hit, [`Bsdf::new`] builds the shading frame; `eval` / `sample` / `pdf` take world
//! directions and never own a random generator: the caller hands in uniform numbers.
//!
//! # The model (reflectance.md)
//!
//! With `h = wi + wo` NOT normalised and `(x, y, z)` the shading frame (`z = n`; for the
//! anisotropic lobe `x = uhat`, `y = vhat`):
//!
//! ```text
//! f = rho_d / pi + rho_s * (h.h) / (pi au av (h.z)^4) * exp(-((h.x/au)^2 + (h.y/av)^2) / (h.z)^2)
//! ```
//!
//! which is RADIANCE's W-G-M-D Ward lobe; the isotropic lobe is `au = av = alpha`
//! (`(h.x)^2 + (h.y)^2 = h.h - (h.n)^2`). `f` is zero unless both `wo` and `wi` are strictly
//! above the surface.
//!
//! # Sampling
//!
//! A one-sample mixture of the cosine lobe and the Ward lobe. The specular lobe is picked
//! with probability `p_spec = lum(rho_s) / (lum(rho_d) + lum(rho_s))`, at least 0.1 when
//! `rho_s` is non-zero, exactly 1 when `rho_d` is zero and exactly 0 when `rho_s` is zero;
//! the lobe choice is `u < 1 - p_spec` -> cosine lobe, else Ward lobe (so `u = 1` always
//! picks the Ward lobe of a pure specular material, as `transport` relies on).
//!
//! The Ward lobe samples the normalised half vector `ĥ` (Walter 2005, "Notes on the Ward
//! BRDF"): `phi = atan2(av sin(2 pi u1), au cos(2 pi u1))` (Walter's
//! `atan(av/au tan(2 pi u1))` with the quadrant of `2 pi u1`), `tan^2(theta) = -ln(1 - u0) /
//! (cos^2 phi / au^2 + sin^2 phi / av^2)`, then `wi = reflect(wo, ĥ)`. Its solid-angle pdf
//! is `p_h(ĥ) / (4 wo.ĥ)` with
//! `p_h = exp(-tan^2(theta) (cos^2 phi / au^2 + sin^2 phi / av^2)) / (pi au av cos^3 theta)`.
//! Half vectors that reflect `wo` below the surface are lost (`sample` returns `None`), so
//! the Ward part of [`Bsdf::pdf`] integrates to slightly less than one at grazing views and
//! large roughness: it is the exact density of the directions `sample` returns.
//!
//! OWNER: material helper. The public API below is what the rest of the code relies on.

pub mod texture;

use crate::error::Error;
use crate::math::{self, Frame, Vec3, INV_PI, PI};

pub use texture::{TextureGrid, TextureId, TextureInfo, Textures, Wrap};

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
    Ward {
        rho_d: Vec3,
        rho_s: Vec3,
        alpha: f32,
    },
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
    Isotropic {
        specularity: f32,
        roughness: f32,
    },
    Anisotropic {
        specularity: f32,
        roughness_u: f32,
        roughness_v: f32,
        direction: Vec3,
    },
    Mirror,
}

/// A group's material as the renderer uses it: the model, and optionally a diffuse map
/// that replaces `rho_d` point by point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceMaterial {
    pub material: Material,
    pub diffuse_map: Option<TextureId>,
}

fn check_unit(x: f32, what: &'static str) -> Result<(), Error> {
    if x.is_finite() && (0.0..=1.0).contains(&x) {
        Ok(())
    } else {
        Err(Error::InvalidValue { what })
    }
}

fn check_roughness(x: f32, what: &'static str) -> Result<(), Error> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidValue { what })
    }
}

impl Material {
    /// Resolves a file's `color` and parameters by the group's kind (scene-format.md):
    /// `rho_d = color (1 - s)`; `rho_s = s` (plastic) or `color s` (metal); a mirror
    /// reflects `color`. Errors on values outside their ranges (reflectance.md: roughness
    /// in (0, 0.3]... checked as > 0 and finite; colour and specularity in [0, 1]).
    ///
    /// The anisotropic `direction` is kept as given (any non-zero length); [`Bsdf::new`]
    /// projects it onto the surface.
    pub fn from_params(kind: Kind, color: Vec3, params: Params) -> Result<Material, Error> {
        const COLOR: &str = "material: color components must be finite and in [0, 1]";
        for c in color.to_array() {
            check_unit(c, COLOR)?;
        }
        const SPEC: &str = "material: specularity must be finite and in [0, 1]";
        let specular = |s: f32| match kind {
            Kind::Plastic => Vec3::splat(s),
            Kind::Metal => color * s,
        };
        Ok(match params {
            Params::Diffuse => Material::Diffuse { rho_d: color },
            Params::Mirror => Material::Mirror { rho: color },
            Params::Isotropic {
                specularity,
                roughness,
            } => {
                check_unit(specularity, SPEC)?;
                check_roughness(roughness, "material: roughness must be finite and > 0")?;
                Material::Ward {
                    rho_d: color * (1.0 - specularity),
                    rho_s: specular(specularity),
                    alpha: roughness,
                }
            }
            Params::Anisotropic {
                specularity,
                roughness_u,
                roughness_v,
                direction,
            } => {
                check_unit(specularity, SPEC)?;
                check_roughness(roughness_u, "material: roughness_u must be finite and > 0")?;
                check_roughness(roughness_v, "material: roughness_v must be finite and > 0")?;
                if !math::is_finite(direction) {
                    return Err(Error::InvalidValue {
                        what: "material: direction_u must be finite",
                    });
                }
                let direction = math::representable_direction(direction);
                if !(direction.length_squared() > 0.0) {
                    return Err(Error::InvalidValue {
                        what: "material: direction_u must not be the zero vector",
                    });
                }
                Material::WardAnisotropic {
                    rho_d: color * (1.0 - specularity),
                    rho_s: specular(specularity),
                    alpha_u: roughness_u,
                    alpha_v: roughness_v,
                    direction,
                }
            }
        })
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

/// Smallest roughness the lobe is evaluated with: guards a zero or NaN roughness of a
/// hand-built [`Material`] (from_params rejects them) against infinities.
const MIN_ALPHA: f32 = 1e-4;
/// Lower bound of the specular lobe's selection probability when `rho_s` is non-zero.
const MIN_SPECULAR_PROBABILITY: f32 = 0.1;
/// `exp(-x)` for `x` beyond this is treated as zero (`exp(-80)` is about 1.8e-35).
const MAX_EXPONENT: f32 = 80.0;
/// Floor of the denominators of the lobe and its pdf, and ceiling of their values.
const TINY: f32 = 1e-30;
const HUGE: f32 = 1e30;

/// The lobes of a BSDF, resolved at one point.
#[derive(Clone, Copy, Debug)]
enum Lobes {
    /// Perfect specular reflection.
    Mirror { rho: Vec3 },
    /// Cosine lobe plus W-G-M-D Ward lobe (isotropic when `alpha_u == alpha_v`).
    Glossy {
        rho_d: Vec3,
        rho_s: Vec3,
        alpha_u: f32,
        alpha_v: f32,
        /// Probability of sampling the Ward lobe; negative when both lobes are black.
        p_spec: f32,
    },
}

/// A material at one surface point, with its shading frame.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    frame: Frame,
    lobes: Lobes,
}

/// `part / whole`, within [0, 1]; 0 where `whole` is not positive.
#[inline]
fn share(part: f32, whole: f32) -> f32 {
    if whole > 0.0 {
        (part / whole).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Negative and NaN components to zero.
#[inline]
fn non_negative(v: Vec3) -> Vec3 {
    v.max(Vec3::ZERO)
}

#[inline]
fn alpha_guard(a: f32) -> f32 {
    // `f32::max` returns the other operand for NaN.
    a.max(MIN_ALPHA)
}

/// The probability of the specular lobe (see the module documentation); negative when
/// both reflectances are black.
fn specular_probability(rho_d: Vec3, rho_s: Vec3) -> f32 {
    let ld = math::luminance(rho_d);
    let ls = math::luminance(rho_s);
    let has_d = rho_d.max_element() > 0.0;
    let has_s = rho_s.max_element() > 0.0;
    match (has_d, has_s) {
        (false, false) => -1.0,
        (true, false) => 0.0,
        (false, true) => 1.0,
        (true, true) => {
            let p = ls / (ld + ls);
            if p.is_finite() {
                p.clamp(MIN_SPECULAR_PROBABILITY, 1.0)
            } else {
                0.5
            }
        }
    }
}

/// Whether an anisotropic lobe with `direction` falls back to isotropic at unit normal
/// `n`: the direction is parallel to the normal, so its projection on the surface gives
/// no u axis (reflectance.md). The same test as `Frame::from_normal_and_direction`, on a
/// unit direction; public so that a host can tell a user where it happens.
pub fn anisotropic_falls_back(n: Vec3, direction: Vec3) -> bool {
    !(n.cross(normalized(direction)).length_squared() > 1e-12)
}

/// Unit vector `v / |v|` through libm; zero for a zero vector.
#[inline]
fn normalized(v: Vec3) -> Vec3 {
    let l2 = v.length_squared();
    if l2 > 0.0 {
        v * (1.0 / math::sqrt(l2))
    } else {
        Vec3::ZERO
    }
}

/// A uniform number forced into [0, 1] (NaN to 0).
#[inline]
fn unit(u: f32) -> f32 {
    if u >= 0.0 {
        u.min(1.0)
    } else {
        0.0
    }
}

/// The exponent `((h.x/au)^2 + (h.y/av)^2) / (h.z)^2` of the Ward lobe (local `h`, any
/// length): `tan^2` of the half-vector angle, weighted by the roughnesses.
#[inline]
fn ward_exponent(hl: Vec3, au: f32, av: f32) -> f32 {
    let x = hl.x / au;
    let y = hl.y / av;
    (x * x + y * y) / (hl.z * hl.z)
}

/// The W-G-M-D lobe for unit `rho_s` at the un-normalised half vector `h = wo + wi`, given
/// in the shading frame (`hl`) with its squared length `h2`. Zero where `h` is below the
/// surface or the exponential underflows.
#[inline]
fn ward_lobe(hl: Vec3, h2: f32, au: f32, av: f32) -> f32 {
    if !(hl.z > 0.0) {
        return 0.0;
    }
    let e = ward_exponent(hl, au, av);
    if !(e < MAX_EXPONENT) {
        return 0.0;
    }
    let hz2 = hl.z * hl.z;
    let denom = (PI * au * av * hz2 * hz2).max(TINY);
    (h2 * math::exp(-e) / denom).min(HUGE)
}

/// Up to [`math::LANES`] half vectors `h = wo + wi` for [`ward_lobes`], one array per
/// coordinate in the shading frame, and their squared lengths.
#[derive(Clone, Copy, Debug, Default)]
pub struct HalfVectorLanes {
    pub x: [f32; math::LANES],
    pub y: [f32; math::LANES],
    pub z: [f32; math::LANES],
    pub length_squared: [f32; math::LANES],
}

/// `ward_lobe` at each lane of `h`, the same bits, evaluated as vectors (the exponential
/// by [`math::exp_lanes`]): where a fit evaluates the lobe at thousands of cached samples
/// for each candidate. Every lane is computed; a caller ignores those it did not fill.
pub fn ward_lobes(h: &HalfVectorLanes, au: f32, av: f32) -> [f32; math::LANES] {
    let mut exponent = [0.0; math::LANES];
    let mut live = [false; math::LANES];
    for j in 0..math::LANES {
        let e = ward_exponent(Vec3::new(h.x[j], h.y[j], h.z[j]), au, av);
        // `ward_lobe`'s two early zeros, as a mask; a masked lane takes exp(0).
        live[j] = h.z[j] > 0.0 && e < MAX_EXPONENT;
        exponent[j] = if live[j] { -e } else { 0.0 };
    }
    let exponential = math::exp_lanes(exponent);
    let mut lobe = [0.0; math::LANES];
    for j in 0..math::LANES {
        let hz2 = h.z[j] * h.z[j];
        let denom = (PI * au * av * hz2 * hz2).max(TINY);
        let value = (h.length_squared[j] * exponential[j] / denom).min(HUGE);
        lobe[j] = if live[j] { value } else { 0.0 };
    }
    lobe
}

/// Whether the Ward exponent at a half vector of `tan^2 = tan2` is past its underflow
/// bound for every roughness up to the (guarded) `alpha`, with a 1% margin for rounding:
/// true only where the lobe is zero for certain, so that skipping it changes no bit.
#[inline]
fn ward_vanishes(tan2: f32, alpha: f32) -> bool {
    tan2 > MAX_EXPONENT * 1.01 * alpha * alpha
}

impl Bsdf {
    /// `n` is the unit geometric normal already turned towards `wo` (surfaces reflect on
    /// both sides); `rho_d` overrides the material's diffuse reflectance (a diffuse map;
    /// ignored by a mirror). Negative or NaN reflectance components count as zero.
    pub fn new(material: &Material, rho_d: Option<Vec3>, n: Vec3) -> Bsdf {
        let glossy = |frame: Frame, d: Vec3, s: Vec3, au: f32, av: f32| {
            let rho_d = non_negative(rho_d.unwrap_or(d));
            let rho_s = non_negative(s);
            Bsdf {
                frame,
                lobes: Lobes::Glossy {
                    rho_d,
                    rho_s,
                    alpha_u: alpha_guard(au),
                    alpha_v: alpha_guard(av),
                    p_spec: specular_probability(rho_d, rho_s),
                },
            }
        };
        match *material {
            Material::Mirror { rho } => Bsdf {
                frame: Frame::from_normal(n),
                lobes: Lobes::Mirror {
                    rho: non_negative(rho),
                },
            },
            Material::Diffuse { rho_d } => {
                glossy(Frame::from_normal(n), rho_d, Vec3::ZERO, 1.0, 1.0)
            }
            Material::Ward {
                rho_d,
                rho_s,
                alpha,
            } => glossy(Frame::from_normal(n), rho_d, rho_s, alpha, alpha),
            Material::WardAnisotropic {
                rho_d,
                rho_s,
                alpha_u,
                alpha_v,
                direction,
            } => {
                if !anisotropic_falls_back(n, direction) {
                    let frame = Frame::from_normal_and_direction(n, normalized(direction));
                    glossy(frame, rho_d, rho_s, alpha_u, alpha_v)
                } else {
                    // reflectance.md: a direction parallel to n falls back to isotropic.
                    let (au, av) = (alpha_guard(alpha_u), alpha_guard(alpha_v));
                    let a = math::sqrt(0.5 * (au * au + av * av));
                    glossy(Frame::from_normal(n), rho_d, rho_s, a, a)
                }
            }
        }
    }

    /// True when the material has no diffuse or glossy part (a mirror): light sampling
    /// is pointless there.
    pub fn is_delta(&self) -> bool {
        matches!(self.lobes, Lobes::Mirror { .. })
    }

    /// `f(wo, wi)` (without the cosine); zero when `wi` is below the surface.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let n = self.frame.z;
        if !(n.dot(wo) > 0.0 && n.dot(wi) > 0.0) {
            return Vec3::ZERO;
        }
        self.eval_above(wo + wi)
    }

    /// The diffuse lobe's share of `f(wo, wi)`, channel by channel: `(rho_d / pi) / f`, 0
    /// where `f` is 0 and for a mirror. Light reflected towards `wo` from `wi` splits by it
    /// into what the diffuse colour reflects and what the specular lobe does.
    pub fn diffuse_share(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let Lobes::Glossy { rho_d, .. } = self.lobes else {
            return Vec3::ZERO;
        };
        let f = self.eval(wo, wi);
        let f_d = rho_d * INV_PI;
        Vec3::new(share(f_d.x, f.x), share(f_d.y, f.y), share(f_d.z, f.z))
    }

    /// [`Bsdf::eval`] for a `wo` and `wi` both above the surface, given by their sum `h`:
    /// a caller that keeps `h` across many materials skips the horizon test.
    #[inline]
    pub fn eval_above(&self, h: Vec3) -> Vec3 {
        let Lobes::Glossy {
            rho_d,
            rho_s,
            alpha_u,
            alpha_v,
            ..
        } = self.lobes
        else {
            return Vec3::ZERO;
        };
        let mut f = rho_d * INV_PI;
        if rho_s.max_element() > 0.0 {
            f += rho_s * self.ward(h, alpha_u, alpha_v);
        }
        f
    }

    /// The Ward lobe's reflectance and roughnesses `(rho_s, alpha_u, alpha_v)` when the
    /// BSDF is that lobe alone (no diffuse part; not a mirror). Then [`Bsdf::eval_above`]
    /// at `h` is `rho_s` times [`ward_lobes`] at `h` in [`Bsdf::to_local`]'s frame, to the
    /// bit.
    pub fn lobe_alone(&self) -> Option<(Vec3, f32, f32)> {
        match self.lobes {
            Lobes::Glossy {
                rho_d,
                rho_s,
                alpha_u,
                alpha_v,
                ..
            } if rho_d == Vec3::ZERO => Some((rho_s, alpha_u, alpha_v)),
            _ => None,
        }
    }

    /// `v` in the shading frame.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        self.frame.to_local(v)
    }

    /// Whether [`Bsdf::eval_above`] is zero for certain at a half vector whose angle to
    /// the normal has `tan^2 = tan2`: no diffuse part, and the Ward exponent past its
    /// underflow bound for the larger roughness. A sharp lobe far from its highlight costs
    /// no exponential then.
    #[inline]
    pub fn vanishes_at(&self, tan2: f32) -> bool {
        match self.lobes {
            Lobes::Mirror { .. } => true,
            Lobes::Glossy {
                rho_d,
                alpha_u,
                alpha_v,
                ..
            } => rho_d == Vec3::ZERO && ward_vanishes(tan2, alpha_u.max(alpha_v)),
        }
    }

    /// The W-G-M-D lobe for unit `rho_s` at the un-normalised half vector `h = wo + wi`.
    #[inline]
    fn ward(&self, h: Vec3, au: f32, av: f32) -> f32 {
        ward_lobe(self.frame.to_local(h), h.length_squared(), au, av)
    }

    /// Solid-angle pdf of `wi = reflect(wo, ĥ)` when the Ward lobe samples `ĥ`.
    fn ward_pdf(&self, wo: Vec3, wi: Vec3, au: f32, av: f32) -> f32 {
        let h = normalized(wo + wi);
        let hl = self.frame.to_local(h);
        let c = hl.z;
        let wo_h = wo.dot(h);
        if !(c > 0.0 && wo_h > 0.0) {
            return 0.0;
        }
        let e = ward_exponent(hl, au, av);
        if !(e < MAX_EXPONENT) {
            return 0.0;
        }
        let denom = (4.0 * PI * au * av * c * c * c * wo_h).max(TINY);
        (math::exp(-e) / denom).min(HUGE)
    }

    /// Solid-angle pdf with which [`Bsdf::sample`] picks `wi` (zero for a mirror).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let Lobes::Glossy {
            alpha_u,
            alpha_v,
            p_spec,
            ..
        } = self.lobes
        else {
            return 0.0;
        };
        let n = self.frame.z;
        let cos_i = n.dot(wi);
        if !(n.dot(wo) > 0.0 && cos_i > 0.0) || p_spec < 0.0 {
            return 0.0;
        }
        let mut pdf = 0.0;
        if p_spec < 1.0 {
            pdf += (1.0 - p_spec) * cos_i * INV_PI;
        }
        if p_spec > 0.0 {
            pdf += p_spec * self.ward_pdf(wo, wi, alpha_u, alpha_v);
        }
        pdf
    }

    /// Samples `wi` from a mixture of the cosine lobe and the specular lobe, with `u`
    /// picking the lobe and `u2` the direction. `None` when the sample is absorbed or falls
    /// below the surface.
    pub fn sample(&self, wo: Vec3, u: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let n = self.frame.z;
        let cos_o = n.dot(wo);
        if !(cos_o > 0.0) {
            return None;
        }
        let (alpha_u, alpha_v, p_spec) = match self.lobes {
            Lobes::Mirror { rho } => {
                let wi = normalized(n * (2.0 * cos_o) - wo);
                return Some(BsdfSample {
                    wi,
                    weight: rho,
                    pdf: 1.0,
                    delta: true,
                });
            }
            Lobes::Glossy {
                alpha_u,
                alpha_v,
                p_spec,
                ..
            } => (alpha_u, alpha_v, p_spec),
        };
        if p_spec < 0.0 {
            return None;
        }
        let [u0, u1] = [unit(u2[0]), unit(u2[1])];
        let diffuse = p_spec <= 0.0 || (p_spec < 1.0 && u < 1.0 - p_spec);
        let wi_local = if diffuse {
            // Cosine-weighted hemisphere.
            let r = math::sqrt(u0);
            let phi = 2.0 * PI * u1;
            let z = math::sqrt((1.0 - u0).max(0.0));
            Vec3::new(r * math::cos(phi), r * math::sin(phi), z)
        } else {
            let h = sample_half_vector(u0, u1, alpha_u, alpha_v);
            let wo_local = self.frame.to_local(wo);
            h * (2.0 * wo_local.dot(h)) - wo_local
        };
        if !(wi_local.z > 0.0) {
            return None;
        }
        let wi = normalized(self.frame.to_world(wi_local));
        let cos_i = n.dot(wi);
        let pdf = self.pdf(wo, wi);
        if !(cos_i > 0.0 && pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        let weight = self.eval(wo, wi) * (cos_i / pdf);
        if !math::is_finite(weight) {
            return None;
        }
        Some(BsdfSample {
            wi,
            weight,
            pdf,
            delta: false,
        })
    }
}

/// Walter's half-vector sampling of the (an)isotropic Ward lobe, in the local frame.
fn sample_half_vector(u0: f32, u1: f32, au: f32, av: f32) -> Vec3 {
    let phi0 = 2.0 * PI * u1;
    let (s0, c0) = (math::sin(phi0), math::cos(phi0));
    let (sin_phi, cos_phi) = if au == av {
        (s0, c0)
    } else {
        // atan(av/au tan(phi0)) in the quadrant of phi0.
        let phi = math::atan2(av * s0, au * c0);
        (math::sin(phi), math::cos(phi))
    };
    let k = cos_phi * cos_phi / (au * au) + sin_phi * sin_phi / (av * av);
    let tan2 = -math::ln((1.0 - u0).max(f32::MIN_POSITIVE)) / k;
    let cos_theta = 1.0 / math::sqrt(1.0 + tan2);
    let sin_theta = math::sqrt(tan2) * cos_theta;
    Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Sampler;

    fn normal() -> Vec3 {
        Vec3::new(0.3, -0.5, 0.8).normalize()
    }

    /// A direction at polar angle `theta` (degrees) from `n`, azimuth `phi` (radians).
    fn at_angle(n: Vec3, theta_deg: f32, phi: f32) -> Vec3 {
        let f = Frame::from_normal(n);
        let t = math::radians(theta_deg);
        f.to_world(Vec3::new(
            math::sin(t) * math::cos(phi),
            math::sin(t) * math::sin(phi),
            math::cos(t),
        ))
    }

    fn plastic_iso(rho_d: f32, rho_s: f32, alpha: f32) -> Material {
        Material::Ward {
            rho_d: Vec3::splat(rho_d),
            rho_s: Vec3::splat(rho_s),
            alpha,
        }
    }

    fn plastic_aniso(rho_d: f32, rho_s: f32, au: f32, av: f32) -> Material {
        Material::WardAnisotropic {
            rho_d: Vec3::splat(rho_d),
            rho_s: Vec3::splat(rho_s),
            alpha_u: au,
            alpha_v: av,
            direction: Vec3::new(1.0, 0.2, 0.1),
        }
    }

    /// Integral of `g` over the unit sphere, on a polar grid around `center` whose polar
    /// angle `pi t^2` crowds the nodes near `center` (where a sharp lobe lives).
    fn sphere_quad(center: Vec3, nt: usize, np: usize, mut g: impl FnMut(Vec3) -> f64) -> f64 {
        let f = Frame::from_normal(center);
        let mut sum = 0.0f64;
        let dt = 1.0 / nt as f64;
        let dp = 2.0 * core::f64::consts::PI / np as f64;
        for i in 0..nt {
            let t = (i as f64 + 0.5) * dt;
            let theta = core::f64::consts::PI * t * t;
            let jac = libm::sin(theta) * 2.0 * core::f64::consts::PI * t * dt * dp;
            let (st, ct) = (libm::sin(theta) as f32, libm::cos(theta) as f32);
            let mut ring = 0.0f64;
            for j in 0..np {
                let phi = ((j as f64 + 0.5) * dp) as f32;
                let d = f.to_world(Vec3::new(st * math::cos(phi), st * math::sin(phi), ct));
                ring += g(d);
            }
            sum += ring * jac;
        }
        sum
    }

    fn mirror_dir(n: Vec3, wo: Vec3) -> Vec3 {
        n * (2.0 * n.dot(wo)) - wo
    }

    /// Monte Carlo albedo from `sample` (first channel): mean, standard error, and the
    /// fraction of samples that were not lost.
    fn albedo_mc(b: &Bsdf, wo: Vec3, count: usize, key: u64) -> (f64, f64, f64) {
        let mut rng = Sampler::from_key(key);
        let (mut s, mut s2, mut kept) = (0.0f64, 0.0f64, 0usize);
        for _ in 0..count {
            let u = rng.next_f32();
            let u2 = rng.next_2d();
            if let Some(smp) = b.sample(wo, u, u2) {
                let w = smp.weight.x as f64;
                assert!(w.is_finite() && w >= 0.0);
                s += w;
                s2 += w * w;
                kept += 1;
            }
        }
        let c = count as f64;
        let mean = s / c;
        let var = (s2 / c - mean * mean).max(0.0);
        (mean, libm::sqrt(var / c), kept as f64 / c)
    }

    /// Quadrature grid of the energy tests (the polar grid resolves a = 0.01 to ~1e-4).
    const QUAD: (usize, usize) = (900, 450);

    /// MC albedo == quadrature of `f cos` (sample/pdf/eval consistency), albedo <= 1, and
    /// the pdf integrates to the fraction of samples that are not lost.
    fn check_energy(m: &Material, theta: f32, key: u64) {
        let n = normal();
        let wo = at_angle(n, theta, 0.7);
        let b = Bsdf::new(m, None, n);
        let r = mirror_dir(n, wo);
        let quad = sphere_quad(r, QUAD.0, QUAD.1, |wi| {
            (b.eval(wo, wi).x * n.dot(wi).max(0.0)) as f64
        });
        let pdf_mass = sphere_quad(r, QUAD.0, QUAD.1, |wi| b.pdf(wo, wi) as f64);
        let count = 20_000;
        let (mc, se, kept) = albedo_mc(&b, wo, count, key);
        let ctx = std::format!("{m:?} at {theta} deg: quad {quad} mc {mc} +- {se}");
        // W-G-M-D: the albedo of the pure lobe is 1 - a^2 at normal incidence and falls at
        // grazing angles in every case tested here (up to 85 degrees); 1e-3 covers the
        // quadrature error.
        assert!(quad <= 1.0 + 1e-3, "albedo above one: {ctx}");
        assert!(mc <= 1.0 + 4.0 * se + 1e-3, "albedo above one: {ctx}");
        assert!(
            (mc - quad).abs() <= 4.0 * se + 2e-3,
            "sample/eval mismatch: {ctx}"
        );
        let se_kept = libm::sqrt(kept * (1.0 - kept) / count as f64);
        assert!(
            (pdf_mass - kept).abs() <= 4.0 * se_kept + 2e-3,
            "pdf mass {pdf_mass} != kept fraction {kept}: {ctx}"
        );
        assert!(pdf_mass <= 1.0 + 1e-3, "{ctx}");
    }

    const ANGLES: [f32; 4] = [0.0, 30.0, 60.0, 80.0];

    #[test]
    fn energy_isotropic() {
        for (k, a) in [0.01, 0.03, 0.1, 0.2, 0.3].into_iter().enumerate() {
            for (j, theta) in ANGLES.into_iter().enumerate() {
                check_energy(&plastic_iso(0.0, 1.0, a), theta, (10 * k + j) as u64);
            }
        }
    }

    #[test]
    fn energy_anisotropic() {
        let pairs = [(0.01, 0.05), (0.05, 0.3), (0.3, 0.1), (0.02, 0.2)];
        for (k, (au, av)) in pairs.into_iter().enumerate() {
            for (j, theta) in ANGLES.into_iter().enumerate() {
                check_energy(
                    &plastic_aniso(0.0, 1.0, au, av),
                    theta,
                    (100 + 10 * k + j) as u64,
                );
            }
        }
    }

    #[test]
    fn energy_mixture() {
        let materials = [
            plastic_iso(0.5, 0.5, 0.05),
            plastic_iso(0.9, 0.1, 0.2),
            plastic_aniso(0.7, 0.3, 0.03, 0.15),
            Material::Diffuse {
                rho_d: Vec3::splat(1.0),
            },
        ];
        for (k, m) in materials.iter().enumerate() {
            for (j, theta) in [0.0, 45.0, 80.0].into_iter().enumerate() {
                check_energy(m, theta, (200 + 10 * k + j) as u64);
            }
        }
    }

    #[test]
    fn pdf_integrates_to_one_away_from_grazing() {
        let n = normal();
        let lobes = [
            Material::Diffuse {
                rho_d: Vec3::splat(0.5),
            },
            plastic_iso(0.0, 1.0, 0.01),
            plastic_iso(0.0, 1.0, 0.1),
            plastic_aniso(0.0, 1.0, 0.02, 0.2),
            plastic_iso(0.5, 0.5, 0.1),
        ];
        for m in &lobes {
            for theta in [0.0, 20.0] {
                let wo = at_angle(n, theta, 0.3);
                let b = Bsdf::new(m, None, n);
                let mass =
                    sphere_quad(mirror_dir(n, wo), QUAD.0, QUAD.1, |wi| b.pdf(wo, wi) as f64);
                assert!((mass - 1.0).abs() < 2e-3, "{m:?} at {theta}: {mass}");
            }
        }
    }

    /// Chi-square test of `sample` against `pdf` on a (cos theta, phi) grid of the
    /// hemisphere, plus one bin for lost samples; bins expecting fewer than 5 are pooled.
    fn chi_square(m: &Material, theta: f32, key: u64) {
        const NC: usize = 16;
        const NP: usize = 32;
        const SUB: usize = 16;
        let count = 100_000usize;
        let n = normal();
        let frame = Frame::from_normal(n);
        let wo = at_angle(n, theta, 0.7);
        let b = Bsdf::new(m, None, n);
        let mut observed = [0usize; NC * NP + 1];
        let mut rng = Sampler::from_key(key);
        for _ in 0..count {
            let u = rng.next_f32();
            let u2 = rng.next_2d();
            match b.sample(wo, u, u2) {
                Some(s) => {
                    let l = frame.to_local(s.wi);
                    let c = ((l.z * NC as f32) as usize).min(NC - 1);
                    let mut phi = math::atan2(l.y, l.x);
                    if phi < 0.0 {
                        phi += 2.0 * PI;
                    }
                    let p = ((phi / (2.0 * PI) * NP as f32) as usize).min(NP - 1);
                    observed[c * NP + p] += 1;
                }
                None => observed[NC * NP] += 1,
            }
        }
        let mut expected = [0.0f64; NC * NP + 1];
        let dc = 1.0 / (NC * SUB) as f64;
        let dp = 2.0 * core::f64::consts::PI / (NP * SUB) as f64;
        let mut total = 0.0;
        for (c, row) in expected.chunks_mut(NP).take(NC).enumerate() {
            for (p, e) in row.iter_mut().enumerate() {
                let mut mass = 0.0f64;
                for i in 0..SUB {
                    let z = ((c * SUB + i) as f64 + 0.5) * dc;
                    let r = libm::sqrt(1.0 - z * z);
                    for j in 0..SUB {
                        let phi = ((p * SUB + j) as f64 + 0.5) * dp;
                        let l = Vec3::new(
                            (r * libm::cos(phi)) as f32,
                            (r * libm::sin(phi)) as f32,
                            z as f32,
                        );
                        mass += b.pdf(wo, frame.to_world(l)) as f64;
                    }
                }
                *e = mass * dc * dp * count as f64;
                total += *e;
            }
        }
        expected[NC * NP] = (count as f64 - total).max(0.0);
        let (mut chi2, mut dof) = (0.0f64, 0usize);
        let (mut pool_e, mut pool_o) = (0.0f64, 0usize);
        for (&e, &o) in expected.iter().zip(observed.iter()) {
            if e < 5.0 {
                pool_e += e;
                pool_o += o;
            } else {
                chi2 += (o as f64 - e) * (o as f64 - e) / e;
                dof += 1;
            }
        }
        if pool_e >= 5.0 {
            chi2 += (pool_o as f64 - pool_e) * (pool_o as f64 - pool_e) / pool_e;
            dof += 1;
        } else {
            assert!(
                pool_o <= 20,
                "{m:?}: {pool_o} samples where the pdf expects {pool_e}"
            );
        }
        let dof = dof.saturating_sub(1).max(1) as f64;
        // About five standard deviations above the mean of the chi-square distribution.
        let limit = dof + 5.0 * libm::sqrt(2.0 * dof);
        assert!(chi2 < limit, "{m:?} at {theta} deg: chi2 {chi2} dof {dof}");
    }

    #[test]
    fn sampling_matches_pdf() {
        let cases = [
            Material::Diffuse {
                rho_d: Vec3::splat(0.8),
            },
            plastic_iso(0.0, 1.0, 0.1),
            plastic_iso(0.0, 1.0, 0.25),
            plastic_aniso(0.0, 1.0, 0.06, 0.25),
            plastic_aniso(0.0, 1.0, 0.3, 0.1),
            Material::Ward {
                rho_d: Vec3::new(0.6, 0.5, 0.4),
                rho_s: Vec3::splat(0.2),
                alpha: 0.1,
            },
            Material::WardAnisotropic {
                rho_d: Vec3::new(0.2, 0.3, 0.4),
                rho_s: Vec3::new(0.5, 0.4, 0.3),
                alpha_u: 0.08,
                alpha_v: 0.2,
                direction: Vec3::new(0.0, 1.0, 1.0),
            },
        ];
        for (k, m) in cases.iter().enumerate() {
            for (j, theta) in [40.0, 75.0].into_iter().enumerate() {
                chi_square(m, theta, (300 + 10 * k + j) as u64);
            }
        }
    }

    #[test]
    fn reciprocity() {
        let n = normal();
        let mut rng = Sampler::from_key(7);
        let materials = [
            plastic_iso(0.3, 0.7, 0.05),
            plastic_aniso(0.3, 0.7, 0.04, 0.2),
        ];
        for m in &materials {
            let b = Bsdf::new(m, None, n);
            let mut nonzero = 0;
            for _ in 0..2000 {
                let wo = at_angle(n, 89.0 * rng.next_f32(), 2.0 * PI * rng.next_f32());
                let wi = at_angle(n, 89.0 * rng.next_f32(), 2.0 * PI * rng.next_f32());
                let (a, c) = (b.eval(wo, wi), b.eval(wi, wo));
                assert!(
                    (a - c).abs().max_element() <= 1e-5 * a.abs().max_element(),
                    "{a} {c}"
                );
                // Near the mirror direction too, where the lobe matters.
                let wr = mirror_dir(n, wo);
                let w2 = normalized(wr + 0.05 * (wi - wr));
                if n.dot(w2) > 0.0 {
                    let (a, c) = (b.eval(wo, w2), b.eval(w2, wo));
                    assert!((a - c).abs().max_element() <= 1e-5 * a.abs().max_element());
                    nonzero += (a.x > 1.0) as usize;
                }
            }
            assert!(nonzero > 100);
        }
    }

    #[test]
    fn eval_and_pdf_vanish_below_the_surface() {
        let n = normal();
        let m = plastic_aniso(0.5, 0.5, 0.1, 0.2);
        let b = Bsdf::new(&m, None, n);
        let wo = at_angle(n, 30.0, 0.0);
        let below = at_angle(n, 120.0, 2.0);
        let horizon = at_angle(n, 90.0, 1.0);
        let horizon = horizon - n * n.dot(horizon);
        assert_eq!(b.eval(wo, below), Vec3::ZERO);
        assert_eq!(b.eval(below, wo), Vec3::ZERO);
        assert_eq!(b.pdf(wo, below), 0.0);
        assert_eq!(b.pdf(below, wo), 0.0);
        assert_eq!(b.eval(wo, horizon), Vec3::ZERO);
        assert!(b.sample(below, 0.5, [0.3, 0.3]).is_none());
        assert!(b.eval(wo, at_angle(n, 30.0, 1.0)).x > 0.0);
    }

    /// The diffuse share splits `f` into its lobes: times `f` it is the diffuse lobe's
    /// value, all of a diffuse material's, none of a mirror's or below the surface.
    #[test]
    fn diffuse_share_is_the_diffuse_lobes_part_of_f() {
        let n = normal();
        let wo = at_angle(n, 30.0, 0.0);
        let rho_d = Vec3::new(0.5, 0.2, 0.0);
        let plastic = Bsdf::new(&plastic_aniso(0.5, 0.5, 0.1, 0.2), Some(rho_d), n);
        for (theta, phi) in [(10.0, 3.0), (30.0, 2.5), (60.0, 1.0), (85.0, 0.2)] {
            let wi = at_angle(n, theta, phi);
            let (f, share) = (plastic.eval(wo, wi), plastic.diffuse_share(wo, wi));
            let diffuse = rho_d * INV_PI;
            assert!(
                (share * f - diffuse).abs().max_element() <= 1e-6,
                "{share} {f}"
            );
            assert!(share.cmple(Vec3::ONE).all() && share.z == 0.0);
        }
        let mirror_direction = at_angle(n, 30.0, core::f32::consts::PI);
        let share = plastic.diffuse_share(wo, mirror_direction);
        assert!(
            share.x < 0.5,
            "the lobe's highlight is mostly the lobe's: {share}"
        );
        let lambert = Bsdf::new(&Material::Diffuse { rho_d }, None, n);
        let wi = at_angle(n, 40.0, 2.0);
        assert_eq!(lambert.diffuse_share(wo, wi), Vec3::new(1.0, 1.0, 0.0));
        assert_eq!(
            plastic.diffuse_share(wo, at_angle(n, 120.0, 2.0)),
            Vec3::ZERO
        );
        let mirror = Bsdf::new(&Material::Mirror { rho: Vec3::ONE }, None, n);
        assert_eq!(mirror.diffuse_share(wo, wi), Vec3::ZERO);
    }

    #[test]
    fn mirror_reflects() {
        let n = normal();
        let rho = Vec3::new(0.9, 0.8, 0.7);
        let b = Bsdf::new(&Material::Mirror { rho }, Some(Vec3::ONE), n);
        assert!(b.is_delta());
        let wo = at_angle(n, 35.0, 1.2);
        let s = b.sample(wo, 0.3, [0.1, 0.9]).unwrap();
        assert!(s.delta);
        assert_eq!(s.weight, rho);
        assert!((s.wi - at_angle(n, 35.0, 1.2 + PI)).length() < 1e-5);
        assert!((s.wi.dot(n) - wo.dot(n)).abs() < 1e-6);
        assert!((s.wi.length() - 1.0).abs() < 1e-6);
        assert_eq!(b.eval(wo, s.wi), Vec3::ZERO);
        assert_eq!(b.pdf(wo, s.wi), 0.0);
        assert!(!Bsdf::new(&plastic_iso(0.5, 0.5, 0.1), None, n).is_delta());
    }

    #[test]
    fn pure_specular_lobe_is_sampled_with_u_one() {
        // transport.rs samples its Ward lobes with `sample(wo, 1.0, u)`.
        let n = normal();
        let wo = at_angle(n, 50.0, 0.4);
        let b = Bsdf::new(&plastic_iso(0.0, 1.0, 0.01), None, n);
        for u in [0.0, 0.5, 1.0] {
            let s = b.sample(wo, u, [0.5, 0.5]).unwrap();
            assert!(s.wi.dot(mirror_dir(n, wo)) > 0.99, "u = {u}");
            assert!((s.pdf - b.pdf(wo, s.wi)).abs() <= 1e-6 * s.pdf);
        }
        // A diffuse-only BSDF always samples the cosine lobe, even with u = 1.
        let d = Bsdf::new(&Material::Diffuse { rho_d: Vec3::ONE }, None, n);
        let s = d.sample(wo, 1.0, [0.0, 0.0]).unwrap();
        assert!((s.wi - n).length() < 1e-5);
        // Black: nothing to sample.
        let black = Bsdf::new(&plastic_iso(0.0, 0.0, 0.1), None, n);
        assert!(black.sample(wo, 0.5, [0.5, 0.5]).is_none());
        assert_eq!(black.pdf(wo, n), 0.0);
    }

    #[test]
    fn lobe_probability() {
        assert_eq!(specular_probability(Vec3::ZERO, Vec3::ONE), 1.0);
        assert_eq!(specular_probability(Vec3::ONE, Vec3::ZERO), 0.0);
        assert!(specular_probability(Vec3::ZERO, Vec3::ZERO) < 0.0);
        assert_eq!(specular_probability(Vec3::ONE, Vec3::splat(0.01)), 0.1);
        let p = specular_probability(Vec3::splat(0.25), Vec3::splat(0.75));
        assert!((p - 0.75).abs() < 1e-6);
    }

    #[test]
    fn diffuse_map_overrides_rho_d() {
        let n = normal();
        let wo = at_angle(n, 20.0, 0.0);
        let wi = at_angle(n, 60.0, 2.0);
        let map = Vec3::new(0.1, 0.2, 0.3);
        for m in [
            Material::Diffuse {
                rho_d: Vec3::splat(0.9),
            },
            plastic_iso(0.9, 0.0, 0.1),
            plastic_aniso(0.9, 0.0, 0.1, 0.2),
        ] {
            let f = Bsdf::new(&m, Some(map), n).eval(wo, wi);
            assert!((f - map * INV_PI).abs().max_element() < 1e-7, "{m:?}: {f}");
        }
    }

    #[test]
    fn anisotropic_axes_and_fallback() {
        let n = Vec3::Z;
        let m = Material::WardAnisotropic {
            rho_d: Vec3::ZERO,
            rho_s: Vec3::ONE,
            alpha_u: 0.05,
            alpha_v: 0.2,
            direction: Vec3::new(2.0, 0.0, 1.0),
        };
        let b = Bsdf::new(&m, None, n);
        let wo = at_angle(n, 30.0, 0.0);
        // Tilting the reflection along x (the u axis, narrow) loses more than along y.
        let tilt = |d: Vec3| normalized(mirror_dir(n, wo) + 0.1 * d);
        assert!(b.eval(wo, tilt(Vec3::X)).x < 0.5 * b.eval(wo, tilt(Vec3::Y)).x);
        // Direction along n: isotropic with a = sqrt((au^2 + av^2) / 2).
        let mut par = m;
        if let Material::WardAnisotropic { direction, .. } = &mut par {
            *direction = Vec3::new(0.0, 0.0, -3.0);
        }
        let a = math::sqrt(0.5 * (0.05 * 0.05 + 0.2 * 0.2));
        let iso = Bsdf::new(&plastic_iso(0.0, 1.0, a), None, n);
        let fb = Bsdf::new(&par, None, n);
        for wi in [tilt(Vec3::X), tilt(Vec3::Y), at_angle(n, 20.0, 2.0)] {
            let (x, y) = (fb.eval(wo, wi).x, iso.eval(wo, wi).x);
            assert!((x - y).abs() <= 1e-5 * y, "{x} {y}");
        }
    }

    #[test]
    fn matches_the_formula_of_reflectance_md() {
        // Isotropic, written exactly as in reflectance.md with h not normalised.
        let n = normal();
        let (rd, rs, a) = (0.3f32, 0.6f32, 0.12f32);
        let b = Bsdf::new(&plastic_iso(rd, rs, a), None, n);
        let wo = at_angle(n, 25.0, 0.2);
        let wi = at_angle(n, 30.0, 0.2 + PI + 0.15);
        let h = wo + wi;
        let (hh, hn) = (h.dot(h), h.dot(n));
        let want = rd / PI
            + rs * hh / (PI * a * a * hn * hn * hn * hn)
                * math::exp(-(hh - hn * hn) / (hn * hn * a * a));
        let got = b.eval(wo, wi).x;
        assert!((got - want).abs() <= 1e-4 * want, "{got} {want}");
        // Anisotropic with uhat, vhat built as reflectance.md says.
        let d = Vec3::new(1.0, 1.0, 0.0);
        let (au, av) = (0.07f32, 0.2f32);
        let m = Material::WardAnisotropic {
            rho_d: Vec3::splat(rd),
            rho_s: Vec3::splat(rs),
            alpha_u: au,
            alpha_v: av,
            direction: d,
        };
        let b = Bsdf::new(&m, None, n);
        let vhat = n.cross(d).normalize();
        let uhat = vhat.cross(n);
        let (hu, hv) = (h.dot(uhat), h.dot(vhat));
        let want = rd / PI
            + rs * hh / (PI * au * av * hn * hn * hn * hn)
                * math::exp(-(hu * hu / (au * au) + hv * hv / (av * av)) / (hn * hn));
        let got = b.eval(wo, wi).x;
        assert!((got - want).abs() <= 1e-4 * want, "{got} {want}");
    }

    #[test]
    fn no_nan_on_extreme_inputs() {
        let n = normal();
        let materials = [
            plastic_iso(0.5, 0.5, 0.0),
            plastic_iso(0.5, 0.5, f32::NAN),
            plastic_iso(0.0, 1.0, 1e-6),
            plastic_aniso(0.0, 1.0, 1e-6, 0.3),
            plastic_aniso(0.2, 0.8, 3.0, 0.001),
            plastic_iso(0.0, 1.0, 5.0),
        ];
        let us = [0.0, 1e-7, 0.5, 1.0 - 1e-7, 1.0, f32::NAN, -1.0, 2.0];
        for m in &materials {
            let b = Bsdf::new(m, None, n);
            for theta in [0.0, 45.0, 89.9, 89.999, 90.0] {
                let wo = at_angle(n, theta, 0.3);
                for &u in &us {
                    for &u0 in &us {
                        for &u1 in &us {
                            if let Some(s) = b.sample(wo, u, [u0, u1]) {
                                assert!(math::is_finite(s.weight) && s.pdf.is_finite());
                                assert!(s.pdf > 0.0 && s.weight.min_element() >= 0.0);
                                assert!(math::is_finite(s.wi) && n.dot(s.wi) > 0.0);
                            }
                        }
                    }
                }
                for wi in [wo, mirror_dir(n, wo), n, at_angle(n, 89.999, 0.3 + PI)] {
                    let f = b.eval(wo, wi);
                    let p = b.pdf(wo, wi);
                    assert!(
                        math::is_finite(f) && p.is_finite() && p >= 0.0,
                        "{m:?} {f} {p}"
                    );
                }
            }
        }
    }

    #[test]
    fn from_params_resolves_by_kind() {
        let c = Vec3::new(0.8, 0.4, 0.2);
        let iso = Params::Isotropic {
            specularity: 0.25,
            roughness: 0.1,
        };
        let p = Material::from_params(Kind::Plastic, c, iso).unwrap();
        assert_eq!(
            p,
            Material::Ward {
                rho_d: c * 0.75,
                rho_s: Vec3::splat(0.25),
                alpha: 0.1
            }
        );
        let m = Material::from_params(Kind::Metal, c, iso).unwrap();
        assert_eq!(
            m,
            Material::Ward {
                rho_d: c * 0.75,
                rho_s: c * 0.25,
                alpha: 0.1
            }
        );
        let d = Vec3::new(0.0, 2.0, 0.0);
        let an = Params::Anisotropic {
            specularity: 0.5,
            roughness_u: 0.05,
            roughness_v: 0.2,
            direction: d,
        };
        assert_eq!(
            Material::from_params(Kind::Metal, c, an).unwrap(),
            Material::WardAnisotropic {
                rho_d: c * 0.5,
                rho_s: c * 0.5,
                alpha_u: 0.05,
                alpha_v: 0.2,
                direction: d
            }
        );
        // A direction whose squared length f32 cannot hold keeps its direction.
        for scale in [1e-30, 1e30] {
            let an = Params::Anisotropic {
                specularity: 0.5,
                roughness_u: 0.05,
                roughness_v: 0.2,
                direction: d * scale,
            };
            match Material::from_params(Kind::Metal, c, an).unwrap() {
                Material::WardAnisotropic { direction, .. } => assert_eq!(direction, Vec3::Y),
                other => panic!("{other:?}"),
            }
        }
        assert_eq!(
            Material::from_params(Kind::Plastic, c, Params::Diffuse).unwrap(),
            Material::Diffuse { rho_d: c }
        );
        assert_eq!(
            Material::from_params(Kind::Metal, c, Params::Mirror).unwrap(),
            Material::Mirror { rho: c }
        );
        assert_eq!(Material::Mirror { rho: c }.rho_d(), Vec3::ZERO);
        assert_eq!(p.rho_d(), c * 0.75);
        // Roughness above RADIANCE's documented 0.3 is the host's business.
        let rough = Params::Isotropic {
            specularity: 0.1,
            roughness: 0.5,
        };
        assert!(Material::from_params(Kind::Plastic, c, rough).is_ok());
    }

    #[test]
    fn from_params_rejects_bad_values() {
        let c = Vec3::splat(0.5);
        let iso = |s: f32, r: f32| Params::Isotropic {
            specularity: s,
            roughness: r,
        };
        let an = |r_u: f32, r_v: f32, d: Vec3| Params::Anisotropic {
            specularity: 0.5,
            roughness_u: r_u,
            roughness_v: r_v,
            direction: d,
        };
        let bad = |kind: Kind, color: Vec3, params: Params| match Material::from_params(
            kind, color, params,
        ) {
            Err(Error::InvalidValue { what }) => assert!(what.starts_with("material: ")),
            other => panic!("{color} {params:?}: {other:?}"),
        };
        for color in [
            Vec3::new(1.1, 0.5, 0.5),
            Vec3::new(0.5, -0.1, 0.5),
            Vec3::new(0.5, 0.5, f32::NAN),
            Vec3::new(f32::INFINITY, 0.5, 0.5),
        ] {
            bad(Kind::Plastic, color, Params::Diffuse);
            bad(Kind::Metal, color, Params::Mirror);
            bad(Kind::Plastic, color, iso(0.1, 0.1));
        }
        for s in [-0.1, 1.5, f32::NAN] {
            bad(Kind::Plastic, c, iso(s, 0.1));
        }
        for r in [0.0, -0.1, f32::NAN, f32::INFINITY] {
            bad(Kind::Metal, c, iso(0.5, r));
            bad(Kind::Metal, c, an(r, 0.1, Vec3::X));
            bad(Kind::Metal, c, an(0.1, r, Vec3::X));
        }
        bad(Kind::Plastic, c, an(0.1, 0.1, Vec3::ZERO));
        bad(
            Kind::Plastic,
            c,
            an(0.1, 0.1, Vec3::new(f32::NAN, 1.0, 0.0)),
        );
        // The boundaries are valid.
        assert!(Material::from_params(Kind::Plastic, Vec3::ONE, iso(1.0, 0.3)).is_ok());
        assert!(Material::from_params(Kind::Plastic, Vec3::ZERO, iso(0.0, 0.3)).is_ok());
    }
}
