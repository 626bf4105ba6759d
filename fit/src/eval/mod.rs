//! `psc eval`: a fitted room against the dev scene's ground truth, beside the baselines, in the
//! protocol of PhotoScene's Table 2. The only module of this crate that reads `truth/`.
//!
//! What is rendered (our path tracer, per-light images combined with each method's radiances):
//! - the input views (truth: the photos and their label images), the novel views
//!   (`truth/novel/`) and the relit views (`truth/relit/`, labels of the underlying view), where
//!   each light's radiance is the method's times the truth's `relit / original` ratio per
//!   channel, so the comparison is free of the global albedo–light scale;
//! - per method: `fitted` (the fit's materials.json), `flat fitted` and `pixel median`
//!   ([`baselines`]) under the fit's lights, and with `oracle` the true materials under the true
//!   lights (the floor the renderer's noise and the geometry leave);
//! - the renders of an input view under the fit's lights are multiplied by the fit's RGB
//!   exposure of that view (result.json `lights.exposure_rgb`; 1 without one), as the fit
//!   compared them with the photos; novel and relit views, and the oracle, are at exposure 1;
//! - on the coarse model (the paper's protocol) and on `truth/scene_true.obj`.
//!
//! Each (geometry, method, camera) is rendered once: a relit view with the camera of an input
//! view reuses that view's per-light images. All renders share one seed, so the methods see the
//! same sampling noise. Metrics: [`metrics`]. Rows average over every (image, part) pair of the
//! view kind with at least [`metrics::MIN_PART_PIXELS`] pixels; SSIM over the images.

mod backend;
pub mod baselines;
mod floor;
pub mod metrics;
mod report;
mod truth;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use psc_runtime::library::Library;

pub use floor::UnseenFloor;
pub use metrics::PartMetrics;
pub use report::{check_eval_dir, write_outputs};
pub use truth::ViewKind;

use backend::{GeometryContext, Image, RenderSettings};
use truth::{EvalView, Radiances};

/// A problem with the evaluation's input, worth showing to the user as is.
#[derive(Clone, Debug, PartialEq)]
pub struct EvalError(pub String);

impl std::fmt::Display for EvalError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for EvalError {}

impl From<psc_render::RenderError> for EvalError {
    fn from(e: psc_render::RenderError) -> Self {
        EvalError(e.to_string())
    }
}

/// Which mesh the views are rendered on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Geometry {
    /// The scene's coarse model (scene.json `mesh`): the paper's protocol.
    Model,
    /// `truth/scene_true.obj`: isolates what the fit controls from the model's misalignment.
    Truth,
}

impl Geometry {
    pub fn name(self) -> &'static str {
        match self {
            Geometry::Model => "model",
            Geometry::Truth => "truth",
        }
    }
}

/// The materials and lights a row renders with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Method {
    /// The true materials under the true lights (with `--oracle`).
    Oracle,
    /// The fit's materials.json under its lights.json.
    Fitted,
    /// A constant albedo per part fitted to the photos under the fit's lights.
    FlatFitted,
    /// The median photo colour per part, roughness 0.7, under the fit's lights.
    PixelMedian,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Oracle => "oracle",
            Method::Fitted => "fitted",
            Method::FlatFitted => "flat fitted",
            Method::PixelMedian => "pixel median",
        }
    }

    /// File-name form.
    pub fn slug(self) -> &'static str {
        match self {
            Method::Oracle => "oracle",
            Method::Fitted => "fitted",
            Method::FlatFitted => "flat_fitted",
            Method::PixelMedian => "pixel_median",
        }
    }
}

#[derive(Clone, Debug)]
pub struct EvalOptions {
    /// Samples per pixel of every evaluation render (the truth images have 256).
    pub spp: u32,
    pub seed: u64,
    /// Worker threads (None: all cores).
    pub threads: Option<usize>,
    pub geometries: Vec<Geometry>,
    /// The rows to render, in table order; [`Method::Oracle`] is the true materials under the
    /// true lights.
    pub methods: Vec<Method>,
    /// The view kinds to evaluate.
    pub kinds: Vec<ViewKind>,
    /// Rounds of the flat-fitted baseline's albedo update.
    pub flat_iterations: u32,
    /// Samples per pixel of the flat fit's renders (part means need few).
    pub flat_spp: u32,
    /// Path depth, Mitsuba convention (the truth renders used 6).
    pub max_depth: u32,
}

