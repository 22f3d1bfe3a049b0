//! Cuts as level sets, and the visibility criterion (seed 004 §4.2.2 in 2D, §6.2 in 3D).
//!
//! # Representation
//! A cut is a set of planar *facets* in the reference configuration: the line segments of a 2D
//! cutting path `T₀–T₁–…–Tₙ`, or the triangles swept by a 3D blade. Each facet carries the two
//! level-set functions of the seed (after Stolarska et al. 2001):
//!
//! - `φ(x) = n·(x − T)`, the signed distance to the facet's line or plane (Eq. 4.5: positive on
//!   one side of the cut, negative on the other);
//! - `ψ(x) = t·(x − T)`, the signed distance along the cutting direction to the line or plane
//!   orthogonal to the cut at its end `T` (Eq. 4.6: negative behind the end).
//!
//! Progressing along one direction moves `T` (Eqs. 4.7–4.9: only `ψ` changes); a change of
//! direction starts a new facet with its own pair, the previous pair staying valid behind the
//! corner (Eqs. 4.10–4.13). Keeping one pair per segment instead of the seed's single rotated
//! pair makes the criterion below exact at corners: with one pair, two points on the outer side
//! of a corner may see each other across the inner wedge.
//!
//! # Visibility (Eqs. 4.14–4.17)
//! A node `I` is affected when its influence domain reaches the cut (`|φ_I| < d_I` and
//! `ψ_I < d_I`, Eq. 4.14, for some facet). For an affected node and a point `P` of its domain,
//! `P` stays in the domain when `φ_I φ_P ≥ 0` for every facet (same side, Eq. 4.15); otherwise the
//! segment `I–P` crosses the facet's plane where `ψ = ψ_I + s(ψ_P − ψ_I)`, `s = φ_I/(φ_I − φ_P)`,
//! and `P` is dropped when that crossing lies on the facet (Eqs. 4.16–4.17, with the geometric
//! check of the seed's case 3b written in level sets). The end of the cut is open: a line
//! through the tip itself is not blocked, so a node at the tip is seen from both faces.
//!
//! Nodes and integration points that lie exactly on a facet are allocated to one side by a small
//! signed level-set value (the seed's `±ε`): here they carry a *sight* position shifted by
//! `±ε n`, used only for the criterion.

use crate::geometry::vec3::{add, cross, dot, norm, scale, sub};

/// Why a cut could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CutError {
    /// Fewer than two points, or a zero-length segment.
    #[error("a cutting path needs at least two distinct points; segment {segment} has zero length")]
    Degenerate {
        /// The offending segment (or 0 when there are too few points).
        segment: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("cut point {index} is not finite")]
    NotFinite {
        /// The point.
        index: usize,
    },
    /// A 3D blade position that does not sweep an area.
    #[error("blade positions {from} and {to} sweep no area")]
    NoArea {
        /// First blade position.
        from: usize,
        /// Second.
        to: usize,
    },
    /// Two 2D paths combined.
    #[error("separate 2D cutting paths cannot be combined; a 2D cut progresses with advance()")]
    Union,
    /// 2D and 3D pieces mixed.
    #[error("a {expected}D cut cannot take a {got}D piece")]
    Dimension {
        /// The cut's dimension.
        expected: usize,
        /// The piece's.
        got: usize,
    },
}

/// One planar piece of a cut: a segment (2D) or a triangle (3D).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Facet {
    /// Vertices; the 2D segment runs from `vertices[0]` to its end `vertices[1]`.
    pub vertices: [[f64; 3]; 3],
    /// Unit normal (`n` of `φ`).
    pub normal: [f64; 3],
    /// Unit cutting direction (`t` of `ψ`, 2D only).
    pub direction: [f64; 3],
    /// Segment length (2D) or 0 (3D).
    pub length: f64,
    /// Whether the end of this facet is the open tip of the cut (2D).
    pub open_end: bool,
}

