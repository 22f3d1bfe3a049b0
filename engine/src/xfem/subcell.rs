//! Cut planes, and the integration of a cell on each side of them.
//!
//! A cut cell is integrated on sub-tetrahedra that each lie on one side of every cut plane
//! crossing it (the usual XFEM sub-cell quadrature, Moës et al. 1999). The cell is first split in
//! its reference coordinates — a tetrahedron is its own single piece; a hexahedron is cut into the
//! six Kuhn tetrahedra of the reference cube — and each piece is clipped by one plane after the
//! other, with the plane's level set `φ(x) = n·(x − p)` evaluated at the piece's vertices through
//! the cell's isoparametric map and interpolated linearly inside. On tetrahedra and on
//! parallelepipeds the map is affine and the clipping is exact; on a distorted hexahedron the
//! plane is approximated by a piecewise planar surface in the reference cube.
//!
//! Quadrature on each sub-tetrahedron: on a tetrahedral cell the strain of a linear field is
//! constant and the centroid is exact; on a hexahedral cell a 27-point conical-product rule
//! (Duffy collapse with Gauss–Jacobi factors), exact for polynomials of total degree 5, so that the trilinear stiffness integrand (degree ≤ 4
//! on a parallelepiped) is integrated exactly and the sub-cells add up to the cell's own 2×2×2
//! Gauss stiffness to rounding.

use std::sync::OnceLock;

use crate::mesh::CellKind;
use crate::mesh::shape;

/// A cut plane `φ(x) = n·(x − p) = 0`, `n` of unit length; its positive side is `φ > 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// A point of the plane.
    pub point: [f64; 3],
    /// Unit normal.
    pub normal: [f64; 3],
}

impl Plane {
    /// The signed distance `φ(x)`.
    #[inline]
    pub fn phi(&self, x: [f64; 3]) -> f64 {
        let n = self.normal;
        n[0] * (x[0] - self.point[0]) + n[1] * (x[1] - self.point[1]) + n[2] * (x[2] - self.point[2])
    }

    /// The same plane moved to pass through `x` (the node-centred planes of the cracking-node
    /// method, seed 000 §3.2.2).
    pub fn through(&self, x: [f64; 3]) -> Self {
        Self {
            point: x,
            normal: self.normal,
        }
    }
}

/// A tetrahedron of a cell's reference coordinates lying on one side of each of the planes it
/// was clipped by: bit `k` of `sides` is set when it is on the positive side of plane `k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubTet {
    /// Vertices in the cell's reference coordinates.
    pub xi: [[f64; 3]; 4],
    /// Side of each plane (bit k: positive side of plane k).
    pub sides: u32,
}

impl SubTet {
    /// Volume in reference coordinates.
    pub fn reference_volume(&self) -> f64 {
        tet_volume(&self.xi)
    }
}

fn tet_volume(v: &[[f64; 3]; 4]) -> f64 {
    let a = sub(v[1], v[0]);
    let b = sub(v[2], v[0]);
    let c = sub(v[3], v[0]);
    (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])).abs() / 6.0
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn lerp(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])]
}

/// The reference tetrahedron.
const REF_TET: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// The six Kuhn tetrahedra of the reference cube `[−1, 1]³` (sharing the diagonal from node 0
/// to node 6), as indices of [`shape::HEX_NODES`].
const HEX_KUHN: [[usize; 4]; 6] = [[0, 1, 2, 6], [0, 1, 5, 6], [0, 3, 2, 6], [0, 3, 7, 6], [0, 4, 5, 6], [0, 4, 7, 6]];

/// The physical position of reference point `xi` of a cell with node coordinates `x`.
pub fn map_point(kind: CellKind, x: &[[f64; 3]], xi: [f64; 3]) -> [f64; 3] {
    let mut out = [0.0; 3];
    match kind {
        CellKind::Tet4 => {
            let n = [1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]];
            for (na, xa) in n.iter().zip(x) {
                for i in 0..3 {
                    out[i] += na * xa[i];
                }
            }
        }
        CellKind::Hex8 => {
            let n = shape::hex_n(xi);
            for (na, xa) in n.iter().zip(x) {
                for i in 0..3 {
                    out[i] += na * xa[i];
                }
            }
        }
    }
    out
}

/// The shape-function derivatives with respect to the reference coordinates at `xi`.
pub fn reference_gradients(kind: CellKind, xi: [f64; 3], out: &mut [[f64; 3]]) {
    match kind {
        CellKind::Tet4 => out[..4].copy_from_slice(&shape::TET_DN),
        CellKind::Hex8 => out[..8].copy_from_slice(&shape::hex_dn(xi)),
    }
}

/// Level-set values below `SNAP` times the cell's size count as zero (a node on a plane).
const SNAP: f64 = 1e-10;

