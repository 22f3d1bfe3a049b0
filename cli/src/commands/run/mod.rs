//! `vademecum run`: a headless session — no network client — playing a scripted tool
//! trajectory at the tick rate, recording forces as CSV and frames as `.pvd`/`.vtu`, and
//! printing a summary (tick latency percentiles, deadline misses, peak force).
//!
//! A cutting scene plays a scalpel (by default along the scene's pre-planned cuts, one after
//! the other): the force log gains the blade's force split, the summary the cut (its path,
//! cells, cracked nodes), and the recording the organ opened by the session's cut — the
//! full-order XFEM of the cut the session made, under the scene's loads, split along the cut —
//! as the last step of the organ's `.pvd`, with the blade's swept surface beside it. A
//! co-rotational cutting scene adds the visual surface's series and the partial cut's (the
//! swept surface in the cells the blade entered and had not cut yet).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, bail};
use serde::Serialize;
use vademecum_engine::mesh::vtk;
use vademecum_engine::pipeline::MAX_BLADE_EDGE;
use vademecum_server::session::stats::Percentiles;
use vademecum_server::session::{Answer, Hand, Script, Session, SessionConfig, Trajectory};

use super::scene_input::load_scene;
use crate::cli::RunArgs;
use crate::commands::build::ensure_bundles;
use frames::FrameRecorder;
use hands::HandKind;

mod forces;
mod frames;
mod hands;

/// What `vademecum run` reports (also written as `summary.json`).
#[derive(Debug, Serialize)]
struct Summary {
    scene: String,
    organs: Vec<String>,
    effects: Vec<&'static str>,
    trajectory: String,
    /// Each hand of a run of several (one per tool; its rows of `forces.csv` carry its
    /// name); empty for a run of one, whose figures are the run's.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    hands: Vec<HandSummary>,
    duration_s: f64,
    ticks: u64,
    tick_rate_hz: f64,
    deadline_misses: u64,
    miss_rate: f64,
    /// Times the session fell back to its reduced fidelity under load, and the ticks it ran
    /// reduced: always 0, a headless run is deterministic and never falls back (the fields
    /// stay for readers of the summary; `run --haptic`, a live session, reports its own).
    fidelity_fallbacks: u64,
    reduced_ticks: u64,
    tick_work_us: Percentiles,
    tick_lateness_us: Percentiles,
    /// The largest force on a tool (N; with several hands, the largest of theirs) and when.
    peak_force_n: f64,
    peak_force_time_s: f64,
    /// Answers in contact (with several hands, summed over them: each hand is answered
    /// every tick).
    contact_ticks: u64,
    rejected_inputs: u64,
    dropped_answers: u64,
    frames: usize,
    record: PathBuf,
    /// The cut the session made (cutting scenes).
    #[serde(skip_serializing_if = "Option::is_none")]
    cut: Option<CutSummary>,
    /// What the grasper did (tearing scenes).
    #[serde(skip_serializing_if = "Option::is_none")]
    tear: Option<TearSummary>,
    /// The co-rotational deformation and its coupling to the force (co-rotational cutting).
    #[serde(skip_serializing_if = "Option::is_none")]
    corotational: Option<CorotationalSummary>,
    /// The memory the session held of its own, by part (at the end of the run).
    memory: vademecum_server::session::SessionMemory,
}

