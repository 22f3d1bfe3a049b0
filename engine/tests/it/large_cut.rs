//! An organ cut and deformed largely at once (issue 46, "Effects compose on one organ"): a
//! block of St Venant–Kirchhoff tissue clamped at its base, cut down the middle of its top
//! half (a cut on cell faces), pressed beside the cut — the composed law (the lattice's
//! stiffening of the uncut organ times the cut's linear force) against Newton on the organ cut
//! by split nodes, and a session that cuts the organ with its scalpel and presses beside the
//! cut with its probe serving exactly that law.

use crate::common;
use std::sync::Arc;

use vademecum_engine::bundle::{self, LoadedBundle};
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::{self, Events, Pipeline, ToolInput, ToolKind};
use vademecum_engine::scene::Scene;
use vademecum_engine::study::large_cut::{composed_states, nodes_beside};
use vademecum_engine::xfem::Enrichment;

/// The built-in `large_cut`: a flap 2 × 1 × 1 m (8 × 4 × 4 hexahedra, E = 1 kPa, ν = 0.3,
/// deforming largely) clamped at its base and touched on its top; the scalpel's planned cut goes
/// down the plane x = 1 (a plane of cell faces) through the top half, across the whole depth.
fn scene_text() -> String {
    Scene::builtin("large_cut").unwrap().source
}

fn scene(text: &str) -> Scene {
    Scene::from_toml(text, "large_cut.toml").unwrap()
}

/// The organ built, written and loaded back as a session would.
fn bundle(scene: &Scene) -> Arc<LoadedBundle> {
    let built = offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), scene, &built).unwrap();
    Arc::new(bundle::load_bundle(dir.path()).unwrap())
}

#[test]
fn the_composed_law_beside_a_cut_is_within_its_estimate_of_newton_on_the_split_organ() {
    let scene = scene(&scene_text());
    assert_eq!(scene.cut_organ(), Some(0), "a scene of one organ that deforms largely cuts it");
    let b = bundle(&scene);
    let lattice = b.anm.as_ref().expect("the organ deforms largely: its bundle holds a lattice");
    let params = BuildOptions::for_scene(&scene, true).large.unwrap();
    let model = scene.organ_model(0).unwrap();
    let cut = scene.planned_cuts().unwrap().remove(0);
    let enr = Enrichment::from_cut(&model.mesh, &cut, &pipeline::cut_params(&scene, None)).unwrap();
    assert!(!enr.is_empty());
    let nodes = nodes_beside(&model, &enr, lattice, 12);
    assert!(nodes.len() >= 8, "{nodes:?}");
    let states = composed_states(&model, &enr, lattice, &params, &nodes, |_, _| {}).unwrap();
    let within: Vec<_> = states.iter().filter(|s| s.sample().within_force).collect();
    assert!(
        within.len() >= 3 * nodes.len(),
        "{} states within the lattice's force",
        within.len()
    );
    // the cut reaches these presses: the cut organ is softer there, and the stiffening differs
    let softest = states.iter().map(|s| s.softening).fold(1.0, f64::max);
    assert!(softest > 1.2, "the cut softens the presses beside it by at most {softest}");
    let worst = |e: &dyn Fn(&&vademecum_engine::study::large_cut::ComposedState) -> f64| within.iter().map(e).fold(0.0, f64::max);
    let (composed, linear_cut, uncut_large) = (
        worst(&|s| s.error()),
        worst(&|s| s.linear_cut_error()),
        worst(&|s| s.uncut_large_error()),
    );
    let composition = worst(&|s| s.composition_error().unwrap_or(0.0));
    let bounded = within.iter().filter(|s| s.error() <= s.estimate).count();
    eprintln!(
        "{} presses beside the cut, {} states within the lattice's force: largest error (of the cut's linear force) composed {composed:.4} \
         (the composition alone {composition:.4}), the linear cut model {linear_cut:.4}, the large law ignoring the cut {uncut_large:.4}; \
         softening up to {softest:.3}; the estimate bounds {bounded} of {}",
        nodes.len(),
        within.len(),
        within.len()
    );
    for s in &states {
        eprintln!(
            "node {:4} depth {:.4} λ {:.2}: served {:.4} truth {:.4} (uncut {:?}) softening {:.3} error {:.4} estimate {:.4}",
            s.node,
            s.depth_m,
            s.lambda,
            s.served,
            s.truth,
            s.uncut_truth.map(|r| (r * 1e4).round() / 1e4),
            s.softening,
            s.error(),
            s.estimate
        );
    }
    // the composition is worth its name: better than either effect alone
    assert!(
        composed < 0.5 * linear_cut,
        "composed {composed} against the linear cut model's {linear_cut}"
    );
    assert!(
        composed < 0.5 * uncut_large,
        "composed {composed} against the uncut large law's {uncut_large}"
    );
    // and its estimate bounds the true error in at least 95 % of the states
    assert!(bounded as f64 >= 0.95 * within.len() as f64, "{bounded} of {}", within.len());
    // the interaction term the estimate adds bounds the composition's own error (the uncut
    // organ's exact stiffening applied to the cut's force), with no help from the lattice's
    let exact: Vec<_> = states.iter().filter_map(|s| s.uncut_truth.map(|r| (s, r))).collect();
    let covered = exact
        .iter()
        .filter(|(s, r)| s.composition_error().unwrap() <= (r - 1.0).abs() * (s.softening - 1.0))
        .count();
    eprintln!(
        "the interaction term bounds the composition's own error in {covered} of {} states",
        exact.len()
    );
    assert!(
        exact.len() >= within.len() / 2 && covered as f64 >= 0.95 * exact.len() as f64,
        "{covered} of {}",
        exact.len()
    );
}

