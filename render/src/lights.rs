//! Light radiances: the `--lights` file (a public type that reads and writes), where the
//! radiances a render uses come from, and their validation.
//!
//! File format (`photoscene` lights, what `psc render --lights` reads and `psc fit` writes):
//! `{"lights": [{"name": "ceiling0", "radiance_rgb": [r, g, b]}, ...], "environment_scale": s}`.
//! A radiance is linear RGB: three numbers, or one number for a grey triple (`radiance` is
//! accepted for `radiance_rgb`); `environment_scale` likewise, optional (default 1). Every value
//! must be finite, non-negative and representable as an f32; each light is listed at most once;
//! unknown fields are errors. Lights the scene has but the file does not name keep unit radiance
//! (a warning); lights the file names but the scene lacks are ignored (a warning).
//!
//! Truth never leaks: without a lights file the radiances are the documented default (unit
//! radiance, said in a warning); the dev scenes' `truth/truth.json` is read only when asked for
//! by name ([`LightsSource::Truth`], `psc render --lights truth`).

use std::fmt;
use std::path::{Path, PathBuf};

use serde::de::{self, Deserializer, SeqAccess, Unexpected, Visitor};
use serde::{Deserialize, Serialize, Serializer};

use crate::scene::Scene;
use crate::RenderError;

/// A linear RGB value of a lights file: finite, non-negative, representable as f32. Reads from
/// a number (grey) or `[r, g, b]`; writes as `[r, g, b]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rgb(pub [f32; 3]);

impl Serialize for Rgb {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(s)
    }
}

const EXPECTED_RGB: &str = "a non-negative number or an array [r, g, b] of three non-negative numbers";

/// One component: a finite, non-negative number that fits in an f32.
fn component<E: de::Error>(x: f64) -> Result<f32, E> {
    if !x.is_finite() {
        return Err(E::invalid_value(Unexpected::Float(x), &"a finite number"));
    }
    if x < 0.0 {
        return Err(E::invalid_value(Unexpected::Float(x), &"a non-negative number (radiance cannot be negative)"));
    }
    if !(x as f32).is_finite() {
        return Err(E::custom(format_args!(
            "{x:e} is larger than the largest f32 ({:e}); expected a radiance that fits in 32-bit floats",
            f32::MAX
        )));
    }
    Ok(x as f32)
}

struct Component(f32);

impl<'de> Deserialize<'de> for Component {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Component;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a non-negative number")
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<Component, E> {
                component(x).map(Component)
            }
            fn visit_u64<E: de::Error>(self, x: u64) -> Result<Component, E> {
                component(x as f64).map(Component)
            }
            fn visit_i64<E: de::Error>(self, x: i64) -> Result<Component, E> {
                component(x as f64).map(Component)
            }
        }
        d.deserialize_any(V)
    }
}

impl<'de> Deserialize<'de> for Rgb {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Rgb;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(EXPECTED_RGB)
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<Rgb, E> {
                component(x).map(|c| Rgb([c; 3]))
            }
            fn visit_u64<E: de::Error>(self, x: u64) -> Result<Rgb, E> {
                self.visit_f64(x as f64)
            }
            fn visit_i64<E: de::Error>(self, x: i64) -> Result<Rgb, E> {
                self.visit_f64(x as f64)
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Rgb, A::Error> {
                let mut out = [0.0f32; 3];
                for (i, slot) in out.iter_mut().enumerate() {
                    match seq.next_element::<Component>()? {
                        Some(c) => *slot = c.0,
                        None => return Err(de::Error::invalid_length(i, &"three numbers [r, g, b]")),
                    }
                }
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::invalid_length(4, &"three numbers [r, g, b]"));
                }
                Ok(Rgb(out))
            }
        }
        d.deserialize_any(V)
    }
}

/// One light of a lights file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightEntry {
    pub name: String,
    #[serde(alias = "radiance")]
    pub radiance_rgb: Rgb,
}

/// A lights file (format in the module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightsFile {
    #[serde(default)]
    pub lights: Vec<LightEntry>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment_scale: Option<Rgb>,
}

impl LightsFile {
    /// Parse and validate the text of the lights file at `path` (named in errors).
    pub fn parse(path: &Path, text: &str) -> Result<Self, RenderError> {
        let file: LightsFile = crate::json::parse(path, text)?;
        file.check(path)?;
        Ok(file)
    }

    /// Read and validate a lights file.
    pub fn read(path: &Path) -> Result<Self, RenderError> {
        let text = crate::json::read_text(path, "lights file")?;
        Self::parse(path, &text)
    }

    /// Every light at most once (values are checked while parsing).
    fn check(&self, path: &Path) -> Result<(), RenderError> {
        let mut first: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
        for (i, l) in self.lights.iter().enumerate() {
            if let Some(&j) = first.get(l.name.as_str()) {
                return Err(RenderError::Invalid(format!(
                    "{}: light '{}' is listed twice (lights[{j}] and lights[{i}]); expected each light once",
                    path.display(),
                    l.name
                )));
            }
            first.insert(&l.name, i);
        }
        Ok(())
    }

    /// The file that gives `radiances` to the lights `names` (the scene's, in order).
    pub fn from_radiances(radiances: &LightRadiances, names: &[String]) -> Self {
        LightsFile {
            lights: names
                .iter()
                .zip(&radiances.lights)
                .map(|(name, &rgb)| LightEntry { name: name.clone(), radiance_rgb: Rgb(rgb) })
                .collect(),
            environment_scale: Some(Rgb(radiances.environment)),
        }
    }

