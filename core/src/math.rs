//! The one math backend of the workspace. Everything goes through libm so floats are
//! bit-identical in debug and release, on every target, and in the host (which must call
//! these, never `f32::sin` and friends).

pub use glam::{Vec2, Vec3};

pub const PI: f32 = core::f32::consts::PI;
pub const INV_PI: f32 = core::f32::consts::FRAC_1_PI;

#[inline]
pub fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}
#[inline]
pub fn exp(x: f32) -> f32 {
    libm::expf(x)
}

/// 2^23: from it up, f32 holds only integers.
const TWO_TO_23: f32 = 8_388_608.0;

/// `t` rounded toward zero, as `t as i32` would for `|t| < 2^22`, without leaving floats:
/// the nearest integer, by adding and taking away 1.5 * 2^23, then one step back towards
/// zero where that went past `t`.
#[inline]
fn truncate(t: f32) -> f32 {
    const ROUND: f32 = 1.5 * TWO_TO_23;
    let nearest = (t + ROUND) - ROUND;
    if t >= 0.0 && nearest > t {
        nearest - 1.0
    } else if t < 0.0 && nearest < t {
        nearest + 1.0
    } else {
        nearest
    }
}

/// How many values [`exp_lanes`] takes at once.
pub const LANES: usize = 8;

/// [`exp`] of each of `x`, the same bits lane by lane, written so that the compiler
/// evaluates the lanes as vectors: a lobe fit evaluates the Ward lobe at every cached
/// sample for each of dozens of roughnesses, and libm's `expf` one call at a time was the
/// larger part of that.
///
/// It is libm's `expf` (FreeBSD's `e_expf.c`): the argument reduction `x = k ln2 + r`
/// with `ln2` in two parts, its rational approximation on `r`, and `2^k` applied by one
/// product, with its three ranges of `|x|` as selects instead of branches. Lanes where it
/// over- or underflows (`|x| >= 87.34`) or that are NaN go to libm itself.
pub fn exp_lanes(x: [f32; LANES]) -> [f32; LANES] {
    // libm's constants by their bits, which decimal literals round to only nearly.
    const LN2_HI: f32 = f32::from_bits(0x3f31_7200);
    const LN2_LO: f32 = f32::from_bits(0x35bf_be8e);
    const INV_LN2: f32 = f32::from_bits(0x3fb8_aa3b);
    const P1: f32 = f32::from_bits(0x3e2a_aa8f);
    const P2: f32 = f32::from_bits(0xbb35_5215);
    /// `|x|`'s bits from which libm's special cases start (87.34, then infinities, NaN).
    const SPECIAL: u32 = 0x42ae_ac50;
    let mut out = [0.0; LANES];
    let mut special = false;
    for (out, &v) in out.iter_mut().zip(&x) {
        let magnitude = v.to_bits() & 0x7fff_ffff;
        let negative = v.to_bits() >> 31 != 0;
        special |= magnitude >= SPECIAL;
        // libm's three reductions: k by rounding beyond 1.5 ln2, +-1 beyond 0.5 ln2, and
        // none (k = 0: the same sums with `hi = v`, `lo = 0`) below. In floats, so that
        // no lane needs a conversion to an integer.
        let k = if magnitude > 0x3f85_1592 {
            truncate(INV_LN2 * v + if negative { -0.5 } else { 0.5 })
        } else if magnitude > 0x3eb1_7218 {
            if negative {
                -1.0
            } else {
                1.0
            }
        } else {
            0.0
        };
        let hi = v - k * LN2_HI;
        let lo = k * LN2_LO;
        let r = hi - lo;
        let rr = r * r;
        let c = r - rr * (P1 + rr * P2);
        let y = 1.0 + (r * c / (2.0 - c) - lo + hi);
        // `2^k`, exact, as libm's scalbnf applies it for k in [-126, 127] (the only k of
        // the lanes kept): `k + 127` is the low bits of `k + 127 + 2^23`.
        let biased = k.clamp(-126.0, 127.0) + (127.0 + TWO_TO_23);
        let scale = f32::from_bits((biased.to_bits() & 0x7f_ffff) << 23);
        *out = if magnitude > 0x3900_0000 {
            y * scale
        } else {
            1.0 + v
        };
    }
    if special {
        for (out, &v) in out.iter_mut().zip(&x) {
            if v.to_bits() & 0x7fff_ffff >= SPECIAL {
                *out = libm::expf(v);
            }
        }
    }
    out
}
#[inline]
pub fn ln(x: f32) -> f32 {
    libm::logf(x)
}
#[inline]
pub fn sin(x: f32) -> f32 {
    libm::sinf(x)
}
#[inline]
pub fn cos(x: f32) -> f32 {
    libm::cosf(x)
}
#[inline]
pub fn tan(x: f32) -> f32 {
    libm::tanf(x)
}
#[inline]
pub fn atan(x: f32) -> f32 {
    libm::atanf(x)
}
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    libm::atan2f(y, x)
}
#[inline]
pub fn acos(x: f32) -> f32 {
    libm::acosf(x.clamp(-1.0, 1.0))
}
#[inline]
pub fn floor(x: f32) -> f32 {
    libm::floorf(x)
}
#[inline]
pub fn powf(x: f32, y: f32) -> f32 {
    libm::powf(x, y)
}
#[inline]
pub fn abs(x: f32) -> f32 {
    libm::fabsf(x)
}
/// Degrees to radians.
#[inline]
pub fn radians(deg: f32) -> f32 {
    deg * (PI / 180.0)
}

