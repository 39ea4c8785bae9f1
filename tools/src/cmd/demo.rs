//! `penelope demo`: the paper's test task on simulated devices. An operator's hand moves the
//! FRHC, the PUMA 200 follows, touches a wall, and the operator feels it.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::runs::report::{Report, report};
use penelope_supervisor::runs::rerun::RunRecipe;
use penelope_supervisor::runs::{
    DEMO_SYSTEM, Law, MasterKinematics, RunOptions, RunOutput, run, with_master_kinematics,
};
use penelope_supervisor::system::SystemFile;

use super::usage;

mod files;
mod plots;

/// Options of `penelope demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// System file (default: the shipped `config/demo.toml`).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Length of the run, for example `20s` or `1500ms` (default: the operator script, 20 s).
    #[arg(long, value_parser = parse_duration)]
    duration: Option<Duration>,
    /// Bilateral law: `force-position` (position forward, force back), `position-error`, `wave`
    /// (wave variables), or `tdpa` (force-position with time-domain passivity's two-port
    /// controllers).
    #[arg(long, value_parser = ["force-position", "position-error", "wave", "tdpa"])]
    law: Option<String>,
    /// Position scale: slave motion per master motion.
    #[arg(long)]
    scale: Option<f64>,
    /// Seed of every random source (sensor noise).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output folder for telemetry, plots and the report (default: `out/demo-<unix time>`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Print the report as JSON on stdout (progress and file names go to stderr).
    #[arg(long)]
    json: bool,
    /// Run the same loops on a simulated clock: faster than real time and bit-for-bit
    /// reproducible for a given seed.
    #[arg(long)]
    sim_clock: bool,
    /// The master's kinematics: `float` (the FRHC's joints on `board/sim`, f64 on the host) or
    /// `fpga` (on `board/fpga`: the board's bit-exact forward kinematics and tau = J^T F, with
    /// its latency). Default: the file's boards.
    #[arg(long, value_parser = ["float", "fpga"])]
    kinematics: Option<String>,
    /// Recording profile: `penelope` (`run.mcap` only) or `ros2`: also `run-ros2.mcap`, the
    /// run's ROS 2 topic set as CDR with `ros2msg` schemas (`ros2 bag`, rosbags, Foxglove's
    /// ROS views); `run.mcap`, which `penelope recording rerun` reads, is written as always.
    #[arg(long, value_name = "PROFILE", default_value = "penelope", value_parser = ["penelope", "ros2"])]
    record_profile: String,
}

/// Parses `20s`, `1.5s`, `1500ms`, `2m` or a bare number of seconds.
pub fn parse_duration(text: &str) -> Result<Duration, String> {
    let text = text.trim();
    let (number, unit) = match text.find(|c: char| c.is_ascii_alphabetic()) {
        Some(i) => text.split_at(i),
        None => (text, "s"),
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("not a duration: `{text}` (try 20s or 500ms)"))?;
    let seconds = match unit {
        "s" => value,
        "ms" => value / 1e3,
        "us" => value / 1e6,
        "m" | "min" => value * 60.0,
        _ => {
            return Err(format!(
                "unknown unit `{unit}` in `{text}` (use s, ms, us or m)"
            ));
        }
    };
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(format!("duration must be positive: `{text}`"));
    }
    Ok(Duration::from_secs_f64(seconds))
}

