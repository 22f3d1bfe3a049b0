//! The static linear-elastic solve: assemble `K_ff`, factor it, solve
//! `K_ff u_f = f_f − K_fc ū_c`, and post-process reactions, strain energy and stresses.
//!
//! Stages, in order (each reported to the caller's `on_stage` for progress display, and timed):
//! 1. check that the constraints remove every rigid motion;
//! 2. build the sparsity pattern;
//! 3. assemble;
//! 4. symbolic analysis (fill-reducing ordering; reusable for any matrix of this pattern);
//! 5. numeric Cholesky factorization;
//! 6. triangular solves;
//! 7. post-processing: internal forces, reactions `R = f_int − f_ext` on constrained
//!    degrees of freedom, strain energy `½ uᵀ K u`, cell stresses.

use std::sync::Arc;
use std::time::Instant;

use super::assembly::{self, AssemblyError, DofMap, MaterialMap, SymmetricPattern};
use super::element::{self, Locking};
use crate::mesh::Mesh;
use crate::solve::{self, Cholesky, SolveError};

/// Boundary conditions and loads of a static problem, as full-length vectors over the
/// degrees of freedom (`3·node + component`).
#[derive(Debug, Clone, PartialEq)]
pub struct StaticProblem {
    /// Whether each degree of freedom is prescribed.
    pub constrained: Vec<bool>,
    /// Prescribed displacement (m) of each constrained degree of freedom (others ignored).
    pub prescribed: Vec<f64>,
    /// External nodal forces (N), pressures included as dead loads on the reference surface.
    pub forces: Vec<f64>,
    /// The pressure loads (already in `forces` on the reference surface): a large-deformation
    /// solve makes them follow the deformed surface ([`super::loads::PressureLoad`]).
    pub pressures: Vec<super::loads::PressureLoad>,
    /// Springs to the ground (N/m per degree of freedom; an elastic foundation), zero where
    /// there is none.
    pub springs: Vec<f64>,
}

impl StaticProblem {
    /// A problem with no constraints and no loads on `n_nodes` nodes.
    pub fn new(n_nodes: usize) -> Self {
        Self {
            constrained: vec![false; 3 * n_nodes],
            prescribed: vec![0.0; 3 * n_nodes],
            forces: vec![0.0; 3 * n_nodes],
            pressures: Vec::new(),
            springs: vec![0.0; 3 * n_nodes],
        }
    }

    /// Whether each degree of freedom is held, rigidly or by a spring (what removes rigid
    /// motions).
    pub fn supported(&self) -> Vec<bool> {
        self.constrained.iter().zip(&self.springs).map(|(&c, &s)| c || s > 0.0).collect()
    }

    /// Adds a pressure load: its reference-surface forces to `forces`, and the load itself for
    /// a large-deformation solve to follow.
    pub fn add_pressure(&mut self, mesh: &crate::mesh::Mesh, load: super::loads::PressureLoad) {
        load.add_forces(mesh, None, 1.0, &mut self.forces);
        self.pressures.push(load);
    }

    /// Fixes all three components of `nodes` at zero.
    pub fn clamp(&mut self, nodes: &[usize]) {
        for &n in nodes {
            for i in 0..3 {
                self.constrained[3 * n + i] = true;
                self.prescribed[3 * n + i] = 0.0;
            }
        }
    }

    /// Prescribes component `i` of `nodes` to `value` (m).
    pub fn prescribe(&mut self, nodes: &[usize], i: usize, value: f64) {
        for &n in nodes {
            self.constrained[3 * n + i] = true;
            self.prescribed[3 * n + i] = value;
        }
    }
}

/// A stage of [`solve()`], reported before it starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Checking constraints against rigid motions.
    Check,
    /// Building the sparsity pattern.
    Pattern,
    /// Assembling the stiffness.
    Assembly,
    /// Symbolic analysis.
    Analysis,
    /// Numeric factorization.
    Factorization,
    /// Triangular solves.
    Solve,
    /// Reactions, energy, stresses.
    Post,
}

