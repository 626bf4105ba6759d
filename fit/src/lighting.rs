//! Stage 3, the lighting the parts are fitted under.
//!
//! PhotoScene took its initial per-pixel lighting from a trained network; photoscene renders
//! it instead. Per view, the path tracer estimates an incoming-light grid around the coarse
//! model's surface at every `stride`-th pixel, one grid per emitter at unit radiance (the grids
//! are linear in the radiances, so a new radiance estimate recombines them without tracing).
//! The indirect light in the grids depends on the materials of the other parts: they are
//! rendered with the current estimate of every part's material.
//!
//! The initial radiances, read from no ground truth: every part gets its pixel-median photo
//! colour as albedo (roughness 0.7), the input views are rendered once per emitter at unit
//! radiance, and one common RGB radiance is chosen so that the rendered views match the photos
//! in the mean over the pixels where the photo's label and the model agree (and the photo is
//! not clipped). `--lights` replaces this with known radiances; the global solve of the next
//! stage refines it per light.

use glam::Vec3;
use psc_render::lightgrid::{compute_light_grid, LightGrid, LightGridOptions};
use psc_render::material::MaterialBinding;
use psc_render::{RenderOptions, Renderer};
use rayon::prelude::*;

use crate::error::FitError;
use crate::observe::{ViewObservation, NO_PART};
use crate::shading::{LightSample, BINS};

/// How the light grids are estimated.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GridSettings {
    /// One cell every `stride` pixels.
    pub stride: usize,
    pub samples_per_bin: u32,
    pub max_depth: u32,
}

impl Default for GridSettings {
    fn default() -> Self {
        GridSettings { stride: 4, samples_per_bin: 2, max_depth: 6 }
    }
}

/// The light grids of one view, one per emitter slot at unit radiance.
pub struct ViewGrids {
    pub grid: LightGrid,
}

/// Estimates the per-slot light grids of every view with the renderer's current materials.
pub fn view_grids(
    renderer: &Renderer,
    views: &[ViewObservation],
    settings: GridSettings,
    seed: u64,
) -> Result<Vec<ViewGrids>, FitError> {
    views
        .iter()
        .enumerate()
        .map(|(v, obs)| {
            let opts = LightGridOptions {
                stride: settings.stride,
                samples_per_bin: settings.samples_per_bin,
                seed: psc_base::mix64(seed ^ (v as u64) << 8),
                max_depth: settings.max_depth,
                per_light: true,
                ..Default::default()
            };
            Ok(ViewGrids { grid: compute_light_grid(renderer, &obs.camera, &opts)? })
        })
        .collect()
}

/// A view's light grid combined for given radiances and precomputed for shading.
pub struct ShadingGrid {
    width: usize,
    height: usize,
    stride: usize,
    /// Per cell the part it sees (index into part names) or [`NO_PART`].
    part: Vec<u32>,
    cells: Vec<Option<LightSample>>,
}

impl ShadingGrid {
    /// `radiance[k]` is the RGB radiance of slot k (the grid's per-light order).
    pub fn new(grids: &ViewGrids, radiance: &[[f32; 3]], camera_position: Vec3) -> ShadingGrid {
        let g = &grids.grid;
        let cells = (0..g.grid_width * g.grid_height)
            .into_par_iter()
            .map(|c| {
                if g.valid[c] == 0 {
                    return None;
                }
                let mut bins = [[0.0f32; 3]; BINS];
                for (k, (_, data)) in g.per_slot.iter().enumerate() {
                    let r = radiance.get(k).copied().unwrap_or([0.0; 3]);
                    for (b, out) in bins.iter_mut().enumerate() {
                        let o = (c * BINS + b) * 3;
                        for ch in 0..3 {
                            out[ch] += r[ch] * data[o + ch];
                        }
                    }
                }
                let (n, t) = (Vec3::from(g.normal[c]), Vec3::from(g.tangent[c]));
                let wo = (camera_position - Vec3::from(g.position[c])).normalize_or_zero();
                let wo_local = Vec3::new(wo.dot(t), wo.dot(n.cross(t)), wo.dot(n));
                Some(LightSample::new(&bins, wo_local))
            })
            .collect();
        let part = g
            .part_id
            .iter()
            .zip(&g.valid)
            .map(|(&p, &v)| if v != 0 && p > 0 { p as u32 - 1 } else { NO_PART })
            .collect();
        ShadingGrid { width: g.grid_width, height: g.grid_height, stride: g.stride, part, cells }
    }

