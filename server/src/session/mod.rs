//! Sessions: a scene, its loaded bundles (shared read-only with other sessions), the effect
//! pipeline built from the scene's `[effects]`, a tick loop, an answer dispatcher and a frame
//! producer — each a turn on a pool's worker or a thread of its own.
//!
//! - The **tick loop** owns the pipeline. It runs on a tick worker shared with other sessions
//!   ([`scheduler`], [`SessionConfig::ticking`]) or on a thread of its own (the same loop,
//!   with one session; always for a haptic session) — "the tick thread" below is whichever
//!   runs it. It keeps a period (1 ms by default) and, between its deadlines, waits parked: [`Session::submit`] queues a tool state in the bounded
//!   command queue and unparks it, and it answers at once — draining the queue with
//!   `try_recv` (at most [`MAX_COMMANDS_PER_TICK`] per wake-up), each tool state in arrival
//!   order, one pipeline tick each, into the session's preallocated answer ring (see
//!   [`answers`]). At each deadline it re-evaluates the last tool state when the period
//!   answered none (the force stays fresh for a device; the tissue advances one pipeline tick
//!   per answer, or one per period without any) and writes the period's state into a triple
//!   buffer (a wait-free latest-value slot) for the frame thread. A haptic session's tick
//!   thread waits for its bridge instead and answers queued states when it wakes. It never awaits, never allocates in the
//!   loop (a counting-allocator test holds it to that), and shares no lock with another
//!   thread: histograms are handed over through lock-free queues ([`stats`]).
//! - The **answer dispatcher** (an answer worker's turn, [`answers::AnswerWorkers`], or a
//!   thread of the session's own) routes the ring's answers to each stream's tokio
//!   channel, so the wake-up of async tasks costs the tick nothing; a consumer that stops
//!   reading loses answers (counted) and never blocks the tick.
//! - The **frame thread** reads the latest tick state at the frame rate, turns it into the
//!   displacement of every organ's surface (f32, node-major modes) and publishes it on a
//!   `tokio::sync::watch` channel, where the latest frame wins: a slow viewer skips frames
//!   and never delays a force. It is a frame worker shared with other sessions
//!   ([`frames::FrameWorkers`], [`SessionConfig::framing`]) or a thread of the session's own
//!   (always for a co-rotational cutting session, whose deformation costs milliseconds a frame).
//!
//! Backpressure: the command queue is bounded ([`SessionConfig::queue`]); when it is full,
//! [`Session::submit`] refuses the tool state at once ([`SubmitError::Busy`]) instead of
//! queueing latency.

pub mod answers;
pub mod demand;
pub mod devices;
pub mod fidelity;
pub mod frames;
pub mod memory;
pub mod scheduler;
pub mod script;
pub mod stats;
mod tick;
mod workers;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use tokio::sync::watch;
use vademecum_bridge::peer::HapticPeer;
use vademecum_bridge::timing::{RealtimeStatus, WaitStrategy};
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::contact::Bounds;
use vademecum_engine::pipeline::{GraspSite, Pipeline, PipelineError, TickState, ToolInput, ToolKind};
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::schema::{Fallback, ToolSpec};
use vademecum_proto::shm::{ChannelNameError, HapticChannel, OpenError};
use workers::Placed;

pub use answers::{AnswerStream, AnswerWorkers, StreamId};
pub use devices::{DeviceWorkers, DeviceWorkersConfig};
pub use frames::{Frame, FrameWorkers, FrameWorkersConfig, SurfaceGeometry};
pub use memory::SessionMemory;
pub use scheduler::{PlaceError, SchedulerConfig, TickScheduler};
pub use script::{BuiltinPathError, builtin_grasp, builtin_incisions, builtin_palpation, palpation_reach, tool_at};
pub use stats::{BridgeSnapshot, StatsSnapshot, TickStats};
pub use tick::MAX_COMMANDS_PER_TICK;
pub use vademecum_bridge::trajectory::Trajectory;

/// A tool state sent to a session, with where to send its answer.
#[derive(Debug, Clone)]
pub struct ToolCommand {
    /// The tool state.
    pub input: ToolInput,
    /// The client's sequence number, echoed in the answer.
    pub seq: u64,
    /// The client's timestamp (µs, its own clock), echoed.
    pub client_time_us: u64,
    /// When the server received it.
    pub received: Instant,
    /// The stream the answer goes to ([`Session::open_answers`]).
    pub reply: StreamId,
    /// The state names its tool (`ToolState.tool`): the session moves named tools together
    /// and its frames list every tool ([`Frame::tools`]).
    pub named: bool,
}

/// The answer to one tool state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Answer {
    /// The sequence number of the tool state answered.
    pub seq: u64,
    /// Its client timestamp, echoed (µs).
    pub client_time_us: u64,
    /// When the session received it (µs since the session started).
    pub received_us: u64,
    /// When the tick answered it (µs since the session started).
    pub answered_us: u64,
    /// The tissue's step (pipeline tick) that answered it, counted from 0: one per answer and
    /// one per period that answered none, so the difference between two answers' numbers is
    /// the steps the tissue took from one to the other.
    pub tick: u64,
    /// Force, contact and events.
    pub state: TickState,
}

