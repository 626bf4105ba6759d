//! The part's UV transform φ: texture position `(s, t) = 1.5^k · R(θ) · (u, v) + offset` of the
//! mesh uv, as PhotoScene parametrises it (rotation, log-scale with base 1.5, translation). It
//! is the assignment file's `uv_scale` / `uv_rotation_deg` / `uv_offset` with one scale for
//! both axes, so a fitted transform is rendered exactly as it was fitted.

use serde::{Deserialize, Serialize};

pub const LOG_SCALE_BASE: f32 = 1.5;
/// PhotoScene's UV search range of the log-scale k.
pub const LOG_SCALE_RANGE: (f32, f32) = (-3.5, 4.25);

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct UvTransform {
    /// θ in radians.
    pub rotation: f32,
    /// k: the scale is 1.5^k.
    pub log_scale: f32,
    pub offset: [f32; 2],
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform { rotation: 0.0, log_scale: 0.0, offset: [0.0, 0.0] }
    }
}

impl UvTransform {
    pub fn scale(&self) -> f32 {
        LOG_SCALE_BASE.powf(self.log_scale)
    }

    /// `(s, t)` of the mesh uv.
    #[inline]
    pub fn apply(&self, uv: [f32; 2], scale: f32, (sin, cos): (f32, f32)) -> [f32; 2] {
        [scale * (cos * uv[0] - sin * uv[1]) + self.offset[0], scale * (sin * uv[0] + cos * uv[1]) + self.offset[1]]
    }

    /// Rows of the 2×3 matrix (the renderer's `MaterialBinding::uv_transform`).
    pub fn matrix(&self) -> [[f32; 3]; 2] {
        let (s, c) = self.rotation.sin_cos();
        let k = self.scale();
        [[k * c, -k * s, self.offset[0]], [k * s, k * c, self.offset[1]]]
    }

    /// Wraps the rotation into [−π, π) and the offset into [0, 1) (graphs tile with period 1)
    /// and clamps the log-scale to PhotoScene's range.
    pub fn canonical(mut self) -> Self {
        let tau = std::f32::consts::TAU;
        self.rotation = (self.rotation + std::f32::consts::PI).rem_euclid(tau) - std::f32::consts::PI;
        self.offset = self.offset.map(|o| o.rem_euclid(1.0));
        self.log_scale = self.log_scale.clamp(LOG_SCALE_RANGE.0, LOG_SCALE_RANGE.1);
        self
    }

    /// Accumulates the gradient of a loss with respect to (θ, k, offset x, offset y) from
    /// its gradient `d_st` with respect to the texture position of mesh uv `uv`.
    #[inline]
    pub fn backprop(uv: [f32; 2], scale: f32, (sin, cos): (f32, f32), d_st: [f32; 2], acc: &mut [f64; 4]) {
        // ∂(s,t)/∂θ = scale · R'(θ) uv, ∂(s,t)/∂k = ln 1.5 · scale · R(θ) uv.
        let r = [cos * uv[0] - sin * uv[1], sin * uv[0] + cos * uv[1]];
        let dr = [-sin * uv[0] - cos * uv[1], cos * uv[0] - sin * uv[1]];
        acc[0] += f64::from(scale * (d_st[0] * dr[0] + d_st[1] * dr[1]));
        acc[1] += f64::from(LOG_SCALE_BASE.ln() * scale * (d_st[0] * r[0] + d_st[1] * r[1]));
        acc[2] += f64::from(d_st[0]);
        acc[3] += f64::from(d_st[1]);
    }
}

/// A tangent-space normal of texture space rotated into mesh-uv tangent space: slopes follow
/// the pattern's rotation, not its scale (scaling a tile scales its heights with it).
#[inline]
pub fn normal_to_mesh(n: [f32; 3], (sin, cos): (f32, f32)) -> [f32; 3] {
    [cos * n[0] + sin * n[1], -sin * n[0] + cos * n[1], n[2]]
}
