//! Every method's offline build: from a scene's organ to a vademecum bundle on disk. Assemble
//! K once, factor it once, build the PGD modes (or take them from snapshots, [`shard`]),
//! optionally measure them against the brute-force solution, recompress; then the stages the
//! scene's effects need — the large-deformation lattice, the cutting basis, the tearing
//! stages — and write the bundle. The loaded, runtime form of a bundle is
//! [`crate::bundle::LoadedBundle`].
//!
//! This module sits above the methods (`pgd`, `rom`, `xfem`, `damage`) and the scene it
//! builds from; the methods never import it.

pub mod shard;

use std::borrow::Cow;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use crate::bundle::{self, ArrayData, BundleError, CutBasis, KIND, Manifest, TEAR_ARRAYS, tear_prefix};
use crate::damage::store::TearArrays;
use crate::fem::OrganModel;
use crate::fem::assembly::{self, AssemblyError, DofMap, SymmetricMatrix, SymmetricPattern};
use crate::pgd::build::{self, PgdInfo, PgdParams, SeparatedSolution};
use crate::pgd::vademecum::{LocalCompliance, Vademecum};
use crate::pgd::{brute, compress};
use crate::rom::palpation::{AnmLattice, AnmLatticeParams};
use crate::rom::study::StudyError;
use crate::scene::{Scene, SceneError};
use crate::solve::{self, Cholesky, SolveError};
use crate::xfem::reduced::{Discontinuous, ReducedCut, RitzBasis};

/// How to build.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildOptions {
    /// Stopping criteria of the greedy enrichment.
    pub params: PgdParams,
    /// Target relative L2 error of the displacement field over all load states. The build
    /// measures the error of every prefix of the modes against the exact solution (streamed
    /// in the blocked pass it makes anyway for the exact contact compliances) and keeps the
    /// fewest modes that meet it.
    pub tolerance: f64,
    /// Recompress the greedy modes by QR + SVD before truncating (the truncated SVD is the
    /// best basis of its size, so this never keeps more modes).
    pub recompress: bool,
    /// Radius (m) of the tool footprint over which each unit load is spread (0: point loads).
    pub load_radius: f64,
    /// Also build the large-deformation lattice, for the organs that deform largely
    /// ([`Scene::organ_large`]; `Some` when any does).
    pub large: Option<AnmLatticeParams>,
    /// Refuse an organ whose direct solve is estimated to need more than this many bytes
    /// ([`crate::solve::memory`]); `None`: no limit.
    pub max_memory: Option<u64>,
    /// Keep the fewest tearing modes whose calibrated force error meets this (relative;
    /// [`crate::damage::build::TearSettings::target_force_error`]); `None`: all the modes the
    /// scene's `fidelity.tearing` makes.
    pub tear_target_error: Option<f64>,
    /// Build the fewest lattice positions whose served force's largest error against full
    /// Newton at nodes off the lattice meets this (relative; [`AnmLattice::build_for_target`],
    /// [`crate::rom::lattice_check::lattice_error`]); `None`: the scene's
    /// `fidelity.large.positions`.
    pub large_target_error: Option<f64>,
    /// Keep the largest sliver threshold whose local-fields force stays within this of the
    /// full XFEM's on the scene's cut ([`crate::xfem::accuracy::sliver_for_target`]); `None`:
    /// the scene's `fidelity.xfem.sliver`.
    pub cut_target_error: Option<f64>,
}

impl BuildOptions {
    /// What a scene's `[fidelity.pgd]` asks for, with the load footprint of its probe.
    pub fn for_scene(scene: &Scene, recompress: bool) -> Self {
        let f = scene.spec.fidelity.pgd;
        Self {
            params: PgdParams {
                global_tolerance: f.global_tolerance,
                enrichment_tolerance: f.enrichment_tolerance,
                max_modes: f.max_modes,
                max_iterations: f.max_iterations,
                block: f.block,
            },
            tolerance: f.tolerance,
            recompress,
            load_radius: probe_radius(scene),
            large: scene.any_large().then(|| {
                let l = scene.spec.fidelity.large;
                AnmLatticeParams {
                    positions: l.positions,
                    max_force: l.max_force,
                    patch_radius: probe_radius(scene),
                    load_steps: l.load_steps,
                    modes: l.modes,
                    order: l.order,
                }
            }),
            max_memory: None,
            tear_target_error: None,
            large_target_error: None,
            cut_target_error: None,
        }
    }
}

/// A stage of [`build_organ`], for progress displays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BuildStage {
    /// Assembling K.
    Assembly,
    /// Factoring K.
    Factorization,
    /// Mode `k` done, with its relative energy.
    Mode(usize, f64),
    /// Recompressing the modes.
    Recompression,
    /// Exact columns done out of total (contact compliances and error measurement).
    Exact(usize, usize),
    /// Large-deformation lattice positions done out of total.
    Lattice(usize, usize),
    /// Full-order laws for a lattice's target error done out of total
    /// ([`crate::rom::lattice_check::LATTICE_CHECK_NODES`]).
    LatticeCheck(usize, usize),
    /// The Ritz basis of a cutting session.
    CutBasis,
    /// The bare enrichment's force-error calibration: full XFEM solves at cracked nodes done
    /// out of total ([`crate::xfem::accuracy::bare_force_error`]).
    CutCalibration(usize, usize),
    /// Tearing's offline stage (references, POD, vademecum) of grasp site `site` (0: the
    /// scene's grasp) out of `sites`: what, and the fraction done.
    Tearing {
        /// The grasp site (0: the scene's).
        site: usize,
        /// Grasp sites in all.
        sites: usize,
        /// The stage.
        what: &'static str,
        /// Fraction done.
        fraction: f64,
    },
}