const H: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// The scalpel (tool 0) at depth `z` of its stroke down the plane x = 1, upright, its blade
/// across the block.
fn scalpel(z: f64) -> ToolInput {
    ToolInput {
        tool: 0,
        kind: ToolKind::Scalpel,
        position_m: [1.0, -0.1, z],
        blade_end_m: [1.0, 1.1, z],
        orientation: [H, 0.0, 0.0, -H],
        ..ToolInput::default()
    }
}

/// The probe (tool 1) at (x, 0.5) on the top, `depth` m into it (its sphere's bottom).
fn probe(x: f64, depth: f64) -> ToolInput {
    ToolInput {
        tool: 1,
        kind: ToolKind::Probe,
        position_m: [x, 0.5, 1.0 + 0.05 - depth],
        ..ToolInput::default()
    }
}

/// The probe's force pressing `depth` in at x after a straight press from above (its proxy
/// settled), and the tick's error estimate.
fn press(p: &mut Pipeline, x: f64, depth: f64) -> ([f64; 3], f64) {
    p.reset();
    let mut last = None;
    for k in 0..=40 {
        let s = p.tick(&probe(x, -0.02 + (depth + 0.02) * k as f64 / 40.0));
        last = Some(s);
    }
    let s = last.unwrap();
    assert!(s.events.has(Events::CONTACT), "{s:?}");
    (s.force_n, s.force_error_n.unwrap())
}

/// The scalpel's stroke: down from above the top to z = 0.5 in 600 ticks, then out.
fn stroke(p: &mut Pipeline) {
    for k in 0..=600 {
        p.tick(&scalpel(1.1 - 0.6 * k as f64 / 600.0));
    }
    for k in 0..=100 {
        p.tick(&scalpel(0.5 + 0.7 * k as f64 / 100.0));
    }
}

#[test]
fn a_session_cuts_an_organ_that_deforms_largely_and_serves_the_lattice_stiffening_of_the_cut_force() {
    let large = scene(&scene_text());
    let linear = scene(&common::with_keys(&scene_text(), &[("organs[0].deformation", "linear".into())]));
    let b = bundle(&large);
    let mut composed = Pipeline::for_scene(&large, std::slice::from_ref(&b)).unwrap();
    let mut cut_only = Pipeline::for_scene(&linear, std::slice::from_ref(&b)).unwrap();
    composed.set_deterministic(true);
    cut_only.set_deterministic(true);
    let presses = [(0.875, 0.1), (1.125, 0.1), (0.875, 0.2), (0.75, 0.15), (1.5, 0.1)];
    let before: Vec<_> = presses
        .iter()
        .map(|&(x, d)| (press(&mut composed, x, d), press(&mut cut_only, x, d)))
        .collect();
    stroke(&mut composed);
    stroke(&mut cut_only);
    let (a, c) = (composed.cut_status().unwrap(), cut_only.cut_status().unwrap());
    let cracked = |s: &pipeline::cutting::CutStatus| s.nodes.load(std::sync::atomic::Ordering::Relaxed);
    assert!(cracked(&a) > 0, "the stroke cut the organ");
    assert_eq!(cracked(&a), cracked(&c), "the same stroke makes the same cut");
    let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    for (&(x, d), ((large_uncut, _), (linear_uncut, _))) in presses.iter().zip(&before) {
        let (f, estimate) = press(&mut composed, x, d);
        let (f_cut, _) = press(&mut cut_only, x, d);
        // the lattice's stiffening at this contact, as the uncut organ's palpation served it
        let r = norm(*large_uncut) / norm(*linear_uncut);
        for k in 0..3 {
            assert!(
                (f[k] - r * f_cut[k]).abs() <= 1e-9 * norm(f),
                "at x = {x}, depth {d}: {f:?} against {r} × {f_cut:?}"
            );
        }
        // the interaction of the two corrections is in the estimate
        let interaction = (r - 1.0).abs() * norm(std::array::from_fn(|k| f_cut[k] - linear_uncut[k]));
        assert!(
            estimate >= interaction,
            "at x = {x}: estimate {estimate} below the interaction {interaction}"
        );
        eprintln!(
            "x = {x}, depth {d}: composed {:.4} N (the uncut large law {:.4}, the linear cut {:.4}, linear {:.4}; r = {r:.4}), estimate {estimate:.4} N",
            norm(f),
            norm(*large_uncut),
            norm(f_cut),
            norm(*linear_uncut)
        );
    }
}

