//! Stage 2's second look at a weak lobe: a ladder of roughnesses, chosen by render.
//!
//! A group whose whole diffuse error is not established above `DIFFUSE_THRESHOLD` may
//! hold only a weak lobe, and its cache's proposal is least reliable there: the
//! closed-form fit over a finite set of incident samples rewards a sharp, weak lobe that
//! lines up with a few bright samples (docs/recovery.md, "The cache's proposal depends on the cache's size").
//! Glossy's yellow box (specularity 0.1, roughness 0.2 in the truth) is proposed at
//! roughness 0.05, which removes 0.002 of its 0.029 error in a render, and stays diffuse,
//! while a lobe of roughness 0.3 on the same cache removes 0.019 at z 6.
//!
//! So when such a group's proposal fails stage 2's test, a fixed ladder of roughnesses
//! spanning the search's range is tried: at each rung the reflectances come from the cache
//! in closed form (a linear fit, with no choice of roughness to be fooled; its squares
//! taken across two halves of each pixel's samples, since the plain sums' noise made a
//! large group's rungs all specularity: the living room's desk at 256 px, s 0.2 against
//! 0.05 at every rung, each rendering worse than diffuse), every rung is
//! rendered against the diffuse model on fresh samples, and the rung that removes the most
//! error (at its lower confidence bound, measured again at 4x where that bound leaves the
//! choice open; then refined by half a rung) goes to the same
//! keep-or-reject test as the proposal did, from the ladder's samples up. One more test on
//! a group that already failed one adds a little to the false-positive rate; the test's z
//! of `GAIN_SIGNIFICANCE` on fresh samples bounds it.

use relume_core::fit;
use relume_core::material::Kind;
use relume_core::stages::isotropic::{ROUGHNESS_MAX, ROUGHNESS_MIN};

use super::cache::{self, GroupCache};
use super::model::GroupModel;
use super::{min_samples_spp, pixels, Recovery};
use crate::error::Error;

/// Rungs of the ladder, log-spaced over `[ROUGHNESS_MIN, ROUGHNESS_MAX]` (a ratio of
/// about 2.3 between rungs: a lobe between two rungs is within a factor 1.5 of one).
pub const LADDER_RUNGS: usize = 6;

/// The roughness of rung `k`.
pub fn rung_roughness(k: usize) -> f64 {
    let t = k as f64 / (LADDER_RUNGS - 1) as f64;
    ROUGHNESS_MIN * libm::pow(ROUGHNESS_MAX / ROUGHNESS_MIN, t)
}

/// The chosen rung: its model, and the gain over the diffuse model that chose it (on the
/// ladder's samples; the caller decides on its own).
#[derive(Clone, Copy)]
pub struct Rung {
    pub model: GroupModel,
    pub specularity: f64,
    pub roughness: f64,
    /// The gain in squared relative error ([`fit::ModelComparison::squared_gain`]) and its
    /// standard error.
    pub squared_gain: f64,
    pub squared_gain_sigma: f64,
    /// `squared_gain - EXCEEDS_SIGMAS squared_gain_sigma`, what chose it.
    pub lower: f64,
    pub spp: u32,
}

/// Pixel samples each rung is rendered with, in all (the race's [`RACE_MIN_SAMPLES`]).
/// More choose the roughness better but cost more than they gain: on glossy, seeds 1-10,
/// 2^17 (with rungs then ranked by the gain in relative error) gave 93 classes right of
/// 110 against 2^15's 92, and chose broad rungs (0.13-0.3) for the yellow box where 2^15
/// also picks sharp ones; but it took the living room's 64-px recovery (seeds 1-3) from
/// 29-35 s to 38-43 s, where 2^15 takes 33-38 s.
///
/// [`RACE_MIN_SAMPLES`]: super::refine::RACE_MIN_SAMPLES
pub const LADDER_SAMPLES: u64 = 1 << 15;

/// Renders lobes of group `g` against its diffuse model, on the pixels and samples its
/// decisions use (at least [`LADDER_SAMPLES`]) and on one seed, and reads each one's gain.
struct RungMeter {
    g: usize,
    kind: Kind,
    pixels: Vec<pixels::PurePixel>,
    spp: u32,
    seed: u64,
    diffuse_terms: Vec<([f64; 2], f64)>,
    /// The model `g` had before, restored by [`RungMeter::finish`].
    before: GroupModel,
    evaluations: u32,
}

