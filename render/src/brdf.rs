//! The shading layer: the Karis microfacet BRDF exactly as the fit's shading layer uses it.
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

use glam::Vec3;
use std::f32::consts::PI;

/// Specular reflectance at normal incidence (Mitsuba `principled` with `specular = 0.625`).
pub const F0: f32 = 0.05;
/// Smallest roughness the BRDF accepts; smaller values are clamped (α = 4e-4).
pub const MIN_ROUGHNESS: f32 = 0.02;

/// Karis' spherical-Gaussian Schlick Fresnel, `v_h` = cos of the angle between v and h.
#[inline]
pub fn fresnel(v_h: f32) -> f32 {
    F0 + (1.0 - F0) * ((-5.55473 * v_h - 6.98316) * v_h).exp2()
}

/// GGX normal distribution with α = r².
#[inline]
pub fn ggx_d(n_h: f32, roughness: f32) -> f32 {
    let a = roughness * roughness;
    let a2 = a * a;
    let d = n_h * n_h * (a2 - 1.0) + 1.0;
    a2 / (PI * d * d)
}

/// Schlick-GGX masking for one direction with k = (r+1)²/8.
#[inline]
pub fn g1(x: f32, roughness: f32) -> f32 {
    let k = (roughness + 1.0) * (roughness + 1.0) / 8.0;
    x / (x * (1.0 - k) + k)
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
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl Karis {
    pub fn new(albedo: Vec3, roughness: f32) -> Self {
        let roughness = if roughness.is_finite() { roughness.clamp(MIN_ROUGHNESS, 1.0) } else { 1.0 };
        Karis { albedo: albedo.max(Vec3::ZERO), roughness, specular_weight: 1.0 }
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
        let d = ggx_d(h.z, self.roughness);
        let f = fresnel(v_h);
        let g = g1(wo.z, self.roughness) * g1(wi.z, self.roughness);
        self.specular_weight * d * f * g / (4.0 * wo.z * wi.z)
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
        let k = (self.roughness + 1.0) * (self.roughness + 1.0) / 8.0;
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
        if !(pdf > 0.0) || !pdf.is_finite() {
            return None;
        }
        let weight = f * (wi.z / pdf);
        Some(BrdfSample { wi, weight, pdf })
    }
}
