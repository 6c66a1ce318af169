//! Simulated annealing over a bounded box of `D` parameters, seeded, in ask/tell form:
//! the annealer proposes, the caller evaluates (a render, in parallel, on the host) and
//! tells the cost back. The same seed and the same costs give the same sequence.
//!
//! Moves are Gaussian-like steps (sum of two uniforms) scaled by the box and by a step size
//! that adapts to keep the acceptance rate near [`TARGET_ACCEPTANCE`]; the temperature
//! falls geometrically per level; the best point seen is kept.

use crate::error::Error;
use crate::rng::Sampler;

/// Acceptance rate the step size is steered towards (Corana et al.'s classic choice).
pub const TARGET_ACCEPTANCE: f64 = 0.44;

/// The cooling schedule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Schedule {
    /// Starting temperature, in units of the cost.
    pub initial_temperature: f64,
    /// Temperature factor per level, in (0, 1).
    pub cooling: f64,
    /// Proposals per temperature level.
    pub steps_per_level: u32,
    /// Levels in all.
    pub levels: u32,
    /// Initial step, as a fraction of each parameter's range.
    pub initial_step: f64,
}

impl Schedule {
    pub fn total_steps(&self) -> u32 {
        self.steps_per_level.saturating_mul(self.levels)
    }

    fn check(&self) -> Result<(), Error> {
        let ok = self.initial_temperature > 0.0
            && self.initial_temperature.is_finite()
            && self.cooling > 0.0
            && self.cooling < 1.0
            && self.steps_per_level > 0
            && self.levels > 0
            && self.initial_step > 0.0
            && self.initial_step <= 1.0;
        if ok {
            Ok(())
        } else {
            Err(Error::InvalidValue {
                what: "annealing schedule",
            })
        }
    }
}

/// The state of one annealing chain over `D` parameters.
pub struct Annealer<const D: usize> {
    lower: [f64; D],
    upper: [f64; D],
    schedule: Schedule,
    rng: Sampler,
    current: [f64; D],
    current_cost: f64,
    best: [f64; D],
    best_cost: f64,
    pending: Option<[f64; D]>,
    temperature: f64,
    step: [f64; D],
    steps_done: u32,
    accepted_in_level: u32,
}

impl<const D: usize> Annealer<D> {
    /// A chain starting at `start` (clamped into the box) whose cost is `start_cost`.
    pub fn new(
        lower: [f64; D],
        upper: [f64; D],
        start: [f64; D],
        start_cost: f64,
        schedule: Schedule,
        seed: u64,
    ) -> Result<Annealer<D>, Error> {
        schedule.check()?;
        check_bounds(
            &lower,
            &upper,
            "annealing bounds: need finite lower < upper, a finite width apart",
        )?;
        let start = clamp_into(start, &lower, &upper);
        let cost = if start_cost.is_nan() {
            f64::INFINITY
        } else {
            start_cost
        };
        let step = core::array::from_fn(|d| schedule.initial_step * (upper[d] - lower[d]));
        Ok(Annealer {
            lower,
            upper,
            schedule,
            rng: Sampler::from_key(crate::rng::stream_key(&[seed, 0x00A2_2EA1])),
            current: start,
            current_cost: cost,
            best: start,
            best_cost: cost,
            pending: None,
            temperature: schedule.initial_temperature,
            step,
            steps_done: 0,
            accepted_in_level: 0,
        })
    }

    /// True when the schedule is spent.
    pub fn is_done(&self) -> bool {
        self.steps_done >= self.schedule.total_steps()
    }

    /// The next point to evaluate (the same point until its cost is told).
    pub fn propose(&mut self) -> [f64; D] {
        if let Some(p) = self.pending {
            return p;
        }
        let mut p = self.current;
        for (x, step) in p.iter_mut().zip(self.step) {
            // Sum of two uniforms: a triangular step in (-step, step), mode 0.
            let u = self.rng.next_f32() as f64 + self.rng.next_f32() as f64 - 1.0;
            *x += u * step;
        }
        let p = reflect_into(p, &self.lower, &self.upper);
        self.pending = Some(p);
        p
    }

    /// The cost of the last proposal: accepted by the Metropolis rule.
    pub fn tell(&mut self, cost: f64) {
        let Some(p) = self.pending.take() else { return };
        let cost = if cost.is_nan() { f64::INFINITY } else { cost };
        let accept = if cost <= self.current_cost {
            true
        } else {
            let u = self.rng.next_f32() as f64;
            u < libm::exp(-(cost - self.current_cost) / self.temperature)
        };
        if accept {
            self.current = p;
            self.current_cost = cost;
            self.accepted_in_level = self.accepted_in_level.saturating_add(1);
        }
        if cost < self.best_cost {
            self.best = p;
            self.best_cost = cost;
        }
        self.steps_done = self.steps_done.saturating_add(1);
        if self
            .steps_done
            .is_multiple_of(self.schedule.steps_per_level)
        {
            self.end_level();
        }
    }

    fn end_level(&mut self) {
        let rate = self.accepted_in_level as f64 / self.schedule.steps_per_level as f64;
        // Widen the steps when too many are accepted, narrow them when too few.
        let factor = if rate > TARGET_ACCEPTANCE {
            1.0 + 2.0 * (rate - TARGET_ACCEPTANCE) / (1.0 - TARGET_ACCEPTANCE)
        } else {
            1.0 / (1.0 + 2.0 * (TARGET_ACCEPTANCE - rate) / TARGET_ACCEPTANCE)
        };
        for d in 0..D {
            let range = self.upper[d] - self.lower[d];
            self.step[d] = (self.step[d] * factor).clamp(1e-6 * range, range);
        }
        self.accepted_in_level = 0;
        self.temperature *= self.schedule.cooling;
        // Restart each level from the best point: annealing with elitism.
        self.current = self.best;
        self.current_cost = self.best_cost;
    }

