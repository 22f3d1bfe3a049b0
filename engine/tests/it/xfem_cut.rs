//! The full-order XFEM cut (issue 15, engine part 1): the identity check — a cut lying on cell
//! faces gives, to solver precision, the answer of the same mesh with the nodes on those faces
//! duplicated — on a block of hexahedra and of tetrahedra and on the built-in organ, and the
//! hard cases (a cut through nodes, a sliver, a detached piece, a cut reaching the fixed
//! boundary, ν = 0.499, bad blades), each with a finite, bounded answer or a typed error.

use crate::common;

use vademecum_engine::fem::Locking;
use vademecum_engine::fem::assembly::MaterialMap;
use vademecum_engine::fem::linear_static::{self, StaticProblem};
use vademecum_engine::geometry::cut::{Cut, CutError};
use vademecum_engine::material::LinearElastic;
use vademecum_engine::mesh::Mesh;
use vademecum_engine::mesh::procedural::{self, LobeParams};
use vademecum_engine::xfem::identity;
use vademecum_engine::xfem::system::{self, XfemSolution};
use vademecum_engine::xfem::{Detached, Enrichment, Front, XfemParams};

fn materials(mesh: &Mesh, poisson: f64) -> MaterialMap {
    MaterialMap::uniform(LinearElastic::new(1e4, poisson).unwrap(), 1000.0, mesh.n_cells())
}

/// Solves the cut problem by XFEM and on the duplicated mesh; returns the largest difference
/// of any node's displacement on either side, relative to the largest displacement.
fn identity_gap(mesh: &Mesh, locking: Locking, problem: &StaticProblem, enr: &Enrichment) -> (f64, XfemSolution) {
    let mats = materials(mesh, 0.3);
    let x = system::solve(mesh, &mats, locking, problem, enr, &XfemParams::default()).unwrap();
    (identity::identity_gap(mesh, &mats, locking, problem, enr, &x).unwrap(), x)
}

/// A 4 × 2 × 3 block of unit cells, clamped at its base, its top pulled apart across x = 2.
fn block(tets: bool) -> (Mesh, StaticProblem) {
    let mesh = if tets {
        procedural::block_tet([0.0; 3], [4.0, 2.0, 3.0], [4, 2, 3])
    } else {
        procedural::block_hex([0.0; 3], [4.0, 2.0, 3.0], [4, 2, 3])
    };
    let mut p = StaticProblem::new(mesh.n_nodes());
    for (a, x) in mesh.nodes.iter().enumerate() {
        if x[2] == 0.0 {
            p.clamp(&[a]);
        }
        if x[2] == 3.0 {
            // none on the plane x = 2: a force on a cracked node acts on the node's own side,
            // which depends on where the plane passes
            if x[0] != 2.0 {
                p.forces[3 * a] = (x[0] - 2.0).signum();
                p.forces[3 * a + 2] = -0.5;
            }
        }
    }
    (mesh, p)
}

/// The blade drawn down the plane x = 2 from above the top to height `depth`, across the block.
fn face_cut(depth: f64) -> Cut {
    Cut::swept(&[([2.0, -0.1, 3.1], [2.0, 2.1, 3.1]), ([2.0, -0.1, depth], [2.0, 2.1, depth])]).unwrap()
}

#[test]
fn a_cut_on_cell_faces_equals_duplicated_nodes_on_a_block_of_hexahedra() {
    let (mesh, p) = block(false);
    let enr = Enrichment::from_cut(&mesh, &face_cut(1.0), &XfemParams::default()).unwrap();
    // the cells on both sides of x = 2 between z = 1 and 3; the nodes on the plane at z = 1, 2, 3
    assert_eq!(enr.cut_cells.len(), 2 * 2 * 2);
    assert_eq!(enr.len(), 3 * 3, "enriched {:?}", enr.nodes);
    assert!(enr.nodes.iter().all(|&a| mesh.nodes[a][0] == 2.0 && mesh.nodes[a][2] >= 1.0));
    for locking in [Locking::None, Locking::Bbar] {
        let (gap, x) = identity_gap(&mesh, locking, &p, &enr);
        assert!(gap < 1e-10, "{locking:?}: relative gap {gap:.3e}");
        assert!(x.residual < 1e-10 && x.detached.is_empty());
        // and the cut opens: the top nodes on x = 2 separate
        let top = (0..mesh.n_nodes()).find(|&a| mesh.nodes[a] == [2.0, 0.0, 3.0]).unwrap();
        let k = enr.index(top).unwrap();
        assert!(x.q[3 * k].abs() > 1e-5, "jump {:?}", &x.q[3 * k..3 * k + 3]);
    }
}

