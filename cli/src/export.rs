//! `psc export <scene> --assign materials.json --lights lights.json --out <dir>`: the fitted room
//! as glTF 2.0 (`scene.gltf`, `scene.bin`, `textures/`) and as a Mitsuba 3 scene
//! (`scene_mitsuba.xml`, `meshes/`), through `psc_export::export`. The folder appears whole or
//! not at all; an existing one is replaced only with `--force`.

use std::path::PathBuf;
use std::process::ExitCode;

use psc_base::output::Replace;
use psc_export::ExportOptions;
use psc_render::scene::Scene;
use psc_render::LightRadiances;
use psc_runtime::assign::Assignment;
use psc_runtime::library::{default_library_root, Library};

use crate::{checks, Error};

#[derive(clap::Args)]
pub struct Args {
    /// Scene folder (with scene.json).
    scene: PathBuf,
    /// Material assignment (the `psc render --assign` format, e.g. a fit's materials.json).
    #[arg(long)]
    assign: PathBuf,
    /// Light radiances (the `psc render --lights` format, e.g. a fit's lights.json).
    #[arg(long)]
    lights: PathBuf,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Edge of the baked maps in texels (at least 1; the bake's texel limit applies).
    #[arg(long, default_value_t = 1024, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    texture_size: usize,
    /// Graph library folder (default: this checkout's graphs/).
    #[arg(long)]
    lib: Option<PathBuf>,
    /// Replace an existing --out folder whole.
    #[arg(long)]
    force: bool,
}

pub fn run(args: Args) -> Result<ExitCode, Error> {
    let replace = if args.force { Replace::Yes } else { Replace::No };
    let mut inputs = vec![args.scene.as_path(), &args.assign, &args.lights];
    inputs.extend(args.lib.as_deref());
    checks::new_folder("--out", &args.out, replace, &inputs)?;
    checks::bake_size("--texture-size", args.texture_size)?;
    let scene = Scene::load(&args.scene)?;
    let mut warnings = scene.warnings.clone();
    // Both files are read before the library is compiled: a broken one fails fast.
    let assignment = Assignment::read(&args.assign)?;
    let lights = LightRadiances::from_file(&args.lights, &scene, &mut warnings)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let library = Library::load(&args.lib.clone().unwrap_or_else(default_library_root))?;
    let options = ExportOptions { texture_size: args.texture_size };
    let summary = psc_export::export(&args.out, replace, &scene, &library, &assignment, &lights, &options)?;
    for w in &summary.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "exported {} parts, {} lights, {} cameras ({} files, maps {}²) to {}",
        summary.parts,
        summary.lights,
        summary.cameras,
        summary.files.len(),
        args.texture_size,
        args.out.display()
    );
    println!("  glTF:    {}", args.out.join("scene.gltf").display());
    println!("  Mitsuba: {}", args.out.join("scene_mitsuba.xml").display());
    Ok(ExitCode::SUCCESS)
}
