//! `vademecum bench tear`: tearing by continuum damage (seed 000 ch. 4) on a scene — the
//! offline stage (full-order references, POD, vademecum), the POD–PGD integrator's error per
//! step against the references (both variants), what the explicit scheme costs against
//! Newton, the dissipated energy, the online step cost beside a null loop, and memory.

use std::hint::black_box;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, bail};
use plotters::prelude::*;
use serde::Serialize;
use vademecum_engine::damage::DamageLaw;
use vademecum_engine::damage::build::{self, TearBuildReport};
use vademecum_engine::damage::model::TearModel;
use vademecum_engine::damage::online::{OnlineTear, TearOffline, Variant};
use vademecum_engine::damage::reference::{self, RunSettings, Scheme, TearRun};
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::tearing;

use super::bench_pgd::{Stat, stat, time_n, write_stats};
use crate::cli::BenchTearArgs;
use crate::progress::Stages;

/// One pseudo-time step of the comparison.
#[derive(Debug, Serialize)]
struct StepRow {
    step: usize,
    load_factor: f64,
    /// Relative L2 error of the simplified integrator against the explicit h = 0 reference.
    simplified_error: f64,
    /// Relative L2 error of the full integrator against the explicit h ≠ 0 reference.
    full_error: f64,
    /// L2 distance of the explicit h = 0 reference from Newton (the scheme's drift), relative
    /// to Newton's largest displacement over the run (a cyclic load returns to zero).
    explicit_drift: f64,
    max_damage_reference: f64,
    max_damage_simplified: f64,
    torn_cells_reference: usize,
    /// The load's resultant (N) on a scene pulled by forces, and the load-weighted mean
    /// displacement along it (m); on a scene driven by prescribed displacements `load_n` is
    /// absent and `prescribed_m` is the prescribed displacements' resultant (m) instead.
    load_n: Option<f64>,
    prescribed_m: Option<f64>,
    displacement_reference_m: f64,
    displacement_simplified_m: f64,
    displacement_full_m: f64,
    displacement_newton_m: f64,
}

/// A grasp site beside the scene's.
#[derive(Debug, Serialize)]
struct SiteRow {
    centre_m: [f64; 3],
    pull_direction: [f64; 3],
    nodes: usize,
    pod_vectors: usize,
    pgd_modes: usize,
    /// Full-order references plus POD and vademecums (s).
    offline_seconds: f64,
    offline_bytes: usize,
    /// Worst relative L2 error of the simplified integrator against the site's explicit
    /// reference (h = 0) over the schedule: pulled along its direction, and across it (the
    /// worst of [`OTHER_PULLS`]).
    error_along: f64,
    error_across: f64,
}

#[derive(Debug, Serialize)]
struct Report {
    scene: String,
    nodes: usize,
    points: usize,
    tearable_points: usize,
    local_dofs: usize,
    build: TearBuildReport,
    warnings: Vec<String>,
    newton_seconds: f64,
    steps: Vec<StepRow>,
    /// Energy dissipated at the end (J): explicit h = 0, explicit h ≠ 0, Newton, and the two
    /// integrators.
    dissipated_j: [f64; 5],
    /// Steps on which the coefficients left the box / were clamped / sub-stepped.
    simplified_flags: [usize; 3],
    full_flags: [usize; 3],
    /// Pulls in other directions (multipliers along, across, across the load) and their
    /// worst relative L2 error against the reference under the same load (h = 0).
    other_pulls: Vec<([f64; 3], f64)>,
    /// The grasp sites beside the scene's (`[fidelity.tearing] grasp_sites`): each one's
    /// offline stage and accuracy against its own full-order reference.
    sites: Vec<SiteRow>,
    timing: Vec<Stat>,
    offline_bytes: usize,
    session_bytes: usize,
}

/// The pulls across and oblique to the load a bench compares (multipliers of the patterns).
pub const OTHER_PULLS: [[f64; 3]; 3] = [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.7, 0.5, -0.5]];