impl Facet {
    fn segment(from: [f64; 3], to: [f64; 3]) -> Self {
        let d = sub(to, from);
        let length = norm(d);
        let t = scale(d, 1.0 / length);
        Self {
            vertices: [from, to, to],
            normal: [-t[1], t[0], 0.0],
            direction: t,
            length,
            open_end: true,
        }
    }

    fn triangle(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Option<Self> {
        let n = cross(sub(b, a), sub(c, a));
        let area2 = norm(n);
        let size = norm(sub(b, a)).max(norm(sub(c, a)));
        (area2 > 1e-12 * size * size).then(|| Self {
            vertices: [a, b, c],
            normal: scale(n, 1.0 / area2),
            direction: [0.0; 3],
            length: 0.0,
            open_end: false,
        })
    }

    /// `φ(x)`: signed distance to the facet's line or plane (Eq. 4.5).
    pub fn phi(&self, x: [f64; 3]) -> f64 {
        dot(self.normal, sub(x, self.vertices[1]))
    }

    /// `ψ(x)`: signed distance along the cutting direction from the facet's end (Eq. 4.6;
    /// 2D segments).
    pub fn psi(&self, x: [f64; 3]) -> f64 {
        dot(self.direction, sub(x, self.vertices[1]))
    }

    fn is_segment(&self) -> bool {
        self.length > 0.0
    }

    /// Whether the point `c` of the facet's plane lies on the facet (closed, except the open
    /// tip of a 2D cut).
    fn contains(&self, c: [f64; 3], tol: f64) -> bool {
        if self.is_segment() {
            let s = self.psi(c);
            s >= -self.length - tol && if self.open_end { s < -tol } else { s <= tol }
        } else {
            // barycentric coordinates in the plane
            let [a, b, cc] = self.vertices;
            let (e0, e1, p) = (sub(b, a), sub(cc, a), sub(c, a));
            let (d00, d01, d11) = (dot(e0, e0), dot(e0, e1), dot(e1, e1));
            let (d20, d21) = (dot(p, e0), dot(p, e1));
            let den = d00 * d11 - d01 * d01;
            let v = (d11 * d20 - d01 * d21) / den;
            let w = (d00 * d21 - d01 * d20) / den;
            let rel = tol / d00.max(d11).sqrt();
            v >= -rel && w >= -rel && v + w <= 1.0 + rel
        }
    }

    /// Distance from `x` to the facet.
    pub fn distance(&self, x: [f64; 3]) -> f64 {
        if self.is_segment() {
            let s = self.psi(x).clamp(-self.length, 0.0);
            norm(sub(x, add(self.vertices[1], scale(self.direction, s))))
        } else {
            let phi = self.phi(x);
            let foot = sub(x, scale(self.normal, phi));
            if self.contains(foot, 0.0) {
                return phi.abs();
            }
            let [a, b, c] = self.vertices;
            [(a, b), (b, c), (c, a)]
                .iter()
                .map(|&(p, q)| {
                    let e = sub(q, p);
                    let s = (dot(sub(x, p), e) / dot(e, e)).clamp(0.0, 1.0);
                    norm(sub(x, add(p, scale(e, s))))
                })
                .fold(f64::INFINITY, f64::min)
        }
    }

    /// Whether the straight segment `a–b` passes through the facet (the visibility criterion).
    pub fn blocks(&self, a: [f64; 3], b: [f64; 3]) -> bool {
        let (pa, pb) = (self.phi(a), self.phi(b));
        if pa * pb >= 0.0 {
            return false; // Eq. 4.15: same side, or one of them on the extension of the cut
        }
        let s = pa / (pa - pb);
        let c = add(a, scale(sub(b, a), s));
        self.contains(c, 0.0)
    }
}

/// A cut: a 2D cutting path or a swept 3D surface, in the reference configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Cut {
    dim: usize,
    facets: Vec<Facet>,
    /// 2D: the path `T₀…Tₙ`; 3D: the blade positions, two points each.
    path: Vec<[f64; 3]>,
    /// 3D: the swept quadrilaterals `(a_k, b_k, b_{k+1}, a_{k+1})`.
    quads: Vec<[[f64; 3]; 4]>,
}

