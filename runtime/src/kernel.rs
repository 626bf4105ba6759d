//! Compiled graphs as parallel kernels over batches of points.
//!
//! A [`Kernel`] is a forward [`Program`] with its native code and, optionally, an [`Adjoint`]
//! (from `psc_compiler::diff::reverse::adjoint`) with its native code. Batches are
//! split into fixed [`CHUNK`]-point chunks evaluated in parallel with rayon. Chunk boundaries
//! do not depend on the thread count and every point's arithmetic is independent of which
//! chunk or vector lane it lands in, so per-point results are bit-identical for any number of
//! threads. Parameter gradients are summed per chunk in f64, then the chunk partials are added
//! sequentially in chunk order: the summed gradient is bit-identical for any thread count too.
//!
//! Where each gradient is among the adjoint's outputs is its [`AdjointLayout`], returned by the
//! differentiation with the program and checked against the forward program once, when the
//! kernel is built.

use std::fmt;
use std::sync::Arc;

use psc_compiler::ir::Program;
use psc_compiler::{Adjoint, AdjointLayout};
use psc_jit::{CompiledKernel, JitError};
use rayon::prelude::*;

/// Points per parallel work item. A multiple of every vector width the JIT uses, so only
/// the batch's last chunk has a partial vector.
pub const CHUNK: usize = 4096;

#[derive(Clone, Debug, PartialEq)]
pub enum KernelError {
    Jit(JitError),
    /// Arguments disagree with the program or with each other.
    Shape(String),
    /// [`Kernel::adjoint`] on a kernel built without an adjoint program.
    NoAdjoint,
    /// The adjoint program does not have the layout it came with, for this forward program.
    BadAdjoint(String),
}

impl fmt::Display for KernelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KernelError::Jit(e) => e.fmt(f),
            KernelError::Shape(m) => write!(f, "kernel arguments do not match: {m}"),
            KernelError::NoAdjoint => write!(f, "this kernel was built without an adjoint"),
            KernelError::BadAdjoint(m) => write!(f, "adjoint program has an unexpected layout: {m}"),
        }
    }
}

impl std::error::Error for KernelError {}

impl From<JitError> for KernelError {
    fn from(e: JitError) -> Self {
        KernelError::Jit(e)
    }
}

struct AdjointKernel {
    adjoint: Adjoint,
    jit: CompiledKernel,
}

/// A forward program, its compiled kernel, and optionally its compiled adjoint.
pub struct Kernel {
    forward: Program,
    /// Shared so a kernel with an adjoint can reuse an already compiled forward kernel.
    forward_jit: Arc<CompiledKernel>,
    adjoint: Option<AdjointKernel>,
}

/// Result of [`Kernel::adjoint`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Gradients {
    /// Forward outputs at every point (the adjoint computes them anyway), SoA.
    pub values: Vec<Vec<f32>>,
    /// Per point: sum over outputs of seed × d output / d u.
    pub d_u: Vec<f32>,
    pub d_v: Vec<f32>,
    /// Indexed by parameter slot (`forward().num_params` long), summed over all points;
    /// zero for slots the adjoint does not differentiate.
    pub d_params: Vec<f64>,
}

impl Kernel {
    /// Compiles a forward-only kernel.
    pub fn new(forward: Program) -> Result<Kernel, KernelError> {
        let forward_jit = Arc::new(psc_jit::compile(&forward)?);
        Ok(Kernel { forward, forward_jit, adjoint: None })
    }

    /// Compiles a kernel with its adjoint, checking the adjoint's layout against `forward`.
    pub fn with_adjoint(forward: Program, adjoint: Adjoint) -> Result<Kernel, KernelError> {
        Kernel::new(forward)?.with_added_adjoint(adjoint)
    }

    /// This kernel's forward code (shared, not recompiled) plus a compiled `adjoint`, whose
    /// layout is checked against the forward program first.
    pub fn with_added_adjoint(&self, adjoint: Adjoint) -> Result<Kernel, KernelError> {
        adjoint.layout.check(&self.forward, &adjoint.program).map_err(KernelError::BadAdjoint)?;
        let jit = psc_jit::compile(&adjoint.program)?;
        Ok(Kernel {
            forward: self.forward.clone(),
            forward_jit: Arc::clone(&self.forward_jit),
            adjoint: Some(AdjointKernel { adjoint, jit }),
        })
    }

