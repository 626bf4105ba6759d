//! `psc-render`: scene folders, G-buffers, the Karis BRDF, per-pixel incoming-light grids and a
//! CPU path tracer.
//!
//! Owns: loading and validating scene folders (`photoscene-scene/1`, see
//! `shared/design/scene-format.md`), OBJ meshes with one material part per `usemtl`, pinhole
//! cameras, the BVH ([`bvh`]: 4-wide, collapsed from an obvhs binary BVH), the shading layer
//! ([`brdf`], the exact formulas the fit uses), the material interface ([`SurfaceMaterial`],
//! [`MaterialBinding`]), the path tracer with next-event estimation and MIS, G-buffers, light
//! grids, per-light renders, image I/O, the lights file ([`lights`]: a public type that reads
//! and writes, with validation) and JSON reading with errors that name the field ([`json`]).
//!
//! Must never: depend on the grammar/compiler/JIT/runtime crates (render is a leaf; the runtime
//! implements [`SurfaceMaterial`] for compiled graphs), read `truth/` on behalf of the fit (only
//! [`truth`] does, and only when asked for by name: `--materials truth`, `--geometry truth`,
//! `--lights truth`), panic on bad input
//! (every problem with a scene is a [`RenderError`] or a warning), or leave half-written files.

pub mod brdf;
pub mod bvh;
pub mod camera;
pub mod emitters;
mod error;
pub mod gbuffer;
pub mod geometry;
pub mod image_io;
pub mod integrator;
pub mod json;
pub mod lightgrid;
pub mod lights;
pub mod material;
pub mod mesh;
mod mtl;
pub mod rng;
pub mod scene;
pub mod truth;

pub use camera::{Camera, CameraSpec};
pub use error::RenderError;
pub use gbuffer::{render_gbuffer, GBuffer};
pub use integrator::{RenderOptions, RenderOutput, Renderer};
pub use lightgrid::{
    compute_light_grid, compute_light_grid_with_progress, LightGrid, LightGridOptions, GRID_PHI_BINS, GRID_THETA_BINS,
};
pub use lights::{LightRadiances, LightsFile, LightsSource};
pub use material::{ConstantMaterial, ImageMaterial, MaterialBinding, SurfaceMaterial, SurfaceSample, Texture};
pub use scene::{Scene, View};
