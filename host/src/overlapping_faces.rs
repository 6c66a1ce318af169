//! Faces of two groups that overlap in one plane where a view sees them: a picture
//! modelled as a quad on its wall's plane, a rug on the floor's, a wall tessellated twice
//! for two materials. Where they overlap, the ray tracer's closest hit is a tie, and which
//! group a view sees, and which one light bounces off, is left to its tie rule (the lower
//! triangle index, an accident of the OBJ's order), or to rounding where they are not
//! exactly one plane.
//! Faces a hair apart are no better: a path leaving one starts `RAY_EPSILON` of the
//! scene's size off it ([`crate::light_placement`]'s slack), beyond the other, so light
//! passes through. Exact copies are [`crate::repeated_triangles`]' to tell.
//!
//! An overlap no view sees is left alone: a box standing on the floor has its bottom in
//! the floor's plane, and a frame its back in the wall's, but both are closed over, and
//! every reference scene has such faces.
//!
//! Triangles are gathered by plane (a rounded normal and offset, so that only faces that
//! may be coplanar meet), and within a plane that holds several groups, a sweep over
//! their extents in the plane tests only pairs whose boxes overlap.

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::hash::{DefaultHasher, Hash, Hasher};

use relume_core::geometry::{longest_side, Ray, Surface, Triangle, View};
use relume_core::math::Vec3;
use relume_core::render::RAY_EPSILON;
use relume_core::scene::Scene;

use crate::assemble::OwnedScene;
use crate::error::Error;
use crate::light_placement::SLACK_IN_EPSILONS;
use crate::repeated_triangles::corners_key;
use crate::text::{counted, significant};

/// Steps per unit of a normal's components when planes are gathered: a face and one
/// turned by more than about 1/NORMAL_STEPS radians never meet.
const NORMAL_STEPS: f64 = 64.0;

/// How close to a rounding boundary a normal's component must be for a face to be put in
/// the neighbouring gathering too (so that two faces on either side of it still meet).
const NORMAL_MARGIN: f64 = 0.05;

/// Faces this close (as a share of the slack) are in one plane: their tie is the tracer's.
const TIE_SHARE_OF_SLACK: f64 = 0.01;

/// Points of overlap kept per pair of groups, to look for from the views.
const POINTS_PER_PAIR: usize = 32;

/// Triangle pairs counted per pair of groups. Past it the warning says "at least", and no
/// more of those two groups' faces are tested: faces that all overlap one another would
/// otherwise cost the square of their number (20,000 thin triangles of two groups in one
/// plane took minutes to `check`).
const MAX_COUNTED_PAIRS: usize = 10_000;

/// A face prepared for the tests, in f64.
struct Face {
    triangle: usize,
    surface: Surface,
    /// Unit normal, turned so that its largest component is positive.
    normal: [f64; 3],
    /// Whether the triangle's own front normal is `normal` (not turned).
    front: bool,
    corners: [[f64; 3]; 3],
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

impl Face {
    /// None for a triangle of no area.
    fn new(triangle: usize, t: &Triangle) -> Option<Face> {
        let corners = t.v.map(|p| p.to_array().map(f64::from));
        let n = cross(sub(corners[1], corners[0]), sub(corners[2], corners[0]));
        let length = dot(n, n).sqrt();
        if !(length > 0.0 && length.is_finite()) {
            return None;
        }
        let largest = (0..3)
            .max_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs()))
            .unwrap_or(2);
        let sign = if n[largest] < 0.0 { -1.0 } else { 1.0 };
        Some(Face {
            triangle,
            surface: t.surface,
            normal: n.map(|c| c * sign / length),
            front: sign > 0.0,
            corners,
        })
    }

    fn offset(&self) -> f64 {
        dot(self.normal, self.corners[0])
    }

    /// The largest distance of `other`'s corners from this face's plane.
    fn distance_to(&self, other: &Face) -> f64 {
        let d = self.offset();
        other
            .corners
            .iter()
            .map(|&c| (dot(self.normal, c) - d).abs())
            .fold(0.0, f64::max)
    }
}

/// Two in-plane axes for faces of unit normal `n`.
fn plane_axes(n: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let helper = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = cross(n, helper);
    let ul = dot(u, u).sqrt();
    let u = u.map(|c| c / ul);
    (u, cross(n, u))
}

