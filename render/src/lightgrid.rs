//! Per-pixel incoming-light grids: the lighting representation the fit's shading layer uses.
//!
//! For each grid cell (the pixel at `(gx·stride + stride/2, gy·stride + stride/2)`), the camera
//! ray through that pixel's centre finds a surface point; around it, in the local frame
//! (z = shading normal facing the camera, x = unit tangent along dp/du, y = z × x), the
//! hemisphere is split into [`GRID_THETA_BINS`] polar bins of equal angle over [0, π/2] and
//! [`GRID_PHI_BINS`] azimuth bins over [0, 2π) (φ from x towards y). Each bin holds the mean
//! incoming radiance over its solid angle. Light arriving straight from the area lights is
//! estimated by sampling points on every light (`direct_samples` per light, shadow rays tested,
//! each sample binned by its direction), everything else with `samples_per_bin` directions drawn
//! uniformly in solid angle inside the bin, each traced as a full path (remaining depth
//! `max_depth − 1`, so that shading the grid reproduces a `max_depth` render) whose first
//! segment ignores area lights. Small lamps are found by a handful of bin directions at best;
//! sampling them directly makes the direct light, most of a room's light, nearly noise-free.
//!
//! File format (`save`): `lightgrid.json` (header, below) and `lightgrid.bin` (little-endian
//! arrays at the byte offsets the header lists). Arrays: `radiance` f32 [gh, gw, θ, φ, 3]
//! (radiance with the render's light radiances), `valid` u8 [gh, gw] (1 = the cell sees the
//! model), `part_id` u16 [gh, gw] (G-buffer convention), `position`, `normal`, `tangent` f32
//! [gh, gw, 3], and with per-light grids one `radiance:<light>` array per light slot at unit
//! radiance (`radiance` = Σ radiance_k · `radiance:<k>`).

use std::f32::consts::PI;
use std::path::Path;

use glam::Vec3;
use psc_base::output::{Replace, StagedDir};
use psc_base::progress::{self, NoProgress, Progress};
use rayon::prelude::*;
use serde_json::json;

use crate::camera::Camera;
use crate::geometry::Traced;
use crate::image_io;
use crate::integrator::{run_in_pool, PathConfig, PathState, Renderer};
use crate::rng::Rng;
use crate::RenderError;

pub const GRID_THETA_BINS: usize = 8;
pub const GRID_PHI_BINS: usize = 16;
const BINS: usize = GRID_THETA_BINS * GRID_PHI_BINS;

#[derive(Clone, Debug)]
pub struct LightGridOptions {
    /// One cell every `stride` pixels in x and y (1 = every pixel).
    pub stride: usize,
    pub samples_per_bin: u32,
    /// Light samples per area light and cell for the direct light.
    pub direct_samples: u32,
    pub seed: u64,
    pub max_depth: u32,
    pub rr_depth: u32,
    pub threads: Option<usize>,
    /// Keep one grid per light slot.
    pub per_light: bool,
    /// Validation only: Lambertian bounces (the specular lobe off) along the grid's paths.
    pub diffuse_only: bool,
}

impl Default for LightGridOptions {
    fn default() -> Self {
        LightGridOptions {
            stride: 8,
            samples_per_bin: 4,
            direct_samples: 64,
            seed: 0,
            max_depth: 6,
            rr_depth: 5,
            threads: None,
            per_light: false,
            diffuse_only: false,
        }
    }
}

pub struct LightGrid {
    pub image_width: usize,
    pub image_height: usize,
    pub stride: usize,
    pub grid_width: usize,
    pub grid_height: usize,
    pub valid: Vec<u8>,
    pub part_id: Vec<u16>,
    pub position: Vec<[f32; 3]>,
    pub normal: Vec<[f32; 3]>,
    pub tangent: Vec<[f32; 3]>,
    /// [gh, gw, θ, φ, 3] with the renderer's light radiances.
    pub radiance: Vec<f32>,
    /// (slot name, [gh, gw, θ, φ, 3] at unit radiance), when requested.
    pub per_slot: Vec<(String, Vec<f32>)>,
}

