//! `psc render`: path-traced images, G-buffers, per-pixel light grids and per-light renders of a
//! scene folder or of a fit output folder (the scene its `result.json` names, with the fitted
//! `materials.json` and `lights.json`). Parses the options into a
//! `psc_runtime::view::ViewRequest`, opens the view there, and renders through `psc-render`.
//!
//! Light radiances: `--lights lights.json`, or `--lights truth` (a dev scene's true radiances,
//! for validation), else a fit output's `lights.json`, else every light at unit radiance (said
//! on stderr). Materials: `--assign` overrides the parts it names (over a fit's materials too);
//! `--set part.param=value` edits the assignment (`psc_runtime::edit`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use psc_render::{compute_light_grid_with_progress, image_io, LightGridOptions, LightsSource, RenderOptions, Renderer};
use psc_runtime::assign::Assignment;
use psc_runtime::edit::{apply_edits, Edit};
use psc_runtime::fitted::FitOutput;
use psc_runtime::library::{default_library_root, Library};
use psc_runtime::view::{open_view, CameraChoice, GeometryChoice, MaterialsChoice, OpenedView, ViewRequest};

use psc_base::output::Replace;

use crate::progress::Drawer;
use crate::{checks, Error, Failure, Usage};

#[derive(clap::ValueEnum, Clone, Copy, PartialEq, Eq, Debug)]
pub enum Materials {
    /// From the MTL: map_Kd textures, else Kd; roughness Pr, else 0.5.
    Mtl,
    /// The dev scenes' truth/truth.json materials (validation only).
    Truth,
}

#[derive(clap::ValueEnum, Clone, Copy, PartialEq, Eq, Debug)]
pub enum Geometry {
    /// The scene's coarse model (scene.json "mesh").
    Model,
    /// truth/scene_true.obj (validation only).
    Truth,
}

#[derive(clap::Args)]
pub struct Args {
    /// Scene folder (with scene.json), or a `psc fit` output folder (with result.json): its
    /// scene rendered with the fitted materials and lights.
    scene: PathBuf,
    /// View whose camera and resolution to use (default: the first view). Rendering a fit
    /// output from one of its views, the image is multiplied by the exposure the fit solved for
    /// that view (result.json), as `renders/<view>.png`, so it compares with the photo.
    #[arg(long, conflicts_with = "camera")]
    view: Option<String>,
    /// Camera JSON: {"position", "look_at", "up", "fov_y_deg"} or {"camera": {...}}, optional width/height.
    #[arg(long)]
    camera: Option<PathBuf>,
    /// Samples per pixel (at most 65 536).
    #[arg(long, default_value_t = 64, value_parser = checks::parse_spp)]
    spp: u32,
    /// Image size WxH (default: the view's photo, or the camera file's size).
    #[arg(long, value_parser = checks::parse_size)]
    size: Option<(usize, usize)>,
    /// Output: an image (.exr linear, .png sRGB), or a folder with --gbuffer/--light-grid/--per-light.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write G-buffers (part id, uv, normals, tangent frame, depth, position) into the --out folder.
    #[arg(long, conflicts_with_all = ["light_grid", "per_light", "bench"])]
    gbuffer: bool,
    /// Write the per-pixel incoming-light grid (lightgrid.json + lightgrid.bin) into the --out folder.
    #[arg(long, conflicts_with = "bench")]
    light_grid: bool,
    /// One image per light (and the environment) at unit radiance into the --out folder; with
    /// --light-grid, one grid per light in the same file.
    #[arg(long, conflicts_with = "bench")]
    per_light: bool,
    /// Light radiances: a file {"lights": [{"name", "radiance_rgb"}], "environment_scale"}, or
    /// `truth` for a dev scene's true radiances (validation only; `./truth` for a file of that
    /// name). Without it, every light has unit radiance.
    #[arg(long)]
    lights: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t = Materials::Mtl)]
    materials: Materials,
    /// Procedural materials: a JSON file assigning library graphs (with parameters and uv
    /// transforms) to parts; parts it does not name keep the --materials choice.
    #[arg(long)]
    assign: Option<PathBuf>,
    /// Override one fitted (or assigned) value: part.param=value, values comma-separated
    /// (colours linear r,g,b); also part.albedo_scale=r,g,b, part.roughness_scale=x,
    /// part.uv.rotation=deg, part.uv.scale=s, part.uv.log_scale=k (scale 1.5^k), part.uv.offset=u,v.
    /// Repeatable; needs a fit output or --assign.
    #[arg(long = "set")]
    edits: Vec<String>,
    /// Graph library folder for --assign, a fit output and --set (default: this checkout's graphs/).
    #[arg(long)]
    lib: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t = Geometry::Model)]
    geometry: Geometry,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores; at most 256).
    #[arg(long, value_parser = checks::parse_threads)]
    threads: Option<usize>,
    /// Path depth, Mitsuba convention (1 = emitters only, 2 = direct light), at most 1024.
    #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u32).range(1..=1024))]
    max_depth: u32,
    /// Light grid: one cell every N pixels.
    #[arg(long, default_value_t = 8, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    grid_stride: usize,
    /// Light grid: paths per hemisphere bin.
    #[arg(long, default_value_t = 4, value_parser = checks::parse_grid_samples)]
    grid_samples: u32,
    /// Print throughput: primary rays/s, path rays/s and the render time.
    #[arg(long)]
    bench: bool,
    /// Validation only: Lambertian shading (the specular lobe off), to compare with Mitsuba's `diffuse`.
    #[arg(long)]
    diffuse_only: bool,
    /// No progress (bars on a terminal, else a line log on stderr).
    #[arg(long)]
    quiet: bool,
    /// Replace an existing --out folder (G-buffers, light grid, per-light images) whole.
    #[arg(long)]
    force: bool,
}

