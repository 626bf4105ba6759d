//! Material assignment files: which library graph, at which parameters and uv transform, shades
//! each part of a scene. `psc render --assign` reads them; the fit writes its result as one.
//!
//! ```json
//! { "parts": {
//!     "floor": { "graph": "oak_planks", "params": { "rows": 8, "light": [0.6, 0.4, 0.2] },
//!                "uv_scale": [2, 2], "uv_offset": [0, 0], "uv_rotation_deg": 0,
//!                "albedo_scale": [1, 1, 1], "roughness_scale": 1 },
//!     "walls": { "graph": "painted_wall" } } }
//! ```
//! - `graph` (required): a graph of the library, by name.
//! - `params`: parameters by name, in the format of `psc bake --params`
//!   ([`crate::params::ParamSpace::from_json`]): parameters not given keep their defaults;
//!   colours are linear `[r, g, b]` or `{"srgb": [r, g, b]}`; numbers are read at `f32`
//!   precision; every value is checked against the parameter's range when the assignment is
//!   bound to a library.
//! - `uv_scale` (a number or `[su, sv]`, each of magnitude in [`UV_SCALE_RANGE`], 1e-4 to 1e4;
//!   negative mirrors), `uv_offset` (`[ou, ov]`),
//!   `uv_rotation_deg`: the texture coordinates the graph sees are
//!   `(s, t) = (su (c u − s v) + ou, sv (s u + c v) + ov)` with `c, s = cos, sin(rotation)`.
//!   Defaults: 1, `[0, 0]`, 0.
//! - `albedo_scale` (`[r, g, b]`, default `[1, 1, 1]`) and `roughness_scale` (default 1)
//!   multiply the graph's albedo and roughness; finite and non-negative.
//!
//! Unknown fields, duplicate keys and values of the wrong type are errors naming the file, the
//! part and the field. Parts the file does not list keep the scene's own (MTL) material.
//! [`Assignment::to_json`] writes every field explicitly (`uv_scale` as `[su, sv]`), and reading
//! it back gives an equal [`Assignment`].

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use psc_render::material::MaterialBinding;
use serde_json::{json, Map, Value};

use crate::json::{self, JsonError};
use crate::library::{Library, Material};
use crate::material::ProceduralMaterial;
use crate::params::{ParamError, ParamSpace};

/// A whole assignment: part name → material.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Assignment {
    pub parts: BTreeMap<String, PartMaterial>,
}

/// The material of one part.
#[derive(Clone, Debug, PartialEq)]
pub struct PartMaterial {
    /// Name of a library graph.
    pub graph: String,
    /// Parameter values by name (see the module docs); unnamed parameters keep their defaults.
    pub params: Map<String, Value>,
    pub uv: UvTransform,
    pub albedo_scale: [f32; 3],
    pub roughness_scale: f32,
}

/// The magnitudes a uv scale may have (texture tiles per mesh uv unit; a negative scale
/// mirrors). The fit's scales are `1.5^k` for `k` in [−3.5, 4.25], about 0.24 to 5.6, and a
/// room's uvs are about a metre per unit, so this admits any real use (a tile of 0.1 mm to one
/// of 10 km) while refusing what only maps a part to one texel (0, a subnormal) or to noise.
pub const UV_SCALE_RANGE: (f32, f32) = (1e-4, 1e4);

/// A uv scale `[su, sv]` is usable when both are finite with magnitude in [`UV_SCALE_RANGE`]
/// (the one check for assignment files and `--set` edits); the error gives the value and the
/// range.
pub fn check_uv_scale(scale: [f32; 2]) -> Result<(), String> {
    let (lo, hi) = UV_SCALE_RANGE;
    match scale.iter().find(|s| !(s.is_finite() && (lo..=hi).contains(&s.abs()))) {
        None => Ok(()),
        Some(&s) => {
            let why = if s == 0.0 { " (a scale of 0 maps the part to one texel)" } else { "" };
            Err(format!("the scale {s:e} is outside the usable range{why}: a uv scale's magnitude must be between {lo:e} and {hi:e}"))
        }
    }
}

/// Scale, rotation and offset of the texture coordinates (see the module docs for the order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    pub scale: [f32; 2],
    pub offset: [f32; 2],
    pub rotation_deg: f32,
}

impl UvTransform {
    pub const IDENTITY: UvTransform = UvTransform { scale: [1.0, 1.0], offset: [0.0, 0.0], rotation_deg: 0.0 };

