//! `vademecum bench haptic`: the 1 kHz haptic path on this machine, each figure beside a null
//! loop measured in the same run, idle or with a CPU hog, so the OS floor and our overhead
//! are told apart.
//!
//! Three phases of `--seconds` each, all driven by the device bridge's own loop
//! ([`vademecum_bridge::bridge_loop`]) with the same wait strategy:
//!
//! 1. **null** — the same timing loop with no IPC and no work (a fixed device, a link that
//!    answers at once);
//! 2. **round trip** — the bridge against an echo peer over iceoryx2 shared memory: the peer
//!    waits for each state like a session does ([`vademecum_bridge::peer`]) and answers at once
//!    with zero force;
//! 3. **full tick** — the bridge's simulated stylus palpating the built-in organ against a
//!    real session (contact search, force from the vademecum, answer).
//!
//! For each: device read → force written (our IPC and work), deadline → force written (the
//! OS floor plus ours: the figure compared with the null loop), deadline misses, and the CPU
//! spent by the bridge's and the peer's threads. `--hog N` runs N threads of floating-point
//! busy work for the whole run (null phase included).

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
use vademecum_bridge::timing::{self, WaitStrategy};
use vademecum_bridge::trajectory::Trajectory;
use vademecum_engine::scene::Scene;
use vademecum_proto::shm::{self, HapticChannel};

use crate::cli_main::cli::BenchHapticArgs;
use crate::cli_main::commands::build::ensure_bundles;
use crate::session::stats::Percentiles;
use crate::session::{HapticConfig, Session, SessionConfig, builtin_palpation};

#[derive(Debug, Serialize)]
struct Phase {
    phase: &'static str,
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
    hog_threads: usize,
    seconds: f64,
    bridge_scheduling: String,
    phases: Vec<Phase>,
}