/// Whether two triangles of one plane, given in its 2-D coordinates, overlap by more than
/// `margin` across on every separating axis: a shared edge or corner is no overlap.
fn overlap_2d(a: [[f64; 2]; 3], b: [[f64; 2]; 3], margin: f64) -> bool {
    let axes = (0..3).flat_map(|i| {
        [a, b].map(|t| {
            let (p, q) = (t[i], t[(i + 1) % 3]);
            let (ex, ey) = (q[0] - p[0], q[1] - p[1]);
            let l = (ex * ex + ey * ey).sqrt();
            [-ey / l, ex / l]
        })
    });
    let extent = |t: [[f64; 2]; 3], axis: [f64; 2]| {
        let s = t.map(|p| p[0] * axis[0] + p[1] * axis[1]);
        (s[0].min(s[1]).min(s[2]), s[0].max(s[1]).max(s[2]))
    };
    axes.filter(|axis| axis[0].is_finite() && axis[1].is_finite())
        .all(|axis| {
            let (a0, a1) = extent(a, axis);
            let (b0, b1) = extent(b, axis);
            a1.min(b1) - a0.max(b0) > margin
        })
}

/// What was found for one pair of groups.
#[derive(Default)]
struct Overlap {
    pairs: usize,
    /// The largest distance between overlapping faces' planes.
    apart: f64,
    /// Points inside overlaps (of the first [`POINTS_PER_PAIR`] pairs of triangles).
    points: Vec<[f64; 3]>,
}

