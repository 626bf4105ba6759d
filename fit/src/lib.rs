//! `psc-fit`: fits a procedural material to every part of a room from its photos, and evaluates
//! fitted rooms against ground truth (`psc fit`, `psc eval`).
//!
//! Owns: the stages of the fit, one module each, with plain data passed between them (targets
//! from photos and G-buffers, the differentiable shading layer, losses, the optimiser, graph
//! selection, the per-part fit), and the evaluation against `truth/`.
//!
//! Must never: read `truth/` outside the evaluation module (the fit sees only what a user would
//! give it), define a second BRDF or parameter convention (it uses `psc_render::brdf` and
//! `psc_runtime`'s parameters), or draw progress itself (the CLI does, through callbacks).

#![forbid(unsafe_code)]

pub mod align;
pub mod contrast;
pub mod error;
pub mod eval;
pub mod features;
pub mod layer;
pub mod light_solve;
pub mod lighting;
pub mod loss;
pub mod observe;
pub mod optim;
pub mod output;
pub mod part;
pub mod part_fit;
pub mod pipeline;
pub mod refit;
pub mod render_noise;
pub mod result;
pub mod search;
pub mod select;
pub mod shading;
pub mod targets;
pub mod uvmap;
pub mod views;
pub mod working;

pub use error::FitError;
