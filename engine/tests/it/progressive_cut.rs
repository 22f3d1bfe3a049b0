//! Semi-progressive cutting (seed 003 §3.3): a cell is cut only once the blade has crossed it
//! entirely; partly crossed cells wait in the lists L1–L3 with their crossings shown; a blade
//! that stops, backs out and resumes cuts what one steady stroke cuts; a blade through nodes
//! or along faces cuts only cells it really divides.

use std::collections::BTreeSet;

use vademecum_engine::mesh::{Mesh, procedural};
use vademecum_engine::xfem::progressive::{NotTetrahedra, ProgressiveCut};

/// The blade's edge at `x` along the stroke: from its tip at depth `tip_z` up through the top
/// of the block, in the plane `y = y0 + slope·x` (a vertical blade moving along x).
fn blade(x: f64, y0: f64, slope: f64, tip_z: f64) -> ([f64; 3], [f64; 3]) {
    let y = y0 + slope * x;
    ([x, y, tip_z], [x, y, 1.5])
}

/// Sweeps the blade through the positions `xs` in turn; returns the cut's state.
fn stroke(mesh: &Mesh, xs: &[f64], y0: f64, slope: f64, tip_z: f64) -> ProgressiveCut {
    let mut cut = ProgressiveCut::new(mesh).unwrap();
    for w in xs.windows(2) {
        let (t0, b0) = blade(w[0], y0, slope, tip_z);
        let (t1, b1) = blade(w[1], y0, slope, tip_z);
        cut.sweep(mesh, t0, b0, t1, b1);
    }
    cut
}

fn set(cut: &ProgressiveCut) -> BTreeSet<usize> {
    cut.cut_cells().iter().copied().collect()
}

/// Whether the plane `y = y0 + slope·x` has vertices of cell `c` strictly on both sides.
fn divides(mesh: &Mesh, c: usize, y0: f64, slope: f64) -> bool {
    let phi: Vec<f64> = mesh
        .cell(c)
        .iter()
        .map(|&a| mesh.nodes[a][1] - y0 - slope * mesh.nodes[a][0])
        .collect();
    phi.iter().any(|&p| p > 1e-12) && phi.iter().any(|&p| p < -1e-12)
}

#[test]
fn a_cell_is_cut_only_once_the_blade_has_crossed_it() {
    let mesh = procedural::block_tet([0.0; 3], [1.0; 3], [4, 4, 2]);
    let (y0, slope) = (0.53, 0.07);
    // a steady stroke through the whole block, the tip below it: every cell the plane divides
    let through = stroke(&mesh, &[-0.1, 1.1], y0, slope, -0.5);
    let divided: BTreeSet<usize> = (0..mesh.n_cells()).filter(|&c| divides(&mesh, c, y0, slope)).collect();
    assert_eq!(set(&through), divided);
    assert!(through.lists().iter().all(Vec::is_empty), "nothing left half crossed");
    // stopped halfway: the cells behind the blade are cut, those it stands in are crossed on
    // some edges only (L1–L3, shown as polygons), those ahead untouched
    let half = stroke(&mesh, &[-0.1, 0.6], y0, slope, -0.5);
    let cut = set(&half);
    assert!(!cut.is_empty() && cut.is_subset(&divided) && cut.len() < divided.len());
    let [l1, l2, l3] = half.lists();
    let waiting: BTreeSet<usize> = l1.iter().chain(&l2).chain(&l3).copied().collect();
    assert!(!waiting.is_empty() && waiting.is_disjoint(&cut));
    for c in &waiting {
        assert!(divided.contains(c), "cell {c} crossed but the plane does not divide it");
        let centroid_x: f64 = mesh.cell(*c).iter().map(|&a| mesh.nodes[a][0]).sum::<f64>() / 4.0;
        assert!(centroid_x > 0.3, "cell {c} behind the blade left uncut");
    }
    for (c, x) in half.partial() {
        assert!(!half.is_cut(c));
        for p in x.edges.values() {
            assert!(
                (p[1] - y0 - slope * p[0]).abs() < 1e-9 && p[0] <= 0.6 + 1e-9,
                "crossing {p:?} off the swept part"
            );
        }
    }
    // a shallow blade (tip at mid-depth) cuts the upper cells only
    let shallow = stroke(&mesh, &[-0.1, 1.1], y0, slope, 0.5);
    assert!(set(&shallow).is_subset(&divided) && set(&shallow).len() < divided.len());
    for c in set(&shallow) {
        assert!(mesh.cell(c).iter().any(|&a| mesh.nodes[a][2] > 0.5), "cell {c} below the tip cut");
    }
}

