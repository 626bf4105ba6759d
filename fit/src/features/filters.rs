//! The oriented filter bank: Freeman–Adelson's steerable quadrature pair G2/H2 (second
//! derivative of a Gaussian and a cubic approximation of its Hilbert transform) as seven
//! x–y separable 9-tap basis filters built from five 1D factors, with the steering
//! coefficients for any number of orientations, and the 1D line operations the bank's forward
//! and adjoint passes use.
//!
//! Coordinates: x is the column (to the right), y the row (downwards); an orientation θ is
//! measured from +x towards +y, and the filter of orientation θ varies along (cos θ, sin θ),
//! so it responds to stripes whose bars run perpendicular to that direction.
//!
//! Filters: with g(t) = exp(−t²), sampled at t = 0.67·(k − 4) for k = 0..9 (σ ≈ 1.06 px, the
//! spacing of Freeman and Adelson's tables) and x' = x cos θ + y sin θ,
//! G2(θ) = 0.9213 (2x'² − 1) g(x) g(y) and H2(θ) = 0.978 (x'³ − 2.254 x') g(x) g(y).
//! Expanding x'² and x'³ gives the separable bases (row factor · column factor):
//! G2a = A2·A0, G2b = A1·A1, G2c = A0·A2 and H2a = A3·A0, H2b = B2·A1, H2c = A1·B2,
//! H2d = A0·A3, with A0 = g, A1 = t g, A2 = (2t² − 1) g, A3 = (t³ − 2.254 t) g,
//! B2 = (t² − 2.254/3) g. Steering is exact at every sample (a polynomial identity).
//!
//! Changes to the textbook filters, both keeping steerability exact: A2 is made zero-sum
//! (subtracting a multiple of A0 adds the same isotropic term to every G2(θ)), so a constant
//! image gives exactly zero response; both filters are scaled by one factor so that G2's
//! peak gain for a sinusoid along its orientation is 1 (the peak is at a period of 4.7
//! pixels; H2 peaks at 0.93 there). Energies G2² + H2² are therefore in squared amplitude
//! units of the input signal. H2 (odd) responds weakly to linear ramps (its polynomial is a
//! fit, not an exact Hilbert transform): smooth shading leaks a little into coarse scales.

pub(super) const RADIUS: usize = 4;
pub(super) const TAPS: usize = 2 * RADIUS + 1;
pub(super) const NUM_FACTORS: usize = 5;
pub(super) const NUM_BASIS: usize = 7;

const A0: usize = 0;
const A1: usize = 1;
const A2: usize = 2;
const A3: usize = 3;
const B2: usize = 4;

/// The basis filters as (row factor, column factor): G2a, G2b, G2c, then H2a, H2b, H2c, H2d.
pub(super) const BASIS: [(usize, usize); NUM_BASIS] =
    [(A2, A0), (A1, A1), (A0, A2), (A3, A0), (B2, A1), (A1, B2), (A0, A3)];

/// Sample spacing of the continuous filters, in their own units per pixel.
const SPACING: f64 = 0.67;
/// Freeman and Adelson's H2 linear coefficient.
const H2_LINEAR: f64 = 2.254;
const G2_GAIN: f64 = 0.9213;
const H2_GAIN: f64 = 0.978;

/// The five 1D factors and the steering coefficients of each orientation.
#[derive(Clone, Debug)]
pub(super) struct Bank {
    /// Row/column factors A0, A1, A2, A3, B2 (tap k at offset k − RADIUS).
    pub factors: [[f32; TAPS]; NUM_FACTORS],
    /// Per orientation: G2(θ) = Σ_{i<3} steer[i]·basis_i, H2(θ) = Σ_{i≥3} steer[i]·basis_i,
    /// the gains and the normalisation folded in.
    pub steer: Vec<[f32; NUM_BASIS]>,
}

