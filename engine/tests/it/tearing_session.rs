//! The tearing effect of a session (seed 000 §4.6.2) through the whole pipeline: the grasper
//! takes hold within its jaw width, the pull loads the tissue by displacement control, the
//! damage grows, the grasp is lost when the tissue under the jaws tears and the force fades
//! without a jump; the offline stage survives the bundle bit for bit.

use crate::common;
use std::sync::Arc;

use vademecum_engine::bundle;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::damage::build;
use vademecum_engine::damage::online::{OnlineTear, TearOffline, Variant};
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::tearing::FADE_TICKS;
use vademecum_engine::pipeline::{Events, Pipeline, TickState, ToolInput, ToolKind};
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::tearing;

/// The seed's cube (E = 5 Pa), its upper corner (1, 1, 1) the grasp pulled up, with Simó
/// damage `alpha`, `beta` (0.4, 0.4: the seed's, D tends to 0.6 and never reaches the 0.8
/// threshold; 0.1, 0: the stiffness goes to zero, the cube tears near 20 % strain).
fn cube(alpha: f64, beta: f64, max_force: f64) -> Scene {
    let text = common::with_keys(
        &Scene::builtin("cube_tear").unwrap().source,
        &[
            ("organs[0].materials[0].damage.alpha", alpha.into()),
            ("organs[0].materials[0].damage.beta", beta.into()),
            ("tools[0].max_force", max_force.into()),
        ],
    );
    Scene::from_toml(&text, "cube.toml").unwrap()
}

/// The scene's bundle, built and loaded back as a session would.
fn bundle(scene: &Scene) -> Arc<LoadedBundle> {
    let built = offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {}).unwrap();
    assert!(!built.tear.is_empty(), "a tearing scene's bundle holds the tearing vademecum");
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), scene, &built).unwrap();
    Arc::new(bundle::load_bundle(dir.path()).unwrap())
}

fn jaws(at: [f64; 3], closure: f64) -> ToolInput {
    ToolInput {
        kind: ToolKind::Grasper,
        position_m: at,
        closure,
        ..ToolInput::default()
    }
}

fn up(dz: f64) -> [f64; 3] {
    [1.0, 1.0, 1.0 + dz]
}

fn fz(s: &TickState) -> f64 {
    s.force_n[2]
}

#[test]
fn the_stored_offline_stage_steps_exactly_as_the_built_one() {
    let scene = cube(0.4, 0.4, 1.0);
    let b = bundle(&scene);
    let (model, _) = tearing::tear_model(&scene, 0).unwrap();
    let (settings, limits) = tearing::settings(&scene);
    let (built, _, _) = build::build(model.clone(), &settings, |_, _| {}).unwrap();
    let stored = TearOffline::from_arrays(model, (*b.tear[0]).clone()).unwrap();
    for variant in [Variant::Simplified, Variant::Full] {
        let mut a = OnlineTear::new(Arc::new(built.clone()), variant, limits);
        let mut c = OnlineTear::new(Arc::new(stored.clone()), variant, limits);
        for _ in 0..10 {
            a.step(1.0);
            c.step(1.0);
        }
        assert_eq!(a.displacement_vec(), c.displacement_vec(), "{variant:?}");
    }
}

