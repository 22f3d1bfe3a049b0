//! Reduced online cutting (seed 000 §3.2.3, §3.3): `u = u_cont + u_disc`, the continuous part on
//! the PGD modes used as a Ritz basis, the discontinuous part on the enriched nodes of the
//! current cut, solved as one small bordered system per cut.
//!
//! # The two Ritz bases
//! With the spatial modes `F_k` of a vademecum (`u(x; s) ≈ Σ_k F_k(x) G_k(s)`):
//!
//! - **PRB**, the parametric reduced basis (§3.2.1.1, §3.3.1): one coefficient per mode,
//!   `u_cont = Σ_k β_k F_k(x) G_k(s_p)`. At the current load state `s_p` the factor `G_k(s_p)`
//!   only scales the k-th basis function, so the Ritz space is `span{F_k}` and the coefficients
//!   `β_k G_k(s_p)` are what is solved for. (The seed's doubly weak form integrates over every
//!   load state; with a discontinuous part that does not depend on `s`, that would impose one
//!   and the same opening of the cut on every load position, not the one under the tool, so
//!   the form is taken at the current load state.)
//! - **SRB**, the space reduced basis (§3.2.1.2, §3.3.2, Eq. 3.1): one coefficient per mode and
//!   displacement component, `u_j = Σ_i β_ij X̃_ji(x)` — the modes split into their three
//!   component fields, a basis three times larger.
//!
//! # The bordered system
//! The basis `X` (columns over the free standard degrees of freedom) is made K-orthonormal once
//! (`XᵀKX = I`, by the eigen-decomposition of the Gram matrix, dropping directions below 10⁻¹²
//! of the largest). The Galerkin system of the standard weak form (Eq. 3.6) is then
//!
//! `[I  E; Eᵀ  K_ee] [β; q] = [Xᵀf; 0]`,  `E = XᵀK_ue`,
//!
//! with `K_ue`, `K_ee` the blocks of the full-order XFEM stiffness ([`super::system`]) that
//! involve enriched functions. Its Cholesky factor is `[I 0; Eᵀ L_S]` with `L_S L_Sᵀ =
//! K_ee − EᵀE`. When the scalpel enriches new nodes they are *appended*
//! ([`Enrichment::extended`]): their rows of the matrix are new, the old rows do not change
//! (each entry couples two functions and depends on their two planes only), so the factor is
//! *bordered* — new rows computed against the old ones, `O(d²)` per new row for a system of
//! dimension d — and never refactored.
//!
//! # Bare enrichment or local discontinuous fields (§3.2.2)
//! With the *bare* enrichment above, the continuous part has to absorb, on the modes, how the
//! tissue around the cut adjusts to the opening — which the modes, responses of the uncut
//! organ to surface loads, represent poorly (10–40 % error on the patch, `BENCHMARKS.md`). The
//! seed instead pre-computes, by XFEM, a *local discontinuous field* for each cracked node: the
//! opening together with the response of the uncut degrees of freedom to it. Taking for each
//! enriched unknown e the function `ψ_e = [w_e; 1_e]` with `w_e = −K⁻¹ K_ue 1_e` (the static
//! response of the standard degrees of freedom to a unit jump) makes the system block-diagonal,
//! `XᵀK_ext Ψ = 0`:
//!
//! `β = Xᵀf`,  `S q = Wᵀf`,  `S = K_ee − K_eu K⁻¹ K_ue`,  `u = Xβ + Wq`,
//!
//! and the answer is then exact up to the error of the modes on the *uncut* response `K⁻¹f`.
//! Each new enriched unknown costs one sparse solve with the organ's factorization (kept by the
//! model) and borders the Cholesky factor of the Schur complement S.
//!
//! # Online evaluation
//! For a load `f` on a few nodes: `b = Xᵀf` (a few rows of X), a forward and a backward
//! substitution, and the displacement of any node `u_a = X_a β` (its own side) plus `q` for
//! the other side of an enriched node. The contact compliance at a patch of nodes is
//! `C = Φ A⁻¹ Φᵀ = ZᵀZ`, `Z = L⁻¹Φᵀ`: one forward substitution with three right-hand sides,
//! `3m²/2` multiply–adds for m enriched unknowns.
//!
//! # The contact table
//! The forward substitution is linear in its right-hand side, and the factor only grows by
//! bordering (its old rows never change): for every degree of freedom `(a, i)` of the nodes a
//! contact can load, the enriched part of `y_ai = L⁻¹ r_ai` (`r_ai` the unit load at `(a, i)`:
//! its row of `W`, or `[X̂_ai; 0]` bare) is fixed once computed, and a new enriched unknown only
//! appends one entry to each. [`ReducedCut::tabulate`] keeps these columns, extended by every
//! cut step (one row of the factor against each column: `O(d)` per column and new unknown,
//! on the cut's thread). The compliance the cut adds at a patch is then
//!
//! `ΔC = ZᵀZ`,  `Z = Σ_a w_a [y_a0 y_a1 y_a2]` (enriched parts),
//!
//! `15m` multiply–adds instead of `3m²/2`, exact (the same sums in another order). Bare, the
//! identity block's part of `ZᵀZ` is the uncut Ritz compliance `Φ_X Φ_Xᵀ` and cancels exactly.

use std::time::Instant;

use nalgebra::DMatrix;

use super::enrichment::{Enrichment, EnrichmentError, XfemParams};
use super::subcell::Plane;
use super::system::{self, XfemError};
use crate::fem::Locking;
use crate::fem::assembly::{self, DofMap, MaterialMap, SymmetricPattern};
use crate::fem::linear_static::StaticProblem;
use crate::mesh::Mesh;
use crate::rom::pod::dot;

/// Which Ritz basis carries the continuous part (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RitzBasis {
    /// Parametric reduced basis: one coefficient per mode.
    Prb,
    /// Space reduced basis: one coefficient per mode and component.
    Srb,
}

