//! The error estimate of a cut organ's force (`force_error_n`): with the seed's local fields the
//! linear law's round-off (the cut's compliance is the full XFEM's); with the bare enrichment
//! the build's calibration of its force error at the scene's cut, checked against the full
//! XFEM at points between the cracked nodes it was calibrated at (seed 000 §3.2–3.3).

use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::time::{Duration, Instant};

use vademecum_engine::bundle;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::{Pipeline, ToolInput, ToolKind};
use vademecum_engine::scene::Scene;
use vademecum_engine::study::estimate::{self, Coverage};

/// `patch_cut` (§3.5.1) with the bare enrichment on the vademecum's modes.
fn bare_patch() -> Scene {
    let text = Scene::builtin("patch_cut").unwrap().source.replace(
        "[fidelity]\nlocking = \"none\"",
        "[fidelity]\nlocking = \"none\"\n\n[fidelity.xfem]\ndiscontinuous = \"bare\"",
    );
    assert!(text.contains("\"bare\""));
    Scene::from_toml(&text, "patch_cut_bare.toml").unwrap()
}

fn norm(f: [f64; 3]) -> f64 {
    f.iter().map(|x| x * x).sum::<f64>().sqrt()
}

#[test]
fn the_bare_enrichment_carries_its_calibrated_force_error_and_it_bounds_the_full_xfem() {
    let scene = bare_patch();
    let built = offline::build_organ(&scene, 0, &BuildOptions::for_scene(&scene, true), &mut |_| {}).unwrap();
    let e = built
        .report
        .cut
        .as_ref()
        .and_then(|c| c.bare_force_error)
        .expect("a bare build calibrates");
    // the bare enrichment is far from the full XFEM at the cut (tens of per cent: the study's
    // cutting sweep), and finite
    assert!(e > 0.05 && e < 10.0, "{e}");
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), &scene, &built).unwrap();
    let bundle = bundle::load_bundle(dir.path()).unwrap();
    assert_eq!(bundle.cut_bare_force_error(), Ok(Some(e)));

    // between the cracked nodes: the estimate bounds the full XFEM's force (measured: 48 of
    // 48, at a median of 8 times the error; calibrated at the cracked nodes alone, 45 of 48)
    let model = scene.organ_model(0).unwrap();
    let all = estimate::cut_samples(&scene, &model, &bundle, 16, |_, _| {}).unwrap();
    let of = |m: &str| all.iter().copied().filter(|s| s.model == m).collect::<Vec<_>>();
    // and on the cut halfway, which the calibration never saw (measured: 48 of 48, 9 times)
    let halfway = Coverage::of(&of(estimate::CUT_BARE_HALFWAY));
    assert!(halfway.samples == 48 && halfway.fraction() >= 0.95, "{halfway:?}");
    let samples = of(estimate::CUT_BARE);
    let c = Coverage::of(&samples);
    assert_eq!(c.samples, 48);
    assert!(c.fraction() >= 0.95 && c.median_ratio > 1.0, "{c:?}");
    // and the bare model is really off there: the estimate is not bounding a zero
    assert!(c.max_relative_error > 0.05, "{c:?}");

    // a session attaches it: the scalpel pressed down the patch until the cut reaches the
    // tick, then pressed at the cut, the force's estimate e·|f|
    let mut p = Pipeline::for_scene(&scene, &[Arc::new(bundle.clone())]).unwrap();
    let status = p.cut_status().unwrap();
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let blade = |z: f64| ToolInput {
        kind: ToolKind::Scalpel,
        position_m: [4.0, -0.1, z],
        blade_end_m: [4.0, 1.1, z],
        orientation: [h, 0.0, 0.0, -h],
        ..ToolInput::default()
    };
    for i in 0..=1200 {
        p.tick(&blade(5.1 - 1.2 * f64::from(i) / 1200.0));
        std::thread::sleep(Duration::from_millis(1));
    }
    let start = Instant::now();
    while status.cells.load(Relaxed) < 2 && start.elapsed() < Duration::from_secs(10) {
        p.tick(&blade(3.9));
        std::thread::sleep(Duration::from_millis(1));
    }
    assert!(status.cells.load(Relaxed) >= 2, "the cut did not reach the model");
    for _ in 0..50 {
        p.tick(&blade(3.9));
        std::thread::sleep(Duration::from_millis(1));
    }
    let s = p.tick(&blade(4.5));
    let f = norm(s.force_n);
    assert!(f > 0.0 && f.is_finite());
    let got = s.force_error_n.expect("the bare model's force carries the calibration");
    assert!((got - e * f).abs() <= 1e-9 * e * f, "{got:e} for {f} N and e = {e}");

    // a bundle without the calibration (built before it) gives none; a corrupt one is refused
    let mut old = bundle.clone();
    old.manifest.info["cut"].as_object_mut().unwrap().remove("bare_force_error");
    assert_eq!(old.cut_bare_force_error(), Ok(None));
    let mut bad = bundle;
    bad.manifest.info["cut"]["bare_force_error"] = serde_json::json!(-1.0);
    let e = bad.cut_bare_force_error().unwrap_err();
    assert!(e.to_string().contains("rebuild"), "{e}");
    assert!(Pipeline::for_scene(&scene, &[Arc::new(bad)]).is_err());
}

#[test]
fn the_local_fields_forces_between_the_cracked_nodes_agree_with_the_full_xfem() {
    let scene = Scene::builtin("patch_cut").unwrap();
    let built = offline::build_organ(&scene, 0, &BuildOptions::for_scene(&scene, true), &mut |_| {}).unwrap();
    assert_eq!(
        built.report.cut.as_ref().unwrap().bare_force_error,
        None,
        "local fields need no calibration"
    );
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), &scene, &built).unwrap();
    let bundle = bundle::load_bundle(dir.path()).unwrap();
    let model = scene.organ_model(0).unwrap();
    let samples = estimate::cut_samples(&scene, &model, &bundle, 8, |_, _| {}).unwrap();
    let c = Coverage::of(&samples);
    assert!(samples.iter().all(|s| s.model == estimate::CUT));
    // the Schur complement of the cracked nodes: round-off, within the 1e-9 estimate
    assert!(c.samples == 24 && c.bounded == 24 && c.max_relative_error < 1e-11, "{c:?}");
}
