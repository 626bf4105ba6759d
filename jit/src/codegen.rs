//! Cranelift code generation: one function per program, structure-of-arrays, `F32X4` lanes.
//!
//! Generated signature (see [`crate::abi`]):
//! `extern "C" fn(params: *const [f32; 4], constants: *const [f32; 4], inputs: *const *const f32,
//! outputs: *const *mut f32, n: usize)`: parameters and constants splatted to 16-byte aligned
//! lanes, `inputs = [u, v, seed0, seed1, …]` and one output column per program output.
//!
//! Shape of the function:
//! - main loop: `groups` independent 4-lane vectors per iteration (4·groups points), the
//!   program emitted node by node with the groups interleaved, so each node's `groups`
//!   instances are independent chains the CPU can overlap;
//! - no tail loop: `n` must be a multiple of 4·groups ([`crate::abi`] runs the last partial
//!   block on padded copies). Emitting the program once instead of twice halves compile time;
//! - leaves (constants, parameters, column loads) are re-emitted at each use, so the only
//!   long-lived values are the ones the program itself keeps.
//!
//! The generated code makes no calls (no libm, no libcalls: transcendentals are inline
//! polynomials, rounding uses SSE4.1/NEON instructions, FMA is only used when native).

use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use cranelift_codegen::entity::packed_option::ReservedValue;
use cranelift_codegen::ir::{condcodes::FloatCC, condcodes::IntCC, types, AbiParam, InstBuilder, MemFlagsData, Value};
use cranelift_codegen::ir::{Block, Type};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, FuncId, Module};
use psc_compiler::ir::{Op, Program};

use crate::approx;
use crate::arith::{Arith, Cmp};
use crate::ops::{eval_op, live_nodes};
use crate::schedule;
use crate::{JitError, OptLevel, Options};

/// A defined (not yet finalized) module holding the kernel function.
pub(crate) struct Built {
    pub module: JITModule,
    pub func: FuncId,
    pub fused: bool,
    /// Vectors per loop iteration.
    pub groups: usize,
    /// The constant table the kernel reads (its second argument), as lane bit patterns.
    pub constants: Vec<u32>,
}

pub(crate) fn build(program: &Program, opts: &Options) -> Result<Built, JitError> {
    let cg = |e: &dyn std::fmt::Display| JitError::Codegen(e.to_string());
    let mut flags = settings::builder();
    let level = match opts.opt_level {
        OptLevel::None => "none",
        OptLevel::Speed => "speed",
    };
    flags.set("opt_level", level).map_err(|e| cg(&e))?;
    let regalloc = if program.nodes.len() > opts.single_pass_above { "single_pass" } else { "backtracking" };
    flags.set("regalloc_algorithm", regalloc).map_err(|e| cg(&e))?;
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
    // cranelift-native always targets the host.
    let x86 = cfg!(target_arch = "x86_64");
    let ptr = isa.pointer_type();
    let mut module = JITModule::new(JITBuilder::with_isa(isa, default_libcall_names()));
    let mut ctx = module.make_context();
    let mut sig = module.make_signature();
    for _ in 0..5 {
        sig.params.push(AbiParam::new(ptr));
    }
    let func = module.declare_anonymous_function(&sig).map_err(|e| cg(&e))?;
    ctx.func.signature = sig;
    let groups = opts.groups.clamp(1, 4);
    let constants;
    let body;
    let mut fctx = FunctionBuilderContext::new();
    {
        let mut b = FunctionBuilder::new(&mut ctx.func, &mut fctx);
        let mut lanes =
            Lanes { b: &mut b, fused, x86, table: Value::reserved_value(), constants: ConstTable::default() };
        body = define(&mut lanes, program, groups, ptr);
        constants = lanes.constants.bits;
        b.seal_all_blocks();
        b.finalize(module.target_config());
    }
    if let Some(max_live) = opts.schedule {
        schedule::schedule_block(&mut ctx.func, body, max_live);
    }
    module.define_function(func, &mut ctx).map_err(|e| cg(&e))?;
    if let Some(dir) = std::env::var_os("PSC_JIT_DUMP") {
        dump_machine_code(&ctx, Path::new(&dir));
    }
    module.clear_context(&mut ctx);
    Ok(Built { module, func, fused, groups, constants })
}

fn mem() -> MemFlagsData {
    // The safe wrapper guarantees every column holds `n` floats: accesses cannot trap.
    MemFlagsData::new().with_notrap()
}

