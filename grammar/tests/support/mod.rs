//! Test helpers: a compact S-expression printer for the AST (so that golden files
//! stay readable) and a plain-text renderer for errors.
#![allow(dead_code)] // each test binary uses a different part

use psc_grammar::ast::*;
use psc_grammar::{line_col, ParseError};
use std::fmt::Write;

/// Prints the items one per line, the parts of fns and graphs indented below them.
pub fn print_file(file: &File) -> String {
    let mut out = String::new();
    for item in &file.items {
        print_item(&mut out, item);
    }
    out
}

fn doc(doc: &Option<String>) -> String {
    doc.as_ref().map_or(String::new(), |d| format!("  doc={d:?}"))
}

fn print_item(out: &mut String, item: &Item) {
    match item {
        Item::Import(import) => {
            let path: Vec<&str> = import.path.iter().map(|i| i.name.as_str()).collect();
            writeln!(out, "import {}", path.join(".")).unwrap();
        }
        Item::Const(c) => writeln!(out, "const {} = {}{}", c.name.name, expr(&c.value), doc(&c.doc)).unwrap(),
        Item::Fn(f) => {
            writeln!(out, "fn {} -> {}{}", f.name.name, ty(&f.ret), doc(&f.doc)).unwrap();
            for p in &f.params {
                let konst = if p.is_const { "const " } else { "" };
                let default = p.default.as_ref().map_or(String::new(), |d| format!(" = {}", expr(d)));
                writeln!(out, "  param {konst}{}: {}{default}", p.name.name, ty(&p.ty)).unwrap();
            }
            print_block_lines(out, &f.body, 1);
        }
        Item::Graph(g) => {
            writeln!(out, "graph {}{}", g.name.name, doc(&g.doc)).unwrap();
            for member in &g.members {
                print_member(out, member);
            }
        }
    }
}

fn print_member(out: &mut String, member: &GraphMember) {
    let line = match member {
        GraphMember::Category(name, _) => format!("category {}", name.name),
        GraphMember::Description(text, _) => format!("description {text:?}"),
        GraphMember::Param(p) => {
            let range =
                p.range.as_ref().map_or(String::new(), |(lo, hi, _)| format!(" in [{}, {}]", expr(lo), expr(hi)));
            let int = if p.is_int { " int" } else { "" };
            format!("param {} = {}{range}{int}{}", p.name.name, expr(&p.default), doc(&p.doc))
        }
        GraphMember::Node { name, value, .. } => format!("node {} = {}", name.name, expr(value)),
        GraphMember::Const(c) => {
            format!("const {} = {}{}", c.name.name, expr(&c.value), doc(&c.doc))
        }
        GraphMember::Output { name, value, .. } => {
            format!("output {} = {}", name.name, expr(value))
        }
    };
    writeln!(out, "  {line}").unwrap();
}

fn print_block_lines(out: &mut String, block: &Block, depth: usize) {
    let indent = "  ".repeat(depth);
    for s in &block.stmts {
        match s {
            Stmt::For { var, start, end, body, .. } => {
                writeln!(out, "{indent}for {} in {} .. {}", var.name, expr(start), expr(end)).unwrap();
                print_block_lines(out, body, depth + 1);
            }
            other => writeln!(out, "{indent}{}", stmt(other)).unwrap(),
        }
    }
    if let Some(tail) = &block.tail {
        writeln!(out, "{indent}=> {}", expr(tail)).unwrap();
    }
}

fn stmt(s: &Stmt) -> String {
    match s {
        Stmt::Let { mutable, name, ty: t, value, .. } => {
            let kw = if *mutable { "var" } else { "let" };
            let t = t.as_ref().map_or(String::new(), |t| format!(": {}", ty(t)));
            format!("{kw} {}{t} = {}", name.name, expr(value))
        }
        Stmt::Assign { target, op, value, .. } => {
            let op = op.map_or("=".to_owned(), |op| format!("{}=", op.symbol()));
            format!("{} {op} {}", target.name, expr(value))
        }
        Stmt::For { var, start, end, body, .. } => {
            format!("for {} in {} .. {} {}", var.name, expr(start), expr(end), inline_block(body))
        }
    }
}

