//! The fit of a whole scene, stage after stage: observe the views, align every part, estimate
//! the lighting, then per part choose a view, select a graph and fit it. Each stage is a module
//! of its own; this one only passes their plain data along and times them.

use std::collections::BTreeMap;
use std::time::Instant;

use psc_render::material::MaterialBinding;
use psc_render::scene::{LightRadiances, Scene};
use psc_render::Renderer;
use psc_runtime::library::Library;
use psc_runtime::material::ProceduralMaterial;
use serde::{Deserialize, Serialize};

use crate::align::{align_view, AlignedPart, Dropped, Warp};
use crate::error::FitError;
use crate::features::{FeatureConfig, Scratch};
use crate::layer::{MaterialState, PartView, Sampling, Workspace};
use crate::light_solve::LightSolve;
use crate::lighting::{self, GridSettings, ShadingGrid};
use crate::loss::{LossValue, LossWeights, PartLoss};
use crate::observe::ViewObservation;
use crate::optim::Free;
use crate::part_fit::{fit_part, FitSettings, Problem};
use crate::refit::{self, RoundInputs, RoundLighting};
use crate::select::{select, Ranked, SelectSettings};
use crate::targets::part_view;
use crate::uvmap::UvTransform;
use crate::views::{choose, ViewScore};

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
    /// Parts with fewer usable pixels get a homogeneous material.
    pub min_pixels: usize,
    pub loss: LossWeights,
    pub features: FeatureConfig,
    /// Rounds of: lights re-estimated under the fitted materials (unless given), light grids
    /// re-rendered, albedo scale and roughness re-fitted.
    pub refit_rounds: usize,
    /// Most iterations of a re-fit.
    pub refit_iterations: u32,
}

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
            min_pixels: 500,
            loss: LossWeights::default(),
            features: FeatureConfig::default(),
            refit_rounds: 3,
            refit_iterations: 150,
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

/// How a part got its material.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PartStatus {
    /// Selected and fitted.
    Fitted,
    /// The graph was given with `--graph`.
    Forced,
    /// Too few usable pixels: a homogeneous material at the shading-normalised median colour.
    Homogeneous,
    /// No view shows it: the documented default (homogeneous mid grey, roughness 0.5).
    Unobserved,
}

/// Pixel counts of a part in its chosen view.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct PixelCounts {
    /// Labelled in the photo (M_photo).
    pub photo: usize,
    /// Seen on the coarse model (M_geo).
    pub model: usize,
    pub usable: usize,
    pub fitted: usize,
    pub dropped: Dropped,
}

/// Seconds spent per stage for one part.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct PartTimings {
    pub targets: f64,
    pub selection: f64,
    pub fit: f64,
}

/// The fit of one part (saved whole in `result.json`, so `--refit-only` can start from it).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PartResult {
    pub name: String,
    pub status: PartStatus,
    pub graph: String,
    pub state: MaterialState,
    /// Scale of the graph's roughness map in the output, so that its mean over the part is the
    /// fitted roughness.
    pub roughness_scale: f32,
    /// The selection's best graphs with their votes (empty when not selected).
    pub top: Vec<Ranked>,
    pub view: Option<String>,
    /// Index of the chosen view in the scene's views.
    pub view_index: Option<usize>,
    pub view_scores: Vec<ViewScore>,
    pub warp: Option<Warp>,
    pub iou: Option<(f32, f32)>,
    pub pixels: PixelCounts,
    pub loss: LossValue,
    pub history: Vec<f32>,
    pub iterations: u32,
    pub uv_candidates: usize,
    pub timings: PartTimings,
}

/// Everything a fit decided.
#[derive(Clone, Debug)]
pub struct FitResult {
    pub parts: Vec<PartResult>,
    /// Light slot names (scene lights, then "environment") and their fitted RGB radiance.
    pub slot_names: Vec<String>,
    pub radiance: Vec<[f32; 3]>,
    /// How the radiances were obtained.
    pub light_source: String,
    /// The global light solves of the re-fit rounds, in order (none with `--lights`).
    pub light_rounds: Vec<LightRound>,
    /// Per view (scene order), its RGB exposure: the factor between a render of the fitted
    /// scene and that view's photo. The last light solve's (1 for a single view, and until the
    /// first solve); with `--lights`, the previous fit's or 1.
    pub exposure: Vec<[f32; 3]>,
    /// (stage, seconds) in order.
    pub timings: Vec<(String, f64)>,
}