#[test]
fn co_rotational_cutting_of_an_organ_that_deforms_largely_is_refused_with_its_reason() {
    let text = common::with_keys(&scene_text(), &[("fidelity.cutting", "corotational_xfem".into())]);
    let err = Scene::from_toml(&text, "s.toml").unwrap_err().to_string();
    assert!(
        err.contains("fidelity.cutting") && err.contains("deforms largely") && err.contains("pgd_xfem"),
        "{err}"
    );
}

#[test]
fn an_organ_marked_cuttable_is_the_one_cut_and_the_mark_is_checked() {
    // the flap beside a linear block: by default the linear organ is cut, the mark moves the
    // scalpel to the flap that deforms largely
    let mut t: toml::Table = toml::from_str(&scene_text()).unwrap();
    let mut block = t["organs"][0].as_table().unwrap().clone();
    block.insert("name".into(), "block".into());
    block.remove("deformation");
    block.remove("cuts");
    block.insert(
        "mesh".into(),
        toml::from_str::<toml::Table>(
            "builtin = \"block\"\norigin = [3.0, 0.0, 0.0]\nsize = [1.0, 1.0, 1.0]\ndivisions = [2, 2, 2]\ncell = \"hex8\"",
        )
        .unwrap()
        .into(),
    );
    t.get_mut("organs").unwrap().as_array_mut().unwrap().insert(0, block.into());
    let text = toml::to_string(&t).unwrap();
    // the flap's planned cut belongs to the cut organ: unmarked, that is the linear block
    let err = Scene::from_toml(&text, "two.toml").unwrap_err().to_string();
    assert!(err.contains("only the cut organ has cuts"), "{err}");
    let marked = common::with_keys(&text, &[("organs[1].cuttable", true.into())]);
    let scene = Scene::from_toml(&marked, "two.toml").unwrap();
    assert_eq!(scene.cut_organ(), Some(1));
    assert!(scene.organ_large(1) && !scene.organ_large(0));
    // two marks, a mark with cutting off, a mark on an organ that tears: refused at the mark
    let two = common::with_keys(&marked, &[("organs[0].cuttable", true.into())]);
    let err = Scene::from_toml(&two, "two.toml").unwrap_err().to_string();
    assert!(err.contains("organs[1].cuttable") && err.contains("one organ"), "{err}");
    let off = common::with_keys(
        &scene_text(),
        &[("organs[0].cuttable", true.into()), ("effects.cutting", false.into())],
    );
    let err = Scene::from_toml(&off, "off.toml").unwrap_err().to_string();
    assert!(err.contains("cuttable") && err.contains("cutting is off"), "{err}");
    let damage = toml::Value::Table(toml::from_str("alpha = 0.1\nbeta = 0.0").unwrap());
    let torn = common::with_keys(
        &marked,
        &[
            ("organs[1].materials[0].damage", damage),
            ("organs[1].deformation", "linear".into()),
            ("effects.tearing", true.into()),
        ],
    );
    let err = Scene::from_toml(&torn, "torn.toml").unwrap_err().to_string();
    assert!(err.contains("organs[1].cuttable") && err.contains("tears"), "{err}");
}
