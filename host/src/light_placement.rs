//! Lights placed against a surface. A light whose front lies within the renderer's ray
//! slack of a group's surface (flush with a ceiling, or a hair behind it) is hidden from
//! the views, which see the surface, yet lights the room as if nothing were there: a
//! shadow ray stops short of the light by `RAY_EPSILON` of its length, and a secondary
//! ray starts that far off the surface it leaves. The cornell lamp moved into the ceiling
//! plane rendered the room as bright as before with no lamp in sight, and `check` blamed
//! the exposure.

use relume_core::geometry::{Ray, Surface};
use relume_core::math::Vec3;
use relume_core::render::RAY_EPSILON;

use crate::assemble::OwnedScene;
use crate::error::Error;
use crate::text::counted;

/// How far in front of a light a surface hides it and still lets its light through, in
/// `RAY_EPSILON`s of the scene's size: a shadow ray's slack is `RAY_EPSILON` of its length
/// (up to the scene's diagonal, 1.7 sizes) and the ray starts that far off its surface.
pub(crate) const SLACK_IN_EPSILONS: f32 = 2.0;

/// Points tested per light, at most (its triangles' centroids, evenly strided).
const POINTS_PER_LIGHT: usize = 256;

/// The share of a light's points behind a surface from which it is warned of.
const HIDDEN_SHARE: f64 = 0.5;

/// A warning for each light most of whose points have a group's surface within the ray
/// slack in front of them (or in their plane, where the surface wins the views' rays).
pub fn lights_against_surfaces(owned: &mut OwnedScene) -> Result<Vec<String>, Error> {
    let (group_names, light_names) = (owned.group_names.clone(), owned.light_names.clone());
    let scene = owned.build()?;
    let slack = SLACK_IN_EPSILONS * RAY_EPSILON * scene.size();
    // Each light's triangles, in one pass over the scene's.
    let mut of_light = vec![Vec::new(); light_names.len()];
    for t in scene.triangles {
        if let Surface::Light(l) = t.surface {
            if let Some(own) = of_light.get_mut(l as usize) {
                own.push(t);
            }
        }
    }
    let mut warnings = Vec::new();
    for (name, own) in light_names.iter().zip(&of_light) {
        let stride = own.len().div_ceil(POINTS_PER_LIGHT).max(1);
        let mut tested = 0usize;
        let mut hidden_by = vec![0usize; group_names.len()];
        for t in own.iter().step_by(stride) {
            let normal = t.normal_area2().normalize_or_zero();
            if normal == Vec3::ZERO {
                continue;
            }
            tested += 1;
            let centroid = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
            // From just in front of the light back to it: the first surface met within
            // the slack (or in the light's plane) is what the views see there.
            let ray = Ray::new(centroid + normal * slack, -normal);
            let hit = scene.intersect(&ray, slack * 1.01);
            let surface = hit.and_then(|h| scene.triangles.get(h.triangle as usize));
            if let Some(Surface::Group(g)) = surface.map(|s| s.surface) {
                if let Some(n) = hidden_by.get_mut(g as usize) {
                    *n += 1;
                }
            }
        }
        let hidden: usize = hidden_by.iter().sum();
        if tested == 0 || (hidden as f64) < HIDDEN_SHARE * tested as f64 {
            continue;
        }
        let most = (0..group_names.len())
            .max_by_key(|&g| hidden_by[g])
            .unwrap_or(0);
        warnings.push(format!(
            "light '{name}' lies against group '{}': at {hidden} of {} on it, a surface is within {} units in front of it or in its plane, closer than the renderer's ray slack; the views see that surface where the light is, yet the light shines through it as if it were not there: move the light in front of the surface by more than that, or cut the surface away behind it",
            group_names.get(most).map_or("?", String::as_str),
            counted(tested as u64, "point"),
            crate::text::significant(f64::from(slack)),
        ));
    }
    Ok(warnings)
}
