//! A visual surface split along a cut and closed by the cut faces (seed 003 §3.4, issue 16):
//! after every cut step the surface stays a closed, consistently oriented 2-manifold, the cut
//! introduces no self-intersection at rest, it encloses the same volume, and every vertex
//! follows the side of the cut it belongs to.

use crate::common;

use std::collections::HashMap;
use std::path::PathBuf;

use vademecum_engine::geometry::vec3::{cross, dot, sub};
use vademecum_engine::mesh::{self, Mesh, procedural};
use vademecum_engine::xfem::progressive::ProgressiveCut;
use vademecum_engine::xfem::visual::{Embedding, VisualMesh};
use vademecum_engine::xfem::visual_split::{self, SplitError, SplitSurface, VertexSide};
use vademecum_engine::xfem::{Enrichment, Plane, XfemParams};

/// The surface of the unit cube, each face an `m × m` grid of squares cut in two, facing out.
fn cube_surface(m: usize) -> VisualMesh {
    let mut index: HashMap<[usize; 3], usize> = HashMap::new();
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let mut vertex = |g: [usize; 3]| {
        *index.entry(g).or_insert_with(|| {
            vertices.push(g.map(|k| k as f64 / m as f64));
            vertices.len() - 1
        })
    };
    for axis in 0..3 {
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        for high in [false, true] {
            for i in 0..m {
                for j in 0..m {
                    let at = |di: usize, dj: usize| {
                        let mut g = [0; 3];
                        g[axis] = if high { m } else { 0 };
                        g[a] = i + di;
                        g[b] = j + dj;
                        g
                    };
                    let q = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)].map(&mut vertex);
                    // (a, b, axis) is right-handed: counter-clockwise in (a, b) faces +axis
                    if high {
                        triangles.push([q[0], q[1], q[2]]);
                        triangles.push([q[0], q[2], q[3]]);
                    } else {
                        triangles.push([q[0], q[2], q[1]]);
                        triangles.push([q[0], q[3], q[2]]);
                    }
                }
            }
        }
    }
    VisualMesh { vertices, triangles }
}

/// Volume enclosed (divergence theorem).
fn volume(vertices: &[[f64; 3]], triangles: &[[usize; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| vertices[v]);
            (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0
        })
        .sum()
}

/// The connected pieces (sets of triangles sharing vertices).
fn pieces(s: &VisualMesh) -> Vec<Vec<[usize; 3]>> {
    let mut parent: Vec<usize> = (0..s.vertices.len()).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for t in &s.triangles {
        for k in 1..3 {
            let (a, b) = (find(&mut parent, t[0]), find(&mut parent, t[k]));
            parent[a] = b;
        }
    }
    let mut by_root: HashMap<usize, Vec<[usize; 3]>> = HashMap::new();
    for t in &s.triangles {
        by_root.entry(find(&mut parent, t[0])).or_default().push(*t);
    }
    let mut out: Vec<_> = by_root.into_values().collect();
    out.sort_by_key(|p| p.len());
    out
}

/// Whether segment `p q` crosses the inside of triangle `t` away from its edges and the
/// segment's ends (a transversal crossing; coplanar ones are not).
fn pierces(p: [f64; 3], q: [f64; 3], t: [[f64; 3]; 3]) -> bool {
    let d = sub(q, p);
    let (e1, e2) = (sub(t[1], t[0]), sub(t[2], t[0]));
    let h = cross(d, e2);
    let det = dot(e1, h);
    let scale = dot(e1, e1).sqrt() * dot(e2, e2).sqrt() * dot(d, d).sqrt();
    if det.abs() <= 1e-9 * scale {
        return false;
    }
    let s = sub(p, t[0]);
    let u = dot(s, h) / det;
    let qv = cross(s, e1);
    let v = dot(d, qv) / det;
    let w = dot(e2, qv) / det;
    let eps = 1e-7;
    u > eps && v > eps && u + v < 1.0 - eps && w > eps && w < 1.0 - eps
}

