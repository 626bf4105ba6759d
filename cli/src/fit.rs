//! `psc fit <scene> --out <dir>`: fits a procedural material to every part of a scene from its
//! photos (and estimates the lighting), then writes the result folder. A thin layer over
//! `psc-fit`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use psc_base::output::{Replace, StagedDir};
use psc_base::progress::Progress as _;
use psc_export::ExportOptions;
use psc_fit::output::{self, OutputOptions};
use psc_fit::pipeline::{continue_fit, fit_scene, Continue, FitOptions, Progress};
use psc_fit::targets::WindowShape;
use psc_render::scene::{LightRadiances, Scene};
use psc_runtime::assign::Assignment;
use psc_runtime::library::{default_library_root, Library};

use crate::progress::Drawer;
use crate::{checks, Error, Failure, Usage};

#[derive(clap::Args)]
pub struct Args {
    /// Scene folder (photoscene-scene/1: scene.json, OBJ model, photos, optional labels and lights).
    scene: PathBuf,
    /// Output folder (written whole or not at all).
    #[arg(long)]
    out: PathBuf,
    /// Replace the output folder if it exists.
    #[arg(long)]
    force: bool,
    /// Start from the fit already in --out (its result.json): keep every part's graph,
    /// parameters and UV transform, and run only the light solve and the albedo/roughness
    /// re-fit rounds; --out is then replaced.
    #[arg(long, conflicts_with = "resume")]
    refit_only: bool,
    /// Continue the fit already in --out (its result.json): every fitted part keeps its graph
    /// (unless --graph forces another) and its optimisation continues from the fitted state for
    /// --iterations more, without selection or global UV search; then the light rounds run
    /// again from the previous lights; --out is then replaced.
    #[arg(long)]
    resume: bool,
    /// Known light radiances (the `psc render --lights` format) instead of estimating them.
    #[arg(long)]
    lights: Option<PathBuf>,
    /// Force a part's graph, skipping selection: --graph floor=oak_planks (repeatable).
    #[arg(long = "graph", value_parser = parse_pair)]
    graphs: Vec<(String, String)>,
    /// Graph library folder (default: this checkout's graphs/).
    #[arg(long)]
    lib: Option<PathBuf>,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores; at most 256).
    #[arg(long, value_parser = checks::parse_threads)]
    threads: Option<usize>,
    /// Random exemplars per graph for selection (at most 1000: a hundred times PhotoScene's ten).
    #[arg(long, default_value_t = fit_defaults().select.exemplars, value_parser = parse_exemplars)]
    exemplars: usize,
    /// Graphs at the top of the selection's pattern vote that each run a start of the fit
    /// (global UV search and a short run), beside the whole-loss vote's winner; the one that
    /// reaches the lowest loss is fitted.
    #[arg(long, default_value_t = fit_defaults().select.contenders as u16, value_parser = clap::value_parser!(u16).range(1..=16))]
    contenders: u16,
    /// Most gradient iterations per part.
    #[arg(long, default_value_t = fit_defaults().fit.max_iterations)]
    iterations: u32,
    /// Most photo pixels a part is fitted on (larger parts: the window with the most usable
    /// pixels); at least the 500 a part needs to be fitted at all.
    #[arg(long, default_value_t = fit_defaults().fit_pixels, value_parser = parse_fit_pixels)]
    fit_pixels: usize,
    /// The shape of the window a part with more usable pixels than `--fit-pixels` is fitted on:
    /// the aspect of the part's bounding box, or as square as the part allows at the same area
    /// (so that a wide floor is fitted on a square of it rather than a thin strip; it measured
    /// better graph families, worse texture contrast: see fit/src/targets.rs).
    #[arg(long, value_enum, default_value_t = fit_defaults().fit_window_shape.into())]
    fit_window: FitWindow,
    /// Most photo pixels of a part that graph selection and the UV search render each
    /// candidate on (larger parts: the window with the most usable pixels).
    #[arg(long, default_value_t = fit_defaults().search_pixels, value_parser = parse_fit_pixels)]
    search_pixels: usize,
    /// Most supersamples per pixel axis when selection and the UV search render a candidate
    /// (the fit itself takes up to 4): more cost time, and keep a fine pattern on a far part from
    /// aliasing into noise.
    #[arg(long, default_value_t = fit_defaults().fit.search_sampling.max_per_axis, value_parser = clap::value_parser!(u32).range(1..=8))]
    search_samples: u32,
    /// Photos with more pixels are fitted at a working resolution within this many: averaged
    /// over blocks of the smallest whole number of pixels that brings them within it (0: always
    /// the full resolution, which for a 12-megapixel photo takes hours; else at least 16384).
    #[arg(long, default_value_t = psc_fit::pipeline::DEFAULT_MAX_PHOTO_PIXELS, value_parser = parse_photo_budget)]
    max_photo_pixels: usize,
    /// At most this many rounds of global light solve + albedo/roughness re-fit after the
    /// first fit (they stop early once no light or exposure moves by more than 2%).
    #[arg(long, default_value_t = fit_defaults().refit_rounds)]
    refit_rounds: usize,
    /// Size of the baked maps per part (0: none).
    #[arg(long, default_value_t = OutputOptions::default().texture_size)]
    texture_size: usize,
    /// Samples per pixel of the re-rendered input views (0: none).
    #[arg(long, default_value_t = OutputOptions::default().render_spp)]
    render_spp: u32,
    /// No progress output.
    #[arg(long)]
    quiet: bool,
}

