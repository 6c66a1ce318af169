//! The panorama's calibration, read off the lights it sees. A light reflects nothing, so a
//! pixel wholly inside one shows its radiance and nothing else: the panorama's value there
//! over the declared radiance is the view's exposure error times the light's radiance error.
//! Every recovered reflectance scales with that factor, and nothing else in the input shows
//! it: the interreflections absorb part of it, so a panorama 2x too bright was recovered
//! with every colour below 1 and lobes on diffuse walls (docs/stability.md).
//!
//! A view that sees no light is checked against the others instead ([`read_views`]): the
//! recovered model is fitted to every view at once, so an exposure error in one view is
//! left in that view's residual, in part (the groups it alone sees absorb the rest).

use glam::Vec3;
use relume_core::fit::GroupFit;
use serde::Serialize;

use super::pixels::{LightPixel, PurePixel};
use crate::images::{self, Image};
use crate::text::counted;

/// The largest relative difference, in any channel, between a light's pixels and its
/// declared radiance before recovery warns. The references' light pixels equal the
/// radiance to 0.26-0.42% (their READMEs); bench stability saw a 2% exposure error put
/// box-diffuse's reflectances about 1% off (the target), and 10% change a class.
pub const CALIBRATION_TOLERANCE: f64 = 0.02;

/// The panorama over one light in one view.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct LightReading {
    pub light: String,
    pub view: String,
    /// Pixels wholly inside the light, with their four neighbours.
    pub pixels: u32,
    pub declared: [f64; 3],
    /// The panorama's median over those pixels per channel (exposure applied).
    pub measured: [f64; 3],
    /// `measured / declared` per channel; `null` where the light is declared dark.
    pub ratio: [Option<f64>; 3],
}

impl LightReading {
    /// One line for a reader: the light, the view, and the panorama over the declared
    /// radiance per channel.
    pub fn describe(&self) -> String {
        format!(
            "light '{}' in view '{}' reads {} x its declared radiance (R G B, {} pixels)",
            self.light,
            self.view,
            self.ratios_text(),
            self.pixels
        )
    }

    /// The ratios as `R G B`, `-` for a channel declared dark.
    fn ratios_text(&self) -> String {
        let ratios: Vec<String> = self
            .ratio
            .iter()
            .map(|q| q.map_or("-".into(), factor_text))
            .collect();
        ratios.join(" ")
    }

    /// The channel furthest from its declared radiance, as `measured / declared`.
    fn worst_ratio(&self) -> Option<f64> {
        self.ratio
            .iter()
            .flatten()
            .copied()
            .max_by(|a, b| (a - 1.0).abs().total_cmp(&(b - 1.0).abs()))
    }
}

/// One reading per light and view that sees it, lights in scene order, then views.
/// `pixels` are in view and row order. The reading is the median per channel: a light
/// holds one radiance, and a hot pixel of the capture inside it (a pixel of 1e17 among
/// fifty) put the mean, and the calibration warning, off by orders of magnitude.
pub fn read_lights(
    pixels: &[LightPixel],
    real: &[Image],
    light_names: &[String],
    light_radiance: &[Vec3],
    view_names: &[String],
) -> Vec<LightReading> {
    // Values per (light, view), in one pass over the pixels.
    let n_views = view_names.len();
    let mut values = vec![Vec::<[f32; 3]>::new(); light_names.len() * n_views];
    for p in pixels {
        let image = &real[p.view as usize];
        let value = image.pixels[(p.y * image.width + p.x) as usize];
        values[p.light as usize * n_views + p.view as usize].push(value);
    }
    let mut readings = Vec::new();
    for (l, (name, radiance)) in light_names.iter().zip(light_radiance).enumerate() {
        for (v, view) in view_names.iter().enumerate() {
            let inside = &values[l * n_views + v];
            if inside.is_empty() {
                continue;
            }
            let declared = radiance.to_array().map(f64::from);
            let measured = std::array::from_fn(|c| {
                median(inside.iter().map(|value| f64::from(value[c])).collect()).unwrap_or(0.0)
            });
            let mut ratio = [None; 3];
            for c in 0..3 {
                if declared[c] > 0.0 {
                    ratio[c] = Some(measured[c] / declared[c]);
                }
            }
            readings.push(LightReading {
                light: name.clone(),
                view: view.clone(),
                pixels: inside.len() as u32,
                declared,
                measured,
                ratio,
            });
        }
    }
    readings
}

/// A factor to three decimals, with an exponent where that would hide it or run to dozens
/// of digits (a light declared at 1e-30 read "23999999923894154511256926552064.000x").
fn factor_text(f: f64) -> String {
    if (1e-3..1e6).contains(&f.abs()) || f == 0.0 {
        format!("{f:.3}")
    } else {
        format!("{f:.3e}")
    }
}

/// What `check` and `recover` print where no reading was made.
pub const NOT_CHECKED: &str = "calibration: not checked (no view sees a light's emitting side over a pixel and its four neighbours)";

