//! Tick phase: where in its period a periodic thread ticks, on the system's common clock.
//!
//! A thread with a [`TickPhase`] ticks at `k·period + phase` on the common clock (this host's
//! `CLOCK_MONOTONIC` plus the estimated offset [`CommonOffset`]), not at whatever phase it
//! happened to start with. A teleoperation channel's master loop ticks at phase 0 and its slave
//! loop half a period later, on any hosts: a sample made by either loop then waits about half a
//! period for the other's next tick, in both directions, instead of one direction waiting
//! almost a whole period while the other waits almost none.
//!
//! The grid follows the offset estimate: when a newer estimate moves the grid by more than
//! [`TickGrid::tolerance`] from the deadline the executor would sleep to, the next deadline is
//! re-placed, once, on the nearest grid point at least half a period after the tick that just
//! ran (and not before its end). So a re-phase never puts two ticks closer than half a period
//! apart, nor more than one and a half periods apart (plus any overrun), and no tick is
//! skipped for it: every tick still runs the loop's safety checks.
//!
//! [`TickGrid`] is the arithmetic, without a clock (the executor, a simulation and the tests
//! use the same); [`TickPhase`] is what a [`PeriodicConfig`](super::PeriodicConfig) carries.

use core::sync::atomic::{AtomicI64, Ordering};
use core::time::Duration;
use std::sync::Arc;

use penelope_hal::Timestamp;

/// The common clock less this host's monotonic clock, ns, shared without a lock: its owner
/// (the node's clock estimate) writes each new estimate, periodic threads read it once a tick.
/// Zero until told otherwise (a host that is its own common clock).
#[derive(Debug, Default)]
pub struct CommonOffset(AtomicI64);

impl CommonOffset {
    /// An offset of `ns`.
    pub const fn new(ns: i64) -> Self {
        CommonOffset(AtomicI64::new(ns))
    }

    /// Publishes a new estimate, ns.
    pub fn set(&self, ns: i64) {
        self.0.store(ns, Ordering::Release);
    }

    /// The newest estimate, ns.
    ///
    /// # Real-time
    /// One atomic load.
    pub fn get(&self) -> i64 {
        self.0.load(Ordering::Acquire)
    }
}

/// Where a periodic thread's ticks sit: at `k·period + phase` on the common clock, the common
/// clock being this host's plus `offset`.
#[derive(Clone, Debug)]
pub struct TickPhase {
    /// The phase on the common clock (taken modulo the period).
    pub phase: Duration,
    /// The common clock less this host's.
    pub offset: Arc<CommonOffset>,
}

impl TickPhase {
    /// Ticks at `phase` into each period of the common clock that `offset` places.
    pub fn new(phase: Duration, offset: Arc<CommonOffset>) -> Self {
        TickPhase { phase, offset }
    }
}

impl PartialEq for TickPhase {
    fn eq(&self, other: &Self) -> bool {
        self.phase == other.phase && Arc::ptr_eq(&self.offset, &other.offset)
    }
}

impl Eq for TickPhase {}

/// The deadline grid of a thread with a [`TickPhase`]: pure arithmetic on this host's times
/// and an offset, so the same code places the executor's deadlines and a test's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickGrid {
    period_ns: u64,
    phase_ns: u64,
    rephased: u64,
}

impl TickGrid {
    /// The grid `k·period + phase` (a zero period is raised to 1 ns; the phase is taken modulo
    /// the period).
    pub fn new(period: Duration, phase: Duration) -> Self {
        let period_ns = u64::try_from(period.as_nanos()).unwrap_or(u64::MAX).max(1);
        let phase_ns = u64::try_from(phase.as_nanos()).unwrap_or(u64::MAX) % period_ns;
        TickGrid {
            period_ns,
            phase_ns,
            rephased: 0,
        }
    }

    /// How far a deadline may be off the grid before it is re-placed: a fiftieth of the period
    /// (20 µs at 1 kHz), so the jitter of successive offset estimates between hosts does not
    /// move the ticks, and a real change does.
    pub fn tolerance(&self) -> Duration {
        Duration::from_nanos(self.period_ns / 50)
    }

    /// The first grid point at or after `not_before` (this host's clock), the common clock
    /// reading `offset_ns` ahead of this host's.
    pub fn first_at_or_after(&self, not_before: Timestamp, offset_ns: i64) -> Timestamp {
        let wait = match self.position(not_before, offset_ns) {
            0 => 0,
            r => self.period_ns - r,
        };
        Timestamp::from_nanos(not_before.as_nanos().saturating_add(wait))
    }

    /// How far `deadline` (this host's clock) is after its nearest grid point, ns (negative:
    /// before it), in `(-period/2, period/2]`.
    pub fn error_ns(&self, deadline: Timestamp, offset_ns: i64) -> i64 {
        let r = self.position(deadline, offset_ns);
        let r = i64::try_from(r).unwrap_or(i64::MAX);
        let period = i64::try_from(self.period_ns).unwrap_or(i64::MAX);
        if r > period / 2 { r - period } else { r }
    }