/// The `SCHED_FIFO` priority a device session's tick thread (or device worker) asks for.
pub const DEVICE_FIFO_PRIORITY: i32 = 70;

/// A session's haptic channel: where its device bridge sends tool states (see
/// [`vademecum_bridge::peer`]).
#[derive(Debug, Clone, PartialEq)]
pub struct HapticConfig {
    /// The channel name the bridge opens (`vademecum-bridge --session <name>`).
    pub channel: HapticChannel,
    /// How the tick thread waits for the bridge's states.
    pub wait: WaitStrategy,
    /// Spin window of the hybrid wait.
    pub spin_window: Duration,
    /// `SCHED_FIFO` priority asked for the tick thread (not with the spin wait, which would
    /// trip the kernel's real-time throttle); refused gracefully when not permitted.
    pub fifo_priority: Option<i32>,
    /// Pin the tick thread to this CPU (refused gracefully when the OS says no).
    pub cpu: Option<usize>,
    /// Where the hybrid wait expects the bridge's next state from.
    pub phase: vademecum_bridge::peer::PhaseSource,
}

impl HapticConfig {
    /// The channel `name` with the default (hybrid) wait.
    pub fn new(channel: HapticChannel) -> Self {
        Self {
            channel,
            wait: WaitStrategy::Hybrid,
            spin_window: vademecum_bridge::timing::DEFAULT_SPIN_WINDOW,
            fifo_priority: Some(DEVICE_FIFO_PRIORITY),
            cpu: None,
            phase: vademecum_bridge::peer::PhaseSource::Schedule,
        }
    }
}

/// The haptic channel of each of the scene's tools, with the tool's index in the scene: a
/// scene with one tool is driven on `base` itself, one with several has a channel per tool,
/// `<base>.<tool name>` ([`HapticChannel::for_tool`]) — a bridge per tool, two devices for two
/// hands.
pub fn tool_channels(base: &HapticChannel, scene: &Scene) -> Result<Vec<(usize, HapticChannel)>, ChannelNameError> {
    match scene.spec.tools.as_slice() {
        [] | [_] => Ok(vec![(0, base.clone())]),
        tools => tools.iter().enumerate().map(|(k, t)| Ok((k, base.for_tool(t.name())?))).collect(),
    }
}

/// Opens the haptic channels of `channels` (their peers: the first's, which paces the tick
/// loop, and the other tools').
fn open_channels(
    channels: &[(usize, HapticChannel)],
    wait: WaitStrategy,
    window: Duration,
    period: Duration,
) -> Result<(HapticPeer, Vec<(usize, HapticPeer)>), SessionError> {
    let open = |c: &HapticChannel| {
        HapticPeer::open(c, wait, window, period).map_err(|source| SessionError::Haptic {
            channel: c.name().to_string(),
            source,
        })
    };
    let ((_, first), rest) = channels.split_first().expect("a haptic session has a channel");
    let peer = open(first)?;
    let others = rest
        .iter()
        .map(|(tool, c)| Ok((*tool, open(c)?)))
        .collect::<Result<_, SessionError>>()?;
    Ok((peer, others))
}

/// Why a session did not start.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The scene asks for what the pipeline cannot do.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// No tick worker could take the session.
    #[error(transparent)]
    Ticking(#[from] PlaceError),
    /// A scripted hand that cannot move the tool it names ([`Hand`]).
    #[error("scripted hand {hand}: {why}")]
    Hand {
        /// The hand, numbered from 1.
        hand: usize,
        /// Why.
        why: String,
    },
    /// A tool's name cannot name its haptic channel ([`tool_channels`]).
    #[error(
        "the scene's tools need a haptic channel each: {0} (name the tools with letters, digits, '-' and '_', or use a shorter channel name)"
    )]
    ToolChannel(#[from] ChannelNameError),
    /// The haptic channel could not be opened.
    #[error("haptic channel '{channel}': {source}")]
    Haptic {
        /// The channel.
        channel: String,
        /// Why.
        source: OpenError,
    },
}