#[test]
fn a_cut_on_cell_faces_equals_duplicated_nodes_on_a_block_of_tetrahedra() {
    let (mesh, p) = block(true);
    let enr = Enrichment::from_cut(&mesh, &face_cut(1.0), &XfemParams::default()).unwrap();
    assert_eq!(enr.len(), 9);
    let (gap, x) = identity_gap(&mesh, Locking::None, &p, &enr);
    assert!(gap < 1e-10, "relative gap {gap:.3e}");
    assert!(x.residual < 1e-10);
}

#[test]
fn a_cut_on_cell_faces_equals_duplicated_nodes_on_the_organ() {
    // the built-in lobe: its mid-plane x = 0 is a plane of cell faces
    let mesh = procedural::lobe(&LobeParams::default());
    let mut p = StaticProblem::new(mesh.n_nodes());
    let mut top = [(f64::MIN, 0usize); 2];
    for (a, x) in mesh.nodes.iter().enumerate() {
        if x[1] <= -0.04 {
            p.clamp(&[a]);
        }
        // the highest node on each side near y = 0.02
        let side = usize::from(x[0] > 0.0);
        if x[0].abs() > 0.005 && x[0].abs() < 0.015 && (x[1] - 0.02).abs() < 0.006 && x[2] > top[side].0 {
            top[side] = (x[2], a);
        }
    }
    p.forces[3 * top[0].1] = -0.5;
    p.forces[3 * top[1].1] = 0.5;
    // the blade goes down x = 0 to mid-height over the front half of the lobe
    let cut = Cut::swept(&[([0.0, -0.01, 0.08], [0.0, 0.06, 0.08]), ([0.0, -0.01, 0.0], [0.0, 0.06, 0.0])]).unwrap();
    let enr = Enrichment::from_cut(&mesh, &cut, &XfemParams::default()).unwrap();
    assert!(enr.len() > 20, "{} enriched nodes", enr.len());
    assert!(enr.nodes.iter().all(|&a| mesh.nodes[a][0].abs() < 1e-12));
    let (gap, x) = identity_gap(&mesh, Locking::None, &p, &enr);
    assert!(gap < 1e-9, "relative gap {gap:.3e}");
    assert!(x.detached.is_empty());
}

#[test]
fn a_cut_across_cells_opens_between_its_two_sides() {
    // a cut half-way between grid planes: every cell it crosses is split, all its nodes enriched
    let (mesh, p) = block(false);
    let cut = Cut::swept(&[([2.5, -0.1, 3.1], [2.5, 2.1, 3.1]), ([2.5, -0.1, 1.0], [2.5, 2.1, 1.0])]).unwrap();
    let enr = Enrichment::from_cut(&mesh, &cut, &XfemParams::default()).unwrap();
    assert_eq!(enr.cut_cells.len(), 2 * 2);
    assert_eq!(enr.len(), 2 * 3 * 3);
    let mats = materials(&mesh, 0.3);
    let x = system::solve(&mesh, &mats, Locking::Bbar, &p, &enr, &XfemParams::default()).unwrap();
    assert!(x.residual < 1e-10);
    // the two lips of the cut at the top separate along x: the node at x = 3 on the cut's
    // positive side moves right of its negative-side neighbour at x = 2 by more than the
    // uncut block lets them
    let uncut = system::solve(&mesh, &mats, Locking::Bbar, &p, &Enrichment::none(&mesh), &XfemParams::default()).unwrap();
    let node = |x: [f64; 3]| (0..mesh.n_nodes()).find(|&a| mesh.nodes[a] == x).unwrap();
    let (l, r) = (node([2.0, 1.0, 3.0]), node([3.0, 1.0, 3.0]));
    let stretch = |s: &XfemSolution| s.u[3 * r] - s.u[3 * l];
    assert!(
        stretch(&x) > 3.0 * stretch(&uncut),
        "cut {:.3e} vs uncut {:.3e}",
        stretch(&x),
        stretch(&uncut)
    );
}

