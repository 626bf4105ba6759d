//! Options that make no sense are refused before any work, with exit 2 and a message naming the
//! option, what was expected and what was given; bad input files get exit 1. Nothing is written
//! in either case.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn psc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_psc")).args(args).current_dir(repo()).output().expect("psc runs")
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-options-test-{name}-")).tempdir().unwrap()
}

/// Runs every case in `dir` and checks the exit code, that stderr has each expected piece,
/// and that `dir` is still empty afterwards (apart from the files the cases set up).
fn check(dir: &Path, cases: &[(Vec<String>, i32, Vec<&str>)]) {
    let before: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    let mut failures = Vec::new();
    for (args, code, wants) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = psc(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        if out.status.code() != Some(*code) || !wants.iter().all(|w| stderr.contains(w)) || stderr.contains("panicked")
        {
            failures.push(format!(
                "psc {}\n  exit {:?} (want {code})\n  stderr: {stderr}",
                args.join(" "),
                out.status.code()
            ));
        }
        let after: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(before, after, "psc {} left files behind", args.join(" "));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

fn v(args: &[&str]) -> Vec<String> {
    args.iter().map(|s| s.to_string()).collect()
}

#[test]
fn render_options_that_make_no_sense_are_usage_errors() {
    let tmp = scratch("render");
    let dir = tmp.path();
    let d = dir.to_str().unwrap();
    let png = format!("{d}/x.png");
    let folder = format!("{d}/out");
    let file = format!("{d}/a_file.txt");
    std::fs::write(&file, "not a folder").unwrap();
    let room = "examples/room";
    let cases = vec![
        (
            v(&["render", room, "--gbuffer", "--light-grid", "--out", &folder]),
            2,
            vec!["'--gbuffer' cannot be used with '--light-grid'"],
        ),
        (v(&["render", room, "--gbuffer", "--per-light", "--out", &folder]), 2, vec!["cannot be used with"]),
        (v(&["render", room, "--max-depth", "0", "--out", &png]), 2, vec!["--max-depth", "0 is not in 1..=1024"]),
        (v(&["render", room, "--spp", "0", "--out", &png]), 2, vec!["--spp", "'0'"]),
        (v(&["render", room, "--threads", "0", "--out", &png]), 2, vec!["--threads", "'0'"]),
        (v(&["render", room, "--grid-stride", "0", "--light-grid", "--out", &folder]), 2, vec!["--grid-stride"]),
        (v(&["render", room, "--size", "0x5", "--out", &png]), 2, vec!["--size", "expected WIDTHxHEIGHT", "'0x5'"]),
        (v(&["render", room, "--size", "big", "--out", &png]), 2, vec!["--size", "got 'big'"]),
        (
            v(&["render", room, "--out", &format!("{d}/x.jpg")]),
            2,
            vec!["--out: expected a path ending in .png or .exr, got"],
        ),
        (v(&["render", room, "--out", d]), 2, vec!["--out:", "is a directory; expected an image file path"]),
        (v(&["render", room, "--gbuffer", "--out", &file]), 2, vec!["--out:", "is a file; expected a folder"]),
        (v(&["render", room]), 2, vec!["--out: required"]),
        (v(&["render", room, "--view", "nope", "--out", &png]), 1, vec!["no view 'nope' (views: view0)"]),
        (v(&["render", room, "--lights", "truth", "--out", &png]), 1, vec!["truth/truth.json", "not found"]),
        (v(&["render", room, "--assign", d, "--out", &png]), 1, vec!["expected a JSON file, found a directory"]),
    ];
    check(dir, &cases);
}

/// Requests past the documented limits (`psc_base::limits`) are refused before anything is
/// allocated, saying the limit and the memory the request would need.
#[test]
fn requests_past_the_limits_are_refused_at_once() {
    let tmp = scratch("limits");
    let dir = tmp.path();
    let d = dir.to_str().unwrap();
    let png = format!("{d}/x.png");
    let cam = format!("{d}/cam.json");
    std::fs::write(
        &cam,
        r#"{"position": [2, 1.5, 4], "look_at": [2, 1, 0], "fov_y_deg": 60, "width": 100000, "height": 100000}"#,
    )
    .unwrap();
    let room = "examples/room";
    let cases = vec![
        (
            v(&["render", room, "--threads", "100000", "--out", &png]),
            2,
            vec!["--threads", "100,000 threads requested; the limit is 256"],
        ),
        (v(&["render", room, "--size", "100000x100000", "--out", &png]), 2, vec!["the limit is 67,108,864 pixels"]),
        (
            v(&["render", room, "--size", "4294967295x4294967295", "--gbuffer", "--out", &format!("{d}/g")]),
            2,
            vec!["the limit is 67,108,864 pixels"],
        ),
        (v(&["render", room, "--spp", "100000000", "--out", &png]), 2, vec!["the limit is 65,536 samples"]),
        (
            v(&["render", room, "--light-grid", "--grid-samples", "100000", "--out", &format!("{d}/g")]),
            2,
            vec!["the limit is 4,096 paths"],
        ),
        (
            v(&["render", room, "--camera", &cam, "--out", &png]),
            1,
            vec!["100000x100000", "the limit is 67,108,864 pixels", "GiB of memory"],
        ),
        (
            v(&["library", "--sheet", &format!("{d}/s.png"), "--size", "1000000", "--only", "plaster"]),
            2,
            vec!["--size: bake of 1000000x1000000 texels", "the limit is 67,108,864 texels"],
        ),
        (
            v(&["library", "--sheet", &format!("{d}/s.png"), "--variants", "100000"]),
            2,
            vec!["would need about", "the limit is 16.0 GiB"],
        ),
        (v(&["library", "--bench", "1000000"]), 2, vec!["--bench:", "the limit is 67,108,864 texels"]),
        (
            v(&["bench", "--size", "1000000"]),
            2,
            vec!["--size: bake of 1000000x1000000 texels", "the limit is 67,108,864 texels"],
        ),
        (
            v(&["bake", "oak_planks", "--size", "8", "--random", "100000000", "--out", &format!("{d}/b")]),
            2,
            vec!["--random:", "the limit is 10,000 variants"],
        ),
        (
            v(&["bake", "knit", "--size", "9000", "--out", &format!("{d}/b")]),
            2,
            vec!["--size:", "the limit is 67,108,864 texels"],
        ),
        (v(&["bench", "--synthetic", "100000000", "--size", "8"]), 2, vec!["--synthetic", "expected 1 to 65536 ops"]),
        (
            v(&["fit", room, "--exemplars", "4000000000", "--out", &format!("{d}/f")]),
            2,
            vec!["--exemplars", "expected 1 to 1000 exemplars"],
        ),
        (v(&["fit", room, "--fit-pixels", "1", "--out", &format!("{d}/f")]), 2, vec!["--fit-pixels", "at least 500"]),
        (
            v(&["fit", room, "--search-pixels", "499", "--out", &format!("{d}/f")]),
            2,
            vec!["--search-pixels", "at least 500"],
        ),
        (v(&["fit", room, "--search-samples", "0", "--out", &format!("{d}/f")]), 2, vec!["--search-samples", "'0'"]),
        (
            v(&["fit", room, "--fit-window", "round", "--out", &format!("{d}/f")]),
            2,
            vec!["--fit-window", "'round'", "square"],
        ),
        (v(&["fit", room, "--search-samples", "9", "--out", &format!("{d}/f")]), 2, vec!["--search-samples", "'9'"]),
        (v(&["eval", room, room, "--threads", "0"]), 2, vec!["--threads", "at least 1 thread"]),
        (v(&["eval", room, room, "--spp", "0"]), 2, vec!["--spp", "at least 1 sample"]),
        (v(&["eval", room, room, "--flat-spp", "0"]), 2, vec!["--flat-spp", "at least 1 sample"]),
        (v(&["eval", room, room, "--max-depth", "0"]), 2, vec!["--max-depth"]),
        (
            v(&["fit", room, "--graph", "floor=plaster", "--graph", "floor=knit", "--out", &format!("{d}/f")]),
            2,
            vec!["--graph: part 'floor' is forced twice (plaster, then knit)"],
        ),
        (v(&["report", room, "--scene", &format!("{d}/no-scene")]), 1, vec!["--scene:", "no scene.json"]),
    ];
    check(dir, &cases);
}

#[test]
fn bench_sizes_and_runs_of_zero_are_usage_errors() {
    let tmp = scratch("bench");
    let cases = vec![
        (v(&["bench", "--size", "0"]), 2, vec!["--size", "'0'", "0 is not in 1.."]),
        (v(&["bench", "--runs", "0"]), 2, vec!["--runs", "'0'", "0 is not in 1.."]),
    ];
    check(tmp.path(), &cases);
}

/// `psc export --texture-size 0` is a usage error before the scene or the library is read, as
/// an over-limit size is; it was refused only by the export itself (exit 1, after loading).
#[test]
fn export_texture_sizes_out_of_range_are_usage_errors() {
    let tmp = scratch("export");
    let d = tmp.path().to_str().unwrap();
    let out = format!("{d}/out");
    let room = "examples/room";
    let (assign, lights) = ("examples/room/materials.json", "examples/room/lights.json");
    let export = |size: &str| {
        v(&["export", room, "--assign", assign, "--lights", lights, "--out", &out, "--texture-size", size])
    };
    let cases = vec![
        (export("0"), 2, vec!["--texture-size", "'0'", "0 is not in 1.."]),
        (export("100000"), 2, vec!["--texture-size:", "the limit is 67,108,864 texels"]),
    ];
    check(tmp.path(), &cases);
}

/// An output below an existing file (`--out notes.txt/out`) names the file and says it is not a
/// folder, before any work (it said `notes.txt: File exists (os error 17)`, or `Not a directory`
/// after rendering).
#[test]
fn outputs_inside_a_file_name_the_file() {
    let tmp = scratch("file-in-path");
    let d = tmp.path().to_str().unwrap();
    let file = format!("{d}/notes.txt");
    std::fs::write(&file, "not a folder").unwrap();
    let (inside, deeper, png) = (format!("{file}/out"), format!("{file}/a/out"), format!("{file}/out.png"));
    let room = "examples/room";
    let (assign, lights) = ("examples/room/materials.json", "examples/room/lights.json");
    let says = |dest: &str| format!("--out: {file}: is a file, not a folder, so {dest} cannot be written inside it");
    let cases = [
        (v(&["render", room, "--gbuffer", "--size", "8x6", "--out", &inside]), 2, vec![says(&inside)]),
        (v(&["render", room, "--spp", "1", "--size", "8x6", "--out", &png]), 2, vec![says(&png)]),
        (v(&["bake", "knit", "--size", "4", "--out", &deeper]), 2, vec![says(&deeper)]),
        (
            v(&["export", room, "--assign", assign, "--lights", lights, "--texture-size", "4", "--out", &inside]),
            2,
            vec![says(&inside)],
        ),
        (
            v(&["library", "--only", "knit", "--size", "8", "--sheet", &png]),
            2,
            vec![format!("--sheet: {file}: is a file, not a folder")],
        ),
    ];
    let cases: Vec<(Vec<String>, i32, Vec<&str>)> =
        cases.iter().map(|(a, c, w)| (a.clone(), *c, w.iter().map(String::as_str).collect())).collect();
    check(tmp.path(), &cases);
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "not a folder");
}

#[test]
fn library_and_bake_options_that_make_no_sense_are_usage_errors() {
    let tmp = scratch("library");
    let dir = tmp.path();
    let d = dir.to_str().unwrap();
    let file = format!("{d}/a_file.txt");
    std::fs::write(&file, "not a folder").unwrap();
    let cases = vec![
        (
            v(&["library", "--only", "zzz"]),
            2,
            vec!["--only: no graph's name or category contains 'zzz'", "categories: brick"],
        ),
        (v(&["library", "--sheet", &format!("{d}/s.jpg")]), 2, vec!["--sheet: expected a path ending in .png, got"]),
        (v(&["library", "--sheet", d]), 2, vec!["--sheet:", "is a directory"]),
        (v(&["library", "--size", "0"]), 2, vec!["--size", "'0'"]),
        (v(&["library", "--per-row", "0"]), 2, vec!["--per-row", "'0'"]),
        (v(&["bake", "knit", "--size", "0", "--out", &format!("{d}/b")]), 2, vec!["--size", "'0'"]),
        (v(&["bake", "knit", "--size", "4", "--out", &file]), 2, vec!["--out:", "is a file; expected a folder"]),
        (
            v(&["bake", "graphs", "--size", "4", "--out", &format!("{d}/b")]),
            1,
            vec!["graphs is a directory; expected a .psg file or the name"],
        ),
        (
            v(&["bake", "knit", "--size", "4", "--params", d, "--out", &format!("{d}/b")]),
            1,
            vec!["expected a JSON file, found a directory"],
        ),
        (
            v(&["bake", "oak_planks", "--name", "walnut", "--size", "4", "--out", &format!("{d}/b")]),
            1,
            vec!["contradicts"],
        ),
    ];
    check(dir, &cases);
}