/// Direction (local frame) for bin (i, j) and a uniform sample `u`: uniform in solid angle.
#[inline]
pub fn bin_direction(i: usize, j: usize, u: [f32; 2]) -> Vec3 {
    let c0 = (i as f32 * (PI / 2.0) / GRID_THETA_BINS as f32).cos();
    let c1 = ((i + 1) as f32 * (PI / 2.0) / GRID_THETA_BINS as f32).cos();
    let cos_t = c0 - u[0] * (c0 - c1);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = (j as f32 + u[1]) * 2.0 * PI / GRID_PHI_BINS as f32;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Solid angle of polar bin i (same for every φ bin).
pub fn bin_solid_angle(i: usize) -> f32 {
    let c0 = (i as f32 * (PI / 2.0) / GRID_THETA_BINS as f32).cos();
    let c1 = ((i + 1) as f32 * (PI / 2.0) / GRID_THETA_BINS as f32).cos();
    (c0 - c1) * 2.0 * PI / GRID_PHI_BINS as f32
}

struct Cell {
    valid: bool,
    part: u16,
    p: [f32; 3],
    n: [f32; 3],
    t: [f32; 3],
    /// [slot][bin] rgb
    slots: Vec<Vec3>,
}

/// Estimate the grid for `camera` (at its resolution).
pub fn compute_light_grid(r: &Renderer, camera: &Camera, opts: &LightGridOptions) -> Result<LightGrid, RenderError> {
    compute_light_grid_with_progress(r, camera, opts, &NoProgress)
}

/// [`compute_light_grid`], reporting the stage "light grid" in cells to `progress`.
pub fn compute_light_grid_with_progress(
    r: &Renderer,
    camera: &Camera,
    opts: &LightGridOptions,
    progress: &dyn Progress,
) -> Result<LightGrid, RenderError> {
    use psc_base::limits;
    if opts.stride == 0 || opts.samples_per_bin == 0 {
        return Err(RenderError::Invalid("light grid stride and samples per bin must be positive".into()));
    }
    if opts.max_depth < 2 {
        return Err(RenderError::Invalid(format!(
            "a light grid needs max_depth of at least 2 (incoming light at a surface is one bounce from the \
             camera), got {}",
            opts.max_depth
        )));
    }
    limits::check_count("light-grid paths per bin", opts.samples_per_bin as u64, limits::MAX_GRID_SAMPLES, "paths")?;
    let (w, h) = (camera.width, camera.height);
    let (gw, gh) = (w.div_ceil(opts.stride), h.div_ceil(opts.stride));
    let ns = r.n_slots();
    // Per cell: the slot values of every bin, the combined grid and the per-light copies, plus
    // the cell's geometry.
    let per_cell = (BINS * 12) as u64 * (ns as u64 + 1 + if opts.per_light { ns as u64 } else { 0 }) + 64;
    limits::check_elements(
        format!("light grid of {gw}x{gh} cells (stride {})", opts.stride),
        &[gw as u64, gh as u64],
        limits::MAX_PIXELS,
        "cells",
        per_cell,
    )?;
    let n_parts = r.part_names().len() as u32;
    let cfg = PathConfig {
        max_depth: opts.max_depth.saturating_sub(1),
        rr_depth: opts.rr_depth,
        per_light: opts.per_light,
        diffuse_only: opts.diffuse_only,
        skip_direct_emitters: true,
    };
    let work = || {
        (0..gw * gh)
            .into_par_iter()
            .map(|c| {
                let x = ((c % gw) * opts.stride + opts.stride / 2).min(w - 1);
                let y = ((c / gw) * opts.stride + opts.stride / 2).min(h - 1);
                let d = camera.direction(x as f32 + 0.5, y as f32 + 0.5);
                let mut cell = Cell {
                    valid: false,
                    part: 0,
                    p: [0.0; 3],
                    n: [0.0; 3],
                    t: [0.0; 3],
                    slots: vec![Vec3::ZERO; ns * BINS],
                };
                let hit = match r.geometry().trace(camera.position, d, f32::INFINITY) {
                    Traced::Surface(hit) => hit,
                    Traced::Emitter { light, .. } => {
                        cell.part = (n_parts + 1 + light) as u16;
                        progress.advance(1);
                        return cell;
                    }
                    Traced::Miss => {
                        progress.advance(1);
                        return cell;
                    }
                };
                let tn = r.materials()[hit.part as usize].eval(hit.uv).normal;
                let sf = r.geometry().shading_frame(&hit, -d, tn);
                let frame = crate::brdf::Frame::new(sf.frame.n, sf.tangent);
                let origin = r.geometry().offset(hit.p, sf.ng);
                let mut acc = vec![Vec3::ZERO; ns];
                let inv = 1.0 / opts.samples_per_bin as f32;
                for i in 0..GRID_THETA_BINS {
                    for j in 0..GRID_PHI_BINS {
                        let b = i * GRID_PHI_BINS + j;
                        acc.iter_mut().for_each(|a| *a = Vec3::ZERO);
                        for s in 0..opts.samples_per_bin {
                            let mut st = PathState {
                                rng: Rng::new(opts.seed, c as u64, (b as u64) << 32 | s as u64),
                                rays: 0,
                                out: &mut acc,
                            };
                            let u = st.rng.next_2d();
                            let dir = frame.to_world(bin_direction(i, j, u));
                            if dir.dot(sf.ng) > 0.0 {
                                r.li(origin, dir, &cfg, &mut st);
                            }
                        }
                        for (k, a) in acc.iter().enumerate() {
                            cell.slots[k * BINS + b] = *a * inv;
                        }
                    }
                }
                add_direct_light(r, origin, sf.ng, &frame, opts, c as u64, &mut cell.slots);
                cell.valid = true;
                cell.part = (hit.part + 1) as u16;
                cell.p = hit.p.to_array();
                cell.n = frame.n.to_array();
                cell.t = frame.t.to_array();
                progress.advance(1);
                cell
            })
            .collect()
    };
    let cells: Vec<Cell> =
        progress::stage(progress, "light grid", Some((gw * gh) as u64), "cells", || run_in_pool(opts.threads, work))?;
    let mut radiance = vec![0.0f32; gw * gh * BINS * 3];
    let mut per_slot: Vec<(String, Vec<f32>)> = if opts.per_light {
        r.slot_names().iter().map(|n| (n.clone(), vec![0.0f32; gw * gh * BINS * 3])).collect()
    } else {
        Vec::new()
    };
    for (c, cell) in cells.iter().enumerate() {
        for b in 0..BINS {
            let mut sum = Vec3::ZERO;
            for (k, radiance_k) in r.slot_radiance().iter().enumerate() {
                let v = cell.slots[k * BINS + b];
                sum += v * *radiance_k;
                if opts.per_light {
                    per_slot[k].1[(c * BINS + b) * 3..(c * BINS + b) * 3 + 3].copy_from_slice(&v.to_array());
                }
            }
            radiance[(c * BINS + b) * 3..(c * BINS + b) * 3 + 3].copy_from_slice(&sum.to_array());
        }
    }
    Ok(LightGrid {
        image_width: w,
        image_height: h,
        stride: opts.stride,
        grid_width: gw,
        grid_height: gh,
        valid: cells.iter().map(|c| c.valid as u8).collect(),
        part_id: cells.iter().map(|c| c.part).collect(),
        position: cells.iter().map(|c| c.p).collect(),
        normal: cells.iter().map(|c| c.n).collect(),
        tangent: cells.iter().map(|c| c.t).collect(),
        radiance,
        per_slot,
    })
}

/// The bin (row-major index) of a direction in the cell's local frame (z > 0).
#[inline]
pub fn bin_of(local: Vec3) -> usize {
    let theta = local.z.clamp(-1.0, 1.0).acos();
    let i = ((theta / (PI / 2.0) * GRID_THETA_BINS as f32) as usize).min(GRID_THETA_BINS - 1);
    let phi = local.y.atan2(local.x).rem_euclid(2.0 * PI);
    let j = ((phi / (2.0 * PI) * GRID_PHI_BINS as f32) as usize).min(GRID_PHI_BINS - 1);
    i * GRID_PHI_BINS + j
}

/// Adds the unit-radiance light of every area light to the bins it arrives through: the mean
/// over `direct_samples` light samples of 1/pdf (solid angle), per bin divided by the bin's
/// solid angle, is the bin's mean radiance from that light.
fn add_direct_light(
    r: &Renderer,
    origin: Vec3,
    ng: Vec3,
    frame: &crate::brdf::Frame,
    opts: &LightGridOptions,
    cell: u64,
    slots: &mut [Vec3],
) {
    let n = opts.direct_samples;
    if n == 0 {
        return;
    }
    for k in 0..r.lights().len() {
        let mut rng = Rng::new(opts.seed ^ 0xd1_5ec7, cell, k as u64);
        for _ in 0..n {
            let u_tri = rng.next_f32();
            let u = rng.next_2d();
            let Some(lp) = r.lights().sample(k, u_tri, u) else { continue };
            let to = lp.p - origin;
            let dist2 = to.length_squared();
            let dist = dist2.sqrt();
            let wi = to / dist;
            let cos_l = -lp.n.dot(wi);
            let local = frame.to_local(wi);
            if !(cos_l > 0.0 && wi.dot(ng) > 0.0 && local.z > 0.0) {
                continue;
            }
            if r.geometry().occluded(origin, wi, dist * (1.0 - 1e-4) - r.geometry().eps) {
                continue;
            }
            let pdf = lp.pdf_area * dist2 / cos_l;
            if !(pdf > 0.0 && pdf.is_finite()) {
                continue;
            }
            let b = bin_of(local);
            let omega = bin_solid_angle(b / GRID_PHI_BINS);
            slots[k * BINS + b] += Vec3::ONE / (pdf * n as f32 * omega);
        }
    }
}

impl LightGrid {
    /// Mean radiance of bin (θ i, φ j) at cell (gx, gy).
    pub fn at(&self, gx: usize, gy: usize, i: usize, j: usize) -> [f32; 3] {
        let o = (((gy * self.grid_width + gx) * GRID_THETA_BINS + i) * GRID_PHI_BINS + j) * 3;
        [self.radiance[o], self.radiance[o + 1], self.radiance[o + 2]]
    }

    /// Write `dir/lightgrid.json` and `dir/lightgrid.bin` (format in the module docs) into the
    /// existing folder `dir`; [`LightGrid::write_folder`] makes a new folder whole.
    pub fn save(&self, dir: &Path) -> Result<(), RenderError> {
        let (gw, gh) = (self.grid_width, self.grid_height);
        let mut bin: Vec<u8> = Vec::new();
        let mut arrays = Vec::new();
        let mut push = |name: &str, dtype: &str, shape: Vec<usize>, bytes: Vec<u8>, bin: &mut Vec<u8>| {
            while !bin.len().is_multiple_of(16) {
                bin.push(0);
            }
            arrays
                .push(json!({"name": name, "dtype": dtype, "shape": shape, "offset": bin.len(), "bytes": bytes.len()}));
            bin.extend_from_slice(&bytes);
        };
        let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let vec3s = |v: &[[f32; 3]]| v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let grid_shape = vec![gh, gw, GRID_THETA_BINS, GRID_PHI_BINS, 3];
        push("radiance", "f32le", grid_shape.clone(), f32s(&self.radiance), &mut bin);
        push("valid", "u8", vec![gh, gw], self.valid.clone(), &mut bin);
        push("part_id", "u16le", vec![gh, gw], self.part_id.iter().flat_map(|x| x.to_le_bytes()).collect(), &mut bin);
        push("position", "f32le", vec![gh, gw, 3], vec3s(&self.position), &mut bin);
        push("normal", "f32le", vec![gh, gw, 3], vec3s(&self.normal), &mut bin);
        push("tangent", "f32le", vec![gh, gw, 3], vec3s(&self.tangent), &mut bin);
        for (name, data) in &self.per_slot {
            push(&format!("radiance:{name}"), "f32le", grid_shape.clone(), f32s(data), &mut bin);
        }
        let header = json!({
            "format": "photoscene-lightgrid/1",
            "image_size": [self.image_width, self.image_height],
            "stride": self.stride,
            "grid_size": [gw, gh],
            "cell_pixel": "cell (gx, gy) is the pixel (min(gx*stride + stride/2, W-1), min(gy*stride + stride/2, H-1)), sampled at its centre",
            "theta_bins": GRID_THETA_BINS,
            "phi_bins": GRID_PHI_BINS,
            "bins": "theta bin i covers [i, i+1]·(π/2)/8 from the normal; phi bin j covers [j, j+1]·2π/16 from the tangent towards normal × tangent",
            "frame": "z = shading normal facing the camera, x = tangent (dp/du made orthogonal to z), y = z × x (world-space normal and tangent arrays below)",
            "value": "mean incoming radiance over the bin's solid angle (linear RGB)",
            "data_file": "lightgrid.bin",
            "arrays": arrays,
        });
        image_io::atomic_write(&dir.join("lightgrid.bin"), &bin)?;
        let text = serde_json::to_vec_pretty(&header).map_err(|e| RenderError::Invalid(e.to_string()))?;
        image_io::atomic_write(&dir.join("lightgrid.json"), &text)
    }

    /// Write the grid (see [`LightGrid::save`]) as the new folder `dest`, which appears whole or
    /// not at all; an existing `dest` is refused unless `replace` is `Replace::Yes`.
    pub fn write_folder(&self, dest: &Path, replace: Replace) -> Result<(), RenderError> {
        let staged = StagedDir::new(dest, replace)?;
        self.save(staged.path())?;
        staged.commit()?;
        Ok(())
    }
}
