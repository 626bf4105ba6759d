//! Inline polynomial transcendentals, generic over [`Arith`] so the generated vector code and
//! its scalar mirror are the same algorithm.
//!
//! Coefficients are the classic Cephes single-precision minimax sets; range reductions are
//! Cody–Waite with split constants. Every input, including NaN and ±inf, goes through the
//! same straight-line code: there are no branches, no calls and no integer conversion that
//! can trap (float-to-int conversions give `i32::MIN` out of range). Measured maximum errors
//! (see `tests/transcendentals.rs`, which asserts them; "ulp"-level figures are against f64
//! `std`):
//!
//! | fn      | domain swept                   | bound asserted                       |
//! |---------|--------------------------------|--------------------------------------|
//! | sin/cos | \|x\| ≤ 1e4                     | abs error < 2e-6 (measured ~1e-7)    |
//! | exp     | x ∈ [-87, 88.7] (normal result) | rel error < 1e-6                     |
//! | log     | x ∈ [1e-38, 3e38]              | rel error < 1e-6 (abs < 1e-7 near 1) |
//! | atan2   | all quadrants, wide magnitudes | abs error < 1e-6                     |
//! | pow     | a ∈ (0, 1e4], \|b ln a\| ≤ 80  | rel error < 2e-6 + 2e-7·\|b ln a\|    |
//!
//! Outside the swept range sin/cos stay bounded but lose accuracy (reduction uses a float
//! quotient); inf/NaN give NaN as in `std`.

// Coefficients are kept as their published decimals (Cephes); the f32 rounding is intended.
#![allow(clippy::excessive_precision)]

use crate::arith::{Arith, Cmp};

// Operand order in `a.fma(x, y, z)`: x86 FMA overwrites its first operand, so a multiplicand
// that is used again later (the reduced argument, `z = r²`, the quotient `k`) goes second and
// the one that dies here (a coefficient, the running polynomial) first; otherwise every step
// needs a register copy. The product is exact, so the order never changes a result.

const FRAC_2_PI: f32 = std::f32::consts::FRAC_2_PI;
// pi/2 split so that k*P1 and k*P2 are exact for |k| < 2^15 even without FMA.
const P1: f32 = 1.570_312_5;
const P2: f32 = 4.837_512_969_970_703_125e-4;
const P3: f32 = 7.549_789_954_891_882e-8;

/// Reduces `x` to `r ∈ ~[-pi/4, pi/4]` with `x = r + q·pi/2`.
fn reduce_half_pi<A: Arith>(a: &mut A, x: A::F) -> (A::F, A::I) {
    let c = a.f(FRAC_2_PI);
    let t = a.mul(x, c);
    let k = a.nearest(t);
    let (m1, m2, m3) = (a.f(-P1), a.f(-P2), a.f(-P3));
    let r = a.fma(m1, k, x);
    let r = a.fma(m2, k, r);
    let r = a.fma(m3, k, r);
    // Past |x| ~ 1e6 the float quotient k is too coarse and r is no longer small; clamping
    // keeps the polynomials bounded (the result is then merely in [-1, 1], not accurate).
    // Spelled so NaN passes through (and so cranelift lowers each to one minps/maxps).
    let (one, mone) = (a.f(1.0), a.f(-1.0));
    let hi = a.cmp(Cmp::Lt, one, r);
    let r = a.sel(hi, one, r);
    let lo = a.cmp(Cmp::Lt, r, mone);
    let r = a.sel(lo, mone, r);
    let q = a.to_int(k);
    (r, q)
}

/// sin(r) on the reduced range.
fn sin_poly<A: Arith>(a: &mut A, r: A::F, z: A::F) -> A::F {
    let (s3, s2, s1) = (a.f(-1.951_529_589_1e-4), a.f(8.332_160_873_6e-3), a.f(-1.666_665_461_1e-1));
    let p = a.fma(s3, z, s2);
    let p = a.fma(p, z, s1);
    let rz = a.mul(r, z);
    a.fma(rz, p, r)
}

