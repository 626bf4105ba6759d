//! `psc library`.

use std::process::ExitCode;

use crate::Failure;

#[derive(clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> Result<ExitCode, Failure> {
    Err(Failure("`psc library` is not built yet".into()))
}
