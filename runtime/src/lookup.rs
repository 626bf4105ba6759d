//! Finding the graph a user named: a `.psg` file (its only graph, or the one named), or the name
//! of a graph of a library folder. `psc bake` uses it; so can the fit and tests.

use std::fmt;
use std::path::{Path, PathBuf};

use psc_compiler::{compile_files, CompiledGraph, Options};

use crate::library::{default_library_root, psg_files};

/// Why the named graph could not be found or compiled.
#[derive(Debug)]
pub enum LookupError {
    /// A path ending in `.psg` that is not a file.
    NoSuchFile(PathBuf),
    /// A directory where a `.psg` file or a graph name was expected.
    IsADirectory(PathBuf),
    /// The library folder could not be read.
    Library { root: PathBuf, message: String },
    /// The source has errors (rendered diagnostics).
    Diagnostics(String),
    /// No graph of that name (`known` lists the graphs there are).
    NoSuchGraph { name: String, place: String, known: Vec<String> },
    /// A graph name and a different `name` (which only chooses among a file's graphs).
    NameConflict { spec: String, name: String },
    /// The file defines no graph.
    Empty(PathBuf),
}

impl fmt::Display for LookupError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LookupError::NoSuchFile(p) => write!(f, "no such file: {}", p.display()),
            LookupError::IsADirectory(p) => write!(
                f,
                "{} is a directory; expected a .psg file or the name of a library graph (use --lib for a library folder)",
                p.display()
            ),
            LookupError::Library { root, message } => write!(f, "cannot read the library {}: {message}", root.display()),
            LookupError::Diagnostics(text) => write!(f, "the graph has errors:\n{text}"),
            LookupError::NoSuchGraph { name, place, known } => {
                write!(f, "no graph named `{name}` in {place} (there are: {})", known.join(", "))
            }
            LookupError::NameConflict { spec, name } => write!(
                f,
                "`{spec}` is a graph name, so the graph name `{name}` given besides it contradicts it (a name chooses among the graphs of a .psg file)"
            ),
            LookupError::Empty(p) => write!(f, "{} defines no graph", p.display()),
        }
    }
}

impl std::error::Error for LookupError {}

/// Finds and compiles the graph `spec` names.
///
/// - `spec` ending in `.psg`, or naming a file: that file is compiled (with `lib` as its import
///   root when given); `name` chooses among its graphs, else the first is taken.
/// - Otherwise `spec` is a graph name, looked up in the library folder `lib` (default: the
///   shipped graphs/); `name` must then be absent or equal to it.
pub fn find_graph(spec: &str, name: Option<&str>, lib: Option<&Path>) -> Result<CompiledGraph, LookupError> {
    let path = PathBuf::from(spec);
    if path.is_dir() {
        return Err(LookupError::IsADirectory(path));
    }
    if path.extension().is_some_and(|e| e == "psg") || path.is_file() {
        if !path.is_file() {
            return Err(LookupError::NoSuchFile(path));
        }
        let graphs = compile(std::slice::from_ref(&path), &Options { lib_root: lib.map(Path::to_path_buf) })?;
        return match name {
            Some(n) => pick(graphs, n, &path.display().to_string()),
            None => graphs.into_iter().next().ok_or(LookupError::Empty(path)),
        };
    }
    let root = lib.map(Path::to_path_buf).unwrap_or_else(default_library_root);
    let files = psg_files(&root).map_err(|e| LookupError::Library { root: root.clone(), message: e.to_string() })?;
    let graphs = compile(&files, &Options { lib_root: Some(root.clone()) })?;
    if let Some(n) = name.filter(|n| *n != spec) {
        return Err(LookupError::NameConflict { spec: spec.to_string(), name: n.to_string() });
    }
    pick(graphs, spec, &format!("the library {}", root.display()))
}

fn compile(files: &[PathBuf], options: &Options) -> Result<Vec<CompiledGraph>, LookupError> {
    let output = compile_files(files, options);
    if output.has_errors() {
        return Err(LookupError::Diagnostics(output.render_diagnostics()));
    }
    Ok(output.graphs)
}

fn pick(mut graphs: Vec<CompiledGraph>, name: &str, place: &str) -> Result<CompiledGraph, LookupError> {
    match graphs.iter().position(|g| g.info.name == name) {
        Some(i) => Ok(graphs.swap_remove(i)),
        None => Err(LookupError::NoSuchGraph {
            name: name.to_string(),
            place: place.to_string(),
            known: graphs.iter().map(|g| g.info.name.clone()).collect(),
        }),
    }
}
