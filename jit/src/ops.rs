//! Every IR op as the JIT computes it, once, generic over [`Arith`]; plus the scalar mirror
//! interpreter built on it.
//!
//! Non-transcendental ops are bit-exact with `psc_compiler::ir::semantics` (tested). The
//! comparison-based ops use `fcmp` + select exactly as semantics.rs spells them (`a < b ? a :
//! b`), never `fmin`/`fmax`, whose NaN and signed-zero behaviour differs.

use psc_compiler::ir::{Op, Program};

use crate::approx;
use crate::arith::{Arith, Cmp, FlopCounter, Scalar};

/// Evaluates non-leaf `op` on operand values `x`, `y`, `z` (unused ones are ignored).
/// Leaves are the caller's business; passing one is a logic error and yields `x`.
pub fn eval_op<A: Arith>(a: &mut A, op: &Op, x: A::F, y: A::F, z: A::F) -> A::F {
    match *op {
        Op::Const(_) | Op::U | Op::V | Op::Param(_) | Op::Seed(_) => x,
        Op::Neg(_) => a.neg(x),
        Op::Abs(_) => a.abs(x),
        Op::Floor(_) => a.floor(x),
        Op::Sqrt(_) => {
            // sqrt(max(x, 0)); NaN → 0 like `f32::max`.
            let zero = a.f(0.0);
            let pos = a.cmp(Cmp::Lt, zero, x);
            let x = a.sel(pos, x, zero);
            a.sqrt(x)
        }
        Op::Sin(_) => approx::sin(a, x),
        Op::Cos(_) => approx::cos(a, x),
        Op::Exp(_) => approx::exp(a, x),
        Op::Log(_) => approx::log(a, x),
        Op::Add(..) => a.add(x, y),
        Op::Sub(..) => a.sub(x, y),
        Op::Mul(..) => a.mul(x, y),
        Op::Div(..) => a.div(x, y),
        Op::Min(..) => {
            let m = a.cmp(Cmp::Lt, x, y);
            a.sel(m, x, y)
        }
        Op::Max(..) => {
            // a > b spelled b < a: the same predicate, and the form cranelift lowers to maxps.
            let m = a.cmp(Cmp::Lt, y, x);
            a.sel(m, x, y)
        }
        Op::Pow(..) => approx::pow(a, x, y),
        Op::Atan2(..) => approx::atan2(a, x, y),
        Op::Hash(..) => hash(a, x, y),
        Op::Lt(..) => boolean(a, Cmp::Lt, x, y),
        Op::Le(..) => boolean(a, Cmp::Le, x, y),
        Op::Eq(..) => boolean(a, Cmp::Eq, x, y),
        Op::Select(..) => {
            let zero = a.f(0.0);
            let c = a.cmp(Cmp::Une, x, zero);
            a.sel(c, y, z)
        }
    }
}

fn boolean<A: Arith>(a: &mut A, cc: Cmp, x: A::F, y: A::F) -> A::F {
    let m = a.cmp(cc, x, y);
    let (one, zero) = (a.f(1.0), a.f(0.0));
    a.sel(m, one, zero)
}

/// `semantics::hash` on integer lanes.
fn hash<A: Arith>(a: &mut A, x: A::F, y: A::F) -> A::F {
    let ia = a.to_int(x);
    let ib = a.to_int(y);
    let k1 = a.i(0x9E37_79B1_u32 as i32);
    let k2 = a.i(0x85EB_CA77_u32 as i32);
    let ha = a.imul(ia, k1);
    let hb = a.imul(ib, k2);
    let mut h = a.ixor(ha, hb);
    for (shift, mul) in [(15, Some(0x2C1B_3C6D_u32)), (12, Some(0x297A_2D39)), (15, None)] {
        let s = a.ushr(h, shift);
        h = a.ixor(h, s);
        if let Some(m) = mul {
            let m = a.i(m as i32);
            h = a.imul(h, m);
        }
    }
    let top = a.ushr(h, 8);
    let f = a.to_float(top); // < 2^24: exact
    let scale = a.f(1.0 / 16_777_216.0);
    a.mul(f, scale)
}

/// Nodes some output depends on; the kernel computes only these.
pub fn live_nodes(program: &Program) -> Vec<bool> {
    let mut live = vec![false; program.nodes.len()];
    for out in &program.outputs {
        live[out.node.index()] = true;
    }
    for i in (0..program.nodes.len()).rev() {
        if live[i] {
            for operand in program.nodes[i].operands() {
                live[operand.index()] = true;
            }
        }
    }
    live
}

/// Floating-point operations per point of the generated kernel (FMA = 2), for GFLOP/s.
pub fn flops_per_point(program: &Program) -> usize {
    let mut counter = FlopCounter::default();
    let live = live_nodes(program);
    // Mirrors codegen: `sin x` and `cos x` of one `x` share everything but the final selection.
    let mut trig_operands = std::collections::HashSet::new();
    for (op, _) in program.nodes.iter().zip(&live).filter(|(op, l)| **l && !op.is_leaf()) {
        match *op {
            Op::Sin(x) | Op::Cos(x) => {
                let mut already_counted = FlopCounter::default();
                let shared = if trig_operands.insert(x) { &mut counter } else { &mut already_counted };
                let parts = approx::sin_cos_parts(shared, ());
                approx::finish_sin_cos(&mut counter, parts, 0);
            }
            _ => eval_op(&mut counter, op, (), (), ()),
        }
    }
    counter.flops
}

/// The scalar mirror of a compiled kernel: evaluates `program` at one point exactly as the
/// generated code does (bit for bit when `fused` matches [`crate::CompiledKernel::uses_fma`]).
///
/// # Panics
/// If `params` or `seeds` are shorter than the program needs (a test helper, not an API for
/// untrusted input).
pub fn mirror_eval_point(program: &Program, fused: bool, params: &[f32], u: f32, v: f32, seeds: &[f32]) -> Vec<f32> {
    let mut a = Scalar { fused };
    let mut values = vec![0.0f32; program.nodes.len()];
    for (i, op) in program.nodes.iter().enumerate() {
        values[i] = match *op {
            Op::Const(bits) => f32::from_bits(bits),
            Op::U => u,
            Op::V => v,
            Op::Param(p) => params[p as usize],
            Op::Seed(s) => seeds[s as usize],
            _ => {
                let mut it = op.operands().map(|id| values[id.index()]);
                let (x, y, z) = (it.next().unwrap_or(0.0), it.next().unwrap_or(0.0), it.next().unwrap_or(0.0));
                eval_op(&mut a, op, x, y, z)
            }
        };
    }
    program.outputs.iter().map(|o| values[o.node.index()]).collect()
}