impl Summary {
    /// The summary as `vademecum run` prints it.
    fn print(&self, out: &mut impl Write) -> std::io::Result<()> {
        let s = self;
        writeln!(out, "scene '{}': {} ({})", s.scene, s.organs.join(", "), s.effects.join(" → "))?;
        if s.hands.is_empty() {
            writeln!(out, "  trajectory     {} — {:.1} s", s.trajectory, s.duration_s)?;
        } else {
            writeln!(out, "  hands          {}, at once — {:.1} s", s.hands.len(), s.duration_s)?;
            for h in &s.hands {
                writeln!(out, "  '{}'  {}", h.tool, h.trajectory)?;
                writeln!(
                    out,
                    "  {:w$}  peak {:.3} N at {:.3} s; in contact {} ticks",
                    "",
                    h.peak_force_n,
                    h.peak_force_time_s,
                    h.contact_ticks,
                    w = h.tool.chars().count() + 2
                )?;
            }
        }
        writeln!(
            out,
            "  ticks          {} at {:.0} Hz; {} deadline misses ({:.2} %)",
            s.ticks,
            s.tick_rate_hz,
            s.deadline_misses,
            100.0 * s.miss_rate
        )?;
        if s.fidelity_fallbacks > 0 {
            writeln!(
                out,
                "  fidelity       fell back {} time(s) under load: {} ticks ({:.1} %) at the reduced setting (fidelity.fallback)",
                s.fidelity_fallbacks,
                s.reduced_ticks,
                100.0 * s.reduced_ticks as f64 / s.ticks.max(1) as f64
            )?;
        }
        let p = |x: &Percentiles| {
            format!(
                "p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs",
                x.p50, x.p99, x.p999, x.max
            )
        };
        writeln!(out, "  tick work      {}", p(&s.tick_work_us))?;
        writeln!(
            out,
            "  tick lateness  {} (the OS wake-up floor; see BENCHMARKS.md)",
            p(&s.tick_lateness_us)
        )?;
        if s.hands.is_empty() {
            writeln!(
                out,
                "  force          peak {:.3} N at {:.3} s; in contact {} of {} ticks",
                s.peak_force_n, s.peak_force_time_s, s.contact_ticks, s.ticks
            )?;
        }
        let parts: Vec<String> = s
            .memory
            .parts
            .iter()
            .map(|(p, b)| format!("{p} {:.2}", *b as f64 / 1048576.0))
            .collect();
        writeln!(
            out,
            "  memory         {:.2} MiB of its own ({} MiB; the bundle's shared data not counted)",
            s.memory.total() as f64 / 1048576.0,
            parts.join(", ")
        )?;
        if let Some(c) = &s.cut {
            writeln!(
                out,
                "  cut            {:.2} mm of blade path cutting: {} cells, {} cracked nodes; {} strokes, {} cutting ticks, {} cuts swapped into the tick",
                c.cut_path_m * 1e3,
                c.cut_cells,
                c.enriched_nodes,
                c.strokes,
                c.cutting_ticks,
                c.advances
            )?;
            if let Some(o) = &c.opened {
                writeln!(
                    out,
                    "  opened         under the scene's loads the cut opens up to {:.3e} m (full-order XFEM, {})",
                    o.max_opening_m,
                    c.opened_vtu.as_ref().map_or(String::new(), |p| p.display().to_string())
                )?;
            }
        }
        if let Some(c) = &s.corotational {
            writeln!(
                out,
                "  co-rotational  {} frames, {:.1} ms mean ({:.1} max); {} factored on the frame thread, {} factors installed, {} rebuilt as the cut grew, {} cuts refused, {} failed; residual {:.1e}",
                c.frames, c.frame_ms_mean, c.frame_ms_max, c.factored, c.installed, c.rebuilt, c.refused_cuts, c.failures, c.residual
            )?;
            writeln!(
                out,
                "  correction     solved at the deformation shown in {} frames: {:.1} conjugate-gradient iterations mean ({} max) from the factor thread's factor, {} not converged (no estimate)",
                c.corrections, c.correction_iterations_mean, c.correction_iterations_max, c.corrections_unconverged
            )?;
            if c.held_pieces > 0 {
                writeln!(
                    out,
                    "  loose pieces   {} cut loose from every support, held where they came loose",
                    c.held_pieces
                )?;
            }
            writeln!(
                out,
                "  coupling       {} ticks with the rotation correction ({} refused); {} landings, each a force step of {:.2e} N mean, {:.2e} N max, blended in: at most {:.2e} N from one tick to the next",
                c.corrected_ticks, c.refused_corrections, c.landings, c.landing_jump_mean_n, c.landing_jump_max_n, c.blend_step_max_n
            )?;
            if let Some(v) = &c.visual_pvd {
                writeln!(out, "  visual mesh    {}", v.display())?;
            }
            if let Some(p) = &c.partial_pvd {
                writeln!(
                    out,
                    "  partial cut    shown in {} frames (the swept surface in cells the blade entered and had not cut yet): {}",
                    c.partial_frames,
                    p.display()
                )?;
            }
        }
        if let Some(t) = &s.tear {
            let at = |x: Option<f64>| x.map_or("never".to_string(), |t| format!("at {t:.3} s"));
            writeln!(
                out,
                "  grasp          taken {}, released {}",
                at(t.grasped_at_s),
                at(t.released_at_s)
            )?;
            match t.torn_at_s {
                Some(ts) => writeln!(
                    out,
                    "  TORN           the tissue under the jaws tore at {ts:.3} s under {:.3} N: the grasp was lost",
                    t.force_at_tear_n.unwrap_or(0.0)
                )?,
                None => writeln!(out, "  torn           no: the tissue held")?,
            }
            writeln!(
                out,
                "  damage         grew in {} ticks; at the end largest {:.3}, {} cells torn, {:.3e} J dissipated",
                t.tearing_ticks, t.max_damage, t.torn_cells, t.dissipated_j
            )?;
        }
        writeln!(
            out,
            "  recorded       {} (forces.csv{}, {} frames per organ in *.pvd{})",
            s.record.display(),
            if s.hands.is_empty() { "" } else { " with a row per hand and tick" },
            s.frames,
            if s.cut.is_some() { "; blade_force.svg" } else { "" }
        )?;
        Ok(())
    }
}

/// One hand of a run of several: its tool and trajectory, and what its rows of the force log
/// saw.
#[derive(Debug, Serialize)]
struct HandSummary {
    tool: String,
    trajectory: String,
    peak_force_n: f64,
    peak_force_time_s: f64,
    contact_ticks: u64,
}

