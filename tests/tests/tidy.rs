//! Tidy checks over the workspace's source, in the style of rust-analyzer's `tidy` test: rules
//! that ARCHITECTURE.md states, checked by code so they cannot silently rot.
//!
//! - Every Rust module opens with a `//!` doc.
//! - `unsafe` appears only in the files ARCHITECTURE.md lists (and justifies) under "Where
//!   `unsafe` is allowed"; every listed file still uses it; a crate without `unsafe` says
//!   `#![forbid(unsafe_code)]` at its root.
//! - Ground truth (a `truth` path component, `truth.json`, `scene_true`) appears in the string
//!   literals of library code only in the validation and evaluation modules allowed to read it
//!   (tests may read it freely).
//! - No crate depends upward: every `psc-*` dependency of every crate follows the documented
//!   order, which ARCHITECTURE.md states in the same words as [`ORDER`].

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The crate folders of the workspace, bottom up.
const CRATES: [&str; 11] =
    ["base", "grammar", "compiler", "jit", "render", "runtime", "fit", "export", "report", "cli", "tests"];

/// The documented dependency order (each chain as ARCHITECTURE.md writes it).
const ORDER: [&str; 4] = [
    "base → grammar → compiler → jit → runtime → fit → cli",
    "base → render → runtime",
    "runtime → export → cli",
    "base → render → report → cli",
];

/// Library files allowed to name ground truth in string literals: the validation module that
/// reads it for `psc render`'s explicit truth options, the CLI that offers them, and the fit's
/// evaluation. (Test code is free to.)
const TRUTH_READERS: [&str; 3] = ["render/src/truth.rs", "cli/src/render.rs", "fit/src/eval"];

fn root() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent().unwrap_or(here).to_path_buf()
}

/// Every `.rs` file under the crate folders (not `target/`), relative to the root.
fn rust_files() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else { return };
        for e in entries.flatten() {
            let p = e.path();
            let ty = e.file_type().unwrap();
            if ty.is_dir() && e.file_name() != "target" {
                walk(&p, out);
            } else if ty.is_file() && p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut out = Vec::new();
    for c in CRATES {
        walk(&root().join(c), &mut out);
    }
    let root = root();
    let mut rel: Vec<PathBuf> = out.iter().map(|p| p.strip_prefix(&root).unwrap().to_path_buf()).collect();
    rel.sort();
    assert!(rel.len() > 50, "found only {} Rust files under {}", rel.len(), root.display());
    rel
}

fn read(rel: &Path) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("{}: {e}", rel.display()))
}

fn slash(p: &Path) -> String {
    p.to_string_lossy().replace('\\', "/")
}

/// Library code: a crate's `src/` (not its `tests/`, `examples/` or `benches/`).
fn is_library_code(rel: &str) -> bool {
    rel.split('/').nth(1) == Some("src") && !rel.starts_with("tests/")
}

/// The code of a line without its `//` comment, and its string literals, each with the code
/// just before it (to see whether it is a path argument), roughly: enough for this
/// repository's sources (a `//` inside a string literal ends the code early, which only makes
/// the checks below miss, never report falsely).
fn code_and_strings(line: &str) -> (String, Vec<(String, String)>) {
    let mut code = String::new();
    let mut strings = Vec::new();
    let mut chars = line.chars().peekable();
    let mut in_str: Option<String> = None;
    while let Some(c) = chars.next() {
        match (&mut in_str, c) {
            (Some(s), '\\') => {
                s.push(c);
                if let Some(n) = chars.next() {
                    s.push(n);
                }
            }
            (Some(_), '"') => strings.push((code.clone(), in_str.take().unwrap())),
            (Some(s), _) => s.push(c),
            (None, '"') => in_str = Some(String::new()),
            (None, '/') if chars.peek() == Some(&'/') => break,
            (None, '\'') => {
                // A char literal such as '"' must not open a string; lifetimes pass through.
                code.push(c);
                let rest: String = chars.clone().take(3).collect();
                if rest.starts_with('\\') || rest.chars().nth(1) == Some('\'') {
                    for n in chars.by_ref() {
                        if n == '\'' {
                            break;
                        }
                    }
                }
            }
            (None, _) => code.push(c),
        }
    }
    (code, strings)
}

