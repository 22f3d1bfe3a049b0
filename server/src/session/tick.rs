//! The real-time tick loop of a session (see the [module docs](super)).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant};

use vademecum_bridge::peer::HapticPeer;
use vademecum_engine::pipeline::{Events, Pipeline, TickState, ToolInput, ToolKind};
use vademecum_proto::shm::{self, HapticState, TOOL_GRASPER, TOOL_PROBE, TOOL_SCALPEL};

use super::answers::{AnswerRing, StreamId};
use super::stats::{Histograms, TickStats};
use super::{Answer, Command, Trajectory};

/// How many ticks between hand-overs of the tick thread's histograms to the readers.
const PUBLISH_EVERY: u64 = 64;

/// After a stall longer than this many periods the loop restarts its schedule from now
/// instead of running the missed ticks back to back (they are counted as misses).
const MAX_CATCH_UP: u32 = 10;

/// Most queued tool states one wake-up of the tick thread answers (on arrival, or at a
/// deadline). A client at the tick rate sends one per tick; 16 absorbs a burst of 16 ms of
/// network jitter at once while bounding one stretch of work to 16 pipeline ticks (tens of
/// µs). A longer backlog is answered right after (or over the next ticks of a haptic
/// session), in order.
pub const MAX_COMMANDS_PER_TICK: usize = 16;

/// What the tick thread leaves for the frame thread.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Latest {
    /// The step (pipeline tick) number of the state.
    pub tick: u64,
    /// Session time (µs).
    pub time_us: u64,
    /// The tick's state.
    pub state: TickState,
}

/// A trajectory the tick thread plays, and the stream its answers go to.
pub(super) struct ScriptRun {
    pub trajectory: Trajectory,
    pub to: StreamId,
}

pub(super) struct TickLoop {
    pub pipeline: Pipeline,
    pub commands: Receiver<Command>,
    pub answers: Arc<AnswerRing>,
    pub stats: Arc<TickStats>,
    pub latest: triple_buffer::Input<Latest>,
    pub stop: Arc<AtomicBool>,
    pub period: Duration,
    pub epoch: Instant,
    pub script: Option<ScriptRun>,
    /// One-shot events ([`Events::ONE_SHOT`]) of ticks that answered no one, owed to the next
    /// answer.
    pub owed: u32,
    /// Pipeline ticks so far: the tissue's steps, one per answer and one per period that
    /// answered none. Answers and frames carry the number of the step they show.
    pub steps: u64,
}

impl TickLoop {
    fn micros(&self, t: Instant) -> u64 {
        t.saturating_duration_since(self.epoch).as_micros() as u64
    }

    /// One pipeline tick: the tissue's next step, and its number.
    fn step(&mut self, input: &ToolInput) -> (u64, TickState) {
        let step = self.steps;
        self.steps += 1;
        (step, self.pipeline.tick(input))
    }

    /// One pipeline tick that answers someone: it carries the happenings owed by the ticks
    /// that answered no one.
    fn tick_answered(&mut self, input: &ToolInput) -> (u64, TickState) {
        let (step, mut state) = self.step(input);
        state.events.0 |= std::mem::take(&mut self.owed);
        (step, state)
    }

    fn answer(&mut self, input: &ToolInput, seq: u64, client_time_us: u64, received: Instant) -> Answer {
        let (tick, state) = self.tick_answered(input);
        if state.events.has(Events::REJECTED_INPUT) {
            self.stats.rejected.fetch_add(1, Ordering::Relaxed);
        }
        let now = Instant::now();
        Answer {
            seq,
            client_time_us,
            received_us: self.micros(received),
            answered_us: self.micros(now),
            tick,
            state,
        }
    }

    /// Answers a state from the haptic channel at once.
    fn answer_haptic(&mut self, peer: &mut HapticPeer, s: &HapticState, local: &mut Histograms) -> (ToolInput, TickState) {
        let input = tool_input(s);
        let (_, state) = self.tick_answered(&input);
        if state.events.has(Events::REJECTED_INPUT) {
            self.stats.rejected.fetch_add(1, Ordering::Relaxed);
        }
        let depth = state.contact.map_or(0.0, |c| c.depth_m);
        if peer.answer(s, state.force_n, depth, state.events.0).is_err() {
            self.stats.haptic_errors.fetch_add(1, Ordering::Relaxed);
        }
        Histograms::record(&mut local.haptic, shm::monotonic_ns().saturating_sub(s.t_read_ns));
        self.stats.haptic_answered.fetch_add(1, Ordering::Relaxed);
        (input, state)
    }

