//! The study's sweep of the large-deformation lattice (scenes with `effects.deformation =
//! "large"`): lattice sizes — a quarter, half, one and two times `fidelity.large.positions`;
//! farthest-point sampling nests them, so one build of the largest gives every size, each
//! position timed — against the positions a contact blends (1, the reduced fidelity, or 4).
//! Then, at the scene's positions blending four, each setting of a position's path one at a
//! time: half and twice `fidelity.large.load_steps` (the Newton snapshots), a third and two
//! thirds of `fidelity.large.modes` (the POD basis), and ANM orders 2, 4 and 8 beside the
//! scene's `fidelity.large.order` (one lattice build each).
//! For each point: the served force's error against full Newton at surface nodes off every
//! lattice (relative, median and largest, over the states within the lattice's force), how
//! often the error estimate bounds it, the online cost of the law per tick (mean, p50 and p99
//! over the sampled states, beside a null loop), and the offline cost (its positions' build
//! time, its bundle bytes). Kept in `lattice.json` for the study's build: a resumed study does
//! not redo it.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};
use vademecum_engine::offline::BuildOptions;
use vademecum_engine::rom::lattice_check;
use vademecum_engine::rom::palpation::{AnmLattice, AnmLatticeParams, NewtonLaw};
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::schema::LargeFidelity;
use vademecum_engine::study::estimate::{self, within_force};

use super::bench_pgd::{stat, time_n};
use super::study_report::{Group, scatter};

/// Positions blended per contact: the reduced fidelity's one, and the session's four.
const NEIGHBOURS: [usize; 2] = [1, 4];

/// Evaluations of the law timed per point.
const TIMED: usize = 20_000;

/// One point of the sweep.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct LatticePoint {
    pub(super) positions: usize,
    pub(super) neighbours: usize,
    /// The path's settings: Newton load steps (snapshots), most POD modes, ANM order.
    pub(super) load_steps: usize,
    pub(super) modes: usize,
    pub(super) order: usize,
    /// States within the lattice's force (the same states for every point), and the relative
    /// error of the served force there.
    pub(super) states: usize,
    pub(super) median_error: f64,
    pub(super) max_error: f64,
    /// States (all, past the paths too) whose error the estimate bounds, of `all_states`.
    pub(super) bounded: usize,
    pub(super) all_states: usize,
    /// The law's evaluation over the sampled states (µs): mean (its cost per tick, what the
    /// front weighs: a state within a path costs a bisection, one past it a tangent), p50, p99.
    pub(super) tick_mean_us: f64,
    pub(super) tick_p50_us: f64,
    pub(super) tick_p99_us: f64,
    pub(super) null_p50_us: f64,
    pub(super) build_s: f64,
    pub(super) bytes: usize,
    /// The path's own error: median and largest relative error of the served force at the
    /// scene's lattice positions themselves (full Newton there, between its load steps), where
    /// no interpolation enters — what the load steps, POD modes and ANM order decide. `None`
    /// for a lattice that lacks some of those positions.
    #[serde(default)]
    pub(super) path_median_error: Option<f64>,
    #[serde(default)]
    pub(super) path_max_error: Option<f64>,
    #[serde(default)]
    pub(super) front: bool,
}

/// What `lattice.json` keeps.
#[derive(Debug, Serialize, Deserialize)]
struct LatticeRecord {
    key: String,
    points: Vec<LatticePoint>,
}

/// The key of `lattice.json`: the study's build and this sweep's version (a record written
/// before the path settings were swept is redone).
fn record_key(key: &str) -> String {
    format!("{key}/paths")
}

/// Bundle bytes of a lattice (what its arrays hold, f64 each).
fn lattice_bytes(lattice: &AnmLattice) -> usize {
    let a = lattice.to_arrays();
    8 * (a.max_force.len()
        + a.nodes.len()
        + a.points.len()
        + a.normals.len()
        + a.d_linear.len()
        + a.modes.len()
        + a.probe.len()
        + a.step_ptr.len()
        + a.step_meta.len()
        + a.step_data.len())
}

