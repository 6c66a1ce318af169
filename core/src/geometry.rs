//! Rays, triangles, surfaces and views: the geometric vocabulary of the core.

use crate::error::Error;
use crate::math::{self, Vec2, Vec3};

/// A ray `origin + t * direction`, `t` in `(0, t_max)`. `direction` is unit length.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    pub direction: Vec3,
}

impl Ray {
    #[inline]
    pub fn new(origin: Vec3, direction: Vec3) -> Ray {
        Ray { origin, direction }
    }

    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.direction * t
    }
}

/// What a triangle belongs to: a material group, or a light source. Indices point into
/// the scene's group and light tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Surface {
    Group(u16),
    Light(u16),
}

/// One triangle of the scene, with its texture coordinates (OBJ `vt`, zero where absent).
/// The front side is the counter-clockwise one: its normal is `(v1 - v0) x (v2 - v0)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub v: [Vec3; 3],
    pub uv: [Vec2; 3],
    pub surface: Surface,
}

/// The longest side of the triangles' bounding box (0 with none): a scene's or a group's
/// size, which tolerances and ray offsets are measured in so that they do not depend on
/// the unit of length.
pub fn longest_side<'a>(triangles: impl IntoIterator<Item = &'a Triangle>) -> f32 {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for triangle in triangles {
        let (a, b) = triangle.bounds();
        lo = lo.min(a);
        hi = hi.max(b);
    }
    (hi - lo).max_element().max(0.0)
}

impl Triangle {
    /// The unnormalised front normal; its length is twice the area.
    #[inline]
    pub fn normal_area2(&self) -> Vec3 {
        (self.v[1] - self.v[0]).cross(self.v[2] - self.v[0])
    }

    #[inline]
    pub fn area(&self) -> f32 {
        0.5 * self.normal_area2().length()
    }

    /// Point at barycentric `(b1, b2)` (weights of `v1` and `v2`).
    #[inline]
    pub fn point(&self, b1: f32, b2: f32) -> Vec3 {
        self.v[0] * (1.0 - b1 - b2) + self.v[1] * b1 + self.v[2] * b2
    }

    /// Texture coordinate at barycentric `(b1, b2)`.
    #[inline]
    pub fn uv_at(&self, b1: f32, b2: f32) -> Vec2 {
        self.uv[0] * (1.0 - b1 - b2) + self.uv[1] * b1 + self.uv[2] * b2
    }

    /// Axis-aligned bounds `(min, max)`.
    #[inline]
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (
            self.v[0].min(self.v[1]).min(self.v[2]),
            self.v[0].max(self.v[1]).max(self.v[2]),
        )
    }
}

/// A pinhole view with RADIANCE `rpict -vtv` geometry (scene-format.md, "Views").
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub position: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit image right, scaled by `2 tan(fov_h / 2)`.
    pub right_span: Vec3,
    /// Unit image up, scaled by `2 tan(fov_v / 2)`.
    pub up_span: Vec3,
    pub width: u32,
    pub height: u32,
}

impl View {
    /// Checks the view and precomputes its frame. `fov_deg` are the full angles.
    pub fn new(
        position: Vec3,
        direction: Vec3,
        up: Vec3,
        fov_deg: [f32; 2],
        size: [u32; 2],
    ) -> Result<View, Error> {
        if !math::is_finite(position) || !math::is_finite(direction) || !math::is_finite(up) {
            return Err(Error::InvalidValue {
                what: "view position, direction and up must be finite",
            });
        }
        // Both at unit size: the frame squares their cross product, the fourth power of
        // their size, which left f32 from a size of 1e10 (or 1e-12) on.
        let direction = math::scaled_to_unit_size(direction);
        let up = math::scaled_to_unit_size(up);
        if !(direction.length_squared() > 0.0) {
            return Err(Error::InvalidValue {
                what: "view direction must not be zero",
            });
        }
        let forward = direction.normalize();
        let right = direction.cross(up);
        if !(right.length_squared() > 1e-12 * direction.length_squared() * up.length_squared()) {
            return Err(Error::InvalidValue {
                what: "view up must not be zero or parallel to the direction",
            });
        }
        let right = right.normalize();
        let up_dir = right.cross(forward);
        for fov in fov_deg {
            if !(fov > 0.0 && fov < 180.0) {
                return Err(Error::InvalidValue {
                    what: "view fov_deg must be in (0, 180) degrees",
                });
            }
        }
        for side in size {
            if side == 0 || side > crate::config::MAX_VIEW_SIDE {
                return Err(Error::Capacity {
                    what: "MAX_VIEW_SIDE (pixels per view side, at least 1)",
                    max: crate::config::MAX_VIEW_SIDE as usize,
                    needed: side as usize,
                });
            }
        }
        let span_h = 2.0 * math::tan(math::radians(fov_deg[0]) * 0.5);
        let span_v = 2.0 * math::tan(math::radians(fov_deg[1]) * 0.5);
        Ok(View {
            position,
            forward,
            right_span: right * span_h,
            up_span: up_dir * span_v,
            width: size[0],
            height: size[1],
        })
    }

