//! Cycle timing kept by the real-time thread: fixed-bucket histograms of the wake-up
//! latency (how late `clock_nanosleep` returned after the deadline) and of the compute
//! time (from the wake-up to after the setpoint was handed to the publisher thread).
//!
//! Recording a value never allocates, locks or logs: a histogram is an array of counters
//! with log-spaced bucket edges, computed once when it is built. The buckets are
//! `BUCKETS_PER_DECADE` per decade from 1 µs to 100 ms, so a percentile is known to
//! within one bucket (12 %: each edge is 10^(1/20) times the previous one); below 1 µs
//! and from 100 ms up there is one bucket each. The maximum is kept exactly.
//!
//! The daemon logs the summary once, when the cycle ends (`kerfd` on SIGTERM), and
//! [`Daemon::timing`](super::Daemon::timing) returns it to an in-process caller.

use std::fmt;

/// Buckets per decade of nanoseconds.
pub(crate) const BUCKETS_PER_DECADE: usize = 20;

/// The lower edge of the first log-spaced bucket, ns (1 µs).
pub(crate) const LOWEST_EDGE_NS: u64 = 1_000;

/// Decades covered by the log-spaced buckets: 1 µs to 100 ms.
const DECADES: usize = 5;

/// Edges between buckets: 1 µs, …, 100 ms.
const EDGES: usize = BUCKETS_PER_DECADE * DECADES + 1;

/// Buckets: one below 1 µs, the log-spaced ones, one from 100 ms up.
pub const BUCKETS: usize = EDGES + 1;

/// A fixed-bucket histogram of durations in ns.
#[derive(Clone, Debug)]
pub struct Histogram {
    /// `edges_ns[i]` is the lower edge of bucket `i + 1` (bucket 0 is below the first).
    edges_ns: [u64; EDGES],
    counts: [u64; BUCKETS],
    total: u64,
    max_ns: u64,
}

impl Default for Histogram {
    fn default() -> Self {
        Self::new()
    }
}

impl Histogram {
    /// An empty histogram.
    pub fn new() -> Self {
        let mut edges_ns = [0u64; EDGES];
        for (i, e) in edges_ns.iter_mut().enumerate() {
            let exponent = i as f64 / BUCKETS_PER_DECADE as f64;
            *e = (LOWEST_EDGE_NS as f64 * 10f64.powf(exponent)).round() as u64;
        }
        Histogram {
            edges_ns,
            counts: [0; BUCKETS],
            total: 0,
            max_ns: 0,
        }
    }

    /// Counts one duration. No allocation, lock or system call.
    pub fn record(&mut self, ns: u64) {
        let bucket = self.edges_ns.partition_point(|&e| e <= ns);
        self.counts[bucket] += 1;
        self.total += 1;
        self.max_ns = self.max_ns.max(ns);
    }

    /// Durations counted.
    pub fn count(&self) -> u64 {
        self.total
    }

    /// The largest duration counted, ns (exact); 0 when empty.
    pub fn max_ns(&self) -> u64 {
        self.max_ns
    }

    /// An upper bound of the `q` quantile (0 < `q` ≤ 1), ns: the upper edge of the bucket
    /// that holds the value of rank ⌈q·count⌉, never above the maximum. 0 when empty.
    pub(crate) fn quantile_ns(&self, q: f64) -> u64 {
        if self.total == 0 {
            return 0;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.total as f64).ceil() as u64).max(1);
        let mut seen = 0u64;
        for (bucket, &c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                let upper = self.edges_ns.get(bucket).copied().unwrap_or(self.max_ns);
                return upper.min(self.max_ns);
            }
        }
        self.max_ns
    }

    /// p50, p99, p99.9 and the maximum.
    pub fn percentiles(&self) -> Percentiles {
        Percentiles {
            p50_ns: self.quantile_ns(0.5),
            p99_ns: self.quantile_ns(0.99),
            p999_ns: self.quantile_ns(0.999),
            max_ns: self.max_ns,
        }
    }
}

/// Percentiles of a [`Histogram`] (upper bounds within one bucket; the maximum exact).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Percentiles {
    /// Median, ns.
    pub p50_ns: u64,
    /// 99th percentile, ns.
    pub p99_ns: u64,
    /// 99.9th percentile, ns.
    pub p999_ns: u64,
    /// Maximum, ns.
    pub max_ns: u64,
}

