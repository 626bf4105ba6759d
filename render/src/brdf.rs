//! The shading layer: the Karis microfacet BRDF, the one definition the path tracer, the
//! contact sheet and the fit use.
//!
//! `f(wo, wi) = albedo/π + D·F·G / (4 (n·wo)(n·wi))` with
//! * α = r², `D = α² / (π ((n·h)²(α²−1) + 1)²)` (GGX),
//! * `F = F0 + (1−F0)·2^((−5.55473 v·h − 6.98316) v·h)`, F0 = 0.05 (dielectric, no metallic),
//! * `G = G1(n·v)·G1(n·l)`, `G1(x) = x / (x(1−k) + k)`, k = (r+1)²/8 (Schlick-GGX, Karis).
//!
//! All directions are in the local shading frame (z = normal) and point away from the surface.
//! The BRDF is zero unless both directions are above the surface (the caller flips the frame for
//! two-sided surfaces). Roughness is clamped to [`MIN_ROUGHNESS`, 1] to keep D finite.
//! Sampling mixes a cosine lobe and GGX `D(h)(n·h)` half-vector sampling; [`Karis::pdf`] is the
//! exact density of [`Karis::sample`] (solid angle measure).
//!
//! The formulas are written once, generic over [`Real`] (`f32` to render and fit, `f64` to check
//! derivatives without f32 cancellation); [`grad`] gives their exact derivatives with respect to
//! the roughness, the cosines and the normal. [`KarisWo`], the path tracer's per-hit form, hoists
//! the terms that depend on `wo` alone out of the same arithmetic, so its values are
//! bit-identical (tested).

use glam::Vec3;
use std::f32::consts::PI;
use std::ops::{Add, Div, Mul, Neg, Sub};

pub mod grad;

pub use grad::{f_cos_grad, specular_cos_grad, specular_grad, FCosGrad, SpecularGrad};

/// Specular reflectance at normal incidence (Mitsuba `principled` with `specular = 0.625`).
pub const F0: f32 = 0.05;
/// Smallest roughness the BRDF accepts; smaller values are clamped (α = 4e-4).
pub const MIN_ROUGHNESS: f32 = 0.02;

/// The scalar the BRDF formulas are generic over. Only `f32` and `f64` implement it; constants
/// enter through [`Real::lit`] as the f32 values the renderer uses, so the `f64` instance is the
/// same function evaluated more precisely.
pub trait Real:
    Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    fn lit(x: f32) -> Self;
    fn exp2(self) -> Self;
    fn sqrt(self) -> Self;
    fn is_finite(self) -> bool;
}

