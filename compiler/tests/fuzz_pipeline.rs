//! Whole-pipeline fuzzing: hostile text through `compile_text` (parse, imports, check, lower,
//! adjoint), from three sources:
//! (a) mutations of the real library files (slices deleted, duplicated, swapped or inserted,
//!     identifiers replaced by other identifiers of the file, numbers by extreme values, lines
//!     dropped or duplicated);
//! (b) random token soups (keywords, library names, punctuation, extreme numbers, comments),
//!     bare or wrapped in a graph;
//! (c) random bytes, bare or spliced into a library file.
//!
//! For every input: the compiler returns (no panic: an internal compiler error diagnostic is
//! how the compiler thread reports one), every diagnostic's spans lie within its file's text on
//! char boundaries, every rendered diagnostic shows `file:line:col` of its span, and when there
//! are no errors every graph's forward and adjoint programs `validate()` and evaluate.
//!
//! Inputs are compiled as `graphs/<family>/__fuzz.psg` (never written) so `import std.*`
//! resolves to the real library. `PSC_FUZZ_CASES` sets the cases per strategy (default 400).

mod support;

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use psc_compiler::diag::Diagnostic;
use psc_compiler::interp::eval_point;
use psc_compiler::{compile_text, CompileOutput, Options};
use support::*;

// ---------------------------------------------------------------------------------------------
// The oracle

/// Compiles `bytes` as a file of the library folder `family` and checks every property.
fn check_input(family: &str, bytes: &[u8]) -> Result<(), String> {
    let path = graphs_dir().join(family).join("__fuzz.psg");
    let out = compile_text(&path, bytes.to_vec(), &Options::default());
    check_output(&out)
        .map_err(|e| format!("{e}\n--- input ({} bytes) ---\n{}", bytes.len(), String::from_utf8_lossy(bytes)))
}

fn check_output(out: &CompileOutput) -> Result<(), String> {
    for d in &out.diagnostics {
        if d.message.contains("internal compiler error") {
            return Err(format!("internal compiler error: {}", d.render(&out.sources)));
        }
        check_span(out, d.file, d.span, d)?;
        for (file, span, _) in &d.related {
            check_span(out, *file, *span, d)?;
        }
        let rendered = d.render(&out.sources);
        let (line, col) = out.sources.line_col(d.file, d.span.start);
        let location = format!("{}:{line}:{col}", out.sources.name(d.file));
        if !rendered.contains(&location) {
            return Err(format!("rendered diagnostic lacks `{location}`:\n{rendered}"));
        }
    }
    if !out.has_errors() {
        if out.files.iter().any(|(_, ok)| !ok) {
            return Err("no errors, but a file is marked as failed".into());
        }
        for g in &out.graphs {
            g.forward.validate().map_err(|e| format!("graph {}: forward program invalid: {e}", g.info.name))?;
            if g.forward.outputs.len() != psc_compiler::Channel::COUNT {
                return Err(format!("graph {}: {} outputs", g.info.name, g.forward.outputs.len()));
            }
            let adjoint = g.adjoint();
            adjoint.program.validate().map_err(|e| format!("graph {}: adjoint program invalid: {e}", g.info.name))?;
            adjoint
                .layout
                .check(&g.forward, &adjoint.program)
                .map_err(|e| format!("graph {}: adjoint layout: {e}", g.info.name))?;
            let params = g.info.default_params();
            if params.len() < g.forward.num_params {
                return Err(format!(
                    "graph {}: {} parameter slots, the program reads {}",
                    g.info.name,
                    params.len(),
                    g.forward.num_params
                ));
            }
            eval_point(&g.forward, &params, 0.3, 0.7, &[]);
            eval_point(&adjoint.program, &params, 0.3, 0.7, &[1.0; 9]);
        }
    }
    Ok(())
}

