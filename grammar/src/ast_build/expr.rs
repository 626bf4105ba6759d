//! Building expressions, blocks and statements of the AST from pest pairs.
//!
//! Every built expression also reports its *depth* (the longest chain of nested
//! nodes below it). Bracket nesting is bounded by `scan.rs`, but operator chains
//! (`a + b + c + …`, `- - - x`, `else if` chains) are not, and a very deep tree would
//! overflow the stack of whoever walks or even drops it. Beyond [`MAX_EXPR_DEPTH`]
//! we report an error and cut the tree short.

use super::{AstBuilder, Pair, Pairs};
use crate::ast::*;
use crate::syntax::Rule;
use pest::pratt_parser::{Assoc, Op, PrattParser};
use std::sync::LazyLock;

/// The deepest expression tree the parser builds (counting blocks and statements on
/// the way down). Consumers can recurse over the AST without fear up to this depth.
pub const MAX_EXPR_DEPTH: usize = 512;

/// An AST node with its depth.
pub(crate) struct Deep<T> {
    pub node: T,
    pub depth: usize,
}

/// Precedence, loosest first; all binary operators are left-associative.
static PRATT: LazyLock<PrattParser<Rule>> = LazyLock::new(|| {
    let left = |rule| Op::infix(rule, Assoc::Left);
    PrattParser::new()
        .op(left(Rule::op_or))
        .op(left(Rule::op_and))
        .op(left(Rule::op_eq) | left(Rule::op_ne))
        .op(left(Rule::op_lt) | left(Rule::op_le) | left(Rule::op_gt) | left(Rule::op_ge))
        .op(left(Rule::op_add) | left(Rule::op_sub))
        .op(left(Rule::op_mul) | left(Rule::op_div) | left(Rule::op_rem))
});

fn binary_op(rule: Rule) -> BinOp {
    match rule {
        Rule::op_or => BinOp::Or,
        Rule::op_and => BinOp::And,
        Rule::op_eq => BinOp::Eq,
        Rule::op_ne => BinOp::Ne,
        Rule::op_lt => BinOp::Lt,
        Rule::op_le => BinOp::Le,
        Rule::op_gt => BinOp::Gt,
        Rule::op_ge => BinOp::Ge,
        Rule::op_add => BinOp::Add,
        Rule::op_sub => BinOp::Sub,
        Rule::op_mul => BinOp::Mul,
        Rule::op_div => BinOp::Div,
        Rule::op_rem => BinOp::Rem,
        other => unreachable!("not a binary operator: {other:?}"),
    }
}