/// Relative tolerance (of the cut's size) for "on the cut".
const ON_CUT: f64 = 1e-9;

impl Cut {
    /// A 2D cutting path through `points` (at least two), each turn a change of cutting
    /// direction.
    pub fn path(points: &[[f64; 2]]) -> Result<Self, CutError> {
        let mut cut = Self {
            dim: 2,
            facets: Vec::new(),
            path: Vec::new(),
            quads: Vec::new(),
        };
        if points.len() < 2 {
            return Err(CutError::Degenerate { segment: 0 });
        }
        for (i, p) in points.iter().enumerate() {
            if !p.iter().all(|v| v.is_finite()) {
                return Err(CutError::NotFinite { index: i });
            }
        }
        cut.path.push([points[0][0], points[0][1], 0.0]);
        for p in &points[1..] {
            cut.advance([p[0], p[1]])?;
        }
        Ok(cut)
    }

    /// Progresses the 2D cut from its current end to `to`: along the same direction the last
    /// segment grows (Eqs. 4.7–4.9), otherwise a new segment starts (Eqs. 4.10–4.13).
    pub fn advance(&mut self, to: [f64; 2]) -> Result<(), CutError> {
        if self.dim != 2 {
            return Err(CutError::Dimension {
                expected: self.dim,
                got: 2,
            });
        }
        let to3 = [to[0], to[1], 0.0];
        if !to.iter().all(|v| v.is_finite()) {
            return Err(CutError::NotFinite { index: self.path.len() });
        }
        let end = *self.path.last().expect("a path starts with a point");
        let d = sub(to3, end);
        if norm(d) <= ON_CUT * norm(end).max(norm(to3)).max(f64::MIN_POSITIVE) {
            return Err(CutError::Degenerate {
                segment: self.path.len() - 1,
            });
        }
        if let Some(last) = self.facets.last_mut() {
            last.open_end = false;
            let t = scale(d, 1.0 / norm(d));
            let turn = last.direction[0] * t[1] - last.direction[1] * t[0];
            if turn.abs() < 1e-9 && dot(last.direction, t) > 0.0 {
                // same direction: the end moves along, ψ shifts by the advance
                let start = last.vertices[0];
                *last = Facet::segment(start, to3);
                *self.path.last_mut().expect("non-empty") = to3;
                return Ok(());
            }
        }
        self.facets.push(Facet::segment(end, to3));
        self.path.push(to3);
        Ok(())
    }

    /// A 3D cut swept by a straight blade: each consecutive pair of blade positions
    /// `(a_k, b_k) → (a_{k+1}, b_{k+1})` adds the quadrilateral between them (two triangles).
    pub fn swept(blade: &[([f64; 3], [f64; 3])]) -> Result<Self, CutError> {
        let mut cut = Self {
            dim: 3,
            facets: Vec::new(),
            path: Vec::new(),
            quads: Vec::new(),
        };
        if blade.len() < 2 {
            return Err(CutError::Degenerate { segment: 0 });
        }
        for (i, (a, b)) in blade.iter().enumerate() {
            if !a.iter().chain(b).all(|v| v.is_finite()) {
                return Err(CutError::NotFinite { index: i });
            }
            cut.path.extend([*a, *b]);
        }
        for k in 0..blade.len() - 1 {
            let ((a0, b0), (a1, b1)) = (blade[k], blade[k + 1]);
            let t1 = Facet::triangle(a0, b0, b1);
            let t2 = Facet::triangle(a0, b1, a1);
            if t1.is_none() && t2.is_none() {
                return Err(CutError::NoArea { from: k, to: k + 1 });
            }
            cut.facets.extend(t1.into_iter().chain(t2));
            cut.quads.push([a0, b0, b1, a1]);
        }
        Ok(cut)
    }

