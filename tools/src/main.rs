//! `penelope`: the one command line of the Penelope teleoperation architecture.
//!
//! Each subcommand lives in its own module under `cmd/`; this file only parses and dispatches.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cmd;

/// Penelope: distributed hard-real-time bilateral teleoperation.
#[derive(Parser, Debug)]
#[command(name = "penelope", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The teleoperation demo: FRHC master, PUMA 200 slave, a wall; report, telemetry and plots.
    Demo(cmd::demo::Args),
    /// Kinematics and dynamics of a robot model: fk, jacobian, ik, gravity, inertia, rne.
    Kin(cmd::kin::Args),
    /// Benchmarks: jitter beside cyclictest, FPGA model throughput.
    #[command(subcommand)]
    Bench(cmd::bench::BenchCommand),
    /// Experiments on the simulated clock: `delay` (each law against each round-trip delay).
    #[command(subcommand)]
    Experiment(cmd::experiment::ExperimentCommand),
    /// Check this host for real-time use and print what to fix.
    Doctor(cmd::doctor::Args),
    /// Drive a Galil DMC motion controller over a serial line.
    Galil(cmd::galil::Args),
    /// Emulate a Galil DMC-40x0 on a pseudo-terminal.
    GalilSim(cmd::galil_sim::Args),
    /// Talk to an ATI Net F/T force/torque sensor over UDP: bias, read, monitor.
    Netft(cmd::netft::Args),
    /// Emulate an ATI Net F/T on a UDP port (optionally with a Galil DMC whose arm it sits on).
    NetftSim(cmd::netft_sim::Args),
    /// Check a V4L2 camera by hand: `probe DEVICE` lists its formats, sizes and rates and
    /// captures a few frames with their timestamp source.
    #[command(subcommand)]
    Camera(cmd::camera::CameraCommand),
    /// Run a node: its creator, its objects and their real-time loops, served over TCP.
    Node(cmd::node::Args),
    /// Run the naming service alone.
    Naming(cmd::naming::Args),
    /// Recordings (MCAP): `info FILE` says what one holds, `rerun FILE` runs a recorded
    /// simulated-clock demo again and compares.
    #[command(subcommand)]
    Recording(cmd::recording::RecordingCommand),
    /// Talk to the nodes: list, create, configure, activate, call methods, watch telemetry.
    Ctl(cmd::ctl::Args),
    /// Shared secrets: `new FILE` writes a strong one (mode 600, never over an existing file).
    #[command(subcommand)]
    Secret(cmd::secret::SecretCommand),
    /// The web interface: the naming tree, object forms, lifecycle, live plots, e-stop, in a
    /// browser (loopback by default; elsewhere a login with the shared secret).
    Web(cmd::web::Args),
    /// The live stream for Foxglove (`foxglove.websocket.v1`): the robots' transforms and
    /// descriptions, the scene, ticks and links, on loopback; the e-stop as a service.
    Foxglove(cmd::foxglove::Args),
}

fn main() -> ExitCode {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(args) => cmd::demo::run_demo(args),
        Command::Kin(args) => cmd::kin::run(args),
        Command::Bench(bench) => cmd::bench::run(bench),
        Command::Experiment(e) => cmd::experiment::run(e),
        Command::Doctor(args) => cmd::doctor::run(args),
        Command::Galil(args) => cmd::galil::run(args),
        Command::GalilSim(args) => cmd::galil_sim::run(args),
        Command::Netft(args) => cmd::netft::run(args),
        Command::NetftSim(args) => cmd::netft_sim::run(args),
        Command::Camera(c) => cmd::camera::run(c),
        Command::Node(args) => cmd::node::run(args),
        Command::Naming(args) => cmd::naming::run(args),
        Command::Ctl(args) => cmd::ctl::run(args),
        Command::Web(args) => cmd::web::run(args),
        Command::Foxglove(args) => cmd::foxglove::run(args),
        Command::Secret(c) => cmd::secret::run(c),
        Command::Recording(c) => cmd::recording::run(c),
    };
    match result {
        Ok(code) => code,
        Err(err) => cmd::report_error(&err),
    }
}
