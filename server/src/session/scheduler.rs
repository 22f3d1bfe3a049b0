//! Tick workers: a few threads that each tick many sessions, instead of a thread per session.
//!
//! A session's tick work is a few µs per period, but a sleeping thread per session that
//! shares a core with others wakes late (`BENCHMARKS.md`): the threads, not the work, limit
//! how many sessions a core holds. A [`TickScheduler`] runs a fixed pool of workers (by
//! default one per core the process may use; the pool is `session::workers`, shared with the
//! frame and answer workers). Each worker owns the tick loops of the sessions placed on it and
//! runs one loop of its own:
//!
//! 1. take the sessions handed to it (a bounded channel; its session list is allocated once,
//!    [`MAX_SESSIONS_PER_WORKER`] long, so taking one allocates nothing);
//! 2. give every session its turn (`TickLoop::poll`): the tool states that arrived are
//!    answered, and the deadline tick runs when it is due;
//! 3. park until the earliest deadline of its sessions — or until a session's
//!    [`super::Session::submit`] unparks it, so a tool state is answered on arrival.
//!
//! The sessions' deadlines are spread over the period: each session placed gets the next
//! fraction of a low-discrepancy sequence ([`spread`]) as its phase on a grid shared by the
//! scheduler, so a worker's deadline ticks do not all fall at the same instant.
//!
//! A session ended (stopped, its script over) is handed back to its owner through a one-slot
//! channel, with its clock, and its last histograms are merged and both freed there: a worker
//! never frees a pipeline nor takes the lock the statistics' readers take. Each session keeps its own
//! period, deadlines, histograms and statistics, so what it observes is what it observed on a
//! thread of its own. A session is placed on the least-loaded worker (each measures its
//! utilisation, its CPU time over wall time) and stays on it; it is refused, saying the load, when
//! it would take that worker past [`SchedulerConfig::max_utilisation`] (admission control: a
//! new session is refused rather than every session degraded). Sessions with a haptic channel keep a thread of their own (they wait on the bridge),
//! and so does a session whose configuration has an `on_tick_thread` hook (the hook is
//! per-thread: CPU pinning, the counting-allocator test) — on a worker of its own, the same
//! loop.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::SyncSender;
use std::thread::Thread;
use std::time::Instant;

use vademecum_bridge::timing::RealtimeStatus;

use super::tick::{Clock, TickLoop};
pub use super::workers::{MAX_JOBS_PER_WORKER as MAX_SESSIONS_PER_WORKER, PlaceError};
use super::workers::{Placed, Poll, Polled, Pool, PoolConfig};

/// How the tick workers run.
#[derive(Debug, Clone, Copy)]
pub struct SchedulerConfig {
    /// Worker threads (at least 1).
    pub workers: usize,
    /// Pin worker `k` to CPU `k` (refused gracefully when the OS says no).
    pub pin: bool,
    /// `SCHED_FIFO` priority asked for the workers (refused gracefully when not permitted).
    pub fifo_priority: Option<i32>,
    /// Called on each worker thread before anything else (instrumentation such as the
    /// counting-allocator test of the worker loop).
    pub on_start: Option<fn()>,
    /// Admission control: a session is refused when placing it would take the least-loaded
    /// worker's measured utilisation (its CPU time over wall time) above this fraction (0.6:
    /// headroom for the OS's late wake-ups and for bursts).
    pub max_utilisation: f64,
}

impl Default for SchedulerConfig {
    /// One worker per CPU the process may use, unpinned, at normal priority.
    fn default() -> Self {
        Self {
            workers: std::thread::available_parallelism().map_or(1, |n| n.get()),
            pin: false,
            fifo_priority: None,
            on_start: None,
            max_utilisation: DEFAULT_MAX_UTILISATION,
        }
    }
}

/// The default [`SchedulerConfig::max_utilisation`].
pub const DEFAULT_MAX_UTILISATION: f64 = 0.6;

/// A session's tick loop on its way to a worker, and back.
pub(super) struct Job {
    pub tick: Box<TickLoop>,
    pub clock: Clock,
    /// Where the ended loop and its clock go back to their owner (one slot: never blocks).
    pub done: SyncSender<(Box<TickLoop>, Clock)>,
    /// Set when the loop has ended.
    pub finished: Arc<AtomicBool>,
    /// Where its deadlines fall in the period, set by the scheduler that places it (`None`: a
    /// period from its start).
    pub phase: Option<Phase>,
}

/// A tick loop's place in the period: its deadlines at `epoch + (m + fraction) · period`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Phase {
    pub epoch: Instant,
    pub fraction: f64,
}

/// The `k`-th session's phase fraction: `k · (√5 − 1)/2` modulo 1, a low-discrepancy sequence
/// — however many sessions have come (and gone), the fractions given stay spread over the
/// period (the closest two of the first `n` are more than `0.44 / n` apart, against `1 / n`
/// for an even spacing that would have to be redone at every arrival).
pub fn spread(k: u64) -> f64 {
    const GOLDEN: f64 = 0.618_033_988_749_894_9;
    (k as f64 * GOLDEN).fract()
}

