//! Co-rotational XFEM (seed 003 §3.1, Eqs. 1–6): linear elasticity in a frame that turns
//! with each side of each cut element, so that a flap cut loose and rotating keeps its
//! volume where the linear XFEM inflates it.
//!
//! # Sides and their virtual elements
//! With the shifted Heaviside, a cell cut by the planes of its cracked nodes falls into sides
//! (the sub-cells with one sign pattern, [`super::system::side_moments`]); on a side `s` the
//! displacement is that of a *virtual element* on the cell's nodes (seed 003 Eq. 4, the
//! "alternative mesh" of §3.2): `p_sa = u_a + Σ_k H̃_k(s) q_k` over the enriched nodes `k` at
//! node `a`. An uncut cell is one side with `p_a = u_a`.
//!
//! # Forces
//! Each side turns with its own rotation `R_s`, the polar factor of the side's mean
//! deformation gradient `F_s = I + Σ_a p_sa ⊗ ḡ_a` (`ḡ_a` the mean of `∇N_a` over the side;
//! exact for tetrahedra), and its elastic forces are those of the linear side stiffness in that
//! frame (Eq. 1):
//!
//! `f_s = R_s K_s (R_sᵀ x_s − X)`, `K_s = ∫_{V_s} Bᵀ C B dV`, `x_s = X + p_s`,
//!
//! distributed to the generalized nodes as the virtual element's nodes are made of them: all
//! of `f_sa` to node `a`, `H̃_k(s) f_sa` to enriched node `k` (Eqs. 2–3, 5). The seed scales
//! the whole cell's stiffness by the side's volume fraction, `(V_s/V) K`; we integrate the side
//! exactly on its sub-cells, which is the same for a constant-strain tetrahedron and better
//! for a hexahedron. A rigid motion of any side — each its own rotation, a piece cut loose
//! included — makes `R_sᵀ x_s − X` a translation, which `K_s` annihilates: zero force.
//!
//! # Solve
//! Quasi-static, in load steps; each step iterates `K_w δ = f_ext − f_int` with the warped
//! stiffness `K_w = Σ_s T_sᵀ R_s K_s R_sᵀ T_s` (`T_s` the virtual element's map from the
//! generalized nodes; the derivative of `R_s` left out, as the co-rotational method does: the
//! iteration converges to the exact equilibrium of `f_int`, linearly).
//!
//! # Loose pieces
//! A piece the cut frees from every support has a singular stiffness. As the linear XFEM's
//! [`super::Detached::Hold`], a soft foundation of stiffness `E·h` per copy holds it
//! ([`CorotationalXfem::loose_pieces`]); it is anchored where the piece was when it came loose
//! ([`CorotationalXfem::anchor_loose`]), so the piece stays there and carries its own loads.
//!
//! # Volumetric locking
//! The sides use the plain (fully integrated) element: the co-rotational model does not carry
//! B̄ or the averaged nodal pressure (their dilatation couples the sides of a cut cell).

use std::sync::Arc;

use nalgebra::Matrix3;

use super::enrichment::Enrichment;
use super::system::{self, XfemError, generalized_cell, moment_block, side_moments};
use crate::fem::assembly::{self, DofMap, MaterialMap, SymmetricMatrix, SymmetricPattern};
use crate::fem::linear_static::StaticProblem;
use crate::mesh::Mesh;
use crate::solve::Cholesky;

/// Why a co-rotational solve failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CorotationalError {
    /// The model could not be set up or a factorization failed.
    #[error(transparent)]
    Xfem(#[from] XfemError),
    /// A load step's equilibrium iteration did not converge.
    #[error("load step {step}: no equilibrium after {iterations} iterations (relative residual {residual:.2e})")]
    NotConverged {
        /// The step (1-based).
        step: usize,
        /// Iterations done.
        iterations: usize,
        /// Last relative residual.
        residual: f64,
    },
}

/// One side of one cell and its virtual element.
#[derive(Debug, Clone)]
struct Side {
    cell: usize,
    /// `(local node a, generalized node n + k, H̃_k(s))` of every enriched node of the cell
    /// whose shifted Heaviside is not zero on this side.
    enriched: Vec<(usize, usize, f64)>,
    volume: f64,
    /// Mean gradient of each standard function over the side.
    mean_grad: [[f64; 3]; 8],
    /// `K_s`, row-major `3n × 3n`.
    k: Vec<f64>,
}

