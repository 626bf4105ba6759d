//! Material assignment files: which library graph, at which parameters and uv transform, shades
//! each part of a scene. This is the form in which a fit's result is written and read back.
//!
//! ```json
//! { "parts": {
//!     "floor": { "graph": "oak_planks", "params": { "rows": 8, "light": [0.6, 0.4, 0.2] },
//!                "uv_scale": [2, 2], "uv_offset": [0, 0], "uv_rotation_deg": 0,
//!                "albedo_scale": [1, 1, 1], "roughness_scale": 1 },
//!     "walls": { "graph": "painted_wall" } } }
//! ```
//! `params` has the format of `psc bake --params` ([`crate::params::ParamSpace::from_json`]):
//! parameters not given keep their defaults; colours are linear `[r, g, b]` or
//! `{"srgb": [r, g, b]}`; every value is checked against the parameter's range. Parts not listed
//! keep the scene's own (MTL) material.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use psc_render::material::MaterialBinding;
use serde::Deserialize;

use crate::library::Library;
use crate::material::ProceduralMaterial;
use crate::params::ParamSpace;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct AssignmentFile {
    parts: BTreeMap<String, PartAssignment>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PartAssignment {
    graph: String,
    #[serde(default = "empty_object")]
    params: serde_json::Value,
    #[serde(default)]
    uv_scale: Option<UvScale>,
    #[serde(default)]
    uv_offset: Option<[f32; 2]>,
    #[serde(default)]
    uv_rotation_deg: Option<f32>,
    #[serde(default)]
    albedo_scale: Option<[f32; 3]>,
    #[serde(default)]
    roughness_scale: Option<f32>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum UvScale {
    Uniform(f32),
    PerAxis([f32; 2]),
}

/// Reads `path` and replaces the bindings of the parts it names. `part_names[i]` names
/// `bindings[i]`.
pub fn apply_assignment(
    path: &Path,
    library: &Library,
    part_names: &[String],
    bindings: &mut [MaterialBinding],
) -> Result<(), String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let file: AssignmentFile =
        serde_json::from_str(&text).map_err(|e| format!("{}:{}:{}: {e}", path.display(), e.line(), e.column()))?;
    for (part, a) in &file.parts {
        let at = |msg: String| format!("{}: part `{part}`: {msg}", path.display());
        let index = part_names
            .iter()
            .position(|p| p == part)
            .ok_or_else(|| at(format!("the scene has no such part (parts: {})", part_names.join(", "))))?;
        let material = library.get(&a.graph).ok_or_else(|| {
            let names: Vec<&str> = library.names().collect();
            at(format!("no graph `{}` in the library (graphs: {})", a.graph, names.join(", ")))
        })?;
        let params = ParamSpace::new(&material.graph.info).from_json(&a.params).map_err(|e| at(e.to_string()))?;
        let procedural = ProceduralMaterial::new(material.clone(), params).map_err(at)?;
        let uv_transform = uv_transform(a).map_err(at)?;
        let albedo_scale = a.albedo_scale.unwrap_or([1.0; 3]);
        let roughness_scale = a.roughness_scale.unwrap_or(1.0);
        if albedo_scale.iter().chain([&roughness_scale]).any(|x| !x.is_finite() || *x < 0.0) {
            return Err(at("albedo_scale and roughness_scale must be finite and non-negative".into()));
        }
        bindings[index] =
            MaterialBinding { material: Arc::new(procedural), uv_transform, albedo_scale, roughness_scale };
    }
    Ok(())
}

fn empty_object() -> serde_json::Value {
    serde_json::Value::Object(Default::default())
}

fn uv_transform(a: &PartAssignment) -> Result<[[f32; 3]; 2], String> {
    let (sx, sy) = match a.uv_scale {
        None => (1.0, 1.0),
        Some(UvScale::Uniform(s)) => (s, s),
        Some(UvScale::PerAxis([x, y])) => (x, y),
    };
    let [ox, oy] = a.uv_offset.unwrap_or([0.0, 0.0]);
    let theta = a.uv_rotation_deg.unwrap_or(0.0).to_radians();
    if ![sx, sy, ox, oy, theta].iter().all(|x| x.is_finite()) || sx == 0.0 || sy == 0.0 {
        return Err("uv_scale must be non-zero and uv_offset/uv_rotation_deg finite".into());
    }
    let (s, c) = theta.sin_cos();
    Ok([[sx * c, -sx * s, ox], [sy * s, sy * c, oy]])
}