/// How a session runs.
#[derive(Debug, Clone)]
pub struct SessionConfig {
    /// Tick period (1 ms: 1 kHz).
    pub period: Duration,
    /// Frames produced per second for viewers (each viewer takes them at its own rate, up
    /// to this).
    pub frame_rate_hz: f64,
    /// Capacity of the command queue.
    pub queue: usize,
    /// The haptic channel, if a device bridge drives this session.
    pub haptic: Option<HapticConfig>,
    /// Called on the tick thread before anything else (CPU pinning, instrumentation such as
    /// the counting-allocator test of the tick loop); the session then ticks on a thread of
    /// its own.
    pub on_tick_thread: Option<fn()>,
    /// The tick workers the session is ticked by ([`scheduler`]); `None`: a thread of its own.
    /// A haptic session is ticked by a device worker or has a thread of its own.
    pub ticking: Option<Arc<TickScheduler>>,
    /// The device workers a haptic session with the event wait is ticked by
    /// ([`devices`]); `None`: a haptic session has a thread of its own.
    pub devices: Option<Arc<DeviceWorkers>>,
    /// The frame workers that make the session's frames ([`frames::FrameWorkers`]); `None`: a
    /// thread of its own. A co-rotational cutting session always has a thread of its own.
    pub framing: Option<Arc<FrameWorkers>>,
    /// The answer workers that route the session's answers to its streams
    /// ([`answers::AnswerWorkers`]); `None`: a dispatcher thread of its own.
    pub answering: Option<Arc<AnswerWorkers>>,
    /// Whether the session may fall back to its reduced fidelity under load ([`fidelity`]),
    /// when its scene allows it (`fidelity.fallback = "auto"`, the default). `serve
    /// --no-fidelity-fallback` turns it off for every session.
    pub fallback: bool,
    /// A deterministic session (headless runs, `vademecum run`): the same tool path gives
    /// bitwise the same answers and frames on any load. It never falls back
    /// ([`Self::fallback`] is ignored); the work beside the tick lands at ticks fixed by the
    /// path, the tick waiting for it ([`Pipeline::set_deterministic`]); frame `n` shows the
    /// first step at or after `n / frame_rate_hz` of session time, made while the tick waits,
    /// every one kept for the recorder ([`Session::take_frame_log`]); session time is the
    /// step's (`step × period`), not the clock's. Its ticks run late where a live session's
    /// side work would land late instead: not for a device.
    pub deterministic: bool,
}

impl Default for SessionConfig {
    fn default() -> Self {
        Self {
            period: Duration::from_millis(1),
            frame_rate_hz: 60.0,
            queue: 4096,
            haptic: None,
            on_tick_thread: None,
            ticking: None,
            devices: None,
            framing: None,
            answering: None,
            fallback: true,
            deterministic: false,
        }
    }
}

/// Why a tool state was not accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SubmitError {
    /// The command queue is full: the client sends faster than the session ticks.
    #[error("the session's command queue is full; send tool states no faster than the tick rate")]
    Busy,
    /// The session has stopped.
    #[error("the session has stopped")]
    Closed,
}

/// A running session.
#[derive(Debug)]
pub struct Session {
    id: String,
    scene: Arc<Scene>,
    bundles: Vec<Arc<LoadedBundle>>,
    effects: Vec<&'static str>,
    workspace: Bounds,
    grasp_sites: Vec<GraspSite>,
    tool_kinds: Vec<ToolKind>,
    commands: SyncSender<Command>,
    /// The tick thread, unparked when a tool state is queued (answers on arrival).
    tick_thread: std::thread::Thread,
    /// The thread making its frames (a frame worker's, or its own), unparked when it stops.
    frame_thread: std::thread::Thread,
    /// Signalled when its frame producer has ended and been dropped.
    frames_done: std::sync::Mutex<Receiver<()>>,
    /// Signalled when its answer dispatcher has delivered the last answer and closed the
    /// streams.
    answers_done: std::sync::Mutex<Receiver<()>>,
    router: Arc<answers::Router>,
    frames: watch::Sender<Arc<Frame>>,
    /// The rates viewers ask frames at.
    frame_demand: Arc<demand::FrameDemand>,
    geometry: Arc<SurfaceGeometry>,
    stats: Arc<TickStats>,
    stop: Arc<AtomicBool>,
    /// Where the tick loop comes back when it has ended ([`scheduler::Job`]).
    tick_done: std::sync::Mutex<Receiver<(Box<tick::TickLoop>, tick::Clock)>>,
    /// Whether the tick loop has ended.
    tick_finished: Arc<AtomicBool>,
    /// The frame thread and the tick thread of a session that has them of its own.
    threads: Vec<JoinHandle<()>>,
    epoch: Instant,
    config: SessionConfig,
    realtime: Option<RealtimeStatus>,
    cut: Option<Arc<vademecum_engine::pipeline::cutting::CutStatus>>,
    /// Its memory at start (a cut's part grows: [`Self::memory`]).
    memory: SessionMemory,
    /// Every frame of a deterministic session, for its recorder ([`Self::take_frame_log`]).
    frame_log: std::sync::Mutex<Option<Receiver<Arc<Frame>>>>,
    /// A device worker of its own: a haptic session with a channel per tool and no device
    /// workers given waits on all its bridges' events there, so that every hand is answered
    /// in its own tick. Last: dropped after the loop it ticked has come back.
    _own_devices: Option<Arc<DeviceWorkers>>,
}

/// What the tick thread receives.
#[derive(Debug)]
enum Command {
    Tool(ToolCommand),
}

/// What the tick thread plays itself (headless runs): one hand, or one per tool of the scene,
/// each answering into its own `answers`.
#[derive(Debug)]
pub struct Script {
    /// The hands, played in this order within each period (each answer is one pipeline
    /// tick, as each channel of a two-device session is). The script ends with the
    /// longest; a hand whose trajectory ended holds its last keyframe.
    pub hands: Vec<Hand>,
}

