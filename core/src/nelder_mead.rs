//! Nelder-Mead simplex search over a bounded box of `D` parameters, in the same ask/tell
//! form as [`crate::anneal::Annealer`]: the search proposes, the caller evaluates and tells
//! the cost back. It is the local optimiser Boivin & Gagalowicz used, kept beside the
//! annealing so that a benchmark can show where a global search pays.
//!
//! Standard coefficients (reflection 1, expansion 2, contraction 1/2, shrink 1/2) and the
//! usual acceptance rules (Lagarias et al. 1998). Every point is clamped into the box, so the
//! search never evaluates outside it. No randomness: the same start and the same costs
//! give the same sequence. It stops when the evaluation budget is spent or the simplex has
//! collapsed to [`COLLAPSED`] of the box in every dimension.

use crate::anneal::{check_bounds, clamp_into};
use crate::error::Error;

/// Largest `D` supported: the simplex lives in fixed arrays of `MAX_DIMENSIONS + 1`
/// vertices (stable Rust cannot size an array by `D + 1`).
pub const MAX_DIMENSIONS: usize = 15;
const MAX_VERTICES: usize = MAX_DIMENSIONS + 1;

/// Simplex extent, as a fraction of each parameter's range, below which no further
/// evaluation can tell its vertices apart in any useful way.
pub const COLLAPSED: f64 = 1e-9;

const REFLECT: f64 = 1.0;
const EXPAND: f64 = 2.0;
const CONTRACT: f64 = 0.5;
const SHRINK: f64 = 0.5;

/// What the pending proposal is for.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase<const D: usize> {
    /// Evaluating initial vertex `i` (1..=D): the start stepped along axis `i - 1`.
    Init(usize),
    Reflect,
    Expand {
        reflected: [f64; D],
        cost: f64,
    },
    Contract {
        reflected: [f64; D],
        cost: f64,
        inside: bool,
    },
    /// Evaluating vertex `i` (1..=D) moved halfway towards the best.
    Shrink(usize),
    Collapsed,
}

/// The state of one Nelder-Mead search over `D` parameters.
pub struct NelderMead<const D: usize> {
    lower: [f64; D],
    upper: [f64; D],
    step: f64,
    /// Vertices `0..=D`; sorted by cost (best first) whenever the phase is `Reflect`.
    points: [[f64; D]; MAX_VERTICES],
    costs: [f64; MAX_VERTICES],
    phase: Phase<D>,
    pending: Option<[f64; D]>,
    evaluations: u32,
    max_evaluations: u32,
    best: [f64; D],
    best_cost: f64,
}

impl<const D: usize> NelderMead<D> {
    /// A search from `start` (clamped into the box) whose cost is `start_cost`; the first
    /// simplex steps `initial_step` of each range along each axis (inwards at a bound), and
    /// at most `max_evaluations` proposals are made.
    pub fn new(
        lower: [f64; D],
        upper: [f64; D],
        start: [f64; D],
        start_cost: f64,
        max_evaluations: u32,
        initial_step: f64,
    ) -> Result<NelderMead<D>, Error> {
        if D == 0 || D > MAX_DIMENSIONS {
            return Err(Error::InvalidValue {
                what: "Nelder-Mead dimensions: need 1..=MAX_DIMENSIONS",
            });
        }
        check_bounds(
            &lower,
            &upper,
            "Nelder-Mead bounds: need finite lower < upper, a finite width apart",
        )?;
        if !(initial_step > 0.0 && initial_step <= 1.0) {
            return Err(Error::InvalidValue {
                what: "Nelder-Mead initial step: need a fraction of the range in (0, 1]",
            });
        }
        let start = clamp_into(start, &lower, &upper);
        let cost = finite_or_worst(start_cost);
        let points = [start; MAX_VERTICES];
        let mut costs = [f64::INFINITY; MAX_VERTICES];
        costs[0] = cost;
        Ok(NelderMead {
            lower,
            upper,
            step: initial_step,
            points,
            costs,
            phase: Phase::Init(1),
            pending: None,
            evaluations: 0,
            max_evaluations,
            best: start,
            best_cost: cost,
        })
    }

    /// True when the budget is spent or the simplex has collapsed.
    pub fn is_done(&self) -> bool {
        self.evaluations >= self.max_evaluations || self.phase == Phase::Collapsed
    }

    /// The next point to evaluate (the same point until its cost is told).
    pub fn propose(&mut self) -> [f64; D] {
        if let Some(p) = self.pending {
            return p;
        }
        let p = self.point_for_phase();
        self.pending = Some(p);
        p
    }