impl RungMeter {
    fn new(
        rec: &mut Recovery,
        g: usize,
        kind: Kind,
        diffuse: GroupModel,
        group_spp: u32,
        seed: u64,
    ) -> Result<Self, Error> {
        let (pixels, spp) = rec.decision_pixels(g, group_spp);
        let before = rec.models[g];
        rec.models[g] = diffuse;
        // An error ends the recovery, so the model need not be restored on that path.
        let diffuse_terms = rec.paired_terms(&pixels, spp, seed)?;
        Ok(RungMeter {
            g,
            kind,
            pixels,
            spp,
            seed,
            diffuse_terms,
            before,
            evaluations: 1,
        })
    }

    /// The isotropic lobe `model` rendered and compared with the diffuse model; `None`
    /// for another model or when no pixel could be compared.
    fn measure_model(
        &mut self,
        rec: &mut Recovery,
        model: GroupModel,
    ) -> Result<Option<Rung>, Error> {
        let GroupModel::Isotropic {
            specularity,
            roughness,
            ..
        } = model
        else {
            return Ok(None);
        };
        rec.models[self.g] = model;
        let terms = rec.paired_terms(&self.pixels, self.spp, self.seed)?;
        self.evaluations += 1;
        Ok(
            super::paired_comparison(&self.diffuse_terms, &terms).map(|c| Rung {
                model,
                specularity,
                roughness,
                squared_gain: c.squared_gain,
                squared_gain_sigma: c.squared_gain_sigma,
                lower: c.squared_gain - fit::EXCEEDS_SIGMAS * c.squared_gain_sigma,
                spp: self.spp,
            }),
        )
    }

    /// The rung of `roughness`: its reflectances from the cache in closed form (across
    /// halves), then measured; `None` without a positive specularity.
    fn measure(
        &mut self,
        rec: &mut Recovery,
        cache: &GroupCache,
        roughness: f64,
    ) -> Result<Option<Rung>, Error> {
        let kind = self.kind;
        let fit = cache::isotropic_fit_across_halves(&rec.pool, cache, kind, roughness);
        if fit.specularity.is_nan() || fit.specularity <= 0.0 {
            return Ok(None);
        }
        let model = GroupModel::Isotropic {
            kind,
            color: fit.color,
            specularity: fit.specularity,
            roughness,
        };
        self.measure_model(rec, model)
    }

    /// Every rung of the ladder, measured.
    fn measure_ladder(
        &mut self,
        rec: &mut Recovery,
        cache: &GroupCache,
    ) -> Result<Vec<Rung>, Error> {
        let mut measured = Vec::new();
        for k in 0..LADDER_RUNGS {
            measured.extend(self.measure(rec, cache, rung_roughness(k))?);
        }
        Ok(measured)
    }

    /// Restores the group's model; returns the renders spent.
    fn finish(self, rec: &mut Recovery) -> u32 {
        rec.models[self.g] = self.before;
        self.evaluations
    }
}

/// The better of two rungs by their gain's lower bound.
fn better(a: Option<Rung>, b: Option<Rung>) -> Option<Rung> {
    match (a, b) {
        (Some(a), Some(b)) => Some(if b.lower > a.lower { b } else { a }),
        (a, b) => a.or(b),
    }
}

/// Rungs measured again in the ladder's second round ([`best_rung`]).
pub const SECOND_ROUND_RUNGS: usize = 3;

/// How many times the first round's samples the second round renders with: half the
/// standard error on each rung's gain.
pub const SECOND_ROUND_GROWTH: u32 = 4;

/// What [`best_rung`] found: the best rung, every rung's latest reading, the group
/// samples per pixel its choice was made at, and the renders spent.
struct Ladder {
    best: Option<Rung>,
    measured: Vec<Rung>,
    group_spp: u32,
    /// The first round's best, when a second round was taken.
    first_round: Option<Rung>,
    /// The samples per pixel of a first round that would have had a second but for the
    /// cap on a measurement's samples.
    second_round_capped: Option<u32>,
    evaluations: u32,
}

