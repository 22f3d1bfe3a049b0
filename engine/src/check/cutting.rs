//! Cutting by XFEM (seed 000 ch. 3, the full-order reference of the online model) on a
//! 4 × 2 × 3 block clamped at its base, its top pulled apart across x = 2: a cut through a
//! plane of nodes down to the clamped base (both lips held there), the same cut at ν = 0.499,
//! each against the mesh with its cut nodes duplicated (the identity a cut on cell faces must
//! meet); the block cut right through with only one end held (the loose piece found, held on
//! its soft foundation, bounded); and malformed blades (typed refusals).

use super::{Case, Expect, Outcome, Size, diagnostic, finite, outcome};
use crate::fem::Locking;
use crate::fem::assembly::MaterialMap;
use crate::fem::linear_static::StaticProblem;
use crate::material::LinearElastic;
use crate::mesh::{Mesh, procedural};
use crate::meshless::cut::Cut;
use crate::xfem::identity::identity_gap;
use crate::xfem::system;
use crate::xfem::{Enrichment, XfemParams};

/// The block (4 × 2 × 3, `k` cells per unit length), clamped at z = 0 (or, `one_end`, at
/// x = 0 only), its top pushed apart across x = 2 (or, `one_end`, its far end down).
fn block(size: Size, one_end: bool) -> (Mesh, StaticProblem) {
    let k = size.pick(1, 2);
    let mesh = procedural::block_hex([0.0; 3], [4.0, 2.0, 3.0], [4 * k, 2 * k, 3 * k]);
    let mut p = StaticProblem::new(mesh.n_nodes());
    for (a, x) in mesh.nodes.iter().enumerate() {
        if (!one_end && x[2] == 0.0) || (one_end && x[0] == 0.0) {
            p.clamp(&[a]);
        }
        if one_end && x[0] == 4.0 {
            p.forces[3 * a + 2] = -0.1;
        }
        // none on the plane x = 2: a force on a cracked node acts on its own side only
        if !one_end && x[2] == 3.0 && x[0] != 2.0 {
            p.forces[3 * a] = (x[0] - 2.0).signum();
            p.forces[3 * a + 2] = -0.5;
        }
    }
    (mesh, p)
}

fn materials(mesh: &Mesh, nu: f64) -> MaterialMap {
    MaterialMap::uniform(LinearElastic::new(1e4, nu).expect("valid moduli"), 1000.0, mesh.n_cells())
}

/// The plane x = 2 from above the top down to `depth` (below 0: through the base).
fn plane_cut(depth: f64) -> Result<Cut, Outcome> {
    Cut::swept(&[([2.0, -0.1, 3.1], [2.0, 2.1, 3.1]), ([2.0, -0.1, depth], [2.0, 2.1, depth])]).map_err(diagnostic)
}

fn through_nodes(size: Size, nu: f64, depth: f64) -> Outcome {
    outcome(|| {
        let (mesh, p) = block(size, false);
        let enr = Enrichment::from_cut(&mesh, &plane_cut(depth)?, &XfemParams::default()).map_err(diagnostic)?;
        let mats = materials(&mesh, nu);
        let x = system::solve(&mesh, &mats, Locking::Bbar, &p, &enr, &XfemParams::default()).map_err(diagnostic)?;
        if !(finite(&x.u) && finite(&x.q)) || x.residual > 1e-8 || !x.detached.is_empty() {
            return Ok(Outcome::Broken(format!(
                "residual {:.1e}, {} pieces detached",
                x.residual,
                x.detached.len()
            )));
        }
        let base_held = enr
            .nodes
            .iter()
            .enumerate()
            .filter(|&(_, &a)| mesh.nodes[a][2] == 0.0)
            .all(|(k, _)| x.q[3 * k..3 * k + 3] == [0.0; 3]);
        if !base_held {
            return Ok(Outcome::Broken("a lip moved at the clamped base".into()));
        }
        let gap = identity_gap(&mesh, &mats, Locking::Bbar, &p, &enr, &x).map_err(diagnostic)?;
        Ok(Outcome::answer(
            format!(
                "{} nodes cracked, residual {:.1e}, both lips held at the base",
                enr.len(),
                x.residual
            ),
            gap,
        ))
    })
}

fn cut_loose(size: Size) -> Outcome {
    outcome(|| {
        let (mesh, p) = block(size, true);
        let cut = Cut::swept(&[([2.0, -0.1, 3.1], [2.0, 2.1, 3.1]), ([2.0, -0.1, -0.1], [2.0, 2.1, -0.1])]).map_err(diagnostic)?;
        let enr = Enrichment::from_cut(&mesh, &cut, &XfemParams::default()).map_err(diagnostic)?;
        let x = system::solve(&mesh, &materials(&mesh, 0.3), Locking::Bbar, &p, &enr, &XfemParams::default()).map_err(diagnostic)?;
        let sag = (0..mesh.n_nodes())
            .filter(|&a| mesh.nodes[a][0] == 4.0)
            .map(|a| x.u[3 * a + 2].abs())
            .fold(0.0, f64::max);
        let free = x.detached.first().map_or(0, |d| d.free.len());
        // held by the foundation k = E h per copy: a tenth of a newton per node sinks ~1e-5 m
        if x.detached.len() != 1 || free != 6 || !(finite(&x.u) && finite(&x.q)) || !(sag > 1e-7 && sag < 1e-3) {
            return Ok(Outcome::Broken(format!(
                "{} pieces detached ({free} rigid motions free), sag {sag:.2e} m",
                x.detached.len()
            )));
        }
        Ok(Outcome::bounded(format!(
            "1 piece found loose (6 rigid motions), held on its foundation: sags {:.1} µm",
            1e6 * sag
        )))
    })
}

fn bad_blade(_: Size) -> Outcome {
    match Cut::swept(&[([0.0, 0.0, f64::NAN], [1.0, 0.0, 0.0]), ([0.0; 3], [1.0, 1.0, 0.0])]) {
        Err(e) => match Cut::swept(&[([1.0; 3], [1.0; 3]), ([2.0; 3], [2.0; 3])]) {
            Err(z) => Outcome::Diagnostic(format!("NaN blade: {e}; zero-length blade: {z}")),
            Ok(_) => Outcome::Broken("a zero-length blade was accepted".into()),
        },
        Ok(_) => Outcome::Broken("a NaN blade was accepted".into()),
    }
}

pub(super) fn cases() -> Vec<Case> {
    // the duplicated mesh is the same linear system reordered: solver precision
    const IDENTITY: Expect = Expect::within(1e-9);
    vec![
        Case {
            name: "a cut through nodes to the fixed boundary",
            method: "XFEM full order, hex8 B-bar",
            expect: IDENTITY,
            run: |s| through_nodes(s, 0.3, -0.1),
        },
        Case {
            name: "a cut through nodes, ν = 0.499",
            method: "XFEM full order, hex8 B-bar",
            expect: IDENTITY,
            run: |s| through_nodes(s, 0.499, 1.0),
        },
        Case {
            name: "a piece cut loose",
            method: "XFEM full order, hex8 B-bar",
            expect: Expect::FINITE,
            run: cut_loose,
        },
        Case {
            name: "a NaN blade, a zero-length blade",
            method: "cut surface",
            expect: Expect::Diagnostic(&["NaN blade"]),
            run: bad_blade,
        },
    ]
}
