//! The study's sweep of the meshless solver (scenes with `fidelity.solver = "meshless"`;
//! seed 004): what its three settings cost and buy on the scene's first organ.
//!
//! Points: the influence radius (1.6, the scene's, 3.0 mean edge lengths) × the integration
//! (1 point per cell, the seed's, or 4 per tetrahedron / 8 per hexahedron) at the scene's
//! tolerance; and the relaxation's tolerance at 100×, 10× and a tenth of the scene's, at the
//! scene's support and integration. Each point is one whole solve (`meshless::organ::solve`,
//! cuts included).
//!
//! The full-order model on the same mesh is the finite-element Newton–Raphson solve of the
//! same organ, law and loads (what `vademecum solve` runs with `solver = "fem"`); against it,
//! on the loaded organ before any cut: the relative L2 error of the displacement at the mesh's
//! nodes, of the reactions over the named regions, and of the strain energy. (The two are
//! different discretisations of the same continuum on the same nodes: the figure is their
//! distance, which the meshless setting moves, not an error of one alone.) A cut has no
//! finite-element counterpart on a hyperelastic organ: after the cuts the reactions are
//! compared with those of the most accurate setting (the scene's support and integration, a
//! tenth of its tolerance). Cost: the solve's wall time and relaxation steps, the integration
//! points, the shape functions' memory. Points are kept one per line in `meshless.jsonl`: a
//! killed study resumes without solving them again.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};
use vademecum_engine::damage::reference::l2_error;
use vademecum_engine::fem::hyperelastic::Volumetric;
use vademecum_engine::fem::nonlinear_static::{self, NewtonParams};
use vademecum_engine::meshless::organ::{self, OrganSettings};
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::schema::SolverKind;

use super::solve::{meshless_law, meshless_settings};
use super::study_report::{Group, rel, scatter};

/// Influence radii swept beside the scene's (mean edge lengths at the node).
const SUPPORTS: [f64; 2] = [1.6, 3.0];
/// Tolerances swept, as factors of the scene's.
const TOLERANCE_FACTORS: [f64; 3] = [100.0, 10.0, 0.1];
/// Bytes of one shape-function entry (node index, `φ`, its three derivatives) and the
/// per-point overhead (three vector headers and the weight).
const ENTRY_BYTES: usize = 40;
const POINT_BYTES: usize = 80;

/// One setting of the meshless solver, measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct MeshlessPoint {
    pub(super) support: f64,
    pub(super) integration: usize,
    pub(super) tolerance: f64,
    /// Why the solve failed (the typed diagnostic), or `None`.
    pub(super) failure: Option<String>,
    /// Against the finite-element solve, before any cut: the displacement at the mesh's nodes,
    /// the reactions over the named regions (relative L2) and the strain energy (`NaN`, kept
    /// as `null`, when the solve failed).
    #[serde(deserialize_with = "super::study_report::nan_if_null")]
    pub(super) field_error: f64,
    #[serde(deserialize_with = "super::study_report::nan_if_null")]
    pub(super) reaction_error: f64,
    #[serde(deserialize_with = "super::study_report::nan_if_null")]
    pub(super) energy_error: f64,
    /// After the cuts (scenes with cuts): the reactions' relative difference from the most
    /// accurate setting's (filled when the outputs are written).
    #[serde(default)]
    pub(super) cut_reaction_error: Option<f64>,
    /// The reactions over the named regions after the cuts (N, 3 per region).
    pub(super) final_reactions: Vec<f64>,
    pub(super) steps: usize,
    pub(super) solve_s: f64,
    pub(super) integration_points: usize,
    pub(super) shape_bytes: usize,
    #[serde(default)]
    pub(super) front: bool,
}

/// Equal to 1e-12: serde_json reads a float back to within an ulp, not always exactly.
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs()
}

impl MeshlessPoint {
    /// Whether the point measured setting `s`.
    fn same_setting(&self, s: &OrganSettings) -> bool {
        close(self.support, s.support) && self.integration == s.integration && close(self.tolerance, s.params.tolerance)
    }
}

