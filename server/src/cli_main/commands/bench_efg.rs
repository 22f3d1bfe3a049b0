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
    let case = reference::square(n, stretch, 0.49, q)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("thread pool")?;
    let bar = Stages::start(&format!("{n} x {n} nodes, {:.0} % stretch, {threads} thread(s)", 100.0 * stretch));
    let t = Instant::now();
    let s = pool
        .install(|| {
            efg::solve(&case.problem, &AdrParams::default(), |step, e| {
                bar.stage(&format!("step {step}, error {e:.2e} m"))
            })
        })
        .with_context(|| format!("{n} x {n} nodes at {stretch} stretch"))?;
    let seconds = t.elapsed().as_secs_f64();
    bar.finish();
    let force = case.force(&s);
    let at_seed = (stretch - 0.2).abs() < 1e-12;
    Ok(Row {
        nodes: n * n,
        integration_points: case.problem.points.len(),
        per_cell: q * q,
        stretch,
        threads,
        energy_j: s.energy,
        force_n: force,
        energy_error: at_seed.then(|| s.energy / TABLE_3_2.0 - 1.0),
        force_error: at_seed.then(|| force / TABLE_3_2.1 - 1.0),
        steps: s.steps,
        seconds,
    })
}

pub fn run(a: BenchEfgArgs) -> anyhow::Result<ExitCode> {
    if a.nodes.iter().chain([&a.range_nodes]).any(|&n| !(3..=201).contains(&n)) || a.threads.contains(&0) {
        bail!("--nodes must lie in 3..=201 per edge and --threads be at least 1");
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
    for &s in &a.stretch {
        rows.push(run_one(a.range_nodes, s, *a.threads.last().unwrap_or(&1), q)?);
    }
    print_rows(
        a.json,
        &rows,
        &[
            "nodes",
            "integration points (per cell)",
            "stretch",
            "threads",
            "energy (J/m)",
            "vs seed",
            "reaction (N/m)",
            "vs seed",
            "steps",
            "time (s)",
        ],
        |r| {
            vec![
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
