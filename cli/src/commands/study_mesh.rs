//! The study's sweep of the mesh itself: the scene's first organ at coarser and finer
//! discretisations, each with its own PGD vademecum, against the finest.
//!
//! Levels: a procedural mesh (`builtin`) at its `divisions` times each factor of
//! `--refinements` (default ½, 1, 1.5; rounded, at least 1), or a mesh file and the files given
//! with `--mesh-file` (ordered by their cell count). Each level is built as a palpation scene
//! (linear, no cutting or tearing: the mesh's own cost, not the effects', which have their own
//! sweeps) at the scene's PGD settings.
//!
//! What a session serves on each level is compared with the finest level's:
//!
//! - **the contact force** at fixed points of the accessible surface (up to [`PROBES`]
//!   loadable nodes of the scene's own mesh inside the loadable region, drawn uniformly with a
//!   fixed seed): the force
//!   `K(s) δ` for a 1 mm indentation along the surface normal, with `K(s)` the probe's contact
//!   stiffness (`Vademecum::contact_stiffness`, the tip's law: the exact nodal stiffnesses
//!   interpolated) at the nearest point `s` of that level's surface (the tool's footprint
//!   of `probe_radius` spreads the load, so it can converge once cells are smaller than the
//!   footprint; a point load's cannot);
//! - **the strain energy** under the scene's static loads (the full-order linear solve), when it
//!   has loads.
//!
//! With three levels or more, the generalised Richardson extrapolation of Celik et al. (2008,
//! "Procedure for estimation and reporting of uncertainty due to discretization in CFD
//! applications") on the three finest gives the observed order of convergence and an estimate
//! of the finest level's own error. Cost: the build's wall time, the bundle's bytes, modes,
//! and a frame's surface field (p50, p99 beside a null loop). Kept in `mesh.json`, resumed as
//! a whole.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};
use vademecum_engine::bundle;
use vademecum_engine::contact::Surface;
use vademecum_engine::fem::linear_static;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pgd::{Footprint, Vademecum};
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::schema::DeformationModel;

use super::frame_cost::Frames;
use super::study_report::{Group, rel, scatter};

/// Points of the accessible surface where the contact force is compared.
const PROBES: usize = 16;
/// Frames timed per level.
const FRAMES: usize = 1000;
/// Indentation of the compared contact force (m).
const INDENTATION: f64 = 1e-3;

/// One discretisation of the organ, measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct MeshLevel {
    /// `divisions` (procedural) or the mesh file.
    pub(super) mesh: String,
    /// Why the level could not be built or measured (it is then left out of the comparison).
    #[serde(default)]
    pub(super) failure: Option<String>,
    pub(super) nodes: usize,
    pub(super) cells: usize,
    /// A typical cell size: the mean length of the edges at a node, over the nodes (m; NaN
    /// for a failed level).
    #[serde(deserialize_with = "super::study_report::nan_if_null")]
    pub(super) cell_size: f64,
    pub(super) modes: usize,
    pub(super) build_s: f64,
    pub(super) bundle_bytes: u64,
    /// A frame's surface field at all the level's modes (µs p50, p99, and a null loop's p50
    /// in the same run; `None` when the level has no fully loadable surface triangle to make
    /// frames from).
    pub(super) frame_p50_us: Option<f64>,
    #[serde(default)]
    pub(super) frame_p99_us: Option<f64>,
    #[serde(default)]
    pub(super) null_p50_us: Option<f64>,
    /// The normal contact force at each probe (N; `None` where the probe is not loadable).
    pub(super) forces: Vec<Option<f64>>,
    /// The strain energy under the scene's static loads (J), when it has loads.
    pub(super) energy_j: Option<f64>,
    /// Against the finest level: the median and the largest relative difference of the probes'
    /// forces, and of the energy (filled when the sweep ends).
    #[serde(default)]
    pub(super) force_error_median: Option<f64>,
    #[serde(default)]
    pub(super) force_error_max: Option<f64>,
    #[serde(default)]
    pub(super) energy_error: Option<f64>,
    #[serde(default)]
    pub(super) front: bool,
}

