//! The full-order reference: the explicit incremental finite-element scheme of seed 000
//! Alg. 4.1, and the equilibrium-iterated (Newton) scheme it approximates.
//!
//! # Explicit (Alg. 4.1)
//! Per pseudo-time step: assemble `K_t` with the damage of the last step
//! (`C_t = g_t C⁰ − (h_t/r_t) σ⁰_t⊗σ⁰_t` with [`Tangent::Consistent`] — the sign and the `1/r`
//! corrected, see [`super::law`] —, or `g_t C⁰` with [`Tangent::Secant`], the seed's
//! simplification h = 0 of §4.5.3), solve `K_t ∆u = ∆f`, add `∆u`, update the damage at every
//! point. It is forward Euler on the damage: nothing brings the state back to equilibrium, so
//! it drifts, and after a load–unload cycle it need not return to the start
//! (`the_explicit_scheme_drifts_where_newton_returns`).
//!
//! # Newton
//! Per step: find `u` with `f_int(u) = f_ext` where `f_int = Σ_p w_p g(max(r_n, Φ_p(u))) B̄ᵀσ⁰`,
//! by Newton's method on the consistent tangent (the secant where the tangent is not positive
//! definite — past a stress peak —, which still converges, linearly). This is the equilibrium
//! path the explicit scheme approximates.
//!
//! # Fast pulls
//! A step that would raise some point's damage by more than `max_damage_increment` is split
//! in halves (up to [`MAX_SPLITS`] times): a pull faster than one step can follow is
//! followed in sub-steps, and the report says how many.

use super::law::PointState;
use super::model::TearModel;
use super::points::Sym;
use crate::solve::{Cholesky, SolveError};

/// How often a step may be halved.
pub const MAX_SPLITS: u32 = 8;

/// Newton iterations without a new smallest residual after which a step is split instead of
/// iterated further (it is not converging: typically the step crosses the onset of
/// localisation).
const STALL: usize = 8;

/// The stiffness of an explicit step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Tangent {
    /// `g C⁰`: the seed's simplified model (h = 0, §4.5.3).
    Secant,
    /// `g C⁰ − (h/r) σ⁰⊗σ⁰`: the full model (Eq. 4.11).
    Consistent,
}

/// The scheme of a reference run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scheme {
    /// Alg. 4.1 with the given stiffness.
    Explicit(Tangent),
    /// Equilibrium by Newton's method at every step.
    Newton,
}

impl Scheme {
    /// A short label for tables and plots.
    pub fn label(self) -> &'static str {
        match self {
            Self::Explicit(Tangent::Secant) => "explicit, h = 0",
            Self::Explicit(Tangent::Consistent) => "explicit, h ≠ 0",
            Self::Newton => "Newton (equilibrium)",
        }
    }
}

/// Settings of a reference run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSettings {
    /// The scheme.
    pub scheme: Scheme,
    /// Largest damage increment a step may make before it is split (`∞`: never split, the
    /// seed's scheme).
    pub max_damage_increment: f64,
    /// Newton's relative residual tolerance.
    pub tolerance: f64,
    /// Newton iterations per step before giving up.
    pub max_iterations: usize,
}

impl RunSettings {
    /// The seed's scheme, no splitting.
    pub fn seed(scheme: Scheme) -> Self {
        Self {
            scheme,
            max_damage_increment: f64::INFINITY,
            tolerance: 1e-10,
            max_iterations: 60,
        }
    }
}

