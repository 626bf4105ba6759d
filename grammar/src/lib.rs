//! `psc-grammar`: the front door of photoscene — `.psg` source text in, an AST out.
//!
//! This crate owns the text → AST step: the pest grammar (`psg.pest`), the lexical
//! checks that keep pest safe on any input (nesting depth, control characters,
//! unterminated comments and strings), the lowering of pest's pairs into [`ast`]
//! nodes with byte [`ast::Span`]s into the given text, and syntax errors with
//! helpful messages and precise spans.
//!
//! It must never: resolve names or imports, check types or evaluate anything (the
//! compiler's checker does), read files (callers pass text), or print (errors are
//! returned as values; rendering them is the CLI's job). It must never panic, hang or
//! overflow the stack, whatever the input.

pub mod ast;
mod error;
mod lower;
mod lower_expr;
mod parser;
mod scan;
mod syntax;

pub use error::{line_col, ParseError};
pub use lower_expr::MAX_EXPR_DEPTH;
pub use parser::parse;
pub use scan::MAX_NESTING;
