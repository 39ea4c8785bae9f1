//! A `trajectory/teleop` channel with both ends on one node and `faults` in its configuration:
//! each direction goes through a seeded delay line, on the simulated clock, deterministic per
//! seed (issue 14's delay channel).

use std::time::Duration;

use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::runs::{DEMO_SYSTEM, Law, RunOptions, RunOutput, run};
use penelope_supervisor::system::SystemFile;

/// The demo's system, its channel given `faults` (TOML) and `fault_seed`.
fn demo_with(faults: Option<&str>, fault_seed: u64) -> SystemFile {
    let mut file = SystemFile::parse(DEMO_SYSTEM).expect("config/demo.toml parses");
    let link = file
        .objects
        .iter_mut()
        .find(|o| o.kind == "trajectory/teleop")
        .expect("the demo has a channel");
    if let Some(f) = faults {
        link.config = format!("{}\nfaults = {f}\nfault_seed = {fault_seed}\n", link.config);
    }
    file
}

fn simulate(file: &SystemFile, law: Law, duration: Duration) -> RunOutput {
    let options = RunOptions {
        duration: Some(duration),
        law: Some(law),
        scale: None,
        seed: 1,
        clock: ClockMode::Simulated,
    };
    run(file, &options, &mut |_| {}).expect("the system runs")
}

/// The lag, ms, at which the slave's reference best follows the master's tool motion during
/// the free-motion sweeps before the clutch (1.0 to 8.5 s): for each candidate lag, the RMS of
/// `slave reference(t) - master tool(t - lag)` less its mean (the mapping's anchor offset); the
/// smallest wins. Identity mapping, scale 1: the slave's reference is the master's motion.
fn best_lag_ms(out: &RunOutput) -> (u64, f64) {
    let start = out.info.start;
    let master: Vec<(Duration, nalgebra::Vector3<f64>)> = out
        .master
        .iter()
        .map(|m| (m.sample.time - start, m.sample.tool_position))
        .collect();
    let master_at = |t: Duration| {
        // The latest master tick at or before t.
        let i = master.partition_point(|(mt, _)| *mt <= t);
        master.get(i.checked_sub(1)?).map(|(_, p)| *p)
    };
    let window = Duration::from_millis(1_000)..Duration::from_millis(8_500);
    let slave: Vec<(Duration, nalgebra::Vector3<f64>)> = out
        .slave
        .iter()
        .map(|s| (s.sample.time - start, s.sample.reference_position))
        .filter(|(t, _)| window.contains(t))
        .collect();
    assert!(slave.len() > 5_000, "slave ticks: {}", slave.len());
    let mut best = (0, f64::INFINITY);
    for lag in 0..=120u64 {
        let d = Duration::from_millis(lag);
        let diffs: Vec<_> = slave
            .iter()
            .filter_map(|(t, r)| Some(r - master_at(t.checked_sub(d)?)?))
            .collect();
        let mean = diffs.iter().sum::<nalgebra::Vector3<f64>>() / diffs.len() as f64;
        let rms = (diffs.iter().map(|e| (e - mean).norm_squared()).sum::<f64>()
            / diffs.len() as f64)
            .sqrt();
        if rms < best.1 {
            best = (lag, rms);
        }
    }
    best
}

#[test]
fn a_fifty_millisecond_delay_shifts_the_slaves_reference_fifty_milliseconds_behind_the_master() {
    let nine = Duration::from_secs(9);
    let plain = simulate(&demo_with(None, 1), Law::ForcePosition, nine);
    let delayed = simulate(
        &demo_with(Some("{ delay_ms = 50 }"), 1),
        Law::ForcePosition,
        nine,
    );
    let (lag0, rms0) = best_lag_ms(&plain);
    let (lag50, rms50) = best_lag_ms(&delayed);
    println!(
        "slave reference behind the master: {lag0} ms without delay (residual {:.3} mm), \
         {lag50} ms with 50 ms (residual {:.3} mm)",
        rms0 * 1e3,
        rms50 * 1e3
    );
    // The communication period is 2 ms: the delay line delivers at the sending end's first
    // tick at or after the release time.
    let added = lag50 as i64 - lag0 as i64;
    assert!(
        (48..=52).contains(&added),
        "the delay line added {added} ms, not 50 ± 2"
    );
    assert!(
        rms50 < 0.5e-3,
        "the delayed reference is the master's motion"
    );
}

#[test]
fn the_same_fault_seed_gives_identical_runs_and_another_seed_another_run() {
    let faults = "{ delay_ms = 20.0, jitter_ms = 10.0, loss = 0.05 }";
    let four = Duration::from_secs(4);
    let a = simulate(&demo_with(Some(faults), 3), Law::ForcePosition, four);
    let b = simulate(&demo_with(Some(faults), 3), Law::ForcePosition, four);
    assert_eq!(a.slave.len(), b.slave.len());
    assert!(
        a.master == b.master && a.slave == b.slave,
        "same seed, different telemetry"
    );
    // The sensor noise's seed is the same: only the delay line's draws differ.
    let c = simulate(&demo_with(Some(faults), 4), Law::ForcePosition, four);
    assert!(
        a.slave != c.slave,
        "another fault seed must draw other delays and losses"
    );
}

#[test]
fn a_clock_offset_on_a_one_node_channel_is_refused() {
    let file = demo_with(Some("{ delay_ms = 5.0, clock_offset_us = 100.0 }"), 1);
    let options = RunOptions {
        duration: Some(Duration::from_millis(100)),
        ..RunOptions::default()
    };
    let err = run(&file, &options, &mut |_| {})
        .err()
        .expect("refused")
        .to_string();
    assert!(err.contains("clock_offset_us"), "{err}");
}
