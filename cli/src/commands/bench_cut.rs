//! `vademecum bench cut`: the reduced online cutting models (PRB and SRB, bare enrichment or
//! local discontinuous fields; seed 000 §3.2–3.3) against the full-order XFEM on the same mesh
//! and cut, step by step along a scene's pre-planned cuts; the error against the number of
//! modes (a plot); and the per-tick cost against the number of enriched nodes (the compliance
//! the cut adds at a contact, by forward substitution and from the contact table a session
//! keeps), beside a null loop, with the cost of bordering the factor and of extending the
//! table, and the memory.

use std::hint::black_box;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use plotters::prelude::*;
use serde::Serialize;
use vademecum_engine::fem::OrganModel;
use vademecum_engine::geometry::cut::Cut;
use vademecum_engine::geometry::vec3;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pgd::{PgdParams, Vademecum};
use vademecum_engine::scene::Scene;
use vademecum_engine::xfem::reduced::{Discontinuous, ReducedCut, RitzBasis};
use vademecum_engine::xfem::system::{self, XfemSolution};
use vademecum_engine::xfem::{Enrichment, Plane, XfemParams};

use super::bench_pgd::{Stat, stat, time_n, write_stats};
use crate::cli::BenchCutArgs;
use crate::progress::Stages;

const VARIANTS: [(RitzBasis, Discontinuous); 4] = [
    (RitzBasis::Prb, Discontinuous::Bare),
    (RitzBasis::Srb, Discontinuous::Bare),
    (RitzBasis::Prb, Discontinuous::LocalFields),
    (RitzBasis::Srb, Discontinuous::LocalFields),
];

fn variant_name(v: (RitzBasis, Discontinuous)) -> String {
    format!(
        "{} {}",
        v.0.name(),
        match v.1 {
            Discontinuous::Bare => "bare",
            Discontinuous::LocalFields => "local fields",
        }
    )
}

#[derive(Debug, Serialize)]
struct Step {
    /// Blade positions of the cuts reached so far.
    blade_positions: usize,
    cut_cells: usize,
    enriched_nodes: usize,
    /// Relative L2 error of the displacement (both lips of every node) per variant.
    errors: Vec<f64>,
    /// Largest opening at a cracked node, full XFEM (m).
    full_opening_m: f64,
    /// The same, per variant (m).
    openings_m: Vec<f64>,
}

#[derive(Debug, Serialize)]
struct TickRow {
    enriched_nodes: usize,
    unknowns: usize,
    variant: String,
    /// Bytes of the basis, local fields and bordered factor.
    bytes: usize,
    /// Mean time to enrich one node (assembly of its rows + bordering), µs.
    border_per_node_us: f64,
    /// Mean time to extend the contact table by one node's unknowns, µs.
    table_per_node_us: f64,
    /// Bytes of the contact table.
    table_bytes: usize,
    /// Loadable nodes tabulated.
    table_nodes: usize,
    stats: Vec<Stat>,
}

#[derive(Debug, Serialize)]
struct Report {
    scene: String,
    organ: String,
    nodes: usize,
    cells: usize,
    modes: usize,
    pgd_tolerance: f64,
    variants: Vec<String>,
    steps: Vec<Step>,
    modes_sweep: Vec<(usize, Vec<f64>)>,
    ticks: Vec<TickRow>,
    plot: PathBuf,
    /// The cutting pipeline in a session (`bench_cut_session`), unless `--no-session`.
    #[serde(skip_serializing_if = "Option::is_none")]
    session: Option<super::bench_cut_session::SessionReport>,
}

