//! The bridge's 1 kHz loop: read the device, send the tool state, take the force, make it
//! safe, write it to the device — every period, on the bridge's own clock.
//!
//! One tick, in order:
//!
//! 1. wait for the tick's deadline ([`WaitStrategy`]);
//! 2. read the device at the tick's scheduled time; pass the sample through the
//!    [`InputGuard`] (non-finite held, excursions and jumps clamped, counted);
//! 3. publish the [`HapticState`] (organ frame);
//! 4. take the newest force; if it does not yet answer this tick's state, wait for it up to
//!    [`BridgeParams::answer_wait`] — polling, or blocked on the server's `answered` event
//!    ([`AnswerWake`]) — (unless eight ticks in a row went unanswered in time: then
//!    only on every 16th tick, so a server that answers a tick late, or is gone, costs no
//!    spinning);
//! 5. a force is *fresh* when it arrived since the last tick and answers a state read less
//!    than [`STALE_AFTER_TICKS`] periods ago; otherwise the watchdog ages the last one
//!    ([`watchdog_scale`]: zero four ticks after the last fresh force);
//! 6. shape it ([`ForceGuard`]: finite, clamped, rate-limited) and write it to the device;
//!    record device read → force written for fresh forces, the deadline, the trace row;
//! 7. every [`BridgeParams::report_every`] ticks, publish a [`BridgeReport`].
//!
//! Nothing in the loop allocates: the trace and the histogram are sized before it starts.
//! Per-tick transport errors are counted and the tick goes on (the watchdog makes it safe).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use hdrhistogram::Histogram;
use vademecum_proto::shm::{self, BridgeReport, HapticCommand, HapticState, STATE_ADJUSTED, TOOL_PROBE, TOOL_SCALPEL};

use crate::device::{Device, DeviceError, DeviceReading};
use crate::guard::{ForceGuard, InputGuard, watchdog_scale};
use crate::link::Link;
use crate::profile::{DeviceProfile, FrameMap};
use crate::timing::{self, WaitStrategy};

/// A force answering a state read this many periods ago or earlier is stale, not fresh.
pub const STALE_AFTER_TICKS: u64 = 5;

/// After this many ticks in a row without their own answer in time, the loop stops polling
/// for it (the server answers a tick late, or is gone) and probes again every 16th tick.
const GIVE_UP_WAITING: u32 = 8;

/// After a stall longer than this many periods the loop restarts its schedule from now
/// (the missed ticks are counted as misses, not run back to back).
const MAX_CATCH_UP: u32 = 10;

/// How a tick waits for the answer to its own state (step 4 of the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum AnswerWake {
    /// Poll the force subscriber until the answer arrives or the wait is over: the answer is
    /// taken microseconds after it is published, at the cost of a busy CPU for up to
    /// [`BridgeParams::answer_wait`] a tick — the right choice for one device on its own core.
    #[default]
    Poll,
    /// Block on the server's `answered` event (a kernel wake-up per answer, tens of µs on a
    /// busy host) and spend no CPU while waiting: the choice when several bridges share a
    /// host's cores, where polling bridges would take the cores the server needs.
    Event,
}

impl std::fmt::Display for AnswerWake {
    /// The command-line name (`poll`, `event`).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Poll => "poll",
            Self::Event => "event",
        })
    }
}

/// How the loop runs.
#[derive(Debug, Clone)]
pub struct BridgeParams {
    /// Tick period (1 ms: 1 kHz).
    pub period: Duration,
    /// How the loop waits for its deadlines.
    pub strategy: WaitStrategy,
    /// Spin window of the hybrid strategy.
    pub window: Duration,
    /// How long a tick waits for the answer to its own state (0: use whatever is there).
    pub answer_wait: Duration,
    /// How it waits for it.
    pub answer_wake: AnswerWake,
    /// Stop after this long (None: until stopped, or the device is done).
    pub duration: Option<Duration>,
    /// Give up when no fresh force arrived for this long (None: wait for the server forever).
    pub server_timeout: Option<Duration>,
    /// Trace rows kept (the first ones); later rows are counted as dropped.
    pub trace_limit: usize,
    /// Ticks between two reports.
    pub report_every: u32,
    /// Device limits.
    pub profile: DeviceProfile,
    /// Device frame → organ frame.
    pub frame: FrameMap,
    /// Tool kind sent ([`TOOL_PROBE`] …); `None`: a scalpel while the device reports a blade,
    /// else a probe.
    pub tool: Option<u32>,
    /// Before the loop starts (its buffers allocated): touch the stack and lock the
    /// process's memory in RAM ([`timing::lock_memory`]), so no tick takes a page fault.
    pub lock_memory: bool,
    /// While the loop runs, hold a PM QoS request for CPU wake-ups within 0 µs
    /// ([`timing::request_wake_latency`]): idle CPUs poll instead of halting.
    pub hold_wake_latency: bool,
}