impl Stage {
    /// A short label for progress displays.
    pub fn label(self) -> &'static str {
        match self {
            Stage::Check => "checking constraints",
            Stage::Pattern => "building sparsity pattern",
            Stage::Assembly => "assembling stiffness",
            Stage::Analysis => "symbolic analysis",
            Stage::Factorization => "Cholesky factorization",
            Stage::Solve => "solving",
            Stage::Post => "post-processing",
        }
    }
}

/// Wall-clock time of each stage (s).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Timings {
    /// Pattern construction.
    pub pattern_s: f64,
    /// Assembly of `K_ff` and the right-hand side.
    pub assembly_s: f64,
    /// Symbolic analysis.
    pub analysis_s: f64,
    /// Numeric factorization.
    pub factorization_s: f64,
    /// Triangular solves.
    pub solve_s: f64,
    /// Post-processing.
    pub post_s: f64,
}

impl Timings {
    /// Sum of all stages.
    pub fn total_s(&self) -> f64 {
        self.pattern_s + self.assembly_s + self.analysis_s + self.factorization_s + self.solve_s + self.post_s
    }
}

/// The result of a static solve.
#[derive(Debug, Clone)]
pub struct StaticSolution {
    /// Displacements (m), full length.
    pub u: Vec<f64>,
    /// Reactions (N) on constrained degrees of freedom, zero elsewhere.
    pub reactions: Vec<f64>,
    /// Strain energy `½ uᵀ K u` (J).
    pub strain_energy: f64,
    /// Relative equilibrium residual on the free degrees of freedom,
    /// `‖f_int − f_ext‖ / max(‖f_ext‖, ‖R‖)`.
    pub residual: f64,
    /// Cell-centre stresses (Voigt, Pa).
    pub stresses: Vec<[f64; 6]>,
    /// Cell von Mises stresses (Pa).
    pub von_mises: Vec<f64>,
    /// Largest nodal displacement magnitude (m).
    pub max_displacement: f64,
    /// The node where it occurs.
    pub max_displacement_node: usize,
    /// Number of equations.
    pub n_free: usize,
    /// Stored non-zeros of the lower triangle of `K_ff`.
    pub nnz: usize,
    /// Stage timings.
    pub timings: Timings,
}

impl StaticSolution {
    /// Displacement of `node`.
    pub fn displacement(&self, node: usize) -> [f64; 3] {
        [self.u[3 * node], self.u[3 * node + 1], self.u[3 * node + 2]]
    }

    /// Sum of reactions over `nodes` (N).
    pub fn reaction_sum(&self, nodes: &[usize]) -> [f64; 3] {
        super::node_sum(&self.reactions, nodes)
    }
}

/// Why a static solve failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum StaticError {
    /// Nothing is constrained: the system is singular.
    #[error(
        "no degree of freedom is fixed, so the body can move freely and the system is singular; give the scene a non-empty fixed region"
    )]
    NoConstraints,
    /// The constraints leave rigid motions free.
    #[error("the fixed region does not stop the body from moving: free {}; fix more nodes or nodes that are not aligned", .free.join("; "))]
    RigidMotion {
        /// The free motions.
        free: Vec<String>,
    },
    /// A cell operator failed.
    #[error(transparent)]
    Assembly(#[from] AssemblyError),
    /// The factorization failed.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The solution is not finite (should not happen once the checks above pass).
    #[error(
        "the solution contains non-finite values (the system is ill-conditioned, or the loads so large that the displacements, stresses or energy overflow): check the material parameters and the loads' magnitudes"
    )]
    NonFinite,
}

