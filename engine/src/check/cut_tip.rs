//! A cut that ends inside a cell, by the crack-tip enrichment of [`crate::xfem::tip`] (issue
//! 47), on the edge-crack block of `docs/cutting.md` ("Where the cut ends"): 0.1 × 0.1 × 0.02 m,
//! n × n × n/5 hexahedra (B̄), E = 3 kPa, ν = 0.45, the base clamped, 30 Pa pulling the top, a
//! through-thickness cut from the left face at mid-height. The blade stops on a line of nodes,
//! on a cell face, inside a cell (a 20° cut), within 1e-9 of a node line and of a face (the
//! energy must not jump: against the blade exactly there), at the block's far face (the top
//! cut loose), inside a cell of tetrahedra; malformed tip lines and the averaged nodal
//! pressure are typed refusals.

use super::{Case, Expect, Outcome, Size, diagnostic, finite, outcome, relative};
use crate::fem::Locking;
use crate::fem::assembly::MaterialMap;
use crate::fem::linear_static::StaticProblem;
use crate::geometry::cut::Cut;
use crate::material::LinearElastic;
use crate::mesh::{Mesh, procedural};
use crate::xfem::tip::{self, Branch, TipEnrichment, TipLine, TipParams};
use crate::xfem::{Front, XfemParams};

/// The method's name in the table.
const METHOD: &str = "XFEM, crack-tip enrichment";

/// Cells along the block's side.
fn cells(size: Size) -> usize {
    size.pick(10, 20)
}

/// The block and its load (module docs), of hexahedra or (`tets`) six tetrahedra per box.
fn block(n: usize, tets: bool) -> (Mesh, StaticProblem) {
    let nz = (n / 5).max(1);
    let make = if tets { procedural::block_tet } else { procedural::block_hex };
    let mesh = make([0.0; 3], [0.1, 0.1, 0.02], [n, n, nz]);
    let (hx, hz) = (0.1 / n as f64, 0.02 / nz as f64);
    let mut p = StaticProblem::new(mesh.n_nodes());
    for (a, x) in mesh.nodes.iter().enumerate() {
        if x[1] == 0.0 {
            p.clamp(&[a]);
        }
        if (x[1] - 0.1).abs() < 1e-12 {
            // consistent nodal forces of a uniform traction on bilinear faces
            let wx = if x[0] == 0.0 || (x[0] - 0.1).abs() < 1e-12 { 0.5 } else { 1.0 };
            let wz = if x[2] == 0.0 || (x[2] - 0.02).abs() < 1e-12 { 0.5 } else { 1.0 };
            p.forces[3 * a + 1] = 30.0 * wx * hx * wz * hz;
        }
    }
    (mesh, p)
}

/// The cut from 5 mm outside the left face to `length` along the direction `angle` (rad)
/// above the horizontal, through the whole thickness, and where its blade stopped.
fn edge_cut(angle: f64, length: f64) -> Result<(Cut, TipLine), Outcome> {
    let (c, s) = (angle.cos(), angle.sin());
    let at = |t: f64| ([t * c, 0.05 + t * s, -0.001], [t * c, 0.05 + t * s, 0.021]);
    let cut = Cut::swept(&[at(-0.005), at(length)]).map_err(diagnostic)?;
    let (a, b) = at(length);
    Ok((
        cut,
        TipLine {
            a,
            b,
            normal: [-s, c, 0.0],
            forward: [c, s, 0.0],
        },
    ))
}

/// The strain energy `½ fᵀu` (J) of the block cut to `length` at `angle` with the blade's
/// edge enriched by `√r sin(θ/2)`, and how many nodes carry it; a broken outcome for a
/// residual above 1e-8 or a non-finite field. Hexahedra with B̄, tetrahedra for
/// [`Locking::None`] and [`Locking::Nodal`].
fn energy(n: usize, angle: f64, length: f64, locking: Locking) -> Result<(f64, usize), Outcome> {
    let (mesh, p) = block(n, locking == Locking::Nodal || locking == Locking::None);
    let mats = MaterialMap::uniform(LinearElastic::new(3e3, 0.45).map_err(diagnostic)?, 1000.0, mesh.n_cells());
    let (cut, line) = edge_cut(angle, length)?;
    let params = XfemParams {
        front: Front::Shared,
        ..XfemParams::default()
    };
    let tp = TipParams {
        branch: Branch::Jump,
        ..TipParams::default()
    };
    let enr = TipEnrichment::new(&mesh, &cut, &line, &params, tp).map_err(diagnostic)?;
    let x = tip::solve(&mesh, &mats, locking, &p, &enr).map_err(diagnostic)?;
    let good = finite(&x.u) && finite(&x.q) && x.residual <= 1e-8;
    if !good {
        return Err(Outcome::Broken(format!(
            "residual {:.1e}, finite: {}",
            x.residual,
            finite(&x.u) && finite(&x.q)
        )));
    }
    let e = 0.5 * p.forces.iter().zip(&x.u).map(|(f, u)| f * u).sum::<f64>();
    Ok((e, enr.tip_nodes.len()))
}

