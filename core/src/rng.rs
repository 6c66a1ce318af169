//! Seeded random streams. Every random number of a render comes from a stream derived
//! from `(seed, view, pixel, sample)`, or for a sample's point in its pixel from a
//! scrambling keyed by `(seed, view, pixel, half)` ([`crate::strata`]), so an image never
//! depends on thread count or order.
//! The integer-to-float conversion is our own (documented below), so golden images do not
//! depend on a library's distribution code.

use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

/// SplitMix64 finaliser: a fast, well-mixing 64-bit hash.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash of a tuple of stream coordinates, chained so that (a, b) != (b, a).
#[inline]
pub fn stream_key(parts: &[u64]) -> u64 {
    let mut h = 0x005E_ED0F_2E1A_u64;
    for &p in parts {
        h = mix64(h ^ p);
    }
    h
}

/// A random stream: xoshiro128++ seeded from a stream key.
pub struct Sampler {
    rng: Xoshiro128PlusPlus,
}

impl Sampler {
    /// The stream of one pixel sample of one view.
    pub fn for_pixel_sample(seed: u64, view: u32, pixel: u32, sample: u32) -> Sampler {
        Sampler::from_key(stream_key(&[
            seed,
            view as u64,
            pixel as u64,
            sample as u64,
        ]))
    }

    pub fn from_key(key: u64) -> Sampler {
        Sampler {
            rng: Xoshiro128PlusPlus::seed_from_u64(key),
        }
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        self.rng.next_u32()
    }

    /// A float uniform in [0, 1): the top 24 bits of a `u32`, times 2^-24.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        unit_f32(self.next_u32())
    }

    #[inline]
    pub fn next_2d(&mut self) -> [f32; 2] {
        let a = self.next_f32();
        [a, self.next_f32()]
    }
}

/// `u32` to a float uniform in [0, 1): exact, never 1.0.
#[inline]
pub fn unit_f32(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_f32_is_in_range() {
        assert_eq!(unit_f32(0), 0.0);
        assert!(unit_f32(u32::MAX) < 1.0);
    }

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let mut s1 = Sampler::for_pixel_sample(7, 0, 10, 3);
        let mut s2 = Sampler::for_pixel_sample(7, 0, 10, 3);
        let mut s3 = Sampler::for_pixel_sample(7, 0, 10, 4);
        let x1 = s1.next_u32();
        assert_eq!(x1, s2.next_u32());
        assert_ne!(x1, s3.next_u32());
    }

    #[test]
    fn mean_is_one_half() {
        let mut s = Sampler::from_key(1);
        let n = 100_000;
        let mean: f64 = (0..n).map(|_| s.next_f32() as f64).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
    }
}
