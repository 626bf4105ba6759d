//! A `psc fit` output folder opened for rendering: the scene `result.json` names, the fitted
//! materials (`materials.json`, an assignment file) and light radiances (`lights.json`), so
//! that `psc render <fit-output>` renders the fitted room from any camera, relit (`--lights`)
//! or edited (`--set`, [`crate::edit`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::assign::{AssignError, Assignment};

/// The files of a fit output that rendering needs.
#[derive(Clone, Debug, PartialEq)]
pub struct FitOutput {
    pub dir: PathBuf,
    /// The scene folder the fit was made from.
    pub scene: PathBuf,
    /// `materials.json`: the fitted assignment.
    pub materials: PathBuf,
    /// `lights.json`: the fitted radiances.
    pub lights: PathBuf,
    /// Per input view name, the RGB exposure the fit solved for it (`result.json`'s
    /// `lights.exposure_rgb`): the factor between a render of the fitted room from that view
    /// and its photo. Empty for fits made before exposures (every view at 1).
    pub exposures: BTreeMap<String, [f32; 3]>,
}

impl FitOutput {
    /// Whether `dir` looks like a fit output (it has `result.json` and is not a scene folder).
    pub fn is_fit_output(dir: &Path) -> bool {
        dir.join("result.json").is_file() && !dir.join("scene.json").is_file()
    }

    /// Opens the fit output in `dir`: its `result.json` must name a scene folder that exists
    /// (as written, or relative to the fit folder's parent), and `materials.json` and
    /// `lights.json` must be there. Errors name the file and what is missing.
    pub fn open(dir: &Path) -> Result<FitOutput, String> {
        let result_path = dir.join("result.json");
        let result = crate::json::read_file(&result_path).map_err(|e| e.to_string())?;
        if !result.get("format").and_then(Value::as_str).is_some_and(|f| f.starts_with("photoscene-fit/")) {
            return Err(format!(
                "{}: not a `psc fit` result (no \"format\": \"photoscene-fit/1\")",
                result_path.display()
            ));
        }
        let named = result
            .get("scene")
            .and_then(Value::as_str)
            .ok_or_else(|| format!("{}: \"scene\" (the scene folder) is missing", result_path.display()))?;
        let scene = resolve_scene(dir, named).ok_or_else(|| {
            format!(
                "{}: the scene folder '{named}' it names is not there (neither as written nor beside {})",
                result_path.display(),
                dir.display()
            )
        })?;
        let file = |name: &str| {
            let p = dir.join(name);
            if p.is_file() {
                Ok(p)
            } else {
                Err(format!("{}: missing from the fit output", p.display()))
            }
        };
        Ok(FitOutput {
            dir: dir.to_path_buf(),
            scene,
            materials: file("materials.json")?,
            lights: file("lights.json")?,
            exposures: exposures_of(&result).map_err(|e| format!("{}: {e}", result_path.display()))?,
        })
    }

    /// The fit's exposure of the scene view `view` (1 for a view it has none for).
    pub fn exposure(&self, view: &str) -> [f32; 3] {
        self.exposures.get(view).copied().unwrap_or([1.0; 3])
    }

    /// The fitted assignment.
    pub fn assignment(&self) -> Result<Assignment, AssignError> {
        Assignment::read(&self.materials)
    }
}

/// What a fit's `result.json` records of its lights beyond `lights.json`, read from one pass
/// over the file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ResultLights {
    /// Per view, its RGB exposure (`lights.exposure_rgb`); empty when absent.
    pub exposures: BTreeMap<String, [f32; 3]>,
    /// The spread the last light solve stated for the log ratio of every pair of lights
    /// (`lights.solve_rounds[-1].solve.log_ratio_sd`: `[i][j]`, a standard deviation or `null`
    /// where the photos do not determine it); `None` when absent (fits under known lights, fits
    /// from before it was recorded).
    pub ratio_spread: Option<Vec<Vec<Option<f32>>>>,
}

/// [`ResultLights`] of a fit's `result.json`; empty when the file is absent. A present but
/// unreadable file, an exposure that is not three finite positive numbers or a spread that is
/// not a square table of non-negative numbers and nulls is an error.
pub fn read_result_lights(result_path: &Path) -> Result<ResultLights, String> {
    if !result_path.is_file() {
        return Ok(ResultLights::default());
    }
    let result = crate::json::read_file(result_path).map_err(|e| e.to_string())?;
    let located = |e: String| format!("{}: {e}", result_path.display());
    Ok(ResultLights {
        exposures: exposures_of(&result).map_err(located)?,
        ratio_spread: ratio_spread_of(&result).map_err(located)?,
    })
}