#[test]
fn a_sliver_is_not_enriched_and_the_answer_stays_bounded() {
    // the cut plane 1e-6 away from the grid plane x = 2: nodes at x = 2 have 1e-6 of their
    // support on one side
    let (mesh, p) = block(false);
    let x0 = 2.0 + 1e-6;
    let cut = Cut::swept(&[([x0, -0.1, 3.1], [x0, 2.1, 3.1]), ([x0, -0.1, 1.0], [x0, 2.1, 1.0])]).unwrap();
    let enr = Enrichment::from_cut(&mesh, &cut, &XfemParams::default()).unwrap();
    assert!(!enr.dropped.is_empty());
    assert!(enr.dropped.iter().all(|d| d.fraction < 1e-4));
    let x = system::solve(&mesh, &materials(&mesh, 0.3), Locking::Bbar, &p, &enr, &XfemParams::default()).unwrap();
    assert!(x.residual < 1e-8, "residual {:.3e}", x.residual);
    // the same opening as the cut on the grid plane, to the sliver's size
    let on_plane = Enrichment::from_cut(&mesh, &face_cut(1.0), &XfemParams::default()).unwrap();
    let y = system::solve(&mesh, &materials(&mesh, 0.3), Locking::Bbar, &p, &on_plane, &XfemParams::default()).unwrap();
    // compared side by side (the planes share their normal; which side a node's standard
    // value describes differs: its own side)
    assert_eq!(cut.facets()[0].normal, face_cut(1.0).facets()[0].normal);
    let (mut umax, mut diff) = (0.0f64, 0.0f64);
    for a in 0..mesh.n_nodes() {
        for positive in [true, false] {
            let (s, t) = (x.side_displacement(&enr, a, positive), y.side_displacement(&on_plane, a, positive));
            for i in 0..3 {
                umax = umax.max(t[i].abs());
                diff = diff.max((s[i] - t[i]).abs());
            }
        }
    }
    // the sliver (10⁻⁶ of two cells' volume) glued to the other side: a change far below 10⁻⁴
    assert!(diff < 1e-4 * umax, "sliver cut differs by {diff:.3e} of {umax:.3e}");
}

#[test]
fn a_piece_cut_loose_is_detected_held_and_bounded() {
    // clamp only the left end; cut the block through at x = 2: the right part floats
    let mesh = procedural::block_hex([0.0; 3], [4.0, 2.0, 3.0], [4, 2, 3]);
    let mut p = StaticProblem::new(mesh.n_nodes());
    for (a, x) in mesh.nodes.iter().enumerate() {
        if x[0] == 0.0 {
            p.clamp(&[a]);
        }
        if x[0] == 4.0 {
            p.forces[3 * a + 2] = -0.1;
        }
    }
    let cut = Cut::swept(&[([2.0, -0.1, 3.1], [2.0, 2.1, 3.1]), ([2.0, -0.1, -0.1], [2.0, 2.1, -0.1])]).unwrap();
    let enr = Enrichment::from_cut(&mesh, &cut, &XfemParams::default()).unwrap();
    assert_eq!(enr.len(), 12);
    for action in [Detached::Hold, Detached::Remove] {
        let params = XfemParams {
            detached: action,
            ..XfemParams::default()
        };
        let x = system::solve(&mesh, &materials(&mesh, 0.3), Locking::Bbar, &p, &enr, &params).unwrap();
        assert_eq!(x.detached.len(), 1, "{action:?}");
        let piece = &x.detached[0];
        assert_eq!(piece.action, action);
        assert_eq!(
            piece.free.len(),
            6,
            "a loose piece has all six rigid motions free: {:?}",
            piece.free
        );
        // the piece: the nodes right of the cut (x > 2) and the other side of the cut nodes
        assert_eq!(piece.copies.len(), 2 * 3 * 4 + 12);
        assert!(x.u.iter().chain(&x.q).all(|v| v.is_finite()));
        let right = (0..mesh.n_nodes()).filter(|&a| mesh.nodes[a][0] == 4.0);
        let sag = right.map(|a| x.u[3 * a + 2].abs()).fold(0.0, f64::max);
        match action {
            // held by the foundation k = E h per copy: 0.1 N per node sinks about 1e-5 m
            Detached::Hold => assert!(sag > 1e-7 && sag < 1e-3, "sag {sag:.3e}"),
            Detached::Remove => assert!(sag < 1e-12, "a removed piece carries no load: {sag:.3e}"),
        }
    }
}

#[test]
fn a_cut_through_nodes_reaching_the_fixed_boundary_holds_both_lips() {
    // the full-depth cut of the block clamped at its base: the base nodes on the cut are held
    // on both sides (their jump is fixed at zero), nothing detaches
    let (mesh, p) = block(false);
    let enr = Enrichment::from_cut(&mesh, &face_cut(-0.1), &XfemParams::default()).unwrap();
    assert_eq!(enr.len(), 12);
    let x = system::solve(&mesh, &materials(&mesh, 0.3), Locking::Bbar, &p, &enr, &XfemParams::default()).unwrap();
    assert!(x.detached.is_empty());
    for (k, &a) in enr.nodes.iter().enumerate() {
        if mesh.nodes[a][2] == 0.0 {
            assert_eq!(&x.q[3 * k..3 * k + 3], &[0.0; 3]);
        }
    }
    let (gap, _) = identity_gap(&mesh, Locking::Bbar, &p, &enr);
    assert!(gap < 1e-10, "{gap:.3e}");
}

