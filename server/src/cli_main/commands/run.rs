//! `vademecum run`: a headless session — no network client — playing a scripted tool
//! trajectory at the tick rate, recording forces as CSV and frames as `.pvd`/`.vtu`, and
//! printing a summary (tick latency percentiles, deadline misses, peak force).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::session::stats::Percentiles;
use crate::session::{Answer, Script, Session, SessionConfig, Trajectory};
use anyhow::{Context, bail};
use serde::Serialize;
use vademecum_engine::mesh::vtk::{self, Field};
use vademecum_engine::pipeline::Events;

use crate::cli_main::cli::RunArgs;
use crate::cli_main::commands::build::ensure_bundles;
use crate::cli_main::commands::solve::load_scene;

/// What `vademecum run` reports (also written as `summary.json`).
#[derive(Debug, Serialize)]
struct Summary {
    scene: String,
    organs: Vec<String>,
    effects: Vec<&'static str>,
    trajectory: String,
    duration_s: f64,
    ticks: u64,
    tick_rate_hz: f64,
    deadline_misses: u64,
    miss_rate: f64,
    tick_work_us: Percentiles,
    tick_lateness_us: Percentiles,
    peak_force_n: f64,
    peak_force_time_s: f64,
    contact_ticks: u64,
    rejected_inputs: u64,
    dropped_answers: u64,
    frames: usize,
    record: PathBuf,
}

/// Force log row.
struct Row {
    tick: u64,
    t_s: f64,
    a: Answer,
}

