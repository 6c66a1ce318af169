//! Pixels that see out of the scene where the panorama is bright.
//!
//! A ray through such a pixel meets no geometry, so every render of the scene is black
//! there, whatever the materials: the panorama shows something the scene lacks (a wall
//! left out of the OBJ or hidden, or a window onto an outside the scene does not hold,
//! whose light then reaches the room undeclared). cornell with its back wall hidden saw
//! out of the room in 304 of view py's 1024 pixels; `check` said nothing, and recovery
//! put the missing wall's light into every colour (the ceiling 20% off, the walls 8-9%,
//! the box diffuse instead of glossy) with one warning of an exposure off by 1.15x.

use glam::Vec3;
use relume_core::geometry::View;
use relume_core::math::luminance;
use relume_core::scene::Scene;

use crate::images::Image;
use crate::parallel;
use crate::text::counted;

/// An outside pixel counts as bright from this share of the median of the view's pixels
/// that see the scene: far above a capture's black level, far below any lit surface.
pub const BRIGHT_SHARE_OF_MEDIAN: f32 = 0.1;

/// A view is warned of from this share of its pixels seeing out of the scene while
/// bright: a silhouette's few pixels whose centre passes an edge do not count.
pub const WARNED_SHARE: f64 = 0.01;

/// Where in a pixel rays are sent to tell whether it sees out of the scene: its centre
/// and corners. A pixel on the rim of an opening sees the rim over part of its footprint
/// and is bright in a panorama of the scene itself; its centre alone missed (cornell
/// without its back wall, rendered by relume: 30 of view py's 1024 pixels were told).
const FOOTPRINT: [(f32, f32); 5] = [(0.5, 0.5), (0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)];

/// One warning per view in which at least [`WARNED_SHARE`] of the pixels see out of the
/// scene (rays through the pixel's centre and corners meet nothing) where `real` (the
/// view's image) is bright.
pub fn bright_outside_warnings(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    views: &[View],
    real: &[Image],
    view_names: &[String],
) -> Vec<String> {
    views
        .iter()
        .zip(real)
        .zip(view_names)
        .filter_map(|((view, image), name)| {
            let outside = parallel::map_pixels(pool, view, |x, y| {
                FOOTPRINT.iter().all(|&(dx, dy)| {
                    let ray = view.ray(x as f32 + dx, y as f32 + dy);
                    scene.intersect(&ray, f32::INFINITY).is_none()
                })
            });
            let bright = bright_outside(&outside, image)?;
            Some(format!(
                "view '{name}': {bright} of its {} see out of the scene (no geometry there, so every render is black) where the panorama is bright: the scene lacks what the view shows there (a wall left out of the OBJ or hidden, or a window onto an outside that the scene does not hold, whose light it then lacks too); the colours of the groups it lights take that light instead",
                counted(outside.len() as u64, "pixel"),
            ))
        })
        .collect()
}

/// How many of the pixels flagged in `outside` are bright in `image` (one flag a pixel,
/// in row order), when they are at least [`WARNED_SHARE`] of its pixels.
fn bright_outside(outside: &[bool], image: &Image) -> Option<usize> {
    let lum = |p: &[f32; 3]| luminance(Vec3::from(*p));
    let mut inside: Vec<f32> = (image.pixels.iter().zip(outside))
        .filter(|(_, &out)| !out)
        .map(|(p, _)| lum(p))
        .collect();
    if inside.is_empty() || inside.len() == outside.len() {
        return None;
    }
    let mid = inside.len() / 2;
    let (_, median, _) = inside.select_nth_unstable_by(mid, f32::total_cmp);
    let floor = BRIGHT_SHARE_OF_MEDIAN * *median;
    let bright = (image.pixels.iter().zip(outside))
        .filter(|(p, &out)| out && lum(p) > floor)
        .count();
    (bright as f64 >= WARNED_SHARE * outside.len() as f64 && bright > 0).then_some(bright)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(values: &[f32]) -> Image {
        Image {
            width: values.len() as u32,
            height: 1,
            pixels: values.iter().map(|&v| [v; 3]).collect(),
        }
    }

    /// Pixels that see out of the scene count where they are bright against the median
    /// of those that see it, and only past [`WARNED_SHARE`] of the view.
    #[test]
    fn bright_pixels_outside_the_scene_are_counted() {
        let mut values = vec![1.0; 200];
        let mut outside = vec![false; 200];
        // Four outside pixels, two of them bright: 1% of 200.
        for (i, v) in [(0, 0.5), (1, 0.2), (2, 0.05), (3, 0.0)] {
            values[i] = v;
            outside[i] = true;
        }
        assert_eq!(bright_outside(&outside, &image(&values)), Some(2));
        // One bright pixel is under 1% of the view.
        values[1] = 0.0;
        assert_eq!(bright_outside(&outside, &image(&values)), None);
        // No pixel outside, or none inside: nothing to say (a view of the sky alone is
        // refused elsewhere).
        assert_eq!(bright_outside(&[false; 200], &image(&values)), None);
        assert_eq!(bright_outside(&[true; 200], &image(&values)), None);
    }
}
