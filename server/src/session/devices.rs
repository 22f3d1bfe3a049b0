//! Device workers: a few threads that each tick many sessions driven by device bridges,
//! blocked on all their bridges' events at once — instead of a thread per device session.
//!
//! A device session answers its bridge's tool state the moment it arrives (the force goes back
//! in the same bridge tick), so its tick loop cannot sleep to a deadline like a gRPC session
//! on a tick worker ([`super::scheduler`]): it waits for the bridge. On a thread of its own
//! it waits with the session's strategy (polling, or blocked on the bridge's `wake` event:
//! [`vademecum_bridge::peer`]). Many device sessions on one host want the event wait —
//! polling threads take the cores the ticks need — and then a thread each is only a blocked
//! thread each. A device worker runs the event wait for many sessions at once:
//!
//! 1. take the sessions handed to it, their haptic channels opened by whoever started them
//!    (opening one takes milliseconds of file and socket work: never on the worker); its
//!    session list and wait list are allocated once, [`MAX_DEVICES_PER_WORKER`] long, so
//!    taking one allocates nothing;
//! 2. give every session its turn (`TickLoop::poll_device`): the bridge's state that
//!    arrived is answered at once, a tick of its own (as on a thread of its own); otherwise
//!    the deadline tick runs when it is due (the force stays fresh while the bridge pauses,
//!    queued gRPC tool states are answered);
//! 3. block in `ppoll(2)` on the wake events of all its sessions until the earliest of their
//!    deadlines — a bridge's state wakes it at once.
//!
//! A session placed, or stopped, is seen at the worker's next wake-up: within a period and a
//! half (every device session has a deadline that close). A stopped session's loop goes back
//! to its owner with its channel (`Job::end`), which closes it there. A session is placed on the
//! least-loaded worker (utilisation, then sessions) and stays there; the workers ask for
//! `SCHED_FIFO` like a device session's own thread (refused gracefully).

use std::sync::mpsc::Receiver;
use std::thread::Thread;
use std::time::Instant;

use vademecum_bridge::peer::HapticPeer;
use vademecum_bridge::timing::RealtimeStatus;
use vademecum_engine::pipeline::MAX_TOOLS;

use super::scheduler::Job;
use super::workers::{PlaceError, Placed, Poll, Pool, PoolConfig, Waiter, WorkerShared, run_jobs};

/// Most device sessions one worker runs (the pool's limit: a session beyond it is refused).
pub const MAX_DEVICES_PER_WORKER: usize = super::workers::MAX_JOBS_PER_WORKER;

/// How the device workers run.
#[derive(Debug, Clone, Copy)]
pub struct DeviceWorkersConfig {
    /// Worker threads (at least 1).
    pub workers: usize,
    /// `SCHED_FIFO` priority asked for the workers (refused gracefully when not permitted).
    pub fifo_priority: Option<i32>,
    /// Called on each worker thread before anything else (instrumentation such as the
    /// counting-allocator test of the worker loop).
    pub on_start: Option<fn()>,
}

/// A pool of device workers (module docs).
#[derive(Debug)]
pub struct DeviceWorkers {
    pool: Pool<Job>,
}

impl DeviceWorkers {
    /// Starts `config.workers` workers.
    pub fn new(config: DeviceWorkersConfig) -> std::io::Result<Self> {
        let pool = Pool::with_loop(
            "device-worker",
            PoolConfig {
                workers: config.workers,
                pin: false,
                fifo_priority: config.fifo_priority,
                on_start: config.on_start,
            },
            run_device_worker,
        )?;
        Ok(Self { pool })
    }

    /// Device sessions on each worker.
    pub fn load(&self) -> Vec<usize> {
        self.pool.load()
    }

    /// What the OS granted each worker.
    pub fn realtime(&self) -> Vec<RealtimeStatus> {
        self.pool.realtime()
    }