/// Pairs of triangles (sharing no vertex position) of which one's edge pierces the other.
fn self_intersections(s: &VisualMesh, among: impl Fn(usize) -> bool) -> usize {
    let key = |x: [f64; 3]| x.map(|c| (c * 1e9).round() as i64);
    let tri = |t: &[usize; 3]| t.map(|v| s.vertices[v]);
    let boxes: Vec<([f64; 3], [f64; 3])> = s
        .triangles
        .iter()
        .map(|t| {
            let x = tri(t);
            (
                std::array::from_fn(|k| x[0][k].min(x[1][k]).min(x[2][k])),
                std::array::from_fn(|k| x[0][k].max(x[1][k]).max(x[2][k])),
            )
        })
        .collect();
    let mut found = 0;
    for i in (0..s.triangles.len()).filter(|&i| among(i)) {
        let ti = tri(&s.triangles[i]);
        for j in 0..s.triangles.len() {
            if i == j || (0..3).any(|k| boxes[i].1[k] < boxes[j].0[k] || boxes[j].1[k] < boxes[i].0[k]) {
                continue;
            }
            let tj = tri(&s.triangles[j]);
            if ti.iter().any(|a| tj.iter().any(|b| key(*a) == key(*b))) {
                continue;
            }
            let edge_through = |a: [[f64; 3]; 3], b: [[f64; 3]; 3]| (0..3).any(|k| pierces(a[k], a[(k + 1) % 3], b));
            if edge_through(ti, tj) || edge_through(tj, ti) {
                found += 1;
            }
        }
    }
    found
}

/// The invariants every split must keep: closed, consistently oriented, the same volume, no
/// triangle of no area, no self-intersection made by the triangles the split touched.
fn check_invariants(before: &VisualMesh, after: &SplitSurface) {
    let s = &after.surface;
    let edges = s.edges();
    if !edges.is_closed_manifold() {
        let mut count: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
        for (i, t) in s.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                count.entry((a.min(b), a.max(b))).or_default().push(i);
            }
        }
        for (e, ts) in count.iter().filter(|(_, t)| t.len() != 2) {
            eprintln!(
                "edge {e:?} sides {:?} {:?}: triangles {:?}",
                after.side[e.0],
                after.side[e.1],
                ts.iter().map(|&i| s.triangles[i]).collect::<Vec<_>>()
            );
        }
    }
    assert!(edges.is_closed_manifold(), "{edges:?}");
    let (v0, v1) = (volume(&before.vertices, &before.triangles), volume(&s.vertices, &s.triangles));
    assert!((v1 - v0).abs() <= 1e-9 * v0.abs(), "volume {v0} before, {v1} after");
    let scale = {
        let a = s.triangles.iter().map(|t| {
            let [a, b, c] = t.map(|v| s.vertices[v]);
            dot(cross(sub(b, a), sub(c, a)), cross(sub(b, a), sub(c, a))).sqrt() / 2.0
        });
        a.fold(f64::INFINITY, f64::min)
    };
    assert!(scale > 0.0, "a triangle of no area");
    assert_eq!(after.side.len(), s.vertices.len());
    let original: std::collections::HashSet<[usize; 3]> = before.triangles.iter().copied().collect();
    let n = self_intersections(s, |i| !original.contains(&s.triangles[i]));
    assert_eq!(n, 0, "the cut made {n} self-intersections");
}

fn x_plane(x: f64) -> Plane {
    Plane {
        point: [x, 0.5, 0.5],
        normal: [1.0, 0.0, 0.0],
    }
}

fn crossed(mesh: &Mesh, plane: &Plane) -> Vec<usize> {
    Enrichment::cells_crossed_by(mesh, plane).into_iter().map(|(c, _)| c).collect()
}

#[test]
fn a_cut_through_the_whole_cube_makes_two_closed_pieces_of_the_right_volumes() {
    let surface = cube_surface(4);
    // the simulation mesh a little inside the surface: the surface hangs out of it
    let mesh = procedural::block_tet([0.02; 3], [0.96; 3], [5, 5, 5]);
    let plane = x_plane(0.43);
    let split = visual_split::split(&surface, &mesh, &plane, &crossed(&mesh, &plane)).unwrap();
    check_invariants(&surface, &split);
    let p = pieces(&split.surface);
    assert_eq!(p.len(), 2);
    let mut vols: Vec<f64> = p.iter().map(|t| volume(&split.surface.vertices, t)).collect();
    vols.sort_by(f64::total_cmp);
    assert!((vols[0] - 0.43).abs() < 1e-12 && (vols[1] - 0.57).abs() < 1e-12, "{vols:?}");
    // the cap spans the whole cross-section, the surface outside the simulation mesh included
    let r = split.report;
    assert!((r.cap_area - 1.0).abs() < 1e-12, "{r:?}");
    assert_eq!(r.front_vertices, 0);
    // every contour vertex (on the grid lines and the squares' diagonals) opened
    assert_eq!(r.doubled_vertices, r.plane_vertices);
    assert_eq!(r.doubled_vertices, 32);
    println!("{r:?}");
}

