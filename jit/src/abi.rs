//! The only `unsafe` in the crate: turning finalized machine code into a callable function,
//! calling it, and releasing its memory.
//!
//! Contract of the generated function (established by [`crate::codegen`]):
//! `fn(params, constants, inputs, outputs, n)`, for `n` a multiple of `block`, reads the
//! 16-byte aligned lane tables `params[0..num_params]` and `constants[..]`, reads `n` floats
//! from each of the `2 + num_seeds` input columns, writes `n` floats to each of the
//! `num_outputs` output columns, and touches no other memory. It makes no calls, takes no
//! locks, keeps no state, and cannot trap or unwind (no integer division; float-to-int
//! conversions are the non-trapping `cvttps2dq`). So it is sound to call whenever those
//! pointers are valid for those ranges — which [`NativeKernel::call`] checks on every call —
//! and output columns do not overlap inputs or each other (guaranteed by `&mut` borrows).

use cranelift_jit::JITModule;
use cranelift_module::FuncId;

use crate::JitError;

type RawKernel = unsafe extern "C" fn(*const Lanes, *const Lanes, *const *const f32, *const *mut f32, usize);

/// One value splatted to four lanes, aligned as the generated code's table loads require.
#[derive(Clone, Copy)]
#[repr(C, align(16))]
pub(crate) struct Lanes([f32; 4]);

impl Lanes {
    fn splat(x: f32) -> Self {
        Lanes([x; 4])
    }
}

/// Executable code plus the module that owns its pages.
pub(crate) struct NativeKernel {
    /// `Some` until drop; taken there to free the code pages.
    module: Option<JITModule>,
    entry: RawKernel,
    /// The kernel's constant table.
    constants: Vec<Lanes>,
    num_params: usize,
    num_inputs: usize,
    num_outputs: usize,
    /// Points per loop iteration; the native code only accepts multiples of it.
    block: usize,
}

// SAFETY: after `finalize_definitions` the code and constant pages are immutable (read/exec)
// and the generated function is pure apart from writing the caller's output slices, so any
// number of threads may call it at once (`Sync`). The `JITModule` is never touched again
// except by `Drop`, which has exclusive access; freeing the mapping from another thread than
// the one that created it is fine (`munmap`/`VirtualFree` are thread-agnostic), so moving the
// owner between threads is sound too (`Send`).
unsafe impl Send for NativeKernel {}
unsafe impl Sync for NativeKernel {}

impl NativeKernel {
    /// The most points [`NativeKernel::call_points`] evaluates on the stack in one call.
    pub(crate) const MAX_POINTS: usize = 16;

    /// Finalizes `module` and resolves the kernel's entry point.
    pub(crate) fn finalize(
        mut module: JITModule,
        func: FuncId,
        num_params: usize,
        num_seeds: usize,
        num_outputs: usize,
        block: usize,
        constant_bits: &[u32],
    ) -> Result<Self, JitError> {
        if let Err(e) = module.finalize_definitions() {
            // SAFETY: nothing from this module was handed out; its memory is unreferenced.
            unsafe { module.free_memory() };
            return Err(JitError::Codegen(e.to_string()));
        }
        let code = module.get_finalized_function(func);
        // SAFETY: `func` was declared with five pointer-sized parameters and no returns using
        // the host's default calling convention, which is `extern "C"` on every target
        // cranelift-native supports; pointers and usize are pointer-sized.
        let entry = unsafe { std::mem::transmute::<*const u8, RawKernel>(code) };
        let constants = constant_bits.iter().map(|&b| Lanes::splat(f32::from_bits(b))).collect();
        Ok(NativeKernel {
            module: Some(module),
            entry,
            constants,
            num_params,
            num_inputs: 2 + num_seeds,
            num_outputs,
            block,
        })
    }