fn check_span(
    out: &CompileOutput,
    file: psc_compiler::diag::FileId,
    span: psc_grammar::ast::Span,
    d: &Diagnostic,
) -> Result<(), String> {
    let text = out.sources.text(file);
    let on_boundaries =
        text.is_char_boundary(span.start.min(text.len())) && text.is_char_boundary(span.end.min(text.len()));
    if span.start > span.end || span.end > text.len() || !on_boundaries {
        return Err(format!(
            "span {}..{} of `{}` is not within its file `{}` ({} bytes) on char boundaries",
            span.start,
            span.end,
            d.message,
            out.sources.name(file),
            text.len()
        ));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Inputs

struct LibFile {
    family: String,
    text: String,
    idents: Vec<String>,
}

fn library() -> &'static [LibFile] {
    static LIB: std::sync::OnceLock<Vec<LibFile>> = std::sync::OnceLock::new();
    LIB.get_or_init(|| {
        psg_files_under(&graphs_dir())
            .into_iter()
            .map(|p| {
                let text = std::fs::read_to_string(&p).unwrap();
                let family = p.parent().unwrap().file_name().unwrap().to_string_lossy().into_owned();
                let family = if family == "graphs" { "misc".to_string() } else { family };
                let mut idents: Vec<String> = tokens(&text)
                    .into_iter()
                    .filter(|t| t.1 == Tok::Ident)
                    .map(|t| text[t.0.clone()].to_string())
                    .collect();
                idents.sort();
                idents.dedup();
                LibFile { family, text, idents }
            })
            .collect()
    })
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Tok {
    Ident,
    Number,
}

/// Byte ranges of identifiers and numeric literals (outside comments too: mutations may hit
/// comments, which is fine).
fn tokens(text: &str) -> Vec<(std::ops::Range<usize>, Tok)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c.is_ascii_alphabetic() || c == b'_' {
            let s = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            out.push((s..i, Tok::Ident));
        } else if c.is_ascii_digit() {
            let s = i;
            while i < b.len()
                && (b[i].is_ascii_digit() || b[i] == b'.' && b.get(i + 1).is_some_and(|x| x.is_ascii_digit()))
            {
                i += 1;
            }
            if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
                let mut j = i + 1;
                if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
                    j += 1;
                }
                if j < b.len() && b[j].is_ascii_digit() {
                    i = j;
                    while i < b.len() && b[i].is_ascii_digit() {
                        i += 1;
                    }
                }
            }
            out.push((s..i, Tok::Number));
        } else {
            i += 1;
        }
    }
    out
}

const EXTREME_NUMBERS: &[&str] = &[
    "1e38",
    "-1e38",
    "3.5e38",
    "1e39",
    "-0",
    "-0.0",
    "0",
    "0.0",
    "1e-45",
    "1.4e-45",
    "1e-50",
    "1e-38",
    "99999999999999999999",
    "2147483647",
    "2147483648",
    "-2147483648",
    "4294967296",
    "9223372036854775807",
    "9223372036854775808",
    "18446744073709551616",
    "1e308",
    "1e400",
    "65536",
    "100000",
    "1000000",
    "16777217",
    "0.5",
    "1",
    "2",
    "-1",
    "3",
];

/// One edit of a library file. Positions are fractions of the text (or counts), resolved when
/// applied, so that shrinking keeps them meaningful.
#[derive(Clone, Debug)]
enum Mutation {
    Delete {
        at: f64,
        len: usize,
    },
    Duplicate {
        at: f64,
        len: usize,
        to: f64,
    },
    Swap {
        a: f64,
        b: f64,
        len: usize,
    },
    /// A slice of another library file (by index) inserted here.
    Insert {
        at: f64,
        from: usize,
        from_at: f64,
        len: usize,
    },
    /// The k-th identifier occurrence replaced by the j-th identifier of the file.
    ReplaceIdent {
        k: usize,
        j: usize,
    },
    /// Every occurrence of one identifier replaced by another of the file.
    RenameAll {
        k: usize,
        j: usize,
    },
    /// The k-th numeric literal replaced by an extreme value.
    ReplaceNumber {
        k: usize,
        value: usize,
    },
    /// Every numeric literal replaced by one extreme value.
    AllNumbers {
        value: usize,
    },
    DropLine {
        k: usize,
    },
    DuplicateLine {
        k: usize,
    },
    /// A token of the soup vocabulary inserted.
    InsertToken {
        at: f64,
        tok: usize,
    },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let frac = 0.0..1.0f64;
    prop_oneof![
        (frac.clone(), 1..200usize).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (frac.clone(), 1..200usize, frac.clone()).prop_map(|(at, len, to)| Mutation::Duplicate { at, len, to }),
        (frac.clone(), frac.clone(), 1..120usize).prop_map(|(a, b, len)| Mutation::Swap { a, b, len }),
        (frac.clone(), any::<usize>(), frac.clone(), 1..300usize)
            .prop_map(|(at, from, from_at, len)| Mutation::Insert { at, from, from_at, len }),
        (any::<usize>(), any::<usize>()).prop_map(|(k, j)| Mutation::ReplaceIdent { k, j }),
        (any::<usize>(), any::<usize>()).prop_map(|(k, j)| Mutation::RenameAll { k, j }),
        (any::<usize>(), any::<usize>()).prop_map(|(k, value)| Mutation::ReplaceNumber { k, value }),
        any::<usize>().prop_map(|value| Mutation::AllNumbers { value }),
        any::<usize>().prop_map(|k| Mutation::DropLine { k }),
        any::<usize>().prop_map(|k| Mutation::DuplicateLine { k }),
        (frac, any::<usize>()).prop_map(|(at, tok)| Mutation::InsertToken { at, tok }),
    ]
}