#[test]
fn a_cut_ending_inside_closes_at_its_front_and_keeps_one_piece() {
    let surface = cube_surface(5);
    // cells 0.2 wide with a layer boundary at z = 0.5: the cut down from the top to mid-height
    let mesh = procedural::block_tet([-0.1; 3], [1.2; 3], [6, 6, 6]);
    let plane = x_plane(0.37);
    let centre_z = |c: usize| mesh.cell(c).iter().map(|&a| mesh.nodes[a][2]).sum::<f64>() / 4.0;
    let cells: Vec<usize> = crossed(&mesh, &plane).into_iter().filter(|&c| centre_z(c) > 0.5).collect();
    let split = visual_split::split(&surface, &mesh, &plane, &cells).unwrap();
    check_invariants(&surface, &split);
    assert_eq!(pieces(&split.surface).len(), 1);
    let r = split.report;
    assert!((r.cap_area - 0.5).abs() < 1e-12, "{r:?}");
    assert!(r.front_vertices > 0, "{r:?}");
    // opened above mid-height only; where the front comes out, the slit ends in one vertex
    for (v, &x) in split.surface.vertices.iter().enumerate() {
        match split.side[v] {
            VertexSide::Positive | VertexSide::Negative => assert!(x[2] > 0.5 - 1e-12, "vertex {v} at {x:?}"),
            VertexSide::Mean => assert!(x[2] <= 0.5 + 1e-12 || x[2] > 0.0 && x[1] > 0.0 && x[1] < 1.0, "{x:?}"),
            VertexSide::Own => assert!(plane.phi(x).abs() > 1e-12),
        }
    }
}

#[test]
fn a_plane_through_surface_vertices_makes_no_sliver() {
    let surface = cube_surface(5);
    let mesh = procedural::block_tet([-0.1; 3], [1.2; 3], [6, 6, 6]);
    // x = 0.4 holds a column of surface vertices, and x = 0.1 + 1e-13 nearly a layer of nodes
    for x in [0.4, 0.1 + 1e-13] {
        let plane = x_plane(x);
        let split = visual_split::split(&surface, &mesh, &plane, &crossed(&mesh, &plane)).unwrap();
        check_invariants(&surface, &split);
        let p = pieces(&split.surface);
        assert_eq!(p.len(), 2, "x = {x}");
        let v: Vec<f64> = p.iter().map(|t| volume(&split.surface.vertices, t)).collect();
        assert!(
            (v.iter().copied().fold(f64::INFINITY, f64::min) - x.min(1.0 - x)).abs() < 1e-9,
            "{v:?}"
        );
    }
}

#[test]
fn no_cut_cell_leaves_the_surface_as_it_was_but_split_along_the_plane() {
    let surface = cube_surface(3);
    let mesh = procedural::block_tet([-0.1; 3], [1.2; 3], [4, 4, 4]);
    let split = visual_split::split(&surface, &mesh, &x_plane(0.5), &[]).unwrap();
    check_invariants(&surface, &split);
    assert_eq!(pieces(&split.surface).len(), 1);
    assert_eq!((split.report.cap_triangles, split.report.doubled_vertices), (0, 0));
    let bad = visual_split::split(&surface, &mesh, &x_plane(0.5), &[10_000]).unwrap_err();
    assert!(matches!(bad, SplitError::Cell { cell: 10_000, .. }), "{bad}");
    let flat = Plane {
        point: [0.5; 3],
        normal: [0.0; 3],
    };
    assert!(matches!(
        visual_split::split(&surface, &mesh, &flat, &[]),
        Err(SplitError::Malformed(_))
    ));
    let nan = VisualMesh {
        vertices: vec![[f64::NAN; 3]; 3],
        triangles: vec![[0, 1, 2]],
    };
    assert!(matches!(
        visual_split::split(&nan, &mesh, &x_plane(0.5), &[]),
        Err(SplitError::Malformed(_))
    ));
    let hexes = procedural::block_hex([0.0; 3], [1.0; 3], [1, 1, 1]);
    assert!(matches!(
        visual_split::split(&surface, &hexes, &x_plane(0.5), &[]),
        Err(SplitError::NotTetrahedra(_))
    ));
}

/// Each side's own motion (an affine one per side).
fn motion(positive: bool, x: [f64; 3]) -> [f64; 3] {
    if positive {
        [0.3 + 0.2 * x[1], -0.1, 0.05 * x[0]]
    } else {
        [-0.2, 0.1 * x[2], 0.4]
    }
}

