//! Tick statistics: counters as atomics, latency histograms (HdrHistogram) recorded on the
//! tick thread into a local set and handed over whole, lock-free, to the readers, who merge
//! them — the tick thread never merges, resets, allocates or waits for a reader.
//!
//! # The hand-over
//! Three sets of histograms exist for a session's life: the one the tick thread records into,
//! and two that travel through two one-slot lock-free queues (`crossbeam_queue::ArrayQueue`):
//! `full` (tick → readers) and `empty` (readers → tick). Every few ticks the tick thread, if
//! `full` is free and `empty` holds a set, swaps its set for the empty one and pushes its own
//! into `full` — two queue operations and a pointer swap. A reader ([`TickStats::histograms`],
//! and so every snapshot and the metrics page) pops `full`, merges it into the cumulative
//! histograms under a mutex the tick thread never touches, resets it and pushes it into
//! `empty`. When nobody reads, the tick thread simply keeps recording into its set.

use std::sync::Mutex;

use crossbeam_queue::ArrayQueue;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use hdrhistogram::Histogram;
use serde::Serialize;
use vademecum_engine::pipeline::MAX_TOOLS;
use vademecum_proto::shm::BridgeReport;

/// Highest latency a histogram tracks (ns): 10 s; larger values are clamped.
const MAX_NS: u64 = 10_000_000_000;

fn histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1, MAX_NS, 3).expect("valid histogram bounds")
}

/// The latency histograms of a session.
#[derive(Debug, Clone)]
pub struct Histograms {
    /// Work done in a tick period (ns): the deadline tick from its start to its end, plus
    /// the answers given on arrival during the period.
    pub work: Histogram<u64>,
    /// How late a tick started after its deadline (ns): the OS wake-up floor plus any
    /// overrun of the previous tick.
    pub lateness: Histogram<u64>,
    /// From a tool state's arrival at the session to its answer leaving the tick (ns).
    pub response: Histogram<u64>,
    /// Haptic channel: from the bridge's device read to the force published (ns) — the
    /// shared-memory hop in plus the tick's work.
    pub haptic: Histogram<u64>,
}

impl Default for Histograms {
    fn default() -> Self {
        Self {
            work: histogram(),
            lateness: histogram(),
            response: histogram(),
            haptic: histogram(),
        }
    }
}

impl Histograms {
    /// Bytes of the four histograms' counts.
    pub fn heap_bytes(&self) -> usize {
        [&self.work, &self.lateness, &self.response, &self.haptic]
            .iter()
            .map(|h| h.distinct_values() * std::mem::size_of::<u64>())
            .sum()
    }

    /// Records a value (ns), clamped to the tracked range.
    pub fn record(h: &mut Histogram<u64>, ns: u64) {
        let _ = h.record(ns.clamp(1, MAX_NS));
    }

    fn merge_from(&mut self, other: &Self) {
        let _ = self.work.add(&other.work);
        let _ = self.lateness.add(&other.lateness);
        let _ = self.response.add(&other.response);
        let _ = self.haptic.add(&other.haptic);
    }

    fn reset(&mut self) {
        self.work.reset();
        self.lateness.reset();
        self.response.reset();
        self.haptic.reset();
    }
}

