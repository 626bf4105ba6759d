//! Helpers shared by the library-level test files (`fuzz_pipeline`, `library_gradients`,
//! `std_nodes`, `ir_invariants`): finding and compiling the library, a deterministic RNG,
//! random parameter vectors, an evaluator that reports which branch every piecewise op took
//! (to skip finite-difference probes that cross a kink or a jump), and the finite-difference
//! gradient check and the tiling check themselves.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use psc_base::SplitMix64;
use psc_compiler::interp::{eval, Batch};
use psc_compiler::ir::{semantics, Op, Program};
use psc_compiler::{compile_files, Adjoint, Channel, CompiledGraph, GraphInfo, Options, ParamKind};

// ---------------------------------------------------------------------------------------------
// The library

/// `/…/graphs`, the library root.
pub fn graphs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../graphs")
}

/// Every `.psg` under `dir`, recursively, sorted.
pub fn psg_files_under(dir: &Path) -> Vec<PathBuf> {
    psc_compiler::find_sources(dir).unwrap_or_else(|e| panic!("reading {}: {e}", dir.display()))
}

/// The material graph files: everything under `graphs/` except `graphs/std/`.
pub fn material_files() -> Vec<PathBuf> {
    let std_dir = graphs_dir().join("std");
    psg_files_under(&graphs_dir()).into_iter().filter(|p| !p.starts_with(&std_dir)).collect()
}

/// The node library files, `graphs/std/*.psg`.
pub fn std_files() -> Vec<PathBuf> {
    psg_files_under(&graphs_dir().join("std"))
}

/// Compiles every material graph of the library; panics with the rendered diagnostics if any
/// file has an error. Sorted by graph name.
pub fn compile_library() -> Vec<CompiledGraph> {
    let files = material_files();
    assert!(files.len() >= 20, "the library is missing: {} files", files.len());
    let out = compile_files(&files, &Options::default());
    assert!(!out.has_errors(), "the library does not compile:\n{}", out.render_diagnostics());
    let mut graphs = out.graphs;
    assert!(graphs.len() >= files.len(), "{} graphs from {} files", graphs.len(), files.len());
    graphs.sort_by(|a, b| a.info.name.cmp(&b.info.name));
    graphs
}

/// Optional filter from `PSC_GRAPHS` (comma-separated graph names) for focused runs.
pub fn graph_filter() -> Option<Vec<String>> {
    std::env::var("PSC_GRAPHS").ok().map(|s| s.split(',').map(|x| x.trim().to_string()).collect())
}

pub fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

// ---------------------------------------------------------------------------------------------
// Deterministic randomness (reproducible across runs)

