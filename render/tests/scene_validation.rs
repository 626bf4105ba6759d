//! Broken scenes give clear errors or warnings, never panics.

mod common;

use common::*;
use psc_render::{RenderError, Scene};

fn load_err(dir: &std::path::Path) -> RenderError {
    match Scene::load(dir) {
        Ok(_) => panic!("scene in {} should not load", dir.display()),
        Err(e) => e,
    }
}

#[test]
fn valid_scene_loads_with_parts_and_no_warnings() {
    let tmp = temp_dir("valid");
    let dir = tmp.path();
    write_scene(dir);
    let s = Scene::load(dir).unwrap();
    assert_eq!(s.mesh.part_names, ["floor", "ceiling", "walls", "crate"]);
    assert_eq!(s.mesh.triangles.len(), 14);
    assert_eq!(s.views[0].width, W);
    assert_eq!(s.lights.len(), 1);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

#[test]
fn missing_mesh_is_an_error_naming_the_file() {
    let tmp = temp_dir("nomesh");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::remove_file(dir.join("room.obj")).unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("room.obj") && msg.contains("not found"), "{msg}");
}

#[test]
fn missing_light_mesh_and_photo_are_errors() {
    let tmp = temp_dir("nolight");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::remove_file(dir.join("lights/lamp.obj")).unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("lamp.obj") && msg.contains("light 'lamp'"), "{msg}");
    let tmp = temp_dir("nophoto");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::remove_file(dir.join("views/view0.png")).unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("view0.png"), "{msg}");
}

#[test]
fn malformed_json_reports_line_and_column() {
    let tmp = temp_dir("badjson");
    let dir = tmp.path();
    write_scene(dir);
    // Drop the comma after "units": the error is on line 4 (the "up" key), column 3.
    let text = manifest(GOOD_CAMERA, GOOD_LABELS).replace("\"meters\",", "\"meters\"");
    std::fs::write(dir.join("scene.json"), text).unwrap();
    let e = load_err(dir);
    match &e {
        RenderError::Json { line, column, .. } => assert_eq!((*line, *column), (4, 3), "{e}"),
        other => panic!("expected a JSON error, got {other}"),
    }
    let msg = e.to_string();
    assert!(msg.contains("scene.json:4:3:"), "{msg}");
}

#[test]
fn schema_errors_also_have_a_location() {
    let tmp = temp_dir("schema");
    let dir = tmp.path();
    write_scene(dir);
    let text = manifest(GOOD_CAMERA, GOOD_LABELS).replace("\"fov_y_deg\": 60.0", "\"fov_y_deg\": \"wide\"");
    std::fs::write(dir.join("scene.json"), text).unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("scene.json:") && msg.contains("invalid type"), "{msg}");
}

#[test]
fn obj_without_uvs_warns_and_generates_them() {
    let tmp = temp_dir("nouv");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::write(dir.join("room.obj"), room_obj(false)).unwrap();
    let s = Scene::load(dir).unwrap();
    assert!(s.warnings.iter().any(|w| w.contains("no texture coordinates")), "{:?}", s.warnings);
    assert_eq!(s.mesh.generated_uv_parts.len(), 4);
    // Floor uvs are the (x, z) coordinates: they vary and span the 4 m floor.
    let floor = s.mesh.part_index("floor").unwrap() as u32;
    let uvs: Vec<[f32; 2]> = s
        .mesh
        .triangles
        .iter()
        .zip(&s.mesh.tri_part)
        .filter(|(_, &p)| p == floor)
        .flat_map(|(t, _)| t.iter().map(|&i| s.mesh.uvs[i as usize]))
        .collect();
    let max_u = uvs.iter().map(|u| u[0]).fold(f32::MIN, f32::max);
    let max_v = uvs.iter().map(|u| u[1]).fold(f32::MIN, f32::max);
    assert_eq!((max_u, max_v), (4.0, 4.0));
}

#[test]
fn label_image_of_the_wrong_size_is_an_error() {
    let tmp = temp_dir("labelsize");
    let dir = tmp.path();
    write_scene(dir);
    write_labels(dir, W + 1, H);
    let msg = load_err(dir).to_string();
    assert!(msg.contains("41x30") && msg.contains("40x30"), "{msg}");
}

