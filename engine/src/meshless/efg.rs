//! Total Lagrangian element-free Galerkin with adaptive dynamic relaxation (seed 004 §3.2,
//! the MTLADR algorithm; Joldes, Wittek & Miller 2011).
//!
//! # Internal forces (Eqs. 3.19–3.22)
//! At each integration point (weight `w`, MLS gradients `∇φ_I` in the reference
//! configuration): `F = I + Σ_I u_I ⊗ ∇φ_I` (in 2D, plane strain: `F₃₃ = 1`), `C = FᵀF`,
//! `S = 2∂W/∂C` from the hyperelastic law, `P = FS`, and `f_I += w P ∇φ_I`. The `u_I` are field
//! variables, not nodal displacements: MLS functions do not interpolate.
//!
//! # Essential boundary conditions (Eq. 3.18)
//! For the nodes `b` on the essential boundary, the field variables are solved every step so
//! that the *interpolated* displacement at those nodes is the prescribed one:
//! `Φ_bb U_b = Ū − Φ_bm U_m`, with `Φ` the shape functions evaluated at the boundary nodes
//! (`Φ_bb` factored once). The reaction conjugate to the prescribed displacements is then
//! `R = Φ_bb⁻ᵀ f_b` (virtual work, at equilibrium of the free field variables).
//!
//! # Adaptive dynamic relaxation (Eqs. 3.3–3.8, 3.23–3.25)
//! Explicit central differences with mass-proportional damping, time step `Δt = 1`:
//! `u⁺ = u + β(u − u⁻) + α M⁻¹(f_ext − f_int(u))`, `α = 2/(2 + c)`, `β = (2 − c)/(2 + c)`,
//! with the lumped masses scaled so that the highest frequency of `M⁻¹K` is below the stability
//! limit 4 (a Gershgorin bound over the integration points, Eqs. 3.11–3.15 in spirit) and the
//! damping `c = 2√ω²_min` from the estimate of the lowest frequency
//! `ω²_min ≈ (u − u_l)ᵀ(f(u) − f(u_l)) / (u − u_l)ᵀM(u − u_l)` refreshed every few steps
//! (Eq. 3.8). The loading phase ramps the prescribed displacements with light damping; the
//! relaxation stops when the estimated absolute error `ρ*/(1 − ρ*) ‖u⁺ − u‖∞` falls below the
//! tolerance, `ρ*` the corrected spectral radius of the iteration (Eq. 3.25, η = 0.2).

use nalgebra::{DMatrix, Matrix3};
use rayon::prelude::*;

use super::grid::IntegrationPoint;
use super::mls::{MlsError, NodeCloud, ShapeValues};
use crate::material::hyperelastic::{Hyperelastic, Part};

/// A meshless large-deformation problem.
#[derive(Debug, Clone)]
pub struct EfgProblem {
    /// The nodes and their supports (2D: plane strain; 3D).
    pub cloud: NodeCloud,
    /// Integration points.
    pub points: Vec<IntegrationPoint>,
    /// The material.
    pub law: Hyperelastic,
    /// Prescribed displacement components at load factor 1: `(node, component, value)`.
    pub prescribed: Vec<(usize, usize, f64)>,
    /// Point forces at load factor 1, at node positions: `(node, force)` (N; per metre in 2D).
    /// Applied through the shape functions, `f_I = Σ_J φ_I(x_J) F_J` (MLS functions do not
    /// interpolate).
    pub loads: Vec<(usize, [f64; 3])>,
}

/// Settings of the relaxation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdrParams {
    /// Absolute accuracy of the displacement field (m), Eq. 3.24.
    pub tolerance: f64,
    /// Steps of the loading phase (prescribed displacements ramped linearly).
    pub loading_steps: usize,
    /// Most steps in all.
    pub max_steps: usize,
    /// Steps between two estimates of the lowest frequency.
    pub update_every: usize,
}

impl Default for AdrParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-7,
            loading_steps: 2000,
            max_steps: 200_000,
            update_every: 20,
        }
    }
}

