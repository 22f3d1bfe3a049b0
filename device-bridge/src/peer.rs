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
//! - `Hybrid` (default): sleep until `window` before the state is expected, then poll:
//!   answered within microseconds when the OS wakes the thread on time, at about
//!   `window / period` of a core. "Expected" comes from the bridge's own tick grid, tracked
//!   from the read times its states carry ([`BridgePhase`]) — not from when this side
//!   happened to see the last state, which would carry one late wake-up into the next
//!   window.
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

/// The bridge's tick grid, tracked from the sequence numbers and read times
/// (`CLOCK_MONOTONIC`, shared by both processes) its states carry.
///
/// The bridge reads state `k` at the deadline `origin + k · period` of its own schedule, plus
/// its wake-up lateness (never negative). So `origin` is the *earliest* of the observed
/// `t_read − k · period`: an earlier one moves the estimate there at once; a later one moves it
/// a sixteenth of the way (a late bridge wake-up is jitter, not a new schedule); one more than
/// [`RESCHEDULED_AFTER`] periods later (the bridge restarted its schedule after a stall, or a
/// new bridge started) is taken at once.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BridgePhase {
    /// The schedule's origin (ns; `None` before the first state).
    origin_ns: Option<i128>,
}

/// A read this many periods behind the tracked schedule means a new schedule.
pub const RESCHEDULED_AFTER: u64 = 2;

impl BridgePhase {
    /// Takes state `seq`, read at `t_read_ns`, into the estimate.
    pub fn observe(&mut self, seq: u64, t_read_ns: u64, period_ns: u64) {
        let o = t_read_ns as i128 - seq as i128 * period_ns as i128;
        self.origin_ns = Some(match self.origin_ns {
            Some(g) if o >= g && o - g <= (RESCHEDULED_AFTER * period_ns) as i128 => g + (o - g) / 16,
            _ => o,
        });
    }

    /// When the bridge reads state `seq`, by its tracked schedule (`None` before the first
    /// state).
    pub fn read_time(&self, seq: u64, period_ns: u64) -> Option<u64> {
        self.origin_ns
            .map(|g| (g + seq as i128 * period_ns as i128).clamp(0, u64::MAX as i128) as u64)
    }
}

/// Where the hybrid wait takes the next state's expected arrival from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PhaseSource {
    /// The bridge's own schedule, tracked from its states' sequence numbers and read times
    /// ([`BridgePhase`]).
    #[default]
    Schedule,
    /// One period after this side last saw a state: the method before 2026-12-02, kept so
    /// that `vademecum bench haptic --peer-phase last-seen` can measure against it. A state
    /// seen late (this thread woke late) moves the next window late by as much.
    LastSeen,
}

impl std::str::FromStr for PhaseSource {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "schedule" => Ok(Self::Schedule),
            "last-seen" => Ok(Self::LastSeen),
            _ => Err(format!("unknown phase source {s:?}: use schedule or last-seen")),
        }
    }
}

impl std::fmt::Display for PhaseSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Schedule => "schedule",
            Self::LastSeen => "last-seen",
        })
    }
}

/// How the last wait went, in `CLOCK_MONOTONIC` ns (0: that step did not happen): what
/// each answer reports of the server's side ([`HapticCommand`]'s `t_peer_*`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct WaitTrace {
    /// When the peer meant to start polling (the end of its sleep).
    planned_ns: u64,
    /// When it started polling (its first poll after the sleep).
    polling_ns: u64,
    /// When it received the state (0: none arrived).
    received_ns: u64,
}

/// The server's side of a haptic channel (see the [module docs](self)).
#[derive(Debug)]
pub struct HapticPeer {
    _node: iceoryx2::prelude::Node<iceoryx2::prelude::ipc::Service>,
    _services: HapticServices,
    states: ShmSubscriber<HapticState>,
    commands: ShmPublisher<HapticCommand>,
    reports: ShmSubscriber<BridgeReport>,
    wake: Option<iceoryx2::port::listener::Listener<iceoryx2::prelude::ipc::Service>>,
    answer_event: iceoryx2::port::notifier::Notifier<iceoryx2::prelude::ipc::Service>,
    strategy: WaitStrategy,
    window: Duration,
    period: Duration,
    phase: BridgePhase,
    phase_source: PhaseSource,
    last_seq: u64,
    last_seen_ns: u64,
    trace: WaitTrace,
    answered: u64,
    skipped: u64,
}