    /// The ray through image position `(x, y)` in pixel units: `x` in `[0, width]` from the
    /// left edge, `y` in `[0, height]` from the top. Pixel `(i, j)`'s centre is
    /// `(i + 0.5, j + 0.5)`.
    #[inline]
    pub fn ray(&self, x: f32, y: f32) -> Ray {
        let sx = x / self.width as f32 - 0.5;
        let sy = 0.5 - y / self.height as f32;
        let d = self.forward + self.right_span * sx + self.up_span * sy;
        Ray::new(self.position, d.normalize())
    }

    /// The row-major index of pixel `(x, y)`, which keys its random streams. A pixel
    /// outside the view (which a caller may render: its ray is well defined) wraps round
    /// rather than overflow.
    #[inline]
    pub fn pixel_index(&self, x: u32, y: u32) -> u32 {
        y.wrapping_mul(self.width).wrapping_add(x)
    }

    #[inline]
    pub fn n_pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_pixel_looks_forward_and_corners_follow_rpict() {
        let v = View::new(Vec3::ZERO, Vec3::X, Vec3::Z, [90.0, 90.0], [2, 2]).unwrap();
        let c = v.ray(1.0, 1.0);
        assert!((c.direction - Vec3::X).length() < 1e-6);
        // Top-left corner of the image: right = X x Z = -Y, so left is +Y; top is +Z.
        let tl = v.ray(0.0, 0.0).direction;
        let expect = Vec3::new(1.0, 1.0, 1.0).normalize();
        assert!((tl - expect).length() < 1e-5, "{tl:?}");
    }

    #[test]
    fn degenerate_views_are_errors() {
        assert!(View::new(Vec3::ZERO, Vec3::X, Vec3::X, [90.0, 90.0], [4, 4]).is_err());
        assert!(View::new(Vec3::ZERO, Vec3::ZERO, Vec3::Z, [90.0, 90.0], [4, 4]).is_err());
        assert!(View::new(Vec3::ZERO, Vec3::X, Vec3::Z, [180.0, 90.0], [4, 4]).is_err());
        assert!(View::new(Vec3::ZERO, Vec3::X, Vec3::Z, [90.0, 90.0], [0, 4]).is_err());
    }

    /// Only the directions of `direction` and `up` count, at any length f32 holds (the
    /// squares of 1e-30 and 1e30 underflow and overflow).
    #[test]
    fn a_view_is_the_same_at_any_length_of_direction_and_up() {
        let view = |d: Vec3, u: Vec3| View::new(Vec3::ZERO, d, u, [60.0, 45.0], [8, 6]).unwrap();
        let unit = view(Vec3::new(1.0, 2.0, -0.5), Vec3::Z);
        for scale in [1e-30, 1e-3, 7.0, 1e30] {
            let v = view(Vec3::new(1.0, 2.0, -0.5) * scale, Vec3::Z * (1.0 / scale));
            for (x, y) in [(0.0, 0.0), (3.5, 2.0), (8.0, 6.0)] {
                let (a, b) = (v.ray(x, y).direction, unit.ray(x, y).direction);
                assert!(
                    (a - b).length() < 1e-6,
                    "scale {scale}: {a:?} against {b:?}"
                );
            }
        }
    }

    /// The rays of `rpict -vtv` (scene-format.md, "Views") in f64, from `direction` and
    /// `up` of any length: the formula as the spec writes it.
    fn rpict_ray(
        d: [f64; 3],
        up: [f64; 3],
        fov_deg: [f64; 2],
        size: [f64; 2],
        x: f64,
        y: f64,
    ) -> [f64; 3] {
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let unit = |a: [f64; 3]| {
            let l = libm::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
            a.map(|c| c / l)
        };
        let (f, r) = (unit(d), unit(cross(d, up)));
        let u = cross(r, f);
        let (sx, sy) = (x / size[0] - 0.5, 0.5 - y / size[1]);
        let (th, tv) = fov_deg
            .map(|a| 2.0 * libm::tan(a.to_radians() * 0.5))
            .into();
        unit(core::array::from_fn(|k| {
            f[k] + sx * th * r[k] + sy * tv * u[k]
        }))
    }

    /// A direction and an up both long (or both short) are a view like any other: their
    /// cross product, the square of their size, once overflowed f32 (from 1e10: the
    /// image's right and up were zero, every pixel looked straight ahead, silently; from
    /// 1e15 the view was refused as "up parallel to the direction") or underflowed it
    /// (1e-12).
    #[test]
    fn a_view_of_long_or_short_direction_and_up_follows_rpict() {
        let (d, up) = ([1.0f64, 2.0, -0.5], [0.0f64, 0.0, 1.0]);
        for scale in [1e10f64, 1e15, 1e18, 1e-12, 1e-18] {
            let at = |v: [f64; 3]| Vec3::from_array(v.map(|c| (c * scale) as f32));
            let view = View::new(Vec3::ZERO, at(d), at(up), [60.0, 45.0], [8, 6])
                .unwrap_or_else(|e| panic!("scale {scale:e}: {e}"));
            for (x, y) in [(0.0, 0.0), (3.5, 2.0), (8.0, 6.0), (1.0, 5.5)] {
                let got = view.ray(x, y).direction;
                let want = rpict_ray(d, up, [60.0, 45.0], [8.0, 6.0], x as f64, y as f64);
                let want = Vec3::from_array(want.map(|c| c as f32));
                assert!(
                    (got - want).length() < 1e-6,
                    "scale {scale:e}, ({x}, {y}): {got:?} against {want:?}"
                );
            }
        }
    }
}