/// The options as a request for the runtime, for a scene folder or a fit output (`fit`).
fn view_request(args: &Args, fit: Option<&FitOutput>) -> ViewRequest {
    ViewRequest {
        scene: fit.map_or_else(|| args.scene.clone(), |f| f.scene.clone()),
        geometry: match args.geometry {
            Geometry::Model => GeometryChoice::Model,
            Geometry::Truth => GeometryChoice::Truth,
        },
        camera: match (&args.camera, &args.view) {
            (Some(file), _) => CameraChoice::File(file.clone()),
            (None, Some(view)) => CameraChoice::View(view.clone()),
            (None, None) => CameraChoice::FirstView,
        },
        size: args.size,
        materials: match args.materials {
            Materials::Mtl => MaterialsChoice::Mtl,
            Materials::Truth => MaterialsChoice::Truth,
        },
        assignment: None,
        assign: args.assign.clone(),
        library: args.lib.clone(),
        lights: match (&args.lights, fit) {
            (None, Some(f)) => LightsSource::File(f.lights.clone()),
            (given, _) => LightsSource::from_arg(given.as_deref()),
        },
    }
}

/// The materials of a fit output and `--assign`, edited by `--set`: the request's in-memory
/// assignment (and the library that checked the edits, for opening the view with).
fn materials(args: &Args, fit: Option<&FitOutput>, req: &mut ViewRequest) -> Result<Option<Library>, Error> {
    let fitted = match fit {
        Some(f) => Some(f.assignment()?),
        None => None,
    };
    // Bad values are bad input (exit 1), like a bad value in an assignment file.
    let edits = args.edits.iter().map(|e| Edit::parse(e)).collect::<Result<Vec<_>, _>>()?;
    if edits.is_empty() {
        req.assignment = fitted;
        return Ok(None);
    }
    if fitted.is_none() && args.assign.is_none() {
        return Err(Usage("--set: edits a fit output's materials or an --assign file; give one".into()).into());
    }
    let mut merged = fitted.unwrap_or_default();
    if let Some(path) = req.assign.take() {
        merged.parts.extend(Assignment::read(&path)?.parts);
    }
    let library = Library::load(&args.lib.clone().unwrap_or_else(default_library_root))?;
    req.assignment = Some(apply_edits(&merged, &edits, &library)?);
    Ok(Some(library))
}

/// What is written where, decided from the options before any work is done.
enum Output {
    Image(PathBuf),
    Folder(PathBuf),
    /// `--bench` without `--out`: only figures are printed.
    Nothing,
}

fn output(args: &Args) -> Result<Output, Error> {
    let folder_mode = args.gbuffer || args.light_grid || args.per_light;
    match (&args.out, folder_mode) {
        (None, _) if args.bench => Ok(Output::Nothing),
        (None, true) => Err(Usage("--out: required; expected the folder to write into".into()).into()),
        (None, false) => {
            Err(Usage("--out: required; expected an image path ending in .png (sRGB) or .exr (linear)".into()).into())
        }
        (Some(p), true) => {
            let inputs: Vec<&Path> = std::iter::once(args.scene.as_path())
                .chain([&args.camera, &args.lights, &args.assign, &args.lib].into_iter().filter_map(|p| p.as_deref()))
                .collect();
            checks::new_folder("--out", p, replace(args), &inputs)?;
            Ok(Output::Folder(p.clone()))
        }
        (Some(p), false) => {
            checks::image_path("--out", p, &["png", "exr"])?;
            Ok(Output::Image(p.clone()))
        }
    }
}

fn replace(args: &Args) -> Replace {
    if args.force {
        Replace::Yes
    } else {
        Replace::No
    }
}

