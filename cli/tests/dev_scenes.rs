//! `psc render` on a shared dev scene with the validation options that read ground truth, each
//! asked for by name. Needs `../shared/scenes`: says so loudly when absent, fails then under CI.

#[allow(dead_code)] // the file serves several test crates
#[path = "../../tests/src/dev_scenes.rs"]
mod dev_scenes;
#[path = "../../tests/src/not_run.rs"]
mod not_run;

use std::process::Command;

#[test]
fn render_reads_truth_when_asked_for_by_name() {
    let Some(dir) = dev_scenes::dev_scene("dev_1", "render_reads_truth_when_asked_for_by_name") else { return };
    let out_tmp = tempfile::Builder::new().prefix("psc-cli-dev-scene-").tempdir().unwrap();
    let out_dir = out_tmp.path();
    let image = out_dir.join("truth.exr");
    let run = |extra: &[&str]| {
        let mut args = vec!["render", dir.to_str().unwrap(), "--spp", "1", "--size", "16x12", "--quiet"];
        args.extend_from_slice(extra);
        Command::new(env!("CARGO_BIN_EXE_psc")).args(&args).output().expect("psc runs")
    };
    let out =
        run(&["--materials", "truth", "--geometry", "truth", "--lights", "truth", "--out", image.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(image.is_file());
    // Without --lights the default is said, and differs from the truth's radiances.
    let unit = out_dir.join("unit.exr");
    let out = Command::new(env!("CARGO_BIN_EXE_psc"))
        .args(["render", dir.to_str().unwrap(), "--spp", "1", "--size", "16x12", "--out", unit.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("unit radiance"), "{}", String::from_utf8_lossy(&out.stderr));
}
