//! Interpolation of reduced bases between precomputed load positions (seed 001 §5).
//!
//! # The methods
//! A POD basis `A ∈ ℝ^{N×r}` (orthonormal columns) stands for a point of the Grassmann
//! manifold `G(r, N)` — its column space; the columns themselves are defined only up to a
//! rotation (and, mode by mode, a sign). Given bases `A_k` at neighbouring positions with
//! weights `w_k` (`Σ w_k = 1`):
//!
//! - **PODI** (§5.2): interpolate the bases linearly. Taken literally, `Σ w_k A_k` mixes
//!   columns that need not correspond (a flipped sign cancels a mode), so each basis is first
//!   rotated onto the reference one (the heaviest neighbour) by the orthogonal Procrustes
//!   rotation `Q_k = U Vᵀ`, `A_kᵀ A_0 = U Σ Vᵀ`, which is the best one-to-one matching of
//!   their modes; the weighted sum is then made orthonormal again by its polar factor.
//! - **Grassmann** (§5.1): with the reference `A_0`, map each neighbour to the tangent space
//!   at `A_0` (`(I − A_0A_0ᵀ) A_k (A_0ᵀA_k)⁻¹ = U Σ Vᵀ`, `Γ_k = U atan(Σ) Vᵀ`), interpolate
//!   there (`Γ = Σ w_k Γ_k`), and map back (`Γ = U Σ Vᵀ`, `A = A_0 V cos Σ Vᵀ + U sin Σ Vᵀ`).
//!   The seed writes the exponential without the trailing `Vᵀ`, which spans the same space.
//!
//! All three are equivariant under an isometric embedding, so they can run on the
//! coordinates `C_k = WᵀA_k` of the bases in an orthonormal basis `W` of their union, at a
//! cost independent of the mesh size.

use nalgebra::DMatrix;

/// Why an interpolation failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InterpolationError {
    /// Nothing to interpolate, or shapes that differ.
    #[error("interpolation needs bases of the same shape and one weight each ({0})")]
    Shape(String),
    /// The weights are not a partition of unity.
    #[error("interpolation weights must be finite, non-negative and sum to 1")]
    Weights,
    /// A neighbour's subspace is orthogonal to the reference's in some direction: the
    /// logarithm does not exist (the positions are too far apart for Grassmann interpolation).
    #[error("basis {0} has a direction orthogonal to the reference basis; the Grassmann logarithm does not exist")]
    Orthogonal(usize),
}

fn check(bases: &[DMatrix<f64>], weights: &[f64]) -> Result<usize, InterpolationError> {
    if bases.is_empty() || bases.len() != weights.len() || bases.iter().any(|b| b.shape() != bases[0].shape()) {
        return Err(InterpolationError::Shape(format!(
            "{} bases, {} weights",
            bases.len(),
            weights.len()
        )));
    }
    let sum: f64 = weights.iter().sum();
    if weights.iter().any(|w| !w.is_finite() || *w < 0.0) || (sum - 1.0).abs() > 1e-9 {
        return Err(InterpolationError::Weights);
    }
    Ok((0..weights.len()).max_by(|&a, &b| weights[a].total_cmp(&weights[b])).unwrap_or(0))
}

/// The orthonormal polar factor `U Vᵀ` of `m = U Σ Vᵀ`: the nearest matrix with orthonormal
/// columns.
pub(crate) fn polar(m: DMatrix<f64>) -> DMatrix<f64> {
    let svd = m.svd(true, true);
    let (u, vt) = (svd.u.expect("computed"), svd.v_t.expect("computed"));
    u * vt
}

/// `a` rotated onto `reference`: `a Q` with the Procrustes rotation `Q = U Vᵀ`,
/// `aᵀ reference = U Σ Vᵀ` (the same column space as `a`).
pub fn align(a: &DMatrix<f64>, reference: &DMatrix<f64>) -> DMatrix<f64> {
    a * polar(a.transpose() * reference)
}

/// PODI with Procrustes alignment (see the [module docs](self)).
pub fn podi(bases: &[DMatrix<f64>], weights: &[f64]) -> Result<DMatrix<f64>, InterpolationError> {
    let r0 = check(bases, weights)?;
    let reference = &bases[r0];
    let mut sum = DMatrix::zeros(reference.nrows(), reference.ncols());
    for (b, &w) in bases.iter().zip(weights) {
        if w > 0.0 {
            sum += w * align(b, reference);
        }
    }
    Ok(polar(sum))
}

/// `Log_{a0}(a1)`: the tangent vector at `a0` of the geodesic to `a1`.
pub fn grassmann_log(a0: &DMatrix<f64>, a1: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let m = a0.transpose() * a1;
    let inv = m.try_inverse()?;
    let proj = a1 - a0 * (a0.transpose() * a1);
    let svd = (proj * inv).svd(true, true);
    let (u, vt) = (svd.u.expect("computed"), svd.v_t.expect("computed"));
    let s = DMatrix::from_diagonal(&svd.singular_values.map(f64::atan));
    Some(u * s * vt)
}

