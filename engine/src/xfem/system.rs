//! The full-order XFEM system: assembly over standard and enriched degrees of freedom, the
//! detection of pieces the cuts have set loose, and the static solve.
//!
//! # Unknowns
//! `u(x) = Σ_a N_a(x) u_a + Σ_{I∈S} N_I(x) [H(φ_I(x)) − H(φ_I(x_I))] q_I` (seed 000 Eq. 3.3 with
//! the shifted Heaviside of seed 003 Eqs. 4–6): the standard nodal values `u_a` are the
//! displacements at the nodes, and `q_I` is the jump of node I's other side. Degrees of
//! freedom are numbered as *generalized nodes*: `0..n` the mesh nodes, `n + k` the k-th
//! enriched node — so the sparsity pattern, the Dirichlet elimination and the sparse Cholesky
//! of the standard solver apply unchanged.
//!
//! # Cell matrices
//! The extended stiffness is `[K, K_ue; K_eu, K_ee]` where `K` is the uncut stiffness, assembled
//! as usual with the scene's locking option — so that the reduced online model can take `XᵀKX`
//! from the vademecum unchanged. The blocks that involve enriched functions come from the cells
//! with enriched nodes, integrated on their sub-tetrahedra ([`super::subcell`]): on each, every
//! enriched function is the node's shape function times a constant `s ∈ {−1, 0, 1}`, so the
//! cell matrix over its `n + k` generalized nodes is the usual bilinear form of the generalized
//! gradients `[∇N_1 … ∇N_n, s_1 ∇N_{I_1} … s_k ∇N_{I_k}]`. On hexahedra with B̄ the mean
//! dilatation of every generalized function is taken over the whole cell, as for the standard
//! ones (one mean pressure per cell, cut or not: with a per-side mean the standard block of cut
//! cells would change by `κ (V₁V₂/V)(ḡ₁ − ḡ₂)(ḡ₁ − ḡ₂)ᵀ`). On tetrahedra the enriched blocks use
//! the plain tet4 volumetric term, or — with the averaged nodal pressure — the nodal dilatations
//! extended to the enriched functions: node a's volume change `G_a · u` takes every generalized
//! function of the cells around it, so one nodal pressure acts on both lips of a cut through a
//! node's patch (the lips may trade volume without penalty; with duplicated nodes each lip
//! would have its own, which is why the identity check below holds without this option only).
//!
//! # Boundary conditions
//! A node held on a Dirichlet boundary holds both lips of a cut through it: its enriched
//! degrees of freedom are held at zero jump. Springs act on the standard degrees of freedom.
//!
//! # Detached pieces
//! Each side of each node is a *copy*: `(a, own side)` is generalized node `a`, `(I, other
//! side)` is generalized node `n + k`. Copies that share a sub-cell of positive volume belong
//! to the same piece of material (union–find over all cells). A piece whose supports do not
//! remove its six rigid motions would make the stiffness singular: it is held by a soft
//! foundation of stiffness `E·h` on every copy (and, with [`Detached::Remove`], its loads are
//! dropped), and reported.

use std::sync::Arc;
use std::time::Instant;

use super::enrichment::{Detached, Enrichment, XfemParams};
use super::subcell;
use crate::fem::assembly::{self, AssemblyError, DofMap, MaterialMap, SymmetricMatrix, SymmetricPattern};
use crate::fem::element::{self, ElementError, Locking};
use crate::fem::linear_static::{StaticError, StaticProblem};
use crate::fem::nodal::{self, NodalPatches};
use crate::material::LinearElastic;
use crate::mesh::shape;
use crate::mesh::{CellKind, Mesh};
use crate::solve::{self, Cholesky, SolveError};

