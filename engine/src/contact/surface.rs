//! An organ's closed reference surface, prepared for contact: triangle geometry, smooth
//! normals, triangle neighbourhoods and a grid that also knows inside from outside.

use super::grid::{CellClass, Grid};
use crate::geometry::vec3::{cross, dot, sub};

/// A point on a surface triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// The triangle (index into [`Surface::triangles`]).
    pub triangle: usize,
    /// Barycentric weights of the point in it.
    pub weights: [f64; 3],
    /// The point (m).
    pub point: [f64; 3],
}

/// The surface (see the module docs of [`crate::contact`]).
#[derive(Debug, Clone)]
pub struct Surface {
    tris: Vec<[usize; 3]>,
    /// Per triangle: vertex a, edges ab, ac, unit normal.
    geom: Vec<[[f64; 3]; 4]>,
    /// Angle-weighted pseudo-normal of every node (zero for nodes off the surface).
    vertex_normals: Vec<[f64; 3]>,
    /// Per triangle, the triangle across the edge opposite each vertex ([`NO_NEIGHBOUR`] on
    /// an open edge).
    across: Vec<[u32; 3]>,
    grid: Grid,
}

/// Marks an open edge in `Surface::across`.
const NO_NEIGHBOUR: u32 = u32::MAX;

/// How far outside a triangle (in barycentric weight) a projection may land and still be
/// taken there: round-off on a shared edge, not a reason to walk.
const PROJECTION_SLACK: f64 = 1e-9;

/// Newton iterations of one projection: started from the last tick's solution it converges
/// quadratically, in 1–3 iterations.
const PROJECTION_ITERATIONS: usize = 12;

/// Weights clamped to the triangle (non-negative, summing to one).
fn clamp_weights(w: [f64; 3]) -> [f64; 3] {
    let w = w.map(|x| x.max(0.0));
    let sum = w[0] + w[1] + w[2];
    if sum > 0.0 { w.map(|x| x / sum) } else { [1.0 / 3.0; 3] }
}

fn unit(a: [f64; 3]) -> Option<[f64; 3]> {
    let l = dot(a, a).sqrt();
    (l > 0.0 && l.is_finite()).then(|| a.map(|x| x / l))
}

impl Surface {
    /// Bytes of its buffers (triangles, geometry, normals, adjacency, grid).
    pub fn heap_bytes(&self) -> usize {
        use crate::memory::vec_bytes;
        vec_bytes(&self.tris) + vec_bytes(&self.geom) + vec_bytes(&self.vertex_normals) + vec_bytes(&self.across) + self.grid.heap_bytes()
    }

    /// Prepares the triangles `tris` (outward-oriented, indices into `nodes`) of a closed
    /// surface.
    pub fn new(nodes: &[[f64; 3]], tris: Vec<[usize; 3]>) -> Self {
        let geom: Vec<[[f64; 3]; 4]> = tris
            .iter()
            .map(|t| {
                let (a, b, c) = (nodes[t[0]], nodes[t[1]], nodes[t[2]]);
                let (ab, ac) = (sub(b, a), sub(c, a));
                let n = unit(cross(ab, ac)).unwrap_or([0.0; 3]);
                [a, ab, ac, n]
            })
            .collect();
        // angle-weighted pseudo-normals (Bærentzen and Aanæs 2005): the sign of (p − q)·n at
        // the nearest surface point q tells inside from outside, also at edges and vertices
        let mut vn = vec![[0.0; 3]; nodes.len()];
        for (t, g) in tris.iter().zip(&geom) {
            for a in 0..3 {
                let p = nodes[t[a]];
                let (u, v) = (sub(nodes[t[(a + 1) % 3]], p), sub(nodes[t[(a + 2) % 3]], p));
                let (lu, lv) = (dot(u, u).sqrt(), dot(v, v).sqrt());
                if lu > 0.0 && lv > 0.0 {
                    let angle = (dot(u, v) / (lu * lv)).clamp(-1.0, 1.0).acos();
                    for k in 0..3 {
                        vn[t[a]][k] += angle * g[3][k];
                    }
                }
            }
        }
        for n in &mut vn {
            *n = unit(*n).unwrap_or([0.0; 3]);
        }
        // triangles around each node, then the neighbour across each edge
        let mut around: Vec<Vec<u32>> = vec![Vec::new(); nodes.len()];
        for (i, t) in tris.iter().enumerate() {
            for &n in t {
                around[n].push(i as u32);
            }
        }
        let mut across = vec![[NO_NEIGHBOUR; 3]; tris.len()];
        for (i, t) in tris.iter().enumerate() {
            for a in 0..3 {
                let (e0, e1) = (t[(a + 1) % 3], t[(a + 2) % 3]);
                if let Some(&j) = around[e0].iter().find(|&&j| j as usize != i && tris[j as usize].contains(&e1)) {
                    across[i][a] = j;
                }
            }
        }
        let boxes: Vec<([f64; 3], [f64; 3])> = tris
            .iter()
            .map(|t| {
                let lo = [0, 1, 2].map(|k| t.iter().map(|&n| nodes[n][k]).fold(f64::INFINITY, f64::min));
                let hi = [0, 1, 2].map(|k| t.iter().map(|&n| nodes[n][k]).fold(f64::NEG_INFINITY, f64::max));
                (lo, hi)
            })
            .collect();
        let grid = Grid::new(&boxes);
        Self {
            tris,
            geom,
            vertex_normals: vn,
            across,
            grid,
        }
    }