/// Relative L2 error of reduced fields against the full XFEM over every node's both lips, and
/// the largest reduced opening.
fn error(enr: &Enrichment, u: &[f64], q: &[f64], full: &XfemSolution) -> (f64, f64) {
    let (mut num, mut den) = (0.0, 0.0);
    for a in 0..u.len() / 3 {
        for positive in [true, false] {
            let f = full.side_displacement(enr, a, positive);
            let s = enr.index(a).map_or(0.0, |k| enr.shifted(k, positive));
            for i in 0..3 {
                let r = u[3 * a + i] + enr.index(a).map_or(0.0, |k| s * q[3 * k + i]);
                num += (r - f[i]).powi(2);
                den += f[i] * f[i];
            }
        }
    }
    let opening = (0..enr.len())
        .map(|k| (0..3).map(|i| q[3 * k + i].powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    ((num / den.max(f64::MIN_POSITIVE)).sqrt(), opening)
}

fn reduced(
    model: &OrganModel,
    modes: &[f64],
    n_modes: usize,
    v: (RitzBasis, Discontinuous),
    params: &XfemParams,
) -> anyhow::Result<ReducedCut> {
    Ok(ReducedCut::new(
        &model.mesh,
        &model.materials,
        model.locking,
        &model.problem,
        modes,
        n_modes,
        v.0,
        v.1,
        params,
    )?)
}

/// The cut cells of each blade position of the scene's cuts, in order (each cut from its first
/// position to its last).
fn progressive_cells(model: &OrganModel, cuts: &[Cut], params: &XfemParams) -> anyhow::Result<Vec<Vec<(usize, Plane)>>> {
    let mut out = Vec::new();
    for cut in cuts {
        let p = cut.points();
        for k in 2..=p.len() / 2 {
            let blade: Vec<([f64; 3], [f64; 3])> = (0..k).map(|i| (p[2 * i], p[2 * i + 1])).collect();
            out.push(Enrichment::cut_cells(&model.mesh, &Cut::swept(&blade)?, params)?);
        }
    }
    Ok(out)
}

/// Cells to cut to reach about `target` enriched nodes: planes through the organ's centre,
/// normal to y then x, then shifted copies, each plane's cells nearest the centre first.
fn growing_cells(model: &OrganModel) -> Vec<(usize, Plane)> {
    let mesh = &model.mesh;
    let (lo, hi) = mesh.bounding_box();
    let centre = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])];
    let h = (mesh.diameter().powi(3) / mesh.n_cells().max(1) as f64).cbrt();
    let mut out: Vec<(usize, Plane)> = Vec::new();
    let mut taken = vec![false; mesh.n_cells()];
    for shift in [0.0, 4.0, -4.0, 8.0, -8.0] {
        for normal in [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]] {
            let mut point = centre;
            let axis = if normal[1] == 1.0 { 1 } else { 0 };
            point[axis] += shift * h;
            let plane = Plane { point, normal };
            let mut cells = Enrichment::cells_crossed_by(mesh, &plane);
            let dist = |c: usize| {
                let cell = mesh.cell(c);
                let p = mesh.nodes[cell[0]];
                (0..3).map(|i| (p[i] - centre[i]).powi(2)).sum::<f64>()
            };
            cells.sort_by(|a, b| dist(a.0).total_cmp(&dist(b.0)));
            for (c, p) in cells {
                if !std::mem::replace(&mut taken[c], true) {
                    out.push((c, p));
                }
            }
        }
    }
    out
}

