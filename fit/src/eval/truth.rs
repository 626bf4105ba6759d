//! Reading a dev scene's ground truth (`truth/truth.json`: novel views with their label images,
//! relit views, the true light radiances and the relit ones) and assembling the list of images
//! `psc eval` compares against: the input views (the photos themselves), the novel views and the
//! relit views. Only the evaluation reads `truth/`.

use std::collections::BTreeMap;
use std::path::Path;

use psc_render::camera::CameraSpec;
use serde::Deserialize;

use super::backend::{self, GeometryContext, Image};
use super::EvalError;

#[derive(Deserialize)]
struct TruthFile {
    #[serde(default)]
    lights: Vec<TruthLight>,
    #[serde(default)]
    parts: Vec<TruthPart>,
    #[serde(default)]
    novel_views: Vec<NovelView>,
    #[serde(default)]
    relit_views: Vec<RelitView>,
    environment_scale: Option<serde_json::Value>,
}

#[derive(Deserialize)]
struct TruthLight {
    name: String,
    radiance_rgb: [f32; 3],
    #[serde(flatten)]
    other: BTreeMap<String, serde_json::Value>,
}

#[derive(Deserialize)]
struct TruthPart {
    name: String,
    label: u16,
    /// What made the true texture ("planks", "stripes", "plaster", "plain", "photo", …).
    #[serde(default)]
    kind: Option<String>,
}

#[derive(Deserialize)]
struct NovelView {
    name: String,
    image: String,
    parts: String,
    camera: CameraSpec,
}

#[derive(Deserialize)]
struct RelitView {
    name: String,
    image: String,
    view: String,
    camera: CameraSpec,
    radiance_key: String,
}

/// Which images a row of the table averages.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum ViewKind {
    Input,
    Novel,
    Relit,
}

impl ViewKind {
    pub fn name(self) -> &'static str {
        match self {
            ViewKind::Input => "input",
            ViewKind::Novel => "novel",
            ViewKind::Relit => "relit",
        }
    }
}

/// Light radiances: one per scene light (scene order) and the environment scale.
#[derive(Clone, Debug, PartialEq)]
pub struct Radiances {
    pub lights: Vec<[f32; 3]>,
    pub environment: [f32; 3],
}

/// One image to compare against.
pub struct EvalView {
    pub name: String,
    pub kind: ViewKind,
    pub camera: CameraSpec,
    pub width: usize,
    pub height: usize,
    /// The ground truth, sRGB-encoded values in [0, 1].
    pub truth: Image,
    /// Label values (0 = unlabelled) and what they name; `None` when the view has no labels.
    pub labels: Option<(Vec<u16>, BTreeMap<u16, String>)>,
    /// For relit views: the relit radiance of light k is the method's radiance times `ratio[k]`
    /// (per channel); `None` for input and novel views.
    pub relight: Option<Radiances>,
}

/// The ground truth of a dev scene.
pub struct Truth {
    pub views: Vec<EvalView>,
    /// The true radiances (truth.json `radiance_rgb`).
    pub lights: Radiances,
    /// The true relit radiances, per relit view name.
    pub relit_lights: BTreeMap<String, Radiances>,
    /// Per true part, the kind of its texture (truth.json `parts[].kind`), where given.
    pub part_kinds: BTreeMap<String, String>,
    pub warnings: Vec<String>,
}

fn read_truth_file(scene_dir: &Path) -> Result<TruthFile, EvalError> {
    let dir = scene_dir.join("truth");
    if !dir.is_dir() {
        return Err(EvalError(format!(
            "{}: no truth/ folder; psc eval needs a scene with ground truth (a dev scene)",
            scene_dir.display()
        )));
    }
    let path = dir.join("truth.json");
    let text = std::fs::read_to_string(&path).map_err(|e| EvalError(format!("{}: {e}", path.display())))?;
    serde_json::from_str(&text).map_err(|e| EvalError(format!("{}:{}:{}: {e}", path.display(), e.line(), e.column())))
}

fn rgb_of(value: &serde_json::Value) -> Option<[f32; 3]> {
    match value {
        serde_json::Value::Number(n) => n.as_f64().map(|x| [x as f32; 3]),
        serde_json::Value::Array(a) if a.len() == 3 => {
            let v: Vec<f32> = a.iter().filter_map(|x| x.as_f64()).map(|x| x as f32).collect();
            (v.len() == 3).then(|| [v[0], v[1], v[2]])
        }
        _ => None,
    }
}

fn finite(c: &[f32; 3]) -> bool {
    c.iter().all(|x| x.is_finite() && *x >= 0.0)
}

/// Read the image and check it has the size of its label image.
fn truth_image(path: &Path, size: Option<(usize, usize)>) -> Result<(usize, usize, Image), EvalError> {
    let (w, h, img) = backend::read_encoded(path)?;
    if let Some((lw, lh)) = size {
        if (lw, lh) != (w, h) {
            return Err(EvalError(format!(
                "{}: the image is {w}x{h} but its label image is {lw}x{lh}",
                path.display()
            )));
        }
    }
    Ok((w, h, img))
}

