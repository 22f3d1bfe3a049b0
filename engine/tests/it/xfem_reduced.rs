//! Reduced online cutting against the full-order XFEM on the same mesh and cut (issue 15,
//! engine part 2): the PGD modes of the patch's vademecum as a Ritz basis (PRB and SRB),
//! bordered with the enriched nodes as the cut grows.

use crate::common;
use vademecum_engine::geometry::cut::Cut;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pgd::PgdParams;
use vademecum_engine::scene::Scene;
use vademecum_engine::xfem::reduced::{Discontinuous, ReducedCut, ReducedError, RitzBasis};
use vademecum_engine::xfem::system;
use vademecum_engine::xfem::{Enrichment, Front, XfemParams};

/// The reduced cutting model of a built organ, with the default XFEM settings.
fn reduced(b: &offline::Built, basis: RitzBasis, disc: Discontinuous) -> ReducedCut {
    reduced_with(b, basis, disc, &XfemParams::default())
}

/// [`reduced`] with the XFEM settings `params`.
fn reduced_with(b: &offline::Built, basis: RitzBasis, disc: Discontinuous, params: &XfemParams) -> ReducedCut {
    let (m, v) = (&b.model, &b.vademecum);
    ReducedCut::new(
        &m.mesh,
        &m.materials,
        m.locking,
        &m.problem,
        v.f_raw(),
        v.modes(),
        basis,
        disc,
        params,
    )
    .unwrap()
}

fn built(scene: &Scene, tolerance: f64) -> offline::Built {
    let opts = BuildOptions {
        params: PgdParams {
            global_tolerance: tolerance,
            enrichment_tolerance: 1e-8,
            max_modes: 400,
            max_iterations: 60,
            block: 1,
        },
        tolerance,
        recompress: true,
        load_radius: 0.0,
        large: None,
        max_memory: None,
        tear_target_error: None,
        large_target_error: None,
        cut_target_error: None,
    };
    offline::build_organ(scene, 0, &opts, &mut |_| {}).unwrap()
}

/// Relative L2 error of the reduced fields against the full XFEM, over every node's both sides.
fn error(enr: &Enrichment, u: &[f64], q: &[f64], full: &system::XfemSolution) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    let n = u.len() / 3;
    for a in 0..n {
        for positive in [true, false] {
            let f = full.side_displacement(enr, a, positive);
            let mut r = [u[3 * a], u[3 * a + 1], u[3 * a + 2]];
            if let Some(k) = enr.index(a) {
                let s = enr.shifted(k, positive);
                for i in 0..3 {
                    r[i] += s * q[3 * k + i];
                }
            }
            for i in 0..3 {
                num += (r[i] - f[i]).powi(2);
                den += f[i] * f[i];
            }
        }
    }
    (num / den).sqrt()
}

#[test]
fn prb_and_srb_follow_the_full_xfem_on_the_patch_as_the_cut_grows() {
    let scene = Scene::builtin("patch").unwrap();
    let b = built(&scene, 1e-4);
    let m = &b.model;
    let params = XfemParams::default();
    for basis in [RitzBasis::Prb, RitzBasis::Srb] {
        let mut errors = Vec::new();
        for disc in [Discontinuous::Bare, Discontinuous::LocalFields] {
            let mut red = reduced(&b, basis, disc);
            // the blade goes down the plane x = 2 from the top, one cell row at a time
            for (step, depth) in [4.0, 3.0, 2.0].into_iter().enumerate() {
                let cut = Cut::swept(&[([2.0, -0.1, 5.1], [2.0, 1.1, 5.1]), ([2.0, -0.1, depth], [2.0, 1.1, depth])]).unwrap();
                let cells = Enrichment::cut_cells(&m.mesh, &cut, &params).unwrap();
                let up = red.cut(&m.mesh, &cells).unwrap();
                assert_eq!(up.new_nodes.len(), if step == 0 { 4 } else { 2 });
                let enr = red.enrichment().clone();
                let full = system::solve(&m.mesh, &m.materials, m.locking, &m.problem, &enr, &params).unwrap();
                let (u, q) = red.displacements(&m.problem.forces);
                let e = error(&enr, &u, &q, &full);
                eprintln!(
                    "{} {disc:?} depth {depth}: {} enriched, dim {}, L2 error {e:.3e}",
                    basis.name(),
                    enr.len(),
                    red.dim()
                );
                assert!(e.is_finite());
                errors.push((disc, e));
            }
        }
        // with local fields the answer is the full XFEM's up to the modes' error on the uncut
        // response (the vademecum's tolerance, 1e-4): far below the seed's 7e-3
        for (disc, e) in &errors {
            match disc {
                Discontinuous::LocalFields => assert!(*e < 1e-3, "{} local fields: {e:.3e}", basis.name()),
                Discontinuous::Bare => assert!(*e < 1.0, "{} bare: {e:.3e}", basis.name()),
            }
        }
    }
}

