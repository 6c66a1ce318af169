//! Views inside a closed surface that no light is inside. No light reaches anything such a
//! view sees, whatever the materials, so a render of its pixels is black and the fits
//! pull every colour they touch toward the bound to explain the panorama there: a camera
//! placed inside cornell's sphere turned the sphere into an anisotropic metal from the
//! 64 pixels of its inside (docs/stability.md, "Fuzzed"). Such a view is told of and its
//! pixels are left out.
//!
//! A surface is closed when every edge of its non-degenerate triangles is shared by an
//! even number of them (a watertight mesh; the corners compared as bits, as OBJ vertices
//! shared by index are). A point is inside it when a ray from it crosses the surface an
//! odd number of times, decided by the majority of three rays so that a ray through an
//! edge does not decide alone. A thin panel seen from behind is open, and a room's walls
//! hold its lights: neither is told of.

use std::collections::HashMap;

use glam::Vec3;
use relume_core::geometry::{Surface, Triangle, View};

/// A view whose position lies inside a closed group no light is inside.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EnclosedView {
    pub view: usize,
    pub group: u16,
}

/// Three directions no axis-aligned or diagonal face of a model is likely to hold.
const PARITY_RAYS: [[f32; 3]; 3] = [
    [0.534_522, 0.267_261, 0.801_784],
    [-0.711_512, 0.613_413, 0.342_997],
    [0.155_167, -0.898_546, -0.410_571],
];

/// Where a light's emission starts, as a fraction of the scene's size in front of its
/// largest triangle: a ceiling panel flush with the ceiling is inside the room by it.
const LIGHT_POINT_OFFSET: f32 = 1e-4;

/// The views inside a closed group that holds no light's emitting side, with the first
/// such group (in group order) for each.
pub fn enclosed_views(triangles: &[Triangle], views: &[View]) -> Vec<EnclosedView> {
    let closed = closed_groups(triangles);
    if closed.is_empty() {
        return Vec::new();
    }
    let size = relume_core::geometry::longest_side(triangles);
    let light_points = light_points(triangles, size * LIGHT_POINT_OFFSET);
    // Per view, the first closed group holding it; a group's lights are looked for once,
    // and only where it holds a view.
    let mut found = Vec::new();
    let mut lit: Vec<Option<bool>> = vec![None; closed.len()];
    for (vi, view) in views.iter().enumerate() {
        for (s, surface) in closed.iter().enumerate() {
            if !surface.holds(view.position) {
                continue;
            }
            let holds_a_light =
                *lit[s].get_or_insert_with(|| light_points.iter().any(|&(_, p)| surface.holds(p)));
            if !holds_a_light {
                found.push(EnclosedView {
                    view: vi,
                    group: surface.group,
                });
                break;
            }
        }
    }
    found
}

/// Where no light reaches what the views see: the lights (by index) inside a closed group
/// that holds no view, with the first such group for each. A lamp inside a closed box
/// sheds no light past it, and the refusal listed every cause but that one.
pub fn enclosed_lights(triangles: &[Triangle], views: &[View]) -> Vec<(u16, u16)> {
    let closed = closed_groups(triangles);
    let size = relume_core::geometry::longest_side(triangles);
    let mut found = Vec::new();
    for (light, point) in light_points(triangles, size * LIGHT_POINT_OFFSET) {
        let enclosing = closed
            .iter()
            .find(|c| c.holds(point) && !views.iter().any(|v| c.holds(v.position)));
        if let Some(c) = enclosing {
            found.push((light, c.group));
        }
    }
    found
}

/// [`enclosed_lights`] as words for a refusal or a warning that no light reaches the
/// views: "; light 'lamp' is inside group 'box', ..." (empty where none is).
pub fn enclosed_lights_said(
    triangles: &[Triangle],
    views: &[View],
    light_names: &[String],
    group_names: &[String],
) -> String {
    enclosed_lights(triangles, views)
        .iter()
        .map(|&(l, g)| {
            format!(
                "; light '{}' is inside group '{}', a closed surface that no view is inside, so none of its light reaches what the views see",
                light_names[l as usize], group_names[g as usize]
            )
        })
        .collect()
}

/// A closed group's triangles, with their bounds.
struct ClosedSurface {
    group: u16,
    triangles: Vec<[Vec3; 3]>,
    lo: Vec3,
    hi: Vec3,
}

impl ClosedSurface {
    /// Whether `p` is inside: an odd number of crossings on at least two of three rays.
    fn holds(&self, p: Vec3) -> bool {
        if p.cmplt(self.lo).any() || p.cmpgt(self.hi).any() {
            return false;
        }
        let odd = PARITY_RAYS
            .iter()
            .filter(|d| {
                let d = Vec3::from_array(**d);
                let crossings = (self.triangles.iter()).filter(|t| crosses(p, d, t)).count();
                crossings % 2 == 1
            })
            .count();
        odd >= 2
    }
}

/// Whether the ray from `origin` along `dir` crosses the triangle ahead of it
/// (Moller-Trumbore).
fn crosses(origin: Vec3, dir: Vec3, [a, b, c]: &[Vec3; 3]) -> bool {
    let (e1, e2) = (*b - *a, *c - *a);
    let pv = dir.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 {
        return false;
    }
    let tv = origin - *a;
    let u = tv.dot(pv) / det;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let qv = tv.cross(e1);
    let v = dir.dot(qv) / det;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    e2.dot(qv) / det > 0.0
}