impl AstBuilder<'_> {
    /// Builds a node one level above children of depth `below`, or a placeholder
    /// (with one error, at the level where the limit is first crossed) when too deep.
    fn node(&self, kind: ExprKind, span: Span, below: usize) -> Deep<Expr> {
        let depth = below + 1;
        if depth > MAX_EXPR_DEPTH {
            if below == MAX_EXPR_DEPTH {
                self.error_with_hint(
                    format!("expression nested too deeply (more than {MAX_EXPR_DEPTH} levels)"),
                    span,
                    "split it into `let` bindings",
                );
            }
            // Dropping `kind` here is safe: its children are at most MAX_EXPR_DEPTH deep
            // (anything deeper was already replaced by a placeholder).
            return Deep { node: Expr { kind: ExprKind::Float(0.0), span }, depth };
        }
        Deep { node: Expr { kind, span }, depth }
    }

    pub(crate) fn expr(&self, pair: Pair) -> Deep<Expr> {
        debug_assert_eq!(pair.as_rule(), Rule::expr);
        PRATT
            .map_primary(|unary| self.unary(unary))
            .map_infix(|lhs, op, rhs| {
                let span = lhs.node.span.to(rhs.node.span);
                let below = lhs.depth.max(rhs.depth);
                let kind = ExprKind::Binary(binary_op(op.as_rule()), Box::new(lhs.node), Box::new(rhs.node));
                self.node(kind, span, below)
            })
            .parse(pair.into_inner())
    }

    /// `prefix* primary .field*`: postfix binds tighter than prefix (`-a.x` is `-(a.x)`).
    fn unary(&self, pair: Pair) -> Deep<Expr> {
        let mut prefixes = Vec::new();
        let mut inner = pair.into_inner();
        let mut operand = loop {
            let part = inner.next().expect("grammar: a unary has a primary");
            match part.as_rule() {
                Rule::op_neg => prefixes.push((UnOp::Neg, self.span(&part))),
                Rule::op_not => prefixes.push((UnOp::Not, self.span(&part))),
                _ => break self.primary(part),
            }
        };
        for access in inner {
            let span = operand.node.span.to(self.span(&access));
            let field = self.ident(access.into_inner().nth(1).expect("grammar: `.` name"));
            let below = operand.depth;
            operand = self.node(ExprKind::Field(Box::new(operand.node), field), span, below);
        }
        for (op, op_span) in prefixes.into_iter().rev() {
            let span = op_span.to(operand.node.span);
            let below = operand.depth;
            operand = self.node(ExprKind::Unary(op, Box::new(operand.node)), span, below);
        }
        operand
    }

    fn primary(&self, pair: Pair) -> Deep<Expr> {
        let span = self.span(&pair);
        match pair.as_rule() {
            Rule::float_lit => self.node(ExprKind::Float(self.float_literal(&pair)), span, 0),
            Rule::int_lit => self.node(ExprKind::Int(self.int_literal(&pair)), span, 0),
            Rule::bool_lit => {
                let value = pair.into_inner().next().map(|kw| kw.as_rule()) == Some(Rule::kw_true);
                self.node(ExprKind::Bool(value), span, 0)
            }
            Rule::name => {
                let ident = self.ident(pair.into_inner().next().expect("grammar: name"));
                self.node(ExprKind::Name(ident), span, 0)
            }
            Rule::call => self.call(pair),
            Rule::record => self.record(pair),
            Rule::paren => {
                // The parentheses add no node, but the span covers them so that
                // `(a + b).x` reads naturally in messages.
                let inner = pair.into_inner().find(|p| p.as_rule() == Rule::expr);
                let mut built = self.expr(inner.expect("grammar: parenthesised expr"));
                built.node.span = span;
                built
            }
            Rule::block => {
                let block = self.block(pair);
                self.node(ExprKind::Block(Box::new(block.node)), span, block.depth)
            }
            Rule::if_expr => self.if_chain(pair),
            other => unreachable!("grammar: unexpected primary {other:?}"),
        }
    }

    fn float_literal(&self, pair: &Pair) -> f64 {
        let text = pair.as_str();
        let value: f64 = text.parse().unwrap_or(f64::INFINITY);
        // `float` is 32-bit: a literal that does not fit would silently become inf.
        if !value.is_finite() || !(value as f32).is_finite() {
            self.error_with_hint(
                format!("literal out of range: `{text}`"),
                self.span(pair),
                "a float is 32-bit; its largest value is about 3.4e38",
            );
            return 0.0;
        }
        value
    }

    fn int_literal(&self, pair: &Pair) -> i64 {
        let text = pair.as_str();
        text.parse().unwrap_or_else(|_| {
            self.error_with_hint(
                format!("literal out of range: `{text}`"),
                self.span(pair),
                format!("an int must fit in 64 bits (at most {})", i64::MAX),
            );
            0
        })
    }

    /// `name(positional…, named: …)`.
    fn call(&self, pair: Pair) -> Deep<Expr> {
        let span = self.span(&pair);
        let mut inner = pair.into_inner();
        let callee = self.ident(inner.next().expect("grammar: callee"));
        let mut args = Vec::new();
        let mut below = 0;
        let mut seen_named = false;
        for arg in inner.filter(|p| p.as_rule() == Rule::arg) {
            let arg_span = self.span(&arg);
            let mut parts = arg.into_inner().filter(|p| p.as_rule() != Rule::colon);
            let first = parts.next().expect("grammar: arg");
            let (name, value) = if first.as_rule() == Rule::ident {
                (Some(self.ident(first)), self.expr(parts.next().expect("grammar: arg value")))
            } else {
                (None, self.expr(first))
            };
            if name.is_some() {
                seen_named = true;
            } else if seen_named {
                self.error_with_hint(
                    "positional argument after a named argument",
                    arg_span,
                    "named arguments come last: `f(a, b, k: 2)`",
                );
            }
            below = below.max(value.depth);
            args.push(Arg { name, value: value.node });
        }
        self.node(ExprKind::Call(callee, args), span, below)
    }

    /// `(a: x, b: y)`.
    fn record(&self, pair: Pair) -> Deep<Expr> {
        let span = self.span(&pair);
        let mut fields = Vec::new();
        let mut below = 0;
        for field in pair.into_inner().filter(|p| p.as_rule() == Rule::field_init) {
            let mut parts = field.into_inner().filter(|p| p.as_rule() != Rule::colon);
            let name = self.ident(parts.next().expect("grammar: field name"));
            let value = self.expr(parts.next().expect("grammar: field value"));
            below = below.max(value.depth);
            fields.push((name, value.node));
        }
        self.node(ExprKind::Record(fields), span, below)
    }

    /// `if c0 { b0 } else if c1 { b1 } … else { bn }`, nested from the right.
    fn if_chain(&self, pair: Pair) -> Deep<Expr> {
        let end = self.span(&pair).end;
        let mut arms = Vec::new(); // (start of `if`, condition, block)
        let mut if_start = None;
        let mut condition = None;
        let mut final_block = None;
        for part in pair.into_inner() {
            match part.as_rule() {
                Rule::kw_if => if_start = Some(self.span(&part).start),
                Rule::expr => condition = Some(self.expr(part)),
                Rule::block => {
                    let block = self.block(part);
                    match (if_start.take(), condition.take()) {
                        (Some(start), Some(cond)) => arms.push((start, cond, block)),
                        _ => final_block = Some(block),
                    }
                }
                _ => {} // `else`
            }
        }
        let mut otherwise = final_block.expect("grammar: an `if` ends with `else { … }`");
        // Fold the arms from the last one; each nested `if` becomes the sole tail of
        // the enclosing `else` block, as if written `else { if … }`.
        loop {
            let (start, cond, then) = arms.pop().expect("grammar: an `if` has one arm");
            let span = Span::new(start, end);
            let below = cond.depth.max(then.depth).max(otherwise.depth);
            let kind = ExprKind::If(Box::new(cond.node), Box::new(then.node), Box::new(otherwise.node));
            let nested = self.node(kind, span, below);
            if arms.is_empty() {
                return nested;
            }
            let depth = nested.depth + 1;
            let block = Block { stmts: Vec::new(), tail: Some(Box::new(nested.node)), span };
            otherwise = Deep { node: block, depth };
        }
    }

    /// `{ stmt* expr }` or a loop body `{ stmt* }`.
    pub(crate) fn block(&self, pair: Pair) -> Deep<Block> {
        let span = self.span(&pair);
        let mut stmts = Vec::new();
        let mut tail = None;
        let mut below = 0;
        for part in pair.into_inner() {
            match part.as_rule() {
                Rule::expr => {
                    let value = self.expr(part);
                    below = below.max(value.depth);
                    tail = Some(Box::new(value.node));
                }
                Rule::let_stmt | Rule::assign_stmt | Rule::for_stmt => {
                    let stmt = self.stmt(part);
                    below = below.max(stmt.depth);
                    stmts.push(stmt.node);
                }
                _ => {} // braces
            }
        }
        Deep { node: Block { stmts, tail, span }, depth: below + 1 }
    }

    fn stmt(&self, pair: Pair) -> Deep<Stmt> {
        let span = self.span(&pair);
        let rule = pair.as_rule();
        let mut parts = significant(pair.into_inner());
        match rule {
            Rule::let_stmt => {
                let mutable = parts.next().map(|kw| kw.as_rule()) == Some(Rule::kw_var);
                let name = self.ident(parts.next().expect("grammar: let name"));
                let mut next = parts.next().expect("grammar: let value");
                let ty = if next.as_rule() == Rule::expr {
                    None
                } else {
                    let ty = self.type_expr(next);
                    next = parts.next().expect("grammar: let value");
                    Some(ty)
                };
                let value = self.expr(next);
                let depth = value.depth + 1;
                Deep { node: Stmt::Let { mutable, name, ty, value: value.node, span }, depth }
            }
            Rule::assign_stmt => {
                let target = self.ident(parts.next().expect("grammar: assignment target"));
                let op = match parts.next().expect("grammar: assignment operator").as_str() {
                    "+=" => Some(BinOp::Add),
                    "-=" => Some(BinOp::Sub),
                    "*=" => Some(BinOp::Mul),
                    "/=" => Some(BinOp::Div),
                    _ => None,
                };
                let value = self.expr(parts.next().expect("grammar: assigned value"));
                let depth = value.depth + 1;
                Deep { node: Stmt::Assign { target, op, value: value.node, span }, depth }
            }
            Rule::for_stmt => {
                let var = self.ident(parts.next().expect("grammar: loop variable"));
                let start = self.expr(parts.next().expect("grammar: loop start"));
                let end = self.expr(parts.next().expect("grammar: loop end"));
                let body = self.block(parts.next().expect("grammar: loop body"));
                let depth = start.depth.max(end.depth).max(body.depth) + 1;
                let node = Stmt::For { var, start: start.node, end: end.node, body: body.node, span };
                Deep { node, depth }
            }
            other => unreachable!("grammar: unexpected statement {other:?}"),
        }
    }

    /// `float`, `vec2`, … or `(a: float, id: vec2)`.
    pub(crate) fn type_expr(&self, pair: Pair) -> TypeExpr {
        match pair.as_rule() {
            Rule::type_name => TypeExpr::Named(self.ident(pair.into_inner().next().expect("grammar: type name"))),
            Rule::record_type => {
                let span = self.span(&pair);
                let fields = pair
                    .into_inner()
                    .filter(|p| p.as_rule() == Rule::field_type)
                    .map(|field| {
                        let mut parts = significant(field.into_inner());
                        let name = self.ident(parts.next().expect("grammar: field name"));
                        (name, self.type_expr(parts.next().expect("grammar: field type")))
                    })
                    .collect();
                TypeExpr::Record(fields, span)
            }
            other => unreachable!("grammar: unexpected type {other:?}"),
        }
    }
}

/// The children that carry meaning: punctuation and the keywords that only introduce
/// a construct are dropped (keywords that *choose* something, like `var` vs `let`,
/// are kept).
pub(crate) fn significant(pairs: Pairs) -> impl Iterator<Item = Pair> {
    pairs.filter(|p| {
        !matches!(
            p.as_rule(),
            Rule::semi
                | Rule::comma
                | Rule::colon
                | Rule::dot
                | Rule::dotdot
                | Rule::arrow
                | Rule::lparen
                | Rule::rparen
                | Rule::lbrace
                | Rule::rbrace
                | Rule::lbracket
                | Rule::rbracket
                | Rule::assign
                | Rule::kw_import
                | Rule::kw_fn
                | Rule::kw_graph
                | Rule::kw_for
                | Rule::kw_in
                | Rule::kw_param
                | Rule::kw_node
                | Rule::kw_output
                | Rule::kw_category
                | Rule::kw_description
        )
    })
}
