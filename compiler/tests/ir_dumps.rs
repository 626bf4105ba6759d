//! File-driven golden tests of the IR (in the style of naga's snapshots and cranelift's
//! filetests): every `tests/ir/*.psg` is compiled, and what `psc compile --emit ir` and
//! `--emit adjoint` print for its graphs (the same `CompiledGraph::ir_dump` / `adjoint_dump`)
//! is compared with `tests/snapshots/ir_dumps__<name>.snap`. A case is a small `.psg` file
//! whose leading comment says what it exercises; `tests/ir/util/` holds modules the cases
//! import (the folder is their library root, so the shipped library can change freely).
//!
//! Add a case by adding a file; re-bless after an intended change with
//! `INSTA_UPDATE=always cargo test --release -p psc-compiler --test ir_dumps` and review the
//! diff like code: every changed line is a changed program.

use std::path::{Path, PathBuf};

use psc_compiler::{compile_files, Options};

fn cases_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ir")
}

#[test]
fn every_ir_case_compiles_validates_and_matches_its_snapshot() {
    let dir = cases_dir();
    // Top-level files only: `util/` holds imported modules, not cases.
    let mut cases = psc_compiler::find_sources(&dir).unwrap();
    cases.retain(|p| p.parent() == Some(&dir));
    assert!(cases.len() >= 8, "the IR cases are missing: {}", cases.len());
    for case in cases {
        let name = case.file_stem().unwrap().to_string_lossy().into_owned();
        let out = compile_files(std::slice::from_ref(&case), &Options { lib_root: Some(dir.clone()) });
        assert!(!out.has_errors(), "{name}:\n{}", out.render_diagnostics());
        assert!(!out.graphs.is_empty(), "{name}: no graph");
        let mut dump = String::new();
        for g in &out.graphs {
            let adjoint = g.adjoint();
            g.forward.validate().unwrap_or_else(|e| panic!("{name}: forward: {e}"));
            adjoint.program.validate().unwrap_or_else(|e| panic!("{name}: adjoint: {e}"));
            adjoint.layout.check(&g.forward, &adjoint.program).unwrap_or_else(|e| panic!("{name}: {e}"));
            // As `psc compile --emit ir` and `--emit adjoint` print them (one `println!` each).
            dump.push_str(&format!("{}\n{}\n", g.ir_dump(), g.adjoint_dump(&adjoint)));
        }
        // Paths differ between machines: show them relative to the cases folder.
        let dump = dump.replace(&format!("{}/", dir.canonicalize().unwrap().display()), "");
        insta::assert_snapshot!(name, dump);
    }
}
