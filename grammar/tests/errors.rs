//! Golden tests of error messages: what the user reads is the spec.

mod support;

use psc_grammar::parse;
use support::render_errors;

/// The rendered errors of an input that must not parse.
fn errors_of(src: &str) -> String {
    match parse(src) {
        Ok(file) => panic!("expected errors, parsed: {}", support::print_file(&file)),
        Err(errors) => {
            assert!(!errors.is_empty(), "an Err must carry at least one error");
            render_errors(src, &errors)
        }
    }
}

#[test]
fn missing_semicolon() {
    let src = "fn f(x: float) -> float {\n    let y = x * 2.0\n    y\n}\n";
    insta::assert_snapshot!(errors_of(src));
}

#[test]
fn missing_semicolon_after_const() {
    insta::assert_snapshot!(errors_of("const A = 1\nconst B = 2;\n"));
}

#[test]
fn unterminated_block_comment() {
    insta::assert_snapshot!(errors_of("const A = 1;\n/* the end is\nnever reached\nconst B = 2;\n"));
}

#[test]
fn unterminated_string() {
    insta::assert_snapshot!(errors_of("graph g {\n    description \"Oak floor\n    output roughness = 0.5\n}\n"));
}

#[test]
fn bad_token() {
    insta::assert_snapshot!(errors_of("const A = 1 $ 2;\n"));
}

#[test]
fn range_without_comma() {
    insta::assert_snapshot!(errors_of("graph g {\n    param x = 1 in [0 1]\n}\n"));
}

#[test]
fn nesting_too_deep() {
    let src = format!("const A = {}1{};\n", "(".repeat(200), ")".repeat(200));
    insta::assert_snapshot!(errors_of(&src));
}

#[test]
fn huge_literals() {
    let src = "const A = 99999999999999999999;\nconst B = 1e999;\nconst C = 1e39 + 1;\n";
    insta::assert_snapshot!(errors_of(src));
}

#[test]
fn int_param_without_range() {
    insta::assert_snapshot!(errors_of("graph g {\n    param n = 4 int\n}\n"));
}

#[test]
fn keyword_as_name() {
    insta::assert_snapshot!(errors_of("fn let(x: float) -> float { x }\n"));
}

#[test]
fn keyword_as_node_name() {
    insta::assert_snapshot!(errors_of("graph g {\n    node output = 1.0\n}\n"));
}

#[test]
fn stray_closing_brace() {
    insta::assert_snapshot!(errors_of("fn f() -> float { 1.0 } }\n"));
}

#[test]
fn unclosed_and_mismatched_brackets() {
    insta::assert_snapshot!(errors_of("fn f() -> float { g(1.0] }\nfn h() -> float {\n"));
}

#[test]
fn binary_garbage() {
    insta::assert_snapshot!(errors_of("graph \u{0}\u{1}\u{7f}\u{ff}\u{fffd}\u{9b} {}"));
}

#[test]
fn missing_else() {
    insta::assert_snapshot!(errors_of("fn f(x: float) -> float { if x > 0.0 { 1.0 } }\n"));
}

#[test]
fn missing_result_type() {
    insta::assert_snapshot!(errors_of("fn f(x: float) { x }\n"));
}

#[test]
fn positional_after_named() {
    insta::assert_snapshot!(errors_of("const A = f(k: 1, 2);\n"));
}

#[test]
fn unknown_graph_member() {
    insta::assert_snapshot!(errors_of("graph g {\n    param a = 1\n    albedo = 2\n}\n"));
}

#[test]
fn loop_body_has_no_value() {
    insta::assert_snapshot!(errors_of("fn f() -> float {\n    var s = 0.0;\n    for i in 0..4 { s }\n    s\n}\n"));
}

#[test]
fn bad_string_escape() {
    insta::assert_snapshot!(errors_of("graph g { description \"a\\qb\" }\n"));
}

#[test]
fn too_deep_operator_chain() {
    let src = format!("const A =\n{}1;\n", "1 +\n".repeat(600));
    insta::assert_snapshot!(errors_of(&src));
}

/// Errors in several items are all reported: parsing resumes at the next item.
#[test]
fn recovery_reports_each_broken_item() {
    let src = "\
import std.noise
fn ok() -> float { 1.0 }
fn broken(x: float) -> float {
    let y = x +;
    y
}
const C = ;
graph g {
    output albedo = vec3(1.0)
    param p = 1 in [0, ]
}
const D = 1e999;
";
    insta::assert_snapshot!(errors_of(src));
}

#[test]
fn empty_file_is_ok() {
    assert_eq!(parse("").unwrap().items.len(), 0);
    assert_eq!(parse("  // only a comment\n/* and another */\n").unwrap().items.len(), 0);
}
