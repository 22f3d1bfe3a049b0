//! Seed 001 §5 online: a reduced model at a new load position from the stored models of its
//! neighbours — interpolated basis (PODI), interpolated tangent and load, and interpolated
//! nonlinear force terms `f_p^nl` of every order — without touching the mesh.
//!
//! # The method
//! Offline, each stored model `k` keeps its basis `A_k`, its reduced tangent at the origin
//! `K_k = A_kᵀKA_k`, and the nonlinear terms of its own series from the origin,
//! `f_{p,k}^nl = K_k ζ_{p,k} − λ_{p,k} f_k` (`p = 2…N`; with the path scaled by
//! `c = 1/|K⁻¹f|` every series has `λ₁ = 1/√2`, so the terms of different positions are
//! expanded in the same parameter and can be blended). For a neighbourhood of stored models
//! the pair blocks `M_kl = A_kᵀA_l` and `K_kl = A_kᵀKA_l` are precomputed (`O(N r²)` per pair).
//!
//! Online, with weights `w_k` and the reference `0` (the heaviest): the Procrustes rotations
//! `Q_k = polar(M_k0)` align the bases; `B = Σ w_k A_k Q_k` (never formed) has Gram matrix
//! `G = Σ_kl w_k w_l Q_kᵀ M_kl Q_l = LLᵀ`, and the interpolated basis is `A = B L⁻ᵀ` (PODI made
//! orthonormal). In it
//!
//! - `K_r = L⁻¹ (Σ_kl w_k w_l Q_kᵀ K_kl Q_l) L⁻ᵀ`,
//! - `f_r = L⁻¹ Σ_k w_k Q_kᵀ (A_kᵀ F)` for the new load `F` (its reductions on the stored bases
//!   are sums over the few loaded nodes),
//! - `f_p^nl = L⁻¹ Σ_k w_k Q_kᵀ f_{p,k}^nl` (§5.3),
//! - the probe row `L⁻¹ Σ_k w_k Q_kᵀ (A_kᵀ e)`,
//!
//! then the order recursion of Eqs. 44–45 with these. Everything is `r × r` work per pair of
//! neighbours: the cost does not depend on the mesh.

use nalgebra::{DMatrix, DVector};

use super::anm::{AnmError, Series};
use super::interpolate::{InterpolationError, polar};
use crate::fem::assembly::{DofMap, SymmetricMatrix};

/// What a stored model contributes online (its basis is needed offline only).
#[derive(Debug, Clone)]
pub struct StoredModel {
    /// The basis `A_k` (`N × r`), for the pair blocks.
    pub basis: DMatrix<f64>,
    /// `K_k = A_kᵀKA_k`.
    pub tangent: DMatrix<f64>,
    /// `f_{p,k}^nl` for `p = 2…N`.
    pub nonlinear: Vec<DVector<f64>>,
}

impl StoredModel {
    /// From a stored model's basis, reduced tangent at the origin, reduced load and its series
    /// from the origin (expanded with `c = 1/|K⁻¹f|`).
    pub fn new(basis: DMatrix<f64>, tangent: DMatrix<f64>, load: &[f64], series: &Series) -> Self {
        let r = series.r;
        let f = DVector::from_column_slice(load);
        let nonlinear = (2..=series.order)
            .map(|p| {
                let z = DVector::from_column_slice(&series.zeta[(p - 1) * r..p * r]);
                &tangent * z - series.lambda[p - 1] * &f
            })
            .collect();
        Self { basis, tangent, nonlinear }
    }
}

/// The precomputed pair blocks of a neighbourhood of stored models.
#[derive(Debug, Clone)]
pub struct Neighbourhood {
    models: Vec<StoredModel>,
    m: Vec<Vec<DMatrix<f64>>>,
    k: Vec<Vec<DMatrix<f64>>>,
}

/// `A_kᵀ K A_l` with `K` assembled on the free degrees of freedom of `dofs`.
fn cross_stiffness(a: &DMatrix<f64>, b: &DMatrix<f64>, dofs: &DofMap, k: &SymmetricMatrix) -> DMatrix<f64> {
    let nf = dofs.n_free();
    let restrict = |m: &DMatrix<f64>, j: usize| {
        let mut v = vec![0.0; nf];
        dofs.restrict(m.column(j).as_slice(), &mut v);
        v
    };
    let mut kb = vec![0.0; nf];
    let mut out = DMatrix::zeros(a.ncols(), b.ncols());
    let fa: Vec<Vec<f64>> = (0..a.ncols()).map(|i| restrict(a, i)).collect();
    for j in 0..b.ncols() {
        k.mul_vec(&restrict(b, j), &mut kb);
        for (i, ai) in fa.iter().enumerate() {
            out[(i, j)] = ai.iter().zip(&kb).map(|(x, y)| x * y).sum();
        }
    }
    out
}