/// One scripted hand: a trajectory and the tool it moves.
#[derive(Debug)]
pub struct Hand {
    /// The scene tool it moves, by its index in `[[tools]]`; `None`: the session's one tool
    /// at a time, a probe or, with a blade, a scalpel (a grasper in a scene whose only tool
    /// is one) — as a client that names no tool.
    pub tool: Option<usize>,
    /// The trajectory, sampled at every tick.
    pub trajectory: Trajectory,
    /// Where every tick's answer goes (sequence number = tick).
    pub answers: tokio::sync::mpsc::Sender<Answer>,
}

impl Script {
    /// One hand, the session's one tool at a time.
    pub fn new(trajectory: Trajectory, answers: tokio::sync::mpsc::Sender<Answer>) -> Self {
        Self {
            hands: vec![Hand {
                tool: None,
                trajectory,
                answers,
            }],
        }
    }

    /// The script's length (s): its longest hand's.
    pub fn duration_s(&self) -> f64 {
        self.hands.iter().map(|h| h.trajectory.duration_s()).fold(0.0, f64::max)
    }
}

/// Whether a session of `scene` with `config` falls back to its reduced fidelity under load:
/// a live session whose server and scene allow it (a deterministic one never does).
fn falls_back(config: &SessionConfig, scene: &Scene) -> bool {
    config.fallback && !config.deterministic && scene.spec.fidelity.fallback == Fallback::Auto
}

/// What the frames show of a tearing session: its damage pictures on the torn organ's
/// surface, when the pipeline tears.
fn tear_view(
    pictures: Option<vademecum_engine::pipeline::TearPictures>,
    offline: Vec<Arc<vademecum_engine::damage::online::TearOffline>>,
    geometry: &SurfaceGeometry,
) -> Option<frames::TearView> {
    match (pictures, offline) {
        (Some(pictures), offline) if !offline.is_empty() => {
            let o = pictures.peek_output_buffer().organ;
            geometry
                .organs
                .get(o)
                .map(|surface| frames::TearView::new(pictures, offline, surface))
        }
        _ => None,
    }
}

/// What a session keeps of its pipeline before its tick loop takes it: what it reports (its
/// effects, their memory, its workspace, grasp sites and tools) and what its frames draw
/// (the cut's status, the damage pictures, the co-rotational deformation).
struct PipelineParts {
    effects: Vec<&'static str>,
    effects_memory: Vec<(&'static str, usize)>,
    tear_pictures: Option<vademecum_engine::pipeline::TearPictures>,
    tear_offline: Vec<Arc<vademecum_engine::damage::online::TearOffline>>,
    cut: Option<Arc<vademecum_engine::pipeline::cutting::CutStatus>>,
    corotational: Option<vademecum_engine::pipeline::corotational::CorotationalDeformation>,
    workspace: Bounds,
    grasp_sites: Vec<GraspSite>,
    tool_kinds: Vec<ToolKind>,
}

impl PipelineParts {
    /// Takes them from `pipeline` (the deformation set `deterministic` as the session is).
    fn take(pipeline: &mut Pipeline, deterministic: bool) -> Self {
        Self {
            effects: pipeline.effect_names(),
            effects_memory: pipeline.memory_bytes(),
            tear_pictures: pipeline.take_tear_pictures(),
            tear_offline: pipeline.tear_offline().to_vec(),
            cut: pipeline.cut_status(),
            corotational: pipeline.take_corotational().map(|mut c| {
                c.set_deterministic(deterministic);
                c
            }),
            workspace: pipeline.workspace(),
            grasp_sites: pipeline.grasp_sites().to_vec(),
            tool_kinds: [ToolKind::Probe, ToolKind::Scalpel, ToolKind::Grasper]
                .into_iter()
                .filter(|&k| pipeline.accepts(k))
                .collect(),
        }
    }
}

/// The engine's kind of a scene tool.
pub fn tool_kind(t: &ToolSpec) -> ToolKind {
    match t {
        ToolSpec::Probe { .. } => ToolKind::Probe,
        ToolSpec::Scalpel { .. } => ToolKind::Scalpel,
        ToolSpec::Grasper { .. } => ToolKind::Grasper,
    }
}

/// The tick thread's form of `script`: each hand's stream registered with `router` and the
/// state it sends resolved — a named tool's kind is the scene's; a scalpel needs a blade in
/// its trajectory, and a tool moves with one hand at most.
fn script_run(script: Script, scene: &Scene, router: &answers::Router) -> Result<tick::ScriptRun, SessionError> {
    let tools = &scene.spec.tools;
    let duration_s = script.duration_s();
    if script.hands.is_empty() {
        return Err(SessionError::Hand {
            hand: 0,
            why: "a script needs a hand".into(),
        });
    }
    let mut hands = Vec::with_capacity(script.hands.len());
    for (i, h) in script.hands.into_iter().enumerate() {
        let why = |why: String| SessionError::Hand { hand: i + 1, why };
        let kind = match h.tool {
            None => None,
            Some(t) if t >= tools.len().min(vademecum_engine::pipeline::MAX_TOOLS) => {
                return Err(why(format!("the scene has no tool {t} ({} tools)", tools.len())));
            }
            Some(t) => {
                let kind = tool_kind(&tools[t]);
                if kind == ToolKind::Scalpel && !h.trajectory.has_blade() {
                    return Err(why(format!("'{}' is a scalpel, but its trajectory has no blade", tools[t].name())));
                }
                if hands.iter().any(|o: &tick::ScriptHand| o.tool == Some(t)) {
                    return Err(why(format!("'{}' already has a hand", tools[t].name())));
                }
                Some(kind)
            }
        };
        hands.push(tick::ScriptHand {
            tool: h.tool,
            kind,
            to: router.register(h.answers).expect("a new router takes streams"),
            trajectory: h.trajectory,
        });
    }
    if hands.len() > 1 && hands.iter().any(|h| h.tool.is_none()) {
        return Err(SessionError::Hand {
            hand: hands.iter().position(|h| h.tool.is_none()).unwrap_or(0) + 1,
            why: "a script of several hands names the tool of each".into(),
        });
    }
    Ok(tick::ScriptRun { hands, duration_s })
}

impl Session {
    /// Starts a session on `scene` with one loaded bundle per organ.
    pub fn start(id: String, scene: Arc<Scene>, bundles: Vec<Arc<LoadedBundle>>, config: SessionConfig) -> Result<Self, SessionError> {
        Self::start_with(id, scene, bundles, config, None)
    }

