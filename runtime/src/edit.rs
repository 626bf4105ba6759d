//! Edits of a material assignment from the command line: `psc render --set part.param=value`.
//!
//! An edit is `<part>.<target>=<values>`, values comma-separated (linear for colours):
//! - `<part>.<param>`: a parameter the part's graph declares (one number, or `r,g,b` for a
//!   colour), checked against the declared range; integers must be integral;
//! - `<part>.albedo_scale=r,g,b` (or one number for all three), `<part>.roughness_scale=x`:
//!   finite and ≥ 0;
//! - `<part>.uv.rotation=degrees`, `<part>.uv.scale=s` or `su,sv` (magnitude 1e-4 to 1e4,
//!   `assign::UV_SCALE_RANGE`),
//!   `<part>.uv.log_scale=k` (the fit's parametrisation: scale `1.5^k` on both axes),
//!   `<part>.uv.offset=ou,ov`.
//!
//! Part names may contain dots: the part is the longest prefix that names a part of the
//! assignment. Every error says what exists (the parts, the graph's parameters with their
//! ranges, the edit targets), so a typo is fixed from the message alone.

use std::fmt;

use psc_compiler::ParamKind;
use serde_json::{json, Value};

use crate::assign::Assignment;
use crate::library::Library;
use crate::params::ParamSpace;

/// The fit's UV log-scale base (`psc_fit::uvmap::LOG_SCALE_BASE`; the fit sits above this crate).
pub const UV_LOG_SCALE_BASE: f32 = 1.5;

/// The targets besides the graph's own parameters.
pub const SCALE_TARGETS: [&str; 6] =
    ["albedo_scale", "roughness_scale", "uv.rotation", "uv.scale", "uv.log_scale", "uv.offset"];

/// One `--set` edit, parsed but not yet checked against an assignment.
#[derive(Clone, Debug, PartialEq)]
pub struct Edit {
    /// `part.target`, as given (split once the parts are known).
    pub key: String,
    pub values: Vec<f64>,
}

/// Why an edit cannot be applied; the message says what exists.
#[derive(Clone, Debug, PartialEq)]
pub struct EditError(pub String);

impl fmt::Display for EditError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for EditError {}

impl Edit {
    /// Parses `part.target=v1,v2,…` (see the module docs).
    pub fn parse(text: &str) -> Result<Edit, EditError> {
        let bad = |why: &str| {
            EditError(format!("--set `{text}`: {why}; expected part.param=value (e.g. floor.ring_freq=30, walls.albedo_scale=0.8,0.8,0.9)"))
        };
        let (key, values) = text.split_once('=').ok_or_else(|| bad("no `=`"))?;
        let key = key.trim();
        if !key.contains('.') || key.starts_with('.') || key.ends_with('.') {
            return Err(bad("the name must be part.param"));
        }
        let values = values
            .split(',')
            .map(|v| {
                let v = v.trim();
                match v.parse::<f64>() {
                    Ok(x) if x.is_finite() && (x as f32).is_finite() => Ok(x),
                    Ok(_) => Err(bad(&format!("`{v}` is not a finite 32-bit number"))),
                    Err(_) => Err(bad(&format!("`{v}` is not a number"))),
                }
            })
            .collect::<Result<Vec<f64>, EditError>>()?;
        Ok(Edit { key: key.to_string(), values })
    }