/// Reads of the splatted parameter and constant tables: 16-byte aligned, never written while
/// the kernel runs, always in bounds.
fn table_mem() -> MemFlagsData {
    MemFlagsData::new().with_notrap().with_aligned().with_readonly()
}

/// Writes the kernel's machine code to `dir/kernel-<n>.bin` (raw x86-64 or aarch64 bytes, for
/// `objdump -D -b binary` and `llvm-mca`; see `tools/jit_mca.sh`). A development aid behind
/// the `PSC_JIT_DUMP` environment variable; failures are reported and otherwise ignored.
fn dump_machine_code(ctx: &cranelift_codegen::Context, dir: &Path) {
    static DUMPED: AtomicUsize = AtomicUsize::new(0);
    let Some(code) = ctx.compiled_code() else { return };
    let path = dir.join(format!("kernel-{}.bin", DUMPED.fetch_add(1, Ordering::Relaxed)));
    if let Err(e) = std::fs::write(&path, code.code_buffer()) {
        eprintln!("PSC_JIT_DUMP: cannot write {}: {e}", path.display());
    }
}

/// Defines the whole function; returns the loop body block.
fn define(a: &mut Lanes, program: &Program, groups: usize, ptr: Type) -> Block {
    let b = &mut *a.b;
    let entry = b.create_block();
    b.append_block_params_for_function_params(entry);
    b.switch_to_block(entry);
    let (params, table, inputs, outputs, n) = {
        let p = b.block_params(entry);
        (p[0], p[1], p[2], p[3], p[4])
    };
    a.table = table;
    let ptr_bytes = ptr.bytes() as i32;
    let in_cols: Vec<Value> =
        (0..2 + program.num_seeds).map(|k| b.ins().load(ptr, mem(), inputs, ptr_bytes * k as i32)).collect();
    let out_cols: Vec<Value> =
        (0..program.outputs.len()).map(|k| b.ins().load(ptr, mem(), outputs, ptr_bytes * k as i32)).collect();
    let header = b.create_block();
    let body = b.create_block();
    let exit = b.create_block();
    let i_main = b.append_block_param(header, ptr);
    let zero = b.ins().iconst(ptr, 0);
    b.ins().jump(header, &[zero.into()]);

    // `n` is a multiple of 4·groups (the caller pads the tail), so one loop covers every point.
    b.switch_to_block(header);
    let more = b.ins().icmp(IntCC::UnsignedLessThan, i_main, n);
    b.ins().brif(more, body, &[], exit, &[]);

    b.switch_to_block(body);
    let two = b.ins().iconst(ptr, 2);
    let base = b.ins().ishl(i_main, two);
    emit_program(a, program, &out_cols, Leaves { params, in_cols: &in_cols, base }, groups);
    let b = &mut *a.b;
    let step = b.ins().iconst(ptr, 4 * groups as i64);
    let next = b.ins().iadd(i_main, step);
    b.ins().jump(header, &[next.into()]);

    b.switch_to_block(exit);
    b.ins().return_(&[]);
    body
}

/// Emits every live node for `groups` vectors, storing outputs as soon as they are computed.
fn emit_program(a: &mut Lanes, program: &Program, out_cols: &[Value], leaves: Leaves, groups: usize) {
    let live = live_nodes(program);
    let mut outputs_of: HashMap<usize, Vec<usize>> = HashMap::new();
    for (k, out) in program.outputs.iter().enumerate() {
        outputs_of.entry(out.node.index()).or_default().push(k);
    }
    let mut vals: Vec<Vec<Value>> = vec![Vec::new(); program.nodes.len()];
    let mut trig: HashMap<(usize, usize), approx::SinCosParts<Lanes>> = HashMap::new();
    for (i, op) in program.nodes.iter().enumerate() {
        if !live[i] {
            continue;
        }
        if let Op::Sin(x) | Op::Cos(x) = *op {
            // `sin x` and `cos x` of one `x` (rotations, directions) share the reduction and
            // both polynomials; only the final quadrant selection differs.
            let quarter_turns = i32::from(matches!(op, Op::Cos(_)));
            vals[i] = (0..groups)
                .map(|g| {
                    let parts = match trig.get(&(x.index(), g)) {
                        Some(&parts) => parts,
                        None => {
                            let xv = operand(a, program, &vals, x.index(), g, leaves);
                            let parts = approx::sin_cos_parts(a, xv);
                            trig.insert((x.index(), g), parts);
                            parts
                        }
                    };
                    approx::finish_sin_cos(a, parts, quarter_turns)
                })
                .collect();
        } else if !op.is_leaf() {
            vals[i] = (0..groups)
                .map(|g| {
                    let mut it = op.operands().map(|id| operand(a, program, &vals, id.index(), g, leaves));
                    let x = it.next().expect("non-leaf has an operand");
                    let y = it.next().unwrap_or(x);
                    let z = it.next().unwrap_or(x);
                    eval_op(a, op, x, y, z)
                })
                .collect();
        }
        if let Some(ks) = outputs_of.get(&i) {
            for &k in ks {
                for g in 0..groups {
                    let value = operand(a, program, &vals, i, g, leaves);
                    store_column(a, out_cols[k], leaves.base, g, value);
                }
            }
        }
    }
}