pub fn run(args: Args) -> Result<ExitCode, Error> {
    let output = output(&args)?;
    let fit = if FitOutput::is_fit_output(&args.scene) { Some(FitOutput::open(&args.scene)?) } else { None };
    let mut request = view_request(&args, fit.as_ref());
    let library = materials(&args, fit.as_ref(), &mut request)?;
    let drawer = Drawer::new(args.quiet || args.bench);
    let OpenedView { scene, camera, view, width, height, materials, radiances, warnings } =
        open_view(&request, library.as_ref(), &drawer)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    if !args.quiet {
        eprintln!("lights: {}", radiances.source);
    }
    let renderer = Renderer::new_with_progress(&scene, materials, &radiances, &drawer)?;
    let replace = replace(&args);
    let folder = || match &output {
        Output::Folder(dir) => Ok(dir.clone()),
        _ => Err(Failure("internal: no output folder for a folder output".into())),
    };

    if args.gbuffer {
        let dir = folder()?;
        let gb = renderer.gbuffer(&camera)?;
        gb.write_folder(&dir, replace)?;
        eprintln!("wrote G-buffers ({width}x{height}) to {}", dir.display());
        return Ok(ExitCode::SUCCESS);
    }
    if args.light_grid {
        let dir = folder()?;
        let opts = LightGridOptions {
            stride: args.grid_stride,
            samples_per_bin: args.grid_samples,
            seed: args.seed,
            max_depth: args.max_depth,
            threads: args.threads,
            per_light: args.per_light,
            diffuse_only: args.diffuse_only,
            ..Default::default()
        };
        let start = std::time::Instant::now();
        let grid = compute_light_grid_with_progress(&renderer, &camera, &opts, &drawer)?;
        grid.write_folder(&dir, replace)?;
        eprintln!(
            "wrote a {}x{} light grid (8x16 bins) to {} in {:.2} s",
            grid.grid_width,
            grid.grid_height,
            dir.display(),
            start.elapsed().as_secs_f64()
        );
        return Ok(ExitCode::SUCCESS);
    }

    let opts = RenderOptions {
        width,
        height,
        spp: args.spp,
        seed: args.seed,
        max_depth: args.max_depth,
        threads: args.threads,
        per_light: args.per_light,
        diffuse_only: args.diffuse_only,
        ..Default::default()
    };
    if args.bench {
        let (primary, p_secs) = renderer.primary_ray_benchmark(&camera, 16, args.threads)?;
        let result = renderer.render(&camera, &opts)?;
        let threads = args.threads.unwrap_or_else(rayon::current_num_threads);
        println!(
            "scene {} ({} triangles), {width}x{height}, {} spp, max_depth {}, {threads} threads",
            args.scene.display(),
            scene.mesh.triangles.len(),
            args.spp,
            args.max_depth
        );
        println!("primary rays: {:.2} Mrays/s ({primary} rays in {p_secs:.3} s)", primary as f64 / p_secs / 1e6);
        println!(
            "full paths:   {:.2} Mrays/s ({} rays incl. shadow rays, {:.2} rays/sample)",
            result.rays as f64 / result.seconds / 1e6,
            result.rays,
            result.rays as f64 / (width * height) as f64 / args.spp as f64
        );
        println!(
            "render time:  {:.3} s ({:.2} Msamples/s)",
            result.seconds,
            (width * height) as f64 * args.spp as f64 / result.seconds / 1e6
        );
        if let Output::Image(path) = &output {
            image_io::write_rgb(path, width, height, &result.image)?;
        }
        return Ok(ExitCode::SUCCESS);
    }
    let result = renderer.render_with_progress(&camera, &opts, &drawer)?;
    if args.per_light {
        let dir = folder()?;
        result.write_per_light_folder(&dir, replace)?;
        eprintln!(
            "wrote {} per-light images (unit radiance) and combined.exr to {} in {:.2} s",
            result.per_light.len(),
            dir.display(),
            result.seconds
        );
    } else if let Output::Image(path) = &output {
        let mut image = result.image;
        // A fit's exposure belongs to the camera of the photo it was solved on, not to the
        // lights: a relit input view keeps it; a camera file has none.
        if let (Some(fit), Some(view)) = (&fit, &view) {
            let exposure = fit.exposure(view);
            if exposure != [1.0; 3] {
                image.iter_mut().for_each(|p| p.iter_mut().zip(exposure).for_each(|(c, e)| *c *= e));
                if !args.quiet {
                    eprintln!(
                        "exposure: the fit's for view '{view}', {:.3} {:.3} {:.3} (RGB)",
                        exposure[0], exposure[1], exposure[2]
                    );
                }
            }
        }
        image_io::write_rgb(path, width, height, &image)?;
        eprintln!("wrote {} ({width}x{height}, {} spp) in {:.2} s", path.display(), args.spp, result.seconds);
    }
    Ok(ExitCode::SUCCESS)
}
