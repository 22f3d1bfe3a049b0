//! The large-deformation palpation model served online (seed 001): the ANM-POD lattice against
//! full Newton at its positions, its bundle form, and the pipeline that scales the linear
//! vademecum's force by it.

use crate::common;
use std::sync::Arc;

use vademecum_engine::bundle;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::{Events, Fidelity, Pipeline, PipelineError, ToolInput};
use vademecum_engine::rom::palpation::{AnmLattice, AnmLatticeParams, NewtonLaw};
use vademecum_engine::scene::Scene;

/// The built-in cornea on a coarse mesh, asking for large deformations with a small lattice.
fn cornea(large: bool) -> Scene {
    let text = common::with_keys(
        vademecum_engine::scene::builtin("cornea").unwrap(),
        &[
            ("organs[0].mesh.divisions", vec![12, 12, 2].into()),
            ("fidelity.large.positions", 3.into()),
            ("fidelity.large.load_steps", 4.into()),
            ("effects.deformation", if large { "large" } else { "linear" }.into()),
        ],
    );
    Scene::from_toml(&text, ".").unwrap()
}

/// A lattice of `positions` on the coarse cornea: its force, the probe's patch, few steps.
fn small_lattice(positions: usize) -> AnmLatticeParams {
    AnmLatticeParams {
        positions,
        max_force: 0.126,
        patch_radius: 1e-3,
        load_steps: 4,
        modes: 9,
        order: 6,
    }
}

#[test]
fn lattice_paths_give_the_full_model_force_depth_law_at_their_positions() {
    let scene = cornea(false);
    let organ = scene.organ_model(0).unwrap();
    let laws = organ.laws.clone().unwrap();
    let params = small_lattice(3);
    let lattice = AnmLattice::build(&organ, &laws, &params, |_, _| {}).unwrap();
    assert_eq!(lattice.positions.len(), 3);
    let p = &lattice.positions[0];
    // the first position is the accessible node nearest the centroid: on the dome's axis, the
    // load pushing straight down
    assert!(p.normal[2] < -0.99, "{:?}", p.normal);

    // full Newton with the same load at the same position
    let newton = NewtonLaw::at(&organ, &laws, &AnmLatticeParams { load_steps: 8, ..params }, p.node).unwrap();
    assert_eq!(newton.steps.len(), 8, "{newton:?}");
    let curve = newton.steps;
    let mut zeta = vec![0.0; lattice.max_modes()];
    for &(l, d) in &curve {
        // the lattice's law gives back the load factor Newton needed for that depth
        let (lambda, extrapolated) = p.load_at_depth(d, &mut zeta);
        assert!(!extrapolated);
        assert!((lambda - l).abs() < 1e-3 * l, "depth {d}: λ {lambda} vs Newton {l}");
    }
    // strongly nonlinear: at the full load the linear model is far off, so the ratio of the
    // nonlinear to the linear force differs from one
    let (l_end, d_end) = *curve.last().unwrap();
    let s = lattice.stiffness_ratio(p.point, d_end, 4, &mut zeta);
    let (own, _) = p.load_at_depth(d_end, &mut zeta);
    assert!(
        (s.ratio - own * p.d_linear / d_end).abs() < 1e-12,
        "at a lattice point its own ratio"
    );
    assert!((own - l_end).abs() < 1e-3 * l_end);
    assert!((s.ratio - 1.0).abs() > 0.1, "ratio {}", s.ratio);
    // small presses are linear
    let tiny = lattice.stiffness_ratio(p.point, 1e-4 * d_end, 4, &mut zeta);
    assert!((tiny.ratio - 1.0).abs() < 1e-2, "{}", tiny.ratio);
    // past the path's end: extrapolated, finite, said so
    let deep = lattice.stiffness_ratio(p.point, 3.0 * d_end, 4, &mut zeta);
    assert!(deep.extrapolated && deep.ratio.is_finite() && deep.ratio > 0.0);
    // between positions: a blend of neighbours, finite and positive
    let mid = [0, 1, 2].map(|k| 0.5 * (p.point[k] + lattice.positions[1].point[k]));
    let m = lattice.stiffness_ratio(mid, 0.5 * d_end, 4, &mut zeta);
    assert!(m.ratio.is_finite() && m.ratio > 0.0);
    // nonsense depths are harmless
    for d in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert_eq!(lattice.stiffness_ratio(p.point, d, 4, &mut zeta).ratio, 1.0);
    }

    // the bundle form round-trips, and damaged arrays are refused
    let arrays = lattice.to_arrays();
    let n = organ.mesh.n_nodes();
    assert_eq!(AnmLattice::from_arrays(&arrays, n).unwrap(), lattice);
    let mut bad = arrays.clone();
    bad.step_data.pop();
    assert!(AnmLattice::from_arrays(&bad, n).is_err());
    let mut bad = arrays.clone();
    bad.probe[0] = f64::NAN;
    assert!(AnmLattice::from_arrays(&bad, n).is_err());
    let mut bad = arrays.clone();
    bad.nodes[0] = n as i64;
    assert!(AnmLattice::from_arrays(&bad, n).is_err());
    let mut bad = arrays;
    bad.step_meta[0] = 99.0;
    assert!(AnmLattice::from_arrays(&bad, n).is_err());
}

