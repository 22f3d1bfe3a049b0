//! `vademecum bench corot`: what one equilibrium iteration of the co-rotational XFEM (seed 003
//! §3.1) costs on a tetrahedral mesh with a number of cut cells — the elastic forces (a polar
//! decomposition per side), the warped stiffness, its Cholesky factorization (the symbolic
//! analysis done once) and the solve — beside a null loop measured in the same run; and what a
//! frame of the session's deformation costs with the factor kept across frames
//! (`xfem::corotational::Frames`: the forces twice and a solve).

use std::hint::black_box;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use serde::Serialize;
use vademecum_engine::fem::assembly::MaterialMap;
use vademecum_engine::fem::linear_static::StaticProblem;
use vademecum_engine::material::LinearElastic;
use vademecum_engine::mesh::{self, Mesh, procedural};
use vademecum_engine::solve::Cholesky;
use vademecum_engine::xfem::corotational::CorotationalXfem;
use vademecum_engine::xfem::{Enrichment, Plane, XfemParams};

use super::bench_pgd::{Stat, stat, time_n, write_stats};
use crate::cli::BenchCorotArgs;

/// One mesh with one number of cut cells.
#[derive(Debug, Serialize)]
struct Row {
    mesh: String,
    nodes: usize,
    cells: usize,
    cut_cells: usize,
    enriched_nodes: usize,
    sides: usize,
    free_dofs: usize,
    /// p50 of each part (ms): forces, stiffness, factorization, solve; and their sum.
    forces_ms: f64,
    stiffness_ms: f64,
    factor_ms: f64,
    solve_ms: f64,
    iteration_ms: f64,
    iterations_per_second: f64,
    /// A frame of the session's deformation with a factor kept across frames
    /// (`Frames::step`): the forces twice (the correction is kept if it lowers the residual)
    /// and one solve.
    frame_ms: f64,
    frames_per_second: f64,
}

#[derive(Debug, Serialize)]
struct Report {
    rows: Vec<Row>,
    null_loop: Stat,
}

/// The first `n` cells (by distance from the mesh's centre) a plane through its centre crosses.
fn cut(mesh: &Mesh, n: usize) -> anyhow::Result<Enrichment> {
    let (lo, hi) = mesh.bounding_box();
    let centre: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
    let len = (1.0f64 + 0.09 + 0.04).sqrt();
    let plane = Plane {
        point: centre,
        normal: [1.0 / len, 0.3 / len, 0.2 / len],
    };
    let mut cells = Enrichment::cells_crossed_by(mesh, &plane);
    let dist = |c: usize| {
        let cell = mesh.cell(c);
        (0..3)
            .map(|k| (cell.iter().map(|&a| mesh.nodes[a][k]).sum::<f64>() / cell.len() as f64 - centre[k]).powi(2))
            .sum::<f64>()
    };
    cells.sort_by(|a, b| dist(a.0).total_cmp(&dist(b.0)));
    cells.truncate(n);
    Enrichment::from_cut_cells(mesh, &cells, &XfemParams::default()).context("enriching the cut cells")
}

