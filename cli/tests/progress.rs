//! Progress when stderr is not a terminal (a log, CI): a plain line per stage start, per 10% of
//! its work (at most one a second, an interval these tests set to 0) and per stage end, from
//! every long command; nothing with `--quiet`.

use std::path::Path;
use std::process::{Command, Output};

/// `psc` with every 10% line logged however fast the stage (no minimum interval).
fn psc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_psc"))
        .args(args)
        .env("PSC_PROGRESS_SECONDS", "0")
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .output()
        .expect("psc runs")
}

#[test]
fn long_commands_log_their_stages_as_lines() {
    let tmp = tempfile::Builder::new().prefix("psc-progress-test-").tempdir().unwrap();
    let dir = tmp.path();

    let maps = dir.join("maps");
    let out = psc(&["bake", "knit", "--size", "8", "--random", "29", "--out", maps.to_str().unwrap()]);
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{log}");
    assert!(log.contains("bake: started (30 sets of maps at 8²)"), "{log}");
    for pct in [10, 50, 90] {
        assert!(log.contains(&format!("bake: {pct}% (")), "no {pct}% line in:\n{log}");
    }
    assert!(log.contains("bake: done in"), "{log}");
    assert!(log.lines().count() < 20, "a line per 10%, not per variant:\n{log}");

    let image = dir.join("room.png");
    let out = psc(&["render", "examples/room", "--spp", "2", "--size", "32x24", "--out", image.to_str().unwrap()]);
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{log}");
    for line in ["loading room.obj: started", "render: started (1536 samples)", "render: 50% (", "render: done in"] {
        assert!(log.contains(line), "no `{line}` in:\n{log}");
    }

    let quiet = dir.join("quiet.png");
    let out =
        psc(&["render", "examples/room", "--spp", "1", "--size", "8x6", "--quiet", "--out", quiet.to_str().unwrap()]);
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(!log.contains("started") && !log.contains("done in"), "--quiet still logged:\n{log}");
}
