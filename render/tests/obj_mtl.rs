//! Hostile OBJ and MTL files: paths out of the scene folder are not read, every fallback warns
//! with the file and line, and OBJ errors give the line.

mod common;

use common::*;
use psc_render::Scene;

fn load_warnings(dir: &std::path::Path) -> (Scene, String) {
    let s = Scene::load(dir).unwrap_or_else(|e| panic!("{e}"));
    let w = s.warnings.join("\n");
    (s, w)
}

#[test]
fn mtllib_and_textures_outside_the_folder_are_not_read() {
    let tmp = temp_dir("mtl-escape");
    let dir = tmp.path();
    write_scene(dir);
    let obj = room_obj(true).replace("mtllib room.mtl", "mtllib ../../../../etc/shadow");
    std::fs::write(dir.join("room.obj"), obj).unwrap();
    let (s, w) = load_warnings(dir);
    assert!(w.contains("room.obj:1: mtllib not read") && w.contains("outside the scene folder"), "{w}");
    assert_eq!(s.mesh.part_names, ["floor", "ceiling", "walls", "crate"], "parts keep their names");

    let tmp = temp_dir("tex-escape");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::write(dir.join("room.mtl"), format!("{MTL}map_Kd ../../../etc/hostname\n")).unwrap();
    let (s, w) = load_warnings(dir);
    assert!(w.contains("material 'crate'") && w.contains("outside the scene folder"), "{w}");
    assert!(s.mesh.part_mtl[3].map_kd.is_none());
}

#[test]
fn every_mtl_fallback_warns_with_file_and_line() {
    // usemtl names missing from the MTL.
    let tmp = temp_dir("usemtl-missing");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::write(dir.join("room.mtl"), "newmtl floor\nKd 0.5 0.4 0.3\n").unwrap();
    let (_, w) = load_warnings(dir);
    for part in ["ceiling", "walls", "crate"] {
        assert!(w.contains(&format!("usemtl '{part}' is not defined")), "{part}: {w}");
    }
    assert!(w.contains("room.obj:"), "{w}");

    // One bad Kd line: that material keeps the default, the others keep theirs.
    let tmp = temp_dir("bad-kd");
    let dir = tmp.path();
    write_scene(dir);
    let mtl = MTL.replace("Kd 0.6 0.6 0.6", "Kd 0.6 zero 0.6");
    std::fs::write(dir.join("room.mtl"), &mtl).unwrap();
    let (s, w) = load_warnings(dir);
    assert!(w.contains("room.mtl:6: Kd of material 'walls'") && w.contains("0.6 zero 0.6"), "{w}");
    assert_eq!(s.mesh.part_mtl[0].kd, Some([0.5, 0.4, 0.3]));
    assert_eq!(s.mesh.part_mtl[2].kd, None);
    assert_eq!(s.mesh.part_mtl[3].kd, Some([0.3, 0.5, 0.2]));

    // Not an MTL file at all.
    let tmp = temp_dir("not-mtl");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::write(dir.join("room.mtl"), "{\"this\": \"is json\"}\n\u{0}\u{1}binary\n").unwrap();
    let (_, w) = load_warnings(dir);
    assert!(w.contains("room.mtl: not an MTL file"), "{w}");

    // A missing MTL.
    let tmp = temp_dir("no-mtl");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::remove_file(dir.join("room.mtl")).unwrap();
    let (_, w) = load_warnings(dir);
    assert!(w.contains("room.obj:1:") && w.contains("not found"), "{w}");
}

#[test]
fn obj_errors_carry_the_line() {
    for (bad, expect) in [
        ("v 1 2 abc\n", "a vertex needs three numbers"),
        ("f 1 2 99\n", "vertex index '99'"),
        ("f 1/77 2 3\n", "texture index '77'"),
        ("f 1 x 3\n", "vertex index 'x'"),
    ] {
        let tmp = temp_dir("obj-line");
        let dir = tmp.path();
        write_scene(dir);
        let obj = room_obj(true);
        let line = obj.lines().count() + 1;
        std::fs::write(dir.join("room.obj"), format!("{obj}{bad}")).unwrap();
        let msg = match Scene::load(dir) {
            Ok(_) => panic!("{bad:?} should not load"),
            Err(e) => e.to_string(),
        };
        assert!(msg.contains(&format!("room.obj: line {line}: {expect}")), "{bad:?}: {msg}");
    }
}

/// A face may name `vn`/`vt` indices only of normals / texture coordinates the file defines. tobj
/// checks that only when the file has some; with none it dropped the indices silently. The room
/// model and a light mesh go through the same check.
#[test]
fn face_indices_into_missing_normals_or_uvs_are_errors() {
    for (what, bad, expect) in [
        ("room", "f 1//9 2//9 3//9\n", "normal index '9' is not one of the 0 normals"),
        ("room", "f 1/5/ 2/5/ 3/5/\n", "texture index '5' is not one of the 0 texture coordinates"),
        ("light", "f 1//9 2//9 3//9\n", "normal index '9' is not one of the 0 normals"),
    ] {
        let tmp = temp_dir("obj-missing-vn");
        let dir = tmp.path();
        write_scene(dir);
        let (file, base) = match what {
            "room" => ("room.obj", room_obj(false)),
            _ => ("lights/lamp.obj", LIGHT_OBJ.replace("vn 0 -1 0\n", "").replace("//1", "")),
        };
        assert!(!base.contains("vn") && !base.contains("vt"), "{base}");
        let line = base.lines().count() + 1;
        std::fs::write(dir.join(file), format!("{base}{bad}")).unwrap();
        let msg = match Scene::load(dir) {
            Ok(_) => panic!("{what} {bad:?} should not load"),
            Err(e) => e.to_string(),
        };
        assert!(msg.contains(&format!("{file}: line {line}: {expect}")), "{what} {bad:?}: {msg}");
    }
}