    /// Runs the kernel over `n` points. Re-checks every length the generated code relies on,
    /// so this is safe to call with any arguments.
    pub(crate) fn call(
        &self,
        params: &[f32],
        u: &[f32],
        v: &[f32],
        seeds: &[&[f32]],
        outputs: &mut [&mut [f32]],
    ) -> Result<(), JitError> {
        let n = u.len();
        let ok = params.len() >= self.num_params
            && 2 + seeds.len() == self.num_inputs
            && outputs.len() == self.num_outputs
            && v.len() == n
            && seeds.iter().all(|c| c.len() == n)
            && outputs.iter().all(|c| c.len() == n);
        if !ok {
            return Err(JitError::Shape("column count or length mismatch at the native boundary".into()));
        }
        SCRATCH.with_borrow_mut(|scratch| {
            scratch.params.clear();
            scratch.params.extend(params[..self.num_params].iter().map(|&p| Lanes::splat(p)));
            let whole = n - n % self.block;
            if whole > 0 {
                scratch.in_ptrs.clear();
                scratch.in_ptrs.extend([u, v].iter().chain(seeds).map(|c| c.as_ptr()));
                scratch.out_ptrs.clear();
                scratch.out_ptrs.extend(outputs.iter_mut().map(|c| c.as_mut_ptr()));
                // SAFETY: lengths checked above are ≥ `whole`, a multiple of `block`, as the
                // contract in the module docs requires; the pointer arrays and the slices they
                // point into outlive the call; outputs are distinct `&mut` borrows so they
                // alias neither each other nor the inputs.
                unsafe { self.enter(scratch, whole) };
            }
            if whole < n {
                self.run_tail(scratch, [u, v].iter().chain(seeds).copied(), outputs, whole, n);
            }
        });
        Ok(())
    }

    /// Evaluates the points `(u[k], v[k])` (at most [`NativeKernel::MAX_POINTS`]) of a program
    /// without seeds into `out` (point-major: `out[k * num_outputs + o]`), with every buffer on
    /// the stack: the renderer's per-hit path (one hit, or the few hits of a packet that share
    /// a material), where the general call's bookkeeping would cost a noticeable share of a
    /// small kernel. Each point has a lane of its own, so a point's values do not depend on the
    /// others. Falls back to [`NativeKernel::call`] past the stack buffers' sizes.
    pub(crate) fn call_points(&self, params: &[f32], u: &[f32], v: &[f32], out: &mut [f32]) -> Result<(), JitError> {
        const MAX_BLOCK: usize = NativeKernel::MAX_POINTS;
        const MAX_PARAMS: usize = 64;
        const MAX_OUTPUTS: usize = 16;
        let (n, n_out) = (u.len(), self.num_outputs);
        if n == 0 || v.len() != n || n > MAX_BLOCK || params.len() < self.num_params || out.len() != n * n_out {
            return Err(JitError::Shape("point count or length mismatch at the native boundary".into()));
        }
        let padded = n.div_ceil(self.block) * self.block;
        let fits = padded <= MAX_BLOCK && self.num_params <= MAX_PARAMS && n_out <= MAX_OUTPUTS;
        if !fits || self.num_inputs != 2 {
            let mut columns: Vec<Vec<f32>> = vec![vec![0.0; n]; n_out];
            let mut outputs: Vec<&mut [f32]> = columns.iter_mut().map(|c| &mut c[..]).collect();
            self.call(params, u, v, &[], &mut outputs)?;
            for (o, column) in columns.iter().enumerate() {
                column.iter().enumerate().for_each(|(k, &x)| out[k * n_out + o] = x);
            }
            return Ok(());
        }
        let mut lanes = [Lanes([0.0; 4]); MAX_PARAMS];
        for (lane, &p) in lanes.iter_mut().zip(&params[..self.num_params]) {
            *lane = Lanes::splat(p);
        }
        // The lanes past the last point evaluate the last point again (a value they are sure to
        // handle), as the batch call's tail does.
        let (mut u_col, mut v_col) = ([u[n - 1]; MAX_BLOCK], [v[n - 1]; MAX_BLOCK]);
        u_col[..n].copy_from_slice(u);
        v_col[..n].copy_from_slice(v);
        let mut out_cols = [[0.0f32; MAX_BLOCK]; MAX_OUTPUTS];
        let in_ptrs = [u_col.as_ptr(), v_col.as_ptr()];
        let out_ptrs: [*mut f32; MAX_OUTPUTS] = std::array::from_fn(|k| out_cols[k].as_mut_ptr());
        // SAFETY: two input columns and `num_outputs` output columns of MAX_BLOCK ≥ `padded`
        // floats each (`padded` a multiple of `block`), all distinct stack arrays that outlive
        // the call; `lanes` holds `num_params` splatted parameters.
        unsafe { (self.entry)(lanes.as_ptr(), self.constants.as_ptr(), in_ptrs.as_ptr(), out_ptrs.as_ptr(), padded) };
        for (o, col) in out_cols[..n_out].iter().enumerate() {
            col[..n].iter().enumerate().for_each(|(k, &x)| out[k * n_out + o] = x);
        }
        Ok(())
    }

