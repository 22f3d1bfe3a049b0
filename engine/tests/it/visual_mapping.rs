//! Visual meshes mapped to the simulation mesh (seed 003 §3.2, §3.4): SOFA's smooth liver
//! surface (`../shared/data/meshes/sofa/liver-smooth.obj`, 2,194 vertices) embedded in its
//! tetrahedral liver (`sofa/liver.msh`, 596 cells) follows any affine motion exactly, and
//! once the liver is cut through, every vertex follows the side of the cut it lies on.

use crate::common;

use std::path::PathBuf;

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use vademecum_engine::mesh::{self, Mesh};
use vademecum_engine::xfem::visual::{Embedding, VisualError, VisualMesh};
use vademecum_engine::xfem::{Enrichment, Plane, XfemParams};

fn liver() -> Option<(Mesh, VisualMesh)> {
    let dir: PathBuf = common::shared_data()?.join("data/meshes/sofa");
    let mesh = mesh::read(dir.join("liver.msh")).unwrap();
    let visual = VisualMesh::load_obj(&dir.join("liver-smooth.obj"), 1.0).unwrap();
    Some((mesh, visual))
}

fn affine(a: &Matrix3<f64>, t: [f64; 3], x: [f64; 3]) -> [f64; 3] {
    let y = a * Vector3::new(x[0], x[1], x[2]);
    [y[0] + t[0], y[1] + t[1], y[2] + t[2]]
}

#[test]
fn the_smooth_liver_is_a_closed_surface_embedded_in_the_tetrahedra() {
    let Some((mesh, visual)) = liver() else { return };
    assert_eq!((visual.vertices.len(), visual.triangles.len()), (2194, 4384));
    assert!(visual.edges().is_closed_manifold(), "{:?}", visual.edges());
    let e = Embedding::new(&mesh, &visual.vertices).unwrap();
    let inside = e.outside.iter().filter(|&&o| o == 0.0).count();
    let worst = e.outside.iter().copied().fold(0.0, f64::max);
    println!(
        "{inside} of {} vertices inside a tetrahedron; the farthest outside at barycentric −{worst:.2}",
        e.cell.len()
    );
    // any affine motion of the nodes moves every vertex by the same motion (barycentric
    // coordinates extrapolate exactly outside)
    let a = Matrix3::new(0.9, 0.2, 0.0, -0.1, 1.1, 0.3, 0.05, 0.0, 0.95) - Matrix3::identity();
    let t = [0.3, -0.2, 0.1];
    let d: Vec<f64> = mesh.nodes.iter().flat_map(|&x| affine(&a, t, x)).collect();
    let mut u = vec![0.0; 3 * visual.vertices.len()];
    e.displacements(&mesh, &Enrichment::none(&mesh), &visual.vertices, &d, &mut u);
    for (v, &x) in visual.vertices.iter().enumerate() {
        let want = affine(&a, t, x);
        for i in 0..3 {
            assert!(
                (u[3 * v + i] - want[i]).abs() < 1e-9,
                "vertex {v}: {:?} vs {want:?}",
                &u[3 * v..3 * v + 3]
            );
        }
    }
}

#[test]
fn cut_through_every_vertex_follows_its_own_side() {
    let Some((mesh, visual)) = liver() else { return };
    // a plane across the liver, nudged until no node falls to the sliver rule (then both
    // sides' motions are represented exactly)
    let normal = Vector3::new(1.0, 0.3, -0.2).normalize();
    let enr_at = |offset: f64| {
        let plane = Plane {
            point: [-1.4 + offset, 2.6, 0.5],
            normal: [normal[0], normal[1], normal[2]],
        };
        let cells = Enrichment::cells_crossed_by(&mesh, &plane);
        (plane, Enrichment::from_cut_cells(&mesh, &cells, &XfemParams::default()).unwrap())
    };
    let (plane, enr) = (0..50)
        .map(|k| enr_at(0.013 * k as f64))
        .find(|(_, e)| e.dropped.is_empty())
        .expect("a plane with no sliver");
    assert!(enr.len() > 20, "{} enriched nodes", enr.len());
    // the two sides move apart, each by its own rigid motion
    let q1 = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.0, 1.0, 0.3)), 0.4).into_inner();
    let q2 = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(1.0, 0.0, 0.2)), -0.5).into_inner();
    let (t1, t2) = ([0.5, 0.0, 0.2], [-0.4, 0.3, 0.0]);
    let motion = |positive: bool, x: [f64; 3]| {
        let (q, t) = if positive { (&q1, t1) } else { (&q2, t2) };
        affine(&(q - Matrix3::identity()), t, x)
    };
    let d = common::two_sides::displacements(&mesh, &enr, &plane, motion);
    let mut e = Embedding::new(&mesh, &visual.vertices).unwrap();
    let moved = e.follow_cut(&mesh, &enr, &visual.vertices);
    let mut u = vec![0.0; 3 * visual.vertices.len()];
    e.displacements(&mesh, &enr, &visual.vertices, &d, &mut u);
    let mut on_each = [0, 0];
    for (v, &x) in visual.vertices.iter().enumerate() {
        let positive = plane.phi(x) > 0.0;
        on_each[usize::from(positive)] += 1;
        let want = motion(positive, x);
        for i in 0..3 {
            assert!(
                (u[3 * v + i] - want[i]).abs() < 1e-9,
                "vertex {v} on the {} side: {:?} vs {want:?}",
                if positive { "+" } else { "−" },
                &u[3 * v..3 * v + 3]
            );
        }
    }
    println!(
        "{} enriched nodes; vertices on the two sides {on_each:?}; {moved} re-associated to a cut cell",
        enr.len()
    );
    assert!(moved > 0, "vertices hanging outside the mesh across the cut from their cell");
    assert!(on_each[0] > 100 && on_each[1] > 100);
}