impl RitzBasis {
    /// Its short name.
    pub fn name(self) -> &'static str {
        match self {
            RitzBasis::Prb => "PRB",
            RitzBasis::Srb => "SRB",
        }
    }
}

/// What carries the discontinuous part (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Discontinuous {
    /// The enriched shape functions `N_I H̃_I` alone (Eq. 3.6 as written).
    Bare,
    /// Local discontinuous fields: each enriched function with the static response of the
    /// uncut degrees of freedom to it (§3.2.2).
    LocalFields,
}

/// Why the reduced cut model failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReducedError {
    /// The modes do not match the mesh.
    #[error("the modes have {got} values, expected {modes} modes × {dofs} degrees of freedom")]
    Modes {
        /// Values given.
        got: usize,
        /// Modes announced.
        modes: usize,
        /// Degrees of freedom of the mesh.
        dofs: usize,
    },
    /// The basis spans nothing.
    #[error("the Ritz basis is empty or all its directions are null")]
    EmptyBasis,
    /// Enrichment failed.
    #[error(transparent)]
    Enrichment(#[from] EnrichmentError),
    /// The full-order assembly failed.
    #[error(transparent)]
    Xfem(#[from] XfemError),
    /// The factorization of the uncut stiffness failed.
    #[error(transparent)]
    Solve(#[from] crate::solve::SolveError),
    /// A new row of the bordered factor has no positive pivot: the new enrichment is linearly
    /// dependent on the basis and the old one (e.g. a piece made only of cut lips came loose).
    #[error("bordering the factor failed at enriched unknown {unknown}: the cut made the reduced system singular")]
    Singular {
        /// The enriched unknown.
        unknown: usize,
    },
}

/// What one cut step changed.
#[derive(Debug, Clone, PartialEq)]
pub struct CutUpdate {
    /// Nodes enriched by this step.
    pub new_nodes: Vec<usize>,
    /// Enriched unknowns after the step.
    pub enriched_unknowns: usize,
    /// Time to assemble the new rows (s).
    pub assembly_s: f64,
    /// Time to border the factor (s).
    pub bordering_s: f64,
    /// Time to extend the contact table ([`ReducedCut::tabulate`]) by the new unknowns (s).
    pub tabulating_s: f64,
}

/// The enriched parts of the forward substitutions of the unit loads at the degrees of freedom
/// of the contact nodes (module docs, "The contact table").
#[derive(Debug, Clone)]
struct ContactTable {
    /// The nodes tabulated.
    nodes: std::sync::Arc<[usize]>,
    /// For each node of the mesh, its position in `nodes`, or `u32::MAX`.
    slot: std::sync::Arc<[u32]>,
    /// One block per cut step, covering its new enriched unknowns: entry-major, entry
    /// `3p + i` (node `nodes[p]`, component i) holding the block's unknowns contiguously.
    blocks: Vec<std::sync::Arc<[f64]>>,
    /// Enriched unknowns the blocks cover.
    covered: usize,
}

impl ContactTable {
    fn entries(&self) -> usize {
        3 * self.nodes.len()
    }

    /// Unknowns of a block.
    fn len_of(&self, block: &[f64]) -> usize {
        block.len() / self.entries().max(1)
    }
}

/// What a tick reads of the reduced cutting model: the basis rows, the local fields, the
/// bordered factor — the contact compliance of the cut organ, and nothing that allocates.
///
/// A view is cheap to take ([`ReducedCut::view`]): the basis is shared, each local field is a
/// shared column, only the factor (`O(m²)` for m enriched unknowns) is copied. A session's
/// tick holds one while the cut grows on another thread, and swaps in the next one when it
/// is ready.
#[derive(Debug, Clone)]
pub struct CutView {
    disc: Discontinuous,
    /// The local fields' standard parts `w_e`, one shared column (`n_free`) per enriched unknown.
    w: Vec<std::sync::Arc<[f64]>>,
    dofs: std::sync::Arc<DofMap>,
    /// The K-orthonormal basis, row-major: `n_free × nb`.
    x: std::sync::Arc<[f64]>,
    nb: usize,
    /// The bordered factor: of the whole system (bare) or of S (local fields).
    factor: Bordered,
    /// Workspace of the compliance: three columns of the system's dimension.
    scratch: Vec<f64>,
    /// The contact table, when the model keeps one ([`ReducedCut::tabulate`]).
    table: Option<ContactTable>,
}

/// The reduced cutting model of one organ (module docs).
#[derive(Debug, Clone)]
pub struct ReducedCut {
    basis: RitzBasis,
    /// The uncut stiffness's factorization (local fields only).
    chol: Option<crate::solve::Cholesky>,
    n_nodes: usize,
    /// What the tick reads.
    online: CutView,
    enr: Enrichment,
    /// Equations (of the extended system) of the enriched unknowns, in order.
    enriched_eqs: usize,
    materials: MaterialMap,
    locking: Locking,
    problem: StaticProblem,
    params: XfemParams,
}

impl ReducedCut {
    /// The model with no cut yet, from the spatial modes `modes` (mode-major over all `3n`
    /// degrees of freedom, `n_modes` of them) of a vademecum of the same mesh, supports and
    /// material.
    ///
    /// With local fields the modes may be left out (`n_modes = 0`): the model then carries the
    /// cut's part alone — [`CutView::added_compliance`] is all it answers, what a session
    /// adds to the vademecum's own contact compliance — and costs one factorization of the
    /// uncut stiffness instead of the K-orthonormalisation of the basis (`O(n_b² n)` and a
    /// dense eigenproblem of the basis's size: minutes for thousands of modes).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        mesh: &Mesh,
        materials: &MaterialMap,
        locking: Locking,
        problem: &StaticProblem,
        modes: &[f64],
        n_modes: usize,
        basis: RitzBasis,
        disc: Discontinuous,
        params: &XfemParams,
    ) -> Result<Self, ReducedError> {
        if n_modes == 0 && disc == Discontinuous::LocalFields && modes.is_empty() {
            // the cut's part alone (see above)
            return Self::from_basis(mesh, materials, locking, problem, basis, Vec::new().into(), 0, disc, params);
        }
        let (x, nb) = Self::orthonormal_basis(mesh, materials, locking, problem, modes, n_modes, basis)?;
        Self::from_basis(mesh, materials, locking, problem, basis, x.into(), nb, disc, params)
    }

    /// The K-orthonormal Ritz basis [`new`](Self::new) builds from the modes (row-major
    /// `n_free × nb`, and `nb`): what a bundle stores so that a session with bare
    /// enrichment does not compute it again ([`from_basis`](Self::from_basis)).
    pub fn orthonormal_basis(
        mesh: &Mesh,
        materials: &MaterialMap,
        locking: Locking,
        problem: &StaticProblem,
        modes: &[f64],
        n_modes: usize,
        basis: RitzBasis,
    ) -> Result<(Vec<f64>, usize), ReducedError> {
        let dofs = DofMap::new(&problem.constrained);
        let k = stiffness(mesh, materials, locking, problem, &dofs)?;
        k_orthonormal(&k, &ritz_columns(mesh.n_dofs(), &dofs, modes, n_modes, basis)?)
    }

    /// [`new`](Self::new) on a K-orthonormal basis computed before
    /// ([`orthonormal_basis`](Self::orthonormal_basis), stored in a bundle): `x` row-major
    /// `n_free × nb`, shared (the sessions of one bundle hold one copy).
    #[allow(clippy::too_many_arguments)]
    pub fn from_basis(
        mesh: &Mesh,
        materials: &MaterialMap,
        locking: Locking,
        problem: &StaticProblem,
        basis: RitzBasis,
        x: std::sync::Arc<[f64]>,
        nb: usize,
        disc: Discontinuous,
        params: &XfemParams,
    ) -> Result<Self, ReducedError> {
        let dofs = DofMap::new(&problem.constrained);
        if x.len() != nb * dofs.n_free() || (nb == 0 && disc == Discontinuous::Bare) {
            return Err(ReducedError::Modes {
                got: x.len(),
                modes: nb,
                dofs: dofs.n_free(),
            });
        }
        let k = stiffness(mesh, materials, locking, problem, &dofs)?;
        Self::assemble(mesh, materials, locking, problem, dofs, k, basis, (x, nb), disc, params)
    }

    #[allow(clippy::too_many_arguments)]
    fn assemble(
        mesh: &Mesh,
        materials: &MaterialMap,
        locking: Locking,
        problem: &StaticProblem,
        dofs: DofMap,
        k: assembly::SymmetricMatrix,
        basis: RitzBasis,
        (x, nb): (std::sync::Arc<[f64]>, usize),
        disc: Discontinuous,
        params: &XfemParams,
    ) -> Result<Self, ReducedError> {
        let chol = match disc {
            Discontinuous::Bare => None,
            Discontinuous::LocalFields => Some(crate::solve::Cholesky::factor(&k)?),
        };
        Ok(Self {
            basis,
            chol,
            n_nodes: mesh.n_nodes(),
            online: CutView {
                disc,
                w: Vec::new(),
                dofs: std::sync::Arc::new(dofs),
                x,
                nb,
                factor: Bordered::new(if disc == Discontinuous::Bare { nb } else { 0 }),
                scratch: vec![0.0; 3 * nb],
                table: None,
            },
            enr: Enrichment::none(mesh),
            enriched_eqs: 0,
            materials: materials.clone(),
            locking,
            problem: problem.clone(),
            params: *params,
        })
    }

    /// The basis in use.
    pub fn basis(&self) -> RitzBasis {
        self.basis
    }

    /// Dimension of the continuous part (directions kept of the basis).
    pub fn basis_size(&self) -> usize {
        self.online.nb
    }

    /// Dimension of the bordered system.
    pub fn dim(&self) -> usize {
        self.online.nb + self.enriched_eqs
    }

    /// The current enrichment.
    pub fn enrichment(&self) -> &Enrichment {
        &self.enr
    }

    /// What carries the discontinuous part.
    pub fn discontinuous(&self) -> Discontinuous {
        self.online.disc
    }

    /// Bytes held by the basis, the local fields, the bordered factor and the contact table
    /// (not the uncut factorization).
    pub fn bytes(&self) -> usize {
        8 * (self.online.x.len() + self.online.w.len() * self.online.dofs.n_free() + self.online.factor.l.len()) + self.online.table_bytes()
    }

    /// Cuts the cells `new_cells` (each with the plane that crossed it): enriches their nodes
    /// and borders the factor with the new rows (module docs).
    pub fn cut(&mut self, mesh: &Mesh, new_cells: &[(usize, Plane)]) -> Result<CutUpdate, ReducedError> {
        let fresh: Vec<(usize, Plane)> = new_cells
            .iter()
            .filter(|(c, _)| !self.enr.cut_cells.iter().any(|(d, _)| d == c))
            .copied()
            .collect();
        let enr = self.enr.extended(mesh, &fresh, &self.params)?;
        let old_nodes = self.enr.len();
        let new_nodes = enr.nodes[old_nodes..].to_vec();
        if new_nodes.is_empty() {
            self.enr = enr;
            return Ok(CutUpdate {
                new_nodes,
                enriched_unknowns: self.enriched_eqs,
                assembly_s: 0.0,
                bordering_s: 0.0,
                tabulating_s: 0.0,
            });
        }
        let clock = Instant::now();
        let triplets = system::enriched_rows(mesh, &self.materials, self.locking, &enr, old_nodes)?;
        let nf = self.online.dofs.n_free();
        let n3 = 3 * self.n_nodes;
        // the unknown of every enriched degree of freedom (none where the node is held)
        let mut unknown_of = Vec::with_capacity(3 * enr.len());
        let mut total = 0;
        for &a in &enr.nodes {
            for i in 0..3 {
                unknown_of.push((!self.problem.constrained[3 * a + i]).then(|| {
                    total += 1;
                    total - 1
                }));
            }
        }
        let n_new = total - self.enriched_eqs;
        // the new rows over standard equations (c < nf) and enriched unknowns (nf + e)
        let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n_new];
        for (r, c, v) in triplets {
            let Some(row) = unknown_of[r - n3] else { continue };
            let col = if c < n3 {
                match DofMap::eq(&self.online.dofs, c) {
                    Some(e) => e,
                    None => continue,
                }
            } else {
                match unknown_of[c - n3] {
                    Some(e) if e <= row => nf + e,
                    _ => continue,
                }
            };
            rows[row - self.enriched_eqs].push((col, v));
        }
        let assembly_s = clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        let nb = self.online.nb;
        let m0 = self.enriched_eqs;
        // a failed step leaves the model at the previous cut
        let rollback = (self.online.factor.l.len(), self.online.factor.row_start.len(), self.online.w.len());
        let mut a = Vec::new();
        let mut w = vec![0.0; nf];
        for (j, row) in rows.iter().enumerate() {
            let e = m0 + j;
            match self.online.disc {
                Discontinuous::Bare => {
                    // A[d, 0..nb] = Σ_c K[r, c] X̂[c, :]; A[d, nb + e'] = K[r, nf + e']
                    let d = nb + e;
                    a.clear();
                    a.resize(d + 1, 0.0);
                    for &(c, v) in row {
                        if c < nf {
                            let xr = &self.online.x[c * nb..(c + 1) * nb];
                            for (t, xv) in xr.iter().enumerate() {
                                a[t] += v * xv;
                            }
                        } else {
                            a[nb + c - nf] += v;
                        }
                    }
                    if self.online.factor.border(d, &a).is_err() {
                        self.undo(rollback);
                        return Err(ReducedError::Singular { unknown: e });
                    }
                }
                Discontinuous::LocalFields => {
                    // w_e = −K⁻¹ K_ue 1_e; S[e, e'] = K_ee[e, e'] + K_eu[e, :] w_e'
                    w.fill(0.0);
                    for &(c, v) in row.iter().filter(|(c, _)| *c < nf) {
                        w[c] -= v;
                    }
                    self.chol
                        .as_ref()
                        .expect("local fields keep the factorization")
                        .solve_in_place(&mut w);
                    self.online.w.push(w.as_slice().into());
                    a.clear();
                    a.resize(e + 1, 0.0);
                    for &(c, v) in row {
                        if c < nf {
                            for (t, at) in a.iter_mut().enumerate() {
                                *at += v * self.online.w[t][c];
                            }
                        } else {
                            a[c - nf] += v;
                        }
                    }
                    if self.online.factor.border(e, &a).is_err() {
                        self.undo(rollback);
                        return Err(ReducedError::Singular { unknown: e });
                    }
                }
            }
        }
        self.enriched_eqs = total;
        self.enr = enr;
        self.online.scratch.resize(3 * self.dim(), 0.0);
        let bordering_s = clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        self.online.extend_table();
        Ok(CutUpdate {
            new_nodes,
            enriched_unknowns: total,
            assembly_s,
            bordering_s,
            tabulating_s: clock.elapsed().as_secs_f64(),
        })
    }

    /// Keeps the contact table of `nodes` (module docs, "The contact table"), the nodes a
    /// contact can load (a session's: its vademecum's loadable nodes): from now on every cut
    /// step extends it, and the compliance at a patch of these nodes costs `O(m)` instead of
    /// `O(m²)`. Nodes out of the mesh are ignored; a patch with a node not in the table is
    /// answered by the forward substitution as before.
    pub fn tabulate(&mut self, nodes: &[usize]) {
        let mut slot = vec![u32::MAX; self.n_nodes];
        let mut kept = Vec::with_capacity(nodes.len());
        for &a in nodes {
            if a < self.n_nodes && slot[a] == u32::MAX {
                slot[a] = kept.len() as u32;
                kept.push(a);
            }
        }
        self.online.table = Some(ContactTable {
            nodes: kept.into(),
            slot: slot.into(),
            blocks: Vec::new(),
            covered: 0,
        });
        self.online.extend_table();
    }

    /// Bytes of the contact table ([`tabulate`](Self::tabulate); 0 without one).
    pub fn table_bytes(&self) -> usize {
        self.online.table_bytes()
    }

    /// Drops the rows and fields a failed [`cut`](Self::cut) appended.
    fn undo(&mut self, (l, rows, w): (usize, usize, usize)) {
        self.online.factor.l.truncate(l);
        self.online.factor.row_start.truncate(rows);
        self.online.w.truncate(w);
    }

    /// Solves the reduced system for the right-hand side `b` in place (`b.len() = dim`; the
    /// coefficients `[β; q]`).
    pub fn solve_in_place(&self, b: &mut [f64]) {
        match self.online.disc {
            Discontinuous::Bare => self.online.factor.solve_in_place(b),
            Discontinuous::LocalFields => self.online.factor.solve_in_place(&mut b[self.online.nb..]),
        }
    }

    /// The coefficients `[β; q]` (length [`dim`](Self::dim)) for nodal forces `forces`
    /// (full length `3n`).
    pub fn coefficients(&self, forces: &[f64], out: &mut [f64]) {
        let nb = self.online.nb;
        out.fill(0.0);
        for (d, f) in forces.iter().enumerate() {
            if *f != 0.0
                && let Some(e) = DofMap::eq(&self.online.dofs, d)
            {
                for (t, xv) in self.online.x[e * nb..(e + 1) * nb].iter().enumerate() {
                    out[t] += f * xv;
                }
                if self.online.disc == Discontinuous::LocalFields {
                    for (t, o) in out[nb..].iter_mut().enumerate() {
                        *o += f * self.online.w[t][e];
                    }
                }
            }
        }
        self.solve_in_place(out);
    }

    /// The standard displacements (full length `3n`, own sides) and enriched amplitudes
    /// (3 per enriched node) of coefficients `coeffs`.
    pub fn fields(&self, coeffs: &[f64], u: &mut [f64], q: &mut [f64]) {
        let nb = self.online.nb;
        u.fill(0.0);
        for d in 0..u.len() {
            if let Some(e) = DofMap::eq(&self.online.dofs, d) {
                u[d] = self.online.x[e * nb..(e + 1) * nb]
                    .iter()
                    .zip(&coeffs[..nb])
                    .map(|(a, b)| a * b)
                    .sum();
                if self.online.disc == Discontinuous::LocalFields {
                    u[d] += coeffs[nb..].iter().enumerate().map(|(t, qv)| qv * self.online.w[t][e]).sum::<f64>();
                }
            }
        }
        for (qk, slots) in q.chunks_exact_mut(3).zip(self.opening_unknowns()) {
            for (qi, slot) in qk.iter_mut().zip(slots) {
                *qi = slot.map_or(0.0, |e| coeffs[nb + e]);
            }
        }
    }

    /// For each enriched node (in [`Enrichment::nodes`] order), the index among the enriched
    /// unknowns of each component of its opening `q` (`None` where the degree of freedom is
    /// held): the order [`fields`](Self::fields) reads them in.
    pub fn opening_unknowns(&self) -> Vec<[Option<usize>; 3]> {
        let mut e = 0;
        self.enr
            .nodes
            .iter()
            .map(|&a| {
                std::array::from_fn(|i| {
                    DofMap::eq(&self.online.dofs, 3 * a + i).map(|_| {
                        e += 1;
                        e - 1
                    })
                })
            })
            .collect()
    }

    /// The 3×3 compliance of the cut organ at a load patch ([`CutView::contact_compliance`]).
    pub fn contact_compliance(&mut self, nodes: &[usize], weights: &[f64]) -> [[f64; 3]; 3] {
        self.online.contact_compliance(nodes, weights)
    }

    /// What a tick reads of the model as it is now (see [`CutView`]).
    pub fn view(&self) -> CutView {
        self.online.clone()
    }

    /// The standard displacements (full length `3n`) and enriched amplitudes for nodal forces
    /// `forces` (full length): [`coefficients`](Self::coefficients) then
    /// [`fields`](Self::fields), allocating — for offline comparisons, not for a tick.
    pub fn displacements(&self, forces: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let mut c = vec![0.0; self.dim()];
        self.coefficients(forces, &mut c);
        let mut u = vec![0.0; 3 * self.n_nodes];
        let mut q = vec![0.0; 3 * self.enr.len()];
        self.fields(&c, &mut u, &mut q);
        (u, q)
    }
}

