//! Reading a `psc fit` output folder for display: `result.json` (required: it is what makes a
//! folder a fit output), then whatever else is there — `parts/<part>.json`, `materials.json`,
//! `lights.json`, `eval/eval.json`, and the scene folder `result.json` names (its photos and
//! label images). Optional pieces that are missing or unreadable become a note on the page, not
//! an error: a report of a partial folder is still worth having.

use std::path::{Path, PathBuf};

use psc_render::Scene;
use serde_json::Value;

use crate::ReportError;

/// The format `result.json` declares (any `photoscene-fit/…` version is accepted).
pub const FORMAT_PREFIX: &str = "photoscene-fit/";

/// Everything the page shows, read once.
pub struct FitFolder {
    /// Where the files are read from.
    pub dir: PathBuf,
    /// The path the page names the folder by (`dir` unless the report says otherwise).
    pub shown_as: PathBuf,
    pub result: Value,
    pub parts: Vec<Part>,
    /// `lights.json`, or why it is not available.
    pub lights: Result<Value, String>,
    /// `eval/eval.json`, or why it is not available.
    pub eval: Result<Value, String>,
    /// The scene with the photos, or why it is not available.
    pub scene: Result<Scene, String>,
    /// The scene folder that was looked for (for messages).
    pub scene_dir: Option<PathBuf>,
}

/// One part: its line in `result.json`, its own file and its entry in `materials.json`.
pub struct Part {
    pub name: String,
    /// The part's line in `result.json` (`name`, `status`, `graph`, `loss`, `view`).
    pub summary: Value,
    /// `parts/<part>.json`, or why it is not available.
    pub detail: Result<Value, String>,
    /// The part's entry in `materials.json`, or why it is not available.
    pub material: Result<Value, String>,
    /// `parts/<part>/`, where the baked maps are.
    pub maps_dir: PathBuf,
}

impl Part {
    /// The view the part was fitted in, if any.
    pub fn view(&self) -> Option<&str> {
        self.summary.get("view").and_then(Value::as_str)
    }

    pub fn graph(&self) -> Option<&str> {
        self.summary.get("graph").and_then(Value::as_str)
    }

    pub fn status(&self) -> &str {
        self.summary.get("status").and_then(Value::as_str).unwrap_or("unknown")
    }
}

/// The file-name stem `psc fit` uses for a part or view name (the rule of
/// `psc_fit::output::file_stem`: ASCII letters, digits, `-` and `_` kept, anything else `_`).
pub fn file_stem(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect()
}

/// The JSON file at `path`; else why not (the caller names the file).
fn read_json(path: &Path) -> Result<Value, String> {
    // The renderer's reader of JSON text: the size cap, and a byte-order mark (an editor's, on
    // a hand-edited file) skipped.
    let text = psc_render::json::read_text(path, "a JSON file").map_err(|e| e.to_string())?;
    serde_json::from_str(&text).map_err(|e| format!("not valid JSON: {e}"))
}

/// The file `relative` of the fit folder `dir`; else why not, for the page, naming it by its
/// path within the folder (which stays true wherever the folder is moved).
fn optional_json(dir: &Path, relative: &str) -> Result<Value, String> {
    let path = dir.join(relative);
    if !path.exists() {
        return Err(format!("{relative} does not exist"));
    }
    read_json(&path).map_err(|why| format!("{relative}: {why}"))
}

