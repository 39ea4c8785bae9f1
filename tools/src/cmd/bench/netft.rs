//! `penelope bench netft`: the Net F/T driver against its emulator on loopback, at each rate
//! asked: records sent by the emulator beside records the driver received and published
//! (and missed, by RDT sequence), and the time from the emulator taking a sample to the
//! driver's cell holding it (UDP on loopback plus the I/O thread).
//!
//! The latency is measured in one process on one clock: the emulator's contact model stamps
//! each sample it produces (one per record) into a table indexed by RDT sequence; a reader
//! polls the driver's newest sample and subtracts. Polling sees most samples, not all, so the
//! percentiles are over the samples seen.

use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use penelope_drivers::netft::emulator::{EmulatorConfig, MAX_RATE_HZ, NetFtEmulator};
use penelope_drivers::netft::{NetFt, NetFtConfig};
use penelope_rt_core::clock::MonotonicClock;
use serde_json::json;

use crate::cmd::usage;

/// Options.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Emulator rates to run, Hz (each 1..=7000).
    #[arg(long, value_delimiter = ',', default_value = "1000,7000")]
    pub rates: Vec<f64>,
    /// Seconds per rate.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Print one JSON object per rate instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Slots of the send-time table (a few seconds at the top rate; a slot is reused after that).
const SLOTS: usize = 1 << 16;

/// Runs the benchmark.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if !(args.seconds.is_finite() && (0.1..=600.0).contains(&args.seconds)) {
        return Err(usage("--seconds must be 0.1..=600"));
    }
    if args.rates.is_empty()
        || !args
            .rates
            .iter()
            .all(|r| r.is_finite() && (1.0..=MAX_RATE_HZ).contains(r))
    {
        return Err(usage("--rates must be 1..=7000 Hz each"));
    }
    if !args.json {
        println!(
            "rate (Hz)   sent    received  missed  received/sent  received rate (Hz)   latency p50 / p99 / max (µs)"
        );
    }
    for &rate in &args.rates {
        let r = one_rate(rate, Duration::from_secs_f64(args.seconds))?;
        if args.json {
            println!("{}", r);
        } else {
            println!(
                "{:>9.0} {:>7} {:>10} {:>7} {:>14.4} {:>19.1}   {:>6.1} / {:>6.1} / {:>7.1}",
                rate,
                r["sent"].as_u64().unwrap_or(0),
                r["received"].as_u64().unwrap_or(0),
                r["missed"].as_u64().unwrap_or(0),
                r["received_over_sent"].as_f64().unwrap_or(f64::NAN),
                r["received_rate_hz"].as_f64().unwrap_or(f64::NAN),
                r["latency_us"]["p50"].as_f64().unwrap_or(f64::NAN),
                r["latency_us"]["p99"].as_f64().unwrap_or(f64::NAN),
                r["latency_us"]["max"].as_f64().unwrap_or(f64::NAN),
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn one_rate(rate: f64, length: Duration) -> anyhow::Result<serde_json::Value> {
    let sent_at: Arc<Vec<AtomicU64>> = Arc::new((0..SLOTS).map(|_| AtomicU64::new(0)).collect());
    let table = sent_at.clone();
    let mut produced: u64 = 0;
    // One call per record: the first record is RDT sequence 1.
    let source = move |_t: Duration| {
        produced += 1;
        table[(produced as usize) % SLOTS]
            .store(MonotonicClock::read().as_nanos(), Ordering::Relaxed);
        [0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
    };
    let emu = NetFtEmulator::spawn(
        EmulatorConfig {
            rate_hz: rate,
            ..EmulatorConfig::default()
        },
        source,
    )?;
    let ft = NetFt::open(NetFtConfig::new(emu.local_addr()))?;
    anyhow::ensure!(
        ft.wait_for_records(1, Duration::from_secs(5)),
        "no record from the emulator"
    );
    let start = Instant::now();
    let first = ft.counters();
    let mut latencies = Vec::new();
    let mut last_seq = 0u32;
    while start.elapsed() < length {
        if let Some(s) = ft.latest()
            && s.rdt_sequence != last_seq
        {
            last_seq = s.rdt_sequence;
            let sent = sent_at[(s.rdt_sequence as usize) % SLOTS].load(Ordering::Relaxed);
            if sent > 0 && s.stamp.as_nanos() >= sent {
                latencies.push((s.stamp.as_nanos() - sent) as f64 / 1e3);
            }
        }
        std::thread::sleep(Duration::from_micros(50));
    }
    let seconds = start.elapsed().as_secs_f64();
    let sent_before = emu.counters().sent;
    let c = ft.counters();
    ft.stop();
    let e = emu.counters();
    emu.stop();
    let received = c.records - first.records;
    latencies.sort_by(f64::total_cmp);
    let pct = |p: f64| -> f64 {
        if latencies.is_empty() {
            return f64::NAN;
        }
        latencies[((latencies.len() - 1) as f64 * p).round() as usize]
    };
    Ok(json!({
        "rate_hz": rate,
        "seconds": seconds,
        "sent": e.sent,
        "received": c.records,
        "missed": c.missed,
        "malformed": c.malformed,
        "received_over_sent": c.records as f64 / sent_before.max(1) as f64,
        "received_rate_hz": received as f64 / seconds,
        "latency_us": {
            "samples": latencies.len(),
            "p50": pct(0.5),
            "p99": pct(0.99),
            "max": pct(1.0),
        },
    }))
}
