//! Cutting by the extended finite element method (seed 000 chapter 3): Heaviside-enriched
//! nodes around a cut, in the cracking-node form, on tetrahedra and hexahedra.
//!
//! `u = u_cont + u_disc`: the continuous part on the standard shape functions (or, online, on
//! the PGD modes), the discontinuous part `Σ_{I∈S} N_I(x) H̃_I(x) q_I` on the nodes `S` a cut
//! has cracked, with the shifted Heaviside `H̃_I(x) = H(φ_I(x)) − H(φ_I(x_I))` (seed 003
//! Eqs. 4–6), which vanishes at the node so that `u_a` stays the displacement of node a.
//!
//! # Layout
//! - [`blade`]: the scalpel's blade, the split of its force and the cut criterion (§3.4).
//! - [`subcell`]: cut planes, splitting a cell into sub-tetrahedra on each side, quadrature.
//! - [`enrichment`]: from the swept blade surface to cut cells and cracked nodes (one plane per
//!   node, the cracking-node method), the sliver rule.
//! - [`identity`]: the reference of a cut on cell faces (the mesh with its cut nodes duplicated).
//! - [`online`]: the scalpel cutting as it moves: the criterion, the swept surface, the cells
//!   it crosses, the model bordered.
//! - [`progressive`]: semi-progressive cutting (seed 003 §3.3): the blade's swept quads
//!   crossed with the cells' edges, a cell cut once crossed entirely.
//! - [`partial`]: the swept surface inside cells the blade entered but has not cut, shown
//!   (never simulated) so the incision follows the blade continuously.
//! - [`reduced`]: the online model: PGD modes as a Ritz basis (PRB, SRB) bordered with the
//!   enriched nodes, the factor updated as the cut grows.
//! - [`corotational`]: co-rotational XFEM (seed 003 §3.1): each side of a cut cell turns with
//!   its own rotation, so rotating flaps keep their volume.
//! - [`system`]: the full-order XFEM system (the reference of the reduced online models), its
//!   detached pieces, and the static solve.
//! - [`tip`]: a cut that ends inside a cell — the crack-tip (branch-function) enrichment along
//!   the blade's edge, full order (issue 47).
//! - [`view`]: the mesh split along a cut, for viewers and recordings.
//! - [`visual`]: visual surfaces embedded in the tetrahedra, following each side of a cut.
//! - [`visual_split`]: a visual surface split along a cut and closed by the cut faces.

pub mod accuracy;
pub mod blade;
pub mod corotational;
pub mod enrichment;
pub mod identity;
pub mod online;
pub mod partial;
pub mod progressive;
pub mod reduced;
pub mod subcell;
pub mod system;
pub mod tip;
pub mod view;
pub mod visual;
pub mod visual_split;

pub use enrichment::{Detached, Enrichment, EnrichmentError, Front, XfemParams};
pub use subcell::Plane;
pub use system::{XfemError, XfemSolution};
