//! A cut made visible: the mesh with each enriched node split into its two sides, so that a
//! viewer (ParaView, the session's frames) draws the opening.
//!
//! Each enriched node gets a copy for its other side; a cell whose centre lies on a node's
//! other side uses the copy. The displacement of a copy is `u_I + s q_I` (the shifted
//! Heaviside `s` of that side). On a cut along cell faces the picture is exact (it is the
//! duplicated-node mesh of the identity check); inside cut cells the discontinuity is drawn
//! on the nearest cell faces.

use super::enrichment::Enrichment;
use super::system::XfemSolution;
use crate::mesh::Mesh;

/// The split mesh of a cut, and how to carry fields onto it.
#[derive(Debug, Clone)]
pub struct SplitMesh {
    /// The mesh with the copies appended (node `n + k` is the other side of enriched node k).
    pub mesh: Mesh,
    n: usize,
}

impl SplitMesh {
    /// Splits `mesh` along the enrichment `enr`.
    pub fn new(mesh: &Mesh, enr: &Enrichment) -> Self {
        let n = mesh.n_nodes();
        let npc = mesh.kind.nodes_per_cell();
        let mut nodes = mesh.nodes.clone();
        nodes.extend(enr.nodes.iter().map(|&a| mesh.nodes[a]));
        let mut cells = Vec::with_capacity(mesh.cells.len());
        for c in mesh.cells_iter() {
            let mut centre = [0.0; 3];
            for &a in c {
                for i in 0..3 {
                    centre[i] += mesh.nodes[a][i] / npc as f64;
                }
            }
            cells.extend(c.iter().map(|&a| match enr.index(a) {
                Some(k) if (enr.planes[k].phi(centre) > 0.0) != enr.own_positive[k] => n + k,
                _ => a,
            }));
        }
        let mut split = mesh.clone();
        split.nodes = nodes;
        split.cells = cells;
        Self { mesh: split, n }
    }

    /// The displacement of every node of the split mesh: each node's own, and `u_I + s q_I` for
    /// each copy.
    pub fn displacement(&self, enr: &Enrichment, u: &[f64], q: &[f64]) -> Vec<f64> {
        let mut out = u[..3 * self.n].to_vec();
        for (k, &a) in enr.nodes.iter().enumerate() {
            let s = enr.shifted(k, !enr.own_positive[k]);
            out.extend((0..3).map(|i| u[3 * a + i] + s * q[3 * k + i]));
        }
        out
    }

    /// [`displacement`](Self::displacement) of a full-order solution.
    pub fn of_solution(&self, enr: &Enrichment, sol: &XfemSolution) -> Vec<f64> {
        self.displacement(enr, &sol.u, &sol.q)
    }

    /// A per-node field of the mesh (e.g. reactions) carried to the split mesh: copies take
    /// zero.
    pub fn extend_zero(&self, values: &[f64], components: usize) -> Vec<f64> {
        let mut out = values.to_vec();
        out.resize(self.mesh.nodes.len() * components, 0.0);
        out
    }
}