/// Where leaves read from inside the loop body.
#[derive(Clone, Copy)]
struct Leaves<'c> {
    params: Value,
    in_cols: &'c [Value],
    base: Value,
}

/// The value of node `i` for vector group `g`. Leaves are re-emitted at every use rather than
/// once per iteration: a parameter broadcast or a column load is one instruction, while a
/// value held from the top of a long body costs a register or a spill slot throughout.
fn operand(a: &mut Lanes, program: &Program, vals: &[Vec<Value>], i: usize, g: usize, leaves: Leaves) -> Value {
    match program.nodes[i] {
        Op::Const(bits) => a.f(f32::from_bits(bits)),
        Op::Param(p) => a.b.ins().load(types::F32X4, table_mem(), leaves.params, 16 * p as i32),
        Op::U => load_column(a, leaves.in_cols[0], leaves.base, g),
        Op::V => load_column(a, leaves.in_cols[1], leaves.base, g),
        Op::Seed(s) => load_column(a, leaves.in_cols[2 + s as usize], leaves.base, g),
        _ => vals[i][g],
    }
}

fn load_column(a: &mut Lanes, col: Value, base: Value, g: usize) -> Value {
    let addr = a.b.ins().iadd(col, base);
    a.b.ins().load(types::F32X4, mem(), addr, 16 * g as i32)
}

fn store_column(a: &mut Lanes, col: Value, base: Value, g: usize, v: Value) {
    let addr = a.b.ins().iadd(col, base);
    a.b.ins().store(mem(), v, addr, 16 * g as i32);
}

/// Splatted constants, deduplicated by lane type and bits, in the order the kernel's constant
/// table holds them.
#[derive(Default)]
struct ConstTable {
    index: HashMap<u32, i32>,
    bits: Vec<u32>,
}

/// [`Arith`] over cranelift `F32X4` / `I32X4` values.
///
/// Every use of a constant is its own aligned load from the constant table (the kernel's
/// second argument) rather than a value materialised once: a load with one use is folded
/// into its consumer as a memory operand, so constants cost no instruction and no register,
/// where a materialised splat would stay live across the body and be spilled (regalloc2 does
/// not rematerialise).
struct Lanes<'a, 'f> {
    b: &'a mut FunctionBuilder<'f>,
    fused: bool,
    /// Whether the target is x86-64 (`x86_cvtt2dq` exists).
    x86: bool,
    table: Value,
    constants: ConstTable,
}

impl Lanes<'_, '_> {
    fn vconst(&mut self, float: bool, bits: u32) -> Value {
        let next = self.constants.bits.len() as i32;
        let slot = *self.constants.index.entry(bits).or_insert(next);
        if slot == next {
            self.constants.bits.push(bits);
        }
        let ty = if float { types::F32X4 } else { types::I32X4 };
        self.b.ins().load(ty, table_mem(), self.table, 16 * slot)
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
        if self.x86 {
            self.b.ins().x86_cvtt2dq(types::I32X4, x)
        } else {
            // Elsewhere: the saturating conversion, then NaN and out-of-range lanes to i32::MIN.
            let converted = self.b.ins().fcvt_to_sint_sat(types::I32X4, x);
            let (lo, hi) = (self.f(-2_147_483_648.0), self.f(2_147_483_648.0));
            let at_least_lo = self.b.ins().fcmp(FloatCC::GreaterThanOrEqual, x, lo);
            let below_hi = self.b.ins().fcmp(FloatCC::LessThan, x, hi);
            let in_range = self.b.ins().band(at_least_lo, below_hi);
            let min = self.i(i32::MIN);
            self.b.ins().bitselect(in_range, converted, min)
        }
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
