//! Two tools in contact with one organ at once (issue 46, "forces couple"): the forces solved
//! together from the vademecum's compliances between the contact points
//! (`pgd::coupled::coupled_forces`) against the full-order finite-element model of the same
//! mesh with the same two contacts — pressing with one tool changes the other's force as the
//! full model says.

use std::sync::Arc;

use vademecum_engine::bundle::{self, LoadedBundle};
use vademecum_engine::fem::linear_static;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pgd::coupled::{CoupledError, coupled_forces};
use vademecum_engine::pgd::vademecum::Vademecum;
use vademecum_engine::scene::Scene;

fn bundle(scene: &Scene) -> Arc<LoadedBundle> {
    let built = offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), scene, &built).unwrap();
    Arc::new(bundle::load_bundle(dir.path()).unwrap())
}

fn at(node: usize) -> ([usize; 3], [f64; 3]) {
    ([node; 3], [1.0, 0.0, 0.0])
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// The load node nearest the middle of the loadable surface, and the load node nearest to it
/// 15–25 mm away (close enough to feel a press there).
fn middle_and_near(b: &LoadedBundle) -> (usize, usize) {
    let loads = b.vademecum.load_nodes();
    let centroid = [0, 1, 2].map(|k| loads.iter().map(|&n| b.nodes[n][k]).sum::<f64>() / loads.len() as f64);
    let a = *loads
        .iter()
        .min_by(|&&p, &&q| dist(b.nodes[p], centroid).total_cmp(&dist(b.nodes[q], centroid)))
        .unwrap();
    let near = *loads
        .iter()
        .filter(|&&n| (0.015..0.025).contains(&dist(b.nodes[n], b.nodes[a])))
        .min_by(|&&p, &&q| dist(b.nodes[p], b.nodes[a]).total_cmp(&dist(b.nodes[q], b.nodes[a])))
        .expect("a load node 15–25 mm from the middle");
    (a, near)
}

/// The full-order compliance between load nodes `nodes`: the patch-averaged displacement at
/// each per unit force spread over each one's patch (the vademecum's load states), by direct
/// solves of the organ's finite-element model with its supports and no other load.
fn full_order_compliance(scene: &Scene, v: &Vademecum, nodes: &[usize]) -> Vec<Vec<[[f64; 3]; 3]>> {
    let model = scene.organ_model(0).unwrap();
    let patch = |n: usize| {
        let j = v.load_nodes().iter().position(|&m| m == n).expect("a load node");
        v.patches()[j].clone()
    };
    let mut c = vec![vec![[[0.0; 3]; 3]; nodes.len()]; nodes.len()];
    for (j, &load) in nodes.iter().enumerate() {
        let (pn, pw) = patch(load);
        for d in 0..3 {
            let mut problem = model.problem.clone();
            problem.forces.iter_mut().for_each(|f| *f = 0.0);
            problem.prescribed.iter_mut().for_each(|u| *u = 0.0);
            for (&n, &w) in pn.iter().zip(&pw) {
                problem.forces[3 * n + d] += w;
            }
            let sol = linear_static::solve(&model.mesh, &model.materials, model.locking, &problem, &mut |_| {}).unwrap();
            for (i, &obs) in nodes.iter().enumerate() {
                let (on, ow) = patch(obs);
                for r in 0..3 {
                    c[i][j][r][d] = on.iter().zip(&ow).map(|(&n, &w)| w * sol.u[3 * n + r]).sum();
                }
            }
        }
    }
    c
}

/// `Σ_j C(i ← j) f_j = δ_i` solved densely (the full-order side: 3k unknowns).
fn solve_dense(c: &[Vec<[[f64; 3]; 3]>], delta: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let k = delta.len();
    let a = nalgebra::DMatrix::from_fn(3 * k, 3 * k, |r, s| c[r / 3][s / 3][r % 3][s % 3]);
    let b = nalgebra::DVector::from_iterator(3 * k, delta.iter().flatten().copied());
    let x = a.lu().solve(&b).unwrap();
    (0..k).map(|i| [x[3 * i], x[3 * i + 1], x[3 * i + 2]]).collect()
}

/// The full model's forces for the contact law of the tools together (`pgd::coupled`): each
/// tool's force along its own law's direction `f̂_i = C(i ← i)⁻¹ n_i` (at a load node the
/// full model's own block is exact), scaled by `a_i` from `Σ_j f̂_iᵀ C(i ← j) f̂_j a_j =
/// f̂_iᵀ δ_i` — solved densely with the full model's blocks.
fn pressed(c: &[Vec<[[f64; 3]; 3]>], delta: &[[f64; 3]], normals: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let k = delta.len();
    let m = |b: &[[f64; 3]; 3]| nalgebra::Matrix3::from_fn(|r, s| b[r][s]);
    let v = |x: &[f64; 3]| nalgebra::Vector3::from_column_slice(x);
    let dirs: Vec<nalgebra::Vector3<f64>> = (0..k).map(|i| m(&c[i][i]).try_inverse().unwrap() * v(&normals[i])).collect();
    let s = nalgebra::DMatrix::from_fn(k, k, |i, j| dirs[i].dot(&(m(&c[i][j]) * dirs[j])));
    let r = nalgebra::DVector::from_fn(k, |i, _| dirs[i].dot(&v(&delta[i])));
    let a = s.lu().solve(&r).unwrap();
    (0..k).map(|i| [0, 1, 2].map(|d| a[i] * dirs[i][d])).collect()
}

#[test]
fn two_tools_pressing_one_organ_feel_each_other_as_the_full_model_says() {
    let scene = Scene::builtin("organ").unwrap();
    let b = bundle(&scene);
    let v = &b.vademecum;
    let loads = v.load_nodes();
    // tool A at the middle load node; tool B at a load node 15–25 mm away (close enough to
    // feel A), and tool C far away (at the farthest load node)
    let (a, near) = middle_and_near(&b);
    let far = *loads
        .iter()
        .max_by(|&&p, &&q| dist(b.nodes[p], b.nodes[a]).total_cmp(&dist(b.nodes[q], b.nodes[a])))
        .unwrap();
    for other in [near, far] {
        let nodes = [a, other];
        let full = full_order_compliance(&scene, v, &nodes);
        // reciprocity of the reduced blocks, and their agreement with the full model
        let cab = v.cross_compliance(at(a), at(other)).unwrap();
        let cba = v.cross_compliance(at(other), at(a)).unwrap();
        let scale = full[0][0].iter().flatten().map(|x| x.abs()).fold(0.0, f64::max);
        for i in 0..3 {
            for d in 0..3 {
                assert!((cab[i][d] - cba[d][i]).abs() < 1e-3 * scale, "C(a←b) = C(b←a)ᵀ: {cab:?} {cba:?}");
            }
        }
        // A pressed 2 mm in along −z, B held where it is (its penetration zero): B's force is
        // A's press carried through the tissue
        for delta in [[[0.0, 0.0, -0.002], [0.0; 3]], [[0.0, 0.0, -0.002], [0.0, 0.0, -0.001]]] {
            let normals = [[0.0, 0.0, 1.0]; 2];
            let want = pressed(&full, &delta, &normals);
            let mut got = [[0.0; 3]; 2];
            coupled_forces(v, &[at(a), at(other)], &[Default::default(); 2], &normals, &delta, &mut got).unwrap();
            let fa = want[0].iter().map(|x| x * x).sum::<f64>().sqrt();
            for (t, (g, w)) in got.iter().zip(&want).enumerate() {
                let e = dist(*g, *w) / fa;
                eprintln!(
                    "A at {:?}, B {:.1} mm away, δ {delta:?}: tool {t} full {w:?} N, coupled {g:?} N, error {e:.2e} of |f_A|",
                    b.nodes[a],
                    1e3 * dist(b.nodes[a], b.nodes[other])
                );
                // within five probe radii the blocks are exact (measured 3e-15 at 19 mm);
                // farther, the modes carry them, whose field the build holds to 1e-3
                // (measured 2e-5 at 81 mm)
                let near = dist(b.nodes[a], b.nodes[other]) <= vademecum_engine::offline::COUPLING_REACH_RADII * 0.004;
                let tolerance = if near { 1e-12 } else { 2e-3 };
                assert!(e < tolerance, "tool {t}: {g:?} against the full model's {w:?} N ({e:.2e} of |f_A|)");
            }
            // B's force is not zero: held still, it feels A's press
            assert!(want[1].iter().any(|x| x.abs() > 1e-6 * fa), "{want:?}");
        }
    }
    // one tool alone is the single-tool law
    let mut one = [[0.0; 3]];
    coupled_forces(
        v,
        &[at(a)],
        &[Default::default()],
        &[[0.0, 0.0, 1.0]],
        &[[0.0, 0.0, -0.002]],
        &mut one,
    )
    .unwrap();
    let single = Vademecum::contact_force(&v.compliance(at(a).0, at(a).1).unwrap(), [0.0, 0.0, -0.002]);
    assert!(
        dist(one[0], single) <= 1e-12 * single.iter().map(|x| x.abs()).sum::<f64>(),
        "{one:?} {single:?}"
    );
    // two tools on the same spot are refused, not solved into nonsense
    let mut two = [[0.0; 3]; 2];
    assert_eq!(
        coupled_forces(
            v,
            &[at(a), at(a)],
            &[Default::default(); 2],
            &[[0.0, 0.0, 1.0]; 2],
            &[[0.0, 0.0, -0.002]; 2],
            &mut two
        ),
        Err(CoupledError::Singular)
    );
}

/// The full model's forces for probes that only push (the contact problem of the points,
/// solved by trying every set of active contacts): on the active set the tools press together
/// ([`pressed`]) and every force pushes (`f_i · n_i ≤ 0`); every other contact's point was
/// drawn farther in than its probe reaches, as the probe measures it (`f̂_i · u_i ≤ f̂_i ·
/// δ_i`), and takes no force.
fn unilateral(c: &[Vec<[[f64; 3]; 3]>], delta: &[[f64; 3]], normals: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let k = delta.len();
    let d3 = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let apply = |m: &[[f64; 3]; 3], x: [f64; 3]| m.map(|row| d3(row, x));
    for set in (1u32..1 << k).rev() {
        let active: Vec<usize> = (0..k).filter(|i| set & (1 << i) != 0).collect();
        let sub: Vec<Vec<[[f64; 3]; 3]>> = active.iter().map(|&i| active.iter().map(|&j| c[i][j]).collect()).collect();
        let d: Vec<[f64; 3]> = active.iter().map(|&i| delta[i]).collect();
        let n: Vec<[f64; 3]> = active.iter().map(|&i| normals[i]).collect();
        let g = pressed(&sub, &d, &n);
        let mut f = vec![[0.0; 3]; k];
        for (&i, gi) in active.iter().zip(&g) {
            f[i] = *gi;
        }
        let pushes = active.iter().all(|&i| d3(f[i], normals[i]) <= 0.0);
        let open = (0..k).filter(|i| set & (1 << i) == 0).all(|i| {
            let u = (0..k).fold([0.0; 3], |u, j| {
                let cu = apply(&c[i][j], f[j]);
                [u[0] + cu[0], u[1] + cu[1], u[2] + cu[2]]
            });
            let own = nalgebra::Matrix3::from_fn(|r, s| c[i][i][r][s]).try_inverse().unwrap();
            let dir = [0, 1, 2].map(|r| (0..3).map(|s| own[(r, s)] * normals[i][s]).sum::<f64>());
            d3(u, dir) <= d3(delta[i], dir)
        });
        if pushes && open {
            return f;
        }
    }
    panic!("no set of active contacts solves the contact problem")
}

/// The organ scene with a second probe, `left` (tool 1), beside the scene's own (tool 0).
fn two_probe_scene() -> Scene {
    let text = format!(
        "{}\n[[tools]]\nkind = \"probe\"\nname = \"left\"\nradius = 0.004\n",
        vademecum_engine::scene::builtin("organ").unwrap()
    );
    Scene::from_toml(&text, "two_probes.toml").unwrap()
}

/// Two probes of one session (issue 46, "forces couple"), ticked together by the pipeline:
/// each tool's force is the full-order model's for the two contacts together, within the
/// vademecum's error, and the error estimate of each answer covers it; the probe held still
/// feels the other's press (its force falls as the other draws the surface down), and lets
/// go when the other would make it pull; a tool alone is the single-tool law; a tool the
/// scene does not name, or the same tool twice in a tick, is rejected.
#[test]
fn two_probes_of_one_session_press_together_as_the_full_model_says() {
    use vademecum_engine::pipeline::{Events, Pipeline, TickState, ToolInput};
    let scene = two_probe_scene();
    let b = bundle(&scene);
    let v = &b.vademecum;
    let (a, near) = middle_and_near(&b);
    let r = 0.004;
    // a tip on the node's normal line, `depth` into the surface
    let tip = |node: usize, depth: f64, tool: usize| {
        let n = crate::common::node_normal(&b, node);
        ToolInput {
            tool,
            position_m: [0, 1, 2].map(|k| b.nodes[node][k] + (r - depth) * n[k]),
            ..ToolInput::default()
        }
    };
    let full = full_order_compliance(&scene, v, &[a, near]);
    let mut pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    let norm = |f: [f64; 3]| f.iter().map(|x| x * x).sum::<f64>().sqrt();
    // B held 1.5 mm in, A pressed 1 and 2 mm in: both push, and B's push weakens as A draws
    // the surface under it down
    let alone_b = pipe.tick(&tip(near, 1.5e-3, 1));
    let mut before = norm(alone_b.force_n);
    for depth_a in [1e-3, 2e-3, 3e-3, 4e-3] {
        let tools = [tip(a, depth_a, 0), tip(near, 1.5e-3, 1)];
        let mut states = [TickState::default(); 2];
        pipe.tick_tools(&tools, &mut states);
        let delta: Vec<[f64; 3]> = states.iter().map(|s| s.contact.expect("both in contact").imposed_m).collect();
        for s in &states {
            let c = s.contact.unwrap();
            assert!(c.weights.iter().any(|&w| w > 1.0 - 1e-6), "the proxy stays on its node: {c:?}");
        }
        let normals = [crate::common::node_normal(&b, a), crate::common::node_normal(&b, near)];
        let want = unilateral(&full, &delta, &normals);
        // the vademecum's error is relative to the field each load makes: to the larger of
        // the forces each tool would need alone
        let fa = (0..2)
            .map(|i| norm(solve_dense(&[vec![full[i][i]]], &delta[i..=i])[0]))
            .fold(0.0, f64::max);
        for (t, (s, w)) in states.iter().zip(&want).enumerate() {
            // the force on the tool is the reaction to the force on the tissue
            let got = s.force_n.map(|x| -x);
            let e = dist(got, *w);
            let estimate = s.force_error_n.expect("an estimate");
            let n = normals[t];
            eprintln!(
                "A {:.0} mm in: tool {t} full {w:?} N (f·n/|f| {:.2}), pipeline {got:?} N, error {e:.2e} N, estimate {estimate:.2e} N",
                depth_a * 1e3,
                (w[0] * n[0] + w[1] * n[1] + w[2] * n[2]) / norm(*w).max(1e-300)
            );
            assert!(
                e < 2e-3 * fa,
                "tool {t}: {got:?} against the full model's {w:?} N ({:.1e} of the larger force alone)",
                e / fa
            );
            assert!(estimate >= e, "tool {t}: estimate {estimate:.2e} N below the error {e:.2e} N");
            assert!(
                got.iter().zip(&n).map(|(f, n)| f * n).sum::<f64>() <= 0.0,
                "tool {t} pushes: {got:?}"
            );
        }
        // B, held still, feels A's press: its force falls as A goes in, to nothing where
        // A draws the surface away from under it
        let now = norm(states[1].force_n);
        assert!(now < before - 0.1 || now == 0.0, "B's force went from {before} to {now} N");
        before = now;
    }
    // B barely touching (0.1 mm) while A presses 2 mm: alone B's tissue would have to be
    // pulled up to stay on it, and a probe cannot pull: B lets go, and A's force is its own
    pipe.reset();
    let a_alone = pipe.tick(&tip(a, 2e-3, 0));
    let mut states = [TickState::default(); 2];
    pipe.tick_tools(&[tip(a, 2e-3, 0), tip(near, 1e-4, 1)], &mut states);
    assert_eq!(states[1].force_n, [0.0; 3], "{:?}", states[1]);
    assert!(
        dist(states[0].force_n, a_alone.force_n) <= 1e-12 * norm(a_alone.force_n),
        "{states:?} {a_alone:?}"
    );
    // A alone: the single-tool law at its node
    pipe.reset();
    let one = pipe.tick(&tip(a, 2e-3, 0));
    let single = Vademecum::contact_force(&v.compliance(at(a).0, at(a).1).unwrap(), one.contact.unwrap().imposed_m);
    assert!(dist(one.force_n.map(|x| -x), single) <= 1e-9 * norm(single), "{one:?} {single:?}");
    // a third tool the scene does not name, and tool 0 twice in one tick, are refused
    let mut states = [TickState::default(); 3];
    pipe.tick_tools(&[tip(a, 2e-3, 0), tip(a, 2e-3, 0), tip(near, 1e-3, 2)], &mut states);
    assert!(states[0].events.has(Events::CONTACT), "{:?}", states[0]);
    for s in &states[1..] {
        assert!(s.events.has(Events::REJECTED_INPUT) && s.force_n == [0.0; 3], "{s:?}");
    }
}

/// The per-answer error estimate of two probes pressing together covers the true error
/// against the full model (its contact problem for pushing probes) in at least 95 % of
/// sampled states: every pair of 12 load nodes spread over the organ's top (66 pairs), each
/// probe pressed 0.5–3 mm in along its normal; the states it misses are printed.
#[test]
fn the_error_estimate_of_two_probes_covers_the_full_models_error() {
    use vademecum_engine::pipeline::{Pipeline, TickState, ToolInput};
    use vademecum_engine::rng::Rng;
    let scene = two_probe_scene();
    let b = bundle(&scene);
    let v = &b.vademecum;
    let loads = v.load_nodes();
    let nodes: Vec<usize> = (0..12).map(|i| loads[(i * loads.len()) / 12 + loads.len() / 24]).collect();
    let full = full_order_compliance(&scene, v, &nodes);
    let mut pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    let mut rng = Rng(0x5eed_0046);
    let r = 0.004;
    let (mut covered, mut samples, mut worst, mut largest) = (0, 0, 0.0f64, 0.0f64);
    let norm = |f: [f64; 3]| f.iter().map(|x| x * x).sum::<f64>().sqrt();
    for i in 0..nodes.len() {
        for j in i + 1..nodes.len() {
            let pair = [nodes[i], nodes[j]];
            let normals = pair.map(|n| crate::common::node_normal(&b, n));
            let depths = [0.0005 + 0.0025 * rng.unit(), 0.0005 + 0.0025 * rng.unit()];
            let tools: Vec<ToolInput> = (0..2)
                .map(|t| ToolInput {
                    tool: t,
                    position_m: [0, 1, 2].map(|k| b.nodes[pair[t]][k] + (r - depths[t]) * normals[t][k]),
                    ..ToolInput::default()
                })
                .collect();
            pipe.reset();
            let mut states = [TickState::default(); 2];
            pipe.tick_tools(&tools, &mut states);
            let delta: Vec<[f64; 3]> = states.iter().map(|s| s.contact.expect("in contact").imposed_m).collect();
            let sub = vec![vec![full[i][i], full[i][j]], vec![full[j][i], full[j][j]]];
            let want = unilateral(&sub, &delta, &normals);
            let alone = (0..2)
                .map(|t| norm(solve_dense(&[vec![sub[t][t]]], &delta[t..=t])[0]))
                .fold(0.0, f64::max);
            for (s, w) in states.iter().zip(&want) {
                let e = dist(s.force_n.map(|x| -x), *w);
                let estimate = s.force_error_n.expect("an estimate");
                samples += 1;
                covered += usize::from(estimate >= e);
                if e > 0.0 {
                    worst = worst.max(e / estimate.max(f64::MIN_POSITIVE));
                }
                largest = largest.max(e / alone);
                if e > 1e-3 * alone || estimate < e {
                    eprintln!(
                        "nodes {pair:?} {:.1} mm apart, depths {depths:?}: got {:?}, full {w:?}, error {e:.2e} N, estimate {estimate:.2e} N, alone {alone:.3} N",
                        1e3 * dist(b.nodes[pair[0]], b.nodes[pair[1]]),
                        s.force_n.map(|x| -x)
                    );
                }
            }
        }
    }
    eprintln!(
        "the estimate covers the error in {covered} of {samples} answers (largest error / estimate {worst:.2}); largest error {largest:.1e} of the larger force alone"
    );
    assert!(covered * 100 >= 95 * samples, "covered {covered} of {samples}");
    // the modes hold the field to 1e-3 over all load states, not every pair's block: measured
    // 2.0e-2 at one pair 14 mm apart, at most 2.5e-3 at the others (BENCHMARKS.md)
    assert!(largest < 3e-2, "an error of {largest:.1e} of the larger force alone");
}

/// A probe held still while the other presses in beside it (the server's two-hands test, at
/// the left probe's spot between two nodes): its force never rises, and eases continuously from
/// the moment the other touches the tissue it moves — the largest change between samples
/// halves when the step halves. (Imposing the whole displacement vector at each contact pinned
/// the tissue's sideways motion under the second probe when it touched: the held probe's force
/// stepped up by 0.065 N whatever the step.)
#[test]
fn a_probe_held_still_eases_continuously_as_the_other_presses_beside_it() {
    use vademecum_engine::pipeline::{Pipeline, TickState, ToolInput};
    let scene = two_probe_scene();
    let b = bundle(&scene);
    let left = ToolInput {
        tool: 1,
        position_m: [0.015, 0.0, 0.025 + 0.004 - 0.0015],
        ..ToolInput::default()
    };
    let mut largest = [0.0; 2];
    for (pass, steps) in [40, 80].into_iter().enumerate() {
        let mut pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
        let mut felt = vec![pipe.tick(&left).force_n[2]];
        let mut engaged = false;
        for i in 1..=steps {
            let depth = 2e-3 * f64::from(i) / f64::from(steps);
            let right = ToolInput {
                tool: 0,
                position_m: [0.0, 0.0, 0.029 - depth],
                ..ToolInput::default()
            };
            let mut states = [TickState::default(); 2];
            pipe.tick_tools(&[right, left], &mut states);
            engaged |= states[0].force_n != [0.0; 3];
            felt.push(states[1].force_n[2]);
        }
        assert!(engaged, "the right probe pushes by 2 mm");
        assert!(felt.windows(2).all(|w| w[1] <= w[0]), "the held probe's force rose: {felt:?}");
        assert!(felt[steps as usize] < felt[0] - 0.5, "{felt:?}");
        largest[pass] = felt.windows(2).map(|w| w[0] - w[1]).fold(0.0, f64::max);
    }
    assert!(largest[1] < 0.6 * largest[0], "a step in the held probe's force: {largest:?} N");
}