/// cos(r) on the reduced range.
fn cos_poly<A: Arith>(a: &mut A, z: A::F) -> A::F {
    let (c3, c2, c1) = (a.f(2.443_315_711_809_948e-5), a.f(-1.388_731_625_493_765e-3), a.f(4.166_664_568_298_827e-2));
    let p = a.fma(c3, z, c2);
    let p = a.fma(p, z, c1);
    let zz = a.mul(z, z);
    let (mhalf, one) = (a.f(-0.5), a.f(1.0));
    let head = a.fma(mhalf, z, one);
    a.fma(zz, p, head)
}

/// The work `sin x` and `cos x` share: the reduced argument's quadrant and both polynomials.
pub struct SinCosParts<A: Arith> {
    quadrant: A::I,
    sin_r: A::F,
    cos_r: A::F,
}

// By hand: a derive would require `A: Copy`, but only the lane types need to be.
impl<A: Arith> Clone for SinCosParts<A> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<A: Arith> Copy for SinCosParts<A> {}

/// Reduces `x` and evaluates both polynomials; [`finish_sin_cos`] then picks sin or cos.
pub fn sin_cos_parts<A: Arith>(a: &mut A, x: A::F) -> SinCosParts<A> {
    let (r, quadrant) = reduce_half_pi(a, x);
    let z = a.mul(r, r);
    let sin_r = sin_poly(a, r, z);
    let cos_r = cos_poly(a, z);
    SinCosParts { quadrant, sin_r, cos_r }
}

/// sin(x) from its parts when `quarter_turns == 0`, cos(x) when it is 1.
pub fn finish_sin_cos<A: Arith>(a: &mut A, parts: SinCosParts<A>, quarter_turns: i32) -> A::F {
    let q = if quarter_turns == 0 {
        parts.quadrant
    } else {
        let shift = a.i(quarter_turns);
        a.iadd(parts.quadrant, shift)
    };
    // Odd quadrants swap sin and cos; quadrants 2 and 3 flip the sign.
    let one = a.i(1);
    let two = a.i(2);
    let zero = a.i(0);
    let odd = a.iand(q, one);
    let even = a.ieq(odd, zero);
    let y = a.sel(even, parts.sin_r, parts.cos_r);
    let half_turn = a.iand(q, two);
    let sign = a.shl(half_turn, 30);
    let yb = a.float_to_bits(y);
    let yb = a.ixor(yb, sign);
    a.bits_to_float(yb)
}

pub fn sin<A: Arith>(a: &mut A, x: A::F) -> A::F {
    let parts = sin_cos_parts(a, x);
    finish_sin_cos(a, parts, 0)
}

pub fn cos<A: Arith>(a: &mut A, x: A::F) -> A::F {
    let parts = sin_cos_parts(a, x);
    finish_sin_cos(a, parts, 1)
}

/// e^x. Inputs are clamped to [-104, 89] first (NaN passes through the clamp), which keeps
/// the exponent arithmetic in range: results overflow to inf and underflow to 0 exactly
/// where `expf` does.
pub fn exp<A: Arith>(a: &mut A, x: A::F) -> A::F {
    let hi = a.f(89.0);
    let lo = a.f(-104.0);
    let over = a.cmp(Cmp::Lt, hi, x);
    let x = a.sel(over, hi, x);
    let under = a.cmp(Cmp::Lt, x, lo);
    let x = a.sel(under, lo, x);
    let log2e = a.f(std::f32::consts::LOG2_E);
    let t = a.mul(x, log2e);
    let k = a.nearest(t);
    let (l1, l2) = (a.f(-0.693_359_375), a.f(2.121_944_4e-4));
    let r = a.fma(l1, k, x);
    let r = a.fma(l2, k, r);
    let coeffs = [
        1.987_569_15e-4,
        1.398_199_950_7e-3,
        8.333_451_907_3e-3,
        4.166_579_589_4e-2,
        1.666_666_545_9e-1,
        5.000_000_120_1e-1,
    ];
    let mut p = a.f(coeffs[0]);
    for &c in &coeffs[1..] {
        let c = a.f(c);
        p = a.fma(p, r, c);
    }
    let z = a.mul(r, r);
    let one = a.f(1.0);
    let r1 = a.add(r, one);
    let e = a.fma(p, z, r1);
    // Scale by 2^k in two halves so that every partial power of two is a normal float:
    // k ∈ [-150, 129] splits into halves in [-75, 65].
    let ki = a.to_int(k);
    let k1 = a.sshr(ki, 1);
    let k2 = a.isub(ki, k1);
    let s1 = pow2i(a, k1);
    let s2 = pow2i(a, k2);
    let e = a.mul(e, s1);
    a.mul(e, s2)
}

