//! Parameter vectors of a graph: the one place that knows how a graph's declared parameters map
//! to the flat `f32` vector its kernels take, and every conversion of that vector.
//!
//! A graph's parameters ([`psc_compiler::GraphInfo::params`]) occupy consecutive *slots* in
//! declaration order: one per float or int, three (linear r, g, b) per colour. Kernels take
//! natural units. This module gives, for that vector:
//! - defaults and random variants ([`ParamSpace::random`], seeded [`SplitMix64`], the sequence
//!   `psc bake --random` and the contact sheet use);
//! - JSON in and out, by parameter name ([`ParamSpace::from_json`], [`ParamSpace::to_json`]):
//!   numbers for floats and ints, `[r, g, b]` (linear) or `{"srgb": [r, g, b]}` for colours in;
//!   linear `[r, g, b]` out;
//! - the unit cube: every slot mapped affinely to [0, 1] by its declared range
//!   ([`ParamSpace::to_unit`], [`ParamSpace::from_unit`]) and gradients carried across that map
//!   ([`ParamSpace::unit_gradient`]), the space the fit's optimiser works in;
//! - projection onto the declared ranges, integers rounded ([`ParamSpace::project`]).
//!
//! Every check returns a [`ParamError`] naming the parameter; callers add the file.

use std::fmt;

use psc_base::color::{linear_to_srgb, srgb_to_linear};
use psc_base::SplitMix64;
use psc_compiler::{GraphInfo, ParamInfo, ParamKind};
use serde_json::Value;

/// What a slot holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlotKind {
    /// A float parameter: differentiable.
    Continuous,
    /// An integer parameter: searched, never differentiated.
    Discrete,
    /// Channel 0, 1 or 2 (r, g, b; linear) of a colour parameter: differentiable.
    ColorChannel(u8),
}

/// One slot of the parameter vector with its declared range.
#[derive(Clone, Debug, PartialEq)]
pub struct Slot {
    /// Index of the parameter in [`GraphInfo::params`] (and [`ParamSpace::params`]).
    pub param: usize,
    pub kind: SlotKind,
    pub min: f32,
    pub max: f32,
}

impl Slot {
    pub fn is_differentiable(&self) -> bool {
        self.kind != SlotKind::Discrete
    }

    fn span(&self) -> f32 {
        self.max - self.min
    }
}

/// A problem with a parameter vector or a parameter file's contents.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamError {
    /// The JSON value holding the parameters is not an object.
    NotAnObject { found: String },
    /// A name the graph does not declare.
    Unknown { graph: String, name: String, known: Vec<String> },
    /// A value of the wrong JSON type (`expected` says what would do).
    WrongType { name: String, expected: String, found: String },
    /// A finite number outside the declared range (`channel` for colours).
    OutOfRange { name: String, channel: Option<usize>, value: f64, min: f32, max: f32 },
    /// An integer parameter given a fractional value.
    NotAnInteger { name: String, value: f64 },
    /// NaN or an infinity (in a vector, or a number too large for `f32`).
    NotFinite { name: String, channel: Option<usize> },
    /// A vector of the wrong length for the graph.
    WrongLength { graph: String, expected: usize, found: usize },
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let channel = |c: &Option<usize>| c.map(|c| format!(" channel {c} ({})", ["r", "g", "b"][c % 3]));
        match self {
            ParamError::NotAnObject { found } => {
                write!(f, "parameters must be a JSON object of name → value, found {found}")
            }
            ParamError::Unknown { graph, name, known } if known.is_empty() => {
                write!(f, "graph `{graph}` has no parameters, but `{name}` was given")
            }
            ParamError::Unknown { graph, name, known } => {
                write!(f, "graph `{graph}` has no parameter `{name}` (it has: {})", known.join(", "))
            }
            ParamError::WrongType { name, expected, found } => {
                write!(f, "`{name}` must be {expected}, found {found}")
            }
            ParamError::OutOfRange { name, channel: c, value, min, max } => write!(
                f,
                "`{name}`{} = {} is outside its range [{min}, {max}]",
                channel(c).unwrap_or_default(),
                shortest(*value)
            ),
            ParamError::NotAnInteger { name, value } => {
                write!(f, "`{name}` = {} must be an integer (it is a discrete parameter)", shortest(*value))
            }
            ParamError::NotFinite { name, channel: c } => {
                write!(f, "`{name}`{} is not a finite number", channel(c).unwrap_or_default())
            }
            ParamError::WrongLength { graph, expected, found } => {
                write!(f, "graph `{graph}` takes {expected} parameter values, got {found}")
            }
        }
    }
}

