//! Bounding volume hierarchy over the scene's triangles: a binned-SAH build into lent,
//! flat buffers, and closest-hit / any-hit traversal with a fixed stack.
//!
//! OWNER: bvh helper. The public API below is what the rest of the code relies on.
//!
//! # Layout
//! - `nodes`: a tree of up to [`WIDTH`] children a node, the root at node 0. A node holds
//!   its children's boxes lane by lane, so that one ray meets all four in one vector
//!   operation; a child is another node (`count` 0, `child` its index, always after its
//!   parent) or a leaf (`child` its first triangle in `packed`, `count` how many). Leaves
//!   are not nodes. At most `n` nodes for `n` triangles.
//! - `packed`: the triangles in leaf order as `(v0, e1, e2, index)`, ready for
//!   Möller–Trumbore. The build uses it as its work array (the permutation it sorts).
//!
//! # Build
//! The binary tree of binned SAH (32 bins per axis over the centroid bounds), collapsed
//! into wide nodes as it is built, without an allocator or recursion: a node's children
//! are its binary children, and while it has fewer than [`WIDTH`] the largest (by area)
//! that the binary rule would split is replaced by its two halves. The binary rule: a
//! range of at most [`MAX_LEAF_TRIANGLES`] triangles becomes a leaf unless SAH prefers a
//! split; a larger one is split by SAH, or at the middle of its range when all centroids
//! coincide or no bin boundary separates them. The children of the deepest nodes (at
//! depth `MAX_BVH_DEPTH - 1`, the root's 0) are leaves whatever their size. Child boxes are
//! padded by a few ulps of the scene's largest coordinate (or of their own, if larger) so
//! that the rounding of the slab test never loses a triangle lying on a box face (flat
//! walls give flat boxes), nor enters its box past a hit at the same distance.
//!
//! # Traversal
//! A node's four boxes are tested at once; the nearest child hit is visited next and the
//! others pushed with their entry distance, nearest on top, and skipped on pop when a hit
//! closer than that entry has been found. Of hits at one distance (an edge two triangles
//! share) the lower triangle index is taken, so the answer does not hang on the tree's
//! shape or the order it is walked in (for rays that start within the scene's bounds, or
//! about as far from them as they are large: `t` rounds by ulps of a ray's length). On the
//! living room's ray sets (`relume bench rays`, one thread) four children a node trace
//! 4-27% more rays a second than two did (docs/renderer-vs-radiance.md, "Ray tracing
//! speed"). The fixed stack cannot overflow (see `STACK`).

use crate::config::{MAX_BVH_DEPTH, MAX_LEAF_TRIANGLES, MAX_TRIANGLES};
use crate::error::{check_capacity, Error};
use crate::geometry::{Ray, Triangle};

/// Children a node can have.
pub const WIDTH: usize = 4;

/// One node of the flat tree (128 bytes): its children's boxes, lane by lane.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct BvhNode {
    /// `min[axis][slot]`: the lower corner of child `slot`'s box. An empty slot's box lies
    /// at +infinity, where no ray enters it.
    pub min: [[f32; WIDTH]; 3],
    pub max: [[f32; WIDTH]; 3],
    /// A node child: its index (after this node's). A leaf child: the index of its first
    /// triangle in the leaf-order array. An empty slot: [`EMPTY_SLOT`].
    pub child: [u32; WIDTH],
    /// Triangles in a leaf child; 0 for a node child or an empty slot.
    pub count: [u32; WIDTH],
}

/// The `child` of an empty slot.
pub const EMPTY_SLOT: u32 = u32::MAX;

impl Default for BvhNode {
    /// A node of empty slots.
    fn default() -> BvhNode {
        BvhNode {
            min: [[f32::INFINITY; WIDTH]; 3],
            max: [[f32::INFINITY; WIDTH]; 3],
            child: [EMPTY_SLOT; WIDTH],
            count: [0; WIDTH],
        }
    }
}

/// A triangle in leaf order, laid out for intersection.
#[derive(Clone, Copy, Debug, Default)]
pub struct PackedTriangle {
    pub v0: [f32; 3],
    pub e1: [f32; 3],
    pub e2: [f32; 3],
    /// Index of the triangle in the scene's triangle array.
    pub index: u32,
}

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    /// Index into the scene's triangle array.
    pub triangle: u32,
    /// Barycentric weights of `v1` and `v2`.
    pub b1: f32,
    pub b2: f32,
}

/// The storage a BVH is built into, lent by the caller. [`Bvh::buffer_sizes`] tells how
/// large each slice must be.
pub struct BvhBuffers<'a> {
    pub nodes: &'a mut [BvhNode],
    pub packed: &'a mut [PackedTriangle],
}

/// A built hierarchy: read-only views of the lent buffers.
#[derive(Clone, Copy)]
pub struct Bvh<'a> {
    /// The nodes in use (empty when there are no triangles).
    nodes: &'a [BvhNode],
    /// The triangles in leaf order (exactly the scene's triangle count).
    packed: &'a [PackedTriangle],
}

/// SAH bins per axis (32 gave ~8% faster traversal than 16 on the living room).
const BINS: usize = 32;
/// SAH cost of one interior node (two box tests), relative to one triangle test.
const COST_TRAVERSAL: f32 = 1.0;
/// SAH cost of one triangle test.
const COST_INTERSECT: f32 = 1.0;
/// Stack entries of a build or a traversal: the children pending are at most `WIDTH - 1`
/// siblings of each node on the path from the root, and nodes are fewer than
/// `MAX_BVH_DEPTH` deep. (Small on purpose: when the traversal's stack was an array
/// cleared for every ray, 256 entries cost 20-25% of the primary rays' speed; it is now
/// left uncleared, [`Stack`], and the build's still is.)
const STACK: usize = 64;
/// `STACK - 1`, to index the stack without bounds checks (`STACK` is a power of two).
const STACK_MASK: usize = STACK - 1;
const _: () = assert!(STACK.is_power_of_two());
// The deepest node's ancestors leave `WIDTH - 1` children each, and its own `WIDTH` are
// pushed before the nearest is popped: `(WIDTH - 1) (MAX_BVH_DEPTH - 1) + WIDTH`.
const _: () = assert!(STACK > (WIDTH - 1) * MAX_BVH_DEPTH);

// ---------------------------------------------------------------------------------------
// Small float helpers (branch-free `minss`/`maxss`; NaN handling is not needed where
// they are used).

#[inline(always)]
fn fmin(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn sub3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
fn add3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline(always)]
fn cross3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

// ---------------------------------------------------------------------------------------
// Build.

/// An axis-aligned box; `EMPTY` is inverted so that growing it by anything gives that.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    min: [f32; 3],
    max: [f32; 3],
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: [f32::INFINITY; 3],
        max: [f32::NEG_INFINITY; 3],
    };

    #[inline]
    fn grow(&mut self, b: &Aabb) {
        for k in 0..3 {
            self.min[k] = self.min[k].min(b.min[k]);
            self.max[k] = self.max[k].max(b.max[k]);
        }
    }

    #[inline]
    fn grow_point(&mut self, p: [f32; 3]) {
        for (k, c) in p.into_iter().enumerate() {
            self.min[k] = self.min[k].min(c);
            self.max[k] = self.max[k].max(c);
        }
    }

    /// Half the surface area (SAH only compares ratios). Empty boxes give 0.
    #[inline]
    fn half_area(&self) -> f32 {
        let d = sub3(self.max, self.min);
        if !(d[0] >= 0.0 && d[1] >= 0.0 && d[2] >= 0.0) {
            return 0.0;
        }
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    }

    #[inline]
    fn centroid(&self) -> [f32; 3] {
        [
            (self.min[0] + self.max[0]) * 0.5,
            (self.min[1] + self.max[1]) * 0.5,
            (self.min[2] + self.max[2]) * 0.5,
        ]
    }

    /// The box grown on every side by a few ulps of its coordinates or of `scale` (the
    /// scene's largest coordinate), whichever is larger: a hit's `t`, and the slab test's,
    /// round by ulps of the ray's length, which a box's own coordinates do not bound (a
    /// floor at z = 0 has a box `f32::MIN_POSITIVE` thick).
    fn padded(&self, scale: f32) -> Aabb {
        let mut out = *self;
        for k in 0..3 {
            let m = self.min[k].abs().max(self.max[k].abs()).max(scale);
            let eps = m * (1.0 / 1_048_576.0) + f32::MIN_POSITIVE;
            out.min[k] = self.min[k] - eps;
            out.max[k] = self.max[k] + eps;
        }
        out
    }
}

