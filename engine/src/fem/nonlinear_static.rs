//! Static equilibrium at large deformations: Newton–Raphson on the total Lagrangian
//! hyperelastic cells of [`super::hyperelastic`], with load stepping, a consistent predictor,
//! a backtracking line search on the potential energy, and step cutting when Newton fails.
//!
//! # The method
//! Find the displacement `u` (with `u = λū` on the constrained degrees of freedom) such that
//! the residual `r(u) = λ f_ext − f_int(u)` vanishes on the free ones, for load factors
//! `λ` stepping from 0 to 1. Each step:
//!
//! 1. *predictor* — the tangent response to the increment of prescribed displacement and
//!    load: `K_ff Δu_f = −K_fc Δū_c + Δλ f_ext,f` (without it a large prescribed step would
//!    invert the cells next to the moving boundary);
//! 2. *Newton* — `K_ff δu = r_f`, then `u ← u + α δu` with `α` halved until the potential
//!    energy `Π = Σ_e Π_e − λ f_ext·u` decreases enough (Armijo) and no cell inverts;
//!    converged when `‖r_f‖ ≤ tol · max(‖λ f_ext‖, ‖f_int,c‖)` (external load or reaction);
//! 3. on failure (no convergence, an inverted cell, a tangent that is not positive definite)
//!    the step is halved and retried from the last equilibrium, down to a minimum step.
//!
//! The sparsity pattern and the symbolic Cholesky factorization are computed once and reused
//! by every factorization.

use std::sync::Arc;

use super::assembly::{DofMap, SymmetricMatrix, SymmetricPattern, scatter_cell};
use super::hyperelastic::{self, CellError, CellScratch, LawMap, Volumetric};
use super::linear_static::StaticProblem;
use super::nodal::{NodalPatches, NodalVolumes, PatchError};
use crate::material::hyperelastic::Hyperelastic;
use crate::mesh::Mesh;
use crate::solve::{Cholesky, SolveError};

/// Newton–Raphson settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonParams {
    /// Initial number of load steps (the step grows back after cuts).
    pub steps: usize,
    /// Newton iterations per step before the step is cut.
    pub max_iterations: usize,
    /// Relative residual tolerance.
    pub tolerance: f64,
    /// Smallest load-factor step before giving up.
    pub min_step: f64,
}

impl Default for NewtonParams {
    /// Four steps (a 20 % stretch in 5 % increments converges in 3–5 iterations each),
    /// 25 iterations, 1e-9 (far below discretization error), steps down to 1e-4.
    fn default() -> Self {
        Self {
            steps: 4,
            max_iterations: 25,
            tolerance: 1e-9,
            min_step: 1e-4,
        }
    }
}

/// How the solve went.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NewtonInfo {
    /// Load steps taken (converged).
    pub steps: usize,
    /// Newton iterations in all.
    pub iterations: usize,
    /// Step cuts.
    pub cuts: usize,
    /// Final relative residual.
    pub residual: f64,
    /// `(λ, strain energy)` after each converged step.
    pub path: Vec<(f64, f64)>,
}

/// A solved large-deformation problem.
#[derive(Debug, Clone)]
pub struct NonlinearSolution {
    /// Displacement of every degree of freedom (m).
    pub u: Vec<f64>,
    /// Internal forces on every degree of freedom (N); on constrained ones, the reaction.
    pub f_int: Vec<f64>,
    /// Strain energy (J).
    pub energy: f64,
    /// Iterations, cuts, load path.
    pub info: NewtonInfo,
}

impl NonlinearSolution {
    /// Sum of the reactions over `nodes` (N).
    pub fn reaction_sum(&self, nodes: &[usize]) -> [f64; 3] {
        super::node_sum(&self.f_int, nodes)
    }
}