    /// Runs points `start..n` (fewer than `block`) on copies padded to one block with the last
    /// point, and copies the real results back.
    fn run_tail<'a>(
        &self,
        scratch: &mut Scratch,
        inputs: impl Iterator<Item = &'a [f32]>,
        outputs: &mut [&mut [f32]],
        start: usize,
        n: usize,
    ) {
        let block = self.block;
        scratch.padded.clear();
        for column in inputs {
            let last = column[column.len() - 1];
            scratch.padded.extend(column[start..n].iter().copied().chain(std::iter::repeat(last)).take(block));
        }
        let outputs_at = scratch.padded.len();
        scratch.padded.resize(outputs_at + block * outputs.len(), 0.0);
        let base = scratch.padded.as_mut_ptr();
        scratch.in_ptrs.clear();
        // SAFETY (both): offsets stay inside `padded`, which is not resized again below.
        scratch.in_ptrs.extend((0..self.num_inputs).map(|k| unsafe { base.add(k * block) } as *const f32));
        scratch.out_ptrs.clear();
        scratch.out_ptrs.extend((0..outputs.len()).map(|k| unsafe { base.add(outputs_at + k * block) }));
        // SAFETY: every padded column is exactly `block` floats long and lies in `padded`,
        // input columns before output columns, no two overlapping.
        unsafe { self.enter(scratch, block) };
        for (k, out) in outputs.iter_mut().enumerate() {
            let from = outputs_at + k * block;
            out[start..n].copy_from_slice(&scratch.padded[from..from + n - start]);
        }
    }

    /// Calls the native code on the pointer arrays in `scratch`.
    ///
    /// # Safety
    /// `scratch.in_ptrs` and `scratch.out_ptrs` hold `num_inputs` and `num_outputs` pointers,
    /// each valid for `n` floats (`n` a multiple of `block`); output columns overlap nothing.
    unsafe fn enter(&self, scratch: &Scratch, n: usize) {
        debug_assert!(scratch.in_ptrs.len() == self.num_inputs && scratch.out_ptrs.len() == self.num_outputs);
        // SAFETY: the caller's contract, plus `params` holding `num_params` splatted lanes and
        // `constants` the table the code was generated against.
        unsafe {
            (self.entry)(
                scratch.params.as_ptr(),
                self.constants.as_ptr(),
                scratch.in_ptrs.as_ptr(),
                scratch.out_ptrs.as_ptr(),
                n,
            )
        }
    }
}

/// Per-thread buffers reused by every batch call, so that evaluating a kernel (even a batch
/// shorter than one block) does not allocate.
#[derive(Default)]
struct Scratch {
    params: Vec<Lanes>,
    in_ptrs: Vec<*const f32>,
    out_ptrs: Vec<*mut f32>,
    padded: Vec<f32>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::default();
}

impl Drop for NativeKernel {
    fn drop(&mut self) {
        if let Some(module) = self.module.take() {
            // SAFETY: `entry` is the only pointer into the module's memory and it dies with
            // `self`; no call can be in flight because calls borrow `self`.
            unsafe { module.free_memory() };
        }
    }
}
