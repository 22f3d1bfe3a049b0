//! The identity check of a cut lying on cell faces: XFEM must give, to solver precision, the
//! answer of the same mesh with every enriched node duplicated (cells on the other side of a
//! node's plane use the copy). It is the reference the cutting tests and the hard-case suite
//! measure the full-order XFEM against.

use super::Enrichment;
use super::system::XfemSolution;
use crate::fem::Locking;
use crate::fem::assembly::MaterialMap;
use crate::fem::linear_static::{self, StaticError, StaticProblem};
use crate::mesh::Mesh;

/// The same mesh with every enriched node duplicated: cells on the other side of a node's
/// plane use the copy (node `n + k` for the `k`-th enriched node), which carries the node's
/// constraints; loads stay on the originals.
pub fn duplicated(mesh: &Mesh, enr: &Enrichment, problem: &StaticProblem) -> (Mesh, StaticProblem) {
    let n = mesh.n_nodes();
    let mut nodes = mesh.nodes.clone();
    nodes.extend(enr.nodes.iter().map(|&a| mesh.nodes[a]));
    let npc = mesh.kind.nodes_per_cell();
    let mut cells = Vec::with_capacity(mesh.n_cells() * npc);
    for c in mesh.cells_iter() {
        let centre = c.iter().fold([0.0; 3], |s, &a| {
            let p = mesh.nodes[a];
            std::array::from_fn(|i| s[i] + p[i] / npc as f64)
        });
        for &a in c {
            cells.push(match enr.index(a) {
                Some(k) if (enr.planes[k].phi(centre) > 0.0) != enr.own_positive[k] => n + k,
                _ => a,
            });
        }
    }
    let dup = Mesh::new(nodes, mesh.kind, cells).expect("the same cells on copies of their nodes");
    let mut p = StaticProblem::new(dup.n_nodes());
    p.constrained[..3 * n].copy_from_slice(&problem.constrained);
    p.prescribed[..3 * n].copy_from_slice(&problem.prescribed);
    p.forces[..3 * n].copy_from_slice(&problem.forces);
    p.springs[..3 * n].copy_from_slice(&problem.springs);
    for (k, &a) in enr.nodes.iter().enumerate() {
        for i in 0..3 {
            p.constrained[3 * (n + k) + i] = problem.constrained[3 * a + i];
            p.prescribed[3 * (n + k) + i] = problem.prescribed[3 * a + i];
        }
    }
    (dup, p)
}

/// The largest difference between the XFEM solution `x` and the duplicated mesh's, over every
/// node on either side of the cut, relative to the duplicated mesh's largest displacement.
pub fn identity_gap(
    mesh: &Mesh,
    materials: &MaterialMap,
    locking: Locking,
    problem: &StaticProblem,
    enr: &Enrichment,
    x: &XfemSolution,
) -> Result<f64, StaticError> {
    let (dup, p) = duplicated(mesh, enr, problem);
    let d = linear_static::solve(&dup, materials, locking, &p, &mut |_| {})?;
    let n = mesh.n_nodes();
    let mut gap: f64 = (0..3 * n).map(|i| (x.u[i] - d.u[i]).abs()).fold(0.0, f64::max);
    for (k, &a) in enr.nodes.iter().enumerate() {
        let other = x.side_displacement(enr, a, !enr.own_positive[k]);
        for i in 0..3 {
            gap = gap.max((other[i] - d.u[3 * (n + k) + i]).abs());
        }
    }
    Ok(gap / d.max_displacement)
}
