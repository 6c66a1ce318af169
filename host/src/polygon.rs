//! Triangles of an OBJ polygon. tobj fans a face from its first corner, which is right for
//! a convex polygon only: an L-shaped face came out with a triangle over its notch.
//! RADIANCE's obj2rad keeps such a face a `polygon`, which RADIANCE renders concave as it
//! is, so relume triangulates a concave face by ear clipping in the face's own plane and
//! keeps the fan for a convex one (the same triangles as before).

/// How an OBJ face becomes triangles.
#[derive(Clone, Debug, PartialEq)]
pub enum Cut {
    /// The fan from the first corner is right: a triangle, a convex polygon, or one of no
    /// area (no plane to be seen flat in; its triangles have no area either).
    Fan,
    /// A concave face's triangles, as corner indices (in the face's winding, so that each
    /// triangle faces as the polygon does).
    Ears(Vec<[usize; 3]>),
    /// The polygon crosses itself, so no triangles cover "it": the caller fans it, as
    /// tobj does, and says so.
    CrossesItself,
}

/// A face is tested for crossings edge against edge, sweeping along x so that only edges
/// whose boxes overlap are paired; past this many pairs visited (those of a face of 4,096
/// corners tested pair by pair, or of a larger one whose edges overlap in x as much) the
/// test stops, and only a
/// face that turns round twice or where ear clipping finds no ear is told of, so that a
/// face of 10^5 overlapping edges does not stall the reading of its file.
pub const CROSSING_TEST_PAIRS: usize = 4096 * 4095 / 2;

/// How clearly two edges must cross, as a share of the polygon's size squared, to be told:
/// far above the rounding of its coordinates (1e-16 of its size), far below a crossing one
/// could see.
const CROSSING_TOLERANCE: f64 = 1e-10;

/// Cuts the face of `corners` (3D positions in the face's order) into triangles.
pub fn cut(corners: &[[f64; 3]]) -> Cut {
    let n = corners.len();
    if n <= 3 {
        return Cut::Fan;
    }
    let Some(flat) = flatten(corners) else {
        // No area overall, yet a fan triangle with some: lobes of opposite turn (a
        // symmetric bow tie).
        return if (2..n).any(|i| has_area(corners[0], corners[i - 1], corners[i])) {
            Cut::CrossesItself
        } else {
            Cut::Fan
        };
    };
    let box_ = bounds(&flat);
    let size = extent(box_);
    // A corner given twice, the second rounded a hair off the first (an exporter's teeth,
    // each ending where the next begins), lies on every ear beside it: it is one corner.
    let ring = distinct_corners(&flat, SAME_CORNER * size);
    if ring.len() < 3 {
        return Cut::Fan;
    }
    let at: Vec<[f64; 2]> = ring.iter().map(|&i| flat[i]).collect();
    if crosses_itself(&at, size) == Some(true) {
        return Cut::CrossesItself;
    }
    // Counter-clockwise in the plane: the sign of the area (Newell's normal points along
    // the axis kept, so a face of either winding reads positive).
    let m = at.len();
    let convex = (0..m).all(|i| cross(at[(i + m - 1) % m], at[i], at[(i + 1) % m]) >= 0.0);
    if convex {
        // Every corner turning left, it is simple if it turns round once: a circle traced
        // twice (past the edge test's pairs) also turns left everywhere.
        return if turns(&at) > 1 {
            Cut::CrossesItself
        } else {
            Cut::Fan
        };
    }
    match ear_clip(&at, box_) {
        Some(triangles) => Cut::Ears(triangles.into_iter().map(|t| t.map(|k| ring[k])).collect()),
        None => Cut::CrossesItself,
    }
}

/// How near two corners of a face are one, as a share of the face's size: far above the
/// rounding of its coordinates (1e-16 of its size), far below a length one could see.
const SAME_CORNER: f64 = 1e-9;

/// The box around `flat`: its lower and upper corners.
type Bounds = ([f64; 2], [f64; 2]);