impl Bank {
    pub fn new(orientations: usize) -> Bank {
        let t: Vec<f64> = (0..TAPS).map(|k| (k as f64 - RADIUS as f64) * SPACING).collect();
        let g: Vec<f64> = t.iter().map(|t| (-t * t).exp()).collect();
        let sample = |f: &dyn Fn(f64) -> f64| -> [f64; TAPS] { std::array::from_fn(|k| f(t[k]) * g[k]) };
        let a0 = sample(&|_| 1.0);
        let a1 = sample(&|t| t);
        let mut a2 = sample(&|t| 2.0 * t * t - 1.0);
        let a3 = sample(&|t| t * t * t - H2_LINEAR * t);
        let b2 = sample(&|t| t * t - H2_LINEAR / 3.0);
        let dc = a2.iter().sum::<f64>() / a0.iter().sum::<f64>();
        for (v, base) in a2.iter_mut().zip(&a0) {
            *v -= dc * base;
        }
        // Peak gain of G2(0) = G2_GAIN·A2(x)A0(y) for cos(ωx): G2_GAIN·Â2(ω)·Â0(0).
        let a0_dc: f64 = a0.iter().sum();
        let peak = (1..=2000)
            .map(|i| {
                let w = std::f64::consts::PI * i as f64 / 2000.0;
                let resp: f64 = a2.iter().enumerate().map(|(k, v)| v * (w * (k as f64 - RADIUS as f64)).cos()).sum();
                (G2_GAIN * resp * a0_dc).abs()
            })
            .fold(0.0, f64::max);
        let scale = 1.0 / peak;
        let steer = (0..orientations)
            .map(|o| {
                let theta = std::f64::consts::PI * o as f64 / orientations as f64;
                let (s, c) = theta.sin_cos();
                let gs = G2_GAIN * scale;
                let hs = H2_GAIN * scale;
                // 2x'² − 1 = c²(2x² − 1) + s²(2y² − 1) + 4cs·xy.
                [
                    (gs * c * c) as f32,
                    (gs * 4.0 * c * s) as f32,
                    (gs * s * s) as f32,
                    (hs * c * c * c) as f32,
                    (hs * 3.0 * c * c * s) as f32,
                    (hs * 3.0 * c * s * s) as f32,
                    (hs * s * s * s) as f32,
                ]
            })
            .collect();
        let to32 = |a: [f64; TAPS]| a.map(|v| v as f32);
        Bank { factors: [to32(a0), to32(a1), to32(a2), to32(a3), to32(b2)], steer }
    }
}

/// `y += a·x`.
#[inline(never)]
pub(super) fn axpy(a: f32, x: &[f32], y: &mut [f32]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += a * x;
    }
}

/// Sum in f64 in a fixed order (four lanes, then the tail), so that it vectorises, gives the
/// same bits on every run, and keeps the pooled means accurate enough for finite differences.
#[inline]
pub(super) fn lane_sum(x: &[f32]) -> f64 {
    let mut lanes = [0.0f64; 4];
    let mut chunks = x.chunks_exact(4);
    for c in &mut chunks {
        for (l, v) in lanes.iter_mut().zip(c) {
            *l += f64::from(*v);
        }
    }
    let tail: f64 = chunks.remainder().iter().map(|&v| f64::from(v)).sum();
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 2D filter of basis `i` at (x, y) offsets.
    fn basis_2d(bank: &Bank, i: usize, x: usize, y: usize) -> f32 {
        let (r, c) = BASIS[i];
        bank.factors[r][x] * bank.factors[c][y]
    }

    #[test]
    fn steering_matches_rotated_filters() {
        // Steered G2(θ) must equal the rotated continuous formula sampled at each tap (up to
        // the isotropic zero-mean correction, which cancels in differences of orientations),
        // so compare G2(θ) − G2(θ + 90°) with 0.9213·2(x'² − y'²)·g·g scaled.
        let bank = Bank::new(8);
        let scale_g = bank.steer[0][0] as f64; // gs at θ = 0
        for o in 0..8 {
            let perp = (o + 4) % 8;
            let theta = std::f64::consts::PI * o as f64 / 8.0;
            let (s, c) = theta.sin_cos();
            for y in 0..TAPS {
                for x in 0..TAPS {
                    let steered = |o: usize| (0..3).map(|i| bank.steer[o][i] * basis_2d(&bank, i, x, y)).sum::<f32>();
                    let got = steered(o) - steered(perp);
                    let (tx, ty) = ((x as f64 - 4.0) * SPACING, (y as f64 - 4.0) * SPACING);
                    let (xr, yr) = (tx * c + ty * s, -tx * s + ty * c);
                    let g = (-(tx * tx + ty * ty)).exp();
                    let want = scale_g * 2.0 * (xr * xr - yr * yr) * g;
                    assert!((got as f64 - want).abs() < 1e-5, "o {o} ({x},{y}): {got} vs {want}");
                }
            }
        }
    }

    #[test]
    fn steered_h2_is_the_rotated_cubic() {
        let bank = Bank::new(6);
        let hs = bank.steer[0][3] as f64;
        for o in 0..6 {
            let theta = std::f64::consts::PI * o as f64 / 6.0;
            let (s, c) = theta.sin_cos();
            for y in 0..TAPS {
                for x in 0..TAPS {
                    let got: f32 = (3..7).map(|i| bank.steer[o][i] * basis_2d(&bank, i, x, y)).sum();
                    let (tx, ty) = ((x as f64 - 4.0) * SPACING, (y as f64 - 4.0) * SPACING);
                    let xr = tx * c + ty * s;
                    let want = hs * (xr * xr * xr - H2_LINEAR * xr) * (-(tx * tx + ty * ty)).exp();
                    assert!((got as f64 - want).abs() < 1e-5, "o {o} ({x},{y}): {got} vs {want}");
                }
            }
        }
    }

    #[test]
    fn constant_images_give_no_response() {
        let bank = Bank::new(4);
        for (i, &(r, c)) in BASIS.iter().enumerate() {
            let dc: f32 = bank.factors[r].iter().sum::<f32>() * bank.factors[c].iter().sum::<f32>();
            assert!(dc.abs() < 1e-6, "basis {i} has DC {dc}");
        }
    }
}
