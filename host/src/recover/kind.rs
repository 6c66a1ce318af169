//! Kind "auto": which kind, plastic or metal, a group whose scene leaves it open is
//! fitted as (stages 2 and 4, and in stage 4 once more for a plastic lobe that still
//! leaves too much error, [`choose_again`]). Plastic is the simpler explanation (an uncoloured
//! highlight); metal is kept only where it is measurably better, by the rule every more
//! complex model passes. Chosen on the cache alone (a tie within 1e-4 to plastic),
//! glossy's yellow box at 64 px, seed 1, a plastic of s 0.1 whose broad highlight hardly
//! shows its colour, came out metal, its specular reflectance 23% off (3% with the kind
//! given). docs/recovery.md, "Kind auto".

use relume_core::fit;
use relume_core::material::Kind;

use super::model::GroupModel;
use super::report::{keep_rule, KindChoice};
use super::{ComparisonReport, GroupReport, Recovery};
use crate::error::Error;

/// The stage name of a kind comparison in report.json is the stage's number and this.
pub const KIND_COMPARISON: &str = "kind";

/// One kind's best fit of a group on its transport cache: its relative error there, the
/// model it proposes, and what the stage goes on with if it is chosen.
pub(super) struct KindFit<T> {
    pub kind: Kind,
    pub cache_error: f64,
    pub model: GroupModel,
    pub fit: T,
}

/// Of a group's cache fits, one per kind tried (plastic first), the one stage `stage`
/// goes on with, and the renders spent. One kind: its fit. Two: plastic, unless metal
/// accounts for more than `SPECULAR_GAIN_THRESHOLD` over it on the cache
/// (`fit::cache_effect`, whose fit takes in the cache's noise and reads more gain, not
/// less, than a render) and a render at `spp` then shows the metal proposal better by
/// the keep rule (`fit::ModelComparison::favours_complex`). The choice is a decision in
/// the report, the render a comparison of stage "`<stage>` kind", and the stage with the
/// two cache errors `kind_choice`.
pub(super) fn choose<T>(
    rec: &mut Recovery,
    g: usize,
    fits: Vec<KindFit<T>>,
    (stage, spp): (u32, u32),
    report: &mut GroupReport,
) -> Result<(Option<KindFit<T>>, u32), Error> {
    let mut fits = fits.into_iter();
    let (plastic, metal) = match (fits.next(), fits.next()) {
        (Some(plastic), Some(metal)) => (plastic, metal),
        (only, _) => return Ok((only, 0)),
    };
    debug_assert!(plastic.kind == Kind::Plastic && metal.kind == Kind::Metal);
    report.kind_choice = Some(KindChoice {
        stage,
        cache_errors: [plastic.cache_error, metal.cache_error],
    });
    let on_cache = format!(
        "relative error on its transport cache plastic {:.4}, metal {:.4}",
        plastic.cache_error, metal.cache_error
    );
    let metal_on_cache = fit::cache_effect(plastic.cache_error, metal.cache_error);
    let mut renders = 0;
    let metal_wins = if metal_on_cache <= fit::SPECULAR_GAIN_THRESHOLD {
        report.decisions.push(format!(
            "stage {stage}: kind auto: plastic, the simpler: metal accounts for {metal_on_cache:.4} more on its transport cache, at most SPECULAR_GAIN_THRESHOLD {} ({on_cache})",
            fit::SPECULAR_GAIN_THRESHOLD
        ));
        false
    } else {
        let why = format!(
            "metal accounts for {metal_on_cache:.4} more on its transport cache ({on_cache})"
        );
        by_render(
            rec,
            g,
            (plastic.model, metal.model),
            (stage, spp),
            (&why, report),
            &mut renders,
        )?
    };
    if metal_wins {
        return Ok((Some(metal), renders));
    }
    report.metal_passed_over = Some(metal.model);
    Ok((Some(plastic), renders))
}

