//! `vademecum build`: PGD vademecums of every organ of a scene, written as bundles.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::Context;
use vademecum_engine::bundle;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::damage::build::{TearBuildReport, TearTarget};
use vademecum_engine::offline::shard::{self, ShardInfo, ShardOf};
use vademecum_engine::offline::{self, BuildOptions, BuildStage, Built, ModesFrom};
use vademecum_engine::rom::palpation::LatticeTarget;
use vademecum_engine::scene::Scene;
use vademecum_engine::xfem::accuracy::SliverTarget;

use super::scene_input::{load_scene, memory_limit};
use crate::cli::{BuildArgs, MergeArgs, ModesMethod};
use crate::progress::Stages;

/// Builds organ `i` of `scene` with the greedy PGD, with a progress display.
pub(crate) fn build_with_progress(scene: &Scene, i: usize, opts: &BuildOptions) -> anyhow::Result<(Built, Stages)> {
    build_from_with_progress(scene, i, opts, ModesFrom::Pgd)
}

/// Builds organ `i` of `scene`, its modes from `from`, with a progress display.
fn build_from_with_progress(scene: &Scene, i: usize, opts: &BuildOptions, from: ModesFrom<'_>) -> anyhow::Result<(Built, Stages)> {
    let name = scene.spec.organs[i].name.clone();
    let eps = opts.params.global_tolerance;
    let bar = Stages::start(&format!("building '{name}'"));
    // refused or warned before the build, which can take minutes
    let model = scene.organ_model_within(i, opts.max_memory);
    let model = match model {
        Ok(m) => m,
        Err(e) => {
            bar.finish();
            return Err(anyhow::Error::new(e).context(format!("cannot build organ '{name}'")));
        }
    };
    for w in &model.warnings {
        bar.warn(w);
    }
    let built = offline::build_organ_from(scene, i, opts, from, &mut |s| match s {
        BuildStage::Assembly => bar.stage("assembling K"),
        BuildStage::Factorization => bar.stage("factoring K"),
        BuildStage::Mode(k, e) => bar.stage(&format!("mode {k}, energy {e:.2e} (stop below {eps:.1e})")),
        BuildStage::Recompression => bar.stage("recompressing (QR + SVD)"),
        BuildStage::Exact(done, total) => bar.stage(&format!("exact pass: compliances and errors, {done}/{total} load states")),
        BuildStage::Lattice(done, total) => bar.stage(&format!(
            "large deformations: full Newton, POD and ANM at lattice position {done}/{total}"
        )),
        BuildStage::LatticeCheck(done, total) => bar.stage(&format!(
            "large deformations: full Newton off the lattice for --target-error, node {done}/{total}"
        )),
        BuildStage::CutBasis => bar.stage("cutting: the K-orthonormal Ritz basis for bare enrichment"),
        BuildStage::CutCalibration(done, total) => bar.stage(&format!(
            "cutting: the bare enrichment's force against the full XFEM, cracked node {done}/{total}"
        )),
        BuildStage::Tearing {
            site,
            sites,
            what,
            fraction,
        } => bar.stage(&if sites > 1 {
            format!("tearing, grasp site {}/{sites}: {what} {:.0} %", site + 1, 100.0 * fraction)
        } else {
            format!("tearing: {what} {:.0} %", 100.0 * fraction)
        }),
    })
    .with_context(|| format!("cannot build organ '{name}'"))?;
    Ok((built, bar))
}

/// The bundle of every organ of `scene` in `dir` (`<dir>/<organ>.bundle`), loaded and
/// checked against the scene and its meshes; a bundle that is missing, unreadable or built
/// from another scene or mesh is (re)built first, with a note on stderr saying why.
pub(crate) fn ensure_bundles(scene: &Scene, dir: &Path) -> anyhow::Result<Vec<Arc<LoadedBundle>>> {
    let mut out = Vec::new();
    for i in 0..scene.spec.organs.len() {
        let name = &scene.spec.organs[i].name;
        let path = dir.join(format!("{name}.bundle"));
        let mesh = scene.organ_mesh(i)?;
        let reason = if !path.exists() {
            format!("no bundle at {} yet", path.display())
        } else {
            match bundle::load_bundle(&path) {
                Ok(b) => match bundle::check_matches(&path, &b.manifest, scene, &mesh) {
                    Ok(()) => {
                        out.push(Arc::new(b));
                        continue;
                    }
                    Err(e) => e.to_string(),
                },
                Err(e) => e.to_string(),
            }
        };
        eprintln!("vademecum: building the vademecum of '{name}' ({reason})");
        let opts = BuildOptions {
            max_memory: memory_limit(None)?,
            ..BuildOptions::for_scene(scene, true)
        };
        let (built, bar) = build_with_progress(scene, i, &opts)?;
        bar.stage("writing bundle");
        offline::write_bundle(&path, scene, &built).with_context(|| format!("cannot write bundle {}", path.display()))?;
        bar.finish();
        let b = bundle::load_bundle(&path).with_context(|| format!("cannot read back bundle {}", path.display()))?;
        out.push(Arc::new(b));
    }
    Ok(out)
}