fn liver() -> Option<(Mesh, VisualMesh)> {
    let dir: PathBuf = common::shared_data()?.join("data/meshes/sofa");
    let mesh = mesh::read(dir.join("liver.msh")).unwrap();
    let visual = VisualMesh::load_obj(&dir.join("liver-smooth.obj"), 1.0).unwrap();
    Some((mesh, visual))
}

#[test]
fn the_smooth_liver_opens_along_a_progressive_incision_step_by_step() {
    let Some((mesh, visual)) = liver() else { return };
    let (lo, hi) = mesh.bounding_box();
    // a scalpel held in the plane x = x0, its edge vertical through the whole liver, drawn along y
    let x0 = lo[0] + 0.41 * (hi[0] - lo[0]);
    let (z0, z1) = (lo[2] - 0.1, hi[2] + 0.1);
    let mut cut = ProgressiveCut::new(&mesh).unwrap();
    let steps = 8;
    let at = |s: usize| lo[1] - 0.1 + (hi[1] - lo[1] + 0.2) * s as f64 / steps as f64;
    let mut cap_area = 0.0;
    for s in 0..steps {
        let (y0, y1) = (at(s), at(s + 1));
        cut.sweep(&mesh, [x0, y0, z0], [x0, y0, z1], [x0, y1, z0], [x0, y1, z1]);
        let Some(plane) = visual_split::cut_plane(&mesh, &cut).unwrap() else {
            continue;
        };
        assert!(
            (plane.normal[0].abs() - 1.0).abs() < 1e-9 && (plane.point[0] - x0).abs() < 1e-9,
            "{plane:?}"
        );
        let split = visual_split::split(&visual, &mesh, &plane, cut.cut_cells()).unwrap();
        check_invariants(&visual, &split);
        // the cap only grows as the blade advances
        assert!(split.report.cap_area >= cap_area - 1e-12, "step {s}: {:?}", split.report);
        cap_area = split.report.cap_area;
        // every vertex follows its side: hosted in a cut cell, it moves exactly with its side
        let enr = Enrichment::from_cut_cells(&mesh, &cut.cut_planes(&mesh), &XfemParams::default()).unwrap();
        let d = common::two_sides::displacements(&mesh, &enr, &plane, motion);
        let mut e = Embedding::new(&mesh, &split.surface.vertices).unwrap().with_sides(&split.side);
        e.follow_cut(&mesh, &enr, &split.surface.vertices);
        let mut u = vec![0.0; 3 * split.surface.vertices.len()];
        e.displacements(&mesh, &enr, &split.surface.vertices, &d, &mut u);
        let mut checked = 0;
        for (v, &x) in split.surface.vertices.iter().enumerate() {
            let positive = match split.side[v] {
                VertexSide::Positive => true,
                VertexSide::Negative => false,
                VertexSide::Own => plane.phi(x) > 0.0,
                VertexSide::Mean => continue,
            };
            let host_cut = mesh.cell(e.cell[v]).iter().all(|&a| enr.index(a).is_some());
            if !host_cut || enr.dropped.iter().any(|dn| mesh.cell(e.cell[v]).contains(&dn.node)) {
                continue;
            }
            let want = motion(positive, x);
            for i in 0..3 {
                assert!(
                    (u[3 * v + i] - want[i]).abs() < 1e-9,
                    "step {s}, vertex {v} ({:?}): {:?} vs {want:?}",
                    split.side[v],
                    &u[3 * v..3 * v + 3]
                );
            }
            checked += 1;
        }
        println!(
            "step {s}: {} cut cells, {:?}, {checked} vertices checked in cut cells",
            cut.cut_cells().len(),
            split.report
        );
        if split.report.doubled_vertices > 0 {
            assert!(checked > 0);
        }
    }
    // cut through: the liver is in two pieces
    let plane = visual_split::cut_plane(&mesh, &cut).unwrap().unwrap();
    let split = visual_split::split(&visual, &mesh, &plane, cut.cut_cells()).unwrap();
    assert_eq!(pieces(&split.surface).len(), 2);
}

