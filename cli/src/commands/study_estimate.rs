//! The study's check of the per-answer error estimate (`ToolResponse.force_error_n`): sampled
//! contact states served as a session serves them, each beside the full-order model's answer
//! (module `engine::study::estimate`), the share the estimate bounds, a table and a plot.
//! Kept in `estimate.json` for the study's build: a resumed study does not redo it.

use std::path::Path;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use plotters::prelude::*;
use serde::{Deserialize, Serialize};
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::offline::BuildOptions;
use vademecum_engine::scene::Scene;
use vademecum_engine::study::estimate::{self, Coverage, Sample};
use vademecum_engine::study::large_cut;

/// The share of sampled states the estimate must bound.
pub(super) const REQUIRED: f64 = 0.95;

/// The version of the set of states the check samples: 2 added the third grasps and the grasps
/// after another site's pull, 3 the cut organ, 4 the co-rotational press, 5 the grasps after
/// many pulls, 6 the co-rotational press beside the cut, 7 the bare enrichment on the cut
/// halfway, 8 the organ cut and deformed largely (a record without it is of version 0, redone).
const SAMPLES: u32 = 8;

/// Contact points of the cut organ sampled (each pressed along the three axes; six full XFEM
/// solves each).
const CUT_POINTS: usize = 16;

/// What `estimate.json` keeps.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct EstimateRecord {
    /// The study build's key: another build redoes the check.
    key: String,
    /// The states sampled ([`SAMPLES`]): a record of another set is redone.
    #[serde(default)]
    samples: u32,
    /// Per model (`linear`, `large`): samples, bounded, median estimate / true error, largest
    /// relative error.
    pub(super) coverage: Vec<(String, Coverage)>,
}

