//! Cranelift code generation: one function per program, structure-of-arrays, `F32X4` lanes.
//!
//! Generated signature (see [`crate::abi`]):
//! `extern "C" fn(params: *const f32, inputs: *const *const f32, outputs: *const *mut f32, n: usize)`
//! with `inputs = [u, v, seed0, seed1, …]` and one output column per program output.
//!
//! Shape of the function:
//! - main loop: `groups` independent 4-lane vectors per iteration (4·groups points), the
//!   program emitted node by node with the groups interleaved, so each node's `groups`
//!   instances are independent chains the CPU can overlap;
//! - tail loop: one vector per iteration whose lanes read point `min(i + j, n - 1)` and are
//!   stored in reverse lane order, so padding lanes (which all repeat point `n - 1`) are
//!   overwritten by the real lane last. Branch-free, in bounds for every `n ≥ 1`, and `n = 0`
//!   never enters it.
//!
//! The generated code makes no calls (no libm, no libcalls: transcendentals are inline
//! polynomials, rounding uses SSE4.1/NEON instructions, FMA is only used when native).

use std::collections::HashMap;

use cranelift_codegen::ir::{condcodes::FloatCC, condcodes::IntCC, types, AbiParam, InstBuilder, MemFlagsData, Value};
use cranelift_codegen::ir::{ConstantData, Type};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, FuncId, Module};
use psc_compiler::ir::{Op, Program};

use crate::arith::{Arith, Cmp};
use crate::ops::{eval_op, live_nodes};
use crate::{JitError, OptLevel, Options};

/// A defined (not yet finalized) module holding the kernel function.
pub(crate) struct Built {
    pub module: JITModule,
    pub func: FuncId,
    pub fused: bool,
}

pub(crate) fn build(program: &Program, opts: &Options) -> Result<Built, JitError> {
    let cg = |e: &dyn std::fmt::Display| JitError::Codegen(e.to_string());
    let mut flags = settings::builder();
    let level = match opts.opt_level {
        OptLevel::None => "none",
        OptLevel::Speed => "speed",
    };
    flags.set("opt_level", level).map_err(|e| cg(&e))?;
    flags.set("is_pic", "false").map_err(|e| cg(&e))?;
    flags.set("use_colocated_libcalls", "false").map_err(|e| cg(&e))?;
    // The IR is verified by construction; cranelift's verifier roughly doubles compile time.
    flags.set("enable_verifier", if cfg!(debug_assertions) { "true" } else { "false" }).map_err(|e| cg(&e))?;
    let isa = cranelift_native::builder()
        .map_err(|e| JitError::UnsupportedHost(e.to_string()))?
        .finish(settings::Flags::new(flags))
        .map_err(|e| cg(&e))?;
    if !isa.has_round() {
        // Without native rounding, floor/nearest would become libcalls.
        return Err(JitError::UnsupportedHost("no native vector rounding (x86-64 needs SSE4.1)".into()));
    }
    let fused = isa.has_native_fma();
    let ptr = isa.pointer_type();
    let mut module = JITModule::new(JITBuilder::with_isa(isa, default_libcall_names()));
    let mut ctx = module.make_context();
    let mut sig = module.make_signature();
    for _ in 0..4 {
        sig.params.push(AbiParam::new(ptr));
    }
    let func = module.declare_anonymous_function(&sig).map_err(|e| cg(&e))?;
    ctx.func.signature = sig;
    let mut fctx = FunctionBuilderContext::new();
    {
        let mut b = FunctionBuilder::new(&mut ctx.func, &mut fctx);
        let mut lanes = Lanes { b: &mut b, fused, consts: HashMap::new() };
        define(&mut lanes, program, opts.groups.clamp(1, 4), ptr);
        b.seal_all_blocks();
        b.finalize(module.target_config());
    }
    module.define_function(func, &mut ctx).map_err(|e| cg(&e))?;
    module.clear_context(&mut ctx);
    Ok(Built { module, func, fused })
}

