//! Rendering diagnostics on very long source lines: a window around the span instead of the
//! whole line.
//!
//! codespan-reporting prints every labelled line in full, so an error on a 200 KB line (a
//! minified or generated file, or hostile input) would echo 200 KB. When a labelled line is
//! longer than [`MAX_SHOWN_LINE`] bytes, the diagnostic is rendered against an [`Excerpt`]
//! instead of the sources: a small text holding only the lines the renderer will show (each
//! label's lines and one on either side), with every long one cut to a window around the
//! labels on it, marked by an ellipsis where it was cut. Line numbers are the real ones, and
//! so is the column in the `file:line:col` header. Diagnostics on ordinary lines never come
//! here, so their rendering is exactly codespan's.

use std::collections::{BTreeMap, HashMap};
use std::ops::Range;

use codespan_reporting::diagnostic::Diagnostic as CsDiagnostic;
use codespan_reporting::files::{Error, Files};

use super::SourceMap;

/// Longest source line (in bytes) shown whole; longer lines show a window of this size.
pub const MAX_SHOWN_LINE: usize = 160;
/// Bytes shown before the first label point on a cut line.
const SHOWN_BEFORE: usize = 48;
const ELLIPSIS: &str = "…";

/// One shown line of an excerpt.
struct Line {
    /// Where the line's text is in the excerpt (trailing newline included).
    view: Range<usize>,
    /// The original bytes shown (a window of the line, without its newline).
    window: Range<usize>,
    /// Bytes of the ellipsis in front (0 when the window starts the line).
    prefix: usize,
    /// Start of the original line, for real columns.
    line_start: usize,
}

/// The shown lines of one file, keyed by their real line index.
struct FileExcerpt {
    text: String,
    lines: BTreeMap<usize, Line>,
    /// `(view start, real line index)` of every shown line, in order, for lookups by offset.
    starts: Vec<(usize, usize)>,
}

/// The texts a diagnostic is rendered against when it touches a long line (see the module docs).
pub(super) struct Excerpt<'a> {
    sources: &'a SourceMap,
    files: HashMap<usize, FileExcerpt>,
}

impl<'a> Excerpt<'a> {
    /// An excerpt for `diagnostic` (its labels already clamped to their texts), and the
    /// diagnostic with its labels moved into the excerpt; `None` when no labelled line is long.
    pub(super) fn build(
        sources: &'a SourceMap,
        diagnostic: &CsDiagnostic<usize>,
    ) -> Option<(Excerpt<'a>, CsDiagnostic<usize>)> {
        let files = &sources.files;
        // The lines each file shows, with the label points on each.
        let mut wanted: BTreeMap<usize, BTreeMap<usize, Vec<usize>>> = BTreeMap::new();
        let mut any_long = false;
        for label in &diagnostic.labels {
            let (first, last) = (
                files.line_index(label.file_id, label.range.start).ok()?,
                files.line_index(label.file_id, label.range.end).ok()?,
            );
            let shown = wanted.entry(label.file_id).or_default();
            // The label's lines and one on either side: the renderer shows a single line
            // between two labelled ones instead of a break.
            for line in first.saturating_sub(1)..=last + 1 {
                let Ok(range) = files.line_range(label.file_id, line) else { continue };
                any_long |= range.len() > MAX_SHOWN_LINE;
                shown.entry(line).or_default();
            }
            shown.entry(first).or_default().push(label.range.start);
            shown.entry(last).or_default().push(label.range.end);
        }
        if !any_long {
            return None;
        }
        let mut excerpt = Excerpt { sources, files: HashMap::new() };
        for (&file, lines) in &wanted {
            let source = sources.text(super::FileId(file));
            let mut text = String::new();
            let mut shown = BTreeMap::new();
            for (&index, points) in lines {
                let range = files.line_range(file, index).ok()?;
                let body = trim_newline(source, range.clone());
                let window = window(source, body.clone(), points);
                let start = text.len();
                let prefix = if window.start > body.start { ELLIPSIS.len() } else { 0 };
                if prefix > 0 {
                    text.push_str(ELLIPSIS);
                }
                text.push_str(&source[window.clone()]);
                if window.end < body.end {
                    text.push_str(ELLIPSIS);
                }
                text.push('\n');
                shown.insert(index, Line { view: start..text.len(), window, prefix, line_start: body.start });
            }
            let starts = shown.iter().map(|(&index, line): (&usize, &Line)| (line.view.start, index)).collect();
            excerpt.files.insert(file, FileExcerpt { text, lines: shown, starts });
        }
        let mut moved = diagnostic.clone();
        for label in &mut moved.labels {
            let f = &excerpt.files[&label.file_id];
            let start = f.to_view(files.line_index(label.file_id, label.range.start).ok()?, label.range.start, false);
            let end = f.to_view(files.line_index(label.file_id, label.range.end).ok()?, label.range.end, true);
            label.range = start..end.max(start);
        }
        Some((excerpt, moved))
    }
}

