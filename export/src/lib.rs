//! The fitted room for the tools people already have: a glTF 2.0 scene (metallic-roughness,
//! for Blender and any viewer) and a Mitsuba 3 scene, both with baked maps per part.
//!
//! Owns: turning a scene, a material assignment (bound to the library) and light radiances into
//! `scene.gltf` + `scene.bin` + `textures/*.png` ([`gltf`]) and `scene_mitsuba.xml` +
//! `meshes/*.ply` ([`mitsuba`]), sharing the per-part geometry and baked maps ([`prepare`]).
//! Must never: shade, fit or render anything of its own (the look is the renderer's model,
//! expressed in each format as closely as it allows), read ground truth, or write outside the
//! folder it is given (callers stage that folder; [`export`] does it for them).

#![forbid(unsafe_code)]

pub mod gltf;
pub mod mitsuba;
pub mod prepare;

use std::fmt;
use std::path::{Path, PathBuf};

use psc_base::output::{Replace, StagedDir};
use psc_render::scene::Scene;
use psc_render::LightRadiances;
use psc_runtime::assign::Assignment;
use psc_runtime::library::Library;

/// Choices of an export.
#[derive(Clone, Debug)]
pub struct ExportOptions {
    /// Baked maps are `texture_size`² texels (the default: 1024).
    pub texture_size: usize,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions { texture_size: 1024 }
    }
}

/// What an export wrote.
#[derive(Clone, Debug, Default)]
pub struct ExportSummary {
    /// Every file written, relative to the export folder, in the order written.
    pub files: Vec<PathBuf>,
    pub parts: usize,
    pub lights: usize,
    pub cameras: usize,
    /// Things a user should know (a part without an assigned graph, an environment left out).
    pub warnings: Vec<String>,
}

/// Why an export failed. Nothing is left in the destination on any of them.
#[derive(Debug)]
pub enum ExportError {
    /// The inputs do not fit together (unknown part, graph not in the library, bad radiance,
    /// bad texture size).
    Input(String),
    /// A file could not be written.
    Io { path: PathBuf, message: String },
}

impl fmt::Display for ExportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExportError::Input(m) => f.write_str(m),
            ExportError::Io { path, message } => write!(f, "{}: {message}", path.display()),
        }
    }
}

impl std::error::Error for ExportError {}

impl ExportError {
    pub(crate) fn io(path: &Path, e: impl fmt::Display) -> Self {
        ExportError::Io { path: path.to_path_buf(), message: e.to_string() }
    }
}

/// Largest texture edge accepted: a 16384² RGB map is 0.8 GB before encoding.
pub const MAX_TEXTURE_SIZE: usize = 16384;

fn check_options(options: &ExportOptions) -> Result<(), ExportError> {
    let n = options.texture_size;
    if n == 0 || n > MAX_TEXTURE_SIZE {
        return Err(ExportError::Input(format!("texture size {n}: expected 1 to {MAX_TEXTURE_SIZE} texels a side")));
    }
    psc_base::limits::check_elements(
        format!("baked map of {n}x{n} texels"),
        &[n as u64, n as u64],
        psc_base::limits::MAX_TEXELS,
        "texels",
        100,
    )
    .map_err(|e| ExportError::Input(e.to_string()))?;
    Ok(())
}

/// Writes both formats into `dir` (an existing, empty folder the caller stages and renames
/// into place): `scene.gltf`, `scene.bin`, `textures/`, `scene_mitsuba.xml`, `meshes/`. Every
/// input is checked before anything is written.
pub fn write_all(
    dir: &Path,
    scene: &Scene,
    library: &Library,
    assignment: &Assignment,
    lights: &LightRadiances,
    options: &ExportOptions,
) -> Result<ExportSummary, ExportError> {
    check_options(options)?;
    let prepared = prepare::prepare(scene, library, assignment, lights, options.texture_size)?;
    let mut summary = ExportSummary {
        parts: prepared.parts.len(),
        lights: prepared.lights.len(),
        cameras: scene.views.len(),
        warnings: prepared.warnings.clone(),
        ..ExportSummary::default()
    };
    summary.files.extend(write_textures(dir, &prepared)?);
    summary.files.extend(gltf::write(dir, scene, &prepared)?);
    summary.files.extend(mitsuba::write(dir, scene, &prepared)?);
    Ok(summary)
}

