//! The differentiable shading layer: renders a part's crop from a graph, its parameters, the
//! UV transform φ, a per-RGB albedo scale and a part-wide roughness, and back-propagates a
//! gradient of the rendered image to all of them exactly.
//!
//! Per fit pixel: supersamples within the pixel's uv footprint (the count adapts to the
//! footprint's extent in texture space, so zooming the material out averages its detail as a
//! camera would instead of aliasing it), maps every sample through φ, evaluates the graph at all
//! samples of the part in one batch through its JIT kernel, rotates the tangent-space normal
//! into the pixel's frame the way the renderer does, shades it against the pixel's light grid
//! ([`crate::shading`]), averages the samples' linear values and encodes the average as sRGB of
//! `clamp(e·I, 0, 1)` with the view's RGB exposure `e` (per channel). The graph's own roughness map is replaced by
//! the part-wide value while fitting (as PhotoScene); its metallic channel is not used (the
//! BRDF is dielectric).
//!
//! The per-axis cap on the sample count ([`Sampling::max_per_axis`]: 4 in the fit, 2 in the
//! search) binds where a pattern is scaled finest. There the samples no longer resolve the
//! footprint, and the render keeps an aliasing residual: a fixed grain that the losses can take
//! for the photo's noise or fine texture. On dev_2's `walls_b` (beadboard at log-scale 4.25,
//! its fitted state re-scored by a one-iteration `--resume`), caps of 2, 4 and 16 per axis give
//! a loss of 0.0209, 0.0177 and 0.0188 and a statistics term of 0.0059, 0.0074 and 0.0087 (the
//! grain's spread). Measured and left out: caps of 8 (fit) and 4 (search). That wall left the
//! range end (twill at log-scale 1.41), but dev_2's fit took 1.8× as long, and no missed
//! target was met: texture contrast over the pixel median's (true geometry, input / novel / relit)
//! went from 0.53 / 0.42 / 0.73 to 0.54 / 0.51 / 0.67 on dev_2 and from 0.46 / 0.67 / 0.50 to
//! 0.44 / 0.79 / 0.52 on dev_3, and dev_2's lights from 0.1% to 36.5% off the truth's ratio.
//!
//! The backward pass seeds the fused adjoint kernel with the gradient of every sample's albedo
//! and normal, which returns the parameter gradient and the gradient with respect to each
//! sample's texture position; the latter flows into φ.

use glam::Vec3;
use psc_compiler::Channel;
use psc_render::image_io::linear_to_srgb;
use psc_runtime::kernel::Gradients;
use psc_runtime::library::Material;
use rayon::prelude::*;

use crate::error::FitError;
use crate::shading::LightSample;
use crate::uvmap::{normal_to_mesh, UvTransform};

/// Forward channel columns the layer reads.
const ALBEDO: usize = Channel::AlbedoR.index();
const NORMAL: usize = Channel::NormalX.index();
const CHANNEL_COUNT: usize = Channel::COUNT;
const _: () = assert!(Channel::AlbedoB.index() == ALBEDO + 2 && Channel::NormalZ.index() == NORMAL + 2);

/// One pixel of a part's crop that is fitted.
#[derive(Clone, Debug)]
pub struct FitPixel {
    /// Index into the crop (row-major).
    pub crop_index: u32,
    /// Mesh uv at the pixel centre and its footprint (d uv per crop pixel step in x and y).
    pub uv: [f32; 2],
    pub duv_dx: [f32; 2],
    pub duv_dy: [f32; 2],
    /// −1 where the mesh's bitangent is mirrored against normal × tangent.
    pub bitangent_sign: f32,
    /// Unit direction to the camera in the local frame (x = tangent, y = normal × tangent).
    pub wo_local: Vec3,
    pub light: LightSample,
}

