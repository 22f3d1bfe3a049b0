//! The cut surface inside cells the blade has entered but not yet crossed (seed 003 §3.3:
//! "the cut is shown progressively"): shown, never simulated.
//!
//! A cell is cut — enriched, simulated — only once the blade has crossed it entirely
//! ([`super::online`], [`super::progressive`]). Until then the surface the blade swept inside
//! it is drawn so that the incision follows the blade continuously rather than cell by cell:
//! the swept triangles clipped to each tetrahedron the blade reached that is not cut yet
//! (Sutherland–Hodgman against the tetrahedron's four faces, exact for planar facets).
//!
//! [`PartialSurface::update`] is incremental: a swept triangle all of whose cells are cut is
//! retired and never clipped again, so the work follows the blade's front, not the length of
//! the cut.

use crate::geometry::vec3::{cross, dot, lerp, norm, sub};
use crate::mesh::{CellKind, Mesh};

/// The part of `polygon` (planar, convex or not, its vertices in order) on the side of the
/// plane `dot(n, x) <= offset` (Sutherland–Hodgman against one plane).
fn clip_half_space(polygon: &[[f64; 3]], n: [f64; 3], offset: f64) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(polygon.len() + 1);
    for (i, &p) in polygon.iter().enumerate() {
        let q = polygon[(i + 1) % polygon.len()];
        let (dp, dq) = (dot(n, p) - offset, dot(n, q) - offset);
        if dp <= 0.0 {
            out.push(p);
        }
        if (dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0) {
            out.push(lerp(p, q, dp / (dp - dq)));
        }
    }
    out
}

/// The part of triangle `t` inside tetrahedron `tet` (its four vertices), as a polygon in
/// order (empty when they do not overlap with a positive area).
pub fn clip_triangle_to_tet(t: &[[f64; 3]; 3], tet: &[[f64; 3]; 4]) -> Vec<[f64; 3]> {
    let mut poly = t.to_vec();
    for (i, j, k, l) in [(1, 2, 3, 0), (0, 2, 3, 1), (0, 1, 3, 2), (0, 1, 2, 3)] {
        let mut n = cross(sub(tet[j], tet[i]), sub(tet[k], tet[i]));
        // outward: away from the opposite vertex
        if dot(n, sub(tet[l], tet[i])) > 0.0 {
            n = n.map(|v| -v);
        }
        poly = clip_half_space(&poly, n, dot(n, tet[i]));
        if poly.len() < 3 {
            return Vec::new();
        }
    }
    poly
}

fn area(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    0.5 * norm(cross(sub(b, a), sub(c, a)))
}

/// The swept surface inside the cells a blade reached and has not cut (module docs).
#[derive(Debug, Clone)]
pub struct PartialSurface {
    /// Bounding boxes of the cells.
    boxes: Vec<([f64; 3], [f64; 3])>,
    /// Swept triangles seen so far.
    seen: usize,
    /// Those still in a cell that is not cut (or not known to be), with the cells they reach.
    live: Vec<(usize, Vec<usize>)>,
}

impl PartialSurface {
    /// For `mesh` (tetrahedra; `None` for other cells, which are not cut progressively).
    pub fn new(mesh: &Mesh) -> Option<Self> {
        if mesh.kind != CellKind::Tet4 {
            return None;
        }
        Some(Self {
            boxes: super::progressive::cell_boxes(mesh),
            seen: 0,
            live: Vec::new(),
        })
    }

    fn tet(mesh: &Mesh, c: usize) -> [[f64; 3]; 4] {
        let cell = mesh.cell(c);
        std::array::from_fn(|i| mesh.nodes[cell[i]])
    }

