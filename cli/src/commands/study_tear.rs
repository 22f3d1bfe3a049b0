//! The study's sweep of tearing (scenes with `effects.tearing = true`; seed 000 ch. 4): the
//! POD–PGD integrator at every size of its two reductions, against the full-order explicit
//! reference it reduces, on the scene's schedule.
//!
//! The full-order references run once (the two explicit schemes, h = 0 and h ≠ 0: the
//! snapshots, and the references of the simplified and the full integrator). Then for each
//! number of POD vectors of the damage field (1, 2, the scene's, and more when the snapshots
//! carry them) one vademecum is built over the POD coefficients with the scene's settings, each
//! mode timed; its prefixes of 5, 10, 20, 40 and all modes (the greedy build stopped there,
//! [`DamageVademecum::prefix`]) are the points. The pulls across the load are left out: the
//! error is that of the pull along the scene's load.
//!
//! Per point: the vademecum's own error (its increment against exact solves at the snapshots'
//! coefficients: the PGD truncation alone), the worst relative L2 error of the displacement over the schedule's steps
//! against the scene's integrator's reference, the worst relative error of the grasp's
//! response (the load-weighted displacement along the load, what the grasper feels), the online
//! step's cost (p50, p99 beside a null loop), the offline cost (POD + vademecum to that mode +
//! Ritz form, the shared references apart) and the offline data's bytes. Kept in `tear.json`.
//!
//! [`DamageVademecum::prefix`]: vademecum_engine::damage::vademecum::DamageVademecum::prefix

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};
use vademecum_engine::damage::build;
use vademecum_engine::damage::model::TearModel;
use vademecum_engine::damage::online::{OnlineTear, RitzOperator, StepLimits, TearOffline, Variant};
use vademecum_engine::damage::pod::DamageBasis;
use vademecum_engine::damage::reference;
use vademecum_engine::damage::vademecum::{self, AffineSystem};
use vademecum_engine::rom::pod::PodCriterion;
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::tearing;

use super::bench_pgd::{stat, time_n};
use super::study_report::{Group, scatter};
use super::tear_timing::{EVERY_DIRECTION, step_times};

/// Prefixes of each vademecum measured (capped at its modes; all of them always).
const PREFIXES: [usize; 4] = [5, 10, 20, 40];

/// Online steps timed per point (whole schedules).
const TIMED_STEPS: usize = 2000;

/// One point of the sweep.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct TearPoint {
    pub(super) pod_vectors: usize,
    pub(super) pgd_modes: usize,
    /// The vademecum's own error: the largest relative error of its unit-step increment
    /// against the exact `K(ξ)⁻¹ b(ξ)` at the snapshots' POD coefficients (the PGD truncation
    /// alone, without the integrator's stepping).
    #[serde(default)]
    pub(super) vademecum_error: f64,
    /// Worst relative L2 error of the displacement over the steps, and of the grasp's response.
    pub(super) field_error: f64,
    pub(super) response_error: f64,
    pub(super) step_p50_us: f64,
    pub(super) step_p99_us: f64,
    pub(super) null_p50_us: f64,
    /// POD + vademecum to this mode + Ritz form (s), the references apart.
    pub(super) build_s: f64,
    pub(super) bytes: usize,
    #[serde(default)]
    pub(super) front: bool,
}

/// What the sweep found (`tear.json`).
#[derive(Debug, Serialize, Deserialize)]
pub(super) struct TearSweep {
    key: String,
    /// The scene's integrator, POD vectors and vademecum modes.
    pub(super) variant: String,
    pub(super) scene_pod_vectors: usize,
    pub(super) scene_pgd_modes: usize,
    /// The full-order references' time (s), shared by every point.
    pub(super) reference_s: f64,
    pub(super) points: Vec<TearPoint>,
    /// The scene's whole vademecum (with its pulls across the load) and the prefixes of it
    /// `vademecum build --target-error` tries ([`target_points`]).
    #[serde(default)]
    pub(super) target: Vec<TargetPoint>,
}

/// A prefix `vademecum build --target-error` tries of the scene's whole tearing vademecum:
/// what it keeps, how close the grasper's force is to the full-order model's, what a step
/// costs.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct TargetPoint {
    /// Modes per pull pattern (along the load, then across it).
    pub(super) modes: Vec<usize>,
    /// The calibrated relative error of the grasper's force at the last load level, over the
    /// calibration's pulls (NaN: the calibration did not reach it).
    pub(super) force_error: f64,
    /// One step pulled along the diagonal of the three directions (every pattern stepped).
    pub(super) step_p50_us: f64,
    pub(super) step_p99_us: f64,
    pub(super) null_p50_us: f64,
}

