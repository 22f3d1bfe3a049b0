//! Haptic contact through the whole palpation pipeline, on the built-in organ and the
//! OpenHELP liver: a probe pressed far deeper than its radius never lets go and its force
//! grows with depth, a pressed probe sliding across triangle edges and vertices (and off the
//! accessible surface onto the support) feels no jump, and the probe can come at the organ
//! from any side, the fixed face included.

mod common;

use std::sync::Arc;

use vademecum_engine::contact::{Surface, SurfacePoint};
use vademecum_engine::pgd::offline::{self, BuildOptions, LoadedBundle};
use vademecum_engine::pipeline::{Events, Pipeline, TickState, ToolInput, palpation};
use vademecum_engine::scene::Scene;

/// The scene's vademecum, built and loaded back from a bundle as a session would.
fn bundle(scene: &Scene) -> Arc<LoadedBundle> {
    let built = offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), scene, &built).unwrap();
    Arc::new(offline::load_bundle(dir.path()).unwrap())
}

fn tick(p: &mut Pipeline, tip: [f64; 3]) -> TickState {
    p.tick(&ToolInput {
        position_m: tip,
        ..ToolInput::default()
    })
}

fn norm(f: [f64; 3]) -> f64 {
    f.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Surface points spread over the accessible surface: `count` loadable nodes evenly picked,
/// each with its smooth outward normal.
fn press_points(b: &LoadedBundle, count: usize) -> Vec<([f64; 3], [f64; 3])> {
    let surface = Surface::new(&b.nodes, b.surface.clone());
    let loads = b.vademecum.load_nodes();
    (0..count)
        .map(|i| {
            let node = loads[(i * loads.len()) / count + loads.len() / (2 * count)];
            let (t, a) = b
                .surface
                .iter()
                .enumerate()
                .find_map(|(t, tri)| tri.iter().position(|&n| n == node).map(|a| (t, a)))
                .unwrap();
            let mut weights = [0.0; 3];
            weights[a] = 1.0;
            let at = SurfacePoint {
                triangle: t,
                weights,
                point: b.nodes[node],
            };
            (b.nodes[node], surface.normal_at(&at))
        })
        .collect()
}

/// Presses along the inward normal at each point from 2 radii outside to `depth_radii`
/// radii deep: the force is never zero once touching and its magnitude never decreases.
fn press_straight_down(scene: &Scene, b: &Arc<LoadedBundle>, points: usize, depth_radii: f64) {
    let r = 0.004;
    let steps = 2000;
    for (p, n) in press_points(b, points) {
        let mut pipe = Pipeline::for_scene(scene, std::slice::from_ref(b)).unwrap();
        let (mut last, mut touching) = (0.0, false);
        let mut deepest = 0.0;
        for i in 0..=steps {
            let h = 2.0 * r - (2.0 + depth_radii) * r * i as f64 / steps as f64;
            let s = tick(&mut pipe, [0, 1, 2].map(|k| p[k] + h * n[k]));
            let f = norm(s.force_n);
            if touching {
                assert!(s.contact.is_some() && f > 0.0, "lost the contact at {p:?} at height {h}");
                assert!(f >= last * (1.0 - 1e-9), "force fell from {last} to {f} N at {p:?}, height {h}");
            }
            if h < r - 1e-9 {
                assert!(s.contact.is_some(), "no contact at {p:?} with the tip {h} m off the surface");
            }
            touching |= s.contact.is_some();
            last = f;
            deepest = s.contact.map_or(0.0, |c| c.depth_m);
        }
        assert!(deepest >= depth_radii * r * 0.99, "{deepest}");
    }
}

/// Sweeps a pressed probe along a path given by `at(u)`, u ∈ [0, 1], in `n` steps: the
/// largest change of the force between two steps.
fn sweep_jump(pipe: &mut Pipeline, n: usize, at: impl Fn(f64) -> [f64; 3]) -> f64 {
    pipe.reset();
    let mut prev = tick(pipe, at(0.0));
    let mut jump: f64 = 0.0;
    for i in 1..=n {
        let s = tick(pipe, at(i as f64 / n as f64));
        assert!(s.contact.is_some(), "lost the contact at step {i} of {n}");
        jump = jump.max(norm([0, 1, 2].map(|k| s.force_n[k] - prev.force_n[k])));
        prev = s;
    }
    jump
}

#[test]
fn organ_pressed_to_four_radii_never_lets_go_and_the_force_grows() {
    let scene = Scene::builtin("organ").unwrap();
    let b = bundle(&scene);
    press_straight_down(&scene, &b, 6, 4.0);
}

#[test]
fn organ_pressed_and_swept_across_edges_and_off_the_accessible_surface_feels_no_jump() {
    let scene = Scene::builtin("organ").unwrap();
    let b = bundle(&scene);
    let mut pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    // 2 mm below the top surface (a tip of radius 4 mm pressed 6 mm deep), across the
    // lobe's triangles (edges and vertices) towards its fixed posterior edge (y < −0.04 m),
    // where the nodes cannot be loaded and the support takes over
    let path = |u: f64| {
        let y = -0.047 * u;
        [0.003, y, 0.025 * (1.0 - (y / 0.05).powi(2)).max(0.0).sqrt() - 0.002]
    };
    let coarse = sweep_jump(&mut pipe, 3000, path);
    let fine = sweep_jump(&mut pipe, 6000, path);
    assert!(
        fine < 0.7 * coarse,
        "a jump: the largest step change is {coarse} N at n, {fine} N at 2n"
    );
    // it did reach the support: the tissue carries only part of the force at the end
    let end = tick(&mut pipe, path(1.0));
    let c = end.contact.unwrap();
    assert!(
        norm(c.tissue_force_n) < 0.99 * norm(end.force_n),
        "{:?} {:?}",
        c.tissue_force_n,
        end.force_n
    );
}

#[test]
fn organ_entered_from_every_side_holds_the_contact_to_the_centre() {
    let scene = Scene::builtin("organ").unwrap();
    let b = bundle(&scene);
    let mut pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    let k_max = palpation::support_stiffness(&b.vademecum);
    let centre = [0.0, 0.0, 0.01];
    // +z: the accessible top; −y: the fixed posterior edge; −z: the bottom; x: the tips;
    // diagonals: edges of the body
    let dirs: [[f64; 3]; 8] = [
        [0.0, 0.0, 1.0],
        [0.0, -1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, -1.0],
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, -1.0, 1.0],
        [1.0, 1.0, -1.0],
    ];
    for d in dirs {
        let l = norm(d);
        let d = d.map(|x| x / l);
        pipe.reset();
        let (mut touching, mut last) = (false, 0.0);
        let n = 4000;
        for i in 0..=n {
            let u = 0.15 * (1.0 - i as f64 / n as f64);
            let s = tick(&mut pipe, [0, 1, 2].map(|k| centre[k] + u * d[k]));
            if touching {
                assert!(s.contact.is_some(), "from {d:?}: lost the contact at {u} m from the centre");
                let f = norm(s.force_n);
                assert!(f > 0.0, "from {d:?}: zero force at {u} m from the centre");
                // no jump: at most what the stiffest point of the organ gives for one step,
                // three times over (the compliance also changes along the way)
                let step = 0.15 / n as f64;
                assert!((f - last).abs() < 3.0 * k_max * step, "from {d:?}: {last} -> {f} N at {u}");
                last = f;
            } else if s.contact.is_some() {
                touching = true;
                last = norm(s.force_n);
            }
        }
        assert!(touching, "from {d:?}: never touched");
    }
}