/// Where `face`'s part of `region` lies: the mean corner of the polygon that clipping
/// triangle `a` by triangle `b` leaves (both in the plane's 2-D coordinates along `u`
/// and `v`), put back on `face`'s plane. None when the clip leaves nothing.
fn overlap_point(
    a: [[f64; 2]; 3],
    b: [[f64; 2]; 3],
    (u, v): ([f64; 3], [f64; 3]),
    face: &Face,
) -> Option<[f64; 3]> {
    let twice_area = |t: [[f64; 2]; 3]| {
        (t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (t[1][1] - t[0][1])
    };
    let turn = if twice_area(b) < 0.0 { -1.0 } else { 1.0 };
    let mut polygon: Vec<[f64; 2]> = a.to_vec();
    for i in 0..3 {
        let (p, q) = (b[i], b[(i + 1) % 3]);
        let side =
            |x: [f64; 2]| turn * ((q[0] - p[0]) * (x[1] - p[1]) - (q[1] - p[1]) * (x[0] - p[0]));
        let mut clipped = Vec::with_capacity(polygon.len() + 1);
        for k in 0..polygon.len() {
            let (c, d) = (polygon[k], polygon[(k + 1) % polygon.len()]);
            let (sc, sd) = (side(c), side(d));
            if sc >= 0.0 {
                clipped.push(c);
            }
            if (sc >= 0.0) != (sd >= 0.0) {
                let t = sc / (sc - sd);
                clipped.push([c[0] + t * (d[0] - c[0]), c[1] + t * (d[1] - c[1])]);
            }
        }
        polygon = clipped;
    }
    if polygon.is_empty() {
        return None;
    }
    let n = polygon.len() as f64;
    let x = polygon.iter().map(|p| p[0]).sum::<f64>() / n;
    let y = polygon.iter().map(|p| p[1]).sum::<f64>() / n;
    let offset = face.offset();
    Some([0, 1, 2].map(|i| u[i] * x + v[i] * y + face.normal[i] * offset))
}

/// Warnings for groups whose faces overlap in one plane, or within the renderer's ray
/// slack of it, where a view sees the overlap: one per pair of groups, naming the view,
/// a point and the number of triangle pairs.
pub fn overlapping_face_warnings(owned: &mut OwnedScene) -> Result<Vec<String>, Error> {
    let slack = f64::from(SLACK_IN_EPSILONS * RAY_EPSILON * longest_side(owned.triangles()));
    let found = find_overlaps(owned.triangles(), slack);
    if found.is_empty() {
        return Ok(Vec::new());
    }
    let group_names = owned.group_names.clone();
    let view_names: Vec<String> = owned.desc.views.iter().map(|v| v.name.clone()).collect();
    let views = owned.views.clone();
    let origin = owned.origin;
    let scene = owned.build()?;
    let name = |g: u16| group_names.get(g as usize).map_or("?", String::as_str);
    let mut warnings = Vec::new();
    for ((a, b), o) in found {
        let Some((p, view)) = o
            .points
            .iter()
            .find_map(|&p| seen_by(&scene, &views, p, slack).map(|v| (p, v)))
        else {
            continue;
        };
        let at = format!(
            "({}, {}, {})",
            significant(p[0] + origin[0]),
            significant(p[1] + origin[1]),
            significant(p[2] + origin[2])
        );
        let view = view_names.get(view).map_or("?", String::as_str);
        let at_least = if o.pairs >= MAX_COUNTED_PAIRS {
            "at least "
        } else {
            ""
        };
        let what = format!(
            "{at_least}{} of triangles, seen from view '{view}' at {at}",
            counted(o.pairs as u64, "pair")
        );
        warnings.push(if o.apart <= TIE_SHARE_OF_SLACK * slack {
            format!(
                "groups '{}' and '{}' overlap in one plane ({what}): which of the two a view sees there, and which one light bounces off, is left to chance; move one in front of the other by more than {} units (the renderer's ray slack), or cut the covered part away",
                name(a),
                name(b),
                significant(slack)
            )
        } else {
            format!(
                "groups '{}' and '{}' overlap {} units apart ({what}), closer than the renderer's ray slack of {} units: the views see the nearer, but light leaving either starts beyond the other and passes through it; move them further apart, or cut the covered part away",
                name(a),
                name(b),
                significant(o.apart),
                significant(slack)
            )
        });
    }
    Ok(warnings)
}

/// The first of `views` that sees point `p` (in the frame the scene's triangles and views
/// were moved to): `p` within its frame, and nothing nearer than `p` less `slack` on the
/// line from its position.
fn seen_by(scene: &Scene, views: &[View], p: [f64; 3], slack: f64) -> Option<usize> {
    let p = Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32);
    views.iter().position(|view| {
        let d = p - view.position;
        let z = d.dot(view.forward);
        if z.is_nan() || z <= 0.0 {
            return false;
        }
        let sx = d.dot(view.right_span) / (view.right_span.length_squared() * z);
        let sy = d.dot(view.up_span) / (view.up_span.length_squared() * z);
        if !(sx.abs() <= 0.5 && sy.abs() <= 0.5) {
            return false;
        }
        let distance = d.length();
        let hit = scene.intersect(&Ray::new(view.position, d / distance), f32::INFINITY);
        hit.is_some_and(|h| f64::from(h.t) >= f64::from(distance) - slack)
    })
}

/// Each pair of groups (smaller index first, in order) with faces that overlap within
/// `slack` of one plane, exact copies left out.
fn find_overlaps(triangles: &[Triangle], slack: f64) -> Vec<((u16, u16), Overlap)> {
    let found: RefCell<HashMap<(u16, u16), Overlap>> = RefCell::new(HashMap::new());
    // Two groups' faces, until that pair has MAX_COUNTED_PAIRS counted.
    let of_groups = |a: &Face, b: &Face| match (a.surface, b.surface) {
        (Surface::Group(g), Surface::Group(h)) => {
            g != h
                && found
                    .borrow()
                    .get(&(g.min(h), g.max(h)))
                    .is_none_or(|o| o.pairs < MAX_COUNTED_PAIRS)
        }
        _ => false,
    };
    let is_group = |s: Surface| matches!(s, Surface::Group(_));
    scan(
        triangles,
        slack,
        is_group,
        of_groups,
        |a, b, apart, point| {
            if corners_key(&triangles[a.triangle]) == corners_key(&triangles[b.triangle]) {
                return; // an exact copy: repeated_triangles tells it
            }
            let (Surface::Group(g), Surface::Group(h)) = (a.surface, b.surface) else {
                return;
            };
            let mut found = found.borrow_mut();
            let entry = found.entry((g.min(h), g.max(h))).or_default();
            entry.pairs += 1;
            entry.apart = entry.apart.max(apart);
            if entry.points.len() < POINTS_PER_PAIR {
                entry.points.extend(point());
            }
        },
    );
    let mut pairs: Vec<_> = found.into_inner().into_iter().collect();
    pairs.sort_unstable_by_key(|(k, _)| *k);
    pairs
}