/// The groups whose non-degenerate triangles share every edge an even number of times.
fn closed_groups(triangles: &[Triangle]) -> Vec<ClosedSurface> {
    let mut by_group: std::collections::BTreeMap<u16, Vec<&Triangle>> = Default::default();
    for t in triangles {
        if let Surface::Group(g) = t.surface {
            if t.area() > 0.0 {
                by_group.entry(g).or_default().push(t);
            }
        }
    }
    let bits = |p: Vec3| p.to_array().map(f32::to_bits);
    let mut closed = Vec::new();
    for (group, tris) in by_group {
        // A closed surface needs four faces at least.
        if tris.len() < 4 {
            continue;
        }
        let mut edges: HashMap<[[u32; 3]; 2], u32> = HashMap::with_capacity(3 * tris.len());
        for t in &tris {
            for k in 0..3 {
                let mut edge = [bits(t.v[k]), bits(t.v[(k + 1) % 3])];
                edge.sort_unstable();
                *edges.entry(edge).or_default() += 1;
            }
        }
        if edges.values().any(|n| n % 2 == 1) {
            continue;
        }
        let triangles: Vec<[Vec3; 3]> = tris.iter().map(|t| t.v).collect();
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for p in triangles.iter().flatten() {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        closed.push(ClosedSurface {
            group,
            triangles,
            lo,
            hi,
        });
    }
    closed
}

/// One point per light, with its index: `offset` in front of the centre of its largest
/// triangle, on the side it emits from.
fn light_points(triangles: &[Triangle], offset: f32) -> Vec<(u16, Vec3)> {
    let mut largest: std::collections::BTreeMap<u16, &Triangle> = Default::default();
    for t in triangles {
        if let Surface::Light(l) = t.surface {
            let entry = largest.entry(l).or_insert(t);
            if t.area() > entry.area() {
                *entry = t;
            }
        }
    }
    largest
        .iter()
        .filter_map(|(&l, t)| {
            let normal = t.normal_area2().try_normalize()?;
            let centre = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
            Some((l, centre + offset * normal))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    /// A cube's twelve triangles, outward, for `surface`.
    fn cube(lo: Vec3, hi: Vec3, surface: Surface) -> Vec<Triangle> {
        let corner = |i: usize| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        };
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        quads
            .iter()
            .flat_map(|q| {
                [[q[0], q[1], q[2]], [q[0], q[2], q[3]]].map(|[a, b, c]| Triangle {
                    v: [corner(a), corner(b), corner(c)],
                    uv: [Vec2::ZERO; 3],
                    surface,
                })
            })
            .collect()
    }

    fn view_at(position: Vec3) -> View {
        View::new(position, Vec3::X, Vec3::Z, [90.0, 90.0], [4, 4]).unwrap()
    }

    /// A room (a closed box holding a light) with a closed crate in it and an open shelf:
    /// a view in the crate is told of, views in the room, and behind the shelf, are not.
    #[test]
    fn a_view_inside_a_closed_group_without_a_light_is_found() {
        let mut triangles = cube(Vec3::splat(-5.0), Vec3::splat(5.0), Surface::Group(0));
        triangles.extend(cube(Vec3::splat(1.0), Vec3::splat(2.0), Surface::Group(1)));
        // The shelf: the crate's top face alone, lower.
        let mut shelf = cube(Vec3::splat(-3.0), Vec3::splat(-2.0), Surface::Group(2));
        shelf.truncate(2);
        triangles.extend(shelf);
        // A ceiling panel flush with the ceiling, emitting down.
        triangles.push(Triangle {
            v: [
                Vec3::new(-1.0, -1.0, 5.0),
                Vec3::new(0.0, 1.0, 5.0),
                Vec3::new(1.0, -1.0, 5.0),
            ],
            uv: [Vec2::ZERO; 3],
            surface: Surface::Light(0),
        });
        let views = [
            view_at(Vec3::ZERO),
            view_at(Vec3::splat(1.5)),
            view_at(Vec3::new(-2.5, -2.5, -2.5)),
            view_at(Vec3::new(-2.5, -2.5, -3.5)),
        ];
        let found = enclosed_views(&triangles, &views);
        assert_eq!(found, [EnclosedView { view: 1, group: 1 }]);

        // With one face of the crate gone, it is open and nothing is told of.
        let mut open = triangles.clone();
        open.drain(12..14);
        assert_eq!(enclosed_views(&open, &views), []);

        assert_eq!(enclosed_lights(&triangles, &views), []);

        // With the light inside the crate, nothing is told of the views; the light is
        // enclosed while no view is in the crate with it.
        let last = triangles.len() - 1;
        triangles[last].v = triangles[last].v.map(|p| p * 0.1 + Vec3::splat(1.5));
        assert_eq!(enclosed_views(&triangles, &views), []);
        assert_eq!(enclosed_lights(&triangles, &views), []);
        let outside = [views[0], views[2]];
        assert_eq!(enclosed_lights(&triangles, &outside), [(0, 1)]);
        let said = enclosed_lights_said(
            &triangles,
            &outside,
            &["lamp".into()],
            &["room".into(), "crate".into(), "shelf".into()],
        );
        assert!(
            said.starts_with(
                "; light 'lamp' is inside group 'crate', a closed surface that no view is inside"
            ),
            "{said}"
        );
    }

    /// Parity from inside and outside a cube, for a point on the rays' axis-aligned
    /// diagonals too.
    #[test]
    fn a_point_is_inside_a_closed_surface_by_the_parity_of_its_crossings() {
        let surface = closed_groups(&cube(Vec3::ZERO, Vec3::ONE, Surface::Group(3)))
            .pop()
            .unwrap();
        assert_eq!(surface.group, 3);
        for (p, inside) in [
            ([0.5, 0.5, 0.5], true),
            ([0.01, 0.99, 0.5], true),
            ([1.5, 0.5, 0.5], false),
            ([0.5, 0.5, -0.01], false),
        ] {
            assert_eq!(surface.holds(Vec3::from_array(p)), inside, "{p:?}");
        }
    }
}