/// Frames timed per prefix by `--target-tick-us`.
const TIMED_FRAMES: usize = 400;

/// Whether the kept modes of `built` evaluate a frame within `target_us` (their p50, µs), or
/// why not: their time, and the most modes of the build's error curve that fit, with their
/// error.
fn within_tick(built: &offline::Built, target_us: f64) -> anyhow::Result<Result<f64, String>> {
    let v = &built.vademecum;
    let frames = super::frame_cost::Frames::of(v, &built.model.boundary.triangles())?;
    let kept = v.modes();
    let p50 = frames.p50_us(v, kept, TIMED_FRAMES);
    if p50 <= target_us {
        return Ok(Ok(p50));
    }
    // the most modes within the target: the frame's cost grows with the modes
    let mut fit = None;
    for &(k, e) in built.report.error_curve.iter().rev().filter(|&&(k, _)| k < kept) {
        let t = frames.p50_us(v, k, TIMED_FRAMES);
        if t <= target_us {
            fit = Some((k, e, t));
            break;
        }
    }
    let r = &built.report;
    Ok(Err(match fit {
        Some((k, e, t)) => format!(
            "the {kept} modes that meet the error target {:.1e} take {p50:.1} µs per frame (p50), over --target-tick-us {target_us}; within it the most is {k} modes ({t:.1} µs) at error {e:.3e}: ask --target-error {e:.1e} for them",
            r.tolerance
        ),
        None => format!(
            "the {kept} modes that meet the error target {:.1e} take {p50:.1} µs per frame (p50), over --target-tick-us {target_us}, and no prefix the build measured fits within it",
            r.tolerance
        ),
    }))
}

/// Contacts timed on the cut organ by `--target-tick-us`.
const TIMED_CUT: usize = 20_000;

/// The cut's part of a tick on organ `i` of a cutting scene, as `--target-tick-us` times it.
struct CutTick {
    /// p50 of the compliance the scene's cut adds at a contact (µs).
    p50_us: f64,
    /// p50 of a null loop timed the same way (µs).
    null_us: f64,
    /// Nodes the scene's cut cracks.
    nodes: usize,
}

/// The cut's part of a tick (`CutView::added_compliance`, what a session adds to the
/// vademecum's compliance at every contact once the organ is cut) on the session's own cut
/// model ([`vademecum_engine::pipeline::cut_model`]: the settings and the sliver rule this build
/// chose, the contact table), cut along the scene's pre-planned cuts, at the centroids of the
/// surface triangles around the cracked nodes in turn; `None` on a scene that does not cut
/// (or whose cut leaves no free surface triangle).
fn cut_tick(scene: &Scene, built: &Built) -> Result<Option<CutTick>, String> {
    use vademecum_engine::xfem::accuracy::{crack_triangles, cut_cells};
    let Some(report) = &built.report.cut else { return Ok(None) };
    let model = &built.model;
    let (mut reduced, params) =
        vademecum_engine::pipeline::cut_model(scene, model, &built.vademecum, built.cut_basis.as_ref(), Some(report.sliver))
            .map_err(|e| e.to_string())?;
    reduced
        .cut(
            &model.mesh,
            &cut_cells(&scene.planned_cuts().map_err(|e| e.to_string())?, model, &params).map_err(|e| e.to_string())?,
        )
        .map_err(|e| e.to_string())?;
    let nodes = reduced.enrichment().len();
    let triangles = crack_triangles(model, reduced.enrichment());
    if triangles.is_empty() {
        return Ok(None);
    }
    let mut view = reduced.view();
    let third = 1.0 / 3.0;
    let mut k = 0usize;
    let times = super::bench_pgd::time_n(TIMED_CUT, || {
        k += 1;
        let c = view.added_compliance(&triangles[k % triangles.len()], &[third; 3]);
        c[0][0] + c[1][1] + c[2][2]
    });
    Ok(Some(CutTick {
        p50_us: super::bench_pgd::stat("cut", times).p50_us,
        null_us: super::bench_pgd::stat("null", super::bench_pgd::time_n(TIMED_CUT, || 0.0)).p50_us,
        nodes,
    }))
}

