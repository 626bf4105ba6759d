//! The photoscene runtime: compiled graphs as callable kernels over batches of points, the
//! material library, baking, and the binding of materials to the renderer.
//!
//! Owns: parallel evaluation (rayon) with deterministic reductions, the library of compiled
//! graphs, parameter vectors, image output of baked maps, material assignment files and their
//! `--set` edits, fit output folders opened for rendering, and the setup the commands share
//! (opening a scene for a view, finding a graph the user named), so that the CLI only parses
//! arguments and prints. Must never: parse or type-check source (that is the compiler's),
//! generate code (that is the JIT's), or read a scene's ground truth unless a caller's choice
//! names it.

#![forbid(unsafe_code)]

pub mod assign;
pub mod bake;
pub mod edit;
pub mod fitted;
pub mod json;
pub mod kernel;
pub mod library;
pub mod lookup;
pub mod material;
pub mod params;
pub mod sheet;
pub mod view;