/// Why a build failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BuildError {
    /// The scene's organ is unusable.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A cell operator failed.
    #[error(transparent)]
    Assembly(#[from] AssemblyError),
    /// The stiffness could not be factored.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The constraints leave rigid motions free.
    #[error("the fixed region does not stop the body from moving: free {}", .0.join("; "))]
    RigidMotion(Vec<String>),
    /// No accessible node can carry a load.
    #[error("no accessible surface node is free to move, so there is nothing to build; check the accessible and fixed regions")]
    NoLoadStates,
    /// The bundle could not be written.
    #[error(transparent)]
    Bundle(#[from] BundleError),
    /// The large-deformation lattice could not be built.
    #[error("large-deformation lattice: {0}")]
    Large(#[from] StudyError),
    /// The cutting session's Ritz basis could not be built.
    #[error("cutting: {0}")]
    Cutting(String),
    /// The snapshots given to a build do not fit the organ.
    #[error("snapshots: {0}")]
    Snapshots(String),
    /// Tearing's offline stage failed.
    #[error("tearing: {0}")]
    Tearing(String),
}

/// What a build did (also stored in the bundle's manifest).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BuildReport {
    /// Organ name.
    pub organ: String,
    /// Mesh nodes.
    pub nodes: usize,
    /// Free equations.
    pub equations: usize,
    /// Loadable surface nodes.
    pub load_nodes: usize,
    /// Radius of the load footprint (m).
    pub load_radius: f64,
    /// Mean number of nodes per load patch.
    pub mean_patch_nodes: f64,
    /// Load states (3 per loadable node).
    pub load_states: usize,
    /// Where the modes came from: "pgd" (the greedy PGD), "snapshots" (the truncated SVD of
    /// the exact responses, solved in this build), "snapshots (merged)" (solved by shards).
    pub modes_from: &'static str,
    /// The greedy builder's report (for snapshots: one "mode" per load state, no iterations).
    pub greedy: PgdInfo,
    /// Modes kept in the bundle.
    pub modes: usize,
    /// Whether the kept modes are the recompressed ones.
    pub recompressed: bool,
    /// The target relative L2 error.
    pub tolerance: f64,
    /// Whether the kept modes meet it (false: the greedy stopped, by ε_R or the mode cap,
    /// before reaching it, and every mode is kept).
    pub target_met: bool,
    /// Relative L2 error of all the greedy modes against the exact solution.
    pub error_greedy: f64,
    /// Relative L2 error of the kept modes against the exact solution.
    pub error: f64,
    /// Error against the exact solution as modes are added (`(modes, error)`, sampled, in
    /// the order the bundle stores them).
    pub error_curve: Vec<(usize, f64)>,
    /// Assembly time (s).
    pub assembly_s: f64,
    /// Symbolic + numeric factorization time (s).
    pub factorization_s: f64,
    /// Greedy PGD time (s), including its solves.
    pub pgd_s: f64,
    /// Recompression time (s).
    pub recompress_s: f64,
    /// Time of the brute-force solution alone (s): one blocked pass of solves over all load
    /// states with the same factorization.
    pub brute_force_s: f64,
    /// Time of the blocked pass over all load states that computes the exact local
    /// compliances and measures the error of the modes (s; includes the brute-force solves).
    pub exact_pass_s: f64,
    /// Exact local compliance blocks stored (neighbouring load-node pairs).
    pub local_blocks: usize,
    /// Bytes of the modes kept, as stored in the bundle (f32).
    pub modes_bytes: usize,
    /// Bytes of the full parametric solution (all dofs × all load states, f64).
    pub full_bytes: usize,
    /// Positions of the large-deformation lattice (0: none built).
    pub anm_positions: usize,
    /// Seconds spent on it.
    pub anm_s: f64,
    /// What [`BuildOptions::large_target_error`] asked of the lattice and what the build kept.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub anm_target: Option<crate::rom::palpation::LatticeTarget>,
    /// What was built for a cutting session (scenes with `effects.cutting`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cut: Option<CutReport>,
    /// What was built for tearing (the tearable organ of a scene with `effects.tearing`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tear: Option<crate::damage::build::TearBuildReport>,
    /// What was built for the grasp sites beside the scene's (`[fidelity.tearing]
    /// grasp_sites`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tear_sites: Vec<GraspSiteReport>,
}

/// A grasp site beside the scene's and what its offline stage built.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GraspSiteReport {
    /// The grasped nodes' centre (m).
    pub centre_m: [f64; 3],
    /// The pull's direction (the surface's outward normal there).
    pub pull_direction: [f64; 3],
    /// Nodes grasped.
    pub nodes: usize,
    /// Its offline stage.
    pub build: crate::damage::build::TearBuildReport,
}

/// What a build stored for a cutting session.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CutReport {
    /// What carries the discontinuous part (`fidelity.xfem.discontinuous`).
    pub discontinuous: Discontinuous,
    /// The Ritz basis (`fidelity.xfem.basis`).
    pub basis: RitzBasis,
    /// Directions of the K-orthonormal basis stored (0: none needed — with local fields a
    /// session adds the cut's compliance to the vademecum's own and needs no basis).
    pub basis_size: usize,
    /// The sliver rule a session of this bundle cuts with (the scene's, or what a target
    /// chose: [`BuildOptions::cut_target_error`]).
    pub sliver: f64,
    /// What the target asked and what the build kept (`None` without one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target: Option<crate::xfem::accuracy::SliverTarget>,
    /// With bare enrichment, the largest relative error of its force against the full XFEM's
    /// on the scene's cut ([`crate::xfem::accuracy::bare_force_error`]): the relative error
    /// estimate a session attaches to the cut organ's forces. `None` with local fields (exact).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bare_force_error: Option<f64>,
    /// Seconds spent on it.
    pub seconds: f64,
}

/// The pre-planned cuts of the cut organ ([`Scene::cut_organ`]), the organ the cutting stage
/// calibrates against.
fn scene_cuts(scene: &Scene) -> Result<Vec<crate::geometry::cut::Cut>, BuildError> {
    scene.planned_cuts().map_err(|e| BuildError::Cutting(e.to_string()))
}

/// Everything a build produced.
#[derive(Debug, Clone)]
pub struct Built {
    /// The online vademecum.
    pub vademecum: Vademecum,
    /// The report.
    pub report: BuildReport,
    /// The organ model it was built from.
    pub model: OrganModel,
    /// The large-deformation lattice, when the scene asks for it.
    pub anm: Option<AnmLattice>,
    /// The cutting session's Ritz basis, when the scene cuts with bare enrichment.
    pub cut_basis: Option<CutBasis>,
    /// Tearing's offline arrays, for the tearable organ of a tearing scene: the scene's
    /// grasp, then the other grasp sites (empty: no tearing).
    pub tear: Vec<TearArrays>,
}

