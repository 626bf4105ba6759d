//! Lowering expressions, blocks, statements and calls.

use psc_grammar::ast::{self, BinOp, Expr, ExprKind, Span, UnOp};

use super::builtins::{lower_builtin, partial, substitute, zip_with};
use super::{Lowered, Lowerer, Value};
use crate::builtins::Builtin;
use crate::check::MAX_LOOP_TRIPS;
use crate::ir::NodeId;
use crate::module::ItemRef;
use crate::types::swizzle;

impl Lowerer<'_> {
    pub(super) fn lower_expr(&mut self, e: &Expr) -> Lowered<Value> {
        self.visits += 1;
        Ok(match &e.kind {
            ExprKind::Float(x) => Value::scalar(self.b.constant(*x as f32)),
            ExprKind::Int(i) => Value::scalar(self.b.constant(*i as f32)),
            ExprKind::Bool(x) => Value::scalar(self.b.constant(if *x { 1.0 } else { 0.0 })),
            ExprKind::Name(id) => self.lower_name(id)?,
            ExprKind::Unary(op, inner) => {
                let v = self.lower_expr(inner)?;
                match op {
                    UnOp::Neg => v.map_nodes(&mut |id| self.b.neg(id)),
                    UnOp::Not => v.map_nodes(&mut |id| {
                        let one = self.b.constant(1.0);
                        self.b.sub(one, id)
                    }),
                }
            }
            ExprKind::Binary(op, a, b) => {
                let a = self.lower_expr(a)?;
                let b = self.lower_expr(b)?;
                self.binary(*op, &a, &b)
            }
            ExprKind::Call(name, args) => {
                let v = self.lower_call(e.span, name, args)?;
                self.check_size(e.span)?;
                v
            }
            ExprKind::Field(base, field) => {
                let v = self.lower_expr(base)?;
                match &v {
                    Value::Record(fields) => fields
                        .iter()
                        .find(|(n, _)| *n == field.name)
                        .map(|(_, v)| v.clone())
                        .ok_or_else(|| self.error(field.span, "internal: unknown field survived checking"))?,
                    Value::Num(comps) => {
                        let idx = swizzle(&field.name, comps.len())
                            .ok_or_else(|| self.error(field.span, "internal: bad swizzle survived checking"))?;
                        Value::Num(idx.iter().map(|&i| comps[i]).collect())
                    }
                }
            }
            ExprKind::Record(fields) => {
                let mut out = Vec::new();
                for (name, value) in fields {
                    out.push((name.name.clone(), self.lower_expr(value)?));
                }
                Value::Record(out.into())
            }
            ExprKind::If(cond, then, otherwise) => {
                let c = self.lower_expr(cond)?.comp(0);
                let a = self.lower_block(then)?;
                let b = self.lower_block(otherwise)?;
                self.select(c, &a, &b)
            }
            ExprKind::Block(block) => self.lower_block(block)?,
        })
    }

    fn select(&mut self, c: NodeId, a: &Value, b: &Value) -> Value {
        match (a, b) {
            (Value::Record(fa), Value::Record(fb)) => Value::Record(
                fa.iter()
                    .zip(fb.iter())
                    .map(|((n, x), (_, y))| (n.clone(), self.select(c, x, y)))
                    .collect::<Vec<_>>()
                    .into(),
            ),
            _ => zip_with(&mut self.b, &[a.clone(), b.clone()], |b, v| b.select(c, v[0], v[1])),
        }
    }

    pub(super) fn binary(&mut self, op: BinOp, a: &Value, b: &Value) -> Value {
        let args = [a.clone(), b.clone()];
        zip_with(&mut self.b, &args, |b, v| {
            let (x, y) = (v[0], v[1]);
            match op {
                BinOp::Add => b.add(x, y),
                BinOp::Sub => b.sub(x, y),
                BinOp::Mul => b.mul(x, y),
                BinOp::Div => b.div(x, y),
                BinOp::Rem => {
                    let q = b.div(x, y);
                    let f = b.floor(q);
                    let m = b.mul(y, f);
                    b.sub(x, m)
                }
                BinOp::Lt => b.lt(x, y),
                BinOp::Le => b.le(x, y),
                BinOp::Gt => b.lt(y, x),
                BinOp::Ge => b.le(y, x),
                BinOp::Eq => b.eq(x, y),
                BinOp::Ne => {
                    let e = b.eq(x, y);
                    let one = b.constant(1.0);
                    b.sub(one, e)
                }
                BinOp::And => b.mul(x, y),
                BinOp::Or => b.max(x, y),
            }
        })
    }

    fn lower_name(&mut self, id: &ast::Ident) -> Lowered<Value> {
        if let Some((_, v)) = self.locals.iter().rev().find(|(n, _)| *n == id.name) {
            return Ok(v.clone());
        }
        if let Some(graph) = self.graph.clone() {
            if let Some(v) = graph.params.get(&id.name) {
                return Ok(v.clone());
            }
            if let Some(v) = graph.values.borrow().get(&id.name) {
                return Ok(v.clone());
            }
            if let Some(e) = graph.nodes.get(&id.name).or_else(|| graph.consts.get(&id.name)) {
                // Node bodies see only graph-level names, never the locals of the use site.
                let saved = std::mem::take(&mut self.locals);
                let v = self.lower_expr(e);
                self.locals = saved;
                let v = v?;
                graph.values.borrow_mut().insert(id.name.clone(), v.clone());
                return Ok(v);
            }
        }
        match self.set.lookup(self.module, &id.name) {
            Ok(Some(item @ ItemRef::Const(module, index))) => {
                if let Some(v) = self.consts.get(&item) {
                    return Ok(v.clone());
                }
                let def = self.set.module(module).const_def(index);
                let v = self.in_module(module, None, |l| l.lower_expr(&def.value))?;
                self.consts.insert(item, v.clone());
                Ok(v)
            }
            _ if id.name == "uv" => {
                let (u, v) = (self.b.u(), self.b.v());
                Ok(Value::Num(vec![u, v]))
            }
            _ => Err(self.error(id.span, format!("internal: unresolved name `{}` survived checking", id.name))),
        }
    }

    /// Runs `f` with the scope of another module (function bodies resolve names where they
    /// were written), with only the given locals, and without the graph's names.
    fn in_module<T>(
        &mut self,
        module: crate::module::ModuleId,
        locals: Option<Vec<(String, Value)>>,
        f: impl FnOnce(&mut Self) -> Lowered<T>,
    ) -> Lowered<T> {
        let saved_module = std::mem::replace(&mut self.module, module);
        let saved_file = std::mem::replace(&mut self.file, self.set.module(module).file);
        let saved_locals = std::mem::replace(&mut self.locals, locals.unwrap_or_default());
        let saved_graph = self.graph.take();
        let result = f(self);
        self.module = saved_module;
        self.file = saved_file;
        self.locals = saved_locals;
        self.graph = saved_graph;
        result
    }

    pub(super) fn lower_block(&mut self, block: &ast::Block) -> Lowered<Value> {
        let mark = self.locals.len();
        for stmt in &block.stmts {
            self.lower_stmt(stmt)?;
        }
        let v = match &block.tail {
            Some(tail) => self.lower_expr(tail)?,
            None => return Err(self.error(block.span, "internal: block without value survived checking")),
        };
        self.locals.truncate(mark);
        Ok(v)
    }

    fn lower_stmt(&mut self, stmt: &ast::Stmt) -> Lowered<()> {
        match stmt {
            ast::Stmt::Let { name, value, ty, .. } => {
                let mut v = self.lower_expr(value)?;
                if let Some(ty) = ty {
                    v = self.coerce(v, ty);
                }
                self.locals.push((name.name.clone(), v));
            }
            ast::Stmt::Assign { target, op, value, .. } => {
                let v = self.lower_expr(value)?;
                let slot = self
                    .locals
                    .iter()
                    .rposition(|(n, _)| *n == target.name)
                    .ok_or_else(|| self.error(target.span, "internal: assignment to unknown variable"))?;
                let new = match op {
                    Some(op) => {
                        let old = self.locals[slot].1.clone();
                        self.binary(*op, &old, &v)
                    }
                    None => v,
                };
                self.locals[slot].1 = new;
            }
            ast::Stmt::For { var, start, end, body, span } => {
                let a = self.const_int(start)?;
                let b = self.const_int(end)?;
                if b - a > MAX_LOOP_TRIPS {
                    return Err(
                        self.error(*span, format!("this loop runs {} times; the limit is {MAX_LOOP_TRIPS}", b - a))
                    );
                }
                for i in a..b {
                    let mark = self.locals.len();
                    let iv = self.b.constant(i as f32);
                    self.locals.push((var.name.clone(), Value::scalar(iv)));
                    for s in &body.stmts {
                        self.lower_stmt(s)?;
                    }
                    self.locals.truncate(mark);
                    self.check_size(*span)?;
                    self.check_work(*span)?;
                }
            }
        }
        Ok(())
    }

    fn const_int(&mut self, e: &Expr) -> Lowered<i64> {
        let v = self.lower_expr(e)?;
        match self.b.const_of(v.comp(0)) {
            Some(x) if x.is_finite() => Ok(x as i64),
            _ => Err(self.error(e.span, "internal: loop bound is not constant")),
        }
    }

    fn lower_call(&mut self, span: Span, name: &ast::Ident, args: &[ast::Arg]) -> Lowered<Value> {
        match self.set.lookup(self.module, &name.name) {
            Ok(Some(ItemRef::Fn(module, index))) => self.inline_call(span, module, index, args),
            _ => {
                let which = Builtin::from_name(&name.name)
                    .ok_or_else(|| self.error(name.span, format!("internal: unknown function `{}`", name.name)))?;
                let mut values = Vec::with_capacity(args.len());
                for a in args {
                    values.push(self.lower_expr(&a.value)?);
                }
                Ok(match which {
                    Builtin::Sample => {
                        let (u, v) = (values[1].comp(0), values[1].comp(1));
                        substitute(&mut self.b, &values[0], u, v)
                    }
                    Builtin::Ddu => partial(&mut self.b, &mut self.d_du, &values[0]),
                    Builtin::Ddv => partial(&mut self.b, &mut self.d_dv, &values[0]),
                    other => lower_builtin(&mut self.b, other, &values),
                })
            }
        }
    }

    fn inline_call(
        &mut self,
        span: Span,
        module: crate::module::ModuleId,
        index: usize,
        args: &[ast::Arg],
    ) -> Lowered<Value> {
        let def = self.set.module(module).fn_def(index);
        let mut bound: Vec<Option<Value>> = vec![None; def.params.len()];
        for (k, arg) in args.iter().enumerate() {
            let slot = match &arg.name {
                None => k,
                Some(n) => def
                    .params
                    .iter()
                    .position(|p| p.name.name == n.name)
                    .ok_or_else(|| self.error(n.span, "internal: unknown named argument"))?,
            };
            let v = self.lower_expr(&arg.value)?;
            bound[slot] = Some(v);
        }
        let mut locals = Vec::with_capacity(def.params.len());
        for (p, v) in def.params.iter().zip(bound) {
            let v = match (v, &p.default) {
                (Some(v), _) => v,
                (None, Some(default)) => self.in_module(module, None, |l| l.lower_expr(default))?,
                (None, None) => return Err(self.error(span, "internal: missing argument survived checking")),
            };
            locals.push((p.name.name.clone(), self.coerce(v, &p.ty)));
        }
        self.check_work(span)?;
        self.calls.push((self.file, span));
        let body = &def.body;
        let result = self.in_module(module, Some(locals), |l| l.lower_block(body));
        self.calls.pop();
        let result = result?;
        Ok(self.coerce(result, &def.ret))
    }

    /// Broadcasts a scalar argument to the declared vector width of a parameter.
    fn coerce(&mut self, v: Value, ty: &ast::TypeExpr) -> Value {
        let width = match ty {
            ast::TypeExpr::Named(id) => match id.name.as_str() {
                "vec2" => 2,
                "vec3" | "color" => 3,
                _ => return v,
            },
            ast::TypeExpr::Record(..) => return v,
        };
        match &v {
            Value::Num(c) if c.len() == 1 => Value::Num(vec![c[0]; width]),
            _ => v,
        }
    }
}