/// Samples the estimate of organ 0 of `scene` (its study bundle `bundle`): `points` linear
/// states, `nodes` nodes off the lattice when the scene has large deformations, and each grasp
/// site pulled in the mixed directions of `estimate::TEAR_MIXES` when it tears; writes
/// `estimate.csv` and `estimate_vs_error.svg` to `out`. Reuses `estimate.json` when it was made
/// for build `key`.
pub(super) fn check(
    scene: &Scene,
    bundle: &LoadedBundle,
    key: &str,
    points: usize,
    nodes: usize,
    out: &Path,
) -> anyhow::Result<EstimateRecord> {
    let record_path = out.join("estimate.json");
    if let Ok(old) = std::fs::read_to_string(&record_path)
        && let Ok(rec) = serde_json::from_str::<EstimateRecord>(&old)
        && rec.key == key
        && rec.samples == SAMPLES
    {
        eprintln!("resuming: the error estimate's check in {} is reused", record_path.display());
        return Ok(rec);
    }
    let model = scene.organ_model(0)?;
    let bar = ProgressBar::new_spinner();
    bar.set_style(ProgressStyle::with_template("{spinner} {msg} [{elapsed}]").unwrap_or_else(|_| ProgressStyle::default_spinner()));
    bar.enable_steady_tick(std::time::Duration::from_millis(120));
    bar.set_message(format!("error estimate: {points} linear states against the full model"));
    let mut samples = estimate::linear_samples(&model, bundle, points)?;
    let large = scene.organ_large(0);
    if large && let (Some(lattice), Some(params)) = (&bundle.anm, BuildOptions::for_scene(scene, true).large) {
        bar.set_message(format!("error estimate: full Newton at {nodes} nodes off the lattice"));
        samples.extend(estimate::large_samples(&model, lattice, &params, nodes, |done, total| {
            bar.set_message(format!("error estimate: full Newton at nodes off the lattice, {done}/{total}"))
        })?);
    }
    if scene.spec.effects.tearing && vademecum_engine::scene::tearing::tearable_organ(scene) == Some(0) {
        // every grasp site's calibration, each pulled in mixed directions, as later grasps too
        // (after the next site's pull, when there are several)
        let (tear_model, _) = vademecum_engine::scene::tearing::tear_model(scene, 0)?;
        let sites = bundle.tear.len();
        let offs = bundle
            .tear
            .iter()
            .map(|arrays| {
                vademecum_engine::damage::online::TearOffline::from_arrays(tear_model.clone(), (**arrays).clone())
                    .map(std::sync::Arc::new)
                    .map_err(anyhow::Error::msg)
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        for (k, off) in offs.iter().enumerate() {
            let other = (sites > 1).then(|| &offs[(k + 1) % sites]);
            samples.extend(estimate::tear_samples(off, other, |done, total| {
                bar.set_message(format!(
                    "error estimate: grasp site {} of {sites}, mixed pulls against the full-order model, {done}/{total}",
                    k + 1
                ))
            })?);
        }
    }
    // the study measures organ 0 (`study::run`): its cut when it is the cut organ
    let cut_here = scene.cut_organ() == Some(0);
    if cut_here {
        samples.extend(
            estimate::cut_samples(scene, &model, bundle, CUT_POINTS, |done, total| {
                bar.set_message(format!(
                    "error estimate: the cut organ pressed between its cracked nodes against the full XFEM, {done}/{total}"
                ))
            })
            .map_err(anyhow::Error::msg)?,
        );
    }
    if cut_here && scene.spec.fidelity.cutting == vademecum_engine::scene::schema::CuttingModel::CorotationalXfem {
        bar.set_message("error estimate: a co-rotational press, each tick against the deformation's own compliance");
        if let Some(contact) = press(&model, bundle, |_| true) {
            samples.extend(
                estimate::corotational_samples(&model.mesh, &model.materials, &model.problem, &contact, None)
                    .map_err(anyhow::Error::msg)?,
            );
        }
        // the same beside the scene's cut, on the organ cut by it
        bar.set_message("error estimate: a co-rotational press beside the cut, each tick against the deformation's own compliance");
        let cut = std::sync::Arc::new(scene_cut(scene, &model, bundle)?);
        if let Some(contact) = press(&model, bundle, |t| t.iter().any(|&a| cut.index(a).is_some())) {
            samples.extend(
                estimate::corotational_samples(&model.mesh, &model.materials, &model.problem, &contact, Some(&cut))
                    .map_err(anyhow::Error::msg)?,
            );
        }
    }
    if cut_here
        && large
        && let (Some(lattice), Some(params)) = (&bundle.anm, BuildOptions::for_scene(scene, true).large)
    {
        // the scene's cuts on the organ that deforms largely, pressed beside them
        let cut = scene_cut(scene, &model, bundle)?;
        if !cut.is_empty() {
            let beside = large_cut::nodes_beside(&model, &cut, lattice, nodes);
            let states = large_cut::composed_states(&model, &cut, lattice, &params, &beside, |done, total| {
                bar.set_message(format!(
                    "error estimate: the cut organ that deforms largely, Newton on the split organ beside the cut, {done}/{total}"
                ))
            })?;
            samples.extend(states.iter().map(large_cut::ComposedState::sample));
        }
    }
    bar.finish_and_clear();

    let mut csv = String::from("model,x_m,y_m,z_m,depth_m,beyond_range,served,truth,error,estimate,bounded\n");
    for s in &samples {
        csv += &format!(
            "{},{:e},{:e},{:e},{:e},{},{:e},{:e},{:e},{:e},{}\n",
            s.model,
            s.point_m[0],
            s.point_m[1],
            s.point_m[2],
            s.depth_m,
            s.beyond_range,
            s.served,
            s.truth,
            s.error,
            s.estimate,
            s.bounded()
        );
    }
    std::fs::write(out.join("estimate.csv"), csv).context("cannot write estimate.csv")?;
    plot(&samples, &scene.spec.scene.name, &out.join("estimate_vs_error.svg"))?;
    let coverage = estimate::MODELS
        .into_iter()
        .map(|m| {
            let of: Vec<Sample> = samples.iter().copied().filter(|s| s.model == m).collect();
            (m.to_string(), Coverage::of(&of))
        })
        .filter(|(_, c)| c.samples > 0)
        .collect();
    let rec = EstimateRecord {
        key: key.to_string(),
        samples: SAMPLES,
        coverage,
    };
    std::fs::write(&record_path, serde_json::to_string_pretty(&rec)?)?;
    Ok(rec)
}

/// The enrichment of organ 0 (`model`) cut by the scene's planned cuts, with the sliver rule
/// its bundle chose: the cut a session's cutting model makes of them.
fn scene_cut(
    scene: &Scene,
    model: &vademecum_engine::fem::OrganModel,
    bundle: &LoadedBundle,
) -> anyhow::Result<vademecum_engine::xfem::Enrichment> {
    let params = vademecum_engine::pipeline::cut_params(scene, bundle.cut_sliver().map_err(anyhow::Error::msg)?);
    let cells = vademecum_engine::xfem::accuracy::cut_cells(&scene.organ_cuts(0)?, model, &params).map_err(anyhow::Error::msg)?;
    Ok(vademecum_engine::xfem::Enrichment::from_cut_cells(&model.mesh, &cells, &params)?)
}

/// Of the organ's smallest extent, how deep [`press`] pushes (linearly).
const PRESS_DEPTH: f64 = 0.1;

/// A press into organ `model` at the centroid of its highest accessible surface triangle (all
/// three nodes accessible and free) of those `near` keeps, along the triangle's inward normal,
/// with the force that
/// pushes it [`PRESS_DEPTH`] of the organ's smallest extent deep by the linear law (the
/// vademecum's exact compliance there, `bundle`): rotations of a few degrees to tens.
fn press(
    model: &vademecum_engine::fem::OrganModel,
    bundle: &LoadedBundle,
    near: impl Fn(&[usize; 3]) -> bool,
) -> Option<vademecum_engine::pipeline::Contact> {
    use vademecum_engine::mesh::boundary::triangle_area_normal;
    let free = |a: usize| !(0..3).any(|i| model.problem.constrained[3 * a + i]);
    let top = model
        .boundary
        .triangles()
        .into_iter()
        .filter(|t| near(t) && t.iter().all(|&a| free(a) && model.accessible_nodes.contains(&a)))
        .max_by(|a, b| {
            let z = |t: &[usize; 3]| t.iter().map(|&n| model.mesh.nodes[n][2]).sum::<f64>();
            z(a).total_cmp(&z(b))
        })?;
    let (_, n) = triangle_area_normal(&model.mesh, top);
    let size = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let c = bundle
        .vademecum
        .contact_compliance(top, [1.0 / 3.0; 3], vademecum_engine::pgd::Footprint::Tip)?;
    let along: f64 = (0..3).map(|i| (0..3).map(|j| n[i] * c[i][j] * n[j]).sum::<f64>()).sum::<f64>() / (size * size);
    let (lo, hi) = model.mesh.bounding_box();
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(f64::INFINITY, f64::min);
    let force = PRESS_DEPTH * extent / along;
    if !(force.is_finite() && force > 0.0) {
        return None;
    }
    Some(vademecum_engine::pipeline::Contact {
        nodes: top,
        weights: [1.0 / 3.0; 3],
        tissue_force_n: n.map(|x| -force * x / size),
        loadable: 1.0,
        ..Default::default()
    })
}

/// The sentence of the verdict: per model, the share bounded and how loose the bound is.
pub(super) fn verdict(rec: &EstimateRecord) -> String {
    let parts: Vec<String> = rec
        .coverage
        .iter()
        .map(|(m, c)| {
            let how = if c.max_relative_error < 1e-12 {
                format!(
                    "the full model agrees to round-off (largest difference {:.1e} relative, the estimate being 1e-9 of the force)",
                    c.max_relative_error
                )
            } else {
                format!(
                    "median estimate / true error {:.2}, largest true error {:.2e} relative{}",
                    c.median_ratio,
                    c.max_relative_error,
                    if m == "large" {
                        " (up to 1.5 times the lattice's force, past its paths)"
                    } else {
                        ""
                    }
                )
            };
            format!(
                "{m}: the estimate bounds the full model's error in {} of {} sampled states ({:.1} %, {} {:.0} %); {how}",
                c.bounded,
                c.samples,
                100.0 * c.fraction(),
                if c.fraction() >= REQUIRED { "meeting" } else { "BELOW" },
                100.0 * REQUIRED,
            )
        })
        .collect();
    format!("Per-answer error estimate — {}.", parts.join("; "))
}

/// Whether every model's estimate meets [`REQUIRED`].
pub(super) fn holds(rec: &EstimateRecord) -> bool {
    rec.coverage.iter().all(|(_, c)| c.fraction() >= REQUIRED)
}

/// Estimate against true error, log–log, relative to the served value, with the line where they
/// are equal: a bounded state lies above it.
fn plot(samples: &[Sample], scene: &str, file: &Path) -> anyhow::Result<()> {
    let rel = |v: f64, s: &Sample| (v / s.served.abs().max(f64::MIN_POSITIVE)).max(1e-17);
    let pts: Vec<(f64, f64, &Sample)> = samples.iter().map(|s| (rel(s.error, s), rel(s.estimate, s), s)).collect();
    let lo = pts.iter().flat_map(|p| [p.0, p.1]).fold(1.0, f64::min) * 0.5;
    let hi = pts.iter().flat_map(|p| [p.0, p.1]).fold(1e-12, f64::max) * 2.0;
    let root = crate::plot::canvas(file, (760, 640))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{scene}: per-answer error estimate against the true error"),
            ("sans-serif", 18),
        )
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d((lo..hi).log_scale(), (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("true error against the full model (relative)")
        .y_desc("estimate the session attaches (relative)")
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()?;
    chart
        .draw_series(LineSeries::new([(lo, lo), (hi, hi)], BLACK.stroke_width(1)))?
        .label("estimate = error (bounded above)")
        .legend(crate::plot::line_key(BLACK.stroke_width(1)));
    // (model, past the paths, legend, colour): the two cutting models never share a scene
    let groups: [(&str, bool, &str, usize); 13] = [
        ("linear", false, "linear law", 0),
        ("large", false, "large deformations, within the lattice's paths", 1),
        ("large", true, "large deformations, past the paths", 2),
        ("tearing", false, "tearing, mixed pulls", 3),
        (estimate::SECOND_GRASP, false, "tearing, a second grasp of damaged tissue", 4),
        (estimate::THIRD_GRASP, false, "tearing, a third grasp", 5),
        (estimate::OTHER_SITE, false, "tearing, after another site's pull", 6),
        (estimate::MANY_PULLS, false, "tearing, after six pulls at two sites", 1),
        (estimate::CUT, false, "cutting, between the cracked nodes", 7),
        (estimate::CUT_BARE, false, "cutting, bare enrichment, between the cracked nodes", 7),
        (estimate::CUT_BARE_HALFWAY, false, "cutting, bare enrichment, the cut halfway", 3),
        (estimate::COROTATIONAL, false, "cutting, a co-rotational press", 4),
        (
            estimate::COROTATIONAL_CUT,
            false,
            "cutting, a co-rotational press beside the cut",
            5,
        ),
    ];
    for (model, beyond, label, k) in groups {
        let color = super::bench_anm::PALETTE[k];
        let of: Vec<(f64, f64)> = pts
            .iter()
            .filter(|p| p.2.model == model && p.2.beyond_range == beyond)
            .map(|p| (p.0, p.1))
            .collect();
        if of.is_empty() {
            continue;
        }
        chart
            .draw_series(of.iter().map(|&(x, y)| Circle::new((x, y), 4, color.filled())))?
            .label(label)
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
    }
    crate::plot::legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present()?;
    Ok(())
}
