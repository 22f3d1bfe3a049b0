//! Sparse direct solvers: Cholesky `K = L Lᵀ` through faer, with the symbolic analysis kept
//! and reused for every numeric factorization of the same pattern, plus the check that a set
//! of constraints removes every rigid-body motion (the usual cause of a singular stiffness).

pub mod memory;

use faer::MatMut;
use faer::Side;
use faer::linalg::solvers::Solve;
use faer::sparse::SparseColMatRef;
use faer::sparse::linalg::LltError;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};

/// A symmetric sparse matrix given by its lower triangle in compressed columns (row indices
/// sorted within each column): what the factorizations take. The finite elements' assembled
/// matrix (`crate::fem::system::SymmetricMatrix`) is one; this module imports no element.
pub trait LowerTriangle {
    /// The lower triangle as a faer matrix.
    fn lower(&self) -> SparseColMatRef<'_, usize, f64>;
}

/// Why a factorization failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SolveError {
    /// The matrix is not positive definite: a pivot was zero or negative. For a stiffness this
    /// means a rigid motion or a mechanism is not prevented, or a cell is inverted.
    #[error(
        "the stiffness matrix is singular or indefinite (non-positive pivot at equation {pivot} of {n} in the solver's ordering): some part of the body can move freely; check the fixed region and that the mesh is one connected piece"
    )]
    NotPositiveDefinite {
        /// Pivot index in the fill-reducing ordering.
        pivot: usize,
        /// Matrix dimension.
        n: usize,
    },
    /// The factorization ran out of memory or failed internally.
    #[error("sparse factorization failed: {0}")]
    Internal(String),
}

/// A sparse Cholesky factorization whose symbolic part can be reused.
#[derive(Debug, Clone)]
pub struct Cholesky {
    symbolic: SymbolicLlt<usize>,
    llt: Llt<usize, f64>,
    n: usize,
}

impl Cholesky {
    /// Symbolic analysis (fill-reducing ordering, elimination tree) of `k`'s pattern.
    pub fn analyze(k: &impl LowerTriangle) -> Result<SymbolicLlt<usize>, SolveError> {
        SymbolicLlt::try_new(k.lower().symbolic(), Side::Lower).map_err(|e| SolveError::Internal(format!("{e:?}")))
    }

    /// Numeric factorization of `k` with an existing symbolic analysis of its pattern.
    pub fn factor_with(symbolic: SymbolicLlt<usize>, k: &impl LowerTriangle) -> Result<Self, SolveError> {
        let n = k.lower().nrows();
        let llt = Llt::try_new_with_symbolic(symbolic.clone(), k.lower(), Side::Lower).map_err(|e| match e {
            LltError::Numeric(faer::linalg::cholesky::llt::factor::LltError::NonPositivePivot { index }) => {
                SolveError::NotPositiveDefinite { pivot: index, n }
            }
            LltError::Generic(g) => SolveError::Internal(format!("{g:?}")),
        })?;
        Ok(Self { symbolic, llt, n })
    }

    /// Symbolic analysis and numeric factorization in one go.
    pub fn factor(k: &impl LowerTriangle) -> Result<Self, SolveError> {
        let s = Self::analyze(k)?;
        Self::factor_with(s, k)
    }

    /// Refactors a matrix with the same pattern, keeping the symbolic analysis.
    pub fn refactor(&mut self, k: &impl LowerTriangle) -> Result<(), SolveError> {
        *self = Self::factor_with(self.symbolic.clone(), k)?;
        Ok(())
    }

    /// The symbolic analysis (cheap to clone: reference counted).
    pub fn symbolic(&self) -> &SymbolicLlt<usize> {
        &self.symbolic
    }

    /// Matrix dimension.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Solves `K x = b` in place (`rhs` holds b on entry and x on exit).
    pub fn solve_in_place(&self, rhs: &mut [f64]) {
        assert_eq!(rhs.len(), self.n, "right-hand side length must equal the matrix dimension");
        let m = MatMut::from_column_major_slice_mut(rhs, self.n, 1);
        self.llt.solve_in_place(m);
    }

