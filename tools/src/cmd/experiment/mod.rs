//! `penelope experiment`: experiments a control engineer reruns and compares; each runs a
//! system file's task many times on the simulated clock (fast, reproducible for a seed).
//!
//! - `delay`: the tapping-on-a-stiff-wall task for each law and each round-trip delay, with a
//!   stability verdict per run (`penelope_supervisor::runs::delay` defines the criterion), a
//!   table, a stability-map plot and JSON.
//! - `sync`: video and force reaching the operator, in the layouts of hosts, with a camera
//!   whose link is delayed: the latency of each, the skew between them unaligned, and what is
//!   left of it after alignment (`sync` module).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use penelope_supervisor::runs::delay::{DelayPlan, DelayRun, run_plan};
use penelope_supervisor::runs::{DEMO_SYSTEM, Law};
use penelope_supervisor::system::SystemFile;

use super::demo::parse_duration;
use super::usage;

mod map;
mod sync;

/// Which experiment to run.
#[derive(clap::Subcommand, Debug)]
pub enum ExperimentCommand {
    /// Each law against each round-trip delay (half each way) on the simulated clock: stable
    /// or not, tracking, force tracking, drag, contact force; a table, a stability map, JSON.
    Delay(DelayArgs),
    /// Video and force at the operator's station: a camera on the robot's node, its link
    /// delayed; capture-to-display latency of the video, measurement-to-display latency of the
    /// force, and their skew before and after alignment (p50, p99, max), per layout of hosts.
    Sync(sync::SyncArgs),
}

/// Options of `penelope experiment delay`.
#[derive(clap::Args, Debug)]
pub struct DelayArgs {
    /// The laws, by name, comma-separated (`force-position`, `position-error`, `wave`, `tdpa`).
    #[arg(long, default_value = "force-position,position-error,wave,tdpa")]
    laws: String,
    /// Round-trip delays, comma-separated, in ms unless a unit says otherwise (`0,10,50ms`,
    /// `0.1s`); each direction gets half.
    #[arg(long, default_value = "0,10,50,100,200ms")]
    delays: String,
    /// Jitter of each direction, ms: every sample a further U(0, jitter) late.
    #[arg(long, value_name = "MS", default_value = "0")]
    jitter: String,
    /// The wall's stiffness, N/m (default: the system file's, 4000 in the demo's).
    #[arg(long, value_name = "N_PER_M")]
    wall_stiffness: Option<f64>,
    /// Seed of the delay lines and the sensor noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Length of each run (default: the operator's script, 20 s).
    #[arg(long, value_parser = parse_duration)]
    duration: Option<Duration>,
    /// Runs at once (default: the cores, at most 4).
    #[arg(long)]
    jobs: Option<usize>,
    /// System file (default: the shipped `config/demo.toml`).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Print `{"runs": [...]}` as JSON on stdout instead of the table.
    #[arg(long)]
    json: bool,
    /// Output folder for the stability map and `runs.json` (default: `out/delay-<unix time>`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// Runs the chosen experiment.
pub fn run(command: ExperimentCommand) -> anyhow::Result<ExitCode> {
    match command {
        ExperimentCommand::Delay(args) => run_delay(args),
        ExperimentCommand::Sync(args) => sync::run(args),
    }
}

/// `0,10,50,100,200ms`: every number in ms, or in the unit written after it (`ms`, `s`).
fn parse_delays(text: &str) -> Result<Vec<f64>, String> {
    let mut out = Vec::new();
    for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        out.push(parse_ms(item)?);
    }
    if out.is_empty() {
        return Err(format!("no delay in `{text}`"));
    }
    Ok(out)
}

/// `50`, `50ms` or `0.05s`, in ms; zero allowed.
fn parse_ms(item: &str) -> Result<f64, String> {
    let (number, scale) = if let Some(n) = item.strip_suffix("ms") {
        (n, 1.0)
    } else if let Some(n) = item.strip_suffix('s') {
        (n, 1e3)
    } else {
        (item, 1.0)
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("not a delay: `{item}` (try 50 or 50ms)"))?;
    let ms = value * scale;
    // The delay line's range: one direction at most a minute.
    if !(ms.is_finite() && (0.0..=60_000.0).contains(&ms)) {
        return Err(format!("`{item}` is outside 0..=60000 ms"));
    }
    Ok(ms)
}

fn parse_laws(text: &str) -> Result<Vec<Law>, String> {
    let names: Vec<&str> = Law::ALL.iter().map(|l| l.as_str()).collect();
    text.split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|name| {
            Law::from_name(name)
                .ok_or_else(|| format!("unknown law `{name}` (one of {})", names.join(", ")))
        })
        .collect::<Result<Vec<_>, _>>()
        .and_then(|l| {
            if l.is_empty() {
                Err("no law given".to_string())
            } else {
                Ok(l)
            }
        })
}