impl MeshLevel {
    fn failed(mesh: String, why: String) -> Self {
        Self {
            mesh,
            failure: Some(why),
            nodes: 0,
            cells: 0,
            cell_size: f64::NAN,
            modes: 0,
            build_s: 0.0,
            bundle_bytes: 0,
            frame_p50_us: None,
            frame_p99_us: None,
            null_p50_us: None,
            forces: Vec::new(),
            energy_j: None,
            force_error_median: None,
            force_error_max: None,
            energy_error: None,
            front: false,
        }
    }
}

/// Richardson's estimate on the three finest levels for one quantity.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub(super) struct Extrapolation {
    /// Observed order of convergence in the cell size.
    pub(super) order: f64,
    /// The extrapolated value, and the finest level's relative distance from it.
    pub(super) value: f64,
    pub(super) finest_error: f64,
}

/// What the sweep found (`mesh.json`).
#[derive(Debug, Serialize, Deserialize)]
pub(super) struct MeshSweep {
    key: String,
    pub(super) organ: String,
    /// The scene's own level (index into `levels`).
    pub(super) scene_level: usize,
    pub(super) probe_radius: f64,
    /// The probes (m), on the scene's own mesh.
    pub(super) probes: Vec<[f64; 3]>,
    pub(super) levels: Vec<MeshLevel>,
    /// Of the median probe's force and of the energy (three levels or more, monotone).
    pub(super) force_extrapolation: Option<Extrapolation>,
    pub(super) energy_extrapolation: Option<Extrapolation>,
}

/// What the levels are made of: the scene itself with its first organ's mesh replaced.
#[derive(Debug, Clone)]
struct Level {
    label: String,
    scene: Scene,
}

/// The divisions of a procedural mesh scaled by `f` (rounded, at least 1).
fn scaled(d: [usize; 3], f: f64) -> [usize; 3] {
    d.map(|n| ((n as f64 * f).round() as usize).max(1))
}

/// The palpation scene of `scene` (its effects off but deformation, linear): what a level
/// builds.
fn palpation(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    s.spec.effects.deformation = DeformationModel::Linear;
    for o in &mut s.spec.organs {
        o.deformation = None;
    }
    s.spec.effects.cutting = false;
    s.spec.effects.tearing = false;
    s
}

/// The levels of the sweep (see the [module docs](self)), coarse to fine, and which is the
/// scene's own; `None` when there is only one.
fn levels(scene: &Scene, factors: &[f64], files: &[PathBuf]) -> anyhow::Result<Option<(Vec<Level>, usize)>> {
    let base = palpation(scene);
    let m = &scene.spec.organs[0].mesh;
    let mut out: Vec<(usize, Level)> = Vec::new();
    if let Some(d) = m.effective_divisions() {
        let mut seen = Vec::new();
        for &f in factors {
            let div = scaled(d, f);
            if seen.contains(&div) {
                continue;
            }
            seen.push(div);
            let mut s = base.clone();
            s.spec.organs[0].mesh.divisions = Some(div);
            let cells = s.organ_mesh(0)?.n_cells();
            out.push((
                cells,
                Level {
                    label: format!("divisions {div:?}"),
                    scene: s,
                },
            ));
        }
    } else {
        out.push((
            base.organ_mesh(0)?.n_cells(),
            Level {
                label: m.file.clone().unwrap_or_default(),
                scene: base.clone(),
            },
        ));
        for f in files {
            let mut s = base.clone();
            s.spec.organs[0].mesh.file = Some(std::path::absolute(f)?.display().to_string());
            let cells = s.organ_mesh(0).with_context(|| format!("--mesh-file {}", f.display()))?.n_cells();
            out.push((
                cells,
                Level {
                    label: f.display().to_string(),
                    scene: s,
                },
            ));
        }
    }
    if out.len() < 2 {
        return Ok(None);
    }
    let own_cells = base.organ_mesh(0)?.n_cells();
    out.sort_by_key(|(c, _)| *c);
    let own = out.iter().position(|(c, _)| *c == own_cells).unwrap_or(0);
    Ok(Some((out.into_iter().map(|(_, l)| l).collect(), own)))
}

/// Up to `n` loadable nodes of `v` spread over the surface `tris`, as points: nodes inside the
/// loadable region (every surface triangle at them loadable), so that the nearest surface point
/// of another level of the mesh is loadable too.
fn probes(v: &Vademecum, nodes: &[[f64; 3]], tris: &[[usize; 3]], n: usize) -> Vec<[f64; 3]> {
    let mut inside = vec![true; nodes.len()];
    for t in tris {
        if !t.iter().all(|&a| v.is_loadable(a)) {
            t.iter().for_each(|&a| inside[a] = false);
        }
    }
    let cand: Vec<[f64; 3]> = v.load_nodes().iter().filter(|&&i| inside[i]).map(|&i| nodes[i]).collect();
    sample(&cand, n)
}