/// With the crack front shared (`fidelity.xfem.front = "shared"`) the online model grows its
/// cut as the full XFEM does: each step cracks the nodes the blade has passed — the new row's
/// front stays shared, the last step's front is cracked — and its field follows the full XFEM's
/// with the same front to the modes' error.
#[test]
fn with_the_front_shared_the_reduced_model_follows_the_full_xfem_as_the_cut_grows() {
    let scene = Scene::builtin("patch").unwrap();
    let b = built(&scene, 1e-4);
    let m = &b.model;
    let params = XfemParams {
        front: Front::Shared,
        ..XfemParams::default()
    };
    let mut red = reduced_with(&b, RitzBasis::Srb, Discontinuous::LocalFields, &params);
    for depth in [4.0, 3.0, 2.0] {
        let cut = Cut::swept(&[([2.0, -0.1, 5.1], [2.0, 1.1, 5.1]), ([2.0, -0.1, depth], [2.0, 1.1, depth])]).unwrap();
        let cells = Enrichment::cut_cells(&m.mesh, &cut, &params).unwrap();
        let up = red.cut(&m.mesh, &cells).unwrap();
        // the two nodes of the row above the blade's edge; those on its edge stay shared
        assert_eq!(up.new_nodes.len(), 2, "depth {depth}");
        let enr = red.enrichment().clone();
        assert!(
            enr.nodes.iter().all(|&a| m.mesh.nodes[a][2] > depth + 0.5),
            "depth {depth}: {:?}",
            enr.nodes
        );
        assert_eq!(enr.front.len(), 2, "depth {depth}");
        // the same as enriching the whole cut at once
        let once = Enrichment::from_cut(&m.mesh, &cut, &params).unwrap();
        let (mut a, mut o) = (enr.nodes.clone(), once.nodes.clone());
        a.sort_unstable();
        o.sort_unstable();
        assert_eq!(a, o, "depth {depth}");
        let full = system::solve(&m.mesh, &m.materials, m.locking, &m.problem, &enr, &params).unwrap();
        let (u, q) = red.displacements(&m.problem.forces);
        let e = error(&enr, &u, &q, &full);
        eprintln!("front shared, depth {depth}: {} enriched, L2 error {e:.3e}", enr.len());
        assert!(e < 1e-3, "depth {depth}: {e:.3e}");
    }
}

#[test]
fn bordering_step_by_step_equals_cutting_at_once() {
    let scene = Scene::builtin("patch").unwrap();
    let b = built(&scene, 1e-4);
    let m = &b.model;
    let params = XfemParams::default();
    let cut = |depth: f64| Cut::swept(&[([2.0, -0.1, 5.1], [2.0, 1.1, 5.1]), ([2.0, -0.1, depth], [2.0, 1.1, depth])]).unwrap();
    for disc in [Discontinuous::Bare, Discontinuous::LocalFields] {
        let new = || reduced(&b, RitzBasis::Srb, disc);
        let (mut steps, mut once) = (new(), new());
        for depth in [4.0, 3.0, 2.0] {
            steps
                .cut(&m.mesh, &Enrichment::cut_cells(&m.mesh, &cut(depth), &params).unwrap())
                .unwrap();
        }
        once.cut(&m.mesh, &Enrichment::cut_cells(&m.mesh, &cut(2.0), &params).unwrap())
            .unwrap();
        assert_eq!(steps.dim(), once.dim());
        // the same unknowns, possibly in another order: compare the fields
        let fields = |r: &ReducedCut| {
            let (u, q) = r.displacements(&m.problem.forces);
            let mut jumps: Vec<(usize, [f64; 3])> = r
                .enrichment()
                .nodes
                .iter()
                .enumerate()
                .map(|(k, &a)| (a, [q[3 * k], q[3 * k + 1], q[3 * k + 2]]))
                .collect();
            jumps.sort_by_key(|j| j.0);
            (u, jumps)
        };
        let ((u1, q1), (u2, q2)) = (fields(&steps), fields(&once));
        let umax = u2.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(u1.iter().zip(&u2).all(|(a, b)| (a - b).abs() < 1e-10 * umax), "{disc:?}");
        for ((a1, j1), (a2, j2)) in q1.iter().zip(&q2) {
            assert_eq!(a1, a2);
            assert!((0..3).all(|i| (j1[i] - j2[i]).abs() < 1e-10 * umax), "{disc:?} node {a1}");
        }
    }
}

