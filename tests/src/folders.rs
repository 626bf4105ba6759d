//! Scratch copies of folder trees, for tests that break or reshape a scene or a library without
//! touching the original.
//!
//! Shared by file between test crates (`#[path]`), so it depends on `std` only.

use std::path::Path;

/// Copies the tree at `from` to `to`, leaving out every file or folder, at any depth, whose
/// name is in `skip` (e.g. `&["truth"]`: a dev scene as a user would have it).
pub fn copy_tree(from: &Path, to: &Path, skip: &[&str]) {
    std::fs::create_dir_all(to).unwrap_or_else(|e| panic!("{}: {e}", to.display()));
    for entry in std::fs::read_dir(from).unwrap_or_else(|e| panic!("{}: {e}", from.display())) {
        let entry = entry.unwrap();
        let name = entry.file_name();
        if skip.iter().any(|s| name == *s) {
            continue;
        }
        let (src, dst) = (entry.path(), to.join(&name));
        if entry.file_type().unwrap().is_dir() {
            copy_tree(&src, &dst, skip);
        } else {
            std::fs::copy(&src, &dst).unwrap_or_else(|e| panic!("{} → {}: {e}", src.display(), dst.display()));
        }
    }
}