/// Load nodes of an organ: accessible surface nodes with at least one free component.
pub fn load_nodes(model: &OrganModel) -> Vec<usize> {
    model
        .accessible_nodes
        .iter()
        .copied()
        .filter(|&n| (0..3).any(|i| !model.problem.constrained[3 * n + i]))
        .collect()
}

/// The radius (m) of the scene's first probe tool, or 0 (point loads) when it has none.
pub fn probe_radius(scene: &Scene) -> f64 {
    scene
        .spec
        .tools
        .iter()
        .find_map(|t| match t {
            crate::scene::schema::ToolSpec::Probe { radius, .. } => Some(*radius),
            _ => None,
        })
        .unwrap_or(0.0)
}

/// The footprint of a tool of radius `r` pressing at each load node: the surface nodes
/// within `r` of it, weighted by their share of surface area times a hat `(1 − d/r)`, and
/// normalised to sum to one (the node alone when `r` is zero or no neighbour is that close).
///
/// A point load on a finite-element mesh has a compliance that grows without bound as the
/// mesh is refined (the elastic response to a point force is singular), and its responses
/// are not low-rank: on the built-in organ, 828 of 927 modes are needed for 1e-3 (see
/// BENCHMARKS.md). Spreading the unit load over the probe's tip area is what the tool does,
/// makes the contact stiffness mesh-independent, and makes the responses compressible.
pub fn load_patches(model: &OrganModel, loads: &[usize], radius: f64) -> Vec<(Vec<usize>, Vec<f64>)> {
    let mesh = &model.mesh;
    let mut area = vec![0.0; mesh.n_nodes()];
    for t in model.boundary.triangles() {
        let (a, _) = crate::mesh::boundary::triangle_area_normal(mesh, t);
        for n in t {
            area[n] += a / 3.0;
        }
    }
    let surface = model.boundary.nodes();
    loads
        .iter()
        .map(|&s| {
            let ps = mesh.nodes[s];
            let mut nodes = vec![s];
            let mut w = vec![area[s].max(f64::MIN_POSITIVE)];
            if radius > 0.0 {
                for &a in &surface {
                    if a == s {
                        continue;
                    }
                    let d = (0..3).map(|k| (mesh.nodes[a][k] - ps[k]).powi(2)).sum::<f64>().sqrt();
                    if d < radius {
                        nodes.push(a);
                        w.push(area[a] * (1.0 - d / radius));
                    }
                }
            }
            let total: f64 = w.iter().sum();
            (nodes, w.into_iter().map(|x| x / total).collect())
        })
        .collect()
}

/// The load vector of each load state `3j + d`: unit force in direction d over patch j.
pub fn load_vectors(patches: &[(Vec<usize>, Vec<f64>)], dofs: &DofMap) -> Vec<build::LoadVector> {
    patches
        .iter()
        .flat_map(|(nodes, w)| {
            (0..3).map(move |d| {
                nodes
                    .iter()
                    .zip(w)
                    .filter_map(|(&a, &x)| dofs.eq(3 * a + d).map(|e| (e, x)))
                    .collect()
            })
        })
        .collect()
}

/// How far apart (in load radii) two load nodes may be and still get an exact compliance
/// block between them: two tools' tips of radius r are at least 2r apart, and up to about
/// 5r the modes carry the block between them worst (measured on the built-in organ: 2 % at
/// 14 mm with r = 4 mm, at most 0.25 % beyond 20 mm; BENCHMARKS.md, "Two tools on one organ").
pub const COUPLING_REACH_RADII: f64 = 5.0;

/// Neighbours of each load node among the load nodes: itself, every load node sharing a
/// surface triangle with it, and every load node within `reach` (m) of it (sorted).
fn load_neighbours(model: &OrganModel, loads: &[usize], reach: f64) -> Vec<Vec<usize>> {
    let mut index = vec![usize::MAX; model.mesh.n_nodes()];
    for (j, &n) in loads.iter().enumerate() {
        index[n] = j;
    }
    let nodes = &model.mesh.nodes;
    let near = |a: usize, b: usize| (0..3).map(|k| (nodes[a][k] - nodes[b][k]).powi(2)).sum::<f64>() <= reach * reach;
    let mut nbrs: Vec<Vec<usize>> = (0..loads.len())
        .map(|j| {
            (0..loads.len())
                .filter(|&b| b == j || (reach > 0.0 && near(loads[j], loads[b])))
                .collect()
        })
        .collect();
    for t in model.boundary.triangles() {
        for &a in &t {
            for &b in &t {
                if index[a] != usize::MAX && index[b] != usize::MAX {
                    nbrs[index[a]].push(index[b]);
                }
            }
        }
    }
    for l in nbrs.iter_mut() {
        l.sort_unstable();
        l.dedup();
    }
    nbrs
}

/// Patch average of component i of a solution over load patch `b`.
fn patch_value(u: &[f64], dofs: &DofMap, patch: &(Vec<usize>, Vec<f64>), i: usize) -> f64 {
    patch
        .0
        .iter()
        .zip(&patch.1)
        .map(|(&a, &w)| dofs.eq(3 * a + i).map_or(0.0, |e| w * u[e]))
        .sum()
}

/// Assembles `K_ff` of an organ over its free degrees of freedom and factors it once (with
/// progress stages and timings): what every vademecum computation starts from.
#[allow(clippy::type_complexity)]
pub fn stiffness(model: &OrganModel, on: &mut dyn FnMut(BuildStage)) -> Result<(DofMap, SymmetricMatrix, Cholesky, f64, f64), BuildError> {
    on(BuildStage::Assembly);
    let clock = Instant::now();
    let dofs = DofMap::new(&model.problem.constrained);
    let pattern = Arc::new(SymmetricPattern::for_locking(&model.mesh, &dofs, model.locking));
    let mut rhs = vec![0.0; dofs.n_free()];
    let mut k = assembly::assemble_stiffness(
        &model.mesh,
        &model.materials,
        model.locking,
        &dofs,
        pattern,
        &model.problem.prescribed,
        &mut rhs,
    )?;
    assembly::add_springs(&mut k, &dofs, &model.problem.springs);
    let assembly_s = clock.elapsed().as_secs_f64();
    on(BuildStage::Factorization);
    let clock = Instant::now();
    let chol = Cholesky::factor(&k)?;
    Ok((dofs, k, chol, assembly_s, clock.elapsed().as_secs_f64()))
}