    /// The cost of the last proposal.
    pub fn tell(&mut self, cost: f64) {
        let Some(p) = self.pending.take() else { return };
        let cost = finite_or_worst(cost);
        self.evaluations = self.evaluations.saturating_add(1);
        if cost < self.best_cost {
            self.best = p;
            self.best_cost = cost;
        }
        match self.phase {
            Phase::Init(i) | Phase::Shrink(i) => {
                self.points[i] = p;
                self.costs[i] = cost;
                if i == D {
                    self.start_iteration();
                } else {
                    self.phase = match self.phase {
                        Phase::Init(_) => Phase::Init(i + 1),
                        _ => Phase::Shrink(i + 1),
                    };
                }
            }
            Phase::Reflect => {
                if cost < self.costs[0] {
                    self.phase = Phase::Expand { reflected: p, cost };
                } else if cost < self.costs[D - 1] {
                    self.replace_worst(p, cost);
                } else {
                    self.phase = Phase::Contract {
                        reflected: p,
                        cost,
                        inside: cost >= self.costs[D],
                    };
                }
            }
            Phase::Expand {
                reflected,
                cost: reflected_cost,
            } => {
                if cost < reflected_cost {
                    self.replace_worst(p, cost);
                } else {
                    self.replace_worst(reflected, reflected_cost);
                }
            }
            Phase::Contract {
                cost: reflected_cost,
                inside,
                ..
            } => {
                let accept = if inside {
                    cost < self.costs[D]
                } else {
                    cost <= reflected_cost
                };
                if accept {
                    self.replace_worst(p, cost);
                } else {
                    self.phase = Phase::Shrink(1);
                }
            }
            Phase::Collapsed => {}
        }
    }

    /// The best point told so far and its cost.
    pub fn best(&self) -> ([f64; D], f64) {
        (self.best, self.best_cost)
    }

    pub fn evaluations(&self) -> u32 {
        self.evaluations
    }

    fn point_for_phase(&self) -> [f64; D] {
        let c = self.centroid();
        let towards = |from: &[f64; D], to: &[f64; D], t: f64| -> [f64; D] {
            let p = core::array::from_fn(|d| from[d] + t * (to[d] - from[d]));
            clamp_into(p, &self.lower, &self.upper)
        };
        match self.phase {
            Phase::Init(i) => {
                let mut p = self.points[0];
                let d = i - 1;
                let h = self.step * (self.upper[d] - self.lower[d]);
                p[d] = if p[d] + h <= self.upper[d] {
                    p[d] + h
                } else {
                    p[d] - h
                };
                clamp_into(p, &self.lower, &self.upper)
            }
            // c + a (c - worst) = c + (-a) (worst - c).
            Phase::Reflect => towards(&c, &self.points[D], -REFLECT),
            Phase::Expand { reflected, .. } => towards(&c, &reflected, EXPAND),
            Phase::Contract {
                reflected, inside, ..
            } => {
                if inside {
                    towards(&c, &self.points[D], CONTRACT)
                } else {
                    towards(&c, &reflected, CONTRACT)
                }
            }
            Phase::Shrink(i) => towards(&self.points[0], &self.points[i], SHRINK),
            Phase::Collapsed => self.best,
        }
    }

    /// The centroid of every vertex but the worst.
    fn centroid(&self) -> [f64; D] {
        let mut c = [0.0; D];
        for p in &self.points[..D] {
            for d in 0..D {
                c[d] += p[d];
            }
        }
        c.map(|x| x / D as f64)
    }

    fn replace_worst(&mut self, p: [f64; D], cost: f64) {
        self.points[D] = p;
        self.costs[D] = cost;
        self.start_iteration();
    }

    /// Orders the vertices (a stable insertion sort: ties keep their order, so the search
    /// is deterministic) and checks for collapse.
    fn start_iteration(&mut self) {
        for i in 1..=D {
            let mut j = i;
            while j > 0 && self.costs[j] < self.costs[j - 1] {
                self.costs.swap(j, j - 1);
                self.points.swap(j, j - 1);
                j -= 1;
            }
        }
        let collapsed = (0..D).all(|d| {
            let extent = self.points[1..=D]
                .iter()
                .map(|p| libm::fabs(p[d] - self.points[0][d]))
                .fold(0.0, f64::max);
            extent <= COLLAPSED * (self.upper[d] - self.lower[d])
        });
        self.phase = if collapsed {
            Phase::Collapsed
        } else {
            Phase::Reflect
        };
    }
}