    /// Starts a session whose tick thread plays `script` and stops at its end (headless
    /// runs); tool states can still be submitted.
    pub fn start_scripted(
        id: String,
        scene: Arc<Scene>,
        bundles: Vec<Arc<LoadedBundle>>,
        config: SessionConfig,
        script: Script,
    ) -> Result<Self, SessionError> {
        Self::start_with(id, scene, bundles, config, Some(script))
    }

    fn start_with(
        id: String,
        scene: Arc<Scene>,
        bundles: Vec<Arc<LoadedBundle>>,
        config: SessionConfig,
        script: Option<Script>,
    ) -> Result<Self, SessionError> {
        let mut pipeline = Pipeline::for_scene(&scene, &bundles)?;
        pipeline.set_deterministic(config.deterministic);
        let channels = match &config.haptic {
            Some(h) => tool_channels(&h.channel, &scene)?,
            None => Vec::new(),
        };
        let PipelineParts {
            effects,
            effects_memory,
            tear_pictures,
            tear_offline,
            cut,
            corotational,
            workspace,
            grasp_sites,
            tool_kinds,
        } = PipelineParts::take(&mut pipeline, config.deterministic);
        let geometry = Arc::new(SurfaceGeometry::of(&scene, &bundles));
        let (commands, rx) = mpsc::sync_channel(config.queue.max(1));
        let stats = Arc::new(TickStats::default());
        // every answer of a tick and of the queue behind it fits in the ring
        let ring = Arc::new(answers::AnswerRing::new(
            config.queue.max(1) + MAX_COMMANDS_PER_TICK + 1,
            stats.clone(),
        ));
        let memory = SessionMemory::of(
            &effects_memory,
            config.queue.max(1),
            ring.capacity(),
            stats.histogram_bytes(),
            &geometry,
        );
        let router = Arc::new(answers::Router::new());
        let named_hands = script.as_ref().is_some_and(|s| s.hands.iter().any(|h| h.tool.is_some()));
        let script = script.map(|s| script_run(s, &scene, &router)).transpose()?;
        let answers_done = Self::start_answers(&id, &config, &ring, &router)?;
        let (latest_in, latest_out) = triple_buffer::triple_buffer(&tick::Latest::default());
        let (frames, _) = watch::channel(Arc::new(Frame::rest(&geometry)));
        let stop = Arc::new(AtomicBool::new(false));
        let epoch = Instant::now();
        let tick_loop = Box::new(tick::TickLoop {
            pipeline,
            commands: rx,
            answers: ring.clone(),
            stats: stats.clone(),
            latest: latest_in,
            stop: stop.clone(),
            period: config.period,
            epoch,
            script,
            owed: [0; vademecum_engine::pipeline::MAX_TOOLS],
            steps: 0,
            peer: None,
            others: Vec::new(),
            governor: fidelity::Governor::new(config.period, falls_back(&config, &scene)),
            lockstep: None,
            deterministic: config.deterministic,
            held: Default::default(),
            tool_states: Default::default(),
            // a channel per tool, or a scripted hand per tool: frames list every tool
            named: channels.len() > 1 || named_hands,
        });
        let (done, tick_done) = mpsc::sync_channel(1);
        let tick_finished = Arc::new(AtomicBool::new(false));
        let mut job = scheduler::Job {
            tick: tick_loop,
            clock: tick::Clock::default(),
            done,
            finished: tick_finished.clone(),
            phase: None,
        };
        let tear = tear_view(tear_pictures, tear_offline, &geometry);
        let frame_demand = Arc::new(demand::FrameDemand::default());
        let producer = frames::FrameProducer::new(
            bundles.clone(),
            geometry.clone(),
            latest_out,
            frames.clone(),
            stats.clone(),
            stop.clone(),
            config.frame_rate_hz,
            cut.clone(),
            tear,
        )
        .with_demand(frame_demand.clone());
        let own_frame_thread = corotational.is_some() || config.framing.is_none();
        let producer = match corotational {
            Some(c) => producer.with_corotational(c),
            None => producer,
        };
        let (frames_done_tx, frames_done) = mpsc::sync_channel(1);
        let frame_job = frames::FrameJob {
            producer,
            done: frames_done_tx,
        };
        let mut threads = Vec::with_capacity(2);
        let (frame_thread, frame_log) = match Self::place_frames(&id, frame_job, &config, own_frame_thread, &mut job, &mut threads) {
            Ok(placed) => placed,
            Err(e) => {
                job.end(); // closes its answers: the dispatcher ends
                let _ = answers_done.recv();
                return Err(e);
            }
        };
        let abandon = |threads: &mut Vec<JoinHandle<()>>| {
            stop.store(true, Ordering::Relaxed);
            frame_thread.unpark();
            let _ = frames_done.recv();
            // the tick job was ended, its answers closed
            let _ = answers_done.recv();
            threads.drain(..).for_each(|t| drop(t.join()));
        };
        let (tick_thread, realtime, own_devices) = match Self::place_tick(&id, job, &config, &channels, &mut threads) {
            Ok(placed) => placed,
            Err(e) => {
                abandon(&mut threads);
                return Err(e);
            }
        };
        Ok(Self {
            id,
            scene,
            bundles,
            effects,
            workspace,
            grasp_sites,
            tool_kinds,
            commands,
            tick_thread,
            frame_thread,
            frames_done: std::sync::Mutex::new(frames_done),
            answers_done: std::sync::Mutex::new(answers_done),
            router,
            frames,
            frame_demand,
            geometry,
            stats,
            stop,
            tick_done: std::sync::Mutex::new(tick_done),
            tick_finished,
            threads,
            epoch,
            config,
            realtime,
            cut,
            memory,
            frame_log: std::sync::Mutex::new(frame_log),
            _own_devices: own_devices,
        })
    }