/// Why an XFEM solve failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum XfemError {
    /// The uncut problem is not well posed (no supports, a free rigid motion).
    #[error(transparent)]
    Problem(#[from] StaticError),
    /// A cell could not be integrated.
    #[error(transparent)]
    Assembly(#[from] AssemblyError),
    /// The factorization failed.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The solution is not finite.
    #[error("the XFEM solution contains non-finite values")]
    NonFinite,
    /// A combination this solver does not handle.
    #[error("{0} is not supported")]
    Unsupported(&'static str),
}

/// A piece of material that no support holds after the cut.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    /// Its copies (generalized nodes: `a < n` a mesh node's own side, `n + k` the other side of
    /// the k-th enriched node).
    pub copies: Vec<usize>,
    /// The rigid motions its supports left free.
    pub free: Vec<String>,
    /// What was done with it.
    pub action: Detached,
}

/// The result of an XFEM static solve.
#[derive(Debug, Clone, PartialEq)]
pub struct XfemSolution {
    /// Standard displacements (3 per mesh node): the displacement at each node.
    pub u: Vec<f64>,
    /// Enriched amplitudes (3 per enriched node): the jump to the node's other side.
    pub q: Vec<f64>,
    /// Pieces no support held.
    pub detached: Vec<Piece>,
    /// Free equations.
    pub n_free: usize,
    /// Stored entries of the factorized matrix (lower triangle).
    pub nnz: usize,
    /// `‖K x − f‖ / ‖f‖` over the free equations.
    pub residual: f64,
    /// Wall time of assembly, factorization and solve (s).
    pub seconds: f64,
}

impl XfemSolution {
    /// The displacement of `node`'s side `positive` of its plane (its own displacement when it
    /// is not enriched or `positive` is its own side).
    pub fn side_displacement(&self, enr: &Enrichment, node: usize, positive: bool) -> [f64; 3] {
        let mut d = [self.u[3 * node], self.u[3 * node + 1], self.u[3 * node + 2]];
        if let Some(k) = enr.index(node) {
            let s = enr.shifted(k, positive);
            for i in 0..3 {
                d[i] += s * self.q[3 * k + i];
            }
        }
        d
    }
}

/// How the enriched blocks of a cut cell take the volumetric term, following the scene's
/// locking option (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EnrichedVolumetric {
    /// At every quadrature point (plain integration).
    Plain,
    /// On the cell's mean dilatation (B̄ on hexahedra).
    CellMean,
    /// On the nodal dilatations of the averaged-nodal-pressure tetrahedron, extended to the
    /// enriched functions (assembled over nodal patches, not in the cell matrix).
    Nodal,
}

impl EnrichedVolumetric {
    /// The treatment that matches `locking` on cells of `kind`.
    pub fn of(kind: CellKind, locking: Locking) -> Self {
        match (kind, locking) {
            (CellKind::Hex8, Locking::None) | (CellKind::Tet4, Locking::None | Locking::Sri | Locking::Bbar) => Self::Plain,
            (CellKind::Hex8, _) => Self::CellMean,
            (CellKind::Tet4, Locking::Nodal) => Self::Nodal,
        }
    }
}

/// The generalized cell of cell `c`: its nodes, then `n_nodes + k` for each enriched node `k`
/// among them; and the local index of each enriched node.
pub fn generalized_cell(mesh: &Mesh, enr: &Enrichment, c: usize, cell_nodes: &mut Vec<usize>, local: &mut Vec<(usize, usize)>) {
    cell_nodes.clear();
    local.clear();
    let cell = mesh.cell(c);
    cell_nodes.extend_from_slice(cell);
    for (a, &node) in cell.iter().enumerate() {
        if let Some(k) = enr.index(node) {
            local.push((a, k));
            cell_nodes.push(mesh.n_nodes() + k);
        }
    }
}

/// One side of the cut inside a cell: its volume and which copies it holds.
#[derive(Debug, Clone, PartialEq)]
pub struct CellSide {
    /// Physical volume.
    pub volume: f64,
    /// The shifted Heaviside of each enriched node of the cell on this side.
    pub shifts: Vec<f64>,
}

/// One side of a cell, with the moments of the standard shape functions over it: on a side
/// every generalized gradient is a standard one times a constant, so every matrix over the
/// side follows from these.
#[derive(Debug, Clone, PartialEq)]
pub struct SideMoments {
    /// The side: volume and the shifted Heaviside of each enriched node of the cell.
    pub side: CellSide,
    /// `M_ab = ∫_side ∇N_a ⊗ ∇N_b`, row-major `n × n`, set for `a ≤ b` only (`M_ba = M_abᵀ`).
    pub m: Vec<[[f64; 3]; 3]>,
    /// `∫_side ∇N_a`.
    pub g: [[f64; 3]; 8],
}

impl SideMoments {
    /// `M_ab` for any `a, b`.
    pub fn moment(&self, n: usize, a: usize, b: usize) -> [[f64; 3]; 3] {
        if a <= b {
            self.m[a * n + b]
        } else {
            let t = self.m[b * n + a];
            std::array::from_fn(|i| std::array::from_fn(|j| t[j][i]))
        }
    }
}

/// The 3 × 3 block of the isotropic stiffness `∫ Bᵀ C B` coupling two functions whose
/// gradient moment is `mab = ∫ ∇N_a ⊗ ∇N_b`: `μ(M_ji − ⅔M_ij + tr M δ_ij)` plus, with `plain`,
/// the volumetric `κ M_ij` (left out when the dilatation is taken elsewhere, as B̄ does).
pub fn moment_block(mab: &[[f64; 3]; 3], mu: f64, kappa: f64, plain: bool) -> [[f64; 3]; 3] {
    let trace = mab[0][0] + mab[1][1] + mab[2][2];
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let mut v = mu * (mab[j][i] - 2.0 / 3.0 * mab[i][j]);
            if i == j {
                v += mu * trace;
            }
            if plain {
                v += kappa * mab[i][j];
            }
            v
        })
    })
}