/// `Exp_{a0}(gamma)`: the subspace reached from `a0` along `gamma` (orthonormal columns).
pub fn grassmann_exp(a0: &DMatrix<f64>, gamma: &DMatrix<f64>) -> DMatrix<f64> {
    let svd = gamma.clone().svd(true, true);
    let (u, vt) = (svd.u.expect("computed"), svd.v_t.expect("computed"));
    let v = vt.transpose();
    let cos = DMatrix::from_diagonal(&svd.singular_values.map(f64::cos));
    let sin = DMatrix::from_diagonal(&svd.singular_values.map(f64::sin));
    // re-orthonormalize against round-off
    polar(a0 * &v * cos * &vt + u * sin * vt)
}

/// Grassmann-manifold interpolation at the heaviest neighbour (see the [module docs](self)).
pub fn grassmann(bases: &[DMatrix<f64>], weights: &[f64]) -> Result<DMatrix<f64>, InterpolationError> {
    let r0 = check(bases, weights)?;
    let a0 = &bases[r0];
    let mut gamma = DMatrix::zeros(a0.nrows(), a0.ncols());
    for (k, (b, &w)) in bases.iter().zip(weights).enumerate() {
        if w > 0.0 && k != r0 {
            gamma += w * grassmann_log(a0, b).ok_or(InterpolationError::Orthogonal(k))?;
        }
    }
    Ok(grassmann_exp(a0, &gamma))
}

/// Inverse-distance weights `w_k ∝ d_k^(−2)` (exactly 1 on a neighbour at distance 0).
pub fn inverse_distance_weights(distances: &[f64]) -> Vec<f64> {
    if let Some(k) = distances.iter().position(|&d| d <= 0.0) {
        return (0..distances.len()).map(|i| if i == k { 1.0 } else { 0.0 }).collect();
    }
    let w: Vec<f64> = distances.iter().map(|d| d.powi(-2)).collect();
    let s: f64 = w.iter().sum();
    w.into_iter().map(|x| x / s).collect()
}

/// The largest principal angle (radians) between the column spaces of two orthonormal bases:
/// `acos(σ_min(aᵀb))`, 0 for the same subspace.
pub fn largest_angle(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    let s = (a.transpose() * b).singular_values();
    s.iter().copied().fold(f64::INFINITY, f64::min).clamp(-1.0, 1.0).acos()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn orthonormal(n: usize, r: usize, seed: u64) -> DMatrix<f64> {
        let mut s = seed;
        let m = DMatrix::from_fn(n, r, |_, _| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        });
        polar(m)
    }

    #[test]
    fn log_and_exp_are_inverse_and_the_geodesic_ends_on_the_neighbour() {
        let a0 = orthonormal(12, 3, 1);
        let a1 = polar(&a0 + 0.3 * orthonormal(12, 3, 2));
        let g = grassmann_log(&a0, &a1).unwrap();
        // tangent: orthogonal to a0
        assert!((a0.transpose() * &g).norm() < 1e-12);
        let back = grassmann_exp(&a0, &g);
        assert!(largest_angle(&back, &a1) < 1e-7, "{}", largest_angle(&back, &a1));
        assert!(largest_angle(&grassmann_exp(&a0, &(0.0 * g)), &a0) < 1e-7);
    }

    #[test]
    fn interpolation_reproduces_a_neighbour_and_ignores_rotations_and_signs() {
        let a0 = orthonormal(10, 3, 3);
        let a1 = polar(&a0 + 0.4 * orthonormal(10, 3, 4));
        // the same subspace as a1 with shuffled, sign-flipped columns
        let mut q = DMatrix::zeros(3, 3);
        q[(0, 2)] = -1.0;
        q[(1, 0)] = 1.0;
        q[(2, 1)] = -1.0;
        let a1r = &a1 * q;
        for f in [podi, grassmann] {
            let at1 = f(&[a0.clone(), a1r.clone()], &[0.0, 1.0]).unwrap();
            assert!(largest_angle(&at1, &a1) < 1e-7);
            let mid = f(&[a0.clone(), a1r.clone()], &[0.5, 0.5]).unwrap();
            let mid_plain = f(&[a0.clone(), a1.clone()], &[0.5, 0.5]).unwrap();
            assert!(largest_angle(&mid, &mid_plain) < 1e-7, "rotating a basis changes nothing");
            assert!((mid.transpose() * &mid - DMatrix::identity(3, 3)).norm() < 1e-12);
        }
        // Grassmann's midpoint is equidistant from both ends
        let mid = grassmann(&[a0.clone(), a1.clone()], &[0.5, 0.5]).unwrap();
        let (d0, d1) = (largest_angle(&mid, &a0), largest_angle(&mid, &a1));
        assert!((d0 - d1).abs() < 1e-6, "{d0} vs {d1}");
    }

    #[test]
    fn weights_are_checked_and_inverse_distance_is_exact_at_nodes() {
        let a = orthonormal(6, 2, 5);
        assert!(podi(std::slice::from_ref(&a), &[0.5]).is_err());
        assert!(grassmann(&[a.clone(), a.clone()], &[1.0]).is_err());
        assert_eq!(inverse_distance_weights(&[0.3, 0.0, 1.0]), vec![0.0, 1.0, 0.0]);
        let w = inverse_distance_weights(&[1.0, 2.0]);
        assert!((w[0] - 0.8).abs() < 1e-12 && (w[1] - 0.2).abs() < 1e-12);
    }
}
