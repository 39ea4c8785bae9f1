//! `penelope bench jitter`: the control loop's wake-up latency beside cyclictest's.
//!
//! Our control loop (the rt-core executor running a real [`ControlLoop`] on the simulated
//! six-joint testbed robot, with its communication loop in a second thread) and `cyclictest`
//! (rt-tests) run in alternating slices under the same load, at the same period, FIFO priority and
//! CPU. Both histograms use 1 µs buckets and are summarised the same way (min, p50, p99, p99.9,
//! max, and "late by a period or more"), then the ratios ours/cyclictest are printed. A second
//! phase finds our achievable control rate: the shortest period, among 1, 2, 4, 8, 10 and 20 kHz,
//! whose short run had no overrun.
//!
//! Writes `jitter.json` and `jitter.svg` (the two histograms, log scale) to `--out`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{Context as _, bail};
use penelope_hal::{JointReference, Reference, RobotModel};
use penelope_rt_core::cell::{Stamped, latest};
use penelope_rt_core::comm::CommLoop;
use penelope_rt_core::control::{ControlCommand, ControlConfig, ControlLoop, ControlPorts};
use penelope_rt_core::controller::JointPid;
use penelope_rt_core::exec::{self, Flow, PeriodicConfig, RtStatus, RunReport, Setting};
use penelope_rt_core::ring::ring;
use penelope_rt_core::safety::SafetyConfig;
use penelope_rt_core::stats::{DEFAULT_BUCKETS, LatencyHistogram, LatencySummary};
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_testbed::{ChainBoard, DecoupledChain, SineTrajectory, critically_damped_gains};
use serde_json::json;

use crate::cmd::usage;

/// Options of `penelope bench jitter`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Control period (for example 1ms, 500us).
    #[arg(long, default_value = "1ms")]
    pub period: String,
    /// Total measuring time, shared equally by our loop and cyclictest (for example 30s, 2m).
    #[arg(long, default_value = "30s")]
    pub duration: String,
    /// Background load while measuring.
    #[arg(long, value_enum, default_value_t = Load::None)]
    pub load: Load,
    /// CPU to pin both measured threads to (default: the last CPU).
    #[arg(long)]
    pub cpu: Option<usize>,
    /// SCHED_FIFO priority of both measured threads.
    #[arg(long, default_value_t = 90)]
    pub priority: u8,
    /// Length of one alternation slice (short slices spread a changing background load evenly
    /// over both sides).
    #[arg(long, default_value = "1s")]
    pub slice: String,
    /// Length of each run of the achievable-rate search; `0s` skips the search.
    #[arg(long, default_value = "2s")]
    pub rate_duration: String,
    /// Directory for jitter.json and jitter.svg.
    #[arg(long, default_value = "target/penelope-bench/jitter")]
    pub out: PathBuf,
}

/// Background load.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Load {
    /// No added load.
    None,
    /// `stress-ng --cpu <ncpu> --io 1 --vm 1 --vm-bytes 256M`.
    Stress,
}

/// Parses `1ms`, `500us`, `30s`, `2m`, `250ns`, `1.5s`.
pub fn parse_duration(text: &str) -> Option<Duration> {
    let t = text.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.'))?;
    let (number, unit) = t.split_at(split);
    let value: f64 = number.parse().ok()?;
    let scale = match unit.trim() {
        "ns" => 1e-9,
        "us" | "µs" => 1e-6,
        "ms" => 1e-3,
        "s" => 1.0,
        "m" | "min" => 60.0,
        _ => return None,
    };
    let secs = value * scale;
    (secs.is_finite() && secs >= 0.0).then(|| Duration::from_secs_f64(secs))
}

fn parse_arg(name: &str, text: &str) -> anyhow::Result<Duration> {
    parse_duration(text).ok_or_else(|| {
        usage(format!(
            "--{name} {text:?}: expected a duration like 1ms, 500us, 30s"
        ))
    })
}