/// What the sweep found (`meshless.json`).
#[derive(Debug, Serialize, Deserialize)]
pub(super) struct MeshlessSweep {
    pub(super) organ: String,
    pub(super) scene_support: f64,
    pub(super) scene_integration: usize,
    pub(super) scene_tolerance: f64,
    /// The finite-element Newton solve's time (s), its strain energy (J).
    pub(super) reference_s: f64,
    pub(super) reference_energy_j: f64,
    pub(super) cuts: usize,
    pub(super) points: Vec<MeshlessPoint>,
}

/// The settings swept from the scene's `own` (see the [module docs](self)).
fn settings(own: &OrganSettings) -> Vec<OrganSettings> {
    let mut supports: Vec<f64> = SUPPORTS.into_iter().chain([own.support]).collect();
    supports.sort_by(f64::total_cmp);
    supports.dedup();
    let mut out: Vec<OrganSettings> = supports
        .iter()
        .flat_map(|&support| {
            [1, 2].map(|integration| OrganSettings {
                support,
                integration,
                ..*own
            })
        })
        .collect();
    for f in TOLERANCE_FACTORS {
        let mut s = *own;
        s.params.tolerance *= f;
        out.push(s);
    }
    out
}

/// The reactions over the named regions (3 per region) of node reactions `r`.
fn region_reactions(regions: &[(String, Vec<usize>)], r: &[f64]) -> Vec<f64> {
    regions
        .iter()
        .flat_map(|(_, nodes)| vademecum_engine::fem::node_sum(r, nodes))
        .collect()
}