/// Where no pixel is interior to a light but some lie wholly on one beside its edge (a
/// small light, or coarse views): says so, with the (view, light) that has the most of
/// them. Such pixels are not read: a camera's or a filter's blur at the light's edge mixes
/// in what surrounds it, and a warning from a blurred reading would blame the exposure.
/// Before, the calibration was said to find no light "in whole pixels" where four were.
pub fn unchecked_warning(
    interior: &[LightPixel],
    edges: &[LightPixel],
    light_names: &[String],
    view_names: &[String],
) -> Option<String> {
    if !interior.is_empty() || edges.is_empty() {
        return None;
    }
    let mut counts = std::collections::BTreeMap::<(u32, u16), u32>::new();
    for p in edges {
        *counts.entry((p.view, p.light)).or_default() += 1;
    }
    // The most pixels; of equal counts the first view, then the first light.
    let (&(view, light), &most) = counts
        .iter()
        .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(a.0)))?;
    let (light, view) = (&light_names[light as usize], &view_names[view as usize]);
    let which = match counts.len() {
        1 => format!("the {} that see light '{light}' wholly, in view '{view}', lie beside its edge", counted(most, "pixel")),
        _ => format!("the {} that see one wholly lie beside its edge (most, {most}, light '{light}' in view '{view}')", counted(edges.len() as u64, "pixel")),
    };
    Some(format!(
        "the panorama's calibration (its exposure against the lights' radiance) is not checked: no pixel sees a light's emitting side together with its four neighbours, and {which}, where a camera's or a filter's blur mixes in what surrounds the light; views finer where they see a light would check it"
    ))
}

/// A light declared dark (radiance 0) whose pixels read more than this fraction of the
/// brightest light's radiance: far brighter than a lamp's glass or shade lit by the room
/// (the references' groups read 0.2-1.5% of their lamp's radiance on average), so most
/// likely a lamp that was on when the panorama was taken.
pub const DARK_LIGHT_LIT: f64 = 0.1;

/// Classes under a panorama brighter than its lights declare (a reading above 1): a
/// diffuse fit leaves a weak lobe less error to show by (the living room's desk at 256 px,
/// its stage-1 error: 0.022 at 1x, 0.018 at 1.05x, 0.016 at 1.10x, where stage 2 finds
/// its lobe accounts for 0.009, under the 1% a lobe must).
const CLASSES_UNDER_A_BRIGHT_PANORAMA: &str = "on the references a panorama bright against its lights hid weak lobes (specularity under 0.1): the living room's desk (s 0.05) was left diffuse at 1.10x (at 1.05x on 1 seed of 6), as with its lamp 10% dim";
/// Classes under a panorama darker than its lights declare (a reading under 1).
const CLASSES_UNDER_A_DARK_PANORAMA: &str = "on the references a panorama dark against its lights gave groups lobes they do not have: box-diffuse's box_red and textured's stand took one (s 0.03-0.04) at 0.90x, as with their lamp 10% bright; a reading under 1 can also be a light clipped in the capture";

/// A warning for each reading off by more than [`CALIBRATION_TOLERANCE`] in some channel,
/// and for each light declared dark that reads more than [`DARK_LIGHT_LIT`] of the
/// brightest channel of any light's declared radiance (`light_radiance`).
pub fn calibration_warnings(readings: &[LightReading], light_radiance: &[Vec3]) -> Vec<String> {
    let brightest = light_radiance
        .iter()
        .map(|r| r.max_element() as f64)
        .fold(0.0, f64::max);
    let mut warnings = Vec::new();
    for r in readings {
        let Some(worst) = r.worst_ratio() else {
            let reads = r.measured.iter().copied().fold(0.0, f64::max);
            if r.declared == [0.0; 3] && brightest > 0.0 && reads > DARK_LIGHT_LIT * brightest {
                warnings.push(format!(
                    "light '{}' is declared dark (radiance 0) but reads [{:.3}, {:.3}, {:.3}] in view '{}' over {} pixels wholly inside it, {:.0}% of the brightest light's radiance: if it was on when the panorama was taken, give its radiance; recovery explains the light it sheds with the materials",
                    r.light,
                    r.measured[0],
                    r.measured[1],
                    r.measured[2],
                    r.view,
                    r.pixels,
                    100.0 * reads / brightest
                ));
            }
            continue;
        };
        // A channel declared dark in a light that is not: its ratio is undefined, and the
        // reading said "-" there without a word ([30, 28, 0] over a lamp read 24 in blue).
        for c in 0..3 {
            if r.declared[c] == 0.0 && r.measured[c] > DARK_LIGHT_LIT * brightest {
                warnings.push(format!(
                    "light '{}' is declared 0 in channel {} but reads {} there in view '{}' over {} pixels wholly inside it, {:.0}% of the brightest light's radiance: is its radiance declared right?",
                    r.light,
                    ["R", "G", "B"][c],
                    crate::text::significant(r.measured[c]),
                    r.view,
                    r.pixels,
                    100.0 * r.measured[c] / brightest
                ));
            }
        }
        if (worst - 1.0).abs() <= CALIBRATION_TOLERANCE {
            continue;
        }
        // What the stability study saw such an error do to classes, by its sign (a
        // capture can also clip a lamp where it clips nothing else: then the light reads
        // low and the exposure is right).
        let classes = match worst < 1.0 {
            true => CLASSES_UNDER_A_DARK_PANORAMA,
            false => CLASSES_UNDER_A_BRIGHT_PANORAMA,
        };
        warnings.push(format!(
            "light '{}' reads {}x its declared radiance in view '{}' (R G B {} over {} pixels wholly inside it): the view's exposure or the light's radiance is off by that factor, and every recovered reflectance with it, a diffuse one by about half of it (box-diffuse's 2.5% at 5%, 5% at 10%); {classes} (docs/stability.md)",
            r.light,
            factor_text(worst),
            r.view,
            r.ratios_text(),
            r.pixels
        ));
    }
    warnings
}

