//! `psc-tests`: cross-crate integration tests (in `tests/`) and the helpers they share.

#![forbid(unsafe_code)]

pub mod dev_scenes;
pub mod folders;
pub mod not_run;