fn ty(t: &TypeExpr) -> String {
    match t {
        TypeExpr::Named(name) => name.name.clone(),
        TypeExpr::Record(fields, _) => {
            let fields: Vec<String> = fields.iter().map(|(n, t)| format!("{}: {}", n.name, ty(t))).collect();
            format!("({})", fields.join(", "))
        }
    }
}

fn inline_block(block: &Block) -> String {
    let mut parts: Vec<String> = block.stmts.iter().map(|s| format!("{};", stmt(s))).collect();
    if let Some(tail) = &block.tail {
        parts.push(expr(tail));
    }
    format!("{{ {} }}", parts.join(" "))
}

/// Expressions as fully parenthesised prefix forms: precedence is explicit.
pub fn expr(e: &Expr) -> String {
    match &e.kind {
        ExprKind::Float(v) => format!("{v:?}"),
        ExprKind::Int(v) => v.to_string(),
        ExprKind::Bool(v) => v.to_string(),
        ExprKind::Name(name) => name.name.clone(),
        ExprKind::Unary(UnOp::Neg, x) => format!("(neg {})", expr(x)),
        ExprKind::Unary(UnOp::Not, x) => format!("(not {})", expr(x)),
        ExprKind::Binary(op, l, r) => format!("({} {} {})", op.symbol(), expr(l), expr(r)),
        ExprKind::Call(name, args) => {
            let mut s = format!("({}", name.name);
            for arg in args {
                match &arg.name {
                    Some(n) => write!(s, " {}: {}", n.name, expr(&arg.value)).unwrap(),
                    None => write!(s, " {}", expr(&arg.value)).unwrap(),
                }
            }
            s + ")"
        }
        ExprKind::Field(x, field) => format!("(. {} {})", expr(x), field.name),
        ExprKind::Record(fields) => {
            let fields: Vec<String> = fields.iter().map(|(n, v)| format!("{}: {}", n.name, expr(v))).collect();
            format!("(record {})", fields.join(", "))
        }
        ExprKind::If(c, a, b) => {
            format!("(if {} {} {})", expr(c), inline_block(a), inline_block(b))
        }
        ExprKind::Block(b) => inline_block(b),
    }
}

/// Renders errors like the CLI will: position, message, source line, caret, hint.
pub fn render_errors(src: &str, errors: &[ParseError]) -> String {
    let mut out = String::new();
    for error in errors {
        let (line, col) = line_col(src, error.span.start);
        writeln!(out, "{line}:{col}: {}", error.message).unwrap();
        let text = src.lines().nth(line - 1).unwrap_or("");
        let shown: String = text.chars().map(|c| if c.is_control() { '?' } else { c }).collect();
        writeln!(out, "  | {shown}").unwrap();
        let width = src[error.span.start..error.span.end].chars().take_while(|&c| c != '\n').count().max(1);
        writeln!(out, "  | {}{}", " ".repeat(col - 1), "^".repeat(width)).unwrap();
        if let Some(hint) = &error.hint {
            writeln!(out, "  = hint: {hint}").unwrap();
        }
    }
    out
}

/// Calls `f` with the kind and span of every node of the file (items, members,
/// statements, blocks, expressions, types, names), parents before children.
pub fn for_each_span(file: &File, f: &mut dyn FnMut(&str, Span)) {
    for item in &file.items {
        match item {
            Item::Import(import) => {
                f("import", import.span);
                import.path.iter().for_each(|i| ident(i, f));
            }
            Item::Const(c) => const_def(c, f),
            Item::Fn(func) => {
                f("fn", func.span);
                ident(&func.name, f);
                for p in &func.params {
                    f("fn_param", p.span);
                    ident(&p.name, f);
                    type_spans(&p.ty, f);
                    p.default.iter().for_each(|d| expr_spans(d, f));
                }
                type_spans(&func.ret, f);
                block_spans(&func.body, f);
            }
            Item::Graph(g) => {
                f("graph", g.span);
                ident(&g.name, f);
                for member in &g.members {
                    member_spans(member, f);
                }
            }
        }
    }
}

