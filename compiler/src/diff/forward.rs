//! Forward-mode differentiation: `d(node)/d(wrt)` as new IR in the same [`Builder`].
//!
//! The lowering differentiates many nodes of one graph with respect to the same variable (the
//! three channels of a normal, `ddu` inside `ddu`), so [`ForwardDiff`] keeps its memo across
//! calls; [`derivative`] is the one-shot form. Derivatives of derivatives work because the
//! derivative nodes are ordinary builder nodes: differentiate them again like any other.
//! The per-op rules are in the parent module.

use std::collections::HashMap;
use std::fmt;

use super::{accumulate, extend_activity, local_rule, LocalRule};
use crate::ir::{Builder, NodeId, Op, Output, Program};

/// The variable to differentiate with respect to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Wrt {
    U,
    V,
    Param(u32),
}

impl Wrt {
    fn is_leaf(self, op: &Op) -> bool {
        match (self, op) {
            (Wrt::U, Op::U) | (Wrt::V, Op::V) => true,
            (Wrt::Param(p), Op::Param(q)) => p == *q,
            _ => false,
        }
    }
}

impl fmt::Display for Wrt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Wrt::U => write!(f, "u"),
            Wrt::V => write!(f, "v"),
            Wrt::Param(p) => write!(f, "param{p}"),
        }
    }
}

/// `d(node)/d(wrt)`, emitted into `b`. Memoised within this call only; use [`ForwardDiff`] to
/// differentiate several nodes of one builder.
pub fn derivative(b: &mut Builder, node: NodeId, wrt: Wrt) -> NodeId {
    ForwardDiff::new(wrt).derivative(b, node)
}

/// A forward differentiator for one variable and **one builder**: it remembers the derivative of
/// every node it has seen, by id, so it must only be used with the builder it was first used
/// with (a builder only grows, so remembered ids stay valid).
#[derive(Clone, Debug)]
pub struct ForwardDiff {
    wrt: Wrt,
    /// `active[i]`: node `i` of the builder has a derivative that is not identically 0.
    active: Vec<bool>,
    derivatives: HashMap<NodeId, NodeId>,
}

impl ForwardDiff {
    pub fn new(wrt: Wrt) -> Self {
        ForwardDiff { wrt, active: Vec::new(), derivatives: HashMap::new() }
    }

    pub fn wrt(&self) -> Wrt {
        self.wrt
    }

    /// Whether `node` depends on the variable through an op with a non-zero derivative.
    pub fn is_active(&mut self, b: &Builder, node: NodeId) -> bool {
        self.track(b);
        self.active[node.index()]
    }

    /// `d(node)/d(wrt)`, emitted into `b` (a constant 0 when `node` is inactive).
    pub fn derivative(&mut self, b: &mut Builder, node: NodeId) -> NodeId {
        self.track(b);
        if !self.active[node.index()] {
            return b.constant(0.0);
        }
        if let Some(&d) = self.derivatives.get(&node) {
            return d;
        }
        // Iterative rather than recursive: generated graphs can be deep enough to overflow the
        // stack. Ids are a topological order, so differentiating the pending nodes in increasing
        // id order always finds operand derivatives ready.
        let pending = self.pending_in_cone(b, node);
        for id in pending {
            let d = self.differentiate_one(b, id);
            self.derivatives.insert(id, d);
        }
        self.derivatives[&node]
    }

    /// Catches up with nodes added to the builder since the last call (by anyone, including
    /// this differentiator: second derivatives differentiate its own output).
    fn track(&mut self, b: &Builder) {
        let wrt = self.wrt;
        extend_activity(&mut self.active, b.len(), |i| b.op(NodeId(i as u32)), |op| wrt.is_leaf(op));
    }

