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

/// A user's direction (a view's, a material's `direction_u`) whose squared length f32
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