    pub fn forward(&self) -> &Program {
        &self.forward
    }
    pub fn forward_jit(&self) -> &CompiledKernel {
        &self.forward_jit
    }
    pub fn adjoint_program(&self) -> Option<&Program> {
        self.adjoint.as_ref().map(|a| &a.adjoint.program)
    }
    pub fn adjoint_layout(&self) -> Option<&AdjointLayout> {
        self.adjoint.as_ref().map(|a| &a.adjoint.layout)
    }
    pub fn adjoint_jit(&self) -> Option<&CompiledKernel> {
        self.adjoint.as_ref().map(|a| &a.jit)
    }
    /// Parameter slots the adjoint differentiates (empty without an adjoint).
    pub fn wrt_params(&self) -> &[u32] {
        self.adjoint.as_ref().map_or(&[], |a| a.adjoint.layout.wrt())
    }

    /// Forward outputs at the points `(u[k], v[k])`, one column per output.
    ///
    /// Allocates the columns; in a loop, [`Kernel::eval_into`] reuses them instead (fresh
    /// pages are faulted in on first write, which for cheap graphs costs as much as the
    /// kernel itself).
    pub fn eval(&self, params: &[f32], u: &[f32], v: &[f32]) -> Result<Vec<Vec<f32>>, KernelError> {
        let mut cols = Vec::new();
        self.eval_into(params, u, v, &mut cols)?;
        Ok(cols)
    }

    /// [`Kernel::eval`] into `cols`, resized to one column of `u.len()` per output; columns
    /// already that long are overwritten in place, without allocating.
    pub fn eval_into(&self, params: &[f32], u: &[f32], v: &[f32], cols: &mut Vec<Vec<f32>>) -> Result<(), KernelError> {
        run_chunked(&self.forward_jit, params, u, v, &[], cols)
    }

    /// Forward outputs at the texel centres of a `w`×`h` image, row-major, each column
    /// `w*h` long. Texel `(x, y)` is at `u = (x + 0.5) / w`, `v = 1 - (y + 0.5) / h`: row 0
    /// is the top of the image (v near 1), matching the OpenGL/OBJ convention that v grows
    /// upward while images are stored top row first.
    pub fn eval_grid(&self, params: &[f32], w: usize, h: usize) -> Result<Vec<Vec<f32>>, KernelError> {
        let (u, v) = grid_uv(w, h)?;
        self.eval(params, &u, &v)
    }

    /// Reverse-mode gradients: `d_out[o][k]` is the incoming gradient of output `o` at point
    /// `k`. Returns the forward values, per-point `d_u`, `d_v`, and per-slot parameter
    /// gradients summed over all points (deterministically, see the module docs).
    pub fn adjoint(&self, params: &[f32], u: &[f32], v: &[f32], d_out: &[&[f32]]) -> Result<Gradients, KernelError> {
        let mut gradients = Gradients::default();
        self.adjoint_into(params, u, v, d_out, &mut gradients)?;
        Ok(gradients)
    }

    /// [`Kernel::adjoint`] into `out`, reusing its columns when they are already long enough.
    pub fn adjoint_into(
        &self,
        params: &[f32],
        u: &[f32],
        v: &[f32],
        d_out: &[&[f32]],
        out: &mut Gradients,
    ) -> Result<(), KernelError> {
        let adj = self.adjoint.as_ref().ok_or(KernelError::NoAdjoint)?;
        check_points(u, v)?;
        let n = u.len();
        let nf = self.forward.outputs.len();
        if d_out.len() != nf {
            return Err(KernelError::Shape(format!(
                "{} gradient columns given, the graph has {nf} outputs",
                d_out.len()
            )));
        }
        if let Some((o, c)) = d_out.iter().enumerate().find(|(_, c)| c.len() != n) {
            return Err(KernelError::Shape(format!("gradient column {o} has {} points, u has {n}", c.len())));
        }
        let layout = &adj.adjoint.layout;
        let nw = layout.wrt().len();
        // Columns kept per point: forward values, d_u, d_v (outputs `0..nf + 2`, the layout's
        // d_u and d_v); the d_param columns after them are chunk scratch.
        debug_assert_eq!((layout.d_u(), layout.d_v(), layout.d_param(0)), (nf, nf + 1, nf + 2));
        let mut kept = std::mem::take(&mut out.values);
        kept.resize_with(nf, Vec::new);
        kept.extend([std::mem::take(&mut out.d_u), std::mem::take(&mut out.d_v)]);
        resize_columns(&mut kept, nf + 2, n);
        let work = split_columns(&mut kept, n);
        let partials: Vec<Vec<f64>> = work
            .into_par_iter()
            .enumerate()
            .map(|(c, mut outs)| -> Result<Vec<f64>, JitError> {
                let r = chunk_range(c, n);
                let len = r.len();
                let seeds: Vec<&[f32]> = d_out.iter().map(|s| &s[r.clone()]).collect();
                let mut scratch = vec![vec![0.0f32; len]; nw];
                outs.extend(scratch.iter_mut().map(|s| &mut s[..]));
                adj.jit.run(params, &u[r.clone()], &v[r], &seeds, &mut outs)?;
                // Sequential f64 sums: the order within a chunk is fixed.
                Ok(scratch.iter().map(|col| col.iter().map(|&g| f64::from(g)).sum()).collect())
            })
            .collect::<Result<_, _>>()?;
        let mut d_params = vec![0.0f64; self.forward.num_params];
        for partial in &partials {
            for (slot, g) in layout.wrt().iter().zip(partial) {
                d_params[*slot as usize] += g;
            }
        }
        out.d_v = kept.pop().unwrap_or_default();
        out.d_u = kept.pop().unwrap_or_default();
        out.values = kept;
        out.d_params = d_params;
        Ok(())
    }
}