/// Sides per parallel chunk of the force evaluation.
const FORCE_CHUNK: usize = 2048;

/// The co-rotational XFEM model of a cut organ.
#[derive(Debug, Clone)]
pub struct CorotationalXfem {
    mesh: Mesh,
    sides: Vec<Side>,
    /// Over the `3(n + m)` generalized degrees of freedom.
    dofs: DofMap,
    pattern: Arc<SymmetricPattern>,
    /// Prescribed values of the generalized dofs (the problem's; enriched ones zero).
    prescribed: Vec<f64>,
    forces: Vec<f64>,
    /// Pieces no support holds ([`Self::loose_pieces`]).
    loose: Vec<(Vec<usize>, Vec<String>)>,
    /// The soft foundation that holds them.
    foundation: Foundation,
}

/// A soft elastic foundation on the copies of the loose pieces (the linear XFEM's
/// [`super::Detached::Hold`]): the energy `½ k Σ_c |w_c(d) − w_c(d̄)|²`, `w_c` a copy's
/// displacement (`u_a` for a node's own side, `u_a + s q_k` for the other side of enriched
/// node `k`) and `d̄` the anchor state — rest, or where the piece came loose
/// ([`CorotationalXfem::anchor_loose`]). It does not turn with the piece: it holds it where
/// it was, as forceps would, and carries the piece's own loads.
#[derive(Debug, Clone, Default)]
struct Foundation {
    /// `k = E·h` per copy and component.
    stiffness: f64,
    /// Every held copy's generalized nodes with their coefficients, and its anchor
    /// displacement.
    copies: Vec<(Vec<(usize, f64)>, [f64; 3])>,
    /// Which copy each is, across models of a growing cut: its node, and the plane of the
    /// enrichment whose other side it is (`None`: the node's own side).
    ids: Vec<(usize, Option<super::Plane>)>,
}

impl Foundation {
    /// A copy's displacement under `d`.
    fn displacement(terms: &[(usize, f64)], d: &[f64]) -> [f64; 3] {
        let mut w = [0.0; 3];
        for &(g, c) in terms {
            for i in 0..3 {
                w[i] += c * d[3 * g + i];
            }
        }
        w
    }

    /// Adds its forces `k c_j (w_c − w̄_c)` under `d` to `f`.
    fn add_forces(&self, d: &[f64], f: &mut [f64]) {
        for (terms, anchor) in &self.copies {
            let w = Self::displacement(terms, d);
            for &(g, c) in terms {
                for i in 0..3 {
                    f[3 * g + i] += self.stiffness * c * (w[i] - anchor[i]);
                }
            }
        }
    }
}

/// Settings of the equilibrium iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorotationalSettings {
    /// Load steps.
    pub steps: usize,
    /// Convergence: the residual's norm below this fraction of the external and reaction
    /// forces' (or, when both vanish — a piece turned free of stress —, of the largest
    /// unbalance a load step started with).
    pub tolerance: f64,
    /// Most iterations per step.
    pub max_iterations: usize,
}

impl Default for CorotationalSettings {
    /// 10 steps, 10⁻⁸, 200 iterations.
    fn default() -> Self {
        Self {
            steps: 10,
            tolerance: 1e-8,
            max_iterations: 200,
        }
    }
}

/// A converged co-rotational solution.
#[derive(Debug, Clone, PartialEq)]
pub struct CorotationalSolution {
    /// Every generalized degree of freedom: the nodes' displacements (m), then the enriched
    /// nodes' jumps.
    pub d: Vec<f64>,
    /// Equilibrium iterations of each step.
    pub iterations: Vec<usize>,
}

/// The polar rotation of `f` (`f = R U`, `R` proper orthogonal), from its singular value
/// decomposition; the identity for a degenerate `f`.
pub fn polar_rotation(f: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = f.svd(true, true);
    let (Some(mut u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    if (u * v_t).determinant() < 0.0 {
        // the reflection goes to the smallest singular value's direction
        let k = (0..3)
            .min_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]))
            .expect("three singular values");
        u.column_mut(k).neg_mut();
    }
    u * v_t
}