fn plot(report: &Report, file: &Path) -> anyhow::Result<()> {
    let root = crate::plot::canvas(file, (900, 600))?;
    let max_modes = report.modes_sweep.iter().map(|m| m.0).max().unwrap_or(1) as f64;
    let all: Vec<f64> = report
        .modes_sweep
        .iter()
        .flat_map(|m| m.1.iter().copied())
        .filter(|e| *e > 0.0 && e.is_finite())
        .collect();
    let lo = all.iter().copied().fold(1.0, f64::min).max(1e-12) * 0.5;
    let hi = all.iter().copied().fold(1e-6, f64::max) * 2.0;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{}: reduced cutting against the full XFEM, final cut", report.scene),
            ("sans-serif", 18),
        )
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..max_modes * 1.05, (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("PGD modes in the Ritz basis")
        .y_desc("relative L2 error of the displacement")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()?;
    let palette = super::bench_anm::PALETTE;
    for (v, name) in report.variants.iter().enumerate() {
        let color = palette[v % palette.len()];
        let pts: Vec<(f64, f64)> = report
            .modes_sweep
            .iter()
            .map(|(m, e)| (*m as f64, e[v]))
            .filter(|p| p.1 > 0.0 && p.1.is_finite())
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
            .label(name.clone())
            .legend(crate::plot::line_key(color.stroke_width(2)));
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
    }
    chart
        .draw_series(LineSeries::new(vec![(0.0, 7e-3), (max_modes * 1.05, 7e-3)], BLACK.stroke_width(1)))?
        .label("seed 000 §3.5.2: below 7e-3")
        .legend(crate::plot::line_key(BLACK.stroke_width(1)));
    crate::plot::legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present()?;
    Ok(())
}

/// A Markdown table header: the leading columns, then one per variant.
fn header(out: &mut impl Write, lead: &[&str], variants: &[String]) -> std::io::Result<()> {
    writeln!(out, "| {} | {} |", lead.join(" | "), variants.join(" | "))?;
    writeln!(out, "|{}", "---:|".repeat(lead.len() + variants.len()))
}

/// Stage 1 of `bench cut`: the organ cut along the scene's `cuts` blade position by blade
/// position, each variant's displacement and opening against the full XFEM's at each; and
/// the enrichment at the final cut.
fn along_the_cuts(model: &OrganModel, v: &Vademecum, cuts: &[Cut], params: &XfemParams) -> anyhow::Result<(Vec<Step>, Enrichment)> {
    let stages = Stages::start("accuracy along the cut");
    let steps_cells = progressive_cells(model, cuts, params)?;
    let mut models: Vec<ReducedCut> = VARIANTS
        .iter()
        .map(|&var| reduced(model, v.f_raw(), v.modes(), var, params))
        .collect::<anyhow::Result<_>>()?;
    let mut steps = Vec::new();
    for (k, cells) in steps_cells.iter().enumerate() {
        stages.stage(&format!("blade position {} of {}", k + 2, steps_cells.len() + 1));
        for m in &mut models {
            m.cut(&model.mesh, cells)?;
        }
        let enr = models[0].enrichment().clone();
        let full = system::solve(&model.mesh, &model.materials, model.locking, &model.problem, &enr, params)?;
        let full_opening_m = (0..enr.len())
            .map(|k| (0..3).map(|i| full.q[3 * k + i].powi(2)).sum::<f64>().sqrt())
            .fold(0.0, f64::max);
        let (mut errors, mut openings_m) = (Vec::new(), Vec::new());
        for m in &models {
            // each model keeps its own order of enriched nodes: compare through its enrichment
            let (u, q) = m.displacements(&model.problem.forces);
            let full_m = system::solve(&model.mesh, &model.materials, model.locking, &model.problem, m.enrichment(), params)?;
            let (e, o) = error(m.enrichment(), &u, &q, &full_m);
            errors.push(e);
            openings_m.push(o);
        }
        steps.push(Step {
            blade_positions: k + 2,
            cut_cells: enr.cut_cells.len(),
            enriched_nodes: enr.len(),
            errors,
            full_opening_m,
            openings_m,
        });
    }
    stages.finish();
    Ok((steps, models[0].enrichment().clone()))
}

