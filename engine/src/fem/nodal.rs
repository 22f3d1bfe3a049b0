//! The averaged-nodal-pressure tetrahedron (Bonet & Burton 1998): linear tetrahedra without
//! volumetric locking.
//!
//! # Why
//! A linear tetrahedron has a constant strain, so a nearly incompressible material asks every
//! cell to keep its volume: one constraint per cell, about five cells per node, against three
//! degrees of freedom per node — the mesh locks (a Lamé cylinder at ν = 0.4999 comes out
//! 17 % too stiff on average, some nodes 50 %). Averaging the volume change over the cells
//! around each *node* leaves one constraint per node against three unknowns, the ratio of
//! a locking-free element, while the deviatoric (shear) part stays cell by cell and keeps the
//! element stable.
//!
//! # The method
//! Each node `a` owns a quarter of each cell around it: the reference nodal volume
//! `V_a = Σ_{e∋a} V_e/4`, and, deformed, `v_a = Σ_{e∋a} v_e/4`. The volumetric energy is
//! evaluated once per node on the nodal volume ratio `θ_a = v_a / V_a`, each cell's quarter
//! with its own law:
//!
//! `Π_vol = Σ_a Σ_{e∋a} (V_e/4) U_e(θ_a)`, so `∂Π_vol/∂θ_a = V_a p_a`, `∂²Π_vol/∂θ_a² = V_a k_a`
//!
//! with the nodal pressure `p_a = Σ_{e∋a} (V_e/4) U_e'(θ_a) / V_a` and modulus `k_a` likewise
//! from `U_e''`. With `g_e = ∂v_e/∂x` (`g_{e,b} = v_e ∇_x N_b`, the cell's current
//! gradients), `∂v_a/∂x = G_a = Σ_{e∋a} g_e / 4` and
//!
//! - internal forces: `f = Σ_a p_a G_a = Σ_e p̄_e g_e`, `p̄_e = ¼ Σ_{a∈e} p_a` (cell by cell);
//! - tangent: `K = Σ_a (k_a / V_a) G_a G_aᵀ + Σ_e p̄_e ∂²v_e`, where
//!   `∂²v_e/∂x_{bi}∂x_{ck} = v_e (h_{bi} h_{ck} − h_{bk} h_{ci})`, `h = ∇_x N`.
//!
//! The first term couples every pair of nodes of a node's patch (the cells around it), so the
//! stiffness pattern reaches a node's neighbours' neighbours ([`NodalPatches::couplings`]).
//! At small strains (`U = K/2 (θ−1)²`) it is the linear element: `θ_a − 1 = b_a · u` with
//! `b_a = Σ_{e∋a} (V_e/4) ∇N_e / V_a` (the nodal dilatation), `K_vol = Σ_a κ_a V_a b_a b_aᵀ`,
//! and the cell's pressure `p̄_e = ¼ Σ_{a∈e} κ_a (b_a · u)`.
//!
//! Reference: J. Bonet, A. J. Burton, *A simple average nodal pressure tetrahedral element
//! for incompressible and nearly incompressible dynamic explicit applications*, Commun.
//! Numer. Meth. Engng 14 (1998) 437–449.

use nalgebra::Vector3;

use super::hyperelastic::{CellError, LawMap, Volumetric, deformation_gradient};
use super::system::{DofMap, SymmetricMatrix, scatter_cell};
use crate::mesh::shape;
use crate::mesh::{CellKind, Mesh};

/// The cells and nodes around every node of a tetrahedral mesh, and the nodal volumes.
#[derive(Debug, Clone, PartialEq)]
pub struct NodalPatches {
    /// Cells around node `a`: `cells[cell_ptr[a]..cell_ptr[a+1]]`.
    cell_ptr: Vec<usize>,
    cells: Vec<usize>,
    /// Nodes of those cells (sorted, unique, `a` included): `nodes[node_ptr[a]..node_ptr[a+1]]`.
    node_ptr: Vec<usize>,
    nodes: Vec<usize>,
    /// Reference nodal volume `V_a = Σ_{e∋a} V_e/4` (m³).
    volume: Vec<f64>,
    /// Reference volume of every cell (m³).
    cell_volume: Vec<f64>,
}

