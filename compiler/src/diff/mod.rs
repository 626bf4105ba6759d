//! Symbolic differentiation of IR: forward mode (d/du, d/dv, d/dparam, used for normals from
//! height and for `ddu`/`ddv`, nested to any order) and reverse mode (one fused program that
//! computes every output together with the adjoints of u, v and chosen parameters).
//!
//! Both modes emit IR through a [`Builder`], so derivative code is hash-consed with the values
//! it differentiates (`cos(x)` for `d sin(x)` reuses a `cos(x)` the program already has) and
//! constant-folded (a factor `1` or `0` disappears). Both use the same per-op rules, defined
//! once (`local_rule`, below), so forward and reverse agree by construction.
//!
//! # Activity
//! A node is *active* when its derivative is not identically zero: it is the differentiation
//! variable, or an op with a non-zero rule that has an active operand. Piecewise-constant ops
//! (`floor`, `hash`, `lt`, `le`, `eq`) are never active, and `select(c, a, b)` is active only
//! through `a` or `b`, never through `c`. Inactive nodes get no derivative code at all.
//!
//! # Rules (as OSL and Halide do at kinks: the derivative of the branch that was taken)
//! | op | derivative |
//! | --- | --- |
//! | `neg a` | `-a'` |
//! | `abs a` | `a' * select(a < 0, -1, 1)` (so `+1` at `a = 0`) |
//! | `floor`, `hash`, `lt`, `le`, `eq` | `0` (hence `fract x = x - floor x` has derivative `x'`) |
//! | `sqrt a` | `a' * 0.5 / sqrt(a)` where `a > f32::MIN_POSITIVE`, else `0` (never inf/NaN at 0) |
//! | `sin a`, `cos a`, `exp a` | `a' cos a`, `-a' sin a`, `a' exp a` |
//! | `log a` | `a' / a` where `a > f32::MIN_POSITIVE`, else `0` (the op clamps its input there) |
//! | `a + b`, `a - b`, `a * b` | `a' + b'`, `a' - b'`, `a' b + a b'` |
//! | `a / b` | `a' / b - b' (a / b) / b` (quotient rule) |
//! | `min(a, b)`, `max(a, b)` | `select(a < b, a', b')`, `select(b < a, a', b')`: the active branch, same comparison as the op |
//! | `select(c, a, b)` | `select(c, a', b')` |
//! | `pow(a, b)` | `a' b pow(a, b - 1) + b' pow(a, b) log(a)`; both terms are `0` where `a <= 0` because `pow` is `0` there |
//! | `atan2(y, x)` | `(x y' - y x') / (x² + y²)`, `0` where `x² + y²` is `0` (origin or underflow) |
//!
//! `u`, `v` and `param i` differentiate to `1` or `0`; constants and seeds to `0`.
//!
//! # Non-finite values
//! The guarded quotients (`sqrt`, `log`, `atan2`) never divide where their guard fails, so the
//! derivative code of a program with finite values has finite values too, including in the
//! branch a `select` discards. That matters for reverse mode, which multiplies the discarded
//! branch's zero adjoint by its partials: `0 · inf` would be NaN. The remaining limit: where
//! the *forward* program already has a non-finite intermediate in a discarded branch
//! (`select(c, 0, sqrt(v) / 0)`), forward mode routes around it but the adjoint is NaN, as in
//! other reverse-mode systems (JAX's `where`). The runtime reports such intermediates anyway.
//! So is a derivative that overflows f32 where the value does not (the slope of
//! `pow(0.36, -87.3) ≈ 3e38` is about 9e38): not representable, and NaN in a discarded branch.

pub mod forward;
pub mod reverse;

pub use forward::{derivative, derivative_program, ForwardDiff, Wrt};
pub use reverse::{adjoint, Adjoint, AdjointLayout};

use crate::ir::{Builder, NodeId, Op};

/// Inputs at or below this make the `sqrt` and `log` derivatives 0: `log` is constant there,
/// and `0.5 / sqrt(a)` would be infinite at 0.
const DOMAIN_GUARD: f32 = f32::MIN_POSITIVE;

