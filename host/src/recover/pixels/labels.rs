//! What each pixel of a view sees: its footprint's rays traced to label it pure (whole on
//! one group), on a light or mixed; a group's border pixels and texture coordinates.

use std::collections::HashSet;

use relume_core::bvh::Hit;
use relume_core::geometry::{Surface, Triangle, View};
use relume_core::render;
use relume_core::scene::Scene;
use relume_core::stages::texture_map::{FOOTPRINT_OFFSETS, FOOTPRINT_SAMPLES};

use crate::compare::LABEL_RAYS_PER_SIDE;
use crate::parallel;

use super::PurePixel;

/// A pixel whose whole footprint, and the footprints of its four neighbours, see the
/// emitting side of one light: its value is the light's radiance, untouched by the blur of
/// a camera or a filter at the light's edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LightPixel {
    pub view: u32,
    pub x: u32,
    pub y: u32,
    pub light: u16,
}

/// What the label pass over every view finds.
pub struct Labels {
    /// Every pure pixel of every view, in view and row order.
    pub pure: Vec<PurePixel>,
    /// Every light pixel (interior to a light), in view and row order.
    pub lights: Vec<LightPixel>,
    /// Pixels wholly on a light's emitting side but beside its edge (a neighbour is not):
    /// not read, since blur at the edge may reach them, but told of where no pixel is
    /// interior ([`super::super::calibration::unchecked_warning`]).
    pub light_edges: Vec<LightPixel>,
    /// Every pixel interior to a light's back (black as declared), in view and row order.
    pub light_backs: Vec<LightPixel>,
    /// The views with no pure pixel.
    pub empty_views: Vec<usize>,
}

/// Labels every pixel of every view by what its whole footprint sees.
pub fn label_views(pool: &rayon::ThreadPool, scene: &Scene, views: &[View]) -> Labels {
    let mut found = Labels {
        pure: Vec::new(),
        lights: Vec::new(),
        light_edges: Vec::new(),
        light_backs: Vec::new(),
        empty_views: Vec::new(),
    };
    for (vi, view) in views.iter().enumerate() {
        let labels = parallel::map_pixels(pool, view, |x, y| {
            render::pixel_surface(scene, view, x, y, LABEL_RAYS_PER_SIDE)
        });
        let (w, h) = (view.width, view.height);
        let label = |x: u32, y: u32| labels[(y * w + x) as usize];
        // Whether the four neighbours of (x, y) are in the view and all see `surface`.
        let neighbours_see = |x: u32, y: u32, surface: Surface| {
            x > 0
                && y > 0
                && x + 1 < w
                && y + 1 < h
                && [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)]
                    .iter()
                    .all(|&(nx, ny)| label(nx, ny) == Some(surface))
        };
        // Light backs among the pixels of no surface (few: silhouettes, the sky), held to
        // the same interior as light pixels.
        let backs = parallel::map_pixels(pool, view, |x, y| match label(x, y) {
            None => render::pixel_light_back(scene, view, x, y, LABEL_RAYS_PER_SIDE),
            Some(_) => None,
        });
        let back = |x: u32, y: u32| backs[(y * w + x) as usize];
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                if let Some(light) = back(x, y) {
                    let around = [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)];
                    if around.iter().all(|&(nx, ny)| back(nx, ny) == Some(light)) {
                        found.light_backs.push(LightPixel {
                            view: vi as u32,
                            x,
                            y,
                            light,
                        });
                    }
                }
            }
        }
        let before = found.pure.len();
        for y in 0..h {
            for x in 0..w {
                match label(x, y) {
                    Some(Surface::Group(group)) => found.pure.push(PurePixel {
                        view: vi as u32,
                        x,
                        y,
                        group,
                    }),
                    Some(Surface::Light(light)) => {
                        let pixel = LightPixel {
                            view: vi as u32,
                            x,
                            y,
                            light,
                        };
                        match neighbours_see(x, y, Surface::Light(light)) {
                            true => found.lights.push(pixel),
                            false => found.light_edges.push(pixel),
                        }
                    }
                    _ => {}
                }
            }
        }
        if found.pure.len() == before {
            found.empty_views.push(vi);
        }
    }
    found
}

