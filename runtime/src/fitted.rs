//! A `psc fit` output folder opened for rendering: the scene `result.json` names, the fitted
//! materials (`materials.json`, an assignment file) and light radiances (`lights.json`), so
//! that `psc render <fit-output>` renders the fitted room from any camera, relit (`--lights`)
//! or edited (`--set`, [`crate::edit`]).

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
        })
    }

    /// The fitted assignment.
    pub fn assignment(&self) -> Result<Assignment, AssignError> {
        Assignment::read(&self.materials)
    }
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