#[test]
fn a_blade_that_stops_backs_out_and_resumes_cuts_what_one_stroke_cuts() {
    let mesh = procedural::block_tet([0.0; 3], [1.0; 3], [5, 5, 3]);
    let (y0, slope) = (0.37, -0.11);
    let steady = stroke(&mesh, &[-0.1, 1.1], y0, slope, -0.2);
    // small steps, a stop, a retreat along the path and a resumption
    let mut xs: Vec<f64> = (0..=14).map(|k| -0.1 + 0.05 * k as f64).collect();
    xs.extend([0.5, 0.3, 0.3, 0.45]);
    xs.extend((0..=14).map(|k| 0.45 + 0.05 * k as f64));
    let halting = stroke(&mesh, &xs, y0, slope, -0.2);
    assert_eq!(set(&halting), set(&steady));
    // each cell cut once, the order following the blade
    assert_eq!(halting.cut_cells().len(), set(&halting).len());
}

#[test]
fn a_blade_through_nodes_or_along_faces_cuts_only_what_it_divides() {
    let mesh = procedural::block_tet([0.0; 3], [1.0; 3], [4, 4, 2]);
    // along the node layer y = 0.5: every cell touches the plane with a face, an edge or a
    // vertex and none is divided
    let along = stroke(&mesh, &[-0.1, 1.1], 0.5, 0.0, -0.5);
    assert!(along.cut_cells().is_empty(), "{:?}", along.cut_cells());
    // through the nodes (0, 0.25, ·) and (1, 0.75, ·) diagonally: it cuts exactly the cells
    // it divides, those it passes by a vertex or an edge stay whole
    let (y0, slope) = (0.25, 0.5);
    let diagonal = stroke(&mesh, &[-0.1, 1.1], y0, slope, -0.5);
    let divided: BTreeSet<usize> = (0..mesh.n_cells()).filter(|&c| divides(&mesh, c, y0, slope)).collect();
    assert_eq!(set(&diagonal), divided);
    // two strokes meeting at a point: each cuts its own cells
    let mut cross = stroke(&mesh, &[-0.1, 0.5], 0.53, 0.0, -0.5);
    let (t0, b0) = ([0.5, -0.1, -0.5], [0.5, -0.1, 1.5]);
    let (t1, b1) = ([0.5, 0.53, -0.5], [0.5, 0.53, 1.5]);
    cross.sweep(&mesh, t0, b0, t1, b1);
    assert!(!cross.cut_cells().is_empty());
    // a blade that does not move cuts nothing
    let mut still = ProgressiveCut::new(&mesh).unwrap();
    let (t, b) = blade(0.5, 0.53, 0.0, -0.5);
    assert!(still.sweep(&mesh, t, b, t, b).is_empty());
    // hexahedra are refused
    let hexes = procedural::block_hex([0.0; 3], [1.0; 3], [1, 1, 1]);
    assert!(matches!(ProgressiveCut::new(&hexes), Err(NotTetrahedra(_))));
}

