//! The material library: every graph under a folder compiled once, with its JIT kernels.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use psc_compiler::{compile_files, CompiledGraph, Options};
use rayon::prelude::*;

use crate::kernel::{Kernel, KernelError};

/// One compiled graph with its native forward kernel; the fused forward + adjoint kernel is
/// compiled on first use, because rendering and baking never need it and it is about three
/// quarters of the JIT time.
pub struct Material {
    pub graph: CompiledGraph,
    /// Forward only: `eval`, `eval_grid`.
    pub kernel: Kernel,
    gradient: OnceLock<Result<Kernel, KernelError>>,
}

impl Material {
    /// Compiles the forward kernel of a compiled graph.
    pub fn new(graph: CompiledGraph) -> Result<Material, KernelError> {
        let kernel = Kernel::new(graph.forward.clone())?;
        Ok(Material { graph, kernel, gradient: OnceLock::new() })
    }

    /// The kernel with the fused adjoint over every continuous parameter (compiled once, on the
    /// first call, by whichever thread gets there first).
    pub fn gradient_kernel(&self) -> Result<&Kernel, KernelError> {
        self.gradient
            .get_or_init(|| self.kernel.with_added_adjoint(self.graph.adjoint()))
            .as_ref()
            .map_err(Clone::clone)
    }

    pub fn name(&self) -> &str {
        &self.graph.info.name
    }
}

#[derive(Debug)]
pub enum LibraryError {
    /// Source problems, rendered (file:line:col, caret, hint), one diagnostic after another.
    Diagnostics(String),
    Kernel {
        graph: String,
        error: KernelError,
    },
    Io(String),
}

impl fmt::Display for LibraryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LibraryError::Diagnostics(text) => write!(f, "the graphs have errors:\n{text}"),
            LibraryError::Kernel { graph, error } => {
                write!(f, "cannot compile graph `{graph}` to native code: {error}")
            }
            LibraryError::Io(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for LibraryError {}

/// Every material graph of a library folder (the `std/` modules are imported, not listed).
pub struct Library {
    pub materials: Vec<Arc<Material>>,
    /// Front end (parse, check, lower) and forward JIT time, for reports.
    pub front_end_time: Duration,
    pub jit_time: Duration,
}

impl Library {
    /// Compiles every `.psg` file under `root` (recursively) and JIT-compiles its graphs.
    pub fn load(root: &Path) -> Result<Library, LibraryError> {
        let files = psg_files(root).map_err(|e| LibraryError::Io(format!("cannot read {}: {e}", root.display())))?;
        Library::compile(&files, &Options { lib_root: Some(root.to_path_buf()) })
    }

    /// Compiles the given files; any error in any of them fails the whole library.
    pub fn compile(files: &[PathBuf], options: &Options) -> Result<Library, LibraryError> {
        let started = Instant::now();
        let output = compile_files(files, options);
        if output.has_errors() {
            return Err(LibraryError::Diagnostics(output.render_diagnostics()));
        }
        let front_end_time = started.elapsed();
        let started = Instant::now();
        let materials: Result<Vec<_>, _> = output
            .graphs
            .into_par_iter()
            .map(|graph| {
                let name = graph.info.name.clone();
                Material::new(graph).map(Arc::new).map_err(|error| LibraryError::Kernel { graph: name, error })
            })
            .collect();
        Ok(Library { materials: materials?, front_end_time, jit_time: started.elapsed() })
    }

    /// Compiles every material's gradient kernel now, in parallel, instead of on first use;
    /// returns the wall time it took.
    pub fn compile_gradients(&self) -> Result<Duration, LibraryError> {
        let started = Instant::now();
        self.materials.par_iter().try_for_each(|m| {
            m.gradient_kernel().map(drop).map_err(|error| LibraryError::Kernel { graph: m.name().to_string(), error })
        })?;
        Ok(started.elapsed())
    }

    pub fn get(&self, name: &str) -> Option<&Arc<Material>> {
        self.index_of(name).map(|i| &self.materials[i])
    }

    /// The index in [`Library::materials`] of the graph called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.materials.iter().position(|m| m.name() == name)
    }

    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.materials.iter().map(|m| m.name())
    }
}

/// The library folder shipped with photoscene (`graphs/` at the repository root).
pub fn default_library_root() -> PathBuf {
    let runtime_crate = Path::new(env!("CARGO_MANIFEST_DIR"));
    runtime_crate.parent().unwrap_or(runtime_crate).join("graphs")
}

/// Every `.psg` file under `root`, sorted, excluding `std/` module folders.
pub fn psg_files(root: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files = psc_compiler::find_sources(root)?;
    files.retain(|p| {
        !p.strip_prefix(root).unwrap_or(p).parent().is_some_and(|d| d.components().any(|c| c.as_os_str() == "std"))
    });
    Ok(files)
}
