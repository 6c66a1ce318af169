//! Stage 2: the isotropic Ward model (RADIANCE plastic / metal).
//!
//! Under a Ward material a pixel is linear in the reflectances: `I = rho_d * D + S * B(a)`
//! per channel, where `D` is the pixel for `rho_d = 1, S = 0` and `B(a)` the pixel for a
//! unit specular lobe of roughness `a` (both from [`crate::transport`]'s cache). So for a
//! given roughness the best reflectances are a linear least-squares problem, solved here in
//! closed form, and only the roughness is searched, globally: a log-spaced grid over the
//! paper's range, then golden-section refinement around the best grid point.
//!
//! Plastic: `rho_d` per channel and one white specularity `s` (S = s).
//! Metal: one colour `c` per channel and one `s`, with `rho_d = c (1 - s)`, `S = c s`.

use crate::material::Kind;

/// Roughness bounds of the search (the paper's Table 2 range; reflectance.md keeps it in
/// (0, 0.3]; below the lower bound a group is tested as a mirror).
pub const ROUGHNESS_MIN: f64 = 0.005;
pub const ROUGHNESS_MAX: f64 = 0.3;
/// Grid points of the roughness search (log-spaced), before refinement.
pub const ROUGHNESS_GRID: usize = 32;
/// Golden-section steps after the grid.
pub const ROUGHNESS_REFINE_STEPS: usize = 24;

/// Per-channel sums of the normal equations over a group's pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LinearSums {
    /// sum D^2, sum D B, sum B^2, sum D T, sum B T, sum T^2 per channel.
    pub dd: [f64; 3],
    pub db: [f64; 3],
    pub bb: [f64; 3],
    pub dt: [f64; 3],
    pub bt: [f64; 3],
    pub tt: [f64; 3],
}

impl LinearSums {
    pub fn add(&mut self, d: [f32; 3], b: [f32; 3], t: [f32; 3]) {
        for c in 0..3 {
            let (d, b, t) = (d[c] as f64, b[c] as f64, t[c] as f64);
            self.dd[c] += d * d;
            self.db[c] += d * b;
            self.bb[c] += b * b;
            self.dt[c] += d * t;
            self.bt[c] += b * t;
            self.tt[c] += t * t;
        }
    }

    /// Adds one pixel whose parts come from two independent halves of its samples
    /// (`d[0], b[0]` and `d[1], b[1]`). The squares and products of the normal equations
    /// are taken across the halves (`D_a D_b`, not `D^2`): their expectations are those of
    /// the noise-free parts, where a part's square also holds its sampling variance. That
    /// variance pulls a least-squares fit through noisy regressors towards zero and trades
    /// between the two parts (errors in variables); on a large group with few samples per
    /// pixel it is what the fit sees most. `D` and `B` cannot be negative, so neither can the
    /// cross squares; the 2x2 system may still be indefinite, which the solvers read as no
    /// specular part.
    pub fn add_halves(&mut self, d: [[f32; 3]; 2], b: [[f32; 3]; 2], t: [f32; 3]) {
        for c in 0..3 {
            let [da, db] = [d[0][c] as f64, d[1][c] as f64];
            let [ba, bb] = [b[0][c] as f64, b[1][c] as f64];
            let t = t[c] as f64;
            self.dd[c] += da * db;
            self.db[c] += 0.5 * (da * bb + db * ba);
            self.bb[c] += ba * bb;
            self.dt[c] += 0.5 * (da + db) * t;
            self.bt[c] += 0.5 * (ba + bb) * t;
            self.tt[c] += t * t;
        }
    }

    /// Adds the sums of another part of the same group (in a fixed order).
    pub fn merge(&mut self, other: &LinearSums) {
        for c in 0..3 {
            self.dd[c] += other.dd[c];
            self.db[c] += other.db[c];
            self.bb[c] += other.bb[c];
            self.dt[c] += other.dt[c];
            self.bt[c] += other.bt[c];
            self.tt[c] += other.tt[c];
        }
    }

