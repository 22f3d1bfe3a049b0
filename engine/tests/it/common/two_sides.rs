//! The generalized displacements that move each side of a cut by its own motion, for the
//! tests of what follows a cut's sides.

use vademecum_engine::mesh::Mesh;
use vademecum_engine::xfem::{Enrichment, Plane};

/// The XFEM displacements (the nodes', then the enriched nodes' jumps) of `mesh` cut by `enr`
/// under which the material on each side of `plane` moves by `motion(positive, x)`: each node
/// by its side's motion, each enriched node's jump the difference to the other side's.
pub fn displacements(mesh: &Mesh, enr: &Enrichment, plane: &Plane, motion: impl Fn(bool, [f64; 3]) -> [f64; 3]) -> Vec<f64> {
    let n = mesh.n_nodes();
    let mut d = vec![0.0; 3 * (n + enr.len())];
    for (a, &x) in mesh.nodes.iter().enumerate() {
        d[3 * a..3 * a + 3].copy_from_slice(&motion(plane.phi(x) > 0.0, x));
    }
    for (k, &a) in enr.nodes.iter().enumerate() {
        let own = enr.planes[k].phi(mesh.nodes[a]) > 0.0;
        let other = motion(!own, mesh.nodes[a]);
        let h = enr.shifted(k, !own);
        for i in 0..3 {
            d[3 * (n + k) + i] = (other[i] - d[3 * a + i]) / h;
        }
    }
    d
}