/// 2^k for k ∈ [-126, 127], built from exponent bits.
fn pow2i<A: Arith>(a: &mut A, k: A::I) -> A::F {
    let bias = a.i(127);
    let e = a.iadd(k, bias);
    let b = a.shl(e, 23);
    a.bits_to_float(b)
}

/// ln(x) for x > 0 (normal, subnormal or +inf). Zero, negative and NaN inputs give finite
/// garbage, never a trap: callers guard the domain first.
pub fn log_positive<A: Arith>(a: &mut A, x: A::F) -> A::F {
    // Subnormals: scale into the normal range and compensate in the exponent.
    let min_pos = a.f(f32::MIN_POSITIVE);
    let tiny = a.cmp(Cmp::Lt, x, min_pos);
    let scale = a.f(8_388_608.0); // 2^23
    let xs = a.mul(x, scale);
    let xn = a.sel(tiny, xs, x);
    let (m23, zero) = (a.f(-23.0), a.f(0.0));
    let e_adj = a.sel(tiny, m23, zero);

    let bits = a.float_to_bits(xn);
    let mant_mask = a.i(0x007F_FFFF);
    let one_bits = a.i(0x3F80_0000);
    let mb = a.iand(bits, mant_mask);
    let mb = a.ixor(mb, one_bits);
    let m = a.bits_to_float(mb); // [1, 2)
    let eb = a.ushr(bits, 23);
    let bias = a.i(127);
    let ei = a.isub(eb, bias);
    let e = a.to_float(ei);
    let e = a.add(e, e_adj);
    // Centre the mantissa on 1: m ∈ [sqrt(1/2), sqrt(2)).
    let sqrt2 = a.f(std::f32::consts::SQRT_2);
    let big = a.cmp(Cmp::Lt, sqrt2, m);
    let half = a.f(0.5);
    let mh = a.mul(m, half);
    let m = a.sel(big, mh, m);
    let one = a.f(1.0);
    let e1 = a.add(e, one);
    let e = a.sel(big, e1, e);
    let f = a.sub(m, one); // exact (Sterbenz)

    let coeffs = [
        7.037_683_629_2e-2,
        -1.151_461_031_0e-1,
        1.167_699_874_0e-1,
        -1.242_014_084_6e-1,
        1.424_932_278_7e-1,
        -1.666_805_766_5e-1,
        2.000_071_476_5e-1,
        -2.499_999_399_3e-1,
        3.333_333_117_4e-1,
    ];
    let mut p = a.f(coeffs[0]);
    for &c in &coeffs[1..] {
        let c = a.f(c);
        p = a.fma(p, f, c);
    }
    let z = a.mul(f, f);
    let fz = a.mul(f, z);
    let y = a.mul(p, fz);
    let ln2_lo = a.f(-2.121_944_4e-4);
    let y = a.fma(ln2_lo, e, y);
    let neg_half = a.f(-0.5);
    let y = a.fma(neg_half, z, y);
    let r = a.add(f, y);
    let ln2_hi = a.f(0.693_359_375);
    let r = a.fma(ln2_hi, e, r);
    let inf = a.f(f32::INFINITY);
    let is_inf = a.cmp(Cmp::Eq, x, inf);
    a.sel(is_inf, inf, r)
}

