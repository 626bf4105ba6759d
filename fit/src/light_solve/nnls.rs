//! Non-negative least squares on the normal equations: the Lawson–Hanson active-set method.

use nalgebra::{DMatrix, DVector};

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
pub(super) fn solve_passive(g: &DMatrix<f64>, h: &DVector<f64>, passive: &[bool]) -> Vec<f64> {
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
