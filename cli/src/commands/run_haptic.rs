//! `vademecum run --haptic CHANNEL`: a headless session driven by a device bridge over
//! shared memory instead of a script; runs until `--duration` or a signal, then prints what
//! the session and the bridge measured.

use std::io::Write;
use std::path::Path;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use serde::Serialize;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::scene::Scene;
use vademecum_proto::shm::{self, HapticChannel};

use crate::cli::RunArgs;
use vademecum_server::session::stats::Percentiles;
use vademecum_server::session::{BridgeSnapshot, HapticConfig, Session, SessionConfig, tool_channels};

#[derive(Debug, Serialize)]
struct Summary {
    scene: String,
    channel: String,
    wait: String,
    duration_s: f64,
    ticks: u64,
    deadline_misses: u64,
    haptic_answered: u64,
    haptic_skipped: u64,
    rejected_inputs: u64,
    /// Times the live session fell back to its reduced fidelity under load, and the ticks it
    /// ran reduced (their forces carry `reduced_fidelity` in their events).
    fidelity_fallbacks: u64,
    reduced_ticks: u64,
    tick_work_us: Percentiles,
    read_to_answer_us: Percentiles,
    bridge: Option<BridgeSnapshot>,
    /// A scene with several tools: each bridge's report, by the tool it moved (those that
    /// reported).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    bridges: Vec<ToolBridge>,
    /// What the scalpel cut (cutting scenes).
    cut: Option<HapticCut>,
}

/// One bridge of a session with a bridge per tool.
#[derive(Debug, Serialize)]
struct ToolBridge {
    tool: String,
    #[serde(flatten)]
    report: BridgeSnapshot,
}

/// What the cut thread of a cutting session did.
#[derive(Debug, Serialize)]
struct HapticCut {
    cells: u64,
    cracked_nodes: u64,
    blade_states: u64,
    refused: u64,
    overwritten: u64,
    path_mm: f64,
}