/// The rung of group `g`'s ladder whose gain over `diffuse` is largest at its lower bound
/// (`gain - EXCEEDS_SIGMAS sigma`, in squared error: a sharp rung's gain is the noisiest,
/// and the plain largest gain is most often a sharp rung the samples favour; and a weak
/// group's errors, cut at 0 when noise outweighs them, would rank nothing), then the
/// better of it and the two roughnesses halfway (in log) to its neighbours; each rendered
/// with at least [`LADDER_SAMPLES`] on the ladder's own seed.
///
/// A first round whose best rung does not gain at its lower bound has not chosen: its
/// rungs' gains are within their noise of each other and of 0. Glossy's teal box (s 0.04,
/// roughness 0.08; 426 pixels at 64 px) read its best rung at 0.0003-0.0007 +- 0.0005-0.0007
/// on seeds where the test kept it, and below 0 or at the search's bound (roughness 0.3)
/// where it stayed diffuse. Then the [`SECOND_ROUND_RUNGS`] rungs of most gain are measured
/// again at [`SECOND_ROUND_GROWTH`] times the samples on a fresh seed, and the choice (and
/// the half-rungs) made there.
fn best_rung(
    rec: &mut Recovery,
    g: usize,
    cache: &GroupCache,
    kind: Kind,
    diffuse: GroupModel,
    group_spp: u32,
) -> Result<Ladder, Error> {
    let seed = rec.seed ^ 0x001A_DDE2 ^ g as u64;
    let mut meter = RungMeter::new(rec, g, kind, diffuse, group_spp, seed)?;
    let mut measured = meter.measure_ladder(rec, cache)?;
    let mut best = best_of(&measured);
    let mut evaluations = 0;
    let mut first_round = None;
    let mut chosen_at = group_spp;
    // A round held by the cap of `Recovery::decision_pixels` to much the same samples
    // would be a second chance, not a better measurement (`fit::DECISION_MIN_GROWTH`).
    let grown = group_spp.saturating_mul(SECOND_ROUND_GROWTH);
    let (_, grown_spp) = rec.decision_pixels(g, grown);
    let room = grown_spp as u64 >= meter.spp as u64 * fit::DECISION_MIN_GROWTH as u64;
    let wanted = second_round(&measured);
    let capped = wanted.is_some() && !room;
    let first_spp = meter.spp;
    if let Some(again) = wanted.filter(|_| room) {
        evaluations += meter.finish(rec);
        first_round = best;
        chosen_at = grown;
        meter = RungMeter::new(rec, g, kind, diffuse, chosen_at, seed ^ 0x2ED0_0000)?;
        measured.retain(|r| !again.iter().any(|a| a.roughness == r.roughness));
        let mut second = Vec::with_capacity(again.len());
        for rung in again {
            second.extend(meter.measure_model(rec, rung.model)?);
        }
        best = best_of(&second);
        measured.extend(second);
    }
    if let Some(at) = best.as_ref().map(|b| b.roughness) {
        for roughness in [at / half_step(), at * half_step()] {
            if (ROUGHNESS_MIN..=ROUGHNESS_MAX).contains(&roughness) {
                let rung = meter.measure(rec, cache, roughness)?;
                measured.extend(rung);
                best = better(best, rung);
            }
        }
    }
    evaluations += meter.finish(rec);
    Ok(Ladder {
        best,
        measured,
        group_spp: chosen_at,
        first_round,
        second_round_capped: capped.then_some(first_spp),
        evaluations,
    })
}

