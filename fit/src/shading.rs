//! The shading layer's lighting half: a pixel's incoming-light grid, precomputed so that the
//! Karis BRDF (`psc_render::brdf`, the renderer's) can be integrated against it for any normal
//! and roughness in a few hundred flops, with exact derivatives.
//!
//! The grid holds the mean radiance `L_b` of each of 8 θ × 16 φ bins of the hemisphere around
//! the unperturbed normal z (see `psc_render::lightgrid`). The shaded value is
//!
//! `I = albedo/π · E(n) + S(r)`, with `E(n) = Σ_b max(n·m_b, 0) L_b` and
//! `S(r) = Σ_b spec(wo, l_b, r) (z·l_b) L_b ω_b`,
//!
//! where `m_b = ∫_bin l dω` is the bin's first moment (so `E` is the exact integral of the
//! clamped cosine over every bin that lies wholly above the perturbed normal's horizon),
//! `l_b` the bin's central direction and `ω_b` its solid angle. The specular lobe is evaluated
//! at the unperturbed normal: F0 is 0.05, so it is a small part of the signal, and the grid's
//! bins are far wider than a glossy lobe anyway. Roughness is part-wide while fitting, so
//! `S` is tabulated over [`ROUGHNESS_STEPS`] roughness values and interpolated linearly.
//!
//! `E(n)` is evaluated without touching most bins: with the full linear sum
//! `C = Σ_b m_b ⊗ L_b`, `E(n) = C n − Σ_{b: n·m_b < 0} (n·m_b) L_b`, and the bins below a tilted
//! normal's horizon form, in each polar row, a short arc of azimuths around the direction
//! opposite the tilt, fewer the higher the row. The arcs are walked outward from their centre
//! from the horizon row upwards until a row has none. An unperturbed normal costs nine
//! multiply-adds, a normal tilted by 30° about a dozen bins.

use std::f32::consts::PI;
use std::sync::OnceLock;

use glam::Vec3;
use psc_render::brdf::{Karis, MIN_ROUGHNESS};
use psc_render::lightgrid::{bin_direction, bin_solid_angle, GRID_PHI_BINS, GRID_THETA_BINS};

pub const ROWS: usize = GRID_THETA_BINS;
pub const COLS: usize = GRID_PHI_BINS;
pub const BINS: usize = ROWS * COLS;
/// Roughness values the specular term is tabulated at, evenly spaced over [MIN_ROUGHNESS, 1].
pub const ROUGHNESS_STEPS: usize = 16;

/// The roughness of table entry `j`.
pub fn table_roughness(j: usize) -> f32 {
    MIN_ROUGHNESS + (1.0 - MIN_ROUGHNESS) * j as f32 / (ROUGHNESS_STEPS - 1) as f32
}

/// Bin geometry shared by every pixel.
struct BinGeometry {
    /// First moment ∫_bin l dω.
    moment: [Vec3; BINS],
    /// Central direction.
    centre: [Vec3; BINS],
    /// Solid angle.
    omega: [f32; BINS],
}

fn bins() -> &'static BinGeometry {
    static GEOMETRY: OnceLock<BinGeometry> = OnceLock::new();
    GEOMETRY.get_or_init(|| {
        let dt = (PI / 2.0) / ROWS as f32;
        let dp = 2.0 * PI / COLS as f32;
        let mut g = BinGeometry { moment: [Vec3::ZERO; BINS], centre: [Vec3::ZERO; BINS], omega: [0.0; BINS] };
        for i in 0..ROWS {
            let (t0, t1) = (i as f64 * dt as f64, (i + 1) as f64 * dt as f64);
            // ∫ sin²θ dθ and ∫ sinθ cosθ dθ over the row.
            let s2 = (t1 / 2.0 - (2.0 * t1).sin() / 4.0) - (t0 / 2.0 - (2.0 * t0).sin() / 4.0);
            let sc = (t1.sin().powi(2) - t0.sin().powi(2)) / 2.0;
            for j in 0..COLS {
                let (p0, p1) = (j as f64 * dp as f64, (j + 1) as f64 * dp as f64);
                let b = i * COLS + j;
                g.moment[b] = Vec3::new(
                    (s2 * (p1.sin() - p0.sin())) as f32,
                    (s2 * (p0.cos() - p1.cos())) as f32,
                    (sc * (p1 - p0)) as f32,
                );
                g.centre[b] = bin_direction(i, j, [0.5, 0.5]);
                g.omega[b] = bin_solid_angle(i);
            }
        }
        g
    })
}