/// Whether a non-leaf `op` is active given which of its operands are. Leaves are decided by the
/// caller (it knows the differentiation variables).
pub(crate) fn is_active_op(op: &Op, operand_active: impl Fn(NodeId) -> bool) -> bool {
    match *op {
        Op::Floor(_) | Op::Hash(..) | Op::Lt(..) | Op::Le(..) | Op::Eq(..) => false,
        Op::Select(_, a, b) => operand_active(a) || operand_active(b),
        _ => op.operands().any(operand_active),
    }
}

/// Extends `flags` (activity of nodes `0..flags.len()`) to nodes `0..len`, reading ops with
/// `op_at`. Incremental, so a builder that keeps growing can be tracked in amortised O(1).
pub(crate) fn extend_activity(
    flags: &mut Vec<bool>,
    len: usize,
    op_at: impl Fn(usize) -> Op,
    leaf_active: impl Fn(&Op) -> bool,
) {
    for i in flags.len()..len {
        let op = op_at(i);
        let active = if op.is_leaf() { leaf_active(&op) } else { is_active_op(&op, |x| flags[x.index()]) };
        flags.push(active);
    }
}

/// How the derivative of one operand enters the derivative of the node.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Factor {
    One,
    Times(NodeId),
    /// Kept separate from `Times(1 / x)` because one division is cheaper than two ops.
    DividedBy(NodeId),
}

impl Factor {
    pub(crate) fn apply(self, b: &mut Builder, derivative: NodeId) -> NodeId {
        match self {
            Factor::One => derivative,
            Factor::Times(k) => b.mul(k, derivative),
            Factor::DividedBy(k) => b.div(derivative, k),
        }
    }
}

/// One term `± factor · d(operand)` of a chain rule. The sign is kept apart so that sums
/// become `sub` instead of `add(neg …)`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Term {
    pub operand: NodeId,
    pub factor: Factor,
    pub negated: bool,
}

/// The chain rule of one node, restricted to its active operands.
#[derive(Clone, Debug)]
pub(crate) enum LocalRule {
    /// `d(node) = Σ ± factor · d(operand)` (empty for piecewise-constant ops).
    Linear(Vec<Term>),
    /// `d(node) = select(cond, d(if_true), d(if_false))`: min, max and select route the
    /// derivative to the branch they take instead of multiplying by 0/1 masks.
    Route { cond: NodeId, if_true: NodeId, if_false: NodeId },
}

