//! Compiled procedural graphs as the renderer's [`SurfaceMaterial`]s.

use std::sync::Arc;

use psc_compiler::Channel;
use psc_jit::CompiledKernel;
use psc_render::material::{SurfaceMaterial, SurfaceSample};

use crate::library::Material;

/// A library material at one parameter vector, evaluated by its JIT kernel at the hit's uv.
pub struct ProceduralMaterial {
    material: Arc<Material>,
    params: Vec<f32>,
}

impl ProceduralMaterial {
    /// `params` must have one value per parameter slot of the graph.
    pub fn new(material: Arc<Material>, params: Vec<f32>) -> Result<Self, String> {
        let want = material.graph.info.num_slots();
        if params.len() != want {
            return Err(format!("graph `{}` takes {want} parameter values, got {}", material.name(), params.len()));
        }
        Ok(ProceduralMaterial { material, params })
    }

    pub fn at_defaults(material: Arc<Material>) -> Self {
        let params = material.graph.info.default_params();
        ProceduralMaterial { material, params }
    }
}

/// The forward program's channels at point `k` (`at(c)`: channel `c` there) to a sample.
fn sample_from(at: impl Fn(Channel) -> f32) -> SurfaceSample {
    SurfaceSample {
        albedo: Channel::ALBEDO.map(&at),
        roughness: at(Channel::Roughness),
        normal: Channel::NORMAL.map(&at),
    }
}

impl SurfaceMaterial for ProceduralMaterial {
    /// One hit: the JIT kernel's single-point entry (stack buffers only, no thread pool),
    /// since the path tracer shades one hit at a time.
    fn eval(&self, uv: [f32; 2]) -> SurfaceSample {
        let mut c = [0.0f32; Channel::COUNT];
        match self.material.kernel.forward_jit().run_point(&self.params, uv[0], uv[1], &mut c) {
            Ok(()) => sample_from(|ch| c[ch.index()]),
            Err(_) => SHAPE_ERROR_SAMPLE,
        }
    }

    /// The hits of a path-tracing packet that share this material: up to
    /// [`CompiledKernel::MAX_POINTS`] at a time through the stack-only packet entry, one SIMD
    /// lane each, so the values are those of [`SurfaceMaterial::eval`] bit for bit.
    fn eval_batch(&self, uvs: &[[f32; 2]], out: &mut [SurfaceSample]) {
        const N: usize = CompiledKernel::MAX_POINTS;
        let kernel = self.material.kernel.forward_jit();
        for (uvs, out) in uvs.chunks(N).zip(out.chunks_mut(N)) {
            let n = uvs.len();
            let (mut u, mut v) = ([0.0f32; N], [0.0f32; N]);
            for (k, p) in uvs.iter().enumerate() {
                (u[k], v[k]) = (p[0], p[1]);
            }
            let mut c = [0.0f32; N * Channel::COUNT];
            match kernel.run_points(&self.params, &u[..n], &v[..n], &mut c[..n * Channel::COUNT]) {
                Ok(()) => {
                    for (k, o) in out.iter_mut().enumerate() {
                        *o = sample_from(|ch| c[k * Channel::COUNT + ch.index()]);
                    }
                }
                Err(_) => out.fill(SHAPE_ERROR_SAMPLE),
            }
        }
    }
}

/// Parameters are validated at construction, so a kernel shape error is a bug: shade it a loud
/// magenta rather than abort a long render.
const SHAPE_ERROR_SAMPLE: SurfaceSample =
    SurfaceSample { albedo: [1.0, 0.0, 1.0], roughness: 1.0, normal: [0.0, 0.0, 1.0] };