impl CorotationalXfem {
    /// The model of `mesh` with `materials` (linear elastic; the plain element, module docs),
    /// the supports and loads of `problem`, cut by `enr`.
    pub fn new(mesh: &Mesh, materials: &MaterialMap, problem: &StaticProblem, enr: &Enrichment) -> Result<Self, XfemError> {
        let n = mesh.n_nodes();
        let ng = n + enr.len();
        let system::Generalized {
            prescribed,
            dofs,
            supported,
            constrained,
        } = system::generalized_dofs(mesh, problem, enr)?;
        let mut pieces = system::Pieces::new(ng);
        let npc = mesh.kind.nodes_per_cell();
        let (mut cell_nodes, mut local) = (Vec::new(), Vec::new());
        let mut adj: Vec<Vec<usize>> = vec![Vec::new(); ng];
        let mut sides = Vec::new();
        let mut x = [[0.0; 3]; 8];
        for c in 0..mesh.n_cells() {
            generalized_cell(mesh, enr, c, &mut cell_nodes, &mut local);
            for &a in &cell_nodes {
                adj[a].extend_from_slice(&cell_nodes);
            }
            mesh.cell_coords(c, &mut x[..npc]);
            let mat = &materials.table[materials.of_cell[c] as usize];
            let (kappa, mu) = (mat.bulk(), mat.shear());
            let moments = side_moments(mesh.kind, &x[..npc], enr, &local)
                .map_err(|source| XfemError::Assembly(assembly::AssemblyError { cell: c, source }))?;
            let total: f64 = moments.iter().map(|s| s.side.volume).sum();
            for sm in moments.iter().filter(|s| s.side.volume > 1e-12 * total) {
                let nd = 3 * npc;
                let mut k = vec![0.0; nd * nd];
                for a in 0..npc {
                    for b in 0..npc {
                        let block = moment_block(&sm.moment(npc, a, b), mu, kappa, true);
                        for i in 0..3 {
                            k[(3 * a + i) * nd + 3 * b..(3 * a + i) * nd + 3 * b + 3].copy_from_slice(&block[i]);
                        }
                    }
                }
                let enriched: Vec<(usize, usize, f64)> = local
                    .iter()
                    .zip(&sm.side.shifts)
                    .filter(|(_, s)| **s != 0.0)
                    .map(|(&(a, kk), &s)| (a, n + kk, s))
                    .collect();
                // the copies this side joins into one piece of material
                let cell = mesh.cell(c);
                let copy = |a: usize| enriched.iter().find(|e| e.0 == a).map_or(cell[a], |e| e.1);
                for a in 1..npc {
                    pieces.join(copy(0), copy(a));
                }
                sides.push(Side {
                    cell: c,
                    enriched,
                    volume: sm.side.volume,
                    mean_grad: std::array::from_fn(|a| sm.g[a].map(|v| v / sm.side.volume)),
                    k,
                });
            }
        }
        for l in adj.iter_mut() {
            l.sort_unstable();
            l.dedup();
        }
        let loose = system::loose_pieces(mesh, enr, &mut pieces, &supported, &constrained);
        let foundation = Foundation {
            stiffness: if loose.is_empty() {
                0.0
            } else {
                system::foundation_stiffness(mesh, materials)
            },
            copies: loose
                .iter()
                .flat_map(|(copies, _)| copies.iter().map(|&c| (system::copy_terms(enr, n, c), [0.0; 3])))
                .collect(),
            ids: loose
                .iter()
                .flat_map(|(copies, _)| {
                    copies.iter().map(|&c| {
                        if c < n {
                            (c, None)
                        } else {
                            (enr.nodes[c - n], Some(enr.planes[c - n]))
                        }
                    })
                })
                .collect(),
        };
        let pattern = Arc::new(SymmetricPattern::from_adjacency(&adj, &dofs));
        let mut forces = problem.forces.clone();
        forces.resize(3 * ng, 0.0);
        Ok(Self {
            mesh: mesh.clone(),
            sides,
            dofs,
            pattern,
            prescribed,
            forces,
            loose,
            foundation,
        })
    }

    /// The pieces the cut set loose from every support (their copies — `a < n` a node's own
    /// side, `n + k` the other side of enriched node `k` — and the rigid motions left free).
    /// A soft foundation of stiffness `E·h` per copy holds them (as the linear XFEM's
    /// [`super::Detached::Hold`]), at rest unless anchored elsewhere
    /// ([`Self::anchor_loose`]).
    pub fn loose_pieces(&self) -> &[(Vec<usize>, Vec<String>)] {
        &self.loose
    }