/// Up to `n` distinct points of `cand` drawn uniformly (a partial Fisher–Yates shuffle with a
/// fixed seed: the same probes on every run). Uniform, not spread to the extremes: farthest-point
/// sampling picks the region's rim, next to the supports, where the mesh matters most, and would
/// make the sweep speak for the rim alone.
fn sample(cand: &[[f64; 3]], n: usize) -> Vec<[f64; 3]> {
    let mut pool = cand.to_vec();
    let mut rng = vademecum_engine::rng::Rng(0x9E37_79B9_7F4A_7C15);
    let n = n.min(pool.len());
    for i in 0..n {
        let j = i + (rng.next_u64() % (pool.len() - i) as u64) as usize;
        pool.swap(i, j);
    }
    pool.truncate(n);
    pool
}

/// The normal contact force for a 1 mm indentation at the surface point nearest each probe
/// (`None` where that point is not loadable).
fn probe_forces(v: &Vademecum, nodes: &[[f64; 3]], tris: &[[usize; 3]], probes: &[[f64; 3]]) -> Vec<Option<f64>> {
    let surface = Surface::new(nodes, tris.to_vec());
    probes
        .iter()
        .map(|&p| {
            let s = surface.nearest(p)?;
            let n = surface.normal_at(&s);
            let c = v.contact_compliance(surface.triangles()[s.triangle], s.weights, Footprint::Tip)?;
            let f = Vademecum::contact_force(&c, n.map(|x| -INDENTATION * x));
            Some(-(0..3).map(|k| f[k] * n[k]).sum::<f64>())
        })
        .collect()
}

/// The median of the finite values of `v` (`NaN` when none).
fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Celik et al. (2008)'s generalised Richardson extrapolation of `q` on three levels of cell
/// sizes `h` (coarse to fine, `h[0] > h[1] > h[2]`): the observed order `p` solves
/// `p = (ln|ε₃₂/ε₂₁| + ln((r₂₁ᵖ − s)/(r₃₂ᵖ − s))) / ln r₂₁` (fixed-point iterations), with
/// `ε₂₁ = q_fine − q_mid`, `ε₃₂ = q_mid − q_coarse`, `r` the size ratios and `s` the sign of
/// `ε₃₂/ε₂₁`; then `q_ext = (r₂₁ᵖ q_fine − q_mid)/(r₂₁ᵖ − 1)`. `None` when the differences
/// vanish, change sign or grow with refinement (no monotone convergence to extrapolate: the
/// order is taken without Celik's absolute value, and must stay positive), or `p` is not
/// finite.
fn extrapolate(h: [f64; 3], q: [f64; 3]) -> Option<Extrapolation> {
    let (r21, r32) = (h[1] / h[2], h[0] / h[1]);
    let (e21, e32) = (q[2] - q[1], q[1] - q[0]);
    if !(r21 > 1.0 && r32 > 1.0) || e21 == 0.0 || e32 == 0.0 || !q.iter().all(|x| x.is_finite()) {
        return None;
    }
    let s = (e32 / e21).signum();
    if s < 0.0 {
        return None;
    }
    let mut p = ((e32 / e21).abs().ln() / r21.ln()).max(0.1);
    for _ in 0..100 {
        let qp = ((r21.powf(p) - s) / (r32.powf(p) - s)).ln();
        // Celik et al. take the absolute value; a non-positive order is a difference that
        // grows as the mesh refines, which has no limit to extrapolate to
        let next = ((e32 / e21).abs().ln() + qp) / r21.ln();
        if !(next.is_finite() && next > 0.0) {
            return None;
        }
        if (next - p).abs() < 1e-10 * next.max(1.0) {
            p = next;
            break;
        }
        p = next;
    }
    let rp = r21.powf(p);
    let value = (rp * q[2] - q[1]) / (rp - 1.0);
    (p.is_finite() && p > 0.0 && value.is_finite()).then(|| Extrapolation {
        order: p,
        value,
        finest_error: rel(q[2], value),
    })
}

