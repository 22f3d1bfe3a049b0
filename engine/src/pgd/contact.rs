//! Where a spherical tool tip touches the accessible surface, and how deep.
//!
//! The tip (centre c, radius r) is compared with the reference surface made of the
//! accessible triangles (all three nodes loadable). With s the closest surface point, n the
//! triangle's outward normal and `d = (c − s)·n` the signed distance, the tip touches when
//! `d < r`; the surface point s is then pushed by `δ = −(r − d) n`, which the vademecum turns
//! into a force. A tip that is not finite, is farther than r from every accessible triangle,
//! or lies behind the surface by more than one tip diameter (it went through, or is on the
//! other side of the organ) makes no contact: zero force, never garbage.
//!
//! Contact needs the closest triangle within 2r of the tip (a tip farther from every
//! triangle, or more than a diameter behind the surface, makes none), so the search visits
//! only the triangles listed in the cells of a uniform grid that overlap the box of half-side
//! 2r around the tip: the same answer as a scan over every triangle, at a cost independent
//! of the organ's size.

use super::vademecum::Vademecum;

/// A contact found by [`SurfaceContact::query`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPoint {
    /// The triangle's nodes.
    pub nodes: [usize; 3],
    /// Barycentric weights of the contact point in it.
    pub weights: [f64; 3],
    /// The imposed surface displacement δ (m), along the inward normal.
    pub penetration: [f64; 3],
    /// Penetration depth `r − d` (m, positive).
    pub depth: f64,
}

/// The accessible reference surface, prepared for contact queries.
#[derive(Debug, Clone)]
pub struct SurfaceContact {
    tris: Vec<[usize; 3]>,
    /// Per triangle: vertex a, edges ab, ac, unit normal.
    geom: Vec<[[f64; 3]; 4]>,
    grid: Grid,
}

/// A uniform grid over the triangles' bounding box; each cell lists the triangles whose
/// bounding box overlaps it (CSR).
#[derive(Debug, Clone)]
struct Grid {
    origin: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    ptr: Vec<u32>,
    tris: Vec<u32>,
}

/// Most cells per axis.
const MAX_CELLS: usize = 64;