/// One step's result.
#[derive(Debug, Clone, PartialEq)]
pub struct StepResult {
    /// The load factor reached (sum of the schedule so far).
    pub load_factor: f64,
    /// Displacement (m, full length).
    pub u: Vec<f64>,
    /// `g` of the tearable points.
    pub g: Vec<f64>,
    /// Each cell's damage.
    pub cell_damage: Vec<f64>,
    /// Cells torn.
    pub torn_cells: usize,
    /// Largest point damage.
    pub max_damage: f64,
    /// Energy dissipated so far (J).
    pub dissipated: f64,
    /// Energy stored (J).
    pub stored: f64,
    /// Work of the applied forces and of the reactions at prescribed displacements so far (J).
    pub work: f64,
    /// Sub-steps the step took (1 unless it was split).
    pub substeps: u32,
    /// Newton iterations (0 for the explicit scheme).
    pub iterations: usize,
    /// Tearable points whose stiffness sits on the law's residual floor: fully damaged, they
    /// carry their share on `residual · C⁰` alone, at whatever strain that takes (an
    /// equilibrium the law itself would not have: [`carrying_limit`]).
    pub on_floor: usize,
}

/// What limits the load the damage laws of `model` can carry, in words for an error or a
/// warning: a Simó law with β = 0 saturates at `α√E` in uniaxial stress (no equilibrium above
/// it under a prescribed force, but for the residual floor); a softening law has none past its
/// peak `f_t` under a prescribed force (drive it by a displacement); β > 0 never saturates.
pub fn carrying_limit(model: &TearModel) -> String {
    use super::law::DamageLaw;
    let (mut saturating, mut softening) = (None::<f64>, false);
    for law in model.points.law.iter().flatten() {
        match *law {
            DamageLaw::Simo { alpha, beta: 0.0, .. } => saturating = Some(saturating.map_or(alpha, |a| a.min(alpha))),
            DamageLaw::Softening { .. } => softening = true,
            DamageLaw::Simo { .. } => {}
        }
    }
    let mut why = Vec::new();
    if let Some(alpha) = saturating {
        why.push(format!(
            "Simó's law with beta = 0 carries at most alpha·√E in uniaxial stress (alpha = {alpha} √Pa): a larger force has no equilibrium but on the residual stiffness floor"
        ));
    }
    if softening {
        why.push(
            "a softening law loaded past its peak stress f_t has no equilibrium under a prescribed force: drive the pull by a prescribed displacement (kind = \"displacement\") to follow it down"
                .to_string(),
        );
    }
    if why.is_empty() {
        "the load may exceed what the damaged tissue can carry".to_string()
    } else {
        format!("the load exceeds what the damaged tissue can carry: {}", why.join("; "))
    }
}

/// A whole run.
#[derive(Debug, Clone, PartialEq)]
pub struct TearRun {
    /// The scheme.
    pub scheme: Scheme,
    /// Step 0 (the start) then one entry per step of the schedule.
    pub steps: Vec<StepResult>,
    /// Wall time of the run (s).
    pub seconds: f64,
}

/// A reference run failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RunError {
    /// The factorization failed.
    #[error("step {step}: {source}")]
    Solve {
        /// The step.
        step: usize,
        /// Why.
        source: SolveError,
    },
    /// Newton's method did not converge.
    #[error("step {step}: no equilibrium found after {iterations} Newton iterations (relative residual {residual:.2e}); {why}")]
    NoEquilibrium {
        /// The step.
        step: usize,
        /// Iterations made.
        iterations: usize,
        /// The last relative residual.
        residual: f64,
        /// What in the model's damage laws limits the load it can carry ([`carrying_limit`]).
        why: String,
    },
    /// A step produced a non-finite displacement.
    #[error("step {step}: the displacement is not finite")]
    NotFinite {
        /// The step.
        step: usize,
    },
}

/// The running state of a reference run.
struct Runner<'a> {
    m: &'a TearModel,
    s: RunSettings,
    state: Vec<PointState>,
    u: Vec<f64>,
    phi: Vec<f64>,
    sigma0: Vec<Sym>,
    chol: Option<Cholesky>,
    factor: f64,
    dissipated: f64,
    work: f64,
    /// Applied force plus reactions on constrained dofs at the current state (full length).
    forces: Vec<f64>,
}

