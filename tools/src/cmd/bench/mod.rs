//! `penelope bench`: benchmarks a person can rerun and compare.

use std::process::ExitCode;

pub mod fpga;
pub mod jitter;
pub mod layout;
pub mod netft;
pub mod record;
pub mod record_flood;
pub mod rpc;
#[cfg(feature = "zenoh")]
pub mod zenoh;

/// Which benchmark to run.
#[derive(clap::Subcommand, Debug)]
pub enum BenchCommand {
    /// Control-loop wake-up latency beside cyclictest, idle or under load.
    Jitter(jitter::Args),
    /// FPGA kinematics model throughput beside the float model, and the modelled hardware latency.
    Fpga(fpga::Args),
    /// Remote-call round trip beside a raw TCP echo and ICMP ping, idle and under load.
    Rpc(rpc::Args),
    /// The task in the one-, two- and four-host layouts (network namespaces; needs root):
    /// tracking, force, end-to-end latency beside a raw UDP echo, loop timing.
    Layout(layout::Args),
    /// Net F/T driver against its emulator on loopback: records received beside sent, loss,
    /// and the sample-to-driver latency, at each rate.
    Netft(netft::Args),
    /// Recording throughput: ticks and megabytes per second a node records with no drop,
    /// beside the rate its loops produce.
    Record(record::Args),
    /// The Zenoh bridge's one-way latency beside the data plane's, on loopback (a build with
    /// `--features zenoh`).
    #[cfg(feature = "zenoh")]
    Zenoh(zenoh::Args),
}

/// Runs the chosen benchmark.
pub fn run(command: BenchCommand) -> anyhow::Result<ExitCode> {
    match command {
        BenchCommand::Jitter(args) => jitter::run(args),
        BenchCommand::Fpga(args) => fpga::run(args),
        BenchCommand::Rpc(args) => rpc::run(args),
        BenchCommand::Layout(args) => layout::run(args),
        BenchCommand::Netft(args) => netft::run(args),
        BenchCommand::Record(args) => record::run(args),
        #[cfg(feature = "zenoh")]
        BenchCommand::Zenoh(args) => zenoh::run(args),
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

/// A running `stress-ng`, stopped (with its workers) when dropped.
pub(crate) struct StressNg {
    child: std::process::Child,
}

impl StressNg {
    /// Starts `stress-ng ARGS --quiet`, waits `settle` for its workers to spin up, and fails if it
    /// already exited (a bad option, a missing binary).
    pub(crate) fn start(args: &[&str], settle: std::time::Duration) -> anyhow::Result<StressNg> {
        use anyhow::Context;
        use std::process::{Command, Stdio};
        let mut child = Command::new("stress-ng")
            .args(args)
            .arg("--quiet")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .context("starting stress-ng")?;
        std::thread::sleep(settle);
        if let Some(status) = child.try_wait()? {
            anyhow::bail!("stress-ng {} exited at once ({status})", args.join(" "));
        }
        Ok(StressNg { child })
    }

    /// The child's process id.
    pub(crate) fn id(&self) -> u32 {
        self.child.id()
    }
}

impl Drop for StressNg {
    fn drop(&mut self) {
        // stress-ng forwards SIGTERM to its workers; a plain kill() would leave them running.
        let _ = std::process::Command::new("kill")
            .arg("-TERM")
            .arg(self.child.id().to_string())
            .status();
        let _ = self.child.wait();
    }
}