    /// The 2×3 matrix the renderer applies to the mesh uv (rows of `M` in `(s, t) = M (u, v, 1)`).
    pub fn matrix(&self) -> [[f32; 3]; 2] {
        let [sx, sy] = self.scale;
        let [ox, oy] = self.offset;
        let (s, c) = self.rotation_deg.to_radians().sin_cos();
        [[sx * c, -sx * s, ox], [sy * s, sy * c, oy]]
    }
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform::IDENTITY
    }
}

impl PartMaterial {
    /// A graph at its defaults, untransformed, unscaled.
    pub fn new(graph: impl Into<String>) -> PartMaterial {
        PartMaterial {
            graph: graph.into(),
            params: Map::new(),
            uv: UvTransform::IDENTITY,
            albedo_scale: [1.0; 3],
            roughness_scale: 1.0,
        }
    }

    /// Sets every parameter from a full vector (as a fit holds it), by name.
    pub fn with_param_values(mut self, space: &ParamSpace, values: &[f32]) -> Result<PartMaterial, ParamError> {
        space.check(values)?;
        self.params = space.to_json_map(values)?;
        Ok(self)
    }

    /// The library material and its full parameter vector.
    pub fn resolve(&self, library: &Library) -> Result<(Arc<Material>, Vec<f32>), AssignProblem> {
        let material = library.get(&self.graph).ok_or_else(|| AssignProblem::UnknownGraph {
            graph: self.graph.clone(),
            known: library.names().map(str::to_string).collect(),
        })?;
        let params = ParamSpace::new(&material.graph.info)
            .from_json(&Value::Object(self.params.clone()))
            .map_err(AssignProblem::Param)?;
        Ok((material.clone(), params))
    }

    /// This part's binding for the renderer.
    pub fn binding(&self, library: &Library) -> Result<MaterialBinding, AssignProblem> {
        let (material, params) = self.resolve(library)?;
        let procedural =
            ProceduralMaterial::new(material, params).map_err(|e| AssignProblem::Invalid { message: e.to_string() })?;
        Ok(MaterialBinding {
            material: Arc::new(procedural),
            uv_transform: self.uv.matrix(),
            albedo_scale: self.albedo_scale,
            roughness_scale: self.roughness_scale,
        })
    }

    fn to_json(&self) -> Value {
        let mut o = Map::new();
        o.insert("graph".into(), json!(self.graph));
        if !self.params.is_empty() {
            o.insert("params".into(), Value::Object(self.params.clone()));
        }
        o.insert("uv_scale".into(), json!(self.uv.scale));
        o.insert("uv_offset".into(), json!(self.uv.offset));
        o.insert("uv_rotation_deg".into(), json!(self.uv.rotation_deg));
        o.insert("albedo_scale".into(), json!(self.albedo_scale));
        o.insert("roughness_scale".into(), json!(self.roughness_scale));
        Value::Object(o)
    }

    fn from_json(value: &Value) -> Result<PartMaterial, (Option<&'static str>, AssignProblem)> {
        let obj = value.as_object().ok_or((None, wrong("an object with at least \"graph\"", value)))?;
        for key in obj.keys() {
            if !PART_FIELDS.contains(&key.as_str()) {
                return Err((None, AssignProblem::UnknownField { field: key.clone(), known: &PART_FIELDS }));
            }
        }
        let field = |name: &'static str| obj.get(name);
        let at = |name: &'static str| move |p: AssignProblem| (Some(name), p);
        let graph = match field("graph") {
            Some(Value::String(g)) if !g.is_empty() => g.clone(),
            Some(v) => return Err((Some("graph"), wrong("the name of a library graph", v))),
            None => return Err((None, AssignProblem::MissingField { field: "graph" })),
        };
        let params = match field("params") {
            None => Map::new(),
            Some(Value::Object(m)) => m.iter().map(|(k, v)| (k.clone(), at_f32_precision(v))).collect(),
            Some(v) => return Err((Some("params"), wrong("an object of parameter name → value", v))),
        };
        let scale = match field("uv_scale") {
            None => [1.0, 1.0],
            Some(v @ Value::Number(_)) => {
                let s = finite(v, "a non-zero number or [su, sv]").map_err(at("uv_scale"))?;
                [s, s]
            }
            Some(v) => floats::<2>(v, "a non-zero number or [su, sv]").map_err(at("uv_scale"))?,
        };
        check_uv_scale(scale).map_err(|message| (Some("uv_scale"), AssignProblem::Invalid { message }))?;
        let offset =
            field("uv_offset").map_or(Ok([0.0, 0.0]), |v| floats::<2>(v, "[ou, ov]")).map_err(at("uv_offset"))?;
        let rotation_deg = field("uv_rotation_deg")
            .map_or(Ok(0.0), |v| finite(v, "an angle in degrees"))
            .map_err(at("uv_rotation_deg"))?;
        let albedo_scale = field("albedo_scale")
            .map_or(Ok([1.0; 3]), |v| floats::<3>(v, "[r, g, b], each finite and ≥ 0"))
            .map_err(at("albedo_scale"))?;
        if albedo_scale.iter().any(|&x| x < 0.0) {
            return Err((
                Some("albedo_scale"),
                AssignProblem::Invalid { message: format!("{albedo_scale:?} has a negative channel") },
            ));
        }
        let roughness_scale = field("roughness_scale")
            .map_or(Ok(1.0), |v| finite(v, "a finite number ≥ 0"))
            .map_err(at("roughness_scale"))?;
        if roughness_scale < 0.0 {
            return Err((
                Some("roughness_scale"),
                AssignProblem::Invalid { message: format!("{roughness_scale} is negative") },
            ));
        }
        Ok(PartMaterial {
            graph,
            params,
            uv: UvTransform { scale, offset, rotation_deg },
            albedo_scale,
            roughness_scale,
        })
    }
}