/// Everything about one part in one view that stays fixed while its material is fitted.
pub struct PartView {
    /// Crop size in fit pixels; a fit pixel covers `factor`×`factor` photo pixels whose top-left
    /// photo pixel of the crop is `origin`.
    pub width: usize,
    pub height: usize,
    pub origin: [usize; 2],
    pub factor: usize,
    pub pixels: Vec<FitPixel>,
    /// Per crop pixel, how much it counts (0 outside the usable mask). Pixels clipped in the
    /// photo count like the others, for the pattern and for the colour statistics alike: the
    /// layer clips its render the same way (`clamp(e·I, 0, 1)`), so a candidate is compared
    /// with the photo as both would be recorded. Left out, they would leave a partly clipped
    /// part's darker pixels only, and its fitted albedo too dark (a selection on the value).
    pub weight: Vec<f32>,
    /// The photo, sRGB-encoded, per crop pixel (0 where the weight is 0).
    pub target: Vec<[f32; 3]>,
    /// The photo's linear values, per crop pixel.
    pub target_linear: Vec<[f32; 3]>,
    /// The view's RGB exposure: the factor per channel between a linear render and the photo
    /// (the light solve's, 1 before it).
    pub exposure: [f32; 3],
    /// The target's pixel noise at the crop's resolution: standard deviations of r, g, b and
    /// luma (sRGB). Zeros: a noise-free target.
    pub noise: [f32; 4],
    /// The factor (in (0, 1]) `noise` carries from the render-noise check
    /// ([`crate::render_noise`]): the fraction of what a photo-side noise estimator reads on
    /// this crop that is noise. The feature loss scales its own estimate by it. 1: all of it.
    pub noise_scale: f32,
    /// Per crop pixel, the face it lies on: a cluster of similar surface normals (see
    /// [`crate::targets`]). The statistics loss compares colours face by face, since how each
    /// face of a part is lit is the scene's to explain, not the material's. Empty: one face.
    pub faces: Vec<u8>,
}

/// How densely the layer samples a pixel's footprint.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sampling {
    /// Samples per unit of footprint extent in texture (tile) units, per axis.
    pub density: f32,
    /// At most this many samples per axis (the count per pixel is its square).
    pub max_per_axis: u32,
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling { density: 160.0, max_per_axis: 4 }
    }
}

/// The material being fitted, in natural units.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MaterialState {
    /// One value per parameter slot of the graph.
    pub params: Vec<f32>,
    pub uv: UvTransform,
    pub albedo_scale: [f32; 3],
    pub roughness: f32,
}

/// The gradient of a scalar loss with respect to a [`MaterialState`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Gradient {
    /// Per parameter slot (zero for discrete slots).
    pub params: Vec<f64>,
    /// With respect to θ, k, offset x, offset y.
    pub uv: [f64; 4],
    pub albedo_scale: [f64; 3],
    pub roughness: f64,
}

/// Buffers reused from call to call (one per thread that renders).
#[derive(Default)]
pub struct Workspace {
    /// Per pixel, its first sample (len = pixels + 1).
    first: Vec<u32>,
    mesh_uv: Vec<[f32; 2]>,
    u: Vec<f32>,
    v: Vec<f32>,
    columns: Vec<Vec<f32>>,
    seeds: Vec<Vec<f32>>,
    gradients: Gradients,
    /// Per fit pixel, the linear value before exposure.
    pub linear: Vec<[f32; 3]>,
    /// The rendered crop, sRGB-encoded (0 outside the fit pixels).
    pub image: Vec<[f32; 3]>,
}

impl Workspace {
    /// The mean of a forward channel over every sample of the last render.
    pub fn channel_mean(&self, channel: Channel) -> f32 {
        let col = &self.columns[channel.index()];
        (col.iter().map(|&x| f64::from(x)).sum::<f64>() / col.len().max(1) as f64) as f32
    }
}

/// Pixels per parallel work item; fixed so that sums are identical for any thread count.
const PIXEL_CHUNK: usize = 512;

impl PartView {
    pub fn total_weight(&self) -> f32 {
        self.weight.iter().sum()
    }

    /// A linear render value as the photo shows it: sRGB of the exposed value, clamped.
    #[inline]
    fn encode(&self, linear: [f32; 3]) -> [f32; 3] {
        [0, 1, 2].map(|c| linear_to_srgb(self.exposure[c] * linear[c]))
    }