// SAFETY: iceoryx2's `ipc` ports are not `Send` because they share state through `Rc`s
// (its single-threaded arc policy), among the node, the services and the ports made from
// them. A peer owns all of them — its fields are private and no method hands out an iceoryx2
// object (samples are copied out and dropped, or loaned and sent, within the call) — so every
// `Rc` of that graph is reachable only through the peer, and moving the peer moves the whole
// graph: no reference count is ever touched by two threads. iceoryx2 keeps no thread-local
// state (no `thread_local!` in iceoryx2, its cal and posix layers, 0.10) and its sockets and
// shared memory belong to the process. `HapticPeer` is not `Sync`. This lets a session open
// its channel on the thread that starts it (milliseconds: files, sockets) and hand the peer to
// the worker that ticks it, and get it back to close it there: the worker does neither.
unsafe impl Send for HapticPeer {}

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
        let answer_event = services.answered.notifier_builder().create().map_err(|e| port("answered", &e))?;
        Ok(Self {
            _node: node,
            _services: services,
            states,
            commands,
            reports,
            wake,
            answer_event,
            strategy,
            window,
            period,
            phase: BridgePhase::default(),
            phase_source: PhaseSource::default(),
            last_seq: 0,
            last_seen_ns: 0,
            trace: WaitTrace::default(),
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
        self.last_seen_ns != 0 && shm::monotonic_ns().saturating_sub(self.last_seen_ns) < IDLE_AFTER.as_nanos() as u64
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
    /// (on the bridge's tracked tick grid), never up to the deadline: a late bridge costs a
    /// sleep, not a spinning thread that could starve it — the tick thread may run under
    /// `SCHED_FIFO`, the bridge may not.
    pub fn wait_for_state(&mut self, deadline: Instant) -> Option<HapticState> {
        let now = Instant::now();
        let now_ns = shm::monotonic_ns();
        self.trace = WaitTrace::default();
        let (spin_from, spin_until) = match self.effective_strategy() {
            WaitStrategy::Event => return self.wait_for_event(deadline),
            WaitStrategy::Sleep => (deadline, deadline),
            WaitStrategy::Spin => (now, deadline),
            WaitStrategy::Hybrid => {
                let (period, window) = (self.period.as_nanos() as u64, self.window.as_nanos() as u64);
                // the state after the last one seen, on the bridge's schedule; states whose
                // window has passed are given up (the bridge skipped them, or we were late)
                let predicted = match self.phase_source {
                    PhaseSource::Schedule => self.phase.read_time(self.last_seq.wrapping_add(1), period),
                    PhaseSource::LastSeen => (self.last_seen_ns != 0).then(|| self.last_seen_ns + period),
                };
                let expected = predicted.map(|t| {
                    let behind = now_ns.saturating_sub(window).saturating_sub(t);
                    t + behind.div_ceil(period.max(1)) * period
                });
                match expected {
                    Some(expected_ns) => {
                        let at = |ns: u64| {
                            if ns >= now_ns {
                                now + Duration::from_nanos(ns - now_ns)
                            } else {
                                now.checked_sub(Duration::from_nanos(now_ns - ns)).unwrap_or(now)
                            }
                        };
                        (
                            at(expected_ns.saturating_sub(window)).min(deadline),
                            at(expected_ns + window).min(deadline),
                        )
                    }
                    None => (deadline.checked_sub(self.window).unwrap_or(deadline), deadline),
                }
            }
        };
        self.trace.planned_ns = now_ns + spin_from.saturating_duration_since(now).as_nanos() as u64;
        let mut got = None;
        let mut polling_ns = 0;
        timing::wait_between(spin_from, spin_until, || {
            if polling_ns == 0 {
                polling_ns = shm::monotonic_ns();
            }
            got = self.poll();
            got.is_some()
        });
        self.trace.polling_ns = polling_ns;
        if got.is_none() && spin_until < deadline {
            let left = deadline.saturating_duration_since(Instant::now());
            if !left.is_zero() {
                std::thread::sleep(left);
            }
            got = self.poll();
        }
        if let Some(s) = &got {
            self.arrived(s);
        }
        got
    }

    /// Notes a state's arrival: when, and the bridge's phase it shows.
    fn arrived(&mut self, s: &HapticState) {
        self.trace.received_ns = shm::monotonic_ns();
        self.last_seen_ns = self.trace.received_ns;
        self.last_seq = s.seq;
        self.phase.observe(s.seq, s.t_read_ns, self.period.as_nanos() as u64);
    }

    /// Takes the hybrid wait's expected arrivals from `source` (default: the bridge's
    /// schedule).
    pub fn with_phase_source(mut self, source: PhaseSource) -> Self {
        self.phase_source = source;
        self
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

    /// The file descriptor the bridge's wake event makes readable (the event wait's only): a
    /// worker that serves many channels waits on all of theirs at once (`poll(2)`), then takes
    /// each channel's state with [`Self::try_state`].
    pub fn wake_fd(&self) -> Option<std::os::fd::RawFd> {
        use iceoryx2::prelude::FileDescriptorBased;
        // SAFETY: the number is only used to wait for readability while the listener lives
        // (it is neither closed nor read through it)
        self.wake.as_ref().map(|l| unsafe { l.file_descriptor().native_handle() })
    }

    /// The bridge's newest state if one arrived, without waiting; `woken`: the wake event
    /// fired (its notifications are consumed, so that the descriptor is not readable again
    /// for them).
    pub fn try_state(&mut self, woken: bool) -> Option<HapticState> {
        if woken && let Some(l) = &self.wake {
            let _ = l.try_wait(|_| {});
        }
        self.trace = WaitTrace::default();
        let s = self.poll()?;
        self.trace.polling_ns = shm::monotonic_ns();
        self.arrived(&s);
        Some(s)
    }

    /// Blocks on the bridge's wake event until a state arrives or `deadline` passes.
    fn wait_for_event(&mut self, deadline: Instant) -> Option<HapticState> {
        loop {
            if let Some(s) = self.poll() {
                self.arrived(&s);
                return Some(s);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return None;
            }
            match &self.wake {
                Some(l) => {
                    if l.timed_wait(|_| {}, shm::event_timeout(left)).is_err() {
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
        let w = self.trace;
        let cmd = HapticCommand {
            seq: self.answered,
            state_seq: state.seq,
            t_read_ns: state.t_read_ns,
            t_answer_ns: shm::monotonic_ns(),
            force_n,
            depth_m,
            events,
            reserved: 0,
            t_peer_planned_ns: w.planned_ns,
            t_peer_polling_ns: w.polling_ns,
            t_peer_received_ns: w.received_ns,
        };
        let sample = self.commands.loan_uninit().map_err(|_| LinkError::Loan)?;
        sample.write_payload(cmd).send().map_err(|_| LinkError::Send)?;
        // wakes a bridge that blocks on the event for its answer; free when nobody listens
        self.answer_event.notify().map(|_| ()).map_err(|_| LinkError::Send)
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

#[cfg(test)]
mod tests {
    use super::BridgePhase;
    use std::time::Duration;
    use vademecum_proto::shm;

    /// A wait of less than a microsecond left must not become a zero socket timeout (the
    /// kernel's "forever"): the event wait of a session whose bridge had gone hung its close.
    #[test]
    fn an_event_wait_never_asks_the_socket_for_a_zero_timeout() {
        for ns in [1, 400, 999, 1000, 1001, 250_000, 1_500_000] {
            let t = shm::event_timeout(Duration::from_nanos(ns));
            assert!(t >= Duration::from_micros(1), "{ns} ns → {t:?}");
            assert!(
                t >= Duration::from_nanos(ns) && t < Duration::from_nanos(ns) + Duration::from_micros(1),
                "{ns} ns → {t:?}"
            );
            assert_eq!(t.subsec_nanos() % 1000, 0, "whole microseconds: {t:?}");
        }
    }

    const P: u64 = 1_000_000;

    #[test]
    fn the_schedule_follows_the_earliest_reads_and_ignores_late_ones() {
        let mut ph = BridgePhase::default();
        assert_eq!(ph.read_time(3, P), None);
        // state k read 7 µs after its deadline at k ms (+ 1 s), state 10 woken 675 µs late
        for k in 0..20u64 {
            let late = if k == 10 { 675_000 } else { 0 };
            ph.observe(k, 1_000 * P + k * P + 7_000 + late, P);
            // right after the late one, the next state is still expected within 50 µs
            if k == 10 {
                let t = ph.read_time(11, P).unwrap();
                assert!(t - (1_000 * P + 11 * P + 7_000) < 50_000, "{t}");
            }
        }
        assert_eq!(ph.read_time(20, P), Some(1_000 * P + 20 * P + 7_000));
        // an earlier read moves the schedule at once
        ph.observe(21, 1_000 * P + 21 * P + 2_000, P);
        assert_eq!(ph.read_time(22, P), Some(1_000 * P + 22 * P + 2_000));
        // the bridge restarted its schedule after a stall: taken at once
        ph.observe(22, 1_000 * P + 40 * P + 500_000, P);
        assert_eq!(ph.read_time(23, P), Some(1_000 * P + 41 * P + 500_000));
        // a new bridge, counting from 0 again
        ph.observe(0, 2_000 * P + 300, P);
        assert_eq!(ph.read_time(1, P), Some(2_000 * P + P + 300));
    }
}
