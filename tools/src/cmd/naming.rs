//! `penelope naming` (being written).

use std::process::ExitCode;

/// Options of `penelope naming`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `penelope naming`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let _ = args;
    Err(crate::cmd::usage("penelope naming: not built yet"))
}