impl FitResult {
    /// The fitted materials as renderer bindings, one per model part.
    pub fn bindings(&self, library: &Library) -> Result<Vec<MaterialBinding>, FitError> {
        self.parts.iter().map(|p| binding(library, &p.graph, &p.state, p.roughness_scale)).collect()
    }

    /// The radiances in the renderer's form.
    pub fn light_radiances(&self, scene: &Scene) -> LightRadiances {
        let n = scene.lights.len();
        LightRadiances {
            lights: self.radiance[..n].to_vec(),
            environment: self.radiance.get(n).copied().unwrap_or([1.0; 3]),
            source: self.light_source.clone(),
        }
    }
}

/// A renderer binding for a graph at a fitted state.
pub fn binding(
    library: &Library,
    graph: &str,
    state: &MaterialState,
    roughness_scale: f32,
) -> Result<MaterialBinding, FitError> {
    let material = library.get(graph).ok_or_else(|| FitError::Input(format!("no graph `{graph}` in the library")))?;
    let procedural = ProceduralMaterial::new(material.clone(), state.params.clone()).map_err(FitError::Input)?;
    Ok(MaterialBinding {
        material: std::sync::Arc::new(procedural),
        uv_transform: state.uv.matrix(),
        albedo_scale: state.albedo_scale,
        roughness_scale,
    })
}

/// One round's light solve and how much it moved the radiances.
#[derive(Clone, Debug, Serialize)]
pub struct LightRound {
    pub solve: LightSolve,
    /// Largest relative change of a slot's radiance (luminance) against the previous round.
    pub change: f32,
}

/// Rounds stop once no light's radiance moves by more than this fraction.
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

/// The documented default for parts no view shows.
const UNOBSERVED_ALBEDO: [f32; 3] = [0.5; 3];
pub(crate) const DEFAULT_ROUGHNESS: f32 = 0.5;
const HOMOGENEOUS: &str = "homogeneous";

/// What `--resume` and `--refit-only` start from: a previous fit's parts, radiances and
/// per-view exposures (its `result.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PreviousFit {
    pub parts: Vec<PartResult>,
    pub radiance: Vec<[f32; 3]>,
    /// One per view in scene order; empty (every view at 1) in fits made before exposures.
    #[serde(default)]
    pub exposure: Vec<[f32; 3]>,
}

impl PreviousFit {
    /// The exposure of every view of a scene with `n_views` views (1 where none was saved).
    fn exposures(&self, n_views: usize) -> Vec<[f32; 3]> {
        (0..n_views).map(|v| self.exposure.get(v).copied().unwrap_or([1.0; 3])).collect()
    }

