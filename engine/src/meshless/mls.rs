//! Moving-least-squares shape functions (seed 004 §3.2.2; Liu & Gu 2005, ch. 5) with a linear
//! basis and the quartic spline weight, in 2D and 3D.
//!
//! # The method
//! At a point `x`, with the linear basis `p(x) = [1, x, y(, z)]ᵀ` and the nodes `I` whose
//! influence domain (a disc or ball of radius `d_I`) contains `x`, weights
//! `w_I = w(|x − x_I| / d_I)`, `w(r̄) = 1 − 6r̄² + 8r̄³ − 3r̄⁴` for `r̄ ≤ 1` (Eq. 3.9–3.10),
//!
//! `A(x) = Σ_I w_I p(x_I) p(x_I)ᵀ`, `φ_I(x) = p(x)ᵀ A⁻¹ w_I p(x_I) = γᵀ B_I`, `γ = A⁻¹p`,
//!
//! and their derivatives `φ_I,k = γ,kᵀ B_I + γᵀ B_I,k` with `γ,k = A⁻¹(p,k − A,k γ)`,
//! `B_I,k = w_I,k p(x_I)`. The functions reproduce the basis exactly: `Σφ_I = 1`,
//! `Σφ_I x_I = x`, `Σφ_I,k x_I = e_k` (tested), but are not interpolating (`φ_I(x_J) ≠ δ_IJ`),
//! which is why essential boundary conditions need the treatment of seed 004 Eq. 3.18.
//!
//! The basis is evaluated in coordinates centred on `x` and scaled by the local support size,
//! so `A` stays well conditioned for any physical units.
//!
//! With a cut ([`crate::geometry::cut`]), a node's influence domain loses the points it cannot see
//! through the cut (the visibility criterion).

use crate::dense::{cholesky_relative, cholesky_solve};
use crate::geometry::cut::Cut;

/// The quartic spline weight `w(r̄)` and its derivative `dw/dr̄` (Eq. 3.9).
pub fn quartic_spline(r: f64) -> (f64, f64) {
    if r >= 1.0 {
        return (0.0, 0.0);
    }
    let r2 = r * r;
    (1.0 - 6.0 * r2 + 8.0 * r2 * r - 3.0 * r2 * r2, -12.0 * r + 24.0 * r2 - 12.0 * r2 * r)
}

/// Why the shape functions could not be built at a point.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MlsError {
    /// Too few nodes, or nodes all on a line (2D) or plane (3D), cover the point.
    #[error(
        "the moment matrix is singular at ({x:.4e}, {y:.4e}, {z:.4e}): {covering} node(s) cover this point, at least {needed} not all on one {flat} are needed; enlarge the influence domains"
    )]
    Singular {
        /// The point's x.
        x: f64,
        /// The point's y.
        y: f64,
        /// The point's z (0 in 2D).
        z: f64,
        /// Nodes whose support contains it.
        covering: usize,
        /// `dim + 1`.
        needed: usize,
        /// "line" or "plane".
        flat: &'static str,
    },
}

/// The shape functions at one point: the supporting nodes, `φ_I` and `∂φ_I/∂x_k`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ShapeValues {
    /// Supporting nodes.
    pub nodes: Vec<usize>,
    /// `φ_I`, one per supporting node.
    pub phi: Vec<f64>,
    /// `∂φ_I/∂x_k`, `dim` per supporting node (`[I][k]`, flat).
    pub grad: Vec<f64>,
}

impl ShapeValues {
    /// The approximation `Σ_I φ_I u_I` of a field with `dim` components per node (`u`, flat;
    /// the components beyond `dim` are 0).
    pub fn interpolate(&self, u: &[f64], dim: usize) -> [f64; 3] {
        let mut v = [0.0; 3];
        for (&i, &phi) in self.nodes.iter().zip(&self.phi) {
            for k in 0..dim {
                v[k] += phi * u[dim * i + k];
            }
        }
        v
    }

