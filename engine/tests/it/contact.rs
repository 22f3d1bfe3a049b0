//! Haptic contact through the whole palpation pipeline, on the built-in organ and the
//! OpenHELP liver: a probe pressed far deeper than its radius never lets go and its force
//! grows with depth, a pressed probe sliding across triangle edges and vertices (and off the
//! accessible surface onto the support) feels no jump, and the probe can come at the organ
//! from any side, the fixed face included — and a tip that leaves the organ, by a straight
//! lift or a jump from deep inside to anywhere outside, feels no force once its sphere is
//! clear of the organ and no more than the surface it reaches while it is not.

use crate::common;

use std::sync::Arc;

use vademecum_engine::bundle;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::contact::{Surface, SurfacePoint};
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::{Events, Pipeline, TickState, ToolInput, palpation};
use vademecum_engine::scene::Scene;

/// The scene's vademecum, built and loaded back from a bundle as a session would.
fn bundle(scene: &Scene) -> Arc<LoadedBundle> {
    let built = offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), scene, &built).unwrap();
    Arc::new(bundle::load_bundle(dir.path()).unwrap())
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
    let loads = b.vademecum.load_nodes();
    (0..count)
        .map(|i| {
            let node = loads[(i * loads.len()) / count + loads.len() / (2 * count)];
            (b.nodes[node], common::node_normal(b, node))
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
    let text = common::with_keys(
        vademecum_engine::scene::builtin("organ").unwrap(),
        &[("tools[0].max_force", 5.0.into())],
    );
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

/// The truth about a point, from the organ's triangles alone (no grid, no proxy): its distance
/// to the surface (brute force over every triangle) and whether it is inside (the parity of a
/// ray's crossings, Möller–Trumbore, along a direction no mesh plane holds).
struct Truth<'a> {
    nodes: &'a [[f64; 3]],
    tris: &'a [[usize; 3]],
    surface: Surface,
}

impl<'a> Truth<'a> {
    fn new(b: &'a LoadedBundle) -> Self {
        Self {
            nodes: &b.nodes,
            tris: &b.surface,
            surface: Surface::new(&b.nodes, b.surface.clone()),
        }
    }

    fn distance(&self, p: [f64; 3]) -> f64 {
        (0..self.tris.len())
            .map(|t| norm(sub(p, self.surface.closest_on(t, p).point)))
            .fold(f64::INFINITY, f64::min)
    }

    fn inside(&self, p: [f64; 3]) -> bool {
        let dir = [0.301_511_344_577_763_6, 0.452_267_016_866_645_4, 0.839_924_459_895_198_6];
        let mut crossings = 0;
        for t in self.tris {
            let (a, b, c) = (self.nodes[t[0]], self.nodes[t[1]], self.nodes[t[2]]);
            let (e1, e2) = (sub(b, a), sub(c, a));
            let h = cross(dir, e2);
            let det = dot(e1, h);
            if det.abs() < 1e-18 {
                continue;
            }
            let s = sub(p, a);
            let u = dot(s, h) / det;
            let q = cross(s, e1);
            let v = dot(dir, q) / det;
            if (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0 && dot(e2, q) / det > 0.0 {
                crossings += 1;
            }
        }
        crossings % 2 == 1
    }
}

fn probe_radius(scene: &Scene) -> f64 {
    let r = offline::probe_radius(scene);
    assert!(r > 0.0, "a probe");
    r
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Presses deep (4 to 14 radii, straight along the inward normal of a random loadable node),
/// then jumps out in 1 to 128 ticks to a random point — near the surface (within three radii
/// above a random surface point) or anywhere around the organ — and holds it for a few ticks.
/// Wherever the tip's sphere does not reach the organ (the centre outside, farther than r
/// from every triangle) the force is exactly zero; where it does with the centre outside, the
/// depth is at most what the nearest surface gives (r − distance): the proxy never stays on
/// a part of the surface the tool left through the tissue.
fn jumps_out_feel_nothing(scene: &Scene, b: &Arc<LoadedBundle>, trials: usize, seed: u64) {
    let r = probe_radius(scene);
    let truth = Truth::new(b);
    let loads = b.vademecum.load_nodes();
    let pts = press_points(b, loads.len().min(64));
    let all: Vec<([f64; 3], [f64; 3])> = {
        let s = &truth.surface;
        (0..b.surface.len())
            .map(|t| {
                let at = SurfacePoint {
                    triangle: t,
                    weights: [1.0 / 3.0; 3],
                    point: [0, 1, 2].map(|k| b.surface[t].iter().map(|&n| b.nodes[n][k]).sum::<f64>() / 3.0),
                };
                (at.point, s.normal_at(&at))
            })
            .collect()
    };
    let (lo, hi) = {
        let bb = vademecum_engine::contact::Bounds::of(&b.nodes, &b.surface);
        (bb.min.map(|x| x - 3.0 * r), bb.max.map(|x| x + 3.0 * r))
    };
    let mut rng = vademecum_engine::rng::Rng(seed);
    let mut pipe = Pipeline::for_scene(scene, std::slice::from_ref(b)).unwrap();
    let (mut outside_free, mut outside_touching) = (0, 0);
    for trial in 0..trials {
        pipe.reset();
        let (p, n) = pts[(rng.unit() * pts.len() as f64) as usize];
        let depth = (4.0 + 10.0 * rng.unit()) * r;
        let steps = 40;
        let mut tip = p;
        for i in 0..=steps {
            let h = 2.0 * r - (2.0 * r + depth) * i as f64 / steps as f64;
            tip = [0, 1, 2].map(|k| p[k] + h * n[k]);
            tick(&mut pipe, tip);
        }
        let target = if rng.unit() < 0.5 {
            let (q, m) = all[(rng.unit() * all.len() as f64) as usize];
            let h = 3.0 * r * rng.unit();
            [0, 1, 2].map(|k| q[k] + h * m[k])
        } else {
            [0, 1, 2].map(|k| lo[k] + rng.unit() * (hi[k] - lo[k]))
        };
        let ticks = 1 + (rng.unit() * 128.0) as usize;
        let from = tip;
        let mut last = None;
        for i in 1..=ticks + 3 {
            let u = (i as f64 / ticks as f64).min(1.0);
            last = Some(tick(&mut pipe, [0, 1, 2].map(|k| from[k] + u * (target[k] - from[k]))));
        }
        let s = last.unwrap();
        if truth.inside(target) {
            continue;
        }
        let d = truth.distance(target);
        if d >= r {
            outside_free += 1;
            assert!(
                s.force_n == [0.0; 3] && s.contact.is_none(),
                "trial {trial}: the tip is outside, {d} m from the organ (radius {r}), after a press {depth} m deep at {p:?} and a jump to {target:?} in {ticks} ticks, yet the force is {:?} N (contact {:?})",
                s.force_n,
                s.contact
            );
        } else {
            outside_touching += 1;
            // (touching along the smooth normal field is `d < r` measured along it, which can
            // be longer than the gap where the surface curves sharply: no contact is allowed)
            if let Some(c) = s.contact {
                assert!(
                    c.depth_m <= r - d + 1e-9,
                    "trial {trial}: the tip's centre is outside, {d} m from the organ, yet the depth is {} m (proxy {:?}) after a press {depth} m deep at {p:?} and a jump in {ticks} ticks",
                    c.depth_m,
                    c.proxy_m
                );
            }
        }
    }
    assert!(
        outside_free > trials / 5 && outside_touching > trials / 10,
        "{outside_free} {outside_touching}"
    );
}

#[test]
fn organ_jumps_out_of_deep_presses_feel_no_force_in_free_air() {
    let scene = Scene::builtin("organ").unwrap();
    let b = bundle(&scene);
    // the reproducer: 11.5 radii deep at (0, +18.6 mm), then 2 mm above the top at (0, −18.6 mm)
    let r = probe_radius(&scene);
    let truth = Truth::new(&b);
    let top = |y: f64| {
        let mut z = 0.05;
        while !truth.inside([0.0, y, z - 1e-5]) && z > -0.05 {
            z -= 1e-5;
        }
        z
    };
    let (z0, z1) = (top(0.0186), top(-0.0186));
    for ticks in [1, 2, 5, 17, 64, 128] {
        let mut pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
        for i in 0..=400 {
            tick(&mut pipe, [0.0, 0.0186, z0 + r - 12.5 * r * i as f64 / 400.0]);
        }
        let from = [0.0, 0.0186, z0 - 11.5 * r];
        let to = [0.0, -0.0186, z1 + 0.002];
        let mut s = tick(&mut pipe, from);
        for i in 1..=ticks {
            let u = i as f64 / ticks as f64;
            s = tick(&mut pipe, [0, 1, 2].map(|k| from[k] + u * (to[k] - from[k])));
        }
        let c = s.contact.expect("2 mm above the top, a 4 mm tip touches it");
        assert!(
            c.depth_m <= r - truth.distance(to) + 1e-9,
            "jumped out in {ticks} ticks: depth {} m, force {:?} N",
            c.depth_m,
            s.force_n
        );
        let lifted = tick(&mut pipe, [to[0], to[1], to[2] + r]);
        assert_eq!(lifted.force_n, [0.0; 3]);
    }
    jumps_out_feel_nothing(&scene, &b, 2000, 0x5eed_0044);
}

#[test]
fn liver_jumps_out_of_deep_presses_feel_no_force_in_free_air() {
    let Some(shared) = common::shared_data() else { return };
    let scene = common::shared_scene("liver_h20.toml", &shared);
    let b = bundle(&scene);
    jumps_out_feel_nothing(&scene, &b, 1000, 0x5eed_1044);
}

/// Straight presses from `start` along the unit `dir` over `length` (m) in steps of `step`
/// (m): the largest fall of the force between two steps while the tip stays inside the organ
/// (as the truth says: a press that goes through and out of the far side is let go there)
/// below the probe's force limit (a saturated force is flat), and the largest force reached.
fn largest_fall(scene: &Scene, b: &Arc<LoadedBundle>, presses: &[([f64; 3], [f64; 3], f64)], step: f64) -> (f64, f64) {
    let truth = Truth::new(b);
    let mut pipe = Pipeline::for_scene(scene, std::slice::from_ref(b)).unwrap();
    let (mut fall, mut most): (f64, f64) = (0.0, 0.0);
    for &(start, dir, length) in presses {
        pipe.reset();
        let steps = (length / step).ceil() as usize;
        let mut last: Option<(f64, bool)> = None;
        for i in 0..=steps {
            let tip = [0, 1, 2].map(|k| start[k] + length * dir[k] * i as f64 / steps as f64);
            let s = tick(&mut pipe, tip);
            let f = norm(s.force_n);
            let inside = truth.inside(tip);
            if let Some((before, was_inside)) = last
                && inside
                && was_inside
                && !s.events.has(Events::FORCE_SATURATED)
            {
                fall = fall.max(before - f);
            }
            most = most.max(f);
            last = Some((f, inside));
        }
    }
    (fall, most)
}

/// Pressed straight in along the surface's inward normal, 14 radii deep at six points (to the
/// probe's 50 N limit), the force never falls while the tip is inside. (Pressed obliquely near
/// the lobe's rounded rim it can: the open part of issue 44, in `docs/contact.md`.)
#[test]
fn organ_pressed_straight_in_along_the_normal_never_loses_force() {
    let scene = Scene::builtin("organ").unwrap();
    let b = bundle(&scene);
    let r = probe_radius(&scene);
    let normal: Vec<_> = press_points(&b, 6)
        .into_iter()
        .map(|(p, n)| ([0, 1, 2].map(|k| p[k] + 2.0 * r * n[k]), n.map(|x| -x), 16.0 * r))
        .collect();
    let (fall, most) = largest_fall(&scene, &b, &normal, 1e-5);
    assert!(most > 10.0, "the presses reached only {most} N");
    assert!(
        fall <= 1e-9 * most,
        "pressed along the normal, the force fell by {fall} N in a step"
    );
}

/// The seven straight presses that are not along the normal (docs/contact.md, "Pressing
/// deep"): straight down (−z) at six points of the organ, from 2 radii above to 16 radii past
/// the point, and in from +y through 11 cm of the lobe — each named, with its start, direction
/// and length (m).
fn seven_presses(b: &LoadedBundle, r: f64) -> Vec<(String, [f64; 3], [f64; 3], f64)> {
    let mut presses: Vec<(String, [f64; 3], [f64; 3], f64)> = press_points(b, 6)
        .into_iter()
        .map(|(p, _)| (format!("down at {p:?}"), [p[0], p[1], p[2] + 2.0 * r], [0.0, 0.0, -1.0], 16.0 * r))
        .collect();
    presses.push(("from +y".into(), [0.0, 0.08, 0.01], [0.0, -1.0, 0.0], 0.12));
    presses
}

/// Along a straight press ([`seven_presses`], in 10 µm steps) the force never falls while the
/// tip moves into the surface at the proxy (`v · n(s) ≤ 0` at the step's start: the depth
/// grows), inside the organ and below the probe's limit: it eases only where the tip moves out
/// through the surface the proxy is on, heading out of the organ past its rim (docs/contact.md,
/// "Pressing deep"). The three presses at the top's inner points (4–6) never head out, so
/// their force never falls at any step inside and below the limit. With the blend's stiffness
/// the force fell by 31.1 N summed over the steps going deeper (its ripple under the sliding
/// proxy: by 0.56, 1.84 and 6.41 N at presses 4–6), and by 0.03 N where the proxy jumped
/// 0.33 mm into a fold of the normal field. (Press 1's point is on the lobe's side: a press
/// straight down grazes past it outside.)
#[test]
fn a_straight_press_never_loses_force_while_it_goes_deeper() {
    let scene = Scene::builtin("organ").unwrap();
    let b = bundle(&scene);
    let r = probe_radius(&scene);
    let truth = Truth::new(&b);
    let mut deeper = 0;
    for (i, (name, start, dir, length)) in seven_presses(&b, r).into_iter().enumerate() {
        let inner = (3..=5).contains(&i);
        let mut pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
        let (mut last, mut pressed): (Option<(f64, f64)>, usize) = (None, 0);
        for k in 0..=(length / 1e-5).round() as usize {
            let tip = [0, 1, 2].map(|d| start[d] + 1e-5 * k as f64 * dir[d]);
            let s = tick(&mut pipe, tip);
            let Some(c) = s.contact.filter(|_| truth.inside(tip) && !s.events.has(Events::FORCE_SATURATED)) else {
                last = None;
                continue;
            };
            let f = norm(s.force_n);
            // the press direction against the proxy's outward normal (δ = −depth · n)
            let vn = -(0..3).map(|d| c.imposed_m[d] * dir[d]).sum::<f64>() / norm(c.imposed_m);
            if let Some((before, into)) = last {
                assert!(!inner || into <= 0.0, "press {} ({name}) heads out at {tip:?}", i + 1);
                if into <= 0.0 {
                    assert!(
                        f >= before,
                        "press {} ({name}), going deeper: the force fell {before} → {f} N at {tip:?}",
                        i + 1
                    );
                    deeper += 1;
                    pressed += 1;
                }
            }
            last = Some((f, vn));
        }
        assert!(
            !inner || pressed > 1000,
            "press {}: only {pressed} steps inside and below the limit",
            i + 1
        );
    }
    assert!(deeper > 15_000, "only {deeper} steps pressed deeper");
}

/// The [`seven_presses`] measured (docs/contact.md, "Pressing deep"): prints, per press, the largest fall of the force between two 10 µm steps while the tip is
/// inside and below the force limit, and the falls summed; then sweeps 10 cm across the top
/// at three depths (0.5, 1.5 and 3 radii where they start) and three y, printing the largest
/// force step per 10 µm (continuity) and the largest horizontal / vertical force (how much a
/// sweep drags the tissue — none for a frictionless proxy on a flat top). A measurement, not a
/// check: run with
/// `cargo test -p vademecum-engine --test it oblique_presses -- --ignored --nocapture`.
#[test]
#[ignore]
fn oblique_presses_where_the_force_falls() {
    let scene = Scene::builtin("organ").unwrap();
    let b = bundle(&scene);
    let r = probe_radius(&scene);
    let truth = Truth::new(&b);
    let mut pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    let step = 1e-5;
    for (name, start, dir, length) in seven_presses(&b, r) {
        pipe.reset();
        let steps = (length / step).ceil() as usize;
        let mut last: Option<(f64, f64, [f64; 3])> = None;
        let (mut worst, mut at, mut cum, mut jump) = (0.0f64, 0.0, 0.0f64, 0.0);
        let (mut dcum, mut dlast, mut dfirst) = (0.0f64, 0.0f64, None::<f64>);
        for i in 0..=steps {
            let t = length * i as f64 / steps as f64;
            let tip = [0, 1, 2].map(|k| start[k] + t * dir[k]);
            let s = tick(&mut pipe, tip);
            let f = norm(s.force_n);
            let inside = truth.inside(tip);
            let proxy = s.contact.map(|c| c.proxy_m).unwrap_or([0.0; 3]);
            let depth = s.contact.map(|c| c.depth_m).unwrap_or(0.0);
            if s.contact.is_some() && dfirst.is_none() {
                dfirst = Some(t);
            }
            if s.contact.is_some() && inside && depth < dlast {
                dcum += dlast - depth;
            }
            dlast = depth;
            if let Some((before, _, p0)) = last
                && inside
                && !s.events.has(Events::FORCE_SATURATED)
                && s.contact.is_some()
            {
                let fall = before - f;
                if fall > 0.0 {
                    cum += fall;
                }
                if fall > worst {
                    worst = fall;
                    at = t;
                    jump = norm([0, 1, 2].map(|k| proxy[k] - p0[k]));
                }
            }
            last = Some((f, t, proxy));
        }
        eprintln!(
            "{name}: largest fall {worst:.4} N at {at:.5} m along the press (the proxy moved {jump:.1e} m in that step), falls summed {cum:.2} N; depth falls summed {dcum:.2e} m; touched at {dfirst:?}"
        );
    }
    // sweeps across the top at depths below and past one radius: the largest change of the
    // force in a 10 µm step (continuity) and the largest tangential share of it (drag)
    for depth in [0.5 * r, 1.5 * r, 3.0 * r] {
        for y in [-0.02, 0.0, 0.02] {
            pipe.reset();
            let top = |x: f64| {
                // the organ's top surface under (x, y): the first contact going down
                let mut p = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
                let mut z = 0.06;
                while z > -0.06 && tick(&mut p, [x, y, z]).contact.is_none() {
                    z -= 1e-4;
                }
                z - r
            };
            let x0 = -0.05;
            let z = top(x0) + r - depth;
            let (mut most_step, mut drag, mut last) = (0.0f64, 0.0f64, None::<[f64; 3]>);
            for i in 0..=10_000 {
                let x = x0 + 0.1 * i as f64 / 10_000.0;
                let s = tick(&mut pipe, [x, y, z]);
                if let (Some(_), Some(l)) = (s.contact, last) {
                    most_step = most_step.max(norm(sub(s.force_n, l)));
                    let vertical = s.force_n[2].abs();
                    if vertical > 0.05 {
                        drag = drag.max(norm([s.force_n[0], s.force_n[1], 0.0]) / vertical);
                    }
                }
                last = s.contact.map(|_| s.force_n);
            }
            eprintln!(
                "sweep at {:.1} radii deep, y = {y}: largest force step {most_step:.4} N per 10 µm, largest horizontal / vertical force {drag:.2}",
                depth / r
            );
        }
    }
}

/// The probe's contact stiffness along the lobe's top under mesh refinement: the vertical
/// stiffness `1/c_zz` of a load spread over the probe's tip (radius r = 4 mm, weights
/// `area · (1 − d/r)` over the surface nodes within r of the point) at points every 2.5 mm
/// along the middle of the top, on the built-in organ at 1–4 × its divisions (the full-order
/// direct solve), beside what the scene's own mesh serves: the blend of the nodes' patches
/// (the vademecum's load at a point of a triangle), with patches of the probe's radius and
/// with patches at least 1.5 mesh sizes wide, and the nodes' stiffnesses interpolated
/// (`Σ β_a / c_aa`). Reference size (4× is 195,396 unknowns, 3.5 GB):
/// `cargo test --release -p vademecum-engine --test it probe_stiffness_under_refinement -- --ignored --nocapture`
/// (`LEVELS=3` for a quicker look).
#[test]
#[ignore = "reference size (30 s, 3.5 GB): the command is in its doc comment"]
fn probe_stiffness_under_refinement() {
    use vademecum_engine::mesh::boundary::triangle_area_normal;
    let r = 0.004;
    let xs: Vec<f64> = (0..=24).map(|i| -0.03 + 0.0025 * i as f64).collect();
    let levels: usize = std::env::var("LEVELS").ok().and_then(|v| v.parse().ok()).unwrap_or(4);
    let mut rows: Vec<(String, Vec<f64>)> = Vec::new();
    for k in 1..=levels {
        let text = vademecum_engine::scene::keys::with_keys(
            vademecum_engine::scene::builtin("organ").unwrap(),
            &[("organs[0].mesh.divisions", &format!("[{}, {}, {}]", 16 * k, 10 * k, 6 * k))],
        )
        .unwrap();
        let scene = Scene::from_toml(&text, "<organ refined>").unwrap();
        let model = scene.organ_model(0).unwrap();
        let clock = std::time::Instant::now();
        let (dofs, _, chol, _, _) = offline::stiffness(&model, &mut |_| {}).unwrap();
        let mesh = &model.mesh;
        let tris = model.boundary.triangles();
        let mut area = vec![0.0; mesh.n_nodes()];
        let mut edge = vec![0.0f64; mesh.n_nodes()];
        let dist = |a: [f64; 3], b: [f64; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt();
        for &t in &tris {
            let (a, _) = triangle_area_normal(mesh, t);
            for (i, &n) in t.iter().enumerate() {
                area[n] += a / 3.0;
                for j in [1, 2] {
                    edge[n] = edge[n].max(dist(mesh.nodes[n], mesh.nodes[t[(i + j) % 3]]));
                }
            }
        }
        let surface = model.boundary.nodes();
        // a hat patch of radius `rad` centred at `p` (normalised weights)
        let patch = |p: [f64; 3], rad: f64| -> Vec<(usize, f64)> {
            let w: Vec<(usize, f64)> = surface
                .iter()
                .filter_map(|&a| {
                    let d = dist(mesh.nodes[a], p);
                    (d < rad).then(|| (a, area[a] * (1.0 - d / rad)))
                })
                .collect();
            let total: f64 = w.iter().map(|x| x.1).sum();
            w.into_iter().map(|(a, x)| (a, x / total)).collect()
        };
        // the top triangle under (x, 0) and the barycentric weights of the point on it
        let top = |x: f64| -> ([usize; 3], [f64; 3], [f64; 3]) {
            let mut best: Option<([usize; 3], [f64; 3], [f64; 3])> = None;
            for &t in &tris {
                let [a, b, c] = t.map(|n| mesh.nodes[n]);
                let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
                if det.abs() < 1e-14 {
                    continue;
                }
                let l1 = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (0.0 - a[1])) / det;
                let l2 = ((b[0] - a[0]) * (0.0 - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
                let l0 = 1.0 - l1 - l2;
                if l0 < -1e-12 || l1 < -1e-12 || l2 < -1e-12 {
                    continue;
                }
                let p = [0, 1, 2].map(|i| l0 * a[i] + l1 * b[i] + l2 * c[i]);
                if best.is_none_or(|q| p[2] > q.2[2]) {
                    best = Some((t, [l0, l1, l2], p));
                }
            }
            best.unwrap()
        };
        let mut loads: Vec<(String, usize, Vec<(usize, f64)>)> = Vec::new();
        // the nodes' own patches, for the interpolated nodal stiffness Σ β_a / c_aa:
        // (point, β_a, the patch's index in `loads`)
        let mut own: Vec<(usize, f64, usize)> = Vec::new();
        for (i, &x) in xs.iter().enumerate() {
            let (t, bary, p) = top(x);
            let mut centred = patch(p, r);
            if centred.is_empty() {
                centred = t.iter().zip(bary).map(|(&a, w)| (a, w)).collect();
            }
            loads.push((format!("tip-centred patch, {}× divisions", k), i, centred));
            if k == 1 {
                for (name, c) in [("blend of node patches r", 0.0), ("blend of node patches max(r, 1.5 h)", 1.5)] {
                    let mut blend: Vec<(usize, f64)> = Vec::new();
                    for (&a, b) in t.iter().zip(bary) {
                        for (n, w) in patch(mesh.nodes[a], r.max(c * edge[a])) {
                            blend.push((n, b * w));
                        }
                    }
                    loads.push((name.to_string(), i, blend));
                }
                for (&a, b) in t.iter().zip(bary) {
                    own.push((i, b, loads.len()));
                    loads.push(("node patch".to_string(), i, patch(mesh.nodes[a], r)));
                }
            }
        }
        let n = dofs.n_free();
        let mut rhs = vec![0.0; n * loads.len()];
        for (j, (_, _, w)) in loads.iter().enumerate() {
            for &(a, x) in w {
                if let Some(e) = dofs.eq(3 * a + 2) {
                    rhs[j * n + e] += x;
                }
            }
        }
        chol.solve_many_in_place(&mut rhs, loads.len());
        let stiffness = |j: usize, w: &[(usize, f64)]| {
            1.0 / w
                .iter()
                .map(|&(a, x)| dofs.eq(3 * a + 2).map_or(0.0, |e| x * rhs[j * n + e]))
                .sum::<f64>()
        };
        for name in loads
            .iter()
            .map(|l| l.0.clone())
            .filter(|n| n != "node patch")
            .collect::<std::collections::BTreeSet<_>>()
        {
            let ks: Vec<f64> = loads
                .iter()
                .enumerate()
                .filter(|(_, l)| l.0 == name)
                .map(|(j, (_, _, w))| stiffness(j, w))
                .collect();
            rows.push((name, ks));
        }
        if k == 1 {
            let mut ks = vec![0.0; xs.len()];
            for &(i, b, j) in &own {
                ks[i] += b * stiffness(j, &loads[j].2);
            }
            rows.push(("nodal stiffnesses interpolated".to_string(), ks));
        }
        eprintln!("{k}× divisions: {} free dofs, solved in {:.1} s", n, clock.elapsed().as_secs_f64());
    }
    eprintln!("vertical stiffness (N/mm) at x = -30 … +30 mm every 2.5 mm, y = 0:");
    for (name, ks) in &rows {
        let (lo, hi) = ks.iter().fold((f64::MAX, 0.0f64), |(l, h), &k| (l.min(k), h.max(k)));
        let mean = ks.iter().sum::<f64>() / ks.len() as f64;
        eprintln!(
            "{name:>40}: mean {:.3}, min {:.3}, max {:.3} (max/min {:.2}) | {}",
            mean / 1e3,
            lo / 1e3,
            hi / 1e3,
            hi / lo,
            ks.iter().map(|k| format!("{:.2}", k / 1e3)).collect::<Vec<_>>().join(" ")
        );
    }
    assert!(rows.iter().all(|(_, ks)| ks.iter().all(|k| k.is_finite() && *k > 0.0)));
    // against the finest level (converged: 3× and 4× agree to 3.5 % at every point)
    let row = |name: &str| &rows.iter().find(|r| r.0 == name).unwrap().1;
    let finest = row(&format!("tip-centred patch, {levels}× divisions"));
    let worst = |ks: &[f64]| ks.iter().zip(finest).map(|(k, f)| (k / f - 1.0).abs()).fold(0.0, f64::max);
    let roughest = |ks: &[f64]| ks.windows(2).map(|w| (w[1] - w[0]).abs()).fold(0.0, f64::max);
    for (name, ks) in &rows {
        eprintln!(
            "{name:>40}: largest |error| {:.1} %, largest change per 2.5 mm {:.3} N/mm",
            100.0 * worst(ks),
            roughest(ks) / 1e3
        );
    }
    if levels >= 4 {
        let before = row(&format!("tip-centred patch, {}× divisions", levels - 1));
        assert!(worst(before) < 0.05, "converged to 5 % at every point");
        // what docs/contact.md claims: on the scene's mesh, the interpolated nodal stiffnesses
        // are closer to the converged stiffness, and smoother, than the blend of patches
        let (interp, blend) = (row("nodal stiffnesses interpolated"), row("blend of node patches r"));
        assert!(worst(interp) < worst(blend) && roughest(interp) < roughest(blend));
    }
}

/// How far the surface under a probe's tip moves, relative to the tip's depth, in the frames
/// a session shows (docs/contact.md, "The field the frames show"): the field is the response
/// `C(s) f` to the force `f = K(s) δ` of the tip's law, so the point under the tip moves by
/// `nᵀ C(s) K(s) n` of the depth along the normal — 1 at the nodes, and between them what the
/// coarse mesh's blend makes of the tip's load. Prints its range over 20,000 random points of
/// the organ's accessible triangles and its value at the triangles' centres. A measurement:
/// `cargo test -p vademecum-engine --test it surface_under_the_tip -- --ignored --nocapture`.
#[test]
#[ignore]
fn surface_under_the_tip_between_nodes() {
    use vademecum_engine::mesh::boundary::triangle_area_normal;
    use vademecum_engine::pgd::Footprint;
    use vademecum_engine::rng::Rng;
    let scene = Scene::builtin("organ").unwrap();
    let b = bundle(&scene);
    let v = &b.vademecum;
    let model = scene.organ_model(0).unwrap();
    let tris: Vec<[usize; 3]> = b.surface.iter().copied().filter(|t| t.iter().all(|&n| v.is_loadable(n))).collect();
    let mut rng = Rng(0x071b_5eed);
    let (mut lo, mut hi, mut centre_lo, mut centre_hi) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    let ratio = |tri: [usize; 3], w: [f64; 3]| {
        let (_, n) = triangle_area_normal(&model.mesh, tri);
        let size = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let n = n.map(|x| x / size);
        let k = v.contact_stiffness(tri, w, Footprint::Tip).unwrap();
        let c = v.compliance(tri, w).unwrap();
        let kn = k.map(|row| (0..3).map(|j| row[j] * n[j]).sum::<f64>());
        let ckn: Vec<f64> = c.iter().map(|row| (0..3).map(|j| row[j] * kn[j]).sum::<f64>()).collect();
        (0..3).map(|i| n[i] * ckn[i]).sum::<f64>()
    };
    for _ in 0..20_000 {
        let tri = tris[(rng.next_u64() % tris.len() as u64) as usize];
        let (x, y) = (rng.unit(), rng.unit());
        let (x, y) = if x + y > 1.0 { (1.0 - x, 1.0 - y) } else { (x, y) };
        let q = ratio(tri, [1.0 - x - y, x, y]);
        lo = lo.min(q);
        hi = hi.max(q);
    }
    for &tri in &tris {
        let q = ratio(tri, [1.0 / 3.0; 3]);
        centre_lo = centre_lo.min(q);
        centre_hi = centre_hi.max(q);
    }
    eprintln!(
        "the surface under the tip moves by {lo:.3}–{hi:.3} of the depth ({} accessible triangles; at their centres {centre_lo:.3}–{centre_hi:.3})",
        tris.len()
    );
}
