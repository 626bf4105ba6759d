//! Exact derivatives of the Karis BRDF, for the fit: the specular term and the full
//! `f·cos θl` with respect to the roughness, the four cosines and the normal.
//!
//! Each gradient function evaluates the value with the same arithmetic as [`specular`] (the
//! value it returns is bit-identical to it) and differentiates the closed form by hand:
//! * `D = a2 / (π d²)`, `d = (n·h)²(a2−1) + 1`, `a2 = r⁴`:
//!   `∂D/∂(n·h) = −4 a2 (n·h)(a2−1) / (π d³)`, `∂D/∂a2 = (d − 2 a2 (n·h)²) / (π d³)`;
//! * `F = F0 + (1−F0) 2^e`, `e = (−5.55473 x − 6.98316) x`: `∂F/∂x = (1−F0) 2^e ln 2 (−2·5.55473 x − 6.98316)`;
//! * `G1(x)/x = 1/q`, `q = x(1−k) + k`: `∂(G1/x)/∂x = −(1−k)/q²`, `∂G1/∂x = k/q²`,
//!   `∂G1/∂k = −x(1−x)/q²`, `∂k/∂r = (r+1)/4`.
//!
//! Outside the support (n·v ≤ 0 or n·l ≤ 0) value and derivatives are 0. Roughness is used as
//! given: a caller that clamps it (as [`super::Karis::new`] does with
//! [`super::clamp_roughness`]) multiplies the roughness derivative by 0 outside the range.
//! Derivatives with respect to v·h treat it as an independent variable; the clamp of v·h at 0
//! in [`Cosines::new`] never binds for directions above the surface (v·h ≥ 0 there).

use super::{fresnel, ggx_d, masking_k, positive, specular, Cosines, Real, F0};
use std::f32::consts::{LN_2, PI};

/// A value and its partial derivatives with respect to the roughness and the four cosines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpecularGrad<T> {
    pub value: T,
    pub d_roughness: T,
    pub d_n_v: T,
    pub d_n_l: T,
    pub d_n_h: T,
    pub d_v_h: T,
}

impl<T: Real> SpecularGrad<T> {
    fn zero() -> Self {
        let z = T::lit(0.0);
        SpecularGrad { value: z, d_roughness: z, d_n_v: z, d_n_l: z, d_n_h: z, d_v_h: z }
    }

    /// The gradient with respect to the normal n of a function of the cosines, for unit v, l
    /// and h = normalize(v + l) (which do not depend on n): `∂n·v · v + ∂n·l · l + ∂n·h · h`.
    /// n is treated as a free vector (no projection onto unit length): a caller that
    /// normalises its normal chains through that normalisation itself.
    pub fn d_normal(&self, v: [T; 3], l: [T; 3], h: [T; 3]) -> [T; 3] {
        std::array::from_fn(|i| self.d_n_v * v[i] + self.d_n_l * l[i] + self.d_n_h * h[i])
    }
}