impl Default for BridgeParams {
    fn default() -> Self {
        Self {
            period: Duration::from_millis(1),
            strategy: WaitStrategy::Hybrid,
            window: timing::DEFAULT_SPIN_WINDOW,
            answer_wait: Duration::from_micros(300),
            answer_wake: AnswerWake::Poll,
            duration: None,
            server_timeout: None,
            trace_limit: 600_000,
            report_every: 250,
            profile: DeviceProfile::SIM,
            frame: FrameMap::default(),
            tool: None,
            lock_memory: true,
            hold_wake_latency: true,
        }
    }
}

/// One tick as it happened.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TraceRow {
    /// Tick number (= the state's sequence number).
    pub tick: u64,
    /// Device read (`CLOCK_MONOTONIC`, ns).
    pub t_read_ns: u64,
    /// How late the bridge woke for this tick, after its deadline (ns).
    pub lateness_ns: u64,
    /// State published (ns).
    pub t_sent_ns: u64,
    /// Force written (ns).
    pub t_write_ns: u64,
    /// The server's side of this tick's own answer (ns; all 0 when the force written does
    /// not answer this tick's state): when it meant to start polling, started polling,
    /// received the state, and answered ([`HapticCommand`]).
    pub t_peer_planned_ns: u64,
    /// Started polling (ns).
    pub t_peer_polling_ns: u64,
    /// Received the state (ns).
    pub t_peer_received_ns: u64,
    /// Answered (ns).
    pub t_answer_ns: u64,
    /// Position sent (organ frame, m).
    pub position_m: [f64; 3],
    /// Whether a fresh force arrived this tick.
    pub fresh: bool,
    /// The tick (state sequence number) the force answers (`u64::MAX`: none yet).
    pub answers: u64,
    /// The force received from the server (organ frame, N).
    pub received_n: [f64; 3],
    /// The force written to the device (device frame, N).
    pub output_n: [f64; 3],
    /// Ticks since the last fresh force.
    pub age: u32,
    /// Whether the input guard adjusted the sample.
    pub input_adjusted: bool,
}

/// Why the loop ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EndReason {
    /// The requested duration elapsed.
    Duration,
    /// The device has nothing more to play.
    DeviceFinished,
    /// Asked to stop (signal).
    Stopped,
    /// No fresh force for [`BridgeParams::server_timeout`].
    ServerTimeout,
}

/// What a run of the loop produced.
#[derive(Debug)]
pub struct BridgeOutcome {
    /// Why it ended.
    pub end: EndReason,
    /// The final counters and latency percentiles.
    pub report: BridgeReport,
    /// Device read → force written over the fresh forces (ns).
    pub latency_ns: Histogram<u64>,
    /// Lateness of each tick's start after its deadline (ns): the OS wake-up floor.
    pub lateness_ns: Histogram<u64>,
    /// From each tick's deadline to its force written (ns): the wake-up floor plus the
    /// tick's own work and IPC — the figure to compare with a null loop's.
    pub completion_ns: Histogram<u64>,
    /// The first [`BridgeParams::trace_limit`] ticks.
    pub trace: Vec<TraceRow>,
    /// While tracing: the answers that arrived after their own tick (answering an earlier
    /// state), whether used or superseded — where a trace finds the server's side of a tick
    /// whose answer came too late.
    pub late_answers: Vec<HapticCommand>,
    /// Ticks not traced.
    pub trace_dropped: u64,
    /// Forces superseded by a newer one before use.
    pub skipped_forces: u64,
    /// States, forces or reports that could not be sent.
    pub link_errors: u64,
    /// Whether the memory was locked before the loop, or why not.
    pub memory_locked: Result<(), timing::Refused>,
    /// Whether the CPU wake-up latency request was held during the loop, or why not.
    pub wake_latency_held: Result<(), timing::Refused>,
    /// vCPU steal time during the loop, summed over the machine's CPUs
    /// ([`timing::vcpu_steal`]; `None` where not reported).
    pub steal: Option<Duration>,
    /// Wall time of the loop.
    pub wall: Duration,
    /// CPU time of the loop's thread.
    pub cpu: Duration,
}