#[test]
fn nearly_incompressible_tissue_stays_finite() {
    let (mesh, p) = block(false);
    let enr = Enrichment::from_cut(&mesh, &face_cut(1.0), &XfemParams::default()).unwrap();
    let x = system::solve(&mesh, &materials(&mesh, 0.499), Locking::Bbar, &p, &enr, &XfemParams::default()).unwrap();
    assert!(x.residual < 1e-8, "{:.3e}", x.residual);
    assert!(x.u.iter().chain(&x.q).all(|v| v.is_finite() && v.abs() < 1.0));
}

#[test]
fn bad_blades_are_typed_errors() {
    assert!(matches!(
        Cut::swept(&[([0.0, 0.0, f64::NAN], [1.0, 0.0, 0.0]), ([0.0; 3], [1.0, 1.0, 0.0])]),
        Err(CutError::NotFinite { index: 0 })
    ));
    // a zero-length blade sweeps no area
    assert!(matches!(
        Cut::swept(&[([1.0; 3], [1.0; 3]), ([2.0; 3], [2.0; 3])]),
        Err(CutError::NoArea { .. })
    ));
    assert!(matches!(Cut::swept(&[([1.0; 3], [2.0; 3])]), Err(CutError::Degenerate { .. })));
    // a 2D path is refused by the volume enrichment
    let (mesh, _) = block(false);
    let path = Cut::path(&[[0.0, 0.0], [1.0, 1.0]]).unwrap();
    assert!(Enrichment::from_cut(&mesh, &path, &XfemParams::default()).is_err());
}

#[test]
fn the_two_lips_of_a_symmetric_cut_open_symmetrically() {
    // the block and its loads are mirror-symmetric about x = 2: so must the opening be
    let (mesh, p) = block(false);
    let enr = Enrichment::from_cut(&mesh, &face_cut(1.0), &XfemParams::default()).unwrap();
    let x = system::solve(&mesh, &materials(&mesh, 0.3), Locking::Bbar, &p, &enr, &XfemParams::default()).unwrap();
    let umax = x.u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for &a in &enr.nodes {
        let (l, r) = (x.side_displacement(&enr, a, true), x.side_displacement(&enr, a, false));
        assert!((l[0] + r[0]).abs() < 1e-12 * umax.max(1.0), "node {a}: lips {l:?} {r:?}");
        assert!((l[2] - r[2]).abs() < 1e-12 * umax.max(1.0), "node {a}: lips {l:?} {r:?}");
    }
}

#[test]
fn node_centred_planes_through_a_cell_equal_the_cut_on_the_nearest_faces() {
    // the cracking-node form: a cut at x = 2.4 moved to planes through the nodes at x = 2
    let (mesh, p) = block(false);
    let params = XfemParams {
        node_centred: true,
        ..XfemParams::default()
    };
    let cut = Cut::swept(&[([2.4, -0.1, 3.1], [2.4, 2.1, 3.1]), ([2.4, -0.1, 1.0], [2.4, 2.1, 1.0])]).unwrap();
    let centred = Enrichment::from_cut(&mesh, &cut, &params).unwrap();
    assert_eq!(centred.len(), 9);
    assert!(centred.nodes.iter().all(|&a| mesh.nodes[a][0] == 2.0));
    let on_faces = Enrichment::from_cut(&mesh, &face_cut(1.0), &XfemParams::default()).unwrap();
    let mats = materials(&mesh, 0.3);
    let x = system::solve(&mesh, &mats, Locking::Bbar, &p, &centred, &params).unwrap();
    let y = system::solve(&mesh, &mats, Locking::Bbar, &p, &on_faces, &XfemParams::default()).unwrap();
    let umax = y.u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for a in 0..mesh.n_nodes() {
        for positive in [true, false] {
            let (s, t) = (
                x.side_displacement(&centred, a, positive),
                y.side_displacement(&on_faces, a, positive),
            );
            for i in 0..3 {
                assert!((s[i] - t[i]).abs() < 1e-10 * umax, "node {a}: {s:?} vs {t:?}");
            }
        }
    }
}

