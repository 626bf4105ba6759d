//! The photoscene JIT: compiles a scalar IR [`Program`] to a native, vectorised
//! structure-of-arrays kernel with cranelift.
//!
//! Owns: code generation (`codegen`), the inline polynomial transcendentals (`approx`), the
//! one definition of each op as the JIT computes it (`ops`, generic over `arith`, which also
//! gives a bit-exact scalar mirror for tests), and the native call boundary (`abi`, the only
//! `unsafe` module). Must never: call out of generated code (no libm, no Rust callbacks, so
//! nothing reachable from native code can panic), leak code pages (kernels free their module
//! on drop), or trust caller-provided lengths (every call is validated).
//!
//! Accuracy: programs without `sin/cos/exp/log/pow/atan2` are bit-exact with the reference
//! interpreter; the transcendentals' error bounds are documented in [`approx`].

// `unsafe` is denied everywhere but `abi`, the native call boundary (see its module docs and
// ARCHITECTURE.md). `deny`, not `forbid`, so that one module can be allowed.
#![deny(unsafe_code)]

#[allow(unsafe_code)]
mod abi;
pub mod approx;
pub mod arith;
mod codegen;
pub mod ops;
mod schedule;

use std::fmt;
use std::time::{Duration, Instant};

use psc_compiler::ir::Program;

pub use ops::{flops_per_point, mirror_eval_point};

/// Why a program could not be compiled or a kernel could not run.
#[derive(Clone, Debug, PartialEq)]
pub enum JitError {
    /// The program violates the IR invariants.
    InvalidProgram(String),
    /// The host CPU lacks something the generated code needs.
    UnsupportedHost(String),
    /// Cranelift refused the function (a bug in this crate).
    Codegen(String),
    /// Arguments of [`CompiledKernel::run`] disagree with the program or with each other.
    Shape(String),
}

impl fmt::Display for JitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            JitError::InvalidProgram(m) => write!(f, "invalid IR program: {m}"),
            JitError::UnsupportedHost(m) => write!(f, "unsupported host for the JIT: {m}"),
            JitError::Codegen(m) => write!(f, "code generation failed: {m}"),
            JitError::Shape(m) => write!(f, "kernel arguments do not match: {m}"),
        }
    }
}

impl std::error::Error for JitError {}

/// Cranelift's optimisation level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OptLevel {
    None,
    Speed,
}

/// Code generation choices; [`Options::default`] is the measured-fastest configuration.
///
/// Measured with `psc bench --variants` (300-op synthetic material, 2 shared cores): cranelift
/// `opt_level = "none"` ran the forward kernel 20–40% faster than `"speed"` (whose egraph
/// pass and scheduler lengthen dependency chains, cf. wasmtime #6159/#6260) and the adjoint
/// equally fast, while compiling no slower. Interleaving 2 or 4 vectors per iteration gave no
/// reproducible gain over 1 (a graph's DAG already has ample independent work for the
/// out-of-order core; more groups only add register pressure) and costs 2–6x compile time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Options {
    pub opt_level: OptLevel,
    /// Independent 4-lane vectors per main-loop iteration (1..=4).
    pub groups: usize,
    /// List-schedule the loop body for instruction-level parallelism, keeping about this many
    /// vector values live (`schedule.rs`); `None` keeps the IR's order.
    pub schedule: Option<usize>,
    /// Programs of more ops than this get cranelift's single-pass register allocator instead
    /// of its backtracking one ([`SINGLE_PASS_ABOVE`] by default).
    pub single_pass_above: usize,
}

/// Ops above which a program's registers are allocated in a single pass.
///
/// Cranelift's backtracking allocator (regalloc2's ion) goes quadratic when thousands of
/// values are live at once, as the forward values of a long chain are through its adjoint: a
/// 1000-line let-chain (5 860 ops forward, 12 876 forward + adjoint) compiled in 1.2 s + 2.2 s,
/// and a 5000-line one took 81 s to bake. The single-pass allocator compiles those in 46 ms +
/// 46 ms and 0.55 s, and the chain's kernels ran as fast. On the library's kernels (at most
/// 2 602 ops, compiled in at most 8 + 21 ms) its code ran at 0.72x (forward) and 0.68x
/// (adjoint) the speed, geometric mean over `psc bench graphs`, so it is kept for programs
/// past the library's.
pub const SINGLE_PASS_ABOVE: usize = 4000;

impl Default for Options {
    fn default() -> Self {
        Options {
            opt_level: OptLevel::None,
            groups: 1,
            schedule: Some(schedule::MAX_LIVE),
            single_pass_above: SINGLE_PASS_ABOVE,
        }
    }
}

/// A compiled program: native code plus what is needed to call it safely.
pub struct CompiledKernel {
    native: abi::NativeKernel,
    num_params: usize,
    num_seeds: usize,
    output_names: Vec<String>,
    fused: bool,
    options: Options,
    compile_time: Duration,
    flops_per_point: usize,
}

/// Compiles `program` with the default [`Options`].
pub fn compile(program: &Program) -> Result<CompiledKernel, JitError> {
    compile_with(program, &Options::default())
}

