//! Saying that a test could not run, because a dev scene or an external checker is missing. The
//! message goes straight to the process's stderr: the test harness captures `eprintln!` and
//! shows it only for a failing test, so a skip said that way vanishes from a passing run's log.
//!
//! Shared by file between test crates (`#[path]`), so it depends on `std` only.

use std::io::Write;

/// Prints `message` as a loud SKIPPED banner on the real stderr.
pub fn say_skipped(message: &str) {
    let _ = writeln!(std::io::stderr(), "\n==== SKIPPED: {message} ====\n");
}