impl Default for EvalOptions {
    fn default() -> Self {
        EvalOptions {
            spp: 128,
            seed: 0,
            threads: None,
            geometries: vec![Geometry::Model, Geometry::Truth],
            methods: vec![Method::Fitted, Method::FlatFitted, Method::PixelMedian],
            kinds: vec![ViewKind::Input, ViewKind::Novel, ViewKind::Relit],
            flat_iterations: 5,
            flat_spp: 32,
            max_depth: 6,
        }
    }
}

/// What the evaluation is doing, for a progress display.
#[derive(Clone, Debug)]
pub enum Progress {
    /// The number of renders the evaluation will make.
    Planned { renders: usize },
    /// One render finished.
    Rendered { what: String },
}

/// The fit's output as the evaluation reads it.
#[derive(Clone, Debug)]
pub struct FitFiles {
    /// The `psc render --assign` file.
    pub materials: PathBuf,
    /// The `psc render --lights` file.
    pub lights: PathBuf,
    /// The fit's `result.json`, for the input views' exposures; optional (every view at 1
    /// without it, or without its `lights.exposure_rgb`).
    pub result: PathBuf,
}

impl FitFiles {
    /// `<dir>/materials.json`, `<dir>/lights.json` and `<dir>/result.json`.
    pub fn in_dir(dir: &Path) -> FitFiles {
        FitFiles {
            materials: dir.join("materials.json"),
            lights: dir.join("lights.json"),
            result: dir.join("result.json"),
        }
    }
}

/// One rendered image compared with its truth.
#[derive(Clone, Debug)]
pub struct ImageResult {
    pub geometry: Geometry,
    pub method: Method,
    pub kind: ViewKind,
    pub view: String,
    pub width: usize,
    pub height: usize,
    pub ssim: Option<f64>,
    pub parts: Vec<PartMetrics>,
    /// The render, linear RGB.
    pub render: Image,
}

/// The averages of one (geometry, view kind, method).
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    pub geometry: Geometry,
    pub kind: ViewKind,
    pub method: Method,
    pub rmse: f64,
    pub mean_colour: f64,
    pub colour_w1: f64,
    pub contrast_w1: f64,
    pub ssim: f64,
    /// (image, part) pairs averaged.
    pub parts: usize,
    pub images: usize,
}

/// The result of an evaluation.
#[derive(Clone, Debug)]
pub struct Evaluation {
    pub scene: PathBuf,
    pub fit: FitFiles,
    pub options: EvalOptions,
    pub part_names: Vec<String>,
    /// Linear albedo of the pixel-median baseline, per part (model order).
    pub pixel_median: Vec<[f32; 3]>,
    pub flat_albedo: Vec<[f32; 3]>,
    pub flat_roughness: Vec<f32>,
    /// Per round of the flat fit, the largest change of a linear albedo channel, and its part.
    pub flat_changes: Vec<(f64, String)>,
    /// Parts no input view shows (the baselines give them the median of all labelled pixels).
    pub unseen_parts: Vec<String>,
    /// Per (geometry, view kind) whose images show an unseen part: the floor those parts put
    /// under the fitted / pixel-median ratios (the `floor` module).
    pub unseen_floors: Vec<UnseenFloor>,
    /// The lights every method but the oracle renders under (scene order), and the true ones.
    pub fitted_lights: Vec<[f32; 3]>,
    pub true_lights: Vec<[f32; 3]>,
    /// The spread the fit's light solve states for each pair's log ratio (result.json), if any.
    pub stated_light_spread: Option<Vec<Vec<Option<f32>>>>,
    /// Per input view (scene order), the fit's RGB exposure its renders under the fit's lights
    /// are multiplied by.
    pub input_exposure: Vec<(String, [f32; 3])>,
    pub images: Vec<ImageResult>,
    pub rows: Vec<Row>,
    /// Per part with a true texture kind: the graph the fit chose and whether its family is
    /// the one that kind expects.
    pub graph_choice: Vec<GraphChoice>,
    pub warnings: Vec<String>,
    /// (stage, seconds) in order.
    pub timings: Vec<(String, f64)>,
    pub renders: usize,
    pub wall_seconds: f64,
}

/// A fitted part's graph against the kind of its true texture.
#[derive(Clone, Debug)]
pub struct GraphChoice {
    pub part: String,
    pub kind: String,
    pub graph: String,
    /// The graph's declared category (`category` in its `.psg`).
    pub category: String,
    /// `Some(matches)` for the kinds with an expected family, None for the others ("plain",
    /// "photo", "model_texture": any family may be right) and for parts the fit made
    /// homogeneous for lack of pixels.
    pub matches: Option<bool>,
}