/// Why the solve stopped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EfgError {
    /// Shape functions could not be built.
    #[error(transparent)]
    Shape(#[from] MlsError),
    /// A cut could not be built.
    #[error(transparent)]
    Cut(#[from] crate::geometry::cut::CutError),
    /// A point given on the deformed body could not be traced back to the reference body.
    #[error(
        "the point ({x:.4e}, {y:.4e}, {z:.4e}) of the deformed body could not be placed in the reference configuration (is it inside the body?)"
    )]
    Placement {
        /// x (m).
        x: f64,
        /// y (m).
        y: f64,
        /// z (m).
        z: f64,
    },
    /// The boundary shape-function matrix is singular.
    #[error("the essential-boundary shape-function matrix is singular: the boundary nodes' supports are degenerate")]
    Boundary,
    /// A material point inverted or the iteration diverged.
    #[error("the relaxation diverged at step {step}: {why}")]
    Diverged {
        /// Step.
        step: usize,
        /// What happened.
        why: String,
    },
    /// The step limit was reached.
    #[error("no convergence in {steps} steps (estimated error {error:.3e} m, tolerance {tolerance:.1e} m)")]
    NoConvergence {
        /// Steps taken.
        steps: usize,
        /// Last error estimate.
        error: f64,
        /// The tolerance.
        tolerance: f64,
    },
}

/// A relaxed solution.
#[derive(Debug, Clone)]
pub struct EfgSolution {
    /// Field variables (`dim` per node).
    pub field: Vec<f64>,
    /// Interpolated displacements at the nodes (`dim` per node).
    pub displacement: Vec<f64>,
    /// Strain energy (J; per metre of thickness in 2D).
    pub energy: f64,
    /// Reactions conjugate to the prescribed components, in the order of
    /// [`EfgProblem::prescribed`] (N; per metre of thickness in 2D).
    pub reactions: Vec<f64>,
    /// Relaxation steps.
    pub steps: usize,
    /// Final error estimate (m).
    pub error: f64,
    /// `‖f_int − f_ext‖ / ‖f_int‖` over the free field variables at the end.
    pub residual: f64,
    /// Times the relaxation started again with heavier masses (and, while loading, a longer
    /// ramp) after a material point inverted in a transient.
    pub restarts: usize,
}

/// Room left between the measured highest frequency at the reference state and the stability
/// limit, for the stiffening of large strains.
const MARGIN: f64 = 1.5;
/// Power iterations for the highest frequency.
const POWER_ITERATIONS: usize = 40;
/// Steps between two measurements of the highest frequency.
const RESCALE_EVERY: usize = 250;
/// Restarts allowed after an inverted transient, and the mass factor of each.
const MAX_RESTARTS: usize = 4;
const RESTART_MASS: f64 = 4.0;
/// Factor on the loading ramp's steps at each restart.
const RESTART_RAMP: usize = 8;
/// Integration points per parallel task.
const PARALLEL_BLOCK: usize = 512;

struct Model {
    dim: usize,
    shapes: Vec<ShapeValues>,
    weights: Vec<f64>,
    law: Hyperelastic,
}

impl Model {
    /// Adds one integration point's internal forces into `f`; its energy, or `None` when it
    /// inverts.
    fn point(&self, p: usize, u: &[f64], f: &mut [f64]) -> Option<f64> {
        let d = self.dim;
        let (s, w) = (&self.shapes[p], self.weights[p]);
        let fm = s.deformation_gradient(u, d);
        let r = self.law.response(&(fm.transpose() * fm), Part::Full)?;
        let pk = fm * r.stress_tensor();
        for (a, &i) in s.nodes.iter().enumerate() {
            for k in 0..d {
                f[d * i + k] += w * (0..d).map(|j| pk[(k, j)] * s.grad[a * d + j]).sum::<f64>();
            }
        }
        Some(w * r.energy)
    }

    /// Internal forces (and energy), in parallel over blocks of integration points (rayon);
    /// `None` when a point inverts.
    fn forces(&self, u: &[f64], f: &mut [f64]) -> Option<f64> {
        let n = self.shapes.len();
        let threads = rayon::current_num_threads().max(1);
        if threads == 1 || n < 2 * PARALLEL_BLOCK {
            f.fill(0.0);
            let mut e = 0.0;
            for p in 0..n {
                e += self.point(p, u, f)?;
            }
            return e.is_finite().then_some(e);
        }
        let blocks = n.div_ceil(PARALLEL_BLOCK);
        let (sum, e) = (0..blocks)
            .into_par_iter()
            .map(|b| {
                let mut local = vec![0.0; f.len()];
                let mut e = 0.0;
                for p in b * PARALLEL_BLOCK..((b + 1) * PARALLEL_BLOCK).min(n) {
                    e += self.point(p, u, &mut local)?;
                }
                Some((local, e))
            })
            .try_reduce(
                || (vec![0.0; f.len()], 0.0),
                |(mut a, ea), (b, eb)| {
                    for (x, y) in a.iter_mut().zip(&b) {
                        *x += y;
                    }
                    Some((a, ea + eb))
                },
            )?;
        f.copy_from_slice(&sum);
        e.is_finite().then_some(e)
    }
}