    /// This 3D cut and `other` together (e.g. two separate incisions).
    pub fn union(&self, other: &Cut) -> Result<Cut, CutError> {
        if self.dim != 3 || other.dim != 3 {
            return Err(if self.dim == other.dim {
                CutError::Union
            } else {
                CutError::Dimension {
                    expected: self.dim,
                    got: other.dim,
                }
            });
        }
        let mut out = self.clone();
        out.facets.extend_from_slice(&other.facets);
        out.path.extend_from_slice(&other.path);
        out.quads.extend_from_slice(&other.quads);
        Ok(out)
    }

    /// Space dimension.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The facets.
    pub fn facets(&self) -> &[Facet] {
        &self.facets
    }

    /// 2D: the path points `T₀…Tₙ`; 3D: the blade end points, two per position.
    pub fn points(&self) -> &[[f64; 3]] {
        &self.path
    }

    /// The open tip of a 2D cut.
    pub fn tip(&self) -> Option<[f64; 3]> {
        (self.dim == 2).then(|| *self.path.last().expect("non-empty"))
    }

    /// Total length (2D) or area (3D).
    pub fn size(&self) -> f64 {
        self.facets
            .iter()
            .map(|f| {
                if f.is_segment() {
                    f.length
                } else {
                    0.5 * norm(cross(sub(f.vertices[1], f.vertices[0]), sub(f.vertices[2], f.vertices[0])))
                }
            })
            .sum()
    }

    fn tolerance(&self) -> f64 {
        let extent = self.path.iter().map(|p| norm(*p)).fold(0.0, f64::max);
        ON_CUT * extent.max(f64::MIN_POSITIVE)
    }

    /// Distance from `x` to the cut.
    pub fn distance(&self, x: [f64; 3]) -> f64 {
        self.facets.iter().map(|f| f.distance(x)).fold(f64::INFINITY, f64::min)
    }

    /// Whether the segment `a–b` crosses the cut: `b` is not visible from `a`.
    pub fn blocks(&self, a: [f64; 3], b: [f64; 3]) -> bool {
        self.facets.iter().any(|f| f.blocks(a, b))
    }

    /// When `x` lies on the cut (not at its open tip): the direction in which to shift it to be
    /// on the positive side of every facet it touches (the mean of their normals).
    pub fn on_cut(&self, x: [f64; 3]) -> Option<[f64; 3]> {
        let tol = self.tolerance();
        if self.tip().is_some_and(|t| norm(sub(x, t)) <= tol) {
            return None;
        }
        let mut n = [0.0; 3];
        let mut any = false;
        for f in &self.facets {
            if f.distance(x) <= tol {
                n = add(n, f.normal);
                any = true;
            }
        }
        let len = norm(n);
        (any && len > 0.0).then(|| scale(n, 1.0 / len))
    }

    /// The sight position of `x` on side `side` (±1): `x` itself off the cut, `x ± ε n` on it.
    pub fn sight(&self, x: [f64; 3], side: f64) -> [f64; 3] {
        match self.on_cut(x) {
            Some(n) => add(x, scale(n, side * 1e3 * self.tolerance())),
            None => x,
        }
    }

