//! The random-program generator of the gradient tests and the per-node evaluation helpers
//! their finite-difference probes use.

use proptest::prelude::*;
use psc_compiler::diff::Wrt;
use psc_compiler::interp::eval_point;
use psc_compiler::ir::random::{non_leaf_op, NON_LEAF_KINDS};
use psc_compiler::ir::{semantics, Builder, NodeId, Op, Output, Program};

pub const NUM_PARAMS: u32 = 3;

// ---------------------------------------------------------------------------------------------
// Random programs

/// Every non-leaf op kind's mnemonic, in the order `random::non_leaf_op` numbers them (the
/// generator's `kind` k > 0 is `non_leaf_op(k - 1, …)`; 0 is a constant).
pub static OP_KINDS: std::sync::LazyLock<Vec<&'static str>> = std::sync::LazyLock::new(|| {
    (0..NON_LEAF_KINDS).map(|k| non_leaf_op(k, NodeId(0), NodeId(0), NodeId(0)).expect("a kind").mnemonic()).collect()
});

/// One generated node: an op kind, three operand picks and a constant (for kind 0).
#[derive(Clone, Debug)]
pub struct NodeSpec {
    kind: usize,
    picks: [u16; 3],
    constant: f32,
}

pub fn node_spec() -> impl Strategy<Value = NodeSpec> {
    (0..=NON_LEAF_KINDS, any::<[u16; 3]>(), -3.0f32..3.0).prop_map(|(kind, picks, constant)| NodeSpec {
        kind,
        picks,
        constant,
    })
}

/// Random DAGs over u, v, three params and constants, built through `Builder` (so folded and
/// hash-consed like real lowered graphs), with one to three outputs.
pub fn program() -> impl Strategy<Value = Program> {
    (prop::collection::vec(node_spec(), 3..28), prop::collection::vec(any::<u16>(), 0..3))
        .prop_map(|(specs, extra_outputs)| build_program(&specs, &extra_outputs))
}

pub fn build_program(specs: &[NodeSpec], extra_outputs: &[u16]) -> Program {
    let mut b = Builder::new();
    let mut pool = vec![b.u(), b.v()];
    pool.extend((0..NUM_PARAMS).map(|p| b.param(p)));
    for spec in specs {
        // A third of the picks come from the last few nodes, so programs grow deep, not only
        // wide; a third are inputs, so that most nodes depend on several variables.
        let pick = |k: usize| {
            let (raw, n) = (spec.picks[k] as usize, pool.len());
            match raw % 3 {
                0 => pool[n - 1 - (raw / 3) % n.min(4)],
                1 => pool[(raw / 3) % n],
                _ => pool[(raw / 3) % (2 + NUM_PARAMS as usize)],
            }
        };
        let (a, c, d) = (pick(0), pick(1), pick(2));
        let node = match spec.kind {
            0 => b.constant(spec.constant),
            k => b.push(non_leaf_op(k - 1, a, c, d).expect("kind in range")),
        };
        pool.push(node);
    }
    // The main output sums the last three nodes, so that it rarely ends in a piecewise-constant
    // op and usually depends on several inputs.
    let n = pool.len();
    let tail = b.add(pool[n - 1], pool[n - 2]);
    let mut outputs = vec![b.add(tail, pool[n - 3])];
    outputs.extend(extra_outputs.iter().map(|&k| pool[k as usize % pool.len()]));
    let outputs = outputs.into_iter().enumerate().map(|(k, node)| Output { name: format!("o{k}"), node }).collect();
    let mut program = b.finish(outputs);
    program.eliminate_dead_code();
    program
}

// ---------------------------------------------------------------------------------------------
// Evaluation helpers

#[derive(Clone, Copy, Debug)]
pub struct Point {
    pub u: f32,
    pub v: f32,
    pub params: [f32; NUM_PARAMS as usize],
}

impl Point {
    pub fn get(&self, wrt: Wrt) -> f32 {
        match wrt {
            Wrt::U => self.u,
            Wrt::V => self.v,
            Wrt::Param(p) => self.params[p as usize],
        }
    }
    pub fn with(mut self, wrt: Wrt, x: f32) -> Point {
        match wrt {
            Wrt::U => self.u = x,
            Wrt::V => self.v = x,
            Wrt::Param(p) => self.params[p as usize] = x,
        }
        self
    }
    pub fn eval(&self, program: &Program, seeds: &[f32]) -> Vec<f32> {
        eval_point(program, &self.params, self.u, self.v, seeds)
    }
}