    /// Sum of squared residuals of `T ~ r D + S B` per channel.
    fn sse(&self, r: [f64; 3], s: [f64; 3]) -> f64 {
        (0..3)
            .map(|c| {
                self.tt[c] - 2.0 * (r[c] * self.dt[c] + s[c] * self.bt[c])
                    + r[c] * r[c] * self.dd[c]
                    + 2.0 * r[c] * s[c] * self.db[c]
                    + s[c] * s[c] * self.bb[c]
            })
            .sum::<f64>()
            .max(0.0)
    }

    fn total_tt(&self) -> f64 {
        self.tt[0] + self.tt[1] + self.tt[2]
    }
}

/// The best reflectances for one roughness.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WardFit {
    /// RADIANCE colour (a1 a2 a3).
    pub color: [f64; 3],
    /// RADIANCE specularity (a4).
    pub specularity: f64,
    pub rho_d: [f64; 3],
    pub rho_s: [f64; 3],
    /// Sum of squared residuals.
    pub sse: f64,
    /// `sqrt(sse / sum T^2)`: the relative error of this fit over the cached pixels.
    pub relative_error: f64,
}

fn finish(sums: &LinearSums, rho_d: [f64; 3], rho_s: [f64; 3], color: [f64; 3], s: f64) -> WardFit {
    let sse = sums.sse(rho_d, rho_s);
    let tt = sums.total_tt();
    WardFit {
        color,
        specularity: s,
        rho_d,
        rho_s,
        sse,
        relative_error: if tt > 0.0 { libm::sqrt(sse / tt) } else { 0.0 },
    }
}