/// Runs the demo.
pub fn run_demo(args: Args) -> anyhow::Result<ExitCode> {
    let text = match &args.config {
        Some(path) => std::fs::read_to_string(path)
            .map_err(|e| usage(format!("reading the system file {}: {e}", path.display())))?,
        None => DEMO_SYSTEM.to_string(),
    };
    let where_ = args.config.as_ref().map_or_else(
        || "config/demo.toml".to_string(),
        |p| p.display().to_string(),
    );
    let mut system = SystemFile::parse(&text).map_err(|e| usage(format!("{where_}: {e}")))?;
    if let Some(k) = args
        .kinematics
        .as_deref()
        .and_then(MasterKinematics::from_name)
    {
        system = with_master_kinematics(&system, k).map_err(|e| usage(format!("{where_}: {e}")))?;
    }
    // (clap has checked the word.)
    let law = args.law.as_deref().and_then(Law::from_name);
    if let Some(s) = args.scale
        && !(s.is_finite() && s > 0.0)
    {
        return Err(usage(format!("--scale must be a positive number, got {s}")));
    }
    let options = RunOptions {
        duration: args.duration,
        law,
        scale: args.scale,
        seed: args.seed,
        clock: if args.sim_clock {
            ClockMode::Simulated
        } else {
            ClockMode::RealTime
        },
    };
    let out_dir = args.out.clone().unwrap_or_else(default_out_dir);

    let bar = ProgressBar::new(1000);
    bar.set_style(
        ProgressStyle::with_template("{prefix} [{bar:30}] {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_prefix(format!(
        "{} {}",
        system.name.as_deref().unwrap_or("system"),
        if args.sim_clock {
            "(simulated clock)"
        } else {
            "(real time)"
        }
    ));
    let output = run(&system, &options, &mut |p| {
        let fraction = p.elapsed.as_secs_f64() / p.total.as_secs_f64().max(1e-9);
        bar.set_position((fraction * 1000.0).clamp(0.0, 1000.0) as u64);
        bar.set_message(format!(
            "{:5.1}/{:.0} s  {:<10}  tracking {:5.2} mm  contact {:5.1} N  commanded {:4.1} N",
            p.elapsed.as_secs_f64(),
            p.total.as_secs_f64(),
            p.phase,
            p.tracking_error * 1e3,
            p.contact_force,
            p.commanded_force
        ));
    })
    .map_err(|e| usage(e.to_string()))?;
    bar.finish_and_clear();

    let report = report(&output);
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    // What `penelope recording rerun` needs to run it again.
    let duration = options
        .duration
        .unwrap_or_else(|| output.info.script.duration());
    let recipe = RunRecipe::new(&text, &options, args.kinematics.as_deref(), duration);
    let mut written = write_outputs(&out_dir, &output, &report, &recipe)?;
    if args.record_profile == "ros2" {
        let path = out_dir.join("run-ros2.mcap");
        penelope_supervisor::runs::recording::write_run_ros2(&path, &output)
            .with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        for f in &written {
            eprintln!("wrote {}", f.display());
        }
    } else {
        print_report(&report, &out_dir, &written);
    }
    Ok(ExitCode::SUCCESS)
}

fn default_out_dir() -> PathBuf {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    PathBuf::from("out").join(format!("demo-{secs}"))
}

fn write_outputs(
    dir: &Path,
    output: &RunOutput,
    report: &Report,
    recipe: &RunRecipe,
) -> anyhow::Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for (name, rows) in [
        ("telemetry-master.csv", &output.master),
        ("telemetry-slave.csv", &output.slave),
    ] {
        let path = dir.join(name);
        files::write_telemetry(&path, output.info.start, &output.info.script, rows)
            .with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
    }
    let path = dir.join("run.mcap");
    penelope_supervisor::runs::recording::write_run(&path, output, Some(recipe))
        .with_context(|| format!("writing {}", path.display()))?;
    written.push(path);
    let path = dir.join("report.json");
    std::fs::write(&path, serde_json::to_string_pretty(report)?)
        .with_context(|| format!("writing {}", path.display()))?;
    written.push(path);
    written.extend(plots::write_all(dir, output).context("drawing plots")?);
    Ok(written)
}

fn print_report(r: &Report, dir: &Path, written: &[PathBuf]) {
    print_run(r);
    println!();
    print_task_figures(r);
    print_loop_timing(r);
    print_safety(r);
    println!();
    print_written(dir, written);
}

/// The run: lab, law, clock, seed, duration, mapping and master kinematics.
fn print_run(r: &Report) {
    println!(
        "Penelope teleoperation demo: {} ({} law, {} clock, seed {})",
        r.lab, r.law, r.clock, r.seed
    );
    println!(
        "  run: {:.1} s, scale {}, force gain {}",
        r.duration_s, r.scale, r.force_gain
    );
    let k = &r.kinematics;
    if k.master == "fpga" {
        println!(
            "  master kinematics: fpga board (bit-exact): FK {} cycles, {:.3} µs to the host; FK + force {} cycles, {:.3} µs; command on the motors {:.3} µs after the encoder latch",
            k.fk_cycles,
            k.fk_latency_us,
            k.fk_force_cycles,
            k.fk_force_latency_us,
            k.command_delay_us
        );
    } else {
        println!("  master kinematics: float (on the host)");
    }
}

