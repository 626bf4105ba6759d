//! The material interface the renderer shades with, and its two built-in implementations.
//!
//! A material maps a texture coordinate to a [`SurfaceSample`] (linear albedo, roughness,
//! tangent-space normal). The runtime implements [`SurfaceMaterial`] for compiled procedural
//! graphs; render only knows the trait. A [`MaterialBinding`] attaches a material to one part
//! with a uv transform and albedo/roughness scales.
//!
//! uv convention (OBJ): u to the right, v up; for images, v = 0 is the bottom row and v = 1 the
//! top row. Wrap: repeat. Filter: bilinear with texel centres at (i + ½)/size.

use std::path::Path;
use std::sync::Arc;

use crate::image_io;
use crate::RenderError;

/// What a material says about one surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceSample {
    /// Linear RGB albedo (diffuse reflectance), normally in [0, 1].
    pub albedo: [f32; 3],
    /// Perceptual roughness r (α = r²), in [0, 1].
    pub roughness: f32,
    /// Tangent-space normal (x along dp/du, y along dp/dv, z along the surface normal); need not
    /// be normalised. `[0, 0, 1]` means no perturbation.
    pub normal: [f32; 3],
}

impl Default for SurfaceSample {
    fn default() -> Self {
        SurfaceSample { albedo: [0.5; 3], roughness: 0.5, normal: [0.0, 0.0, 1.0] }
    }
}

/// A material evaluated at texture coordinates. Implementations must be deterministic.
pub trait SurfaceMaterial: Send + Sync {
    fn eval(&self, uv: [f32; 2]) -> SurfaceSample;

    /// Evaluate many points at once (`out.len() == uvs.len()`); override for SIMD/JIT batches.
    fn eval_batch(&self, uvs: &[[f32; 2]], out: &mut [SurfaceSample]) {
        for (uv, o) in uvs.iter().zip(out.iter_mut()) {
            *o = self.eval(*uv);
        }
    }

    /// A hint that [`SurfaceMaterial::eval`] at `uv` follows soon: start loading what it reads
    /// (texels) so the path tracer can trace a shadow ray meanwhile. No effect on results.
    fn prefetch(&self, _uv: [f32; 2]) {}
}

/// The same sample everywhere.
#[derive(Clone, Debug)]
pub struct ConstantMaterial {
    pub albedo: [f32; 3],
    pub roughness: f32,
}

impl SurfaceMaterial for ConstantMaterial {
    fn eval(&self, _uv: [f32; 2]) -> SurfaceSample {
        SurfaceSample { albedo: self.albedo, roughness: self.roughness, normal: [0.0, 0.0, 1.0] }
    }
}

/// Texel storage: 8-bit sRGB (decoded through a table at lookup; 4 bytes a texel keeps large
/// textures cache-friendly) or linear floats.
#[derive(Clone, Debug)]
enum Texels {
    Srgb8(Vec<[u8; 4]>),
    Linear(Vec<[f32; 3]>),
}

/// sRGB byte → linear, the same values as `srgb_to_linear(i / 255)`.
fn srgb_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| crate::image_io::srgb_to_linear(i as f32 / 255.0)))
}

/// An RGB image sampled bilinearly with repeat wrapping, OBJ v-up convention; values linear.
#[derive(Clone, Debug)]
pub struct Texture {
    pub width: usize,
    pub height: usize,
    texels: Texels,
}

impl Texture {
    /// From linear texels, row-major, row 0 = top of the image.
    pub fn new(width: usize, height: usize, data: Vec<[f32; 3]>) -> Result<Self, RenderError> {
        if width == 0 || height == 0 || data.len() != width * height {
            return Err(RenderError::Invalid(format!(
                "texture of {width}x{height} needs {} texels, got {}",
                width * height,
                data.len()
            )));
        }
        Ok(Texture { width, height, texels: Texels::Linear(data) })
    }

