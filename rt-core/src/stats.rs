//! Timing statistics with fixed storage: a bucketed latency histogram and running duration
//! statistics. Both record in constant time without allocating, so the periodic executor keeps
//! them in the real-time thread.

use core::time::Duration;

/// The default number of histogram buckets: 1 µs wide, up to 10 ms, then one overflow bucket.
pub const DEFAULT_BUCKETS: usize = 10_000;

/// A histogram of durations in `N` buckets of equal width, plus an overflow bucket, with the exact
/// minimum, maximum and sum.
///
/// Percentiles are reported as the upper edge of the bucket that holds them (so they are never
/// optimistic by more than one bucket width); one that falls in the overflow bucket is reported as
/// the exact maximum.
#[derive(Clone, Debug, PartialEq)]
pub struct LatencyHistogram<const N: usize = DEFAULT_BUCKETS> {
    bucket_ns: u64,
    counts: [u64; N],
    overflow: u64,
    count: u64,
    sum_ns: u128,
    min_ns: u64,
    max_ns: u64,
}

impl<const N: usize> Default for LatencyHistogram<N> {
    fn default() -> Self {
        Self::new(Duration::from_micros(1))
    }
}

/// The headline figures of a [`LatencyHistogram`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LatencySummary {
    /// Samples recorded.
    pub count: u64,
    /// Smallest sample.
    pub min: Duration,
    /// Median.
    pub p50: Duration,
    /// 99th percentile.
    pub p99: Duration,
    /// 99.9th percentile.
    pub p999: Duration,
    /// Largest sample.
    pub max: Duration,
    /// Mean.
    pub mean: Duration,
    /// Samples beyond the last bucket.
    pub overflow: u64,
}

impl<const N: usize> LatencyHistogram<N> {
    /// An empty histogram whose buckets are `bucket` wide (at least 1 ns).
    pub const fn new(bucket: Duration) -> Self {
        let ns = bucket.as_nanos();
        let bucket_ns = if ns == 0 {
            1
        } else if ns > u64::MAX as u128 {
            u64::MAX
        } else {
            ns as u64
        };
        LatencyHistogram {
            bucket_ns,
            counts: [0; N],
            overflow: 0,
            count: 0,
            sum_ns: 0,
            min_ns: u64::MAX,
            max_ns: 0,
        }
    }

    /// Records one sample.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn record(&mut self, sample: Duration) {
        let ns = u64::try_from(sample.as_nanos()).unwrap_or(u64::MAX);
        self.record_n(ns, 1);
    }

    /// Records `n` samples of `ns` nanoseconds (for importing another tool's histogram).
    pub fn record_n(&mut self, ns: u64, n: u64) {
        if n == 0 {
            return;
        }
        let index = ns / self.bucket_ns;
        match usize::try_from(index)
            .ok()
            .and_then(|i| self.counts.get_mut(i))
        {
            Some(c) => *c += n,
            None => self.overflow += n,
        }
        self.count += n;
        self.sum_ns += u128::from(ns) * u128::from(n);
        self.min_ns = self.min_ns.min(ns);
        self.max_ns = self.max_ns.max(ns);
    }

    /// Adds every sample of `other` (whose buckets must have the same width; if not, `other`'s
    /// samples are re-bucketed at their bucket's lower edge).
    pub fn merge(&mut self, other: &LatencyHistogram<N>) {
        for (i, &c) in other.counts.iter().enumerate() {
            if c > 0 {
                self.record_n(i as u64 * other.bucket_ns, c);
            }
        }
        if other.overflow > 0 {
            self.record_n(other.max_ns, other.overflow);
        }
        if other.count > 0 {
            // Exact extremes and sum, not the bucket edges used above.
            self.min_ns = self.min_ns.min(other.min_ns);
            self.max_ns = self.max_ns.max(other.max_ns);
        }
    }

    /// Forgets every sample.
    pub fn clear(&mut self) {
        let bucket = self.bucket_ns;
        *self = LatencyHistogram::new(Duration::from_nanos(bucket));
    }

    /// Width of one bucket.
    pub fn bucket_width(&self) -> Duration {
        Duration::from_nanos(self.bucket_ns)
    }

    /// Samples recorded.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Samples per bucket; bucket `i` holds `[i * width, (i + 1) * width)`.
    pub fn buckets(&self) -> &[u64; N] {
        &self.counts
    }

    /// Samples beyond the last bucket.
    pub fn overflow(&self) -> u64 {
        self.overflow
    }

    /// Smallest sample, or `None` when empty.
    pub fn min(&self) -> Option<Duration> {
        (self.count > 0).then(|| Duration::from_nanos(self.min_ns))
    }

    /// Largest sample, or `None` when empty.
    pub fn max(&self) -> Option<Duration> {
        (self.count > 0).then(|| Duration::from_nanos(self.max_ns))
    }

    /// Mean sample, or `None` when empty.
    pub fn mean(&self) -> Option<Duration> {
        (self.count > 0).then(|| {
            let mean = self.sum_ns / u128::from(self.count);
            Duration::from_nanos(u64::try_from(mean).unwrap_or(u64::MAX))
        })
    }

    /// Samples at or above `threshold` (counted by bucket: exact when `threshold` is a multiple of
    /// the bucket width).
    pub fn count_at_or_above(&self, threshold: Duration) -> u64 {
        let ns = u64::try_from(threshold.as_nanos()).unwrap_or(u64::MAX);
        let first = usize::try_from(ns / self.bucket_ns).unwrap_or(usize::MAX);
        self.counts.iter().skip(first).sum::<u64>() + self.overflow
    }

    /// The `p`-quantile (`p` in `[0, 1]`, clamped): the upper edge of the bucket holding it, never
    /// above the maximum. `None` when empty.
    pub fn percentile(&self, p: f64) -> Option<Duration> {
        if self.count == 0 {
            return None;
        }
        let p = if p.is_nan() { 1.0 } else { p.clamp(0.0, 1.0) };
        // The rank (1-based) of the sample we want.
        let rank = (libm::ceil(p * self.count as f64) as u64).clamp(1, self.count);
        let mut seen = 0u64;
        for (i, &c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                let upper = (i as u64 + 1).saturating_mul(self.bucket_ns);
                return Some(Duration::from_nanos(
                    upper.min(self.max_ns).max(self.min_ns),
                ));
            }
        }
        Some(Duration::from_nanos(self.max_ns))
    }

    /// Count, min, p50, p99, p99.9, max and mean (all zero when empty).
    pub fn summary(&self) -> LatencySummary {
        let pct = |p| self.percentile(p).unwrap_or_default();
        LatencySummary {
            count: self.count,
            min: self.min().unwrap_or_default(),
            p50: pct(0.5),
            p99: pct(0.99),
            p999: pct(0.999),
            max: self.max().unwrap_or_default(),
            mean: self.mean().unwrap_or_default(),
            overflow: self.overflow,
        }
    }
}

