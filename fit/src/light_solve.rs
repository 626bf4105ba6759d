//! The global light solve: non-negative RGB radiances of every emitter that make the input
//! views, rendered with the current materials, match the photos.
//!
//! Every emitter slot is rendered at unit radiance (renders are linear in the radiances), so a
//! pixel's value is `Σ_k R_k I_k(p)`; per colour channel the radiances minimise
//! `Σ_p w_p (photo_p − Σ_k R_k I_k(p))²` subject to `R ≥ 0`, pooled over the usable pixels of
//! every part in every view (the label agrees with the model, not clipped, away from edges).
//! The non-negativity is solved exactly (Lawson–Hanson active sets on the normal equations,
//! not "solve, then drop negatives"), and the weights are iteratively re-weighted with a Cauchy
//! loss on the relative residual, so that the pixels a misaligned model gets wrong do not
//! dominate.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::error::FitError;
use crate::observe::{ViewObservation, NO_PART};

/// The solved radiances and how well they explain the photos.
#[derive(Clone, Debug, Serialize)]
pub struct LightSolve {
    /// RGB radiance per slot.
    pub radiance: Vec<[f32; 3]>,
    /// Per slot, its share of the light reaching the solve's pixels (luminance-weighted).
    pub share: Vec<f32>,
    pub pixels: usize,
    /// Weighted RMS of the relative residual, per channel, after the last re-weighting.
    pub relative_rms: [f32; 3],
    /// Fraction of pixels the robust weights count as outliers (weight below 0.5).
    pub outliers: f32,
}

/// Re-weighting rounds.
const ROUNDS: usize = 6;

/// Pixels every view contributes: label agrees with the model, not clipped, not on an edge.
fn usable_pixels(obs: &ViewObservation) -> Vec<usize> {
    (0..obs.pixels())
        .filter(|&i| {
            let part = obs.geo.part[i];
            let label = obs.labels.as_ref().map_or(part, |l| l[i]);
            part != NO_PART && label == part && !obs.photo.clipped(i) && !obs.geo.on_edge(i, 0.05)
        })
        .collect()
}

/// Solves the radiances from `renders[view][slot]` (unit-radiance images at the views' sizes).
pub fn solve(views: &[ViewObservation], renders: &[Vec<Vec<[f32; 3]>>]) -> Result<LightSolve, FitError> {
    let slots = renders.first().map_or(0, |r| r.len());
    if slots == 0 {
        return Err(FitError::Input("the scene has no lights to solve for".into()));
    }
    // Gather (photo, unit renders) per usable pixel.
    let mut photo: Vec<[f32; 3]> = Vec::new();
    let mut unit: Vec<[f32; 3]> = Vec::new(); // pixel-major, `slots` entries per pixel
    for (obs, slot_images) in views.iter().zip(renders) {
        for i in usable_pixels(obs) {
            photo.push(obs.photo.linear[i]);
            unit.extend(slot_images.iter().map(|img| img[i]));
        }
    }
    let n = photo.len();
    if n < 100 {
        return Err(FitError::Input(format!(
            "cannot solve the lights: only {n} photo pixels agree with the model (give --lights with known radiances)"
        )));
    }
    let mut radiance = vec![[0.0f32; 3]; slots];
    let mut rms = [0.0f32; 3];
    let mut outliers = 0usize;
    for c in 0..3 {
        let mut weight = vec![1.0f64; n];
        let mut x = vec![0.0f64; slots];
        for _ in 0..ROUNDS {
            let mut g = DMatrix::<f64>::zeros(slots, slots);
            let mut h = DVector::<f64>::zeros(slots);
            for p in 0..n {
                let a = &unit[p * slots..(p + 1) * slots];
                let (w, b) = (weight[p], f64::from(photo[p][c]));
                for j in 0..slots {
                    let aj = f64::from(a[j][c]);
                    h[j] += w * aj * b;
                    for k in j..slots {
                        g[(j, k)] += w * aj * f64::from(a[k][c]);
                    }
                }
            }
            for j in 0..slots {
                for k in 0..j {
                    g[(j, k)] = g[(k, j)];
                }
            }
            x = nnls(&g, &h);
            // Cauchy weights on the relative residual, scaled by its median absolute deviation.
            let residual: Vec<f64> = (0..n)
                .map(|p| {
                    let a = &unit[p * slots..(p + 1) * slots];
                    let model: f64 = (0..slots).map(|k| x[k] * f64::from(a[k][c])).sum();
                    let b = f64::from(photo[p][c]);
                    (b - model) / b.max(0.02)
                })
                .collect();
            let mut abs: Vec<f64> = residual.iter().map(|r| r.abs()).collect();
            let mid = abs.len() / 2;
            let mad = *abs.select_nth_unstable_by(mid, f64::total_cmp).1;
            let scale = (2.385 * 1.4826 * mad).max(0.02);
            for (w, r) in weight.iter_mut().zip(&residual) {
                *w = 1.0 / (1.0 + (r / scale).powi(2));
            }
            let total: f64 = weight.iter().sum();
            rms[c] = (weight.iter().zip(&residual).map(|(w, r)| w * r * r).sum::<f64>() / total).sqrt() as f32;
            if c == 1 {
                outliers = weight.iter().filter(|&&w| w < 0.5).count();
            }
        }
        for (r, v) in radiance.iter_mut().zip(&x) {
            r[c] = *v as f32;
        }
    }
    // Each slot's share of the light on the solve's pixels.
    let mut light = vec![0.0f64; slots];
    for p in 0..n {
        for k in 0..slots {
            let a = unit[p * slots + k];
            light[k] += (0..3).map(|c| f64::from(radiance[k][c] * a[c])).sum::<f64>();
        }
    }
    let total: f64 = light.iter().sum::<f64>().max(1e-12);
    Ok(LightSolve {
        radiance,
        share: light.iter().map(|l| (l / total) as f32).collect(),
        pixels: n,
        relative_rms: rms,
        outliers: outliers as f32 / n as f32,
    })
}

