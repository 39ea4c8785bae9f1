//! End-to-end latencies of a run, read off its recordings, beside their physical limit.
//!
//! Both directions are found by matching what one side received to what the other side
//! measured, exactly (up to rounding), so no clock offset or model enters: the slave's
//! reference moves by the master's tool motion times the scale (rotation keeps lengths), and
//! the master's commanded force is the slave's sensed force times the force gain. Both sides'
//! times are on one clock (one machine: one node, or the namespaces of `penelope bench
//! layout`).
//!
//! The physical limit of one sample is the transport plus the wait for the receiving loop's
//! tick: from the sender's tick to the first tick of the receiver at or after the instant the
//! sample was ready (the sender's tick, its wake-up latency and execution time) plus the
//! transport's one-way trip. The estimate takes the transport's median trip and the sender's
//! recorded times, so when the receiving tick falls within a few microseconds of the instant
//! the sample is ready it can name the tick after the one the sample reached: a sample that
//! reached an earlier tick shows that tick was within reach, and its limit is then its own
//! latency (a limit is never above what was achieved). Two loops on one clock keep the phase they started with, so a run's
//! figures are that phase plus the transport when the handoff is at the limit: the ratio of the
//! measured figure to the limit says how much the architecture adds.

use std::time::Duration;

use nalgebra::Vector3;
use penelope_hal::Timestamp;
use penelope_runtime::objects::tick::TickRecord;
use serde::Serialize;

use super::RunOutput;

/// How far back a match is looked for.
const WINDOW: Duration = Duration::from_millis(200);
/// Master samples a slave may have missed between two it took (newest wins).
const SKIPPED: usize = 12;
/// Relative tolerance of a match (rounding, not physics).
const MATCH: f64 = 1e-9;

/// Percentiles of a set of latencies, µs.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Percentiles {
    /// Median.
    pub p50_us: f64,
    /// 90th percentile.
    pub p90_us: f64,
    /// 99th percentile.
    pub p99_us: f64,
    /// Largest.
    pub max_us: f64,
    /// Values.
    pub samples: usize,
}

impl Percentiles {
    /// Of `values` (µs); zeros when there are none.
    pub fn of(mut values: Vec<f64>) -> Percentiles {
        values.retain(|v| v.is_finite());
        values.sort_by(f64::total_cmp);
        let at = |p: f64| {
            if values.is_empty() {
                return 0.0;
            }
            values[((values.len() - 1) as f64 * p).round() as usize]
        };
        Percentiles {
            p50_us: at(0.5),
            p90_us: at(0.9),
            p99_us: at(0.99),
            max_us: at(1.0),
            samples: values.len(),
        }
    }
}

/// One direction's end-to-end latency beside its physical limit.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct EndToEnd {
    /// Measured: from the sender's control tick to the receiver's tick that used the sample
    /// (flattened in JSON: `p50_us`, ..., `samples` beside `limit` and the ratios).
    #[serde(flatten)]
    pub latency: Percentiles,
    /// The limit of the same samples: the transport plus the wait for the receiving tick.
    pub limit: Percentiles,
    /// Measured over limit at the median (1: at the limit; 0 with no samples).
    pub ratio_p50: f64,
    /// Measured over limit at the 99th percentile.
    pub ratio_p99: f64,
}