impl Real for f32 {
    #[inline(always)]
    fn lit(x: f32) -> Self {
        x
    }
    #[inline(always)]
    fn exp2(self) -> Self {
        f32::exp2(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
}

impl Real for f64 {
    #[inline(always)]
    fn lit(x: f32) -> Self {
        x as f64
    }
    #[inline(always)]
    fn exp2(self) -> Self {
        f64::exp2(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
}

/// Karis' spherical-Gaussian Schlick Fresnel, `v_h` = cos of the angle between v and h.
#[inline]
pub fn fresnel<T: Real>(v_h: T) -> T {
    T::lit(F0) + (T::lit(1.0) - T::lit(F0)) * ((T::lit(-5.55473) * v_h - T::lit(6.98316)) * v_h).exp2()
}

/// GGX normal distribution with α = r².
#[inline]
pub fn ggx_d<T: Real>(n_h: T, roughness: T) -> T {
    let a = roughness * roughness;
    let a2 = a * a;
    let d = n_h * n_h * (a2 - T::lit(1.0)) + T::lit(1.0);
    a2 / (T::lit(PI) * d * d)
}

/// The masking constant k = (r+1)²/8 of [`g1`].
#[inline]
pub fn masking_k<T: Real>(roughness: T) -> T {
    (roughness + T::lit(1.0)) * (roughness + T::lit(1.0)) / T::lit(8.0)
}

/// Schlick-GGX masking for one direction with k = (r+1)²/8.
#[inline]
pub fn g1<T: Real>(x: T, roughness: T) -> T {
    let k = masking_k(roughness);
    x / (x * (T::lit(1.0) - k) + k)
}

/// The roughness the BRDF uses for a material's roughness `r`: clamped to
/// [[`MIN_ROUGHNESS`], 1]; non-finite values become 1. Its derivative is 1 inside the range and
/// 0 outside.
#[inline]
pub fn clamp_roughness(r: f32) -> f32 {
    if r.is_finite() {
        r.clamp(MIN_ROUGHNESS, 1.0)
    } else {
        1.0
    }
}

/// The cosines the BRDF depends on: n·v, n·l, n·h and v·h, with h = normalize(v + l).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cosines<T> {
    pub n_v: T,
    pub n_l: T,
    pub n_h: T,
    pub v_h: T,
}

impl<T: Real> Cosines<T> {
    /// From unit vectors `n` (normal), `v` (towards the viewer) and `l` (towards the light);
    /// v·h is clamped at 0 as in [`Karis::specular`]. Also returns h.
    #[inline]
    pub fn new(n: [T; 3], v: [T; 3], l: [T; 3]) -> (Self, [T; 3]) {
        let s = [v[0] + l[0], v[1] + l[1], v[2] + l[2]];
        // As glam's normalize: times the reciprocal length (the same bits as the path tracer).
        let inv_len = T::lit(1.0) / dot(s, s).sqrt();
        let h = [s[0] * inv_len, s[1] * inv_len, s[2] * inv_len];
        let v_h = dot(v, h);
        let v_h = if v_h > T::lit(0.0) { v_h } else { T::lit(0.0) };
        (Cosines { n_v: dot(n, v), n_l: dot(n, l), n_h: dot(n, h), v_h }, h)
    }
}

/// `x > 0`, false for NaN (the BRDF's support test).
#[inline(always)]
pub(crate) fn positive<T: Real>(x: T) -> bool {
    x > T::lit(0.0)
}

#[inline(always)]
pub(crate) fn dot<T: Real>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The specular term `D·F·G / (4 n·v n·l)` of the cosines (0 unless n·v > 0 and n·l > 0);
/// `roughness` is used as given (see [`clamp_roughness`]).
#[inline]
pub fn specular<T: Real>(c: Cosines<T>, roughness: T) -> T {
    if !positive(c.n_v) || !positive(c.n_l) {
        return T::lit(0.0);
    }
    let d = ggx_d(c.n_h, roughness);
    let f = fresnel(c.v_h);
    let g = g1(c.n_v, roughness) * g1(c.n_l, roughness);
    d * f * g / (T::lit(4.0) * c.n_v * c.n_l)
}

/// An orthonormal frame; `n` is the local z axis.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub t: Vec3,
    pub b: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// A frame around `n` (unit) whose x axis is `tangent` made orthogonal to `n`; falls back to
    /// an arbitrary tangent when `tangent` is (nearly) parallel to `n` or zero.
    pub fn new(n: Vec3, tangent: Vec3) -> Self {
        let t = tangent - n * n.dot(tangent);
        let t = if t.length_squared() > 1e-12 { t.normalize() } else { Self::from_normal(n).t };
        Frame { t, b: n.cross(t), n }
    }
    /// A frame around `n` with an arbitrary (but deterministic) tangent (Duff et al. 2017).
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let bb = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { t, b: bb, n }
    }
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

/// A sampled incoming direction.
#[derive(Clone, Copy, Debug)]
pub struct BrdfSample {
    /// Direction in the local frame.
    pub wi: Vec3,
    /// `f(wo, wi) · cos θi / pdf`.
    pub weight: Vec3,
    /// Solid-angle density of `wi`.
    pub pdf: f32,
}

/// The Karis BRDF at one point: linear albedo and perceptual roughness r.
#[derive(Clone, Copy, Debug)]
pub struct Karis {
    pub albedo: Vec3,
    pub roughness: f32,
    /// 1 normally; 0 turns the specular lobe off (validation against purely diffuse renders).
    pub specular_weight: f32,
}

#[inline]
fn luminance(c: Vec3) -> f32 {
    psc_base::color::luminance(c.to_array())
}

impl Karis {
    pub fn new(albedo: Vec3, roughness: f32) -> Self {
        Karis { albedo: albedo.max(Vec3::ZERO), roughness: clamp_roughness(roughness), specular_weight: 1.0 }
    }

    /// Lambertian only (validation): the specular lobe switched off.
    pub fn diffuse_only(mut self) -> Self {
        self.specular_weight = 0.0;
        self
    }

    /// The specular term `D·F·G / (4 n·v n·l)` alone (scalar: F0 is grey).
    pub fn specular(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 || self.specular_weight == 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize();
        let v_h = wo.dot(h).max(0.0);
        let c = Cosines { n_v: wo.z, n_l: wi.z, n_h: h.z, v_h };
        // specular_weight is 1 here (0 returned above): the product is exact.
        self.specular_weight * specular(c, self.roughness)
    }

    /// `f(wo, wi)` (without the cosine).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        self.albedo * (1.0 / PI) + Vec3::splat(self.specular(wo, wi))
    }

    /// Probability of picking the specular lobe when sampling for `wo`.
    #[inline]
    fn specular_probability(&self, wo: Vec3) -> f32 {
        if self.specular_weight == 0.0 {
            return 0.0;
        }
        let s = fresnel(wo.z.max(0.0));
        let d = luminance(self.albedo);
        (s / (s + d)).clamp(0.1, 0.9)
    }

    /// Solid-angle pdf of [`Karis::sample`] producing `wi`.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let ps = self.specular_probability(wo);
        let diffuse = wi.z / PI;
        if ps == 0.0 {
            return diffuse;
        }
        let h = (wo + wi).normalize();
        let spec = ggx_d(h.z, self.roughness) * h.z / (4.0 * wo.dot(h).abs().max(1e-8));
        ps * spec + (1.0 - ps) * diffuse
    }