/// The graph categories a true texture kind is expected to be fitted with.
pub fn expected_categories(kind: &str) -> Option<&'static [&'static str]> {
    match kind {
        "planks" => Some(&["wood"]),
        "stripes" => Some(&["fabric", "carpet", "wallpaper"]),
        "plaster" => Some(&["concrete"]),
        "tiles" => Some(&["tiles"]),
        "brick" => Some(&["brick"]),
        "marble" => Some(&["stone"]),
        _ => None,
    }
}

fn graph_choices(
    materials: &Path,
    kinds: &BTreeMap<String, String>,
    library: &Library,
) -> Result<Vec<GraphChoice>, EvalError> {
    let text = std::fs::read_to_string(materials).map_err(|e| EvalError(format!("{}: {e}", materials.display())))?;
    let v: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| EvalError(format!("{}:{}:{}: {e}", materials.display(), e.line(), e.column())))?;
    // Parts the fit gave a homogeneous material for lack of pixels (result.json's status) had
    // no choice to make: they are listed, not judged.
    let statuses: BTreeMap<String, String> = materials
        .parent()
        .map(|d| d.join("result.json"))
        .and_then(|p| std::fs::read_to_string(p).ok())
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| v.get("parts").and_then(|p| p.as_array()).cloned())
        .unwrap_or_default()
        .iter()
        .filter_map(|p| Some((p.get("name")?.as_str()?.to_string(), p.get("status")?.as_str()?.to_string())))
        .collect();
    let mut out = Vec::new();
    for (part, kind) in kinds {
        let Some(graph) =
            v.pointer(&format!("/parts/{}/graph", part.replace('~', "~0").replace('/', "~1"))).and_then(|g| g.as_str())
        else {
            continue;
        };
        let category = library.get(graph).map_or_else(|| "?".to_string(), |m| m.graph.info.category.clone());
        let chosen = !matches!(statuses.get(part).map(String::as_str), Some("homogeneous" | "unobserved"));
        let matches = expected_categories(kind).filter(|_| chosen).map(|cats| cats.contains(&category.as_str()));
        out.push(GraphChoice { part: part.clone(), kind: kind.clone(), graph: graph.to_string(), category, matches });
    }
    Ok(out)
}

