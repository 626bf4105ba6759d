//! Lowering of the intrinsic functions, and resampling by substitution of positions.

use std::collections::HashMap;

use crate::builtins::Builtin;
use crate::diff::forward::ForwardDiff;
use crate::ir::{Builder, NodeId, Op};

use super::Value;

/// Componentwise application with scalar broadcast.
pub(super) fn zip_with(b: &mut Builder, args: &[Value], f: impl Fn(&mut Builder, &[NodeId]) -> NodeId) -> Value {
    let width = args.iter().map(|a| a.comps().len()).max().unwrap_or(1);
    let comps = (0..width)
        .map(|k| {
            let xs: Vec<NodeId> = args.iter().map(|a| a.comp(k)).collect();
            f(b, &xs)
        })
        .collect();
    Value::Num(comps)
}

pub(super) fn dot(b: &mut Builder, x: &Value, y: &Value) -> NodeId {
    let width = x.comps().len().max(y.comps().len());
    let mut acc = b.constant(0.0);
    for k in 0..width {
        let p = b.mul(x.comp(k), y.comp(k));
        acc = b.add(acc, p);
    }
    acc
}

pub(super) fn normalize(b: &mut Builder, x: &Value) -> Value {
    let d = dot(b, x, x);
    let len = b.sqrt(d);
    let tiny = b.constant(1e-20);
    let safe = b.max(len, tiny);
    let inv = {
        let one = b.constant(1.0);
        b.div(one, safe)
    };
    zip_with(b, &[x.clone(), Value::scalar(inv)], |b, c| b.mul(c[0], c[1]))
}

/// sRGB transfer function to linear, per component.
fn srgb_to_linear(b: &mut Builder, c: NodeId) -> NodeId {
    let knee = b.constant(0.04045);
    let low = b.scale(1.0 / 12.92, c);
    let shifted = {
        let k = b.constant(0.055);
        let s = b.add(c, k);
        b.scale(1.0 / 1.055, s)
    };
    let gamma = b.constant(2.4);
    let high = b.pow(shifted, gamma);
    let is_low = b.le(c, knee);
    b.select(is_low, low, high)
}

