//! The meshless reference solver of seed 004 (MTLADR): element-free Galerkin with
//! moving-least-squares shape functions on a cloud of nodes, integrated on a background grid.
//!
//! - [`mls`]: MLS shape functions (linear basis, quartic spline weight, disc/ball supports)
//!   and the node cloud with its neighbour search.
//! - [`grid`]: the background grid of integration cells (one Gauss point per cell).
//! - [`efg`]: total Lagrangian EFG forces, essential boundary conditions (Eq. 3.18) and
//!   adaptive dynamic relaxation.
//! - [`mod@reference`]: seed 004's verification problems (the Table 3.2 square).
//!
//! The total Lagrangian neo-Hookean forces, adaptive dynamic relaxation, essential boundary
//! conditions and cutting build on these; a cut's level sets and the visibility criterion are
//! [`crate::geometry::cut`]'s (the XFEM reads the same cuts).

pub mod cutting;
pub mod efg;
pub mod grid;
pub mod mls;
pub mod organ;
pub mod reference;

pub use mls::{MlsError, NodeCloud, ShapeValues};
