//! A scene's organ solved by the meshless solver (`[fidelity] solver = "meshless"`).
//!
//! The mesh's nodes become the node cloud, with influence radii of `support` times the mean
//! length of the edges at each node; its cells become the background integration cells
//! (1 point, or the 4-point tetrahedron / 2×2×2 hexahedron rules), as MTLED integrates over
//! background tetrahedra. The constraints and loads are the finite-element model's: prescribed
//! components become essential conditions (seed 004 Eq. 3.18), nodal forces are applied
//! through the shape functions. Pre-planned cuts are made on the loaded, relaxed organ and the
//! organ is relaxed again (seed 004 §6.2), as a surgeon cuts stretched tissue.

use nalgebra::Matrix3;

use super::cutting::{CutNodes, cut_cloud};
use super::efg::{self, AdrParams, EfgError, EfgProblem, EfgSolution};
use super::grid::IntegrationPoint;
use super::mls::NodeCloud;
use crate::fem::element::von_mises;
use crate::fem::linear_static::StaticProblem;
use crate::geometry::cut::Cut;
use crate::material::hyperelastic::{Hyperelastic, Part};
use crate::mesh::shape;
use crate::mesh::{CellKind, Mesh};

/// How an organ is discretised and relaxed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrganSettings {
    /// Influence radius in mean edge lengths at the node.
    pub support: f64,
    /// Integration points per cell and axis: 1, or 2 (4 per tetrahedron, 8 per hexahedron).
    pub integration: usize,
    /// The relaxation.
    pub params: AdrParams,
}

/// A relaxed organ.
#[derive(Debug, Clone)]
pub struct OrganSolution {
    /// The loaded organ before its cuts (when it has any).
    pub uncut: Option<EfgSolution>,
    /// Its reactions at the mesh's nodes (3 per node, N), as [`OrganSolution::reactions`].
    pub uncut_reactions: Option<Vec<f64>>,
    /// The final state.
    pub solution: EfgSolution,
    /// The final node cloud (the mesh's nodes first, then the nodes the cuts added).
    pub cloud: NodeCloud,
    /// Nodes split and inserted by the cuts.
    pub cut_nodes: CutNodes,
    /// Displacement at the mesh's nodes (3 per node, m).
    pub displacement: Vec<f64>,
    /// Von Mises stress at each cell's centre (Pa).
    pub von_mises: Vec<f64>,
    /// Integration points.
    pub integration_points: usize,
    /// Reactions at the mesh's nodes (3 per node, N): the conjugate of each prescribed
    /// component, zero elsewhere.
    pub reactions: Vec<f64>,
    /// Prescribed components.
    pub prescribed: usize,
}

impl OrganSolution {
    /// Sum of the reactions over `nodes` (N).
    pub fn reaction_sum(&self, nodes: &[usize]) -> [f64; 3] {
        crate::fem::node_sum(&self.reactions, nodes)
    }
}

/// Influence radii: `support` × the mean length of the edges of the cells at each node.
pub fn node_radii(mesh: &Mesh, support: f64) -> Vec<f64> {
    let mut sum = vec![0.0; mesh.n_nodes()];
    let mut count = vec![0usize; mesh.n_nodes()];
    for cell in mesh.cells_iter() {
        for &(a, b) in crate::mesh::quality::edges(mesh.kind) {
            let (i, j) = (cell[a], cell[b]);
            let l = (0..3).map(|k| (mesh.nodes[i][k] - mesh.nodes[j][k]).powi(2)).sum::<f64>().sqrt();
            for n in [i, j] {
                sum[n] += l;
                count[n] += 1;
            }
        }
    }
    sum.iter()
        .zip(&count)
        .map(|(s, &c)| support * if c > 0 { s / c as f64 } else { 0.0 })
        .collect()
}