/// min ½ xᵀGx − hᵀx subject to x ≥ 0 (G symmetric positive semi-definite): the Lawson–Hanson
/// active-set method on the normal equations.
pub fn nnls(g: &DMatrix<f64>, h: &DVector<f64>) -> Vec<f64> {
    let n = h.len();
    let scale = (0..n).map(|i| g[(i, i)]).fold(0.0f64, f64::max).max(1e-300);
    let tol = 1e-12 * scale;
    let mut x = vec![0.0f64; n];
    let mut passive = vec![false; n];
    let gradient =
        |x: &[f64]| -> Vec<f64> { (0..n).map(|i| h[i] - (0..n).map(|j| g[(i, j)] * x[j]).sum::<f64>()).collect() };
    for _ in 0..3 * n + 3 {
        let w = gradient(&x);
        let Some(j) = (0..n).filter(|&j| !passive[j] && w[j] > tol).max_by(|&a, &b| w[a].total_cmp(&w[b])) else {
            break;
        };
        passive[j] = true;
        loop {
            let s = solve_passive(g, h, &passive);
            if (0..n).all(|i| !passive[i] || s[i] > 0.0) {
                x = s;
                break;
            }
            // Step from x towards s until the first passive variable reaches 0.
            let alpha = (0..n)
                .filter(|&i| passive[i] && s[i] <= 0.0)
                .map(|i| x[i] / (x[i] - s[i]))
                .fold(f64::INFINITY, f64::min);
            for i in 0..n {
                x[i] += alpha * (s[i] - x[i]);
                if passive[i] && x[i] <= 1e-15 * (1.0 + x[i].abs()) {
                    passive[i] = false;
                    x[i] = 0.0;
                }
            }
            if !passive.iter().any(|&p| p) {
                break;
            }
        }
    }
    x
}

/// The unconstrained minimiser over the passive variables (others 0).
fn solve_passive(g: &DMatrix<f64>, h: &DVector<f64>, passive: &[bool]) -> Vec<f64> {
    let idx: Vec<usize> = (0..passive.len()).filter(|&i| passive[i]).collect();
    let m = idx.len();
    let sub = DMatrix::from_fn(m, m, |a, b| g[(idx[a], idx[b])]);
    let rhs = DVector::from_fn(m, |a, _| h[idx[a]]);
    // A whisper of ridge keeps collinear lights (two lamps side by side) solvable.
    let ridge = 1e-10 * (0..m).map(|a| sub[(a, a)]).fold(0.0f64, f64::max).max(1e-300);
    let solved = (sub.clone() + DMatrix::identity(m, m) * ridge)
        .cholesky()
        .map(|ch| ch.solve(&rhs))
        .unwrap_or_else(|| sub.pseudo_inverse(1e-12).map(|p| p * &rhs).unwrap_or_else(|_| DVector::zeros(m)));
    let mut out = vec![0.0f64; passive.len()];
    for (a, &i) in idx.iter().enumerate() {
        out[i] = solved[a];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use psc_base::SplitMix64;

    /// The true NNLS minimiser by enumerating every active set (small problems only).
    fn brute_force(g: &DMatrix<f64>, h: &DVector<f64>) -> Vec<f64> {
        let n = h.len();
        let objective = |x: &[f64]| {
            let gx: Vec<f64> = (0..n).map(|i| (0..n).map(|j| g[(i, j)] * x[j]).sum()).collect();
            0.5 * (0..n).map(|i| x[i] * gx[i]).sum::<f64>() - (0..n).map(|i| h[i] * x[i]).sum::<f64>()
        };
        let mut best = (0.0f64, vec![0.0; n]);
        for mask in 1..(1u32 << n) {
            let passive: Vec<bool> = (0..n).map(|i| mask >> i & 1 == 1).collect();
            let s = solve_passive(g, h, &passive);
            if s.iter().all(|&v| v >= 0.0) {
                let f = objective(&s);
                if f < best.0 {
                    best = (f, s);
                }
            }
        }
        best.1
    }

    #[test]
    fn nnls_finds_the_constrained_minimum() {
        let mut rng = SplitMix64::new(11);
        for trial in 0..300 {
            let (rows, n) = (12, 1 + trial % 5);
            let a = DMatrix::from_fn(rows, n, |_, _| rng.next_f64() - 0.3);
            let b = DVector::from_fn(rows, |_, _| rng.next_f64() * 2.0 - 0.8);
            let (g, h) = (a.transpose() * &a, a.transpose() * &b);
            let x = nnls(&g, &h);
            let y = brute_force(&g, &h);
            for (p, q) in x.iter().zip(&y) {
                assert!((p - q).abs() < 1e-8 * (1.0 + q.abs()), "trial {trial}: {x:?} vs {y:?}");
            }
        }
    }
}
