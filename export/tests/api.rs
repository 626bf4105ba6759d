//! `psc_export::export` and `write_all` as a library: refused inputs leave nothing behind, and
//! the same inputs give the same bytes. (The formats themselves are checked end to end in
//! `cli/tests/export.rs`.)

use std::path::{Path, PathBuf};

use psc_base::output::Replace;
use psc_export::{export, ExportError, ExportOptions};
use psc_render::scene::Scene;
use psc_render::LightRadiances;
use psc_runtime::assign::{Assignment, PartMaterial, UvTransform};
use psc_runtime::library::Library;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-export-api-{name}-")).tempdir().unwrap()
}

/// The example room, a one-graph library (homogeneous) and an assignment of it to the floor
/// (rotated, scaled) and the walls.
fn inputs() -> (Scene, Library, Assignment, LightRadiances) {
    let scene = Scene::load(&root().join("examples/room")).unwrap();
    let library = Library::compile(
        &[root().join("graphs/homogeneous.psg")],
        &psc_compiler::Options { lib_root: Some(root().join("graphs")) },
    )
    .unwrap();
    let mut assignment = Assignment::default();
    let mut floor = PartMaterial::new("homogeneous");
    floor.uv = UvTransform { scale: [2.0, 2.0], offset: [0.1, 0.2], rotation_deg: 30.0 };
    floor.albedo_scale = [0.9, 0.8, 0.7];
    assignment.parts.insert("floor".into(), floor);
    assignment.parts.insert("walls".into(), PartMaterial::new("homogeneous"));
    let mut warnings = Vec::new();
    let lights = LightRadiances::from_file(&root().join("examples/room/lights.json"), &scene, &mut warnings).unwrap();
    (scene, library, assignment, lights)
}

#[test]
fn refused_inputs_leave_nothing() {
    let (scene, library, assignment, lights) = inputs();
    let tmp = scratch("refused");
    let dir = tmp.path();
    let dest = dir.join("out");
    let options = ExportOptions { texture_size: 8 };

    let mut nan = lights.clone();
    nan.lights[1][2] = f32::NAN;
    let e = export(&dest, Replace::No, &scene, &library, &assignment, &nan, &options).unwrap_err();
    assert!(matches!(&e, ExportError::Input(m) if m.contains("ceiling1")), "{e}");

    let mut unknown = assignment.clone();
    unknown.parts.insert("sofa".into(), PartMaterial::new("homogeneous"));
    let e = export(&dest, Replace::No, &scene, &library, &unknown, &lights, &options).unwrap_err();
    assert!(e.to_string().contains("sofa"), "{e}");

    let mut graph = assignment.clone();
    graph.parts.insert("rug".into(), PartMaterial::new("oak_planks"));
    let e = export(&dest, Replace::No, &scene, &library, &graph, &lights, &options).unwrap_err();
    assert!(e.to_string().contains("oak_planks"), "{e}");

    let e = export(&dest, Replace::No, &scene, &library, &assignment, &lights, &ExportOptions { texture_size: 0 })
        .unwrap_err();
    assert!(e.to_string().contains("texture size"), "{e}");

    let left: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn the_same_inputs_give_the_same_bytes() {
    let (scene, library, assignment, lights) = inputs();
    let tmp = scratch("determinism");
    let dir = tmp.path();
    let options = ExportOptions { texture_size: 16 };
    let a = export(&dir.join("a"), Replace::No, &scene, &library, &assignment, &lights, &options).unwrap();
    let b = export(&dir.join("b"), Replace::No, &scene, &library, &assignment, &lights, &options).unwrap();
    assert_eq!(a.files, b.files);
    assert_eq!(a.parts, scene.mesh.part_names.len());
    // Unassigned parts with a map_Kd would warn; the example's MTL has none, so no warnings.
    assert!(a.warnings.is_empty(), "{:?}", a.warnings);
    for f in &a.files {
        let (x, y) = (std::fs::read(dir.join("a").join(f)).unwrap(), std::fs::read(dir.join("b").join(f)).unwrap());
        assert!(x == y, "{} differs between two exports", f.display());
    }
    assert!(a.files.iter().any(|f| f == Path::new("scene.gltf")));
    assert!(a.files.iter().any(|f| f == Path::new("scene_mitsuba.xml")));
}
