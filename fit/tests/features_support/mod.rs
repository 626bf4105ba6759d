//! Helpers shared by the feature-loss tests: a seeded generator, synthetic patterns, region
//! shapes, and a landscape summary.

#![allow(dead_code)]

use psc_fit::features::Region;

/// A small deterministic generator (SplitMix64).
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

/// A textured image in [0, 1]: a few random oriented sinusoids per channel plus pixel noise.
pub fn random_pattern(w: usize, h: usize, rng: &mut Rng) -> Vec<[f32; 3]> {
    let waves: Vec<(f32, f32, f32, [f32; 3])> = (0..4)
        .map(|_| {
            let theta = rng.range(0.0, std::f32::consts::PI);
            let period = rng.range(3.0, 20.0);
            let k = 2.0 * std::f32::consts::PI / period;
            (
                k * theta.cos(),
                k * theta.sin(),
                rng.range(0.0, 6.3),
                [rng.range(0.0, 0.12), rng.range(0.0, 0.12), rng.range(0.0, 0.12)],
            )
        })
        .collect();
    let base = [rng.range(0.3, 0.7), rng.range(0.3, 0.7), rng.range(0.3, 0.7)];
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let mut px = base;
            for (kx, ky, ph, amp) in &waves {
                let s = (kx * x + ky * y + ph).sin();
                for c in 0..3 {
                    px[c] += amp[c] * s;
                }
            }
            px.map(|v| (v + rng.range(-0.02, 0.02)).clamp(0.0, 1.0))
        })
        .collect()
}

/// Named region shapes for tests: full rectangle, soft disc, thin diagonal band, ring.
pub fn shape(name: &str, w: usize, h: usize) -> Region {
    let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
    let weight = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            let r = ((x - cx).powi(2) + (y - cy).powi(2)).sqrt();
            match name {
                "rect" => 1.0,
                "disc" => {
                    let edge = cx.min(cy) - 1.0;
                    // Soft rim: weights ramp from 1 to 0.2 over the outer 4 pixels.
                    if r > edge {
                        0.0
                    } else {
                        (0.2 + 0.8 * (edge - r) / 4.0).min(1.0)
                    }
                }
                "band" => {
                    // A diagonal band 12 px wide (the bank needs 9 px to respond at all).
                    let d = ((x - cx) * 0.6 - (y - cy) * 0.8).abs();
                    if d < 6.0 {
                        1.0
                    } else {
                        0.0
                    }
                }
                "ring" => {
                    let outer = cx.min(cy) - 1.0;
                    if r < outer && r > outer - 14.0 {
                        1.0
                    } else {
                        0.0
                    }
                }
                other => panic!("unknown shape {other}"),
            }
        })
        .collect();
    Region { width: w, height: h, weight }
}

/// Index of the minimum of a grid of losses.
pub fn argmin(values: &[f32]) -> usize {
    values.iter().enumerate().fold(0, |best, (i, &v)| if v < values[best] { i } else { best })
}