/// Where a build's separated solution `u(x, s) ≈ Σ F_k(x) G_k(s)` comes from.
#[derive(Debug, Clone, Copy)]
pub enum ModesFrom<'a> {
    /// The greedy PGD (seed 000, Alg. 2.1): one mode at a time, each a fixed point alternating between
    /// space and load position — sequential, since every mode corrects the ones before.
    Pgd,
    /// The exact responses `U = K⁻¹ F_L` of every load state (the snapshots), solved here and
    /// recompressed (QR + SVD: the truncated SVD of `U`, the best basis of each size). Its
    /// columns are independent, so it shards ([`solve_shard`]).
    Snapshots,
    /// The truncated SVD of exact responses given (`n_free × load states`, column-major): the
    /// shards of a sharded build, merged — the same bundle as [`ModesFrom::Snapshots`].
    Given(&'a [f64]),
}

/// Builds organ `index` of `scene` with the greedy PGD.
pub fn build_organ(scene: &Scene, index: usize, opts: &BuildOptions, on: &mut dyn FnMut(BuildStage)) -> Result<Built, BuildError> {
    build_organ_from(scene, index, opts, ModesFrom::Pgd, on)
}

/// Shard `of` of the exact responses `U = K⁻¹ F_L` of organ `index` of `scene`: the columns of
/// its load states ([`shard_range`]; `n_free × range.len()`, column-major), solved in the same
/// blocks of columns as a single-process build, so a sharded build merged is the same bundle
/// to the bit.
pub fn solve_shard(
    scene: &Scene,
    index: usize,
    opts: &BuildOptions,
    of: shard::ShardOf,
    on: &mut dyn FnMut(BuildStage),
) -> Result<ShardColumns, BuildError> {
    let model = scene.organ_model_within(index, opts.max_memory)?;
    let LoadStates { dofs, chol, load_eqs, .. } = load_states(&model, opts, on)?;
    let total = load_eqs.len();
    let range = shard_range(total, of.index, of.count);
    let n = dofs.n_free();
    let mut u = vec![0.0; n * range.len()];
    brute::solve_blocks_in(&chol, &load_eqs, range.clone(), &mut |start, block| {
        let at = (start - range.start) * n;
        u[at..at + block.len()].copy_from_slice(block);
        on(BuildStage::Exact(start + block.len() / n, total));
    });
    Ok(ShardColumns {
        u,
        range,
        load_states: total,
        n_free: n,
    })
}

/// The columns a shard solved ([`solve_shard`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ShardColumns {
    /// `U`'s columns of the shard's load states (`n_free × range.len()`, column-major).
    pub u: Vec<f64>,
    /// Its load states.
    pub range: std::ops::Range<usize>,
    /// Load states of the organ in all.
    pub load_states: usize,
    /// The organ's free equations (rows of `U`), also for a shard with no load state: the
    /// merge checks every shard against the first.
    pub n_free: usize,
}

/// What every build of an organ starts from, a whole one or a shard: its load states and its
/// stiffness, assembled and factored.
struct LoadStates {
    /// The nodes a tool may press (three load states each).
    loads: Vec<usize>,
    dofs: DofMap,
    k: SymmetricMatrix,
    chol: Cholesky,
    assembly_s: f64,
    factorization_s: f64,
    /// Each load node's patch (nodes, weights) at the build's load radius.
    patches: Vec<(Vec<usize>, Vec<f64>)>,
    /// The load vector of every load state.
    load_eqs: Vec<build::LoadVector>,
}

/// The load states and the factored stiffness of `model`, refusing an organ with a free rigid
/// motion (K singular) or no node a tool may press.
fn load_states(model: &OrganModel, opts: &BuildOptions, on: &mut dyn FnMut(BuildStage)) -> Result<LoadStates, BuildError> {
    let free = solve::free_rigid_motions(&model.mesh.nodes, &model.problem.supported());
    if !free.is_empty() {
        return Err(BuildError::RigidMotion(free));
    }
    let loads = load_nodes(model);
    if loads.is_empty() {
        return Err(BuildError::NoLoadStates);
    }
    let (dofs, k, chol, assembly_s, factorization_s) = stiffness(model, on)?;
    let patches = load_patches(model, &loads, opts.load_radius);
    let load_eqs = load_vectors(&patches, &dofs);
    Ok(LoadStates {
        loads,
        dofs,
        k,
        chol,
        assembly_s,
        factorization_s,
        patches,
        load_eqs,
    })
}

/// Which load states shard `i` of `n` (0-based) solves: contiguous ranges of whole blocks of
/// [`brute::BLOCK`] columns, as even as whole blocks allow.
pub fn shard_range(load_states: usize, i: usize, n: usize) -> std::ops::Range<usize> {
    let blocks = load_states.div_ceil(brute::BLOCK);
    let at = |k: usize| (blocks * k / n * brute::BLOCK).min(load_states);
    at(i)..at(i + 1)
}