    /// Starts the answer dispatcher of a session on an answer worker, or a thread of its own:
    /// it takes the tick's answers from `ring` to the streams of `router`; returns what it
    /// signals when it has delivered the last answer and closed the streams.
    fn start_answers(
        id: &str,
        config: &SessionConfig,
        ring: &Arc<answers::AnswerRing>,
        router: &Arc<answers::Router>,
    ) -> Result<Receiver<()>, SessionError> {
        let (done, answers_done) = mpsc::sync_channel(1);
        let dispatcher = answers::Dispatcher {
            ring: ring.clone(),
            router: router.clone(),
            done,
        };
        match &config.answering {
            Some(workers) => workers.place(dispatcher)?,
            None => dispatcher.spawn(format!("answers-{id}")),
        }
        Ok(answers_done)
    }

    /// Places the frame thread of a session: a lockstep thread of its own for a deterministic
    /// one (the tick `job` waits for it; its frames logged, returned), a frame worker's, or a
    /// thread of its own (`own`: a co-rotational deformation's frames are too heavy to share a
    /// worker). When a worker refuses, the caller ends the tick `job`.
    fn place_frames(
        id: &str,
        frame_job: frames::FrameJob,
        config: &SessionConfig,
        own: bool,
        job: &mut scheduler::Job,
        threads: &mut Vec<JoinHandle<()>>,
    ) -> Result<(std::thread::Thread, Option<Receiver<Arc<Frame>>>), SessionError> {
        match &config.framing {
            _ if config.deterministic => {
                let (t, lockstep, log) = frames::spawn_lockstep(id, frame_job, config.frame_rate_hz, config.period);
                job.tick.lockstep = Some(lockstep);
                let thread = t.thread().clone();
                threads.push(t);
                Ok((thread, Some(log)))
            }
            Some(workers) if !own => Ok((workers.place(frame_job)?, None)),
            _ => {
                let t = std::thread::Builder::new()
                    .name(format!("frames-{id}"))
                    .spawn(move || workers::run_alone(frame_job))
                    .expect("the OS can start a thread");
                let thread = t.thread().clone();
                threads.push(t);
                Ok((thread, None))
            }
        }
    }