    /// From 8-bit sRGB texels (4th byte unused), row-major, row 0 = top of the image.
    pub fn from_srgb8(width: usize, height: usize, data: Vec<[u8; 4]>) -> Result<Self, RenderError> {
        if width == 0 || height == 0 || data.len() != width * height {
            return Err(RenderError::Invalid(format!(
                "texture of {width}x{height} needs {} texels, got {}",
                width * height,
                data.len()
            )));
        }
        Ok(Texture { width, height, texels: Texels::Srgb8(data) })
    }

    /// Load an 8/16-bit PNG/JPEG (decoded from sRGB when `srgb`, else taken as linear /max) or a
    /// linear EXR. 8-bit sRGB images stay 8-bit in memory.
    pub fn load(path: &Path, srgb: bool) -> Result<Self, RenderError> {
        let is_exr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        if srgb && !is_exr && path.is_file() {
            image_io::dimensions(path)?;
            let img = image::open(path).map_err(|e| RenderError::image(path, e))?;
            if matches!(
                img.color(),
                image::ColorType::Rgb8 | image::ColorType::Rgba8 | image::ColorType::L8 | image::ColorType::La8
            ) {
                let rgb = img.to_rgb8();
                let (w, h) = (rgb.width() as usize, rgb.height() as usize);
                let data = rgb.pixels().map(|p| [p[0], p[1], p[2], 0]).collect();
                return Texture::from_srgb8(w, h, data);
            }
        }
        let img = image_io::read_rgb(path, srgb)?;
        Texture::new(img.width, img.height, img.data)
    }

    /// Linear value of texel (x, y), row 0 = top.
    #[inline]
    pub fn texel(&self, x: usize, y: usize) -> [f32; 3] {
        let i = y * self.width + x;
        match &self.texels {
            Texels::Linear(d) => d[i],
            Texels::Srgb8(d) => {
                let t = srgb_table();
                let p = d[i];
                [t[p[0] as usize], t[p[1] as usize], t[p[2] as usize]]
            }
        }
    }

    /// The four texels of a bilinear lookup (x0, x1, y0, y1) and the weights (fx, fy); `None`
    /// for a non-finite uv.
    #[inline]
    fn footprint(&self, uv: [f32; 2]) -> Option<([usize; 4], f32, f32)> {
        let (w, h) = (self.width as f32, self.height as f32);
        let u = uv[0] - floor(uv[0]);
        let v = uv[1] - floor(uv[1]);
        // x in [-0.5, w - 0.5), y in [-0.5, h - 0.5]
        let x = u * w - 0.5;
        let y = (1.0 - v) * h - 0.5;
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        let (x0f, y0f) = ((x + 1.0) as i32 - 1, (y + 1.0) as i32 - 1); // floor for x >= -1
        let (fx, fy) = (x - x0f as f32, y - y0f as f32);
        let wrap = |i: i32, n: usize| -> usize {
            if i < 0 {
                n - 1
            } else if i as usize >= n {
                i as usize - n
            } else {
                i as usize
            }
        };
        let (x0, x1) = (wrap(x0f, self.width), wrap(x0f + 1, self.width));
        let (y0, y1) = (wrap(y0f, self.height), wrap(y0f + 1, self.height));
        Some(([x0, x1, y0, y1], fx, fy))
    }

    /// Bilinear lookup at OBJ-convention (u, v), repeat wrap.
    #[inline]
    pub fn sample(&self, uv: [f32; 2]) -> [f32; 3] {
        let Some(([x0, x1, y0, y1], fx, fy)) = self.footprint(uv) else { return self.texel(0, 0) };
        let (a, b, c, d) = (self.texel(x0, y0), self.texel(x1, y0), self.texel(x0, y1), self.texel(x1, y1));
        let mut out = [0.0; 3];
        for k in 0..3 {
            let top = a[k] + (b[k] - a[k]) * fx;
            let bot = c[k] + (d[k] - c[k]) * fx;
            out[k] = top + (bot - top) * fy;
        }
        out
    }