/// Sweeps the mesh (see the [module docs](self)); writes `mesh.csv`, `mesh_error_vs_cost.svg`
/// and `mesh_error_vs_frame.svg` to `out`. `None` when there is a single level.
pub(super) fn sweep(scene: &Scene, key: &str, factors: &[f64], files: &[PathBuf], out: &Path) -> anyhow::Result<Option<MeshSweep>> {
    let key = format!("{key} {factors:?} {files:?}");
    let record_path = out.join("mesh.json");
    if let Ok(old) = std::fs::read_to_string(&record_path)
        && let Ok(rec) = serde_json::from_str::<MeshSweep>(&old)
        && rec.key == key
    {
        eprintln!("resuming: the mesh sweep in {} is reused", record_path.display());
        write_outputs(&rec, &scene.spec.scene.name, out)?;
        return Ok(Some(rec));
    }
    let Some((levels, own)) = levels(scene, factors, files)? else {
        return Ok(None);
    };
    let bar = ProgressBar::new_spinner();
    bar.set_style(ProgressStyle::with_template("{spinner} {msg} [{elapsed}]").unwrap_or_else(|_| ProgressStyle::default_spinner()));
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let tmp = out.join("mesh_bundle");
    let mut measured = Vec::new();
    let mut probe_points = Vec::new();
    let probe_radius = BuildOptions::for_scene(scene, true).load_radius;
    // the scene's own level first: it places the probes
    let order: Vec<usize> = std::iter::once(own).chain((0..levels.len()).filter(|&i| i != own)).collect();
    for (n, &i) in order.iter().enumerate() {
        let l = &levels[i];
        let what = format!("mesh sweep {}/{}: {}", n + 1, levels.len(), l.label);
        let level = measure(l, &mut probe_points, &tmp, |stage| bar.set_message(format!("{what}: {stage}")))
            .unwrap_or_else(|e| MeshLevel::failed(l.label.clone(), format!("{e:#}")));
        let _ = std::fs::remove_dir_all(&tmp);
        measured.push((i, level));
    }
    bar.finish_and_clear();
    measured.sort_by_key(|(i, _)| *i);
    let levels: Vec<MeshLevel> = measured.into_iter().map(|(_, l)| l).collect();
    let mut rec = MeshSweep {
        key,
        organ: scene.spec.organs[0].name.clone(),
        scene_level: own,
        probe_radius,
        probes: probe_points,
        levels,
        force_extrapolation: None,
        energy_extrapolation: None,
    };
    finish(&mut rec);
    std::fs::write(&record_path, serde_json::to_string_pretty(&rec)?)?;
    write_outputs(&rec, &scene.spec.scene.name, out)?;
    Ok(Some(rec))
}

/// Builds and measures one level; the first call (the scene's own level) places the probes.
fn measure(l: &Level, probe_points: &mut Vec<[f64; 3]>, tmp: &Path, stage: impl Fn(&str)) -> anyhow::Result<MeshLevel> {
    stage("building");
    // a level too large for this machine fails with the build's memory diagnostic, not the OOM killer
    let opts = BuildOptions {
        max_memory: super::scene_input::memory_limit(None)?,
        ..BuildOptions::for_scene(&l.scene, true)
    };
    let t = Instant::now();
    let built = offline::build_organ(&l.scene, 0, &opts, &mut |_| {}).context("the build failed")?;
    let build_s = t.elapsed().as_secs_f64();
    offline::write_bundle(tmp, &l.scene, &built).with_context(|| format!("cannot write {}", tmp.display()))?;
    let bundle_bytes = super::bench_effects::dir_bytes(tmp)?;
    let b = bundle::load_bundle(tmp)?;
    if probe_points.is_empty() {
        *probe_points = probes(&b.vademecum, &b.nodes, &b.surface, PROBES);
    }
    stage("measuring");
    let timing = Frames::of(&b.vademecum, &b.surface)
        .ok()
        .map(|f| f.timing(&b.vademecum, b.vademecum.modes(), FRAMES));
    let model = &built.model;
    let p = &model.problem;
    let energy_j = if p.forces.iter().any(|&f| f != 0.0) || p.prescribed.iter().any(|&u| u != 0.0) || !p.pressures.is_empty() {
        let sol = linear_static::solve(&model.mesh, &model.materials, model.locking, &model.problem, &mut |_| {})
            .context("the static solve failed")?;
        Some(sol.strain_energy)
    } else {
        None
    };
    let edges = vademecum_engine::meshless::organ::node_radii(&model.mesh, 1.0);
    Ok(MeshLevel {
        mesh: l.label.clone(),
        failure: None,
        nodes: model.mesh.n_nodes(),
        cells: model.mesh.n_cells(),
        cell_size: edges.iter().sum::<f64>() / edges.len().max(1) as f64,
        modes: built.report.modes,
        build_s,
        bundle_bytes,
        frame_p50_us: timing.map(|t| t.0),
        frame_p99_us: timing.map(|t| t.1),
        null_p50_us: timing.map(|t| t.2),
        forces: probe_forces(&b.vademecum, &b.nodes, &b.surface, probe_points),
        energy_j,
        force_error_median: None,
        force_error_max: None,
        energy_error: None,
        front: false,
    })
}