/// The cell's size: its largest node-to-node distance.
pub fn cell_size(x: &[[f64; 3]]) -> f64 {
    let mut h: f64 = 0.0;
    for (a, xa) in x.iter().enumerate() {
        for xb in &x[a + 1..] {
            let d = sub(*xa, *xb);
            h = h.max((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt());
        }
    }
    h
}

/// `φ` of `plane` at `p`, snapped to zero within `10⁻¹⁰ · h` (a node on the plane).
#[inline]
pub fn snapped_phi(plane: &Plane, p: [f64; 3], h: f64) -> f64 {
    let v = plane.phi(p);
    if v.abs() <= SNAP * h { 0.0 } else { v }
}

/// Splits a cell (node coordinates `x`) into sub-tetrahedra on one side of each of `planes`
/// (at most 32). Pieces of zero volume are left out. A point on a plane (φ = 0) counts as on
/// its negative side.
pub fn split(kind: CellKind, x: &[[f64; 3]], planes: &[Plane]) -> Vec<SubTet> {
    assert!(planes.len() <= 32, "at most 32 planes per cell");
    let h = cell_size(x);
    let mut tets: Vec<SubTet> = match kind {
        CellKind::Tet4 => vec![SubTet { xi: REF_TET, sides: 0 }],
        CellKind::Hex8 => HEX_KUHN
            .iter()
            .map(|t| SubTet {
                xi: t.map(|a| shape::HEX_NODES[a]),
                sides: 0,
            })
            .collect(),
    };
    let min_volume = 1e-12 * tets.iter().map(SubTet::reference_volume).sum::<f64>();
    let mut next = Vec::new();
    for (k, plane) in planes.iter().enumerate() {
        next.clear();
        for t in &tets {
            let phi = t.xi.map(|xi| snapped_phi(plane, map_point(kind, x, xi), h));
            clip(t, &phi, 1 << k, &mut next);
        }
        next.retain(|t| t.reference_volume() > min_volume);
        std::mem::swap(&mut tets, &mut next);
    }
    tets
}

/// Clips `t` by the linear function with vertex values `phi`, pushing the positive part (with
/// `bit` set) and the negative part.
fn clip(t: &SubTet, phi: &[f64; 4], bit: u32, out: &mut Vec<SubTet>) {
    let pos: Vec<usize> = (0..4).filter(|&a| phi[a] > 0.0).collect();
    let neg: Vec<usize> = (0..4).filter(|&a| phi[a] <= 0.0).collect();
    let v = t.xi;
    // the crossing on edge (a, b), a positive and b not
    let e = |a: usize, b: usize| lerp(v[a], v[b], phi[a] / (phi[a] - phi[b]));
    let with = |xi: [[f64; 3]; 4], positive: bool| SubTet {
        xi,
        sides: if positive { t.sides | bit } else { t.sides },
    };
    match pos.len() {
        0 => out.push(*t),
        4 => out.push(with(v, true)),
        1 | 3 => {
            // the lone vertex and the prism on the other side
            let (lone, rest, lone_positive) = if pos.len() == 1 {
                (pos[0], &neg, true)
            } else {
                (neg[0], &pos, false)
            };
            let ex: Vec<[f64; 3]> = rest.iter().map(|&b| if lone_positive { e(lone, b) } else { e(b, lone) }).collect();
            out.push(with([v[lone], ex[0], ex[1], ex[2]], lone_positive));
            prism([ex[0], ex[1], ex[2]], [v[rest[0]], v[rest[1]], v[rest[2]]], |xi| {
                out.push(with(xi, !lone_positive))
            });
        }
        _ => {
            let (p1, p2, n1, n2) = (pos[0], pos[1], neg[0], neg[1]);
            let (e11, e12, e21, e22) = (e(p1, n1), e(p1, n2), e(p2, n1), e(p2, n2));
            prism([v[p1], e11, e12], [v[p2], e21, e22], |xi| out.push(with(xi, true)));
            prism([v[n1], e11, e21], [v[n2], e12, e22], |xi| out.push(with(xi, false)));
        }
    }
}

/// The three tetrahedra of the prism with triangles `a` and `b` (`a_i–b_i` its lateral edges).
fn prism(a: [[f64; 3]; 3], b: [[f64; 3]; 3], mut push: impl FnMut([[f64; 3]; 4])) {
    push([a[0], a[1], a[2], b[2]]);
    push([a[0], a[1], b[1], b[2]]);
    push([a[0], b[0], b[1], b[2]]);
}

/// The `n`-point Gauss–Jacobi rule on [0, 1] for the weight `(1 − x)^α` (Golub–Welsch: the
/// eigenvalues of the Jacobi matrix of the Jacobi polynomials `P^(α,0)`): nodes and weights.
fn gauss_jacobi(n: usize, alpha: f64) -> Vec<(f64, f64)> {
    let (a, b) = (alpha, 0.0);
    let mut j = nalgebra::DMatrix::<f64>::zeros(n, n);
    for k in 0..n {
        let kf = k as f64;
        let s = 2.0 * kf + a + b;
        j[(k, k)] = if k == 0 {
            (b - a) / (a + b + 2.0)
        } else {
            (b * b - a * a) / (s * (s + 2.0))
        };
        if k + 1 < n {
            let k1 = kf + 1.0;
            let s1 = 2.0 * k1 + a + b;
            let off = (4.0 * k1 * (k1 + a) * (k1 + b) * (k1 + a + b) / (s1 * s1 * (s1 + 1.0) * (s1 - 1.0))).sqrt();
            j[(k, k + 1)] = off;
            j[(k + 1, k)] = off;
        }
    }
    let e = j.symmetric_eigen();
    // ∫_{−1}^{1} (1 − t)^α dt = 2^{α+1}/(α+1); on [0, 1] the weights scale by 2^{−(α+1)}
    let mu0 = 2f64.powf(a + 1.0) / (a + 1.0);
    let mut out: Vec<(f64, f64)> = (0..n)
        .map(|i| {
            let t = e.eigenvalues[i];
            let v = e.eigenvectors[(0, i)];
            (0.5 * (1.0 + t), mu0 * v * v / 2f64.powf(a + 1.0))
        })
        .collect();
    out.sort_by(|p, q| p.0.total_cmp(&q.0));
    out
}

/// The conical-product rule on the reference tetrahedron (Stroud): the Duffy collapse
/// `ξ = u, η = (1 − u)v, ζ = (1 − u)(1 − v)w` with 3-point Gauss–Jacobi rules for its Jacobian
/// `(1 − u)²(1 − v)` — 27 points, exact for polynomials of total degree 5. Weights sum to ⅙.
fn duffy_rule() -> &'static [([f64; 3], f64)] {
    static RULE: OnceLock<Vec<([f64; 3], f64)>> = OnceLock::new();
    RULE.get_or_init(|| {
        let (gu, gv, gw) = (gauss_jacobi(3, 2.0), gauss_jacobi(3, 1.0), gauss_jacobi(3, 0.0));
        let mut rule = Vec::with_capacity(27);
        for &(u, wu) in &gu {
            for &(v, wv) in &gv {
                for &(s, ws) in &gw {
                    rule.push(([u, (1.0 - u) * v, (1.0 - u) * (1.0 - v) * s], wu * wv * ws));
                }
            }
        }
        rule
    })
}