/// The sides of cell `x` (of `kind`) cut by the planes of its enriched nodes `local` (the
/// local index and enriched index of each), with the moments of the standard functions over
/// each ([`SideMoments`]); one side when no plane crosses it (the cell's own Gauss rule).
pub fn side_moments(kind: CellKind, x: &[[f64; 3]], enr: &Enrichment, local: &[(usize, usize)]) -> Result<Vec<SideMoments>, ElementError> {
    let n = kind.nodes_per_cell();
    let mut planes: Vec<subcell::Plane> = Vec::new();
    let plane_of: Vec<usize> = local
        .iter()
        .map(|&(_, k)| {
            let p = enr.planes[k];
            planes.iter().position(|q| *q == p).unwrap_or_else(|| {
                planes.push(p);
                planes.len() - 1
            })
        })
        .collect();
    let mut sides: Vec<SideMoments> = Vec::new();
    let mut dn = [[0.0; 3]; 8];
    let mut grad = [[0.0; 3]; 8];
    let mut bad = None;
    let pieces = subcell::split(kind, x, &planes);
    // a cell no plane crosses is one side: its own Gauss rule, not the sub-cells'
    let whole = pieces.iter().all(|t| t.sides == pieces[0].sides);
    for t in pieces.iter().take(if whole { 1 } else { pieces.len() }) {
        let shifts: Vec<f64> = local
            .iter()
            .zip(&plane_of)
            .map(|(&(_, k), &p)| enr.shifted(k, (t.sides >> p) & 1 == 1))
            .collect();
        let side = match sides.iter().position(|s| s.side.shifts == shifts) {
            Some(i) => i,
            None => {
                sides.push(SideMoments {
                    side: CellSide { volume: 0.0, shifts },
                    m: vec![[[0.0; 3]; 3]; n * n],
                    g: [[0.0; 3]; 8],
                });
                sides.len() - 1
            }
        };
        let sm = &mut sides[side];
        let at_point = |xi: [f64; 3], w: f64| {
            subcell::reference_gradients(kind, xi, &mut dn);
            let det = shape::physical_gradients(x, &dn[..n], &mut grad[..n]);
            if det <= 0.0 {
                bad = Some(det);
                return;
            }
            let wd = w * det;
            sm.side.volume += wd;
            for a in 0..n {
                let ga = grad[a].map(|v| wd * v);
                for i in 0..3 {
                    sm.g[a][i] += ga[i];
                }
                for b in a..n {
                    let mab = &mut sm.m[a * n + b];
                    for i in 0..3 {
                        for j in 0..3 {
                            mab[i][j] += ga[i] * grad[b][j];
                        }
                    }
                }
            }
        };
        if whole {
            subcell::whole_cell_quadrature(kind, at_point);
        } else {
            subcell::quadrature(kind, t, at_point);
        }
        if let Some(det) = bad {
            return Err(ElementError::NonPositiveJacobian { det });
        }
    }
    Ok(sides)
}

/// The stiffness of a cell with enriched nodes over its generalized nodes (module docs), row-
/// major `(3(n+k))²` into `ke`, with its standard–standard block left at zero (it belongs to the
/// uncut stiffness); returns the cell's sides, and writes into `divergence` the integral over
/// the cell of every generalized gradient, `∫_e g_j` (the cell's volume change per unit value
/// of each generalized degree of freedom).
pub fn enriched_cell_stiffness(
    kind: CellKind,
    x: &[[f64; 3]],
    enr: &Enrichment,
    local: &[(usize, usize)],
    mat: &LinearElastic,
    volumetric: EnrichedVolumetric,
    ke: &mut Vec<f64>,
    divergence: &mut Vec<[f64; 3]>,
) -> Result<Vec<CellSide>, ElementError> {
    let n = kind.nodes_per_cell();
    let ng = n + local.len();
    ke.clear();
    ke.resize(9 * ng * ng, 0.0);
    divergence.clear();
    divergence.resize(ng, [0.0; 3]);
    let (kappa, mu) = (mat.bulk(), mat.shear());
    let plain = volumetric == EnrichedVolumetric::Plain;
    let sides = side_moments(kind, x, enr, local)?;
    // generalized function p: standard node p (p < n), or s_j ∇N_{a_j} (p = n + j)
    let node_of = |p: usize| if p < n { p } else { local[p - n].0 };
    let nd = 3 * ng;
    for sm in &sides {
        let s = |p: usize| if p < n { 1.0 } else { sm.side.shifts[p - n] };
        for p in 0..ng {
            for q in 0..ng {
                let spq = s(p) * s(q);
                if (p < n && q < n) || spq == 0.0 {
                    continue; // the standard–standard block is the uncut stiffness's
                }
                let block = moment_block(&sm.moment(n, node_of(p), node_of(q)), mu, kappa, plain);
                for i in 0..3 {
                    for j in 0..3 {
                        ke[(3 * p + i) * nd + 3 * q + j] += spq * block[i][j];
                    }
                }
            }
        }
        for p in 0..ng {
            for i in 0..3 {
                divergence[p][i] += s(p) * sm.g[node_of(p)][i];
            }
        }
    }
    let volume: f64 = sides.iter().map(|s| s.side.volume).sum();
    close_cell_matrix(ke, n, ng, divergence, volume, kappa, mu, volumetric);
    Ok(sides.into_iter().map(|s| s.side).collect())
}

