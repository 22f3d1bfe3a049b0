//! Tick statistics: counters as atomics, latency histograms (HdrHistogram) recorded on the
//! tick thread into a local histogram and merged into the shared one with `try_lock`, so
//! the tick thread never waits for a reader.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use hdrhistogram::Histogram;
use serde::Serialize;

/// Highest latency a histogram tracks (ns): 10 s; larger values are clamped.
const MAX_NS: u64 = 10_000_000_000;

fn histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1, MAX_NS, 3).expect("valid histogram bounds")
}

/// The latency histograms of a session.
#[derive(Debug, Clone)]
pub struct Histograms {
    /// Work done in a tick, from its start to its end (ns).
    pub work: Histogram<u64>,
    /// How late a tick started after its deadline (ns): the OS wake-up floor plus any
    /// overrun of the previous tick.
    pub lateness: Histogram<u64>,
    /// From a tool state's arrival at the session to its answer leaving the tick (ns).
    pub response: Histogram<u64>,
}

impl Default for Histograms {
    fn default() -> Self {
        Self {
            work: histogram(),
            lateness: histogram(),
            response: histogram(),
        }
    }
}

impl Histograms {
    /// Records a value (ns), clamped to the tracked range.
    pub fn record(h: &mut Histogram<u64>, ns: u64) {
        let _ = h.record(ns.clamp(1, MAX_NS));
    }

    fn merge_from(&mut self, other: &Self) {
        let _ = self.work.add(&other.work);
        let _ = self.lateness.add(&other.lateness);
        let _ = self.response.add(&other.response);
    }

    fn reset(&mut self) {
        self.work.reset();
        self.lateness.reset();
        self.response.reset();
    }
}

/// Counters and histograms shared between the tick thread and readers.
#[derive(Debug, Default)]
pub struct TickStats {
    /// Ticks run.
    pub ticks: AtomicU64,
    /// Ticks that started more than one period after their deadline.
    pub misses: AtomicU64,
    /// Tool states answered.
    pub answered: AtomicU64,
    /// Tool states rejected (non-finite or out of range): answered with zero force.
    pub rejected: AtomicU64,
    /// Answers dropped because the receiver's queue was full or gone.
    pub dropped: AtomicU64,
    /// Frames produced for viewers.
    pub frames: AtomicU64,
    histograms: Mutex<Histograms>,
}

impl TickStats {
    /// Merges `local` into the shared histograms if no reader holds them (never waits), then
    /// clears `local` when merged. Called by the tick thread every few ticks.
    pub fn publish(&self, local: &mut Histograms) -> bool {
        match self.histograms.try_lock() {
            Ok(mut h) => {
                h.merge_from(local);
                local.reset();
                true
            }
            Err(_) => false,
        }
    }

    /// A copy of the shared histograms (waits for the tick thread's brief merge at most).
    pub fn histograms(&self) -> Histograms {
        self.histograms.lock().map(|h| h.clone()).unwrap_or_default()
    }

    /// A summary of everything so far.
    pub fn snapshot(&self) -> StatsSnapshot {
        let h = self.histograms();
        StatsSnapshot {
            ticks: self.ticks.load(Ordering::Relaxed),
            misses: self.misses.load(Ordering::Relaxed),
            answered: self.answered.load(Ordering::Relaxed),
            rejected: self.rejected.load(Ordering::Relaxed),
            dropped: self.dropped.load(Ordering::Relaxed),
            frames: self.frames.load(Ordering::Relaxed),
            work_us: Percentiles::of(&h.work),
            lateness_us: Percentiles::of(&h.lateness),
            response_us: Percentiles::of(&h.response),
        }
    }
}

/// Latency percentiles (µs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Percentiles {
    /// Samples.
    pub count: u64,
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// 99.9th percentile.
    pub p999: f64,
    /// Largest.
    pub max: f64,
}

impl Percentiles {
    /// Of a histogram in ns.
    pub fn of(h: &Histogram<u64>) -> Self {
        if h.is_empty() {
            return Self::default();
        }
        let us = |ns: u64| ns as f64 / 1e3;
        Self {
            count: h.len(),
            p50: us(h.value_at_quantile(0.5)),
            p99: us(h.value_at_quantile(0.99)),
            p999: us(h.value_at_quantile(0.999)),
            max: us(h.max()),
        }
    }
}

/// What [`TickStats::snapshot`] returns.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StatsSnapshot {
    /// Ticks run.
    pub ticks: u64,
    /// Deadline misses (a tick starting more than one period late).
    pub misses: u64,
    /// Tool states answered.
    pub answered: u64,
    /// Tool states rejected.
    pub rejected: u64,
    /// Answers dropped.
    pub dropped: u64,
    /// Frames produced.
    pub frames: u64,
    /// Work per tick.
    pub work_us: Percentiles,
    /// Lateness of the tick start.
    pub lateness_us: Percentiles,
    /// Tool state in → answer out.
    pub response_us: Percentiles,
}