/// Plastic: minimise over `rho_d` (3) and `s` with `S = s` white; `s` in [0, 1],
/// `rho_d` in [0, 1 - s] (1 itself with no lobe), colour = rho_d / (1 - s) kept <= 1.
pub fn solve_plastic(sums: &LinearSums) -> WardFit {
    // Eliminate rho_d_c = (dt_c - s db_c) / dd_c, then solve for s.
    let mut num = 0.0;
    let mut den = 0.0;
    for c in 0..3 {
        let q = sums.bb[c];
        num += sums.bt[c];
        den += q;
        if sums.dd[c] > 0.0 {
            num -= sums.db[c] * sums.dt[c] / sums.dd[c];
            den -= sums.db[c] * sums.db[c] / sums.dd[c];
        }
    }
    let s = if den > 0.0 {
        (num / den).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let rho_d: [f64; 3] = core::array::from_fn(|c| {
        if sums.dd[c] > 0.0 {
            ((sums.dt[c] - s * sums.db[c]) / sums.dd[c]).clamp(0.0, (1.0 - s).max(0.0))
        } else {
            0.0
        }
    });
    let color = core::array::from_fn(|c| {
        if s < 1.0 {
            (rho_d[c] / (1.0 - s)).min(1.0)
        } else {
            0.0
        }
    });
    finish(sums, rho_d, [s; 3], color, s)
}

/// The best reflectances for a lobe of `kind` ([`solve_plastic`] or [`solve_metal`]).
pub fn solve(kind: Kind, sums: &LinearSums) -> WardFit {
    match kind {
        Kind::Plastic => solve_plastic(sums),
        Kind::Metal => solve_metal(sums),
    }
}

/// Diffuse only (`S = 0`): the stage-1 model on the same pixels, for a like-for-like
/// comparison with the Ward fits.
pub fn solve_diffuse(sums: &LinearSums) -> WardFit {
    let rho_d: [f64; 3] = core::array::from_fn(|c| {
        if sums.dd[c] > 0.0 {
            (sums.dt[c] / sums.dd[c]).clamp(0.0, 1.0)
        } else {
            0.0
        }
    });
    finish(sums, rho_d, [0.0; 3], rho_d, 0.0)
}

/// Metal: minimise over colour `c` (3) and `s`, `rho_d = c (1 - s)`, `S = c s`. For a given
/// `s` each channel's colour is closed-form; `s` is found by a fine scan of [0, 1] (cheap:
/// sums only), refined by golden section.
pub fn solve_metal(sums: &LinearSums) -> WardFit {
    let colors_for = |s: f64| -> [f64; 3] {
        core::array::from_fn(|c| {
            let gg = (1.0 - s) * (1.0 - s) * sums.dd[c]
                + 2.0 * s * (1.0 - s) * sums.db[c]
                + s * s * sums.bb[c];
            let gt = (1.0 - s) * sums.dt[c] + s * sums.bt[c];
            if gg > 0.0 {
                (gt / gg).clamp(0.0, 1.0)
            } else {
                0.0
            }
        })
    };
    let sse_for = |s: f64| {
        let c = colors_for(s);
        sums.sse(
            core::array::from_fn(|k| c[k] * (1.0 - s)),
            core::array::from_fn(|k| c[k] * s),
        )
    };
    let (s, _) = minimise_1d(sse_for, 0.0, 1.0, 101, 30, false);
    let c = colors_for(s);
    finish(
        sums,
        core::array::from_fn(|k| c[k] * (1.0 - s)),
        core::array::from_fn(|k| c[k] * s),
        c,
        s,
    )
}

/// Global minimum of `f` on `[lo, hi]`: `n_grid` grid points (log-spaced when `log`), then
/// golden-section search in the bracket around the best one. Returns `(x, f(x))`.
pub fn minimise_1d(
    mut f: impl FnMut(f64) -> f64,
    lo: f64,
    hi: f64,
    n_grid: usize,
    refine_steps: usize,
    log: bool,
) -> (f64, f64) {
    let n = n_grid.max(2);
    let at = |i: usize| -> f64 {
        let t = i as f64 / (n - 1) as f64;
        if log {
            lo * libm::pow(hi / lo, t)
        } else {
            lo + (hi - lo) * t
        }
    };
    let mut best_i = 0;
    let mut best = f64::INFINITY;
    for i in 0..n {
        let v = f(at(i));
        if v < best {
            best = v;
            best_i = i;
        }
    }
    let mut a = at(best_i.saturating_sub(1));
    let mut b = at((best_i + 1).min(n - 1));
    let mut best_x = at(best_i);
    const INV_PHI: f64 = 0.618_033_988_749_894_9;
    let mut x1 = b - INV_PHI * (b - a);
    let mut x2 = a + INV_PHI * (b - a);
    let mut f1 = f(x1);
    let mut f2 = f(x2);
    for _ in 0..refine_steps {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - INV_PHI * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + INV_PHI * (b - a);
            f2 = f(x2);
        }
    }
    for (x, v) in [(x1, f1), (x2, f2)] {
        if v < best {
            best = v;
            best_x = x;
        }
    }
    (best_x, best)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Synthetic pixels: D and B vary from pixel to pixel (as irradiance and highlights do).
    fn sums_for(rho_d: [f64; 3], rho_s: [f64; 3]) -> LinearSums {
        let mut s = LinearSums::default();
        for i in 0..200 {
            let x = i as f32 / 200.0;
            let d = [0.2 + x, 0.3 + 0.5 * x, 0.25 + 0.2 * x];
            let bump = libm::expf(-((x - 0.5) * (x - 0.5)) / 0.01) * 3.0 + 0.05;
            let b = [bump, bump * 0.9, bump * 1.1];
            let t: [f32; 3] =
                core::array::from_fn(|c| (rho_d[c] * d[c] as f64 + rho_s[c] * b[c] as f64) as f32);
            s.add(d, b, t);
        }
        s
    }

    /// A noisy group: `PIXELS` pixels whose parts are each estimated twice from few
    /// samples (the diffuse part within +-80%, the lobe's all or nothing, as a sharp lobe's
    /// few samples are), the panorama exact; the noise drawn from stream `key`. Returns the
    /// sums from both halves' mean (`add`) and across the halves (`add_halves`).
    fn noisy_sums(rho_d: [f64; 3], s: f64, key: u64) -> (LinearSums, LinearSums) {
        const PIXELS: usize = 16_000;
        let mut rng = crate::rng::Sampler::from_key(key);
        let (mut mean, mut cross) = (LinearSums::default(), LinearSums::default());
        for i in 0..PIXELS {
            let x = (i % 200) as f32 / 200.0;
            let d = [0.2 + x, 0.3 + 0.5 * x, 0.25 + 0.2 * x];
            let bump = libm::expf(-((x - 0.5) * (x - 0.5)) / 0.01) * 3.0 + 0.05;
            let t: [f32; 3] =
                core::array::from_fn(|c| (rho_d[c] * d[c] as f64 + s * bump as f64) as f32);
            let mut half = || {
                let u = 0.2 + 1.6 * rng.next_f32();
                let v = if rng.next_f32() < 0.5 { 0.0 } else { 2.0 };
                (d.map(|d| d * u), [bump * v; 3])
            };
            let ((da, ba), (db, bb)) = (half(), half());
            let avg = |a: [f32; 3], b: [f32; 3]| core::array::from_fn(|c| 0.5 * (a[c] + b[c]));
            mean.add(avg(da, db), avg(ba, bb), t);
            cross.add_halves([da, db], [ba, bb], t);
        }
        (mean, cross)
    }

    /// Over eight noisy groups the fit across halves is centred on the truth, where the
    /// plain sums of the same pixels are pulled low every time (specularity by a quarter,
    /// the red reflectance by 8%).
    #[test]
    fn sums_across_halves_take_the_sampling_noise_out_of_the_fit() {
        let (rho_d, s) = ([0.45, 0.28, 0.15], 0.05);
        const GROUPS: u64 = 8;
        let (mut mean_s, mut mean_rho) = (0.0, [0.0; 3]);
        for key in 1..=GROUPS {
            let (mean, cross) = noisy_sums(rho_d, s, key);
            let biased = solve_plastic(&mean);
            assert!(biased.specularity < 0.85 * s, "{biased:?}");
            assert!(biased.rho_d[0] < 0.95 * rho_d[0], "{biased:?}");
            let fit = solve_plastic(&cross);
            mean_s += fit.specularity / GROUPS as f64;
            for (mean, rho) in mean_rho.iter_mut().zip(fit.rho_d) {
                *mean += rho / GROUPS as f64;
            }
        }
        assert!((mean_s - s).abs() < 0.04 * s, "{mean_s}");
        for (got, want) in mean_rho.iter().zip(rho_d) {
            assert!((got - want).abs() < 0.015 * want, "{mean_rho:?}");
        }
        // Noise-free halves give the plain sums.
        let mut plain = LinearSums::default();
        let mut halves = LinearSums::default();
        plain.add([0.3, 0.2, 0.1], [1.5, 1.5, 1.5], [0.2, 0.1, 0.05]);
        halves.add_halves([[0.3, 0.2, 0.1]; 2], [[1.5, 1.5, 1.5]; 2], [0.2, 0.1, 0.05]);
        assert_eq!(plain, halves);
    }

    #[test]
    fn plastic_reflectances_are_recovered_exactly_from_exact_data() {
        let fit = solve_plastic(&sums_for([0.4, 0.3, 0.1], [0.06; 3]));
        assert!((fit.specularity - 0.06).abs() < 1e-5, "{fit:?}");
        for (got, want) in fit.rho_d.iter().zip([0.4, 0.3, 0.1]) {
            assert!((got - want).abs() < 1e-5, "{fit:?}");
        }
        assert!(fit.relative_error < 1e-4);
    }

    #[test]
    fn metal_colour_and_specularity_are_recovered_from_exact_data() {
        let (c, s) = ([0.9, 0.7, 0.35], 0.9);
        let fit = solve_metal(&sums_for(c.map(|c| c * (1.0 - s)), c.map(|c| c * s)));
        assert!((fit.specularity - s).abs() < 1e-3, "{fit:?}");
        for (got, want) in fit.color.iter().zip(c) {
            assert!((got - want).abs() < 2e-3, "{fit:?}");
        }
    }

    #[test]
    fn a_diffuse_group_gets_no_specularity() {
        let fit = solve_plastic(&sums_for([0.5, 0.5, 0.5], [0.0; 3]));
        assert!(fit.specularity < 1e-6, "{fit:?}");
    }

    #[test]
    fn minimise_1d_finds_a_narrow_global_minimum_on_a_log_grid() {
        let target = 0.037f64;
        let f = |a: f64| {
            let d = libm::log(a / target);
            d * d - 0.5 * libm::exp(-d * d / 0.01)
        };
        let (x, _) = minimise_1d(
            f,
            ROUGHNESS_MIN,
            ROUGHNESS_MAX,
            ROUGHNESS_GRID,
            ROUGHNESS_REFINE_STEPS,
            true,
        );
        assert!((x / target - 1.0).abs() < 1e-3, "{x}");
    }
}
