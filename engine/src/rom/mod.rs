//! Reduced-order models for large deformations (seed 001): POD bases, the St Venant–Kirchhoff
//! model in reduced coordinates, and the asymptotic numerical method on it.
//!
//! - [`pod`]: snapshots → SVD → an orthonormal basis `A` kept by an energy criterion; `AᵀKA`.
//! - [`svk`]: the exact reduced internal force of St Venant–Kirchhoff as polynomial tensors
//!   (`O(r⁴)` online, whatever the mesh).
//! - [`anm`]: asymptotic expansions of the equilibrium branch in reduced coordinates with one
//!   tangent per step, their validity radius, and continuation.
//! - [`interpolate`]: bases between load positions — PODI (Procrustes-aligned) and the
//!   Grassmann manifold's log/exp maps.
//! - [`lattice`]: reduced models on a lattice of load positions and their interpolation
//!   off it, against the full model.
//! - [`lattice_check`]: a palpation lattice against the full model's force–depth laws at
//!   nodes off it (what `build --target-error` holds a lattice to).
//! - [`palpation`]: the online large-deformation model — ANM paths on a lattice of surface
//!   positions, served as a nonlinear force–depth law under the tool.
//! - [`podi_online`]: seed 001 §5 online — a model at a new position from its neighbours'
//!   stored models (PODI basis, interpolated tangent, load and nonlinear terms), mesh-free.
//! - [`study`]: ANM-POD against full Newton on a scene's load case (seed 001 §6).
//! - [`crate::dense`] (outside this module): the small in-place Cholesky of the online solves.

pub mod anm;
pub mod interpolate;
pub mod lattice;
pub mod lattice_check;
pub mod palpation;
pub mod pod;
pub mod podi_online;
pub mod study;
pub mod svk;

pub use anm::{AnmError, AnmParams, Path, Series};
pub use pod::{Pod, PodCriterion, PodError};
pub use svk::{ReduceError, ReducedSvk};

/// The mean displacement of `nodes` along the unit vector `direction` (`u` flat, 3 per node):
/// "the displacement under the load" that the studies and the served law read.
pub(crate) fn mean_along(u: &[f64], nodes: &[usize], direction: [f64; 3]) -> f64 {
    nodes
        .iter()
        .map(|&i| (0..3).map(|k| u[3 * i + k] * direction[k]).sum::<f64>())
        .sum::<f64>()
        / nodes.len().max(1) as f64
}

/// `v / |v|`, or `None` for a zero or non-finite vector.
pub(crate) fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    (n > 0.0 && n.is_finite()).then(|| v.map(|x| x / n))
}
