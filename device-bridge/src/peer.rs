//! The server's side of a haptic channel: wait for the bridge's tool state, answer it with a
//! force, read the bridge's reports. A session's tick thread owns one; so does the echo peer
//! of `vademecum bench haptic`.
//!
//! # Waiting for the bridge
//!
//! The bridge ticks on its own clock; a state arrives about every period. The peer waits for
//! it by polling the subscriber (pub-sub wakes nobody by itself), with the session's
//! [`WaitStrategy`]:
//!
//! - `Sleep`: the session keeps its own 1 kHz schedule and answers the newest state at each
//!   of its ticks — no CPU spent waiting, but the force answers a state up to a period old
//!   and reaches the bridge one tick late.
//! - `Spin`: poll continuously until the state arrives: answered within microseconds; a
//!   whole core per session.
//! - `Hybrid` (default): sleep until `window` before the state is expected (the last arrival
//!   plus one period), then poll: answered within microseconds when the OS wakes the thread
//!   on time, at about `window / period` of a core.
//! - `Event`: block on the `wake` event the bridge raises after each state: no spinning;
//!   each answer pays a kernel wake-up.
//!
//! When no state arrived for [`IDLE_AFTER`], the bridge is taken as gone and every polling strategy
//! sleeps: a session without a device pays nothing for the channel.

use std::time::{Duration, Instant};

use vademecum_proto::shm::{
    self, BridgeReport, HapticChannel, HapticCommand, HapticServices, HapticState, OpenError, ShmPublisher, ShmSubscriber,
};

use crate::link::LinkError;
use crate::timing::{self, WaitStrategy};

/// With no state for this long, the peer stops spinning for the bridge.
pub const IDLE_AFTER: Duration = Duration::from_millis(100);

/// The server's side of a haptic channel (see the [module docs](self)).
#[derive(Debug)]
pub struct HapticPeer {
    _node: iceoryx2::prelude::Node<iceoryx2::prelude::ipc::Service>,
    _services: HapticServices,
    states: ShmSubscriber<HapticState>,
    commands: ShmPublisher<HapticCommand>,
    reports: ShmSubscriber<BridgeReport>,
    wake: Option<iceoryx2::port::listener::Listener<iceoryx2::prelude::ipc::Service>>,
    strategy: WaitStrategy,
    window: Duration,
    period: Duration,
    last_arrival: Option<Instant>,
    answered: u64,
    skipped: u64,
}

impl HapticPeer {
    /// Opens `channel` and creates the server's ports. Fails when another server already
    /// answers on the channel (one publisher of forces per channel).
    pub fn open(channel: &HapticChannel, strategy: WaitStrategy, window: Duration, period: Duration) -> Result<Self, OpenError> {
        let node = shm::node(&format!("vademecum-session-{}", std::process::id()))?;
        let services = HapticServices::open(&node, channel)?;
        let port =
            |what: &str, e: &dyn std::fmt::Debug| OpenError::port(channel, what, e, "another session already answers on this channel");
        let commands = services.command.publisher_builder().create().map_err(|e| port("command", &e))?;
        let states = services
            .state
            .subscriber_builder()
            .buffer_size(shm::SUBSCRIBER_BUFFER)
            .create()
            .map_err(|e| port("state", &e))?;
        let reports = services
            .report
            .subscriber_builder()
            .buffer_size(shm::SUBSCRIBER_BUFFER)
            .create()
            .map_err(|e| port("report", &e))?;
        let wake = match strategy {
            WaitStrategy::Event => Some(services.wake.listener_builder().create().map_err(|e| port("wake", &e))?),
            _ => None,
        };
        Ok(Self {
            _node: node,
            _services: services,
            states,
            commands,
            reports,
            wake,
            strategy,
            window,
            period,
            last_arrival: None,
            answered: 0,
            skipped: 0,
        })
    }

    /// The newest state received, if any (older ones are skipped and counted).
    fn poll(&mut self) -> Option<HapticState> {
        let mut newest = None;
        while let Ok(Some(sample)) = self.states.receive() {
            if newest.is_some() {
                self.skipped += 1;
            }
            newest = Some(*sample);
        }
        newest
    }