impl BridgeOutcome {
    /// What the loop secured before it started, in words: `memory locked, wake latency held
    /// at 0 µs`, or why not.
    pub fn safeguards(&self) -> String {
        let memory = match &self.memory_locked {
            Ok(()) => "memory locked".to_string(),
            Err(why) => format!("memory not locked ({why})"),
        };
        let wake = match &self.wake_latency_held {
            Ok(()) => "CPU wake-up latency held at 0 µs".to_string(),
            Err(why) => format!("CPU wake-up latency not held ({why})"),
        };
        format!("{memory}, {wake}")
    }

    /// vCPU steal during the loop as a percentage of the machine's CPU time
    /// (`cpus` × wall time), when the kernel reports it.
    pub fn steal_percent(&self, cpus: usize) -> Option<f64> {
        let wall = self.wall.as_secs_f64() * cpus.max(1) as f64;
        self.steal.map(|s| 100.0 * s.as_secs_f64() / wall.max(1e-9))
    }
}

/// Why the loop could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BridgeError {
    /// The device failed (the force was zeroed and the device released).
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// Invalid parameters.
    #[error("invalid bridge parameters: {0}")]
    Params(String),
}

fn histogram() -> Histogram<u64> {
    // 1 ns … 10 s at 3 significant digits: sized once, never resized in the loop
    Histogram::new_with_bounds(1, 10_000_000_000, 3).expect("static histogram bounds are valid")
}

/// Runs the loop on the calling thread until the duration, the device's end, a server
/// timeout, or `stop`; the device is released (zero force) on every way out.
pub fn run<D: Device + ?Sized, L: Link>(
    device: &mut D,
    link: &mut L,
    p: &BridgeParams,
    stop: &Arc<AtomicBool>,
) -> Result<BridgeOutcome, BridgeError> {
    p.profile.validate().map_err(BridgeError::Params)?;
    if p.period.is_zero() || p.report_every == 0 {
        return Err(BridgeError::Params("the period and the report interval must be positive".into()));
    }
    let result = run_inner(device, link, p, stop);
    device.release();
    result
}

