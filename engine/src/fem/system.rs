//! The system the assembly fills: the degree-of-freedom numbering (`DofMap`), the
//! lower-triangular sparsity pattern of `K_ff` and the symmetric sparse matrix on it, and the
//! scatter of one cell's matrix into it. Below both the assembly and the nodal (averaged
//! pressure) elements, which fill it alike.
//!
//! Dirichlet conditions are applied by elimination: constrained degrees of freedom get no
//! equation, and their prescribed values move to the right-hand side,
//! `K_ff u_f = f_f − K_fc ū_c`. The stored matrix is the lower triangle of `K_ff` in
//! compressed-column form (what faer's sparse Cholesky reads with `Side::Lower`).

use std::sync::Arc;

use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};

use crate::mesh::Mesh;

/// Marker of a constrained degree of freedom in [`DofMap`].
const FIXED: u32 = u32::MAX;

/// Maps each degree of freedom (`3·node + component`) to its equation, or to none if it is
/// constrained. Equations follow node order, so the matrix bandwidth follows the mesh's.
#[derive(Debug, Clone, PartialEq)]
pub struct DofMap {
    eq: Vec<u32>,
    n_free: usize,
}

impl DofMap {
    /// Bytes of its equation numbers.
    pub fn heap_bytes(&self) -> usize {
        crate::memory::vec_bytes(&self.eq)
    }

    /// Numbers the unconstrained degrees of freedom in order.
    pub fn new(constrained: &[bool]) -> Self {
        let mut eq = Vec::with_capacity(constrained.len());
        let mut n = 0u32;
        for &c in constrained {
            if c {
                eq.push(FIXED);
            } else {
                eq.push(n);
                n += 1;
            }
        }
        Self { eq, n_free: n as usize }
    }

    /// Number of degrees of freedom (free and constrained).
    pub fn n_dofs(&self) -> usize {
        self.eq.len()
    }

    /// Number of equations (free degrees of freedom).
    pub fn n_free(&self) -> usize {
        self.n_free
    }

    /// The equation of degree of freedom `dof`, or `None` if it is constrained.
    #[inline]
    pub fn eq(&self, dof: usize) -> Option<usize> {
        let e = self.eq[dof];
        (e != FIXED).then_some(e as usize)
    }

    /// Whether `dof` is constrained.
    #[inline]
    pub fn is_constrained(&self, dof: usize) -> bool {
        self.eq[dof] == FIXED
    }

    /// The full vector: `free[eq(d)]` for free dofs, `prescribed[d]` for constrained ones.
    pub fn expand(&self, free: &[f64], prescribed: &[f64], out: &mut [f64]) {
        debug_assert_eq!(out.len(), self.eq.len());
        for (d, o) in out.iter_mut().enumerate() {
            *o = match self.eq(d) {
                Some(e) => free[e],
                None => prescribed[d],
            };
        }
    }

    /// Gathers the free entries of a full vector.
    pub fn restrict(&self, full: &[f64], out: &mut [f64]) {
        for (d, &v) in full.iter().enumerate() {
            if let Some(e) = self.eq(d) {
                out[e] = v;
            }
        }
    }
}

/// The lower-triangular sparsity pattern of `K_ff`, shared between matrices (stiffness, mass)
/// and reused by every numeric factorization.
#[derive(Debug, Clone)]
pub struct SymmetricPattern {
    symbolic: SymbolicSparseColMat<usize>,
}

impl SymmetricPattern {
    /// The pattern of all couplings between free degrees of freedom of nodes sharing a cell.
    pub fn build(mesh: &Mesh, dofs: &DofMap) -> Self {
        let nn = mesh.n_nodes();
        // node adjacency (including the node itself), sorted
        let mut adj: Vec<Vec<usize>> = vec![Vec::new(); nn];
        for cell in mesh.cells_iter() {
            for &a in cell {
                adj[a].extend_from_slice(cell);
            }
        }
        for l in adj.iter_mut() {
            l.sort_unstable();
            l.dedup();
        }
        Self::from_adjacency(&adj, dofs)
    }