/// Runs the benchmark.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let (period, duration, slice, rate_duration) = checked_durations(&args)?;
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let cpu = checked_cpu(&args, cpus)?;

    ensure_tools(args.load)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;

    let _load = match args.load {
        Load::None => None,
        Load::Stress => Some(start_stress(cpus)?),
    };

    let half = duration / 2;
    let slices = (half.as_secs_f64() / slice.as_secs_f64()).ceil().max(1.0) as u32;
    let per_slice = half / slices;
    eprintln!(
        "measuring {} us period on CPU {cpu} at SCHED_FIFO {}: {slices} slice(s) of {:.1} s each for our loop and cyclictest, load {:?}",
        period.as_micros(),
        args.priority,
        per_slice.as_secs_f64(),
        args.load
    );

    let mut ours = Measurement::new("penelope");
    let mut theirs = Measurement::new("cyclictest");
    let mut rt = RtStatus::default();
    let mut pairs = Vec::with_capacity(slices as usize);
    for i in 0..slices {
        let report = run_ours(period, per_slice, args.priority, cpu)?;
        rt = report.rt;
        ours.add_report(&report);
        let ct = run_cyclictest(period, per_slice, args.priority, cpu)?;
        theirs.add(&ct);
        pairs.push((report.latency.summary(), ct.summary()));
        eprintln!("  slice {}/{slices} done", i + 1);
    }

    let rates = if rate_duration.is_zero() {
        Vec::new()
    } else {
        achievable_rates(rate_duration, args.priority, cpu)?
    };
    let best = rates.iter().filter(|r| r.overruns == 0).map(|r| r.hz).max();

    let text = render_text(
        &args, period, duration, cpu, &ours, &theirs, &pairs, &rates, best, &rt,
    );
    print!("{text}");
    let json_path = args.out.join("jitter.json");
    let svg_path = args.out.join("jitter.svg");
    let doc = json!({
        "period_us": period.as_micros() as u64,
        "duration_s": duration.as_secs_f64(),
        "load": format!("{:?}", args.load).to_lowercase(),
        "cpu": cpu,
        "priority": args.priority,
        "rt": rt_json(&rt),
        "ours": ours.json(period),
        "cyclictest": theirs.json(period),
        "ratios": ratios_json(&ours.histogram.summary(), &theirs.histogram.summary()),
        "per_slice_median_ratios": {
            "p99": super::finite_or_null(median_ratio(&pairs, |s| s.p99)),
            "p999": super::finite_or_null(median_ratio(&pairs, |s| s.p999)),
        },
        "rates": rates.iter().map(|r| json!({
            "hz": r.hz, "ticks": r.ticks, "overruns": r.overruns, "late_by_a_period": r.late,
            "p999_us": us(r.p999), "exec_mean_us": us(r.exec_mean), "exec_max_us": us(r.exec_max),
            "cyclictest_late_by_a_period": r.baseline_late,
        })).collect::<Vec<_>>(),
        "best_overrun_free_hz": best,
    });
    std::fs::write(&json_path, serde_json::to_string_pretty(&doc)?)
        .with_context(|| format!("writing {}", json_path.display()))?;
    plot(&svg_path, period, &args, &ours, &theirs)?;
    println!("wrote {} and {}", json_path.display(), svg_path.display());
    Ok(ExitCode::SUCCESS)
}

/// The run's durations from the arguments: the period (whole microseconds, 20 µs to 1 s), the
/// duration and slice (at least 10 periods each) and the rate runs' duration; and the priority
/// checked (1 to 99).
fn checked_durations(args: &Args) -> anyhow::Result<(Duration, Duration, Duration, Duration)> {
    let period = parse_arg("period", &args.period)?;
    let duration = parse_arg("duration", &args.duration)?;
    let slice = parse_arg("slice", &args.slice)?;
    let rate_duration = parse_arg("rate-duration", &args.rate_duration)?;
    if period < Duration::from_micros(20)
        || period > Duration::from_secs(1)
        || period.subsec_nanos() % 1000 != 0
    {
        return Err(usage(
            "--period must be a whole number of microseconds between 20us and 1s",
        ));
    }
    if duration < period * 10 || slice < period * 10 {
        return Err(usage(
            "--duration and --slice must cover at least 10 periods",
        ));
    }
    if !(1..=99).contains(&args.priority) {
        return Err(usage("--priority must be 1 to 99"));
    }
    Ok((period, duration, slice, rate_duration))
}