fn run_inner<D: Device + ?Sized, L: Link>(
    device: &mut D,
    link: &mut L,
    p: &BridgeParams,
    stop: &Arc<AtomicBool>,
) -> Result<BridgeOutcome, BridgeError> {
    let dt = p.period.as_secs_f64();
    let period_ns = p.period.as_nanos() as u64;
    let mut input = InputGuard::new(&p.profile, dt);
    let mut force = ForceGuard::new(&p.profile, dt);
    let mut log = Log::new(p.trace_limit);
    let mut r = BridgeReport::default();
    let safeguards = Safeguards::take(p);
    let start = Instant::now();
    let t0_ns = shm::monotonic_ns();
    let mut next = start;
    let mut tick: u64 = 0;
    let mut age: u32 = u32::MAX;
    let mut target_n = [0.0; 3];
    let mut received_n = [0.0; 3];
    let mut answers = u64::MAX;
    let mut missed_in_tick: u32 = 0;
    let end = loop {
        if stop.load(Ordering::Relaxed) {
            break EndReason::Stopped;
        }
        timing::wait_until(next, p.strategy, p.window, || false);
        let woke = Instant::now();
        let late_ns = woke.saturating_duration_since(next).as_nanos() as u64;
        let _ = log.lateness.record(late_ns.max(1));
        let t_s = tick as f64 * dt;
        if p.duration.is_some_and(|d| t_s >= d.as_secs_f64()) {
            break EndReason::Duration;
        }
        if device.finished(t_s) {
            break EndReason::DeviceFinished;
        }
        // 2. read and admit the sample
        let t_read_ns = shm::monotonic_ns();
        let reading = device.read(t_s)?;
        let (x_dev, verdict) = input.admit(reading.position_m);
        r.rejected_non_finite += u64::from(verdict.non_finite);
        r.clamped_workspace += u64::from(verdict.outside);
        r.clamped_jumps += u64::from(verdict.jump);
        let state = tool_state(p, &reading, x_dev, verdict.adjusted(), tick, t_read_ns);
        // 3. send it
        if link.send_state(&state).is_err() {
            log.link_errors += 1;
        }
        let t_sent_ns = shm::monotonic_ns();
        // 4. take the newest force, polling a little for this tick's own answer
        let wait = !p.answer_wait.is_zero() && (missed_in_tick < GIVE_UP_WAITING || tick.is_multiple_of(16));
        let newest = newest_answer(link, p, wait, tick, t_read_ns, &mut log);
        // 5. fresh, or aged by the watchdog
        let fresh = newest.filter(|c| c.t_read_ns >= t0_ns && t_read_ns.saturating_sub(c.t_read_ns) < STALE_AFTER_TICKS * period_ns);
        if fresh.is_some_and(|c| c.t_read_ns == t_read_ns) {
            missed_in_tick = 0;
        } else {
            missed_in_tick = missed_in_tick.saturating_add(1);
        }
        if let Some(c) = fresh {
            age = 0;
            received_n = c.force_n;
            target_n = p.frame.force_to_device(c.force_n);
            answers = c.state_seq;
            r.fresh_forces += 1;
        } else {
            age = age.saturating_add(1);
            r.watchdog_ticks += 1;
        }
        // 6. shape and write
        let (out, fv) = force.shape(target_n, watchdog_scale(age));
        r.rejected_forces += u64::from(fv.non_finite);
        r.clamped_forces += u64::from(fv.clamped);
        r.rate_limited_forces += u64::from(fv.rate_limited);
        device.write_force(out);
        let t_write_ns = shm::monotonic_ns();
        if let Some(c) = fresh {
            let _ = log.latency.record(t_write_ns.saturating_sub(c.t_read_ns).max(1));
        }
        let done = Instant::now();
        let _ = log.completion.record(done.saturating_duration_since(next).as_nanos().max(1) as u64);
        if done > next + p.period {
            r.deadline_misses += 1;
        }
        r.ticks += 1;
        let own = fresh.filter(|c| c.t_read_ns == t_read_ns).unwrap_or_default();
        log.trace(TraceRow {
            tick,
            t_read_ns,
            lateness_ns: late_ns,
            t_sent_ns,
            t_write_ns,
            t_peer_planned_ns: own.t_peer_planned_ns,
            t_peer_polling_ns: own.t_peer_polling_ns,
            t_peer_received_ns: own.t_peer_received_ns,
            t_answer_ns: own.t_answer_ns,
            position_m: state.position_m,
            fresh: fresh.is_some(),
            answers,
            received_n,
            output_n: out,
            age,
            input_adjusted: verdict.adjusted(),
        });
        // 7. report; housekeeping while the server is away
        if (tick + 1).is_multiple_of(u64::from(p.report_every)) {
            log.report(link, &mut r);
        }
        let silent = if age == u32::MAX { tick + 1 } else { u64::from(age) };
        if silent > 50 && tick.is_multiple_of(500) {
            link.maintain();
        }
        if let Some(limit) = p.server_timeout
            && silent as f64 * dt >= limit.as_secs_f64()
        {
            break EndReason::ServerTimeout;
        }
        tick += 1;
        next += p.period;
        let now = Instant::now();
        if now > next + p.period * MAX_CATCH_UP {
            next = now;
        }
    };
    log.report(link, &mut r);
    Ok(log.outcome(end, r, link, safeguards, start))
}

