//! The integration points where damage lives (seed 000 §4.3: "the chosen points have been
//! taken to coincide with the Gauss integration points of each element").
//!
//! Hexahedra carry the 2×2×2 Gauss points, linear tetrahedra their single point. Each point
//! holds its shape-function gradients `∇N_a` and, for the volumetric part, `∇̄N_a`: on
//! hexahedra the cell average `(1/V)∫∇N_a dV` (the mean-dilatation B̄ of
//! [`crate::fem::Locking::Bbar`], so that damaged near-incompressible hexahedra do not lock),
//! on tetrahedra the same constant gradients. The strain a point sees is
//! `ε̄ = dev sym(Σ_a u_a ⊗ ∇N_a) + ⅓ (Σ_a u_a · ∇̄N_a) I`, its undamaged stress
//! `σ⁰ = κ tr ε̄ I + 2μ dev ε̄`, its undamaged energy `Ψ⁰ = ½ ε̄ : σ⁰`, and its force on the
//! cell's nodes `f_a = w (dev σ ∇N_a + p ∇̄N_a)` with `p = ⅓ tr σ` (that is `B̄ᵀσ`).
//!
//! Tensors are in Voigt order `[xx, yy, zz, xy, yz, zx]` with tensor (not engineering) shear
//! components.

use std::sync::Arc;

use super::law::{DamageLaw, PointState};
use crate::fem::assembly::{DofMap, MaterialMap, SymmetricMatrix, SymmetricPattern, scatter_cell};
use crate::fem::element::ElementError;
use crate::mesh::shape;
use crate::mesh::{CellKind, Mesh};

/// A symmetric tensor in Voigt order with tensor shear components.
pub type Sym = [f64; 6];

/// `a : b` of two symmetric tensors.
#[inline]
pub fn ddot(a: &Sym, b: &Sym) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + 2.0 * (a[3] * b[3] + a[4] * b[4] + a[5] * b[5])
}

/// The integration points of a mesh, with the damage law of those that may tear.
#[derive(Debug, Clone)]
pub struct MaterialPoints {
    /// Nodes per cell (4 or 8).
    pub nodes_per_cell: usize,
    /// The points of cell `c` are `first[c] .. first[c + 1]`.
    pub first: Vec<usize>,
    /// Owning cell of each point.
    pub cell: Vec<usize>,
    /// Integration weight (m³).
    pub weight: Vec<f64>,
    /// `∇N_a` at the point (only the first `nodes_per_cell` rows are used).
    pub grad: Vec<[[f64; 3]; 8]>,
    /// `∇̄N_a`, the gradients of the volumetric part.
    pub vgrad: Vec<[[f64; 3]; 8]>,
    /// Bulk modulus κ of the point's material (Pa).
    pub kappa: Vec<f64>,
    /// Shear modulus μ (Pa).
    pub mu: Vec<f64>,
    /// The damage law of a tearable point (`None`: the material never damages).
    pub law: Vec<Option<DamageLaw>>,
    /// The tearable points, in the order of every damage field (snapshots, POD modes).
    pub tearable: Vec<usize>,
}

