//! Every `.psg` file in the repository's `graphs/` folder parses.
//!
//! The standard library and the materials are written by hand in the language, so
//! they are the best sample of real input there is.

mod support;

use std::path::{Path, PathBuf};

fn psg_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            psg_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "psg") {
            out.push(path);
        }
    }
}

#[test]
fn every_library_file_parses() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../graphs");
    let mut files = Vec::new();
    psg_files(&root, &mut files);
    files.sort();
    let mut failures = String::new();
    for file in &files {
        let src = std::fs::read_to_string(file).unwrap();
        if let Err(errors) = psc_grammar::parse(&src) {
            failures += &format!("{}:\n{}", file.display(), support::render_errors(&src, &errors));
        }
    }
    assert!(failures.is_empty(), "{} files, failures:\n{failures}", files.len());
}