    /// Anchors the foundation of the loose pieces at the state `d` (e.g. the deformation the
    /// cut set them loose in, carried over: [`Self::carry_over`]): they are held where they
    /// were, not pulled back to rest. A copy that `previous` (the model of the cut before)
    /// already held keeps its anchor, so a held piece does not creep by its sag at every
    /// growth of the cut.
    ///
    /// # Panics
    /// If `d` is not [`Self::n_dofs`] long.
    pub fn anchor_loose(&mut self, d: &[f64], previous: Option<&CorotationalXfem>) {
        assert_eq!(d.len(), self.dofs.n_dofs(), "a state of every generalized dof");
        let f = &mut self.foundation;
        for ((terms, anchor), id) in f.copies.iter_mut().zip(&f.ids) {
            let kept = previous.and_then(|p| {
                let g = &p.foundation;
                g.ids.iter().position(|i| i == id).map(|j| g.copies[j].1)
            });
            *anchor = kept.unwrap_or_else(|| Foundation::displacement(terms, d));
        }
    }

    /// The foundation's forces on the loose pieces under `d` (zero without loose pieces):
    /// `k c_j (w_c − w̄_c)` on every generalized dof of every held copy (the loads the
    /// foundation carries, with the sign of an internal force).
    pub fn foundation_forces(&self, d: &[f64]) -> Vec<f64> {
        let mut f = vec![0.0; d.len()];
        self.foundation.add_forces(d, &mut f);
        f
    }

    /// The prescribed values of every generalized dof (the problem's supports; zero on the
    /// enriched dofs), what [`Frames::step`] takes for a fixed support.
    pub fn prescribed(&self) -> &[f64] {
        &self.prescribed
    }

    /// The index among the free dofs of generalized dof `dof` (`None`: constrained), the
    /// numbering of [`Self::factor_at`]'s factor.
    pub fn free_index(&self, dof: usize) -> Option<usize> {
        self.dofs.eq(dof)
    }

    /// Generalized degrees of freedom, `3(n + m)`.
    pub fn n_dofs(&self) -> usize {
        self.dofs.n_dofs()
    }

    /// Sides of all cells (an uncut cell is one).
    pub fn n_sides(&self) -> usize {
        self.sides.len()
    }

    /// The virtual element's nodal displacements of `side` under `d`.
    fn virtual_nodes(&self, side: &Side, d: &[f64], p: &mut [[f64; 3]; 8]) {
        for (a, &node) in self.mesh.cell(side.cell).iter().enumerate() {
            p[a] = [d[3 * node], d[3 * node + 1], d[3 * node + 2]];
        }
        for &(a, g, s) in &side.enriched {
            for i in 0..3 {
                p[a][i] += s * d[3 * g + i];
            }
        }
    }

    /// The side's mean deformation gradient for virtual displacements `p`.
    fn gradient(&self, side: &Side, p: &[[f64; 3]; 8]) -> Matrix3<f64> {
        let npc = self.mesh.kind.nodes_per_cell();
        let mut f = Matrix3::identity();
        for (pa, g) in p.iter().zip(&side.mean_grad).take(npc) {
            for i in 0..3 {
                for j in 0..3 {
                    f[(i, j)] += pa[i] * g[j];
                }
            }
        }
        f
    }

    /// Every side under `d` (uncut cells included), in side order: its cell, reference
    /// volume and mean deformation gradient `F_s`.
    pub fn deformations(&self, d: &[f64]) -> Vec<(usize, f64, Matrix3<f64>)> {
        let mut p = [[0.0; 3]; 8];
        self.sides
            .iter()
            .map(|s| {
                self.virtual_nodes(s, d, &mut p);
                (s.cell, s.volume, self.gradient(s, &p))
            })
            .collect()
    }

    /// The rotation `R_s` of every side under `d`, in side order.
    pub fn rotations(&self, d: &[f64]) -> Vec<Matrix3<f64>> {
        self.deformations(d).iter().map(|(_, _, f)| polar_rotation(f)).collect()
    }

