//! The meshless reference solver of seed 004 (MTLADR): element-free Galerkin with
//! moving-least-squares shape functions on a cloud of nodes, integrated on a background grid.
//!
//! - [`mls`]: MLS shape functions (linear basis, quartic spline weight, disc/ball supports)
//!   and the node cloud with its neighbour search.
//! - [`grid`]: the background grid of integration cells (one Gauss point per cell).
//!
//! The total Lagrangian neo-Hookean forces, adaptive dynamic relaxation, essential boundary
//! conditions and cutting build on these.

pub mod grid;
pub mod mls;

pub use mls::{MlsError, NodeCloud, ShapeValues};