fn uses_unsafe(text: &str) -> bool {
    text.lines().any(|l| {
        let (code, _) = code_and_strings(l);
        code.match_indices("unsafe").any(|(i, _)| {
            let before = code[..i].chars().last();
            let after = code[i + 6..].chars().next();
            !before.is_some_and(|c| c.is_alphanumeric() || c == '_')
                && !after.is_some_and(|c| c.is_alphanumeric() || c == '_')
        })
    })
}

#[test]
fn every_module_opens_with_a_doc_comment() {
    let missing: Vec<String> =
        rust_files().iter().filter(|f| !read(f).trim_start().starts_with("//!")).map(|f| slash(f)).collect();
    assert!(missing.is_empty(), "these files do not open with a `//!` module doc:\n  {}", missing.join("\n  "));
}

/// The files ARCHITECTURE.md lists under its "Where `unsafe` is allowed" heading.
fn unsafe_allow_list(architecture: &str) -> BTreeSet<String> {
    let start = architecture.find("## Where `unsafe` is allowed").expect("ARCHITECTURE.md has a section on unsafe");
    let section = &architecture[start..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |i| i + 3)];
    section
        .lines()
        .filter_map(|l| l.strip_prefix("- `"))
        .filter_map(|l| l.split('`').next())
        .map(str::to_string)
        .collect()
}

#[test]
fn unsafe_only_where_architecture_md_allows_it() {
    let allowed = unsafe_allow_list(&read(Path::new("ARCHITECTURE.md")));
    assert!(!allowed.is_empty());
    let using: BTreeSet<String> = rust_files().iter().filter(|f| uses_unsafe(&read(f))).map(|f| slash(f)).collect();
    let unlisted: Vec<&String> = using.difference(&allowed).collect();
    assert!(unlisted.is_empty(), "`unsafe` in files ARCHITECTURE.md does not list and justify: {unlisted:?}");
    let stale: Vec<&String> = allowed.difference(&using).collect();
    assert!(stale.is_empty(), "ARCHITECTURE.md allows `unsafe` in files that no longer use it: {stale:?}");

    // A crate with no unsafe at all forbids it, so that none creeps in unlisted and unjustified.
    let mut missing = Vec::new();
    for c in CRATES {
        if using.iter().any(|f| f.starts_with(&format!("{c}/"))) {
            continue;
        }
        let lib = root().join(c).join("src/lib.rs");
        let main = root().join(c).join("src/main.rs");
        let root_file = if lib.is_file() { lib } else { main };
        let text = std::fs::read_to_string(&root_file).unwrap_or_default();
        if !text.contains("#![forbid(unsafe_code)]") {
            missing.push(slash(root_file.strip_prefix(root()).unwrap()));
        }
    }
    assert!(missing.is_empty(), "crates without unsafe code must say #![forbid(unsafe_code)] in {missing:?}");
}

#[test]
fn the_word_unsafe_is_found_only_in_code() {
    // The detector itself: comments, strings and lint names do not count.
    assert!(uses_unsafe("    let x = unsafe { f() };"));
    assert!(uses_unsafe("unsafe impl Send for K {}"));
    assert!(!uses_unsafe("//! the `unsafe` module"));
    assert!(!uses_unsafe("#![forbid(unsafe_code)]"));
    assert!(!uses_unsafe("let s = \"unsafe\";"));
    assert!(!uses_unsafe("let c = '\"'; let s = \"unsafe\";"));
}

/// Whether a string literal, with the code before it, names ground truth as a path: the files
/// `truth.json` and `scene_true.*`, a path with a `truth` component, or the bare word `truth`
/// handed to a path constructor (`join("truth")`). Comparing an argument with the word (the
/// `--lights truth` convention) reads nothing and does not count.
fn names_truth(before: &str, literal: &str) -> bool {
    let components: Vec<&str> = literal.split(['/', '\\']).collect();
    let path_call = ["join(", "new(", "from(", "push("].iter().any(|f| before.trim_end().ends_with(f));
    literal.contains("truth.json")
        || literal.contains("scene_true")
        || (components.len() > 1 && components.contains(&"truth"))
        || (literal == "truth" && path_call)
}