impl MaterialPoints {
    /// The points of `mesh` with the moduli of `materials`, with B̄ on hexahedra when `bbar`
    /// (else full integration of the volumetric part); `law_of(cell, size)` gives the
    /// damage law of a tearable cell, where `size` is its characteristic length (m; the
    /// cube root of its volume for a hexahedron, the edge of the regular tetrahedron of its
    /// volume for a tetrahedron).
    pub fn new<E>(
        mesh: &Mesh,
        materials: &MaterialMap,
        bbar: bool,
        mut law_of: impl FnMut(usize, f64) -> Result<Option<DamageLaw>, E>,
    ) -> Result<Self, PointsError<E>> {
        let n = mesh.kind.nodes_per_cell();
        let mut pts = Self {
            nodes_per_cell: n,
            first: Vec::with_capacity(mesh.n_cells() + 1),
            cell: Vec::new(),
            weight: Vec::new(),
            grad: Vec::new(),
            vgrad: Vec::new(),
            kappa: Vec::new(),
            mu: Vec::new(),
            law: Vec::new(),
            tearable: Vec::new(),
        };
        let mut x = vec![[0.0; 3]; n];
        let gauss = shape::hex_gauss_2();
        for c in 0..mesh.n_cells() {
            pts.first.push(pts.cell.len());
            mesh.cell_coords(c, &mut x);
            let mat = materials.of(c);
            let mut grads: Vec<([[f64; 3]; 8], f64)> = Vec::with_capacity(8);
            match mesh.kind {
                CellKind::Tet4 => {
                    let mut g = [[0.0; 3]; 8];
                    let det = shape::physical_gradients(&x, &shape::TET_DN, &mut g[..4]);
                    grads.push((g, det / 6.0));
                }
                CellKind::Hex8 => {
                    for q in gauss {
                        let mut g = [[0.0; 3]; 8];
                        let det = shape::physical_gradients(&x, &shape::hex_dn(q), &mut g);
                        grads.push((g, det));
                    }
                }
            }
            if let Some(&(_, det)) = grads.iter().find(|(_, w)| *w <= 0.0) {
                return Err(PointsError::Cell {
                    cell: c,
                    source: ElementError::NonPositiveJacobian { det },
                });
            }
            let volume: f64 = grads.iter().map(|(_, w)| w).sum();
            let mut gbar = [[0.0; 3]; 8];
            for (g, w) in &grads {
                for a in 0..n {
                    for i in 0..3 {
                        gbar[a][i] += w * g[a][i] / volume;
                    }
                }
            }
            let size = match mesh.kind {
                CellKind::Hex8 => volume.cbrt(),
                CellKind::Tet4 => (6.0 * std::f64::consts::SQRT_2 * volume).cbrt(),
            };
            let law = law_of(c, size).map_err(PointsError::Law)?;
            for (g, w) in grads {
                if law.is_some() {
                    pts.tearable.push(pts.cell.len());
                }
                pts.cell.push(c);
                pts.weight.push(w);
                pts.grad.push(g);
                pts.vgrad.push(if bbar { gbar } else { g });
                pts.kappa.push(mat.bulk());
                pts.mu.push(mat.shear());
                pts.law.push(law);
            }
        }
        pts.first.push(pts.cell.len());
        Ok(pts)
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.cell.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.cell.is_empty()
    }

    /// The strain `ε̄` at point `p` from the full displacement vector `u`.
    #[inline]
    pub fn strain(&self, mesh: &Mesh, p: usize, u: &[f64]) -> Sym {
        let cell = mesh.cell(self.cell[p]);
        let (g, gv) = (&self.grad[p], &self.vgrad[p]);
        let mut h = [[0.0; 3]; 3];
        let mut theta_bar = 0.0;
        for (a, &node) in cell.iter().enumerate() {
            let ua = [u[3 * node], u[3 * node + 1], u[3 * node + 2]];
            for i in 0..3 {
                for j in 0..3 {
                    h[i][j] += ua[i] * g[a][j];
                }
                theta_bar += ua[i] * gv[a][i];
            }
        }
        let tr = h[0][0] + h[1][1] + h[2][2];
        let d = (theta_bar - tr) / 3.0;
        [
            h[0][0] + d,
            h[1][1] + d,
            h[2][2] + d,
            0.5 * (h[0][1] + h[1][0]),
            0.5 * (h[1][2] + h[2][1]),
            0.5 * (h[2][0] + h[0][2]),
        ]
    }

    /// The undamaged stress `σ⁰ = κ tr ε I + 2μ dev ε`.
    #[inline]
    pub fn stress0(&self, p: usize, e: &Sym) -> Sym {
        let (k, m) = (self.kappa[p], self.mu[p]);
        let tr = e[0] + e[1] + e[2];
        let v = k * tr - 2.0 * m * tr / 3.0;
        [
            v + 2.0 * m * e[0],
            v + 2.0 * m * e[1],
            v + 2.0 * m * e[2],
            2.0 * m * e[3],
            2.0 * m * e[4],
            2.0 * m * e[5],
        ]
    }

    /// The equivalent strain `Φ = √(2Ψ⁰) = √(ε : σ⁰)` (√Pa) and `σ⁰` at point `p`.
    #[inline]
    pub fn phi(&self, mesh: &Mesh, p: usize, u: &[f64]) -> (f64, Sym) {
        let e = self.strain(mesh, p, u);
        let s = self.stress0(p, &e);
        (ddot(&e, &s).max(0.0).sqrt(), s)
    }

