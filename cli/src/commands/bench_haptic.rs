//! `vademecum bench haptic`: the 1 kHz haptic path on this machine, each figure beside a null
//! loop measured in the same run, idle or with a CPU hog, so the OS floor and our overhead
//! are told apart.
//!
//! Three phases of `--seconds` each (four with `--two-hands`), all driven by the device bridge's own loop
//! ([`vademecum_bridge::bridge_loop`]) with the same wait strategy:
//!
//! 1. **null** — the same timing loop with no IPC and no work (a fixed device, a link that
//!    answers at once);
//! 2. **round trip** — the bridge against an echo peer over iceoryx2 shared memory: the peer
//!    waits for each state like a session does ([`vademecum_bridge::peer`]) and answers at once
//!    with zero force;
//! 3. **full tick** — the bridge's simulated stylus palpating the built-in organ against a
//!    real session (contact search, force from the vademecum, answer);
//! 4. **two hands** (`--two-hands`) — two bridges, each on its tool's channel of one session
//!    on the organ with a second probe (which waits on both bridges' events on a device
//!    worker of its own): each bridge's figures.
//!
//! For each: device read → force written (our IPC and work), deadline → force written (the
//! OS floor plus ours: the figure compared with the null loop), deadline misses, and the CPU
//! spent by the bridge's and the peer's threads. `--hog N` runs N threads of floating-point
//! busy work for the whole run (null phase included); `--cotenant` runs real processes beside
//! it (this executable's `solve` and `build`, restarted as they finish).
//!
//! The round-trip and full-tick phases are traced tick by tick (the bridge's timestamps and
//! the server's wait times the answers carry) and their late ticks sorted by cause
//! ([`vademecum_bridge::tail`]); `--trace DIR` writes the traces (the null loop's too). `--repeat N` runs the three
//! phases N times and summarises the median and spread over the runs and how many runs meet
//! the haptic goal (full tick deadline→write p99 within 50 µs of the null loop's, read→write
//! p99 ≤ 100 µs, misses within the null loop's + 0.1 %).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use serde::Serialize;
use vademecum_bridge::bridge_loop::{self, BridgeOutcome, BridgeParams};
use vademecum_bridge::device::NullDevice;
use vademecum_bridge::device::sim::{HandModel, SimStylus};
use vademecum_bridge::link::{Link, NullLink, ShmLink};
use vademecum_bridge::peer::HapticPeer;
use vademecum_bridge::tail::{self, TailCauses};
use vademecum_bridge::timing::{self, WaitStrategy};
use vademecum_bridge::trajectory::Trajectory;
use vademecum_engine::scene::Scene;
use vademecum_proto::shm::{self, HapticChannel};

use crate::cli::BenchHapticArgs;
use crate::commands::build::ensure_bundles;
use vademecum_server::session::stats::Percentiles;
use vademecum_server::session::{HapticConfig, Session, SessionConfig, builtin_palpation};

#[derive(Debug, Serialize)]
struct Phase {
    phase: &'static str,
    /// Late ticks by cause (phases with IPC).
    tail: Option<TailCauses>,
    /// Ticks on which the bridge woke later than the spin window after its deadline.
    late_wakeups: u64,
    /// vCPU steal during the phase (% of the machine's CPU time), where reported.
    steal_percent: Option<f64>,
    ticks: u64,
    read_to_write_us: Percentiles,
    deadline_to_write_us: Percentiles,
    deadline_misses: u64,
    miss_percent: f64,
    fresh_percent: f64,
    bridge_cpu_percent: f64,
    peer_cpu_percent: f64,
}

#[derive(Debug, Serialize)]
struct Report {
    wait: String,
    peer_wait: String,
    peer_phase: String,
    hog_threads: usize,
    cotenants: bool,
    seconds: f64,
    bridge_scheduling: String,
    phases: Vec<Phase>,
}

