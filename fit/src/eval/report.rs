//! The evaluation's outputs: the Table-2-style text table, the JSON (`photoscene-eval/1`), and
//! the eval folder (`eval.json` + `renders/<geometry>/<method>/<view>.png`), written whole or not at
//! all.

use std::path::{Path, PathBuf};

use psc_base::output::{Replace, StagedDir};

use serde_json::{json, Value};

use super::backend;
use super::{EvalError, Evaluation, Geometry, GraphChoice, Method, Row, ViewKind};

/// The ratio rows of the table: numerator / denominator per metric.
const RATIOS: [(Method, Method); 4] = [
    (Method::Fitted, Method::PixelMedian),
    (Method::Fitted, Method::FlatFitted),
    (Method::FlatFitted, Method::PixelMedian),
    (Method::Oracle, Method::PixelMedian),
];

/// The label of the rows of [`super::UnseenFloor`].
const UNSEEN_FLOOR: &str = "floor of unseen parts";

/// Per metric ratio of two rows; SSIM is compared as 1 − SSIM (lower is better, like the rest).
pub fn ratio(num: &Row, den: &Row) -> [f64; 5] {
    [
        num.rmse / den.rmse,
        num.mean_colour / den.mean_colour,
        num.colour_w1 / den.colour_w1,
        num.contrast_w1 / den.contrast_w1,
        (1.0 - num.ssim) / (1.0 - den.ssim),
    ]
}

