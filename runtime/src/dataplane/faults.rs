//! Seeded link faults for datagrams, because these machines have no netem: a [`FaultyLink`]
//! sits between a sender and the socket (or stands for the network in a test) and delays,
//! jitters, loses, duplicates, reorders and cuts what passes through it, as its
//! [`FaultConfig`] says.
//!
//! Every decision is drawn from a ChaCha8 generator seeded by the caller, a fixed number of
//! draws per item sent: the same seed, configuration and calls give the same faults, so a
//! failing run can be replayed. Times are [`Duration`]s since an origin the caller chooses
//! (the start of the run); outage windows are measured from the same origin.
//!
//! What an item goes through, in order, when sent at `now`:
//!
//! 1. sent inside an outage window (`from_s <= now < to_s`): dropped;
//! 2. lost with probability `loss`;
//! 3. scheduled for release at `now + delay + U(0, jitter)` (so jitter alone may reorder
//!    items sent closer together than the jitter);
//! 4. with probability `duplicate`, a second copy scheduled the same way with its own jitter;
//! 5. with probability `reorder`, held back: released just after the next item sent (at the
//!    later of the two release times), or, if none comes, [`REORDER_HOLD_LIMIT`] after its own
//!    release time. One item is held at a time, and the item that passes it is not held in
//!    turn, so a `reorder` of p holds back a share p / (1 + p) of a steady stream.
//!
//! The link holds at most `capacity` items (held item included); copies beyond it are
//! dropped and counted. Its queue is allocated once, when the link is made.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::time::Duration;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

/// The longest `delay_ms` and `jitter_ms` accepted: one minute.
pub const MAX_DELAY_MS: f64 = 60_000.0;

/// The latest outage bound accepted, s (about 115 days).
pub const MAX_OUTAGE_S: f64 = 10_000_000.0;

/// How long past its own release time a held-back item waits for a next item to pass it.
pub const REORDER_HOLD_LIMIT: Duration = Duration::from_millis(50);

/// The faults of one direction of a link, as written in a system file or a test (TOML):
///
/// ```toml
/// delay_ms = 2.0
/// jitter_ms = 5.0
/// loss = 0.01
/// duplicate = 0.001
/// reorder = 0.01
/// outages = [{ from_s = 10.0, to_s = 12.5 }]
/// clock_offset_us = 3700.0
/// ```
///
/// Every key is optional (zero: no fault); unknown keys are refused. `clock_offset_us` is not a
/// fault of the link but of the end that sends: its clock reads that much ahead (negative:
/// behind) in every time it stamps, so that heartbeats have an offset to find on one host.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, serde::Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct FaultConfig {
    /// Fixed delay added to every item, ms, 0..=60000 (`MAX_DELAY_MS`).
    pub delay_ms: f64,
    /// Upper bound of the uniform extra delay, ms, 0..=60000 (`MAX_DELAY_MS`).
    pub jitter_ms: f64,
    /// Probability an item is lost, in `0..=1`.
    pub loss: f64,
    /// Probability an item is delivered twice, in `0..=1`.
    pub duplicate: f64,
    /// Probability an item is held back past the next one, in `0..=1`.
    pub reorder: f64,
    /// Windows in which every item sent is dropped.
    pub outages: Vec<OutageWindow>,
    /// How far ahead the sending end's clock reads, µs, -1e7..=1e7 (`MAX_CLOCK_OFFSET_US`, 10 s
    /// either way).
    pub clock_offset_us: f64,
}

/// The largest injected clock offset, µs (10 s either way).
pub const MAX_CLOCK_OFFSET_US: f64 = 10_000_000.0;

/// A window of time in which the link carries nothing: items sent at `from_s <= t < to_s`
/// are dropped.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, serde::Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OutageWindow {
    /// Start, s since the link's origin (inclusive).
    pub from_s: f64,
    /// End, s since the link's origin (exclusive).
    pub to_s: f64,
}