/// Tearing steps timed per grasp site by `--target-tick-us`.
const TIMED_TEAR_STEPS: usize = 1000;

/// The p50 (µs) of one tearing step of each grasp site of organ `i` — on the tick path while
/// the jaws hold, pulled along the diagonal of the load and the two directions across it so
/// that every pattern's modes are stepped — when all are within `target_us`; else why not:
/// the first site over it, and the time of the fewest modes `--target-error` keeps.
/// With the p50s, that of a null loop timed the same way (µs).
fn tear_within_tick(scene: &Scene, i: usize, built: &Built, target_us: f64) -> Result<(Vec<f64>, f64), String> {
    use vademecum_engine::damage::online::TearOffline;
    use vademecum_engine::damage::vademecum::AffineSystem;
    use vademecum_engine::scene::tearing;
    if built.tear.is_empty() {
        return Ok((Vec::new(), 0.0));
    }
    let model = tearing::tear_model(scene, i).map_err(|e| e.to_string())?.0;
    let (_, limits) = tearing::settings(scene);
    let variant = scene.spec.fidelity.tearing.variant;
    let p50 = |off: &Arc<TearOffline>| {
        let times = super::tear_timing::step_times(off, variant, limits, super::tear_timing::EVERY_DIRECTION, TIMED_TEAR_STEPS);
        if times.is_empty() {
            0.0
        } else {
            super::bench_pgd::stat("step", times).p50_us
        }
    };
    let null = super::bench_pgd::stat("null", super::bench_pgd::time_n(TIMED_TEAR_STEPS, || 0.0)).p50_us;
    let mut out = Vec::new();
    for ((site, report), arrays) in tear_builds(&built.report).zip(&built.tear) {
        let off = Arc::new(TearOffline::from_arrays(model.clone(), arrays.clone())?);
        let t = p50(&off);
        if t > target_us {
            let keep: Vec<usize> = off
                .vademecum
                .patterns
                .iter()
                .map(|&n| n.min(vademecum_engine::damage::build::FEWEST_TARGET_MODES))
                .collect();
            let q = p50(&Arc::new(off.pattern_prefix(&keep, &AffineSystem::of(&off.model, &off.basis))));
            return Err(format!(
                "tearing{site}: a step of the PGD modes {:?} takes {t:.2} µs (p50 on this machine, pulled in every direction; null loop {null:.2} µs), over --target-tick-us {target_us}; the fewest --target-error keeps, {keep:?}, take {q:.2} µs{}",
                off.vademecum.patterns,
                match report.target.as_ref().and_then(|t| t.tried.iter().find(|(m, _)| *m == keep)) {
                    // what a target tried of these modes: their force error, the target that keeps them
                    Some((_, e)) if q <= target_us && e.is_finite() => format!(
                        " at a force error of {}: --target-error {:.1e} keeps them",
                        percent(*e),
                        next_up(*e)
                    ),
                    _ if q <= target_us => ": a larger --target-error keeps fewer modes".into(),
                    _ => " — no setting of the tearing vademecum fits".into(),
                }
            ));
        }
        out.push(t);
    }
    Ok((out, null))
}

/// Where `run_from` takes each organ's modes from.
enum Source {
    /// Built here, by the method asked.
    Here(ModesMethod),
    /// Merged from the shards in the output folder (waiting up to `wait` s for them), removed
    /// afterwards unless `keep`.
    Shards { wait: f64, keep: bool },
}

pub fn run(a: BuildArgs) -> anyhow::Result<ExitCode> {
    if let Some(of) = a.shard {
        return run_shard(a, of);
    }
    let method = a.method;
    Ok(run_from(a, Source::Here(method))?.0)
}