/// Running count, minimum, maximum and mean of durations (execution times).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DurationStats {
    count: u64,
    sum_ns: u128,
    min_ns: u64,
    max_ns: u64,
}

impl Default for DurationStats {
    fn default() -> Self {
        Self::new()
    }
}

impl DurationStats {
    /// No samples yet.
    pub const fn new() -> Self {
        DurationStats {
            count: 0,
            sum_ns: 0,
            min_ns: u64::MAX,
            max_ns: 0,
        }
    }

    /// Records one sample.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn record(&mut self, sample: Duration) {
        let ns = u64::try_from(sample.as_nanos()).unwrap_or(u64::MAX);
        self.count += 1;
        self.sum_ns += u128::from(ns);
        self.min_ns = self.min_ns.min(ns);
        self.max_ns = self.max_ns.max(ns);
    }

    /// Samples recorded.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Smallest sample (zero when empty).
    pub fn min(&self) -> Duration {
        if self.count == 0 {
            Duration::ZERO
        } else {
            Duration::from_nanos(self.min_ns)
        }
    }

    /// Largest sample (zero when empty).
    pub fn max(&self) -> Duration {
        Duration::from_nanos(self.max_ns)
    }

    /// Mean sample (zero when empty).
    pub fn mean(&self) -> Duration {
        if self.count == 0 {
            return Duration::ZERO;
        }
        let mean = self.sum_ns / u128::from(self.count);
        Duration::from_nanos(u64::try_from(mean).unwrap_or(u64::MAX))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn us(x: u64) -> Duration {
        Duration::from_micros(x)
    }

    #[test]
    fn percentiles_are_bucket_upper_edges() {
        let mut h = LatencyHistogram::<100>::default();
        assert_eq!(h.percentile(0.5), None);
        for i in 0..1000u64 {
            h.record(Duration::from_nanos(i * 50)); // 0 .. 49.95 us, uniform
        }
        let s = h.summary();
        assert_eq!(s.count, 1000);
        assert_eq!(s.min, Duration::ZERO);
        assert_eq!(s.max, Duration::from_nanos(49_950));
        assert_eq!(s.p50, us(25));
        assert_eq!(s.p99, Duration::from_nanos(49_950).min(us(50)));
        assert!(s.mean > us(24) && s.mean < us(26));
        assert_eq!(h.count_at_or_above(us(40)), 200);
    }

    #[test]
    fn overflow_reports_the_exact_maximum() {
        let mut h = LatencyHistogram::<10>::default();
        for _ in 0..99 {
            h.record(us(3));
        }
        h.record(Duration::from_millis(7));
        assert_eq!(h.overflow(), 1);
        assert_eq!(h.percentile(0.5), Some(us(4)));
        assert_eq!(h.percentile(1.0), Some(Duration::from_millis(7)));
        assert_eq!(h.percentile(f64::NAN), Some(Duration::from_millis(7)));
        let mut merged = LatencyHistogram::<10>::default();
        merged.merge(&h);
        merged.merge(&h);
        assert_eq!(merged.count(), 200);
        assert_eq!(merged.overflow(), 2);
        assert_eq!(merged.max(), Some(Duration::from_millis(7)));
        merged.clear();
        assert_eq!(merged.count(), 0);
    }

    #[test]
    fn duration_stats_track_extremes() {
        let mut s = DurationStats::new();
        assert_eq!(s.mean(), Duration::ZERO);
        for x in [5, 1, 9] {
            s.record(us(x));
        }
        assert_eq!(
            (s.min(), s.max(), s.mean(), s.count()),
            (us(1), us(9), us(5), 3)
        );
    }
}