fn phase(name: &'static str, o: &BridgeOutcome, peer_cpu: Duration) -> Phase {
    let wall = o.wall.as_secs_f64().max(1e-9);
    let r = &o.report;
    Phase {
        phase: name,
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
    make: impl FnOnce() -> anyhow::Result<(D, L)> + Send + 'static,
) -> anyhow::Result<(BridgeOutcome, String)>
where
    D: vademecum_bridge::device::Device,
    L: Link,
{
    std::thread::Builder::new()
        .name("bench-bridge".into())
        .spawn(move || -> anyhow::Result<(BridgeOutcome, String)> {
            let rt = timing::request_realtime(fifo, None).to_string();
            let (mut device, mut link) = make()?;
            let stop = Arc::new(AtomicBool::new(false));
            Ok((bridge_loop::run(&mut device, &mut link, &params, &stop)?, rt))
        })
        .context("cannot start the bridge thread")?
        .join()
        .map_err(|_| anyhow::anyhow!("the bridge thread panicked"))?
}

/// Busy floating-point work until `stop`.
fn hog(stop: Arc<AtomicBool>) {
    let mut x = 1.000_001f64;
    while !stop.load(Ordering::Relaxed) {
        for _ in 0..10_000 {
            x = (x * 1.000_000_1).sqrt() + 1e-9;
        }
        std::hint::black_box(x);
    }
}

pub fn run(a: BenchHapticArgs) -> anyhow::Result<ExitCode> {
    if !(a.seconds > 0.0 && a.seconds <= 600.0) {
        bail!("--seconds must lie in (0, 600], got {}", a.seconds);
    }
    shm::quiet_iceoryx2_logging();
    let scene = Arc::new(Scene::builtin("organ")?);
    let dir = a.bundles.clone().unwrap_or_else(|| PathBuf::from("out/organ"));
    let bundles = ensure_bundles(&scene, &dir)?;
    let radius = vademecum_engine::pgd::offline::probe_radius(&scene);
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
    let hand = Trajectory::new(keys).map_err(anyhow::Error::msg)?;

    let period = Duration::from_millis(1);
    let params = BridgeParams {
        strategy: a.wait,
        window: Duration::from_micros(a.spin_window_us),
        duration: Some(Duration::from_secs_f64(a.seconds)),
        trace_limit: 0,
        ..BridgeParams::default()
    };
    let fifo = (a.realtime && a.wait != WaitStrategy::Spin).then_some(80);
    let hog_stop = Arc::new(AtomicBool::new(false));
    let hogs: Vec<_> = (0..a.hog)
        .map(|_| {
            let s = hog_stop.clone();
            std::thread::spawn(move || hog(s))
        })
        .collect();
    let bar = |what: &str| {
        eprintln!(
            "vademecum: bench haptic: {what} ({} s, {} wait, {} hog threads)",
            a.seconds, a.wait, a.hog
        )
    };
    let mut phases = Vec::new();

    bar("null loop");
    let (null, rt) = bridge_thread(params.clone(), fifo, || Ok((NullDevice::default(), NullLink::default())))?;
    phases.push(phase("null loop", &null, Duration::ZERO));

    bar("iceoryx2 round trip (echo peer)");
    let channel = HapticChannel::new(&format!("bench-echo-{}", std::process::id()))?;
    let echo_stop = Arc::new(AtomicBool::new(false));
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let echo = {
        let (channel, stop, peer_wait, window) = (channel.clone(), echo_stop.clone(), a.peer_wait, params.window);
        std::thread::Builder::new()
            .name("bench-echo".into())
            .spawn(move || -> anyhow::Result<Duration> {
                let mut peer = HapticPeer::open(&channel, peer_wait, window, period)?;
                timing::request_realtime(fifo.map(|p| p - 10).filter(|_| peer_wait != WaitStrategy::Spin), None);
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
    let (rtt, _) = bridge_thread(params.clone(), fifo, move || {
        Ok((NullDevice::default(), ShmLink::open(&echo_channel)?))
    })?;
    echo_stop.store(true, Ordering::Relaxed);
    let echo_cpu = echo.join().map_err(|_| anyhow::anyhow!("the echo peer panicked"))??;
    phases.push(phase("iceoryx2 round trip", &rtt, echo_cpu));

    bar("full tick (session on the built-in organ)");
    let channel = HapticChannel::new(&format!("bench-full-{}", std::process::id()))?;
    let mut haptic = HapticConfig::new(channel.clone());
    haptic.wait = a.peer_wait;
    haptic.spin_window = params.window;
    haptic.fifo_priority = fifo.map(|p| p - 10);
    let session = Session::start(
        "bench".into(),
        scene.clone(),
        bundles.clone(),
        SessionConfig {
            haptic: Some(haptic),
            ..SessionConfig::default()
        },
    )?;
    let cpu0 = session.stats().tick_cpu_ns.load(Ordering::Relaxed);
    let (full, _) = bridge_thread(params.clone(), fifo, move || {
        Ok((SimStylus::new(hand, HandModel::default()), ShmLink::open(&channel)?))
    })?;
    let tick_cpu = Duration::from_nanos(session.stats().tick_cpu_ns.load(Ordering::Relaxed).saturating_sub(cpu0));
    let _ = session.close();
    phases.push(phase("full tick", &full, tick_cpu));

    hog_stop.store(true, Ordering::Relaxed);
    for h in hogs {
        let _ = h.join();
    }
    let report = Report {
        wait: a.wait.to_string(),
        peer_wait: a.peer_wait.to_string(),
        hog_threads: a.hog,
        seconds: a.seconds,
        bridge_scheduling: rt,
        phases,
    };
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&report)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(
        out,
        "haptic path, {} s per phase at 1 kHz, bridge {} wait, peer {} wait, {} hog threads; bridge: {}",
        report.seconds, report.wait, report.peer_wait, report.hog_threads, report.bridge_scheduling
    )?;
    writeln!(
        out,
        "{:<22} {:>26} {:>34} {:>14} {:>8} {:>13}",
        "phase", "read→write p50/p99 µs", "deadline→write p50/p99/p99.9/max µs", "misses", "fresh %", "CPU br/peer %"
    )?;
    for p in &report.phases {
        writeln!(
            out,
            "{:<22} {:>26} {:>34} {:>14} {:>8.1} {:>13}",
            p.phase,
            format!("{:.1} / {:.1}", p.read_to_write_us.p50, p.read_to_write_us.p99),
            format!(
                "{:.0} / {:.0} / {:.0} / {:.0}",
                p.deadline_to_write_us.p50, p.deadline_to_write_us.p99, p.deadline_to_write_us.p999, p.deadline_to_write_us.max
            ),
            format!("{} ({:.3} %)", p.deadline_misses, p.miss_percent),
            p.fresh_percent,
            format!("{:.0} / {:.0}", p.bridge_cpu_percent, p.peer_cpu_percent),
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
