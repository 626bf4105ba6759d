//! `psc fit` on bad input, as a user meets it: every case ends with a clear message naming
//! the problem, exit code 1 (2 for an option past its limit, as for every usage error), no
//! panic, and no output folder (nor a staging folder beside it).
//! Each case is a scratch copy of the bundled example room with one thing broken.

use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "../../tests/src/folders.rs"]
mod folders;
use folders::copy_tree;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A scratch folder holding a copy of the example room at `<scratch>/room`, removed when the
/// returned guard is dropped.
fn room(case: &str) -> tempfile::TempDir {
    let dir = tempfile::Builder::new().prefix(&format!("psc-fit-bad-{case}-")).tempdir().unwrap();
    copy_tree(&repo().join("examples/room"), &dir.path().join("room"), &[]);
    dir
}

fn edit_scene(scratch: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let path = scratch.join("room/scene.json");
    let mut scene: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    edit(&mut scene);
    std::fs::write(&path, serde_json::to_string_pretty(&scene).unwrap()).unwrap();
}

/// Runs `psc fit <scratch>/room --out <scratch>/out extra…`, asserts the failure contract and
/// returns stderr.
fn fails(scratch: &Path, extra: &[&str]) -> String {
    let room = scratch.join("room");
    let out = scratch.join("out");
    let mut args = vec!["fit".to_string(), room.display().to_string(), "--out".into(), out.display().to_string()];
    args.extend(["--quiet", "--texture-size", "0", "--render-spp", "0"].map(String::from));
    args.extend(extra.iter().map(|s| s.to_string()));
    let run = Command::new(env!("CARGO_BIN_EXE_psc")).args(&args).output().unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert_eq!(run.status.code(), Some(1), "psc {}: {stderr}", args.join(" "));
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("error:"), "{stderr}");
    let leftovers: Vec<_> = std::fs::read_dir(scratch)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "room" && n != "existing" && n != "lights.json")
        .collect();
    assert!(leftovers.is_empty(), "left behind: {leftovers:?}");
    stderr
}

#[test]
fn label_image_of_another_size() {
    let tmp = room("labels-size");
    let s = tmp.path();
    image::GrayImage::new(160, 120).save(s.join("room/views/view0_parts.png")).unwrap();
    let err = fails(s, &[]);
    assert!(err.contains("160x120") && err.contains("320x240"), "{err}");
}

#[test]
fn missing_photo() {
    let tmp = room("no-photo");
    let s = tmp.path();
    std::fs::remove_file(s.join("room/views/view0.png")).unwrap();
    let err = fails(s, &[]);
    assert!(err.contains("view0.png"), "{err}");
}

#[test]
fn a_scene_without_views() {
    let tmp = room("no-views");
    let s = tmp.path();
    edit_scene(s, |v| v["views"] = serde_json::json!([]));
    let err = fails(s, &[]);
    assert!(err.contains("no views"), "{err}");
}

#[test]
fn a_camera_that_sees_nothing() {
    let tmp = room("looks-away");
    let s = tmp.path();
    edit_scene(s, |v| {
        v["views"][0]["camera"]["position"] = serde_json::json!([2.8, 1.4, 10.5]);
        v["views"][0]["camera"]["look_at"] = serde_json::json!([2.8, 1.4, 14.5]);
    });
    let err = fails(s, &["--refit-rounds", "0"]);
    assert!(err.contains("0 photo pixels agree with the model"), "{err}");
}

#[test]
fn forced_graphs_naming_unknown_parts_or_graphs() {
    let tmp = room("forced");
    let s = tmp.path();
    let err = fails(s, &["--graph", "sofa=walnut"]);
    assert!(err.contains("no part `sofa`") && err.contains("floor"), "{err}");
    let err = fails(s, &["--graph", "floor=no_such_graph"]);
    assert!(err.contains("no graph `no_such_graph`"), "{err}");
}

#[test]
fn light_files_with_bad_radiances() {
    let tmp = room("lights");
    let s = tmp.path();
    let path = s.join("lights.json");
    for (text, expect) in [
        (r#"{"lights":[{"name":"ceiling0","radiance_rgb":[NaN,1,1]}]}"#, "radiance_rgb"),
        (r#"{"lights":[{"name":"ceiling0","radiance_rgb":[-1,1,1]}]}"#, "negative"),
        (r#"{"lights":[{"name":"ceiling0","radiance_rgb":[1e999,1,1]}]}"#, "radiance_rgb"),
        (r#"{"lights":[{"name":"ceiling0","radiance_rgb":[1,1,1]}]}"#, "no radiance for light 'ceiling1'"),
        (
            r#"{"lights":[{"name":"ceiling0","radiance_rgb":[1,1,1]},{"name":"ceiling1","radiance_rgb":[1,1,1]},
               {"name":"ceiling2","radiance_rgb":[1,1,1]},{"name":"no_such_light","radiance_rgb":[1,1,1]}]}"#,
            "'no_such_light' is not in the scene",
        ),
        (
            r#"{"lights":[{"name":"ceiling0","radiance_rgb":0},{"name":"ceiling1","radiance_rgb":0},
               {"name":"ceiling2","radiance_rgb":0}],"environment_scale":0}"#,
            "every light's radiance is 0",
        ),
    ] {
        std::fs::write(&path, text).unwrap();
        let err = fails(s, &["--lights", path.to_str().unwrap()]);
        assert!(err.contains(expect), "{text}: {err}");
    }
}

