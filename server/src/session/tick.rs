//! The real-time tick loop of a session (see the [module docs](super)).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant};

use vademecum_bridge::peer::HapticPeer;
use vademecum_engine::pipeline::{Events, Fidelity, MAX_TOOLS, Pipeline, TickState, ToolInput, ToolKind};
use vademecum_proto::shm::{self, HapticState, TOOL_GRASPER, TOOL_PROBE, TOOL_SCALPEL};

use super::answers::{AnswerRing, StreamId};
use super::stats::{Histograms, TickStats};
use super::workers::Poll;
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
    /// The tick's state: of the tool it answered (or replayed).
    pub state: TickState,
    /// Every tool's state at that tick, by its index in the scene, in a session that moves
    /// named tools (`None`: the tool has not moved yet, or the session moves one tool at a
    /// time).
    pub tools: [Option<TickState>; MAX_TOOLS],
}

/// The hands the tick thread plays, and how long.
pub(super) struct ScriptRun {
    pub hands: Vec<ScriptHand>,
    /// The longest hand's duration (s).
    pub duration_s: f64,
}

/// A trajectory the tick thread plays, the tool it moves, and the stream its answers go to.
pub(super) struct ScriptHand {
    /// The scene tool (`None`: the one tool at a time) and its kind.
    pub tool: Option<usize>,
    pub kind: Option<ToolKind>,
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
    /// One-shot events ([`Events::ONE_SHOT`]) of each tool (by index) from ticks that did not
    /// answer it — periods that answered no one, and ticks that answered another tool —
    /// owed to its next answer: a cut that lands while the grasper moves reaches the
    /// scalpel's client, never the grasper's.
    pub owed: [u32; MAX_TOOLS],
    /// The tissue's steps so far: one per answer (a pipeline tick) and one per period that
    /// answered none (a pipeline tick replaying the last tool state, or, before any tool, a
    /// period at rest). Answers and frames carry the number of the step they show.
    pub steps: u64,
    /// The haptic channel of a session a device worker ticks (opened by whoever starts the
    /// loop; it goes back to the session's owner with the loop, and is closed there): the
    /// first tool's, which paces the loop.
    pub peer: Option<HapticPeer>,
    /// The other tools' haptic channels, with each tool's index in the scene (a scene with
    /// several tools has a channel per tool, [`super::tool_channels`]): a state that arrives
    /// on one is answered at the loop's next turn — at once on a device worker, which wakes
    /// on every channel (where such a session ticks: a server's, or one of its own); at the
    /// first tool's next state or deadline on a thread of its own (only with an
    /// `on_tick_thread` hook).
    pub others: Vec<(usize, HapticPeer)>,
    /// Falls back to the reduced fidelity under load ([`super::fidelity`]).
    pub governor: super::fidelity::Governor,
    /// The frames a deterministic session makes while its tick waits
    /// ([`Lockstep`]).
    pub lockstep: Option<Lockstep>,
    /// A deterministic session ([`super::SessionConfig::deterministic`]): session time is
    /// the step's.
    pub deterministic: bool,
    /// Each tool's latest valid state, by its index in the scene: every step moves all of
    /// them together ([`Pipeline::tick_tools`]).
    pub held: [Option<ToolInput>; MAX_TOOLS],
    /// Each tool's state at the last step.
    pub tool_states: [Option<TickState>; MAX_TOOLS],
    /// A state named its tool ([`super::ToolCommand::named`]): frames list every tool.
    pub named: bool,
}

/// A tick loop's clock and recordings: its next deadline, its period count, the current
/// period's answers, its histograms until handed over. Kept beside the loop by whoever runs
/// it, so that both can be borrowed at once.
pub(super) struct Clock {
    /// The next deadline (set when the loop starts).
    next: Instant,
    /// Periods (deadline ticks) so far.
    tick: u64,
    /// The current period.
    this: Period,
    /// The histograms recorded since the last hand-over.
    local: Box<Histograms>,
    /// Work done so far (ns): a pooled session's share of its worker's CPU.
    work_total_ns: u64,
    /// The loop has a thread of its own that waits for its bridge: its CPU figure is the
    /// thread's CPU time (the wait included), not the work done.
    cpu_of_thread: bool,
}

