//! Proper orthogonal decomposition of snapshots (seed 001 §2).
//!
//! # The method
//! The snapshots `u¹ … uᵐ` (full displacement vectors, zero on clamped degrees of freedom)
//! are the columns of `Q ∈ ℝ^{N×m}`. Its thin SVD `Q = U Σ Vᵀ` gives the POD modes (the
//! columns of `U`, the eigenvectors of the correlation `QQᵀ` of seed 001 Eq. 4), ordered by
//! the energy `σ_k²` they carry. The basis `A = [φ₁ … φ_r]` keeps the smallest `r` whose
//! captured energy `Σ_{k≤r} σ_k² / Σ_k σ_k²` reaches the criterion (seed 001 keeps the modes
//! whose eigenvalue is not negligible against the first). The reduced linear model of a
//! stiffness `K` is `AᵀKA` (seed 001 Eq. 13).

use faer::Mat;

use crate::fem::assembly::{DofMap, SymmetricMatrix};

/// How many modes to keep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PodCriterion {
    /// Fraction of the snapshots' energy `Σσ²` the basis must capture (in `(0, 1]`).
    pub energy: f64,
    /// Never more modes than this.
    pub max_modes: usize,
}

impl Default for PodCriterion {
    /// `1 − 10⁻¹⁰` of the energy (a relative displacement error of about 10⁻⁵ on the
    /// snapshots), at most 12 modes (seed 001 uses 9 for the liver).
    fn default() -> Self {
        Self {
            energy: 1.0 - 1e-10,
            max_modes: 12,
        }
    }
}

/// Why no basis could be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PodError {
    /// No snapshot, or snapshots of different lengths.
    #[error("POD needs at least one snapshot, all of the same length ({0})")]
    Shape(String),
    /// A snapshot holds NaN or infinity.
    #[error("snapshot {0} is not finite")]
    NotFinite(usize),
    /// Every snapshot is zero.
    #[error("every snapshot is zero: there is nothing to reduce")]
    Zero,
    /// The criterion is out of range.
    #[error("the energy criterion must be in (0, 1] and at least one mode allowed")]
    Criterion,
}

/// An orthonormal reduced basis.
#[derive(Debug, Clone, PartialEq)]
pub struct Pod {
    /// Length of a full vector.
    pub n: usize,
    /// Number of modes kept `r`.
    pub modes: usize,
    /// The modes, column-major `n × r` (mode `k` is `basis[k n .. (k+1) n]`).
    pub basis: Vec<f64>,
    /// Every singular value of the snapshot matrix, decreasing.
    pub singular_values: Vec<f64>,
    /// Energy fraction the kept modes capture.
    pub captured: f64,
}

impl Pod {
    /// The POD basis of `snapshots` under `criterion`.
    pub fn from_snapshots(snapshots: &[Vec<f64>], criterion: PodCriterion) -> Result<Self, PodError> {
        if !(criterion.energy > 0.0 && criterion.energy <= 1.0) || criterion.max_modes == 0 {
            return Err(PodError::Criterion);
        }
        let n = snapshots.first().map_or(0, Vec::len);
        if n == 0 || snapshots.iter().any(|s| s.len() != n) {
            return Err(PodError::Shape(format!("{} snapshots", snapshots.len())));
        }
        if let Some(k) = snapshots.iter().position(|s| s.iter().any(|x| !x.is_finite())) {
            return Err(PodError::NotFinite(k));
        }
        let q = Mat::from_fn(n, snapshots.len(), |i, k| snapshots[k][i]);
        let svd = q.thin_svd().map_err(|_| PodError::Zero)?;
        let sigma: Vec<f64> = (0..svd.S().dim()).map(|i| svd.S()[i]).collect();
        let total: f64 = sigma.iter().map(|s| s * s).sum();
        if total <= 0.0 || total.is_nan() {
            return Err(PodError::Zero);
        }
        // keep modes up to the energy criterion, and never one at round-off level
        let floor = sigma[0] * 1e-12 * (sigma.len() as f64).sqrt();
        let mut modes = 0;
        let mut captured = 0.0;
        while modes < sigma.len() && modes < criterion.max_modes && sigma[modes] > floor {
            captured += sigma[modes] * sigma[modes] / total;
            modes += 1;
            if captured >= criterion.energy {
                break;
            }
        }
        let u = svd.U();
        let mut basis = Vec::with_capacity(n * modes);
        for k in 0..modes {
            basis.extend((0..n).map(|i| u[(i, k)]));
        }
        Ok(Self {
            n,
            modes,
            basis,
            singular_values: sigma,
            captured,
        })
    }