/// Completes an enriched cell matrix over `ng` generalized functions (the first `n` the
/// standard ones) whose deviatoric (and, plain, volumetric) part is integrated: with
/// [`EnrichedVolumetric::CellMean`] the volumetric term of the cell's mean dilatation of every
/// function (`divergence[p] = ∫_e g_p`, over the cell's `volume`), then the standard–standard
/// block set to zero (it is the uncut stiffness's).
#[allow(clippy::too_many_arguments)]
pub(super) fn close_cell_matrix(
    ke: &mut [f64],
    n: usize,
    ng: usize,
    divergence: &[[f64; 3]],
    volume: f64,
    kappa: f64,
    mu: f64,
    volumetric: EnrichedVolumetric,
) {
    if volumetric == EnrichedVolumetric::CellMean {
        let gbar: Vec<[f64; 3]> = divergence.iter().map(|s| s.map(|v| v / volume)).collect();
        element::add_terms(ke, ng, &gbar, volume, kappa, mu, true, false);
    }
    let nd = 3 * ng;
    for r in 0..3 * n {
        ke[r * nd..r * nd + 3 * n].fill(0.0);
    }
}

/// The stiffness per node of the soft foundation that holds a loose piece, `E·h`: the
/// stiffest material's Young's modulus times the mean cell size (the order of one cell's own
/// stiffness, so a held piece stays near where it was cut and carries its own loads).
pub(super) fn foundation_stiffness(mesh: &Mesh, materials: &MaterialMap) -> f64 {
    let npc = mesh.kind.nodes_per_cell();
    let h_sum: f64 = (0..mesh.n_cells())
        .map(|c| {
            let mut x = [[0.0; 3]; 8];
            mesh.cell_coords(c, &mut x[..npc]);
            subcell::cell_size(&x[..npc])
        })
        .sum();
    let young = materials.table.iter().map(|m| m.young).fold(0.0, f64::max);
    young * h_sum / mesh.n_cells().max(1) as f64
}

/// The generalized nodes a copy's displacement is made of, with their coefficients: `u_a` for
/// a node's own side (`copy = a < n`), `u_a + s q_k` for the other side of enriched node `k`
/// (`copy = n + k`, `s` the shifted Heaviside there).
pub(super) fn copy_terms(enr: &Enrichment, n: usize, copy: usize) -> Vec<(usize, f64)> {
    if copy < n {
        return vec![(copy, 1.0)];
    }
    let kk = copy - n;
    vec![(enr.nodes[kk], 1.0), (copy, enr.shifted(kk, !enr.own_positive[kk]))]
}

/// Union–find over copies.
pub(super) struct Pieces {
    parent: Vec<usize>,
}

/// The pieces of material `pieces` joins (over the `n + m` copies of `mesh` cut by `enr`)
/// whose supports leave a rigid motion free — a node's own copy held where `supported` holds
/// it, an enriched copy where `constrained` does —, each with its copies and those motions;
/// none while the organ is one piece.
pub(super) fn loose_pieces(
    mesh: &Mesh,
    enr: &Enrichment,
    pieces: &mut Pieces,
    supported: &[bool],
    constrained: &[bool],
) -> Vec<(Vec<usize>, Vec<String>)> {
    let n = mesh.n_nodes();
    let mut members: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for a in 0..pieces.parent.len() {
        let r = pieces.find(a);
        members.entry(r).or_default().push(a);
    }
    if members.len() <= 1 {
        return Vec::new();
    }
    let copy_node = |a: usize| if a < n { a } else { enr.nodes[a - n] };
    let held = |a: usize, i: usize| if a < n { supported[3 * a + i] } else { constrained[3 * a + i] };
    members
        .into_values()
        .filter_map(|copies| {
            let pos: Vec<[f64; 3]> = copies.iter().map(|&a| mesh.nodes[copy_node(a)]).collect();
            let sup: Vec<bool> = copies
                .iter()
                .flat_map(|&a| (0..3).map(move |i| (a, i)))
                .map(|(a, i)| held(a, i))
                .collect();
            let free = solve::free_rigid_motions(&pos, &sup);
            (!free.is_empty()).then_some((copies, free))
        })
        .collect()
}

