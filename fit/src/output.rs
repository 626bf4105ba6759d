//! Writing a fit: `materials.json` (the `psc render --assign` format), `lights.json` (the
//! `--lights` format), `parts/<part>.json` (the decisions and measurements behind each part),
//! baked maps per part, the input views re-rendered (at each view's fitted exposure) beside
//! their photos, and `result.json`.
//!
//! The folder is written whole or not at all: everything goes into a temporary sibling that is
//! renamed into place at the end.

use std::path::{Path, PathBuf};

use psc_base::output::{Replace, StagedDir};
use psc_render::scene::{Scene, View};
use psc_render::{image_io, RenderOptions, Renderer};
use psc_runtime::bake::{bake, write_maps};
use psc_runtime::library::Library;
use psc_runtime::params::ParamSpace;
use rayon::prelude::*;
use serde_json::{json, Value};

use crate::error::FitError;
use crate::observe::Photo;
use crate::pipeline::{FitResult, PartResult, PreviousFit};
use crate::working::WorkingRaster;

/// What to write besides the JSON files.
#[derive(Clone, Debug)]
pub struct OutputOptions {
    /// Baked maps per part at this size (0: none).
    pub texture_size: usize,
    /// Samples per pixel of the re-rendered input views (0: none).
    pub render_spp: u32,
    /// Replace an existing output folder.
    pub force: bool,
    pub seed: u64,
    /// The command line that made the fit, for `result.json`.
    pub command: String,
}

impl Default for OutputOptions {
    /// What `psc fit` writes without options: 1024² maps, re-renders at 64 spp, seed 0.
    fn default() -> OutputOptions {
        OutputOptions { texture_size: 1024, render_spp: 64, force: false, seed: 0, command: String::new() }
    }
}

fn out_err(path: &Path, e: impl std::fmt::Display) -> FitError {
    FitError::Output(format!("{}: {e}", path.display()))
}

fn write_json(path: &Path, value: &Value) -> Result<(), FitError> {
    let mut text = serde_json::to_string_pretty(value).map_err(|e| out_err(path, e))?;
    text.push('\n');
    std::fs::write(path, text).map_err(|e| out_err(path, e))
}

/// One part of `materials.json`.
pub fn assignment_entry(library: &Library, p: &PartResult) -> Value {
    let info = &library.get(&p.graph).expect("fitted graphs come from the library").graph.info;
    let k = p.state.uv.scale();
    json!({
        "graph": p.graph,
        "params": ParamSpace::new(info).to_json(&p.state.params).expect("fitted vectors have the graph's length"),
        "uv_scale": [k, k],
        "uv_offset": p.state.uv.offset,
        "uv_rotation_deg": p.state.uv.rotation.to_degrees(),
        "albedo_scale": p.state.albedo_scale,
        "roughness_scale": p.roughness_scale,
    })
}

/// The lights file of a fit.
pub fn lights_json(result: &FitResult, scene: &Scene) -> Value {
    let n = scene.lights.len();
    let lights: Vec<Value> =
        scene.lights.iter().zip(&result.radiance).map(|(l, r)| json!({"name": l.name, "radiance_rgb": r})).collect();
    let mut v = json!({ "lights": lights });
    if let Some(env) = result.radiance.get(n) {
        v["environment_scale"] = json!(env);
    }
    v
}

fn part_json(p: &PartResult) -> Value {
    json!({
        "name": p.name,
        "status": p.status,
        "graph": p.graph,
        "top": p.top,
        "flat_check": p.flat_check,
        "view": p.view,
        "view_scores": p.view_scores,
        "alignment": { "warp": p.warp, "iou_initial": p.iou.map(|x| x.0), "iou": p.iou.map(|x| x.1) },
        "pixels": p.pixels,
        "uv": { "rotation_deg": p.state.uv.rotation.to_degrees(), "log_scale": p.state.uv.log_scale,
                "scale": p.state.uv.scale(), "offset": p.state.uv.offset },
        "albedo_scale": p.state.albedo_scale,
        "roughness": p.state.roughness,
        "roughness_scale": p.roughness_scale,
        "loss": p.loss,
        "loss_curve": p.history,
        "iterations": p.iterations,
        "uv_candidates": p.uv_candidates,
        "timings_s": p.timings,
    })
}