/// A nodal patch could not be built.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PatchError {
    /// Only linear tetrahedra average their pressure over nodes.
    #[error("the averaged nodal pressure applies to linear tetrahedra only")]
    NotTetrahedra,
    /// A reference cell is inverted or degenerate.
    #[error("cell {cell} is inverted or degenerate (volume {volume:.3e} m³)")]
    Degenerate {
        /// The cell.
        cell: usize,
        /// Its signed volume.
        volume: f64,
    },
}

impl NodalPatches {
    /// The patches of `mesh` (linear tetrahedra).
    pub fn new(mesh: &Mesh) -> Result<Self, PatchError> {
        if mesh.kind != CellKind::Tet4 {
            return Err(PatchError::NotTetrahedra);
        }
        let nn = mesh.n_nodes();
        let mut count = vec![0usize; nn + 1];
        for cell in mesh.cells_iter() {
            for &a in cell {
                count[a + 1] += 1;
            }
        }
        for a in 0..nn {
            count[a + 1] += count[a];
        }
        let cell_ptr = count.clone();
        let mut fill = count;
        let mut cells = vec![0usize; cell_ptr[nn]];
        let mut cell_volume = Vec::with_capacity(mesh.n_cells());
        let mut volume = vec![0.0; nn];
        let (mut x, mut g) = ([[0.0; 3]; 4], [[0.0; 3]; 4]);
        for (c, cell) in mesh.cells_iter().enumerate() {
            mesh.cell_coords(c, &mut x);
            let v = shape::physical_gradients(&x, &shape::TET_DN, &mut g) / 6.0;
            if v.is_nan() || v <= 0.0 {
                return Err(PatchError::Degenerate { cell: c, volume: v });
            }
            cell_volume.push(v);
            for &a in cell {
                cells[fill[a]] = c;
                fill[a] += 1;
                volume[a] += v / 4.0;
            }
        }
        let mut node_ptr = Vec::with_capacity(nn + 1);
        node_ptr.push(0);
        let mut nodes = Vec::new();
        let mut patch = Vec::new();
        for a in 0..nn {
            patch.clear();
            for &c in &cells[cell_ptr[a]..cell_ptr[a + 1]] {
                patch.extend_from_slice(mesh.cell(c));
            }
            patch.sort_unstable();
            patch.dedup();
            nodes.extend_from_slice(&patch);
            node_ptr.push(nodes.len());
        }
        Ok(Self {
            cell_ptr,
            cells,
            node_ptr,
            nodes,
            volume,
            cell_volume,
        })
    }

    /// The patches of `mesh` when `wanted` and the mesh is tetrahedral, else none (hexahedra
    /// take the mean dilatation instead).
    pub fn when(mesh: &Mesh, wanted: bool) -> Result<Option<Self>, PatchError> {
        if wanted && mesh.kind == CellKind::Tet4 {
            Self::new(mesh).map(Some)
        } else {
            Ok(None)
        }
    }

    /// Cells around node `a`.
    pub fn cells(&self, a: usize) -> &[usize] {
        &self.cells[self.cell_ptr[a]..self.cell_ptr[a + 1]]
    }

    /// Nodes of the cells around node `a` (sorted, `a` included).
    pub fn nodes(&self, a: usize) -> &[usize] {
        &self.nodes[self.node_ptr[a]..self.node_ptr[a + 1]]
    }

    /// Reference nodal volume `V_a` (m³).
    pub fn volume(&self, a: usize) -> f64 {
        self.volume[a]
    }

    /// Reference volume of cell `c` (m³).
    pub fn cell_volume(&self, c: usize) -> f64 {
        self.cell_volume[c]
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.volume.len()
    }

    /// Every node's list of the nodes its stiffness rows reach: the union of the patches of
    /// the nodes in its own patch (neighbours' neighbours), sorted.
    pub fn couplings(&self) -> Vec<Vec<usize>> {
        (0..self.n_nodes())
            .map(|a| {
                let mut reach: Vec<usize> = self.nodes(a).iter().flat_map(|&c| self.nodes(c).iter().copied()).collect();
                reach.sort_unstable();
                reach.dedup();
                reach
            })
            .collect()
    }

    /// Position of node `b` in the patch of node `a`.
    #[inline]
    fn slot(&self, a: usize, b: usize) -> usize {
        self.nodes(a)
            .binary_search(&b)
            .expect("a cell's nodes are in the patches of its nodes")
    }