/// The bounds of a packed triangle, from the vertices as traversal sees them.
#[inline]
fn packed_bounds(p: &PackedTriangle) -> Aabb {
    let v1 = add3(p.v0, p.e1);
    let v2 = add3(p.v0, p.e2);
    let mut b = Aabb {
        min: p.v0,
        max: p.v0,
    };
    b.grow_point(v1);
    b.grow_point(v2);
    b
}

/// A triangle laid out for intersection.
#[inline]
fn pack(t: &Triangle, index: u32) -> PackedTriangle {
    let v0 = t.v[0].to_array();
    PackedTriangle {
        v0,
        e1: sub3(t.v[1].to_array(), v0),
        e2: sub3(t.v[2].to_array(), v0),
        index,
    }
}

/// The SAH bin of a centroid coordinate. Saturating casts keep NaN and overflow in range.
#[inline]
fn bin_of(c: f32, lo: f32, scale: f32) -> usize {
    (((c - lo) * scale) as usize).min(BINS - 1)
}

/// A chosen split: centroids in bins `<= bin` along `axis` go to the first child.
#[derive(Clone, Copy)]
struct Split {
    axis: usize,
    bin: usize,
    lo: f32,
    scale: f32,
    /// `A_L N_L + A_R N_R` (unnormalised SAH cost of the children).
    cost: f32,
}

/// The best binned-SAH split of `items` (centroid bounds `cb`), if any bin boundary
/// separates them.
fn find_split(items: &[PackedTriangle], cb: &Aabb) -> Option<Split> {
    let mut best: Option<Split> = None;
    for axis in 0..3 {
        let lo = cb.min[axis];
        let extent = cb.max[axis] - lo;
        if !(extent > 0.0) {
            continue;
        }
        let scale = BINS as f32 / extent;
        if !scale.is_finite() {
            continue;
        }
        let mut counts = [0u32; BINS];
        let mut boxes = [Aabb::EMPTY; BINS];
        for p in items {
            let b = packed_bounds(p);
            let k = bin_of(b.centroid()[axis], lo, scale);
            counts[k] += 1;
            boxes[k].grow(&b);
        }
        // Right-to-left sweep: area and count of bins k+1.. for each boundary k.
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0u32; BINS];
        let mut acc = Aabb::EMPTY;
        let mut n = 0u32;
        for k in (1..BINS).rev() {
            acc.grow(&boxes[k]);
            n += counts[k];
            right_area[k - 1] = acc.half_area();
            right_count[k - 1] = n;
        }
        let mut acc = Aabb::EMPTY;
        let mut n = 0u32;
        for k in 0..BINS - 1 {
            acc.grow(&boxes[k]);
            n += counts[k];
            if n == 0 || right_count[k] == 0 {
                continue;
            }
            let cost = acc.half_area() * n as f32 + right_area[k] * right_count[k] as f32;
            // Strict `<`: ties keep the earlier axis and boundary (deterministic).
            if best.is_none_or(|b| cost < b.cost) {
                best = Some(Split {
                    axis,
                    bin: k,
                    lo,
                    scale,
                    cost,
                });
            }
        }
    }
    best
}

/// Moves the triangles of `items` whose centroid falls in bins `<= split.bin` to the
/// front; returns how many there are.
fn partition(items: &mut [PackedTriangle], split: &Split) -> usize {
    let goes_left = |p: &PackedTriangle| {
        bin_of(
            packed_bounds(p).centroid()[split.axis],
            split.lo,
            split.scale,
        ) <= split.bin
    };
    let mut i = 0;
    let mut j = items.len();
    while i < j {
        if goes_left(&items[i]) {
            i += 1;
        } else {
            j -= 1;
            items.swap(i, j);
        }
    }
    i
}

/// A range of the leaf-order array on its way to becoming a child: its padded box, and
/// where the binary rule splits it (its triangles already partitioned there), if it does.
#[derive(Clone, Copy)]
struct Range {
    start: usize,
    end: usize,
    bounds: Aabb,
    split_at: Option<usize>,
}

impl Default for Range {
    fn default() -> Range {
        Range {
            start: 0,
            end: 0,
            bounds: Aabb::EMPTY,
            split_at: None,
        }
    }
}

/// A node child to build: its range, its depth in nodes, and the node and slot whose
/// `child` must point at it.
#[derive(Clone, Copy, Default)]
struct Task {
    range: Range,
    depth: usize,
    parent: usize,
    slot: usize,
}

impl<'a> Bvh<'a> {
    /// `(nodes, packed)` lengths needed for `n_triangles`.
    pub fn buffer_sizes(n_triangles: usize) -> (usize, usize) {
        (n_triangles.max(1), n_triangles)
    }

    /// Builds the hierarchy. Errors: capacity (too many triangles), buffers too small,
    /// non-finite vertices.
    pub fn build(triangles: &[Triangle], buffers: BvhBuffers<'a>) -> Result<Bvh<'a>, Error> {
        Bvh::build_with_depth(triangles, buffers, MAX_BVH_DEPTH)
    }

    /// [`Bvh::build`] with nodes fewer than `max_depth` deep (at most [`MAX_BVH_DEPTH`]):
    /// children there are leaves, however large.
    fn build_with_depth(
        triangles: &[Triangle],
        buffers: BvhBuffers<'a>,
        max_depth: usize,
    ) -> Result<Bvh<'a>, Error> {
        let n = triangles.len();
        check_capacity("config::MAX_TRIANGLES", MAX_TRIANGLES, n)?;
        let BvhBuffers { nodes, packed } = buffers;
        // Every node but a lone root has at least two children, so a tree over at most
        // `n` leaves has at most `n - 1` nodes besides the root's.
        let nodes_needed = n;
        if nodes.len() < nodes_needed {
            return Err(Error::BufferTooSmall {
                what: "bvh nodes",
                needed: nodes_needed,
                got: nodes.len(),
            });
        }
        if packed.len() < n {
            return Err(Error::BufferTooSmall {
                what: "bvh packed",
                needed: n,
                got: packed.len(),
            });
        }
        if triangles.iter().any(|t| !t.v.iter().all(|v| v.is_finite())) {
            return Err(Error::InvalidValue {
                what: "triangle vertex is not finite",
            });
        }
        let packed = &mut packed[..n];
        for (i, (p, t)) in packed.iter_mut().zip(triangles).enumerate() {
            *p = pack(t, i as u32);
        }
        let used = if n == 0 {
            0
        } else {
            build_nodes(nodes, packed, max_depth.clamp(1, MAX_BVH_DEPTH))
        };
        let nodes: &'a [BvhNode] = nodes;
        let packed: &'a [PackedTriangle] = packed;
        Ok(Bvh {
            nodes: nodes.get(..used).unwrap_or(&[]),
            packed,
        })
    }

