//! Student's t distribution, for tests whose standard error is itself estimated from few
//! degrees of freedom: a comparison over `n` pixels estimates its render noise from `n`
//! squared differences (`fit::ModelComparison`), so its z is t with `n` degrees of freedom,
//! and at 15 pixels a normal z of 3 is passed on noise alone 3.5 times as often as the
//! normal says.

/// Degrees of freedom from which [`critical_value`] uses the Cornish-Fisher expansion in
/// `1 / df` instead of inverting the exact distribution (its error there is below 1e-6).
const EXPANSION_FROM: u32 = 100;

/// Degrees of freedom up to which [`upper_tail`] sums its exact series (one term per two
/// degrees of freedom: 50,000 at most); past them it takes the normal tail of Abramowitz
/// and Stegun's 26.7.8 transform, whose error there is below 1e-11.
const SERIES_TO: u32 = 100_000;

/// The probability that t with `df` degrees of freedom exceeds `t` (for `t >= 0`), from
/// the exact finite sums for whole degrees of freedom (Abramowitz and Stegun 26.7.3-4) up
/// to `SERIES_TO`, whose cost grows with `df`, and from a transform to the normal
/// past it. With no degrees of freedom, 0.5 (nothing is known).
pub fn upper_tail(t: f64, df: u32) -> f64 {
    if df == 0 {
        return 0.5;
    }
    let nu = df as f64;
    if df > SERIES_TO {
        let x = t * (1.0 - 0.25 / nu) / libm::sqrt(1.0 + t * t / (2.0 * nu));
        return normal_upper_tail(x);
    }
    let theta = libm::atan(t.abs() / libm::sqrt(nu));
    let (s, c) = (libm::sin(theta), libm::cos(theta));
    let c2 = c * c;
    // Two-sided: the probability that |T| <= t.
    let within = if df % 2 == 1 {
        // 2/pi [theta + sin cos (1 + 2/3 cos^2 + (2 4)/(3 5) cos^4 + ...)], up to cos^(df-2).
        let (mut term, mut sum) = (1.0, 0.0);
        if df > 1 {
            sum = 1.0;
            let mut k = 2;
            while k + 1 < df {
                term *= c2 * k as f64 / (k + 1) as f64;
                sum += term;
                k += 2;
            }
        }
        core::f64::consts::FRAC_2_PI * (theta + s * c * sum)
    } else {
        // sin [1 + 1/2 cos^2 + (1 3)/(2 4) cos^4 + ...], up to cos^(df-2).
        let (mut term, mut sum) = (1.0, 1.0);
        let mut k = 1;
        while k + 1 < df {
            term *= c2 * k as f64 / (k + 1) as f64;
            sum += term;
            k += 2;
        }
        s * sum
    };
    let tail = 0.5 * (1.0 - within);
    if t >= 0.0 {
        tail
    } else {
        1.0 - tail
    }
}

