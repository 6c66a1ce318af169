//! `relume check`: the input's checks alone, and a preview of stage 1 at a few samples (each
//! group's first diffuse colour, and whether light reaches it).

use std::path::Path;
use std::time::Instant;

use serde::Serialize;

use super::{inspect, read, Inspection};
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::parallel;
use crate::recover::calibration::{self, LightReading, ViewReading};
use crate::recover::model::GroupModel;
use crate::recover::orientation::OrientationReading;
use crate::recover::pixels::{self, PurePixel};
use crate::recover::{stage1, warnings, Recovery};

/// One group as the panorama sees it.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct GroupSight {
    pub group: String,
    pub kind: String,
    /// Its pure pixels in each view, in the scene's order of views.
    pub pure_pixels: Vec<u32>,
    /// Its diffuse colour after stage 1's iteration at `PREVIEW_SPP` samples per pixel:
    /// a first reading, before any lobe is tried (`null` where no pixel sees the group or
    /// no light reaches it).
    pub preview_colour: Option<[f64; 3]>,
}

impl GroupSight {
    pub fn total(&self) -> u32 {
        self.pure_pixels.iter().sum()
    }
}

/// What `relume check` found.
#[derive(Serialize, Clone, Debug)]
pub struct CheckReport {
    pub views: Vec<String>,
    pub groups: Vec<GroupSight>,
    pub light_readings: Vec<LightReading>,
    pub orientation_readings: Vec<OrientationReading>,
    /// The warnings `relume recover` would print before its work, and those of its input
    /// that it prints after: a group that no view sees whole, views too small.
    pub warnings: Vec<String>,
    /// The groups seen, but in fewer than `warnings::FEW_PIXELS` pure pixels: a lobe
    /// recovered on them was seen to change with the seed.
    pub few_pixels: Vec<(String, u32)>,
    /// The groups whose texture coordinates no map can be laid over, and why
    /// (`coordinates_unfit_for_a_map`): a texture they show is told, not mapped.
    pub unfit_for_a_map: Vec<(String, String)>,
    /// The groups whose texture coordinates reach past [0, 1], and their span: a texture
    /// is tiled over them, and a map recovered for one repeats.
    pub tiled: Vec<(String, String)>,
    /// Each view's pixels of the preview rendered under its colours against the
    /// panorama: a view off the others by more than `VIEW_GROSS_FACTOR` is warned of.
    pub view_readings: Vec<ViewReading>,
    /// Samples per pixel of the colours' preview, and the renders it took.
    pub preview_spp: u32,
    pub preview_renders: u32,
    pub seconds: f64,
}

/// Samples per pixel of `relume check`'s preview of stage 1. At 4, on at most
/// [`PREVIEW_GROUP_PIXELS`] a group, the references' diffuse groups at 256 px read within
/// 6% of their true colours (the living room's floor +3%, its pedestal +5%: the glossy
/// groups around them taken for diffuse), in 1.0 s on 2 cores (0.3 s without it).
pub const PREVIEW_SPP: u32 = 4;

/// Pixels of each group (at most, spread over it) that `relume check`'s preview renders.
pub(super) const PREVIEW_GROUP_PIXELS: usize = 2048;

/// The seed of `relume check`'s preview: check takes none, and its findings are the same
/// from run to run.
pub(super) const PREVIEW_SEED: u64 = 0xC4EC_0001;

/// Each view's reading under the preview's colours: its pixels of the preview rendered
/// again (one render per view with pixels, at the preview's samples and seed) against the
/// panorama; and the renders that took.
pub(super) fn preview_view_readings(
    rec: &mut Recovery,
    view_names: &[String],
) -> Result<(Vec<ViewReading>, u32), Error> {
    let mut readings = Vec::with_capacity(view_names.len());
    let mut renders = 0;
    for (v, name) in view_names.iter().enumerate() {
        let pixels: Vec<PurePixel> = rec
            .pure
            .iter()
            .filter(|p| p.view as usize == v)
            .copied()
            .collect();
        let fits = match pixels.is_empty() {
            true => Vec::new(),
            false => {
                renders += 1;
                rec.evaluate_pixels(&pixels, PREVIEW_SPP, rec.seed, &|_| true)?
            }
        };
        readings.push(calibration::read_view_fits(name, &fits));
    }
    Ok((readings, renders))
}

