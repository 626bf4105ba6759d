//! `psc` end to end, as a user runs it: exit codes, what is printed, which files appear, and
//! that a failing command leaves no output behind.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn psc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_psc")).args(args).current_dir(repo()).output().expect("psc runs")
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A fresh, empty scratch folder per test.
fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-cli-test-{name}-")).tempdir().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn compile_accepts_the_library_and_reports_sizes() {
    let out = psc(&["compile", "graphs"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(stdout.contains("graph oak_planks"), "{stdout}");
    assert!(stdout.contains("after DCE") && stdout.contains("forward+adjoint"), "{stdout}");
    assert!(stdout.contains("0 errors"), "{stdout}");
}

#[test]
fn compile_fails_with_a_located_hint_for_a_typo() {
    let out = psc(&["compile", "compiler/tests/ui/typo_in_call.psg"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = text(&out.stderr);
    assert!(stderr.contains("typo_in_call.psg:5:14"), "{stderr}");
    assert!(stderr.contains("did you mean `fbm`?"), "{stderr}");
}

#[test]
fn compile_json_is_machine_readable() {
    let out = psc(&["compile", "--json", "compiler/tests/ui/cycle.psg", "graphs/fabric/knit.psg"]);
    assert_eq!(out.status.code(), Some(1), "one of the two files has an error");
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("valid JSON on stdout");
    assert_eq!(doc["graphs"].as_array().map(Vec::len), Some(1));
    let d = &doc["diagnostics"][0];
    assert_eq!(d["severity"], "error");
    assert!(d["line"].as_u64().is_some() && d["column"].as_u64().is_some());
}

#[test]
fn compile_emits_ir() {
    let out = psc(&["compile", "--emit", "ir", "graphs/homogeneous.psg"]);
    assert!(out.status.success());
    let stdout = text(&out.stdout);
    assert!(stdout.contains("out albedo.r = ") && stdout.contains("= param 0"), "{stdout}");
}

#[test]
fn missing_inputs_are_errors_not_panics() {
    for args in [
        vec!["compile", "no/such/file.psg"],
        vec!["bake", "no_such_graph", "--size", "8"],
        vec!["render", "no/such/scene", "--out", "x.png"],
    ] {
        let out = psc(&args);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {}", text(&out.stderr));
        assert!(text(&out.stderr).starts_with("error:"), "{args:?}: {}", text(&out.stderr));
    }
}

#[test]
fn bake_writes_every_map_and_random_variants() {
    let scratch_dir = scratch("bake");
    let dir = scratch_dir.path().join("maps");
    let out = psc(&["bake", "knit", "--size", "16", "--random", "2", "--seed", "3", "--out", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let mut names: Vec<String> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    for suffix in ["albedo.png", "albedo.exr", "normal.png", "roughness.png", "height.exr", "params.json"] {
        assert_eq!(
            names.iter().filter(|n| n.ends_with(suffix)).count(),
            3,
            "{suffix} for defaults + 2 variants in {names:?}"
        );
    }
}

#[test]
fn bake_refuses_out_of_range_parameters_and_writes_nothing() {
    let tmp = scratch("bake-bad");
    let dir = tmp.path();
    let params = dir.join("p.json");
    std::fs::write(&params, r#"{"rows": 99}"#).unwrap();
    let out_dir = dir.join("maps");
    let out = psc(&[
        "bake",
        "oak_planks",
        "--size",
        "8",
        "--params",
        params.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("rows"), "{}", text(&out.stderr));
    let written = std::fs::read_dir(&out_dir).map(|d| d.count()).unwrap_or(0);
    assert_eq!(written, 0, "a refused bake must not leave files");
}

/// `psc render examples/room` with the bundled assignment and lights, 1 spp, at `size`.
fn render_example_room(size: &str, out: &Path) -> Output {
    psc(&[
        "render",
        "examples/room",
        "--assign",
        "examples/room/materials.json",
        "--lights",
        "examples/room/lights.json",
        "--spp",
        "1",
        "--size",
        size,
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ])
}

#[test]
fn render_the_example_room_with_procedural_materials() {
    let tmp = scratch("render");
    let dir = tmp.path();
    let image = dir.join("room.png");
    let out = render_example_room("32x24", &image);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let decoded = std::fs::read(&image).expect("the image was written");
    assert_eq!(&decoded[1..4], b"PNG");

    // Same inputs and seed, same file, byte for byte (EXR tiles are compressed in parallel).
    let exrs: Vec<Vec<u8>> = (0..4)
        .map(|k| {
            let path = dir.join(format!("room{k}.exr"));
            let out = render_example_room("320x240", &path);
            assert!(out.status.success(), "{}", text(&out.stderr));
            std::fs::read(&path).expect("the EXR was written")
        })
        .collect();
    assert!(exrs.iter().all(|e| *e == exrs[0]), "renders with one seed wrote different EXR files");

    // A bad assignment fails before anything is written.
    let bad = dir.join("bad.json");
    std::fs::write(&bad, r#"{"parts": {"flor": {"graph": "oak_planks"}}}"#).unwrap();
    let image2 = dir.join("never.png");
    let out = psc(&[
        "render",
        "examples/room",
        "--assign",
        bad.to_str().unwrap(),
        "--spp",
        "1",
        "--size",
        "8x6",
        "--quiet",
        "--out",
        image2.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = text(&out.stderr);
    assert!(stderr.contains("part `flor`") && stderr.contains("floor"), "{stderr}");
    assert!(!image2.exists(), "no output after an error");
}

#[test]
fn a_closed_pipe_stops_output_without_a_panic() {
    use std::io::Read;
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_psc"))
        .args(["compile", "--emit", "ir", "graphs"])
        .current_dir(repo())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("psc runs");
    // Read a little, then hang up, as `| head` does.
    let mut first = [0u8; 64];
    child.stdout.take().unwrap().read_exact(&mut first).unwrap();
    let mut stderr = String::new();
    child.stderr.take().unwrap().read_to_string(&mut stderr).unwrap();
    child.wait().unwrap();
    assert!(!stderr.contains("panicked"), "{stderr}");
}