/// Builds organ `index` of `scene`, its modes from `from`.
pub fn build_organ_from(
    scene: &Scene,
    index: usize,
    opts: &BuildOptions,
    from: ModesFrom<'_>,
    on: &mut dyn FnMut(BuildStage),
) -> Result<Built, BuildError> {
    let model = scene.organ_model_within(index, opts.max_memory)?;
    let mesh = &model.mesh;
    let LoadStates {
        loads,
        dofs,
        k,
        chol,
        assembly_s,
        factorization_s,
        patches,
        load_eqs,
    } = load_states(&model, opts, on)?;
    let n_free = dofs.n_free();
    let (snapshots, sep, greedy) = initial_modes(from, &k, &chol, &load_eqs, n_free, &opts.params, on)?;
    let snapshots = snapshots.as_deref();
    let pgd_s = greedy.time_s;
    let clock = Instant::now();
    // snapshots are always recompressed: kept raw they would be one mode per load state
    let recompressed = (opts.recompress || snapshots.is_some()) && sep.modes > 0;
    let mut candidate = if recompressed {
        on(BuildStage::Recompression);
        compress::recompress(&sep, 0.0).ok_or_else(|| {
            BuildError::Snapshots("the modes hold a non-finite value: their SVD cannot be taken (solve the snapshots again)".into())
        })?
    } else {
        sep.clone()
    };
    let recompress_s = clock.elapsed().as_secs_f64();
    // The bundle stores the modes in f32: round them now, so the errors measured below are
    // those of the modes served and a loaded bundle equals the built vademecum exactly.
    for x in candidate.f.iter_mut().chain(candidate.g.iter_mut()) {
        *x = *x as f32 as f64;
    }
    // One blocked pass over all load states: the exact local compliances (they make the
    // haptic force exact) and the error of every prefix of the modes.
    let greedy_as_built = (recompressed && snapshots.is_none()).then_some(&sep);
    let exact = exact_pass(
        &model,
        &loads,
        &dofs,
        &patches,
        &chol,
        &load_eqs,
        snapshots,
        &candidate,
        greedy_as_built,
        COUPLING_REACH_RADII * opts.load_radius,
        on,
    );
    let ExactPass {
        local,
        curve,
        solve_s,
        exact_pass_s,
        ..
    } = exact;
    let error_greedy = exact.greedy_curve.as_ref().unwrap_or(&curve).last().copied().unwrap_or(1.0);
    let needed = curve.iter().position(|&e| e <= opts.tolerance).map(|i| i + 1);
    let target_met = needed.is_some();
    candidate.truncate(needed.unwrap_or(candidate.modes));
    let error = if candidate.modes == 0 { 1.0 } else { curve[candidate.modes - 1] };
    let step = (curve.len() / 40).max(1);
    let error_curve = curve
        .iter()
        .enumerate()
        .filter(|(i, _)| (i + 1) % step == 0 || i + 1 == curve.len())
        .map(|(i, e)| (i + 1, *e))
        .collect();
    let final_sep = &candidate;
    let vademecum = Vademecum::from_separated(final_sep, &dofs, &loads, &patches)
        .with_local(local)
        .expect("local compliances are consistent by construction");
    let mut report = BuildReport {
        organ: model.name.clone(),
        nodes: mesh.n_nodes(),
        equations: dofs.n_free(),
        load_nodes: loads.len(),
        load_states: load_eqs.len(),
        load_radius: opts.load_radius,
        modes_from: match from {
            ModesFrom::Pgd => "pgd",
            ModesFrom::Snapshots => "snapshots",
            ModesFrom::Given(_) => "snapshots (merged)",
        },
        mean_patch_nodes: patches.iter().map(|p| p.0.len()).sum::<usize>() as f64 / patches.len() as f64,
        modes: final_sep.modes,
        recompressed,
        tolerance: opts.tolerance,
        target_met,
        greedy,
        error_greedy,
        error,
        error_curve,
        assembly_s,
        factorization_s,
        pgd_s,
        recompress_s,
        brute_force_s: solve_s,
        exact_pass_s,
        local_blocks: vademecum.local().map_or(0, |l| l.nbr.len()),
        modes_bytes: 4 * final_sep.modes * (mesh.n_dofs() + load_eqs.len()),
        full_bytes: 8 * mesh.n_dofs() * load_eqs.len(),
        anm_positions: 0,
        anm_s: 0.0,
        anm_target: None,
        cut: None,
        tear: None,
        tear_sites: Vec::new(),
    };
    let anm = if scene.organ_large(index) {
        lattice_stage(&model, opts, &mut report, on)?
    } else {
        None
    };
    let cut_basis = if scene.cut_organ() == Some(index) {
        let (cut, basis) = cut_stage(scene, &model, &vademecum, opts, on)?;
        report.cut = Some(cut);
        basis
    } else {
        None
    };
    let tear = if scene.spec.effects.tearing && crate::scene::tearing::tearable_organ(scene) == Some(index) {
        let (tear_report, sites, arrays) = tear_stage(scene, index, opts, on)?;
        (report.tear, report.tear_sites) = (Some(tear_report), sites);
        arrays
    } else {
        Vec::new()
    };
    Ok(Built {
        vademecum,
        report,
        model,
        anm,
        cut_basis,
        tear,
    })
}

/// The modes before recompression: the greedy PGD's (seed 000 Alg. 2.1), or the snapshots
/// `U = K⁻¹ F_L` — solved here, or given by the shards — as `F = U, G = I` (recompression
/// then takes their truncated SVD); with the snapshots, when the modes come from them.
fn initial_modes<'a>(
    from: ModesFrom<'a>,
    k: &SymmetricMatrix,
    chol: &Cholesky,
    load_eqs: &[build::LoadVector],
    n_free: usize,
    params: &PgdParams,
    on: &mut dyn FnMut(BuildStage),
) -> Result<(Option<Cow<'a, [f64]>>, SeparatedSolution, PgdInfo), BuildError> {
    let total = load_eqs.len();
    // the snapshots, when the modes come from them: solved here or given by the shards
    let mut snapshots_s = 0.0;
    let snapshots: Option<Cow<'a, [f64]>> = match from {
        ModesFrom::Pgd => None,
        ModesFrom::Snapshots => {
            let (u, time_s) = brute::solve_all(chol, load_eqs, &mut |done| on(BuildStage::Exact(done, total)));
            snapshots_s = time_s;
            Some(Cow::Owned(u))
        }
        ModesFrom::Given(u) => {
            if u.len() != n_free * total {
                return Err(BuildError::Snapshots(format!(
                    "{} values given for {total} load states of {n_free} equations ({} expected)",
                    u.len(),
                    n_free * total
                )));
            }
            Some(Cow::Borrowed(u))
        }
    };
    let (sep, greedy) = match snapshots.as_deref() {
        None => build::build(k, chol, load_eqs, params, &mut |m, e| on(BuildStage::Mode(m, e))),
        Some(u) => {
            // F = U, G = I: recompression below is then the truncated SVD of U itself
            let mut g = vec![0.0; total * total];
            for q in 0..total {
                g[q * total + q] = 1.0;
            }
            let sep = SeparatedSolution {
                n: n_free,
                p: total,
                modes: total,
                f: u.to_vec(),
                g,
            };
            let info = PgdInfo {
                modes: total,
                iterations: Vec::new(),
                mode_energy: Vec::new(),
                converged: true,
                // the snapshots' solves (0 when the shards solved them)
                time_s: snapshots_s,
                solves: total,
            };
            (sep, info)
        }
    };
    Ok((snapshots, sep, greedy))
}