    /// Active nodes reachable from `root` through derivative-carrying operands whose derivative
    /// is not known yet, sorted by id.
    fn pending_in_cone(&self, b: &Builder, root: NodeId) -> Vec<NodeId> {
        let mut pending = Vec::new();
        let mut seen = std::collections::HashSet::new();
        let mut stack = vec![root];
        seen.insert(root);
        while let Some(id) = stack.pop() {
            pending.push(id);
            let op = b.op(id);
            let carriers = match op {
                // The condition of a select never carries a derivative.
                Op::Select(_, x, y) => [Some(x), Some(y), None],
                _ => {
                    let mut it = op.operands();
                    [it.next(), it.next(), it.next()]
                }
            };
            for operand in carriers.into_iter().flatten() {
                if self.active[operand.index()] && !self.derivatives.contains_key(&operand) && seen.insert(operand) {
                    stack.push(operand);
                }
            }
        }
        pending.sort_unstable();
        pending
    }

    /// Emits the derivative of one active node whose active operands are all differentiated.
    fn differentiate_one(&self, b: &mut Builder, node: NodeId) -> NodeId {
        if b.op(node).is_leaf() {
            return b.constant(1.0);
        }
        let active = &self.active;
        let rule = local_rule(b, node, &|x| active[x.index()]);
        let derivatives = &self.derivatives;
        let derivative_of = |b: &mut Builder, x: NodeId| match derivatives.get(&x) {
            Some(&d) => d,
            None => {
                debug_assert!(!active[x.index()], "operand {x} differentiated out of order");
                b.constant(0.0)
            }
        };
        match rule {
            LocalRule::Linear(terms) => {
                let mut sum = None;
                for term in terms {
                    let d = derivative_of(b, term.operand);
                    let contribution = term.factor.apply(b, d);
                    sum = Some(accumulate(b, sum, contribution, term.negated));
                }
                sum.unwrap_or_else(|| b.constant(0.0))
            }
            LocalRule::Route { cond, if_true, if_false } => {
                let d_true = derivative_of(b, if_true);
                let d_false = derivative_of(b, if_false);
                b.select(cond, d_true, d_false)
            }
        }
    }
}

/// A program whose outputs are the derivatives of `forward`'s outputs with respect to `wrt`,
/// named `d_{wrt}:{name}`, sharing `forward`'s nodes (for tests, tools and the CLI).
pub fn derivative_program(forward: &Program, wrt: Wrt) -> Program {
    let mut b = Builder::from_program(forward);
    let mut diff = ForwardDiff::new(wrt);
    let outputs = forward
        .outputs
        .iter()
        .map(|o| Output { name: format!("d_{wrt}:{}", o.name), node: diff.derivative(&mut b, o.node) })
        .collect();
    let mut program = b.finish(outputs);
    program.eliminate_dead_code();
    program
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interp::eval_point;

    #[test]
    fn inactive_subexpressions_emit_nothing() {
        let mut b = Builder::new();
        let (u, p) = (b.u(), b.param(0));
        let heavy = b.sin(p);
        let heavy = b.exp(heavy);
        let f = b.mul(heavy, u);
        let ops = |b: &Builder| (0..b.len()).filter(|&i| !b.op(NodeId(i as u32)).is_leaf()).count();
        let before = ops(&b);
        let d = derivative(&mut b, f, Wrt::U);
        assert_eq!(d, heavy, "d/du (g(p) u) is g(p) itself");
        assert_eq!(ops(&b), before, "no new op (only the constant 1 for du/du)");
    }

    #[test]
    fn memo_is_kept_across_calls_and_second_derivatives_work() {
        let mut b = Builder::new();
        let u = b.u();
        let three = b.constant(3.0);
        let cube = b.pow(u, three);
        let mut ddu = ForwardDiff::new(Wrt::U);
        let first = ddu.derivative(&mut b, cube);
        let len = b.len();
        assert_eq!(ddu.derivative(&mut b, cube), first);
        assert_eq!(b.len(), len, "a repeated call emits nothing");
        let second = ddu.derivative(&mut b, first);
        let prog = b.finish(vec![Output { name: "d2".into(), node: second }]);
        let got = eval_point(&prog, &[], 0.5, 0.0, &[])[0];
        assert!((got - 3.0).abs() < 1e-5, "d²/du² u³ at 0.5 = 6·0.5, got {got}");
    }
}
