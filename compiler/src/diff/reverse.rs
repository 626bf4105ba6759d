//! Reverse-mode differentiation: the adjoint program of a forward program.
//!
//! [`adjoint`] returns one fused program that computes the forward outputs and, from one
//! incoming gradient `Seed(k)` per forward output `k`, the gradient of the implied loss with
//! respect to u, v and the chosen parameters, at each texel. The adjoint code is emitted into a
//! builder seeded with the forward nodes, so it reuses forward values (and any derivative
//! factor the forward program already computes) instead of recomputing them.
//! The per-op rules are in the parent module.
//!
//! The program comes with its [`AdjointLayout`]: which output holds which gradient. Callers
//! read the layout, never the output names (those are for IR dumps only).

use super::{accumulate, extend_activity, local_rule, LocalRule};
use crate::ir::{Builder, NodeId, Op, Output, Program};

/// Where each value is among an adjoint program's inputs and outputs.
///
/// Seeds: `Seed(k)` is the incoming gradient of forward output `k`, for every forward output
/// (`num_seeds() == forward_outputs()`, used or not). Outputs, in order: the forward outputs
/// (same names and order as the forward program), `d_u` (output [`Self::d_u`]), `d_v`
/// ([`Self::d_v`]), then one `d_param` output per differentiated parameter slot, in the order
/// of [`Self::wrt`] ([`Self::d_param`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdjointLayout {
    forward_outputs: usize,
    wrt: Vec<u32>,
}

impl AdjointLayout {
    /// The layout of the adjoint of a program with `forward_outputs` outputs, differentiated
    /// with respect to the parameter slots `wrt` (in this order).
    pub fn new(forward_outputs: usize, wrt: Vec<u32>) -> Self {
        AdjointLayout { forward_outputs, wrt }
    }

    /// Forward outputs, which are also the first outputs of the adjoint.
    pub fn forward_outputs(&self) -> usize {
        self.forward_outputs
    }

    /// Seed inputs: one per forward output.
    pub fn num_seeds(&self) -> usize {
        self.forward_outputs
    }

    /// Output index of the per-point gradient with respect to u.
    pub fn d_u(&self) -> usize {
        self.forward_outputs
    }

    /// Output index of the per-point gradient with respect to v.
    pub fn d_v(&self) -> usize {
        self.forward_outputs + 1
    }

    /// The differentiated parameter slots, in the order of their outputs.
    pub fn wrt(&self) -> &[u32] {
        &self.wrt
    }

    /// Output index of the gradient with respect to `wrt()[k]`.
    pub fn d_param(&self, k: usize) -> usize {
        self.forward_outputs + 2 + k
    }

    /// Output index of the gradient with respect to parameter slot `slot`, if differentiated.
    pub fn d_param_of_slot(&self, slot: u32) -> Option<usize> {
        self.wrt.iter().position(|&s| s == slot).map(|k| self.d_param(k))
    }

    /// Total outputs of the adjoint program.
    pub fn num_outputs(&self) -> usize {
        self.forward_outputs + 2 + self.wrt.len()
    }

    /// Checks that `adjoint` has this layout for `forward`: seed and output counts, forward
    /// outputs first under the forward names, and distinct differentiated slots that `forward`
    /// has. Runtimes call this before trusting the layout with memory they index.
    pub fn check(&self, forward: &Program, adjoint: &Program) -> Result<(), String> {
        let nf = forward.outputs.len();
        if self.forward_outputs != nf {
            return Err(format!("layout for {} forward outputs, the forward program has {nf}", self.forward_outputs));
        }
        if adjoint.num_seeds != self.num_seeds() {
            return Err(format!("{} seeds for {nf} forward outputs", adjoint.num_seeds));
        }
        if adjoint.outputs.len() != self.num_outputs() {
            return Err(format!("{} outputs where the layout has {}", adjoint.outputs.len(), self.num_outputs()));
        }
        if adjoint.num_params != forward.num_params {
            return Err(format!(
                "{} parameter slots, the forward program has {}",
                adjoint.num_params, forward.num_params
            ));
        }
        for (f, a) in forward.outputs.iter().zip(&adjoint.outputs) {
            if f.name != a.name {
                return Err(format!("output `{}` where forward output `{}` was expected", a.name, f.name));
            }
        }
        for (k, &slot) in self.wrt.iter().enumerate() {
            if slot as usize >= forward.num_params {
                return Err(format!("differentiates slot {slot}; the program has {} slots", forward.num_params));
            }
            if self.wrt[..k].contains(&slot) {
                return Err(format!("differentiates slot {slot} twice"));
            }
        }
        Ok(())
    }
}

/// `9 seeds; outputs 0..9 forward, 9 d_u, 10 d_v, 11.. d_param of slots [0, 1, 2]`.
impl std::fmt::Display for AdjointLayout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} seeds; outputs 0..{} forward, {} d_u, {} d_v, {}.. d_param of slots {:?}",
            self.num_seeds(),
            self.forward_outputs,
            self.d_u(),
            self.d_v(),
            self.d_param(0),
            self.wrt
        )
    }
}

/// A fused forward + adjoint program and its layout.
#[derive(Clone, Debug, PartialEq)]
pub struct Adjoint {
    pub program: Program,
    pub layout: AdjointLayout,
}