pub fn run(a: RunArgs) -> anyhow::Result<ExitCode> {
    if a.haptic.is_none() && (a.duration.is_some() || a.haptic_wait.is_some()) {
        bail!("--duration and --haptic-wait apply to haptic runs: add --haptic CHANNEL");
    }
    if !(a.frame_rate > 0.0 && a.frame_rate <= 60.0) {
        bail!("--frame-rate must lie in (0, 60] frames per second, got {}", a.frame_rate);
    }
    if !(a.depth > 0.0 && a.depth < 0.05) {
        bail!("--depth must lie in (0, 0.05) m, got {}", a.depth);
    }
    let scene = Arc::new(load_scene(&a.source)?);
    let base = PathBuf::from("out").join(&scene.spec.scene.name);
    let bundle_dir = a.bundles.clone().unwrap_or_else(|| base.clone());
    let record = a.record.clone().unwrap_or_else(|| base.join("run"));
    // a bad trajectory file fails before any build
    let scripted = a.script.as_ref().map(|p| Trajectory::read(p)).transpose()?;
    if scene.spec.effects.cutting {
        bail!(
            "cutting in live sessions is not available yet: `vademecum solve` cuts this scene's pre-planned cuts by the full-order XFEM, and `vademecum bench cut` runs the reduced online model along them (docs/cutting.md)"
        );
    }
    let radius = offline_probe_radius(&scene)?;
    let bundles = ensure_bundles(&scene, &bundle_dir)?;
    let (trajectory, source) = match (scripted, &a.script) {
        (Some(t), Some(p)) => (t, p.display().to_string()),
        _ => (
            crate::session::builtin_palpation(&bundles[0], radius, a.depth, 0.015)
                .map_err(|e| anyhow::anyhow!("cannot script the built-in palpation: {e}"))?,
            format!(
                "built-in palpation of '{}' ({} mm deep, 15 mm slide)",
                scene.spec.organs[0].name,
                a.depth * 1e3
            ),
        ),
    };
    let frames_dir = record.join("frames");
    std::fs::create_dir_all(&frames_dir).with_context(|| format!("cannot create {}", frames_dir.display()))?;
    trajectory
        .write(&record.join("trajectory.csv"))
        .with_context(|| format!("cannot write {}", record.join("trajectory.csv").display()))?;
    if let Some(channel) = &a.haptic {
        return super::run_haptic::run(&a, channel, scene, bundles, &record);
    }

    let config = SessionConfig {
        frame_rate_hz: a.frame_rate,
        ..SessionConfig::default()
    };
    let period_s = config.period.as_secs_f64();
    let (tx, mut rx) = tokio::sync::mpsc::channel::<Answer>(8192);
    let session = Session::start_scripted(
        "run".into(),
        scene.clone(),
        bundles.clone(),
        config,
        Script {
            trajectory: trajectory.clone(),
            answers: tx,
        },
    )?;
    // the force log, written by its own thread as answers arrive
    let forces_path = record.join("forces.csv");
    let writer = std::thread::spawn({
        let path = forces_path.clone();
        move || -> anyhow::Result<(f64, f64, u64)> {
            let mut w = csv::Writer::from_path(&path).with_context(|| format!("cannot write {}", path.display()))?;
            w.write_record([
                "tick",
                "t_s",
                "x_m",
                "y_m",
                "z_m",
                "fx_n",
                "fy_n",
                "fz_n",
                "contact",
                "depth_m",
                "events",
                "latency_us",
            ])?;
            let (mut peak, mut peak_t, mut contacts) = (0.0f64, 0.0f64, 0u64);
            while let Some(a) = rx.blocking_recv() {
                let row = Row {
                    tick: a.tick,
                    t_s: a.tick as f64 * period_s,
                    a,
                };
                let f = row.a.state.force_n;
                let mag = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
                if mag > peak {
                    peak = mag;
                    peak_t = row.t_s;
                }
                let c = row.a.state.contact;
                contacts += u64::from(c.is_some());
                let p = c.map_or([f64::NAN; 3], |c| c.point_m);
                w.write_record(&[
                    row.tick.to_string(),
                    format!("{:.6}", row.t_s),
                    format!("{:e}", p[0]),
                    format!("{:e}", p[1]),
                    format!("{:e}", p[2]),
                    format!("{:e}", f[0]),
                    format!("{:e}", f[1]),
                    format!("{:e}", f[2]),
                    u8::from(row.a.state.events.has(Events::CONTACT)).to_string(),
                    format!("{:e}", c.map_or(0.0, |c| c.depth_m)),
                    row.a.state.events.0.to_string(),
                    (row.a.answered_us - row.a.received_us).to_string(),
                ])?;
            }
            w.flush()?;
            Ok((peak, peak_t, contacts))
        }
    });
    // frames: take the latest at the frame rate, write one surface .vtu per organ
    let geometry = session.geometry().clone();
    let effects = session.effects().to_vec();
    let mut frames_rx = session.subscribe_frames();
    let bar = indicatif::ProgressBar::new((trajectory.duration_s() * 1000.0).round() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} running '{msg}' {bar:30} {pos}/{len} ms")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message(scene.spec.scene.name.clone());
    let clock = Instant::now();
    let interval = Duration::from_secs_f64(1.0 / a.frame_rate);
    let mut steps: Vec<Vec<(f64, String)>> = vec![Vec::new(); geometry.organs.len()];
    let positions: Vec<Vec<[f64; 3]>> = geometry
        .organs
        .iter()
        .map(|o| {
            o.positions_m
                .chunks_exact(3)
                .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64])
                .collect()
        })
        .collect();
    let triangles: Vec<Vec<usize>> = geometry
        .organs
        .iter()
        .map(|o| o.triangles.iter().map(|&i| i as usize).collect())
        .collect();
    while !session.finished() {
        std::thread::sleep(interval);
        bar.set_position((clock.elapsed().as_secs_f64() * 1000.0) as u64);
        if !frames_rx.has_changed().unwrap_or(false) {
            continue;
        }
        let frame = frames_rx.borrow_and_update().clone();
        for (k, o) in geometry.organs.iter().enumerate() {
            let file = format!("{}_{:05}.vtu", o.name, frame.seq);
            let u: Vec<f64> = frame.displacements_m[k].iter().map(|&x| x as f64).collect();
            vtk::write_surface_vtu(
                &frames_dir.join(&file),
                &positions[k],
                &triangles[k],
                &[Field {
                    name: "displacement",
                    components: 3,
                    values: &u,
                }],
            )?;
            steps[k].push((frame.time_s, format!("frames/{file}")));
        }
    }
    bar.finish_and_clear();
    let stats = session.wait();
    let (peak, peak_t, contacts) = writer.join().map_err(|_| anyhow::anyhow!("the force writer panicked"))??;
    for (k, o) in geometry.organs.iter().enumerate() {
        vtk::write_pvd(&record.join(format!("{}.pvd", o.name)), &steps[k])?;
    }
    let summary = Summary {
        scene: scene.spec.scene.name.clone(),
        organs: geometry.organs.iter().map(|o| o.name.clone()).collect(),
        effects,
        trajectory: source,
        duration_s: trajectory.duration_s(),
        ticks: stats.ticks,
        tick_rate_hz: 1.0 / period_s,
        deadline_misses: stats.misses,
        miss_rate: stats.misses as f64 / stats.ticks.max(1) as f64,
        tick_work_us: stats.work_us,
        tick_lateness_us: stats.lateness_us,
        peak_force_n: peak,
        peak_force_time_s: peak_t,
        contact_ticks: contacts,
        rejected_inputs: stats.rejected,
        dropped_answers: stats.dropped,
        frames: steps.first().map_or(0, |s| s.len()),
        record: record.clone(),
    };
    std::fs::write(record.join("summary.json"), serde_json::to_string_pretty(&summary)?)
        .with_context(|| format!("cannot write {}", record.join("summary.json").display()))?;
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&summary)?)?;
    } else {
        let s = &summary;
        writeln!(out, "scene '{}': {} ({})", s.scene, s.organs.join(", "), s.effects.join(" → "))?;
        writeln!(out, "  trajectory     {} — {:.1} s", s.trajectory, s.duration_s)?;
        writeln!(
            out,
            "  ticks          {} at {:.0} Hz; {} deadline misses ({:.2} %)",
            s.ticks,
            s.tick_rate_hz,
            s.deadline_misses,
            100.0 * s.miss_rate
        )?;
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
        writeln!(
            out,
            "  force          peak {:.3} N at {:.3} s; in contact {} of {} ticks",
            s.peak_force_n, s.peak_force_time_s, s.contact_ticks, s.ticks
        )?;
        writeln!(
            out,
            "  recorded       {} (forces.csv, {} frames per organ in *.pvd)",
            s.record.display(),
            s.frames
        )?;
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

fn offline_probe_radius(scene: &vademecum_engine::scene::Scene) -> anyhow::Result<f64> {
    let r = vademecum_engine::pgd::offline::probe_radius(scene);
    if r > 0.0 {
        Ok(r)
    } else {
        bail!("the scene has no probe tool; add a [[tools]] entry with kind = \"probe\"")
    }
}
