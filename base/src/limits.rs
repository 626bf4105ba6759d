//! Resource limits: how much one request may ask for, checked before anything is allocated, with
//! an error that says the limit and how much memory the request would need.
//!
//! The numbers come from the machine photoscene targets (24 GiB, 2 cores; the same for
//! developers and CI): no single request may plan to use more than [`MEMORY_BUDGET`] (16 GiB,
//! leaving room for the rest of the process and the system), and each count has a cap far above
//! any real use and far below what overflows or exhausts memory:
//!
//! | limit | value | why |
//! | --- | --- | --- |
//! | [`MAX_PIXELS`] | 2²⁶ (8192 × 8192) | a render holds ~100–300 bytes a pixel (slot images, per-light copies, EXR encoding) |
//! | [`MAX_TEXELS`] | 2²⁶ (8192²) | a bake holds ~100 bytes a texel (nine channels, uv, maps, encoders) |
//! | [`MAX_SPP`] | 2¹⁶ | 65 536 samples a pixel is hours even for a small image |
//! | [`MAX_GRID_SAMPLES`] | 2¹² | paths per hemisphere bin of a light grid (×128 bins a cell) |
//! | [`MAX_THREADS`] | 256 | each thread has a stack; two cores gain nothing past a few |
//! | [`MAX_VARIANTS`] | 10 000 | random variants of one bake (each writes five files) |
//! | [`MAX_JSON_BYTES`] | 64 MiB | a JSON input file (scene, camera, lights, assignment, parameters: kilobytes in use) |
//!
//! Memory estimates are the caller's (it knows its bytes per element); [`check_elements`] does
//! the overflow-safe arithmetic and the comparison with the budget.

use std::fmt;

/// Most memory one request may plan to use.
pub const MEMORY_BUDGET: u64 = 16 << 30;
/// Most pixels in one image (render, G-buffer, light-grid source image, photo, label image).
pub const MAX_PIXELS: u64 = 1 << 26;
/// Most texels in one bake or sheet sample.
pub const MAX_TEXELS: u64 = 1 << 26;
/// Most samples per pixel of a render.
pub const MAX_SPP: u64 = 1 << 16;
/// Most paths per hemisphere bin of a light grid.
pub const MAX_GRID_SAMPLES: u64 = 1 << 12;
/// Most worker threads.
pub const MAX_THREADS: u64 = 256;
/// Most random variants of one bake.
pub const MAX_VARIANTS: u64 = 10_000;
/// Largest JSON input file read.
pub const MAX_JSON_BYTES: u64 = 64 << 20;

/// A request over a limit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LimitError {
    /// What was requested, e.g. "image of 100000x100000 pixels".
    pub what: String,
    /// The requested count (saturated at u64::MAX when the product overflows).
    pub requested: u64,
    /// The limit it exceeds (a count, or bytes for the memory budget).
    pub limit: u64,
    /// Unit of `requested` and `limit` ("pixels", "bytes", ...).
    pub unit: &'static str,
    /// Memory the request would need, when known.
    pub bytes: Option<u64>,
}

impl fmt::Display for LimitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.unit == "bytes" {
            write!(
                f,
                "{} would need about {} of memory; the limit is {} (photoscene plans for a 24 GiB machine)",
                self.what,
                format_bytes(self.requested),
                format_bytes(self.limit)
            )
        } else {
            let requested =
                if self.requested == u64::MAX { "more than 2^64".to_string() } else { group(self.requested) };
            write!(
                f,
                "{}: {requested} {} requested; the limit is {} {}",
                self.what,
                self.unit,
                group(self.limit),
                self.unit
            )?;
            if let Some(b) = self.bytes {
                write!(f, " (it would need about {} of memory)", format_bytes(b))?;
            }
            Ok(())
        }
    }
}

impl std::error::Error for LimitError {}

