//! The reference meaning of every IR op on scalars.
//!
//! Constant folding, the interpreter and the JIT's tests all use these functions, so there is
//! exactly one definition of what, say, `Pow(-1, 2)` or `Hash(3, 7)` is.

use super::Op;

/// Evaluates a non-leaf op on already-computed operand values. Leaves return `None`.
#[inline]
pub fn eval(op: &Op, a: f32, b: f32, c: f32) -> Option<f32> {
    Some(match op {
        Op::Const(_) | Op::U | Op::V | Op::Param(_) | Op::Seed(_) => return None,
        Op::Neg(_) => -a,
        Op::Abs(_) => a.abs(),
        Op::Floor(_) => a.floor(),
        Op::Sqrt(_) => sqrt(a),
        Op::Sin(_) => a.sin(),
        Op::Cos(_) => a.cos(),
        Op::Exp(_) => a.exp(),
        Op::Log(_) => log(a),
        Op::Add(..) => a + b,
        Op::Sub(..) => a - b,
        Op::Mul(..) => a * b,
        Op::Div(..) => a / b,
        Op::Min(..) => min(a, b),
        Op::Max(..) => max(a, b),
        Op::Pow(..) => pow(a, b),
        Op::Atan2(..) => atan2(a, b),
        Op::Hash(..) => hash(a, b),
        Op::Lt(..) => bool(a < b),
        Op::Le(..) => bool(a <= b),
        Op::Eq(..) => bool(a == b),
        Op::Select(..) => select(a, b, c),
    })
}

#[inline]
pub fn bool(x: bool) -> f32 {
    if x {
        1.0
    } else {
        0.0
    }
}

#[inline]
pub fn sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

#[inline]
pub fn log(x: f32) -> f32 {
    x.max(f32::MIN_POSITIVE).ln()
}

#[inline]
pub fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

#[inline]
pub fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

#[inline]
pub fn pow(a: f32, b: f32) -> f32 {
    if a > 0.0 {
        a.powf(b)
    } else {
        0.0
    }
}

#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    if y == 0.0 && x == 0.0 {
        0.0
    } else {
        y.atan2(x)
    }
}

#[inline]
pub fn select(c: f32, a: f32, b: f32) -> f32 {
    if c != 0.0 {
        a
    } else {
        b
    }
}

/// Float to integer as the JIT does it (x86 `cvttps2dq`, one instruction): truncate toward
/// zero; NaN and values outside the `i32` range give `i32::MIN`.
#[inline]
pub fn to_int(x: f32) -> i32 {
    if (-2_147_483_648.0..2_147_483_648.0).contains(&x) {
        x as i32
    } else {
        i32::MIN
    }
}

/// A 2D integer hash (a murmur3-style finaliser over two multiplied lanes) mapped to
/// `[0, 1)` with 24 bits, so that `hash(a, b) * 2^24` is an exact integer and hashes can chain.
#[inline]
pub fn hash(a: f32, b: f32) -> f32 {
    let ia = to_int(a) as u32;
    let ib = to_int(b) as u32;
    let mut h = ia.wrapping_mul(0x9E37_79B1) ^ ib.wrapping_mul(0x85EB_CA77);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297A_2D39);
    h ^= h >> 15;
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(test)]
mod tests {
    use super::to_int;

    #[test]
    fn to_int_truncates_in_range_and_gives_min_outside() {
        assert_eq!(to_int(2.9), 2);
        assert_eq!(to_int(-2.9), -2);
        assert_eq!(to_int(-2_147_483_648.0), i32::MIN);
        assert_eq!(to_int(2_147_483_520.0), 2_147_483_520); // the largest f32 below 2^31
        for outside in [2_147_483_648.0, 1e20, -1e20, f32::INFINITY, f32::NEG_INFINITY, f32::NAN] {
            assert_eq!(to_int(outside), i32::MIN, "{outside}");
        }
    }
}