/// What the frame thread's co-rotational deformation did, and how the force followed it.
#[derive(Debug, Serialize)]
struct CorotationalSummary {
    frames: u64,
    /// Frame time (ms): mean and largest.
    frame_ms_mean: f64,
    frame_ms_max: f64,
    /// Frames that factored themselves; factors installed from the factor thread; models
    /// rebuilt as the cut grew; frames that failed.
    factored: u64,
    installed: u64,
    rebuilt: u64,
    /// Cuts the model could not take (it stayed at the last one).
    refused_cuts: u64,
    /// Pieces the cut set loose, held where they came loose by the model's soft foundation.
    held_pieces: u64,
    failures: u64,
    /// The last frame's relative residual.
    residual: f64,
    /// Frames that solved the correction at the deformation shown; the conjugate-gradient
    /// iterations of their slowest column, mean and largest; solves that did not converge.
    corrections: u64,
    correction_iterations_mean: f64,
    correction_iterations_max: u64,
    corrections_unconverged: u64,
    /// Ticks whose force took the rotation correction; corrections refused.
    corrected_ticks: u64,
    refused_corrections: u64,
    /// Corrections that landed during a contact, and the whole force step each would make
    /// (N); the tick blends each in over 32 ticks: the largest step between two ticks (N).
    landings: u64,
    landing_jump_max_n: f64,
    landing_jump_mean_n: f64,
    blend_step_max_n: f64,
    /// The visual surface's series (`None`: the organ has no visual mesh).
    visual_pvd: Option<PathBuf>,
    /// Frames that showed a partial cut (the swept surface in cells the blade entered and had
    /// not cut yet), and their series.
    partial_frames: u64,
    partial_pvd: Option<PathBuf>,
}

/// What a tearing run did: when the jaws took hold, when the tissue tore, when they let go.
#[derive(Debug, Default, Serialize)]
struct TearSummary {
    grasped_at_s: Option<f64>,
    torn_at_s: Option<f64>,
    /// The force on the tool just before the tear (N).
    force_at_tear_n: Option<f64>,
    released_at_s: Option<f64>,
    /// Ticks in which the damage grew.
    tearing_ticks: u64,
    /// At the last frame: the largest cell damage, the torn cells, the energy dissipated.
    max_damage: f64,
    torn_cells: usize,
    dissipated_j: f64,
}

/// What a cutting run cut.
#[derive(Debug, Serialize)]
struct CutSummary {
    /// Length of the blade tip's path while the blade was cutting (m).
    cut_path_m: f64,
    cut_cells: u64,
    enriched_nodes: u64,
    /// Ticks whose in-plane blade force exceeded the scalpel's cut_force.
    cutting_ticks: u64,
    /// Cutting strokes started (EVENT_CUT_STARTED) and cut models swapped into the tick
    /// (EVENT_CUT_ADVANCED).
    strokes: u64,
    advances: u64,
    /// Steps the cut thread could not take (a piece cut loose), and blade states it missed.
    refused_steps: u64,
    missed_blade_states: u64,
    /// The organ opened by this cut, full-order XFEM under the scene's loads.
    opened: Option<super::solve::XfemSummary>,
    /// Files: the opened organ (split mesh) and the blade's swept surface.
    opened_vtu: Option<PathBuf>,
    cut_surface_vtu: Option<PathBuf>,
}

/// How deep the built-in palpation presses without `--depth` (m), unless a large-deformation
/// lattice's paths end sooner ([`palpation_depth`]).
const PALPATION_DEPTH_M: f64 = 0.004;

/// How far the built-in palpation slides (m).
const PALPATION_SLIDE_M: f64 = 0.015;

/// The share of the lattice's reach the default palpation presses to: short of the paths'
/// end, where the law is still a path's and not an extrapolation.
const WITHIN_REACH: f64 = 0.9;

/// The built-in palpation's depth (m) and why, when it is not the user's `--depth`: 4 mm, or
/// [`WITHIN_REACH`] of the depth where the lattice's paths around the slide end when that is
/// shallower (`vademecum_server::session::palpation_reach`).
fn palpation_depth(b: &vademecum_engine::bundle::LoadedBundle, asked: Option<f64>) -> anyhow::Result<(f64, String)> {
    if let Some(d) = asked {
        return Ok((d, String::new()));
    }
    let reach = vademecum_server::session::palpation_reach(b, PALPATION_SLIDE_M)
        .map_err(|e| anyhow::anyhow!("cannot script the built-in palpation: {e}"))?;
    Ok(match reach {
        Some(r) if WITHIN_REACH * r < PALPATION_DEPTH_M => (
            WITHIN_REACH * r,
            format!(
                ": {:.0} % of the {:.3} mm where the large-deformation lattice's paths around the slide end; --depth presses deeper",
                100.0 * WITHIN_REACH,
                r * 1e3
            ),
        ),
        _ => (PALPATION_DEPTH_M, String::new()),
    })
}

