//! `vademecum bench anm`: seed 001's ANM-POD against full Newton–Raphson on a scene's load
//! case — the table, the plot, and the online cost per evaluation beside a null loop.

use std::hint::black_box;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use plotters::prelude::*;
use serde::Serialize;
use vademecum_engine::fem::hyperelastic::LawMap;
use vademecum_engine::material::hyperelastic::Hyperelastic;
use vademecum_engine::rom::anm::{self, Series};
use vademecum_engine::rom::lattice::{self, LatticeParams, LatticeStudy};
use vademecum_engine::rom::study::{self, ReducedCase, Study, StudyParams};
use vademecum_engine::rom::{AnmParams, PodCriterion};
use vademecum_engine::scene::Scene;

use super::bench_pgd::{Rng, Stat, stat, time_n, write_stats};
use crate::cli::BenchAnmArgs;
use crate::progress::Stages;

/// Seed 001 §6.2: orders 5–6 within 5 % of Newton up to about 5 mm under the tool.
const TOLERANCE: f64 = 0.05;

#[derive(Debug, Serialize)]
struct Report {
    scene: String,
    organ: String,
    nodes: usize,
    cells: usize,
    dofs: usize,
    study: Study,
    reach_mm: Vec<(usize, f64)>,
    online: Vec<Stat>,
    interpolation: Option<LatticeStudy>,
    plot: PathBuf,
}

/// Online figures at order 6 on the reduced case.
fn online(case: &ReducedCase, force: f64, calls: usize) -> anyhow::Result<Vec<Stat>> {
    let r = case.pod.modes;
    let params = AnmParams::default();
    let scale = anm::displacement_scale(&case.model, &case.load)?;
    let path = anm::continuation(&case.model, &case.load, 1.0, &params)?;
    let origin = vec![0.0; r];
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    let mut zeta = vec![0.0; r];
    let probe = |z: &[f64]| -> f64 { case.probe.iter().zip(z).map(|(p, z)| p * z).sum() };
    let null = time_n(calls, || black_box(0.0));
    // a precomputed path: load → reduced state → displacement under the tool
    let eval = time_n(calls, || {
        let l = rng.unit();
        if path.at_load(l, &mut zeta) { probe(&zeta) * force } else { 0.0 }
    });
    // a new series (what an interpolated model costs): tangent, factorization, 6 orders
    let expand = time_n(calls, || {
        let s = Series::expand(&case.model, &case.load, &origin, 0.0, 6, scale, params.tolerance).expect("expanded above");
        s.radius
    });
    let cont = time_n((calls / 10).max(10), || {
        anm::continuation(&case.model, &case.load, 1.0, &params).map_or(0.0, |p| p.end_load())
    });
    Ok(vec![
        stat("null timing loop", null),
        stat("evaluate the order-6 path at a load (state + tool displacement)", eval),
        stat("one order-6 series (tangent, Cholesky, 6 orders)", expand),
        stat("order-6 continuation from 0 to the full load", cont),
    ])
}

/// The series colours of the benchmark plots.
pub(crate) const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(214, 39, 40),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

fn plot(study: &Study, title: &str, file: &Path) -> anyhow::Result<()> {
    let mm = |d: f64| 1e3 * d.abs();
    let d_max = study.points.iter().map(|p| mm(p.newton)).fold(0.0, f64::max) * 1.15;
    let f_max = study.force * 1.15;
    let root = crate::plot::canvas(file, (900, 620))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(56)
        .build_cartesian_2d(0.0..d_max, 0.0..f_max)?;
    chart
        .configure_mesh()
        .x_desc("displacement under the load (mm)")
        .y_desc("load (N)")
        .draw()?;
    let palette = PALETTE;
    for (k, curve) in study.curves.iter().enumerate() {
        let color = palette[k % palette.len()];
        chart
            .draw_series(LineSeries::new(
                curve
                    .iter()
                    .map(|&(d, l)| (mm(d), l * study.force))
                    .filter(|&(d, f)| d <= d_max && (0.0..=f_max).contains(&f)),
                color.stroke_width(2),
            ))?
            .label(format!("ANM-POD, one series, order {}", study.orders[k]))
            .legend(crate::plot::line_key(color.stroke_width(2)));
    }
    let cont: Vec<(f64, f64)> = study
        .points
        .iter()
        .filter_map(|p| p.continuation.map(|d| (mm(d), p.lambda * study.force)))
        .collect();
    chart
        .draw_series(cont.iter().map(|&p| Cross::new(p, 6, BLACK.stroke_width(2))))?
        .label("ANM-POD order 6, continuation")
        .legend(|(x, y)| Cross::new((x + 10, y), 6, BLACK.stroke_width(2)));
    let newton: Vec<(f64, f64)> = std::iter::once((0.0, 0.0))
        .chain(study.points.iter().map(|p| (mm(p.newton), p.lambda * study.force)))
        .collect();
    chart
        .draw_series(LineSeries::new(newton.clone(), BLACK.stroke_width(1)))?
        .label("full Newton-Raphson")
        .legend(|(x, y)| Circle::new((x + 10, y), 4, BLACK.filled()));
    chart.draw_series(newton.iter().map(|&p| Circle::new(p, 4, BLACK.filled())))?;
    crate::plot::legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present()?;
    Ok(())
}