/// `v` with every non-integer number rounded to the nearest `f32` (the precision kernels take),
/// so that an assignment written from `f32` values reads back equal: serde_json's float parser
/// may land one f64 ulp away from the written value. Numbers too large for an `f32` are kept,
/// for the parameter check to refuse.
fn at_f32_precision(v: &Value) -> Value {
    match v {
        Value::Number(n) if n.is_f64() => {
            let x = n.as_f64().unwrap_or(f64::NAN) as f32;
            match serde_json::Number::from_f64(x as f64) {
                Some(r) if x.is_finite() => Value::Number(r),
                _ => v.clone(),
            }
        }
        Value::Array(a) => Value::Array(a.iter().map(at_f32_precision).collect()),
        Value::Object(o) => Value::Object(o.iter().map(|(k, x)| (k.clone(), at_f32_precision(x))).collect()),
        _ => v.clone(),
    }
}

const PART_FIELDS: [&str; 7] =
    ["graph", "params", "uv_scale", "uv_offset", "uv_rotation_deg", "albedo_scale", "roughness_scale"];

fn wrong(expected: &str, found: &Value) -> AssignProblem {
    AssignProblem::WrongType { expected: expected.to_string(), found: crate::params::describe(found) }
}

/// A number that is finite as an `f32`.
fn finite(v: &Value, expected: &str) -> Result<f32, AssignProblem> {
    let x = v.as_f64().ok_or_else(|| wrong(expected, v))?;
    if (x as f32).is_finite() {
        Ok(x as f32)
    } else {
        Err(AssignProblem::Invalid { message: format!("{x:e} is beyond the largest 32-bit float (3.4e38)") })
    }
}

/// An array of exactly `N` finite numbers.
fn floats<const N: usize>(v: &Value, expected: &str) -> Result<[f32; N], AssignProblem> {
    let arr = v.as_array().filter(|a| a.len() == N).ok_or_else(|| wrong(expected, v))?;
    let mut out = [0.0; N];
    for (o, x) in out.iter_mut().zip(arr) {
        *o = finite(x, expected)?;
    }
    Ok(out)
}

impl Assignment {
    /// Reads an assignment file (see the module docs). Checks its shape and values; the graphs
    /// and parameters are checked against a library by [`Assignment::bind`].
    pub fn read(path: &Path) -> Result<Assignment, AssignError> {
        let value = json::read_file(path).map_err(|e| AssignError::file(path, AssignProblem::Json(e)))?;
        Assignment::from_json(&value).map_err(|e| e.in_file(path))
    }

    /// The assignment in a JSON value, as [`Assignment::read`] reads it from a file.
    pub fn from_json(value: &Value) -> Result<Assignment, AssignError> {
        let top = value
            .as_object()
            .ok_or_else(|| AssignError::new(None, None, wrong("an object {\"parts\": {...}}", value)))?;
        if let Some(key) = top.keys().find(|k| *k != "parts") {
            return Err(AssignError::new(
                None,
                None,
                AssignProblem::UnknownField { field: key.clone(), known: &["parts"] },
            ));
        }
        let parts = match top.get("parts") {
            Some(Value::Object(parts)) => parts,
            Some(v) => {
                return Err(AssignError::new(None, Some("parts"), wrong("an object of part name → material", v)))
            }
            None => return Err(AssignError::new(None, None, AssignProblem::MissingField { field: "parts" })),
        };
        let mut out = Assignment::default();
        for (name, v) in parts {
            let part = PartMaterial::from_json(v)
                .map_err(|(field, problem)| AssignError::new(Some(name.clone()), field, problem))?;
            out.parts.insert(name.clone(), part);
        }
        Ok(out)
    }