/// Calls `f(ξ, w)` at the quadrature points of sub-tetrahedron `t` of a cell of `kind`, with
/// reference weights `w` (summing to the reference volume of `t`; multiply by `det J`).
pub fn quadrature(kind: CellKind, t: &SubTet, mut f: impl FnMut([f64; 3], f64)) {
    let v = t.xi;
    let vol = t.reference_volume();
    match kind {
        CellKind::Tet4 => {
            let mut c = [0.0; 3];
            for p in &v {
                for i in 0..3 {
                    c[i] += 0.25 * p[i];
                }
            }
            f(c, vol);
        }
        CellKind::Hex8 => {
            let (a, b, c) = (sub(v[1], v[0]), sub(v[2], v[0]), sub(v[3], v[0]));
            for &(l, w) in duffy_rule() {
                let xi = [
                    v[0][0] + l[0] * a[0] + l[1] * b[0] + l[2] * c[0],
                    v[0][1] + l[0] * a[1] + l[1] * b[1] + l[2] * c[1],
                    v[0][2] + l[0] * a[2] + l[1] * b[2] + l[2] * c[2],
                ];
                f(xi, 6.0 * vol * w);
            }
        }
    }
}

/// Calls `f(ξ, w)` at the 27 points of the degree-5 conical-product rule on sub-tetrahedron `t`,
/// whatever the cell's kind (for integrands that are not polynomial: the branch functions of a
/// crack tip, [`super::tip`]); weights as [`quadrature`]'s.
pub fn rich_quadrature(t: &SubTet, mut f: impl FnMut([f64; 3], f64)) {
    let v = t.xi;
    let vol = t.reference_volume();
    let (a, b, c) = (sub(v[1], v[0]), sub(v[2], v[0]), sub(v[3], v[0]));
    for &(l, w) in duffy_rule() {
        let xi = std::array::from_fn(|i| v[0][i] + l[0] * a[i] + l[1] * b[i] + l[2] * c[i]);
        f(xi, 6.0 * vol * w);
    }
}

/// Calls `f(ξ, w)` at the quadrature points of a whole cell of `kind` (a cell no plane
/// crosses): the 2×2×2 Gauss rule of the hexahedron (the uncut stiffness's), the centroid of the
/// tetrahedron.
pub fn whole_cell_quadrature(kind: CellKind, mut f: impl FnMut([f64; 3], f64)) {
    match kind {
        CellKind::Tet4 => f([0.25; 3], 1.0 / 6.0),
        CellKind::Hex8 => shape::hex_gauss_2().into_iter().for_each(|p| f(p, 1.0)),
    }
}

