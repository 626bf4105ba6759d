//! Baking a compiled graph to image maps: albedo (sRGB PNG and linear EXR), normal (PNG,
//! OpenGL convention), roughness (PNG), height (EXR), metallic (PNG, only when used).
//!
//! Texel `(i, j)` (column `i`, row `j` from the top of the image) is evaluated at
//! `uv = ((i + 0.5) / N, 1 - (j + 0.5) / N)`: v grows upwards in the image, as OpenGL texture
//! space does, so the written normal map is a standard OpenGL (+Y up) map. Graphs are periodic
//! over the unit tile, so every baked map tiles seamlessly at any size.
//!
//! Every file is written to a temporary name in the destination folder and renamed into place,
//! so a failed or interrupted bake never leaves a half-written output.

use std::io;
use std::path::{Path, PathBuf};

use psc_compiler::{GraphInfo, ParamKind};

use crate::kernel::grid_uv;

/// Evaluates a graph's forward program at a batch of points: `(params, u, v)` to the nine
/// channels of [`psc_compiler::CHANNELS`], one column each, as long as `u`.
pub type Evaluator<'a> = dyn Fn(&[f32], &[f32], &[f32]) -> Result<Vec<Vec<f32>>, String> + Sync + 'a;

/// Baked maps of one graph at one parameter vector, row-major from the top row.
#[derive(Clone, Debug)]
pub struct Maps {
    pub size: usize,
    /// Linear RGB, three floats per texel.
    pub albedo: Vec<f32>,
    pub roughness: Vec<f32>,
    /// Unit tangent-space normals (OpenGL convention), three floats per texel.
    pub normal: Vec<f32>,
    /// Height in tile units.
    pub height: Vec<f32>,
    pub metallic: Vec<f32>,
}

/// Assembles maps from the nine forward channels evaluated over [`grid_uv`].
pub fn maps_from_channels(size: usize, ch: &[Vec<f32>]) -> Result<Maps, String> {
    let n = size * size;
    if ch.len() != 9 || ch.iter().any(|c| c.len() != n) {
        return Err(format!("expected 9 channels of {n} values, got {}", ch.len()));
    }
    let mut albedo = Vec::with_capacity(3 * n);
    let mut normal = Vec::with_capacity(3 * n);
    for k in 0..n {
        albedo.extend_from_slice(&[ch[0][k], ch[1][k], ch[2][k]]);
        normal.extend_from_slice(&[ch[4][k], ch[5][k], ch[6][k]]);
    }
    Ok(Maps { size, albedo, roughness: ch[3].clone(), normal, height: ch[7].clone(), metallic: ch[8].clone() })
}

/// Evaluates a graph over a `size`×`size` grid and returns its maps.
pub fn bake(eval: &Evaluator, params: &[f32], size: usize) -> Result<Maps, String> {
    let (u, v) = grid_uv(size, size).map_err(|e| e.to_string())?;
    let ch = eval(params, &u, &v)?;
    maps_from_channels(size, &ch)
}

/// The workspace's one sRGB transfer (clamped to [0, 1], NaN to 0).
pub use psc_base::color::{linear_to_srgb, srgb_to_linear};