/// Lowers a call to a built-in other than `sample`, `ddu`, `ddv` (which need the lowerer).
pub(super) fn lower_builtin(b: &mut Builder, which: Builtin, args: &[Value]) -> Value {
    use Builtin::*;
    let unary = |b: &mut Builder, f: fn(&mut Builder, NodeId) -> NodeId| zip_with(b, &args[..1], |b, c| f(b, c[0]));
    match which {
        Abs => unary(b, Builder::abs),
        Floor => unary(b, Builder::floor),
        Ceil => zip_with(b, args, |b, c| {
            let n = b.neg(c[0]);
            let f = b.floor(n);
            b.neg(f)
        }),
        Fract => unary(b, Builder::fract),
        Sign => zip_with(b, args, |b, c| {
            let zero = b.constant(0.0);
            let one = b.constant(1.0);
            let minus = b.constant(-1.0);
            let pos = b.lt(zero, c[0]);
            let neg = b.lt(c[0], zero);
            let inner = b.select(neg, minus, zero);
            b.select(pos, one, inner)
        }),
        Sqrt => unary(b, Builder::sqrt),
        Sin => unary(b, Builder::sin),
        Cos => unary(b, Builder::cos),
        Exp => unary(b, Builder::exp),
        Log => unary(b, Builder::log),
        Pow => zip_with(b, args, |b, c| b.pow(c[0], c[1])),
        Min => zip_with(b, args, |b, c| b.min(c[0], c[1])),
        Max => zip_with(b, args, |b, c| b.max(c[0], c[1])),
        Atan2 => zip_with(b, args, |b, c| b.atan2(c[0], c[1])),
        Step => zip_with(b, args, |b, c| b.le(c[0], c[1])),
        Clamp => zip_with(b, args, |b, c| {
            let lo = b.max(c[0], c[1]);
            b.min(lo, c[2])
        }),
        Mix => zip_with(b, args, |b, c| {
            let d = b.sub(c[1], c[0]);
            let s = b.mul(d, c[2]);
            b.add(c[0], s)
        }),
        Smoothstep => zip_with(b, args, |b, c| {
            let num = b.sub(c[2], c[0]);
            let den = b.sub(c[1], c[0]);
            let t = b.div(num, den);
            let zero = b.constant(0.0);
            let one = b.constant(1.0);
            let t = b.max(t, zero);
            let t = b.min(t, one);
            let three = b.constant(3.0);
            let two_t = b.scale(2.0, t);
            let k = b.sub(three, two_t);
            let tt = b.mul(t, t);
            b.mul(tt, k)
        }),
        Length => {
            let d = dot(b, &args[0], &args[0]);
            Value::scalar(b.sqrt(d))
        }
        Dot => Value::scalar(dot(b, &args[0], &args[1])),
        Distance => {
            let diff = zip_with(b, args, |b, c| b.sub(c[0], c[1]));
            let d = dot(b, &diff, &diff);
            Value::scalar(b.sqrt(d))
        }
        Normalize => normalize(b, &args[0]),
        Cross => {
            let (x, y) = (&args[0], &args[1]);
            let comp = |b: &mut Builder, i: usize, j: usize| {
                let p = b.mul(x.comp(i), y.comp(j));
                let q = b.mul(x.comp(j), y.comp(i));
                b.sub(p, q)
            };
            Value::Num(vec![comp(b, 1, 2), comp(b, 2, 0), comp(b, 0, 1)])
        }
        Select => {
            let c = args[0].comp(0);
            zip_with(b, &args[1..], |b, v| b.select(c, v[0], v[1]))
        }
        Float | Rgb => {
            if which == Rgb {
                Value::Num(args.iter().map(|a| a.comp(0)).collect())
            } else {
                args[0].clone()
            }
        }
        Hash => Value::scalar(b.hash(args[0].comp(0), args[1].comp(0))),
        Vec2 | Vec3 => {
            let want = if which == Vec2 { 2 } else { 3 };
            let mut comps: Vec<NodeId> = args.iter().flat_map(|a| a.comps().to_vec()).collect();
            if comps.len() == 1 {
                comps = vec![comps[0]; want];
            }
            Value::Num(comps)
        }
        Srgb => Value::Num(args.iter().map(|a| srgb_to_linear(b, a.comp(0))).collect()),
        Sample | Ddu | Ddv => unreachable!("handled by the lowerer"),
    }
}

/// `∂value/∂u` or `∂value/∂v` (whichever `diff` differentiates), componentwise. One
/// differentiator per variable lives as long as the graph's builder, so derivatives of shared
/// subexpressions are emitted once for the whole graph.
pub(super) fn partial(b: &mut Builder, diff: &mut ForwardDiff, value: &Value) -> Value {
    value.map_nodes(&mut |id| diff.derivative(b, id))
}

/// The value `roots` would have if `uv` were `(u, v)`: every node depending on `U`/`V` is
/// rebuilt with the new position substituted (hash-consing shares what does not change).
pub(super) fn substitute(b: &mut Builder, value: &Value, u: NodeId, v: NodeId) -> Value {
    let mut roots = Vec::new();
    value.for_each_node(&mut |id| roots.push(id));
    // The cone of the roots, in ascending (topological) order.
    let mut seen: HashMap<NodeId, NodeId> = HashMap::new();
    let mut cone = Vec::new();
    let mut stack = roots.clone();
    let mut visited = std::collections::HashSet::new();
    while let Some(id) = stack.pop() {
        if !visited.insert(id) {
            continue;
        }
        cone.push(id);
        stack.extend(b.op(id).operands());
    }
    cone.sort_unstable();
    for id in cone {
        let op = b.op(id);
        let new = match op {
            Op::U => u,
            Op::V => v,
            _ if op.is_leaf() => id,
            _ => {
                let rebuilt = op.map_operands(|a| seen[&a]);
                if rebuilt == op {
                    id
                } else {
                    b.push(rebuilt)
                }
            }
        };
        seen.insert(id, new);
    }
    value.map_nodes(&mut |id| seen[&id])
}
