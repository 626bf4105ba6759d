//! Small synthetic scenes written into a fresh temporary folder.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A fresh, empty temporary folder, removed when the returned guard is dropped.
pub fn temp_dir(tag: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-render-test-{tag}-")).tempdir().unwrap()
}

/// A 4 × 2.5 × 4 room (x, y, z) seen from inside, parts floor / walls / ceiling, with a box on
/// the floor (part "crate"). With `uvs` false the OBJ has no `vt`.
pub fn room_obj(uvs: bool) -> String {
    let mut s = String::from("mtllib room.mtl\n");
    let quads: [(&str, [[f32; 3]; 4]); 7] = [
        ("floor", [[0.0, 0.0, 0.0], [0.0, 0.0, 4.0], [4.0, 0.0, 4.0], [4.0, 0.0, 0.0]]),
        ("ceiling", [[0.0, 2.5, 0.0], [4.0, 2.5, 0.0], [4.0, 2.5, 4.0], [0.0, 2.5, 4.0]]),
        ("walls", [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [4.0, 2.5, 0.0], [0.0, 2.5, 0.0]]),
        ("walls", [[0.0, 0.0, 4.0], [0.0, 2.5, 4.0], [4.0, 2.5, 4.0], [4.0, 0.0, 4.0]]),
        ("walls", [[0.0, 0.0, 0.0], [0.0, 2.5, 0.0], [0.0, 2.5, 4.0], [0.0, 0.0, 4.0]]),
        ("walls", [[4.0, 0.0, 0.0], [4.0, 0.0, 4.0], [4.0, 2.5, 4.0], [4.0, 2.5, 0.0]]),
        ("crate", [[1.5, 0.5, 1.5], [1.5, 0.5, 2.5], [2.5, 0.5, 2.5], [2.5, 0.5, 1.5]]),
    ];
    let mut v = 0;
    let mut current = "";
    for (name, q) in quads {
        for p in q {
            s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
        if uvs {
            s += "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n";
        }
        if name != current {
            s += &format!("usemtl {name}\n");
            current = name;
        }
        let f = |i: usize| if uvs { format!("{}/{}", v + i, v + i) } else { format!("{}", v + i) };
        s += &format!("f {} {} {} {}\n", f(1), f(2), f(3), f(4));
        v += 4;
    }
    s
}

pub const MTL: &str = "newmtl floor\nKd 0.5 0.4 0.3\nnewmtl ceiling\nKd 0.8 0.8 0.8\nnewmtl walls\nKd 0.6 0.6 0.6\nnewmtl crate\nKd 0.3 0.5 0.2\n";

/// Emits downwards (−y) from just below the ceiling.
pub const LIGHT_OBJ: &str =
    "v 1.5 2.49 1.5\nv 2.5 2.49 1.5\nv 2.5 2.49 2.5\nv 1.5 2.49 2.5\nvn 0 -1 0\nf 1//1 2//1 3//1 4//1\n";

pub const W: usize = 40;
pub const H: usize = 30;

/// The scene.json of the test room, with a `{CAMERA}` and `{LABELS}` placeholder replaced.
pub fn manifest(camera: &str, part_labels: &str) -> String {
    format!(
        r#"{{
  "format": "photoscene-scene/1",
  "units": "meters",
  "up": [0, 1, 0],
  "mesh": "room.obj",
  "views": [
    {{
      "name": "view0",
      "image": "views/view0.png",
      "camera": {camera},
      "parts": "views/view0_parts.png",
      "part_labels": {part_labels}
    }}
  ],
  "lights": [ {{ "name": "lamp", "mesh": "lights/lamp.obj" }} ]
}}"#
    )
}

pub const GOOD_CAMERA: &str =
    r#"{ "position": [2.0, 1.4, 3.8], "look_at": [2.0, 0.8, 1.0], "up": [0, 1, 0], "fov_y_deg": 60.0 }"#;
pub const GOOD_LABELS: &str = r#"{ "1": "floor", "2": "walls", "3": "crate" }"#;

/// Write a complete, valid scene; tests then break one thing.
pub fn write_scene(dir: &Path) {
    std::fs::create_dir_all(dir.join("views")).unwrap();
    std::fs::create_dir_all(dir.join("lights")).unwrap();
    std::fs::write(dir.join("room.obj"), room_obj(true)).unwrap();
    std::fs::write(dir.join("room.mtl"), MTL).unwrap();
    std::fs::write(dir.join("lights/lamp.obj"), LIGHT_OBJ).unwrap();
    std::fs::write(dir.join("scene.json"), manifest(GOOD_CAMERA, GOOD_LABELS)).unwrap();
    psc_render::image_io::write_rgb(&dir.join("views/view0.png"), W, H, &vec![[0.5; 3]; W * H]).unwrap();
    write_labels(dir, W, H);
}

pub fn write_labels(dir: &Path, w: usize, h: usize) {
    let labels: Vec<u16> = (0..w * h).map(|i| if i / w > h / 2 { 1 } else { 2 }).collect();
    psc_render::image_io::write_gray16(&dir.join("views/view0_parts.png"), w, h, &labels).unwrap();
}

/// The dev scene `name`, from shared/ beside the checkout (CI layout). When it is absent the
/// test cannot run: outside CI that is said loudly on stderr and the caller skips (None); with
/// the environment variable `CI` set (CI always has the scenes) it is a failure.
pub fn dev_scene(name: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes").join(name);
    if p.join("scene.json").is_file() {
        return Some(p);
    }
    let msg = format!("dev scene {} not found", p.display());
    if std::env::var_os("CI").is_some() {
        panic!("{msg}: CI must have shared/scenes beside the checkout");
    }
    eprintln!("\n*** TEST NOT RUN: {msg}; this test checked nothing (set up shared/scenes to run it) ***\n");
    None
}
