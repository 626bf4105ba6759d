//! Data-driven golden tests of diagnostics: every `tests/ui/*.psg` is compiled and its rendered
//! diagnostics compared with `tests/snapshots/diagnostics__<name>.snap`. Re-bless with
//! `INSTA_UPDATE=always cargo test -p psc-compiler --test diagnostics` and review the diff.

use std::path::{Path, PathBuf};

use psc_compiler::{compile_files, Options};

fn library_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../graphs")
}

#[test]
fn every_ui_case_reports_errors_and_matches_its_snapshot() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ui");
    let cases = psc_compiler::find_sources(&dir).unwrap();
    assert!(cases.len() >= 10, "the ui cases are missing");
    for case in cases {
        let name = case.file_stem().unwrap().to_string_lossy().into_owned();
        let out = compile_files(std::slice::from_ref(&case), &Options { lib_root: Some(library_root()) });
        assert!(out.has_errors(), "{name}: expected at least one error");
        assert!(out.graphs.is_empty(), "{name}: a file with errors must not produce graphs");
        // Paths differ between machines; show them relative to the ui folder.
        let lib = library_root();
        let rendered = out
            .render_diagnostics()
            .replace(&format!("{}/", dir.display()), "")
            .replace(&lib.display().to_string(), "<lib>");
        insta::assert_snapshot!(name, rendered);
    }
}