/// The blade stopped at `length` along `angle` (rad), the cells of `locking` ([`energy`]):
/// its energy, which must be positive, and its tip nodes.
fn stops_at(size: Size, angle: f64, length: f64, locking: Locking, place: &str) -> Outcome {
    outcome(|| {
        let (e, tips) = energy(cells(size), angle, length, locking)?;
        if e.is_nan() || e <= 0.0 {
            return Ok(Outcome::Broken(format!("energy {e:.4e} J")));
        }
        Ok(Outcome::bounded(format!("{place}: energy {e:.4e} J, {tips} tip nodes")))
    })
}

/// The blade stopped 1e-9 cells beside `length`, on both sides: the relative change of the
/// energy against the blade exactly at `length` (continuity: a cut rounded to whole cells
/// jumps by a third of the energy here).
fn beside(size: Size, length: f64) -> Outcome {
    outcome(|| {
        let n = cells(size);
        let eps = 1e-9 * 0.1 / n as f64;
        let (at, _) = energy(n, 0.0, length, Locking::Bbar)?;
        let (below, _) = energy(n, 0.0, length - eps, Locking::Bbar)?;
        let (above, _) = energy(n, 0.0, length + eps, Locking::Bbar)?;
        let jump = relative(below, at).max(relative(above, at));
        Ok(Outcome::answer(
            format!("energy {below:.6e} / {at:.6e} / {above:.6e} J 1e-9 cells before, at and past"),
            jump,
        ))
    })
}

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "a blade stopping on a line of nodes",
            method: METHOD,
            expect: Expect::FINITE,
            run: |size| stops_at(size, 0.0, 0.05, Locking::Bbar, "tip on a node line"),
        },
        Case {
            name: "a blade stopping on a cell face",
            method: METHOD,
            expect: Expect::FINITE,
            run: |size| stops_at(size, 0.0, 0.05 + 0.05 / cells(size) as f64, Locking::Bbar, "tip on a face"),
        },
        Case {
            name: "a blade stopping inside a cell (20°)",
            method: METHOD,
            expect: Expect::FINITE,
            run: |size| stops_at(size, 20f64.to_radians(), 0.05, Locking::Bbar, "tip inside a cell"),
        },
        Case {
            name: "a blade stopping inside a cell, on tetrahedra (20°)",
            method: METHOD,
            expect: Expect::FINITE,
            run: |size| stops_at(size, 20f64.to_radians(), 0.05, Locking::None, "tip inside a tetrahedron"),
        },
        Case {
            name: "a blade stopping 1e-9 cells beside a node line",
            method: METHOD,
            expect: Expect::within(1e-4),
            run: |size| beside(size, 0.05),
        },
        Case {
            name: "a blade stopping 1e-9 cells beside a face",
            method: METHOD,
            expect: Expect::within(1e-4),
            run: |size| beside(size, 0.05 + 0.05 / cells(size) as f64),
        },
        Case {
            name: "a blade stopping at the far face (the top cut loose)",
            method: METHOD,
            expect: Expect::Diagnostic(&["reached the organ's surface"]),
            run: |size| stops_at(size, 0.0, 0.1, Locking::Bbar, "tip on the far face"),
        },
        Case {
            name: "a tip line outside the organ, or of zero length",
            method: METHOD,
            expect: Expect::Diagnostic(&["passes through no cell"]),
            run: |size| {
                outcome(|| {
                    let (mesh, _) = block(cells(size), false);
                    let (cut, mut line) = edge_cut(0.0, 0.05)?;
                    let degenerate = TipLine { b: line.a, ..line };
                    let params = XfemParams::default();
                    match TipEnrichment::new(&mesh, &cut, &degenerate, &params, TipParams::default()) {
                        Err(tip::TipError::Degenerate) => {}
                        other => return Ok(Outcome::Broken(format!("a zero-length tip line: {other:?}"))),
                    }
                    line.a[0] += 1.0;
                    line.b[0] += 1.0;
                    TipEnrichment::new(&mesh, &cut, &line, &params, TipParams::default()).map_err(diagnostic)?;
                    Ok(Outcome::Broken("a tip line 1 m outside the block was accepted".into()))
                })
            },
        },
        Case {
            name: "the tip enrichment with the averaged nodal pressure",
            method: METHOD,
            expect: Expect::Diagnostic(&["not supported"]),
            run: |size| stops_at(size, 0.0, 0.05, Locking::Nodal, "nodal pressure"),
        },
    ]
}