impl fmt::Display for Percentiles {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let us = |ns: u64| ns as f64 / 1000.0;
        write!(
            f,
            "p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs",
            us(self.p50_ns),
            us(self.p99_ns),
            us(self.p999_ns),
            us(self.max_ns)
        )
    }
}

/// The cycle thread's two histograms.
#[derive(Clone, Debug, Default)]
pub struct CycleTiming {
    /// Wake-up latency: the time read after the sleep minus the deadline.
    pub latency: Histogram,
    /// Compute time: from the wake-up to after the setpoint was published.
    pub compute: Histogram,
}

impl CycleTiming {
    /// Empty histograms.
    pub fn new() -> Self {
        Self::default()
    }

    /// Counts one cycle. No allocation, lock or system call.
    pub fn record(&mut self, latency_ns: u64, compute_ns: u64) {
        self.latency.record(latency_ns);
        self.compute.record(compute_ns);
    }

    /// The percentiles of both.
    pub fn summary(&self) -> TimingSummary {
        TimingSummary {
            cycles: self.latency.count(),
            latency: self.latency.percentiles(),
            compute: self.compute.percentiles(),
            publish: Percentiles::default(),
        }
    }
}

/// What the cycle thread reports when it ends.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TimingSummary {
    /// Cycles counted.
    pub cycles: u64,
    /// Wake-up latency.
    pub latency: Percentiles,
    /// Compute time (wake-up to after the setpoint was handed to the publisher).
    pub compute: Percentiles,
    /// Publishing latency the helper thread adds: from the hand-over to after iceoryx2's
    /// `send_copy` (see [`super::publish`]).
    pub publish: Percentiles,
}

impl fmt::Display for TimingSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} cycles; wake-up latency {}; compute {}; publish added {}",
            self.cycles, self.latency, self.compute, self.publish
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_are_log_spaced_from_1_us_to_100_ms() {
        let h = Histogram::new();
        assert_eq!(h.edges_ns[0], 1_000);
        assert_eq!(h.edges_ns[BUCKETS_PER_DECADE], 10_000);
        assert_eq!(h.edges_ns[EDGES - 1], 100_000_000);
        for w in h.edges_ns.windows(2) {
            let ratio = w[1] as f64 / w[0] as f64;
            assert!((ratio - 10f64.powf(0.05)).abs() < 1e-3, "{w:?}");
        }
    }

    #[test]
    fn quantiles_bound_the_values_within_one_bucket() {
        let mut h = Histogram::new();
        // 990 values of 10 µs, 9 of 500 µs, 1 of 7 ms.
        for _ in 0..990 {
            h.record(10_000);
        }
        for _ in 0..9 {
            h.record(500_000);
        }
        h.record(7_000_000);
        let bucket = 10f64.powf(1.0 / BUCKETS_PER_DECADE as f64);
        let p = h.percentiles();
        assert!(p.p50_ns > 10_000 && (p.p50_ns as f64) <= 10_000.0 * bucket + 1.0);
        // The 990th value is still 10 µs.
        assert_eq!(p.p99_ns, p.p50_ns);
        // The 999th is 500 µs.
        assert!(p.p999_ns > 500_000 && (p.p999_ns as f64) <= 500_000.0 * bucket + 1.0);
        assert_eq!(p.max_ns, 7_000_000);
        assert_eq!(h.count(), 1000);
    }

    #[test]
    fn values_outside_the_range_land_in_the_end_buckets() {
        let mut h = Histogram::new();
        h.record(0);
        h.record(999);
        assert_eq!(h.quantile_ns(1.0), 999);
        h.record(250_000_000);
        assert_eq!(h.quantile_ns(1.0), 250_000_000);
        // Rank 2 of 3 is below 1 µs: the bucket's upper edge.
        assert_eq!(h.quantile_ns(0.5), 1_000);
        assert_eq!(Histogram::new().quantile_ns(0.5), 0);
    }

    #[test]
    fn a_cycle_records_both_histograms() {
        let mut t = CycleTiming::new();
        t.record(20_000, 3_000);
        t.record(40_000, 6_000);
        let s = t.summary();
        assert_eq!(s.cycles, 2);
        assert_eq!(s.latency.max_ns, 40_000);
        assert_eq!(s.compute.max_ns, 6_000);
        assert!(s.compute.p50_ns >= 3_000 && s.compute.p50_ns < 6_000);
    }
}