    /// Checks that the previous fit belongs to `scene` and `library`.
    fn check(&self, scene: &Scene, library: &Library, n_slots: usize) -> Result<(), FitError> {
        let names: Vec<&String> = self.parts.iter().map(|p| &p.name).collect();
        if names.len() != scene.mesh.part_names.len() || names.iter().zip(&scene.mesh.part_names).any(|(a, b)| *a != b)
        {
            return Err(FitError::Input(format!(
                "the previous fit is of other parts ({}) than the scene's ({})",
                names.iter().map(|n| n.as_str()).collect::<Vec<_>>().join(", "),
                scene.mesh.part_names.join(", ")
            )));
        }
        if self.radiance.len() != n_slots || self.radiance.iter().flatten().any(|c| !c.is_finite() || *c < 0.0) {
            return Err(FitError::Input(format!(
                "the previous fit has {} light radiances for the scene's {n_slots} (or a bad value)",
                self.radiance.len()
            )));
        }
        let n_views = scene.views.len();
        let bad_exposure = self.exposure.iter().flatten().any(|e| !e.is_finite() || *e <= 0.0);
        if (!self.exposure.is_empty() && self.exposure.len() != n_views) || bad_exposure {
            return Err(FitError::Input(format!(
                "the previous fit has {} view exposures for the scene's {n_views} views (or one not finite and positive)",
                self.exposure.len()
            )));
        }
        for p in &self.parts {
            let material = library
                .get(&p.graph)
                .ok_or_else(|| FitError::Input(format!("part `{}`: no graph `{}` in the library", p.name, p.graph)))?;
            if material.graph.info.default_params().len() != p.state.params.len() {
                return Err(FitError::Input(format!(
                    "part `{}`: the previous fit has {} parameter values for graph `{}`, which has {}",
                    p.name,
                    p.state.params.len(),
                    p.graph,
                    material.graph.info.default_params().len()
                )));
            }
        }
        Ok(())
    }
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

/// Continues a previous fit (`psc fit --resume`): every part fitted before keeps its graph
/// (unless `--graph` now forces another) and its optimisation starts from the fitted state,
/// with no selection and no global UV search, for `options.fit.max_iterations` more
/// iterations; the lights start from the previous fit's and the light rounds run again. Parts
/// that were homogeneous or unobserved are fitted anew (their pixels may have changed with
/// the labels).
pub fn resume_scene(
    scene: &Scene,
    library: &Library,
    radiances: Option<&LightRadiances>,
    previous: &PreviousFit,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<FitResult, FitError> {
    run(scene, library, radiances, Mode::Resume(previous), options, progress)
}

/// Where a run starts from.
#[derive(Clone, Copy)]
enum Mode<'a> {
    /// From nothing: select and fit every part.
    Fit,
    /// From a previous fit: continue every part's optimisation, then the light rounds.
    Resume(&'a PreviousFit),
    /// From a previous fit: the light rounds only.
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

/// The light solve and re-fit rounds only, from a previous fit (`psc fit --refit-only`): every
/// part keeps its graph, parameters and UV transform.
pub fn refit_scene(
    scene: &Scene,
    library: &Library,
    radiances: Option<&LightRadiances>,
    previous: &PreviousFit,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<FitResult, FitError> {
    run(scene, library, radiances, Mode::RefitOnly(previous), options, progress)
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
            let obs = ViewObservation::new(v, &scene.mesh.part_names, renderer.geometry());
            progress.advance(1);
            obs
        })
        .collect::<Result<_, _>>()?;
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
    lap("light estimate", &mut timings);
    progress.stage("light grids", views.len() as u64);
    let grids = lighting::view_grids(&renderer, &views, options.grid, options.seed)?;
    let shading: Vec<ShadingGrid> =
        grids.iter().zip(&views).map(|(g, o)| ShadingGrid::new(g, &radiance, o.camera.position)).collect();
    lap("light grids", &mut timings);

    let mut parts = Vec::with_capacity(n_parts);
    let fit_parts = !matches!(mode, Mode::RefitOnly(_));
    if let Mode::RefitOnly(p) = mode {
        parts = p.parts.clone();
    }
    if fit_parts {
        progress.stage("fit parts", n_parts as u64);
    }
    // Before the first light solve every view is at exposure 1; a resumed fit keeps the
    // exposures solved with the lights it starts from.
    let exposure = previous.map_or_else(|| vec![[1.0; 3]; views.len()], |p| p.exposures(views.len()));
    for part in (0..n_parts).filter(|_| fit_parts) {
        let name = &scene.mesh.part_names[part];
        let before = previous.map(|p| &p.parts[part]);
        let inputs = PartInputs {
            scene,
            library,
            homogeneous: &homogeneous,
            renderer: &renderer,
            views: &views,
            exposure: &exposure,
        };
        let result = fit_one_part(&inputs, &aligned, &shading, part as u32, before, options)?;
        progress.note(&summary(name, &result));
        parts.push(result);
        progress.advance(1);
    }
    lap("fit parts", &mut timings);

    let mut result = FitResult {
        parts,
        slot_names: renderer.slot_names().to_vec(),
        radiance,
        light_source,
        light_rounds: Vec::new(),
        exposure,
        timings,
    };
    let mut shading = shading;
    let inputs = RoundInputs { library, homogeneous: &homogeneous, views: &views, aligned: &aligned, options };
    {
        let light = RoundLighting { renderer: &renderer, shading: &shading, exposure: &result.exposure };
        for part in result.parts.iter_mut() {
            refit::match_whole_part(&inputs, &light, part)?;
        }
    }
    lap("match part means", &mut result.timings);
    for round in 0..options.refit_rounds {
        renderer.set_materials(result.bindings(library)?)?;
        if radiances.is_none() {
            progress.stage("solve lights", 1);
            let solve = refit::solve_lights(&renderer, &views, options.seed ^ 0x5eed_0001 ^ round as u64)?;
            progress.advance(1);
            if solve.radiance.iter().all(|r| r.iter().all(|&c| c <= 0.0)) {
                progress.note(&format!(
                    "round {}: the light solve found no light; keeping the previous radiances",
                    round + 1
                ));
                break;
            }
            let change = relative_change(&result.radiance, &solve.radiance);
            let lights: Vec<String> = result
                .slot_names
                .iter()
                .zip(&solve.radiance)
                .zip(&solve.share)
                .map(|((n, r), s)| format!("{n} ({:.1}, {:.1}, {:.1}) carries {:.0}%", r[0], r[1], r[2], s * 100.0))
                .collect();
            progress.note(&format!(
                "round {}: lights solved from {} pixels (relative rms {:.3}, {:.0}% outliers): {}; change {:.1}%{}",
                round + 1,
                solve.pixels,
                solve.relative_rms[1],
                solve.outliers * 100.0,
                lights.join(", "),
                change * 100.0,
                exposure_note(&views, &solve.exposure)
            ));
            result.radiance = solve.radiance.clone();
            result.exposure = solve.exposure.clone();
            // The joint solve's albedo factors start the re-fit (which then refines them).
            for (part, factor) in result.parts.iter_mut().zip(&solve.part_scales) {
                if part.status != PartStatus::Unobserved {
                    part.state.albedo_scale.iter_mut().zip(factor).for_each(|(s, f)| *s *= f);
                }
            }
            result.light_source = format!(
                "solved per light under the fitted materials (NNLS, robust), round {} of at most {}",
                round + 1,
                options.refit_rounds
            );
            result.light_rounds.push(LightRound { solve, change });
        }
        progress.stage("light grids", views.len() as u64);
        let grids = lighting::view_grids(&renderer, &views, options.grid, options.seed ^ 0x5eed_0002)?;
        shading =
            grids.iter().zip(&views).map(|(g, o)| ShadingGrid::new(g, &result.radiance, o.camera.position)).collect();
        progress.stage("re-fit albedo scale and roughness", n_parts as u64);
        let light = RoundLighting { renderer: &renderer, shading: &shading, exposure: &result.exposure };
        for part in result.parts.iter_mut() {
            refit::refit_appearance(&inputs, &light, part)?;
            refit::match_whole_part(&inputs, &light, part)?;
            progress.advance(1);
        }
        lap(&format!("re-fit round {}", round + 1), &mut result.timings);
        let converged = result.light_rounds.last().is_some_and(|r| r.change < LIGHT_CONVERGED);
        if converged {
            progress.note(&format!("lights converged after {} rounds", round + 1));
            break;
        }
    }
    Ok(result)
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

fn summary(name: &str, r: &PartResult) -> String {
    match r.status {
        PartStatus::Unobserved => format!("{name}: seen in no view; default material"),
        PartStatus::Homogeneous => {
            format!("{name}: {} usable pixels; homogeneous at its shading-normalised median", r.pixels.usable)
        }
        _ => format!(
            "{name}: {} (top: {}) in view {}, loss {:.4} after {} iterations",
            r.graph,
            r.top.iter().map(|t| t.graph.as_str()).collect::<Vec<_>>().join(", "),
            r.view.as_deref().unwrap_or("-"),
            r.loss.total,
            r.iterations
        ),
    }
}

/// What every part's fit reads.
struct PartInputs<'a> {
    scene: &'a Scene,
    library: &'a Library,
    homogeneous: &'a std::sync::Arc<psc_runtime::library::Material>,
    renderer: &'a Renderer,
    views: &'a [ViewObservation],
    /// Per view, the exposure its photo is compared at.
    exposure: &'a [[f32; 3]],
}

/// Fits one part; `before`: the part in a previous fit that this one continues (`--resume`).
fn fit_one_part(
    inputs: &PartInputs,
    aligned: &[Vec<AlignedPart>],
    shading: &[ShadingGrid],
    part: u32,
    before: Option<&PartResult>,
    options: &FitOptions,
) -> Result<PartResult, FitError> {
    let PartInputs { scene, library, homogeneous, renderer, views, exposure } = *inputs;
    let name = scene.mesh.part_names[part as usize].clone();
    let started = Instant::now();
    let mut result = PartResult {
        name: name.clone(),
        status: PartStatus::Unobserved,
        graph: HOMOGENEOUS.to_string(),
        state: flat_state(homogeneous, UNOBSERVED_ALBEDO, DEFAULT_ROUGHNESS),
        roughness_scale: 1.0,
        top: Vec::new(),
        view: None,
        view_index: None,
        view_scores: Vec::new(),
        warp: None,
        iou: None,
        pixels: PixelCounts::default(),
        loss: LossValue::default(),
        history: Vec::new(),
        iterations: 0,
        uv_candidates: 0,
        timings: PartTimings::default(),
    };
    // Candidate views with their search-resolution targets and shading-normalised colours.
    let mut candidates: Vec<(&AlignedPart, PartView, [f32; 3])> = Vec::new();
    let mut ws = Workspace::default();
    for (v, list) in aligned.iter().enumerate() {
        let Some(a) = list.iter().find(|a| a.part == part && !a.usable.is_empty()) else { continue };
        let obs = &views[v];
        let Some(view) =
            part_view(obs, a, renderer.geometry(), &obs.camera, &shading[v], options.search_pixels, exposure[v])
        else {
            continue;
        };
        let colour = flat_colour(homogeneous, &view, &mut ws)?;
        candidates.push((a, view, colour));
    }
    if candidates.is_empty() {
        return Ok(result);
    }
    let (scores, best) = choose(
        views,
        &candidates.iter().map(|c| c.0).collect::<Vec<_>>(),
        &candidates.iter().map(|c| c.2).collect::<Vec<_>>(),
    );
    let (chosen, search_view, colour) = candidates.swap_remove(best);
    let obs = &views[chosen.view];
    result.view = Some(obs.name.clone());
    result.view_index = Some(chosen.view);
    result.view_scores = scores;
    result.warp = Some(chosen.warp);
    result.iou = Some((chosen.iou_initial, chosen.iou));
    result.pixels = PixelCounts {
        photo: chosen.photo_pixels,
        model: chosen.model_pixels,
        usable: chosen.usable.len(),
        fitted: 0,
        dropped: chosen.dropped,
    };
    if chosen.usable.len() < options.min_pixels {
        result.status = PartStatus::Homogeneous;
        result.state = flat_state(homogeneous, colour, DEFAULT_ROUGHNESS);
        result.pixels.fitted = search_view.pixels.len();
        result.timings.targets = started.elapsed().as_secs_f64();
        return Ok(result);
    }
    let fit_view = part_view(
        obs,
        chosen,
        renderer.geometry(),
        &obs.camera,
        &shading[chosen.view],
        options.fit_pixels,
        exposure[chosen.view],
    )
    .expect("the search view of the same pixels exists");
    result.pixels.fitted = fit_view.pixels.len();
    let mut scratch = Scratch::default();
    let fit_loss = PartLoss::new(&fit_view, options.loss, &options.features, &mut scratch)?;
    let search_loss = PartLoss::new(&search_view, options.loss, &options.features, &mut scratch)?;
    result.timings.targets = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let seed = psc_base::mix64(options.seed ^ (u64::from(part) << 32));
    let forced = options.forced.get(&name);
    // A part continued from a previous fit keeps its graph unless told otherwise.
    let continued = before.filter(|b| {
        matches!(b.status, PartStatus::Fitted | PartStatus::Forced) && forced.is_none_or(|g| *g == b.graph)
    });
    let selection = match (forced, continued) {
        (Some(_), _) | (None, Some(_)) => None,
        (None, None) => {
            Some(select(library, &search_view, &search_loss, options.select, options.fit.search_sampling, seed, None)?)
        }
    };
    result.timings.selection = started.elapsed().as_secs_f64();
    if let (Some(dir), Some(sel)) = (std::env::var_os("PSC_FIT_DUMP"), &selection) {
        debug_dump(std::path::Path::new(&dir), &name, homogeneous, library, &search_view, sel, colour, options)?;
    }
    let started = Instant::now();
    let graph_name = match (forced, continued, &selection) {
        (Some(g), _, _) => g.clone(),
        (None, Some(b), _) => b.graph.clone(),
        (None, None, Some(s)) => s.ranking[0].graph.clone(),
        (None, None, None) => unreachable!("selection runs unless the graph is forced or continued"),
    };
    let graph_index = library.materials.iter().position(|m| m.name() == graph_name).expect("checked above");
    let material = &library.materials[graph_index];
    let starts: Vec<MaterialState> = match (&selection, continued) {
        (_, Some(b)) => vec![b.state.clone()],
        (Some(s), None) => s.exemplars_of(graph_index).take(options.fit.starts).map(|e| e.state.clone()).collect(),
        (None, None) => vec![MaterialState {
            params: material.graph.info.default_params(),
            uv: UvTransform::default(),
            albedo_scale: [1.0; 3],
            roughness: DEFAULT_ROUGHNESS,
        }],
    };
    let problem = Problem {
        material,
        fit_view: &fit_view,
        fit_loss: &fit_loss,
        search_view: &search_view,
        search_loss: &search_loss,
    };
    let settings = match continued {
        // Its UV transform was searched and refined already: a global search would throw that away.
        Some(_) => FitSettings { starts: 1, start_iterations: 0, global_uv_search: false, ..options.fit },
        None => options.fit,
    };
    let fit = fit_part(&problem, &starts, &settings, Free::ALL)?;
    // The output keeps the graph's roughness map, scaled to the fitted part-wide value.
    fit_view.render(material, &fit.state, options.fit.sampling, &mut ws)?;
    let map_mean = ws.channel_mean(psc_compiler::Channel::Roughness);
    result.roughness_scale = if map_mean > 1e-4 { (fit.state.roughness / map_mean).clamp(0.0, 50.0) } else { 1.0 };
    result.status = match continued {
        Some(b) => b.status.clone(),
        None if forced.is_some() => PartStatus::Forced,
        None => PartStatus::Fitted,
    };
    result.graph = graph_name;
    result.top = match (selection, continued) {
        (Some(s), _) => s.ranking.into_iter().take(3).collect(),
        (None, Some(b)) => b.top.clone(),
        (None, None) => Vec::new(),
    };
    result.state = fit.state;
    result.loss = fit.loss;
    let (earlier_history, earlier_iterations, earlier_candidates) =
        continued.map_or((Vec::new(), 0, 0), |b| (b.history.clone(), b.iterations, b.uv_candidates));
    result.history = earlier_history.into_iter().chain(fit.history).collect();
    result.iterations = earlier_iterations + fit.iterations;
    result.uv_candidates = earlier_candidates + fit.uv_candidates;
    result.timings.fit = started.elapsed().as_secs_f64();
    Ok(result)
}

/// The homogeneous graph at linear colour `albedo` (values above 1 stay in the albedo scale).
pub(crate) fn flat_state(
    homogeneous: &psc_runtime::library::Material,
    albedo: [f32; 3],
    roughness: f32,
) -> MaterialState {
    let info = &homogeneous.graph.info;
    let mut params = info.default_params();
    let mut albedo_scale = [1.0f32; 3];
    if let Some(p) = info.param("albedo_color") {
        for c in 0..3 {
            params[p.slot + c] = albedo[c].clamp(0.0, 1.0);
            if albedo[c] > 1.0 {
                albedo_scale[c] = albedo[c];
                params[p.slot + c] = 1.0;
            }
        }
    }
    if let Some(p) = info.param("rough") {
        params[p.slot] = roughness;
    }
    MaterialState { params, uv: UvTransform::default(), albedo_scale, roughness }
}

/// The shading-normalised median colour of a part: the albedo scale that colour-matches a
/// white homogeneous material to the photo.
pub(crate) fn flat_colour(
    homogeneous: &psc_runtime::library::Material,
    view: &PartView,
    ws: &mut Workspace,
) -> Result<[f32; 3], FitError> {
    let white = flat_state(homogeneous, [1.0; 3], DEFAULT_ROUGHNESS);
    view.render(homogeneous, &white, Sampling { density: 0.0, max_per_axis: 1 }, ws)?;
    Ok(view.matched_albedo_scale(&white, ws))
}

/// Debugging aid (`PSC_FIT_DUMP=dir`): the search view's photo, a homogeneous render at the
/// part's colour and the best exemplar, side by side.
#[allow(clippy::too_many_arguments)]
fn debug_dump(
    dir: &std::path::Path,
    name: &str,
    homogeneous: &psc_runtime::library::Material,
    library: &Library,
    view: &PartView,
    selection: &crate::select::Selection,
    colour: [f32; 3],
    options: &FitOptions,
) -> Result<(), FitError> {
    let mut ws = Workspace::default();
    let (w, h) = (view.width, view.height);
    let mut out = vec![[0.0f32; 3]; 3 * w * h];
    let mut put = |k: usize, img: &[[f32; 3]]| {
        for y in 0..h {
            for x in 0..w {
                out[y * 3 * w + k * w + x] = img[y * w + x].map(psc_render::image_io::srgb_to_linear);
            }
        }
    };
    put(0, &view.target);
    view.render(
        homogeneous,
        &flat_state(homogeneous, colour, DEFAULT_ROUGHNESS),
        options.fit.search_sampling,
        &mut ws,
    )?;
    put(1, &ws.image);
    let best = &selection.exemplars[0];
    view.render(&library.materials[best.graph], &best.state, options.fit.search_sampling, &mut ws)?;
    put(2, &ws.image);
    std::fs::create_dir_all(dir).map_err(|e| FitError::Output(e.to_string()))?;
    psc_render::image_io::write_rgb(&dir.join(format!("{name}.png")), 3 * w, h, &out)?;
    Ok(())
}