#[test]
fn the_contact_table_answers_the_forward_substitution_as_the_cut_grows() {
    // a model keeping the contact table of the patch's loadable nodes against the same model
    // without one, after every step of a cut that grows, at patches of tabulated nodes (the
    // table's answer) and with a node outside it (the substitution's): the same compliance
    let scene = Scene::builtin("patch").unwrap();
    let b = built(&scene, 1e-4);
    let m = &b.model;
    let params = XfemParams::default();
    let cut = |depth: f64| Cut::swept(&[([2.0, -0.1, 5.1], [2.0, 1.1, 5.1]), ([2.0, -0.1, depth], [2.0, 1.1, depth])]).unwrap();
    let loadable = b.vademecum.load_nodes().to_vec();
    let other = (0..m.mesh.n_nodes()).find(|a| !loadable.contains(a)).unwrap();
    for disc in [Discontinuous::Bare, Discontinuous::LocalFields] {
        let (mut plain, mut kept) = (reduced(&b, RitzBasis::Srb, disc), reduced(&b, RitzBasis::Srb, disc));
        kept.tabulate(&loadable);
        assert_eq!(kept.table_bytes() > 0, !loadable.is_empty());
        for depth in [4.0, 3.0, 2.0] {
            let cells = Enrichment::cut_cells(&m.mesh, &cut(depth), &params).unwrap();
            plain.cut(&m.mesh, &cells).unwrap();
            let up = kept.cut(&m.mesh, &cells).unwrap();
            assert!(up.tabulating_s >= 0.0);
            let (mut p, mut k) = (plain.view(), kept.view());
            let mut largest = 0.0f64;
            for (n, &a) in loadable.iter().enumerate() {
                let c = loadable[(n + 1) % loadable.len()];
                // every fifth patch with a node out of the table, every seventh with it at
                // zero weight (a contact's node the vademecum cannot load)
                let third = if n % 5 == 0 || n % 7 == 0 {
                    other
                } else {
                    loadable[(n + 2) % loadable.len()]
                };
                let w = if n % 7 == 0 { [0.6, 0.4, 0.0] } else { [0.5, 0.3, 0.2] };
                let nodes = [a, c, third];
                for (x, y) in [
                    (p.added_compliance(&nodes, &w), k.added_compliance(&nodes, &w)),
                    (p.contact_compliance(&nodes, &w), k.contact_compliance(&nodes, &w)),
                ] {
                    let scale = x[0][0].abs().max(x[1][1].abs()).max(x[2][2].abs()).max(1e-30);
                    for i in 0..3 {
                        for j in 0..3 {
                            assert!((x[i][j] - y[i][j]).abs() <= 1e-10 * scale, "{disc:?} {nodes:?}: {x:?} {y:?}");
                        }
                    }
                }
                largest = largest.max(p.added_compliance(&nodes, &w)[2][2]);
            }
            assert!(largest > 0.0, "{disc:?}: the cut adds compliance at the top");
        }
    }
}