/// Rec. 709 luminance of a linear RGB value.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// True when every component is finite.
#[inline]
pub fn is_finite(v: Vec3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// A user's direction (a material's `direction_u`) whose squared length f32
/// cannot hold (it underflows or overflows, as at lengths 1e-30 or 1e30), scaled to a
/// largest component of 1; any other vector unchanged, so that ordinary inputs keep their
/// exact bits. Only the direction of such vectors counts.
pub fn representable_direction(v: Vec3) -> Vec3 {
    let m = v.abs().max_element();
    if v.length_squared().is_normal() || !(m > 0.0) || !m.is_finite() {
        v
    } else {
        v / m
    }
}

/// `v` scaled by a power of two, exactly, to a largest component in [1, 2) (the zero
/// vector and one with a component not finite unchanged): the same direction, whose
/// squares, and whose cross product with another so scaled, f32 holds at any length of
/// `v`. Scaling by a power of two commutes with every rounding until a product leaves
/// f32's normal range, so a direction normalised, or crossed with another and then
/// normalised, has the same bits as from `v` itself wherever those stayed in range.
pub fn scaled_to_unit_size(v: Vec3) -> Vec3 {
    let m = v.abs().max_element();
    if !(m > 0.0 && m.is_finite()) {
        return v;
    }
    // m = f 2^e with f in [0.5, 1): m 2^(1 - e) is in [1, 2).
    let (_, e) = libm::frexpf(m);
    Vec3::from_array(v.to_array().map(|c| libm::scalbnf(c, 1 - e)))
}

/// An orthonormal basis whose `z` is the given unit normal (Duff et al. 2017, branchless).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub x: Vec3,
    pub y: Vec3,
    pub z: Vec3,
}

impl Frame {
    pub fn from_normal(n: Vec3) -> Frame {
        let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let x = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let y = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { x, y, z: n }
    }

    /// A frame with `z = n` and `x` along the projection of `direction` onto the surface
    /// (RADIANCE's plastic2/metal2 convention: `v = normalize(n x d)`, `u = v x n`).
    /// Falls back to [`Frame::from_normal`] when `direction` is parallel to `n`.
    pub fn from_normal_and_direction(n: Vec3, direction: Vec3) -> Frame {
        let v = n.cross(direction);
        let len2 = v.length_squared();
        if !(len2 > 1e-12) {
            return Frame::from_normal(n);
        }
        let y = v * (1.0 / sqrt(len2));
        let x = y.cross(n);
        Frame { x, y, z: n }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.x), v.dot(self.y), v.dot(self.z))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.x * v.x + self.y * v.y + self.z * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `exp_lanes` against libm's `expf` over `x`, lane by lane, bit for bit.
    fn assert_same_bits(x: [f32; LANES]) {
        let lanes = exp_lanes(x);
        for (v, got) in x.iter().zip(lanes) {
            let want = libm::expf(*v);
            assert_eq!(
                got.to_bits(),
                want.to_bits(),
                "exp({v:e}) = {got:e}, libm {want:e}"
            );
        }
    }

    /// Every 1021st float in [-128, 128] (over two million, both signs), and every float
    /// within 16 ulps of the bounds of libm's ranges of `|x|`.
    #[test]
    fn exp_lanes_are_libms_expf_to_the_bit() {
        let mut values = std::vec::Vec::new();
        let top = 128.0f32.to_bits();
        for bits in (0..=top).step_by(1021) {
            values.push(f32::from_bits(bits));
        }
        for bound in [
            0x3900_0000u32,
            0x3eb1_7218,
            0x3f85_1592,
            0x42ae_ac50,
            0x42b1_7218,
        ] {
            values.extend((bound - 16..=bound + 16).map(f32::from_bits));
        }
        values.extend([0.0, f32::INFINITY, f32::NAN, 200.0]);
        let negated: std::vec::Vec<f32> = values.iter().map(|v| -v).collect();
        values.extend(negated);
        for chunk in values.chunks(LANES) {
            let mut batch = [0.5f32; LANES];
            batch[..chunk.len()].copy_from_slice(chunk);
            assert_same_bits(batch);
        }
    }
}
