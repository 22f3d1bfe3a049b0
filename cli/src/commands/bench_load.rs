//! `vademecum bench load`: a server under many sessions, driven over real gRPC.
//!
//! Starts `vademecum serve` (this executable) as a child process on a free loopback port,
//! creates `--sessions` sessions of the built-in organ (or of a built-in tearing scene,
//! `--builtin`: a grasper pulls its grasp to half its max force and back), and for
//! `--seconds` drives each with
//! `--clients-per-session` interaction streams sending tool states at `--rate` (each waits
//! for its answer before the next: a frontend's round trip) and `--viewers` viewers at 30 Hz.
//! Measured in the same run, side by side:
//!
//! - a **null loop** in this process (a thread sleeping to 1 ms deadlines, doing nothing):
//!   the OS wake-up floor under this load, against the sessions' own tick lateness and misses
//!   (from each session's statistics);
//! - a **tonic echo** (the same stream against a service that answers at once, in this
//!   process) paced as the clients: the floor of a gRPC round trip under this load, against
//!   the clients' round trips;
//! - the server's **CPU** (`/proc/PID/stat`) and **RSS** (`/proc/PID/status`), and every
//!   client's account: states sent = answered + refused + lost.
//!
//! Prints a table, writes the figures as JSON (`--json FILE`).

use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Child, Command, ExitCode, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use hdrhistogram::Histogram;
use serde::Serialize;
use vademecum_engine::scene::Scene;

use super::bench_load_chaos::{Bridges, Chaos, ChaosAccount};
use super::bench_load_client::{ClientAccount, Drive, client, connect};
use super::bench_session::{EchoServer, NullCounts, bench_path, echo_once, hist, null_loop_until};
use crate::cli::BenchLoadArgs;
use crate::commands::build::ensure_bundles;
use vademecum_server::session::stats::Percentiles;

/// The figures of a run, as written to the JSON file.
#[derive(Debug, Serialize)]
struct Report {
    sessions: usize,
    clients_per_session: usize,
    viewers_per_session: usize,
    seconds: f64,
    rate_hz: f64,
    tick_workers: Option<usize>,
    frame_workers: Option<usize>,
    /// The server's CPU wake-up latency request (serve --wake-latency-us), as it said.
    server_wake_latency: Option<String>,
    null_loop_lateness_us: Percentiles,
    null_loop_misses: u64,
    null_loop_ticks: u64,
    session_ticks: u64,
    session_misses: u64,
    session_miss_rate_worst: f64,
    session_tick_work_p99_us_worst: f64,
    round_trip_us: Percentiles,
    echo_round_trip_us: Percentiles,
    states_sent: u64,
    states_answered: u64,
    states_refused: u64,
    states_lost: u64,
    /// Of the gRPC clients' answers, those in contact with the tissue, and those that say it
    /// tore.
    answers_in_contact: u64,
    answers_torn: u64,
    frames_received: u64,
    server_cpu_cores: f64,
    /// The server's CPU by kind of thread (cores).
    server_cpu_cores_by_thread: std::collections::BTreeMap<String, f64>,
    server_rss_mib: f64,
    server_peak_rss_mib: f64,
    /// The server's RSS before any session was created.
    server_idle_rss_mib: f64,
    /// What each session reports it holds of its own (mean, MiB; `SessionStats.memory_bytes`).
    session_memory_mib: f64,
    /// States sent by killed clients and not answered when they died (chaos).
    states_in_flight_at_kill: u64,
    /// The time series, one entry per `--window`.
    windows: Vec<Window>,
    /// The sessions driven by device bridges (`--haptic`).
    #[serde(skip_serializing_if = "Option::is_none")]
    haptic: Option<HapticReport>,
    /// Threads of the CPU hog (`--hog`), and how long it ran (s).
    hog_threads: usize,
    hog_seconds: f64,
    /// The sessions' fidelity fallbacks (`SessionStats.fidelity_fallbacks`, summed), and the
    /// share of their ticks at the reduced fidelity.
    fidelity_fallbacks: u64,
    reduced_tick_pct: f64,
    /// What the chaos did (`--chaos-every`).
    #[serde(skip_serializing_if = "Option::is_none")]
    chaos: Option<ChaosReport>,
}

/// The device sessions of a run, from their statistics (their bridges' reports included).
#[derive(Debug, Serialize)]
struct HapticReport {
    sessions: usize,
    /// How their tick loops waited for the bridges (serve --haptic-wait).
    wait: String,
    /// Device workers that ticked them (0: a thread each).
    device_workers: usize,
    /// How the bridges waited for their answers (vademecum-bridge --answer-wake).
    bridge_answer_wake: String,
    /// Tool states from the bridges answered, all sessions.
    answered: u64,
    /// Their ticks and deadline misses.
    ticks: u64,
    misses: u64,
    /// The bridges' device read → force written (µs): the worst session's median and p99.
    bridge_latency_p50_us_worst: f64,
    bridge_latency_p99_us_worst: f64,
    /// The bridges' own deadline misses, and ticks their watchdog held or faded the force.
    bridge_deadline_misses: u64,
    bridge_watchdog_ticks: u64,
    /// Bridges killed (SIGKILL) and restarted.
    bridge_kills: u64,
}