pub fn run(a: BenchAnmArgs) -> anyhow::Result<ExitCode> {
    if a.orders.is_empty() || a.orders.iter().any(|&o| !(1..=anm::MAX_ORDER).contains(&o)) {
        bail!("--orders must list orders in 1..={}", anm::MAX_ORDER);
    }
    if a.steps < 2 || a.modes == 0 || a.calls == 0 {
        bail!("--steps must be at least 2, --modes and --calls at least 1");
    }
    let scene = match &a.scene {
        Some(p) => Scene::load(p)?,
        None => Scene::builtin(&a.builtin)?,
    };
    let organ = scene.organ_model(0)?;
    // the seed's law: St Venant–Kirchhoff with each cell's E and ν
    let laws = LawMap {
        laws: organ.materials.table.iter().map(Hyperelastic::svk).collect(),
        of_cell: organ.materials.of_cell.clone(),
    };
    let params = StudyParams {
        load_steps: a.steps,
        pod: PodCriterion {
            energy: 1.0 - 1e-12,
            max_modes: a.modes,
        },
        orders: a.orders.clone(),
        load_multiplier: a.load_multiplier,
        ..StudyParams::default()
    };
    let bar = Stages::start(&organ.name);
    let (study, case) =
        study::anm_pod(&organ.mesh, &laws, &organ.problem, &params, |s| bar.stage(s)).with_context(|| format!("organ '{}'", organ.name))?;
    bar.stage("online cost");
    let online = online(&case, study.force, a.calls)?;
    let interpolation = match a.lattice {
        None => None,
        Some(side) => {
            let size = {
                let (lo, hi) = organ.mesh.bounding_box();
                (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)
            };
            let radius = vademecum_engine::offline::probe_radius(&scene);
            let params = LatticeParams {
                side,
                spacing: a.spacing.unwrap_or(size / 10.0),
                patch_radius: radius,
                pod: params.pod,
                enrich: a.enrich,
                ..LatticeParams::default()
            };
            let mut scaled = organ.problem.clone();
            for f in &mut scaled.forces {
                *f *= a.load_multiplier;
            }
            Some(
                lattice::interpolation_study(
                    &organ.mesh,
                    &laws,
                    &organ.materials,
                    &scaled,
                    &organ.accessible_nodes,
                    &params,
                    |s| bar.stage(s),
                )
                .context("interpolation study")?,
            )
        }
    };
    let file = a
        .plot
        .clone()
        .unwrap_or_else(|| PathBuf::from("out").join(&scene.spec.scene.name).join("anm.svg"));
    if let Some(dir) = file.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let title = format!(
        "{}: St Venant-Kirchhoff, {} N, POD {} modes",
        scene.spec.scene.name, study.force, study.modes
    );
    plot(&study, &title, &file).with_context(|| format!("cannot write the plot {}", file.display()))?;
    bar.finish();
    let reach_mm = study.orders.iter().map(|&o| (o, 1e3 * study.reach(o, TOLERANCE))).collect();
    let report = Report {
        scene: scene.spec.scene.name.clone(),
        organ: organ.name.clone(),
        nodes: organ.mesh.n_nodes(),
        cells: organ.mesh.n_cells(),
        dofs: organ.mesh.n_dofs(),
        study,
        reach_mm,
        online,
        interpolation,
        plot: file,
    };
    let mut out = std::io::stdout().lock();
    if a.json {
        serde_json::to_writer_pretty(&mut out, &report)?;
        writeln!(out)?;
    } else {
        print_report(&mut out, &report)?;
    }
    Ok(ExitCode::SUCCESS)
}