fn exposures_of(result: &Value) -> Result<BTreeMap<String, [f32; 3]>, String> {
    let Some(entry) = result.pointer("/lights/exposure_rgb") else { return Ok(BTreeMap::new()) };
    let map = entry.as_object().ok_or("lights.exposure_rgb: expected {\"view\": [r, g, b], …}")?;
    map.iter()
        .map(|(view, value)| {
            let rgb: Option<Vec<f32>> =
                value.as_array().map(|a| a.iter().filter_map(Value::as_f64).map(|x| x as f32).collect());
            match rgb.as_deref() {
                Some(&[r, g, b]) if [r, g, b].iter().all(|x| x.is_finite() && *x > 0.0) => {
                    Ok((view.clone(), [r, g, b]))
                }
                _ => Err(format!("lights.exposure_rgb: view '{view}': {value} is not three finite positive numbers")),
            }
        })
        .collect()
}

fn ratio_spread_of(result: &Value) -> Result<Option<Vec<Vec<Option<f32>>>>, String> {
    let rounds = result.pointer("/lights/solve_rounds").and_then(Value::as_array);
    let Some(entry) = rounds.and_then(|r| r.last()).and_then(|r| r.pointer("/solve/log_ratio_sd")) else {
        return Ok(None);
    };
    let bad = || "lights.solve_rounds: log_ratio_sd is not a square table of numbers or nulls".to_string();
    let rows = entry.as_array().ok_or_else(bad)?;
    let table: Vec<Vec<Option<f32>>> = rows
        .iter()
        .map(|row| {
            let row = row.as_array().ok_or_else(bad)?;
            row.iter()
                .map(|v| match v {
                    Value::Null => Ok(None),
                    v => v.as_f64().filter(|x| x.is_finite() && *x >= 0.0).map(|x| Some(x as f32)).ok_or_else(bad),
                })
                .collect()
        })
        .collect::<Result<_, String>>()?;
    if table.iter().any(|row| row.len() != table.len()) {
        return Err(bad());
    }
    Ok(Some(table))
}

/// The scene folder a fit's `result.json` names: as written (absolute, or relative to the
/// working directory `psc fit` ran in) when it holds a `scene.json`, else relative to the fit
/// folder's parent (a fit output moved together with its scene).
pub fn resolve_scene(fit_dir: &Path, named: &str) -> Option<PathBuf> {
    let p = PathBuf::from(named);
    if p.join("scene.json").is_file() {
        return Some(p);
    }
    if p.is_absolute() {
        return None;
    }
    let beside = fit_dir.parent().unwrap_or(Path::new(".")).join(&p);
    beside.join("scene.json").is_file().then_some(beside)
}

#[cfg(test)]
mod tests {
    use super::{read_result_lights, ResultLights};

    fn spread_of(result: &str) -> Result<Option<Vec<Vec<Option<f32>>>>, String> {
        let dir = tempfile::Builder::new().prefix("psc-fitted-").tempdir().unwrap();
        let path = dir.path().join("result.json");
        std::fs::write(&path, result).unwrap();
        read_result_lights(&path).map(|lights| lights.ratio_spread)
    }

    #[test]
    fn the_last_solve_rounds_spread_is_read_and_a_malformed_one_refused() {
        let rounds = r#"{"lights": {"solve_rounds": [
            {"solve": {"log_ratio_sd": [[0, 9], [9, 0]]}},
            {"solve": {"log_ratio_sd": [[0, 0.5], [null, 0]]}}]}}"#;
        assert_eq!(spread_of(rounds).unwrap(), Some(vec![vec![Some(0.0), Some(0.5)], vec![None, Some(0.0)]]));
        assert_eq!(spread_of(r#"{"lights": {"solve_rounds": []}}"#).unwrap(), None);
        assert_eq!(spread_of(r#"{"lights": {}}"#).unwrap(), None);
        for bad in [r#"[[0, "x"], [1, 0]]"#, r#"[[0, 1]]"#, r#"[[0, -1], [1, 0]]"#, r#"{"a": 1}"#] {
            let result = format!(r#"{{"lights": {{"solve_rounds": [{{"solve": {{"log_ratio_sd": {bad}}}}}]}}}}"#);
            let error = spread_of(&result).unwrap_err();
            assert!(error.contains("log_ratio_sd"), "{bad}: {error}");
        }
        let missing = std::path::Path::new("/nonexistent/result.json");
        assert_eq!(read_result_lights(missing).unwrap(), ResultLights::default());
    }
}
