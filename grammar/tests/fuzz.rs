//! Property-based fuzzing of `parse`: whatever the input, it returns (no panic, no
//! hang, no stack overflow) and every span it hands out is valid.
//!
//! Input sources: random bytes, random soups of the language's tokens (also within
//! balanced brackets, to get past the lexical pre-scan), and
//! mutations (delete / insert / duplicate a slice) of a valid sample file.
//! `PSC_FUZZ_CASES` sets the number of cases per strategy (default 2000); run with
//! `--nocapture` to see the total:
//! `PSC_FUZZ_CASES=70000 cargo test -p psc-grammar --test fuzz -- --nocapture`

mod support;

use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use psc_grammar::parse;
use support::{assert_span_valid, for_each_span};

const SAMPLE: &str = include_str!("samples/full.psg");

const TOKENS: &[&str] = &[
    "import",
    "const",
    "fn",
    "graph",
    "let",
    "var",
    "for",
    "in",
    "if",
    "else",
    "true",
    "false",
    "param",
    "node",
    "output",
    "category",
    "description",
    "int",
    "float",
    "vec2",
    "vec3",
    "uv",
    "x",
    "acc",
    "_a1",
    "srgb",
    "f1",
    "0",
    "1",
    "42",
    "1.0",
    "2e-3",
    "1e999",
    "99999999999999999999",
    "0.5",
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
    "=",
    "+=",
    "-=",
    "*=",
    "/=",
    "->",
    "..",
    ".",
    ",",
    ":",
    ";",
    "(",
    ")",
    "{",
    "}",
    "[",
    "]",
    "\"text\"",
    "\"unterminated",
    "\"esc\\\"aped\\q\"",
    "// line comment\n",
    "/* block */",
    "/*",
    "*/",
    "/// doc\n",
    "é",
    "\u{0}",
    "\t",
    "\r\n",
];

fn cases() -> u32 {
    std::env::var("PSC_FUZZ_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(2000)
}

/// Parses `src` and checks the invariants; what the tests assert for every input.
fn check(src: &str) {
    match parse(src) {
        Ok(file) => for_each_span(&file, &mut |kind, span| assert_span_valid(src, kind, span)),
        Err(errors) => {
            assert!(!errors.is_empty(), "Err without errors for {src:?}");
            for error in &errors {
                assert_span_valid(src, &error.message, error.span);
                assert!(!error.message.is_empty());
            }
        }
    }
}

/// Runs `strategy` for the configured number of cases; returns how many ran.
fn run<S: Strategy<Value = String>>(name: &str, strategy: S) -> u32 {
    let config = Config { cases: cases(), failure_persistence: None, ..Config::default() };
    let mut runner = TestRunner::new(config);
    let count = std::cell::Cell::new(0);
    let result = runner.run(&strategy, |src| {
        count.set(count.get() + 1);
        check(&src);
        Ok(())
    });
    if let Err(failure) = result {
        panic!("{name}: {failure}");
    }
    println!("fuzz {name}: {} inputs parsed", count.get());
    count.get()
}

fn random_bytes() -> impl Strategy<Value = String> {
    prop::collection::vec(any::<u8>(), 0..400).prop_map(|bytes| String::from_utf8_lossy(&bytes).into_owned())
}

fn token_soup() -> impl Strategy<Value = String> {
    let separator = prop::sample::select(&[" ", " ", " ", "\n", ""][..]);
    prop::collection::vec((prop::sample::select(TOKENS), separator), 0..80)
        .prop_map(|tokens| tokens.into_iter().flat_map(|(t, s)| [t, s]).collect())
}

/// Tokens that cannot cause a lexical error, grouped in balanced brackets: these
/// inputs get past the pre-scan and exercise the grammar itself.
fn balanced_soup() -> impl Strategy<Value = String> {
    let clean: Vec<&'static str> = TOKENS
        .iter()
        .copied()
        .filter(|t| !t.contains(['(', ')', '{', '}', '[', ']', '\0', '"']) && !t.starts_with("/*") && *t != "*/")
        .collect();
    let leaf = prop::collection::vec(prop::sample::select(clean), 0..6).prop_map(|t| t.join(" "));
    leaf.prop_recursive(6, 64, 6, |inner| {
        (prop::sample::select(&["()", "{}", "[]"][..]), prop::collection::vec(inner, 0..6), any::<bool>()).prop_map(
            |(brackets, parts, newline)| {
                let (open, close) = brackets.split_at(1);
                let separator = if newline { "\n" } else { " " };
                format!("{open}{}{close}", parts.join(separator))
            },
        )
    })
    .prop_map(|body| {
        // Mostly inside an item, so that expressions and statements get exercised.
        format!("fn f(x: float) -> float {{ {body} }}\ngraph g {{ {body} }}\nconst A = {body};")
    })
}

#[derive(Clone, Debug)]
enum Mutation {
    Delete,
    Duplicate,
    InsertToken(&'static str),
    InsertBytes(Vec<u8>),
}

fn mutated_sample() -> impl Strategy<Value = String> {
    let mutation = prop_oneof![
        Just(Mutation::Delete),
        Just(Mutation::Duplicate),
        prop::sample::select(TOKENS).prop_map(Mutation::InsertToken),
        prop::collection::vec(any::<u8>(), 1..8).prop_map(Mutation::InsertBytes),
    ];
    prop::collection::vec((mutation, 0..SAMPLE.len(), 0usize..40), 1..4).prop_map(|mutations| {
        let mut text = SAMPLE.to_owned();
        for (mutation, at, len) in mutations {
            let at = floor_boundary(&text, at.min(text.len()));
            let end = floor_boundary(&text, (at + len).min(text.len()));
            match mutation {
                Mutation::Delete => text.replace_range(at..end, ""),
                Mutation::Duplicate => {
                    let slice = text[at..end].to_owned();
                    text.insert_str(at, &slice);
                }
                Mutation::InsertToken(token) => text.insert_str(at, token),
                Mutation::InsertBytes(bytes) => text.insert_str(at, &String::from_utf8_lossy(&bytes)),
            }
        }
        text
    })
}

fn floor_boundary(text: &str, mut at: usize) -> usize {
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    at
}

#[test]
fn fuzz_parse_never_fails_badly() {
    let total = run("random bytes", random_bytes())
        + run("token soup", token_soup())
        + run("balanced token soup", balanced_soup())
        + run("mutated sample", mutated_sample());
    println!("fuzz total: {total} inputs parsed");
    assert!(total >= 4 * cases(), "ran {total} inputs");
}

/// The sample itself must stay valid, or the mutations test nothing interesting.
#[test]
fn the_mutated_sample_is_valid() {
    assert!(parse(SAMPLE).is_ok());
}