/// `(load · u) / |load|₁`-like measures: the resultant of the unit load and the displacement
/// along it, weighted by the load (for the shear cube: stress and strain).
/// The resultant of what drives `model` (N for forces; for prescribed displacements, m),
/// and the weighted mean displacement along it. [`forced`] says which.
pub(super) fn measure(model: &TearModel) -> (f64, impl Fn(&[f64]) -> f64 + '_) {
    let total: f64 = model.load.iter().map(|f| f.abs()).sum();
    let prescribed: f64 = model.prescribed.iter().map(|f| f.abs()).sum();
    let (w, norm) = if total > 0.0 {
        (&model.load, total)
    } else {
        (&model.prescribed, prescribed.max(f64::MIN_POSITIVE))
    };
    let resultant = (0..3).map(|i| w.iter().skip(i).step_by(3).sum::<f64>().powi(2)).sum::<f64>().sqrt();
    (resultant, move |u: &[f64]| u.iter().zip(w).map(|(u, f)| u * f).sum::<f64>() / norm)
}

/// Whether `model` is pulled by forces (else by prescribed displacements: [`measure`]).
fn forced(model: &TearModel) -> bool {
    model.load.iter().any(|f| *f != 0.0)
}

fn run_online(
    off: &Arc<TearOffline>,
    variant: Variant,
    limits: vademecum_engine::damage::online::StepLimits,
) -> (Vec<Vec<f64>>, Vec<f64>, [usize; 3], f64) {
    let mut online = OnlineTear::new(off.clone(), variant, limits);
    let (mut us, mut dmax, mut flags) = (Vec::new(), Vec::new(), [0; 3]);
    for &ds in &off.model.schedule {
        let s = online.step(ds);
        flags[0] += s.outside as usize;
        flags[1] += s.clamped as usize;
        flags[2] += (s.substeps > 1) as usize;
        us.push(online.displacement_vec());
        dmax.push(online.state.iter().map(|p| 1.0 - p.g).fold(0.0, f64::max));
    }
    (us, dmax, flags, online.dissipated)
}

