//! The visual surface split along a cut and closed by the triangulated cut faces (seed 003
//! §3.4: "when a cut happens an internal mesh must also be created and mapped").
//!
//! # What the split makes
//! A closed surface `M` cut by a planar region `R` (the part of the cut plane `P` inside the
//! cut cells) becomes the boundary of what is left of its inside, `M'`:
//!
//! 1. `M` is split along `P`: every triangle crossing the plane is cut into triangles on one
//!    side each, a new vertex where an edge crosses (vertices within a hair of the plane —
//!    10⁻⁹ of the surface's size — are taken as on it, so a vertex exactly on the plane makes
//!    no sliver). Where the surface crosses `P`, its edges on `P` form the *contour*.
//! 2. In the plane (2D coordinates on `P`), a constrained Delaunay triangulation (spade) holds
//!    the contour and the boundary of `R`, their crossings inserted on both (a contour edge
//!    split at a crossing is split in `M` too). A triangle of it is *cap* when it is inside
//!    `M` (even–odd rule against the contour) and inside `R`: inside a cut cell's
//!    cross-section, or, outside the simulation mesh (visual surfaces hang just outside their
//!    tetrahedra), nearest to a cut cell's cross-section rather than an uncut one's.
//! 3. The contour edges bordering the cap are *opened*: their vertices get a second copy for
//!    the negative side's triangles, unless the vertex also borders an edge that stays closed
//!    (where the cut's edge comes out through the surface: the slit ends there) or lies on the
//!    front. The cap's inner points get one copy per side, its front points one for both.
//! 4. The cap is added twice: on the positive side with the positive copies, facing `−n` (out
//!    of the material above the plane), and on the negative side, facing `+n`. Where the cut
//!    ends inside the surface (its front), both caps share the front's vertices and edges.
//!    An edge that parts (opened, or inside the cap) with both ends shared — the front crossing
//!    the contour twice, or running across the cap — parts at a midpoint with a copy per side.
//!
//! Every edge of `M'` is then shared by exactly two triangles traversing it in opposite
//! directions, as in `M`: a closed, consistently oriented 2-manifold (at rest its two caps lie
//! on each other; they part as the sides move).
//!
//! # Sides
//! Each vertex of `M'` says which side of the cut it follows ([`VertexSide`]): the copies of an
//! opened vertex one each; a vertex on the plane that is not opened (on the front, or where the
//! plane crosses the surface outside the cut) the mean of both, where the surface closes;
//! every other vertex the side of `P` it lies on.
//!
//! # Limits
//! One plane per cut: a cut whose crossings stray from their best plane by more than 1 % of a
//! cell is refused ([`SplitError::NotPlanar`]) rather than split wrongly; a session then splits
//! along the cut's largest planar part ([`largest_planar_part`]). A surface face lying
//! in the cut plane stays whole, on the side its normal leaves the material on.

use std::collections::HashMap;

use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use super::progressive::{ProgressiveCut, TET_EDGES};
use super::subcell::Plane;
pub use super::visual::VertexSide;
use super::visual::VisualMesh;
use crate::geometry::vec3::{cross, dot, lerp, sub};
use crate::mesh::{CellKind, Mesh};

/// A visual surface split along a cut.
#[derive(Debug, Clone, PartialEq)]
pub struct SplitSurface {
    /// The split surface: the original vertices first (same indices), then the new ones.
    pub surface: VisualMesh,
    /// The side each vertex follows.
    pub side: Vec<VertexSide>,
    /// What the split did.
    pub report: SplitReport,
}

/// What a split did, in counts.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SplitReport {
    /// Vertices on the cut plane (snapped or made where an edge crosses it).
    pub plane_vertices: usize,
    /// Contour edges opened.
    pub opened_edges: usize,
    /// Vertices given a second copy.
    pub doubled_vertices: usize,
    /// Vertices made on the cut's front inside the surface.
    pub front_vertices: usize,
    /// Triangles of each side's cap.
    pub cap_triangles: usize,
    /// Area of each side's cap (m²).
    pub cap_area: f64,
}

/// A surface could not be split along a cut.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SplitError {
    /// The simulation mesh is not made of tetrahedra.
    #[error("visual surfaces are split in tetrahedra; this mesh has {0:?} cells")]
    NotTetrahedra(CellKind),
    /// A cut cell is not in the mesh.
    #[error("cut cell {cell} is not in the mesh ({cells} cells)")]
    Cell {
        /// The cell.
        cell: usize,
        /// Cells in the mesh.
        cells: usize,
    },
    /// The cut is not one plane.
    #[error(
        "the cut is not planar: its crossings lie up to {residual:.3e} m from their best plane \
         (tolerance {tolerance:.3e} m); a visual surface is split along one plane per cut"
    )]
    NotPlanar {
        /// Largest distance of a crossing from the fitted plane.
        residual: f64,
        /// The tolerance (1 % of the mean cut cell's size).
        tolerance: f64,
    },
    /// The surface or the plane is malformed (an empty or non-finite surface, a plane
    /// without a finite normal).
    #[error("cannot split: {0}")]
    Malformed(String),
    /// The plane's triangulation could not be built (degenerate geometry).
    #[error("the cut faces could not be triangulated: {0}")]
    Triangulation(String),
}

fn cross2(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// Coordinates in the cut plane: `x = o + s u + t w`, with `u × w = n`.
struct Frame {
    origin: [f64; 3],
    u: [f64; 3],
    w: [f64; 3],
}

impl Frame {
    fn new(plane: &Plane) -> Self {
        let n = plane.normal;
        let k = (0..3).min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs())).unwrap_or(0);
        let mut e = [0.0; 3];
        e[k] = 1.0;
        let u = cross(e, n);
        let l = dot(u, u).sqrt();
        let u = [u[0] / l, u[1] / l, u[2] / l];
        Self {
            origin: plane.point,
            u,
            w: cross(n, u),
        }
    }

    fn to_2d(&self, x: [f64; 3]) -> [f64; 2] {
        let d = sub(x, self.origin);
        [dot(d, self.u), dot(d, self.w)]
    }
}

