//! Typing expressions, blocks and calls.

use std::collections::HashMap;

use psc_grammar::ast::{self, BinOp, Expr, ExprKind, Span, UnOp};

use super::{Checker, Local, Typed, MAX_EXPR_DEPTH};
use crate::builtins::Builtin;
use crate::diag::did_you_mean;
use crate::module::ItemRef;
use crate::types::{swizzle, Ty};

/// Loops may not run more iterations than this: each one is unrolled into the IR.
pub const MAX_LOOP_TRIPS: i64 = 1024;

impl Checker<'_> {
    pub(super) fn check_expr(&mut self, e: &Expr) -> Typed {
        if self.depth >= MAX_EXPR_DEPTH {
            self.error(e.span, "expression is nested too deeply").hint =
                Some(format!("split it with `let` bindings (the limit is {MAX_EXPR_DEPTH} levels)"));
            return Typed::error();
        }
        self.depth += 1;
        let t = self.check_expr_inner(e);
        self.depth -= 1;
        t
    }

    fn check_expr_inner(&mut self, e: &Expr) -> Typed {
        match &e.kind {
            ExprKind::Float(_) => Typed::new(Ty::Float, true),
            ExprKind::Int(_) => Typed::new(Ty::Int, true),
            ExprKind::Bool(_) => Typed::new(Ty::Bool, true),
            ExprKind::Name(id) => self.check_name(id),
            ExprKind::Unary(op, inner) => {
                let t = self.check_expr(inner);
                let ok = match op {
                    UnOp::Neg => t.ty.is_numeric() || t.ty == Ty::Error,
                    UnOp::Not => t.ty.coerces_to(&Ty::Bool),
                };
                if !ok {
                    let sym = if *op == UnOp::Neg { "-" } else { "!" };
                    self.error(e.span, format!("cannot apply `{sym}` to {}", t.ty));
                    return Typed::error();
                }
                t
            }
            ExprKind::Binary(op, a, b) => {
                let ta = self.check_expr(a);
                let tb = self.check_expr(b);
                let konst = ta.konst && tb.konst;
                match self.binary_type(*op, &ta.ty, &tb.ty) {
                    Some(ty) => Typed::new(ty, konst),
                    None => {
                        self.error(e.span, format!("cannot apply `{}` to {} and {}", op.symbol(), ta.ty, tb.ty)).hint =
                            binary_hint(*op, &ta.ty, &tb.ty);
                        Typed::error()
                    }
                }
            }
            ExprKind::Call(name, args) => self.check_call(e.span, name, args),
            ExprKind::Field(base, field) => {
                let t = self.check_expr(base);
                self.field_type(&t, field)
            }
            ExprKind::Record(fields) => {
                let mut out: Vec<(String, Ty)> = Vec::new();
                let mut konst = true;
                for (name, value) in fields {
                    if out.iter().any(|(n, _)| *n == name.name) {
                        self.error(name.span, format!("field `{}` appears twice", name.name));
                    }
                    let t = self.check_expr(value);
                    konst &= t.konst;
                    out.push((name.name.clone(), t.ty.to_float()));
                }
                Typed::new(Ty::Record(out.into()), konst)
            }
            ExprKind::If(cond, then, otherwise) => {
                let c = self.check_expr(cond);
                if !c.ty.coerces_to(&Ty::Bool) {
                    self.error(cond.span, format!("an `if` condition must be bool, found {}", c.ty)).hint =
                        Some("compare it, e.g. `x > 0.5`".into());
                }
                let a = self.check_block(then);
                let b = self.check_block(otherwise);
                let konst = c.konst && a.konst && b.konst;
                if a.ty.coerces_to(&b.ty) {
                    Typed::new(b.ty.to_float(), konst)
                } else if b.ty.coerces_to(&a.ty) {
                    Typed::new(a.ty.to_float(), konst)
                } else {
                    self.error(e.span, format!("`if` branches have different types: {} and {}", a.ty, b.ty));
                    Typed::error()
                }
            }
            ExprKind::Block(block) => self.check_block(block),
        }
    }

    fn binary_type(&self, op: BinOp, a: &Ty, b: &Ty) -> Option<Ty> {
        if *a == Ty::Error || *b == Ty::Error {
            return Some(match op {
                BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne | BinOp::And | BinOp::Or => {
                    Ty::Bool
                }
                _ => Ty::Error,
            });
        }
        match op {
            BinOp::Add | BinOp::Sub | BinOp::Mul | BinOp::Rem => Ty::unify_numeric(a, b),
            BinOp::Div => Ty::unify_numeric(a, b).map(|t| t.to_float()),
            BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => {
                (a.width() == Some(1) && b.width() == Some(1)).then_some(Ty::Bool)
            }
            BinOp::Eq | BinOp::Ne => {
                let scalars = a.width() == Some(1) && b.width() == Some(1);
                let bools = *a == Ty::Bool && *b == Ty::Bool;
                (scalars || bools).then_some(Ty::Bool)
            }
            BinOp::And | BinOp::Or => (*a == Ty::Bool && *b == Ty::Bool).then_some(Ty::Bool),
        }
    }

    fn check_name(&mut self, id: &ast::Ident) -> Typed {
        if let Some(local) = self.locals.iter().rev().find(|l| l.name == id.name) {
            return Typed::new(local.ty.clone(), local.konst);
        }
        if let Some(graph) = self.graph.clone() {
            if let Some(t) = self.graph_name(&graph, id) {
                return t;
            }
        }
        match self.set.lookup(self.module, &id.name) {
            Ok(Some(item @ ItemRef::Const(module, index))) => {
                if self.const_in_progress(item) {
                    // Lowering would expand the value forever.
                    self.error(id.span, format!("`{}` is defined in terms of itself", id.name)).hint =
                        Some("a constant's value may not refer back to it, directly or through other constants".into());
                    return Typed::error();
                }
                let def = self.set.module(module).const_def(index);
                return self.const_type(item, def);
            }
            Ok(Some(ItemRef::Fn(..))) => {
                self.error(id.span, format!("`{}` is a function, not a value", id.name)).hint =
                    Some(format!("call it: `{}(…)`", id.name));
                return Typed::error();
            }
            Err(candidates) => {
                self.ambiguous(id, &candidates);
                return Typed::error();
            }
            Ok(None) => {}
        }
        if id.name == "uv" {
            return Typed::new(Ty::Vec2, false);
        }
        if Builtin::from_name(&id.name).is_some() {
            self.error(id.span, format!("`{}` is a built-in function, not a value", id.name)).hint =
                Some(format!("call it: `{}(…)`", id.name));
            return Typed::error();
        }
        let mut names: Vec<String> = self.locals.iter().map(|l| l.name.clone()).collect();
        if let Some(g) = &self.graph {
            names.extend(g.names());
        }
        names.extend(self.set.visible_names(self.module).into_iter().map(String::from));
        names.push("uv".into());
        let hint = did_you_mean(&id.name, names.iter().map(|s| s.as_str()));
        let d = self.error(id.span, format!("unknown name `{}`", id.name));
        d.label = "not found in this scope".into();
        d.hint = hint;
        Typed::error()
    }

    fn ambiguous(&mut self, id: &ast::Ident, candidates: &[ItemRef]) {
        let modules: Vec<String> = candidates
            .iter()
            .map(|c| match c {
                ItemRef::Fn(m, _) | ItemRef::Const(m, _) => self.set.sources.name(self.set.module(*m).file).to_string(),
            })
            .collect();
        self.error(id.span, format!("`{}` is defined by several imported modules", id.name)).hint =
            Some(format!("found in {}; define your own or import only one", modules.join(" and ")));
    }

    fn field_type(&mut self, base: &Typed, field: &ast::Ident) -> Typed {
        match &base.ty {
            Ty::Error => Typed::error(),
            Ty::Record(fields) => match fields.iter().find(|(n, _)| *n == field.name) {
                Some((_, ty)) => Typed::new(ty.clone(), base.konst),
                None => {
                    let hint = did_you_mean(&field.name, fields.iter().map(|(n, _)| n.as_str())).or_else(|| {
                        Some(format!(
                            "its fields are: {}",
                            fields.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(", ")
                        ))
                    });
                    self.error(field.span, format!("no field `{}` on {}", field.name, base.ty)).hint = hint;
                    Typed::error()
                }
            },
            ty @ (Ty::Vec2 | Ty::Vec3) => match swizzle(&field.name, ty.width().expect("vector")) {
                Some(idx) => Typed::new(Ty::of_width(idx.len()), base.konst),
                None => {
                    let letters = if *ty == Ty::Vec2 { "x, y" } else { "x, y, z or r, g, b" };
                    self.error(field.span, format!("`.{}` is not a component of {ty}", field.name)).hint =
                        Some(format!("swizzles use up to three of {letters}"));
                    Typed::error()
                }
            },
            ty => {
                self.error(field.span, format!("{ty} has no fields")).hint =
                    Some("only vectors and records have `.` access".into());
                Typed::error()
            }
        }
    }

    pub(super) fn check_block(&mut self, block: &ast::Block) -> Typed {
        let mark = self.locals.len();
        let mut konst = true;
        for stmt in &block.stmts {
            self.check_stmt(stmt);
        }
        let t = match &block.tail {
            Some(tail) => {
                let t = self.check_expr(tail);
                konst &= t.konst;
                t.ty
            }
            None => {
                self.error(Span::new(block.span.end.saturating_sub(1), block.span.end), "this block has no value")
                    .hint = Some("end it with an expression without `;`".into());
                Ty::Error
            }
        };
        self.locals.truncate(mark);
        Typed::new(t, konst)
    }

    fn check_stmt(&mut self, stmt: &ast::Stmt) {
        match stmt {
            ast::Stmt::Let { mutable, name, ty, value, .. } => {
                let t = self.check_expr(value);
                let declared = ty.as_ref().map(|ty| self.resolve_type(ty));
                let ty = match declared {
                    Some(d) => {
                        if !t.ty.coerces_to(&d) {
                            self.error(
                                value.span,
                                format!("`{}` is declared {d} but its value is {}", name.name, t.ty),
                            );
                        }
                        d
                    }
                    None => t.ty.clone(),
                };
                self.locals.push(Local { name: name.name.clone(), ty, mutable: *mutable, konst: t.konst && !*mutable });
            }
            ast::Stmt::Assign { target, op, value, span } => {
                let t = self.check_expr(value);
                let Some(local) = self.locals.iter().rev().find(|l| l.name == target.name).cloned() else {
                    let hint = did_you_mean(&target.name, self.locals.iter().map(|l| l.name.as_str()));
                    self.error(target.span, format!("cannot assign to `{}`: no such variable", target.name)).hint =
                        hint.or_else(|| Some(format!("declare it first: `var {} = …;`", target.name)));
                    return;
                };
                if !local.mutable {
                    self.error(target.span, format!("cannot assign to `{}`: it is not a `var`", target.name)).hint =
                        Some(format!("declare it with `var {} = …;` to make it mutable", target.name));
                    return;
                }
                let result = match op {
                    Some(op) => self.binary_type(*op, &local.ty, &t.ty),
                    None => Some(t.ty.clone()),
                };
                match result {
                    Some(r) if r.coerces_to(&local.ty) => {}
                    _ => {
                        self.error(
                            *span,
                            format!("cannot assign {} to `{}`, which is {}", t.ty, target.name, local.ty),
                        );
                    }
                }
            }
            ast::Stmt::For { var, start, end, body, .. } => {
                let bounds = [self.check_expr(start), self.check_expr(end)];
                for (t, e) in bounds.iter().zip([start, end]) {
                    if !matches!(t.ty, Ty::Int | Ty::Error) {
                        self.error(e.span, format!("loop bounds must be int, found {}", t.ty));
                    } else if !t.konst {
                        self.error(e.span, "loop bounds must be compile-time constants").hint =
                            Some("loops are unrolled; use a literal, a `const` or a `const` fn parameter".into());
                    }
                }
                if let (ExprKind::Int(a), ExprKind::Int(b)) = (&start.kind, &end.kind) {
                    if b - a > MAX_LOOP_TRIPS {
                        self.error(end.span, format!("this loop runs {} times; the limit is {MAX_LOOP_TRIPS}", b - a));
                    }
                }
                let mark = self.locals.len();
                self.locals.push(Local { name: var.name.clone(), ty: Ty::Int, mutable: false, konst: true });
                for s in &body.stmts {
                    self.check_stmt(s);
                }
                if let Some(tail) = &body.tail {
                    self.error(tail.span, "a loop body has no value").hint =
                        Some("end the expression with `;`, or assign it: `acc += …;`".into());
                }
                self.locals.truncate(mark);
            }
        }
    }

    fn check_call(&mut self, span: Span, name: &ast::Ident, args: &[ast::Arg]) -> Typed {
        let callee = match self.set.lookup(self.module, &name.name) {
            Ok(found) => found,
            Err(candidates) => {
                self.ambiguous(name, &candidates);
                for a in args {
                    self.check_expr(&a.value);
                }
                return Typed::error();
            }
        };
        match callee {
            Some(item @ ItemRef::Fn(module, index)) => {
                if module == self.module {
                    if let Some(caller) = self.current_fn {
                        self.calls.entry(caller).or_default().push((index, name.span));
                    }
                }
                self.check_user_call(span, name, item, args)
            }
            Some(ItemRef::Const(..)) => {
                self.error(name.span, format!("`{}` is a constant, not a function", name.name));
                Typed::error()
            }
            None => match Builtin::from_name(&name.name) {
                Some(b) => self.check_builtin_call(span, name, b, args),
                None => {
                    let mut names: Vec<String> =
                        self.set.visible_names(self.module).into_iter().map(String::from).collect();
                    names.extend(Builtin::names().map(String::from));
                    let hint = did_you_mean(&name.name, names.iter().map(|s| s.as_str()));
                    self.error(name.span, format!("unknown function `{}`", name.name)).hint =
                        hint.or_else(|| Some("is an `import` missing? e.g. `import std.noise;`".into()));
                    for a in args {
                        self.check_expr(&a.value);
                    }
                    Typed::error()
                }
            },
        }
    }

    fn check_builtin_call(&mut self, span: Span, name: &ast::Ident, b: Builtin, args: &[ast::Arg]) -> Typed {
        let mut tys = Vec::new();
        let mut konst = b.preserves_constness();
        for a in args {
            if let Some(n) = &a.name {
                self.error(n.span, format!("built-in `{}` takes no named arguments", name.name));
            }
            let t = self.check_expr(&a.value);
            konst &= t.konst;
            tys.push(t.ty);
        }
        match b.check(&tys) {
            Ok(ty) => Typed::new(ty, konst),
            Err(msg) => {
                self.error(span, format!("`{}` {msg}", name.name));
                Typed::error()
            }
        }
    }

    fn check_user_call(&mut self, span: Span, name: &ast::Ident, item: ItemRef, args: &[ast::Arg]) -> Typed {
        let sig = self.signature(item);
        let mut bound: HashMap<usize, Span> = HashMap::new();
        let mut seen_named = false;
        for (k, arg) in args.iter().enumerate() {
            let t = self.check_expr(&arg.value);
            let slot = match &arg.name {
                None => {
                    if seen_named {
                        self.error(arg.value.span, "positional argument after a named one").hint =
                            Some("put positional arguments first".into());
                        continue;
                    }
                    if k >= sig.params.len() {
                        self.error(
                            arg.value.span,
                            format!("`{}` takes at most {} arguments", name.name, sig.params.len()),
                        );
                        continue;
                    }
                    k
                }
                Some(n) => {
                    seen_named = true;
                    match sig.params.iter().position(|p| p.name == n.name) {
                        Some(i) => i,
                        None => {
                            let hint =
                                did_you_mean(&n.name, sig.params.iter().map(|p| p.name.as_str())).or_else(|| {
                                    Some(format!(
                                        "its parameters are: {}",
                                        sig.params.iter().map(|p| p.name.as_str()).collect::<Vec<_>>().join(", ")
                                    ))
                                });
                            self.error(n.span, format!("`{}` has no parameter `{}`", name.name, n.name)).hint = hint;
                            continue;
                        }
                    }
                }
            };
            if bound.insert(slot, arg.value.span).is_some() {
                self.error(arg.value.span, format!("argument `{}` is given twice", sig.params[slot].name));
                continue;
            }
            let p = &sig.params[slot];
            if !t.ty.coerces_to(&p.ty) {
                self.error(
                    arg.value.span,
                    format!("argument `{}` of `{}` expects {}, found {}", p.name, name.name, p.ty, t.ty),
                )
                .label = format!("this is {}", t.ty);
            } else if p.is_const && !t.konst {
                self.error(
                    arg.value.span,
                    format!("argument `{}` of `{}` must be a compile-time constant", p.name, name.name),
                )
                .hint = Some("it drives unrolling; use a literal, a `const`, or a `const` parameter".into());
            }
        }
        let missing: Vec<&str> = sig
            .params
            .iter()
            .enumerate()
            .filter(|(i, p)| !p.has_default && !bound.contains_key(i))
            .map(|(_, p)| p.name.as_str())
            .collect();
        if !missing.is_empty() {
            self.error(
                span,
                format!(
                    "missing argument{} `{}` in call to `{}`",
                    if missing.len() > 1 { "s" } else { "" },
                    missing.join("`, `"),
                    name.name
                ),
            );
        }
        Typed::new(sig.ret.clone(), false)
    }
}

fn binary_hint(op: BinOp, a: &Ty, b: &Ty) -> Option<String> {
    match op {
        BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge
            if a.width().is_some_and(|w| w > 1) || b.width().is_some_and(|w| w > 1) =>
        {
            Some("comparisons are between scalars; compare a component such as `.x`".into())
        }
        BinOp::And | BinOp::Or => Some("`&&` and `||` combine bools (comparisons)".into()),
        _ if a.width().zip(b.width()).is_some_and(|(x, y)| x > 1 && y > 1 && x != y) => {
            Some("use a swizzle (`.xy`) or a constructor (`vec3(v, 0.0)`) to match the widths".into())
        }
        _ => None,
    }
}