fn bounds(flat: &[[f64; 2]]) -> Bounds {
    flat.iter().fold(
        ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
        |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1])],
                [hi[0].max(p[0]), hi[1].max(p[1])],
            )
        },
    )
}

/// The largest side of the box `(lo, hi)`.
fn extent((lo, hi): Bounds) -> f64 {
    (hi[0] - lo[0]).max(hi[1] - lo[1])
}

/// The indices of the corners of the ring `flat` that lie farther than `within` (in both
/// coordinates) from the corner kept before them, the last also from the first.
fn distinct_corners(flat: &[[f64; 2]], within: f64) -> Vec<usize> {
    let same =
        |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() <= within && (a[1] - b[1]).abs() <= within;
    let mut kept: Vec<usize> = Vec::with_capacity(flat.len());
    for (i, &p) in flat.iter().enumerate() {
        if kept.last().is_none_or(|&k| !same(flat[k], p)) {
            kept.push(i);
        }
    }
    while kept.len() > 1 && same(flat[kept[kept.len() - 1]], flat[kept[0]]) {
        kept.pop();
    }
    kept
}

/// How many times the closed polygon `flat` turns round: the sum of its corners' turning
/// angles over a full turn, rounded.
fn turns(flat: &[[f64; 2]]) -> i64 {
    let n = flat.len();
    let total: f64 = (0..n)
        .map(|i| {
            let (a, b, c) = (flat[(i + n - 1) % n], flat[i], flat[(i + 1) % n]);
            let (u, v) = ([b[0] - a[0], b[1] - a[1]], [c[0] - b[0], c[1] - b[1]]);
            libm::atan2(u[0] * v[1] - u[1] * v[0], u[0] * v[0] + u[1] * v[1])
        })
        .sum();
    libm::round(total.abs() / (2.0 * core::f64::consts::PI)) as i64
}

/// Whether two edges of the closed polygon `flat` (of extent `size`) that share no corner
/// cross each other, each one's ends clearly on either side of the other (by
/// [`CROSSING_TOLERANCE`] of `size` squared): a polygon that touches itself at a corner is
/// left to ear clipping. `None` when [`CROSSING_TEST_PAIRS`] pairs did not settle it.
///
/// Two edges that cross that clearly meet at a point of both, so edges whose x ranges are
/// apart are never paired: a sweep along x (sweep and prune) pairs each edge with those
/// before it that still reach its left end, and then only where their y ranges meet.
fn crosses_itself(flat: &[[f64; 2]], size: f64) -> Option<bool> {
    let n = flat.len();
    // `cross` is twice a triangle's area: the polygon's size squared at most.
    let clear = CROSSING_TOLERANCE * size * size;
    let apart = |s: f64, t: f64| (s < -clear && t > clear) || (s > clear && t < -clear);
    let edge = |i: usize| (flat[i], flat[(i + 1) % n]);
    let range = |i: usize, k: usize| {
        let (a, b) = edge(i);
        (a[k].min(b[k]), a[k].max(b[k]))
    };
    // Edges i and i + 1 share a corner, and so do n - 1 and 0.
    let neighbours = |i: usize, j: usize| {
        let d = i.abs_diff(j);
        d == 1 || d == n - 1
    };
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| range(i, 0).0.total_cmp(&range(j, 0).0));
    let mut reaching: Vec<usize> = Vec::new();
    let mut pairs = 0usize;
    for &i in &order {
        let left = range(i, 0).0;
        reaching.retain(|&j| range(j, 0).1 >= left);
        let (a, b) = edge(i);
        let (low, high) = range(i, 1);
        for &j in &reaching {
            // Every pair the sweep visits counts, paired or not: edges stacked in y over
            // one x range (a ladder of long rungs) are all visited.
            pairs += 1;
            if pairs > CROSSING_TEST_PAIRS {
                return None;
            }
            let (j_low, j_high) = range(j, 1);
            if neighbours(i, j) || j_high < low || j_low > high {
                continue;
            }
            let (c, d) = edge(j);
            if apart(cross(a, b, c), cross(a, b, d)) && apart(cross(c, d, a), cross(c, d, b)) {
                return Some(true);
            }
        }
        reaching.push(i);
    }
    Some(false)
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

