//! Semi-progressive cutting (seed 003 §3.3): the blade sweeps a quadrilateral each step (its
//! edge's previous and current positions); the points where that surface crosses the edges of
//! the tetrahedra are kept per cell — the seed's lists L1, L2, L3 of cells crossed on one, two,
//! three (or more) edges — and a cell is cut only once the blade has crossed it entirely: when
//! its crossed edges separate its vertices into two groups. Until then the cut surface inside
//! a partly crossed cell is shown only ([`ProgressiveCut::partial`]: the polygon of its
//! crossings), never simulated, which spares the "many unnecessary faces of very small sizes"
//! a fully progressive cut makes.
//!
//! Crossings are kept for the rest of the cut: a blade that stops, backs out along its path
//! and comes back sweeps no new edge, and resuming adds to what was crossed before. A crossing
//! exactly at a vertex marks the vertex as *on the blade*: an edge touching such a vertex
//! counts as crossed for the separation, as long as each group keeps a vertex off the blade (a
//! blade grazing a vertex cuts nothing).

use std::collections::BTreeMap;

use crate::geometry::vec3::{cross, dot, sub};
use crate::mesh::{CellKind, Mesh};

/// The six edges of a tetrahedron (local vertex pairs).
pub const TET_EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];

/// Relative tolerance of a crossing at an edge's end (a vertex on the blade).
const AT_VERTEX: f64 = 1e-9;

/// What the blade has crossed in one cell.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Crossings {
    /// Crossing point of each crossed edge (local edge index, point).
    pub edges: BTreeMap<u8, [f64; 3]>,
    /// Local vertices the blade passed through.
    pub on_blade: [bool; 4],
}

impl Crossings {
    /// Edges crossed, the seed's list index (1, 2, 3 or more).
    pub fn count(&self) -> usize {
        self.edges.len()
    }

    /// Whether the crossings separate the vertices into two groups, each with a vertex off the
    /// blade, every edge between them crossed or touching a vertex on the blade, one at least
    /// crossed (module docs): the group without vertex 3 as a bit mask of local vertices.
    pub fn separation(&self) -> Option<u8> {
        // the 7 partitions of 4 vertices into two non-empty groups
        for group in 1u8..8 {
            let inside = |v: usize| group & (1 << v) != 0;
            let off_in = (0..4).any(|v| inside(v) && !self.on_blade[v]);
            let off_out = (0..4).any(|v| !inside(v) && !self.on_blade[v]);
            if !(off_in && off_out) {
                continue;
            }
            let mut genuine = false;
            let separated = TET_EDGES.iter().enumerate().all(|(k, &[a, b])| {
                if inside(a) == inside(b) {
                    return true;
                }
                let crossed = self.edges.contains_key(&(k as u8));
                genuine |= crossed;
                crossed || self.on_blade[a] || self.on_blade[b]
            });
            if separated && genuine {
                return Some(group);
            }
        }
        None
    }
}

/// The state of a semi-progressive cut.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgressiveCut {
    /// Crossings of every cell the blade has touched.
    cells: BTreeMap<usize, Crossings>,
    /// Cells cut, in the order they were.
    cut: Vec<usize>,
    is_cut: Vec<bool>,
    /// Bounding boxes of the cells (min, max).
    boxes: Vec<([f64; 3], [f64; 3])>,
}

/// A semi-progressive cut needs tetrahedra.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("semi-progressive cutting works on tetrahedra; this mesh has {0:?} cells")]
pub struct NotTetrahedra(pub CellKind);

/// Where the segment `p → q` meets the triangle `t`: the parameter along the segment, or
/// `None` (Möller–Trumbore; a segment in the triangle's plane meets nothing).
fn segment_triangle(p: [f64; 3], q: [f64; 3], t: [[f64; 3]; 3]) -> Option<f64> {
    let d = sub(q, p);
    let (e1, e2) = (sub(t[1], t[0]), sub(t[2], t[0]));
    let h = cross(d, e2);
    let det = dot(e1, h);
    let scale = dot(e1, e1).max(dot(e2, e2)) * dot(d, d).sqrt();
    if det.abs() <= 1e-14 * scale {
        return None;
    }
    let s = sub(p, t[0]);
    let u = dot(s, h) / det;
    let qv = cross(s, e1);
    let v = dot(d, qv) / det;
    let tol = 1e-12;
    if u < -tol || v < -tol || u + v > 1.0 + tol {
        return None;
    }
    let w = dot(e2, qv) / det;
    (-AT_VERTEX..=1.0 + AT_VERTEX).contains(&w).then_some(w.clamp(0.0, 1.0))
}

impl ProgressiveCut {
    /// A cut of `mesh` (tetrahedra) that has crossed nothing yet.
    pub fn new(mesh: &Mesh) -> Result<Self, NotTetrahedra> {
        if mesh.kind != CellKind::Tet4 {
            return Err(NotTetrahedra(mesh.kind));
        }
        let boxes = cell_boxes(mesh);
        Ok(Self {
            cells: BTreeMap::new(),
            cut: Vec::new(),
            is_cut: vec![false; mesh.n_cells()],
            boxes,
        })
    }