/// `vademecum merge`: the bundles from the shards of a sharded build.
pub fn merge(m: MergeArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        m.wait >= 0.0 && m.wait.is_finite(),
        "--wait must be a number of seconds ≥ 0, got {}",
        m.wait
    );
    let publish_to = m.publish.clone();
    let a = BuildArgs {
        source: m.source,
        out: m.out,
        no_recompress: false,
        max_memory: m.max_memory,
        target_error: m.target_error,
        target_tick_us: None,
        json: m.json,
        method: ModesMethod::Snapshots,
        shard: None,
    };
    let (code, written) = run_from(
        a,
        Source::Shards {
            wait: m.wait,
            keep: m.keep_shards,
        },
    )?;
    if let Some(store) = publish_to.filter(|_| code == ExitCode::SUCCESS) {
        for (organ, digest) in super::publish::publish(&written, &store)? {
            println!("published {organ}: {digest} in {}", store.display());
        }
    }
    Ok(code)
}

/// Refuses a scene whose build does more than the linear vademecum: those parts do not shard.
fn shardable(scene: &Scene) -> anyhow::Result<()> {
    let e = &scene.spec.effects;
    let more: Vec<&str> = [
        (scene.any_large(), "large deformations"),
        (e.cutting, "cutting"),
        (e.tearing, "tearing"),
    ]
    .into_iter()
    .filter_map(|(on, what)| on.then_some(what))
    .collect();
    anyhow::ensure!(
        more.is_empty(),
        "scene '{}' also builds {} offline, which does not shard: build it in one process (`vademecum build` without --shard)",
        scene.spec.scene.name,
        more.join(", ")
    );
    Ok(())
}