/// How leaves read their per-point column in the current loop.
enum Access {
    /// Vector loads at `base + 16·group`; `base` is the byte offset of point `i`.
    Direct { base: Value },
    /// One vector whose lane `j` reads byte offset `offs[j]` (clamped indices).
    Gather { offs: [Value; 4] },
}

fn mem() -> MemFlagsData {
    // The safe wrapper guarantees every column holds `n` floats: accesses cannot trap.
    MemFlagsData::new().with_notrap()
}

fn define(a: &mut Lanes, program: &Program, groups: usize, ptr: Type) {
    let b = &mut *a.b;
    let entry = b.create_block();
    b.append_block_params_for_function_params(entry);
    b.switch_to_block(entry);
    let (params, inputs, outputs, n) = {
        let p = b.block_params(entry);
        (p[0], p[1], p[2], p[3])
    };
    let ptr_bytes = ptr.bytes() as i32;
    let in_cols: Vec<Value> =
        (0..2 + program.num_seeds).map(|k| b.ins().load(ptr, mem(), inputs, ptr_bytes * k as i32)).collect();
    let out_cols: Vec<Value> =
        (0..program.outputs.len()).map(|k| b.ins().load(ptr, mem(), outputs, ptr_bytes * k as i32)).collect();
    let header = b.create_block();
    let body = b.create_block();
    let tail_header = b.create_block();
    let tail_body = b.create_block();
    let exit = b.create_block();
    let i_main = b.append_block_param(header, ptr);
    let i_tail = b.append_block_param(tail_header, ptr);
    let zero = b.ins().iconst(ptr, 0);
    b.ins().jump(header, &[zero.into()]);

    // Main loop header: run the body while a whole block of 4·groups points remains.
    b.switch_to_block(header);
    let step = b.ins().iconst(ptr, 4 * groups as i64);
    let end = b.ins().iadd(i_main, step);
    let fits = b.ins().icmp(IntCC::UnsignedLessThanOrEqual, end, n);
    b.ins().brif(fits, body, &[], tail_header, &[i_main.into()]);

    b.switch_to_block(body);
    let two = b.ins().iconst(ptr, 2);
    let base = b.ins().ishl(i_main, two);
    emit_program(a, program, params, &in_cols, &out_cols, &Access::Direct { base }, groups);
    a.b.ins().jump(header, &[end.into()]);

    // Tail: one clamped vector per iteration until every point is written.
    let b = &mut *a.b;
    b.switch_to_block(tail_header);
    let more = b.ins().icmp(IntCC::UnsignedLessThan, i_tail, n);
    b.ins().brif(more, tail_body, &[], exit, &[]);

    b.switch_to_block(tail_body);
    let one = b.ins().iconst(ptr, 1);
    let last = b.ins().isub(n, one);
    let two = b.ins().iconst(ptr, 2);
    let offs: [Value; 4] = std::array::from_fn(|j| {
        let jj = b.ins().iconst(ptr, j as i64);
        let idx = b.ins().iadd(i_tail, jj);
        let idx = b.ins().umin(idx, last);
        b.ins().ishl(idx, two)
    });
    emit_program(a, program, params, &in_cols, &out_cols, &Access::Gather { offs }, 1);
    let b = &mut *a.b;
    let four = b.ins().iconst(ptr, 4);
    let next = b.ins().iadd(i_tail, four);
    b.ins().jump(tail_header, &[next.into()]);

    b.switch_to_block(exit);
    b.ins().return_(&[]);
}