/// Stage 2 of `bench cut`: at the final cut, each variant's error against the full XFEM
/// with the first `modes` of the vademecum's modes (and all of them).
fn error_against_modes(
    model: &OrganModel,
    v: &Vademecum,
    modes: &[usize],
    final_enr: &Enrichment,
    final_cells: &[(usize, Plane)],
    params: &XfemParams,
) -> anyhow::Result<Vec<(usize, Vec<f64>)>> {
    let stages = Stages::start("error against modes");
    let full = system::solve(&model.mesh, &model.materials, model.locking, &model.problem, final_enr, params)?;
    let n_modes = v.modes();
    let mut counts: Vec<usize> = modes.iter().copied().filter(|&m| m >= 1 && m <= n_modes).collect();
    if !counts.contains(&n_modes) {
        counts.push(n_modes);
    }
    let n_dofs = model.mesh.n_dofs();
    let mut modes_sweep = Vec::new();
    for &m in &counts {
        stages.stage(&format!("{m} modes"));
        let mut errs = Vec::new();
        for &var in &VARIANTS {
            let mut r = reduced(model, &v.f_raw()[..m * n_dofs], m, var, params)?;
            r.cut(&model.mesh, final_cells)?;
            let (u, q) = r.displacements(&model.problem.forces);
            let full_m = if r.enrichment().nodes == final_enr.nodes {
                None
            } else {
                Some(system::solve(
                    &model.mesh,
                    &model.materials,
                    model.locking,
                    &model.problem,
                    r.enrichment(),
                    params,
                )?)
            };
            errs.push(error(r.enrichment(), &u, &q, full_m.as_ref().unwrap_or(&full)).0);
        }
        modes_sweep.push((m, errs));
    }
    stages.finish();
    Ok(modes_sweep)
}

/// Stage 3 of `bench cut`: what a session's tick adds to the contact compliance, by forward
/// substitution and from the contact table, as the cut grows to each of `enriched` nodes
/// (`ticks_timed` ticks each), with the cost of bordering and tabulating per new node.
fn tick_costs(
    model: &OrganModel,
    v: &Vademecum,
    enriched: &[usize],
    ticks_timed: usize,
    params: &XfemParams,
) -> anyhow::Result<Vec<TickRow>> {
    let stages = Stages::start("tick cost");
    let grow = growing_cells(model);
    let mut ticks = Vec::new();
    for &var in &[(RitzBasis::Srb, Discontinuous::LocalFields), (RitzBasis::Srb, Discontinuous::Bare)] {
        // the same model without and with the contact table of the loadable nodes (a session's)
        let mut r = reduced(model, v.f_raw(), v.modes(), var, params)?;
        let mut tab = r.clone();
        tab.tabulate(v.load_nodes());
        let mut at = 0;
        let (mut border_s, mut table_s, mut bordered) = (0.0, 0.0, 0usize);
        for &target in enriched {
            stages.stage(&format!("{} at {target} enriched nodes", variant_name(var)));
            while r.enrichment().len() < target && at < grow.len() {
                let next = (at + 4).min(grow.len());
                let up = r.cut(&model.mesh, &grow[at..next])?;
                border_s += up.assembly_s + up.bordering_s;
                bordered += up.new_nodes.len();
                table_s += tab.cut(&model.mesh, &grow[at..next])?.tabulating_s;
                at = next;
            }
            if r.enrichment().len() < target {
                stages.warn(&format!(
                    "the organ's planes enrich only {} nodes; {target} not reached",
                    r.enrichment().len()
                ));
                break;
            }
            // the contact: the two loadable nodes nearest the first enriched node
            let first = model.mesh.nodes[r.enrichment().nodes[0]];
            let mut near = v.load_nodes().to_vec();
            let dist = |p: usize| vec3::norm(vec3::sub(model.mesh.nodes[p], first));
            near.sort_by(|&p, &q| dist(p).total_cmp(&dist(q)));
            let (a0, a1) = (near[0], *near.get(1).unwrap_or(&near[0]));
            let null = time_n(ticks_timed, || black_box(0.0));
            // what a session's tick adds to the vademecum's compliance (the Ritz part, which
            // contact_compliance adds, is the uncut model's and not the session's)
            let time = |m: &ReducedCut| {
                let mut view = m.view();
                let mut flip = 0usize;
                time_n(ticks_timed, || {
                    flip += 1;
                    let w = if flip.is_multiple_of(2) { [0.6, 0.4] } else { [0.4, 0.6] };
                    let c = view.added_compliance(&[a0, a1], &w);
                    c[0][0] + c[1][1] + c[2][2]
                })
            };
            let (direct, tabulated) = (time(&r), time(&tab));
            let per_node = |s: f64| 1e6 * s / bordered.max(1) as f64;
            ticks.push(TickRow {
                enriched_nodes: r.enrichment().len(),
                unknowns: r.dim(),
                variant: variant_name(var),
                bytes: r.bytes(),
                border_per_node_us: per_node(border_s),
                table_per_node_us: per_node(table_s),
                table_bytes: tab.table_bytes(),
                table_nodes: v.load_nodes().len(),
                stats: vec![
                    stat("null loop", null),
                    stat("the cut's compliance at the contact, forward substitution (one tick)", direct),
                    stat("the cut's compliance at the contact, contact table (one tick)", tabulated),
                ],
            });
        }
    }
    stages.finish();
    Ok(ticks)
}