/// Evaluate the fit in `fit` against the ground truth of `scene_dir`. Writes nothing; see
/// [`write_outputs`].
pub fn evaluate(
    scene_dir: &Path,
    fit: &FitFiles,
    library: &Library,
    opts: &EvalOptions,
    progress: &mut dyn FnMut(Progress),
) -> Result<Evaluation, EvalError> {
    let started = Instant::now();
    let mut timings = Vec::new();
    let mut stage = Instant::now();
    let mut lap = |name: &str, stage: &mut Instant| {
        timings.push((name.to_string(), stage.elapsed().as_secs_f64()));
        *stage = Instant::now();
    };
    if opts.spp == 0 || opts.flat_spp == 0 {
        return Err(EvalError("samples per pixel must be positive".into()));
    }
    if opts.geometries.is_empty() || opts.methods.is_empty() || opts.kinds.is_empty() {
        return Err(EvalError("nothing to evaluate: no geometry, method or view kind".into()));
    }
    for (what, path) in [("materials", &fit.materials), ("lights", &fit.lights)] {
        if !path.is_file() {
            return Err(EvalError(format!("{}: the fit's {what} file is missing", path.display())));
        }
    }
    let mut geometries = opts.geometries.clone();
    geometries.sort();
    geometries.dedup();
    let mut model = GeometryContext::load(scene_dir, None)?;
    let truth = truth::load(&model)?;
    let truth_mesh = if geometries.contains(&Geometry::Truth) {
        Some(backend::truth_mesh(scene_dir).ok_or_else(|| {
            EvalError(format!("{}: no truth/scene_true.obj (use --geometry model)", scene_dir.display()))
        })?)
    } else {
        None
    };

    let mut warnings = model.scene.warnings.clone();
    warnings.extend(truth.warnings.iter().cloned());
    let (fitted_lights, fitted_env) = backend::read_lights_file(&fit.lights, &model)?;
    let fitted_radiances = Radiances { lights: fitted_lights.clone(), environment: fitted_env };
    let psc_runtime::fitted::ResultLights { exposures, ratio_spread: stated_light_spread } =
        psc_runtime::fitted::read_result_lights(&fit.result).map_err(EvalError)?;
    let assigned_parts = assigned_part_names(&fit.materials)?;
    let fitted_model = model.assigned_materials(&fit.materials, library)?;
    let graph_choice = graph_choices(&fit.materials, &truth.part_kinds, library)?;
    for p in model.part_names() {
        if !assigned_parts.contains(p) {
            warnings
                .push(format!("materials.json does not name part '{p}': `fitted` renders it with its MTL material"));
        }
    }
    lap("load", &mut stage);

    let inputs: Vec<&EvalView> = truth.views.iter().filter(|v| v.kind == ViewKind::Input).collect();
    let input_exposure: Vec<(String, [f32; 3])> =
        inputs.iter().map(|v| (v.name.clone(), exposures.get(&v.name).copied().unwrap_or([1.0; 3]))).collect();
    // The exposure a method's render of a view is multiplied by.
    let exposure_of = |v: &EvalView, method: Method| -> [f32; 3] {
        match (v.kind, method) {
            (ViewKind::Input, m) if m != Method::Oracle => {
                input_exposure.iter().find(|(n, _)| *n == v.name).map_or([1.0; 3], |e| e.1)
            }
            _ => [1.0; 3],
        }
    };
    let evaluated: Vec<&EvalView> = truth.views.iter().filter(|v| opts.kinds.contains(&v.kind)).collect();
    let mut cameras = Vec::new();
    for v in &evaluated {
        let key = (v.camera.clone(), v.width, v.height);
        if !cameras.contains(&key) {
            cameras.push(key);
        }
    }
    let mut methods = opts.methods.clone();
    methods.sort();
    methods.dedup();
    let flat_rounds = if methods.contains(&Method::FlatFitted) { opts.flat_iterations } else { 0 };
    let planned = flat_rounds as usize * inputs.len() + geometries.len() * methods.len() * cameras.len();
    progress(Progress::Planned { renders: planned });
    let mut renders = 0usize;

    // Baselines, from the input photos on the coarse model.
    let masks = baselines::input_masks(&model, &inputs)?;
    let (pixel_median, unseen_parts) = baselines::pixel_median(&model, &inputs, &masks);
    let flat_roughness = baselines::fitted_roughness(&model, &inputs, &fitted_model, &assigned_parts)?;
    let flat_settings =
        RenderSettings { spp: opts.flat_spp, seed: opts.seed, max_depth: opts.max_depth, threads: opts.threads };
    let flat_slots = fitted_radiances.slots(model.has_environment());
    let aligned = baselines::aligned_masks(&model, &inputs, &masks)?;
    let (flat_albedo, flat_changes) = baselines::flat_fit(
        &mut model,
        &inputs,
        &aligned,
        &pixel_median,
        &flat_roughness,
        &flat_slots,
        &input_exposure.iter().map(|e| e.1).collect::<Vec<_>>(),
        &flat_settings,
        flat_rounds,
        &mut |what| {
            renders += 1;
            progress(Progress::Rendered { what });
        },
    )?;
    lap("flat fit", &mut stage);

    let settings = RenderSettings { spp: opts.spp, seed: opts.seed, max_depth: opts.max_depth, threads: opts.threads };
    let model_parts = model.part_names().to_vec();
    let mut images = Vec::new();
    let mut model_slot = Some(model);
    for &geometry in &geometries {
        let mut ctx = match geometry {
            Geometry::Model => model_slot.take().expect("the model context is used once"),
            Geometry::Truth => GeometryContext::load(scene_dir, truth_mesh.as_deref())?,
        };
        let flat_materials = constants_by_name(&ctx, &model_parts, &flat_albedo, &flat_roughness);
        let median_rough = vec![baselines::PIXEL_MEDIAN_ROUGHNESS; model_parts.len()];
        let median_materials = constants_by_name(&ctx, &model_parts, &pixel_median, &median_rough);
        for &method in &methods {
            let materials = match method {
                Method::Oracle => ctx.truth_materials(&mut warnings)?,
                Method::Fitted => ctx.assigned_materials(&fit.materials, library)?,
                Method::FlatFitted => flat_materials.clone(),
                Method::PixelMedian => median_materials.clone(),
            };
            let base = if method == Method::Oracle { &truth.lights } else { &fitted_radiances };
            for (camera, width, height) in &cameras {
                let slots = ctx.render_slots(&materials, camera, *width, *height, &settings)?;
                renders += 1;
                progress(Progress::Rendered {
                    what: format!("{} {} {}x{}", geometry.name(), method.name(), width, height),
                });
                for v in evaluated.iter().filter(|v| (&v.camera, v.width, v.height) == (camera, *width, *height)) {
                    let radiances = match (&v.relight, method) {
                        (None, _) => base.clone(),
                        (Some(_), Method::Oracle) => truth.relit_lights[&v.name].clone(),
                        (Some(ratio), _) => base.times(ratio),
                    };
                    let mut linear = backend::combine_slots(&slots, &radiances.slots(ctx.has_environment()));
                    let exposure = exposure_of(v, method);
                    for p in linear.iter_mut() {
                        p.iter_mut().zip(exposure).for_each(|(x, e)| *x *= e);
                    }
                    images.push(compare(geometry, method, v, linear));
                }
            }
        }
        lap(&format!("render {}", geometry.name()), &mut stage);
    }
    images.sort_by(|a, b| (a.geometry, a.kind, a.method, &a.view).cmp(&(b.geometry, b.kind, b.method, &b.view)));
    let rows = aggregate(&images);
    let unseen_floors = floor::unseen_floors(&images, &rows, &unseen_parts);
    lap("metrics", &mut stage);
    warnings.sort();
    warnings.dedup();
    Ok(Evaluation {
        scene: scene_dir.to_path_buf(),
        fit: fit.clone(),
        options: opts.clone(),
        part_names: model_parts,
        pixel_median,
        flat_albedo,
        flat_roughness,
        flat_changes,
        unseen_parts,
        unseen_floors,
        fitted_lights,
        true_lights: truth.lights.lights.clone(),
        stated_light_spread,
        input_exposure,
        images,
        graph_choice,
        rows,
        warnings,
        timings,
        renders,
        wall_seconds: started.elapsed().as_secs_f64(),
    })
}

