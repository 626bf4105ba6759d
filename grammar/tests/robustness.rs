//! Adversarial inputs: deep nesting, long chains, odd bytes. The parser must answer
//! (Ok or Err, never a panic, a hang or a stack overflow), on a modest stack.

use psc_grammar::{parse, MAX_NESTING};

/// Parses on a thread with a 2 MiB stack (rayon's and the test harness's default),
/// so that the result does not depend on the stack of the thread running the test.
fn parse_on_small_stack(src: String) -> Result<(), Vec<String>> {
    std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(move || match parse(&src) {
            Ok(_) => Ok(()),
            Err(errors) => Err(errors.into_iter().map(|e| e.message).collect()),
        })
        .unwrap()
        .join()
        .expect("the parser panicked")
}

/// `depth` nested constructs, each built by `open` / `close` around `inner`.
fn nested(open: &str, inner: &str, close: &str, depth: usize) -> String {
    format!("{}{inner}{}", open.repeat(depth), close.repeat(depth))
}

/// Each shape, nested exactly to the limit, parses; one level more is an error.
#[test]
fn nesting_up_to_the_limit_parses_and_beyond_is_an_error() {
    let shapes: [(&str, &str, &str, &str, &str, usize); 7] = [
        // (prefix, open, inner, close, suffix, brackets used by prefix + suffix)
        ("const A = ", "(", "1", ")", ";", 0),
        ("const A = ", "f(", "1", ")", ";", 0),
        ("const A = ", "-(", "1", ")", ";", 0),
        ("const A = ", "(a: ", "1", ")", ";", 0),
        ("fn f() -> float ", "{ ", "1.0", " }", "", 0),
        ("fn f() -> float { ", "if c { ", "1.0", " } else { 0.0 }", " }", 1),
        ("fn f(p: ", "(a: ", "float", ")", ") -> float { 1.0 }", 1),
    ];
    for (prefix, open, inner, close, suffix, used) in shapes {
        let at_limit = format!("{prefix}{}{suffix}", nested(open, inner, close, MAX_NESTING - used));
        assert_eq!(parse_on_small_stack(at_limit), Ok(()), "shape {open}…{close} at the limit");
        let beyond = format!("{prefix}{}{suffix}", nested(open, inner, close, MAX_NESTING - used + 1));
        let errors = parse_on_small_stack(beyond).unwrap_err();
        assert!(errors[0].contains("nesting too deep"), "shape {open}…{close}: {errors:?}");
    }
}

#[test]
fn very_deep_nesting_is_rejected_before_parsing() {
    for open in ["(", "[", "{", "f(", "{ let a = "] {
        let src = format!("const A = {}", open.repeat(100_000));
        let errors = parse_on_small_stack(src).unwrap_err();
        assert!(errors[0].contains("nesting too deep"), "{open}: {errors:?}");
    }
}

/// Chains that the grammar parses by repetition would still build a deep tree;
/// the parser refuses them with an error instead of overflowing a later walk.
#[test]
fn long_chains_are_errors_not_crashes() {
    let n = 20_000;
    let chains = [
        format!("const A = {}x;", "-".repeat(n)),
        format!("const A = {}x;", "!".repeat(n)),
        format!("const A = x{};", ".y".repeat(n)),
        format!("const A = {}1;", "1 + ".repeat(n)),
        format!("const A = {}1;", "1 * 2 + ".repeat(n)),
        format!("fn f() -> float {{ if a {{ 1.0 }} {}else {{ 0.0 }} }}", "else if a { 1.0 } ".repeat(n)),
    ];
    for src in chains {
        let errors = parse_on_small_stack(src).unwrap_err();
        assert!(errors[0].contains("nested too deeply"), "{errors:?}");
    }
}

#[test]
fn long_flat_inputs_parse() {
    let consts: String = (0..20_000).map(|i| format!("const C{i} = {i}.5 * 2;\n")).collect();
    assert_eq!(parse_on_small_stack(consts), Ok(()));
    let statements: String = (0..20_000).map(|i| format!("    s += {i}.0;\n")).collect();
    let body = format!("fn f() -> float {{\n    var s = 0.0;\n{statements}    s\n}}\n");
    assert_eq!(parse_on_small_stack(body), Ok(()));
    let members: String = (0..20_000).map(|i| format!("    node n{i} = {i}\n")).collect();
    assert_eq!(parse_on_small_stack(format!("graph g {{\n{members}}}\n")), Ok(()));
    let args = "1, ".repeat(20_000);
    assert_eq!(parse_on_small_stack(format!("const A = f({args});")), Ok(()));
}

#[test]
fn many_errors_are_capped() {
    let src = "const A = ;\n".repeat(10_000);
    let errors = parse_on_small_stack(src).unwrap_err();
    assert!(errors.len() > 1 && errors.len() <= 25, "{} errors", errors.len());
}

#[test]
fn odd_characters_are_errors() {
    for src in ["\0", "const A = 1;\u{0}", "\u{1b}[31m", "const A = \u{85}1;", "\u{7f}", "const\u{c}A = 1;"] {
        let errors = parse_on_small_stack(src.to_owned()).unwrap_err();
        assert!(errors[0].contains("control character"), "{src:?}: {errors:?}");
    }
    for src in ["é", "\u{fffd}", "const A = 1 \u{2028} ;", "🦀"] {
        assert!(parse_on_small_stack(src.to_owned()).is_err(), "{src:?}");
    }
    // A byte-order mark and CRLF line ends are fine.
    assert_eq!(parse_on_small_stack("\u{feff}const A = 1;\r\nconst B = 2;\r\n".to_owned()), Ok(()));
}

#[test]
fn literals_at_the_edges() {
    assert_eq!(parse_on_small_stack("const A = 9223372036854775807;".into()), Ok(()));
    assert!(parse_on_small_stack("const A = 9223372036854775808;".into()).is_err());
    assert_eq!(parse_on_small_stack("const A = 3.4e38; const B = 1e-999;".into()), Ok(()));
    assert!(parse_on_small_stack("const A = 3.5e38;".into()).is_err());
    let long_digits = format!("const A = 0.{};", "1".repeat(10_000));
    assert_eq!(parse_on_small_stack(long_digits), Ok(()));
}

/// A 200 KB word where a token is expected is named by a short prefix, not echoed whole.
#[test]
fn huge_tokens_are_not_echoed_in_messages() {
    let word = "n".repeat(200_000);
    let src = format!("graph g {{\n    output albedo = vec3(0.5) {word}\n}}\n");
    let errors = psc_grammar::parse(&src).expect_err("a stray word is an error");
    for e in &errors {
        assert!(e.message.len() < 300, "{} bytes: {}…", e.message.len(), &e.message[..100]);
        assert!(e.span.end <= src.len());
    }
    assert!(errors.iter().any(|e| e.message.contains("`nnnn") && e.message.contains('…')), "{errors:?}");
}