#[test]
fn a_blade_re_entering_or_trembling_in_a_cut_changes_nothing() {
    let (mesh, p) = block(false);
    let once = Enrichment::from_cut(&mesh, &face_cut(1.0), &XfemParams::default()).unwrap();
    // the same incision twice
    let twice = face_cut(1.0).union(&face_cut(1.0)).unwrap();
    let again = Enrichment::from_cut(&mesh, &twice, &XfemParams::default()).unwrap();
    assert_eq!(again.nodes, once.nodes);
    // a blade trembling 1,000 times up and down inside the upper cell row of the cut
    let blade: Vec<_> = (0..1000)
        .map(|i| {
            let z = if i % 2 == 0 { 3.1 } else { 1.9 };
            ([2.0, -0.1, z], [2.0, 2.1, z])
        })
        .collect();
    let tremble = Enrichment::from_cut(&mesh, &Cut::swept(&blade).unwrap(), &XfemParams::default()).unwrap();
    // it cuts the top row only: the nodes on the plane at z = 2 and 3
    assert_eq!(tremble.len(), 6);
    let x = system::solve(&mesh, &materials(&mesh, 0.3), Locking::Bbar, &p, &tremble, &XfemParams::default()).unwrap();
    assert!(x.residual < 1e-10 && x.u.iter().chain(&x.q).all(|v| v.is_finite()));
}

#[test]
fn cutting_the_whole_accessible_layer_off_leaves_a_held_piece() {
    // a horizontal cut through the whole block at z = 2.5: the top half-layer is cut loose
    let (mesh, p) = block(false);
    let cut = Cut::swept(&[([-0.1, -0.1, 2.5], [-0.1, 2.1, 2.5]), ([4.1, -0.1, 2.5], [4.1, 2.1, 2.5])]).unwrap();
    let enr = Enrichment::from_cut(&mesh, &cut, &XfemParams::default()).unwrap();
    assert_eq!(enr.cut_cells.len(), 8);
    let x = system::solve(&mesh, &materials(&mesh, 0.3), Locking::Bbar, &p, &enr, &XfemParams::default()).unwrap();
    assert_eq!(x.detached.len(), 1);
    assert!(x.residual < 1e-8, "{:.3e}", x.residual);
    assert!(x.u.iter().chain(&x.q).all(|v| v.is_finite() && v.abs() < 1.0));
}

#[test]
fn a_cut_across_the_nearly_incompressible_organ_with_nodal_pressure_solves() {
    // ν = 0.49 on tetrahedra: the averaged nodal pressure extended to the enriched functions; a cut off the cell faces (x = 3 mm) down to mid-height
    let mesh = procedural::lobe(&LobeParams::default());
    let mut p = StaticProblem::new(mesh.n_nodes());
    for (a, x) in mesh.nodes.iter().enumerate() {
        if x[1] <= -0.04 {
            p.clamp(&[a]);
        }
        if x[2] > 0.02 && x[0].abs() > 0.01 && x[0].abs() < 0.02 {
            p.forces[3 * a] = 0.05 * x[0].signum();
        }
    }
    let cut = Cut::swept(&[
        ([0.003, -0.01, 0.08], [0.003, 0.06, 0.08]),
        ([0.003, -0.01, 0.0], [0.003, 0.06, 0.0]),
    ])
    .unwrap();
    let enr = Enrichment::from_cut(&mesh, &cut, &XfemParams::default()).unwrap();
    assert!(enr.len() > 20);
    let x = system::solve(&mesh, &materials(&mesh, 0.49), Locking::Nodal, &p, &enr, &XfemParams::default()).unwrap();
    assert!(x.residual < 1e-8, "{:.3e}", x.residual);
    assert!(x.u.iter().chain(&x.q).all(|v| v.is_finite()));
    // the cut opens: some jump is of the order of the displacements
    let umax = x.u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let qmax = x.q.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(qmax > 0.1 * umax, "jump {qmax:.3e} vs displacement {umax:.3e}");
}

#[test]
fn an_incision_in_the_liver_opens_and_softens_it() {
    // scenes/liver_h20_cut.toml: the OpenHELP liver (nodal-pressure tetrahedra, ν = 0.48) with a
    // 4 cm incision through cells (not along faces), its lower lip pulled
    let Some(shared) = common::shared_data() else { return };
    let scene = common::shared_scene("liver_h20_cut.toml", &shared);
    let m = scene.organ_model(0).unwrap();
    let cuts = scene.organ_cuts(0).unwrap();
    let params = scene.spec.fidelity.xfem.params();
    let enr = Enrichment::from_cut(&m.mesh, &cuts[0], &params).unwrap();
    assert!(
        enr.cut_cells.len() >= 10 && enr.len() >= 10,
        "{} cells, {} nodes",
        enr.cut_cells.len(),
        enr.len()
    );
    let x = system::solve(&m.mesh, &m.materials, m.locking, &m.problem, &enr, &params).unwrap();
    assert!(x.residual < 1e-8, "{:.3e}", x.residual);
    assert!(x.detached.is_empty());
    let uncut = linear_static::solve(&m.mesh, &m.materials, m.locking, &m.problem, &mut |_| {}).unwrap();
    let energy = 0.5 * m.problem.forces.iter().zip(&x.u).map(|(f, u)| f * u).sum::<f64>();
    assert!(
        energy > 1.1 * uncut.strain_energy,
        "cut {energy:.3e} J, uncut {:.3e} J",
        uncut.strain_energy
    );
    let opening =
        x.q.chunks(3)
            .map(|j| (j[0] * j[0] + j[1] * j[1] + j[2] * j[2]).sqrt())
            .fold(0.0, f64::max);
    assert!(opening > 1e-4 && opening < 1e-2, "opening {opening:.3e} m");
}