#[test]
fn a_piece_the_blade_cut_loose_turns_rigidly_in_the_corotational_model() {
    use vademecum_engine::fem::Locking;
    use vademecum_engine::fem::assembly::MaterialMap;
    use vademecum_engine::fem::linear_static::StaticProblem;
    use vademecum_engine::material::LinearElastic;
    use vademecum_engine::xfem::corotational::{CorotationalSettings, CorotationalXfem};
    use vademecum_engine::xfem::{Enrichment, XfemParams, system};
    // a stroke through the whole block along y = 0.53 cuts it in two
    let mesh = procedural::block_tet([0.0; 3], [1.0; 3], [3, 3, 3]);
    let cut = stroke(&mesh, &[-0.1, 1.1], 0.53, 0.0, -0.5);
    let planes = cut.cut_planes(&mesh);
    for (_, p) in &planes {
        assert!((p.normal[1] - 1.0).abs() < 1e-9 && (p.point[1] - 0.53).abs() < 1e-9, "{p:?}");
    }
    let enr = Enrichment::from_cut_cells(&mesh, &planes, &XfemParams::default()).unwrap();
    // the face y = 0 held, the face y = 1 turned by 30° about the x axis and moved off by 0.2
    let q = nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::x_axis(), 0.5).into_inner();
    let rigid = |x: [f64; 3]| {
        let y = q * nalgebra::Vector3::new(x[0], x[1], x[2]);
        [y[0] - x[0], y[1] - x[1] + 0.2, y[2] - x[2]]
    };
    let mut problem = StaticProblem::new(mesh.n_nodes());
    for (a, x) in mesh.nodes.iter().enumerate() {
        if x[1] <= 1e-12 {
            problem.clamp(&[a]);
        } else if x[1] >= 1.0 - 1e-12 {
            for (i, v) in rigid(*x).into_iter().enumerate() {
                problem.prescribe(&[a], i, v);
            }
        }
    }
    let mats = MaterialMap::uniform(LinearElastic::new(1000.0, 0.3).unwrap(), 1000.0, mesh.n_cells());
    let model = CorotationalXfem::new(&mesh, &mats, &problem, &enr).unwrap();
    let co = model.solve(&CorotationalSettings::default()).unwrap();
    let linear = system::solve(&mesh, &mats, Locking::None, &problem, &enr, &XfemParams::default()).unwrap();
    // every node of the loose piece moves rigidly, every node of the held one stays
    let deviation = |d: &[f64]| {
        let mut worst = 0.0f64;
        for (a, &x) in mesh.nodes.iter().enumerate() {
            let want = if x[1] > 0.53 { rigid(x) } else { [0.0; 3] };
            for i in 0..3 {
                worst = worst.max((d[3 * a + i] - want[i]).abs());
            }
        }
        worst
    };
    let (co_dev, lin_dev) = (deviation(&co.d), deviation(&linear.u));
    println!(
        "{} cells cut; deviation from the rigid turn: co-rotational {co_dev:.1e} m, linear XFEM {lin_dev:.1e} m",
        planes.len()
    );
    assert!(co_dev < 1e-6, "{co_dev:e}");
    assert!(lin_dev > 1e-2, "the linear XFEM strains a turned piece: {lin_dev:e}");
}