/// Why the solve stopped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NonlinearError {
    /// A reference cell is degenerate.
    #[error("cell {cell}: {source}")]
    Mesh {
        /// The cell.
        cell: usize,
        /// Why.
        source: CellError,
    },
    /// The continuation stopped without reaching equilibrium: the step fell below the minimum,
    /// or the load factor stagnated over many step cuts (a limit point).
    #[error(
        "no equilibrium beyond load factor {load_factor:.4} of the {laws} organ ({why}; the last attempt: {reason}{}{}); {hint}",
        residual.map(|r| format!(", relative residual {r:.2e}")).unwrap_or_default(),
        j_min.map(|(j, c)| format!(", smallest det F {j:.3} in cell {c}")).unwrap_or_default()
    )]
    NoConvergence {
        /// Last converged load factor.
        load_factor: f64,
        /// The step that failed.
        step: f64,
        /// Relative residual of the last attempt, when it got as far as one.
        residual: Option<f64>,
        /// Why the last attempt failed.
        reason: Box<str>,
        /// Why the continuation gave up (step below the minimum, or stagnation).
        why: Box<str>,
        /// The laws of the organ, by name.
        laws: Box<str>,
        /// The smallest `det F` over the cells at the last equilibrium, and its cell.
        j_min: Option<(f64, usize)>,
        /// What to try.
        hint: &'static str,
    },
    /// The problem is malformed.
    #[error("{0}")]
    Invalid(String),
}

struct Assembled {
    energy: f64,
    f_int: Vec<f64>,
    k: Option<SymmetricMatrix>,
    /// `−K_fc Δū_c` (length `n_free`).
    predictor: Vec<f64>,
}

struct Model<'a> {
    mesh: &'a Mesh,
    laws: &'a LawMap,
    volumetric: Volumetric,
    dofs: DofMap,
    pattern: Arc<SymmetricPattern>,
    /// The nodal patches under [`Volumetric::Nodal`] on tetrahedra.
    patches: Option<NodalPatches>,
    /// Follower pressures (their reference-surface forces are in the problem's forces).
    pressures: &'a [super::loads::PressureLoad],
    /// Springs to the ground (N/m per degree of freedom).
    springs: &'a [f64],
}

enum AssembleError {
    Cell(usize, CellError),
}

impl Model<'_> {
    /// Energy and internal forces at `u`; with `tangent`, also `K_ff` and `−K_fc Δū_c`. Follower
    /// pressures at load factor `lambda` enter as their change from the reference surface,
    /// `f_int − λ (f_p(u) − f_p(0))`, and their load stiffness `− λ ∂f_p/∂u` (symmetric part).
    fn assemble(&self, u: &[f64], lambda: f64, tangent: bool, delta_prescribed: Option<&[f64]>) -> Result<Assembled, AssembleError> {
        let mesh = self.mesh;
        let n = mesh.kind.nodes_per_cell();
        let nd = 3 * n;
        let mut s = CellScratch::new(mesh.kind);
        let (mut fe, mut ke) = (vec![0.0; nd], vec![0.0; nd * nd]);
        let (mut x, mut ue) = (vec![[0.0; 3]; n], vec![0.0; nd]);
        let mut f_int = vec![0.0; u.len()];
        let mut k = tangent.then(|| SymmetricMatrix::zeros(self.pattern.clone()));
        let mut predictor = vec![0.0; self.dofs.n_free()];
        let nodal = match &self.patches {
            Some(p) => Some(NodalVolumes::at(mesh, p, self.laws, u).map_err(|(c, e)| AssembleError::Cell(c, e))?),
            None => None,
        };
        let mut energy = nodal.as_ref().map_or(0.0, |nv| nv.energy);
        let mut eqs = vec![None; nd];
        for c in 0..mesh.n_cells() {
            mesh.cell_coords(c, &mut x);
            let cell = mesh.cell(c);
            for a in 0..n {
                for i in 0..3 {
                    ue[3 * a + i] = u[3 * cell[a] + i];
                    eqs[3 * a + i] = self.dofs.eq(3 * cell[a] + i);
                }
            }
            let st = hyperelastic::cell(
                mesh.kind,
                &x,
                &ue,
                self.laws.of(c),
                self.volumetric,
                &mut s,
                &mut fe,
                k.as_ref().map(|_| &mut ke[..]),
            )
            .map_err(|e| AssembleError::Cell(c, e))?;
            if let Some(nv) = &nodal {
                nv.add_cell_terms(c, &mut fe, k.as_ref().map(|_| &mut ke[..]));
            }
            energy += st.energy;
            for p in 0..nd {
                f_int[3 * cell[p / 3] + p % 3] += fe[p];
            }
            if let Some(k) = k.as_mut() {
                scatter_cell(k, &ke, cell, &eqs, delta_prescribed, &mut predictor);
            }
        }
        if let (Some(nv), Some(patches), Some(k)) = (&nodal, &self.patches, k.as_mut()) {
            nv.scatter_node_terms(mesh, patches, &self.dofs, k, delta_prescribed, &mut predictor);
        }
        // springs to the ground (an elastic foundation): energy ½ k u², force k u, stiffness k
        for (d, &ks) in self.springs.iter().enumerate() {
            if ks != 0.0 {
                energy += 0.5 * ks * u[d] * u[d];
                f_int[d] += ks * u[d];
            }
        }
        if let Some(k) = k.as_mut() {
            super::assembly::add_springs(k, &self.dofs, self.springs);
        }
        if lambda != 0.0 {
            for p in self.pressures {
                p.add_forces(mesh, Some(u), -lambda, &mut f_int);
                p.add_forces(mesh, None, lambda, &mut f_int);
                if let Some(k) = k.as_mut() {
                    let mut face_eqs = Vec::new();
                    p.for_each_stiffness(mesh, u, -lambda, |nodes, block| {
                        face_eqs.clear();
                        face_eqs.extend(nodes.iter().flat_map(|&n| (0..3).map(move |i| 3 * n + i)).map(|d| self.dofs.eq(d)));
                        scatter_cell(k, block, nodes, &face_eqs, delta_prescribed, &mut predictor);
                    });
                }
            }
        }
        Ok(Assembled {
            energy,
            f_int,
            k,
            predictor,
        })
    }
}