    /// Points along a 2D path every `spacing` or less (both ends of each segment included, the
    /// tip last), for the discretisation of the cut by nodes; in 3D, a grid over each swept
    /// quadrilateral, `spacing` or less apart along the blade and along the sweep.
    pub fn stations(&self, spacing: f64) -> Vec<[f64; 3]> {
        let mut out: Vec<[f64; 3]> = Vec::new();
        let tol = self.tolerance();
        let push = |p: [f64; 3], out: &mut Vec<[f64; 3]>| {
            if !out.iter().any(|q| norm(sub(*q, p)) <= tol) {
                out.push(p);
            }
        };
        let steps = |l: f64| (l / spacing * (1.0 - 1e-9)).ceil().max(1.0) as usize;
        for f in self.facets.iter().filter(|f| f.is_segment()) {
            let k = steps(f.length);
            for i in 0..=k {
                let s = -f.length + f.length * i as f64 / k as f64;
                push(add(f.vertices[1], scale(f.direction, s)), &mut out);
            }
        }
        for &[a0, b0, b1, a1] in &self.quads {
            let ks = steps(norm(sub(b0, a0)).max(norm(sub(b1, a1))));
            let kt = steps(norm(sub(a1, a0)).max(norm(sub(b1, b0))));
            for j in 0..=kt {
                let t = j as f64 / kt as f64;
                let (a, b) = (add(a0, scale(sub(a1, a0), t)), add(b0, scale(sub(b1, b0), t)));
                for i in 0..=ks {
                    push(add(a, scale(sub(b, a), i as f64 / ks as f64)), &mut out);
                }
            }
        }
        // the tip last
        if let Some(t) = self.tip()
            && let Some(i) = out.iter().position(|q| norm(sub(*q, t)) <= tol)
        {
            let tip = out.remove(i);
            out.push(tip);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seg_cross(a: [f64; 3], b: [f64; 3], p: [f64; 3], q: [f64; 3]) -> bool {
        // brute force: do the open segments a–b and p–q intersect (2D)?
        let o = |u: [f64; 3], v: [f64; 3], w: [f64; 3]| (v[0] - u[0]) * (w[1] - u[1]) - (v[1] - u[1]) * (w[0] - u[0]);
        o(a, b, p) * o(a, b, q) < 0.0 && o(p, q, a) * o(p, q, b) < 0.0
    }

    #[test]
    fn level_sets_are_signed_distances() {
        let cut = Cut::path(&[[0.0, 0.0], [2.0, 0.0]]).unwrap();
        let f = cut.facets()[0];
        assert_eq!(f.phi([1.0, 0.5, 0.0]), 0.5);
        assert_eq!(f.phi([1.0, -0.5, 0.0]), -0.5);
        assert_eq!(f.psi([1.0, 0.5, 0.0]), -1.0);
        assert_eq!(f.psi([3.0, 0.0, 0.0]), 1.0);
        assert!((cut.distance([3.0, 1.0, 0.0]) - 2f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn advancing_along_the_same_direction_grows_the_segment() {
        let mut cut = Cut::path(&[[0.0, 0.0], [1.0, 1.0]]).unwrap();
        cut.advance([2.0, 2.0]).unwrap();
        assert_eq!(cut.facets().len(), 1);
        assert!((cut.facets()[0].length - 8f64.sqrt()).abs() < 1e-12);
        cut.advance([2.0, 3.0]).unwrap();
        assert_eq!(cut.facets().len(), 2, "a change of direction starts a segment");
        assert!(!cut.facets()[0].open_end && cut.facets()[1].open_end);
        assert_eq!(cut.advance([2.0, 3.0]), Err(CutError::Degenerate { segment: 2 }));
        assert!(matches!(Cut::path(&[[0.0, 0.0]]), Err(CutError::Degenerate { .. })));
        assert!(matches!(
            Cut::path(&[[0.0, 0.0], [f64::NAN, 1.0]]),
            Err(CutError::NotFinite { index: 1 })
        ));
    }

    #[test]
    fn visibility_matches_brute_force_segment_intersection_around_corners() {
        // seed 004 Fig. 4.8's path (two collinear segments, then a turn), scaled up
        let cut = Cut::path(&[[50.0, 90.0], [59.0, 82.0], [66.0, 75.0], [58.0, 52.0]]).unwrap();
        assert_eq!(cut.facets().len(), 3, "AB and BC are not exactly collinear in the seed");
        let mut s: u64 = 7;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            40.0 + 40.0 * ((s >> 11) as f64 / (1u64 << 53) as f64)
        };
        let pts = cut.points().to_vec();
        let mut blocked = 0;
        for _ in 0..20_000 {
            let a = [rnd(), rnd() + 10.0, 0.0];
            let b = [rnd(), rnd() + 10.0, 0.0];
            let brute = pts.windows(2).any(|w| seg_cross(a, b, w[0], w[1]));
            assert_eq!(cut.blocks(a, b), brute, "{a:?} {b:?}");
            blocked += brute as usize;
        }
        assert!(blocked > 1000, "the sample exercises the criterion: {blocked}");
        // the open tip: a line through the end itself is not blocked
        let d = [58.0, 52.0, 0.0];
        assert!(!cut.blocks([50.0, 52.0, 0.0], [66.0, 52.0, 0.0]));
        assert!(!cut.blocks([57.0, 53.0, 0.0], d));
        // a corner is closed
        assert!(cut.blocks([58.0, 82.0, 0.0], [60.0, 82.0, 0.0]));
    }

    #[test]
    fn points_on_the_cut_get_a_side() {
        let cut = Cut::path(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]).unwrap();
        let x = [0.5, 0.0, 0.0];
        let n = cut.on_cut(x).unwrap();
        assert_eq!(n, [0.0, 1.0, 0.0]);
        let (up, down) = (cut.sight(x, 1.0), cut.sight(x, -1.0));
        assert!(up[1] > 0.0 && down[1] < 0.0 && up[1] < 1e-5);
        assert!(cut.blocks(up, down) && !cut.blocks(up, [0.5, 0.3, 0.0]));
        // the corner: shifted along the mean normal, into either side of both segments
        let c = [1.0, 0.0, 0.0];
        let (a, b) = (cut.sight(c, 1.0), cut.sight(c, -1.0));
        assert!(cut.facets().iter().all(|f| f.phi(a) > 0.0 && f.phi(b) < 0.0));
        // the tip is not on the cut: it stays where it is
        assert_eq!(cut.on_cut([1.0, 1.0, 0.0]), None);
        assert_eq!(cut.sight([1.0, 1.0, 0.0], 1.0), [1.0, 1.0, 0.0]);
        // stations: both ends of each segment, tip last, no repeats
        let st = cut.stations(0.3);
        assert_eq!(st.len(), 9);
        assert_eq!(*st.last().unwrap(), [1.0, 1.0, 0.0]);
    }

    #[test]
    fn a_swept_blade_cuts_a_plane_region() {
        // the blade from (0,0,z)–(0,1,z) swept along x to x = 1: the square 0 ≤ x, y ≤ 1 at z = 0.5
        let cut = Cut::swept(&[([0.0, 0.0, 0.5], [0.0, 1.0, 0.5]), ([1.0, 0.0, 0.5], [1.0, 1.0, 0.5])]).unwrap();
        assert_eq!(cut.facets().len(), 2);
        assert!((cut.size() - 1.0).abs() < 1e-12);
        assert!(cut.blocks([0.3, 0.7, 0.2], [0.4, 0.6, 0.9]));
        assert!(cut.blocks([0.5, 0.5, 0.2], [0.5, 0.5, 0.9]), "through the diagonal of the quad");
        assert!(!cut.blocks([1.3, 0.7, 0.2], [1.4, 0.6, 0.9]), "beyond the swept region");
        assert!(!cut.blocks([0.3, 0.7, 0.6], [0.4, 0.6, 0.9]), "same side");
        assert!((cut.distance([0.5, 0.5, 0.8]) - 0.3).abs() < 1e-12);
        assert!((cut.distance([2.0, 0.5, 0.5]) - 1.0).abs() < 1e-12);
        assert!(cut.on_cut([0.2, 0.2, 0.5]).is_some());
        assert!(matches!(
            Cut::swept(&[([0.0; 3], [0.0, 1.0, 0.0]), ([0.0; 3], [0.0, 1.0, 0.0])]),
            Err(CutError::NoArea { .. })
        ));
    }
}