    /// The elastic forces `f_int(d)` on every generalized degree of freedom (module docs; full
    /// length; on constrained dofs, `f_int − f_ext` is the reaction), the foundation's on the
    /// loose pieces included ([`Self::loose_pieces`]).
    pub fn internal_forces(&self, d: &[f64]) -> Vec<f64> {
        use rayon::prelude::*;
        // fixed chunks of sides in parallel, their sums added in order: the same bits every run
        let parts: Vec<Vec<f64>> = self.sides.par_chunks(FORCE_CHUNK).map(|sides| self.side_forces(sides, d)).collect();
        let mut parts = parts.into_iter();
        let mut f = parts.next().unwrap_or_else(|| vec![0.0; d.len()]);
        for part in parts {
            for (a, b) in f.iter_mut().zip(&part) {
                *a += b;
            }
        }
        self.foundation.add_forces(d, &mut f);
        f
    }

    /// The elastic forces of `sides` (type docs), over every generalized dof.
    fn side_forces(&self, sides: &[Side], d: &[f64]) -> Vec<f64> {
        let npc = self.mesh.kind.nodes_per_cell();
        let nd = 3 * npc;
        let mut f = vec![0.0; d.len()];
        let (mut p, mut e, mut fl) = ([[0.0; 3]; 8], vec![0.0; nd], vec![0.0; nd]);
        for side in sides {
            self.virtual_nodes(side, d, &mut p);
            let r = polar_rotation(&self.gradient(side, &p));
            let cell = self.mesh.cell(side.cell);
            // e = Rᵀ x − X on every node of the virtual element
            for (a, &node) in cell.iter().enumerate() {
                let xa = self.mesh.nodes[node];
                let x = nalgebra::Vector3::new(xa[0] + p[a][0], xa[1] + p[a][1], xa[2] + p[a][2]);
                let local = r.transpose() * x;
                for i in 0..3 {
                    e[3 * a + i] = local[i] - xa[i];
                }
            }
            for (row, out) in fl.iter_mut().enumerate() {
                *out = side.k[row * nd..(row + 1) * nd].iter().zip(&e).map(|(k, v)| k * v).sum();
            }
            for (a, &node) in cell.iter().enumerate() {
                let fa = r * nalgebra::Vector3::new(fl[3 * a], fl[3 * a + 1], fl[3 * a + 2]);
                for i in 0..3 {
                    f[3 * node + i] += fa[i];
                }
                for &(b, g, s) in &side.enriched {
                    if b == a {
                        for i in 0..3 {
                            f[3 * g + i] += s * fa[i];
                        }
                    }
                }
            }
        }
        f
    }

    /// The warped stiffness `Σ_s T_sᵀ R_s K_s R_sᵀ T_s` at `d` over the free generalized dofs
    /// (module docs), plus the loose pieces' foundation: what each equilibrium iteration
    /// factors.
    pub fn tangent(&self, d: &[f64]) -> SymmetricMatrix {
        let npc = self.mesh.kind.nodes_per_cell();
        let nd = 3 * npc;
        let mut k = SymmetricMatrix::zeros(self.pattern.clone());
        let mut p = [[0.0; 3]; 8];
        let mut kr = vec![0.0; nd * nd];
        let (mut nodes, mut coef, mut eqs, mut ke) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut dummy = vec![0.0; self.dofs.n_free()];
        for side in &self.sides {
            self.virtual_nodes(side, d, &mut p);
            let r = polar_rotation(&self.gradient(side, &p));
            // R K_s Rᵀ, block by block
            for a in 0..npc {
                for b in 0..npc {
                    let blk = Matrix3::from_fn(|i, j| side.k[(3 * a + i) * nd + 3 * b + j]);
                    let rot = r * blk * r.transpose();
                    for i in 0..3 {
                        for j in 0..3 {
                            kr[(3 * a + i) * nd + 3 * b + j] = rot[(i, j)];
                        }
                    }
                }
            }
            // the generalized nodes the virtual element is made of: (generalized node, its
            // virtual node, coefficient)
            nodes.clear();
            coef.clear();
            for (a, &node) in self.mesh.cell(side.cell).iter().enumerate() {
                nodes.push(node);
                coef.push((a, 1.0));
            }
            for &(a, g, s) in &side.enriched {
                nodes.push(g);
                coef.push((a, s));
            }
            let ng = nodes.len();
            ke.clear();
            ke.resize(9 * ng * ng, 0.0);
            for (pi, &(a, ca)) in coef.iter().enumerate() {
                for (qi, &(b, cb)) in coef.iter().enumerate() {
                    for i in 0..3 {
                        for j in 0..3 {
                            ke[(3 * pi + i) * 3 * ng + 3 * qi + j] = ca * cb * kr[(3 * a + i) * nd + 3 * b + j];
                        }
                    }
                }
            }
            eqs.clear();
            for &g in &nodes {
                for i in 0..3 {
                    eqs.push(self.dofs.eq(3 * g + i));
                }
            }
            assembly::scatter_cell(&mut k, &ke, &nodes, &eqs, None, &mut dummy);
        }
        for (terms, _) in &self.foundation.copies {
            system::add_copy_spring(&mut k, &self.dofs, terms, self.foundation.stiffness);
        }
        k
    }