#[derive(clap::ValueEnum, Clone, Copy, PartialEq, Eq, Debug)]
enum FitWindow {
    Box,
    Square,
}

impl From<WindowShape> for FitWindow {
    fn from(shape: WindowShape) -> Self {
        match shape {
            WindowShape::BoundingBox => FitWindow::Box,
            WindowShape::Square => FitWindow::Square,
        }
    }
}

impl From<FitWindow> for WindowShape {
    fn from(window: FitWindow) -> Self {
        match window {
            FitWindow::Box => WindowShape::BoundingBox,
            FitWindow::Square => WindowShape::Square,
        }
    }
}

/// The library's defaults, which the options' defaults show rather than repeat (the output
/// options' likewise come from `OutputOptions::default()`).
fn fit_defaults() -> FitOptions {
    FitOptions::default()
}

fn parse_exemplars(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n @ 1..=1000) => Ok(n),
        Ok(n) => Err(format!("expected 1 to 1000 exemplars per graph, got {n}")),
        Err(e) => Err(format!("{e}")),
    }
}

/// Fewer fitted pixels than a part needs to be fitted at all (`FitOptions::min_pixels`) would
/// fit its texture on a handful of them.
fn parse_fit_pixels(s: &str) -> Result<usize, String> {
    let n: usize = s.parse().map_err(|e| format!("{e}"))?;
    let least = fit_defaults().min_pixels;
    if n < least {
        return Err(format!("{n} pixels are too few to fit a part's texture on; give at least {least}"));
    }
    Ok(n)
}

/// Fewer working pixels leave too few for a part's texture (a fit wants 500 usable pixels of a
/// part) and for the light estimate.
const MIN_PHOTO_BUDGET: usize = 16_384;

fn parse_photo_budget(s: &str) -> Result<usize, String> {
    let n: usize = s.parse().map_err(|e| format!("{e}"))?;
    if n != 0 && n < MIN_PHOTO_BUDGET {
        return Err(format!(
            "{n} pixels are too few to fit a room at; give 0 (full resolution) or at least {MIN_PHOTO_BUDGET}"
        ));
    }
    Ok(n)
}

fn parse_pair(s: &str) -> Result<(String, String), String> {
    let (a, b) = s.split_once('=').ok_or("expected part=graph")?;
    if a.is_empty() || b.is_empty() {
        return Err("expected part=graph".into());
    }
    Ok((a.to_string(), b.to_string()))
}

/// The fit's stages and notes drawn by the command line's progress drawer.
struct FitProgress<'a> {
    drawer: &'a Drawer,
    open: AtomicBool,
}

impl Progress for FitProgress<'_> {
    fn stage(&self, name: &str, total: u64) {
        if self.open.swap(true, Ordering::Relaxed) {
            self.drawer.finish();
        }
        self.drawer.start(name, Some(total), "steps");
    }
    fn advance(&self, steps: u64) {
        self.drawer.advance(steps);
    }
    fn note(&self, text: &str) {
        self.drawer.line(text);
    }
}

impl FitProgress<'_> {
    fn done(&self) {
        if self.open.swap(false, Ordering::Relaxed) {
            self.drawer.finish();
        }
    }
}