    /// `B̄ᵀσ` at point `p` (without the weight), flat `3n`: `dev σ ∇N_a + ⅓ tr σ ∇̄N_a`.
    #[inline]
    pub fn b_transpose(&self, p: usize, s: &Sym, out: &mut [f64]) {
        let (g, gv) = (&self.grad[p], &self.vgrad[p]);
        let pr = (s[0] + s[1] + s[2]) / 3.0;
        let dev = [[s[0] - pr, s[3], s[5]], [s[3], s[1] - pr, s[4]], [s[5], s[4], s[2] - pr]];
        for a in 0..self.nodes_per_cell {
            for i in 0..3 {
                out[3 * a + i] = dev[i][0] * g[a][0] + dev[i][1] * g[a][1] + dev[i][2] * g[a][2] + pr * gv[a][i];
            }
        }
    }

    /// Adds `c · w_p B̄ᵀ C⁰ B̄` of point `p` to the cell matrix `ke` (row-major `(3n)²`).
    #[inline]
    pub fn add_stiffness(&self, p: usize, c: f64, ke: &mut [f64]) {
        let n = self.nodes_per_cell;
        let w = c * self.weight[p];
        crate::fem::element::add_terms(ke, n, &self.vgrad[p][..n], w, self.kappa[p], 0.0, true, false);
        crate::fem::element::add_terms(ke, n, &self.grad[p][..n], w, 0.0, self.mu[p], false, true);
    }

    /// Adds `c · v vᵀ` to `ke` for a vector `v` of length `3n`.
    #[inline]
    pub fn add_rank_one(c: f64, v: &[f64], ke: &mut [f64]) {
        let nd = v.len();
        for i in 0..nd {
            for j in 0..nd {
                ke[i * nd + j] += c * v[i] * v[j];
            }
        }
    }

    /// Assembles `Σ_p w_p B̄ᵀ C_p B̄` over free dofs, with `C_p = coef(p) C⁰ − rank(p)` where
    /// `rank(p) = Some((c, σ))` subtracts `c σ⊗σ` (the loading part of the consistent tangent,
    /// `c = h/r`), and adds `−K_fc ū_c` to `rhs` for the `prescribed` values (full length).
    pub fn assemble(
        &self,
        mesh: &Mesh,
        dofs: &DofMap,
        pattern: Arc<SymmetricPattern>,
        coef: impl Fn(usize) -> f64,
        rank: impl Fn(usize) -> Option<(f64, Sym)>,
        prescribed: Option<&[f64]>,
        rhs: &mut [f64],
    ) -> SymmetricMatrix {
        let mut k = SymmetricMatrix::zeros(pattern);
        let n = self.nodes_per_cell;
        let nd = 3 * n;
        let (mut ke, mut v, mut eqs) = (vec![0.0; nd * nd], vec![0.0; nd], vec![None; nd]);
        for c in 0..mesh.n_cells() {
            ke.fill(0.0);
            let mut any = false;
            for p in self.first[c]..self.first[c + 1] {
                let cp = coef(p);
                if cp != 0.0 {
                    self.add_stiffness(p, cp, &mut ke);
                    any = true;
                }
                if let Some((r, s)) = rank(p) {
                    self.b_transpose(p, &s, &mut v);
                    Self::add_rank_one(-r * self.weight[p], &v, &mut ke);
                    any = true;
                }
            }
            if !any {
                continue;
            }
            let cell = mesh.cell(c);
            for a in 0..n {
                for i in 0..3 {
                    eqs[3 * a + i] = dofs.eq(3 * cell[a] + i);
                }
            }
            scatter_cell(&mut k, &ke, cell, &eqs, prescribed, rhs);
        }
        k
    }

    /// The internal forces `Σ_p w_p g_p B̄ᵀσ⁰_p` (full length) of the displacement `u` with
    /// the damage `state` (one entry per point).
    pub fn internal_forces(&self, mesh: &Mesh, state: &[PointState], u: &[f64], f: &mut [f64]) {
        f.fill(0.0);
        let nd = 3 * self.nodes_per_cell;
        let mut v = vec![0.0; nd];
        for p in 0..self.len() {
            let e = self.strain(mesh, p, u);
            let s = self.stress0(p, &e);
            self.b_transpose(p, &s, &mut v);
            let c = state[p].g * self.weight[p];
            for (k, &node) in mesh.cell(self.cell[p]).iter().enumerate() {
                for i in 0..3 {
                    f[3 * node + i] += c * v[3 * k + i];
                }
            }
        }
    }

