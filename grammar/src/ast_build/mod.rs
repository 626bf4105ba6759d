//! Building the AST from pest's parse tree: items and graph members here, expressions,
//! blocks and statements in [`expr`]. (This is the grammar's pass, pest pairs → AST; the
//! compiler's `lower` is the later AST → IR pass.)
//!
//! pest has already checked the syntax; what can still go wrong here is what a
//! grammar cannot express well (literal ranges, argument order, string escapes,
//! expression depth). Such problems are collected, not returned early, so that one
//! run reports them all.

mod expr;

pub use expr::MAX_EXPR_DEPTH;

use crate::ast::*;
use crate::error::ParseError;
use crate::syntax::Rule;
use expr::significant;
use std::cell::RefCell;

pub(crate) type Pair<'i> = pest::iterators::Pair<'i, Rule>;
pub(crate) type Pairs<'i> = pest::iterators::Pairs<'i, Rule>;

/// Builds the AST of one parsed chunk of a source file.
pub(crate) struct AstBuilder<'s> {
    /// The whole source file (doc comments are looked up in it).
    src: &'s str,
    /// Where the parsed chunk starts in `src`: added to every pest offset.
    base: usize,
    /// The `///` lines of `src`, in order.
    doc_lines: &'s [Span],
    /// A `RefCell` because the Pratt parser's closures all need to report errors.
    errors: RefCell<Vec<ParseError>>,
}

impl<'s> AstBuilder<'s> {
    pub(crate) fn new(src: &'s str, base: usize, doc_lines: &'s [Span]) -> Self {
        AstBuilder { src, base, doc_lines, errors: RefCell::new(Vec::new()) }
    }

    pub(crate) fn into_errors(self) -> Vec<ParseError> {
        self.errors.into_inner()
    }

    pub(crate) fn error_with_hint(&self, message: impl Into<String>, span: Span, hint: impl Into<String>) {
        self.errors.borrow_mut().push(ParseError::new(message, span).with_hint(hint));
    }

    /// The span of a pair, without trailing whitespace and comments.
    ///
    /// pest ends a rule after the trivia it skipped before an optional or repeated
    /// part that then did not match (`expr ~ semi?`), so a rule's own end can lie past
    /// its last token. The last token never does: follow the last children down to it.
    pub(crate) fn span(&self, pair: &Pair) -> Span {
        let start = pair.as_span().start();
        let mut last = pair.clone();
        while let Some(child) = last.clone().into_inner().last() {
            last = child;
        }
        let end = last.as_span().end().max(start);
        Span::new(start + self.base, end + self.base)
    }

    pub(crate) fn ident(&self, pair: Pair) -> Ident {
        debug_assert_eq!(pair.as_rule(), Rule::ident);
        Ident { name: pair.as_str().to_owned(), span: self.span(&pair) }
    }

    /// Builds the items of the `file` pair.
    pub(crate) fn file(&self, file: Pair) -> Vec<Item> {
        file.into_inner().filter(|p| p.as_rule() != Rule::EOI).map(|item| self.item(item)).collect()
    }

    fn item(&self, pair: Pair) -> Item {
        match pair.as_rule() {
            Rule::import => {
                let span = self.span(&pair);
                let path = significant(pair.into_inner()).map(|p| self.ident(p)).collect();
                Item::Import(Import { path, span })
            }
            Rule::const_def => Item::Const(self.const_def(pair)),
            Rule::fn_def => Item::Fn(self.fn_def(pair)),
            Rule::graph_def => Item::Graph(self.graph_def(pair)),
            other => unreachable!("grammar: unexpected item {other:?}"),
        }
    }

    /// `const NAME = expr` (at file level with its `;`, in a graph without).
    fn const_def(&self, pair: Pair) -> ConstDef {
        let span = self.span(&pair);
        let mut parts = significant(pair.into_inner()).filter(|p| p.as_rule() != Rule::kw_const);
        let name = self.ident(parts.next().expect("grammar: const name"));
        let value = self.expr(parts.next().expect("grammar: const value")).node;
        ConstDef { doc: self.doc_before(span.start), name, value, span }
    }

    fn fn_def(&self, pair: Pair) -> FnDef {
        let span = self.span(&pair);
        let mut params = Vec::new();
        let mut name = None;
        let mut ret = None;
        let mut body = None;
        for part in significant(pair.into_inner()) {
            match part.as_rule() {
                Rule::ident => name = Some(self.ident(part)),
                Rule::fn_param => params.push(self.fn_param(part)),
                Rule::type_name | Rule::record_type => ret = Some(self.type_expr(part)),
                Rule::block => body = Some(self.block(part).node),
                other => unreachable!("grammar: unexpected part of fn {other:?}"),
            }
        }
        FnDef {
            doc: self.doc_before(span.start),
            name: name.expect("grammar: fn name"),
            params,
            ret: ret.expect("grammar: fn result type"),
            body: body.expect("grammar: fn body"),
            span,
        }
    }