    /// The triangles (node indices).
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.tris
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// Whether the surface has no triangle.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// The closest point of triangle `t` to `p`.
    pub fn closest_on(&self, t: usize, p: [f64; 3]) -> SurfacePoint {
        let g = &self.geom[t];
        let (weights, point) = closest_on_triangle(p, g[0], g[1], g[2]);
        SurfacePoint {
            triangle: t,
            weights,
            point,
        }
    }

    fn dist2(&self, t: usize, p: [f64; 3]) -> f64 {
        let q = self.closest_on(t, p).point;
        dot(sub(p, q), sub(p, q))
    }

    /// The smooth outward normal at a surface point: the pseudo-normals of the triangle's
    /// vertices interpolated with the point's weights (continuous across edges and vertices).
    pub fn normal_at(&self, s: &SurfacePoint) -> [f64; 3] {
        let t = self.tris[s.triangle];
        let mut n = [0.0; 3];
        for a in 0..3 {
            for k in 0..3 {
                n[k] += s.weights[a] * self.vertex_normals[t[a]][k];
            }
        }
        unit(n).unwrap_or(self.geom[s.triangle][3])
    }

    /// Signed distance of `p` from the surface point `s` along the smooth normal (positive
    /// outside).
    pub fn signed_distance(&self, s: &SurfacePoint, p: [f64; 3]) -> f64 {
        dot(sub(p, s.point), self.normal_at(s))
    }

    /// The surface point nearest to `p` among the triangles within `reach` (a box search in
    /// the grid), if any.
    pub fn nearest_within(&self, p: [f64; 3], reach: f64) -> Option<SurfacePoint> {
        let mut best: Option<(f64, usize)> = None;
        self.grid.for_each_near(p, reach, |t| {
            let d = self.dist2(t, p);
            if best.is_none_or(|b| d < b.0 || (d == b.0 && t < b.1)) {
                best = Some((d, t));
            }
        });
        let (d2, t) = best?;
        (d2.sqrt() <= reach).then(|| self.closest_on(t, p))
    }

    /// The surface point nearest to `p`, for a point inside the grid's box (the search
    /// widens until it is sure); `None` outside the box.
    pub fn nearest(&self, p: [f64; 3]) -> Option<SurfacePoint> {
        let (t, _) = self.grid.nearest(p, |t| self.dist2(t, p))?;
        Some(self.closest_on(t, p))
    }

    /// The class of the grid cell holding `p`.
    pub fn grid_class(&self, p: [f64; 3]) -> CellClass {
        self.grid.class_of(p)
    }