/// Measures `lattice` (built with `params`, in `build_s`) blending `k` positions against the
/// full-order laws `truth` off the lattice: the errors within its force, the estimate's
/// coverage, the law's cost per tick beside a null loop; and against `own`, the laws at the
/// scene's positions, the path's own error when the lattice holds them all.
fn measure(
    lattice: &AnmLattice,
    params: &AnmLatticeParams,
    k: usize,
    truth: &[NewtonLaw],
    own: &[NewtonLaw],
    build_s: f64,
) -> LatticePoint {
    let samples = estimate::served(lattice, truth, k);
    let within = within_force(&samples);
    let holds_own = !own.is_empty() && own.iter().all(|l| lattice.positions.iter().any(|p| p.node == l.node));
    let path = holds_own.then(|| within_force(&estimate::served(lattice, own, k)));
    let mut zeta = vec![0.0; lattice.max_modes()];
    let mut i = 0;
    let evals = time_n(TIMED, || {
        i = (i + 1) % samples.len().max(1);
        samples
            .get(i)
            .map_or(0.0, |s| lattice.stiffness_ratio(s.point_m, s.depth_m, k, &mut zeta).ratio)
    });
    let tick_mean_us = evals.iter().sum::<f64>() / evals.len().max(1) as f64;
    let tick = stat("law", evals);
    let null = stat("null", time_n(TIMED, || 0.0));
    LatticePoint {
        positions: lattice.positions.len(),
        neighbours: k,
        load_steps: params.load_steps,
        modes: params.modes,
        order: params.order,
        states: within.len(),
        median_error: within.get(within.len() / 2).copied().unwrap_or(f64::NAN),
        max_error: within.last().copied().unwrap_or(f64::NAN),
        bounded: samples.iter().filter(|s| s.bounded()).count(),
        all_states: samples.len(),
        tick_mean_us,
        tick_p50_us: tick.p50_us,
        tick_p99_us: tick.p99_us,
        null_p50_us: null.p50_us,
        build_s,
        bytes: lattice_bytes(lattice),
        path_median_error: path.as_ref().and_then(|e| e.get(e.len() / 2).copied()),
        path_max_error: path.as_ref().and_then(|e| e.last().copied()),
        front: false,
    }
}

/// The path settings swept at the scene's positions, one knob at a time from `p`'s: half and
/// twice the load steps, a third and two thirds of the modes, ANM orders 2, 4, 8.
fn path_settings(p: &AnmLatticeParams) -> Vec<AnmLatticeParams> {
    let mut out: Vec<AnmLatticeParams> = Vec::new();
    for steps in [p.load_steps.div_ceil(2).max(2), 2 * p.load_steps] {
        out.push(AnmLatticeParams { load_steps: steps, ..*p });
    }
    for modes in [p.modes.div_ceil(3), (2 * p.modes).div_ceil(3)] {
        out.push(AnmLatticeParams { modes: modes.max(1), ..*p });
    }
    for order in [2, 4, 8] {
        out.push(AnmLatticeParams { order, ..*p });
    }
    out.retain(|q| q != p);
    out.dedup();
    out
}

