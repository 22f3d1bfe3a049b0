//! `vademecum bench fe`: assembly, factorization and solve time of the static problem on the
//! built-in block at several sizes.

use std::io::Write;
use std::process::ExitCode;

use anyhow::bail;
use serde::Serialize;
use vademecum_engine::fem::Locking;
use vademecum_engine::fem::assembly::MaterialMap;
use vademecum_engine::fem::linear_static::{self, StaticProblem};
use vademecum_engine::material::LinearElastic;
use vademecum_engine::mesh::{Mesh, procedural, select::Region};

use crate::cli::{BenchFeArgs, CellArg};
use crate::progress::Stages;

#[derive(Debug, Serialize)]
struct Row {
    cell: &'static str,
    divisions: [usize; 3],
    nodes: usize,
    dofs: usize,
    equations: usize,
    nonzeros_lower: usize,
    assembly_s: f64,
    analysis_s: f64,
    factorization_s: f64,
    solve_s: f64,
    threads: usize,
}

/// The 4:1:1 bar whose node count `(4n+1)(n+1)²` is closest to `dofs/3`.
fn bar_for(dofs: usize, cell: CellArg) -> (Mesh, [usize; 3]) {
    let target = dofs as f64 / 3.0;
    let n = (1..400).min_by(|&a, &b| {
        let f = |n: usize| (((4 * n + 1) * (n + 1) * (n + 1)) as f64 - target).abs();
        f(a).total_cmp(&f(b))
    });
    let n = n.unwrap_or(1);
    let (size, div) = ([0.4, 0.1, 0.1], [4 * n, n, n]);
    let mesh = match cell {
        CellArg::Hex8 => procedural::block_hex([0.0; 3], size, div),
        CellArg::Tet4 => procedural::block_tet([0.0; 3], size, div),
    };
    (mesh, div)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

pub fn run_fe(a: BenchFeArgs) -> anyhow::Result<ExitCode> {
    if a.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    let threads = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let mut rows = Vec::new();
    for &dofs in &a.dofs {
        let (mesh, divisions) = bar_for(dofs, a.cell);
        let mat = MaterialMap::uniform(LinearElastic::new(1e5, 0.45)?, 1000.0, mesh.n_cells());
        let mut p = StaticProblem::new(mesh.n_nodes());
        p.clamp(
            &Region::Box {
                min: [0.0; 3],
                max: [0.0, 0.1, 0.1],
            }
            .nodes(&mesh)?,
        );
        let tip = Region::Box {
            min: [0.4, 0.0, 0.0],
            max: [0.4, 0.1, 0.1],
        }
        .nodes(&mesh)?;
        vademecum_engine::fem::loads::add_distributed_force(&mut p.forces, &tip, [0.0, 0.0, -1.0]);
        let mut times: [Vec<f64>; 4] = Default::default();
        let mut last = None;
        for r in 0..a.repeat {
            let bar = Stages::start(&format!("{} dofs, run {}/{}", mesh.n_dofs(), r + 1, a.repeat));
            let sol = linear_static::solve(&mesh, &mat, Locking::Bbar, &p, &mut |s| bar.stage(s.label()))?;
            bar.finish();
            times[0].push(sol.timings.assembly_s);
            times[1].push(sol.timings.analysis_s);
            times[2].push(sol.timings.factorization_s);
            times[3].push(sol.timings.solve_s);
            last = Some((sol.n_free, sol.nnz));
        }
        let (equations, nnz) = last.unwrap_or((0, 0));
        let [t0, t1, t2, t3] = times;
        rows.push(Row {
            cell: mesh.kind.name(),
            divisions,
            nodes: mesh.n_nodes(),
            dofs: mesh.n_dofs(),
            equations,
            nonzeros_lower: nnz,
            assembly_s: median(t0),
            analysis_s: median(t1),
            factorization_s: median(t2),
            solve_s: median(t3),
            threads,
        });
    }
    print_rows(
        a.json,
        &rows,
        &[
            "cell",
            "nodes",
            "dofs",
            "nnz (lower)",
            "assembly (s)",
            "analysis (s)",
            "factorization (s)",
            "solve (s)",
        ],
        |r| {
            vec![
                r.cell.to_string(),
                r.nodes.to_string(),
                r.dofs.to_string(),
                r.nonzeros_lower.to_string(),
                format!("{:.3}", r.assembly_s),
                format!("{:.3}", r.analysis_s),
                format!("{:.3}", r.factorization_s),
                format!("{:.4}", r.solve_s),
            ]
        },
    )?;
    if !a.json {
        println!("median of {} run(s), {} hardware thread(s)", a.repeat, threads);
    }
    Ok(ExitCode::SUCCESS)
}

/// Prints `rows` as pretty JSON, or as a Markdown table: the `header` titles, then `row` of
/// each (the cells, already formatted).
pub(crate) fn print_rows<T: Serialize>(json: bool, rows: &[T], header: &[&str], row: impl Fn(&T) -> Vec<String>) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(rows)?)?;
        return Ok(());
    }
    writeln!(out, "| {} |", header.join(" | "))?;
    // the first column names the row: left-aligned; the figures right-aligned
    writeln!(out, "|---|{}", "---:|".repeat(header.len().saturating_sub(1)))?;
    for r in rows {
        writeln!(out, "| {} |", row(r).join(" | "))?;
    }
    Ok(())
}

/// A relative error as a signed percentage, or a dash when there is no reference.
pub(crate) fn signed_percent(e: Option<f64>) -> String {
    e.map_or("—".to_string(), |e| format!("{:+.2} %", 100.0 * e))
}