/// The highest frequency `ω²_max` of `M⁻¹K(u)` by power iteration from `dir` (updated), with
/// `K(u)v` as a difference of internal forces over a step `eps`.
fn highest_frequency(model: &Model, u: &[f64], mass: &[f64], constrained: &[bool], dir: &mut [f64], eps: f64, iterations: usize) -> f64 {
    let d = model.dim;
    let nd = u.len();
    let mut f0 = vec![0.0; nd];
    if model.forces(u, &mut f0).is_none() {
        return f64::NAN;
    }
    let mut kv = vec![0.0; nd];
    let mut probe = vec![0.0; nd];
    let mut highest = 0.0;
    for _ in 0..iterations {
        let norm = dir.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm == 0.0 {
            break;
        }
        for q in 0..nd {
            probe[q] = u[q] + eps * dir[q] / norm;
        }
        if model.forces(&probe, &mut kv).is_none() {
            return f64::NAN;
        }
        for q in 0..nd {
            dir[q] = if constrained[q] { 0.0 } else { (kv[q] - f0[q]) / eps / mass[q / d] };
        }
        highest = dir.iter().map(|x| x * x).sum::<f64>().sqrt();
    }
    highest
}

/// Solves `problem` by adaptive dynamic relaxation from the reference state, the prescribed
/// displacements ramped over `params.loading_steps`; `progress(step, error)` now and then.
pub fn solve(problem: &EfgProblem, params: &AdrParams, progress: impl FnMut(usize, f64)) -> Result<EfgSolution, EfgError> {
    run(problem, params, None, progress)
}

/// Relaxes `problem` from the field variables `start` (`dim` per node) with the prescribed
/// displacements at their full value: the steady state after a change such as a cut (seed 004
/// §4.2.3 (b)–(c): shape functions, masses and forces are rebuilt, the relaxation restarts).
pub fn relax(problem: &EfgProblem, params: &AdrParams, start: &[f64], progress: impl FnMut(usize, f64)) -> Result<EfgSolution, EfgError> {
    assert_eq!(
        start.len(),
        problem.cloud.dim() * problem.cloud.len(),
        "field variables of the cloud"
    );
    run(problem, params, Some(start), progress)
}

/// The essential boundary of an EFG problem, imposed by Eq. 3.18: the nodes with a prescribed
/// component, the shape functions at them (`Φ_bb`, factored), and the prescribed values.
struct EssentialBoundary {
    dim: usize,
    /// The boundary nodes, sorted.
    bnodes: Vec<usize>,
    /// The shape functions at each boundary node.
    at_b: Vec<ShapeValues>,
    /// `Φ_bb`: the boundary nodes' shape functions at the boundary nodes; its LU and that of
    /// its transpose (the reactions).
    phi_bb: DMatrix<f64>,
    lu: nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>,
    lu_t: nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>,
    /// Per boundary node and component, the value prescribed at λ = 1.
    target: Vec<Option<f64>>,
    /// Per field variable, whether it is prescribed.
    constrained: Vec<bool>,
}

