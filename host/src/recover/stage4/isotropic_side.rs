//! The isotropic side of stage 4's decision: the best isotropic (or diffuse) explanation
//! an anisotropic fit must beat, and the model kept if it loses; for kind "auto", stage 2's
//! metal once more.

use relume_core::fit;
use relume_core::material::Kind;

use super::super::cache::{self, GroupCache};
use super::super::kind;
use super::super::model::GroupModel;
use super::super::refine::RACE_SIGNIFICANCE;
use super::super::{anisotropic, fit_ward, fit_ward_by, uncertainty, GroupReport, Recovery};
use super::gate::{levelled_colour, Levelled};
use super::{IsotropicSide, Searched, Stage};
use crate::error::Error;
use crate::scene_file::GroupKind;

/// What an isotropic alternative to a group's isotropic model (or diffuse one) is worth.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Alternative {
    /// No better: the rival stands.
    Worse,
    /// Better, but not by enough to replace the model kept: only the rival the
    /// anisotropic fit must beat.
    Rival,
    /// Better by enough to replace the model kept, too.
    Replaces,
}

/// The worth of an isotropic alternative to `rival` by their comparison `c`. Against a
/// diffuse rival it needs what stage 2's lobes need (and `explains_highlight`, a picture's
/// pattern test); against an isotropic one any gain makes it the rival, and a gain at
/// `RACE_SIGNIFICANCE` replaces the model kept.
fn isotropic_alternative(
    rival: &GroupModel,
    c: &fit::ModelComparison,
    explains_highlight: impl FnOnce() -> bool,
) -> Alternative {
    match rival {
        GroupModel::Diffuse { .. } if c.favours_complex() && explains_highlight() => {
            Alternative::Replaces
        }
        GroupModel::Diffuse { .. } => Alternative::Worse,
        _ if c.gain > 0.0 && c.z() >= RACE_SIGNIFICANCE => Alternative::Replaces,
        _ if c.gain > 0.0 => Alternative::Rival,
        _ => Alternative::Worse,
    }
}

/// Records that group `g`'s isotropic lobe (`kind`, `specularity`, `roughness`) is one
/// of stage 4's cache's fits: its spread is that cache's proposal's, not stage 2's
/// ladder's.
pub(super) fn lobe_of_this_cache(
    report: &mut GroupReport,
    rec: &Recovery,
    cache: &GroupCache,
    kind: Kind,
    specularity: f64,
    roughness: f64,
) {
    report.lobe_from_ladder = false;
    report.lobe_sigmas = Vec::from(uncertainty::proposal_size_dependence(
        &rec.pool,
        cache,
        kind,
        specularity,
        roughness,
    ));
}

