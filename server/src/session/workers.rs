//! A pool of worker threads that each run many polled jobs: the machinery shared by the tick
//! workers ([`super::scheduler`]), the frame and answer workers, and the device workers
//! ([`super::devices`]).
//!
//! A job is polled ([`Polled::poll`]): it does what is due and says when it wants its next
//! turn. Each worker owns the jobs placed on it and runs one loop (`run_jobs`):
//!
//! 1. take the jobs handed to it (a bounded channel; its job list is allocated once,
//!    [`MAX_JOBS_PER_WORKER`] long, so taking one allocates nothing);
//! 2. give every job its turn; a job that has ended is handed to [`Placed::end`];
//! 3. park until the earliest wake-up its jobs asked for — or until someone unparks it (a
//!    session's submit, a session closing). A device worker gives its turns and waits its
//!    own way (a [`Waiter`]: blocked on its bridges' events), the rest of the loop the same.
//!
//! Each worker measures its utilisation — its thread's CPU time over wall time, every quarter
//! second (one clock read then: CPU time, unlike wake-to-park time, does not count the time
//! the OS gave to others) — and publishes it with its job count, for placement and admission
//! control.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

use vademecum_bridge::timing::{self, RealtimeStatus};

/// Most jobs one worker runs.
pub const MAX_JOBS_PER_WORKER: usize = 256;

/// How often a worker measures its utilisation.
const UTILISATION_WINDOW: Duration = Duration::from_millis(250);

/// What a worker does next with a job ([`Polled::poll`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Poll {
    /// Give it a turn again at this instant.
    At(Instant),
    /// It has ended.
    Ended,
}

/// A job a pool can place on a worker.
pub(super) trait Placed: Send + 'static {
    /// The job has ended, or could not be placed: hand it back to its owner.
    fn end(self);
}

/// A job a worker runs in turns.
pub(super) trait Polled: Placed {
    /// Called once on the worker that takes the job, before its first turn.
    fn start(&mut self);
    /// A turn: do what is due, say when the next turn is.
    fn poll(&mut self) -> Poll;
}

/// A worker's loop: runs the jobs its inbox hands it, publishing what [`WorkerShared`] holds,
/// until the inbox is closed and its last job ended.
pub(super) type WorkerLoop<J> = fn(&Receiver<J>, &WorkerShared);

/// How a pool's workers run.
#[derive(Debug, Clone, Copy)]
pub(super) struct PoolConfig {
    /// Worker threads (at least 1).
    pub workers: usize,
    /// Pin worker `k` to CPU `k` (refused gracefully when the OS says no).
    pub pin: bool,
    /// `SCHED_FIFO` priority asked for the workers (refused gracefully when not permitted).
    pub fifo_priority: Option<i32>,
    /// Called on each worker thread before anything else.
    pub on_start: Option<fn()>,
}

impl PoolConfig {
    /// `workers` unpinned workers at normal priority.
    pub fn plain(workers: usize) -> Self {
        Self {
            workers,
            pin: false,
            fifo_priority: None,
            on_start: None,
        }
    }
}

/// Why a job could not be placed on a worker.
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
        /// The limit (`SchedulerConfig::max_utilisation`).
        limit: f64,
        /// Sessions on that worker.
        sessions: usize,
    },
    /// Every worker runs [`MAX_JOBS_PER_WORKER`] jobs.
    #[error("every worker is full ({0} sessions each)")]
    Full(usize),
    /// The workers have stopped.
    #[error("the workers have stopped")]
    Stopped,
}

/// One worker, as the pool sees it.
struct Worker<J> {
    thread: Thread,
    inbox: SyncSender<J>,
    shared: Arc<WorkerShared>,
    realtime: RealtimeStatus,
}

/// What a worker publishes.
#[derive(Debug, Default)]
pub(super) struct WorkerShared {
    /// Jobs on it (counted when placed, until they end).
    jobs: AtomicUsize,
    /// Its utilisation over its last window, as `f64` bits.
    utilisation: AtomicU64,
}

impl WorkerShared {
    fn utilisation(&self) -> f64 {
        f64::from_bits(self.utilisation.load(Ordering::Relaxed))
    }
}

/// A worker's utilisation measurement: its thread's CPU time over wall time, published every
/// [`UTILISATION_WINDOW`] (one clock read in between).
struct Utilisation {
    window_start: Instant,
    cpu_start: Duration,
}