impl EssentialBoundary {
    fn new(problem: &EfgProblem) -> Result<Self, EfgError> {
        let cloud = &problem.cloud;
        let d = cloud.dim();
        let nd = d * cloud.len();
        let mut bnodes: Vec<usize> = problem.prescribed.iter().map(|&(i, _, _)| i).collect();
        bnodes.sort_unstable();
        bnodes.dedup();
        let bindex = |i: usize| bnodes.binary_search(&i).ok();
        let mut at_b = Vec::with_capacity(bnodes.len());
        for &i in &bnodes {
            let mut s = ShapeValues::default();
            cloud.shape_at_node(i, &mut s)?;
            at_b.push(s);
        }
        let nb = bnodes.len();
        let mut phi_bb = DMatrix::<f64>::zeros(nb, nb);
        for (r, s) in at_b.iter().enumerate() {
            for (a, &j) in s.nodes.iter().enumerate() {
                if let Some(c) = bindex(j) {
                    phi_bb[(r, c)] = s.phi[a];
                }
            }
        }
        let lu = phi_bb.clone().lu();
        if !lu.is_invertible() {
            return Err(EfgError::Boundary);
        }
        let lu_t = phi_bb.transpose().lu();
        // which components are prescribed at each boundary node, and to what (at λ = 1)
        let mut target = vec![None; nb * d];
        for &(i, k, v) in &problem.prescribed {
            target[bindex(i).expect("listed") * d + k] = Some(v);
        }
        let constrained: Vec<bool> = (0..nd)
            .map(|q| bindex(q / d).is_some_and(|b| target[b * d + q % d].is_some()))
            .collect();
        Ok(Self {
            dim: d,
            bnodes,
            at_b,
            phi_bb,
            lu,
            lu_t,
            target,
            constrained,
        })
    }

    /// The index of node `i` among the boundary nodes.
    fn index(&self, i: usize) -> Option<usize> {
        self.bnodes.binary_search(&i).ok()
    }

    /// Eq. 3.18: `U_b = Φ_bb⁻¹ (λŪ − Φ_bm U_m)`, component by component, into `u`.
    fn impose(&self, u: &mut [f64], lambda: f64) {
        let (d, nb, target) = (self.dim, self.bnodes.len(), &self.target);
        for k in 0..d {
            let mut rhs = nalgebra::DVector::zeros(nb);
            for (r, s) in self.at_b.iter().enumerate() {
                let Some(v) = target[r * d + k] else {
                    continue;
                };
                let mut x = lambda * v;
                for (a, &j) in s.nodes.iter().enumerate() {
                    if self.index(j).is_none_or(|c| target[c * d + k].is_none()) {
                        x -= s.phi[a] * u[d * j + k];
                    }
                }
                rhs[r] = x;
            }
            // rows without a target in this component: keep the current field variable
            let mut m = self.phi_bb.clone();
            for r in 0..nb {
                if target[r * d + k].is_none() {
                    m.row_mut(r).fill(0.0);
                    m[(r, r)] = 1.0;
                    rhs[r] = u[d * self.bnodes[r] + k];
                }
            }
            if let Some(sol) = if (0..nb).all(|r| target[r * d + k].is_some()) {
                self.lu.solve(&rhs)
            } else {
                m.lu().solve(&rhs)
            } {
                for r in 0..nb {
                    u[d * self.bnodes[r] + k] = sol[r];
                }
            }
        }
    }

    /// The reactions at the `prescribed` components, `Φ_bb⁻ᵀ f_b` per component, of the
    /// internal forces `f`.
    fn reactions(&self, f: &[f64], prescribed: &[(usize, usize, f64)]) -> Vec<f64> {
        let (d, nb) = (self.dim, self.bnodes.len());
        let mut per = vec![0.0; nb * d];
        for k in 0..d {
            let fb = nalgebra::DVector::from_iterator(nb, self.bnodes.iter().map(|&i| f[d * i + k]));
            if let Some(r) = self.lu_t.solve(&fb) {
                for b in 0..nb {
                    per[b * d + k] = r[b];
                }
            }
        }
        prescribed
            .iter()
            .map(|&(i, k, _)| per[self.index(i).expect("listed") * d + k])
            .collect()
    }
}

/// The external forces through the shape functions at the loaded nodes.
fn external_forces(problem: &EfgProblem) -> Result<Vec<f64>, EfgError> {
    let cloud = &problem.cloud;
    let d = cloud.dim();
    let mut f_ext = vec![0.0; d * cloud.len()];
    for &(j, force) in &problem.loads {
        let mut s = ShapeValues::default();
        cloud.shape_at_node(j, &mut s)?;
        for (a, &i) in s.nodes.iter().enumerate() {
            for k in 0..d {
                f_ext[d * i + k] += s.phi[a] * force[k];
            }
        }
    }
    Ok(f_ext)
}