fn to_u8(x: f32) -> u8 {
    if x.is_nan() {
        0
    } else {
        (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
    }
}

/// Writes `bytes` through a temporary file in the same folder, then renames it into place.
pub fn write_atomic(path: &Path, write: impl FnOnce(&Path) -> io::Result<()>) -> io::Result<()> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().and_then(|s| s.to_str()).unwrap_or("out");
    // Keep the real extension last so the image encoders pick the right format.
    let tmp = dir.join(format!(".{}.{}.tmp.{name}", name, std::process::id()));
    let result = write(&tmp).and_then(|_| std::fs::rename(&tmp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn io_err(e: impl std::fmt::Display) -> io::Error {
    io::Error::other(e.to_string())
}

/// Writes an 8-bit RGB PNG.
pub fn write_png_rgb(path: &Path, size: (u32, u32), rgb: &[u8]) -> io::Result<()> {
    write_atomic(path, |tmp| {
        image::save_buffer_with_format(tmp, rgb, size.0, size.1, image::ColorType::Rgb8, image::ImageFormat::Png)
            .map_err(io_err)
    })
}

/// Writes an 8-bit greyscale PNG.
pub fn write_png_gray(path: &Path, size: (u32, u32), gray: &[u8]) -> io::Result<()> {
    write_atomic(path, |tmp| {
        image::save_buffer_with_format(tmp, gray, size.0, size.1, image::ColorType::L8, image::ImageFormat::Png)
            .map_err(io_err)
    })
}

/// Writes a 32-bit float EXR with RGB channels (`channels` = 3) or one `Y` channel.
pub fn write_exr(path: &Path, size: usize, data: &[f32], channels: usize) -> io::Result<()> {
    use exr::prelude::*;
    write_atomic(path, |tmp| {
        if channels == 3 {
            // The renderer's encoder: the same settings, block order fixed for reproducible bytes.
            let rgb: Vec<[f32; 3]> = data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            let bytes = psc_render::image_io::encode_exr(size, size, &rgb).map_err(io_err)?;
            return std::fs::write(tmp, bytes);
        }
        let channel = AnyChannel::new("Y", FlatSamples::F32(data.to_vec()));
        let layer = Layer::new(
            (size, size),
            LayerAttributes::named("height"),
            Encoding::SMALL_LOSSLESS, // scan lines in increasing order: reproducible bytes
            AnyChannels::sort(SmallVec::from_vec(vec![channel])),
        );
        Image::from_layer(layer).write().to_file(tmp).map_err(io_err)
    })
}

/// Writes every map of `maps` into `dir` as `{stem}_albedo.png`, `{stem}_albedo.exr`,
/// `{stem}_normal.png`, `{stem}_roughness.png`, `{stem}_height.exr` and, when the graph is
/// not everywhere dielectric, `{stem}_metallic.png`. Returns the paths written.
pub fn write_maps(maps: &Maps, dir: &Path, stem: &str) -> io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let s = maps.size;
    let dims = (s as u32, s as u32);
    let mut written = Vec::new();

    let albedo_srgb: Vec<u8> = maps.albedo.iter().map(|&x| to_u8(linear_to_srgb(x))).collect();
    let p = dir.join(format!("{stem}_albedo.png"));
    write_png_rgb(&p, dims, &albedo_srgb)?;
    written.push(p);

    let p = dir.join(format!("{stem}_albedo.exr"));
    write_exr(&p, s, &maps.albedo, 3)?;
    written.push(p);

    let normal: Vec<u8> = maps.normal.iter().map(|&x| to_u8(x * 0.5 + 0.5)).collect();
    let p = dir.join(format!("{stem}_normal.png"));
    write_png_rgb(&p, dims, &normal)?;
    written.push(p);

    let rough: Vec<u8> = maps.roughness.iter().map(|&x| to_u8(x)).collect();
    let p = dir.join(format!("{stem}_roughness.png"));
    write_png_gray(&p, dims, &rough)?;
    written.push(p);

    let p = dir.join(format!("{stem}_height.exr"));
    write_exr(&p, s, &maps.height, 1)?;
    written.push(p);

    if maps.metallic.iter().any(|&m| m != 0.0) {
        let metal: Vec<u8> = maps.metallic.iter().map(|&x| to_u8(x)).collect();
        let p = dir.join(format!("{stem}_metallic.png"));
        write_png_gray(&p, dims, &metal)?;
        written.push(p);
    }
    Ok(written)
}

/// The deterministic generator for random parameter variants: the workspace's SplitMix64.
pub use psc_base::SplitMix64 as Rng;

/// A random parameter vector: continuous parameters uniform over their range, discrete ones
/// uniform over their integers, colours the default scaled by 0.7–1.3 in sRGB plus up to ±0.08
/// per channel (so that variants stay plausible members of the material's family).
pub fn random_params(info: &GraphInfo, rng: &mut Rng) -> Vec<f32> {
    let mut out = info.default_params();
    for p in &info.params {
        match p.kind {
            ParamKind::Continuous { min, max } => out[p.slot] = min + (max - min) * rng.next_f32(),
            ParamKind::Discrete { min, max } => {
                let span = (max - min + 1) as u64;
                out[p.slot] = (min + (rng.next_u64() % span) as i64) as f32;
            }
            ParamKind::Color => {
                // A common brightness change and a smaller independent shift per channel.
                let scale = 0.7 + 0.6 * rng.next_f32();
                for c in 0..3 {
                    let s = linear_to_srgb(p.default[c]) * scale + 0.16 * (rng.next_f32() - 0.5);
                    out[p.slot + c] = srgb_to_linear(s);
                }
            }
        }
    }
    out
}

/// Reads a parameter file: a JSON object mapping parameter names to numbers (continuous and
/// discrete) or to `[r, g, b]` (colours, linear) or `{"srgb": [r, g, b]}`. Parameters not
/// named keep their defaults; unknown names and out-of-range values are errors.
pub fn params_from_json(info: &GraphInfo, json: &serde_json::Value) -> Result<Vec<f32>, String> {
    let obj = json.as_object().ok_or("the parameter file must hold a JSON object")?;
    let mut out = info.default_params();
    for (name, value) in obj {
        let p = info.param(name).ok_or_else(|| {
            let names: Vec<&str> = info.params.iter().map(|p| p.name.as_str()).collect();
            format!("graph `{}` has no parameter `{name}` (it has: {})", info.name, names.join(", "))
        })?;
        match p.kind {
            ParamKind::Continuous { min, max } => {
                let x = value.as_f64().ok_or_else(|| format!("`{name}` must be a number"))? as f32;
                if !(min..=max).contains(&x) {
                    return Err(format!("`{name}` = {x} is outside its range [{min}, {max}]"));
                }
                out[p.slot] = x;
            }
            ParamKind::Discrete { min, max } => {
                let x = value.as_f64().ok_or_else(|| format!("`{name}` must be an integer"))?;
                if x.fract() != 0.0 || x < min as f64 || x > max as f64 {
                    return Err(format!("`{name}` = {x} must be an integer in [{min}, {max}]"));
                }
                out[p.slot] = x as f32;
            }
            ParamKind::Color => {
                let (arr, srgb) = match value {
                    serde_json::Value::Object(o) if o.contains_key("srgb") => (&o["srgb"], true),
                    v => (v, false),
                };
                let arr = arr
                    .as_array()
                    .filter(|a| a.len() == 3)
                    .ok_or_else(|| format!("`{name}` must be [r, g, b] or {{\"srgb\": [r, g, b]}}"))?;
                for (c, x) in arr.iter().enumerate() {
                    let x = x.as_f64().ok_or_else(|| format!("`{name}` must hold numbers"))? as f32;
                    if !(0.0..=1.0).contains(&x) {
                        return Err(format!("`{name}` channel {c} = {x} is outside [0, 1]"));
                    }
                    out[p.slot + c] = if srgb { srgb_to_linear(x) } else { x };
                }
            }
        }
    }
    Ok(out)
}

/// The parameter vector as a JSON object in the format [`params_from_json`] reads (colours as
/// linear `[r, g, b]`), for writing next to random variants.
pub fn params_to_json(info: &GraphInfo, params: &[f32]) -> serde_json::Value {
    let mut obj = serde_json::Map::new();
    for p in &info.params {
        let v = match p.kind {
            ParamKind::Color => serde_json::json!([params[p.slot], params[p.slot + 1], params[p.slot + 2]]),
            ParamKind::Discrete { .. } => serde_json::json!(params[p.slot] as i64),
            ParamKind::Continuous { .. } => serde_json::json!(params[p.slot]),
        };
        obj.insert(p.name.clone(), v);
    }
    serde_json::Value::Object(obj)
}