    /// The deformation gradient `F = I + Σ_I u_I ⊗ ∇φ_I` of the displacement field variables
    /// `u` (`dim` per node; in 2D, plane strain: `F₃₃ = 1`).
    pub fn deformation_gradient(&self, u: &[f64], dim: usize) -> nalgebra::Matrix3<f64> {
        let mut f = nalgebra::Matrix3::identity();
        for (a, &i) in self.nodes.iter().enumerate() {
            for k in 0..dim {
                for j in 0..dim {
                    f[(k, j)] += u[dim * i + k] * self.grad[a * dim + j];
                }
            }
        }
        f
    }
}

/// A cloud of nodes with their influence radii and a uniform bucket grid for the search.
#[derive(Debug, Clone)]
pub struct NodeCloud {
    dim: usize,
    points: Vec<[f64; 3]>,
    radius: Vec<f64>,
    lo: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    buckets: Vec<Vec<usize>>,
    /// The cut, if any, with each node's side (±1, for nodes on the cut), its sight position
    /// (see [`crate::geometry::cut`]) and whether its influence domain reaches the cut.
    cut: Option<CutState>,
}

#[derive(Debug, Clone)]
struct CutState {
    cut: Cut,
    side: Vec<f64>,
    sight: Vec<[f64; 3]>,
    near: Vec<bool>,
}

