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

/// A pure pixel brighter, in some channel, than this times that channel of every light's
/// declared radiance is not a surface of the scene (its reflectance is at most 1 in every
/// channel): the margin allows for a capture's noise and a calibration a few percent off
/// (the living room's mirror reads 0.90x its light).
pub const BRIGHTER_THAN_THE_LIGHTS: f32 = 2.0;

/// A channel's bound is at least this share of the lights' brightest channel: a light
/// declared without blue, in a capture whose blue is noise or a black level, is not
/// refused for it. (The bound was the brightest channel for all three, and a light
/// declared [30, 28, 0] over a capture lit in blue left every colour's blue at its
/// starting 0.5 without a word: no light of the scene reached it.)
pub const CHANNEL_FLOOR: f32 = 0.01;

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
    let Some(brightest) = brightest_per_channel(light_radiance) else {
        return Ok((pure, None));
    };
    let overall = brightest.iter().map(|b| b.0).fold(0.0, f32::max);
    let bound = brightest.map(|(b, _)| BRIGHTER_THAN_THE_LIGHTS * b.max(CHANNEL_FLOOR * overall));
    let value = |p: &PurePixel| {
        let image = &real[p.view as usize];
        image.pixels[(p.y * image.width + p.x) as usize]
    };
    let past = |v: [f32; 3]| (0..3).find(|&c| v[c] > bound[c]);
    let too_bright = |p: &PurePixel| past(value(p)).is_some();
    let (bright, kept): (Vec<PurePixel>, Vec<PurePixel>) = pure.into_iter().partition(too_bright);
    let Some(first) = bright.first() else {
        return Ok((kept, None));
    };
    let total = bright.len() + kept.len();
    let share = bright.len() as f64 / total as f64;
    let v = value(first);
    let c = past(v).unwrap_or(0);
    let (level, light) = brightest[c];
    let there = match level > 0.0 {
        true => format!("{level:?}, light '{}'", names.lights[light]),
        false => "no light emits there".into(),
    };
    let floor = match level < CHANNEL_FLOOR * overall {
        true => format!(", at least CHANNEL_FLOOR {CHANNEL_FLOOR} of their brightest channel"),
        false => String::new(),
    };
    let what = format!(
        "{} of {total} ({:.2}%) {} brighter in channel {} than {BRIGHTER_THAN_THE_LIGHTS}x the lights' radiance there ({there}{floor}), which no surface of the scene can be: a surface reflects at most the light that reaches it. The first: view '{}' pixel (x {}, y {}) on group '{}' reads [{:?}, {:?}, {:?}]",
        counted(bright.len() as u64, "pure pixel"),
        100.0 * share,
        if bright.len() == 1 { "is" } else { "are" },
        ["R", "G", "B"][c],
        names.views[first.view as usize],
        first.x,
        first.y,
        names.groups[first.group as usize],
        v[0],
        v[1],
        v[2],
    );
    if share > TOO_BRIGHT_SHARE {
        // All in one view of several: that view's exposure is the likelier cause (one
        // view's exposure 1e6 was blamed on the lights).
        let view = first.view;
        let one_view = names.views.len() > 1 && bright.iter().all(|p| p.view == view);
        let cause = match one_view {
            true => format!(
                "every one of them in view '{}': its exposure is likely too high, or a light the scene lacks (a window, a lamp not declared) shines only there",
                names.views[view as usize]
            ),
            false => "a light the scene lacks (a window, a lamp not declared) or a light's radiance declared too low".to_string(),
        };
        return Err(Error::input(
            scene_file,
            format!("{what}: {cause} (more than TOO_BRIGHT_SHARE {TOO_BRIGHT_SHARE} of the pure pixels: refused)"),
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

/// Per channel, the brightest light's radiance there and that light's index (the first
/// of equals); `None` when every light is dark.
fn brightest_per_channel(light_radiance: &[Vec3]) -> Option<[(f32, usize); 3]> {
    let mut brightest = [(0.0f32, 0usize); 3];
    for (i, r) in light_radiance.iter().enumerate() {
        for (c, b) in brightest.iter_mut().enumerate() {
            if r[c] > b.0 {
                *b = (r[c], i);
            }
        }
    }
    brightest.iter().any(|b| b.0 > 0.0).then_some(brightest)
}

/// A warning for each channel in which no light of the scene emits while another does:
/// no reflectance can be measured there, and every colour keeps its start in it.
pub fn unlit_channel_warnings(light_radiance: &[Vec3], start: f64) -> Vec<String> {
    let Some(brightest) = brightest_per_channel(light_radiance) else {
        return Vec::new();
    };
    (0..3)
        .filter(|&c| brightest[c].0 <= 0.0)
        .map(|c| {
            format!(
                "no light of the scene emits in channel {}: no reflectance can be measured in it, and every recovered colour keeps its start, {start}, there (is a light's radiance declared right?)",
                ["R", "G", "B"][c]
            )
        })
        .collect()
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

    /// Too many too bright pixels, all in one view of two: that view's exposure is named
    /// as the likely cause; spread over both, the lights are.
    #[test]
    fn too_bright_pixels_in_one_view_of_several_blame_its_exposure() {
        let s = |v: &[&str]| v.iter().map(|n| n.to_string()).collect::<Vec<_>>();
        let (views, groups, lights) = (
            s(&["front", "back"]),
            s(&["floor", "wall"]),
            s(&["off", "lamp"]),
        );
        let names = Names {
            views: &views,
            groups: &groups,
            lights: &lights,
        };
        let radiance = [Vec3::ZERO, Vec3::new(4.0, 10.0, 6.0)];
        let two_views = |front: &[(u32, f32)], back: &[(u32, f32)]| {
            let (mut pure, mut real) = case(200, front);
            let (back_pure, back_real) = case(200, back);
            pure.extend(back_pure.into_iter().map(|p| PurePixel { view: 1, ..p }));
            real.extend(back_real);
            let file = Path::new("scene.toml");
            leave_out_too_bright(file, pure, &real, &names, &radiance)
                .unwrap_err()
                .to_string()
        };
        let hot = [(2, 1e6), (13, 1e6), (50, 1e6), (60, 1e6), (70, 1e6)];
        let message = two_views(&hot, &[]);
        assert!(
            message.contains("5 pure pixels of 400 (1.25%)")
                && message
                    .contains("every one of them in view 'front': its exposure is likely too high"),
            "{message}"
        );
        let message = two_views(&hot[..3], &hot[3..]);
        assert!(
            !message.contains("every one of them")
                && message.contains("a light the scene lacks (a window, a lamp not declared) or a light's radiance declared too low"),
            "{message}"
        );
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
            warning.starts_with("1 pure pixel of 200 (0.50%) is brighter in channel G than 2x the lights' radiance there (10.0, light 'lamp')")
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
        // Each channel against its own lights: a light without blue (the other off)
        // leaves a pixel blue at 0.5 too bright, where the floor of 1% of the brightest
        // channel (0.1, bound 0.2) would pass a capture's noise of 0.15.
        let yellow = [Vec3::ZERO, Vec3::new(4.0, 10.0, 0.0)];
        let (pure, mut real) = case(200, &[]);
        for p in real[0].pixels.iter_mut() {
            p[2] = 0.0;
        }
        real[0].pixels[5] = [0.3, 0.3, 0.15];
        let (kept, warning) =
            leave_out_too_bright(file, pure.clone(), &real, &names, &yellow).unwrap();
        assert_eq!((kept, warning), (pure.clone(), None));
        let message = leave_out_too_bright(file, pure, &case(200, &[]).1, &names, &yellow)
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("200 pure pixels of 200 (100.00%) are brighter in channel B than 2x the lights' radiance there (no light emits there, at least CHANNEL_FLOOR 0.01 of their brightest channel)"),
            "{message}"
        );
        assert_eq!(
            unlit_channel_warnings(&yellow, 0.5),
            ["no light of the scene emits in channel B: no reflectance can be measured in it, and every recovered colour keeps its start, 0.5, there (is a light's radiance declared right?)"]
        );
        assert!(unlit_channel_warnings(&lights, 0.5).is_empty());
        // Every light dark: no bound (a scene without light is refused elsewhere).
        let (pure, real) = case(200, &[(13, 1e17)]);
        let dark = [Vec3::ZERO];
        let (kept, warning) =
            leave_out_too_bright(file, pure.clone(), &real, &names, &dark).unwrap();
        assert_eq!((kept, warning), (pure, None));
    }
}