/// Black photos: the light estimate finds no light, and nothing can be fitted under none.
#[test]
fn black_photos() {
    let tmp = room("black");
    let s = tmp.path();
    let photo = s.join("room/views/view0.png");
    let (w, h) = image::image_dimensions(&photo).unwrap();
    image::RgbImage::new(w, h).save(&photo).unwrap();
    let err = fails(s, &[]);
    assert!(err.contains("every light's radiance is 0") && err.contains("black"), "{err}");
}

#[test]
fn a_library_with_a_broken_graph() {
    let tmp = room("library");
    let s = tmp.path();
    let lib = s.join("room/lib");
    copy_tree(&repo().join("graphs"), &lib, &[]);
    std::fs::write(lib.join("broken.psg"), "graph broken { output albedo = ; }\n").unwrap();
    let err = fails(s, &["--lib", lib.to_str().unwrap()]);
    assert!(err.contains("broken.psg:1:"), "{err}");
}

#[test]
fn an_existing_output_folder_is_refused_before_any_work() {
    let tmp = room("exists");
    let s = tmp.path();
    let existing = s.join("existing");
    std::fs::create_dir_all(&existing).unwrap();
    std::fs::write(existing.join("keep.txt"), "mine").unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_psc"))
        .args(["fit", s.join("room").to_str().unwrap(), "--out", existing.to_str().unwrap(), "--quiet"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("already exists") && stderr.contains("--force"), "{stderr}");
    assert_eq!(std::fs::read_to_string(existing.join("keep.txt")).unwrap(), "mine");
}

#[test]
fn resume_or_refit_only_without_an_earlier_fit() {
    let tmp = room("no-previous");
    let s = tmp.path();
    for flag in ["--resume", "--refit-only"] {
        let err = fails(s, &[flag]);
        assert!(err.contains("result.json") && err.contains("earlier `psc fit`"), "{flag}: {err}");
    }
}

/// Sizes past the documented limits are usage errors (exit 2) before any work: a bake of
/// 10⁸×10⁸ texels used to abort on its allocation after the whole fit.
#[test]
fn sizes_past_the_limits_are_refused_before_any_work() {
    let tmp = room("huge");
    let s = tmp.path();
    for (option, value) in [("--texture-size", "100000000"), ("--render-spp", "4000000000")] {
        let run = Command::new(env!("CARGO_BIN_EXE_psc"))
            .args(["fit", s.join("room").to_str().unwrap(), "--out", s.join("out").to_str().unwrap(), "--quiet"])
            .args([option, value])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{option} {value}: {stderr}");
        assert!(stderr.contains(option) && stderr.contains("the limit is"), "{stderr}");
        assert!(!stderr.contains("panicked") && !stderr.contains("memory allocation"), "{stderr}");
        assert!(!s.join("out").exists(), "{option}: an output folder was made");
    }
}

/// A previous fit whose state no fit could reach (a hand-edited or damaged `result.json`) is
/// refused by `--resume` and `--refit-only`, naming the part and the value, and the previous
/// fit stays as it was: carried on, such a state made outputs no reader accepts (a UV
/// log-scale of 10⁶ wrote `"uv_scale": [null, null]`).
#[test]
fn resume_or_refit_only_from_a_state_no_fit_reaches() {
    let tmp = room("bad-state");
    let s = tmp.path();
    let (room, out) = (s.join("room"), s.join("out"));
    let mut args: Vec<String> =
        ["fit", room.to_str().unwrap(), "--out", out.to_str().unwrap()].map(String::from).to_vec();
    for part in ["floor", "ceiling", "walls", "rug", "crate_crate", "barrel_barrelS_D"] {
        args.extend(["--graph".into(), format!("{part}=homogeneous")]);
    }
    args.extend(
        ["--quiet", "--iterations", "10", "--refit-rounds", "0", "--texture-size", "0", "--render-spp", "0"]
            .map(String::from),
    );
    let run = Command::new(env!("CARGO_BIN_EXE_psc")).args(&args).output().unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let result_path = out.join("result.json");
    let good = std::fs::read_to_string(&result_path).unwrap();
    type Edit = fn(&mut serde_json::Value);
    let edits: [(&str, Edit, &str); 4] = [
        ("log-scale", |st| st["uv"]["log_scale"] = 1e6.into(), "UV transform"),
        ("albedo scale", |st| st["albedo_scale"] = serde_json::json!([-5.0, -5.0, -5.0]), "albedo scale"),
        ("roughness", |st| st["roughness"] = 0.0.into(), "roughness 0"),
        ("parameters", |st| st["params"][0] = 1e30.into(), "parameters"),
    ];
    for (what, edit, says) in edits {
        let mut result: serde_json::Value = serde_json::from_str(&good).unwrap();
        edit(&mut result["fit_state"]["parts"][0]["state"]);
        let damaged = serde_json::to_string_pretty(&result).unwrap();
        std::fs::write(&result_path, &damaged).unwrap();
        for flag in ["--resume", "--refit-only"] {
            let run = Command::new(env!("CARGO_BIN_EXE_psc"))
                .args(["fit", room.to_str().unwrap(), "--out", out.to_str().unwrap(), flag, "--quiet"])
                .output()
                .unwrap();
            let stderr = String::from_utf8_lossy(&run.stderr);
            assert_eq!(run.status.code(), Some(1), "{what} {flag}: {stderr}");
            assert!(stderr.contains("part `floor`") && stderr.contains(says), "{what} {flag}: {stderr}");
            assert_eq!(std::fs::read_to_string(&result_path).unwrap(), damaged, "{what} {flag}: the fit was replaced");
        }
    }
}