/// The first two light triangles (indices into `triangles`, in order) that overlap
/// within `slack` of one plane facing the same way, with a point of their overlap: both
/// emit there, and the light is counted twice. Exact copies included.
pub fn overlapping_light_faces(
    triangles: &[Triangle],
    slack: f64,
) -> Option<(usize, usize, [f64; 3])> {
    let of_lights = |a: &Face, b: &Face| {
        matches!(
            (a.surface, b.surface),
            (Surface::Light(_), Surface::Light(_))
        ) && a.front == b.front
    };
    let mut first: Option<(usize, usize, [f64; 3])> = None;
    let is_light = |s: Surface| matches!(s, Surface::Light(_));
    scan(triangles, slack, is_light, of_lights, |a, b, _, point| {
        let (i, j) = (a.triangle.min(b.triangle), a.triangle.max(b.triangle));
        if first.is_none_or(|(fi, fj, _)| (i, j) < (fi, fj)) {
            let p = point().unwrap_or_else(|| a.corners[0]);
            first = Some((i, j, p));
        }
    });
    first
}

/// Calls `on_overlap` once for each pair of the faces `admits` (by their surface) that
/// `may_pair` admits (from their
/// surfaces and facing alone) and that overlap by more than `slack` across within `slack`
/// of one plane, with their planes' distance and a way to a point of the overlap.
fn scan(
    triangles: &[Triangle],
    slack: f64,
    admits: impl Fn(Surface) -> bool,
    may_pair: impl Fn(&Face, &Face) -> bool,
    mut on_overlap: impl FnMut(&Face, &Face, f64, &dyn Fn() -> Option<[f64; 3]>),
) {
    if !(slack > 0.0 && slack.is_finite()) {
        return;
    }
    // Each face under a hash of its rounded plane (or two, or more, near a rounding
    // boundary), sorted: 16 bytes a face, where a map of lists cost several times that.
    let mut entries: Vec<(u64, u32)> = Vec::new();
    for (i, t) in triangles.iter().enumerate() {
        if !admits(t.surface) {
            continue;
        }
        if let Some(face) = Face::new(i, t) {
            plane_keys(&face, slack, |key| {
                let mut hasher = DefaultHasher::new();
                key.hash(&mut hasher);
                entries.push((hasher.finish(), i as u32));
            });
        }
    }
    entries.sort_unstable();
    let mut seen: HashSet<(u32, u32)> = HashSet::new();
    for run in entries.chunk_by(|a, b| a.0 == b.0) {
        let faces = || {
            run.iter()
                .filter_map(|&(_, i)| Face::new(i as usize, &triangles[i as usize]))
        };
        // One face of each surface and facing: `may_pair` looks at nothing else, so a
        // plane where it admits no pair of these (one group's floor) is passed over
        // before its faces are held.
        let mut kinds: Vec<Face> = Vec::new();
        for f in faces() {
            if !kinds
                .iter()
                .any(|k| k.surface == f.surface && k.front == f.front)
            {
                kinds.push(f);
            }
        }
        if kinds.iter().any(|a| kinds.iter().any(|b| may_pair(a, b))) {
            let faces: Vec<Face> = faces().collect();
            sweep_plane(&faces, slack, &may_pair, &mut seen, &mut on_overlap);
        }
    }
}