/// Read `truth/` of the scene `ctx` was loaded from (the coarse model's context: input views and
/// their labels come from scene.json).
pub fn load(ctx: &GeometryContext) -> Result<Truth, EvalError> {
    let scene_dir = ctx.scene.root.clone();
    let file = read_truth_file(&scene_dir)?;
    let truth_path = scene_dir.join("truth").join("truth.json");
    let mut warnings = Vec::new();

    // True radiances, in scene light order.
    let mut lights = Vec::new();
    for l in &ctx.scene.lights {
        let t = file
            .lights
            .iter()
            .find(|t| t.name == l.name)
            .ok_or_else(|| EvalError(format!("{}: no light '{}'", truth_path.display(), l.name)))?;
        if !finite(&t.radiance_rgb) {
            return Err(EvalError(format!("{}: light '{}' has a bad radiance_rgb", truth_path.display(), l.name)));
        }
        lights.push(t.radiance_rgb);
    }
    let environment = match &file.environment_scale {
        Some(v) => rgb_of(v).filter(finite).ok_or_else(|| {
            EvalError(format!("{}: environment_scale must be a number or [r, g, b] ≥ 0", truth_path.display()))
        })?,
        None => [1.0; 3],
    };
    let true_lights = Radiances { lights, environment };

    let mut views = Vec::new();
    for v in &ctx.scene.views {
        let (w, h, img) = truth_image(&v.image, v.labels.as_ref().map(|l| (l.width, l.height)))?;
        let labels = v.labels.as_ref().map(|l| (l.data.clone(), v.part_labels.clone()));
        if labels.is_none() {
            warnings.push(format!("view '{}' has no part labels: only its SSIM is measured", v.name));
        }
        views.push(EvalView {
            name: v.name.clone(),
            kind: ViewKind::Input,
            camera: v.camera_spec.clone(),
            width: w,
            height: h,
            truth: img,
            labels,
            relight: None,
        });
    }

    let truth_labels: BTreeMap<u16, String> = file.parts.iter().map(|p| (p.label, p.name.clone())).collect();
    for n in &file.novel_views {
        let label_path = scene_dir.join(&n.parts);
        let (lw, lh, data) = backend::read_labels(&label_path)?;
        let (w, h, img) = truth_image(&scene_dir.join(&n.image), Some((lw, lh)))?;
        let mut unknown: Vec<u16> = data.iter().copied().filter(|l| *l != 0 && !truth_labels.contains_key(l)).collect();
        unknown.sort_unstable();
        unknown.dedup();
        if !unknown.is_empty() {
            warnings.push(format!("novel view '{}': label values {unknown:?} name no part; not measured", n.name));
        }
        views.push(EvalView {
            name: n.name.clone(),
            kind: ViewKind::Novel,
            camera: n.camera.clone(),
            width: w,
            height: h,
            truth: img,
            labels: Some((data, truth_labels.clone())),
            relight: None,
        });
    }

    let mut relit_lights = BTreeMap::new();
    for r in &file.relit_views {
        let base = ctx.scene.view(&r.view).ok_or_else(|| {
            EvalError(format!(
                "{}: relit view '{}' names view '{}', which scene.json lacks",
                truth_path.display(),
                r.name,
                r.view
            ))
        })?;
        let (w, h, img) = truth_image(&scene_dir.join(&r.image), Some((base.width, base.height)))?;
        let mut ratio = Vec::new();
        let mut relit = Vec::new();
        for (l, orig) in ctx.scene.lights.iter().zip(&true_lights.lights) {
            let t = file.lights.iter().find(|t| t.name == l.name).expect("checked above");
            let value = t.other.get(&r.radiance_key).and_then(rgb_of).filter(finite).ok_or_else(|| {
                EvalError(format!(
                    "{}: light '{}' has no valid '{}' for relit view '{}'",
                    truth_path.display(),
                    l.name,
                    r.radiance_key,
                    r.name
                ))
            })?;
            let mut q = [0.0f32; 3];
            for k in 0..3 {
                q[k] = if orig[k] > 0.0 {
                    value[k] / orig[k]
                } else if value[k] == 0.0 {
                    0.0
                } else {
                    return Err(EvalError(format!(
                        "{}: light '{}' is off (radiance 0) but relit on: no ratio to apply",
                        truth_path.display(),
                        l.name
                    )));
                };
            }
            ratio.push(q);
            relit.push(value);
        }
        // The environment keeps its scale when relit (the dev scenes have none).
        relit_lights.insert(r.name.clone(), Radiances { lights: relit, environment: true_lights.environment });
        views.push(EvalView {
            name: r.name.clone(),
            kind: ViewKind::Relit,
            camera: r.camera.clone(),
            width: w,
            height: h,
            truth: img,
            labels: base.labels.as_ref().map(|l| (l.data.clone(), base.part_labels.clone())),
            relight: Some(Radiances { lights: ratio, environment: [1.0; 3] }),
        });
    }
    let part_kinds = file.parts.iter().filter_map(|p| Some((p.name.clone(), p.kind.clone()?))).collect();
    Ok(Truth { views, lights: true_lights, relit_lights, part_kinds, warnings })
}

impl Radiances {
    /// Per-channel product (relit radiances from a ratio).
    pub fn times(&self, ratio: &Radiances) -> Radiances {
        let mul = |a: &[f32; 3], b: &[f32; 3]| [a[0] * b[0], a[1] * b[1], a[2] * b[2]];
        Radiances {
            lights: self.lights.iter().zip(&ratio.lights).map(|(a, b)| mul(a, b)).collect(),
            environment: mul(&self.environment, &ratio.environment),
        }
    }

    /// Slot radiances in the renderer's slot order (lights, then the environment if any).
    pub fn slots(&self, has_environment: bool) -> Vec<[f32; 3]> {
        let mut v = self.lights.clone();
        if has_environment {
            v.push(self.environment);
        }
        v
    }
}
