//! The lane arithmetic every op and every polynomial is written against.
//!
//! There is exactly one source for the meaning of each op as the JIT computes it
//! ([`crate::ops`]); it is generic over [`Arith`]. Code generation instantiates it with
//! cranelift `F32X4`/`I32X4` values (`codegen`), and [`Scalar`] instantiates it with
//! plain `f32`/`i32`, giving a bit-exact scalar mirror of the generated code. Tests compare
//! the JIT against that mirror exactly and the mirror against `std`/f64 for accuracy.

/// A float comparison. All are *ordered* (false on NaN) except [`Cmp::Une`] and [`Cmp::Uno`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cmp {
    Lt,
    Le,
    Eq,
    /// Unordered or not equal: Rust's `a != b` (true when either is NaN).
    Une,
    /// Either operand is NaN.
    Uno,
}

/// Element-wise arithmetic on float lanes `F`, 32-bit integer lanes `I` and lane masks `M`.
pub trait Arith {
    type F: Copy;
    type I: Copy;
    type M: Copy;

    fn f(&mut self, x: f32) -> Self::F;
    fn i(&mut self, x: i32) -> Self::I;

    fn add(&mut self, a: Self::F, b: Self::F) -> Self::F;
    fn sub(&mut self, a: Self::F, b: Self::F) -> Self::F;
    fn mul(&mut self, a: Self::F, b: Self::F) -> Self::F;
    fn div(&mut self, a: Self::F, b: Self::F) -> Self::F;
    /// `a * b + c`, fused (one rounding) when the target has FMA, else two roundings.
    fn fma(&mut self, a: Self::F, b: Self::F, c: Self::F) -> Self::F;
    fn neg(&mut self, a: Self::F) -> Self::F;
    fn abs(&mut self, a: Self::F) -> Self::F;
    fn sqrt(&mut self, a: Self::F) -> Self::F;
    fn floor(&mut self, a: Self::F) -> Self::F;
    /// Round to nearest, ties to even.
    fn nearest(&mut self, a: Self::F) -> Self::F;

    fn cmp(&mut self, cc: Cmp, a: Self::F, b: Self::F) -> Self::M;
    /// `if m { a } else { b }` per lane.
    fn sel(&mut self, m: Self::M, a: Self::F, b: Self::F) -> Self::F;
    fn mand(&mut self, a: Self::M, b: Self::M) -> Self::M;

    /// Truncate toward zero; NaN and values outside the `i32` range give `i32::MIN` (never
    /// traps): x86 `cvttps2dq`, and `psc_compiler::ir::semantics::to_int`.
    fn to_int(&mut self, x: Self::F) -> Self::I;
    /// Signed integer to float, round to nearest.
    fn to_float(&mut self, x: Self::I) -> Self::F;
    fn float_to_bits(&mut self, x: Self::F) -> Self::I;
    fn bits_to_float(&mut self, x: Self::I) -> Self::F;

    fn iadd(&mut self, a: Self::I, b: Self::I) -> Self::I;
    fn isub(&mut self, a: Self::I, b: Self::I) -> Self::I;
    /// Wrapping multiply.
    fn imul(&mut self, a: Self::I, b: Self::I) -> Self::I;
    fn iand(&mut self, a: Self::I, b: Self::I) -> Self::I;
    fn ixor(&mut self, a: Self::I, b: Self::I) -> Self::I;
    fn shl(&mut self, a: Self::I, s: u8) -> Self::I;
    /// Logical right shift.
    fn ushr(&mut self, a: Self::I, s: u8) -> Self::I;
    /// Arithmetic right shift.
    fn sshr(&mut self, a: Self::I, s: u8) -> Self::I;
    fn ieq(&mut self, a: Self::I, b: Self::I) -> Self::M;
}

/// Scalar `f32` arithmetic that mirrors the generated vector code bit for bit.
#[derive(Clone, Copy, Debug)]
pub struct Scalar {
    /// Must match the kernel's [`crate::CompiledKernel::uses_fma`] for bit-exactness.
    pub fused: bool,
}

impl Arith for Scalar {
    type F = f32;
    type I = i32;
    type M = bool;

