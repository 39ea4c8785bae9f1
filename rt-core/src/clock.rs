//! Clocks. Logic never reads one: the executor (or the simulation runner) reads it once per tick
//! and passes the [`Timestamp`] in. This module holds the two sources of those timestamps.

use core::cell::Cell;
use core::time::Duration;

use penelope_hal::Timestamp;

/// A source of monotonic timestamps.
pub trait Clock {
    /// The current instant.
    ///
    /// # Real-time
    /// Implementations must not allocate or block (a `clock_gettime` call at most).
    fn now(&self) -> Timestamp;
}

/// A simulated clock: time moves only when told to. Single-threaded (it is not `Sync`), for
/// deterministic simulations.
#[derive(Debug, Default)]
pub struct SimClock {
    now: Cell<Timestamp>,
}

impl SimClock {
    /// A clock reading `start`.
    pub const fn new(start: Timestamp) -> Self {
        SimClock {
            now: Cell::new(start),
        }
    }

    /// Sets the time (never backwards: an earlier `t` is ignored, the clock stays monotonic).
    pub fn set(&self, t: Timestamp) {
        if t > self.now.get() {
            self.now.set(t);
        }
    }

    /// Moves time forward by `by`.
    pub fn advance(&self, by: Duration) {
        self.now.set(self.now.get() + by);
    }
}

impl Clock for SimClock {
    fn now(&self) -> Timestamp {
        self.now.get()
    }
}

/// The system's `CLOCK_MONOTONIC`, the clock the periodic executor sleeps on.
#[cfg(feature = "std")]
#[derive(Clone, Copy, Debug, Default)]
pub struct MonotonicClock;

#[cfg(feature = "std")]
impl MonotonicClock {
    /// `CLOCK_MONOTONIC` now.
    ///
    /// # Real-time
    /// One `clock_gettime` (vDSO) call; no allocation.
    pub fn read() -> Timestamp {
        // SAFETY: `ts` is a valid out-pointer; CLOCK_MONOTONIC always exists on Linux.
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        unsafe {
            libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts);
        }
        timespec_to_timestamp(&ts)
    }
}

#[cfg(feature = "std")]
impl Clock for MonotonicClock {
    fn now(&self) -> Timestamp {
        MonotonicClock::read()
    }
}

#[cfg(feature = "std")]
pub(crate) fn timespec_to_timestamp(ts: &libc::timespec) -> Timestamp {
    let secs = u64::try_from(ts.tv_sec).unwrap_or(0);
    let nanos = u64::try_from(ts.tv_nsec).unwrap_or(0);
    Timestamp::from_nanos(secs.saturating_mul(1_000_000_000).saturating_add(nanos))
}

#[cfg(feature = "std")]
pub(crate) fn timestamp_to_timespec(t: Timestamp) -> libc::timespec {
    let n = t.as_nanos();
    libc::timespec {
        tv_sec: libc::time_t::try_from(n / 1_000_000_000).unwrap_or(libc::time_t::MAX),
        tv_nsec: (n % 1_000_000_000) as libc::c_long,
    }
}

#[cfg(feature = "std")]
/// Sleeps until `deadline` on `CLOCK_MONOTONIC` (absolute), resuming after signals.
///
/// # Real-time
/// One `clock_nanosleep` call (more only after a signal); no allocation.
pub fn sleep_until(deadline: Timestamp) {
    let ts = timestamp_to_timespec(deadline);
    loop {
        // SAFETY: `ts` is a valid timespec; the remainder pointer may be null with TIMER_ABSTIME.
        let rc = unsafe {
            libc::clock_nanosleep(
                libc::CLOCK_MONOTONIC,
                libc::TIMER_ABSTIME,
                &ts,
                std::ptr::null_mut(),
            )
        };
        if rc != libc::EINTR {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sim_clock_is_monotonic() {
        let c = SimClock::new(Timestamp::from_nanos(10));
        c.advance(Duration::from_nanos(5));
        assert_eq!(c.now(), Timestamp::from_nanos(15));
        c.set(Timestamp::from_nanos(3));
        assert_eq!(c.now(), Timestamp::from_nanos(15));
        c.set(Timestamp::from_nanos(30));
        assert_eq!(c.now(), Timestamp::from_nanos(30));
    }

    #[cfg(feature = "std")]
    #[test]
    fn monotonic_clock_does_not_go_back() {
        let a = MonotonicClock.now();
        let b = MonotonicClock.now();
        assert!(b >= a);
        assert_eq!(timespec_to_timestamp(&timestamp_to_timespec(a)), a);
    }
}