impl CutView {
    /// What carries the discontinuous part.
    pub fn discontinuous(&self) -> Discontinuous {
        self.disc
    }

    /// Appends to the contact table the block of the enriched unknowns it does not cover yet:
    /// for each column `y` (a tabulated degree of freedom `(a, i)`, equation `q`) and each new
    /// unknown e, `y_e = (r_e − L[d, ..d] y[..d]) / L[d, d]` (`d` the factor's row of e; `r_e`
    /// = `W[q, e]` with local fields, 0 bare, where the identity block's part of `y` is
    /// `X̂[q, :]`).
    fn extend_table(&mut self) {
        let m = self.enriched_unknowns();
        let Some(t) = &self.table else { return };
        let (m0, n) = (t.covered, t.entries());
        if m0 >= m || n == 0 {
            return;
        }
        let (id, nb, len) = (self.factor.identity, self.nb, m - m0);
        let mut block = vec![0.0; n * len];
        for (p, &a) in t.nodes.iter().enumerate() {
            for i in 0..3 {
                let Some(q) = DofMap::eq(&self.dofs, 3 * a + i) else { continue }; // a held degree of freedom: zero
                let k = 3 * p + i;
                for j in 0..len {
                    let e = m0 + j;
                    let row = self.factor.row(id + e);
                    let mut s = match self.disc {
                        Discontinuous::Bare => dot(&row[..nb], &self.x[q * nb..(q + 1) * nb]),
                        Discontinuous::LocalFields => 0.0,
                    };
                    let mut off = id;
                    for b in &t.blocks {
                        let bl = t.len_of(b);
                        s += dot(&row[off..off + bl], &b[k * bl..(k + 1) * bl]);
                        off += bl;
                    }
                    s += dot(&row[off..off + j], &block[k * len..k * len + j]);
                    let r = match self.disc {
                        Discontinuous::Bare => 0.0,
                        Discontinuous::LocalFields => self.w[e][q],
                    };
                    block[k * len + j] = (r - s) / row[id + e];
                }
            }
        }
        let t = self.table.as_mut().expect("checked above");
        t.blocks.push(block.into());
        t.covered = m;
    }

