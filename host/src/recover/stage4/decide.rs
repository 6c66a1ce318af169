//! The end of stage 4 for a group: the anisotropic fit against the isotropic side, its
//! pattern test for a picture, and its shape against its own isotropic shadow.

use relume_core::fit;

use super::super::model::GroupModel;
use super::super::{anisotropic, keep_rule, ComparisonReport, GroupReport, Recovery};
use super::isotropic_side::lobe_of_this_cache;
use super::{IsotropicSide, Searched, Stage};
use crate::error::Error;

impl Stage<'_> {
    /// The decision between the isotropic side and the anisotropic fit `refined`, by their
    /// comparison `(c, decision_spp)` (a render at `decision_spp`): for a textured group the
    /// anisotropic gain must also come from a highlight, and a fit that beats the rival
    /// must also beat its own isotropic shadow. Sets the group's model where the decision
    /// changes it from `side.kept`, says why in `r`; returns the evaluations spent.
    pub(super) fn decide(
        &self,
        rec: &mut Recovery,
        r: &mut GroupReport,
        searched: &Searched,
        side: IsotropicSide,
        refined: GroupModel,
        (c, decision_spp): (fit::ModelComparison, u32),
    ) -> Result<u32, Error> {
        let Searched {
            g,
            cache,
            kind,
            pictured,
        } = *searched;
        let IsotropicSide { rival, kept, .. } = side;
        let mut evaluations = 0;
        // For a textured group, the anisotropic gain must also come from a highlight.
        let over_isotropic = matches!(rival, GroupModel::Isotropic { .. });
        let pattern = match (pictured, c.favours_complex()) {
            (Some(p), true) => p.anisotropic(&rec.pool, kind, over_isotropic),
            _ => None,
        };
        // An anisotropic fit that beats the rival must also beat its own isotropic shadow
        // (the same colour and specularity, the roughnesses' geometric mean): otherwise
        // its gain is the lobe's size and colour, not its shape (glossy's gold sphere at
        // 64 px, seed 4: roughness_u 0.0803 against roughness_v 0.0794, kept
        // anisotropic at z 7.1 over stage 2's lobe).
        let passes =
            c.favours_complex() && refined.has_lobe() && pattern.is_none_or(|t| t.passes());
        let shape = match anisotropic::isotropic_projection(refined) {
            Some(shadow) if passes => rec
                .compare_models(g, (shadow, refined), 4 * self.verify_spp, &mut evaluations)?
                .map(|(s, spp)| (shadow, s, spp)),
            _ => None,
        };
        let shape_shown = shape.is_none_or(|(_, s, _)| s.favours_complex());
        let mut report = ComparisonReport::new(
            "4 anisotropic",
            rival.name(),
            refined.name(),
            &c,
            decision_spp,
        );
        report.kept_complex &= passes && shape_shown;
        r.add_comparison(report, &c);
        if let Some((_, s, spp)) = shape {
            let mut report =
                ComparisonReport::new("4 anisotropic shape", "isotropic", "anisotropic", &s, spp);
            report.kept_complex &= shape_shown;
            r.add_comparison(report, &s);
        }
        let measured = format!(
            "accounts for {:.4} of relative error (removes {:.4} +- {:.4}) in a render at {decision_spp} spp (z {:.1}; {} {:.4}, anisotropic {:.4})",
            c.effect(),
            c.gain,
            c.gain_sigma,
            c.z(),
            rival.name(),
            c.error_simple,
            c.error_complex
        );
        if let Some(test) = pattern.filter(|t| !t.passes()) {
            r.anisotropic_turned_down = Some(refined);
            r.decisions.push(format!(
                "stage 4: stays {}: the anisotropic fit {measured}, but its gain follows the picture, not a highlight: {}",
                kept.name(),
                test.describe()
            ));
        } else if let (true, Some((shadow, s, spp))) = (passes && !shape_shown, shape) {
            let GroupModel::Isotropic {
                kind,
                specularity,
                roughness,
                ..
            } = shadow
            else {
                return Ok(evaluations);
            };
            r.decisions.push(format!(
                "stage 4: isotropic (s {specularity:.4}, roughness {roughness:.4}), the anisotropic fit's shadow: the anisotropic fit {measured}, but not for its shape: against its isotropic shadow it removes {:.4} +- {:.4} in a render at {spp} spp (z {:.1}; needs {})",
                s.gain,
                s.gain_sigma,
                s.z(),
                keep_rule(&s),
            ));
            rec.models[g] = shadow;
            r.set_decided(s.simple_estimate());
            lobe_of_this_cache(r, rec, cache, kind, specularity, roughness);
        } else if let (
            true,
            GroupModel::Anisotropic {
                roughness_u,
                roughness_v,
                direction: d,
                ..
            },
        ) = (passes, refined)
        {
            if let Some(test) = pattern {
                r.decisions.push(format!(
                    "stage 4: the anisotropic gain explains a highlight: {}",
                    test.describe()
                ));
            }
            let shape_said = shape.map_or(String::new(), |(_, s, spp)| {
                format!(
                    "; and for its shape: against its isotropic shadow it removes {:.4} +- {:.4} in a render at {spp} spp (z {:.1})",
                    s.gain,
                    s.gain_sigma,
                    s.z()
                )
            });
            r.decisions.push(format!(
                "stage 4: anisotropic (roughness_u {roughness_u:.4}, roughness_v {roughness_v:.4}, direction [{:.3}, {:.3}, {:.3}]) {measured}: {}{shape_said}",
                d[0], d[1], d[2],
                keep_rule(&c),
            ));
            rec.models[g] = refined;
            r.set_decided(c.complex_estimate());
        } else if c.favours_complex() && !refined.has_lobe() {
            r.decisions.push(format!(
                "stage 4: stays {}: the best anisotropic fit {measured}, but it has no lobe (specularity 0): its gain is its colour's, which the colour polish takes up",
                kept.name(),
            ));
        } else {
            r.decisions.push(format!(
                "stage 4: stays {}: the best anisotropic fit {measured}: needs {}",
                kept.name(),
                keep_rule(&c),
            ));
        }
        Ok(evaluations)
    }
}
