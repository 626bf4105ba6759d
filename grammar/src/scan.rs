//! A lexical pre-pass over the source, run before pest.
//!
//! pest is a recursive-descent parser: it is only safe on input whose nesting is
//! bounded, and its messages for lexical problems (a comment or string that never
//! ends, a stray bracket) point at the end of the file rather than at the cause.
//! This pass walks the text once, iteratively, and:
//! - rejects control characters, unterminated block comments and strings, nesting
//!   deeper than [`MAX_NESTING`], and unbalanced brackets, with precise spans;
//! - collects the `///` doc comments (attached to items later);
//! - collects the places where a top-level item starts, used to resume parsing after
//!   a syntax error so that errors in several items are reported in one run.

use crate::ast::Span;
use crate::error::{line_col, ParseError};

/// The deepest bracket nesting (`(`, `[`, `{` together) that is accepted.
pub const MAX_NESTING: usize = 128;

/// Past this many lexical errors the rest is probably not source text at all.
const MAX_SCAN_ERRORS: usize = 20;

const ITEM_KEYWORDS: [&str; 4] = ["import", "const", "fn", "graph"];

pub(crate) struct Scan {
    pub errors: Vec<ParseError>,
    /// Each `///` comment, from the first `/` to the end of its line (newline excluded).
    pub doc_lines: Vec<Span>,
    /// Offsets of item keywords that are the first token of their line, outside any
    /// bracket: safe places to restart the parser.
    pub item_starts: Vec<usize>,
}

struct Scanner<'s> {
    src: &'s str,
    pos: usize,
    /// Open brackets: the byte and its offset.
    open: Vec<(u8, usize)>,
    /// Nothing but whitespace or comments since the last newline.
    at_line_start: bool,
    /// A bracket error was reported and the brackets have not balanced since: more
    /// complaints would most likely be consequences of the first.
    brackets_confused: bool,
    out: Scan,
}

pub(crate) fn scan(src: &str) -> Scan {
    let mut scanner = Scanner {
        src,
        pos: 0,
        open: Vec::new(),
        at_line_start: true,
        brackets_confused: false,
        out: Scan { errors: Vec::new(), doc_lines: Vec::new(), item_starts: Vec::new() },
    };
    scanner.run();
    scanner.out
}

