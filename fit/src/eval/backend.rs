//! Every use `psc eval` makes of the renderer's and the runtime's APIs, in one place, so that a
//! change there is adapted here only: loading a scene on either geometry, material bindings
//! (MTL, truth, assignment files, constants), per-light path-traced renders, G-buffers, images.

use std::path::Path;

use psc_render::camera::{Camera, CameraSpec};
use psc_render::image_io;
use psc_render::{render_gbuffer, LightRadiances, MaterialBinding, RenderOptions, Renderer, Scene};
use psc_runtime::library::Library;

use super::EvalError;

pub use psc_render::image_io::{linear_to_srgb, srgb_to_linear};

/// A linear RGB image, row 0 at the top.
pub type Image = Vec<[f32; 3]>;

/// One geometry of the scene (the coarse model or the true mesh) with its BVH, built once and
/// reused for every method and view.
pub struct GeometryContext {
    pub scene: Scene,
    renderer: Renderer,
}

impl GeometryContext {
    /// `mesh`: `None` for the scene's own model, else the OBJ to use in its place.
    pub fn load(scene_dir: &Path, mesh: Option<&Path>) -> Result<Self, EvalError> {
        let scene = Scene::load_with_mesh(scene_dir, mesh)?;
        let mut warnings = Vec::new();
        let materials = scene.mtl_materials(&mut warnings);
        // Per-light renders select lights by area, so the radiances given here do not matter.
        let renderer = Renderer::new(&scene, materials, &LightRadiances::unit(&scene))?;
        Ok(GeometryContext { scene, renderer })
    }

    pub fn part_names(&self) -> &[String] {
        &self.scene.mesh.part_names
    }

    /// Names of the light slots: the area lights, then "environment" if the scene has one.
    pub fn slot_names(&self) -> &[String] {
        self.renderer.slot_names()
    }

    pub fn light_names(&self) -> Vec<String> {
        self.scene.lights.iter().map(|l| l.name.clone()).collect()
    }

    pub fn has_environment(&self) -> bool {
        self.scene.environment.is_some()
    }

    /// The scene's own (MTL) materials, one per part.
    pub fn mtl_materials(&self) -> Vec<MaterialBinding> {
        let mut warnings = Vec::new();
        self.scene.mtl_materials(&mut warnings)
    }

    /// The dev scene's true materials (truth/truth.json), one per part.
    pub fn truth_materials(&self, warnings: &mut Vec<String>) -> Result<Vec<MaterialBinding>, EvalError> {
        Ok(psc_render::truth::truth_materials(&self.scene, warnings)?)
    }

    /// The MTL materials with the parts an assignment file names replaced by library graphs.
    pub fn assigned_materials(&self, path: &Path, library: &Library) -> Result<Vec<MaterialBinding>, EvalError> {
        let mut bindings = self.mtl_materials();
        psc_runtime::assign::apply_assignment(path, library, self.part_names(), &mut bindings)
            .map_err(|e| EvalError(e.to_string()))?;
        Ok(bindings)
    }

    /// One image per light slot at unit radiance, path-traced from `camera` at `width`×`height`.
    pub fn render_slots(
        &mut self,
        materials: &[MaterialBinding],
        camera: &CameraSpec,
        width: usize,
        height: usize,
        render: &RenderSettings,
    ) -> Result<Vec<Image>, EvalError> {
        let camera = Camera::new(camera, width, height, "eval camera")?;
        self.renderer.set_materials(materials.to_vec())?;
        let opts = RenderOptions {
            width,
            height,
            spp: render.spp,
            seed: render.seed,
            max_depth: render.max_depth,
            threads: render.threads,
            per_light: true,
            ..Default::default()
        };
        let out = self.renderer.render(&camera, &opts)?;
        Ok(out.per_light.into_iter().map(|(_, img)| img).collect())
    }

    /// Part index + 1 (0 = no part) and the mesh uv of what each pixel centre sees.
    pub fn part_ids_and_uvs(
        &self,
        camera: &CameraSpec,
        width: usize,
        height: usize,
    ) -> Result<(Vec<u16>, Vec<[f32; 2]>), EvalError> {
        let camera = Camera::new(camera, width, height, "eval camera")?;
        let gb =
            render_gbuffer(self.renderer.geometry(), &camera, self.part_names(), &self.renderer.lights().names, None)?;
        let n_parts = self.part_names().len() as u16;
        let ids = gb.part_id.into_iter().map(|id| if id > n_parts { 0 } else { id }).collect();
        Ok((ids, gb.uv))
    }
}