/// The CPU to measure on: `--cpu`, else the last of `cpus`.
fn checked_cpu(args: &Args, cpus: usize) -> anyhow::Result<usize> {
    let cpu = args.cpu.unwrap_or(cpus - 1);
    if cpu >= cpus {
        return Err(usage(format!(
            "--cpu {cpu}: this machine has CPUs 0 to {}",
            cpus - 1
        )));
    }
    Ok(cpu)
}

/// The achievable rate: runs of `rate_duration` at 1 to 20 kHz, each against cyclictest.
fn achievable_rates(
    rate_duration: Duration,
    priority: u8,
    cpu: usize,
) -> anyhow::Result<Vec<RateRun>> {
    let mut rates = Vec::new();
    eprintln!(
        "achievable rate: {:.1} s runs at 1, 2, 4, 8, 10, 20 kHz",
        rate_duration.as_secs_f64()
    );
    for hz in [1_000u64, 2_000, 4_000, 8_000, 10_000, 20_000] {
        let p = Duration::from_nanos(1_000_000_000 / hz);
        let report = run_ours(p, rate_duration, priority, cpu)?;
        let baseline = run_cyclictest(p, rate_duration, priority, cpu)?;
        rates.push(RateRun {
            hz,
            ticks: report.ticks,
            overruns: report.overruns,
            late: report.latency.count_at_or_above(p),
            p999: report.latency.summary().p999,
            exec_mean: report.exec.mean(),
            exec_max: report.exec.max(),
            baseline_late: baseline.count_at_or_above(p),
        });
    }
    Ok(rates)
}

fn us(d: Duration) -> f64 {
    d.as_nanos() as f64 / 1000.0
}

struct RateRun {
    hz: u64,
    ticks: u64,
    overruns: u64,
    late: u64,
    p999: Duration,
    exec_mean: Duration,
    exec_max: Duration,
    /// cyclictest's wake-ups late by a period or more, same rate and length.
    baseline_late: u64,
}

/// One side's merged results.
struct Measurement {
    name: &'static str,
    histogram: Box<LatencyHistogram>,
    overruns: Option<u64>,
}

impl Measurement {
    fn new(name: &'static str) -> Self {
        Measurement {
            name,
            histogram: Box::default(),
            overruns: None,
        }
    }

    fn add(&mut self, h: &LatencyHistogram) {
        self.histogram.merge(h);
    }

    fn add_report(&mut self, r: &RunReport) {
        self.histogram.merge(&r.latency);
        *self.overruns.get_or_insert(0) += r.overruns;
    }

    fn json(&self, period: Duration) -> serde_json::Value {
        let s = self.histogram.summary();
        let buckets: Vec<[u64; 2]> = self
            .histogram
            .buckets()
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(i, c)| [i as u64, *c])
            .collect();
        json!({
            "samples": s.count,
            "min_us": us(s.min), "p50_us": us(s.p50), "p99_us": us(s.p99),
            "p999_us": us(s.p999), "max_us": us(s.max), "mean_us": us(s.mean),
            "late_by_a_period": self.histogram.count_at_or_above(period),
            "overruns": self.overruns,
            "histogram_bucket_us": 1,
            "histogram": buckets,
            "overflow": s.overflow,
        })
    }
}

/// The median over slice pairs of `pick(ours) / pick(cyclictest)`.
fn median_ratio(
    pairs: &[(LatencySummary, LatencySummary)],
    pick: impl Fn(&LatencySummary) -> Duration,
) -> f64 {
    super::finite_median(pairs.iter().map(|(a, b)| ratio(pick(a), pick(b))))
}