/// Whether the triangle (a, b, c) in 3D has any area.
fn has_area(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> bool {
    let (u, v) = (sub(b, a), sub(c, a));
    let normal = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    normal.iter().any(|&x| x != 0.0)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Twice the signed area of the triangle (a, b, c): positive where it turns left at b.
pub fn cross(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Ear clipping of a counter-clockwise simple polygon (within the box `box_`): repeatedly
/// cut off a convex corner whose triangle holds no other corner. `None` where no ear is
/// left before the end (a polygon that crosses itself).
///
/// The corners left are a ring (`prev`, `next`), walked round from the last ear cut; only a
/// corner that does not turn left can lie in an ear, so only those are tested, and cutting
/// an ear only makes its neighbours turn more to the left. A face of 15,000 corners, a
/// comb, took 21 s with every corner tested from the start of the ring each time.
fn ear_clip(flat: &[[f64; 2]], box_: Bounds) -> Option<Vec<[usize; 3]>> {
    let n = flat.len();
    let mut prev: Vec<usize> = (0..n).map(|i| (i + n - 1) % n).collect();
    let mut next: Vec<usize> = (0..n).map(|i| (i + 1) % n).collect();
    let turn =
        |prev: &[usize], next: &[usize], i: usize| cross(flat[prev[i]], flat[i], flat[next[i]]);
    let reflex_corners = (0..n).filter(|&i| turn(&prev, &next, i) <= 0.0);
    let mut reflex = ReflexGrid::new(flat, box_, reflex_corners);
    // Twice the area not yet cut off, and what counts as none of it.
    let mut remaining: f64 = (0..n)
        .map(|i| cross([0.0, 0.0], flat[i], flat[(i + 1) % n]))
        .sum();
    let size = extent(box_);
    let none_left = SAME_CORNER * size * size;
    let mut triangles = Vec::with_capacity(n - 2);
    let (mut left, mut at, mut tried) = (n, 0, 0);
    while left > 3 {
        let (a, b, c) = (prev[at], at, next[at]);
        // A corner at the same place as one of the ear's own (a face that touches itself
        // there, as a keyhole's bridge does) is that corner again, not one inside. Such a
        // face can leave a ring of no area with a corner that turns left (a figure 8,
        // both loops cut off): an ear larger than the area left is no ear.
        let own = |p: usize| [a, b, c].iter().any(|&k| flat[k] == flat[p]);
        let area = turn(&prev, &next, b);
        let ear = area > 0.0
            && area <= remaining + none_left
            && !reflex.any_in([flat[a], flat[b], flat[c]], |p| {
                p != a
                    && p != b
                    && p != c
                    && !own(p)
                    && inside_or_on(flat[p], flat[a], flat[b], flat[c])
            });
        if !ear {
            tried += 1;
            if tried > left {
                // What is left covers nothing (the figure 8's seam): done without it.
                return (remaining.abs() <= none_left).then_some(triangles);
            }
            at = c;
            continue;
        }
        triangles.push([a, b, c]);
        remaining -= area;
        next[a] = c;
        prev[c] = a;
        left -= 1;
        reflex.remove(b);
        for k in [a, c] {
            reflex.set(k, turn(&prev, &next, k) <= 0.0);
        }
        (at, tried) = (c, 0);
    }
    let (a, b, c) = (prev[at], at, next[at]);
    if cross(flat[a], flat[b], flat[c]) <= 0.0 {
        return (remaining.abs() <= none_left).then_some(triangles);
    }
    triangles.push([a, b, c]);
    Some(triangles)
}

/// The corners that do not turn left, the only ones an ear can hold, on a uniform grid
/// over the face, so that an ear is tested against those near it alone: tested against all
/// of them, a comb of 10^5 corners took 10 s and a spiral 14 s.
struct ReflexGrid<'a> {
    flat: &'a [[f64; 2]],
    low: [f64; 2],
    /// Cells a unit of length.
    scale: [f64; 2],
    side: usize,
    /// The corners in each cell, in row order; one no longer reflex stays until skipped.
    cells: Vec<Vec<usize>>,
    is_reflex: Vec<bool>,
}

impl<'a> ReflexGrid<'a> {
    /// The grid over `flat`, whose box is `(low, high)`, holding the corners `reflex`.
    fn new(
        flat: &'a [[f64; 2]],
        (low, high): Bounds,
        reflex: impl Iterator<Item = usize>,
    ) -> ReflexGrid<'a> {
        let reflex: Vec<usize> = reflex.collect();
        let side = (libm::sqrt(reflex.len() as f64) as usize).clamp(1, 1024);
        let scale = [0, 1].map(|k| {
            let span = high[k] - low[k];
            if span > 0.0 && span.is_finite() {
                side as f64 / span
            } else {
                0.0
            }
        });
        let mut grid = ReflexGrid {
            flat,
            low,
            scale,
            side,
            cells: vec![Vec::new(); side * side],
            is_reflex: vec![false; flat.len()],
        };
        for p in reflex {
            grid.set(p, true);
        }
        grid
    }

    /// The cell column or row of coordinate `x` along axis `k`, clamped to the grid.
    fn cell(&self, k: usize, x: f64) -> usize {
        let c = (x - self.low[k]) * self.scale[k];
        if c >= 0.0 {
            (c as usize).min(self.side - 1)
        } else {
            0
        }
    }

    fn set(&mut self, p: usize, reflex: bool) {
        if reflex && !self.is_reflex[p] {
            let [x, y] = self.flat[p];
            let cell = self.cell(1, y) * self.side + self.cell(0, x);
            self.cells[cell].push(p);
        }
        self.is_reflex[p] = reflex;
    }

    fn remove(&mut self, p: usize) {
        self.is_reflex[p] = false;
    }

    /// Whether `test` holds for a reflex corner in a cell the triangle's box meets.
    fn any_in(&self, triangle: [[f64; 2]; 3], test: impl Fn(usize) -> bool) -> bool {
        let range = |k: usize| {
            let lo = triangle.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min);
            let hi = triangle
                .iter()
                .map(|p| p[k])
                .fold(f64::NEG_INFINITY, f64::max);
            self.cell(k, lo)..=self.cell(k, hi)
        };
        range(1).any(|row| {
            range(0).any(|column| {
                self.cells[row * self.side + column]
                    .iter()
                    .any(|&p| self.is_reflex[p] && test(p))
            })
        })
    }
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
            let Cut::Ears(triangles) = cut(&corners) else {
                panic!("no ears");
            };
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
        assert_eq!(cut(&square), Cut::Fan);
        assert_eq!(cut(&square[..3]), Cut::Fan);
    }

    /// A bow tie crosses itself, lopsided or not (whose area cancels); so does a
    /// pentagram, whose every corner turns left; and an L whose last edge crosses its
    /// first. A face of no area is fanned: its triangles have none either.
    #[test]
    fn a_face_that_crosses_itself_is_told_and_one_of_no_area_fanned() {
        let flat = |points: &[[f64; 2]]| -> Vec<[f64; 3]> {
            points.iter().map(|p| [p[0], 0.5, p[1]]).collect()
        };
        let bow_tie = flat(&[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]);
        assert_eq!(cut(&bow_tie), Cut::CrossesItself);
        let lopsided = flat(&[[0.0, 0.0], [2.0, 1.0], [2.0, 0.0], [0.0, 3.0]]);
        assert_eq!(cut(&lopsided), Cut::CrossesItself);
        let star: Vec<[f64; 2]> = (0..5)
            .map(|k| {
                let angle = 4.0 * std::f64::consts::PI * k as f64 / 5.0;
                [libm::cos(angle), libm::sin(angle)]
            })
            .collect();
        assert_eq!(cut(&flat(&star)), Cut::CrossesItself);
        let crossed_l = flat(&[
            [0.0, 0.0],
            [2.0, 0.0],
            [2.0, 1.0],
            [1.0, 1.0],
            [1.0, 2.0],
            [3.0, -1.0],
        ]);
        assert_eq!(cut(&crossed_l), Cut::CrossesItself);
        let line = [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
        assert_eq!(cut(&line), Cut::Fan);
        // A quad with a corner given twice is a triangle, not a crossing.
        let repeated = flat(&[[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
        assert_eq!(cut(&repeated), Cut::Fan);
    }

    /// A comb whose teeth each end where the next begins, that corner given twice and
    /// some an ulp apart (the rounding of `x + width` against the next `x`), does not
    /// cross itself: it is cut as though each such corner were given once.
    #[test]
    fn corners_given_twice_in_rounded_coordinates_do_not_cross() {
        let teeth = 300;
        let width = 0.5 / teeth as f64;
        let mut points: Vec<[f64; 2]> = (0..teeth)
            .flat_map(|i| {
                let x = 1.0 + i as f64 * width;
                [[x, 0.5], [x + width / 2.0, 0.7], [x + width, 0.5]]
            })
            .collect();
        assert!(
            points
                .windows(2)
                .any(|w| w[0] != w[1] && (w[0][0] - w[1][0]).abs() < 1e-12),
            "no corner given twice an ulp apart"
        );
        points.extend([[1.5, 0.4], [1.0, 0.4]]);
        let corners: Vec<[f64; 3]> = points.iter().map(|p| [p[0], p[1], 0.0]).collect();
        let Cut::Ears(triangles) = cut(&corners) else {
            panic!("no ears: {:?}", cut(&corners));
        };
        // One triangle fewer for each corner given twice: 2 corners a tooth and 3 more.
        assert_eq!(triangles.len(), 2 * teeth + 3 - 2);
        let twice_area = 2.0 * (0.5 * 0.1 + 0.5 * 0.2 / 2.0);
        assert!((area(&corners, &triangles).abs() - twice_area).abs() < 1e-9);
    }

    /// A face that touches itself at a corner without crossing (a figure 8 pinched at one
    /// corner, a square with a triangular hole reached by a bridge) is cut into ears within
    /// it: the corner given twice lay on every ear beside it, and the face was fanned over
    /// its hole and told to cross itself.
    #[test]
    fn a_face_that_touches_itself_at_a_corner_is_cut_within_it() {
        let flat = |points: &[[f64; 2]]| -> Vec<[f64; 3]> {
            points.iter().map(|p| [p[0], p[1], 0.0]).collect()
        };
        // Two squares of area 4 each, joined at (2, 2).
        let eight = flat(&[
            [0.0, 0.0],
            [2.0, 0.0],
            [2.0, 2.0],
            [4.0, 2.0],
            [4.0, 4.0],
            [2.0, 4.0],
            [2.0, 2.0],
            [0.0, 2.0],
        ]);
        // A 4x4 square less a triangle of area 2, reached from corner (0, 0).
        let keyhole = flat(&[
            [0.0, 0.0],
            [4.0, 0.0],
            [4.0, 4.0],
            [0.0, 4.0],
            [0.0, 0.0],
            [1.0, 1.0],
            [1.0, 3.0],
            [3.0, 1.0],
            [1.0, 1.0],
        ]);
        for (face, twice_area) in [(eight, 16.0), (keyhole, 28.0)] {
            let Cut::Ears(triangles) = cut(&face) else {
                panic!("no ears: {:?}", cut(&face));
            };
            assert!((area(&face, &triangles) - twice_area).abs() < 1e-9);
            for t in &triangles {
                let flat = |i: usize| [face[i][0], face[i][1]];
                assert!(cross(flat(t[0]), flat(t[1]), flat(t[2])) > 0.0, "{t:?}");
            }
        }
    }

    /// Random keyholes (a convex polygon less a triangle reached by a bridge from its
    /// first corner) and figure 8s (two convex polygons meeting at one corner): each is cut
    /// into triangles that turn as the face does and whose area is the face's. Before the
    /// corner given twice was taken for itself, 1.7% of keyholes found no ear.
    #[test]
    fn random_faces_that_touch_themselves_are_cut_within_them() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut uniform = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let tau = 2.0 * std::f64::consts::PI;
        // Corners of a convex polygon round (cx, cy), counter-clockwise, each in its own
        // n-th of the turn (so that for n >= 5 it holds a disc of half its radius).
        let mut convex = |cx: f64, cy: f64, r: f64, n: usize| -> Vec<[f64; 2]> {
            let angles: Vec<f64> = (0..n)
                .map(|k| tau * (k as f64 + 0.1 + 0.8 * uniform()) / n as f64)
                .collect();
            angles
                .iter()
                .map(|&t| [cx + r * libm::cos(t), cy + r * libm::sin(t)])
                .collect()
        };
        let shoelace = |ring: &[[f64; 2]]| -> f64 {
            (0..ring.len())
                .map(|i| cross([0.0, 0.0], ring[i], ring[(i + 1) % ring.len()]))
                .sum()
        };
        for round in 0..400 {
            let ring: Vec<[f64; 2]> = if round % 2 == 0 {
                let outer = convex(0.0, 0.0, 1.0, 5 + round % 9);
                let hole = convex(0.0, 0.0, 0.2, 3);
                if outer.len() < 3 || hole.len() < 3 {
                    continue;
                }
                let mut ring = outer.clone();
                ring.push(outer[0]);
                // The hole clockwise, from its first corner back to it.
                ring.extend([hole[0], hole[2], hole[1], hole[0]]);
                ring
            } else {
                // Two discs' polygons touching at the origin, left and right of it.
                let left = convex(-1.0, 0.0, 1.0, 4 + round % 7);
                let right = convex(1.0, 0.0, 1.0, 4 + round % 5);
                let touching = |poly: Vec<[f64; 2]>, toward: f64| -> Vec<[f64; 2]> {
                    // Moved so that its corner nearest the origin is at it.
                    let k = (0..poly.len())
                        .min_by(|&i, &j| (toward * poly[i][0]).total_cmp(&(toward * poly[j][0])))
                        .unwrap();
                    let o = poly[k];
                    (0..poly.len())
                        .map(|i| poly[(k + i) % poly.len()])
                        .map(|p| [p[0] - o[0], p[1] - o[1]])
                        .collect()
                };
                let (l, r) = (touching(left, -1.0), touching(right, 1.0));
                if l.len() < 3 || r.len() < 3 {
                    continue;
                }
                l.into_iter().chain(r).collect()
            };
            let face: Vec<[f64; 3]> = ring.iter().map(|p| [p[0], p[1], 0.0]).collect();
            let Cut::Ears(triangles) = cut(&face) else {
                panic!("round {round}: {:?} for {ring:?}", cut(&face));
            };
            let twice_area = shoelace(&ring);
            assert!(
                (area(&face, &triangles) - twice_area).abs() < 1e-9,
                "round {round}: {} against {twice_area}",
                area(&face, &triangles)
            );
            for t in &triangles {
                let flat = |i: usize| ring[i];
                assert!(
                    cross(flat(t[0]), flat(t[1]), flat(t[2])) > 0.0,
                    "round {round}: {t:?}"
                );
            }
        }
    }

    /// A circle traced twice turns left at every corner and crosses itself nowhere near a
    /// corner: past the 4,096 corners where the edge test once stopped, it is still told.
    #[test]
    fn a_circle_traced_twice_crosses_itself() {
        let n = 4100;
        let circle: Vec<[f64; 3]> = (0..n)
            .map(|k| {
                let angle = 4.0 * std::f64::consts::PI * (k as f64 + 0.5) / n as f64;
                [libm::cos(angle), libm::sin(angle), 0.0]
            })
            .collect();
        assert_eq!(cut(&circle), Cut::CrossesItself);
        assert_eq!(cut(&circle[..n / 2]), Cut::Fan);
    }

    /// A bow tie whose sides are cut into 1,031 edges each (4,124 corners, none on the
    /// crossing): ear clipping finds ears all round it, so only the edge test tells, and
    /// the sweep pairs few enough edges to test them all.
    #[test]
    fn a_face_of_thousands_of_corners_that_crosses_itself_is_told() {
        let bow_tie = [[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]];
        let per_edge = 1031;
        let corners: Vec<[f64; 3]> = (0..bow_tie.len())
            .flat_map(|e| {
                let (a, b) = (bow_tie[e], bow_tie[(e + 1) % bow_tie.len()]);
                (0..per_edge).map(move |k| {
                    let t = k as f64 / per_edge as f64;
                    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), 0.0]
                })
            })
            .collect();
        let flat = flatten(&corners).unwrap();
        assert!(ear_clip(&flat, bounds(&flat)).is_some());
        assert_eq!(crosses_itself(&flat, 1.0), Some(true));
        assert_eq!(cut(&corners), Cut::CrossesItself);
    }

    /// A ladder of 5,000 long rungs, each over the whole x range at its own height (a
    /// zigzag): no two rungs' boxes meet, yet the sweep visits every pair; it stops at its
    /// budget instead of visiting 50 million, and the face is cut into ears.
    #[test]
    fn a_face_of_rungs_over_one_x_range_stops_the_edge_test_at_its_pairs() {
        let rungs = 5000;
        let flat: Vec<[f64; 2]> = (0..rungs)
            .flat_map(|i| {
                let y = i as f64 / rungs as f64;
                let (near, far) = if i % 2 == 0 { (0.0, 1.0) } else { (1.0, 0.0) };
                [[near, y], [far, y]]
            })
            .collect();
        assert_eq!(crosses_itself(&flat, 1.0), None);
    }

    /// A comb of 3,000 slanted teeth, each edge's box over most of the others': the sweep
    /// gives up past its pairs instead of testing 18 million, and the face, which does not
    /// cross itself, is cut into ears as before.
    #[test]
    fn a_face_whose_edges_all_overlap_stops_the_edge_test_at_its_pairs() {
        let teeth = 3000;
        let width = 1.0 / teeth as f64;
        let mut flat: Vec<[f64; 2]> = (0..teeth)
            .flat_map(|i| {
                let x = 1.0 - i as f64 * width;
                [[x + 1.0, 1.0], [x - width / 2.0, 0.0]]
            })
            .collect();
        flat.extend([[0.0, -1.0], [2.0, -1.0]]);
        assert_eq!(crosses_itself(&flat, 3.0), None);
        let corners: Vec<[f64; 3]> = flat.iter().map(|p| [p[0], p[1], 0.0]).collect();
        assert!(matches!(cut(&corners), Cut::Ears(_)), "{:?}", cut(&corners));
    }

    /// A comb of 5,000 teeth (10,003 corners) is cut into 10,001 triangles covering its
    /// area once, each turning as the face does; tested against every corner from the
    /// start of the ring each time, it took 21 s.
    #[test]
    fn a_face_of_many_corners_is_cut_in_one_pass_round_its_ring() {
        let teeth = 5000;
        let width = 1.0 / teeth as f64;
        let mut points: Vec<[f64; 2]> = (0..teeth)
            .flat_map(|i| {
                let x = i as f64 * width;
                [[x, 0.0], [x + width / 2.0, 1.0]]
            })
            .map(|[x, y]| [1.0 - x, y])
            .collect();
        points.extend([[0.0, 0.0], [0.0, -1.0], [1.0, -1.0]]);
        let corners: Vec<[f64; 3]> = points.iter().map(|p| [p[0], p[1], 0.0]).collect();
        let Cut::Ears(triangles) = cut(&corners) else {
            panic!("no ears: {:?}", cut(&corners));
        };
        assert_eq!(triangles.len(), corners.len() - 2);
        let twice_area = 2.0 * (1.0 + 0.5);
        assert!((area(&corners, &triangles) - twice_area).abs() < 1e-9);
        for t in &triangles {
            let flat = |i: usize| [corners[i][0], corners[i][1]];
            assert!(cross(flat(t[0]), flat(t[1]), flat(t[2])) > 0.0, "{t:?}");
        }
    }
}