    /// Renders `state` into `ws.image` (and `ws.linear`).
    pub fn render(
        &self,
        material: &Material,
        state: &MaterialState,
        sampling: Sampling,
        ws: &mut Workspace,
    ) -> Result<(), FitError> {
        self.layout(state, sampling, ws);
        material
            .kernel
            .eval_into(&state.params, &ws.u, &ws.v, &mut ws.columns)
            .map_err(|error| FitError::Kernel { graph: material.name().to_string(), error })?;
        let rot = state.uv.rotation.sin_cos();
        let cols = &ws.columns;
        let first = &ws.first;
        let linear: Vec<[f32; 3]> = self
            .pixels
            .par_iter()
            .enumerate()
            .map(|(p, px)| {
                let (a, b) = (first[p] as usize, first[p + 1] as usize);
                let inv = 1.0 / (b - a) as f32;
                let mut sum = [0.0f32; 3];
                for k in a..b {
                    let n = local_normal(column_triple(cols, NORMAL, k), rot, px);
                    let e = px.light.irradiance(n.normal);
                    for ((s, a), e) in sum.iter_mut().zip(column_triple(cols, ALBEDO, k)).zip(e) {
                        *s += a.max(0.0) * e;
                    }
                }
                let (spec, _) = px.light.specular(state.roughness);
                [0, 1, 2].map(|c| state.albedo_scale[c] * sum[c] * inv / std::f32::consts::PI + spec[c])
            })
            .collect();
        ws.image.clear();
        ws.image.resize(self.width * self.height, [0.0; 3]);
        for (px, l) in self.pixels.iter().zip(&linear) {
            ws.image[px.crop_index as usize] = self.encode(*l);
        }
        ws.linear = linear;
        Ok(())
    }

    /// The gradient of a loss with respect to `state`, given the loss's gradient with respect
    /// to the rendered crop (`d_image`, per crop pixel). Must follow [`Self::render`] of the
    /// same state with the same workspace.
    pub fn backward(
        &self,
        material: &Material,
        state: &MaterialState,
        ws: &mut Workspace,
        d_image: &[[f32; 3]],
    ) -> Result<Gradient, FitError> {
        let kernel_error = |error| FitError::Kernel { graph: material.name().to_string(), error };
        let rot = state.uv.rotation.sin_cos();
        let n_samples = ws.u.len();
        ws.seeds.resize_with(CHANNEL_COUNT, Vec::new);
        for s in ws.seeds.iter_mut() {
            s.clear();
            s.resize(n_samples, 0.0);
        }
        // Per pixel: the gradient with respect to its linear value, then per sample the seeds
        // for albedo and normal; per chunk the sums for albedo scale, roughness and θ (through
        // the normal rotation).
        let exposure = self.exposure;
        let (first, cols, linear) = (&ws.first, &ws.columns, &ws.linear);
        let mut seed_cols: Vec<&mut [f32]> = Vec::new();
        let mut rest: &mut [Vec<f32>] = &mut ws.seeds;
        while let Some((head, tail)) = rest.split_first_mut() {
            seed_cols.push(head.as_mut_slice());
            rest = tail;
        }
        let seed_chunks = chunk_seed_columns(seed_cols, first, PIXEL_CHUNK);
        let partials: Vec<[f64; 5]> = self
            .pixels
            .par_chunks(PIXEL_CHUNK)
            .zip(seed_chunks)
            .enumerate()
            .map(|(chunk, (pixels, mut seeds))| {
                let mut acc = [0.0f64; 5]; // albedo scale rgb, roughness, θ
                let base = first[chunk * PIXEL_CHUNK] as usize;
                for (q, px) in pixels.iter().enumerate() {
                    let p = chunk * PIXEL_CHUNK + q;
                    let d_lin: [f32; 3] = [0, 1, 2].map(|c| {
                        let x = exposure[c] * linear[p][c];
                        if x > 0.0 && x < 1.0 {
                            d_image[px.crop_index as usize][c] * srgb_slope(x) * exposure[c]
                        } else {
                            0.0
                        }
                    });
                    if d_lin == [0.0; 3] {
                        continue;
                    }
                    let (_, d_spec) = px.light.specular(state.roughness);
                    acc[3] += (0..3).map(|c| f64::from(d_lin[c] * d_spec[c])).sum::<f64>();
                    let (a, b) = (first[p] as usize, first[p + 1] as usize);
                    let w = 1.0 / ((b - a) as f32 * std::f32::consts::PI);
                    for k in a..b {
                        let raw = column_triple(cols, ALBEDO, k);
                        let albedo = raw.map(|x| x.max(0.0));
                        let tn = column_triple(cols, NORMAL, k);
                        let n = local_normal(tn, rot, px);
                        let g = [0, 1, 2].map(|c| d_lin[c] * w * state.albedo_scale[c] * albedo[c]);
                        let (e, d_n) = px.light.irradiance_grad(n.normal, g);
                        let s = k - base;
                        for c in 0..3 {
                            if raw[c] > 0.0 {
                                seeds[ALBEDO + c][s] = d_lin[c] * w * state.albedo_scale[c] * e[c];
                            }
                            acc[c] += f64::from(d_lin[c] * w * albedo[c] * e[c]);
                        }
                        if let Some(d_tn) = n.backprop(d_n, px) {
                            let d_tex = normal_from_mesh_grad(d_tn, rot);
                            seeds[NORMAL][s] = d_tex[0];
                            seeds[NORMAL + 1][s] = d_tex[1];
                            seeds[NORMAL + 2][s] = d_tex[2];
                            // ∂(mesh normal)/∂θ: x' = c nx + s ny → −s nx + c ny = y'; y' → −x'.
                            let m = n.mesh;
                            acc[4] += f64::from(d_tn[0] * m[1] - d_tn[1] * m[0]);
                        }
                    }
                }
                acc
            })
            .collect();
        let mut sums = [0.0f64; 5];
        for p in &partials {
            for (s, x) in sums.iter_mut().zip(p) {
                *s += x;
            }
        }
        let gradient_kernel = material.gradient_kernel().map_err(kernel_error)?;
        let seed_refs: Vec<&[f32]> = ws.seeds.iter().map(|s| s.as_slice()).collect();
        gradient_kernel
            .adjoint_into(&state.params, &ws.u, &ws.v, &seed_refs, &mut ws.gradients)
            .map_err(kernel_error)?;
        let scale = state.uv.scale();
        let mut d_uv = [0.0f64; 4];
        for k in 0..n_samples {
            UvTransform::backprop(ws.mesh_uv[k], scale, rot, [ws.gradients.d_u[k], ws.gradients.d_v[k]], &mut d_uv);
        }
        d_uv[0] += sums[4];
        Ok(Gradient {
            params: ws.gradients.d_params.clone(),
            uv: d_uv,
            albedo_scale: [sums[0], sums[1], sums[2]],
            roughness: sums[3],
        })
    }