    /// Solves for equilibrium under the problem's forces and prescribed displacements ramped
    /// over `settings.steps` load steps (module docs).
    pub fn solve(&self, settings: &CorotationalSettings) -> Result<CorotationalSolution, CorotationalError> {
        let target = self.prescribed.clone();
        self.solve_path(settings, |lambda, out| {
            for (o, t) in out.iter_mut().zip(&target) {
                *o = lambda * t;
            }
        })
    }

    /// [`Self::solve`] with the prescribed values at load factor `λ ∈ (0, 1]` written by
    /// `prescribed(λ, out)` into the full-length `out` (read on constrained dofs only): a
    /// prescribed motion along a path, as a rotation.
    pub fn solve_path(
        &self,
        settings: &CorotationalSettings,
        mut prescribed: impl FnMut(f64, &mut [f64]),
    ) -> Result<CorotationalSolution, CorotationalError> {
        let nd = self.dofs.n_dofs();
        let mut d = vec![0.0; nd];
        let mut target = vec![0.0; nd];
        let mut iterations = Vec::new();
        let mut symbolic = None;
        let steps = settings.steps.max(1);
        let mut r = vec![0.0; self.dofs.n_free()];
        let mut unbalance = 0.0f64;
        for step in 1..=steps {
            let lambda = step as f64 / steps as f64;
            prescribed(lambda, &mut target);
            for (k, v) in d.iter_mut().enumerate() {
                if self.dofs.eq(k).is_none() {
                    *v = target[k];
                }
            }
            let mut done = None;
            let mut residual = f64::INFINITY;
            for it in 0..=settings.max_iterations {
                let (r2, scale2) = self.residual(&d, lambda, &self.forces, &mut r);
                // the scale: external and reaction forces, or — for a motion that ends free of
                // stress, with neither — the largest unbalance a load step started with
                if it == 0 {
                    unbalance = unbalance.max(r2);
                }
                let scale2 = scale2.max(unbalance);
                residual = (r2 / scale2.max(f64::MIN_POSITIVE)).sqrt();
                if !residual.is_finite() {
                    return Err(XfemError::NonFinite.into());
                }
                if residual <= settings.tolerance || scale2 == 0.0 {
                    done = Some(it);
                    break;
                }
                if it == settings.max_iterations {
                    break;
                }
                let chol = self.factor_at(&d, symbolic.take())?;
                symbolic = Some(chol.symbolic().clone());
                chol.solve_in_place(&mut r);
                for (k, v) in d.iter_mut().enumerate() {
                    if let Some(e) = self.dofs.eq(k) {
                        *v += r[e];
                    }
                }
            }
            match done {
                Some(it) => iterations.push(it),
                None => {
                    return Err(CorotationalError::NotConverged {
                        step,
                        iterations: settings.max_iterations,
                        residual,
                    });
                }
            }
        }
        Ok(CorotationalSolution { d, iterations })
    }

    /// The free dofs' residual `r = λ f_ext − f_int(d)` into `r`, `f_ext = forces`; returns
    /// `|r|²` and the square of its scale: the external and reaction forces' norm.
    fn residual(&self, d: &[f64], lambda: f64, forces: &[f64], r: &mut [f64]) -> (f64, f64) {
        let f = self.internal_forces(d);
        let (mut r2, mut scale2) = (0.0, 0.0);
        for (k, &fk) in f.iter().enumerate() {
            let ext = lambda * forces[k];
            match self.dofs.eq(k) {
                Some(e) => {
                    r[e] = ext - fk;
                    r2 += r[e] * r[e];
                    scale2 += ext * ext;
                }
                None => scale2 += (fk - ext) * (fk - ext),
            }
        }
        (r2, scale2)
    }