/// `ln(max(x, MIN_POSITIVE))`, the IR's guarded log.
pub fn log<A: Arith>(a: &mut A, x: A::F) -> A::F {
    let min_pos = a.f(f32::MIN_POSITIVE);
    let above = a.cmp(Cmp::Lt, min_pos, x);
    let x = a.sel(above, x, min_pos); // NaN → MIN_POSITIVE, as `f32::max` does
    log_positive(a, x)
}

/// `if a > 0 { a^b } else { 0 }` as `exp(b·ln a)`, with `powf`'s exact cases `a^0 = 1` and
/// `1^b = 1` (even for NaN b).
pub fn pow<A: Arith>(a: &mut A, x: A::F, y: A::F) -> A::F {
    let l = log_positive(a, x);
    let t = a.mul(y, l);
    let r = exp(a, t);
    let (zero, one) = (a.f(0.0), a.f(1.0));
    let y0 = a.cmp(Cmp::Eq, y, zero);
    let r = a.sel(y0, one, r);
    let x1 = a.cmp(Cmp::Eq, x, one);
    let r = a.sel(x1, one, r);
    let pos = a.cmp(Cmp::Lt, zero, x);
    a.sel(pos, r, zero)
}

/// `atan2(y, x)` with `atan2(±0, ±0) = 0`; NaN in, NaN out.
pub fn atan2<A: Arith>(a: &mut A, y: A::F, x: A::F) -> A::F {
    let ax = a.abs(x);
    let ay = a.abs(y);
    let steep = a.cmp(Cmp::Lt, ax, ay);
    let mx = a.sel(steep, ay, ax);
    let mn = a.sel(steep, ax, ay);
    let t = a.div(mn, mx);
    // mn == mx covers 0/0 and inf/inf: the ratio is 1 in the limit that matters.
    let one = a.f(1.0);
    let same = a.cmp(Cmp::Eq, mn, mx);
    let t = a.sel(same, one, t);
    // t ∈ [0, 1]; above tan(pi/8) use atan(t) = pi/4 + atan((t-1)/(t+1)).
    let tan_pi_8 = a.f(0.414_213_562_373_095_1);
    let big = a.cmp(Cmp::Lt, tan_pi_8, t);
    let tm = a.sub(t, one);
    let tp = a.add(t, one);
    let tq = a.div(tm, tp);
    let tr = a.sel(big, tq, t);
    let (quarter_pi, zero) = (a.f(std::f32::consts::FRAC_PI_4), a.f(0.0));
    let off = a.sel(big, quarter_pi, zero);
    let z = a.mul(tr, tr);
    let coeffs = [8.053_744_495_38e-2, -1.387_768_560_32e-1, 1.997_771_064_78e-1, -3.333_294_915_39e-1];
    let mut p = a.f(coeffs[0]);
    for &c in &coeffs[1..] {
        let c = a.f(c);
        p = a.fma(p, z, c);
    }
    let pz = a.mul(p, z);
    let at = a.fma(pz, tr, tr);
    let at = a.add(off, at);
    let half_pi = a.f(std::f32::consts::FRAC_PI_2);
    let comp = a.sub(half_pi, at);
    let at = a.sel(steep, comp, at);
    let pi = a.f(std::f32::consts::PI);
    let back = a.sub(pi, at);
    let left = a.cmp(Cmp::Lt, x, zero);
    let at = a.sel(left, back, at);
    // Copy y's sign onto the non-negative angle.
    let sign_mask = a.i(i32::MIN);
    let yb = a.float_to_bits(y);
    let ys = a.iand(yb, sign_mask);
    let ab = a.float_to_bits(at);
    let ab = a.ixor(ab, ys);
    let at = a.bits_to_float(ab);
    let y0 = a.cmp(Cmp::Eq, y, zero);
    let x0 = a.cmp(Cmp::Eq, x, zero);
    let origin = a.mand(y0, x0);
    let at = a.sel(origin, zero, at);
    let nan = a.cmp(Cmp::Uno, x, y);
    let sum = a.add(x, y);
    a.sel(nan, sum, at)
}