/// The tool state of tick `tick` (read at `t_read_ns`) from the device's `reading`, whose
/// position the input guard admitted as `x_dev` (`adjusted`: it had to change it: the
/// velocity is then not trusted). Whatever else of the reading is not finite is dropped: the
/// velocity and the orientation to zero, the closure to open, the blade onto the tip (a
/// zero-length blade, which the server refuses).
fn tool_state(p: &BridgeParams, reading: &DeviceReading, x_dev: [f64; 3], adjusted: bool, tick: u64, t_read_ns: u64) -> HapticState {
    let velocity = if adjusted || !reading.velocity_m_s.iter().all(|v| v.is_finite()) {
        [0.0; 3]
    } else {
        p.frame.velocity_to_organ(reading.velocity_m_s)
    };
    let closure = if reading.closure.is_finite() {
        reading.closure.clamp(0.0, 1.0)
    } else {
        0.0
    };
    // the blade moves with the tip the guard admitted
    let blade_end = reading
        .blade_end_m
        .filter(|e| e.iter().chain(&reading.position_m).all(|v| v.is_finite()))
        .map_or(x_dev, |e| std::array::from_fn(|k| x_dev[k] + e[k] - reading.position_m[k]));
    let orientation = if reading.orientation.iter().all(|v| v.is_finite()) {
        reading.orientation
    } else {
        [0.0; 4]
    };
    HapticState {
        seq: tick,
        t_read_ns,
        position_m: p.frame.to_organ(x_dev),
        velocity_m_s: velocity,
        closure,
        tool: p
            .tool
            .unwrap_or(if reading.blade_end_m.is_some() { TOOL_SCALPEL } else { TOOL_PROBE }),
        flags: if adjusted { STATE_ADJUSTED } else { 0 },
        orientation,
        blade_end_m: p.frame.to_organ(blade_end),
    }
}

/// The newest force on the link; when `wait`, polling (or blocking, [`AnswerWake::Event`]) up
/// to [`BridgeParams::answer_wait`] for the answer to this tick's own state (`tick`, read at
/// `t_read_ns`). Answers to earlier states met on the way go to the log's trace.
fn newest_answer<L: Link>(link: &mut L, p: &BridgeParams, wait: bool, tick: u64, t_read_ns: u64, log: &mut Log) -> Option<HapticCommand> {
    let mut newest = link.poll_command();
    if let Some(c) = &newest {
        log.keep_late(c, tick);
    }
    let own = |c: &HapticCommand| c.state_seq == tick && c.t_read_ns == t_read_ns;
    if wait && !newest.as_ref().is_some_and(own) {
        let until = Instant::now() + p.answer_wait;
        let mut answered = |link: &mut L| {
            if let Some(c) = link.poll_command() {
                log.keep_late(&c, tick);
                newest = Some(c);
            }
            newest.as_ref().is_some_and(own)
        };
        let mut blocked = p.answer_wake == AnswerWake::Event;
        while blocked && !answered(link) {
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            // a link that cannot block falls back to polling
            blocked = link.wait_command(left);
        }
        if !blocked {
            timing::wait_between(Instant::now(), until, || answered(link));
        }
    }
    newest
}

/// What the loop secured before it started ([`BridgeParams::lock_memory`],
/// [`BridgeParams::hold_wake_latency`]; the request is held while this lives), and the
/// clocks its outcome is measured from.
struct Safeguards {
    memory_locked: Result<(), timing::Refused>,
    wake_latency: Option<Result<timing::WakeLatencyRequest, timing::Refused>>,
    steal0: Option<Duration>,
    cpu0: Duration,
}

impl Safeguards {
    fn take(p: &BridgeParams) -> Self {
        let memory_locked = if p.lock_memory {
            timing::prefault_stack();
            timing::lock_memory()
        } else {
            Err(timing::Refused::NotAsked)
        };
        Self {
            memory_locked,
            wake_latency: p.hold_wake_latency.then(|| timing::request_wake_latency(0)),
            steal0: timing::vcpu_steal(),
            cpu0: timing::thread_cpu_time(),
        }
    }
}

/// What the loop records for its outcome: the histograms, the trace (at most `limit` rows, and
/// as many answers that came late) and the link's failures.
struct Log {
    latency: Histogram<u64>,
    lateness: Histogram<u64>,
    completion: Histogram<u64>,
    trace: Vec<TraceRow>,
    late_answers: Vec<HapticCommand>,
    trace_dropped: u64,
    link_errors: u64,
    limit: usize,
}

impl Log {
    /// Allocates everything before the loop: a tick does not allocate.
    fn new(limit: usize) -> Self {
        Self {
            latency: histogram(),
            lateness: histogram(),
            completion: histogram(),
            trace: Vec::with_capacity(limit),
            late_answers: Vec::with_capacity(limit),
            trace_dropped: 0,
            link_errors: 0,
            limit,
        }
    }

