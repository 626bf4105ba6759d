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
    /// Where this camera's raster lies in the raster its field of view was given for (see
    /// [`Camera::window`]); the identity for a camera made by [`Camera::new`].
    raster: RasterWindow,
}

/// Pixel `(i, j)` of a windowed camera covers pixels `[x0 + i·step, x0 + (i+1)·step) ×
/// [y0 + j·step, …)` of the full raster, which is `full_width × full_height`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct RasterWindow {
    origin: [f32; 2],
    step: f32,
    full_width: f32,
    full_height: f32,
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
        let raster = RasterWindow { origin: [0.0; 2], step: 1.0, full_width: width as f32, full_height: height as f32 };
        Ok(Camera { position, forward, right, up, width, height, tan_half_y, tan_half_x, raster })
    }

    /// The same camera seen through a coarser raster: `width × height` pixels of `step × step`
    /// pixels of this one each, the first at pixel `origin` (a box-downsampled image of this
    /// camera's, cropped to whole blocks). The rays through block centres are exactly this
    /// camera's rays through those points.
    pub fn window(&self, origin: [usize; 2], step: usize, width: usize, height: usize) -> Camera {
        let r = self.raster;
        let raster = RasterWindow {
            origin: [r.origin[0] + origin[0] as f32 * r.step, r.origin[1] + origin[1] as f32 * r.step],
            step: r.step * step as f32,
            ..r
        };
        Camera { width, height, raster, ..self.clone() }
    }

    /// Unit direction of the ray through continuous raster position (x, y).
    #[inline]
    pub fn direction(&self, x: f32, y: f32) -> Vec3 {
        let r = &self.raster;
        // Exactly `x` and `y` for an unwindowed camera (0 + x·1).
        let (x, y) = (r.origin[0] + x * r.step, r.origin[1] + y * r.step);
        let sx = (2.0 * x / r.full_width - 1.0) * self.tan_half_x;
        let sy = (1.0 - 2.0 * y / r.full_height) * self.tan_half_y;
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
        let r = &self.raster;
        let full = [(sx + 1.0) * 0.5 * r.full_width, (1.0 - sy) * 0.5 * r.full_height];
        Some([(full[0] - r.origin[0]) / r.step, (full[1] - r.origin[1]) / r.step])
    }
}

/// A camera file for `psc render --camera`: either a [`CameraSpec`] or `{"camera": {...}}`,
/// optionally with `"width"` and `"height"` (both or neither).
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
        (None, None) => None,
        (given, _) => {
            let (has, lacks) = if given.is_some() { ("width", "height") } else { ("height", "width") };
            return Err(RenderError::Invalid(format!(
                "{}: \"{has}\" is given without \"{lacks}\"; give both (the image size in pixels) or neither",
                path.display()
            )));
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(width: usize, height: usize) -> Camera {
        let spec =
            CameraSpec { position: [0.3, 1.2, 2.0], look_at: [0.1, 0.9, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 55.0 };
        Camera::new(&spec, width, height, "test").unwrap()
    }

    #[test]
    fn a_window_shoots_the_rays_of_the_blocks_it_stands_for() {
        let full = camera(643, 481);
        // 3×3 blocks, the remainder (643 − 3·213 = 4, 481 − 3·160 = 1) split around them.
        let coarse = full.window([2, 0], 3, 213, 160);
        for (i, j) in [(0usize, 0usize), (212, 159), (100, 7), (5, 120)] {
            let centre = full.direction(2.0 + 3.0 * i as f32 + 1.5, 3.0 * j as f32 + 1.5);
            let d = coarse.direction(i as f32 + 0.5, j as f32 + 0.5);
            assert!((d - centre).length() < 1e-6, "block ({i}, {j}): {d} against {centre}");
            // Projection inverts it, in the coarse raster.
            let p = coarse.project(coarse.position + d * 3.0).unwrap();
            assert!((p[0] - (i as f32 + 0.5)).abs() < 1e-3 && (p[1] - (j as f32 + 0.5)).abs() < 1e-3, "{p:?}");
        }
        // A window of a window composes.
        let twice = full.window([1, 1], 2, 300, 200).window([3, 2], 2, 70, 40);
        let d = twice.direction(0.25, 0.75);
        let e = full.direction(1.0 + 2.0 * (3.0 + 2.0 * 0.25), 1.0 + 2.0 * (2.0 + 2.0 * 0.75));
        assert!((d - e).length() < 1e-6, "{d} against {e}");
    }

    #[test]
    fn an_unwindowed_camera_maps_rasters_as_before() {
        let c = camera(320, 240);
        let d = c.direction(17.5, 200.25);
        let sx = (2.0 * 17.5 / 320.0 - 1.0) * c.tan_half_x;
        let sy = (1.0 - 2.0 * 200.25 / 240.0) * c.tan_half_y;
        assert_eq!(d, (c.forward + c.right * sx + c.up * sy).normalize());
    }
}