/// A point of the plane's triangulation.
#[derive(Debug, Clone, Copy)]
struct PlanePoint {
    xy: [f64; 2],
    x: [f64; 3],
    /// The surface vertex it is (contour points), if any.
    vertex: Option<usize>,
}

/// A segment of the plane with the points inserted along it, by parameter.
#[derive(Debug, Clone)]
struct Segment {
    ends: [usize; 2],
    splits: Vec<(f64, usize)>,
}

impl Segment {
    fn new(a: usize, b: usize) -> Self {
        Self {
            ends: [a, b],
            splits: Vec::new(),
        }
    }

    /// Its pieces, in order from `ends[0]` to `ends[1]`.
    fn pieces(&self) -> Vec<[usize; 2]> {
        let mut s = self.splits.clone();
        s.sort_by(|a, b| a.0.total_cmp(&b.0));
        s.dedup_by_key(|p| p.1);
        let mut chain = vec![self.ends[0]];
        chain.extend(s.iter().map(|p| p.1).filter(|&p| p != self.ends[0] && p != self.ends[1]));
        chain.push(self.ends[1]);
        chain.dedup();
        chain.windows(2).map(|w| [w[0], w[1]]).collect()
    }
}

/// A tetrahedron's cross-section by the plane: its convex polygon (counter-clockwise in the
/// plane's coordinates) as keys of the points it is made of (`(a, a)` a node on the plane,
/// `(a, b)` with `a < b` the crossing of edge ab).
fn cross_section(mesh: &Mesh, c: usize, phi: &[f64], frame: &Frame) -> Vec<((usize, usize), [f64; 3], [f64; 2])> {
    let cell = mesh.cell(c);
    let mut pts: Vec<((usize, usize), [f64; 3], [f64; 2])> = Vec::with_capacity(4);
    for &a in cell {
        if phi[a] == 0.0 {
            pts.push(((a, a), mesh.nodes[a], frame.to_2d(mesh.nodes[a])));
        }
    }
    for [i, j] in TET_EDGES {
        let (a, b) = (cell[i].min(cell[j]), cell[i].max(cell[j]));
        if phi[a] * phi[b] < 0.0 {
            let t = phi[a] / (phi[a] - phi[b]);
            let x = lerp(mesh.nodes[a], mesh.nodes[b], t);
            pts.push(((a, b), x, frame.to_2d(x)));
        }
    }
    if pts.len() < 3 {
        return Vec::new();
    }
    let n = pts.len() as f64;
    let centre = [
        pts.iter().map(|p| p.2[0]).sum::<f64>() / n,
        pts.iter().map(|p| p.2[1]).sum::<f64>() / n,
    ];
    pts.sort_by(|p, q| {
        let a = (p.2[1] - centre[1]).atan2(p.2[0] - centre[0]);
        let b = (q.2[1] - centre[1]).atan2(q.2[0] - centre[0]);
        a.total_cmp(&b)
    });
    pts
}

