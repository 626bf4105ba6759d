//! Requests over the resource limits are refused before anything is allocated, with the limit
//! and the memory they would need; photos and label images whose headers claim huge sizes, and
//! truncated photos, are errors naming the file.

mod common;

use common::*;
use psc_render::camera::Camera;
use psc_render::{compute_light_grid, LightGridOptions, LightRadiances, RenderError, RenderOptions, Renderer, Scene};

fn renderer() -> (Scene, Renderer) {
    // The tests only render from memory, so the scene's folder can go when this returns.
    let tmp = temp_dir("limits");
    let dir = tmp.path();
    write_scene(dir);
    let scene = Scene::load(dir).unwrap();
    let mut w = Vec::new();
    let r = Renderer::new(&scene, scene.mtl_materials(&mut w), &LightRadiances::unit(&scene)).unwrap();
    (scene, r)
}

fn render_err(r: &Renderer, cam: &Camera, o: RenderOptions) -> String {
    match r.render(cam, &o) {
        Ok(_) => panic!("{o:?} should be refused"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn huge_images_spp_threads_and_depth_zero_are_refused() {
    let (scene, r) = renderer();
    let cam = &scene.views[0].camera;
    let base = RenderOptions { width: 8, height: 6, spp: 1, ..Default::default() };
    for (w, h) in [(100_000, 100_000), (65_536, 65_536), (99_999_999_999, 2), (4_294_967_295, 4_294_967_295)] {
        let e = render_err(&r, cam, RenderOptions { width: w, height: h, ..base.clone() });
        assert!(e.contains(&format!("{w}x{h}")) && e.contains("67,108,864 pixels") && e.contains("memory"), "{e}");
    }
    let e = render_err(&r, cam, RenderOptions { spp: 1_000_000, ..base.clone() });
    assert!(e.contains("samples per pixel") && e.contains("65,536"), "{e}");
    let e = render_err(&r, cam, RenderOptions { threads: Some(100_000), ..base.clone() });
    assert!(e.contains("100,000 threads") && e.contains("256"), "{e}");
    let e = render_err(&r, cam, RenderOptions { max_depth: 0, ..base.clone() });
    assert!(e.contains("max_depth 0 renders nothing"), "{e}");
    assert!(r.render(cam, &base).is_ok());
}

#[test]
fn cameras_and_grids_over_the_limits_are_refused() {
    let (scene, r) = renderer();
    let spec = &scene.views[0].camera_spec;
    let e = Camera::new(spec, 100_000, 100_000, "camera.json").unwrap_err().to_string();
    assert!(e.contains("camera.json") && e.contains("67,108,864"), "{e}");
    // A grid at every pixel of an 8192² image fits the pixel limit but not the memory budget.
    let big = Camera::new(spec, 8192, 8192, "big").unwrap();
    let o = LightGridOptions { stride: 1, ..Default::default() };
    let e = compute_light_grid(&r, &big, &o).err().expect("refused").to_string();
    assert!(e.contains("light grid of 8192x8192 cells") && e.contains("GiB"), "{e}");
    let cam = &scene.views[0].camera;
    let o = LightGridOptions { samples_per_bin: 1_000_000, ..Default::default() };
    let e = compute_light_grid(&r, cam, &o).err().expect("refused").to_string();
    assert!(e.contains("paths per bin") && e.contains("4,096"), "{e}");
    let o = LightGridOptions { max_depth: 1, ..Default::default() };
    let e = compute_light_grid(&r, cam, &o).err().expect("refused").to_string();
    assert!(e.contains("max_depth of at least 2"), "{e}");
}

/// A ~60-byte PNG whose header claims `w`×`h` (8-bit, colour `color_type`) and whose data is
/// one empty IDAT.
fn lying_png(w: u32, h: u32, color_type: u8) -> Vec<u8> {
    png_from_chunks(w, h, 8, color_type, &[(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01])])
}

fn load_err(dir: &std::path::Path) -> RenderError {
    match Scene::load(dir) {
        Ok(_) => panic!("{} should not load", dir.display()),
        Err(e) => e,
    }
}

#[test]
fn photos_and_labels_with_huge_headers_are_refused_naming_the_file() {
    let tmp = temp_dir("huge-photo");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::write(dir.join("views/view0.png"), lying_png(100_000, 100_000, 2)).unwrap();
    // Without labels too: the photo alone is checked.
    let manifest = std::fs::read_to_string(dir.join("scene.json")).unwrap();
    std::fs::write(dir.join("scene.json"), manifest.replace(r#""parts": "views/view0_parts.png","#, "")).unwrap();
    let e = load_err(dir).to_string();
    assert!(e.contains("view0.png") && e.contains("100000x100000") && e.contains("67,108,864"), "{e}");

    let tmp = temp_dir("huge-labels");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::write(dir.join("views/view0_parts.png"), lying_png(100_000, 100_000, 0)).unwrap();
    let e = load_err(dir).to_string();
    assert!(e.contains("view0_parts.png") && e.contains("67,108,864"), "{e}");
}

#[test]
fn a_truncated_photo_is_an_error_naming_the_file() {
    let tmp = temp_dir("truncated-photo");
    let dir = tmp.path();
    write_scene(dir);
    let p = dir.join("views/view0.png");
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let e = load_err(dir).to_string();
    assert!(e.contains("view0.png"), "{e}");
    // Same for a lying header with a small size but no pixel data.
    std::fs::write(&p, lying_png(W as u32, H as u32, 2)).unwrap();
    let e = load_err(dir).to_string();
    assert!(e.contains("view0.png"), "{e}");
}

/// JSON input files past the documented 64 MiB are refused before they are read (a sparse file
/// here: nothing is written), and a lights file of many thousand entries is read in one pass,
/// its unknown names summed up rather than listed one warning each.
#[test]
fn huge_json_files_and_lights_files_of_many_entries() {
    let tmp = temp_dir("json-limits");
    let dir = tmp.path();
    write_scene(dir);
    let scene = Scene::load(dir).unwrap();
    let big = dir.join("big.json");
    std::fs::File::create(&big).unwrap().set_len(psc_base::limits::MAX_JSON_BYTES + 1).unwrap();
    let mut warnings = Vec::new();
    let e = LightRadiances::from_file(&big, &scene, &mut warnings).unwrap_err().to_string();
    assert!(e.contains("big.json") && e.contains("64 MiB limit"), "{e}");
    std::fs::copy(&big, dir.join("scene.json")).unwrap();
    let e = load_err(dir).to_string();
    assert!(e.contains("scene.json") && e.contains("64 MiB limit"), "{e}");

    let n = 50_000;
    let entries: Vec<String> = (0..n)
        .map(|i| format!(r#"{{"name": "l{i}", "radiance_rgb": [1, 1, 1]}}"#))
        .chain([r#"{"name": "lamp", "radiance_rgb": [2, 3, 4]}"#.to_string()])
        .collect();
    let many = dir.join("many.json");
    std::fs::write(&many, format!(r#"{{"lights": [{}]}}"#, entries.join(","))).unwrap();
    let mut warnings = Vec::new();
    let r = LightRadiances::from_file(&many, &scene, &mut warnings).unwrap();
    assert_eq!(r.lights, vec![[2.0, 3.0, 4.0]]);
    assert_eq!(warnings.len(), 6, "{warnings:?}");
    assert!(warnings[5].contains(&format!("{} more lights not in the scene", n - 5)), "{warnings:?}");
    // A name listed twice, far apart, is still found.
    std::fs::write(&many, format!(r#"{{"lights": [{}, {}]}}"#, entries.join(","), entries[7])).unwrap();
    let e = LightRadiances::from_file(&many, &scene, &mut Vec::new()).unwrap_err().to_string();
    assert!(e.contains(&format!("lights[7] and lights[{}]", n + 1)), "{e}");
}