/// [`SplitMix64`] with the seeding and ranges these tests use.
#[derive(Clone, Debug)]
pub struct Rng(SplitMix64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix64::new(seed ^ 0x5DEE_CE66_D1CE_4E5B))
    }
    /// A generator seeded from a name (a graph or fn), so adding graphs does not reshuffle
    /// the samples of the others.
    pub fn for_name(name: &str, salt: u64) -> Self {
        let mut h = 0xcbf2_9ce4_8422_2325u64 ^ salt;
        for b in name.bytes() {
            h = (h ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
        Rng::new(h)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f32 {
        self.0.next_f32()
    }
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
    pub fn below(&mut self, n: usize) -> usize {
        self.0.below(n)
    }
}

/// A random parameter vector: continuous parameters uniform in their range, colours uniform in
/// [0, 1] per channel, discrete parameters at a uniformly chosen integer of their range.
pub fn random_params(info: &GraphInfo, rng: &mut Rng) -> Vec<f32> {
    let mut out = info.default_params();
    for p in &info.params {
        match p.kind {
            ParamKind::Continuous { min, max } => out[p.slot] = rng.range(min, max),
            ParamKind::Discrete { min, max } => out[p.slot] = (min + rng.below((max - min + 1) as usize) as i64) as f32,
            ParamKind::Color => {
                for k in 0..3 {
                    out[p.slot + k] = rng.unit();
                }
            }
        }
    }
    out
}

/// The default vector, then `extra` random ones.
pub fn param_vectors(info: &GraphInfo, rng: &mut Rng, extra: usize) -> Vec<Vec<f32>> {
    let mut v = vec![info.default_params()];
    v.extend((0..extra).map(|_| random_params(info, rng)));
    v
}

// ---------------------------------------------------------------------------------------------
// Evaluation with branch signatures

/// One evaluation point with its own parameter vector.
#[derive(Clone, Debug)]
pub struct Lane {
    pub u: f32,
    pub v: f32,
    pub params: Vec<f32>,
}

/// Evaluates `program` at every lane (each with its own parameters; no seeds) and returns, per
/// lane, the program outputs and a signature of every piecewise decision taken: the value of
/// every `floor` and `hash`, every comparison, which operand `min`/`max` chose, the sign of
/// `abs`, `pow`, `sqrt`, `log`, `div` operands, and the `atan2` branch cut. Two lanes with the
/// same signature lie in one smooth piece of the program (no kink, no jump between them along
/// a short segment). `None` for a lane with a non-finite intermediate.
///
/// Uses [`semantics::eval`], the same definition the interpreter uses; the callers take the
/// compared values from the interpreter itself.
pub fn eval_signatures(program: &Program, lanes: &[Lane]) -> Vec<Option<(Vec<f32>, u64)>> {
    let n = lanes.len();
    let uses = program.use_counts();
    let mut remaining = uses.clone();
    let is_output: Vec<bool> = {
        let mut o = vec![false; program.nodes.len()];
        for out in &program.outputs {
            o[out.node.index()] = true;
        }
        o
    };
    let mut values: Vec<Option<Vec<f32>>> = vec![None; program.nodes.len()];
    let mut sig = vec![0xcbf2_9ce4_8422_2325u64; n];
    let mut finite = vec![true; n];
    for (i, op) in program.nodes.iter().enumerate() {
        if uses[i] == 0 {
            continue;
        }
        let column: Vec<f32> = match *op {
            Op::Const(bits) => vec![f32::from_bits(bits); n],
            Op::U => lanes.iter().map(|l| l.u).collect(),
            Op::V => lanes.iter().map(|l| l.v).collect(),
            Op::Param(p) => lanes.iter().map(|l| l.params[p as usize]).collect(),
            Op::Seed(_) => panic!("eval_signatures: seeds are not supported"),
            _ => {
                let ids: Vec<usize> = op.operands().map(|id| id.index()).collect();
                let col = |k: usize| ids.get(k).map(|&id| values[id].as_deref().expect("operand alive"));
                let (a, b, c) = (col(0), col(1), col(2));
                let mut out = Vec::with_capacity(n);
                for k in 0..n {
                    let x = a.map_or(0.0, |s| s[k]);
                    let y = b.map_or(0.0, |s| s[k]);
                    let z = c.map_or(0.0, |s| s[k]);
                    let r = semantics::eval(op, x, y, z).expect("non-leaf");
                    let decision: Option<u64> = match op {
                        Op::Floor(_) | Op::Hash(..) | Op::Lt(..) | Op::Le(..) | Op::Eq(..) => Some(r.to_bits() as u64),
                        Op::Abs(_) => Some((x < 0.0) as u64),
                        Op::Sqrt(_) | Op::Pow(..) => Some((x > 0.0) as u64),
                        Op::Log(_) => Some((x > f32::MIN_POSITIVE) as u64),
                        Op::Min(..) => Some((x < y) as u64),
                        Op::Max(..) => Some((x > y) as u64),
                        Op::Div(..) => Some((y < 0.0) as u64),
                        Op::Select(..) => Some((x != 0.0) as u64),
                        Op::Atan2(..) => Some(if y < 0.0 { 1 + (x < 0.0) as u64 } else { 0 }),
                        _ => None,
                    };
                    if let Some(d) = decision {
                        let h = &mut sig[k];
                        *h = (*h ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ d).wrapping_mul(0x100_0000_01b3);
                        *h ^= *h >> 29;
                    }
                    if !r.is_finite() {
                        finite[k] = false;
                    }
                    out.push(r);
                }
                out
            }
        };
        values[i] = Some(column);
        for operand in op.operands() {
            let r = &mut remaining[operand.index()];
            *r -= 1;
            if *r == 0 && !is_output[operand.index()] {
                values[operand.index()] = None;
            }
        }
    }
    (0..n)
        .map(|k| {
            finite[k].then(|| {
                let outs = program.outputs.iter().map(|o| values[o.node.index()].as_ref().unwrap()[k]).collect();
                (outs, sig[k])
            })
        })
        .collect()
}

/// Interpreter values of every output at the points `(u[k], v[k])`, all with `params`.
pub fn interp_points(program: &Program, params: &[f32], u: &[f32], v: &[f32], seeds: &[&[f32]]) -> Vec<Vec<f32>> {
    let columns = eval(program, params, &Batch { u, v, seeds });
    (0..u.len()).map(|k| columns.iter().map(|c| c[k]).collect()).collect()
}

// ---------------------------------------------------------------------------------------------
// Gradients against finite differences

/// What a derivative is taken with respect to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Var {
    U,
    V,
    Slot(u32),
}

impl std::fmt::Display for Var {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Var::U => write!(f, "u"),
            Var::V => write!(f, "v"),
            Var::Slot(s) => write!(f, "param{s}"),
        }
    }
}