impl Stage<'_> {
    /// The isotropic side, from `start`: stage 2's fit, unless one of this cache's
    /// isotropic fits (the scene's other materials are better known now) or the
    /// anisotropic fit's own shadow (roughness sqrt(u v)) measures better. The anisotropic
    /// fit is weighed against the better of them (`rival`) however slight its edge, so
    /// that it wins only over the best isotropic explanation; but if it loses, the
    /// isotropic model kept (`kept`) changes only when a render shows the alternative
    /// better at `RACE_SIGNIFICANCE`, as the race's incumbent does: glossy's steel box on
    /// seed 4 took the shadow's s 0.80, roughness 0.086 (truth 0.95, 0.14) over stage 2's
    /// 0.90, 0.10 on a gain of 0.0015 +- 0.0020.
    pub(super) fn isotropic_side(
        &self,
        rec: &mut Recovery,
        r: &mut GroupReport,
        searched: &Searched,
        start: IsotropicSide,
        anisotropic_fit: GroupModel,
    ) -> Result<IsotropicFits, Error> {
        let Searched {
            g,
            cache,
            kind,
            pictured,
        } = *searched;
        let mut evaluations = 0;
        let (iso, alpha, n) = fit_ward(&rec.pool, cache, kind);
        evaluations += n;
        let on_cache = GroupModel::Isotropic {
            kind,
            color: iso.color,
            specularity: iso.specularity,
            roughness: alpha,
        };
        // The same fit on the sums across two halves of each pixel's samples: free of the
        // dilution the samples' noise puts into the plain sums (which trades specularity
        // for a sharper lobe), but no sum of squares, so where a lobe is weak it can run
        // to a bound; only ever a challenger, which a render must show better. Glossy's
        // steel box on seed 4 (64 px): the plain fit s 0.80, roughness 0.087, this one
        // 0.92, 0.113 at z 4.8 over it (truth 0.95, 0.14).
        let (across, across_alpha, n) =
            fit_ward_by(|alpha| cache::isotropic_fit_across_halves(&rec.pool, cache, kind, alpha));
        evaluations += n;
        let across_halves = (across.specularity > 0.0 && across.specularity <= 1.0).then_some(
            GroupModel::Isotropic {
                kind,
                color: across.color,
                specularity: across.specularity,
                roughness: across_alpha,
            },
        );
        let mut side = start;
        for (what, alternative) in [
            ("the isotropic fit on this cache", Some(on_cache)),
            (
                "the isotropic fit across the halves of this cache's samples",
                across_halves,
            ),
            (
                "the anisotropic fit's isotropic shadow",
                anisotropic::isotropic_projection(anisotropic_fit),
            ),
        ] {
            // A fit of no lobe (specularity 0) is the diffuse model of its colour.
            let Some(alternative) = alternative.filter(GroupModel::has_lobe) else {
                continue;
            };
            let Some((c, spp)) = rec.compare_models(
                g,
                (side.rival, alternative),
                4 * self.verify_spp,
                &mut evaluations,
            )?
            else {
                continue;
            };
            // Between two isotropic fits the better one; a group stage 2 left diffuse
            // takes a lobe here only as stage 2 would have kept one (significance).
            // A picture's lobe must also explain a highlight rather than the picture.
            let verdict = isotropic_alternative(&side.rival, &c, || {
                pictured
                    .and_then(|p| p.isotropic(&rec.pool, kind))
                    .is_none_or(|t| t.passes())
            });
            if verdict == Alternative::Worse {
                continue;
            }
            let measured = format!(
                "{what} measures better than the {} model: it removes {:.4} +- {:.4} more relative error in a render at {spp} spp (z {:.1})",
                side.rival.name(),
                c.gain,
                c.gain_sigma,
                c.z()
            );
            side.rival = alternative;
            let decision = match (verdict, alternative) {
                (
                    Alternative::Replaces,
                    GroupModel::Isotropic {
                        specularity,
                        roughness,
                        ..
                    },
                ) => {
                    side.kept = alternative;
                    side.replaced = true;
                    format!("stage 4: {measured}, and replaces it (s {specularity:.4}, roughness {roughness:.4})")
                }
                _ => format!(
                    "stage 4: {measured}: the anisotropic fit is weighed against it, but short of RACE_SIGNIFICANCE {RACE_SIGNIFICANCE} it does not replace the model kept"
                ),
            };
            r.decisions.push(decision);
        }
        Ok(IsotropicFits {
            side,
            error: iso.relative_error,
            evaluations,
        })
    }

    /// Kind "auto": a plastic lobe whose group came on to this stage (more than
    /// DIFFUSE_THRESHOLD of error left) may be a metal's highlight that stage 2 could not
    /// tell apart on its proposals, whose colours were fitted under the scene as it was
    /// then (glossy's steel box: 10% bright). So the metal stage 2 passed over, its colour
    /// levelled, is weighed against `kept` once more (`kind::choose_again`, with the
    /// cache's `plastic_error` beside the metal's). `None` where that does not apply, else
    /// the metal when it is chosen, and the evaluations spent.
    pub(super) fn metal_again(
        &self,
        rec: &mut Recovery,
        r: &mut GroupReport,
        g: usize,
        cache: &GroupCache,
        kept: GroupModel,
        plastic_error: f64,
    ) -> Result<Option<(Option<GroupModel>, u32)>, Error> {
        let (
            GroupKind::Auto,
            false,
            GroupModel::Isotropic {
                kind: Kind::Plastic,
                ..
            },
            Some(GroupModel::Isotropic {
                kind: Kind::Metal,
                color,
                specularity,
                roughness,
            }),
        ) = (self.kinds[g], self.textured[g], kept, r.metal_passed_over)
        else {
            return Ok(None);
        };
        let mut evaluations = 0;
        let (metal_fit, _, n) = fit_ward(&rec.pool, cache, Kind::Metal);
        evaluations += n;
        let metal = |color| GroupModel::Isotropic {
            kind: Kind::Metal,
            color,
            specularity,
            roughness,
        };
        let Levelled {
            color: levelled,
            said: levelling,
            ..
        } = levelled_colour(
            rec,
            g,
            metal(color),
            color,
            (self.verify_spp, r.pure_pixels),
        )?;
        evaluations += 1;
        let levelled_by = format!("its colour {levelling}");
        let (chosen, n) = kind::choose_again(
            rec,
            g,
            (kept, metal(levelled)),
            [plastic_error, metal_fit.relative_error],
            (4 * self.verify_spp, &levelled_by),
            r,
        )?;
        Ok(Some((chosen, evaluations + n)))
    }
}

