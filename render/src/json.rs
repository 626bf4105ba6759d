//! Reading the crate's JSON files (scene.json, camera, lights, truth) with errors that name the
//! file, the line and column, and the field (`views[0].camera.fov_y_deg`), and say what was
//! expected and what was found.

use std::path::Path;

use psc_base::limits::MAX_JSON_BYTES;
use serde::de::DeserializeOwned;

use crate::RenderError;

/// Read a file that must exist and be a regular file (a directory or a missing path gets its
/// own message, naming `what` the file is for). A UTF-8 byte-order mark at the start (some
/// Windows editors write one) is dropped: it is not part of the JSON (or OBJ, MTL) text, and
/// line 1's columns are then those an editor shows.
pub fn read_text(path: &Path, what: &str) -> Result<String, RenderError> {
    check_file(path, what)?;
    let bytes = std::fs::metadata(path).map_err(|e| RenderError::io(path, e))?.len();
    if bytes > MAX_JSON_BYTES {
        return Err(RenderError::io(
            path,
            format!("{bytes} bytes is larger than the {} MiB limit for JSON input files", MAX_JSON_BYTES >> 20),
        ));
    }
    let text = std::fs::read_to_string(path).map_err(|e| RenderError::io(path, e))?;
    Ok(match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    })
}

/// `Ok` when `path` is a regular file; otherwise an error saying whether it is missing or a
/// directory (or something else), and what was expected.
pub fn check_file(path: &Path, what: &str) -> Result<(), RenderError> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => Ok(()),
        Ok(m) if m.is_dir() => Err(RenderError::io(path, format!("is a directory; expected {what} (a file)"))),
        Ok(_) => Err(RenderError::io(path, format!("is not a regular file; expected {what}"))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(RenderError::io(path, format!("{what} not found"))),
        Err(e) => Err(RenderError::io(path, format!("cannot read {what}: {e}"))),
    }
}

/// Parse `text` (the contents of `path`) as a `T`. Every JSON file this crate reads holds an
/// object, so any other value at the top level is refused as such (serde reads an array as a
/// struct's fields in order, which said `field [0]: invalid type` for a scene.json holding
/// `[{...}]`, and names Rust types for a number).
pub fn parse<T: DeserializeOwned>(path: &Path, text: &str) -> Result<T, RenderError> {
    top_level_object(path, text)?;
    let de = &mut serde_json::Deserializer::from_str(text);
    let value: T = serde_path_to_error::deserialize(&mut *de).map_err(|e| {
        let field = e.path().to_string();
        let mut err = RenderError::json(path, e.inner());
        if let RenderError::Json { message, .. } = &mut err {
            if field != "." {
                *message = format!("field `{field}`: {message}");
            }
        }
        err
    })?;
    de.end().map_err(|e| RenderError::json(path, &e))?;
    Ok(value)
}

/// `Ok` unless `text` is valid JSON whose top-level value is not an object, or starts an array;
/// then an error at that value saying what it is. (Other text that is not JSON is left to the
/// typed parse, which locates the syntax error.)
fn top_level_object(path: &Path, text: &str) -> Result<(), RenderError> {
    let start = text.trim_start_matches([' ', '\t', '\n', '\r']);
    if start.is_empty() || start.starts_with('{') {
        return Ok(());
    }
    let found = match serde_json::from_str::<serde_json::Value>(text) {
        Ok(serde_json::Value::Array(a)) => format!("an array of {} elements", a.len()),
        Ok(serde_json::Value::String(_)) => "a string".into(),
        Ok(serde_json::Value::Number(n)) => format!("the number {n}"),
        Ok(serde_json::Value::Bool(b)) => format!("`{b}`"),
        Ok(serde_json::Value::Null) => "`null`".into(),
        // Not JSON either: an array still says why (serde would report its first element).
        Err(_) if start.starts_with('[') => "an array".into(),
        Ok(serde_json::Value::Object(_)) | Err(_) => return Ok(()),
    };
    let before = &text[..text.len() - start.len()];
    let line = before.matches('\n').count() + 1;
    let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    Err(RenderError::Json {
        path: path.to_path_buf(),
        line,
        column,
        message: format!("the file must hold a JSON object ({{ ... }}), found {found}"),
    })
}

/// Read and parse a JSON file (`what` names it in errors: "scene manifest", "lights file").
pub fn read<T: DeserializeOwned>(path: &Path, what: &str) -> Result<T, RenderError> {
    let text = read_text(path, what)?;
    parse(path, &text)
}