pub fn run(a: RunArgs) -> anyhow::Result<ExitCode> {
    check_arguments(&a)?;
    let scene = Arc::new(load_scene(&a.source)?);
    let base = PathBuf::from("out").join(&scene.spec.scene.name);
    let bundle_dir = a.bundles.clone().unwrap_or_else(|| base.clone());
    let record = a.record.clone().unwrap_or_else(|| base.join("run"));
    // a bad trajectory file fails before any build
    let scripted = hands::scripted(&scene, &a.script)?;
    let cutting = scene.spec.effects.cutting;
    if cutting {
        if scripted.is_empty() {
            check_blade(&scene, None)?;
        }
        for h in scripted.iter().filter(|h| h.kind(&scene, cutting, false) == HandKind::Scalpel) {
            check_blade(&scene, Some(&h.trajectory))?;
        }
    }
    let tearing = scene.spec.effects.tearing;
    let radius = if cutting || tearing || !scripted.is_empty() {
        0.0
    } else {
        offline_probe_radius(&scene)?
    };
    let bundles = ensure_bundles(&scene, &bundle_dir)?;
    let hands = if scripted.is_empty() {
        hands::builtin(&scene, &bundles, radius, a.depth)?
    } else {
        scripted
    };
    let several = hands.len() > 1;
    let duration_s = hands::duration_s(&hands);
    let frames_dir = record.join("frames");
    std::fs::create_dir_all(&frames_dir).with_context(|| format!("cannot create {}", frames_dir.display()))?;
    let mut hand_scripts = Vec::with_capacity(hands.len());
    for h in &hands {
        let file = h.script_file(&record, several);
        h.trajectory
            .write(&file)
            .with_context(|| format!("cannot write {}", file.display()))?;
        hand_scripts.push(file);
    }
    if let Some(channel) = &a.haptic {
        return super::run_haptic::run(&a, channel, scene, bundles, &record, &hand_scripts);
    }

    // a lab operator's headless run gives the same recording on any load
    let config = SessionConfig {
        frame_rate_hz: a.frame_rate,
        deterministic: true,
        ..SessionConfig::default()
    };
    let period_s = config.period.as_secs_f64();
    let mut script = Script { hands: Vec::new() };
    let mut logged = Vec::with_capacity(hands.len());
    for h in &hands {
        let (tx, rx) = tokio::sync::mpsc::channel::<Answer>(8192);
        let kind = h.kind(&scene, cutting, tearing);
        logged.push(forces::LoggedHand {
            answers: rx,
            tool: h.name.clone(),
            cutting: kind == HandKind::Scalpel && cutting,
            jaws: (kind == HandKind::Grasper && tearing).then(|| h.trajectory.clone()),
        });
        script.hands.push(Hand {
            tool: h.tool,
            trajectory: h.trajectory.clone(),
            answers: tx,
        });
    }
    // the force log, written by its own thread as answers arrive
    let writer = forces::spawn(record.join("forces.csv"), logged, period_s);
    let session = Session::start_scripted("run".into(), scene.clone(), bundles.clone(), config, script)?;
    let cut_status = session.cut_status().cloned();
    let cutting = cut_status.is_some();
    // frames: every frame of the session's log, one surface .vtu per organ
    let geometry = session.geometry().clone();
    let effects = session.effects().to_vec();
    let mut frames = FrameRecorder::new(&geometry, frames_dir);
    record_frames(&session, &mut frames, &scene.spec.scene.name, duration_s, a.frame_rate)?;
    let session_stats = session.stats().clone();
    let memory = session.memory();
    let stats = session.wait();
    let logs = writer.join().map_err(|_| anyhow::anyhow!("the force writer panicked"))??;
    let mut hand_summaries = Vec::with_capacity(hands.len());
    let mut forces = forces::ForceLog::default();
    for (h, log) in hands.iter().zip(logs) {
        hand_summaries.push(HandSummary {
            tool: h.name.clone(),
            trajectory: h.source.clone(),
            peak_force_n: log.peak_n,
            peak_force_time_s: log.peak_t_s,
            contact_ticks: log.contact_ticks,
        });
        if several {
            forces.merge(log, h.kind(&scene, cutting, tearing));
        } else {
            forces = log;
        }
    }
    let mut tear = forces.tear;
    if let Some((max_damage, torn_cells, dissipated_j)) = frames.last_damage {
        (tear.max_damage, tear.torn_cells, tear.dissipated_j) = (max_damage, torn_cells, dissipated_j);
    }
    let tear = tearing.then_some(tear);
    if let Some((_, cut_force)) = scene.spec.scalpel().filter(|_| cutting) {
        plot_blade(
            &record.join("blade_force.svg"),
            &scene.spec.scene.name,
            &forces.blade_rows,
            cut_force,
        )?;
    }
    let cut = match &cut_status {
        Some(status) => Some(record_cut(
            &scene,
            status,
            forces.cut_counts,
            &record,
            &mut frames.steps[0],
            duration_s,
        )?),
        None => None,
    };
    frames.write_series(&record)?;
    let corotational = (scene.spec.fidelity.cutting == vademecum_engine::scene::schema::CuttingModel::CorotationalXfem && cutting)
        .then(|| -> anyhow::Result<CorotationalSummary> {
            let (visual_pvd, partial_pvd) = frames.write_cut_series(&record)?;
            let mut summary = corotational_summary(&session_stats, cut_status.as_deref(), visual_pvd);
            (summary.partial_frames, summary.partial_pvd) = (frames.partial_frames, partial_pvd);
            Ok(summary)
        })
        .transpose()?;
    let summary = Summary {
        scene: scene.spec.scene.name.clone(),
        organs: geometry.organs.iter().map(|o| o.name.clone()).collect(),
        effects,
        trajectory: hands.iter().map(|h| h.source.as_str()).collect::<Vec<_>>().join("; "),
        hands: if several { hand_summaries } else { Vec::new() },
        duration_s,
        ticks: stats.ticks,
        tick_rate_hz: 1.0 / period_s,
        deadline_misses: stats.misses,
        miss_rate: stats.misses as f64 / stats.ticks.max(1) as f64,
        fidelity_fallbacks: stats.fallbacks,
        reduced_ticks: stats.reduced_ticks,
        tick_work_us: stats.work_us,
        tick_lateness_us: stats.lateness_us,
        peak_force_n: forces.peak_n,
        peak_force_time_s: forces.peak_t_s,
        contact_ticks: forces.contact_ticks,
        rejected_inputs: stats.rejected,
        dropped_answers: stats.dropped,
        frames: frames.steps.first().map_or(0, |s| s.len()),
        record: record.clone(),
        cut,
        tear,
        corotational,
        memory,
    };
    std::fs::write(record.join("summary.json"), serde_json::to_string_pretty(&summary)?)
        .with_context(|| format!("cannot write {}", record.join("summary.json").display()))?;
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&summary)?)?;
    } else {
        summary.print(&mut out)?;
    }
    if summary.dropped_answers > 0 {
        eprintln!(
            "vademecum: warning: {} force rows were dropped (the writer fell behind)",
            summary.dropped_answers
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// Writes every frame of the headless `session`'s log with `frames` as the session plays
/// (`duration_s` of trajectory, frames at `frame_rate`), with a progress bar.
fn record_frames(session: &Session, frames: &mut FrameRecorder, scene_name: &str, duration_s: f64, frame_rate: f64) -> anyhow::Result<()> {
    let bar = indicatif::ProgressBar::new((duration_s * 1000.0).round() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} running '{msg}' {bar:30} {pos}/{len} ms")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message(scene_name.to_string());
    let interval = Duration::from_secs_f64(1.0 / frame_rate);
    let session_stats = session.stats();
    let period_s = session.config().period.as_secs_f64();
    // the recorder is no real-time work: it yields the cores to the tick thread; it writes
    // every frame of the deterministic session (whose tick waits for it when it falls
    // FRAME_LOG frames behind)
    vademecum_engine::pipeline::lower_thread_priority();
    let log = session
        .take_frame_log()
        .ok_or_else(|| anyhow::anyhow!("the headless session keeps no frame log"))?;
    let period_ms = period_s * 1e3;
    loop {
        let frame = match log.recv_timeout(interval) {
            Ok(frame) => frame,
            // every frame is in the log once the tick loop has ended (it waited for each)
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) if session.finished() => match log.try_recv() {
                Ok(frame) => frame,
                Err(_) => break,
            },
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                bar.set_position((session_stats.steps.load(std::sync::atomic::Ordering::Relaxed) as f64 * period_ms) as u64);
                continue;
            }
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
        };
        bar.set_position((frame.tick as f64 * period_ms) as u64);
        frames.write(&frame)?;
    }
    bar.finish_and_clear();
    Ok(())
}