    /// The lighting at continuous model raster position (x, y) on `part`: bilinear between
    /// the surrounding cells that see the same part, else the nearest such cell within two
    /// cells; None when there is none.
    pub fn at(&self, x: f32, y: f32, part: u32) -> Option<LightSample> {
        let s = self.stride as f32;
        // Cell (gx, gy) is centred on raster (gx·s + s/2 + 0.5, ...), clamped to the image.
        let fx = (x - 0.5 - (self.stride / 2) as f32) / s;
        let fy = (y - 0.5 - (self.stride / 2) as f32) / s;
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        let mut picked: Vec<(&LightSample, f32)> = Vec::with_capacity(4);
        for (dx, dy, w) in
            [(0, 0, (1.0 - tx) * (1.0 - ty)), (1, 0, tx * (1.0 - ty)), (0, 1, (1.0 - tx) * ty), (1, 1, tx * ty)]
        {
            if let Some(cell) = self.cell(x0 as i64 + dx, y0 as i64 + dy, part) {
                if w > 0.0 {
                    picked.push((cell, w));
                }
            }
        }
        let total: f32 = picked.iter().map(|p| p.1).sum();
        if total > 1e-6 {
            let samples: Vec<&LightSample> = picked.iter().map(|p| p.0).collect();
            let weights: Vec<f32> = picked.iter().map(|p| p.1 / total).collect();
            return Some(LightSample::blend(&samples, &weights));
        }
        let (cx, cy) = (fx.round() as i64, fy.round() as i64);
        let mut best: Option<(&LightSample, i64)> = None;
        for dy in -2..=2i64 {
            for dx in -2..=2i64 {
                if let Some(cell) = self.cell(cx + dx, cy + dy, part) {
                    let d = dx * dx + dy * dy;
                    if best.is_none_or(|b| d < b.1) {
                        best = Some((cell, d));
                    }
                }
            }
        }
        best.map(|b| b.0.clone())
    }

    fn cell(&self, gx: i64, gy: i64, part: u32) -> Option<&LightSample> {
        if gx < 0 || gy < 0 || gx as usize >= self.width || gy as usize >= self.height {
            return None;
        }
        let c = gy as usize * self.width + gx as usize;
        if self.part[c] != part {
            return None;
        }
        self.cells[c].as_ref()
    }
}

/// The median of each channel of the photo's linear values over pixels labelled `part` (or
/// seen on it by the model where a view has no labels) and not clipped, over all views; None
/// when no such pixel exists.
pub fn pixel_median(views: &[ViewObservation], part: u32) -> Option<[f32; 3]> {
    let mut values: [Vec<f32>; 3] = Default::default();
    for obs in views {
        let labels = obs.labels.as_ref().unwrap_or(&obs.geo.part);
        for (i, &l) in labels.iter().enumerate() {
            if l == part && !obs.photo.clipped(i) {
                for (v, x) in values.iter_mut().zip(obs.photo.linear[i]) {
                    v.push(x);
                }
            }
        }
    }
    if values[0].is_empty() {
        return None;
    }
    Some([0, 1, 2].map(|c| median(&mut values[c])))
}

pub fn median(v: &mut [f32]) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f32::total_cmp);
    *m
}

/// Materials for the initial light estimate: each part's pixel-median colour, roughness 0.7
/// (parts no view shows: grey 0.5).
pub fn median_materials(views: &[ViewObservation], n_parts: usize) -> Vec<MaterialBinding> {
    (0..n_parts as u32).map(|p| MaterialBinding::constant(pixel_median(views, p).unwrap_or([0.5; 3]), 0.7)).collect()
}

/// Samples per pixel of the per-emitter renders: the initial estimate's, and each of the light
/// solve's two estimates (`refit::solve_lights`; what more samples did to the solve and to the
/// fits: `light_solve`'s module docs).
pub const ESTIMATE_SPP: u32 = 16;

/// Unit-radiance images of every emitter slot in every view, at the views' sizes:
/// `[view][slot][pixel]`.
pub type UnitRenders = Vec<Vec<Vec<[f32; 3]>>>;

/// Per-view, per-slot renders at unit radiance with the renderer's materials: `[view][slot]`.
pub fn unit_renders(renderer: &Renderer, views: &[ViewObservation], seed: u64) -> Result<UnitRenders, FitError> {
    unit_renders_at(renderer, views, seed, ESTIMATE_SPP)
}

/// [`unit_renders`] at `spp` samples per pixel.
pub fn unit_renders_at(
    renderer: &Renderer,
    views: &[ViewObservation],
    seed: u64,
    spp: u32,
) -> Result<UnitRenders, FitError> {
    views
        .iter()
        .map(|obs| {
            let opts = RenderOptions {
                width: obs.camera.width,
                height: obs.camera.height,
                spp,
                seed,
                per_light: true,
                ..Default::default()
            };
            let out = renderer.render(&obs.camera, &opts)?;
            Ok(out.per_light.into_iter().map(|(_, img)| img).collect())
        })
        .collect()
}

/// One common RGB radiance for every slot, matching the photos' mean (see the module docs).
/// Returns the radiance and the number of pixels it was estimated from.
pub fn common_radiance(views: &[ViewObservation], renders: &UnitRenders) -> Result<([f32; 3], usize), FitError> {
    let mut photo = [0.0f64; 3];
    let mut rendered = [0.0f64; 3];
    let mut count = 0usize;
    for (obs, slots) in views.iter().zip(renders) {
        for i in 0..obs.pixels() {
            let part = obs.geo.part[i];
            let label = obs.labels.as_ref().map_or(part, |l| l[i]);
            if part == NO_PART || label != part || obs.photo.clipped(i) || obs.geo.on_edge(i, 0.05) {
                continue;
            }
            count += 1;
            for c in 0..3 {
                photo[c] += f64::from(obs.photo.linear[i][c]);
                rendered[c] += slots.iter().map(|s| f64::from(s[i][c])).sum::<f64>();
            }
        }
    }
    if count < 100 || rendered.iter().any(|&r| r.is_nan() || r <= 0.0) {
        return Err(FitError::Input(format!(
            "cannot estimate the light: only {count} photo pixels agree with the model and receive light \
             (give --lights with known radiances)"
        )));
    }
    Ok(([0, 1, 2].map(|c| (photo[c] / rendered[c]) as f32), count))
}
