//! The delay line of a `trajectory/teleop` channel whose two ends are on this node: what one end
//! sends reaches the other's latest-value cell `delay ± jitter` later, some of it lost, as the
//! data plane's seeded fault layer ([`FaultyLink`]) would have delivered it between two nodes.
//! So every law runs against the same delays on the simulated clock, deterministic per seed.
//!
//! The line is driven by the sending end's communication ticks: each tick puts the new sample
//! in and writes every sample now due into the cell (in release order; the receiving channel
//! drops one older than what it already has, as it does for reordered datagrams). A sample is
//! therefore delivered at the first sending tick at or after its release time: within one
//! communication period of `delay + jitter`.

use std::time::Duration;

use penelope_hal::Timestamp;
use penelope_rt_core::cell::ArcLatestWriter;
use penelope_rt_core::teleop::TeleopSample;

use crate::dataplane::faults::{FaultConfig, FaultConfigError, FaultCounters, FaultyLink};

/// The shortest communication period a loop may have (`comm_period_us` = 250): the rate the
/// line's queue is sized for.
const FASTEST_SAMPLE_PERIOD: Duration = Duration::from_micros(250);

/// The most samples a line holds at once, whatever its delay (about 17 MB of samples): a
/// longer delay at the fastest rate drops what does not fit, counted in
/// [`FaultCounters::dropped_capacity`].
pub const MAX_DELAY_LINE_CAPACITY: usize = 1 << 16;

/// One direction of a channel on this node, through injected faults.
pub struct DelayLine {
    link: FaultyLink<TeleopSample>,
}

impl DelayLine {
    /// A line with the faults of `config`, drawn from a generator seeded with `seed`. Its
    /// queue is made here, large enough for the configured delay and jitter (plus a reorder
    /// hold) at the fastest communication rate, each sample possibly duplicated, up to
    /// [`MAX_DELAY_LINE_CAPACITY`].
    ///
    /// # Errors
    /// The errors of [`FaultConfig::validate`].
    pub fn new(config: &FaultConfig, seed: u64) -> Result<Self, FaultConfigError> {
        config.validate()?;
        let span = Duration::from_secs_f64((config.delay_ms + config.jitter_ms) / 1e3)
            + crate::dataplane::faults::REORDER_HOLD_LIMIT;
        let in_flight = span.as_nanos() / FASTEST_SAMPLE_PERIOD.as_nanos() + 1;
        let copies = if config.duplicate > 0.0 { 2 } else { 1 };
        let capacity = usize::try_from(in_flight * copies + 8)
            .unwrap_or(usize::MAX)
            .min(MAX_DELAY_LINE_CAPACITY);
        Ok(DelayLine {
            link: FaultyLink::new(config, seed, capacity)?,
        })
    }

    /// Puts `sample` (sent at `sample.sent`) on the line and writes every sample due by then
    /// into `cell`.
    ///
    /// # Real-time
    /// No allocation (the queue was made with its capacity; beyond it a sample is dropped and
    /// counted), no locks: a few random draws, a heap push, and pops with cell writes.
    pub fn send(&mut self, sample: TeleopSample, cell: &mut ArcLatestWriter<TeleopSample>) {
        let now = since_origin(sample.sent);
        self.link.send(now, sample);
        while let Some(due) = self.link.poll(now) {
            cell.write(due);
        }
    }

    /// What the faults did so far.
    pub fn counters(&self) -> FaultCounters {
        self.link.counters()
    }

    /// Samples on their way.
    pub fn in_flight(&self) -> usize {
        self.link.in_flight()
    }

    /// The most samples the line holds at once.
    pub fn capacity(&self) -> usize {
        self.link.capacity()
    }
}

/// A node's time as the line's time since its origin (the clock's zero: outage windows in a
/// fault configuration are seconds of the node's clock).
fn since_origin(t: Timestamp) -> Duration {
    Duration::from_nanos(t.as_nanos())
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_hal::{JointReference, JointVector, Reference};
    use penelope_rt_core::cell::{Fresh, latest};

    fn sample(k: u64, period_ms: u64) -> TeleopSample {
        TeleopSample::new(
            k,
            Timestamp::from_nanos(k * period_ms * 1_000_000),
            Reference::Joint(JointReference {
                position: JointVector::repeat(k as f64),
                ..JointReference::default()
            }),
        )
    }

    /// Feeds 500 samples, one every 2 ms, and returns (send tick, sequence) of what the
    /// receiving cell held new after each tick.
    fn deliveries(config: &FaultConfig, seed: u64) -> Vec<(u64, u64)> {
        let mut line = DelayLine::new(config, seed).unwrap();
        let (mut w, mut r) = latest::<TeleopSample>();
        let mut got = Vec::new();
        for k in 1..=500 {
            line.send(sample(k, 2), &mut w);
            if let Fresh::New(s) = r.read() {
                got.push((k, s.sequence));
            }
        }
        got
    }

    #[test]
    fn a_constant_delay_delivers_each_sample_that_much_later() {
        let config = FaultConfig {
            delay_ms: 50.0,
            ..FaultConfig::default()
        };
        let got = deliveries(&config, 1);
        // 50 ms is 25 periods of 2 ms: sample k arrives at tick k + 25, none before tick 26.
        assert_eq!(got.first(), Some(&(26, 1)));
        assert!(got.iter().all(|&(tick, seq)| tick == seq + 25), "{got:?}");
        assert_eq!(got.len(), 475);
    }

    #[test]
    fn jitter_and_loss_are_the_same_for_a_seed_and_differ_for_another() {
        let config = FaultConfig {
            delay_ms: 20.0,
            jitter_ms: 10.0,
            loss: 0.1,
            ..FaultConfig::default()
        };
        let a = deliveries(&config, 7);
        assert_eq!(a, deliveries(&config, 7));
        assert_ne!(a, deliveries(&config, 8));
        // Every delivery is 20..=32 ms late (jitter, rounded up to the next 2 ms tick).
        for &(tick, seq) in &a {
            let late_ms = (tick - seq) * 2;
            assert!(
                (20..=32).contains(&late_ms),
                "{seq} arrived {late_ms} ms late"
            );
        }
        assert!(
            a.len() < 480,
            "about a tenth lost: {} of 500 arrived",
            a.len()
        );
    }

    #[test]
    fn the_queue_is_sized_for_the_delay() {
        let config = FaultConfig {
            delay_ms: 100.0,
            ..FaultConfig::default()
        };
        let line = DelayLine::new(&config, 1).unwrap();
        // (100 + 50 ms hold) / 0.25 ms + 1 + 8.
        assert_eq!(line.capacity(), 609);
        let huge = FaultConfig {
            delay_ms: 60_000.0,
            ..FaultConfig::default()
        };
        assert_eq!(
            DelayLine::new(&huge, 1).unwrap().capacity(),
            MAX_DELAY_LINE_CAPACITY
        );
    }
}