/// What a view's pixels see, each pixel counted once by the rays that label it: told to a
/// user whose views hold no pure pixel, so the cause (views outside the geometry, an OBJ
/// in other units, groups hidden, views too coarse) can be told from the counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sight {
    /// Pixels whose every ray escapes the scene.
    pub nothing: u32,
    /// Pixels whose rays meet lights (or escape) and no group.
    pub lights_only: u32,
    /// Pixels with a group in part of their footprint.
    pub groups_in_part: u32,
}

impl Sight {
    /// "8x8 pixels: 64 see nothing, 0 only lights, 0 a group in part".
    pub fn describe(&self, view: &View) -> String {
        format!(
            "{}x{} pixels: {} see nothing, {} only lights, {} a group in part",
            view.width, view.height, self.nothing, self.lights_only, self.groups_in_part
        )
    }
}

/// Counts what the pixels of `view` see (see [`Sight`]).
pub fn sight(pool: &rayon::ThreadPool, scene: &Scene, view: &View) -> Sight {
    let seen = parallel::map_pixels(pool, view, |x, y| {
        let (mut light, mut group) = (false, false);
        for surface in label_ray_surfaces(scene, view, x, y) {
            match surface {
                Some(Surface::Group(_)) => group = true,
                Some(Surface::Light(_)) => light = true,
                None => {}
            }
        }
        (light, group)
    });
    let mut sight = Sight::default();
    for (light, group) in seen {
        match (light, group) {
            (_, true) => sight.groups_in_part += 1,
            (true, false) => sight.lights_only += 1,
            (false, false) => sight.nothing += 1,
        }
    }
    sight
}

/// Per group for which `wanted` is true, the pixels of every view whose footprint sees it
/// in part, in at least `min_share` of the [`LABEL_RAYS_PER_SIDE`]^2 rays that label a
/// pixel (a grid over the pixel's square, edges included, as `render::pixel_surface`'s),
/// and sees in the others only groups that `known` accepts: no light, no void, no group
/// whose material is not known. Each with the group's share of the rays. In view and row
/// order.
pub fn mixed_pixels(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    views: &[View],
    n_groups: usize,
    min_share: f64,
    wanted: impl Fn(u16) -> bool + Sync,
    known: impl Fn(u16) -> bool + Sync,
) -> Vec<Vec<(PurePixel, f64)>> {
    let mut found = vec![Vec::new(); n_groups];
    for (vi, view) in views.iter().enumerate() {
        let shares = parallel::map_pixels(pool, view, |x, y| {
            let mut on: Option<(u16, u32)> = None;
            let mut rays = 0;
            for surface in label_ray_surfaces(scene, view, x, y) {
                rays += 1;
                match surface {
                    Some(Surface::Group(h)) if wanted(h) => match on {
                        None => on = Some((h, 1)),
                        Some((g, count)) if g == h => on = Some((g, count + 1)),
                        // Two groups of unknown material: neither can be told apart.
                        Some(_) => return None,
                    },
                    Some(Surface::Group(h)) if known(h) => {}
                    _ => return None,
                }
            }
            let (g, count) = on?;
            let share = count as f64 / rays as f64;
            // A pixel it covers whole is a pure pixel, left out of the recovery's on
            // purpose where there are any (`--limit-group-pixels`).
            (share >= min_share && count < rays).then_some((g, share))
        });
        for (i, share) in shares.into_iter().enumerate() {
            if let Some((g, share)) = share {
                let pixel = PurePixel {
                    view: vi as u32,
                    x: i as u32 % view.width,
                    y: i as u32 / view.width,
                    group: g,
                };
                found[g as usize].push((pixel, share));
            }
        }
    }
    found
}

/// The texture coordinates where the rays through pixel `p` at its footprint samples
/// (`texture_map::FOOTPRINT_OFFSETS`) hit.
pub fn pixel_uvs(
    scene: &Scene,
    views: &[View],
    p: &PurePixel,
) -> Option<[glam::Vec2; FOOTPRINT_SAMPLES]> {
    let mut uvs = [glam::Vec2::ZERO; FOOTPRINT_SAMPLES];
    for (uv, [dx, dy]) in uvs.iter_mut().zip(FOOTPRINT_OFFSETS) {
        let (hit, triangle) = first_hit(
            scene,
            &views[p.view as usize],
            p.x as f32 + dx,
            p.y as f32 + dy,
        )?;
        *uv = triangle.uv_at(hit.b1, hit.b2);
    }
    Some(uvs)
}