    /// Keeps `c` for the trace if it answers a state before `tick`'s (once, whether used or
    /// not).
    fn keep_late(&mut self, c: &HapticCommand, tick: u64) {
        if c.state_seq < tick && self.late_answers.len() < self.limit && self.late_answers.last().is_none_or(|l| l.seq != c.seq) {
            self.late_answers.push(*c);
        }
    }

    /// Traces a tick, or counts it dropped past the limit.
    fn trace(&mut self, row: TraceRow) {
        if self.trace.len() < self.limit {
            self.trace.push(row);
        } else {
            self.trace_dropped += 1;
        }
    }

    /// Sends `r`, its latency percentiles filled in and stamped now, to the server.
    fn report<L: Link>(&mut self, link: &mut L, r: &mut BridgeReport) {
        fill_percentiles(r, &self.latency);
        r.t_ns = shm::monotonic_ns();
        if link.send_report(r).is_err() {
            self.link_errors += 1;
        }
    }

    /// The loop's outcome: it ended for `end` with the counts `r`.
    fn outcome<L: Link>(self, end: EndReason, report: BridgeReport, link: &L, safeguards: Safeguards, start: Instant) -> BridgeOutcome {
        BridgeOutcome {
            end,
            report,
            latency_ns: self.latency,
            lateness_ns: self.lateness,
            completion_ns: self.completion,
            trace: self.trace,
            late_answers: self.late_answers,
            trace_dropped: self.trace_dropped,
            skipped_forces: link.skipped(),
            link_errors: self.link_errors,
            memory_locked: safeguards.memory_locked,
            wake_latency_held: match safeguards.wake_latency {
                Some(Ok(_held)) => Ok(()),
                Some(Err(why)) => Err(why),
                None => Err(timing::Refused::NotAsked),
            },
            steal: timing::vcpu_steal().zip(safeguards.steal0).map(|(b, a)| b.saturating_sub(a)),
            wall: start.elapsed(),
            cpu: timing::thread_cpu_time().saturating_sub(safeguards.cpu0),
        }
    }
}

fn fill_percentiles(r: &mut BridgeReport, h: &Histogram<u64>) {
    if h.is_empty() {
        return;
    }
    r.latency_p50_ns = h.value_at_quantile(0.5);
    r.latency_p99_ns = h.value_at_quantile(0.99);
    r.latency_p999_ns = h.value_at_quantile(0.999);
    r.latency_max_ns = h.max();
}

