//! The fit's targets for the first view of a dev scene, built as the fit builds them before its
//! light rounds (pixel-median materials, one common radiance, the render-noise check), for the
//! tests that look at what the losses are given. Reads `truth/truth.json` for the parts'
//! texture kinds, as tests may; the fit does not. A test crate using it declares `not_run`
//! (`tests/src/not_run.rs`) at its root, where `dev_scenes` looks for it.

use psc_fit::align::align_view;
use psc_fit::layer::PartView;
use psc_fit::lighting::{self, GridSettings, ShadingGrid};
use psc_fit::observe::ViewObservation;
use psc_fit::pipeline::FitOptions;
use psc_fit::render_noise;
use psc_fit::targets::part_view;
use psc_render::scene::{LightRadiances, Scene};
use psc_render::Renderer;

#[allow(dead_code)] // the file serves several test crates
#[path = "../../../tests/src/dev_scenes.rs"]
mod dev_scenes;

/// One part's target in the view.
#[allow(dead_code)] // not every test crate reads every field
pub struct DevPart {
    pub name: String,
    /// The truth's texture kind (`plain`, `photo`, `planks`, …).
    pub kind: String,
    pub view: PartView,
}

/// Every part of dev scene `scene`'s first view with at least `min_usable` usable pixels, its
/// target built at the fit's budget of 4096 fit pixels; None when the scene is missing (said
/// loudly by `dev_scene`; `test` names the caller).
pub fn first_view_parts(scene: &str, test: &str, min_usable: usize) -> Option<Vec<DevPart>> {
    let dir = dev_scenes::dev_scene(scene, test)?;
    let loaded = Scene::load(&dir).unwrap();
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth/truth.json")).unwrap()).unwrap();
    let kind_of = |part: &str| {
        let parts = truth["parts"].as_array().unwrap();
        let p = parts.iter().find(|p| p["name"] == part).unwrap();
        p["kind"].as_str().unwrap().to_string()
    };
    let n_parts = loaded.mesh.part_names.len();
    let mut renderer =
        Renderer::new(&loaded, loaded.mtl_materials(&mut Vec::new()), &LightRadiances::unit(&loaded)).unwrap();
    let views = vec![ViewObservation::new(&loaded.views[0], &loaded.mesh.part_names, renderer.geometry(), 0).unwrap()];
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
    let fit_window = FitOptions::default().fit_window();
    let parts = aligned[0]
        .iter()
        .filter(|a| a.usable.len() >= min_usable)
        .map(|a| {
            let view =
                part_view(obs, a, renderer.geometry(), &obs.camera, &shading, fit_window, [1.0; 3], Some(&noise[0]))
                    .unwrap();
            let name = loaded.mesh.part_names[a.part as usize].clone();
            DevPart { kind: kind_of(&name), name, view }
        })
        .collect();
    Some(parts)
}