impl Polled for Job {
    fn start(&mut self) {
        match self.phase {
            Some(p) => self.tick.start_at_phase(&mut self.clock, p.epoch, p.fraction),
            None => self.tick.start(&mut self.clock),
        }
    }

    fn poll(&mut self) -> Poll {
        self.tick.poll(&mut self.clock)
    }
}

impl Placed for Job {
    /// The loop has ended: its answers closed, it goes back to its owner with its clock, who
    /// hands its last recordings over ([`TickLoop::hand_over`]) and frees both — a worker
    /// takes no lock a reader holds and frees nothing.
    fn end(mut self) {
        // a device worker's session: its bridge's last report
        if let Some(mut peer) = self.tick.peer.take() {
            self.tick.keep_bridge_reports(&mut peer);
            self.tick.peer = Some(peer);
        }
        self.tick.close_answers();
        self.finished.store(true, Ordering::Release);
        // the owner may be gone (a session dropped mid-start): then it is dropped here
        let _ = self.done.try_send((self.tick, self.clock));
    }
}

/// A pool of tick workers (module docs).
#[derive(Debug)]
pub struct TickScheduler {
    pool: Pool<Job>,
    config: SchedulerConfig,
    /// The origin of every session's phase.
    epoch: Instant,
    /// Sessions placed so far (the next one's phase: [`spread`]).
    placed: AtomicU64,
}

impl TickScheduler {
    /// Starts `config.workers` workers.
    pub fn new(config: SchedulerConfig) -> std::io::Result<Self> {
        let pool = Pool::new(
            "tick-worker",
            PoolConfig {
                workers: config.workers,
                pin: config.pin,
                fifo_priority: config.fifo_priority,
                on_start: config.on_start,
            },
        )?;
        Ok(Self {
            pool,
            config,
            epoch: Instant::now(),
            placed: AtomicU64::new(0),
        })
    }

    /// How it was configured.
    pub fn config(&self) -> SchedulerConfig {
        self.config
    }

    /// Sessions on each worker.
    pub fn load(&self) -> Vec<usize> {
        self.pool.load()
    }

    /// Each worker's measured utilisation (its CPU time over wall time, over its last quarter
    /// second).
    pub fn utilisation(&self) -> Vec<f64> {
        self.pool.utilisation()
    }

    /// What the OS granted each worker (pinning, priority).
    pub fn realtime(&self) -> Vec<RealtimeStatus> {
        self.pool.realtime()
    }

    /// Hands `job` to the least-loaded worker (by measured utilisation in steps of 5 %, then by
    /// sessions) unless admitting it would take that worker past
    /// [`SchedulerConfig::max_utilisation`] — a new session is estimated to cost what that
    /// worker's sessions cost on average —; returns the thread to unpark when a tool state is
    /// queued for it. When it cannot be placed, the job is ended (its answers closed, the loop
    /// handed back) and the reason returned.
    pub(super) fn place(&self, mut job: Job) -> Result<Thread, PlaceError> {
        job.phase = Some(Phase {
            epoch: self.epoch,
            fraction: spread(self.placed.fetch_add(1, Ordering::Relaxed)),
        });
        self.pool.place(job, Some(self.config.max_utilisation))
    }
}

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use super::super::tick::phased_deadline;
    use super::spread;

    /// However many sessions have been placed, the phases given so far stay spread over the
    /// period: the closest two of the first n are more than 0.44 of an even spacing apart
    /// (the golden-ratio sequence's worst up to a thousand sessions is 0.4477, at n = 988).
    #[test]
    fn the_phases_given_stay_spread_over_the_period() {
        for n in 2..=1024u64 {
            let mut f: Vec<f64> = (0..n).map(spread).collect();
            f.sort_by(f64::total_cmp);
            let closest = (0..f.len())
                .map(|i| (f[(i + 1) % f.len()] - f[i]).rem_euclid(1.0))
                .fold(1.0, f64::min);
            assert!(closest > 0.44 / n as f64, "{n} sessions: closest phases {closest}");
            assert!(f.iter().all(|x| (0.0..1.0).contains(x)));
        }
    }

    /// A session's first deadline is on its phase's grid, between one and two periods away.
    #[test]
    fn a_phased_deadline_is_on_its_grid_a_period_or_more_away() {
        let epoch = Instant::now();
        let period = Duration::from_millis(1);
        for (since_us, fraction) in [(0, 0.0), (0, 0.5), (1234, 0.25), (999, 0.999), (5000, 0.0), (7321, 0.618)] {
            let now = epoch + Duration::from_micros(since_us);
            let d = phased_deadline(epoch, now, period, fraction);
            assert!(
                d >= now + period && d < now + 2 * period,
                "{since_us} µs, {fraction}: {:?}",
                d - now
            );
            let on_grid = (d - epoch).as_nanos() % period.as_nanos();
            let want = (fraction * 1e6) as u128;
            assert_eq!(on_grid, want, "{since_us} µs, {fraction}");
        }
    }
}
