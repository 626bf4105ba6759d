//! The photoscene runtime: compiled graphs as callable kernels over batches of points, the
//! material library, baking, and the binding of materials to the renderer.
//!
//! Owns: parallel evaluation (rayon) with deterministic reductions, the library of compiled
//! graphs, image output of baked maps. Must never: parse or type-check source (that is the
//! compiler's), or generate code (that is the JIT's).

pub mod assign;
pub mod bake;
pub mod json;
pub mod kernel;
pub mod library;
pub mod material;
pub mod params;
pub mod sheet;