#[test]
fn a_large_deformation_scene_builds_a_lattice_bundle_and_the_pipeline_scales_the_force() {
    let scene = cornea(true);
    let opts = BuildOptions::for_scene(&scene, true);
    assert!(opts.large.is_some());
    let built = offline::build_organ(&scene, 0, &opts, &mut |_| {}).unwrap();
    assert_eq!(built.report.anm_positions, 3);
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), &scene, &built).unwrap();
    let bundle = Arc::new(bundle::load_bundle(dir.path()).unwrap());
    let lattice = bundle.anm.clone().expect("the bundle carries the lattice");
    assert_eq!(Some(&lattice), built.anm.as_ref());

    // the probe pressing 0.3 mm into the apex: the large pipeline's force is the linear one
    // scaled by the lattice's ratio there
    let apex = lattice.positions[0].point;
    let tool = ToolInput {
        position_m: [apex[0], apex[1], apex[2] + 1.0e-3 - 0.3e-3],
        ..ToolInput::default()
    };
    let mut large = Pipeline::for_scene(&scene, std::slice::from_ref(&bundle)).unwrap();
    let mut linear = Pipeline::for_scene(&cornea(false), std::slice::from_ref(&bundle)).unwrap();
    let (fl, fn_) = (linear.tick(&tool), large.tick(&tool));
    let contact = fl.contact.expect("the probe touches the apex");
    let mut zeta = vec![0.0; lattice.max_modes()];
    let ratio = lattice.stiffness_ratio(contact.point_m, contact.depth_m, 4, &mut zeta).ratio;
    assert!((ratio - 1.0).abs() > 0.01, "a press this deep is nonlinear: ratio {ratio}");
    for k in 0..3 {
        assert!((fn_.force_n[k] - ratio * fl.force_n[k]).abs() <= 1e-12 * (1.0 + fl.force_n[k].abs()));
    }

    // the reduced fidelity (a session under load): the nearest position alone, flagged; the
    // linear law has no cheaper setting and keeps its force; back at full fidelity, the same
    // force as before
    large.set_fidelity(Fidelity::Reduced);
    linear.set_fidelity(Fidelity::Reduced);
    large.reset();
    linear.reset();
    let (rl, rn) = (linear.tick(&tool), large.tick(&tool));
    assert!(rn.events.has(Events::REDUCED_FIDELITY) && rl.events.has(Events::REDUCED_FIDELITY));
    assert_eq!(rl.force_n, fl.force_n);
    let nearest = lattice.stiffness_ratio(contact.point_m, contact.depth_m, 1, &mut zeta).ratio;
    for k in 0..3 {
        assert!((rn.force_n[k] - nearest * fl.force_n[k]).abs() <= 1e-12 * (1.0 + fl.force_n[k].abs()));
    }
    assert!(rn.force_error_n.unwrap() > 0.0);
    large.set_fidelity(Fidelity::Full);
    large.reset();
    let back = large.tick(&tool);
    assert!(!back.events.has(Events::REDUCED_FIDELITY));
    assert_eq!(back.force_n, fn_.force_n);

    // a bundle built without the lattice cannot serve a large-deformation scene
    let plain = offline::build_organ(&cornea(false), 0, &BuildOptions::for_scene(&cornea(false), true), &mut |_| {}).unwrap();
    let dir2 = tempfile::tempdir().unwrap();
    offline::write_bundle(dir2.path(), &cornea(false), &plain).unwrap();
    let plain = Arc::new(bundle::load_bundle(dir2.path()).unwrap());
    assert!(plain.anm.is_none());
    let e = Pipeline::for_scene(&scene, &[plain]).unwrap_err();
    assert_eq!(e, PipelineError::NoLattice { organ: 0 });
    assert!(e.to_string().contains("vademecum build"));
}

