//! The fit's error type: every way a fit can fail, each with a message worth showing as is.

use std::fmt;

use psc_render::RenderError;
use psc_runtime::kernel::KernelError;
use psc_runtime::library::LibraryError;

#[derive(Debug)]
pub enum FitError {
    /// The scene folder, a photo, a label image or a lights file.
    Scene(RenderError),
    /// The graph library does not compile.
    Library(LibraryError),
    /// A kernel call failed (a bug, or a graph whose kernel cannot be built).
    Kernel { graph: String, error: KernelError },
    /// Options or inputs that cannot be fitted (named part unknown, output folder exists, ...).
    Input(String),
    /// Writing the results.
    Output(String),
}

impl fmt::Display for FitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FitError::Scene(e) => e.fmt(f),
            FitError::Library(e) => e.fmt(f),
            FitError::Kernel { graph, error } => write!(f, "graph `{graph}`: {error}"),
            FitError::Input(m) | FitError::Output(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for FitError {}

impl From<RenderError> for FitError {
    fn from(e: RenderError) -> Self {
        FitError::Scene(e)
    }
}

impl From<LibraryError> for FitError {
    fn from(e: LibraryError) -> Self {
        FitError::Library(e)
    }
}
