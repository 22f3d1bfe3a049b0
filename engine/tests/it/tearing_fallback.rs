//! Tearing's cheaper setting under load (issue 19, fidelity fallback): the build chooses the
//! fewest modes per pull pattern whose calibrated force error stays within
//! `FALLBACK_ERROR_GROWTH` of all of them and stores it; a session under load steps exactly
//! that prefix (simplified integrator), from the state it holds, and says the prefix's own
//! error estimate; on the seed's cube (seed 000 §4.6.1.1).

use std::sync::Arc;

use vademecum_engine::bundle;
use vademecum_engine::damage::build;
use vademecum_engine::damage::online::{OnlineTear, StepLimits, TearOffline, Variant};
use vademecum_engine::damage::vademecum::AffineSystem;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::{Fidelity, Pipeline, TickState, ToolInput, ToolKind};
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::tearing;

fn built(target: Option<f64>) -> (TearOffline, build::TearBuildReport) {
    let scene = Scene::builtin("cube_tear").unwrap();
    let (model, _) = tearing::tear_model(&scene, 0).unwrap();
    let (settings, _) = tearing::settings(&scene);
    let settings = build::TearSettings {
        target_force_error: target,
        ..settings
    };
    let (off, report, _) = build::build(model, &settings, |_, _| {}).unwrap();
    (off, report)
}

fn last(t: &[[f64; 2]]) -> f64 {
    t.last().unwrap()[1]
}

#[test]
fn the_build_stores_the_fewest_modes_whose_force_stays_about_as_accurate() {
    let (off, report) = built(None);
    let f = off
        .fallback
        .clone()
        .expect("the cube's build makes more modes than the fallback keeps");
    // fewer modes, each pattern's first ones, the first prefix tried that qualifies
    assert_eq!(f.modes.len(), off.vademecum.patterns.len());
    assert!(f.modes.iter().zip(&off.vademecum.patterns).all(|(&k, &n)| k >= 1 && k <= n));
    assert!(f.modes.iter().sum::<usize>() < off.vademecum.n_modes, "{:?}", f.modes);
    // its calibration reaches every load level, within the allowed growth of the whole's
    assert_eq!(f.force_error.len(), off.force_error.len());
    assert!(last(&f.force_error) <= build::FALLBACK_ERROR_GROWTH * last(&off.force_error));
    assert_eq!(report.fallback, Some((f.modes.clone(), last(&f.force_error))));
    // and it is that prefix's calibration: the same table a prefix build with this target keeps
    let (kept, _) = built(Some(last(&f.force_error)));
    assert_eq!(kept.vademecum.patterns, f.modes);
    assert_eq!(kept.force_error, f.force_error);
    // a build that already keeps the fewest modes has nothing cheaper
    assert_eq!(kept.fallback, None);

    // the bundle's arrays keep it; corrupt ones are refused with the rebuild advice
    let scene = Scene::builtin("cube_tear").unwrap();
    let model = tearing::tear_model(&scene, 0).unwrap().0;
    let arrays = off.to_arrays();
    let back = TearOffline::from_arrays(model.clone(), arrays.clone()).unwrap();
    assert_eq!(back.fallback, off.fallback);
    let mut none = arrays.clone();
    none.fallback_modes.clear();
    none.fallback_force_error.clear();
    assert_eq!(TearOffline::from_arrays(model.clone(), none).unwrap().fallback, None);
    let n = &off.vademecum.patterns;
    for modes in [vec![n[0] + 1, 1, 1], vec![0, 1, 1], vec![5], n.clone()] {
        let mut a = arrays.clone();
        a.fallback_modes = modes.clone();
        let e = TearOffline::from_arrays(model.clone(), a).unwrap_err();
        assert!(e.contains("fallback_modes") && e.contains("rebuild"), "{modes:?}: {e}");
    }
    let mut a = arrays;
    a.fallback_force_error = vec![1.0, 0.2, 0.5, 0.3];
    let e = TearOffline::from_arrays(model, a).unwrap_err();
    assert!(e.contains("fallback_force_error"), "{e}");
}