/// A warning for each light whose back (`back_readings`: [`read_lights`] over the pixels
/// interior to a light's non-emitting side) reads more than [`DARK_LIGHT_LIT`] of its own
/// declared radiance: a light's back is black, and one that shines is most likely a light
/// whose triangles face the other way, which left the room lit from a light turned to
/// the wall it sits on and was told only as groups "too bright" for the lights.
pub fn facing_away_warnings(back_readings: &[LightReading]) -> Vec<String> {
    back_readings
        .iter()
        .filter_map(|r| {
            let declared = r.declared.iter().copied().fold(0.0, f64::max);
            let reads = r.measured.iter().copied().fold(0.0, f64::max);
            (declared > 0.0 && reads > DARK_LIGHT_LIT * declared).then(|| {
                format!(
                    "light '{}' is seen from behind in view '{}' ({} wholly on its back), yet reads {}x its declared radiance there (R G B {}) where its back is black: its triangles likely face away from where it shines; a light emits from its front only, where its vertices turn counter-clockwise (scene-format.md): reverse their order in the OBJ",
                    r.light,
                    r.view,
                    counted(r.pixels, "pixel"),
                    factor_text(reads / declared),
                    r.ratios_text(),
                )
            })
        })
        .collect()
}

/// How far one view's mean residual may lie from the median of the other views' before
/// recovery warns that its exposure may be off. On the references the views agree to
/// within 0.8% of that median (64 and 256 px, effort fast); one view 5% too bright lay
/// 3.5-4% off it (glossy and living room, 64 px).
pub const VIEW_AGREEMENT: f64 = 0.02;

/// And it must lie this many of the view's own standard errors from it: at a few hundred
/// pixels a firefly of the render moves a view's mean by whole percents.
pub const VIEW_SIGMAS: f64 = 3.0;

/// Fewer pure pixels and a view's mean is not compared: a few pixels are one group's.
pub const MIN_VIEW_PIXELS: u32 = 256;

/// But a view of fewer is still warned of when the panorama over the render is off the
/// others' by more than this factor either way: after the fit no group's misfit moves a
/// view's mean so far, and an exposure off by orders of magnitude in one 8-px view left
/// its recovery wrong without a word. So is a view of any size, in ratios; and `relume
/// check` tells this much from its preview of stage 1.
pub const VIEW_GROSS_FACTOR: f64 = 2.0;

/// The final render against the panorama over one view's pure pixels.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct ViewReading {
    pub view: String,
    pub pure_pixels: u32,
    /// Mean over the pure pixels and channels.
    pub panorama_mean: f64,
    pub render_mean: f64,
    /// `(render - panorama) / panorama`; `null` without pixels or light.
    pub rel_mean_diff: Option<f64>,
    /// The standard error of `rel_mean_diff` from the spread of the pixels' differences:
    /// the render's noise, the panorama's and the misfit's. On cornell's 32-px views a
    /// view's mean moves by up to 2% between seeds; on the references' 64-px views by
    /// under 1%.
    pub rel_mean_diff_sigma: Option<f64>,
}

/// One reading per view: the panorama `real` against the final `renders` (one radiance
/// per pixel of each view) over the pure pixels, summed in their order.
pub fn read_views(
    pure: &[PurePixel],
    real: &[Image],
    renders: &[Vec<Vec3>],
    view_names: &[String],
) -> Vec<ViewReading> {
    // Per view: pixels, sum of the panorama, of the render, of the squared differences
    // (channels summed per pixel).
    let mut sums = vec![(0u32, 0.0f64, 0.0f64, 0.0f64); view_names.len()];
    for p in pure {
        let v = p.view as usize;
        let at = (p.y * real[v].width + p.x) as usize;
        let (Some(t), Some(r)) = (real[v].pixels.get(at), renders[v].get(at)) else {
            continue;
        };
        let t: f64 = t.iter().map(|&c| c as f64).sum();
        let r: f64 = r.to_array().iter().map(|&c| c as f64).sum();
        let s = &mut sums[v];
        s.0 += 1;
        s.1 += t;
        s.2 += r;
        s.3 += (r - t) * (r - t);
    }
    view_names
        .iter()
        .zip(sums)
        .map(|(name, (pixels, real, rendered, squares))| {
            let n = pixels.max(1) as f64;
            let mean_diff = (rendered - real) / n;
            let variance = (squares / n - mean_diff * mean_diff).max(0.0);
            let defined = real > 0.0 && pixels > 1;
            ViewReading {
                rel_mean_diff_sigma: defined.then(|| (variance / (n - 1.0)).sqrt() / (real / n)),
                ..ViewReading::from_sums(name, pixels, real, rendered)
            }
        })
        .collect()
}

impl ViewReading {
    /// A reading from a view's sums over its `pixels` (channels summed) of the panorama
    /// and the render, without a standard error.
    fn from_sums(view: &str, pixels: u32, real: f64, rendered: f64) -> ViewReading {
        let n = pixels.max(1) as f64;
        ViewReading {
            view: view.to_string(),
            pure_pixels: pixels,
            panorama_mean: real / (3.0 * n),
            render_mean: rendered / (3.0 * n),
            rel_mean_diff: (real > 0.0).then(|| (rendered - real) / real),
            rel_mean_diff_sigma: None,
        }
    }
}

