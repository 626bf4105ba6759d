//! Reading the runtime's JSON input files (parameter files, assignment files) strictly: a size
//! limit checked before reading, a clear message for a directory given as a file, syntax errors
//! with line and column, and duplicate object keys refused (serde_json keeps the last one
//! silently, so `{"rows": 4, "rows": 9}` would mean 9 without a word).
//!
//! The typed readers above this (`params`, `assign`) take the [`Value`] and check each field
//! themselves, so their messages can name the field and say what was expected.

use std::fmt;
use std::path::{Path, PathBuf};

use serde::de::{DeserializeSeed, Error as _, MapAccess, SeqAccess, Visitor};
use serde_json::{Map, Number, Value};

/// Largest JSON input file read (parameter and assignment files are a few kilobytes).
pub use psc_base::limits::MAX_JSON_BYTES;

/// Why a JSON file could not be read.
#[derive(Debug)]
pub enum JsonErrorKind {
    /// The path names a directory (or something else that is not a regular file).
    NotAFile,
    Io(std::io::Error),
    TooLarge {
        bytes: u64,
    },
    /// Not UTF-8 or not JSON, or a duplicate key: `line` and `column` are 1-based.
    Syntax {
        line: usize,
        column: usize,
        message: String,
    },
}

/// A JSON file that could not be read, with its path.
#[derive(Debug)]
pub struct JsonError {
    pub path: PathBuf,
    pub kind: JsonErrorKind,
}

impl fmt::Display for JsonError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self.path.display();
        match &self.kind {
            JsonErrorKind::NotAFile => write!(f, "{p}: expected a JSON file, found a directory or special file"),
            JsonErrorKind::Io(e) => write!(f, "cannot read {p}: {e}"),
            JsonErrorKind::TooLarge { bytes } => write!(
                f,
                "{p}: {bytes} bytes is larger than the {} MiB limit for JSON input files",
                MAX_JSON_BYTES >> 20
            ),
            JsonErrorKind::Syntax { line, column, message } => write!(f, "{p}:{line}:{column}: {message}"),
        }
    }
}

impl std::error::Error for JsonError {}

/// Reads and parses `path` (see the module docs for what is refused).
pub fn read_file(path: &Path) -> Result<Value, JsonError> {
    let err = |kind| JsonError { path: path.to_path_buf(), kind };
    let meta = std::fs::metadata(path).map_err(|e| err(JsonErrorKind::Io(e)))?;
    if !meta.is_file() {
        return Err(err(JsonErrorKind::NotAFile));
    }
    if meta.len() > MAX_JSON_BYTES {
        return Err(err(JsonErrorKind::TooLarge { bytes: meta.len() }));
    }
    let bytes = std::fs::read(path).map_err(|e| err(JsonErrorKind::Io(e)))?;
    parse(&bytes).map_err(err)
}

/// Parses JSON text, refusing duplicate keys (with the position of the second one). A UTF-8
/// byte-order mark at the start (some Windows editors write one) is not part of the JSON and is
/// skipped, as `psc_render`'s reader of scene files skips it.
pub fn parse(bytes: &[u8]) -> Result<Value, JsonErrorKind> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let syntax = |e: serde_json::Error| JsonErrorKind::Syntax {
        line: e.line(),
        column: e.column(),
        message: strip_position(&e.to_string()),
    };
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let value = Strict.deserialize(&mut de).map_err(syntax)?;
    de.end().map_err(syntax)?;
    Ok(value)
}

/// serde_json appends " at line L column C", which the caller prints in front instead.
fn strip_position(message: &str) -> String {
    match message.rfind(" at line ") {
        Some(i) => message[..i].to_string(),
        None => message.to_string(),
    }
}

/// Builds a [`Value`] like serde_json does, but refuses duplicate object keys.
struct Strict;

impl<'de> DeserializeSeed<'de> for Strict {
    type Value = Value;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<Value, D::Error> {
        d.deserialize_any(Strict)
    }
}