    /// `G_a` (flat, `3·|patch|`, overwritten) from the cells' volume gradients
    /// `g_e = ∂v_e/∂x` (`cell_grad[c][b]`, 4 nodes × 3): `G_a = Σ_{e∋a} g_e / 4`.
    pub fn gather(&self, mesh: &Mesh, a: usize, cell_grad: &[[[f64; 3]; 4]], out: &mut Vec<f64>) {
        out.clear();
        out.resize(3 * self.nodes(a).len(), 0.0);
        for &c in self.cells(a) {
            for (k, &b) in mesh.cell(c).iter().enumerate() {
                let s = self.slot(a, b);
                for i in 0..3 {
                    out[3 * s + i] += 0.25 * cell_grad[c][k][i];
                }
            }
        }
    }

    /// Adds `w · G Gᵀ` over the patch of node `a` into `k` (and `−(w G Gᵀ)_fc ū_c` into `rhs`
    /// as [`scatter_cell`] does), using `dense` and `eqs` as scratch.
    #[allow(clippy::too_many_arguments)]
    pub fn scatter_rank_one(
        &self,
        a: usize,
        w: f64,
        grad: &[f64],
        dofs: &DofMap,
        k: &mut SymmetricMatrix,
        prescribed: Option<&[f64]>,
        rhs: &mut [f64],
        dense: &mut Vec<f64>,
        eqs: &mut Vec<Option<usize>>,
    ) {
        let patch = self.nodes(a);
        let nd = 3 * patch.len();
        dense.clear();
        dense.resize(nd * nd, 0.0);
        for p in 0..nd {
            for q in 0..nd {
                dense[p * nd + q] = w * grad[p] * grad[q];
            }
        }
        eqs.clear();
        eqs.extend(patch.iter().flat_map(|&b| (0..3).map(move |i| 3 * b + i)).map(|d| dofs.eq(d)));
        scatter_cell(k, dense, patch, eqs, prescribed, rhs);
    }
}

/// Volume gradients `g_e = V_e ∇N_e` of every reference cell (the small-strain `∂v_e/∂x`).
pub fn reference_volume_gradients(mesh: &Mesh, patches: &NodalPatches) -> Vec<[[f64; 3]; 4]> {
    let (mut x, mut g) = ([[0.0; 3]; 4], [[0.0; 3]; 4]);
    (0..mesh.n_cells())
        .map(|c| {
            mesh.cell_coords(c, &mut x);
            shape::physical_gradients(&x, &shape::TET_DN, &mut g);
            let v = patches.cell_volume(c);
            g.map(|gb| gb.map(|x| v * x))
        })
        .collect()
}

/// The small-strain nodal dilatations `θ_a − 1 = G_a · u / V_a` of every node, from the full
/// displacement vector.
pub fn nodal_dilatations(mesh: &Mesh, patches: &NodalPatches, grads: &[[[f64; 3]; 4]], u: &[f64]) -> Vec<f64> {
    let mut div = vec![0.0; mesh.n_nodes()];
    for (c, cell) in mesh.cells_iter().enumerate() {
        // v_e's rate: Σ_b g_{e,b} · u_b
        let dv: f64 = cell
            .iter()
            .enumerate()
            .map(|(k, &b)| (0..3).map(|i| grads[c][k][i] * u[3 * b + i]).sum::<f64>())
            .sum();
        for &a in cell {
            div[a] += 0.25 * dv;
        }
    }
    for (a, d) in div.iter_mut().enumerate() {
        *d /= patches.volume(a);
    }
    div
}

/// The volume-weighted average over the cells around each node of a per-cell quantity
/// (a nodal bulk modulus from the cells' ones).
pub fn nodal_average(patches: &NodalPatches, of_cell: impl Fn(usize) -> f64) -> Vec<f64> {
    (0..patches.n_nodes())
        .map(|a| {
            let s: f64 = patches.cells(a).iter().map(|&c| 0.25 * patches.cell_volume(c) * of_cell(c)).sum();
            s / patches.volume(a)
        })
        .collect()
}