impl std::error::Error for ParamError {}

/// The parameter vector of one graph: its parameters, their slots and ranges.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamSpace {
    graph: String,
    params: Vec<ParamInfo>,
    slots: Vec<Slot>,
}

impl ParamSpace {
    pub fn new(info: &GraphInfo) -> ParamSpace {
        let mut slots = vec![Slot { param: 0, kind: SlotKind::Continuous, min: 0.0, max: 0.0 }; info.num_slots()];
        for (i, p) in info.params.iter().enumerate() {
            for c in 0..p.width() {
                let kind = match p.kind {
                    ParamKind::Continuous { .. } => SlotKind::Continuous,
                    ParamKind::Discrete { .. } => SlotKind::Discrete,
                    ParamKind::Color => SlotKind::ColorChannel(c as u8),
                };
                let (min, max) = p.bounds();
                slots[p.slot + c] = Slot { param: i, kind, min, max };
            }
        }
        ParamSpace { graph: info.name.clone(), params: info.params.clone(), slots }
    }

    /// The graph's name, for messages.
    pub fn graph(&self) -> &str {
        &self.graph
    }

    /// The declared parameters, in declaration (= slot) order.
    pub fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    pub fn slots(&self) -> &[Slot] {
        &self.slots
    }

    /// Number of slots (the length of every parameter vector of this graph).
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    pub fn param(&self, name: &str) -> Option<&ParamInfo> {
        self.params.iter().find(|p| p.name == name)
    }