fn num(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

fn rgb(c: &[f32; 3]) -> Value {
    json!([c[0], c[1], c[2]])
}

fn render_path(geometry: Geometry, method: Method, view: &str) -> PathBuf {
    Path::new("renders").join(geometry.name()).join(method.slug()).join(format!("{view}.png"))
}

impl Evaluation {
    /// The table printed by `psc eval`: per geometry and view kind, one row per method and one
    /// per ratio.
    pub fn table(&self) -> String {
        let mut s = String::new();
        s.push_str(&format!(
            "psc eval: {} ({} spp, seed {}, {} renders, {:.1} s wall)\n",
            self.scene.display(),
            self.options.spp,
            self.options.seed,
            self.renders,
            self.wall_seconds
        ));
        s.push_str("per part (sRGB, parts >= 200 px, averaged over image x part); SSIM per image; ratio rows: SSIM as 1-SSIM\n");
        s.push_str(&format!(
            "{:<8} {:<6} {:<23} {:>7} {:>7} {:>8} {:>8} {:>7} {:>6} {:>5}\n",
            "geometry", "views", "method", "RMSE", "mean", "colourW1", "contrW1", "SSIM", "parts", "imgs"
        ));
        let mut keys: Vec<(Geometry, ViewKind)> = self.rows.iter().map(|r| (r.geometry, r.kind)).collect();
        keys.dedup();
        for (geometry, kind) in keys {
            let mut first = true;
            let mut label = || {
                let l = if first {
                    format!("{:<8} {:<6}", geometry.name(), kind.name())
                } else {
                    format!("{:<8} {:<6}", "", "")
                };
                first = false;
                l
            };
            for r in self.rows.iter().filter(|r| (r.geometry, r.kind) == (geometry, kind)) {
                s.push_str(&format!(
                    "{} {:<23} {:>7.4} {:>7.4} {:>8.4} {:>8.4} {:>7.4} {:>6} {:>5}\n",
                    label(),
                    r.method.name(),
                    r.rmse,
                    r.mean_colour,
                    r.colour_w1,
                    r.contrast_w1,
                    r.ssim,
                    r.parts,
                    r.images
                ));
            }
            for (a, b) in RATIOS {
                if let (Some(n), Some(d)) = (self.row(geometry, kind, a), self.row(geometry, kind, b)) {
                    let q = ratio(n, d);
                    s.push_str(&format!(
                        "{} {:<23} {:>6.2}x {:>6.2}x {:>7.2}x {:>7.2}x {:>6.2}x\n",
                        label(),
                        format!("{} / {}", a.name(), b.name()),
                        q[0],
                        q[1],
                        q[2],
                        q[3],
                        q[4]
                    ));
                }
            }
            if let Some(f) = self.unseen_floors.iter().find(|f| (f.geometry, f.kind) == (geometry, kind)) {
                s.push_str(&format!(
                    "{} {:<23} {:>6.2}x {:>6.2}x {:>7.2}x {:>7.2}x {:>7}\n",
                    label(),
                    UNSEEN_FLOOR,
                    f.rmse,
                    f.mean_colour,
                    f.colour_w1,
                    f.contrast_w1,
                    "-"
                ));
            }
        }
        if !self.flat_changes.is_empty() {
            let c: Vec<String> = self.flat_changes.iter().map(|(c, part)| format!("{c:.4} ({part})")).collect();
            s.push_str(&format!("flat fit: largest change of a linear albedo channel per round {}\n", c.join(", ")));
        }
        if !self.unseen_parts.is_empty() {
            s.push_str(&format!(
                "parts no input view shows (baselines use the median of all labelled pixels): {}\n",
                self.unseen_parts.join(", ")
            ));
            if !self.unseen_floors.is_empty() {
                s.push_str(&format!(
                    "  '{UNSEEN_FLOOR}' rows: fitted / pixel median with every photographed part scored 0; no fit of those parts goes below it\n"
                ));
            }
        }
        if self.fitted_lights.len() > 1 && self.fitted_lights.len() == self.true_lights.len() {
            let lights = super::metrics::LightRatios::new(&self.fitted_lights, &self.true_lights);
            let rel: Vec<String> = lights.relative().iter().map(|r| format!("{r:.3}")).collect();
            s.push_str(&format!(
                "lights: fitted/true luminance per light over their geometric mean {} (worst {:.1}% off; between two \
                 lights {:.1}% off{}; global scale {:.3})\n",
                rel.join(", "),
                lights.worst() * 100.0,
                lights.between_two() * 100.0,
                self.stated_spread_note(&lights),
                lights.scale
            ));
        }
        let judged: Vec<&GraphChoice> = self.graph_choice.iter().filter(|c| c.matches.is_some()).collect();
        if !self.graph_choice.is_empty() {
            let right = judged.iter().filter(|c| c.matches == Some(true)).count();
            s.push_str(&format!(
                "graph choice: {right} of {} parts with a judged texture kind fitted with the expected family\n",
                judged.len()
            ));
            for c in &self.graph_choice {
                let verdict = match c.matches {
                    Some(true) => "expected",
                    Some(false) => "other family",
                    None => "not judged",
                };
                s.push_str(&format!(
                    "  {:<28} true {:<14} fitted {:<22} ({}) {verdict}\n",
                    c.part, c.kind, c.graph, c.category
                ));
            }
        }
        let times: Vec<String> = self.timings.iter().map(|(n, t)| format!("{n} {t:.1} s")).collect();
        s.push_str(&format!("time: {} (wall {:.1} s)\n", times.join(", "), self.wall_seconds));
        s
    }

    /// What the fit stated for the pair of lights furthest off the truth's ratio: the spread its
    /// light solve gave that pair's log ratio (result.json), beside the error it turned out to have.
    fn stated_spread_note(&self, lights: &super::metrics::LightRatios) -> String {
        let (hi, lo) = lights.extreme_pair();
        let Some(table) = self.stated_light_spread.as_ref().filter(|_| hi != lo) else { return String::new() };
        match table.get(hi).and_then(|row| row.get(lo)) {
            Some(Some(sd)) if *sd < crate::light_solve::DETERMINED_LOG_SD => {
                format!(
                    " against the ±{:.0}% (1 sd) the fit stated for that pair",
                    crate::light_solve::spread_percent(*sd)
                )
            }
            Some(_) => ", a pair the fit stated its photos do not determine".into(),
            None => String::new(),
        }
    }

    /// The evaluation as JSON: options, definitions, baselines, rows, ratios, per-image and
    /// per-part numbers, timings.
    pub fn to_json(&self) -> Value {
        let row = |r: &Row| {
            json!({
                "geometry": r.geometry.name(), "views": r.kind.name(), "method": r.method.name(),
                "rmse": num(r.rmse), "mean_colour": num(r.mean_colour), "colour_w1": num(r.colour_w1),
                "contrast_w1": num(r.contrast_w1), "ssim": num(r.ssim), "parts": r.parts, "images": r.images,
            })
        };
        let mut ratios = Vec::new();
        for r in self.rows.iter().filter(|r| r.method == Method::PixelMedian) {
            for (a, b) in RATIOS {
                if let (Some(n), Some(d)) = (self.row(r.geometry, r.kind, a), self.row(r.geometry, r.kind, b)) {
                    let q = ratio(n, d);
                    ratios.push(json!({
                        "geometry": r.geometry.name(), "views": r.kind.name(),
                        "numerator": a.name(), "denominator": b.name(),
                        "rmse": num(q[0]), "mean_colour": num(q[1]), "colour_w1": num(q[2]),
                        "contrast_w1": num(q[3]), "one_minus_ssim": num(q[4]),
                    }));
                }
            }
        }
        let images: Vec<Value> = self
            .images
            .iter()
            .map(|im| {
                let parts: Vec<Value> = im
                    .parts
                    .iter()
                    .map(|p| {
                        json!({
                            "part": p.part, "pixels": p.pixels, "rmse": num(p.rmse),
                            "mean_colour": num(p.mean_colour), "colour_w1": num(p.colour_w1),
                            "contrast_w1": p.contrast_w1.map_or(Value::Null, num),
                        })
                    })
                    .collect();
                json!({
                    "geometry": im.geometry.name(), "method": im.method.name(), "views": im.kind.name(),
                    "view": im.view, "ssim": im.ssim.map_or(Value::Null, num),
                    "render": render_path(im.geometry, im.method, &im.view).to_string_lossy(),
                    "parts": parts,
                })
            })
            .collect();
        // Per (geometry, kind, method, part): the part's numbers averaged over the images.
        let mut by_part: std::collections::BTreeMap<(Geometry, ViewKind, Method, &str), Vec<&super::PartMetrics>> =
            Default::default();
        for im in &self.images {
            for p in &im.parts {
                by_part.entry((im.geometry, im.kind, im.method, p.part.as_str())).or_default().push(p);
            }
        }
        let part_rows: Vec<Value> = by_part
            .iter()
            .map(|((g, k, m, part), ps)| {
                let avg = |f: &dyn Fn(&super::PartMetrics) -> Option<f64>| {
                    let v: Vec<f64> = ps.iter().filter_map(|p| f(p)).collect();
                    num(if v.is_empty() { f64::NAN } else { v.iter().sum::<f64>() / v.len() as f64 })
                };
                json!({
                    "geometry": g.name(), "views": k.name(), "method": m.name(), "part": part,
                    "images": ps.len(), "pixels": ps.iter().map(|p| p.pixels).sum::<usize>(),
                    "rmse": avg(&|p| Some(p.rmse)), "mean_colour": avg(&|p| Some(p.mean_colour)),
                    "colour_w1": avg(&|p| Some(p.colour_w1)), "contrast_w1": avg(&|p| p.contrast_w1),
                })
            })
            .collect();
        let per_part = |values: &dyn Fn(usize) -> Value| -> Value {
            self.part_names
                .iter()
                .enumerate()
                .map(|(i, n)| (n.clone(), values(i)))
                .collect::<serde_json::Map<_, _>>()
                .into()
        };
        let o = &self.options;
        json!({
            "format": "photoscene-eval/1",
            "scene": self.scene.to_string_lossy(),
            "materials": self.fit.materials.to_string_lossy(),
            "lights": self.fit.lights.to_string_lossy(),
            "options": {
                "spp": o.spp, "seed": o.seed, "max_depth": o.max_depth,
                "methods": o.methods.iter().map(|m| m.name()).collect::<Vec<_>>(),
                "views": o.kinds.iter().map(|k| k.name()).collect::<Vec<_>>(),
                "geometries": o.geometries.iter().map(|g| g.name()).collect::<Vec<_>>(),
                "flat_iterations": o.flat_iterations, "flat_spp": o.flat_spp,
            },
            "definitions": {
                "values": "sRGB-encoded values in [0, 1]; renders encoded with the sRGB transfer and clamped",
                "parts": "per image, the pixels of each part in the truth label image; parts with >= 200 pixels; rows average over every (image, part) pair of the view kind",
                "rmse": "sqrt(mean over the part's pixels and channels of (render - truth)^2)",
                "mean_colour": "Euclidean norm of the difference of the part's mean RGB colours / sqrt(3)",
                "colour_w1": "1-Wasserstein distance of the part's value distributions, per channel, averaged over channels",
                "contrast_w1": "1-Wasserstein distance of the distributions of Rec. 709 luma gradient magnitudes sqrt(dx^2 + dy^2) (forward differences, pixels whose right and lower neighbours are in the part)",
                "ssim": "whole image, 11x11 Gaussian window sigma 1.5, K1 0.01, K2 0.03, valid positions, mean over channels; rows average over images",
                "relit": "each light's radiance is the method's times the truth's relit/original ratio per channel (oracle: the true relit radiances)",
                "pixel_median": "per part, per-channel median of the linear photo colours over its labelled pixels in the input views; roughness 0.7; flat normal",
                "flat_fitted": "constant albedo per part from the pixel median, multiplied by photo mean / render mean per channel (linear; pixels of the input views labelled as the part, showing the part in the coarse model's G-buffer, the render clipped at 1 as the photo is; the fit's lights and exposures) and clamped to [0, 1], flat_iterations times; roughness: the fitted material's mean over the part's input-view pixels where materials.json names the part, else 0.7",
                "oracle": "the true materials under the true lights",
                "unseen_floors": "per geometry and view kind whose images show a part no input view shows: the fitted row with every other part's term 0, over the pixel median's row; the fitted / pixel median ratio cannot go below it by fitting the photographed parts",
                "stated_log_ratio_sd": "lights.stated_log_ratio_sd[i][j]: the standard deviation of ln(L_i / L_j) (luminances) that the fit's last light solve stated (result.json), from the cluster-robust spread its misfit leaves; null where the photos do not determine it, absent for fits that do not record it",
                "exposure": "renders of an input view under the fit's lights (every method but the oracle) are multiplied by the fit's RGB exposure of that view (lights.input_exposure); novel and relit views at 1",
            },
            "lights": {
                "fitted": self.fitted_lights.iter().map(rgb).collect::<Vec<_>>(),
                "true": self.true_lights.iter().map(rgb).collect::<Vec<_>>(),
                "stated_log_ratio_sd": self.stated_light_spread,
                "input_exposure": self.input_exposure.iter().map(|(v, e)| (v.clone(), rgb(e))).collect::<serde_json::Map<_, _>>(),
            },
            "baselines": {
                "pixel_median_albedo": per_part(&|i| rgb(&self.pixel_median[i])),
                "flat_fitted_albedo": per_part(&|i| rgb(&self.flat_albedo[i])),
                "flat_fitted_roughness": per_part(&|i| json!(self.flat_roughness[i])),
                "flat_fit_round_changes": self
                    .flat_changes
                    .iter()
                    .map(|(c, part)| json!({"largest_albedo_change": num(*c), "part": part}))
                    .collect::<Vec<_>>(),
                "unseen_parts": self.unseen_parts,
            },
            "rows": self.rows.iter().map(row).collect::<Vec<_>>(),
            "unseen_floors": self.unseen_floors.iter().map(|f| json!({
                "geometry": f.geometry.name(), "views": f.kind.name(), "rmse": num(f.rmse),
                "mean_colour": num(f.mean_colour), "colour_w1": num(f.colour_w1), "contrast_w1": num(f.contrast_w1),
            })).collect::<Vec<_>>(),
            "ratios": ratios,
            "parts": part_rows,
            "images": images,
            "graph_choice": self.graph_choice.iter().map(|c| json!({
                "part": c.part, "true_kind": c.kind, "graph": c.graph, "category": c.category, "expected_family": c.matches,
            })).collect::<Vec<_>>(),
            "warnings": self.warnings,
            "timings_s": self.timings.iter().map(|(n, t)| json!({"stage": n, "seconds": t})).collect::<Vec<_>>(),
            "renders": self.renders,
            "wall_seconds": self.wall_seconds,
        })
    }
}

/// An evaluation replaces a previous evaluation and nothing else: `eval_dir` must not exist, or
/// be a folder holding an `eval.json`. Callers check it before the renders (an evaluation
/// takes minutes); [`write_outputs`] checks it again before replacing anything.
pub fn check_eval_dir(eval_dir: &Path) -> Result<(), EvalError> {
    if std::fs::symlink_metadata(eval_dir).is_ok() && !eval_dir.join("eval.json").is_file() {
        return Err(EvalError(format!(
            "{} exists and is not a previous evaluation (it has no eval.json); choose another folder",
            eval_dir.display()
        )));
    }
    Ok(())
}

/// Write `eval_dir/eval.json` and `eval_dir/renders/…` as a whole (a staged folder that then
/// replaces a previous evaluation in `eval_dir`; see [`check_eval_dir`]). With `json_copy`,
/// the JSON is also written there. On any error nothing is left behind.
pub fn write_outputs(eval: &Evaluation, eval_dir: &Path, json_copy: Option<&Path>) -> Result<(), EvalError> {
    check_eval_dir(eval_dir)?;
    let staged = StagedDir::new(eval_dir, Replace::Yes).map_err(|e| EvalError(e.to_string()))?;
    let text = serde_json::to_string_pretty(&eval.to_json()).expect("JSON values serialise") + "\n";
    let io = |p: &Path, e: std::io::Error| EvalError(format!("{}: {e}", p.display()));
    for im in &eval.images {
        let path = staged.path().join(render_path(im.geometry, im.method, &im.view));
        let dir = path.parent().expect("render paths have folders");
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
        backend::write_png(&path, im.width, im.height, &im.render)?;
    }
    // Inside the staged folder a plain write suffices: the folder appears whole or not at all.
    let json = staged.path().join("eval.json");
    std::fs::write(&json, &text).map_err(|e| io(&json, e))?;
    if let Some(path) = json_copy {
        backend::atomic_write(path, text.as_bytes())?;
    }
    staged.commit().map_err(|e| EvalError(e.to_string()))?;
    Ok(())
}