/// What the exact pass over every load state found.
struct ExactPass {
    /// The exact local compliances between neighbouring load nodes.
    local: LocalCompliance,
    /// The error of every prefix of the candidate modes, and of the greedy modes as built
    /// when they were measured too.
    curve: Vec<f64>,
    greedy_curve: Option<Vec<f64>>,
    /// Time in the solves (s), and of the whole pass (s).
    solve_s: f64,
    exact_pass_s: f64,
}

/// One blocked pass over all load states (solved with `chol`, or the `snapshots` given): the
/// exact local compliances of the organ's `patches` between neighbouring load nodes (and those
/// within `reach`, m), and the
/// error of every prefix of `candidate`'s modes (and of `greedy`'s, the modes as the greedy
/// PGD built them, when given) against the exact responses.
fn exact_pass(
    model: &OrganModel,
    loads: &[usize],
    dofs: &DofMap,
    patches: &[(Vec<usize>, Vec<f64>)],
    chol: &Cholesky,
    load_eqs: &[build::LoadVector],
    snapshots: Option<&[f64]>,
    candidate: &SeparatedSolution,
    greedy: Option<&SeparatedSolution>,
    reach: f64,
    on: &mut dyn FnMut(BuildStage),
) -> ExactPass {
    let n_free = dofs.n_free();
    let total = load_eqs.len();
    let nbrs = load_neighbours(model, loads, reach);
    let mut local = LocalCompliance {
        ptr: vec![0],
        nbr: Vec::new(),
        c: Vec::new(),
    };
    for l in &nbrs {
        local.nbr.extend_from_slice(l);
        local.c.extend(std::iter::repeat_n([[0.0; 3]; 3], l.len()));
        local.ptr.push(local.nbr.len());
    }
    // the greedy modes as built, measured too when the bundle keeps their recompression
    // (the snapshots are exact)
    let mut errs_greedy = greedy.map(brute::PrefixErrors::new);
    let mut errs = brute::PrefixErrors::new(candidate);
    let clock = Instant::now();
    let mut solve_s = 0.0;
    let mut lap = Instant::now();
    let mut visit = |start: usize, block: &[f64]| {
        solve_s += lap.elapsed().as_secs_f64();
        for (col, u) in block.chunks_exact(n_free).enumerate() {
            let q = start + col;
            let (j, d) = (q / 3, q % 3);
            for k in local.ptr[j]..local.ptr[j + 1] {
                let b = local.nbr[k];
                for i in 0..3 {
                    local.c[k][i][d] = patch_value(u, dofs, &patches[b], i);
                }
            }
        }
        errs.add_block(candidate, start, block);
        if let (Some(e), Some(g)) = (errs_greedy.as_mut(), greedy) {
            e.add_block(g, start, block);
        }
        on(BuildStage::Exact(start + block.len() / n_free, total));
        lap = Instant::now();
    };
    match snapshots {
        None => brute::solve_blocks(chol, load_eqs, &mut visit),
        Some(u) => {
            for start in (0..total).step_by(brute::BLOCK) {
                let end = (start + brute::BLOCK).min(total);
                visit(start, &u[start * n_free..end * n_free]);
            }
        }
    }
    let exact_pass_s = clock.elapsed().as_secs_f64();
    ExactPass {
        local,
        curve: errs.curve(),
        greedy_curve: errs_greedy.map(|e| e.curve()),
        solve_s,
        exact_pass_s,
    }
}

/// The large-deformation stage (an organ that deforms largely, [`Scene::organ_large`], in
/// options with `large`): the organ's ANM-POD lattice of
/// palpation paths (seed 001), grown until it meets `large_target_error` against full Newton
/// at nodes off it when there is one ([`crate::rom::lattice_check`]); its size, time and
/// target go into `report`.
fn lattice_stage(
    model: &OrganModel,
    opts: &BuildOptions,
    report: &mut BuildReport,
    on: &mut dyn FnMut(BuildStage),
) -> Result<Option<AnmLattice>, BuildError> {
    Ok(match &opts.large {
        None => None,
        Some(params) => {
            let clock = Instant::now();
            // the seed's law: St Venant–Kirchhoff with each material's E and ν
            let laws = crate::rom::palpation::svk_laws(model);
            let lattice = match opts.large_target_error {
                None => AnmLattice::build(model, &laws, params, |done, total| on(BuildStage::Lattice(done, total)))?,
                Some(e) => {
                    use crate::rom::lattice_check;
                    // up to twice the scene's positions (what the study sweeps), checked at
                    // nodes none of them is
                    let most = AnmLatticeParams {
                        positions: 2 * params.positions,
                        ..*params
                    };
                    let exclude: Vec<usize> = AnmLattice::order(model, &most)?.iter().map(|p| p.0).collect();
                    let truth = lattice_check::newton_laws(model, params, &exclude, lattice_check::LATTICE_CHECK_NODES, |done, total| {
                        on(BuildStage::LatticeCheck(done, total))
                    })?;
                    let (lattice, t) = AnmLattice::build_for_target(
                        model,
                        &laws,
                        &most,
                        e,
                        |l| lattice_check::lattice_error(l, &truth),
                        |done, total| on(BuildStage::Lattice(done, total)),
                    )?;
                    report.anm_target = Some(t);
                    lattice
                }
            };
            report.anm_positions = lattice.positions.len();
            report.anm_s = clock.elapsed().as_secs_f64();
            Some(lattice)
        }
    })
}