    /// `ΔC = ZᵀZ` at a patch from the contact table (module docs), or `None` when the table
    /// does not cover the patch's nodes of nonzero weight (a contact's weight is zero at a node
    /// the vademecum cannot load) or the cut's unknowns.
    fn tabulated_part(&self, nodes: &[usize], weights: &[f64]) -> Option<[[f64; 3]; 3]> {
        let t = self.table.as_ref().filter(|t| t.covered == self.enriched_unknowns())?;
        let tabulated = |a: usize| t.slot.get(a).is_some_and(|&s| s != u32::MAX);
        if nodes.iter().zip(weights).any(|(&a, &w)| w != 0.0 && !tabulated(a)) {
            return None;
        }
        let mut c = [[0.0; 3]; 3];
        for b in &t.blocks {
            let bl = t.len_of(b);
            for k in 0..bl {
                let mut z = [0.0; 3];
                for (&a, &w) in nodes.iter().zip(weights).filter(|(_, w)| **w != 0.0) {
                    let e = 3 * t.slot[a] as usize;
                    for (i, zi) in z.iter_mut().enumerate() {
                        *zi += w * b[(e + i) * bl + k];
                    }
                }
                for i in 0..3 {
                    for j in 0..3 {
                        c[i][j] += z[i] * z[j];
                    }
                }
            }
        }
        Some(c)
    }

