//! Pixels brighter than the scene's lights allow. A surface reflects at most the light
//! that reaches it (its reflectance is at most 1 in every channel), so no surface of a
//! scene whose only emitters are its lights is brighter than the brightest of them: a mirror
//! shows a light at its radiance times its reflectance, a diffuse wall far less (the
//! references' brightest pure pixel is 0.02-0.90x their brightest light's radiance, the
//! living room's mirror the most). A pure pixel beyond that is a hot pixel of the capture,
//! or light from a source the scene lacks or declares too dim. One such pixel at 1e17 put
//! cornell's floor at its bound 0.99 ("1.6e14x as bright as the render") and the rest of
//! the room wrong, without naming the pixel.

use std::path::Path;

use glam::Vec3;

use super::pixels::PurePixel;
use crate::error::Error;
use crate::images::Image;
use crate::text::counted;

/// A pure pixel brighter, in some channel, than this times the brightest channel of any
/// light's declared radiance is not a surface of the scene: the margin allows for a
/// capture's noise and a calibration a few percent off (the living room's mirror reads
/// 0.90x its light).
pub const BRIGHTER_THAN_THE_LIGHTS: f32 = 2.0;

/// Up to this share of the pure pixels such pixels are left out of the fit with a warning
/// (a hot pixel, a small glint of a source the scene lacks); beyond it the panorama is
/// refused: the scene's lights cannot have lit it.
pub const TOO_BRIGHT_SHARE: f64 = 0.01;

/// The pure pixels `pure` of the panorama `real` with those brighter than the lights allow
/// left out, and the warning that says so (`None` when there are none). An error where
/// they are more than [`TOO_BRIGHT_SHARE`] of all. `light_radiance` is every light's
/// declared radiance, in the order of `names.lights`; a scene whose lights are all dark
/// is left to the test that refuses a scene without light.
pub fn leave_out_too_bright(
    scene_file: &Path,
    pure: Vec<PurePixel>,
    real: &[Image],
    names: &Names,
    light_radiance: &[Vec3],
) -> Result<(Vec<PurePixel>, Option<String>), Error> {
    let Some((brightest, light)) = brightest_light(light_radiance) else {
        return Ok((pure, None));
    };
    let bound = BRIGHTER_THAN_THE_LIGHTS * brightest;
    let value = |p: &PurePixel| {
        let image = &real[p.view as usize];
        image.pixels[(p.y * image.width + p.x) as usize]
    };
    let too_bright = |p: &PurePixel| value(p).iter().any(|&c| c > bound);
    let (bright, kept): (Vec<PurePixel>, Vec<PurePixel>) = pure.into_iter().partition(too_bright);
    let Some(first) = bright.first() else {
        return Ok((kept, None));
    };
    let total = bright.len() + kept.len();
    let share = bright.len() as f64 / total as f64;
    let v = value(first);
    let what = format!(
        "{} of {total} ({:.2}%) {} brighter than {BRIGHTER_THAN_THE_LIGHTS}x the brightest light's radiance ({brightest:?} in its brightest channel, light '{}'), which no surface of the scene can be: a surface reflects at most the light that reaches it. The first: view '{}' pixel (x {}, y {}) on group '{}' reads [{:?}, {:?}, {:?}]",
        counted(bright.len() as u64, "pure pixel"),
        100.0 * share,
        if bright.len() == 1 { "is" } else { "are" },
        names.lights[light],
        names.views[first.view as usize],
        first.x,
        first.y,
        names.groups[first.group as usize],
        v[0],
        v[1],
        v[2],
    );
    if share > TOO_BRIGHT_SHARE {
        return Err(Error::input(
            scene_file,
            format!("{what}: a light the scene lacks (a window, a lamp not declared) or a light's radiance declared too low (more than TOO_BRIGHT_SHARE {TOO_BRIGHT_SHARE} of the pure pixels: refused)"),
        ));
    }
    let warning = format!(
        "{what}: left out of the fit (a hot pixel of the capture, or a source the scene lacks; more than TOO_BRIGHT_SHARE {TOO_BRIGHT_SHARE} of the pure pixels would be refused)"
    );
    Ok((kept, Some(warning)))
}

