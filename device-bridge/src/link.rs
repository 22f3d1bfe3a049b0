//! The bridge's side of a haptic channel: publish tool states and reports, receive forces.
//!
//! [`ShmLink`] talks to a session over iceoryx2 shared memory; [`NullLink`] answers every
//! state at once with zero force and no IPC (the benchmark's null loop). Every port is created
//! before the loop starts; per tick, a link only loans, writes and sends, or receives.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use vademecum_proto::shm::{
    self, BridgeReport, HapticChannel, HapticCommand, HapticServices, HapticState, OpenError, ShmPublisher, ShmSubscriber,
};

/// A per-tick transport failure, counted by the loop (the tick goes on in safe mode).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum LinkError {
    /// No sample could be loaned (every slot is in flight).
    #[error("no shared-memory sample could be loaned")]
    Loan,
    /// The sample could not be delivered.
    #[error("the sample could not be delivered")]
    Send,
}

/// The bridge's side of a haptic channel (see the [module docs](self)).
pub trait Link {
    /// Publishes this tick's tool state.
    fn send_state(&mut self, state: &HapticState) -> Result<(), LinkError>;
    /// The newest force received since the last call, if any (older ones are skipped and
    /// counted in [`Link::skipped`]).
    fn poll_command(&mut self) -> Option<HapticCommand>;
    /// Publishes the bridge's counters.
    fn send_report(&mut self, report: &BridgeReport) -> Result<(), LinkError>;
    /// Forces received but superseded by a newer one before the bridge used them.
    fn skipped(&self) -> u64;
    /// Blocks until the server signals a force published, or `timeout` passes; `false` when
    /// this link cannot block on such a signal (the caller polls [`Link::poll_command`]
    /// instead). A signal already pending returns at once.
    fn wait_command(&mut self, timeout: std::time::Duration) -> bool {
        let _ = timeout;
        false
    }
    /// Asks for housekeeping off the hot path, when the server seems gone: the shared-memory
    /// leftovers of crashed processes are removed (on another thread) so that a restarted
    /// server can take the channel. Must cost the calling thread no more than a flag and a
    /// wake-up (it is called only while the server is silent, and then every 500 ticks).
    fn maintain(&mut self) {}
}

/// The iceoryx2 transport.
#[derive(Debug)]
pub struct ShmLink {
    _node: iceoryx2::prelude::Node<iceoryx2::prelude::ipc::Service>,
    _services: HapticServices,
    housekeeping: Housekeeping,
    states: ShmPublisher<HapticState>,
    commands: ShmSubscriber<HapticCommand>,
    reports: ShmPublisher<BridgeReport>,
    wake: iceoryx2::port::notifier::Notifier<iceoryx2::prelude::ipc::Service>,
    answered: iceoryx2::port::listener::Listener<iceoryx2::prelude::ipc::Service>,
    skipped: u64,
}

impl ShmLink {
    /// Opens `channel` (creating its services if the server has not yet) and creates the
    /// bridge's ports. Fails when another bridge already publishes on the channel.
    pub fn open(channel: &HapticChannel) -> Result<Self, OpenError> {
        let node = shm::node(&format!("vademecum-bridge-{}", std::process::id()))?;
        let services = HapticServices::open(&node, channel)?;
        let port = |what: &str, e: &dyn std::fmt::Debug| OpenError::port(channel, what, e, "another bridge already drives this channel");
        let states = services.state.publisher_builder().create().map_err(|e| port("state", &e))?;
        let commands = services
            .command
            .subscriber_builder()
            .buffer_size(shm::SUBSCRIBER_BUFFER)
            .create()
            .map_err(|e| port("command", &e))?;
        let reports = services.report.publisher_builder().create().map_err(|e| port("report", &e))?;
        let wake = services.wake.notifier_builder().create().map_err(|e| port("wake", &e))?;
        let answered = services.answered.listener_builder().create().map_err(|e| port("answered", &e))?;
        Ok(Self {
            _node: node,
            _services: services,
            housekeeping: Housekeeping::start(),
            states,
            commands,
            reports,
            wake,
            answered,
            skipped: 0,
        })
    }
}

