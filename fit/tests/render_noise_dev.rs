//! The render-noise check tells a photo's pixel noise from its finest texture on the dev scenes:
//! the crop of a photo-textured wall (dev_1's gravel, dev_3's bricks, whose noise estimates read
//! two to three times those of the plain parts beside them) has its estimate cut, while every
//! plain part keeps its own, dev_1's ceiling included: lit only by bounces, it is as noisy as
//! the gravel wall, and a photo-wide noise level would have called that noise texture.
//! Reads `truth/truth.json` for the parts' texture kinds, as tests may; the fit does not.

use psc_fit::align::align_view;
use psc_fit::lighting::{self, GridSettings, ShadingGrid};
use psc_fit::observe::ViewObservation;
use psc_fit::render_noise;
use psc_fit::targets::part_view;
use psc_render::scene::{LightRadiances, Scene};
use psc_render::Renderer;

#[allow(dead_code)] // the file serves several test crates
#[path = "../../tests/src/dev_scenes.rs"]
mod dev_scenes;
#[path = "../../tests/src/not_run.rs"]
mod not_run;

/// Per part of the scene's first view with at least 2000 usable pixels: its name, true texture
/// kind and the factor the check puts on its crop's noise estimate.
fn noise_factors(name: &str) -> Option<Vec<(String, String, f32)>> {
    let dir = dev_scenes::dev_scene(name, "render_noise_dev")?;
    let scene = Scene::load(&dir).unwrap();
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth/truth.json")).unwrap()).unwrap();
    let kind_of = |part: &str| {
        let parts = truth["parts"].as_array().unwrap();
        let p = parts.iter().find(|p| p["name"] == part).unwrap();
        p["kind"].as_str().unwrap().to_string()
    };
    let n_parts = scene.mesh.part_names.len();
    let mut renderer =
        Renderer::new(&scene, scene.mtl_materials(&mut Vec::new()), &LightRadiances::unit(&scene)).unwrap();
    let views = vec![ViewObservation::new(&scene.views[0], &scene.mesh.part_names, renderer.geometry(), 0).unwrap()];
    // As the fit starts: pixel-median materials and one common radiance.
    renderer.set_materials(lighting::median_materials(&views, n_parts)).unwrap();
    let (common, _) =
        lighting::common_radiance(&views, &lighting::unit_renders(&renderer, &views, 0).unwrap()).unwrap();
    let radiance = vec![common; renderer.n_slots()];
    let aligned = vec![align_view(&views[0], 0, n_parts)];
    let noise = render_noise::estimate(&renderer, &views, &aligned, &radiance, 0).unwrap();
    let grids = lighting::view_grids(&renderer, &views, GridSettings::default(), 0).unwrap();
    let shading = ShadingGrid::new(&grids[0], &radiance, views[0].camera.position);
    let obs = &views[0];
    let mut out = Vec::new();
    for a in aligned[0].iter().filter(|a| a.usable.len() >= 2000) {
        let pv =
            part_view(obs, a, renderer.geometry(), &obs.camera, &shading, 4096, [1.0; 3], Some(&noise[0])).unwrap();
        let part = scene.mesh.part_names[a.part as usize].clone();
        let kind = kind_of(&part);
        out.push((part, kind, pv.noise_scale));
    }
    Some(out)
}

#[test]
fn photo_textures_lose_noise_and_plain_parts_keep_theirs() {
    for (scene, textured) in [("dev_1", "walls"), ("dev_3", "walls_b")] {
        let Some(factors) = noise_factors(scene) else { continue };
        eprintln!("{scene}: {factors:?}");
        let (_, _, f) = factors.iter().find(|(p, _, _)| p == textured).expect("the wall is seen");
        assert!(*f < 0.8, "{scene}: {textured}'s noise estimate kept {f} of itself: {factors:?}");
        let plain: Vec<_> = factors.iter().filter(|(_, k, _)| k == "plain").collect();
        assert!(plain.len() >= 2, "{scene}: {factors:?}");
        for (part, _, f) in plain {
            assert!(*f > 0.95, "{scene}: the plain {part}'s noise estimate was cut to {f} of itself: {factors:?}");
        }
    }
}