    /// Places the tick loop of a session: a device worker's for a haptic session that waits on
    /// events (its channel opened here: opening takes milliseconds), a tick worker's, or a
    /// thread of its own ([`Self::spawn_tick_thread`]); with what the OS granted a device
    /// session's thread. On failure the job has ended; the caller abandons the frame thread.
    fn place_tick(
        id: &str,
        mut job: scheduler::Job,
        config: &SessionConfig,
        channels: &[(usize, HapticChannel)],
        threads: &mut Vec<JoinHandle<()>>,
    ) -> Result<(std::thread::Thread, Option<RealtimeStatus>, Option<Arc<DeviceWorkers>>), SessionError> {
        // several hands and no device workers: one of its own (the event wait on every bridge)
        let own = match (&config.haptic, config.on_tick_thread, &config.devices) {
            (Some(h), None, None) if channels.len() > 1 => match DeviceWorkers::new(DeviceWorkersConfig {
                workers: 1,
                fifo_priority: h.fifo_priority,
                on_start: None,
            }) {
                Ok(w) => Some(Arc::new(w)),
                Err(_) => {
                    // no thread could be started
                    job.end();
                    return Err(SessionError::Ticking(PlaceError::Stopped));
                }
            },
            _ => None,
        };
        let devices = own.as_ref().or(config.devices.as_ref());
        match (&config.ticking, &config.haptic, config.on_tick_thread, devices) {
            (_, Some(h), None, Some(devices)) if own.is_some() || h.wait == WaitStrategy::Event => {
                match open_channels(channels, WaitStrategy::Event, h.spin_window, config.period) {
                    Ok((peer, others)) => {
                        job.tick.peer = Some(peer);
                        job.tick.others = others;
                    }
                    Err(e) => {
                        job.end();
                        return Err(e);
                    }
                }
                let (thread, realtime) = devices.place(job)?;
                Ok((thread, Some(realtime), own))
            }
            (Some(workers), None, None, _) => Ok((workers.place(job)?, None, None)),
            _ => {
                let (thread, realtime) = Self::spawn_tick_thread(id, job, config, channels.to_vec())?;
                let t = thread.thread().clone();
                threads.push(thread);
                Ok((t, realtime, None))
            }
        }
    }

    /// Every frame of a deterministic session ([`SessionConfig::deterministic`]), in order, for
    /// its recorder: taken once (`None` after, and for a live session). The recorder must
    /// read it: the frame thread, and the tick with it, wait when [`frames::FRAME_LOG`] frames
    /// are unread. It ends when the session's frame thread has ended.
    pub fn take_frame_log(&self) -> Option<Receiver<Arc<Frame>>> {
        self.frame_log.lock().unwrap_or_else(|p| p.into_inner()).take()
    }

    /// A thread of the session's own for its tick loop: a haptic session's (it opens the
    /// haptic channel's ports, which belong to the thread that uses them, and says whether it
    /// could — what the OS granted it), or a worker of its own ([`workers::run_alone`]).
    fn spawn_tick_thread(
        id: &str,
        job: scheduler::Job,
        config: &SessionConfig,
        channels: Vec<(usize, HapticChannel)>,
    ) -> Result<(JoinHandle<()>, Option<RealtimeStatus>), SessionError> {
        let haptic = config.haptic.clone();
        let on_tick_thread = config.on_tick_thread;
        let (opened_tx, opened_rx) = mpsc::sync_channel::<Result<Option<RealtimeStatus>, SessionError>>(1);
        let thread = std::thread::Builder::new()
            .name(format!("tick-{id}"))
            .spawn(move || {
                if let Some(init) = on_tick_thread {
                    init();
                }
                let Some(h) = haptic else {
                    let _ = opened_tx.send(Ok(None));
                    return workers::run_alone(job);
                };
                let mut job = job;
                match open_channels(&channels, h.wait, h.spin_window, job.tick.period) {
                    Ok((p, others)) => {
                        job.tick.others = others;
                        let mut peer = p.with_phase_source(h.phase);
                        let fifo = h.fifo_priority.filter(|_| h.wait != WaitStrategy::Spin);
                        let _ = opened_tx.send(Ok(Some(vademecum_bridge::timing::request_realtime(fifo, h.cpu))));
                        job.tick.run_haptic(&mut job.clock, &mut peer);
                        job.end();
                    }
                    Err(e) => {
                        job.end();
                        let _ = opened_tx.send(Err(e));
                    }
                }
            })
            .expect("the OS can start a thread");
        match opened_rx.recv() {
            Ok(Ok(rt)) => Ok((thread, rt)),
            Ok(Err(e)) => {
                let _ = thread.join();
                Err(e)
            }
            Err(_) => panic!("the tick thread ended before opening its haptic channel"),
        }
    }

    /// The session id.
    pub fn id(&self) -> &str {
        &self.id
    }

    /// The scene.
    pub fn scene(&self) -> &Arc<Scene> {
        &self.scene
    }

    /// The loaded bundles, one per organ.
    pub fn bundles(&self) -> &[Arc<LoadedBundle>] {
        &self.bundles
    }

    /// Where tool positions are accepted (the organs' box grown by a margin).
    pub fn workspace(&self) -> Bounds {
        self.workspace
    }

    /// Where the grasper takes hold and which way it pulls (tearing scenes; the scene's
    /// grasp first).
    pub fn grasp_sites(&self) -> &[GraspSite] {
        &self.grasp_sites
    }

