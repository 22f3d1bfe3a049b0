//! `build --target-error` on a cutting scene: the largest sliver threshold whose local-fields
//! force stays within the target of the full XFEM's on the scene's cut (the study's cutting
//! sweep, `docs/accuracy.md`), on SOFA's liver cut by one stroke (`liver_cut`).

use crate::common;

use vademecum_engine::bundle;
use vademecum_engine::scene::Scene;
use vademecum_engine::xfem::accuracy::{Reference, TARGET_SLIVERS, sliver_for_target};

#[test]
fn a_target_error_keeps_the_largest_sliver_threshold_whose_force_meets_it() {
    if common::shared_data().is_none() {
        return;
    }
    let scene = Scene::builtin("liver_cut").unwrap();
    let model = scene.organ_model(0).unwrap();
    let params = scene.spec.fidelity.xfem.params();
    let cuts = scene.organ_cuts(0).unwrap();
    let reference = Reference::of(&cuts, &model, &params, |_, _| {}).unwrap();
    assert!(
        !reference.contacts.is_empty() && reference.enriched.len() > 20,
        "{:?}",
        reference.contacts
    );
    // a loose target: the cheapest threshold that changes the model, if within it
    let loose = sliver_for_target(&cuts, &model, &params, 10.0, &reference).unwrap();
    assert_eq!(loose.tried.len(), 1, "{loose:?}");
    assert_eq!(loose.sliver, loose.tried[0].0);
    // a target no larger threshold meets: the scene's own (exact) rule, every one tried, each
    // enriching fewer nodes and erring more than the target
    let strict = sliver_for_target(&cuts, &model, &params, 1e-9, &reference).unwrap();
    assert_eq!(strict.sliver, params.sliver);
    assert!(!strict.tried.is_empty(), "{strict:?}");
    for &(s, n, e) in &strict.tried {
        assert!(TARGET_SLIVERS.contains(&s) && s > params.sliver);
        assert!(n < reference.enriched.len() && e > 1e-9, "{strict:?}");
    }
    // between: the first threshold (cheapest first) within the target
    let (s, _, e) = *strict.tried.last().unwrap();
    let mid = sliver_for_target(&cuts, &model, &params, e, &reference).unwrap();
    let kept = strict.tried.iter().find(|r| r.2 <= e).unwrap().0;
    assert_eq!(mid.sliver, kept, "{mid:?}");
    assert!(kept >= s);
}

/// The bundle keeps the sliver rule the target chose and a session cuts with it; a bundle
/// whose stored rule is no fraction is refused with the rebuild advice.
#[test]
fn the_bundle_keeps_the_chosen_sliver_rule_and_a_session_cuts_with_it() {
    use std::sync::Arc;
    use vademecum_engine::offline::{self, BuildOptions};
    use vademecum_engine::pipeline::Pipeline;
    if common::shared_data().is_none() {
        return;
    }
    let scene = Scene::builtin("liver_cut").unwrap();
    let opts = BuildOptions {
        cut_target_error: Some(0.01),
        ..BuildOptions::for_scene(&scene, true)
    };
    let built = offline::build_organ(&scene, 0, &opts, &mut |_| {}).unwrap();
    let cut = built.report.cut.clone().unwrap();
    let t = cut.target.clone().unwrap();
    assert!(cut.sliver > scene.spec.fidelity.xfem.sliver && cut.sliver == t.sliver, "{cut:?}");
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), &scene, &built).unwrap();
    let bundle = bundle::load_bundle(dir.path()).unwrap();
    assert_eq!(bundle.cut_sliver(), Ok(Some(cut.sliver)));
    Pipeline::for_scene(&scene, &[Arc::new(bundle.clone())]).expect("a session cuts with the stored rule");
    // a bundle built without a target says nothing: the scene's rule
    let plain = offline::build_organ(&scene, 0, &BuildOptions::for_scene(&scene, true), &mut |_| {}).unwrap();
    assert_eq!(plain.report.cut.as_ref().map(|c| c.sliver), Some(scene.spec.fidelity.xfem.sliver));
    // a stored rule that is no fraction
    let mut bad = bundle;
    bad.manifest.info["cut"]["sliver"] = serde_json::json!(0.7);
    let e = bad.cut_sliver().unwrap_err();
    assert!(e.to_string().contains("rebuild"), "{e}");
    let Err(e) = Pipeline::for_scene(&scene, &[Arc::new(bad)]) else {
        panic!("a bundle with a sliver rule of 0.7 was accepted");
    };
    let e = e.to_string();
    assert!(e.contains("sliver"), "{e}");
}
