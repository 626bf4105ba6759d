//! The entry point: source text in, [`File`] or every error we can find out.

use crate::ast::File;
use crate::ast_build::AstBuilder;
use crate::error::ParseError;
use crate::scan::scan;
use crate::syntax::{translate, PsgParser, Rule};
use pest::Parser;

/// Past this many errors the rest are most likely consequences of the first ones.
const MAX_ERRORS: usize = 25;

/// Parses a whole `.psg` file.
///
/// On failure, returns every error found (at least one, in source order within each
/// pass): lexical problems first (they stop the parse: brackets and comments must be
/// sound before the structure can be trusted), otherwise one syntax error per broken
/// item — after a syntax error, parsing resumes at the next line that starts a
/// top-level item — plus the problems found while building the AST (literal ranges,
/// argument order, string escapes, expression depth).
pub fn parse(src: &str) -> Result<File, Vec<ParseError>> {
    let scanned = scan(src);
    if !scanned.errors.is_empty() {
        return Err(scanned.errors);
    }
    let mut items = Vec::new();
    let mut errors = Vec::new();
    let mut chunk_start = 0;
    while errors.len() < MAX_ERRORS {
        let chunk = &src[chunk_start..];
        match PsgParser::parse(Rule::file, chunk) {
            Ok(mut pairs) => {
                let builder = AstBuilder::new(src, chunk_start, &scanned.doc_lines);
                let file = pairs.next().expect("pest: `file` yields one pair");
                items.extend(builder.file(file));
                errors.extend(builder.into_errors());
                break;
            }
            Err(error) => {
                let error = translate(error, chunk, chunk_start);
                let failed_at = error.span.start;
                errors.push(error);
                // Resume at the next item that starts at or after the failure (an
                // item cut short often fails right at the keyword of the next one).
                let next = scanned.item_starts.iter().find(|&&s| s >= failed_at && s > chunk_start);
                match next {
                    Some(&next) => chunk_start = next,
                    None => break,
                }
            }
        }
    }
    if errors.is_empty() {
        Ok(File { items })
    } else {
        errors.truncate(MAX_ERRORS);
        Err(errors)
    }
}