/// The names a message gives: of the views, the groups and the lights, by index.
pub struct Names<'a> {
    pub views: &'a [String],
    pub groups: &'a [String],
    pub lights: &'a [String],
}

/// The brightest channel of any light's radiance and that light's index; `None` when
/// every light is dark.
fn brightest_light(light_radiance: &[Vec3]) -> Option<(f32, usize)> {
    let (i, r) = light_radiance
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.max_element().total_cmp(&b.1.max_element()))?;
    (r.max_element() > 0.0).then_some((r.max_element(), i))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixel(x: u32, group: u16) -> PurePixel {
        PurePixel {
            view: 0,
            x,
            y: 0,
            group,
        }
    }

    fn names() -> (Vec<String>, Vec<String>, Vec<String>) {
        let s = |v: &[&str]| v.iter().map(|n| n.to_string()).collect();
        (s(&["front"]), s(&["floor", "wall"]), s(&["off", "lamp"]))
    }

    /// A row of `n` pixels at 0.3 but for the hot ones, each group's pixels all pure.
    fn case(n: u32, hot: &[(u32, f32)]) -> (Vec<PurePixel>, Vec<Image>) {
        let mut pixels = vec![[0.3f32; 3]; n as usize];
        for &(x, v) in hot {
            pixels[x as usize] = [0.3, v, 0.3];
        }
        let image = Image {
            width: n,
            height: 1,
            pixels,
        };
        (
            (0..n).map(|x| pixel(x, (x % 2) as u16)).collect(),
            vec![image],
        )
    }

    #[test]
    fn a_hot_pixel_is_left_out_and_named_and_many_are_refused() {
        let (v, g, l) = names();
        let names = Names {
            views: &v,
            groups: &g,
            lights: &l,
        };
        // The brightest channel of any light: the lamp's 10. A mirror showing the lamp at
        // its radiance is a surface of the scene; twice it is not.
        let lights = [Vec3::ZERO, Vec3::new(4.0, 10.0, 6.0)];
        let file = Path::new("scene.toml");
        let (pure, real) = case(200, &[(7, 10.0), (13, 1e17)]);
        let (kept, warning) =
            leave_out_too_bright(file, pure.clone(), &real, &names, &lights).unwrap();
        assert_eq!(kept.len(), 199);
        assert!(!kept.contains(&pixel(13, 1)) && kept.contains(&pixel(7, 1)));
        let warning = warning.unwrap();
        assert!(
            warning.starts_with("1 pure pixel of 200 (0.50%) is brighter than 2x the brightest light's radiance (10.0 in its brightest channel, light 'lamp')")
                && warning.contains("view 'front' pixel (x 13, y 0) on group 'wall' reads [0.3, 1e17, 0.3]")
                && warning.contains("left out of the fit"),
            "{warning}"
        );
        // Within the bound nothing is left out.
        let (pure, real) = case(200, &[(7, 19.9)]);
        let (kept, warning) =
            leave_out_too_bright(file, pure.clone(), &real, &names, &lights).unwrap();
        assert_eq!((kept, warning), (pure, None));
        // Three of 200: more than 1%, a light the scene lacks.
        let (pure, real) = case(200, &[(2, 21.0), (13, 1e17), (50, 30.0)]);
        let err = leave_out_too_bright(file, pure, &real, &names, &lights).unwrap_err();
        let message = err.to_string();
        assert!(
            message.contains("scene.toml")
                && message.contains("3 pure pixels of 200 (1.50%)")
                && message.contains("pixel (x 2, y 0) on group 'floor'")
                && message.contains("a light the scene lacks"),
            "{message}"
        );
        // Every light dark: no bound (a scene without light is refused elsewhere).
        let (pure, real) = case(200, &[(13, 1e17)]);
        let dark = [Vec3::ZERO];
        let (kept, warning) =
            leave_out_too_bright(file, pure.clone(), &real, &names, &dark).unwrap();
        assert_eq!((kept, warning), (pure, None));
    }
}