#[test]
fn the_cut_compliance_at_a_node_is_the_full_xfem_displacement_per_unit_force() {
    let scene = Scene::builtin("patch").unwrap();
    let b = built(&scene, 1e-4);
    let m = &b.model;
    let params = XfemParams::default();
    let cut = Cut::swept(&[([2.0, -0.1, 5.1], [2.0, 1.1, 5.1]), ([2.0, -0.1, 3.0], [2.0, 1.1, 3.0])]).unwrap();
    let cells = Enrichment::cut_cells(&m.mesh, &cut, &params).unwrap();
    // the node at the top right of the cut's lip
    let node = (0..m.mesh.n_nodes()).find(|&a| m.mesh.nodes[a] == [3.0, 0.0, 5.0]).unwrap();
    for disc in [Discontinuous::Bare, Discontinuous::LocalFields] {
        let mut red = reduced(&b, RitzBasis::Srb, disc);
        red.cut(&m.mesh, &cells).unwrap();
        let c = red.contact_compliance(&[node], &[1.0]);
        let enr = red.enrichment().clone();
        let mut worst: f64 = 0.0;
        let mut scale: f64 = 0.0;
        for d in 0..3 {
            let mut p = m.problem.clone();
            p.forces.fill(0.0);
            p.forces[3 * node + d] = 1.0;
            let full = system::solve(&m.mesh, &m.materials, m.locking, &p, &enr, &params).unwrap();
            for i in 0..3 {
                worst = worst.max((c[i][d] - full.u[3 * node + i]).abs());
                scale = scale.max(full.u[3 * node + i].abs());
            }
        }
        eprintln!("{disc:?}: compliance error {:.3e} of {scale:.3e}", worst);
        if disc == Discontinuous::LocalFields {
            assert!(worst < 1e-3 * scale, "{worst:.3e} of {scale:.3e}");
        }
        assert!(c.iter().flatten().all(|x| x.is_finite()));
    }
}

/// The built-in 4 × 1 × 1 bar with `divisions` cells, clamped at x = 0, its free end's upper
/// corner loaded downwards by 1 N.
fn bar(divisions: [usize; 3]) -> Scene {
    let [i, j, k] = divisions;
    let text = common::with_keys(
        vademecum_engine::scene::builtin("bar").unwrap(),
        &[("organs[0].mesh.divisions", vec![i as i64, j as i64, k as i64].into())],
    );
    Scene::from_toml(&text, "bar.toml").unwrap()
}

/// The patch's reduced model (local fields, SRB) and an online scalpel on it.
fn patch_scalpel() -> (offline::Built, vademecum_engine::xfem::online::OnlineCut) {
    let scene = Scene::builtin("patch").unwrap();
    let b = built(&scene, 1e-4);
    let params = XfemParams::default();
    let red = reduced(&b, RitzBasis::Srb, Discontinuous::LocalFields);
    let online = vademecum_engine::xfem::online::OnlineCut::new(&b.model.mesh, red, 1.0, &params).unwrap();
    (b, online)
}

#[test]
fn a_scalpel_drawn_down_with_enough_force_cuts_cell_by_cell() {
    use vademecum_engine::xfem::blade::Blade;
    let (b, mut s) = patch_scalpel();
    let mesh = &b.model.mesh;
    // the blade across the depth, in the plane x = 4 (normal x: a quarter turn about z), drawn
    // down from above the top to z = 3.9 in 1,000 ticks, the tissue resisting with 2 N upwards
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let q = [h, 0.0, 0.0, -h];
    let mut cracked = Vec::new();
    for i in 0..=1000 {
        let z = 5.1 - 1.2 * i as f64 / 1000.0;
        let blade = Blade::new([4.0, -0.1, z], [4.0, 1.1, z], q).unwrap();
        assert!((blade.normal[0].abs() - 1.0).abs() < 1e-12);
        let step = s.step(mesh, &blade, [0.0, 0.0, 2.0]).unwrap();
        assert!(step.cutting && (step.split.in_plane() - 2.0).abs() < 1e-12);
        cracked.push(s.model().enrichment().len());
    }
    // the top cell row is cut once the blade has crossed it: the two cells at x = 4, their four
    // nodes on the plane cracked — the pre-planned patch_cut
    assert_eq!(s.model().enrichment().cut_cells.len(), 2);
    let mut nodes: Vec<[f64; 3]> = s.model().enrichment().nodes.iter().map(|&a| mesh.nodes[a]).collect();
    nodes.sort_by(|a, b| a.partial_cmp(b).unwrap());
    assert_eq!(nodes, vec![[4.0, 0.0, 4.0], [4.0, 0.0, 5.0], [4.0, 1.0, 4.0], [4.0, 1.0, 5.0]]);
    // and only once the blade reached the bottom of the row (z = 4, at tick 917) to within the
    // coverage tolerance (5 % of the cell's size √3: z = 4.087, tick 844)
    let first = cracked.iter().position(|&n| n > 0).unwrap();
    assert!((844..=917).contains(&first), "cracked at tick {first}");
}