/// Sweeps the lattice of organ 0 of `scene` (see the [module docs](self)) with full Newton at
/// `nodes` nodes off it; writes `lattice.csv` and `lattice_error_vs_tick.svg` to `out`. `None`
/// for a scene without large deformations.
pub(super) fn sweep(scene: &Scene, key: &str, nodes: usize, out: &Path) -> anyhow::Result<Option<Vec<LatticePoint>>> {
    let Some(params) = BuildOptions::for_scene(scene, true).large else {
        return Ok(None);
    };
    let record_path = out.join("lattice.json");
    if let Ok(old) = std::fs::read_to_string(&record_path)
        && let Ok(rec) = serde_json::from_str::<LatticeRecord>(&old)
        && rec.key == record_key(key)
    {
        eprintln!("resuming: the lattice sweep in {} is reused", record_path.display());
        return Ok(Some(rec.points));
    }
    let model = scene.organ_model(0)?;
    // the law `build` gives the lattice: St Venant–Kirchhoff with the materials' E and ν
    let laws = &vademecum_engine::rom::palpation::svk_laws(&model);
    let sizes: Vec<usize> = {
        let p = params.positions.max(2);
        let mut s = vec![(p / 4).max(2), (p / 2).max(2), p, 2 * p];
        s.dedup();
        s
    };
    let largest = *sizes.last().expect("not empty");
    let bar = ProgressBar::new(largest as u64);
    bar.set_style(ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed}]").unwrap_or_else(|_| ProgressStyle::default_bar()));
    bar.set_message("lattice positions (the largest lattice; the smaller ones are its first positions)");
    let mut times = Vec::with_capacity(largest);
    let mut last = Instant::now();
    let full = AnmLattice::build(
        &model,
        laws,
        &vademecum_engine::rom::palpation::AnmLatticeParams {
            positions: largest,
            ..params
        },
        |done, total| {
            times.push(last.elapsed().as_secs_f64());
            last = Instant::now();
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        },
    )?;
    bar.finish_and_clear();
    let spinner = ProgressBar::new_spinner();
    spinner.enable_steady_tick(std::time::Duration::from_millis(120));
    spinner.set_message(format!("lattice sweep: full Newton at {nodes} nodes off the lattice"));
    let exclude: Vec<usize> = full.positions.iter().map(|p| p.node).collect();
    let truth = lattice_check::newton_laws(&model, &params, &exclude, nodes, |done, total| {
        spinner.set_message(format!("lattice sweep: full Newton at nodes off the lattice, {done}/{total}"))
    })?;
    // the laws at the scene's own positions, between the paths' load steps
    let between = AnmLatticeParams {
        load_steps: 2 * params.load_steps + 1,
        ..params
    };
    let scene_positions = &full.positions[..params.positions.min(full.positions.len())];
    let mut own = Vec::with_capacity(scene_positions.len());
    for (i, p) in scene_positions.iter().enumerate() {
        spinner.set_message(format!(
            "lattice sweep: full Newton at the scene's positions, {i}/{}",
            scene_positions.len()
        ));
        match NewtonLaw::at(&model, laws, &between, p.node) {
            Ok(law) => own.push(law),
            Err(e) => spinner.suspend(|| eprintln!("lattice sweep: no full Newton at position node {}: {e}", p.node)),
        }
    }
    spinner.finish_and_clear();

    let mut points = Vec::new();
    for &p in &sizes {
        let lattice = AnmLattice {
            max_force: full.max_force,
            positions: full.positions[..p.min(full.positions.len())].to_vec(),
        };
        let build_s = times.iter().take(lattice.positions.len()).sum();
        for k in NEIGHBOURS {
            points.push(measure(&lattice, &params, k, &truth, &own, build_s));
        }
    }
    // the path's settings, one at a time, at the scene's positions blending four
    let settings = path_settings(&params);
    let bar = ProgressBar::new((settings.len() * params.positions) as u64);
    bar.set_style(ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed}]").unwrap_or_else(|_| ProgressStyle::default_bar()));
    for (i, q) in settings.iter().enumerate() {
        bar.set_message(format!(
            "lattice paths: {} load steps, {} modes, order {}",
            q.load_steps, q.modes, q.order
        ));
        let start = Instant::now();
        match AnmLattice::build(&model, laws, q, |done, _| bar.set_position((i * params.positions + done) as u64)) {
            Ok(lattice) => points.push(measure(&lattice, q, 4, &truth, &own, start.elapsed().as_secs_f64())),
            Err(e) => bar.suspend(|| {
                eprintln!(
                    "lattice paths: {} load steps, {} modes, order {}: not built ({e})",
                    q.load_steps, q.modes, q.order
                )
            }),
        }
    }
    bar.finish_and_clear();
    let front = super::study_report::pareto(&points.iter().map(|p| (p.tick_mean_us, p.max_error)).collect::<Vec<_>>());
    for (p, f) in points.iter_mut().zip(front) {
        p.front = f;
    }
    let mut csv = String::from(
        "positions,neighbours,load_steps,modes,order,states,median_error,max_error,path_median_error,path_max_error,bounded,all_states,tick_mean_us,tick_p50_us,tick_p99_us,null_p50_us,build_s,bytes,front\n",
    );
    for p in &points {
        csv += &format!(
            "{},{},{},{},{},{},{:e},{:e},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.2},{},{}\n",
            p.positions,
            p.neighbours,
            p.load_steps,
            p.modes,
            p.order,
            p.states,
            p.median_error,
            p.max_error,
            p.path_median_error.map_or(String::new(), |e| format!("{e:e}")),
            p.path_max_error.map_or(String::new(), |e| format!("{e:e}")),
            p.bounded,
            p.all_states,
            p.tick_mean_us,
            p.tick_p50_us,
            p.tick_p99_us,
            p.null_p50_us,
            p.build_s,
            p.bytes,
            p.front
        );
    }
    std::fs::write(out.join("lattice.csv"), csv).context("cannot write lattice.csv")?;
    plot(
        &points,
        &scene.spec.scene.name,
        &scene.spec.fidelity.large,
        &out.join("lattice_error_vs_tick.svg"),
    )?;
    let rec = LatticeRecord {
        key: record_key(key),
        points,
    };
    std::fs::write(&record_path, serde_json::to_string_pretty(&rec)?)?;
    Ok(Some(rec.points))
}