/// A file-system-safe stem for a part name.
pub fn file_stem(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect()
}

/// Writes the whole output folder `out` (see the module docs): built in a staging folder and
/// renamed into place, so that an error or an interrupt leaves `out` as it was.
pub fn write(
    out: &Path,
    scene: &Scene,
    library: &Library,
    result: &FitResult,
    options: &OutputOptions,
) -> Result<(), FitError> {
    let replace = if options.force { Replace::Yes } else { Replace::No };
    let staged = StagedDir::new(out, replace).map_err(|e| FitError::Output(e.to_string()))?;
    write_into(staged.path(), scene, library, result, options)?;
    staged.commit().map_err(|e| FitError::Output(e.to_string()))?;
    Ok(())
}

/// Reads the state a previous fit saved in `<dir>/result.json` (for `psc fit --resume` and `--refit-only`).
pub fn read_previous(dir: &Path) -> Result<PreviousFit, FitError> {
    let path = dir.join("result.json");
    // The shared reader: the JSON size cap, duplicate keys refused, a byte-order mark skipped.
    let value: Value = psc_runtime::json::read_file(&path).map_err(|e| {
        FitError::Input(format!("{e} (--resume and --refit-only start from the output of an earlier `psc fit`)"))
    })?;
    let state = value
        .get("fit_state")
        .cloned()
        .ok_or_else(|| FitError::Input(format!("{}: no `fit_state` (written by an older psc fit?)", path.display())))?;
    serde_json::from_value(state).map_err(|e| FitError::Input(format!("{}: fit_state: {e}", path.display())))
}

/// Writes the output files into `dir`, an existing (staging) folder.
pub fn write_into(
    dir: &Path,
    scene: &Scene,
    library: &Library,
    result: &FitResult,
    options: &OutputOptions,
) -> Result<(), FitError> {
    let parts_dir = dir.join("parts");
    std::fs::create_dir_all(&parts_dir).map_err(|e| out_err(&parts_dir, e))?;
    let mut assignment = serde_json::Map::new();
    for p in &result.parts {
        assignment.insert(p.name.clone(), assignment_entry(library, p));
        write_json(&parts_dir.join(format!("{}.json", file_stem(&p.name))), &part_json(p))?;
    }
    write_json(&dir.join("materials.json"), &json!({ "parts": assignment }))?;
    write_json(&dir.join("lights.json"), &lights_json(result, scene))?;
    if options.texture_size > 0 {
        // In parallel: encoding a part's PNG and EXR maps runs on one thread.
        result
            .parts
            .par_iter()
            .with_max_len(1)
            .try_for_each(|p| bake_part(library, p, &parts_dir.join(file_stem(&p.name)), options.texture_size))?;
    }
    let mut renders = Vec::new();
    if options.render_spp > 0 {
        renders = render_views(dir, scene, library, result, options)?;
    }
    let timings: serde_json::Map<String, Value> = result.timings.iter().map(|(k, v)| (k.clone(), json!(v))).collect();
    let exposure: serde_json::Map<String, Value> =
        scene.views.iter().enumerate().map(|(i, v)| (v.name.clone(), json!(view_exposure(result, i)))).collect();
    write_json(
        &dir.join("result.json"),
        &json!({
            "format": "photoscene-fit/1",
            "version": env!("CARGO_PKG_VERSION"),
            "command": options.command,
            // Absolute, so the folder can be rendered and reported from anywhere.
            "scene": std::fs::canonicalize(&scene.root).unwrap_or_else(|_| scene.root.clone()).display().to_string(),
            "lights": { "source": result.light_source, "slots": result.slot_names, "radiance_rgb": result.radiance,
                        "exposure_rgb": exposure, "solve_rounds": result.light_rounds },
            // Everything `--resume` and `--refit-only` start from, exactly (f32 values round-trip in JSON).
            "fit_state": PreviousFit { parts: result.parts.clone(), radiance: result.radiance.clone(),
                                       exposure: result.exposure.clone() },
            "parts": result.parts.iter().map(|p| json!({"name": p.name, "status": p.status, "graph": p.graph,
                "loss": p.loss.total, "view": p.view})).collect::<Vec<_>>(),
            "views": scene.views.iter().enumerate().map(|(i, v)| json!({"name": v.name,
                "photo_size": [v.width, v.height], "working_raster": view_raster(result, i, v)})).collect::<Vec<_>>(),
            "renders": renders.iter().map(|p| p.strip_prefix(dir).unwrap_or(p).display().to_string()).collect::<Vec<_>>(),
            "timings_s": timings,
        }),
    )
}

