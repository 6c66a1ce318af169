//! The texture coordinates of a flat group as an affine function of the surface point:
//! what RADIANCE needs to place a `colorpict` (`output::radiance`).

use glam::Vec3;
use relume_core::geometry::{longest_side, Surface, Triangle};

use super::super::Recovery;

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
    use glam::Vec2;

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
}