/// Runs the session of `scene` for the bridges on `channel`; `hand_scripts` are the run's
/// trajectories written for `vademecum-bridge --device sim --script` (one per hand).
pub fn run(
    a: &RunArgs,
    channel: &str,
    scene: Arc<Scene>,
    bundles: Vec<Arc<LoadedBundle>>,
    record: &Path,
    hand_scripts: &[std::path::PathBuf],
) -> anyhow::Result<ExitCode> {
    let channel = HapticChannel::new(channel)?;
    let duration = match a.duration {
        None => None,
        Some(s) if s.is_finite() && s > 0.0 => Some(Duration::from_secs_f64(s)),
        Some(s) => bail!("--duration must be a positive number of seconds, got {s}"),
    };
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, stop.clone()).context("cannot install the signal handlers")?;
    }
    shm::quiet_iceoryx2_logging();
    let mut haptic = HapticConfig::new(channel.clone());
    if let Some(w) = a.haptic_wait {
        haptic.wait = w;
    }
    haptic.spin_window = Duration::from_micros(a.haptic_spin_us);
    // several hands: the session waits on every bridge's event (a device worker of its own)
    let tools = tool_channels(&channel, &scene)?;
    let wait = if tools.len() > 1 {
        vademecum_bridge::timing::WaitStrategy::Event
    } else {
        haptic.wait
    };
    let config = SessionConfig {
        frame_rate_hz: a.frame_rate,
        haptic: Some(haptic),
        ..SessionConfig::default()
    };
    let session = Session::start("run".into(), scene.clone(), bundles, config)?;
    let rt = session.realtime().map(|r| r.to_string()).unwrap_or_default();
    let channels = match tools.as_slice() {
        [_] => format!("haptic channel '{}'", channel.name()),
        several => format!(
            "haptic channels {} (a bridge per tool: `vademecum-bridge --session {} --tool-name NAME`)",
            several
                .iter()
                .map(|(k, c)| format!("'{}' ({})", c.name(), scene.spec.tools[*k].name()))
                .collect::<Vec<_>>()
                .join(", "),
            channel.name()
        ),
    };
    eprintln!(
        "vademecum: {channels} open ({} wait, tick thread: {rt}); hand script for `vademecum-bridge --device sim`: {}",
        wait,
        hand_scripts.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
    );
    let clock = Instant::now();
    let mut connected = false;
    let mut seen = 0;
    while !stop.load(Ordering::Relaxed) && duration.is_none_or(|d| clock.elapsed() < d) {
        std::thread::sleep(Duration::from_millis(100));
        let n = session.stats().haptic_answered.load(Ordering::Relaxed);
        if (n > seen) != connected {
            connected = n > seen;
            eprintln!(
                "vademecum: bridge {} at {:.1} s",
                if connected { "connected" } else { "silent" },
                clock.elapsed().as_secs_f64()
            );
        }
        seen = n;
    }
    let cut = session.cut_status().map(|c| HapticCut {
        cells: c.cells.load(Ordering::Relaxed),
        cracked_nodes: c.nodes.load(Ordering::Relaxed),
        blade_states: c.steps.load(Ordering::Relaxed),
        refused: c.refused.load(Ordering::Relaxed),
        overwritten: c.overwritten.load(Ordering::Relaxed),
        path_mm: c.path_um.load(Ordering::Relaxed) as f64 * 1e-3,
    });
    let stats = session.close();
    let s = Summary {
        scene: scene.spec.scene.name.clone(),
        channel: channel.name().to_string(),
        wait: wait.to_string(),
        duration_s: clock.elapsed().as_secs_f64(),
        ticks: stats.ticks,
        deadline_misses: stats.misses,
        haptic_answered: stats.haptic_answered,
        haptic_skipped: stats.haptic_skipped,
        rejected_inputs: stats.rejected,
        fidelity_fallbacks: stats.fallbacks,
        reduced_ticks: stats.reduced_ticks,
        tick_work_us: stats.work_us,
        read_to_answer_us: stats.haptic_us,
        bridge: stats.bridge,
        bridges: if tools.len() > 1 {
            stats
                .bridges
                .iter()
                .map(|&(t, report)| ToolBridge {
                    tool: scene.spec.tools[t].name().to_string(),
                    report,
                })
                .collect()
        } else {
            Vec::new()
        },
        cut,
    };
    std::fs::write(record.join("summary.json"), serde_json::to_string_pretty(&s)?)
        .with_context(|| format!("cannot write {}", record.join("summary.json").display()))?;
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&s)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    let p = |x: &Percentiles| {
        format!(
            "p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs",
            x.p50, x.p99, x.p999, x.max
        )
    };
    writeln!(
        out,
        "scene '{}' on haptic channel '{}' ({} wait), {:.1} s",
        s.scene, s.channel, s.wait, s.duration_s
    )?;
    writeln!(
        out,
        "  states answered {} ({} superseded before answering), rejected {}",
        s.haptic_answered, s.haptic_skipped, s.rejected_inputs
    )?;
    writeln!(out, "  device read -> force published   {}", p(&s.read_to_answer_us))?;
    writeln!(out, "  tick work                        {}", p(&s.tick_work_us))?;
    if s.fidelity_fallbacks > 0 {
        writeln!(
            out,
            "  fidelity: fell back {} time(s) under load, {} ticks ({:.1} %) at the reduced setting; set fidelity.fallback = \"off\" for quantitative work",
            s.fidelity_fallbacks,
            s.reduced_ticks,
            100.0 * s.reduced_ticks as f64 / s.ticks.max(1) as f64
        )?;
    }
    if let Some(c) = &s.cut {
        writeln!(
            out,
            "  cut: {} cells, {} cracked nodes, blade path {:.1} mm while cutting ({} blade states, {} refused)",
            c.cells, c.cracked_nodes, c.path_mm, c.blade_states, c.refused
        )?;
    }
    let bridge = |b: &BridgeSnapshot| {
        format!(
            "{} ticks, {} misses, {} fresh forces, read -> written {}",
            b.ticks,
            b.deadline_misses,
            b.fresh_forces,
            p(&b.latency_us)
        )
    };
    if tools.len() > 1 {
        for t in &s.bridges {
            writeln!(out, "  bridge '{}': {}", t.tool, bridge(&t.report))?;
        }
        if s.bridges.len() < tools.len() {
            writeln!(out, "  bridges: {} of {} reported", s.bridges.len(), tools.len())?;
        }
    } else {
        match &s.bridge {
            Some(b) => writeln!(out, "  bridge: {}", bridge(b))?,
            None => writeln!(out, "  bridge: no report received")?,
        }
    }
    Ok(ExitCode::SUCCESS)
}
