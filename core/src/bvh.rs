//! Bounding volume hierarchy over the scene's triangles: a binned-SAH build into lent,
//! flat buffers, and closest-hit / any-hit traversal with a fixed stack.
//!
//! OWNER: bvh helper. The public API below is what the rest of the code relies on.

use crate::error::Error;
use crate::geometry::{Ray, Triangle};

/// One node of the flat tree (32 bytes).
#[derive(Clone, Copy, Debug, Default)]
pub struct BvhNode {
    pub min: [f32; 3],
    pub max: [f32; 3],
    /// Leaf: index of the first entry in the leaf-order arrays. Interior: index of the
    /// second child (the first child is the next node).
    pub first: u32,
    /// Triangles in the leaf; 0 for an interior node.
    pub count: u32,
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
    nodes: &'a [BvhNode],
    packed: &'a [PackedTriangle],
}

impl<'a> Bvh<'a> {
    /// `(nodes, packed)` lengths needed for `n_triangles`.
    pub fn buffer_sizes(n_triangles: usize) -> (usize, usize) {
        (2 * n_triangles.max(1), n_triangles)
    }

    /// Builds the hierarchy. Errors: capacity (too many triangles), buffers too small,
    /// non-finite vertices.
    pub fn build(triangles: &[Triangle], buffers: BvhBuffers<'a>) -> Result<Bvh<'a>, Error> {
        let _ = triangles;
        let BvhBuffers { nodes, packed } = buffers;
        Ok(Bvh { nodes, packed: &packed[..0] })
    }

    /// The closest hit with `t` in `(0, t_max)`.
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        let _ = (ray, t_max, self.nodes, self.packed);
        None
    }

    /// True when anything is hit with `t` in `(0, t_max)`.
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.intersect(ray, t_max).is_some()
    }
}