/// What every render of one evaluation shares.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub spp: u32,
    pub seed: u64,
    pub max_depth: u32,
    pub threads: Option<usize>,
}

/// Σ radiance_k × slot image k.
pub fn combine_slots(slots: &[Image], radiances: &[[f32; 3]]) -> Image {
    let n = slots.first().map_or(0, |s| s.len());
    let mut out = vec![[0.0f32; 3]; n];
    for (img, r) in slots.iter().zip(radiances) {
        for (o, p) in out.iter_mut().zip(img) {
            for k in 0..3 {
                o[k] += p[k] * r[k];
            }
        }
    }
    out
}

/// A constant material (flat normal).
pub fn constant_material(albedo: [f32; 3], roughness: f32) -> MaterialBinding {
    MaterialBinding::constant(albedo, roughness)
}

/// Roughness of a binding at a mesh uv (uv transform and roughness scale applied).
pub fn roughness_at(binding: &MaterialBinding, uv: [f32; 2]) -> f32 {
    binding.eval(uv).roughness
}

/// Light radiances of a lights file (`psc render --lights` format), one per scene light, then
/// the environment scale; every scene light must be named, and every value finite and ≥ 0.
pub fn read_lights_file(path: &Path, ctx: &GeometryContext) -> Result<(Vec<[f32; 3]>, [f32; 3]), EvalError> {
    if !path.is_file() {
        return Err(EvalError(format!("{}: not found", path.display())));
    }
    let mut warnings = Vec::new();
    let r = LightRadiances::from_file(path, &ctx.scene, &mut warnings)?;
    // The renderer's reader gives unnamed lights unit radiance; a fit's result must name them.
    let text = std::fs::read_to_string(path).map_err(|e| EvalError(format!("{}: {e}", path.display())))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| EvalError(format!("{}: {e}", path.display())))?;
    let named: Vec<&str> =
        value["lights"].as_array().map_or(Vec::new(), |a| a.iter().filter_map(|l| l["name"].as_str()).collect());
    if let Some(missing) = ctx.scene.lights.iter().find(|l| !named.contains(&l.name.as_str())) {
        return Err(EvalError(format!(
            "{}: no radiance for light '{}' (eval needs every light)",
            path.display(),
            missing.name
        )));
    }
    for (i, c) in r.lights.iter().chain([&r.environment]).enumerate() {
        if !c.iter().all(|x| x.is_finite() && *x >= 0.0) {
            let what =
                ctx.scene.lights.get(i).map_or("the environment scale".to_string(), |l| format!("light '{}'", l.name));
            return Err(EvalError(format!("{}: {what} has a non-finite or negative radiance {c:?}", path.display())));
        }
    }
    Ok((r.lights, r.environment))
}

/// An 8/16-bit image's values scaled to [0, 1] without decoding (sRGB-encoded values).
pub fn read_encoded(path: &Path) -> Result<(usize, usize, Image), EvalError> {
    let img = image_io::read_rgb(path, false)?;
    Ok((img.width, img.height, img.data))
}

pub fn read_labels(path: &Path) -> Result<(usize, usize, Vec<u16>), EvalError> {
    Ok(image_io::read_labels(path)?)
}

/// Write a linear image as an 8-bit sRGB PNG.
pub fn write_png(path: &Path, width: usize, height: usize, linear: &[[f32; 3]]) -> Result<(), EvalError> {
    Ok(image_io::write_rgb(path, width, height, linear)?)
}

pub fn atomic_write(path: &Path, bytes: &[u8]) -> Result<(), EvalError> {
    Ok(image_io::atomic_write(path, bytes)?)
}

/// `truth/scene_true.obj` of a dev scene, if present.
pub fn truth_mesh(scene_dir: &Path) -> Option<std::path::PathBuf> {
    psc_render::truth::truth_mesh(scene_dir)
}
