//! Tick workers: a few threads that each tick many sessions, instead of a thread per session.
//!
//! A session's tick work is a few µs per period, but a sleeping thread per session that
//! shares a core with others wakes late (`BENCHMARKS.md`): the threads, not the work, limit
//! how many sessions a core holds. A [`TickScheduler`] runs a fixed pool of workers (by
//! default one per core the process may use). Each worker owns the tick loops of the
//! sessions placed on it and runs one loop of its own:
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
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

use vademecum_bridge::timing::{self, RealtimeStatus};

use super::tick::{Clock, Poll, TickLoop};

/// Most sessions one worker ticks.
pub const MAX_SESSIONS_PER_WORKER: usize = 256;

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

/// How often a worker measures its utilisation.
const UTILISATION_WINDOW: Duration = Duration::from_millis(250);

/// A session's tick loop on its way to a worker, and back.
pub(super) struct Job {
    pub tick: Box<TickLoop>,
    pub clock: Clock,
    /// Where the ended loop and its clock go back to their owner (one slot: never blocks).
    pub done: SyncSender<(Box<TickLoop>, Clock)>,
    /// Set when the loop has ended.
    pub finished: Arc<AtomicBool>,
}

impl Job {
    /// The loop has ended: its answers closed, it goes back to its owner with its clock, who
    /// hands its last recordings over ([`TickLoop::hand_over`]) and frees both — a worker
    /// takes no lock a reader holds and frees nothing.
    pub fn end(self) {
        self.tick.close_answers();
        self.finished.store(true, Ordering::Release);
        // the owner may be gone (a session dropped mid-start): then it is dropped here
        let _ = self.done.try_send((self.tick, self.clock));
    }
}

/// Why a session could not be placed on a worker.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PlaceError {
    /// Admitting the session would push the least-loaded worker past the limit.
    #[error(
        "the server's tick workers are loaded: the least-loaded is busy {:.0} % of the time with \
         {sessions} session(s), and a session there costs ~{:.1} % — over the {:.0} % limit; \
         close a session, or add tick workers",
        100.0 * utilisation,
        100.0 * estimate,
        100.0 * limit
    )]
    Overloaded {
        /// The least-loaded worker's measured utilisation.
        utilisation: f64,
        /// What a session adds there (its sessions' mean).
        estimate: f64,
        /// The limit ([`SchedulerConfig::max_utilisation`]).
        limit: f64,
        /// Sessions on that worker.
        sessions: usize,
    },
    /// Every worker ticks [`MAX_SESSIONS_PER_WORKER`] sessions.
    #[error("every tick worker is full ({0} sessions each)")]
    Full(usize),
    /// The workers have stopped.
    #[error("the tick workers have stopped")]
    Stopped,
}

/// One worker, as the scheduler sees it.
#[derive(Debug)]
struct Worker {
    thread: Thread,
    inbox: SyncSender<Job>,
    shared: Arc<WorkerShared>,
    realtime: RealtimeStatus,
}

/// What a worker publishes.
#[derive(Debug, Default)]
struct WorkerShared {
    /// Sessions on it (counted when placed, until they end).
    sessions: AtomicUsize,
    /// Its utilisation over its last window, as `f64` bits.
    utilisation: AtomicU64,
}

impl WorkerShared {
    fn utilisation(&self) -> f64 {
        f64::from_bits(self.utilisation.load(Ordering::Relaxed))
    }
}

/// A pool of tick workers (module docs).
#[derive(Debug)]
pub struct TickScheduler {
    workers: Vec<Worker>,
    handles: Vec<JoinHandle<()>>,
    config: SchedulerConfig,
}

impl TickScheduler {
    /// Starts `config.workers` workers.
    pub fn new(config: SchedulerConfig) -> std::io::Result<Self> {
        let mut workers = Vec::new();
        let mut handles = Vec::new();
        for k in 0..config.workers.max(1) {
            let (inbox, rx) = std::sync::mpsc::sync_channel::<Job>(MAX_SESSIONS_PER_WORKER);
            let shared = Arc::new(WorkerShared::default());
            let (granted_tx, granted_rx) = std::sync::mpsc::sync_channel(1);
            let published = shared.clone();
            let cpu = config.pin.then_some(k);
            let fifo = config.fifo_priority;
            let on_start = config.on_start;
            let handle = std::thread::Builder::new().name(format!("tick-worker-{k}")).spawn(move || {
                if let Some(init) = on_start {
                    init();
                }
                let _ = granted_tx.send(timing::request_realtime(fifo, cpu));
                run_worker(&rx, &published);
            })?;
            let realtime = granted_rx.recv().unwrap_or_else(|_| RealtimeStatus {
                fifo: Err("the worker ended at once".into()),
                cpu: Ok(None),
            });
            workers.push(Worker {
                thread: handle.thread().clone(),
                inbox,
                shared,
                realtime,
            });
            handles.push(handle);
        }
        Ok(Self { workers, handles, config })
    }

    /// How it was configured.
    pub fn config(&self) -> SchedulerConfig {
        self.config
    }

    /// Sessions on each worker.
    pub fn load(&self) -> Vec<usize> {
        self.workers.iter().map(|w| w.shared.sessions.load(Ordering::Relaxed)).collect()
    }