    /// How many nodes the hierarchy uses: with [`Bvh::from_built`], the buffers can be
    /// viewed again without building.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// A view of buffers that [`Bvh::build`] filled for these `triangles`, using
    /// `node_count` nodes ([`Bvh::node_count`]): recovery renders the same geometry many
    /// times under new materials, and building costs as much as a few hundred thousand
    /// rays. Errors if the buffers are too short for the counts, or if the nodes are not a
    /// tree laid out as the build lays one (`in_build_order`: each node walked at most
    /// once, so every walk ends, and within the walk's stack). Traversal checks every
    /// index, so buffers that were not built for these triangles give wrong hits, never a
    /// panic or a hang. A small target can keep a tree built elsewhere in read-only
    /// memory and view it here.
    pub fn from_built(
        triangles: &[Triangle],
        nodes: &'a [BvhNode],
        packed: &'a [PackedTriangle],
        node_count: usize,
    ) -> Result<Bvh<'a>, Error> {
        let n = triangles.len();
        let (Some(nodes), Some(packed)) = (nodes.get(..node_count), packed.get(..n)) else {
            return Err(Error::BufferTooSmall {
                what: "built bvh",
                needed: node_count.max(n),
                got: nodes.len().min(packed.len()),
            });
        };
        if (n == 0) != (node_count == 0) {
            return Err(Error::InvalidValue {
                what: "built bvh: node count does not match the triangles",
            });
        }
        if !in_build_order(nodes) {
            return Err(Error::InvalidValue {
                what: "built bvh: the nodes are not a tree in the order Bvh::build lays one out",
            });
        }
        Ok(Bvh { nodes, packed })
    }

    /// The closest hit with `t` in `(0, t_max)`.
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        let r = RayData::new(ray);
        let mut best_t = t_max;
        let mut best_idx = u32::MAX;
        let mut best_b = (0.0f32, 0.0f32);
        let mut stack = Stack::new();
        let mut cur = Pending::ROOT;
        if self.nodes.is_empty() {
            return None;
        }
        loop {
            if cur.count == 0 {
                if let Some(node) = self.nodes.get(cur.child as usize) {
                    if let Some(nearest) = visit_children(node, &r, best_t, &mut stack) {
                        cur = nearest;
                        continue;
                    }
                }
            } else {
                let first = cur.child as usize;
                let end = first.saturating_add(cur.count as usize);
                if let Some(tris) = self.packed.get(first..end) {
                    for p in tris {
                        if let Some((t, b1, b2)) = intersect_triangle(p, &r, best_t) {
                            // Of two hits at the same distance (an edge two triangles
                            // share), the lower index: the answer then does not hang on
                            // the order the tree is walked in.
                            let tie = t == best_t && best_idx != u32::MAX && p.index < best_idx;
                            if t < best_t || tie {
                                best_t = t;
                                best_idx = p.index;
                                best_b = (b1, b2);
                            }
                        }
                    }
                }
            }
            // Pop the nearest pending child that can still hold a closer hit.
            loop {
                let Some(pending) = stack.pop() else {
                    return (best_idx != u32::MAX).then_some(Hit {
                        t: best_t,
                        triangle: best_idx,
                        b1: best_b.0,
                        b2: best_b.1,
                    });
                };
                if pending.entry < best_t || (pending.entry == best_t && best_idx != u32::MAX) {
                    cur = pending;
                    break;
                }
            }
        }
    }

    /// True when anything is hit with `t` in `(0, t_max)`.
    ///
    /// The walk repeats `intersect`'s loop on purpose, its child step shared
    /// (`visit_children`): in the binary tree, one helper for the whole step cost 9-14%
    /// Mrays/s on the living-room ray sets (`relume bench rays`, same run), and this is the
    /// renderer's innermost loop.
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        let r = RayData::new(ray);
        let mut stack = Stack::new();
        let mut cur = Pending::ROOT;
        if self.nodes.is_empty() {
            return false;
        }
        loop {
            if cur.count == 0 {
                if let Some(node) = self.nodes.get(cur.child as usize) {
                    if let Some(nearest) = visit_children(node, &r, t_max, &mut stack) {
                        cur = nearest;
                        continue;
                    }
                }
            } else {
                let first = cur.child as usize;
                let end = first.saturating_add(cur.count as usize);
                if let Some(tris) = self.packed.get(first..end) {
                    for p in tris {
                        if intersect_triangle(p, &r, t_max).is_some_and(|(t, _, _)| t < t_max) {
                            return true;
                        }
                    }
                }
            }
            match stack.pop() {
                Some(pending) => cur = pending,
                None => return false,
            }
        }
    }
}

/// Whether `nodes` are a tree in [`build_nodes`]' order: depth first from node 0, each
/// node's node children taken last slot first, nodes fewer than [`MAX_BVH_DEPTH`] deep.
/// Every node but the root is then the child of exactly one node, after it, so that a walk
/// visits each node at most once and its stack never fills. Checking that every child
/// points forward is not enough: nodes whose children all name the next node are walked
/// 4^depth times. One pass, with a stack as deep as the build's.
fn in_build_order(nodes: &[BvhNode]) -> bool {
    // The children announced and not yet met, with their depths.
    let mut announced = [(0u32, 0usize); STACK];
    let mut sp = 0usize;
    for (i, node) in nodes.iter().enumerate() {
        let depth = if i == 0 {
            0
        } else {
            // Node i is the child announced last and not yet met.
            let Some(top) = sp.checked_sub(1) else {
                return false;
            };
            sp = top;
            let (child, depth) = announced[sp];
            if child as usize != i || depth >= MAX_BVH_DEPTH {
                return false;
            }
            depth
        };
        for (&child, &count) in node.child.iter().zip(&node.count) {
            if count == 0 && child != EMPTY_SLOT {
                let Some(entry) = announced.get_mut(sp) else {
                    return false;
                };
                *entry = (child, depth + 1);
                sp += 1;
            }
        }
    }
    sp == 0
}

/// `packed[start..end]` as a [`Range`]: its box, and its split by the binary rule (the
/// module's "Build"), which partitions its triangles.
/// `scale` is the scene's largest coordinate ([`Aabb::padded`]).
fn make_range(packed: &mut [PackedTriangle], (start, end): (usize, usize), scale: f32) -> Range {
    let items = packed.get_mut(start..end).unwrap_or(&mut []);
    let count = items.len();
    let mut bounds = Aabb::EMPTY;
    let mut cbounds = Aabb::EMPTY;
    for p in items.iter() {
        let b = packed_bounds(p);
        bounds.grow(&b);
        cbounds.grow_point(b.centroid());
    }
    let mut split_at = None;
    if count > 1 {
        match find_split(items, &cbounds) {
            Some(split) => {
                let split_cost = COST_TRAVERSAL + COST_INTERSECT * split.cost / bounds.half_area();
                let leaf_cost = COST_INTERSECT * count as f32;
                // `!(leaf <= split)`: a NaN cost (huge coordinates) also splits.
                if count > MAX_LEAF_TRIANGLES || !(leaf_cost <= split_cost) {
                    let m = partition(items, &split);
                    split_at = Some(if m == 0 || m == count { count / 2 } else { m });
                }
            }
            None if count > MAX_LEAF_TRIANGLES => split_at = Some(count / 2),
            None => {}
        }
    }
    Range {
        start,
        end,
        bounds: bounds.padded(scale),
        split_at,
    }
}

/// The children of a node over `range` (which splits, or is the whole tree): its two
/// binary halves, then, while there are fewer than [`WIDTH`], the largest child that
/// splits replaced by its halves. Returns them and how many there are.
fn open_children(
    packed: &mut [PackedTriangle],
    range: Range,
    scale: f32,
) -> ([Range; WIDTH], usize) {
    let mut kids = [Range::default(); WIDTH];
    kids[0] = range;
    let mut k = 1;
    while k < WIDTH {
        // The largest that splits; ties keep the first (deterministic).
        let mut open: Option<(usize, usize, f32)> = None;
        for (i, kid) in kids[..k].iter().enumerate() {
            if let Some(m) = kid.split_at {
                let area = kid.bounds.half_area();
                if open.is_none_or(|(_, _, a)| area > a) {
                    open = Some((i, m, area));
                }
            }
        }
        let Some((i, m, _)) = open else {
            break;
        };
        let r = kids[i];
        let mid = r.start + m;
        kids[i] = make_range(packed, (r.start, mid), scale);
        kids[k] = make_range(packed, (mid, r.end), scale);
        k += 1;
    }
    (kids, k)
}

