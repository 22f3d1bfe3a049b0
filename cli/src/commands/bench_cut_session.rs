//! The session part of `vademecum bench cut`: the tick of the cutting pipeline against the same
//! organ palpated by a scene that does not cut (what a palpation scene pays), the scalpel's tick
//! while the cut thread cuts and once the cut is made, each beside a null loop; and the same cut
//! by the full-order XFEM offline and by the session online, the contact forces side by side.

use std::hint::black_box;
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::time::{Duration, Instant};

use anyhow::Context;
use serde::Serialize;
use vademecum_engine::bundle;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::offline::{self, Built};
use vademecum_engine::pipeline::{Events, Pipeline, ToolInput, ToolKind};
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::schema::ToolSpec;
use vademecum_engine::xfem::{Enrichment, system};

use super::bench_pgd::{Stat, stat, time_n};

/// A contact force of the cut organ, by the session and by the full-order XFEM.
#[derive(Debug, Serialize)]
pub(super) struct ForcePair {
    /// Where the blade pressed (the middle of its edge, m).
    pub point_m: [f64; 3],
    /// The session's force on the tissue (N).
    pub session_n: [f64; 3],
    /// The full XFEM's force for the same imposed displacement at the same patch (N), times the
    /// lattice's stiffening there on an organ that deforms largely.
    pub full_n: [f64; 3],
    /// `|session − full| / |full|`.
    pub relative_difference: f64,
}

/// What the session part measured.
#[derive(Debug, Serialize)]
pub(super) struct SessionReport {
    /// Tick statistics (µs): null loop, palpation scene, scalpel while cutting, after.
    pub ticks: Vec<Stat>,
    /// Cells and cracked nodes the incisions made, and cut models swapped into the tick.
    pub cut_cells: u64,
    pub enriched_nodes: u64,
    pub advances: u64,
    pub forces: Vec<ForcePair>,
}

/// The scene as a palpation scene: cutting off, the scalpel replaced by a probe of the
/// scalpel's contact radius.
fn palpation_variant(scene: &Scene) -> Scene {
    let mut spec = scene.spec.clone();
    spec.effects.cutting = false;
    for t in &mut spec.tools {
        if let ToolSpec::Scalpel { name, blade_length, .. } = t {
            *t = ToolSpec::Probe {
                name: name.clone(),
                radius: vademecum_engine::pipeline::SCALPEL_TIP_FRACTION * *blade_length,
                max_force: vademecum_engine::scene::schema::GLOBAL_FORCE_LIMIT_N,
            };
        }
    }
    Scene { spec, ..scene.clone() }
}