/// Emits every live node for `groups` vectors, storing outputs as soon as they are computed.
fn emit_program(
    a: &mut Lanes,
    program: &Program,
    params: Value,
    in_cols: &[Value],
    out_cols: &[Value],
    access: &Access,
    groups: usize,
) {
    let live = live_nodes(program);
    let mut outputs_of: HashMap<usize, Vec<usize>> = HashMap::new();
    for (k, out) in program.outputs.iter().enumerate() {
        outputs_of.entry(out.node.index()).or_default().push(k);
    }
    // Fresh per block: cached constants must be defined in a block dominating their uses.
    a.consts.clear();
    let mut vals: Vec<Vec<Value>> = vec![Vec::new(); program.nodes.len()];
    for (i, op) in program.nodes.iter().enumerate() {
        if !live[i] {
            continue;
        }
        vals[i] = match *op {
            Op::Const(bits) => vec![a.f(f32::from_bits(bits)); groups],
            Op::Param(p) => {
                let s = a.b.ins().load(types::F32, mem(), params, 4 * p as i32);
                vec![a.b.ins().splat(types::F32X4, s); groups]
            }
            Op::U => load_column(a, in_cols[0], access, groups),
            Op::V => load_column(a, in_cols[1], access, groups),
            Op::Seed(s) => load_column(a, in_cols[2 + s as usize], access, groups),
            _ => (0..groups)
                .map(|g| {
                    let mut it = op.operands().map(|id| vals[id.index()][g]);
                    let x = it.next().expect("non-leaf has an operand");
                    let y = it.next().unwrap_or(x);
                    let z = it.next().unwrap_or(x);
                    eval_op(a, op, x, y, z)
                })
                .collect(),
        };
        if let Some(ks) = outputs_of.get(&i) {
            for &k in ks {
                for (g, &value) in vals[i].iter().enumerate() {
                    store_column(a, out_cols[k], access, g, value);
                }
            }
        }
    }
}

fn load_column(a: &mut Lanes, col: Value, access: &Access, groups: usize) -> Vec<Value> {
    let b = &mut *a.b;
    match access {
        Access::Direct { base } => {
            let addr = b.ins().iadd(col, *base);
            (0..groups).map(|g| b.ins().load(types::F32X4, mem(), addr, 16 * g as i32)).collect()
        }
        Access::Gather { offs } => {
            let lane = |b: &mut FunctionBuilder, j: usize| {
                let addr = b.ins().iadd(col, offs[j]);
                b.ins().load(types::F32, mem(), addr, 0)
            };
            let l0 = lane(b, 0);
            let mut v = b.ins().scalar_to_vector(types::F32X4, l0);
            for j in 1..4 {
                let l = lane(b, j);
                v = b.ins().insertlane(v, l, j as u8);
            }
            vec![v]
        }
    }
}

fn store_column(a: &mut Lanes, col: Value, access: &Access, g: usize, v: Value) {
    let b = &mut *a.b;
    match access {
        Access::Direct { base } => {
            let addr = b.ins().iadd(col, *base);
            b.ins().store(mem(), v, addr, 16 * g as i32);
        }
        Access::Gather { offs } => {
            // Reverse order: padding lanes alias point n-1, whose real lane is stored last.
            for j in (0..4).rev() {
                let e = b.ins().extractlane(v, j as u8);
                let addr = b.ins().iadd(col, offs[j]);
                b.ins().store(mem(), e, addr, 0);
            }
        }
    }
}

/// [`Arith`] over cranelift `F32X4` / `I32X4` values.
struct Lanes<'a, 'f> {
    b: &'a mut FunctionBuilder<'f>,
    fused: bool,
    /// Splat constants already materialised in the current block, by type and bits.
    consts: HashMap<(bool, u32), Value>,
}

impl Lanes<'_, '_> {
    fn vconst(&mut self, float: bool, bits: u32) -> Value {
        if let Some(&v) = self.consts.get(&(float, bits)) {
            return v;
        }
        let bytes: Vec<u8> = bits.to_le_bytes().repeat(4);
        let handle = self.b.func.dfg.constants.insert(ConstantData::from(bytes));
        let ty = if float { types::F32X4 } else { types::I32X4 };
        let v = self.b.ins().vconst(ty, handle);
        self.consts.insert((float, bits), v);
        v
    }
}