#[test]
fn bad_visual_meshes_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let missing = VisualMesh::load_obj(&dir.path().join("none.obj"), 1.0).unwrap_err();
    assert!(matches!(missing, VisualError::File { .. }), "{missing}");
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nf 1 2 7\n").unwrap();
    let e = VisualMesh::load_obj(&bad, 1.0).unwrap_err().to_string();
    assert!(e.contains("bad.obj"), "{e}");
    let empty = dir.path().join("empty.obj");
    std::fs::write(&empty, "v 0 0 0\n").unwrap();
    assert!(VisualMesh::load_obj(&empty, 1.0).is_err());
    // a hexahedral simulation mesh cannot carry one (yet)
    let hexes = vademecum_engine::mesh::procedural::block_hex([0.0; 3], [1.0; 3], [1, 1, 1]);
    assert!(matches!(Embedding::new(&hexes, &[[0.5; 3]]), Err(VisualError::NotTetrahedra(_))));
    // a surface with a hole is not a closed manifold
    let open = VisualMesh {
        vertices: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3]],
    };
    let r = open.edges();
    assert_eq!((r.boundary, r.non_manifold, r.misoriented), (3, 0, 0));
    let flipped = VisualMesh {
        triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 2, 3]],
        ..open
    };
    assert!(!flipped.edges().is_closed_manifold() && flipped.edges().misoriented > 0);
}

/// The most negative barycentric coordinate of `p` in the tetrahedron `x` (0 or more inside),
/// by Cramer's rule: independent of the engine's own.
fn least_coordinate(x: &[[f64; 3]; 4], p: [f64; 3]) -> f64 {
    let m = Matrix3::from_fn(|i, j| x[j + 1][i] - x[0][i]);
    let det = m.determinant();
    let r = Vector3::new(p[0] - x[0][0], p[1] - x[0][1], p[2] - x[0][2]);
    let l: Vec<f64> = (0..3)
        .map(|c| {
            let mut mc = m;
            mc.set_column(c, &r);
            mc.determinant() / det
        })
        .collect();
    [1.0 - l[0] - l[1] - l[2], l[0], l[1], l[2]]
        .into_iter()
        .fold(f64::INFINITY, f64::min)
}

/// The least-outside cell of every vertex by a search of every cell.
fn brute_least_outside(mesh: &Mesh, p: [f64; 3]) -> f64 {
    let mut x = [[0.0; 3]; 4];
    (0..mesh.n_cells())
        .map(|c| {
            mesh.cell_coords(c, &mut x);
            least_coordinate(&x, p)
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn each_vertex_is_embedded_in_the_cell_it_is_least_outside_of_at_a_cost_linear_in_the_vertices() {
    // SOFA's smooth liver: 1,974 of its 2,194 vertices lie outside every tetrahedron; the
    // search near each (grid shells) finds a cell as little outside as a search of all 596
    let Some((mesh, visual)) = liver() else { return };
    let e = Embedding::new(&mesh, &visual.vertices).unwrap();
    for (v, &p) in visual.vertices.iter().enumerate() {
        let best = brute_least_outside(&mesh, p);
        let got = (-e.outside[v]).min(0.0);
        assert!(
            got >= best.min(0.0) - 1e-9,
            "vertex {v} at {p:?}: embedded {} outside its cell, {} possible",
            -got,
            -best
        );
    }
    println!(
        "liver: {} cells tried for {} vertices ({:.1} each; all {} each before)",
        e.examined,
        visual.vertices.len(),
        e.examined as f64 / visual.vertices.len() as f64,
        mesh.n_cells()
    );
    // 3,000 small closed boxes scattered over and around a block of 10,368 tetrahedra (the
    // fuzzer's surface that made a cut session twice as slow): each vertex tries a bounded
    // number of cells, not all of them, and still follows any affine motion exactly
    let block = vademecum_engine::mesh::procedural::block_tet([0.0; 3], [1.0; 3], [12, 12, 12]);
    let mut vertices = Vec::new();
    let mut rng = common::mutate::Rng(0x2545_f491_4f6c_dd1d);
    let mut next = || (rng.next() >> 11) as f64 / (1u64 << 53) as f64;
    for _ in 0..3000 {
        let c: [f64; 3] = std::array::from_fn(|_| -0.5 + 2.0 * next());
        for corner in 0..8 {
            vertices.push(std::array::from_fn(|k| c[k] + if corner >> k & 1 == 1 { 0.01 } else { -0.01 }));
        }
    }
    let e = Embedding::new(&block, &vertices).unwrap();
    println!(
        "3,000 boxes: {:.1} of {} cells tried per vertex",
        e.examined as f64 / vertices.len() as f64,
        block.n_cells()
    );
    assert!(
        e.examined < 200 * vertices.len(),
        "{} cells tried for {} vertices of a {}-cell mesh",
        e.examined,
        vertices.len(),
        block.n_cells()
    );
    let a = Matrix3::new(0.9, 0.2, 0.0, -0.1, 1.1, 0.3, 0.05, 0.0, 0.95) - Matrix3::identity();
    let t = [0.3, -0.2, 0.1];
    let d: Vec<f64> = block.nodes.iter().flat_map(|&x| affine(&a, t, x)).collect();
    let mut u = vec![0.0; 3 * vertices.len()];
    e.displacements(&block, &Enrichment::none(&block), &vertices, &d, &mut u);
    for (v, &x) in vertices.iter().enumerate() {
        let want = affine(&a, t, x);
        assert!((0..3).all(|i| (u[3 * v + i] - want[i]).abs() < 1e-9), "box vertex {v} at {x:?}");
    }
}