fn pos(text: &[u8], f: f64) -> usize {
    ((text.len() as f64) * f) as usize
}

fn apply(text: &mut Vec<u8>, m: &Mutation, own_idents: &[String]) {
    let lib = library();
    let n = text.len();
    let clamp = |a: usize, len: usize| (a.min(n), (a + len).min(n));
    match *m {
        Mutation::Delete { at, len } => {
            let (a, b) = clamp(pos(text, at), len);
            text.drain(a..b);
        }
        Mutation::Duplicate { at, len, to } => {
            let (a, b) = clamp(pos(text, at), len);
            let slice = text[a..b].to_vec();
            let t = pos(text, to);
            text.splice(t..t, slice);
        }
        Mutation::Swap { a, b, len } => {
            let (mut a, mut b) = (pos(text, a), pos(text, b));
            if a > b {
                std::mem::swap(&mut a, &mut b);
            }
            let len = len.min(b - a).min(n - b);
            if len > 0 {
                let first = text[a..a + len].to_vec();
                let second = text[b..b + len].to_vec();
                text[a..a + len].copy_from_slice(&second);
                text[b..b + len].copy_from_slice(&first);
            }
        }
        Mutation::Insert { at, from, from_at, len } => {
            let src = lib[from % lib.len()].text.as_bytes();
            let s = pos(src, from_at);
            let slice = src[s..(s + len).min(src.len())].to_vec();
            let t = pos(text, at);
            text.splice(t..t, slice);
        }
        Mutation::ReplaceIdent { k, j } | Mutation::RenameAll { k, j } => {
            let s = String::from_utf8_lossy(text).into_owned();
            let toks: Vec<_> = tokens(&s).into_iter().filter(|t| t.1 == Tok::Ident).collect();
            if toks.is_empty() || own_idents.is_empty() {
                return;
            }
            let range = toks[k % toks.len()].0.clone();
            let replacement = &own_idents[j % own_idents.len()];
            if matches!(m, Mutation::RenameAll { .. }) {
                let old = &s[range];
                let mut out = String::new();
                let mut last = 0;
                for (r, _) in toks.iter().filter(|t| &s[t.0.clone()] == old) {
                    out.push_str(&s[last..r.start]);
                    out.push_str(replacement);
                    last = r.end;
                }
                out.push_str(&s[last..]);
                *text = out.into_bytes();
            } else {
                let mut out = s.clone();
                out.replace_range(range, replacement);
                *text = out.into_bytes();
            }
        }
        Mutation::ReplaceNumber { value, .. } | Mutation::AllNumbers { value } => {
            let s = String::from_utf8_lossy(text).into_owned();
            let toks: Vec<_> = tokens(&s).into_iter().filter(|t| t.1 == Tok::Number).collect();
            if toks.is_empty() {
                return;
            }
            let value = EXTREME_NUMBERS[value % EXTREME_NUMBERS.len()];
            let chosen: Vec<_> = match m {
                Mutation::ReplaceNumber { k, .. } => vec![toks[k % toks.len()].0.clone()],
                _ => toks.iter().map(|t| t.0.clone()).collect(),
            };
            let mut out = String::new();
            let mut last = 0;
            for r in chosen {
                out.push_str(&s[last..r.start]);
                out.push_str(value);
                last = r.end;
            }
            out.push_str(&s[last..]);
            *text = out.into_bytes();
        }
        Mutation::DropLine { k } | Mutation::DuplicateLine { k } => {
            let mut lines: Vec<Vec<u8>> = text.split(|&c| c == b'\n').map(|l| l.to_vec()).collect();
            let i = k % lines.len();
            if matches!(m, Mutation::DropLine { .. }) {
                lines.remove(i);
            } else {
                let l = lines[i].clone();
                lines.insert(i, l);
            }
            *text = lines.join(&b'\n');
        }
        Mutation::InsertToken { at, tok } => {
            let t = pos(text, at);
            let v = vocabulary();
            let word = format!(" {} ", v[tok % v.len()]);
            text.splice(t..t, word.into_bytes());
        }
    }
}