    /// The Cholesky factor of the warped stiffness at `d` (on the free dofs), reusing a
    /// symbolic analysis when given: what a frame thread's model takes from a slower thread
    /// ([`Frames::install`]).
    pub fn factor_at(&self, d: &[f64], symbolic: Option<faer::sparse::linalg::solvers::SymbolicLlt<usize>>) -> Result<Cholesky, XfemError> {
        let k = self.tangent(d);
        Ok(match symbolic {
            Some(s) => Cholesky::factor_with(s, &k),
            None => Cholesky::factor(&k),
        }?)
    }

    /// The deformation advanced frame by frame from rest ([`Frames`]), under the problem's
    /// forces.
    pub fn frames(self: &Arc<Self>) -> Frames {
        self.frames_from(vec![0.0; self.dofs.n_dofs()])
    }

    /// [`Self::frames`] from the state `d` (e.g. a previous model's, carried over to this
    /// one's dofs: [`Self::carry_over`]).
    ///
    /// # Panics
    /// If `d` is not [`Self::n_dofs`] long.
    pub fn frames_from(self: &Arc<Self>, d: Vec<f64>) -> Frames {
        assert_eq!(d.len(), self.dofs.n_dofs(), "a state of every generalized dof");
        Frames {
            model: self.clone(),
            forces: self.forces.clone(),
            d,
            factor: None,
            r: vec![0.0; self.dofs.n_free()],
            unbalance: 0.0,
        }
    }

    /// The mesh's nodes' displacements of `d` (made for a model cut by `old`), with the
    /// jumps of the enriched nodes this model (cut by `new`) shares with it, and zero for the
    /// others: the state a deformation continues from when the cut grows.
    pub fn carry_over(&self, d: &[f64], old: &Enrichment, new: &Enrichment) -> Vec<f64> {
        let n = 3 * self.mesh.n_nodes();
        let mut out = vec![0.0; self.dofs.n_dofs()];
        out[..n].copy_from_slice(&d[..n]);
        for (k, (node, plane)) in new.nodes.iter().zip(&new.planes).enumerate() {
            if let Some(j) = (0..old.len()).find(|&j| old.nodes[j] == *node && old.planes[j] == *plane)
                && n + 3 * j + 3 <= d.len()
            {
                out[n + 3 * k..n + 3 * k + 3].copy_from_slice(&d[n + 3 * j..n + 3 * j + 3]);
            }
        }
        out
    }

    /// The reference and deformed volumes of the cells for which `which(cell)` holds, under
    /// `d`: `Σ_s V_s` and `Σ_s det(F_s) V_s` over their sides (exact for tetrahedra, the
    /// mean gradient's for hexahedra).
    pub fn volumes(&self, d: &[f64], which: impl Fn(usize) -> bool) -> (f64, f64) {
        let (mut v0, mut v) = (0.0, 0.0);
        for (_, vs, f) in self.deformations(d).iter().filter(|s| which(s.0)) {
            v0 += vs;
            v += f.determinant() * vs;
        }
        (v0, v)
    }

    /// The generalized displacements of a linear XFEM solution, in this model's order.
    pub fn of_linear(solution: &system::XfemSolution) -> Vec<f64> {
        solution.u.iter().chain(&solution.q).copied().collect()
    }
}

/// The co-rotational deformation advanced one frame at a time, at the rate a frame thread
/// sustains (the multi-rate framework of seed 003 §4): each frame evaluates the co-rotational
/// forces at the current state and corrects it once with a factor of the warped stiffness kept
/// across frames,
///
/// `K_w(d_f) δ = λ f_ext − f_int(d)`, `d ← d + δ`,
///
/// `d_f` the state the factor was made at. This is a modified Newton iteration: its fixed
/// point is the exact equilibrium of `f_int` whatever `d_f`, and it converges linearly while
/// the rotations at `d` stay near those at `d_f`. The factorization — most of an iteration's
/// cost — is made off the frame thread from a recent state
/// ([`CorotationalXfem::factor_at`]) and installed when it lands ([`Frames::install`]).
///
/// A correction is kept only if it lowers the residual (one more evaluation of the forces);
/// otherwise the frame factors at its own state — with no factor installed yet, or when the
/// state has turned too far from the factor's: for a slender part, whose axial stiffness the
/// warped stiffness turns into its bending directions, a few degrees suffice to make the stale
/// correction grow the residual.
#[derive(Debug)]
pub struct Frames {
    model: Arc<CorotationalXfem>,
    /// The external forces on the generalized dofs (the problem's, unless set).
    forces: Vec<f64>,
    d: Vec<f64>,
    factor: Option<Cholesky>,
    r: Vec<f64>,
    unbalance: f64,
}

