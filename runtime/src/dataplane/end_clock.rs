//! The clock a data-plane end stamps its datagrams with: when heartbeats leave and are
//! answered, and when datagrams arrive (the four timestamps of [`LinkClock`]).
//!
//! On a node clocked in real time ([`LinkTime::Real`]) the times are true: `CLOCK_MONOTONIC`
//! (the node's clock) read at the moment of each send, and each datagram's arrival as the
//! kernel stamped it (`SO_TIMESTAMPNS`, on `CLOCK_REALTIME`, converted to the node's clock by
//! reading both clocks). So the estimate is not disturbed by how long a datagram waited for the
//! communication thread's next tick. On a simulated clock ([`LinkTime::Tick`]) every time is
//! the communication tick's: runs stay bit-reproducible, and the estimate is good to a
//! communication period.
//!
//! Either way an injected offset (`clock_offset_us` of the channel's `faults`) is added to
//! every time the end stamps, so that a test can put two ends on one host on clocks that
//! disagree by a known amount.
//!
//! [`LinkClock`]: penelope_protocol::link_clock::LinkClock

use nix::time::{ClockId, clock_gettime};
use penelope_rt_core::clock::MonotonicClock;

/// Where an end's times come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LinkTime {
    /// The communication tick's time (a simulated clock: deterministic).
    #[default]
    Tick,
    /// The node's real clock read at each send, and the kernel's receive stamps.
    Real,
}

/// The clock one end stamps with: its time source and an injected offset.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EndClock {
    time: LinkTime,
    offset_ns: i64,
}

impl EndClock {
    /// Times from `time`, read `offset_ns` ahead.
    pub fn new(time: LinkTime, offset_ns: i64) -> Self {
        EndClock { time, offset_ns }
    }

    /// Where the times come from.
    pub fn time(&self) -> LinkTime {
        self.time
    }

    /// The injected offset, ns (the end's clock minus the node's).
    pub fn offset_ns(&self) -> i64 {
        self.offset_ns
    }

    /// The end's time now, ns: the tick's time `tick_ns` (`Tick`) or the node's clock read now
    /// (`Real`), plus the offset.
    ///
    /// # Real-time
    /// At most one `clock_gettime` (vDSO); no allocation.
    pub fn now(&self, tick_ns: i64) -> i64 {
        let node = match self.time {
            LinkTime::Tick => tick_ns,
            LinkTime::Real => monotonic_ns(),
        };
        node.saturating_add(self.offset_ns)
    }

    /// The end's time at which a datagram arrived, ns: the kernel's stamp `kernel_realtime_ns`
    /// converted to the node's clock (`Real`, when the kernel stamped it), else as
    /// [`now`](Self::now).
    ///
    /// # Real-time
    /// At most three `clock_gettime` calls (vDSO); no allocation.
    pub fn received(&self, tick_ns: i64, kernel_realtime_ns: Option<i64>) -> i64 {
        match (self.time, kernel_realtime_ns) {
            (LinkTime::Real, Some(stamp)) => realtime_to_monotonic(stamp)
                .map_or_else(|| self.now(tick_ns), |n| n.saturating_add(self.offset_ns)),
            _ => self.now(tick_ns),
        }
    }

    /// A time of the end's clock as the node's: without the injected offset.
    pub fn to_node(&self, end_ns: i64) -> i64 {
        end_ns.saturating_sub(self.offset_ns)
    }
}

/// `CLOCK_MONOTONIC` now, ns (the node's clock on real time).
fn monotonic_ns() -> i64 {
    i64::try_from(MonotonicClock::read().as_nanos()).unwrap_or(i64::MAX)
}

/// A `CLOCK_REALTIME` time as `CLOCK_MONOTONIC`: the realtime clock is read between two reads
/// of the monotonic one, whose mean is taken as the same instant (the reads are tens of ns
/// apart). `None` if the realtime clock cannot be read.
fn realtime_to_monotonic(realtime_ns: i64) -> Option<i64> {
    let before = monotonic_ns();
    let real = clock_gettime(ClockId::CLOCK_REALTIME).ok()?;
    let after = monotonic_ns();
    let real = real
        .tv_sec()
        .checked_mul(1_000_000_000)?
        .checked_add(real.tv_nsec())?;
    let mono = before + (after - before) / 2;
    realtime_ns.checked_sub(real.checked_sub(mono)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_times_are_the_ticks_plus_the_offset_and_real_ones_the_node_clock() {
        let tick = EndClock::new(LinkTime::Tick, 3_700_000);
        assert_eq!(tick.now(1_000), 3_701_000);
        assert_eq!(tick.received(1_000, Some(42)), 3_701_000);
        assert_eq!(tick.to_node(3_701_000), 1_000);

        let real = EndClock::new(LinkTime::Real, -5_000);
        let before = monotonic_ns();
        let now = real.now(0);
        let after = monotonic_ns();
        assert!((before - 5_000..=after - 5_000).contains(&now));
        // A kernel stamp of "now" on the realtime clock is now on the node's.
        let rt = clock_gettime(ClockId::CLOCK_REALTIME).unwrap();
        let rt = rt.tv_sec() * 1_000_000_000 + rt.tv_nsec();
        let at = real.received(0, Some(rt));
        let mono = monotonic_ns() - 5_000;
        assert!((mono - at).abs() < 1_000_000, "{} ns apart", mono - at);
        // Without a stamp: read now.
        assert!(real.received(0, None) >= at);
    }
}
