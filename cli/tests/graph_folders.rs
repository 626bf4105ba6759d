//! `psc` on hostile graph input, as a user meets it: folders with link loops, one graph name in
//! two library files, exponential inlining, a 200 KB source line. Each ends with a clear
//! result (exit 0 or 1 and a short message), never a hang or a flood.

use std::path::Path;
use std::process::{Command, Output};

fn psc(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_psc")).args(args).current_dir(dir).output().expect("psc runs")
}

/// A fresh scratch folder per test, removed when dropped.
struct Scratch(tempfile::TempDir);

impl Scratch {
    fn new(name: &str) -> Scratch {
        Scratch(tempfile::Builder::new().prefix(&format!("psc-cli-folders-{name}-")).tempdir().unwrap())
    }
    fn path(&self) -> &Path {
        self.0.path()
    }
    fn write(&self, rel: &str, text: &str) {
        let path = self.path().join(rel);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }
}

fn graph(name: &str) -> String {
    format!("graph {name} {{\n    output albedo = vec3(0.5)\n    output roughness = 0.5\n    output height = 0.0\n}}\n")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[cfg(unix)]
#[test]
fn compile_walks_a_folder_with_link_loops_once() {
    use std::os::unix::fs::symlink;
    let dir = Scratch::new("loops");
    dir.write("a/x.psg", &graph("x"));
    dir.write("y.psg", &graph("y"));
    symlink("..", dir.path().join("a/up")).unwrap();
    symlink("../a", dir.path().join("a/again")).unwrap();
    let out = psc(&["compile", "--lib", ".", "."], dir.path());
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(stdout.contains("2 graphs from 2 files"), "{stdout}");
    assert_eq!(stdout.matches("graph x ").count(), 1, "{stdout}");
}

#[test]
fn bake_refuses_a_name_two_library_files_define_and_names_both() {
    let dir = Scratch::new("clash");
    dir.write("lib/std/empty.psg", "");
    dir.write("lib/stone/oak.psg", &graph("oak"));
    dir.write("lib/wood/oak.psg", &graph("oak"));
    let out = psc(&["bake", "oak", "--lib", "lib", "--size", "8", "--out", "out"], dir.path());
    assert_eq!(out.status.code(), Some(1));
    let stderr = text(&out.stderr);
    assert!(stderr.contains("graph `oak` is defined in two files"), "{stderr}");
    assert!(stderr.contains("stone/oak.psg") && stderr.contains("wood/oak.psg"), "{stderr}");
    assert!(!dir.path().join("out").exists(), "nothing is written");
}

#[test]
fn compile_refuses_exponential_inlining_with_a_located_error() {
    let dir = Scratch::new("expo");
    let mut src = String::from("fn f0(x: float) -> float { x }\n");
    for k in 1..=40 {
        src += &format!("fn f{k}(x: float) -> float {{ f{}(x) + f{}(x * 1.1) }}\n", k - 1, k - 1);
    }
    src += "graph g {\n    output albedo = vec3(f40(uv.x))\n    output roughness = 0.5\n    output height = 0.0\n}\n";
    dir.write("expo.psg", &src);
    let out = psc(&["compile", "expo.psg"], dir.path());
    assert_eq!(out.status.code(), Some(1));
    let stderr = text(&out.stderr);
    assert!(stderr.contains("budget exceeded here") && stderr.contains("expo.psg:"), "{stderr}");
}

#[test]
fn a_diagnostic_on_a_200_kb_line_prints_a_window_of_it() {
    let dir = Scratch::new("long");
    let src = format!("graph g {{\n    output albedo = vec3({}fmb(uv))\n}}\n", " ".repeat(200_000));
    dir.write("long.psg", &src);
    let out = psc(&["compile", "long.psg"], dir.path());
    assert_eq!(out.status.code(), Some(1));
    let stderr = text(&out.stderr);
    assert!(stderr.len() < 4_000, "{} bytes on stderr", stderr.len());
    assert!(stderr.contains("long.psg:2:200026") && stderr.contains('…'), "{stderr}");
}
