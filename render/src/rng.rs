//! A small counter-seeded random number generator (PCG32). Every sample of every pixel gets its
//! own stream from `(seed, pixel, sample)`, which makes renders independent of thread count.

/// PCG32 (XSH-RR), 64-bit state.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

pub use psc_base::mix64;

impl Rng {
    /// A stream determined by three keys (typically seed, pixel index, sample index).
    pub fn new(seed: u64, a: u64, b: u64) -> Self {
        let s =
            mix64(seed ^ mix64(a.wrapping_add(0x9e37_79b9_7f4a_7c15) ^ mix64(b.wrapping_mul(0xd1b5_4a32_d192_ed03))));
        let inc = (mix64(s ^ 0x2545_f491_4f6c_dd1d) << 1) | 1;
        let mut r = Rng { state: 0, inc };
        r.next_u32();
        r.state = r.state.wrapping_add(s);
        r.next_u32();
        r
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    #[inline]
    pub fn next_2d(&mut self) -> [f32; 2] {
        [self.next_f32(), self.next_f32()]
    }
}