/// The error estimate each answer carries: attached by the pipeline (the lattice's spread for
/// large deformations, the round-off for the linear law), and bounding the full model's error
/// at nodes off the lattice — Newton pushed 1.5 times past the lattice's force, so the states
/// past its paths are checked too — and at random points for the linear law.
#[test]
fn the_error_estimate_bounds_the_full_model_off_the_lattice() {
    use vademecum_engine::study::estimate::{Coverage, large_samples, linear_samples};
    let scene = cornea(true);
    let opts = BuildOptions::for_scene(&scene, true);
    let built = offline::build_organ(&scene, 0, &opts, &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), &scene, &built).unwrap();
    let bundle = Arc::new(bundle::load_bundle(dir.path()).unwrap());
    let lattice = bundle.anm.clone().unwrap();
    let organ = scene.organ_model(0).unwrap();

    // the pipeline attaches it: zero away from the organ, the spread-based bound in contact
    let mut large = Pipeline::for_scene(&scene, std::slice::from_ref(&bundle)).unwrap();
    let apex = lattice.positions[0].point;
    let away = large.tick(&ToolInput {
        position_m: [apex[0], apex[1], apex[2] + 0.01],
        ..ToolInput::default()
    });
    assert_eq!(away.force_error_n, Some(0.0));
    let press = ToolInput {
        position_m: [apex[0] + 0.4e-3, apex[1], apex[2] + 1.0e-3 - 0.15e-3],
        ..ToolInput::default()
    };
    let fl = Pipeline::for_scene(&cornea(false), std::slice::from_ref(&bundle))
        .unwrap()
        .tick(&press);
    let fe = large.tick(&press);
    let c = fe.contact.unwrap();
    let mut zeta = vec![0.0; lattice.max_modes()];
    let s = lattice.stiffness_ratio(c.point_m, c.depth_m, 4, &mut zeta);
    let norm = |f: [f64; 3]| f.iter().map(|x| x * x).sum::<f64>().sqrt();
    let e = fe.force_error_n.unwrap();
    assert!(s.nearest_m > 0.0 && !s.extrapolated, "{s:?}");
    let rates = lattice.interpolation_rates(4);
    assert!(rates.len() == 3 && rates.iter().all(|&r| r > 0.0), "{rates:?}");
    assert!(
        (e - norm(fl.force_n) * (s.error(&rates) + 1e-9 * s.ratio)).abs() <= 1e-12 * e,
        "{e}"
    );
    assert!(e < 0.5 * norm(fe.force_n), "a useful estimate: {e} of {}", norm(fe.force_n));
    let le = fl.force_error_n.unwrap();
    assert!(le > 0.0 && le <= 1e-8 * norm(fl.force_n), "{le}");

    // against the full model: ≥ 95 % of the states bounded (what the study checks per scene)
    let params = opts.large.unwrap();
    let samples = large_samples(&organ, &lattice, &params, 4, |_, _| {}).unwrap();
    let cov = Coverage::of(&samples);
    assert!(cov.samples >= 12, "{cov:?}");
    assert!(samples.iter().any(|s| s.beyond_range), "the states past the paths are sampled");
    assert!(
        cov.max_relative_error > 1e-3,
        "off the lattice the served law is not exact: {cov:?}"
    );
    assert!(cov.fraction() >= 0.95, "{cov:?}\n{samples:#?}");
    let samples = linear_samples(&organ, &bundle, 20).unwrap();
    let cov = Coverage::of(&samples);
    assert_eq!(cov.samples, 20);
    assert_eq!(cov.bounded, 20, "{samples:#?}");
}