    /// Solves for several right-hand sides stored column-major in `rhs` (`n × ncols`).
    pub fn solve_many_in_place(&self, rhs: &mut [f64], ncols: usize) {
        assert_eq!(rhs.len(), self.n * ncols);
        let m = MatMut::from_column_major_slice_mut(rhs, self.n, ncols);
        self.llt.solve_in_place(m);
    }
}

/// Names of the six rigid-body motions, in the order of [`free_rigid_motions`].
pub const RIGID_MOTIONS: [&str; 6] = [
    "translation along x",
    "translation along y",
    "translation along z",
    "rotation about x",
    "rotation about y",
    "rotation about z",
];

/// Which rigid-body motions a set of constrained degrees of freedom leaves free.
///
/// Builds `R` (constrained dofs × 6 rigid modes, coordinates centred and scaled), and looks for
/// near-null directions of `RᵀR`. Returns a description of each free motion (empty when the
/// constraints fix the body). `constrained[3n+i]` marks component i of node n.
pub fn free_rigid_motions(nodes: &[[f64; 3]], constrained: &[bool]) -> Vec<String> {
    let n = nodes.len().max(1) as f64;
    let mut c = [0.0; 3];
    for p in nodes {
        for k in 0..3 {
            c[k] += p[k] / n;
        }
    }
    let scale = nodes
        .iter()
        .map(|p| (0..3).map(|k| (p[k] - c[k]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let mut g = nalgebra::Matrix6::<f64>::zeros();
    for (d, &is_c) in constrained.iter().enumerate() {
        if !is_c {
            continue;
        }
        let (node, i) = (d / 3, d % 3);
        let p = nodes[node];
        let x = [(p[0] - c[0]) / scale, (p[1] - c[1]) / scale, (p[2] - c[2]) / scale];
        // component i of each rigid mode at x: translations e_k; rotations ω×x
        let rot = [[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]];
        let mut row = [0.0; 6];
        row[i] = 1.0;
        for k in 0..3 {
            row[3 + k] = rot[k][i];
        }
        for a in 0..6 {
            for b in 0..6 {
                g[(a, b)] += row[a] * row[b];
            }
        }
    }
    let eig = nalgebra::SymmetricEigen::new(g);
    let max = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    let mut out = Vec::new();
    for (k, &lam) in eig.eigenvalues.iter().enumerate() {
        if lam <= 1e-10 * max.max(1.0) {
            let v = eig.eigenvectors.column(k);
            // describe by the dominant components
            let mut parts: Vec<(f64, usize)> = (0..6).map(|a| (v[a].abs(), a)).filter(|(m, _)| *m > 0.2).collect();
            parts.sort_by(|a, b| b.0.total_cmp(&a.0));
            let names: Vec<&str> = parts.iter().map(|(_, a)| RIGID_MOTIONS[*a]).collect();
            out.push(names.join(" + "));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube_nodes() -> Vec<[f64; 3]> {
        (0..8)
            .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
            .collect()
    }

    #[test]
    fn clamping_a_face_fixes_every_rigid_motion() {
        let nodes = cube_nodes();
        let mut c = vec![false; 24];
        for n in 0..8 {
            if nodes[n][0] == 0.0 {
                c[3 * n..3 * n + 3].fill(true);
            }
        }
        assert!(free_rigid_motions(&nodes, &c).is_empty());
    }

    #[test]
    fn one_fixed_node_leaves_three_rotations() {
        let nodes = cube_nodes();
        let mut c = vec![false; 24];
        c[0..3].fill(true);
        assert_eq!(free_rigid_motions(&nodes, &c).len(), 3);
        assert_eq!(free_rigid_motions(&nodes, &[false; 24]).len(), 6);
    }
}