#[test]
fn friction_pressing_the_flat_and_bad_forces_cut_nothing() {
    use vademecum_engine::xfem::blade::Blade;
    let (b, mut s) = patch_scalpel();
    let mesh = &b.model.mesh;
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let q = [h, 0.0, 0.0, -h];
    for i in 0..=1000 {
        let z = 5.1 - 1.2 * i as f64 / 1000.0;
        let blade = Blade::new([4.0, -0.1, z], [4.0, 1.1, z], q).unwrap();
        // below the threshold (friction), normal to the blade (the flat), or not finite
        let f = match i % 3 {
            0 => [0.0, 0.0, 0.9],
            1 => [50.0, 0.0, 0.0],
            _ => [f64::NAN, 0.0, 1e9],
        };
        let step = s.step(mesh, &blade, f).unwrap();
        assert!(!step.cutting, "tick {i}: {f:?}");
    }
    assert!(s.model().enrichment().is_empty() && s.cut().is_none());
}

#[test]
fn a_trembling_blade_and_a_blade_back_in_its_cut_stay_bounded() {
    use vademecum_engine::xfem::blade::Blade;
    let (b, mut s) = patch_scalpel();
    let mesh = &b.model.mesh;
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let q = [h, 0.0, 0.0, -h];
    // 1,000 ticks trembling up and down across the top cell row
    for i in 0..1000 {
        let z = if i % 2 == 0 { 5.1 } else { 3.9 };
        let blade = Blade::new([4.0, -0.1, z], [4.0, 1.1, z], q).unwrap();
        s.step(mesh, &blade, [0.0, 0.0, 2.0]).unwrap();
    }
    assert_eq!(s.model().enrichment().len(), 4);
    // back in the cut: reported, nothing new
    let blade = Blade::new([4.0, -0.1, 4.5], [4.0, 1.1, 4.5], q).unwrap();
    let step = s.step(mesh, &blade, [0.0, 0.0, 0.5]).unwrap();
    assert!(step.in_cut && !step.cutting && step.new_nodes == 0);
    let c = s.model_mut().contact_compliance(&[0], &[1.0]);
    assert!(c.iter().flatten().all(|x| x.is_finite()));
}

#[test]
fn on_the_organ_cutting_adds_no_error_to_the_local_fields_model() {
    // the built-in organ's own vademecum (default build) and load; a cut down the lobe's
    // mid-plane x = 0 over its front half. With local fields the reduced answer is exact up to
    // the modes' error on the uncut response, so the error with the cut is the error without
    let scene = Scene::builtin("organ").unwrap();
    let b = offline::build_organ(&scene, 0, &BuildOptions::for_scene(&scene, true), &mut |_| {}).unwrap();
    let m = &b.model;
    let params = XfemParams::default();
    let mut red = reduced(&b, RitzBasis::Prb, Discontinuous::LocalFields);
    let uncut_full = system::solve(&m.mesh, &m.materials, m.locking, &m.problem, red.enrichment(), &params).unwrap();
    let (u, q) = red.displacements(&m.problem.forces);
    let e_uncut = error(red.enrichment(), &u, &q, &uncut_full);
    let cut = Cut::swept(&[([0.0, -0.01, 0.08], [0.0, 0.06, 0.08]), ([0.0, -0.01, 0.0], [0.0, 0.06, 0.0])]).unwrap();
    red.cut(&m.mesh, &Enrichment::cut_cells(&m.mesh, &cut, &params).unwrap()).unwrap();
    let enr = red.enrichment().clone();
    assert!(enr.len() > 20);
    let full = system::solve(&m.mesh, &m.materials, m.locking, &m.problem, &enr, &params).unwrap();
    let (u, q) = red.displacements(&m.problem.forces);
    let e_cut = error(&enr, &u, &q, &full);
    eprintln!("organ: {} cracked nodes; error uncut {e_uncut:.3e}, cut {e_cut:.3e}", enr.len());
    assert!(e_cut <= 1.5 * e_uncut + 1e-9, "uncut {e_uncut:.3e}, cut {e_cut:.3e}");
    assert!(e_cut < 0.05, "{e_cut:.3e}");
}