impl Utilisation {
    /// Starts a window now.
    fn start() -> Self {
        Self {
            window_start: Instant::now(),
            cpu_start: timing::thread_cpu_time(),
        }
    }

    /// Publishes the utilisation when a window has passed.
    fn update(&mut self, shared: &WorkerShared) {
        let now = Instant::now();
        let window = now - self.window_start;
        if window >= UTILISATION_WINDOW {
            let cpu = timing::thread_cpu_time();
            let u = (cpu.saturating_sub(self.cpu_start)).as_secs_f64() / window.as_secs_f64();
            shared.utilisation.store(u.to_bits(), Ordering::Relaxed);
            (self.window_start, self.cpu_start) = (now, cpu);
        }
    }

    /// The worker has no job: publishes 0 and parks until one comes, then starts a new window.
    fn idle(&mut self, shared: &WorkerShared) {
        shared.utilisation.store(0f64.to_bits(), Ordering::Relaxed);
        std::thread::park();
        *self = Self::start();
    }
}

/// A pool of workers running jobs of type `J` (module docs).
pub(super) struct Pool<J> {
    workers: Vec<Worker<J>>,
    handles: Vec<JoinHandle<()>>,
}

impl<J> std::fmt::Debug for Pool<J> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pool")
            .field("load", &self.load())
            .field("utilisation", &self.utilisation())
            .field("realtime", &self.realtime())
            .finish()
    }
}

