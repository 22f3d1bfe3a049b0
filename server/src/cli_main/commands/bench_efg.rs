//! `vademecum bench efg`: the meshless solver (seed 004) against Table 3.2, its run time and
//! relaxation steps against node count with 1 and 2 threads, and the 40–100 % stretch range.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use serde::Serialize;
use vademecum_engine::meshless::efg::{self, AdrParams};
use vademecum_engine::meshless::reference::{self, TABLE_3_2};

use super::bench::{print_rows, signed_percent};
use crate::cli_main::cli::BenchEfgArgs;
use crate::cli_main::progress::Stages;

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
        rows.push(run_case(
            reference::cube(n, 0.2, 0.49, 2)?,
            n,
            3,
            0.2,
            threads,
            2,
            reference::TABLE_5_2,
        )?);
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
    Ok(ExitCode::SUCCESS)
}