    /// Bytes of the contact table's blocks (shared by the views) and maps.
    fn table_bytes(&self) -> usize {
        use crate::memory::slice_bytes;
        self.table.as_ref().map_or(0, |t| {
            slice_bytes(&t.nodes) + slice_bytes(&t.slot) + t.blocks.iter().map(|b| slice_bytes(b)).sum::<usize>()
        })
    }

    /// Bytes of the arrays its copies share (the local fields' columns, the basis, the
    /// degree-of-freedom map): counted once however many copies are in flight.
    pub fn shared_bytes(&self) -> usize {
        use crate::memory::{slice_bytes, vec_bytes};
        vec_bytes(&self.w)
            + self.w.iter().map(|c| slice_bytes(c)).sum::<usize>()
            + slice_bytes(&self.x)
            + self.dofs.heap_bytes()
            + self.table_bytes()
    }

    /// Bytes of what each copy holds of its own (the bordered factor, the workspace).
    pub fn own_bytes(&self) -> usize {
        use crate::memory::vec_bytes;
        vec_bytes(&self.factor.l) + vec_bytes(&self.factor.row_start) + vec_bytes(&self.scratch)
    }

    /// Dimension of the bordered system.
    pub fn dim(&self) -> usize {
        self.nb + self.enriched_unknowns()
    }