impl HapticReport {
    fn of(stats: &[vademecum_client::pb::SessionStats], a: &BenchLoadArgs, bridge_kills: u64) -> Self {
        Self {
            sessions: stats.len(),
            wait: a.haptic_wait.to_string(),
            device_workers: a.device_workers.unwrap_or(0),
            bridge_answer_wake: a.bridge_answer_wake.to_string(),
            answered: stats.iter().map(|s| s.haptic_answered).sum(),
            ticks: stats.iter().map(|s| s.ticks).sum(),
            misses: stats.iter().map(|s| s.deadline_misses).sum(),
            bridge_latency_p50_us_worst: stats.iter().map(|s| s.bridge_latency_p50_us).fold(0.0, f64::max),
            bridge_latency_p99_us_worst: stats.iter().map(|s| s.bridge_latency_p99_us).fold(0.0, f64::max),
            bridge_deadline_misses: stats.iter().map(|s| s.bridge_deadline_misses).sum(),
            bridge_watchdog_ticks: stats.iter().map(|s| s.bridge_watchdog_ticks).sum(),
            bridge_kills,
        }
    }
}

/// One window of the time series.
#[derive(Debug, Serialize)]
struct Window {
    /// End of the window (s since the load started).
    t_s: f64,
    server_rss_mib: f64,
    /// Deadline misses in the window (% of ticks): the null loop's, the sessions' without a
    /// chaos client, the chaos clients' sessions'.
    null_miss_pct: f64,
    sessions_miss_pct: f64,
    chaos_sessions_miss_pct: Option<f64>,
    /// The device sessions' misses (`--haptic`).
    haptic_sessions_miss_pct: Option<f64>,
    /// Clients killed in the window.
    kills: u64,
    /// Sessions at their reduced fidelity at the window's end, and fallbacks in the window.
    sessions_reduced: usize,
    fallbacks: u64,
}

/// The chaos of a run.
#[derive(Debug, Serialize)]
struct ChaosReport {
    clients: usize,
    every_s: f64,
    kills: u64,
    states_sent: u64,
    states_answered: u64,
    states_refused: u64,
    states_in_flight_at_kill: u64,
}

