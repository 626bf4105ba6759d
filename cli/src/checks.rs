//! Checks of option values that clap's types cannot express, shared by the commands, each
//! giving a [`Usage`] error that names the option, what was expected and what was given.

use std::path::Path;

use psc_base::limits::{self, LimitError};
use psc_base::output::{OutputError, Replace};

use crate::{Error, Failure, Usage};

/// `path` is to be written as an image file with one of `extensions` (lower case, no dot), not
/// inside a file.
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
        Some(e) if extensions.contains(&e.as_str()) => in_a_folder(option, path),
        _ => Err(Usage(format!("{option}: expected a path ending in {wanted}, got {}", path.display()))),
    }
}

/// No file stands where `path` needs a folder (`--out notes.txt/out`); the write would refuse it
/// too, after the work.
fn in_a_folder(option: &str, path: &Path) -> Result<(), Usage> {
    psc_base::output::check_parents(path).map_err(|e| Usage(format!("{option}: {e}")))
}

/// `path` is to be written as a folder: it must not be an existing file, nor be inside one.
pub fn folder_path(option: &str, path: &Path) -> Result<(), Usage> {
    if path.exists() && !path.is_dir() {
        return Err(Usage(format!("{option}: {} is a file; expected a folder to write into", path.display())));
    }
    in_a_folder(option, path)
}

/// `path` is to be written as a new folder: not a file, not an existing folder unless it may
/// be replaced (`--force`), and never a folder that is or holds one of the command's `inputs`
/// (replacing it would delete them). Checked before any work; the staged write checks again.
pub fn new_folder(option: &str, path: &Path, replace: Replace, inputs: &[&Path]) -> Result<(), Error> {
    folder_path(option, path)?;
    keeps_inputs(option, path, inputs)?;
    if replace == Replace::No && path.exists() {
        return Err(Failure(OutputError::Exists(path.to_path_buf()).to_string()).into());
    }
    Ok(())
}

/// The output folder `out` must not be, or hold, any of `inputs` (compared after resolving
/// links and `..`; inputs or an output that do not exist cannot be deleted).
pub fn keeps_inputs(option: &str, out: &Path, inputs: &[&Path]) -> Result<(), Usage> {
    let Ok(out_real) = out.canonicalize() else { return Ok(()) };
    for input in inputs {
        let Ok(real) = input.canonicalize() else { continue };
        if real.starts_with(&out_real) {
            let relation = if real == out_real { "is" } else { "holds" };
            return Err(Usage(format!(
                "{option}: {} {relation} the input {}; writing the output there would delete it (choose another folder)",
                out.display(),
                input.display()
            )));
        }
    }
    Ok(())
}

/// An option whose value is over a documented limit (`psc_base::limits`): a usage error that
/// names the option and says the limit and the memory the request would need.
pub fn over_limit(option: &str, e: LimitError) -> Usage {
    Usage(format!("{option}: {e}"))
}

/// A bake (or contact-sheet sample) of `size`×`size` texels: the texel limit and memory (the
/// nine channel columns, the uv grid and the maps, about 100 bytes a texel).
pub fn bake_size(option: &str, size: usize) -> Result<(), Usage> {
    let size = size as u64;
    limits::check_elements(format!("bake of {size}x{size} texels"), &[size, size], limits::MAX_TEXELS, "texels", 100)
        .map(drop)
        .map_err(|e| over_limit(option, e))
}

/// A worker-thread count for clap: at least 1, at most `psc_base::limits::MAX_THREADS`.
pub fn parse_threads(s: &str) -> Result<usize, String> {
    let n: u64 = s.trim().parse().map_err(|_| format!("expected a number of threads, got '{s}'"))?;
    if n == 0 {
        return Err("expected at least 1 thread, got 0".into());
    }
    limits::check_threads(n).map_err(|e| e.to_string())?;
    Ok(n as usize)
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
    limits::check_image("image", w as u64, h as u64, 0).map_err(|e| e.to_string())?;
    Ok((w, h))
}

/// Samples per pixel for clap: at least 1, at most `psc_base::limits::MAX_SPP`.
pub fn parse_spp(s: &str) -> Result<u32, String> {
    let n: u64 = s.trim().parse().map_err(|_| format!("expected a number of samples, got '{s}'"))?;
    if n == 0 {
        return Err("expected at least 1 sample per pixel, got 0".into());
    }
    limits::check_count("samples per pixel", n, limits::MAX_SPP, "samples").map_err(|e| e.to_string())?;
    Ok(n as u32)
}

/// Light-grid paths per bin for clap: at least 1, at most `psc_base::limits::MAX_GRID_SAMPLES`.
pub fn parse_grid_samples(s: &str) -> Result<u32, String> {
    let n: u64 = s.trim().parse().map_err(|_| format!("expected a number of paths, got '{s}'"))?;
    if n == 0 {
        return Err("expected at least 1 path per bin, got 0".into());
    }
    limits::check_count("paths per bin", n, limits::MAX_GRID_SAMPLES, "paths").map_err(|e| e.to_string())?;
    Ok(n as u32)
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
        let e = parse_size("100000x100000").unwrap_err();
        assert!(e.contains("the limit is 67,108,864 pixels"), "{e}");
        assert!(parse_size("4294967295x4294967295").unwrap_err().contains("the limit is"));
        assert_eq!(parse_spp("64"), Ok(64));
        assert!(parse_spp("100000000").unwrap_err().contains("the limit is 65,536 samples"));
    }

    #[test]
    fn thread_counts_are_bounded_by_the_documented_limit() {
        assert_eq!(parse_threads("2"), Ok(2));
        let e = parse_threads("100000").unwrap_err();
        assert!(e.contains("100,000 threads requested") && e.contains("the limit is 256"), "{e}");
        assert!(parse_threads("0").is_err() && parse_threads("many").is_err());
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