/// The volumetric state of a deformed tetrahedral mesh under the nodal pressure (large
/// strains; module docs): every cell's current volume and gradients and mean nodal pressure,
/// every node's volumetric modulus, and the volumetric energy.
#[derive(Debug, Clone, PartialEq)]
pub struct NodalVolumes {
    /// Current volume `v_e` of every cell (0 for cells whose law does not split).
    volume_now: Vec<f64>,
    /// Current gradients `h_b = F⁻ᵀ ∇_X N_b` of every cell.
    h: Vec<[[f64; 3]; 4]>,
    /// `p̄_e = ¼ Σ_{a∈e} p_a` (Pa).
    pressure: Vec<f64>,
    /// `k_a / V_a` of every node (Pa/m³), the weight of its rank-one term.
    weight: Vec<f64>,
    /// `Π_vol` (J).
    pub energy: f64,
}

impl NodalVolumes {
    /// The state at displacement `u` (full vector) of cells made of `laws`; cells whose law
    /// does not split (St Venant–Kirchhoff) keep their whole energy in the cell and take no
    /// part. Fails on the first inverted cell or node.
    pub fn at(mesh: &Mesh, patches: &NodalPatches, laws: &LawMap, u: &[f64]) -> Result<Self, (usize, CellError)> {
        let nc = mesh.n_cells();
        let (mut volume_now, mut h) = (vec![0.0; nc], vec![[[0.0; 3]; 4]; nc]);
        let (mut x, mut g) = ([[0.0; 3]; 4], [[0.0; 3]; 4]);
        let nn = mesh.n_nodes();
        let (mut v_ref, mut v_now) = (vec![0.0; nn], vec![0.0; nn]);
        for (c, cell) in mesh.cells_iter().enumerate() {
            if !Volumetric::Nodal.per_node(mesh.kind, laws.of(c)) {
                continue;
            }
            mesh.cell_coords(c, &mut x);
            shape::physical_gradients(&x, &shape::TET_DN, &mut g);
            let mut ue = [0.0; 12];
            for (k, &b) in cell.iter().enumerate() {
                ue[3 * k..3 * k + 3].copy_from_slice(&u[3 * b..3 * b + 3]);
            }
            let f = deformation_gradient(&ue, &g);
            let det_f = f.determinant();
            let fit = match f.try_inverse() {
                Some(inv) if det_f.is_finite() && det_f > 0.0 => inv.transpose(),
                _ => return Err((c, CellError::Inverted { det_f })),
            };
            for k in 0..4 {
                let hk = fit * Vector3::from(g[k]);
                h[c][k] = [hk[0], hk[1], hk[2]];
            }
            let v0 = patches.cell_volume(c);
            volume_now[c] = det_f * v0;
            for &a in cell {
                v_ref[a] += 0.25 * v0;
                v_now[a] += 0.25 * volume_now[c];
            }
        }
        // nodal pressure and modulus: each cell's quarter with its own law, at θ_a
        let (mut p, mut weight) = (vec![0.0; nn], vec![0.0; nn]);
        let mut energy = 0.0;
        for a in 0..nn {
            if v_ref[a] == 0.0 {
                continue;
            }
            let theta = v_now[a] / v_ref[a];
            if theta.is_nan() || theta <= 0.0 {
                return Err((patches.cells(a)[0], CellError::Volume { theta }));
            }
            let (mut dp, mut dk) = (0.0, 0.0);
            for &c in patches.cells(a) {
                if volume_now[c] == 0.0 {
                    continue;
                }
                let (uu, du, ddu) = laws.of(c).volumetric(theta);
                let w = 0.25 * patches.cell_volume(c);
                energy += w * uu;
                dp += w * du;
                dk += w * ddu;
            }
            p[a] = dp / v_ref[a];
            // (k_a / V_a), with k_a = Σ w U'' / V_a
            weight[a] = dk / (v_ref[a] * v_ref[a]);
        }
        let pressure = mesh
            .cells_iter()
            .enumerate()
            .map(|(c, cell)| {
                if volume_now[c] == 0.0 {
                    0.0
                } else {
                    0.25 * cell.iter().map(|&a| p[a]).sum::<f64>()
                }
            })
            .collect();
        Ok(Self {
            volume_now,
            h,
            pressure,
            weight,
            energy,
        })
    }

    /// The mean nodal pressure `p̄_e` of cell `c` (Pa).
    pub fn pressure(&self, c: usize) -> f64 {
        self.pressure[c]
    }

