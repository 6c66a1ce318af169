//! Triangles given twice. Two groups that share a triangle (the same three corners, a wall
//! exported with two materials) leave it to the closest hit's tie rule (the lower triangle
//! index, an accident of the OBJ's order) which one a view sees there, and which one a
//! path bounces off; a group with copies of its own triangles renders the
//! same but costs a test per copy for every ray that reaches them (a million copies of one
//! quad took 18 s at 4 samples per pixel, against 0.02 s). Lights given twice are refused
//! when the scene is assembled, since both copies emit.

use std::collections::HashMap;
use std::hash::{DefaultHasher, Hash, Hasher};

use relume_core::geometry::{Surface, Triangle};

use crate::text::counted;

/// A triangle's corners in a fixed order, as bits: surfaces reflect on both sides, so the
/// same corners in any order are the same surface.
pub(crate) fn corners_key(t: &Triangle) -> [[u32; 3]; 3] {
    let mut key = t.v.map(|p| p.to_array().map(f32::to_bits));
    key.sort_unstable();
    key
}

/// Warnings for the groups' triangles given twice: once per pair of groups that share
/// some, and once per group with copies of its own.
pub fn repeated_triangle_warnings(triangles: &[Triangle], group_names: &[String]) -> Vec<String> {
    // By a 64-bit hash of the key, the first triangle seen with it (16 bytes a triangle,
    // 64 MB at the core's 4M); a match is confirmed on the key itself, and two keys of
    // one hash, which 4M triangles make with odds of about 1 in 2 million, are taken as distinct.
    let mut first_with: HashMap<u64, usize> = HashMap::with_capacity(triangles.len());
    let mut shared: HashMap<(u16, u16), usize> = HashMap::new();
    let mut copies = vec![0usize; group_names.len()];
    for (i, t) in triangles.iter().enumerate() {
        let Surface::Group(g) = t.surface else {
            continue;
        };
        let key = corners_key(t);
        // A corner given twice (`f 29 29 30`) makes no surface at all: no ray hits it, and
        // copies of it are no copies of a face.
        if key[0] == key[1] || key[1] == key[2] {
            continue;
        }
        let mut hasher = DefaultHasher::new();
        key.hash(&mut hasher);
        let first = *first_with.entry(hasher.finish()).or_insert(i);
        if first == i || corners_key(&triangles[first]) != key {
            continue;
        }
        match triangles[first].surface {
            Surface::Group(h) if h == g => {
                if let Some(n) = copies.get_mut(g as usize) {
                    *n += 1;
                }
            }
            Surface::Group(h) => *shared.entry((h.min(g), h.max(g))).or_default() += 1,
            Surface::Light(_) => {}
        }
    }
    let name = |g: u16| group_names.get(g as usize).map_or("?", String::as_str);
    let mut pairs: Vec<_> = shared.into_iter().collect();
    pairs.sort_unstable();
    let mut warnings: Vec<String> = pairs
        .into_iter()
        .map(|((a, b), n)| {
            format!(
                "groups '{}' and '{}' share {} (the same corners): which of the two a view sees there, and which one light bounces off, is left to chance; give each surface to one group",
                name(a),
                name(b),
                counted(n as u64, "triangle")
            )
        })
        .collect();
    for (g, &n) in copies.iter().enumerate().filter(|(_, &n)| n > 0) {
        warnings.push(format!(
            "group '{}' has {} given again (the same corners): they render as one, but every ray that reaches them tests each copy; give each face once",
            name(g as u16),
            counted(n as u64, "triangle")
        ));
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;
    use relume_core::math::{Vec2, Vec3};

    fn triangle(v: [[f32; 3]; 3], surface: Surface) -> Triangle {
        Triangle {
            v: v.map(Vec3::from),
            uv: [Vec2::ZERO; 3],
            surface,
        }
    }

    #[test]
    fn shared_and_copied_triangles_are_told_once_per_pair_and_group() {
        let a = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let b = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
        let turned = [a[2], a[1], a[0]];
        let names = ["wall".to_string(), "paint".to_string(), "floor".to_string()];
        let triangles = [
            triangle(a, Surface::Group(0)),
            triangle(turned, Surface::Group(1)),
            triangle(b, Surface::Group(2)),
            triangle(b, Surface::Group(2)),
            triangle(b, Surface::Group(2)),
            triangle(a, Surface::Light(0)),
        ];
        let warnings = repeated_triangle_warnings(&triangles, &names);
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(
            warnings[0]
                .starts_with("groups 'wall' and 'paint' share 1 triangle (the same corners)"),
            "{}",
            warnings[0]
        );
        assert!(
            warnings[1].starts_with("group 'floor' has 2 triangles given again"),
            "{}",
            warnings[1]
        );
        // Distinct triangles say nothing.
        let apart = [
            triangle(a, Surface::Group(0)),
            triangle(b, Surface::Group(1)),
        ];
        assert!(repeated_triangle_warnings(&apart, &names).is_empty());
        // Faces of a corner given twice are no surface, however often given.
        let point = [a[0], a[0], a[1]];
        let degenerate = [
            triangle(point, Surface::Group(0)),
            triangle(point, Surface::Group(0)),
            triangle([a[1], a[0], a[0]], Surface::Group(1)),
        ];
        assert!(repeated_triangle_warnings(&degenerate, &names).is_empty());
    }
}
