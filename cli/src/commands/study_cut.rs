//! The study's sweep of cutting (scenes with `effects.cutting = true`; seed 000 §3.2–3.3): the
//! scene's pre-planned cuts (or, without any, the organ's cells crossed by a plane through its
//! centre) made at once, then for each setting of the reduced cut model the contact force a
//! session serves against the full-order XFEM's on the same mesh and cut.
//!
//! A session's force on the cut organ is `(C(s) + ΔC)⁻¹ δ`: the vademecum's exact local
//! compliance `C(s)` (the uncut organ's; no mode enters it) plus what the cut adds at the
//! contact, `ΔC` ([`CutView::added_compliance`]). The settings that change `ΔC`:
//! - what carries the discontinuous part (`fidelity.xfem.discontinuous`): the local fields
//!   (the default; exact up to round-off, no mode enters them) or the bare enrichment on a
//!   Ritz basis of the vademecum's first modes (`fidelity.xfem.basis`, SRB or PRB) — swept at
//!   10, 40 and 160 modes;
//! - the sliver rule (`fidelity.xfem.sliver`): the scene's, 10⁻³, 10⁻² and 5·10⁻², fewer nodes
//!   enriched each, a cheaper cut and tick against the opening near the cut's edges.
//!
//! Per point: the relative error of the force for a unit imposed displacement along each axis
//! at cracked surface nodes (median and largest), the enriched nodes, the cut's part of the
//! tick (`ΔC` at a two-node patch from the contact table a session keeps, p50 and p99 beside a
//! null loop), the cut thread's work for the whole cut (cracking the nodes, bordering the
//! factor, extending the contact table), the model's preparation when the session starts and
//! its bytes. Kept in `cut.json` for the study's build.
//!
//! [`CutView::added_compliance`]: vademecum_engine::xfem::reduced::CutView::added_compliance

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};
use vademecum_engine::fem::OrganModel;
use vademecum_engine::pgd::Vademecum;
use vademecum_engine::pipeline::palpation::LINEAR_RELATIVE_ERROR;
use vademecum_engine::scene::Scene;
use vademecum_engine::xfem::accuracy::{CONTACTS, Reference, cut_cells};
use vademecum_engine::xfem::reduced::{Discontinuous, ReducedCut, RitzBasis};
use vademecum_engine::xfem::{Enrichment, Plane, XfemParams};

use super::bench_pgd::{stat, time_n};
use super::study_report::{Group, scatter};

/// Sliver thresholds swept beside the scene's.
const SLIVERS: [f64; 3] = [1e-3, 1e-2, 5e-2];

/// Mode counts of the bare enrichment's Ritz basis.
const BARE_MODES: [usize; 3] = [10, 40, 160];

/// Evaluations of `ΔC` timed per point.
const TIMED: usize = 20_000;

/// One point of the sweep.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct CutPoint {
    /// `local fields` or `bare`.
    pub(super) discontinuous: String,
    /// The Ritz basis (`srb`, `prb`) and its modes; 0 modes with local fields.
    pub(super) basis: String,
    pub(super) modes: usize,
    pub(super) sliver: f64,
    pub(super) enriched_nodes: usize,
    /// Relative error of the force for a unit imposed displacement along each axis at each
    /// contact node, against the full XFEM at the scene's sliver: median and largest.
    pub(super) force_error_median: f64,
    pub(super) force_error_max: f64,
    /// How many of the `states` compared (contact nodes × axes) a session's error estimate
    /// bounds: with local fields `1e-9 · |f|` (the cut's compliance is the full XFEM's); the
    /// bare enrichment attaches none (0).
    #[serde(default)]
    pub(super) estimate_bounded: usize,
    #[serde(default)]
    pub(super) states: usize,
    /// The cut's part of a tick: `ΔC` at a two-node patch (µs).
    pub(super) tick_p50_us: f64,
    pub(super) tick_p99_us: f64,
    pub(super) null_p50_us: f64,
    /// The cut thread's work for the whole cut (ms) and the model's preparation (s).
    pub(super) cut_ms: f64,
    pub(super) prepare_s: f64,
    pub(super) bytes: usize,
    #[serde(default)]
    pub(super) front: bool,
}