/// Runs the model's schedule with `settings`; `progress(step, of)` after each step.
pub fn run(model: &TearModel, settings: RunSettings, progress: impl FnMut(usize, usize)) -> Result<TearRun, RunError> {
    Runner::at_rest(model, settings, model.virgin()).run(progress)
}

/// Runs `model`'s schedule from the damage earlier grasps left: each of `before`, in order, a
/// model (another pull direction — [`TearModel::pull_load`] — or another grasp site's model on
/// the same mesh) run for the first `steps` steps of its schedule from the damage the one
/// before left, the tissue released after each (the secant model at rest under no load, no
/// displacement). `before = [(first, k)]` is a second grasp of tissue a first one damaged.
/// Step 0 of the run is the last released state; `progress(step, of)` after each step of
/// `model`'s schedule.
pub fn run_after(
    before: &[(&TearModel, usize)],
    model: &TearModel,
    settings: RunSettings,
    progress: impl FnMut(usize, usize),
) -> Result<TearRun, RunError> {
    let mut state = model.virgin();
    for &(first, steps) in before {
        let mut pre = Runner::at_rest(first, settings, state);
        for (k, &ds) in first.schedule.iter().take(steps).enumerate() {
            pre.step(k + 1, ds, 0)?;
        }
        state = pre.state;
    }
    Runner::at_rest(model, settings, state).run(progress)
}

impl<'a> Runner<'a> {
    /// A runner of `model` at rest (no load, no displacement) with the points' `state`.
    fn at_rest(model: &'a TearModel, settings: RunSettings, state: Vec<PointState>) -> Self {
        let n = model.points.len();
        Runner {
            m: model,
            s: settings,
            state,
            u: vec![0.0; 3 * model.mesh.n_nodes()],
            phi: vec![0.0; n],
            sigma0: vec![[0.0; 6]; n],
            chol: None,
            factor: 0.0,
            dissipated: 0.0,
            work: 0.0,
            forces: vec![0.0; 3 * model.mesh.n_nodes()],
        }
    }

    /// The model's schedule from here.
    fn run(mut self, mut progress: impl FnMut(usize, usize)) -> Result<TearRun, RunError> {
        let t0 = std::time::Instant::now();
        let schedule = &self.m.schedule;
        let mut steps = vec![self.result(1, 0)];
        for (k, &ds) in schedule.iter().enumerate() {
            let (substeps, iterations) = self.step(k + 1, ds, 0)?;
            steps.push(self.result(substeps, iterations));
            progress(k + 1, schedule.len());
        }
        Ok(TearRun {
            scheme: self.s.scheme,
            steps,
            seconds: t0.elapsed().as_secs_f64(),
        })
    }
}