/// The server child: killed when dropped.
struct Server {
    child: Child,
    addr: String,
    /// What the server said of its CPU wake-up latency request, if it was asked for one.
    wake_latency: Option<String>,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Server {
    /// `vademecum serve` on a free loopback port, bundles under `bundle_root`.
    fn start(a: &BenchLoadArgs, bundle_root: &std::path::Path) -> anyhow::Result<Self> {
        let exe = std::env::current_exe().context("cannot find this executable to start the server")?;
        let mut cmd = Command::new(exe);
        cmd.args(["serve", "--listen", "127.0.0.1:0", "--no-auth", "--bundle-root"])
            .arg(bundle_root)
            .args(["--max-sessions", &a.sessions.to_string()])
            .args([
                "--max-streams",
                // a killed chaos client's stream may linger until the server notices the reset
                &(a.sessions * (a.clients_per_session + a.viewers) + a.chaos_clients)
                    .max(1)
                    .to_string(),
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null());
        if let Some(n) = a.tick_workers {
            cmd.args(["--tick-workers", &n.to_string()]);
        }
        if let Some(n) = a.frame_workers {
            cmd.args(["--frame-workers", &n.to_string()]);
        }
        if let Some(us) = a.server_wake_latency_us {
            cmd.args(["--wake-latency-us", &us.to_string()]);
        }
        if a.no_fidelity_fallback {
            cmd.arg("--no-fidelity-fallback");
        }
        if a.haptic > 0 {
            cmd.args(["--haptic-wait", &a.haptic_wait.to_string()]);
            if let Some(n) = a.device_workers {
                cmd.args(["--device-workers", &n.to_string()]);
            }
        }
        let mut child = cmd.spawn().context("cannot start the server")?;
        let stdout = child.stdout.take().context("the server's output")?;
        let mut lines = BufReader::new(stdout).lines();
        let mut wake_latency = None;
        let addr = loop {
            match lines.next() {
                Some(Ok(l)) => {
                    if let Some(a) = l.strip_prefix("listening on ") {
                        break a.trim().to_string();
                    }
                    if let Some(w) = l.strip_prefix("CPU wake-up latency: ") {
                        wake_latency = Some(w.to_string());
                    }
                }
                _ => {
                    let _ = child.kill();
                    bail!("the server ended before listening");
                }
            }
        };
        // keep draining its output so it never blocks on a full pipe
        std::thread::spawn(move || for _ in lines {});
        Ok(Self { child, addr, wake_latency })
    }

    /// CPU time the server has used (user + system), from `/proc/PID/stat`.
    fn cpu(&self) -> Option<Duration> {
        stat_cpu(&std::fs::read_to_string(format!("/proc/{}/stat", self.child.id())).ok()?)
    }

    /// CPU time used by each kind of the server's threads (the name up to its first `-`:
    /// `tick` workers, `frames` threads, `answers` dispatchers, `tokio` runtime workers…),
    /// from `/proc/PID/task/*/stat`.
    fn cpu_by_thread_kind(&self) -> std::collections::BTreeMap<String, Duration> {
        let mut kinds = std::collections::BTreeMap::new();
        let Ok(tasks) = std::fs::read_dir(format!("/proc/{}/task", self.child.id())) else {
            return kinds;
        };
        for t in tasks.flatten() {
            let Ok(comm) = std::fs::read_to_string(t.path().join("comm")) else {
                continue;
            };
            let Some(cpu) = std::fs::read_to_string(t.path().join("stat")).ok().and_then(|s| stat_cpu(&s)) else {
                continue;
            };
            let kind = comm.trim().split('-').next().unwrap_or("").to_string();
            *kinds.entry(kind).or_insert(Duration::ZERO) += cpu;
        }
        kinds
    }

    /// Resident and peak resident memory (MiB), from `/proc/PID/status`.
    fn rss(&self) -> (f64, f64) {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).unwrap_or_default();
        let field = |name: &str| {
            status
                .lines()
                .find_map(|l| l.strip_prefix(name))
                .and_then(|v| v.split_whitespace().next()?.parse::<f64>().ok())
                .map_or(0.0, |kib| kib / 1024.0)
        };
        (field("VmRSS:"), field("VmHWM:"))
    }
}

/// User + system CPU time from a `/proc/…/stat` line.
fn stat_cpu(stat: &str) -> Option<Duration> {
    // fields after the command name (which may hold spaces) closed by ')'
    let rest = stat.get(stat.rfind(')')? + 2..)?;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: u64 = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as u64;
    Some(Duration::from_nanos(ticks * 1_000_000_000 / hz))
}

/// One viewer at 30 Hz on a connection of its own until `stop`: the frames it received.
async fn viewer(addr: String, id: String, stop: Arc<AtomicBool>) -> u64 {
    let Some(session) = connect(&addr, &id).await else {
        return 0;
    };
    let Ok(mut frames) = session.watch(30.0).await else {
        return 0;
    };
    let mut n = 0;
    while !stop.load(Ordering::Relaxed) {
        match tokio::time::timeout(Duration::from_millis(100), frames.message()).await {
            Ok(Ok(Some(_))) => n += 1,
            Ok(_) => break,
            Err(_) => {}
        }
    }
    n
}

/// The echo's round trips at `period` until `stop`.
async fn echo_client(echo: Arc<EchoServer>, period: Duration, stop: Arc<AtomicBool>) -> anyhow::Result<Histogram<u64>> {
    let (tx, mut responses) = echo.stream().await?;
    let mut h = hist();
    let mut ticker = tokio::time::interval(period);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut i = 0u64;
    while !stop.load(Ordering::Relaxed) {
        ticker.tick().await;
        let t0 = Instant::now();
        echo_once(&tx, &mut responses, i).await?;
        let _ = h.record((t0.elapsed().as_nanos() as u64).max(1));
        i += 1;
    }
    Ok(h)
}

/// Refuses durations, rates and counts out of their range, and more chaos and device clients
/// than sessions, before anything starts.
fn check_arguments(a: &BenchLoadArgs) -> anyhow::Result<()> {
    if !(a.seconds > 0.0 && a.seconds <= 3600.0) {
        bail!("--seconds must lie in (0, 3600], got {}", a.seconds);
    }
    if !(a.rate > 0.0 && a.rate <= 2000.0) {
        bail!("--rate must lie in (0, 2000] Hz, got {}", a.rate);
    }
    if a.sessions == 0 || a.sessions > 1024 {
        bail!("--sessions must lie in 1..=1024, got {}", a.sessions);
    }
    if !(a.window > 0.0 && a.window.is_finite()) {
        bail!("--window must be a positive number of seconds, got {}", a.window);
    }
    if let Some(e) = a.chaos_every {
        if !(e > 0.0 && e.is_finite()) {
            bail!("--chaos-every must be a positive number of seconds, got {e}");
        }
        if a.chaos_clients == 0 || a.chaos_clients > a.sessions {
            bail!(
                "--chaos-clients must lie in 1..={} (the sessions), got {}",
                a.sessions,
                a.chaos_clients
            );
        }
    }
    if let Some(h) = a.hog_seconds
        && !(h >= 0.0 && h.is_finite())
    {
        bail!("--hog-seconds must be a non-negative number of seconds, got {h}");
    }
    let chaos_sessions = if a.chaos_every.is_some() { a.chaos_clients } else { 0 };
    if chaos_sessions + a.haptic > a.sessions {
        bail!(
            "--haptic {} with {chaos_sessions} chaos clients is more than the {} sessions",
            a.haptic,
            a.sessions
        );
    }
    Ok(())
}

pub fn run(a: BenchLoadArgs) -> anyhow::Result<ExitCode> {
    check_arguments(&a)?;
    let scene = Scene::builtin(&a.builtin)?;
    let tearing = scene.spec.effects.tearing;
    if a.builtin != "organ" && !tearing {
        bail!(
            "--builtin {}: bench load drives the built-in organ with a probe or a tearing scene with a grasper",
            a.builtin
        );
    }
    if a.builtin != "organ" && (a.haptic > 0 || a.chaos_every.is_some()) {
        bail!(
            "--haptic and --chaos-every drive the built-in organ only (not --builtin {})",
            a.builtin
        );
    }
    let size = {
        let (lo, hi) = scene.organ_mesh(0)?.bounding_box();
        (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt()
    };
    let dir = a.bundles.clone().unwrap_or_else(|| PathBuf::from("out").join(&a.builtin));
    ensure_bundles(&scene, &dir)?;
    let dir = std::fs::canonicalize(&dir).with_context(|| format!("cannot resolve {}", dir.display()))?;
    let root = dir.parent().map(PathBuf::from).unwrap_or_else(|| PathBuf::from("/"));
    let name = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let server = Server::start(&a, &root)?;
    let plan = Plan {
        chaos_sessions: if a.chaos_every.is_some() { a.chaos_clients } else { 0 },
        // the device sessions are the last --haptic ones
        first_haptic: a.sessions - a.haptic,
        period: Duration::from_secs_f64(1.0 / a.rate),
        tearing,
        size,
        addr: format!("http://{}", server.addr),
    };
    let rt = tokio::runtime::Runtime::new().context("cannot start the async runtime")?;
    let report = rt.block_on(load(&a, &plan, &server, &name))?;
    drop(server);
    print_report(&report)?;
    if let Some(path) = &a.json {
        std::fs::write(path, serde_json::to_string_pretty(&report)?).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// How a run's sessions are driven, from its arguments and scene.
struct Plan {
    /// The first sessions, each driven by a chaos client (a process killed now and then).
    chaos_sessions: usize,
    /// The sessions from this one on are device sessions, driven by bridges.
    first_haptic: usize,
    /// Between two tool states of a client.
    period: Duration,
    /// A tearing scene (a grasper pulls) or the organ (a probe presses).
    tearing: bool,
    /// The organ's size (m): its bounding box's diagonal.
    size: f64,
    /// The server's address.
    addr: String,
}

/// The load itself: creates the sessions on `server` (bundle folder `name`), drives them for
/// `--seconds` beside the null loop, the echo and the hog, and gathers the figures.
async fn load(a: &BenchLoadArgs, plan: &Plan, server: &Server, name: &str) -> anyhow::Result<Report> {
    let (idle_rss, _) = server.rss();
    let sessions = create_sessions(a, plan, name).await?;
    // the echo, in this process
    let echo_server = Arc::new(EchoServer::start().await?);
    let stop = Arc::new(AtomicBool::new(false));
    let cpu0 = server.cpu();
    let kinds0 = server.cpu_by_thread_kind();
    let wall = Instant::now();
    let ids: Vec<String> = sessions.iter().map(|s| s.id().to_string()).collect();
    let script_dir = tempfile::tempdir().context("cannot make a folder for the bridges' script")?;
    let bridges = start_bridges(a, plan, script_dir.path())?;
    let chaos = match plan.chaos_sessions {
        0 => None,
        k => Some(Chaos::start(&plan.addr, &ids[..k], a.rate)?),
    };
    let (clients, viewers) = spawn_drivers(a, plan, &sessions, &stop)?;
    let echo = tokio::spawn(echo_client(echo_server.clone(), plan.period, stop.clone()));
    let null_counts = Arc::new(NullCounts::default());
    let null = {
        let (stop, counts) = (stop.clone(), null_counts.clone());
        std::thread::spawn(move || null_loop_until(&stop, &counts))
    };
    let mut run = UnderLoad {
        wall,
        chaos,
        bridges,
        windows: Vec::new(),
        hog_seconds: 0.0,
    };
    run.drive(a, plan, server, &sessions, &null_counts).await?;
    let cpu = match (cpu0, server.cpu()) {
        (Some(a0), Some(a1)) => (a1 - a0).as_secs_f64() / wall.elapsed().as_secs_f64(),
        _ => f64::NAN,
    };
    let (rss, peak) = server.rss();
    let secs = wall.elapsed().as_secs_f64();
    let cpu_by_thread: std::collections::BTreeMap<String, f64> = server
        .cpu_by_thread_kind()
        .into_iter()
        .map(|(k, t)| {
            let before = kinds0.get(&k).copied().unwrap_or(Duration::ZERO);
            (k, t.saturating_sub(before).as_secs_f64() / secs)
        })
        .filter(|(_, c)| *c > 0.0)
        .collect();
    stop.store(true, Ordering::Relaxed);
    let chaos = run.chaos.map(Chaos::finish);
    let bridge_kills = run.bridges.as_ref().map_or(0, |b| b.kills);
    // the device sessions' figures while their bridges still run
    let mut haptic_stats = Vec::new();
    for s in &sessions[plan.first_haptic..] {
        haptic_stats.push(s.stats().await?);
    }
    if let Some(b) = run.bridges {
        b.finish();
    }
    let clients = Accounts::of(clients, viewers, chaos.as_ref()).await?;
    let echo = echo.await??;
    let (null_p, null_misses, null_ticks) = null.join().map_err(|_| anyhow::anyhow!("the null loop panicked"))?;
    if let Ok(echo_server) = Arc::try_unwrap(echo_server) {
        echo_server.stop().await;
    }
    let closed = Closed::of(sessions).await?;
    Ok(Report {
        sessions: a.sessions,
        clients_per_session: a.clients_per_session,
        viewers_per_session: a.viewers,
        seconds: a.seconds,
        rate_hz: a.rate,
        tick_workers: a.tick_workers,
        frame_workers: a.frame_workers,
        server_wake_latency: server.wake_latency.clone(),
        null_loop_lateness_us: null_p,
        null_loop_misses: null_misses,
        null_loop_ticks: null_ticks,
        session_ticks: closed.ticks,
        session_misses: closed.misses,
        session_miss_rate_worst: closed.worst_rate,
        session_tick_work_p99_us_worst: closed.worst_work,
        round_trip_us: Percentiles::of(&clients.rtt),
        echo_round_trip_us: Percentiles::of(&echo),
        states_sent: clients.sent,
        states_answered: clients.answered,
        states_refused: clients.refused,
        states_lost: clients.sent.saturating_sub(clients.answered + clients.refused + clients.in_flight),
        answers_in_contact: clients.contact,
        answers_torn: clients.torn,
        frames_received: clients.frames,
        server_cpu_cores: cpu,
        server_cpu_cores_by_thread: cpu_by_thread,
        server_rss_mib: rss,
        server_peak_rss_mib: peak,
        server_idle_rss_mib: idle_rss,
        session_memory_mib: closed.memory as f64 / a.sessions as f64 / 1048576.0,
        states_in_flight_at_kill: clients.in_flight,
        windows: run.windows,
        haptic: (a.haptic > 0).then(|| HapticReport::of(&haptic_stats, a, bridge_kills)),
        hog_threads: a.hog,
        hog_seconds: run.hog_seconds,
        fidelity_fallbacks: closed.fallbacks,
        reduced_tick_pct: 100.0 * closed.reduced_ticks as f64 / closed.ticks.max(1) as f64,
        chaos: chaos.map(|c| ChaosReport {
            clients: plan.chaos_sessions,
            every_s: a.chaos_every.unwrap_or(0.0),
            kills: c.kills,
            states_sent: c.sent,
            states_answered: c.answered,
            states_refused: c.refused,
            states_in_flight_at_kill: c.in_flight_at_kill,
        }),
    })
}

/// Creates the run's `--sessions` sessions of the built-in scene (bundle folder `name`), the
/// last `--haptic` of them device sessions on channels of their own.
async fn create_sessions(a: &BenchLoadArgs, plan: &Plan, name: &str) -> anyhow::Result<Vec<vademecum_client::Session>> {
    let c = vademecum_client::Client::connect(plan.addr.clone()).await?;
    let mut sessions = Vec::new();
    for k in 0..a.sessions {
        let scene = vademecum_client::SceneSpec::Builtin(a.builtin.clone());
        let label = format!("load{k}");
        let s = if k >= plan.first_haptic {
            c.create_haptic_session(scene, name, &label, &haptic_channel(k)).await
        } else {
            c.create_session(scene, name, &label).await
        }
        .with_context(|| format!("session {k} of {}", a.sessions))?;
        sessions.push(s);
    }
    Ok(sessions)
}

/// The shared-memory channel of device session `k` (unique to this process).
fn haptic_channel(k: usize) -> String {
    format!("load-{}-h{k}", std::process::id())
}

/// Starts a bridge per device session (`--haptic`), each playing the bench's hand path from a
/// script written into `script_dir`.
fn start_bridges(a: &BenchLoadArgs, plan: &Plan, script_dir: &std::path::Path) -> anyhow::Result<Option<Bridges>> {
    if a.haptic == 0 {
        return Ok(None);
    }
    let script = script_dir.join("hand.csv");
    let keys = (0..=((a.seconds + 10.0) * 100.0) as u64)
        .map(|j| (j as f64 * 0.01, bench_path(10 * j), 0.0))
        .collect();
    vademecum_bridge::trajectory::Trajectory::new(keys)
        .map_err(|e| anyhow::anyhow!("the bridges' hand script: {e}"))?
        .write(&script)
        .context("cannot write the bridges' hand script")?;
    let channels: Vec<String> = (plan.first_haptic..a.sessions).map(haptic_channel).collect();
    Ok(Some(Bridges::start(
        a.bridge.as_deref(),
        &channels,
        &script,
        a.seconds + 10.0,
        a.bridge_answer_wake,
    )?))
}

/// The gRPC clients (`--clients-per-session` for each session with neither a chaos client nor
/// a bridge; a probe, or a grasper on a tearing scene) and the viewers (`--viewers` each).
#[allow(clippy::type_complexity)]
fn spawn_drivers(
    a: &BenchLoadArgs,
    plan: &Plan,
    sessions: &[vademecum_client::Session],
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<(Vec<tokio::task::JoinHandle<ClientAccount>>, Vec<tokio::task::JoinHandle<u64>>)> {
    let mut clients = Vec::new();
    let mut viewers = Vec::new();
    for (k, s) in sessions.iter().enumerate() {
        // a chaos session's client is a process of its own
        for _ in 0..a.clients_per_session * usize::from(k >= plan.chaos_sessions && k < plan.first_haptic) {
            let quiet: super::bench_load_client::Progress = Box::new(|_| {});
            let drive = if plan.tearing {
                Drive::grasp(s.info(), plan.size).context("a tearing session without a grasp site")?
            } else {
                Drive::Probe
            };
            clients.push(tokio::spawn(client(
                plan.addr.clone(),
                s.id().to_string(),
                drive,
                plan.period,
                stop.clone(),
                quiet,
            )));
        }
        for _ in 0..a.viewers {
            viewers.push(tokio::spawn(viewer(plan.addr.clone(), s.id().to_string(), stop.clone())));
        }
    }
    Ok((clients, viewers))
}

/// The run while under load: the chaos and the bridges it kills, the windows it samples.
struct UnderLoad {
    wall: Instant,
    chaos: Option<Chaos>,
    bridges: Option<Bridges>,
    windows: Vec<Window>,
    /// How long the hog ran (s).
    hog_seconds: f64,
}

impl UnderLoad {
    /// Holds the load for `--seconds`: runs the CPU hog for `--hog-seconds`, kills a chaos
    /// client every `--chaos-every` and one bridge halfway, and samples every session and the
    /// null loop each `--window`.
    async fn drive(
        &mut self,
        a: &BenchLoadArgs,
        plan: &Plan,
        server: &Server,
        sessions: &[vademecum_client::Session],
        null_counts: &NullCounts,
    ) -> anyhow::Result<()> {
        let wall = self.wall;
        let mut bridge_kill = a.chaos_every.map(|_| wall + Duration::from_secs_f64(a.seconds / 2.0));
        let progress = indicatif::ProgressBar::new(a.seconds.ceil() as u64).with_message("under load");
        let end = wall + Duration::from_secs_f64(a.seconds);
        let window = Duration::from_secs_f64(a.window);
        let (mut next_window, mut kills) = (wall + window, 0);
        let mut next_kill = a.chaos_every.map(|e| wall + window + Duration::from_secs_f64(e));
        let mut before = sample(sessions, null_counts).await?;
        // the CPU hog, beside the server, for --hog-seconds of the load
        let hog_stop = Arc::new(AtomicBool::new(false));
        let hogs: Vec<_> = (0..a.hog)
            .map(|_| {
                let s = hog_stop.clone();
                std::thread::spawn(move || super::bench_haptic::hog(s))
            })
            .collect();
        let hog_end = wall + Duration::from_secs_f64(a.hog_seconds.unwrap_or(a.seconds).min(a.seconds));
        let mut hog_ran = if a.hog > 0 { None } else { Some(0.0) };
        while Instant::now() < end {
            if hog_ran.is_none() && Instant::now() >= hog_end {
                hog_stop.store(true, Ordering::Relaxed);
                hog_ran = Some(wall.elapsed().as_secs_f64());
            }
            tokio::time::sleep(Duration::from_millis(250).min(end.saturating_duration_since(Instant::now()))).await;
            progress.set_position(wall.elapsed().as_secs());
            if let (Some(c), Some(t)) = (&mut self.chaos, next_kill)
                && Instant::now() >= t
            {
                c.kill_one()?;
                kills += 1;
                next_kill = a.chaos_every.map(|e| t + Duration::from_secs_f64(e));
            }
            if let (Some(b), Some(t)) = (&mut self.bridges, bridge_kill)
                && Instant::now() >= t
            {
                b.kill_one()?;
                bridge_kill = None;
                kills += 1;
            }
            if Instant::now() >= next_window || Instant::now() >= end {
                let now = sample(sessions, null_counts).await?;
                let groups = Groups {
                    chaos: plan.chaos_sessions,
                    haptic: a.haptic,
                };
                self.windows
                    .push(now.window_since(&before, wall.elapsed().as_secs_f64(), server.rss().0, groups, kills));
                (before, kills) = (now, 0);
                next_window += window;
            }
        }
        progress.finish_and_clear();
        hog_stop.store(true, Ordering::Relaxed);
        self.hog_seconds = hog_ran.unwrap_or_else(|| wall.elapsed().as_secs_f64());
        for h in hogs {
            let _ = h.join();
        }
        Ok(())
    }
}

/// Every client's account of a run, the chaos clients' included, and the viewers' frames.
struct Accounts {
    sent: u64,
    answered: u64,
    refused: u64,
    contact: u64,
    torn: u64,
    /// States sent by killed clients and not answered when they died.
    in_flight: u64,
    rtt: Histogram<u64>,
    frames: u64,
}

impl Accounts {
    /// Waits for the clients and the viewers to end (after the run's stop) and adds them up.
    async fn of(
        clients: Vec<tokio::task::JoinHandle<ClientAccount>>,
        viewers: Vec<tokio::task::JoinHandle<u64>>,
        chaos: Option<&ChaosAccount>,
    ) -> anyhow::Result<Self> {
        let mut me = Self {
            sent: 0,
            answered: 0,
            refused: 0,
            contact: 0,
            torn: 0,
            in_flight: chaos.map_or(0, |c| c.in_flight_at_kill),
            rtt: hist(),
            frames: 0,
        };
        for c in clients {
            let acc = c.await?;
            me.sent += acc.sent;
            me.answered += acc.answered;
            me.refused += acc.refused;
            me.contact += acc.contact;
            me.torn += acc.torn;
            if let Some(h) = acc.rtt {
                let _ = me.rtt.add(&h);
            }
        }
        if let Some(c) = chaos {
            me.sent += c.sent;
            me.answered += c.answered;
            me.refused += c.refused;
        }
        for v in viewers {
            me.frames += v.await?;
        }
        Ok(me)
    }
}

/// What the sessions said of themselves when closed: ticks, misses, memory, fallbacks.
struct Closed {
    ticks: u64,
    misses: u64,
    worst_rate: f64,
    worst_work: f64,
    memory: u64,
    fallbacks: u64,
    reduced_ticks: u64,
}

impl Closed {
    /// Closes every session and adds up its statistics.
    async fn of(sessions: Vec<vademecum_client::Session>) -> anyhow::Result<Self> {
        let mut me = Self {
            ticks: 0,
            misses: 0,
            worst_rate: 0.0,
            worst_work: 0.0,
            memory: 0,
            fallbacks: 0,
            reduced_ticks: 0,
        };
        for s in sessions {
            let st = s.close().await?;
            me.memory += st.memory_bytes;
            me.fallbacks += st.fidelity_fallbacks;
            me.reduced_ticks += st.reduced_ticks;
            me.ticks += st.ticks;
            me.misses += st.deadline_misses;
            me.worst_rate = me.worst_rate.max(st.deadline_misses as f64 / st.ticks.max(1) as f64);
            me.worst_work = me.worst_work.max(st.tick_work_p99_us);
        }
        Ok(me)
    }
}

/// Which sessions a window reports apart: the first `chaos` (clients killed), the last
/// `haptic` (device bridges).
#[derive(Debug, Clone, Copy)]
struct Groups {
    chaos: usize,
    haptic: usize,
}

/// The counts a window is measured between: each session's ticks and misses, the null loop's;
/// each session's fallbacks and whether it runs reduced.
struct Sample {
    sessions: Vec<(u64, u64)>,
    null: (u64, u64),
    fidelity: Vec<(u64, bool)>,
}

/// Samples every session's statistics (over gRPC) and the null loop's counts.
async fn sample(sessions: &[vademecum_client::Session], null: &NullCounts) -> anyhow::Result<Sample> {
    let mut counts = Vec::with_capacity(sessions.len());
    let mut fidelity = Vec::with_capacity(sessions.len());
    for s in sessions {
        let st = s.stats().await.with_context(|| format!("the statistics of session {}", s.id()))?;
        counts.push((st.ticks, st.deadline_misses));
        fidelity.push((st.fidelity_fallbacks, st.fidelity_reduced));
    }
    Ok(Sample {
        sessions: counts,
        null: (null.ticks.load(Ordering::Relaxed), null.misses.load(Ordering::Relaxed)),
        fidelity,
    })
}

impl Sample {
    /// The window from `before` to this sample, ending at `t_s`, with the server's RSS then; the
    /// chaos sessions' misses and the device sessions' apart.
    fn window_since(&self, before: &Self, t_s: f64, rss_mib: f64, groups: Groups, kills: u64) -> Window {
        let pct = |(t, m): (u64, u64)| 100.0 * m as f64 / t.max(1) as f64;
        let delta = |range: std::ops::Range<usize>| {
            range.fold((0, 0), |(t, m), k| {
                let (a, b) = (before.sessions[k], self.sessions[k]);
                (t + b.0.saturating_sub(a.0), m + b.1.saturating_sub(a.1))
            })
        };
        let n = self.sessions.len().min(before.sessions.len());
        let chaos = groups.chaos.min(n);
        let first_haptic = n.saturating_sub(groups.haptic).max(chaos);
        Window {
            t_s,
            server_rss_mib: rss_mib,
            null_miss_pct: pct((self.null.0.saturating_sub(before.null.0), self.null.1.saturating_sub(before.null.1))),
            sessions_miss_pct: pct(delta(chaos..first_haptic)),
            chaos_sessions_miss_pct: (chaos > 0).then(|| pct(delta(0..chaos))),
            haptic_sessions_miss_pct: (first_haptic < n).then(|| pct(delta(first_haptic..n))),
            kills,
            sessions_reduced: self.fidelity.iter().filter(|f| f.1).count(),
            fallbacks: self
                .fidelity
                .iter()
                .zip(&before.fidelity)
                .map(|(a, b)| a.0.saturating_sub(b.0))
                .sum(),
        }
    }
}

/// The load's windows as a table (RSS, misses, kills, fallbacks over time) and its trend
/// from the first to the last.
fn print_windows(out: &mut impl Write, windows: &[Window]) -> std::io::Result<()> {
    writeln!(
        out,
        "| t (s) | RSS (MiB) | null loop misses | sessions' misses | chaos sessions' misses | device sessions' misses | kills | fallbacks | sessions reduced |"
    )?;
    writeln!(out, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|")?;
    let opt = |p: Option<f64>| p.map_or("—".into(), |p| format!("{p:.3} %"));
    for w in windows {
        writeln!(
            out,
            "| {:.0} | {:.1} | {:.3} % | {:.3} % | {} | {} | {} | {} | {} |",
            w.t_s,
            w.server_rss_mib,
            w.null_miss_pct,
            w.sessions_miss_pct,
            opt(w.chaos_sessions_miss_pct),
            opt(w.haptic_sessions_miss_pct),
            w.kills,
            w.fallbacks,
            w.sessions_reduced
        )?;
    }
    let (first, last) = (&windows[0], &windows[windows.len() - 1]);
    let half = windows.len() / 2;
    let mean = |ws: &[Window]| ws.iter().map(|w| w.sessions_miss_pct).sum::<f64>() / ws.len().max(1) as f64;
    writeln!(
        out,
        "trend: RSS {:.1} → {:.1} MiB from the first window to the last; sessions' misses {:.3} % in the first half, {:.3} % in the second",
        first.server_rss_mib,
        last.server_rss_mib,
        mean(&windows[..half]),
        mean(&windows[half..])
    )?;
    Ok(())
}

fn print_report(r: &Report) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    let pct = |n: u64, of: u64| 100.0 * n as f64 / of.max(1) as f64;
    writeln!(
        out,
        "{} sessions x {} client(s) at {} Hz + {} viewer(s) at 30 Hz, {} s, tick workers: {}, frame workers: {}",
        r.sessions,
        r.clients_per_session,
        r.rate_hz,
        r.viewers_per_session,
        r.seconds,
        r.tick_workers.map_or("default (one per CPU)".to_string(), |n| n.to_string()),
        r.frame_workers.map_or("default (one per CPU)".to_string(), |n| n.to_string())
    )?;
    if let Some(w) = &r.server_wake_latency {
        writeln!(out, "server's CPU wake-up latency request: {w}")?;
    }
    writeln!(out, "| what | samples | p50 (µs) | p99 (µs) | p99.9 (µs) | max (µs) | misses |")?;
    writeln!(out, "|---|---:|---:|---:|---:|---:|---:|")?;
    let row = |out: &mut std::io::StdoutLock, what: &str, p: &Percentiles, misses: String| {
        writeln!(
            out,
            "| {what} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {misses} |",
            p.count, p.p50, p.p99, p.p999, p.max
        )
    };
    row(
        &mut out,
        "null loop in the load generator: lateness of a 1 ms sleep",
        &r.null_loop_lateness_us,
        format!("{} ({:.3} %)", r.null_loop_misses, pct(r.null_loop_misses, r.null_loop_ticks)),
    )?;
    row(
        &mut out,
        "gRPC round trip, every client (send → answer)",
        &r.round_trip_us,
        "—".into(),
    )?;
    row(&mut out, "… tonic echo, same stream and pacing", &r.echo_round_trip_us, "—".into())?;
    writeln!(
        out,
        "sessions: {} ticks, {} deadline misses ({:.3} %; worst session {:.3} %); worst tick work p99 {:.1} µs",
        r.session_ticks,
        r.session_misses,
        pct(r.session_misses, r.session_ticks),
        100.0 * r.session_miss_rate_worst,
        r.session_tick_work_p99_us_worst
    )?;
    writeln!(
        out,
        "fidelity: {} fallback(s) to the reduced setting; {:.2} % of the sessions' ticks ran reduced{}",
        r.fidelity_fallbacks,
        r.reduced_tick_pct,
        if r.hog_threads > 0 {
            format!(
                " (a CPU hog of {} thread(s) ran for the first {:.0} s)",
                r.hog_threads, r.hog_seconds
            )
        } else {
            String::new()
        }
    )?;
    writeln!(
        out,
        "tool states: {} sent = {} answered + {} refused + {} in flight when a client was killed + {} lost; {} frames to viewers",
        r.states_sent, r.states_answered, r.states_refused, r.states_in_flight_at_kill, r.states_lost, r.frames_received
    )?;
    writeln!(
        out,
        "contact: {} of the clients' answers touched or held the tissue ({:.1} %), {} said it tore",
        r.answers_in_contact,
        100.0 * r.answers_in_contact as f64 / r.states_answered.max(1) as f64,
        r.answers_torn
    )?;
    let by: Vec<String> = r.server_cpu_cores_by_thread.iter().map(|(k, c)| format!("{k} {c:.2}")).collect();
    writeln!(
        out,
        "server: {:.2} cores of CPU ({}), RSS {:.1} MiB (peak {:.1} MiB)",
        r.server_cpu_cores,
        by.join(", "),
        r.server_rss_mib,
        r.server_peak_rss_mib
    )?;
    writeln!(
        out,
        "memory: each session reports {:.2} MiB of its own; the server's RSS grew {:.2} MiB per session (from {:.1} MiB idle; the bundle's shared data once)",
        r.session_memory_mib,
        (r.server_rss_mib - r.server_idle_rss_mib) / r.sessions as f64,
        r.server_idle_rss_mib
    )?;
    if let Some(c) = &r.chaos {
        writeln!(
            out,
            "chaos: {} clients as processes, one killed (SIGKILL) every {} s: {} kills; their states {} sent = {} answered + {} refused + {} in flight when killed",
            c.clients, c.every_s, c.kills, c.states_sent, c.states_answered, c.states_refused, c.states_in_flight_at_kill
        )?;
    }
    if let Some(h) = &r.haptic {
        writeln!(
            out,
            "device sessions: {} driven by bridges (server waits: {} on {}; bridges wait for answers: {}): {} states answered, {} deadline misses of {} ticks ({:.3} %); bridges' read → force p50/p99 (worst) {:.1}/{:.1} µs, {} bridge deadline misses, {} watchdog ticks, {} bridge(s) killed and restarted",
            h.sessions,
            h.wait,
            match h.device_workers {
                0 => "a thread each".to_string(),
                n => format!("{n} device worker(s)"),
            },
            h.bridge_answer_wake,
            h.answered,
            h.misses,
            h.ticks,
            pct(h.misses, h.ticks),
            h.bridge_latency_p50_us_worst,
            h.bridge_latency_p99_us_worst,
            h.bridge_deadline_misses,
            h.bridge_watchdog_ticks,
            h.bridge_kills
        )?;
    }
    if r.windows.len() > 1 {
        print_windows(&mut out, &r.windows)?;
    }
    Ok(())
}
