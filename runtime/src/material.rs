//! Compiled procedural graphs as the renderer's [`SurfaceMaterial`]s.

use std::sync::Arc;

use psc_compiler::CHANNELS;
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

/// Channel columns of the forward program (see `psc_compiler::CHANNELS`) to a sample.
fn sample_at(channels: &[Vec<f32>], k: usize) -> SurfaceSample {
    SurfaceSample {
        albedo: [channels[0][k], channels[1][k], channels[2][k]],
        roughness: channels[3][k],
        normal: [channels[4][k], channels[5][k], channels[6][k]],
    }
}

impl SurfaceMaterial for ProceduralMaterial {
    /// One hit: the JIT kernel's single-point entry (stack buffers only, no thread pool),
    /// since the path tracer shades one hit at a time.
    fn eval(&self, uv: [f32; 2]) -> SurfaceSample {
        let mut c = [0.0f32; CHANNELS.len()];
        match self.material.kernel.forward_jit().run_point(&self.params, uv[0], uv[1], &mut c) {
            Ok(()) => SurfaceSample { albedo: [c[0], c[1], c[2]], roughness: c[3], normal: [c[4], c[5], c[6]] },
            Err(_) => SHAPE_ERROR_SAMPLE,
        }
    }

    fn eval_batch(&self, uvs: &[[f32; 2]], out: &mut [SurfaceSample]) {
        let u: Vec<f32> = uvs.iter().map(|p| p[0]).collect();
        let v: Vec<f32> = uvs.iter().map(|p| p[1]).collect();
        match self.material.kernel.eval(&self.params, &u, &v) {
            Ok(channels) => {
                for (k, o) in out.iter_mut().enumerate() {
                    *o = sample_at(&channels, k);
                }
            }
            Err(_) => out.fill(SHAPE_ERROR_SAMPLE),
        }
    }
}

/// Parameters are validated at construction, so a kernel shape error is a bug: shade it a loud
/// magenta rather than abort a long render.
const SHAPE_ERROR_SAMPLE: SurfaceSample =
    SurfaceSample { albedo: [1.0, 0.0, 1.0], roughness: 1.0, normal: [0.0, 0.0, 1.0] };
