//! `psc render`: path-traced images, G-buffers, per-pixel light grids and per-light renders of a
//! scene folder. A thin layer over `psc-render`.
//!
//! Light radiances: `--lights lights.json`, `--lights truth` (the dev scenes' truth/truth.json,
//! validation only), else unit radiance with a warning saying so.

use std::path::PathBuf;
use std::process::ExitCode;

use psc_render::camera::{load_camera_file, Camera};
use psc_render::{
    compute_light_grid_with_progress, image_io, truth, LightGridOptions, LightRadiances, LightsSource, RenderOptions,
    Renderer, Scene,
};

use crate::Failure;

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
    /// Scene folder (with scene.json).
    scene: PathBuf,
    /// View whose camera and resolution to use (default: the first view).
    #[arg(long, conflicts_with = "camera")]
    view: Option<String>,
    /// Camera JSON: {"position", "look_at", "up", "fov_y_deg"} or {"camera": {...}}, optional width/height.
    #[arg(long)]
    camera: Option<PathBuf>,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    spp: u32,
    /// Image size WxH (default: the view's photo, or the camera file's size).
    #[arg(long, value_parser = parse_size)]
    size: Option<(usize, usize)>,
    /// Output: an image (.exr linear, .png sRGB), or a folder with --gbuffer/--light-grid/--per-light.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write G-buffers (part id, uv, normals, tangent frame, depth, position) into the --out folder.
    #[arg(long)]
    gbuffer: bool,
    /// Write the per-pixel incoming-light grid (lightgrid.json + lightgrid.bin) into the --out folder.
    #[arg(long)]
    light_grid: bool,
    /// One image per light (and the environment) at unit radiance into the --out folder; with
    /// --light-grid, one grid per light in the same file.
    #[arg(long)]
    per_light: bool,
    /// Light radiances: {"lights": [{"name", "radiance_rgb"}], "environment_scale"}, or `truth`
    /// for a dev scene's truth/truth.json (default: unit radiance, with a warning).
    #[arg(long)]
    lights: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t = Materials::Mtl)]
    materials: Materials,
    /// Procedural materials: a JSON file assigning library graphs (with parameters and uv
    /// transforms) to parts; parts it does not name keep the --materials choice.
    #[arg(long)]
    assign: Option<PathBuf>,
    /// Graph library folder for --assign (default: this checkout's graphs/).
    #[arg(long, requires = "assign")]
    lib: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t = Geometry::Model)]
    geometry: Geometry,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Path depth, Mitsuba convention (1 = emitters only, 2 = direct light).
    #[arg(long, default_value_t = 6)]
    max_depth: u32,
    /// Light grid: one cell every N pixels.
    #[arg(long, default_value_t = 8)]
    grid_stride: usize,
    /// Light grid: paths per hemisphere bin.
    #[arg(long, default_value_t = 4)]
    grid_samples: u32,
    /// Print throughput: primary rays/s, path rays/s and the render time.
    #[arg(long)]
    bench: bool,
    /// Validation only: Lambertian shading (the specular lobe off), to compare with Mitsuba's `diffuse`.
    #[arg(long)]
    diffuse_only: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Replace an existing --out folder (G-buffers, light grid, per-light images) whole.
    #[arg(long)]
    force: bool,
}

fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WxH, e.g. 320x240")?;
    let w: usize = w.trim().parse().map_err(|_| "bad width")?;
    let h: usize = h.trim().parse().map_err(|_| "bad height")?;
    if w == 0 || h == 0 {
        return Err("size must be positive".into());
    }
    Ok((w, h))
}

/// A minimal terminal drawer for the library's progress reports (the platform helper replaces
/// it with the CLI's own bar and line-log drawer).
struct Bar {
    show: bool,
    bar: std::sync::Mutex<Option<indicatif::ProgressBar>>,
}