/// Counts of one gradient check.
#[derive(Clone, Debug, Default)]
pub struct GradCoverage {
    /// Derivatives compared with finite differences and found to agree.
    pub compared: usize,
    /// Of those, clearly non-zero ones (|exact| > 1e-4).
    pub non_zero: usize,
    /// Probes skipped: a branch changes on the probe, a value is non-finite, or the step
    /// cannot resolve the derivative (the estimates at h and h/2 disagree).
    pub skipped_branch: usize,
    pub skipped_unresolved: usize,
    /// Failures (descriptions); the caller asserts this is empty.
    pub failures: Vec<String>,
}

impl GradCoverage {
    pub fn add(&mut self, o: &GradCoverage) {
        self.compared += o.compared;
        self.non_zero += o.non_zero;
        self.skipped_branch += o.skipped_branch;
        self.skipped_unresolved += o.skipped_unresolved;
        self.failures.extend(o.failures.iter().cloned());
    }
    pub fn skipped(&self) -> usize {
        self.skipped_branch + self.skipped_unresolved
    }
}

/// The tolerance of the finite-difference comparison, stated once:
///
/// |exact − R| ≤ REL · (1 + |exact|) + TRUNC · |D(h) − D(h/2)| + NOISE · J / h + ROUND · ε · S / h
///
/// with REL = 2e-3, TRUNC = 0.5, NOISE = 4, ROUND = 1, where D(h) is the central difference
/// over [x−h, x+h] of L = Σ seed_k · channel_k (channels in f32 by the interpreter, summed in
/// f64), R = D(h/2) + (D(h/2) − D(h)) / 3 its Richardson extrapolation (the h² truncation
/// term cancels; |D(h) − D(h/2)| bounds what is left), J the measured f32 rounding noise of L
/// (the largest deviation of L at four points a few dozen ulps from x from the line through
/// L(x) with slope D(h): deep intermediates such as `97 · pith` in wood pores lose low bits
/// that the outputs do not show; R carries about 4 J / h of it), ε f32's epsilon and
/// S = Σ |seed_k| · max|channel_k| over the probe (the rounding of the channels themselves:
/// half an ulp each, differenced over 2h). A probe is compared only when every piecewise
/// decision of the program is the same at x−h, x−h/2, x, x+h/2, x+h and the jittered points
/// (so the probe lies in one smooth piece), every value there is finite, and
/// |D(h) − D(h/2)| ≤ 5 % · (1 + |D(h)|) (the step resolves the derivative).
pub const GRAD_REL: f32 = 2e-3;
pub const GRAD_TRUNC: f32 = 0.5;
pub const GRAD_NOISE: f32 = 4.0;
pub const GRAD_ROUND: f32 = 1.0;
/// Probe steps, relative to max(1, |x|): the second is used when the first crosses a branch,
/// cannot resolve the derivative, or disagrees.
pub const GRAD_STEPS: [f32; 2] = [1e-3, 1e-4];

