//! Reading source files into modules, resolving `import`s against the library root, and the
//! per-module scope of functions and constants.
//!
//! Invariants once [`ModuleSet::load`] returns: every module's imports are loaded (or a
//! diagnostic says why not), import cycles are reported, and each module's scope maps names to
//! the unique item defining them (duplicates are reported and the first wins).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use psc_grammar::ast::{self, Span};

use crate::diag::{did_you_mean, Diagnostic, FileId, SourceMap};

/// Files larger than this are refused before parsing: no material graph is anywhere near it.
pub const MAX_SOURCE_BYTES: usize = 4 << 20;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ModuleId(pub usize);

/// What a name in a module's scope refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ItemRef {
    Fn(ModuleId, usize),
    Const(ModuleId, usize),
}

pub struct Module {
    pub file: FileId,
    pub path: PathBuf,
    pub ast: ast::File,
    pub imports: Vec<ModuleId>,
    /// This module's own functions and constants, by name → index into `ast.items`.
    pub own: HashMap<String, ItemRef>,
}

impl Module {
    pub fn fn_def(&self, index: usize) -> &ast::FnDef {
        match &self.ast.items[index] {
            ast::Item::Fn(f) => f,
            _ => unreachable!("ItemRef::Fn points at a fn"),
        }
    }
    pub fn const_def(&self, index: usize) -> &ast::ConstDef {
        match &self.ast.items[index] {
            ast::Item::Const(c) => c,
            _ => unreachable!("ItemRef::Const points at a const"),
        }
    }
    pub fn graphs(&self) -> impl Iterator<Item = &ast::GraphDef> {
        self.ast.items.iter().filter_map(|i| match i {
            ast::Item::Graph(g) => Some(g),
            _ => None,
        })
    }
}

/// All modules of one compilation, with their sources.
#[derive(Default)]
pub struct ModuleSet {
    pub modules: Vec<Module>,
    pub sources: SourceMap,
    pub diagnostics: Vec<Diagnostic>,
    lib_root: Option<PathBuf>,
    by_path: HashMap<PathBuf, ModuleId>,
    loading: Vec<PathBuf>,
}

/// Where `import a.b.c;` looks when no `--lib` is given and no ancestor folder holds `std/`.
fn builtin_library_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("graphs")
}

impl ModuleSet {
    pub fn new(lib_root: Option<PathBuf>) -> Self {
        ModuleSet { lib_root, ..Default::default() }
    }

    pub fn module(&self, id: ModuleId) -> &Module {
        &self.modules[id.0]
    }

    /// Loads a user file and, transitively, what it imports. `None` if the file could not be
    /// read or parsed (the reasons are in `diagnostics`).
    pub fn load(&mut self, path: &Path) -> Option<ModuleId> {
        let canonical = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
        if let Some(&id) = self.by_path.get(&canonical) {
            return Some(id);
        }
        let bytes = match std::fs::read(path) {
            Ok(b) => b,
            Err(e) => {
                let file = self.sources.add(path.display().to_string(), "");
                self.diagnostics.push(Diagnostic::error(
                    file,
                    Span::default(),
                    format!("cannot read `{}`: {e}", path.display()),
                ));
                return None;
            }
        };
        self.load_text(&canonical, &path.display().to_string(), bytes)
    }

    /// Loads source text as if it were the file at `path` (used by tests and `load`).
    pub fn load_text(&mut self, path: &Path, display_name: &str, bytes: Vec<u8>) -> Option<ModuleId> {
        if bytes.len() > MAX_SOURCE_BYTES {
            let file = self.sources.add(display_name, "");
            self.diagnostics.push(
                Diagnostic::error(
                    file,
                    Span::default(),
                    format!("file is {} bytes; the limit is {MAX_SOURCE_BYTES}", bytes.len()),
                )
                .with_hint("is this really a .psg material graph?"),
            );
            return None;
        }
        let text = match String::from_utf8(bytes) {
            Ok(t) => t,
            Err(e) => {
                let at = e.utf8_error().valid_up_to();
                let lossy = String::from_utf8_lossy(e.as_bytes()).into_owned();
                let file = self.sources.add(display_name, lossy);
                self.diagnostics.push(
                    // The stored text is the lossy conversion, where the bad byte became U+FFFD
                    // (three bytes): the caret must cover that whole character.
                    Diagnostic::error(file, Span::new(at, at + '\u{FFFD}'.len_utf8()), "file is not valid UTF-8")
                        .with_label("invalid byte here")
                        .with_hint("is this a binary file? .psg graphs are UTF-8 text"),
                );
                return None;
            }
        };
        let file = self.sources.add(display_name, text.clone());
        let ast = match psc_grammar::parse(&text) {
            Ok(ast) => ast,
            Err(errors) => {
                for e in errors {
                    self.diagnostics.push(Diagnostic::error(file, e.span, e.message).with_hint_opt(e.hint));
                }
                return None;
            }
        };
        let id = ModuleId(self.modules.len());
        let own = self.collect_own_items(file, id, &ast);
        self.modules.push(Module { file, path: path.to_path_buf(), ast, imports: Vec::new(), own });
        self.by_path.insert(path.to_path_buf(), id);
        self.loading.push(path.to_path_buf());
        let imports: Vec<ast::Import> = self.modules[id.0]
            .ast
            .items
            .iter()
            .filter_map(|i| match i {
                ast::Item::Import(imp) => Some(imp.clone()),
                _ => None,
            })
            .collect();
        for import in &imports {
            if let Some(dep) = self.resolve_import(id, import) {
                if !self.modules[id.0].imports.contains(&dep) {
                    self.modules[id.0].imports.push(dep);
                }
            }
        }
        self.loading.pop();
        Some(id)
    }

