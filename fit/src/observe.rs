//! Stage 1, what each view shows: the photo (encoded and linear), the part each photo pixel is
//! labelled with, and the coarse model traced from the view's camera (the G-buffer the masks
//! and the alignment are computed from). Also the exact surface point behind any continuous
//! raster position, with its uv footprint, which the later stages trace at warped positions.

use std::path::Path;

use glam::Vec3;
use psc_render::camera::Camera;
use psc_render::geometry::{SceneGeometry, Traced};
use psc_render::image_io;
use psc_render::scene::View;
use rayon::prelude::*;

use crate::error::FitError;
use crate::working::WorkingRaster;

/// Marks "no part" in per-pixel part arrays.
pub const NO_PART: u32 = u32::MAX;

/// An encoded photo value at or above this, in any channel, is clipped.
pub const CLIP_LEVEL: f32 = 0.99;

/// A photo: values as encoded in the file (sRGB, in [0, 1]) and linear radiance.
#[derive(Clone, Debug)]
pub struct Photo {
    pub width: usize,
    pub height: usize,
    pub encoded: Vec<[f32; 3]>,
    pub linear: Vec<[f32; 3]>,
    /// Per pixel, whether it is clipped (see [`Photo::clipped`]).
    clip: Vec<bool>,
}

impl Photo {
    /// Decodes every pixel of `path`: PNG/JPEG are sRGB-encoded (8 or 16 bit), EXR is linear
    /// (its encoded form is the sRGB encoding of its values clamped to [0, 1]).
    pub fn load(path: &Path) -> Result<Photo, FitError> {
        let is_exr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        let img = image_io::read_rgb(path, false)?;
        let (encoded, linear) = if is_exr {
            let enc = img.data.iter().map(|c| c.map(image_io::linear_to_srgb)).collect();
            (enc, img.data)
        } else {
            let lin = img.data.iter().map(|c| c.map(image_io::srgb_to_linear)).collect();
            (img.data, lin)
        };
        if let Some(bad) = linear.iter().position(|c: &[f32; 3]| c.iter().any(|v| !v.is_finite())) {
            return Err(FitError::Input(format!(
                "{}: pixel ({}, {}) is not a finite number",
                path.display(),
                bad % img.width,
                bad / img.width
            )));
        }
        let clip = encoded.iter().map(|c: &[f32; 3]| c.iter().any(|&v| v >= CLIP_LEVEL)).collect();
        Ok(Photo { width: img.width, height: img.height, encoded, linear, clip })
    }

    /// A photo from its values (`width × height`, row-major) and clipping mask.
    pub fn from_parts(
        width: usize,
        height: usize,
        encoded: Vec<[f32; 3]>,
        linear: Vec<[f32; 3]>,
        clip: Vec<bool>,
    ) -> Photo {
        assert!(encoded.len() == width * height && linear.len() == width * height && clip.len() == width * height);
        Photo { width, height, encoded, linear, clip }
    }

    /// Whether pixel `i` is clipped: its true value is unknown. In a photo as loaded, any channel
    /// at or above 0.99 of full scale; at a working raster, any such pixel in its block.
    pub fn clipped(&self, i: usize) -> bool {
        self.clip[i]
    }
}

/// The coarse model seen through one camera, one ray per pixel centre.
#[derive(Clone, Debug)]
pub struct GeoBuffer {
    pub width: usize,
    pub height: usize,
    /// Model part hit (index into the scene's part names), or [`NO_PART`] (miss or emitter).
    pub part: Vec<u32>,
    /// Whether the pixel sees an emitter.
    pub emitter: Vec<bool>,
    /// Distance along the ray (0 for misses).
    pub depth: Vec<f32>,
}

impl GeoBuffer {
    pub fn trace(geometry: &SceneGeometry, camera: &Camera) -> GeoBuffer {
        let (w, h) = (camera.width, camera.height);
        let hits: Vec<(u32, bool, f32)> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let d = camera.direction((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
                match geometry.trace(camera.position, d, f32::INFINITY) {
                    Traced::Surface(hit) => (hit.part, false, hit.t),
                    Traced::Emitter { t, .. } => (NO_PART, true, t),
                    Traced::Miss => (NO_PART, false, 0.0),
                }
            })
            .collect();
        GeoBuffer {
            width: w,
            height: h,
            part: hits.iter().map(|x| x.0).collect(),
            emitter: hits.iter().map(|x| x.1).collect(),
            depth: hits.iter().map(|x| x.2).collect(),
        }
    }

    /// Whether pixel `i` lies on a depth edge: a 4-neighbour on another part, or whose depth
    /// differs by more than `rel` of this pixel's depth.
    pub fn on_edge(&self, i: usize, rel: f32) -> bool {
        let (x, y) = (i % self.width, i / self.width);
        let neighbours = [
            (x > 0).then(|| i - 1),
            (x + 1 < self.width).then(|| i + 1),
            (y > 0).then(|| i - self.width),
            (y + 1 < self.height).then(|| i + self.width),
        ];
        neighbours
            .into_iter()
            .flatten()
            .any(|j| self.part[j] != self.part[i] || (self.depth[j] - self.depth[i]).abs() > rel * self.depth[i])
    }
}

/// One input view: its photo, labels and the coarse model traced through its camera.
pub struct ViewObservation {
    pub name: String,
    pub camera: Camera,
    pub photo: Photo,
    /// Per photo pixel, the part its label names, or [`NO_PART`]; `None` without a label image.
    pub labels: Option<Vec<u32>>,
    pub geo: GeoBuffer,
    /// Where this observation's raster lies in the photo file (`camera`, `photo`, `labels` and
    /// `geo` are all at it).
    pub raster: WorkingRaster,
}