/// Fills each measured level's difference from the finest measured one, the front (build
/// time against the force's median difference), and the extrapolations on the three finest.
fn finish(rec: &mut MeshSweep) {
    let ok: Vec<usize> = (0..rec.levels.len()).filter(|&i| rec.levels[i].failure.is_none()).collect();
    let Some(&last) = ok.last() else { return };
    let finest = rec.levels[last].clone();
    // probes unloadable on some level are left out everywhere
    let force = |l: &MeshLevel, k: usize| l.forces.get(k).copied().flatten();
    let usable: Vec<usize> = (0..rec.probes.len())
        .filter(|&k| ok.iter().all(|&i| force(&rec.levels[i], k).is_some()))
        .collect();
    for &i in &ok {
        let l = &mut rec.levels[i];
        let e: Vec<f64> = usable.iter().filter_map(|&k| Some(rel(force(l, k)?, force(&finest, k)?))).collect();
        l.force_error_median = (!e.is_empty()).then(|| median(e.clone()));
        l.force_error_max = e.iter().copied().reduce(f64::max);
        l.energy_error = l.energy_j.zip(finest.energy_j).map(|(a, b)| rel(a, b));
    }
    let coarser = &ok[..ok.len() - 1];
    let cost: Vec<(f64, f64)> = coarser
        .iter()
        .map(|&i| (rec.levels[i].build_s, rec.levels[i].force_error_median.unwrap_or(f64::INFINITY)))
        .collect();
    for (&i, f) in coarser.iter().zip(super::study_report::pareto(&cost)) {
        rec.levels[i].front = f;
    }
    if let [.., a, b, c] = ok[..] {
        let t = [&rec.levels[a], &rec.levels[b], &rec.levels[c]];
        let h = t.map(|l| l.cell_size);
        let med = |l: &MeshLevel| median(usable.iter().filter_map(|&k| force(l, k)).collect());
        rec.force_extrapolation = extrapolate(h, t.map(med));
        rec.energy_extrapolation = match t.map(|l| l.energy_j) {
            [Some(a), Some(b), Some(c)] => extrapolate(h, [a, b, c]),
            _ => None,
        };
    }
}