#[test]
fn without_modes_the_local_fields_model_adds_the_same_compliance_and_bare_needs_them() {
    // what a session builds (the cut's part alone) against the model on the modes: the same
    // added compliance at every top node of the patch, cut down x = 4 through the top row
    let scene = Scene::builtin("patch").unwrap();
    let b = built(&scene, 1e-4);
    let m = &b.model;
    let params = XfemParams::default();
    let mut full = reduced(&b, RitzBasis::Srb, Discontinuous::LocalFields);
    let new = |disc| ReducedCut::new(&m.mesh, &m.materials, m.locking, &m.problem, &[], 0, RitzBasis::Srb, disc, &params);
    let mut bare = new(Discontinuous::LocalFields).unwrap();
    assert_eq!(bare.basis_size(), 0);
    assert!(matches!(new(Discontinuous::Bare), Err(ReducedError::EmptyBasis)));
    let cut = Cut::swept(&[([4.0, -0.1, 5.1], [4.0, 1.1, 5.1]), ([4.0, -0.1, 3.95], [4.0, 1.1, 3.95])]).unwrap();
    let cells = Enrichment::cut_cells(&m.mesh, &cut, &params).unwrap();
    full.cut(&m.mesh, &cells).unwrap();
    bare.cut(&m.mesh, &cells).unwrap();
    let (mut fv, mut bv) = (full.view(), bare.view());
    let mut largest = 0.0f64;
    for a in (0..m.mesh.n_nodes()).filter(|&a| m.mesh.nodes[a][2] == 5.0) {
        let (x, y) = (fv.added_compliance(&[a], &[1.0]), bv.added_compliance(&[a], &[1.0]));
        for i in 0..3 {
            for j in 0..3 {
                assert!(
                    (x[i][j] - y[i][j]).abs() <= 1e-12 * x[i][i].abs().max(1e-30),
                    "node {a}: {x:?} {y:?}"
                );
                largest = largest.max(x[i][j].abs());
            }
        }
    }
    assert!(largest > 0.0, "the cut adds compliance at the top");
}

#[test]
fn the_walls_a_viewer_draws_part_as_the_full_xfem_opens() {
    // the patch cut down x = 4 through the top row (a cut on cell faces), 1 N down on a top
    // node beside it: the picture's walls — the uncut response plus what the cut adds, and the
    // opening on the copies — are the full XFEM's split mesh, to solver precision (the local
    // fields are exact given the uncut response)
    use vademecum_engine::pipeline::cutting::CutPicture;
    let scene = Scene::builtin("patch").unwrap();
    let b = built(&scene, 1e-4);
    let m = &b.model;
    let params = XfemParams::default();
    let mut model = ReducedCut::new(
        &m.mesh,
        &m.materials,
        m.locking,
        &m.problem,
        &[],
        0,
        RitzBasis::Srb,
        Discontinuous::LocalFields,
        &params,
    )
    .unwrap();
    let cut = Cut::swept(&[([4.0, -0.1, 5.1], [4.0, 1.1, 5.1]), ([4.0, -0.1, 3.95], [4.0, 1.1, 3.95])]).unwrap();
    let cells = Enrichment::cut_cells(&m.mesh, &cut, &params).unwrap();
    model.cut(&m.mesh, &cells).unwrap();
    let picture = CutPicture::new(0, 1, &m.mesh, &model);
    let enr = model.enrichment().clone();
    let walls = &picture.walls;
    assert!(!walls.is_empty());
    assert!(walls.vertices.iter().any(|v| v.copy.is_some()) && walls.vertices.iter().any(|v| v.copy.is_none()));
    assert!(walls.triangles.iter().flatten().all(|&t| (t as usize) < walls.vertices.len()));
    // the two walls of the face x = 4 of the top row, each two triangles, and the wedges of
    // the crack front below it
    let on_plane = walls.vertices.iter().all(|v| m.mesh.nodes[v.node][0] == 4.0);
    assert!(on_plane, "every wall vertex lies in the cut's plane");
    let a = (0..m.mesh.n_nodes()).find(|&a| m.mesh.nodes[a] == [3.0, 0.0, 5.0]).unwrap();
    let force = [0.0, 0.0, -1.0];
    let mut problem = m.problem.clone();
    problem.forces.fill(0.0);
    problem.forces[3 * a + 2] = -1.0;
    let uncut = system::solve(&m.mesh, &m.materials, m.locking, &problem, &Enrichment::none(&m.mesh), &params).unwrap();
    let full = system::solve(&m.mesh, &m.materials, m.locking, &problem, &enr, &params).unwrap();
    let mut coeffs = vec![0.0; picture.view.dim()];
    picture.view.added_response(&[a], &[1.0], force, &mut coeffs);
    let u0: Vec<f64> = picture
        .wall_nodes
        .iter()
        .flat_map(|&n| uncut.u[3 * n..3 * n + 3].to_vec())
        .collect();
    let mut drawn = Vec::new();
    picture.wall_displacements(&coeffs, &u0, &mut drawn);
    let scale = full.u.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    let mut opening = 0.0f64;
    for (v, d) in walls.vertices.iter().zip(drawn.chunks_exact(3)) {
        let positive = match (enr.index(v.node), v.copy) {
            (Some(k), None) => enr.own_positive[k],
            (Some(k), Some(_)) => !enr.own_positive[k],
            (None, _) => true,
        };
        let f = full.side_displacement(&enr, v.node, positive);
        for i in 0..3 {
            assert!(
                (f64::from(d[i]) - f[i]).abs() <= 1e-6 * scale,
                "node {} {:?}: {d:?} vs {f:?}",
                v.node,
                v.copy
            );
        }
        if let Some(k) = enr.index(v.node) {
            opening = opening.max((0..3).map(|i| full.q[3 * k + i].powi(2)).sum::<f64>().sqrt());
        }
    }
    assert!(opening > 1e-3 * scale, "the load opens the cut: {opening} against {scale}");
}