/// Compiles `program` with explicit code generation options.
pub fn compile_with(program: &Program, options: &Options) -> Result<CompiledKernel, JitError> {
    let start = Instant::now();
    program.check_well_formed().map_err(|e| JitError::InvalidProgram(e.to_string()))?;
    let built = codegen::build(program, options)?;
    let native = abi::NativeKernel::finalize(
        built.module,
        built.func,
        program.num_params,
        program.num_seeds,
        program.outputs.len(),
        4 * built.groups,
        &built.constants,
    )?;
    Ok(CompiledKernel {
        native,
        num_params: program.num_params,
        num_seeds: program.num_seeds,
        output_names: program.outputs.iter().map(|o| o.name.clone()).collect(),
        fused: built.fused,
        options: *options,
        compile_time: start.elapsed(),
        flops_per_point: ops::flops_per_point(program),
    })
}

impl CompiledKernel {
    /// Evaluates the program at the points `(u[k], v[k])`, with `seeds[s][k]` the adjoint
    /// seeds (empty for forward programs), writing `outputs[o][k]`.
    ///
    /// Requires `params.len() >= num_params`, `v`, every seed column and every output column
    /// as long as `u`, exactly `num_seeds` seed columns and `num_outputs` output columns.
    pub fn run(
        &self,
        params: &[f32],
        u: &[f32],
        v: &[f32],
        seeds: &[&[f32]],
        outputs: &mut [&mut [f32]],
    ) -> Result<(), JitError> {
        let n = u.len();
        let shape = |m: String| Err(JitError::Shape(m));
        if params.len() < self.num_params {
            return shape(format!("{} parameters given, the program reads {}", params.len(), self.num_params));
        }
        if v.len() != n {
            return shape(format!("u has {n} points but v has {}", v.len()));
        }
        if seeds.len() != self.num_seeds {
            return shape(format!("{} seed columns given, the program has {}", seeds.len(), self.num_seeds));
        }
        if let Some((s, c)) = seeds.iter().enumerate().find(|(_, c)| c.len() != n) {
            return shape(format!("seed column {s} has {} points, u has {n}", c.len()));
        }
        if outputs.len() != self.output_names.len() {
            return shape(format!(
                "{} output columns given, the program has {}",
                outputs.len(),
                self.output_names.len()
            ));
        }
        if let Some((o, c)) = outputs.iter().enumerate().find(|(_, c)| c.len() != n) {
            return shape(format!("output column {o} has {} points, u has {n}", c.len()));
        }
        self.native.call(params, u, v, seeds, outputs)
    }

    /// Evaluates one point of a forward program (no seeds) into `out`, one value per output,
    /// without allocating: the per-hit path of the renderer. Same results as [`Self::run`] on
    /// a one-point batch.
    pub fn run_point(&self, params: &[f32], u: f32, v: f32, out: &mut [f32]) -> Result<(), JitError> {
        self.run_points(params, &[u], &[v], out)
    }

    /// The most points [`Self::run_points`] takes.
    pub const MAX_POINTS: usize = abi::NativeKernel::MAX_POINTS;

    /// Evaluates up to [`Self::MAX_POINTS`] points of a forward program (no seeds) into `out`,
    /// point-major (`out[k * num_outputs + o]`: output `o` at point `k`), without allocating:
    /// the renderer's path for the hits of a packet that share a material. Bit for bit the
    /// values [`Self::run`] gives for the same points.
    pub fn run_points(&self, params: &[f32], u: &[f32], v: &[f32], out: &mut [f32]) -> Result<(), JitError> {
        if self.num_seeds != 0 {
            return Err(JitError::Shape(format!(
                "run_points needs a program without seeds, this one has {}",
                self.num_seeds
            )));
        }
        if params.len() < self.num_params {
            return Err(JitError::Shape(format!(
                "{} parameters given, the program reads {}",
                params.len(),
                self.num_params
            )));
        }
        let (n, n_out) = (u.len(), self.output_names.len());
        if n == 0 || n > Self::MAX_POINTS || v.len() != n {
            return Err(JitError::Shape(format!(
                "run_points takes 1 to {} points with as many v as u, got {n} u and {} v",
                Self::MAX_POINTS,
                v.len()
            )));
        }
        if out.len() != n * n_out {
            return Err(JitError::Shape(format!(
                "{} output values given for {n} points of {n_out} outputs",
                out.len()
            )));
        }
        self.native.call_points(params, u, v, out)
    }

    pub fn num_params(&self) -> usize {
        self.num_params
    }
    pub fn num_seeds(&self) -> usize {
        self.num_seeds
    }
    pub fn num_outputs(&self) -> usize {
        self.output_names.len()
    }
    pub fn output_names(&self) -> &[String] {
        &self.output_names
    }
    /// Whether polynomials use fused multiply-add (pass to [`mirror_eval_point`]).
    pub fn uses_fma(&self) -> bool {
        self.fused
    }
    pub fn options(&self) -> Options {
        self.options
    }
    /// Wall time of [`compile`]: validation, cranelift, finalization.
    pub fn compile_time(&self) -> Duration {
        self.compile_time
    }
    /// Floating-point operations per point (FMA counts 2), for throughput figures.
    pub fn flops_per_point(&self) -> usize {
        self.flops_per_point
    }
}

impl fmt::Debug for CompiledKernel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CompiledKernel")
            .field("num_params", &self.num_params)
            .field("num_seeds", &self.num_seeds)
            .field("outputs", &self.output_names)
            .field("fused", &self.fused)
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}