/// [`write_all`] into a staged folder renamed to `dest` when complete (an existing `dest` is
/// replaced only with [`Replace::Yes`]); on any error nothing appears at `dest`.
pub fn export(
    dest: &Path,
    replace: Replace,
    scene: &Scene,
    library: &Library,
    assignment: &Assignment,
    lights: &LightRadiances,
    options: &ExportOptions,
) -> Result<ExportSummary, ExportError> {
    check_options(options)?;
    prepare::check_inputs(scene, library, assignment, lights)?;
    let staged = StagedDir::new(dest, replace).map_err(|e| ExportError::io(dest, e))?;
    let summary = write_all(staged.path(), scene, library, assignment, lights, options)?;
    staged.commit().map_err(|e| ExportError::io(dest, e))?;
    Ok(summary)
}

/// The texture files of a part (relative to the export folder). Both formats share them.
pub struct TextureNames {
    /// sRGB albedo × albedo_scale (RGB).
    pub base_color: String,
    /// Tangent-space normal map, OpenGL convention (RGB), when the graph perturbs normals.
    pub normal: String,
    /// glTF's packed map: R = 1 (unused), G = roughness, B = metallic = 0.
    pub metallic_roughness: String,
    /// Roughness alone (one channel), for Mitsuba.
    pub roughness: String,
    /// The normal map with green inverted, for Mitsuba on parts whose tangent frame is
    /// left-handed (see [`prepare::PreparedPart::left_handed`]).
    pub normal_flipped: String,
}

impl TextureNames {
    pub fn of(stem: &str) -> TextureNames {
        TextureNames {
            base_color: format!("textures/{stem}_basecolor.png"),
            normal: format!("textures/{stem}_normal.png"),
            metallic_roughness: format!("textures/{stem}_metallic_roughness.png"),
            roughness: format!("textures/{stem}_roughness.png"),
            normal_flipped: format!("textures/{stem}_normal_mitsuba.png"),
        }
    }
}

/// Whether Mitsuba needs the green-inverted normal map for `part`.
pub(crate) fn mitsuba_flips_normal(part: &prepare::PreparedPart) -> bool {
    part.left_handed > part.right_handed
}

fn write_textures(dir: &Path, prepared: &prepare::Prepared) -> Result<Vec<PathBuf>, ExportError> {
    let mut files = Vec::new();
    for part in &prepared.parts {
        let prepare::PartLook::Baked { maps, .. } = &part.look else { continue };
        let names = TextureNames::of(&part.stem);
        let n = maps.size;
        files.push(write_png(dir, &names.base_color, n, 3, &maps.base_color)?);
        let packed: Vec<u8> = maps.roughness.iter().flat_map(|&r| [255, r, 0]).collect();
        files.push(write_png(dir, &names.metallic_roughness, n, 3, &packed)?);
        files.push(write_png(dir, &names.roughness, n, 1, &maps.roughness)?);
        if let Some(normal) = &maps.normal {
            files.push(write_png(dir, &names.normal, n, 3, normal)?);
            if mitsuba_flips_normal(part) {
                let flipped: Vec<u8> = normal.chunks_exact(3).flat_map(|c| [c[0], 255 - c[1], c[2]]).collect();
                files.push(write_png(dir, &names.normal_flipped, n, 3, &flipped)?);
            }
        }
    }
    Ok(files)
}

/// Encodes an 8-bit PNG (`channels` 1 or 3) into `dir/rel`, creating its folder.
pub(crate) fn write_png(
    dir: &Path,
    rel: &str,
    size: usize,
    channels: usize,
    data: &[u8],
) -> Result<PathBuf, ExportError> {
    let path = dir.join(rel);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(|e| ExportError::io(parent, e))?;
    }
    let color = if channels == 1 { image::ExtendedColorType::L8 } else { image::ExtendedColorType::Rgb8 };
    image::save_buffer_with_format(&path, data, size as u32, size as u32, color, image::ImageFormat::Png)
        .map_err(|e| ExportError::io(&path, e))?;
    Ok(PathBuf::from(rel))
}

/// Writes `bytes` to `dir/rel`, creating its folder.
pub(crate) fn write_file(dir: &Path, rel: &str, bytes: &[u8]) -> Result<PathBuf, ExportError> {
    let path = dir.join(rel);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(|e| ExportError::io(parent, e))?;
    }
    std::fs::write(&path, bytes).map_err(|e| ExportError::io(&path, e))?;
    Ok(PathBuf::from(rel))
}