impl NodeCloud {
    /// A cloud in `dim` (2 or 3) dimensions; `radius[I]` is node `I`'s influence radius (in 2D
    /// the z coordinates are ignored).
    pub fn new(dim: usize, points: Vec<[f64; 3]>, radius: Vec<f64>) -> Self {
        assert!(dim == 2 || dim == 3, "2D or 3D");
        assert_eq!(points.len(), radius.len());
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &points {
            for k in 0..dim {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if points.is_empty() {
            (lo, hi) = ([0.0; 3], [0.0; 3]);
        }
        for k in dim..3 {
            (lo[k], hi[k]) = (0.0, 0.0);
        }
        let cell = radius.iter().copied().fold(0.0, f64::max).max(f64::MIN_POSITIVE);
        let mut dims = [1; 3];
        for k in 0..dim {
            dims[k] = (((hi[k] - lo[k]) / cell).floor() as usize + 1).min(1 << 10);
        }
        let mut buckets = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        let mut cloud = Self {
            dim,
            points,
            radius,
            lo,
            cell,
            dims,
            buckets: Vec::new(),
            cut: None,
        };
        for (i, p) in cloud.points.iter().enumerate() {
            buckets[cloud.bucket_of(p)].push(i);
        }
        cloud.buckets = buckets;
        cloud
    }

    fn coords(&self, p: &[f64; 3]) -> [usize; 3] {
        let mut c = [0; 3];
        for k in 0..self.dim {
            let v = ((p[k] - self.lo[k]) / self.cell).floor();
            c[k] = if v.is_nan() || v < 0.0 {
                0
            } else {
                (v as usize).min(self.dims[k] - 1)
            };
        }
        c
    }

    fn bucket_of(&self, p: &[f64; 3]) -> usize {
        let c = self.coords(p);
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// Space dimension.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the cloud is empty.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Node positions.
    pub fn points(&self) -> &[[f64; 3]] {
        &self.points
    }

    /// Node influence radii.
    pub fn radii(&self) -> &[f64] {
        &self.radius
    }

    /// The cut, if any.
    pub fn cut(&self) -> Option<&Cut> {
        self.cut.as_ref().map(|c| &c.cut)
    }

    /// The side (±1) of each node with respect to the cut (+1 without one); it matters only
    /// for nodes on the cut.
    pub fn sides(&self) -> Option<&[f64]> {
        self.cut.as_ref().map(|c| c.side.as_slice())
    }

    /// The same nodes seen through `cut` (replacing any earlier one); `side[I]` (±1) allocates
    /// node `I` to one face when it lies on the cut (seed 004 Fig. 4.3).
    pub fn with_cut(mut self, cut: Cut, side: Vec<f64>) -> Self {
        assert_eq!(side.len(), self.points.len(), "one side per node");
        assert_eq!(cut.dim(), self.dim, "cut and cloud of one dimension");
        let sight: Vec<[f64; 3]> = self.points.iter().zip(&side).map(|(p, &s)| cut.sight(*p, s)).collect();
        // Eq. 4.14: the nodes whose influence domain reaches the cut
        let near = self.points.iter().zip(&self.radius).map(|(p, &r)| cut.distance(*p) < r).collect();
        self.cut = Some(CutState { cut, side, sight, near });
        self
    }

    /// Where node `i` looks from, for the visibility criterion.
    fn sight_of(&self, i: usize) -> [f64; 3] {
        self.cut.as_ref().map_or(self.points[i], |c| c.sight[i])
    }

    /// Nodes whose influence domain contains `x` and, when there is a cut, that see `x`
    /// (sorted).
    pub fn covering(&self, x: [f64; 3], out: &mut Vec<usize>) {
        let sight = self.cut.as_ref().map_or(x, |c| c.cut.sight(x, 1.0));
        self.covering_seen(x, sight, out);
    }

    /// [`NodeCloud::covering`] with the visibility judged from `sight` (`x` itself, or `x`
    /// shifted off the cut to one of its faces).
    fn covering_seen(&self, x: [f64; 3], sight: [f64; 3], out: &mut Vec<usize>) {
        out.clear();
        let c = self.coords(&x);
        let range = |k: usize| {
            if k < self.dim {
                c[k].saturating_sub(1)..=(c[k] + 1).min(self.dims[k] - 1)
            } else {
                0..=0
            }
        };
        for bz in range(2) {
            for by in range(1) {
                for bx in range(0) {
                    for &i in &self.buckets[(bz * self.dims[1] + by) * self.dims[0] + bx] {
                        let d2: f64 = (0..self.dim).map(|k| (x[k] - self.points[i][k]).powi(2)).sum();
                        if d2 < self.radius[i] * self.radius[i] && self.visible(i, sight) {
                            out.push(i);
                        }
                    }
                }
            }
        }
        out.sort_unstable();
    }

    /// Eqs. 4.15–4.17: whether node `i` sees a point whose sight position is `sight`.
    fn visible(&self, i: usize, sight: [f64; 3]) -> bool {
        match &self.cut {
            Some(c) if c.near[i] => !c.cut.blocks(c.sight[i], sight),
            _ => true,
        }
    }

    /// The shape functions and their gradients at `x` into `out` (a point on the cut is
    /// allocated to the positive face).
    pub fn shape(&self, x: [f64; 3], out: &mut ShapeValues) -> Result<(), MlsError> {
        self.shape_on_side(x, 1.0, out)
    }

    /// The shape functions at node `i`'s position, on node `i`'s face of the cut.
    pub fn shape_at_node(&self, i: usize, out: &mut ShapeValues) -> Result<(), MlsError> {
        self.shape_seen(self.points[i], self.sight_of(i), out)
    }

    /// The shape functions at `x` on the face `side` (±1) of the cut.
    pub fn shape_on_side(&self, x: [f64; 3], side: f64, out: &mut ShapeValues) -> Result<(), MlsError> {
        let sight = self.cut.as_ref().map_or(x, |c| c.cut.sight(x, side));
        self.shape_seen(x, sight, out)
    }

    fn shape_seen(&self, x: [f64; 3], sight: [f64; 3], out: &mut ShapeValues) -> Result<(), MlsError> {
        let dim = self.dim;
        let m = dim + 1;
        self.covering_seen(x, sight, &mut out.nodes);
        let n = out.nodes.len();
        // local coordinates: centred on x, scaled by the mean support radius
        let h = if n > 0 {
            out.nodes.iter().map(|&i| self.radius[i]).sum::<f64>() / n as f64
        } else {
            1.0
        };
        let singular = |covering| MlsError::Singular {
            x: x[0],
            y: x[1],
            z: x[2],
            covering,
            needed: m,
            flat: if dim == 2 { "line" } else { "plane" },
        };
        if n < m {
            return Err(singular(n));
        }
        // per node: w, ∂w/∂x_k (physical), p(x_I) in local coordinates
        let mut a = [[0.0; 4]; 4];
        let mut da = [[[0.0; 4]; 4]; 3];
        let mut ws = Vec::with_capacity(n);
        for &i in &out.nodes {
            let mut pi = [1.0, 0.0, 0.0, 0.0];
            let mut dist2 = 0.0;
            for k in 0..dim {
                pi[k + 1] = (self.points[i][k] - x[k]) / h;
                dist2 += (self.points[i][k] - x[k]).powi(2);
            }
            let dist = dist2.sqrt();
            let (w, dw) = quartic_spline(dist / self.radius[i]);
            // ∂w/∂x_k = dw/dr̄ · (x_k − x_Ik) / (|x − x_I| d_I)
            let mut dwx = [0.0; 3];
            if dist > 0.0 {
                for k in 0..dim {
                    dwx[k] = dw * (x[k] - self.points[i][k]) / (dist * self.radius[i]);
                }
            }
            for r in 0..m {
                for c in 0..m {
                    a[r][c] += w * pi[r] * pi[c];
                    for k in 0..dim {
                        da[k][r][c] += dwx[k] * pi[r] * pi[c];
                    }
                }
            }
            ws.push((w, dwx, pi));
        }
        // The basis in a frame centred on x: p(y) = [1, (y − x)/h] (an affine change of basis
        // leaves the MLS functions unchanged). At y = x, p = e₀ and ∂p/∂y_k = e_{k+1}/h; the
        // frame is held fixed while differentiating, so A,k comes from the weights alone.
        // one factorisation of A for γ and its derivatives; a relative pivot floor reports
        // nodes (nearly) on a line or plane as singular instead of inverting noise
        let mut l = [0.0; 16];
        for r in 0..m {
            for c in 0..m {
                l[r * m + c] = a[r][c];
            }
        }
        cholesky_relative(&mut l[..m * m], m, 1e-12).map_err(|_| singular(n))?;
        let mut gamma = [0.0; 4];
        gamma[0] = 1.0;
        cholesky_solve(&l[..m * m], m, &mut gamma[..m]);
        let mut dgamma = [[0.0; 4]; 3];
        for k in 0..dim {
            // A γ,k = p,k − A,k γ
            let rhs = &mut dgamma[k];
            rhs[k + 1] = 1.0 / h;
            for r in 0..m {
                rhs[r] -= (0..m).map(|c| da[k][r][c] * gamma[c]).sum::<f64>();
            }
            cholesky_solve(&l[..m * m], m, &mut rhs[..m]);
        }
        out.phi.clear();
        out.grad.clear();
        for (w, dwx, pi) in ws {
            let gp: f64 = (0..m).map(|r| gamma[r] * pi[r]).sum();
            out.phi.push(w * gp);
            for k in 0..dim {
                let dgp: f64 = (0..m).map(|r| dgamma[k][r] * pi[r]).sum();
                out.grad.push(w * dgp + dwx[k] * gp);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_cloud(dim: usize, n: usize, spacing: f64, factor: f64, jitter: f64) -> NodeCloud {
        let mut pts = Vec::new();
        let mut s: u64 = 12345;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let nz = if dim == 3 { n } else { 1 };
        for k in 0..nz {
            for j in 0..n {
                for i in 0..n {
                    let mut p = [
                        i as f64 * spacing,
                        j as f64 * spacing,
                        if dim == 3 { k as f64 * spacing } else { 0.0 },
                    ];
                    for q in p.iter_mut().take(dim) {
                        *q += jitter * spacing * rnd();
                    }
                    pts.push(p);
                }
            }
        }
        let r = vec![factor * spacing; pts.len()];
        NodeCloud::new(dim, pts, r)
    }

    #[test]
    fn the_weight_is_the_quartic_spline() {
        assert_eq!(quartic_spline(0.0), (1.0, 0.0));
        assert_eq!(quartic_spline(1.0), (0.0, 0.0));
        let (w, dw) = quartic_spline(0.5);
        assert!((w - (1.0 - 1.5 + 1.0 - 0.1875)).abs() < 1e-15);
        let h = 1e-6;
        assert!((dw - (quartic_spline(0.5 + h).0 - quartic_spline(0.5 - h).0) / (2.0 * h)).abs() < 1e-8);
        // C¹ at the edge of the support
        assert!(quartic_spline(1.0 - 1e-6).1.abs() < 1e-9);
    }

    #[test]
    fn shape_functions_reproduce_linear_fields_and_their_gradients() {
        for dim in [2, 3] {
            // an irregular cloud in physical units of metres (millimetre spacing)
            let cloud = grid_cloud(dim, 6, 1e-3, 2.2, 0.4);
            let mut s = ShapeValues::default();
            for x in [[2.3e-3, 1.7e-3, 2.9e-3], [0.4e-3, 4.1e-3, 1.1e-3], [2.5e-3, 2.5e-3, 2.5e-3]] {
                cloud.shape(x, &mut s).unwrap();
                let sum: f64 = s.phi.iter().sum();
                assert!((sum - 1.0).abs() < 1e-12, "partition of unity: {sum}");
                for j in 0..dim {
                    let v: f64 = s.nodes.iter().zip(&s.phi).map(|(&i, f)| f * cloud.points()[i][j]).sum();
                    assert!((v - x[j]).abs() < 1e-15, "reproduces x_{j}: {v} vs {}", x[j]);
                    for k in 0..dim {
                        let g: f64 = s
                            .nodes
                            .iter()
                            .enumerate()
                            .map(|(a, &i)| s.grad[a * dim + k] * cloud.points()[i][j])
                            .sum();
                        let expected = if j == k { 1.0 } else { 0.0 };
                        assert!((g - expected).abs() < 1e-9, "∂x_{j}/∂x_{k} = {g}");
                    }
                }
                let gsum: Vec<f64> = (0..dim).map(|k| (0..s.nodes.len()).map(|a| s.grad[a * dim + k]).sum()).collect();
                assert!(gsum.iter().all(|g| g.abs() < 1e-6), "Σ∂φ = 0: {gsum:?}");
            }
        }
    }

    #[test]
    fn gradients_match_finite_differences() {
        let cloud = grid_cloud(2, 7, 0.01, 2.5, 0.3);
        let x = [0.031, 0.027, 0.0];
        let mut s = ShapeValues::default();
        cloud.shape(x, &mut s).unwrap();
        let h = 1e-7;
        for k in 0..2 {
            let (mut xp, mut xm) = (x, x);
            xp[k] += h;
            xm[k] -= h;
            let (mut sp, mut sm) = (ShapeValues::default(), ShapeValues::default());
            cloud.shape(xp, &mut sp).unwrap();
            cloud.shape(xm, &mut sm).unwrap();
            assert_eq!(sp.nodes, s.nodes, "same support nearby");
            for a in 0..s.nodes.len() {
                let fd = (sp.phi[a] - sm.phi[a]) / (2.0 * h);
                assert!(
                    (fd - s.grad[a * 2 + k]).abs() < 1e-5 * (1.0 + fd.abs()),
                    "node {a}, k {k}: {fd} vs {}",
                    s.grad[a * 2 + k]
                );
            }
        }
    }

    #[test]
    fn too_small_supports_are_reported_not_inverted() {
        let cloud = grid_cloud(2, 4, 1.0, 0.9, 0.0);
        let mut s = ShapeValues::default();
        let e = cloud.shape([1.0, 1.0, 0.0], &mut s).unwrap_err();
        assert!(e.to_string().contains("enlarge the influence domains"), "{e}");
        // collinear nodes in 2D
        let line = NodeCloud::new(2, (0..5).map(|i| [i as f64, 0.0, 0.0]).collect(), vec![3.0; 5]);
        assert!(matches!(line.shape([2.0, 0.1, 0.0], &mut s), Err(MlsError::Singular { .. })));
    }
}
