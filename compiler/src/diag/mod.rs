//! Diagnostics: what went wrong, where (file, byte span), and a hint; rendered with
//! codespan-reporting as `file:line:col`, the source line, and a caret under the span. A source
//! line longer than [`MAX_SHOWN_LINE`] bytes is shown as a window around the span
//! (`excerpt.rs`), and messages quoting huge names are shortened, so no input can make a
//! diagnostic echo kilobytes.

mod excerpt;

pub use excerpt::MAX_SHOWN_LINE;

use codespan_reporting::diagnostic::{Diagnostic as CsDiagnostic, Label};
use codespan_reporting::files::SimpleFiles;
use codespan_reporting::term::{self, termcolor};

use psc_grammar::ast::Span;

/// Longest message, label or hint (in bytes) shown whole; longer ones are cut with an ellipsis.
const MAX_MESSAGE: usize = 400;

/// Index of a file in a [`SourceMap`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FileId(pub usize);

/// Every source text the compiler has read, by [`FileId`], for rendering diagnostics.
#[derive(Default)]
pub struct SourceMap {
    files: SimpleFiles<String, String>,
    names: Vec<String>,
}

impl SourceMap {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn add(&mut self, name: impl Into<String>, text: impl Into<String>) -> FileId {
        let name = name.into();
        self.names.push(name.clone());
        FileId(self.files.add(name, text.into()))
    }

    pub fn name(&self, file: FileId) -> &str {
        &self.names[file.0]
    }

    pub fn text(&self, file: FileId) -> &str {
        self.files.get(file.0).map(|f| f.source().as_str()).unwrap_or("")
    }

    /// 1-based line and column (in characters) of a byte offset ([`psc_grammar::line_col`]).
    pub fn line_col(&self, file: FileId, offset: usize) -> (usize, usize) {
        psc_grammar::line_col(self.text(file), offset)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Severity {
    Warning,
    Error,
}

/// One finding about a source file.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostic {
    pub severity: Severity,
    pub message: String,
    pub file: FileId,
    pub span: Span,
    /// Short text shown under the caret.
    pub label: String,
    /// "did you mean `fbm`?" and the like.
    pub hint: Option<String>,
    /// Secondary places: "first defined here".
    pub related: Vec<(FileId, Span, String)>,
}

impl Diagnostic {
    pub fn error(file: FileId, span: Span, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: Severity::Error,
            message: message.into(),
            file,
            span,
            label: String::new(),
            hint: None,
            related: Vec::new(),
        }
    }

    pub fn warning(file: FileId, span: Span, message: impl Into<String>) -> Self {
        Diagnostic { severity: Severity::Warning, ..Diagnostic::error(file, span, message) }
    }

    pub fn with_label(mut self, label: impl Into<String>) -> Self {
        self.label = label.into();
        self
    }

