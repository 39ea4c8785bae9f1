//! `penelope netft`: talk to an ATI Net F/T (or `penelope netft-sim`) over UDP: bias it, read
//! one wrench, or watch the stream with its counters.

use std::net::SocketAddr;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Subcommand;
use penelope_drivers::netft::{Calibration, NetFt, NetFtConfig};
use penelope_rt_core::clock::MonotonicClock;

/// Options.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The box's RDT address: ip:port, or an IP address alone for the box's port 49152.
    #[arg(long)]
    pub addr: String,
    /// Counts per newton (the box's cfgcpf).
    #[arg(long, default_value_t = 1_000_000.0)]
    pub counts_per_force: f64,
    /// Counts per newton-metre (the box's cfgcpt).
    #[arg(long, default_value_t = 1_000_000.0)]
    pub counts_per_torque: f64,
    /// A reading older than this is refused, ms; also how long to wait for the first record
    /// (times 100).
    #[arg(long, default_value_t = 20)]
    pub timeout_ms: u64,
    /// What to do.
    #[command(subcommand)]
    pub action: Action,
}

/// What to do with the sensor.
#[derive(Subcommand, Debug)]
pub enum Action {
    /// Take the present reading as the box's zero (its software bias, command 0x42).
    Bias,
    /// Print one wrench, N and N·m in the sensor frame (exit 1 on a fault).
    Read {
        /// Print `{"force": [..], "torque": [..], "status": .., "rdt_sequence": ..}`.
        #[arg(long)]
        json: bool,
    },
    /// Print the wrench and the stream's counters every interval.
    Monitor {
        /// Print period, ms.
        #[arg(long, default_value_t = 200)]
        interval_ms: u64,
        /// Stop after this many lines (default: run until interrupted).
        #[arg(long)]
        count: Option<u64>,
    },
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let address: SocketAddr = penelope_drivers::netft::parse_address(&args.addr)
        .map_err(|e| crate::cmd::usage(format!("--addr: {e}")))?;
    let calibration = Calibration {
        counts_per_force: args.counts_per_force,
        counts_per_torque: args.counts_per_torque,
    };
    if !calibration.is_valid() {
        return Err(crate::cmd::usage(
            "--counts-per-force and --counts-per-torque must be finite and positive",
        ));
    }
    if !(1..=10_000).contains(&args.timeout_ms) {
        return Err(crate::cmd::usage("--timeout-ms must be 1..=10000"));
    }
    let mut config = NetFtConfig::new(address);
    config.calibration = calibration;
    config.timeout = Duration::from_millis(args.timeout_ms);
    let ft = NetFt::open(config)?;
    let first = config.timeout * 100;
    if !ft.wait_for_records(1, first) {
        anyhow::bail!(
            "no RDT record from {address} within {} ms (is the box, or `penelope netft-sim`, there?)",
            first.as_millis()
        );
    }
    match args.action {
        Action::Bias => {
            let before = ft.counters().biases;
            ft.request_bias();
            // The I/O thread sends it at its next turn: wait for it to be counted (bounded).
            let deadline = Instant::now() + Duration::from_secs(1);
            while ft.counters().biases == before {
                anyhow::ensure!(Instant::now() < deadline, "the bias request was not sent");
                std::thread::sleep(Duration::from_millis(1));
            }
            println!("bias sent to {address}");
        }
        Action::Read { json } => {
            let w = ft.read(MonotonicClock::read())?;
            let s = ft.latest().unwrap_or_default();
            if json {
                println!(
                    "{}",
                    serde_json::json!({
                        "force": [w.force.x, w.force.y, w.force.z],
                        "torque": [w.torque.x, w.torque.y, w.torque.z],
                        "status": s.status.0,
                        "rdt_sequence": s.rdt_sequence,
                    })
                );
            } else {
                println!(
                    "F [{:9.4} {:9.4} {:9.4}] N   T [{:8.5} {:8.5} {:8.5}] N·m   status {:#010x}   rdt {}",
                    w.force.x,
                    w.force.y,
                    w.force.z,
                    w.torque.x,
                    w.torque.y,
                    w.torque.z,
                    s.status.0,
                    s.rdt_sequence
                );
            }
        }
        Action::Monitor { interval_ms, count } => {
            let interval = Duration::from_millis(interval_ms.max(1));
            let mut last = ft.counters();
            let mut at = Instant::now();
            let mut lines = 0u64;
            while count.is_none_or(|c| lines < c) {
                std::thread::sleep(interval);
                let c = ft.counters();
                let dt = at.elapsed().as_secs_f64();
                at = Instant::now();
                let rate = (c.records - last.records) as f64 / dt;
                let reading = match ft.read(MonotonicClock::read()) {
                    Ok(w) => format!(
                        "F [{:8.3} {:8.3} {:8.3}] N  T [{:7.4} {:7.4} {:7.4}] N·m",
                        w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z
                    ),
                    Err(e) => format!("FAULT: {e}"),
                };
                println!(
                    "{reading}  {rate:6.0} rec/s  missed {} in {} gaps  malformed {}  status errors {}  saturated {}  timeouts {}",
                    c.missed, c.gaps, c.malformed, c.status_errors, c.saturated, c.timeouts
                );
                last = c;
                lines += 1;
            }
        }
    }
    ft.stop();
    Ok(ExitCode::SUCCESS)
}