#[test]
fn a_cut_that_is_not_one_plane_is_refused_with_its_residual() {
    let mesh = procedural::block_tet([0.0; 3], [1.0; 3], [4, 4, 4]);
    let mut cut = ProgressiveCut::new(&mesh).unwrap();
    assert_eq!(visual_split::cut_plane(&mesh, &cut).unwrap(), None);
    // two strokes at a right angle
    cut.sweep(&mesh, [0.41, -0.1, -0.1], [0.41, -0.1, 1.1], [0.41, 1.1, -0.1], [0.41, 1.1, 1.1]);
    cut.sweep(&mesh, [-0.1, 0.63, -0.1], [-0.1, 0.63, 1.1], [1.1, 0.63, -0.1], [1.1, 0.63, 1.1]);
    let e = visual_split::cut_plane(&mesh, &cut).unwrap_err();
    assert!(matches!(e, SplitError::NotPlanar { .. }), "{e}");
    assert!(e.to_string().contains("not planar"), "{e}");
}

#[test]
fn a_blade_that_backs_out_and_comes_back_leaves_the_same_split() {
    let surface = cube_surface(4);
    let mesh = procedural::block_tet([-0.1; 3], [1.2; 3], [6, 6, 6]);
    let mut cut = ProgressiveCut::new(&mesh).unwrap();
    let stroke = |cut: &mut ProgressiveCut, y0: f64, y1: f64| {
        cut.sweep(&mesh, [0.43, y0, -0.2], [0.43, y0, 1.2], [0.43, y1, -0.2], [0.43, y1, 1.2]);
    };
    stroke(&mut cut, -0.2, 0.55);
    let plane = visual_split::cut_plane(&mesh, &cut).unwrap().unwrap();
    let first = visual_split::split(&surface, &mesh, &plane, cut.cut_cells()).unwrap();
    check_invariants(&surface, &first);
    // back out along the path, stop, and return to where it was
    stroke(&mut cut, 0.55, 0.1);
    stroke(&mut cut, 0.1, 0.55);
    let plane = visual_split::cut_plane(&mesh, &cut).unwrap().unwrap();
    let again = visual_split::split(&surface, &mesh, &plane, cut.cut_cells()).unwrap();
    assert_eq!(again, first);
    // and resuming opens further
    stroke(&mut cut, 0.55, 1.3);
    let plane = visual_split::cut_plane(&mesh, &cut).unwrap().unwrap();
    let through = visual_split::split(&surface, &mesh, &plane, cut.cut_cells()).unwrap();
    check_invariants(&surface, &through);
    assert!(through.report.cap_area > first.report.cap_area);
    assert_eq!(pieces(&through.surface).len(), 2);
}

#[test]
fn strokes_meeting_split_the_surface_along_the_larger_one_which_stays_closed() {
    // a T: a cut through the cube down x = 0.37 (the larger), and one along z = 0.53 from the
    // left face that meets it
    let surface = cube_surface(5);
    let mesh = procedural::block_tet([-0.1; 3], [1.2; 3], [6, 6, 6]);
    let (a, b) = (
        x_plane(0.37),
        Plane {
            point: [0.5, 0.5, 0.53],
            normal: [0.0, 0.0, 1.0],
        },
    );
    let centre = |c: usize, k: usize| mesh.cell(c).iter().map(|&v| mesh.nodes[v][k]).sum::<f64>() / 4.0;
    let mut cut: Vec<(usize, Plane)> = Enrichment::cells_crossed_by(&mesh, &a);
    let along_a = cut.len();
    let more: Vec<(usize, Plane)> = Enrichment::cells_crossed_by(&mesh, &b)
        .into_iter()
        .filter(|(c, _)| centre(*c, 0) < 0.3 && !cut.iter().any(|(d, _)| d == c))
        .collect();
    cut.extend(more);
    assert!(cut.len() > along_a);
    // not one plane; its largest planar part is the stroke down x = 0.37
    let e = visual_split::cut_plane_of_cells(&mesh, &cut, visual_split::SESSION_PLANARITY).unwrap_err();
    assert!(matches!(e, SplitError::NotPlanar { .. }));
    let (plane, part) = visual_split::largest_planar_part(&mesh, &cut, visual_split::SESSION_PLANARITY).unwrap();
    assert_eq!(part.len(), along_a);
    assert!(
        (plane.normal[0].abs() - 1.0).abs() < 1e-9 && (plane.phi([0.37, 0.2, 0.9])).abs() < 1e-9,
        "{plane:?}"
    );
    // split along it: two closed pieces, the invariants hold
    let cells: Vec<usize> = part.iter().map(|c| c.0).collect();
    let split = visual_split::split(&surface, &mesh, &plane, &cells).unwrap();
    check_invariants(&surface, &split);
    assert_eq!(pieces(&split.surface).len(), 2);
    // a cut with no planar part of three cells gives none
    assert!(visual_split::largest_planar_part(&mesh, &cut[..2], visual_split::SESSION_PLANARITY).is_none());
}