/// The isotropic side a stage-4 search found ([`Stage::isotropic_side`]).
pub(super) struct IsotropicFits {
    pub(super) side: IsotropicSide,
    /// The relative error of the isotropic fit on the cache, of the kind searched.
    pub(super) error: f64,
    pub(super) evaluations: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A comparison of errors 0.1 and `0.1 - gain`, its squared gain and sigma consistent.
    fn comparison(gain: f64, gain_sigma: f64) -> fit::ModelComparison {
        let (simple, complex) = (0.1, 0.1 - gain);
        fit::ModelComparison {
            pixels: 400,
            error_simple: simple,
            error_complex: complex,
            squared_sigma_simple: 0.0,
            squared_sigma_complex: 0.0,
            gain,
            gain_sigma,
            squared_gain: simple * simple - complex * complex,
            squared_gain_sigma: gain_sigma * (simple + complex),
        }
    }

    #[test]
    fn an_isotropic_alternative_replaces_the_model_kept_only_at_race_significance() {
        let lobe = GroupModel::Isotropic {
            kind: Kind::Metal,
            color: [0.6; 3],
            specularity: 0.9,
            roughness: 0.1,
        };
        // Glossy's steel box on seed 4: 0.0015 +- 0.0020 made the shadow the rival only.
        let noise = comparison(0.0015, 0.0020);
        assert_eq!(
            isotropic_alternative(&lobe, &noise, || true),
            Alternative::Rival
        );
        let clear = comparison(0.0850, 0.0109);
        assert_eq!(
            isotropic_alternative(&lobe, &clear, || true),
            Alternative::Replaces
        );
        let worse = comparison(-0.001, 0.002);
        assert_eq!(
            isotropic_alternative(&lobe, &worse, || true),
            Alternative::Worse
        );

        // A diffuse group takes a lobe only as stage 2 would, and a picture's lobe only
        // where it explains a highlight.
        let diffuse = GroupModel::Diffuse { color: [0.5; 3] };
        assert_eq!(
            isotropic_alternative(&diffuse, &noise, || true),
            Alternative::Worse
        );
        assert_eq!(
            isotropic_alternative(&diffuse, &clear, || true),
            Alternative::Replaces
        );
        assert_eq!(
            isotropic_alternative(&diffuse, &clear, || false),
            Alternative::Worse
        );
    }
}