    /// Hands a device session's tick loop (its haptic peer opened with the event wait) to the
    /// least-loaded worker; returns that worker's thread and what the OS granted it. When it
    /// cannot be placed, the job is ended and the reason returned.
    pub(super) fn place(&self, job: Job) -> Result<(Thread, RealtimeStatus), PlaceError> {
        if job.tick.peer.as_ref().and_then(|p| p.wake_fd()).is_none() {
            // without the wake event the worker would never hear its bridge
            job.end();
            return Err(PlaceError::Stopped);
        }
        let thread = self.pool.place(job, None)?;
        let realtime = self.pool.realtime_of(&thread).unwrap_or(RealtimeStatus {
            fifo: Err(vademecum_bridge::timing::Refused::Unreported("unknown worker")),
            cpu: Ok(None),
        });
        Ok((thread, realtime))
    }
}

/// A device worker's loop (module docs): the workers' loop, waiting on the bridges.
fn run_device_worker(inbox: &Receiver<Job>, shared: &WorkerShared) {
    // no tick of the haptic path takes a fault on a stack page seen for the first time
    vademecum_bridge::timing::prefault_stack();
    let mut bridges = Bridges {
        fds: Vec::with_capacity(MAX_DEVICES_PER_WORKER * MAX_TOOLS),
    };
    run_jobs(inbox, shared, &mut bridges);
}

/// What a device worker waits on: the wake events of each session's bridges (one per tool
/// channel), [`MAX_TOOLS`] slots per session in the order of its session list (unused slots
/// hold −1, which poll(2) ignores).
struct Bridges {
    fds: Vec<libc::pollfd>,
}

impl Waiter<Job> for Bridges {
    fn taken(&mut self, job: &Job) {
        let fd = |p: Option<&HapticPeer>| libc::pollfd {
            // the first is checked by `place`; a negative descriptor is ignored by poll(2)
            fd: p.and_then(|p| p.wake_fd()).unwrap_or(-1),
            events: libc::POLLIN,
            revents: 0,
        };
        self.fds.push(fd(job.tick.peer.as_ref()));
        for slot in 1..MAX_TOOLS {
            self.fds.push(fd(job.tick.others.get(slot - 1).map(|(_, p)| p)));
        }
    }

    fn turn(&mut self, k: usize, job: &mut Job) -> Poll {
        let mut woken = 0u32;
        for (slot, f) in self.fds[k * MAX_TOOLS..(k + 1) * MAX_TOOLS].iter_mut().enumerate() {
            if std::mem::take(&mut f.revents) != 0 {
                woken |= 1 << slot;
            }
        }
        job.tick.poll_device(&mut job.clock, woken)
    }

    fn removed(&mut self, k: usize) {
        // the last session's slots take the place of session k's
        let last = self.fds.len() - MAX_TOOLS;
        self.fds.copy_within(last.., k * MAX_TOOLS);
        self.fds.truncate(last);
    }

    fn wait(&mut self, until: Instant) {
        wait_for_bridges(&mut self.fds, until);
    }
}

/// Blocks until one of `fds` is readable (a bridge's state arrived) or `until`: `ppoll(2)`,
/// whose timeout has nanosecond resolution (`poll(2)`'s milliseconds would miss deadlines).
fn wait_for_bridges(fds: &mut [libc::pollfd], until: Instant) {
    let left = until.saturating_duration_since(Instant::now());
    if left.is_zero() {
        return;
    }
    let timeout = libc::timespec {
        tv_sec: left.as_secs() as libc::time_t,
        tv_nsec: left.subsec_nanos() as libc::c_long,
    };
    // SAFETY: `fds` is a live, exclusively borrowed slice of `pollfd` for the whole call, and
    // `timeout` outlives it; no signal mask is given. An interrupted wait (EINTR) or any
    // error just returns: every session is polled again, and its deadline still holds.
    unsafe {
        libc::ppoll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, &timeout, std::ptr::null());
    }
}
