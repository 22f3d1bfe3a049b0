//! PGD computational vademecums (seed 000, chapter 2): the displacement of an organ for a unit
//! load at any node of its accessible surface, in separated form
//!
//! `u(x; s) ≈ Σ_{k=1}^{N} F_k(x) · G_k(s)`   (Eq. 2.6)
//!
//! # Discrete problem
//! The parameter s runs over the load states `p = 3j + d`: a unit force in direction d at the
//! j-th accessible node (the direction is folded into the parameter). With `F_L` the matrix
//! whose column p is that unit force (Eq. 2.17, `G_L = I`), the exact parametric solution is
//! `U = K⁻¹ F_L` (one column per load state) — the brute-force reference of [`brute`].
//!
//! # Greedy enrichment with an alternating fixed point (Alg. 2.1)
//! Given N modes, the next pair (R, S) solves, alternately, with the parameter "mass" `M_S = I`:
//!
//! - R-step (Eq. 2.23): `K R (SᵀS) = F_L S − Σ_i K F_i (G_iᵀ S)`, i.e.
//!   `R = [K⁻¹(F_L S) − Σ_i F_i (G_iᵀ S)] / (SᵀS)` — one solve with the single factorization of K;
//! - S-step (Eq. 2.22): `S (RᵀKR) = F_Lᵀ R − Σ_i G_i (F_iᵀ K R)`.
//!
//! The fixed point stops when the rank-one product `R Sᵀ` changes by less than ε_F
//! (relative, Frobenius) or after the iteration cap; enrichment stops when the new mode's
//! energy `‖R‖_K ‖S‖` falls below ε_R times the first mode's, or at the mode cap. Because K is
//! symmetric positive definite, each (R, S) is the best rank-one correction of the residual
//! in the energy norm, so the error decreases monotonically.
//!
//! # Layout
//! - [`build`]: the greedy builder ([`build::build`]) and its parameters and report.
//! - [`brute`]: the brute-force parametric solution and error measures.
//! - [`compress`]: recompression of the modes by QR + SVD (an orthonormal basis, fewer modes
//!   at equal error).
//! - [`vademecum`]: the online evaluator (Eq. 2.6 at a load state, local compliances).
//! - [`coupled`]: several tools in contact at once (the forces solved together).
//!
//! An organ's whole build (modes from the greedy PGD or from sharded snapshots, and every
//! other method's stage) is [`crate::offline`]'s; the bundle it writes is [`crate::bundle`]'s.

pub mod brute;
pub mod build;
pub mod compress;
pub mod coupled;
pub mod vademecum;

pub use build::{LoadVector, PgdInfo, PgdParams, SeparatedSolution};
pub use vademecum::{Footprint, Vademecum};