/// Runs the session part on `scene` with its vademecum `built`, timing `n` ticks per row.
pub(super) fn run(scene: &Scene, built: &Built, n: usize, stages: &crate::progress::Stages) -> anyhow::Result<SessionReport> {
    let dir = tempfile::tempdir()?;
    offline::write_bundle(dir.path(), scene, built)?;
    let bundle: Arc<LoadedBundle> = Arc::new(bundle::load_bundle(dir.path())?);
    let cuts = scene.organ_cuts(scene.cut_organ().context("the scene cuts no organ")?)?;
    let points: Vec<&[[f64; 3]]> = cuts.iter().map(|c| c.points()).collect();
    let (blade, _) = scene.spec.scalpel().context("the scene has no scalpel")?;
    let incisions = vademecum_server::session::builtin_incisions(&bundle, &points, 0.5 * blade, 2.0).map_err(anyhow::Error::msg)?;
    let tool = |t: f64| vademecum_server::session::tool_at(&incisions, t);
    // where the blade presses while it draws the first cut: its middle position
    let first = points[0];
    let mid_t = 0.5 + 1.0; // half way through the first cut (after the 0.5 s approach)
    let pressed = tool(mid_t);

    let mut rows = Vec::new();
    rows.push(stat("null loop", time_n(n, || black_box(0.0))));
    // 1. the same organ palpated by a scene that does not cut
    stages.stage("session: the palpation scene's tick");
    let palp_scene = palpation_variant(scene);
    let mut palp = Pipeline::for_scene(&palp_scene, std::slice::from_ref(&bundle))?;
    let probe = ToolInput {
        kind: ToolKind::Probe,
        position_m: pressed.contact_point(),
        ..ToolInput::default()
    };
    palp.tick(&probe);
    rows.push(stat(
        &format!("palpation scene ({}): probe tick, pressed", palp.effect_names().join(" → ")),
        time_n(n, || palp.tick(&probe).force_n[2]),
    ));
    // 2. the cutting scene, uncut, then playing the incisions at 1 kHz with the cut thread
    stages.stage("session: the scalpel's tick");
    let mut cut = Pipeline::for_scene(scene, std::slice::from_ref(&bundle))?;
    let status = cut.cut_status().context("a cutting pipeline")?;
    cut.tick(&pressed);
    rows.push(stat(
        &format!(
            "cutting scene ({}): scalpel tick, pressed, before any cut",
            cut.effect_names().join(" → ")
        ),
        time_n(n, || cut.tick(&pressed).force_n[2]),
    ));
    cut.reset();
    let ticks = (incisions.duration_s() * 1000.0).round() as usize;
    let (mut during, mut advances) = (Vec::with_capacity(ticks), 0u64);
    let start = Instant::now();
    for k in 0..=ticks {
        let input = tool(k as f64 * 1e-3);
        let t = Instant::now();
        let s = cut.tick(&input);
        during.push(t.elapsed().as_secs_f64() * 1e6);
        advances += u64::from(s.events.has(Events::CUT_ADVANCED));
        // keep to the 1 kHz clock, so the cut thread sees the blade as a session would
        let next = start + Duration::from_micros(1000 * (k as u64 + 1));
        if let Some(wait) = next.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
    }
    // a second more at the end, so that the cut thread finishes and the tick takes its last model
    let end = tool(incisions.duration_s());
    for _ in 0..1000 {
        advances += u64::from(cut.tick(&end).events.has(Events::CUT_ADVANCED));
        std::thread::sleep(Duration::from_millis(1));
    }
    rows.push(stat(
        &format!(
            "scalpel tick while cutting (the built-in incisions, {:.1} s, the cut thread beside it)",
            incisions.duration_s()
        ),
        during,
    ));
    cut.reset();
    cut.tick(&pressed);
    let (cells, nodes) = (status.cells.load(Relaxed), status.nodes.load(Relaxed));
    rows.push(stat(
        &format!("scalpel tick, pressed on the cut ({nodes} cracked nodes)"),
        time_n(n, || cut.tick(&pressed).force_n[2]),
    ));

    // 3. the forces, online and offline, where the blade pressed along the first cut
    stages.stage("session: the forces against the full XFEM");
    let model = &built.model;
    let params = scene.spec.fidelity.xfem.params();
    let enr = Enrichment::from_cut_cells(&model.mesh, &status.shape().cells, &params)?;
    let mut forces = Vec::new();
    let n_pos = first.len() / 2;
    let mut at: Vec<usize> = vec![1, n_pos / 2, n_pos.saturating_sub(2)];
    at.dedup();
    for k in at {
        let t = 0.5 + 2.0 * k as f64 / (n_pos - 1) as f64;
        let input = tool(t);
        // the blade brought there along the incision, so that its contact tracks the surface
        cut.reset();
        for ms in 0..(t * 1000.0) as usize {
            cut.tick(&tool(ms as f64 * 1e-3));
        }
        let s = cut.tick(&input);
        let Some(c) = s.contact.filter(|c| (1.0 - c.loadable).abs() < 1e-9) else {
            continue;
        };
        // the full XFEM's compliance at the same patch: three solves with the patch loaded
        let mut comp = [[0.0; 3]; 3];
        for j in 0..3 {
            let mut problem = model.problem.clone();
            problem.forces.iter_mut().for_each(|f| *f = 0.0);
            for (&a, &w) in c.nodes.iter().zip(&c.weights) {
                problem.forces[3 * a + j] += w;
            }
            let sol = system::solve(&model.mesh, &model.materials, model.locking, &problem, &enr, &params)?;
            for (&a, &w) in c.nodes.iter().zip(&c.weights) {
                for i in 0..3 {
                    comp[i][j] += w * sol.u[3 * a + i];
                }
            }
        }
        // on an organ that deforms largely the session scales the cut's linear force by the
        // lattice's stiffening at this contact: the full XFEM's, scaled the same, is its reference
        let r = c.stiffened.map_or(1.0, |s| s.ratio);
        let full = vademecum_engine::pgd::Vademecum::contact_force(&comp, c.imposed_m).map(|f| r * f);
        let diff = (0..3).map(|i| (c.tissue_force_n[i] - full[i]).powi(2)).sum::<f64>().sqrt();
        let norm = full.iter().map(|x| x * x).sum::<f64>().sqrt();
        forces.push(ForcePair {
            point_m: input.contact_point(),
            session_n: c.tissue_force_n,
            full_n: full,
            relative_difference: diff / norm.max(f64::MIN_POSITIVE),
        });
    }
    Ok(SessionReport {
        ticks: rows,
        cut_cells: cells,
        enriched_nodes: nodes,
        advances,
        forces,
    })
}
