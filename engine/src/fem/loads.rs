//! Nodal forces from point, surface and body loads.
//!
//! A traction `t` (Pa) on a boundary face contributes `f_a = ∫_face t N_a dA`: `t·A/3` per
//! node of a flat triangle, and a 2×2 Gauss rule on the bilinear quadrilateral. A pressure `p`
//! (Pa, positive pushing into the body) contributes `f_a = −p ∫_face N_a n dA`, `n` the
//! outward normal: with the face parametrised by `x(ξ, η)`, `n dA = (∂x/∂ξ × ∂x/∂η) dξ dη`,
//! so `f_a = −p Σ_g w_g N_a(g) (x_ξ × x_η)(g)` — exact for the flat triangle (one point) and the
//! bilinear quadrilateral (2×2 points). On the deformed surface the same sum is the follower
//! load of large deformations ([`PressureLoad`]). A body force density `ρ g` contributes
//! `f_a = g ∫ ρ N_a dV` (the lumped mass times g). A total force over a region is shared
//! equally by its nodes ([`add_distributed_force`]): simple, but not consistent with the
//! shape functions on an uneven mesh; tractions and pressures are.

use super::assembly::{self, AssemblyError, MaterialMap};
use crate::mesh::Mesh;
use crate::mesh::boundary::{Boundary, triangle_area_normal};
use nalgebra::Vector3;

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

/// The integration points of a boundary face with `len` nodes (3 or 4): shape functions `N`,
/// their derivatives along the two face coordinates, and the weight.
fn face_points(len: u8) -> Vec<([f64; 4], [f64; 4], [f64; 4], f64)> {
    if len == 3 {
        // x(ξ, η) = x₀ + ξ (x₁ − x₀) + η (x₂ − x₀) on the unit triangle (area ½): exact in one point
        return vec![(
            [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 0.0],
            [-1.0, 1.0, 0.0, 0.0],
            [-1.0, 0.0, 1.0, 0.0],
            0.5,
        )];
    }
    let g = 1.0 / 3f64.sqrt();
    [(-g, -g), (g, -g), (g, g), (-g, g)]
        .map(|(xi, eta)| {
            (
                [
                    (1.0 - xi) * (1.0 - eta) / 4.0,
                    (1.0 + xi) * (1.0 - eta) / 4.0,
                    (1.0 + xi) * (1.0 + eta) / 4.0,
                    (1.0 - xi) * (1.0 + eta) / 4.0,
                ],
                [-(1.0 - eta) / 4.0, (1.0 - eta) / 4.0, (1.0 + eta) / 4.0, -(1.0 + eta) / 4.0],
                [-(1.0 - xi) / 4.0, -(1.0 + xi) / 4.0, (1.0 + xi) / 4.0, (1.0 - xi) / 4.0],
                1.0,
            )
        })
        .to_vec()
}

/// A uniform pressure on boundary faces (their nodes, outward order): a dead load on the
/// reference surface at small strains, a follower load on the deformed surface at large ones.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PressureLoad {
    /// The faces' node indices (3 or 4 each), in the boundary's outward order.
    pub faces: Vec<Vec<usize>>,
    /// Pressure (Pa), positive pushing into the body.
    pub pressure: f64,
}

impl PressureLoad {
    /// The pressure `pressure` on the boundary faces `faces` (indices into `boundary.faces`).
    pub fn on(boundary: &Boundary, faces: &[usize], pressure: f64) -> Self {
        Self {
            faces: faces.iter().map(|&f| boundary.faces[f].node_slice().to_vec()).collect(),
            pressure,
        }
    }

    /// Adds `scale ×` the nodal forces on the surface with nodes at `x(n) = X_n + u_n` (`u`:
    /// full displacement vector, or `None` for the reference surface) into `f`.
    pub fn add_forces(&self, mesh: &Mesh, u: Option<&[f64]>, scale: f64, f: &mut [f64]) {
        for face in &self.faces {
            let x = face_coords(mesh, face, u);
            for (n, dxi, deta, w) in face_points(face.len() as u8) {
                let (a, b) = tangents(&x, &dxi, &deta);
                let c = Vector3::from(a).cross(&Vector3::from(b));
                for (k, &node) in face.iter().enumerate() {
                    for i in 0..3 {
                        f[3 * node + i] -= scale * self.pressure * w * n[k] * c[i];
                    }
                }
            }
        }
    }