/// A split-node model built from the geometry alone (no enrichment): the nodes `split`
/// selects get a copy, which the cells whose centre `copied_side` selects use instead. Returns
/// the mesh, `problem` on it (the copies free, unloaded) and, for each copy, (original, copy).
fn split_by_hand(
    mesh: &Mesh,
    problem: &StaticProblem,
    split: impl Fn([f64; 3]) -> bool,
    copied_side: impl Fn([f64; 3]) -> bool,
) -> (Mesh, StaticProblem, Vec<(usize, usize)>) {
    let n = mesh.n_nodes();
    let split: Vec<usize> = (0..n).filter(|&a| split(mesh.nodes[a])).collect();
    let mut copy = vec![None; n];
    for (k, &a) in split.iter().enumerate() {
        copy[a] = Some(n + k);
    }
    let mut nodes = mesh.nodes.clone();
    nodes.extend(split.iter().map(|&a| mesh.nodes[a]));
    let npc = mesh.kind.nodes_per_cell();
    let mut cells = Vec::new();
    for c in mesh.cells_iter() {
        let centre = c
            .iter()
            .fold([0.0; 3], |s, &a| std::array::from_fn(|i| s[i] + mesh.nodes[a][i] / npc as f64));
        let copied = copied_side(centre);
        cells.extend(c.iter().map(|&a| if copied { copy[a].unwrap_or(a) } else { a }));
    }
    let dup = Mesh::new(nodes, mesh.kind, cells).unwrap();
    let mut p = StaticProblem::new(dup.n_nodes());
    p.constrained[..3 * n].copy_from_slice(&problem.constrained);
    p.forces[..3 * n].copy_from_slice(&problem.forces);
    let pairs = split.iter().enumerate().map(|(k, &a)| (a, n + k)).collect();
    (dup, p, pairs)
}

/// A cut that stops inside the tissue opens up to where the blade stopped and no further: with
/// the crack front's nodes shared, the XFEM equals, to solver precision, a split-node model
/// built by hand from the geometry; the seed's rule (every node of a cut cell cracked) opens
/// the front nodes too, and differs from it by far more than the solver's error.
#[test]
fn a_cut_that_stops_inside_opens_to_the_blade_and_no_further_as_a_split_node_model() {
    for tets in [false, true] {
        let (mesh, p) = block(tets);
        let depth = 1.0;
        // the block cut by [`face_cut`]: the nodes on x = 2 strictly above `depth` split, the
        // front's shared, the copies used right of the plane
        let (dup, dp, pairs) = split_by_hand(&mesh, &p, |x| x[0] == 2.0 && x[2] > depth, |c| c[0] > 2.0);
        let mats = materials(&mesh, 0.3);
        let locking = if tets { Locking::None } else { Locking::Bbar };
        let reference = linear_static::solve(&dup, &materials(&dup, 0.3), locking, &dp, &mut |_| {}).unwrap();
        let gap_to_split = |front: Front| {
            let params = XfemParams {
                front,
                ..XfemParams::default()
            };
            let enr = Enrichment::from_cut(&mesh, &face_cut(depth), &params).unwrap();
            let x = system::solve(&mesh, &mats, locking, &p, &enr, &params).unwrap();
            assert!(x.residual < 1e-10);
            let mut gap: f64 = 0.0;
            for a in 0..mesh.n_nodes() {
                let copy = pairs.iter().find(|(o, _)| *o == a).map(|&(_, c)| c);
                // the node's displacement on each side: left of the plane, right of it
                let (left, right) = match enr.index(a) {
                    Some(k) => {
                        let right_positive = enr.planes[k].phi([2.5, 1.0, 2.0]) > 0.0;
                        (
                            x.side_displacement(&enr, a, !right_positive),
                            x.side_displacement(&enr, a, right_positive),
                        )
                    }
                    None => {
                        let u = [x.u[3 * a], x.u[3 * a + 1], x.u[3 * a + 2]];
                        (u, u)
                    }
                };
                let right_ref = copy.unwrap_or(a);
                for i in 0..3 {
                    gap = gap.max((left[i] - reference.u[3 * a + i]).abs());
                    gap = gap.max((right[i] - reference.u[3 * right_ref + i]).abs());
                }
            }
            let max = reference.u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            (gap / max, enr)
        };
        let (shared, enr) = gap_to_split(Front::Shared);
        assert!(
            shared < 1e-10,
            "tets {tets}: front shared, relative gap to the split-node model {shared:.3e}"
        );
        // the front's three nodes (x = 2, z = 1) stay shared, the six above them are cracked
        assert_eq!(enr.len(), 6, "tets {tets}: enriched {:?}", enr.nodes);
        assert_eq!(enr.front.len(), 3, "tets {tets}: front {:?}", enr.front);
        assert!(enr.front.iter().all(|&a| mesh.nodes[a][0] == 2.0 && mesh.nodes[a][2] == depth));
        let (cracked, _) = gap_to_split(Front::Cracked);
        assert!(
            cracked > 1e-3,
            "tets {tets}: the seed's rule should open the front: gap {cracked:.3e}"
        );
    }
}