impl Report {
    /// The report as `bench cut` prints it (Markdown tables).
    fn print(&self, out: &mut impl Write) -> std::io::Result<()> {
        writeln!(
            out,
            "scene '{}', organ '{}': {} nodes, {} cells; vademecum of {} modes (PGD tolerance {:.0e})\n",
            self.scene, self.organ, self.nodes, self.cells, self.modes, self.pgd_tolerance
        )?;
        writeln!(
            out,
            "Relative L2 error against the full XFEM along the cut (both lips of every node):\n"
        )?;
        header(
            out,
            &["blade positions", "cut cells", "enriched nodes", "opening, full (m)"],
            &self.variants,
        )?;
        for s in &self.steps {
            write!(
                out,
                "| {} | {} | {} | {:.3e} |",
                s.blade_positions, s.cut_cells, s.enriched_nodes, s.full_opening_m
            )?;
            for e in &s.errors {
                write!(out, " {e:.2e} |")?;
            }
            writeln!(out)?;
        }
        writeln!(
            out,
            "\nError at the final cut against the number of modes (plot: {}):\n",
            self.plot.display()
        )?;
        header(out, &["modes"], &self.variants)?;
        for (m, e) in &self.modes_sweep {
            write!(out, "| {m} |")?;
            for x in e {
                write!(out, " {x:.2e} |")?;
            }
            writeln!(out)?;
        }
        writeln!(
            out,
            "\nTick cost against enriched nodes (the 3x3 compliance the cut adds at a two-node contact, what a session's tick adds to the vademecum's; each beside a null loop):\n"
        )?;
        for t in &self.ticks {
            writeln!(
                out,
                "{}: {} enriched nodes, {} unknowns, {:.1} KiB, enriching one node {:.0} µs; contact table of {} loadable nodes {:.1} KiB, extended by {:.0} µs a node",
                t.variant,
                t.enriched_nodes,
                t.unknowns,
                t.bytes as f64 / 1024.0,
                t.border_per_node_us,
                t.table_nodes,
                t.table_bytes as f64 / 1024.0,
                t.table_per_node_us
            )?;
            write_stats(out, &t.stats)?;
            writeln!(out)?;
        }
        if let Some(s) = &self.session {
            writeln!(
                out,
                "The cutting pipeline of a session (the scene's scalpel drawing its pre-planned cuts at 1 kHz: {} cells, {} cracked nodes, {} cut models swapped into the tick):\n",
                s.cut_cells, s.enriched_nodes, s.advances
            )?;
            write_stats(out, &s.ticks)?;
            writeln!(
                out,
                "\nThe same cut, the contact force where the blade pressed along the first cut: the session (vademecum + the cut's local fields) against the full-order XFEM (on an organ that deforms largely, both times the lattice's stiffening at the contact):\n"
            )?;
            writeln!(out, "| point (mm) | session (N) | full XFEM (N) | relative difference |")?;
            writeln!(out, "|---|---|---|---:|")?;
            let v = |x: [f64; 3], s: f64| format!("({:.4}, {:.4}, {:.4})", s * x[0], s * x[1], s * x[2]);
            for f in &s.forces {
                writeln!(
                    out,
                    "| {} | {} | {} | {:.2e} |",
                    v(f.point_m, 1e3),
                    v(f.session_n, 1.0),
                    v(f.full_n, 1.0),
                    f.relative_difference
                )?;
            }
        }
        Ok(())
    }
}