impl Default for Clock {
    fn default() -> Self {
        Self {
            next: Instant::now(),
            tick: 0,
            this: Period::default(),
            local: Box::default(),
            work_total_ns: 0,
            cpu_of_thread: false,
        }
    }
}

impl TickLoop {
    fn micros(&self, t: Instant) -> u64 {
        t.saturating_duration_since(self.epoch).as_micros() as u64
    }

    /// One pipeline tick: the tissue's next step, and its number — `input` together with
    /// every other tool at its latest state (the contacts of tools on one organ are solved
    /// together); the state answers `input`.
    fn step(&mut self, input: &ToolInput, answered: bool) -> (u64, TickState) {
        let mut state = [TickState::default()];
        let step = self.step_tools(std::slice::from_ref(input), answered, &mut state);
        (step, state[0])
    }

    /// One pipeline tick moving every tool of `inputs` (distinct tools: a script's hands) at
    /// once, every other tool at its latest state; `states[i]` answers `inputs[i]`. Each
    /// tool's one-shot events are owed to its next answer unless `answered` (this tick
    /// answers `inputs`).
    fn step_tools(&mut self, inputs: &[ToolInput], answered: bool, states: &mut [TickState]) -> u64 {
        let step = self.steps;
        self.steps += 1;
        if let [input] = inputs
            && input.tool >= MAX_TOOLS
        {
            // no tool of the scene: rejected alone
            states[0] = self.pipeline.tick(input);
            return step;
        }
        let mut set = [ToolInput::default(); MAX_TOOLS];
        // where each of `inputs` is in the set
        let mut mine = [usize::MAX; MAX_TOOLS];
        let mut n = 0;
        for (slot, held) in self.held.iter().enumerate() {
            if let Some(i) = inputs.iter().position(|t| t.tool == slot) {
                mine[i] = n;
                set[n] = inputs[i];
                n += 1;
            } else if let Some(h) = held {
                set[n] = *h;
                n += 1;
            }
        }
        let mut all = [TickState::default(); MAX_TOOLS];
        self.pipeline.tick_tools(&set[..n], &mut all[..n]);
        for (t, st) in set[..n].iter().zip(&all) {
            self.tool_states[t.tool] = Some(*st);
            if !(answered && inputs.iter().any(|i| i.tool == t.tool)) {
                self.owed[t.tool] |= st.events.0 & Events::ONE_SHOT;
            }
        }
        for (i, input) in inputs.iter().enumerate() {
            states[i] = all[mine[i]];
            if input.is_valid() {
                self.held[input.tool] = Some(*input);
            }
        }
        step
    }

    /// One pipeline tick that answers someone: it carries the happenings owed to its tool by
    /// the ticks that did not answer it.
    fn tick_answered(&mut self, input: &ToolInput) -> (u64, TickState) {
        let mut state = [TickState::default()];
        let step = self.tools_answered(std::slice::from_ref(input), &mut state);
        (step, state[0])
    }

    /// [`TickLoop::tick_answered`] for several tools moved at once ([`TickLoop::step_tools`]).
    fn tools_answered(&mut self, inputs: &[ToolInput], states: &mut [TickState]) -> u64 {
        let step = self.step_tools(inputs, true, states);
        for (input, state) in inputs.iter().zip(states.iter_mut()) {
            if let Some(owed) = self.owed.get_mut(input.tool) {
                state.events.0 |= std::mem::take(owed);
            }
            if state.events.has(Events::REJECTED_INPUT) {
                self.stats.rejected.fetch_add(1, Ordering::Relaxed);
            }
        }
        step
    }

