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
//! The search is a linear scan over the accessible triangles (tens of nanoseconds each); a
//! spatial grid is the next step for organs with many thousands of accessible triangles.

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
            .collect();
        Self { tris, geom }
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
        for (i, g) in self.geom.iter().enumerate() {
            let (w, q) = closest_on_triangle(tip, g[0], g[1], g[2]);
            let d2 = dot(sub(tip, q), sub(tip, q));
            if best.is_none_or(|b| d2 < b.0) {
                best = Some((d2, i, w));
            }
        }
        let (d2, i, w) = best?;
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
