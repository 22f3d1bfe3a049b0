//! The cutting effect of a session (seed 000 §3.4) through the whole pipeline: a scalpel
//! pressed through the patch of §3.5.1 cuts it cell by cell on the cut thread, the tick swaps
//! the cut model in and the tissue under the blade softens; the flat of the blade, friction and
//! bad blade states cut nothing; a scene that does not cut carries no cutting effect.

use crate::common;
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::time::{Duration, Instant};

use vademecum_engine::bundle::{self, LoadedBundle};
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::corotational::BLEND_TICKS;
use vademecum_engine::pipeline::{Events, Pipeline, TickState, ToolInput, ToolKind};
use vademecum_engine::scene::Scene;

/// The scene's vademecum, built and loaded back from a bundle as a session would.
fn bundle(scene: &Scene) -> Arc<LoadedBundle> {
    let built = offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), scene, &built).unwrap();
    Arc::new(bundle::load_bundle(dir.path()).unwrap())
}

fn patch_cut() -> Pipeline {
    let scene = Scene::builtin("patch_cut").unwrap();
    let b = bundle(&scene);
    Pipeline::for_scene(&scene, &[b]).unwrap()
}

const H: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// A quarter turn about z: the blade plane's normal is x (the plane x = const).
const UPRIGHT: [f64; 4] = [H, 0.0, 0.0, -H];
/// A quarter turn about x: the normal is z (the flat of the blade faces down).
const FLAT: [f64; 4] = [H, H, 0.0, 0.0];

/// The scalpel with its edge across the patch's depth (y from −0.1 to 1.1) at height `z` in
/// the plane x = 4, turned by `q`.
fn blade(z: f64, q: [f64; 4]) -> ToolInput {
    ToolInput {
        kind: ToolKind::Scalpel,
        position_m: [4.0, -0.1, z],
        blade_end_m: [4.0, 1.1, z],
        orientation: q,
        ..ToolInput::default()
    }
}