/// The nodal patches when `volumetric` averages over nodes of a tetrahedral mesh.
fn nodal_patches(mesh: &Mesh, volumetric: Volumetric) -> Result<Option<NodalPatches>, NonlinearError> {
    NodalPatches::when(mesh, volumetric == Volumetric::Nodal).map_err(|e| match e {
        PatchError::Degenerate { cell, volume } => NonlinearError::Mesh {
            cell,
            source: CellError::Reference { det: 6.0 * volume },
        },
        PatchError::NotTetrahedra => NonlinearError::Invalid(e.to_string()),
    })
}

/// Why a tangent could not be factorized, in the terms of a large-deformation solve of `laws`.
fn tangent_failure(e: SolveError, laws: &LawMap) -> String {
    let svk = laws.laws.iter().any(|l| !l.splits());
    match e {
        SolveError::NotPositiveDefinite { pivot, n } => format!(
            "the tangent stiffness is not positive definite at this deformation (pivot {pivot} of {n}): {}",
            if svk {
                "St Venant-Kirchhoff softens and loses stability in strong compression, or a slender part buckles"
            } else {
                "a structural instability (a slender part buckles or snaps through) or an unconstrained rigid motion"
            }
        ),
        SolveError::Internal(m) => format!("the factorization failed: {m}"),
    }
}

/// The names of the laws in `laws`, for messages (`neo-Hookean`, `Mooney-Rivlin and St
/// Venant-Kirchhoff`).
fn law_names(laws: &LawMap) -> String {
    let mut names: Vec<&str> = laws
        .laws
        .iter()
        .map(|l| match l {
            Hyperelastic::StVenantKirchhoff { .. } => "St Venant-Kirchhoff",
            Hyperelastic::NeoHookean { .. } => "neo-Hookean",
            Hyperelastic::MooneyRivlin { .. } => "Mooney-Rivlin",
        })
        .collect();
    names.dedup();
    names.join(" and ")
}

/// The smallest `det F` over the cells' integration points at `u`, and its cell.
fn smallest_det_f(mesh: &Mesh, u: &[f64]) -> Option<(f64, usize)> {
    let n = mesh.kind.nodes_per_cell();
    let mut s = CellScratch::new(mesh.kind);
    let (mut x, mut ue) = (vec![[0.0; 3]; n], vec![0.0; 3 * n]);
    let mut best: Option<(f64, usize)> = None;
    for c in 0..mesh.n_cells() {
        mesh.cell_coords(c, &mut x);
        for (a, &node) in mesh.cell(c).iter().enumerate() {
            ue[3 * a..3 * a + 3].copy_from_slice(&u[3 * node..3 * node + 3]);
        }
        let _ = hyperelastic::for_each_point(mesh.kind, &x, &mut s, |_, g| {
            let d = hyperelastic::deformation_gradient(&ue, g).determinant();
            if best.is_none_or(|(b, _)| d < b) {
                best = Some((d, c));
            }
        });
    }
    best
}

