//! `penelope ctl` (being written).

use std::process::ExitCode;

/// Options of `penelope ctl`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `penelope ctl`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let _ = args;
    Err(crate::cmd::usage("penelope ctl: not built yet"))
}