/// The task's figures: tracking, contact, drag, tapping energy, clutch.
fn print_task_figures(r: &Report) {
    println!("  free-motion tracking (slave tool)");
    println!(
        "    vs its reference: RMS {:.3} mm   max {:.3} mm   over {} ticks",
        r.tracking.rms_mm, r.tracking.max_mm, r.tracking.samples
    );
    println!(
        "    vs the master's mapped pose at the same instant: RMS {:.3} mm   max {:.3} mm",
        r.tracking.against_master_rms_mm, r.tracking.against_master_max_mm
    );
    println!("  steady contact with the wall");
    println!(
        "    sensed {:.2} N (true {:.2} N)   expected display {:.2} N   motors display {:.2} N ({:.2}% off; law commands {:.2} N)   hand feels {:.2} N",
        r.contact.sensed_force_n,
        r.contact.true_contact_force_n,
        r.contact.expected_display_n,
        r.contact.displayed_force_n,
        r.contact.display_error_pct,
        r.contact.commanded_force_n,
        r.contact.hand_force_n
    );
    println!("  free-motion drag felt by the operator");
    println!("    RMS {:.2} N   max {:.2} N", r.drag.rms_n, r.drag.max_n);
    println!("  tapping: peak energy per cycle (J)");
    let peaks: Vec<String> = r
        .energy
        .tap_cycle_peaks_j
        .iter()
        .map(|e| format!("{e:.3}"))
        .collect();
    if peaks.is_empty() {
        println!("    the run ended before the tapping phase");
    } else {
        println!(
            "    {}   last/largest earlier {:.2}   operator work {:.3} J",
            peaks.join(" "),
            r.energy.growth_ratio,
            r.energy.operator_work_j
        );
    }
    println!("  clutch (indexing)");
    println!(
        "    largest reference step {:.3} mm (normal motion: {:.3} mm per tick)",
        r.clutch.max_step_mm, r.clutch.normal_max_step_mm
    );
    println!("  end-to-end latency, p50/p99 µs (limit: the wait for the receiving tick)");
    if r.clock == "simulated" {
        println!(
            "    (simulated clock: both loops tick at the same instants, stepped in a fixed order, \
             so a sample can be used at its own instant: 0 µs, below the limit)"
        );
    }
    for (what, e) in [
        ("motion->command", &r.latency.motion_to_command),
        ("contact->force", &r.latency.contact_to_force),
    ] {
        println!(
            "    {what:<16} {:.0}/{:.0}   limit {:.0}/{:.0}   ratio {:.2}/{:.2}   over {} samples",
            e.latency.p50_us,
            e.latency.p99_us,
            e.limit.p50_us,
            e.limit.p99_us,
            e.ratio_p50,
            e.ratio_p99,
            e.latency.samples
        );
    }
}

/// Each loop's wake-up latency, overruns and execution time (real clock only).
fn print_loop_timing(r: &Report) {
    if r.timing.is_empty() {
        println!("  loop timing: simulated clock (no wake-up latency to measure)");
    } else {
        println!(
            "  loop timing (wake-up latency, µs)          min    p50    p99  p99.9    max  overruns  exec mean/max"
        );
        for t in &r.timing {
            println!(
                "    {:<16} {:>6.0} µs period {}  {:>6.1} {:>6.1} {:>6.1} {:>6.1} {:>6.1}  {:>8}  {:.1}/{:.1}",
                t.name,
                t.period_us,
                if t.realtime { "FIFO" } else { "normal" },
                t.latency_us[0],
                t.latency_us[1],
                t.latency_us[2],
                t.latency_us[3],
                t.latency_us[4],
                t.overruns,
                t.exec_us[0],
                t.exec_us[1]
            );
        }
    }
}

/// Safety events, faults and dropped samples.
fn print_safety(r: &Report) {
    println!("  safety events");
    if r.safety_events.is_empty() {
        println!("    none");
    }
    for (event, count) in &r.safety_events {
        println!("    {event:<36} {count}");
    }
    for f in &r.faults {
        println!("    FAULT {f}");
    }
    if r.dropped_samples > 0 {
        println!(
            "  WARNING: {} telemetry samples dropped (the logger fell behind)",
            r.dropped_samples
        );
    }
}

/// Where the output went, and its files.
fn print_written(dir: &Path, written: &[PathBuf]) {
    println!("  output in {}:", dir.display());
    for f in written {
        println!(
            "    {}",
            f.file_name().map_or_else(
                || f.display().to_string(),
                |n| n.to_string_lossy().into_owned()
            )
        );
    }
}
