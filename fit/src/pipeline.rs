//! The fit of a whole scene, stage after stage: observe the views, align every part, estimate
//! the lighting, fit every part (`part`), then the rounds of light solve and re-fit (`refit`).
//! Each stage is a module of its own; this one only passes their plain data along, times them
//! and reports progress. It is where a run starts: afresh, or continuing a previous fit
//! (`--resume`, `--refit-only`).

use std::collections::BTreeMap;
use std::time::Instant;

use psc_render::scene::{LightRadiances, Scene};
use psc_render::Renderer;
use psc_runtime::library::Library;
use rayon::prelude::*;

use crate::align::{align_view, AlignedPart};
use crate::error::FitError;
use crate::features::FeatureConfig;
use crate::lighting::{self, GridSettings, ShadingGrid};
use crate::loss::LossWeights;
use crate::observe::ViewObservation;
use crate::part::{fit_one_part, summary, PartInputs, HOMOGENEOUS};
use crate::part_fit::FitSettings;
use crate::refit::{self, RoundInputs, RoundLighting};
use crate::render_noise;
use crate::select::SelectSettings;
use crate::targets::{Window, WindowShape};

pub use crate::result::{
    binding, FitResult, LightRound, PartResult, PartStatus, PartTimings, PixelCounts, PreviousFit,
};

/// Everything a fit can be told.
#[derive(Clone, Debug)]
pub struct FitOptions {
    pub seed: u64,
    /// Parts whose graph is given (`--graph part=name`): no selection for them.
    pub forced: BTreeMap<String, String>,
    pub select: SelectSettings,
    pub fit: FitSettings,
    pub grid: GridSettings,
    /// Fit pixels of a part's fit view and of its search view (selection, UV search).
    pub fit_pixels: usize,
    pub search_pixels: usize,
    /// The shape of a part's fit window when the part holds more than `fit_pixels` (the search
    /// window keeps its bounding box's aspect).
    pub fit_window_shape: WindowShape,
    /// Parts with fewer usable pixels get a homogeneous material.
    pub min_pixels: usize,
    pub loss: LossWeights,
    pub features: FeatureConfig,
    /// Rounds of: lights re-estimated under the fitted materials (unless given), light grids
    /// re-rendered, albedo scale and roughness re-fitted.
    pub refit_rounds: usize,
    /// Most iterations of a re-fit.
    pub refit_iterations: u32,
    /// Photos with more pixels are fitted at a working raster within this many (0: no limit;
    /// see [`crate::working`]).
    pub max_photo_pixels: usize,
}

impl FitOptions {
    /// The window selection and the UV search render their candidates on: the aspect of the
    /// part's bounding box (a square one was measured; see [`crate::targets`]).
    pub fn search_window(&self) -> Window {
        Window { max_pixels: self.search_pixels, shape: WindowShape::BoundingBox }
    }

    /// The window a part's parameters are fitted on.
    pub fn fit_window(&self) -> Window {
        Window { max_pixels: self.fit_pixels, shape: self.fit_window_shape }
    }
}

/// About 420×315: the dev scenes' 320×240 photos are fitted as they are; a 640×480 photo at
/// half size, a 12-megapixel one at a tenth.
pub const DEFAULT_MAX_PHOTO_PIXELS: usize = 1 << 17;

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            seed: 0,
            forced: BTreeMap::new(),
            select: SelectSettings::default(),
            fit: FitSettings::default(),
            grid: GridSettings::default(),
            fit_pixels: 4096,
            search_pixels: 1024,
            fit_window_shape: WindowShape::BoundingBox,
            min_pixels: 500,
            loss: LossWeights::default(),
            features: FeatureConfig::default(),
            refit_rounds: 3,
            refit_iterations: 150,
            max_photo_pixels: DEFAULT_MAX_PHOTO_PIXELS,
        }
    }
}