fn norm(f: [f64; 3]) -> f64 {
    f.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Ticks at `tool` (1 ms apart, as a session would) until `done` or 10 s; the states seen.
fn hold(p: &mut Pipeline, tool: &ToolInput, mut done: impl FnMut(&TickState) -> bool) -> Vec<TickState> {
    let start = Instant::now();
    let mut seen = Vec::new();
    while start.elapsed() < Duration::from_secs(10) {
        let s = p.tick(tool);
        seen.push(s);
        if done(&s) {
            break;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    seen
}

#[test]
fn a_scalpel_pressed_down_the_patch_cuts_the_top_row_and_the_tissue_there_softens() {
    let mut p = patch_cut();
    assert_eq!(p.effect_names(), vec!["palpation", "cutting"]);
    assert!(p.accepts(ToolKind::Scalpel) && !p.accepts(ToolKind::Probe));
    let status = p.cut_status().unwrap();
    // down from above the top (z = 5) to z = 3.9 in 1,200 ticks; the tissue pushes the blade
    // up, in its plane: the blade cuts
    let mut events = 0;
    let mut before = None;
    for i in 0..=1200 {
        let z = 5.1 - 1.2 * i as f64 / 1200.0;
        let s = p.tick(&blade(z, UPRIGHT));
        // one tick a millisecond, as a session ticks: the cut thread's queue holds a second of
        // blade states, so a blade swept faster than that could lose the start of its stroke
        std::thread::sleep(Duration::from_millis(1));
        events |= s.events.0;
        if (z - 4.5).abs() < 5e-4 {
            before = Some(norm(s.force_n));
        }
        if let Some(b) = s.blade {
            // the split sums back to the force
            for k in 0..3 {
                assert!((b.perpendicular_n[k] + b.parallel_n[k] - s.force_n[k]).abs() <= 1e-12 * (1.0 + norm(s.force_n)));
            }
        }
    }
    assert!(events & Events::CONTACT != 0 && events & Events::CUT_STARTED != 0);
    // the cut thread crosses the top cell row once the blade passed its bottom: two cells,
    // four nodes (the pre-planned patch_cut), swapped into the tick
    // (the swap may come while the blade is still going down, or after: the events of both)
    hold(&mut p, &blade(3.9, UPRIGHT), |s| {
        events |= s.events.0;
        events & Events::CUT_ADVANCED != 0 && status.cells.load(Relaxed) >= 2
    });
    assert!(
        events & Events::CUT_ADVANCED != 0,
        "no cut reached the tick: {} steps, {} cells, {} refused, {} overwritten",
        status.steps.load(Relaxed),
        status.cells.load(Relaxed),
        status.refused.load(Relaxed),
        status.overwritten.load(Relaxed)
    );
    assert_eq!(status.cells.load(Relaxed), 2);
    assert_eq!(status.nodes.load(Relaxed), 4);
    assert_eq!(status.refused.load(Relaxed), 0);
    // back at the same depth as before the cut: the opened tissue pushes back less
    let s = p.tick(&blade(4.5, UPRIGHT));
    let (before, after) = (before.unwrap(), norm(s.force_n));
    assert!(after.is_finite() && after > 0.0);
    assert!(after < 0.99 * before, "force {after} N after the cut, {before} N before");
    // the local fields make the cut's compliance the full XFEM's: the answer keeps the linear
    // law's round-off estimate (the study checks it against the full XFEM)
    let e = s.force_error_n.expect("the cut organ's force carries its estimate");
    assert!((e - 1e-9 * after).abs() <= 1e-12 * after, "{e:e} for {after} N");
    // the blade is in its cut now (the cut thread tells the next ticks)
    let seen = hold(&mut p, &blade(4.5, UPRIGHT), |s| s.events.has(Events::BLADE_IN_CUT));
    assert!(seen.last().unwrap().events.has(Events::BLADE_IN_CUT));
    assert_eq!(status.overwritten.load(Relaxed), 0);
}

/// `fidelity.xfem.front = "shared"` in a session: the same stroke cuts the same two cells, but
/// only the two nodes of the top edge crack — the row the blade's edge stopped on stays shared
/// — so the tissue opens down to the blade and no further: back at z = 4.5 the blade feels more
/// of the tissue than with the seed's rule, whose opening runs one cell row past the blade, and
/// less than before the cut.
#[test]
fn with_the_front_shared_a_session_opens_the_cut_down_to_the_blade_only() {
    let mut forces = Vec::new();
    for front in ["cracked", "shared"] {
        let base = Scene::builtin("patch_cut").unwrap();
        let xfem: toml::Table = toml::from_str(&format!("front = \"{front}\"")).unwrap();
        let text = common::with_keys(&base.source, &[("fidelity.xfem", xfem.into())]);
        let scene = Scene::from_toml(&text, "patch_cut.toml").unwrap();
        let mut p = Pipeline::for_scene(&scene, &[bundle(&scene)]).unwrap();
        p.set_deterministic(true);
        let status = p.cut_status().unwrap();
        let mut before = 0.0;
        for i in 0..=1200 {
            let z = 5.1 - 1.2 * i as f64 / 1200.0;
            let s = p.tick(&blade(z, UPRIGHT));
            if (z - 4.5).abs() < 5e-4 {
                before = norm(s.force_n);
            }
        }
        for _ in 0..100 {
            p.tick(&blade(3.9, UPRIGHT));
        }
        assert_eq!(status.cells.load(Relaxed), 2, "{front}");
        assert_eq!(status.nodes.load(Relaxed), if front == "shared" { 2 } else { 4 }, "{front}");
        let after = norm(p.tick(&blade(4.5, UPRIGHT)).force_n);
        eprintln!("front {front}: {before} N before the cut, {after} N after");
        assert!(after < 0.99 * before, "{front}: {after} N after the cut, {before} N before");
        forces.push(after);
    }
    assert!(forces[1] > 1.01 * forces[0], "{forces:?}");
}

#[test]
fn the_flat_of_the_blade_and_friction_cut_nothing() {
    let mut p = patch_cut();
    let status = p.cut_status().unwrap();
    // the flat pressed down: the tissue's force is normal to the blade plane
    for i in 0..=600 {
        let z = 5.1 - 0.6 * i as f64 / 600.0;
        let s = p.tick(&blade(z, FLAT));
        let b = s.blade.unwrap();
        assert!(!b.cutting && !s.events.has(Events::CUT_STARTED), "tick {i}");
        assert!(norm(b.parallel_n) <= 0.5 * norm(b.perpendicular_n), "tick {i}: {b:?}");
    }
    // upright but barely touching: the force stays below cut_force (1 N), friction
    let s = p.tick(&blade(5.05, UPRIGHT));
    assert!(s.events.has(Events::CONTACT) && !s.blade.unwrap().cutting && norm(s.force_n) < 1.0);
    std::thread::sleep(Duration::from_millis(50));
    assert_eq!(status.cells.load(Relaxed), 0);
}

#[test]
fn bad_blade_states_are_rejected_with_zero_force() {
    let mut p = patch_cut();
    let good = blade(4.8, UPRIGHT);
    assert!(!p.tick(&good).events.has(Events::REJECTED_INPUT));
    let mut cases = Vec::new();
    // zero length, NaN end, an edge of three blade lengths, an orientation with no plane
    // through the edge (the frame's y along the edge), a probe in a scene without one
    cases.push(ToolInput {
        blade_end_m: good.position_m,
        ..good
    });
    cases.push(ToolInput {
        blade_end_m: [f64::NAN, 0.0, 0.0],
        ..good
    });
    cases.push(ToolInput {
        blade_end_m: [4.0, -0.1 + 3.0 * 1.2, 4.8],
        ..good
    });
    cases.push(ToolInput {
        orientation: [1.0, 0.0, 0.0, 0.0],
        ..good
    });
    cases.push(ToolInput {
        kind: ToolKind::Probe,
        ..good
    });
    for (i, t) in cases.iter().enumerate() {
        let s = p.tick(t);
        assert!(s.events.has(Events::REJECTED_INPUT), "case {i}");
        assert_eq!(s.force_n, [0.0; 3], "case {i}");
        assert!(s.blade.is_none());
    }
}

#[test]
fn a_palpation_scene_carries_no_cutting_and_refuses_a_bundle_of_another_mesh() {
    // the built-in patch, with its probe
    let scene = Scene::builtin("patch").unwrap();
    let b = bundle(&scene);
    let mut p = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    assert_eq!(p.effect_names(), vec!["palpation"]);
    assert!(p.cut_status().is_none() && !p.accepts(ToolKind::Scalpel));
    // a probe tick leaves no blade split
    let s = p.tick(&ToolInput {
        position_m: [2.5, 0.5, 4.9],
        ..ToolInput::default()
    });
    assert!(s.events.has(Events::CONTACT) && s.blade.is_none());
    // a bundle of another mesh
    let cornea = Scene::builtin("keratotomy").unwrap();
    let e = Pipeline::for_scene(&cornea, &[b]).unwrap_err();
    assert!(e.to_string().contains("another mesh"), "{e}");
}

#[test]
fn the_scalpels_force_is_clamped_to_its_max_force() {
    // the patch_cut scene with a scalpel that renders at most 0.5 N: pressed 0.6 m into the
    // top (a force of several newtons on this soft patch), the force keeps its direction,
    // its magnitude is the limit and the tick is flagged
    let text = common::with_keys(&Scene::builtin("patch_cut").unwrap().source, &[("tools[0].max_force", 0.5.into())]);
    let scene = Scene::from_toml(&text, "patch_cut_limited.toml").unwrap();
    let mut limited = Pipeline::for_scene(&scene, &[bundle(&scene)]).unwrap();
    let mut free = patch_cut();
    let (mut a, mut b) = (TickState::default(), TickState::default());
    for i in 0..=70 {
        let tool = blade(5.1 - 0.01 * f64::from(i), FLAT);
        (a, b) = (limited.tick(&tool), free.tick(&tool));
    }
    assert!(norm(b.force_n) > 1.0, "the unclamped force: {:?}", b.force_n);
    assert!((norm(a.force_n) - 0.5).abs() < 1e-12, "{:?}", a.force_n);
    assert!(a.events.0 & Events::FORCE_SATURATED != 0 && b.events.0 & Events::FORCE_SATURATED == 0);
    let cos = (0..3).map(|k| a.force_n[k] * b.force_n[k]).sum::<f64>() / (norm(a.force_n) * norm(b.force_n));
    assert!((cos - 1.0).abs() < 1e-12);
    // and the scene says so
    assert!(Scene::from_toml(&common::with_keys(&text, &[("tools[0].max_force", 500.0.into())]), "x.toml").is_err());
}

#[test]
fn a_bundle_stores_the_basis_bare_enrichment_needs_and_old_bundles_still_load() {
    use vademecum_engine::bundle;
    // bare enrichment needs the K-orthonormal Ritz basis: the build stores it (bundle
    // version 2), the session takes it from there, and the model is the one computed from
    // the modes
    let text = Scene::builtin("patch_cut").unwrap().source.replace(
        "[fidelity]\nlocking = \"none\"",
        "[fidelity]\nlocking = \"none\"\n\n[fidelity.xfem]\ndiscontinuous = \"bare\"\nbasis = \"prb\"",
    );
    assert!(text.contains("\"bare\""));
    let scene = Scene::from_toml(&text, "patch_cut_bare.toml").unwrap();
    let built = offline::build_organ(&scene, 0, &BuildOptions::for_scene(&scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let manifest = offline::write_bundle(dir.path(), &scene, &built).unwrap();
    assert_eq!(manifest.version, bundle::VERSION);
    assert_eq!(manifest.info["cut"]["discontinuous"], "bare");
    let size = manifest.info["cut"]["basis_size"].as_u64().unwrap() as usize;
    assert!(size > 0 && size <= built.vademecum.modes());
    let loaded = bundle::load_bundle(dir.path()).unwrap();
    let stored = loaded.cut_basis.clone().expect("the bundle holds the basis");
    assert_eq!((stored.size, stored.x.len() % size), (size, 0));
    assert_eq!(stored.x, built.cut_basis.as_ref().unwrap().x, "stored exactly (f64)");
    // a session on it cuts (the basis from the bundle)
    let mut p = Pipeline::for_scene(&scene, &[Arc::new(loaded)]).unwrap();
    let status = p.cut_status().unwrap();
    let down = |z: f64| blade(z, UPRIGHT);
    for i in 0..=120 {
        p.tick(&down(5.1 - 0.01 * f64::from(i)));
        std::thread::sleep(Duration::from_millis(1));
    }
    let seen = hold(&mut p, &down(3.9), |_| status.cells.load(Relaxed) > 0);
    assert!(status.cells.load(Relaxed) > 0 && seen.iter().all(|s| s.force_n.iter().all(|f| f.is_finite())));

    // the palpation scene's bundle has no cutting section; rewritten as version 1 (what
    // earlier builds wrote) it still loads; a version from the future is refused, saying so
    let palp = Scene::builtin("patch").unwrap();
    let b = offline::build_organ(&palp, 0, &BuildOptions::for_scene(&palp, true), &mut |_| {}).unwrap();
    assert!(b.report.cut.is_none() && b.cut_basis.is_none());
    let old = tempfile::tempdir().unwrap();
    offline::write_bundle(old.path(), &palp, &b).unwrap();
    let path = old.path().join(bundle::MANIFEST);
    let m = std::fs::read_to_string(&path).unwrap();
    let v2 = format!("\"version\": {}", bundle::VERSION);
    assert!(m.contains(&v2), "{m}");
    std::fs::write(&path, m.replace(&v2, "\"version\": 1")).unwrap();
    let l = bundle::load_bundle(old.path()).unwrap();
    assert!(l.cut_basis.is_none() && l.manifest.version == 1);
    std::fs::write(&path, m.replace(&v2, "\"version\": 99")).unwrap();
    let e = bundle::load_bundle(old.path()).unwrap_err().to_string();
    assert!(e.contains("version 99") && e.contains("rebuild"), "{e}");
}

/// `patch_cut` with co-rotational cutting (seed 003), without its load (the co-rotational
/// deformation carries the scene's loads; here only the blade's).
fn corotational_patch_cut() -> (Scene, Arc<LoadedBundle>) {
    let text = Scene::builtin("patch_cut")
        .unwrap()
        .source
        .replace("force = [0.0, 0.0, -1.0]", "force = [0.0, 0.0, 0.0]")
        .replace("[fidelity]\n", "[fidelity]\ncutting = \"corotational_xfem\"\n");
    assert!(text.contains("force = [0.0, 0.0, 0.0]"));
    let scene = Scene::from_toml(&text, "patch_cut_corot.toml").unwrap();
    let b = bundle(&scene);
    (scene, b)
}

#[test]
fn co_rotational_cutting_keeps_the_reduced_force_until_a_frame_lands_then_follows_the_deformation() {
    let (scene, b) = corotational_patch_cut();
    let mut corot = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    let mut linear = patch_cut();
    assert!(linear.take_corotational().is_none());
    let mut deformation = corot
        .take_corotational()
        .expect("a co-rotational scene hands its deformation to the frame thread");
    assert!(corot.take_corotational().is_none());
    // the flat of the blade pressed into the top, cutting nothing: until a frame lands the
    // tick's force is the reduced model's, bit for bit
    let mut last = TickState::default();
    for i in 0..=14 {
        let tool = blade(5.1 - 0.01 * f64::from(i), FLAT);
        let (a, l) = (corot.tick(&tool), linear.tick(&tool));
        assert_eq!(a.force_n, l.force_n, "tick {i}");
        last = a;
    }
    let contact = last.contact.expect("the blade presses the patch");
    // frames of the co-rotational deformation under that contact (the frame thread's work)
    for _ in 0..20 {
        deformation.step_with_picture(None, Some(&contact)).unwrap();
    }
    let tool = blade(5.1 - 0.14, FLAT);
    let status = corot.cut_status().unwrap();
    // the landing tick still applies the correction in effect before (none): the new one is
    // blended in over the next BLEND_TICKS ticks
    let (a, l) = (corot.tick(&tool), linear.tick(&tool));
    assert_eq!(a.force_n, l.force_n);
    assert_eq!(status.landings.load(Relaxed), 1, "the correction landed during the contact");
    let mut prev = a.force_n;
    let mut largest_step = 0.0f64;
    let mut blended = Vec::new();
    for _ in 0..BLEND_TICKS {
        let (a, _) = (corot.tick(&tool), linear.tick(&tool));
        largest_step = largest_step.max(norm(std::array::from_fn(|k| a.force_n[k] - prev[k])));
        prev = a.force_n;
        blended.push(a);
    }
    // each blended force carries an estimate that covers the rest of the blend: at least its
    // distance from the force with the correction fully in (the deformation's own compliance,
    // to the correction's solve)
    for a in &blended {
        let e = a.force_error_n.expect("a corrected force carries its estimate");
        let left = norm(std::array::from_fn(|k| a.force_n[k] - prev[k]));
        assert!(e >= left && e <= left + 1e-6 * norm(prev), "estimate {e:e}, left to blend {left:e}");
    }
    assert!(status.corrected_ticks.load(Relaxed) >= 1 && status.refused_corrections.load(Relaxed) == 0);
    // the deformation shown is small against the patch (0.08 deep in 5): its correction moves the
    // force by a little; the whole step is what the landing reports, spread over the blend
    let l = linear.tick(&tool);
    let diff = norm(std::array::from_fn(|k| prev[k] - l.force_n[k]));
    assert!(diff > 0.0 && diff < 0.2 * norm(l.force_n), "{prev:?} vs {:?}", l.force_n);
    let jump = status.landing_jump_max_un.load(Relaxed) as f64 * 1e-6;
    assert!((jump - diff).abs() <= 1e-6 + 1e-9 * diff, "landing step {jump:e} vs {diff:e}");
    let step = status.blend_step_max_un.load(Relaxed) as f64 * 1e-6;
    assert!((step - largest_step).abs() <= 1e-6, "{step:e} vs {largest_step:e}");
    assert!(
        largest_step < 2.0 * diff / f64::from(BLEND_TICKS),
        "{largest_step:e} per tick for a {diff:e} step"
    );
    assert!(deformation.frames() == 20 && deformation.revision() == 0);
}

#[test]
fn co_rotational_cutting_and_visual_meshes_are_checked_when_the_scene_is_read() {
    let patch_cut = Scene::builtin("patch_cut").unwrap().source;
    let cases = [
        // the model without cutting
        (
            patch_cut
                .replace("cutting = true", "cutting = false")
                .replace("[fidelity]\n", "[fidelity]\ncutting = \"corotational_xfem\"\n"),
            "cutting is off",
        ),
        // a visual mesh in a scene that does not draw it
        (
            patch_cut.replace(
                "[[organs.materials]]",
                "[organs.visual]\nfile = \"liver.obj\"\n\n[[organs.materials]]",
            ),
            "co-rotational cutting sessions",
        ),
        // a visual mesh that is not an OBJ
        (
            patch_cut
                .replace(
                    "[[organs.materials]]",
                    "[organs.visual]\nfile = \"liver.stl\"\n\n[[organs.materials]]",
                )
                .replace("[fidelity]\n", "[fidelity]\ncutting = \"corotational_xfem\"\n"),
            ".obj",
        ),
        // an unknown model
        (patch_cut.replace("[fidelity]\n", "[fidelity]\ncutting = \"magic\"\n"), "magic"),
    ];
    for (i, (text, says)) in cases.iter().enumerate() {
        let e = Scene::from_toml(text, "case.toml").unwrap_err().to_string();
        assert!(e.contains(says), "case {i}: {e}");
    }
    // a visual file that does not exist is reported when the session starts
    let text = cases[2].0.replace("liver.stl", "missing.obj");
    let scene = Scene::from_toml(&text, "case.toml").unwrap();
    let e = scene.organ_visual(0).unwrap_err().to_string();
    assert!(e.contains("missing.obj"), "{e}");
    // a visual surface scaled out of all proportion (scale = 1e300 ran, and every frame held
    // inf) is refused, saying to check the scale
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("box.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    let at = dir.path().join("case.toml");
    for (scale, ok) in [("1.0", true), ("1e300", false), ("5000.0", false)] {
        let text = cases[2]
            .0
            .replace("file = \"liver.stl\"", &format!("file = \"box.obj\"\nscale = {scale}"));
        let scene = Scene::from_toml(&text, &at).unwrap();
        match scene.organ_visual(0) {
            Ok(v) => assert!(ok, "scale {scale} accepted: {:?}", v.map(|v| v.vertices.len())),
            Err(e) => {
                assert!(!ok, "scale {scale}: {e}");
                assert!(e.to_string().contains("check `scale`"), "{e}");
            }
        }
    }
}