/// (library file index, mutations).
fn mutated_file() -> impl Strategy<Value = (usize, Vec<Mutation>)> {
    (any::<usize>(), prop::collection::vec(mutation(), 1..5))
}

fn vocabulary() -> &'static [String] {
    static V: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();
    V.get_or_init(|| {
        let mut v: Vec<String> = [
            "import",
            "const",
            "fn",
            "graph",
            "param",
            "node",
            "let",
            "var",
            "for",
            "in",
            "output",
            "category",
            "description",
            "if",
            "else",
            "true",
            "false",
            "int",
            "float",
            "vec2",
            "vec3",
            "color",
            "bool",
            "uv",
            "sin",
            "cos",
            "floor",
            "fract",
            "abs",
            "sqrt",
            "pow",
            "exp",
            "log",
            "min",
            "max",
            "clamp",
            "mix",
            "step",
            "smoothstep",
            "atan2",
            "length",
            "dot",
            "cross",
            "normalize",
            "distance",
            "select",
            "hash",
            "sample",
            "ddu",
            "ddv",
            "srgb",
            "rgb",
            "albedo",
            "roughness",
            "height",
            "normal",
            "metallic",
            "std",
            "std.noise",
            "std.cells",
            "std.tiles",
            "fbm",
            "cells",
            "bricks",
            "perlin",
            "blur",
            "p",
            "x",
            "a",
            "f1",
            "id",
            "octaves",
            "{",
            "}",
            "(",
            ")",
            "[",
            "]",
            ",",
            ";",
            ":",
            ".",
            "..",
            "->",
            "=",
            "+=",
            "-=",
            "*=",
            "/=",
            "+",
            "-",
            "*",
            "/",
            "%",
            "<",
            "<=",
            ">",
            ">=",
            "==",
            "!=",
            "&&",
            "||",
            "!",
            "\"text\"",
            "\"unterminated",
            "// comment\n",
            "/// doc\n",
            "/* block */",
            "/* open",
            "*/",
            "\n",
            "\t",
            "é",
            "\u{feff}",
            "\0",
            ".x",
            ".xy",
            ".zyx",
            ".rgb",
            ".f1",
            "0..4",
            "0..1000000",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        v.extend(EXTREME_NUMBERS.iter().map(|s| s.to_string()));
        v
    })
}

/// A random token soup: bare, after an import, or as the body of a graph.
fn token_soup() -> impl Strategy<Value = String> {
    let v = vocabulary();
    (0..3usize, prop::collection::vec((0..v.len(), prop::sample::select(vec!["", " ", "\n"])), 0..120)).prop_map(
        |(wrap, toks)| {
            let body: String = toks.iter().map(|(t, sep)| format!("{}{sep}", vocabulary()[*t])).collect();
            match wrap {
                0 => body,
                1 => format!("import std.noise;\nimport std.cells;\n{body}"),
                _ => format!(
                    "import std.noise;\nimport std.tiles;\ngraph soup {{\n    param a = 0.5 in [0, 1]\n    {body}\n    output albedo = vec3(a)\n    output roughness = 0.5\n    output height = 0.0\n}}\n"
                ),
            }
        },
    )
}

/// Random bytes, bare or spliced into a library file.
fn random_bytes() -> impl Strategy<Value = (Option<usize>, f64, Vec<u8>)> {
    (prop::option::of(any::<usize>()), 0.0..1.0f64, prop::collection::vec(any::<u8>(), 0..400))
}