#[test]
fn a_piece_with_uncut_nodes_cut_loose_is_refused_or_bounded() {
    // the bar of eight cells clamped at x = 0, cut through at x = 2.25 (through cells, not
    // nodes): the free end, with uncut nodes inside it, holds on to nothing
    let scene = bar([8, 2, 2]);
    let b = built(&scene, 1e-6);
    let m = &b.model;
    let params = XfemParams::default();
    let through = Cut::swept(&[([2.25, -0.1, 1.1], [2.25, 1.1, 1.1]), ([2.25, -0.1, -0.1], [2.25, 1.1, -0.1])]).unwrap();
    let cells = Enrichment::cut_cells(&m.mesh, &through, &params).unwrap();
    for (basis, disc) in [
        (RitzBasis::Srb, Discontinuous::LocalFields),
        (RitzBasis::Prb, Discontinuous::LocalFields),
        (RitzBasis::Srb, Discontinuous::Bare),
        (RitzBasis::Prb, Discontinuous::Bare),
    ] {
        let mut red = reduced(&b, basis, disc);
        let (u0, _) = red.displacements(&m.problem.forces);
        let size0 = u0.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let before = red.dim();
        let outcome = red.cut(&m.mesh, &cells);
        let (u, q) = red.displacements(&m.problem.forces);
        assert!(u.iter().chain(&q).all(|x| x.is_finite()));
        let size = u.iter().chain(&q).fold(0.0f64, |a, v| a.max(v.abs()));
        println!(
            "{basis:?} {disc:?}: {:?}; largest displacement {size:.2e} (uncut {size0:.2e})",
            outcome.as_ref().map(|_| ())
        );
        match disc {
            // the local fields' Schur complement is singular with the piece (its free motion is
            // in their span): a typed error, the model left at the previous cut
            Discontinuous::LocalFields => {
                assert!(matches!(outcome, Err(ReducedError::Singular { .. })), "{outcome:?}");
                assert_eq!(red.dim(), before);
                assert_eq!(size, size0);
            }
            // the bare enrichment cannot move the piece's uncut nodes alone (the modes are the
            // uncut organ's): the basis holds the piece, the answer stays of the order of the
            // uncut one (measured 2.4 and 1.2 times it)
            Discontinuous::Bare => {
                assert!(outcome.is_ok(), "{outcome:?}");
                assert!(size < 10.0 * size0, "{size:e} against {size0:e}");
            }
        }
    }
}
