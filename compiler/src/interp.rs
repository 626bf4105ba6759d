//! The reference interpreter: evaluates any [`Program`] (forward or adjoint) over a batch of
//! points, one node at a time across the whole batch.
//!
//! It is deliberately simple — it is the oracle the JIT is tested against — and its
//! node-by-node schedule is the same one diffmat uses, which makes it the baseline the JIT's
//! throughput is quoted against.

use crate::ir::{semantics, Op, Program};

/// Per-texel inputs of one batch, structure-of-arrays.
pub struct Batch<'a> {
    pub u: &'a [f32],
    pub v: &'a [f32],
    /// One slice per seed (adjoint programs only), each as long as `u`.
    pub seeds: &'a [&'a [f32]],
}

/// Evaluates `program` at every point of `batch`; returns one vector per program output.
///
/// # Panics
/// If the slices disagree in length, or `params`/`seeds` are shorter than the program needs:
/// callers validate those (they are programming errors, not input errors).
pub fn eval(program: &Program, params: &[f32], batch: &Batch) -> Vec<Vec<f32>> {
    let n = batch.u.len();
    assert_eq!(batch.v.len(), n, "u and v differ in length");
    assert!(params.len() >= program.num_params, "too few parameters");
    assert!(batch.seeds.len() >= program.num_seeds, "too few seeds");
    let uses = program.use_counts();
    let mut values: Vec<Option<Vec<f32>>> = vec![None; program.nodes.len()];
    let mut remaining = uses.clone();
    for (i, op) in program.nodes.iter().enumerate() {
        if uses[i] == 0 {
            continue;
        }
        let column: Vec<f32> = match *op {
            Op::Const(bits) => vec![f32::from_bits(bits); n],
            Op::U => batch.u.to_vec(),
            Op::V => batch.v.to_vec(),
            Op::Param(p) => vec![params[p as usize]; n],
            Op::Seed(s) => {
                let seed = batch.seeds[s as usize];
                assert_eq!(seed.len(), n, "seed length differs from the batch");
                seed.to_vec()
            }
            _ => {
                let mut ops = op.operands();
                let a = ops.next().map(|id| values[id.index()].as_deref().expect("operand alive"));
                let b = ops.next().map(|id| values[id.index()].as_deref().expect("operand alive"));
                let c = ops.next().map(|id| values[id.index()].as_deref().expect("operand alive"));
                (0..n)
                    .map(|k| {
                        let x = a.map_or(0.0, |s| s[k]);
                        let y = b.map_or(0.0, |s| s[k]);
                        let z = c.map_or(0.0, |s| s[k]);
                        semantics::eval(op, x, y, z).expect("non-leaf")
                    })
                    .collect()
            }
        };
        values[i] = Some(column);
        // Free operand columns as soon as their last user has run.
        for operand in op.operands() {
            let r = &mut remaining[operand.index()];
            *r -= 1;
            if *r == 0 && !program.outputs.iter().any(|o| o.node == operand) {
                values[operand.index()] = None;
            }
        }
    }
    program.outputs.iter().map(|o| values[o.node.index()].clone().expect("output computed")).collect()
}

/// Evaluates at a single point; convenient for tests and finite differences.
pub fn eval_point(program: &Program, params: &[f32], u: f32, v: f32, seeds: &[f32]) -> Vec<f32> {
    let seed_slices: Vec<[f32; 1]> = seeds.iter().map(|&s| [s]).collect();
    let seed_refs: Vec<&[f32]> = seed_slices.iter().map(|s| &s[..]).collect();
    let batch = Batch { u: &[u], v: &[v], seeds: &seed_refs };
    eval(program, params, &batch).into_iter().map(|col| col[0]).collect()
}