/// The median of `values` (the mean of the middle two for an even count); `None` when
/// there are none.
fn median(mut values: Vec<f64>) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    let k = values.len();
    match k {
        0 => None,
        _ if k % 2 == 1 => Some(values[k / 2]),
        _ => Some(0.5 * (values[k / 2 - 1] + values[k / 2])),
    }
}

/// One view's reading from the fits of its pixels' groups (`relume check`'s preview,
/// which renders a subset of each group's pure pixels: `pure_pixels` counts those). No
/// standard error: the preview's readings are for the gross test only.
pub fn read_view_fits(view: &str, fits: &[GroupFit]) -> ViewReading {
    let pixels: u32 = fits.iter().map(|f| f.pixels).sum();
    let real: f64 = fits.iter().flat_map(|f| f.sum_real).sum();
    let rendered: f64 = fits.iter().flat_map(|f| f.sum_rendered).sum();
    ViewReading::from_sums(view, pixels, real, rendered)
}

/// What each view's image header divided its stored values by
/// ([`images::read_view_image_and_header`]), in the views' order: the warnings that blame a
/// view's exposure name it, since a header's `EXPOSURE` is applied without a word (an
/// `EXPOSURE=1e300` read as a black view).
#[derive(Clone, Copy)]
pub struct ImageHeaders<'a> {
    pub views: &'a [String],
    pub divisors: &'a [Option<[f64; 3]>],
}

impl ImageHeaders<'_> {
    /// No view's header scales it.
    #[cfg(test)]
    pub const NONE: ImageHeaders<'static> = ImageHeaders {
        views: &[],
        divisors: &[],
    };

    /// [`images::header_note`] for the view named `view`.
    fn note(&self, view: &str) -> String {
        let divisor = self.views.iter().position(|v| v == view);
        images::header_note(divisor.and_then(|i| self.divisors.get(i).copied().flatten()))
    }
}

/// A warning for each view whose mean residual lies more than [`VIEW_AGREEMENT`], and
/// more than [`VIEW_SIGMAS`] of its standard errors, from the median of the other views'
/// (views of at least [`MIN_VIEW_PIXELS`]; at least two others to take a median of); and
/// for each view, of any size, off the others by more than [`VIEW_GROSS_FACTOR`].
pub fn view_warnings(readings: &[ViewReading], headers: ImageHeaders) -> Vec<String> {
    let gross = gross_view_warnings(readings, headers, "the recovered model renders");
    let mut warnings = Vec::new();
    for (r, diff, typical) in against_the_others(readings, MIN_VIEW_PIXELS) {
        let sigma = r.rel_mean_diff_sigma.unwrap_or(f64::INFINITY);
        // A view the gross test tells of is told once. Only those: the gross test's median
        // is of every view, this one's of the large ones, and a view gross against the
        // large ones alone was once told by neither.
        let told_gross = gross.iter().any(|(view, _)| *view == r.view);
        if told_gross || (diff - typical).abs() <= VIEW_AGREEMENT.max(VIEW_SIGMAS * sigma) {
            continue;
        }
        warnings.push(format!(
            "view '{}': the recovered model renders its {} pure pixels {:+.1}% (+- {:.1}%) off the panorama, where the other views' median is {:+.1}%: its exposure may be off by about {:.3}x{} (partly absorbed by the groups only it sees)",
            r.view,
            r.pure_pixels,
            100.0 * diff,
            100.0 * sigma,
            100.0 * typical,
            view_factor(diff, typical),
            headers.note(&r.view)
        ));
    }
    warnings.extend(gross.into_iter().map(|(_, warning)| warning));
    warnings
}

/// The gross part of [`view_warnings`] for `relume check`, whose readings are of stage 1's
/// preview: every group diffuse at a few samples, too rough for the 2% test (a glossy
/// group's highlight in one view moves its mean), not for a factor of 2.
pub fn preview_view_warnings(readings: &[ViewReading], headers: ImageHeaders) -> Vec<String> {
    let gross = gross_view_warnings(readings, headers, "the first look's diffuse colours render");
    gross.into_iter().map(|(_, warning)| warning).collect()
}

/// The factor by which a view's exposure may be off: the panorama over the render, against
/// the same for the other views (`diff` and `typical` are render over panorama, minus 1).
fn view_factor(diff: f64, typical: f64) -> f64 {
    (1.0 + typical) / (1.0 + diff)
}

/// Each view of at least `min_pixels` pure pixels with its mean residual and the median
/// of the other such views' (where there are at least two others). A view the model
/// renders black has no ratio to compare, as one black in the panorama has none (its
/// -100% in the others' median had two lit views beside it told their exposure off).
fn against_the_others(readings: &[ViewReading], min_pixels: u32) -> Vec<(&ViewReading, f64, f64)> {
    let compared: Vec<(&ViewReading, f64)> = readings
        .iter()
        .filter(|r| r.pure_pixels >= min_pixels && r.render_mean != 0.0)
        .filter_map(|r| Some((r, r.rel_mean_diff?)))
        .collect();
    let others_of = |i: usize| -> Vec<f64> {
        let others = compared.iter().enumerate().filter(|&(j, _)| j != i);
        others.map(|(_, o)| o.1).collect()
    };
    (0..compared.len())
        .filter_map(|i| {
            let others = others_of(i);
            if others.len() < 2 {
                return None;
            }
            Some((compared[i].0, compared[i].1, median(others)?))
        })
        .collect()
}