    /// The symmetric part of the load stiffness `∂f/∂u` on the deformed surface, times
    /// `scale`, visited face by face: `visit(face nodes, 3m × 3m block, row-major)`. Over a
    /// closed surface, or one whose edges are held, the load is conservative and this is the
    /// whole load stiffness; on an open free edge the skew part is left out (Newton then
    /// converges linearly near that edge instead of quadratically).
    pub fn for_each_stiffness(&self, mesh: &Mesh, u: &[f64], scale: f64, mut visit: impl FnMut(&[usize], &[f64])) {
        let mut block = Vec::new();
        for face in &self.faces {
            let m = face.len();
            let nd = 3 * m;
            block.clear();
            block.resize(nd * nd, 0.0);
            let x = face_coords(mesh, face, Some(u));
            for (n, dxi, deta, w) in face_points(m as u8) {
                let (a, b) = tangents(&x, &dxi, &deta);
                // ∂(a × b)/∂x_l = −dξ_l [b]× + dη_l [a]×, with [v]× δ = v × δ
                for k in 0..m {
                    for l in 0..m {
                        let s = -scale * self.pressure * w * n[k];
                        let (mb, ma) = (skew(b, -dxi[l]), skew(a, deta[l]));
                        for i in 0..3 {
                            for j in 0..3 {
                                let v = s * (mb[i][j] + ma[i][j]);
                                // symmetric part: half here, half on the transposed entry
                                block[(3 * k + i) * nd + 3 * l + j] += 0.5 * v;
                                block[(3 * l + j) * nd + 3 * k + i] += 0.5 * v;
                            }
                        }
                    }
                }
            }
            visit(face, &block);
        }
    }
}

/// `c [v]×`, the matrix with `[v]× δ = v × δ`.
fn skew(v: [f64; 3], c: f64) -> [[f64; 3]; 3] {
    [[0.0, -c * v[2], c * v[1]], [c * v[2], 0.0, -c * v[0]], [-c * v[1], c * v[0], 0.0]]
}

fn face_coords(mesh: &Mesh, face: &[usize], u: Option<&[f64]>) -> Vec<[f64; 3]> {
    face.iter()
        .map(|&n| {
            let x = mesh.nodes[n];
            match u {
                Some(u) => [x[0] + u[3 * n], x[1] + u[3 * n + 1], x[2] + u[3 * n + 2]],
                None => x,
            }
        })
        .collect()
}

fn tangents(x: &[[f64; 3]], dxi: &[f64; 4], deta: &[f64; 4]) -> ([f64; 3], [f64; 3]) {
    let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
    for (k, xk) in x.iter().enumerate() {
        for i in 0..3 {
            a[i] += dxi[k] * xk[i];
            b[i] += deta[k] * xk[i];
        }
    }
    (a, b)
}

/// Adds an elastic foundation of `stiffness` (Pa/m: springs per unit area) on the boundary
/// faces `faces` to the nodal spring constants `springs` (N/m per degree of freedom) on the
/// `components`: each node carries the stiffness of its share `∫ N_a dA` of the faces (the
/// row sum of the consistent face matrix `k ∫ N_a N_b dA`, lumped).
pub fn add_foundation(springs: &mut [f64], mesh: &Mesh, boundary: &Boundary, faces: &[usize], stiffness: f64, components: &[usize]) {
    for &fi in faces {
        let face = boundary.faces[fi].node_slice();
        let x = face_coords(mesh, face, None);
        for (n, dxi, deta, w) in face_points(face.len() as u8) {
            let (a, b) = tangents(&x, &dxi, &deta);
            let c = Vector3::from(a).cross(&Vector3::from(b));
            let da = w * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            for (k, &node) in face.iter().enumerate() {
                for &i in components {
                    springs[3 * node + i] += stiffness * n[k] * da;
                }
            }
        }
    }
}

/// Spreads a total `force` (N) over the cells `cells` as a uniform force density `F / V`,
/// consistently: node `a` gets `F ∫ N_a dV / V` (for linear cells, the lumped share of each
/// cell's volume). Returns the loaded volume (m³).
pub fn add_volume_force(f: &mut [f64], mesh: &Mesh, cells: &[usize], force: [f64; 3]) -> Result<f64, AssemblyError> {
    let n = mesh.kind.nodes_per_cell();
    let (mut x, mut share) = (vec![[0.0; 3]; n], vec![0.0; n]);
    let s = super::element::ElementScratch::default();
    let mut volume = 0.0;
    let mut shares = vec![0.0; mesh.n_nodes()];
    for &c in cells {
        mesh.cell_coords(c, &mut x);
        // the lumped mass of unit density is ∫ N_a dV
        super::element::lumped_mass(mesh.kind, &x, 1.0, &s, &mut share).map_err(|source| AssemblyError { cell: c, source })?;
        for (a, &node) in mesh.cell(c).iter().enumerate() {
            shares[node] += share[a];
            volume += share[a];
        }
    }
    for (node, &w) in shares.iter().enumerate() {
        if w != 0.0 {
            add_point_force(f, node, force.map(|c| c * w / volume));
        }
    }
    Ok(volume)
}

