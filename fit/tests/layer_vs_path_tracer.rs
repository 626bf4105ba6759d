//! The shading layer predicts what the path tracer renders: for every part of a dev scene seen
//! through its own model (no misalignment, no labels), homogeneous materials at each part's
//! pixel-median colour (and two textured graphs under rotated, scaled UV transforms, bound as the
//! fit's output binds them) are shaded by the layer against the view's light grids and
//! path-traced at the same pixels; the part means must agree. This is the contract that lets a fit under
//! the layer be rendered by `psc render` and look like the photo.

use psc_fit::align::align_view;
use psc_fit::layer::{MaterialState, Sampling, Workspace};
use psc_fit::lighting::{self, GridSettings, ShadingGrid};
use psc_fit::observe::ViewObservation;
use psc_fit::targets::{part_view, Window};
use psc_fit::uvmap::UvTransform;
use psc_render::scene::{LightRadiances, Scene};
use psc_render::{RenderOptions, Renderer};
use psc_runtime::library::{default_library_root, Library};

#[allow(dead_code)] // the file serves several test crates
#[path = "../../tests/src/dev_scenes.rs"]
mod dev_scenes;
#[path = "../../tests/src/not_run.rs"]
mod not_run;

fn check_scene(name: &str, library: &Library, graph: &str, uv: UvTransform) -> Vec<(String, usize, [f64; 3])> {
    let Some(dir) = dev_scenes::dev_scene(name, "layer_vs_path_tracer") else { return Vec::new() };
    let scene = Scene::load(&dir).unwrap();
    let n_parts = scene.mesh.part_names.len();
    let mut radiances = LightRadiances::unit(&scene);
    radiances.lights.iter_mut().for_each(|l| *l = [40.0, 38.0, 36.0]);
    let mut renderer = Renderer::new(&scene, scene.mtl_materials(&mut Vec::new()), &radiances).unwrap();
    let mut view = scene.views[0].clone();
    view.labels = None; // M_photo = M_geo: the photo's pixels play no part here
    let obs = ViewObservation::new(&view, &scene.mesh.part_names, renderer.geometry(), 0).unwrap();
    let views = vec![obs];
    let medians = lighting::median_materials(&views, n_parts);
    let colours: Vec<[f32; 3]> = medians.iter().map(|m| m.eval([0.5, 0.5]).albedo).collect();
    let material = library.get(graph).unwrap();
    let states: Vec<MaterialState> = colours
        .iter()
        .map(|c| {
            let info = &material.graph.info;
            let mut params = info.default_params();
            if let Some(p) = info.param("albedo_color") {
                params[p.slot..p.slot + 3].copy_from_slice(c);
            }
            MaterialState { params, uv, albedo_scale: [1.0; 3], roughness: 0.7 }
        })
        .collect();
    // As the fit's output: the graph's roughness map scaled so its mean is the layer's value.
    let bindings = states
        .iter()
        .map(|s| {
            let unscaled = psc_fit::pipeline::binding(library, graph, s, 1.0).unwrap();
            let mean_roughness = (0..1024)
                .map(|i| unscaled.material.eval([(i % 32) as f32 / 32.0, (i / 32) as f32 / 32.0]).roughness)
                .sum::<f32>()
                / 1024.0;
            psc_fit::pipeline::binding(library, graph, s, s.roughness / mean_roughness.max(1e-4)).unwrap()
        })
        .collect();
    renderer.set_materials(bindings).unwrap();
    let grid_settings = GridSettings { stride: 4, samples_per_bin: 4, max_depth: 6 };
    let grids = lighting::view_grids(&renderer, &views, grid_settings, 1).unwrap();
    let radiance: Vec<[f32; 3]> = radiances.lights.clone();
    let shading = ShadingGrid::new(&grids[0], &radiance, views[0].camera.position);
    let obs = &views[0];
    let rendered = renderer
        .render(
            &obs.camera,
            &RenderOptions {
                width: obs.camera.width,
                height: obs.camera.height,
                spp: 128,
                seed: 3,
                ..Default::default()
            },
        )
        .unwrap();
    let mut out = Vec::new();
    let mut ws = Workspace::default();
    for aligned in align_view(obs, 0, n_parts) {
        let Some(pv) =
            part_view(obs, &aligned, renderer.geometry(), &obs.camera, &shading, Window::WHOLE, [1.0; 3], None)
        else {
            continue;
        };
        if pv.pixels.len() < 500 {
            continue;
        }
        let state = &states[aligned.part as usize];
        pv.render(material, state, Sampling::default(), &mut ws).unwrap();
        let (mut layer, mut traced) = ([0.0f64; 3], [0.0f64; 3]);
        for (px, l) in pv.pixels.iter().zip(&ws.linear) {
            let c = px.crop_index as usize;
            let (x, y) = (pv.origin[0] + c % pv.width, pv.origin[1] + c / pv.width);
            let t = rendered.image[y * obs.camera.width + x];
            for k in 0..3 {
                layer[k] += f64::from(l[k]);
                traced[k] += f64::from(t[k]);
            }
        }
        let ratio = [0, 1, 2].map(|k| layer[k] / traced[k]);
        out.push((scene.mesh.part_names[aligned.part as usize].clone(), pv.pixels.len(), ratio));
    }
    out
}

#[test]
fn the_layer_predicts_the_path_tracer_part_by_part() {
    let library = Library::load(&default_library_root()).unwrap();
    let mut worst = 0.0f64;
    let mut compared = 0;
    let cases = [
        ("dev_2", "homogeneous", UvTransform::default()),
        ("dev_4", "homogeneous", UvTransform::default()),
        ("dev_4", "carrara_marble", UvTransform { rotation: 2.7, log_scale: 1.8, offset: [0.8, 0.9] }),
        ("dev_4", "polished_concrete", UvTransform { rotation: 0.5, log_scale: 0.5, offset: [0.2, 0.4] }),
    ];
    for (name, graph, uv) in cases {
        for (part, pixels, ratio) in check_scene(name, &library, graph, uv) {
            let name = format!("{name} {graph}");
            eprintln!(
                "{name:<22} {part:<26} {pixels:>6} px  layer / path tracer {:.3} {:.3} {:.3}",
                ratio[0], ratio[1], ratio[2]
            );
            worst = ratio.iter().fold(worst, |w, r| w.max((r - 1.0).abs()));
            compared += 1;
        }
    }
    if compared == 0 {
        return;
    }
    assert!(compared >= 6, "only {compared} parts compared");
    assert!(worst < 0.06, "the layer and the path tracer disagree by {:.1}% on some part", worst * 100.0);
}
