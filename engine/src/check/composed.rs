//! Effects composed on one organ: the built-in `large_cut` flap, cut by the scalpel while it
//! deforms largely ([`crate::pipeline::cutting::stiffened_cut`]). A probe pressed deep on the
//! cut's lip and exactly on its line, far past the lattice's paths, must answer finite forces
//! that never fall while it goes deeper, flagged beyond range, with finite estimates; the
//! composed law's estimate must bound its error against Newton on the organ cut by split nodes
//! ([`crate::study::large_cut`]) in 95 % of the states; the co-rotational model, not composed
//! with the lattice, is a typed refusal.

use std::sync::{Arc, Mutex};

use super::{Case, Expect, Outcome, Size, builtin_at, diagnostic, outcome, session_bundle};
use crate::bundle::LoadedBundle;
use crate::offline::BuildOptions;
use crate::pipeline::{self, Events, Pipeline, ToolInput, ToolKind};
use crate::scene::Scene;

/// The built-in `large_cut`, twice as fine at full size.
fn flap_scene(size: Size) -> Result<Scene, Outcome> {
    builtin_at("large_cut", size, ["[8, 4, 4]", "[16, 8, 8]"])
}

/// The flap's bundle for `size` (its PGD vademecum and lattice), built once per process and
/// size, written and loaded back as a session's.
fn flap_bundle(scene: &Scene, size: Size) -> Result<Arc<LoadedBundle>, Outcome> {
    static BUILT: Mutex<Vec<(Size, Arc<LoadedBundle>)>> = Mutex::new(Vec::new());
    session_bundle(&BUILT, scene, size)
}

const H: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// The scalpel's stroke down x = 1 to half height, upright, then out: the flap cut as its
/// scene plans.
fn cut_the_flap(p: &mut Pipeline) {
    let blade = |z: f64| ToolInput {
        kind: ToolKind::Scalpel,
        position_m: [1.0, -0.1, z],
        blade_end_m: [1.0, 1.1, z],
        orientation: [H, 0.0, 0.0, -H],
        ..ToolInput::default()
    };
    for k in 0..=600 {
        p.tick(&blade(1.1 - 0.6 * f64::from(k) / 600.0));
    }
    for k in 0..=100 {
        p.tick(&blade(0.5 + 0.7 * f64::from(k) / 100.0));
    }
}

/// The flap cut, then the probe pressed straight down at (x, 0.5) from 2 cm above to 60 cm
/// deep (the lattice's paths end near 20 cm; the probe's limit is 60 N): every force finite,
/// never falling while the probe goes deeper, with a finite estimate.
fn deep_press(size: Size, x: f64) -> Outcome {
    outcome(|| {
        let scene = flap_scene(size)?;
        let b = flap_bundle(&scene, size)?;
        let mut p = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).map_err(diagnostic)?;
        p.set_deterministic(true);
        cut_the_flap(&mut p);
        let cracked = p.cut_status().map_or(0, |s| s.nodes.load(std::sync::atomic::Ordering::Relaxed));
        if cracked == 0 {
            return Err(Outcome::Broken("the stroke did not cut the flap".into()));
        }
        let (mut last, mut beyond, mut saturated, mut worst_estimate) = (0.0f64, None, false, 0.0f64);
        let steps = 2000;
        for k in 0..=steps {
            let depth = -0.02 + 0.62 * f64::from(k) / f64::from(steps);
            let s = p.tick(&ToolInput {
                tool: 1,
                position_m: [x, 0.5, 1.05 - depth],
                ..ToolInput::default()
            });
            let f = s.force_n.iter().map(|v| v * v).sum::<f64>().sqrt();
            if !(f.is_finite() && s.force_n.iter().all(|v| v.is_finite())) {
                return Err(Outcome::Broken(format!(
                    "a non-finite force at depth {depth:.3} m: {:?}",
                    s.force_n
                )));
            }
            if f < last * (1.0 - 1e-9) {
                return Err(Outcome::Broken(format!(
                    "the force fell from {last:.4} to {f:.4} N at depth {depth:.3} m while the probe went deeper"
                )));
            }
            if s.events.has(Events::CONTACT) {
                match s.force_error_n {
                    Some(e) if e.is_finite() => worst_estimate = worst_estimate.max(e),
                    other => return Err(Outcome::Broken(format!("estimate {other:?} at depth {depth:.3} m"))),
                }
            }
            if beyond.is_none() && s.events.has(Events::BEYOND_RANGE) {
                beyond = Some(depth);
            }
            saturated |= s.events.has(Events::FORCE_SATURATED);
            last = f;
        }
        Ok(Outcome::bounded(format!(
            "{cracked} cracked nodes; the force rises to {last:.2} N{}, beyond the lattice's paths from {} deep, estimates ≤ {worst_estimate:.2} N",
            if saturated { " (the probe's limit)" } else { "" },
            beyond.map_or("nowhere".to_string(), |d| format!("{:.0} mm", d * 1e3)),
        )))
    })
}

