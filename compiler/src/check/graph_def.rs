//! Checking a `graph { … }`: its members, parameter ranges and defaults, node cycles, outputs.

use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;

use psc_grammar::ast::{self, GraphMember, Span};

use super::{Checker, Typed};
use crate::diag::did_you_mean;
use crate::types::Ty;

/// What an output channel group is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    Required,
    /// At least one of `height` and `normal` is required.
    HeightOrNormal,
    Optional,
}

/// The outputs a graph may declare, their types and whether they are required.
pub const OUTPUTS: &[(&str, Ty, OutputKind)] = &[
    ("albedo", Ty::Vec3, OutputKind::Required),
    ("roughness", Ty::Float, OutputKind::Required),
    ("height", Ty::Float, OutputKind::HeightOrNormal),
    ("normal", Ty::Vec3, OutputKind::HeightOrNormal),
    ("metallic", Ty::Float, OutputKind::Optional),
];

/// Names a graph body defines, and the lazily computed types of its nodes.
pub(crate) struct GraphScope {
    params: HashMap<String, Ty>,
    nodes: HashMap<String, (ast::Expr, Span)>,
    consts: HashMap<String, ast::Expr>,
    state: RefCell<HashMap<String, NodeState>>,
    /// Nodes being typed, outermost first, for cycle messages.
    stack: RefCell<Vec<String>>,
}

#[derive(Clone)]
enum NodeState {
    InProgress,
    Done(Typed),
}

impl GraphScope {
    pub(crate) fn names(&self) -> Vec<String> {
        self.params.keys().chain(self.nodes.keys()).chain(self.consts.keys()).cloned().collect()
    }
}

