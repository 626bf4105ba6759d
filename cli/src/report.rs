//! `psc report <out>`: writes `<out>/report.html`, one self-contained offline page of a fit
//! output. A thin layer over `psc_report::write_report_with`.

use std::path::PathBuf;
use std::process::ExitCode;

use psc_report::{write_report_with, ReportOptions};

use crate::Failure;

#[derive(clap::Args)]
pub struct Args {
    /// The fit's output folder (result.json, parts/, renders/, …).
    out: PathBuf,
    /// The scene folder with the photos (default: the one result.json names).
    #[arg(long)]
    scene: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<ExitCode, Failure> {
    // Without --scene a missing scene is said on the page (a fit output moved without it); a
    // scene named on the command line that is not there is a mistake to say at once.
    if let Some(scene) = &args.scene {
        if !scene.join("scene.json").is_file() {
            return Err(Failure(format!("--scene: {} is not a scene folder (no scene.json)", scene.display())));
        }
    }
    let path = write_report_with(&args.out, &ReportOptions { scene: args.scene, ..Default::default() })?;
    let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    eprintln!("wrote {} ({:.1} MB)", path.display(), bytes as f64 / 1e6);
    Ok(ExitCode::SUCCESS)
}