impl Runner<'_> {
    fn result(&self, substeps: u32, iterations: usize) -> StepResult {
        let (cell_damage, torn_cells) = self.m.cell_damage(&self.state);
        StepResult {
            load_factor: self.factor,
            u: self.u.clone(),
            g: self.m.damage_field(&self.state),
            cell_damage,
            torn_cells,
            max_damage: self.state.iter().map(PointState::damage).fold(0.0, f64::max),
            dissipated: self.dissipated,
            stored: self.m.points.stored_energy(&self.m.mesh, &self.state, &self.u),
            work: self.work,
            substeps,
            iterations,
            on_floor: self
                .state
                .iter()
                .zip(&self.m.points.law)
                .filter(|(s, law)| law.as_ref().is_some_and(|l| s.g <= l.residual()))
                .count(),
        }
    }

    fn factor_solve(&mut self, step: usize, k: &crate::fem::assembly::SymmetricMatrix, rhs: &mut [f64]) -> Result<(), SolveError> {
        let _ = step;
        match &mut self.chol {
            Some(c) => c.refactor(k)?,
            None => self.chol = Some(Cholesky::factor(k)?),
        }
        self.chol.as_ref().expect("just factored").solve_in_place(rhs);
        Ok(())
    }

    /// One step of multiplier `ds`, split while it damages too fast. Returns the sub-steps
    /// and the Newton iterations made.
    fn step(&mut self, step: usize, ds: f64, depth: u32) -> Result<(u32, usize), RunError> {
        let saved = (self.state.clone(), self.u.clone(), self.dissipated, self.work, self.forces.clone());
        let (dmax, iterations, failed) = match self.s.scheme {
            Scheme::Explicit(t) => (self.explicit(step, ds, t)?, 0, false),
            Scheme::Newton => match self.newton(step, ds) {
                Ok((d, it)) => (d, it, false),
                Err(e @ RunError::NoEquilibrium { .. }) if depth >= MAX_SPLITS => return Err(e),
                Err(RunError::NoEquilibrium { .. }) => (f64::INFINITY, 0, true),
                Err(e) => return Err(e),
            },
        };
        if failed || (dmax > self.s.max_damage_increment && depth < MAX_SPLITS) {
            (self.state, self.u, self.dissipated, self.work, self.forces) = saved;
            let (a, ia) = self.step(step, 0.5 * ds, depth + 1)?;
            let (b, ib) = self.step(step, 0.5 * ds, depth + 1)?;
            return Ok((a + b, ia + ib));
        }
        self.factor += ds;
        Ok((1, iterations))
    }

    /// The applied forces at load factor `f` on free dofs and the reactions `f_int` on
    /// constrained ones, and the work increment of moving from the last state.
    fn account(&mut self, du: &[f64], new_factor: f64) {
        let m = self.m;
        let mut fint = vec![0.0; self.u.len()];
        m.points.internal_forces(&m.mesh, &self.state, &self.u, &mut fint);
        let mut forces = vec![0.0; self.u.len()];
        for d in 0..forces.len() {
            forces[d] = if m.dofs.is_constrained(d) {
                fint[d] + m.springs[d] * self.u[d]
            } else {
                new_factor * m.load[d]
            };
        }
        self.work += forces
            .iter()
            .zip(&self.forces)
            .zip(du)
            .map(|((a, b), d)| 0.5 * (a + b) * d)
            .sum::<f64>();
        self.forces = forces;
    }

    /// Alg. 4.1, lines 3–22, for one (sub)step. Returns the largest damage increment.
    fn explicit(&mut self, step: usize, ds: f64, tangent: Tangent) -> Result<f64, RunError> {
        let m = self.m;
        let nf = m.dofs.n_free();
        let mut rhs = vec![0.0; nf];
        m.dofs.restrict(&m.load.iter().map(|f| ds * f).collect::<Vec<_>>(), &mut rhs);
        let dub: Vec<f64> = m.prescribed.iter().map(|v| ds * v).collect();
        let sig = (tangent == Tangent::Consistent).then_some(&self.sigma0[..]);
        let k = m.stiffness(&self.state, sig, Some(&dub), &mut rhs);
        self.factor_solve(step, &k, &mut rhs)
            .map_err(|source| RunError::Solve { step, source })?;
        let mut du = vec![0.0; self.u.len()];
        m.dofs.expand(&rhs, &dub, &mut du);
        if du.iter().any(|v| !v.is_finite()) {
            return Err(RunError::NotFinite { step });
        }
        for (u, d) in self.u.iter_mut().zip(&du) {
            *u += d;
        }
        m.strains(&self.u, &mut self.phi, &mut self.sigma0);
        let (diss, dmax) = m.update_damage(&mut self.state, &self.phi);
        self.dissipated += diss;
        self.account(&du, self.factor + ds);
        Ok(dmax)
    }

    /// Equilibrium at load factor `factor + ds` by Newton's method. Returns the largest damage
    /// increment and the iterations.
    fn newton(&mut self, step: usize, ds: f64) -> Result<(f64, usize), RunError> {
        let m = self.m;
        let nf = m.dofs.n_free();
        let target = self.factor + ds;
        let start = self.state.clone();
        let u0 = self.u.clone();
        // predictor: the prescribed displacements moved, free dofs kept
        for d in 0..self.u.len() {
            if m.dofs.is_constrained(d) {
                self.u[d] += ds * m.prescribed[d];
            }
        }
        let fext: Vec<f64> = m.load.iter().map(|f| target * f).collect();
        let fscale = {
            let mut f = vec![0.0; nf];
            m.dofs.restrict(&fext, &mut f);
            f.iter().map(|v| v * v).sum::<f64>().sqrt()
        };
        let mut fint = vec![0.0; self.u.len()];
        let mut trial = start.clone();
        let mut last = f64::INFINITY;
        let mut best = (f64::INFINITY, 0);
        let mut scale = fscale;
        for it in 1..=self.s.max_iterations {
            // trial state from the converged one
            m.strains(&self.u, &mut self.phi, &mut self.sigma0);
            trial.copy_from_slice(&start);
            for &p in &m.points.tearable {
                let law = m.points.law[p].as_ref().expect("tearable");
                trial[p].update(law, self.phi[p]);
            }
            m.points.internal_forces(&m.mesh, &trial, &self.u, &mut fint);
            let mut res = vec![0.0; nf];
            for d in 0..self.u.len() {
                if let Some(e) = m.dofs.eq(d) {
                    res[e] = fext[d] - fint[d] - m.springs[d] * self.u[d];
                }
            }
            let norm = res.iter().map(|v| v * v).sum::<f64>().sqrt();
            if it == 1 {
                // the reactions of the prescribed motion set the scale when there is no force
                let react: f64 = (0..self.u.len())
                    .filter(|&d| m.dofs.is_constrained(d))
                    .map(|d| fint[d] * fint[d])
                    .sum::<f64>()
                    .sqrt();
                scale = fscale.max(react).max(norm).max(f64::MIN_POSITIVE);
            }
            last = norm / scale;
            if last < best.0 {
                best = (last, it);
            } else if it - best.1 >= STALL {
                break;
            }
            if last <= self.s.tolerance {
                let (diss, dmax) = {
                    let mut st = start.clone();
                    let r = m.update_damage(&mut st, &self.phi);
                    self.state = st;
                    r
                };
                self.dissipated += diss;
                let du: Vec<f64> = self.u.iter().zip(&u0).map(|(a, b)| a - b).collect();
                self.account(&du, target);
                return Ok((dmax, it - 1));
            }
            let k = m.stiffness(&trial, Some(&self.sigma0), None, &mut vec![0.0; nf]);
            let mut du = res.clone();
            if self.factor_solve(step, &k, &mut du).is_err() {
                // past a peak the tangent is not positive definite: the secant still converges
                let k = m.stiffness(&trial, None, None, &mut vec![0.0; nf]);
                du.copy_from_slice(&res);
                self.factor_solve(step, &k, &mut du)
                    .map_err(|source| RunError::Solve { step, source })?;
            }
            for d in 0..self.u.len() {
                if let Some(e) = m.dofs.eq(d) {
                    self.u[d] += du[e];
                }
            }
            if self.u.iter().any(|v| !v.is_finite()) {
                break;
            }
        }
        self.u = u0;
        Err(RunError::NoEquilibrium {
            step,
            iterations: self.s.max_iterations,
            residual: last,
            why: carrying_limit(m),
        })
    }
}

/// The L2 error of `u` against `reference`, absolute and relative: `‖u − u_ref‖₂` and
/// `‖u − u_ref‖₂ / ‖u_ref‖₂` (the seed's Figs. 4.6 and 4.10).
pub fn l2_error(u: &[f64], reference: &[f64]) -> (f64, f64) {
    let e = u.iter().zip(reference).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
    let n = reference.iter().map(|b| b * b).sum::<f64>().sqrt();
    (e, if n > 0.0 { e / n } else { e })
}