/// The rounded planes a face is gathered under: its normal in steps of 1/NORMAL_STEPS and
/// its offset in cells of four slacks, and the neighbouring step or cell of any that it
/// lies near the edge of, so that two faces of one plane always share a key. Passed to
/// `each` (one key for most faces, up to 16), with no allocation.
fn plane_keys(face: &Face, slack: f64, mut each: impl FnMut([i64; 4])) {
    let offset = face.offset() / (4.0 * slack);
    let scaled = face.normal.map(|c| c * NORMAL_STEPS);
    let coordinates = [scaled[0], scaled[1], scaled[2], offset];
    let margins = [NORMAL_MARGIN, NORMAL_MARGIN, NORMAL_MARGIN, 0.25];
    let mut nearest = [0i64; 4];
    let mut other = [None; 4];
    for axis in 0..4 {
        let x = coordinates[axis];
        let n = x.round();
        nearest[axis] = n as i64;
        if ((x - x.floor()) - 0.5).abs() < margins[axis] {
            other[axis] = Some(if x < n { n - 1.0 } else { n + 1.0 } as i64);
        }
    }
    // Every choice of nearest or other per axis, where an axis has another.
    for choice in 0u32..16 {
        let mut key = nearest;
        let mut possible = true;
        for axis in 0..4 {
            if choice & (1 << axis) != 0 {
                match other[axis] {
                    Some(o) => key[axis] = o,
                    None => possible = false,
                }
            }
        }
        if possible {
            each(key);
        }
    }
}

