//! A fixed-size latency histogram: recorded from a communication thread (no allocation, one
//! add), read as percentiles by whoever shows it.
//!
//! Buckets are 1 µs wide below 200 µs, 10 µs below 2 ms and 100 µs below 20 ms, with one
//! bucket above: a loopback or LAN trip resolves to the microsecond, a congested one to a tenth
//! of a millisecond.

/// Buckets of each width: (width ns, how many).
const RANGES: [(i64, usize); 3] = [(1_000, 200), (10_000, 180), (100_000, 180)];
/// All buckets, the last one for everything from 20 ms up.
pub const BUCKETS: usize = 200 + 180 + 180 + 1;

/// Latencies, ns, counted in buckets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TripHistogram {
    counts: [u32; BUCKETS],
    /// Values below zero (a clock-offset estimate off by more than the trip).
    below_zero: u32,
    total: u64,
    max_ns: i64,
}

impl Default for TripHistogram {
    fn default() -> Self {
        TripHistogram {
            counts: [0; BUCKETS],
            below_zero: 0,
            total: 0,
            max_ns: 0,
        }
    }
}

/// The bucket of `ns` (at least zero).
fn bucket(ns: i64) -> usize {
    let mut base_ns = 0i64;
    let mut base_index = 0usize;
    for (width, count) in RANGES {
        let top = base_ns + width * count as i64;
        if ns < top {
            return base_index + ((ns - base_ns) / width) as usize;
        }
        base_ns = top;
        base_index += count;
    }
    BUCKETS - 1
}

/// The middle of bucket `i`, ns (the overflow bucket: its lower edge).
fn middle(i: usize) -> i64 {
    let mut base_ns = 0i64;
    let mut base_index = 0usize;
    for (width, count) in RANGES {
        if i < base_index + count {
            return base_ns + (i - base_index) as i64 * width + width / 2;
        }
        base_ns += width * count as i64;
        base_index += count;
    }
    base_ns
}

impl TripHistogram {
    /// Counts one latency.
    ///
    /// # Real-time
    /// A few comparisons and one add; no allocation.
    pub fn record(&mut self, ns: i64) {
        self.total += 1;
        if ns < 0 {
            self.below_zero = self.below_zero.saturating_add(1);
            return;
        }
        self.max_ns = self.max_ns.max(ns);
        let b = &mut self.counts[bucket(ns)];
        *b = b.saturating_add(1);
    }

    /// Latencies counted (including those below zero).
    pub fn count(&self) -> u64 {
        self.total
    }

    /// Latencies below zero.
    pub fn below_zero(&self) -> u32 {
        self.below_zero
    }

    /// The largest latency, ns.
    pub fn max_ns(&self) -> i64 {
        self.max_ns
    }

    /// The `p`-quantile (0..=1), ns, to the resolution of its bucket (values below zero count
    /// as zero); `None` when empty.
    pub fn quantile(&self, p: f64) -> Option<i64> {
        if self.total == 0 {
            return None;
        }
        let rank = ((self.total - 1) as f64 * p.clamp(0.0, 1.0)).round() as u64;
        let mut seen = u64::from(self.below_zero);
        if rank < seen {
            return Some(0);
        }
        for (i, &c) in self.counts.iter().enumerate() {
            seen += u64::from(c);
            if rank < seen {
                return Some(middle(i).min(self.max_ns));
            }
        }
        Some(self.max_ns)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_tile_the_range_and_quantiles_land_within_one() {
        assert_eq!(bucket(0), 0);
        assert_eq!(bucket(999), 0);
        assert_eq!(bucket(1_000), 1);
        assert_eq!(bucket(199_999), 199);
        assert_eq!(bucket(200_000), 200);
        assert_eq!(bucket(1_999_999), 379);
        assert_eq!(bucket(2_000_000), 380);
        assert_eq!(bucket(19_999_999), 559);
        assert_eq!(bucket(20_000_000), BUCKETS - 1);
        assert_eq!(bucket(i64::MAX), BUCKETS - 1);
        let mut h = TripHistogram::default();
        assert_eq!(h.quantile(0.5), None);
        // 1..=100 µs, then one slow trip of 5 ms.
        for us in 1..=100 {
            h.record(us * 1_000 + 300);
        }
        h.record(5_000_000);
        h.record(-10);
        assert_eq!(h.count(), 102);
        assert_eq!(h.below_zero(), 1);
        let p50 = h.quantile(0.5).unwrap();
        assert!((49_000..=51_500).contains(&p50), "{p50}");
        assert_eq!(h.quantile(1.0), Some(5_000_000));
        assert_eq!(h.quantile(0.0), Some(0));
        assert_eq!(h.max_ns(), 5_000_000);
    }
}