/// Texel-centre coordinates of a `w`×`h` grid, row 0 at the top (see [`Kernel::eval_grid`]).
pub fn grid_uv(w: usize, h: usize) -> Result<(Vec<f32>, Vec<f32>), KernelError> {
    let n = w.checked_mul(h).ok_or_else(|| KernelError::Shape(format!("{w}x{h} grid is too large")))?;
    let mut u = Vec::with_capacity(n);
    let mut v = Vec::with_capacity(n);
    for y in 0..h {
        // Computed from the flipped row index so rows are exact mirrors of each other.
        let vy = ((h - 1 - y) as f32 + 0.5) / h as f32;
        for x in 0..w {
            u.push((x as f32 + 0.5) / w as f32);
            v.push(vy);
        }
    }
    Ok((u, v))
}

/// The fixed chunks a batch of `n` points is split into, as parallel work: [`CHUNK`] points
/// each, the last one shorter. The same for any thread count, which is what makes results
/// independent of it; benchmarks and baselines (the interpreter) use it to run over the same
/// chunks as kernels do.
pub fn chunk_ranges(n: usize) -> impl IndexedParallelIterator<Item = std::ops::Range<usize>> {
    (0..n.div_ceil(CHUNK)).into_par_iter().map(move |c| chunk_range(c, n))
}

/// Runs any compiled kernel over the chunks of a batch, in parallel: `seeds` (one column per
/// seed the kernel reads, each as long as `u`) and the outputs into `cols`, resized to one
/// column of `u.len()` per output (allocations are kept). [`Kernel::eval_into`] is this with
/// the forward kernel; code generation benchmarks call it with kernels of other options.
pub fn run_chunked(
    jit: &CompiledKernel,
    params: &[f32],
    u: &[f32],
    v: &[f32],
    seeds: &[&[f32]],
    cols: &mut Vec<Vec<f32>>,
) -> Result<(), KernelError> {
    check_points(u, v)?;
    let n = u.len();
    if let Some((s, c)) = seeds.iter().enumerate().find(|(_, c)| c.len() != n) {
        return Err(KernelError::Shape(format!("seed column {s} has {} points, u has {n}", c.len())));
    }
    resize_columns(cols, jit.num_outputs(), n);
    let work = split_columns(cols, n);
    work.into_par_iter().enumerate().try_for_each(|(c, mut outs)| {
        let r = chunk_range(c, n);
        let s: Vec<&[f32]> = seeds.iter().map(|col| &col[r.clone()]).collect();
        jit.run(params, &u[r.clone()], &v[r], &s, &mut outs)
    })?;
    Ok(())
}

fn check_points(u: &[f32], v: &[f32]) -> Result<(), KernelError> {
    if u.len() != v.len() {
        return Err(KernelError::Shape(format!("u has {} points but v has {}", u.len(), v.len())));
    }
    Ok(())
}

fn chunk_range(c: usize, n: usize) -> std::ops::Range<usize> {
    c * CHUNK..((c + 1) * CHUNK).min(n)
}

/// Makes `cols` exactly `count` columns of `n` floats, keeping existing allocations.
fn resize_columns(cols: &mut Vec<Vec<f32>>, count: usize, n: usize) {
    cols.resize_with(count, Vec::new);
    for col in cols.iter_mut() {
        col.resize(n, 0.0);
    }
}

/// Regroups `cols` (each `n` long) into per-chunk lists of mutable column slices.
fn split_columns(cols: &mut [Vec<f32>], n: usize) -> Vec<Vec<&mut [f32]>> {
    let chunks = n.div_ceil(CHUNK);
    let mut work: Vec<Vec<&mut [f32]>> = (0..chunks).map(|_| Vec::with_capacity(cols.len())).collect();
    for col in cols.iter_mut() {
        for (c, piece) in col.chunks_mut(CHUNK).enumerate() {
            work[c].push(piece);
        }
    }
    work
}