    /// Answers the queued tool states, in arrival order, at most [`MAX_COMMANDS_PER_TICK`]:
    /// each answer is one pipeline tick, the period's latest state and input kept in
    /// `period`. `Err` when every sender is gone.
    fn answer_queued(&mut self, period: &mut Period, local: &mut Histograms) -> Result<usize, ()> {
        let mut n = 0;
        while n < MAX_COMMANDS_PER_TICK {
            match self.commands.try_recv() {
                Ok(Command::Tool(c)) => {
                    let a = self.answer(&c.input, c.seq, c.client_time_us, c.received);
                    Histograms::record(
                        &mut local.response,
                        Instant::now().saturating_duration_since(c.received).as_nanos() as u64,
                    );
                    // counted before it leaves, so a reader that has the answer sees it counted
                    self.stats.answered.fetch_add(1, Ordering::Relaxed);
                    self.answers.push(c.reply, a);
                    period.state = Some(a.state);
                    if c.input.is_valid() {
                        period.last_input = Some(c.input);
                    }
                    n += 1;
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => return Err(()),
            }
        }
        Ok(n)
    }

    /// Waits for the deadline `next` parked, answering every tool state at once as it arrives
    /// ([`super::Session::submit`] unparks this thread after queueing it): a state is answered
    /// within the thread's wake-up, not at the next deadline. The work of each arrival is
    /// added to the period's, recorded with its deadline tick. `Err` when every sender is gone.
    fn wait_answering(&mut self, next: Instant, period: &mut Period, local: &mut Histograms) -> Result<(), ()> {
        let mut backlog = false;
        loop {
            let now = Instant::now();
            if now >= next || self.stop.load(Ordering::Relaxed) {
                return Ok(());
            }
            if !backlog {
                std::thread::park_timeout(next - now);
            }
            let start = Instant::now();
            let n = self.answer_queued(period, local)?;
            backlog = n == MAX_COMMANDS_PER_TICK;
            if n > 0 {
                self.answers.wake();
                period.work_ns += start.elapsed().as_nanos() as u64;
            }
        }
    }

    /// Runs until stopped (or the script ends); with a haptic `peer`, the tick also answers
    /// the device bridge (see [`vademecum_bridge::peer`] for how it waits), without one it
    /// answers tool states on arrival between its deadlines ([`Self::wait_answering`]).
    pub fn run(mut self, mut peer: Option<HapticPeer>) {
        let mut local = Box::<Histograms>::default();
        if peer.is_some() {
            // no tick of the haptic path takes a fault on a stack page seen for the first time
            vademecum_bridge::timing::prefault_stack();
        }
        let period = self.period;
        let mut next = Instant::now() + period;
        let mut tick: u64 = 0;
        let mut this = Period::default();
        'ticks: while !self.stop.load(Ordering::Relaxed) {
            let arrived = match peer.as_mut() {
                Some(p) => p.wait_for_state(next),
                None => {
                    if self.wait_answering(next, &mut this, &mut local).is_err() {
                        break 'ticks;
                    }
                    None
                }
            };
            let start = Instant::now();
            if start >= next {
                // a deadline tick (not one woken early by the bridge)
                let late = start.saturating_duration_since(next);
                Histograms::record(&mut local.lateness, late.as_nanos() as u64);
                if late > period {
                    self.stats.misses.fetch_add(1, Ordering::Relaxed);
                }
            }
            let mut answered = false;
            if let (Some(p), Some(s)) = (peer.as_mut(), arrived.as_ref()) {
                let (input, st) = self.answer_haptic(p, s, &mut local);
                this.state = Some(st);
                if input.is_valid() {
                    this.last_input = Some(input);
                }
            }
            if let Some(script) = self.script.take() {
                let t = tick as f64 * period.as_secs_f64();
                if t > script.trajectory.duration_s() + 0.5 * period.as_secs_f64() {
                    break 'ticks;
                }
                let mut input = super::tool_at(&script.trajectory, t);
                // a scene whose only tool is a grasper plays its trajectory (and closure) with it
                if input.kind == ToolKind::Probe && !self.pipeline.accepts(ToolKind::Probe) && self.pipeline.accepts(ToolKind::Grasper) {
                    input.kind = ToolKind::Grasper;
                }
                let a = self.answer(&input, tick, self.micros(start), start);
                Histograms::record(&mut local.response, (a.answered_us - a.received_us) * 1000);
                // counted before it leaves, so a reader that has the answer sees it counted
                self.stats.answered.fetch_add(1, Ordering::Relaxed);
                self.answers.push(script.to, a);
                answered = true;
                this.state = Some(a.state);
                this.last_input = Some(input);
                self.script = Some(script);
            }
            match self.answer_queued(&mut this, &mut local) {
                Ok(n) => answered |= n > 0,
                Err(()) => break 'ticks,
            }
            if answered {
                // one wake-up of the dispatcher per tick, however many answers it carries
                self.answers.wake();
            }
            let state = match this.state.take() {
                Some(state) => Some(state),
                None => this.last_input.map(|input| {
                    // time goes on for the tissue; what happened is owed to the next answer
                    let (_, st) = self.step(&input);
                    self.owed |= st.events.0 & Events::ONE_SHOT;
                    st
                }),
            };
            if let Some(state) = state {
                self.latest.write(Latest {
                    tick: self.steps.saturating_sub(1),
                    time_us: self.micros(start),
                    state,
                });
            }
            self.stats.ticks.fetch_add(1, Ordering::Relaxed);
            tick += 1;
            // the periodic bookkeeping (histogram hand-over, the CPU-time syscall, the bridge's
            // report) is part of the tick whose work it lengthens: timed with it below
            if tick.is_multiple_of(PUBLISH_EVERY) {
                self.stats.publish(&mut local);
                let cpu = vademecum_bridge::timing::thread_cpu_time().as_nanos() as u64;
                self.stats.tick_cpu_ns.store(cpu, Ordering::Relaxed);
                if let Some(p) = peer.as_mut() {
                    if let Some(r) = p.poll_report() {
                        self.stats.bridge.store(&r);
                    }
                    self.stats.haptic_skipped.store(p.skipped(), Ordering::Relaxed);
                }
            }
            // the period's work: its deadline tick and its answers on arrival
            let work = start.elapsed().as_nanos() as u64 + std::mem::take(&mut this.work_ns);
            Histograms::record(&mut local.work, work);
            next = match &peer {
                Some(p) => p.next_deadline(next, start, arrived.is_some()),
                None => next + period,
            };
            let now = Instant::now();
            if now > next + period * MAX_CATCH_UP {
                next = now;
            }
        }
        if let Some(p) = peer.as_mut()
            && let Some(r) = p.poll_report()
        {
            self.stats.bridge.store(&r);
        }
        self.stats.finish(&local);
        self.answers.finish();
    }
}

/// What a period of the tick loop has answered so far: the tissue advances one pipeline tick
/// per answer, and one at the deadline only when the period answered nothing.
#[derive(Debug, Default)]
struct Period {
    /// The latest state of the period's answers (`None`: nothing answered yet).
    state: Option<TickState>,
    /// The last valid tool state received, re-evaluated at deadlines that answered nothing.
    last_input: Option<ToolInput>,
    /// The work of its answers on arrival so far (ns).
    work_ns: u64,
}

/// The engine's tool state for a haptic sample.
fn tool_input(s: &HapticState) -> ToolInput {
    ToolInput {
        kind: match s.tool {
            TOOL_SCALPEL => ToolKind::Scalpel,
            TOOL_GRASPER => ToolKind::Grasper,
            TOOL_PROBE => ToolKind::Probe,
            _ => ToolKind::Other,
        },
        position_m: s.position_m,
        velocity_m_s: s.velocity_m_s,
        closure: s.closure,
        orientation: if s.orientation == [0.0; 4] {
            [1.0, 0.0, 0.0, 0.0]
        } else {
            s.orientation
        },
        blade_end_m: s.blade_end_m,
    }
}