/// Tests the faces of one gathered plane pairwise, by a sweep along one in-plane axis:
/// only faces that `may_pair` admits and whose extents overlap on both axes are compared.
fn sweep_plane(
    faces: &[Face],
    slack: f64,
    may_pair: &impl Fn(&Face, &Face) -> bool,
    seen: &mut HashSet<(u32, u32)>,
    on_overlap: &mut impl FnMut(&Face, &Face, f64, &dyn Fn() -> Option<[f64; 3]>),
) {
    let (u, v) = plane_axes(faces[0].normal);
    let items: Vec<([[f64; 2]; 3], [f64; 4])> = faces
        .iter()
        .map(|f| {
            let p = f.corners.map(|c| [dot(c, u), dot(c, v)]);
            let (mut u0, mut u1, mut v0, mut v1) = (p[0][0], p[0][0], p[0][1], p[0][1]);
            for q in &p[1..] {
                (u0, u1) = (u0.min(q[0]), u1.max(q[0]));
                (v0, v1) = (v0.min(q[1]), v1.max(q[1]));
            }
            (p, [u0, u1, v0, v1])
        })
        .collect();
    let mut order: Vec<usize> = (0..faces.len()).collect();
    order.sort_unstable_by(|&a, &b| items[a].1[0].total_cmp(&items[b].1[0]).then(a.cmp(&b)));
    // The faces the sweep has passed, by kind (surface and facing, all `may_pair` looks
    // at; the first face of the kind stands for it): a kind it admits no pair with is
    // passed over whole, so that faces of one group, or of a pair of groups that has been
    // counted enough, cost nothing each. A kind's faces whose extents the sweep has left
    // behind are dropped when it is next looked at.
    let mut active: Vec<(usize, Vec<usize>)> = Vec::new();
    for &i in &order {
        let (p, bx) = items[i];
        let fa = &faces[i];
        for (kind, members) in active.iter_mut() {
            if !may_pair(fa, &faces[*kind]) {
                continue;
            }
            members.retain(|&j| items[j].1[1] > bx[0] + slack);
            for &j in members.iter() {
                let (q, by) = items[j];
                let fb = &faces[j];
                if !(by[2] < bx[3] - slack && bx[2] < by[3] - slack) {
                    continue;
                }
                let (ta, tb) = (fa.triangle as u32, fb.triangle as u32);
                let pair = (ta.min(tb), ta.max(tb));
                if seen.contains(&pair) {
                    continue;
                }
                let apart = fa.distance_to(fb).max(fb.distance_to(fa));
                if apart.is_nan() || apart > slack || !overlap_2d(p, q, slack) {
                    continue;
                }
                seen.insert(pair);
                on_overlap(fa, fb, apart, &|| overlap_point(p, q, (u, v), fa));
                if !may_pair(fa, &faces[*kind]) {
                    break;
                }
            }
        }
        let same_kind = |&(kind, _): &(usize, Vec<usize>)| {
            faces[kind].surface == fa.surface && faces[kind].front == fa.front
        };
        match active.iter_mut().find(|k| same_kind(k)) {
            Some((_, members)) => members.push(i),
            None => active.push((i, vec![i])),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use relume_core::math::{self, Vec2, Vec3};

    fn triangle(v: [[f32; 3]; 3], group: u16) -> Triangle {
        Triangle {
            v: v.map(Vec3::from),
            uv: [Vec2::ZERO; 3],
            surface: Surface::Group(group),
        }
    }

    /// A quad in the plane through `origin` spanned by `a` and `b`, as two triangles
    /// split along one diagonal or the other.
    fn quad(origin: Vec3, a: Vec3, b: Vec3, other_diagonal: bool, group: u16) -> [Triangle; 2] {
        let [p, q, r, s] = [origin, origin + a, origin + a + b, origin + b].map(|v| v.to_array());
        if other_diagonal {
            [triangle([p, q, s], group), triangle([q, r, s], group)]
        } else {
            [triangle([p, q, r], group), triangle([p, r, s], group)]
        }
    }

    /// The pairs of groups found, with their triangle pairs, distance and points.
    fn overlaps(t: &[Triangle]) -> Vec<((u16, u16), Overlap)> {
        let slack = f64::from(SLACK_IN_EPSILONS * RAY_EPSILON * longest_side(t));
        find_overlaps(t, slack)
    }

    /// A 4x3 wall in the plane x = 0 tilted by `tilt` about the z axis (0 for an axis
    /// plane), a room's floor to set the scene's size, and a 1x1 picture `lift` in front
    /// of the wall.
    fn wall_and_picture(tilt: f32, lift: f32, picture_group: u16) -> Vec<Triangle> {
        let (s, c) = (math::sin(tilt), math::cos(tilt));
        let along = Vec3::new(s, c, 0.0);
        let normal = Vec3::new(c, -s, 0.0);
        let up = Vec3::Z;
        let mut t = Vec::new();
        t.extend(quad(Vec3::ZERO, along * 4.0, up * 3.0, false, 0));
        t.extend(quad(
            along * 1.5 + up + normal * lift,
            along,
            up,
            true,
            picture_group,
        ));
        t.extend(quad(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::X * 5.0,
            Vec3::Y * 4.0,
            false,
            2,
        ));
        t
    }

    #[test]
    fn a_picture_in_its_walls_plane_is_found_with_points_on_it() {
        for tilt in [0.0f32, 0.3, 1.0, 2.5] {
            let found = overlaps(&wall_and_picture(tilt, 0.0, 1));
            assert_eq!(found.len(), 1, "tilt {tilt}");
            let ((a, b), o) = &found[0];
            assert_eq!((*a, *b), (0, 1));
            assert_eq!(o.pairs, 4, "each picture triangle over both wall triangles");
            assert!(o.apart < 1e-6, "{}", o.apart);
            // Every point lies on the picture, in the wall's plane.
            let (s, c) = (f64::from(math::sin(tilt)), f64::from(math::cos(tilt)));
            for p in &o.points {
                let along = p[0] * s + p[1] * c;
                let off = p[0] * c - p[1] * s;
                assert!(off.abs() < 1e-5, "{p:?}");
                assert!(
                    (1.5..=2.5).contains(&along) && (1.0..=2.0).contains(&p[2]),
                    "{p:?}"
                );
            }
            assert_eq!(o.points.len(), 4);
        }
    }

    #[test]
    fn a_picture_within_the_slack_is_found_apart_and_one_beyond_it_is_not() {
        // The scene is 5 units long: the slack is 2 * 1e-4 * 5 = 0.001.
        let found = overlaps(&wall_and_picture(0.3, 0.0005, 1));
        assert_eq!(found.len(), 1);
        assert!(
            (found[0].1.apart - 0.0005).abs() < 1e-6,
            "{}",
            found[0].1.apart
        );
        for lift in [0.002, 0.1, -0.01] {
            assert!(
                overlaps(&wall_and_picture(0.3, lift, 1)).is_empty(),
                "lift {lift}"
            );
        }
    }

    #[test]
    fn neighbours_copies_and_one_groups_own_faces_are_no_overlap() {
        // Two groups meeting edge to edge in one plane (a wall of two materials).
        let mut t = Vec::new();
        t.extend(quad(Vec3::ZERO, Vec3::Y * 2.0, Vec3::Z * 3.0, false, 0));
        t.extend(quad(Vec3::Y * 2.0, Vec3::Y * 2.0, Vec3::Z * 3.0, true, 1));
        assert!(overlaps(&t).is_empty());
        // A picture in its wall's plane, of the wall's own group.
        assert!(overlaps(&wall_and_picture(0.3, 0.0, 0)).is_empty());
        // The same quad, split the same way, in two groups: repeated_triangles' case.
        let mut t = Vec::new();
        t.extend(quad(Vec3::ZERO, Vec3::Y, Vec3::Z, false, 0));
        t.extend(quad(Vec3::ZERO, Vec3::Y, Vec3::Z, false, 1));
        assert!(overlaps(&t).is_empty());
        // Split along the other diagonal, the copy overlaps: each triangle two others.
        let mut t = Vec::new();
        t.extend(quad(Vec3::ZERO, Vec3::Y, Vec3::Z, false, 0));
        t.extend(quad(Vec3::ZERO, Vec3::Y, Vec3::Z, true, 1));
        let found = overlaps(&t);
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].1.pairs, 4);
    }

    /// `n` thin triangles of each of groups 0 and 1 in the plane z = 0, every one over
    /// every one of the other group (each shifted along x by a little), beside a floor of
    /// group 2 that sets the scene's size.
    fn stacked_slivers(n: usize) -> Vec<Triangle> {
        let mut t = Vec::new();
        for k in 0..n {
            for group in 0..2u16 {
                let x = 1.0 + (2 * k + group as usize) as f32 * 1e-4;
                t.push(triangle(
                    [[x, 1.0, 0.0], [x + 2.0, 1.0, 0.0], [x + 1.0, 1.5, 0.0]],
                    group,
                ));
            }
        }
        t.extend(quad(
            Vec3::new(0.0, 3.0, 0.0),
            Vec3::X * 5.0,
            Vec3::Y,
            false,
            2,
        ));
        t
    }

    #[test]
    fn every_pair_is_counted_up_to_the_cap_and_no_further() {
        let found = overlaps(&stacked_slivers(40));
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].0, (0, 1));
        assert_eq!(found[0].1.pairs, 40 * 40);
        // 150 x 150 pairs overlap: counting stops at the cap, with its points and distance.
        let found = overlaps(&stacked_slivers(150));
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].1.pairs, MAX_COUNTED_PAIRS);
        assert_eq!(found[0].1.points.len(), POINTS_PER_PAIR);
        assert!(found[0].1.apart < 1e-6);
    }

    #[test]
    fn light_faces_overlap_only_facing_the_same_way() {
        let light = |v: [[f32; 3]; 3], l: u16| Triangle {
            surface: Surface::Light(l),
            ..triangle(v, 0)
        };
        let a = [[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]];
        let b = [[0.2, 0.2, 2.0], [1.2, 0.2, 2.0], [0.2, 1.2, 2.0]];
        let turned = [b[2], b[1], b[0]];
        let floor = quad(Vec3::ZERO, Vec3::X * 3.0, Vec3::Y * 3.0, false, 0);
        for (other, l, expected) in [(b, 0, true), (b, 1, true), (turned, 0, false)] {
            let mut t = floor.to_vec();
            t.extend([light(a, 0), light(other, l)]);
            let slack = f64::from(SLACK_IN_EPSILONS * RAY_EPSILON * longest_side(&t));
            let found = overlapping_light_faces(&t, slack);
            assert_eq!(found.is_some(), expected, "{other:?} of light {l}");
            if let Some((i, j, p)) = found {
                assert_eq!((i, j), (2, 3));
                assert!(p[2] == 2.0 && (0.2..0.8).contains(&p[0]), "{p:?}");
            }
        }
    }

    #[test]
    fn faces_on_either_side_of_a_rounding_boundary_still_meet() {
        // Offsets walked across several cells of four slacks: wherever the wall's plane
        // falls, the picture in it is found.
        for k in 0..40 {
            let x = 0.37 + k as f32 * 0.00023;
            let mut t = wall_and_picture(0.0, 0.0, 1);
            for tri in &mut t[..4] {
                for v in &mut tri.v {
                    v.x += x;
                }
            }
            assert_eq!(overlaps(&t).len(), 1, "x {x}");
        }
    }
}