/// The nodal masses of the `n` nodes: the Gershgorin bound of the stiffness row sums, so that
/// `ω²_max ≤ 4` with `Δt = 1` (none zero).
fn gershgorin_masses(model: &Model, n: usize) -> Vec<f64> {
    let d = model.dim;
    let modulus = match model.law {
        Hyperelastic::NeoHookean { mu, kappa, .. } | Hyperelastic::MooneyRivlin { c10: mu, kappa, .. } => kappa + 4.0 / 3.0 * mu,
        Hyperelastic::StVenantKirchhoff { lambda, mu } => lambda + 2.0 * mu,
    };
    let mut mass = vec![0.0; n];
    for (s, &w) in model.shapes.iter().zip(&model.weights) {
        let norms: Vec<f64> = (0..s.nodes.len())
            .map(|a| (0..d).map(|k| s.grad[a * d + k].powi(2)).sum::<f64>().sqrt())
            .collect();
        let total: f64 = norms.iter().sum();
        for (a, &i) in s.nodes.iter().enumerate() {
            mass[i] += w * modulus * norms[a] * total * d as f64;
        }
    }
    for m in &mut mass {
        if *m <= 0.0 {
            *m = f64::MIN_POSITIVE;
        }
    }
    mass
}

/// Scales the Gershgorin `mass`es, loose by a factor of a few, so that the highest frequency
/// of `M⁻¹K` at the state `u`, measured by power iteration, sits at `4/MARGIN`; the probe
/// direction and the cloud's size, kept to measure it again along the way (large strains
/// stiffen).
fn calibrate_masses(model: &Model, cloud: &NodeCloud, constrained: &[bool], u: &[f64], mass: &mut [f64]) -> (Vec<f64>, f64) {
    let d = model.dim;
    // The bound is loose by a factor of a few: measure the highest frequency of M⁻¹K at the
    // reference state by power iteration and scale the masses so that it sits at 4/MARGIN;
    // the measurement is repeated along the way, since large strains stiffen.
    let size = cloud
        .points()
        .iter()
        .flat_map(|p| p.iter().take(d).copied())
        .fold(0.0f64, |a, x| a.max(x.abs()))
        .max(f64::MIN_POSITIVE);
    let nd = constrained.len();
    let mut probe_dir: Vec<f64> = (0..nd)
        .map(|q| {
            if constrained[q] {
                0.0
            } else {
                ((q * 7919) % 13) as f64 - 6.0 + 0.5
            }
        })
        .collect();
    let highest = highest_frequency(model, u, mass, constrained, &mut probe_dir, 1e-7 * size, POWER_ITERATIONS);
    if highest.is_finite() && highest > 0.0 {
        for m in mass.iter_mut() {
            *m *= highest * MARGIN / 4.0;
        }
    }
    (probe_dir, size)
}

/// Eq. 3.8 with `l` the previous step: `Δuᵀ Δf / Δuᵀ M Δu` over the free field variables
/// (`Δu = u − prev`, `Δf = f − f_prev`), when both are positive.
fn rayleigh_quotient(u: &[f64], prev: &[f64], f: &[f64], f_prev: &[f64], mass: &[f64], constrained: &[bool], d: usize) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for q in 0..u.len() {
        if !constrained[q] {
            let du = u[q] - prev[q];
            num += du * (f[q] - f_prev[q]);
            den += du * du * mass[q / d];
        }
    }
    (den > 0.0 && num > 0.0).then(|| num / den)
}

/// The solution at convergence: the energy, the relative residual of the out-of-balance
/// force `f_int − f_ext` over the free field variables, the reactions at the prescribed
/// components, and the displacement at the nodes (`u` holds the field variables; `f` is
/// scratch for the forces).
fn converged(
    problem: &EfgProblem,
    model: &Model,
    boundary: &EssentialBoundary,
    f_ext: &[f64],
    u: Vec<f64>,
    f: &mut [f64],
    steps: usize,
    error: f64,
    restarts: usize,
) -> Result<EfgSolution, EfgError> {
    let (cloud, constrained) = (&problem.cloud, &boundary.constrained);
    let d = cloud.dim();
    let (n, nd) = (cloud.len(), d * cloud.len());
    let energy = model.forces(&u, f).unwrap_or(f64::NAN);
    let scale = f.iter().map(|x| x * x).sum::<f64>().sqrt().max(f64::MIN_POSITIVE);
    for (fq, e) in f.iter_mut().zip(f_ext) {
        *fq -= e;
    }
    let residual = (0..nd).filter(|&q| !constrained[q]).map(|q| f[q] * f[q]).sum::<f64>().sqrt() / scale;
    let reactions = boundary.reactions(f, &problem.prescribed);
    let mut displacement = Vec::with_capacity(nd);
    let mut s = ShapeValues::default();
    for i in 0..n {
        cloud.shape_at_node(i, &mut s)?;
        displacement.extend_from_slice(&s.interpolate(&u, d)[..d]);
    }
    Ok(EfgSolution {
        field: u,
        displacement,
        energy,
        reactions,
        steps,
        error,
        residual,
        restarts,
    })
}