fn ident(i: &Ident, f: &mut dyn FnMut(&str, Span)) {
    f("ident", i.span);
}

fn const_def(c: &ConstDef, f: &mut dyn FnMut(&str, Span)) {
    f("const", c.span);
    ident(&c.name, f);
    expr_spans(&c.value, f);
}

fn member_spans(member: &GraphMember, f: &mut dyn FnMut(&str, Span)) {
    match member {
        GraphMember::Category(name, span) => {
            f("category", *span);
            ident(name, f);
        }
        GraphMember::Description(_, span) => f("description", *span),
        GraphMember::Param(p) => {
            f("param", p.span);
            ident(&p.name, f);
            expr_spans(&p.default, f);
            if let Some((lo, hi, span)) = &p.range {
                f("range", *span);
                expr_spans(lo, f);
                expr_spans(hi, f);
            }
        }
        GraphMember::Node { name, value, span } | GraphMember::Output { name, value, span } => {
            f("member", *span);
            ident(name, f);
            expr_spans(value, f);
        }
        GraphMember::Const(c) => const_def(c, f),
    }
}

fn type_spans(t: &TypeExpr, f: &mut dyn FnMut(&str, Span)) {
    f("type", t.span());
    if let TypeExpr::Record(fields, _) = t {
        for (name, t) in fields {
            ident(name, f);
            type_spans(t, f);
        }
    }
}

fn block_spans(block: &Block, f: &mut dyn FnMut(&str, Span)) {
    f("block", block.span);
    for s in &block.stmts {
        match s {
            Stmt::Let { name, ty, value, span, .. } => {
                f("let", *span);
                ident(name, f);
                ty.iter().for_each(|t| type_spans(t, f));
                expr_spans(value, f);
            }
            Stmt::Assign { target, value, span, .. } => {
                f("assign", *span);
                ident(target, f);
                expr_spans(value, f);
            }
            Stmt::For { var, start, end, body, span } => {
                f("for", *span);
                ident(var, f);
                expr_spans(start, f);
                expr_spans(end, f);
                block_spans(body, f);
            }
        }
    }
    block.tail.iter().for_each(|t| expr_spans(t, f));
}

fn expr_spans(e: &Expr, f: &mut dyn FnMut(&str, Span)) {
    f("expr", e.span);
    match &e.kind {
        ExprKind::Float(_) | ExprKind::Int(_) | ExprKind::Bool(_) => {}
        ExprKind::Name(name) => ident(name, f),
        ExprKind::Unary(_, x) => expr_spans(x, f),
        ExprKind::Binary(_, l, r) => {
            expr_spans(l, f);
            expr_spans(r, f);
        }
        ExprKind::Call(name, args) => {
            ident(name, f);
            for arg in args {
                arg.name.iter().for_each(|n| ident(n, f));
                expr_spans(&arg.value, f);
            }
        }
        ExprKind::Field(x, name) => {
            expr_spans(x, f);
            ident(name, f);
        }
        ExprKind::Record(fields) => {
            for (name, value) in fields {
                ident(name, f);
                expr_spans(value, f);
            }
        }
        ExprKind::If(c, a, b) => {
            expr_spans(c, f);
            block_spans(a, f);
            block_spans(b, f);
        }
        ExprKind::Block(b) => block_spans(b, f),
    }
}

/// Checks the invariants every span must satisfy: inside `src`, on char boundaries,
/// not reversed.
pub fn assert_span_valid(src: &str, what: &str, span: Span) {
    assert!(
        span.start <= span.end && span.end <= src.len(),
        "{what} span {span:?} outside input of {} bytes",
        src.len()
    );
    assert!(
        src.is_char_boundary(span.start) && src.is_char_boundary(span.end),
        "{what} span {span:?} not on char boundaries"
    );
}