    /// Enriched unknowns of the cut so far (0 before any cut).
    pub fn enriched_unknowns(&self) -> usize {
        self.factor.dim() - self.factor.identity
    }

    /// The 3×3 compliance of the cut organ at a load patch (`nodes` with `weights` summing to
    /// one; the patch-averaged displacement per unit force spread over the patch):
    /// `C = Φ A⁻¹ Φᵀ` (module docs). With local fields `C = Φ_X Φ_Xᵀ + ZᵀZ`, `Z = L_S⁻¹ W_pᵀ`;
    /// bare, `C = ZᵀZ`, `Z = L⁻¹ [Φ_Xᵀ; 0]`. The displacement an own-side node sees; no
    /// allocation.
    pub fn contact_compliance(&mut self, nodes: &[usize], weights: &[f64]) -> [[f64; 3]; 3] {
        if let Some(mut c) = self.tabulated_part(nodes, weights) {
            add(&mut c, &self.ritz_part(nodes, weights), 1.0);
            return c;
        }
        let mut c = self.factored_part(nodes, weights);
        if self.disc == Discontinuous::LocalFields {
            add(&mut c, &self.ritz_part(nodes, weights), 1.0);
        }
        c
    }

    /// What the cut adds to the compliance of the uncut Ritz model at a load patch:
    /// `C_cut − Φ_X Φ_Xᵀ` — with local fields `ZᵀZ`, the response to the openings alone.
    /// Symmetric positive semi-definite (the cut model's space contains the uncut one's); zero
    /// before any cut. No allocation.
    pub fn added_compliance(&mut self, nodes: &[usize], weights: &[f64]) -> [[f64; 3]; 3] {
        if let Some(c) = self.tabulated_part(nodes, weights) {
            return c;
        }
        let mut c = self.factored_part(nodes, weights);
        if self.disc == Discontinuous::Bare {
            add(&mut c, &self.ritz_part(nodes, weights), -1.0);
        }
        c
    }

    /// What the cut adds to the uncut Ritz model's response to a force `f` (N) spread over a
    /// load patch (`nodes` with `weights` summing to one), as coefficients `[β − β₀; q]`
    /// (`out.len() = dim`), `β₀ = X_pᵀ f` the uncut answer: bare, the bordered solve minus
    /// `β₀`; with local fields `β = β₀` and only the openings `q = S⁻¹ W_pᵀ f` remain.
    /// The displacement it adds is [`added_displacement`](Self::added_displacement) on each
    /// node's own side, plus `s q` on the other side of an enriched node. The frame thread's
    /// picture of the opening; no allocation.
    pub fn added_response(&self, nodes: &[usize], weights: &[f64], f: [f64; 3], out: &mut [f64]) {
        let nb = self.nb;
        out.fill(0.0);
        let rhs = |out: &mut [f64], sign: f64, ritz: bool, local: bool| {
            for (&a, &w) in nodes.iter().zip(weights) {
                for (i, fi) in f.iter().enumerate() {
                    let Some(e) = DofMap::eq(&self.dofs, 3 * a + i) else { continue };
                    let fi = sign * w * fi;
                    if ritz {
                        for (o, xv) in out[..nb].iter_mut().zip(&self.x[e * nb..(e + 1) * nb]) {
                            *o += fi * xv;
                        }
                    }
                    if local {
                        for (o, col) in out[nb..].iter_mut().zip(&self.w) {
                            *o += fi * col[e];
                        }
                    }
                }
            }
        };
        match self.disc {
            Discontinuous::Bare => {
                rhs(out, 1.0, true, false);
                self.factor.solve_in_place(out);
                rhs(out, -1.0, true, false);
            }
            Discontinuous::LocalFields => {
                rhs(out, 1.0, false, true);
                self.factor.solve_in_place(&mut out[nb..]);
            }
        }
    }