    pub fn best(&self) -> ([f64; D], f64) {
        (self.best, self.best_cost)
    }

    /// The chain's current point (the last accepted one).
    pub fn current(&self) -> [f64; D] {
        self.current
    }

    pub fn evaluations(&self) -> u32 {
        self.steps_done
    }
}

/// Refuses a search box that is not finite with `lower < upper` on every axis (`what`
/// names the search). Shared by the searches of this crate.
pub(crate) fn check_bounds<const D: usize>(
    lower: &[f64; D],
    upper: &[f64; D],
    what: &'static str,
) -> Result<(), Error> {
    for d in 0..D {
        // The width too: the steps are fractions of it, and a box of -1e308..1e308 (whose
        // width is infinite) would propose its corners alone.
        let width = upper[d] - lower[d];
        if !(lower[d].is_finite() && upper[d].is_finite() && width > 0.0 && width.is_finite()) {
            return Err(Error::InvalidValue { what });
        }
    }
    Ok(())
}

/// `p` forced into the box (NaN to the lower bound).
pub(crate) fn clamp_into<const D: usize>(
    mut p: [f64; D],
    lower: &[f64; D],
    upper: &[f64; D],
) -> [f64; D] {
    for d in 0..D {
        p[d] = if p[d].is_nan() {
            lower[d]
        } else {
            p[d].clamp(lower[d], upper[d])
        };
    }
    p
}

/// Mirrors a step that leaves the box back into it (then clamps what is still outside).
fn reflect_into<const D: usize>(mut p: [f64; D], lower: &[f64; D], upper: &[f64; D]) -> [f64; D] {
    for d in 0..D {
        if p[d] < lower[d] {
            p[d] = 2.0 * lower[d] - p[d];
        } else if p[d] > upper[d] {
            p[d] = 2.0 * upper[d] - p[d];
        }
    }
    clamp_into(p, lower, upper)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn schedule() -> Schedule {
        // Ends at T = 0.8^50 ~ 1e-5: below the cost resolution the tests ask for.
        Schedule {
            initial_temperature: 1.0,
            cooling: 0.8,
            steps_per_level: 40,
            levels: 50,
            initial_step: 0.3,
        }
    }

    fn run<const D: usize>(
        f: impl Fn(&[f64; D]) -> f64,
        lo: [f64; D],
        hi: [f64; D],
        start: [f64; D],
        seed: u64,
    ) -> ([f64; D], f64) {
        let mut a = Annealer::new(lo, hi, start, f(&start), schedule(), seed).unwrap();
        while !a.is_done() {
            let p = a.propose();
            a.tell(f(&p));
        }
        a.best()
    }

    #[test]
    fn finds_the_minimum_of_a_shifted_quadratic() {
        let f = |p: &[f64; 3]| {
            let (a, b, c) = (p[0] - 0.3, p[1] + 0.2, p[2] - 0.9);
            a * a + 4.0 * b * b + c * c
        };
        let (best, cost) = run(f, [-1.0; 3], [1.0; 3], [0.0; 3], 1);
        assert!(cost < 1e-4, "cost {cost} at {best:?}");
        assert!(
            (best[0] - 0.3).abs() < 0.01
                && (best[1] + 0.2).abs() < 0.01
                && (best[2] - 0.9).abs() < 0.01
        );
    }

    #[test]
    fn escapes_a_local_minimum_where_descent_would_stay() {
        // Two wells in 1D: a shallow one at -0.6 (start) and the deep one at 0.7.
        let f = |p: &[f64; 1]| {
            let x = p[0];
            -0.3 * libm::exp(-((x + 0.6) * (x + 0.6)) / 0.01)
                - 1.0 * libm::exp(-((x - 0.7) * (x - 0.7)) / 0.01)
        };
        let (best, _) = run(f, [-1.0], [1.0], [-0.6], 5);
        assert!((best[0] - 0.7).abs() < 0.02, "{best:?}");
    }

    #[test]
    fn stays_inside_the_box_and_is_reproducible() {
        let f = |p: &[f64; 2]| -(p[0] + p[1]); // optimum at the upper corner
        let (a, _) = run(f, [0.0, 0.0], [0.5, 2.0], [0.1, 0.1], 9);
        let (b, _) = run(f, [0.0, 0.0], [0.5, 2.0], [0.1, 0.1], 9);
        assert_eq!(a, b);
        assert!(
            a[0] <= 0.5 && a[1] <= 2.0 && a[0] > 0.49 && a[1] > 1.98,
            "{a:?}"
        );
    }

    #[test]
    fn bad_bounds_and_schedules_are_errors() {
        assert!(Annealer::new([1.0], [0.0], [0.5], 0.0, schedule(), 1).is_err());
        // Each bound finite, their width not.
        assert!(Annealer::new([-1e308], [1e308], [0.5], 0.0, schedule(), 1).is_err());
        let mut s = schedule();
        s.cooling = 1.5;
        assert!(Annealer::new([0.0], [1.0], [0.5], 0.0, s, 1).is_err());
    }
}
