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
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::SyncSender;
use std::thread::Thread;

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
}

impl Polled for Job {
    fn start(&mut self) {
        self.tick.start(&mut self.clock);
    }

    fn poll(&mut self) -> Poll {
        self.tick.poll(&mut self.clock)
    }
}

impl Placed for Job {
    /// The loop has ended: its answers closed, it goes back to its owner with its clock, who
    /// hands its last recordings over ([`TickLoop::hand_over`]) and frees both — a worker
    /// takes no lock a reader holds and frees nothing.
    fn end(self) {
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
        Ok(Self { pool, config })
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
    pub(super) fn place(&self, job: Job) -> Result<Thread, PlaceError> {
        self.pool.place(job, Some(self.config.max_utilisation))
    }
}
