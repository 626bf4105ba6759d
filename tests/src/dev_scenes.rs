//! The shared development scenes (`../shared/scenes/dev_*` beside the checkout) for tests that
//! need them. Where they are absent a test cannot run: it says so on the real stderr (past the
//! test harness's capture, so a passing run still shows it) and, when the environment variable
//! `CI` is set, fails instead, since CI always has the scenes.
//!
//! Shared by file between test crates (`#[path]`, beside `not_run.rs`, which it calls as
//! `crate::not_run`), so it depends on `std` only.

use std::path::{Path, PathBuf};

/// The folder holding `dev_1` … `dev_4`.
pub fn dev_scenes_root() -> PathBuf {
    // Every crate of the workspace is one level below the checkout.
    let krate = Path::new(env!("CARGO_MANIFEST_DIR"));
    krate.parent().unwrap_or(krate).join("../shared/scenes")
}

/// The dev scene `name`, or `None` (said loudly; a failure under `CI`) when it is missing.
/// `test` names the caller in the message.
pub fn dev_scene(name: &str, test: &str) -> Option<PathBuf> {
    let dir = dev_scenes_root().join(name);
    if dir.join("scene.json").is_file() {
        return Some(dir);
    }
    let message = format!("dev scene {name} not found at {}: the test `{test}` could not run", dir.display());
    if std::env::var_os("CI").is_some() {
        panic!("{message}, and CI is set (CI always has ../shared/scenes)");
    }
    crate::not_run::say_skipped(&format!("{message} (set CI=1 to make this a failure)"));
    None
}

/// Every dev scene, in order; `None` (said loudly, a failure under `CI`) if any is missing.
pub fn all_dev_scenes(test: &str) -> Option<Vec<PathBuf>> {
    ["dev_1", "dev_2", "dev_3", "dev_4"].iter().map(|n| dev_scene(n, test)).collect()
}