/// Writes mesh.csv, mesh_error_vs_cost.svg and mesh_error_vs_frame.svg (also when the sweep
/// is resumed).
fn write_outputs(s: &MeshSweep, scene: &str, out: &Path) -> anyhow::Result<()> {
    let opt = |v: Option<f64>, precision: usize| v.map_or(String::new(), |v| format!("{v:.precision$e}"));
    let us = |v: Option<f64>| v.map_or(String::new(), |t| format!("{t:.3}"));
    let mut csv = String::from(
        "mesh,nodes,cells,cell_size_m,modes,build_s,bundle_bytes,frame_p50_us,frame_p99_us,null_p50_us,force_error_median,force_error_max,energy_j,energy_error,scene,front,failure\n",
    );
    for (i, l) in s.levels.iter().enumerate() {
        csv += &format!(
            "\"{}\",{},{},{:e},{},{:.3},{},{},{},{},{},{},{},{},{},{},\"{}\"\n",
            l.mesh,
            l.nodes,
            l.cells,
            l.cell_size,
            l.modes,
            l.build_s,
            l.bundle_bytes,
            us(l.frame_p50_us),
            us(l.frame_p99_us),
            us(l.null_p50_us),
            opt(l.force_error_median, 6),
            opt(l.force_error_max, 6),
            opt(l.energy_j, 9),
            opt(l.energy_error, 6),
            i == s.scene_level,
            l.front,
            l.failure.as_deref().unwrap_or("").replace('"', "'")
        );
    }
    std::fs::write(out.join("mesh.csv"), csv).context("cannot write mesh.csv")?;
    // every measured level but the finest, its distance from which is zero
    let finest = s.levels.iter().rposition(|l| l.failure.is_none());
    let coarser: Vec<&MeshLevel> = s
        .levels
        .iter()
        .enumerate()
        .filter(|(i, l)| l.failure.is_none() && Some(*i) != finest)
        .map(|(_, l)| l)
        .collect();
    let plot = |cost: fn(&MeshLevel) -> Option<f64>, (file, against, x_desc): (&str, &str, &str)| {
        let group = |label: &str, err: fn(&MeshLevel) -> Option<f64>, triangles: bool| Group {
            label: label.into(),
            triangles,
            points: coarser
                .iter()
                .map(|l| {
                    (
                        cost(l).unwrap_or(f64::NAN),
                        err(l).unwrap_or(f64::NAN),
                        format!("{} nodes", l.nodes),
                    )
                })
                .collect(),
        };
        let groups = [
            group("contact force at the probes (median)", |l| l.force_error_median, false),
            group("strain energy under the scene's loads", |l| l.energy_error, true),
        ];
        let costs: Vec<(f64, f64)> = coarser
            .iter()
            .map(|l| (cost(l).unwrap_or(f64::INFINITY), l.force_error_median.unwrap_or(f64::INFINITY)))
            .collect();
        let front = coarser
            .iter()
            .zip(super::study_report::pareto(&costs))
            .filter(|(_, f)| *f)
            .filter_map(|(l, _)| Some((cost(l)?, l.force_error_median?)))
            .collect();
        scatter(
            &out.join(file),
            &format!("{scene} '{}': the mesh, difference from the finest against {against}", s.organ),
            (x_desc, "relative difference from the finest level"),
            &groups,
            front,
        )
    };
    plot(
        |l| Some(l.build_s),
        ("mesh_error_vs_cost.svg", "the build", "build of the level's vademecum (s)"),
    )?;
    plot(
        |l| l.frame_p50_us,
        (
            "mesh_error_vs_frame.svg",
            "a frame",
            "surface field of one frame at all modes, p50 (µs)",
        ),
    )
}