    /// The displacement (m) the cut adds at node `a` on its own side, for coefficients from
    /// [`added_response`](Self::added_response): `X_a (β − β₀) + W_a q` (the second term with
    /// local fields only; zero at a held degree of freedom).
    pub fn added_displacement(&self, coeffs: &[f64], a: usize) -> [f64; 3] {
        let nb = self.nb;
        std::array::from_fn(|i| {
            let Some(e) = DofMap::eq(&self.dofs, 3 * a + i) else { return 0.0 };
            let mut u: f64 = self.x[e * nb..(e + 1) * nb].iter().zip(&coeffs[..nb]).map(|(p, q)| p * q).sum();
            if self.disc == Discontinuous::LocalFields {
                u += self.w.iter().zip(&coeffs[nb..]).map(|(col, q)| col[e] * q).sum::<f64>();
            }
            u
        })
    }

    /// `Φ_X Φ_Xᵀ` at the patch, from the rows of X̂ (K-orthonormal: the uncut Ritz compliance).
    fn ritz_part(&self, nodes: &[usize], weights: &[f64]) -> [[f64; 3]; 3] {
        let nb = self.nb;
        let mut c = [[0.0; 3]; 3];
        for (&a, &wa) in nodes.iter().zip(weights) {
            for (&b, &wb) in nodes.iter().zip(weights) {
                for (i, ci) in c.iter_mut().enumerate() {
                    let Some(ea) = DofMap::eq(&self.dofs, 3 * a + i) else { continue };
                    for (j, cij) in ci.iter_mut().enumerate() {
                        let Some(eb) = DofMap::eq(&self.dofs, 3 * b + j) else { continue };
                        let (ra, rb) = (&self.x[ea * nb..(ea + 1) * nb], &self.x[eb * nb..(eb + 1) * nb]);
                        *cij += wa * wb * ra.iter().zip(rb).map(|(p, q)| p * q).sum::<f64>();
                    }
                }
            }
        }
        c
    }

    /// `ZᵀZ` at the patch: `Z = L⁻¹ [Φ_Xᵀ; 0]` (bare) or `Z = L_S⁻¹ W_pᵀ` (local fields).
    fn factored_part(&mut self, nodes: &[usize], weights: &[f64]) -> [[f64; 3]; 3] {
        let (nb, m) = (self.nb, self.enriched_unknowns());
        let mut c = [[0.0; 3]; 3];
        let len = match self.disc {
            Discontinuous::Bare => nb + m,
            Discontinuous::LocalFields => m,
        };
        if len == 0 {
            return c;
        }
        let z = &mut self.scratch[..3 * len];
        z.fill(0.0);
        // the right-hand sides, averaged over the patch
        for (&a, &w) in nodes.iter().zip(weights) {
            for i in 0..3 {
                let Some(e) = DofMap::eq(&self.dofs, 3 * a + i) else { continue };
                match self.disc {
                    Discontinuous::Bare => {
                        for (t, v) in self.x[e * nb..(e + 1) * nb].iter().enumerate() {
                            z[i * len + t] += w * v;
                        }
                    }
                    Discontinuous::LocalFields => {
                        for (t, col) in self.w.iter().enumerate() {
                            z[i * len + t] += w * col[e];
                        }
                    }
                }
            }
        }
        self.factor.forward3_in_place(z, len);
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] = z[i * len..(i + 1) * len]
                    .iter()
                    .zip(&z[j * len..(j + 1) * len])
                    .map(|(p, q)| p * q)
                    .sum::<f64>();
            }
        }
        c
    }
}

/// The K-orthonormal basis of the span of `columns` (each `n_free` long), row-major
/// `n_free × nb`, and `nb`: `G = XᵀKX = Q Λ Qᵀ`, `X̂ = X Q Λ^{-1/2}`, dropping the directions
/// below 10⁻¹² of the largest.
fn k_orthonormal(k: &assembly::SymmetricMatrix, columns: &[Vec<f64>]) -> Result<(Vec<f64>, usize), ReducedError> {
    let nc = columns.len();
    if nc == 0 {
        return Err(ReducedError::EmptyBasis);
    }
    let nf = columns[0].len();
    let mut kx = vec![0.0; nf];
    let mut gram = DMatrix::<f64>::zeros(nc, nc);
    for j in 0..nc {
        k.mul_vec(&columns[j], &mut kx);
        for i in 0..nc {
            gram[(i, j)] = columns[i].iter().zip(&kx).map(|(a, b)| a * b).sum();
        }
    }
    let gram = (&gram + gram.transpose()) * 0.5;
    let eig = gram.symmetric_eigen();
    let top = eig.eigenvalues.iter().fold(0.0f64, |m, v| m.max(*v));
    let keep: Vec<usize> = (0..nc).filter(|&i| eig.eigenvalues[i] > 1e-12 * top && top > 0.0).collect();
    let nb = keep.len();
    if nb == 0 {
        return Err(ReducedError::EmptyBasis);
    }
    let mut x = vec![0.0; nf * nb];
    for (b, &i) in keep.iter().enumerate() {
        let s = eig.eigenvalues[i].sqrt().recip();
        for (j, col) in columns.iter().enumerate() {
            let w = eig.eigenvectors[(j, i)] * s;
            if w != 0.0 {
                for r in 0..nf {
                    x[r * nb + b] += w * col[r];
                }
            }
        }
    }
    Ok((x, nb))
}