/// The POD sizes swept: 1, 2, the scene's `own`, and twice it, within the snapshots' `rank`.
fn pod_sizes(own: usize, rank: usize) -> Vec<usize> {
    let mut s: Vec<usize> = [1, 2, own, 2 * own].into_iter().filter(|&k| k >= 1 && k <= rank.max(1)).collect();
    s.sort_unstable();
    s.dedup();
    s
}

/// The prefixes measured of a vademecum of `modes` modes.
fn prefixes(modes: usize) -> Vec<usize> {
    let mut p: Vec<usize> = PREFIXES.into_iter().filter(|&m| m < modes).collect();
    p.push(modes);
    p
}

/// Sweeps tearing on the scene's tearable organ (see the [module docs](self)); writes
/// `tear.csv`, `tear_target.csv` and `tear_error_vs_step.svg` to `out`. `None` for a scene without tearing.
pub(super) fn sweep(scene: &Scene, key: &str, out: &Path) -> anyhow::Result<Option<TearSweep>> {
    if !scene.spec.effects.tearing {
        return Ok(None);
    }
    let record_path = out.join("tear.json");
    if let Ok(old) = std::fs::read_to_string(&record_path)
        && let Ok(rec) = serde_json::from_str::<TearSweep>(&old)
        && rec.key == key
    {
        eprintln!("resuming: the tearing sweep in {} is reused", record_path.display());
        write_outputs(&rec, scene, out)?;
        return Ok(Some(rec));
    }
    let i = tearing::tearable_organ(scene).context("the scene tears but no organ has a damage law")?;
    let (model, _) = tearing::tear_model(scene, i)?;
    let (settings, limits) = tearing::settings(scene);
    let variant = scene.spec.fidelity.tearing.variant;
    let bar = ProgressBar::new(100);
    bar.set_style(ProgressStyle::with_template("{bar:30} {pos}% {msg} [{elapsed}]").unwrap_or_else(|_| ProgressStyle::default_bar()));
    let start = Instant::now();
    let runs = build::references(&model, |what, f| {
        bar.set_message(format!("tearing sweep: full-order {what}"));
        bar.set_position((100.0 * f) as u64);
    })?;
    let reference_s = start.elapsed().as_secs_f64();
    let truth = &runs[usize::from(variant == Variant::Full)];
    let snapshots = build::snapshots(&runs);
    let own = DamageBasis::from_snapshots(&snapshots, settings.pod, settings.margin)?;
    let (_, response) = super::bench_tear::measure(&model);
    let mut points = Vec::new();
    let mut scene_pgd_modes = 0;
    let sizes = pod_sizes(own.len(), snapshots.len() - 1);
    for (n, &k) in sizes.iter().enumerate() {
        bar.set_message(format!("tearing sweep: {k} POD vectors ({} of {})", n + 1, sizes.len()));
        bar.set_position(0);
        let t0 = Instant::now();
        let basis = DamageBasis::from_snapshots(&snapshots, PodCriterion { energy: 1.0, max_modes: k }, settings.margin)?;
        if points.iter().any(|p: &TearPoint| p.pod_vectors == basis.len()) {
            // the snapshots hold fewer independent damage fields than asked for
            continue;
        }
        let sys = AffineSystem::of(&model, &basis);
        let pod_s = t0.elapsed().as_secs_f64();
        // the exact increments at the snapshots' coefficients, once for every prefix
        let exact: Vec<(Vec<f64>, Vec<f64>)> = snapshots
            .iter()
            .filter_map(|s| {
                let mut xi = vec![0.0; basis.len()];
                basis.project(s, &mut xi);
                sys.solve(&xi).ok().map(|e| (xi, e))
            })
            .collect();
        let mut mode_s = Vec::new();
        let t1 = Instant::now();
        let vad = vademecum::build(&sys, &basis.lo, &basis.hi, &settings.vademecum, |m, _| {
            mode_s.push(t1.elapsed().as_secs_f64());
            bar.set_position((100 * m / settings.vademecum.max_modes.max(1)) as u64);
        })?;
        if k == own.len() {
            scene_pgd_modes = vad.n_modes;
        }
        for m in prefixes(vad.n_modes) {
            let t2 = Instant::now();
            let v = vad.prefix(m);
            let (mut a, mut du) = (vec![0.0; v.n_modes], vec![0.0; v.n_free]);
            let vademecum_error = exact.iter().fold(0.0f64, |w, (xi, e)| {
                v.coefficients(xi, &mut a);
                v.combine(&a, &mut du);
                w.max(reference::l2_error(&du, e).1)
            });
            let ritz = RitzOperator::new(&v, &sys);
            let off = Arc::new(TearOffline::new(model.clone(), basis.clone(), v, ritz));
            let build_s = pod_s + mode_s.get(m.saturating_sub(1)).copied().unwrap_or(0.0) + t2.elapsed().as_secs_f64();
            // the schedule, each step against the reference
            let mut online = OnlineTear::new(off.clone(), variant, limits);
            let (mut field_error, mut response_error) = (0.0f64, 0.0f64);
            for (s, &ds) in off.model.schedule.iter().enumerate() {
                online.step(ds);
                let u = online.displacement_vec();
                let r = &truth.steps[s + 1].u;
                field_error = field_error.max(reference::l2_error(&u, r).1);
                let (a, b) = (response(&u), response(r));
                response_error = response_error.max(super::study_report::rel(a, b));
            }
            // the step's cost over whole schedules
            let times = step_times(&off, variant, limits, [1.0, 0.0, 0.0], TIMED_STEPS);
            let (step, null) = (stat("step", times), stat("null", time_n(TIMED_STEPS, || 0.0)));
            points.push(TearPoint {
                pod_vectors: basis.len(),
                pgd_modes: m,
                vademecum_error,
                field_error,
                response_error,
                step_p50_us: step.p50_us,
                step_p99_us: step.p99_us,
                null_p50_us: null.p50_us,
                build_s,
                bytes: off.memory_bytes(),
                front: false,
            });
        }
    }
    let front = super::study_report::pareto(&points.iter().map(|p| (p.step_p50_us, p.field_error)).collect::<Vec<_>>());
    for (p, f) in points.iter_mut().zip(front) {
        p.front = f;
    }
    bar.set_message("tearing sweep: the prefixes --target-error tries (nine calibration pulls)");
    bar.set_position(0);
    let target = target_points(model.clone(), &settings, variant, limits)?;
    bar.finish_and_clear();
    let rec = TearSweep {
        key: key.to_string(),
        variant: variant.label().into(),
        scene_pod_vectors: own.len(),
        scene_pgd_modes,
        reference_s,
        points,
        target,
    };
    write_outputs(&rec, scene, out)?;
    std::fs::write(&record_path, serde_json::to_string_pretty(&rec)?)?;
    Ok(Some(rec))
}

