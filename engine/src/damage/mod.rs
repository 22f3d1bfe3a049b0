//! Tearing by continuum damage (seed 000 chapter 4): Simó's isotropic damage at the
//! integration points, the explicit incremental finite-element reference (Alg. 4.1) beside the
//! equilibrium-iterated one, and the POD–PGD vademecum used as a time integrator (Alg. 4.2).
//!
//! # Layout
//! - [`law`]: the damage laws — the seed's saturating exponential (Eq. 4.3) and the threshold
//!   with exponential softening, regularised by the element size —, their `h = −g′`, the
//!   exact dissipation, the residual stiffness.
//! - [`points`]: the integration points of a mesh (B̄ on hexahedra), their strains, stresses,
//!   forces and stiffness with a damage field.
//! - [`model`]: a tearing problem — mesh, supports, points, load increment, schedule.
//! - [`reference`](mod@reference): the full-order runs: explicit (h = 0 or the consistent tangent) and Newton.
//! - [`pod`]: the POD basis of damage snapshots and the projection `ξ = υᵀg`.
//! - [`vademecum`]: the PGD vademecum `∆u(ξ₁ … ξ_q)` over the POD coefficients (§4.5.4).
//! - [`online`]: the POD–PGD integrator (Alg. 4.2): the seed's simplified model (h = 0) and
//!   the full one (h ≠ 0, the vademecum's modes as a Ritz basis with the loading points'
//!   rank-one tangent terms).
//! - [`sites`]: where else the grasper can take hold — grasp sites spread over the tearable
//!   surface, each with its own load and offline stage.
//! - [`build`]: the offline stage — snapshots, POD, vademecum, Ritz form, validation.
//! - [`store`]: the offline stage's arrays, as a bundle stores them.
//!
//! A scene's tearable organ becomes a [`model::TearModel`] in `crate::scene::tearing`.

pub mod build;
pub mod law;
pub mod model;
pub mod online;
pub mod pod;
pub mod points;
pub mod reference;
pub mod sites;
pub mod store;
pub mod vademecum;

pub use law::{DamageLaw, LawError, PointState};
pub use model::TearModel;
pub use reference::{RunSettings, Scheme, Tangent, TearRun};
