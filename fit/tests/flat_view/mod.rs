//! A crop of a flat, evenly lit surface seen head-on, for the tests that render library graphs
//! through the layer without a scene (supersampling, selection).

use glam::Vec3;
use psc_fit::layer::{FitPixel, MaterialState, PartView, Sampling, Workspace};
use psc_fit::shading::{LightSample, BINS};
use psc_fit::uvmap::UvTransform;
use psc_runtime::library::Material;

/// A `size`×`size` crop, `step` uv units per pixel, under a uniform light of 0.4 per bin; the
/// target is a flat grey (callers that need a photo set `target` and `target_linear`).
pub fn flat_view(size: usize, step: f32) -> PartView {
    let light = LightSample::new(&[[0.4; 3]; BINS], Vec3::Z);
    let pixels = (0..size * size)
        .map(|i| FitPixel {
            crop_index: i as u32,
            uv: [(i % size) as f32 * step + 0.013, (i / size) as f32 * step + 0.029],
            duv_dx: [step, 0.0],
            duv_dy: [0.0, -step],
            bitangent_sign: 1.0,
            wo_local: Vec3::Z,
            light: light.clone(),
        })
        .collect();
    PartView {
        width: size,
        height: size,
        origin: [0, 0],
        factor: 1,
        pixels,
        weight: vec![1.0; size * size],
        target: vec![[0.5; 3]; size * size],
        target_linear: vec![[0.2; 3]; size * size],
        exposure: [1.0; 3],
        noise: [0.0; 4],
        noise_scale: 1.0,
        faces: Vec::new(),
    }
}

/// A `size`² flat crop whose photo is `material` at its defaults, seen through `uv`.
#[allow(dead_code)] // not every test that shares this module renders a photo
pub fn photo_of(material: &Material, uv: UvTransform, size: usize) -> PartView {
    let mut view = flat_view(size, 1.0 / size as f32);
    let state =
        MaterialState { params: material.graph.info.default_params(), uv, albedo_scale: [1.0; 3], roughness: 0.5 };
    let mut ws = Workspace::default();
    view.render(material, &state, Sampling::default(), &mut ws).unwrap();
    view.target = ws.image.clone();
    view.target_linear = ws.linear.clone();
    view
}
