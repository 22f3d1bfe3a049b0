//! `vademecum study`: what accuracy costs for a scene's PGD vademecum. One build at a tight
//! tolerance measures the error of every prefix of the modes against the exact parametric
//! solution (the build's blocked exact pass); each prefix, stored in f32 or quantised to i16,
//! is then a fidelity point whose online cost (the surface displacement field of one frame,
//! beside a null loop) and offline cost (bundle bytes at that prefix, the build time) are
//! measured. Writes the table (CSV, JSON), two plots with the Pareto front marked, and a
//! verdict. Then the per-answer error estimate is checked against the full model
//! ([`super::study_estimate`]): the study fails (exit 1) when it bounds fewer than 95 % of the
//! sampled states. Resumable: the build, every finished point and the estimate's check are
//! kept in the output folder and not redone.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use serde::{Deserialize, Serialize};
use vademecum_engine::bundle;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pgd::vademecum::{NodeMajorField, QuantizedField};
use vademecum_engine::scene::Scene;

use super::bench_pgd::{stat, time_n};
use super::frame_cost::Frames;
use super::scene_input::load_scene;
use super::study_report::{Group, pareto, scatter};
use crate::cli::StudyArgs;
use crate::commands::build::build_with_progress;

/// What the study keeps of its build (`build.json`).
#[derive(Debug, Serialize, Deserialize, PartialEq)]
struct BuildRecord {
    /// FNV-1a of the scene's TOML and the study's tolerance: a different scene rebuilds.
    key: String,
    organ: String,
    tolerance: f64,
    build_s: f64,
    modes: usize,
    load_states: usize,
    /// `(modes, relative L2 error over all load states)`, as the build measured it.
    error_curve: Vec<(usize, f64)>,
    /// Bundle bytes that do not grow with the modes, and bytes per mode.
    fixed_bytes: u64,
    bytes_per_mode: f64,
}

/// One fidelity point (`points.jsonl`, one per line).
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Point {
    storage: String,
    modes: usize,
    /// Relative L2 error of the displacement field over all load states (i16: plus the
    /// measured quantisation error, an upper bound by the triangle inequality).
    field_error: f64,
    /// The contact force comes from the exact local compliances: no mode enters it.
    force_error: f64,
    frame_p50_us: f64,
    frame_p99_us: f64,
    null_p50_us: f64,
    field_bytes: usize,
    bundle_bytes: u64,
    #[serde(default)]
    front_online: bool,
    #[serde(default)]
    front_offline: bool,
}