fn run_delay(args: DelayArgs) -> anyhow::Result<ExitCode> {
    let laws = parse_laws(&args.laws).map_err(|e| usage(format!("--laws: {e}")))?;
    let round_trip_ms = parse_delays(&args.delays).map_err(|e| usage(format!("--delays: {e}")))?;
    let jitter_ms = parse_ms(args.jitter.trim()).map_err(|e| usage(format!("--jitter: {e}")))?;
    if let Some(k) = args.wall_stiffness
        && !(k.is_finite() && k > 0.0)
    {
        return Err(usage(format!(
            "--wall-stiffness must be a positive number of N/m, got {k}"
        )));
    }
    if round_trip_ms.iter().any(|d| d / 2.0 + jitter_ms > 60_000.0) {
        return Err(usage("a direction's delay plus jitter exceeds 60000 ms"));
    }
    let text = match &args.config {
        Some(path) => std::fs::read_to_string(path)
            .map_err(|e| usage(format!("reading the system file {}: {e}", path.display())))?,
        None => DEMO_SYSTEM.to_string(),
    };
    let system = SystemFile::parse(&text).map_err(|e| usage(format!("system file: {e}")))?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let plan = DelayPlan {
        laws,
        round_trip_ms,
        jitter_ms,
        wall_stiffness: args.wall_stiffness,
        seed: args.seed,
        duration: args.duration,
        jobs: args.jobs.unwrap_or(cores.min(4)).max(1),
    };
    let total = plan.laws.len() * plan.round_trip_ms.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    eprintln!(
        "delay experiment: {total} runs of the task on the simulated clock, {} at once",
        plan.jobs
    );
    let runs = run_plan(&system, &plan, &|r: &DelayRun| {
        let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        eprintln!(
            "  [{n}/{total}] {} at {} ms round trip: {} ({:.1} s)",
            r.law,
            r.delay_ms,
            if r.stable { "stable" } else { "UNSTABLE" },
            r.wall_time_s
        );
    })
    .map_err(|e| usage(e.to_string()))?;

    let out_dir = args.out.clone().unwrap_or_else(|| {
        let secs = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        PathBuf::from("out").join(format!("delay-{secs}"))
    });
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let json = serde_json::to_string_pretty(&serde_json::json!({ "runs": runs }))?;
    let runs_path = out_dir.join("runs.json");
    std::fs::write(&runs_path, &json)
        .with_context(|| format!("writing {}", runs_path.display()))?;
    let map_path = out_dir.join("stability-map.svg");
    map::write(&map_path, &plan, &runs).context("drawing the stability map")?;
    if args.json {
        println!("{json}");
        eprintln!("wrote {}", runs_path.display());
        eprintln!("wrote {}", map_path.display());
    } else {
        print_table(&plan, &runs);
        println!();
        println!("  wrote {}", runs_path.display());
        println!("  wrote {}", map_path.display());
    }
    Ok(ExitCode::SUCCESS)
}

fn print_table(plan: &DelayPlan, runs: &[DelayRun]) {
    println!(
        "Delay experiment: tapping on a stiff wall{}, jitter {} ms each way, seed {} \
         (simulated clock; delays are round trips, half each way)",
        plan.wall_stiffness
            .map_or(String::new(), |k| format!(" of {k} N/m")),
        plan.jitter_ms,
        plan.seed
    );
    println!();
    println!(
        "  {:<16} {:>9}  {:<8} {:>7} {:>7} {:>8} {:>9} {:>9} {:>8} {:>8} {:>9}",
        "law",
        "delay ms",
        "stable",
        "growth",
        "ripple",
        "rest",
        "track",
        "vs master",
        "force",
        "drag",
        "max force"
    );
    println!(
        "  {:<16} {:>9}  {:<8} {:>7} {:>7} {:>8} {:>9} {:>9} {:>8} {:>8} {:>9}",
        "", "(rt)", "", "", "", "mm", "RMS mm", "RMS mm", "err %", "RMS N", "N"
    );
    for r in runs {
        println!(
            "  {:<16} {:>9.0}  {:<8} {:>7.2} {:>7.2} {:>8.2} {:>9.2} {:>9.2} {:>8.1} {:>8.2} {:>9.1}",
            r.law,
            r.delay_ms,
            if r.stable { "yes" } else { "NO" },
            r.energy_growth,
            r.contact_ripple,
            r.rest_motion_mm,
            r.tracking_rms_mm,
            r.against_master_rms_mm,
            r.force_error_pct,
            r.drag_rms_n,
            r.max_contact_force_n
        );
    }
    let unstable: Vec<&DelayRun> = runs.iter().filter(|r| !r.stable).collect();
    if !unstable.is_empty() {
        println!();
        println!("  why unstable");
        for r in unstable {
            println!(
                "    {} at {} ms: {}",
                r.law,
                r.delay_ms,
                r.reasons.join("; ")
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delays_are_milliseconds_unless_a_unit_says_otherwise() {
        assert_eq!(
            parse_delays("0,10,50,100,200ms").unwrap(),
            vec![0.0, 10.0, 50.0, 100.0, 200.0]
        );
        assert_eq!(parse_delays("0.1s, 20").unwrap(), vec![100.0, 20.0]);
        assert!(parse_delays("soon").is_err());
        assert!(parse_delays("-5").is_err());
        assert!(parse_laws("force-position,telepathy").is_err());
        assert_eq!(
            parse_laws("position-error").unwrap(),
            vec![Law::PositionError]
        );
    }
}