fn run(
    problem: &EfgProblem,
    params: &AdrParams,
    start: Option<&[f64]>,
    mut progress: impl FnMut(usize, f64),
) -> Result<EfgSolution, EfgError> {
    let cloud = &problem.cloud;
    let d = cloud.dim();
    let n = cloud.len();
    let nd = d * n;
    let mut loading_steps = if start.is_some() { 0 } else { params.loading_steps };
    let mut shapes = Vec::with_capacity(problem.points.len());
    for p in &problem.points {
        let mut s = ShapeValues::default();
        cloud.shape(p.x, &mut s)?;
        shapes.push(s);
    }
    let model = Model {
        dim: d,
        weights: problem.points.iter().map(|p| p.weight).collect(),
        shapes,
        law: problem.law,
    };
    let f_ext = external_forces(problem)?;
    // essential boundary: the nodes with a prescribed component, their shape functions there
    let boundary = EssentialBoundary::new(problem)?;
    let constrained = &boundary.constrained;
    // masses: Gershgorin bound of the stiffness row sums, so that ω²_max ≤ 4 with Δt = 1
    let mut mass = gershgorin_masses(&model, n);
    let mut u = start.map_or_else(|| vec![0.0; nd], <[f64]>::to_vec);
    let (mut probe_dir, size) = calibrate_masses(&model, cloud, constrained, &u, &mut mass);
    if start.is_some() {
        boundary.impose(&mut u, 1.0);
    }
    let initial = u.clone();
    let mut prev = u.clone();
    let mut f = vec![0.0; nd];
    let mut f_prev = vec![0.0; nd];
    let mut omega2: f64 = 1e-6;
    let mut estimate: f64 = 1e-6;
    let mut error = f64::INFINITY;
    // first step of the current attempt, and attempts restarted with heavier masses
    let (mut origin, mut restarts) = (0, 0);
    for step in 0..params.max_steps {
        let local = step - origin;
        let lambda = ((local + 1) as f64 / loading_steps.max(1) as f64).min(1.0);
        let loading = local < loading_steps;
        let inverted = model.forces(&u, &mut f).is_none();
        if inverted || u.iter().any(|x| !x.is_finite()) {
            // A transient too violent for the explicit integration (e.g. the faces of a fresh
            // cut springing open): start again with heavier masses, i.e. a smaller time step.
            if restarts == MAX_RESTARTS {
                return Err(EfgError::Diverged {
                    step,
                    why: format!(
                        "{} after {MAX_RESTARTS} restarts with masses {}× heavier",
                        if inverted {
                            "a material point inverted (det F ≤ 0)"
                        } else {
                            "non-finite field variables"
                        },
                        RESTART_MASS.powi(MAX_RESTARTS as i32)
                    ),
                });
            }
            restarts += 1;
            for m in &mut mass {
                *m *= RESTART_MASS;
            }
            // and a gentler ramp: heavier masses alone make the prescribed motion faster
            // against the structure's slower dynamics (the next attempt's transient as violent)
            if loading_steps > 0 {
                loading_steps = (loading_steps * RESTART_RAMP).min(params.max_steps / 4);
            }
            (omega2, estimate) = (1e-6, 1e-6);
            u.copy_from_slice(&initial);
            prev.copy_from_slice(&initial);
            f_prev.fill(0.0);
            origin = step + 1;
            continue;
        }
        // the out-of-balance force f_int − λ f_ext
        for (fq, e) in f.iter_mut().zip(&f_ext) {
            *fq -= lambda * e;
        }
        // Eq. 3.8 with l = the previous step: the Rayleigh quotient of the last change, which
        // aligns with the slowest mode as the relaxation proceeds
        if let Some(q) = rayleigh_quotient(&u, &prev, &f, &f_prev, &mass, constrained, d) {
            estimate = q.min(4.0);
        }
        f_prev.copy_from_slice(&f);
        if step % params.update_every.max(1) == 0 && step > 0 {
            omega2 = estimate;
        }
        // large strains stiffen: re-measure the highest frequency and grow the masses
        if step > 0 && step % RESCALE_EVERY == 0 {
            let now = highest_frequency(&model, &u, &mass, constrained, &mut probe_dir, 1e-7 * size, POWER_ITERATIONS / 4);
            if now.is_finite() && now * MARGIN > 4.0 {
                let grow = now * MARGIN / 4.0;
                for m in &mut mass {
                    *m *= grow;
                }
                omega2 /= grow;
                estimate /= grow;
            }
        }
        // the estimated optimal damping, while loading as while relaxing: light damping during
        // a fast ramp lets kinetic energy pile up at the moving boundary and invert it
        let c = 2.0 * omega2.sqrt();
        let (alpha, beta) = (2.0 / (2.0 + c), (2.0 - c) / (2.0 + c));
        let mut change = 0.0f64;
        for q in 0..nd {
            if constrained[q] {
                continue;
            }
            let next = u[q] + beta * (u[q] - prev[q]) - alpha * f[q] / mass[q / d];
            change = change.max((next - u[q]).abs());
            prev[q] = u[q];
            u[q] = next;
        }
        for q in 0..nd {
            if constrained[q] {
                prev[q] = u[q];
            }
        }
        boundary.impose(&mut u, lambda);
        if !loading {
            let w = omega2.sqrt();
            let rho = (2.0 - w) / (2.0 + w);
            let rho = rho + 0.2 * (1.0 - rho);
            error = rho / (1.0 - rho) * change;
            if step % 1000 == 0 {
                progress(step, error);
            }
            if error < params.tolerance && local > loading_steps + 2 * params.update_every {
                return converged(problem, &model, &boundary, &f_ext, u, &mut f, step + 1, error, restarts);
            }
        }
    }
    Err(EfgError::NoConvergence {
        steps: params.max_steps,
        error,
        tolerance: params.tolerance,
    })
}

