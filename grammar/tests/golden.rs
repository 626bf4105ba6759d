//! Golden tests: the AST of sample files, printed compactly. The snapshots are the spec.

mod support;

use psc_grammar::parse;
use support::{print_file, render_errors};

fn parse_ok(src: &str) -> String {
    match parse(src) {
        Ok(file) => print_file(&file),
        Err(errors) => panic!("unexpected errors:\n{}", render_errors(src, &errors)),
    }
}

#[test]
fn full_sample() {
    insta::assert_snapshot!(parse_ok(include_str!("samples/full.psg")));
}

#[test]
fn operator_precedence() {
    insta::assert_snapshot!(parse_ok(include_str!("samples/precedence.psg")));
}