/// Distance from `p` to a convex counter-clockwise polygon (0 inside).
fn polygon_distance(poly: &[[f64; 2]], p: [f64; 2]) -> f64 {
    let mut inside = true;
    let mut best = f64::INFINITY;
    for k in 0..poly.len() {
        let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
        let e = [b[0] - a[0], b[1] - a[1]];
        let d = [p[0] - a[0], p[1] - a[1]];
        if cross2(e, d) < 0.0 {
            inside = false;
        }
        let l2 = e[0] * e[0] + e[1] * e[1];
        let t = if l2 > 0.0 {
            ((d[0] * e[0] + d[1] * e[1]) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = [d[0] - t * e[0], d[1] - t * e[1]];
        best = best.min((q[0] * q[0] + q[1] * q[1]).sqrt());
    }
    if inside { 0.0 } else { best }
}

/// Where segments `p0 p1` and `q0 q1` meet: the parameters along each, if they do (within
/// `tol`, relative), parallel ones never.
fn segments_meet(p0: [f64; 2], p1: [f64; 2], q0: [f64; 2], q1: [f64; 2], tol: f64) -> Option<(f64, f64)> {
    let r = [p1[0] - p0[0], p1[1] - p0[1]];
    let s = [q1[0] - q0[0], q1[1] - q0[1]];
    let den = cross2(r, s);
    let scale = (r[0] * r[0] + r[1] * r[1]).sqrt() * (s[0] * s[0] + s[1] * s[1]).sqrt();
    if den.abs() <= 1e-12 * scale {
        return None;
    }
    let d = [q0[0] - p0[0], q0[1] - p0[1]];
    let t = cross2(d, s) / den;
    let u = cross2(d, r) / den;
    ((-tol..=1.0 + tol).contains(&t) && (-tol..=1.0 + tol).contains(&u)).then_some((t.clamp(0.0, 1.0), u.clamp(0.0, 1.0)))
}

/// Distance parameter of `p` projected on segment `a b`, and its distance from it.
fn project(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> (f64, f64) {
    let e = [b[0] - a[0], b[1] - a[1]];
    let l2 = e[0] * e[0] + e[1] * e[1];
    let t = if l2 > 0.0 {
        ((p[0] - a[0]) * e[0] + (p[1] - a[1]) * e[1]) / l2
    } else {
        0.0
    };
    let q = [a[0] + t * e[0] - p[0], a[1] + t * e[1] - p[1]];
    (t, (q[0] * q[0] + q[1] * q[1]).sqrt())
}

/// The surface split along the plane: its vertices (the crossings of its edges appended),
/// their signed distances (0 on the plane), its triangles with the side each lies on (±1).
struct Halves {
    vertices: Vec<[f64; 3]>,
    phi: Vec<f64>,
    triangles: Vec<([usize; 3], i8)>,
}

/// Step 1 (module docs): every triangle crossing the plane cut into triangles on one side
/// each, a crossing vertex per edge; `snapped` is the signed distance, 0 within a hair.
fn halves(visual: &VisualMesh, plane: &Plane, snapped: impl Fn([f64; 3]) -> f64) -> Halves {
    let mut vertices = visual.vertices.clone();
    let mut phi: Vec<f64> = vertices.iter().map(|&x| snapped(x)).collect();
    let mut crossing: HashMap<(usize, usize), usize> = HashMap::new();
    // triangles with their side (+1 / -1)
    let mut triangles: Vec<([usize; 3], i8)> = Vec::with_capacity(visual.triangles.len() + 64);
    for t in &visual.triangles {
        let s = t.map(|v| phi[v]);
        let (pos, neg) = (s.iter().any(|&f| f > 0.0), s.iter().any(|&f| f < 0.0));
        if !(pos && neg) {
            let side = if pos {
                1
            } else if neg {
                -1
            } else {
                // a face in the plane: on the side its outward normal leaves the material on
                let (a, b, c) = (vertices[t[0]], vertices[t[1]], vertices[t[2]]);
                if dot(cross(sub(b, a), sub(c, a)), plane.normal) > 0.0 {
                    -1
                } else {
                    1
                }
            };
            triangles.push((*t, side));
            continue;
        }
        let mut polys: [Vec<usize>; 2] = [Vec::with_capacity(4), Vec::with_capacity(4)];
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if phi[a] >= 0.0 {
                polys[0].push(a);
            }
            if phi[a] <= 0.0 {
                polys[1].push(a);
            }
            if phi[a] * phi[b] < 0.0 {
                let key = (a.min(b), a.max(b));
                let x = *crossing.entry(key).or_insert_with(|| {
                    let (p, q) = key;
                    let tt = phi[p] / (phi[p] - phi[q]);
                    vertices.push(lerp(vertices[p], vertices[q], tt));
                    phi.push(0.0);
                    vertices.len() - 1
                });
                polys[0].push(x);
                polys[1].push(x);
            }
        }
        for (poly, side) in polys.iter().zip([1i8, -1]) {
            for k in 1..poly.len().saturating_sub(1) {
                triangles.push(([poly[0], poly[k], poly[k + 1]], side));
            }
        }
    }
    Halves { vertices, phi, triangles }
}

/// The contour: the edges on the plane between triangles of opposite sides.
fn contour_edges(triangles: &[([usize; 3], i8)], phi: &[f64]) -> Vec<(usize, usize)> {
    let on_plane = |v: usize| phi[v] == 0.0;

    // the contour: edges on the plane between triangles of opposite sides
    let mut edge_sides: HashMap<(usize, usize), (u8, u8)> = HashMap::new();
    for &(t, side) in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if on_plane(a) && on_plane(b) {
                let e = edge_sides.entry((a.min(b), a.max(b))).or_default();
                if side > 0 { e.0 += 1 } else { e.1 += 1 }
            }
        }
    }
    let mut contour: Vec<(usize, usize)> = edge_sides.iter().filter(|e| *e.1 == (1, 1)).map(|(&e, _)| e).collect();
    contour.sort_unstable();
    contour
}

/// The cut region in the plane: every crossed cell's cross-section (whether it is cut), and
/// the boundary of the cut ones' union as segments between points added to `points`.
struct Region {
    sections: Vec<(bool, Vec<[f64; 2]>)>,
    segments: Vec<Segment>,
}