    pub fn with_hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }

    pub fn with_hint_opt(mut self, hint: Option<String>) -> Self {
        self.hint = hint.or(self.hint);
        self
    }

    pub fn with_related(mut self, file: FileId, span: Span, note: impl Into<String>) -> Self {
        self.related.push((file, span, note.into()));
        self
    }

    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }

    fn to_codespan(&self) -> CsDiagnostic<usize> {
        let base = match self.severity {
            Severity::Error => CsDiagnostic::error(),
            Severity::Warning => CsDiagnostic::warning(),
        };
        let short = |text: &str| excerpt::shorten(text, MAX_MESSAGE).into_owned();
        let mut labels =
            vec![Label::primary(self.file.0, self.span.start..self.span.end).with_message(short(&self.label))];
        for (file, span, note) in &self.related {
            labels.push(Label::secondary(file.0, span.start..span.end).with_message(short(note)));
        }
        let notes = self.hint.iter().map(|h| format!("hint: {}", short(h))).collect();
        base.with_message(short(&self.message)).with_labels(labels).with_notes(notes)
    }

    /// Plain text, as in golden tests and when stderr is not a terminal.
    pub fn render(&self, sources: &SourceMap) -> String {
        let config = term::Config::default();
        let diagnostic = self.clamped(sources).to_codespan();
        let rendered = match excerpt::Excerpt::build(sources, &diagnostic) {
            Some((excerpt, moved)) => term::emit_into_string(&config, &excerpt, &moved),
            None => term::emit_into_string(&config, &sources.files, &diagnostic),
        };
        rendered.unwrap_or_else(|_| format!("error: {}\n", excerpt::shorten(&self.message, MAX_MESSAGE)))
    }

    /// Coloured, for a terminal.
    pub fn emit_colored(&self, sources: &SourceMap, out: &mut dyn termcolor::WriteColor) {
        let config = term::Config::default();
        let diagnostic = self.clamped(sources).to_codespan();
        let written = match excerpt::Excerpt::build(sources, &diagnostic) {
            Some((excerpt, moved)) => term::emit_to_write_style(out, &config, &excerpt, &moved),
            None => term::emit_to_write_style(out, &config, &sources.files, &diagnostic),
        };
        if written.is_err() {
            let message = excerpt::shorten(&self.message, MAX_MESSAGE);
            let _ = std::io::Write::write_fmt(out, format_args!("error: {message}\n"));
        }
    }

    /// Spans clamped to the text and to char boundaries, so rendering can never fail.
    fn clamped(&self, sources: &SourceMap) -> Diagnostic {
        let clamp = |file: FileId, span: Span| {
            let text = sources.text(file);
            let start = text.floor_char_boundary(span.start);
            let end = text.floor_char_boundary(span.end).max(start);
            Span::new(start, end)
        };
        let mut d = self.clone();
        d.span = clamp(d.file, d.span);
        for r in &mut d.related {
            r.1 = clamp(r.0, r.1);
        }
        d
    }
}

/// Best-effort "did you mean" among `candidates` (Levenshtein distance ≤ 1/3 of the length).
pub fn did_you_mean<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<String> {
    let limit = (name.chars().count() / 3).max(1);
    candidates
        .into_iter()
        .filter(|c| *c != name)
        .map(|c| (edit_distance(name, c), c))
        .filter(|(d, _)| *d <= limit)
        .min_by(|a, b| a.0.cmp(&b.0).then_with(|| a.1.cmp(b.1)))
        .map(|(_, c)| format!("did you mean `{c}`?"))
}

/// Optimal-string-alignment distance: Levenshtein plus adjacent transpositions, so that the
/// most common typo (`fmb` for `fbm`) costs one edit.
fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut d = vec![vec![0usize; b.len() + 1]; a.len() + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, cell) in d[0].iter_mut().enumerate() {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            d[i][j] = (d[i - 1][j] + 1).min(d[i][j - 1] + 1).min(d[i - 1][j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                d[i][j] = d[i][j].min(d[i - 2][j - 2] + 1);
            }
        }
    }
    d[a.len()][b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggestions_prefer_the_closest_name() {
        assert_eq!(did_you_mean("fmb", ["fbm", "noise", "cells"]), Some("did you mean `fbm`?".into()));
        assert_eq!(did_you_mean("zzzzzz", ["fbm", "noise"]), None);
    }

    #[test]
    fn rendering_shows_position_and_caret() {
        let mut sources = SourceMap::new();
        let f = sources.add("a.psg", "graph g {\n  output albedo = foo\n}\n");
        let d = Diagnostic::error(f, Span::new(28, 31), "unknown name `foo`").with_hint("did you mean `fbm`?");
        let text = d.render(&sources);
        assert!(text.contains("a.psg:2:19"), "{text}");
        assert!(text.contains("^^^"), "{text}");
        assert!(text.contains("hint: did you mean `fbm`?"), "{text}");
        assert_eq!(sources.line_col(f, 28), (2, 19));
    }

    #[test]
    fn out_of_range_spans_do_not_break_rendering() {
        let mut sources = SourceMap::new();
        let f = sources.add("a.psg", "é");
        let d = Diagnostic::error(f, Span::new(1, 99), "x");
        assert!(d.render(&sources).contains("error: x"));
    }
}