/// The value t with `df` degrees of freedom exceeds with probability `p` (`0 < p < 0.5`;
/// NaN outside it, where the bisection's bracket would grow without end). With no degrees
/// of freedom no value is known to be exceeded that rarely: infinity, which no test passes.
pub fn critical_value(p: f64, df: u32) -> f64 {
    if !(p > 0.0 && p < 0.5) {
        return f64::NAN;
    }
    if df == 0 {
        return f64::INFINITY;
    }
    let z = normal_critical_value(p);
    if df >= EXPANSION_FROM {
        return cornish_fisher(z, df as f64);
    }
    // Bisection on the exact tail: t's quantile is above the normal's. The bracket
    // doubles some 1,000 times at most (one degree of freedom, p near the smallest
    // double), and stops at infinity.
    let (mut lo, mut hi) = (z, z.max(1.0));
    while upper_tail(hi, df) > p {
        if !hi.is_finite() {
            return f64::INFINITY;
        }
        hi *= 2.0;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if upper_tail(mid, df) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The probability that a standard normal exceeds `z`.
pub fn normal_upper_tail(z: f64) -> f64 {
    0.5 * libm::erfc(z / core::f64::consts::SQRT_2)
}

/// The value a standard normal exceeds with probability `p` (`0 < p < 0.5`), by bisection.
fn normal_critical_value(p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 40.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if normal_upper_tail(mid) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// t's quantile from the normal's `z` by the Cornish-Fisher expansion in `1 / nu`
/// (Abramowitz and Stegun 26.7.5).
fn cornish_fisher(z: f64, nu: f64) -> f64 {
    let z2 = z * z;
    let g1 = z * (z2 + 1.0) / 4.0;
    let g2 = z * ((5.0 * z2 + 16.0) * z2 + 3.0) / 96.0;
    let g3 = z * (((3.0 * z2 + 19.0) * z2 + 17.0) * z2 - 15.0) / 384.0;
    let g4 = z * ((((79.0 * z2 + 776.0) * z2 + 1482.0) * z2 - 1920.0) * z2 - 945.0) / 92160.0;
    z + (g1 + (g2 + (g3 + g4 / nu) / nu) / nu) / nu
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tails_match_the_closed_forms_of_one_and_two_degrees_of_freedom() {
        for t in [0.0, 0.3, 1.0, 2.5, 7.0, 40.0] {
            // One degree of freedom: Cauchy. Two: 1/2 - t / (2 sqrt(t^2 + 2)).
            let cauchy = 0.5 - libm::atan(t) / core::f64::consts::PI;
            let two = 0.5 - t / (2.0 * libm::sqrt(t * t + 2.0));
            assert!((upper_tail(t, 1) - cauchy).abs() < 1e-14, "t {t}");
            assert!((upper_tail(t, 2) - two).abs() < 1e-14, "t {t}");
        }
        assert!((upper_tail(-1.0, 1) - (1.0 - upper_tail(1.0, 1))).abs() < 1e-15);
    }

    #[test]
    fn the_critical_values_invert_the_tails_and_tend_to_the_normal() {
        let p = normal_upper_tail(3.0);
        assert!((p - 0.001_349_898).abs() < 1e-9, "{p}");
        // Cauchy's quantile is tan(pi (1/2 - p)).
        let cauchy = libm::tan(core::f64::consts::PI * (0.5 - p));
        assert!((critical_value(p, 1) - cauchy).abs() < 1e-6 * cauchy);
        for df in [2, 3, 5, 15, 40, 99] {
            let t = critical_value(p, df);
            assert!((upper_tail(t, df) - p).abs() < 1e-12, "df {df}");
        }
        // The expansion takes over where the exact inversion left off, continuously.
        let (exact, expanded) = (critical_value(p, 99), cornish_fisher(3.0, 99.0));
        assert!((exact - expanded).abs() < 1e-5, "{exact} {expanded}");
        assert!((upper_tail(critical_value(p, 100), 100) - p).abs() < 1e-8);
        // Falling towards the normal's 3 as the degrees of freedom grow.
        let values: [f64; 6] = [15, 16, 80, 100, 1000, 1_000_000].map(|df| critical_value(p, df));
        assert!(values.windows(2).all(|w| w[0] > w[1]), "{values:?}");
        assert!((values[0] - 3.59).abs() < 0.01 && (values[5] - 3.0).abs() < 1e-4);
    }

    #[test]
    fn no_degrees_of_freedom_and_very_many_answer_at_once() {
        // df 0 once doubled the bisection's bracket for ever; 4e9 summed 2e9 terms.
        assert_eq!(critical_value(0.01, 0), f64::INFINITY);
        assert_eq!(upper_tail(2.0, 0), 0.5);
        let p = normal_upper_tail(3.0);
        for df in [SERIES_TO + 1, 1 << 24, u32::MAX] {
            // Above the normal's tail, by less as df grows (24 / df of it at t = 3).
            let tail = upper_tail(3.0, df);
            assert!(
                tail > p && tail - p < 30.0 / df as f64 * p,
                "df {df}: {tail}"
            );
            assert!(critical_value(p, df).is_finite());
        }
        // The series and the transform meet where one takes over from the other.
        for t in [0.0, 0.5, 2.0, 4.0, 8.0] {
            let (series, transform) = (upper_tail(t, SERIES_TO), upper_tail(t, SERIES_TO + 1));
            assert!(
                (series - transform).abs() < 1e-9,
                "t {t}: {series} {transform}"
            );
        }
        // The smallest probabilities with one degree of freedom end too: the tail's
        // doubles reach 0 near t = 1e16, where its bracket stops growing.
        for p in [1e-300, f64::MIN_POSITIVE, 5e-324] {
            let t = critical_value(p, 1);
            assert!(t > 1e15, "p {p}: {t}");
        }
    }

    #[test]
    fn a_probability_outside_the_upper_half_has_no_critical_value() {
        // A negative p once doubled the bisection's bracket for ever.
        for p in [-0.1, 0.0, 0.5, 0.7, f64::NAN, f64::INFINITY] {
            for df in [1, 5, 99, 100] {
                assert!(critical_value(p, df).is_nan(), "p {p} df {df}");
            }
        }
    }
}