impl FileExcerpt {
    /// Where original byte `at` of line `index` is in the excerpt. A point cut off on the left
    /// goes to the ellipsis there; on the right, to the end of the ellipsis when it ends a
    /// label (`is_end`, so the caret runs on under it), else to its start.
    fn to_view(&self, index: usize, at: usize, is_end: bool) -> usize {
        let line = &self.lines[&index];
        let text_start = line.view.start + line.prefix;
        if at < line.window.start {
            return line.view.start;
        }
        if at > line.window.end {
            let after = line.view.end - 1; // before the newline: after the right ellipsis
            return if is_end { after } else { text_start + line.window.len() };
        }
        text_start + (at - line.window.start)
    }

    /// The real index of the shown line holding excerpt offset `at` (the last line for the end).
    fn line_of(&self, at: usize) -> Option<usize> {
        let k = self.starts.partition_point(|&(start, _)| start <= at);
        self.starts.get(k.checked_sub(1)?).map(|&(_, index)| index)
    }
}

/// The line's range without its line ending.
fn trim_newline(source: &str, range: Range<usize>) -> Range<usize> {
    let line = &source[range.clone()];
    let body = line.trim_end_matches(['\n', '\r']);
    range.start..range.start + body.len()
}

/// The part of `body` to show: all of it when short, else [`MAX_SHOWN_LINE`] bytes starting a
/// little before the first label point on it.
fn window(source: &str, body: Range<usize>, points: &[usize]) -> Range<usize> {
    if body.len() <= MAX_SHOWN_LINE {
        return body;
    }
    let first = points.iter().copied().filter(|p| body.contains(p) || *p == body.end).min().unwrap_or(body.start);
    let start = source.floor_char_boundary(first.saturating_sub(SHOWN_BEFORE).max(body.start));
    let end = source.floor_char_boundary((start + MAX_SHOWN_LINE).min(body.end));
    start..end.max(start)
}

impl<'a> Files<'a> for Excerpt<'_> {
    type FileId = usize;
    type Name = &'a str;
    type Source = &'a str;

    fn name(&'a self, id: usize) -> Result<&'a str, Error> {
        Ok(self.sources.name(super::FileId(id)))
    }

    fn source(&'a self, id: usize) -> Result<&'a str, Error> {
        self.files.get(&id).map(|f| f.text.as_str()).ok_or(Error::FileMissing)
    }

    fn line_index(&'a self, id: usize, byte_index: usize) -> Result<usize, Error> {
        let f = self.files.get(&id).ok_or(Error::FileMissing)?;
        f.line_of(byte_index).ok_or(Error::IndexTooLarge { given: byte_index, max: f.text.len() })
    }

    fn line_range(&'a self, id: usize, line_index: usize) -> Result<Range<usize>, Error> {
        let f = self.files.get(&id).ok_or(Error::FileMissing)?;
        let max = f.lines.keys().next_back().copied().unwrap_or(0);
        f.lines.get(&line_index).map(|l| l.view.clone()).ok_or(Error::LineTooLarge { given: line_index, max })
    }

    /// The real column: characters from the start of the original line.
    fn column_number(&'a self, id: usize, line_index: usize, byte_index: usize) -> Result<usize, Error> {
        let f = self.files.get(&id).ok_or(Error::FileMissing)?;
        let line = f.lines.get(&line_index).ok_or(Error::LineTooLarge { given: line_index, max: 0 })?;
        let offset = byte_index.saturating_sub(line.view.start + line.prefix).min(line.window.len());
        let original = line.window.start + offset;
        let source = self.sources.text(super::FileId(id));
        Ok(source[line.line_start..original].chars().count() + 1)
    }
}

/// Shortens `text` to at most `max` bytes (on a char boundary) with an ellipsis, for messages
/// that quote source (a 200 KB identifier in "unknown name `…`").
pub(super) fn shorten(text: &str, max: usize) -> std::borrow::Cow<'_, str> {
    if text.len() <= max {
        return text.into();
    }
    let cut = text.floor_char_boundary(max);
    format!("{}{ELLIPSIS}", &text[..cut]).into()
}

#[cfg(test)]
mod tests {
    use super::MAX_SHOWN_LINE;
    use crate::diag::{Diagnostic, SourceMap};
    use psc_grammar::ast::Span;

    /// Caret line under the first line containing `needle`: the carets' columns, in chars.
    fn caret_columns(text: &str, needle: &str) -> (usize, std::ops::Range<usize>) {
        let lines: Vec<&str> = text.lines().collect();
        let at = lines.iter().position(|l| l.contains(needle)).unwrap_or_else(|| panic!("no `{needle}` in\n{text}"));
        let source_col = lines[at].chars().collect::<String>().find(needle).unwrap();
        let carets = lines[at + 1];
        let first = carets.chars().position(|c| c == '^').expect("carets");
        let len = carets.chars().filter(|&c| c == '^').count();
        (lines[at][..source_col].chars().count(), first..first + len)
    }

