//! The report's lights section: the radiances, the global solves, how far the photos determine
//! the ratio between two lights, and the per-view exposures.

use std::fmt::Write;

use serde_json::Value;

use crate::fit_folder::FitFolder;
use crate::html::{esc, hex_of_linear, missing, swatch, table, value};
use crate::page::as_rgb;

pub(crate) fn lights(fit: &FitFolder) -> String {
    let mut s = String::from("<h2 id=\"lights\">Lights</h2>");
    if let Some(source) = fit.result.pointer("/lights/source").and_then(Value::as_str) {
        let _ = write!(s, "<p>Radiances: {}.</p>", esc(source));
    }
    let lights = match &fit.lights {
        Ok(l) => l,
        Err(e) => return s + &missing("lights.json", e),
    };
    let list = lights.get("lights").and_then(Value::as_array).cloned().unwrap_or_default();
    // Shares of the light reaching the solved pixels: given directly, or the last global solve's.
    let rounds = fit.result.pointer("/lights/solve_rounds").and_then(Value::as_array);
    let shares = fit
        .result
        .pointer("/lights/shares")
        .and_then(Value::as_array)
        .or_else(|| rounds?.last()?.pointer("/solve/share")?.as_array());
    let truth = fit.eval.as_ref().ok().and_then(|e| e.pointer("/lights/true")).and_then(Value::as_array);
    let mut header = vec!["light", "radiance (linear RGB)"];
    if shares.is_some() {
        header.push("share");
    }
    if truth.is_some() {
        header.push("true radiance (from eval.json)");
    }
    let rows: Vec<Vec<String>> = list
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let radiance = l.get("radiance_rgb").cloned().unwrap_or(Value::Null);
            let mut row = vec![
                esc(l.get("name").and_then(Value::as_str).unwrap_or("?")),
                match as_rgb(&radiance) {
                    Some(rgb) => {
                        let m = rgb.iter().cloned().fold(0.0, f64::max).max(1e-12);
                        format!("{}{}", swatch(&hex_of_linear(rgb.map(|c| c / m))), value(&radiance))
                    }
                    None => value(&radiance),
                },
            ];
            if let Some(sh) = shares {
                row.push(sh.get(i).map(value).unwrap_or_default());
            }
            if let Some(t) = truth {
                row.push(t.get(i).map(value).unwrap_or_default());
            }
            row
        })
        .collect();
    if rows.is_empty() {
        s.push_str("<p>The scene has no light meshes.</p>");
    } else {
        s.push_str(&table(&header, &rows));
    }
    if let Some(env) = lights.get("environment_scale") {
        let _ = write!(s, "<p>Environment scale: {}.</p>", value(env));
    }
    if let Some(rounds) = rounds.filter(|r| !r.is_empty()) {
        let rows: Vec<Vec<String>> = rounds
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let at = |p: &str| r.pointer(p).map(value).unwrap_or_default();
                vec![
                    format!("{}", i + 1),
                    at("/change"),
                    at("/solve/pixels"),
                    at("/solve/relative_rms"),
                    at("/solve/outliers"),
                ]
            })
            .collect();
        s.push_str("<p>Global light solves of the re-fit rounds (largest relative change of a light against the round before; the fit's residual).</p>");
        s.push_str(&table(&["round", "change", "pixels", "relative RMS (r, g, b)", "outlier fraction"], &rows));
    }
    s + &ratio_spread(rounds.map(Vec::as_slice), &list) + &exposures(fit)
}

/// How far the photos determine the ratio between every two lights: the spread the last light
/// solve states for its log ratio (`log_ratio_sd`), as a percentage either way at 1 sd.
fn ratio_spread(rounds: Option<&[Value]>, lights: &[Value]) -> String {
    let Some(table_of) = rounds.and_then(|r| r.last()).and_then(|r| r.pointer("/solve/log_ratio_sd")) else {
        return String::new();
    };
    let name = |i: usize| esc(lights.get(i).and_then(|l| l.get("name")).and_then(Value::as_str).unwrap_or("?"));
    let mut rows = Vec::new();
    for i in 0..lights.len() {
        for j in i + 1..lights.len() {
            let spread = match table_of.pointer(&format!("/{i}/{j}")) {
                Some(Value::Null) => "not determined by the photos".to_string(),
                Some(v) => match v.as_f64() {
                    Some(sd) => format!("±{:.0}%", sd.exp_m1() * 100.0),
                    None => continue,
                },
                None => continue,
            };
            rows.push(vec![format!("{} / {}", name(i), name(j)), spread]);
        }
    }
    if rows.is_empty() {
        return String::new();
    }
    "<p>How far the photos determine the ratio between two lights: the spread (1 sd) the last solve's misfit leaves it, clustered by part and view. Where the spread is comparable to the ratio itself, the photos hardly determine it and the solve's damping sets it.</p>".to_string()
        + &table(&["lights", "ratio spread"], &rows)
}

/// The per-view RGB exposures the light solve found (`lights.exposure_rgb`), when the fit has
/// several views (a single view's is 1 by definition).
fn exposures(fit: &FitFolder) -> String {
    let Some(map) = fit.result.pointer("/lights/exposure_rgb").and_then(Value::as_object) else {
        return String::new();
    };
    if map.len() < 2 {
        return String::new();
    }
    let rows: Vec<Vec<String>> = map.iter().map(|(view, e)| vec![esc(view), value(e)]).collect();
    "<p>Per-view exposure: the factor per channel between a render of the fitted scene and the view's photo (solved with the lights; their geometric mean over the views, weighted by pixels, is 1).</p>".to_string()
        + &table(&["view", "exposure (r, g, b)"], &rows)
}
