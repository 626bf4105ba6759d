//! `psc-tests`: cross-crate integration tests (in `tests/`) and the helpers they share.

pub mod dev_scenes;