impl ViewObservation {
    /// `part_names` are the model's parts; labels naming other parts count as unlabelled (the
    /// scene loader has already warned about them). A photo of more than `max_pixels` pixels
    /// (0: no limit) is observed at a working raster (see [`crate::working`]).
    pub fn new(
        view: &View,
        part_names: &[String],
        geometry: &SceneGeometry,
        max_pixels: usize,
    ) -> Result<Self, FitError> {
        let photo = Photo::load(&view.image)?;
        if (photo.width, photo.height) != (view.width, view.height) {
            return Err(FitError::Input(format!(
                "{}: decoded size {}x{} differs from its header's {}x{}",
                view.image.display(),
                photo.width,
                photo.height,
                view.width,
                view.height
            )));
        }
        let labels = view.labels.as_ref().map(|l| {
            let lut: std::collections::BTreeMap<u16, u32> = view
                .part_labels
                .iter()
                .filter_map(|(&value, name)| part_names.iter().position(|p| p == name).map(|k| (value, k as u32)))
                .collect();
            l.data.iter().map(|v| lut.get(v).copied().unwrap_or(NO_PART)).collect::<Vec<u32>>()
        });
        let raster = WorkingRaster::for_photo(photo.width, photo.height, max_pixels);
        let camera = raster.camera(&view.camera);
        let labels = labels.map(|l| raster.labels(l, photo.width));
        let photo = raster.photo(photo);
        let geo = GeoBuffer::trace(geometry, &camera);
        Ok(ViewObservation { name: view.name.clone(), camera, photo, labels, geo, raster })
    }

    pub fn pixels(&self) -> usize {
        self.photo.width * self.photo.height
    }
}

/// The model surface behind one raster position, in the frame the shading layer works in.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub part: u32,
    /// Mesh uv (OBJ convention, before any uv transform).
    pub uv: [f32; 2],
    /// d uv / d raster x and d uv / d raster y (columns of the footprint Jacobian), per unit of
    /// the caller's raster step.
    pub duv_dx: [f32; 2],
    pub duv_dy: [f32; 2],
    pub position: Vec3,
    /// Unit shading normal on the camera's side.
    pub normal: Vec3,
    /// Unit tangent along dp/du, orthogonal to `normal`.
    pub tangent: Vec3,
    /// +1 when the mesh bitangent (sign of dp/dv) is `normal × tangent`, −1 when mirrored.
    pub bitangent_sign: f32,
    /// Direction to the camera in the local frame (x = tangent, y = normal × tangent, z = normal).
    pub wo_local: Vec3,
}

/// Traces the ray through continuous raster position `(x, y)` of `camera` and returns the model
/// surface it hits (None for misses and emitters). The footprint Jacobian is that of raster
/// steps `(step_x, 0)` and `(0, step_y)`, from ray differentials against the tangent plane.
pub fn surface_at(
    geometry: &SceneGeometry,
    camera: &Camera,
    x: f32,
    y: f32,
    step_x: f32,
    step_y: f32,
) -> Option<SurfacePoint> {
    let d = camera.direction(x, y);
    let Traced::Surface(hit) = geometry.trace(camera.position, d, f32::INFINITY) else { return None };
    let sf = geometry.shading_frame(&hit, -d, [0.0, 0.0, 1.0]);
    let n = sf.frame.n;
    let t = sf.tangent;
    let bitangent_sign = if sf.bitangent.dot(n.cross(t)) < 0.0 { -1.0 } else { 1.0 };
    let wo = -d;
    let wo_local = Vec3::new(wo.dot(t), wo.dot(n.cross(t)), wo.dot(n));
    // Ray differentials: where the neighbouring rays meet the tangent plane, expressed in uv.
    let plane_n = sf.ng;
    let offset_uv = |dir: Vec3| -> [f32; 2] {
        let denom = dir.dot(plane_n);
        if denom.abs() < 1e-8 {
            return [0.0, 0.0];
        }
        let t_hit = (hit.p - camera.position).dot(plane_n) / denom;
        let dp = camera.position + dir * t_hit - hit.p;
        solve_uv(hit.dpdu, hit.dpdv, dp)
    };
    let duv_dx = offset_uv(camera.direction(x + step_x, y));
    let duv_dy = offset_uv(camera.direction(x, y + step_y));
    Some(SurfacePoint {
        part: hit.part,
        uv: hit.uv,
        duv_dx,
        duv_dy,
        position: hit.p,
        normal: n,
        tangent: t,
        bitangent_sign,
        wo_local,
    })
}

/// Least-squares `(du, dv)` with `dpdu·du + dpdv·dv ≈ dp`.
fn solve_uv(dpdu: Vec3, dpdv: Vec3, dp: Vec3) -> [f32; 2] {
    let (a, b, c) = (dpdu.dot(dpdu), dpdu.dot(dpdv), dpdv.dot(dpdv));
    let det = a * c - b * b;
    if det.is_nan() || det.abs() <= 1e-20 {
        return [0.0, 0.0];
    }
    let (r0, r1) = (dpdu.dot(dp), dpdv.dot(dp));
    let du = (c * r0 - b * r1) / det;
    let dv = (a * r1 - b * r0) / det;
    if du.is_finite() && dv.is_finite() {
        [du, dv]
    } else {
        [0.0, 0.0]
    }
}