/// Why a fault configuration was refused; names the key at fault.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FaultConfigError {
    /// Not TOML, a key of the wrong type, or an unknown key.
    #[error("fault configuration: {message}")]
    Parse {
        /// The TOML parser's message (it names the key).
        message: String,
    },
    /// A value outside its range, or not a number.
    #[error("`{key}` = {value}: must be {expected}")]
    OutOfRange {
        /// The key, e.g. `loss` or `outages[1].to_s`.
        key: String,
        /// The value given.
        value: f64,
        /// The range it must be in.
        expected: &'static str,
    },
    /// An outage window that ends before it starts, or ends as it starts.
    #[error("`{key}`: from_s = {from_s} is not before to_s = {to_s}")]
    EmptyOutage {
        /// The window, e.g. `outages[1]`.
        key: String,
        /// Its start, s.
        from_s: f64,
        /// Its end, s.
        to_s: f64,
    },
}

impl FaultConfig {
    /// Parses and validates a fault configuration written in TOML.
    ///
    /// # Errors
    /// [`FaultConfigError::Parse`] for bad TOML, wrong types and unknown keys; the errors of
    /// [`validate`](Self::validate) otherwise.
    pub fn from_toml(text: &str) -> Result<FaultConfig, FaultConfigError> {
        let config: FaultConfig = toml::from_str(text).map_err(|e| FaultConfigError::Parse {
            message: e.to_string(),
        })?;
        config.validate()?;
        Ok(config)
    }

    /// The injected clock offset, ns (rounded).
    pub fn clock_offset_ns(&self) -> i64 {
        (self.clock_offset_us * 1_000.0).round() as i64
    }

    /// Checks every value is in its range.
    ///
    /// # Errors
    /// [`FaultConfigError::OutOfRange`] for the first value out of range (NaN included),
    /// [`FaultConfigError::EmptyOutage`] for a window that does not end after it starts.
    pub fn validate(&self) -> Result<(), FaultConfigError> {
        let delays = "a number of milliseconds in 0..=60000";
        check("delay_ms", self.delay_ms, MAX_DELAY_MS, delays)?;
        check("jitter_ms", self.jitter_ms, MAX_DELAY_MS, delays)?;
        let probability = "a probability in 0..=1";
        check("loss", self.loss, 1.0, probability)?;
        check("duplicate", self.duplicate, 1.0, probability)?;
        check("reorder", self.reorder, 1.0, probability)?;
        let offset = self.clock_offset_us;
        if !(-MAX_CLOCK_OFFSET_US..=MAX_CLOCK_OFFSET_US).contains(&offset) {
            return Err(FaultConfigError::OutOfRange {
                key: "clock_offset_us".to_owned(),
                value: offset,
                expected: "a number of microseconds in -10000000..=10000000",
            });
        }
        let seconds = "a number of seconds in 0..=10000000";
        for (index, window) in self.outages.iter().enumerate() {
            let key = |field: &str| format!("outages[{index}].{field}");
            check(&key("from_s"), window.from_s, MAX_OUTAGE_S, seconds)?;
            check(&key("to_s"), window.to_s, MAX_OUTAGE_S, seconds)?;
            if window.from_s >= window.to_s {
                return Err(FaultConfigError::EmptyOutage {
                    key: format!("outages[{index}]"),
                    from_s: window.from_s,
                    to_s: window.to_s,
                });
            }
        }
        Ok(())
    }
}

/// `value` must be a number in `0..=max`.
fn check(key: &str, value: f64, max: f64, expected: &'static str) -> Result<(), FaultConfigError> {
    if (0.0..=max).contains(&value) {
        Ok(())
    } else {
        Err(FaultConfigError::OutOfRange {
            key: key.to_owned(),
            value,
            expected,
        })
    }
}