/// Counters and histograms shared between the tick thread and readers.
#[derive(Debug)]
pub struct TickStats {
    /// Ticks run (deadline ticks: the session's periods).
    pub ticks: AtomicU64,
    /// The tissue's steps so far (one per answer, one per period that answered none), as of
    /// the last deadline tick: what a heartbeat says is the session's now.
    pub steps: AtomicU64,
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
    /// Tool states from the haptic channel answered.
    pub haptic_answered: AtomicU64,
    /// Tool states from the haptic channel superseded by a newer one before being answered.
    pub haptic_skipped: AtomicU64,
    /// Forces that could not be published on the haptic channel.
    pub haptic_errors: AtomicU64,
    /// The latest report of each tool's bridge, by the tool's index in the scene (zero until
    /// one arrives): the first is the session's one bridge when its scene has one tool.
    pub bridges: [BridgeStats; MAX_TOOLS],
    /// CPU time of the tick thread (ns), updated every few ticks.
    pub tick_cpu_ns: AtomicU64,
    /// The co-rotational deformation (co-rotational cutting) on the frame thread.
    pub corotational: CorotationalStats,
    /// Co-rotational frames that failed (the state kept).
    pub corotational_failures: AtomicU64,
    /// Times the session fell back to its reduced fidelity ([`super::fidelity`]).
    pub fallbacks: AtomicU64,
    /// Whether it runs reduced now (the frames read it to take their prefix of the modes).
    pub reduced: AtomicBool,
    /// Periods it ran reduced.
    pub reduced_ticks: AtomicU64,
    /// Everything merged so far (readers only).
    histograms: Mutex<Histograms>,
    /// A recorded set waiting for a reader.
    full: ArrayQueue<Box<Histograms>>,
    /// A cleared set waiting for the tick thread.
    empty: ArrayQueue<Box<Histograms>>,
}

impl Default for TickStats {
    fn default() -> Self {
        let empty = ArrayQueue::new(1);
        let _ = empty.push(Box::default());
        Self {
            ticks: AtomicU64::new(0),
            steps: AtomicU64::new(0),
            misses: AtomicU64::new(0),
            answered: AtomicU64::new(0),
            rejected: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            frames: AtomicU64::new(0),
            haptic_answered: AtomicU64::new(0),
            haptic_skipped: AtomicU64::new(0),
            haptic_errors: AtomicU64::new(0),
            bridges: Default::default(),
            tick_cpu_ns: AtomicU64::new(0),
            corotational: CorotationalStats::default(),
            corotational_failures: AtomicU64::new(0),
            fallbacks: AtomicU64::new(0),
            reduced: AtomicBool::new(false),
            reduced_ticks: AtomicU64::new(0),
            histograms: Mutex::new(Histograms::default()),
            full: ArrayQueue::new(1),
            empty,
        }
    }
}

/// What the frame thread's co-rotational deformation has done (co-rotational cutting).
#[derive(Debug, Default)]
pub struct CorotationalStats {
    /// Frames advanced.
    pub frames: AtomicU64,
    /// Frames that factored on the frame thread (no fresh factor, or the kept one's
    /// correction did not lower the residual).
    pub factored: AtomicU64,
    /// Factors from the factor thread installed.
    pub installed: AtomicU64,
    /// Models rebuilt because the cut grew.
    pub rebuilt: AtomicU64,
    /// Cuts the model could not take (its model or factor could not be made): it stays at
    /// the last one.
    pub refused_cuts: AtomicU64,
    /// Pieces the cut so far set loose, held where they came loose (the last frame's count).
    pub held_pieces: AtomicU64,
    /// The last frame's relative residual (f64 bits).
    pub residual_bits: AtomicU64,
    /// Time of a frame (µs): the last, the largest, the sum.
    pub last_us: AtomicU64,
    /// The largest frame time (µs).
    pub max_us: AtomicU64,
    /// Frame times summed (µs).
    pub sum_us: AtomicU64,
    /// Frames that solved a correction at the deformation shown.
    pub corrections: AtomicU64,
    /// Their conjugate-gradient iterations (the slowest column's), summed.
    pub correction_iterations_sum: AtomicU64,
    /// The most iterations of one.
    pub correction_iterations_max: AtomicU64,
    /// Solves that did not converge (their forces carry no error estimate).
    pub corrections_unconverged: AtomicU64,
}