#[test]
fn colour_label_image_is_an_error() {
    let tmp = temp_dir("labelrgb");
    let dir = tmp.path();
    write_scene(dir);
    psc_render::image_io::write_rgb(&dir.join("views/view0_parts.png"), W, H, &vec![[0.2; 3]; W * H]).unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("grayscale"), "{msg}");
}

/// A palette of `n` colours none of which is the gray level of its index, nor has it as a
/// channel: a reader that took colours for labels gets other values.
fn palette(n: usize) -> Vec<u8> {
    (0..n as u8).flat_map(|i| [100 + i, 50 + i, 200 - i]).collect()
}

/// `pixels` (`w` wide) written as a `depth`-bit palette PNG, then read back as labels.
fn palette_labels(dir: &std::path::Path, w: usize, depth: u8, interlaced: bool, pixels: &[u8]) -> Vec<u16> {
    let h = pixels.len() / w;
    let plte = palette(usize::from(*pixels.iter().max().unwrap()) + 1);
    let png = if interlaced {
        interlaced_png_bytes(w, h, depth, 3, Some(&plte), pixels)
    } else {
        let rows: Vec<Vec<u8>> = pixels.chunks(w).map(|r| pack_row(r, depth)).collect();
        png_bytes(w as u32, h as u32, depth, 3, Some(&plte), &rows)
    };
    let path = dir.join("labels.png");
    std::fs::write(&path, png).unwrap();
    let (rw, rh, data) = psc_render::image_io::read_labels(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((rw, rh), (w, h), "{depth}-bit");
    data
}

/// `w` × `h` labels cycling through the `n` values (every value when w + h - 1 ≥ n), each row
/// shifted by one so rows read from the wrong place give other values.
fn diagonal(w: usize, h: usize, n: usize) -> Vec<u8> {
    (0..w * h).map(|i| ((i % w + i / w) % n) as u8).collect()
}

fn widened(v: &[u8]) -> Vec<u16> {
    v.iter().copied().map(u16::from).collect()
}

/// A palette PNG, as PASCAL VOC and ADE20K store label maps, gives its indices: it was refused,
/// as `image` expands a palette to RGB.
#[test]
fn palette_label_image_is_read_by_index() {
    let tmp = temp_dir("labelpalette");
    let pixels = diagonal(7, 5, 4);
    assert_eq!(palette_labels(tmp.path(), 7, 8, false, &pixels), widened(&pixels));
}

/// 4-, 2- and 1-bit indices are unpacked most significant bit first, and each row starts on a
/// byte: 13 pixels end in padding bits at each of these depths.
#[test]
fn sub_byte_palette_label_images_are_unpacked_row_by_row() {
    let tmp = temp_dir("labelpalettebits");
    for depth in [4u8, 2, 1] {
        let pixels = diagonal(13, 5, 1 << depth);
        assert_eq!(palette_labels(tmp.path(), 13, depth, false, &pixels), widened(&pixels), "{depth}-bit");
    }
}

/// An interlaced (Adam7) label PNG gives its pixels in place, sub-byte indices included.
#[test]
fn interlaced_palette_label_images_are_deinterlaced() {
    let tmp = temp_dir("labelinterlaced");
    for depth in [8u8, 4, 1] {
        // 13 × 11: every one of the seven passes has pixels, and rows end in padding bits.
        let pixels = diagonal(13, 11, 1 << depth.min(4));
        assert_eq!(palette_labels(tmp.path(), 13, depth, true, &pixels), widened(&pixels), "{depth}-bit");
    }
}

/// Colour label images are still refused, saying what the file stores.
#[test]
fn colour_label_images_are_refused_saying_what_they_hold() {
    let tmp = temp_dir("labelcolour");
    let must = "a label image must be grayscale (the labels as gray levels) or a palette PNG (the labels as \
                palette indices), this one is";
    let rgb = tmp.path().join("rgb.png");
    psc_render::image_io::write_rgb(&rgb, 4, 3, &[[0.2; 3]; 12]).unwrap();
    let gray_alpha = tmp.path().join("gray_alpha.png");
    std::fs::write(&gray_alpha, png_bytes(2, 1, 8, 4, None, &[vec![1, 255, 2, 255]])).unwrap();
    let rgba16 = tmp.path().join("rgba16.png");
    std::fs::write(&rgba16, png_bytes(1, 1, 16, 6, None, &[vec![0; 8]])).unwrap();
    // Not a PNG: decoded by `image`, and named from what it decodes to.
    let jpeg = tmp.path().join("rgb.jpg");
    image::RgbImage::from_pixel(4, 3, image::Rgb([200, 40, 40])).save(&jpeg).unwrap();
    for (path, kind) in [
        (&rgb, "8-bit RGB colour"),
        (&gray_alpha, "8-bit grayscale with alpha"),
        (&rgba16, "16-bit RGBA colour"),
        (&jpeg, "8-bit RGB colour"),
    ] {
        let msg = psc_render::image_io::read_labels(path).unwrap_err().to_string();
        assert_eq!(msg, format!("{}: {must} {kind}", path.display()));
    }
}

/// A scene whose label image is a palette PNG loads, its indices naming the parts.
#[test]
fn palette_label_image_names_the_parts_of_a_scene() {
    let tmp = temp_dir("scenepalette");
    let dir = tmp.path();
    write_scene(dir);
    // Unlabelled top rows, walls, a crate in the middle, floor below (GOOD_LABELS' 1, 2, 3).
    let label = |x: usize, y: usize| match (x, y) {
        (_, 0..3) => 0u8,
        (15..25, 12..18) => 3,
        (_, y) if y > H / 2 => 1,
        _ => 2,
    };
    let rows: Vec<Vec<u8>> = (0..H).map(|y| (0..W).map(|x| label(x, y)).collect()).collect();
    let png = png_bytes(W as u32, H as u32, 8, 3, Some(&palette(4)), &rows);
    std::fs::write(dir.join("views/view0_parts.png"), png).unwrap();
    let s = Scene::load(dir).unwrap_or_else(|e| panic!("{e}"));
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let view = &s.views[0];
    let part_of = |l: u16| view.part_labels.get(&l).and_then(|name| s.mesh.part_index(name));
    let got: Vec<Option<usize>> = view.labels.as_ref().unwrap().data.iter().map(|&l| part_of(l)).collect();
    let want: Vec<Option<usize>> =
        (0..W * H).map(|i| [None, Some(0), Some(2), Some(3)][usize::from(label(i % W, i / W))]).collect();
    assert_eq!(got, want, "part ids (floor 0, walls 2, crate 3)");
}

/// A truncated or corrupt label PNG is an error naming the file, wherever it is cut.
#[test]
fn truncated_or_corrupt_palette_label_image_is_an_error_naming_the_file() {
    let tmp = temp_dir("labeltruncated");
    let path = tmp.path().join("labels.png");
    let pixels = diagonal(7, 5, 4);
    let rows: Vec<Vec<u8>> = pixels.chunks(7).map(|r| pack_row(r, 8)).collect();
    let png = png_bytes(7, 5, 8, 3, Some(&palette(4)), &rows);
    std::fs::write(&path, &png).unwrap();
    assert_eq!(psc_render::image_io::read_labels(&path).unwrap_or_else(|e| panic!("{e}")).2, widened(&pixels));
    // The pixel data ends 4 bytes (the CRC) before IEND's 12.
    let mut broken: Vec<Vec<u8>> = (0..png.len() - 16).map(|n| png[..n].to_vec()).collect();
    let mut flipped = png.clone();
    flipped[png.len() - 20] ^= 0x40; // in the last image data bytes: a CRC mismatch
    broken.push(flipped);
    for bytes in broken {
        std::fs::write(&path, &bytes).unwrap();
        let msg = match psc_render::image_io::read_labels(&path) {
            Ok(_) => panic!("{} of {} bytes read as labels", bytes.len(), png.len()),
            Err(e) => e.to_string(),
        };
        assert!(msg.starts_with(&format!("{}: ", path.display())), "{} bytes: {msg}", bytes.len());
    }
}

/// A 1-, 2- or 4-bit grayscale label image gives the values it stores: the decoder scales them
/// to 8 bits, which turned the labels 1, 2 of a 4-bit image into 17, 34.
#[test]
fn low_bit_depth_label_images_give_their_stored_values() {
    let tmp = temp_dir("labellowbit");
    let dir = tmp.path();
    write_scene(dir);
    let label = |y: usize| if y > H / 2 { 1u8 } else { 2 };
    for depth in [2u8, 4] {
        let per_byte = 8 / depth as usize;
        let rows: Vec<Vec<u8>> = (0..H)
            .map(|y| {
                (0..W.div_ceil(per_byte)).map(|_| (0..per_byte).fold(0u8, |acc, _| (acc << depth) | label(y))).collect()
            })
            .collect();
        let png = png_bytes(W as u32, H as u32, depth, 0, None, &rows);
        std::fs::write(dir.join("views/view0_parts.png"), png).unwrap();
        let (w, h, data) = psc_render::image_io::read_labels(&dir.join("views/view0_parts.png")).unwrap();
        assert_eq!((w, h), (W, H));
        let want: Vec<u16> = (0..W * H).map(|i| u16::from(label(i / W))).collect();
        assert!(data == want, "{depth}-bit: got values {:?}", data.iter().collect::<std::collections::BTreeSet<_>>());
        let s = Scene::load(dir).unwrap_or_else(|e| panic!("{e}"));
        assert!(s.warnings.is_empty(), "{depth}-bit: {:?}", s.warnings);
    }
}

#[test]
fn labels_naming_unknown_parts_warn() {
    let tmp = temp_dir("unknownpart");
    let dir = tmp.path();
    write_scene(dir);
    let labels = r#"{ "1": "floor", "2": "sofa" }"#;
    std::fs::write(dir.join("scene.json"), manifest(GOOD_CAMERA, labels)).unwrap();
    let s = Scene::load(dir).unwrap();
    assert!(s.warnings.iter().any(|w| w.contains("'sofa'") && w.contains("does not have")), "{:?}", s.warnings);
    // A label value in the image without a name also warns.
    let labels = r#"{ "1": "floor" }"#;
    std::fs::write(dir.join("scene.json"), manifest(GOOD_CAMERA, labels)).unwrap();
    let s = Scene::load(dir).unwrap();
    assert!(s.warnings.iter().any(|w| w.contains("[2]") && w.contains("no entry")), "{:?}", s.warnings);
}

#[test]
fn non_integer_label_key_is_an_error() {
    let tmp = temp_dir("labelkey");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::write(dir.join("scene.json"), manifest(GOOD_CAMERA, r#"{ "one": "floor" }"#)).unwrap();
    assert!(load_err(dir).to_string().contains("'one'"));
}

#[test]
fn degenerate_cameras_are_errors() {
    let cases = [
        (r#"{ "position": [2, 1, 2], "look_at": [2, 1, 2], "up": [0, 1, 0], "fov_y_deg": 60 }"#, "coincide"),
        (r#"{ "position": [2, 1, 3], "look_at": [2, 1, 1], "up": [0, 1, 0], "fov_y_deg": 0 }"#, "fov_y_deg"),
        (r#"{ "position": [2, 1, 3], "look_at": [2, 1, 1], "up": [0, 1, 0], "fov_y_deg": 200 }"#, "fov_y_deg"),
        (r#"{ "position": [2, 2, 2], "look_at": [2, 0, 2], "up": [0, 1, 0], "fov_y_deg": 60 }"#, "parallel"),
        (r#"{ "position": [2, 1, 3], "look_at": [2, 1, 1], "up": [0, 0, 0], "fov_y_deg": 60 }"#, "zero up"),
        // Far beyond f32 precision: named as such, not as "up vector parallel".
        (r#"{ "position": [1e38, 1, 3], "look_at": [2, 1, 1], "up": [0, 1, 0], "fov_y_deg": 60 }"#, "position"),
        (r#"{ "position": [2, 1, 3], "look_at": [2, -1e20, 1], "up": [0, 1, 0], "fov_y_deg": 60 }"#, "look_at"),
    ];
    for (camera, expect) in cases {
        let tmp = temp_dir("camera");
        let dir = tmp.path();
        write_scene(dir);
        std::fs::write(dir.join("scene.json"), manifest(camera, GOOD_LABELS)).unwrap();
        let e = load_err(dir);
        assert!(matches!(e, RenderError::Camera { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains("view 'view0'") && msg.contains(expect), "{msg}");
        assert!(expect == "parallel" || !msg.contains("parallel"), "{msg}");
    }
}

#[test]
fn files_named_by_a_scene_stay_inside_it() {
    for (mesh, expect) in [
        ("../../../../etc/passwd", "outside the scene folder"),
        ("/etc/passwd", "absolute paths are not allowed"),
        ("views/../../x.obj", "outside the scene folder"),
    ] {
        let tmp = temp_dir("confined");
        let dir = tmp.path();
        write_scene(dir);
        let text = std::fs::read_to_string(dir.join("scene.json")).unwrap();
        std::fs::write(dir.join("scene.json"), text.replace(r#""mesh": "room.obj""#, &format!(r#""mesh": "{mesh}""#)))
            .unwrap();
        let msg = load_err(dir).to_string();
        assert!(msg.contains(expect), "{mesh}: {msg}");
    }
    #[cfg(unix)]
    {
        // A symbolic link out of the folder is refused too.
        let tmp = temp_dir("confined-link");
        let dir = tmp.path();
        write_scene(dir);
        std::os::unix::fs::symlink("/etc/hostname", dir.join("link.obj")).unwrap();
        let text = std::fs::read_to_string(dir.join("scene.json")).unwrap();
        std::fs::write(dir.join("scene.json"), text.replace(r#""mesh": "room.obj""#, r#""mesh": "link.obj""#)).unwrap();
        let msg = load_err(dir).to_string();
        assert!(msg.contains("outside the scene folder"), "{msg}");
    }
}

#[test]
fn a_folder_where_a_file_is_expected_is_not_called_missing() {
    let tmp = temp_dir("dir-for-file");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::remove_file(dir.join("room.obj")).unwrap();
    std::fs::create_dir(dir.join("room.obj")).unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("is a directory") && !msg.contains("not found"), "{msg}");
    let msg = match Scene::load(&dir.join("views")) {
        Ok(_) => panic!("no scene.json"),
        Err(e) => e.to_string(),
    };
    assert!(msg.contains("scene.json") && msg.contains("not found"), "{msg}");
}

#[test]
fn nested_arrays_in_scene_json_name_the_field() {
    let tmp = temp_dir("nested");
    let dir = tmp.path();
    write_scene(dir);
    let text = std::fs::read_to_string(dir.join("scene.json")).unwrap();
    std::fs::write(dir.join("scene.json"), text.replace(r#""mesh": "room.obj""#, r#""mesh": [["room.obj"]]"#)).unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("field `mesh`") && msg.contains("sequence") && msg.contains("string"), "{msg}");
    let text = manifest(GOOD_CAMERA, GOOD_LABELS).replace(r#""fov_y_deg": 60.0"#, r#""fov_y_deg": [60]"#);
    std::fs::write(dir.join("scene.json"), text).unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("views[0].camera.fov_y_deg"), "{msg}");
}

#[test]
fn missing_mtl_keeps_part_names_with_a_warning() {
    let tmp = temp_dir("nomtl");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::remove_file(dir.join("room.mtl")).unwrap();
    let s = Scene::load(dir).unwrap();
    assert_eq!(s.mesh.part_names, ["floor", "ceiling", "walls", "crate"]);
    assert!(s.warnings.iter().any(|w| w.contains("room.mtl")), "{:?}", s.warnings);
}

#[test]
fn no_lights_key_places_ceiling_lights() {
    let tmp = temp_dir("autolights");
    let dir = tmp.path();
    write_scene(dir);
    let text = manifest(GOOD_CAMERA, GOOD_LABELS)
        .replace(r#""lights": [ { "name": "lamp", "mesh": "lights/lamp.obj" } ]"#, r#""units2": 1"#);
    // unknown keys are rejected: that is a schema error with a location
    std::fs::write(dir.join("scene.json"), &text).unwrap();
    assert!(matches!(load_err(dir), RenderError::Json { .. }));
    let text = text.replace(",\n  \"units2\": 1", "");
    std::fs::write(dir.join("scene.json"), &text).unwrap();
    let s = Scene::load(dir).unwrap();
    assert!(s.lights_generated);
    assert!(!s.lights.is_empty());
    // every generated emitter faces down, below the ceiling
    for l in &s.lights {
        for t in &l.triangles {
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            assert!(n.y < 0.0 && t[0].y < 2.5);
        }
    }
}

/// A camera file gives its image size whole or not at all: `width` alone (or `height` alone) is
/// an error naming the file and the missing field, not a silent fall-back to another size.
#[test]
fn camera_file_with_width_or_height_alone_is_an_error() {
    let tmp = temp_dir("camera-size");
    let camera = r#""position": [2.0, 1.4, 3.8], "look_at": [2.0, 0.8, 1.0], "fov_y_deg": 60.0"#;
    for (body, given, missing) in [
        (format!(r#"{{ {camera}, "width": 100 }}"#), "width", "height"),
        (format!(r#"{{ "camera": {{ {camera} }}, "height": 100 }}"#), "height", "width"),
    ] {
        let path = tmp.path().join(format!("cam_{given}.json"));
        std::fs::write(&path, body).unwrap();
        let msg = match psc_render::camera::load_camera_file(&path) {
            Ok(c) => panic!("{given} alone should not load: {:?}", c.size),
            Err(e) => e.to_string(),
        };
        assert!(msg.contains(&path.display().to_string()), "{msg}");
        assert!(msg.contains(&format!("\"{given}\" is given without \"{missing}\"")), "{msg}");
    }
    let path = tmp.path().join("both.json");
    std::fs::write(&path, format!(r#"{{ {camera}, "width": 100, "height": 50 }}"#)).unwrap();
    assert_eq!(psc_render::camera::load_camera_file(&path).unwrap().size, Some((100, 50)));
}

/// A UTF-8 byte-order mark at the start of scene.json (and of the OBJ, the MTL, a camera file)
/// is skipped: it said `scene.json:1:1: expected value`.
#[test]
fn a_leading_byte_order_mark_is_skipped() {
    let tmp = temp_dir("bom");
    let dir = tmp.path();
    write_scene(dir);
    for file in ["scene.json", "room.obj", "room.mtl"] {
        let text = std::fs::read_to_string(dir.join(file)).unwrap();
        std::fs::write(dir.join(file), format!("\u{feff}{text}")).unwrap();
    }
    let s = Scene::load(dir).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.mesh.part_names, ["floor", "ceiling", "walls", "crate"], "the BOM'd mtllib line is read");
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let camera = dir.join("camera.json");
    std::fs::write(&camera, format!("\u{feff}{GOOD_CAMERA}")).unwrap();
    psc_render::camera::load_camera_file(&camera).unwrap_or_else(|e| panic!("{e}"));
    // Still an error (with its place) when the text after it is not JSON.
    std::fs::write(dir.join("scene.json"), "\u{feff}{ \"format\": }").unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("scene.json:1:13:"), "{msg}");
}

/// A scene.json (or camera file) whose top level is not an object says the file must hold one,
/// at the value: an array said `field [0]: invalid type` (serde reads it as the fields in order).
#[test]
fn a_json_file_that_is_not_an_object_says_so() {
    let tmp = temp_dir("not-object");
    let dir = tmp.path();
    write_scene(dir);
    let good = manifest(GOOD_CAMERA, GOOD_LABELS);
    for (text, at, found) in [
        (format!("[{good}]"), "1:1", "found an array of 1 elements"),
        ("[]".to_string(), "1:1", "found an array of 0 elements"),
        ("\n  5\n".to_string(), "2:3", "found the number 5"),
        ("\"scene\"".to_string(), "1:1", "found a string"),
        ("null".to_string(), "1:1", "found `null`"),
    ] {
        std::fs::write(dir.join("scene.json"), &text).unwrap();
        let msg = load_err(dir).to_string();
        let want = format!("scene.json:{at}: the file must hold a JSON object ({{ ... }}), {found}");
        assert!(msg.contains(&want), "{text:?}: {msg}");
    }
    // A broken array is still an array; other text that is not JSON keeps its syntax error.
    std::fs::write(dir.join("scene.json"), "[1, ").unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("scene.json:1:1: the file must hold a JSON object ({ ... }), found an array"), "{msg}");
    std::fs::write(dir.join("scene.json"), "scene").unwrap();
    let msg = load_err(dir).to_string();
    assert!(msg.contains("scene.json:1:1: expected value"), "{msg}");
    let camera = dir.join("camera.json");
    std::fs::write(&camera, format!("[{GOOD_CAMERA}]")).unwrap();
    let msg = psc_render::camera::load_camera_file(&camera).unwrap_err().to_string();
    assert!(msg.contains("camera.json:1:1: the file must hold a JSON object"), "{msg}");
}