impl Scanner<'_> {
    fn run(&mut self) {
        while let Some(c) = self.peek_char() {
            if self.out.errors.len() >= MAX_SCAN_ERRORS {
                return;
            }
            let start = self.pos;
            match c {
                '\n' => {
                    self.at_line_start = true;
                    self.pos += 1;
                }
                ' ' | '\t' | '\r' | '\u{FEFF}' => self.pos += c.len_utf8(),
                '/' if self.rest().starts_with("//") => self.line_comment(),
                '/' if self.rest().starts_with("/*") => {
                    if !self.block_comment() {
                        return; // everything after an unterminated comment is comment
                    }
                }
                '"' => {
                    self.at_line_start = false;
                    self.string();
                }
                '(' | '[' | '{' => {
                    self.at_line_start = false;
                    self.open.push((c as u8, start));
                    self.pos += 1;
                    if self.open.len() > MAX_NESTING {
                        self.error(
                            format!("nesting too deep: more than {MAX_NESTING} levels of brackets"),
                            Span::new(start, start + 1),
                            Some("split the expression into `let` bindings or functions"),
                        );
                        return; // the rest would only repeat the same complaint
                    }
                }
                ')' | ']' | '}' => {
                    self.at_line_start = false;
                    self.close_bracket(c as u8);
                    self.pos += 1;
                }
                _ if is_forbidden_control(c) => {
                    self.control_error(start, c);
                    self.pos += c.len_utf8();
                }
                _ => {
                    if self.at_line_start && self.open.is_empty() && starts_item_keyword(self.rest()) {
                        self.out.item_starts.push(start);
                    }
                    self.at_line_start = false;
                    self.pos += c.len_utf8();
                }
            }
        }
        self.report_unclosed();
    }

    fn rest(&self) -> &str {
        &self.src[self.pos..]
    }

    fn peek_char(&self) -> Option<char> {
        self.rest().chars().next()
    }

    fn error(&mut self, message: String, span: Span, hint: Option<&str>) {
        if self.out.errors.len() < MAX_SCAN_ERRORS {
            let mut error = ParseError::new(message, span);
            error.hint = hint.map(str::to_owned);
            self.out.errors.push(error);
        }
    }

    fn control_error(&mut self, at: usize, c: char) {
        let message = format!("control character U+{:04X} is not allowed in source text", c as u32);
        self.error(message, Span::new(at, at + c.len_utf8()), None);
    }

    /// Reports the control characters in `src[start..end]` (the inside of a comment or
    /// string: those are skipped as a whole, but must be clean text too).
    fn check_controls(&mut self, start: usize, end: usize) {
        for (offset, c) in self.src[start..end].char_indices() {
            if is_forbidden_control(c) {
                self.control_error(start + offset, c);
            }
        }
    }

    fn line_comment(&mut self) {
        let start = self.pos;
        let end = self.rest().find('\n').map_or(self.src.len(), |i| start + i);
        let text = &self.src[start..end];
        // `////…` is a plain comment, as in Rust; a `///` after code on the same line
        // documents nothing.
        if self.at_line_start && text.starts_with("///") && !text.starts_with("////") {
            // Trailing blanks are trimmed so that the AST builder can find the line by
            // its end, walking back over blank space from an item.
            self.out.doc_lines.push(Span::new(start, start + text.trim_end_matches([' ', '\t', '\r']).len()));
        }
        self.check_controls(start, end);
        self.pos = end;
    }

    /// Skips a `/* … */` comment; false when it never ends.
    fn block_comment(&mut self) -> bool {
        let start = self.pos;
        match self.src[start + 2..].find("*/") {
            Some(i) => {
                let end = start + 2 + i + 2;
                self.check_controls(start, end);
                self.pos = end;
                true
            }
            None => {
                self.check_controls(start, self.src.len());
                self.error(
                    "unterminated block comment".to_owned(),
                    Span::new(start, start + 2),
                    Some("a block comment ends with `*/`; block comments do not nest"),
                );
                self.pos = self.src.len();
                false
            }
        }
    }

    /// Skips a string literal; strings may not span lines.
    fn string(&mut self) {
        let start = self.pos;
        let mut chars = self.src[start + 1..].char_indices();
        while let Some((i, c)) = chars.next() {
            let at = start + 1 + i;
            match c {
                '"' => {
                    self.check_controls(start, at);
                    self.pos = at + 1;
                    return;
                }
                '\n' => break,
                '\\' => {
                    // An escaped quote does not end the string; an escaped newline
                    // does not continue it.
                    if let Some((_, '"' | '\\')) = chars.clone().next() {
                        chars.next();
                    }
                }
                _ => {}
            }
        }
        let end = self.rest().find('\n').map_or(self.src.len(), |i| start + i);
        self.check_controls(start, end);
        self.error(
            "unterminated string".to_owned(),
            Span::new(start, end),
            Some("a string ends with `\"` on the same line"),
        );
        self.pos = end;
    }

    fn close_bracket(&mut self, close: u8) {
        let at = self.pos;
        let name = close as char;
        match self.open.last() {
            Some(&(open, _)) if matching_close(open) == close => {
                self.open.pop();
                if self.open.is_empty() {
                    self.brackets_confused = false;
                }
            }
            _ if self.brackets_confused => {
                // Keep the stack roughly in step, without reporting.
                if let Some(depth) = self.open.iter().rposition(|&(o, _)| matching_close(o) == close) {
                    self.open.truncate(depth);
                }
                self.brackets_confused = !self.open.is_empty();
            }
            Some(&(open, open_at)) => {
                let (line, col) = line_col(self.src, open_at);
                let hint = format!(
                    "the `{}` opened at {line}:{col} is still open; close it with `{}` first",
                    open as char,
                    matching_close(open) as char
                );
                self.error(format!("mismatched `{name}`"), Span::new(at, at + 1), Some(&hint));
                // If an outer bracket matches, the inner ones were left unclosed: resume
                // there. Otherwise the closer is stray.
                if let Some(depth) = self.open.iter().rposition(|&(o, _)| matching_close(o) == close) {
                    self.open.truncate(depth);
                }
                self.brackets_confused = !self.open.is_empty();
            }
            None => {
                let hint = format!("there is no open `{}` for it to close", matching_open(close) as char);
                self.error(format!("unmatched `{name}`"), Span::new(at, at + 1), Some(&hint));
            }
        }
    }

    fn report_unclosed(&mut self) {
        if self.brackets_confused {
            return;
        }
        for (open, at) in std::mem::take(&mut self.open) {
            let hint = format!("no matching `{}` before the end of the file", matching_close(open) as char);
            self.error(format!("unclosed `{}`", open as char), Span::new(at, at + 1), Some(&hint));
        }
    }
}

/// Control characters other than tab, newline and carriage return (C0, DEL, C1).
fn is_forbidden_control(c: char) -> bool {
    c.is_control() && !matches!(c, '\t' | '\n' | '\r')
}

fn starts_item_keyword(text: &str) -> bool {
    ITEM_KEYWORDS.iter().any(|keyword| {
        text.starts_with(keyword)
            && !text[keyword.len()..].chars().next().is_some_and(|c| c.is_ascii_alphanumeric() || c == '_')
    })
}

fn matching_close(open: u8) -> u8 {
    match open {
        b'(' => b')',
        b'[' => b']',
        _ => b'}',
    }
}

fn matching_open(close: u8) -> u8 {
    match close {
        b')' => b'(',
        b']' => b'[',
        _ => b'{',
    }
}