/// `vademecum build --shard I/N`: the exact responses of shard I's load states of every organ.
fn run_shard(a: BuildArgs, of: ShardOf) -> anyhow::Result<ExitCode> {
    let scene = load_scene(&a.source)?;
    shardable(&scene)?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&scene.spec.scene.name));
    let opts = BuildOptions {
        max_memory: memory_limit(a.max_memory)?,
        ..BuildOptions::for_scene(&scene, true)
    };
    for i in 0..scene.spec.organs.len() {
        let name = scene.spec.organs[i].name.clone();
        let bar = Stages::start(&format!("shard {}/{} of '{name}'", of.index, of.count));
        let clock = std::time::Instant::now();
        let offline::ShardColumns {
            u,
            range,
            load_states: total,
            n_free,
        } = offline::solve_shard(&scene, i, &opts, of, &mut |s| match s {
            BuildStage::Assembly => bar.stage("assembling K"),
            BuildStage::Factorization => bar.stage("factoring K"),
            BuildStage::Exact(done, total) => bar.stage(&format!("exact responses, load state {done}/{total}")),
            _ => {}
        })
        .with_context(|| format!("cannot build organ '{name}'"))?;
        let info = ShardInfo {
            shard: of,
            start: range.start,
            end: range.end,
            load_states: total,
            n_free,
            load_radius: opts.load_radius,
        };
        bar.stage("writing the shard");
        let dir = shard::write_shard(&out, &scene, i, &info, &u).with_context(|| format!("cannot write the shard of '{name}'"))?;
        bar.finish();
        println!(
            "organ '{name}': shard {}/{}: load states {}..{} of {total} ({n_free} equations), {:.2} s -> {}",
            of.index,
            of.count,
            range.start,
            range.end,
            clock.elapsed().as_secs_f64(),
            dir.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The exact responses of organ `i` from the shards in `out`, waiting up to `wait` s for them.
fn merged_snapshots(scene: &Scene, i: usize, out: &Path, wait: f64) -> anyhow::Result<(Vec<f64>, Vec<PathBuf>)> {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs_f64(wait);
    let mut said = false;
    while !shard::all_present(out, scene, i) && std::time::Instant::now() < deadline {
        if !said {
            eprintln!(
                "waiting up to {wait} s for every shard of '{}' in {}",
                scene.spec.organs[i].name,
                out.display()
            );
            said = true;
        }
        std::thread::sleep(std::time::Duration::from_millis(500));
    }
    Ok(shard::read_shards(out, scene, i)?)
}

/// Builds (or merges) every organ's bundle: the exit code and the bundle folders written.
fn run_from(a: BuildArgs, source: Source) -> anyhow::Result<(ExitCode, Vec<PathBuf>)> {
    let scene = load_scene(&a.source)?;
    if matches!(source, Source::Shards { .. }) {
        shardable(&scene)?;
    }
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&scene.spec.scene.name));
    let mut opts = BuildOptions {
        max_memory: memory_limit(a.max_memory)?,
        ..BuildOptions::for_scene(&scene, !a.no_recompress)
    };
    if let Some(e) = a.target_error {
        anyhow::ensure!(e > 0.0 && e < 1.0, "--target-error must lie in (0, 1), got {e}");
        opts.tolerance = e;
        opts.tear_target_error = Some(e);
        opts.large_target_error = Some(e);
        opts.cut_target_error = Some(e);
    }
    if let Some(t) = a.target_tick_us {
        anyhow::ensure!(
            t > 0.0 && t.is_finite(),
            "--target-tick-us must be a positive number of µs, got {t}"
        );
    }
    let mut reports = Vec::new();
    let mut written = Vec::new();
    let mut stdout = std::io::stdout().lock();
    for i in 0..scene.spec.organs.len() {
        let name = scene.spec.organs[i].name.clone();
        let (merged, shards) = match &source {
            Source::Shards { wait, .. } => {
                let (u, dirs) = merged_snapshots(&scene, i, &out, *wait)?;
                (Some(u), dirs)
            }
            Source::Here(_) => (None, Vec::new()),
        };
        let from = match (&source, &merged) {
            (_, Some(u)) => ModesFrom::Given(u),
            (Source::Here(ModesMethod::Snapshots), None) => ModesFrom::Snapshots,
            _ => ModesFrom::Pgd,
        };
        let (built, bar) = build_from_with_progress(&scene, i, &opts, from)?;
        drop(merged);
        let r = &built.report;
        if let Some(e) = a.target_error
            && !r.target_met
        {
            bar.finish();
            eprintln!(
                "vademecum: organ '{name}': no prefix of the {} modes built meets --target-error {e:.1e}: the closest is {:.3e} with all of them; raise fidelity.pgd.max_modes or lower fidelity.pgd.global_tolerance (no bundle written)",
                r.greedy.modes, r.error_greedy
            );
            return Ok((ExitCode::FAILURE, written));
        }
        if let Some(why) = r.anm_target.as_ref().filter(|t| !t.met).map(lattice_target_missed) {
            bar.finish();
            eprintln!("vademecum: organ '{name}': {why} (no bundle written)");
            return Ok((ExitCode::FAILURE, written));
        }
        if let Some(why) = tear_target_missed(r) {
            bar.finish();
            eprintln!("vademecum: organ '{name}': {why} (no bundle written)");
            return Ok((ExitCode::FAILURE, written));
        }
        let (mut frame_p50, mut tear_p50, mut cut_p50) = (None, None, None);
        if let Some(t) = a.target_tick_us {
            bar.stage("timing the frames");
            let timed = within_tick(&built, t)?.map(|p50| frame_p50 = Some((p50, t)));
            if !built.tear.is_empty() && timed.is_ok() {
                bar.stage("timing the tearing step");
            }
            let timed = timed.and_then(|()| tear_within_tick(&scene, i, &built, t).map(|p| tear_p50 = Some(p)));
            if built.report.cut.is_some() && timed.is_ok() {
                bar.stage("timing the cut's compliance at the scene's cut");
            }
            let timed = timed.and_then(|()| {
                cut_p50 = cut_tick(&scene, &built)?;
                match &cut_p50 {
                    Some(c) if c.p50_us > t => Err(format!(
                        "cutting: the compliance the scene's cut ({} cracked nodes) adds at a contact takes {:.2} µs (p50 on this machine; null loop {:.2} µs), over --target-tick-us {t}; it has no cheaper setting than the contact table it is read from (a larger sliver rule, which --target-error picks, cracks fewer nodes)",
                        c.nodes, c.p50_us, c.null_us
                    )),
                    _ => Ok(()),
                }
            });
            if let Err(why) = timed {
                bar.finish();
                eprintln!("vademecum: organ '{name}': {why} (no bundle written)");
                return Ok((ExitCode::FAILURE, written));
            }
        }
        bar.stage("writing bundle");
        let dir = out.join(format!("{name}.bundle"));
        offline::write_bundle(&dir, &scene, &built).with_context(|| format!("cannot write bundle {}", dir.display()))?;
        written.push(dir.clone());
        bar.finish();
        if let Source::Shards { keep: false, .. } = source {
            for d in &shards {
                std::fs::remove_dir_all(d).with_context(|| format!("cannot remove the merged shard {}", d.display()))?;
            }
        }
        print_targets(&name, r, a.target_error, frame_p50, tear_p50.as_ref(), cut_p50.as_ref());
        if !a.json {
            print_report(&mut stdout, &built, &dir)?;
        }
        reports.push(built.report);
    }
    if a.json {
        writeln!(stdout, "{}", serde_json::to_string_pretty(&reports)?)?;
    }
    Ok((ExitCode::SUCCESS, written))
}