impl Grid {
    fn new(geom: &[[[f64; 3]; 4]]) -> Self {
        let boxes: Vec<([f64; 3], [f64; 3])> = geom
            .iter()
            .map(|g| {
                let pts = [
                    g[0],
                    [g[0][0] + g[1][0], g[0][1] + g[1][1], g[0][2] + g[1][2]],
                    [g[0][0] + g[2][0], g[0][1] + g[2][1], g[0][2] + g[2][2]],
                ];
                let lo = [0, 1, 2].map(|k| pts.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min));
                let hi = [0, 1, 2].map(|k| pts.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max));
                (lo, hi)
            })
            .collect();
        let lo = [0, 1, 2].map(|k| boxes.iter().map(|b| b.0[k]).fold(f64::INFINITY, f64::min));
        let hi = [0, 1, 2].map(|k| boxes.iter().map(|b| b.1[k]).fold(f64::NEG_INFINITY, f64::max));
        if boxes.is_empty() || !lo.iter().chain(&hi).all(|x| x.is_finite()) {
            return Self {
                origin: [0.0; 3],
                cell: 1.0,
                dims: [0; 3],
                ptr: vec![0],
                tris: Vec::new(),
            };
        }
        // cells about two mean triangle sizes wide, at most MAX_CELLS per axis
        let mean = boxes
            .iter()
            .map(|b| (0..3).map(|k| b.1[k] - b.0[k]).fold(0.0, f64::max))
            .sum::<f64>()
            / boxes.len() as f64;
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        let cell = (2.0 * mean).max(extent / MAX_CELLS as f64).max(f64::MIN_POSITIVE);
        let dims = [0, 1, 2].map(|k| (((hi[k] - lo[k]) / cell).floor() as usize + 1).min(MAX_CELLS));
        let index = |x: f64, k: usize| (((x - lo[k]) / cell).floor().max(0.0) as usize).min(dims[k] - 1);
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        for (t, (a, b)) in boxes.iter().enumerate() {
            for i in index(a[0], 0)..=index(b[0], 0) {
                for j in index(a[1], 1)..=index(b[1], 1) {
                    for l in index(a[2], 2)..=index(b[2], 2) {
                        lists[(i * dims[1] + j) * dims[2] + l].push(t as u32);
                    }
                }
            }
        }
        let mut ptr = vec![0u32];
        let mut tris = Vec::new();
        for l in lists {
            tris.extend(l);
            ptr.push(tris.len() as u32);
        }
        Self {
            origin: lo,
            cell,
            dims,
            ptr,
            tris,
        }
    }

    /// Calls `visit` with every triangle listed in a cell that overlaps the box `p ± reach`
    /// (a triangle may come more than once).
    fn for_each_near(&self, p: [f64; 3], reach: f64, mut visit: impl FnMut(usize)) {
        if self.dims[0] == 0 {
            return;
        }
        let mut range = [(0usize, 0usize); 3];
        for k in 0..3 {
            let a = ((p[k] - reach - self.origin[k]) / self.cell).floor();
            let b = ((p[k] + reach - self.origin[k]) / self.cell).floor();
            if b < 0.0 || a > (self.dims[k] - 1) as f64 {
                return;
            }
            range[k] = (a.max(0.0) as usize, (b as usize).min(self.dims[k] - 1));
        }
        for i in range[0].0..=range[0].1 {
            for j in range[1].0..=range[1].1 {
                for l in range[2].0..=range[2].1 {
                    let c = (i * self.dims[1] + j) * self.dims[2] + l;
                    for &t in &self.tris[self.ptr[c] as usize..self.ptr[c + 1] as usize] {
                        visit(t as usize);
                    }
                }
            }
        }
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl SurfaceContact {
    /// Keeps the surface triangles whose nodes the vademecum can load.
    pub fn new(nodes: &[[f64; 3]], surface: &[[usize; 3]], v: &Vademecum) -> Self {
        let tris: Vec<[usize; 3]> = surface.iter().copied().filter(|t| t.iter().all(|&n| v.is_loadable(n))).collect();
        Self::from_triangles(nodes, tris)
    }

    /// Prepares the given triangles.
    fn from_triangles(nodes: &[[f64; 3]], tris: Vec<[usize; 3]>) -> Self {
        let geom = tris
            .iter()
            .map(|t| {
                let (a, b, c) = (nodes[t[0]], nodes[t[1]], nodes[t[2]]);
                let (ab, ac) = (sub(b, a), sub(c, a));
                let n = [
                    ab[1] * ac[2] - ab[2] * ac[1],
                    ab[2] * ac[0] - ab[0] * ac[2],
                    ab[0] * ac[1] - ab[1] * ac[0],
                ];
                let len = dot(n, n).sqrt().max(f64::MIN_POSITIVE);
                [a, ab, ac, [n[0] / len, n[1] / len, n[2] / len]]
            })
            .collect::<Vec<_>>();
        let grid = Grid::new(&geom);
        Self { tris, geom, grid }
    }

    /// Number of accessible triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// Whether there is no accessible triangle.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// The contact of a tip of radius `radius` (m) centred at `tip` (m), if any.
    pub fn query(&self, tip: [f64; 3], radius: f64) -> Option<ContactPoint> {
        if !(tip.iter().all(|x| x.is_finite()) && radius.is_finite() && radius > 0.0) {
            return None;
        }
        let mut best: Option<(f64, usize, [f64; 3])> = None;
        self.grid.for_each_near(tip, 2.0 * radius, |i| {
            let g = &self.geom[i];
            let (w, q) = closest_on_triangle(tip, g[0], g[1], g[2]);
            let d2 = dot(sub(tip, q), sub(tip, q));
            if best.is_none_or(|b| d2 < b.0 || (d2 == b.0 && i < b.1)) {
                best = Some((d2, i, w));
            }
        });
        self.accept(tip, radius, best?)
    }

    /// Turns the closest triangle into a contact, if the tip touches it.
    fn accept(&self, tip: [f64; 3], radius: f64, (d2, i, w): (f64, usize, [f64; 3])) -> Option<ContactPoint> {
        let n = self.geom[i][3];
        let s = {
            let g = &self.geom[i];
            [
                g[0][0] + w[1] * g[1][0] + w[2] * g[2][0],
                g[0][1] + w[1] * g[1][1] + w[2] * g[2][1],
                g[0][2] + w[1] * g[1][2] + w[2] * g[2][2],
            ]
        };
        let d = dot(sub(tip, s), n);
        if d2.sqrt() > radius.max(-d) || d >= radius || d < -2.0 * radius {
            return None;
        }
        let depth = radius - d;
        Some(ContactPoint {
            nodes: self.tris[i],
            weights: w,
            penetration: [-depth * n[0], -depth * n[1], -depth * n[2]],
            depth,
        })
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::boundary::Boundary;
    use crate::mesh::procedural;

    /// The grid search finds exactly what a scan over every triangle finds.
    #[test]
    fn grid_search_matches_a_full_scan() {
        let mesh = procedural::lobe(&procedural::LobeParams::default());
        let tris = Boundary::of(&mesh).triangles();
        let sc = SurfaceContact::from_triangles(&mesh.nodes, tris);
        let scan = |tip: [f64; 3], r: f64| {
            let mut best: Option<(f64, usize, [f64; 3])> = None;
            for (i, g) in sc.geom.iter().enumerate() {
                let (w, q) = closest_on_triangle(tip, g[0], g[1], g[2]);
                let d2 = dot(sub(tip, q), sub(tip, q));
                if best.is_none_or(|b| d2 < b.0) {
                    best = Some((d2, i, w));
                }
            }
            sc.accept(tip, r, best?)
        };
        let mut seed = 0x2545_F491_4F6C_DD1Du64;
        let mut unit = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut touching, mut n) = (0, 0);
        for _ in 0..20_000 {
            // tips near the surface: a random node, pushed a random way by up to 1.5 cm
            let p = mesh.nodes[(unit() * mesh.n_nodes() as f64) as usize % mesh.n_nodes()];
            let tip = [0, 1, 2].map(|k| p[k] + 0.03 * (unit() - 0.5));
            let r = 0.002 + 0.008 * unit();
            let (a, b) = (sc.query(tip, r), scan(tip, r));
            assert_eq!(a, b, "tip {tip:?}, r {r}");
            touching += usize::from(a.is_some());
            n += 1;
        }
        assert!(touching > n / 20, "the sample should touch often ({touching} of {n})");
        // far away, or not finite: nothing
        assert_eq!(sc.query([1.0, 1.0, 1.0], 0.004), None);
        assert_eq!(sc.query([f64::NAN, 0.0, 0.0], 0.004), None);
    }
}