/// The input checks of `relume recover` and a preview of its first stage: each group's
/// diffuse colour at a few samples per pixel, and whether light reaches it. No output but
/// `json` if given (the report as JSON, which may replace none of the run's inputs).
pub fn check(
    scene: &Path,
    threads: Option<usize>,
    json: Option<&Path>,
) -> Result<CheckReport, Error> {
    let start = Instant::now();
    let mut input = read(scene)?;
    let mut set = OutputSet::keeping(std::mem::take(&mut input.inputs));
    if let Some(path) = json {
        set.check_target(path)?;
    }
    let pool = parallel::thread_pool(threads)?;
    let Inspection {
        pure,
        light_readings,
        orientation_readings,
        mut warnings,
    } = inspect(scene, &pool, &mut input)?;
    let n_views = input.view_names.len();
    let mut groups: Vec<GroupSight> = input
        .owned
        .group_names
        .iter()
        .zip(&input.kinds)
        .map(|(name, kind)| GroupSight {
            group: name.clone(),
            kind: format!("{kind:?}").to_lowercase(),
            pure_pixels: vec![0; n_views],
            preview_colour: None,
        })
        .collect();
    for p in &pure {
        groups[p.group as usize].pure_pixels[p.view as usize] += 1;
    }
    let mut rec = Recovery {
        views: input.owned.views.clone(),
        models: vec![
            GroupModel::Diffuse {
                color: [crate::recover::START_COLOR; 3]
            };
            groups.len()
        ],
        owned: input.owned,
        real: input.real,
        // A group's mean over a few thousand pixels is as good a first reading as over all.
        pure: pixels::spread_subset(&pure, groups.len(), PREVIEW_GROUP_PIXELS),
        maps: Vec::new(),
        pool: std::sync::Arc::new(pool),
        seed: PREVIEW_SEED,
        terms_memo: Default::default(),
        started: start,
    };
    let names = rec.owned.group_names.clone();
    let preview = stage1::preview_light(&mut rec, &names, PREVIEW_SPP)?;
    for (g, colour) in groups.iter_mut().zip(preview.colours) {
        g.preview_colour = colour;
    }
    warnings.extend(preview.warnings);
    let (view_readings, view_renders) = preview_view_readings(&mut rec, &input.view_names)?;
    warnings.extend(calibration::preview_view_warnings(
        &view_readings,
        calibration::ImageHeaders {
            views: &input.view_names,
            divisors: &input.header_divisors,
        },
    ));
    // A group all hidden, or of no area, was told of by `inspect`, with its cause.
    let hidden = |g: &&GroupSight| {
        let at = names.iter().position(|n| *n == g.group);
        at.is_some_and(|i| input.hidden[i] || input.no_area[i])
    };
    for g in groups.iter().filter(|g| g.total() == 0 && !hidden(g)) {
        warnings.push(format!(
            "group '{}': no pure pixel in any view; recover will not recover its material",
            g.group
        ));
    }
    let sides: Vec<(String, u32)> = (input.view_names.iter().cloned())
        .zip(rec.views.iter().map(|v| v.width.min(v.height)))
        .collect();
    warnings.extend(warnings::small_views(&sides));
    let few_pixels = groups
        .iter()
        .filter(|g| (1..warnings::FEW_PIXELS).contains(&g.total()))
        .map(|g| (g.group.clone(), g.total()))
        .collect();
    let unfit_for_a_map = (names.iter().zip(&input.unfit_for_a_map))
        .filter_map(|(name, why)| Some((name.clone(), why.clone()?)))
        .collect();
    let tiled = (names.iter().zip(&input.tiled))
        .filter_map(|(name, span)| Some((name.clone(), span.clone()?)))
        .collect();
    let report = CheckReport {
        views: input.view_names,
        groups,
        light_readings,
        orientation_readings,
        warnings,
        few_pixels,
        unfit_for_a_map,
        tiled,
        view_readings,
        preview_spp: PREVIEW_SPP,
        preview_renders: preview.evaluations + view_renders,
        seconds: start.elapsed().as_secs_f64(),
    };
    if let Some(path) = json {
        let text =
            serde_json::to_string_pretty(&report).map_err(|e| Error::Usage(e.to_string()))?;
        set.add(path, text.as_bytes())?;
    }
    set.commit()?;
    Ok(report)
}