#[test]
fn the_swept_surface_is_shown_in_the_cells_the_blade_entered_and_not_in_those_it_cut() {
    use vademecum_engine::xfem::partial::PartialSurface;
    let mesh = procedural::block_tet([0.0; 3], [1.0; 3], [4, 4, 2]);
    let (y0, slope) = (0.53, 0.07);
    let mut cut = ProgressiveCut::new(&mesh).unwrap();
    let mut shown = PartialSurface::new(&mesh).unwrap();
    let mut swept: Vec<[[f64; 3]; 3]> = Vec::new();
    let area = |t: &[[f64; 3]; 3]| {
        let n = vademecum_engine::geometry::vec3::cross(
            vademecum_engine::geometry::vec3::sub(t[1], t[0]),
            vademecum_engine::geometry::vec3::sub(t[2], t[0]),
        );
        0.5 * vademecum_engine::geometry::vec3::dot(n, n).sqrt()
    };
    // the blade's swept surface inside the block up to x, its tip at depth 0.25: the part of
    // the plane over 0 ≤ x ≤ x_end, 0.25 ≤ z ≤ 1, tilted by the slope
    let inside = |x: f64| x.clamp(0.0, 1.0) * 0.75 * (1.0f64 + slope * slope).sqrt();
    let xs: Vec<f64> = (0..=24).map(|k| -0.1 + 0.05 * k as f64).collect();
    let mut seen_partial = false;
    for w in xs.windows(2) {
        let (t0, b0) = blade(w[0], y0, slope, 0.25);
        let (t1, b1) = blade(w[1], y0, slope, 0.25);
        cut.sweep(&mesh, t0, b0, t1, b1);
        swept.extend([[t0, b0, b1], [t0, b1, t1]]);
        let partial = shown.update(&mesh, &swept, |c| cut.is_cut(c));
        // every shown triangle lies in the swept plane, behind the blade, in a cell not cut
        for t in &partial {
            for p in t {
                assert!((p[1] - y0 - slope * p[0]).abs() < 1e-12 && p[0] <= w[1] + 1e-12 && p[2] >= 0.25 - 1e-12);
            }
            let c: Vec<f64> = (0..3).map(|k| (t[0][k] + t[1][k] + t[2][k]) / 3.0).collect();
            let host = (0..mesh.n_cells()).find(|&cell| {
                let tet: [[f64; 3]; 4] = std::array::from_fn(|i| mesh.nodes[mesh.cell(cell)[i]]);
                barycentric_inside(&tet, [c[0], c[1], c[2]])
            });
            let host = host.expect("a shown triangle lies in the mesh");
            assert!(!cut.is_cut(host), "a triangle shown in cell {host}, which is cut");
        }
        // with the cut cells' share of the swept surface, it makes up the whole of it inside
        // the block: nothing shown twice, nothing missing
        let shown_area: f64 = partial.iter().map(area).sum();
        let cut_area: f64 = swept
            .iter()
            .map(|t| {
                cut.cut_cells()
                    .iter()
                    .map(|&c| {
                        let tet: [[f64; 3]; 4] = std::array::from_fn(|i| mesh.nodes[mesh.cell(c)[i]]);
                        let p = vademecum_engine::xfem::partial::clip_triangle_to_tet(t, &tet);
                        (1..p.len().saturating_sub(1)).map(|j| area(&[p[0], p[j], p[j + 1]])).sum::<f64>()
                    })
                    .sum::<f64>()
            })
            .sum();
        let total = inside(w[1]);
        assert!(
            (shown_area + cut_area - total).abs() < 1e-9 * total.max(1e-3),
            "{shown_area} + {cut_area} against {total}"
        );
        seen_partial |= shown_area > 0.0 && w[1] < 1.0;
    }
    assert!(seen_partial, "the blade's front showed a partial surface");
    // through the block with its tip inside: the cells at the tip's depth stay partly crossed
    assert!(!cut.cut_cells().is_empty());
}

/// Whether `p` lies inside tetrahedron `tet` (barycentric coordinates all ≥ −10⁻¹²).
fn barycentric_inside(tet: &[[f64; 3]; 4], p: [f64; 3]) -> bool {
    use vademecum_engine::geometry::vec3::{cross, dot, sub};
    let vol = |a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]| dot(sub(b, a), cross(sub(c, a), sub(d, a)));
    let v = vol(tet[0], tet[1], tet[2], tet[3]);
    let l = [
        vol(p, tet[1], tet[2], tet[3]) / v,
        vol(tet[0], p, tet[2], tet[3]) / v,
        vol(tet[0], tet[1], p, tet[3]) / v,
        vol(tet[0], tet[1], tet[2], p) / v,
    ];
    l.iter().all(|&x| x >= -1e-12)
}