/// The adjoint program of `forward` for the parameter slots `wrt_params`, with its layout.
///
/// Inputs: U, V, the same parameter slots as `forward`, and the seeds of [`AdjointLayout`].
/// Outputs: as [`AdjointLayout`] says; they are named after the forward outputs, then `d_u`,
/// `d_v` and `d_param{slot}` (for dumps). A gradient that is identically zero is the constant 0.
///
/// Only nodes that depend on u, v or a `wrt_params` slot (through ops with a non-zero
/// derivative) and that reach an output get adjoint code; dead code is removed at the end.
///
/// # Panics
/// If `forward` already reads seeds (an adjoint of an adjoint would need two seed families).
pub fn adjoint(forward: &Program, wrt_params: &[u32]) -> Adjoint {
    assert_eq!(forward.num_seeds, 0, "adjoint of a program that already reads seeds");
    let n = forward.nodes.len();
    let mut active = Vec::with_capacity(n);
    extend_activity(
        &mut active,
        n,
        |i| forward.nodes[i],
        |op| match *op {
            Op::U | Op::V => true,
            Op::Param(p) => wrt_params.contains(&p),
            _ => false,
        },
    );

    let mut b = Builder::from_program(forward);
    b.reserve_seeds(forward.outputs.len());
    // adjoints[i]: the running sum of dLoss/d(node i) for forward node i.
    let mut adjoints: Vec<Option<NodeId>> = vec![None; n];
    for (k, out) in forward.outputs.iter().enumerate() {
        if active[out.node.index()] {
            let seed = b.seed(k as u32);
            let slot = &mut adjoints[out.node.index()];
            *slot = Some(accumulate(&mut b, *slot, seed, false));
        }
    }

    // Reverse topological order: when node i is reached, every user of i (all have larger ids)
    // has already added its contribution, so adjoints[i] is complete.
    for i in (0..n).rev() {
        let Some(incoming) = adjoints[i] else { continue };
        let node = NodeId(i as u32);
        let rule = local_rule(&mut b, node, &|x| active[x.index()]);
        match rule {
            LocalRule::Linear(terms) => {
                for term in terms {
                    let contribution = term.factor.apply(&mut b, incoming);
                    let slot = &mut adjoints[term.operand.index()];
                    *slot = Some(accumulate(&mut b, *slot, contribution, term.negated));
                }
            }
            LocalRule::Route { cond, if_true, if_false } => {
                let zero = b.constant(0.0);
                if active[if_true.index()] {
                    let routed = b.select(cond, incoming, zero);
                    let slot = &mut adjoints[if_true.index()];
                    *slot = Some(accumulate(&mut b, *slot, routed, false));
                }
                if active[if_false.index()] {
                    let routed = b.select(cond, zero, incoming);
                    let slot = &mut adjoints[if_false.index()];
                    *slot = Some(accumulate(&mut b, *slot, routed, false));
                }
            }
        }
    }

    // A leaf occurs at most once in a hash-consed program, so its adjoint is the whole gradient.
    let gradient_of = |b: &mut Builder, leaf: Op| {
        forward.nodes.iter().position(|op| *op == leaf).and_then(|i| adjoints[i]).unwrap_or_else(|| b.constant(0.0))
    };
    let mut outputs = forward.outputs.clone();
    outputs.push(Output { name: "d_u".into(), node: gradient_of(&mut b, Op::U) });
    outputs.push(Output { name: "d_v".into(), node: gradient_of(&mut b, Op::V) });
    for &slot in wrt_params {
        outputs.push(Output { name: format!("d_param{slot}"), node: gradient_of(&mut b, Op::Param(slot)) });
    }
    let mut program = b.finish(outputs);
    program.eliminate_dead_code();
    Adjoint { program, layout: AdjointLayout::new(forward.outputs.len(), wrt_params.to_vec()) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interp::eval_point;

    #[test]
    fn gradient_of_a_product_and_unused_inputs() {
        let mut b = Builder::new();
        let (u, p0) = (b.u(), b.param(0));
        let f = b.mul(u, p0);
        let forward = b.finish(vec![Output { name: "f".into(), node: f }]);
        let adj = adjoint(&forward, &[0]);
        adj.program.validate().unwrap();
        adj.layout.check(&forward, &adj.program).unwrap();
        let names: Vec<_> = adj.program.outputs.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, ["f", "d_u", "d_v", "d_param0"]);
        let (l, got) = (&adj.layout, eval_point(&adj.program, &[3.0], 2.0, 5.0, &[10.0]));
        assert_eq!([got[0], got[l.d_u()], got[l.d_v()], got[l.d_param(0)]], [6.0, 30.0, 0.0, 20.0]);
        assert_eq!(l.d_param_of_slot(0), Some(3));
        assert_eq!(l.d_param_of_slot(1), None);
    }

    #[test]
    fn the_layout_check_rejects_mismatches() {
        let mut b = Builder::new();
        let (u, p0, p1) = (b.u(), b.param(0), b.param(1));
        let f = b.mul(u, p0);
        let g = b.add(f, p1);
        let forward = b.finish(vec![Output { name: "f".into(), node: f }, Output { name: "g".into(), node: g }]);
        let adj = adjoint(&forward, &[1, 0]);
        adj.layout.check(&forward, &adj.program).unwrap();
        let bad = |layout: AdjointLayout| layout.check(&forward, &adj.program).unwrap_err();
        assert!(bad(AdjointLayout::new(1, vec![1, 0])).contains("forward outputs"));
        assert!(bad(AdjointLayout::new(2, vec![1])).contains("outputs where the layout has"));
        assert!(bad(AdjointLayout::new(2, vec![1, 1])).contains("twice"));
        assert!(bad(AdjointLayout::new(2, vec![1, 7])).contains("slot 7"));
        let mut renamed = adj.program.clone();
        renamed.outputs[0].name = "h".into();
        assert!(adj.layout.check(&forward, &renamed).unwrap_err().contains("`h`"));
    }
}