#[test]
fn the_reduced_integrator_steps_exactly_the_fallback_prefix() {
    let (off, _) = built(None);
    let f = off.fallback.clone().unwrap();
    let sys = AffineSystem::of(&off.model, &off.basis);
    let prefix = Arc::new(off.pattern_prefix(&f.modes, &sys));
    let off = Arc::new(off);
    let limits = StepLimits {
        max_damage_increment: 0.05,
        max_substeps: 8,
    };
    // a pull along the load with some across it, then back: damage grows, sub-steps split
    let pulls: Vec<[f64; 3]> = (0..14).map(|k| if k < 10 { [1.0, 0.3, -0.2] } else { [-1.0, 0.0, 0.1] }).collect();
    for variant in [Variant::Simplified, Variant::Full] {
        let mut reduced = OnlineTear::new(off.clone(), variant, limits);
        reduced.set_reduced(true);
        let mut small = OnlineTear::new(prefix.clone(), Variant::Simplified, limits);
        for (k, &ds) in pulls.iter().enumerate() {
            let (a, b) = (reduced.step_pull(ds), small.step_pull(ds));
            assert_eq!(a.substeps, b.substeps, "{variant:?} step {k}");
            let (u, v) = (reduced.displacement_vec(), small.displacement_vec());
            let scale = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let diff = u.iter().zip(&v).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            assert!(diff <= 1e-12 * scale, "{variant:?} step {k}: {diff:e} of {scale:e}");
            assert!(reduced.state.iter().zip(&small.state).all(|(x, y)| (x.g - y.g).abs() < 1e-12));
        }
        // its estimate is the fallback's calibration (at the first level at or past |s|₂, times
        // |s|₁/|s|₂), the scene's setting's when it returns
        let s = [0.5, 0.1, 0.0];
        let l2 = (0.25f64 + 0.01).sqrt();
        let at = f.force_error.iter().find(|r| r[0] >= l2 * (1.0 - 1e-9)).unwrap()[1];
        let estimate = reduced.force_error_for(s).unwrap();
        assert!((estimate - at * 0.6 / l2).abs() < 1e-15, "{estimate} vs {at}");
        reduced.set_reduced(false);
        assert_eq!(reduced.force_error_for(s), off.force_error_for(s));
    }
}

fn jaws(dz: f64) -> ToolInput {
    ToolInput {
        kind: ToolKind::Grasper,
        position_m: [1.0, 1.0, 1.0 + dz],
        closure: 1.0,
        ..ToolInput::default()
    }
}

#[test]
fn a_session_falls_back_mid_pull_without_a_jump_and_returns() {
    let scene = Scene::builtin("cube_tear").unwrap();
    let built = offline::build_organ(&scene, 0, &BuildOptions::for_scene(&scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), &scene, &built).unwrap();
    let bundle = Arc::new(bundle::load_bundle(dir.path()).unwrap());
    let stored = TearOffline::from_arrays(tearing::tear_model(&scene, 0).unwrap().0, (*bundle.tear[0]).clone()).unwrap();
    let fallback = stored.fallback.clone().expect("the stored bundle keeps its fallback");
    let run = |switch: Option<(usize, usize)>| -> Vec<TickState> {
        let mut p = Pipeline::for_scene(&scene, std::slice::from_ref(&bundle)).unwrap();
        (0..=600)
            .map(|k| {
                if let Some((down, up)) = switch {
                    if k == down {
                        p.set_fidelity(Fidelity::Reduced);
                    }
                    if k == up {
                        p.set_fidelity(Fidelity::Full);
                    }
                }
                p.tick(&jaws(0.05 * k.min(500) as f64 / 500.0))
            })
            .collect()
    };
    let full = run(None);
    let mixed = run(Some((200, 400)));
    let fz = |s: &TickState| s.force_n[2];
    // the same answers until the switch; then no jump: each tick's change stays the size of the
    // full run's
    assert_eq!(full[..200], mixed[..200]);
    let step = |v: &[TickState], k: usize| (fz(&v[k]) - fz(&v[k - 1])).abs();
    let typical = (150..450).map(|k| step(&full, k)).fold(0.0, f64::max);
    for k in 195..410 {
        assert!(
            step(&mixed, k) <= 2.0 * typical + 1e-12,
            "tick {k}: {} N against {typical} N",
            step(&mixed, k)
        );
    }
    // reduced and back, the force for the same pull stays within both settings' calibrated
    // errors of the scene's (each is within its own of the full-order model's), and each
    // force's estimate is within its setting's envelope (times at most √3 for a mixed pull)
    let bound = last(&fallback.force_error) + last(&stored.force_error);
    for k in (210..=600).step_by(10) {
        let (a, b) = (fz(&mixed[k]), fz(&full[k]));
        assert!((a - b).abs() <= bound * b.abs(), "tick {k}: {a} N against {b} N");
        let envelope = if (200..400).contains(&k) {
            &fallback.force_error
        } else {
            &stored.force_error
        };
        let e = mixed[k].force_error_n.expect("a held force has an estimate");
        assert!(
            e > 0.0 && e <= last(envelope) * 3f64.sqrt() * a.abs() * (1.0 + 1e-9),
            "tick {k}: {e} N"
        );
    }
    // the reduced ticks' estimates are the fallback's, not the scene's setting's
    assert!((200..400).any(|k| mixed[k].force_error_n != full[k].force_error_n));
}