#[test]
fn the_grasper_takes_hold_pulls_and_lets_go_smoothly() {
    let scene = cube(0.4, 0.4, 1.0);
    let mut p = Pipeline::for_scene(&scene, &[bundle(&scene)]).unwrap();
    assert_eq!(p.effect_names(), ["tearing"], "no probe: the grasper is the only tool");
    assert!(!p.tick(&jaws(up(0.0), 1.0)).events.has(Events::REJECTED_INPUT));

    // closing out of reach (jaw_width 0.2 m) takes nothing
    let mut p = Pipeline::for_scene(&scene, &[bundle(&scene)]).unwrap();
    let far = p.tick(&jaws([1.0, 1.0, 1.3], 1.0));
    assert!(!far.events.has(Events::GRASPED) && far.force_n == [0.0; 3]);
    let open = p.tick(&jaws([1.0, 1.0, 1.3], 0.0));
    assert!(!open.events.has(Events::GRASPED));
    // closing at the corner holds it
    let s = p.tick(&jaws(up(0.0), 1.0));
    assert!(s.events.has(Events::GRASPED) && s.events.has(Events::CONTACT));
    // pulling up 5 cm over 500 ticks: the tissue pulls back, harder as it goes, and damages
    let mut last = 0.0;
    let mut tearing = 0;
    for k in 1..=500 {
        let s = p.tick(&jaws(up(0.05 * k as f64 / 500.0), 1.0));
        assert!(fz(&s) <= last + 1e-12, "tick {k}: the reaction grows with the pull");
        // the jaws hold the corner across the pull too (pulled up, it would slide sideways):
        // a lateral reaction, smaller than the vertical one
        let lateral = s.force_n[0].hypot(s.force_n[1]);
        assert!(lateral <= 0.5 * fz(&s).abs() + 1e-12, "tick {k}: {:?}", s.force_n);
        last = fz(&s);
        // each held force carries its calibrated error estimate: a few per cent at most
        // (tearing_estimate.rs checks it against the full-order model)
        let e = s.force_error_n.expect("a held force has an error estimate");
        assert!(e > 0.0 && e <= 0.1 * fz(&s).abs() + 1e-12, "tick {k}: {e} N on {} N", fz(&s));
        tearing += s.events.has(Events::TEARING) as u32;
        assert!(!s.events.has(Events::TISSUE_TORN), "beta = 0.4 never reaches D = 0.8");
    }
    assert!(last < 0.0 && tearing > 400, "force {last} N, {tearing} ticks of growing damage");
    // holding still: the force settles (the pull is matched) and no damage grows
    let mut held = p.tick(&jaws(up(0.05), 1.0));
    for _ in 0..50 {
        held = p.tick(&jaws(up(0.05), 1.0));
    }
    assert!(!held.events.has(Events::TEARING));
    // opening the jaws: released, the force fades over FADE_TICKS, never by more than its share
    let peak = -fz(&held);
    let s = p.tick(&jaws(up(0.05), 0.0));
    assert!(s.events.has(Events::RELEASED));
    let mut prev = -fz(&s);
    for _ in 0..FADE_TICKS {
        let s = p.tick(&jaws(up(0.05), 0.0));
        let now = -fz(&s);
        assert!(
            now == 0.0 || s.force_error_n.is_none(),
            "a fading force is the fade's, not the tissue's"
        );
        assert!(prev - now <= peak / f64::from(FADE_TICKS) + 1e-9, "a jump of {} N", prev - now);
        prev = now;
    }
    assert!(prev.abs() < 1e-12, "the force is gone: {prev}");
    // and the damage stays: grasping and pulling again, the tissue is softer
    assert!(p.tick(&jaws(up(0.0), 1.0)).events.has(Events::GRASPED));
    let mut again = TickState::default();
    for k in 1..=100 {
        again = p.tick(&jaws(up(0.01 * k as f64 / 100.0), 1.0));
    }
    assert!(!again.events.has(Events::TEARING), "no new damage below the earlier strain");
}

#[test]
fn the_grasp_is_lost_when_the_tissue_under_the_jaws_tears() {
    let scene = cube(0.1, 0.0, 5.0);
    let mut p = Pipeline::for_scene(&scene, &[bundle(&scene)]).unwrap();
    assert!(p.tick(&jaws(up(0.0), 1.0)).events.has(Events::GRASPED));
    let (mut torn_at, mut peak) = (None, 0.0f64);
    let mut forces = Vec::new();
    // a 0.8 m pull over 4 s (the workspace ends 1 m beyond the organ)
    for k in 1..=4000 {
        let s = p.tick(&jaws(up(0.8 * k as f64 / 4000.0), 1.0));
        forces.push(-fz(&s));
        peak = peak.max(-fz(&s));
        if s.events.has(Events::TISSUE_TORN) {
            torn_at = Some(k);
            break;
        }
    }
    let k = torn_at.expect("the cube tears under the jaws");
    // the force then fades: never a jump larger than its share of the fade, down to zero
    let mut prev = *forces.last().unwrap();
    for j in 1..=FADE_TICKS + 5 {
        let s = p.tick(&jaws(up(0.8 * (k + j as usize) as f64 / 4000.0).map(|x| x.min(1.8)), 1.0));
        let now = -fz(&s);
        assert!(prev - now <= peak / f64::from(FADE_TICKS) + 1e-9, "a jump of {} N", prev - now);
        assert!(!s.events.has(Events::GRASPED), "a torn grasp is not taken again");
        prev = now;
    }
    assert!(prev.abs() < 1e-12, "the grasp is lost: {prev} N");
    // closing the jaws again on the torn corner holds nothing
    let _ = p.tick(&jaws(up(0.0), 0.0));
    assert!(!p.tick(&jaws(up(0.0), 1.0)).events.has(Events::GRASPED));
    // the picture the frames read: the torn cell is past the threshold
    let mut pictures = p.take_tear_pictures().unwrap();
    let pic = pictures.read();
    assert!(pic.cell_damage[0] >= pic.torn && !pic.grasped, "{:?}", pic.cell_damage);
}