/// The composed law at up to 6 nodes beside the scene's cut against Newton on the organ cut by
/// split nodes: the share of states within the lattice's force its estimate does not bound.
fn estimate_against_newton(size: Size) -> Outcome {
    outcome(|| {
        let scene = flap_scene(size)?;
        let b = flap_bundle(&scene, size)?;
        let lattice = b.anm.as_ref().ok_or_else(|| Outcome::Broken("no lattice in the bundle".into()))?;
        let params = BuildOptions::for_scene(&scene, true)
            .large
            .ok_or_else(|| Outcome::Broken("the scene has no large-deformation settings".into()))?;
        let model = scene.organ_model(0).map_err(diagnostic)?;
        let cut = scene.planned_cuts().map_err(diagnostic)?.remove(0);
        let enr = crate::xfem::Enrichment::from_cut(&model.mesh, &cut, &pipeline::cut_params(&scene, None)).map_err(diagnostic)?;
        let nodes = crate::study::large_cut::nodes_beside(&model, &enr, lattice, 6);
        let states = crate::study::large_cut::composed_states(&model, &enr, lattice, &params, &nodes, |_, _| {}).map_err(diagnostic)?;
        let within: Vec<_> = states.iter().filter(|s| s.sample().within_force).collect();
        if within.is_empty() {
            return Err(Outcome::Broken("Newton reached no state within the lattice's force".into()));
        }
        let unbounded = within.iter().filter(|s| s.error() > s.estimate).count();
        let worst = within.iter().map(|s| s.error()).fold(0.0, f64::max);
        let alone = within
            .iter()
            .map(|s| s.linear_cut_error().max(s.uncut_large_error()))
            .fold(0.0, f64::max);
        Ok(Outcome::answer(
            format!(
                "{} states at {} nodes: the estimate bounds {} (largest error {:.1} % of the cut's linear force; either effect alone {:.0} %)",
                within.len(),
                nodes.len(),
                within.len() - unbounded,
                100.0 * worst,
                100.0 * alone
            ),
            unbounded as f64 / within.len() as f64,
        ))
    })
}

/// The co-rotational cutting model asked of the flap, which deforms largely.
fn corotational_refused(_size: Size) -> Outcome {
    let text = crate::scene::builtin("large_cut").expect("the built-in large_cut");
    let text = text.replace("[fidelity]\n", "[fidelity]\ncutting = \"corotational_xfem\"\n");
    match Scene::from_toml(&text, "<hard case: large_cut, co-rotational>") {
        Ok(_) => Outcome::Broken("accepted: the co-rotational model is not composed with the lattice".into()),
        Err(e) => diagnostic(e),
    }
}

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "a probe pressed 60 cm deep on a cut's lip, past the lattice",
            method: "cutting × large deformations",
            expect: Expect::FINITE,
            run: |size| deep_press(size, 0.875),
        },
        Case {
            name: "a probe pressed 60 cm deep on the cut's line",
            method: "cutting × large deformations",
            expect: Expect::FINITE,
            run: |size| deep_press(size, 1.0),
        },
        Case {
            name: "the composed force beside a cut against Newton on the split organ",
            method: "cutting × large deformations",
            expect: Expect::within(0.05),
            run: estimate_against_newton,
        },
        Case {
            name: "co-rotational cutting of an organ that deforms largely",
            method: "cutting × large deformations",
            expect: Expect::Diagnostic(&["not composed"]),
            run: corotational_refused,
        },
    ]
}