/// A cut that grows cell by cell (the online cut) cracks a front node once the cells ahead of
/// it are cut, and ends with what cutting it all at once gives.
#[test]
fn a_growing_cut_cracks_the_front_nodes_once_the_blade_has_passed_them() {
    let (mesh, _) = block(false);
    let params = XfemParams {
        front: Front::Shared,
        ..XfemParams::default()
    };
    let all = Enrichment::cut_cells(&mesh, &face_cut(0.0), &params).unwrap();
    // the cells in the order a blade going down meets them
    let mut order = all.clone();
    order.sort_by(|a, b| {
        let top = |c: usize| -mesh.cell(c).iter().map(|&n| mesh.nodes[n][2]).sum::<f64>();
        top(a.0).total_cmp(&top(b.0))
    });
    let mut enr = Enrichment::none(&mesh);
    for step in order.chunks(4) {
        enr = enr.extended(&mesh, step, &params).unwrap();
        let deepest = enr
            .cut_cells
            .iter()
            .flat_map(|&(c, _)| mesh.cell(c))
            .map(|&n| mesh.nodes[n][2])
            .fold(f64::MAX, f64::min);
        // the nodes on the plane strictly above the deepest cut cell's bottom are cracked, those at
        // its bottom are the front — until the cut reaches the base, whose nodes have no cell
        // below them: then every node on the plane is cracked
        for a in (0..mesh.n_nodes()).filter(|&a| mesh.nodes[a][0] == 2.0) {
            let z = mesh.nodes[a][2];
            assert_eq!(
                enr.index(a).is_some(),
                z > deepest || deepest == 0.0,
                "node at z = {z}, cut down to {deepest}"
            );
            assert_eq!(
                enr.front.contains(&a),
                z == deepest && deepest > 0.0,
                "node at z = {z}, cut down to {deepest}"
            );
        }
    }
    let at_once = Enrichment::from_cut_cells(&mesh, &all, &params).unwrap();
    let mut grown = enr.nodes.clone();
    grown.sort_unstable();
    let mut once = at_once.nodes.clone();
    once.sort_unstable();
    assert_eq!(grown, once);
}

/// Issue 47's block: 0.1 m wide (x) and high (y), 0.02 m thick (z), E = 3 kPa, ν = 0.45, the
/// base clamped, 30 Pa pulling the top up, meshed with n × n × n/5 hexahedra.
fn edge_crack_block(n: usize) -> (Mesh, StaticProblem) {
    let mesh = procedural::block_hex([0.0; 3], [0.1, 0.1, 0.02], [n, n, (n / 5).max(1)]);
    let mut p = StaticProblem::new(mesh.n_nodes());
    let (hx, hz) = (0.1 / n as f64, 0.02 / (n / 5).max(1) as f64);
    for (a, x) in mesh.nodes.iter().enumerate() {
        if x[1] == 0.0 {
            p.clamp(&[a]);
        }
        if (x[1] - 0.1).abs() < 1e-12 {
            // the consistent nodal forces of a uniform traction on bilinear faces: a quarter of
            // each face around the node
            let wx = if x[0] == 0.0 || (x[0] - 0.1).abs() < 1e-12 { 0.5 } else { 1.0 };
            let wz = if x[2] == 0.0 || (x[2] - 0.02).abs() < 1e-12 { 0.5 } else { 1.0 };
            p.forces[3 * a + 1] = 30.0 * wx * hx * wz * hz;
        }
    }
    (mesh, p)
}

