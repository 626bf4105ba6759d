//! Shared helpers for the JIT tests: random programs, random points, comparisons.
#![allow(dead_code)]

use psc_base::SplitMix64;
use psc_compiler::ir::random::{non_leaf_op, NON_LEAF_KINDS};
use psc_compiler::ir::{Builder, NodeId, Op, Output, Program};

/// [`SplitMix64`] with the ranges these tests draw from, so point sets are reproducible from
/// a proptest seed.
pub struct Rng(SplitMix64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix64::new(seed))
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.0.next_f32()
    }
    /// A mix of ordinary, large, tiny and special values.
    pub fn nasty(&mut self) -> f32 {
        match self.next_u64() % 16 {
            0 => 0.0,
            1 => -0.0,
            2 => f32::NAN,
            3 => f32::INFINITY,
            4 => f32::NEG_INFINITY,
            5 => 1e-40,
            6 => self.uniform(-1e6, 1e6),
            7 => self.uniform(-200.0, 200.0),
            8 => (self.next_u64() % 21) as f32 - 10.0,
            _ => self.uniform(-4.0, 4.0),
        }
    }
}

/// Which ops a random program may use.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum OpSet {
    /// Every op.
    All,
    /// Every op except sin, cos, exp, log, pow, atan2.
    Exact,
}

/// `non_leaf_op` kinds of sin, cos, exp, log, pow, atan2.
const TRANSCENDENTAL: [usize; 6] = [4, 5, 6, 7, 14, 15];

/// Builds a random DAG: `spec` entries are (op kind, operand picks); `consts` seed the leaves.
pub fn random_program(
    spec: &[(u8, u32, u32, u32)],
    consts: &[f32],
    num_seeds: u32,
    outs: &[u32],
    set: OpSet,
) -> Program {
    let mut b = Builder::new();
    let mut pool: Vec<NodeId> = vec![b.u(), b.v(), b.param(0), b.param(1), b.param(2)];
    for s in 0..num_seeds {
        pool.push(b.seed(s));
    }
    for &c in consts {
        pool.push(b.constant(c));
    }
    for &(kind, x, y, z) in spec {
        let mut kind = kind as usize % (NON_LEAF_KINDS + 1);
        if set == OpSet::Exact && TRANSCENDENTAL.contains(&kind) {
            kind = [0, 1, 2, 3, 8, 9][kind % 6];
        }
        let pick = |k: u32| pool[k as usize % pool.len()];
        let (a, c, d) = (pick(x), pick(y), pick(z));
        // The one kind past the last is a square, so that squares of wide ranges are common.
        let op = non_leaf_op(kind, a, c, d).unwrap_or(Op::Mul(a, a));
        let id = b.push(op);
        pool.push(id);
    }
    let n = pool.len() as u32;
    let mut outputs: Vec<Output> = outs
        .iter()
        .enumerate()
        .map(|(k, &o)| Output { name: format!("o{k}"), node: pool[(n - 1 - o % n.min(6)) as usize] })
        .collect();
    // Always also expose the last node, the deepest one.
    outputs.push(Output { name: "last".into(), node: *pool.last().unwrap() });
    b.reserve_params(3);
    b.finish(outputs)
}

/// Equal bits, or both NaN (payloads differ between paths), or both zero (`max(-0, 0)` may
/// return either zero, so `sqrt(max(x, 0))` may too).
pub fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()) || (a == 0.0 && b == 0.0)
}

/// Strictly equal bits, or both NaN.
pub fn same_bits(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

/// Runs a compiled kernel over columns, returning the output columns.
pub fn run_jit(k: &psc_jit::CompiledKernel, params: &[f32], u: &[f32], v: &[f32], seeds: &[Vec<f32>]) -> Vec<Vec<f32>> {
    let n = u.len();
    let mut outs = vec![vec![0.0f32; n]; k.num_outputs()];
    let seed_refs: Vec<&[f32]> = seeds.iter().map(|s| &s[..]).collect();
    let mut out_refs: Vec<&mut [f32]> = outs.iter_mut().map(|c| &mut c[..]).collect();
    k.run(params, u, v, &seed_refs, &mut out_refs).expect("shapes are right");
    outs
}

/// Resident set size of this process in bytes.
pub fn rss_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("Linux /proc");
    let pages: u64 = statm.split_whitespace().nth(1).unwrap().parse().unwrap();
    pages * 4096
}