/// Refuses arguments out of their range, or meant for a haptic run, before anything is built.
fn check_arguments(a: &RunArgs) -> anyhow::Result<()> {
    if a.haptic.is_none() && (a.duration.is_some() || a.haptic_wait.is_some()) {
        bail!("--duration and --haptic-wait apply to haptic runs: add --haptic CHANNEL");
    }
    if !(a.frame_rate > 0.0 && a.frame_rate <= 60.0) {
        bail!("--frame-rate must lie in (0, 60] frames per second, got {}", a.frame_rate);
    }
    if let Some(d) = a.depth
        && !(d > 0.0 && d < 0.05)
    {
        bail!("--depth must lie in (0, 0.05) m, got {d}");
    }
    Ok(())
}

/// A cutting scene's blade, checked before any build: a scripted trajectory that a scene
/// without a probe needs a blade in, and a blade edge the session would reject at every tick,
/// each refused saying what to change.
fn check_blade(scene: &vademecum_engine::scene::Scene, scripted: Option<&Trajectory>) -> anyhow::Result<()> {
    if let Some(t) = scripted
        && !t.has_blade()
        && vademecum_engine::offline::probe_radius(scene) <= 0.0
    {
        bail!(
            "the scene cuts and has no probe, but the trajectory has no blade: add the columns bx_m,by_m,bz_m,qw,qx,qy,qz (the other end of the blade's edge and its orientation; see `vademecum run --help`)"
        );
    }
    // a blade edge the session would reject at every tick fails before any build, saying
    // what to change
    if let Some((blade_length, _)) = scene.spec.scalpel() {
        let longest = match scripted {
            Some(t) => t.longest_blade().map(|(t, e)| (format!("at t = {t:.3} s of the script"), e)),
            None => scene
                .planned_cuts()
                .map_err(|e| anyhow::anyhow!("{e}"))?
                .iter()
                .enumerate()
                .flat_map(|(c, cut)| {
                    cut.points()
                        .chunks_exact(2)
                        .map(move |ab| (c, (0..3).map(|k| (ab[1][k] - ab[0][k]).powi(2)).sum::<f64>().sqrt()))
                })
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(c, e)| (format!("in the scene's pre-planned cut {c}"), e)),
        };
        if let Some((at, edge)) = longest
            && edge > MAX_BLADE_EDGE * blade_length
        {
            bail!(
                "the blade's edge is {:.1} mm long {at}, but the scalpel's blade_length is {:.1} mm and a session accepts edges up to {MAX_BLADE_EDGE} blade lengths: lengthen the scalpel's blade_length or shorten the edge",
                edge * 1e3,
                blade_length * 1e3
            );
        }
    }
    Ok(())
}