fn p50(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

pub fn run(a: BenchCorotArgs) -> anyhow::Result<ExitCode> {
    if a.iterations == 0 {
        anyhow::bail!("--iterations must be at least 1");
    }
    let meshes: Vec<(String, Mesh)> = if a.meshes.is_empty() {
        vec![(
            "built-in block 24 x 6 x 6".into(),
            procedural::block_tet([0.0; 3], [4.0, 1.0, 1.0], [24, 6, 6]),
        )]
    } else {
        a.meshes
            .iter()
            .map(|p: &PathBuf| {
                let m = mesh::read(p).with_context(|| format!("reading {}", p.display()))?;
                Ok((
                    p.file_name()
                        .map_or_else(|| p.display().to_string(), |f| f.to_string_lossy().into_owned()),
                    m,
                ))
            })
            .collect::<anyhow::Result<_>>()?
    };
    let mut rows = Vec::new();
    for (name, mesh) in &meshes {
        let (lo, hi) = mesh.bounding_box();
        let size = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        // held at its lowest tenth along z
        let mut problem = StaticProblem::new(mesh.n_nodes());
        let held: Vec<usize> = (0..mesh.n_nodes())
            .filter(|&i| mesh.nodes[i][2] <= lo[2] + 0.1 * (hi[2] - lo[2]))
            .collect();
        problem.clamp(&held);
        let mats = MaterialMap::uniform(LinearElastic::new(3000.0, 0.45)?, 1000.0, mesh.n_cells());
        for &n in &a.cuts {
            eprintln!("vademecum: {name}, {n} cut cells");
            let enr = cut(mesh, n)?;
            let model = CorotationalXfem::new(mesh, &mats, &problem, &enr).map_err(|e| anyhow::anyhow!("{e}"))?;
            // a turned and stretched state: every side has a rotation to find
            let d: Vec<f64> = (0..model.n_dofs())
                .map(|k| {
                    if k < 3 * mesh.n_nodes() {
                        0.01 * size * ((k as f64) * 0.37).sin()
                    } else {
                        0.0
                    }
                })
                .collect();
            let forces = time_n(a.iterations, || black_box(model.internal_forces(&d))[0]);
            let mut k = model.tangent(&d);
            let stiffness = time_n(a.iterations, || {
                k = model.tangent(&d);
                k.values[0]
            });
            let symbolic = Cholesky::analyze(&k)?;
            let mut chol = Cholesky::factor_with(symbolic.clone(), &k)?;
            let factor = time_n(a.iterations, || {
                chol = Cholesky::factor_with(symbolic.clone(), &k).expect("factored once already");
                0.0
            });
            let mut r = vec![1.0; chol.n()];
            let solve = time_n(a.iterations, || {
                r.fill(1.0);
                chol.solve_in_place(&mut r);
                r[0]
            });
            let ms = |v: &[f64]| p50(v) / 1e3;
            let iteration_ms = ms(&forces) + ms(&stiffness) + ms(&factor) + ms(&solve);
            let frame_ms = 2.0 * ms(&forces) + ms(&solve);
            rows.push(Row {
                mesh: name.clone(),
                nodes: mesh.n_nodes(),
                cells: mesh.n_cells(),
                cut_cells: enr.cut_cells.len(),
                enriched_nodes: enr.len(),
                sides: model.n_sides(),
                free_dofs: chol.n(),
                forces_ms: ms(&forces),
                stiffness_ms: ms(&stiffness),
                factor_ms: ms(&factor),
                solve_ms: ms(&solve),
                iteration_ms,
                iterations_per_second: 1e3 / iteration_ms,
                frame_ms,
                frames_per_second: 1e3 / frame_ms,
            });
        }
    }
    let report = Report {
        rows,
        null_loop: stat("null loop", time_n(10_000, || black_box(0.0))),
    };
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&report)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(
        out,
        "one equilibrium iteration of the co-rotational XFEM (p50 of {} each, ms)\n\n| mesh | nodes | cells | cut cells | enriched nodes | sides | free dofs | forces | stiffness | factor | solve | iteration | iterations/s | frame, factor kept | frames/s |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        a.iterations
    )?;
    for r in &report.rows {
        writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} | {:.2} | {:.1} |",
            r.mesh,
            r.nodes,
            r.cells,
            r.cut_cells,
            r.enriched_nodes,
            r.sides,
            r.free_dofs,
            r.forces_ms,
            r.stiffness_ms,
            r.factor_ms,
            r.solve_ms,
            r.iteration_ms,
            r.iterations_per_second,
            r.frame_ms,
            r.frames_per_second
        )?;
    }
    writeln!(out)?;
    write_stats(&mut out, std::slice::from_ref(&report.null_loop))?;
    Ok(ExitCode::SUCCESS)
}