impl psc_base::progress::Progress for Bar {
    fn start(&self, stage: &str, total: Option<u64>, unit: &str) {
        if !self.show {
            return;
        }
        let bar = indicatif::ProgressBar::with_draw_target(total, indicatif::ProgressDrawTarget::stderr());
        let template = format!("{{msg}} [{{bar:40}}] {{pos}}/{{len}} {unit}, {{elapsed}} (eta {{eta}})");
        if let Ok(style) = indicatif::ProgressStyle::with_template(&template) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_message(stage.to_string());
        *self.bar.lock().unwrap_or_else(|p| p.into_inner()) = Some(bar);
    }
    fn advance(&self, n: u64) {
        if let Some(b) = self.bar.lock().unwrap_or_else(|p| p.into_inner()).as_ref() {
            b.inc(n);
        }
    }
    fn finish(&self) {
        if let Some(b) = self.bar.lock().unwrap_or_else(|p| p.into_inner()).take() {
            b.finish_and_clear();
        }
    }
}

pub fn run(args: Args) -> Result<ExitCode, Failure> {
    let bar = Bar { show: !args.quiet && !args.bench, bar: Default::default() };
    let mesh_override = match args.geometry {
        Geometry::Model => None,
        Geometry::Truth => Some(truth::truth_mesh(&args.scene).ok_or("no truth/scene_true.obj next to the scene")?),
    };
    let scene = Scene::load_with_progress(&args.scene, mesh_override.as_deref(), &bar)?;
    let mut warnings = scene.warnings.clone();

    // Camera and size.
    let (spec, default_size, context) = if let Some(path) = &args.camera {
        let file = load_camera_file(path)?;
        let size = file.size.or_else(|| scene.views.first().map(|v| (v.width, v.height))).unwrap_or((640, 480));
        (file.camera, size, path.display().to_string())
    } else {
        let view = match &args.view {
            Some(name) => scene.view(name).ok_or_else(|| {
                let names: Vec<&str> = scene.views.iter().map(|v| v.name.as_str()).collect();
                format!("no view '{name}' (views: {})", names.join(", "))
            })?,
            None => scene.views.first().ok_or("the scene has no views; give --camera")?,
        };
        (view.camera_spec.clone(), (view.width, view.height), format!("view '{}'", view.name))
    };
    let (width, height) = args.size.unwrap_or(default_size);
    let camera = Camera::new(&spec, width, height, &context)?;

    let mut materials = match args.materials {
        Materials::Mtl => scene.mtl_materials(&mut warnings),
        Materials::Truth => truth::truth_materials(&scene, &mut warnings)?,
    };
    if let Some(assign) = &args.assign {
        let root = args.lib.clone().unwrap_or_else(psc_runtime::library::default_library_root);
        let library = psc_runtime::library::Library::load(&root)?;
        psc_runtime::assign::apply_assignment(assign, &library, &scene.mesh.part_names, &mut materials)?;
    }
    let radiances = LightRadiances::resolve(&scene, &LightsSource::from_arg(args.lights.as_deref()), &mut warnings)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    if !args.quiet {
        eprintln!("lights: {}", radiances.source);
    }
    let renderer = Renderer::new_with_progress(&scene, materials, &radiances, &bar)?;
    let out = args.out.clone();
    let replace = if args.force { psc_base::output::Replace::Yes } else { psc_base::output::Replace::No };
    let need_out = || out.clone().ok_or_else(|| Failure("--out is required".into()));

    if args.gbuffer {
        let dir = need_out()?;
        let gb = renderer.gbuffer(&camera)?;
        gb.write_folder(&dir, replace)?;
        eprintln!("wrote G-buffers ({width}x{height}) to {}", dir.display());
        return Ok(ExitCode::SUCCESS);
    }
    if args.light_grid {
        let dir = need_out()?;
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
        let grid = compute_light_grid_with_progress(&renderer, &camera, &opts, &bar)?;
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
        if let Some(path) = &out {
            image_io::write_rgb(path, width, height, &result.image)?;
        }
        return Ok(ExitCode::SUCCESS);
    }
    let result = renderer.render_with_progress(&camera, &opts, &bar)?;
    if args.per_light {
        let dir = need_out()?;
        result.write_per_light_folder(&dir, replace)?;
        eprintln!(
            "wrote {} per-light images (unit radiance) and combined.exr to {} in {:.2} s",
            result.per_light.len(),
            dir.display(),
            result.seconds
        );
    } else {
        let path = need_out()?;
        image_io::write_rgb(&path, width, height, &result.image)?;
        eprintln!("wrote {} ({width}x{height}, {} spp) in {:.2} s", path.display(), args.spp, result.seconds);
    }
    Ok(ExitCode::SUCCESS)
}