pub fn run(args: Args) -> Result<ExitCode, Error> {
    let mut forced = BTreeMap::new();
    for (part, graph) in &args.graphs {
        if let Some(first) = forced.insert(part.clone(), graph.clone()) {
            return Err(Usage(format!(
                "--graph: part '{part}' is forced twice ({first}, then {graph}); give each part once"
            ))
            .into());
        }
    }
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().map_err(|e| Failure(e.to_string()))?;
    }
    // Sizes are checked before any work: a bake past the texel limit would abort on its
    // allocation after minutes of fitting.
    if args.texture_size > 0 {
        checks::bake_size("--texture-size", args.texture_size)?;
    }
    if args.render_spp > 0 {
        psc_base::limits::check_count(
            "samples per pixel",
            u64::from(args.render_spp),
            psc_base::limits::MAX_SPP,
            "samples",
        )
        .map_err(|e| checks::over_limit("--render-spp", e))?;
    }
    let started = Instant::now();
    let scene = Scene::load(&args.scene)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let root = args.lib.clone().unwrap_or_else(default_library_root);
    let library = Library::load(&root)?;
    let radiances = match &args.lights {
        Some(p) => {
            let mut warnings = Vec::new();
            let r = LightRadiances::from_file(p, &scene, &mut warnings)?;
            // Fitting "under known lights" with some unknown would fit the albedos to a
            // guess: what `psc render` only warns about is an error here.
            if !warnings.is_empty() {
                return Err(Failure(format!(
                    "--lights must give every light of the scene and no other: {}",
                    warnings.join("; ")
                ))
                .into());
            }
            Some(r)
        }
        None => None,
    };
    // Refuse an existing --out before hours of work, not after; the folder is built aside and
    // renamed into place at the end, so an error or Ctrl-C leaves nothing half-written.
    let from_previous = args.refit_only || args.resume;
    let previous = if from_previous { Some(output::read_previous(&args.out)?) } else { None };
    let replace = if args.force || from_previous { Replace::Yes } else { Replace::No };
    // The previous fit in --out (--resume, --refit-only) has been read: it is replaced by design.
    let inputs: Vec<&Path> = std::iter::once(args.scene.as_path())
        .chain([&args.lights, &args.lib].into_iter().filter_map(|p| p.as_deref()))
        .collect();
    checks::keeps_inputs("--out", &args.out, &inputs)?;
    let staged = StagedDir::new(&args.out, replace).map_err(|e| Failure(e.to_string()))?;
    let mut options = FitOptions { seed: args.seed, ..Default::default() };
    options.forced = forced;
    options.select.exemplars = args.exemplars;
    options.select.contenders = usize::from(args.contenders);
    options.fit.max_iterations = args.iterations;
    options.refit_rounds = args.refit_rounds;
    options.fit_pixels = args.fit_pixels.max(1);
    options.search_pixels = args.search_pixels;
    options.fit_window_shape = args.fit_window.into();
    options.fit.search_sampling.max_per_axis = args.search_samples;
    options.max_photo_pixels = args.max_photo_pixels;
    let drawer = Drawer::new(args.quiet);
    let progress = FitProgress { drawer: &drawer, open: AtomicBool::new(false) };
    let result = match &previous {
        Some(p) => {
            let how = if args.resume { Continue::Resume } else { Continue::RefitOnly };
            continue_fit(&scene, &library, radiances.as_ref(), p, how, &options, &progress)?
        }
        None => fit_scene(&scene, &library, radiances.as_ref(), &options, &progress)?,
    };
    let output_options = OutputOptions {
        texture_size: args.texture_size,
        render_spp: args.render_spp,
        force: args.force || from_previous,
        seed: args.seed,
        command: std::env::args().collect::<Vec<_>>().join(" "),
    };
    progress.stage("write results", 1);
    output::write_into(staged.path(), &scene, &library, &result, &output_options)?;
    // The same materials and lights for other tools: exactly what materials.json says.
    let exported = if args.texture_size > 0 {
        progress.stage("export glTF and Mitsuba scenes", 1);
        let assignment = Assignment::read(&staged.path().join("materials.json"))?;
        let export_options = ExportOptions { texture_size: args.texture_size };
        let lights = result.light_radiances(&scene);
        Some(psc_export::write_all(staged.path(), &scene, &library, &assignment, &lights, &export_options)?)
    } else {
        None
    };
    progress.stage("report", 1);
    let report_options =
        psc_report::ReportOptions { scene: Some(args.scene.clone()), shown_as: Some(args.out.clone()) };
    psc_report::write_report_with(staged.path(), &report_options).map_err(|e| Failure(e.to_string()))?;
    staged.commit().map_err(|e| Failure(e.to_string()))?;
    progress.done();
    if !args.quiet {
        eprintln!(
            "fitted {} parts in {:.1} s; wrote {}",
            result.parts.len(),
            started.elapsed().as_secs_f64(),
            args.out.display()
        );
        eprintln!("report: {}", args.out.join("report.html").display());
        if let Some(summary) = &exported {
            for w in &summary.warnings {
                eprintln!("warning: {w}");
            }
            eprintln!("glTF: {}", args.out.join("scene.gltf").display());
            eprintln!("Mitsuba: {}", args.out.join("scene_mitsuba.xml").display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