/// What each of the [`LABEL_RAYS_PER_SIDE`]^2 rays that label pixel `(x, y)` of `view`
/// meets first: the grid over the pixel's square, edges included, of
/// `render::pixel_surface`.
fn label_ray_surfaces<'s>(
    scene: &'s Scene,
    view: &'s View,
    x: u32,
    y: u32,
) -> impl Iterator<Item = Option<Surface>> + 's {
    let n = LABEL_RAYS_PER_SIDE.max(2);
    let sub = move |k: u32| k as f32 / (n - 1) as f32;
    (0..n * n).map(move |k| {
        first_hit(scene, view, x as f32 + sub(k % n), y as f32 + sub(k / n)).map(|(_, t)| t.surface)
    })
}

/// What the ray through the point `(x, y)` of `view` (in pixels) meets first.
fn first_hit<'s>(scene: &'s Scene, view: &View, x: f32, y: f32) -> Option<(Hit, &'s Triangle)> {
    let hit = scene.intersect(&view.ray(x, y), f32::INFINITY)?;
    Some((hit, scene.triangles.get(hit.triangle as usize)?))
}

/// The pixels around `pure` (group `g`'s pure pixels) that see the group over part of
/// their footprint, each with the texture coordinates of its footprint samples: a sample
/// that misses the group takes the coordinates of one that hits it, so that the mean over
/// the samples is the mean over those on the group. Pixels with fewer than `min_on` of
/// the [`FOOTPRINT_SAMPLES`] on the group are left out, and so are those where any of
/// the [`LABEL_RAYS_PER_SIDE`]^2 rays that labelled the pixel meets neither the group nor
/// a group that `known` accepts: the rest of such a pixel is rendered under the materials
/// recovery has, and a light, the void or a group it could not recover (no pure pixel)
/// would put a radiance it does not know into the map. A pixel whose rays all meet the
/// group is not a border pixel. In the order of `pure`'s neighbours, each pixel once.
pub fn border_pixels(
    scene: &Scene,
    views: &[View],
    pure: &[PurePixel],
    g: u16,
    min_on: usize,
    known: impl Fn(u16) -> bool,
) -> Vec<(PurePixel, [glam::Vec2; FOOTPRINT_SAMPLES])> {
    let of_group: HashSet<(u32, u32, u32)> = pure.iter().map(|p| (p.view, p.x, p.y)).collect();
    let mut tried = HashSet::new();
    let mut found = Vec::new();
    for p in pure {
        let view = &views[p.view as usize];
        let neighbours = (-1i64..=1).flat_map(|dy| (-1i64..=1).map(move |dx| (dx, dy)));
        for (dx, dy) in neighbours {
            let (x, y) = (i64::from(p.x) + dx, i64::from(p.y) + dy);
            if x < 0 || y < 0 || x >= i64::from(view.width) || y >= i64::from(view.height) {
                continue;
            }
            let (x, y) = (x as u32, y as u32);
            if of_group.contains(&(p.view, x, y)) || !tried.insert((p.view, x, y)) {
                continue;
            }
            // The rays that decided that the pixel is not pure.
            let surfaces: Vec<Option<Surface>> = label_ray_surfaces(scene, view, x, y).collect();
            let all_known = surfaces
                .iter()
                .all(|s| matches!(s, Some(Surface::Group(h)) if *h == g || known(*h)));
            // A pixel all on the group is one `pure` left out on purpose (a subset, as
            // the stability study's cut groups are), not a border.
            let on_border = surfaces.iter().any(|s| *s != Some(Surface::Group(g)));
            if !(all_known && on_border) {
                continue;
            }
            let mut uvs = [None; FOOTPRINT_SAMPLES];
            for (uv, [ox, oy]) in uvs.iter_mut().zip(FOOTPRINT_OFFSETS) {
                let on = first_hit(scene, view, x as f32 + ox, y as f32 + oy)
                    .filter(|(_, t)| t.surface == Surface::Group(g));
                *uv = on.map(|(hit, t)| t.uv_at(hit.b1, hit.b2));
            }
            let on: Vec<glam::Vec2> = uvs.iter().flatten().copied().collect();
            if on.len() < min_on.max(1) {
                continue;
            }
            let border = PurePixel {
                view: p.view,
                x,
                y,
                group: g,
            };
            let uvs = std::array::from_fn(|k| uvs[k].unwrap_or(on[k % on.len()]));
            found.push((border, uvs));
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On the bundled cornell box, with the floor taken as unseen: every pixel found sees
    /// it over the share given (counted again here ray by ray) and only known groups
    /// beside it, none is one of its pure pixels, and a lower share finds more.
    #[test]
    fn mixed_pixels_see_the_group_over_their_share_and_known_groups_beside() {
        use crate::assemble::{load_and_assemble, MaterialSource};
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.toml");
        let mut owned = load_and_assemble(&path, MaterialSource::GeometryOnly).unwrap();
        let views = owned.views.clone();
        let n_groups = owned.group_names.len();
        let scene = owned.build().unwrap();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let pure = label_views(&pool, &scene, &views).pure;
        let unseen = 0u16;
        let find = |min_share: f64| {
            mixed_pixels(
                &pool,
                &scene,
                &views,
                n_groups,
                min_share,
                |h| h == unseen,
                |h| h != unseen,
            )
        };
        let half = find(0.5);
        let any = find(0.01);
        assert!(half
            .iter()
            .enumerate()
            .all(|(g, found)| g == 0 || found.is_empty()));
        assert!(
            !half[0].is_empty() && any[0].len() > half[0].len(),
            "{} {}",
            half[0].len(),
            any[0].len()
        );
        let n = LABEL_RAYS_PER_SIDE;
        for &(p, share) in &any[0] {
            let is_pure = pure
                .iter()
                .any(|q| (q.view, q.x, q.y) == (p.view, p.x, p.y));
            let view = &views[p.view as usize];
            let mut on = 0;
            for k in 0..n * n {
                let (fx, fy) = (
                    (k % n) as f32 / (n - 1) as f32,
                    (k / n) as f32 / (n - 1) as f32,
                );
                match first_hit(&scene, view, p.x as f32 + fx, p.y as f32 + fy)
                    .map(|(_, t)| t.surface)
                {
                    Some(Surface::Group(h)) if h == unseen => on += 1,
                    Some(Surface::Group(_)) => {}
                    other => panic!("{p:?} sees {other:?}"),
                }
            }
            assert_eq!(share, on as f64 / (n * n) as f64, "{p:?}");
            assert!(!is_pure && share < 1.0, "{p:?}");
            if share >= 0.5 {
                assert!(half[0].contains(&(p, share)), "{p:?}");
            }
        }
    }

    /// Cornell's light at 32 px per face holds pixels interior to it; at 8 px only four
    /// lie wholly on it, each beside its edge: those are kept apart, not read and not lost.
    #[test]
    fn pixels_wholly_on_a_light_beside_its_edge_are_kept_apart_from_interior_ones() {
        use crate::assemble::{load_and_assemble, MaterialSource};
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.toml");
        let mut owned = load_and_assemble(&path, MaterialSource::GeometryOnly).unwrap();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let fine = owned.views.clone();
        let coarse: Vec<View> = (fine.iter())
            .map(|v| View {
                width: 8,
                height: 8,
                ..*v
            })
            .collect();
        let scene = owned.build().unwrap();
        let at_32 = label_views(&pool, &scene, &fine);
        let at_8 = label_views(&pool, &scene, &coarse);
        assert!(!at_32.lights.is_empty() && !at_32.light_edges.is_empty());
        assert!(at_8.lights.is_empty());
        assert_eq!(at_8.light_edges.len(), 4, "{:?}", at_8.light_edges);
        // An edge pixel has a neighbour off the light; an interior one has none.
        for labels in [&at_32, &at_8] {
            for p in &labels.light_edges {
                assert!(!labels.lights.contains(p), "{p:?}");
            }
        }
    }
}