    #[test]
    fn a_span_deep_in_a_200_kb_line_shows_a_window_with_real_line_and_column() {
        let mut sources = SourceMap::new();
        let line = format!("    output albedo = vec3({}fmb(uv){})", " ".repeat(200_000), " ".repeat(5_000));
        let text = format!("graph g {{\n{line}\n    output roughness = 0.5\n}}\n");
        let at = text.find("fmb").unwrap();
        let f = sources.add("long.psg", text.as_str());
        let d = Diagnostic::error(f, Span::new(at, at + 3), "unknown function `fmb`").with_label("here");
        let out = d.render(&sources);
        assert!(out.len() < 2 * MAX_SHOWN_LINE + 400, "{} bytes:\n{out}", out.len());
        let col = line.find("fmb").unwrap() + 1;
        assert!(out.contains(&format!("long.psg:2:{col}")), "{out}");
        assert_eq!(out.matches('…').count(), 2, "cut on both sides:\n{out}");
        // The carets sit under `fmb` in the window.
        let (name_col, carets) = caret_columns(&out, "fmb(uv)");
        assert_eq!(carets, name_col..name_col + 3, "{out}");
        // The neighbouring short lines are shown as they are.
        assert!(!out.contains("output roughness") || out.contains("    output roughness = 0.5"), "{out}");
    }

    #[test]
    fn a_span_near_the_start_of_a_long_line_is_cut_only_on_the_right() {
        let mut sources = SourceMap::new();
        let text = format!("bad{}\n", " x".repeat(100_000));
        let f = sources.add("a.psg", text.as_str());
        let out = Diagnostic::error(f, Span::new(0, 3), "what").render(&sources);
        assert!(out.contains("a.psg:1:1"), "{out}");
        assert_eq!(out.matches('…').count(), 1, "{out}");
        assert!(out.len() < 2 * MAX_SHOWN_LINE + 300, "{out}");
        // A span running to the end of the line ends under the ellipsis.
        let out = Diagnostic::error(f, Span::new(0, text.len() - 1), "all of it").render(&sources);
        assert!(out.len() < 3 * MAX_SHOWN_LINE + 300, "{} bytes:\n{out}", out.len());
        assert!(out.contains("a.psg:1:1"), "{out}");
    }

    #[test]
    fn related_labels_in_other_files_and_lines_keep_their_places() {
        let mut sources = SourceMap::new();
        let long = format!("graph dup {{ {} }}\n", "node n = 1.0 ".repeat(20_000));
        let a = sources.add("a.psg", "// first\ngraph dup { }\n");
        let b = sources.add("b.psg", format!("// second\n{long}// after\n"));
        let at = 10 + long.find("dup").unwrap();
        let d = Diagnostic::error(b, Span::new(at, at + 3), "graph `dup` is defined in two files").with_related(
            a,
            Span::new(15, 18),
            "first defined here",
        );
        let out = d.render(&sources);
        assert!(out.contains("b.psg:2:7") && out.contains("a.psg:2:7"), "{out}");
        assert!(out.contains("first defined here") && out.contains("graph dup { }"), "{out}");
        assert!(out.len() < 2_000, "{} bytes:\n{out}", out.len());
    }

    #[test]
    fn a_multi_line_span_over_long_lines_stays_small() {
        let mut sources = SourceMap::new();
        let row = "y".repeat(50_000);
        let text = format!("start {{\n{row}\n{row}\n}} end\n");
        let f = sources.add("m.psg", text.as_str());
        let out = Diagnostic::error(f, Span::new(6, text.len() - 5), "block").render(&sources);
        assert!(out.len() < 6 * MAX_SHOWN_LINE + 400, "{} bytes:\n{out}", out.len());
        assert!(out.contains("m.psg:1:7"), "{out}");
    }

    #[test]
    fn huge_names_in_messages_are_shortened() {
        let mut sources = SourceMap::new();
        let name = "n".repeat(100_000);
        let f = sources.add("a.psg", format!("x = {name}\n"));
        let d = Diagnostic::error(f, Span::new(4, 4 + name.len()), format!("unknown name `{name}`"))
            .with_hint(format!("did you mean `{name}`?"));
        let out = d.render(&sources);
        assert!(out.len() < 3_000, "{} bytes", out.len());
        assert!(out.contains("unknown name `nnnn") && out.contains('…'), "{out}");
    }

    #[test]
    fn ordinary_lines_render_exactly_as_codespan_does() {
        let mut sources = SourceMap::new();
        let f = sources.add("a.psg", "graph g {\n  output albedo = foo\n}\n");
        let d = Diagnostic::error(f, Span::new(28, 31), "unknown name `foo`");
        let diagnostic = d.clamped(&sources).to_codespan();
        assert!(super::Excerpt::build(&sources, &diagnostic).is_none());
    }
}