/// The physical volumes of a cell on the positive and the negative side of `plane`.
pub fn side_volumes(kind: CellKind, x: &[[f64; 3]], plane: &Plane) -> [f64; 2] {
    let mut vols = [0.0; 2];
    let mut dn = [[0.0; 3]; 8];
    let n = kind.nodes_per_cell();
    for t in split(kind, x, std::slice::from_ref(plane)) {
        let side = if t.sides & 1 == 1 { 0 } else { 1 };
        quadrature(kind, &t, |xi, w| {
            reference_gradients(kind, xi, &mut dn);
            vols[side] += w * shape::jacobian_det(x, &dn[..n]);
        });
    }
    vols
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_hex() -> Vec<[f64; 3]> {
        shape::HEX_NODES
            .iter()
            .map(|s| [0.5 * (s[0] + 1.0), 0.5 * (s[1] + 1.0), 0.5 * (s[2] + 1.0)])
            .collect()
    }

    #[test]
    fn the_rule_integrates_degree_five_exactly() {
        // ∫_T ξ^a η^b ζ^c = a! b! c! / (a+b+c+3)!
        let fact = |n: u32| (1..=n).map(f64::from).product::<f64>();
        for (a, b, c) in [(0, 0, 0), (2, 1, 0), (1, 1, 1), (3, 2, 0), (0, 0, 5), (2, 2, 1)] {
            let exact = fact(a) * fact(b) * fact(c) / fact(a + b + c + 3);
            let got: f64 = duffy_rule()
                .iter()
                .map(|(p, w)| w * p[0].powi(a as i32) * p[1].powi(b as i32) * p[2].powi(c as i32))
                .sum();
            assert!((got - exact).abs() < 1e-15, "{a}{b}{c}: {got} vs {exact}");
        }
    }

    #[test]
    fn an_oblique_plane_splits_the_unit_cube_into_exact_volumes() {
        // the plane x + y + z = 1 cuts off the corner tetrahedron of volume 1/6
        let x = unit_hex();
        let s3 = 3f64.sqrt().recip();
        let plane = Plane {
            point: [1.0, 0.0, 0.0],
            normal: [s3, s3, s3],
        };
        let [plus, minus] = side_volumes(CellKind::Hex8, &x, &plane);
        assert!((minus - 1.0 / 6.0).abs() < 1e-14, "{minus}");
        assert!((plus - 5.0 / 6.0).abs() < 1e-14, "{plus}");
        // and on a tetrahedron the plane through the mid-edges halves the volume in 1 : 7
        let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let plane = Plane {
            point: [0.5, 0.0, 0.0],
            normal: [s3, s3, s3],
        };
        let [plus, minus] = side_volumes(CellKind::Tet4, &t, &plane);
        assert!(
            (minus - 1.0 / 48.0).abs() < 1e-15 && (plus - 7.0 / 48.0).abs() < 1e-15,
            "{minus} {plus}"
        );
    }

    #[test]
    fn two_planes_give_four_pieces_with_the_right_volumes() {
        let x = unit_hex();
        let planes = [
            Plane {
                point: [0.3, 0.0, 0.0],
                normal: [1.0, 0.0, 0.0],
            },
            Plane {
                point: [0.0, 0.0, 0.6],
                normal: [0.0, 0.0, 1.0],
            },
        ];
        let mut vols = [0.0; 4];
        let mut dn = [[0.0; 3]; 8];
        for t in split(CellKind::Hex8, &x, &planes) {
            quadrature(CellKind::Hex8, &t, |xi, w| {
                reference_gradients(CellKind::Hex8, xi, &mut dn);
                vols[t.sides as usize] += w * shape::jacobian_det(&x, &dn);
            });
        }
        let want = [0.3 * 0.6, 0.7 * 0.6, 0.3 * 0.4, 0.7 * 0.4];
        for (g, w) in vols.iter().zip(want) {
            assert!((g - w).abs() < 1e-14, "{vols:?}");
        }
    }

    #[test]
    fn a_plane_on_a_face_leaves_the_cell_whole_on_one_side() {
        let x = unit_hex();
        let plane = Plane {
            point: [0.0, 0.0, 0.0],
            normal: [0.0, 0.0, 1.0],
        };
        let pieces = split(CellKind::Hex8, &x, &[plane]);
        assert!(pieces.iter().all(|t| t.sides == 1));
        let [plus, minus] = side_volumes(CellKind::Hex8, &x, &plane);
        assert!((plus - 1.0).abs() < 1e-14 && minus == 0.0);
    }
}