/// A NaN cost is the worst possible, so that it is never kept.
fn finite_or_worst(cost: f64) -> f64 {
    if cost.is_nan() {
        f64::INFINITY
    } else {
        cost
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// Runs a search to its end; returns the best and every proposal made.
    fn run<const D: usize>(
        f: impl Fn(&[f64; D]) -> f64,
        lo: [f64; D],
        hi: [f64; D],
        start: [f64; D],
        budget: u32,
    ) -> (([f64; D], f64), Vec<[f64; D]>) {
        let mut nm = NelderMead::new(lo, hi, start, f(&start), budget, 0.25).unwrap();
        let mut proposals = Vec::new();
        while !nm.is_done() {
            let p = nm.propose();
            assert_eq!(nm.propose(), p, "a proposal repeats until told");
            proposals.push(p);
            nm.tell(f(&p));
        }
        assert_eq!(nm.evaluations() as usize, proposals.len());
        (nm.best(), proposals)
    }

    #[test]
    fn finds_the_minimum_of_a_shifted_quadratic() {
        let f = |p: &[f64; 2]| {
            let (a, b) = (p[0] - 0.3, p[1] + 0.2);
            a * a + 4.0 * b * b + a * b
        };
        let ((best, cost), proposals) = run(f, [-1.0; 2], [1.0; 2], [0.0; 2], 100);
        assert!(cost < 1e-8, "cost {cost} at {best:?}");
        assert!((best[0] - 0.3).abs() < 1e-3 && (best[1] + 0.2).abs() < 1e-3);
        assert!(proposals.len() <= 100);
    }

    #[test]
    fn follows_the_rosenbrock_valley_within_budget() {
        let f = |p: &[f64; 2]| {
            let (a, b) = (1.0 - p[0], p[1] - p[0] * p[0]);
            a * a + 100.0 * b * b
        };
        let ((best, cost), proposals) = run(f, [-2.0; 2], [2.0; 2], [-1.2, 1.0], 400);
        assert!(cost < 1e-6, "cost {cost} at {best:?}");
        assert!((best[0] - 1.0).abs() < 1e-2 && (best[1] - 1.0).abs() < 2e-2);
        assert!(proposals.len() <= 400);
    }

    #[test]
    fn stays_inside_the_box_and_reaches_the_bound() {
        // The unconstrained minimum (2, -3) lies outside: the best in the box is (1, 0).
        let f = |p: &[f64; 2]| (p[0] - 2.0) * (p[0] - 2.0) + (p[1] + 3.0) * (p[1] + 3.0);
        let ((best, _), proposals) = run(f, [0.0, 0.0], [1.0, 1.0], [0.9, 0.9], 200);
        assert!(proposals
            .iter()
            .all(|p| (0.0..=1.0).contains(&p[0]) && (0.0..=1.0).contains(&p[1])));
        assert!(best[0] > 1.0 - 1e-6 && best[1] < 1e-6, "{best:?}");
    }

    #[test]
    fn is_deterministic() {
        let f = |p: &[f64; 3]| {
            let d = p[1] * p[2] - 0.2;
            (p[0] - 0.1).abs() + d * d + p[2] * p[2]
        };
        let a = run(f, [-1.0; 3], [1.0; 3], [0.5; 3], 150);
        let b = run(f, [-1.0; 3], [1.0; 3], [0.5; 3], 150);
        assert_eq!(a, b);
    }

    #[test]
    fn spends_exactly_its_budget_unless_collapsed() {
        let f = |p: &[f64; 2]| p[0] * p[0] + p[1] * p[1];
        let (_, proposals) = run(f, [-1.0; 2], [1.0; 2], [0.7, -0.4], 17);
        assert_eq!(proposals.len(), 17);
        // A constant cost gives nothing to follow: the simplex shrinks until collapsed.
        let (_, proposals) = run(|_: &[f64; 2]| 1.0, [-1.0; 2], [1.0; 2], [0.0; 2], 10_000);
        assert!(proposals.len() < 10_000, "{}", proposals.len());
    }

    #[test]
    fn stays_in_the_local_minimum_it_starts_in() {
        // The annealer's two-well test: a shallow well at -0.6 (start), the deep one at
        // 0.7. A local search stays in the shallow one; this is the difference the
        // tradeoff benchmark measures.
        let f = |p: &[f64; 1]| {
            let x = p[0];
            -0.3 * libm::exp(-((x + 0.6) * (x + 0.6)) / 0.01)
                - 1.0 * libm::exp(-((x - 0.7) * (x - 0.7)) / 0.01)
        };
        let ((best, _), _) = run(f, [-1.0], [1.0], [-0.55], 200);
        assert!((best[0] + 0.6).abs() < 0.01, "{best:?}");
    }

    #[test]
    fn nan_costs_are_never_kept() {
        // NaN left of 0.5: the search must not settle there.
        let f = |p: &[f64; 1]| {
            if p[0] < 0.5 {
                f64::NAN
            } else {
                (p[0] - 0.8) * (p[0] - 0.8)
            }
        };
        let ((best, cost), _) = run(f, [0.0], [1.0], [0.6], 100);
        assert!(cost.is_finite() && (best[0] - 0.8).abs() < 1e-3, "{best:?}");
    }

    #[test]
    fn bad_bounds_and_steps_are_errors() {
        assert!(NelderMead::new([1.0], [0.0], [0.5], 0.0, 10, 0.25).is_err());
        assert!(NelderMead::new([0.0], [f64::NAN], [0.5], 0.0, 10, 0.25).is_err());
        assert!(NelderMead::new([-1e308], [1e308], [0.5], 0.0, 10, 0.25).is_err());
        assert!(NelderMead::new([0.0], [1.0], [0.5], 0.0, 10, 0.0).is_err());
        assert!(NelderMead::new([0.0], [1.0], [0.5], 0.0, 10, 1.5).is_err());
        assert!(NelderMead::<0>::new([], [], [], 0.0, 10, 0.25).is_err());
        assert!(NelderMead::new([0.0], [1.0], [0.5], 0.0, 0, 0.25)
            .unwrap()
            .is_done());
    }
}