    /// Whether a bridge sent a state within [`IDLE_AFTER`].
    pub fn bridge_active(&self) -> bool {
        self.last_arrival.is_some_and(|t| t.elapsed() < IDLE_AFTER)
    }

    /// The strategy the next wait uses: the configured one while a bridge is active, sleep
    /// otherwise.
    pub fn effective_strategy(&self) -> WaitStrategy {
        // blocking on the event costs nothing while the bridge is away
        if self.bridge_active() || self.strategy == WaitStrategy::Event {
            self.strategy
        } else {
            WaitStrategy::Sleep
        }
    }

    /// Waits for the bridge's next state until `deadline` (see the [module docs](self)).
    ///
    /// The hybrid wait spins only inside a window around the state's predicted arrival
    /// (phase-locked to the last arrival), never up to the deadline: a late bridge costs a
    /// sleep, not a spinning thread that could starve it — the tick thread may run under
    /// `SCHED_FIFO`, the bridge may not.
    pub fn wait_for_state(&mut self, deadline: Instant) -> Option<HapticState> {
        let now = Instant::now();
        let (spin_from, spin_until) = match self.effective_strategy() {
            WaitStrategy::Event => return self.wait_for_event(deadline),
            WaitStrategy::Sleep => (deadline, deadline),
            WaitStrategy::Spin => (now, deadline),
            WaitStrategy::Hybrid => {
                let mut expected = self.last_arrival.map_or(deadline, |t| t + self.period);
                while expected + self.window < now {
                    expected += self.period;
                }
                let from = expected.checked_sub(self.window).unwrap_or(expected);
                (from.min(deadline), (expected + self.window).min(deadline))
            }
        };
        let mut got = None;
        timing::wait_between(spin_from, spin_until, || {
            got = self.poll();
            got.is_some()
        });
        if got.is_none() && spin_until < deadline {
            let left = deadline.saturating_duration_since(Instant::now());
            if !left.is_zero() {
                std::thread::sleep(left);
            }
            got = self.poll();
        }
        if got.is_some() {
            self.last_arrival = Some(Instant::now());
        }
        got
    }

    /// The deadline after `previous` for a loop that waited with [`Self::wait_for_state`] and
    /// woke at `woke`, having answered a state or not. Bridge-clocked while the peer does not
    /// sleep: the next state is due a period after this one, and the loop's own deadline half
    /// a period later only covers a bridge that skips a beat. Otherwise one period on.
    pub fn next_deadline(&self, previous: Instant, woke: Instant, answered: bool) -> Instant {
        if answered && self.effective_strategy() != WaitStrategy::Sleep {
            woke + self.period + self.period / 2
        } else {
            previous + self.period
        }
    }

    /// Blocks on the bridge's wake event until a state arrives or `deadline` passes.
    fn wait_for_event(&mut self, deadline: Instant) -> Option<HapticState> {
        loop {
            if let Some(s) = self.poll() {
                self.last_arrival = Some(Instant::now());
                return Some(s);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return None;
            }
            match &self.wake {
                Some(l) => {
                    if l.timed_wait(|_| {}, left).is_err() {
                        std::thread::sleep(left);
                    }
                }
                None => std::thread::sleep(left),
            }
        }
    }

    /// Sends the force answering `state`.
    pub fn answer(&mut self, state: &HapticState, force_n: [f64; 3], depth_m: f64, events: u32) -> Result<(), LinkError> {
        self.answered += 1;
        let cmd = HapticCommand {
            seq: self.answered,
            state_seq: state.seq,
            t_read_ns: state.t_read_ns,
            t_answer_ns: shm::monotonic_ns(),
            force_n,
            depth_m,
            events,
            reserved: 0,
        };
        let sample = self.commands.loan_uninit().map_err(|_| LinkError::Loan)?;
        sample.write_payload(cmd).send().map(|_| ()).map_err(|_| LinkError::Send)
    }

    /// The newest bridge report since the last call.
    pub fn poll_report(&mut self) -> Option<BridgeReport> {
        let mut newest = None;
        while let Ok(Some(sample)) = self.reports.receive() {
            newest = Some(*sample);
        }
        newest
    }

    /// States answered.
    pub fn answered(&self) -> u64 {
        self.answered
    }

    /// States superseded by a newer one before they were answered.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }
}