    /// The first deadline of a thread started at `now`: the first grid point at least one
    /// period ahead (time to finish starting, as an unphased thread has).
    pub fn first(&self, now: Timestamp, offset_ns: i64) -> Timestamp {
        self.first_at_or_after(
            Timestamp::from_nanos(now.as_nanos().saturating_add(self.period_ns)),
            offset_ns,
        )
    }

    /// The deadline after the tick scheduled at `ran` that ended at `end`, where the executor's
    /// own rule chose `next` (one period on, or past deadlines an overrun missed): `next` as it
    /// is while it stays on the grid within [`tolerance`](Self::tolerance); after the offset
    /// moved, the first grid point at least half a period after `ran` and not before `end`
    /// (counted in [`rephased`](Self::rephased)).
    pub fn follow(
        &mut self,
        ran: Timestamp,
        end: Timestamp,
        next: Timestamp,
        offset_ns: i64,
    ) -> Timestamp {
        let tolerance = i64::try_from(self.tolerance().as_nanos()).unwrap_or(i64::MAX);
        if self.error_ns(next, offset_ns).abs() <= tolerance {
            return next;
        }
        self.rephased += 1;
        let half = Timestamp::from_nanos(ran.as_nanos().saturating_add(self.period_ns / 2));
        self.first_at_or_after(half.max(end), offset_ns)
    }

    /// Times the grid was re-placed after the offset moved.
    pub fn rephased(&self) -> u64 {
        self.rephased
    }

    /// Where `t` (this host's clock) falls in the period of the grid, ns: 0 on a grid point.
    fn position(&self, t: Timestamp, offset_ns: i64) -> u64 {
        let on_common =
            i128::from(t.as_nanos()) + i128::from(offset_ns) - i128::from(self.phase_ns);
        // In 0..period, so it fits.
        on_common.rem_euclid(i128::from(self.period_ns)) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: u64 = 1_000_000;

    fn at(ns: u64) -> Timestamp {
        Timestamp::from_nanos(ns)
    }

    #[test]
    fn the_first_deadline_is_on_the_grid_of_the_common_clock() {
        let grid = TickGrid::new(Duration::from_nanos(T), Duration::from_nanos(T / 2));
        // The common clock reads 3.7 ms ahead: common 10.2 ms + 3.7 = 13.9 ms; the next
        // point k·T + T/2 at or after it is 14.5 ms common, 10.8 ms here.
        assert_eq!(
            grid.first_at_or_after(at(10_200_000), 3_700_000),
            at(10_800_000)
        );
        // On a grid point already: itself.
        assert_eq!(
            grid.first_at_or_after(at(10_800_000), 3_700_000),
            at(10_800_000)
        );
        // A negative offset (the common clock behind this host's): common 10.0 ms, the point
        // 10.5 ms common is 10.7 ms here.
        assert_eq!(
            grid.first_at_or_after(at(10_200_000), -200_000),
            at(10_700_000)
        );
        // At least a period ahead of the start.
        let first = grid.first(at(10_200_000), 0);
        assert_eq!(first, at(11_500_000));
        assert_eq!(grid.error_ns(first, 0), 0);
        assert_eq!(grid.error_ns(at(11_510_000), 0), 10_000);
        assert_eq!(grid.error_ns(at(11_490_000), 0), -10_000);
        // A phase of a period or more is taken modulo the period.
        assert_eq!(
            TickGrid::new(Duration::from_nanos(T), Duration::from_nanos(3 * T / 2)),
            grid
        );
    }

    #[test]
    fn a_deadline_on_the_grid_is_kept_and_a_moved_offset_rephases_once_bounded() {
        let mut grid = TickGrid::new(Duration::from_nanos(T), Duration::ZERO);
        let ran = at(5_000_000);
        // Within tolerance (the jitter of estimates): kept.
        assert_eq!(
            grid.follow(ran, at(5_100_000), at(6_000_000), 15_000),
            at(6_000_000)
        );
        assert_eq!(grid.rephased(), 0);
        // The offset moved by 0.3 ms: the nearest grid point, 0.7 ms after the tick.
        let next = grid.follow(ran, at(5_100_000), at(6_000_000), 300_000);
        assert_eq!(next, at(5_700_000));
        assert_eq!(grid.rephased(), 1);
        // Moved by 0.7 ms (the nearest point would be 0.3 ms on: closer than half a period):
        // the next one, 1.3 ms on.
        let next = grid.follow(ran, at(5_100_000), at(6_000_000), 700_000);
        assert_eq!(next, at(6_300_000));
        // A tick that ran long: never a deadline already past.
        let next = grid.follow(ran, at(5_800_000), at(7_000_000), 300_000);
        assert_eq!(next, at(6_700_000));
    }
}