/// Constant materials for `ctx`'s parts from per-part values given in `names` order (matched by
/// name; a part `names` lacks keeps its MTL material).
fn constants_by_name(
    ctx: &GeometryContext,
    names: &[String],
    albedo: &[[f32; 3]],
    roughness: &[f32],
) -> Vec<psc_render::MaterialBinding> {
    let mtl = ctx.mtl_materials();
    ctx.part_names()
        .iter()
        .enumerate()
        .map(|(i, name)| match names.iter().position(|p| p == name) {
            Some(j) => backend::constant_material(albedo[j], roughness[j]),
            None => mtl[i].clone(),
        })
        .collect()
}

/// The parts an assignment file names (its `parts` keys).
fn assigned_part_names(path: &Path) -> Result<Vec<String>, EvalError> {
    let text = std::fs::read_to_string(path).map_err(|e| EvalError(format!("{}: {e}", path.display())))?;
    let v: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| EvalError(format!("{}:{}:{}: {e}", path.display(), e.line(), e.column())))?;
    let parts = v
        .get("parts")
        .and_then(|p| p.as_object())
        .ok_or_else(|| EvalError(format!("{}: expected {{\"parts\": {{...}}}}", path.display())))?;
    Ok(parts.keys().cloned().collect())
}

/// Encode a render to sRGB and measure it against the view's truth.
fn compare(geometry: Geometry, method: Method, view: &EvalView, linear: Image) -> ImageResult {
    let encoded: Image = linear.iter().map(|p| p.map(backend::linear_to_srgb)).collect();
    let parts = match &view.labels {
        Some((labels, names)) => metrics::part_metrics(&encoded, &view.truth, view.width, view.height, labels, names),
        None => Vec::new(),
    };
    ImageResult {
        geometry,
        method,
        kind: view.kind,
        view: view.name.clone(),
        width: view.width,
        height: view.height,
        ssim: metrics::ssim(&encoded, &view.truth, view.width, view.height),
        parts,
        render: linear,
    }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for v in values {
        s += v;
        n += 1;
    }
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// One row per (geometry, kind, method) present, in that order.
fn aggregate(images: &[ImageResult]) -> Vec<Row> {
    let mut groups: BTreeMap<(Geometry, ViewKind, Method), Vec<&ImageResult>> = BTreeMap::new();
    for im in images {
        groups.entry((im.geometry, im.kind, im.method)).or_default().push(im);
    }
    groups
        .into_iter()
        .map(|((geometry, kind, method), ims)| {
            let parts: Vec<&PartMetrics> = ims.iter().flat_map(|i| &i.parts).collect();
            Row {
                geometry,
                kind,
                method,
                rmse: mean(parts.iter().map(|p| p.rmse)),
                mean_colour: mean(parts.iter().map(|p| p.mean_colour)),
                colour_w1: mean(parts.iter().map(|p| p.colour_w1)),
                contrast_w1: mean(parts.iter().filter_map(|p| p.contrast_w1)),
                ssim: mean(ims.iter().filter_map(|i| i.ssim)),
                parts: parts.len(),
                images: ims.len(),
            }
        })
        .collect()
}

impl Evaluation {
    /// The row of one (geometry, kind, method), if evaluated.
    pub fn row(&self, geometry: Geometry, kind: ViewKind, method: Method) -> Option<&Row> {
        self.rows.iter().find(|r| (r.geometry, r.kind, r.method) == (geometry, kind, method))
    }
}