#[test]
fn past_the_probe_force_limit_the_force_saturates_with_an_event() {
    let text = vademecum_engine::scene::builtin("organ")
        .unwrap()
        .replace("radius = 0.004                       # m", "radius = 0.004\nmax_force = 5.0");
    let scene = Scene::from_toml(&text, "organ.toml").unwrap();
    let b = bundle(&scene);
    let mut pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    assert_eq!(pipe.max_force_n(), 5.0);
    let top = b
        .nodes
        .iter()
        .filter(|p| p[0].abs() < 1e-3 && p[1].abs() < 0.006)
        .map(|p| p[2])
        .fold(f64::NEG_INFINITY, f64::max);
    let mut saturated = false;
    for i in 0..=3000 {
        let s = tick(&mut pipe, [0.0, 0.0, top + 0.004 - 0.02 * i as f64 / 3000.0]);
        assert!(norm(s.force_n) <= 5.0 * (1.0 + 1e-12));
        if s.events.has(Events::FORCE_SATURATED) {
            saturated = true;
            assert!((norm(s.force_n) - 5.0).abs() < 1e-9);
        } else {
            assert!(!saturated, "once saturated, deeper stays saturated");
        }
    }
    assert!(saturated);
}

#[test]
fn liver_pressed_to_three_radii_never_lets_go_and_the_force_grows() {
    let Some(shared) = common::shared_data() else { return };
    let scene = common::shared_scene("liver_h20.toml", &shared);
    let b = bundle(&scene);
    press_straight_down(&scene, &b, 5, 3.0);
    // and a pressed sweep across its irregular triangles
    let mut pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    let pts = press_points(&b, 2);
    let ((p0, n0), (p1, n1)) = (pts[0], pts[1]);
    let path = |u: f64| [0, 1, 2].map(|k| p0[k] + u * (p1[k] - p0[k]) - 0.006 * ((1.0 - u) * n0[k] + u * n1[k]));
    let (coarse, fine) = (sweep_jump(&mut pipe, 3000, path), sweep_jump(&mut pipe, 6000, path));
    assert!(fine < 0.7 * coarse, "a jump on the liver: {coarse} N at n, {fine} N at 2n");
}