fn phase(name: &'static str, o: &BridgeOutcome, peer_cpu: Duration, p: &BridgeParams) -> Phase {
    let wall = o.wall.as_secs_f64().max(1e-9);
    let r = &o.report;
    Phase {
        phase: name,
        tail: (name != "null loop" && !o.trace.is_empty()).then(|| {
            tail::classify(
                &o.trace,
                &o.late_answers,
                p.answer_wait.as_nanos() as u64,
                p.window.as_nanos() as u64,
            )
        }),
        late_wakeups: o.trace.iter().filter(|t| t.lateness_ns > p.window.as_nanos() as u64).count() as u64,
        steal_percent: o.steal_percent(std::thread::available_parallelism().map_or(1, |n| n.get())),
        ticks: r.ticks,
        read_to_write_us: Percentiles::of(&o.latency_ns),
        deadline_to_write_us: Percentiles::of(&o.completion_ns),
        deadline_misses: r.deadline_misses,
        miss_percent: 100.0 * r.deadline_misses as f64 / r.ticks.max(1) as f64,
        fresh_percent: 100.0 * r.fresh_forces as f64 / r.ticks.max(1) as f64,
        bridge_cpu_percent: 100.0 * o.cpu.as_secs_f64() / wall,
        peer_cpu_percent: 100.0 * peer_cpu.as_secs_f64() / wall,
    }
}

/// Runs the bridge loop on a thread of its own (asking for the scheduling the bridge binary
/// asks for), with the device and link made on that thread.
fn bridge_thread<D, L>(
    params: BridgeParams,
    fifo: Option<i32>,
    cpu: Option<usize>,
    make: impl FnOnce() -> anyhow::Result<(D, L)> + Send + 'static,
) -> anyhow::Result<(BridgeOutcome, String)>
where
    D: vademecum_bridge::device::Device,
    L: Link,
{
    spawn_bridge(params, fifo, cpu, make)?
        .join()
        .map_err(|_| anyhow::anyhow!("the bridge thread panicked"))?
}

/// [`bridge_thread`], not waited for.
fn spawn_bridge<D, L>(
    params: BridgeParams,
    fifo: Option<i32>,
    cpu: Option<usize>,
    make: impl FnOnce() -> anyhow::Result<(D, L)> + Send + 'static,
) -> anyhow::Result<std::thread::JoinHandle<anyhow::Result<(BridgeOutcome, String)>>>
where
    D: vademecum_bridge::device::Device,
    L: Link,
{
    std::thread::Builder::new()
        .name("bench-bridge".into())
        .spawn(move || -> anyhow::Result<(BridgeOutcome, String)> {
            let rt = timing::request_realtime(fifo, cpu).to_string();
            let (mut device, mut link) = make()?;
            let stop = Arc::new(AtomicBool::new(false));
            let out = bridge_loop::run(&mut device, &mut link, &params, &stop)?;
            let rt = format!("{rt}, {}", out.safeguards());
            Ok((out, rt))
        })
        .context("cannot start the bridge thread")
}

/// Busy floating-point work until `stop`.
pub(super) fn hog(stop: Arc<AtomicBool>) {
    let mut x = 1.000_001f64;
    while !stop.load(Ordering::Relaxed) {
        for _ in 0..10_000 {
            x = (x * 1.000_000_1).sqrt() + 1e-9;
        }
        std::hint::black_box(x);
    }
}

/// Real processes beside the benchmark: this executable's `solve` and `build` of the built-in
/// organ, each restarted when it finishes, until dropped.
struct Cotenants {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
    _dir: tempfile::TempDir,
}

impl Cotenants {
    fn start() -> anyhow::Result<Self> {
        let exe = std::env::current_exe().context("cannot find this executable to run co-tenants")?;
        let dir = tempfile::tempdir()?;
        let stop = Arc::new(AtomicBool::new(false));
        // `solve` and `build` of the built-in organ, each writing into the temporary folder
        let jobs = ["solve", "build"].map(|cmd| [cmd.to_string(), "--out".into(), dir.path().join(cmd).display().to_string()]);
        let threads = jobs
            .into_iter()
            .map(|args| {
                let (exe, stop) = (exe.clone(), stop.clone());
                std::thread::spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        let child = std::process::Command::new(&exe)
                            .args(&args)
                            .stdout(std::process::Stdio::null())
                            .stderr(std::process::Stdio::null())
                            .spawn();
                        let Ok(mut child) = child else { return };
                        // poll so that a stop does not wait for a long build
                        loop {
                            if stop.load(Ordering::Relaxed) {
                                let _ = child.kill();
                                let _ = child.wait();
                                return;
                            }
                            if let Ok(Some(_)) = child.try_wait() {
                                break;
                            }
                            std::thread::sleep(Duration::from_millis(50));
                        }
                    }
                })
            })
            .collect();
        Ok(Self { stop, threads, _dir: dir })
    }
}

