//! Opening a scene for a view (`psc_runtime::view`) and finding a graph by file or name
//! (`psc_runtime::lookup`): the choices the CLI offers, as library calls. Ground truth is read
//! only when a choice names it: a scene whose `truth/` is garbage opens fine otherwise.

use std::path::{Path, PathBuf};

use psc_base::progress::NoProgress;
use psc_render::LightsSource;
use psc_runtime::lookup::{find_graph, LookupError};
use psc_runtime::view::{open_view, CameraChoice, GeometryChoice, MaterialsChoice, OpenError, ViewRequest};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-view-test-{name}-")).tempdir().unwrap()
}

/// A copy of the example room (small: an OBJ, an MTL, a photo, labels, three lamps).
fn copy_room(to: &Path) {
    let from = repo().join("examples/room");
    for rel in [
        "scene.json",
        "room.obj",
        "room.mtl",
        "lights.json",
        "materials.json",
        "views/view0.png",
        "views/view0_parts.png",
        "lights/ceiling0.obj",
        "lights/ceiling1.obj",
        "lights/ceiling2.obj",
    ] {
        std::fs::create_dir_all(to.join(rel).parent().unwrap()).unwrap();
        std::fs::copy(from.join(rel), to.join(rel)).unwrap();
    }
}

fn room_request() -> ViewRequest {
    ViewRequest { scene: repo().join("examples/room"), ..Default::default() }
}

#[test]
fn defaults_are_the_first_view_the_model_the_mtl_and_unit_lights() {
    let v = open_view(&room_request(), None, &NoProgress).unwrap();
    let photo = &v.scene.views[0];
    assert_eq!((v.width, v.height), (photo.width, photo.height));
    assert_eq!(v.camera.position.to_array(), photo.camera.position.to_array());
    assert_eq!(v.materials.len(), v.scene.mesh.part_names.len());
    assert!(v.radiances.lights.iter().all(|r| *r == [1.0; 3]));
    assert!(v.radiances.source.contains("unit radiance"), "{}", v.radiances.source);
    assert!(v.warnings.iter().any(|w| w.contains("no lights file given")), "{:?}", v.warnings);
}

#[test]
fn size_camera_file_assignment_and_lights_file_are_applied() {
    let tmp = scratch("choices");
    let dir = tmp.path();
    let cam = dir.join("cam.json");
    std::fs::write(
        &cam,
        r#"{"position": [2, 1.5, 4], "look_at": [2, 1, 0], "fov_y_deg": 60, "width": 40, "height": 30}"#,
    )
    .unwrap();
    let room = repo().join("examples/room");
    let req = ViewRequest {
        camera: CameraChoice::File(cam.clone()),
        assign: Some(room.join("materials.json")),
        lights: LightsSource::File(room.join("lights.json")),
        ..room_request()
    };
    let v = open_view(&req, None, &NoProgress).unwrap();
    assert_eq!((v.width, v.height), (40, 30), "the camera file's size");
    assert_eq!(v.radiances.lights[0], [39.3, 38.5, 37.6]);
    let floor = v.scene.mesh.part_names.iter().position(|p| p == "floor").unwrap();
    assert_eq!(v.materials[floor].uv_transform[0][0], 2.0, "the assignment's uv_scale");
    let v = open_view(&ViewRequest { size: Some((8, 6)), ..req }, None, &NoProgress).unwrap();
    assert_eq!((v.width, v.height, v.camera.width), (8, 6, 8), "an explicit size wins");
}

#[test]
fn unknown_views_and_missing_truth_are_errors() {
    let e = open_view(&ViewRequest { camera: CameraChoice::View("view9".into()), ..room_request() }, None, &NoProgress);
    assert!(matches!(&e, Err(OpenError::NoSuchView { known, .. }) if known == &["view0"]));
    for req in [
        ViewRequest { geometry: GeometryChoice::Truth, ..room_request() },
        ViewRequest { materials: MaterialsChoice::Truth, ..room_request() },
        ViewRequest { lights: LightsSource::Truth, ..room_request() },
    ] {
        let e = open_view(&req, None, &NoProgress).err().expect("the example has no ground truth");
        assert!(e.to_string().contains("asked for the true") || e.to_string().contains("truth"), "{e}");
    }
}

/// A scene with an unreadable truth/ opens with every default choice (so nothing read it),
/// and fails, naming the truth file, exactly when a choice asks for truth.
#[test]
fn truth_is_read_only_when_asked_for_by_name() {
    let tmp = scratch("truth");
    let dir = tmp.path();
    copy_room(dir);
    std::fs::create_dir_all(dir.join("truth")).unwrap();
    std::fs::write(dir.join("truth/truth.json"), "this is not JSON").unwrap();
    std::fs::write(dir.join("truth/scene_true.obj"), "v garbage\nf 1 2 3\n").unwrap();
    let req = ViewRequest {
        scene: dir.to_path_buf(),
        assign: Some(dir.join("materials.json")),
        lights: LightsSource::File(dir.join("lights.json")),
        ..Default::default()
    };
    let v = open_view(&req, None, &NoProgress).expect("truth/ is not read");
    assert!(v.warnings.iter().all(|w| !w.contains("truth")), "{:?}", v.warnings);
    for (what, req) in [
        ("lights", ViewRequest { lights: LightsSource::Truth, ..req.clone() }),
        ("materials", ViewRequest { materials: MaterialsChoice::Truth, ..req.clone() }),
        ("geometry", ViewRequest { geometry: GeometryChoice::Truth, ..req.clone() }),
    ] {
        let e = open_view(&req, None, &NoProgress).err().unwrap_or_else(|| panic!("{what}: truth/ is broken"));
        assert!(e.to_string().contains("truth"), "{what}: {e}");
    }
}

#[test]
fn graphs_are_found_by_file_or_library_name() {
    let tmp = scratch("lookup");
    let dir = tmp.path();
    let file = dir.join("two.psg");
    std::fs::write(
        &file,
        "graph first { output albedo = 0.2\n output roughness = 0.5\n output height = 0.0 }\ngraph second { output albedo = 0.7\n output roughness = 0.5\n output height = 0.0 }\n",
    )
    .unwrap();
    let f = file.to_str().unwrap();
    assert_eq!(find_graph(f, None, None).unwrap().info.name, "first");
    assert_eq!(find_graph(f, Some("second"), None).unwrap().info.name, "second");
    assert!(
        matches!(find_graph(f, Some("third"), None), Err(LookupError::NoSuchGraph { known, .. }) if known == ["first", "second"])
    );
    assert_eq!(find_graph("oak_planks", None, None).unwrap().info.name, "oak_planks");
    assert!(matches!(find_graph("oak_plank", None, None), Err(LookupError::NoSuchGraph { .. })));
    assert!(matches!(find_graph("oak_planks", Some("walnut"), None), Err(LookupError::NameConflict { .. })));
    assert!(matches!(find_graph(dir.to_str().unwrap(), None, None), Err(LookupError::IsADirectory(_))));
    assert!(matches!(find_graph("no/such.psg", None, None), Err(LookupError::NoSuchFile(_))));
    // A library of one file still finds graphs by name, not "the first one".
    let lib_tmp = scratch("lookup-lib");
    let lib = lib_tmp.path();
    std::fs::copy(&file, lib.join("two.psg")).unwrap();
    assert_eq!(find_graph("second", None, Some(lib)).unwrap().info.name, "second");
    assert!(matches!(find_graph("oak_planks", None, Some(lib)), Err(LookupError::NoSuchGraph { .. })));
}
