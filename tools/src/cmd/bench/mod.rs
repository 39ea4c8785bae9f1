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

/// The median of the finite values of `values` (NaN when there is none).
pub(crate) fn finite_median(values: impl IntoIterator<Item = f64>) -> f64 {
    let mut r: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
    if r.is_empty() {
        return f64::NAN;
    }
    r.sort_by(f64::total_cmp);
    let n = r.len();
    if n % 2 == 1 {
        r[n / 2]
    } else {
        (r[n / 2 - 1] + r[n / 2]) / 2.0
    }
}

/// `x` as JSON, or `null` when it is NaN or infinite (JSON has no such numbers).
pub(crate) fn finite_or_null(x: f64) -> serde_json::Value {
    if x.is_finite() {
        serde_json::json!(x)
    } else {
        serde_json::Value::Null
    }
}