    /// Pretty JSON text of the file.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a lights file always serialises") + "\n"
    }

    /// Write the file atomically (a reader never sees half of it).
    pub fn write(&self, path: &Path) -> Result<(), RenderError> {
        crate::image_io::atomic_write(path, self.to_json().as_bytes())
    }
}

/// Where the radiances of a render come from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LightsSource {
    /// Unit radiance for every light and environment scale 1 (said in a warning).
    Default,
    /// A lights file.
    File(PathBuf),
    /// The dev scenes' `truth/truth.json` (validation only; asked for by name).
    Truth,
}

impl LightsSource {
    /// The CLI convention: no argument = [`LightsSource::Default`], the word `truth` =
    /// [`LightsSource::Truth`], anything else a file (`./truth` names a file called truth).
    pub fn from_arg(arg: Option<&Path>) -> Self {
        match arg {
            None => LightsSource::Default,
            Some(p) if p.as_os_str() == "truth" => LightsSource::Truth,
            Some(p) => LightsSource::File(p.to_path_buf()),
        }
    }
}

/// Radiance (linear RGB) of each light of a scene and the environment scale.
#[derive(Clone, Debug, PartialEq)]
pub struct LightRadiances {
    /// One entry per [`Scene::lights`], same order.
    pub lights: Vec<[f32; 3]>,
    pub environment: [f32; 3],
    /// Where the values came from, for messages.
    pub source: String,
}

impl LightRadiances {
    /// Every light at unit radiance, environment scale 1.
    pub fn unit(scene: &Scene) -> Self {
        LightRadiances {
            lights: vec![[1.0; 3]; scene.lights.len()],
            environment: [1.0; 3],
            source: "unit radiance".into(),
        }
    }

    /// Check that there is one radiance per light (`names`, the scene's lights in order) and that
    /// every value is finite and non-negative.
    pub fn validate(&self, names: &[String]) -> Result<(), RenderError> {
        if self.lights.len() != names.len() {
            return Err(RenderError::Invalid(format!(
                "{}: {} light radiances for {} lights",
                self.source,
                self.lights.len(),
                names.len()
            )));
        }
        let ok = |c: &[f32; 3]| c.iter().all(|x| x.is_finite() && *x >= 0.0);
        for (rgb, name) in self.lights.iter().zip(names) {
            if !ok(rgb) {
                return Err(RenderError::Invalid(format!(
                    "{}: radiance of light '{name}' must be finite and non-negative, found {rgb:?}",
                    self.source
                )));
            }
        }
        if !ok(&self.environment) {
            return Err(RenderError::Invalid(format!(
                "{}: the environment scale must be finite and non-negative, found {:?}",
                self.source, self.environment
            )));
        }
        Ok(())
    }

    /// The radiances a lights file gives the scene's lights; `origin` names the file in
    /// messages. Lights the file does not name keep unit radiance (with a warning).
    pub fn from_lights_file(file: &LightsFile, scene: &Scene, origin: &str, warnings: &mut Vec<String>) -> Self {
        let mut out = Self::unit(scene);
        out.source = origin.to_string();
        for (i, l) in scene.lights.iter().enumerate() {
            match file.lights.iter().find(|e| e.name == l.name) {
                Some(e) => out.lights[i] = e.radiance_rgb.0,
                None => warnings.push(format!("{origin}: no radiance for light '{}'; using 1", l.name)),
            }
        }
        // Named one by one up to a few: a file of thousands would bury every other message.
        const NAMED: usize = 5;
        let unknown: Vec<&str> = file
            .lights
            .iter()
            .filter(|e| !scene.lights.iter().any(|l| l.name == e.name))
            .map(|e| e.name.as_str())
            .collect();
        for name in unknown.iter().take(NAMED) {
            warnings.push(format!("{origin}: light '{name}' is not in the scene; ignored"));
        }
        if unknown.len() > NAMED {
            warnings.push(format!("{origin}: {} more lights not in the scene; ignored", unknown.len() - NAMED));
        }
        if let Some(s) = file.environment_scale {
            out.environment = s.0;
        }
        out
    }

    /// Read a lights file for `scene` (format in the module docs).
    pub fn from_file(path: &Path, scene: &Scene, warnings: &mut Vec<String>) -> Result<Self, RenderError> {
        let file = LightsFile::read(path)?;
        Ok(Self::from_lights_file(&file, scene, &path.display().to_string(), warnings))
    }

    /// The radiances `source` gives; [`LightsSource::Default`] adds a warning saying that unit
    /// radiance is used.
    pub fn resolve(scene: &Scene, source: &LightsSource, warnings: &mut Vec<String>) -> Result<Self, RenderError> {
        match source {
            LightsSource::File(p) => Self::from_file(p, scene, warnings),
            LightsSource::Truth => crate::truth::truth_radiances(scene, warnings),
            LightsSource::Default => {
                if !scene.lights.is_empty() || scene.environment.is_some() {
                    warnings.push(
                        "no lights file given: every light has unit radiance [1, 1, 1] and the environment scale \
                         is 1 (give a lights file, or `truth` for a dev scene's true radiances)"
                            .into(),
                    );
                }
                let mut out = Self::unit(scene);
                out.source = "unit radiance (no lights file given)".into();
                Ok(out)
            }
        }
    }
}