/// Step cuts without the load factor advancing by [`STAGNATION_ADVANCE`] after which the
/// continuation stops: it is creeping towards a limit point (no equilibrium beyond), and
/// halving on would only take longer to say so.
const STAGNATION_CUTS: usize = 8;

/// The advance of the load factor that counts as progress for [`STAGNATION_CUTS`].
const STAGNATION_ADVANCE: f64 = 0.01;

/// Newton iterations in a row without the residual decreasing after which an attempt is
/// abandoned as diverging (the step is then cut at once instead of after every iteration).
const DIVERGING_ITERATIONS: usize = 4;

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The symbolic analysis of the tangent's pattern, made at the first factorization and
/// reused by every later one.
#[derive(Default)]
struct Factorizer {
    symbolic: Option<faer::sparse::linalg::solvers::SymbolicLlt<usize>>,
}

impl Factorizer {
    fn factor(&mut self, k: &SymmetricMatrix) -> Result<Cholesky, SolveError> {
        let sym = match &self.symbolic {
            Some(s) => s,
            None => self.symbolic.insert(Cholesky::analyze(k)?),
        };
        Cholesky::factor_with(sym.clone(), k)
    }
}

/// One load step from the converged state `u` at load factor `lambda` to `target`: the
/// consistent predictor for the prescribed displacements' increment, then Newton–Raphson with
/// an Armijo line search on the potential energy (on the residual with follower pressures).
/// The converged state, its assembly, residual and iterations; or why it failed, with the
/// last residual.
fn load_step(
    model: &Model<'_>,
    problem: &StaticProblem,
    f_ext_f: &[f64],
    factor: &mut Factorizer,
    params: &NewtonParams,
    u: &[f64],
    lambda: f64,
    target: f64,
) -> Result<(Vec<f64>, Assembled, f64, usize), (String, Option<f64>)> {
    let nd = u.len();
    let nf = model.dofs.n_free();
    let potential = |energy: f64, lambda: f64, u: &[f64]| energy - lambda * dot(&problem.forces, u);
    let cell_err = |AssembleError::Cell(c, e)| (format!("cell {c}: {e}"), None);
    // 1. predictor
    let delta: Vec<f64> = (0..nd)
        .map(|d| {
            if problem.constrained[d] {
                (target - lambda) * problem.prescribed[d]
            } else {
                0.0
            }
        })
        .collect();
    let a = model.assemble(u, target, true, Some(&delta)).map_err(cell_err)?;
    let mut rhs = a.predictor.clone();
    let mut r0 = vec![0.0; nf];
    model.dofs.restrict(&a.f_int, &mut r0);
    for e in 0..nf {
        rhs[e] += target * f_ext_f[e] - r0[e];
    }
    let chol = factor
        .factor(a.k.as_ref().expect("tangent assembled"))
        .map_err(|e| (tangent_failure(e, model.laws), None))?;
    chol.solve_in_place(&mut rhs);
    let mut ut = u.to_vec();
    for d in 0..nd {
        if problem.constrained[d] {
            ut[d] = target * problem.prescribed[d];
        } else if let Some(e) = model.dofs.eq(d) {
            ut[d] += rhs[e];
        }
    }
    // 2. Newton with line search
    let mut iterations = 0;
    let (mut best, mut since_best) = (f64::INFINITY, 0);
    loop {
        let a = model.assemble(&ut, target, true, None).map_err(cell_err)?;
        let mut r = vec![0.0; nf];
        model.dofs.restrict(&a.f_int, &mut r);
        for e in 0..nf {
            r[e] = target * f_ext_f[e] - r[e];
        }
        let reaction: f64 = (0..nd)
            .filter(|&d| problem.constrained[d])
            .map(|d| a.f_int[d] * a.f_int[d])
            .sum::<f64>()
            .sqrt();
        let scale = (target * norm(f_ext_f)).max(reaction).max(f64::MIN_POSITIVE);
        let residual = norm(&r) / scale;
        if !residual.is_finite() {
            return Err(("the residual is not finite (a law evaluated outside its domain)".into(), None));
        }
        if residual <= params.tolerance {
            return Ok((ut, a, residual, iterations));
        }
        if iterations >= params.max_iterations {
            return Err((format!("no convergence in {iterations} Newton iterations"), Some(residual)));
        }
        if residual < best {
            (best, since_best) = (residual, 0);
        } else {
            since_best += 1;
            if since_best >= DIVERGING_ITERATIONS {
                return Err((
                    format!("Newton diverges (the residual has not decreased in {since_best} iterations)"),
                    Some(residual),
                ));
            }
        }
        iterations += 1;
        let chol = factor
            .factor(a.k.as_ref().expect("tangent assembled"))
            .map_err(|e| (tangent_failure(e, model.laws), Some(residual)))?;
        let mut du = r.clone();
        chol.solve_in_place(&mut du);
        let p0 = potential(a.energy, target, &ut);
        let slope = -dot(&r, &du);
        let mut alpha = 1.0;
        let next = loop {
            let mut trial = ut.clone();
            for d in 0..nd {
                if let Some(e) = model.dofs.eq(d) {
                    trial[d] += alpha * du[e];
                }
            }
            // follower pressures have no potential here: their merit is the residual
            let accept = |t: &Assembled| {
                if model.pressures.is_empty() {
                    potential(t.energy, target, &trial) <= p0 + 1e-4 * alpha * slope
                } else {
                    let mut rt = vec![0.0; nf];
                    model.dofs.restrict(&t.f_int, &mut rt);
                    let rt: f64 = rt
                        .iter()
                        .zip(f_ext_f)
                        .map(|(fi, fe)| (target * fe - fi).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    rt <= (1.0 - 1e-4 * alpha) * norm(&r)
                }
            };
            match model.assemble(&trial, target, false, None) {
                Ok(t) if accept(&t) || alpha < 1.0 / 64.0 => break trial,
                Ok(_) | Err(AssembleError::Cell(..)) if alpha >= 1.0 / 1024.0 => alpha /= 2.0,
                Ok(_) => break trial,
                Err(e) => return Err(cell_err(e)),
            }
        };
        ut = next;
    }
}

/// Solves `problem` (prescribed displacements and nodal forces, applied proportionally to
/// the load factor) on `mesh` made of `laws`; `progress(λ, u)` is called after each converged
/// step with its load factor and displacement (the snapshots of a POD basis).
pub fn solve(
    mesh: &Mesh,
    laws: &LawMap,
    volumetric: Volumetric,
    problem: &StaticProblem,
    params: &NewtonParams,
    mut progress: impl FnMut(f64, &[f64]),
) -> Result<NonlinearSolution, NonlinearError> {
    let nd = 3 * mesh.n_nodes();
    if problem.constrained.len() != nd || problem.prescribed.len() != nd || problem.forces.len() != nd {
        return Err(NonlinearError::Invalid(format!(
            "the problem's vectors must have 3 × {} entries",
            mesh.n_nodes()
        )));
    }
    let positive = |x: f64| x.is_finite() && x > 0.0;
    if params.steps == 0 || !positive(params.tolerance) || !positive(params.min_step) {
        return Err(NonlinearError::Invalid("steps, tolerance and minimum step must be positive".into()));
    }
    let dofs = DofMap::new(&problem.constrained);
    let patches = nodal_patches(mesh, volumetric)?;
    let pattern = Arc::new(SymmetricPattern::with_patches(mesh, &dofs, patches.as_ref()));
    if laws.of_cell.len() != mesh.n_cells() || laws.of_cell.iter().any(|&i| i as usize >= laws.laws.len()) {
        return Err(NonlinearError::Invalid(format!(
            "the law map must name a law for each of the {} cells",
            mesh.n_cells()
        )));
    }
    let model = Model {
        mesh,
        laws,
        volumetric,
        dofs,
        pattern,
        patches,
        pressures: &problem.pressures,
        springs: &problem.springs,
    };
    let nf = model.dofs.n_free();
    let f_ext_f = {
        let mut f = vec![0.0; nf];
        model.dofs.restrict(&problem.forces, &mut f);
        f
    };
    let mut factor = Factorizer::default();
    let mut info = NewtonInfo::default();
    let mut u = vec![0.0; nd];
    let (mut lambda, mut step) = (0.0f64, 1.0 / params.steps as f64);
    // the continuation's progress: the load factor at the last real advance, and the cuts since
    let (mut progress_mark, mut cuts_since_progress) = (0.0f64, 0usize);
    let mut last = model
        .assemble(&u, 0.0, false, None)
        .map_err(|AssembleError::Cell(cell, source)| NonlinearError::Mesh { cell, source })?;
    while lambda < 1.0 {
        let target = (lambda + step).min(1.0);
        let attempt = load_step(&model, problem, &f_ext_f, &mut factor, params, &u, lambda, target);
        match attempt {
            Ok((ut, a, residual, iterations)) => {
                u = ut;
                last = a;
                lambda = target;
                info.steps += 1;
                info.iterations += iterations;
                info.residual = residual;
                info.path.push((lambda, last.energy));
                progress(lambda, &u);
                step = (step * 1.5).min(1.0 / params.steps as f64);
                if lambda - progress_mark >= STAGNATION_ADVANCE {
                    (progress_mark, cuts_since_progress) = (lambda, 0);
                }
            }
            Err((reason, residual)) => {
                info.cuts += 1;
                cuts_since_progress += 1;
                step /= 2.0;
                let why = if step < params.min_step {
                    Some(format!("the load step was cut below {:.0e}", params.min_step))
                } else if cuts_since_progress >= STAGNATION_CUTS {
                    Some(format!(
                        "the load factor advanced less than {STAGNATION_ADVANCE} over {cuts_since_progress} step cuts: a limit point"
                    ))
                } else {
                    None
                };
                if let Some(why) = why {
                    let svk = laws.laws.iter().any(|l| !l.splits());
                    return Err(NonlinearError::NoConvergence {
                        load_factor: lambda,
                        step,
                        residual,
                        reason: reason.into(),
                        why: why.into(),
                        laws: law_names(laws).into(),
                        j_min: smallest_det_f(mesh, &u),
                        hint: if svk {
                            "the load may be beyond what St Venant-Kirchhoff can carry (it softens in compression): lower it, or use neo_hookean"
                        } else {
                            "the load may be beyond what the organ can carry (or a part is unstable): lower it, or support the organ where it gives way"
                        },
                    });
                }
            }
        }
    }
    Ok(NonlinearSolution {
        u,
        f_int: last.f_int,
        energy: last.energy,
        info,
    })
}

/// Solves like [`solve`] and reports the result in the form of a linear static solution
/// (reactions on the constrained degrees of freedom, Cauchy stress and von Mises at cell
/// centres, largest displacement), with the Newton time as the solve time.
pub fn solve_static(
    mesh: &Mesh,
    laws: &LawMap,
    volumetric: Volumetric,
    problem: &StaticProblem,
    params: &NewtonParams,
    mut progress: impl FnMut(f64),
) -> Result<(super::linear_static::StaticSolution, NewtonInfo), NonlinearError> {
    let t = std::time::Instant::now();
    let sol = solve(mesh, laws, volumetric, problem, params, |l, _| progress(l))?;
    let newton_s = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let n = mesh.kind.nodes_per_cell();
    let mut s = CellScratch::new(mesh.kind);
    let (mut x, mut ue) = (vec![[0.0; 3]; n], vec![0.0; 3 * n]);
    let mut stresses = Vec::with_capacity(mesh.n_cells());
    let patches = nodal_patches(mesh, volumetric)?;
    let nodal = match &patches {
        Some(p) => Some(NodalVolumes::at(mesh, p, laws, &sol.u).map_err(|(cell, source)| NonlinearError::Mesh { cell, source })?),
        None => None,
    };
    for c in 0..mesh.n_cells() {
        mesh.cell_coords(c, &mut x);
        let cell = mesh.cell(c);
        for a in 0..n {
            for i in 0..3 {
                ue[3 * a + i] = sol.u[3 * cell[a] + i];
            }
        }
        let pressure = nodal.as_ref().map(|nv| nv.pressure(c));
        let v = hyperelastic::cauchy_at_centre(mesh.kind, &x, &ue, laws.of(c), volumetric, pressure, &mut s)
            .map_err(|source| NonlinearError::Mesh { cell: c, source })?;
        // the linear solution's order: xx, yy, zz, xy, yz, zx
        stresses.push([v[0], v[1], v[2], v[5], v[3], v[4]]);
    }
    let von_mises = stresses.iter().map(|&v| super::element::von_mises(v)).collect();
    let reactions: Vec<f64> = (0..sol.u.len())
        .map(|d| {
            if problem.constrained[d] {
                sol.f_int[d] - problem.forces[d]
            } else {
                // a spring to the ground carries −k u
                -problem.springs[d] * sol.u[d]
            }
        })
        .collect();
    let (mut max_displacement, mut max_displacement_node) = (0.0, 0);
    for i in 0..mesh.n_nodes() {
        let m = (0..3).map(|k| sol.u[3 * i + k].powi(2)).sum::<f64>().sqrt();
        if m > max_displacement {
            (max_displacement, max_displacement_node) = (m, i);
        }
    }
    let dofs = DofMap::new(&problem.constrained);
    let n_free = dofs.n_free();
    let nnz = SymmetricPattern::with_patches(mesh, &dofs, patches.as_ref()).nnz();
    let timings = super::linear_static::Timings {
        solve_s: newton_s,
        post_s: t.elapsed().as_secs_f64(),
        ..Default::default()
    };
    Ok((
        super::linear_static::StaticSolution {
            u: sol.u,
            reactions,
            strain_energy: sol.energy,
            residual: sol.info.residual,
            stresses,
            von_mises,
            max_displacement,
            max_displacement_node,
            n_free,
            nnz,
            timings,
        },
        sol.info,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::linear_static::StaticProblem;
    use crate::material::LinearElastic;
    use crate::material::hyperelastic::Hyperelastic;
    use crate::mesh::procedural::block_tet;

    /// A St Venant-Kirchhoff block pressed beyond its limit load (it softens in compression:
    /// its uniaxial nominal stress bottoms out near 0.38 E) stops with a diagnostic naming the
    /// law, why the continuation gave up and the smallest det F, and no "NaN".
    #[test]
    fn a_load_beyond_the_limit_point_is_reported_with_the_law_and_det_f() {
        use crate::mesh::procedural::block_hex;
        let mesh = block_hex([0.0; 3], [0.01; 3], [2, 2, 2]);
        let m = LinearElastic::new(1000.0, 0.3).unwrap();
        let mut p = StaticProblem::new(mesh.n_nodes());
        let on = |z: f64| -> Vec<usize> { (0..mesh.n_nodes()).filter(|&i| (mesh.nodes[i][2] - z).abs() < 1e-12).collect() };
        let (bottom, top) = (on(0.0), on(0.01));
        p.clamp(&bottom);
        for &n in &top {
            p.forces[3 * n + 2] = -0.6 * 1000.0 * 1e-4 / top.len() as f64;
        }
        let laws = LawMap::uniform(Hyperelastic::svk(&m), mesh.n_cells());
        let e = solve(&mesh, &laws, Volumetric::MeanDilatation, &p, &NewtonParams::default(), |_, _| {}).unwrap_err();
        let NonlinearError::NoConvergence { load_factor, j_min, .. } = &e else {
            panic!("{e:?}")
        };
        assert!(*load_factor < 1.0 && j_min.is_some_and(|(j, _)| j > 0.0 && j < 1.0), "{e:?}");
        let msg = e.to_string();
        assert!(
            msg.contains("St Venant-Kirchhoff organ") && msg.contains("smallest det F") && !msg.contains("NaN"),
            "{msg}"
        );
    }

    /// An eighth of a cube under a uniform follower pressure on its three outer faces (rollers on
    /// the symmetry planes) compresses uniformly to the exact `J = 1 − p/K` of a decoupled law
    /// (Cauchy stress `−p I = U'(J) I`); as a dead load on the reference faces it would reach
    /// `J ≈ 0.761` instead of 0.8 at `p = 0.2 K`.
    #[test]
    fn a_follower_pressure_compresses_a_cube_to_the_exact_volume() {
        use crate::fem::loads::PressureLoad;
        use crate::mesh::boundary::Boundary;
        use crate::mesh::procedural::block_hex;
        let l = 0.01;
        let m = LinearElastic::new(3000.0, 0.3).unwrap();
        let law = Hyperelastic::neo_hookean(&m);
        let kappa = m.bulk();
        let pressure = 0.2 * kappa;
        for (mesh, vol) in [
            (block_hex([0.0; 3], [l; 3], [2, 2, 2]), Volumetric::MeanDilatation),
            (block_tet([0.0; 3], [l; 3], [2, 2, 2]), Volumetric::Nodal),
        ] {
            let mut p = StaticProblem::new(mesh.n_nodes());
            for (n, x) in mesh.nodes.iter().enumerate() {
                for i in 0..3 {
                    if x[i].abs() < 1e-12 {
                        p.constrained[3 * n + i] = true;
                    }
                }
            }
            let b = Boundary::of(&mesh);
            let outer: Vec<usize> = (0..b.faces.len())
                .filter(|&f| (0..3).any(|i| b.faces[f].node_slice().iter().all(|&n| (mesh.nodes[n][i] - l).abs() < 1e-12)))
                .collect();
            p.add_pressure(&mesh, PressureLoad::on(&b, &outer, pressure));
            let laws = LawMap::uniform(law, mesh.n_cells());
            let sol = solve(&mesh, &laws, vol, &p, &NewtonParams::default(), |_, _| {}).unwrap();
            let corner = mesh.nodes.iter().position(|x| x.iter().all(|c| (c - l).abs() < 1e-12)).unwrap();
            let stretch = 1.0 + sol.u[3 * corner] / l;
            let j = stretch.powi(3);
            assert!(
                (j - (1.0 - pressure / kappa)).abs() < 1e-6,
                "{:?}: J = {j}, exact {}",
                mesh.kind,
                1.0 - pressure / kappa
            );
        }
    }

    /// Under the nodal pressure the assembled forces are the gradient of the assembled
    /// energy and the tangent their Jacobian (central differences), with laws that split and
    /// one that does not side by side, and springs to the ground on some degrees of freedom.
    #[test]
    fn nodal_pressure_forces_and_tangent_are_derivatives_of_the_energy() {
        let mesh = block_tet([0.0; 3], [0.02, 0.01, 0.01], [2, 1, 1]);
        let m = LinearElastic::new(3000.0, 0.49).unwrap();
        let laws = LawMap {
            laws: vec![
                Hyperelastic::neo_hookean(&m),
                Hyperelastic::mooney_rivlin(&m, 0.3).unwrap(),
                Hyperelastic::svk(&m),
            ],
            of_cell: (0..mesh.n_cells()).map(|c| [0, 0, 1, 0, 2, 1][c % 6]).collect(),
        };
        let dofs = DofMap::new(&vec![false; mesh.n_dofs()]);
        let patches = nodal_patches(&mesh, Volumetric::Nodal).unwrap();
        // an elastic foundation under some nodes: energy ½ k u², its force and stiffness too
        let springs: Vec<f64> = (0..mesh.n_dofs()).map(|d| if d % 7 == 0 { 50.0 } else { 0.0 }).collect();
        let model = Model {
            mesh: &mesh,
            laws: &laws,
            volumetric: Volumetric::Nodal,
            pattern: Arc::new(SymmetricPattern::with_patches(&mesh, &dofs, patches.as_ref())),
            dofs,
            patches,
            pressures: &[],
            springs: &springs,
        };
        let n = mesh.n_dofs();
        let u: Vec<f64> = (0..n).map(|i| 4e-4 * ((i as f64 * 1.3).sin() + 0.2 * (i % 3) as f64)).collect();
        let a = model.assemble(&u, 1.0, true, None).ok().unwrap();
        let k = a.k.unwrap();
        let fmax = a.f_int.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let h = 1e-8;
        let mut kmax = 0.0f64;
        let mut cols = Vec::new();
        for d in 0..n {
            let mut e = vec![0.0; n];
            e[d] = 1.0;
            let mut col = vec![0.0; n];
            k.mul_vec(&e, &mut col);
            kmax = col.iter().fold(kmax, |m, v| m.max(v.abs()));
            cols.push(col);
        }
        for d in 0..n {
            let (mut up, mut um) = (u.clone(), u.clone());
            up[d] += h;
            um[d] -= h;
            let (p, m) = (
                model.assemble(&up, 1.0, false, None).ok().unwrap(),
                model.assemble(&um, 1.0, false, None).ok().unwrap(),
            );
            let fd = (p.energy - m.energy) / (2.0 * h);
            assert!((fd - a.f_int[d]).abs() < 1e-5 * fmax, "f[{d}]: {fd} vs {}", a.f_int[d]);
            for r in 0..n {
                let kd = (p.f_int[r] - m.f_int[r]) / (2.0 * h);
                assert!((kd - cols[d][r]).abs() < 1e-5 * kmax, "K[{r}][{d}]: {kd} vs {}", cols[d][r]);
            }
        }
    }
}