/// Checks the fused adjoint of `forward` against central finite differences of the
/// seed-weighted forward channels, at each `(u, v)` of `points`, for u, v and every slot the
/// adjoint differentiates (its layout's `wrt`).
pub fn check_gradients(
    label: &str,
    forward: &Program,
    adjoint: &Adjoint,
    params: &[f32],
    points: &[(f32, f32)],
    seeds: &[[f32; 9]],
) -> GradCoverage {
    let nch = forward.outputs.len();
    assert_eq!(nch, Channel::COUNT);
    let (layout, adjoint) = (&adjoint.layout, &adjoint.program);
    layout.check(forward, adjoint).unwrap_or_else(|e| panic!("{label}: adjoint layout: {e}"));
    let slots = layout.wrt();
    let mut cov = GradCoverage::default();

    // Exact gradients, by the interpreter, one batch.
    let u: Vec<f32> = points.iter().map(|p| p.0).collect();
    let v: Vec<f32> = points.iter().map(|p| p.1).collect();
    let seed_cols: Vec<Vec<f32>> = (0..nch).map(|c| seeds.iter().map(|s| s[c]).collect()).collect();
    let seed_refs: Vec<&[f32]> = seed_cols.iter().map(|c| &c[..]).collect();
    let exact = interp_points(adjoint, params, &u, &v, &seed_refs);
    let base = interp_points(forward, params, &u, &v, &[]);
    for (k, e) in exact.iter().enumerate() {
        // The fused program's forward part is the forward program, bit for bit.
        for c in 0..nch {
            if e[c].to_bits() != base[k][c].to_bits() && !(e[c].is_nan() && base[k][c].is_nan()) {
                cov.failures.push(format!(
                    "{label}: fused forward channel {} = {} but forward = {}",
                    Channel::ALL[c],
                    e[c],
                    base[k][c]
                ));
            }
        }
    }

    let mut vars = vec![(Var::U, layout.d_u()), (Var::V, layout.d_v())];
    vars.extend(slots.iter().enumerate().map(|(k, &s)| (Var::Slot(s), layout.d_param(k))));
    for &(var, output) in &vars {
        // Steps: a first try, and a smaller one when the first crosses a branch.
        for (pi, &(pu, pv)) in points.iter().enumerate() {
            let exact_d = exact[pi][output];
            let x0 = match var {
                Var::U => pu,
                Var::V => pv,
                Var::Slot(s) => params[s as usize],
            };
            // Two steps: the second (ten times smaller) is tried when the first crosses a
            // branch, cannot resolve the derivative, or disagrees (the larger step's truncation
            // error can exceed what |D(h) - D(h/2)| predicts on high-frequency noise). A wrong
            // derivative disagrees at both steps; the comparison is made with the same
            // tolerance formula at each.
            let mut outcome = Outcome::Branch;
            let mut failed: Vec<String> = Vec::new();
            for h0 in GRAD_STEPS {
                let h = h0 * x0.abs().max(1.0);
                match probe(forward, params, (pu, pv), var, (x0, h), &seeds[pi], exact_d) {
                    Outcome::Agreed => {
                        outcome = Outcome::Agreed;
                        break;
                    }
                    Outcome::Failed(msg) => failed.push(msg),
                    Outcome::Unresolved => {
                        if !matches!(outcome, Outcome::Failed(_)) {
                            outcome = Outcome::Unresolved;
                        }
                    }
                    Outcome::Branch => {}
                }
                if !failed.is_empty() {
                    outcome = Outcome::Failed(failed.join("; "));
                }
            }
            match outcome {
                Outcome::Branch => cov.skipped_branch += 1,
                Outcome::Unresolved => cov.skipped_unresolved += 1,
                Outcome::Agreed => {
                    cov.compared += 1;
                    cov.non_zero += (exact_d.abs() > 1e-4) as usize;
                }
                Outcome::Failed(msg) => cov.failures.push(format!(
                    "{label}: d/d{var} at (u, v) = ({pu}, {pv}), params {params:?}, seeds {:?}: {msg}",
                    seeds[pi]
                )),
            }
        }
    }
    cov
}

enum Outcome {
    Agreed,
    Branch,
    Unresolved,
    Failed(String),
}