/// Reports what a long fit is doing. Implemented by the command line (bars, log lines).
pub trait Progress: Sync {
    /// A new stage with `total` steps.
    fn stage(&self, name: &str, total: u64);
    fn advance(&self, steps: u64);
    /// A finished result worth a line of its own.
    fn note(&self, text: &str);
}

/// No progress output.
pub struct Silent;

impl Progress for Silent {
    fn stage(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64) {}
    fn note(&self, _: &str) {}
}

/// Rounds stop once no light's radiance and no view's exposure moves by more than this fraction.
const LIGHT_CONVERGED: f32 = 0.02;

fn relative_change(old: &[[f32; 3]], new: &[[f32; 3]]) -> f32 {
    old.iter()
        .zip(new)
        .map(|(a, b)| {
            let (la, lb) = (psc_base::color::luminance(*a), psc_base::color::luminance(*b));
            (lb - la).abs() / la.max(lb).max(1e-6)
        })
        .fold(0.0, f32::max)
}

/// Fits every part of `scene`. `radiances`: known light radiances (`--lights`), else they are
/// estimated from the photos.
pub fn fit_scene(
    scene: &Scene,
    library: &Library,
    radiances: Option<&LightRadiances>,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<FitResult, FitError> {
    run(scene, library, radiances, Mode::Fit, options, progress)
}

/// How [`continue_fit`] goes on from a previous fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Continue {
    /// `psc fit --resume`: every part fitted before keeps its graph (unless `--graph` now
    /// forces another) and its optimisation starts from the fitted state, with no selection
    /// and no global UV search, for `options.fit.max_iterations` more iterations; the lights
    /// and exposures start from the previous fit's and the light rounds run again. Parts that
    /// were homogeneous or unobserved are fitted anew (their pixels may have changed with the
    /// labels).
    Resume,
    /// `psc fit --refit-only`: the light solve and re-fit rounds only; every part keeps its
    /// graph, parameters and UV transform.
    RefitOnly,
}

