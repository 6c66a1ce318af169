//! Stage 5: the diffuse map of every textured group, `T = (I_real - I_specular) / E`,
//! under its stand-in's lobe (none, stage 2's isotropic or stage 4's anisotropic one),
//! with E from the full global illumination of the scene as now known (`texture`).

use std::time::Instant;

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
) -> Result<StageReport, Error> {
    let stage_start = Instant::now();
    let mut evaluations = 0;
    for g in (0..rec.n_groups()).filter(|&g| textured[g]) {
        let standin = rec.models[g];
        let summary = texture::recover_map(rec, g, map_spp, seed)?;
        evaluations += 2;
        reports[g].decisions.push(format!(
            "stage 5: {} map {}x{} from {} pixels (T = (I_real - I_specular) / E under the {} stand-in's lobe); {} highlight and {} shadow pixels removed, {} texels unseen and filled from neighbours",
            rec.models[g].name(),
            summary.side,
            summary.side,
            summary.pixels,
            standin.name(),
            summary.highlights,
            summary.shadows,
            summary.unseen_texels
        ));
    }
    Ok(StageReport {
        stage: "5 diffuse maps".into(),
        evaluations,
        samples_per_pixel: map_spp,
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![
            "textured groups: maps solved by least squares at about one texel per pure pixel, under the untextured stand-in's lobe".into(),
        ],
    })
}
