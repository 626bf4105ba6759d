//! The checker: name resolution, types, arity, constness, cycles, parameter ranges and required
//! outputs. It reports every error of a module in one run and never stops at the first.
//!
//! Invariant after a module checks clean: lowering it cannot fail except on resource limits
//! (loop trip counts, IR size), so `lower` may treat any other surprise as a bug.

mod expr;
mod graph_def;

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::rc::Rc;

use psc_grammar::ast::{self, Span};

use crate::diag::{Diagnostic, FileId};
use crate::module::{ItemRef, ModuleId, ModuleSet};
use crate::types::Ty;

pub use expr::MAX_LOOP_TRIPS;
pub use graph_def::{OutputKind, OUTPUTS};

/// Deepest expression nesting the checker walks; deeper input is rejected, not overflowed. A
/// backstop: the parser already refuses trees deeper than [`psc_grammar::MAX_EXPR_DEPTH`], and
/// the checker runs on the compiler's large stack.
pub const MAX_EXPR_DEPTH: usize = 2 * psc_grammar::MAX_EXPR_DEPTH;

/// A function's checked signature.
#[derive(Clone, Debug)]
pub struct FnSig {
    pub params: Vec<SigParam>,
    pub ret: Ty,
}

#[derive(Clone, Debug)]
pub struct SigParam {
    pub name: String,
    pub ty: Ty,
    pub is_const: bool,
    pub has_default: bool,
}

/// Checks every module of the set; returns all diagnostics (errors and warnings).
pub fn check_all(set: &ModuleSet) -> Vec<Diagnostic> {
    let shared = Shared::default();
    let mut out = Vec::new();
    for id in 0..set.modules.len() {
        let mut checker = Checker::new(set, ModuleId(id), &shared);
        checker.check_module();
        out.extend(checker.diags);
    }
    out
}

/// Caches shared by the checkers of all modules (signatures and const types are computed once).
#[derive(Default)]
struct Shared {
    sigs: RefCell<HashMap<ItemRef, Rc<FnSig>>>,
    const_types: RefCell<HashMap<ItemRef, Option<(Ty, bool)>>>,
}

pub(crate) struct Checker<'a> {
    set: &'a ModuleSet,
    module: ModuleId,
    file: FileId,
    shared: &'a Shared,
    diags: Vec<Diagnostic>,
    /// Local variables, innermost last; blocks truncate back to their length on exit.
    locals: Vec<Local>,
    /// The graph being checked, if any.
    graph: Option<Rc<graph_def::GraphScope>>,
    /// Calls from each function of this module to functions of this module (recursion check).
    calls: HashMap<usize, Vec<(usize, Span)>>,
    current_fn: Option<usize>,
    depth: usize,
}

#[derive(Clone, Debug)]
struct Local {
    name: String,
    ty: Ty,
    mutable: bool,
    konst: bool,
}

/// The type of an expression and whether it is a compile-time constant.
#[derive(Clone, Debug)]
pub(crate) struct Typed {
    ty: Ty,
    konst: bool,
}

impl Typed {
    fn new(ty: Ty, konst: bool) -> Self {
        Typed { ty, konst }
    }
    fn error() -> Self {
        Typed { ty: Ty::Error, konst: true }
    }
}

impl<'a> Checker<'a> {
    fn new(set: &'a ModuleSet, module: ModuleId, shared: &'a Shared) -> Self {
        Checker {
            set,
            module,
            file: set.module(module).file,
            shared,
            diags: Vec::new(),
            locals: Vec::new(),
            graph: None,
            calls: HashMap::new(),
            current_fn: None,
            depth: 0,
        }
    }

    fn error(&mut self, span: Span, message: impl Into<String>) -> &mut Diagnostic {
        self.diags.push(Diagnostic::error(self.file, span, message));
        self.diags.last_mut().expect("just pushed")
    }