    /// Sample positions for `state`'s scale: a jittered n×n grid over each pixel's footprint.
    fn layout(&self, state: &MaterialState, sampling: Sampling, ws: &mut Workspace) {
        let scale = state.uv.scale();
        let rot = state.uv.rotation.sin_cos();
        ws.first.clear();
        ws.mesh_uv.clear();
        ws.u.clear();
        ws.v.clear();
        for (p, px) in self.pixels.iter().enumerate() {
            ws.first.push(ws.mesh_uv.len() as u32);
            let n = samples_per_axis(px, scale, sampling);
            for sy in 0..n {
                for sx in 0..n {
                    let h = psc_base::mix64(((p as u64) << 16) ^ u64::from(sy * n + sx) ^ 0x5eed);
                    let jx = (h >> 40) as f32 / (1u64 << 24) as f32;
                    let jy = ((h >> 16) & 0xff_ffff) as f32 / (1u64 << 24) as f32;
                    let ox = (sx as f32 + if n > 1 { jx } else { 0.5 }) / n as f32 - 0.5;
                    let oy = (sy as f32 + if n > 1 { jy } else { 0.5 }) / n as f32 - 0.5;
                    let uv = [
                        px.uv[0] + px.duv_dx[0] * ox + px.duv_dy[0] * oy,
                        px.uv[1] + px.duv_dx[1] * ox + px.duv_dy[1] * oy,
                    ];
                    let st = state.uv.apply(uv, scale, rot);
                    ws.mesh_uv.push(uv);
                    ws.u.push(st[0]);
                    ws.v.push(st[1]);
                }
            }
        }
        ws.first.push(ws.mesh_uv.len() as u32);
    }