impl Pieces {
    pub(super) fn new(n: usize) -> Self {
        Self { parent: (0..n).collect() }
    }

    fn find(&mut self, mut a: usize) -> usize {
        while self.parent[a] != a {
            self.parent[a] = self.parent[self.parent[a]];
            a = self.parent[a];
        }
        a
    }

    pub(super) fn join(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra.max(rb)] = ra.min(rb);
        }
    }
}

/// The assembled extended system, ready to factor.
pub struct ExtendedSystem {
    /// The degree-of-freedom map over `3(n + m)` generalized degrees of freedom.
    pub dofs: DofMap,
    /// `K_ff` over the free generalized degrees of freedom.
    pub k: SymmetricMatrix,
    /// `f_f − K_fc ū_c`.
    pub rhs: Vec<f64>,
    /// Prescribed values of every generalized degree of freedom.
    pub prescribed: Vec<f64>,
    /// Pieces no support held.
    pub detached: Vec<Piece>,
}

/// The generalized degrees of freedom of `problem` cut by `enr`: the nodes', then the
/// enriched nodes' jumps.
pub(super) struct Generalized {
    /// The nodes' dofs held by a support (clamped or prescribed).
    pub supported: Vec<bool>,
    /// Every generalized dof's constraint: a jump is held where its node's dof is.
    pub constrained: Vec<bool>,
    /// Prescribed values: the problem's, and zero jumps.
    pub prescribed: Vec<f64>,
    /// Their numbering.
    pub dofs: DofMap,
}

/// [`Generalized`] of `problem` cut by `enr`, refused when the supports leave a rigid motion
/// free (the linear and the co-rotational XFEM alike).
pub(super) fn generalized_dofs(mesh: &Mesh, problem: &StaticProblem, enr: &Enrichment) -> Result<Generalized, XfemError> {
    let supported = problem.supported();
    if !supported.iter().any(|c| *c) {
        return Err(StaticError::NoConstraints.into());
    }
    let free = solve::free_rigid_motions(&mesh.nodes, &supported);
    if !free.is_empty() {
        return Err(StaticError::RigidMotion { free }.into());
    }
    let mut constrained = problem.constrained.clone();
    let mut prescribed = problem.prescribed.clone();
    for &a in &enr.nodes {
        for i in 0..3 {
            constrained.push(problem.constrained[3 * a + i]);
            prescribed.push(0.0);
        }
    }
    Ok(Generalized {
        supported,
        dofs: DofMap::new(&constrained),
        constrained,
        prescribed,
    })
}

/// Each generalized node's sorted neighbours in the extended system: the uncut mesh's (with
/// the averaged nodal pressure's wider reach when `patches`), the generalized cells' nodes, and
/// the nodal dilatation's reach into the enriched nodes of a patch's cut cells.
fn generalized_adjacency(mesh: &Mesh, enr: &Enrichment, patches: Option<&NodalPatches>) -> Vec<Vec<usize>> {
    let n = mesh.n_nodes();
    let ng = n + enr.len();
    let (mut cell_nodes, mut local) = (Vec::new(), Vec::new());
    let mut adj: Vec<Vec<usize>> = match patches {
        Some(patches) => patches.couplings(),
        None => vec![Vec::new(); n],
    };
    adj.resize(ng, Vec::new());
    for c in 0..mesh.n_cells() {
        generalized_cell(mesh, enr, c, &mut cell_nodes, &mut local);
        for &a in &cell_nodes {
            adj[a].extend_from_slice(&cell_nodes);
        }
    }
    if let Some(patches) = patches {
        // the nodal dilatation of node a reaches every generalized node of its patch's cells
        for a in 0..n {
            let mut reach: Vec<usize> = Vec::new();
            for &c in patches.cells(a) {
                generalized_cell(mesh, enr, c, &mut cell_nodes, &mut local);
                if !local.is_empty() {
                    reach.extend_from_slice(&cell_nodes);
                }
            }
            if reach.is_empty() {
                continue;
            }
            reach.extend_from_slice(patches.nodes(a));
            for &b in &reach {
                adj[b].extend_from_slice(&reach);
            }
        }
    }
    for l in adj.iter_mut() {
        l.sort_unstable();
        l.dedup();
    }
    adj
}