    /// The pattern coupling every node with the nodes of its sorted list `adj[node]` (the
    /// averaged nodal pressure's wider pattern: `SymmetricPattern::for_locking`, by the
    /// assembly).
    pub(crate) fn from_adjacency(adj: &[Vec<usize>], dofs: &DofMap) -> Self {
        let nn = adj.len();
        let n = dofs.n_free();
        let mut col_ptr = Vec::with_capacity(n + 1);
        col_ptr.push(0usize);
        let mut row_idx = Vec::new();
        for a in 0..nn {
            for i in 0..3 {
                let Some(col) = dofs.eq(3 * a + i) else { continue };
                for &b in &adj[a] {
                    for j in 0..3 {
                        if let Some(row) = dofs.eq(3 * b + j)
                            && row >= col
                        {
                            row_idx.push(row);
                        }
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        Self {
            symbolic: SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx),
        }
    }

    /// Matrix dimension.
    pub fn n(&self) -> usize {
        self.symbolic.nrows()
    }

    /// Stored entries (lower triangle).
    pub fn nnz(&self) -> usize {
        self.symbolic.row_idx().len()
    }

    /// The faer symbolic matrix.
    pub fn symbolic(&self) -> &SymbolicSparseColMat<usize> {
        &self.symbolic
    }

    /// Position of entry `(row, col)` (`row ≥ col`) in the value array.
    #[inline]
    pub fn position(&self, row: usize, col: usize) -> Option<usize> {
        let cp = self.symbolic.col_ptr();
        let (s, e) = (cp[col], cp[col + 1]);
        self.symbolic.row_idx()[s..e].binary_search(&row).ok().map(|k| s + k)
    }
}

/// A symmetric sparse matrix stored as its lower triangle over a shared pattern.
#[derive(Debug, Clone)]
pub struct SymmetricMatrix {
    /// The pattern.
    pub pattern: Arc<SymmetricPattern>,
    /// Values, aligned with the pattern's row indices.
    pub values: Vec<f64>,
}

impl SymmetricMatrix {
    /// A zero matrix on `pattern`.
    pub fn zeros(pattern: Arc<SymmetricPattern>) -> Self {
        let nnz = pattern.nnz();
        Self {
            pattern,
            values: vec![0.0; nnz],
        }
    }

    /// A faer view of the lower triangle.
    pub fn as_faer(&self) -> SparseColMatRef<'_, usize, f64> {
        SparseColMatRef::new(self.pattern.symbolic.as_ref(), &self.values)
    }

    /// `y = A x` using the symmetric lower storage.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        let cp = self.pattern.symbolic.col_ptr();
        let ri = self.pattern.symbolic.row_idx();
        for c in 0..self.pattern.n() {
            for k in cp[c]..cp[c + 1] {
                let r = ri[k];
                let v = self.values[k];
                y[r] += v * x[c];
                if r != c {
                    y[c] += v * x[r];
                }
            }
        }
    }
}

impl crate::solve::LowerTriangle for SymmetricMatrix {
    fn lower(&self) -> SparseColMatRef<'_, usize, f64> {
        self.as_faer()
    }
}

/// Adds a cell matrix `ke` (`nd × nd`, row-major, `nd = eqs.len()`) of the cell with nodes
/// `cell` into the lower triangle of `K_ff`, and `−K_fc ū_c` into `rhs` (length `n_free`) for
/// the prescribed values `prescribed` (full length; `None`: no right-hand side). `eqs[p]` is
/// the equation of the cell's degree of freedom `p`, `None` when it is constrained.
pub fn scatter_cell(
    k: &mut SymmetricMatrix,
    ke: &[f64],
    cell: &[usize],
    eqs: &[Option<usize>],
    prescribed: Option<&[f64]>,
    rhs: &mut [f64],
) {
    let nd = eqs.len();
    debug_assert_eq!(ke.len(), nd * nd);
    for p in 0..nd {
        let Some(rp) = eqs[p] else { continue };
        for q in 0..nd {
            match eqs[q] {
                // K_ff, lower triangle: row rp, column rq
                Some(rq) if rp >= rq => {
                    let pos = k.pattern.position(rp, rq).expect("pattern covers every cell coupling");
                    k.values[pos] += ke[p * nd + q];
                }
                Some(_) => {}
                // −K_fc ū_c
                None => {
                    let ub = prescribed.map_or(0.0, |u| u[3 * cell[q / 3] + q % 3]);
                    if ub != 0.0 {
                        rhs[rp] -= ke[p * nd + q] * ub;
                    }
                }
            }
        }
    }
}
