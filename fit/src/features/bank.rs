//! One pyramid level of the filter bank over its pooling box: the seven basis responses of a
//! plane, their energies pooled per orientation, and the adjoints of both.
//!
//! Every 1D factor is symmetric or antisymmetric about its centre tap, so each 9-tap pass is
//! folded: `f₄·x₀ + Σₖ f₄₊ₖ·(x₊ₖ ± x₋ₖ)`, 5 or 4 multiplies instead of 9. The adjoint passes
//! are the same folded correlation with the odd factors negated, run over buffers padded with
//! zeros (8 columns each side for the row pass, 8 rows above and below for the column pass),
//! so forward and adjoint share one kernel and the transposition stays exact.
//!
//! Layouts over a box of `bw × bh` pixels (n = bw·bh): `basis` holds seven n-blocks;
//! `rows` five blocks of `(bh + 8) × bw` (the box plus the column filter's margin);
//! `d_basis` seven blocks of `(bh + 16) × bw` with the data in rows 8..bh+8; `d_rows` five
//! blocks of `(bh + 8) × (bw + 16)` with the data in columns 8..bw+8.

use super::filters::{self, Bank, BASIS, NUM_BASIS, NUM_FACTORS, RADIUS, TAPS};
use super::pyramid::Level;

/// Whether factor A0, A1, A2, A3, B2 is odd (antisymmetric).
const ODD: [bool; NUM_FACTORS] = [false, true, false, true, false];
const PAD: usize = 2 * RADIUS;

/// `out[x] = Σ_k f[k]·src_k[x]` for nine equally long inputs (tap k reads `src[k]`), folded
/// about the centre: `odd` factors have f[8 − k] = −f[k], even ones f[8 − k] = f[k].
#[inline(always)]
fn fold<const ACC: bool>(src: [&[f32]; TAPS], f: &[f32; TAPS], odd: bool, out: &mut [f32]) {
    let [s0, s1, s2, s3, s4, s5, s6, s7, s8] = src;
    if odd {
        fold_odd::<ACC>(s0, s1, s2, s3, s5, s6, s7, s8, [f[5], f[6], f[7], f[8]], out);
    } else {
        fold_even::<ACC>(s0, s1, s2, s3, s4, s5, s6, s7, s8, [f[4], f[5], f[6], f[7], f[8]], out);
    }
}

// The kernels take every stream as its own reference argument: only then does the compiler
// know that `out` aliases none of them, and vectorise without runtime overlap checks.

#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn fold_odd<const ACC: bool>(
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    s3: &[f32],
    s5: &[f32],
    s6: &[f32],
    s7: &[f32],
    s8: &[f32],
    f: [f32; 4],
    out: &mut [f32],
) {
    let n = out.len();
    let (s0, s1, s2, s3, s5, s6, s7, s8) =
        (&s0[..n], &s1[..n], &s2[..n], &s3[..n], &s5[..n], &s6[..n], &s7[..n], &s8[..n]);
    let [f5, f6, f7, f8] = f;
    for x in 0..n {
        let v = f5 * (s5[x] - s3[x]) + f6 * (s6[x] - s2[x]) + f7 * (s7[x] - s1[x]) + f8 * (s8[x] - s0[x]);
        out[x] = if ACC { out[x] + v } else { v };
    }
}

#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn fold_even<const ACC: bool>(
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    s3: &[f32],
    s4: &[f32],
    s5: &[f32],
    s6: &[f32],
    s7: &[f32],
    s8: &[f32],
    f: [f32; 5],
    out: &mut [f32],
) {
    let n = out.len();
    let (s0, s1, s2, s3, s4) = (&s0[..n], &s1[..n], &s2[..n], &s3[..n], &s4[..n]);
    let (s5, s6, s7, s8) = (&s5[..n], &s6[..n], &s7[..n], &s8[..n]);
    let [f4, f5, f6, f7, f8] = f;
    for x in 0..n {
        let v = f4 * s4[x] + f5 * (s5[x] + s3[x]) + f6 * (s6[x] + s2[x]) + f7 * (s7[x] + s1[x]) + f8 * (s8[x] + s0[x]);
        out[x] = if ACC { out[x] + v } else { v };
    }
}

/// The nine shifted views of a row for a horizontal pass producing `n` outputs.
#[inline(always)]
fn shifted(row: &[f32], n: usize) -> [&[f32]; TAPS] {
    std::array::from_fn(|k| &row[k..k + n])
}

