//! Numerics of vademecum: meshes, materials, finite elements, sparse solvers and scenes.
//!
//! # Layout
//! - [`contact`]: a spherical tool tip against an organ's surface, tracked by a proxy.
//! - [`damage`]: tearing by continuum damage (seed 000 ch. 4): laws, the full-order reference,
//!   the POD–PGD integrator.
//! - [`mesh`]: volume meshes (tet4, hex8), Gmsh and VTK readers, `.vtu`/`.pvd` writers,
//!   boundary surfaces, selections, quality, procedural meshes.
//! - [`material`]: constitutive laws.
//! - [`fem`]: shape functions, cell operators, assembly, loads, the static linear solve.
//! - [`meshless`]: seed 004's element-free Galerkin reference solver (MLS shape functions,
//!   background integration grid).
//! - [`pgd`]: PGD computational vademecums (offline builder, brute-force reference, online
//!   evaluator).
//! - [`rom`]: reduced-order models for large deformations (POD, reduced St Venant–Kirchhoff,
//!   the asymptotic numerical method).
//! - [`pipeline`]: one simulation tick — tool state → contact → the scene's effects → force.
//! - [`solve`]: sparse Cholesky with reusable symbolic analysis; rigid-motion checks.
//! - [`vec3`]: `[f64; 3]` arithmetic for the geometry of cuts, contacts and surfaces.
//! - [`xfem`]: cutting by XFEM (cracking nodes, shifted Heaviside): the full-order reference.
//! - [`check`]: the hard-case suite (every method through its numerically hard inputs).
//! - [`bundle`]: the on-disk form of built vademecums (manifest + `.npy` + checksums).
//! - [`scene`]: scene files (TOML), their validation, and the static problem they describe.
//!
//! This crate does no network or async I/O and spawns no threads on any real-time path;
//! file I/O is limited to reading meshes and scenes and writing results when asked.
#![deny(missing_docs)]
#![allow(non_snake_case)]

pub mod bundle;
pub mod check;
pub mod contact;
pub mod damage;
pub mod dense;
pub mod fem;
pub mod files;
pub mod material;
pub mod memory;
pub mod mesh;
pub mod meshless;
pub mod pgd;
pub mod pipeline;
pub mod rng;
pub mod rom;
pub mod scene;
pub mod solve;
pub mod vec3;
pub mod xfem;