    fn check_module(&mut self) {
        let module = self.set.module(self.module);
        if module.ast.items.iter().all(|i| matches!(i, ast::Item::Import(_))) {
            // The first character (not byte: a file may start with a BOM).
            let first = self.set.sources.text(self.file).chars().next().map_or(0, char::len_utf8);
            let span = Span::new(0, first);
            self.error(span, "this file defines no graph, function or constant").hint =
                Some("a material file needs `graph NAME { … }`; see docs/language.md".into());
        }
        for (index, item) in module.ast.items.iter().enumerate() {
            match item {
                ast::Item::Fn(f) => self.check_fn(index, f),
                ast::Item::Const(c) => {
                    self.const_type(ItemRef::Const(self.module, index), c);
                }
                ast::Item::Graph(g) => self.check_graph(g),
                ast::Item::Import(_) => {}
            }
        }
        self.report_recursion();
    }

    /// The type of a type expression; errors are reported and become `Ty::Error`.
    fn resolve_type(&mut self, t: &ast::TypeExpr) -> Ty {
        match t {
            ast::TypeExpr::Named(id) => match id.name.as_str() {
                "float" => Ty::Float,
                "int" => Ty::Int,
                "bool" => Ty::Bool,
                "vec2" => Ty::Vec2,
                "vec3" | "color" => Ty::Vec3,
                other => {
                    let hint = crate::diag::did_you_mean(other, ["float", "int", "bool", "vec2", "vec3", "color"]);
                    self.error(id.span, format!("unknown type `{other}`")).hint = hint;
                    Ty::Error
                }
            },
            ast::TypeExpr::Record(fields, _) => {
                let mut seen = HashSet::new();
                let mut out = Vec::new();
                for (name, ty) in fields {
                    if !seen.insert(name.name.clone()) {
                        self.error(name.span, format!("field `{}` appears twice", name.name));
                    }
                    let ty = self.resolve_type(ty);
                    out.push((name.name.clone(), ty));
                }
                Ty::Record(out.into())
            }
        }
    }

    /// The signature of a function, computed once. Errors in parameter types are reported when
    /// the function itself is checked, not at each call.
    fn signature(&mut self, item: ItemRef) -> Rc<FnSig> {
        if let Some(sig) = self.shared.sigs.borrow().get(&item) {
            return sig.clone();
        }
        let ItemRef::Fn(module, index) = item else { unreachable!("signature of a fn") };
        let def = self.set.module(module).fn_def(index);
        // Resolve types silently (a scratch checker): the owning module reports the errors.
        let mut scratch = Checker::new(self.set, module, self.shared);
        let params = def
            .params
            .iter()
            .map(|p| SigParam {
                name: p.name.name.clone(),
                ty: scratch.resolve_type(&p.ty),
                is_const: p.is_const,
                has_default: p.default.is_some(),
            })
            .collect();
        let ret = scratch.resolve_type(&def.ret);
        let sig = Rc::new(FnSig { params, ret });
        self.shared.sigs.borrow_mut().insert(item, sig.clone());
        sig
    }

    fn check_fn(&mut self, index: usize, f: &ast::FnDef) {
        self.current_fn = Some(index);
        self.locals.clear();
        let mut seen: HashMap<&str, Span> = HashMap::new();
        for p in &f.params {
            if let Some(first) = seen.insert(&p.name.name, p.name.span) {
                let file = self.file;
                self.error(p.name.span, format!("parameter `{}` appears twice", p.name.name)).related.push((
                    file,
                    first,
                    "first here".into(),
                ));
            }
            let ty = self.resolve_type(&p.ty);
            if p.is_const && !matches!(ty, Ty::Int | Ty::Float | Ty::Bool | Ty::Error) {
                self.error(p.ty.span(), "a `const` parameter must be int, float or bool");
            }
            if let Some(default) = &p.default {
                let saved = std::mem::take(&mut self.locals);
                let t = self.check_expr(default);
                self.locals = saved;
                if !t.ty.coerces_to(&ty) {
                    self.error(
                        default.span,
                        format!("default of `{}` is {}, but the parameter is {ty}", p.name.name, t.ty),
                    );
                } else if !t.konst {
                    self.error(default.span, "a default must be a compile-time constant").hint =
                        Some("use a literal or a `const`".into());
                }
            }
            self.locals.push(Local { name: p.name.name.clone(), ty, mutable: false, konst: p.is_const });
        }
        let ret = self.resolve_type(&f.ret);
        let body = self.check_block(&f.body);
        if !body.ty.coerces_to(&ret) {
            let span = f.body.tail.as_ref().map_or(f.body.span, |t| t.span);
            self.error(span, format!("`{}` returns {ret}, but its body is {}", f.name.name, body.ty)).label =
                format!("this is {}", body.ty);
        }
        self.locals.clear();
        self.current_fn = None;
    }