/// The rungs a first round `measured` leaves to a second: none when it has decided, for a
/// rung (the best gains at its lower bound) or against them all (none gains enough to pass
/// the test at its upper bound, `gain + EXCEEDS_SIGMAS sigma` above the square of
/// `SPECULAR_GAIN_THRESHOLD`, what the test holds a lobe's effect against: the living
/// room's floor at 256 px, its best rung at -0.00014 +- 0.00001; glossy's walls_warm at
/// 256 px, -0.00004 +- 0.00004, where a second round took half of the 47 s that
/// stage 2 spent on a diffuse wall); else, of the rungs that may, the
/// [`SECOND_ROUND_RUNGS`] of most gain.
fn second_round(measured: &[Rung]) -> Option<Vec<Rung>> {
    best_of(measured).filter(|b| b.lower <= 0.0)?;
    let passing = fit::SPECULAR_GAIN_THRESHOLD * fit::SPECULAR_GAIN_THRESHOLD;
    let mut open: Vec<Rung> = measured
        .iter()
        .filter(|r| r.squared_gain + fit::EXCEEDS_SIGMAS * r.squared_gain_sigma > passing)
        .copied()
        .collect();
    open.sort_by(|a, b| b.squared_gain.total_cmp(&a.squared_gain));
    open.truncate(SECOND_ROUND_RUNGS);
    (!open.is_empty()).then_some(open)
}

/// The best of `measured` by [`better`].
fn best_of(measured: &[Rung]) -> Option<Rung> {
    measured
        .iter()
        .copied()
        .fold(None, |b, r| better(b, Some(r)))
}

/// How far a weak lobe that the cache proposed and the test kept can be trusted: the
/// ladder's rungs measured beside it, as [`plausible`] reads them around the better of it
/// and the best rung, and the standard errors that implies for its specularity and
/// roughness. The sandwich of `uncertainty` sees the pixels' pull at the chosen point
/// only, and a weak lobe's pixels pull almost as hard far from it: glossy's box_teal (s
/// 0.04, roughness 0.08) was kept at roughness 0.020 with a claimed sigma of 0.0015, 39
/// standard errors from the truth (64 px, seed 1). Renders only; no decision changes.
/// Also returns the renders spent; no sigmas when the lobe could not be compared.
pub fn spread_around(
    rec: &mut Recovery,
    g: usize,
    cache: &GroupCache,
    kind: Kind,
    diffuse: GroupModel,
    spp: u32,
    chosen: GroupModel,
) -> Result<(Option<LobeSigmas>, u32), Error> {
    let seed = rec.seed ^ 0x5B2E_AD00 ^ g as u64;
    let group_spp = ladder_spp(rec, g, spp);
    let mut meter = RungMeter::new(rec, g, kind, diffuse, group_spp, seed)?;
    let chosen = meter.measure_model(rec, chosen)?;
    let measured = meter.measure_ladder(rec, cache)?;
    let evaluations = meter.finish(rec);
    Ok((chosen.map(|c| sigmas_of_chosen(c, measured)), evaluations))
}

/// The standard errors of `chosen`'s roughness and specularity from the rungs `measured`
/// beside it: [`plausible`] around the better of it and the best rung.
fn sigmas_of_chosen(chosen: Rung, mut measured: Vec<Rung>) -> LobeSigmas {
    let best = measured
        .iter()
        .fold(chosen, |b, r| better(Some(b), Some(*r)).unwrap_or(b));
    measured.push(chosen);
    plausible(&best, &measured).sigmas(&chosen)
}

/// The ratio of a half-rung's roughness to its rung's.
fn half_step() -> f64 {
    libm::sqrt(rung_roughness(1) / rung_roughness(0))
}

