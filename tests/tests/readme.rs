//! The README's example material compiles, and its typo'd variant gives the error the README
//! shows, so the first thing a new user copies cannot rot.

use std::path::Path;

use psc_compiler::{compile_text, Options};

fn readme() -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../README.md")).expect("README.md")
}

/// The first fenced block that defines a graph.
fn example_graph(readme: &str) -> String {
    let start = readme.find("```\nimport std.noise;").expect("the README shows an example graph") + 4;
    let end = start + readme[start..].find("```").expect("the block is closed");
    readme[start..end].to_string()
}

fn as_library_file() -> std::path::PathBuf {
    // Compiled as if it lived in the library, so `import std.noise` resolves.
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../graphs/concrete/my_plaster.psg")
}

#[test]
fn the_readme_example_compiles() {
    let text = example_graph(&readme());
    let out = compile_text(&as_library_file(), text, &Options::default());
    assert!(!out.has_errors(), "{}", out.render_diagnostics());
    assert_eq!(out.graphs.len(), 1);
    assert_eq!(out.graphs[0].info.name, "my_plaster");
}

#[test]
fn the_readme_typo_gives_the_error_it_shows() {
    let readme = readme();
    let text = example_graph(&readme).replace("fbm(", "fmb(");
    let out = compile_text(&as_library_file(), text, &Options::default());
    let rendered = out.render_diagnostics();
    assert!(out.has_errors());
    for line in ["error: unknown function `fmb`", "= hint: did you mean `fbm`?", "node n = fmb(uv, scale, octaves: 5)"]
    {
        assert!(rendered.contains(line), "missing {line:?} in:\n{rendered}");
        assert!(readme.contains(line.trim_start_matches("= ")), "the README no longer shows {line:?}");
    }
    assert!(rendered.contains("my_plaster.psg:10:14"), "{rendered}");
}