impl EndToEnd {
    fn of(pairs: Vec<(f64, f64)>) -> EndToEnd {
        let (latency, limit): (Vec<f64>, Vec<f64>) = pairs.into_iter().unzip();
        let (latency, limit) = (Percentiles::of(latency), Percentiles::of(limit));
        let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
        EndToEnd {
            ratio_p50: ratio(latency.p50_us, limit.p50_us),
            ratio_p99: ratio(latency.p99_us, limit.p99_us),
            latency,
            limit,
        }
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= MATCH * a.abs().max(b.abs()) + 1e-15
}

fn us(later: Timestamp, earlier: Timestamp) -> f64 {
    later.saturating_since(earlier).as_secs_f64() * 1e6
}

/// The ticks of `ticks` (in time order) from [`WINDOW`] before `to` up to `to`.
fn window(ticks: &[TickRecord], to: Timestamp) -> &[TickRecord] {
    let from = Timestamp::from_nanos(to.as_nanos().saturating_sub(WINDOW.as_nanos() as u64));
    let a = ticks.partition_point(|t| t.sample.time < from);
    let b = ticks.partition_point(|t| t.sample.time <= to);
    &ticks[a..b.max(a)]
}

/// The limit for the sample of `sender[k]`, µs: from its tick to the first later tick of
/// `receiver` at or after the instant it was ready (the tick's wake-up latency and execution time, the
/// latter as the next record notes it) plus `transport`. `None` past the receiver's last tick.
fn limit(
    sender: &[TickRecord],
    k: usize,
    receiver: &[TickRecord],
    transport: Duration,
) -> Option<f64> {
    let s = &sender[k].sample;
    let exec = sender
        .get(k + 1)
        .map_or(s.exec_time, |n| n.sample.exec_time);
    let ready = s.time + s.wake_latency + exec + transport;
    // A tick at the sender's own instant cannot use its sample (on a simulated clock both
    // loops tick at the same instants, and nothing is late or takes time).
    let at = receiver.partition_point(|t| t.sample.time < ready || t.sample.time <= s.time);
    receiver.get(at).map(|r| us(r.sample.time, s.time))
}

/// A sample's limit `estimate` against its measured `latency`, µs: a sample that reached a
/// receiving tick after its own but before the estimated one shows that tick was within reach
/// (the estimate's median trip and recorded times can name the tick after it), so its latency is
/// the limit. A sample used at its own instant (0 µs: a simulated clock steps both loops at the
/// same instants) keeps the estimate, which the report shows it is below.
fn within_reach(estimate: f64, latency: f64) -> f64 {
    if latency > 0.0 {
        estimate.min(latency)
    } else {
        estimate
    }
}

/// The index in `ticks` of the record `t` (a member of a window of it).
fn index_of(ticks: &[TickRecord], t: &TickRecord) -> usize {
    ticks.partition_point(|x| x.sample.time < t.sample.time)
}

/// Master motion to slave command, `(latency, limit)` µs: for each new slave reference, the
/// time since the master control tick that measured the pose it was made from, and that
/// sample's limit over a `transport` one-way trip.
pub fn motion_to_command(out: &RunOutput, transport: Duration) -> Vec<(f64, f64)> {
    let scale = out.info.mapping.scale;
    let mut latencies = Vec::new();
    let slave = &out.slave;
    for k in 1..slave.len() {
        let (prev, now) = (&slave[k - 1].sample, &slave[k].sample);
        let step: Vector3<f64> = now.reference_position - prev.reference_position;
        let moved = step.norm() / scale;
        // A new sample that moved the reference measurably (at rest, motions do not identify
        // their sample).
        if moved < 1e-6 {
            continue;
        }
        let master = window(&out.master, now.time);
        // The latest master tick whose motion since an earlier one equals the step.
        let found = (1..master.len()).rev().find(|&j| {
            let p = master[j].sample.tool_position;
            (j.saturating_sub(SKIPPED)..j)
                .any(|i| close((p - master[i].sample.tool_position).norm(), moved))
        });
        if let Some(j) = found {
            let at = index_of(&out.master, &master[j]);
            if let Some(l) = limit(&out.master, at, slave, transport) {
                let latency = us(now.time, master[j].sample.time);
                latencies.push((latency, within_reach(l, latency)));
            }
        }
    }
    latencies
}

/// Slave contact to master force, `(latency, limit)` µs: for each new force the master
/// commands in contact, the time since the slave control tick that sensed it, and that
/// sample's limit over a `transport` one-way trip.
pub fn contact_to_force(out: &RunOutput, transport: Duration) -> Vec<(f64, f64)> {
    let gain = out.info.mapping.force_gain;
    let mut latencies = Vec::new();
    let master = &out.master;
    for k in 1..master.len() {
        let (prev, now) = (&master[k - 1].sample, &master[k].sample);
        let force = now.commanded_wrench.force;
        if force.norm() < 0.5 || force == prev.commanded_wrench.force {
            continue;
        }
        let slave = window(&out.slave, now.time);
        if let Some(s) = slave
            .iter()
            .rev()
            .find(|s| close(s.sample.wrench.force.norm() * gain, force.norm()))
        {
            let at = index_of(&out.slave, s);
            if let Some(l) = limit(&out.slave, at, master, transport) {
                let latency = us(now.time, s.sample.time);
                latencies.push((latency, within_reach(l, latency)));
            }
        }
    }
    latencies
}

/// Both directions of a run beside their limits, the transport's one-way trips given
/// (master to slave, slave to master; zero for a channel of cells on one node).
pub fn end_to_end(out: &RunOutput, transport: (Duration, Duration)) -> (EndToEnd, EndToEnd) {
    (
        EndToEnd::of(motion_to_command(out, transport.0)),
        EndToEnd::of(contact_to_force(out, transport.1)),
    )
}
