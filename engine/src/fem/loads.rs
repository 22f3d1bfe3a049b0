//! Consistent nodal forces from point, surface and body loads.
//!
//! A traction `t` (Pa) on a boundary face contributes `f_a = ∫_face t N_a dA`: `t·A/3` per
//! node of a flat triangle, and a 2×2 Gauss rule on the bilinear quadrilateral. A body force
//! density `ρ g` contributes `f_a = g ∫ ρ N_a dV` (the lumped mass times g).

use super::assembly::{self, AssemblyError, MaterialMap};
use crate::mesh::Mesh;
use crate::mesh::boundary::{Boundary, triangle_area_normal};

/// Adds `force` (N) to node `node` of the full force vector `f`.
pub fn add_point_force(f: &mut [f64], node: usize, force: [f64; 3]) {
    for i in 0..3 {
        f[3 * node + i] += force[i];
    }
}

/// Spreads a total `force` (N) equally over `nodes`.
pub fn add_distributed_force(f: &mut [f64], nodes: &[usize], force: [f64; 3]) {
    if nodes.is_empty() {
        return;
    }
    let share = 1.0 / nodes.len() as f64;
    for &n in nodes {
        add_point_force(f, n, [force[0] * share, force[1] * share, force[2] * share]);
    }
}

/// Adds the nodal forces of a uniform traction `t` (Pa) on the boundary faces `faces`
/// (indices into `boundary.faces`). Returns the loaded area (m²).
pub fn add_traction(f: &mut [f64], mesh: &Mesh, boundary: &Boundary, faces: &[usize], t: [f64; 3]) -> f64 {
    let mut area = 0.0;
    let g = 1.0 / 3f64.sqrt();
    for &fi in faces {
        let face = &boundary.faces[fi];
        if face.len == 3 {
            let tri = [face.nodes[0], face.nodes[1], face.nodes[2]];
            let (a, _) = triangle_area_normal(mesh, tri);
            area += a;
            for &n in &tri {
                add_point_force(f, n, [t[0] * a / 3.0, t[1] * a / 3.0, t[2] * a / 3.0]);
            }
        } else {
            let x: Vec<[f64; 3]> = face.nodes.iter().map(|&n| mesh.nodes[n]).collect();
            for (xi, eta) in [(-g, -g), (g, -g), (g, g), (-g, g)] {
                let n = [
                    (1.0 - xi) * (1.0 - eta) / 4.0,
                    (1.0 + xi) * (1.0 - eta) / 4.0,
                    (1.0 + xi) * (1.0 + eta) / 4.0,
                    (1.0 - xi) * (1.0 + eta) / 4.0,
                ];
                let dxi = [-(1.0 - eta) / 4.0, (1.0 - eta) / 4.0, (1.0 + eta) / 4.0, -(1.0 + eta) / 4.0];
                let deta = [-(1.0 - xi) / 4.0, -(1.0 + xi) / 4.0, (1.0 + xi) / 4.0, (1.0 - xi) / 4.0];
                let mut a = [0.0; 3];
                let mut b = [0.0; 3];
                for k in 0..4 {
                    for i in 0..3 {
                        a[i] += dxi[k] * x[k][i];
                        b[i] += deta[k] * x[k][i];
                    }
                }
                let cr = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
                let da = (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt();
                area += da;
                for k in 0..4 {
                    add_point_force(f, face.nodes[k], [t[0] * n[k] * da, t[1] * n[k] * da, t[2] * n[k] * da]);
                }
            }
        }
    }
    area
}

/// Adds the body force of an acceleration field `g` (m/s², e.g. gravity) on every cell.
/// Returns the total mass (kg).
pub fn add_body_force(f: &mut [f64], mesh: &Mesh, materials: &MaterialMap, g: [f64; 3]) -> Result<f64, AssemblyError> {
    let m = assembly::lumped_masses(mesh, materials)?;
    for (n, mn) in m.iter().enumerate() {
        add_point_force(f, n, [mn * g[0], mn * g[1], mn * g[2]]);
    }
    Ok(m.iter().sum())
}