/// The displacement `u(x) = Σ_I φ_I(x) u_I` and the deformation gradient
/// `F = I + Σ_I u_I ⊗ ∇φ_I` at the reference position `x`.
pub fn deformation_at(cloud: &NodeCloud, field: &[f64], x: [f64; 3]) -> Result<([f64; 3], Matrix3<f64>), MlsError> {
    let d = cloud.dim();
    let mut s = ShapeValues::default();
    cloud.shape(x, &mut s)?;
    Ok((s.interpolate(field, d), s.deformation_gradient(field, d)))
}

/// The opening of the cut at `x` (reference configuration, on the cut): the displacement of
/// the positive face minus that of the negative face, `|u⁺ − u⁻|`.
pub fn opening(cloud: &NodeCloud, field: &[f64], x: [f64; 3]) -> Result<f64, MlsError> {
    let d = cloud.dim();
    let mut s = ShapeValues::default();
    let mut u = [[0.0; 3]; 2];
    for (face, side) in [1.0, -1.0].into_iter().enumerate() {
        cloud.shape_on_side(x, side, &mut s)?;
        u[face] = s.interpolate(field, d);
    }
    Ok((0..d).map(|k| (u[0][k] - u[1][k]).powi(2)).sum::<f64>().sqrt())
}

/// The reference position `X` of the material point now at `x` (`X + u(X) = x`), by Newton's
/// method from `x` — how a cut drawn on the deformed body is placed in the total Lagrangian
/// reference configuration. `None` when the iteration leaves the cloud or does not converge.
pub fn pull_back(cloud: &NodeCloud, field: &[f64], x: [f64; 3]) -> Option<[f64; 3]> {
    let d = cloud.dim();
    let mut xr = x;
    let size = cloud.radii().iter().copied().fold(0.0, f64::max);
    for _ in 0..50 {
        let (u, f) = deformation_at(cloud, field, xr).ok()?;
        let mut r = nalgebra::Vector3::zeros();
        for k in 0..d {
            r[k] = xr[k] + u[k] - x[k];
        }
        if r.norm() <= 1e-12 * size.max(f64::MIN_POSITIVE) {
            return Some(xr);
        }
        // in 2D, F₃₃ = 1 and r₃ = 0: the third row and column leave the step alone
        let step = f.lu().solve(&r)?;
        for k in 0..d {
            xr[k] -= step[k];
        }
    }
    None
}
