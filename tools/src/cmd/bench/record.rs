//! `penelope bench record`: how much a node can record with no drop, beside what its loops
//! produce.
//!
//! The ticks are real: a simulated run of the demo's system (`--sample` long) gives both
//! controllers' ticks with the plant's truth, as `run.mcap` holds them. Two measurements:
//!
//! 1. **Writer ceiling**: one thread writes those ticks into an MCAP file through
//!    [`McapLog`] (JSON, zstd chunks) as fast as
//!    it can, for `--duration`: ticks per second and megabytes per second (file bytes, and the
//!    JSON before compression).
//! 2. **No-drop rate through the node's path**: the node's own recorder thread
//!    ([`Recorder`]) fed by the telemetry pump's
//!    fan-out ([`Subscriptions::publish`], bounded streams, `try_send`), with `K` controllers
//!    each producing 1,000 ticks per second in the pump's 10 ms batches, for `--duration` each,
//!    `K` doubling from 1 until the recorder falls behind: the largest `K` it keeps up with, its
//!    ticks per second and megabytes per second. *Keeps up* means no drop and everything
//!    written within [`KEEP_UP`] of the feed's end. A recorder that falls behind does not drop
//!    at once (each stream buffers 65,536 ticks, over a minute at 1 kHz) but it will in a long
//!    enough recording, so the rate it keeps up with is the rate a node records with no drop.
//!
//! The loops' own rate is one tick per control period per controller: the demo's two
//! controllers at 1 kHz make 2,000 ticks per second.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use penelope_runtime::common_clock::CommonClock;
use penelope_runtime::objects::clock::ClockReader;
use penelope_runtime::objects::recording::mcap_log::McapLog;
use penelope_runtime::objects::recording::{
    RecordProfile, Recorder, RecordingSources, SceneConfig,
};
use penelope_runtime::objects::runtime::Subscriptions;
use penelope_runtime::objects::tick::TickRecord;
use penelope_supervisor::runs::{DEMO_SYSTEM, RunOptions, run as run_task};
use penelope_supervisor::system::SystemFile;
use serde_json::json;

use crate::cmd::demo::parse_duration;
use crate::cmd::usage;

/// The recorder's stream capacity, as a node's recordings have it (a minute at 1 kHz).
const STREAM_CAPACITY: usize = 1 << 16;
/// The telemetry pump's batch period (the controllers' default `telemetry_period_ms`).
const BATCH: Duration = Duration::from_millis(10);
/// How soon after the feed ends the recorder must have written everything to count as keeping
/// up (its batches are 50 ms apart, its chunk flushes 200 ms).
const KEEP_UP: Duration = Duration::from_millis(300);
/// The largest number of controllers tried.
const MAX_CONTROLLERS: usize = 256;

/// Options of `penelope bench record`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Length of each measurement (for example 5s).
    #[arg(long, default_value = "5s", value_parser = parse_duration)]
    pub duration: Duration,
    /// Length of the simulated demo run whose ticks are recorded.
    #[arg(long, default_value = "2s", value_parser = parse_duration)]
    pub sample: Duration,
    /// Folder for the files written (default: a temporary one, removed afterwards).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also run the demo's loops on the real clock and measure them idle, recording, and
    /// recording while N clients subscribe to every tick and never read (`--duration` each).
    #[arg(long, value_name = "N")]
    pub flood: Option<usize>,
}

