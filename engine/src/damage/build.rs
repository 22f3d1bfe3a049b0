//! The offline stage of the POD–PGD integrator: full-order runs for the damage snapshots, their
//! POD basis, the vademecum over its coefficients, the Ritz form, and the vademecum's error
//! against exact solves at the snapshots' coefficients (what every reduced model reports).

use std::time::Instant;

use super::model::TearModel;
use std::sync::Arc;

use super::online::{RitzOperator, TearFallback, TearOffline};
use super::pod::DamageBasis;
use super::reference::{self, RunError, RunSettings, Scheme, Tangent, TearRun};
use super::vademecum::{self, AffineSystem, DamageVademecum, VademecumError, VademecumSettings};
use crate::rom::pod::{PodCriterion, PodError};

/// Settings of the offline stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TearSettings {
    /// How many POD vectors (energy fraction and cap).
    pub pod: PodCriterion,
    /// Margin around the snapshots' coefficient box (fraction of each range).
    pub margin: f64,
    /// The vademecum builder.
    pub vademecum: VademecumSettings,
    /// Also build the vademecums of the two pulls across the scene's load (the grasper then
    /// follows the device in every direction; [`TearModel::pull_load`]).
    pub cross_pulls: bool,
    /// Keep, of the modes the build made, the fewest per pull pattern whose calibrated force
    /// error ([`force_error_table`], at the last load level) is at most this (relative);
    /// `None`: keep them all. `vademecum build --target-error`.
    pub target_force_error: Option<f64>,
}

impl Default for TearSettings {
    /// POD to `1 − 10⁻⁸` of the snapshots' energy with at most 10 vectors (the seed: "not
    /// higher than ten"), a 10 % margin, the default vademecum settings.
    fn default() -> Self {
        Self {
            pod: PodCriterion {
                energy: 1.0 - 1e-8,
                max_modes: 10,
            },
            margin: 0.1,
            vademecum: VademecumSettings::default(),
            cross_pulls: true,
            target_force_error: None,
        }
    }
}

/// What the offline stage did and how accurate its vademecum is.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TearBuildReport {
    /// Snapshots taken.
    pub snapshots: usize,
    /// POD vectors kept.
    pub pod_vectors: usize,
    /// Energy fraction they capture.
    pub captured: f64,
    /// The coefficient box.
    pub lo: Vec<f64>,
    /// The coefficient box.
    pub hi: Vec<f64>,
    /// The smallest `g` the POD reconstruction takes over the box.
    pub min_g_over_box: f64,
    /// PGD modes (all pull patterns).
    pub pgd_modes: usize,
    /// PGD modes of each pull pattern: along the scene's load, then across it.
    pub pattern_modes: Vec<usize>,
    /// Size of the Ritz basis.
    pub ritz_size: usize,
    /// Largest relative error of the vademecum's increment against the exact `K(ξ)⁻¹b(ξ)`
    /// at the snapshots' coefficients (the scene's load).
    pub vademecum_error: f64,
    /// The same for the pulls across the load (0 without them).
    pub cross_vademecum_error: f64,
    /// Time of the full-order runs (s).
    pub reference_seconds: f64,
    /// Time of POD + vademecum + Ritz (s).
    pub build_seconds: f64,
    /// The vademecum builder's own report.
    pub vademecum: vademecum::VademecumReport,
    /// The calibrated relative error of the grasper's force at the schedule's last load
    /// level, over the pulls along and across the load ([`force_error_table`]; NaN when the
    /// calibration failed, and the bundle then carries no estimate).
    pub force_error: f64,
    /// Time of the calibration's full-order runs across the load and online pulls (s).
    pub calibration_seconds: f64,
    /// What [`TearSettings::target_force_error`] asked and what the build kept (`None`
    /// without a target).
    pub target: Option<TearTarget>,
    /// The cheaper setting a session falls back to under load ([`fallback_for`]): the modes
    /// per pull pattern and their calibrated force error at the last load level; `None`
    /// when no prefix qualifies.
    pub fallback: Option<(Vec<usize>, f64)>,
    /// Tearable points the reference run ends with on the law's residual stiffness floor
    /// (`StepResult::on_floor`), and why the law cannot carry the load there: a schedule that
    /// pulls harder than the tissue can hold (0 and empty otherwise).
    pub on_floor: usize,
    /// What limits the load ([`super::reference::carrying_limit`]) when `on_floor > 0`.
    pub on_floor_why: String,
}

