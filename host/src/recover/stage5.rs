//! Stage 5: the diffuse map of every textured group, `T = (I_real - I_specular) / E`,
//! under its stand-in's lobe (none, stage 2's isotropic or stage 4's anisotropic one),
//! with E from the full global illumination of the scene as now known (`texture`).

use std::time::Instant;

use relume_core::render::RenderSettings;

use super::{texture, GroupReport, Recovery, StageReport};
use crate::error::Error;

/// Runs stage 5 on the `textured` groups (stage 3's) at `map_spp`, recording each map in
/// `reports`; each group's model becomes its textured model.
pub(super) fn run(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    textured: &[bool],
    map_spp: u32,
    seed: u64,
    cache_settings: &RenderSettings,
) -> Result<StageReport, Error> {
    let stage_start = Instant::now();
    let mut evaluations = 0;
    for g in (0..rec.n_groups()).filter(|&g| textured[g]) {
        let standin = rec.models[g];
        let summary = texture::recover_map(rec, g, map_spp, seed, cache_settings)?;
        evaluations += 2;
        if let Some(r) = summary.lobe_refit {
            reports[g].decisions.push(format!(
                "stage 5: the stand-in's lobe fitted again with a first map, on the {} highlight pixels of the group's cache (where the map was filled from neighbours, not solved): specularity {:.4} -> {:.4}, roughness {:.4} -> {:.4}, squared residual {:.5} -> {:.5}",
                r.pixels, r.before[0], r.after[0], r.before[1], r.after[1], r.sse_before, r.sse_after
            ));
        }
        let lobe = match summary.lobe_refit {
            Some(_) => "the lobe refitted with the map".to_string(),
            None => format!("the {} stand-in's lobe", standin.name()),
        };
        reports[g].decisions.push(format!(
            "stage 5: {} map {}x{} from {} pure pixels and {} on its border (T = (I_real - I_specular) / E under {lobe}); {} shadow pixels left out, {} highlight pixels kept, {} texels unseen and filled from neighbours",
            rec.models[g].name(),
            summary.side,
            summary.side,
            summary.pixels,
            summary.border_pixels,
            summary.shadows,
            summary.highlights,
            summary.unseen_texels
        ));
    }
    Ok(StageReport {
        stage: "5 diffuse maps".into(),
        evaluations,
        samples_per_pixel: map_spp,
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![
            "textured groups: maps solved by least squares at two texels per pure pixel, from the pure pixels and those on the group's border, under the untextured stand-in's lobe".into(),
        ],
    })
}