/// What the sweep found (`cut.json` keeps it with the study's key).
#[derive(Debug, Serialize, Deserialize)]
pub(super) struct CutSweep {
    key: String,
    /// The contact nodes the forces were compared at.
    contacts: Vec<usize>,
    pub(super) points: Vec<CutPoint>,
    /// Swept sliver thresholds that enrich exactly the scene's nodes on this cut (no cell is
    /// cut near enough to a node to be a sliver): the same model, not measured again.
    pub(super) slivers_without_effect: Vec<f64>,
}

/// One setting: the model prepared, cut, its forces at the reference's contact nodes against
/// the full XFEM's, its tick timed.
fn measure(
    model: &OrganModel,
    modes: &[f64],
    (n_modes, basis, disc): (usize, RitzBasis, Discontinuous),
    params: &XfemParams,
    cells: &[(usize, Plane)],
    reference: &Reference,
    load_nodes: &[usize],
) -> anyhow::Result<CutPoint> {
    let start = Instant::now();
    let n_dofs = model.mesh.n_dofs();
    let mut r = ReducedCut::new(
        &model.mesh,
        &model.materials,
        model.locking,
        &model.problem,
        &modes[..n_modes * n_dofs],
        n_modes,
        basis,
        disc,
        params,
    )?;
    let prepare_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    // as a session keeps it: the cut's work includes the contact table's
    r.tabulate(load_nodes);
    r.cut(&model.mesh, cells)?;
    let cut_ms = 1e3 * start.elapsed().as_secs_f64();
    let mut view = r.view();
    let errors = reference.errors(&mut view);
    let estimate_bounded = if disc == Discontinuous::LocalFields {
        errors.iter().filter(|&&e| e <= LINEAR_RELATIVE_ERROR).count()
    } else {
        0
    };
    let a0 = reference.contacts.first().copied().unwrap_or(0);
    let a1 = reference.contacts.get(1).copied().unwrap_or(a0);
    let mut flip = 0usize;
    let tick = stat(
        "cut tick",
        time_n(TIMED, || {
            flip += 1;
            let w = if flip.is_multiple_of(2) { [0.6, 0.4] } else { [0.4, 0.6] };
            let c = view.added_compliance(&[a0, a1], &w);
            c[0][0] + c[1][1] + c[2][2]
        }),
    );
    let null = stat("null", time_n(TIMED, || 0.0));
    Ok(CutPoint {
        discontinuous: match disc {
            Discontinuous::Bare => "bare".into(),
            Discontinuous::LocalFields => "local fields".into(),
        },
        basis: if n_modes == 0 { "-".into() } else { basis.name().into() },
        modes: n_modes,
        sliver: params.sliver,
        enriched_nodes: r.enrichment().len(),
        force_error_median: errors.get(errors.len() / 2).copied().unwrap_or(f64::NAN),
        force_error_max: errors.last().copied().unwrap_or(f64::NAN),
        estimate_bounded,
        states: errors.len(),
        tick_p50_us: tick.p50_us,
        tick_p99_us: tick.p99_us,
        null_p50_us: null.p50_us,
        cut_ms,
        prepare_s,
        bytes: r.bytes(),
        front: false,
    })
}

/// The settings swept: local fields at the scene's sliver and the others, then the bare
/// enrichment on SRB and PRB bases of the first modes at the scene's sliver.
fn settings(scene_sliver: f64, modes: usize) -> Vec<(usize, RitzBasis, Discontinuous, f64)> {
    let mut out = vec![(0, RitzBasis::Srb, Discontinuous::LocalFields, scene_sliver)];
    for s in SLIVERS {
        if s != scene_sliver {
            out.push((0, RitzBasis::Srb, Discontinuous::LocalFields, s));
        }
    }
    for basis in [RitzBasis::Srb, RitzBasis::Prb] {
        let mut counts: Vec<usize> = BARE_MODES.iter().map(|&m| m.min(modes)).filter(|&m| m > 0).collect();
        counts.dedup();
        for m in counts {
            out.push((m, basis, Discontinuous::Bare, scene_sliver));
        }
    }
    out
}

