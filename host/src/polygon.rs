//! Triangles of an OBJ polygon. tobj fans a face from its first corner, which is right for
//! a convex polygon only: an L-shaped face came out with a triangle over its notch.
//! RADIANCE's obj2rad keeps such a face a `polygon`, which RADIANCE renders concave as it
//! is, so relume triangulates a concave face by ear clipping in the face's own plane and
//! keeps the fan for a convex one (the same triangles as before).

/// A concave face's triangles, as corner indices into `corners` (in the face's winding, so
/// that each triangle faces as the polygon does). `None` where the fan from the first
/// corner is right (a triangle, a convex polygon), and where the polygon is not simple (it
/// crosses itself, or has no area and so no plane to be seen flat in): the caller leaves
/// those to tobj's fan, as before.
pub fn ears(corners: &[[f64; 3]]) -> Option<Vec<[usize; 3]>> {
    let n = corners.len();
    if n <= 3 {
        return None;
    }
    let flat = flatten(corners)?;
    // Counter-clockwise in the plane: the sign of the area (Newell's normal points along
    // the axis kept, so a face of either winding reads positive).
    let convex = (0..n).all(|i| cross(flat[(i + n - 1) % n], flat[i], flat[(i + 1) % n]) >= 0.0);
    if convex {
        return None;
    }
    ear_clip(&flat)
}

/// The corners in 2D, counter-clockwise: the plane's coordinates after dropping the axis
/// along which Newell's normal is largest. `None` for a polygon of no area.
fn flatten(corners: &[[f64; 3]]) -> Option<Vec<[f64; 2]>> {
    let n = corners.len();
    let mut normal = [0.0f64; 3];
    for i in 0..n {
        let (a, b) = (corners[i], corners[(i + 1) % n]);
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    let axis = (0..3).max_by(|&a, &b| normal[a].abs().total_cmp(&normal[b].abs()))?;
    if normal[axis] == 0.0 || !normal[axis].is_finite() {
        return None;
    }
    // The two axes kept, in the order that makes the polygon counter-clockwise.
    let (u, v) = match axis {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    };
    let (u, v) = if normal[axis] > 0.0 { (u, v) } else { (v, u) };
    Some(corners.iter().map(|p| [p[u], p[v]]).collect())
}

/// Twice the signed area of the triangle (a, b, c): positive where it turns left at b.
fn cross(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Ear clipping of a counter-clockwise simple polygon: repeatedly cut off a convex corner
/// whose triangle holds no other corner. `None` where no ear is left before the end (a
/// polygon that crosses itself).
fn ear_clip(flat: &[[f64; 2]]) -> Option<Vec<[usize; 3]>> {
    let mut left: Vec<usize> = (0..flat.len()).collect();
    let mut triangles = Vec::with_capacity(flat.len() - 2);
    while left.len() > 3 {
        let m = left.len();
        let ear = (0..m).find(|&i| {
            let (a, b, c) = (left[(i + m - 1) % m], left[i], left[(i + 1) % m]);
            cross(flat[a], flat[b], flat[c]) > 0.0
                && !left.iter().any(|&p| {
                    p != a && p != b && p != c && inside_or_on(flat[p], flat[a], flat[b], flat[c])
                })
        })?;
        triangles.push([left[(ear + m - 1) % m], left[ear], left[(ear + 1) % m]]);
        left.remove(ear);
    }
    if cross(flat[left[0]], flat[left[1]], flat[left[2]]) <= 0.0 {
        return None;
    }
    triangles.push([left[0], left[1], left[2]]);
    Some(triangles)
}

/// Whether `p` lies in the counter-clockwise triangle (a, b, c) or on its edges.
fn inside_or_on(p: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> bool {
    cross(a, b, p) >= 0.0 && cross(b, c, p) >= 0.0 && cross(c, a, p) >= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Twice the area of the triangles, in the plane z = 0 (signed: counter-clockwise
    /// positive).
    fn area(corners: &[[f64; 3]], triangles: &[[usize; 3]]) -> f64 {
        let flat = |i: usize| [corners[i][0], corners[i][1]];
        triangles
            .iter()
            .map(|t| cross(flat(t[0]), flat(t[1]), flat(t[2])))
            .sum()
    }

    /// An L of six corners in z = 0 (area 3), in both windings: its triangles cover it
    /// once, none over the notch, each turning as the face does. The fan's first triangle
    /// (0, 1, 2) held the notch.
    #[test]
    fn a_concave_face_is_cut_into_ears_within_it() {
        let l = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 2.0, 0.0],
            [0.0, 2.0, 0.0],
        ];
        let notch = [1.5, 1.5];
        for reversed in [false, true] {
            let mut corners = l.to_vec();
            if reversed {
                corners.reverse();
            }
            let triangles = ears(&corners).unwrap();
            assert_eq!(triangles.len(), 4);
            let sign = if reversed { -1.0 } else { 1.0 };
            assert_eq!(area(&corners, &triangles), sign * 6.0);
            for t in &triangles {
                let flat = |i: usize| [corners[i][0], corners[i][1]];
                let (a, b, c) = (flat(t[0]), flat(t[1]), flat(t[2]));
                assert!(sign * cross(a, b, c) > 0.0, "{t:?}");
                let (a, b, c) = if reversed { (c, b, a) } else { (a, b, c) };
                assert!(!inside_or_on(notch, a, b, c), "{t:?} covers the notch");
            }
        }
    }

    /// A convex face keeps tobj's fan (no ears); so does a triangle.
    #[test]
    fn a_convex_face_keeps_its_fan() {
        let square = [
            [0.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
            [0.0, 1.0, 2.0],
            [0.0, 0.0, 2.0],
        ];
        assert_eq!(ears(&square), None);
        assert_eq!(ears(&square[..3]), None);
    }

    /// A bow tie crosses itself, and a face of no area has no plane: the caller fans them.
    #[test]
    fn a_face_that_crosses_itself_or_has_no_area_is_not_triangulated() {
        let bow_tie = [
            [0.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        assert_eq!(ears(&bow_tie), None);
        let line = [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
        assert_eq!(ears(&line), None);
    }
}
