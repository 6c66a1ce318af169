//! Where in a pixel its samples fall: stratified, in two independent halves.
//!
//! A pixel whose footprint holds detail (a statue's facets, a reflection's edges in a
//! mirror, a picture's texels) is noisy mostly by where its samples land, and plain Monte
//! Carlo points clump. So a pixel's points are the 2D Sobol' sequence (a (0,2)-sequence:
//! every power-of-two prefix puts one point in each of its elementary intervals, the
//! `k x k` squares among them), randomised by Owen's nested uniform scrambling, hashed as
//! Burley's "Practical Hash-based Owen Scrambling" (JCGT 2020) does. A scrambled net is
//! still a net, and each point is uniform over the pixel, so the pixel's mean is unbiased.
//!
//! **Two halves.** Samples `0..spp/2` and `spp/2..spp` are two sequences of their own,
//! scrambled independently. Strata over the whole set would give each half half of the
//! pixel, and halves are what the noise is measured across: the transport cache fits
//! across the halves of one trace, and a render's variance is estimated from the
//! difference of its halves' means (a stratified mean's variance is not the sample
//! variance over `n`). Each half is stratified on its own, and the two are independent.

use crate::rng::{stream_key, unit_f32};

/// The half a sample of `spp` belongs to (0 or 1) and its index within that half.
#[inline]
pub fn half_of(sample: u32, spp: u32) -> (u32, u32) {
    let first = spp / 2;
    if sample < first {
        (0, sample)
    } else {
        (1, sample - first)
    }
}

/// Sample `sample` of `spp` of a pixel: its point in the unit square (`[0, 1)^2`), from
/// the scrambled sequence of its half, keyed by `(seed, view, pixel, half)`.
#[inline]
pub fn pixel_point(seed: u64, view: u32, pixel: u32, sample: u32, spp: u32) -> [f32; 2] {
    let (half, index) = half_of(sample, spp);
    let key = stream_key(&[seed, view as u64, pixel as u64, half as u64, 0x0571_7A7A]);
    let (seed_x, seed_y) = (key as u32, (key >> 32) as u32);
    [
        unit_f32(owen_scramble(index.reverse_bits(), seed_x)),
        unit_f32(owen_scramble(sobol_second(index), seed_y)),
    ]
}

/// The second dimension of the Sobol' sequence (primitive polynomial `x + 1`, whose
/// direction numbers are Pascal's triangle mod 2), as a 32-bit fraction. The first is
/// the van der Corput sequence, `index.reverse_bits()`.
#[inline]
fn sobol_second(mut index: u32) -> u32 {
    let mut direction = 1u32 << 31;
    let mut x = 0u32;
    while index != 0 {
        if index & 1 != 0 {
            x ^= direction;
        }
        index >>= 1;
        direction ^= direction >> 1;
    }
    x
}

/// Owen's nested uniform scrambling of a 32-bit fraction: each bit flipped by a hash of
/// the bits above it. On the reversed bits that is a hash in which a bit depends only on
/// the bits below it, which integer multiplies, adds and xors give (Burley's constants).
#[inline]
fn owen_scramble(x: u32, seed: u32) -> u32 {
    let mut v = x.reverse_bits();
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^= v.wrapping_mul(0x53a2_2864);
    v.reverse_bits()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The strata a set of points fills, `k x k` of the unit square.
    fn strata_filled(points: &[[f32; 2]], k: usize) -> std::vec::Vec<usize> {
        let mut count = std::vec![0usize; k * k];
        for p in points {
            let (i, j) = ((p[0] * k as f32) as usize, (p[1] * k as f32) as usize);
            count[j * k + i] += 1;
        }
        count
    }

    /// Each half of a power-of-two count is a net: one point in each of its `k x k`
    /// squares and in each of its `1 x n` and `n x 1` slabs.
    #[test]
    fn each_half_puts_one_point_in_each_stratum() {
        for (spp, k) in [(32u32, 4usize), (128, 8), (2, 1)] {
            for pixel in 0..20 {
                for half in 0..2 {
                    let start = half * spp / 2;
                    let points: std::vec::Vec<[f32; 2]> = (start..start + spp / 2)
                        .map(|s| pixel_point(9, 1, pixel, s, spp))
                        .collect();
                    assert!(strata_filled(&points, k).iter().all(|&c| c == 1));
                    let n = points.len();
                    for axis in 0..2 {
                        let mut slab = std::vec![0usize; n];
                        for p in &points {
                            slab[(p[axis] * n as f32) as usize] += 1;
                        }
                        assert!(slab.iter().all(|&c| c == 1), "axis {axis}, {spp} spp");
                    }
                }
            }
        }
    }

    /// The halves are scrambled independently: their points differ, and each pixel,
    /// view and seed has its own scrambling.
    #[test]
    fn halves_pixels_and_seeds_are_scrambled_apart() {
        let first = pixel_point(9, 1, 5, 0, 16);
        assert_ne!(first, pixel_point(9, 1, 5, 8, 16), "the second half");
        assert_ne!(first, pixel_point(9, 1, 6, 0, 16), "another pixel");
        assert_ne!(first, pixel_point(9, 2, 5, 0, 16), "another view");
        assert_ne!(first, pixel_point(10, 1, 5, 0, 16), "another seed");
        assert_eq!(first, pixel_point(9, 1, 5, 0, 16), "reproducible");
        assert_eq!(half_of(6, 15), (0, 6), "15 samples: 7 in the first half");
        assert_eq!(half_of(7, 15), (1, 0));
        assert_eq!(half_of(14, 15), (1, 7), "and 8 in the second");
        assert_eq!(
            half_of(0, 1),
            (1, 0),
            "a single sample is the second half's first"
        );
    }

    /// Scrambled points are uniform over the square: the mean of a function over many
    /// pixels' points is its integral (here x*y, whose integral is 1/4), and the
    /// stratified estimate of each pixel is far closer to it than plain sampling's.
    #[test]
    fn points_are_uniform_and_a_pixel_mean_is_unbiased() {
        let (pixels, spp) = (4000u32, 16u32);
        let (mut total, mut sq_err) = (0.0f64, 0.0f64);
        for pixel in 0..pixels {
            let mean = (0..spp)
                .map(|s| {
                    let [x, y] = pixel_point(3, 0, pixel, s, spp);
                    (x * y) as f64
                })
                .sum::<f64>()
                / spp as f64;
            total += mean;
            sq_err += (mean - 0.25) * (mean - 0.25);
        }
        let grand = total / pixels as f64;
        assert!((grand - 0.25).abs() < 1e-3, "mean {grand}");
        // Plain sampling's variance of a 16-sample mean of x*y is (1/9 - 1/16)/16 = 3.1e-3.
        let variance = sq_err / pixels as f64;
        assert!(variance < 3.1e-3 / 20.0, "variance {variance}");
    }
}