#[test]
fn truth_is_named_only_by_validation_and_evaluation_code() {
    let mut offenders = Vec::new();
    for f in rust_files() {
        let rel = slash(&f);
        if !is_library_code(&rel) || TRUTH_READERS.iter().any(|a| rel.starts_with(a)) {
            continue;
        }
        for (n, line) in read(&f).lines().enumerate() {
            let (_, strings) = code_and_strings(line);
            if strings.iter().any(|(before, s)| names_truth(before, s)) {
                offenders.push(format!("{rel}:{}: {}", n + 1, line.trim()));
            }
        }
    }
    assert!(
        offenders.is_empty(),
        "ground truth named outside {TRUTH_READERS:?} (only validation and evaluation may read it):\n  {}",
        offenders.join("\n  ")
    );
    assert!(names_truth("root.join(", "truth") && names_truth("", "a/truth/b.png") && names_truth("", "truth.json"));
    assert!(names_truth("Path::new(", "scene_true.obj"));
    assert!(
        !names_truth("if arg == ", "truth")
            && !names_truth("", "ground truth is not read")
            && !names_truth("", "truthy")
    );
}

/// Crate folder → the `psc-*` crates it may depend on (everything below it in [`ORDER`]).
fn allowed_dependencies() -> BTreeMap<&'static str, BTreeSet<&'static str>> {
    let mut below: BTreeMap<&str, BTreeSet<&str>> = CRATES.iter().map(|c| (*c, BTreeSet::new())).collect();
    // Repeat to a fixed point: chains share crates.
    for _ in 0..CRATES.len() {
        for chain in ORDER {
            let chain: Vec<&str> = chain.split(" → ").collect();
            for (i, c) in chain.iter().enumerate() {
                let mut set = below[c].clone();
                for lower in &chain[..i] {
                    set.insert(*lower);
                    set.extend(below[lower].iter().copied());
                }
                below.insert(c, set);
            }
        }
    }
    // The test crate is above everything.
    below.insert("tests", CRATES.iter().copied().filter(|c| *c != "tests").collect());
    below
}

fn folder_of(package: &str) -> Option<&'static str> {
    match package {
        "psc" => Some("cli"),
        "psc-tests" => Some("tests"),
        p => CRATES.iter().copied().find(|c| p.strip_prefix("psc-") == Some(c)),
    }
}

/// The `psc*` dependencies of a Cargo.toml, in every dependency table.
fn psc_dependencies(toml: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut in_deps = false;
    for line in toml.lines().map(str::trim) {
        if line.starts_with('[') {
            in_deps = line.trim_end_matches(']').ends_with("dependencies");
            continue;
        }
        if in_deps {
            let key = line.split(['=', '.', ' ']).next().unwrap_or("");
            if key == "psc" || key.starts_with("psc-") {
                out.insert(key.to_string());
            }
        }
    }
    out
}

#[test]
fn no_crate_depends_upward() {
    let architecture = read(Path::new("ARCHITECTURE.md"));
    for chain in ORDER {
        assert!(architecture.contains(chain), "ARCHITECTURE.md no longer states the order `{chain}`");
    }
    let allowed = allowed_dependencies();
    let mut wrong = Vec::new();
    for c in CRATES {
        let toml = read(&Path::new(c).join("Cargo.toml"));
        for dep in psc_dependencies(&toml) {
            match folder_of(&dep) {
                Some(d) if allowed[c].contains(d) => {}
                Some(d) => wrong.push(format!("{c} depends on {dep} ({d}/), which is not below it")),
                None => wrong.push(format!("{c} depends on {dep}, which is not a crate of the documented order")),
            }
        }
    }
    assert!(wrong.is_empty(), "dependencies against {ORDER:?}:\n  {}", wrong.join("\n  "));
    // The rule itself: runtime sits above render and jit, below fit; render only above base.
    assert!(allowed["runtime"].contains("render") && allowed["runtime"].contains("jit"));
    assert!(!allowed["runtime"].contains("fit") && !allowed["render"].contains("compiler"));
    assert_eq!(allowed["render"], BTreeSet::from(["base"]));
    assert_eq!(psc_dependencies("[dependencies]\npsc-base.workspace = true\nrayon = \"1\"\n[target.'cfg(unix)'.dependencies]\npsc = { path = \"x\" }"),
        BTreeSet::from(["psc".to_string(), "psc-base".to_string()]));
}