/// What a [`FaultyLink`] did, since it was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultCounters {
    /// Items given to [`FaultyLink::send`].
    pub sent: u64,
    /// Items lost (the `loss` draw).
    pub dropped_loss: u64,
    /// Items sent during an outage window.
    pub dropped_outage: u64,
    /// Copies refused because the link held `capacity` items.
    pub dropped_capacity: u64,
    /// Items given a second copy.
    pub duplicated: u64,
    /// Held-back items released after the item sent after them (not counting those released
    /// by [`REORDER_HOLD_LIMIT`], nor the reordering jitter alone causes).
    pub reordered: u64,
    /// Copies returned by [`FaultyLink::poll`].
    pub delivered: u64,
}

/// A copy on its way: released at `release_ns`, ties broken by scheduling order.
#[derive(Debug)]
struct Scheduled<T> {
    release_ns: u64,
    order: u64,
    item: T,
}

impl<T> Scheduled<T> {
    fn key(&self) -> (u64, u64) {
        (self.release_ns, self.order)
    }
}

impl<T> PartialEq for Scheduled<T> {
    fn eq(&self, other: &Self) -> bool {
        self.key() == other.key()
    }
}

impl<T> Eq for Scheduled<T> {}

impl<T> PartialOrd for Scheduled<T> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl<T> Ord for Scheduled<T> {
    /// Reversed, so that the max-heap [`BinaryHeap`] yields the earliest release first.
    fn cmp(&self, other: &Self) -> Ordering {
        other.key().cmp(&self.key())
    }
}

/// The configuration in the units the link works in.
#[derive(Clone, Debug)]
struct Faults {
    delay_ns: u64,
    jitter_ns: u64,
    loss: f64,
    duplicate: f64,
    reorder: f64,
    /// `[from, to)`, ns since the origin.
    outages_ns: Vec<(u64, u64)>,
}

/// One direction of a link with faults: items go in with [`send`](Self::send) and come out
/// of [`poll`](Self::poll) when their release time has come, in release order.
#[derive(Debug)]
pub struct FaultyLink<T> {
    faults: Faults,
    rng: ChaCha8Rng,
    capacity: usize,
    queue: BinaryHeap<Scheduled<T>>,
    /// The item held back until the next one passes it.
    held: Option<Scheduled<T>>,
    next_order: u64,
    counters: FaultCounters,
}

impl<T: Clone> FaultyLink<T> {
    /// A link with the faults of `config`, drawn from a generator seeded with `seed`, holding
    /// at most `capacity` items at once.
    ///
    /// # Errors
    /// The errors of [`FaultConfig::validate`].
    pub fn new(config: &FaultConfig, seed: u64, capacity: usize) -> Result<Self, FaultConfigError> {
        config.validate()?;
        let nanos = |seconds: f64| (seconds * 1e9).round() as u64;
        let faults = Faults {
            delay_ns: nanos(config.delay_ms / 1e3),
            jitter_ns: nanos(config.jitter_ms / 1e3),
            loss: config.loss,
            duplicate: config.duplicate,
            reorder: config.reorder,
            outages_ns: config
                .outages
                .iter()
                .map(|w| (nanos(w.from_s), nanos(w.to_s)))
                .collect(),
        };
        Ok(FaultyLink {
            faults,
            rng: ChaCha8Rng::seed_from_u64(seed),
            capacity,
            queue: BinaryHeap::with_capacity(capacity),
            held: None,
            next_order: 0,
            counters: FaultCounters::default(),
        })
    }