    /// Applies the edit to `assignment`, checking the part, the target and the values (against
    /// the graph's declared parameters in `library`). Nothing changes on error.
    pub fn apply(&self, assignment: &mut Assignment, library: &Library) -> Result<(), EditError> {
        let err = |why: String| EditError(format!("--set {}: {why}", self.key));
        // The longest part name that is a prefix followed by a dot.
        let part = assignment
            .parts
            .keys()
            .filter(|p| {
                self.key.len() > p.len() + 1 && self.key.starts_with(p.as_str()) && self.key.as_bytes()[p.len()] == b'.'
            })
            .max_by_key(|p| p.len())
            .cloned()
            .ok_or_else(|| {
                let known: Vec<&str> = assignment.parts.keys().map(String::as_str).collect();
                err(format!(
                    "no part is named `{}` (parts: {})",
                    self.key.split('.').next().unwrap_or(""),
                    known.join(", ")
                ))
            })?;
        let target = &self.key[part.len() + 1..];
        let m = assignment.parts.get_mut(&part).expect("found among the keys");
        let x = &self.values;
        let count = |n: &[usize]| -> Result<(), EditError> {
            if n.contains(&x.len()) {
                Ok(())
            } else {
                let want: Vec<String> = n.iter().map(|k| k.to_string()).collect();
                Err(err(format!("takes {} value(s), got {}", want.join(" or "), x.len())))
            }
        };
        let f = |v: f64| v as f32;
        match target {
            "albedo_scale" => {
                count(&[1, 3])?;
                let v = if x.len() == 1 { [f(x[0]); 3] } else { [f(x[0]), f(x[1]), f(x[2])] };
                if v.iter().any(|&c| c < 0.0) {
                    return Err(err(format!("{v:?} has a negative channel (a scale is ≥ 0)")));
                }
                m.albedo_scale = v;
            }
            "roughness_scale" => {
                count(&[1])?;
                if x[0] < 0.0 {
                    return Err(err(format!("{} is negative (a scale is ≥ 0)", x[0])));
                }
                m.roughness_scale = f(x[0]);
            }
            "uv.rotation" => {
                count(&[1])?;
                m.uv.rotation_deg = f(x[0]);
            }
            "uv.offset" => {
                count(&[2])?;
                m.uv.offset = [f(x[0]), f(x[1])];
            }
            "uv.scale" | "uv.log_scale" => {
                count(&[1, 2])?;
                let s: Vec<f32> = if target == "uv.scale" {
                    x.iter().map(|&v| f(v)).collect()
                } else {
                    count(&[1])?;
                    vec![UV_LOG_SCALE_BASE.powf(f(x[0]))]
                };
                let s = [s[0], *s.get(1).unwrap_or(&s[0])];
                crate::assign::check_uv_scale(s).map_err(err)?;
                m.uv.scale = s;
            }
            name => {
                let material =
                    library.get(&m.graph).ok_or_else(|| err(format!("graph `{}` is not in the library", m.graph)))?;
                let space = ParamSpace::new(&material.graph.info);
                let Some(p) = space.param(name) else {
                    return Err(err(format!(
                        "part `{part}` (graph `{}`) has no parameter `{name}`; it has: {}; and for every part: {}",
                        m.graph,
                        describe_params(&space),
                        SCALE_TARGETS.join(", ")
                    )));
                };
                let value = match p.kind {
                    ParamKind::Color => {
                        count(&[3])?;
                        json!(x)
                    }
                    ParamKind::Discrete { .. } => {
                        count(&[1])?;
                        if x[0].fract() != 0.0 {
                            return Err(err(format!("`{name}` is an integer parameter; {} is not an integer", x[0])));
                        }
                        json!(x[0] as i64)
                    }
                    ParamKind::Continuous { .. } => {
                        count(&[1])?;
                        json!(x[0])
                    }
                };
                let mut params = m.params.clone();
                params.insert(name.to_string(), value);
                space.from_json(&Value::Object(params.clone())).map_err(|e| err(e.to_string()))?;
                m.params = params;
            }
        }
        Ok(())
    }
}

/// `name (kind in [min, max])` for every parameter of a graph.
pub fn describe_params(space: &ParamSpace) -> String {
    if space.params().is_empty() {
        return "no parameters".into();
    }
    space
        .params()
        .iter()
        .map(|p| match p.kind {
            ParamKind::Continuous { min, max } => format!("{} (number in [{min}, {max}])", p.name),
            ParamKind::Discrete { min, max } => format!("{} (integer in [{min}, {max}])", p.name),
            ParamKind::Color => format!("{} (colour r,g,b linear, each in [0, 1])", p.name),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Applies `edits` in order to a copy of `assignment`; the first error leaves it unchanged.
pub fn apply_edits(assignment: &Assignment, edits: &[Edit], library: &Library) -> Result<Assignment, EditError> {
    let mut out = assignment.clone();
    for e in edits {
        e.apply(&mut out, library)?;
    }
    Ok(out)
}