    /// The swept triangles `swept` (all of them so far, in the order they were swept: the
    /// ones beyond the last call are new) clipped to the cells that are not cut
    /// (`is_cut(c)` false): the triangles of the partial cut surface, in the reference frame.
    pub fn update(&mut self, mesh: &Mesh, swept: &[[[f64; 3]; 3]], is_cut: impl Fn(usize) -> bool) -> Vec<[[f64; 3]; 3]> {
        // the cells each new triangle reaches
        for (i, t) in swept.iter().enumerate().skip(self.seen) {
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for p in t {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            let scale = area(t[0], t[1], t[2]);
            if scale.is_nan() || scale <= 0.0 {
                continue;
            }
            let cells: Vec<usize> = (0..self.boxes.len())
                .filter(|&c| {
                    let (blo, bhi) = self.boxes[c];
                    (0..3).all(|k| bhi[k] >= lo[k] && blo[k] <= hi[k])
                })
                .filter(|&c| {
                    let poly = clip_triangle_to_tet(t, &Self::tet(mesh, c));
                    poly.len() >= 3 && (1..poly.len() - 1).map(|j| area(poly[0], poly[j], poly[j + 1])).sum::<f64>() > 1e-12 * scale
                })
                .collect();
            if !cells.is_empty() {
                self.live.push((i, cells));
            }
        }
        self.seen = self.seen.max(swept.len());
        // retire the triangles whose every cell is cut; clip the others to their uncut cells
        self.live.retain(|(_, cells)| cells.iter().any(|&c| !is_cut(c)));
        let mut out = Vec::new();
        for (i, cells) in &self.live {
            let Some(t) = swept.get(*i) else { continue };
            for &c in cells.iter().filter(|&&c| !is_cut(c)) {
                let poly = clip_triangle_to_tet(t, &Self::tet(mesh, c));
                for j in 1..poly.len().saturating_sub(1) {
                    if area(poly[0], poly[j], poly[j + 1]) > 0.0 {
                        out.push([poly[0], poly[j], poly[j + 1]]);
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TET: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

    fn polygon_area(p: &[[f64; 3]]) -> f64 {
        (1..p.len().saturating_sub(1)).map(|j| area(p[0], p[j], p[j + 1])).sum()
    }

    #[test]
    fn a_triangle_inside_stays_whole_one_outside_vanishes() {
        let inside = [[0.1, 0.1, 0.1], [0.3, 0.1, 0.1], [0.1, 0.3, 0.1]];
        let p = clip_triangle_to_tet(&inside, &TET);
        assert!((polygon_area(&p) - area(inside[0], inside[1], inside[2])).abs() < 1e-15);
        let outside = [[2.0, 0.0, 0.0], [3.0, 0.0, 0.0], [2.0, 1.0, 0.0]];
        assert!(clip_triangle_to_tet(&outside, &TET).is_empty());
    }

    #[test]
    fn a_plane_through_the_tetrahedron_leaves_its_cross_section() {
        // the big triangle in z = 0.5 covers the whole cross-section of the tetrahedron there:
        // the triangle (0,0), (0.5,0), (0,0.5), area 1/8
        let big = [[-5.0, -5.0, 0.5], [10.0, -5.0, 0.5], [-5.0, 10.0, 0.5]];
        let p = clip_triangle_to_tet(&big, &TET);
        assert!((polygon_area(&p) - 0.125).abs() < 1e-14, "{p:?}");
        assert!(p.iter().all(|x| (x[2] - 0.5).abs() < 1e-15));
        // a strip of it, x < 0.2: a trapezoid of area 0.2·(0.5 + 0.3)/2
        let strip = [[-5.0, -5.0, 0.5], [0.2, -5.0, 0.5], [0.2, 10.0, 0.5]];
        let strip2 = [[-5.0, -5.0, 0.5], [0.2, 10.0, 0.5], [-5.0, 10.0, 0.5]];
        let a = polygon_area(&clip_triangle_to_tet(&strip, &TET)) + polygon_area(&clip_triangle_to_tet(&strip2, &TET));
        assert!((a - 0.08).abs() < 1e-14, "{a}");
    }
}