fn cut_region(mesh: &Mesh, node_phi: &[f64], is_cut: &[bool], frame: &Frame, points: &mut Vec<PlanePoint>) -> Region {
    // every cell's cross-section; the cut ones' edges (a key pair) counted for the boundary
    let mut sections: Vec<(bool, Vec<[f64; 2]>)> = Vec::new();
    let mut key_point: HashMap<(usize, usize), usize> = HashMap::new();
    let mut boundary_count: HashMap<((usize, usize), (usize, usize)), u32> = HashMap::new();
    let mut seen_sections: std::collections::HashSet<Vec<(usize, usize)>> = std::collections::HashSet::new();
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        let (mut pos, mut neg) = (false, false);
        for &a in cell {
            pos |= node_phi[a] > 0.0;
            neg |= node_phi[a] < 0.0;
        }
        let zeros = cell.iter().filter(|&&a| node_phi[a] == 0.0).count();
        if !(pos && neg) && zeros < 3 {
            continue;
        }
        let sec = cross_section(mesh, c, node_phi, frame);
        if sec.is_empty() {
            continue;
        }
        let mut keys: Vec<(usize, usize)> = sec.iter().map(|p| p.0).collect();
        keys.sort_unstable();
        let first = seen_sections.insert(keys);
        sections.push((is_cut[c], sec.iter().map(|p| p.2).collect()));
        if !is_cut[c] || !first {
            continue;
        }
        for k in 0..sec.len() {
            let (a, b) = (sec[k].0, sec[(k + 1) % sec.len()].0);
            for (key, x, xy) in [sec[k], sec[(k + 1) % sec.len()]] {
                key_point.entry(key).or_insert_with(|| {
                    points.push(PlanePoint { xy, x, vertex: None });
                    points.len() - 1
                });
            }
            *boundary_count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut region_segments: Vec<Segment> = boundary_count
        .iter()
        .filter(|e| *e.1 == 1)
        .map(|(&(a, b), _)| Segment::new(key_point[&a], key_point[&b]))
        .collect();
    region_segments.sort_by_key(|s| s.ends);
    Region {
        sections,
        segments: region_segments,
    }
}

/// The surface's triangles with the contour edges split at the points given on them
/// (parameters from the lower vertex to the higher), each into a fan from its opposite corner.
fn split_edges(triangles: &[([usize; 3], i8)], edge_splits: &HashMap<(usize, usize), Vec<(f64, usize)>>) -> Vec<([usize; 3], i8)> {
    let mut out = Vec::with_capacity(triangles.len() + 2 * edge_splits.len());
    for &(t, side) in triangles {
        let split_edge = (0..3).find_map(|k| {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edge_splits.get(&(a.min(b), a.max(b))).map(|s| (k, a, b, s))
        });
        let Some((k, a, b, s)) = split_edge else {
            out.push((t, side));
            continue;
        };
        let c = t[(k + 2) % 3];
        let mut inner: Vec<(f64, usize)> = s.iter().map(|&(u, v)| (if a < b { u } else { 1.0 - u }, v)).collect();
        inner.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut chain = vec![a];
        chain.extend(inner.iter().map(|p| p.1));
        chain.push(b);
        for w in chain.windows(2) {
            out.push(([w[0], w[1], c], side));
        }
    }
    out
}

/// The constrained Delaunay triangulation of `points` holding the segments `pieces`; its
/// triangles for which `keep(centre)` holds, counter-clockwise (facing +n), as point indices,
/// and their area.
fn triangulate(
    points: &[PlanePoint],
    pieces: &[[usize; 2]],
    keep: impl Fn([f64; 2]) -> bool,
) -> Result<(Vec<[usize; 3]>, f64), SplitError> {
    let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> = ConstrainedDelaunayTriangulation::new();
    let mut handle_point: HashMap<usize, usize> = HashMap::new();
    let mut handle_of: Vec<Option<spade::handles::FixedVertexHandle>> = vec![None; points.len()];
    let mut used: Vec<usize> = pieces.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    for &p in &used {
        let h = cdt
            .insert(Point2::new(points[p].xy[0], points[p].xy[1]))
            .map_err(|e| SplitError::Triangulation(format!("{e:?}")))?;
        if let Some(&other) = handle_point.get(&h.index()) {
            if points[other].vertex.is_some() && points[p].vertex.is_some() && points[other].vertex != points[p].vertex {
                return Err(SplitError::Triangulation(format!(
                    "surface vertices {:?} and {:?} lie on each other in the cut plane",
                    points[other].vertex, points[p].vertex
                )));
            }
            if points[p].vertex.is_some() {
                handle_point.insert(h.index(), p);
            }
        } else {
            handle_point.insert(h.index(), p);
        }
        handle_of[p] = Some(h);
    }
    let inserted = cdt.num_vertices();
    for &[p, q] in pieces {
        let (Some(hp), Some(hq)) = (handle_of[p], handle_of[q]) else {
            continue;
        };
        if hp != hq && !cdt.exists_constraint(hp, hq) && cdt.try_add_constraint(hp, hq).is_empty() && !cdt.exists_constraint(hp, hq) {
            return Err(SplitError::Triangulation(format!(
                "the contour and the cut's boundary cross near {:?}",
                points[p].x
            )));
        }
    }
    if cdt.num_vertices() != inserted {
        return Err(SplitError::Triangulation("constraints met where no point was inserted".into()));
    }

    let mut cap: Vec<[usize; 3]> = Vec::new();
    let mut cap_area = 0.0;
    for face in cdt.inner_faces() {
        let vs = face.vertices();
        let xy: [[f64; 2]; 3] = vs.map(|v| [v.position().x, v.position().y]);
        let centre = [(xy[0][0] + xy[1][0] + xy[2][0]) / 3.0, (xy[0][1] + xy[1][1] + xy[2][1]) / 3.0];
        if !keep(centre) {
            continue;
        }
        let ids = vs.map(|v| handle_point.get(&v.fix().index()).copied());
        let [Some(a), Some(b), Some(c)] = ids else {
            return Err(SplitError::Triangulation("a cut face's corner is no inserted point".into()));
        };
        let area = 0.5
            * cross2(
                [xy[1][0] - xy[0][0], xy[1][1] - xy[0][1]],
                [xy[2][0] - xy[0][0], xy[2][1] - xy[0][1]],
            );
        cap_area += area.abs();
        // counter-clockwise in the plane: facing +n
        cap.push(if area >= 0.0 { [a, b, c] } else { [a, c, b] });
    }

    Ok((cap, cap_area))
}

/// The arguments of [`split`] checked (tetrahedra, cells in range, a well-formed surface, a
/// finite plane), the plane's normal made unit, and the size of the scene (the diagonal of
/// the box around the surface and the mesh) that the tolerances scale with.
fn checked_plane(visual: &VisualMesh, mesh: &Mesh, plane: &Plane, cut_cells: &[usize]) -> Result<(Plane, f64), SplitError> {
    if mesh.kind != CellKind::Tet4 {
        return Err(SplitError::NotTetrahedra(mesh.kind));
    }
    if let Some(&cell) = cut_cells.iter().find(|&&c| c >= mesh.n_cells()) {
        return Err(SplitError::Cell {
            cell,
            cells: mesh.n_cells(),
        });
    }
    visual.check().map_err(|e| SplitError::Malformed(e.to_string()))?;
    let l = dot(plane.normal, plane.normal).sqrt();
    if !(l > 0.0 && l.is_finite() && plane.point.iter().all(|x| x.is_finite())) {
        return Err(SplitError::Malformed(format!(
            "the cut plane {plane:?} has no finite normal or point"
        )));
    }
    let plane = Plane {
        point: plane.point,
        normal: [plane.normal[0] / l, plane.normal[1] / l, plane.normal[2] / l],
    };
    let size = {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in visual.vertices.iter().chain(&mesh.nodes) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        dot(sub(hi, lo), sub(hi, lo)).sqrt()
    };
    Ok((plane, size))
}

/// Marks where each contour segment and each segment of the cut region's boundary cross or
/// touch (an end of one within `touch` of the other): the splits of both, a new point at each
/// crossing.
fn mark_crossings(
    points: &mut Vec<PlanePoint>,
    contour_segments: &mut [Segment],
    region_segments: &mut [Segment],
    frame: &Frame,
    touch: f64,
) {
    let tol = 1e-9;
    let contour_len = contour_segments.len();
    for ci in 0..contour_len {
        let [a, b] = contour_segments[ci].ends;
        let (pa, pb) = (points[a].xy, points[b].xy);
        for seg in region_segments.iter_mut() {
            let [p, q] = seg.ends;
            let (pp, pq) = (points[p].xy, points[q].xy);
            // an end of either lying on the other
            for (end, at) in [(p, pp), (q, pq)] {
                let (t, d) = project(pa, pb, at);
                if d <= touch && t > tol && t < 1.0 - tol {
                    let x = lerp(points[a].x, points[b].x, t);
                    points[end].x = x;
                    contour_segments[ci].splits.push((t, end));
                }
            }
            for (end, at) in [(a, pa), (b, pb)] {
                let (t, d) = project(pp, pq, at);
                if d <= touch && t > tol && t < 1.0 - tol {
                    seg.splits.push((t, end));
                }
            }
            if let Some((t, u)) = segments_meet(pa, pb, pp, pq, 0.0)
                && t > tol
                && t < 1.0 - tol
                && u > tol
                && u < 1.0 - tol
            {
                let x = lerp(points[a].x, points[b].x, t);
                points.push(PlanePoint {
                    xy: frame.to_2d(x),
                    x,
                    vertex: None,
                });
                let id = points.len() - 1;
                contour_segments[ci].splits.push((t, id));
                seg.splits.push((u, id));
            }
        }
    }
}

/// Each point, or the contour vertex's point it lies on (within `touch`): a region point
/// that fell on a contour vertex is that vertex.
fn aliases(points: &[PlanePoint], vertex_points: impl Iterator<Item = usize>, touch: f64) -> Vec<usize> {
    let mut alias: Vec<usize> = (0..points.len()).collect();
    for pv in vertex_points {
        for (i, p) in points.iter().enumerate().filter(|(_, p)| p.vertex.is_none()) {
            let d = [p.xy[0] - points[pv].xy[0], p.xy[1] - points[pv].xy[1]];
            if (d[0] * d[0] + d[1] * d[1]).sqrt() <= touch {
                alias[i] = pv;
            }
        }
    }
    alias
}

/// The contour's segments cut at their splits into pieces between points (aliases resolved,
/// empty pieces dropped); each new point inside a segment becomes a surface vertex on the
/// plane, and the surface edge it lies on is to be split there: the pieces, and the splits of
/// each edge (lower vertex, higher vertex) by parameter from the lower.
fn split_contour(
    points: &mut [PlanePoint],
    contour_segments: &[Segment],
    alias: &[usize],
    vertices: &mut Vec<[f64; 3]>,
    phi: &mut Vec<f64>,
) -> (Vec<[usize; 2]>, HashMap<(usize, usize), Vec<(f64, usize)>>) {
    let mut edge_splits: HashMap<(usize, usize), Vec<(f64, usize)>> = HashMap::new();
    let mut contour_pieces: Vec<[usize; 2]> = Vec::new();
    for seg in contour_segments {
        let pieces: Vec<[usize; 2]> = seg
            .pieces()
            .into_iter()
            .map(|[p, q]| [alias[p], alias[q]])
            .filter(|[p, q]| p != q)
            .collect();
        for &[_, q] in &pieces[..pieces.len().saturating_sub(1)] {
            if points[q].vertex.is_none() {
                vertices.push(points[q].x);
                phi.push(0.0);
                points[q].vertex = Some(vertices.len() - 1);
            }
        }
        let (a, b) = (
            points[seg.ends[0]].vertex.unwrap_or(usize::MAX),
            points[seg.ends[1]].vertex.unwrap_or(usize::MAX),
        );
        let inner: Vec<(f64, usize)> = pieces[..pieces.len().saturating_sub(1)]
            .iter()
            .filter_map(|&[_, q]| {
                let v = points[q].vertex?;
                let (t, _) = project(points[seg.ends[0]].xy, points[seg.ends[1]].xy, points[q].xy);
                Some((t, v))
            })
            .collect();
        if !inner.is_empty() {
            // parameters from the lower vertex to the higher
            let list = edge_splits.entry((a.min(b), a.max(b))).or_default();
            for (t, v) in inner {
                list.push((if a < b { t } else { 1.0 - t }, v));
            }
        }
        contour_pieces.extend(pieces);
    }
    (contour_pieces, edge_splits)
}

/// How the cap's triangles meet the contour.
struct CapEdges {
    /// Each cap edge (lower point, higher point) and the cap triangles on it (1: its boundary).
    cap_edges: HashMap<(usize, usize), u32>,
    /// The contour's pieces as edges.
    contour_set: std::collections::HashSet<(usize, usize)>,
    /// Points on the cut's front: the cap's boundary off the contour.
    on_front: Vec<bool>,
    /// Per contour point: its contour edges the cap opened, and those it left closed.
    opened_at: HashMap<usize, (u32, u32)>,
    /// Contour edges the cap opened.
    opened_edges: usize,
}

/// The edges of `cap` (over `n_points` plane points) against the contour's pieces.
fn cap_edges(cap: &[[usize; 3]], contour_pieces: &[[usize; 2]], n_points: usize) -> CapEdges {
    let mut cap_edges: HashMap<(usize, usize), u32> = HashMap::new();
    for t in cap {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *cap_edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let contour_set: std::collections::HashSet<(usize, usize)> = contour_pieces.iter().map(|&[p, q]| (p.min(q), p.max(q))).collect();
    let mut on_front = vec![false; n_points];
    for (&(p, q), &n) in &cap_edges {
        if n == 1 && !contour_set.contains(&(p, q)) {
            on_front[p] = true;
            on_front[q] = true;
        }
    }
    // per contour vertex: (opened, closed) contour edges
    let mut opened_at: HashMap<usize, (u32, u32)> = HashMap::new();
    let mut opened_edges = 0;
    for &[p, q] in contour_pieces {
        let open = cap_edges.contains_key(&(p.min(q), p.max(q)));
        opened_edges += usize::from(open);
        for r in [p, q] {
            let e = opened_at.entry(r).or_default();
            if open { e.0 += 1 } else { e.1 += 1 }
        }
    }
    CapEdges {
        cap_edges,
        contour_set,
        on_front,
        opened_at,
        opened_edges,
    }
}

/// Whether `p` lies inside the closed contour made of the segments `contour` (crossings of
/// a ray along +x, even–odd).
fn inside_contour(contour: &[([f64; 2], [f64; 2])], p: [f64; 2]) -> bool {
    let mut inside = false;
    for &(a, b) in contour {
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
            if x > p[0] {
                inside = !inside;
            }
        }
    }
    inside
}

/// Whether `p` lies in the cut region: the nearest of the cells' cross-sections `sections`
/// (each marked cut or not) is a cut one, a cut one winning a tie.
fn inside_cut(sections: &[(bool, Vec<[f64; 2]>)], p: [f64; 2]) -> bool {
    let mut best = (f64::INFINITY, false);
    for (cut, poly) in sections {
        let d = polygon_distance(poly, p);
        if d < best.0 || (d == best.0 && *cut) {
            best = (d, *cut);
        }
        if d == 0.0 && *cut {
            break;
        }
    }
    best.1
}

/// The surface vertices of the cap's points.
struct CapVertices {
    /// Each doubled contour vertex's twin on the negative side.
    twin: HashMap<usize, usize>,
    /// Each cap point's vertex on the positive and on the negative side.
    made: HashMap<usize, [usize; 2]>,
    /// Vertices doubled, and made on the front.
    doubled_vertices: usize,
    front_vertices: usize,
}

/// Each point of `cap`'s vertex on the positive and on the negative side: contour vertices
/// doubled where every contour edge at them opened and the front does not reach them; points
/// inside the cap doubled, points on the front made once (new vertices appended to
/// `vertices` with their `side`).
fn cap_vertices(
    cap: &[[usize; 3]],
    points: &[PlanePoint],
    opened_at: &HashMap<usize, (u32, u32)>,
    on_front: &[bool],
    vertices: &mut Vec<[f64; 3]>,
    side: &mut Vec<VertexSide>,
) -> CapVertices {
    let mut twin: HashMap<usize, usize> = HashMap::new();
    let mut made: HashMap<usize, [usize; 2]> = HashMap::new();
    let (mut doubled_vertices, mut front_vertices) = (0, 0);
    let mut cap_points: Vec<usize> = cap.iter().flatten().copied().collect();
    cap_points.sort_unstable();
    cap_points.dedup();
    let mut push = |x: [f64; 3], s: VertexSide, vertices: &mut Vec<[f64; 3]>| {
        vertices.push(x);
        side.push(s);
        vertices.len() - 1
    };
    for &p in &cap_points {
        match (points[p].vertex, opened_at.get(&p)) {
            (Some(v), Some(&(open, closed))) => {
                if open > 0 && closed == 0 && !on_front[p] {
                    let w = push(vertices[v], VertexSide::Negative, vertices);
                    twin.insert(v, w);
                    made.insert(p, [v, w]);
                    doubled_vertices += 1;
                } else {
                    made.insert(p, [v, v]);
                }
            }
            (Some(v), None) => {
                made.insert(p, [v, v]);
            }
            (None, _) if on_front[p] => {
                let v = push(points[p].x, VertexSide::Mean, vertices);
                made.insert(p, [v, v]);
                front_vertices += 1;
            }
            (None, _) => {
                let a = push(points[p].x, VertexSide::Positive, vertices);
                let b = push(points[p].x, VertexSide::Negative, vertices);
                made.insert(p, [a, b]);
            }
        }
    }
    CapVertices {
        twin,
        made,
        doubled_vertices,
        front_vertices,
    }
}

/// Splits the surface's `tagged` triangles (with their side) where an edge parts — an opened
/// contour edge, an edge inside the cap — but both its ends stay shared (where the front
/// crosses the contour, or runs across the cap): at the edge's midpoint, one new vertex per
/// side (appended to `vertices` and `side`, counted in `doubled_vertices`).
fn part_at_midpoints(
    tagged: Vec<([usize; 3], i8)>,
    cap_edges: &HashMap<(usize, usize), u32>,
    contour_set: &std::collections::HashSet<(usize, usize)>,
    made: &HashMap<usize, [usize; 2]>,
    vertices: &mut Vec<[f64; 3]>,
    side: &mut Vec<VertexSide>,
    doubled_vertices: &mut usize,
) -> Vec<[usize; 3]> {
    // an edge that parts (an opened contour edge, an edge inside the cap) but whose two ends
    // stay shared (where the front crosses the contour, or runs across the cap) parts at its
    // midpoint, one per side
    let mut midpoints: HashMap<(usize, usize), [usize; 2]> = HashMap::new();
    let mut parting: Vec<(usize, usize)> = cap_edges
        .iter()
        .filter(|e| *e.1 == 2 || contour_set.contains(e.0))
        .map(|e| *e.0)
        .collect();
    parting.sort_unstable();
    for (p, q) in parting {
        let (a, b) = (made[&p], made[&q]);
        if a[0] == a[1] && b[0] == b[1] {
            let x = lerp(vertices[a[0]], vertices[b[0]], 0.5);
            let m = [vertices.len(), vertices.len() + 1];
            vertices.extend([x, x]);
            side.extend([VertexSide::Positive, VertexSide::Negative]);
            midpoints.insert((a[0].min(b[0]), a[0].max(b[0])), m);
            *doubled_vertices += 1;
        }
    }
    let mut out: Vec<[usize; 3]> = Vec::with_capacity(tagged.len() + 4 * midpoints.len());
    for (t, side) in tagged {
        // each parting edge of the triangle split in turn
        let mut stack = vec![t];
        while let Some(t) = stack.pop() {
            let split_at = (0..3).find_map(|k| {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                midpoints.get(&(a.min(b), a.max(b))).map(|m| (k, m[usize::from(side < 0)]))
            });
            match split_at {
                Some((k, m)) => {
                    let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                    stack.push([a, m, c]);
                    stack.push([m, b, c]);
                }
                None => out.push(t),
            }
        }
    }
    out
}

/// The surface `visual` split along the part of `plane` inside `cut_cells` of `mesh`, and
/// closed by the cut faces (module docs).
pub fn split(visual: &VisualMesh, mesh: &Mesh, plane: &Plane, cut_cells: &[usize]) -> Result<SplitSurface, SplitError> {
    let (plane, size) = checked_plane(visual, mesh, plane, cut_cells)?;
    let frame = Frame::new(&plane);
    let hair = 1e-9 * size;
    let snapped = |x: [f64; 3]| {
        let f = plane.phi(x);
        if f.abs() <= hair { 0.0 } else { f }
    };

    // 1. the surface split along the plane
    let Halves {
        mut vertices,
        mut phi,
        mut triangles,
    } = halves(visual, &plane, snapped);
    let contour = contour_edges(&triangles, &phi);

    // 2. the plane: the contour's points, the cut region's boundary, their crossings
    let mut points: Vec<PlanePoint> = Vec::new();
    let mut point_of_vertex: HashMap<usize, usize> = HashMap::new();
    let mut add_vertex_point = |v: usize, points: &mut Vec<PlanePoint>| {
        *point_of_vertex.entry(v).or_insert_with(|| {
            points.push(PlanePoint {
                xy: frame.to_2d(vertices[v]),
                x: vertices[v],
                vertex: Some(v),
            });
            points.len() - 1
        })
    };
    let mut contour_segments: Vec<Segment> = contour
        .iter()
        .map(|&(a, b)| Segment::new(add_vertex_point(a, &mut points), add_vertex_point(b, &mut points)))
        .collect();

    let node_phi: Vec<f64> = mesh.nodes.iter().map(|&x| snapped(x)).collect();
    let mut is_cut = vec![false; mesh.n_cells()];
    for &c in cut_cells {
        is_cut[c] = true;
    }
    let Region {
        sections,
        segments: mut region_segments,
    } = cut_region(mesh, &node_phi, &is_cut, &frame, &mut points);

    // crossings and touchings of the contour with the region's boundary, on both
    let touch = 1e-9 * size;
    mark_crossings(&mut points, &mut contour_segments, &mut region_segments, &frame, touch);
    // region points that fell on a contour vertex are that vertex
    let alias = aliases(&points, point_of_vertex.values().copied(), touch);

    // contour edges split at the crossings: in the surface too
    let (contour_pieces, edge_splits) = split_contour(&mut points, &contour_segments, &alias, &mut vertices, &mut phi);
    if !edge_splits.is_empty() {
        triangles = split_edges(&triangles, &edge_splits);
    }

    // the constrained triangulation of the plane
    let mut region_pieces: Vec<[usize; 2]> = Vec::new();
    for seg in &region_segments {
        region_pieces.extend(seg.pieces().into_iter().map(|[p, q]| [alias[p], alias[q]]).filter(|[p, q]| p != q));
    }
    let pieces: Vec<[usize; 2]> = contour_pieces.iter().chain(&region_pieces).copied().collect();

    // 3. the cap: triangles inside the surface and inside the cut
    let contour_xy: Vec<([f64; 2], [f64; 2])> = contour
        .iter()
        .map(|&(a, b)| (frame.to_2d(vertices[a]), frame.to_2d(vertices[b])))
        .collect();
    let (cap, cap_area) = triangulate(&points, &pieces, |p| inside_contour(&contour_xy, p) && inside_cut(&sections, p))?;

    // the cap's edges: on its boundary (once), the contour's opened ones and the front
    let CapEdges {
        cap_edges,
        contour_set,
        on_front,
        opened_at,
        opened_edges,
    } = cap_edges(&cap, &contour_pieces, points.len());
    // each cap point's vertex on the positive and on the negative side
    let n_before = vertices.len();
    let mut side = vec![VertexSide::Own; vertices.len()];
    let CapVertices {
        twin,
        made,
        mut doubled_vertices,
        front_vertices,
    } = cap_vertices(&cap, &points, &opened_at, &on_front, &mut vertices, &mut side);
    let mut tagged: Vec<([usize; 3], i8)> = triangles
        .iter()
        .map(|&(t, side)| {
            (
                if side < 0 {
                    t.map(|v| twin.get(&v).copied().unwrap_or(v))
                } else {
                    t
                },
                side,
            )
        })
        .collect();
    for t in &cap {
        let [a, b, c] = t.map(|p| made[&p]);
        tagged.push(([a[0], c[0], b[0]], 1));
        tagged.push(([a[1], b[1], c[1]], -1));
    }
    let out = part_at_midpoints(
        tagged,
        &cap_edges,
        &contour_set,
        &made,
        &mut vertices,
        &mut side,
        &mut doubled_vertices,
    );
    for (v, s) in side.iter_mut().enumerate().take(n_before) {
        if phi[v] == 0.0 {
            *s = VertexSide::Mean;
        }
    }
    for &v in twin.keys() {
        side[v] = VertexSide::Positive;
    }
    let plane_vertices = phi[..n_before].iter().filter(|&&f| f == 0.0).count();
    Ok(SplitSurface {
        surface: VisualMesh { vertices, triangles: out },
        side,
        report: SplitReport {
            plane_vertices,
            opened_edges,
            doubled_vertices,
            front_vertices,
            cap_triangles: cap.len(),
            cap_area,
        },
    })
}

/// The plane of a semi-progressive cut: the least-squares plane through the crossings of its
/// cut cells, refused when a crossing lies farther from it than 1 % of the mean cut cell's
/// size (the cut is not one plane).
pub fn cut_plane(mesh: &Mesh, cut: &ProgressiveCut) -> Result<Option<Plane>, SplitError> {
    let mut points = Vec::new();
    for &c in cut.cut_cells() {
        let Some(x) = cut.crossings(c) else { continue };
        let cell = mesh.cell(c);
        points.extend(x.edges.values().copied());
        points.extend((0..4).filter(|&v| x.on_blade[v]).map(|v| mesh.nodes[cell[v]]));
    }
    fit_cut_plane(mesh, cut.cut_cells(), &points, 0.01)
}

/// The one plane of the cells cut by an XFEM cut, each with the plane that crossed it (an
/// [`super::enrichment::Enrichment`]'s `cut_cells`): fitted, as [`cut_plane`], to where each
/// cell's plane crosses its edges; `None` before any cell is cut, [`SplitError::NotPlanar`]
/// when a crossing lies farther from it than `tolerance` times the mean cut cell's size. A
/// session's cut follows the blade in the tissue's reference frame — the blade's positions
/// taken back by the tissue's displacement —, so a straight incision is one plane only to
/// within the displacement's variation over the cut (the co-rotational session accepts
/// [`SESSION_PLANARITY`]).
pub fn cut_plane_of_cells(mesh: &Mesh, cut_cells: &[(usize, Plane)], tolerance: f64) -> Result<Option<Plane>, SplitError> {
    let mut points = Vec::new();
    for &(c, plane) in cut_cells {
        let cell = mesh.cell(c);
        for (i, &a) in cell.iter().enumerate() {
            for &b in &cell[i + 1..] {
                let (pa, pb) = (mesh.nodes[a], mesh.nodes[b]);
                let (fa, fb) = (plane.phi(pa), plane.phi(pb));
                if fa == 0.0 {
                    points.push(pa);
                } else if (fa < 0.0) != (fb < 0.0) && fb != 0.0 {
                    points.push(lerp(pa, pb, fa / (fa - fb)));
                }
            }
        }
    }
    let cells: Vec<usize> = cut_cells.iter().map(|c| c.0).collect();
    fit_cut_plane(mesh, &cells, &points, tolerance)
}

/// How far from one plane a session's cut may stray to be split as one, in mean cut cell
/// sizes ([`cut_plane_of_cells`]).
pub const SESSION_PLANARITY: f64 = 0.25;

/// Normals within this angle (rad, 15°) count as one family of planes in
/// [`largest_planar_part`].
const SAME_PLANE_ANGLE: f64 = 0.2618;

/// The largest part of a cut made of several planes (two strokes meeting) that is one plane:
/// the cells whose own planes turn less than 15° from one another, grouped around each cell's
/// plane in turn, the largest group that [`cut_plane_of_cells`] accepts with `tolerance`, with
/// its plane. `None` when no group of at least three cells is planar. What a session splits the
/// visual surface along when the whole cut is not one plane.
pub fn largest_planar_part(mesh: &Mesh, cut_cells: &[(usize, Plane)], tolerance: f64) -> Option<(Plane, Vec<(usize, Plane)>)> {
    let unit = |p: &Plane| {
        let n = p.normal;
        let l = dot(n, n).sqrt();
        n.map(|v| v / l)
    };
    let normals: Vec<[f64; 3]> = cut_cells.iter().map(|(_, p)| unit(p)).collect();
    let same = SAME_PLANE_ANGLE.cos();
    let mut tried: Vec<Vec<usize>> = Vec::new();
    let mut best: Option<(Plane, Vec<(usize, Plane)>)> = None;
    for n in &normals {
        let members: Vec<usize> = (0..cut_cells.len()).filter(|&j| dot(*n, normals[j]).abs() >= same).collect();
        if members.len() < 3 || tried.contains(&members) || best.as_ref().is_some_and(|b| b.1.len() >= members.len()) {
            continue;
        }
        let group: Vec<(usize, Plane)> = members.iter().map(|&j| cut_cells[j]).collect();
        tried.push(members);
        if let Ok(Some(plane)) = cut_plane_of_cells(mesh, &group, tolerance) {
            best = Some((plane, group));
        }
    }
    best
}

/// The least-squares plane of `points` on the cells `cells`, refused when a point lies
/// farther from it than `tolerance` times the cells' mean size.
fn fit_cut_plane(mesh: &Mesh, cells: &[usize], points: &[[f64; 3]], tolerance: f64) -> Result<Option<Plane>, SplitError> {
    if cells.is_empty() || points.len() < 3 {
        return Ok(None);
    }
    let mut size = 0.0;
    let mut xs = [[0.0; 3]; 4];
    for &c in cells {
        mesh.cell_coords(c, &mut xs);
        size += super::subcell::cell_size(&xs);
    }
    let plane = super::progressive::fit_plane(points);
    let residual = points.iter().map(|&p| plane.phi(p).abs()).fold(0.0, f64::max);
    let tolerance = tolerance * size / cells.len() as f64;
    if residual > tolerance {
        return Err(SplitError::NotPlanar { residual, tolerance });
    }
    Ok(Some(plane))
}
