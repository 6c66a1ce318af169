//! Every capacity of the core, named once. A scene that exceeds one of these is
//! rejected with [`crate::Error::Capacity`], which names the constant.

/// Triangles in one scene (after fan triangulation).
pub const MAX_TRIANGLES: usize = 1 << 22;
/// Depth of the BVH in nodes, leaves below: a traversal's stack holds at most 3 children
/// a level (64 entries), and four children a node give 4^21 leaves, where 4 million
/// triangles need some 4^10 (the living room is 9 nodes deep, subdivided to 607,744
/// triangles 15). Deeper ranges become large leaves.
pub const MAX_BVH_DEPTH: usize = 21;
/// Triangles per BVH leaf at most.
pub const MAX_LEAF_TRIANGLES: usize = 4;
/// Material groups in one scene.
pub const MAX_GROUPS: usize = 1024;
/// Light sources (each a set of emitting triangles) in one scene.
pub const MAX_LIGHTS: usize = 256;
/// Views in one panorama (the host refuses more; the core keeps nothing per view, but a
/// caller on a small target sizes its buffers by it).
pub const MAX_VIEWS: usize = 64;
/// Pixels per side of one view.
pub const MAX_VIEW_SIDE: u32 = 16384;
/// Textures in one scene.
pub const MAX_TEXTURES: usize = 1024;
/// Texels of all textures together.
pub const MAX_TEXELS: usize = 1 << 26;
/// Planar mirror groups whose light the renderer samples through the light's image in
/// the mirror (next-event estimation by way of a mirror); light by way of any further
/// mirror is found by BSDF sampling alone, as by way of a curved one.
pub const MAX_MIRROR_PLANES: usize = 8;
/// Path vertices a path tracer follows at most (Russian roulette ends most paths far sooner).
pub const MAX_PATH_DEPTH: u32 = 64;