impl Checker<'_> {
    pub(super) fn check_graph(&mut self, g: &ast::GraphDef) {
        let mut scope = GraphScope {
            params: HashMap::new(),
            nodes: HashMap::new(),
            consts: HashMap::new(),
            state: RefCell::new(HashMap::new()),
            stack: RefCell::new(Vec::new()),
        };
        let mut first_seen: HashMap<String, Span> = HashMap::new();
        let mut outputs: HashMap<String, Span> = HashMap::new();
        let (mut category, mut description) = (None::<Span>, None::<Span>);
        let file = self.file;
        // Pass 1: declarations (so that members may refer to each other in any order).
        for member in &g.members {
            let (name, span) = match member {
                GraphMember::Param(p) => (&p.name, p.span),
                GraphMember::Node { name, span, .. } => (name, *span),
                GraphMember::Const(c) => (&c.name, c.span),
                GraphMember::Category(_, span) => {
                    if let Some(first) = category.replace(*span) {
                        self.error(*span, "`category` is given twice").related.push((file, first, "first here".into()));
                    }
                    continue;
                }
                GraphMember::Description(_, span) => {
                    if let Some(first) = description.replace(*span) {
                        self.error(*span, "`description` is given twice").related.push((
                            file,
                            first,
                            "first here".into(),
                        ));
                    }
                    continue;
                }
                GraphMember::Output { name, .. } => {
                    if let Some(first) = outputs.insert(name.name.clone(), name.span) {
                        self.error(name.span, format!("output `{}` is defined twice", name.name)).related.push((
                            file,
                            first,
                            "first here".into(),
                        ));
                    }
                    continue;
                }
            };
            if name.name == "uv" || crate::builtins::Builtin::from_name(&name.name).is_some() {
                self.error(name.span, format!("`{}` is a built-in name and cannot be redefined", name.name));
                continue;
            }
            if let Some(first) = first_seen.insert(name.name.clone(), name.span) {
                self.error(name.span, format!("`{}` is defined twice in graph `{}`", name.name, g.name.name))
                    .related
                    .push((file, first, "first defined here".into()));
                continue;
            }
            match member {
                GraphMember::Param(p) => {
                    let ty = self.check_param(p);
                    scope.params.insert(p.name.name.clone(), ty);
                }
                GraphMember::Node { name, value, .. } => {
                    scope.nodes.insert(name.name.clone(), (value.clone(), span));
                }
                GraphMember::Const(c) => {
                    scope.consts.insert(c.name.name.clone(), c.value.clone());
                }
                _ => {}
            }
        }
        let scope = Rc::new(scope);
        self.graph = Some(scope.clone());
        // Pass 2: every node (reachable or not), const and output.
        let mut names: Vec<&String> = scope.nodes.keys().chain(scope.consts.keys()).collect();
        names.sort_by_key(|n| first_seen.get(*n).map(|s| s.start));
        for name in names {
            let id = ast::Ident { name: name.clone(), span: first_seen[name] };
            self.graph_name(&scope, &id);
        }
        for member in &g.members {
            if let GraphMember::Output { name, value, .. } = member {
                let t = self.check_expr(value);
                match OUTPUTS.iter().find(|(n, _, _)| *n == name.name) {
                    Some((_, ty, _)) => {
                        if !t.ty.coerces_to(ty) {
                            self.error(value.span, format!("output `{}` must be {ty}, found {}", name.name, t.ty))
                                .label = format!("this is {}", t.ty);
                        }
                    }
                    None => {
                        let hint = did_you_mean(&name.name, OUTPUTS.iter().map(|(n, _, _)| *n))
                            .or_else(|| Some("outputs are albedo, roughness, height, normal and metallic".into()));
                        self.error(name.span, format!("unknown output `{}`", name.name)).hint = hint;
                    }
                }
            }
        }
        self.graph = None;
        for (out, _, kind) in OUTPUTS {
            let missing = match kind {
                OutputKind::Required => !outputs.contains_key(*out),
                OutputKind::HeightOrNormal => {
                    *out == "height" && !outputs.contains_key("height") && !outputs.contains_key("normal")
                }
                OutputKind::Optional => false,
            };
            if missing {
                let what = if *kind == OutputKind::HeightOrNormal {
                    "`height` or `normal`".to_string()
                } else {
                    format!("`{out}`")
                };
                let example = match *out {
                    "albedo" => "output albedo = vec3(0.5)",
                    "roughness" => "output roughness = 0.5",
                    _ => "output height = 0.0",
                };
                self.error(g.name.span, format!("graph `{}` has no {what} output", g.name.name)).hint =
                    Some(format!("add e.g. `{example}`"));
            }
        }
    }

    /// Checks a parameter declaration; returns its type (float, int or vec3).
    fn check_param(&mut self, p: &ast::ParamDef) -> Ty {
        let saved = std::mem::take(&mut self.locals);
        let default = self.check_expr(&p.default);
        let range = p.range.as_ref().map(|(lo, hi, span)| (self.check_expr(lo), self.check_expr(hi), *span));
        self.locals = saved;
        if default.ty == Ty::Error {
            return Ty::Error;
        }
        if !default.konst {
            self.error(p.default.span, "a parameter's default must be a compile-time constant");
            return Ty::Error;
        }
        let is_color = default.ty == Ty::Vec3;
        if is_color {
            if let Some((_, _, span)) = range {
                self.error(span, "colour parameters have no range").hint =
                    Some("each channel ranges over [0, 1] (linear)".into());
            }
            if p.is_int {
                self.error(p.span, "a colour parameter cannot be `int`");
            }
            if let Some(v) = crate::lower::const_value(self.set, self.module, &p.default) {
                if v.iter().any(|c| !(0.0..=1.0).contains(c)) {
                    self.error(p.default.span, format!("colour default {v:?} is outside [0, 1]"));
                }
            }
            return Ty::Vec3;
        }
        if !default.ty.coerces_to(&Ty::Float) {
            self.error(p.default.span, format!("a parameter is a float, an int or a colour, not {}", default.ty));
            return Ty::Error;
        }
        let Some((lo_t, hi_t, range_span)) = range else {
            self.error(
                Span::new(p.span.start, p.default.span.end),
                format!("parameter `{}` needs a range", p.name.name),
            )
            .hint = Some(format!("e.g. `param {} = … in [0, 1]`", p.name.name));
            return if p.is_int { Ty::Int } else { Ty::Float };
        };
        let (lo_e, hi_e, _) = p.range.as_ref().expect("range present");
        for (t, e) in [(&lo_t, lo_e), (&hi_t, hi_e)] {
            if !t.ty.coerces_to(&Ty::Float) {
                self.error(e.span, format!("a range bound must be a number, found {}", t.ty));
                return Ty::Error;
            }
            if !t.konst {
                self.error(e.span, "a range bound must be a compile-time constant");
                return Ty::Error;
            }
        }
        let value =
            |c: &Checker, e: &ast::Expr| crate::lower::const_value(c.set, c.module, e).and_then(|v| v.first().copied());
        let (Some(d), Some(lo), Some(hi)) = (value(self, &p.default), value(self, lo_e), value(self, hi_e)) else {
            return Ty::Error;
        };
        for (x, e) in [(d, &p.default), (lo, lo_e), (hi, hi_e)] {
            if !x.is_finite() {
                self.error(e.span, "this value is not a finite number");
                return Ty::Error;
            }
            if p.is_int && x.fract() != 0.0 {
                self.error(e.span, format!("`{}` is an int parameter, but {x} is not an integer", p.name.name));
            }
        }
        if lo >= hi {
            self.error(range_span, format!("empty range: the minimum {lo} is not below the maximum {hi}")).hint =
                Some("write the range as [min, max]".into());
        } else if d < lo || d > hi {
            self.error(p.default.span, format!("default {d} is outside the range [{lo}, {hi}]")).label =
                "default here".into();
        }
        if p.is_int {
            Ty::Int
        } else {
            Ty::Float
        }
    }

    /// Resolves a name against the graph's params, nodes and consts; `None` if it is none of them.
    pub(super) fn graph_name(&mut self, scope: &Rc<GraphScope>, id: &ast::Ident) -> Option<Typed> {
        if let Some(ty) = scope.params.get(&id.name) {
            return Some(Typed::new(ty.clone(), false));
        }
        let (expr, is_const) = match (scope.nodes.get(&id.name), scope.consts.get(&id.name)) {
            (Some((e, _)), _) => (e, false),
            (None, Some(e)) => (e, true),
            (None, None) => return None,
        };
        let state = scope.state.borrow().get(&id.name).cloned();
        match state {
            Some(NodeState::Done(t)) => Some(t),
            Some(NodeState::InProgress) => {
                let stack = scope.stack.borrow();
                let start = stack.iter().position(|n| *n == id.name).unwrap_or(0);
                let mut cycle: Vec<&str> = stack[start..].iter().map(|s| s.as_str()).collect();
                cycle.push(&id.name);
                let msg = format!("cycle between nodes: {}", cycle.join(" → "));
                drop(stack);
                self.error(id.span, msg).hint =
                    Some("a node cannot depend on itself, directly or through others".into());
                scope.state.borrow_mut().insert(id.name.clone(), NodeState::Done(Typed::error()));
                Some(Typed::error())
            }
            None => {
                scope.state.borrow_mut().insert(id.name.clone(), NodeState::InProgress);
                scope.stack.borrow_mut().push(id.name.clone());
                let saved = std::mem::take(&mut self.locals);
                let t = self.check_expr(expr);
                self.locals = saved;
                scope.stack.borrow_mut().pop();
                if is_const && !t.konst {
                    self.error(expr.span, format!("`{}` must be a compile-time constant", id.name));
                }
                // A cycle found below may already have stored an error type; keep it.
                let mut states = scope.state.borrow_mut();
                let t = match states.get(&id.name) {
                    Some(NodeState::Done(prev)) => prev.clone(),
                    _ => t,
                };
                states.insert(id.name.clone(), NodeState::Done(t.clone()));
                Some(t)
            }
        }
    }
}
