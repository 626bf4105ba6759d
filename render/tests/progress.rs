//! Long operations report progress through psc_base::progress (render per row and sample pass,
//! light grids per cell, mesh loading in bytes) without changing their results.

mod common;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use common::*;
use psc_base::progress::Progress;
use psc_render::{
    compute_light_grid, compute_light_grid_with_progress, LightGridOptions, LightRadiances, RenderOptions, Renderer,
    Scene,
};

#[derive(Default)]
struct Record {
    stages: Mutex<Vec<(String, Option<u64>, String)>>,
    finished: AtomicU64,
    done: AtomicU64,
    calls: AtomicU64,
}

impl Progress for Record {
    fn start(&self, stage: &str, total: Option<u64>, unit: &str) {
        self.stages.lock().unwrap().push((stage.into(), total, unit.into()));
        self.done.store(0, Ordering::SeqCst);
        self.calls.store(0, Ordering::SeqCst);
    }
    fn advance(&self, n: u64) {
        self.done.fetch_add(n, Ordering::SeqCst);
        self.calls.fetch_add(1, Ordering::SeqCst);
    }
    fn finish(&self) {
        self.finished.fetch_add(1, Ordering::SeqCst);
    }
}

#[test]
fn a_small_image_with_many_samples_reports_often_and_renders_the_same() {
    let tmp = temp_dir("progress");
    let dir = tmp.path();
    write_scene(dir);
    let rec = Record::default();
    let scene = Scene::load_with_progress(dir, None, &rec).unwrap();
    {
        let stages = rec.stages.lock().unwrap();
        assert_eq!(stages[0].0, "loading room.obj");
        let size = std::fs::metadata(dir.join("room.obj")).unwrap().len();
        assert_eq!(stages[0].1, Some(size));
        assert!(rec.done.load(Ordering::SeqCst) >= size, "every byte of the OBJ is reported");
    }
    let mut w = Vec::new();
    let r =
        Renderer::new_with_progress(&scene, scene.mtl_materials(&mut w), &LightRadiances::unit(&scene), &rec).unwrap();
    assert!(rec.stages.lock().unwrap().iter().any(|s| s.0 == "building BVH"));

    let cam = &scene.views[0].camera;
    let opts = RenderOptions { width: 8, height: 6, spp: 64, seed: 9, threads: Some(2), ..Default::default() };
    let with = r.render_with_progress(cam, &opts, &rec).unwrap();
    let stage = rec.stages.lock().unwrap().last().cloned().unwrap();
    assert_eq!(stage, ("render".to_string(), Some(8 * 6 * 64), "samples".to_string()));
    assert_eq!(rec.done.load(Ordering::SeqCst), 8 * 6 * 64, "every sample is reported once");
    assert!(rec.calls.load(Ordering::SeqCst) >= 256, "reports per row and sample pass, not per row");
    assert_eq!(rec.finished.load(Ordering::SeqCst), 3, "every stage finished");
    // Progress changes nothing (passes keep each pixel's sample order: checked byte for byte
    // against the single-pass renderer of the previous version when they were introduced).
    let without = r.render(cam, &RenderOptions { threads: Some(1), ..opts.clone() }).unwrap();
    assert_eq!(with.image, without.image);

    let g = LightGridOptions { stride: 8, samples_per_bin: 1, ..Default::default() };
    let grid = compute_light_grid_with_progress(&r, cam, &g, &rec).unwrap();
    let cells = (grid.grid_width * grid.grid_height) as u64;
    assert_eq!(rec.stages.lock().unwrap().last().unwrap().1, Some(cells));
    assert_eq!(rec.done.load(Ordering::SeqCst), cells);
    assert_eq!(grid.radiance, compute_light_grid(&r, cam, &g).unwrap().radiance);
}