fn probe(
    forward: &Program,
    params: &[f32],
    (u, v): (f32, f32),
    var: Var,
    (x0, h): (f32, f32),
    seeds: &[f32; 9],
    exact: f32,
) -> Outcome {
    // Five probe points, then four jittered copies of x (a few dozen ulps away) whose spread
    // measures the f32 rounding noise of the evaluated loss.
    let jitter = x0.abs().max(1.0) * f32::EPSILON * 16.0;
    let offsets = [-h, -h / 2.0, 0.0, h / 2.0, h, jitter, 2.0 * jitter, 3.0 * jitter, 5.0 * jitter];
    let xs: Vec<f32> = offsets.iter().map(|&d| x0 + d).collect();
    let lanes: Vec<Lane> = xs
        .iter()
        .map(|&x| match var {
            Var::U => Lane { u: x, v, params: params.to_vec() },
            Var::V => Lane { u, v: x, params: params.to_vec() },
            Var::Slot(s) => {
                let mut p = params.to_vec();
                p[s as usize] = x;
                Lane { u, v, params: p }
            }
        })
        .collect();
    let sigs = eval_signatures(forward, &lanes);
    if sigs.iter().any(Option::is_none) || !exact.is_finite() {
        return Outcome::Branch;
    }
    let first = sigs[0].as_ref().unwrap().1;
    if sigs.iter().any(|s| s.as_ref().unwrap().1 != first) {
        return Outcome::Branch;
    }
    // The values themselves come from the interpreter.
    let values: Vec<Vec<f32>> =
        lanes.iter().map(|l| interp_points(forward, &l.params, &[l.u], &[l.v], &[]).remove(0)).collect();
    for (l, s) in values.iter().zip(&sigs) {
        let mine = &s.as_ref().unwrap().0;
        if l.iter().zip(mine).any(|(a, b)| a.to_bits() != b.to_bits()) {
            return Outcome::Failed(format!(
                "the signature evaluator disagrees with the interpreter: {l:?} vs {mine:?}"
            ));
        }
    }
    let loss: Vec<f64> =
        values.iter().map(|vals| vals.iter().zip(seeds).map(|(f, s)| (*f as f64) * (*s as f64)).sum()).collect();
    let scale: f32 = (0..values[0].len())
        .map(|c| seeds[c].abs() * values.iter().map(|vals| vals[c].abs()).fold(0.0, f32::max))
        .sum();
    let d_h = ((loss[4] - loss[0]) / (xs[4] as f64 - xs[0] as f64)) as f32;
    let d_half = ((loss[3] - loss[1]) / (xs[3] as f64 - xs[1] as f64)) as f32;
    let disagreement = (d_h - d_half).abs();
    let resolved = disagreement <= 0.05 * (1.0 + d_h.abs()); // false for NaN, on purpose
    if !resolved {
        return Outcome::Unresolved;
    }
    // Rounding noise: how far the jittered losses stray from the line through x with slope D(h).
    let noise = (5..9)
        .map(|j| (loss[j] - loss[2] - d_h as f64 * (xs[j] as f64 - xs[2] as f64)).abs() as f32)
        .fold(0.0f32, f32::max);
    // Richardson extrapolation: D(h/2) + (D(h/2) − D(h)) / 3 cancels the h² truncation term.
    let extrapolated = d_half + (d_half - d_h) / 3.0;
    let tolerance = GRAD_REL * (1.0 + exact.abs())
        + GRAD_TRUNC * disagreement
        + GRAD_NOISE * noise / h
        + GRAD_ROUND * f32::EPSILON * scale / h;
    if std::env::var("PSC_GRAD_DEBUG").is_ok() {
        eprintln!(
            "probe d/d{var} h={h}: exact {exact} R {extrapolated} D(h) {d_h} D(h/2) {d_half} | rel {} trunc {} noise {} round {}",
            GRAD_REL * (1.0 + exact.abs()),
            GRAD_TRUNC * disagreement,
            GRAD_NOISE * noise / h,
            GRAD_ROUND * f32::EPSILON * scale / h
        );
    }
    if (exact - extrapolated).abs() <= tolerance {
        Outcome::Agreed
    } else {
        Outcome::Failed(format!(
            "adjoint {exact}, extrapolated central differences {extrapolated} (D(h) = {d_h} at h = {h}, D(h/2) = {d_half}), \
             tolerance {tolerance}"
        ))
    }
}

