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

#[test]
fn two_tools_pressing_one_organ_feel_each_other_as_the_full_model_says() {
    let scene = Scene::builtin("organ").unwrap();
    let b = bundle(&scene);
    let v = &b.vademecum;
    let loads = v.load_nodes();
    // tool A at the middle load node; tool B at a load node 15–25 mm away (close enough to
    // feel A), and tool C far away (at the farthest load node)
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
            let want = solve_dense(&full, &delta);
            let mut got = [[0.0; 3]; 2];
            coupled_forces(v, &[at(a), at(other)], &delta, &mut got).unwrap();
            let fa = want[0].iter().map(|x| x * x).sum::<f64>().sqrt();
            for (t, (g, w)) in got.iter().zip(&want).enumerate() {
                let e = dist(*g, *w) / fa;
                eprintln!(
                    "A at {:?}, B {:.1} mm away, δ {delta:?}: tool {t} full {w:?} N, coupled {g:?} N, error {e:.2e} of |f_A|",
                    b.nodes[a],
                    1e3 * dist(b.nodes[a], b.nodes[other])
                );
                // the cross blocks of nodes that are not neighbours come from the modes, whose
                // field the build holds to 1e-3 (measured: 8.5e-4 at 19 mm, 2e-5 at 81 mm)
                assert!(e < 2e-3, "tool {t}: {g:?} against the full model's {w:?} N ({e:.2e} of |f_A|)");
            }
            // B's force is not zero: held still, it feels A's press
            assert!(want[1].iter().any(|x| x.abs() > 1e-6 * fa), "{want:?}");
        }
    }
    // one tool alone is the single-tool law
    let mut one = [[0.0; 3]];
    coupled_forces(v, &[at(a)], &[[0.0, 0.0, -0.002]], &mut one).unwrap();
    let single = Vademecum::contact_force(&v.compliance(at(a).0, at(a).1).unwrap(), [0.0, 0.0, -0.002]);
    assert!(
        dist(one[0], single) <= 1e-12 * single.iter().map(|x| x.abs()).sum::<f64>(),
        "{one:?} {single:?}"
    );
    // two tools on the same spot are refused, not solved into nonsense
    let mut two = [[0.0; 3]; 2];
    assert_eq!(
        coupled_forces(v, &[at(a), at(a)], &[[0.0, 0.0, -0.002]; 2], &mut two),
        Err(CoupledError::Singular)
    );
}
