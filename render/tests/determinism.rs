//! Same seed → same image, whatever the thread count; per-light images add up to the render.

mod common;

use common::*;
use psc_render::{LightRadiances, RenderOptions, Renderer, Scene};

fn setup() -> (Scene, Renderer) {
    let tmp = temp_dir("determinism");
    let dir = tmp.path();
    write_scene(dir);
    let scene = Scene::load(dir).unwrap();
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

/// The test room with a second, small lamp in a corner: with two lights the power-weighted
/// light selection depends on the radiances. The folder's guard comes along: the tests read the
/// scene's MTL materials after this returns.
fn two_lamp_scene() -> (tempfile::TempDir, Scene) {
    let tmp = temp_dir("two-lamps");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::write(
        dir.join("lights/corner.obj"),
        "v 0.2 2.49 0.2\nv 0.5 2.49 0.2\nv 0.5 2.49 0.5\nv 0.2 2.49 0.5\nvn 0 -1 0\nf 1//1 2//1 3//1 4//1\n",
    )
    .unwrap();
    let manifest = std::fs::read_to_string(dir.join("scene.json")).unwrap().replace(
        r#"{ "name": "lamp", "mesh": "lights/lamp.obj" }"#,
        r#"{ "name": "lamp", "mesh": "lights/lamp.obj" }, { "name": "corner", "mesh": "lights/corner.obj" }"#,
    );
    std::fs::write(dir.join("scene.json"), manifest).unwrap();
    let scene = Scene::load(dir).unwrap();
    assert_eq!(scene.lights.len(), 2);
    (tmp, scene)
}

#[test]
fn a_renderer_retargeted_to_new_radiances_renders_as_one_built_with_them() {
    let (_dir, scene) = two_lamp_scene();
    let mut w = Vec::new();
    let cam = &scene.views[0].camera;
    let mut first = LightRadiances::unit(&scene);
    first.lights = vec![[1.0; 3], [40.0, 30.0, 20.0]];
    let mut second = LightRadiances::unit(&scene);
    second.lights = vec![[6.0, 5.0, 4.0], [0.5; 3]];

    let fresh = Renderer::new(&scene, scene.mtl_materials(&mut w), &second).unwrap();
    let mut retargeted = Renderer::new(&scene, scene.mtl_materials(&mut w), &first).unwrap();
    let before = retargeted.render(cam, &opts(3, 2)).unwrap();
    retargeted.set_radiances(&second).unwrap();
    let want = fresh.render(cam, &opts(3, 2)).unwrap();
    let got = retargeted.render(cam, &opts(3, 2)).unwrap();
    assert_eq!(got.image, want.image, "re-targeted vs freshly built");
    assert_eq!(got.rays, want.rays, "the same paths: the light selection was rebuilt");
    assert_ne!(before.image, got.image);
    assert_eq!(retargeted.radiances().lights, second.lights);
}

#[test]
fn invalid_radiances_are_refused_and_change_nothing() {
    let (_dir, scene) = two_lamp_scene();
    let mut w = Vec::new();
    let good = LightRadiances::unit(&scene);
    let mut r = Renderer::new(&scene, scene.mtl_materials(&mut w), &good).unwrap();
    for bad in [
        vec![[1.0; 3]],
        vec![[1.0; 3], [-1.0, 0.0, 0.0]],
        vec![[f32::NAN; 3], [1.0; 3]],
        vec![[f32::INFINITY; 3], [1.0; 3]],
    ] {
        let mut l = good.clone();
        l.lights = bad.clone();
        let e = r.set_radiances(&l).expect_err("refused").to_string();
        assert!(e.contains("radiance") || e.contains("lights"), "{e}");
        assert!(Renderer::new(&scene, scene.mtl_materials(&mut w), &l).is_err(), "{bad:?}");
    }
    assert_eq!(r.radiances().lights, good.lights);
}

/// A pattern that differs per part and varies across each part's uv in albedo, roughness and
/// normal, so a sample handed to the wrong path of a packet shows.
struct Waves {
    freq: f32,
}

impl psc_render::SurfaceMaterial for Waves {
    fn eval(&self, uv: [f32; 2]) -> psc_render::SurfaceSample {
        let (a, b) = ((uv[0] * self.freq).sin(), (uv[1] * self.freq * 0.7).cos());
        psc_render::SurfaceSample {
            albedo: [0.45 + 0.4 * a, 0.5 + 0.3 * b, 0.4 + 0.2 * a * b],
            roughness: 0.5 + 0.45 * b,
            normal: [0.3 * a, -0.2 * b, 1.0],
        }
    }

    /// Evaluated back to front, as a batch implementation may: only the pairing of points and
    /// samples is promised.
    fn eval_batch(&self, uvs: &[[f32; 2]], out: &mut [psc_render::SurfaceSample]) {
        for k in (0..uvs.len()).rev() {
            out[k] = self.eval(uvs[k]);
        }
    }
}

/// The render loop traces neighbouring pixels' paths in lockstep and shades the hits that share
/// a part in one batch; every pixel must still be what its paths give one at a time through
/// [`Renderer::li`], bit for bit (a row that is not a whole number of packets included).
#[test]
fn packets_of_paths_render_what_single_paths_do() {
    let (scene, _) = setup();
    let materials = (0..scene.mesh.part_names.len())
        .map(|k| psc_render::MaterialBinding::new(std::sync::Arc::new(Waves { freq: 5.0 + 3.0 * k as f32 })))
        .collect();
    let mut radiances = LightRadiances::unit(&scene);
    radiances.lights[0] = [5.0, 4.0, 3.0];
    let r = Renderer::new(&scene, materials, &radiances).unwrap();
    let cam = &scene.views[0].camera;
    let o = opts(11, 2);
    let got = r.render(cam, &o).unwrap();
    let cfg = o.path_config();
    let mut want = Vec::new();
    for y in 0..H {
        for x in 0..W {
            let mut acc = vec![glam::Vec3::ZERO; r.n_slots()];
            for s in 0..o.spp {
                let mut rng = psc_render::rng::Rng::new(o.seed, (y * W + x) as u64, s as u64);
                let j = rng.next_2d();
                let d = cam.direction(x as f32 + j[0], y as f32 + j[1]);
                let mut st = psc_render::integrator::PathState { rng, rays: 0, out: &mut acc };
                r.li(cam.position, d, &cfg, &mut st);
            }
            let inv = 1.0 / o.spp as f32;
            let px = acc.iter().map(|a| *a * inv).zip(r.slot_radiance()).fold(glam::Vec3::ZERO, |t, (v, l)| t + v * *l);
            want.push(px.to_array());
        }
    }
    const { assert!(!W.is_multiple_of(16), "a row should end in a partial packet") };
    assert!(got.image.iter().any(|p| p[0] > 0.0), "the test room must be lit");
    let differing = got.image.iter().zip(&want).filter(|(a, b)| a != b).count();
    assert_eq!(differing, 0, "{differing} of {} pixels differ from single paths", W * H);
}