/// What `build` says on stderr of the targets each organ met: the modes, lattice, sliver rule
/// and tearing prefixes `--target-error` picked, and the per-tick costs `--target-tick-us`
/// timed (`frame_p50`: the frame's p50 and the target; `tear_p50`: each site's step and the
/// null loop).
fn print_targets(
    name: &str,
    r: &offline::BuildReport,
    target_error: Option<f64>,
    frame_p50: Option<(f64, f64)>,
    tear_p50: Option<&(Vec<f64>, f64)>,
    cut_p50: Option<&CutTick>,
) {
    if let Some(e) = target_error {
        eprintln!(
            "organ '{name}': picked {} modes, the fewest of the {} built whose measured error ({:.3e}) meets --target-error {e:.1e}",
            r.modes, r.greedy.modes, r.error
        );
        if let Some(t) = &r.anm_target {
            eprintln!("organ '{name}': large deformations: {}", lattice_target_line(t));
        }
        if let Some(c) = &r.cut {
            match &c.target {
                Some(t) => eprintln!("organ '{name}': cutting: {}", sliver_target_line(t)),
                None => eprintln!(
                    "organ '{name}': cutting: the bare enrichment's force is not held to --target-error (the study measures it against the full XFEM: docs/accuracy.md, \"Cutting\"); the local fields are exact"
                ),
            }
        }
        for (site, t) in tear_builds(r) {
            if let Some(line) = t.target.as_ref().map(tear_target_line) {
                eprintln!("organ '{name}': tearing{site}: {line}");
            }
        }
    }
    if let Some((p50, t)) = frame_p50 {
        eprintln!(
            "organ '{name}': its {} modes (error {:.3e}) take {p50:.1} µs per frame (p50 on this machine), within --target-tick-us {t}",
            r.modes, r.error
        );
        let (steps, null) = tear_p50.cloned().unwrap_or_default();
        for ((site, b), p50) in tear_builds(r).zip(&steps) {
            eprintln!(
                "organ '{name}': tearing{site}: a step of its PGD modes {:?} takes {p50:.2} µs (p50 on this machine, pulled in every direction; null loop {null:.2} µs), within --target-tick-us {t}",
                b.pattern_modes
            );
        }
        if let Some(c) = cut_p50 {
            eprintln!(
                "organ '{name}': cutting: the compliance the scene's cut ({} cracked nodes) adds at a contact takes {:.2} µs (p50 on this machine; null loop {:.2} µs), within --target-tick-us {t}",
                c.nodes, c.p50_us, c.null_us
            );
        }
    }
}

