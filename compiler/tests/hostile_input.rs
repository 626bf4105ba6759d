//! Input built to hurt the compiler as a whole (issue 14's classes): folder trees with link
//! loops, one graph name in two files, and more below. Each must end quickly with a clear
//! result; none of these tests asserts on time, but each would hang or fail without its fix.

use std::fs;
use std::path::{Path, PathBuf};

use psc_compiler::{compile_files, find_sources, Options};

/// A fresh folder under the system temp dir, removed when dropped.
struct Scratch(tempfile::TempDir);

impl Scratch {
    fn new(name: &str) -> Scratch {
        Scratch(tempfile::Builder::new().prefix(&format!("psc-hostile-{name}-")).tempdir().unwrap())
    }
    fn path(&self) -> &Path {
        self.0.path()
    }
    fn write(&self, rel: &str, text: &str) -> PathBuf {
        let path = self.path().join(rel);
        fs::create_dir_all(path.parent().unwrap()).unwrap();
        fs::write(&path, text).unwrap();
        path
    }
}

fn graph(name: &str) -> String {
    format!("graph {name} {{\n    output albedo = vec3(0.5)\n    output roughness = 0.5\n    output height = 0.0\n}}\n")
}

fn options(root: &Path) -> Options {
    Options { lib_root: Some(root.to_path_buf()) }
}

#[cfg(unix)]
#[test]
fn a_graphs_folder_with_link_loops_compiles_each_file_once() {
    use std::os::unix::fs::symlink;
    let dir = Scratch::new("loops");
    dir.write("a/x.psg", &graph("x"));
    dir.write("b/y.psg", &graph("y"));
    dir.write("top.psg", &graph("top"));
    symlink("..", dir.path().join("a/up")).unwrap();
    symlink("../a", dir.path().join("a/again")).unwrap();
    symlink("../b", dir.path().join("a/b_again")).unwrap();
    symlink("top.psg", dir.path().join("top_link.psg")).unwrap();
    let files = find_sources(dir.path()).unwrap();
    let names: Vec<_> = files.iter().map(|f| f.strip_prefix(dir.path()).unwrap().to_path_buf()).collect();
    assert_eq!(names, ["a/x.psg", "b/y.psg", "top.psg"].map(PathBuf::from));
    let out = compile_files(&files, &options(dir.path()));
    assert!(!out.has_errors(), "{}", out.render_diagnostics());
    let mut graphs: Vec<_> = out.graphs.iter().map(|g| g.info.name.as_str()).collect();
    graphs.sort();
    assert_eq!(graphs, ["top", "x", "y"]);
}

#[test]
fn one_file_given_twice_is_compiled_once() {
    let dir = Scratch::new("twice");
    let path = dir.write("g.psg", &graph("g"));
    let again = dir.path().join(".").join("g.psg");
    let out = compile_files(&[path.clone(), again, path], &options(dir.path()));
    assert!(!out.has_errors(), "{}", out.render_diagnostics());
    assert_eq!(out.graphs.len(), 1);
    assert_eq!(out.files.len(), 3);
    assert!(out.files.iter().all(|(_, ok)| *ok));
}

#[test]
fn one_graph_name_in_two_files_is_an_error_naming_both() {
    let dir = Scratch::new("clash");
    let a = dir.write("stone/oak.psg", &graph("oak"));
    let b = dir.write("wood/oak.psg", &format!("{}\n{}", graph("pine"), graph("oak")));
    let out = compile_files(&[a.clone(), b.clone()], &options(dir.path()));
    assert!(out.has_errors());
    let text = out.render_diagnostics();
    assert!(text.contains("graph `oak` is defined in two files"), "{text}");
    assert!(text.contains(&a.display().to_string()) && text.contains(&b.display().to_string()), "{text}");
    assert!(text.contains("first defined here"), "{text}");
    // The second file is the one in error; the first compiled.
    assert_eq!(out.files, vec![(a, true), (b, false)]);
    // Unique names across the same two files are fine.
    let c = dir.write("wood/pine.psg", &graph("birch"));
    let out = compile_files(&[c, dir.path().join("stone/oak.psg")], &options(dir.path()));
    assert!(!out.has_errors(), "{}", out.render_diagnostics());
}

