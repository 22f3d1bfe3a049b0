//! `vademecum bench cube`: the full-order large-deformation solver against seed 004 Table 5.2
//! (a 0.1 m Abaqus neo-Hookean cube, E = 3000 Pa, ν = 0.49, face y = 0 clamped, face
//! y = 0.1 m pulled in y with its x and z motion fixed; Abaqus with 17,576 nodes, hybrid
//! elements: 0.06477 J and 6.109 N at 20 % stretch), on n³ hexahedra with the mean-dilatation
//! (Q1/P0) element and with full integration (which locks), and on the same cubes split into
//! six tetrahedra each with the averaged nodal pressure and plain (which locks); then the
//! 40–100 % stretch range on hexahedra.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::bail;
use clap::ValueEnum;
use serde::Serialize;
use vademecum_engine::fem::hyperelastic::{LawMap, Volumetric};
use vademecum_engine::fem::linear_static::StaticProblem;
use vademecum_engine::fem::nonlinear_static::{self, NewtonParams};
use vademecum_engine::material::LinearElastic;
use vademecum_engine::material::hyperelastic::Hyperelastic;
use vademecum_engine::mesh::CellKind;
use vademecum_engine::mesh::procedural::{block_hex, block_tet};

use super::bench::{print_rows, signed_percent};
use crate::cli::{BenchCubeArgs, CubeElement};

/// Seed 004 Table 5.2 at 20 % stretch.
const SEED_ENERGY_J: f64 = 0.06477;
const SEED_FORCE_N: f64 = 6.109;

#[derive(Debug, Serialize)]
struct Row {
    cells: usize,
    nodes: usize,
    element: &'static str,
    stretch: f64,
    energy_j: f64,
    force_n: f64,
    energy_error: Option<f64>,
    force_error: Option<f64>,
    steps: usize,
    iterations: usize,
    cuts: usize,
    seconds: f64,
}

fn solve(n: usize, kind: CellKind, volumetric: Volumetric, stretch: f64, steps: usize) -> anyhow::Result<Row> {
    let mesh = match kind {
        CellKind::Hex8 => block_hex([0.0; 3], [0.1; 3], [n, n, n]),
        CellKind::Tet4 => block_tet([0.0; 3], [0.1; 3], [n, n, n]),
    };
    let on = |y: f64| -> Vec<usize> { (0..mesh.n_nodes()).filter(|&i| (mesh.nodes[i][1] - y).abs() < 1e-9).collect() };
    let (bottom, top) = (on(0.0), on(0.1));
    let mut p = StaticProblem::new(mesh.n_nodes());
    p.clamp(&bottom);
    p.prescribe(&top, 0, 0.0);
    p.prescribe(&top, 2, 0.0);
    p.prescribe(&top, 1, 0.1 * stretch);
    let law = Hyperelastic::neo_hookean(&LinearElastic::new(3000.0, 0.49)?);
    let params = NewtonParams {
        steps,
        ..NewtonParams::default()
    };
    let t = Instant::now();
    let s = nonlinear_static::solve(&mesh, &LawMap::uniform(law, mesh.n_cells()), volumetric, &p, &params, |_, _| {})?;
    let force = s.reaction_sum(&top)[1];
    let seed = (stretch - 0.2).abs() < 1e-12;
    Ok(Row {
        cells: n,
        nodes: mesh.n_nodes(),
        element: match (kind, volumetric) {
            (CellKind::Hex8, Volumetric::MeanDilatation | Volumetric::Nodal) => "hex8, mean dilatation",
            (CellKind::Hex8, Volumetric::PointWise) => "hex8, full integration",
            (CellKind::Tet4, Volumetric::Nodal) => "tet4, nodal pressure",
            (CellKind::Tet4, _) => "tet4, plain",
        },
        stretch,
        energy_j: s.energy,
        force_n: force,
        energy_error: seed.then(|| s.energy / SEED_ENERGY_J - 1.0),
        force_error: seed.then(|| force / SEED_FORCE_N - 1.0),
        steps: s.info.steps,
        iterations: s.info.iterations,
        cuts: s.info.cuts,
        seconds: t.elapsed().as_secs_f64(),
    })
}

pub fn run(a: BenchCubeArgs) -> anyhow::Result<ExitCode> {
    if a.cells.iter().any(|&n| !(2..=40).contains(&n)) || !(2..=40).contains(&a.range_cells) {
        bail!("--cells and --range-cells must lie in [2, 40] cells per edge");
    }
    let elements: Vec<CubeElement> = if a.elements.is_empty() {
        CubeElement::value_variants().to_vec()
    } else {
        a.elements.clone()
    };
    let range = elements.contains(&CubeElement::Hex8MeanDilatation);
    let solves = a.cells.len() * elements.len() + if range { a.stretch.len() } else { 0 };
    let mut bar = crate::progress::Steps::start("bench cube", solves);
    let mut rows = Vec::new();
    for &n in &a.cells {
        for &e in &elements {
            let (kind, v) = cell(e);
            bar.step(&format!("{n}³ cubes, {e:?}, 20 % stretch"));
            rows.push(solve(n, kind, v, 0.2, 4)?);
        }
    }
    // the range study is the mean-dilatation hexahedron's
    for &s in a.stretch.iter().filter(|_| range) {
        bar.step(&format!("{}³ cells, {:.0} % stretch", a.range_cells, 100.0 * s));
        rows.push(solve(
            a.range_cells,
            CellKind::Hex8,
            Volumetric::MeanDilatation,
            s,
            (s / 0.05).ceil() as usize,
        )?);
    }
    bar.finish();
    print_rows(
        a.json,
        &rows,
        &[
            "cells",
            "nodes",
            "element",
            "stretch",
            "energy (J)",
            "vs seed",
            "reaction (N)",
            "vs seed",
            "steps / iterations / cuts",
            "time (s)",
        ],
        |r| {
            vec![
                format!("{}³", r.cells),
                r.nodes.to_string(),
                r.element.to_string(),
                format!("{:.0} %", 100.0 * r.stretch),
                format!("{:.5}", r.energy_j),
                signed_percent(r.energy_error),
                format!("{:.4}", r.force_n),
                signed_percent(r.force_error),
                format!("{} / {} / {}", r.steps, r.iterations, r.cuts),
                format!("{:.1}", r.seconds),
            ]
        },
    )?;
    Ok(ExitCode::SUCCESS)
}

/// The cell and volumetric treatment of element `e`.
fn cell(e: CubeElement) -> (CellKind, Volumetric) {
    match e {
        CubeElement::Hex8MeanDilatation => (CellKind::Hex8, Volumetric::MeanDilatation),
        CubeElement::Hex8Full => (CellKind::Hex8, Volumetric::PointWise),
        CubeElement::Tet4Nodal => (CellKind::Tet4, Volumetric::Nodal),
        CubeElement::Tet4Plain => (CellKind::Tet4, Volumetric::PointWise),
    }
}
