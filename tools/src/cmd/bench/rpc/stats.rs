//! Summaries of round-trip samples: moments and exact percentiles.

use serde_json::json;

/// The summary of one probe's round-trip times, all in nanoseconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    /// Samples.
    pub n: usize,
    /// Mean, ns.
    pub mean: f64,
    /// Variance (of the population), ns².
    pub variance: f64,
    /// Smallest sample, ns.
    pub min: f64,
    /// Median (nearest rank), ns.
    pub p50: f64,
    /// 90th percentile (nearest rank), ns.
    pub p90: f64,
    /// 99th percentile (nearest rank), ns.
    pub p99: f64,
    /// 99.9th percentile (nearest rank), ns.
    pub p999: f64,
    /// Largest sample, ns.
    pub max: f64,
}

impl Summary {
    /// Summarises `samples` (ns); `None` when there are none.
    pub fn of(samples: &[u64]) -> Option<Summary> {
        if samples.is_empty() {
            return None;
        }
        let mut sorted = samples.to_vec();
        sorted.sort_unstable();
        let n = sorted.len();
        let mean = sorted.iter().map(|&x| x as f64).sum::<f64>() / n as f64;
        let variance = sorted
            .iter()
            .map(|&x| (x as f64 - mean).powi(2))
            .sum::<f64>()
            / n as f64;
        Some(Summary {
            n,
            mean,
            variance,
            min: sorted[0] as f64,
            p50: percentile(&sorted, 0.50),
            p90: percentile(&sorted, 0.90),
            p99: percentile(&sorted, 0.99),
            p999: percentile(&sorted, 0.999),
            max: sorted[n - 1] as f64,
        })
    }

    /// Standard deviation, ns.
    pub fn std(&self) -> f64 {
        self.variance.sqrt()
    }

    /// The summary in µs (variance in µs²) as JSON.
    pub fn json(&self) -> serde_json::Value {
        json!({
            "n": self.n,
            "mean_us": self.mean / 1e3,
            "variance_us2": self.variance / 1e6,
            "std_us": self.std() / 1e3,
            "min_us": self.min / 1e3,
            "p50_us": self.p50 / 1e3,
            "p90_us": self.p90 / 1e3,
            "p99_us": self.p99 / 1e3,
            "p999_us": self.p999 / 1e3,
            "max_us": self.max / 1e3,
        })
    }
}

/// The nearest-rank `q` quantile (0 < q <= 1) of sorted, non-empty `sorted`.
fn percentile(sorted: &[u64], q: f64) -> f64 {
    let rank = (q * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1] as f64
}

/// `a / b`, NaN when `b` is zero.
pub fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 { a / b } else { f64::NAN }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moments_and_nearest_rank_percentiles() {
        assert_eq!(Summary::of(&[]), None);
        let samples: Vec<u64> = (1..=1000).rev().collect();
        let s = Summary::of(&samples).unwrap();
        assert_eq!(s.n, 1000);
        assert_eq!(s.min, 1.0);
        assert_eq!(s.max, 1000.0);
        assert_eq!(s.p50, 500.0);
        assert_eq!(s.p90, 900.0);
        assert_eq!(s.p99, 990.0);
        assert_eq!(s.p999, 999.0);
        assert!((s.mean - 500.5).abs() < 1e-9);
        // Population variance of 1..=n is (n² - 1) / 12.
        assert!((s.variance - (1000.0f64.powi(2) - 1.0) / 12.0).abs() < 1e-6);
        let one = Summary::of(&[7]).unwrap();
        assert_eq!((one.p50, one.p999, one.variance), (7.0, 7.0, 0.0));
        assert!(ratio(1.0, 0.0).is_nan());
        assert_eq!(ratio(3.0, 2.0), 1.5);
    }
}