impl Neighbourhood {
    /// Precomputes the pair blocks (offline, `O(N r²)` per pair); `k` is the stiffness at the
    /// origin on the free degrees of freedom of `dofs`.
    pub fn new(models: Vec<StoredModel>, dofs: &DofMap, k: &SymmetricMatrix) -> Result<Self, InterpolationError> {
        if models.is_empty() || models.iter().any(|m| m.basis.shape() != models[0].basis.shape()) {
            return Err(InterpolationError::Shape(format!("{} stored models", models.len())));
        }
        let n = models.len();
        let m = (0..n)
            .map(|a| (0..n).map(|b| models[a].basis.transpose() * &models[b].basis).collect())
            .collect();
        let kk = (0..n)
            .map(|a| {
                (0..n)
                    .map(|b| cross_stiffness(&models[a].basis, &models[b].basis, dofs, k))
                    .collect()
            })
            .collect();
        Ok(Self { models, m, k: kk })
    }

    /// The interpolated series of order `order` (at most the stored models' order) for
    /// weights `w`, a load whose reductions on the stored bases are `loads[k] = A_kᵀF`, and the
    /// probe `probes[k] = A_kᵀe`; returns the series and its probe row.
    pub fn series(
        &self,
        w: &[f64],
        loads: &[DVector<f64>],
        probes: &[DVector<f64>],
        order: usize,
        tolerance: f64,
    ) -> Result<(Series, DVector<f64>), AnmError> {
        let n = self.models.len();
        if w.len() != n || loads.len() != n || probes.len() != n {
            return Err(AnmError::Invalid(format!("{n} weights, loads and probes needed")));
        }
        if order < 1 || order > self.models[0].nonlinear.len() + 1 {
            return Err(AnmError::Order(order));
        }
        let r = self.models[0].basis.ncols();
        let r0 = (0..n).max_by(|&a, &b| w[a].total_cmp(&w[b])).unwrap_or(0);
        let q: Vec<DMatrix<f64>> = (0..n).map(|k| polar(self.m[k][r0].clone())).collect();
        let (mut g, mut kr) = (DMatrix::<f64>::zeros(r, r), DMatrix::<f64>::zeros(r, r));
        for a in 0..n {
            for b in 0..n {
                let s = w[a] * w[b];
                if s != 0.0 {
                    g += s * q[a].transpose() * &self.m[a][b] * &q[b];
                    kr += s * q[a].transpose() * &self.k[a][b] * &q[b];
                }
            }
        }
        let chol = g
            .cholesky()
            .ok_or(AnmError::Invalid("the interpolated basis is rank-deficient".into()))?;
        let l = chol.l();
        let linv = l.clone().try_inverse().ok_or(AnmError::Invalid("singular Gram factor".into()))?;
        let blend = |v: &dyn Fn(usize) -> DVector<f64>| -> DVector<f64> {
            let mut s = DVector::zeros(r);
            for k in 0..n {
                if w[k] != 0.0 {
                    s += w[k] * q[k].transpose() * v(k);
                }
            }
            &linv * s
        };
        let kr = &linv * kr * linv.transpose();
        let f = blend(&|k| loads[k].clone());
        let probe = blend(&|k| probes[k].clone());
        let kchol = kr.clone().cholesky().ok_or(AnmError::Unstable { lambda: 0.0, pivot: 0 })?;
        let hat = kchol.solve(&f);
        let c2 = 1.0 / hat.norm_squared();
        let l1 = 1.0 / (c2 * hat.norm_squared() + 1.0).sqrt();
        let mut zeta = Vec::with_capacity(order * r);
        let mut lambda = Vec::with_capacity(order);
        let z1 = l1 * &hat;
        zeta.extend(z1.iter());
        lambda.push(l1);
        let mut last = (z1.norm_squared() * c2 + l1 * l1).sqrt();
        let first = last;
        for p in 2..=order {
            let fnl = blend(&|k| self.models[k].nonlinear[p - 2].clone());
            let znl = kchol.solve(&fnl);
            let lp = -l1 * c2 * znl.dot(&z1);
            let zp = lp * &hat + znl;
            last = (zp.norm_squared() * c2 + lp * lp).sqrt();
            zeta.extend(zp.iter());
            lambda.push(lp);
        }
        if zeta.iter().chain(&lambda).any(|x| !x.is_finite()) {
            return Err(AnmError::NotFinite { lambda: 0.0 });
        }
        let radius = if order > 1 && last > 0.0 {
            (tolerance * first / last).powf(1.0 / (order - 1) as f64)
        } else {
            f64::INFINITY
        };
        Ok((
            Series {
                r,
                order,
                zeta0: vec![0.0; r],
                lambda0: 0.0,
                zeta,
                lambda,
                scale: c2.sqrt(),
                radius,
            },
            probe,
        ))
    }
}
