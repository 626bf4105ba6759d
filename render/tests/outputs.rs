//! Folder outputs (G-buffers, light grids, per-light images) appear whole or not at all, refuse
//! an existing folder unless asked to replace it, and light names cannot escape the folder.

mod common;

use common::*;
use psc_base::output::Replace;
use psc_render::integrator::slot_file_names;
use psc_render::{compute_light_grid, LightGridOptions, LightRadiances, RenderOptions, Renderer, Scene};

fn listing(dir: &std::path::Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

#[test]
fn folder_outputs_are_refused_when_present_and_replaced_whole_when_asked() {
    let tmp = temp_dir("outputs");
    let dir = tmp.path();
    write_scene(dir);
    let scene = Scene::load(dir).unwrap();
    let mut w = Vec::new();
    let r = Renderer::new(&scene, scene.mtl_materials(&mut w), &LightRadiances::unit(&scene)).unwrap();
    let cam = &scene.views[0].camera;
    let out = dir.join("out");
    std::fs::create_dir(&out).unwrap();

    let gb = r.gbuffer(cam).unwrap();
    let e = gb.write_folder(&out.join("gb"), Replace::No);
    assert!(e.is_ok());
    let e = gb.write_folder(&out.join("gb"), Replace::No).unwrap_err().to_string();
    assert!(e.contains("already exists"), "{e}");
    std::fs::write(out.join("gb/stale.exr"), b"old").unwrap();
    gb.write_folder(&out.join("gb"), Replace::Yes).unwrap();
    assert!(!out.join("gb/stale.exr").exists(), "replaced whole: no old file survives");
    assert!(out.join("gb/gbuffer.json").is_file() && out.join("gb/depth.exr").is_file());

    let opts = LightGridOptions { stride: 16, samples_per_bin: 1, ..Default::default() };
    let grid = compute_light_grid(&r, cam, &opts).unwrap();
    grid.write_folder(&out.join("grid"), Replace::No).unwrap();
    assert_eq!(listing(&out.join("grid")), ["lightgrid.bin", "lightgrid.json"]);
    assert!(grid.write_folder(&out.join("grid"), Replace::No).is_err());

    let ro = RenderOptions { width: 8, height: 6, spp: 1, per_light: true, ..Default::default() };
    let img = r.render(cam, &ro).unwrap();
    img.write_per_light_folder(&out.join("pl"), Replace::No).unwrap();
    assert_eq!(listing(&out.join("pl")), ["combined.exr", "lamp.exr"]);
    // A file where the folder goes is never replaced.
    std::fs::write(out.join("file"), b"keep").unwrap();
    assert!(img.write_per_light_folder(&out.join("file"), Replace::Yes).is_err());
    assert_eq!(std::fs::read(out.join("file")).unwrap(), b"keep");
    assert_eq!(listing(&out), ["file", "gb", "grid", "pl"], "no temporaries left");
}

#[test]
fn light_names_become_safe_distinct_file_names() {
    let names = slot_file_names(&["lamp", "../../etc/x", ".hidden", "a/b", "a_b", "combined", ""]);
    assert_eq!(
        names,
        ["lamp.exr", "_.._.._etc_x.exr", "_.hidden.exr", "a_b.exr", "a_b_1.exr", "combined_1.exr", "_.exr"]
    );
    assert!(names.iter().all(|n| !n.contains('/') && !n.starts_with('.')), "{names:?}");
}