// ---------------------------------------------------------------------------------------------
// The tests

fn cases() -> u32 {
    env_usize("PSC_FUZZ_CASES", 400) as u32
}

fn runner() -> TestRunner {
    TestRunner::new(Config { cases: cases(), failure_persistence: None, ..Config::default() })
}

fn report(name: &str, count: &AtomicUsize, started: std::time::Instant) {
    eprintln!("fuzz_pipeline {name}: {} inputs compiled in {:.1?}", count.load(Ordering::Relaxed), started.elapsed());
}

#[test]
fn fuzz_mutated_library_files() {
    let started = std::time::Instant::now();
    let count = AtomicUsize::new(0);
    let lib = library();
    assert!(lib.len() >= 40, "library files missing");
    let result = runner().run(&mutated_file(), |(file, mutations)| {
        let f = &lib[file % lib.len()];
        let mut text = f.text.clone().into_bytes();
        for m in &mutations {
            apply(&mut text, m, &f.idents);
        }
        count.fetch_add(1, Ordering::Relaxed);
        check_input(&f.family, &text).map_err(TestCaseError::fail)
    });
    report("mutated library files", &count, started);
    if let Err(e) = result {
        panic!("{e}");
    }
}

#[test]
fn fuzz_token_soups() {
    let started = std::time::Instant::now();
    let count = AtomicUsize::new(0);
    let result = runner().run(&token_soup(), |text| {
        count.fetch_add(1, Ordering::Relaxed);
        check_input("wood", text.as_bytes()).map_err(TestCaseError::fail)
    });
    report("token soups", &count, started);
    if let Err(e) = result {
        panic!("{e}");
    }
}

#[test]
fn fuzz_random_bytes() {
    let started = std::time::Instant::now();
    let count = AtomicUsize::new(0);
    let lib = library();
    let result = runner().run(&random_bytes(), |(host, at, bytes)| {
        let (family, text) = match host {
            None => ("stone".to_string(), bytes),
            Some(i) => {
                let f = &lib[i % lib.len()];
                let mut t = f.text.clone().into_bytes();
                let p = pos(&t, at);
                t.splice(p..p, bytes);
                (f.family.clone(), t)
            }
        };
        count.fetch_add(1, Ordering::Relaxed);
        check_input(&family, &text).map_err(TestCaseError::fail)
    });
    report("random bytes", &count, started);
    if let Err(e) = result {
        panic!("{e}");
    }
}

/// The unmutated library passes the same oracle (and the oracle sees the compiled graphs).
#[test]
fn the_library_itself_passes_the_oracle() {
    let mut graphs = 0;
    for f in library() {
        let path: PathBuf = graphs_dir().join(&f.family).join("__fuzz.psg");
        let out = compile_text(&path, f.text.clone(), &Options::default());
        assert!(!out.has_errors(), "{}", out.render_diagnostics());
        check_output(&out).unwrap();
        graphs += out.graphs.len();
    }
    assert!(graphs >= 31, "{graphs} graphs");
}

/// The oracle is not vacuous: it rejects a span outside the text and accepts real diagnostics.
#[test]
fn the_oracle_catches_bad_spans_and_accepts_real_errors() {
    let path = graphs_dir().join("wood").join("__fuzz.psg");
    let mut out = compile_text(&path, "graph g { output albedo = nope }", &Options::default());
    assert!(out.has_errors());
    check_output(&out).unwrap();
    out.diagnostics[0].span = psc_grammar::ast::Span::new(5, 500);
    assert!(check_output(&out).is_err());
}

/// Inputs the fuzzer once failed on, kept as regression tests.
#[test]
fn regressions_found_by_fuzzing() {
    let cases: &[&[u8]] = &[
        // "this file defines no graph…" spanned the first byte of a three-byte BOM.
        "\u{feff}".as_bytes(),
        "\u{feff}import std.noise;\n".as_bytes(),
        "\u{feff}// only a comment\n".as_bytes(),
        // An invalid byte (see the known issue in `check_span`).
        &[0x80],
        &[b'g', 0xff, b'\n'],
    ];
    for bytes in cases {
        check_input("wood", bytes).unwrap();
    }
}