fn fnv(text: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

fn file_bytes(path: &Path) -> u64 {
    std::fs::metadata(path).map_or(0, |m| m.len())
}

/// Builds (or reuses) the vademecum at the study's tolerance.
fn build(a: &StudyArgs, scene: &Scene, out: &Path) -> anyhow::Result<(BuildRecord, LoadedBundle)> {
    let text = serde_json::to_string(&scene.spec).context("serialising the scene")?;
    let key = fnv(&format!("{text}\n{}", a.tolerance));
    let record_path = out.join("build.json");
    let bundle_dir = out.join("bundle");
    if let Ok(old) = std::fs::read_to_string(&record_path)
        && let Ok(rec) = serde_json::from_str::<BuildRecord>(&old)
        && rec.key == key
        && let Ok(b) = bundle::load_bundle(&bundle_dir)
    {
        eprintln!("resuming: the study's build in {} is reused", out.display());
        return Ok((rec, b));
    }
    let opts = BuildOptions {
        tolerance: a.tolerance,
        ..BuildOptions::for_scene(scene, true)
    };
    let start = Instant::now();
    let (built, bar) = build_with_progress(scene, 0, &opts)?;
    bar.stage("writing bundle");
    offline::write_bundle(&bundle_dir, scene, &built).with_context(|| format!("cannot write {}", bundle_dir.display()))?;
    bar.finish();
    let build_s = start.elapsed().as_secs_f64();
    let r = &built.report;
    let mode_bytes = file_bytes(&bundle_dir.join("F.npy")) + file_bytes(&bundle_dir.join("G.npy"));
    let total = super::bench_effects::dir_bytes(&bundle_dir)?;
    let rec = BuildRecord {
        key,
        organ: r.organ.clone(),
        tolerance: a.tolerance,
        build_s,
        modes: r.modes,
        load_states: r.load_states,
        error_curve: r.error_curve.iter().copied().filter(|&(k, _)| k <= r.modes).collect(),
        fixed_bytes: total - mode_bytes,
        bytes_per_mode: mode_bytes as f64 / r.modes.max(1) as f64,
    };
    std::fs::write(&record_path, serde_json::to_string_pretty(&rec)?)?;
    // points measured on another build are stale
    let _ = std::fs::remove_file(out.join("points.jsonl"));
    Ok((rec, bundle::load_bundle(&bundle_dir)?))
}

/// Measures one point: the surface field of a frame at `modes` modes in `storage`.
fn measure(b: &LoadedBundle, rec: &BuildRecord, frames: &Frames, storage: &str, modes: usize, error: f64, repeat: usize) -> Point {
    let v = &b.vademecum;
    let (nodes, coeffs) = (&frames.nodes, &frames.coeffs);
    let f32_field = NodeMajorField::from_mode_major(v.f_raw(), v.n_nodes(), modes, nodes);
    let mut out = vec![0.0f32; 3 * nodes.len()];
    let mut i = 0;
    let (times, bytes, quant) = if storage == "i16" {
        let q = QuantizedField::new(v, nodes, modes);
        let mut scaled = vec![0.0f32; modes];
        // the quantisation's own error, on the same contacts
        let mut exact = vec![0.0f32; out.len()];
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for c in coeffs {
            f32_field.eval(&c[..modes], &mut exact);
            q.eval(&c[..modes], &mut scaled, &mut out);
            num += exact.iter().zip(&out).map(|(a, b)| ((a - b) as f64).powi(2)).sum::<f64>();
            den += exact.iter().map(|a| (*a as f64).powi(2)).sum::<f64>();
        }
        let t = time_n(repeat, || {
            i = (i + 1) % coeffs.len();
            q.eval(&coeffs[i][..modes], &mut scaled, &mut out);
            out[0] as f64
        });
        (t, q.bytes(), if den > 0.0 { (num / den).sqrt() } else { 0.0 })
    } else {
        let t = time_n(repeat, || {
            i = (i + 1) % coeffs.len();
            f32_field.eval(&coeffs[i][..modes], &mut out);
            out[0] as f64
        });
        (t, f32_field.bytes(), 0.0)
    };
    let (frame, null) = (stat("frame", times), stat("null", time_n(repeat, || 0.0)));
    let per_mode = if storage == "i16" { 0.5 } else { 1.0 };
    Point {
        storage: storage.into(),
        modes,
        field_error: error + quant,
        force_error: 0.0,
        frame_p50_us: frame.p50_us,
        frame_p99_us: frame.p99_us,
        null_p50_us: null.p50_us,
        field_bytes: bytes,
        bundle_bytes: rec.fixed_bytes + (per_mode * rec.bytes_per_mode * modes as f64) as u64,
        front_online: false,
        front_offline: false,
    }
}

/// Field error against `cost`, one colour per storage, the `front` points joined.
fn plot(
    points: &[Point],
    cost: fn(&Point) -> f64,
    front: fn(&Point) -> bool,
    x_desc: &str,
    title: &str,
    file: &Path,
) -> anyhow::Result<()> {
    let err = |p: &Point| p.field_error.max(1e-16);
    let groups: Vec<Group> = ["f32", "i16"]
        .into_iter()
        .map(|storage| Group {
            label: format!("modes stored in {storage}"),
            triangles: false,
            points: points
                .iter()
                .filter(|p| p.storage == storage)
                .map(|p| (cost(p), err(p), String::new()))
                .collect(),
        })
        .collect();
    let f = points.iter().filter(|p| front(p)).map(|p| (cost(p), err(p))).collect();
    scatter(file, title, (x_desc, "relative L2 error of the displacement field"), &groups, f)
}

/// The PGD's points as `study.csv`.
fn points_csv(points: &[Point]) -> String {
    let mut csv = String::from(
        "storage,modes,field_error,force_error,frame_p50_us,frame_p99_us,null_p50_us,field_bytes,bundle_bytes,front_online,front_offline\n",
    );
    for p in points {
        csv += &format!(
            "{},{},{:e},{},{:.3},{:.3},{:.3},{},{},{},{}\n",
            p.storage,
            p.modes,
            p.field_error,
            p.force_error,
            p.frame_p50_us,
            p.frame_p99_us,
            p.null_p50_us,
            p.field_bytes,
            p.bundle_bytes,
            p.front_online,
            p.front_offline
        );
    }
    csv
}

/// What every sweep of the study found, beside the PGD's points.
struct Sweeps {
    estimate: super::study_estimate::EstimateRecord,
    lattice: Option<Vec<super::study_lattice::LatticePoint>>,
    cut: Option<super::study_cut::CutSweep>,
    tear: Option<super::study_tear::TearSweep>,
    meshless: Option<super::study_meshless::MeshlessSweep>,
    mesh: Option<super::study_mesh::MeshSweep>,
}

/// The PGD's points as the study prints them, one row each, with the fronts they are on.
fn print_points(o: &mut impl Write, points: &[Point]) -> std::io::Result<()> {
    writeln!(
        o,
        "{:>7} {:>6} {:>11} {:>11} {:>11} {:>10}  front",
        "storage", "modes", "field err", "frame p50", "frame p99", "bundle MB"
    )?;
    for p in points {
        writeln!(
            o,
            "{:>7} {:>6} {:>11.3e} {:>9.2}µs {:>9.2}µs {:>10.2}  {}{}",
            p.storage,
            p.modes,
            p.field_error,
            p.frame_p50_us,
            p.frame_p99_us,
            p.bundle_bytes as f64 / 1e6,
            if p.front_online { "online " } else { "" },
            if p.front_offline { "offline" } else { "" }
        )?;
    }
    Ok(())
}

/// The study's verdict in words: the cheapest point meeting the scene's tolerance, then each
/// sweep's own.
fn verdict(points: &[Point], scene: &Scene, rec: &BuildRecord, sweeps: &Sweeps) -> String {
    let Sweeps {
        estimate,
        lattice,
        cut,
        tear,
        meshless,
        mesh,
    } = sweeps;
    let null = points.first().map_or(0.0, |p| p.null_p50_us);
    let target = scene.spec.fidelity.pgd.tolerance;
    let verdict = match points
        .iter()
        .filter(|p| p.field_error <= target && p.front_online)
        .min_by(|a, b| a.frame_p50_us.total_cmp(&b.frame_p50_us))
    {
        Some(p) => format!(
            "The scene's tolerance {target:.0e} is met at the least online cost by {} modes in {} (error {:.2e}, {:.1} µs per frame p50 beside a {:.2} µs null loop, {:.1} MB of bundle).",
            p.modes,
            p.storage,
            p.field_error,
            p.frame_p50_us,
            null,
            p.bundle_bytes as f64 / 1e6
        ),
        None => format!(
            "No point meets the scene's tolerance {target:.0e}: the best is {:.2e} (raise fidelity.pgd.max_modes or lower --tolerance).",
            points.iter().map(|p| p.field_error).fold(f64::INFINITY, f64::min)
        ),
    };
    let verdict = format!(
        "{verdict} The contact force does not depend on the modes (exact local compliances): no prefix changes it. One build measured all {} prefixes in {:.1} s ({} load states). {}",
        rec.error_curve.len(),
        rec.build_s,
        rec.load_states,
        super::study_estimate::verdict(estimate)
    );
    let verdict = match lattice {
        Some(l) => format!("{verdict} {}", super::study_lattice::verdict(l, &scene.spec.fidelity.large)),
        None => verdict,
    };
    let verdict = match tear {
        Some(t) => format!("{verdict} {}", super::study_tear::verdict(t)),
        None => verdict,
    };
    let verdict = match meshless {
        Some(m) => format!("{verdict} {}", super::study_meshless::verdict(m)),
        None => verdict,
    };
    let verdict = match mesh {
        Some(m) => format!("{verdict} {}", super::study_mesh::verdict(m)),
        None => verdict,
    };
    match cut {
        Some(c) => format!(
            "{verdict} {}",
            super::study_cut::verdict(c, scene.spec.fidelity.xfem.sliver, scene.spec.fidelity.xfem.discontinuous)
        ),
        None => verdict,
    }
}

pub fn run(a: StudyArgs) -> anyhow::Result<ExitCode> {
    if !(a.tolerance > 0.0 && a.tolerance < 1.0) {
        bail!("--tolerance must lie in (0, 1), got {}", a.tolerance);
    }
    if a.frames == 0 {
        bail!("--frames must be at least 1");
    }
    if let Some(f) = a.refinements.iter().find(|f| !(f.is_finite() && **f > 0.0 && **f <= 4.0)) {
        bail!("--refinements are factors of the divisions in (0, 4], got {f}");
    }
    let scene = load_scene(&a.source)?;
    if !a.mesh_file.is_empty() && scene.spec.organs[0].mesh.file.is_none() {
        bail!("--mesh-file is for a scene whose first organ's mesh is a file; a procedural mesh is refined by --refinements");
    }
    if let Some(f) = a.mesh_file.iter().find(|f| !f.is_file()) {
        bail!("--mesh-file {}: no such file", f.display());
    }
    let scene_name = scene.spec.scene.name.clone();
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("out").join(&scene_name).join("study"));
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let (rec, bundle) = build(&a, &scene, &out)?;
    let frames = Frames::of(&bundle.vademecum, &bundle.surface)?;

    // resume: the points already measured on this build
    let points_path = out.join("points.jsonl");
    let mut done: BTreeMap<(String, usize), Point> = std::fs::read_to_string(&points_path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str::<Point>(l).ok())
        .map(|p| ((p.storage.clone(), p.modes), p))
        .collect();
    let todo: Vec<(String, usize, f64)> = ["f32", "i16"]
        .iter()
        .flat_map(|s| rec.error_curve.iter().map(move |&(k, e)| (s.to_string(), k, e)))
        .filter(|(s, k, _)| !done.contains_key(&(s.clone(), *k)))
        .collect();
    if !done.is_empty() {
        eprintln!("resuming: {} points measured before, {} to measure", done.len(), todo.len());
    }
    let mut bar = crate::progress::Steps::start("study: points of the front", todo.len());
    let mut log = std::fs::OpenOptions::new().create(true).append(true).open(&points_path)?;
    for (storage, k, e) in todo {
        bar.step(&format!("{storage}, {k} modes"));
        let p = measure(&bundle, &rec, &frames, &storage, k, e, a.frames);
        writeln!(log, "{}", serde_json::to_string(&p)?)?;
        done.insert((storage, k), p);
    }
    bar.finish();
    let sweeps = Sweeps {
        estimate: super::study_estimate::check(&scene, &bundle, &rec.key, a.estimate_points, a.estimate_nodes, &out)?,
        lattice: super::study_lattice::sweep(&scene, &rec.key, a.estimate_nodes, &out)?,
        cut: super::study_cut::sweep(&scene, &bundle.vademecum, &rec.key, &out)?,
        tear: super::study_tear::sweep(&scene, &rec.key, &out)?,
        meshless: super::study_meshless::sweep(&scene, &rec.key, &out)?,
        mesh: super::study_mesh::sweep(&scene, &rec.key, &a.refinements, &a.mesh_file, &out)?,
    };
    let Sweeps {
        estimate,
        lattice,
        cut,
        tear,
        meshless,
        mesh,
    } = &sweeps;

    let mut points: Vec<Point> = done.into_values().collect();
    points.sort_by(|a, b| (a.storage.as_str(), a.modes).cmp(&(b.storage.as_str(), b.modes)));
    let online = pareto(&points.iter().map(|p| (p.frame_p50_us, p.field_error)).collect::<Vec<_>>());
    let offline = pareto(&points.iter().map(|p| (p.bundle_bytes as f64, p.field_error)).collect::<Vec<_>>());
    for (p, (on, off)) in points.iter_mut().zip(online.into_iter().zip(offline)) {
        p.front_online = on;
        p.front_offline = off;
    }

    std::fs::write(out.join("study.csv"), points_csv(&points))?;
    std::fs::write(
        out.join("study.json"),
        serde_json::to_string_pretty(
            &serde_json::json!({ "scene": scene_name, "build": rec, "points": points, "estimate": estimate.coverage, "lattice": lattice, "cut": cut.as_ref().map(|c| &c.points), "cut_slivers_without_effect": cut.as_ref().map(|c| &c.slivers_without_effect), "tear": tear, "meshless": meshless, "mesh": mesh }),
        )?,
    )?;
    plot(
        &points,
        |p| p.frame_p50_us,
        |p| p.front_online,
        "surface field of one frame, p50 (µs)",
        &format!("{scene_name} '{}': error against online cost", rec.organ),
        &out.join("error_vs_online.svg"),
    )?;
    plot(
        &points,
        |p| p.bundle_bytes as f64 / 1e6,
        |p| p.front_offline,
        "bundle size (MB)",
        &format!(
            "{scene_name} '{}': error against bundle size (build {:.1} s)",
            rec.organ, rec.build_s
        ),
        &out.join("error_vs_bundle.svg"),
    )?;

    // the verdict
    let mut o = std::io::stdout().lock();
    print_points(&mut o, &points)?;
    let verdict = verdict(&points, &scene, &rec, &sweeps);
    writeln!(
        o,
        "\n{verdict}\n\nwritten: {}/study.csv, study.json, error_vs_online.svg, error_vs_bundle.svg, estimate.csv, estimate_vs_error.svg{}",
        out.display(),
        [
            (lattice.is_some(), ", lattice.csv, lattice_error_vs_tick.svg"),
            (cut.is_some(), ", cut.csv, cut_error_vs_tick.svg"),
            (tear.is_some(), ", tear.csv, tear_target.csv, tear_error_vs_step.svg"),
            (meshless.is_some(), ", meshless.csv, meshless_error_vs_time.svg"),
            (mesh.is_some(), ", mesh.csv, mesh_error_vs_cost.svg, mesh_error_vs_frame.svg"),
        ]
        .iter()
        .filter(|(on, _)| *on)
        .map(|(_, f)| *f)
        .collect::<String>()
    )?;
    std::fs::write(out.join("verdict.txt"), verdict + "\n")?;
    let cut_holds = cut
        .as_ref()
        .is_none_or(|c| super::study_cut::estimate_holds(c, scene.spec.fidelity.xfem.sliver));
    Ok(if super::study_estimate::holds(estimate) && cut_holds {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

#[cfg(test)]
mod tests {
    use super::pareto;

    #[test]
    fn the_front_keeps_points_no_other_beats_in_both() {
        let pts = [(1.0, 1e-1), (2.0, 1e-2), (3.0, 1e-2), (2.5, 1e-3), (5.0, 1e-3)];
        assert_eq!(pareto(&pts), [true, true, false, true, false]);
    }
}
