//! The system's common clock: the clock of the host that serves the naming service
//! (`CLOCK_MONOTONIC` there), which every node reaches already.
//!
//! Each host's monotonic clock counts from its own boot, so times taken on two hosts cannot be
//! compared as they are. A node whose naming service is on another host estimates that host's
//! clock less its own with the four-timestamp exchange of the data plane's heartbeats
//! ([`LinkClock`]: the offset of the exchange with the least round trip among the last
//! eight), carried by [`Call::Time`] on the connection the node already keeps to the naming
//! service: eight exchanges when it registers, then one with every lease renewal. A recording
//! stamps its messages' log times with it, so that the recordings of several hosts play on one
//! time line.
//!
//! A node that hosts the naming service, or runs on a simulated clock, or has no naming service,
//! is its own common clock (offset zero, exactly): a simulated clock has nothing to agree with.
//!
//! The estimate is as good as NTP's over the same path: half the difference between the two
//! directions' delays, tens of microseconds between hosts on one switch, which is well under a
//! control period.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex, PoisonError};

use penelope_rt_core::clock::MonotonicClock;
use penelope_rt_core::exec::CommonOffset;
use serde::Serialize;

use penelope_protocol::link_clock::{ClockError, LinkClock};
use penelope_protocol::proto::{Reply, WireError};

#[cfg(doc)]
use penelope_protocol::proto::Call;

/// Exchanges made when a node registers, back to back, so that its first recording starts
/// on a filtered estimate.
pub const EXCHANGES_AT_REGISTRATION: usize = 8;

/// Why an exchange of times gave nothing.
#[derive(Debug, thiserror::Error)]
pub enum ExchangeError {
    /// The other host did not answer with its times.
    #[error("no answer: {0}")]
    Asked(#[from] WireError),
    /// Its times are ones no real exchange gives.
    #[error(transparent)]
    Refused(#[from] ClockError),
}

/// Where a node's common clock is.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case", tag = "source")]
pub enum ClockSource {
    /// This node's own clock: it hosts the naming service, runs on a simulated clock, or has
    /// no naming service.
    Own,
    /// The clock of the naming service at this address.
    Naming {
        /// The naming service's address.
        address: SocketAddr,
    },
}

/// The estimate of the common clock less this node's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ClockEstimate {
    /// The common clock less this node's, ns (`None` before the first exchange).
    pub offset_ns: Option<i64>,
    /// The round trip of the exchange it comes from, ns (`None` on a node's own clock).
    pub round_trip_ns: Option<i64>,
    /// The RMS of the kept exchanges' offsets around it, ns.
    pub jitter_ns: Option<i64>,
    /// Exchanges accepted so far.
    pub exchanges: u64,
}

/// A node's view of the common clock (shared: cloning shares the estimate). Not for the
/// real-time threads: it locks; they read the offset from [`offset_cell`](Self::offset_cell).
#[derive(Clone, Debug)]
pub struct CommonClock {
    source: ClockSource,
    estimate: Arc<Mutex<Exchanges>>,
    /// The newest offset estimate, published for the loops' tick phases (zero before the
    /// first, as [`to_common`](Self::to_common) takes it).
    offset: Arc<CommonOffset>,
}

#[derive(Debug, Default)]
struct Exchanges {
    clock: LinkClock,
    next: u64,
}

impl CommonClock {
    /// This node's own clock is the common one.
    pub fn own() -> Self {
        Self::from(ClockSource::Own)
    }

    /// The naming service's at `address`, to be estimated with [`exchange`](Self::exchange).
    pub fn of_naming(address: SocketAddr) -> Self {
        Self::from(ClockSource::Naming { address })
    }

    fn from(source: ClockSource) -> Self {
        CommonClock {
            source,
            estimate: Arc::new(Mutex::new(Exchanges::default())),
            offset: Arc::new(CommonOffset::default()),
        }
    }

    /// The offset estimate (the common clock less this node's, ns), lock-free: what a periodic
    /// thread with a [`TickPhase`](penelope_rt_core::exec::TickPhase) places its ticks with.
    /// Every accepted exchange publishes its new estimate there.
    pub fn offset_cell(&self) -> Arc<CommonOffset> {
        self.offset.clone()
    }

    /// Where the common clock is.
    pub fn source(&self) -> &ClockSource {
        &self.source
    }

    /// One exchange: reads this node's clock (`t1`), asks the other host with `ask` for its
    /// receive and answer times (`t2`, `t3`, from [`Reply::Time`]), reads this node's clock
    /// again (`t4`), and takes them into the estimate. Nothing is asked on a node's own clock.
    ///
    /// # Errors
    /// [`ExchangeError`]: `ask` failed, or the times are ones no real exchange gives (counted,
    /// and the estimate left as it was).
    pub fn exchange(
        &self,
        ask: impl FnOnce() -> Result<(i64, i64), WireError>,
    ) -> Result<(), ExchangeError> {
        self.exchange_with(monotonic_ns, ask)
    }