/// Assembles the XFEM system of `problem` with the cut `enr` (module docs).
pub fn assemble(
    mesh: &Mesh,
    materials: &MaterialMap,
    locking: Locking,
    problem: &StaticProblem,
    enr: &Enrichment,
    params: &XfemParams,
) -> Result<ExtendedSystem, XfemError> {
    let n = mesh.n_nodes();
    let m = enr.len();
    let ng = n + m;
    let Generalized {
        supported,
        constrained,
        prescribed,
        dofs,
    } = generalized_dofs(mesh, problem, enr)?;
    let volumetric = EnrichedVolumetric::of(mesh.kind, locking);
    let patches = NodalPatches::when(mesh, volumetric == EnrichedVolumetric::Nodal).ok().flatten();
    // the pattern: the uncut one (with the nodal pressure's wider reach) and the generalized cells
    let adj = generalized_adjacency(mesh, enr, patches.as_ref());
    let pattern = Arc::new(SymmetricPattern::from_adjacency(&adj, &dofs));
    let mut rhs = vec![0.0; dofs.n_free()];
    // the standard block: the uncut stiffness (standard equations come first in `dofs`)
    let mut k = assembly::assemble_stiffness(mesh, materials, locking, &dofs, pattern, &prescribed, &mut rhs)?;
    let mut forces = problem.forces.clone();
    forces.resize(3 * ng, 0.0);
    let npc = mesh.kind.nodes_per_cell();
    let mut eqs = Vec::new();
    let mut pieces = Pieces::new(ng);
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        if !cell.iter().any(|&a| enr.index(a).is_some()) {
            for &a in &cell[1..] {
                pieces.join(cell[0], a);
            }
        }
    }
    // per cut cell, the volume change of each of its enriched functions (for the nodal pressure)
    let mut enriched_divergence: std::collections::HashMap<usize, Vec<(usize, [f64; 3])>> = Default::default();
    visit_enriched_cells(
        mesh,
        materials,
        enr,
        volumetric,
        |_| true,
        |c, cell_nodes, local, ke, sides, divergence| {
            if patches.is_some() {
                enriched_divergence.insert(c, (0..local.len()).map(|j| (cell_nodes[npc + j], divergence[npc + j])).collect());
            }
            let total: f64 = sides.iter().map(|s| s.volume).sum();
            for side in sides.iter().filter(|s| s.volume > 1e-12 * total) {
                // the copies on this side: each node's own, or the other side of an enriched one
                let mut copies = cell_nodes[..npc].to_vec();
                for (j, &(a, _)) in local.iter().enumerate() {
                    if side.shifts[j] != 0.0 {
                        copies[a] = cell_nodes[npc + j];
                    }
                }
                for &a in &copies[1..] {
                    pieces.join(copies[0], a);
                }
            }
            eqs.clear();
            for &a in cell_nodes {
                for i in 0..3 {
                    eqs.push(dofs.eq(3 * a + i));
                }
            }
            assembly::scatter_cell(&mut k, ke, cell_nodes, &eqs, Some(&prescribed), &mut rhs);
        },
    )?;
    if let Some(patches) = &patches {
        visit_nodal_enriched(mesh, materials, patches, &enriched_divergence, |p, q, v| {
            match (dofs.eq(p), dofs.eq(q)) {
                (Some(r), Some(c)) if r >= c => {
                    let pos = k.pattern.position(r, c).expect("the pattern covers nodal patches");
                    k.values[pos] += v;
                }
                // −K_fc ū_c
                (Some(r), None) => rhs[r] -= v * prescribed[q],
                _ => {}
            }
        });
    }
    let mut springs = problem.springs.clone();
    springs.resize(3 * ng, 0.0);
    assembly::add_springs(&mut k, &dofs, &springs);

    // pieces that no support holds
    let k_hold = foundation_stiffness(mesh, materials);
    let mut detached = Vec::new();
    for (copies, free) in loose_pieces(mesh, enr, &mut pieces, &supported, &constrained) {
        for &a in &copies {
            // the foundation ½ k |u_copy|²
            add_copy_spring(&mut k, &dofs, &copy_terms(enr, n, a), k_hold);
            if params.detached == Detached::Remove && a < n {
                for i in 0..3 {
                    forces[3 * a + i] = 0.0;
                }
            }
        }
        detached.push(Piece {
            copies,
            free,
            action: params.detached,
        });
    }
    for (d, f) in forces.iter().enumerate() {
        if let Some(e) = dofs.eq(d) {
            rhs[e] += f;
        }
    }
    Ok(ExtendedSystem {
        dofs,
        k,
        rhs,
        prescribed,
        detached,
    })
}