/// The cutting stage (a cutting scene, organ 0): with bare enrichment the K-orthonormal Ritz
/// basis a session cuts with and the error of the force it serves on the scene's cut; with
/// local fields, under a target, the sliver rule that meets it ([`crate::xfem::accuracy`]).
fn cut_stage(
    scene: &Scene,
    model: &OrganModel,
    vademecum: &Vademecum,
    opts: &BuildOptions,
    on: &mut dyn FnMut(BuildStage),
) -> Result<(CutReport, Option<CutBasis>), BuildError> {
    let fx = &scene.spec.fidelity.xfem;
    let clock = Instant::now();
    let mut bare_force_error = None;
    let mut cut_basis = None;
    if fx.discontinuous == Discontinuous::Bare {
        on(BuildStage::CutBasis);
        let (x, size) = ReducedCut::orthonormal_basis(
            &model.mesh,
            &model.materials,
            model.locking,
            &model.problem,
            vademecum.f_raw(),
            vademecum.modes(),
            fx.basis,
        )
        .map_err(|e| BuildError::Cutting(e.to_string()))?;
        let x: Arc<[f64]> = x.into();
        let (e, _) = crate::xfem::accuracy::bare_force_error(
            &scene_cuts(scene)?,
            model,
            &fx.params(),
            fx.basis,
            x.clone(),
            size,
            |done, total| on(BuildStage::CutCalibration(done, total)),
        )
        .map_err(|e| BuildError::Cutting(e.to_string()))?;
        bare_force_error = Some(e);
        cut_basis = Some(CutBasis { basis: fx.basis, x, size });
    }
    // a target holds the local fields' force to it through the sliver rule
    let target = match opts.cut_target_error.filter(|_| fx.discontinuous == Discontinuous::LocalFields) {
        None => None,
        Some(e) => {
            use crate::xfem::accuracy;
            let (params, cuts) = (fx.params(), scene_cuts(scene)?);
            let reference = accuracy::Reference::of(&cuts, model, &params, |_, _| {}).map_err(|e| BuildError::Cutting(e.to_string()))?;
            Some(accuracy::sliver_for_target(&cuts, model, &params, e, &reference).map_err(|e| BuildError::Cutting(e.to_string()))?)
        }
    };
    let report = CutReport {
        discontinuous: fx.discontinuous,
        basis: fx.basis,
        basis_size: cut_basis.as_ref().map_or(0, |b| b.size),
        sliver: target.as_ref().map_or(fx.sliver, |t| t.sliver),
        target,
        bare_force_error,
        seconds: clock.elapsed().as_secs_f64(),
    };
    Ok((report, cut_basis))
}

/// The tearing stage (organ `index`, the scene's tearable organ): the POD–PGD offline stage
/// of the scene's grasp and of every other grasp site (seed 000 ch. 4, `damage::build`), with
/// their reports and bundle arrays.
fn tear_stage(
    scene: &Scene,
    index: usize,
    opts: &BuildOptions,
    on: &mut dyn FnMut(BuildStage),
) -> Result<(crate::damage::build::TearBuildReport, Vec<GraspSiteReport>, Vec<TearArrays>), BuildError> {
    use crate::scene::tearing;
    let fail = |e: String| BuildError::Tearing(e);
    let (tear_model, _) = tearing::tear_model(scene, index).map_err(|e| fail(e.to_string()))?;
    let (mut settings, _) = tearing::settings(scene);
    settings.target_force_error = opts.tear_target_error;
    let extra = tearing::extra_sites(scene, index, &tear_model).map_err(|e| fail(e.to_string()))?;
    let sites = 1 + extra.len();
    let (off, tear_report, _) = crate::damage::build::build(tear_model.clone(), &settings, |what, fraction| {
        on(BuildStage::Tearing {
            site: 0,
            sites,
            what,
            fraction,
        })
    })
    .map_err(|e| fail(e.to_string()))?;
    let mut tear = vec![off.to_arrays()];
    let mut site_reports = Vec::new();
    for (k, site) in extra.iter().enumerate() {
        let mut model = tear_model.clone();
        model.load = site.full(model.mesh.n_nodes());
        let (off, build, _) = crate::damage::build::build(model, &settings, |what, fraction| {
            on(BuildStage::Tearing {
                site: k + 1,
                sites,
                what,
                fraction,
            })
        })
        .map_err(|e| fail(format!("grasp site {}: {e}", k + 1)))?;
        let (_, centre_m, _) = off.model.grasp().expect("a site has a load");
        site_reports.push(GraspSiteReport {
            centre_m,
            pull_direction: off.model.pull_frame().expect("a site has a load")[0],
            nodes: site.nodes.len(),
            build,
        });
        tear.push(off.to_site_arrays(site));
    }
    Ok((tear_report, site_reports, tear))
}