    fn f(&mut self, x: f32) -> f32 {
        x
    }
    fn i(&mut self, x: i32) -> i32 {
        x
    }
    fn add(&mut self, a: f32, b: f32) -> f32 {
        a + b
    }
    fn sub(&mut self, a: f32, b: f32) -> f32 {
        a - b
    }
    fn mul(&mut self, a: f32, b: f32) -> f32 {
        a * b
    }
    fn div(&mut self, a: f32, b: f32) -> f32 {
        a / b
    }
    fn fma(&mut self, a: f32, b: f32, c: f32) -> f32 {
        if self.fused {
            a.mul_add(b, c)
        } else {
            a * b + c
        }
    }
    fn neg(&mut self, a: f32) -> f32 {
        -a
    }
    fn abs(&mut self, a: f32) -> f32 {
        a.abs()
    }
    fn sqrt(&mut self, a: f32) -> f32 {
        a.sqrt()
    }
    fn floor(&mut self, a: f32) -> f32 {
        a.floor()
    }
    fn nearest(&mut self, a: f32) -> f32 {
        a.round_ties_even()
    }
    fn cmp(&mut self, cc: Cmp, a: f32, b: f32) -> bool {
        match cc {
            Cmp::Lt => a < b,
            Cmp::Le => a <= b,
            Cmp::Eq => a == b,
            Cmp::Une => a != b,
            Cmp::Uno => a.is_nan() || b.is_nan(),
        }
    }
    fn sel(&mut self, m: bool, a: f32, b: f32) -> f32 {
        if m {
            a
        } else {
            b
        }
    }
    fn mand(&mut self, a: bool, b: bool) -> bool {
        a && b
    }
    fn to_int(&mut self, x: f32) -> i32 {
        psc_compiler::ir::semantics::to_int(x)
    }
    fn to_float(&mut self, x: i32) -> f32 {
        x as f32
    }
    fn float_to_bits(&mut self, x: f32) -> i32 {
        x.to_bits() as i32
    }
    fn bits_to_float(&mut self, x: i32) -> f32 {
        f32::from_bits(x as u32)
    }
    fn iadd(&mut self, a: i32, b: i32) -> i32 {
        a.wrapping_add(b)
    }
    fn isub(&mut self, a: i32, b: i32) -> i32 {
        a.wrapping_sub(b)
    }
    fn imul(&mut self, a: i32, b: i32) -> i32 {
        a.wrapping_mul(b)
    }
    fn iand(&mut self, a: i32, b: i32) -> i32 {
        a & b
    }
    fn ixor(&mut self, a: i32, b: i32) -> i32 {
        a ^ b
    }
    fn shl(&mut self, a: i32, s: u8) -> i32 {
        a.wrapping_shl(u32::from(s))
    }
    fn ushr(&mut self, a: i32, s: u8) -> i32 {
        ((a as u32) >> s) as i32
    }
    fn sshr(&mut self, a: i32, s: u8) -> i32 {
        a >> s
    }
    fn ieq(&mut self, a: i32, b: i32) -> bool {
        a == b
    }
}

/// Counts the floating-point work of one lane: every add/sub/mul/div/sqrt is one flop, an
/// FMA two. Used for the GFLOP/s figure of `psc bench`.
#[derive(Clone, Copy, Debug, Default)]
pub struct FlopCounter {
    pub flops: usize,
}

impl Arith for FlopCounter {
    type F = ();
    type I = ();
    type M = ();
    fn f(&mut self, _: f32) {}
    fn i(&mut self, _: i32) {}
    fn add(&mut self, _: (), _: ()) {
        self.flops += 1;
    }
    fn sub(&mut self, _: (), _: ()) {
        self.flops += 1;
    }
    fn mul(&mut self, _: (), _: ()) {
        self.flops += 1;
    }
    fn div(&mut self, _: (), _: ()) {
        self.flops += 1;
    }
    fn fma(&mut self, _: (), _: (), _: ()) {
        self.flops += 2;
    }
    fn neg(&mut self, _: ()) {}
    fn abs(&mut self, _: ()) {}
    fn sqrt(&mut self, _: ()) {
        self.flops += 1;
    }
    fn floor(&mut self, _: ()) {}
    fn nearest(&mut self, _: ()) {}
    fn cmp(&mut self, _: Cmp, _: (), _: ()) {}
    fn sel(&mut self, _: (), _: (), _: ()) {}
    fn mand(&mut self, _: (), _: ()) {}
    fn to_int(&mut self, _: ()) {}
    fn to_float(&mut self, _: ()) {}
    fn float_to_bits(&mut self, _: ()) {}
    fn bits_to_float(&mut self, _: ()) {}
    fn iadd(&mut self, _: (), _: ()) {}
    fn isub(&mut self, _: (), _: ()) {}
    fn imul(&mut self, _: (), _: ()) {}
    fn iand(&mut self, _: (), _: ()) {}
    fn ixor(&mut self, _: (), _: ()) {}
    fn shl(&mut self, _: (), _: u8) {}
    fn ushr(&mut self, _: (), _: u8) {}
    fn sshr(&mut self, _: (), _: u8) {}
    fn ieq(&mut self, _: (), _: ()) {}
}