/// Sweeps cutting on organ 0 of `scene` (see the [module docs](self)) with the modes of its
/// vademecum `v`; writes `cut.csv` and `cut_error_vs_tick.svg` to `out`. `None` unless organ 0
/// is the scene's cut organ ([`Scene::cut_organ`]).
pub(super) fn sweep(scene: &Scene, v: &Vademecum, key: &str, out: &Path) -> anyhow::Result<Option<CutSweep>> {
    if scene.cut_organ() != Some(0) {
        return Ok(None);
    }
    let record_path = out.join("cut.json");
    if let Ok(old) = std::fs::read_to_string(&record_path)
        && let Ok(rec) = serde_json::from_str::<CutSweep>(&old)
        && rec.key == key
    {
        eprintln!("resuming: the cutting sweep in {} is reused", record_path.display());
        write_outputs(&rec.points, scene, out)?;
        return Ok(Some(rec));
    }
    let model = scene.organ_model(0)?;
    if model.laws.is_some() {
        // a hyperelastic organ is cut by the meshless solver (the scene refuses XFEM for it)
        eprintln!(
            "the cutting sweep is skipped: organ '{}' is hyperelastic, its cuts are the meshless solver's (the meshless sweep makes them)",
            model.name
        );
        return Ok(None);
    }
    let params = scene.spec.fidelity.xfem.params();
    let bar = ProgressBar::new(CONTACTS as u64);
    bar.set_style(ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed}]").unwrap_or_else(|_| ProgressStyle::default_bar()));
    bar.set_message("cutting sweep: the full XFEM's compliances, cut and uncut");
    let reference = Reference::of(&scene.organ_cuts(0)?, &model, &params, |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })
    .map_err(anyhow::Error::msg)?;
    let todo = settings(params.sliver, v.modes());
    bar.set_length(todo.len() as u64);
    bar.set_position(0);
    let (mut points, mut slivers_without_effect) = (Vec::new(), Vec::new());
    for (m, basis, disc, sliver) in todo {
        bar.set_message(format!(
            "cutting sweep: {}, {m} modes, sliver {sliver:.0e}",
            if disc == Discontinuous::Bare { "bare" } else { "local fields" }
        ));
        let p = XfemParams { sliver, ..params };
        let cells = cut_cells(&scene.organ_cuts(0)?, &model, &p).map_err(anyhow::Error::msg)?;
        if sliver != params.sliver && Enrichment::from_cut_cells(&model.mesh, &cells, &p)?.nodes == reference.enriched {
            slivers_without_effect.push(sliver);
            bar.inc(1);
            continue;
        }
        points.push(measure(
            &model,
            v.f_raw(),
            (m, basis, disc),
            &p,
            &cells,
            &reference,
            v.load_nodes(),
        )?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let front = super::study_report::pareto(&points.iter().map(|p| (p.tick_p50_us, p.force_error_max)).collect::<Vec<_>>());
    for (p, f) in points.iter_mut().zip(front) {
        p.front = f;
    }
    write_outputs(&points, scene, out)?;
    let rec = CutSweep {
        key: key.to_string(),
        contacts: reference.contacts,
        points,
        slivers_without_effect,
    };
    std::fs::write(&record_path, serde_json::to_string_pretty(&rec)?)?;
    Ok(Some(rec))
}

/// Writes cut.csv and cut_error_vs_tick.svg of `points` to `out` (also when the sweep is resumed).
fn write_outputs(points: &[CutPoint], scene: &Scene, out: &Path) -> anyhow::Result<()> {
    let mut csv = String::from(
        "discontinuous,basis,modes,sliver,enriched_nodes,force_error_median,force_error_max,estimate_bounded,states,tick_p50_us,tick_p99_us,null_p50_us,cut_ms,prepare_s,bytes,front\n",
    );
    for p in points {
        csv += &format!(
            "{},{},{},{:e},{},{:e},{:e},{},{},{:.3},{:.3},{:.3},{:.2},{:.3},{},{}\n",
            p.discontinuous,
            p.basis,
            p.modes,
            p.sliver,
            p.enriched_nodes,
            p.force_error_median,
            p.force_error_max,
            p.estimate_bounded,
            p.states,
            p.tick_p50_us,
            p.tick_p99_us,
            p.null_p50_us,
            p.cut_ms,
            p.prepare_s,
            p.bytes,
            p.front
        );
    }
    std::fs::write(out.join("cut.csv"), csv).context("cannot write cut.csv")?;
    plot(points, &scene.spec.scene.name, &out.join("cut_error_vs_tick.svg"))?;
    Ok(())
}

/// The sentence of the verdict: the scene's setting, and the cheapest point on the front whose
/// largest force error is within 1 %.
pub(super) fn verdict(sweep: &CutSweep, scene_sliver: f64, scene_disc: Discontinuous) -> String {
    let points = &sweep.points;
    let describe = |p: &CutPoint| {
        let model = if p.modes == 0 {
            p.discontinuous.clone()
        } else {
            format!("{} on {} {} modes", p.discontinuous, p.modes, p.basis)
        };
        format!(
            "{model}, sliver {:.0e} ({} enriched nodes, force error {:.1e} median, {:.1e} largest, ΔC {:.2} µs per tick p50, the cut {:.2} ms on the cut thread)",
            p.sliver, p.enriched_nodes, p.force_error_median, p.force_error_max, p.tick_p50_us, p.cut_ms
        )
    };
    let disc = match scene_disc {
        Discontinuous::Bare => "bare",
        Discontinuous::LocalFields => "local fields",
    };
    let own = points.iter().find(|p| p.sliver == scene_sliver && p.discontinuous == disc);
    let best = points
        .iter()
        .filter(|p| p.front && p.force_error_max <= 1e-2)
        .min_by(|a, b| a.tick_p50_us.total_cmp(&b.tick_p50_us));
    let same = if sweep.slivers_without_effect.is_empty() {
        String::new()
    } else {
        format!(
            " Sliver thresholds {} enrich the same {} nodes on this cut (none of its cells is cut near a node): the rule has nothing to trade here.",
            sweep
                .slivers_without_effect
                .iter()
                .map(|s| format!("{s:.0e}"))
                .collect::<Vec<_>>()
                .join(", "),
            own.map_or(0, |p| p.enriched_nodes)
        )
    };
    let estimate = match own {
        Some(p) if p.discontinuous == "local fields" => format!(
            " The error estimate a session attaches to the cut organ's force (1e-9 of it) bounds {} of the {} forces compared ({:.1} %).",
            p.estimate_bounded,
            p.states,
            100.0 * p.estimate_bounded as f64 / p.states.max(1) as f64
        ),
        Some(_) => " The bare enrichment's forces carry the build's calibration of its force error at the cut as their estimate (checked between the cracked nodes with the per-answer estimate above).".into(),
        None => String::new(),
    };
    format!(
        "Cutting — the scene's setting: {}; the cheapest on the front with every force within 1 % of the full XFEM's: {}.{same}{estimate}",
        own.map_or("not swept".into(), describe),
        best.map_or("none".into(), describe)
    )
}

/// Whether the error estimate of the scene's setting bounds at least 95 % of the forces
/// compared (true when its model attaches none: nothing to hold).
pub(super) fn estimate_holds(sweep: &CutSweep, scene_sliver: f64) -> bool {
    sweep
        .points
        .iter()
        .find(|p| p.sliver == scene_sliver && p.discontinuous == "local fields")
        .is_none_or(|p| p.estimate_bounded as f64 >= super::study_estimate::REQUIRED * p.states as f64)
}

/// Largest force error against the cut's part of the tick, one colour per model, the sliver
/// or the modes beside each point, the front as a line.
fn plot(points: &[CutPoint], scene: &str, file: &Path) -> anyhow::Result<()> {
    let err = |p: &CutPoint| p.force_error_max.max(1e-16);
    let groups: Vec<Group> = [("local fields", "-"), ("bare", "srb"), ("bare", "prb")]
        .into_iter()
        .map(|(disc, basis)| Group {
            label: if basis == "-" {
                "local fields (sliver beside each)".into()
            } else {
                format!("bare, {} basis (modes beside each)", basis.to_uppercase())
            },
            triangles: false,
            points: points
                .iter()
                .filter(|p| p.discontinuous == disc && p.basis.eq_ignore_ascii_case(basis))
                .map(|p| {
                    let tag = if p.modes == 0 {
                        format!("{:.0e}", p.sliver)
                    } else {
                        p.modes.to_string()
                    };
                    (p.tick_p50_us, err(p), tag)
                })
                .collect(),
        })
        .collect();
    let front = points.iter().filter(|p| p.front).map(|p| (p.tick_p50_us, err(p))).collect();
    scatter(
        file,
        &format!("{scene}: cutting, force error against the cut's cost per tick"),
        (
            "ΔC at the contact, per tick, p50 (µs)",
            "largest relative force error against the full XFEM",
        ),
        &groups,
        front,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(disc: &str, modes: usize, sliver: f64, err: f64, tick: f64, front: bool) -> CutPoint {
        CutPoint {
            discontinuous: disc.into(),
            basis: if modes == 0 { "-".into() } else { "SRB".into() },
            modes,
            sliver,
            enriched_nodes: 72,
            force_error_median: err / 2.0,
            force_error_max: err,
            estimate_bounded: 12,
            states: 12,
            tick_p50_us: tick,
            tick_p99_us: 2.0 * tick,
            null_p50_us: 0.02,
            cut_ms: 400.0,
            prepare_s: 0.1,
            bytes: 1000,
            front,
        }
    }

    #[test]
    fn the_verdict_names_the_scenes_setting_the_cheapest_within_one_percent_and_idle_slivers() {
        let sweep = CutSweep {
            key: "k".into(),
            contacts: vec![1],
            points: vec![
                point("local fields", 0, 1e-4, 3e-14, 24.0, true),
                point("local fields", 0, 5e-2, 4e-3, 12.0, true),
                // cheaper still, but 30 % off
                point("bare", 10, 1e-4, 0.3, 8.0, true),
            ],
            slivers_without_effect: vec![1e-3, 1e-2],
        };
        let v = verdict(&sweep, 1e-4, Discontinuous::LocalFields);
        assert!(v.contains("the scene's setting: local fields, sliver 1e-4 (72 enriched nodes, force error 1.5e-14 median, 3.0e-14 largest, ΔC 24.00 µs"), "{v}");
        assert!(v.contains("within 1 % of the full XFEM's: local fields, sliver 5e-2 ("), "{v}");
        assert!(v.contains("Sliver thresholds 1e-3, 1e-2 enrich the same 72 nodes"), "{v}");
        assert!(v.contains("bounds 12 of the 12 forces compared (100.0 %)"), "{v}");
        assert!(estimate_holds(&sweep, 1e-4));
        let mut failing = sweep;
        failing.points[0].estimate_bounded = 11;
        assert!(!estimate_holds(&failing, 1e-4), "11 of 12 is below 95 %");
        let bare = verdict(&failing, 1e-4, Discontinuous::Bare);
        assert!(bare.contains("the scene's setting: bare on 10 SRB modes, sliver 1e-4"), "{bare}");
    }

    #[test]
    fn the_plot_draws_every_point_with_its_models_legend() {
        let points = [
            point("local fields", 0, 1e-4, 3e-14, 4.0, true),
            point("local fields", 0, 1e-3, 6e-3, 3.5, true),
            point("bare", 10, 1e-4, 0.7, 6.5, false),
            CutPoint {
                basis: "PRB".into(),
                ..point("bare", 10, 1e-4, 0.7, 4.6, false)
            },
        ];
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("cut.svg");
        plot(&points, "s", &file).unwrap();
        let svg = std::fs::read_to_string(&file).unwrap();
        // four points and three legend markers (local fields, bare SRB, bare PRB)
        assert_eq!(svg.matches("<circle").count(), 4 + 3, "{svg}");
    }

    #[test]
    fn the_settings_start_at_the_scenes_and_cap_the_modes_at_the_vademecums() {
        let s = settings(1e-4, 30);
        assert_eq!(s[0], (0, RitzBasis::Srb, Discontinuous::LocalFields, 1e-4));
        assert_eq!(s.iter().filter(|x| x.2 == Discontinuous::LocalFields).count(), 4);
        let bare: Vec<usize> = s
            .iter()
            .filter(|x| x.2 == Discontinuous::Bare && x.1 == RitzBasis::Srb)
            .map(|x| x.0)
            .collect();
        assert_eq!(bare, [10, 30]);
        // the scene's sliver among the swept ones is not repeated
        assert_eq!(settings(1e-2, 300).iter().filter(|x| x.3 == 1e-2).count(), 7);
    }
}
