//! Dev-scene ground truth (`truth/truth.json`), for validation and `psc render` conveniences
//! only. The fit must never read truth/; nothing else in this crate calls this module.
//!
//! Materials: per part, `albedo.rgb_linear` (constant) or `albedo.texture` (sRGB image, bilinear,
//! repeat) with `uv_transform` (2×3, applied to the OBJ uv), plus a constant `roughness`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Deserialize;

use crate::lights::{LightEntry, LightRadiances, LightsFile};
use crate::material::{ImageMaterial, MaterialBinding, Texture};
use crate::scene::Scene;
use crate::RenderError;

#[derive(Deserialize)]
struct TruthFile {
    #[serde(default)]
    parts: Vec<TruthPart>,
    #[serde(default)]
    linear_views: std::collections::BTreeMap<String, String>,
    #[serde(default)]
    lights: Vec<TruthLight>,
}

#[derive(Deserialize)]
struct TruthLight {
    name: String,
    radiance_rgb: crate::lights::Rgb,
}

#[derive(Deserialize)]
struct TruthPart {
    name: String,
    roughness: f32,
    albedo: TruthAlbedo,
}

#[derive(Deserialize)]
struct TruthAlbedo {
    rgb_linear: Option<[f32; 3]>,
    texture: Option<String>,
    encoding: Option<String>,
    uv_transform: Option<[[f32; 3]; 2]>,
}

pub fn truth_dir(scene_root: &Path) -> PathBuf {
    scene_root.join("truth")
}

fn read(scene_root: &Path) -> Result<TruthFile, RenderError> {
    let path = truth_dir(scene_root).join("truth.json");
    crate::json::read(&path, "truth file (truth/truth.json)")
}

/// The true light radiances of a dev scene (`--lights truth`; validation only).
pub fn truth_radiances(scene: &Scene, warnings: &mut Vec<String>) -> Result<LightRadiances, RenderError> {
    let truth = read(&scene.root)?;
    let file = LightsFile {
        lights: truth.lights.into_iter().map(|l| LightEntry { name: l.name, radiance_rgb: l.radiance_rgb }).collect(),
        environment_scale: None,
    };
    let origin = truth_dir(&scene.root).join("truth.json").display().to_string();
    Ok(LightRadiances::from_lights_file(&file, scene, &origin, warnings))
}

/// The truth materials for the scene's parts; parts truth.json lacks get the MTL material (with
/// a warning).
pub fn truth_materials(scene: &Scene, warnings: &mut Vec<String>) -> Result<Vec<MaterialBinding>, RenderError> {
    let truth = read(&scene.root)?;
    let fallback = scene.mtl_materials(warnings);
    let dir = truth_dir(&scene.root);
    let mut out = Vec::new();
    for (i, name) in scene.mesh.part_names.iter().enumerate() {
        let Some(p) = truth.parts.iter().find(|p| &p.name == name) else {
            warnings.push(format!("truth.json has no part '{name}'; using its MTL material"));
            out.push(fallback[i].clone());
            continue;
        };
        let binding = match (&p.albedo.texture, p.albedo.rgb_linear) {
            (Some(tex), _) => {
                let srgb = p.albedo.encoding.as_deref().is_none_or(|e| e.eq_ignore_ascii_case("srgb"));
                let t = Texture::load(&dir.join(tex), srgb)?;
                MaterialBinding::new(Arc::new(ImageMaterial::new(t, p.roughness)))
                    .with_uv_transform(p.albedo.uv_transform.unwrap_or(crate::material::IDENTITY_UV))
            }
            (None, Some(rgb)) => MaterialBinding::constant(rgb, p.roughness),
            (None, None) => {
                return Err(RenderError::Invalid(format!(
                    "truth.json: part '{name}' has neither texture nor rgb_linear"
                )))
            }
        };
        out.push(binding);
    }
    Ok(out)
}

/// Path of the linear (EXR) truth image of a view, if truth.json lists one.
pub fn truth_linear_view(scene: &Scene, view: &str) -> Option<PathBuf> {
    let truth = read(&scene.root).ok()?;
    truth.linear_views.get(view).map(|rel| scene.root.join(rel))
}

/// `truth/scene_true.obj`, the exact geometry the dev photos were rendered from, if present.
pub fn truth_mesh(scene_root: &Path) -> Option<PathBuf> {
    let p = truth_dir(scene_root).join("scene_true.obj");
    p.is_file().then_some(p)
}