/// Calls `each(c, cell_nodes, local, ke, sides, divergence)` for every cell with enriched
/// nodes for which `want(local)` holds, with its generalized nodes, the local index and
/// enriched index of each of its enriched nodes, its matrix over them (standard–standard block
/// zero), its sides and the integral of each generalized gradient
/// ([`enriched_cell_stiffness`]).
#[allow(clippy::type_complexity)]
fn visit_enriched_cells(
    mesh: &Mesh,
    materials: &MaterialMap,
    enr: &Enrichment,
    volumetric: EnrichedVolumetric,
    want: impl Fn(&[(usize, usize)]) -> bool,
    mut each: impl FnMut(usize, &[usize], &[(usize, usize)], &[f64], &[CellSide], &[[f64; 3]]),
) -> Result<(), AssemblyError> {
    let npc = mesh.kind.nodes_per_cell();
    let mut x = vec![[0.0; 3]; npc];
    let (mut cell_nodes, mut local) = (Vec::new(), Vec::new());
    let (mut ke, mut divergence) = (Vec::new(), Vec::new());
    for c in 0..mesh.n_cells() {
        generalized_cell(mesh, enr, c, &mut cell_nodes, &mut local);
        if local.is_empty() || !want(&local) {
            continue;
        }
        mesh.cell_coords(c, &mut x);
        let sides = enriched_cell_stiffness(mesh.kind, &x, enr, &local, materials.of(c), volumetric, &mut ke, &mut divergence)
            .map_err(|source| AssemblyError { cell: c, source })?;
        each(c, &cell_nodes, &local, &ke, &sides, &divergence);
    }
    Ok(())
}

/// The enriched part of the averaged-nodal-pressure volumetric stiffness (module docs of
/// [`crate::fem::nodal`]): node a's volume change is `G_a · u` with
/// `G_a = Σ_{e∋a} ¼ ∫_e g_j` over every generalized function j, and its stiffness
/// `(κ_a / V_a) G_a G_aᵀ`; the standard–standard part is in the uncut stiffness. Calls
/// `emit(p, q, value)` for every pair of generalized degrees of freedom `p = 3g + i` of which
/// one at least is enriched, for the nodes whose patch holds a cell of `enriched_divergence`.
fn visit_nodal_enriched(
    mesh: &Mesh,
    materials: &MaterialMap,
    patches: &NodalPatches,
    enriched_divergence: &std::collections::HashMap<usize, Vec<(usize, [f64; 3])>>,
    mut emit: impl FnMut(usize, usize, f64),
) {
    let grads = nodal::reference_volume_gradients(mesh, patches);
    let kappa = nodal::nodal_average(patches, |c| materials.of(c).bulk());
    let n = mesh.n_nodes();
    let mut g: Vec<(usize, [f64; 3])> = Vec::new();
    for a in 0..n {
        g.clear();
        let mut any = false;
        for &c in patches.cells(a) {
            for (b, &node) in mesh.cell(c).iter().enumerate() {
                g.push((node, grads[c][b].map(|v| 0.25 * v)));
            }
            if let Some(e) = enriched_divergence.get(&c) {
                any = true;
                g.extend(e.iter().map(|(j, d)| (*j, d.map(|v| 0.25 * v))));
            }
        }
        if !any {
            continue;
        }
        g.sort_by_key(|(j, _)| *j);
        let mut merged: Vec<(usize, [f64; 3])> = Vec::with_capacity(g.len());
        for &(j, d) in &g {
            match merged.last_mut() {
                Some((last, sum)) if *last == j => (0..3).for_each(|i| sum[i] += d[i]),
                _ => merged.push((j, d)),
            }
        }
        let w = kappa[a] / patches.volume(a);
        for &(p, gp) in &merged {
            for &(q, gq) in &merged {
                if p < n && q < n {
                    continue;
                }
                for i in 0..3 {
                    for j in 0..3 {
                        emit(3 * p + i, 3 * q + j, w * gp[i] * gq[j]);
                    }
                }
            }
        }
    }
}

