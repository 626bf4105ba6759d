//! Same seed → same image, whatever the thread count; per-light images add up to the render.

mod common;

use common::*;
use psc_render::{LightRadiances, RenderOptions, Renderer, Scene};

fn setup() -> (Scene, Renderer) {
    let dir = temp_dir("determinism");
    write_scene(&dir);
    let scene = Scene::load(&dir).unwrap();
    let mut w = Vec::new();
    let materials = scene.mtl_materials(&mut w);
    let mut radiances = LightRadiances::unit(&scene);
    radiances.lights[0] = [5.0, 4.0, 3.0];
    let r = Renderer::new(&scene, materials, &radiances).unwrap();
    (scene, r)
}

fn opts(seed: u64, threads: usize) -> RenderOptions {
    RenderOptions { width: W, height: H, spp: 8, seed, threads: Some(threads), ..Default::default() }
}

#[test]
fn same_seed_same_image_across_thread_counts() {
    let (scene, r) = setup();
    let cam = &scene.views[0].camera;
    let a = r.render(cam, &opts(42, 1)).unwrap();
    let b = r.render(cam, &opts(42, 2)).unwrap();
    let c = r.render(cam, &opts(42, 2)).unwrap();
    let d = r.render(cam, &opts(43, 2)).unwrap();
    assert!(a.image.iter().any(|p| p[0] > 0.0), "the test room must be lit");
    assert_eq!(a.image, b.image, "1 vs 2 threads");
    assert_eq!(b.image, c.image, "two runs");
    assert_eq!(a.rays, b.rays);
    assert_ne!(a.image, d.image, "another seed gives another noise pattern");
}

#[test]
fn per_light_images_sum_to_the_render() {
    let (scene, r) = setup();
    let cam = &scene.views[0].camera;
    let mut o = opts(7, 2);
    o.per_light = true;
    let out = r.render(cam, &o).unwrap();
    assert_eq!(out.per_light.len(), 1);
    assert_eq!(out.per_light[0].0, "lamp");
    for (p, q) in out.image.iter().zip(&out.per_light[0].1) {
        let want = [q[0] * 5.0, q[1] * 4.0, q[2] * 3.0];
        for k in 0..3 {
            assert!((p[k] - want[k]).abs() <= 1e-5 * want[k].abs().max(1.0));
        }
    }
}