/// Adds the body force of an acceleration field/// Adds the body force of an acceleration field `g` (m/s², e.g. gravity) on every cell.
/// Returns the total mass (kg).
pub fn add_body_force(f: &mut [f64], mesh: &Mesh, materials: &MaterialMap, g: [f64; 3]) -> Result<f64, AssemblyError> {
    let m = assembly::lumped_masses(mesh, materials)?;
    for (n, mn) in m.iter().enumerate() {
        add_point_force(f, n, [mn * g[0], mn * g[1], mn * g[2]]);
    }
    Ok(m.iter().sum())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::procedural::{block_hex, block_tet};

    fn all_faces(mesh: &Mesh, p: f64) -> PressureLoad {
        let b = Boundary::of(mesh);
        PressureLoad::on(&b, &(0..b.faces.len()).collect::<Vec<_>>(), p)
    }

    /// A pressure over a closed surface has no resultant, and on one face it is `−p A n`.
    #[test]
    fn pressure_on_a_closed_surface_balances_and_on_a_face_pushes_inwards() {
        for mesh in [
            block_hex([0.0; 3], [0.2, 0.1, 0.3], [2, 2, 3]),
            block_tet([0.0; 3], [0.2, 0.1, 0.3], [2, 2, 3]),
        ] {
            let mut f = vec![0.0; mesh.n_dofs()];
            all_faces(&mesh, 1000.0).add_forces(&mesh, None, 1.0, &mut f);
            let total = super::super::node_sum(&f, &(0..mesh.n_nodes()).collect::<Vec<_>>());
            assert!(total.iter().all(|t| t.abs() < 1e-9), "{total:?}");
            // the face z = 0.3 (area 0.02 m²) is pushed down by p A
            let b = Boundary::of(&mesh);
            let top: Vec<usize> = (0..b.faces.len())
                .filter(|&i| b.faces[i].node_slice().iter().all(|&n| (mesh.nodes[n][2] - 0.3).abs() < 1e-12))
                .collect();
            let mut f = vec![0.0; mesh.n_dofs()];
            PressureLoad::on(&b, &top, 1000.0).add_forces(&mesh, None, 1.0, &mut f);
            let total = super::super::node_sum(&f, &(0..mesh.n_nodes()).collect::<Vec<_>>());
            assert!((total[2] + 1000.0 * 0.02).abs() < 1e-9 && total[0].abs() < 1e-12, "{total:?}");
        }
    }

    /// On a closed surface the follower load is conservative: its stiffness (the symmetric
    /// part assembled here) is the whole Jacobian of the forces (central differences).
    #[test]
    fn follower_pressure_stiffness_is_the_jacobian_of_its_forces() {
        for mesh in [
            block_hex([0.0; 3], [0.2, 0.1, 0.3], [1, 1, 2]),
            block_tet([0.0; 3], [0.2, 0.1, 0.3], [1, 1, 1]),
        ] {
            let load = all_faces(&mesh, 1000.0);
            let n = mesh.n_dofs();
            let u: Vec<f64> = (0..n).map(|i| 0.01 * ((i as f64 * 0.7).sin())).collect();
            let mut k = vec![0.0; n * n];
            load.for_each_stiffness(&mesh, &u, 1.0, |nodes, block| {
                let m = 3 * nodes.len();
                for p in 0..m {
                    for q in 0..m {
                        k[(3 * nodes[p / 3] + p % 3) * n + 3 * nodes[q / 3] + q % 3] += block[p * m + q];
                    }
                }
            });
            let h = 1e-7;
            let kmax = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for d in 0..n {
                let (mut up, mut um) = (u.clone(), u.clone());
                up[d] += h;
                um[d] -= h;
                let (mut fp, mut fm) = (vec![0.0; n], vec![0.0; n]);
                load.add_forces(&mesh, Some(&up), 1.0, &mut fp);
                load.add_forces(&mesh, Some(&um), 1.0, &mut fm);
                for r in 0..n {
                    let fd = (fp[r] - fm[r]) / (2.0 * h);
                    assert!((fd - k[r * n + d]).abs() < 1e-6 * kmax, "K[{r}][{d}]: {fd} vs {}", k[r * n + d]);
                }
            }
        }
    }
}