    /// Sends `item` at `now` (since the link's origin): drops it, or schedules it (and maybe
    /// a copy) for release, as the faults draw.
    pub fn send(&mut self, now: Duration, item: T) {
        self.counters.sent += 1;
        // the same draws for every item, whatever the outcome, so one fault's pattern does
        // not depend on the others' settings
        let lose: f64 = self.rng.random();
        let duplicate: f64 = self.rng.random();
        let hold: f64 = self.rng.random();
        let jitter: f64 = self.rng.random();
        let copy_jitter: f64 = self.rng.random();

        let now_ns = nanos_of(now);
        let in_outage = self
            .faults
            .outages_ns
            .iter()
            .any(|&(from, to)| (from..to).contains(&now_ns));
        if in_outage {
            self.counters.dropped_outage += 1;
            return;
        }
        if lose < self.faults.loss {
            self.counters.dropped_loss += 1;
            return;
        }
        let release_ns = self.release_time(now_ns, jitter);
        let copy = if duplicate < self.faults.duplicate {
            self.counters.duplicated += 1;
            Some(Scheduled {
                release_ns: self.release_time(now_ns, copy_jitter),
                order: self.take_order(),
                item: item.clone(),
            })
        } else {
            None
        };
        let scheduled = Scheduled {
            release_ns,
            order: self.take_order(),
            item,
        };
        if self.in_flight() < self.capacity {
            // the item held back goes out just after this one, which is not held in turn
            let was_holding = if let Some(mut held) = self.held.take() {
                held.release_ns = held.release_ns.max(release_ns);
                held.order = self.take_order();
                self.counters.reordered += 1;
                self.queue.push(held);
                true
            } else {
                false
            };
            if !was_holding && hold < self.faults.reorder {
                self.held = Some(scheduled);
            } else {
                self.queue.push(scheduled);
            }
        } else {
            self.counters.dropped_capacity += 1;
        }
        if let Some(copy) = copy {
            if self.in_flight() < self.capacity {
                self.queue.push(copy);
            } else {
                self.counters.dropped_capacity += 1;
            }
        }
    }

    /// The next item whose release time is at or before `now`, earliest release first; `None`
    /// if none is due.
    pub fn poll(&mut self, now: Duration) -> Option<T> {
        let now_ns = nanos_of(now);
        let hold_limit_ns = nanos_of(REORDER_HOLD_LIMIT);
        if self
            .held
            .as_ref()
            .is_some_and(|h| h.release_ns.saturating_add(hold_limit_ns) <= now_ns)
            && let Some(mut held) = self.held.take()
        {
            held.release_ns = held.release_ns.saturating_add(hold_limit_ns);
            self.queue.push(held);
        }
        if self.queue.peek()?.release_ns > now_ns {
            return None;
        }
        let due = self.queue.pop()?;
        self.counters.delivered += 1;
        Some(due.item)
    }

    /// When the next item will be due (since the link's origin), if any is on its way: how
    /// long a communication thread may sleep.
    pub fn next_release(&self) -> Option<Duration> {
        let queued = self.queue.peek().map(|s| s.release_ns);
        let held = self
            .held
            .as_ref()
            .map(|h| h.release_ns.saturating_add(nanos_of(REORDER_HOLD_LIMIT)));
        let earliest = match (queued, held) {
            (Some(a), Some(b)) => a.min(b),
            (a, b) => a.or(b)?,
        };
        Some(Duration::from_nanos(earliest))
    }

    /// Items on their way (the held-back one included).
    pub fn in_flight(&self) -> usize {
        self.queue.len() + usize::from(self.held.is_some())
    }

    /// The most items the link holds at once.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// What the link did so far.
    pub fn counters(&self) -> FaultCounters {
        self.counters
    }

    /// `now + delay + U(0, jitter)` for a uniform draw `unit` in `0..1`.
    fn release_time(&self, now_ns: u64, unit: f64) -> u64 {
        let jitter_ns = (unit * self.faults.jitter_ns as f64) as u64;
        now_ns
            .saturating_add(self.faults.delay_ns)
            .saturating_add(jitter_ns.min(self.faults.jitter_ns))
    }

    fn take_order(&mut self) -> u64 {
        let order = self.next_order;
        self.next_order += 1;
        order
    }
}

/// `duration` in nanoseconds, saturated to 64 bits.
fn nanos_of(duration: Duration) -> u64 {
    u64::try_from(duration.as_nanos()).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests;