/// `n` with thousands separators: 67,108,864.
fn group(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Bytes in the largest binary unit that keeps the number at or above 1: "1.5 GiB".
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [&str; 7] = ["bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} bytes")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// Check a count against its limit (`what` describes the request).
pub fn check_count(what: impl Into<String>, requested: u64, limit: u64, unit: &'static str) -> Result<(), LimitError> {
    if requested > limit {
        return Err(LimitError { what: what.into(), requested, limit, unit, bytes: None });
    }
    Ok(())
}

/// Check `count` elements (the product of `dims`, overflow-safe) against `limit`, and their
/// memory (`bytes_each` per element) against [`MEMORY_BUDGET`]. Returns the element count.
pub fn check_elements(
    what: impl Into<String>,
    dims: &[u64],
    limit: u64,
    unit: &'static str,
    bytes_each: u64,
) -> Result<u64, LimitError> {
    let what = what.into();
    let count = dims.iter().try_fold(1u64, |a, &d| a.checked_mul(d));
    let bytes = count.and_then(|c| c.checked_mul(bytes_each));
    let count = count.unwrap_or(u64::MAX);
    // bytes_each = 0: a count limit only (the caller checks memory where it knows it).
    let bytes = if bytes_each == 0 { None } else { Some(bytes.unwrap_or(u64::MAX)) };
    if count > limit {
        return Err(LimitError { what, requested: count, limit, unit, bytes });
    }
    if let Some(b) = bytes {
        check_memory(what, b)?;
    }
    Ok(count)
}

/// Check a planned allocation of `bytes` against [`MEMORY_BUDGET`].
pub fn check_memory(what: impl Into<String>, bytes: u64) -> Result<(), LimitError> {
    if bytes > MEMORY_BUDGET {
        return Err(LimitError {
            what: what.into(),
            requested: bytes,
            limit: MEMORY_BUDGET,
            unit: "bytes",
            bytes: None,
        });
    }
    Ok(())
}

/// Check a `width` × `height` image against [`MAX_PIXELS`] and its memory (`bytes_per_pixel`)
/// against the budget; `what` names it ("render", "photo views/a.png").
pub fn check_image(what: &str, width: u64, height: u64, bytes_per_pixel: u64) -> Result<u64, LimitError> {
    check_elements(
        format!("{what} of {width}x{height} pixels"),
        &[width, height],
        MAX_PIXELS,
        "pixels",
        bytes_per_pixel,
    )
}

/// Check a thread count against [`MAX_THREADS`].
pub fn check_threads(threads: u64) -> Result<(), LimitError> {
    check_count("worker threads", threads, MAX_THREADS, "threads")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn images_over_the_limit_say_the_limit_and_the_memory() {
        let e = check_image("render", 100_000, 100_000, 100).unwrap_err();
        let m = e.to_string();
        assert_eq!(e.requested, 10_000_000_000);
        assert!(m.contains("100000x100000") && m.contains("67,108,864") && m.contains("931.3 GiB"), "{m}");
        // Overflowing products saturate instead of wrapping to something small.
        let e = check_image("render", u32::MAX as u64 + 1, u32::MAX as u64 + 1, 12).unwrap_err();
        assert_eq!(e.requested, u64::MAX);
        assert!(e.to_string().contains("more than 2^64"), "{e}");
        // Under the count limit but over the memory budget.
        let e = check_image("grid", 8192, 8192, 1024).unwrap_err();
        assert_eq!(e.unit, "bytes");
        assert!(e.to_string().contains("64.0 GiB") && e.to_string().contains("16.0 GiB"), "{e}");
        assert_eq!(check_image("render", 320, 240, 300), Ok(76_800));
    }

    #[test]
    fn counts_and_threads() {
        assert!(check_threads(100_000).unwrap_err().to_string().contains("100,000 threads requested"));
        assert!(check_threads(2).is_ok());
        assert_eq!(format_bytes(1536), "1.5 KiB");
        assert_eq!(format_bytes(12), "12 bytes");
    }
}
