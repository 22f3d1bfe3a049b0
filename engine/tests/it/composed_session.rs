//! Effects composed on different organs of one session (issue 46): `scenes/effects/
//! tear_and_cut.toml` cuts the seed's patch with a scalpel while a grasper tears a cube beside
//! it, both hands in the same ticks. Each organ's bundle holds only its own effect's data, and
//! each hand gets, tick for tick and bit for bit, what the same hand gets in a session of its
//! effect alone on the same offline data: composing on different organs changes nothing on
//! either — and both effects happen (the cube tears, the patch is cut).

use crate::common;
use std::sync::Arc;

use vademecum_engine::bundle::{self, LoadedBundle};
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::{Events, Pipeline, PipelineError, TickState, ToolInput, ToolKind};
use vademecum_engine::scene::Scene;

fn composed_text() -> String {
    std::fs::read_to_string(common::repo_root().join("scenes/effects/tear_and_cut.toml")).unwrap()
}

/// The composed scene with only organ `organ`, the tool `tool` and the effect `effect`: the
/// session of one effect alone.
fn alone(organ: usize, tool: &str, effect: &str) -> Scene {
    let mut t: toml::Table = toml::from_str(&composed_text()).unwrap();
    let organs = t["organs"].as_array().unwrap()[organ].clone();
    t.insert("organs".into(), toml::Value::Array(vec![organs]));
    let tools: Vec<toml::Value> = t["tools"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|v| v["name"].as_str() == Some(tool))
        .cloned()
        .collect();
    t.insert("tools".into(), toml::Value::Array(tools));
    let mut fx = toml::Table::new();
    fx.insert(effect.into(), true.into());
    t.insert("effects".into(), toml::Value::Table(fx));
    Scene::from_toml(&toml::to_string(&t).unwrap(), "alone.toml").unwrap()
}

/// Organ `index` of `scene` built, written and loaded back as a session would.
fn bundle(scene: &Scene, index: usize) -> Arc<LoadedBundle> {
    let built = offline::build_organ(scene, index, &BuildOptions::for_scene(scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), scene, &built).unwrap();
    Arc::new(bundle::load_bundle(dir.path()).unwrap())
}

const H: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Tick `k` of the two-hand script: the scalpel (tool 0) goes down the plane x = 4 through
/// the patch's top row in 1,200 ticks, upright, and stays; the grasper (tool 1) closes on the
/// cube's corner (9, 1, 1) and pulls it up 0.8 m in 2,000 ticks.
fn hands(k: usize) -> [ToolInput; 2] {
    let z = 5.1 - 1.2 * (k.min(1200) as f64) / 1200.0;
    let scalpel = ToolInput {
        tool: 0,
        kind: ToolKind::Scalpel,
        position_m: [4.0, -0.1, z],
        blade_end_m: [4.0, 1.1, z],
        orientation: [H, 0.0, 0.0, -H],
        ..ToolInput::default()
    };
    let grasper = ToolInput {
        tool: 1,
        kind: ToolKind::Grasper,
        position_m: [9.0, 1.0, 1.0 + 0.8 * (k.min(2000) as f64) / 2000.0],
        closure: 1.0,
        ..ToolInput::default()
    };
    [scalpel, grasper]
}

const TICKS: usize = 2400;