fn ratio(a: Duration, b: Duration) -> f64 {
    if b.is_zero() {
        f64::NAN
    } else {
        a.as_secs_f64() / b.as_secs_f64()
    }
}

fn ratios_json(a: &LatencySummary, b: &LatencySummary) -> serde_json::Value {
    let r = |x, y| {
        let v = ratio(x, y);
        if v.is_finite() { json!(v) } else { json!(null) }
    };
    json!({ "p50": r(a.p50, b.p50), "p99": r(a.p99, b.p99), "p999": r(a.p999, b.p999), "max": r(a.max, b.max) })
}

fn rt_json(rt: &RtStatus) -> serde_json::Value {
    let s = |x: Setting| match x {
        Setting::NotRequested => "not requested".to_string(),
        Setting::Applied => "applied".to_string(),
        Setting::Refused(e) => format!("refused ({})", std::io::Error::from_raw_os_error(e)),
    };
    json!({ "sched_fifo": s(rt.fifo), "affinity": s(rt.affinity), "mlockall": s(rt.memory_locked), "cpu_dma_latency": s(rt.dma_latency) })
}

#[allow(clippy::too_many_arguments)]
fn render_text(
    args: &Args,
    period: Duration,
    duration: Duration,
    cpu: usize,
    ours: &Measurement,
    theirs: &Measurement,
    pairs: &[(LatencySummary, LatencySummary)],
    rates: &[RateRun],
    best: Option<u64>,
    rt: &RtStatus,
) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "\nWake-up latency, period {} us, load {}, CPU {cpu}, SCHED_FIFO {}, {:.0} s total (alternating slices)",
        period.as_micros(),
        format!("{:?}", args.load).to_lowercase(),
        args.priority,
        duration.as_secs_f64()
    );
    let _ = writeln!(
        o,
        "{:<12} {:>8} {:>8} {:>8} {:>8} {:>9} {:>10} {:>9} {:>9}",
        "", "min us", "p50 us", "p99 us", "p99.9 us", "max us", "late>=T", "overruns", "samples"
    );
    for m in [ours, theirs] {
        let s = m.histogram.summary();
        let _ = writeln!(
            o,
            "{:<12} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>9.1} {:>10} {:>9} {:>9}",
            m.name,
            us(s.min),
            us(s.p50),
            us(s.p99),
            us(s.p999),
            us(s.max),
            m.histogram.count_at_or_above(period),
            m.overruns.map_or("-".to_string(), |x| x.to_string()),
            s.count
        );
    }
    let (a, b) = (ours.histogram.summary(), theirs.histogram.summary());
    let _ = writeln!(
        o,
        "{:<12} {:>8} {:>8.2} {:>8.2} {:>8.2} {:>9.2}",
        "ours/ct",
        "",
        ratio(a.p50, b.p50),
        ratio(a.p99, b.p99),
        ratio(a.p999, b.p999),
        ratio(a.max, b.max)
    );
    let _ = writeln!(
        o,
        "(percentiles are 1 us bucket upper edges; late>=T: wake-ups a period or more late; overruns: ticks that ended past the next deadline)"
    );
    if pairs.len() >= 3 {
        let _ = writeln!(
            o,
            "median over the {} slice pairs of ours/cyclictest: p99 {:.2}, p99.9 {:.2} (robust to background load that changes between slices)",
            pairs.len(),
            median_ratio(pairs, |s| s.p99),
            median_ratio(pairs, |s| s.p999)
        );
    }
    let _ = writeln!(
        o,
        "real-time settings of our thread: SCHED_FIFO {}, affinity {}, mlockall {}, cpu_dma_latency {}",
        rt_json(rt)["sched_fifo"].as_str().unwrap_or("?"),
        rt_json(rt)["affinity"].as_str().unwrap_or("?"),
        rt_json(rt)["mlockall"].as_str().unwrap_or("?"),
        rt_json(rt)["cpu_dma_latency"].as_str().unwrap_or("?"),
    );
    if !rates.is_empty() {
        write_rates(&mut o, rates, best);
    }
    o
}