    /// Adds cell `c`'s share of the volumetric forces `p̄_e g_e` into `fe` (12) and, when
    /// given, of the tangent `p̄_e ∂²v_e` into `ke` (12 × 12, row-major).
    pub fn add_cell_terms(&self, c: usize, fe: &mut [f64], ke: Option<&mut [f64]>) {
        let (p, v, h) = (self.pressure[c], self.volume_now[c], &self.h[c]);
        if v == 0.0 {
            return;
        }
        for b in 0..4 {
            for i in 0..3 {
                fe[3 * b + i] += p * v * h[b][i];
            }
        }
        let Some(ke) = ke else { return };
        for b in 0..4 {
            for cc in 0..4 {
                for i in 0..3 {
                    for k in 0..3 {
                        ke[(3 * b + i) * 12 + 3 * cc + k] += p * v * (h[b][i] * h[cc][k] - h[b][k] * h[cc][i]);
                    }
                }
            }
        }
    }

    /// Adds the rank-one nodal terms `(k_a / V_a) G_a G_aᵀ` of every node into `k` (and their
    /// `−K_fc Δū_c` into `rhs`, for the prescribed increments `prescribed`).
    pub fn scatter_node_terms(
        &self,
        mesh: &Mesh,
        patches: &NodalPatches,
        dofs: &DofMap,
        k: &mut SymmetricMatrix,
        prescribed: Option<&[f64]>,
        rhs: &mut [f64],
    ) {
        let grads: Vec<[[f64; 3]; 4]> = (0..mesh.n_cells())
            .map(|c| self.h[c].map(|hb| hb.map(|x| self.volume_now[c] * x)))
            .collect();
        let (mut g, mut dense, mut eqs) = (Vec::new(), Vec::new(), Vec::new());
        for a in 0..mesh.n_nodes() {
            if self.weight[a] == 0.0 {
                continue;
            }
            patches.gather(mesh, a, &grads, &mut g);
            patches.scatter_rank_one(a, self.weight[a], &g, dofs, k, prescribed, rhs, &mut dense, &mut eqs);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::procedural::block_tet;

    #[test]
    fn nodal_volumes_share_out_the_mesh_volume_and_patches_hold_their_cells_nodes() {
        let mesh = block_tet([0.0; 3], [0.02, 0.01, 0.03], [3, 2, 4]);
        let p = NodalPatches::new(&mesh).unwrap();
        let total: f64 = (0..mesh.n_nodes()).map(|a| p.volume(a)).sum();
        assert!((total - 0.02 * 0.01 * 0.03).abs() < 1e-15, "{total}");
        for a in 0..mesh.n_nodes() {
            assert!(p.nodes(a).contains(&a));
            for &c in p.cells(a) {
                assert!(mesh.cell(c).contains(&a));
                assert!(mesh.cell(c).iter().all(|b| p.nodes(a).contains(b)));
            }
        }
        let reach = p.couplings();
        assert!(reach.iter().zip(0..).all(|(r, a)| p.nodes(a).iter().all(|b| r.contains(b))));
    }

    #[test]
    fn a_uniform_expansion_dilates_every_node_alike() {
        let mesh = block_tet([0.0; 3], [0.02, 0.01, 0.03], [3, 2, 4]);
        let p = NodalPatches::new(&mesh).unwrap();
        let g = reference_volume_gradients(&mesh, &p);
        // u = ε x: dilatation tr(ε) = 3ε at every node, boundary nodes included
        let eps = 1e-3;
        let u: Vec<f64> = mesh.nodes.iter().flat_map(|x| x.map(|c| eps * c)).collect();
        for d in nodal_dilatations(&mesh, &p, &g, &u) {
            assert!((d - 3.0 * eps).abs() < 1e-12, "{d}");
        }
        // a rigid rotation (small) dilates nothing
        let u: Vec<f64> = mesh.nodes.iter().flat_map(|x| [-eps * x[1], eps * x[0], 0.0]).collect();
        assert!(nodal_dilatations(&mesh, &p, &g, &u).iter().all(|d| d.abs() < 1e-15));
    }

    #[test]
    fn hexahedra_have_no_nodal_patches() {
        let mesh = crate::mesh::procedural::block_hex([0.0; 3], [1.0; 3], [1, 1, 1]);
        assert_eq!(NodalPatches::new(&mesh).unwrap_err(), PatchError::NotTetrahedra);
    }
}