/// Writes a built vademecum as a bundle in `dir`.
pub fn write_bundle(dir: &Path, scene: &Scene, built: &Built) -> Result<Manifest, BundleError> {
    let v = &built.vademecum;
    let mesh = &built.model.mesh;
    let report = serde_json::to_value(&built.report).unwrap_or(serde_json::Value::Null);
    let manifest = Manifest::new(KIND, scene, &built.model.name, mesh, report);
    let nodes: Vec<f64> = mesh.nodes.iter().flatten().copied().collect();
    let loads: Vec<i64> = v.load_nodes().iter().map(|&n| n as i64).collect();
    let surface: Vec<i64> = built.model.boundary.triangles().iter().flatten().map(|&n| n as i64).collect();
    let mut patch_ptr = vec![0i64];
    let mut patch_nodes = Vec::new();
    let mut patch_weights = Vec::new();
    for (n, w) in v.patches() {
        patch_nodes.extend(n.iter().map(|&x| x as i64));
        patch_weights.extend_from_slice(w);
        patch_ptr.push(patch_nodes.len() as i64);
    }
    let (local_ptr, local_nbr, local_c): (Vec<i64>, Vec<i64>, Vec<f64>) = match v.local() {
        Some(l) => (
            l.ptr.iter().map(|&x| x as i64).collect(),
            l.nbr.iter().map(|&x| x as i64).collect(),
            l.c.iter().flatten().flatten().copied().collect(),
        ),
        None => (vec![0; v.load_nodes().len() + 1], Vec::new(), Vec::new()),
    };
    let m = v.modes() as u64;
    let f32_of = |x: &[f64]| -> Vec<f32> { x.iter().map(|&v| v as f32).collect() };
    let (f, g) = (f32_of(v.f_raw()), f32_of(v.g_raw()));
    let arrays = [
        ("F", vec![m, mesh.n_dofs() as u64], ArrayData::F32(&f)),
        ("G", vec![m, 3 * loads.len() as u64], ArrayData::F32(&g)),
        ("load_nodes", vec![loads.len() as u64], ArrayData::I64(&loads)),
        ("nodes", vec![mesh.n_nodes() as u64, 3], ArrayData::F64(&nodes)),
        ("surface", vec![(surface.len() / 3) as u64, 3], ArrayData::I64(&surface)),
        ("patch_ptr", vec![patch_ptr.len() as u64], ArrayData::I64(&patch_ptr)),
        ("patch_nodes", vec![patch_nodes.len() as u64], ArrayData::I64(&patch_nodes)),
        ("patch_weights", vec![patch_weights.len() as u64], ArrayData::F64(&patch_weights)),
        ("local_ptr", vec![local_ptr.len() as u64], ArrayData::I64(&local_ptr)),
        ("local_nbr", vec![local_nbr.len() as u64], ArrayData::I64(&local_nbr)),
        ("local_c", vec![local_nbr.len() as u64, 3, 3], ArrayData::F64(&local_c)),
    ];
    let mut arrays = arrays.to_vec();
    let anm = built.anm.as_ref().map(AnmLattice::to_arrays);
    if let Some(a) = &anm {
        let len = |v: &[f64]| vec![v.len() as u64];
        arrays.extend([
            ("anm_max_force", len(&a.max_force), ArrayData::F64(&a.max_force)),
            ("anm_nodes", vec![a.nodes.len() as u64], ArrayData::I64(&a.nodes)),
            ("anm_points", vec![a.nodes.len() as u64, 3], ArrayData::F64(&a.points)),
            ("anm_normals", vec![a.nodes.len() as u64, 3], ArrayData::F64(&a.normals)),
            ("anm_d_linear", len(&a.d_linear), ArrayData::F64(&a.d_linear)),
            ("anm_modes", vec![a.modes.len() as u64], ArrayData::I64(&a.modes)),
            ("anm_probe", len(&a.probe), ArrayData::F64(&a.probe)),
            ("anm_step_ptr", vec![a.step_ptr.len() as u64], ArrayData::I64(&a.step_ptr)),
            (
                "anm_step_meta",
                vec![(a.step_meta.len() / 6) as u64, 6],
                ArrayData::F64(&a.step_meta),
            ),
            ("anm_step_data", len(&a.step_data), ArrayData::F64(&a.step_data)),
        ]);
    }
    if let Some(c) = &built.cut_basis {
        let n_free = (c.x.len() / c.size.max(1)) as u64;
        arrays.push(("cut_basis", vec![n_free, c.size as u64], ArrayData::F64(&c.x)));
    }
    // tearing: `tear_*` for the scene's grasp, `tear{k}_*` for grasp site k
    let tear_small: Vec<TearSmall> = built.tear.iter().map(TearSmall::of).collect();
    let tear_names: Vec<Vec<String>> = (0..built.tear.len())
        .map(|k| TEAR_ARRAYS.iter().map(|n| format!("{}{n}", tear_prefix(k))).collect())
        .collect();
    for ((t, small), names) in built.tear.iter().zip(&tear_small).zip(&tear_names) {
        let (q, nm, m) = (t.lo.len() as u64, t.n_modes as u64, t.m as u64);
        let len = |v: &[f64]| vec![v.len() as u64];
        let name = |k: &str| names[TEAR_ARRAYS.iter().position(|n| *n == k).expect("a tearing array")].as_str();
        arrays.extend([
            (name("meta"), vec![2], ArrayData::F64(&small.meta)),
            (
                name("pod_basis"),
                vec![q, t.pod_basis.len() as u64 / q.max(1)],
                ArrayData::F64(&t.pod_basis),
            ),
            (name("singular_values"), len(&t.singular_values), ArrayData::F64(&t.singular_values)),
            (name("lo"), vec![q], ArrayData::F64(&t.lo)),
            (name("hi"), vec![q], ArrayData::F64(&t.hi)),
            (
                name("spatial"),
                vec![nm, t.spatial.len() as u64 / nm.max(1)],
                ArrayData::F64(&t.spatial),
            ),
            (name("factors"), vec![nm, q, t.grid as u64], ArrayData::F64(&t.factors)),
            (name("ritz_v"), vec![t.ritz_v.len() as u64 / m.max(1), m], ArrayData::F64(&t.ritz_v)),
            (name("ritz_k"), vec![q + 1, m, m], ArrayData::F64(&t.ritz_k)),
            (name("ritz_b"), vec![q + 1, m], ArrayData::F64(&t.ritz_b)),
        ]);
        // the pulls across the load, when built (bundles without them pull along it only)
        if t.patterns.len() > 1 {
            arrays.push((name("patterns"), len(&small.patterns), ArrayData::F64(&small.patterns)));
        }
        if !t.force_error.is_empty() {
            arrays.push((
                name("force_error"),
                vec![t.force_error.len() as u64 / 2, 2],
                ArrayData::F64(&t.force_error),
            ));
        }
        if !t.fallback_modes.is_empty() {
            arrays.push((
                name("fallback_modes"),
                len(&small.fallback_modes),
                ArrayData::F64(&small.fallback_modes),
            ));
            arrays.push((
                name("fallback_force_error"),
                vec![t.fallback_force_error.len() as u64 / 2, 2],
                ArrayData::F64(&t.fallback_force_error),
            ));
        }
        if !t.load_nodes.is_empty() {
            arrays.push((
                name("load_nodes"),
                vec![small.load_nodes.len() as u64],
                ArrayData::I64(&small.load_nodes),
            ));
            arrays.push((name("load"), vec![small.load_nodes.len() as u64, 3], ArrayData::F64(&t.load_forces)));
        }
    }
    bundle::write(dir, manifest, &scene.source, &arrays)
}

/// The small arrays a bundle writes for a tearing stage, owned while the bundle is written.
struct TearSmall {
    meta: [f64; 2],
    patterns: Vec<f64>,
    fallback_modes: Vec<f64>,
    load_nodes: Vec<i64>,
}

impl TearSmall {
    fn of(t: &TearArrays) -> Self {
        Self {
            meta: [t.captured, t.grid as f64],
            patterns: t.patterns.iter().map(|&n| n as f64).collect(),
            fallback_modes: t.fallback_modes.iter().map(|&n| n as f64).collect(),
            load_nodes: t.load_nodes.iter().map(|&n| n as i64).collect(),
        }
    }
}