/// The integration points of the mesh's cells: `q = 1`, the centre; `q = 2`, the degree-2
/// 4-point rule of the tetrahedron or the 2×2×2 Gauss rule of the hexahedron.
pub fn integration_points(mesh: &Mesh, q: usize) -> Vec<IntegrationPoint> {
    let npc = mesh.kind.nodes_per_cell();
    let mut x = vec![[0.0; 3]; npc];
    let mut out = Vec::new();
    let mut grad = [[0.0; 3]; 8];
    for c in 0..mesh.n_cells() {
        mesh.cell_coords(c, &mut x);
        match mesh.kind {
            CellKind::Tet4 => {
                let vol = shape::physical_gradients(&x, &shape::TET_DN, &mut grad[..4]) / 6.0;
                let rule: &[[f64; 4]] = if q >= 2 {
                    const A: f64 = 0.585_410_196_624_968_5;
                    const B: f64 = 0.138_196_601_125_010_5;
                    &[[A, B, B, B], [B, A, B, B], [B, B, A, B], [B, B, B, A]]
                } else {
                    &[[0.25; 4]]
                };
                for l in rule {
                    let mut p = [0.0; 3];
                    for (a, xa) in x.iter().enumerate() {
                        for k in 0..3 {
                            p[k] += l[a] * xa[k];
                        }
                    }
                    out.push(IntegrationPoint {
                        x: p,
                        weight: vol / rule.len() as f64,
                    });
                }
            }
            CellKind::Hex8 => {
                let pts: Vec<([f64; 3], f64)> = if q >= 2 {
                    shape::hex_gauss_2().iter().map(|&p| (p, 1.0)).collect()
                } else {
                    vec![([0.0; 3], 8.0)]
                };
                for (xi, w) in pts {
                    let det = shape::physical_gradients(&x, &shape::hex_dn(xi), &mut grad);
                    let n = shape::hex_n(xi);
                    let mut p = [0.0; 3];
                    for (a, xa) in x.iter().enumerate() {
                        for k in 0..3 {
                            p[k] += n[a] * xa[k];
                        }
                    }
                    out.push(IntegrationPoint { x: p, weight: det * w });
                }
            }
        }
    }
    out
}

/// Whether `x` lies in a cell of the mesh (tetrahedra: barycentric coordinates; hexahedra:
/// the inverse trilinear map by Newton's method).
pub fn inside(mesh: &Mesh, x: [f64; 3]) -> bool {
    let npc = mesh.kind.nodes_per_cell();
    let mut cx = vec![[0.0; 3]; npc];
    let tol = 1e-9;
    (0..mesh.n_cells()).any(|c| {
        mesh.cell_coords(c, &mut cx);
        // quick reject on the cell's bounding box
        for k in 0..3 {
            let (lo, hi) = cx
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p[k]), h.max(p[k])));
            let pad = tol * (hi - lo).max(f64::MIN_POSITIVE);
            if x[k] < lo - pad || x[k] > hi + pad {
                return false;
            }
        }
        let mut xi = [0.0; 3];
        for _ in 0..20 {
            let (mut n, mut dn) = ([0.0; 8], [[0.0; 3]; 8]);
            match mesh.kind {
                CellKind::Tet4 => {
                    n[..4].copy_from_slice(&[1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]]);
                    dn[..4].copy_from_slice(&shape::TET_DN);
                }
                CellKind::Hex8 => (n, dn) = (shape::hex_n(xi), shape::hex_dn(xi)),
            }
            let mut r = nalgebra::Vector3::<f64>::zeros();
            let mut j = Matrix3::<f64>::zeros();
            for a in 0..npc {
                for k in 0..3 {
                    r[k] += n[a] * cx[a][k];
                    for m in 0..3 {
                        j[(k, m)] += cx[a][k] * dn[a][m];
                    }
                }
            }
            for k in 0..3 {
                r[k] -= x[k];
            }
            let Some(step) = j.lu().solve(&r) else {
                return false;
            };
            for k in 0..3 {
                xi[k] -= step[k];
            }
            if step.norm() < 1e-12 {
                break;
            }
        }
        match mesh.kind {
            CellKind::Tet4 => xi.iter().all(|&v| v >= -tol) && xi.iter().sum::<f64>() <= 1.0 + tol,
            CellKind::Hex8 => xi.iter().all(|v| v.abs() <= 1.0 + tol),
        }
    })
}