/// Stage 4, for a group of kind "auto" with the plastic lobe `kept`: `passed_over`, the
/// metal proposal stage 2 chose plastic over, its colour levelled under the scene as now
/// known, against `kept` in a render by the keep rule. No cache gate: the stage-4 cache's
/// metal fits are what fall short (glossy's steel box, 64 px, seed 1: its plain fit s
/// 0.71, roughness 0.028, across halves 0.96, 0.3 at the bound; truth 0.95, 0.14), where
/// stage 2's proposal, levelled, renders better than the plastic by 0.0304 +- 0.0050
/// (docs/recovery.md, "Kind auto"). `cache_errors` are this cache's plain plastic and
/// metal fits', for the record. Returns the metal model if it wins, and the renders spent.
pub(super) fn choose_again(
    rec: &mut Recovery,
    g: usize,
    (kept, passed_over): (GroupModel, GroupModel),
    cache_errors: [f64; 2],
    (spp, levelled_by): (u32, &str),
    report: &mut GroupReport,
) -> Result<(Option<GroupModel>, u32), Error> {
    report.kind_choice = Some(KindChoice {
        stage: 4,
        cache_errors,
    });
    let why = format!(
        "again, for the plastic lobe stage 4 kept: stage 2's metal proposal, {levelled_by}"
    );
    let mut renders = 0;
    let metal_wins = by_render(
        rec,
        g,
        (kept, passed_over),
        (4, spp),
        (&why, report),
        &mut renders,
    )?;
    Ok((metal_wins.then_some(passed_over), renders))
}

/// `plastic` against `metal` in a render at `spp` by the keep rule
/// (`fit::ModelComparison::favours_complex`): whether metal wins. The decision (after
/// `why`) goes into the report, the render as a comparison of stage "`<stage>` kind".
/// Plastic where no pixel is lit. Adds the comparison's evaluations to `evaluations`.
fn by_render(
    rec: &mut Recovery,
    g: usize,
    (plastic, metal): (GroupModel, GroupModel),
    (stage, spp): (u32, u32),
    (why, report): (&str, &mut GroupReport),
    evaluations: &mut u32,
) -> Result<bool, Error> {
    let Some((c, decision_spp)) = rec.compare_models(g, (plastic, metal), spp, evaluations)? else {
        report.decisions.push(format!(
            "stage {stage}: kind auto: plastic, the simpler: no lit pixel to compare the kinds on ({why})"
        ));
        return Ok(false);
    };
    let metal_wins = c.favours_complex();
    report.decisions.push(format!(
        "stage {stage}: kind auto: {}: {why}; in a render at {decision_spp} spp it accounts for {:.4} more (removes {:.4} +- {:.4}, z {:.1}), {} {}",
        if metal_wins { "metal" } else { "plastic, the simpler" },
        c.effect(),
        c.gain,
        c.gain_sigma,
        c.z(),
        if metal_wins { "passing the rule" } else { "short of the rule" },
        keep_rule(&c)
    ));
    report.add_comparison(
        ComparisonReport::new(
            &comparison_stage(stage),
            &format!("{} plastic", plastic.name()),
            &format!("{} metal", metal.name()),
            &c,
            decision_spp,
        ),
        &c,
    );
    Ok(metal_wins)
}

/// The report.json stage name of stage `stage`'s kind comparison.
pub fn comparison_stage(stage: u32) -> String {
    format!("{stage} {KIND_COMPARISON}")
}

/// What showed neither kind better in `choice`, if nothing did: its cache's two fits
/// within `SPECULAR_GAIN_THRESHOLD` of each other either way, so that [`choose`] asked no
/// render, or the choice's last render among `comparisons` showing metal short of the
/// keep rule and not worse than plastic at the z the rule asks.
pub fn undecided(choice: &KindChoice, comparisons: &[ComparisonReport]) -> Option<String> {
    let [plastic, metal] = choice.cache_errors;
    let stage = comparison_stage(choice.stage);
    // The last: stage 4 may choose twice, on its anisotropic proposals and again.
    match comparisons.iter().rev().find(|c| c.stage == stage) {
        Some(c) if !c.passed_test && c.z > -c.z_needed => Some(format!(
            "in a render metal fits {} by {:.4} +- {:.4} of relative error, z {:.1}",
            if c.gain >= 0.0 { "better" } else { "worse" },
            c.gain.abs(),
            c.gain_sigma,
            c.z
        )),
        Some(_) => None,
        None => {
            let apart = fit::cache_effect(plastic, metal).max(fit::cache_effect(metal, plastic));
            (apart <= fit::SPECULAR_GAIN_THRESHOLD).then(|| {
                format!(
                    "on its transport cache the two fits are {apart:.4} of relative error apart, at most SPECULAR_GAIN_THRESHOLD {} (plastic {plastic:.4}, metal {metal:.4})",
                    fit::SPECULAR_GAIN_THRESHOLD
                )
            })
        }
    }
}