    fn collect_own_items(&mut self, file: FileId, id: ModuleId, ast: &ast::File) -> HashMap<String, ItemRef> {
        let mut own: HashMap<String, (ItemRef, Span)> = HashMap::new();
        let mut graph_names: HashMap<String, Span> = HashMap::new();
        for (index, item) in ast.items.iter().enumerate() {
            let (name, item_ref) = match item {
                ast::Item::Fn(f) => (&f.name, ItemRef::Fn(id, index)),
                ast::Item::Const(c) => (&c.name, ItemRef::Const(id, index)),
                ast::Item::Graph(g) => {
                    if let Some(first) = graph_names.insert(g.name.name.clone(), g.name.span) {
                        self.diagnostics.push(
                            Diagnostic::error(file, g.name.span, format!("graph `{}` is defined twice", g.name.name))
                                .with_label("second definition")
                                .with_related(file, first, "first defined here"),
                        );
                    }
                    continue;
                }
                ast::Item::Import(_) => continue,
            };
            if crate::builtins::Builtin::from_name(&name.name).is_some() || name.name == "uv" {
                self.diagnostics.push(
                    Diagnostic::error(
                        file,
                        name.span,
                        format!("`{}` is a built-in and cannot be redefined", name.name),
                    )
                    .with_hint("choose another name"),
                );
                continue;
            }
            if let Some((_, first)) = own.get(&name.name) {
                self.diagnostics.push(
                    Diagnostic::error(file, name.span, format!("`{}` is defined twice", name.name))
                        .with_label("second definition")
                        .with_related(file, *first, "first defined here"),
                );
                continue;
            }
            own.insert(name.name.clone(), (item_ref, name.span));
        }
        own.into_iter().map(|(k, (r, _))| (k, r)).collect()
    }

    fn library_root_for(&self, importer: &Path) -> PathBuf {
        if let Some(root) = &self.lib_root {
            return root.clone();
        }
        let mut dir = importer.parent();
        while let Some(d) = dir {
            if d.join("std").is_dir() {
                return d.to_path_buf();
            }
            dir = d.parent();
        }
        builtin_library_root()
    }

    fn resolve_import(&mut self, importer: ModuleId, import: &ast::Import) -> Option<ModuleId> {
        let file = self.modules[importer.0].file;
        let dotted: Vec<&str> = import.path.iter().map(|p| p.name.as_str()).collect();
        let root = self.library_root_for(&self.modules[importer.0].path.clone());
        let mut path = root.clone();
        for part in &dotted {
            path.push(part);
        }
        path.set_extension("psg");
        let canonical = path.canonicalize().unwrap_or_else(|_| path.clone());
        if self.loading.contains(&canonical) {
            self.diagnostics.push(
                Diagnostic::error(
                    file,
                    import.span,
                    format!("import cycle: `{}` is already being imported", dotted.join(".")),
                )
                .with_hint("modules may not import each other in a cycle; move the shared functions to a third module"),
            );
            return None;
        }
        if !path.is_file() {
            let hint = std::fs::read_dir(path.parent().unwrap_or(&root))
                .ok()
                .map(|entries| {
                    entries
                        .filter_map(|e| e.ok())
                        .filter_map(|e| e.path().file_stem().map(|s| s.to_string_lossy().into_owned()))
                        .collect::<Vec<_>>()
                })
                .and_then(|names| did_you_mean(dotted.last().copied().unwrap_or(""), names.iter().map(|s| s.as_str())));
            let root_note = format!("the library root is {}; pass --lib DIR to use another", root.display());
            let hint = match hint {
                Some(h) => format!("{h} ({root_note})"),
                None => root_note,
            };
            self.diagnostics.push(
                Diagnostic::error(file, import.span, format!("cannot find module `{}`", dotted.join(".")))
                    .with_label(format!("looked for {}", path.display()))
                    .with_hint(hint),
            );
            return None;
        }
        let before = self.diagnostics.len();
        let loaded = self.load(&path);
        if loaded.is_none() && self.diagnostics.len() > before {
            self.diagnostics.push(
                Diagnostic::error(file, import.span, format!("module `{}` has errors", dotted.join(".")))
                    .with_label("imported here"),
            );
        }
        loaded
    }

    /// Looks a function or constant up from inside `module`: its own items first, then those of
    /// its imports. `Err` carries every candidate when two imports define the name.
    pub fn lookup(&self, module: ModuleId, name: &str) -> Result<Option<ItemRef>, Vec<ItemRef>> {
        let m = &self.modules[module.0];
        if let Some(r) = m.own.get(name) {
            return Ok(Some(*r));
        }
        let found: Vec<ItemRef> = m.imports.iter().filter_map(|i| self.modules[i.0].own.get(name).copied()).collect();
        match found.len() {
            0 => Ok(None),
            1 => Ok(Some(found[0])),
            _ => Err(found),
        }
    }

    /// Every function and constant name visible from `module`, for "did you mean".
    pub fn visible_names(&self, module: ModuleId) -> Vec<&str> {
        let m = &self.modules[module.0];
        let mut names: Vec<&str> = m.own.keys().map(|s| s.as_str()).collect();
        for i in &m.imports {
            names.extend(self.modules[i.0].own.keys().map(|s| s.as_str()));
        }
        names
    }
}