/// The meshless problem of an organ: its mesh's nodes and cells, one hyperelastic law, the
/// finite-element model's constraints and nodal forces.
pub fn problem(mesh: &Mesh, law: Hyperelastic, fe: &StaticProblem, settings: &OrganSettings) -> EfgProblem {
    let radius = node_radii(mesh, settings.support);
    let mut prescribed = Vec::new();
    let mut loads = Vec::new();
    for i in 0..mesh.n_nodes() {
        for k in 0..3 {
            if fe.constrained[3 * i + k] {
                prescribed.push((i, k, fe.prescribed[3 * i + k]));
            }
        }
        let f = [fe.forces[3 * i], fe.forces[3 * i + 1], fe.forces[3 * i + 2]];
        if f.iter().any(|&v| v != 0.0) {
            loads.push((i, f));
        }
    }
    EfgProblem {
        cloud: NodeCloud::new(3, mesh.nodes.clone(), radius),
        points: integration_points(mesh, settings.integration),
        law,
        prescribed,
        loads,
    }
}

/// Solves the organ, then makes each cut in turn on the relaxed state and relaxes again.
/// `progress(stage, step, error)`: stage 0 loads the organ, stage `k` relaxes after cut `k`.
pub fn solve(
    mesh: &Mesh,
    law: Hyperelastic,
    fe: &StaticProblem,
    cuts: &[Cut],
    settings: &OrganSettings,
    mut progress: impl FnMut(usize, usize, f64),
) -> Result<OrganSolution, EfgError> {
    let mut problem = problem(mesh, law, fe, settings);
    let integration_points = problem.points.len();
    let mut solution = efg::solve(&problem, &settings.params, |s, e| progress(0, s, e))?;
    let mut uncut = None;
    let mut cut_nodes = CutNodes::default();
    if !cuts.is_empty() {
        // stations about one mean edge length apart
        let spacing = problem.cloud.radii().iter().sum::<f64>() / (settings.support * problem.cloud.len().max(1) as f64);
        let mut union: Option<Cut> = None;
        for (k, cut) in cuts.iter().enumerate() {
            let combined = match union.take() {
                None => cut.clone(),
                Some(u) => u.union(cut)?,
            };
            let (cloud, start, nodes) = cut_cloud(&problem.cloud, combined.clone(), &solution.field, spacing, |x| inside(mesh, x))?;
            cut_nodes.split += nodes.split;
            cut_nodes.inserted += nodes.inserted;
            problem.cloud = cloud;
            let relaxed = efg::relax(&problem, &settings.params, &start, |s, e| progress(k + 1, s, e))?;
            uncut.get_or_insert(solution);
            solution = relaxed;
            union = Some(combined);
        }
    }
    let displacement = solution.displacement[..3 * mesh.n_nodes()].to_vec();
    let node_reactions = |s: &EfgSolution| {
        let mut reactions = vec![0.0; 3 * mesh.n_nodes()];
        for (&(node, k, _), r) in problem.prescribed.iter().zip(&s.reactions) {
            reactions[3 * node + k] += r;
        }
        reactions
    };
    let reactions = node_reactions(&solution);
    let von_mises = cell_von_mises(mesh, &problem.cloud, &solution.field, &law);
    Ok(OrganSolution {
        uncut_reactions: uncut.as_ref().map(node_reactions),
        uncut,
        solution,
        cloud: problem.cloud,
        cut_nodes,
        displacement,
        von_mises,
        integration_points,
        reactions,
        prescribed: problem.prescribed.len(),
    })
}

/// Von Mises stress of the Cauchy stress `σ = F S Fᵀ / J` at each cell's centre (0 where the
/// shape functions cannot be built or the point inverted).
fn cell_von_mises(mesh: &Mesh, cloud: &NodeCloud, field: &[f64], law: &Hyperelastic) -> Vec<f64> {
    let npc = mesh.kind.nodes_per_cell();
    let mut x = vec![[0.0; 3]; npc];
    (0..mesh.n_cells())
        .map(|c| {
            mesh.cell_coords(c, &mut x);
            let mut centre = [0.0; 3];
            for p in &x {
                for k in 0..3 {
                    centre[k] += p[k] / npc as f64;
                }
            }
            let Ok((_, f)) = efg::deformation_at(cloud, field, centre) else {
                return 0.0;
            };
            let Some(r) = law.response(&(f.transpose() * f), Part::Full) else {
                return 0.0;
            };
            let sigma = f * r.stress_tensor() * f.transpose() / f.determinant();
            von_mises([
                sigma[(0, 0)],
                sigma[(1, 1)],
                sigma[(2, 2)],
                sigma[(0, 1)],
                sigma[(1, 2)],
                sigma[(2, 0)],
            ])
        })
        .collect()
}
