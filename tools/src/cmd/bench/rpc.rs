//! `penelope bench rpc` (being written).

use std::process::ExitCode;

/// Options of `penelope bench rpc`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `penelope bench rpc`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let _ = args;
    Err(crate::cmd::usage("penelope bench rpc: not built yet"))
}
