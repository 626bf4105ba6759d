//! `psc-grammar`: the front door of photoscene — `.psg` source text in, an AST out.
//!
//! This crate owns the text → AST step: the pest grammar (`psg.pest`), the lexical
//! checks that keep pest safe on any input (nesting depth, control characters,
//! unterminated comments and strings), building the [`ast`] from pest's pairs
//! (`ast_build`, with byte [`ast::Span`]s into the given text), and syntax errors with
//! helpful messages and precise spans.
//!
//! It must never: resolve names or imports, check types or evaluate anything (the
//! compiler's checker does), read files (callers pass text), or print (errors are
//! returned as values; rendering them is the CLI's job). It must never panic, hang or
//! overflow the stack, whatever the input.

#![forbid(unsafe_code)]

pub mod ast;
mod ast_build;
mod error;
mod parser;
mod scan;
mod syntax;

pub use ast_build::MAX_EXPR_DEPTH;
pub use error::{line_col, ParseError};
pub use parser::parse;
pub use scan::MAX_NESTING;