/// A warning for each view, of any number of pure pixels, whose panorama over what
/// `subject` renders lies more than [`VIEW_GROSS_FACTOR`] from the median of every other
/// view's (at least two others): told in ratios, which percentages would hide (a view
/// whose exposure was given as 1e-30 read +4e31%). Each warning beside its view's name.
fn gross_view_warnings<'r>(
    readings: &'r [ViewReading],
    headers: ImageHeaders,
    subject: &str,
) -> Vec<(&'r str, String)> {
    // A view black in the panorama has no ratio to compare (a division by its 0), and is
    // the grossest case of all: an image left black or an exposure mistyped.
    let mut warnings: Vec<(&str, String)> = readings
        .iter()
        .filter(|r| r.pure_pixels > 0 && r.panorama_mean == 0.0 && r.render_mean > 0.0)
        .map(|r| {
            let warning = format!(
                "view '{}': its {} are all 0 in the panorama, where {subject} them at {:.3e} on average: its image may be black or its exposure off{} (the groups only it sees are recovered black)",
                r.view,
                counted(r.pure_pixels, "pure pixel"),
                r.render_mean,
                headers.note(&r.view)
            );
            (r.view.as_str(), warning)
        })
        .collect();
    // A view the model renders black where its panorama is not has no factor either (the
    // panorama over a black render is infinite, and read "off by about infx"): what it
    // sees, no light of the scene reaches.
    warnings.extend(
        readings
            .iter()
            .filter(|r| r.pure_pixels > 0 && r.panorama_mean > 0.0 && r.render_mean == 0.0)
            .map(|r| {
                let warning = format!(
                    "view '{}': {subject} its {} black, where the panorama's mean over them is {:.3e}: no light of the scene reaches what it sees, or its image is not of this scene (the groups only it sees are not recovered)",
                    r.view,
                    counted(r.pure_pixels, "pure pixel"),
                    r.panorama_mean
                );
                (r.view.as_str(), warning)
            }),
    );
    for (r, diff, typical) in against_the_others(readings, 1) {
        let factor = view_factor(diff, typical);
        if (1.0 / VIEW_GROSS_FACTOR..=VIEW_GROSS_FACTOR).contains(&factor) {
            continue;
        }
        // Nor within VIEW_SIGMAS of its standard error: one pixel's heavy tail in a render
        // (a 5-mm light's, in cornell's ceiling view at 8 px: +2170% +- 1610%) read as an
        // exposure 0.044x off, where a render at more samples agreed within 5%.
        if r.rel_mean_diff_sigma
            .is_some_and(|sigma| (diff - typical).abs() <= VIEW_SIGMAS * sigma)
        {
            continue;
        }
        let warning = format!(
            "view '{}': {subject} its {} {:.3e}x the panorama, where the other views' median is {:.3}x: its exposure or image may be off by about {factor:.3e}x{} (more than VIEW_GROSS_FACTOR {VIEW_GROSS_FACTOR} either way; partly absorbed by the groups only it sees)",
            r.view,
            counted(r.pure_pixels, "pure pixel"),
            1.0 + diff,
            1.0 + typical,
            headers.note(&r.view)
        );
        warnings.push((r.view.as_str(), warning));
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: u32, height: u32, value: [f32; 3]) -> Image {
        Image {
            width,
            height,
            pixels: vec![value; (width * height) as usize],
        }
    }

    fn pixel(view: u32, x: u32, light: u16) -> LightPixel {
        LightPixel {
            view,
            x,
            y: 1,
            light,
        }
    }

    #[test]
    fn a_reading_per_light_and_view_with_the_median_over_its_pixels() {
        let mut first = image(4, 4, [0.1; 3]);
        first.pixels[4 + 1] = [10.0, 20.0, 30.0];
        first.pixels[4 + 2] = [12.0, 22.0, 32.0];
        // A hot pixel of the capture inside the lamp: the median does not see it.
        first.pixels[4 + 3] = [1e17, 21.0, 31.0];
        let second = image(4, 4, [24.0, 0.0, 5.0]);
        let readings = read_lights(
            &[
                pixel(0, 1, 1),
                pixel(0, 2, 1),
                pixel(0, 3, 1),
                pixel(1, 1, 1),
                pixel(1, 2, 0),
            ],
            &[first, second],
            &["bulb".into(), "lamp".into()],
            &[Vec3::ZERO, Vec3::new(11.0, 20.0, 31.0)],
            &["a".into(), "b".into()],
        );
        let names: Vec<(&str, &str, u32)> = readings
            .iter()
            .map(|r| (r.light.as_str(), r.view.as_str(), r.pixels))
            .collect();
        assert_eq!(
            names,
            [("bulb", "b", 1), ("lamp", "a", 3), ("lamp", "b", 1)]
        );
        // A dark light has no ratio: it cannot be off by a factor.
        assert_eq!(readings[0].ratio, [None; 3]);
        assert_eq!(readings[1].measured, [12.0, 21.0, 31.0]);
        assert_eq!(
            readings[1].ratio,
            [Some(12.0 / 11.0), Some(21.0 / 20.0), Some(1.0)]
        );
        assert_eq!(readings[2].ratio[0], Some(24.0 / 11.0));
    }

    /// Told only where no pixel is interior to a light and some lie wholly on one, with
    /// the (view, light) holding the most.
    #[test]
    fn a_light_seen_only_beside_its_edge_says_why_the_calibration_is_unchecked() {
        let lights = ["bulb".to_string(), "lamp".to_string()];
        let views = ["a".to_string(), "b".to_string()];
        let one_light = [pixel(1, 1, 1), pixel(1, 2, 1)];
        let text = unchecked_warning(&[], &one_light, &lights, &views).unwrap();
        assert!(
            text.contains("not checked")
                && text.contains(
                    "the 2 pixels that see light 'lamp' wholly, in view 'b', lie beside its edge"
                ),
            "{text}"
        );
        let two = [pixel(0, 1, 0), pixel(1, 1, 1), pixel(1, 2, 1)];
        let text = unchecked_warning(&[], &two, &lights, &views).unwrap();
        assert!(
            text.contains("the 3 pixels that see one wholly lie beside its edge (most, 2, light 'lamp' in view 'b')"),
            "{text}"
        );
        assert_eq!(
            unchecked_warning(&[pixel(0, 2, 0)], &two, &lights, &views),
            None
        );
        assert_eq!(unchecked_warning(&[], &[], &lights, &views), None);
    }

    #[test]
    fn readings_off_by_more_than_the_tolerance_are_warned_of_with_their_factor() {
        let reading = |ratio: [Option<f64>; 3]| LightReading {
            light: "lamp".into(),
            view: "up".into(),
            pixels: 7,
            declared: [1.0; 3],
            measured: ratio.map(|q| q.unwrap_or(0.0)),
            ratio,
        };
        let within = 1.0 + 0.9 * CALIBRATION_TOLERANCE;
        let beyond = 1.0 - 1.1 * CALIBRATION_TOLERANCE;
        let warnings = calibration_warnings(
            &[
                reading([Some(within), Some(1.0), Some(2.0 - within)]),
                reading([None; 3]),
                reading([Some(1.0), Some(beyond), None]),
                reading([Some(2.0), Some(2.0), Some(2.0)]),
            ],
            &[Vec3::ONE],
        );
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(warnings[0].contains(
            "reads 0.978x its declared radiance in view 'up' (R G B 1.000 0.978 - over 7 pixels"
        ));
        assert!(warnings[0].contains(CLASSES_UNDER_A_DARK_PANORAMA));
        assert!(warnings[0].contains("can also be a light clipped in the capture"));
        assert!(warnings[1].contains("reads 2.000x"), "{}", warnings[1]);
        assert!(warnings[1].contains("exposure or the light's radiance"));
        assert!(warnings[1].contains(CLASSES_UNDER_A_BRIGHT_PANORAMA));
        assert!(!warnings[1].contains("clipped"));
    }

    #[test]
    fn view_readings_sum_each_views_pure_pixels() {
        let real = [image(2, 2, [1.0; 3]), image(2, 2, [2.0, 2.0, 5.0])];
        let mut renders = vec![vec![Vec3::splat(1.1); 4], vec![Vec3::splat(3.0); 4]];
        renders[0][3] = Vec3::splat(1.3);
        let pure = |view: u32, x: u32| PurePixel {
            view,
            x,
            y: 1,
            group: 0,
        };
        let readings = read_views(
            &[pure(0, 0), pure(0, 1), pure(1, 1)],
            &real,
            &renders,
            &["a".into(), "b".into(), "c".into()],
        );
        assert_eq!(readings.len(), 3);
        assert_eq!(readings[0].pure_pixels, 2);
        // Channels summed: the panorama 3 and 3, the render 3.3 and 3.9.
        assert!((readings[0].rel_mean_diff.unwrap() - 0.2).abs() < 1e-6);
        // Differences 0.3 and 0.9: a sample deviation of 0.42, over sqrt(2) pixels and the
        // panorama's mean 3.
        assert!((readings[0].rel_mean_diff_sigma.unwrap() - 0.1).abs() < 1e-6);
        assert_eq!(readings[1].panorama_mean, 3.0);
        assert_eq!(readings[1].rel_mean_diff, Some(0.0));
        // One pixel has no spread to measure, and no pixel no residual to compare.
        assert_eq!(readings[1].rel_mean_diff_sigma, None);
        assert_eq!(readings[2].rel_mean_diff, None);
    }

    #[test]
    fn a_view_off_the_others_median_is_warned_of_with_its_factor() {
        let reading = |view: &str, pixels: u32, diff: f64| ViewReading {
            view: view.into(),
            pure_pixels: pixels,
            panorama_mean: 1.0,
            render_mean: 1.0 + diff,
            rel_mean_diff: Some(diff),
            rel_mean_diff_sigma: Some(0.002),
        };
        let agreeing = [
            reading("px", 4000, 0.003),
            reading("nx", 4000, 0.008),
            reading("py", 4000, -0.004),
        ];
        assert!(view_warnings(&agreeing, ImageHeaders::NONE).is_empty());
        // One view 5% too bright in the panorama: its render reads 3% under it.
        let mut readings = agreeing.to_vec();
        readings.push(reading("pz", 4000, -0.03 + 0.003));
        // A view of few pixels is neither warned of nor part of the others' median.
        readings.push(reading("nz", MIN_VIEW_PIXELS - 1, 0.5));
        let warnings = view_warnings(&readings, ImageHeaders::NONE);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].starts_with("view 'pz'")
                && warnings[0].contains("-2.7% (+- 0.2%) off the panorama")
                && warnings[0].contains("median is +0.3%")
                && warnings[0].contains("about 1.031x"),
            "{}",
            warnings[0]
        );
        // A view off the others by more than a factor of 2 is warned of at any size, in
        // ratios: one of few pixels whose panorama is a 1000th of what the others'
        // calibration gives, and a large one whose exposure was given as 1e-30 (which read
        // +4e31% in percent).
        let gross = [
            (
                "tiny",
                40,
                999.0,
                ["1.000e3x the panorama", "about 1.003e-3x"],
            ),
            (
                "dim",
                4000,
                4.0e29,
                ["4000 pure pixels 4.000e29x", "about 2.508e-30x"],
            ),
        ];
        for (name, pixels, diff, says) in gross {
            readings.push(reading(name, pixels, diff));
            let warnings = view_warnings(&readings, ImageHeaders::NONE);
            assert_eq!(warnings.len(), 2, "{warnings:?}");
            let w = &warnings[1];
            assert!(
                w.starts_with(&format!("view '{name}'"))
                    && w.contains("median is 1.003x")
                    && says.iter().all(|s| w.contains(s))
                    && !w.contains('%'),
                "{w}"
            );
            readings.pop();
        }
        // A view black in the panorama where the others are lit is told at any size,
        // without a median: it has no ratio to compare.
        for others in [&readings[..], &readings[..1]] {
            let mut with_black = others.to_vec();
            with_black.push(ViewReading {
                rel_mean_diff: None,
                rel_mean_diff_sigma: None,
                ..reading("black", 12, 0.0)
            });
            with_black.last_mut().unwrap().panorama_mean = 0.0;
            let warnings = view_warnings(&with_black, ImageHeaders::NONE);
            let black: Vec<&String> = warnings.iter().filter(|w| w.contains("'black'")).collect();
            assert!(
                black.len() == 1
                    && black[0].contains("its 12 pure pixels are all 0 in the panorama"),
                "{warnings:?}"
            );
            // A header that divided the view's values is named where it is blamed.
            let names: Vec<String> = with_black.iter().map(|r| r.view.clone()).collect();
            let mut divisors = vec![None; names.len()];
            *divisors.last_mut().unwrap() = Some([1e300; 3]);
            let headers = ImageHeaders {
                views: &names,
                divisors: &divisors,
            };
            let told = view_warnings(&with_black, headers);
            let note = "its exposure off, its header's EXPOSURE and COLORCORR dividing its stored values by 1e300 (";
            for w in &told {
                assert_eq!(w.contains(note), w.contains("'black'"), "{told:?}");
            }
            assert_eq!(told.len(), warnings.len(), "{told:?}");
            // Where the model renders it black too, it agrees with its panorama.
            with_black.last_mut().unwrap().render_mean = 0.0;
            assert!(!view_warnings(&with_black, ImageHeaders::NONE)
                .iter()
                .any(|w| w.contains("'black'")));
        }
        // A gross difference within VIEW_SIGMAS of the view's own standard error is one
        // pixel's heavy tail, not an exposure.
        let mut tail = reading("tail", 60, 21.7);
        tail.rel_mean_diff_sigma = Some(16.1);
        readings.push(tail);
        assert_eq!(view_warnings(&readings, ImageHeaders::NONE).len(), 1);
        readings.last_mut().unwrap().rel_mean_diff_sigma = Some(1.0);
        let warnings = view_warnings(&readings, ImageHeaders::NONE);
        assert!(warnings[1].starts_with("view 'tail'"), "{warnings:?}");
        readings.pop();
        // With one other view there is no median to trust.
        assert!(view_warnings(&readings[2..4], ImageHeaders::NONE).is_empty());
        // Nor is a difference within three of the view's standard errors a finding.
        readings[3].rel_mean_diff_sigma = Some(0.011);
        assert!(view_warnings(&readings, ImageHeaders::NONE).is_empty());
    }

    /// A view's reading of `pure_pixels` whose panorama and render means are as given,
    /// measured to a standard error of 0.05%.
    fn view_reading(view: &str, pure_pixels: u32, panorama: f64, render: f64) -> ViewReading {
        ViewReading {
            view: view.into(),
            pure_pixels,
            panorama_mean: panorama,
            render_mean: render,
            rel_mean_diff: Some((render - panorama) / panorama),
            rel_mean_diff_sigma: Some(0.0005),
        }
    }

    /// Nor is a view the model renders black part of the others' median: with two lit
    /// views beside it, each read the other's residual and its -100% averaged, a median
    /// of -50%, and both were told their exposure may be off by about 0.5x.
    #[test]
    fn a_view_the_model_renders_black_is_not_in_the_others_median() {
        let reading =
            |view: &str, panorama: f64, render: f64| view_reading(view, 1024, panorama, render);
        let readings = [
            reading("floor", 0.2195, 0.2193),
            reading("floor2", 0.2226, 0.2226),
            reading("cellar", 0.05, 0.0),
        ];
        for warnings in [
            view_warnings(&readings, ImageHeaders::NONE),
            preview_view_warnings(&readings, ImageHeaders::NONE),
        ] {
            assert!(
                warnings.len() == 1 && warnings[0].starts_with("view 'cellar'"),
                "{warnings:?}"
            );
        }
    }

    /// A view gross against the large views is told, whatever the small ones read: the
    /// 2% test left out such a view (its factor past VIEW_GROSS_FACTOR against the large
    /// views' median), while the gross test took its median over every view, which small
    /// views reading -45% pulled to 0.55: 0.4 against it is 1.4x, and no one told of a
    /// view off 2.5x against the views that count.
    #[test]
    fn a_view_gross_against_the_large_views_is_told_whatever_the_small_ones_read() {
        let reading = |view: &str, pure_pixels: u32, diff: f64| {
            view_reading(view, pure_pixels, 0.2, 0.2 * (1.0 + diff))
        };
        let mut readings = vec![
            reading("a", 1024, 0.0),
            reading("b", 1024, 0.0),
            reading("c", 1024, -0.6),
        ];
        readings.extend((0..4).map(|k| reading(&format!("small{k}"), 10, -0.45)));
        let warnings = view_warnings(&readings, ImageHeaders::NONE);
        let told_c: Vec<&String> = warnings
            .iter()
            .filter(|w| w.starts_with("view 'c'"))
            .collect();
        assert_eq!(told_c.len(), 1, "{warnings:?}");
        assert!(told_c[0].contains("2.500x"), "{}", told_c[0]);
    }

    /// A view whose pure pixels the model renders black (all on a group no light of the
    /// scene reaches) where its panorama is not has no factor to give: the panorama over
    /// a black render is infinite. It read "0.000e0x the panorama ... off by about infx"
    /// (a cellar under a lit floor, seen by its own view of four, its panorama 0.05).
    #[test]
    fn a_view_the_model_renders_black_is_told_without_an_infinite_factor() {
        let reading =
            |view: &str, panorama: f64, render: f64| view_reading(view, 1024, panorama, render);
        let readings = [
            reading("floor", 0.2195, 0.2193),
            reading("floor2", 0.2226, 0.2226),
            reading("floor3", 0.2287, 0.2288),
            reading("cellar", 0.05, 0.0),
        ];
        for warnings in [
            view_warnings(&readings, ImageHeaders::NONE),
            preview_view_warnings(&readings, ImageHeaders::NONE),
        ] {
            assert_eq!(warnings.len(), 1, "{warnings:?}");
            let w = &warnings[0];
            assert!(
                w.starts_with("view 'cellar'")
                    && w.contains("its 1024 pure pixels black, where the panorama's mean over them is 5.000e-2")
                    && !w.contains("inf")
                    && !w.contains("NaN"),
                "{w}"
            );
        }
    }

    #[test]
    fn a_light_declared_dark_is_warned_of_only_when_it_reads_bright() {
        let dark = |measured: [f64; 3]| LightReading {
            light: "bulb".into(),
            view: "down".into(),
            pixels: 3,
            declared: [0.0; 3],
            measured,
            ratio: [None; 3],
        };
        let brightest = 50.0;
        let lights = [Vec3::ZERO, Vec3::new(20.0, brightest as f32, 30.0)];
        let lit = [0.5, 1.2 * DARK_LIGHT_LIT * brightest, 0.5];
        let warnings = calibration_warnings(
            &[
                dark([0.2, 0.3, 0.2]),
                dark(lit),
                dark([0.9 * DARK_LIGHT_LIT * brightest; 3]),
            ],
            &lights,
        );
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains("light 'bulb' is declared dark")
                && warnings[0].contains("in view 'down'")
                && warnings[0].contains("12% of the brightest"),
            "{}",
            warnings[0]
        );
        // With no light declared bright there is nothing to measure against.
        assert!(calibration_warnings(&[dark(lit)], &[Vec3::ZERO]).is_empty());
    }

    /// A light's back that reads a tenth of its radiance or more shines, and is warned
    /// of; below that it may be a lamp's housing lit by the room, and a light declared
    /// dark has no radiance to compare with.
    #[test]
    fn a_lights_back_is_warned_of_only_when_it_reads_near_its_radiance() {
        let back = |declared: [f64; 3], measured: [f64; 3]| LightReading {
            light: "lamp".into(),
            view: "up".into(),
            pixels: 9,
            declared,
            measured,
            ratio: std::array::from_fn(|c| (declared[c] > 0.0).then(|| measured[c] / declared[c])),
        };
        let declared = [20.0, 10.0, 5.0];
        let warnings = facing_away_warnings(&[
            back(declared, [19.0, 9.5, 4.8]),
            back(declared, [0.9 * DARK_LIGHT_LIT * 20.0; 3]),
            back([0.0; 3], [5.0; 3]),
        ]);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains("light 'lamp' is seen from behind in view 'up' (9 pixels")
                && warnings[0].contains("reads 0.950x its declared radiance"),
            "{}",
            warnings[0]
        );
    }

    /// A light declared dark in one channel that reads bright there is told (its ratio is
    /// undefined, and the reading said "-"); one dim there, as a lamp's glass may be, is
    /// not. A factor past what three decimals show takes an exponent.
    #[test]
    fn a_channel_declared_dark_that_reads_bright_is_told() {
        let yellow = |measured: [f64; 3]| LightReading {
            light: "light".into(),
            view: "pz".into(),
            pixels: 64,
            declared: [30.0, 28.0, 0.0],
            measured,
            ratio: [Some(measured[0] / 30.0), Some(measured[1] / 28.0), None],
        };
        let lights = [Vec3::new(30.0, 28.0, 0.0)];
        let warnings = calibration_warnings(&[yellow([30.0, 28.0, 24.0])], &lights);
        assert_eq!(
            warnings,
            ["light 'light' is declared 0 in channel B but reads 24 there in view 'pz' over 64 pixels wholly inside it, 80% of the brightest light's radiance: is its radiance declared right?"]
        );
        assert!(calibration_warnings(&[yellow([30.0, 28.0, 0.5])], &lights).is_empty());
        assert_eq!(factor_text(0.978), "0.978");
        assert_eq!(factor_text(2.4e31), "2.400e31");
        assert_eq!(factor_text(1e-7), "1.000e-7");
    }
}
