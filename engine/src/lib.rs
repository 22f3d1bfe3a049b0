//! Numerics of vademecum: meshes, finite elements, solvers, every reduced method of the seeds,
//! scenes, bundles, and the tick pipeline that serves them.
//!
//! # Layers (a module imports only from its own layer or below; no circles)
//!
//! 1. **Core** — what every method stands on:
//!    - [`mesh`]: volume meshes (tet4, hex8), their shape functions, Gmsh and VTK readers,
//!      `.vtu`/`.pvd` writers, boundary surfaces, selections, quality, procedural meshes.
//!    - [`material`]: constitutive laws (linear, hyperelastic).
//!    - [`geometry`]: `[f64; 3]` arithmetic and cuts as level sets (seed 004's visibility).
//!    - [`fem`]: cell operators, assembly, loads, the static solves, and [`fem::OrganModel`],
//!      the finite-element problem an organ becomes.
//!    - [`solve`]: sparse Cholesky of any lower triangle, reused symbolic analysis;
//!      rigid-motion checks.
//!    - [`contact`]: a spherical tool tip against an organ's surface, tracked by a proxy.
//!    - [`dense`], [`rng`], [`memory`], [`files`]: small in-place Cholesky, a repeatable
//!      generator, allocation sizes, bounded reading of the files a user names.
//! 2. **Methods**, side by side, each with its offline and online halves:
//!    - [`pgd`]: PGD computational vademecums (seed 000 ch. 2): the greedy builder, the
//!      brute-force reference, the online evaluator.
//!    - [`rom`]: large deformations (seed 001): POD, reduced St Venant–Kirchhoff, the
//!      asymptotic numerical method, the palpation lattice and its full-order check.
//!    - [`xfem`]: cutting by XFEM with cracking nodes (seed 000 ch. 3, seed 003), full-order and
//!      reduced, co-rotational, visual meshes.
//!    - [`damage`]: tearing by continuum damage (seed 000 ch. 4): laws, the full-order
//!      reference, the POD–PGD integrator.
//!    - [`meshless`]: seed 004's element-free Galerkin reference solver with cutting.
//! 3. **Above the methods** — what uses them:
//!    - [`scene`]: scene files (TOML), their validation, the organs they describe as
//!      [`fem::OrganModel`]s and the tearing problem.
//!    - [`bundle`]: the on-disk form of built vademecums (manifest + `.npy` + checksums) and
//!      [`bundle::LoadedBundle`], the runtime form every session uses.
//!    - [`offline`]: every method's offline build of an organ into a bundle, and shards.
//!    - [`pipeline`]: one simulation tick — tool state → contact → the scene's effects → force.
//!    - [`study`]: the served answers against the full-order model (what accuracy costs).
//!    - [`check`]: the hard-case suite (every method through its numerically hard inputs).
//!
//! A new method goes in layer 2 beside the others (its offline stage joins [`offline`], its
//! arrays [`bundle`]); a new effect is a [`pipeline`] effect over the methods it serves.
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
pub mod geometry;
pub mod material;
pub mod memory;
pub mod mesh;
pub mod meshless;
pub mod offline;
pub mod pgd;
pub mod pipeline;
pub mod rng;
pub mod rom;
pub mod scene;
pub mod solve;
pub mod study;
pub mod xfem;
