//! `penelope bench`: benchmarks a person can rerun and compare.

use std::process::ExitCode;

pub mod fpga;
pub mod jitter;
pub mod rpc;

/// Which benchmark to run.
#[derive(clap::Subcommand, Debug)]
pub enum BenchCommand {
    /// Control-loop wake-up latency beside cyclictest, idle or under load.
    Jitter(jitter::Args),
    /// FPGA kinematics model throughput beside the float model, and the modelled hardware latency.
    Fpga(fpga::Args),
    /// Remote-call round trip beside a raw TCP echo and ICMP ping, idle and under load.
    Rpc(rpc::Args),
}

/// Runs the chosen benchmark.
pub fn run(command: BenchCommand) -> anyhow::Result<ExitCode> {
    match command {
        BenchCommand::Jitter(args) => jitter::run(args),
        BenchCommand::Fpga(args) => fpga::run(args),
        BenchCommand::Rpc(args) => rpc::run(args),
    }
}
