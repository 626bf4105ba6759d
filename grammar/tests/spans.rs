//! Spans: the text under each node's span is exactly what was written for it.

mod support;

use psc_grammar::ast::*;
use psc_grammar::parse;
use support::{assert_span_valid, for_each_span};

const SAMPLE: &str = include_str!("samples/full.psg");

/// The source text of every node of `kind` in the sample, in source order.
fn texts_of(kind: &str) -> Vec<&'static str> {
    let file = parse(SAMPLE).expect("sample parses");
    let mut texts = Vec::new();
    for_each_span(&file, &mut |k, span| {
        if k == kind {
            texts.push(&SAMPLE[span.start..span.end]);
        }
    });
    texts
}

#[test]
fn every_span_is_valid_and_names_match() {
    let file = parse(SAMPLE).unwrap();
    let mut count = 0;
    for_each_span(&file, &mut |kind, span| {
        assert_span_valid(SAMPLE, kind, span);
        count += 1;
    });
    assert!(count > 200, "visited only {count} nodes");
    for text in texts_of("ident") {
        assert!(text.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'), "ident span {text:?}");
    }
}

#[test]
fn item_spans() {
    assert_eq!(texts_of("import"), ["import std.noise;", "import std.cells.voronoi;"]);
    let consts = texts_of("const");
    assert_eq!(consts[..2], ["const TAU = 6.2831853;", "const OCTAVES = 4;"]);
    // A graph-level const has no `;` to include.
    assert_eq!(consts[2], "const K = 2.5");
    let fns = texts_of("fn");
    assert!(fns[0].starts_with("fn ring(p: vec2,") && fns[0].ends_with("acc / float(octaves)\n}"));
    let graph = texts_of("graph")[0];
    assert!(graph.starts_with("graph oak_planks {") && graph.ends_with("cells.f1 + -grain % 2\n}"));
}

#[test]
fn fn_part_spans() {
    let params = texts_of("fn_param");
    assert_eq!(params[..3], ["p: vec2", "const octaves: int = 4", "k: float = 1.0"]);
    assert!(texts_of("type").contains(&"(f1: float, id: vec2)"));
    assert_eq!(texts_of("let")[..2], ["let r = length(p);", "var acc = 0.0;"]);
    assert_eq!(texts_of("assign")[0], "acc += sin(r * k * float(i + 1));");
    let for_loop = texts_of("for")[0];
    assert!(for_loop.starts_with("for i in 0..octaves {") && for_loop.ends_with('}'));
    let blocks = texts_of("block");
    assert!(blocks.contains(&"{\n        acc += sin(r * k * float(i + 1));\n    }"));
    assert!(blocks.contains(&"{ let t = x * x; t }"));
}

#[test]
fn expression_spans() {
    let exprs = texts_of("expr");
    for expected in [
        "acc / float(octaves)",
        "r * k * float(i + 1)",
        "float(i + 1)",
        "(f1: best, id: floor(q).xy)",
        "floor(q).xy",
        "if x < 0.25 { 0.0 } else if x < 0.5 { 0.5 } else { { let t = x * x; t } }",
        // The nested `if` of an `else if` starts at its own `if`.
        "if x < 0.5 { 0.5 } else { { let t = x * x; t } }",
        "brick(uv, rows: planks)",
        "!(cells.f1 > 0.5) && true",
        // Parentheses belong to the expression they wrap.
        "(cells.f1 > 0.5)",
        "0.01 * cells.f1 + -grain % 2",
        "-grain % 2",
        "-grain",
        "1e9",
    ] {
        assert!(exprs.contains(&expected), "no expression spans {expected:?}");
    }
}

#[test]
fn graph_member_spans() {
    let params = texts_of("param");
    assert_eq!(params[0], "param planks    = 6      in [2, 16]  int");
    // The optional `;` separator is not part of the member.
    assert_eq!(params[1], "param ring_freq = 18.0   in [4, 60]");
    assert_eq!(texts_of("range"), ["[2, 16]", "[4, 60]"]);
    let members = texts_of("member");
    assert_eq!(members[0], "node cells = brick(uv, rows: planks)");
    assert_eq!(members[1], "let grain = ring(uv - 0.5, octaves: 3) * K");
    assert_eq!(members.last().unwrap(), &"output height    = 0.01 * cells.f1 + -grain % 2");
    assert_eq!(texts_of("category"), ["category wood"]);
    assert_eq!(texts_of("description"), ["description \"Oak floor \\\"planks\\\"\""]);
}

#[test]
fn spans_are_byte_offsets_past_multibyte_text() {
    let src = "// café ☕ — comments may hold any text\nconst A = é;";
    let errors = parse(src).unwrap_err();
    assert_eq!(&src[errors[0].span.start..errors[0].span.end], "é");
    let src = "/// naïve doc\nconst Ω_FREE = 1.0;\nconst B = 2.0;";
    assert!(parse(src).is_err(), "non-ASCII names are not identifiers");
    let src = "/* ünïcödé */ const B = 2.0;";
    let file = parse(src).unwrap();
    let Item::Const(c) = &file.items[0] else { panic!() };
    assert_eq!(&src[c.span.start..c.span.end], "const B = 2.0;");
    assert_eq!(&src[c.value.span.start..c.value.span.end], "2.0");
}

#[test]
fn doc_comments_attach_to_the_next_item_only() {
    let src = "\
/// First line.
///   indented second line
///
fn a() -> float { 1.0 }

/// Orphaned: a blank line does not break the link, but code does.
const X = 1;
const Y = 2; /// trailing: documents nothing
const Z = 3;
//// four slashes: a plain comment
graph g {
    /// The count.
    param n = 1 in [0, 4] int
    // plain
    param m = 2
}
";
    let file = parse(src).unwrap();
    let docs: Vec<Option<&str>> = file
        .items
        .iter()
        .map(|item| match item {
            Item::Fn(f) => f.doc.as_deref(),
            Item::Const(c) => c.doc.as_deref(),
            Item::Graph(g) => g.doc.as_deref(),
            Item::Import(_) => None,
        })
        .collect();
    assert_eq!(
        docs,
        [
            Some("First line.\n  indented second line\n"),
            Some("Orphaned: a blank line does not break the link, but code does."),
            None,
            None,
            None
        ]
    );
    let Item::Graph(g) = &file.items[4] else { panic!() };
    let param_docs: Vec<Option<&str>> = g
        .members
        .iter()
        .map(|m| match m {
            GraphMember::Param(p) => p.doc.as_deref(),
            _ => None,
        })
        .collect();
    assert_eq!(param_docs, [Some("The count."), None]);
}