/// The specular term `s = D·F·G / (4 n·v n·l)` and its derivatives. `value` equals
/// [`specular`]`(c, roughness)` bit for bit.
pub fn specular_grad<T: Real>(c: Cosines<T>, roughness: T) -> SpecularGrad<T> {
    let one = T::lit(1.0);
    if !positive(c.n_v) || !positive(c.n_l) {
        return SpecularGrad::zero();
    }
    let value = specular(c, roughness);
    let r = roughness;
    // D and its derivatives.
    let a = r * r;
    let a2 = a * a;
    let dd = c.n_h * c.n_h * (a2 - one) + one;
    let d = ggx_d(c.n_h, r);
    let pi_d3 = T::lit(PI) * dd * dd * dd;
    let d_d_nh = -T::lit(4.0) * a2 * c.n_h * (a2 - one) / pi_d3;
    let d_d_a2 = (dd - T::lit(2.0) * a2 * c.n_h * c.n_h) / pi_d3;
    let d_d_r = d_d_a2 * T::lit(4.0) * a * r;
    // F and its derivative.
    let f = fresnel(c.v_h);
    let e = (T::lit(-5.55473) * c.v_h - T::lit(6.98316)) * c.v_h;
    let d_f_vh = (one - T::lit(F0)) * e.exp2() * T::lit(LN_2) * (T::lit(-2.0 * 5.55473) * c.v_h - T::lit(6.98316));
    // G1(x)/x = 1/q for each direction, so s = D F / (4 q_v q_l).
    let k = masking_k(r);
    let q_v = c.n_v * (one - k) + k;
    let q_l = c.n_l * (one - k) + k;
    let inv_q = one / (q_v * q_l);
    let d_k_r = (r + one) / T::lit(4.0);
    // ∂q/∂k = 1 − x for each direction.
    let d_invq_k = -inv_q * ((one - c.n_v) / q_v + (one - c.n_l) / q_l);
    let quarter = T::lit(0.25);
    SpecularGrad {
        value,
        d_roughness: quarter * f * (d_d_r * inv_q + d * d_invq_k * d_k_r),
        d_n_v: -quarter * d * f * inv_q * (one - k) / q_v,
        d_n_l: -quarter * d * f * inv_q * (one - k) / q_l,
        d_n_h: quarter * d_d_nh * f * inv_q,
        d_v_h: quarter * d * d_f_vh * inv_q,
    }
}

/// `s·(n·l)`, the specular part of `f·cos θl`, and its derivatives.
pub fn specular_cos_grad<T: Real>(c: Cosines<T>, roughness: T) -> SpecularGrad<T> {
    let g = specular_grad(c, roughness);
    if !positive(c.n_v) || !positive(c.n_l) {
        return g;
    }
    SpecularGrad {
        value: g.value * c.n_l,
        d_roughness: g.d_roughness * c.n_l,
        d_n_v: g.d_n_v * c.n_l,
        d_n_l: g.d_n_l * c.n_l + g.value,
        d_n_h: g.d_n_h * c.n_l,
        d_v_h: g.d_v_h * c.n_l,
    }
}

/// `f(v, l)·(n·l)` per channel for an albedo, a roughness and a normal, with its derivatives:
/// what the fit's shading layer integrates against the light grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FCosGrad<T> {
    /// `albedo_c (n·l)/π + s (n·l)` per channel.
    pub value: [T; 3],
    /// `∂value_c / ∂albedo_c = (n·l)/π` (the same for every channel).
    pub d_albedo: T,
    /// `∂value_c / ∂roughness` (the same for every channel: the specular term is grey).
    pub d_roughness: T,
    /// `∂value_c / ∂n` per channel (n a free vector, see [`SpecularGrad::d_normal`]).
    pub d_normal: [[T; 3]; 3],
}

/// [`FCosGrad`] at a normal `n`, view direction `v` and light direction `l` (unit vectors, any
/// common frame). Zero unless n·v > 0 and n·l > 0. `roughness` is used as given.
pub fn f_cos_grad<T: Real>(n: [T; 3], v: [T; 3], l: [T; 3], albedo: [T; 3], roughness: T) -> FCosGrad<T> {
    let zero = T::lit(0.0);
    let (c, h) = Cosines::new(n, v, l);
    if !positive(c.n_v) || !positive(c.n_l) {
        return FCosGrad { value: [zero; 3], d_albedo: zero, d_roughness: zero, d_normal: [[zero; 3]; 3] };
    }
    let s = specular_cos_grad(c, roughness);
    let inv_pi = T::lit(1.0 / PI);
    let d_albedo = c.n_l * inv_pi;
    let d_spec_n = s.d_normal(v, l, h);
    FCosGrad {
        value: std::array::from_fn(|ch| albedo[ch] * d_albedo + s.value),
        d_albedo,
        d_roughness: s.d_roughness,
        d_normal: std::array::from_fn(|ch| std::array::from_fn(|i| albedo[ch] * inv_pi * l[i] + d_spec_n[i])),
    }
}