pub fn run(a: BenchCutArgs) -> anyhow::Result<ExitCode> {
    if a.ticks == 0 {
        bail!("--ticks must be at least 1");
    }
    let scene = match &a.scene {
        Some(p) => Scene::load(p)?,
        None => Scene::builtin(&a.builtin)?,
    };
    let cuts = scene.organ_cuts(0)?;
    if cuts.is_empty() {
        bail!(
            "scene '{}' has no pre-planned cuts ([[organs.cuts]]) on its first organ",
            scene.spec.scene.name
        );
    }
    let params = scene.spec.fidelity.xfem.params();
    let stages = Stages::start("vademecum");
    stages.stage(&format!("building the PGD vademecum (tolerance {:.0e})", a.tolerance));
    let opts = BuildOptions {
        params: PgdParams {
            global_tolerance: a.tolerance,
            enrichment_tolerance: 1e-8,
            max_modes: a.max_modes,
            max_iterations: 60,
            block: 1,
        },
        tolerance: a.tolerance,
        recompress: true,
        load_radius: 0.0,
        // an organ cut while it deforms largely: its session needs the lattice
        large: BuildOptions::for_scene(&scene, true).large,
        max_memory: None,
        tear_target_error: None,
        large_target_error: None,
        cut_target_error: None,
    };
    let built = offline::build_organ(&scene, 0, &opts, &mut |_| {}).context("building the vademecum")?;
    stages.finish();
    let model = &built.model;
    anyhow::ensure!(model.laws.is_none(), "cutting by XFEM needs a linear material");
    let v = &built.vademecum;
    let n_modes = v.modes();
    let variants: Vec<String> = VARIANTS.iter().map(|v| variant_name(*v)).collect();

    // 1. along the cuts
    let (steps, final_enr) = along_the_cuts(model, v, &cuts, &params)?;
    let final_cells = final_enr.cut_cells.clone();

    // 2. error against the number of modes, at the final cut
    let modes_sweep = error_against_modes(model, v, &a.modes, &final_enr, &final_cells, &params)?;

    // 3. tick cost against enriched nodes
    let ticks = tick_costs(model, v, &a.enriched, a.ticks, &params)?;

    // 4. the cutting pipeline of a session
    let session = if a.no_session {
        None
    } else {
        let stages = Stages::start("session");
        let r = super::bench_cut_session::run(&scene, &built, a.ticks, &stages)?;
        stages.finish();
        Some(r)
    };

    let plot_file = a
        .plot
        .clone()
        .unwrap_or_else(|| PathBuf::from("out").join(&scene.spec.scene.name).join("cut_modes.svg"));
    if let Some(dir) = plot_file.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let report = Report {
        scene: scene.spec.scene.name.clone(),
        organ: model.name.clone(),
        nodes: model.mesh.n_nodes(),
        cells: model.mesh.n_cells(),
        modes: n_modes,
        pgd_tolerance: a.tolerance,
        variants,
        steps,
        modes_sweep,
        ticks,
        plot: plot_file.clone(),
        session,
    };
    plot(&report, &plot_file)?;
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&report)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    report.print(&mut out)?;
    Ok(ExitCode::SUCCESS)
}