/// The modes a build kept for a target force error ([`TearSettings::target_force_error`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TearTarget {
    /// The target (relative error of the grasper's force at the last load level).
    pub error: f64,
    /// Whether the kept modes meet it (when none do, all the modes are kept: the closest).
    pub met: bool,
    /// The modes the build made, per pull pattern.
    pub built_modes: Vec<usize>,
    /// Each prefix tried, fewest modes first: the modes per pattern and its calibrated force
    /// error (NaN when the calibration ended before the last load level).
    pub tried: Vec<(Vec<usize>, f64)>,
}

/// The offline stage failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TearBuildError {
    /// A full-order run failed.
    #[error("full-order reference: {0}")]
    Reference(#[from] RunError),
    /// No POD basis.
    #[error("POD of the damage snapshots: {0}")]
    Pod(#[from] PodError),
    /// No vademecum.
    #[error("vademecum: {0}")]
    Vademecum(#[from] VademecumError),
    /// The problem damages nothing.
    #[error("the model has no tearable material: mark a material with damage = {{ … }}")]
    NothingTearable,
}

/// Runs the offline stage; `progress(stage, fraction)` as it goes. Returns the offline data,
/// the report, and the two explicit reference runs (h = 0, then h ≠ 0) it took snapshots from.
pub fn build(
    model: TearModel,
    settings: &TearSettings,
    mut progress: impl FnMut(&'static str, f64),
) -> Result<(TearOffline, TearBuildReport, [TearRun; 2]), TearBuildError> {
    if model.points.tearable.is_empty() {
        return Err(TearBuildError::NothingTearable);
    }
    let t0 = Instant::now();
    let runs = references(&model, &mut progress)?;
    let cross_pulls = settings.cross_pulls && model.pull_frame().is_some();
    let reference_seconds = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let snapshots = snapshots(&runs);
    let basis = DamageBasis::from_snapshots(&snapshots, settings.pod, settings.margin)?;
    let sys = AffineSystem::of(&model, &basis);
    let settle = |label: &'static str, progress: &mut dyn FnMut(&'static str, f64), m: usize, ratio: f64| {
        progress(
            label,
            (m as f64 / settings.vademecum.max_modes as f64)
                .max(1.0 - ratio.max(1e-12).log10().abs() / 12.0)
                .min(1.0),
        )
    };
    let mut parts = vec![vademecum::build(&sys, &basis.lo, &basis.hi, &settings.vademecum, |m, ratio| {
        settle("vademecum", &mut progress, m, ratio)
    })?];
    // the pulls across the load: the same operators, a force-only right-hand side
    let cross: Vec<AffineSystem> = if cross_pulls {
        (1..=2)
            .map(|p| {
                let mut b = vec![0.0; model.dofs.n_free()];
                model.dofs.restrict(&model.pull_load(p), &mut b);
                let mut rhs = vec![vec![0.0; b.len()]; sys.rhs.len()];
                rhs[0] = b;
                AffineSystem { ops: sys.ops.clone(), rhs }
            })
            .collect()
    } else {
        Vec::new()
    };
    for c in &cross {
        parts.push(vademecum::build(c, &basis.lo, &basis.hi, &settings.vademecum, |m, ratio| {
            settle("vademecum across the pull", &mut progress, m, ratio)
        })?);
    }
    let vad = DamageVademecum::merge(parts);
    let ritz = RitzOperator::new(&vad, &sys);
    let build_seconds = t1.elapsed().as_secs_f64();
    progress("force error calibration", 0.0);
    let t2 = Instant::now();
    let full = std::sync::Arc::new(TearOffline::new(model, basis, vad, ritz));
    // a failed calibration leaves the bundle without an estimate (and meets no target)
    let calibration = Calibration::run(&full, &runs[0]).ok();
    let table = |off: &std::sync::Arc<TearOffline>| calibration.as_ref().and_then(|c| c.table(off).ok()).unwrap_or_default();
    let full_table = table(&full);
    let (mut off, target) = match settings.target_force_error {
        None => {
            let mut off = unshare(full);
            off.force_error = full_table;
            (off, None)
        }
        Some(e) => {
            let (off, t) = keep_for_target(full, full_table, e, &sys, &table);
            (off, Some(t))
        }
    };
    off.fallback = fallback_for(&off, &sys, &table);
    let calibration_seconds = t2.elapsed().as_secs_f64();
    // each pattern's vademecum against exact solves at the snapshots' coefficients
    let vad = &off.vademecum;
    let (mut xi, mut a) = (vec![0.0; off.basis.len()], vec![0.0; vad.n_modes]);
    let mut du = vec![0.0; vad.n_free];
    let mut worst = [0.0f64; 2];
    let patterns = vad.mode_patterns();
    for (k, s) in snapshots.iter().enumerate() {
        progress("validation", k as f64 / snapshots.len() as f64);
        off.basis.project(s, &mut xi);
        vad.coefficients(&xi, &mut a);
        for (p, system) in std::iter::once(&sys).chain(&cross).enumerate() {
            let only: Vec<f64> = a.iter().zip(&patterns).map(|(x, &q)| if q == p { *x } else { 0.0 }).collect();
            vad.combine(&only, &mut du);
            if let Ok(exact) = system.solve(&xi) {
                let (e, _) = reference::l2_error(&du, &exact);
                let n = exact.iter().map(|v| v * v).sum::<f64>().sqrt();
                let w = &mut worst[p.min(1)];
                *w = w.max(if n > 0.0 { e / n } else { e });
            }
        }
    }
    let report = TearBuildReport {
        snapshots: snapshots.len(),
        pod_vectors: off.basis.len(),
        captured: off.basis.pod.captured,
        lo: off.basis.lo.clone(),
        hi: off.basis.hi.clone(),
        min_g_over_box: off.basis.min_over_box(),
        pgd_modes: off.vademecum.n_modes,
        pattern_modes: off.vademecum.patterns.clone(),
        ritz_size: off.ritz.m,
        vademecum_error: worst[0],
        cross_vademecum_error: worst[1],
        reference_seconds,
        build_seconds,
        vademecum: off.vademecum.report.clone(),
        force_error: off.force_error.last().map_or(f64::NAN, |r| r[1]),
        calibration_seconds,
        target,
        fallback: off
            .fallback
            .as_ref()
            .map(|f| (f.modes.clone(), f.force_error.last().map_or(f64::NAN, |r| r[1]))),
        on_floor: runs[0].steps.last().map_or(0, |s| s.on_floor),
        on_floor_why: String::new(),
    };
    let mut report = report;
    if report.on_floor > 0 {
        report.on_floor_why = super::reference::carrying_limit(&off.model);
    }
    Ok((off, report, runs))
}

/// The modes per pull pattern of the first prefix [`TearSettings::target_force_error`] tries
/// (then twice as many, …).
pub const FEWEST_TARGET_MODES: usize = 5;

/// How much larger than the kept modes' calibrated force error (at the last load level) the
/// fallback's may be ([`fallback_for`]).
pub const FALLBACK_ERROR_GROWTH: f64 = 1.25;

/// The prefixes a build tries, fewest modes first: [`FEWEST_TARGET_MODES`] modes of every
/// pull pattern (all of a pattern's when it has fewer), then twice as many, …, while some
/// pattern has more than that (`built`: the modes of each pattern).
fn prefixes(built: &[usize]) -> impl Iterator<Item = Vec<usize>> + '_ {
    let most = built.iter().copied().max().unwrap_or(0);
    std::iter::successors(Some(FEWEST_TARGET_MODES), |k| Some(2 * k))
        .take_while(move |&k| k < most)
        .map(move |k| built.iter().map(|&n| n.min(k)).collect())
}

/// The last calibrated error of `t` when it reaches as many load levels as `reference`, NaN
/// otherwise (a calibration that ended early meets no target).
fn last_error(t: &[[f64; 2]], reference: &[[f64; 2]]) -> f64 {
    match t.last() {
        Some(r) if t.len() == reference.len() => r[1],
        _ => f64::NAN,
    }
}

/// The cheaper setting a session of `off` falls back to under load
/// ([`TearOffline::fallback`]): the fewest modes per pull pattern (5, 10, 20, … as
/// `--target-error` tries them, fewer than `off` holds) whose calibrated force error (`table`) at the last load level is at most
/// [`FALLBACK_ERROR_GROWTH`] times `off`'s own — a cheaper step whose answers stay about as
/// accurate, and say their own estimate. `None` without a calibration of `off`, or when no
/// prefix qualifies (`off` is already that small: `build --target-error` kept few modes).
pub fn fallback_for(off: &TearOffline, sys: &AffineSystem, table: &dyn Fn(&Arc<TearOffline>) -> Vec<[f64; 2]>) -> Option<TearFallback> {
    let own = last_error(&off.force_error, &off.force_error);
    if !own.is_finite() {
        return None;
    }
    prefixes(&off.vademecum.patterns).find_map(|keep| {
        let t = table(&Arc::new(off.pattern_prefix(&keep, sys)));
        (last_error(&t, &off.force_error) <= FALLBACK_ERROR_GROWTH * own).then_some(TearFallback {
            modes: keep,
            force_error: t,
        })
    })
}

/// The offline data out of its `Arc` (a copy only while something else still holds it).
fn unshare(off: std::sync::Arc<TearOffline>) -> TearOffline {
    std::sync::Arc::try_unwrap(off).unwrap_or_else(|a| (*a).clone())
}

/// The fewest modes per pull pattern of `full` whose calibrated force error (`table`, at the
/// last load level; a calibration short of `full_table`'s levels does not meet it) is at
/// most `target`: prefixes of 5, 10, 20, … modes of every pattern, then all of them — the
/// closest when no prefix meets it. `sys` is the model's affine system (each prefix's Ritz
/// basis). The offline data kept carries its own calibration.
fn keep_for_target(
    full: std::sync::Arc<TearOffline>,
    full_table: Vec<[f64; 2]>,
    target: f64,
    sys: &AffineSystem,
    table: &dyn Fn(&std::sync::Arc<TearOffline>) -> Vec<[f64; 2]>,
) -> (TearOffline, TearTarget) {
    let built = full.vademecum.patterns.clone();
    let last = |t: &[[f64; 2]]| last_error(t, &full_table);
    let mut tried = Vec::new();
    let tries: Vec<Vec<usize>> = prefixes(&built).collect();
    for keep in tries {
        let off = std::sync::Arc::new(full.pattern_prefix(&keep, sys));
        let t = table(&off);
        let e = last(&t);
        tried.push((keep, e));
        if e <= target {
            let mut off = unshare(off);
            off.force_error = t;
            let t = TearTarget {
                error: target,
                met: true,
                built_modes: built,
                tried,
            };
            return (off, t);
        }
    }
    let e = last(&full_table);
    tried.push((built.clone(), e));
    let t = TearTarget {
        error: target,
        met: e <= target,
        built_modes: built,
        tried,
    };
    let mut off = unshare(full);
    off.force_error = full_table;
    (off, t)
}

/// The two explicit full-order runs the offline stage takes its snapshots from (h = 0, then
/// h ≠ 0: the references of the simplified and the full integrator); `progress(stage,
/// fraction)` as they go.
pub fn references(model: &TearModel, mut progress: impl FnMut(&'static str, f64)) -> Result<[TearRun; 2], RunError> {
    let mut run = |tangent: Tangent, label: &'static str| {
        reference::run(model, RunSettings::seed(Scheme::Explicit(tangent)), |k, n| {
            progress(label, k as f64 / n as f64)
        })
    };
    Ok([
        run(Tangent::Secant, "reference h = 0")?,
        run(Tangent::Consistent, "reference h ≠ 0")?,
    ])
}

/// The damage snapshots of `runs`: the virgin state once (every online run starts there),
/// then every step of both runs.
pub fn snapshots(runs: &[TearRun; 2]) -> Vec<Vec<f64>> {
    std::iter::once(runs[0].steps[0].g.clone())
        .chain(runs.iter().flat_map(|r| r.steps.iter().skip(1).map(|s| s.g.clone())))
        .collect()
}

/// The relative L2 error, at each step of the model's schedule, of the online integrator on
/// `off` stepping the pull mix `mix` (multipliers of the patterns along the load and across
/// it, [`TearModel::pull_load`]) against the full-order explicit reference (h = 0, the
/// scheme the simplified integrator reduces) under the load `Σ_p mix_p L_p`. Neither splits
/// its steps, so the comparison is of the method alone. What a pull in any direction costs
/// in accuracy.
pub fn pull_errors(off: &std::sync::Arc<TearOffline>, mix: [f64; 3]) -> Result<Vec<f64>, RunError> {
    use super::online::{OnlineTear, StepLimits, Variant};
    let model = &off.model;
    let exact = reference::run(&pulled(model, mix), RunSettings::seed(Scheme::Explicit(Tangent::Secant)), |_, _| {})?;
    let whole = StepLimits {
        max_damage_increment: f64::INFINITY,
        max_substeps: 1,
    };
    let mut online = OnlineTear::new(off.clone(), Variant::Simplified, whole);
    Ok(model
        .schedule
        .iter()
        .enumerate()
        .map(|(k, &ds)| {
            online.step_pull(mix.map(|m| m * ds));
            reference::l2_error(&online.displacement_vec(), &exact.steps[k + 1].u).1
        })
        .collect())
}

/// `model` under the pull mix `mix`: the load `Σ_p mix_p L_p` ([`TearModel::pull_load`]),
/// the prescribed displacements (which go with the pull along the load) times `mix_0`.
fn pulled(model: &TearModel, mix: [f64; 3]) -> TearModel {
    let mut loaded = model.clone();
    let loads: Vec<Vec<f64>> = (0..3).map(|p| model.pull_load(p)).collect();
    loaded.load = (0..loaded.load.len()).map(|d| (0..3).map(|p| mix[p] * loads[p][d]).sum()).collect();
    loaded.prescribed.iter_mut().for_each(|x| *x *= mix[0]);
    loaded
}

/// The error of the force the grasper renders under a pull `mix` (multipliers of the patterns
/// along the load and across it, as [`pull_errors`]), at each step of the model's schedule:
/// rows `[t_k, t′_k, e_k]` with `t_k = |mix| Σ_{j≤k} Δs_j` the load level (unit steps).
///
/// The session holds the grasp by displacement control: it renders `|R| s` for the load `s`
/// at which its reduced model reaches the device's displacement. At step `k` the online
/// integrator (whole steps, as [`pull_errors`]) has the grasp at `w_r = (L_p·u)/|R|` under
/// `t_k·mix`; the full-order model (explicit, h = 0; `exact` if already run, else run here)
/// reaches the same displacement — measured along `w_r` — at the load level `t′`, linear
/// between its steps. The forces for the same displacement differ by `|R| |t_k − t′| |mix|`:
/// `e_k = |t_k − t′| / t_k`. Ends at the first step where the full-order run does not reach
/// `w_r` (its last segment does not rise), or where the reduced grasp does not move.
pub fn force_errors(off: &std::sync::Arc<TearOffline>, mix: [f64; 3], exact: Option<&TearRun>) -> Result<Vec<[f64; 3]>, RunError> {
    force_errors_after(off, &[], mix, exact)
}

/// A pull that came before a grasp ([`force_errors_after`]): the grasp site `site` (the
/// site's own vademecum, or another site's on the same tissue) pulled by `mix` (multipliers of
/// its patterns) for the first `steps` steps of its schedule, then released.
#[derive(Debug, Clone)]
pub struct Prior {
    /// The site pulled.
    pub site: std::sync::Arc<TearOffline>,
    /// The pull's multipliers of the site's patterns (along its load, across it).
    pub mix: [f64; 3],
    /// The steps of the site's schedule pulled.
    pub steps: usize,
}

impl Prior {
    /// `site` pulled along its load for `steps` steps.
    pub fn along(site: &std::sync::Arc<TearOffline>, steps: usize) -> Self {
        Self {
            site: site.clone(),
            mix: [1.0, 0.0, 0.0],
            steps,
        }
    }
}

/// The reduced integrator of site `off` (the simplified one, whole steps) holding the tissue
/// after the pulls `before` (each on its site's vademecum, released, taken over at rest as a
/// session does), [`super::online::OnlineTear::hold`] done: what a session's grasp starts from, and
/// [`super::online::OnlineTear::force_error_for`] the estimate it attaches.
pub fn later_grasp(off: &std::sync::Arc<TearOffline>, before: &[Prior]) -> super::online::OnlineTear {
    use super::online::{OnlineTear, StepLimits, Variant};
    let whole = StepLimits {
        max_damage_increment: f64::INFINITY,
        max_substeps: 1,
    };
    let mut online = OnlineTear::new(off.clone(), Variant::Simplified, whole);
    for p in before {
        let mut first = OnlineTear::new(p.site.clone(), Variant::Simplified, whole);
        first.take_over(&online);
        for &ds in p.site.model.schedule.iter().take(p.steps) {
            first.step_pull(p.mix.map(|m| m * ds));
        }
        online.take_over(&first);
    }
    online.hold();
    online
}

/// [`force_errors`] of a later grasp: the tissue first pulled by each of `before` in turn and
/// released, then pulled by `mix` — the reduced integrators taking over each other's damage at
/// rest as a session does ([`super::online::OnlineTear::take_over`]: each prior pull on its
/// site's vademecum), the full-order model likewise ([`reference::run_after`]; `exact`, if
/// given, must be that run). `before = []` is [`force_errors`]; `[Prior::along(off, k)]` a
/// second grasp after a first pull along the load.
pub fn force_errors_after(
    off: &std::sync::Arc<TearOffline>,
    before: &[Prior],
    mix: [f64; 3],
    exact: Option<&TearRun>,
) -> Result<Vec<[f64; 3]>, RunError> {
    let model = &off.model;
    let loads: Vec<Vec<f64>> = (0..off.patterns()).map(|p| model.pull_load(p)).collect();
    let ran;
    let exact = match exact {
        Some(r) => r,
        None => {
            let seed = RunSettings::seed(Scheme::Explicit(Tangent::Secant));
            let firsts: Vec<(TearModel, usize)> = before.iter().map(|p| (pulled(&p.site.model, p.mix), p.steps)).collect();
            let firsts: Vec<(&TearModel, usize)> = firsts.iter().map(|(m, k)| (m, *k)).collect();
            ran = reference::run_after(&firsts, &pulled(model, mix), seed, |_, _| {})?;
            &ran
        }
    };
    let grasp =
        |u: &[f64]| -> [f64; 3] { std::array::from_fn(|p| loads.get(p).map_or(0.0, |l| l.iter().zip(u).map(|(a, b)| a * b).sum())) };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let size = mix.iter().map(|m| m * m).sum::<f64>().sqrt();
    // the full-order run's levels and grasps
    let mut level = 0.0;
    let full: Vec<(f64, [f64; 3])> = std::iter::once((0.0, grasp(&exact.steps[0].u)))
        .chain(model.schedule.iter().zip(&exact.steps[1..]).map(|(ds, st)| {
            level += ds * size;
            (level, grasp(&st.u))
        }))
        .collect();
    let mut online = later_grasp(off, before);
    let mut out = Vec::with_capacity(model.schedule.len());
    let mut t = 0.0;
    for &ds in &model.schedule {
        online.step_pull(mix.map(|m| m * ds));
        t += ds * size;
        let w = grasp(&online.displacement_vec());
        let reach = dot(w, w).sqrt();
        if !(reach > 0.0 && reach.is_finite()) {
            break;
        }
        let dir = w.map(|x| x / reach);
        let phi: Vec<f64> = full.iter().map(|(_, g)| dot(*g, dir)).collect();
        let cross = phi.windows(2).position(|p| p[0] < reach && p[1] >= reach);
        let j = match cross {
            Some(j) => j,
            // past the full run's last step: its last segment, if it rises
            None if phi.len() >= 2 && phi[phi.len() - 1] > phi[phi.len() - 2] && reach > phi[phi.len() - 1] => phi.len() - 2,
            None => break,
        };
        let s = (reach - phi[j]) / (phi[j + 1] - phi[j]);
        let t_full = full[j].0 + s * (full[j + 1].0 - full[j].0);
        out.push([t, t_full, (t - t_full).abs() / t]);
    }
    Ok(out)
}

/// The calibration a bundle stores ([`TearOffline::force_error`]): [`force_errors`] of the
/// pull along the load (its full-order run is the build's own, `along`) and, when the
/// vademecum follows the pulls across it, of those both ways and of the four diagonals
/// `(1, ±1, ±1)/√3` — nine pulls, and the same nine as second grasps, merged into one
/// envelope: at each level the largest error
/// of any pull up to that level. The diagonals matter: a pull that mixes the directions
/// damages points none of the axes' pulls does, and with the axes alone mixed pulls on the
/// cube's other grasp sites were bounded in 208 of 240 states (all 240 with them). The same
/// pulls again as a second grasp ([`force_errors_after`]: after a first pull along the load
/// to half the schedule, released), so that a grasp of damaged tissue is covered too: without
/// them second grasps on the cube's sites were bounded in 265 of 280 states. Other mixed
/// pulls are not calibrated: `vademecum study` checks how often the envelope bounds them.
pub fn force_error_table(off: &std::sync::Arc<TearOffline>, along: &TearRun) -> Result<Vec<[f64; 2]>, RunError> {
    Calibration::run(off, along)?.table(off)
}

/// The envelope of calibrated pulls ([`Calibration::table`]): `pulls` rows `[level, level of
/// the full model, relative error]`, the first `firsts` of them first grasps. The table's
/// levels are those every first grasp reached (up to the smallest of their highest levels);
/// rows `[level, largest error of any state at or below it]`, levels increasing.
fn envelope(pulls: &[Vec<[f64; 3]>], firsts: usize) -> Vec<[f64; 2]> {
    let reached = |p: &Vec<[f64; 3]>| p.iter().map(|r| r[0]).fold(0.0, f64::max);
    let cap = pulls[..firsts].iter().map(reached).fold(f64::INFINITY, f64::min);
    let mut states: Vec<[f64; 2]> = pulls
        .iter()
        .flatten()
        .filter(|r| r[0] > 0.0 && r[0] <= cap && r[2].is_finite())
        .map(|r| [r[0], r[2]])
        .collect();
    states.sort_by(|a, b| a[0].total_cmp(&b[0]));
    let levels: Vec<f64> = pulls[0].iter().map(|r| r[0]).filter(|&l| l > 0.0 && l <= cap).collect();
    let mut levels = levels;
    levels.sort_by(f64::total_cmp);
    levels.dedup();
    let (mut worst, mut next) = (0.0f64, 0);
    levels
        .into_iter()
        .map(|level| {
            while next < states.len() && states[next][0] <= level {
                worst = worst.max(states[next][1]);
                next += 1;
            }
            [level, worst]
        })
        .collect()
}

/// The steps of the first pull along the load before a second grasp, in the calibration and
/// the study's samples ([`force_errors_after`]): half the model's schedule.
pub fn second_grasp_steps(model: &TearModel) -> usize {
    model.schedule.len() / 2
}

/// The full-order runs of the calibration's pulls ([`force_error_table`]), run once and
/// reused for every vademecum of the same model (the prefixes a target tries).
pub struct Calibration<'a> {
    along: &'a TearRun,
    across: Vec<([f64; 3], TearRun)>,
    /// The second grasps: after the first `pre` steps along the load, each pull's run.
    pre: usize,
    second: Vec<([f64; 3], TearRun)>,
}