impl<'de> Visitor<'de> for Strict {
    type Value = Value;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("any JSON value")
    }
    fn visit_bool<E>(self, b: bool) -> Result<Value, E> {
        Ok(Value::Bool(b))
    }
    fn visit_i64<E>(self, x: i64) -> Result<Value, E> {
        Ok(Value::Number(x.into()))
    }
    fn visit_u64<E>(self, x: u64) -> Result<Value, E> {
        Ok(Value::Number(x.into()))
    }
    fn visit_f64<E: serde::de::Error>(self, x: f64) -> Result<Value, E> {
        Number::from_f64(x).map(Value::Number).ok_or_else(|| E::custom("a number that is not finite"))
    }
    fn visit_str<E>(self, s: &str) -> Result<Value, E> {
        Ok(Value::String(s.to_string()))
    }
    fn visit_string<E>(self, s: String) -> Result<Value, E> {
        Ok(Value::String(s))
    }
    fn visit_unit<E>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }
    fn visit_none<E>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut out = Vec::new();
        while let Some(v) = seq.next_element_seed(Strict)? {
            out.push(v);
        }
        Ok(Value::Array(out))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Value, A::Error> {
        let mut out = Map::new();
        while let Some(key) = map.next_key::<String>()? {
            if out.contains_key(&key) {
                return Err(A::Error::custom(format!("the key \"{key}\" appears twice in one object")));
            }
            let value = map.next_value_seed(Strict)?;
            out.insert(key, value);
        }
        Ok(Value::Object(out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn syntax(text: &str) -> (usize, usize, String) {
        match parse(text.as_bytes()) {
            Err(JsonErrorKind::Syntax { line, column, message }) => (line, column, message),
            other => panic!("{text:?}: expected a syntax error, got {other:?}"),
        }
    }

    #[test]
    fn parses_what_serde_json_parses() {
        let text = r#"{"a": [1, -2, 3.5, 1e-3], "b": {"c": null, "d": true}, "e": "x\u00e9"}"#;
        assert_eq!(parse(text.as_bytes()).unwrap(), serde_json::from_str::<Value>(text).unwrap());
    }

    #[test]
    fn duplicate_keys_are_refused_where_they_occur() {
        let (line, _, message) = syntax("{\n  \"rows\": 4,\n  \"rows\": 9\n}");
        assert_eq!(line, 3);
        assert!(message.contains("\"rows\" appears twice"), "{message}");
        let (_, _, message) = syntax(r#"{"parts": {"floor": {"graph": "a", "graph": "b"}}}"#);
        assert!(message.contains("\"graph\" appears twice"), "{message}");
    }

    #[test]
    fn bad_text_is_located() {
        let (line, column, message) = syntax("{\n \"a\": [1, 2,]\n}");
        assert_eq!((line, column), (2, 13), "{message}");
        assert!(!message.contains(" at line "), "{message}");
        syntax("{} trailing");
        syntax("");
        syntax("1e400");
        syntax(&"[".repeat(100_000));
        assert!(matches!(parse(b"\xff\xfe"), Err(JsonErrorKind::Syntax { .. })));
    }

    #[test]
    fn a_leading_byte_order_mark_is_skipped() {
        let text = "\u{feff}{\"a\": 1}";
        assert_eq!(parse(text.as_bytes()).unwrap(), serde_json::json!({"a": 1}));
        // Columns on line 1 are counted from after it, as editors show them.
        let (line, column, message) = syntax("\u{feff}{\"a\": }");
        assert_eq!((line, column), (1, 7), "{message}");
        // Only at the start: anywhere else it is text that is not JSON.
        syntax("{\"a\": 1}\u{feff}");
        syntax("\u{feff}\u{feff}{}");
    }

    #[test]
    fn a_directory_is_not_a_file() {
        let dir = std::env::temp_dir();
        let e = read_file(&dir).unwrap_err();
        assert!(matches!(e.kind, JsonErrorKind::NotAFile), "{e}");
        assert!(e.to_string().contains("found a directory"), "{e}");
        let e = read_file(Path::new("/no/such/file.json")).unwrap_err();
        assert!(e.to_string().starts_with("cannot read /no/such/file.json"), "{e}");
    }
}