/// `build --target-error` on a large-deformation scene: the fewest lattice positions (2, 4, 8,
/// … in farthest-point order, each size the first positions of the next) whose served force is
/// within the target of full Newton at nodes off the lattice.
#[test]
fn a_target_error_builds_the_fewest_lattice_positions_that_meet_it() {
    use vademecum_engine::rom::lattice_check::{lattice_error, newton_laws};
    let scene = cornea(false);
    let organ = scene.organ_model(0).unwrap();
    let laws = organ.laws.clone().unwrap();
    let params = small_lattice(8);
    let full = AnmLattice::build(&organ, &laws, &params, |_, _| {}).unwrap();
    let order = AnmLattice::order(&organ, &params).unwrap();
    assert_eq!(
        full.positions.iter().map(|p| p.node).collect::<Vec<_>>(),
        order.iter().map(|p| p.0).collect::<Vec<_>>()
    );
    let exclude: Vec<usize> = order.iter().map(|p| p.0).collect();
    let truth = newton_laws(&organ, &params, &exclude, 6, |_, _| {}).unwrap();
    let error = |n: usize| {
        lattice_error(
            &AnmLattice {
                max_force: full.max_force,
                positions: full.positions[..n].to_vec(),
            },
            &truth,
        )
    };
    let (e2, e4, e8) = (error(2), error(4), error(8));
    assert!(
        [e2, e4, e8].iter().all(|e| e.is_finite() && *e > 1e-5),
        "off the lattice no law is exact: {e2} {e4} {e8}"
    );
    let build = |target: f64| {
        let mut checked = Vec::new();
        let (lattice, t) = AnmLattice::build_for_target(
            &organ,
            &laws,
            &params,
            target,
            |l| {
                checked.push(l.positions.len());
                lattice_error(l, &truth)
            },
            |_, _| {},
        )
        .unwrap();
        (lattice, t, checked)
    };

    // a loose target: the two first positions, the whole lattice's own
    let (lattice, t, checked) = build(1.0);
    assert!(t.met && t.most == 8, "{t:?}");
    assert_eq!((t.tried.clone(), checked), (vec![(2, e2)], vec![2]));
    assert_eq!(lattice.positions, full.positions[..2]);

    // a target only the whole lattice's error meets, unless a smaller one does too: the first
    // size within it
    let target = e8 * (1.0 + 1e-9);
    let (lattice, t, _) = build(target);
    let kept = [(2, e2), (4, e4), (8, e8)].into_iter().find(|&(_, e)| e <= target).unwrap().0;
    assert!(t.met, "{t:?}");
    assert_eq!(lattice.positions, full.positions[..kept], "{t:?}");

    // an unreachable target: every size tried, the most positions kept, not met
    let (lattice, t, checked) = build(1e-12);
    assert!(!t.met, "{t:?}");
    assert_eq!(t.tried, vec![(2, e2), (4, e4), (8, e8)]);
    assert_eq!(checked, vec![2, 4, 8]);
    assert_eq!(lattice.positions, full.positions);
}