/// Builds the tree over `packed` (non-empty) into `nodes` (at least `packed.len()` long),
/// its nodes fewer than `max_depth` deep (at least 1); returns the number of nodes used.
/// Depth first: a node's last child is the next node.
fn build_nodes(nodes: &mut [BvhNode], packed: &mut [PackedTriangle], max_depth: usize) -> usize {
    let mut stack = [Task::default(); STACK];
    let mut sp = 0usize;
    let mut at = 0usize;
    let mut depth = 0usize;
    let mut next = 1usize;
    // The largest finite coordinate of the scene, which every box is padded by ulps of.
    let scale = packed
        .iter()
        .flat_map(|p| {
            let b = packed_bounds(p);
            [b.min, b.max]
        })
        .flatten()
        .map(f32::abs)
        .filter(|c| c.is_finite())
        .fold(0.0f32, f32::max);
    let mut range = make_range(packed, (0, packed.len()), scale);
    loop {
        let (kids, k) = open_children(packed, range, scale);
        let mut node = BvhNode::default();
        for (slot, kid) in kids[..k].iter().enumerate() {
            for axis in 0..3 {
                node.min[axis][slot] = kid.bounds.min[axis];
                node.max[axis][slot] = kid.bounds.max[axis];
            }
            if kid.split_at.is_some() && depth + 1 < max_depth {
                // Patched to the child's index when it is built.
                node.count[slot] = 0;
                stack[sp & STACK_MASK] = Task {
                    range: *kid,
                    depth: depth + 1,
                    parent: at,
                    slot,
                };
                sp += 1;
            } else {
                node.child[slot] = kid.start as u32;
                node.count[slot] = (kid.end - kid.start) as u32;
            }
        }
        let Some(slot) = nodes.get_mut(at) else {
            // Unreachable with a buffer of `n` nodes; stop rather than panic.
            break;
        };
        *slot = node;
        if sp == 0 {
            break;
        }
        sp -= 1;
        let task = stack[sp & STACK_MASK];
        at = next;
        next += 1;
        if let Some(parent) = nodes.get_mut(task.parent) {
            parent.child[task.slot] = at as u32;
        }
        range = task.range;
        depth = task.depth;
    }
    next.min(nodes.len())
}

// ---------------------------------------------------------------------------------------
// Traversal.

/// A ray prepared for box and triangle tests.
#[derive(Clone, Copy)]
struct RayData {
    o: [f32; 3],
    d: [f32; 3],
    /// `1 / d`, with zero components replaced by a tiny value of the same sign so that
    /// no `0 * inf` NaN can appear.
    inv: [f32; 3],
    /// Per axis, whether `inv` is negative: the ray then enters a box by its `max` plane
    /// and leaves by its `min`.
    negative: [bool; 3],
}

impl RayData {
    #[inline(always)]
    fn new(ray: &Ray) -> RayData {
        let o = ray.origin.to_array();
        let d = ray.direction.to_array();
        let inv = d.map(|c| {
            let c = if c.abs() < 1e-30 {
                1e-30f32.copysign(c)
            } else {
                c
            };
            1.0 / c
        });
        let negative = inv.map(|c| c < 0.0);
        RayData {
            o,
            d,
            inv,
            negative,
        }
    }
}

/// The children a walk has still to visit, nearest on top. Not cleared for each ray: an
/// array of [`STACK`] entries set to zero cost every ray a `memset` of 768 bytes, 2.2% of
/// a recovery's time (living room at 64 px, `perf`).
type Stack = heapless::Vec<Pending, STACK>;

/// Pushes `p`; the stack never fills (see [`STACK`]), and a push past it would be lost
/// (where the array's index wrapped before).
#[inline(always)]
fn push(stack: &mut Stack, p: Pending) {
    let _ = stack.push(p);
}

/// A child still to visit: a node (`count` 0) or a leaf, and the ray's entry distance
/// into its box.
#[derive(Clone, Copy, Default)]
struct Pending {
    child: u32,
    count: u32,
    entry: f32,
}

impl Pending {
    const ROOT: Pending = Pending {
        child: 0,
        count: 0,
        entry: 0.0,
    };
}

/// Entry distances of the ray into the node's four child boxes, clamped to `[0, t_max]`;
/// `INFINITY` where a box is missed within that range (or the slot is empty). Lane by
/// lane, so that the four slab tests compile to vector operations.
///
/// Each axis's entry and exit planes are chosen once by the sign of the ray's direction
/// (`RayData::negative`) instead of ordered lane by lane with a min and a max: the same
/// values, since `(min - o) * inv <= (max - o) * inv` for `inv > 0` under rounding too.
#[inline(always)]
fn child_entries(n: &BvhNode, r: &RayData, t_max: f32) -> [f32; WIDTH] {
    let planes = |axis: usize| match r.negative[axis] {
        false => (&n.min[axis], &n.max[axis]),
        true => (&n.max[axis], &n.min[axis]),
    };
    let (x0, x1) = planes(0);
    let (y0, y1) = planes(1);
    let (z0, z1) = planes(2);
    let mut out = [0.0f32; WIDTH];
    for (i, out) in out.iter_mut().enumerate() {
        let tx0 = (x0[i] - r.o[0]) * r.inv[0];
        let tx1 = (x1[i] - r.o[0]) * r.inv[0];
        let ty0 = (y0[i] - r.o[1]) * r.inv[1];
        let ty1 = (y1[i] - r.o[1]) * r.inv[1];
        let tz0 = (z0[i] - r.o[2]) * r.inv[2];
        let tz1 = (z1[i] - r.o[2]) * r.inv[2];
        let near = fmax(fmax(tx0, ty0), fmax(tz0, 0.0));
        let far = fmin(fmin(tx1, ty1), fmin(tz1, t_max));
        *out = if near <= far { near } else { f32::INFINITY };
    }
    out
}

/// The nearest child of `n` the ray enters within `t_max`, if any; the others it enters
/// are pushed on `stack` so that they pop nearest first (the order of equal entries does
/// not change a hit: one shared by two triangles goes to the lower index).
/// The entries are sorted where they lie: a small array of them, sorted and then copied,
/// stalled on its loads (store forwarding) and cost a third of the traversal.
#[inline(always)]
fn visit_children(n: &BvhNode, r: &RayData, t_max: f32, stack: &mut Stack) -> Option<Pending> {
    let entries = child_entries(n, r, t_max);
    let pending = |slot: usize| Pending {
        child: n.child[slot & (WIDTH - 1)],
        count: n.count[slot & (WIDTH - 1)],
        entry: entries[slot & (WIDTH - 1)],
    };
    let mut hit = 0u32;
    for (slot, &entry) in entries.iter().enumerate() {
        hit |= ((entry < f32::INFINITY) as u32) << slot;
    }
    if hit == 0 {
        return None;
    }
    let a = hit.trailing_zeros() as usize;
    let rest = hit & (hit - 1);
    if rest == 0 {
        return Some(pending(a));
    }
    let b = rest.trailing_zeros() as usize;
    if rest & (rest - 1) == 0 {
        // Two children, the commonest case after one.
        let (near, far) = if entries[b & (WIDTH - 1)] < entries[a & (WIDTH - 1)] {
            (b, a)
        } else {
            (a, b)
        };
        push(stack, pending(far));
        return Some(pending(near));
    }
    // Three or four: push them all sorted, nearest on top, and pop the nearest.
    let base = stack.len();
    let mut left = hit;
    while left != 0 {
        let slot = left.trailing_zeros() as usize;
        left &= left - 1;
        push(stack, pending(slot));
        let mut j = stack.len() - 1;
        while j > base && stack[j - 1].entry < stack[j].entry {
            stack.swap(j - 1, j);
            j -= 1;
        }
    }
    stack.pop()
}