    /// The albedo scale that colour-matches the last render of `state` (in `ws`) to the photo:
    /// per channel, the median of the photo over the median of the render (linear values; where
    /// the photo's median is clipped, the least scale that renders it clipped).
    pub fn matched_albedo_scale(&self, state: &MaterialState, ws: &Workspace) -> [f32; 3] {
        let mut photo: [Vec<f32>; 3] = Default::default();
        let mut render: [Vec<f32>; 3] = Default::default();
        for (px, l) in self.pixels.iter().zip(&ws.linear) {
            if self.weight[px.crop_index as usize] <= 0.0 {
                continue;
            }
            let t = self.target_linear[px.crop_index as usize];
            for c in 0..3 {
                photo[c].push(t[c] / self.exposure[c]);
                render[c].push(l[c]);
            }
        }
        [0, 1, 2].map(|c| {
            let (p, r) = (crate::lighting::median(&mut photo[c]), crate::lighting::median(&mut render[c]));
            let s = if r > 1e-8 { state.albedo_scale[c] * p / r } else { state.albedo_scale[c] };
            if s.is_finite() {
                s.clamp(1.0 / 64.0, 64.0)
            } else {
                state.albedo_scale[c]
            }
        })
    }

    /// The albedo scale whose render matches the photo's mean sRGB value per channel (the
    /// weighted mean over the crop), from the last render of `state` in `ws`: the diffuse term
    /// is linear in the scale, so each channel is a monotone one-dimensional search (bisection
    /// on the log-scale) without evaluating the graph again.
    pub fn mean_matching_albedo_scale(&self, state: &MaterialState, ws: &Workspace) -> [f32; 3] {
        let total: f64 = self.pixels.iter().map(|px| f64::from(self.weight[px.crop_index as usize])).sum();
        if total <= 0.0 {
            return state.albedo_scale;
        }
        let target: [f64; 3] = [0, 1, 2].map(|c| {
            self.pixels
                .iter()
                .map(|px| {
                    let i = px.crop_index as usize;
                    f64::from(self.weight[i]) * f64::from(self.target[i][c])
                })
                .sum::<f64>()
                / total
        });
        // Per pixel: (weight, diffuse at scale 1, specular).
        let terms: Vec<(f32, [f32; 3], [f32; 3])> = self
            .pixels
            .iter()
            .zip(&ws.linear)
            .map(|(px, l)| {
                let (spec, _) = px.light.specular(state.roughness);
                let diffuse = [0, 1, 2].map(|c| {
                    if state.albedo_scale[c] > 0.0 {
                        (l[c] - spec[c]) / state.albedo_scale[c]
                    } else {
                        0.0
                    }
                });
                (self.weight[px.crop_index as usize], diffuse, spec)
            })
            .collect();
        [0, 1, 2].map(|c| {
            let mean_at = |s: f32| -> f64 {
                terms
                    .iter()
                    .map(|(w, d, sp)| f64::from(*w) * f64::from(linear_to_srgb(self.exposure[c] * (s * d[c] + sp[c]))))
                    .sum::<f64>()
                    / total
            };
            let (mut lo, mut hi) = ((1.0f32 / 64.0).ln(), 64.0f32.ln());
            if mean_at(lo.exp()) >= target[c] {
                return lo.exp();
            }
            if mean_at(hi.exp()) <= target[c] {
                return hi.exp();
            }
            for _ in 0..30 {
                let mid = 0.5 * (lo + hi);
                if mean_at(mid.exp()) < target[c] {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            (0.5 * (lo + hi)).exp()
        })
    }

    /// Turns the last render of `state` in `ws` into the render with albedo scale `scale`
    /// without evaluating the graph again (the diffuse term is linear in the scale).
    pub fn rescale(&self, state: &MaterialState, scale: [f32; 3], ws: &mut Workspace) {
        for (px, l) in self.pixels.iter().zip(ws.linear.iter_mut()) {
            let (spec, _) = px.light.specular(state.roughness);
            for c in 0..3 {
                let diffuse = if state.albedo_scale[c] > 0.0 { (l[c] - spec[c]) / state.albedo_scale[c] } else { 0.0 };
                l[c] = scale[c] * diffuse + spec[c];
            }
            ws.image[px.crop_index as usize] = self.encode(*l);
        }
    }

    /// Samples the layer takes for `state` (for reports and budgets).
    pub fn sample_count(&self, state: &MaterialState, sampling: Sampling) -> usize {
        let scale = state.uv.scale();
        self.pixels.iter().map(|px| samples_per_axis(px, scale, sampling).pow(2) as usize).sum()
    }
}

/// Per-axis sample count for a pixel: its footprint's larger extent in tile units times the
/// density, at least 1.
fn samples_per_axis(px: &FitPixel, scale: f32, sampling: Sampling) -> u32 {
    let len = |d: [f32; 2]| (d[0] * d[0] + d[1] * d[1]).sqrt();
    let extent = scale * len(px.duv_dx).max(len(px.duv_dy));
    let n = (extent * sampling.density).ceil();
    if n.is_finite() {
        (n as u32).clamp(1, sampling.max_per_axis.max(1))
    } else {
        1
    }
}

/// Splits the seed columns into per-chunk groups of mutable slices aligned with the pixel
/// chunks (each chunk owns its pixels' samples).
fn chunk_seed_columns<'a>(columns: Vec<&'a mut [f32]>, first: &[u32], chunk: usize) -> Vec<Vec<&'a mut [f32]>> {
    let pixels = first.len() - 1;
    let bounds: Vec<usize> = (0..pixels.div_ceil(chunk))
        .map(|c| first[((c + 1) * chunk).min(pixels)] as usize - first[c * chunk] as usize)
        .collect();
    let mut out: Vec<Vec<&mut [f32]>> = bounds.iter().map(|_| Vec::with_capacity(columns.len())).collect();
    for col in columns {
        let mut rest = col;
        for (c, &len) in bounds.iter().enumerate() {
            let (head, tail) = rest.split_at_mut(len);
            out[c].push(head);
            rest = tail;
        }
    }
    out
}