/// The built-in trajectory of a scene without a script (one hand), and what it is: incisions
/// along the scene's pre-planned cuts (cutting), a grasp and pull (tearing), or a palpation
/// `radius` off the surface to `depth` (`None`: the default, or the lattice's reach).
fn builtin_trajectory(
    scene: &vademecum_engine::scene::Scene,
    bundles: &[Arc<vademecum_engine::bundle::LoadedBundle>],
    radius: f64,
    depth: Option<f64>,
) -> anyhow::Result<(Trajectory, String)> {
    if scene.cut_organ().is_some() {
        builtin_incisions(scene, bundles)
    } else if scene.spec.effects.tearing {
        builtin_grasp(scene)
    } else {
        builtin_palpation(scene, bundles, 0, radius, depth)
    }
}

/// The built-in palpation of organ `organ` by a probe of tip `radius` (its trajectory and
/// description): pressed `depth` in (`None`: the default, or the lattice's reach), slid, lifted.
fn builtin_palpation(
    scene: &vademecum_engine::scene::Scene,
    bundles: &[Arc<vademecum_engine::bundle::LoadedBundle>],
    organ: usize,
    radius: f64,
    depth: Option<f64>,
) -> anyhow::Result<(Trajectory, String)> {
    let (depth, why) = palpation_depth(&bundles[organ], depth)?;
    Ok((
        vademecum_server::session::builtin_palpation(&bundles[organ], radius, depth, PALPATION_SLIDE_M)
            .map_err(|e| anyhow::anyhow!("cannot script the built-in palpation: {e}"))?,
        format!(
            "built-in palpation of '{}' ({:.3} mm deep{why}, {:.0} mm slide)",
            scene.spec.organs[organ].name,
            depth * 1e3,
            PALPATION_SLIDE_M * 1e3
        ),
    ))
}

/// The built-in incisions of a cutting scene (its trajectory and description): the scalpel
/// along each of the cut organ's pre-planned cuts in turn, [`INCISION_SECONDS`] each.
fn builtin_incisions(
    scene: &vademecum_engine::scene::Scene,
    bundles: &[Arc<vademecum_engine::bundle::LoadedBundle>],
) -> anyhow::Result<(Trajectory, String)> {
    let o = scene.cut_organ().ok_or_else(|| anyhow::anyhow!("the scene does not cut"))?;
    let cuts = scene.organ_cuts(o).map_err(|e| anyhow::anyhow!("{e}"))?;
    if cuts.is_empty() {
        bail!("the scene cuts but plans no cut to script: give a scalpel trajectory with --script, or add [[organs.cuts]] blade positions");
    }
    let points: Vec<&[[f64; 3]]> = cuts.iter().map(|c| c.points()).collect();
    // a cutting scene has a scalpel (scene validation)
    let lift = 0.5 * scene.spec.scalpel().map_or(1e-3, |s| s.0);
    Ok((
        vademecum_server::session::builtin_incisions(&bundles[o], &points, lift, INCISION_SECONDS)
            .map_err(|e| anyhow::anyhow!("cannot script the built-in incisions: {e}"))?,
        format!(
            "built-in incisions of '{}' along its {} pre-planned cut(s), {INCISION_SECONDS} s each",
            scene.spec.organs[o].name,
            cuts.len()
        ),
    ))
}