impl TickStats {
    /// Records a co-rotational frame that took `took`.
    pub fn record_corotational(&self, o: &vademecum_engine::pipeline::corotational::FrameOutcome, took: std::time::Duration) {
        let c = &self.corotational;
        let us = took.as_micros() as u64;
        c.frames.fetch_add(1, Ordering::Relaxed);
        c.last_us.store(us, Ordering::Relaxed);
        c.max_us.fetch_max(us, Ordering::Relaxed);
        c.sum_us.fetch_add(us, Ordering::Relaxed);
        c.installed.fetch_add(u64::from(o.installed), Ordering::Relaxed);
        c.rebuilt.fetch_add(u64::from(o.rebuilt), Ordering::Relaxed);
        c.refused_cuts.fetch_add(u64::from(o.refused_cut), Ordering::Relaxed);
        c.held_pieces.store(o.held_pieces as u64, Ordering::Relaxed);
        if let Some(s) = o.correction {
            c.corrections.fetch_add(1, Ordering::Relaxed);
            c.correction_iterations_sum.fetch_add(s.iterations as u64, Ordering::Relaxed);
            c.correction_iterations_max.fetch_max(s.iterations as u64, Ordering::Relaxed);
            c.corrections_unconverged.fetch_add(u64::from(!s.converged), Ordering::Relaxed);
        }
        if let Some(r) = o.report {
            c.factored.fetch_add(u64::from(r.factored), Ordering::Relaxed);
            c.residual_bits.store(r.residual.to_bits(), Ordering::Relaxed);
        }
    }
}

/// The latest report of a session's device bridge, field by field as atomics (a reader may
/// see fields of two consecutive reports; each is exact).
#[derive(Debug, Default)]
pub struct BridgeStats {
    words: [AtomicU64; BridgeReport::WORDS],
}

/// A bridge report as plain numbers (µs for latencies).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct BridgeSnapshot {
    /// Bridge ticks run.
    pub ticks: u64,
    /// Bridge ticks whose force was written more than a period late.
    pub deadline_misses: u64,
    /// Ticks with a fresh force.
    pub fresh_forces: u64,
    /// Ticks the watchdog held or faded the force.
    pub watchdog_ticks: u64,
    /// Device samples rejected as non-finite.
    pub rejected_non_finite: u64,
    /// Device samples whose jump was clamped.
    pub clamped_jumps: u64,
    /// Device samples clamped to the workspace.
    pub clamped_workspace: u64,
    /// Non-finite forces zeroed.
    pub rejected_forces: u64,
    /// Forces clamped to the device limit.
    pub clamped_forces: u64,
    /// Forces slewed by the rate limit.
    pub rate_limited_forces: u64,
    /// Device read → force written (µs).
    pub latency_us: Percentiles,
}

impl BridgeSnapshot {
    /// Device samples the bridge held (non-finite) or clamped (a jump, the workspace).
    pub fn input_rejections(&self) -> u64 {
        self.rejected_non_finite + self.clamped_jumps + self.clamped_workspace
    }
}

impl From<&BridgeReport> for BridgeSnapshot {
    fn from(r: &BridgeReport) -> Self {
        let us = |ns: u64| ns as f64 / 1e3;
        Self {
            ticks: r.ticks,
            deadline_misses: r.deadline_misses,
            fresh_forces: r.fresh_forces,
            watchdog_ticks: r.watchdog_ticks,
            rejected_non_finite: r.rejected_non_finite,
            clamped_jumps: r.clamped_jumps,
            clamped_workspace: r.clamped_workspace,
            rejected_forces: r.rejected_forces,
            clamped_forces: r.clamped_forces,
            rate_limited_forces: r.rate_limited_forces,
            latency_us: Percentiles {
                count: r.fresh_forces,
                p50: us(r.latency_p50_ns),
                p99: us(r.latency_p99_ns),
                p999: us(r.latency_p999_ns),
                max: us(r.latency_max_ns),
            },
        }
    }
}

impl BridgeStats {
    /// Stores a report.
    pub fn store(&self, r: &BridgeReport) {
        for (a, x) in self.words.iter().zip(r.to_words()) {
            a.store(x, Ordering::Relaxed);
        }
    }

