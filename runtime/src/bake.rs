//! Baking a compiled graph to image maps: albedo (sRGB PNG and linear EXR), normal (PNG,
//! OpenGL convention), roughness (PNG), height (EXR), metallic (PNG, only when used).
//!
//! Texel `(i, j)` (column `i`, row `j` from the top of the image) is evaluated at
//! `uv = ((i + 0.5) / N, 1 - (j + 0.5) / N)`: v grows upwards in the image, as OpenGL texture
//! space does, so the written normal map is a standard OpenGL (+Y up) map. Graphs are periodic
//! over the unit tile, so every baked map tiles seamlessly at any size.
//!
//! Single files (`write_png_rgb`, `write_exr`, …) are written atomically through
//! `psc_base::output`; a set of maps ([`write_maps`]) goes into a folder the caller stages, so a
//! failed or interrupted bake never leaves a half-written or mixed output.

use std::io;
use std::path::{Path, PathBuf};

use psc_base::output::write_atomic_with;
use psc_compiler::Channel;

use crate::kernel::grid_uv;

/// Evaluates a graph's forward program at a batch of points: `(params, u, v)` to the
/// [`Channel::ALL`] columns, in order, each as long as `u`.
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

/// Assembles maps from the forward channels ([`Channel::ALL`]) evaluated over [`grid_uv`].
pub fn maps_from_channels(size: usize, ch: &[Vec<f32>]) -> Result<Maps, String> {
    let n = size * size;
    if ch.len() != Channel::COUNT || ch.iter().any(|c| c.len() != n) {
        return Err(format!("expected {} channels of {n} values, got {}", Channel::COUNT, ch.len()));
    }
    let col = |c: Channel| &ch[c.index()];
    let mut albedo = Vec::with_capacity(3 * n);
    let mut normal = Vec::with_capacity(3 * n);
    for k in 0..n {
        albedo.extend(Channel::ALBEDO.map(|c| col(c)[k]));
        normal.extend(Channel::NORMAL.map(|c| col(c)[k]));
    }
    Ok(Maps {
        size,
        albedo,
        roughness: col(Channel::Roughness).clone(),
        normal,
        height: col(Channel::Height).clone(),
        metallic: col(Channel::Metallic).clone(),
    })
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

fn io_err(e: impl std::fmt::Display) -> io::Error {
    io::Error::other(e.to_string())
}

fn save_png(path: &Path, size: (u32, u32), pixels: &[u8], color: image::ColorType) -> io::Result<()> {
    image::save_buffer_with_format(path, pixels, size.0, size.1, color, image::ImageFormat::Png).map_err(io_err)
}

/// Writes an 8-bit RGB PNG atomically (`psc_base::output::write_atomic_with`).
pub fn write_png_rgb(path: &Path, size: (u32, u32), rgb: &[u8]) -> io::Result<()> {
    write_atomic_with(path, |tmp| save_png(tmp, size, rgb, image::ColorType::Rgb8)).map_err(io::Error::from)
}

/// Writes an 8-bit greyscale PNG atomically.
pub fn write_png_gray(path: &Path, size: (u32, u32), gray: &[u8]) -> io::Result<()> {
    write_atomic_with(path, |tmp| save_png(tmp, size, gray, image::ColorType::L8)).map_err(io::Error::from)
}

/// Writes a 32-bit float EXR with RGB channels (`channels` = 3) or one `Y` channel, atomically.
pub fn write_exr(path: &Path, size: usize, data: &[f32], channels: usize) -> io::Result<()> {
    write_atomic_with(path, |tmp| save_exr(tmp, size, data, channels)).map_err(io::Error::from)
}

fn save_exr(path: &Path, size: usize, data: &[f32], channels: usize) -> io::Result<()> {
    use exr::prelude::*;
    if channels == 3 {
        // The renderer's encoder: the same settings, block order fixed for reproducible bytes.
        let rgb: Vec<[f32; 3]> = data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let bytes = psc_render::image_io::encode_exr(size, size, &rgb).map_err(io_err)?;
        return std::fs::write(path, bytes);
    }
    let channel = AnyChannel::new("Y", FlatSamples::F32(data.to_vec()));
    let layer = Layer::new(
        (size, size),
        LayerAttributes::named("height"),
        Encoding::SMALL_LOSSLESS, // scan lines in increasing order: reproducible bytes
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    Image::from_layer(layer).write().to_file(path).map_err(io_err)
}

/// Writes every map of `maps` into `dir` as `{stem}_albedo.png`, `{stem}_albedo.exr`,
/// `{stem}_normal.png`, `{stem}_roughness.png`, `{stem}_height.exr` and, when the graph is
/// not everywhere dielectric, `{stem}_metallic.png`. Returns the paths written.
///
/// The files are written directly: `dir` is meant to be a folder being staged
/// (`psc_base::output::StagedDir`), which makes the whole set appear at once or not at all.
pub fn write_maps(maps: &Maps, dir: &Path, stem: &str) -> io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let s = maps.size;
    let dims = (s as u32, s as u32);
    let mut written = Vec::new();

    let albedo_srgb: Vec<u8> = maps.albedo.iter().map(|&x| to_u8(linear_to_srgb(x))).collect();
    let p = dir.join(format!("{stem}_albedo.png"));
    save_png(&p, dims, &albedo_srgb, image::ColorType::Rgb8)?;
    written.push(p);

    let p = dir.join(format!("{stem}_albedo.exr"));
    save_exr(&p, s, &maps.albedo, 3)?;
    written.push(p);

    let normal: Vec<u8> = maps.normal.iter().map(|&x| to_u8(x * 0.5 + 0.5)).collect();
    let p = dir.join(format!("{stem}_normal.png"));
    save_png(&p, dims, &normal, image::ColorType::Rgb8)?;
    written.push(p);

    let rough: Vec<u8> = maps.roughness.iter().map(|&x| to_u8(x)).collect();
    let p = dir.join(format!("{stem}_roughness.png"));
    save_png(&p, dims, &rough, image::ColorType::L8)?;
    written.push(p);

    let p = dir.join(format!("{stem}_height.exr"));
    save_exr(&p, s, &maps.height, 1)?;
    written.push(p);

    if maps.metallic.iter().any(|&m| m != 0.0) {
        let metal: Vec<u8> = maps.metallic.iter().map(|&x| to_u8(x)).collect();
        let p = dir.join(format!("{stem}_metallic.png"));
        save_png(&p, dims, &metal, image::ColorType::L8)?;
        written.push(p);
    }
    Ok(written)
}
