//! The POD basis of the damage field (seed 000 §4.5.1) and the range of its coefficients.
//!
//! Snapshots are the vectors `g` of the tearable points at every step of a full-order run;
//! their POD basis `υ₁ … υ_q` (Eq. 4.12, [`crate::rom::pod`]) parametrises the damage:
//! `g ≈ Σ ξ_K υ_K` (Eq. 4.13). Online, `ξ = υᵀg` (the L2 projection onto the orthonormal basis,
//! Alg. 4.2 line 4). The vademecum covers a box of coefficients: the range of the snapshots'
//! projections widened by a margin on each side (the seed sets it "by projecting the damage
//! values of the reference model into the POD reduced basis").

use crate::rom::pod::{Pod, PodCriterion, PodError};

/// The POD basis of damage snapshots and the box of coefficients its vademecum covers.
#[derive(Debug, Clone, PartialEq)]
pub struct DamageBasis {
    /// The orthonormal basis (over the tearable points).
    pub pod: Pod,
    /// Lower bound of each coefficient's range.
    pub lo: Vec<f64>,
    /// Upper bound of each coefficient's range.
    pub hi: Vec<f64>,
}

impl DamageBasis {
    /// The basis of `snapshots` (`g` of the tearable points, one per step) under `criterion`,
    /// with the coefficient box of the snapshots widened by `margin` (a fraction of each
    /// range, and at least `margin` times the largest range, so that a coefficient the
    /// snapshots never vary still has a box).
    pub fn from_snapshots(snapshots: &[Vec<f64>], criterion: PodCriterion, margin: f64) -> Result<Self, PodError> {
        let pod = Pod::from_snapshots(snapshots, criterion)?;
        let q = pod.modes;
        let (mut lo, mut hi) = (vec![f64::INFINITY; q], vec![f64::NEG_INFINITY; q]);
        for s in snapshots {
            for (k, xi) in pod.project(s).into_iter().enumerate() {
                lo[k] = lo[k].min(xi);
                hi[k] = hi[k].max(xi);
            }
        }
        let widest = lo.iter().zip(&hi).map(|(a, b)| b - a).fold(0.0, f64::max).max(1e-12);
        for k in 0..q {
            let pad = margin * (hi[k] - lo[k]).max(widest);
            lo[k] -= pad;
            hi[k] += pad;
        }
        Ok(Self { pod, lo, hi })
    }

    /// Number of coefficients `q`.
    pub fn len(&self) -> usize {
        self.pod.modes
    }

    /// Whether the basis is empty (never, once built).
    pub fn is_empty(&self) -> bool {
        self.pod.modes == 0
    }

    /// `ξ = υᵀg` into `xi` (no allocation). Returns whether some coefficient lies outside
    /// the box.
    pub fn project(&self, g: &[f64], xi: &mut [f64]) -> bool {
        let mut outside = false;
        for (k, x) in xi.iter_mut().enumerate() {
            *x = self.pod.mode(k).iter().zip(g).map(|(a, b)| a * b).sum();
            outside |= *x < self.lo[k] || *x > self.hi[k];
        }
        outside
    }

    /// `g = Σ ξ_K υ_K` at tearable point `i`.
    pub fn lift_at(&self, xi: &[f64], i: usize) -> f64 {
        xi.iter().enumerate().map(|(k, x)| x * self.pod.basis[k * self.pod.n + i]).sum()
    }

    /// The smallest value `Σ ξ_K υ_K` takes over the box at any point: where it is small or
    /// negative the vademecum's stiffness loses positivity inside its own box.
    pub fn min_over_box(&self) -> f64 {
        (0..self.pod.n)
            .map(|i| {
                (0..self.len())
                    .map(|k| {
                        let v = self.pod.basis[k * self.pod.n + i];
                        (self.lo[k] * v).min(self.hi[k] * v)
                    })
                    .sum::<f64>()
            })
            .fold(f64::INFINITY, f64::min)
    }
}