#[test]
fn the_pull_saturates_at_the_graspers_max_force() {
    let scene = cube(0.4, 0.4, 0.3);
    let mut p = Pipeline::for_scene(&scene, &[bundle(&scene)]).unwrap();
    p.tick(&jaws(up(0.0), 1.0));
    let mut s = TickState::default();
    for k in 1..=1000 {
        s = p.tick(&jaws(up(0.9 * k as f64 / 1000.0), 1.0));
    }
    assert!(s.events.has(Events::FORCE_SATURATED));
    assert!((norm(s.force_n) - 0.3).abs() < 1e-9 && fz(&s) < 0.0, "{:?} N", s.force_n);
}

fn norm(f: [f64; 3]) -> f64 {
    f.iter().map(|x| x * x).sum::<f64>().sqrt()
}

#[test]
fn the_tissue_follows_the_jaws_in_every_direction() {
    let scene = cube(0.4, 0.4, 1.0);
    let b = bundle(&scene);
    // pulled across (x, then −y) and obliquely: the reaction points back against the motion
    for dir in [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.6, 0.0, 0.8]] {
        let mut p = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
        assert!(p.tick(&jaws(up(0.0), 1.0)).events.has(Events::GRASPED));
        let (mut s, mut tearing, mut last) = (TickState::default(), 0, 0.0);
        for k in 1..=500 {
            let d = 0.05 * k as f64 / 500.0;
            s = p.tick(&jaws([1.0 + d * dir[0], 1.0 + d * dir[1], 1.0 + d * dir[2]], 1.0));
            let along = s.force_n.iter().zip(&dir).map(|(f, t)| f * t).sum::<f64>();
            assert!(along <= last + 1e-12, "{dir:?}, tick {k}: the reaction grows against the pull");
            last = along;
            tearing += u32::from(s.events.has(Events::TEARING));
        }
        let along = -last;
        // the jaws hold the grasp still across the motion too: the reaction is mostly, not
        // only, against it (the work f·d of an elastic body is positive)
        assert!(along > 0.0 && along >= 0.5 * norm(s.force_n), "{dir:?}: reaction {:?} N", s.force_n);
        assert!(tearing > 100, "{dir:?}: {tearing} ticks of growing damage");
        // opening: the force fades to zero
        for _ in 0..=FADE_TICKS {
            s = p.tick(&jaws(up(0.05), 0.0));
        }
        assert!(norm(s.force_n) < 1e-12, "{dir:?}: {:?} N after the release", s.force_n);
    }
}

#[test]
fn a_tearing_scene_needs_a_grasper_and_its_bundle_and_refuses_other_tools() {
    let scene = cube(0.4, 0.4, 1.0);
    let b = bundle(&scene);
    let mut p = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    let probe = ToolInput {
        position_m: up(0.0),
        ..ToolInput::default()
    };
    assert!(p.tick(&probe).events.has(Events::REJECTED_INPUT), "no probe in the scene");
    let bad = ToolInput {
        closure: f64::NAN,
        ..jaws(up(0.0), 1.0)
    };
    assert!(p.tick(&bad).events.has(Events::REJECTED_INPUT));
    // without its grasper
    let probe: toml::Table = toml::from_str("kind = \"probe\"\nname = \"grasper\"\nradius = 0.01\nmax_force = 1.0").unwrap();
    let text = common::with_keys(&scene.source, &[("tools[0]", probe.into())]);
    let e = Scene::from_toml(&text, "x.toml").unwrap_err();
    assert_eq!(e.key.as_deref(), Some("effects.tearing"), "{e}");
    assert!(e.to_string().contains("grasper"), "{e}");
    // a bundle without the tearing vademecum (built for a palpation scene)
    let mut stale = (*b).clone();
    stale.tear = Vec::new();
    let e = Pipeline::for_scene(&scene, &[Arc::new(stale)]).unwrap_err();
    assert!(e.to_string().contains("vademecum build"), "{e}");
}