impl Arith for Lanes<'_, '_> {
    type F = Value;
    type I = Value;
    type M = Value;

    fn f(&mut self, x: f32) -> Value {
        self.vconst(true, x.to_bits())
    }
    fn i(&mut self, x: i32) -> Value {
        self.vconst(false, x as u32)
    }
    fn add(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().fadd(a, b)
    }
    fn sub(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().fsub(a, b)
    }
    fn mul(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().fmul(a, b)
    }
    fn div(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().fdiv(a, b)
    }
    fn fma(&mut self, a: Value, b: Value, c: Value) -> Value {
        if self.fused {
            self.b.ins().fma(a, b, c)
        } else {
            let p = self.b.ins().fmul(a, b);
            self.b.ins().fadd(p, c)
        }
    }
    fn neg(&mut self, a: Value) -> Value {
        self.b.ins().fneg(a)
    }
    fn abs(&mut self, a: Value) -> Value {
        self.b.ins().fabs(a)
    }
    fn sqrt(&mut self, a: Value) -> Value {
        self.b.ins().sqrt(a)
    }
    fn floor(&mut self, a: Value) -> Value {
        self.b.ins().floor(a)
    }
    fn nearest(&mut self, a: Value) -> Value {
        self.b.ins().nearest(a)
    }
    fn cmp(&mut self, cc: Cmp, a: Value, b: Value) -> Value {
        let cc = match cc {
            Cmp::Lt => FloatCC::LessThan,
            Cmp::Le => FloatCC::LessThanOrEqual,
            Cmp::Eq => FloatCC::Equal,
            Cmp::Une => FloatCC::NotEqual,
            Cmp::Uno => FloatCC::Unordered,
        };
        self.b.ins().fcmp(cc, a, b)
    }
    fn sel(&mut self, m: Value, a: Value, b: Value) -> Value {
        // bitcast(fcmp) directly under bitselect: the pattern cranelift lowers to minps/maxps
        // for Min/Max, and a plain and/andn/or blend otherwise.
        let mf = self.b.ins().bitcast(types::F32X4, MemFlagsData::new(), m);
        self.b.ins().bitselect(mf, a, b)
    }
    fn mand(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().band(a, b)
    }
    fn to_int(&mut self, x: Value) -> Value {
        self.b.ins().fcvt_to_sint_sat(types::I32X4, x)
    }
    fn to_float(&mut self, x: Value) -> Value {
        self.b.ins().fcvt_from_sint(types::F32X4, x)
    }
    fn float_to_bits(&mut self, x: Value) -> Value {
        self.b.ins().bitcast(types::I32X4, MemFlagsData::new(), x)
    }
    fn bits_to_float(&mut self, x: Value) -> Value {
        self.b.ins().bitcast(types::F32X4, MemFlagsData::new(), x)
    }
    fn iadd(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().iadd(a, b)
    }
    fn isub(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().isub(a, b)
    }
    fn imul(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().imul(a, b)
    }
    fn iand(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().band(a, b)
    }
    fn ixor(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().bxor(a, b)
    }
    fn shl(&mut self, a: Value, s: u8) -> Value {
        let amt = self.b.ins().iconst(types::I32, i64::from(s));
        self.b.ins().ishl(a, amt)
    }
    fn ushr(&mut self, a: Value, s: u8) -> Value {
        let amt = self.b.ins().iconst(types::I32, i64::from(s));
        self.b.ins().ushr(a, amt)
    }
    fn sshr(&mut self, a: Value, s: u8) -> Value {
        let amt = self.b.ins().iconst(types::I32, i64::from(s));
        self.b.ins().sshr(a, amt)
    }
    fn ieq(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().icmp(IntCC::Equal, a, b)
    }
}
