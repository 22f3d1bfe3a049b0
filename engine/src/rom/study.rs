//! Accuracy of ANM-POD against the full model on one scene (seed 001 §6): full Newton–Raphson
//! load steps → POD of their states → the reduced St Venant–Kirchhoff model → one asymptotic
//! series from the unloaded state per order (the seed's use: tangent at the origin for the
//! whole curve), the continuation at the highest order, and the exact reduced equilibrium; each
//! compared with Newton under the load, load step by load step.

use std::time::Instant;

use super::anm::{self, AnmError, Series};
use super::pod::{Pod, PodCriterion, PodError};
use super::svk::{ReduceError, ReducedSvk};
use crate::fem::hyperelastic::{LawMap, Volumetric};
use crate::fem::linear_static::StaticProblem;
use crate::fem::nonlinear_static::{self, NewtonParams, NonlinearError};
use crate::mesh::Mesh;

/// Settings of the study.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyParams {
    /// Newton load steps (each converged state is a snapshot and a comparison point).
    pub load_steps: usize,
    /// How many POD modes.
    pub pod: PodCriterion,
    /// Orders of the one-series curves.
    pub orders: Vec<usize>,
    /// Order and `δ` of the continuation.
    pub continuation: anm::AnmParams,
    /// Points per one-series curve.
    pub curve_points: usize,
    /// The scene's loads are multiplied by this at `λ = 1` (seed 001 runs the liver "until
    /// lack of convergence of the Newton–Raphson algorithm").
    pub load_multiplier: f64,
}

impl Default for StudyParams {
    /// 12 load steps, 9 modes at most (seed 001's liver), orders 1–6, continuation at order 6.
    fn default() -> Self {
        Self {
            load_steps: 12,
            pod: PodCriterion {
                energy: 1.0 - 1e-12,
                max_modes: 9,
            },
            orders: (1..=6).collect(),
            continuation: anm::AnmParams::default(),
            curve_points: 120,
            load_multiplier: 1.0,
        }
    }
}

/// Why the study stopped.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// The problem cannot be reduced this way.
    #[error("{0}")]
    Unsupported(String),
    /// The full model failed.
    #[error("full Newton-Raphson: {0}")]
    Newton(#[from] NonlinearError),
    /// POD failed.
    #[error("POD: {0}")]
    Pod(#[from] PodError),
    /// The reduced model could not be built.
    #[error("reduced model: {0}")]
    Reduce(#[from] ReduceError),
    /// The expansion failed.
    #[error("ANM: {0}")]
    Anm(#[from] AnmError),
}

/// One load step of the comparison; displacements under the load, along it (m).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LoadPoint {
    /// Load factor.
    pub lambda: f64,
    /// Full Newton–Raphson.
    pub newton: f64,
    /// Exact equilibrium of the reduced model (the POD error alone).
    pub reduced: Option<f64>,
    /// The continuation.
    pub continuation: Option<f64>,
    /// One series from the origin, per order of [`StudyParams::orders`] (`None`: the series'
    /// load never reaches `λ`).
    pub series: Vec<Option<f64>>,
}

/// What the study found.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Study {
    /// Nodes carrying the load (where the displacement is read).
    pub probe_nodes: Vec<usize>,
    /// Unit direction of the total load.
    pub direction: [f64; 3],
    /// Magnitude of the total load at `λ = 1` (N).
    pub force: f64,
    /// POD modes kept.
    pub modes: usize,
    /// Energy they capture.
    pub captured: f64,
    /// Singular values of the snapshots.
    pub singular_values: Vec<f64>,
    /// Orders of the series columns.
    pub orders: Vec<usize>,
    /// The comparison, step by step.
    pub points: Vec<LoadPoint>,
    /// Each one-series curve as `(displacement, λ)` samples up to where it leaves the plot.
    pub curves: Vec<Vec<(f64, f64)>>,
    /// The continuation's steps and their radii.
    pub continuation_radii: Vec<f64>,
    /// Why full Newton stopped before the full load, when it did (the comparison then ends
    /// at its last converged step, as seed 001 §6.2 does).
    pub newton_stopped: Option<String>,
    /// Seconds: Newton, POD, tensors, one series of the highest order.
    pub seconds: StudySeconds,
}

/// Where the offline time went.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct StudySeconds {
    /// Full Newton–Raphson (all load steps).
    pub newton: f64,
    /// SVD of the snapshots.
    pub pod: f64,
    /// Reduced tensors.
    pub tensors: f64,
}

/// The reduced model of a scene's load case, ready for online evaluation.
#[derive(Debug, Clone)]
pub struct ReducedCase {
    /// The basis.
    pub pod: Pod,
    /// The reduced model.
    pub model: ReducedSvk,
    /// Reduced load `Aᵀf`.
    pub load: Vec<f64>,
    /// `Aᵀ` rows of the probe: `d = probe·ζ` is the displacement under the load.
    pub probe: Vec<f64>,
}

impl Study {
    /// The largest displacement under the load up to which the one series of `order` stays
    /// within `tol` (relative) of Newton at every load step, and the error beyond it.
    pub fn reach(&self, order: usize, tol: f64) -> f64 {
        let Some(k) = self.orders.iter().position(|&o| o == order) else {
            return 0.0;
        };
        let mut reach = 0.0;
        for p in &self.points {
            match p.series[k] {
                Some(d) if (d - p.newton).abs() <= tol * p.newton.abs() => reach = p.newton.abs(),
                _ => break,
            }
        }
        reach
    }
}