    /// The latest report, or `None` before the first.
    pub fn snapshot(&self) -> Option<BridgeSnapshot> {
        let r = BridgeReport::from_words(std::array::from_fn(|i| self.words[i].load(Ordering::Relaxed)));
        (r.t_ns != 0).then(|| BridgeSnapshot::from(&r))
    }
}

impl TickStats {
    /// Hands the tick thread's set `local` over to the readers and gives it a cleared one,
    /// when a reader has collected the last hand-over (else `local` keeps recording).
    /// Lock-free, allocation-free, O(1): called by the tick thread every few ticks. Returns
    /// whether it handed over.
    pub fn publish(&self, local: &mut Box<Histograms>) -> bool {
        if self.full.is_full() {
            return false;
        }
        let Some(spare) = self.empty.pop() else {
            return false;
        };
        let recorded = std::mem::replace(local, spare);
        // the tick thread is the only producer of `full`, and it was free
        let _ = self.full.push(recorded);
        true
    }

    /// Merges what the tick thread recorded since its last hand-over into the cumulative
    /// histograms: for the end of a session, off the real-time path.
    pub fn finish(&self, local: &Histograms) {
        self.collect();
        if let Ok(mut h) = self.histograms.lock() {
            h.merge_from(local);
        }
    }

    /// Merges a handed-over set, if any, and returns it cleared to the tick thread.
    fn collect(&self) {
        if let Some(mut set) = self.full.pop() {
            if let Ok(mut h) = self.histograms.lock() {
                h.merge_from(&set);
            }
            set.reset();
            let _ = self.empty.push(set);
        }
    }

    /// A copy of the cumulative histograms, with the latest hand-over merged in.
    pub fn histograms(&self) -> Histograms {
        self.collect();
        self.histograms.lock().map(|h| h.clone()).unwrap_or_default()
    }

    /// Bytes of the session's histograms: the three sets the tick and the readers pass
    /// between them (module docs) and the readers' merged set, all of one size.
    pub fn histogram_bytes(&self) -> usize {
        4 * self.histograms.lock().map_or(0, |h| h.heap_bytes())
    }

    /// A summary of everything so far.
    pub fn snapshot(&self) -> StatsSnapshot {
        let h = self.histograms();
        StatsSnapshot {
            ticks: self.ticks.load(Ordering::Relaxed),
            misses: self.misses.load(Ordering::Relaxed),
            fallbacks: self.fallbacks.load(Ordering::Relaxed),
            reduced_ticks: self.reduced_ticks.load(Ordering::Relaxed),
            answered: self.answered.load(Ordering::Relaxed),
            rejected: self.rejected.load(Ordering::Relaxed),
            dropped: self.dropped.load(Ordering::Relaxed),
            frames: self.frames.load(Ordering::Relaxed),
            work_us: Percentiles::of(&h.work),
            lateness_us: Percentiles::of(&h.lateness),
            response_us: Percentiles::of(&h.response),
            haptic_answered: self.haptic_answered.load(Ordering::Relaxed),
            haptic_skipped: self.haptic_skipped.load(Ordering::Relaxed),
            haptic_us: Percentiles::of(&h.haptic),
            bridge: self.bridges[0].snapshot(),
            bridges: self
                .bridges
                .iter()
                .enumerate()
                .filter_map(|(tool, b)| b.snapshot().map(|s| (tool, s)))
                .collect(),
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
    /// Times the session fell back to its reduced fidelity.
    pub fallbacks: u64,
    /// Periods it ran reduced.
    pub reduced_ticks: u64,
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
    /// Haptic states answered.
    pub haptic_answered: u64,
    /// Haptic states superseded before being answered.
    pub haptic_skipped: u64,
    /// Bridge device read → force published by the session.
    pub haptic_us: Percentiles,
    /// The first tool's bridge's latest report (the session's one bridge).
    pub bridge: Option<BridgeSnapshot>,
    /// Every bridge's latest report, by the index of the tool it moves (those that reported).
    pub bridges: Vec<(usize, BridgeSnapshot)>,
}
