//! Checks of option values that clap's types cannot express, shared by the commands, each
//! giving a [`Usage`] error that names the option, what was expected and what was given.

use std::path::Path;

use psc_base::output::{OutputError, Replace};

use crate::{Error, Failure, Usage};

/// `path` is to be written as an image file with one of `extensions` (lower case, no dot).
pub fn image_path(option: &str, path: &Path, extensions: &[&str]) -> Result<(), Usage> {
    let wanted = extensions.iter().map(|e| format!(".{e}")).collect::<Vec<_>>().join(" or ");
    if path.is_dir() {
        return Err(Usage(format!(
            "{option}: {} is a directory; expected an image file path ending in {wanted}",
            path.display()
        )));
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext {
        Some(e) if extensions.contains(&e.as_str()) => Ok(()),
        _ => Err(Usage(format!("{option}: expected a path ending in {wanted}, got {}", path.display()))),
    }
}

/// `path` is to be written as a folder: it must not be an existing file.
pub fn folder_path(option: &str, path: &Path) -> Result<(), Usage> {
    if path.exists() && !path.is_dir() {
        return Err(Usage(format!("{option}: {} is a file; expected a folder to write into", path.display())));
    }
    Ok(())
}

/// `path` is to be written as a new folder: not a file, and not an existing folder unless it
/// may be replaced (`--force`). Checked before any work; the staged write checks again.
pub fn new_folder(option: &str, path: &Path, replace: Replace) -> Result<(), Error> {
    folder_path(option, path)?;
    if replace == Replace::No && path.exists() {
        return Err(Failure(OutputError::Exists(path.to_path_buf()).to_string()).into());
    }
    Ok(())
}

/// `WxH` with positive integers, for clap's `value_parser`.
pub fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("expected WIDTHxHEIGHT with positive integers, e.g. 320x240; got '{s}'");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: usize = w.trim().parse().map_err(|_| bad())?;
    let h: usize = h.trim().parse().map_err(|_| bad())?;
    if w == 0 || h == 0 {
        return Err(bad());
    }
    Ok((w, h))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_or_say_what_was_expected() {
        assert_eq!(parse_size("320x240"), Ok((320, 240)));
        assert_eq!(parse_size("8X6"), Ok((8, 6)));
        for bad in ["320", "0x5", "ax5", "5x", "-1x4", "99999999999999999999x2"] {
            let e = parse_size(bad).unwrap_err();
            assert!(e.contains("expected WIDTHxHEIGHT") && e.contains(bad), "{bad}: {e}");
        }
    }

    #[test]
    fn image_paths_need_the_right_extension_and_no_directory() {
        assert!(image_path("--out", Path::new("a/b.PNG"), &["png", "exr"]).is_ok());
        let Usage(m) = image_path("--sheet", Path::new("s.jpg"), &["png"]).unwrap_err();
        assert_eq!(m, "--sheet: expected a path ending in .png, got s.jpg");
        let Usage(m) = image_path("--out", &std::env::temp_dir(), &["png", "exr"]).unwrap_err();
        assert!(m.contains("is a directory") && m.contains(".png or .exr"), "{m}");
    }
}