    /// An orthonormal basis given directly (columns `n × r`, column-major), e.g. the unit
    /// vectors of the free degrees of freedom for a test of the reduced model against the
    /// full one.
    pub fn from_columns(n: usize, basis: Vec<f64>) -> Result<Self, PodError> {
        if n == 0 || basis.is_empty() || !basis.len().is_multiple_of(n) {
            return Err(PodError::Shape(format!("{} entries for columns of {n}", basis.len())));
        }
        let modes = basis.len() / n;
        Ok(Self {
            n,
            modes,
            basis,
            singular_values: vec![1.0; modes],
            captured: 1.0,
        })
    }

    /// Mode `k`.
    pub fn mode(&self, k: usize) -> &[f64] {
        &self.basis[k * self.n..(k + 1) * self.n]
    }

    /// Reduced coordinates of a full vector: `ζ = Aᵀu`.
    pub fn project(&self, u: &[f64]) -> Vec<f64> {
        (0..self.modes).map(|k| dot(self.mode(k), u)).collect()
    }

    /// The full vector of reduced coordinates: `u = Aζ` (overwrites `u`).
    pub fn lift(&self, zeta: &[f64], u: &mut [f64]) {
        u.fill(0.0);
        for (k, &z) in zeta.iter().enumerate() {
            for (ui, &a) in u.iter_mut().zip(self.mode(k)) {
                *ui += z * a;
            }
        }
    }

    /// The reduced linear model `AᵀKA` (row-major `r × r`) of a stiffness `k` assembled on the
    /// free degrees of freedom of `dofs` (the modes vanish on the constrained ones).
    pub fn reduce_matrix(&self, dofs: &DofMap, k: &SymmetricMatrix) -> Vec<f64> {
        let r = self.modes;
        let nf = dofs.n_free();
        let free: Vec<Vec<f64>> = (0..r)
            .map(|m| {
                let mut v = vec![0.0; nf];
                dofs.restrict(self.mode(m), &mut v);
                v
            })
            .collect();
        let mut kv = vec![0.0; nf];
        let mut out = vec![0.0; r * r];
        for j in 0..r {
            k.mul_vec(&free[j], &mut kv);
            for i in 0..r {
                out[i * r + j] = dot(&free[i], &kv);
            }
        }
        out
    }
}

pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_basis_is_orthonormal_and_reproduces_snapshots_of_low_rank() {
        // three snapshots spanning a plane of ℝ⁵
        let a = [1.0, 2.0, 0.0, -1.0, 0.5];
        let b = [0.0, 1.0, 1.0, 3.0, -2.0];
        let s: Vec<Vec<f64>> = [(1.0, 0.0), (0.5, 0.5), (2.0, -1.0)]
            .iter()
            .map(|&(x, y)| (0..5).map(|i| x * a[i] + y * b[i]).collect())
            .collect();
        let pod = Pod::from_snapshots(&s, PodCriterion::default()).unwrap();
        assert_eq!(pod.modes, 2, "a rank-2 set gives two modes");
        for i in 0..2 {
            for j in 0..2 {
                let d = dot(pod.mode(i), pod.mode(j));
                assert!((d - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        let mut back = vec![0.0; 5];
        for v in &s {
            pod.lift(&pod.project(v), &mut back);
            assert!(back.iter().zip(v).all(|(x, y)| (x - y).abs() < 1e-12));
        }
    }

    #[test]
    fn the_energy_criterion_counts_modes() {
        // snapshots e_k scaled by 10^-k: energies 1, 1e-2, 1e-4, 1e-6
        let s: Vec<Vec<f64>> = (0..4)
            .map(|k| {
                let mut v = vec![0.0; 6];
                v[k] = 10f64.powi(-(k as i32));
                v
            })
            .collect();
        let keep = |energy| Pod::from_snapshots(&s, PodCriterion { energy, max_modes: 10 }).unwrap().modes;
        assert_eq!(keep(0.99), 1);
        assert_eq!(keep(0.9999), 2);
        assert_eq!(keep(1.0), 4);
        let capped = Pod::from_snapshots(&s, PodCriterion { energy: 1.0, max_modes: 3 }).unwrap();
        assert_eq!(capped.modes, 3);
    }

    #[test]
    fn bad_snapshots_are_refused() {
        assert!(matches!(Pod::from_snapshots(&[], PodCriterion::default()), Err(PodError::Shape(_))));
        assert!(matches!(
            Pod::from_snapshots(&[vec![1.0, 2.0], vec![1.0]], PodCriterion::default()),
            Err(PodError::Shape(_))
        ));
        assert!(matches!(
            Pod::from_snapshots(&[vec![1.0, f64::NAN]], PodCriterion::default()),
            Err(PodError::NotFinite(0))
        ));
        assert!(matches!(
            Pod::from_snapshots(&[vec![0.0; 3]], PodCriterion::default()),
            Err(PodError::Zero)
        ));
    }
}
