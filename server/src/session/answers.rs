//! How answers leave the tick thread: a preallocated lock-free ring, drained by a dispatcher
//! thread that routes each answer to the stream that asked for it.
//!
//! The tick thread must not allocate, take a lock that another thread can hold, or pay for
//! waking an async task (tokio's wake-up of a task from outside the runtime goes through the
//! runtime's inject queue, a mutex, and a futex). So it only does this:
//!
//! 1. `push` the answer, tagged with its [`StreamId`], into the session's `AnswerRing` (a
//!    bounded `crossbeam_queue::ArrayQueue`, allocated once when the session starts: a push is
//!    a few atomic operations and never allocates);
//! 2. once per tick that answered anything, `unpark` the dispatcher thread (one atomic swap;
//!    one `futex` wake-up when the dispatcher sleeps — a syscall timed inside the tick's work).
//!
//! The **dispatcher** (a session's turn on an answer worker shared with other sessions,
//! [`AnswerWorkers`], or a thread of the session's own; not real-time) pops the ring and hands each
//! answer to its stream's tokio channel with `try_send` — the allocation, the runtime's lock
//! and the task wake-up all happen there. A stream that stops reading loses answers (counted in
//! [`TickStats::dropped`]) and never slows another stream or the tick. Streams register and
//! unregister through a mutex that only async tasks and the dispatcher take.
//!
//! Why one ring per session rather than one per stream: a per-stream ring would travel with
//! each command as a shared handle, and when its stream had gone, the tick thread could drop
//! the last reference and free the ring (a deallocation and a socket or futex close on the
//! tick). With one ring allocated for the session's life and streams named by id, the tick
//! thread never frees anything; an answer for a stream that has gone is discarded by the
//! dispatcher. The queue is multi-producer capable but used by one producer (the tick thread)
//! and one consumer (the dispatcher).
//!
//! Order: answers are pushed in the order the tick computes them and the dispatcher pops in
//! that order, so each stream receives its answers in submission order.
//!
//! Shutdown: when the tick loop ends it raises `AnswerRing::finish`; the dispatcher drains
//! what is left, then drops every stream's sender, so a stream's receiver ends (`None`) only
//! after every answer the tick computed has been delivered.

use std::collections::HashMap;
use std::ops::{Deref, DerefMut};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::SyncSender;
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};
use std::thread::Thread;
use std::time::{Duration, Instant};

use crossbeam_queue::ArrayQueue;
use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TrySendError;

use super::stats::TickStats;
use super::workers::{PlaceError, Placed, Poll, Polled, Pool, PoolConfig};
use super::{Answer, SubmitError};

/// The longest the dispatcher sleeps without being woken: a safety net (a lost wake-up
/// would delay answers by this much, never lose them).
const DISPATCHER_NAP: Duration = Duration::from_millis(50);

/// A stream registered for answers (never reused within a session, so an answer for a stream
/// that has gone can never reach a newer one).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StreamId(u64);

/// The tick thread's end: the ring and the dispatcher to wake.
#[derive(Debug)]
pub(super) struct AnswerRing {
    queue: ArrayQueue<(StreamId, Answer)>,
    dispatcher: OnceLock<Thread>,
    finished: AtomicBool,
    stats: Arc<TickStats>,
}

impl AnswerRing {
    /// A ring of `capacity` answers (allocated now, once).
    pub fn new(capacity: usize, stats: Arc<TickStats>) -> Self {
        Self {
            queue: ArrayQueue::new(capacity.max(1)),
            dispatcher: OnceLock::new(),
            finished: AtomicBool::new(false),
            stats,
        }
    }

    /// How many answers it holds.
    pub fn capacity(&self) -> usize {
        self.queue.capacity()
    }