fn print_report(out: &mut impl Write, r: &Report) -> std::io::Result<()> {
    let s = &r.study;
    writeln!(
        out,
        "{} / {}: {} nodes, {} cells, {} dofs; St Venant-Kirchhoff; {:.4} N on {} node(s) along [{:.3}, {:.3}, {:.3}]",
        r.scene,
        r.organ,
        r.nodes,
        r.cells,
        r.dofs,
        s.force,
        s.probe_nodes.len(),
        s.direction[0],
        s.direction[1],
        s.direction[2]
    )?;
    let sv: Vec<String> = s.singular_values.iter().take(12).map(|v| format!("{v:.2e}")).collect();
    writeln!(
        out,
        "POD: {} modes of {} snapshots, captured energy 1 - {:.1e}; singular values {}",
        s.modes,
        s.points.len(),
        (1.0 - s.captured).max(0.0),
        sv.join(" ")
    )?;
    writeln!(
        out,
        "offline: full Newton {:.2} s, POD {:.3} s, reduced tensors {:.3} s; continuation at order 6: {} steps",
        s.seconds.newton,
        s.seconds.pod,
        s.seconds.tensors,
        s.continuation_radii.len()
    )?;
    if let Some(why) = &s.newton_stopped {
        writeln!(out, "full Newton stopped early: {why}")?;
    }
    writeln!(out, "\ndisplacement under the load (mm) and relative error against full Newton (%)")?;
    write!(out, "| load (N) | Newton | reduced Newton | continuation 6 |")?;
    for o in &s.orders {
        write!(out, " order {o} |")?;
    }
    writeln!(out)?;
    write!(out, "|---|---|---|---|")?;
    for _ in &s.orders {
        write!(out, "---|")?;
    }
    writeln!(out)?;
    let cell = |d: Option<f64>, reference: f64| match d {
        Some(d) => format!("{:.3} ({:+.2})", 1e3 * d, 100.0 * (d - reference) / reference),
        None => "not reached".into(),
    };
    for p in &s.points {
        write!(
            out,
            "| {:.4} | {:.3} | {} | {} |",
            p.lambda * s.force,
            1e3 * p.newton,
            cell(p.reduced, p.newton),
            cell(p.continuation, p.newton)
        )?;
        for d in &p.series {
            write!(out, " {} |", cell(*d, p.newton))?;
        }
        writeln!(out)?;
    }
    write!(out, "\nwithin {:.0} % of Newton up to:", 100.0 * TOLERANCE)?;
    for (o, mm) in &r.reach_mm {
        write!(out, " order {o}: {mm:.2} mm;")?;
    }
    writeln!(out)?;
    writeln!(out, "\nonline cost, r = {} (µs per call)", s.modes)?;
    write_stats(out, &r.online)?;
    if let Some(l) = &r.interpolation {
        writeln!(
            out,
            "\ninterpolation between {} lattice positions ({} modes each, four nearest, inverse-distance weights): \
             relative error at the full load against full Newton there, and the projection error of that position's own Newton states on the basis",
            l.lattice.len(),
            l.modes
        )?;
        write!(out, "| position (mm) | to nearest (mm) | Newton (mm) | own basis |")?;
        for m in lattice::METHODS {
            write!(out, " {m} | projection |")?;
        }
        writeln!(out, " seed §5 online (µs) | blended responses | served force (linear) |")?;
        writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")?;
        for (row, own) in l.rows.iter().zip(&l.own_basis_error) {
            write!(
                out,
                "| {:.1}, {:.1}, {:.1} | {:.2} | {:.3} | {:.2} % |",
                1e3 * row.centre[0],
                1e3 * row.centre[1],
                1e3 * row.centre[2],
                1e3 * row.nearest_m,
                1e3 * row.newton,
                100.0 * own
            )?;
            for m in 0..lattice::METHODS.len() {
                write!(out, " {:.2} % | {:.1e} |", 100.0 * row.error[m], row.projection[m])?;
            }
            writeln!(
                out,
                " {:.2} % ({:.0}) | {:.2} % | {:.2} % ({:.2} %) |",
                100.0 * row.online_error,
                row.online_us,
                100.0 * row.response_error,
                100.0 * row.served_error,
                100.0 * row.correction
            )?;
            for f in &row.failures {
                writeln!(out, "  (failed: {f})")?;
            }
        }
    }
    writeln!(out, "\nplot: {}", r.plot.display())
}