/// The uncut stiffness on the free degrees of freedom `dofs` (with the problem's springs).
fn stiffness(
    mesh: &Mesh,
    materials: &MaterialMap,
    locking: Locking,
    problem: &StaticProblem,
    dofs: &DofMap,
) -> Result<assembly::SymmetricMatrix, ReducedError> {
    let pattern = std::sync::Arc::new(SymmetricPattern::for_locking(mesh, dofs, locking));
    let mut rhs = vec![0.0; dofs.n_free()];
    let mut k =
        assembly::assemble_stiffness(mesh, materials, locking, dofs, pattern, &problem.prescribed, &mut rhs).map_err(XfemError::from)?;
    assembly::add_springs(&mut k, dofs, &problem.springs);
    Ok(k)
}

/// The raw Ritz columns on the free degrees of freedom: the modes (PRB) or their component
/// fields (SRB), from `n_modes` mode-major modes over `n_dofs`.
fn ritz_columns(n_dofs: usize, dofs: &DofMap, modes: &[f64], n_modes: usize, basis: RitzBasis) -> Result<Vec<Vec<f64>>, ReducedError> {
    if modes.len() != n_modes * n_dofs {
        return Err(ReducedError::Modes {
            got: modes.len(),
            modes: n_modes,
            dofs: n_dofs,
        });
    }
    let nf = dofs.n_free();
    Ok(match basis {
        RitzBasis::Prb => (0..n_modes)
            .map(|k| {
                let mut c = vec![0.0; nf];
                dofs.restrict(&modes[k * n_dofs..(k + 1) * n_dofs], &mut c);
                c
            })
            .collect(),
        RitzBasis::Srb => (0..n_modes)
            .flat_map(|k| (0..3).map(move |comp| (k, comp)))
            .map(|(k, comp)| {
                let mut full = modes[k * n_dofs..(k + 1) * n_dofs].to_vec();
                for (d, v) in full.iter_mut().enumerate() {
                    if d % 3 != comp {
                        *v = 0.0;
                    }
                }
                let mut c = vec![0.0; nf];
                dofs.restrict(&full, &mut c);
                c
            })
            .collect(),
    })
}

/// `c += s · d`, entrywise.
fn add(c: &mut [[f64; 3]; 3], d: &[[f64; 3]; 3], s: f64) {
    for (ci, di) in c.iter_mut().zip(d) {
        for (x, y) in ci.iter_mut().zip(di) {
            *x += s * y;
        }
    }
}

/// A Cholesky factor grown by bordering: an identity block of size `identity`, then packed
/// rows, row d holding `L[d, 0..=d]`.
#[derive(Debug, Clone)]
struct Bordered {
    identity: usize,
    l: Vec<f64>,
    row_start: Vec<usize>,
}

impl Bordered {
    fn new(identity: usize) -> Self {
        Self {
            identity,
            l: Vec::new(),
            row_start: Vec::new(),
        }
    }

    fn dim(&self) -> usize {
        self.identity + self.row_start.len()
    }

    /// `L[d, 0..=d]` of a bordered row `d ≥ identity`.
    #[inline]
    fn row(&self, d: usize) -> &[f64] {
        let s = self.row_start[d - self.identity];
        &self.l[s..s + d + 1]
    }

    /// Appends row `d` of the factor from row `d` of the matrix, `a[0..=d]`:
    /// `L[d, c] = (A[d, c] − Σ_{t<c} L[d, t] L[c, t]) / L[c, c]`, `L[d, d] = √(A[d, d] − Σ L[d, t]²)`.
    fn border(&mut self, d: usize, a: &[f64]) -> Result<(), ()> {
        debug_assert_eq!(d, self.dim());
        let nb = self.identity;
        let start = self.l.len();
        self.l.extend_from_slice(&a[..nb]); // against the identity block: L[d, t] = A[d, t]
        for c in nb..d {
            let lc = self.row(c);
            let s: f64 = a[c] - self.l[start..start + c].iter().zip(&lc[..c]).map(|(p, q)| p * q).sum::<f64>();
            let v = s / lc[c];
            self.l.push(v);
        }
        let diag = a[d] - self.l[start..start + d].iter().map(|v| v * v).sum::<f64>();
        if diag.is_nan() || diag <= 1e-14 * a[d].abs() || !diag.is_finite() {
            self.l.truncate(start);
            return Err(());
        }
        self.l.push(diag.sqrt());
        self.row_start.push(start);
        Ok(())
    }

    /// Solves `L y = b` in place.
    fn forward_in_place(&self, b: &mut [f64]) {
        for d in self.identity..self.dim() {
            let r = self.row(d);
            let s: f64 = r[..d].iter().zip(&b[..d]).map(|(p, q)| p * q).sum();
            b[d] = (b[d] - s) / r[d];
        }
    }

    /// Solves `L y = b` for three right-hand sides stored one after the other (`len` each) in
    /// one pass over the factor (the factor is read once, not three times).
    fn forward3_in_place(&self, z: &mut [f64], len: usize) {
        let (z0, rest) = z.split_at_mut(len);
        let (z1, z2) = rest.split_at_mut(len);
        for d in self.identity..self.dim() {
            let r = self.row(d);
            let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
            for (t, v) in r[..d].iter().enumerate() {
                s0 += v * z0[t];
                s1 += v * z1[t];
                s2 += v * z2[t];
            }
            z0[d] = (z0[d] - s0) / r[d];
            z1[d] = (z1[d] - s1) / r[d];
            z2[d] = (z2[d] - s2) / r[d];
        }
    }

    /// Solves `L Lᵀ z = b` in place.
    fn solve_in_place(&self, b: &mut [f64]) {
        let (nb, dim) = (self.identity, self.dim());
        self.forward_in_place(b);
        for d in (nb..dim).rev() {
            let r = self.row(d);
            b[d] /= r[d];
            let z = b[d];
            for (t, v) in r[..d].iter().enumerate() {
                b[t] -= v * z;
            }
        }
    }
}