/// Standard errors of a lobe's roughness and specularity, by name, in that order.
pub type LobeSigmas = [(&'static str, f64); 2];

/// How far the ladder's choice can be trusted: the ranges of roughness and specularity
/// over the rungs it cannot tell from the best (`plausible`), widened in roughness by
/// half a half-rung either side (a lobe between two measured roughnesses), and the
/// standard errors they imply for the chosen values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spread {
    pub roughness: (f64, f64),
    pub specularity: (f64, f64),
    /// Rungs in the ranges.
    pub rungs: usize,
}

impl Spread {
    /// The standard errors of the chosen roughness and specularity, taking each range for
    /// about a 95% interval (two standard errors to its farther end): the sandwich of
    /// `uncertainty` sees the pixels' pull at the chosen point only, and a weak lobe's
    /// pixels pull almost as hard at rungs far apart (glossy's yellow box, roughness 0.2:
    /// chosen at 0.005-0.3 over the seeds, with a sandwich sigma of a few percent).
    pub fn sigmas(&self, chosen: &Rung) -> LobeSigmas {
        let half_width = |(lo, hi): (f64, f64), at: f64| (at - lo).max(hi - at).max(0.0) / 2.0;
        [
            ("roughness", half_width(self.roughness, chosen.roughness)),
            (
                "specularity",
                half_width(self.specularity, chosen.specularity),
            ),
        ]
    }
}

/// The rungs of `measured` whose gain is within [`fit::EXCEEDS_SIGMAS`] standard errors of
/// the `best` one's (each rung's own error and the best's in quadrature: the rungs share
/// the diffuse model's samples, so this is the wider bound), and their ranges.
pub fn plausible(best: &Rung, measured: &[Rung]) -> Spread {
    let close = measured.iter().filter(|r| {
        let sigma = libm::hypot(r.squared_gain_sigma, best.squared_gain_sigma);
        r.squared_gain + fit::EXCEEDS_SIGMAS * sigma >= best.squared_gain
    });
    let mut spread = Spread {
        roughness: (best.roughness, best.roughness),
        specularity: (best.specularity, best.specularity),
        rungs: 0,
    };
    for r in close {
        spread.roughness = (
            spread.roughness.0.min(r.roughness),
            spread.roughness.1.max(r.roughness),
        );
        spread.specularity = (
            spread.specularity.0.min(r.specularity),
            spread.specularity.1.max(r.specularity),
        );
        spread.rungs += 1;
    }
    let half = libm::sqrt(half_step());
    spread.roughness = (
        (spread.roughness.0 / half).max(ROUGHNESS_MIN),
        (spread.roughness.1 * half).min(ROUGHNESS_MAX),
    );
    spread
}

/// What [`second_look`] found.
pub struct SecondLook {
    /// The best rung, tested; or why none was (no rung showed any gain, or the test found
    /// no lit pixel), for the group's decisions.
    pub found: Result<Found, String>,
    /// Renders spent.
    pub evaluations: u32,
}

/// The ladder's best rung and its keep-or-reject test.
pub struct Found {
    pub rung: Rung,
    /// The rungs it could not be told from.
    pub spread: Spread,
    /// The test against the diffuse model and its samples per pixel.
    pub test: (fit::ModelComparison, u32),
    /// What was done, for the group's decisions.
    pub decision: String,
}

/// The ladder for group `g` after `proposal` (the failed test of the cache's proposal)
/// and, when its best rung shows any gain, that rung's test against `diffuse` by
/// `Recovery::compare_models`, from the ladder's samples or the usual start (4x the loop's
/// samples), whichever is more: from the usual start alone a weak lobe's errors are lost
/// in the noise at effort fast and the test stops there (glossy's yellow box on seed 6:
/// 0.016 at z 4.9 on the ladder, -0.029 +- 0.010 at 32 spp).
pub fn second_look(
    rec: &mut Recovery,
    g: usize,
    cache: &GroupCache,
    kind: Kind,
    diffuse: GroupModel,
    spp: u32,
    proposal: Option<fit::ModelComparison>,
) -> Result<SecondLook, Error> {
    let ladder = best_rung(rec, g, cache, kind, diffuse, ladder_spp(rec, g, spp))?;
    let (measured, mut evaluations) = (&ladder.measured, ladder.evaluations);
    let rounds = match (ladder.first_round, ladder.second_round_capped) {
        (Some(first), _) => format!(
            " (none gained at its lower bound at {} spp, the best there roughness {:.4} at {:.5} +- {:.5}, so the SECOND_ROUND_RUNGS {SECOND_ROUND_RUNGS} of most gain were measured again at SECOND_ROUND_GROWTH {SECOND_ROUND_GROWTH}x)",
            first.spp, first.roughness, first.squared_gain, first.squared_gain_sigma
        ),
        (None, Some(spp)) => format!(
            " (none gained at its lower bound at {spp} spp, and no second round: SECOND_ROUND_GROWTH {SECOND_ROUND_GROWTH}x would pass DECISION_MAX_SAMPLES {} per model)",
            fit::DECISION_MAX_SAMPLES
        ),
        (None, None) => String::new(),
    };
    let Some(rung) = ladder.best.filter(|r| r.squared_gain > 0.0) else {
        let proposal = format!(
            "stage 2 ladder: the proposal removes {:.4} +- {:.4} (z {:.1}), short of the test{rounds}",
            proposal.map_or(0.0, |c| c.gain),
            proposal.map_or(0.0, |c| c.gain_sigma),
            proposal.map_or(0.0, |c| c.z()),
        );
        return Ok(SecondLook {
            found: Err(match ladder.best {
                None => format!(
                    "{proposal}; no rung of LADDER_RUNGS {LADDER_RUNGS} has a positive specularity in closed form"
                ),
                Some(best) => no_gain(&proposal, &best, measured),
            }),
            evaluations,
        });
    };
    let spread = plausible(&rung, measured);
    let decision = format!(
        "stage 2 ladder: the proposal removes {:.4} +- {:.4} (z {:.1}), short of the test{rounds}; of LADDER_RUNGS {LADDER_RUNGS} roughnesses and the half-rungs around the best, {:.4} (s {:.4}) removes most ({:.5} +- {:.5} of squared relative error at {} spp) and is tested in its place; {} of the {} measured are within EXCEEDS_SIGMAS {} standard errors of it: roughness {:.4}-{:.4}, s {:.4}-{:.4}",
        proposal.map_or(0.0, |c| c.gain),
        proposal.map_or(0.0, |c| c.gain_sigma),
        proposal.map_or(0.0, |c| c.z()),
        rung.roughness,
        rung.specularity,
        rung.squared_gain,
        rung.squared_gain_sigma,
        rung.spp,
        spread.rungs,
        measured.len(),
        fit::EXCEEDS_SIGMAS,
        spread.roughness.0,
        spread.roughness.1,
        spread.specularity.0,
        spread.specularity.1,
    );
    // From the samples the rung was chosen at, and at no fewer than the proposal's own
    // test (4x the loop's): at effort default the ladder's samples are the fewer, and
    // glossy's white sphere at 256 px read its rung (s 0.025, roughness 0.039 against
    // 0.03, 0.02) at z -1.0 on 96 spp of its decision pixels, where its proposal had 384.
    let test_spp = ladder.group_spp.max(4 * spp);
    let test = rec.compare_models(g, (diffuse, rung.model), test_spp, &mut evaluations)?;
    Ok(SecondLook {
        found: match test {
            Some(test) => Ok(Found {
                rung,
                spread,
                test,
                decision,
            }),
            None => Err(format!("{decision}; but no pixel of it is lit")),
        },
        evaluations,
    })
}

/// Why a ladder whose best rung (at its lower confidence bound) removes no error ends
/// there: that rung's reading, and how many of the others read a gain all the same (each
/// below its noise: a lower bound under the best's).
fn no_gain(proposal: &str, best: &Rung, measured: &[Rung]) -> String {
    let gaining = measured.iter().filter(|r| r.squared_gain > 0.0).count();
    format!(
        "{proposal}; of the {} rungs measured (those with a positive specularity in closed form) none removes error at its lower confidence bound, and the best there (roughness {:.4}, s {:.4}) reads {:+.5} +- {:.5} of squared relative error over the diffuse model at {} spp{}",
        measured.len(),
        best.roughness,
        best.specularity,
        best.squared_gain,
        best.squared_gain_sigma,
        best.spp,
        if gaining > 0 {
            format!("; {gaining} other rung(s) read a gain within their noise")
        } else {
            String::new()
        }
    )
}

/// Samples per pixel of the whole group `g` for its ladder's renders, from the loop's
/// `spp`: at least [`LADDER_SAMPLES`] in all (rendered on the decisions' pixels,
/// `Recovery::decision_pixels`).
fn ladder_spp(rec: &Recovery, g: usize, spp: u32) -> u32 {
    let pixels = pixels::of_group(&rec.pure, g).len() as u32;
    min_samples_spp(spp, pixels, LADDER_SAMPLES)
}

/// Whether stage 2 gives a group a second look: its diffuse error (stage 1's, or a
/// test's of the diffuse model) may leave room only for a weak lobe, i.e. it is not
/// established above `DIFFUSE_THRESHOLD` (by `EXCEEDS_SIGMAS` standard errors). On the point estimate alone, the living room's
/// lamp_body (22 pixels, s 0.05) read 0.055 +- 0.016 and 0.087 +- 0.034 on two seeds,
/// took the strong route, and its proposal's failed test left it diffuse without a look.
pub fn applies(diffuse_error: &fit::ErrorEstimate) -> bool {
    !diffuse_error.exceeds(fit::DIFFUSE_THRESHOLD)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recover::model::NEUTRAL_STAND_IN;

    #[test]
    fn the_ladder_spans_the_search_range_evenly_in_log() {
        assert!((rung_roughness(0) - ROUGHNESS_MIN).abs() < 1e-12);
        assert!((rung_roughness(LADDER_RUNGS - 1) - ROUGHNESS_MAX).abs() < 1e-12);
        let ratios: Vec<f64> = (1..LADDER_RUNGS)
            .map(|k| rung_roughness(k) / rung_roughness(k - 1))
            .collect();
        for r in &ratios {
            assert!((r - ratios[0]).abs() < 1e-9 && *r < 2.5, "{ratios:?}");
        }
    }

    fn rung(roughness: f64, specularity: f64, gain: f64, sigma: f64) -> Rung {
        Rung {
            model: GroupModel::Unseen {
                stand_in: NEUTRAL_STAND_IN,
            },
            specularity,
            roughness,
            squared_gain: gain,
            squared_gain_sigma: sigma,
            lower: gain - fit::EXCEEDS_SIGMAS * sigma,
            spp: 64,
        }
    }

    #[test]
    fn a_ladder_without_gain_says_what_its_best_rung_read_and_counts_the_others_that_gained() {
        // The best at its lower bound reads no gain; a noisier rung reads one.
        let best = rung(0.06, 0.05, -0.0001, 0.0001);
        let noisy = rung(0.005, 0.08, 0.0005, 0.0005);
        let text = no_gain("stage 2 ladder: p", &best, &[best, noisy]);
        assert!(
            text.contains("of the 2 rungs measured")
                && text.contains("(roughness 0.0600, s 0.0500) reads -0.00010 +- 0.00010")
                && text.ends_with("; 1 other rung(s) read a gain within their noise"),
            "{text}"
        );
        let text = no_gain("stage 2 ladder: p", &best, &[best]);
        assert!(!text.contains("other rung"), "{text}");
    }

    #[test]
    fn a_first_round_that_has_not_chosen_leaves_its_rungs_of_most_gain_to_a_second() {
        // The best at its lower bound gains: chosen, no second round.
        let resolved = [
            rung(0.005, 0.05, 0.0001, 0.0004),
            rung(0.0114, 0.05, 0.0009, 0.0002),
            rung(0.0260, 0.05, 0.0003, 0.0001),
        ];
        assert!(second_round(&resolved).is_none());
        // No rung gains at its lower bound (glossy's teal box, 64 px, seed 9: the best,
        // at the search's bound, 0.0066 +- 0.0067): the three of most gain, the noisiest
        // among them, go on; the rung of least gain does not.
        let unresolved = [
            rung(0.005, 0.02, 0.0004, 0.0005),
            rung(0.0114, 0.02, -0.0002, 0.0003),
            rung(0.0260, 0.03, 0.0002, 0.0004),
            rung(0.3, 0.02, 0.0066, 0.0067),
        ];
        let again = second_round(&unresolved).unwrap();
        let roughnesses: Vec<f64> = again.iter().map(|r| r.roughness).collect();
        assert_eq!(roughnesses, [0.3, 0.005, 0.0260]);
        // Fewer rungs than a round holds: all of them.
        assert_eq!(second_round(&unresolved[..2]).unwrap().len(), 2);
        assert!(second_round(&[]).is_none());
        // Only the rungs that may gain at their upper bound; none when no rung may (a
        // diffuse floor's ladder has decided against them all).
        let against = [
            rung(0.005, 0.01, -0.0004, 0.0001),
            rung(0.1323, 0.01, -0.00014, 0.00001),
            rung(0.3, 0.01, -0.0003, 0.0001),
        ];
        assert!(second_round(&against).is_none());
        let one_open = [against[0], rung(0.0260, 0.03, -0.0001, 0.0002), against[2]];
        let again = second_round(&one_open).unwrap();
        assert_eq!(again.len(), 1);
        assert_eq!(again[0].roughness, 0.0260);
        // A rung that may gain at its upper bound, but less than the test asks of a lobe
        // (SPECULAR_GAIN_THRESHOLD squared, 0.0001: glossy's walls_warm at 256 px): none.
        let too_little = [against[0], rung(0.3, 0.0055, -0.00004, 0.00004), against[2]];
        let upper =
            too_little[1].squared_gain + fit::EXCEEDS_SIGMAS * too_little[1].squared_gain_sigma;
        assert!(upper > 0.0);
        assert!(second_round(&too_little).is_none());
        let just_enough = [against[0], rung(0.3, 0.0055, 0.00003, 0.00004), against[2]];
        assert_eq!(second_round(&just_enough).unwrap().len(), 1);
    }

    #[test]
    fn the_spread_spans_the_rungs_the_gains_cannot_tell_apart() {
        let best = rung(0.0387, 0.1, 0.0010, 0.0001);
        let measured = [
            rung(0.005, 0.05, 0.0002, 0.0001),
            rung(0.0114, 0.07, 0.0008, 0.0001),
            best,
            rung(0.0880, 0.12, 0.0009, 0.0002),
            rung(0.2, 0.2, 0.0001, 0.0001),
        ];
        let spread = plausible(&best, &measured);
        assert_eq!(spread.rungs, 3);
        let half = libm::sqrt(half_step());
        assert!((spread.roughness.0 - 0.0114 / half).abs() < 1e-12);
        assert!((spread.roughness.1 - 0.0880 * half).abs() < 1e-12);
        assert_eq!(spread.specularity, (0.07, 0.12));
        let [(_, roughness), (_, specularity)] = spread.sigmas(&best);
        assert!((roughness - (0.0880 * half - 0.0387) / 2.0).abs() < 1e-12);
        assert!((specularity - 0.015).abs() < 1e-12);

        // Clearly the best alone: half a half-rung either side, nothing in specularity.
        let alone = plausible(&best, &[measured[0], best, measured[4]]);
        assert_eq!(alone.rungs, 1);
        assert_eq!(alone.sigmas(&best)[1].1, 0.0);
        assert!(alone.sigmas(&best)[0].1 > 0.0);
    }

    #[test]
    fn a_kept_weak_lobe_is_as_uncertain_as_the_rungs_that_read_as_well() {
        // box_teal's case: kept sharp (roughness 0.02), where broader rungs read as much
        // gain within their noise; its roughness sigma must reach the broadest of them.
        let chosen = rung(0.020, 0.06, 0.0006, 0.0002);
        let measured = vec![
            rung(0.005, 0.03, 0.0001, 0.0001),
            rung(0.0114, 0.05, 0.0004, 0.0002),
            rung(0.0260, 0.06, 0.0006, 0.0002),
            rung(0.0592, 0.05, 0.0005, 0.0002),
            rung(0.1348, 0.04, 0.0005, 0.0003),
            rung(0.3, 0.01, -0.0004, 0.0002),
        ];
        let [(name, roughness), (_, specularity)] = sigmas_of_chosen(chosen, measured.clone());
        assert_eq!(name, "roughness");
        assert!(0.020 + 2.0 * roughness >= 0.1348, "{roughness}");
        // Its specularity spans the rungs that read as well (0.04-0.06).
        assert!((specularity - 0.01).abs() < 1e-12, "{specularity}");

        // A lobe the rungs cannot match keeps half a half-rung of roughness only.
        let clear = rung(0.020, 0.06, 0.0020, 0.0001);
        let [(_, roughness), (_, specularity)] = sigmas_of_chosen(clear, measured.clone());
        assert!(
            roughness < 0.2 * 0.020 && specularity == 0.0,
            "{roughness} {specularity}"
        );

        // A rung clearly better than the lobe kept: the spread is around that rung, and
        // the lobe's sigma reaches it.
        let poor = rung(0.005, 0.02, 0.0001, 0.0001);
        let [(_, roughness), _] = sigmas_of_chosen(poor, measured);
        assert!(0.005 + 2.0 * roughness >= 0.0260, "{roughness}");
    }
}