    /// The blade's edge moved from `(tip0, base0)` to `(tip1, base1)`: the swept quadrilateral
    /// (two triangles) is crossed with the edges of the cells it reaches. Returns the cells
    /// this step cut (now crossed entirely), in cell order. A step that does not move sweeps
    /// nothing.
    pub fn sweep(&mut self, mesh: &Mesh, tip0: [f64; 3], base0: [f64; 3], tip1: [f64; 3], base1: [f64; 3]) -> Vec<usize> {
        let triangles = [[tip0, base0, base1], [tip0, base1, tip1]];
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in [tip0, base0, tip1, base1] {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let mut newly = Vec::new();
        for c in 0..mesh.n_cells() {
            let (blo, bhi) = self.boxes[c];
            if (0..3).any(|k| bhi[k] < lo[k] || blo[k] > hi[k]) {
                continue;
            }
            let cell = mesh.cell(c);
            let mut hits: Vec<(u8, f64, [f64; 3])> = Vec::new();
            for (k, &[a, b]) in TET_EDGES.iter().enumerate() {
                let (p, q) = (mesh.nodes[cell[a]], mesh.nodes[cell[b]]);
                for t in triangles {
                    if let Some(w) = segment_triangle(p, q, t) {
                        let x = std::array::from_fn(|i| p[i] + w * (q[i] - p[i]));
                        hits.push((k as u8, w, x));
                        break;
                    }
                }
            }
            if hits.is_empty() {
                continue;
            }
            let entry = self.cells.entry(c).or_default();
            for (k, w, x) in hits {
                let [a, b] = TET_EDGES[k as usize];
                if w <= AT_VERTEX {
                    entry.on_blade[a] = true;
                } else if w >= 1.0 - AT_VERTEX {
                    entry.on_blade[b] = true;
                } else {
                    entry.edges.entry(k).or_insert(x);
                }
            }
            if !self.is_cut[c] && entry.separation().is_some() {
                self.is_cut[c] = true;
                self.cut.push(c);
                newly.push(c);
            }
        }
        newly
    }

    /// Cells cut so far, in the order they were.
    pub fn cut_cells(&self) -> &[usize] {
        &self.cut
    }

    /// Whether cell `c` is cut.
    pub fn is_cut(&self, c: usize) -> bool {
        self.is_cut.get(c).copied().unwrap_or(false)
    }

    /// The seed's lists: cells crossed (not yet cut) on one, two, and three or more edges.
    pub fn lists(&self) -> [Vec<usize>; 3] {
        let mut l: [Vec<usize>; 3] = Default::default();
        for (&c, x) in &self.cells {
            if !self.is_cut[c] && x.count() > 0 {
                l[x.count().min(3) - 1].push(c);
            }
        }
        l
    }

    /// The crossings of every cell the blade reached and has not cut yet: the polygon of the
    /// cut surface inside it, shown (not simulated) until the cell is cut.
    pub fn partial(&self) -> impl Iterator<Item = (usize, &Crossings)> {
        self.cells.iter().filter(|(c, _)| !self.is_cut[**c]).map(|(c, x)| (*c, x))
    }

    /// The plane of every cut cell, for the enrichment
    /// ([`super::Enrichment::from_cut_cells`]): the least-squares plane through its crossing
    /// points and the vertices the blade passed through (the normal, the direction of least
    /// spread, turned to make its largest component positive).
    pub fn cut_planes(&self, mesh: &Mesh) -> Vec<(usize, super::Plane)> {
        self.cut
            .iter()
            .map(|&c| {
                let x = &self.cells[&c];
                let cell = mesh.cell(c);
                let points: Vec<[f64; 3]> = x
                    .edges
                    .values()
                    .copied()
                    .chain((0..4).filter(|&v| x.on_blade[v]).map(|v| mesh.nodes[cell[v]]))
                    .collect();
                (c, fit_plane(&points))
            })
            .collect()
    }

    /// The crossings of cell `c`, if the blade reached it.
    pub fn crossings(&self, c: usize) -> Option<&Crossings> {
        self.cells.get(&c)
    }
}

/// The bounding box (min, max) of every cell of `mesh`.
pub(crate) fn cell_boxes(mesh: &Mesh) -> Vec<([f64; 3], [f64; 3])> {
    (0..mesh.n_cells())
        .map(|c| {
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for &a in mesh.cell(c) {
                for k in 0..3 {
                    lo[k] = lo[k].min(mesh.nodes[a][k]);
                    hi[k] = hi[k].max(mesh.nodes[a][k]);
                }
            }
            (lo, hi)
        })
        .collect()
}

/// The least-squares plane through `points` (at least three): through their centre, the normal
/// the direction of least spread, turned to make its largest component positive.
pub fn fit_plane(points: &[[f64; 3]]) -> super::Plane {
    let n = points.len().max(1) as f64;
    let centre: [f64; 3] = std::array::from_fn(|k| points.iter().map(|p| p[k]).sum::<f64>() / n);
    let mut m = nalgebra::Matrix3::zeros();
    for p in points {
        let d = nalgebra::Vector3::new(p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]);
        m += d * d.transpose();
    }
    let eig = m.symmetric_eigen();
    let k = (0..3)
        .min_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]))
        .unwrap_or(0);
    let v = eig.eigenvectors.column(k);
    let big = (0..3).max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs())).unwrap_or(0);
    let sign = if v[big] < 0.0 { -1.0 } else { 1.0 };
    super::Plane {
        point: centre,
        normal: [sign * v[0], sign * v[1], sign * v[2]],
    }
}