    fn answer(&mut self, input: &ToolInput, seq: u64, client_time_us: u64, received: Instant) -> Answer {
        let (tick, state) = self.tick_answered(input);
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

    /// Answers a state from the haptic channel of tool `tool` at once; it is the period's
    /// latest state (and, when valid, its input).
    fn answer_haptic(&mut self, peer: &mut HapticPeer, tool: usize, s: &HapticState, clock: &mut Clock) {
        let input = tool_input(s, tool);
        let (_, state) = self.tick_answered(&input);
        let depth = state.contact.map_or(0.0, |c| c.depth_m);
        if peer.answer(s, state.force_n, depth, state.events.0).is_err() {
            self.stats.haptic_errors.fetch_add(1, Ordering::Relaxed);
        }
        Histograms::record(&mut clock.local.haptic, shm::monotonic_ns().saturating_sub(s.t_read_ns));
        self.stats.haptic_answered.fetch_add(1, Ordering::Relaxed);
        clock.this.state = Some(state);
        if input.is_valid() {
            clock.this.last_input = Some(input);
        }
    }

    /// Answers the queued tool states, in arrival order, at most [`MAX_COMMANDS_PER_TICK`]:
    /// each answer is one pipeline tick, the period's latest state and input kept in
    /// `period`. `Err` when every sender is gone.
    fn answer_queued(&mut self, period: &mut Period, local: &mut Histograms) -> Result<usize, ()> {
        let mut n = 0;
        while n < MAX_COMMANDS_PER_TICK {
            match self.commands.try_recv() {
                Ok(Command::Tool(c)) => {
                    self.named |= c.named;
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

    /// Starts `clock`: the first deadline a period from now.
    pub fn start(&self, clock: &mut Clock) {
        clock.next = Instant::now() + self.period;
    }

    /// Starts `clock` with its deadlines at `epoch + (m + fraction) · period` (see
    /// [`phased_deadline`]): the sessions of one worker, given fractions spread over the period,
    /// tick at spread instants instead of all at once.
    pub fn start_at_phase(&self, clock: &mut Clock, epoch: Instant, fraction: f64) {
        clock.next = phased_deadline(epoch, Instant::now(), self.period, fraction);
    }

    /// A worker's turn ([`super::scheduler`]): answers the tool states that arrived (at once,
    /// not at the next deadline: [`super::Session::submit`] unparks the worker after queueing
    /// one), then runs the deadline tick if it is due. Their work is added to the period's,
    /// recorded with its deadline tick.
    pub fn poll(&mut self, clock: &mut Clock) -> Poll {
        if self.stop.load(Ordering::Relaxed) {
            return Poll::Ended;
        }
        let start = Instant::now();
        let Ok(n) = self.answer_queued(&mut clock.this, &mut clock.local) else {
            return Poll::Ended;
        };
        if n > 0 {
            self.answers.wake();
            clock.this.work_ns += start.elapsed().as_nanos() as u64;
        }
        let now = Instant::now();
        if now >= clock.next && !self.deadline(clock, now, None, None, &[None; MAX_TOOLS]) {
            return Poll::Ended;
        }
        if n == MAX_COMMANDS_PER_TICK {
            // a backlog: answered right after, in order
            return Poll::At(Instant::now());
        }
        Poll::At(clock.next)
    }

    /// Runs a haptic session until stopped (or its script ends) on its own thread: waits for
    /// the device bridge's state (see [`vademecum_bridge::peer`] for how) and answers it at
    /// once, the queued tool states with it.
    pub fn run_haptic(&mut self, clock: &mut Clock, peer: &mut HapticPeer) {
        // no tick of the haptic path takes a fault on a stack page seen for the first time
        vademecum_bridge::timing::prefault_stack();
        self.start(clock);
        clock.cpu_of_thread = true;
        while !self.stop.load(Ordering::Relaxed) {
            let arrived = peer.wait_for_state(clock.next);
            // the other tools' bridges have no wake-up of their own here: their notifications
            // are taken with their states
            let others = self.take_others(u32::MAX);
            if !self.deadline(clock, Instant::now(), Some(&mut *peer), arrived.as_ref(), &others) {
                break;
            }
        }
        self.keep_bridge_reports(peer);
    }

    /// The states that arrived on the other tools' channels (bit `i + 1` of `woken`: the wake
    /// event of `others[i]` fired, to be consumed).
    fn take_others(&mut self, woken: u32) -> [Option<HapticState>; MAX_TOOLS] {
        let mut arrived = [None; MAX_TOOLS];
        for (i, (_, p)) in self.others.iter_mut().enumerate() {
            arrived[i] = p.try_state(woken & (1 << (i + 1)) != 0);
        }
        arrived
    }

    /// A device worker's turn ([`super::devices`]) for a haptic session: answers the
    /// bridges' states that arrived (bit 0 of `woken`: the first tool's wake event fired, bit
    /// `i + 1`: that of `others[i]`, to be consumed) — at once, a tick each as on a thread of
    /// its own —, or runs the deadline tick when it is due; says when the next deadline is.
    /// Never blocks: the worker waits on the events of all its sessions at once.
    pub fn poll_device(&mut self, clock: &mut Clock, woken: u32) -> Poll {
        if self.stop.load(Ordering::Relaxed) {
            return Poll::Ended;
        }
        let Some(mut peer) = self.peer.take() else {
            return Poll::Ended;
        };
        let arrived = peer.try_state(woken & 1 != 0);
        let others = self.take_others(woken);
        let now = Instant::now();
        let due = arrived.is_some() || others.iter().any(Option::is_some) || now >= clock.next;
        let go_on = !due || self.deadline(clock, now, Some(&mut peer), arrived.as_ref(), &others);
        self.peer = Some(peer);
        if go_on { Poll::At(clock.next) } else { Poll::Ended }
    }

    /// One tick at `start`: a deadline tick (the session's period), or, with a haptic `peer`,
    /// the answer to the bridge's state `arrived`, which may come before the deadline. Plays
    /// the script, answers the queued tool states, replays the last tool state when the
    /// period answered none, hands the period's state to the frame thread and its histograms
    /// to the readers. `false` when the loop has ended (script over, every sender gone).
    fn deadline(
        &mut self,
        clock: &mut Clock,
        start: Instant,
        mut peer: Option<&mut HapticPeer>,
        arrived: Option<&HapticState>,
        others: &[Option<HapticState>; MAX_TOOLS],
    ) -> bool {
        let period = self.period;
        let next = clock.next;
        let mut late_ns = 0;
        if start >= next {
            // a deadline tick (not one woken early by the bridge)
            let late = start.saturating_duration_since(next);
            late_ns = late.as_nanos() as u64;
            Histograms::record(&mut clock.local.lateness, late_ns);
            if late > period {
                self.stats.misses.fetch_add(1, Ordering::Relaxed);
            }
        }
        let mut answered = false;
        if let (Some(p), Some(s)) = (peer.as_deref_mut(), arrived) {
            // the first channel is the scene's first tool's
            self.answer_haptic(p, 0, s, clock);
        }
        if others.iter().any(Option::is_some) {
            // moved out and back: no allocation
            let mut channels = std::mem::take(&mut self.others);
            for ((tool, p), s) in channels.iter_mut().zip(others) {
                if let Some(s) = s {
                    self.answer_haptic(p, *tool, s, clock);
                }
            }
            self.others = channels;
        }
        if let Some(script) = self.script.take() {
            let t = clock.tick as f64 * period.as_secs_f64();
            if t > script.duration_s + 0.5 * period.as_secs_f64() {
                self.script = Some(script);
                return false;
            }
            // every hand moves in one pipeline tick: the tissue steps once a period, as
            // with one hand
            let mut inputs = [ToolInput::default(); MAX_TOOLS];
            let n = script.hands.len().min(MAX_TOOLS);
            for (input, hand) in inputs.iter_mut().zip(&script.hands) {
                *input = super::tool_at(&hand.trajectory, t);
                match (hand.tool, hand.kind) {
                    (Some(tool), Some(kind)) => (input.tool, input.kind) = (tool, kind),
                    // a scene whose only tool is a grasper plays its trajectory (and closure)
                    // with it
                    _ if input.kind == ToolKind::Probe
                        && !self.pipeline.accepts(ToolKind::Probe)
                        && self.pipeline.accepts(ToolKind::Grasper) =>
                    {
                        input.kind = ToolKind::Grasper
                    }
                    _ => {}
                }
            }
            let mut states = [TickState::default(); MAX_TOOLS];
            let tick = self.tools_answered(&inputs[..n], &mut states[..n]);
            let (received_us, answered_us) = (self.micros(start), self.micros(Instant::now()));
            for (hand, state) in script.hands.iter().zip(&states[..n]) {
                let a = Answer {
                    seq: clock.tick,
                    client_time_us: received_us,
                    received_us,
                    answered_us,
                    tick,
                    state: *state,
                };
                Histograms::record(&mut clock.local.response, (a.answered_us - a.received_us) * 1000);
                // counted before it leaves, so a reader that has the answer sees it counted
                self.stats.answered.fetch_add(1, Ordering::Relaxed);
                self.answers.push(hand.to, a);
                clock.this.state = Some(a.state);
            }
            answered = true;
            clock.this.last_input = Some(inputs[n - 1]);
            self.script = Some(script);
        }
        match self.answer_queued(&mut clock.this, &mut clock.local) {
            Ok(n) => answered |= n > 0,
            Err(()) => return false,
        }
        if answered {
            // one wake-up of the dispatcher per tick, however many answers it carries
            self.answers.wake();
        }
        let state = match (clock.this.state.take(), clock.this.last_input) {
            (Some(state), _) => Some(state),
            (None, Some(input)) => {
                // time goes on for the tissue; what happened is owed to each tool's next answer
                let (_, st) = self.step(&input, false);
                Some(st)
            }
            (None, None) => {
                // no tool yet: the tissue rests through the period, a step all the same
                self.steps += 1;
                None
            }
        };
        if let Some(state) = state {
            let step = self.steps.saturating_sub(1);
            let time_us = if self.deterministic {
                (u128::from(step) * period.as_micros()) as u64
            } else {
                self.micros(start)
            };
            self.latest.write(Latest {
                tick: step,
                time_us,
                state,
                tools: if self.named { self.tool_states } else { [None; MAX_TOOLS] },
            });
        }
        if let Some(frames) = &mut self.lockstep {
            frames.after_step(self.steps.saturating_sub(1));
        }
        self.stats.steps.store(self.steps, Ordering::Relaxed);
        self.stats.ticks.fetch_add(1, Ordering::Relaxed);
        clock.tick += 1;
        // the periodic bookkeeping (histogram hand-over, the CPU figure, the bridge's report)
        // is part of the tick whose work it lengthens: timed with it below
        if clock.tick.is_multiple_of(PUBLISH_EVERY) {
            self.stats.publish(&mut clock.local);
            if let Some(p) = peer.as_deref_mut() {
                self.keep_bridge_reports(p);
                let others: u64 = self.others.iter().map(|(_, o)| o.skipped()).sum();
                self.stats.haptic_skipped.store(p.skipped() + others, Ordering::Relaxed);
            }
            let cpu = if clock.cpu_of_thread {
                // a haptic session's own thread: its CPU time, waiting for the bridge included
                vademecum_bridge::timing::thread_cpu_time().as_nanos() as u64
            } else {
                // a worker's session: the work done for it
                clock.work_total_ns
            };
            self.stats.tick_cpu_ns.store(cpu, Ordering::Relaxed);
        }
        // the period's work: its deadline tick and its answers on arrival
        let work = start.elapsed().as_nanos() as u64 + std::mem::take(&mut clock.this.work_ns);
        Histograms::record(&mut clock.local.work, work);
        clock.work_total_ns += work;
        self.govern(late_ns + work);
        let mut next = match peer.as_deref() {
            Some(p) => p.next_deadline(next, start, arrived.is_some()),
            None => next + period,
        };
        let now = Instant::now();
        if now > next + period * MAX_CATCH_UP {
            next = now;
        }
        clock.next = next;
        true
    }

    /// Gives the period's pressure (its lateness and work, ns) to the fidelity governor and
    /// switches the pipeline and the frames when it says so: a field write and atomics.
    fn govern(&mut self, pressure_ns: u64) {
        if let Some(f) = self.governor.observe(pressure_ns) {
            self.pipeline.set_fidelity(f);
            let reduced = f == Fidelity::Reduced;
            if reduced {
                self.stats.fallbacks.fetch_add(1, Ordering::Relaxed);
            }
            self.stats.reduced.store(reduced, Ordering::Relaxed);
        }
        if self.governor.reduced() {
            self.stats.reduced_ticks.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Closes the answers (an atomic and a wake-up: the dispatcher delivers what is left and
    /// ends the streams) — on the worker, when the loop ends.
    pub fn close_answers(&self) {
        self.answers.finish();
    }

    /// Hands the last recordings to the readers — by the loop's owner once the loop is back
    /// from its worker: merging takes the lock the readers take.
    pub fn hand_over(&self, clock: &Clock) {
        self.stats.finish(&clock.local);
    }
}

/// The tick thread's end of the frames of a deterministic session
/// ([`super::SessionConfig::deterministic`], headless runs): frame `n` (from 1) shows the
/// first step at or after `n / rate` of session time, made while the tick waits, so that it
/// draws that step's state, cut and damage on any load, and the co-rotational correction it
/// leaves lands at the next tick.
pub(super) struct Lockstep {
    /// Steps per frame (the period times the rate, inverted).
    steps_per_frame: f64,
    /// Frames asked so far.
    asked: u64,
    requests: std::sync::mpsc::SyncSender<()>,
    made: Receiver<()>,
}

impl Lockstep {
    /// The tick's end of a frame thread taking `requests` and reporting on `made`, a frame
    /// every `steps_per_frame` steps ([`super::frames::spawn_lockstep`]).
    pub fn new(steps_per_frame: f64, requests: std::sync::mpsc::SyncSender<()>, made: Receiver<()>) -> Self {
        Self {
            steps_per_frame,
            asked: 0,
            requests,
            made,
        }
    }

    /// Makes the frames due once step `step` (counted from 0) is done, waiting for each; a
    /// frame thread that has ended is not waited for.
    pub fn after_step(&mut self, step: u64) {
        while (self.asked + 1) as f64 * self.steps_per_frame <= (step + 1) as f64 {
            self.asked += 1;
            if self.requests.send(()).is_err() || self.made.recv().is_err() {
                return;
            }
        }
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

/// Keeps the newest report of the bridge of tool `tool` in `stats`.
fn keep_bridge_report(stats: &TickStats, peer: &mut HapticPeer, tool: usize) {
    if let Some(r) = peer.poll_report() {
        stats.bridges[tool.min(MAX_TOOLS - 1)].store(&r);
    }
}

impl TickLoop {
    /// Keeps the newest report of every bridge: `peer` (the first tool's) and the other
    /// tools' channels (when a haptic loop ends, and every few ticks).
    pub(super) fn keep_bridge_reports(&mut self, peer: &mut HapticPeer) {
        keep_bridge_report(&self.stats, peer, 0);
        for (tool, p) in self.others.iter_mut() {
            keep_bridge_report(&self.stats, p, *tool);
        }
    }
}

/// The first deadline at least a `period` after `now` on the grid `epoch + (m + fraction) ·
/// period` (`fraction` in [0, 1)): it lies in `[now + period, now + 2 · period)`.
pub(super) fn phased_deadline(epoch: Instant, now: Instant, period: Duration, fraction: f64) -> Instant {
    let p = period.as_nanos().max(1);
    let offset = (fraction.clamp(0.0, 1.0) * p as f64) as u128 % p;
    let from = now.saturating_duration_since(epoch).as_nanos() + p;
    let m = from.saturating_sub(offset).div_ceil(p);
    epoch + Duration::from_nanos(u64::try_from(m * p + offset).unwrap_or(u64::MAX))
}

/// The engine's tool state for a haptic sample on the channel of tool `tool` (the scene's
/// index; 0 for a scene with one tool).
fn tool_input(s: &HapticState, tool: usize) -> ToolInput {
    ToolInput {
        tool,
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