/// The build report of one organ as `build` prints it; `dir` is its bundle.
fn print_report(out: &mut impl Write, built: &Built, dir: &Path) -> std::io::Result<()> {
    let r = &built.report;
    writeln!(
        out,
        "organ '{}': {} nodes, {} equations, {} load states ({} accessible nodes)",
        r.organ, r.nodes, r.equations, r.load_states, r.load_nodes
    )?;
    writeln!(
        out,
        "  load footprint   radius {} m, {:.1} surface nodes per load on average",
        r.load_radius, r.mean_patch_nodes
    )?;
    if r.modes_from == "pgd" {
        writeln!(
            out,
            "  PGD              {} modes, {} solves with the one factorization, {:.2} s{}",
            r.greedy.modes,
            r.greedy.solves,
            r.pgd_s,
            if r.greedy.converged {
                ""
            } else {
                " (stopped by max_modes before reaching the tolerance)"
            }
        )?;
    } else {
        writeln!(
            out,
            "  {:<16} the exact response of each of the {} load states{}",
            r.modes_from,
            r.load_states,
            if r.modes_from == "snapshots" {
                format!(", one solve each with the one factorization, {:.2} s", r.pgd_s)
            } else {
                ", solved by the shards".into()
            }
        )?;
    }
    if r.recompressed {
        writeln!(out, "  recompressed     QR + SVD of the modes ({:.3} s)", r.recompress_s)?;
    }
    writeln!(
        out,
        "  exact pass       brute-force solves {:.2} s, with the {} exact local compliance blocks and the error measurement {:.2} s",
        r.brute_force_s, r.local_blocks, r.exact_pass_s
    )?;
    writeln!(
        out,
        "  error            {:.3e} relative L2 over all load states with {} modes (target {:.1e}; all {} {} modes: {:.3e})",
        r.error,
        r.modes,
        r.tolerance,
        r.greedy.modes,
        if r.modes_from == "pgd" { "greedy" } else { "snapshot" },
        r.error_greedy
    )?;
    if !r.target_met {
        writeln!(
            out,
            "  warning          the target was not reached: lower fidelity.pgd.global_tolerance or raise max_modes"
        )?;
    }
    writeln!(out, "  assembly/factor  {:.3} s / {:.3} s", r.assembly_s, r.factorization_s)?;
    if let Some(l) = &built.anm {
        let steps: usize = l.positions.iter().map(|p| p.path.steps.len()).sum();
        writeln!(
            out,
            "  large            ANM-POD lattice of {} positions to {} N (St Venant-Kirchhoff; {} series in all), {:.2} s",
            r.anm_positions, l.max_force, steps, r.anm_s
        )?;
    }
    if let Some(t) = &r.tear {
        writeln!(
            out,
            "  tearing          {} damage snapshots, {} POD vectors ({:.6} of the energy); PGD modes along/across the pull {:?}; vademecum error {:.2e} along, {:.2e} across; references {:.1} s, build {:.1} s",
            t.snapshots,
            t.pod_vectors,
            t.captured,
            t.pattern_modes,
            t.vademecum_error,
            t.cross_vademecum_error,
            t.reference_seconds,
            t.build_seconds
        )?;
        writeln!(out, "  force error      {}", force_error_line(t))?;
        if t.on_floor > 0 {
            writeln!(
                out,
                "  warning          the full-order reference ends with {} point(s) on the residual stiffness floor (fully damaged, carrying their share on a 1e-4 stiffness at a huge strain): {}",
                t.on_floor, t.on_floor_why
            )?;
        }
    }
    for (k, s) in r.tear_sites.iter().enumerate() {
        let t = &s.build;
        writeln!(
            out,
            "  grasp site {:<5} at {} m pulled along {}, {} nodes: {} POD vectors, PGD modes {:?}; vademecum error {:.2e} along, {:.2e} across; {:.1} s; force error {}",
            k + 2,
            super::vec3(s.centre_m, 4),
            super::vec3(s.pull_direction, 2),
            s.nodes,
            t.pod_vectors,
            t.pattern_modes,
            t.vademecum_error,
            t.cross_vademecum_error,
            t.reference_seconds + t.build_seconds + t.calibration_seconds,
            force_error_line(t)
        )?;
    }
    writeln!(
        out,
        "  size             {:.2} MB of modes (f32) vs {:.2} MB for the full parametric solution (f64)",
        r.modes_bytes as f64 / 1e6,
        r.full_bytes as f64 / 1e6
    )?;
    writeln!(out, "  bundle           {}", dir.display())?;
    Ok(())
}

/// Each tearing build of a report: the scene's grasp, then the other grasp sites, each with
/// how the messages name it.
fn tear_builds(r: &offline::BuildReport) -> impl Iterator<Item = (String, &TearBuildReport)> {
    let first = r.tear.iter().map(|t| (String::new(), t));
    let sites = r
        .tear_sites
        .iter()
        .enumerate()
        .map(|(k, s)| (format!(", grasp site {}", k + 2), &s.build));
    first.chain(sites)
}

/// Why the tearing modes miss `--target-error` (`None` when they meet it or no target was
/// set): the first grasp site that misses, its closest calibrated force error with every mode
/// the build made, and the least target every site meets.
fn tear_target_missed(r: &offline::BuildReport) -> Option<String> {
    let closest = |t: &TearTarget| t.tried.last().map_or(f64::NAN, |(_, e)| *e);
    let (site, target) = tear_builds(r).find_map(|(site, t)| Some((site, t.target.as_ref().filter(|g| !g.met)?)))?;
    let least = tear_builds(r)
        .filter_map(|(_, t)| t.target.as_ref().map(closest))
        .fold(0.0, f64::max);
    Some(format!(
        "tearing{site}: no prefix of the PGD modes {:?} (along the pull, then across it) meets --target-error {:.1e} on the grasper's force: the closest is {} with all of them — the rest is the POD basis's and the integrator's (docs/accuracy.md, \"Tearing\"); {}",
        target.built_modes,
        target.error,
        percent(closest(target)),
        if least.is_finite() {
            format!("every grasp site meets --target-error {:.1e}", next_up(least))
        } else {
            "a site's calibration failed: no target can be met".into()
        },
    ))
}