    /// Start loading the texels [`Texture::sample`] at `uv` reads (a cache hint only).
    #[inline]
    pub fn prefetch(&self, uv: [f32; 2]) {
        let Some(([x0, _, y0, y1], _, _)) = self.footprint(uv) else { return };
        // x0 and x1 share a cache line but for one texel in 16 (8-bit) or 5 (float).
        for (x, y) in [(x0, y0), (x0, y1)] {
            let i = y * self.width + x;
            match &self.texels {
                Texels::Linear(d) => prefetch(&d[i]),
                Texels::Srgb8(d) => prefetch(&d[i]),
            }
        }
    }
}

/// `x.floor()` without a libm call on x86-64's baseline (no SSE4.1 `roundss`); the same value.
#[inline(always)]
fn floor(x: f32) -> f32 {
    if x.abs() < 8_388_608.0 {
        let t = x as i32 as f32; // truncation, exact below 2^23
        if t > x {
            t - 1.0
        } else {
            t
        }
    } else {
        x.floor()
    }
}

#[inline(always)]
fn prefetch<T>(p: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults and has no effect on memory contents.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p as *const T as *const i8)
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Roughness of an [`ImageMaterial`]: a constant or the first channel of a texture.
#[derive(Clone, Debug)]
pub enum RoughnessSource {
    Constant(f32),
    Texture(Texture),
}

/// Albedo from an image texture, roughness constant or from a texture, optional tangent-space
/// normal map (RGB in `[0, 1]` encoding `[-1, 1]`, linear).
#[derive(Clone, Debug)]
pub struct ImageMaterial {
    pub albedo: Texture,
    pub roughness: RoughnessSource,
    pub normal_map: Option<Texture>,
}

impl ImageMaterial {
    pub fn new(albedo: Texture, roughness: f32) -> Self {
        ImageMaterial { albedo, roughness: RoughnessSource::Constant(roughness), normal_map: None }
    }
    pub fn with_normal_map(mut self, map: Texture) -> Self {
        self.normal_map = Some(map);
        self
    }
}

impl SurfaceMaterial for ImageMaterial {
    fn eval(&self, uv: [f32; 2]) -> SurfaceSample {
        let roughness = match &self.roughness {
            RoughnessSource::Constant(r) => *r,
            RoughnessSource::Texture(t) => t.sample(uv)[0],
        };
        let normal = match &self.normal_map {
            Some(t) => {
                let n = t.sample(uv);
                [2.0 * n[0] - 1.0, 2.0 * n[1] - 1.0, 2.0 * n[2] - 1.0]
            }
            None => [0.0, 0.0, 1.0],
        };
        SurfaceSample { albedo: self.albedo.sample(uv), roughness, normal }
    }

    fn prefetch(&self, uv: [f32; 2]) {
        self.albedo.prefetch(uv);
        if let RoughnessSource::Texture(t) = &self.roughness {
            t.prefetch(uv);
        }
        if let Some(t) = &self.normal_map {
            t.prefetch(uv);
        }
    }
}

/// A material attached to one part.
#[derive(Clone)]
pub struct MaterialBinding {
    pub material: Arc<dyn SurfaceMaterial>,
    /// `(s, t) = M · (u, v, 1)`, rows of M.
    pub uv_transform: [[f32; 3]; 2],
    /// Multiplies the material's albedo (per channel).
    pub albedo_scale: [f32; 3],
    /// Multiplies the material's roughness.
    pub roughness_scale: f32,
}

impl std::fmt::Debug for MaterialBinding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MaterialBinding")
            .field("uv_transform", &self.uv_transform)
            .field("albedo_scale", &self.albedo_scale)
            .field("roughness_scale", &self.roughness_scale)
            .finish_non_exhaustive()
    }
}