/// The achievable-rate table and the highest overrun-free rate.
fn write_rates(o: &mut String, rates: &[RateRun], best: Option<u64>) {
    let _ = writeln!(
        o,
        "\nAchievable control rate (our loop, same load; cyclictest at the same rate for reference):"
    );
    let _ = writeln!(
        o,
        "{:>8} {:>9} {:>9} {:>9} {:>10} {:>13} {:>12} {:>11}",
        "rate",
        "ticks",
        "overruns",
        "late>=T",
        "p99.9 us",
        "exec mean us",
        "exec max us",
        "ct late>=T"
    );
    for r in rates {
        let _ = writeln!(
            o,
            "{:>5} kHz {:>9} {:>9} {:>9} {:>10.1} {:>13.1} {:>12.1} {:>11}",
            r.hz / 1000,
            r.ticks,
            r.overruns,
            r.late,
            us(r.p999),
            us(r.exec_mean),
            us(r.exec_max),
            r.baseline_late
        );
    }
    match best {
        Some(hz) => {
            let _ = writeln!(o, "highest overrun-free rate: {} kHz", hz / 1000);
        }
        None => {
            let _ = writeln!(
                o,
                "highest overrun-free rate: none of the tried rates ran without an overrun"
            );
        }
    }
}

/// Runs our control loop (plus its communication thread) for `length` at `period`.
fn run_ours(
    period: Duration,
    length: Duration,
    priority: u8,
    cpu: usize,
) -> anyhow::Result<RunReport> {
    let model = DecoupledChain::six_joint();
    let cpr = 10_000.0;
    let board = ChainBoard::new(model.clone(), cpr);
    let mut safety = SafetyConfig::slave(6, *model.limits());
    safety.watchdog = Duration::from_millis(100);
    let config = ControlConfig::new(period, safety).with_counts_per_radian(cpr);
    let (ref_tx, ref_rx) = latest::<Stamped<Reference>>();
    let (tel_tx, mut tel_rx) = ring::<TelemetrySample, 4096>();
    let (mut cmd_tx, cmd_rx) = ring::<ControlCommand, 8>();
    let ports = ControlPorts {
        reference: ref_rx,
        telemetry: tel_tx,
        commands: cmd_rx,
    };
    let pid = JointPid::new(critically_damped_gains(&model, 30.0));
    let mut control = ControlLoop::new(config, board, model, [pid], ports)
        .map_err(|e| anyhow::anyhow!("control loop: {e}"))?;
    let mut comm = CommLoop::new(SineTrajectory::new(0.1, 0.5), ref_tx);
    cmd_tx
        .push(ControlCommand::Activate)
        .map_err(|_| anyhow::anyhow!("command ring full"))?;

    let ticks = (length.as_nanos() / period.as_nanos()).max(1) as u64;
    let started = Arc::new(AtomicBool::new(false));
    let started_comm = started.clone();
    let comm_config =
        PeriodicConfig::new("jitter-comm", Duration::from_millis(4)).normal_priority();
    let comm_thread = exec::spawn(comm_config, move |tick| {
        if !started_comm.swap(true, Ordering::Relaxed) {
            comm.start(tick.deadline, &Reference::Joint(JointReference::default()));
        }
        comm.tick(tick.deadline);
        Flow::Continue
    })?;
    let control_config = PeriodicConfig::new("jitter-control", period)
        .priority(priority)
        .cpu(cpu);
    let control_thread = exec::spawn(control_config, move |tick| {
        control.tick(tick.deadline);
        control.note_timing(tick.latency(), tick.previous_exec);
        if tick.index + 1 >= ticks {
            Flow::Stop
        } else {
            Flow::Continue
        }
    })?;
    while !control_thread.is_finished() {
        while tel_rx.pop().is_some() {}
        std::thread::sleep(Duration::from_millis(10));
    }
    let report = control_thread.join()?;
    comm_thread.stop_and_join()?;
    Ok(report)
}