fn publish<T: Copy + std::fmt::Debug + iceoryx2::prelude::ZeroCopySend>(p: &ShmPublisher<T>, v: T) -> Result<(), LinkError> {
    let sample = p.loan_uninit().map_err(|_| LinkError::Loan)?;
    sample.write_payload(v).send().map(|_| ()).map_err(|_| LinkError::Send)
}

impl Link for ShmLink {
    fn send_state(&mut self, state: &HapticState) -> Result<(), LinkError> {
        publish(&self.states, *state)?;
        // wakes a session that blocks on the event; free when nobody listens
        self.wake.notify().map(|_| ()).map_err(|_| LinkError::Send)
    }

    fn poll_command(&mut self) -> Option<HapticCommand> {
        let mut newest = None;
        while let Ok(Some(sample)) = self.commands.receive() {
            if newest.is_some() {
                self.skipped += 1;
            }
            newest = Some(*sample);
        }
        newest
    }

    fn send_report(&mut self, report: &BridgeReport) -> Result<(), LinkError> {
        publish(&self.reports, *report)
    }

    fn skipped(&self) -> u64 {
        self.skipped
    }

    fn wait_command(&mut self, timeout: std::time::Duration) -> bool {
        self.answered.timed_wait(|_| {}, shm::event_timeout(timeout)).is_ok()
    }

    fn maintain(&mut self) {
        self.housekeeping.wanted.store(true, Ordering::Relaxed);
        if let Some(t) = &self.housekeeping.thread {
            t.thread().unpark();
        }
    }
}

/// The housekeeping thread of a link: removes the shared-memory leftovers of crashed
/// processes (iceoryx2's dead-node cleanup scans the file system and allocates) when the loop
/// asks for it — the 1 kHz thread only sets a flag and wakes it.
///
/// It sleeps until woken (by [`Link::maintain`] or its drop) and never wakes on a period of
/// its own: on a small VM every stray wake-up competes with the real-time threads.
#[derive(Debug)]
struct Housekeeping {
    wanted: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Housekeeping {
    fn start() -> Self {
        let wanted = Arc::new(AtomicBool::new(false));
        let stop = Arc::new(AtomicBool::new(false));
        let (w, s) = (wanted.clone(), stop.clone());
        let thread = std::thread::Builder::new()
            .name("bridge-housekeeping".into())
            .spawn(move || {
                let node = shm::node(&format!("vademecum-bridge-hk-{}", std::process::id())).ok();
                while !s.load(Ordering::Relaxed) {
                    std::thread::park();
                    if w.swap(false, Ordering::Relaxed)
                        && let Some(n) = &node
                    {
                        n.try_cleanup_dead_nodes();
                    }
                }
            })
            .ok();
        Self { wanted, stop, thread }
    }
}

impl Drop for Housekeeping {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
    }
}

/// Answers every state at once with zero force, without IPC: the null loop.
#[derive(Debug, Default)]
pub struct NullLink {
    pending: Option<HapticState>,
    answered: u64,
}

impl Link for NullLink {
    fn send_state(&mut self, state: &HapticState) -> Result<(), LinkError> {
        self.pending = Some(*state);
        Ok(())
    }

    fn poll_command(&mut self) -> Option<HapticCommand> {
        let s = self.pending.take()?;
        self.answered += 1;
        Some(HapticCommand {
            seq: self.answered,
            state_seq: s.seq,
            t_read_ns: s.t_read_ns,
            t_answer_ns: shm::monotonic_ns(),
            ..HapticCommand::default()
        })
    }

    fn send_report(&mut self, _report: &BridgeReport) -> Result<(), LinkError> {
        Ok(())
    }

    fn skipped(&self) -> u64 {
        0
    }
}