    /// The assignment as JSON, every field written (see the module docs).
    pub fn to_json(&self) -> Value {
        let parts: Map<String, Value> = self.parts.iter().map(|(k, p)| (k.clone(), p.to_json())).collect();
        json!({ "parts": parts })
    }

    /// Pretty-printed JSON text with a final newline, as written to a file.
    pub fn to_json_string(&self) -> String {
        let mut text = serde_json::to_string_pretty(&self.to_json()).expect("JSON values always serialise");
        text.push('\n');
        text
    }

    /// Replaces the bindings of the parts this assignment names; `part_names[i]` names
    /// `bindings[i]`. Every part, graph and parameter is checked before anything changes.
    pub fn bind(
        &self,
        library: &Library,
        part_names: &[String],
        bindings: &mut [MaterialBinding],
    ) -> Result<(), AssignError> {
        let mut new = Vec::with_capacity(self.parts.len());
        for (part, m) in &self.parts {
            let at = |problem| AssignError::new(Some(part.clone()), None, problem);
            let index = part_names
                .iter()
                .position(|p| p == part)
                .ok_or_else(|| at(AssignProblem::UnknownPart { known: part_names.to_vec() }))?;
            let binding = m.binding(library).map_err(|problem| {
                let field = match problem {
                    AssignProblem::Param(_) => Some("params"),
                    AssignProblem::UnknownGraph { .. } => Some("graph"),
                    _ => None,
                };
                AssignError { field, ..at(problem) }
            })?;
            new.push((index, binding));
        }
        for (index, binding) in new {
            bindings[index] = binding;
        }
        Ok(())
    }
}

/// Reads `path` and replaces the bindings of the parts it names (see [`Assignment::bind`]).
pub fn apply_assignment(
    path: &Path,
    library: &Library,
    part_names: &[String],
    bindings: &mut [MaterialBinding],
) -> Result<(), AssignError> {
    Assignment::read(path)?.bind(library, part_names, bindings).map_err(|e| e.in_file(path))
}

/// What is wrong, without where (see [`AssignError`]).
#[derive(Debug)]
pub enum AssignProblem {
    Json(JsonError),
    UnknownField { field: String, known: &'static [&'static str] },
    MissingField { field: &'static str },
    WrongType { expected: String, found: String },
    Invalid { message: String },
    UnknownPart { known: Vec<String> },
    UnknownGraph { graph: String, known: Vec<String> },
    Param(ParamError),
}

/// A problem with an assignment, located by file, part and field where they apply.
#[derive(Debug)]
pub struct AssignError {
    pub file: Option<PathBuf>,
    pub part: Option<String>,
    pub field: Option<&'static str>,
    /// Boxed: errors stay small for the `Result`s that carry them.
    pub problem: Box<AssignProblem>,
}

impl AssignError {
    fn new(part: Option<String>, field: Option<&'static str>, problem: AssignProblem) -> AssignError {
        AssignError { file: None, part, field, problem: Box::new(problem) }
    }

    fn file(path: &Path, problem: AssignProblem) -> AssignError {
        AssignError { file: Some(path.to_path_buf()), part: None, field: None, problem: Box::new(problem) }
    }

    /// The same error, located in `path`.
    pub fn in_file(mut self, path: &Path) -> AssignError {
        self.file = Some(path.to_path_buf());
        self
    }
}

impl fmt::Display for AssignError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let AssignProblem::Json(e) = &*self.problem {
            return e.fmt(f); // already names the file
        }
        if let Some(file) = &self.file {
            write!(f, "{}: ", file.display())?;
        }
        if let Some(part) = &self.part {
            write!(f, "part `{part}`: ")?;
        }
        if let Some(field) = self.field {
            write!(f, "`{field}`: ")?;
        }
        match &*self.problem {
            AssignProblem::Json(_) => Ok(()),
            AssignProblem::UnknownField { field, known } => {
                write!(f, "unknown field `{field}` (expected one of: {})", known.join(", "))
            }
            AssignProblem::MissingField { field } => write!(f, "the field `{field}` is required"),
            AssignProblem::WrongType { expected, found } => write!(f, "expected {expected}, found {found}"),
            AssignProblem::Invalid { message } => f.write_str(message),
            AssignProblem::UnknownPart { known } => {
                write!(f, "the scene has no such part (parts: {})", known.join(", "))
            }
            AssignProblem::UnknownGraph { graph, known } => {
                write!(f, "no graph `{graph}` in the library (graphs: {})", known.join(", "))
            }
            AssignProblem::Param(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for AssignError {}