impl<J> Pool<J> {
    /// Jobs on each worker.
    pub fn load(&self) -> Vec<usize> {
        self.workers.iter().map(|w| w.shared.jobs.load(Ordering::Relaxed)).collect()
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

    /// What the OS granted the worker running on `thread`.
    pub fn realtime_of(&self, thread: &Thread) -> Option<RealtimeStatus> {
        self.workers
            .iter()
            .find(|w| w.thread.id() == thread.id())
            .map(|w| w.realtime.clone())
    }
}

impl<J: Polled> Pool<J> {
    /// Starts `config.workers` workers running [`run_worker`], named `{name}-{k}`.
    pub fn new(name: &str, config: PoolConfig) -> std::io::Result<Self> {
        Self::with_loop(name, config, run_worker::<J>)
    }
}

impl<J: Placed> Pool<J> {
    /// Starts `config.workers` workers running `body`, named `{name}-{k}`.
    pub fn with_loop(name: &str, config: PoolConfig, body: WorkerLoop<J>) -> std::io::Result<Self> {
        let mut workers = Vec::new();
        let mut handles = Vec::new();
        for k in 0..config.workers.max(1) {
            let (inbox, rx) = std::sync::mpsc::sync_channel::<J>(MAX_JOBS_PER_WORKER);
            let shared = Arc::new(WorkerShared::default());
            let (granted_tx, granted_rx) = std::sync::mpsc::sync_channel(1);
            let published = shared.clone();
            let cpu = config.pin.then_some(k);
            let (fifo, on_start) = (config.fifo_priority, config.on_start);
            let handle = std::thread::Builder::new().name(format!("{name}-{k}")).spawn(move || {
                if let Some(init) = on_start {
                    init();
                }
                let _ = granted_tx.send(timing::request_realtime(fifo, cpu));
                body(&rx, &published);
            })?;
            let realtime = granted_rx.recv().unwrap_or(RealtimeStatus {
                fifo: Err(timing::Refused::Unreported("the worker ended at once")),
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
        Ok(Self { workers, handles })
    }

    /// Hands `job` to the least-loaded worker (by measured utilisation in steps of 5 %, then by
    /// jobs) unless admitting it would take that worker's utilisation past `limit` — a new
    /// job is estimated to cost what that worker's jobs cost on average —; returns the thread
    /// to unpark when the job has something to do. When it cannot be placed, the job is
    /// ended and the reason returned.
    pub fn place(&self, job: J, limit: Option<f64>) -> Result<Thread, PlaceError> {
        // utilisations within a step of 5 % count as equal: then the fewer jobs
        let Some(w) = self
            .workers
            .iter()
            .min_by_key(|w| ((w.shared.utilisation() / 0.05) as u64, w.shared.jobs.load(Ordering::Relaxed)))
        else {
            job.end();
            return Err(PlaceError::Stopped);
        };
        let sessions = w.shared.jobs.load(Ordering::Relaxed);
        let utilisation = w.shared.utilisation();
        let estimate = if sessions > 0 { utilisation / sessions as f64 } else { 0.0 };
        if let Some(limit) = limit
            && utilisation + estimate > limit
        {
            job.end();
            return Err(PlaceError::Overloaded {
                utilisation,
                estimate,
                limit,
                sessions,
            });
        }
        if w.shared.jobs.fetch_add(1, Ordering::Relaxed) >= MAX_JOBS_PER_WORKER {
            w.shared.jobs.fetch_sub(1, Ordering::Relaxed);
            job.end();
            return Err(PlaceError::Full(MAX_JOBS_PER_WORKER));
        }
        match w.inbox.try_send(job) {
            Ok(()) => {
                w.thread.unpark();
                Ok(w.thread.clone())
            }
            Err(e) => {
                w.shared.jobs.fetch_sub(1, Ordering::Relaxed);
                let (TrySendError::Full(job) | TrySendError::Disconnected(job)) = e;
                job.end();
                Err(PlaceError::Stopped)
            }
        }
    }
}

impl<J> Drop for Pool<J> {
    /// The workers end once their jobs have ended.
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
pub(super) fn run_alone<J: Polled>(job: J) {
    let (tx, rx) = std::sync::mpsc::sync_channel(1);
    let _ = tx.send(job);
    drop(tx);
    let shared = WorkerShared::default();
    shared.jobs.store(1, Ordering::Relaxed);
    run_worker(&rx, &shared);
}

/// How a worker's loop gives its jobs their turns and waits between them, with what it keeps
/// per job for that (in the order of the loop's job list).
pub(super) trait Waiter<J> {
    /// A job was taken: it is now the last of the list.
    fn taken(&mut self, _job: &J) {}
    /// The turn of job `k` of the list.
    fn turn(&mut self, k: usize, job: &mut J) -> Poll;
    /// Job `k` has ended: the list's last job takes its place.
    fn removed(&mut self, _k: usize) {}
    /// Waits until `until`, or until woken.
    fn wait(&mut self, until: Instant);
}

/// The plain worker's way: [`Polled::poll`] each job, park until the earliest wake-up (a
/// session's submit or close unparks the worker).
struct Park;

impl<J: Polled> Waiter<J> for Park {
    fn turn(&mut self, _k: usize, job: &mut J) -> Poll {
        job.poll()
    }

    fn wait(&mut self, until: Instant) {
        let now = Instant::now();
        if until > now {
            std::thread::park_timeout(until - now);
        }
    }
}

/// A worker's loop (module docs).
fn run_worker<J: Polled>(inbox: &Receiver<J>, shared: &WorkerShared) {
    run_jobs(inbox, shared, &mut Park);
}

/// The loop every worker runs (module docs), giving turns and waiting the `waiter`'s way:
/// until its inbox is closed and its last job ended.
pub(super) fn run_jobs<J: Polled, W: Waiter<J>>(inbox: &Receiver<J>, shared: &WorkerShared, waiter: &mut W) {
    let mut jobs: Vec<J> = Vec::with_capacity(MAX_JOBS_PER_WORKER);
    let mut open = true;
    let mut utilisation = Utilisation::start();
    loop {
        while open && jobs.len() < MAX_JOBS_PER_WORKER {
            match inbox.try_recv() {
                Ok(mut job) => {
                    job.start();
                    waiter.taken(&job);
                    jobs.push(job);
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => open = false,
            }
        }
        let mut wake: Option<Instant> = None;
        let mut k = 0;
        while k < jobs.len() {
            match waiter.turn(k, &mut jobs[k]) {
                Poll::At(t) => {
                    wake = Some(wake.map_or(t, |w| w.min(t)));
                    k += 1;
                }
                Poll::Ended => {
                    waiter.removed(k);
                    jobs.swap_remove(k).end();
                    shared.jobs.fetch_sub(1, Ordering::Relaxed);
                }
            }
        }
        utilisation.update(shared);
        match wake {
            Some(t) => waiter.wait(t),
            // idle: nothing to measure until a job comes
            None if open => utilisation.idle(shared),
            None => return,
        }
    }
}
