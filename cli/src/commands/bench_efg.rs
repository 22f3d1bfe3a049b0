//! `vademecum bench efg`: the meshless solver (seed 004) against Tables 3.2, 5.2 and 4.2: run
//! time and relaxation steps against node count with 1 and 2 threads, the 40–100 % stretch
//! range in 2D and 3D, and the cutting experiment of Fig. 4.8 with regular and refined nodes.

use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use plotters::prelude::*;
use serde::Serialize;
use vademecum_engine::meshless::efg::{self, AdrParams};
use vademecum_engine::meshless::reference::{self, CutSetup, CutStudy, FIG_4_8, TABLE_3_2, TABLE_4_2};

use super::bench::{print_rows, signed_percent};
use crate::cli::BenchEfgArgs;
use crate::progress::Stages;

#[derive(Debug, Serialize)]
struct Row {
    nodes: usize,
    dim: usize,
    integration_points: usize,
    per_cell: usize,
    stretch: f64,
    threads: usize,
    energy_j: f64,
    force_n: f64,
    energy_error: Option<f64>,
    force_error: Option<f64>,
    steps: usize,
    seconds: f64,
}

fn run_one(n: usize, stretch: f64, threads: usize, q: usize) -> anyhow::Result<Row> {
    run_case(reference::square(n, stretch, 0.49, q)?, n, 2, stretch, threads, q, TABLE_3_2)
}

fn run_case(
    case: reference::Pulled,
    n: usize,
    dim: usize,
    stretch: f64,
    threads: usize,
    q: usize,
    seed: (f64, f64),
) -> anyhow::Result<Row> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("thread pool")?;
    let bar = Stages::start(&format!("{n}^{dim} nodes, {:.0} % stretch, {threads} thread(s)", 100.0 * stretch));
    let t = Instant::now();
    let s = pool
        .install(|| {
            efg::solve(&case.problem, &AdrParams::default(), |step, e| {
                bar.stage(&format!("step {step}, error {e:.2e} m"))
            })
        })
        .with_context(|| format!("{n}^{dim} nodes at {stretch} stretch"))?;
    let seconds = t.elapsed().as_secs_f64();
    bar.finish();
    let force = case.force(&s);
    let at_seed = (stretch - 0.2).abs() < 1e-12;
    Ok(Row {
        nodes: n.pow(dim as u32),
        dim,
        integration_points: case.problem.points.len(),
        per_cell: q.pow(dim as u32),
        stretch,
        threads,
        energy_j: s.energy,
        force_n: force,
        energy_error: at_seed.then(|| s.energy / seed.0 - 1.0),
        force_error: at_seed.then(|| force / seed.1 - 1.0),
        steps: s.steps,
        seconds,
    })
}

pub fn run(a: BenchEfgArgs) -> anyhow::Result<ExitCode> {
    if a.nodes.iter().chain([&a.range_nodes]).any(|&n| !(3..=201).contains(&n)) || a.threads.contains(&0) {
        bail!("--nodes must lie in 3..=201 per edge and --threads be at least 1");
    }
    if a.cube_nodes.iter().any(|&n| !(3..=41).contains(&n)) {
        bail!("--cube-nodes must lie in 3..=41 per edge");
    }
    if a.integration.is_empty() || a.integration.iter().any(|&q| !(1..=4).contains(&q)) {
        bail!("--integration takes points per cell side in 1..=4");
    }
    let mut rows = Vec::new();
    for &q in &a.integration {
        for &n in &a.nodes {
            for &t in &a.threads {
                rows.push(run_one(n, 0.2, t, q)?);
            }
        }
    }
    let q = *a.integration.last().unwrap_or(&2);
    let threads = *a.threads.last().unwrap_or(&1);
    for &s in &a.stretch {
        rows.push(run_one(a.range_nodes, s, threads, q)?);
    }
    for &n in &a.cube_nodes {
        for &t in &a.threads {
            rows.push(run_case(reference::cube(n, 0.2, 0.49, 2)?, n, 3, 0.2, t, 2, reference::TABLE_5_2)?);
        }
    }
    if let Some(n) = a.cube_range_nodes {
        for &s in &a.stretch {
            rows.push(run_case(
                reference::cube(n, s, 0.49, 2)?,
                n,
                3,
                s,
                threads,
                2,
                reference::TABLE_5_2,
            )?);
        }
    }
    print_rows(
        a.json,
        &rows,
        &[
            "problem",
            "nodes",
            "integration points (per cell)",
            "stretch",
            "threads",
            "energy (J, 2D: J/m)",
            "vs seed",
            "reaction (N, 2D: N/m)",
            "vs seed",
            "steps",
            "time (s)",
        ],
        |r| {
            vec![
                if r.dim == 2 { "square (2D)" } else { "cube (3D)" }.to_string(),
                r.nodes.to_string(),
                format!("{} ({})", r.integration_points, r.per_cell),
                format!("{:.0} %", 100.0 * r.stretch),
                r.threads.to_string(),
                format!("{:.4}", r.energy_j),
                signed_percent(r.energy_error),
                format!("{:.3}", r.force_n),
                signed_percent(r.force_error),
                r.steps.to_string(),
                format!("{:.2}", r.seconds),
            ]
        },
    )?;
    if a.cut_nodes.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    let mut cuts = Vec::new();
    let mut first: Option<CutStudy> = None;
    for &n in &a.cut_nodes {
        for refined in [false, true] {
            for from_surface in [true, false] {
                if !from_surface && !a.cut_at_a {
                    continue;
                }
                let setup = CutSetup {
                    nodes: n,
                    integration: 2,
                    from_surface,
                    refined,
                };
                let (row, study) = run_cut(&setup, threads)?;
                cuts.push(row);
                if first.is_none() && !refined && from_surface {
                    first = Some(study);
                }
            }
        }
    }
    println!();
    print_rows(
        a.json,
        &cuts,
        &[
            "cut (Fig. 4.8)",
            "nodes",
            "W after AB / BC / CD (J/m)",
            "vs seed",
            "reaction (N/m)",
            "vs seed",
            "steps",
            "time (s)",
        ],
        |r| {
            vec![
                format!(
                    "{} nodes, {}",
                    if r.refined { "refined" } else { "regular" },
                    if r.from_surface { "from the edge" } else { "from A" }
                ),
                format!("{} ({}²)", r.nodes, r.grid),
                r.stage_energies.iter().map(|e| format!("{e:.4}")).collect::<Vec<_>>().join(" / "),
                signed_percent(Some(r.energy_error)),
                format!("{:.3}", r.force_n),
                signed_percent(Some(r.force_error)),
                r.steps.to_string(),
                format!("{:.2}", r.seconds),
            ]
        },
    )?;
    if let (Some(file), Some(study)) = (&a.plot, &first) {
        plot_cut(study, file)?;
        eprintln!("wrote {}", file.display());
    }
    Ok(ExitCode::SUCCESS)
}