    /// Every parameter at its declared default.
    pub fn defaults(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.len()];
        for p in &self.params {
            out[p.slot..p.slot + p.width()].copy_from_slice(&p.default);
        }
        out
    }

    /// A random parameter vector: floats uniform over their range, integers uniform over their
    /// values, colours the default scaled by 0.7–1.3 in sRGB plus up to ±0.08 per channel (so
    /// that variants stay plausible members of the material's family). Draws from `rng` in
    /// parameter order; the sequence is part of `psc bake --random`'s output and must not change.
    pub fn random(&self, rng: &mut SplitMix64) -> Vec<f32> {
        let mut out = self.defaults();
        for p in &self.params {
            match p.kind {
                ParamKind::Continuous { min, max } => out[p.slot] = min + (max - min) * rng.next_f32(),
                ParamKind::Discrete { min, max } => {
                    let span = (max - min + 1) as u64;
                    out[p.slot] = (min + (rng.next_u64() % span) as i64) as f32;
                }
                ParamKind::Color => {
                    // A common brightness change and a smaller independent shift per channel.
                    let scale = 0.7 + 0.6 * rng.next_f32();
                    for c in 0..3 {
                        let s = linear_to_srgb(p.default[c]) * scale + 0.16 * (rng.next_f32() - 0.5);
                        out[p.slot + c] = srgb_to_linear(s);
                    }
                }
            }
        }
        out
    }

    /// Checks that `values` is a valid vector: the right length, finite, every slot in its
    /// range, integers integral.
    pub fn check(&self, values: &[f32]) -> Result<(), ParamError> {
        self.check_len(values.len())?;
        for (s, &x) in self.slots.iter().zip(values) {
            let p = &self.params[s.param];
            let channel = self.channel(s);
            if !x.is_finite() {
                return Err(ParamError::NotFinite { name: p.name.clone(), channel });
            }
            if x < s.min || x > s.max {
                return Err(self.out_of_range(s, channel, x as f64));
            }
            if s.kind == SlotKind::Discrete && x.fract() != 0.0 {
                return Err(ParamError::NotAnInteger { name: p.name.clone(), value: x as f64 });
            }
        }
        Ok(())
    }

    /// Reads parameters by name: a JSON object mapping names to numbers (floats and ints) or to
    /// `[r, g, b]` (colours, linear) or `{"srgb": [r, g, b]}`. Parameters not named keep their
    /// defaults; unknown names, wrong types, non-integral ints and values outside the declared
    /// ranges are errors.
    pub fn from_json(&self, json: &Value) -> Result<Vec<f32>, ParamError> {
        let obj = json.as_object().ok_or_else(|| ParamError::NotAnObject { found: describe(json) })?;
        let mut out = self.defaults();
        for (name, value) in obj {
            let p = self.param(name).ok_or_else(|| ParamError::Unknown {
                graph: self.graph.clone(),
                name: name.clone(),
                known: self.params.iter().map(|p| p.name.clone()).collect(),
            })?;
            let slot = &self.slots[p.slot];
            match p.kind {
                ParamKind::Continuous { min, max } => {
                    let expected = || format!("a number in [{min}, {max}]");
                    out[p.slot] = self.number(name, value, None, expected, slot)?;
                }
                ParamKind::Discrete { min, max } => {
                    let expected = || format!("an integer in [{min}, {max}]");
                    let x = self.number(name, value, None, expected, slot)?;
                    if x.fract() != 0.0 {
                        return Err(ParamError::NotAnInteger { name: name.clone(), value: x as f64 });
                    }
                    out[p.slot] = x;
                }
                ParamKind::Color => {
                    let expected = "[r, g, b] (linear, each in [0, 1]) or {\"srgb\": [r, g, b]}";
                    let wrong = |v: &Value| ParamError::WrongType {
                        name: name.clone(),
                        expected: expected.into(),
                        found: describe(v),
                    };
                    let (rgb, srgb) = match value {
                        Value::Object(o) if o.len() == 1 && o.contains_key("srgb") => (&o["srgb"], true),
                        Value::Object(_) => return Err(wrong(value)),
                        v => (v, false),
                    };
                    let arr = rgb.as_array().filter(|a| a.len() == 3).ok_or_else(|| wrong(rgb))?;
                    for (c, x) in arr.iter().enumerate() {
                        let x = self.number(name, x, Some(c), || "a number in [0, 1]".into(), slot)?;
                        out[p.slot + c] = if srgb { srgb_to_linear(x) } else { x };
                    }
                }
            }
        }
        Ok(out)
    }

    /// One JSON number of parameter `name`, finite as an `f32` and inside `slot`'s range.
    fn number(
        &self,
        name: &str,
        value: &Value,
        channel: Option<usize>,
        expected: impl Fn() -> String,
        slot: &Slot,
    ) -> Result<f32, ParamError> {
        let x = value.as_f64().ok_or_else(|| ParamError::WrongType {
            name: name.to_string(),
            expected: expected(),
            found: describe(value),
        })?;
        if !(x as f32).is_finite() {
            return Err(ParamError::NotFinite { name: name.to_string(), channel });
        }
        if x < slot.min as f64 || x > slot.max as f64 {
            return Err(self.out_of_range(slot, channel, x));
        }
        Ok(x as f32)
    }

    /// The vector as a JSON object that [`ParamSpace::from_json`] reads back to the same bits:
    /// floats as numbers, integers as integers, colours as linear `[r, g, b]`.
    pub fn to_json(&self, values: &[f32]) -> Result<Value, ParamError> {
        self.to_json_map(values).map(Value::Object)
    }

    /// [`ParamSpace::to_json`]'s object itself.
    pub fn to_json_map(&self, values: &[f32]) -> Result<serde_json::Map<String, Value>, ParamError> {
        self.check_len(values.len())?;
        let mut obj = serde_json::Map::new();
        for p in &self.params {
            let v = match p.kind {
                ParamKind::Color => serde_json::json!([values[p.slot], values[p.slot + 1], values[p.slot + 2]]),
                ParamKind::Discrete { .. } => serde_json::json!(values[p.slot] as i64),
                ParamKind::Continuous { .. } => serde_json::json!(values[p.slot]),
            };
            obj.insert(p.name.clone(), v);
        }
        Ok(obj)
    }

    /// Natural units to the unit cube: slot `k` becomes `(x - min) / (max - min)` (colours are
    /// already in [0, 1] and stay as they are). An affine map, so values outside the range map
    /// outside [0, 1] rather than being clamped.
    pub fn to_unit(&self, values: &[f32]) -> Result<Vec<f32>, ParamError> {
        self.check_len(values.len())?;
        Ok(self
            .slots
            .iter()
            .zip(values)
            .map(|(s, &x)| if s.span() > 0.0 { (x - s.min) / s.span() } else { 0.0 })
            .collect())
    }

    /// The inverse of [`ParamSpace::to_unit`]: `min + u (max - min)`. Neither clamps nor rounds;
    /// [`ParamSpace::project`] makes the result a valid vector.
    pub fn from_unit(&self, unit: &[f32]) -> Result<Vec<f32>, ParamError> {
        self.check_len(unit.len())?;
        Ok(self.slots.iter().zip(unit).map(|(s, &u)| s.min + u * s.span()).collect())
    }

    /// A gradient with respect to natural units (as the adjoint kernels give it) to the gradient
    /// with respect to the unit-cube coordinates: the chain rule through [`ParamSpace::from_unit`]
    /// multiplies slot `k` by `max - min`. Integer slots get 0: they are not differentiated.
    pub fn unit_gradient(&self, d_natural: &[f64]) -> Result<Vec<f64>, ParamError> {
        self.check_len(d_natural.len())?;
        Ok(self
            .slots
            .iter()
            .zip(d_natural)
            .map(|(s, &g)| if s.is_differentiable() { g * f64::from(s.span()) } else { 0.0 })
            .collect())
    }

    /// Clamps every slot into its declared range and rounds integer slots to the nearest
    /// integer (halves away from zero) inside it. Infinities clamp to the nearer bound; NaN is an
    /// error, since no value of the range is nearer to it than another.
    pub fn project(&self, values: &mut [f32]) -> Result<(), ParamError> {
        self.check_len(values.len())?;
        for (s, x) in self.slots.iter().zip(values.iter_mut()) {
            if x.is_nan() {
                return Err(ParamError::NotFinite {
                    name: self.params[s.param].name.clone(),
                    channel: self.channel(s),
                });
            }
            let y = if s.kind == SlotKind::Discrete { x.round() } else { *x };
            *x = y.clamp(s.min, s.max);
        }
        Ok(())
    }

    fn channel(&self, s: &Slot) -> Option<usize> {
        match s.kind {
            SlotKind::ColorChannel(c) => Some(c as usize),
            _ => None,
        }
    }

    fn out_of_range(&self, s: &Slot, channel: Option<usize>, value: f64) -> ParamError {
        ParamError::OutOfRange { name: self.params[s.param].name.clone(), channel, value, min: s.min, max: s.max }
    }

    fn check_len(&self, found: usize) -> Result<(), ParamError> {
        if found == self.len() {
            Ok(())
        } else {
            Err(ParamError::WrongLength { graph: self.graph.clone(), expected: self.len(), found })
        }
    }
}

/// `x` as written: as an `f32` when it is one (values from vectors), else in full.
fn shortest(x: f64) -> String {
    if (x as f32) as f64 == x {
        format!("{}", x as f32)
    } else {
        format!("{x}")
    }
}

/// A JSON value's type and, when short, the value itself, for messages.
pub(crate) fn describe(v: &Value) -> String {
    let kind = match v {
        Value::Null => return "null".into(),
        Value::Bool(b) => return format!("{b}"),
        Value::Number(n) => return format!("the number {n}"),
        Value::String(_) => "a string",
        Value::Array(a) => return format!("an array of {} element{}", a.len(), if a.len() == 1 { "" } else { "s" }),
        Value::Object(_) => "an object",
    };
    let text = v.to_string();
    if text.len() <= 40 {
        format!("{kind} {text}")
    } else {
        kind.to_string()
    }
}

#[cfg(test)]
mod tests;