impl<'a> Calibration<'a> {
    /// The pulls across the load and the diagonals, when `off`'s vademecum follows them, and
    /// every pull (along the load too) as a second grasp ([`force_error_table`]).
    pub fn run(off: &TearOffline, along: &'a TearRun) -> Result<Self, RunError> {
        let seed = RunSettings::seed(Scheme::Explicit(Tangent::Secant));
        let mixes: Vec<[f64; 3]> = if off.patterns() == 3 {
            let r = 1.0 / 3f64.sqrt();
            vec![
                [0.0, 1.0, 0.0],
                [0.0, -1.0, 0.0],
                [0.0, 0.0, 1.0],
                [0.0, 0.0, -1.0],
                [r, r, r],
                [r, -r, r],
                [r, r, -r],
                [r, -r, -r],
            ]
        } else {
            Vec::new()
        };
        let model = &off.model;
        let across = mixes
            .iter()
            .map(|&mix| Ok((mix, reference::run(&pulled(model, mix), seed, |_, _| {})?)))
            .collect::<Result<Vec<_>, RunError>>()?;
        let pre = second_grasp_steps(model);
        let second = std::iter::once([1.0, 0.0, 0.0])
            .chain(mixes)
            .map(|mix| Ok((mix, reference::run_after(&[(model, pre)], &pulled(model, mix), seed, |_, _| {})?)))
            .collect::<Result<Vec<_>, RunError>>()?;
        Ok(Self {
            along,
            across,
            pre,
            second,
        })
    }

