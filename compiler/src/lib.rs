//! The photoscene compiler: from a parsed `.psg` file to checked graphs, the scalar IR, its
//! symbolic derivatives, and a reference interpreter.
//!
//! Owns: name resolution, type checking and diagnostics; lowering to the hash-consed IR;
//! forward (d/du, d/dv) and reverse-mode differentiation; the interpreter that is the oracle
//! for the JIT. Must never: generate native code, touch images or scenes, or panic on any
//! input text (every problem with a source file is a [`diag::Diagnostic`]).

pub mod ir;
pub mod interp;
pub mod diff;