/// The rows of the extended stiffness that belong to the enriched nodes `from..` (enriched
/// indices; the nodes a progressing cut has just added): triplets `(row, column, value)` over
/// generalized degrees of freedom `3g + i` (`g < n` a mesh node, `g = n + k` enriched node k),
/// each row one of those nodes' degrees of freedom, entries of one position summing. Only the
/// cells (and nodal patches) around the new nodes are integrated, so the cost follows the
/// cut's growth, not its length.
pub fn enriched_rows(
    mesh: &Mesh,
    materials: &MaterialMap,
    locking: Locking,
    enr: &Enrichment,
    from: usize,
) -> Result<Vec<(usize, usize, f64)>, XfemError> {
    let n = mesh.n_nodes();
    let npc = mesh.kind.nodes_per_cell();
    let first = 3 * (n + from);
    let volumetric = EnrichedVolumetric::of(mesh.kind, locking);
    let patches = NodalPatches::when(mesh, volumetric == EnrichedVolumetric::Nodal).ok().flatten();
    let mut out = Vec::new();
    let mut enriched_divergence: std::collections::HashMap<usize, Vec<(usize, [f64; 3])>> = Default::default();
    // with the nodal pressure, a new node's rows reach the cells of its neighbours' patches
    let near_new: Option<Vec<bool>> = patches.as_ref().map(|p| {
        let mut near = vec![false; n];
        for &a in &enr.nodes[from..] {
            for &b in p.nodes(a) {
                for &c in p.nodes(b) {
                    near[c] = true;
                }
            }
        }
        near
    });
    let want = |local: &[(usize, usize)]| local.iter().any(|&(_, k)| k >= from) || near_new.is_some();
    visit_enriched_cells(mesh, materials, enr, volumetric, want, |c, cell_nodes, local, ke, _, divergence| {
        if let Some(near) = &near_new {
            if mesh.cell(c).iter().any(|&a| near[a]) {
                enriched_divergence.insert(c, (0..local.len()).map(|j| (cell_nodes[npc + j], divergence[npc + j])).collect());
            }
            if !local.iter().any(|&(_, k)| k >= from) {
                return;
            }
        }
        let nd = 3 * cell_nodes.len();
        for (lp, &gp) in cell_nodes.iter().enumerate() {
            if 3 * gp < first {
                continue;
            }
            for i in 0..3 {
                let row = (3 * lp + i) * nd;
                for (lq, &gq) in cell_nodes.iter().enumerate() {
                    for j in 0..3 {
                        let v = ke[row + 3 * lq + j];
                        if v != 0.0 {
                            out.push((3 * gp + i, 3 * gq + j, v));
                        }
                    }
                }
            }
        }
    })?;
    if let Some(patches) = &patches {
        visit_nodal_enriched(mesh, materials, patches, &enriched_divergence, |p, q, v| {
            if p >= first {
                out.push((p, q, v));
            }
        });
    }
    Ok(out)
}

/// Adds the stiffness of a spring `½ k |Σ_j c_j d_j|²` on a copy made of `terms`
/// (`(generalized node, c_j)`, [`copy_terms`]) to `k` over the free dofs: `k c_i c_j` on
/// every pair, component by component.
pub(super) fn add_copy_spring(k: &mut SymmetricMatrix, dofs: &DofMap, terms: &[(usize, f64)], stiffness: f64) {
    for (p, &(gp, cp)) in terms.iter().enumerate() {
        for &(gq, cq) in &terms[..=p] {
            for i in 0..3 {
                if let (Some(er), Some(ec)) = (dofs.eq(3 * gp + i), dofs.eq(3 * gq + i)) {
                    let pos = k
                        .pattern
                        .position(er.max(ec), er.min(ec))
                        .expect("a node couples with its enrichment");
                    k.values[pos] += stiffness * cp * cq;
                }
            }
        }
    }
}

/// Solves the static problem with the cut `enr` by the full-order XFEM.
pub fn solve(
    mesh: &Mesh,
    materials: &MaterialMap,
    locking: Locking,
    problem: &StaticProblem,
    enr: &Enrichment,
    params: &XfemParams,
) -> Result<XfemSolution, XfemError> {
    let clock = Instant::now();
    let sys = assemble(mesh, materials, locking, problem, enr, params)?;
    let (u, q, residual) = factor_and_solve(&sys.k, &sys.rhs, &sys.dofs, &sys.prescribed, mesh.n_nodes())?;
    Ok(XfemSolution {
        u,
        q,
        detached: sys.detached,
        n_free: sys.dofs.n_free(),
        nnz: sys.k.pattern.nnz(),
        residual,
        seconds: clock.elapsed().as_secs_f64(),
    })
}

/// Factors the extended `k` and solves it for `rhs`: the displacements of the `n_nodes` mesh
/// nodes, the enriched degrees of freedom after them (both with `prescribed` where held), and
/// the relative residual.
pub(super) fn factor_and_solve(
    k: &SymmetricMatrix,
    rhs: &[f64],
    dofs: &DofMap,
    prescribed: &[f64],
    n_nodes: usize,
) -> Result<(Vec<f64>, Vec<f64>, f64), XfemError> {
    let chol = Cholesky::factor(k)?;
    let mut x = rhs.to_vec();
    chol.solve_in_place(&mut x);
    if x.iter().any(|v| !v.is_finite()) {
        return Err(XfemError::NonFinite);
    }
    let mut kx = vec![0.0; x.len()];
    k.mul_vec(&x, &mut kx);
    let r2: f64 = kx.iter().zip(rhs).map(|(a, b)| (a - b).powi(2)).sum();
    let f2: f64 = rhs.iter().map(|v| v * v).sum();
    let mut full = vec![0.0; dofs.n_dofs()];
    dofs.expand(&x, prescribed, &mut full);
    let q = full.split_off(3 * n_nodes);
    Ok((full, q, (r2 / f2.max(f64::MIN_POSITIVE)).sqrt()))
}