/// The scene's whole tearing vademecum, built as `vademecum build` builds it (with its pulls
/// across the load and its nine-pull calibration), and every prefix `--target-error` tries of
/// it — 5, 10, 20, … modes a pattern, then all —, each with its calibrated force error (a
/// build asked for an unreachable target of 0 tries them all) and the cost of a step pulled
/// in every direction.
fn target_points(
    model: TearModel,
    settings: &build::TearSettings,
    variant: Variant,
    limits: StepLimits,
) -> anyhow::Result<Vec<TargetPoint>> {
    let s = build::TearSettings {
        target_force_error: Some(0.0),
        ..*settings
    };
    let (full, report, _) = build::build(model, &s, |_, _| {}).context("building the scene's tearing vademecum")?;
    let full = Arc::new(full);
    let sys = AffineSystem::of(&full.model, &full.basis);
    let tried = report.target.map(|t| t.tried).unwrap_or_default();
    Ok(tried
        .into_iter()
        .map(|(modes, force_error)| {
            let off = if modes == full.vademecum.patterns {
                full.clone()
            } else {
                Arc::new(full.pattern_prefix(&modes, &sys))
            };
            let (step, null) = (
                stat("step", step_times(&off, variant, limits, EVERY_DIRECTION, TIMED_STEPS)),
                stat("null", time_n(TIMED_STEPS, || 0.0)),
            );
            TargetPoint {
                modes,
                force_error,
                step_p50_us: step.p50_us,
                step_p99_us: step.p99_us,
                null_p50_us: null.p50_us,
            }
        })
        .collect())
}

