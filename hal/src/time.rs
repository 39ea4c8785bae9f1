//! Monotonic time, passed into every real-time call.
//!
//! Logic never reads a clock: the executor (or a simulated clock in tests) reads it once per tick
//! and hands the [`Timestamp`] down, so the same code runs deterministically on a simulated clock.

use core::ops::{Add, Sub};
use core::time::Duration;

/// An instant on a monotonic clock, in nanoseconds since that clock's (arbitrary) epoch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Timestamp(pub u64);

impl Timestamp {
    /// The clock's epoch.
    pub const ZERO: Timestamp = Timestamp(0);

    /// An instant `nanos` nanoseconds after the epoch.
    pub const fn from_nanos(nanos: u64) -> Self {
        Timestamp(nanos)
    }

    /// Nanoseconds since the epoch.
    pub const fn as_nanos(self) -> u64 {
        self.0
    }

    /// Seconds since the epoch, as a float (for logs and plots; keep integer nanoseconds in logic).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }

    /// The time elapsed since `earlier`, or zero if `earlier` is later than `self`.
    pub const fn saturating_since(self, earlier: Timestamp) -> Duration {
        Duration::from_nanos(self.0.saturating_sub(earlier.0))
    }
}

impl Add<Duration> for Timestamp {
    type Output = Timestamp;
    /// Saturates at the end of the clock's range instead of wrapping.
    fn add(self, rhs: Duration) -> Timestamp {
        let nanos = u64::try_from(rhs.as_nanos()).unwrap_or(u64::MAX);
        Timestamp(self.0.saturating_add(nanos))
    }
}

impl Sub for Timestamp {
    type Output = Duration;
    /// Saturates at zero when `rhs` is later.
    fn sub(self, rhs: Timestamp) -> Duration {
        self.saturating_since(rhs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arithmetic_saturates_instead_of_wrapping() {
        let t = Timestamp::from_nanos(5);
        assert_eq!(t - Timestamp::from_nanos(9), Duration::ZERO);
        assert_eq!(
            (Timestamp(u64::MAX - 1) + Duration::from_secs(1)).as_nanos(),
            u64::MAX
        );
        assert_eq!((t + Duration::from_nanos(10)) - t, Duration::from_nanos(10));
    }
}