/// Three consecutive channel columns at sample `k`.
#[inline]
fn column_triple(cols: &[Vec<f32>], first: usize, k: usize) -> [f32; 3] {
    [cols[first][k], cols[first + 1][k], cols[first + 2][k]]
}

/// d sRGB / d linear at x in (0, 1).
#[inline]
fn srgb_slope(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92
    } else {
        1.055 / 2.4 * x.powf(1.0 / 2.4 - 1.0)
    }
}

/// A graph's tangent-space normal as the shading layer uses it.
struct LocalNormal {
    /// Unit normal in the pixel's local frame.
    normal: Vec3,
    /// The normal in mesh-uv tangent space before normalisation, or None when it was rejected
    /// (the renderer then shades with the unperturbed normal).
    mesh: [f32; 3],
    length: f32,
    accepted: bool,
}

/// Rotates `tn` from texture to mesh tangent space, mirrors it with the bitangent and
/// normalises it in the local frame (x = tangent, y = normal × tangent, z = normal), falling
/// back to z exactly where the renderer's `shading_frame` does: a normal that would face away
/// from the viewer or below the surface.
#[inline]
fn local_normal(tn: [f32; 3], rot: (f32, f32), px: &FitPixel) -> LocalNormal {
    let mesh = normal_to_mesh(tn, rot);
    if mesh == [0.0, 0.0, 1.0] {
        return LocalNormal { normal: Vec3::Z, mesh, length: 1.0, accepted: false };
    }
    let m = Vec3::new(mesh[0], mesh[1] * px.bitangent_sign, mesh[2]);
    let length = m.length();
    let ok = length > 0.0 && length.is_finite();
    let n = if ok { m / length } else { Vec3::ZERO };
    let wo = px.wo_local;
    if ok && n.dot(wo) > 1e-4 && n.z > 0.0 {
        LocalNormal { normal: n, mesh, length, accepted: true }
    } else {
        LocalNormal { normal: Vec3::Z, mesh, length: 1.0, accepted: false }
    }
}

impl LocalNormal {
    /// The gradient with respect to the mesh tangent-space normal, given it with respect to
    /// the unit local normal; None where the normal was rejected (no dependence).
    #[inline]
    fn backprop(&self, d_n: Vec3, px: &FitPixel) -> Option<[f32; 3]> {
        if !self.accepted {
            return None;
        }
        let n = self.normal;
        let d_m = (d_n - n * n.dot(d_n)) / self.length;
        Some([d_m.x, d_m.y * px.bitangent_sign, d_m.z])
    }
}

/// The adjoint of [`normal_to_mesh`]: gradient with respect to the texture-space normal.
#[inline]
fn normal_from_mesh_grad(d: [f32; 3], (sin, cos): (f32, f32)) -> [f32; 3] {
    [cos * d[0] - sin * d[1], sin * d[0] + cos * d[1], d[2]]
}