/// Writes a trace as CSV: `tick,t_read_ns,t_write_ns,x_m,y_m,z_m,fresh,answers,fx_n,fy_n,fz_n,out_x_n,out_y_n,out_z_n,age,input_adjusted,lateness_ns,t_sent_ns,t_peer_planned_ns,t_peer_polling_ns,t_peer_received_ns,t_answer_ns`
/// (received force in the organ frame, output in the device frame; `answers` empty before the
/// first force; the server's times 0 when the force written does not answer the tick's own
/// state). Floats are written in full precision (round-trip exact).
pub fn write_trace(path: &std::path::Path, trace: &[TraceRow]) -> std::io::Result<()> {
    let mut w = csv::Writer::from_path(path)?;
    w.write_record([
        "tick",
        "t_read_ns",
        "t_write_ns",
        "x_m",
        "y_m",
        "z_m",
        "fresh",
        "answers",
        "fx_n",
        "fy_n",
        "fz_n",
        "out_x_n",
        "out_y_n",
        "out_z_n",
        "age",
        "input_adjusted",
        "lateness_ns",
        "t_sent_ns",
        "t_peer_planned_ns",
        "t_peer_polling_ns",
        "t_peer_received_ns",
        "t_answer_ns",
    ])?;
    for t in trace {
        let f = |x: f64| format!("{x:?}");
        let answers = if t.answers == u64::MAX {
            String::new()
        } else {
            t.answers.to_string()
        };
        let age = if t.age == u32::MAX { String::new() } else { t.age.to_string() };
        w.write_record([
            t.tick.to_string(),
            t.t_read_ns.to_string(),
            t.t_write_ns.to_string(),
            f(t.position_m[0]),
            f(t.position_m[1]),
            f(t.position_m[2]),
            u8::from(t.fresh).to_string(),
            answers,
            f(t.received_n[0]),
            f(t.received_n[1]),
            f(t.received_n[2]),
            f(t.output_n[0]),
            f(t.output_n[1]),
            f(t.output_n[2]),
            age,
            u8::from(t.input_adjusted).to_string(),
            t.lateness_ns.to_string(),
            t.t_sent_ns.to_string(),
            t.t_peer_planned_ns.to_string(),
            t.t_peer_polling_ns.to_string(),
            t.t_peer_received_ns.to_string(),
            t.t_answer_ns.to_string(),
        ])?;
    }
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::replay::Replay;
    use crate::device::{DeviceReading, NullDevice};
    use crate::link::NullLink;
    use vademecum_proto::shm::HapticCommand;

    /// A link whose server renders a stiff wall at z = 0 (F = 2000 N/m · depth) and can be
    /// switched off.
    #[derive(Default)]
    struct Wall {
        pending: Option<HapticState>,
        up: bool,
        n: u64,
    }

    impl Link for Wall {
        fn send_state(&mut self, s: &HapticState) -> Result<(), crate::link::LinkError> {
            self.pending = self.up.then_some(*s);
            Ok(())
        }
        fn poll_command(&mut self) -> Option<HapticCommand> {
            let s = self.pending.take()?;
            self.n += 1;
            Some(HapticCommand {
                seq: self.n,
                state_seq: s.seq,
                t_read_ns: s.t_read_ns,
                t_answer_ns: shm::monotonic_ns(),
                force_n: [0.0, 0.0, 2000.0 * (-s.position_m[2]).max(0.0)],
                ..HapticCommand::default()
            })
        }
        fn send_report(&mut self, _: &BridgeReport) -> Result<(), crate::link::LinkError> {
            Ok(())
        }
        fn skipped(&self) -> u64 {
            0
        }
    }

    /// A device pressed 3 mm into the wall that stops answering the server after `cut` ticks.
    struct Pressed {
        writes: Vec<[f64; 3]>,
    }

    impl Device for Pressed {
        fn name(&self) -> &str {
            "pressed"
        }
        fn read(&mut self, _t: f64) -> Result<DeviceReading, DeviceError> {
            Ok(DeviceReading {
                position_m: [0.0, 0.0, -0.003],
                ..DeviceReading::default()
            })
        }
        fn write_force(&mut self, f: [f64; 3]) {
            self.writes.push(f);
        }
    }

    fn params(ticks: u64) -> BridgeParams {
        BridgeParams {
            strategy: WaitStrategy::Sleep,
            duration: Some(Duration::from_millis(ticks)),
            ..BridgeParams::default()
        }
    }

    #[test]
    fn the_force_fades_to_zero_within_five_ticks_when_the_server_goes_silent() {
        let stop = Arc::new(AtomicBool::new(false));
        let mut link = Wall {
            up: true,
            ..Wall::default()
        };
        let mut dev = Pressed { writes: Vec::new() };
        // up for 50 ticks: the force ramps to 6 N (rate limit 1 N per tick) and holds
        let p = params(50);
        let out = run(&mut dev, &mut link, &p, &stop).unwrap();
        assert_eq!(out.end, EndReason::Duration);
        let last = out.trace.last().unwrap();
        assert!(last.fresh && (last.output_n[2] - 6.0).abs() < 1e-9, "{last:?}");
        // a second run on the same device with the server down from the start of the
        // run: the watchdog takes over from the guard's initial zero, so test the fade with a
        // link that goes down mid-run instead
        struct Flaky(Wall, u64);
        impl Link for Flaky {
            fn send_state(&mut self, s: &HapticState) -> Result<(), crate::link::LinkError> {
                self.1 += 1;
                self.0.up = self.1 <= 30;
                self.0.send_state(s)
            }
            fn poll_command(&mut self) -> Option<HapticCommand> {
                self.0.poll_command()
            }
            fn send_report(&mut self, r: &BridgeReport) -> Result<(), crate::link::LinkError> {
                self.0.send_report(r)
            }
            fn skipped(&self) -> u64 {
                0
            }
        }
        let mut flaky = Flaky(Wall::default(), 0);
        let out = run(&mut dev, &mut flaky, &params(60), &stop).unwrap();
        let last_fresh = out.trace.iter().rposition(|t| t.fresh).unwrap();
        assert_eq!(last_fresh, 29);
        assert!(out.trace[last_fresh].output_n[2] > 5.0);
        for t in &out.trace[last_fresh + 5..] {
            assert_eq!(t.output_n, [0.0; 3], "tick {}", t.tick);
        }
        // monotone fade, never a step up
        for w in out.trace[last_fresh..].windows(2) {
            assert!(w[1].output_n[2] <= w[0].output_n[2]);
        }
        assert_eq!(dev.writes.last(), Some(&[0.0; 3]), "the device is released with zero force");
    }

    #[test]
    fn bad_device_samples_are_counted_and_never_become_a_force_spike() {
        let dir = tempfile::tempdir().unwrap();
        let rec = dir.path().join("bad.csv");
        // 2 mm into the wall, a NaN dropout, a 20 cm glitch, an excursion out of the
        // workspace, back to normal
        std::fs::write(
            &rec,
            "t_s,x_m,y_m,z_m\n0,0,0,-0.002\n0.010,NaN,0,-0.002\n0.012,0,0,-0.2\n0.020,0,0,-0.002\n0.030,0,0.9,-0.002\n0.035,0,0,-0.002\n0.060,0,0,-0.002\n",
        )
        .unwrap();
        let mut dev = Replay::read(&rec).unwrap();
        let mut link = Wall {
            up: true,
            ..Wall::default()
        };
        let stop = Arc::new(AtomicBool::new(false));
        let out = run(&mut dev, &mut link, &params(1000), &stop).unwrap();
        assert_eq!(out.end, EndReason::DeviceFinished);
        let r = out.report;
        assert!(r.rejected_non_finite >= 1, "{r:?}");
        assert!(r.clamped_jumps >= 1, "{r:?}");
        assert!(r.clamped_workspace >= 1, "{r:?}");
        let p = DeviceProfile::SIM;
        let step = p.max_force_rate_n_per_s * 1e-3;
        let mut prev = [0.0; 3];
        for t in &out.trace {
            let n = t.output_n.iter().map(|c| c * c).sum::<f64>().sqrt();
            assert!(n <= p.max_force_n + 1e-9, "tick {}: {n} N", t.tick);
            let d = (0..3).map(|k| (t.output_n[k] - prev[k]).powi(2)).sum::<f64>().sqrt();
            assert!(d <= step + 1e-9, "tick {}: a step of {d} N", t.tick);
            // the position sent never moves faster than a hand
            prev = t.output_n;
        }
        for w in out.trace.windows(2) {
            let d = (0..3)
                .map(|k| (w[1].position_m[k] - w[0].position_m[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(d <= p.max_speed_m_s * 1e-3 + 1e-12, "tick {}: moved {d} m", w[1].tick);
            assert!(w[1].position_m.iter().all(|c| c.is_finite()));
        }
    }

    #[test]
    fn the_null_loop_answers_every_tick_fresh() {
        let stop = Arc::new(AtomicBool::new(false));
        let out = run(&mut NullDevice::default(), &mut NullLink::default(), &params(30), &stop).unwrap();
        assert_eq!(out.report.ticks, 30);
        assert_eq!(out.report.fresh_forces, 30);
        assert_eq!(out.latency_ns.len(), 30);
        assert!(out.trace.iter().all(|t| t.fresh && t.age == 0));
    }

    #[test]
    fn a_stop_request_ends_the_loop_and_a_silent_server_times_out() {
        let stop = Arc::new(AtomicBool::new(true));
        let out = run(
            &mut NullDevice::default(),
            &mut NullLink::default(),
            &BridgeParams::default(),
            &stop,
        )
        .unwrap();
        assert_eq!(out.end, EndReason::Stopped);
        let stop = Arc::new(AtomicBool::new(false));
        let p = BridgeParams {
            server_timeout: Some(Duration::from_millis(20)),
            strategy: WaitStrategy::Sleep,
            ..BridgeParams::default()
        };
        let out = run(&mut NullDevice::default(), &mut Wall::default(), &p, &stop).unwrap();
        assert_eq!(out.end, EndReason::ServerTimeout);
        assert!(out.report.ticks >= 20);
    }
}