/// Writes tear.csv, tear_target.csv and tear_error_vs_step.svg of `rec` to `out` (also when
/// the sweep is resumed).
fn write_outputs(rec: &TearSweep, scene: &Scene, out: &Path) -> anyhow::Result<()> {
    let points = &rec.points;
    let mut target = String::from("modes_along,modes_across_1,modes_across_2,force_error,step_p50_us,step_p99_us,null_p50_us\n");
    for p in &rec.target {
        let m = |k: usize| p.modes.get(k).map_or(String::new(), usize::to_string);
        target += &format!(
            "{},{},{},{:e},{:.3},{:.3},{:.3}\n",
            m(0),
            m(1),
            m(2),
            p.force_error,
            p.step_p50_us,
            p.step_p99_us,
            p.null_p50_us
        );
    }
    std::fs::write(out.join("tear_target.csv"), target).context("cannot write tear_target.csv")?;
    let mut csv = String::from(
        "pod_vectors,pgd_modes,vademecum_error,field_error,response_error,step_p50_us,step_p99_us,null_p50_us,build_s,bytes,front\n",
    );
    for p in points {
        csv += &format!(
            "{},{},{:e},{:e},{:e},{:.3},{:.3},{:.3},{:.3},{},{}\n",
            p.pod_vectors,
            p.pgd_modes,
            p.vademecum_error,
            p.field_error,
            p.response_error,
            p.step_p50_us,
            p.step_p99_us,
            p.null_p50_us,
            p.build_s,
            p.bytes,
            p.front
        );
    }
    std::fs::write(out.join("tear.csv"), csv).context("cannot write tear.csv")?;
    plot(points, &scene.spec.scene.name, &out.join("tear_error_vs_step.svg"))?;
    Ok(())
}

/// The sentence of the verdict: the scene's setting, and the cheapest point on the front whose
/// worst field error over the schedule is within 1 % (or, with none, the most accurate).
pub(super) fn verdict(s: &TearSweep) -> String {
    let describe = |p: &TearPoint| {
        format!(
            "{} POD vectors, {} PGD modes (worst error over the steps {:.1e} in the field, {:.1e} in the grasp's response, the vademecum's own {:.1e}; {:.1} µs per step p50; {:.1} s of POD and vademecum)",
            p.pod_vectors, p.pgd_modes, p.field_error, p.response_error, p.vademecum_error, p.step_p50_us, p.build_s
        )
    };
    let own = s
        .points
        .iter()
        .find(|p| p.pod_vectors == s.scene_pod_vectors && p.pgd_modes == s.scene_pgd_modes);
    let best = s
        .points
        .iter()
        .filter(|p| p.front && p.field_error <= 1e-2)
        .min_by(|a, b| a.step_p50_us.total_cmp(&b.step_p50_us));
    let best = match best {
        Some(p) => format!("the cheapest on the front within 1 %: {}", describe(p)),
        None => match s.points.iter().min_by(|a, b| a.field_error.total_cmp(&b.field_error)) {
            Some(p) => format!("no point is within 1 %; the most accurate: {}", describe(p)),
            None => "nothing was measured".into(),
        },
    };
    format!(
        "Tearing ({}, against its full-order reference; the references took {:.2} s) — the scene's setting: {}; {best}.{}",
        s.variant,
        s.reference_s,
        own.map_or("not swept".into(), describe),
        target_verdict(&s.target)
    )
}

/// The sentence on what `--target-error` keeps: the grasper's force error and step of the
/// fewest modes it tries against all of them (empty without the points).
fn target_verdict(t: &[TargetPoint]) -> String {
    let (Some(first), Some(all)) = (t.first(), t.last()) else {
        return String::new();
    };
    let pct = |e: f64| {
        if e.is_finite() {
            format!("{:.2} %", 100.0 * e)
        } else {
            "not calibrated".into()
        }
    };
    if t.len() == 1 {
        return format!(
            " The grasper's force is within {} of the full-order model's with its modes {:?} ({:.2} µs per step pulled in every direction).",
            pct(all.force_error),
            all.modes,
            all.step_p50_us
        );
    }
    // the build's fallback rule on the same prefixes (damage::build::fallback_for)
    let fallback = t[..t.len() - 1]
        .iter()
        .find(|p| p.force_error <= build::FALLBACK_ERROR_GROWTH * all.force_error)
        .map_or_else(
            || {
                format!(
                    " No fewer modes are within {} times that error: a session under load keeps them.",
                    build::FALLBACK_ERROR_GROWTH
                )
            },
            |p| {
                format!(
                    " Under load a session falls back to {:?} ({}, {:.2} µs), the fewest within {} times that error.",
                    p.modes,
                    pct(p.force_error),
                    p.step_p50_us,
                    build::FALLBACK_ERROR_GROWTH
                )
            },
        );
    format!(
        " The grasper's force, calibrated on nine pulls from virgin tissue and again as second grasps: {} with all the modes {:?} ({:.2} µs per step pulled in every direction), {} with {:?} ({:.2} µs): `vademecum build --target-error` keeps the fewest that meet its target (tear_target.csv).{fallback}",
        pct(all.force_error),
        all.modes,
        all.step_p50_us,
        pct(first.force_error),
        first.modes,
        first.step_p50_us
    )
}

