//! The compiler's entry point: load files, check every module, lower the graphs of the clean
//! ones. Runs on a thread with a large stack so that no input, however deeply nested, can
//! overflow it.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use psc_grammar::ast::Span;

use crate::check;
use crate::compiled::CompiledGraph;
use crate::diag::{Diagnostic, FileId, SourceMap};
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
    // Two names for one file (`a.psg`, `./a.psg`, a link) load one module: compile it once.
    let mut modules: Vec<ModuleId> = Vec::new();
    for id in roots.iter().filter_map(|(_, id)| *id) {
        if !modules.contains(&id) {
            modules.push(id);
        }
    }
    diagnostics.extend(graph_names_clash(&set, &modules));
    let bad_files: HashSet<FileId> = diagnostics.iter().filter(|d| d.is_error()).map(|d| d.file).collect();
    let mut graphs = Vec::new();
    let mut outcome: HashMap<ModuleId, bool> = HashMap::new();
    for id in modules {
        let mut ok = !depends_on_bad_file(&set, id, &bad_files);
        if ok {
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
        outcome.insert(id, ok);
    }
    let files = roots.into_iter().map(|(path, id)| (path, id.is_some_and(|id| outcome[&id]))).collect();
    CompileOutput { sources: std::mem::take(&mut set.sources), diagnostics, graphs, files }
}

/// Graph names are global to a compilation (`psc bake NAME`, the runtime library): a name that
/// two files define is an error at the second definition, naming both files. (Two definitions
/// in one file are reported when the file is loaded.)
fn graph_names_clash(set: &ModuleSet, modules: &[ModuleId]) -> Vec<Diagnostic> {
    let mut first: HashMap<&str, (ModuleId, Span)> = HashMap::new();
    let mut out = Vec::new();
    for &id in modules {
        for g in set.module(id).graphs() {
            let name = g.name.name.as_str();
            match first.get(name) {
                None => {
                    first.insert(name, (id, g.name.span));
                }
                Some(&(other, _)) if other == id => {}
                Some(&(other, span)) => {
                    let (here, there) = (set.module(id).file, set.module(other).file);
                    out.push(
                        Diagnostic::error(
                            here,
                            g.name.span,
                            format!(
                                "graph `{name}` is defined in two files: {} and {}",
                                set.sources.name(there),
                                set.sources.name(here)
                            ),
                        )
                        .with_label("second definition")
                        .with_related(there, span, "first defined here")
                        .with_hint("graph names must be unique across the files compiled together; rename one"),
                    );
                }
            }
        }
    }
    out
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

/// Every `.psg` file under `dir`, recursively, each real file once, sorted (so compilations
/// and reports are stable): the one folder walk of every command ([`psc_base::walk`], which
/// follows links without looping).
pub fn find_sources(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    psc_base::walk::files_with_extension(dir, "psg")
}