/// The sentence of the verdict: each level's distance from the finest, the extrapolated error
/// of the finest, the cost.
pub(super) fn verdict(s: &MeshSweep) -> String {
    let levels: Vec<String> = s
        .levels
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let own = if i == s.scene_level { ", the scene's" } else { "" };
            if let Some(why) = &l.failure {
                return format!("{}{own}: not measured ({why})", l.mesh);
            }
            format!(
                "{}{own} ({} nodes, {} modes, build {:.1} s, {:.1} MB, frame {}): force {}{}",
                l.mesh,
                l.nodes,
                l.modes,
                l.build_s,
                l.bundle_bytes as f64 / 1e6,
                l.frame_p50_us.map_or("not timed".into(), |t| format!("{t:.1} µs")),
                l.force_error_median.map_or("not compared".into(), |e| format!("{e:.1e} median")),
                l.energy_error.map_or(String::new(), |e| format!(", energy {e:.1e}"))
            )
        })
        .collect();
    let ext = |what: &str, e: &Option<Extrapolation>| {
        e.map_or(String::new(), |e| {
            format!(
                " Richardson on the three finest: the {what} converges at order {:.2}, the finest level within {:.1e} of its limit.",
                e.order, e.finest_error
            )
        })
    };
    let footprint = if s.probe_radius > 0.0 {
        format!("the tool's footprint {:.1} mm", s.probe_radius * 1e3)
    } else {
        "point loads: the scene has no probe, and a point load's force has no mesh-converged limit".into()
    };
    format!(
        "Mesh (difference from the finest level; the contact force at {} probes, {footprint}) — {}.{}{}",
        s.probes.len(),
        levels.join("; "),
        ext("contact force", &s.force_extrapolation),
        ext("strain energy", &s.energy_extrapolation)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn divisions_scale_round_and_stay_positive() {
        assert_eq!(scaled([16, 10, 6], 0.5), [8, 5, 3]);
        assert_eq!(scaled([16, 10, 6], 1.5), [24, 15, 9]);
        assert_eq!(scaled([1, 1, 3], 0.25), [1, 1, 1]);
    }

    #[test]
    fn richardson_recovers_the_order_and_limit_of_a_power_law() {
        // q(h) = 2 + 0.3 h^1.7 on unevenly refined levels
        let h = [0.4, 0.2, 0.13];
        let q = h.map(|h: f64| 2.0 + 0.3 * h.powf(1.7));
        let e = extrapolate(h, q).unwrap();
        assert!((e.order - 1.7).abs() < 1e-6, "{e:?}");
        assert!((e.value - 2.0).abs() < 1e-9, "{e:?}");
        assert!((e.finest_error - 0.3 * 0.13f64.powf(1.7) / 2.0).abs() < 1e-9);
        // oscillating or stalled differences are not extrapolated
        assert_eq!(extrapolate(h, [1.0, 2.0, 1.5]), None);
        assert_eq!(extrapolate(h, [1.0, 1.0, 1.0]), None);
    }

    fn level(h: f64, forces: [Option<f64>; 2], energy: f64, build_s: f64) -> MeshLevel {
        MeshLevel {
            failure: None,
            cell_size: h,
            build_s,
            forces: forces.to_vec(),
            energy_j: Some(energy),
            ..MeshLevel::failed(format!("h {h}"), String::new())
        }
    }

    #[test]
    fn failed_levels_and_unloadable_probes_are_left_out_and_the_finest_measured_is_the_reference() {
        let mut rec = MeshSweep {
            key: String::new(),
            organ: "o".into(),
            scene_level: 1,
            probe_radius: 1e-3,
            probes: vec![[0.0; 3]; 2],
            levels: vec![
                level(0.4, [Some(1.0), None], 2.0 + 0.3 * 0.4f64.powf(1.7), 1.0),
                level(0.2, [Some(2.0), Some(5.0)], 2.0 + 0.3 * 0.2f64.powf(1.7), 2.0),
                level(0.13, [Some(4.0), Some(5.0)], 2.0 + 0.3 * 0.13f64.powf(1.7), 8.0),
                MeshLevel::failed("finer".into(), "out of memory".into()),
            ],
            force_extrapolation: None,
            energy_extrapolation: None,
        };
        finish(&mut rec);
        // the second probe is not loadable on the coarsest level: only the first is compared
        assert_eq!(rec.levels[0].force_error_median, Some(0.75));
        assert_eq!(rec.levels[1].force_error_median, Some(0.5));
        assert_eq!(rec.levels[2].force_error_median, Some(0.0));
        assert_eq!(rec.levels[3].force_error_median, None);
        assert_eq!(rec.levels.iter().map(|l| l.front).collect::<Vec<_>>(), [true, true, false, false]);
        let e = rec.energy_extrapolation.unwrap();
        assert!((e.order - 1.7).abs() < 1e-6 && (e.value - 2.0).abs() < 1e-9, "{e:?}");
        // the forces 1, 2, 4 do not converge: their differences grow
        assert_eq!(rec.force_extrapolation, None);
        assert!(verdict(&rec).contains("finer: not measured (out of memory)"), "{}", verdict(&rec));
        // the record, failed level and all, survives its round trip through mesh.json
        let back: MeshSweep = serde_json::from_str(&serde_json::to_string(&rec).unwrap()).unwrap();
        assert!(back.levels[3].cell_size.is_nan() && back.levels[3].failure.is_some());
    }

    #[test]
    fn probes_are_distinct_candidates_the_same_on_every_run() {
        let pts: Vec<[f64; 3]> = (0..50).map(|i| [i as f64, 0.0, 0.0]).collect();
        let a = sample(&pts, 16);
        assert_eq!(a, sample(&pts, 16));
        let mut x: Vec<f64> = a.iter().map(|p| p[0]).collect();
        x.sort_by(f64::total_cmp);
        x.dedup();
        assert_eq!(x.len(), 16, "distinct");
        // spread over the candidates, not bunched at one end
        assert!(x[0] < 15.0 && x[15] > 35.0, "{x:?}");
        assert_eq!(sample(&pts[..3], 16).len(), 3);
        assert!(sample(&[], 3).is_empty());
    }
}