    /// `[const] name: type [= default]`.
    fn fn_param(&self, pair: Pair) -> FnParam {
        let span = self.span(&pair);
        let mut parts = significant(pair.into_inner()).peekable();
        let is_const = parts.next_if(|p| p.as_rule() == Rule::kw_const).is_some();
        let name = self.ident(parts.next().expect("grammar: param name"));
        let ty = self.type_expr(parts.next().expect("grammar: param type"));
        let default = parts.next().map(|value| self.expr(value).node);
        FnParam { is_const, name, ty, default, span }
    }

    fn graph_def(&self, pair: Pair) -> GraphDef {
        let span = self.span(&pair);
        let mut parts = significant(pair.into_inner());
        let name = self.ident(parts.next().expect("grammar: graph name"));
        let members = parts.filter(|p| p.as_rule() != Rule::semi).map(|m| self.member(m)).collect();
        GraphDef { doc: self.doc_before(span.start), name, members, span }
    }

    fn member(&self, pair: Pair) -> GraphMember {
        let span = self.span(&pair);
        let rule = pair.as_rule();
        if rule == Rule::graph_const {
            return GraphMember::Const(self.const_def(pair));
        }
        if rule == Rule::param {
            return GraphMember::Param(self.param(pair));
        }
        // `let` is the synonym of `node`; the keyword itself means nothing more.
        let mut parts = significant(pair.into_inner()).filter(|p| p.as_rule() != Rule::kw_let);
        match rule {
            Rule::category => GraphMember::Category(self.ident(parts.next().expect("grammar: category")), span),
            Rule::description => {
                let string = parts.next().expect("grammar: description text");
                GraphMember::Description(self.string_literal(&string), span)
            }
            Rule::node | Rule::output => {
                let name = self.ident(parts.next().expect("grammar: member name"));
                let value = self.expr(parts.next().expect("grammar: member value")).node;
                if rule == Rule::node {
                    GraphMember::Node { name, value, span }
                } else {
                    GraphMember::Output { name, value, span }
                }
            }
            other => unreachable!("grammar: unexpected graph member {other:?}"),
        }
    }

    /// `param name = default [in [lo, hi] [int]]`.
    fn param(&self, pair: Pair) -> ParamDef {
        let span = self.span(&pair);
        let mut parts = significant(pair.into_inner());
        let name = self.ident(parts.next().expect("grammar: param name"));
        let default = self.expr(parts.next().expect("grammar: param default")).node;
        let mut range = None;
        let mut is_int = false;
        for part in parts {
            match part.as_rule() {
                Rule::range => {
                    let range_span = self.span(&part);
                    let mut bounds = part.into_inner().filter(|p| p.as_rule() == Rule::expr);
                    let lo = self.expr(bounds.next().expect("grammar: range low")).node;
                    let hi = self.expr(bounds.next().expect("grammar: range high")).node;
                    range = Some((lo, hi, range_span));
                }
                Rule::kw_int => is_int = true,
                other => unreachable!("grammar: unexpected part of param {other:?}"),
            }
        }
        ParamDef { doc: self.doc_before(span.start), name, default, range, is_int, span }
    }

    /// The text of a string literal, escapes resolved: `\"`, `\\`, `\n`, `\t`.
    fn string_literal(&self, pair: &Pair) -> String {
        let raw = pair.as_str();
        let inner = &raw[1..raw.len() - 1];
        let mut text = String::with_capacity(inner.len());
        let mut chars = inner.char_indices();
        while let Some((i, c)) = chars.next() {
            if c != '\\' {
                text.push(c);
                continue;
            }
            match chars.next() {
                Some((_, '"')) => text.push('"'),
                Some((_, '\\')) => text.push('\\'),
                Some((_, 'n')) => text.push('\n'),
                Some((_, 't')) => text.push('\t'),
                other => {
                    let start = self.span(pair).start + 1 + i;
                    let end = start + 1 + other.map_or(0, |(_, c)| c.len_utf8());
                    self.error_with_hint(
                        format!("unknown escape `{}`", &self.src[start..end]),
                        Span::new(start, end),
                        "the escapes are `\\\"`, `\\\\`, `\\n` and `\\t`",
                    );
                }
            }
        }
        text
    }

    /// The `///` lines directly above `start` (only blank space between them),
    /// joined with '\n', each without its `///` and one following space.
    fn doc_before(&self, start: usize) -> Option<String> {
        let mut lines = Vec::new();
        let mut end = start;
        loop {
            let before = self.src[..end].trim_end_matches([' ', '\t', '\r', '\n']);
            let Ok(index) = self.doc_lines.binary_search_by_key(&before.len(), |doc| doc.end) else {
                break;
            };
            let doc = self.doc_lines[index];
            let text = &self.src[doc.start + 3..doc.end];
            let text = text.strip_prefix(' ').unwrap_or(text);
            lines.push(text.trim_end_matches('\r'));
            end = doc.start;
        }
        if lines.is_empty() {
            return None;
        }
        lines.reverse();
        Some(lines.join("\n"))
    }
}
