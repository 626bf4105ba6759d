//! Environment lighting: a diffuse floor under a uniform sky is a white-furnace case
//! (radiance = albedo × sky radiance), and a non-uniform sky is importance-sampled without bias.

mod common;

use common::temp_dir;
use psc_render::{image_io, LightRadiances, RenderOptions, Renderer, Scene};

fn sky_scene(sky: impl Fn(usize, usize) -> [f32; 3]) -> tempfile::TempDir {
    let tmp = temp_dir("env");
    let dir = tmp.path();
    std::fs::create_dir_all(dir.join("views")).unwrap();
    std::fs::write(
        dir.join("floor.obj"),
        "v -50 0 -50\nv -50 0 50\nv 50 0 50\nv 50 0 -50\nvt 0 0\nvt 0 1\nvt 1 1\nvt 1 0\nusemtl floor\nf 1/1 2/2 3/3 4/4\n",
    )
    .unwrap();
    std::fs::write(dir.join("floor.mtl"), "newmtl floor\nKd 0.5 0.5 0.5\n").unwrap();
    let (w, h) = (32, 16);
    let env: Vec<[f32; 3]> = (0..w * h).map(|i| sky(i % w, i / w)).collect();
    image_io::write_rgb(&dir.join("sky.exr"), w, h, &env).unwrap();
    image_io::write_rgb(&dir.join("views/v.png"), 16, 12, &vec![[0.0; 3]; 16 * 12]).unwrap();
    std::fs::write(
        dir.join("scene.json"),
        r#"{ "format": "photoscene-scene/1", "mesh": "floor.obj",
             "views": [ { "name": "v", "image": "views/v.png",
                          "camera": { "position": [0, 2, 0.01], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov_y_deg": 30 } } ],
             "lights": [], "environment": { "image": "sky.exr" } }"#,
    )
    .unwrap();
    tmp
}

fn mean_red(dir: &std::path::Path, spp: u32) -> f32 {
    let scene = Scene::load(dir).unwrap();
    assert!(scene.lights.is_empty() && scene.environment.is_some());
    let mut w = Vec::new();
    let r = Renderer::new(&scene, scene.mtl_materials(&mut w), &LightRadiances::unit(&scene)).unwrap();
    let opts = RenderOptions { width: 16, height: 12, spp, seed: 5, diffuse_only: true, ..Default::default() };
    let out = r.render(&scene.views[0].camera, &opts).unwrap();
    out.image.iter().map(|p| p[0]).sum::<f32>() / out.image.len() as f32
}

#[test]
fn uniform_sky_white_furnace() {
    let dir = sky_scene(|_, _| [2.0, 2.0, 2.0]);
    let v = mean_red(dir.path(), 64);
    // albedo 0.5 × radiance 2 = 1 (the floor is 100 m wide: the horizon gap is negligible).
    assert!((v - 1.0).abs() < 0.01, "{v}");
}

#[test]
fn bright_sun_patch_is_unbiased() {
    // A small bright patch high in the sky plus a dim sky: the expected floor radiance is
    // albedo/π × ∫ L cos over the upper hemisphere, computed here by quadrature over texels.
    let (w, h) = (32usize, 16usize);
    let sky = move |x: usize, y: usize| if (x, y) == (5, 2) { [400.0; 3] } else { [0.1; 3] };
    let dir = sky_scene(sky);
    let mut e = 0.0f64;
    for y in 0..h / 2 {
        for x in 0..w {
            // texel solid angle × cos θ, integrated exactly over the texel's rows
            let (t0, t1) =
                (std::f64::consts::PI * y as f64 / h as f64, std::f64::consts::PI * (y + 1) as f64 / h as f64);
            let cos_int = 0.5 * (t1.sin().powi(2) - t0.sin().powi(2)); // ∫ cosθ sinθ dθ
            e += sky(x, y)[0] as f64 * cos_int * 2.0 * std::f64::consts::PI / w as f64;
        }
    }
    let expect = 0.5 / std::f64::consts::PI * e;
    let v = mean_red(dir.path(), 64) as f64;
    assert!((v / expect - 1.0).abs() < 0.03, "rendered {v}, expected {expect}");
}
