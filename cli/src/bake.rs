//! `psc bake <graph> --size N [--params p.json] [--random K --seed S] --out dir/`: bakes a
//! graph's albedo (sRGB PNG + linear EXR), normal (PNG, OpenGL), roughness (PNG) and height
//! (EXR) maps. The graph is a `.psg` file (its first graph, or `--name`) or the name of a
//! graph of the library.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use psc_base::limits;
use psc_base::output::{Replace, StagedDir};
use psc_base::SplitMix64;
use psc_runtime::bake;
use psc_runtime::library::Material;
use psc_runtime::lookup::find_graph;
use psc_runtime::params::ParamSpace;

use psc_base::progress::Progress;

use crate::progress::Drawer;
use crate::{checks, Error, Failure};

#[derive(clap::Args)]
pub struct Args {
    /// A .psg file, or the name of a library graph (e.g. `oak_planks`).
    pub graph: String,
    /// Which graph of the file, when it defines several.
    #[arg(long)]
    pub name: Option<String>,
    /// Map size in texels (square), at most 8192.
    #[arg(long, default_value_t = 1024, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub size: usize,
    /// Parameter values: a JSON object of name → number, [r, g, b] (linear) or {"srgb": [r, g, b]}.
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Also bake K random-parameter variants (each with its parameters as JSON), at most 10 000.
    #[arg(long, default_value_t = 0)]
    pub random: usize,
    /// Seed of the random variants.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output folder, written whole or not at all.
    #[arg(long, default_value = "bake")]
    pub out: PathBuf,
    /// Replace an existing --out folder whole (without it, an existing folder is refused).
    #[arg(long)]
    pub force: bool,
    /// No progress (bars on a terminal, else a line log on stderr).
    #[arg(long)]
    pub quiet: bool,
    /// Library root for `import` and for graph names (default: the shipped graphs/ folder).
    #[arg(long)]
    pub lib: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<ExitCode, Error> {
    checks::bake_size("--size", args.size)?;
    limits::check_count("random variants", args.random as u64, limits::MAX_VARIANTS, "variants")
        .map_err(|e| checks::over_limit("--random", e))?;
    let replace = if args.force { Replace::Yes } else { Replace::No };
    let mut inputs: Vec<&Path> = vec![Path::new(&args.graph)];
    inputs.extend(args.params.as_deref());
    inputs.extend(args.lib.as_deref());
    checks::new_folder("--out", &args.out, replace, &inputs)?;
    // Refused at once when --out exists (without --force), before compiling anything.
    let staged = StagedDir::new(&args.out, replace)?;
    let graph = find_graph(&args.graph, args.name.as_deref(), args.lib.as_deref())?;
    let space = ParamSpace::new(&graph.info);
    let params = match &args.params {
        Some(p) => {
            let json = psc_runtime::json::read_file(p)?;
            space.from_json(&json).map_err(|e| Failure(format!("{}: {e}", p.display())))?
        }
        None => space.defaults(),
    };
    let material =
        Material::new(graph).map_err(|e| Failure(format!("cannot compile the graph to native code: {e}")))?;
    let info = &material.graph.info;
    let eval = |p: &[f32], u: &[f32], v: &[f32]| material.kernel.eval(p, u, v).map_err(|e| e.to_string());

    // One variant at a time, baked, written and dropped: memory stays that of one bake however
    // many variants are asked for. The random vectors are drawn in the same order as always.
    let started = Instant::now();
    let mut rng = SplitMix64::new(args.seed);
    let mut files = 0;
    let mut eval_time = Duration::ZERO;
    let drawer = Drawer::new(args.quiet);
    drawer.start("bake", Some(args.random as u64 + 1), &format!("sets of maps at {}²", args.size));
    for k in 0..=args.random {
        let (stem, p) = match k {
            0 => (info.name.clone(), params.clone()),
            k => (format!("{}_random{k:02}", info.name), space.random(&mut rng)),
        };
        let bake_started = Instant::now();
        let maps = bake::bake(&eval, &p, args.size).map_err(Failure)?;
        eval_time += bake_started.elapsed();
        let bad = maps
            .albedo
            .iter()
            .chain(&maps.normal)
            .chain(&maps.roughness)
            .chain(&maps.height)
            .filter(|x| !x.is_finite())
            .count();
        if bad > 0 {
            return Err(Failure(format!("{stem}: {bad} non-finite values; nothing written")).into());
        }
        let written = bake::write_maps(&maps, staged.path(), &stem)
            .map_err(|e| Failure(format!("cannot write to {}: {e}", args.out.display())))?;
        let json_path = staged.path().join(format!("{stem}_params.json"));
        let json = serde_json::to_string_pretty(&space.to_json(&p)?)?;
        std::fs::write(&json_path, json).map_err(|e| Failure(format!("cannot write {}: {e}", json_path.display())))?;
        files += written.len() + 1;
        drawer.advance(1);
    }
    drawer.finish();
    let dest = staged.commit()?;
    eprintln!(
        "wrote {files} files ({} sets of maps at {}², evaluated in {:.2} s) to {} in {:.2} s",
        args.random + 1,
        args.size,
        eval_time.as_secs_f64(),
        dest.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}
