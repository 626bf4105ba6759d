//! The photoscene compiler: from `.psg` source to checked graphs, the scalar IR, its symbolic
//! derivatives, and a reference interpreter.
//!
//! Owns: module loading and imports, name resolution, type checking and diagnostics; lowering
//! to the hash-consed IR; forward (d/du, d/dv) and reverse-mode differentiation; the
//! interpreter that is the oracle for the JIT. Must never: generate native code, touch images
//! or scenes, or panic on any input text (every problem with a source file is a
//! [`diag::Diagnostic`]).
//!
//! Pipeline: [`session::compile_files`] → [`module::ModuleSet`] (parse, imports) →
//! [`check::check_all`] → [`lower::lower_graph`] → [`compiled::CompiledGraph`] (forward
//! [`ir::Program`]) → [`compiled::CompiledGraph::adjoint`]. (`lower` is the AST → IR pass; the
//! pest → AST step before it is the grammar crate's `ast_build`.)

#![forbid(unsafe_code)]

pub mod builtins;
pub mod channel;
pub mod check;
pub mod compiled;
pub mod diag;
pub mod diff;
pub mod interp;
pub mod ir;
pub mod lower;
pub mod module;
pub mod session;
pub mod types;

pub use channel::Channel;
pub use compiled::{CompiledGraph, GraphInfo, ParamInfo, ParamKind};
pub use diff::reverse::{Adjoint, AdjointLayout};
pub use session::{compile_files, compile_text, find_sources, CompileOutput, Options};
