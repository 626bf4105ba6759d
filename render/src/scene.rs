//! Scene folders (`photoscene-scene/1`, see `shared/design/scene-format.md`): the manifest,
//! validation, views with their cameras and label images, emitters, the environment, and the
//! light radiances `psc render` uses.
//!
//! Errors (the scene cannot be used): missing files, malformed JSON (with line:column),
//! degenerate cameras, label images of the wrong size or kind. Warnings (the scene loads):
//! unknown format string, OBJ without uvs, labels naming parts the model lacks, label values
//! without a name, generated lights.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::Vec3;
use serde::Deserialize;

use psc_base::progress::{NoProgress, Progress};

use crate::camera::{Camera, CameraSpec};
use crate::emitters::EnvMap;
use crate::image_io;
use crate::material::{ImageMaterial, MaterialBinding, Texture};
use crate::mesh::{self, Mesh};
use crate::RenderError;

pub use crate::lights::LightRadiances;

pub const FORMAT: &str = "photoscene-scene/1";

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    format: Option<String>,
    units: Option<String>,
    up: Option<[f32; 3]>,
    mesh: String,
    #[serde(default)]
    views: Vec<ViewSpec>,
    lights: Option<Vec<LightSpec>>,
    environment: Option<EnvSpec>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ViewSpec {
    name: String,
    image: String,
    camera: CameraSpec,
    parts: Option<String>,
    #[serde(default)]
    part_labels: BTreeMap<String, String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightSpec {
    name: String,
    mesh: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EnvSpec {
    image: String,
}

/// A part-label image aligned with a photo.
#[derive(Clone, Debug)]
pub struct Labels {
    pub width: usize,
    pub height: usize,
    /// Row-major label values, 0 = unlabelled.
    pub data: Vec<u16>,
}

/// One input photo with its camera.
#[derive(Clone, Debug)]
pub struct View {
    pub name: String,
    pub image: PathBuf,
    pub camera_spec: CameraSpec,
    pub camera: Camera,
    pub width: usize,
    pub height: usize,
    pub labels: Option<Labels>,
    /// Label value → part name, as written in scene.json.
    pub part_labels: BTreeMap<u16, String>,
}

/// One emitter: one-sided triangles emitting along their winding normal.
#[derive(Clone, Debug)]
pub struct LightSource {
    pub name: String,
    pub triangles: Vec<[Vec3; 3]>,
}

/// A loaded, validated scene folder.
pub struct Scene {
    pub root: PathBuf,
    pub up: Vec3,
    pub mesh: Mesh,
    pub views: Vec<View>,
    pub lights: Vec<LightSource>,
    /// True when the manifest had no `lights` and lights were placed on the ceiling.
    pub lights_generated: bool,
    pub environment: Option<EnvMap>,
    pub warnings: Vec<String>,
}

fn require_file(root: &Path, rel: &str, what: &str) -> Result<PathBuf, RenderError> {
    let p = confined(root, rel, what)?;
    crate::json::check_file(&p, what)?;
    Ok(p)
}

/// `root/rel`, refused unless it stays inside the scene folder `root`: files a scene names are
/// part of the scene, so absolute paths and `..` or symbolic links that lead outside are errors
/// (a scene from elsewhere must not make the loader read `/etc/shadow`).
pub fn confined(root: &Path, rel: &str, what: &str) -> Result<PathBuf, RenderError> {
    let given = Path::new(rel);
    let p = root.join(given);
    if given.is_absolute() {
        return Err(RenderError::io(
            &p,
            format!("{what}: absolute paths are not allowed; files named by a scene stay inside its folder"),
        ));
    }
    // Lexically first (also for files that do not exist yet), then through symbolic links.
    let mut depth = 0i32;
    for c in given.components() {
        match c {
            std::path::Component::ParentDir => depth -= 1,
            std::path::Component::Normal(_) => depth += 1,
            _ => {}
        }
        if depth < 0 {
            return Err(RenderError::io(&p, format!("{what}: '{rel}' leads outside the scene folder")));
        }
    }
    if let (Ok(real_root), Ok(real)) = (root.canonicalize(), p.canonicalize()) {
        if !real.starts_with(&real_root) {
            return Err(RenderError::io(
                &p,
                format!("{what}: '{rel}' leads outside the scene folder (to {})", real.display()),
            ));
        }
    }
    Ok(p)
}

impl View {
    /// Every pixel of the photo, linear RGB (decoded from sRGB for PNG/JPEG); errors name the
    /// file.
    pub fn read_photo(&self) -> Result<image_io::RgbImage, RenderError> {
        image_io::read_rgb(&self.image, true)
    }
}

impl Scene {
    /// Load `dir/scene.json` and everything it names.
    pub fn load(dir: &Path) -> Result<Scene, RenderError> {
        Self::load_with_mesh(dir, None)
    }

    /// Like [`Scene::load`] but with another OBJ in place of the manifest's mesh (e.g. the dev
    /// scenes' `truth/scene_true.obj` for validation).
    pub fn load_with_mesh(dir: &Path, mesh_override: Option<&Path>) -> Result<Scene, RenderError> {
        Self::load_with_progress(dir, mesh_override, &NoProgress)
    }

    /// [`Scene::load_with_mesh`], reporting the loading of the mesh (in bytes parsed) to
    /// `progress`.
    pub fn load_with_progress(
        dir: &Path,
        mesh_override: Option<&Path>,
        progress: &dyn Progress,
    ) -> Result<Scene, RenderError> {
        let manifest_path = dir.join("scene.json");
        let m: Manifest = crate::json::read(&manifest_path, "scene manifest (scene.json)")?;
        let mut warnings = Vec::new();
        match m.format.as_deref() {
            Some(FORMAT) => {}
            Some(other) => warnings.push(format!(
                "{}: format '{other}' is not '{FORMAT}'; reading it as {FORMAT}",
                manifest_path.display()
            )),
            None => warnings.push(format!("{}: no \"format\"; assuming {FORMAT}", manifest_path.display())),
        }
        if let Some(u) = m.units.as_deref() {
            if u != "meters" && u != "metres" {
                warnings
                    .push(format!("{}: units '{u}': generated uvs and lights assume metres", manifest_path.display()));
            }
        }
        let up = Vec3::from(m.up.unwrap_or([0.0, 1.0, 0.0]));
        if !up.is_finite() || up.length() <= 1e-6 {
            return Err(RenderError::Invalid(format!("{}: \"up\" must be a non-zero vector", manifest_path.display())));
        }
        let up = up.normalize();

        let mesh_path = match mesh_override {
            Some(p) => p.to_path_buf(),
            None => require_file(dir, &m.mesh, "mesh")?,
        };
        let mesh = mesh::load_obj_in(&mesh_path, dir, &mut warnings, progress)?;

        let mut views: Vec<View> = Vec::new();
        for v in &m.views {
            if views.iter().any(|o| o.name == v.name) {
                return Err(RenderError::Invalid(format!(
                    "{}: two views are named '{}'",
                    manifest_path.display(),
                    v.name
                )));
            }
            views.push(load_view(dir, v, &mesh, &mut warnings)?);
        }

        let mut lights = Vec::new();
        let lights_generated = m.lights.is_none();
        match &m.lights {
            Some(specs) => {
                for l in specs {
                    if lights.iter().any(|o: &LightSource| o.name == l.name) {
                        return Err(RenderError::Invalid(format!(
                            "{}: two lights are named '{}'",
                            manifest_path.display(),
                            l.name
                        )));
                    }
                    let p = require_file(dir, &l.mesh, &format!("mesh of light '{}'", l.name))?;
                    let triangles = mesh::load_emitter_in(&p, dir, &mut warnings)?;
                    lights.push(LightSource { name: l.name.clone(), triangles });
                }
            }
            None => {
                lights = ceiling_lights(&mesh, up);
                warnings.push(format!(
                    "{}: no \"lights\"; placed {} area light(s) on the ceiling every 3 m",
                    manifest_path.display(),
                    lights.len()
                ));
            }
        }

        let environment = match &m.environment {
            Some(e) => {
                let p = require_file(dir, &e.image, "environment image")?;
                let is_exr = p.extension().is_some_and(|x| x.eq_ignore_ascii_case("exr"));
                let img = image_io::read_rgb(&p, !is_exr)?;
                Some(EnvMap::new(img.width, img.height, img.data.into_iter().map(Vec3::from).collect()))
            }
            None => None,
        };
        Ok(Scene { root: dir.to_path_buf(), up, mesh, views, lights, lights_generated, environment, warnings })
    }

    pub fn view(&self, name: &str) -> Option<&View> {
        self.views.iter().find(|v| v.name == name)
    }

    /// Materials from the MTL: `map_Kd` as an sRGB image texture (with `norm`/`bump` as a normal
    /// map), else `Kd` as a constant; roughness from `Pr`, else 0.5. Unreadable textures fall back
    /// to the constant with a warning.
    pub fn mtl_materials(&self, warnings: &mut Vec<String>) -> Vec<MaterialBinding> {
        let mut out = Vec::new();
        for info in &self.mesh.part_mtl {
            let albedo = info.kd.unwrap_or([0.5; 3]);
            let roughness = info.roughness.unwrap_or(0.5);
            let mut binding = MaterialBinding::constant(albedo, roughness);
            if let Some(tex) = &info.map_kd {
                match Texture::load(tex, true) {
                    Ok(t) => {
                        let mut mat = ImageMaterial::new(t, roughness);
                        if let Some(nm) = &info.map_normal {
                            match Texture::load(nm, false) {
                                Ok(n) => mat = mat.with_normal_map(n),
                                Err(e) => warnings.push(format!("normal map ignored: {e}")),
                            }
                        }
                        binding = MaterialBinding::new(Arc::new(mat));
                    }
                    Err(e) => warnings.push(format!("texture ignored, using Kd: {e}")),
                }
            }
            out.push(binding);
        }
        out
    }
}

fn load_view(dir: &Path, v: &ViewSpec, mesh: &Mesh, warnings: &mut Vec<String>) -> Result<View, RenderError> {
    let image = require_file(dir, &v.image, &format!("photo of view '{}'", v.name))?;
    let (width, height) = image_io::dimensions(&image)?;
    // Decode every pixel once: a truncated or corrupt photo is an error naming the file now,
    // not when the fit reads it.
    image_io::read_rgb(&image, true)?;
    let camera = Camera::new(&v.camera, width, height, &format!("view '{}'", v.name))?;
    let mut part_labels = BTreeMap::new();
    for (key, name) in &v.part_labels {
        let value: u16 = key.trim().parse().map_err(|_| {
            RenderError::Invalid(format!("view '{}': part label key '{key}' is not an integer in 1..=65535", v.name))
        })?;
        if value == 0 {
            return Err(RenderError::Invalid(format!(
                "view '{}': label 0 means unlabelled and cannot name a part",
                v.name
            )));
        }
        if mesh.part_index(name).is_none() {
            warnings
                .push(format!("view '{}': label {value} names part '{name}', which the model does not have", v.name));
        }
        part_labels.insert(value, name.clone());
    }
    let labels = match &v.parts {
        Some(rel) => {
            let p = require_file(dir, rel, &format!("part-label image of view '{}'", v.name))?;
            let (w, h, data) = image_io::read_labels(&p)?;
            if (w, h) != (width, height) {
                return Err(RenderError::image(
                    &p,
                    format!("label image is {w}x{h} but the photo is {width}x{height}"),
                ));
            }
            let mut unnamed: Vec<u16> =
                data.iter().copied().filter(|&l| l != 0 && !part_labels.contains_key(&l)).collect();
            unnamed.sort_unstable();
            unnamed.dedup();
            if !unnamed.is_empty() {
                warnings.push(format!(
                    "view '{}': label values {unnamed:?} have no entry in part_labels; treated as unlabelled",
                    v.name
                ));
            }
            Some(Labels { width: w, height: h, data })
        }
        None => None,
    };
    Ok(View { name: v.name.clone(), image, camera_spec: v.camera.clone(), camera, width, height, labels, part_labels })
}

/// 0.5 m square emitters facing down, 5 mm below the highest point of the model, on a grid of
/// roughly 3 m spacing over the model's horizontal extent.
fn ceiling_lights(mesh: &Mesh, up: Vec3) -> Vec<LightSource> {
    let (lo, hi) = mesh.bounds();
    let a = up.abs();
    let (ax, b1, b2) = if a.y >= a.x && a.y >= a.z {
        (1, 0, 2)
    } else if a.x >= a.z {
        (0, 1, 2)
    } else {
        (2, 0, 1)
    };
    let sign = if up[ax] >= 0.0 { 1.0 } else { -1.0 };
    let height = if sign > 0.0 { hi[ax] - 0.005 } else { lo[ax] + 0.005 };
    let n1 = (((hi[b1] - lo[b1]) / 3.0).round() as usize).max(1);
    let n2 = (((hi[b2] - lo[b2]) / 3.0).round() as usize).max(1);
    let mut lights = Vec::new();
    for i in 0..n1 {
        for j in 0..n2 {
            let mut c = Vec3::ZERO;
            c[ax] = height;
            c[b1] = lo[b1] + (i as f32 + 0.5) * (hi[b1] - lo[b1]) / n1 as f32;
            c[b2] = lo[b2] + (j as f32 + 0.5) * (hi[b2] - lo[b2]) / n2 as f32;
            let mut e1 = Vec3::ZERO;
            e1[b1] = 0.25;
            let mut e2 = Vec3::ZERO;
            e2[b2] = 0.25;
            let q = [c - e1 - e2, c + e1 - e2, c + e1 + e2, c - e1 + e2];
            let mut t = [[q[0], q[1], q[2]], [q[0], q[2], q[3]]];
            for tri in &mut t {
                if (tri[1] - tri[0]).cross(tri[2] - tri[0]).dot(up) > 0.0 {
                    tri.swap(1, 2); // emit away from the ceiling
                }
            }
            lights.push(LightSource { name: format!("auto{}", lights.len()), triangles: t.to_vec() });
        }
    }
    lights
}
