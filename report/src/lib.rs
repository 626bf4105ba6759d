//! `psc-report`: `report.html`, one self-contained offline page showing what a `psc fit` output
//! folder holds — per view the photo, the re-render and their difference; per part a crop of the
//! photo, the chosen graph beside its top alternatives, the fitted parameters, the loss curve and
//! swatches of the baked maps; the lights and what they carry; the evaluation table when
//! `psc eval` has run; the command, version and timings.
//!
//! Owns: reading a fit folder for display ([`fit_folder`]), the pictures derived for the page
//! (difference images, crops, thumbnails: [`pictures`]), inline SVG plots ([`svg`]) and the page
//! itself ([`page`], [`html`], the lights section in `lights`). Every image is inlined as a `data:` URI; a Content-Security-Policy
//! forbids any other source, so the page never fetches anything.
//!
//! Must never: change the fit folder except for writing `report.html` (atomically); fit, render
//! or evaluate anything; read ground truth (the evaluation's numbers come from `eval/eval.json`).

#![forbid(unsafe_code)]

pub mod fit_folder;
pub mod html;
mod lights;
pub mod page;
pub mod pictures;
pub mod svg;

use std::fmt;
use std::path::{Path, PathBuf};

pub use fit_folder::FitFolder;

/// Why a report could not be written.
#[derive(Debug)]
pub enum ReportError {
    /// The folder is not the output of `psc fit` (no `result.json`, or not of that format).
    NotAFitOutput { dir: PathBuf, reason: String },
    /// A file of the fit output that is there but cannot be read or makes no sense.
    Input { path: PathBuf, message: String },
    /// Writing `report.html` failed.
    Output { path: PathBuf, message: String },
}

impl fmt::Display for ReportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReportError::NotAFitOutput { dir, reason } => {
                write!(f, "{}: not a `psc fit` output folder: {reason}", dir.display())
            }
            ReportError::Input { path, message } => write!(f, "{}: {message}", path.display()),
            ReportError::Output { path, message } => {
                write!(f, "{}: cannot write the report: {message}", path.display())
            }
        }
    }
}

impl std::error::Error for ReportError {}

/// What may differ from the defaults of [`write_report`].
#[derive(Clone, Debug, Default)]
pub struct ReportOptions {
    /// The scene folder with the photos, instead of the one `result.json` names (for a fit
    /// output that was moved, or made on another machine).
    pub scene: Option<PathBuf>,
    /// The path the page names the fit output by, when the report is written before the folder
    /// reaches its place (`psc fit` writes it into its staging folder, then renames that).
    pub shown_as: Option<PathBuf>,
}

/// Writes `<out_dir>/report.html` for the fit output in `out_dir` (atomically: a reader sees
/// the old file or the whole new one) and returns its path. Pieces the folder lacks (baked maps,
/// renders, the scene's photos or labels, the evaluation) are said to be "not available" on the
/// page; a folder that is not a fit output is an error.
pub fn write_report(out_dir: &Path) -> Result<PathBuf, ReportError> {
    write_report_with(out_dir, &ReportOptions::default())
}

/// [`write_report`] with options.
pub fn write_report_with(out_dir: &Path, options: &ReportOptions) -> Result<PathBuf, ReportError> {
    let mut fit = FitFolder::read(out_dir, options.scene.as_deref())?;
    if let Some(shown_as) = &options.shown_as {
        fit.shown_as = shown_as.clone();
    }
    let text = page::render(&fit);
    let path = out_dir.join("report.html");
    psc_base::output::write_atomic(&path, text.as_bytes())
        .map_err(|e| ReportError::Output { path: path.clone(), message: e.to_string() })?;
    Ok(path)
}
