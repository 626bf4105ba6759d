//! Emitters: one-sided area lights (triangles emitting along their winding normal, black on
//! both sides otherwise) and an equirectangular environment map with importance sampling.
//!
//! Environment convention (Mitsuba 3's `envmap`, y up): a direction d maps to
//! `u = atan2(d.x, −d.z) / 2π` (wrapped to [0, 1)) and `v = acos(d.y) / π`; image column = u·W,
//! row = v·H (row 0 = straight up). Lookups are nearest-texel (piecewise constant), matching the
//! sampling density exactly.

use std::f32::consts::PI;

use glam::Vec3;

use crate::scene::LightSource;

/// Discrete distribution over weights with a CDF.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    cdf: Vec<f32>,
    pub total: f32,
}

impl Distribution1D {
    pub fn new(weights: &[f32]) -> Self {
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        cdf.push(0.0);
        let mut acc = 0.0f64;
        for w in weights {
            acc += w.max(0.0) as f64;
            cdf.push(acc as f32);
        }
        let total = acc as f32;
        if total > 0.0 {
            for c in &mut cdf {
                *c /= total;
            }
        }
        Distribution1D { cdf, total }
    }
    pub fn len(&self) -> usize {
        self.cdf.len() - 1
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Probability of index `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }
    /// Index and the remapped uniform within that index's interval.
    #[inline]
    pub fn sample(&self, u: f32) -> (usize, f32) {
        let n = self.len();
        let mut i = self.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
        while self.pmf(i) <= 0.0 && i + 1 < n {
            i += 1;
        }
        let p = self.pmf(i);
        let r = if p > 0.0 { ((u - self.cdf[i]) / p).clamp(0.0, 0.999_999_9) } else { 0.5 };
        (i, r)
    }
}

/// One emitting triangle.
#[derive(Clone, Copy, Debug)]
pub struct EmitterTri {
    pub p0: Vec3,
    pub e1: Vec3,
    pub e2: Vec3,
    /// Unit emitting normal.
    pub n: Vec3,
    pub area: f32,
}

/// The area lights of a scene, with per-light triangle distributions.
#[derive(Clone, Debug)]
pub struct AreaLights {
    pub names: Vec<String>,
    pub tris: Vec<Vec<EmitterTri>>,
    pub tri_dist: Vec<Distribution1D>,
    pub areas: Vec<f32>,
}

/// A point sampled on a light.
pub struct LightPoint {
    pub p: Vec3,
    pub n: Vec3,
    /// Area density of the point given the light (1 / light area).
    pub pdf_area: f32,
}

impl AreaLights {
    pub fn new(lights: &[LightSource]) -> Self {
        let mut out = AreaLights { names: vec![], tris: vec![], tri_dist: vec![], areas: vec![] };
        for l in lights {
            let tris: Vec<EmitterTri> = l
                .triangles
                .iter()
                .filter_map(|t| {
                    let e1 = t[1] - t[0];
                    let e2 = t[2] - t[0];
                    let c = e1.cross(e2);
                    let area = 0.5 * c.length();
                    (area > 1e-12).then(|| EmitterTri { p0: t[0], e1, e2, n: c.normalize(), area })
                })
                .collect();
            let weights: Vec<f32> = tris.iter().map(|t| t.area).collect();
            out.areas.push(weights.iter().sum());
            out.tri_dist.push(Distribution1D::new(&weights));
            out.tris.push(tris);
            out.names.push(l.name.clone());
        }
        out
    }

    pub fn len(&self) -> usize {
        self.names.len()
    }
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Uniform point on light `k` (by area).
    #[inline(always)]
    pub fn sample(&self, k: usize, u_tri: f32, u: [f32; 2]) -> Option<LightPoint> {
        if self.tris[k].is_empty() {
            return None;
        }
        let (i, _) = self.tri_dist[k].sample(u_tri);
        let t = &self.tris[k][i];
        // Uniform barycentrics (b1, b2) = (su·u1, su·(1−u1)), su = √u0.
        let su = u[0].sqrt();
        let p = t.p0 + t.e1 * (su * u[1]) + t.e2 * (su * (1.0 - u[1]));
        Some(LightPoint { p, n: t.n, pdf_area: 1.0 / self.areas[k] })
    }
}

/// An equirectangular environment map (linear RGB) with an importance-sampling distribution.
#[derive(Clone, Debug)]
pub struct EnvMap {
    pub width: usize,
    pub height: usize,
    pub data: Vec<Vec3>,
    rows: Distribution1D,
    cols: Vec<Distribution1D>,
}

#[inline]
fn luminance(c: Vec3) -> f32 {
    psc_base::color::luminance(c.to_array())
}

impl EnvMap {
    pub fn new(width: usize, height: usize, data: Vec<Vec3>) -> Self {
        let mut row_w = Vec::with_capacity(height);
        let mut cols = Vec::with_capacity(height);
        for y in 0..height {
            let sin_t = (PI * (y as f32 + 0.5) / height as f32).sin();
            let w: Vec<f32> = (0..width).map(|x| luminance(data[y * width + x]).max(0.0) * sin_t + 1e-8).collect();
            let d = Distribution1D::new(&w);
            row_w.push(d.total);
            cols.push(d);
        }
        EnvMap { width, height, data, rows: Distribution1D::new(&row_w), cols }
    }

    #[inline]
    fn texel(&self, d: Vec3) -> (usize, usize, f32) {
        let mut u = d.x.atan2(-d.z) / (2.0 * PI);
        if u < 0.0 {
            u += 1.0;
        }
        let cos_t = d.y.clamp(-1.0, 1.0);
        let v = cos_t.acos() / PI;
        let x = ((u * self.width as f32) as usize).min(self.width - 1);
        let y = ((v * self.height as f32) as usize).min(self.height - 1);
        (x, y, (1.0 - cos_t * cos_t).max(0.0).sqrt())
    }

    /// Radiance arriving from direction `d` (unit, pointing away from the scene).
    pub fn eval(&self, d: Vec3) -> Vec3 {
        let (x, y, _) = self.texel(d);
        self.data[y * self.width + x]
    }

    /// Solid-angle density of [`EnvMap::sample`] producing `d`.
    pub fn pdf(&self, d: Vec3) -> f32 {
        let (x, y, sin_t) = self.texel(d);
        if sin_t <= 1e-6 {
            return 0.0;
        }
        let p = self.rows.pmf(y) * self.cols[y].pmf(x);
        p * (self.width * self.height) as f32 / (2.0 * PI * PI * sin_t)
    }

    /// A direction, its radiance and its solid-angle density.
    pub fn sample(&self, u: [f32; 2]) -> Option<(Vec3, Vec3, f32)> {
        let (y, ry) = self.rows.sample(u[0]);
        let (x, rx) = self.cols[y].sample(u[1]);
        let uu = (x as f32 + rx) / self.width as f32;
        let vv = (y as f32 + ry) / self.height as f32;
        let (phi, theta) = (2.0 * PI * uu, PI * vv);
        let sin_t = theta.sin();
        if sin_t <= 1e-6 {
            return None;
        }
        let d = Vec3::new(sin_t * phi.sin(), theta.cos(), -sin_t * phi.cos());
        let p = self.rows.pmf(y) * self.cols[y].pmf(x) * (self.width * self.height) as f32 / (2.0 * PI * PI * sin_t);
        Some((d, self.data[y * self.width + x], p))
    }
}
