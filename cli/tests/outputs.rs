//! Output sets are whole or absent: a bake is written into a staged folder and appears at once;
//! an existing folder is refused unless `--force`, and then replaced whole (never a mix of old
//! and new files); a bake that fails part-way leaves nothing, not even temporaries.

use std::path::Path;
use std::process::{Command, Output};

fn psc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_psc"))
        .args(args)
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .output()
        .expect("psc runs")
}

fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-outputs-test-{name}-")).tempdir().unwrap()
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|d| d.map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect())
        .unwrap_or_default();
    v.sort();
    v
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn an_existing_bake_folder_is_refused_or_replaced_whole() {
    let tmp = scratch("force");
    let dir = tmp.path();
    let out = dir.join("maps");
    let o = psc(&["bake", "knit", "--size", "8", "--random", "1", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let first = names(&out);
    assert_eq!(first.len(), 12, "{first:?}");
    std::fs::write(out.join("mine.txt"), "a file of the user's").unwrap();

    // Without --force: refused before any work, folder untouched.
    let o = psc(&["bake", "plaster", "--size", "8", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("already exists") && stderr(&o).contains("--force"), "{}", stderr(&o));
    assert!(out.join("mine.txt").is_file() && names(&out).len() == 13);

    // With --force: the new set replaces the old one whole.
    let o = psc(&["bake", "plaster", "--size", "8", "--out", out.to_str().unwrap(), "--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let now = names(&out);
    assert!(now.iter().all(|n| n.starts_with("plaster_")), "old files left beside new ones: {now:?}");
    assert_eq!(names(dir), ["maps"], "no temporaries beside the output");
}

#[test]
fn a_bake_that_fails_part_way_leaves_nothing() {
    let tmp = scratch("partial");
    let dir = tmp.path();
    // At its default the graph is finite; a random variant with `blow = 1` gives an infinite
    // height, which the bake refuses after the first maps were written.
    let graph = dir.join("fragile.psg");
    std::fs::write(
        &graph,
        "graph fragile {\n    param blow = 0 in [0, 1] int\n    output albedo = 0.5\n    output roughness = 0.5\n    output height = (uv.x + 1.0) / (1.0 - blow)\n}\n",
    )
    .unwrap();
    let out = dir.join("maps");
    let o = Command::new(env!("CARGO_BIN_EXE_psc"))
        .args(["bake", graph.to_str().unwrap(), "--size", "8", "--random", "8", "--out", out.to_str().unwrap()])
        .env("PSC_PROGRESS_SECONDS", "0")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("fragile_random") && stderr(&o).contains("non-finite"), "{}", stderr(&o));
    assert!(stderr(&o).contains("bake: 10% (1/9"), "the defaults were baked and written first: {}", stderr(&o));
    assert!(!out.exists(), "a failed bake left {:?}", names(&out));
    assert_eq!(names(dir), ["fragile.psg"], "temporaries left behind");
}

/// Copies the bundled example room (its small files) into `dest`.
fn copy_example_room(dest: &Path) {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/room");
    fn copy(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(from).unwrap() {
            let e = e.unwrap();
            let target = to.join(e.file_name());
            if e.file_type().unwrap().is_dir() {
                copy(&e.path(), &target);
            } else {
                std::fs::copy(e.path(), &target).unwrap();
            }
        }
    }
    copy(&src, dest);
}

/// `--force` replaces an output folder, never the inputs: an output folder that is, or holds,
/// the scene (or another input) is refused before any work, and the inputs stay whole. An
/// evaluation replaces only a previous evaluation.
#[test]
fn an_output_folder_that_holds_an_input_is_refused_even_with_force() {
    let tmp = scratch("inputs");
    let top = tmp.path().join("top");
    let scene = top.join("scene");
    copy_example_room(&scene);
    let before = names(&scene);
    let (top_s, scene_s) = (top.to_str().unwrap(), scene.to_str().unwrap());
    for args in [
        vec!["fit", scene_s, "--out", scene_s, "--force", "--quiet"],
        vec!["fit", scene_s, "--out", top_s, "--force", "--quiet"],
        vec!["render", scene_s, "--gbuffer", "--out", top_s, "--force"],
        vec!["export", scene_s, "--assign", "a.json", "--lights", "l.json", "--out", scene_s, "--force"],
    ] {
        let o = psc(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("the input") && stderr(&o).contains("would delete it"), "{args:?}: {}", stderr(&o));
        assert_eq!(names(&scene), before, "{args:?} touched the scene");
    }

    // `psc eval --eval-dir`: a folder that is not a previous evaluation is kept.
    let mine = tmp.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("keep.txt"), "a file of the user's").unwrap();
    let fit = tmp.path().join("fit");
    std::fs::create_dir(&fit).unwrap();
    for dir in [&mine, &scene] {
        let o = psc(&["eval", fit.to_str().unwrap(), scene_s, "--eval-dir", dir.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains("--eval-dir"), "{}", stderr(&o));
    }
    assert_eq!(names(&mine), ["keep.txt"]);
    assert_eq!(names(&scene), before);
}

/// A reader that goes away (`psc fit ... 2>&1 | head -1`, `psc library | head -1`) stops psc as
/// SIGPIPE stops any Unix tool (killed by the signal: a non-zero status, 141 in a shell), and
/// its staged output goes with it: the fit's staging folder was left behind as `.psc-tmp-*`,
/// because the default action ended the process before anything could remove it.
#[cfg(unix)]
#[test]
fn a_closed_pipe_stops_psc_and_leaves_no_temporaries() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    let tmp = scratch("sigpipe");
    let dir = tmp.path();
    let out = dir.join("fit");
    let room = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/room");
    let fit = [
        "fit",
        room.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--iterations",
        "5",
        "--refit-rounds",
        "0",
        "--texture-size",
        "0",
        "--render-spp",
        "0",
    ];
    // The fit's progress log (stderr, not a terminal) starts once its output folder is staged;
    // stdout closed too (`library` prints its table there, with nothing staged).
    for (args, closed) in [(&fit[..], "stderr"), (&["library"][..], "stdout")] {
        let mut command = Command::new(env!("CARGO_BIN_EXE_psc"));
        command.args(args).stdin(Stdio::null());
        if closed == "stderr" {
            command.stdout(Stdio::null()).stderr(Stdio::piped());
        } else {
            command.stdout(Stdio::piped()).stderr(Stdio::null());
        }
        let mut child = command.spawn().expect("psc runs");
        // Close the read end before psc writes anything.
        drop(child.stderr.take());
        drop(child.stdout.take());
        let status = child.wait().unwrap();
        assert_eq!(status.signal(), Some(libc::SIGPIPE), "{args:?} with {closed} closed: {status:?}");
        assert_eq!(names(dir), Vec::<String>::new(), "{args:?} with {closed} closed left files behind");
    }
}