/// Sweeps the meshless solver's settings on the scene's first organ (see the
/// [module docs](self)); writes `meshless.csv` and `meshless_error_vs_time.svg` to `out`.
/// `None` for a scene not solved by the meshless solver.
pub(super) fn sweep(scene: &Scene, key: &str, out: &Path) -> anyhow::Result<Option<MeshlessSweep>> {
    if scene.spec.fidelity.solver != SolverKind::Meshless {
        return Ok(None);
    }
    let model = scene.organ_model(0)?;
    let law = meshless_law(&model)?;
    let laws = model.laws.as_ref().context("the meshless solver needs a hyperelastic organ")?;
    let cuts = scene.organ_cuts(0)?;
    let own = meshless_settings(scene);

    let bar = ProgressBar::new_spinner();
    bar.set_style(ProgressStyle::with_template("{spinner} {msg} [{elapsed}]").unwrap_or_else(|_| ProgressStyle::default_spinner()));
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar.set_message("meshless sweep: the finite-element reference (Newton-Raphson)");
    let start = Instant::now();
    let (reference, _) = nonlinear_static::solve_static(
        &model.mesh,
        laws,
        Volumetric::for_locking(model.locking),
        &model.problem,
        &NewtonParams::default(),
        |_| {},
    )
    .context("the finite-element reference of the meshless sweep did not converge")?;
    let reference_s = start.elapsed().as_secs_f64();
    let reference_reactions = region_reactions(&model.named_regions, &reference.reactions);

    // resume: the points solved before on this scene
    let log_path = out.join("meshless.jsonl");
    let mut points: Vec<MeshlessPoint> = std::fs::read_to_string(&log_path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| l.strip_prefix(key).and_then(|l| l.strip_prefix(' ')))
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    let todo: Vec<OrganSettings> = settings(&own)
        .into_iter()
        .filter(|s| !points.iter().any(|p| p.same_setting(s)))
        .collect();
    if !points.is_empty() {
        eprintln!(
            "resuming: the meshless sweep in {} has {} points, {} to solve",
            log_path.display(),
            points.len(),
            todo.len()
        );
    }
    let mut log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&log_path)
        .with_context(|| format!("cannot write {}", log_path.display()))?;
    let n = todo.len();
    for (k, s) in todo.into_iter().enumerate() {
        let what = format!(
            "meshless sweep {}/{n}: support {}, {} point(s) per cell and axis, tolerance {:.0e} m",
            k + 1,
            s.support,
            s.integration,
            s.params.tolerance
        );
        bar.set_message(what.clone());
        let problem = organ::problem(&model.mesh, law, &model.problem, &s);
        let mut covering = Vec::new();
        let entries: usize = problem
            .points
            .iter()
            .map(|p| {
                problem.cloud.covering(p.x, &mut covering);
                covering.len()
            })
            .sum();
        let t = Instant::now();
        let solved = organ::solve(&model.mesh, law, &model.problem, &cuts, &s, |stage, step, error| {
            bar.set_message(format!("{what}: stage {stage}, step {step}, error {error:.1e} m"));
        });
        let solve_s = t.elapsed().as_secs_f64();
        let mut p = MeshlessPoint {
            support: s.support,
            integration: s.integration,
            tolerance: s.params.tolerance,
            failure: None,
            field_error: f64::NAN,
            reaction_error: f64::NAN,
            energy_error: f64::NAN,
            cut_reaction_error: None,
            final_reactions: Vec::new(),
            steps: 0,
            solve_s,
            integration_points: problem.points.len(),
            shape_bytes: entries * ENTRY_BYTES + problem.points.len() * POINT_BYTES,
            front: false,
        };
        match solved {
            Err(e) => p.failure = Some(e.to_string()),
            Ok(r) => {
                let loaded = r.uncut.as_ref().unwrap_or(&r.solution);
                let u = &loaded.displacement[..reference.u.len()];
                let reactions = r.uncut_reactions.as_ref().unwrap_or(&r.reactions);
                p.field_error = l2_error(u, &reference.u).1;
                p.reaction_error = l2_error(&region_reactions(&model.named_regions, reactions), &reference_reactions).1;
                p.energy_error = rel(loaded.energy, reference.strain_energy);
                p.final_reactions = region_reactions(&model.named_regions, &r.reactions);
                p.steps = loaded.steps + if r.uncut.is_some() { r.solution.steps } else { 0 };
            }
        }
        writeln!(log, "{key} {}", serde_json::to_string(&p)?)?;
        points.push(p);
    }
    bar.finish_and_clear();
    points.sort_by(|a, b| {
        (a.support, a.integration, -a.tolerance)
            .partial_cmp(&(b.support, b.integration, -b.tolerance))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    finish(&mut points, &own, !cuts.is_empty());
    let sweep = MeshlessSweep {
        organ: model.name.clone(),
        scene_support: own.support,
        scene_integration: own.integration,
        scene_tolerance: own.params.tolerance,
        reference_s,
        reference_energy_j: reference.strain_energy,
        cuts: cuts.len(),
        points,
    };
    write_outputs(&sweep, &scene.spec.scene.name, out)?;
    Ok(Some(sweep))
}

/// The error a point is judged by: after the cuts when there are cuts, before them otherwise.
fn judged(p: &MeshlessPoint) -> f64 {
    p.cut_reaction_error.unwrap_or(p.field_error).max(p.field_error)
}

/// Fills each point's error after the cuts (against the most accurate setting) and marks the
/// Pareto front of the solve's time against [`judged`] error (failed points are off it).
fn finish(points: &mut [MeshlessPoint], own: &OrganSettings, cut: bool) {
    if cut {
        let mut best = *own;
        best.params.tolerance *= TOLERANCE_FACTORS[2];
        let reference = points
            .iter()
            .find(|p| p.same_setting(&best) && p.failure.is_none())
            .map(|p| p.final_reactions.clone());
        for p in points.iter_mut() {
            p.cut_reaction_error = match (&reference, &p.failure) {
                (Some(r), None) => Some(l2_error(&p.final_reactions, r).1),
                _ => None,
            };
        }
    }
    let cost: Vec<(f64, f64)> = points
        .iter()
        .map(|p| {
            if p.failure.is_none() {
                (p.solve_s, judged(p))
            } else {
                (f64::INFINITY, f64::INFINITY)
            }
        })
        .collect();
    for (p, f) in points.iter_mut().zip(super::study_report::pareto(&cost)) {
        p.front = f && p.failure.is_none();
    }
}

/// Writes meshless.csv and meshless_error_vs_time.svg (also when the sweep is resumed).
fn write_outputs(s: &MeshlessSweep, scene: &str, out: &Path) -> anyhow::Result<()> {
    let mut csv = String::from(
        "support,integration,tolerance,field_error,reaction_error,energy_error,cut_reaction_error,steps,solve_s,integration_points,shape_bytes,front,failure\n",
    );
    for p in &s.points {
        csv += &format!(
            "{},{},{:e},{:e},{:e},{:e},{},{},{:.3},{},{},{},\"{}\"\n",
            p.support,
            p.integration,
            p.tolerance,
            p.field_error,
            p.reaction_error,
            p.energy_error,
            p.cut_reaction_error.map_or(String::new(), |e| format!("{e:e}")),
            p.steps,
            p.solve_s,
            p.integration_points,
            p.shape_bytes,
            p.front,
            p.failure.as_deref().unwrap_or("").replace('"', "'")
        );
    }
    std::fs::write(out.join("meshless.csv"), csv).context("cannot write meshless.csv")?;
    std::fs::write(out.join("meshless.json"), serde_json::to_string_pretty(s)?)?;
    let ok = |p: &&MeshlessPoint| p.failure.is_none();
    let groups: Vec<Group> = [1, 2]
        .into_iter()
        .map(|q| Group {
            label: format!("{q} point(s) per cell and axis, support beside each"),
            triangles: false,
            points: s
                .points
                .iter()
                .filter(ok)
                .filter(|p| p.integration == q && close(p.tolerance, s.scene_tolerance))
                .map(|p| (p.solve_s, judged(p), format!("{}", p.support)))
                .collect(),
        })
        .chain(std::iter::once(Group {
            label: "the scene's support and integration, tolerance beside each".into(),
            triangles: true,
            points: s
                .points
                .iter()
                .filter(ok)
                .filter(|p| !close(p.tolerance, s.scene_tolerance))
                .map(|p| (p.solve_s, judged(p), format!("{:.0e}", p.tolerance)))
                .collect(),
        }))
        .collect();
    let front = s.points.iter().filter(|p| p.front).map(|p| (p.solve_s, judged(p))).collect();
    let y = if s.cuts > 0 {
        "relative error (worst of the field before the cuts and the reactions after)"
    } else {
        "relative L2 distance of the displacement from the FE solve"
    };
    scatter(
        &out.join("meshless_error_vs_time.svg"),
        &format!("{scene} '{}': the meshless solver, error against the solve's time", s.organ),
        ("solve (s)", y),
        &groups,
        front,
    )
}

/// The sentence of the verdict: the scene's setting, the cheapest within 1 % of the
/// finite-element solve, the failures.
pub(super) fn verdict(s: &MeshlessSweep) -> String {
    let describe = |p: &MeshlessPoint| {
        let cut = p.cut_reaction_error.map_or(String::new(), |e| {
            format!(", reactions after the cuts {e:.1e} from the most accurate setting's")
        });
        format!(
            "support {}, {} point(s) per cell and axis, tolerance {:.0e} m (displacement {:.1e}, reactions {:.1e}, energy {:.1e} from the FE solve{cut}; {:.1} s, {} steps, {:.1} MB of shape functions)",
            p.support,
            p.integration,
            p.tolerance,
            p.field_error,
            p.reaction_error,
            p.energy_error,
            p.solve_s,
            p.steps,
            p.shape_bytes as f64 / 1e6
        )
    };
    let own = s
        .points
        .iter()
        .find(|p| close(p.support, s.scene_support) && p.integration == s.scene_integration && close(p.tolerance, s.scene_tolerance));
    let fastest = |limit: f64| {
        s.points
            .iter()
            .filter(|p| p.failure.is_none() && judged(p) <= limit)
            .min_by(|a, b| a.solve_s.total_cmp(&b.solve_s))
    };
    // as accurate as the scene's setting: within a tenth of its error
    let as_good = own
        .filter(|p| p.failure.is_none())
        .and_then(|p| fastest(1.1 * judged(p)).filter(|q| q.solve_s < p.solve_s))
        .map_or(String::new(), |q| {
            format!("; as accurate (within a tenth of its error) and faster: {}", describe(q))
        });
    let own = match own {
        Some(p) if p.failure.is_none() => describe(p),
        Some(p) => format!("fails ({})", p.failure.as_deref().unwrap_or("")),
        None => "not swept".into(),
    };
    let best = match fastest(1e-2) {
        Some(p) => format!("the fastest within 1 %: {}", describe(p)),
        None => "no setting is within 1 %".into(),
    };
    let failed: Vec<String> = s
        .points
        .iter()
        .filter(|p| p.failure.is_some())
        .map(|p| format!("support {} with {} point(s)", p.support, p.integration))
        .collect();
    let failed = if failed.is_empty() {
        String::new()
    } else {
        format!(" Failed: {} (meshless.csv says why).", failed.join(", "))
    };
    format!(
        "Meshless solver ('{}', against the finite-element Newton solve of the same mesh, {:.1} s) — the scene's setting: {own}{as_good}; {best}.{failed}",
        s.organ, s.reference_s
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use vademecum_engine::meshless::efg::AdrParams;

    fn own() -> OrganSettings {
        OrganSettings {
            support: 2.2,
            integration: 2,
            params: AdrParams::default(),
        }
    }

    #[test]
    fn the_settings_cross_supports_with_integrations_and_ladder_the_tolerance() {
        let s = settings(&own());
        assert_eq!(s.len(), 9);
        let grid: Vec<(f64, usize)> = s[..6].iter().map(|s| (s.support, s.integration)).collect();
        assert_eq!(grid, [(1.6, 1), (1.6, 2), (2.2, 1), (2.2, 2), (3.0, 1), (3.0, 2)]);
        assert!(s[..6].iter().all(|s| s.params.tolerance == 1e-7));
        let ladder: Vec<f64> = s[6..].iter().map(|s| s.params.tolerance / 1e-7).collect();
        assert!(
            ladder.iter().zip([100.0, 10.0, 0.1]).all(|(a, b)| (a - b).abs() < 1e-9 * b),
            "{ladder:?}"
        );
        // a scene already at one of the swept radii is not solved twice
        assert_eq!(settings(&OrganSettings { support: 3.0, ..own() }).len(), 7);
    }

    fn point(support: f64, tolerance: f64, err: f64, time: f64, reactions: [f64; 3]) -> MeshlessPoint {
        MeshlessPoint {
            support,
            integration: 2,
            tolerance,
            failure: None,
            field_error: err,
            reaction_error: err,
            energy_error: err,
            cut_reaction_error: None,
            final_reactions: reactions.to_vec(),
            steps: 100,
            solve_s: time,
            integration_points: 8,
            shape_bytes: 1000,
            front: false,
        }
    }

    #[test]
    fn after_cuts_points_are_judged_against_the_tightest_setting_and_failures_stay_off_the_front() {
        let mut pts = vec![
            point(2.2, 1e-7, 1e-2, 12.5, [1.0, 0.0, 0.0]),
            point(2.2, 1e-8, 1e-2, 12.0, [1.1, 0.0, 0.0]),
            point(3.0, 1e-7, 5e-3, 30.0, [1.1, 0.0, 0.0]),
            MeshlessPoint {
                failure: Some("shape functions".into()),
                ..point(1.6, 1e-7, f64::NAN, 1.0, [0.0; 3])
            },
        ];
        // a failed point survives the log's round trip (its NaN errors are written as null)
        let back: MeshlessPoint = serde_json::from_str(&serde_json::to_string(&pts[3]).unwrap()).unwrap();
        assert!(back.field_error.is_nan() && back.failure.is_some());
        finish(&mut pts, &own(), true);
        assert!((pts[0].cut_reaction_error.unwrap() - 0.1 / 1.1).abs() < 1e-12);
        assert_eq!(pts[1].cut_reaction_error, Some(0.0));
        assert_eq!(pts[3].cut_reaction_error, None);
        // the cut's 9 % makes the scene's setting worse than the tighter one: off the front
        assert_eq!(pts.iter().map(|p| p.front).collect::<Vec<_>>(), [false, true, true, false]);
    }
}