    /// The stored energy `Σ_p w_p g_p Ψ⁰_p` (J).
    pub fn stored_energy(&self, mesh: &Mesh, state: &[PointState], u: &[f64]) -> f64 {
        (0..self.len())
            .map(|p| {
                let (phi, _) = self.phi(mesh, p, u);
                0.5 * state[p].g * self.weight[p] * phi * phi
            })
            .sum()
    }

    /// The damage of every cell: the mean of its points' `D` weighted by their weights.
    pub fn cell_damage(&self, state: &[PointState], out: &mut [f64]) {
        for (c, o) in out.iter_mut().enumerate() {
            let (mut d, mut w) = (0.0, 0.0);
            for p in self.first[c]..self.first[c + 1] {
                d += self.weight[p] * state[p].damage();
                w += self.weight[p];
            }
            *o = d / w;
        }
    }
}

/// The points could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PointsError<E> {
    /// A cell is inverted or degenerate.
    #[error("cell {cell}: {source}")]
    Cell {
        /// The cell.
        cell: usize,
        /// What is wrong with it.
        source: ElementError,
    },
    /// A cell's damage law is out of range.
    #[error("{0}")]
    Law(E),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::Locking;
    use crate::material::LinearElastic;
    use crate::mesh::procedural;

    fn points(kind: CellKind) -> (Mesh, MaterialMap, MaterialPoints) {
        let mesh = match kind {
            CellKind::Hex8 => procedural::block_hex([0.0; 3], [1.0, 0.7, 0.5], [2, 2, 1]),
            CellKind::Tet4 => procedural::block_tet([0.0; 3], [1.0, 0.7, 0.5], [2, 2, 1]),
        };
        let mat = MaterialMap::uniform(LinearElastic::new(1000.0, 0.3).unwrap(), 1.0, mesh.n_cells());
        let pts = MaterialPoints::new(&mesh, &mat, true, |_, _| Ok::<_, ()>(None)).unwrap();
        (mesh, mat, pts)
    }

    #[test]
    fn undamaged_points_assemble_the_bbar_stiffness() {
        for (kind, locking) in [(CellKind::Hex8, Locking::Bbar), (CellKind::Tet4, Locking::None)] {
            let (mesh, mat, pts) = points(kind);
            let dofs = DofMap::new(&vec![false; 3 * mesh.n_nodes()]);
            let pattern = Arc::new(SymmetricPattern::build(&mesh, &dofs));
            let mut rhs = vec![0.0; dofs.n_free()];
            let k = pts.assemble(&mesh, &dofs, pattern.clone(), |_| 1.0, |_| None, None, &mut rhs);
            let k0 =
                crate::fem::assembly::assemble_stiffness(&mesh, &mat, locking, &dofs, pattern, &vec![0.0; 3 * mesh.n_nodes()], &mut rhs)
                    .unwrap();
            let scale = k0.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (a, b) in k.values.iter().zip(&k0.values) {
                assert!((a - b).abs() < 1e-12 * scale, "{kind:?}: {a} vs {b}");
            }
            // and its internal forces are K u
            let u: Vec<f64> = (0..3 * mesh.n_nodes()).map(|i| ((i * 7919) % 13) as f64 * 1e-3).collect();
            let mut f = vec![0.0; u.len()];
            pts.internal_forces(&mesh, &vec![PointState::VIRGIN; pts.len()], &u, &mut f);
            let mut ku = vec![0.0; u.len()];
            k.mul_vec(&u, &mut ku);
            for (a, b) in f.iter().zip(&ku) {
                assert!((a - b).abs() < 1e-10 * scale, "{kind:?}: f {a} vs Ku {b}");
            }
            // and the energy is ½ uᵀKu
            let e = pts.stored_energy(&mesh, &vec![PointState::VIRGIN; pts.len()], &u);
            let half_uku = 0.5 * u.iter().zip(&ku).map(|(a, b)| a * b).sum::<f64>();
            assert!((e - half_uku).abs() < 1e-10 * half_uku);
        }
    }
}