/// Whether `p` has the scene's path settings `large`.
fn scenes_paths(p: &LatticePoint, large: &LargeFidelity) -> bool {
    (p.load_steps, p.modes, p.order) == (large.load_steps, large.modes, large.order)
}

/// The sentence of the verdict: the scene's setting, and the cheapest point on the front whose
/// median error within the lattice's force is at most 1 % and whose error estimate bounds at
/// least 95 % of the states (a setting whose error bars cannot be trusted is not recommended).
pub(super) fn verdict(points: &[LatticePoint], large: &LargeFidelity) -> String {
    let describe = |p: &LatticePoint| {
        let paths = if scenes_paths(p, large) {
            String::new()
        } else {
            format!(", {} load steps, {} modes, ANM order {}", p.load_steps, p.modes, p.order)
        };
        format!(
            "{} positions blending {}{paths} ({:.2} % median, {:.2} % largest error within the lattice's force, {:.2} µs per tick on average, {:.1} s of build, {} of {} states bounded by the estimate)",
            p.positions,
            p.neighbours,
            100.0 * p.median_error,
            100.0 * p.max_error,
            p.tick_mean_us,
            p.build_s,
            p.bounded,
            p.all_states
        )
    };
    let own = points
        .iter()
        .find(|p| p.positions == large.positions && p.neighbours == 4 && scenes_paths(p, large));
    let best = points
        .iter()
        .filter(|p| p.front && p.median_error <= 1e-2 && p.bounded as f64 >= super::study_estimate::REQUIRED * p.all_states as f64)
        .min_by(|a, b| a.tick_mean_us.total_cmp(&b.tick_mean_us));
    let paths = own.and_then(|o| {
        let path_max = o.path_max_error?;
        // the cheapest build at the scene's positions whose paths stay within 0.1 % where
        // no interpolation enters
        let cheapest = points
            .iter()
            .filter(|p| p.positions == large.positions && p.neighbours == 4 && p.path_max_error.is_some_and(|e| e <= 1e-3))
            .min_by(|a, b| a.build_s.total_cmp(&b.build_s))?;
        Some(format!(
            " The paths' own error at the scene's positions, where no interpolation enters: {:.1e} largest with the scene's settings, against {:.2} % median between positions; the cheapest paths within 0.1 % there: {} load steps, {} modes, ANM order {} ({:.1e} largest, {:.1} s of build against {:.1} s).",
            path_max,
            100.0 * o.median_error,
            cheapest.load_steps,
            cheapest.modes,
            cheapest.order,
            cheapest.path_max_error.unwrap_or(f64::NAN),
            cheapest.build_s,
            o.build_s
        ))
    });
    format!(
        "Large-deformation lattice — the scene's setting: {}; the cheapest on the front with a median error within 1 % and its estimate holding in 95 % of the states: {}.{}",
        own.map_or("not swept".into(), describe),
        best.map_or("none".into(), describe),
        paths.unwrap_or_default()
    )
}