fn probe_of(problem: &StaticProblem) -> Result<(Vec<usize>, [f64; 3], f64), StudyError> {
    let n = problem.forces.len() / 3;
    let nodes: Vec<usize> = (0..n).filter(|&i| (0..3).any(|k| problem.forces[3 * i + k] != 0.0)).collect();
    let mut total = [0.0; 3];
    for &i in &nodes {
        for k in 0..3 {
            total[k] += problem.forces[3 * i + k];
        }
    }
    let force = total.iter().map(|x| x * x).sum::<f64>().sqrt();
    if nodes.is_empty() || force.is_nan() || force <= 0.0 {
        return Err(StudyError::Unsupported("the load case has no force: nothing to follow".into()));
    }
    if problem.constrained.iter().zip(&problem.prescribed).any(|(&c, &v)| c && v != 0.0) {
        return Err(StudyError::Unsupported(
            "the reduced model follows force loads with fixed supports; this load case prescribes nonzero displacements".into(),
        ));
    }
    Ok((nodes, total.map(|t| t / force), force))
}

/// Runs the study on a St Venant–Kirchhoff `mesh` (see the [module docs](self)); `progress`
/// gets a stage label.
pub fn anm_pod(
    mesh: &Mesh,
    laws: &LawMap,
    problem: &StaticProblem,
    params: &StudyParams,
    mut progress: impl FnMut(&str),
) -> Result<(Study, ReducedCase), StudyError> {
    if !(params.load_multiplier.is_finite() && params.load_multiplier > 0.0) {
        return Err(StudyError::Unsupported("the load multiplier must be positive".into()));
    }
    let mut problem = problem.clone();
    for f in &mut problem.forces {
        *f *= params.load_multiplier;
    }
    let problem = &problem;
    let (probe_nodes, direction, force) = probe_of(problem)?;
    let under = |u: &[f64]| super::mean_along(u, &probe_nodes, direction);
    let mut seconds = StudySeconds::default();
    let t = Instant::now();
    let mut snapshots: Vec<(f64, Vec<f64>)> = Vec::new();
    let newton = NewtonParams {
        steps: params.load_steps.max(1),
        ..NewtonParams::default()
    };
    let full = nonlinear_static::solve(mesh, laws, Volumetric::PointWise, problem, &newton, |l, u| {
        progress(&format!("full Newton-Raphson, load factor {l:.3}"));
        snapshots.push((l, u.to_vec()));
    });
    let newton_stopped = match full {
        Ok(_) => None,
        Err(e @ NonlinearError::NoConvergence { .. }) if snapshots.len() >= 2 => Some(e.to_string()),
        Err(e) => return Err(e.into()),
    };
    seconds.newton = t.elapsed().as_secs_f64();

    progress("POD of the load steps");
    let t = Instant::now();
    let states: Vec<Vec<f64>> = snapshots.iter().map(|(_, u)| u.clone()).collect();
    let pod = Pod::from_snapshots(&states, params.pod)?;
    seconds.pod = t.elapsed().as_secs_f64();

    progress("reduced St Venant-Kirchhoff tensors");
    let t = Instant::now();
    let model = ReducedSvk::build(mesh, laws, &pod)?;
    seconds.tensors = t.elapsed().as_secs_f64();
    let load = pod.project(&problem.forces);
    let probe: Vec<f64> = (0..pod.modes).map(|k| under(pod.mode(k))).collect();
    let at = |zeta: &[f64]| -> f64 { probe.iter().zip(zeta).map(|(p, z)| p * z).sum() };

    progress("asymptotic expansions");
    let r = pod.modes;
    let scale = anm::displacement_scale(&model, &load)?;
    let origin = vec![0.0; r];
    let series: Vec<Series> = params
        .orders
        .iter()
        .map(|&o| Series::expand(&model, &load, &origin, 0.0, o, scale, params.continuation.tolerance))
        .collect::<Result<_, _>>()?;
    let path = anm::continuation(&model, &load, 1.0, &params.continuation).ok();
    let d_max = snapshots.last().map_or(0.0, |(_, u)| under(u).abs());
    // generous bounds in the path parameter: a ≈ λ for soft loading, more when stiffening
    let a_hi = 8.0;
    let mut zeta = vec![0.0; r];
    let mut points = Vec::new();
    for (lambda, u) in &snapshots {
        let mut col = Vec::new();
        for s in &series {
            col.push(s.solve_load(*lambda, a_hi).map(|a| {
                s.eval(a, &mut zeta);
                at(&zeta)
            }));
        }
        let reduced = anm::newton(&model, &load, *lambda, 4, 1e-10).ok().map(|z| at(&z));
        let continuation = path.as_ref().and_then(|p| p.at_load(*lambda, &mut zeta).then(|| at(&zeta)));
        points.push(LoadPoint {
            lambda: *lambda,
            newton: under(u),
            reduced,
            continuation,
            series: col,
        });
    }
    let curves = series
        .iter()
        .map(|s| {
            let mut c = Vec::new();
            for k in 0..=params.curve_points {
                let a = a_hi * k as f64 / params.curve_points as f64;
                let l = s.eval(a, &mut zeta);
                let d = at(&zeta);
                c.push((d, l));
                if !(l.is_finite() && d.is_finite()) || l.abs() > 1.5 || d.abs() > 2.0 * d_max {
                    break;
                }
            }
            c
        })
        .collect();
    let study = Study {
        probe_nodes,
        direction,
        force,
        modes: pod.modes,
        captured: pod.captured,
        singular_values: pod.singular_values.clone(),
        orders: params.orders.clone(),
        points,
        curves,
        continuation_radii: path.map(|p| p.steps.iter().map(|s| s.radius).collect()).unwrap_or_default(),
        newton_stopped,
        seconds,
    };
    Ok((study, ReducedCase { pod, model, load, probe }))
}