/// Goes on from a previous fit of `scene` (its `result.json`), as `how` says.
pub fn continue_fit(
    scene: &Scene,
    library: &Library,
    radiances: Option<&LightRadiances>,
    previous: &PreviousFit,
    how: Continue,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<FitResult, FitError> {
    let mode = match how {
        Continue::Resume => Mode::Resume(previous),
        Continue::RefitOnly => Mode::RefitOnly(previous),
    };
    run(scene, library, radiances, mode, options, progress)
}

/// Where a run starts from.
#[derive(Clone, Copy)]
enum Mode<'a> {
    /// From nothing: select and fit every part.
    Fit,
    Resume(&'a PreviousFit),
    RefitOnly(&'a PreviousFit),
}

impl<'a> Mode<'a> {
    fn previous(self) -> Option<&'a PreviousFit> {
        match self {
            Mode::Fit => None,
            Mode::Resume(p) | Mode::RefitOnly(p) => Some(p),
        }
    }
}

fn run(
    scene: &Scene,
    library: &Library,
    radiances: Option<&LightRadiances>,
    mode: Mode,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<FitResult, FitError> {
    let previous = mode.previous();
    let mut timings = Vec::new();
    let mut clock = Instant::now();
    let mut lap = |name: &str, timings: &mut Vec<(String, f64)>| {
        timings.push((name.to_string(), clock.elapsed().as_secs_f64()));
        clock = Instant::now();
    };
    if scene.views.is_empty() {
        return Err(FitError::Input(format!("{}: the scene has no views to fit to", scene.root.display())));
    }
    let homogeneous = library
        .get(HOMOGENEOUS)
        .ok_or_else(|| FitError::Input(format!("the graph library has no `{HOMOGENEOUS}` graph")))?
        .clone();
    for (part, graph) in &options.forced {
        if scene.mesh.part_index(part).is_none() {
            return Err(FitError::Input(format!(
                "--graph {part}={graph}: the scene has no part `{part}` (parts: {})",
                scene.mesh.part_names.join(", ")
            )));
        }
        if library.get(graph).is_none() {
            return Err(FitError::Input(format!("--graph {part}={graph}: no graph `{graph}` in the library")));
        }
    }
    let n_parts = scene.mesh.part_names.len();
    let unit = LightRadiances::unit(scene);
    let mut renderer = Renderer::new(scene, scene.mtl_materials(&mut Vec::new()), &unit)?;

    progress.stage("observe views", scene.views.len() as u64);
    let views: Vec<ViewObservation> = scene
        .views
        .iter()
        .map(|v| {
            let obs = ViewObservation::new(v, &scene.mesh.part_names, renderer.geometry(), options.max_photo_pixels);
            progress.advance(1);
            obs
        })
        .collect::<Result<_, _>>()?;
    for (v, obs) in scene.views.iter().zip(&views) {
        let r = obs.raster;
        if !r.is_identity() {
            progress.note(&format!(
                "{}: the {}x{} photo is fitted at {}x{} (blocks of {f}x{f} pixels; --max-photo-pixels {})",
                v.name,
                v.width,
                v.height,
                r.width,
                r.height,
                options.max_photo_pixels,
                f = r.factor
            ));
        }
    }
    let aligned: Vec<Vec<AlignedPart>> = views.iter().enumerate().map(|(i, o)| align_view(o, i, n_parts)).collect();
    lap("observe and align", &mut timings);

    // Lighting: the other parts' materials for the indirect light are their pixel medians
    // (or the previous fit's materials).
    let n_slots = renderer.n_slots();
    match previous {
        Some(p) => {
            p.check(scene, library, n_slots)?;
            let bindings = p.parts.iter().map(|p| binding(library, &p.graph, &p.state, p.roughness_scale));
            renderer.set_materials(bindings.collect::<Result<_, _>>()?)?;
        }
        None => renderer.set_materials(lighting::median_materials(&views, n_parts))?,
    }
    let (radiance, light_source) = match (radiances, previous) {
        (None, Some(p)) => (p.radiance.clone(), "the previous fit's".to_string()),
        (radiances, _) => match radiances {
            Some(r) => {
                let mut v = r.lights.clone();
                if n_slots > v.len() {
                    v.push(r.environment);
                }
                (v, r.source.clone())
            }
            None => {
                progress.stage("estimate lights", views.len() as u64);
                let renders = lighting::unit_renders(&renderer, &views, options.seed)?;
                let (common, pixels) = lighting::common_radiance(&views, &renders)?;
                progress.note(&format!(
                    "initial light estimate: one common radiance ({:.3}, {:.3}, {:.3}) from {pixels} pixels",
                    common[0], common[1], common[2]
                ));
                (vec![common; n_slots], format!("estimated from the photos (one common radiance, {pixels} pixels)"))
            }
        },
    };
    // Under no light every albedo fits as well as any other: there is nothing to fit.
    if radiance.iter().flatten().all(|&c| c <= 0.0) {
        return Err(FitError::Input(format!(
            "every light's radiance is 0 ({light_source}): the parts cannot be fitted under no light (are the photos black?)"
        )));
    }
    lap("light estimate", &mut timings);
    progress.stage("render noise", views.len() as u64);
    let render_noise = render_noise::estimate(&renderer, &views, &aligned, &radiance, options.seed)?;
    for (obs, noise) in views.iter().zip(&render_noise) {
        if let Some(k) = noise.ratio() {
            progress.note(&format!(
                "{}: photo noise {k:.2}x the render's (parts above {:.2}x hold texture)",
                obs.name,
                k * render_noise::TOLERANCE
            ));
        }
    }
    lap("render noise", &mut timings);
    progress.stage("light grids", views.len() as u64);
    let grids = lighting::view_grids(&renderer, &views, options.grid, options.seed)?;
    let shading: Vec<ShadingGrid> =
        grids.iter().zip(&views).map(|(g, o)| ShadingGrid::new(g, &radiance, o.camera.position)).collect();
    lap("light grids", &mut timings);

    // Before the first light solve every view is at exposure 1; a resumed fit keeps the
    // exposures solved with the lights it starts from.
    let exposure = previous.map_or_else(|| vec![[1.0; 3]; views.len()], |p| p.exposures(views.len()));
    let parts = match mode {
        Mode::RefitOnly(p) => p.parts.clone(),
        Mode::Fit | Mode::Resume(_) => {
            progress.stage("fit parts", n_parts as u64);
            let inputs = PartInputs {
                scene,
                library,
                homogeneous: &homogeneous,
                renderer: &renderer,
                views: &views,
                exposure: &exposure,
                render_noise: &render_noise,
            };
            fit_every_part(&inputs, &aligned, &shading, previous, options, progress)?
        }
    };
    lap("fit parts", &mut timings);

    let mut result = FitResult {
        parts,
        slot_names: renderer.slot_names().to_vec(),
        radiance,
        light_source,
        light_rounds: Vec::new(),
        exposure,
        rasters: views.iter().map(|v| v.raster).collect(),
        timings,
    };
    let mut shading = shading;
    let inputs = RoundInputs {
        library,
        homogeneous: &homogeneous,
        views: &views,
        aligned: &aligned,
        render_noise: &render_noise,
        options,
    };
    {
        let light = RoundLighting { renderer: &renderer, shading: &shading, exposure: &result.exposure };
        result
            .parts
            .par_iter_mut()
            .with_max_len(1)
            .try_for_each(|part| refit::match_whole_part(&inputs, &light, part).map(drop))?;
    }
    lap("match part means", &mut result.timings);
    // Whether the last thing done to the materials is a light solve applied without a re-fit.
    let mut calibrated = false;
    for round in 0..options.refit_rounds {
        renderer.set_materials(result.bindings(library)?)?;
        if radiances.is_none() {
            let seed = options.seed ^ 0x5eed_0001 ^ round as u64;
            let label = format!("round {}", round + 1);
            if !solve_and_apply(&renderer, &inputs, seed, &label, &mut result, progress)? {
                break;
            }
            result.light_source = format!(
                "solved per light under the fitted materials (NNLS, robust), round {} of at most {}",
                round + 1,
                options.refit_rounds
            );
            // A re-fit under lights that barely moved would change little, and would end on
            // the layer's mean match again: the solve just applied stands as the calibration.
            if result.light_rounds.last().is_some_and(|r| r.change < LIGHT_CONVERGED) {
                progress.note(&format!("lights converged in round {}", round + 1));
                calibrated = true;
                lap(&format!("round {} (light solve)", round + 1), &mut result.timings);
                break;
            }
        }
        progress.stage("light grids", views.len() as u64);
        let grids = lighting::view_grids(&renderer, &views, options.grid, options.seed ^ 0x5eed_0002)?;
        shading =
            grids.iter().zip(&views).map(|(g, o)| ShadingGrid::new(g, &result.radiance, o.camera.position)).collect();
        progress.stage("re-fit albedo scale and roughness", n_parts as u64);
        let light = RoundLighting { renderer: &renderer, shading: &shading, exposure: &result.exposure };
        result.parts.par_iter_mut().with_max_len(1).try_for_each(|part| {
            refit::refit_appearance(&inputs, &light, part)?;
            refit::match_whole_part(&inputs, &light, part)?;
            progress.advance(1);
            Ok::<(), FitError>(())
        })?;
        lap(&format!("re-fit round {}", round + 1), &mut result.timings);
    }
    // Each re-fit ends on the whole-part mean match, made in the shading layer (light grids),
    // which undoes part of the solve's path-traced albedo factors (e.g. dev_1's barrel at
    // 0.87 round after round). A last solve under the final materials, applied without a
    // re-fit, leaves parts, lights and exposures as the path tracer sees them, which is how
    // every render and export of the result shows them.
    if radiances.is_none() && !result.light_rounds.is_empty() && !calibrated {
        renderer.set_materials(result.bindings(library)?)?;
        let seed = options.seed ^ 0x5eed_0003;
        if solve_and_apply(&renderer, &inputs, seed, "final calibration", &mut result, progress)? {
            result.light_source.push_str(", then a final solve of lights and part colours");
        }
        lap("final calibration", &mut result.timings);
    }
    Ok(result)
}

/// Every part of the scene fitted, in part order. Parts run in parallel as well as within: a
/// small part's batches leave cores idle. A part's fit reads nothing another part writes, so
/// the results are the same in any order and for any thread count. Each free thread takes the
/// next part in order of [`fit_work`], most first, so that the longest fit does not start
/// last and run alone. Every part runs; the first error in part order is returned.
fn fit_every_part(
    inputs: &PartInputs,
    aligned: &[Vec<AlignedPart>],
    shading: &[ShadingGrid],
    previous: Option<&PreviousFit>,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<Vec<PartResult>, FitError> {
    let n_parts = inputs.scene.mesh.part_names.len();
    let mut by_work: Vec<usize> = (0..n_parts).collect();
    by_work.sort_by_key(|&part| std::cmp::Reverse(fit_work(aligned, part as u32, options.fit_pixels)));
    let mut fitted: Vec<(usize, Result<PartResult, FitError>)> = by_work
        .into_iter()
        .par_bridge()
        .map(|part| {
            let before = previous.map(|p| &p.parts[part]);
            let result = fit_one_part(inputs, aligned, shading, part as u32, before, options);
            if let Ok(r) = &result {
                progress.note(&summary(&inputs.scene.mesh.part_names[part], r));
            }
            progress.advance(1);
            (part, result)
        })
        .collect();
    fitted.sort_by_key(|(part, _)| *part);
    fitted.into_iter().map(|(_, r)| r).collect()
}

/// How many pixels a part's fit will render, roughly: the most over its views of what the fit
/// window would hold there. The window takes at most `fit_pixels` usable pixels, with the
/// clipped pixels among them in proportion (the losses count clipped pixels too). Counting
/// usable pixels alone put dev_2's rug (3262 usable, 5841 clipped, all 9063 fitted: the
/// longest fit of the room) fourth, so it ran alone at the end.
fn fit_work(aligned: &[Vec<AlignedPart>], part: u32, fit_pixels: usize) -> usize {
    aligned
        .iter()
        .flatten()
        .filter(|a| a.part == part)
        .map(|a| {
            let (usable, clipped) = (a.usable.len(), a.clipped.len());
            if usable <= fit_pixels {
                usable + clipped
            } else {
                fit_pixels + clipped * fit_pixels / usable
            }
        })
        .max()
        .unwrap_or(0)
}

/// One global light solve under the renderer's current materials, applied to `result`: the
/// radiances, the views' exposures and every observed part's albedo factor, recorded as a
/// light round. False (and nothing applied) when the solve found no light.
fn solve_and_apply(
    renderer: &Renderer,
    inputs: &RoundInputs,
    seed: u64,
    label: &str,
    result: &mut FitResult,
    progress: &dyn Progress,
) -> Result<bool, FitError> {
    progress.stage("solve lights", 1);
    let solve = refit::solve_lights(renderer, inputs.views, inputs.aligned, seed)?;
    progress.advance(1);
    if solve.radiance.iter().all(|r| r.iter().all(|&c| c <= 0.0)) {
        progress.note(&format!("{label}: the light solve found no light; keeping the previous radiances"));
        return Ok(false);
    }
    let change =
        relative_change(&result.radiance, &solve.radiance).max(relative_change(&result.exposure, &solve.exposure));
    let lights: Vec<String> = result
        .slot_names
        .iter()
        .zip(&solve.radiance)
        .zip(&solve.share)
        .map(|((n, r), s)| format!("{n} ({:.1}, {:.1}, {:.1}) carries {:.0}%", r[0], r[1], r[2], s * 100.0))
        .collect();
    progress.note(&format!(
        "{label}: lights solved from {} pixels (relative rms {:.3}, {:.0}% outliers): {}; change {:.1}%{}{}",
        solve.pixels,
        solve.relative_rms[1],
        solve.outliers * 100.0,
        lights.join(", "),
        change * 100.0,
        exposure_note(inputs.views, &solve.exposure),
        spread_note(&result.slot_names, &solve)
    ));
    result.radiance = solve.radiance.clone();
    result.exposure = solve.exposure.clone();
    // The joint solve's albedo factors (a re-fit, where one follows, refines them).
    for (part, factor) in result.parts.iter_mut().zip(&solve.part_scales) {
        if part.status != PartStatus::Unobserved {
            part.state.albedo_scale.iter_mut().zip(factor).for_each(|(s, f)| *s *= f);
        }
    }
    result.light_rounds.push(LightRound { solve, change });
    Ok(true)
}

/// "; exposures view0 (r, g, b), …" for a solve of several views, else nothing (a single view's
/// exposure is 1 by definition).
fn exposure_note(views: &[ViewObservation], exposure: &[[f32; 3]]) -> String {
    if views.len() < 2 {
        return String::new();
    }
    let list: Vec<String> = views
        .iter()
        .zip(exposure)
        .map(|(v, e)| format!("{} ({:.3}, {:.3}, {:.3})", v.name, e[0], e[1], e[2]))
        .collect();
    format!("; exposures {}", list.join(", "))
}

/// How far the photos determine the least determined ratio between two lights.
fn spread_note(names: &[String], solve: &crate::light_solve::LightSolve) -> String {
    use crate::light_solve::{spread_percent, DETERMINED_LOG_SD};
    let Some((i, j, sd)) = solve.least_determined_ratio() else { return String::new() };
    let pair = format!("{} / {}", names[i], names[j]);
    match sd {
        Some(sd) if sd < DETERMINED_LOG_SD => {
            format!(
                "; the photos determine every ratio between lights, {pair} least: ±{:.0}% (1 sd)",
                spread_percent(sd)
            )
        }
        Some(sd) => format!(
            "; the photos do not determine the ratio {pair} (±{:.0}%, 1 sd): the solve's damping sets it",
            spread_percent(sd)
        ),
        None => format!("; the photos do not determine the ratio {pair} at all: the solve's damping sets it"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::{Dropped, Warp};

    fn seen(part: u32, view: usize, usable: usize, clipped: usize) -> AlignedPart {
        AlignedPart {
            part,
            view,
            warp: Warp::IDENTITY,
            iou_initial: 1.0,
            iou: 1.0,
            photo_pixels: usable + clipped,
            model_pixels: usable + clipped,
            usable: (0..usable as u32).collect(),
            clipped: (0..clipped as u32).collect(),
            dropped: Dropped::default(),
        }
    }

    #[test]
    fn a_mostly_clipped_part_within_the_budget_outranks_a_large_wall() {
        // dev_2's rug against its wall, in one view; the wall also in a second view.
        let aligned = vec![vec![seen(0, 0, 34040, 0), seen(1, 0, 3262, 5841)], vec![seen(0, 1, 20000, 800)]];
        let budget = 4096;
        let (wall, rug) = (fit_work(&aligned, 0, budget), fit_work(&aligned, 1, budget));
        assert_eq!(rug, 9103, "within the budget every usable and clipped pixel is fitted");
        assert_eq!(wall, 4096 + 800 * 4096 / 20000, "the view whose window holds the most");
        assert!(rug > wall);
        assert_eq!(fit_work(&aligned, 2, budget), 0, "a part no view shows");
    }
}