/// The lighting of one grid cell or pixel, ready for shading.
#[derive(Clone, Debug)]
pub struct LightSample {
    /// `C = Σ_b m_b ⊗ L_b`: per channel, a vector over the normal's axes.
    linear: [Vec3; 3],
    /// `L_b` per bin, RGB.
    radiance: Box<[[f32; 3]; BINS]>,
    /// `S(r_j)` per table roughness, RGB.
    specular: [[f32; 3]; ROUGHNESS_STEPS],
}

impl LightSample {
    /// From the mean radiance of every bin (`radiance[b]`, b = row·16 + column) and the
    /// direction to the viewer in the grid's local frame.
    pub fn new(radiance: &[[f32; 3]; BINS], wo_local: Vec3) -> LightSample {
        let g = bins();
        let mut linear = [Vec3::ZERO; 3];
        for (moment, l) in g.moment.iter().zip(radiance) {
            for (acc, x) in linear.iter_mut().zip(l) {
                *acc += *moment * *x;
            }
        }
        let mut specular = [[0.0f32; 3]; ROUGHNESS_STEPS];
        let wo =
            if wo_local.z > 1e-4 { wo_local.normalize() } else { Vec3::new(wo_local.x, wo_local.y, 1e-4).normalize() };
        for (j, s) in specular.iter_mut().enumerate() {
            let brdf = Karis::new(Vec3::ZERO, table_roughness(j));
            for ((&l, &omega), r) in g.centre.iter().zip(&g.omega).zip(radiance) {
                let k = brdf.specular(wo, l) * l.z * omega;
                for (acc, x) in s.iter_mut().zip(r) {
                    *acc += k * x;
                }
            }
        }
        LightSample { linear, radiance: Box::new(*radiance), specular }
    }

    /// `Σ weights[i] · samples[i]` (bilinear interpolation between grid cells; everything here
    /// is linear in the radiance).
    pub fn blend(samples: &[&LightSample], weights: &[f32]) -> LightSample {
        let mut out = LightSample {
            linear: [Vec3::ZERO; 3],
            radiance: Box::new([[0.0; 3]; BINS]),
            specular: [[0.0; 3]; ROUGHNESS_STEPS],
        };
        for (s, &w) in samples.iter().zip(weights) {
            for c in 0..3 {
                out.linear[c] += s.linear[c] * w;
            }
            for (o, r) in out.radiance.iter_mut().zip(s.radiance.iter()) {
                for c in 0..3 {
                    o[c] += r[c] * w;
                }
            }
            for (o, r) in out.specular.iter_mut().zip(&s.specular) {
                for c in 0..3 {
                    o[c] += r[c] * w;
                }
            }
        }
        out
    }

    /// `E(n)` per channel for a unit normal `n` in the local frame.
    #[inline]
    pub fn irradiance(&self, n: Vec3) -> [f32; 3] {
        let mut e = [self.linear[0].dot(n), self.linear[1].dot(n), self.linear[2].dot(n)];
        for_clipped_bins(n, |b, c| {
            let l = &self.radiance[b];
            e[0] -= c * l[0];
            e[1] -= c * l[1];
            e[2] -= c * l[2];
        });
        e
    }

    /// `E(n)` and `Σ_c g_c ∂E_c/∂n` for channel weights `g` (the adjoint of [`Self::irradiance`]).
    #[inline]
    pub fn irradiance_grad(&self, n: Vec3, g: [f32; 3]) -> ([f32; 3], Vec3) {
        let mut e = [self.linear[0].dot(n), self.linear[1].dot(n), self.linear[2].dot(n)];
        let mut d = self.linear[0] * g[0] + self.linear[1] * g[1] + self.linear[2] * g[2];
        let geo = bins();
        for_clipped_bins(n, |b, c| {
            let l = &self.radiance[b];
            e[0] -= c * l[0];
            e[1] -= c * l[1];
            e[2] -= c * l[2];
            d -= geo.moment[b] * (g[0] * l[0] + g[1] * l[1] + g[2] * l[2]);
        });
        (e, d)
    }

