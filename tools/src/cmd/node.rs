//! `penelope node` (being written).

use std::process::ExitCode;

/// Options of `penelope node`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `penelope node`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let _ = args;
    Err(crate::cmd::usage("penelope node: not built yet"))
}
