//! The compiler's entry point: load files, check every module, lower the graphs of the clean
//! ones. Runs on a thread with a large stack so that no input, however deeply nested, can
//! overflow it.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use crate::check;
use crate::diag::{Diagnostic, FileId, SourceMap};
use crate::compiled::CompiledGraph;
use crate::lower;
use crate::module::{ModuleId, ModuleSet};

/// Stack for the compiler thread: generous, because parse trees of hostile input are deep.
const COMPILER_STACK_BYTES: usize = 512 << 20;

/// Everything one compilation produced.
pub struct CompileOutput {
    pub sources: SourceMap,
    /// Errors and warnings, in the order found.
    pub diagnostics: Vec<Diagnostic>,
    /// The graphs of every file that compiled clean, with the file they came from.
    pub graphs: Vec<CompiledGraph>,
    /// Per input file: whether it (and what it imports) compiled without errors.
    pub files: Vec<(PathBuf, bool)>,
}

impl CompileOutput {
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(Diagnostic::is_error)
    }

    /// All diagnostics rendered as plain text.
    pub fn render_diagnostics(&self) -> String {
        self.diagnostics.iter().map(|d| d.render(&self.sources)).collect()
    }
}

/// Options of a compilation.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// The library root for `import`; by default found from the importing file.
    pub lib_root: Option<PathBuf>,
}

/// Input of a compilation: files on disk, or in-memory text (tests, tools).
enum Input {
    Files(Vec<PathBuf>),
    Text { path: PathBuf, text: Vec<u8> },
}

pub fn compile_files(paths: &[PathBuf], options: &Options) -> CompileOutput {
    run_on_big_stack(Input::Files(paths.to_vec()), options.clone())
}

/// Compiles text as if it were the file at `path` (imports resolve relative to `path`).
pub fn compile_text(path: &Path, text: impl Into<Vec<u8>>, options: &Options) -> CompileOutput {
    run_on_big_stack(Input::Text { path: path.to_path_buf(), text: text.into() }, options.clone())
}

fn run_on_big_stack(input: Input, options: Options) -> CompileOutput {
    let worker = std::thread::Builder::new()
        .name("psc-compiler".into())
        .stack_size(COMPILER_STACK_BYTES)
        .spawn(move || compile(input, &options));
    match worker.map(|h| h.join()) {
        Ok(Ok(out)) => out,
        _ => {
            let mut sources = SourceMap::new();
            let file = sources.add("<compiler>", "");
            CompileOutput {
                diagnostics: vec![Diagnostic::error(
                    file,
                    Default::default(),
                    "internal compiler error (the compiler thread failed)",
                )
                .with_hint("please report this with the input file")],
                sources,
                graphs: Vec::new(),
                files: Vec::new(),
            }
        }
    }
}

fn compile(input: Input, options: &Options) -> CompileOutput {
    let mut set = ModuleSet::new(options.lib_root.clone());
    let mut roots: Vec<(PathBuf, Option<ModuleId>)> = Vec::new();
    match input {
        Input::Files(paths) => {
            for path in paths {
                let id = set.load(&path);
                roots.push((path, id));
            }
        }
        Input::Text { path, text } => {
            let display = path.display().to_string();
            let id = set.load_text(&path, &display, text);
            roots.push((path, id));
        }
    }
    let mut diagnostics = std::mem::take(&mut set.diagnostics);
    diagnostics.extend(check::check_all(&set));
    let bad_files: HashSet<FileId> = diagnostics.iter().filter(|d| d.is_error()).map(|d| d.file).collect();
    let mut graphs = Vec::new();
    let mut files = Vec::new();
    for (path, id) in roots {
        let clean = id.is_some_and(|id| !depends_on_bad_file(&set, id, &bad_files));
        let mut ok = clean;
        if clean {
            let id = id.expect("clean modules loaded");
            for g in set.module(id).graphs() {
                match lower::lower_graph(&set, id, g) {
                    Ok(compiled) => graphs.push(compiled),
                    Err(d) => {
                        diagnostics.push(*d);
                        ok = false;
                    }
                }
            }
        }
        files.push((path, ok));
    }
    CompileOutput { sources: std::mem::take(&mut set.sources), diagnostics, graphs, files }
}

/// Whether a module or anything it imports, transitively, has an error.
fn depends_on_bad_file(set: &ModuleSet, root: ModuleId, bad: &HashSet<FileId>) -> bool {
    let mut stack = vec![root];
    let mut seen = HashSet::new();
    while let Some(m) = stack.pop() {
        if !seen.insert(m) {
            continue;
        }
        let module = set.module(m);
        if bad.contains(&module.file) {
            return true;
        }
        stack.extend(module.imports.iter().copied());
    }
    false
}

/// Every `.psg` file under `dir`, recursively, sorted (so compilations and reports are stable).
pub fn find_sources(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d)? {
            let path = entry?.path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "psg") {
                out.push(path);
            }
        }
    }
    out.sort();
    Ok(out)
}