/// Emits the local partial derivatives of `node` (a node of `b`) for its active operands only,
/// so that no partial is computed for an operand whose derivative is zero.
pub(crate) fn local_rule(b: &mut Builder, node: NodeId, active: &dyn Fn(NodeId) -> bool) -> LocalRule {
    let mut terms = Vec::with_capacity(2);
    let mut term = |operand: NodeId, factor: Factor, negated: bool| {
        if active(operand) {
            terms.push(Term { operand, factor, negated });
        }
    };
    match b.op(node) {
        Op::Const(_) | Op::U | Op::V | Op::Param(_) | Op::Seed(_) => {}
        Op::Floor(_) | Op::Hash(..) | Op::Lt(..) | Op::Le(..) | Op::Eq(..) => {}
        Op::Neg(a) => term(a, Factor::One, true),
        Op::Abs(a) => {
            let zero = b.constant(0.0);
            let is_negative = b.lt(a, zero);
            let (minus_one, one) = (b.constant(-1.0), b.constant(1.0));
            let sign = b.select(is_negative, minus_one, one);
            term(a, Factor::Times(sign), false);
        }
        Op::Sqrt(a) => {
            let inside = above_tiny(b, a);
            let half = b.constant(0.5);
            let slope = guarded_quotient(b, inside, half, node);
            term(a, Factor::Times(slope), false);
        }
        Op::Sin(a) => {
            let c = b.cos(a);
            term(a, Factor::Times(c), false);
        }
        Op::Cos(a) => {
            let s = b.sin(a);
            term(a, Factor::Times(s), true);
        }
        Op::Exp(a) => term(a, Factor::Times(node), false),
        Op::Log(a) => {
            let inside = above_tiny(b, a);
            let one = b.constant(1.0);
            let slope = guarded_quotient(b, inside, one, a);
            term(a, Factor::Times(slope), false);
        }
        Op::Add(a, b_) => {
            term(a, Factor::One, false);
            term(b_, Factor::One, false);
        }
        Op::Sub(a, b_) => {
            term(a, Factor::One, false);
            term(b_, Factor::One, true);
        }
        Op::Mul(a, b_) => {
            term(a, Factor::Times(b_), false);
            term(b_, Factor::Times(a), false);
        }
        Op::Div(a, b_) => {
            term(a, Factor::DividedBy(b_), false);
            if active(b_) {
                let quotient_over_divisor = b.div(node, b_);
                term(b_, Factor::Times(quotient_over_divisor), true);
            }
        }
        Op::Pow(a, e) => {
            // No explicit guard: `pow` is 0 for a <= 0, which zeroes both partials there
            // (`log` is finite everywhere, so 0 · log a stays 0).
            if active(a) {
                let one = b.constant(1.0);
                let e_minus_one = b.sub(e, one);
                let power = b.pow(a, e_minus_one);
                let slope = b.mul(e, power);
                term(a, Factor::Times(slope), false);
            }
            if active(e) {
                let ln_a = b.log(a);
                let slope = b.mul(node, ln_a);
                term(e, Factor::Times(slope), false);
            }
        }
        Op::Atan2(y, x) => {
            let (xx, yy) = (b.mul(x, x), b.mul(y, y));
            let radius_sq = b.add(xx, yy);
            let (zero, one) = (b.constant(0.0), b.constant(1.0));
            let away_from_origin = b.lt(zero, radius_sq);
            let inverse_radius_sq = guarded_quotient(b, away_from_origin, one, radius_sq);
            if active(y) {
                let slope = b.mul(x, inverse_radius_sq);
                term(y, Factor::Times(slope), false);
            }
            if active(x) {
                let slope = b.mul(y, inverse_radius_sq);
                term(x, Factor::Times(slope), true);
            }
        }
        // Same comparisons as `semantics::min`/`max`, so ties route to the branch the op takes.
        Op::Min(a, b_) => return LocalRule::Route { cond: b.lt(a, b_), if_true: a, if_false: b_ },
        Op::Max(a, b_) => return LocalRule::Route { cond: b.lt(b_, a), if_true: a, if_false: b_ },
        Op::Select(c, a, b_) => return LocalRule::Route { cond: c, if_true: a, if_false: b_ },
    }
    LocalRule::Linear(terms)
}

/// `x > DOMAIN_GUARD`.
fn above_tiny(b: &mut Builder, x: NodeId) -> NodeId {
    let tiny = b.constant(DOMAIN_GUARD);
    b.lt(tiny, x)
}

/// `numerator / denominator` where `inside`, else 0, without ever dividing by the denominator
/// outside: an infinite intermediate in the branch a select discards would still turn into NaN
/// in reverse mode (the discarded branch gets a zero adjoint, and 0 · inf is NaN), for example
/// in the adjoint of a program that contains a derivative (normals from height).
fn guarded_quotient(b: &mut Builder, inside: NodeId, numerator: NodeId, denominator: NodeId) -> NodeId {
    let (zero, one) = (b.constant(0.0), b.constant(1.0));
    let safe_denominator = b.select(inside, denominator, one);
    let quotient = b.div(numerator, safe_denominator);
    b.select(inside, quotient, zero)
}

/// Adds `± contribution` to an optional running sum.
pub(crate) fn accumulate(b: &mut Builder, sum: Option<NodeId>, contribution: NodeId, negated: bool) -> NodeId {
    match (sum, negated) {
        (None, false) => contribution,
        (None, true) => b.neg(contribution),
        (Some(s), false) => b.add(s, contribution),
        (Some(s), true) => b.sub(s, contribution),
    }
}
