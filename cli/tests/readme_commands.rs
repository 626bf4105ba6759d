//! Every command the README files show works: each `cargo run … -p psc -- …` and `psc …` line of
//! a shell block in README.md, examples/*/README.md and docs/scene-format.md is run (as the
//! built `psc`, in a scratch folder that links `examples/` and holds the README's example graph
//! as `my_plaster.psg`), must exit 0 and must write what its `--out` names.
//!
//! Two adjustments keep it quick and honest: `--spp` is lowered to 2 (a render's sample count
//! changes no option or file the command depends on), and `cargo test --release --workspace`
//! is not run (it is the command running this test) but must be what `.ci/run` runs. Commands
//! of other programs are run only if the program is installed; otherwise the test says loudly
//! that it skipped them.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent().unwrap_or(here).to_path_buf()
}

/// The documents whose commands must work.
fn documents() -> Vec<PathBuf> {
    let mut docs = vec![repo().join("README.md"), repo().join("docs/scene-format.md")];
    for e in std::fs::read_dir(repo().join("examples")).unwrap().flatten() {
        let readme = e.path().join("README.md");
        if readme.is_file() {
            docs.push(readme);
        }
    }
    docs
}

/// Shell commands of a Markdown text: lines of indented code blocks and of fenced blocks tagged
/// `sh`, `bash`, `shell` or `console`, with `\` continuations joined.
fn shell_commands(markdown: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut fence: Option<bool> = None; // Some(is_shell) inside a fenced block
    let mut pending = String::new();
    let mut previous_blank = true;
    let mut in_indented = false;
    for line in markdown.lines() {
        let trimmed = line.trim_start();
        if let Some(tag) = trimmed.strip_prefix("```") {
            fence = match fence {
                Some(_) => None,
                None => Some(matches!(tag.trim(), "sh" | "bash" | "shell" | "console")),
            };
            continue;
        }
        let code = match fence {
            Some(true) => Some(trimmed.trim_start_matches("$ ")),
            Some(false) => None,
            None => {
                let indented = line.starts_with("    ") && (in_indented || previous_blank);
                in_indented = indented || (in_indented && line.trim().is_empty());
                indented.then_some(trimmed)
            }
        };
        previous_blank = line.trim().is_empty();
        let Some(code) = code else { continue };
        pending.push_str(code.trim_end_matches('\\').trim());
        if code.ends_with('\\') {
            pending.push(' ');
        } else if !pending.is_empty() {
            out.push(std::mem::take(&mut pending));
        }
    }
    out
}

/// Splits a command line on whitespace (the README's commands use no quoting).
fn words(command: &str) -> Vec<String> {
    assert!(!command.contains(['"', '\'', '|', '>', ';', '&', '$']), "a README command needs a shell: {command}");
    command.split_whitespace().map(str::to_string).collect()
}

fn installed(program: &str) -> bool {
    std::env::var_os("PATH").is_some_and(|paths| std::env::split_paths(&paths).any(|d| d.join(program).is_file()))
}

/// The arguments of `psc` for a `cargo run … -p psc -- ARGS` or `psc ARGS` command, else None.
fn psc_args(w: &[String]) -> Option<Vec<String>> {
    if w.first()? == "psc" {
        return Some(w[1..].to_vec());
    }
    if w.len() > 2 && w[0] == "cargo" && w[1] == "run" {
        let dashes = w.iter().position(|x| x == "--")?;
        let package = w.iter().position(|x| x == "-p").and_then(|i| w.get(i + 1));
        assert_eq!(package.map(String::as_str), Some("psc"), "`cargo run` of another package: {}", w.join(" "));
        return Some(w[dashes + 1..].to_vec());
    }
    None
}

/// The README's example graph, as the README shows it.
fn example_graph() -> String {
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let start = readme.find("```\nimport std.noise;").expect("the README shows an example graph") + 4;
    let end = start + readme[start..].find("```").unwrap();
    readme[start..end].to_string()
}

#[test]
fn every_command_in_the_readme_files_works() {
    let tmp = tempfile::Builder::new().prefix("psc-readme-commands-").tempdir().unwrap();
    let work = tmp.path();
    std::os::unix::fs::symlink(repo().join("examples"), work.join("examples")).unwrap();
    std::fs::write(work.join("my_plaster.psg"), example_graph()).unwrap();

    let ci = std::fs::read_to_string(repo().join(".ci/run")).unwrap();
    let mut ran = 0;
    let mut failures = Vec::new();
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        for command in shell_commands(&text) {
            let w = words(&command);
            let where_ = format!("{}: {command}", doc.strip_prefix(repo()).unwrap().display());
            if w[0] == "cargo" && w.get(1).map(String::as_str) == Some("test") {
                assert!(ci.lines().any(|l| l.trim() == command), "{where_}: not what .ci/run runs");
                continue;
            }
            let Some(mut args) = psc_args(&w) else {
                if !installed(&w[0]) {
                    let _ = writeln!(
                        std::io::stderr(),
                        "\n*** NOT RUN: {where_} needs `{}`, which is not installed ***\n",
                        w[0]
                    );
                } else if w[0] == "cargo" {
                    failures.push(format!("{where_}: a cargo command this test does not know how to run"));
                }
                continue;
            };
            if args[0] == "fit" {
                // The command as written takes minutes; that it runs at all is what is checked
                // here (fit quality has tests of its own).
                for (option, value) in [
                    ("--iterations", "10"),
                    ("--exemplars", "1"),
                    ("--texture-size", "16"),
                    ("--render-spp", "1"),
                    ("--refit-rounds", "1"),
                ] {
                    if !args.iter().any(|a| a == option) {
                        args.extend([option.to_string(), value.to_string()]);
                    }
                }
            }
            if let Some(i) = args.iter().position(|a| a == "--spp") {
                if args[i + 1].parse::<u32>().is_ok_and(|n| n > 2) {
                    args[i + 1] = "2".into();
                }
            }
            let out = Command::new(env!("CARGO_BIN_EXE_psc")).args(&args).current_dir(work).output().unwrap();
            ran += 1;
            if !out.status.success() {
                failures.push(format!(
                    "{where_}\n  exit {:?}: {}",
                    out.status.code(),
                    String::from_utf8_lossy(&out.stderr)
                ));
                continue;
            }
            if let Some(i) = args.iter().position(|a| a == "--out") {
                if !work.join(&args[i + 1]).exists() {
                    failures.push(format!("{where_}\n  succeeded but wrote no {}", args[i + 1]));
                }
            }
        }
    }
    assert!(failures.is_empty(), "README commands that fail:\n{}", failures.join("\n"));
    assert!(ran >= 4, "only {ran} commands found: is the extraction still right?");
}

#[test]
fn commands_are_found_in_indented_and_shell_blocks_only() {
    let md = "Text `psc inline` is not a command.\n\n    psc render a \\\n        --out b.png\n\n```sh\n$ psc bake knit\n```\n\n```\npsc not-shell\n```\n\n    cargo test --release --workspace\n";
    assert_eq!(shell_commands(md), ["psc render a --out b.png", "psc bake knit", "cargo test --release --workspace"]);
    let w = words("cargo run --release -p psc -- render x --out y.png");
    assert_eq!(psc_args(&w).unwrap(), ["render", "x", "--out", "y.png"]);
}
