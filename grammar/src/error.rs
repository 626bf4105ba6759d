//! The one error type of the parser, and where a byte offset is as line and column.

use crate::ast::Span;
use std::fmt;

/// A syntax error: what is wrong, where, and (when we can tell) how to fix it.
///
/// `span` always lies within the parsed text and on `char` boundaries; it is empty only
/// for "found end of file" errors, where it sits at the very end of the text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    pub message: String,
    pub span: Span,
    pub hint: Option<String>,
}

impl ParseError {
    pub fn new(message: impl Into<String>, span: Span) -> Self {
        ParseError { message: message.into(), span, hint: None }
    }

    pub fn with_hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }

    /// 1-based line and column (in chars) of the start of the span in `src`.
    pub fn line_col(&self, src: &str) -> (usize, usize) {
        line_col(src, self.span.start)
    }
}

/// 1-based line and column (counted in chars) of byte offset `at` in `src`: the one copy every
/// crate uses (the compiler's diagnostics and the CLI's JSON output included). An offset past
/// the end or inside a character counts as the character boundary before it.
pub fn line_col(src: &str, at: usize) -> (usize, usize) {
    let before = &src[..src.floor_char_boundary(at)];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let col = before[line_start..].chars().count() + 1;
    (line, col)
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.message)?;
        if let Some(hint) = &self.hint {
            write!(f, " (hint: {hint})")?;
        }
        Ok(())
    }
}

impl std::error::Error for ParseError {}

#[cfg(test)]
mod tests {
    use super::line_col;

    #[test]
    fn line_col_counts_chars_and_clamps() {
        let src = "ab\né x\n";
        assert_eq!(line_col(src, 0), (1, 1));
        assert_eq!(line_col(src, 3), (2, 1));
        // `x` is byte 6 but the third char of line 2 (é is two bytes).
        assert_eq!(line_col(src, 6), (2, 3));
        // Inside `é`: the boundary before it.
        assert_eq!(line_col(src, 4), (2, 1));
        // Past the end: the end.
        assert_eq!(line_col(src, 99), (3, 1));
    }
}