impl Drop for Cotenants {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// What one run of the three phases needs.
struct Setup {
    scene: Arc<Scene>,
    bundles: Vec<Arc<vademecum_engine::bundle::LoadedBundle>>,
    hand: Trajectory,
    /// `--two-hands`: the organ with a second probe, `left`, its bundles, and the left hand's
    /// path (the right's, 15 mm aside).
    two_hands: Option<(Arc<Scene>, Vec<Arc<vademecum_engine::bundle::LoadedBundle>>, Trajectory)>,
}

/// The built-in organ with a second probe, `left`, like the first (two hands).
fn two_probe_organ() -> anyhow::Result<Scene> {
    let text = format!(
        "{}\n[[tools]]\nkind = \"probe\"\nname = \"left\"\nradius = {}\n",
        vademecum_engine::scene::builtin("organ").context("the built-in organ")?,
        vademecum_engine::offline::probe_radius(&Scene::builtin("organ")?)
    );
    Ok(Scene::from_toml(&text, "organ_two_hands.toml")?)
}

pub fn run(a: BenchHapticArgs) -> anyhow::Result<ExitCode> {
    if !(a.seconds > 0.0 && a.seconds <= 600.0) {
        bail!("--seconds must lie in (0, 600], got {}", a.seconds);
    }
    if !(1..=100).contains(&a.repeat) {
        bail!("--repeat must lie in 1..=100, got {}", a.repeat);
    }
    shm::quiet_iceoryx2_logging();
    let scene = Arc::new(Scene::builtin("organ")?);
    let dir = a.bundles.clone().unwrap_or_else(|| PathBuf::from("out/organ"));
    let bundles = ensure_bundles(&scene, &dir)?;
    let radius = vademecum_engine::offline::probe_radius(&scene);
    let once = builtin_palpation(&bundles[0], radius, 0.004, 0.015).map_err(anyhow::Error::msg)?;
    // the palpation, repeated to cover the phase
    let reps = (a.seconds / 5.0).ceil() as usize + 1;
    let mut keys = Vec::new();
    for r in 0..reps {
        for i in (0..=50).filter(|&i| r == 0 || i > 0) {
            let t = i as f64 * 0.1;
            let s = once.at(t);
            keys.push((t + 5.0 * r as f64, s.position_m, s.closure));
        }
    }
    let two_hands = match a.two_hands {
        false => None,
        true => {
            let scene = two_probe_organ()?;
            let bundles = ensure_bundles(&scene, &dir.join("two_hands"))?;
            // the left hand palpates 15 mm aside of the right, along the same path
            let aside: Vec<(f64, [f64; 3], f64)> = keys.iter().map(|&(t, p, c)| (t, [p[0] + 0.015, p[1], p[2]], c)).collect();
            Some((Arc::new(scene), bundles, Trajectory::new(aside).map_err(anyhow::Error::msg)?))
        }
    };
    let setup = Setup {
        scene,
        bundles,
        hand: Trajectory::new(keys).map_err(anyhow::Error::msg)?,
        two_hands,
    };
    if let Some(d) = &a.trace {
        std::fs::create_dir_all(d).with_context(|| format!("cannot create {}", d.display()))?;
    }
    let hog_stop = Arc::new(AtomicBool::new(false));
    let hogs: Vec<_> = (0..a.hog)
        .map(|_| {
            let s = hog_stop.clone();
            std::thread::spawn(move || hog(s))
        })
        .collect();
    let cotenants = if a.cotenant { Some(Cotenants::start()?) } else { None };
    if cotenants.is_some() {
        // let the co-tenants get going (a build starts with a mesh and an assembly)
        std::thread::sleep(Duration::from_secs(2));
    }
    let mut runs = Vec::with_capacity(a.repeat);
    let mut failure = None;
    for k in 0..a.repeat {
        match run_once(&a, k, &setup) {
            Ok(r) => runs.push(r),
            Err(e) => {
                failure = Some(e);
                break;
            }
        }
    }
    drop(cotenants);
    hog_stop.store(true, Ordering::Relaxed);
    for h in hogs {
        let _ = h.join();
    }
    if let Some(e) = failure {
        return Err(e);
    }
    let summary = (runs.len() > 1).then(|| Summary::of(&runs));
    let mut out = std::io::stdout().lock();
    if a.json {
        let all = serde_json::json!({ "runs": runs, "summary": summary });
        writeln!(out, "{}", serde_json::to_string_pretty(&all)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    for (k, report) in runs.iter().enumerate() {
        print_report(&mut out, k, a.repeat, a.cotenant, report)?;
    }
    if let Some(s) = summary {
        print_summary(&mut out, &s)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// One run of the three phases.
fn run_once(a: &BenchHapticArgs, k: usize, setup: &Setup) -> anyhow::Result<Report> {
    let period = Duration::from_millis(1);
    let params = BridgeParams {
        strategy: a.wait,
        window: Duration::from_micros(a.spin_window_us),
        duration: Some(Duration::from_secs_f64(a.seconds)),
        trace_limit: 0,
        hold_wake_latency: a.wake_latency,
        ..BridgeParams::default()
    };
    // every phase is traced whole (sized before the loop starts)
    let traced = BridgeParams {
        trace_limit: (a.seconds * 1000.0).ceil() as usize + 16,
        ..params.clone()
    };
    let fifo = (a.realtime && a.wait != WaitStrategy::Spin).then_some(80);
    // the bridge on the last CPU, the peer on the one before (when pinning and there are two)
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let (bridge_cpu, peer_cpu) = if a.pin && cpus >= 2 {
        (Some(cpus - 1), Some(cpus - 2))
    } else {
        (None, None)
    };
    let bar = |what: &str| {
        eprintln!(
            "vademecum: bench haptic: run {}/{}: {what} ({} s, {} wait, {} hog threads{})",
            k + 1,
            a.repeat,
            a.seconds,
            a.wait,
            a.hog,
            if a.cotenant { ", co-tenants" } else { "" }
        )
    };
    let write_trace = |phase: &str, o: &BridgeOutcome| -> anyhow::Result<()> {
        if let Some(d) = &a.trace {
            let path = d.join(format!("run{}_{phase}.csv", k + 1));
            vademecum_bridge::bridge_loop::write_trace(&path, &o.trace).with_context(|| format!("cannot write {}", path.display()))?;
        }
        Ok(())
    };
    let mut phases = Vec::new();

    bar("null loop");
    let (null, rt) = bridge_thread(params.clone(), fifo, bridge_cpu, || {
        Ok((NullDevice::default(), NullLink::default()))
    })?;
    phases.push(phase("null loop", &null, Duration::ZERO, &params));

    bar("iceoryx2 round trip (echo peer)");
    let channel = HapticChannel::new(&format!("bench-echo-{}-{k}", std::process::id()))?;
    let echo_stop = Arc::new(AtomicBool::new(false));
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let echo = {
        let (channel, stop, peer_wait, window, phase) = (channel.clone(), echo_stop.clone(), a.peer_wait, params.window, a.peer_phase);
        std::thread::Builder::new()
            .name("bench-echo".into())
            .spawn(move || -> anyhow::Result<Duration> {
                let mut peer = HapticPeer::open(&channel, peer_wait, window, period)?.with_phase_source(phase);
                timing::request_realtime(fifo.map(|p| p - 10).filter(|_| peer_wait != WaitStrategy::Spin), peer_cpu);
                let _ = ready_tx.send(());
                let cpu0 = timing::thread_cpu_time();
                let mut next = Instant::now() + period;
                while !stop.load(Ordering::Relaxed) {
                    // the session's schedule (session/tick.rs)
                    let got = peer.wait_for_state(next);
                    let woke = Instant::now();
                    if let Some(s) = &got {
                        let _ = peer.answer(s, [0.0; 3], 0.0, 0);
                    }
                    next = peer.next_deadline(next, woke, got.is_some());
                }
                Ok(timing::thread_cpu_time().saturating_sub(cpu0))
            })?
    };
    ready_rx
        .recv()
        .map_err(|_| anyhow::anyhow!("the echo peer could not open its channel"))?;
    let echo_channel = channel.clone();
    let (rtt, _) = bridge_thread(traced.clone(), fifo, bridge_cpu, move || {
        Ok((NullDevice::default(), ShmLink::open(&echo_channel)?))
    })?;
    echo_stop.store(true, Ordering::Relaxed);
    let echo_cpu = echo.join().map_err(|_| anyhow::anyhow!("the echo peer panicked"))??;
    write_trace("round_trip", &rtt)?;
    phases.push(phase("iceoryx2 round trip", &rtt, echo_cpu, &params));

    bar("full tick (session on the built-in organ)");
    let channel = HapticChannel::new(&format!("bench-full-{}-{k}", std::process::id()))?;
    let mut haptic = HapticConfig::new(channel.clone());
    haptic.wait = a.peer_wait;
    haptic.spin_window = params.window;
    haptic.fifo_priority = fifo.map(|p| p - 10);
    haptic.cpu = peer_cpu;
    haptic.phase = a.peer_phase;
    let session = Session::start(
        "bench".into(),
        setup.scene.clone(),
        setup.bundles.clone(),
        SessionConfig {
            haptic: Some(haptic),
            ..SessionConfig::default()
        },
    )?;
    let cpu0 = session.stats().tick_cpu_ns.load(Ordering::Relaxed);
    let hand = setup.hand.clone();
    // two bridges share the machine's cores with the session: each blocks on the server's
    // `answered` event instead of polling for its answer, as docs/haptic.md advises when
    // bridges share a host's cores (two polling bridges at a higher real-time priority than
    // the session starve it on two cores)
    let traced_hands = BridgeParams {
        answer_wake: bridge_loop::AnswerWake::Event,
        ..traced.clone()
    };
    let (full, _) = bridge_thread(traced, fifo, bridge_cpu, move || {
        Ok((SimStylus::new(hand, HandModel::default()), ShmLink::open(&channel)?))
    })?;
    let tick_cpu = Duration::from_nanos(session.stats().tick_cpu_ns.load(Ordering::Relaxed).saturating_sub(cpu0));
    let _ = session.close();
    write_trace("full_tick", &full)?;
    phases.push(phase("full tick", &full, tick_cpu, &params));

    if let Some((scene, bundles, left_hand)) = &setup.two_hands {
        // the session waits on both bridges' events (a device worker of its own)
        bar("two hands (two bridges, a session with two probes)");
        let channel = HapticChannel::new(&format!("bench-hands-{}-{k}", std::process::id()))?;
        let mut haptic = HapticConfig::new(channel.clone());
        haptic.spin_window = params.window;
        haptic.fifo_priority = fifo.map(|p| p - 10);
        haptic.cpu = peer_cpu;
        let session = Session::start(
            "bench-hands".into(),
            scene.clone(),
            bundles.clone(),
            SessionConfig {
                haptic: Some(haptic),
                ..SessionConfig::default()
            },
        )?;
        let cpu0 = session.stats().tick_cpu_ns.load(Ordering::Relaxed);
        let hand = |path: &Trajectory, tool: &str| -> anyhow::Result<_> {
            let (path, ch) = (path.clone(), channel.for_tool(tool)?);
            spawn_bridge(traced_hands.clone(), fifo, bridge_cpu, move || {
                Ok((SimStylus::new(path, HandModel::default()), ShmLink::open(&ch)?))
            })
        };
        let (right, left) = (hand(&setup.hand, "probe")?, hand(left_hand, "left")?);
        let join = |h: std::thread::JoinHandle<anyhow::Result<(BridgeOutcome, String)>>| {
            h.join().map_err(|_| anyhow::anyhow!("a bridge thread panicked"))?
        };
        let ((right, _), (left, _)) = (join(right)?, join(left)?);
        let tick_cpu = Duration::from_nanos(session.stats().tick_cpu_ns.load(Ordering::Relaxed).saturating_sub(cpu0));
        let _ = session.close();
        write_trace("two_hands_first", &right)?;
        write_trace("two_hands_second", &left)?;
        phases.push(phase("two hands: first tool", &right, tick_cpu, &params));
        phases.push(phase("two hands: second tool", &left, Duration::ZERO, &params));
    }

    Ok(Report {
        wait: a.wait.to_string(),
        peer_wait: a.peer_wait.to_string(),
        peer_phase: a.peer_phase.to_string(),
        hog_threads: a.hog,
        cotenants: a.cotenant,
        seconds: a.seconds,
        bridge_scheduling: rt,
        phases,
    })
}

fn print_report(out: &mut impl Write, k: usize, of: usize, cotenant: bool, report: &Report) -> anyhow::Result<()> {
    writeln!(
        out,
        "{}haptic path, {} s per phase at 1 kHz, bridge {} wait, peer {} wait ({} phase), {} hog threads{}; bridge: {}",
        if of > 1 { format!("run {}/{of}: ", k + 1) } else { String::new() },
        report.seconds,
        report.wait,
        report.peer_wait,
        report.peer_phase,
        report.hog_threads,
        if cotenant { ", co-tenant solve + build" } else { "" },
        report.bridge_scheduling
    )?;
    writeln!(
        out,
        "{:<22} {:>26} {:>34} {:>14} {:>8} {:>13} {:>8}",
        "phase", "read→write p50/p99 µs", "deadline→write p50/p99/p99.9/max µs", "misses", "fresh %", "CPU br/peer %", "steal %"
    )?;
    for p in &report.phases {
        writeln!(
            out,
            "{:<22} {:>26} {:>34} {:>14} {:>8.1} {:>13} {:>8}",
            p.phase,
            format!("{:.1} / {:.1}", p.read_to_write_us.p50, p.read_to_write_us.p99),
            format!(
                "{:.0} / {:.0} / {:.0} / {:.0}",
                p.deadline_to_write_us.p50, p.deadline_to_write_us.p99, p.deadline_to_write_us.p999, p.deadline_to_write_us.max
            ),
            format!("{} ({:.3} %)", p.deadline_misses, p.miss_percent),
            p.fresh_percent,
            format!("{:.0} / {:.0}", p.bridge_cpu_percent, p.peer_cpu_percent),
            p.steal_percent.map_or("–".into(), |x| format!("{x:.2}")),
        )?;
    }
    writeln!(
        out,
        "  bridge wake-ups later than the spin window: {}",
        report
            .phases
            .iter()
            .map(|p| format!("{} {}", p.phase, p.late_wakeups))
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    for p in &report.phases {
        if let Some(t) = &p.tail {
            let causes: Vec<String> = t.named().iter().map(|(c, n)| format!("{c} {n}")).collect();
            writeln!(
                out,
                "  {}: {} late ticks of {} (read→write > {} µs or a tick late){}{}",
                p.phase,
                t.late,
                t.ticks,
                tail::LATE_NS / 1000,
                if causes.is_empty() { "" } else { ": " },
                causes.join(", ")
            )?;
        }
    }
    Ok(())
}

/// The median and spread over runs, and how many runs meet the haptic goal.
#[derive(Debug, Serialize)]
struct Summary {
    runs: usize,
    /// Full tick deadline→write p99 minus the null loop's, per run (µs).
    full_minus_null_p99_us: Vec<f64>,
    /// Full tick read→write p99, per run (µs).
    full_read_to_write_p99_us: Vec<f64>,
    /// Full tick misses minus the null loop's, per run (percentage points).
    full_minus_null_misses_pct: Vec<f64>,
    /// CPU of the bridge and the tick thread in the full tick phase, per run (% of a core).
    full_cpu_bridge_pct: Vec<f64>,
    full_cpu_peer_pct: Vec<f64>,
    /// (vCPU steal %, misses %) of every phase of every run, where steal is reported.
    steal_and_misses_pct: Vec<(f64, f64)>,
    /// Runs meeting each goal.
    within_50us_of_null: usize,
    read_to_write_p99_at_most_100us: usize,
    misses_within_null_plus_0_1pct: usize,
    cpu_at_most_20pct_per_side: usize,
}

impl Summary {
    fn of(runs: &[Report]) -> Self {
        fn pick<'a>(r: &'a Report, name: &str) -> &'a Phase {
            r.phases.iter().find(|p| p.phase == name).expect("every run has its phases")
        }
        let diff: Vec<f64> = runs
            .iter()
            .map(|r| pick(r, "full tick").deadline_to_write_us.p99 - pick(r, "null loop").deadline_to_write_us.p99)
            .collect();
        let rw: Vec<f64> = runs.iter().map(|r| pick(r, "full tick").read_to_write_us.p99).collect();
        let miss: Vec<f64> = runs
            .iter()
            .map(|r| pick(r, "full tick").miss_percent - pick(r, "null loop").miss_percent)
            .collect();
        let cpu_b: Vec<f64> = runs.iter().map(|r| pick(r, "full tick").bridge_cpu_percent).collect();
        let cpu_p: Vec<f64> = runs.iter().map(|r| pick(r, "full tick").peer_cpu_percent).collect();
        let steal_and_misses_pct = runs
            .iter()
            .flat_map(|r| &r.phases)
            .filter_map(|p| p.steal_percent.map(|st| (st, p.miss_percent)))
            .collect();
        Self {
            runs: runs.len(),
            steal_and_misses_pct,
            within_50us_of_null: diff.iter().filter(|&&d| d <= 50.0).count(),
            read_to_write_p99_at_most_100us: rw.iter().filter(|&&x| x <= 100.0).count(),
            misses_within_null_plus_0_1pct: miss.iter().filter(|&&x| x <= 0.1).count(),
            cpu_at_most_20pct_per_side: cpu_b.iter().zip(&cpu_p).filter(|(b, p)| **b <= 20.5 && **p <= 20.5).count(),
            full_minus_null_p99_us: diff,
            full_read_to_write_p99_us: rw,
            full_minus_null_misses_pct: miss,
            full_cpu_bridge_pct: cpu_b,
            full_cpu_peer_pct: cpu_p,
        }
    }
}

/// Median, minimum and maximum.
fn spread(v: &[f64]) -> (f64, f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let mid = if s.len() % 2 == 1 {
        s[s.len() / 2]
    } else {
        0.5 * (s[s.len() / 2 - 1] + s[s.len() / 2])
    };
    (mid, s[0], s[s.len() - 1])
}

fn print_summary(out: &mut impl Write, s: &Summary) -> anyhow::Result<()> {
    writeln!(out, "over {} runs (median, min – max), full tick phase:", s.runs)?;
    let line = |out: &mut dyn Write, what: &str, v: &[f64], goal: &str, met: usize| -> std::io::Result<()> {
        let (m, lo, hi) = spread(v);
        writeln!(
            out,
            "  {what:<44} {m:>8.1}  ({lo:.1} – {hi:.1})   goal {goal}: {met} of {} runs",
            s.runs
        )
    };
    line(
        out,
        "deadline→write p99 − null loop's (µs)",
        &s.full_minus_null_p99_us,
        "≤ 50",
        s.within_50us_of_null,
    )?;
    line(
        out,
        "read→write p99 (µs)",
        &s.full_read_to_write_p99_us,
        "≤ 100",
        s.read_to_write_p99_at_most_100us,
    )?;
    line(
        out,
        "misses − null loop's (% of ticks)",
        &s.full_minus_null_misses_pct,
        "≤ 0.1",
        s.misses_within_null_plus_0_1pct,
    )?;
    line(
        out,
        "CPU, bridge (% of a core)",
        &s.full_cpu_bridge_pct,
        "≤ 20 per side",
        s.cpu_at_most_20pct_per_side,
    )?;
    line(
        out,
        "CPU, tick thread (% of a core)",
        &s.full_cpu_peer_pct,
        "≤ 20 per side",
        s.cpu_at_most_20pct_per_side,
    )?;
    if s.steal_and_misses_pct.len() >= 3 {
        let (steal, misses): (Vec<f64>, Vec<f64>) = s.steal_and_misses_pct.iter().copied().unzip();
        let (m, lo, hi) = spread(&steal);
        writeln!(
            out,
            "  vCPU steal over all phases: median {m:.2} % ({lo:.2} – {hi:.2}) of CPU time; correlation of misses with steal across the {} phases: r = {:.2}",
            steal.len(),
            pearson(&steal, &misses)
        )?;
    }
    Ok(())
}

/// Pearson's correlation coefficient (0 when either series is constant).
fn pearson(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len()) as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    if sxx > 0.0 && syy > 0.0 { sxy / (sxx * syy).sqrt() } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pearson_of_a_line_and_of_a_constant() {
        let x = [0.1, 0.5, 1.0, 2.0];
        assert!((pearson(&x, &x.map(|v| 3.0 * v + 1.0)) - 1.0).abs() < 1e-12);
        assert!((pearson(&x, &x.map(|v| -v)) + 1.0).abs() < 1e-12);
        assert_eq!(pearson(&x, &[2.0; 4]), 0.0);
    }

    #[test]
    fn spread_is_median_min_max() {
        assert_eq!(spread(&[3.0, 1.0, 2.0]), (2.0, 1.0, 3.0));
        assert_eq!(spread(&[4.0, 1.0, 2.0, 3.0]), (2.5, 1.0, 4.0));
    }
}
