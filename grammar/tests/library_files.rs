//! Every `.psg` file in the repository's `graphs/` folder parses.
//!
//! The standard library and the materials are written by hand in the language, so
//! they are the best sample of real input there is.

mod support;

use std::path::Path;

#[test]
fn every_library_file_parses() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../graphs");
    let files = psc_base::walk::files_with_extension(&root, "psg").unwrap();
    assert!(files.len() >= 20, "the library is missing: {} files", files.len());
    let mut failures = String::new();
    for file in &files {
        let src = std::fs::read_to_string(file).unwrap();
        if let Err(errors) = psc_grammar::parse(&src) {
            failures += &format!("{}:\n{}", file.display(), support::render_errors(&src, &errors));
        }
    }
    assert!(failures.is_empty(), "{} files, failures:\n{failures}", files.len());
}
