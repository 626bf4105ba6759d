//! docs/scene-format.md stays true to the code: each of its JSON examples is read by the reader
//! it documents (lights files, assignments, cameras, the manifest), and the limits it states are
//! the ones `psc_base::limits` enforces.

use std::path::{Path, PathBuf};

use psc_render::camera::load_camera_file;
use psc_render::LightsFile;
use psc_runtime::assign::Assignment;

fn repo() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent().unwrap_or(here).to_path_buf()
}

fn doc() -> String {
    std::fs::read_to_string(repo().join("docs/scene-format.md")).expect("docs/scene-format.md")
}

/// The first ```json block after the heading that starts with `heading`.
fn json_after(doc: &str, heading: &str) -> String {
    let at = doc.find(&format!("\n## {heading}")).unwrap_or_else(|| panic!("no heading `{heading}`"));
    let start = at + doc[at..].find("```json\n").expect("a JSON example") + 8;
    let end = start + doc[start..].find("```").unwrap();
    doc[start..end].to_string()
}

/// A file holding `text` in a fresh folder; the folder goes when the returned guard is dropped.
fn scratch_file(name: &str, text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::Builder::new().prefix("psc-docs-test-").tempdir().unwrap();
    let p = dir.path().join(name);
    std::fs::write(&p, text).unwrap();
    (dir, p)
}

#[test]
fn the_lights_example_is_a_valid_lights_file() {
    let text = json_after(&doc(), "Lights files");
    let file = LightsFile::parse(Path::new("doc-example.json"), &text).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(file.lights.len(), 2);
}

#[test]
fn the_assignment_example_is_a_valid_assignment() {
    let text = json_after(&doc(), "Material assignments");
    let value = psc_runtime::json::parse(text.as_bytes()).unwrap_or_else(|e| panic!("{e:?}"));
    let a = Assignment::from_json(&value).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(a.parts["floor"].uv.scale, [2.0, 2.0]);
    // And it binds: its graphs and parameters exist in the library.
    let lib = psc_runtime::library::Library::load(&psc_runtime::library::default_library_root()).unwrap();
    for (name, part) in &a.parts {
        part.resolve(&lib).unwrap_or_else(|e| panic!("{name}: {e:?}"));
    }
}

#[test]
fn the_camera_example_is_a_valid_camera_file() {
    let (_dir, path) = scratch_file("camera.json", &json_after(&doc(), "Camera files"));
    let cam = load_camera_file(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(cam.size, Some((320, 240)));
}

#[test]
fn the_manifest_example_has_only_fields_the_loader_knows() {
    // The example names files that do not exist, so it cannot load; what must hold is that a
    // real manifest with the same fields loads: the example room's, extended by every optional
    // field of the example, minus the files.
    let text = json_after(&doc(), "scene.json");
    let example: serde_json::Value = serde_json::from_str(&text).unwrap();
    let room: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(repo().join("examples/room/scene.json")).unwrap()).unwrap();
    let keys = |v: &serde_json::Value| -> Vec<String> { v.as_object().unwrap().keys().cloned().collect() };
    for k in keys(&example) {
        assert!(
            ["format", "units", "up", "mesh", "views", "lights", "environment"].contains(&k.as_str()),
            "the example shows a field `{k}` the manifest does not have"
        );
    }
    for k in keys(&example["views"][0]) {
        assert!(room["views"][0].get(&k).is_some(), "view field `{k}` not in a real scene");
    }
}

#[test]
fn the_limits_table_states_the_enforced_limits() {
    use psc_base::limits::*;
    let doc = doc();
    let table = &doc[doc.find("## Limits").unwrap()..doc.find("## Ground truth").unwrap()];
    let row =
        |what: &str| table.lines().find(|l| l.contains(what)).unwrap_or_else(|| panic!("no row `{what}`")).to_string();
    assert_eq!(MAX_PIXELS, 1 << 26);
    assert!(row("pixels of one image").contains("2²⁶"));
    assert_eq!(MAX_TEXELS, 1 << 26);
    assert!(row("texels of one bake").contains("2²⁶"));
    assert!(row("samples per pixel").contains(&group(MAX_SPP)));
    assert!(row("paths per light-grid bin").contains(&group(MAX_GRID_SAMPLES)));
    assert!(row("worker threads").contains(&MAX_THREADS.to_string()));
    assert!(row("random variants").contains(&group(MAX_VARIANTS)));
    assert!(row("JSON input files").contains(&format!("{} MiB", psc_runtime::json::MAX_JSON_BYTES >> 20)));
    assert!(table.contains(&format!("{} GiB", MEMORY_BUDGET >> 30)));
}

/// `n` with thin-space thousands groups, as the table writes them ("65 536").
fn group(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(' ');
        }
        out.push(c);
    }
    out
}
