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
    /// snapshots never vary still has a box) — less where the box would reach damage fields
    /// softer than half the softest snapshot (the stiffness must stay positive over the
    /// whole box: it is a tensor product, whose corners combine extremes the snapshots never
    /// reach together).
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
        let pad: Vec<f64> = (0..q).map(|k| margin * (hi[k] - lo[k]).max(widest)).collect();
        let centre: Vec<f64> = (0..q).map(|k| 0.5 * (lo[k] + hi[k])).collect();
        let half: Vec<f64> = (0..q).map(|k| 0.5 * (hi[k] - lo[k])).collect();
        // the box must not hold damage fields softer than half the softest snapshot: its
        // stiffness would lose positivity where the tensor-product box combines extremes
        let floor = 0.5 * snapshots.iter().flatten().fold(1.0f64, |a, &b| a.min(b)).max(0.0);
        let mut b = Self { pod, lo, hi };
        let set = |b: &mut Self, shrink: f64, t: f64| {
            for k in 0..q {
                b.lo[k] = centre[k] - shrink * half[k] - t * pad[k];
                b.hi[k] = centre[k] + shrink * half[k] + t * pad[k];
            }
        };
        set(&mut b, 1.0, 1.0);
        if b.min_over_box() < floor {
            // the largest margin that keeps the floor, else the snapshots' box shrunk about
            // its centre (coefficients outside it are then clamped online, and reported)
            let stage = |b: &mut Self, f: &dyn Fn(f64) -> (f64, f64)| {
                let (mut ok, mut bad) = (0.0, 1.0);
                for _ in 0..40 {
                    let mid = 0.5 * (ok + bad);
                    let (s, t) = f(mid);
                    set(b, s, t);
                    if b.min_over_box() >= floor { ok = mid } else { bad = mid }
                }
                let (s, t) = f(ok);
                set(b, s, t);
            };
            set(&mut b, 1.0, 0.0);
            if b.min_over_box() >= floor {
                stage(&mut b, &|t| (1.0, t));
            } else {
                stage(&mut b, &|s| (s, 0.0));
            }
        }
        Ok(b)
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
