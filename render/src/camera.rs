//! Pinhole cameras: position, look-at point, up vector, vertical field of view; the resolution
//! is the image's. Pixel row 0 is the top of the image, column 0 the left; pixel (x, y) covers
//! `[x, x+1) × [y, y+1)` in continuous raster coordinates.

use std::path::Path;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::RenderError;

/// Largest camera coordinate accepted (scene units): beyond it f32 ray origins lose the precision
/// the tracer's offsets need (1e7 m already gives metre-sized steps).
pub const MAX_COORDINATE: f32 = 1e7;

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// A camera as written in scene.json (and in `--camera cam.json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    pub fov_y_deg: f32,
}

/// A validated camera at a given resolution.
#[derive(Clone, Debug)]
pub struct Camera {
    pub position: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit vector to the right of the image.
    pub right: Vec3,
    /// Unit vector to the top of the image.
    pub up: Vec3,
    pub width: usize,
    pub height: usize,
    tan_half_y: f32,
    tan_half_x: f32,
}

impl Camera {
    /// Validate `spec` (`context` names it in errors, e.g. "view view0").
    pub fn new(spec: &CameraSpec, width: usize, height: usize, context: &str) -> Result<Camera, RenderError> {
        let err = |m: &str| Err(RenderError::Camera { context: context.to_string(), message: m.to_string() });
        for (field, v) in [("position", spec.position), ("look_at", spec.look_at), ("up", spec.up)] {
            if let Some(c) = v.iter().find(|c| !c.is_finite() || c.abs() > MAX_COORDINATE) {
                return err(&format!(
                    "{field} {v:?} has {c:e}; expected finite coordinates within ±{MAX_COORDINATE:e} scene units (f32 \
                     rays cannot be placed precisely further out)"
                ));
            }
        }
        if !spec.fov_y_deg.is_finite() {
            return err(&format!("fov_y_deg must be a finite number of degrees, got {}", spec.fov_y_deg));
        }
        if width == 0 || height == 0 {
            return err("zero image size");
        }
        // Bytes a pixel of the smallest render needs (one light slot, the image, its encoding);
        // renders, G-buffers and grids check their own, larger needs.
        psc_base::limits::check_image(&format!("{context}: image"), width as u64, height as u64, 36)?;
        if !(spec.fov_y_deg > 0.0 && spec.fov_y_deg < 179.0) {
            return err(&format!("fov_y_deg must be in (0, 179), got {}", spec.fov_y_deg));
        }
        let position = Vec3::from(spec.position);
        let dir = Vec3::from(spec.look_at) - position;
        if dir.length() < 1e-6 {
            return err(&format!("position and look_at coincide ({:?})", spec.position));
        }
        let forward = dir.normalize();
        let up_hint = Vec3::from(spec.up);
        if up_hint.length() < 1e-6 {
            return err(&format!("zero up vector {:?}", spec.up));
        }
        let right = forward.cross(up_hint.normalize());
        if right.length() < 1e-4 {
            return err(&format!(
                "up vector {:?} is parallel to the viewing direction {:?} (from position to look_at)",
                spec.up,
                forward.to_array()
            ));
        }
        let right = right.normalize();
        let up = right.cross(forward);
        let tan_half_y = (spec.fov_y_deg.to_radians() * 0.5).tan();
        let tan_half_x = tan_half_y * width as f32 / height as f32;
        Ok(Camera { position, forward, right, up, width, height, tan_half_y, tan_half_x })
    }

    /// Unit direction of the ray through continuous raster position (x, y).
    #[inline]
    pub fn direction(&self, x: f32, y: f32) -> Vec3 {
        let sx = (2.0 * x / self.width as f32 - 1.0) * self.tan_half_x;
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.tan_half_y;
        (self.forward + self.right * sx + self.up * sy).normalize()
    }

    /// Raster position of a world point, or None if it is behind the camera.
    pub fn project(&self, p: Vec3) -> Option<[f32; 2]> {
        let d = p - self.position;
        let z = d.dot(self.forward);
        if z <= 1e-6 {
            return None;
        }
        let sx = d.dot(self.right) / z / self.tan_half_x;
        let sy = d.dot(self.up) / z / self.tan_half_y;
        Some([(sx + 1.0) * 0.5 * self.width as f32, (1.0 - sy) * 0.5 * self.height as f32])
    }
}

/// A camera file for `psc render --camera`: either a [`CameraSpec`] or `{"camera": {...}}`,
/// optionally with `"width"` and `"height"`.
#[derive(Clone, Debug)]
pub struct CameraFile {
    pub camera: CameraSpec,
    pub size: Option<(usize, usize)>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFileRepr {
    camera: Option<CameraSpec>,
    position: Option<[f32; 3]>,
    look_at: Option<[f32; 3]>,
    up: Option<[f32; 3]>,
    fov_y_deg: Option<f32>,
    width: Option<usize>,
    height: Option<usize>,
}

pub fn load_camera_file(path: &Path) -> Result<CameraFile, RenderError> {
    let r: CameraFileRepr = crate::json::read(path, "camera file")?;
    let size = match (r.width, r.height) {
        (Some(w), Some(h)) => Some((w, h)),
        _ => None,
    };
    let camera = match (r.camera, r.position, r.look_at, r.fov_y_deg) {
        (Some(c), None, None, None) => c,
        (None, Some(position), Some(look_at), Some(fov_y_deg)) => {
            CameraSpec { position, look_at, up: r.up.unwrap_or_else(default_up), fov_y_deg }
        }
        _ => {
            return Err(RenderError::Invalid(format!(
                "{}: expected either {{\"camera\": {{...}}}} or position, look_at, fov_y_deg (and optional up)",
                path.display()
            )))
        }
    };
    Ok(CameraFile { camera, size })
}