/// Runs cyclictest for `length` and returns its histogram in our format.
fn run_cyclictest(
    period: Duration,
    length: Duration,
    priority: u8,
    cpu: usize,
) -> anyhow::Result<LatencyHistogram> {
    let loops = (length.as_nanos() / period.as_nanos()).max(1);
    let output = Command::new("cyclictest")
        .args(["-m", "-q", "-t", "1"])
        .arg(format!("-p{priority}"))
        .arg(format!("-i{}", period.as_micros()))
        .arg(format!("-h{DEFAULT_BUCKETS}"))
        .arg(format!("-l{loops}"))
        .arg(format!("-a{cpu}"))
        .stdin(Stdio::null())
        .output()
        .context("running cyclictest")?;
    if !output.status.success() {
        bail!(
            "cyclictest failed ({}): {}",
            output.status,
            String::from_utf8_lossy(&output.stderr).trim()
        );
    }
    parse_cyclictest(&String::from_utf8_lossy(&output.stdout))
        .context("reading cyclictest's histogram")
}

/// Reads cyclictest's `-h` output (one thread) into a 1 µs histogram.
pub fn parse_cyclictest(text: &str) -> anyhow::Result<LatencyHistogram> {
    let mut h = LatencyHistogram::default();
    let mut max_us = None;
    let mut overflows = 0u64;
    for line in text.lines() {
        let line = line.trim();
        if let Some(rest) = line.strip_prefix('#') {
            let field = |name: &str| {
                rest.trim()
                    .strip_prefix(name)
                    .and_then(|v| v.split_whitespace().next())
                    .and_then(|v| v.parse::<u64>().ok())
            };
            if let Some(v) = field("Max Latencies:") {
                max_us = Some(v);
            }
            if let Some(v) = field("Histogram Overflows:") {
                overflows = v;
            }
            continue;
        }
        let mut cols = line.split_whitespace();
        let (Some(bucket), Some(count)) = (cols.next(), cols.next()) else {
            continue;
        };
        let (Ok(bucket), Ok(count)) = (bucket.parse::<u64>(), count.parse::<u64>()) else {
            continue;
        };
        h.record_n(bucket * 1000, count);
    }
    let Some(max_us) = max_us else {
        bail!("no `# Max Latencies` line")
    };
    if overflows > 0 {
        h.record_n(max_us * 1000, overflows);
    }
    if h.count() == 0 {
        bail!("empty histogram");
    }
    Ok(h)
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .ok()
        .is_some_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

fn have(tool: &str) -> bool {
    Command::new(tool)
        .arg("--help")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok()
}

/// Makes sure cyclictest (and stress-ng when asked) are installed, installing them as root.
fn ensure_tools(load: Load) -> anyhow::Result<()> {
    let mut missing = Vec::new();
    if !have("cyclictest") {
        missing.push("rt-tests");
    }
    if load == Load::Stress && !have("stress-ng") {
        missing.push("stress-ng");
    }
    if missing.is_empty() {
        return Ok(());
    }
    if !is_root() {
        bail!(
            "this benchmark needs {} (cyclictest is the baseline{}): install with `sudo apt-get install -y {}`, or run as root and it installs them",
            missing.join(" and "),
            if load == Load::Stress {
                ", stress-ng the load"
            } else {
                ""
            },
            missing.join(" ")
        );
    }
    eprintln!("installing {} with apt-get", missing.join(" "));
    let ok = Command::new("apt-get")
        .args(["install", "-y", "-qq"])
        .args(&missing)
        .env("DEBIAN_FRONTEND", "noninteractive")
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        // The package lists may be missing on a fresh machine.
        let _ = Command::new("apt-get").args(["update", "-qq"]).status();
        let ok = Command::new("apt-get")
            .args(["install", "-y", "-qq"])
            .args(&missing)
            .env("DEBIAN_FRONTEND", "noninteractive")
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            bail!(
                "`apt-get install -y {}` failed: install them by hand",
                missing.join(" ")
            );
        }
    }
    Ok(())
}