    /// Queues an answer for `to` (tick thread). A full ring drops it, counted.
    pub fn push(&self, to: StreamId, a: Answer) {
        if self.queue.push((to, a)).is_err() {
            self.stats.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Wakes the dispatcher (tick thread, once per tick that pushed).
    pub fn wake(&self) {
        if let Some(t) = self.dispatcher.get() {
            t.unpark();
        }
    }

    /// The tick loop has ended: the dispatcher drains the ring and closes every stream.
    pub fn finish(&self) {
        self.finished.store(true, Ordering::Release);
        self.wake();
    }
}

/// The streams' senders, by id (`None` once the dispatcher has stopped: no new stream).
type Routes = Mutex<Option<HashMap<StreamId, mpsc::Sender<Answer>>>>;

/// The async side's end: registration of streams.
#[derive(Debug)]
pub(super) struct Router {
    routes: Routes,
    next: AtomicU64,
}

impl Router {
    pub fn new() -> Self {
        Self {
            routes: Mutex::new(Some(HashMap::new())),
            next: AtomicU64::new(0),
        }
    }

    fn routes(&self) -> MutexGuard<'_, Option<HashMap<StreamId, mpsc::Sender<Answer>>>> {
        // a panic elsewhere while holding it leaves a map that is still consistent
        self.routes.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Registers `tx` as a stream's sender.
    pub fn register(&self, tx: mpsc::Sender<Answer>) -> Result<StreamId, SubmitError> {
        let id = StreamId(self.next.fetch_add(1, Ordering::Relaxed));
        match self.routes().as_mut() {
            Some(m) => {
                m.insert(id, tx);
                Ok(id)
            }
            None => Err(SubmitError::Closed),
        }
    }

    fn unregister(&self, id: StreamId) {
        if let Some(m) = self.routes().as_mut() {
            m.remove(&id);
        }
    }
}

/// A session's dispatcher on its way to an answer worker (or a thread of its own), and the
/// signal that it has ended.
pub(super) struct Dispatcher {
    pub ring: Arc<AnswerRing>,
    pub router: Arc<Router>,
    /// Signalled once it has delivered every answer and closed every stream.
    pub done: SyncSender<()>,
}

impl Dispatcher {
    /// Runs it on a thread of its own named `name` (it signals `done` when it ends).
    pub fn spawn(self, name: String) {
        let ring = self.ring.clone();
        let handle = std::thread::Builder::new()
            .name(name)
            .spawn(move || super::workers::run_alone(self))
            .expect("the OS can start a thread");
        let _ = ring.dispatcher.set(handle.thread().clone());
    }
}

impl Polled for Dispatcher {
    fn start(&mut self) {}

    /// Routes everything in the ring; after the tick loop has finished, routes what is left
    /// and closes every stream (dropping the senders ends every stream's receiver, after its
    /// last answer). Woken by the tick ([`AnswerRing::wake`]); looks again after a nap anyway
    /// (a lost wake-up would delay answers by that much, never lose them).
    fn poll(&mut self) -> Poll {
        let (ring, router) = (&self.ring, &self.router);
        let finished = ring.finished.load(Ordering::Acquire);
        if !ring.queue.is_empty() {
            let routes = router.routes();
            while let Some((id, a)) = ring.queue.pop() {
                let Some(tx) = routes.as_ref().and_then(|m| m.get(&id)) else {
                    continue; // the stream has gone: nobody waits for this answer
                };
                match tx.try_send(a) {
                    Ok(()) | Err(TrySendError::Closed(_)) => {}
                    Err(TrySendError::Full(_)) => {
                        ring.stats.dropped.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
        }
        if finished {
            router.routes().take();
            return Poll::Ended;
        }
        Poll::At(Instant::now() + DISPATCHER_NAP)
    }
}

impl Placed for Dispatcher {
    fn end(self) {
        // placed but its pool stopped: close the streams all the same
        self.router.routes().take();
        let _ = self.done.try_send(());
    }
}

/// A pool of answer workers: a few threads that each dispatch the answers of many sessions
/// (module docs), instead of a thread per session.
#[derive(Debug)]
pub struct AnswerWorkers {
    pool: Pool<Dispatcher>,
}

impl AnswerWorkers {
    /// Starts `workers` workers at normal priority.
    pub fn new(workers: usize) -> std::io::Result<Self> {
        let pool = Pool::new("answer-worker", PoolConfig::plain(workers))?;
        Ok(Self { pool })
    }

    /// Sessions on each worker.
    pub fn load(&self) -> Vec<usize> {
        self.pool.load()
    }

    /// Hands `d` to the least-loaded worker, which the ring then wakes.
    pub(super) fn place(&self, d: Dispatcher) -> Result<(), PlaceError> {
        let ring = d.ring.clone();
        let thread = self.pool.place(d, None)?;
        let _ = ring.dispatcher.set(thread);
        Ok(())
    }
}

/// A stream's answers: a tokio receiver, unregistered when dropped. Its receiver ends
/// (`None`) when the session has stopped and every answer computed was delivered.
#[derive(Debug)]
pub struct AnswerStream {
    id: StreamId,
    rx: mpsc::Receiver<Answer>,
    router: Arc<Router>,
}

impl AnswerStream {
    pub(super) fn open(router: &Arc<Router>, capacity: usize) -> Result<Self, SubmitError> {
        let (tx, rx) = mpsc::channel(capacity.max(1));
        let id = router.register(tx)?;
        Ok(Self {
            id,
            rx,
            router: router.clone(),
        })
    }

    /// The id to put in [`ToolCommand::reply`](super::ToolCommand::reply).
    pub fn id(&self) -> StreamId {
        self.id
    }
}

impl Deref for AnswerStream {
    type Target = mpsc::Receiver<Answer>;
    fn deref(&self) -> &Self::Target {
        &self.rx
    }
}

impl DerefMut for AnswerStream {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.rx
    }
}

impl Drop for AnswerStream {
    fn drop(&mut self) {
        self.router.unregister(self.id);
    }
}