/// `n` random points in [0, 1)² and a random seed vector (each in [-1, 1]) per point.
pub fn random_points(rng: &mut Rng, n: usize) -> (Vec<(f32, f32)>, Vec<[f32; 9]>) {
    let points = (0..n).map(|_| (rng.unit(), rng.unit())).collect();
    let seeds = (0..n).map(|_| std::array::from_fn(|_| rng.range(-1.0, 1.0))).collect();
    (points, seeds)
}

// ---------------------------------------------------------------------------------------------
// Tiling

/// Tolerance of the tiling comparison: |a − b| ≤ TILE_ABS + TILE_REL · max(|a|, |b|). The
/// evaluation at u + 1 rounds u to a coarser f32 grid (one more bit of exponent), and
/// `u · freq` then carries that error times the frequency into every later value.
pub const TILE_ABS: f32 = 2e-3;
pub const TILE_REL: f32 = 2e-3;

pub fn tile_close(a: f32, b: f32) -> bool {
    (a - b).abs() <= TILE_ABS + TILE_REL * a.abs().max(b.abs()) || (a.is_nan() && b.is_nan())
}

/// Outcome of the tiling check of one program at one parameter vector.
#[derive(Clone, Debug, Default)]
pub struct TileReport {
    /// Point comparisons (each compares all channels at uv against uv + shift).
    pub compared: usize,
    /// Mismatches that went away at small offsets of the point: a discontinuity hit.
    pub isolated: usize,
    /// Consistent mismatches (the first few described).
    pub failures: Vec<String>,
    pub failure_count: usize,
}

/// Compares every output at `uv` with `uv + (1,0)`, `uv + (0,1)` and `uv + (1,1)` at `n`
/// random points. A mismatching point is re-examined at eight small offsets (1e-4 and 1e-3 of
/// the tile each way): when at least six of them match, it was an isolated discontinuity hit
/// (a cell border that the coarser f32 grid at u+1 puts on the other side); otherwise it is a
/// consistent mismatch, a failure.
pub fn check_tiling(program: &Program, params: &[f32], rng: &mut Rng, n: usize) -> TileReport {
    let shifts = [(1.0f32, 0.0f32), (0.0, 1.0), (1.0, 1.0)];
    let pts: Vec<(f32, f32)> = (0..n).map(|_| (rng.unit(), rng.unit())).collect();
    let mut rep = TileReport::default();
    let mismatch = |a: &[f32], b: &[f32]| -> Option<usize> { (0..a.len()).find(|&c| !tile_close(a[c], b[c])) };
    let eval_at = |pts: &[(f32, f32)], shift: (f32, f32)| {
        let u: Vec<f32> = pts.iter().map(|p| p.0 + shift.0).collect();
        let v: Vec<f32> = pts.iter().map(|p| p.1 + shift.1).collect();
        interp_points(program, params, &u, &v, &[])
    };
    let base = eval_at(&pts, (0.0, 0.0));
    for shift in shifts {
        let moved = eval_at(&pts, shift);
        for (k, &(u, v)) in pts.iter().enumerate() {
            rep.compared += 1;
            let Some(c) = mismatch(&base[k], &moved[k]) else { continue };
            let d = [1e-4f32, 1e-3];
            let around: Vec<(f32, f32)> =
                d.iter().flat_map(|&e| [(u + e, v), (u - e, v), (u, v + e), (u, v - e)]).collect();
            let a0 = eval_at(&around, (0.0, 0.0));
            let a1 = eval_at(&around, shift);
            let matching = a0.iter().zip(&a1).filter(|(x, y)| mismatch(x, y).is_none()).count();
            if matching >= 6 {
                rep.isolated += 1;
            } else {
                rep.failure_count += 1;
                if rep.failures.len() < 3 {
                    let name = program.outputs.get(c).map_or("?", |o| o.name.as_str());
                    rep.failures.push(format!(
                        "{name} at ({u}, {v}) = {} but at +{shift:?} = {} ({matching}/8 nearby points match)",
                        base[k][c], moved[k][c]
                    ));
                }
            }
        }
    }
    rep
}