/// The through-thickness cut from the left face at mid-height, 0.05 m long, at `angle` (rad)
/// above the horizontal; the blade starts 5 mm outside the block.
fn edge_cut(angle: f64) -> Cut {
    let (c, s) = (angle.cos(), angle.sin());
    let at = |t: f64| ([t * c, 0.05 + t * s, -0.001], [t * c, 0.05 + t * s, 0.021]);
    Cut::swept(&[at(-0.005), at(0.05)]).unwrap()
}

/// The table of issue 47 (docs/cutting.md "Where the cut ends"): strain energy of the block
/// cut horizontally and at 20°, by the seed's rule and with the front shared, at n = 10, 20,
/// 40 (and 60 with `VADEMECUM_CUT_N60=1`, a few minutes), beside the split-node model's
/// extrapolated energy for the horizontal cut (Richardson from n = 20, 40, 60 when run,
/// else n = 10, 20, 40).
/// `cargo test -p vademecum-engine --test it edge_crack_table -- --ignored --nocapture`.
#[test]
#[ignore = "prints the table of BENCHMARKS.md (a minute)"]
fn edge_crack_table() {
    let mut ns = vec![10, 20, 40];
    if std::env::var_os("VADEMECUM_CUT_N60").is_some() {
        ns.push(60);
    }
    let energy = |p: &StaticProblem, u: &[f64]| 0.5 * p.forces.iter().zip(u).map(|(f, u)| f * u).sum::<f64>();
    let mut split_energies = Vec::new();
    println!("n\tangle\trule\tenergy_J\tenriched\tfront\tseconds");
    for &n in &ns {
        let (mesh, p) = edge_crack_block(n);
        let mats = MaterialMap::uniform(LinearElastic::new(3e3, 0.45).unwrap(), 1000.0, mesh.n_cells());
        for (angle, name) in [(0.0, "0"), (20f64.to_radians(), "20")] {
            for front in [Front::Cracked, Front::Shared] {
                let params = XfemParams {
                    front,
                    ..XfemParams::default()
                };
                let enr = Enrichment::from_cut(&mesh, &edge_cut(angle), &params).unwrap();
                let x = system::solve(&mesh, &mats, Locking::Bbar, &p, &enr, &params).unwrap();
                assert!(x.residual < 1e-8, "residual {:.2e}", x.residual);
                println!(
                    "{n}\t{name}\t{front:?}\t{:.6e}\t{}\t{}\t{:.1}",
                    energy(&p, &x.u),
                    enr.len(),
                    enr.front.len(),
                    x.seconds
                );
            }
        }
        // the horizontal cut lies on cell faces (y = 0.05, x ≤ 0.05): the split-node model,
        // by hand, the front (x = 0.05) shared
        let (dup, dp, pairs) = split_by_hand(&mesh, &p, |x| (x[1] - 0.05).abs() < 1e-12 && x[0] < 0.05 - 1e-12, |c| c[1] > 0.05);
        let dmats = MaterialMap::uniform(LinearElastic::new(3e3, 0.45).unwrap(), 1000.0, dup.n_cells());
        let s = linear_static::solve(&dup, &dmats, Locking::Bbar, &dp, &mut |_| {}).unwrap();
        let e = energy(&dp, &s.u);
        println!("{n}\t0\tsplit-node\t{e:.6e}\t{}\t-\t-", pairs.len());
        split_energies.push((n as f64, e));
    }
    // E(n) = E∞ + C n^(−p) through the last three: p from the ratio of differences
    let k = split_energies.len();
    let [(n1, e1), (n2, e2), (n3, e3)] = [split_energies[k - 3], split_energies[k - 2], split_energies[k - 1]];
    let ratio = (e1 - e2) / (e2 - e3);
    // solve (n1^-p − n2^-p) / (n2^-p − n3^-p) = ratio for p by bisection
    let f = |p: f64| (n1.powf(-p) - n2.powf(-p)) / (n2.powf(-p) - n3.powf(-p)) - ratio;
    let (mut lo, mut hi) = (0.05, 4.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if f(lo) * f(mid) <= 0.0 { hi = mid } else { lo = mid }
    }
    let p = 0.5 * (lo + hi);
    let c = (e2 - e3) / (n2.powf(-p) - n3.powf(-p));
    let limit = e3 - c * n3.powf(-p);
    println!("split-node extrapolated (n = {n1}, {n2}, {n3}): energy {limit:.6e} J, rate n^-{p:.2}");
}