/// `f0(x) = x`, `fK(x) = body(K)` for K = 1..=depth, and a graph whose albedo uses `f{depth}`.
fn nested_calls(depth: usize, body: impl Fn(usize) -> String) -> String {
    let mut src = String::from("fn f0(x: float) -> float { x }\n");
    for k in 1..=depth {
        src += &format!("fn f{k}(x: float) -> float {{ {} }}\n", body(k));
    }
    src + &format!(
        "graph g {{\n    output albedo = vec3(f{depth}(uv.x) * 0.001)\n    output roughness = 0.5\n    output height = 0.0\n}}\n"
    )
}

#[test]
fn exponential_inlining_fails_fast_at_a_call_with_the_graph_call_named() {
    let dir = Scratch::new("expo");
    let twice = |k: usize| format!("f{}(x) + f{}(x * 1.1)", k - 1, k - 1);
    // Fine at depth 10 (2^10 calls).
    let small = dir.write("small.psg", &nested_calls(10, twice));
    let out = compile_files(&[small], &options(dir.path()));
    assert!(!out.has_errors(), "{}", out.render_diagnostics());
    let work = out.graphs[0].stats.lowering_work;
    assert!(work > 1 << 10 && work < psc_compiler::lower::MAX_LOWERING_WORK, "{work}");
    // 2^40 calls: refused, not run for days. Nodes requested and calls without any node
    // (fK(x) = f(K-1)(f(K-1)(x))) both count.
    let nested = |k: usize| format!("f{}(f{}(x))", k - 1, k - 1);
    for (name, body) in [("adds", &twice as &dyn Fn(usize) -> String), ("no_nodes", &nested)] {
        let path = dir.write(&format!("{name}.psg"), &nested_calls(40, body));
        let out = compile_files(std::slice::from_ref(&path), &options(dir.path()));
        assert!(out.graphs.is_empty());
        let text = out.render_diagnostics();
        assert!(text.contains("budget exceeded here"), "{name}: {text}");
        // Located at a call inside a function, with the graph's call named as its origin.
        let d = &out.diagnostics[0];
        let (line, _) = out.sources.line_col(d.file, d.span.start);
        assert!((2..=41).contains(&line), "{name}: line {line}\n{text}");
        assert!(text.contains("inlined from this call in the graph"), "{name}: {text}");
        assert!(text.contains("f40(uv.x)"), "{name}: {text}");
    }
}

/// A loop body that adds no node (`max(x, x)` is `x`): only the work budget can stop it.
#[test]
fn nested_loops_run_out_of_budget_instead_of_running_for_hours() {
    let dir = Scratch::new("loops3");
    let src = "fn busy(x: float) -> float {\n    var acc = x;\n    for i in 0..1000 {\n        for j in 0..1000 {\n            for k in 0..1000 {\n                acc = max(acc, x);\n            }\n        }\n    }\n    acc\n}\ngraph g {\n    output albedo = vec3(busy(uv.x))\n    output roughness = 0.5\n    output height = 0.0\n}\n";
    let path = dir.write("loops.psg", src);
    let out = compile_files(&[path], &options(dir.path()));
    let text = out.render_diagnostics();
    assert!(out.has_errors() && text.contains("budget exceeded here"), "{text}");
}

/// A diagnostic on a 200 KB line shows a window around the span, not the line: for a syntax
/// error, a checker error deep in the line, and a huge unknown name.
#[test]
fn diagnostics_on_a_200_kb_line_stay_small() {
    let dir = Scratch::new("long");
    let spaces = " ".repeat(200_000);
    let cases = [
        format!("graph g {{\n    output albedo = vec3(0.5) 0.0{spaces}\n}}\n"),
        format!("graph g {{\n    output albedo = vec3({spaces}fmb(uv))\n    output roughness = 0.5\n    output height = 0.0\n}}\n"),
        format!("graph g {{\n    output albedo = vec3({})\n    output roughness = 0.5\n    output height = 0.0\n}}\n", "q".repeat(200_000)),
    ];
    for (k, src) in cases.iter().enumerate() {
        let path = dir.write(&format!("long{k}.psg"), src);
        let out = compile_files(&[path], &options(dir.path()));
        assert!(out.has_errors(), "case {k}");
        let text = out.render_diagnostics();
        assert!(text.len() < 2_000, "case {k}: {} bytes of diagnostics", text.len());
        assert!(text.contains('…'), "case {k}: {text}");
        // The header still gives the real line and column of the span.
        let d = &out.diagnostics[0];
        let (line, col) = out.sources.line_col(d.file, d.span.start);
        assert!(text.contains(&format!(":{line}:{col}")), "case {k}: {text}");
    }
}