/// Runs `penelope bench record`.
///
/// # Errors
/// A usage error when the sample run fails; I/O errors writing the files.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let system = SystemFile::parse(DEMO_SYSTEM).map_err(|e| usage(e.to_string()))?;
    let options = RunOptions {
        duration: Some(args.sample),
        ..RunOptions::default()
    };
    let output = run_task(&system, &options, &mut |_| {}).map_err(|e| usage(e.to_string()))?;
    let ticks: Vec<TickRecord> = output.master.iter().chain(&output.slave).copied().collect();
    anyhow::ensure!(!ticks.is_empty(), "the sample run gave no ticks");
    let json_bytes: usize = ticks
        .iter()
        .map(|t| serde_json::to_vec(t).map_or(0, |v| v.len()))
        .sum::<usize>()
        / ticks.len();
    let temporary = args.out.is_none();
    let dir = args.out.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("penelope-bench-record-{}", std::process::id()))
    });
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;

    // 1. The writer's ceiling.
    let path = dir.join("ceiling.mcap");
    let mut log = McapLog::create(&path, "bench")?;
    let channels = [
        log.add_controller("display")?,
        log.add_controller("follow")?,
    ];
    let start = Instant::now();
    let mut written = 0u64;
    let mut seq = 0u64;
    while start.elapsed() < args.duration {
        for (i, t) in ticks.iter().enumerate() {
            let mut t = *t;
            seq += 1;
            t.sample.seq = seq;
            log.tick(channels[i % 2], &t)?;
            written += 1;
        }
    }
    log.finish(&[0, 0])?;
    let secs = start.elapsed().as_secs_f64();
    let file_bytes = std::fs::metadata(&path)?.len();
    let ceiling = json!({
        "ticks": written,
        "seconds": secs,
        "ticks_per_s": written as f64 / secs,
        "file_mb_per_s": file_bytes as f64 / secs / 1e6,
        "json_mb_per_s": (written as f64 * json_bytes as f64) / secs / 1e6,
        "file_bytes_per_tick": file_bytes as f64 / written.max(1) as f64,
        "json_bytes_per_tick": json_bytes,
    });

    // 2. The node's path: pump fan-out, bounded streams, the recorder thread.
    let mut sweep = Vec::new();
    let mut best: Option<serde_json::Value> = None;
    let mut k = 1;
    while k <= MAX_CONTROLLERS {
        let r = through_recorder(&dir, k, &ticks, args.duration)?;
        let clean = r["keeps_up"] == true;
        sweep.push(r.clone());
        if !clean {
            break;
        }
        best = Some(r);
        k *= 2;
    }
    // 3. The loops on the real clock beside a recording and a flood of slow readers.
    let flood = match args.flood {
        Some(n) => Some(super::record_flood::measure(&dir, n, args.duration)?),
        None => None,
    };
    if temporary {
        let _ = std::fs::remove_dir_all(&dir);
    }
    let report = json!({
        "sample_ticks": ticks.len(),
        "loops_ticks_per_s": 2000,
        "writer_ceiling": ceiling,
        "recorder_sweep": sweep,
        "recorder_no_drop": best,
        "flood": flood,
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_report(&report);
        if let Some(f) = &flood {
            super::record_flood::print(f);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `k` controllers at 1 kHz each through the pump's fan-out into a [`Recorder`], for
/// `duration`: offered, written and dropped ticks, and the file's rate.
fn through_recorder(
    dir: &std::path::Path,
    k: usize,
    ticks: &[TickRecord],
    duration: Duration,
) -> anyhow::Result<serde_json::Value> {
    let subs = Arc::new(Subscriptions::default());
    let names: Vec<String> = (0..k).map(|i| format!("c{i}")).collect();
    let streams = names
        .iter()
        .map(|n| (n.clone(), subs.record(n, STREAM_CAPACITY)))
        .collect::<Vec<_>>();
    let dropped: Vec<_> = streams.iter().map(|(_, s)| s.dropped.clone()).collect();
    let path = dir.join(format!("recorder-{k}.mcap"));
    let _ = std::fs::remove_file(&path);
    let sources = RecordingSources {
        node: "bench",
        streams,
        links: Vec::new(),
        lifecycle: None,
        clock: &CommonClock::own(),
        node_time: ClockReader::Real,
        scene: SceneConfig::default(),
    };
    let recorder = Recorder::start(RecordProfile::Penelope, &path, None, sources)?;
    let stop = Arc::new(AtomicBool::new(false));
    // The pump: every 10 ms, each controller's ten new ticks (on absolute deadlines, so a
    // late batch does not lower the rate).
    let per_batch = (BATCH.as_millis() as usize).max(1);
    let start = Instant::now();
    let mut offered = 0u64;
    let mut batch: Vec<TickRecord> = Vec::with_capacity(per_batch);
    let mut next = start;
    let mut seq = 0u64;
    let mut cursor = 0usize;
    while start.elapsed() < duration && !stop.load(Ordering::Relaxed) {
        for (i, name) in names.iter().enumerate() {
            batch.clear();
            for j in 0..per_batch {
                // Each controller its own stretch of the sample: identical streams would
                // compress better than real ones do.
                let mut t = ticks[(cursor + j + i * 397) % ticks.len()];
                t.sample.seq = seq + j as u64 + 1;
                batch.push(t);
            }
            subs.publish(name, &batch, 6);
            offered += per_batch as u64;
        }
        seq += per_batch as u64;
        cursor = (cursor + per_batch) % ticks.len();
        next += BATCH;
        if let Some(wait) = next.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
    }
    let fed = start.elapsed().as_secs_f64();
    let written = recorder.finish()?;
    let drained = start.elapsed().as_secs_f64();
    stop.store(true, Ordering::Relaxed);
    let lost: u64 = dropped.iter().map(|d| d.load(Ordering::Relaxed)).sum();
    let bytes = std::fs::metadata(&path)?.len();
    let _ = std::fs::remove_file(&path);
    Ok(json!({
        "controllers": k,
        "offered_ticks_per_s": offered as f64 / fed,
        "written": written,
        "dropped": lost,
        "file_mb_per_s": bytes as f64 / fed / 1e6,
        "drain_s_after_feed": drained - fed,
        "keeps_up": lost == 0 && drained - fed <= KEEP_UP.as_secs_f64(),
    }))
}

fn print_report(r: &serde_json::Value) {
    let c = &r["writer_ceiling"];
    let f = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    println!(
        "recording throughput (the demo's ticks with the plant's truth, {} sampled; JSON {} B/tick, \
         {:.0} B/tick in the file after zstd)",
        r["sample_ticks"],
        c["json_bytes_per_tick"],
        f(&c["file_bytes_per_tick"])
    );
    println!(
        "  writer ceiling (one thread, McapLog): {:.0} ticks/s, {:.1} MB/s to the file ({:.1} MB/s of JSON)",
        f(&c["ticks_per_s"]),
        f(&c["file_mb_per_s"]),
        f(&c["json_mb_per_s"])
    );
    println!("  through the node's recorder (pump fan-out, bounded streams, recorder thread):");
    println!(
        "    {:>11} {:>14} {:>10} {:>9} {:>10} {:>12}",
        "controllers", "offered tick/s", "written", "dropped", "file MB/s", "lag at end"
    );
    for s in r["recorder_sweep"].as_array().into_iter().flatten() {
        println!(
            "    {:>11} {:>14.0} {:>10} {:>9} {:>10.2} {:>10.2} s",
            s["controllers"].as_u64().unwrap_or(0),
            f(&s["offered_ticks_per_s"]),
            s["written"].as_u64().unwrap_or(0),
            s["dropped"].as_u64().unwrap_or(0),
            f(&s["file_mb_per_s"]),
            f(&s["drain_s_after_feed"])
        );
    }
    match r["recorder_no_drop"].as_object() {
        Some(b) => println!(
            "  keeps up (no drop) with {} controllers at 1 kHz ({:.0} ticks/s, {:.2} MB/s), beside \
             the demo's loops: {} ticks/s",
            b["controllers"],
            f(&b["offered_ticks_per_s"]),
            f(&b["file_mb_per_s"]),
            r["loops_ticks_per_s"]
        ),
        None => println!("  falls behind already at one controller"),
    }
}