    /// The tool kinds the pipeline simulates; a state of another kind is answered with zero
    /// force and `REJECTED_INPUT` (the gRPC service refuses it first).
    pub fn accepts(&self, kind: ToolKind) -> bool {
        self.tool_kinds.contains(&kind)
    }

    /// The effects of the tick pipeline, in order.
    pub fn effects(&self) -> &[&'static str] {
        &self.effects
    }

    /// What the cut thread has done (cutting scenes).
    pub fn cut_status(&self) -> Option<&Arc<vademecum_engine::pipeline::cutting::CutStatus>> {
        self.cut.as_ref()
    }

    /// The configuration it runs with.
    pub fn config(&self) -> &SessionConfig {
        &self.config
    }

    /// What the OS granted the tick thread of a haptic session (`None` without a channel).
    pub fn realtime(&self) -> Option<&RealtimeStatus> {
        self.realtime.as_ref()
    }

    /// When the session started (the origin of its timestamps).
    pub fn epoch(&self) -> Instant {
        self.epoch
    }

    /// The reference surface of every organ (what viewers receive first).
    pub fn geometry(&self) -> &Arc<SurfaceGeometry> {
        &self.geometry
    }

    /// Opens a stream of answers holding up to `capacity` undelivered answers (beyond that a
    /// stream that does not read loses answers, counted): put its [`AnswerStream::id`] in
    /// every [`ToolCommand`] whose answer it should receive.
    pub fn open_answers(&self, capacity: usize) -> Result<AnswerStream, SubmitError> {
        AnswerStream::open(&self.router, capacity)
    }

    /// Queues a tool state and wakes the tick thread, which answers it at once (a haptic
    /// session's at its next wake-up: the bridge's next state or its deadline); refuses at
    /// once when the queue is full.
    pub fn submit(&self, cmd: ToolCommand) -> Result<(), SubmitError> {
        match self.commands.try_send(Command::Tool(cmd)) {
            Ok(()) => {
                self.tick_thread.unpark();
                Ok(())
            }
            Err(TrySendError::Full(_)) => Err(SubmitError::Busy),
            Err(TrySendError::Disconnected(_)) => Err(SubmitError::Closed),
        }
    }

    /// A receiver of the latest frames, made at the session's frame rate (or at the rate
    /// of the fastest viewer that said its rate: [`Self::subscribe_frames_at`]).
    pub fn subscribe_frames(&self) -> watch::Receiver<Arc<Frame>> {
        self.frames.subscribe()
    }

    /// A receiver of the latest frames for a viewer at `rate_hz`: frames are made at the
    /// fastest such viewer's rate (at most the session's) while the guard lives.
    pub fn subscribe_frames_at(&self, rate_hz: f64) -> (watch::Receiver<Arc<Frame>>, demand::DemandGuard) {
        (self.frames.subscribe(), self.frame_demand.ask(rate_hz))
    }

    /// The memory the session holds of its own, by part ([`memory`]): the bundles it shares
    /// are not counted.
    pub fn memory(&self) -> SessionMemory {
        let mut m = self.memory.clone();
        if let Some(c) = &self.cut {
            let bytes = c.memory_bytes.load(Ordering::Relaxed);
            if bytes > 0 {
                m.set("effect:cutting", bytes);
            }
        }
        m
    }

    /// Live statistics.
    pub fn stats(&self) -> &Arc<TickStats> {
        &self.stats
    }

    /// Whether the tick loop has stopped (a script ended, or the session was closed).
    pub fn finished(&self) -> bool {
        self.tick_finished.load(Ordering::Acquire)
    }

    /// Asks the threads to stop (the tick thread finishes its current tick) without waiting
    /// for them; they are joined when the session is dropped or closed.
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
        self.tick_thread.unpark();
        self.frame_thread.unpark();
    }

    /// Stops the threads (the tick thread finishes its current tick), joins them and returns
    /// the final statistics.
    pub fn close(mut self) -> StatsSnapshot {
        self.shutdown();
        self.stats.snapshot()
    }

    /// Waits for a scripted session's tick thread to reach the end of its script, then
    /// closes it.
    pub fn wait(mut self) -> StatsSnapshot {
        self.await_tick_loop();
        self.shutdown();
        self.stats.snapshot()
    }

    /// Blocks until the tick loop has ended and come back, then hands its last recordings
    /// over to the statistics (here, never on a worker) and drops it.
    fn await_tick_loop(&mut self) {
        if let Ok(done) = self.tick_done.get_mut()
            // Err: it came back already, or its worker is gone
            && let Ok((tick, clock)) = done.recv()
        {
            tick.hand_over(&clock);
        }
    }

    fn shutdown(&mut self) {
        self.stop();
        self.await_tick_loop();
        for done in [&mut self.frames_done, &mut self.answers_done] {
            if let Ok(done) = done.get_mut() {
                // Err: it ended already
                let _ = done.recv();
            }
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        self.shutdown();
    }
}