    /// Whether `p` lies inside the closed surface.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        match self.grid.class_of(p) {
            CellClass::Outside => false,
            CellClass::Inside => true,
            CellClass::Boundary => self.nearest(p).is_some_and(|s| self.signed_distance(&s, p) < 0.0),
        }
    }

    /// Projects `p` onto the surface along the smooth normal field (a "Phong projection"):
    /// the point `q(w)` of a triangle and the distance s with `p = q(w) + s N(w)`, found by
    /// Newton's method on the barycentric weights and s, walking to the neighbour across an
    /// edge while the solution lies beyond it (at most `max_steps` walks). Newton starts from
    /// `from` (the proxy's last point and signed distance), so the projection continues the
    /// branch it was on, and because `N` is continuous over the surface (the vertex
    /// pseudo-normals are shared) it moves continuously with `p` — unlike the nearest point,
    /// which jumps across the bisector of every ridge once `p` is deeper than the ridge is
    /// wide. `None` where the branch ends (Newton's method does not converge: `p` beyond a
    /// fold of the normal field, deeper than the organ's local curvature radius). Returns the
    /// point and its signed distance along the normal (positive outside).
    pub fn project(&self, from: (SurfacePoint, f64), p: [f64; 3], max_steps: usize) -> Option<(SurfacePoint, f64)> {
        let (mut start, mut dist) = from;
        let mut t = start.triangle;
        let mut came_from = usize::MAX;
        for _ in 0..=max_steps {
            let (w, d) = self.project_in(t, p, start.weights, dist)?;
            // the most negative weight names the edge the solution lies beyond
            let (a, &low) = w.iter().enumerate().min_by(|x, y| x.1.total_cmp(y.1)).expect("three weights");
            let next = self.across[t][a];
            if low >= -PROJECTION_SLACK {
                let w = clamp_weights(w);
                let g = &self.geom[t];
                let point = [0, 1, 2].map(|k| g[0][k] + w[1] * g[1][k] + w[2] * g[2][k]);
                let here = SurfacePoint {
                    triangle: t,
                    weights: w,
                    point,
                };
                return Some((here, d));
            }
            if next == NO_NEIGHBOUR || next as usize == came_from {
                // an open edge, or a fold of the normal field between two triangles (each
                // solution lies beyond their shared edge): the proxy rests on the edge, at the
                // point whose normal passes nearest to p — the same point from either side, and
                // where the triangle's solution left the edge when the fold began
                let here = self.edge_point(t, a, w, p);
                let d = self.signed_distance(&here, p);
                return Some((here, d));
            }
            let point = {
                let w = clamp_weights(w);
                let g = &self.geom[t];
                [0, 1, 2].map(|k| g[0][k] + w[1] * g[1][k] + w[2] * g[2][k])
            };
            // continue in the neighbour from the point of the shared edge
            came_from = t;
            t = next as usize;
            start = self.closest_on(t, point);
            dist = d;
        }
        None
    }

    /// The point of the edge of triangle `t` opposite vertex `a` whose smooth normal passes
    /// nearest to `p`: the least-squares solution of `p = q(τ) + σ N(τ)` along the edge
    /// (`q` and `N` interpolated between the edge's two nodes, τ ∈ [0, 1]), by Gauss–Newton
    /// from the edge point of the triangle's own solution `w`. Where a fold begins, the
    /// triangle's solution reaches the edge with a zero residual, so the proxy does not jump
    /// into the fold (the point nearest to `p` did: 0.33 mm on the organ); and the problem is
    /// the edge's alone, so either triangle finds the same point.
    fn edge_point(&self, t: usize, a: usize, w: [f64; 3], p: [f64; 3]) -> SurfacePoint {
        let g = &self.geom[t];
        let corner = |i: usize| match i {
            0 => g[0],
            1 => [0, 1, 2].map(|k| g[0][k] + g[1][k]),
            _ => [0, 1, 2].map(|k| g[0][k] + g[2][k]),
        };
        let (i, j) = ((a + 1) % 3, (a + 2) % 3);
        let (x, y) = (corner(i), corner(j));
        let (nx, ny) = (self.vertex_normals[self.tris[t][i]], self.vertex_normals[self.tris[t][j]]);
        let (e, dn) = (sub(y, x), sub(ny, nx));
        let at = |tau: f64| ([0, 1, 2].map(|k| x[k] + tau * e[k]), [0, 1, 2].map(|k| nx[k] + tau * dn[k]));
        let (wi, wj) = (w[i].max(0.0), w[j].max(0.0));
        let mut tau = if wi + wj > 0.0 { wj / (wi + wj) } else { 0.5 };
        let (q, n) = at(tau);
        let mut sigma = dot(sub(p, q), n) / dot(n, n).max(f64::MIN_POSITIVE);
        for _ in 0..PROJECTION_ITERATIONS {
            let (q, n) = at(tau);
            let f = [0, 1, 2].map(|k| q[k] + sigma * n[k] - p[k]);
            let jt = [0, 1, 2].map(|k| e[k] + sigma * dn[k]);
            // the normal equations of J = [jt n]
            let (a11, a12, a22) = (dot(jt, jt), dot(jt, n), dot(n, n));
            let (b1, b2) = (-dot(jt, f), -dot(n, f));
            let det = a11 * a22 - a12 * a12;
            if !(det.is_finite() && det > 1e-14 * a11 * a22) {
                break;
            }
            let dt = (b1 * a22 - b2 * a12) / det;
            let ds = (a11 * b2 - a12 * b1) / det;
            let next = (tau + dt).clamp(0.0, 1.0);
            sigma += ds;
            let moved = (next - tau).abs();
            tau = next;
            if moved.is_nan() || moved <= 1e-15 {
                break;
            }
        }
        if !tau.is_finite() {
            tau = 0.5;
        }
        let mut weights = [0.0; 3];
        weights[i] = 1.0 - tau;
        weights[j] = tau;
        SurfacePoint {
            triangle: t,
            weights,
            point: at(tau).0,
        }
    }

    /// Newton's method for `a + u·ab + v·ac + s·N(1−u−v, u, v) = p` in triangle `t`, from
    /// weights `w0` and signed distance `d0`: the weights (possibly outside the triangle) and
    /// the signed distance `s |N|`.
    fn project_in(&self, t: usize, p: [f64; 3], w0: [f64; 3], d0: f64) -> Option<([f64; 3], f64)> {
        let g = &self.geom[t];
        let tri = self.tris[t];
        let n0 = self.vertex_normals[tri[0]];
        let dn1 = sub(self.vertex_normals[tri[1]], n0);
        let dn2 = sub(self.vertex_normals[tri[2]], n0);
        let (mut u, mut v) = (w0[1], w0[2]);
        let len0 = {
            let nn = [0, 1, 2].map(|k| n0[k] + u * dn1[k] + v * dn2[k]);
            dot(nn, nn).sqrt().max(f64::MIN_POSITIVE)
        };
        let mut s = d0 / len0;
        let scale = dot(g[1], g[1]).max(dot(g[2], g[2])).sqrt() + d0.abs();
        for _ in 0..PROJECTION_ITERATIONS {
            let nn = [0, 1, 2].map(|k| n0[k] + u * dn1[k] + v * dn2[k]);
            let f = [0, 1, 2].map(|k| g[0][k] + u * g[1][k] + v * g[2][k] + s * nn[k] - p[k]);
            if dot(f, f).sqrt() <= 1e-12 * scale {
                let len = dot(nn, nn).sqrt();
                return (len > 0.0 && u.is_finite() && v.is_finite() && s.is_finite()).then_some(([1.0 - u - v, u, v], s * len));
            }
            let cu = [0, 1, 2].map(|k| g[1][k] + s * dn1[k]);
            let cv = [0, 1, 2].map(|k| g[2][k] + s * dn2[k]);
            let det = dot(cu, cross(cv, nn));
            if !(det.is_finite() && det.abs() > 1e-12 * dot(cu, cu).sqrt() * dot(cv, cv).sqrt() * dot(nn, nn).sqrt()) {
                return None;
            }
            // Cramer's rule for J [du dv ds]ᵀ = −f with J = [cu cv nn]
            u -= dot(f, cross(cv, nn)) / det;
            v -= dot(cu, cross(f, nn)) / det;
            s -= dot(cu, cross(cv, f)) / det;
        }
        None
    }
}

/// Closest point of triangle (a, a+ab, a+ac) to p: barycentric weights and the point
/// (Ericson, Real-Time Collision Detection, §5.1.5).
fn closest_on_triangle(p: [f64; 3], a: [f64; 3], ab: [f64; 3], ac: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let at = |v: f64, w: f64| -> ([f64; 3], [f64; 3]) {
        (
            [1.0 - v - w, v, w],
            [
                a[0] + v * ab[0] + w * ac[0],
                a[1] + v * ab[1] + w * ac[1],
                a[2] + v * ab[2] + w * ac[2],
            ],
        )
    };
    let ap = sub(p, a);
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return at(0.0, 0.0);
    }
    let bp = sub(ap, ab);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return at(1.0, 0.0);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return at(d1 / (d1 - d3), 0.0);
    }
    let cp = sub(ap, ac);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return at(0.0, 1.0);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return at(0.0, d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return at(1.0 - w, w);
    }
    let denom = 1.0 / (va + vb + vc);
    at(vb * denom, vc * denom)
}