/// The force on the blade at one scalpel tick, for the plot.
struct BladeRow {
    t_s: f64,
    parallel_n: f64,
    perpendicular_n: f64,
    /// A new cut reached the tick.
    advanced: bool,
}

/// `blade_force.svg`: `|F∥|` and `|F⊥|` on the blade against time, the scalpel's `cut_force`,
/// and the ticks where a new cut reached the tick.
fn plot_blade(file: &std::path::Path, scene: &str, rows: &[BladeRow], cut_force: f64) -> anyhow::Result<()> {
    use plotters::prelude::*;
    let t_max = rows.last().map_or(1.0, |r| r.t_s).max(1e-3);
    let f_max = rows.iter().map(|r| r.parallel_n.max(r.perpendicular_n)).fold(cut_force, f64::max) * 1.1;
    let root = crate::plot::canvas(file, (900, 500))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{scene}: the force on the blade"), ("sans-serif", 18))
        .margin(14)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_max, 0.0..f_max)?;
    chart.configure_mesh().x_desc("time (s)").y_desc("force (N)").draw()?;
    let palette = super::bench_anm::PALETTE;
    let series: [(&str, fn(&BladeRow) -> f64); 2] = [
        ("|F∥|, in the blade's plane", |r| r.parallel_n),
        ("|F⊥|, on the blade's flat", |r| r.perpendicular_n),
    ];
    for ((label, value), colour) in series.into_iter().zip(palette) {
        chart
            .draw_series(LineSeries::new(rows.iter().map(|r| (r.t_s, value(r))), colour.stroke_width(2)))?
            .label(label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], colour.stroke_width(2)));
    }
    chart
        .draw_series(LineSeries::new([(0.0, cut_force), (t_max, cut_force)], BLACK.stroke_width(1)))?
        .label("cut_force")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], BLACK.stroke_width(1)));
    chart
        .draw_series(
            rows.iter()
                .filter(|r| r.advanced)
                .map(|r| Circle::new((r.t_s, r.parallel_n), 4, palette[2].filled())),
        )?
        .label("a new cut reaches the tick")
        .legend(move |(x, y)| Circle::new((x + 9, y), 4, palette[2].filled()));
    crate::plot::legend(&mut chart, SeriesLabelPosition::MiddleRight)?;
    root.present()?;
    Ok(())
}

/// The co-rotational part of a run's summary, from the session's counters.
fn corotational_summary(
    stats: &vademecum_server::session::stats::TickStats,
    cut: Option<&vademecum_engine::pipeline::cutting::CutStatus>,
    visual_pvd: Option<PathBuf>,
) -> CorotationalSummary {
    use std::sync::atomic::Ordering::Relaxed;
    let c = &stats.corotational;
    let frames = c.frames.load(Relaxed);
    let counter =
        |f: fn(&vademecum_engine::pipeline::cutting::CutStatus) -> &std::sync::atomic::AtomicU64| cut.map_or(0, |s| f(s).load(Relaxed));
    let landings = counter(|s| &s.landings);
    CorotationalSummary {
        frames,
        frame_ms_mean: c.sum_us.load(Relaxed) as f64 * 1e-3 / frames.max(1) as f64,
        frame_ms_max: c.max_us.load(Relaxed) as f64 * 1e-3,
        factored: c.factored.load(Relaxed),
        installed: c.installed.load(Relaxed),
        rebuilt: c.rebuilt.load(Relaxed),
        refused_cuts: c.refused_cuts.load(Relaxed),
        held_pieces: c.held_pieces.load(Relaxed),
        failures: stats.corotational_failures.load(Relaxed),
        residual: f64::from_bits(c.residual_bits.load(Relaxed)),
        corrections: c.corrections.load(Relaxed),
        correction_iterations_mean: c.correction_iterations_sum.load(Relaxed) as f64 / c.corrections.load(Relaxed).max(1) as f64,
        correction_iterations_max: c.correction_iterations_max.load(Relaxed),
        corrections_unconverged: c.corrections_unconverged.load(Relaxed),
        corrected_ticks: counter(|s| &s.corrected_ticks),
        refused_corrections: counter(|s| &s.refused_corrections),
        landings,
        landing_jump_max_n: counter(|s| &s.landing_jump_max_un) as f64 * 1e-6,
        landing_jump_mean_n: counter(|s| &s.landing_jump_sum_un) as f64 * 1e-6 / landings.max(1) as f64,
        blend_step_max_n: counter(|s| &s.blend_step_max_un) as f64 * 1e-6,
        visual_pvd,
        partial_frames: 0,
        partial_pvd: None,
    }
}