/// Solves the static linear-elastic problem. See the module docs for the stages.
pub fn solve(
    mesh: &Mesh,
    materials: &MaterialMap,
    locking: Locking,
    problem: &StaticProblem,
    on_stage: &mut dyn FnMut(Stage),
) -> Result<StaticSolution, StaticError> {
    let n_dofs = mesh.n_dofs();
    assert_eq!(problem.constrained.len(), n_dofs, "problem vectors must have 3 entries per node");
    on_stage(Stage::Check);
    let supported = problem.supported();
    if !supported.iter().any(|c| *c) {
        return Err(StaticError::NoConstraints);
    }
    let free = solve::free_rigid_motions(&mesh.nodes, &supported);
    if !free.is_empty() {
        return Err(StaticError::RigidMotion { free });
    }
    let mut t = Timings::default();

    on_stage(Stage::Pattern);
    let clock = Instant::now();
    let dofs = DofMap::new(&problem.constrained);
    let pattern = Arc::new(SymmetricPattern::for_locking(mesh, &dofs, locking));
    t.pattern_s = clock.elapsed().as_secs_f64();

    on_stage(Stage::Assembly);
    let clock = Instant::now();
    let mut rhs = vec![0.0; dofs.n_free()];
    dofs.restrict(&problem.forces, &mut rhs);
    let mut k = assembly::assemble_stiffness(mesh, materials, locking, &dofs, pattern.clone(), &problem.prescribed, &mut rhs)?;
    assembly::add_springs(&mut k, &dofs, &problem.springs);
    t.assembly_s = clock.elapsed().as_secs_f64();

    on_stage(Stage::Analysis);
    let clock = Instant::now();
    let symbolic = Cholesky::analyze(&k)?;
    t.analysis_s = clock.elapsed().as_secs_f64();

    on_stage(Stage::Factorization);
    let clock = Instant::now();
    let chol = Cholesky::factor_with(symbolic, &k)?;
    t.factorization_s = clock.elapsed().as_secs_f64();

    on_stage(Stage::Solve);
    let clock = Instant::now();
    chol.solve_in_place(&mut rhs);
    t.solve_s = clock.elapsed().as_secs_f64();
    if rhs.iter().any(|v| !v.is_finite()) {
        return Err(StaticError::NonFinite);
    }

    on_stage(Stage::Post);
    let clock = Instant::now();
    let mut u = vec![0.0; n_dofs];
    dofs.expand(&rhs, &problem.prescribed, &mut u);
    let mut f_int = assembly::internal_forces(mesh, materials, locking, &u)?;
    let mut reactions = vec![0.0; n_dofs];
    let (mut res2, mut fext2, mut r2) = (0.0, 0.0, 0.0);
    for d in 0..n_dofs {
        // a spring to the ground carries −k u: the foundation's reaction
        let spring = problem.springs[d] * u[d];
        let r = f_int[d] + spring - problem.forces[d];
        if problem.constrained[d] {
            reactions[d] = r;
            r2 += r * r;
        } else {
            res2 += r * r;
            fext2 += problem.forces[d] * problem.forces[d];
            if spring != 0.0 {
                reactions[d] = -spring;
                r2 += spring * spring;
            }
        }
        f_int[d] += spring;
    }
    let strain_energy = 0.5 * u.iter().zip(&f_int).map(|(a, b)| a * b).sum::<f64>();
    let stresses = assembly::cell_stresses(mesh, materials, locking, &u)?;
    let von_mises: Vec<f64> = stresses.iter().map(|s| element::von_mises(*s)).collect();
    // a finite displacement can still overflow what is made of it (a load of 1e308 gave
    // every figure as infinity, printed as null): a result is finite throughout or an error
    if !(strain_energy.is_finite() && reactions.iter().chain(&von_mises).all(|x| x.is_finite())) {
        return Err(StaticError::NonFinite);
    }
    let (mut max_displacement, mut max_displacement_node) = (0.0, 0);
    for n in 0..mesh.n_nodes() {
        let m = (u[3 * n].powi(2) + u[3 * n + 1].powi(2) + u[3 * n + 2].powi(2)).sqrt();
        if m > max_displacement {
            max_displacement = m;
            max_displacement_node = n;
        }
    }
    t.post_s = clock.elapsed().as_secs_f64();
    let denom = fext2.max(r2).sqrt().max(f64::MIN_POSITIVE);
    Ok(StaticSolution {
        u,
        reactions,
        strain_energy,
        residual: res2.sqrt() / denom,
        stresses,
        von_mises,
        max_displacement,
        max_displacement_node,
        n_free: dofs.n_free(),
        nnz: pattern.nnz(),
        timings: t,
    })
}