pub const IDENTITY_UV: [[f32; 3]; 2] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

impl MaterialBinding {
    pub fn new(material: Arc<dyn SurfaceMaterial>) -> Self {
        MaterialBinding { material, uv_transform: IDENTITY_UV, albedo_scale: [1.0; 3], roughness_scale: 1.0 }
    }
    pub fn constant(albedo: [f32; 3], roughness: f32) -> Self {
        Self::new(Arc::new(ConstantMaterial { albedo, roughness }))
    }
    pub fn with_uv_transform(mut self, m: [[f32; 3]; 2]) -> Self {
        self.uv_transform = m;
        self
    }

    #[inline]
    pub fn transform_uv(&self, uv: [f32; 2]) -> [f32; 2] {
        let m = &self.uv_transform;
        [m[0][0] * uv[0] + m[0][1] * uv[1] + m[0][2], m[1][0] * uv[0] + m[1][1] * uv[1] + m[1][2]]
    }

    /// See [`SurfaceMaterial::prefetch`] (at the mesh uv).
    #[inline]
    pub fn prefetch(&self, uv: [f32; 2]) {
        self.material.prefetch(self.transform_uv(uv));
    }

    /// The rotation part of the uv transform as (cos θ, sin θ): the rotation closest to its
    /// 2×2 linear part (exact for a rotation with any uniform or per-axis scale).
    #[inline]
    pub fn uv_rotation(&self) -> (f32, f32) {
        let m = &self.uv_transform;
        let (x, y) = (m[0][0] + m[1][1], m[1][0] - m[0][1]);
        let h = (x * x + y * y).sqrt();
        if h > 0.0 && h.is_finite() {
            (x / h, y / h)
        } else {
            (1.0, 0.0)
        }
    }

    /// Evaluate at the mesh uv: transform, evaluate, scale, clamp to the valid range. The
    /// material's tangent-space normal is rotated from texture space back into mesh-uv space
    /// (slopes follow the pattern's rotation, not its scale), the way the fit's shading layer
    /// does.
    pub fn eval(&self, uv: [f32; 2]) -> SurfaceSample {
        self.finish(self.material.eval(self.transform_uv(uv)))
    }

    /// [`MaterialBinding::eval`] at several mesh uvs at once (`out.len() == uvs.len()`), through
    /// [`SurfaceMaterial::eval_batch`]: the hits of a path-tracing packet on this part. The same
    /// values as one `eval` per point.
    pub fn eval_batch(&self, uvs: &[[f32; 2]], out: &mut [SurfaceSample]) {
        const CHUNK: usize = 16;
        for (uvs, out) in uvs.chunks(CHUNK).zip(out.chunks_mut(CHUNK)) {
            let mut at = [[0.0f32; 2]; CHUNK];
            for (a, &uv) in at.iter_mut().zip(uvs) {
                *a = self.transform_uv(uv);
            }
            self.material.eval_batch(&at[..uvs.len()], out);
            for s in out.iter_mut() {
                *s = self.finish(*s);
            }
        }
    }

    /// A material's sample at transformed uv to the part's: normal back into mesh-uv space,
    /// scales applied, values clamped.
    #[inline]
    fn finish(&self, mut s: SurfaceSample) -> SurfaceSample {
        let (cos, sin) = self.uv_rotation();
        if sin != 0.0 || cos != 1.0 {
            let [nx, ny, nz] = s.normal;
            s.normal = [cos * nx + sin * ny, -sin * nx + cos * ny, nz];
        }
        for k in 0..3 {
            let a = s.albedo[k] * self.albedo_scale[k];
            s.albedo[k] = if a.is_finite() { a.max(0.0) } else { 0.0 };
        }
        let r = s.roughness * self.roughness_scale;
        s.roughness = if r.is_finite() { r.clamp(0.0, 1.0) } else { 1.0 };
        s
    }
}