pub fn run(a: BenchTearArgs) -> anyhow::Result<ExitCode> {
    if let Some(file) = &a.closed_form {
        return closed_form(file);
    }
    if a.passes == 0 {
        bail!("--passes must be at least 1");
    }
    let scene = match &a.scene {
        Some(p) => Scene::load(p)?,
        None => Scene::builtin(&a.builtin)?,
    };
    let name = scene.spec.scene.name.clone();
    let i = tearing::tearable_organ(&scene).with_context(|| format!("scene '{name}'"))?;
    let (model, warnings) = tearing::tear_model(&scene, i)?;
    let (settings, limits) = tearing::settings(&scene);
    let stages = Stages::start("vademecum");
    for w in &warnings {
        stages.warn(w);
    }
    let (off, report, runs) =
        build::build(model, &settings, |what, f| stages.stage(&format!("{what} {:.0} %", 100.0 * f))).context("the offline stage")?;
    stages.stage("Newton reference");
    let t = Instant::now();
    let newton: TearRun = reference::run(&off.model, RunSettings::seed(Scheme::Newton), |_, _| {})?;
    let newton_seconds = t.elapsed().as_secs_f64();
    let off = Arc::new(off);
    stages.stage("online integrators");
    let (us_s, dmax_s, flags_s, diss_s) = run_online(&off, Variant::Simplified, limits);
    let (us_f, _, flags_f, diss_f) = run_online(&off, Variant::Full, limits);
    let (resultant, along) = measure(&off.model);
    let peak = newton
        .steps
        .iter()
        .map(|s| s.u.iter().map(|x| x * x).sum::<f64>().sqrt())
        .fold(f64::MIN_POSITIVE, f64::max);
    let mut steps = Vec::new();
    for k in 0..off.model.schedule.len() {
        let (r0, r1, rn) = (&runs[0].steps[k + 1], &runs[1].steps[k + 1], &newton.steps[k + 1]);
        steps.push(StepRow {
            step: k + 1,
            load_factor: r0.load_factor,
            simplified_error: reference::l2_error(&us_s[k], &r0.u).1,
            full_error: reference::l2_error(&us_f[k], &r1.u).1,
            explicit_drift: reference::l2_error(&r0.u, &rn.u).0 / peak,
            max_damage_reference: r0.max_damage,
            max_damage_simplified: dmax_s[k],
            torn_cells_reference: r0.torn_cells,
            load_n: forced(&off.model).then_some(r0.load_factor * resultant),
            prescribed_m: (!forced(&off.model)).then_some(r0.load_factor * resultant),
            displacement_reference_m: along(&r0.u),
            displacement_simplified_m: along(&us_s[k]),
            displacement_full_m: along(&us_f[k]),
            displacement_newton_m: along(&rn.u),
        });
    }
    let last = |r: &TearRun| r.steps.last().map_or(0.0, |s| s.dissipated);
    let mut other_pulls = Vec::new();
    if off.patterns() == 3 {
        stages.stage("pulls across the load");
        for mix in OTHER_PULLS {
            let worst = build::pull_errors(&off, mix)?.into_iter().fold(0.0, f64::max);
            other_pulls.push((mix, worst));
        }
    }
    let sites = grasp_sites(&scene, i, &off.model, &settings, &stages)?;

    // the online step's cost: the whole schedule, --passes times, each step timed
    let mut timing = Vec::new();
    let n_steps = off.model.schedule.len() * a.passes;
    timing.push(stat("null loop", time_n(n_steps, || black_box(0.0))));
    let mut session_bytes = 0;
    let mut hold = Vec::with_capacity(n_steps);
    for variant in [Variant::Simplified, Variant::Full] {
        stages.stage(&format!("timing {}", variant.label()));
        let mut samples = Vec::with_capacity(n_steps);
        let mut frame = Vec::with_capacity(n_steps);
        let mut u = vec![0.0; 3 * off.model.mesh.n_nodes()];
        for _ in 0..a.passes {
            let mut online = OnlineTear::new(off.clone(), variant, limits);
            session_bytes = online.memory_bytes();
            for &ds in &off.model.schedule {
                let t = Instant::now();
                black_box(online.step(ds));
                samples.push(t.elapsed().as_secs_f64() * 1e6);
                let t = Instant::now();
                online.displacement(&mut u);
                black_box(&u);
                frame.push(t.elapsed().as_secs_f64() * 1e6);
                if variant == Variant::Simplified {
                    // what the tick that takes hold adds: the damage the basis misses
                    let t = Instant::now();
                    black_box(online.hold());
                    hold.push(t.elapsed().as_secs_f64() * 1e6);
                }
            }
        }
        timing.push(stat(&format!("online step, {}", variant.label()), samples));
        timing.push(stat(&format!("whole displacement field (a frame), {}", variant.label()), frame));
    }
    timing.push(stat("taking hold (once per grasp: the damage the basis misses)", hold));
    stages.finish();

    let report = Report {
        scene: name.clone(),
        nodes: off.model.mesh.n_nodes(),
        points: off.model.points.len(),
        tearable_points: off.model.points.tearable.len(),
        local_dofs: off.local.len(),
        build: report,
        warnings,
        newton_seconds,
        steps,
        dissipated_j: [last(&runs[0]), last(&runs[1]), last(&newton), diss_s, diss_f],
        simplified_flags: flags_s,
        full_flags: flags_f,
        other_pulls,
        sites,
        timing,
        offline_bytes: off.memory_bytes(),
        session_bytes,
    };
    let dir = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&name));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    plot_errors(&report, &dir.join("tear_error.svg"))?;
    plot_curve(&report, &dir.join("tear_curve.svg"))?;
    let mut out = std::io::stdout().lock();
    if a.json {
        // stdout holds the JSON alone (the plots' paths go to stderr)
        writeln!(out, "{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        print_text(&mut out, &report)?;
    }
    let plots = format!(
        "plots: {} (error per step), {} (load against displacement)",
        dir.join("tear_error.svg").display(),
        dir.join("tear_curve.svg").display()
    );
    if a.json {
        eprintln!("{plots}");
    } else {
        writeln!(out, "{plots}")?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Builds the offline stage of every grasp site the scene adds and measures it against its
/// own full-order reference.
fn grasp_sites(
    scene: &Scene,
    organ_index: usize,
    model: &TearModel,
    settings: &build::TearSettings,
    stages: &Stages,
) -> anyhow::Result<Vec<SiteRow>> {
    let extra = tearing::extra_sites(scene, organ_index, model)?;
    let mut rows = Vec::new();
    for (k, site) in extra.iter().enumerate() {
        let mut m = model.clone();
        m.load = site.full(m.mesh.n_nodes());
        let label = format!("grasp site {}/{}", k + 2, extra.len() + 1);
        let (off, b, _) = build::build(m, settings, |what, f| stages.stage(&format!("{label}: {what} {:.0} %", 100.0 * f)))
            .with_context(|| format!("the offline stage of {label}"))?;
        let off = Arc::new(off);
        stages.stage(&format!("{label}: accuracy"));
        let worst = |mix: [f64; 3]| build::pull_errors(&off, mix).map(|e| e.into_iter().fold(0.0, f64::max));
        let error_along = worst([1.0, 0.0, 0.0])?;
        let mut error_across = 0.0f64;
        if off.patterns() == 3 {
            for mix in OTHER_PULLS {
                error_across = error_across.max(worst(mix)?);
            }
        }
        let (_, centre_m, _) = off.model.grasp().expect("a site has a load");
        rows.push(SiteRow {
            centre_m,
            pull_direction: off.model.pull_frame().expect("a site has a load")[0],
            nodes: site.nodes.len(),
            pod_vectors: b.pod_vectors,
            pgd_modes: b.pgd_modes,
            offline_seconds: b.reference_seconds + b.build_seconds,
            offline_bytes: off.memory_bytes(),
            error_along,
            error_across,
        });
    }
    Ok(rows)
}

fn print_text(out: &mut impl Write, r: &Report) -> std::io::Result<()> {
    let b = &r.build;
    writeln!(
        out,
        "{}: {} nodes, {} integration points, {} tearable, {} dofs updated per step",
        r.scene, r.nodes, r.points, r.tearable_points, r.local_dofs
    )?;
    writeln!(
        out,
        "offline: {} snapshots, {} POD vectors (1 - captured = {:.1e}), {} PGD modes, Ritz basis {}, \
vademecum error {:.2e} at the snapshots; references {:.2} s, POD + vademecum {:.2} s, Newton {:.2} s",
        b.snapshots,
        b.pod_vectors,
        1.0 - b.captured,
        b.pgd_modes,
        b.ritz_size,
        b.vademecum_error,
        b.reference_seconds,
        b.build_seconds,
        r.newton_seconds
    )?;
    writeln!(
        out,
        "\n| step | load factor | error h = 0 | error h ≠ 0 | explicit vs Newton | max D (ref) | max D (h = 0) | torn cells (ref) |"
    )?;
    writeln!(out, "|---:|---:|---:|---:|---:|---:|---:|---:|")?;
    for s in &r.steps {
        writeln!(
            out,
            "| {} | {:.3} | {:.2e} | {:.2e} | {:.2e} | {:.3} | {:.3} | {} |",
            s.step,
            s.load_factor,
            s.simplified_error,
            s.full_error,
            s.explicit_drift,
            s.max_damage_reference,
            s.max_damage_simplified,
            s.torn_cells_reference
        )?;
    }
    let worst = |f: fn(&StepRow) -> f64| r.steps.iter().map(f).fold(0.0, f64::max);
    writeln!(
        out,
        "\nworst relative L2 error: h = 0 {:.2e}, h ≠ 0 {:.2e}; explicit against Newton at the end {:.2e}",
        worst(|s| s.simplified_error),
        worst(|s| s.full_error),
        r.steps.last().map_or(0.0, |s| s.explicit_drift)
    )?;
    let d = r.dissipated_j;
    writeln!(
        out,
        "dissipated (J): explicit h = 0 {:.4e}, explicit h ≠ 0 {:.4e}, Newton {:.4e}; POD–PGD h = 0 {:.4e}, h ≠ 0 {:.4e}",
        d[0], d[1], d[2], d[3], d[4]
    )?;
    writeln!(
        out,
        "steps outside the box / clamped / sub-stepped: h = 0 {:?}, h ≠ 0 {:?}",
        r.simplified_flags, r.full_flags
    )?;
    if !r.other_pulls.is_empty() {
        let cells: Vec<String> = r
            .other_pulls
            .iter()
            .map(|(m, e)| format!("({:.1}, {:.1}, {:.1}) {e:.2e}", m[0], m[1], m[2]))
            .collect();
        writeln!(
            out,
            "pulled in other directions (multipliers along n, t1, t2; h = 0, worst relative L2 error against the reference under the same load): {}",
            cells.join(", ")
        )?;
    }
    if !r.sites.is_empty() {
        writeln!(
            out,
            "\ngrasp sites beside the scene's (each against its own full-order reference, h = 0):\n\n| centre (m) | pull | nodes | POD | PGD modes | offline (s) | KiB | error along | error across |\n|---|---|---:|---:|---:|---:|---:|---:|---:|"
        )?;
        for s in &r.sites {
            writeln!(
                out,
                "| {} | {} | {} | {} | {} | {:.1} | {:.0} | {:.2e} | {:.2e} |",
                super::vec3(s.centre_m, 4),
                super::vec3(s.pull_direction, 2),
                s.nodes,
                s.pod_vectors,
                s.pgd_modes,
                s.offline_seconds,
                s.offline_bytes as f64 / 1024.0,
                s.error_along,
                s.error_across
            )?;
        }
    }
    writeln!(out)?;
    write_stats(out, &r.timing)?;
    writeln!(
        out,
        "memory: {:.1} KiB shared offline data, {:.1} KiB per session",
        r.offline_bytes as f64 / 1024.0,
        r.session_bytes as f64 / 1024.0
    )
}

fn plot_errors(r: &Report, file: &Path) -> anyhow::Result<()> {
    let root = crate::plot::canvas(file, (900, 560))?;
    let series: [(&str, fn(&StepRow) -> f64); 3] = [
        ("POD–PGD h = 0 vs explicit h = 0", |s| s.simplified_error),
        ("POD–PGD h ≠ 0 vs explicit h ≠ 0", |s| s.full_error),
        ("explicit h = 0 vs Newton (drift)", |s| s.explicit_drift),
    ];
    let all: Vec<f64> = r
        .steps
        .iter()
        .flat_map(|s| series.iter().map(move |(_, f)| f(s)))
        .filter(|e| *e > 0.0 && e.is_finite())
        .collect();
    let lo = all.iter().copied().fold(1.0, f64::min).max(1e-16) * 0.5;
    let hi = all.iter().copied().fold(1e-12, f64::max) * 2.0;
    let n = r.steps.len() as f64;
    let b = &r.build;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{}: {} POD vectors, {} PGD modes", r.scene, b.pod_vectors, b.pgd_modes),
            ("sans-serif", 18),
        )
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..n + 1.0, (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("pseudo-time step")
        .y_desc("relative L2 error of the displacement")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()?;
    for (k, (label, f)) in series.iter().enumerate() {
        let color = super::bench_anm::PALETTE[k];
        let pts: Vec<(f64, f64)> = r
            .steps
            .iter()
            .map(|s| (s.step as f64, f(s)))
            .filter(|p| p.1 > 0.0 && p.1.is_finite())
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
            .label(*label)
            .legend(crate::plot::line_key(color.stroke_width(2)));
    }
    crate::plot::legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present()?;
    Ok(())
}

fn plot_curve(r: &Report, file: &Path) -> anyhow::Result<()> {
    let root = crate::plot::canvas(file, (900, 560))?;
    let series: [(&str, fn(&StepRow) -> f64); 4] = [
        ("explicit h = 0 (reference)", |s| s.displacement_reference_m),
        ("Newton", |s| s.displacement_newton_m),
        ("POD–PGD h = 0", |s| s.displacement_simplified_m),
        ("POD–PGD h ≠ 0", |s| s.displacement_full_m),
    ];
    let xs: Vec<f64> = r.steps.iter().flat_map(|s| series.iter().map(move |(_, f)| f(s))).collect();
    let (x0, x1) = xs.iter().fold((0.0f64, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    // what drives the scene: a force (N), or a prescribed displacement (m)
    let driver = |s: &StepRow| s.load_n.or(s.prescribed_m).unwrap_or(0.0);
    let forced = r.steps.first().is_none_or(|s| s.load_n.is_some());
    let (y0, y1) = r
        .steps
        .iter()
        .fold((0.0f64, 0.0f64), |(a, b), s| (a.min(driver(s)), b.max(driver(s))));
    let pad = |a: f64, b: f64| ((b - a).abs() * 0.05).max(1e-12);
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{}: load against displacement", r.scene), ("sans-serif", 18))
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d(x0 - pad(x0, x1)..x1 + pad(x0, x1), y0 - pad(y0, y1)..y1 + pad(y0, y1))?;
    chart
        .configure_mesh()
        .x_desc("load-weighted displacement along the load (m)")
        .y_desc(if forced {
            "load resultant (N)"
        } else {
            "prescribed displacement resultant (m)"
        })
        .draw()?;
    for (k, (label, f)) in series.iter().enumerate() {
        let color = super::bench_anm::PALETTE[k];
        let pts: Vec<(f64, f64)> = std::iter::once((0.0, 0.0))
            .chain(r.steps.iter().map(|s| (f(s), driver(s))))
            .collect();
        chart
            .draw_series(LineSeries::new(pts, color.stroke_width(if k < 2 { 3 } else { 1 })))?
            .label(*label)
            .legend(crate::plot::line_key(color.stroke_width(2)));
    }
    crate::plot::legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present()?;
    Ok(())
}

/// One law's curve: strain, FE stress and damage, closed-form stress and damage.
struct Curve {
    name: &'static str,
    points: Vec<[f64; 5]>,
}

/// The unit hexahedron (E = 5 Pa, ν = 0.3) on its three symmetry planes, x = 1 and y = 1 held
/// too (uniaxial strain), its top pulled by a prescribed `uz` of 1 per unit step.
fn strained_cube(law: DamageLaw) -> anyhow::Result<TearModel> {
    use vademecum_engine::damage::points::MaterialPoints;
    use vademecum_engine::fem::assembly::MaterialMap;
    use vademecum_engine::material::LinearElastic;
    let mesh = vademecum_engine::mesh::procedural::block_hex([0.0; 3], [1.0; 3], [1, 1, 1]);
    let mat = MaterialMap::uniform(LinearElastic::new(5.0, 0.3)?, 1.0, 1);
    let pts = MaterialPoints::new(&mesh, &mat, false, |_, _| Ok::<_, String>(Some(law))).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let nd = 3 * mesh.n_nodes();
    let (mut constrained, mut prescribed) = (vec![false; nd], vec![0.0; nd]);
    for (a, x) in mesh.nodes.iter().enumerate() {
        for i in 0..3 {
            constrained[3 * a + i] |= x[i] == 0.0 || (i < 2 && x[i] == 1.0);
        }
        if x[2] == 1.0 {
            constrained[3 * a + 2] = true;
            prescribed[3 * a + 2] = 1.0;
        }
    }
    Ok(TearModel::new(mesh, pts, &constrained, vec![0.0; nd], prescribed))
}

/// `--closed-form`: both laws on the strained cube, Newton against `σ = g(r) M ε`.
fn closed_form(file: &Path) -> anyhow::Result<ExitCode> {
    use vademecum_engine::damage::law::PointState;
    let m = {
        let l = vademecum_engine::material::LinearElastic::new(5.0, 0.3)?;
        l.lambda() + 2.0 * l.shear()
    };
    // strain path: to 3 units, back to 1, on to 5 (unload–reload), in steps of `unit / 20`
    let path = |unit: f64| -> Vec<f64> {
        let d = unit / 20.0;
        [vec![d; 60], vec![-d; 40], vec![d; 80]].concat()
    };
    let laws = [
        ("Simó (seed Eq. 4.3), α = 0.4, β = 0.1", DamageLaw::simo(0.4, 0.1, 1e-6)?, 0.2),
        (
            "softening, f_t = 0.5 Pa, G_f = 0.5 J/m²",
            DamageLaw::softening(5.0, 0.5, 0.5, 1.0, 1e-6)?,
            0.1,
        ),
    ];
    let mut curves = Vec::new();
    let mut out = std::io::stdout().lock();
    writeln!(out, "| law | steps | worst stress error (Pa) | worst damage error |")?;
    writeln!(out, "|---|---:|---:|---:|")?;
    for (name, law, unit) in laws {
        let mut model = strained_cube(law)?;
        model.schedule = path(unit);
        let run = reference::run(&model, RunSettings::seed(Scheme::Newton), |_, _| {})?;
        let (mut r_max, mut points) = (0.0f64, Vec::new());
        let (mut es, mut ed) = (0.0f64, 0.0f64);
        let mut f = vec![0.0; 24];
        for s in &run.steps {
            let eps = s.load_factor;
            r_max = r_max.max(m.sqrt() * eps.abs());
            let g = law.g(r_max);
            let state: Vec<PointState> = s.g.iter().map(|&g| PointState { r: r_max, g, h: 0.0 }).collect();
            model.points.internal_forces(&model.mesh, &state, &s.u, &mut f);
            let sigma: f64 = model
                .mesh
                .nodes
                .iter()
                .enumerate()
                .filter(|(_, x)| x[2] == 1.0)
                .map(|(a, _)| f[3 * a + 2])
                .sum();
            let d_fe = 1.0 - s.g.iter().sum::<f64>() / s.g.len() as f64;
            es = es.max((sigma - g * m * eps).abs());
            ed = ed.max((d_fe - (1.0 - g)).abs());
            points.push([eps, sigma, d_fe, g * m * eps, 1.0 - g]);
        }
        writeln!(out, "| {name} | {} | {es:.2e} | {ed:.2e} |", run.steps.len() - 1)?;
        curves.push(Curve { name, points });
    }
    plot_closed_form(&curves, file)?;
    writeln!(out, "plot: {}", file.display())?;
    Ok(ExitCode::SUCCESS)
}

fn plot_closed_form(curves: &[Curve], file: &Path) -> anyhow::Result<()> {
    let root = crate::plot::canvas(file, (1100, 480))?;
    let panels = root.split_evenly((1, curves.len()));
    for (c, area) in curves.iter().zip(&panels) {
        let x1 = c.points.iter().map(|p| p[0]).fold(0.0, f64::max) * 1.05;
        let y1 = c.points.iter().map(|p| p[1].max(p[3])).fold(0.0, f64::max) * 1.15;
        let mut chart = ChartBuilder::on(area)
            .caption(c.name, ("sans-serif", 15))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .right_y_label_area_size(48)
            .build_cartesian_2d(0.0..x1, 0.0..y1)?
            .set_secondary_coord(0.0..x1, 0.0..1.0);
        chart.configure_mesh().x_desc("strain ε").y_desc("stress σ (Pa)").draw()?;
        chart.configure_secondary_axes().y_desc("damage D").draw()?;
        let blue = super::bench_anm::PALETTE[0];
        let red = super::bench_anm::PALETTE[1];
        chart
            .draw_series(LineSeries::new(c.points.iter().map(|p| (p[0], p[3])), blue.stroke_width(2)))?
            .label("σ, closed form")
            .legend(crate::plot::line_key(blue.stroke_width(2)));
        chart
            .draw_series(c.points.iter().step_by(4).map(|p| Circle::new((p[0], p[1]), 3, blue.filled())))?
            .label("σ, finite element (Newton)")
            .legend(move |(x, y)| Circle::new((x + 10, y), 3, blue.filled()));
        chart
            .draw_secondary_series(LineSeries::new(c.points.iter().map(|p| (p[0], p[4])), red.stroke_width(2)))?
            .label("D, closed form")
            .legend(crate::plot::line_key(red.stroke_width(2)));
        chart
            .draw_secondary_series(c.points.iter().step_by(4).map(|p| Circle::new((p[0], p[2]), 3, red.filled())))?
            .label("D, finite element")
            .legend(move |(x, y)| Circle::new((x + 10, y), 3, red.filled()));
        crate::plot::legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    }
    root.present()?;
    Ok(())
}