    /// The envelope of `off`'s force errors over the calibrated pulls: rows `[level, error]`,
    /// at each level the largest error of any pull up to it. Its levels are those every first
    /// grasp reached; a second grasp whose run ended earlier counts up to where it went.
    ///
    /// The envelope is taken over load levels, not steps: every calibrated state `(level,
    /// error)` of every pull, sorted by level, the error at each level the largest of any state
    /// at or below it. On a monotone schedule this is the running maximum step by step; on a
    /// cyclic one (the seed's shear cube, loaded and unloaded) the states on the way back down
    /// count at their own, lower levels — so the table's levels still increase, and the
    /// unloading branch's errors bound the loading branch's too. States at level 0 (a
    /// schedule back at rest: a relative error has no meaning there) are left out.
    pub fn table(&self, off: &std::sync::Arc<TearOffline>) -> Result<Vec<[f64; 2]>, RunError> {
        let mut pulls = vec![force_errors(off, [1.0, 0.0, 0.0], Some(self.along))?];
        for (mix, run) in &self.across {
            pulls.push(force_errors(off, *mix, Some(run))?);
        }
        let firsts = pulls.len();
        for (mix, run) in &self.second {
            pulls.push(force_errors_after(off, &[Prior::along(off, self.pre)], *mix, Some(run))?);
        }
        Ok(envelope(&pulls, firsts))
    }
}