    /// `(f(wo, wi), pdf(wo, wi))` sharing the half-vector terms (what NEE and sampling need).
    #[inline]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        self.at(wo).eval_pdf(wi)
    }

    /// Sample `wi` for `wo`; `u_lobe` picks the lobe, `u` the direction. `None` when the sampled
    /// direction falls below the surface (that probability mass is simply lost).
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: [f32; 2]) -> Option<BrdfSample> {
        self.at(wo).sample(u_lobe, u)
    }

    /// The BRDF for one outgoing direction, with the terms that depend on `wo` alone (lobe
    /// probability, one Fresnel and one masking term) computed once for NEE and sampling.
    #[inline]
    pub fn at(&self, wo: Vec3) -> KarisWo {
        let a = self.roughness * self.roughness;
        let k = masking_k(self.roughness);
        KarisWo {
            wo,
            diffuse: self.albedo * (1.0 / PI),
            ps: if wo.z > 0.0 { self.specular_probability(wo) } else { 0.0 },
            a2: a * a,
            k,
            g1_wo: wo.z / (wo.z * (1.0 - k) + k),
            specular_weight: self.specular_weight,
        }
    }
}

/// [`Karis`] bound to an outgoing direction (see [`Karis::at`]); the same arithmetic as the
/// free functions [`ggx_d`], [`g1`] and [`fresnel`], so results are bit-identical.
#[derive(Clone, Copy, Debug)]
pub struct KarisWo {
    wo: Vec3,
    diffuse: Vec3,
    ps: f32,
    a2: f32,
    k: f32,
    g1_wo: f32,
    specular_weight: f32,
}

impl KarisWo {
    #[inline]
    fn ggx_d(&self, n_h: f32) -> f32 {
        let d = n_h * n_h * (self.a2 - 1.0) + 1.0;
        self.a2 / (PI * d * d)
    }

    /// `(f(wo, wi), pdf(wo, wi))`.
    #[inline]
    pub fn eval_pdf(&self, wi: Vec3) -> (Vec3, f32) {
        let wo = self.wo;
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let ps = self.ps;
        if ps == 0.0 {
            return (self.diffuse, wi.z / PI);
        }
        let h = (wo + wi).normalize();
        let v_h = wo.dot(h).max(0.0);
        let d = self.ggx_d(h.z);
        let g = self.g1_wo * (wi.z / (wi.z * (1.0 - self.k) + self.k));
        let spec = self.specular_weight * d * fresnel(v_h) * g / (4.0 * wo.z * wi.z);
        let pdf = ps * d * h.z / (4.0 * v_h.max(1e-8)) + (1.0 - ps) * wi.z / PI;
        (self.diffuse + Vec3::splat(spec), pdf)
    }

    /// See [`Karis::sample`].
    #[inline(always)]
    pub fn sample(&self, u_lobe: f32, u: [f32; 2]) -> Option<BrdfSample> {
        let wo = self.wo;
        if wo.z <= 0.0 {
            return None;
        }
        let wi = if u_lobe < self.ps {
            let a2 = self.a2;
            let cos2 = ((1.0 - u[0]) / (1.0 + (a2 - 1.0) * u[0])).clamp(0.0, 1.0);
            let cos_t = cos2.sqrt();
            let sin_t = (1.0 - cos2).max(0.0).sqrt();
            let (sin_p, cos_p) = (2.0 * PI * u[1]).sin_cos();
            let h = Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t);
            2.0 * wo.dot(h) * h - wo
        } else {
            let r = u[0].sqrt();
            let (sin_p, cos_p) = (2.0 * PI * u[1]).sin_cos();
            Vec3::new(r * cos_p, r * sin_p, (1.0 - u[0]).max(0.0).sqrt())
        };
        if wi.z <= 1e-7 {
            return None;
        }
        let (f, pdf) = self.eval_pdf(wi);
        if pdf.is_nan() || pdf <= 0.0 || !pdf.is_finite() {
            return None;
        }
        let weight = f * (wi.z / pdf);
        Some(BrdfSample { wi, weight, pdf })
    }
}