/// Every node's value, straight from `semantics`, for the branch and magnitude checks.
pub fn node_values(program: &Program, at: &Point, seeds: &[f32]) -> Vec<f32> {
    let mut values: Vec<f32> = Vec::with_capacity(program.nodes.len());
    for op in &program.nodes {
        let x = match *op {
            Op::Const(bits) => f32::from_bits(bits),
            Op::U => at.u,
            Op::V => at.v,
            Op::Param(p) => at.params[p as usize],
            Op::Seed(k) => seeds[k as usize],
            _ => {
                let mut arg = op.operands().map(|id| values[id.index()]);
                let (a, b, c) = (arg.next().unwrap_or(0.0), arg.next().unwrap_or(0.0), arg.next().unwrap_or(0.0));
                semantics::eval(op, a, b, c).unwrap()
            }
        };
        values.push(x);
    }
    values
}

/// Which side of each discontinuity (of the value or of the derivative) every node is on. Two
/// points with equal signatures are in the same smooth piece of every op, so a finite difference
/// between them measures the derivative the rules define.
pub fn branch_signature(program: &Program, values: &[f32]) -> Vec<i64> {
    let val = |id: NodeId| values[id.index()];
    let key = |x: bool| x as i64;
    program
        .nodes
        .iter()
        .enumerate()
        .map(|(i, op)| match *op {
            Op::Floor(a) => val(a).floor() as i64,
            Op::Hash(a, b) => ((semantics::to_int(val(a)) as i64) << 32) ^ semantics::to_int(val(b)) as i64,
            // Comparisons are discontinuous in their own result.
            Op::Lt(..) | Op::Le(..) | Op::Eq(..) => values[i] as i64,
            Op::Select(c, ..) => key(val(c) != 0.0),
            Op::Min(a, b) => key(val(a) < val(b)),
            Op::Max(a, b) => key(val(a) > val(b)),
            Op::Abs(a) => key(val(a) < 0.0),
            Op::Sqrt(a) | Op::Log(a) => key(val(a) > f32::MIN_POSITIVE),
            Op::Pow(a, _) => key(val(a) > 0.0),
            Op::Div(_, b) => key(val(b) > 0.0),
            // The branch cut of atan2 lies on the negative x axis.
            Op::Atan2(y, x) => key(val(y) >= 0.0) * 2 + key(val(x) >= 0.0),
            _ => 0,
        })
        .collect()
}

/// Whether every node is close to linear over the probe (`values_at[0]`, `[2]`, `[4]` at x-h,
/// x, x+h): its second difference is small next to its first. A node the step cannot resolve
/// (`sin` of a fast-moving argument) may hide under a large smooth term of the output, so the
/// check is per node, not on the output only.
pub fn resolved_by_step(values_at: &[Vec<f32>]) -> bool {
    let (minus, centre, plus) = (&values_at[0], &values_at[2], &values_at[4]);
    (0..centre.len()).all(|i| {
        let first = (plus[i] - minus[i]).abs();
        let second = (plus[i] + minus[i] - 2.0 * centre[i]).abs();
        second <= 0.05 * first + 1e-5 * (1.0 + centre[i].abs())
    })
}

/// Values of every node stay moderate and finite at `at`, so f32 finite differences are
/// meaningful; returns the largest magnitude.
pub fn max_magnitude(values: &[f32]) -> Option<f32> {
    values.iter().try_fold(0.0f32, |m, &x| if x.is_finite() && x.abs() < 1e5 { Some(m.max(x.abs())) } else { None })
}

pub fn is_variable(op: &Op, wrt: Wrt) -> bool {
    match (wrt, *op) {
        (Wrt::U, Op::U) | (Wrt::V, Op::V) => true,
        (Wrt::Param(p), Op::Param(q)) => p == q,
        _ => false,
    }
}

/// The largest finite magnitude among the nodes that depend on an input `is_input` (tangents
/// of a derivative program, adjoints of a fused program): it bounds the f32 rounding error of
/// a result computed from them.
pub fn largest_dependent_value(program: &Program, values: &[f32], is_input: impl Fn(&Op) -> bool) -> f32 {
    let mut depends = vec![false; program.nodes.len()];
    let mut largest = 0.0f32;
    for (i, op) in program.nodes.iter().enumerate() {
        depends[i] = if op.is_leaf() { is_input(op) } else { op.operands().any(|x| depends[x.index()]) };
        if depends[i] && values[i].is_finite() {
            largest = largest.max(values[i].abs());
        }
    }
    largest
}

pub fn point() -> impl Strategy<Value = (Point, [f32; 3])> {
    (0.0f32..1.0, 0.0f32..1.0, [-2.0f32..2.0, -2.0f32..2.0, -2.0f32..2.0], [-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0])
        .prop_map(|(u, v, params, seeds)| (Point { u, v, params }, seeds))
}