/// What one frame did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameReport {
    /// The residual's norm before the correction, relative to the external and reaction
    /// forces' (or to the largest unbalance seen, when both vanish).
    pub residual: f64,
    /// Whether the frame had to factor: no factor installed yet, or the kept one's correction
    /// did not lower the residual (the state has turned too far from the factor's).
    pub factored: bool,
}

impl Frames {
    /// The current generalized displacements.
    pub fn d(&self) -> &[f64] {
        &self.d
    }

    /// The model the frames advance.
    pub fn model(&self) -> &Arc<CorotationalXfem> {
        &self.model
    }

    /// The external forces the next frames balance (N, on the mesh's nodes: `3 n` values;
    /// the enriched dofs carry none), e.g. a tool's contact force moving from frame to frame.
    ///
    /// # Panics
    /// If `forces` is not `3 n` long.
    pub fn set_forces(&mut self, forces: &[f64]) {
        let n = 3 * self.model.mesh.n_nodes();
        assert_eq!(forces.len(), n, "a force on every node");
        self.forces[..n].copy_from_slice(forces);
        self.forces[n..].fill(0.0);
    }

    /// Installs a new factor of the warped stiffness (made by [`CorotationalXfem::factor_at`],
    /// typically on another thread from a recent [`Frames::d`]); the next frames correct with it.
    pub fn install(&mut self, factor: Cholesky) {
        self.factor = Some(factor);
    }

    /// The installed factor (`None` before the first frame).
    pub fn factor(&self) -> Option<&Cholesky> {
        self.factor.as_ref()
    }

    /// The symbolic analysis of the installed factor, for the next one.
    pub fn symbolic(&self) -> Option<faer::sparse::linalg::solvers::SymbolicLlt<usize>> {
        self.factor.as_ref().map(|f| f.symbolic().clone())
    }

    /// `d ← d + K⁻¹ r` on the free dofs, `r` the residual in `self.r`.
    fn correct(&mut self, factor: &Cholesky) {
        factor.solve_in_place(&mut self.r);
        for (k, v) in self.d.iter_mut().enumerate() {
            if let Some(e) = self.model.dofs.eq(k) {
                *v += self.r[e];
            }
        }
    }

    /// One frame at load factor `lambda` with the constrained dofs at `prescribed` (full
    /// length; read on constrained dofs only): the residual, then one correction with the kept
    /// factor (type docs).
    pub fn step(&mut self, lambda: f64, prescribed: &[f64]) -> Result<FrameReport, CorotationalError> {
        let dofs = &self.model.dofs;
        for (k, v) in self.d.iter_mut().enumerate() {
            if dofs.eq(k).is_none() {
                *v = prescribed[k];
            }
        }
        let (r2, scale2) = self.model.residual(&self.d, lambda, &self.forces, &mut self.r);
        self.unbalance = self.unbalance.max(r2);
        let residual = (r2 / scale2.max(self.unbalance).max(f64::MIN_POSITIVE)).sqrt();
        if !residual.is_finite() {
            return Err(XfemError::NonFinite.into());
        }
        // the correction with the kept factor, kept if it lowers the residual; otherwise (or
        // with no factor yet) a factor made here, at the current state
        let before = self.d.clone();
        let mut factored = self.factor.is_none();
        if let Some(factor) = self.factor.take() {
            self.correct(&factor);
            self.factor = Some(factor);
            let (after, _) = self.model.residual(&self.d, lambda, &self.forces, &mut self.r);
            if after >= r2 {
                self.d.copy_from_slice(&before);
                self.model.residual(&self.d, lambda, &self.forces, &mut self.r);
                factored = true;
            }
        }
        if factored {
            let factor = self.model.factor_at(&self.d, self.symbolic())?;
            self.correct(&factor);
            self.factor = Some(factor);
        }
        Ok(FrameReport { residual, factored })
    }
}