#[derive(Debug, Serialize)]
struct CutRow {
    grid: usize,
    refined: bool,
    from_surface: bool,
    nodes: usize,
    stage_energies: Vec<f64>,
    energy_j: f64,
    force_n: f64,
    energy_error: f64,
    force_error: f64,
    /// Relaxation steps, uncut and the three stages.
    steps: usize,
    seconds: f64,
}

fn run_cut(setup: &CutSetup, threads: usize) -> anyhow::Result<(CutRow, CutStudy)> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("thread pool")?;
    let bar = Stages::start(&format!(
        "cut, {}^2 nodes{}",
        setup.nodes,
        if setup.refined { " refined around the cut" } else { "" }
    ));
    let t = Instant::now();
    let study = pool
        .install(|| {
            reference::square_cut(setup, &AdrParams::default(), |stage, step, e| {
                let what = ["stretching", "cut A-B", "cut B-C", "cut C-D"][stage.min(3)];
                bar.stage(&format!("{what}: step {step}, error {e:.2e} m"))
            })
        })
        .with_context(|| format!("cutting study on {}^2 nodes", setup.nodes))?;
    let seconds = t.elapsed().as_secs_f64();
    bar.finish();
    let end = study.stages.last().context("no stage")?;
    let row = CutRow {
        grid: setup.nodes,
        refined: setup.refined,
        from_surface: setup.from_surface,
        nodes: end.cloud_size,
        stage_energies: study.stages.iter().map(|s| s.solution.energy).collect(),
        energy_j: end.solution.energy,
        force_n: end.force,
        energy_error: end.solution.energy / TABLE_4_2.0 - 1.0,
        force_error: end.force / TABLE_4_2.1 - 1.0,
        steps: study.uncut.steps + study.stages.iter().map(|s| s.solution.steps).sum::<usize>(),
        seconds,
    };
    Ok((row, study))
}

/// The cut specimen at the end of cutting: every node at its displaced position `X + u(X)`,
/// the faces' nodes coloured by side, and the seed's path A–B–C–D as drawn on the stretched
/// body before cutting.
fn plot_cut(study: &CutStudy, file: &Path) -> anyhow::Result<()> {
    let end = study.stages.last().context("no stage")?;
    let cloud = &study.cloud;
    let u = &end.solution.displacement;
    let root = crate::plot::canvas(file, (760, 700))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "EFG cut along A-B-C-D (seed 004 Fig. 4.8): W = {:.4} J/m, F = {:.2} N/m",
                end.solution.energy, end.force
            ),
            ("sans-serif", 16),
        )
        .margin(14)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.005..0.125, -0.005..0.105)?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("x (m)")
        .y_desc("y (m)")
        .draw()?;
    let sides = cloud.sides().unwrap_or(&[]);
    let cut = cloud.cut();
    let on_cut = |i: usize| cut.is_some_and(|c| c.distance(cloud.points()[i]) < 1e-9);
    let at = |i: usize| (cloud.points()[i][0] + u[2 * i], cloud.points()[i][1] + u[2 * i + 1]);
    let blue = RGBColor(31, 119, 180);
    let orange = RGBColor(255, 127, 14);
    chart.draw_series(
        (0..cloud.len())
            .filter(|&i| !on_cut(i))
            .map(|i| Circle::new(at(i), 1, RGBColor(90, 90, 90).filled())),
    )?;
    for (side, color, label) in [(1.0, blue, "nodes of one face"), (-1.0, orange, "nodes of the other face")] {
        chart
            .draw_series(
                (0..cloud.len())
                    .filter(|&i| on_cut(i) && sides.get(i) == Some(&side))
                    .map(|i| Circle::new(at(i), 3, color.filled())),
            )?
            .label(label)
            .legend(move |(x, y)| Circle::new((x + 8, y), 3, color.filled()));
    }
    let red = RGBColor(214, 39, 40);
    chart
        .draw_series(LineSeries::new(FIG_4_8.iter().map(|p| (p[0], p[1])), red.stroke_width(2)))?
        .label("A-B-C-D drawn on the stretched body")
        .legend(crate::plot::line_key(red.stroke_width(2)));
    for (p, name) in FIG_4_8.iter().zip(["A", "B", "C", "D"]) {
        chart.draw_series(std::iter::once(Text::new(name, (p[0] + 0.0015, p[1]), ("sans-serif", 14))))?;
    }
    crate::plot::legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present()?;
    Ok(())
}