/// What `--target-error` kept of the sliver rule, for its message.
fn sliver_target_line(t: &SliverTarget) -> String {
    let tried: Vec<String> = t
        .tried
        .iter()
        .map(|(s, n, e)| format!("{s:.0e}: {n} nodes, {}", percent(*e)))
        .collect();
    let tried = if tried.is_empty() {
        "no larger threshold enriches fewer nodes on this cut".to_string()
    } else {
        format!("tried {}", tried.join("; "))
    };
    match t.tried.iter().find(|r| r.0 == t.sliver) {
        Some((s, n, e)) => format!(
            "kept the sliver rule {s:.0e} ({n} nodes enriched), the largest whose force at the cut's cracked surface nodes is within {} of the full XFEM's, meeting --target-error {:.1e} ({tried})",
            percent(*e),
            t.error
        ),
        None => format!(
            "kept the scene's sliver rule {:.0e}: its local fields are the full XFEM's at the cut (exact), and no larger threshold meets --target-error {:.1e} ({tried})",
            t.sliver, t.error
        ),
    }
}

/// The sizes a lattice target tried, for messages.
fn lattice_tried(t: &LatticeTarget) -> String {
    let tried: Vec<String> = t.tried.iter().map(|(n, e)| format!("{n}: {}", percent(*e))).collect();
    tried.join(", ")
}

/// Why no lattice met `--target-error`, for the refusal.
fn lattice_target_missed(t: &LatticeTarget) -> String {
    let least = t.tried.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
    format!(
        "large deformations: no lattice of up to {} positions (twice fidelity.large.positions) meets --target-error {:.1e}: the largest error of its force against full Newton at {} nodes off it, within its force, is {} (positions: error); {}",
        t.most,
        t.error,
        vademecum_engine::rom::lattice_check::LATTICE_CHECK_NODES,
        lattice_tried(t),
        if least.is_finite() {
            format!("--target-error {:.1e} is met", next_up(least))
        } else {
            "no state was checked".into()
        }
    )
}

/// What `--target-error` kept of a lattice, for its message.
fn lattice_target_line(t: &LatticeTarget) -> String {
    let (n, e) = t.tried.last().copied().unwrap_or((t.most, f64::NAN));
    format!(
        "kept {n} lattice positions, the fewest whose force is within {} of full Newton at {} nodes off the lattice (the largest error within its force) and meets --target-error {:.1e} (tried {})",
        percent(e),
        vademecum_engine::rom::lattice_check::LATTICE_CHECK_NODES,
        t.error,
        lattice_tried(t)
    )
}

/// A relative error as a percentage for messages ("not calibrated" for NaN).
fn percent(e: f64) -> String {
    if e.is_finite() {
        format!("{:.2} %", 100.0 * e)
    } else {
        "not calibrated".into()
    }
}

/// `e` rounded up to two significant digits: a target it meets, as the messages print it.
fn next_up(e: f64) -> f64 {
    let scale = 10f64.powi(e.log10().floor() as i32 - 1);
    (e / scale).ceil() * scale
}

/// What `--target-error` kept of a tearing build, for its message.
fn tear_target_line(t: &TearTarget) -> String {
    let (modes, e) = t.tried.last().map_or((&t.built_modes, f64::NAN), |(m, e)| (m, *e));
    let tried: Vec<String> = t.tried.iter().map(|(m, e)| format!("{m:?}: {}", percent(*e))).collect();
    format!(
        "kept the PGD modes {modes:?} of the {:?} built, the fewest whose calibrated force error ({}) meets --target-error {:.1e} (tried {})",
        t.built_modes,
        percent(e),
        t.error,
        tried.join(", ")
    )
}

/// What a grasp site's force error calibration found, for the build's report.
fn force_error_line(t: &TearBuildReport) -> String {
    if t.force_error.is_finite() {
        format!(
            "calibrated: within {:.2} % of the full-order force at the schedule's last load, pulled along, across or diagonally ({:.1} s); {}",
            100.0 * t.force_error,
            t.calibration_seconds,
            match &t.fallback {
                Some((modes, e)) => format!("under load a session falls back to the modes {modes:?} ({})", percent(*e)),
                None => "no fewer modes to fall back to under load".into(),
            }
        )
    } else {
        "not calibrated (a full-order pull across the load failed): the grasper's forces carry no error estimate".into()
    }
}