/// The seven basis responses of one plane over the level's pooling box, basis-major
/// (`basis[i·n + y·bw + x]`). The box lies at least RADIUS pixels inside the level (its pooling
/// weights require it), so no padding is needed.
pub(super) fn filter_level(bank: &Bank, plane: &[f32], level: &Level, rows: &mut Vec<f32>, basis: &mut Vec<f32>) {
    let lw = level.width;
    let (bw, bh) = (level.cols.len(), level.rows.len());
    let n = bw * bh;
    let rh = bh + TAPS - 1;
    rows.resize(NUM_FACTORS * rh * bw, 0.0);
    for ry in 0..rh {
        let y = level.rows.start + ry - RADIUS;
        let inp = &plane[y * lw + level.cols.start - RADIUS..y * lw + level.cols.end + RADIUS];
        for (j, f) in bank.factors.iter().enumerate() {
            let out = &mut rows[(j * rh + ry) * bw..(j * rh + ry + 1) * bw];
            fold::<false>(shifted(inp, bw), f, ODD[j], out);
        }
    }
    basis.resize(NUM_BASIS * n, 0.0);
    for (i, &(rf, cf)) in BASIS.iter().enumerate() {
        let block = &rows[rf * rh * bw..(rf + 1) * rh * bw];
        for y in 0..bh {
            let src: [&[f32]; TAPS] = std::array::from_fn(|k| &block[(y + k) * bw..(y + k + 1) * bw]);
            fold::<false>(src, &bank.factors[cf], ODD[cf], &mut basis[i * n + y * bw..i * n + (y + 1) * bw]);
        }
    }
}

/// The adjoint of [`filter_level`]: adds the plane gradient given the basis gradient (padded
/// layout, see the module docs).
pub(super) fn filter_level_adjoint(
    bank: &Bank,
    d_basis: &[f32],
    level: &Level,
    d_rows: &mut Vec<f32>,
    d_plane: &mut [f32],
) {
    let lw = level.width;
    let (bw, bh) = (level.cols.len(), level.rows.len());
    let rh = bh + TAPS - 1;
    let (pbh, pbw) = (bh + 2 * PAD, bw + 2 * PAD);
    let neg: [[f32; TAPS]; NUM_FACTORS] =
        std::array::from_fn(|j| if ODD[j] { bank.factors[j].map(|v| -v) } else { bank.factors[j] });
    d_rows.clear();
    d_rows.resize(NUM_FACTORS * rh * pbw, 0.0);
    // Columns: dR_rf[y] += Σ_k f_cf[k]·dB_i[y − k], a folded correlation of the padded rows.
    for (i, &(rf, cf)) in BASIS.iter().enumerate() {
        let block = &d_basis[i * pbh * bw..(i + 1) * pbh * bw];
        for y in 0..rh {
            let src: [&[f32]; TAPS] = std::array::from_fn(|k| &block[(y + k) * bw..(y + k + 1) * bw]);
            let start = (rf * rh + y) * pbw + PAD;
            fold::<true>(src, &neg[cf], ODD[cf], &mut d_rows[start..start + bw]);
        }
    }
    // Rows: dX[x] += Σ_j Σ_k f_j[k]·dR_j[x − k], over the zero-padded rows.
    for ry in 0..rh {
        let y = level.rows.start + ry - RADIUS;
        let out = &mut d_plane[y * lw + level.cols.start - RADIUS..y * lw + level.cols.end + RADIUS];
        for (j, f) in neg.iter().enumerate() {
            let row = &d_rows[(j * rh + ry) * pbw..(j * rh + ry + 1) * pbw];
            fold::<true>(shifted(row, bw + TAPS - 1), f, ODD[j], out);
        }
    }
}

/// The seven basis blocks of a box of `n` pixels.
#[inline(always)]
fn blocks(basis: &[f32], n: usize) -> [&[f32]; NUM_BASIS] {
    std::array::from_fn(|i| &basis[i * n..(i + 1) * n])
}

