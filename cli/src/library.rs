//! `psc library [--sheet sheet.png]`: compiles the whole graph library, lists its graphs with
//! their sizes, optionally times a bake of each and writes a contact sheet (every graph at its
//! defaults and a few random variants, lit, with its name).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use psc_base::{limits, SplitMix64};
use psc_runtime::bake;
use psc_runtime::library::{default_library_root, Library};
use psc_runtime::params::ParamSpace;
use psc_runtime::sheet::{self, Cell};

use psc_base::progress::Progress;

use crate::progress::Drawer;
use crate::{checks, Error, Failure, Usage};

#[derive(clap::Args)]
pub struct Args {
    /// Library root (default: the shipped graphs/ folder).
    #[arg(long)]
    pub lib: Option<PathBuf>,
    /// Write a contact sheet to this PNG.
    #[arg(long)]
    pub sheet: Option<PathBuf>,
    /// Size of each sample on the sheet, in pixels.
    #[arg(long, default_value_t = 160, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub size: usize,
    /// Random variants per graph on the sheet, besides the defaults.
    #[arg(long, default_value_t = 3)]
    pub variants: usize,
    /// Seed of the random variants.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Graphs per sheet row (each graph takes 1 + variants cells).
    #[arg(long, default_value_t = 2, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub per_row: usize,
    /// Also compile every graph's fused forward+adjoint kernel (normally compiled on first use
    /// by the fit) and report the time.
    #[arg(long)]
    pub gradients: bool,
    /// Also time a bake of every graph at this size (e.g. 2048) and report the slowest.
    #[arg(long, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub bench: Option<usize>,
    /// Only graphs whose name or category contains one of these (comma-separated).
    #[arg(long)]
    pub only: Option<String>,
    /// No progress (bars on a terminal, else a line log on stderr).
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(args: Args) -> Result<ExitCode, Error> {
    if let Some(sheet) = &args.sheet {
        checks::image_path("--sheet", sheet, &["png"])?;
        checks::bake_size("--size", args.size)?;
    }
    if let Some(size) = args.bench {
        checks::bake_size("--bench", size)?;
    }
    let root = args.lib.clone().unwrap_or_else(default_library_root);
    let started = Instant::now();
    let library = Library::load(&root).map_err(|e| Failure(e.to_string()))?;
    let filters: Vec<String> =
        args.only.as_deref().map(|s| s.split(',').map(str::to_string).collect()).unwrap_or_default();
    let materials: Vec<_> = library
        .materials
        .iter()
        .filter(|m| {
            filters.is_empty()
                || filters
                    .iter()
                    .any(|f| m.graph.info.name.contains(f.as_str()) || m.graph.info.category.contains(f.as_str()))
        })
        .collect();
    if materials.is_empty() {
        let mut categories: Vec<&str> = library.materials.iter().map(|m| m.graph.info.category.as_str()).collect();
        categories.sort_unstable();
        categories.dedup();
        return Err(Usage(format!(
            "--only: no graph's name or category contains {}; categories: {}",
            filters.iter().map(|f| format!("'{f}'")).collect::<Vec<_>>().join(" or "),
            categories.join(", ")
        ))
        .into());
    }
    if args.sheet.is_some() {
        sheet_fits(&args, materials.len())?;
    }
    println!(
        "{} graphs from {} (front end {:.2} s, JIT {:.2} s, total {:.2} s)",
        library.materials.len(),
        root.display(),
        library.front_end_time.as_secs_f64(),
        library.jit_time.as_secs_f64(),
        started.elapsed().as_secs_f64()
    );
    if args.gradients {
        let gradients = library.compile_gradients().map_err(|e| Failure(e.to_string()))?;
        println!(
            "gradient kernels: {:.2} s more ({} fused forward+adjoint kernels); library JIT in all {:.2} s",
            gradients.as_secs_f64(),
            library.materials.len(),
            (library.jit_time + gradients).as_secs_f64()
        );
    }
    println!("{:<26} {:<14} {:>6} {:>6} {:>8}", "graph", "category", "params", "slots", "ops");
    for m in &materials {
        let info = &m.graph.info;
        println!(
            "{:<26} {:<14} {:>6} {:>6} {:>8}",
            info.name,
            info.category,
            info.params.len(),
            info.num_slots(),
            m.graph.forward.op_count()
        );
    }

    let drawer = Drawer::new(args.quiet);
    if let Some(size) = args.bench {
        let mut times = Vec::new();
        drawer.start(&format!("bake at {size}²"), Some(materials.len() as u64), "graphs");
        for m in &materials {
            let params = m.graph.info.default_params();
            let t = Instant::now();
            m.kernel.eval_grid(&params, size, size).map_err(|e| Failure(e.to_string()))?;
            times.push((t.elapsed().as_secs_f64(), m.graph.info.name.clone()));
            drawer.advance(1);
        }
        drawer.finish();
        times.sort_by(|a, b| b.0.total_cmp(&a.0));
        println!("bake at {size}² (forward, all channels), slowest first:");
        for (t, name) in &times {
            println!("  {name:<26} {t:>7.3} s");
        }
    }

    if let Some(path) = &args.sheet {
        let mut cells = Vec::new();
        drawer.start("contact sheet", Some((materials.len() * (args.variants + 1)) as u64), "samples");
        for m in &materials {
            let info = &m.graph.info;
            let eval = |p: &[f32], u: &[f32], v: &[f32]| m.kernel.eval(p, u, v).map_err(|e| e.to_string());
            let space = ParamSpace::new(info);
            let mut rng = SplitMix64::new(args.seed ^ hash_name(&info.name));
            for k in 0..=args.variants {
                let params = if k == 0 { space.defaults() } else { space.random(&mut rng) };
                let maps = bake::bake(&eval, &params, args.size).map_err(Failure)?;
                let label = if k == 0 { info.name.clone() } else { format!("{} #{k}", info.category) };
                cells.push(Cell { label, maps });
                drawer.advance(1);
            }
        }
        drawer.finish();
        let per_row = args.per_row.max(1) * (args.variants + 1);
        sheet::write_sheet(path, &cells, per_row)
            .map_err(|e| Failure(format!("cannot write {}: {e}", path.display())))?;
        println!("contact sheet: {} ({} samples)", path.display(), cells.len());
    }
    Ok(ExitCode::SUCCESS)
}

/// The contact sheet of `graphs` graphs fits the limits: every sample's maps are held until the
/// sheet is composed (about 40 bytes a texel), and the sheet is one image (3 bytes a pixel; each
/// sample takes its size plus a margin and a label strip, about 8 and 24 pixels).
fn sheet_fits(args: &Args, graphs: usize) -> Result<(), Usage> {
    let cells = (graphs as u64).saturating_mul(args.variants as u64 + 1);
    let size = args.size as u64;
    limits::check_elements(
        format!("contact sheet of {cells} samples of {size}x{size}"),
        &[cells, size, size],
        u64::MAX,
        "texels",
        40,
    )
    .map_err(|e| checks::over_limit("--size/--variants", e))?;
    let per_row = (args.per_row as u64).saturating_mul(args.variants as u64 + 1);
    let rows = cells.div_ceil(per_row.max(1));
    let (w, h) = (per_row.saturating_mul(size + 8), rows.saturating_mul(size + 24));
    limits::check_image("contact sheet", w, h, 3).map(drop).map_err(|e| checks::over_limit("--sheet", e))
}

/// A stable per-graph seed offset, so each graph's variants do not depend on the others.
fn hash_name(name: &str) -> u64 {
    name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ b as u64).wrapping_mul(0x1000_0000_01b3))
}