#[test]
fn a_scalpel_cuts_one_organ_while_a_grasper_tears_another_each_as_if_alone() {
    let scene = Scene::from_toml(&composed_text(), "tear_and_cut.toml").unwrap();
    assert_eq!(scene.cut_organ(), Some(0));
    let (patch, cube) = (bundle(&scene, 0), bundle(&scene, 1));
    // each organ's bundle holds its own effect's offline data only (the cut stage's report,
    // the tearing vademecum)
    assert!(patch.manifest.info.get("cut").is_some() && patch.tear.is_empty());
    assert!(cube.manifest.info.get("cut").is_none() && cube.cut_basis.is_none() && !cube.tear.is_empty());

    let mut both = Pipeline::for_scene(&scene, &[patch.clone(), cube.clone()]).unwrap();
    assert_eq!(both.effect_names(), ["palpation", "tearing", "cutting"]);
    assert!(both.accepts(ToolKind::Scalpel) && both.accepts(ToolKind::Grasper) && !both.accepts(ToolKind::Probe));
    let mut cut = Pipeline::for_scene(&alone(0, "scalpel", "cutting"), &[patch]).unwrap();
    let mut tear = Pipeline::for_scene(&alone(1, "grasper", "tearing"), &[cube]).unwrap();
    // the cut lands at ticks fixed by the blade's path, as in a headless run
    for p in [&mut both, &mut cut, &mut tear] {
        p.set_deterministic(true);
    }
    let status = both.cut_status().unwrap();

    let (mut seen_cut, mut seen_tear) = (0u32, 0u32);
    for k in 0..TICKS {
        let tools = hands(k);
        let mut states = [TickState::default(); 2];
        both.tick_tools(&tools, &mut states);
        let scalpel = cut.tick(&ToolInput { tool: 0, ..tools[0] });
        let grasper = tear.tick(&ToolInput { tool: 0, ..tools[1] });
        assert_eq!(states[0].force_n, scalpel.force_n, "tick {k}: the scalpel's force");
        assert_eq!(states[0].events, scalpel.events, "tick {k}: the scalpel's events");
        assert_eq!(states[0].blade, scalpel.blade, "tick {k}: the blade's force");
        assert_eq!(states[0].force_error_n, scalpel.force_error_n, "tick {k}");
        assert_eq!(states[1].force_n, grasper.force_n, "tick {k}: the grasper's force");
        assert_eq!(states[1].events, grasper.events, "tick {k}: the grasper's events");
        assert_eq!(states[1].force_error_n, grasper.force_error_n, "tick {k}");
        seen_cut |= states[0].events.0;
        seen_tear |= states[1].events.0;
    }
    // both effects happened, each on its own organ
    assert!(
        seen_cut & Events::CUT_STARTED != 0 && seen_cut & Events::CUT_ADVANCED != 0,
        "{seen_cut:#b}"
    );
    assert!(status.cells.load(std::sync::atomic::Ordering::Relaxed) >= 2);
    assert!(
        seen_tear & Events::GRASPED != 0 && seen_tear & Events::TISSUE_TORN != 0,
        "{seen_tear:#b}"
    );
    // and neither hand saw the other's events
    assert_eq!(seen_cut & (Events::GRASPED | Events::TEARING | Events::TISSUE_TORN), 0);
    assert_eq!(seen_tear & (Events::CUT_STARTED | Events::CUT_ADVANCED | Events::BLADE_IN_CUT), 0);
}

#[test]
fn a_hand_that_sends_nothing_stays_where_it_was() {
    let scene = Scene::from_toml(&composed_text(), "tear_and_cut.toml").unwrap();
    let (patch, cube) = (bundle(&scene, 0), bundle(&scene, 1));
    let [scalpel, grasper] = hands(0);
    let pulled = ToolInput {
        position_m: [9.0, 1.0, 1.05],
        ..grasper
    };
    // the grasper takes hold and pulls; then 50 ticks move only the scalpel (above the
    // patch), or the grasper sends its state again 50 times: the same grasp either way — a
    // tick without the grasper's state neither releases the grasp nor reloads it
    let mut answers = Vec::new();
    for only_scalpel in [true, false] {
        let mut p = Pipeline::for_scene(&scene, &[patch.clone(), cube.clone()]).unwrap();
        assert!(p.tick(&grasper).events.has(Events::GRASPED));
        let mut forces = vec![p.tick(&pulled).force_n];
        for k in 0..50 {
            let s = p.tick(if only_scalpel { &scalpel } else { &pulled });
            if only_scalpel {
                assert_eq!(s.force_n, [0.0; 3], "tick {k}: the scalpel feels nothing of the grasp");
            }
            assert!(!s.events.has(Events::RELEASED), "tick {k}");
        }
        let again = p.tick(&pulled);
        assert!(!again.events.has(Events::RELEASED) && again.force_n[2] < 0.0, "{:?}", again.force_n);
        forces.push(again.force_n);
        answers.push(forces);
    }
    assert_eq!(answers[0], answers[1]);
}

#[test]
fn effects_on_one_organ_and_with_large_deformations_are_refused_with_their_reason() {
    // every organ tears: nothing is left to cut
    let text = common::with_keys(
        &composed_text(),
        &[(
            "organs[0].materials[0].damage",
            toml::Value::Table(toml::from_str("alpha = 0.1\nbeta = 0.0").unwrap()),
        )],
    );
    let err = Scene::from_toml(&text, "s.toml").unwrap_err().to_string();
    assert!(err.contains("every organ has a damage law"), "{err}");
    // cuts planned on the organ that tears
    let mut t: toml::Table = toml::from_str(&composed_text()).unwrap();
    let cuts = t["organs"][0]["cuts"].clone();
    t["organs"].as_array_mut().unwrap()[1]
        .as_table_mut()
        .unwrap()
        .insert("cuts".into(), cuts);
    let err = Scene::from_toml(&toml::to_string(&t).unwrap(), "s.toml").unwrap_err().to_string();
    assert!(err.contains("only the cut organ has cuts"), "{err}");
    // tearing with large deformations stays refused by the pipeline
    let scene = Scene::builtin("cube_tear").unwrap();
    let large = common::with_keys(&scene.source, &[("effects.deformation", "large".into())]);
    let large = Scene::from_toml(&large, "large.toml").unwrap();
    match Pipeline::for_scene(&large, &[bundle(&scene, 0)]) {
        Err(PipelineError::Unsupported(why)) => assert!(why.contains("large deformations"), "{why}"),
        Err(other) => panic!("refused for another reason: {other}"),
        Ok(_) => panic!("tearing with large deformations is not composed yet"),
    }
}