    /// [`exchange`](Self::exchange) with this node's clock read from `now`.
    ///
    /// # Errors
    /// As [`exchange`](Self::exchange).
    pub fn exchange_with(
        &self,
        mut now: impl FnMut() -> i64,
        ask: impl FnOnce() -> Result<(i64, i64), WireError>,
    ) -> Result<(), ExchangeError> {
        if self.source == ClockSource::Own {
            return Ok(());
        }
        let t1 = now();
        let (t2, t3) = ask()?;
        let t4 = now();
        let mut e = self.estimate.lock().unwrap_or_else(PoisonError::into_inner);
        let seq = e.next;
        e.next += 1;
        e.clock.note_sent(seq, t1);
        e.clock.note_answer(seq, t2, t3, t4)?;
        if let Some(offset) = e.clock.offset() {
            self.offset.set(offset);
        }
        Ok(())
    }

    /// The estimate now.
    pub fn estimate(&self) -> ClockEstimate {
        if self.source == ClockSource::Own {
            return ClockEstimate {
                offset_ns: Some(0),
                ..ClockEstimate::default()
            };
        }
        let e = self.estimate.lock().unwrap_or_else(PoisonError::into_inner);
        ClockEstimate {
            offset_ns: e.clock.offset(),
            round_trip_ns: e.clock.delay(),
            jitter_ns: e.clock.jitter(),
            exchanges: e.clock.counts().accepted,
        }
    }

    /// Node time `node_ns` on the common clock, ns (as it is before the first estimate).
    pub fn to_common(&self, node_ns: u64) -> u64 {
        let offset = self.estimate().offset_ns.unwrap_or(0);
        node_ns.saturating_add_signed(offset)
    }
}

/// The answer to [`Call::Time`]: this host's monotonic clock now, as both the receive and the
/// answer time (the turnaround between them is a few microseconds of the server's own work,
/// which counts as round trip).
pub fn time_reply() -> Reply {
    let now = monotonic_ns();
    Reply::Time {
        received_ns: now,
        sent_ns: now,
    }
}

fn monotonic_ns() -> i64 {
    i64::try_from(MonotonicClock::read().as_nanos()).unwrap_or(i64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_host_ahead_by_a_known_amount_is_found_to_half_the_path_asymmetry() {
        let clock = CommonClock::of_naming("127.0.0.1:7000".parse().unwrap());
        assert_eq!(clock.estimate().offset_ns, None);
        // The naming host's clock reads 3.7 s ahead; each exchange takes 60 µs out and 40 µs
        // back, the server turning around in 5 µs; the first two exchanges queue 2 ms more.
        let ahead = 3_700_000_000i64;
        let mut t = 1_000_000_000i64;
        for k in 0..EXCHANGES_AT_REGISTRATION as i64 {
            let queued = if k < 2 { 2_000_000 } else { 0 };
            let mut reads = [t, t + 60_000 + queued + 5_000 + 40_000].into_iter();
            clock
                .exchange_with(
                    || reads.next().unwrap(),
                    || {
                        let t2 = t + 60_000 + queued + ahead;
                        Ok((t2, t2 + 5_000))
                    },
                )
                .unwrap();
            t += 1_000_000_000;
        }
        let e = clock.estimate();
        assert_eq!(e.exchanges, EXCHANGES_AT_REGISTRATION as u64);
        assert_eq!(
            e.round_trip_ns,
            Some(100_000),
            "the unqueued exchanges chosen"
        );
        // Off by half the asymmetry: (60 - 40) / 2 µs.
        assert_eq!(e.offset_ns, Some(ahead + 10_000));
        assert_eq!(clock.to_common(5), 5 + (ahead + 10_000) as u64);
        // Published for the loops' tick phases, to every clone.
        assert_eq!(clock.clone().offset_cell().get(), ahead + 10_000);
        // A forged answer (received before it was asked) is refused; the estimate stays.
        let mut reads = [t, t + 100].into_iter();
        let forged = clock.exchange_with(|| reads.next().unwrap(), || Ok((t + 50, t + 10)));
        assert!(forged.is_err());
        assert_eq!(clock.estimate().offset_ns, Some(ahead + 10_000));
    }

    #[test]
    fn a_nodes_own_clock_is_the_common_one_exactly_and_asks_nothing() {
        let clock = CommonClock::own();
        let asked = clock.exchange(|| panic!("nothing is asked on a node's own clock"));
        assert!(asked.is_ok());
        assert_eq!(clock.estimate().offset_ns, Some(0));
        assert_eq!(clock.to_common(42), 42);
        assert_eq!(clock.offset_cell().get(), 0);
    }
}