/// The jitter benchmark's load: CPU, I/O and memory workers.
fn start_stress(cpus: usize) -> anyhow::Result<super::StressNg> {
    let cpus = cpus.to_string();
    let args = [
        "--cpu",
        &cpus,
        "--io",
        "1",
        "--vm",
        "1",
        "--vm-bytes",
        "256M",
    ];
    let child = super::StressNg::start(&args, Duration::from_secs(2))?;
    eprintln!("load: stress-ng {} (pid {})", args.join(" "), child.id());
    Ok(child)
}

fn plot(
    path: &Path,
    period: Duration,
    args: &Args,
    ours: &Measurement,
    theirs: &Measurement,
) -> anyhow::Result<()> {
    use plotters::prelude::*;
    let (a, b) = (ours.histogram.summary(), theirs.histogram.summary());
    let hi = a.p999.max(b.p999).max(Duration::from_micros(20)) * 3;
    let x_max = (hi.as_micros() as usize).clamp(20, DEFAULT_BUCKETS);
    let peak = ours
        .histogram
        .buckets()
        .iter()
        .chain(theirs.histogram.buckets().iter())
        .copied()
        .max()
        .unwrap_or(1)
        .max(1);
    let root = SVGBackend::new(path, (1000, 600)).into_drawing_area();
    root.fill(&WHITE)
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    let title = format!(
        "Wake-up latency, period {} us, load {}",
        period.as_micros(),
        format!("{:?}", args.load).to_lowercase()
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(0f64..x_max as f64, (0.5f64..peak as f64 * 2.0).log_scale())
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    chart
        .configure_mesh()
        .x_desc("wake-up latency (us, 1 us buckets)")
        .y_desc("samples")
        .draw()
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    for (m, color) in [(ours, RED), (theirs, BLUE)] {
        let s = m.histogram.summary();
        let points: Vec<(f64, f64)> = m.histogram.buckets()[..x_max]
            .iter()
            .enumerate()
            .flat_map(|(i, &c)| {
                let y = (c as f64).max(0.5);
                [(i as f64, y), (i as f64 + 1.0, y)]
            })
            .collect();
        chart
            .draw_series(LineSeries::new(points, color.stroke_width(2)))
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?
            .label(format!(
                "{}: p50 {:.0} us, p99 {:.0} us, p99.9 {:.0} us, max {:.0} us",
                m.name,
                us(s.p50),
                us(s.p99),
                us(s.p999),
                us(s.max)
            ))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    root.present().map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_parse() {
        assert_eq!(parse_duration("1ms"), Some(Duration::from_millis(1)));
        assert_eq!(parse_duration("500us"), Some(Duration::from_micros(500)));
        assert_eq!(parse_duration("1.5s"), Some(Duration::from_millis(1500)));
        assert_eq!(parse_duration("2m"), Some(Duration::from_secs(120)));
        assert_eq!(parse_duration("ms"), None);
        assert_eq!(parse_duration("3 parsecs"), None);
    }

    #[test]
    fn cyclictest_histograms_parse() {
        let text = "# /dev/cpu_dma_latency set to 0us\n# Histogram\n000006 000001\n000010 000003\n\
                    # Total: 000000004\n# Min Latencies: 00006\n# Avg Latencies: 00009\n\
                    # Max Latencies: 00734\n# Histogram Overflows: 00001\n";
        let h = parse_cyclictest(text).unwrap();
        assert_eq!(h.count(), 5);
        assert_eq!(h.overflow(), 0, "734 us fits in the 10 ms range");
        assert_eq!(h.max(), Some(Duration::from_micros(734)));
        assert_eq!(h.percentile(0.5), Some(Duration::from_micros(11)));
        assert!(parse_cyclictest("garbage").is_err());
    }
}