    /// Each worker's measured utilisation (its CPU time over wall time, over its last quarter
    /// second).
    pub fn utilisation(&self) -> Vec<f64> {
        self.workers.iter().map(|w| w.shared.utilisation()).collect()
    }

    /// What the OS granted each worker (pinning, priority).
    pub fn realtime(&self) -> Vec<RealtimeStatus> {
        self.workers.iter().map(|w| w.realtime.clone()).collect()
    }

    /// Hands `job` to the least-loaded worker (by measured utilisation in steps of 5 %, then by
    /// sessions)
    /// unless admitting it would take that worker past
    /// [`SchedulerConfig::max_utilisation`] — a new session is estimated to cost what that
    /// worker's sessions cost on average —; returns the thread to unpark when a tool state is
    /// queued for it. When it cannot be placed, the job is ended (its answers closed, the loop
    /// handed back) and the reason returned.
    pub(super) fn place(&self, job: Job) -> Result<Thread, PlaceError> {
        // utilisations within a step of 5 % count as equal: then the fewer sessions
        let Some(w) = self
            .workers
            .iter()
            .min_by_key(|w| ((w.shared.utilisation() / 0.05) as u64, w.shared.sessions.load(Ordering::Relaxed)))
        else {
            job.end();
            return Err(PlaceError::Stopped);
        };
        let sessions = w.shared.sessions.load(Ordering::Relaxed);
        let utilisation = w.shared.utilisation();
        let estimate = if sessions > 0 { utilisation / sessions as f64 } else { 0.0 };
        let limit = self.config.max_utilisation;
        if utilisation + estimate > limit {
            job.end();
            return Err(PlaceError::Overloaded {
                utilisation,
                estimate,
                limit,
                sessions,
            });
        }
        if w.shared.sessions.fetch_add(1, Ordering::Relaxed) >= MAX_SESSIONS_PER_WORKER {
            w.shared.sessions.fetch_sub(1, Ordering::Relaxed);
            job.end();
            return Err(PlaceError::Full(MAX_SESSIONS_PER_WORKER));
        }
        match w.inbox.try_send(job) {
            Ok(()) => {
                w.thread.unpark();
                Ok(w.thread.clone())
            }
            Err(e) => {
                w.shared.sessions.fetch_sub(1, Ordering::Relaxed);
                let (TrySendError::Full(job) | TrySendError::Disconnected(job)) = e;
                job.end();
                Err(PlaceError::Stopped)
            }
        }
    }
}

impl Drop for TickScheduler {
    /// The workers end once their sessions have ended.
    fn drop(&mut self) {
        let threads: Vec<Thread> = self.workers.drain(..).map(|w| w.thread).collect();
        for t in &threads {
            t.unpark();
        }
        for h in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}

/// Runs `job` on a worker of its own on this thread, until it ends.
pub(super) fn run_alone(job: Job) {
    let (tx, rx) = std::sync::mpsc::sync_channel(1);
    let _ = tx.send(job);
    drop(tx);
    let shared = WorkerShared::default();
    shared.sessions.store(1, Ordering::Relaxed);
    run_worker(&rx, &shared);
}

/// A worker's loop (module docs): until its inbox is closed and its last session ended.
/// It measures its utilisation — its thread's CPU time over wall time, every quarter second
/// (one clock read then: CPU time, unlike wake-to-park time, does not count the time the OS
/// gave to others) — and publishes it for admission control.
fn run_worker(inbox: &Receiver<Job>, shared: &WorkerShared) {
    let mut jobs: Vec<Job> = Vec::with_capacity(MAX_SESSIONS_PER_WORKER);
    let mut open = true;
    let (mut window_start, mut cpu_start) = (Instant::now(), timing::thread_cpu_time());
    loop {
        while open && jobs.len() < MAX_SESSIONS_PER_WORKER {
            match inbox.try_recv() {
                Ok(mut job) => {
                    job.tick.start(&mut job.clock);
                    jobs.push(job);
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => open = false,
            }
        }
        let mut wake: Option<Instant> = None;
        let mut k = 0;
        while k < jobs.len() {
            let job = &mut jobs[k];
            match job.tick.poll(&mut job.clock) {
                Poll::At(t) => {
                    wake = Some(wake.map_or(t, |w| w.min(t)));
                    k += 1;
                }
                Poll::Ended => {
                    jobs.swap_remove(k).end();
                    shared.sessions.fetch_sub(1, Ordering::Relaxed);
                }
            }
        }
        let now = Instant::now();
        let window = now - window_start;
        if window >= UTILISATION_WINDOW {
            let cpu = timing::thread_cpu_time();
            let u = (cpu.saturating_sub(cpu_start)).as_secs_f64() / window.as_secs_f64();
            shared.utilisation.store(u.to_bits(), Ordering::Relaxed);
            (window_start, cpu_start) = (now, cpu);
        }
        match wake {
            Some(t) => {
                let now = Instant::now();
                if t > now {
                    std::thread::park_timeout(t - now);
                }
            }
            None if open => {
                // idle: nothing to measure until a session comes
                shared.utilisation.store(0f64.to_bits(), Ordering::Relaxed);
                std::thread::park();
                (window_start, cpu_start) = (Instant::now(), timing::thread_cpu_time());
            }
            None => return,
        }
    }
}
