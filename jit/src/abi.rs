//! The only `unsafe` in the crate: turning finalized machine code into a callable function,
//! calling it, and releasing its memory.
//!
//! Contract of the generated function (established by [`crate::codegen`]):
//! `fn(params, constants, inputs, outputs, n)`, for `n` a multiple of `block`, reads the
//! 16-byte aligned lane tables `params[0..num_params]` and `constants[..]`, reads `n` floats from each
//! of the `2 + num_seeds` input columns, writes `n` floats to each of the `num_outputs` output
//! columns, and touches no other memory. It makes no calls, takes no locks, keeps no state,
//! and cannot trap or unwind (no integer division, saturating conversions only). So it is
//! sound to call whenever those pointers are valid for those ranges — which
//! [`NativeKernel::call`] checks on every call — and output columns do not overlap inputs or
//! each other (guaranteed by `&mut` borrows).

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
        inputs: &[&[f32]],
        outputs: &mut [&mut [f32]],
        n: usize,
    ) -> Result<(), JitError> {
        let ok = params.len() >= self.num_params
            && inputs.len() == self.num_inputs
            && outputs.len() == self.num_outputs
            && inputs.iter().all(|c| c.len() == n)
            && outputs.iter().all(|c| c.len() == n);
        if !ok {
            return Err(JitError::Shape("column count or length mismatch at the native boundary".into()));
        }
        let params: Vec<Lanes> = params[..self.num_params].iter().map(|&p| Lanes::splat(p)).collect();
        let whole = n - n % self.block;
        if whole > 0 {
            let in_ptrs: Vec<*const f32> = inputs.iter().map(|c| c.as_ptr()).collect();
            let out_ptrs: Vec<*mut f32> = outputs.iter_mut().map(|c| c.as_mut_ptr()).collect();
            // SAFETY: lengths checked above are ≥ `whole`, a multiple of `block`, as the
            // contract in the module docs requires; the pointer arrays and the slices they
            // point into outlive the call; outputs are distinct `&mut` borrows so they alias
            // neither each other nor the inputs.
            unsafe {
                (self.entry)(params.as_ptr(), self.constants.as_ptr(), in_ptrs.as_ptr(), out_ptrs.as_ptr(), whole)
            };
        }
        if whole < n {
            self.run_tail(&params, inputs, outputs, whole, n);
        }
        Ok(())
    }

    /// Runs points `start..n` (fewer than `block`) on copies padded to one block with the last
    /// point, and copies the real results back.
    fn run_tail(&self, params: &[Lanes], inputs: &[&[f32]], outputs: &mut [&mut [f32]], start: usize, n: usize) {
        let block = self.block;
        let padded_inputs: Vec<Vec<f32>> = inputs
            .iter()
            .map(|c| {
                let mut p = c[start..n].to_vec();
                p.resize(block, c[n - 1]);
                p
            })
            .collect();
        let mut padded_outputs = vec![vec![0.0f32; block]; outputs.len()];
        let in_ptrs: Vec<*const f32> = padded_inputs.iter().map(|c| c.as_ptr()).collect();
        let out_ptrs: Vec<*mut f32> = padded_outputs.iter_mut().map(|c| c.as_mut_ptr()).collect();
        // SAFETY: every column is exactly `block` floats long, the pointers outlive the call,
        // and the padded output buffers are distinct allocations.
        unsafe { (self.entry)(params.as_ptr(), self.constants.as_ptr(), in_ptrs.as_ptr(), out_ptrs.as_ptr(), block) };
        for (out, padded) in outputs.iter_mut().zip(&padded_outputs) {
            out[start..n].copy_from_slice(&padded[..n - start]);
        }
    }
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