/// Largest error within the paths against the law's cost per tick, one colour per blend, the
/// lattice size written beside each point; the path settings (scene's positions, blending
/// four) as triangles, their setting beside each; the front drawn as a line.
fn plot(points: &[LatticePoint], scene: &str, large: &LargeFidelity, file: &Path) -> anyhow::Result<()> {
    let mut groups: Vec<Group> = NEIGHBOURS
        .into_iter()
        .map(|k| Group {
            label: format!("blending {k} position(s)"),
            triangles: false,
            points: points
                .iter()
                .filter(|p| p.neighbours == k && scenes_paths(p, large))
                .map(|p| (p.tick_mean_us, p.max_error, p.positions.to_string()))
                .collect(),
        })
        .collect();
    groups.push(Group {
        label: format!("{} positions, other path settings (steps s, modes m, ANM order o)", large.positions),
        triangles: true,
        points: points
            .iter()
            .filter(|p| !scenes_paths(p, large))
            .map(|p| (p.tick_mean_us, p.max_error, format!("s{} m{} o{}", p.load_steps, p.modes, p.order)))
            .collect(),
    });
    let front = points.iter().filter(|p| p.front).map(|p| (p.tick_mean_us, p.max_error)).collect();
    scatter(
        file,
        &format!("{scene}: large-deformation lattice, error against cost per tick"),
        (
            "the law's evaluation per tick, mean over the sampled states (µs)",
            "largest relative force error within the lattice's force",
        ),
        &groups,
        front,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(positions: usize, neighbours: usize, median: f64, cost: f64, front: bool) -> LatticePoint {
        LatticePoint {
            positions,
            neighbours,
            load_steps: 6,
            modes: 9,
            order: 6,
            states: 10,
            median_error: median,
            max_error: 3.0 * median,
            bounded: 12,
            all_states: 12,
            tick_mean_us: cost,
            tick_p50_us: cost,
            tick_p99_us: 2.0 * cost,
            null_p50_us: 0.02,
            build_s: positions as f64,
            bytes: 1000 * positions,
            path_median_error: None,
            path_max_error: None,
            front,
        }
    }

    #[test]
    fn the_verdict_names_the_scenes_setting_and_the_cheapest_front_point_within_one_percent() {
        let points = [
            point(4, 1, 3e-2, 0.5, true),
            point(4, 4, 8e-3, 2.0, true),
            point(9, 4, 5e-3, 3.0, true),
            point(9, 1, 9e-3, 1.0, false),
            // cheaper still, but its error estimate holds in 5 of 12 states
            LatticePoint {
                bounded: 5,
                ..point(2, 1, 6e-3, 0.2, true)
            },
        ];
        let large = LargeFidelity {
            positions: 9,
            ..LargeFidelity::default()
        };
        let v = verdict(&points, &large);
        assert!(v.contains("the scene's setting: 9 positions blending 4 (0.50 % median"), "{v}");
        assert!(v.contains("95 % of the states: 4 positions blending 4 (0.80 % median"), "{v}");
        let alone = verdict(&points[..1], &large);
        assert!(alone.contains("not swept") && alone.ends_with("none."), "{alone}");
        // a cheaper path setting at the scene's positions is named with its settings
        let mut with_paths = points.to_vec();
        with_paths.push(LatticePoint {
            order: 2,
            ..point(9, 4, 7e-3, 1.5, true)
        });
        let v = verdict(&with_paths, &large);
        assert!(
            v.contains("95 % of the states: 9 positions blending 4, 6 load steps, 9 modes, ANM order 2 (0.70 % median"),
            "{v}"
        );
        // the paths' own error: the cheapest build whose paths stay within 0.1 %
        let with_path = |p: LatticePoint, e: f64, build_s: f64| LatticePoint {
            path_max_error: Some(e),
            build_s,
            ..p
        };
        let paths = [
            with_path(point(9, 4, 5e-3, 3.0, true), 1e-7, 9.0),
            with_path(
                LatticePoint {
                    load_steps: 3,
                    ..point(9, 4, 5e-3, 3.0, false)
                },
                2e-5,
                5.0,
            ),
            with_path(
                LatticePoint {
                    modes: 2,
                    ..point(9, 4, 5e-3, 3.0, false)
                },
                4e-3,
                4.0,
            ),
        ];
        let v = verdict(&paths, &large);
        assert!(
            v.contains("1.0e-7 largest with the scene's settings, against 0.50 % median between positions; the cheapest paths within 0.1 % there: 3 load steps, 9 modes, ANM order 6 (2.0e-5 largest, 5.0 s of build against 9.0 s)"),
            "{v}"
        );
    }

    #[test]
    fn the_path_settings_vary_one_knob_at_a_time_and_never_repeat_the_scenes() {
        let p = AnmLatticeParams::default();
        let s = path_settings(&p);
        assert_eq!(s.len(), 7, "{s:?}");
        assert!(!s.contains(&p));
        for q in &s {
            let changed = [q.load_steps != p.load_steps, q.modes != p.modes, q.order != p.order];
            assert_eq!(changed.iter().filter(|&&c| c).count(), 1, "{q:?}");
            assert_eq!((q.positions, q.max_force), (p.positions, p.max_force));
        }
        assert!(s.iter().any(|q| q.load_steps == 3) && s.iter().any(|q| q.load_steps == 12));
        assert!(s.iter().any(|q| q.modes == 3) && s.iter().any(|q| q.modes == 6));
    }

    #[test]
    fn a_scene_without_large_deformations_has_no_lattice_to_sweep() {
        let scene = Scene::from_toml(vademecum_engine::scene::builtin("organ").unwrap(), ".").unwrap();
        let dir = tempfile::tempdir().unwrap();
        assert!(sweep(&scene, "k", 4, dir.path()).unwrap().is_none());
        assert!(!dir.path().join("lattice.json").exists());
    }
}
