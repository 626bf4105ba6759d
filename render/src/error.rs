//! The one error type of the crate: every problem with a scene, a file or an option.

use std::fmt;
use std::path::{Path, PathBuf};

/// A problem worth showing to the user as is (Display gives a one-line message).
#[derive(Debug)]
pub enum RenderError {
    /// A file could not be read or written.
    Io { path: PathBuf, message: String },
    /// A JSON file does not parse or does not match its schema; line and column are 1-based.
    Json { path: PathBuf, line: usize, column: usize, message: String },
    /// An OBJ or MTL file could not be loaded.
    Obj { path: PathBuf, message: String },
    /// An image could not be decoded or has the wrong size or kind.
    Image { path: PathBuf, message: String },
    /// A camera that cannot form an image (position == look_at, fov out of range, ...).
    Camera { context: String, message: String },
    /// An output could not be written whole (exists, wrong kind, I/O); see `psc_base::output`.
    Output(psc_base::output::OutputError),
    /// A request over a resource limit (`psc_base::limits`): says the limit and the memory.
    Limit(psc_base::limits::LimitError),
    /// Any other inconsistency in a scene or in the options.
    Invalid(String),
}

impl From<psc_base::limits::LimitError> for RenderError {
    fn from(e: psc_base::limits::LimitError) -> Self {
        RenderError::Limit(e)
    }
}

impl From<psc_base::output::OutputError> for RenderError {
    fn from(e: psc_base::output::OutputError) -> Self {
        RenderError::Output(e)
    }
}

impl RenderError {
    pub fn io(path: &Path, e: impl fmt::Display) -> Self {
        RenderError::Io { path: path.to_path_buf(), message: e.to_string() }
    }
    pub fn image(path: &Path, e: impl fmt::Display) -> Self {
        RenderError::Image { path: path.to_path_buf(), message: e.to_string() }
    }
    pub fn json(path: &Path, e: &serde_json::Error) -> Self {
        RenderError::Json { path: path.to_path_buf(), line: e.line(), column: e.column(), message: e.to_string() }
    }
}

impl fmt::Display for RenderError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RenderError::Io { path, message } => write!(f, "{}: {message}", path.display()),
            RenderError::Json { path, line, column, message } => {
                // serde_json's message already ends with "at line L column C"; strip it so the
                // location is given once, compiler style.
                let msg = message.split(" at line ").next().unwrap_or(message);
                write!(f, "{}:{line}:{column}: {msg}", path.display())
            }
            RenderError::Obj { path, message } => write!(f, "{}: {message}", path.display()),
            RenderError::Image { path, message } => write!(f, "{}: {message}", path.display()),
            RenderError::Camera { context, message } => write!(f, "{context}: degenerate camera: {message}"),
            RenderError::Output(e) => write!(f, "{e}"),
            RenderError::Limit(e) => write!(f, "{e}"),
            RenderError::Invalid(message) => write!(f, "{message}"),
        }
    }
}

impl std::error::Error for RenderError {}