/// How long the built-in incisions take to draw each pre-planned cut (s).
const INCISION_SECONDS: f64 = 2.0;

/// The cut a session made, recorded: the organ opened by it (full-order XFEM of the same cut
/// cells under the scene's loads, split along the cut) as the last step of the organ's
/// `.pvd` (at `end_s`), and the blade's swept surface as its own `.vtu`.
fn record_cut(
    scene: &vademecum_engine::scene::Scene,
    status: &vademecum_engine::pipeline::cutting::CutStatus,
    counts: [u64; 3],
    record: &std::path::Path,
    steps: &mut Vec<(f64, String)>,
    end_s: f64,
) -> anyhow::Result<CutSummary> {
    use std::sync::atomic::Ordering::Relaxed;
    use vademecum_engine::xfem::Enrichment;
    let shape = status.shape();
    let mut summary = CutSummary {
        cut_path_m: status.path_um.load(Relaxed) as f64 * 1e-6,
        cut_cells: status.cells.load(Relaxed),
        enriched_nodes: status.nodes.load(Relaxed),
        cutting_ticks: counts[0],
        strokes: counts[1],
        advances: counts[2],
        refused_steps: status.refused.load(Relaxed),
        missed_blade_states: status.overwritten.load(Relaxed),
        opened: None,
        opened_vtu: None,
        cut_surface_vtu: None,
    };
    if shape.cells.is_empty() {
        return Ok(summary);
    }
    let model = scene.organ_model(scene.cut_organ().unwrap_or(0))?;
    let name = model.name.clone();
    let params = scene.spec.fidelity.xfem.params();
    let enr = Enrichment::from_cut_cells(&model.mesh, &shape.cells, &params)?;
    let file = record.join("frames").join(format!("{name}_cut.vtu"));
    let progress = crate::progress::Stages::start("recording the cut");
    let opened = super::solve::solve_enriched(scene, &model, &enr, 1, &file, &progress)?;
    progress.finish();
    steps.push((
        end_s.max(steps.last().map_or(0.0, |s| s.0)) + 1e-3,
        format!("frames/{name}_cut.vtu"),
    ));
    let points: Vec<[f64; 3]> = shape.triangles.iter().flatten().copied().collect();
    let triangles: Vec<usize> = (0..points.len()).collect();
    let surface = record.join(format!("{name}_cut_surface.vtu"));
    vtk::write_surface_vtu(&surface, &points, &triangles, &[], &[])?;
    summary.opened = opened.xfem;
    summary.opened_vtu = Some(opened.output);
    summary.cut_surface_vtu = Some(surface);
    Ok(summary)
}

/// The built-in grasp of a tearing scene (its trajectory and description): the jaws close on
/// the scene's grasp and pull along its load by 1.5 times what the explicit reference's
/// schedule moves the grasp, in 3 s.
fn builtin_grasp(scene: &vademecum_engine::scene::Scene) -> anyhow::Result<(vademecum_server::session::Trajectory, String)> {
    use vademecum_engine::damage::reference;
    use vademecum_engine::scene::tearing;
    let i = tearing::tearable_organ(scene).ok_or_else(|| anyhow::anyhow!("the scene tears but no material has damage"))?;
    let (model, _) = tearing::tear_model(scene, i)?;
    let (_, centre, r) = model
        .grasp()
        .ok_or_else(|| anyhow::anyhow!("the tearable organ has no load to grasp by: add an [[organs.loads]] entry"))?;
    let run = reference::run(
        &model,
        reference::RunSettings::seed(reference::Scheme::Explicit(reference::Tangent::Secant)),
        |_, _| {},
    )?;
    let rn = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    let last = run.steps.last().map(|s| s.u.clone()).unwrap_or_default();
    let w = model.load.iter().zip(&last).map(|(f, u)| f * u).sum::<f64>() / rn;
    // within the session's workspace (the organ's box grown by WORKSPACE_MARGIN_M)
    let pull = (1.5 * w.abs().max(1e-4)).min(0.8 * vademecum_engine::pipeline::WORKSPACE_MARGIN_M);
    let t = vademecum_server::session::builtin_grasp(centre, r, pull, 3.0)
        .map_err(|e| anyhow::anyhow!("cannot script the built-in grasp: {e}"))?;
    Ok((
        t,
        format!(
            "built-in grasp of '{}': close on its grasp, pull {:.1} mm along its load in 3 s, hold, open",
            scene.spec.organs[i].name,
            pull * 1e3
        ),
    ))
}

fn offline_probe_radius(scene: &vademecum_engine::scene::Scene) -> anyhow::Result<f64> {
    let r = vademecum_engine::offline::probe_radius(scene);
    if r > 0.0 {
        Ok(r)
    } else {
        bail!("the scene has no probe tool; add a [[tools]] entry with kind = \"probe\"")
    }
}