/// Two-sided Möller–Trumbore: `(t, b1, b2)` when the ray hits the triangle with
/// `0 < t <= t_max` (callers that want `t_max` open test it: the closest hit takes a
/// second hit at its distance when its index is lower). Degenerate triangles (zero
/// determinant) are never hit.
#[inline(always)]
fn intersect_triangle(p: &PackedTriangle, r: &RayData, t_max: f32) -> Option<(f32, f32, f32)> {
    let pv = cross3(r.d, p.e2);
    let det = dot3(p.e1, pv);
    let s = sub3(r.o, p.v0);
    let q = cross3(s, p.e1);
    // Scale the numerators by the sign of the determinant: the tests below then hold for
    // both faces without a division.
    let sign = 1.0f32.copysign(det);
    let adet = det.abs();
    let u = dot3(s, pv) * sign;
    let v = dot3(r.d, q) * sign;
    if !(u >= 0.0 && v >= 0.0 && u + v <= adet) {
        return None;
    }
    let inv = 1.0 / adet;
    let t = dot3(p.e2, q) * sign * inv;
    if !(t > 0.0 && t <= t_max) {
        return None;
    }
    let b1 = u * inv;
    let b2 = (v * inv).min(1.0 - b1);
    Some((t, b1, b2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Surface;
    use crate::math::{Vec2, Vec3};
    use crate::rng::Sampler;
    use std::vec;
    use std::vec::Vec;

    fn tri(a: Vec3, b: Vec3, c: Vec3) -> Triangle {
        Triangle {
            v: [a, b, c],
            uv: [Vec2::ZERO; 3],
            surface: Surface::Group(0),
        }
    }

    struct Owned {
        nodes: Vec<BvhNode>,
        packed: Vec<PackedTriangle>,
    }

    impl Owned {
        fn new(n: usize) -> Owned {
            let (a, b) = Bvh::buffer_sizes(n);
            Owned {
                nodes: vec![BvhNode::default(); a],
                packed: vec![PackedTriangle::default(); b],
            }
        }
        fn build<'a>(&'a mut self, tris: &[Triangle]) -> Bvh<'a> {
            Bvh::build(
                tris,
                BvhBuffers {
                    nodes: &mut self.nodes,
                    packed: &mut self.packed,
                },
            )
            .unwrap()
        }
    }

    fn rand_vec(s: &mut Sampler, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(
            lo + (hi - lo) * s.next_f32(),
            lo + (hi - lo) * s.next_f32(),
            lo + (hi - lo) * s.next_f32(),
        )
    }

    fn rand_dir(s: &mut Sampler) -> Vec3 {
        loop {
            let v = rand_vec(s, -1.0, 1.0);
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / crate::math::sqrt(l);
            }
        }
    }

    /// Closest hit over all triangles, with the same triangle test; of hits at the same
    /// distance, the first.
    fn brute(tris: &[Triangle], ray: &Ray, t_max: f32) -> Option<Hit> {
        let r = RayData::new(ray);
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        for (i, t) in tris.iter().enumerate() {
            let hit = intersect_triangle(&pack(t, i as u32), &r, t_best);
            if let Some((t, b1, b2)) = hit.filter(|&(t, _, _)| t < t_best) {
                t_best = t;
                best = Some(Hit {
                    t,
                    triangle: i as u32,
                    b1,
                    b2,
                });
            }
        }
        best
    }

    fn random_soup(seed: u64, n: usize, size: f32) -> Vec<Triangle> {
        let mut s = Sampler::from_key(seed);
        (0..n)
            .map(|_| {
                let c = rand_vec(&mut s, -1.0, 1.0);
                tri(
                    c + rand_vec(&mut s, -size, size),
                    c + rand_vec(&mut s, -size, size),
                    c + rand_vec(&mut s, -size, size),
                )
            })
            .collect()
    }

    /// Axis-aligned quads on a grid inside a closed box, all sharing edges: many exact
    /// ties and flat node boxes.
    fn grid_box_scene() -> Vec<Triangle> {
        let mut out = Vec::new();
        let n = 8;
        let quad = |out: &mut Vec<Triangle>, p: Vec3, u: Vec3, v: Vec3| {
            out.push(tri(p, p + u, p + u + v));
            out.push(tri(p, p + u + v, p + v));
        };
        for axis in 0..3 {
            for side in [0.0f32, 4.0] {
                for i in 0..n {
                    for j in 0..n {
                        let step = 4.0 / n as f32;
                        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                        let mut p = Vec3::ZERO;
                        p[axis] = side;
                        p[a] = i as f32 * step;
                        p[b] = j as f32 * step;
                        let mut u = Vec3::ZERO;
                        u[a] = step;
                        let mut v = Vec3::ZERO;
                        v[b] = step;
                        quad(&mut out, p, u, v);
                    }
                }
            }
        }
        // A few boxes inside.
        for k in 0..4 {
            let lo = Vec3::new(0.5 + k as f32 * 0.8, 0.5, 0.0);
            for axis in 0..3 {
                for side in [0.0f32, 0.5] {
                    let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                    let mut p = lo;
                    p[axis] += side;
                    let mut u = Vec3::ZERO;
                    u[a] = 0.5;
                    let mut v = Vec3::ZERO;
                    v[b] = 0.5;
                    quad(&mut out, p, u, v);
                }
            }
        }
        out
    }

    /// A child's box.
    fn child_box(n: &BvhNode, slot: usize) -> Aabb {
        Aabb {
            min: [n.min[0][slot], n.min[1][slot], n.min[2][slot]],
            max: [n.max[0][slot], n.max[1][slot], n.max[2][slot]],
        }
    }

    /// Checks the tree's structure: every triangle in exactly one leaf, every node reached
    /// once and after its parent, child boxes containing their children's boxes and
    /// triangles, empty slots only after the used ones and never entered.
    fn check_tree(bvh: &Bvh, tris: &[Triangle]) {
        let nodes = bvh.nodes;
        let packed = bvh.packed;
        assert_eq!(packed.len(), tris.len());
        if tris.is_empty() {
            assert!(nodes.is_empty());
            return;
        }
        assert!(nodes.len() <= tris.len().max(1));
        // What the build laid out, `from_built` takes back.
        assert!(in_build_order(nodes));
        assert!(Bvh::from_built(tris, nodes, packed, nodes.len()).is_ok());
        let mut seen = vec![false; tris.len()];
        let mut visited = vec![false; nodes.len()];
        let everything = Aabb {
            min: [f32::NEG_INFINITY; 3],
            max: [f32::INFINITY; 3],
        };
        // (node, wide depth, the box its parent gives it)
        let mut stack = vec![(0usize, 0usize, everything)];
        while let Some((i, depth, outer)) = stack.pop() {
            assert!(depth < MAX_BVH_DEPTH);
            assert!(!visited[i], "node {i} reached twice");
            visited[i] = true;
            let n = nodes[i];
            let used = (0..WIDTH).take_while(|&s| n.child[s] != EMPTY_SLOT).count();
            assert!(
                used >= 2 || (i == 0 && used == 1),
                "node {i}: {used} children"
            );
            for slot in 0..WIDTH {
                let b = child_box(&n, slot);
                if slot >= used {
                    assert_eq!((n.child[slot], n.count[slot]), (EMPTY_SLOT, 0));
                    let r = RayData::new(&Ray::new(Vec3::ZERO, Vec3::ONE.normalize()));
                    assert_eq!(child_entries(&n, &r, f32::INFINITY)[slot], f32::INFINITY);
                    continue;
                }
                let within = |inner: &Aabb| {
                    (0..3).all(|k| b.min[k] <= inner.min[k] && inner.max[k] <= b.max[k])
                };
                assert!((0..3).all(|k| outer.min[k] <= b.min[k] && b.max[k] <= outer.max[k]));
                if n.count[slot] == 0 {
                    let c = n.child[slot] as usize;
                    assert!(c > i && c < nodes.len());
                    stack.push((c, depth + 1, b));
                } else {
                    let first = n.child[slot] as usize;
                    for p in &packed[first..first + n.count[slot] as usize] {
                        assert!(!seen[p.index as usize]);
                        seen[p.index as usize] = true;
                        assert!(within(&packed_bounds(p)));
                        for v in tris[p.index as usize].v {
                            assert!((0..3).all(|k| b.min[k] <= v[k] && v[k] <= b.max[k]));
                        }
                    }
                }
            }
        }
        assert!(seen.iter().all(|&s| s), "a triangle is in no leaf");
        assert!(visited.iter().all(|&s| s), "an unreachable node");
    }

    /// The depth of the deepest node (the root's is 0).
    fn depth_of(bvh: &Bvh) -> usize {
        let mut deepest = 0;
        let mut stack = vec![(0usize, 0usize)];
        while let Some((i, depth)) = stack.pop() {
            deepest = deepest.max(depth);
            let n = bvh.nodes[i];
            for slot in 0..WIDTH {
                if n.count[slot] == 0 && n.child[slot] != EMPTY_SLOT {
                    stack.push((n.child[slot] as usize, depth + 1));
                }
            }
        }
        deepest
    }

    fn leaf_sizes(bvh: &Bvh) -> Vec<u32> {
        bvh.nodes
            .iter()
            .flat_map(|n| n.count)
            .filter(|&c| c > 0)
            .collect()
    }

    /// Compares `intersect` and `occluded` with brute force for `n_rays` random rays.
    fn compare_with_brute(tris: &[Triangle], seed: u64, n_rays: usize, lo: f32, hi: f32) {
        let mut owned = Owned::new(tris.len());
        let bvh = owned.build(tris);
        check_tree(&bvh, tris);
        let mut s = Sampler::from_key(seed);
        let mut hits = 0;
        for i in 0..n_rays {
            let o = rand_vec(&mut s, lo, hi);
            let d = if i % 7 == 0 {
                // Axis-aligned directions (zero components) now and then.
                let mut d = Vec3::ZERO;
                d[i % 3] = if i % 2 == 0 { 1.0 } else { -1.0 };
                d
            } else if i % 2 == 0 {
                // Aimed at a random point of a random triangle.
                let t = &tris[(s.next_u32() as usize) % tris.len()];
                let (b1, b2) = (s.next_f32(), s.next_f32());
                let (b1, b2) = if b1 + b2 > 1.0 {
                    (1.0 - b1, 1.0 - b2)
                } else {
                    (b1, b2)
                };
                let to = t.point(b1, b2) - o;
                if to.length_squared() > 1e-8 {
                    to / crate::math::sqrt(to.length_squared())
                } else {
                    rand_dir(&mut s)
                }
            } else {
                rand_dir(&mut s)
            };
            let ray = Ray::new(o, d);
            let t_max = if i % 5 == 0 {
                0.1 + 3.0 * s.next_f32()
            } else {
                f32::INFINITY
            };
            let got = bvh.intersect(&ray, t_max);
            let want = brute(tris, &ray, t_max);
            match (got, want) {
                (None, None) => {}
                (Some(g), Some(w)) => {
                    hits += 1;
                    // The same hit to the bit: of hits at one distance, the lowest index.
                    assert_eq!(
                        (g.triangle, g.t.to_bits(), g.b1.to_bits(), g.b2.to_bits()),
                        (w.triangle, w.t.to_bits(), w.b1.to_bits(), w.b2.to_bits()),
                        "ray {i}"
                    );
                    assert!(g.t > 0.0 && g.t < t_max);
                    assert!(g.b1 >= 0.0 && g.b2 >= 0.0 && g.b1 + g.b2 <= 1.0);
                    let p = tris[g.triangle as usize].point(g.b1, g.b2);
                    let err = (p - ray.at(g.t)).length();
                    assert!(err < 1e-3, "ray {i}: hit point off by {err}");
                }
                (g, w) => panic!("ray {i}: bvh {g:?}, brute force {w:?}"),
            }
            assert_eq!(bvh.occluded(&ray, t_max), want.is_some(), "ray {i}");
        }
        assert!(hits > n_rays / 10, "too few hits ({hits}) to be a test");
    }

    #[test]
    fn random_soups_match_brute_force() {
        for (seed, n, size) in [(1, 1, 0.5), (2, 7, 0.3), (3, 300, 0.2), (4, 2000, 0.05)] {
            let tris = random_soup(seed, n, size);
            compare_with_brute(&tris, seed + 100, 4000, -1.5, 1.5);
        }
    }

    #[test]
    fn grid_box_scene_matches_brute_force() {
        let tris = grid_box_scene();
        // Rays from inside the box (all hit) and from around it.
        compare_with_brute(&tris, 7, 4000, 0.1, 3.9);
        compare_with_brute(&tris, 8, 2000, -2.0, 6.0);
    }

    /// Rays through the grid's shared vertices and edges hit two to six triangles at one
    /// distance: the closest hit is the one of lowest index, as brute force finds it,
    /// however the triangles are ordered (and so the tree built and walked).
    #[test]
    fn a_hit_shared_by_triangles_goes_to_the_lowest_index() {
        let mut tris = grid_box_scene();
        let mut s = Sampler::from_key(16);
        let mut ties = 0;
        for shuffle in 0..3 {
            if shuffle > 0 {
                for i in (1..tris.len()).rev() {
                    tris.swap(i, s.next_u32() as usize % (i + 1));
                }
            }
            let mut owned = Owned::new(tris.len());
            let bvh = owned.build(&tris);
            for t in tris.clone() {
                for at in [
                    t.v[0],
                    t.v[1],
                    (t.v[0] + t.v[1]) * 0.5,
                    (t.v[1] + t.v[2]) * 0.5,
                ] {
                    for from in [Vec3::splat(2.0), Vec3::new(1.5, 2.5, 1.0)] {
                        let d = (at - from).normalize();
                        let ray = Ray::new(from, d);
                        let (got, want) = (bvh.intersect(&ray, 100.0), brute(&tris, &ray, 100.0));
                        let key = |h: Option<Hit>| h.map(|h| (h.triangle, h.t.to_bits()));
                        assert_eq!(key(got), key(want));
                        let r = RayData::new(&ray);
                        let at_t = |h: &Hit| {
                            tris.iter()
                                .enumerate()
                                .filter(|(i, t)| {
                                    intersect_triangle(&pack(t, *i as u32), &r, h.t)
                                        .is_some_and(|(t, _, _)| t == h.t)
                                })
                                .count()
                        };
                        ties += got.is_some_and(|h| at_t(&h) > 1) as u32;
                    }
                }
            }
        }
        assert!(ties > 100, "only {ties} ties: not a test of them");
    }

    /// A floor at z = 0 (and one just above it) of quads in leaves of their own, seen
    /// from inside the room: rays aimed at the quads' shared vertices and edges meet two
    /// to six triangles at one distance, and the closest hit is the lowest index, as brute
    /// force finds it. Boxes padded by ulps of their own coordinates were as thin as
    /// `f32::MIN_POSITIVE` on the floor, thinner than the rounding of `t` over a ray's
    /// length: the box of the lower index was entered past the hit already found and
    /// skipped (3-6% of these rays, one in a thousand a closer hit by an ulp).
    #[test]
    fn ties_on_a_floor_at_zero_go_to_the_lowest_index() {
        let mut s = Sampler::from_key(17);
        let mut wrong = 0;
        for z in [0.0f32, 1e-3] {
            let mut tris = Vec::new();
            for i in 0..16 {
                for j in 0..16 {
                    let p = Vec3::new(i as f32 * 0.1, j as f32 * 0.1, z);
                    let (u, v) = (Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.0, 0.1, 0.0));
                    tris.push(tri(p, p + u, p + u + v));
                    tris.push(tri(p, p + u + v, p + v));
                }
            }
            // The room's ceiling, so that rays start inside the scene's bounds.
            tris.push(tri(
                Vec3::new(0.0, 0.0, 3.0),
                Vec3::new(0.0, 1.6, 3.0),
                Vec3::new(1.6, 0.0, 3.0),
            ));
            let mut owned = Owned::new(tris.len());
            let bvh = owned.build(&tris);
            for t in &tris[..512] {
                for at in [t.v[0], (t.v[0] + t.v[1]) * 0.5, (t.v[1] + t.v[2]) * 0.5] {
                    let from = Vec3::new(
                        1.6 * s.next_f32(),
                        1.6 * s.next_f32(),
                        z + 0.01 + 2.9 * s.next_f32(),
                    );
                    let ray = Ray::new(from, (at - from).normalize());
                    let key = |h: Option<Hit>| h.map(|h| (h.triangle, h.t.to_bits()));
                    let (got, want) = (bvh.intersect(&ray, 9.0), brute(&tris, &ray, 9.0));
                    wrong += (key(got) != key(want)) as u32;
                }
            }
        }
        assert_eq!(wrong, 0, "rays whose closest hit is not brute force's");
    }

    #[test]
    fn leaves_are_small() {
        let tris = random_soup(5, 1000, 0.05);
        let mut owned = Owned::new(tris.len());
        let bvh = owned.build(&tris);
        assert!(leaf_sizes(&bvh)
            .iter()
            .all(|&c| c as usize <= MAX_LEAF_TRIANGLES));
    }

    #[test]
    fn build_is_deterministic() {
        let tris = random_soup(6, 500, 0.1);
        let mut a = Owned::new(tris.len());
        let mut b = Owned::new(tris.len());
        let (ba, bb) = (a.build(&tris), b.build(&tris));
        assert_eq!(ba.nodes.len(), bb.nodes.len());
        for (x, y) in ba.nodes.iter().zip(bb.nodes) {
            assert_eq!(
                (x.min, x.max, x.child, x.count),
                (y.min, y.max, y.child, y.count)
            );
        }
        for (x, y) in ba.packed.iter().zip(bb.packed) {
            assert_eq!(x.index, y.index);
        }
    }

    #[test]
    fn identical_triangles_make_a_valid_tree() {
        let t = tri(
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        );
        let tris = vec![t; 100];
        let mut owned = Owned::new(tris.len());
        let bvh = owned.build(&tris);
        check_tree(&bvh, &tris);
        assert!(leaf_sizes(&bvh)
            .iter()
            .all(|&c| c as usize <= MAX_LEAF_TRIANGLES));
        let ray = Ray::new(Vec3::new(0.25, 0.25, 0.0), Vec3::Z);
        let h = bvh.intersect(&ray, f32::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!((h.b1 - 0.25).abs() < 1e-6 && (h.b2 - 0.25).abs() < 1e-6);
        assert!(bvh.occluded(&ray, 2.0));
        assert!(!bvh.occluded(&ray, 1.0));
        let miss = Ray::new(Vec3::new(0.75, 0.75, 0.0), Vec3::Z);
        assert!(bvh.intersect(&miss, f32::INFINITY).is_none());
        // Same centroids, different shapes: still a valid tree with small leaves.
        let mut s = Sampler::from_key(9);
        let tris: Vec<Triangle> = (0..200)
            .map(|_| {
                let a = rand_vec(&mut s, -1.0, 1.0);
                let b = rand_vec(&mut s, -1.0, 1.0);
                tri(a, b, -a - b)
            })
            .collect();
        compare_with_brute(&tris, 10, 2000, -1.5, 1.5);
    }

    #[test]
    fn both_faces_are_hit_and_t_range_is_open() {
        let tris = [tri(
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        )];
        let mut owned = Owned::new(1);
        let bvh = owned.build(&tris);
        let down = Ray::new(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z);
        let up = Ray::new(Vec3::new(0.0, 0.0, -2.0), Vec3::Z);
        assert!((bvh.intersect(&down, f32::INFINITY).unwrap().t - 2.0).abs() < 1e-6);
        assert!((bvh.intersect(&up, f32::INFINITY).unwrap().t - 2.0).abs() < 1e-6);
        assert!(bvh.intersect(&down, 2.0).is_none());
        assert!(!bvh.occluded(&down, 2.0));
        assert!(bvh.occluded(&down, 2.001));
        // Behind the origin, and starting on the triangle (t = 0): no hit.
        assert!(bvh
            .intersect(&Ray::new(Vec3::new(0.0, 0.0, 2.0), Vec3::Z), 9.0)
            .is_none());
        assert!(bvh.intersect(&Ray::new(Vec3::ZERO, Vec3::Z), 9.0).is_none());
    }

    #[test]
    fn zero_triangles() {
        let mut owned = Owned::new(0);
        let bvh = owned.build(&[]);
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        assert!(bvh.intersect(&ray, f32::INFINITY).is_none());
        assert!(!bvh.occluded(&ray, f32::INFINITY));
        // Even with empty buffers.
        let bvh = Bvh::build(
            &[],
            BvhBuffers {
                nodes: &mut [],
                packed: &mut [],
            },
        )
        .unwrap();
        assert!(bvh.intersect(&ray, f32::INFINITY).is_none());
    }

    #[test]
    fn errors() {
        let tris = random_soup(11, 10, 0.1);
        let mut nodes = vec![BvhNode::default(); 9];
        let mut packed = vec![PackedTriangle::default(); 10];
        let r = Bvh::build(
            &tris,
            BvhBuffers {
                nodes: &mut nodes,
                packed: &mut packed,
            },
        );
        assert_eq!(
            r.err(),
            Some(Error::BufferTooSmall {
                what: "bvh nodes",
                needed: 10,
                got: 9
            })
        );
        let mut nodes = vec![BvhNode::default(); 20];
        let mut packed = vec![PackedTriangle::default(); 9];
        let r = Bvh::build(
            &tris,
            BvhBuffers {
                nodes: &mut nodes,
                packed: &mut packed,
            },
        );
        assert_eq!(
            r.err(),
            Some(Error::BufferTooSmall {
                what: "bvh packed",
                needed: 10,
                got: 9
            })
        );
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let mut tris = tris.clone();
            tris[4].v[2].y = bad;
            let mut packed = vec![PackedTriangle::default(); 10];
            let r = Bvh::build(
                &tris,
                BvhBuffers {
                    nodes: &mut nodes,
                    packed: &mut packed,
                },
            );
            assert_eq!(
                r.err(),
                Some(Error::InvalidValue {
                    what: "triangle vertex is not finite"
                })
            );
        }
        // Capacity is checked before anything is touched (no buffers needed).
        let one = tris[0];
        let many = vec![one; MAX_TRIANGLES + 1];
        let r = Bvh::build(
            &many,
            BvhBuffers {
                nodes: &mut [],
                packed: &mut [],
            },
        );
        assert_eq!(
            r.err(),
            Some(Error::Capacity {
                what: "config::MAX_TRIANGLES",
                max: MAX_TRIANGLES,
                needed: MAX_TRIANGLES + 1
            })
        );
    }

    #[test]
    fn built_buffers_whose_children_point_back_are_refused() {
        let tris = random_soup(11, 40, 0.1);
        let mut nodes = vec![BvhNode::default(); tris.len()];
        let mut packed = vec![PackedTriangle::default(); tris.len()];
        let used = Bvh::build(
            &tris,
            BvhBuffers {
                nodes: &mut nodes,
                packed: &mut packed,
            },
        )
        .unwrap()
        .node_count();
        let slot = (0..WIDTH).find(|&s| nodes[1].count[s] == 0).unwrap();
        let child = nodes[1].child[slot];
        assert!(used > 2 && nodes[0].count == [0; WIDTH] && child > 1);
        assert!(Bvh::from_built(&tris, &nodes, &packed, used).is_ok());
        let refused = Some(Error::InvalidValue {
            what: "built bvh: the nodes are not a tree in the order Bvh::build lays one out",
        });
        // A node child that is its parent, before it, or past the end once made traversal
        // loop for ever or stop short; one named twice is walked twice.
        for bad_child in [0, 1, used as u32, child + 1] {
            let mut bad = nodes.clone();
            bad[1].child[slot] = bad_child;
            let got = Bvh::from_built(&tris, &bad, &packed, used).err();
            assert_eq!(got, refused, "child {bad_child}");
        }
    }

    #[test]
    fn built_buffers_whose_nodes_share_children_are_refused() {
        // Forty nodes, each with four children that are all the next node: every child
        // after its parent, yet a walk would visit the last node 4^39 times (fuzzing the
        // core's API, 2026-12-06: from_built took it and a ray never came back).
        let tris = random_soup(12, 8, 0.1);
        let mut nodes = vec![BvhNode::default(); 40];
        for (i, node) in nodes.iter_mut().enumerate().take(39) {
            node.min = [[-1.0; WIDTH]; 3];
            node.max = [[1.0; WIDTH]; 3];
            node.child = [i as u32 + 1; WIDTH];
        }
        nodes[39].min = [[-1.0; WIDTH]; 3];
        nodes[39].max = [[1.0; WIDTH]; 3];
        nodes[39].child = [0; WIDTH];
        nodes[39].count = [2; WIDTH];
        let packed = vec![PackedTriangle::default(); tris.len()];
        assert_eq!(
            Bvh::from_built(&tris, &nodes, &packed, 40).err(),
            Some(Error::InvalidValue {
                what: "built bvh: the nodes are not a tree in the order Bvh::build lays one out",
            })
        );
        // A path of single children is a tree in the build's order: taken as deep as the
        // build makes nodes, refused deeper.
        for node in &mut nodes[..39] {
            node.child = [node.child[0], EMPTY_SLOT, EMPTY_SLOT, EMPTY_SLOT];
        }
        let mut path = nodes[40 - MAX_BVH_DEPTH..].to_vec();
        for (i, node) in path.iter_mut().enumerate().take(MAX_BVH_DEPTH - 1) {
            node.child[0] = i as u32 + 1;
        }
        assert!(Bvh::from_built(&tris, &path, &packed, MAX_BVH_DEPTH).is_ok());
        assert!(Bvh::from_built(&tris, &nodes, &packed, 40).is_err());
    }

    #[test]
    fn degenerate_and_extreme_input_never_panics() {
        let mut s = Sampler::from_key(12);
        let mut tris = random_soup(13, 50, 0.2);
        // Zero-area triangles: points and segments.
        let p = Vec3::new(0.1, 0.2, 0.3);
        tris.push(tri(p, p, p));
        tris.push(tri(p, p + Vec3::X, p + 2.0 * Vec3::X));
        // Huge coordinates (edges overflow to infinity) and tiny ones.
        tris.push(tri(
            Vec3::splat(-3e38),
            Vec3::splat(3e38),
            Vec3::new(3e38, -3e38, 0.0),
        ));
        tris.push(tri(
            Vec3::splat(1e-40),
            Vec3::splat(2e-40),
            Vec3::new(1e-40, 3e-40, 0.0),
        ));
        let mut owned = Owned::new(tris.len());
        let bvh = owned.build(&tris);
        for i in 0..2000 {
            let o = rand_vec(&mut s, -2.0, 2.0);
            let d = rand_dir(&mut s);
            let ray = match i % 4 {
                0 => Ray::new(o, Vec3::ZERO),
                1 => Ray::new(Vec3::splat(f32::NAN), d),
                2 => Ray::new(o, d * 1e30),
                _ => Ray::new(o, d),
            };
            let _ = bvh.intersect(&ray, f32::INFINITY);
            let _ = bvh.occluded(&ray, f32::NAN);
            let _ = bvh.intersect(&ray, -1.0);
        }
    }

    #[test]
    fn depth_limit_makes_big_leaves_that_still_work() {
        let tris = random_soup(14, 500, 0.1);
        for max_depth in [1, 2, 3] {
            let mut owned = Owned::new(tris.len());
            let bvh = Bvh::build_with_depth(
                &tris,
                BvhBuffers {
                    nodes: &mut owned.nodes,
                    packed: &mut owned.packed,
                },
                max_depth,
            )
            .unwrap();
            check_tree(&bvh, &tris);
            let sizes = leaf_sizes(&bvh);
            assert!(sizes.len() <= WIDTH.pow(max_depth as u32));
            assert!(depth_of(&bvh) < max_depth);
            assert!(sizes.iter().any(|&c| c as usize > MAX_LEAF_TRIANGLES));
            let mut s = Sampler::from_key(15);
            for i in 0..2000 {
                let ray = Ray::new(rand_vec(&mut s, -1.5, 1.5), rand_dir(&mut s));
                let got = bvh.intersect(&ray, f32::INFINITY);
                let want = brute(&tris, &ray, f32::INFINITY);
                assert_eq!(got.map(|h| h.t), want.map(|h| h.t), "ray {i}");
                assert_eq!(bvh.occluded(&ray, f32::INFINITY), want.is_some());
            }
        }
    }

    // -----------------------------------------------------------------------------------
    // Benchmark on the living-room ray sets (ignored: needs /work/shared and --release).

    fn read_obj(path: &str) -> Vec<Triangle> {
        let text = std::fs::read_to_string(path).unwrap();
        let mut v: Vec<Vec3> = Vec::new();
        let mut out = Vec::new();
        for line in text.lines() {
            let mut it = line.split_whitespace();
            match it.next() {
                Some("v") => {
                    let c: Vec<f32> = it.take(3).map(|x| x.parse().unwrap()).collect();
                    v.push(Vec3::new(c[0], c[1], c[2]));
                }
                Some("f") => {
                    let idx: Vec<usize> = it
                        .map(|s| {
                            let i: i64 = s.split('/').next().unwrap().parse().unwrap();
                            if i < 0 {
                                (v.len() as i64 + i) as usize
                            } else {
                                i as usize - 1
                            }
                        })
                        .collect();
                    for k in 2..idx.len() {
                        out.push(tri(v[idx[0]], v[idx[k - 1]], v[idx[k]]));
                    }
                }
                _ => {}
            }
        }
        out
    }

    fn read_u64(b: &[u8]) -> usize {
        u64::from_le_bytes(b[..8].try_into().unwrap()) as usize
    }

    fn f32_at(b: &[u8], i: usize) -> f32 {
        f32::from_le_bytes(b[i..i + 4].try_into().unwrap())
    }

    fn read_rays(path: &str) -> Vec<Ray> {
        let b = std::fs::read(path).unwrap();
        let n = read_u64(&b);
        (0..n)
            .map(|i| {
                let o = 8 + i * 24;
                let f = |k: usize| f32_at(&b, o + 4 * k);
                Ray::new(Vec3::new(f(0), f(1), f(2)), Vec3::new(f(3), f(4), f(5)))
            })
            .collect()
    }

    fn read_hits(path: &str) -> Vec<(f32, i32)> {
        let b = std::fs::read(path).unwrap();
        let n = read_u64(&b);
        (0..n)
            .map(|i| {
                let o = 8 + i * 8;
                (
                    f32_at(&b, o),
                    i32::from_le_bytes(b[o + 4..o + 8].try_into().unwrap()),
                )
            })
            .collect()
    }

    #[test]
    #[ignore = "benchmark: needs /work/shared/bench, run with --release --ignored --nocapture"]
    fn bench_living_room() {
        let root = "/work/shared/bench";
        let tris = read_obj(&std::format!("{root}/living-room/geometry.obj"));
        assert_eq!(tris.len(), 2374);
        let mut owned = Owned::new(tris.len());
        let t0 = std::time::Instant::now();
        let bvh = owned.build(&tris);
        let build_s = t0.elapsed().as_secs_f64();
        check_tree(&bvh, &tris);
        std::println!(
            "build: {:.2} ms, {} nodes, {} leaves, {} nodes deep",
            build_s * 1e3,
            bvh.nodes.len(),
            leaf_sizes(&bvh).len(),
            depth_of(&bvh) + 1
        );
        for set in ["primary", "incoherent"] {
            let rays = read_rays(&std::format!("{root}/rays/living-room/{set}.rays"));
            let want = read_hits(&std::format!("{root}/rays/living-room/{set}.hits"));
            assert_eq!(rays.len(), want.len());
            let mut got = vec![None; rays.len()];
            let mut best = f64::INFINITY;
            for _ in 0..7 {
                let t0 = std::time::Instant::now();
                for (g, r) in got.iter_mut().zip(&rays) {
                    *g = bvh.intersect(r, f32::INFINITY);
                }
                best = best.min(t0.elapsed().as_secs_f64());
            }
            let mut best_occ = f64::INFINITY;
            let mut n_occ = 0;
            for _ in 0..3 {
                let t0 = std::time::Instant::now();
                n_occ = rays
                    .iter()
                    .filter(|r| bvh.occluded(r, f32::INFINITY))
                    .count();
                best_occ = best_occ.min(t0.elapsed().as_secs_f64());
            }
            let agree = got
                .iter()
                .zip(&want)
                .filter(|(g, &(wt, wi))| match g {
                    None => wi < 0,
                    Some(h) => {
                        h.triangle as i32 == wi || (wi >= 0 && (h.t - wt).abs() <= 1e-4 * wt.abs())
                    }
                })
                .count();
            let n_hit = got.iter().filter(|g| g.is_some()).count();
            let pct = 100.0 * agree as f64 / rays.len() as f64;
            std::println!(
                "{set}: {:.2} Mrays/s closest, {:.2} Mrays/s occluded, agreement {pct:.4}% \
                 ({} of {} disagree), hits {n_hit}, occluded {n_occ}",
                rays.len() as f64 / best / 1e6,
                rays.len() as f64 / best_occ / 1e6,
                rays.len() - agree,
                rays.len()
            );
            assert!(pct >= 99.99);
        }
    }
}