/// Adds Σ pool·E(θ) over the box to `sums[θ]`. Pixels of weight 0 are skipped by selection
/// (not multiplication), so non-finite responses there cannot leak in.
pub(super) fn pool_energies(bank: &Bank, level: &Level, basis: &[f32], line: &mut Vec<f32>, sums: &mut [f64]) {
    let n = level.pool.len();
    let b = blocks(basis, n);
    line.resize(n, 0.0);
    for (st, sum) in bank.steer.iter().zip(sums.iter_mut()) {
        steered_energy(*st, b[0], b[1], b[2], b[3], b[4], b[5], b[6], &level.pool, line);
        *sum += filters::lane_sum(line);
    }
}

/// `v` where the pool weight `p` is positive, else +0 (whatever `v` is, NaN included). A bit
/// mask rather than a branch, so that the loops around it vectorise.
#[inline(always)]
fn select_live(p: f32, v: f32) -> f32 {
    let keep = u32::from(p > 0.0).wrapping_neg();
    f32::from_bits(v.to_bits() & keep)
}

/// `out = pool·(G² + H²)` for one orientation, 0 where the pool weight is 0.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn steered_energy(
    st: [f32; NUM_BASIS],
    b0: &[f32],
    b1: &[f32],
    b2: &[f32],
    b3: &[f32],
    b4: &[f32],
    b5: &[f32],
    b6: &[f32],
    pool: &[f32],
    out: &mut [f32],
) {
    let n = out.len();
    let (b0, b1, b2, b3, b4, b5, b6, pool) =
        (&b0[..n], &b1[..n], &b2[..n], &b3[..n], &b4[..n], &b5[..n], &b6[..n], &pool[..n]);
    let [c0, c1, c2, c3, c4, c5, c6] = st;
    for x in 0..n {
        let g = c0 * b0[x] + c1 * b1[x] + c2 * b2[x];
        let h = c3 * b3[x] + c4 * b4[x] + c5 * b5[x] + c6 * b6[x];
        let p = pool[x];
        out[x] = select_live(p, p * (g * g + h * h));
    }
}

/// `dg = w·G`, `dh = w·H` with w = `scale`·pool for one orientation, 0 where the pool weight is 0.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn steered_grad(
    st: [f32; NUM_BASIS],
    scale: f32,
    b0: &[f32],
    b1: &[f32],
    b2: &[f32],
    b3: &[f32],
    b4: &[f32],
    b5: &[f32],
    b6: &[f32],
    pool: &[f32],
    dg: &mut [f32],
    dh: &mut [f32],
) {
    let n = dg.len();
    let (b0, b1, b2, b3, b4, b5, b6, pool) =
        (&b0[..n], &b1[..n], &b2[..n], &b3[..n], &b4[..n], &b5[..n], &b6[..n], &pool[..n]);
    let dh = &mut dh[..n];
    let [c0, c1, c2, c3, c4, c5, c6] = st;
    for x in 0..n {
        let g = c0 * b0[x] + c1 * b1[x] + c2 * b2[x];
        let h = c3 * b3[x] + c4 * b4[x] + c5 * b5[x] + c6 * b6[x];
        let p = pool[x];
        let w = scale * p;
        dg[x] = select_live(p, w * g);
        dh[x] = select_live(p, w * h);
    }
}

/// Basis gradient of one plane given dL/d(mean energy) per orientation, into `d_basis` in the
/// padded layout (every element written). dE/dG = 2G, dE/dH = 2H; pixels of weight 0 get
/// nothing, by selection (their responses may be non-finite).
pub(super) fn energies_adjoint(
    bank: &Bank,
    level: &Level,
    basis: &[f32],
    d_means: &[f64],
    lines: &mut Vec<f32>,
    d_basis: &mut Vec<f32>,
) {
    let n = level.pool.len();
    let bw = level.cols.len();
    let pbh = level.rows.len() + 2 * PAD;
    let b = blocks(basis, n);
    d_basis.clear();
    d_basis.resize(NUM_BASIS * pbh * bw, 0.0);
    lines.resize(2 * n, 0.0);
    let (dg, dh) = lines.split_at_mut(n);
    for (steer, &dm) in bank.steer.iter().zip(d_means) {
        let two_dm = (2.0 * dm) as f32;
        steered_grad(*steer, two_dm, b[0], b[1], b[2], b[3], b[4], b[5], b[6], &level.pool, dg, dh);
        for (i, &c) in steer.iter().enumerate() {
            let start = i * pbh * bw + PAD * bw;
            filters::axpy(c, if i < 3 { &*dg } else { &*dh }, &mut d_basis[start..start + n]);
        }
    }
}