    /// `S(r)` per channel and `dS/dr` (linear interpolation in the table).
    #[inline]
    pub fn specular(&self, roughness: f32) -> ([f32; 3], [f32; 3]) {
        let step = (1.0 - MIN_ROUGHNESS) / (ROUGHNESS_STEPS - 1) as f32;
        let x = ((roughness - MIN_ROUGHNESS) / step).clamp(0.0, (ROUGHNESS_STEPS - 1) as f32);
        let j = (x as usize).min(ROUGHNESS_STEPS - 2);
        let f = x - j as f32;
        let (a, b) = (self.specular[j], self.specular[j + 1]);
        let inside = roughness > MIN_ROUGHNESS && roughness < 1.0;
        let slope = |c: usize| if inside { (b[c] - a[c]) / step } else { 0.0 };
        ([0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * f), [0, 1, 2].map(slope))
    }
}

/// Calls `f(bin, n·m_b)` for every bin with `n·m_b < 0` (below the horizon of `n`), walking,
/// from the horizon row upwards, the arc of azimuths around the direction opposite the tilt
/// until a row has no such bin (rows nearer the pole have fewer: their moments point higher).
#[inline]
fn for_clipped_bins(n: Vec3, mut f: impl FnMut(usize, f32)) {
    if n.x == 0.0 && n.y == 0.0 {
        return;
    }
    let g = bins();
    let centre = opposite_column(n);
    for i in (0..ROWS).rev() {
        let row = i * COLS;
        let c = n.dot(g.moment[row + centre]);
        if c >= 0.0 {
            // The neighbours of the centre column may still dip below when the opposite
            // azimuth falls between two centres.
            let mut any = false;
            for j in [(centre + 1) % COLS, (centre + COLS - 1) % COLS] {
                let c = n.dot(g.moment[row + j]);
                if c < 0.0 {
                    f(row + j, c);
                    any = true;
                }
            }
            if !any {
                return;
            }
            continue;
        }
        f(row + centre, c);
        for step in [1usize, COLS - 1] {
            let mut j = (centre + step) % COLS;
            let mut walked = 1;
            while walked < COLS / 2 {
                let c = n.dot(g.moment[row + j]);
                if c >= 0.0 {
                    break;
                }
                f(row + j, c);
                j = (j + step) % COLS;
                walked += 1;
            }
        }
    }
}

/// The column whose centre azimuth is nearest the direction opposite the normal's tilt,
/// `atan2(−n.y, −n.x)`, without the arctangent or a search over the columns: the quadrant from
/// the signs, the column within it from comparing |y| with |x| tan 22.5°, |x| and |x| tan 67.5°
/// (the columns' edges). On an edge either column may be picked: [`for_clipped_bins`] also
/// looks at the neighbours of a centre that is not clipped, so both picks find the same bins.
#[inline]
fn opposite_column(n: Vec3) -> usize {
    const TAN_22_5: f32 = 0.414_213_57;
    const TAN_67_5: f32 = 2.414_213_6;
    const _: () = assert!(COLS == 16, "the quadrant split below assumes four columns per quadrant");
    let (x, y) = (-n.x, -n.y);
    let (ax, ay) = (x.abs(), y.abs());
    let within = usize::from(ay > TAN_22_5 * ax) + usize::from(ay > ax) + usize::from(ay > TAN_67_5 * ax);
    match (x >= 0.0, y >= 0.0) {
        (true, true) => within,
        (false, true) => 7 - within,
        (false, false) => 8 + within,
        (true, false) => 15 - within,
    }
}

/// The exact sum over every bin, for tests: `E(n) = Σ_b max(n·m_b, 0) L_b`.
pub fn irradiance_reference(radiance: &[[f32; 3]; BINS], n: Vec3) -> [f32; 3] {
    let g = bins();
    let mut e = [0.0f32; 3];
    for (moment, l) in g.moment.iter().zip(radiance) {
        let c = n.dot(*moment).max(0.0);
        for (acc, x) in e.iter_mut().zip(l) {
            *acc += c * x;
        }
    }
    e
}

/// The shaded linear value of one sample and its adjoint.
///
/// `I_c = s_c a_c E_c(n)/π + S_c(r)`; everything a sample needs besides the lighting.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceInput {
    pub albedo: [f32; 3],
    /// Unit normal in the local frame.
    pub normal: Vec3,
}

#[inline]
pub fn shade(light: &LightSample, s: &SurfaceInput, albedo_scale: [f32; 3], specular: [f32; 3]) -> [f32; 3] {
    let e = light.irradiance(s.normal);
    [0, 1, 2].map(|c| albedo_scale[c] * s.albedo[c] * e[c] / PI + specular[c])
}