/// The raster the scene's view `index` was fitted at (the photo's own where the fit has none).
fn view_raster(result: &FitResult, index: usize, view: &View) -> WorkingRaster {
    result.rasters.get(index).copied().unwrap_or_else(|| WorkingRaster::for_photo(view.width, view.height, 0))
}

/// The RGB exposure of the scene's view `index` (1 where the fit has none).
fn view_exposure(result: &FitResult, index: usize) -> [f32; 3] {
    result.exposure.get(index).copied().unwrap_or([1.0; 3])
}

/// The part's material baked over one tile: the graph at its fitted parameters with the albedo
/// and roughness scales applied (what the renderer shades with, before the UV transform).
fn bake_part(library: &Library, p: &PartResult, dir: &Path, size: usize) -> Result<(), FitError> {
    let material = library.get(&p.graph).expect("fitted graphs come from the library");
    let eval = |params: &[f32], u: &[f32], v: &[f32]| material.kernel.eval(params, u, v).map_err(|e| e.to_string());
    let mut maps = bake(&eval, &p.state.params, size).map_err(|e| out_err(dir, e))?;
    for (i, a) in maps.albedo.iter_mut().enumerate() {
        *a = (*a * p.state.albedo_scale[i % 3]).max(0.0);
    }
    for r in maps.roughness.iter_mut() {
        *r = (*r * p.roughness_scale).clamp(0.0, 1.0);
    }
    write_maps(&maps, dir, "material").map_err(|e| out_err(dir, e))?;
    Ok(())
}

/// Each input view re-rendered by the path tracer with the fitted materials and lights, times
/// the view's fitted exposure (so it is comparable with the photo), and a side-by-side of
/// photo and render.
fn render_views(
    dir: &Path,
    scene: &Scene,
    library: &Library,
    result: &FitResult,
    options: &OutputOptions,
) -> Result<Vec<PathBuf>, FitError> {
    let renders_dir = dir.join("renders");
    std::fs::create_dir_all(&renders_dir).map_err(|e| out_err(&renders_dir, e))?;
    let renderer = Renderer::new(scene, result.bindings(library)?, &result.light_radiances(scene))?;
    let mut written = Vec::new();
    for (index, view) in scene.views.iter().enumerate() {
        // At the raster the view was fitted at, beside the photo at that raster.
        let raster = view_raster(result, index, view);
        let (w, h) = (raster.width, raster.height);
        let opts =
            RenderOptions { width: w, height: h, spp: options.render_spp, seed: options.seed, ..Default::default() };
        let mut out = renderer.render(&raster.camera(&view.camera), &opts)?;
        let exposure = view_exposure(result, index);
        for p in out.image.iter_mut() {
            for (x, e) in p.iter_mut().zip(exposure) {
                *x *= e;
            }
        }
        let path = renders_dir.join(format!("{}.png", file_stem(&view.name)));
        image_io::write_rgb(&path, w, h, &out.image)?;
        written.push(path);
        // Photo | render, for looking at them together.
        let photo = raster.photo(Photo::load(&view.image)?);
        let mut pair = vec![[0.0f32; 3]; 2 * w * h];
        for y in 0..h {
            for x in 0..w {
                pair[y * 2 * w + x] = photo.linear[y * w + x];
                pair[y * 2 * w + w + x] = out.image[y * w + x];
            }
        }
        let path = renders_dir.join(format!("{}_beside_photo.png", file_stem(&view.name)));
        image_io::write_rgb(&path, 2 * w, h, &pair)?;
        written.push(path);
    }
    Ok(written)
}