#[cfg(test)]
mod tests {
    use super::envelope;

    /// A monotone schedule: the running maximum, step by step, up to the level every first
    /// grasp reached; a cyclic one (loaded, unloaded to rest, loaded further): levels still
    /// increase, the unloading branch's larger errors bound the levels at and above theirs,
    /// and the state at rest (level 0, no relative error) is left out.
    #[test]
    fn the_calibration_envelope_is_over_increasing_levels_for_any_schedule() {
        let pull = |rows: &[(f64, f64)]| rows.iter().map(|&(l, e)| [l, l, e]).collect::<Vec<_>>();
        let along = pull(&[(1.0, 0.01), (2.0, 0.03), (3.0, 0.02)]);
        let across = pull(&[(1.0, 0.02), (2.0, 0.01)]);
        let second = pull(&[(1.0, 0.0), (2.0, 0.05), (3.0, 0.5)]);
        assert_eq!(
            envelope(&[along, across, second], 2),
            vec![[1.0, 0.02], [2.0, 0.05]],
            "the levels every first grasp reached"
        );
        let cyclic = pull(&[(1.0, 0.01), (2.0, 0.02), (1.0, 0.04), (0.0, f64::NAN), (2.0, 0.03), (4.0, 0.05)]);
        let t = envelope(&[cyclic], 1);
        assert_eq!(t, vec![[1.0, 0.04], [2.0, 0.04], [4.0, 0.05]]);
        assert!(t.windows(2).all(|w| w[1][0] > w[0][0] && w[1][1] >= w[0][1]));
    }
}
