//! `psc-base`: the one copy of small, domain-free helpers that crates on both sides of the
//! workspace need (the compiler chain and the image chain share no other crate).
//!
//! Owns: deterministic random numbers ([`SplitMix64`], [`mix64`], [`mix_name`]); the sRGB
//! transfer and luminance ([`color`]); outputs that appear whole or not at all ([`output`]:
//! atomic file writes, staged output folders, removal of temporaries on error, drop, SIGINT and
//! SIGTERM); resource limits ([`limits`]: pixels, texels, samples, threads, variants and a
//! memory budget, checked before allocating); progress reporting that
//! any crate can call and only the command line draws ([`progress`]); the one folder walker
//! ([`walk::files_with_extension`]: follows links, never loops, lists each real file once);
//! base64 for `data:` URIs ([`base64`]).
//!
//! Must never: depend on another photoscene crate or on anything but `std` and `ctrlc` (the
//! signal handler of [`output`]); know about graphs, kernels, scenes or images.

#![forbid(unsafe_code)]

pub mod base64;
pub mod color;
pub mod limits;
pub mod output;
pub mod progress;
pub mod walk;

/// SplitMix64 finaliser: a good 64-bit mixing function.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A seed derived from `seed` and a name, so that what is seeded by name (a library graph's
/// random draws) stays put when other names are added or reordered.
pub fn mix_name(seed: u64, name: &str) -> u64 {
    name.bytes().fold(seed, |h, b| mix64(h ^ u64::from(b)))
}

/// SplitMix64 (Steele, Lea and Flood 2014): a tiny deterministic generator, so that random
/// variants, workloads and test inputs are reproducible from a seed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.0)
    }

    /// Uniform in [0, 1), 24 bits.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / 16_777_216.0)
    }

    /// Uniform in [0, 1), 53 bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }

    /// Uniform integer in `0..n` (`n > 0`; the modulo bias is below 2^-40 for any `n < 2^24`).
    #[inline]
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_reference_sequence() {
        // First outputs of SplitMix64 seeded with 1234567 (the reference C implementation).
        let mut r = SplitMix64::new(1234567);
        let got: Vec<u64> = (0..3).map(|_| r.next_u64()).collect();
        assert_eq!(got, [6457827717110365317, 3203168211198807973, 9817491932198370423]);
    }

    #[test]
    fn unit_floats_stay_in_range() {
        let mut r = SplitMix64::new(7);
        for _ in 0..10_000 {
            let (a, b) = (r.next_f32(), r.next_f64());
            assert!((0.0..1.0).contains(&a) && (0.0..1.0).contains(&b));
            assert!(r.below(10) < 10);
        }
    }
}
