//! Reverse-mode differentiation: the adjoint program of a forward program.
//!
//! [`adjoint`] returns one fused program that computes the forward outputs and, from one
//! incoming gradient `Seed(k)` per forward output `k`, the gradient of the implied loss with
//! respect to u, v and the chosen parameters, at each texel. The adjoint code is emitted into a
//! builder seeded with the forward nodes, so it reuses forward values (and any derivative
//! factor the forward program already computes) instead of recomputing them.
//! The per-op rules are in the parent module.

use super::{accumulate, extend_activity, local_rule, LocalRule};
use crate::ir::{Builder, NodeId, Op, Output, Program};

/// The adjoint program of `forward` for the parameter slots `wrt_params`.
///
/// Inputs: U, V, the same parameter slots as `forward`, and `Seed(k)` for each forward output
/// `k` (`num_seeds` is the number of forward outputs even when some seed is unused).
/// Outputs, in order: the forward outputs (same names), `d_u`, `d_v`, then `d_param{slot}` for
/// each slot of `wrt_params`. A gradient that is identically zero is the constant 0.
///
/// Only nodes that depend on u, v or a `wrt_params` slot (through ops with a non-zero
/// derivative) and that reach an output get adjoint code; dead code is removed at the end.
///
/// # Panics
/// If `forward` already reads seeds (an adjoint of an adjoint would need two seed families).
pub fn adjoint(forward: &Program, wrt_params: &[u32]) -> Program {
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
    program
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
        adj.validate().unwrap();
        let names: Vec<_> = adj.outputs.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, ["f", "d_u", "d_v", "d_param0"]);
        let got = eval_point(&adj, &[3.0], 2.0, 5.0, &[10.0]);
        assert_eq!(got, vec![6.0, 30.0, 0.0, 20.0]);
    }
}