    /// Whether `item`'s type is being computed further up: a reference to it now closes a cycle.
    fn const_in_progress(&self, item: ItemRef) -> bool {
        matches!(self.shared.const_types.borrow().get(&item), Some(None))
    }

    /// The type of a module-level constant (memoised; a cycle is reported where a reference
    /// closes it, by `check_name`).
    fn const_type(&mut self, item: ItemRef, def: &ast::ConstDef) -> Typed {
        if let Some(entry) = self.shared.const_types.borrow().get(&item) {
            return match entry {
                Some((ty, konst)) => Typed::new(ty.clone(), *konst),
                None => Typed::error(),
            };
        }
        self.shared.const_types.borrow_mut().insert(item, None);
        let ItemRef::Const(module, _) = item else { unreachable!("const_type of a const") };
        let mut inner = Checker::new(self.set, module, self.shared);
        let t = inner.check_expr(&def.value);
        if module == self.module {
            self.diags.extend(inner.diags);
            if !t.konst {
                self.error(def.value.span, format!("`{}` must be a compile-time constant", def.name.name)).hint =
                    Some("constants may use literals, other constants and built-in math, not `uv` or params".into());
            }
        }
        self.shared.const_types.borrow_mut().insert(item, Some((t.ty.clone(), t.konst)));
        t
    }

    /// Reports each cycle in this module's call graph once, at a function on the cycle.
    fn report_recursion(&mut self) {
        let module = self.set.module(self.module);
        let mut state: HashMap<usize, u8> = HashMap::new(); // 1 = on stack, 2 = done
        let mut reported = HashSet::new();
        let mut roots: Vec<usize> = self.calls.keys().copied().collect();
        roots.sort_unstable();
        for root in roots {
            let mut stack: Vec<(usize, usize)> = vec![(root, 0)];
            let mut path: Vec<usize> = vec![root];
            if state.get(&root).copied() == Some(2) {
                continue;
            }
            state.insert(root, 1);
            while let Some(&mut (f, ref mut next)) = stack.last_mut() {
                let callees = self.calls.get(&f).cloned().unwrap_or_default();
                if *next < callees.len() {
                    let (g, span) = callees[*next];
                    *next += 1;
                    match state.get(&g).copied() {
                        Some(1) => {
                            let start = path.iter().position(|&p| p == g).unwrap_or(0);
                            let mut names: Vec<&str> =
                                path[start..].iter().map(|&i| module.fn_def(i).name.name.as_str()).collect();
                            names.push(module.fn_def(g).name.name.as_str());
                            let key: Vec<usize> = {
                                let mut k = path[start..].to_vec();
                                k.sort_unstable();
                                k
                            };
                            if reported.insert(key) {
                                let msg = format!("recursive call: {}", names.join(" → "));
                                self.error(span, msg).hint =
                                    Some("functions are inlined at compile time, so they cannot call themselves; use a `for` loop".into());
                            }
                        }
                        Some(2) => {}
                        _ => {
                            state.insert(g, 1);
                            stack.push((g, 0));
                            path.push(g);
                        }
                    }
                } else {
                    state.insert(f, 2);
                    stack.pop();
                    path.pop();
                }
            }
        }
    }
}