/// Worst field error against the step's cost, one colour per POD size, the modes beside each
/// point, the front as a line.
fn plot(points: &[TearPoint], scene: &str, file: &Path) -> anyhow::Result<()> {
    let err = |p: &TearPoint| p.field_error.max(1e-16);
    let mut sizes: Vec<usize> = points.iter().map(|p| p.pod_vectors).collect();
    sizes.sort_unstable();
    sizes.dedup();
    let groups: Vec<Group> = sizes
        .into_iter()
        .map(|k| Group {
            label: format!("{k} POD vector(s), PGD modes beside each"),
            triangles: false,
            points: points
                .iter()
                .filter(|p| p.pod_vectors == k)
                .map(|p| (p.step_p50_us, err(p), p.pgd_modes.to_string()))
                .collect(),
        })
        .collect();
    let front = points.iter().filter(|p| p.front).map(|p| (p.step_p50_us, err(p))).collect();
    scatter(
        file,
        &format!("{scene}: tearing, error against the online step's cost"),
        ("online step, p50 (µs)", "worst relative L2 error over the schedule"),
        &groups,
        front,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pod_sizes_and_prefixes_include_the_scenes_and_stay_within_what_exists() {
        assert_eq!(pod_sizes(3, 30), [1, 2, 3, 6]);
        assert_eq!(pod_sizes(3, 4), [1, 2, 3]);
        assert_eq!(pod_sizes(1, 30), [1, 2]);
        assert_eq!(prefixes(57), [5, 10, 20, 40, 57]);
        assert_eq!(prefixes(10), [5, 10]);
        assert_eq!(prefixes(3), [3]);
    }

    fn point(pod: usize, modes: usize, err: f64, step: f64, front: bool) -> TearPoint {
        TearPoint {
            pod_vectors: pod,
            pgd_modes: modes,
            vademecum_error: err / 10.0,
            field_error: err,
            response_error: err / 2.0,
            step_p50_us: step,
            step_p99_us: 2.0 * step,
            null_p50_us: 0.02,
            build_s: 1.0,
            bytes: 1000,
            front,
        }
    }

    #[test]
    fn the_verdict_names_the_scenes_setting_and_the_cheapest_within_one_percent_or_the_best() {
        let mut s = TearSweep {
            key: "k".into(),
            variant: "POD–PGD, h = 0".into(),
            scene_pod_vectors: 3,
            scene_pgd_modes: 57,
            reference_s: 0.5,
            target: Vec::new(),
            points: vec![
                point(3, 57, 2e-4, 40.0, true),
                point(3, 10, 5e-3, 12.0, true),
                point(1, 5, 0.2, 3.0, true),
            ],
        };
        let v = verdict(&s);
        assert!(
            v.contains("the scene's setting: 3 POD vectors, 57 PGD modes (worst error over the steps 2.0e-4"),
            "{v}"
        );
        assert!(
            v.contains("the cheapest on the front within 1 %: 3 POD vectors, 10 PGD modes"),
            "{v}"
        );
        s.points.retain(|p| p.field_error > 1e-2);
        let v = verdict(&s);
        assert!(
            v.contains("not swept") && v.contains("no point is within 1 %; the most accurate: 1 POD vectors, 5 PGD modes"),
            "{v}"
        );
    }

    #[test]
    fn the_target_sentence_names_the_fallback_the_build_would_store() {
        let p = |k: usize, e: f64| TargetPoint {
            modes: vec![k; 3],
            force_error: e,
            step_p50_us: k as f64,
            step_p99_us: k as f64,
            null_p50_us: 0.02,
        };
        // the gallbladder's: five modes within 1.25 times all sixty's error
        let v = target_verdict(&[p(5, 0.0521), p(10, 0.049), p(60, 0.0467)]);
        assert!(v.contains("Under load a session falls back to [5, 5, 5] (5.21 %"), "{v}");
        // the first prefix too far off: the next one that is not
        let v = target_verdict(&[p(5, 0.2), p(10, 0.05), p(60, 0.045)]);
        assert!(v.contains("falls back to [10, 10, 10] (5.00 %"), "{v}");
        // none within it: the session keeps its modes
        let v = target_verdict(&[p(5, 0.2), p(60, 0.045)]);
        assert!(v.contains("a session under load keeps them"), "{v}");
    }
}