impl FitFolder {
    /// Reads the fit output in `dir`; `scene` overrides the scene folder `result.json` names.
    pub fn read(dir: &Path, scene: Option<&Path>) -> Result<FitFolder, ReportError> {
        let not_fit = |reason: String| ReportError::NotAFitOutput { dir: dir.to_path_buf(), reason };
        if !dir.is_dir() {
            return Err(not_fit("no such folder".into()));
        }
        let result_path = dir.join("result.json");
        if !result_path.is_file() {
            return Err(not_fit("it has no result.json".into()));
        }
        let result =
            read_json(&result_path).map_err(|message| ReportError::Input { path: result_path.clone(), message })?;
        match result.get("format").and_then(Value::as_str) {
            Some(f) if f.starts_with(FORMAT_PREFIX) => {}
            Some(f) => return Err(not_fit(format!("result.json has format '{f}', not {FORMAT_PREFIX}…"))),
            None => return Err(not_fit(format!("result.json has no \"format\" ({FORMAT_PREFIX}…)"))),
        }
        let Some(lines) = result.get("parts").and_then(Value::as_array) else {
            return Err(ReportError::Input {
                path: result_path,
                message: "\"parts\" must be an array of the fitted parts".into(),
            });
        };
        let materials = optional_json(dir, "materials.json");
        let mut parts = Vec::with_capacity(lines.len());
        for line in lines {
            let Some(name) = line.get("name").and_then(Value::as_str) else {
                return Err(ReportError::Input {
                    path: result_path.clone(),
                    message: format!("a part without a \"name\": {line}"),
                });
            };
            let stem = file_stem(name);
            let material = match &materials {
                Ok(m) => m
                    .get("parts")
                    .and_then(|p| p.get(name))
                    .cloned()
                    .ok_or_else(|| format!("materials.json has no entry for '{name}'")),
                Err(e) => Err(e.clone()),
            };
            parts.push(Part {
                name: name.to_string(),
                summary: line.clone(),
                detail: optional_json(dir, &format!("parts/{stem}.json")),
                material,
                maps_dir: dir.join("parts").join(stem),
            });
        }
        let scene_dir = match scene {
            Some(s) => Some(s.to_path_buf()),
            None => result.get("scene").and_then(Value::as_str).map(|s| resolve_scene(dir, s)),
        };
        let scene = match &scene_dir {
            None => Err("result.json names no scene".to_string()),
            Some(s) if !s.join("scene.json").is_file() => {
                Err(format!("the scene folder {} is not there (give the scene with --scene)", s.display()))
            }
            Some(s) => Scene::load(s).map_err(|e| e.to_string()),
        };
        Ok(FitFolder {
            dir: dir.to_path_buf(),
            shown_as: dir.to_path_buf(),
            lights: optional_json(dir, "lights.json"),
            eval: optional_json(dir, "eval/eval.json"),
            result,
            parts,
            scene,
            scene_dir,
        })
    }

    /// The path of the fit's re-render of view `name`, if there is one.
    /// The raster `psc fit` fitted and re-rendered view `name` at, when it was not the photo's
    /// own: (origin, factor, width, height) as `result.json`'s `views` records it.
    pub fn working_raster(&self, name: &str) -> Option<([usize; 2], usize, usize, usize)> {
        let view = self
            .result
            .get("views")?
            .as_array()?
            .iter()
            .find(|v| v.get("name").and_then(Value::as_str) == Some(name))?;
        let r = view.get("working_raster")?;
        let n = |v: &Value| v.as_u64().map(|x| x as usize);
        let origin = r.get("origin")?.as_array()?;
        let raster = (
            [n(origin.first()?)?, n(origin.get(1)?)?],
            n(r.get("factor")?)?,
            n(r.get("width")?)?,
            n(r.get("height")?)?,
        );
        (raster.1 > 1).then_some(raster)
    }

    pub fn render_of(&self, name: &str) -> Option<PathBuf> {
        let p = self.dir.join("renders").join(format!("{}.png", file_stem(name)));
        p.is_file().then_some(p)
    }
}

/// The scene folder `result.json` names: as written when it exists from here (absolute, or
/// relative to the working directory as `psc fit` was run from it), else relative to the
/// fit folder's parent (a fit output moved together with its scene).
fn resolve_scene(dir: &Path, named: &str) -> PathBuf {
    let p = PathBuf::from(named);
    if p.is_absolute() || p.join("scene.json").is_file() {
        return p;
    }
    let beside = dir.parent().unwrap_or(Path::new(".")).join(&p);
    if beside.join("scene.json").is_file() {
        beside
    } else {
        p
    }
}
