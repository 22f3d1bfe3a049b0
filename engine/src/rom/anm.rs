//! The asymptotic numerical method in reduced coordinates (seed 001 §3–4, Eqs. 25–45).
//!
//! # The method
//! Equilibrium of the reduced St Venant–Kirchhoff model ([`ReducedSvk`]) under a load
//! `λ f` is `g(ζ) = λ f`. Around a known equilibrium `(ζ⁰, λ⁰)` the branch is sought as a
//! power series of a path parameter `a` (Eq. 25, in reduced coordinates Eq. 40):
//!
//! `ζ(a) = ζ⁰ + Σ_{p=1}^{N} a^p ζ_p`,  `λ(a) = λ⁰ + Σ_{p=1}^{N} a^p λ_p`.
//!
//! Since `g` is a cubic polynomial, `g(ζ⁰ + v) = g(ζ⁰) + K_t v + B(v,v) + K₃(v,v,v)` with the
//! one tangent `K_t = ∂g/∂ζ(ζ⁰)` and `B = K₂ + 3K₃(ζ⁰)`. Equating powers of `a` gives a linear
//! problem per order with the same `K_t` (Eqs. 42–45):
//!
//! - order 1: `K_t ζ̂ = f`, `λ₁ = 1/√(c²|ζ̂|² + 1)`, `ζ₁ = λ₁ ζ̂`;
//! - order p: `f_p^nl = −Σ_{i+j=p} B(ζ_i, ζ_j) − Σ_{i+j+k=p} K₃(ζ_i, ζ_j, ζ_k)`,
//!   `ζ_p^nl = K_t⁻¹ f_p^nl`, `λ_p = −λ₁ c² ζ_p^nlᵀ ζ₁`, `ζ_p = λ_p ζ̂ + ζ_p^nl`,
//!
//! where the path parameter is the pseudo arc length `a = c² (ζ − ζ⁰)ᵀζ₁ + (λ − λ⁰)λ₁`
//! (the seed's Eq. 42 constraint). The seed writes it with `c = 1`; with displacements in
//! metres that makes `a` the load factor and nothing else, so here `c` scales the reduced
//! displacement to the size of the linear response to the full load (`c = 1/|K₁⁻¹f|`), the
//! usual ANM practice, and the series can follow the branch through stiffening as well as
//! softening.
//!
//! # Validity radius and continuation
//! A truncated series is accurate for `a ≤ a_max = (δ ‖w₁‖/‖w_N‖)^{1/(N−1)}`, with `w_p =
//! (cζ_p, λ_p)` and `δ` the accepted size of the first neglected term relative to the first
//! (Cochelin, Damil & Potier-Ferry 1994 — seed 001's Ref. 16). [`continuation`] starts a new
//! series at the end of each radius — one tangent factorization per step — until the target
//! load. The one-step use of seed 001 §6 (one series from the unloaded state, tangent at the
//! origin) is [`Series`] evaluated past its radius, which is where its error grows.

use super::pod::dot;
use super::svk::ReducedSvk;
use crate::dense::{cholesky, cholesky_solve};

/// Highest order supported.
pub const MAX_ORDER: usize = 8;

/// Settings of the asymptotic expansion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnmParams {
    /// Truncation order `N` (1…8).
    pub order: usize,
    /// `δ` of the validity radius: the accepted relative size of the last term.
    pub tolerance: f64,
    /// Continuation steps before giving up.
    pub max_steps: usize,
}

impl Default for AnmParams {
    /// Order 6 (seed 001's most accurate), `δ = 10⁻⁶`, 100 steps.
    fn default() -> Self {
        Self {
            order: 6,
            tolerance: 1e-6,
            max_steps: 100,
        }
    }
}

/// Why the branch could not be followed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnmError {
    /// The order is not in 1…8.
    #[error("the ANM order must be in 1..={MAX_ORDER} (got {0})")]
    Order(usize),
    /// The load or the start is malformed.
    #[error("{0}")]
    Invalid(String),
    /// The reduced tangent stopped being positive definite.
    #[error(
        "the reduced tangent is not positive definite at load factor {lambda:.4} (pivot {pivot}): a material or structural instability (St Venant-Kirchhoff softens and collapses in strong compression) or a rigid motion the basis allows"
    )]
    Unstable {
        /// Load factor of the last equilibrium.
        lambda: f64,
        /// The failing pivot.
        pivot: usize,
    },
    /// The load factor stops growing along the branch.
    #[error(
        "the equilibrium path turns back at load factor {lambda:.4} (dλ/da = {slope:.3e}): a limit point, the model cannot carry more load"
    )]
    LimitPoint {
        /// Load factor reached.
        lambda: f64,
        /// `λ₁` of the series there.
        slope: f64,
    },
    /// The validity radius collapsed or the steps ran out.
    #[error(
        "the series' validity radius fell to {radius:.2e} at load factor {lambda:.4} after {steps} steps: the branch is too curved here (a bifurcation or a nearly singular tangent)"
    )]
    Stalled {
        /// Load factor reached.
        lambda: f64,
        /// The last radius.
        radius: f64,
        /// Steps taken.
        steps: usize,
    },
    /// A coefficient was not finite.
    #[error("a series coefficient is not finite at load factor {lambda:.4}")]
    NotFinite {
        /// Load factor of the start of the series.
        lambda: f64,
    },
}

/// One asymptotic expansion around an equilibrium.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Reduced size `r`.
    pub r: usize,
    /// Truncation order `N`.
    pub order: usize,
    /// The start `ζ⁰`.
    pub zeta0: Vec<f64>,
    /// The start `λ⁰`.
    pub lambda0: f64,
    /// `ζ_1 … ζ_N`, `N × r`.
    pub zeta: Vec<f64>,
    /// `λ_1 … λ_N`.
    pub lambda: Vec<f64>,
    /// The displacement scale `c` of the path parameter.
    pub scale: f64,
    /// Validity radius `a_max`.
    pub radius: f64,
}

impl Series {
    /// Expands the branch of `g(ζ) = λ f` around the equilibrium `(zeta0, lambda0)` to order
    /// `order` (see the [module docs](self)); the radius uses `tolerance`.
    pub fn expand(
        model: &ReducedSvk,
        f: &[f64],
        zeta0: &[f64],
        lambda0: f64,
        order: usize,
        scale: f64,
        tolerance: f64,
    ) -> Result<Self, AnmError> {
        let r = model.r;
        if !(1..=MAX_ORDER).contains(&order) {
            return Err(AnmError::Order(order));
        }
        if f.len() != r || zeta0.len() != r {
            return Err(AnmError::Invalid(format!("the load and the start need {r} reduced coordinates")));
        }
        // one more term than kept when N = 1, for the radius
        let terms = order.max(2);
        let mut kt = vec![0.0; r * r];
        model.tangent(zeta0, &mut kt);
        cholesky(&mut kt, r).map_err(|pivot| AnmError::Unstable { lambda: lambda0, pivot })?;
        let mut hat = f.to_vec();
        cholesky_solve(&kt, r, &mut hat);
        let c2 = scale * scale;
        let l1 = 1.0 / (c2 * dot(&hat, &hat) + 1.0).sqrt();
        // M_0 = B = K₂ + 3K₃(ζ⁰); M_k = K₃(·,·,·,ζ_k): N_p = Σ_k Σ_{i+j=p−k} M_k(ζ_i, ζ_j)
        let r3 = r * r * r;
        let mut m = vec![0.0; (terms - 1) * r3];
        model.bilinear_at(zeta0, &mut m[..r3]);
        let mut zeta = vec![0.0; terms * r];
        let mut lambda = vec![0.0; terms];
        lambda[0] = l1;
        for (z, h) in zeta[..r].iter_mut().zip(&hat) {
            *z = l1 * h;
        }
        let mut np = vec![0.0; r];
        for p in 2..=terms {
            if p - 1 < terms - 1 {
                // M_{p−1} from ζ_{p−1}, needed from order p + 1 on
                let (_, rest) = m.split_at_mut((p - 1) * r3);
                let zp = &zeta[(p - 2) * r..(p - 1) * r];
                rest[..r3].fill(0.0);
                model.k3_contract_add(zp, 1.0, &mut rest[..r3]);
            }
            np.fill(0.0);
            for k in 0..=p - 2 {
                let mk = &m[k * r3..(k + 1) * r3];
                for i in 1..p - k {
                    let j = p - k - i;
                    let (zi, zj) = (&zeta[(i - 1) * r..i * r], &zeta[(j - 1) * r..j * r]);
                    for (o, slab) in np.iter_mut().zip(mk.chunks_exact(r * r)) {
                        let mut s = 0.0;
                        for (a, row) in slab.chunks_exact(r).enumerate() {
                            s += zi[a] * dot(row, zj);
                        }
                        *o += s;
                    }
                }
            }
            // ζ_p^nl = −K_t⁻¹ N_p
            for v in np.iter_mut() {
                *v = -*v;
            }
            cholesky_solve(&kt, r, &mut np);
            let lp = -l1 * c2 * dot(&np, &zeta[..r]);
            lambda[p - 1] = lp;
            for (q, z) in zeta[(p - 1) * r..p * r].iter_mut().enumerate() {
                *z = lp * hat[q] + np[q];
            }
        }
        if zeta.iter().chain(&lambda).any(|x| !x.is_finite()) {
            return Err(AnmError::NotFinite { lambda: lambda0 });
        }
        let w = |p: usize| (c2 * dot(&zeta[(p - 1) * r..p * r], &zeta[(p - 1) * r..p * r]) + lambda[p - 1].powi(2)).sqrt();
        let last = w(terms);
        let radius = if last > 0.0 {
            (tolerance * w(1) / last).powf(1.0 / (terms - 1) as f64)
        } else {
            f64::INFINITY
        };
        zeta.truncate(order * r);
        lambda.truncate(order);
        Ok(Self {
            r,
            order,
            zeta0: zeta0.to_vec(),
            lambda0,
            zeta,
            lambda,
            scale,
            radius,
        })
    }

    /// `ζ(a)` into `out`; returns `λ(a)` (Horner).
    pub fn eval(&self, a: f64, out: &mut [f64]) -> f64 {
        let r = self.r;
        out.fill(0.0);
        let mut l = 0.0;
        for p in (1..=self.order).rev() {
            let zp = &self.zeta[(p - 1) * r..p * r];
            for (o, z) in out.iter_mut().zip(zp) {
                *o = (*o + z) * a;
            }
            l = (l + self.lambda[p - 1]) * a;
        }
        for (o, z) in out.iter_mut().zip(&self.zeta0) {
            *o += z;
        }
        self.lambda0 + l
    }

    /// `λ(a)`.
    pub fn load(&self, a: f64) -> f64 {
        self.lambda0 + self.lambda.iter().rev().fold(0.0, |l, lp| (l + lp) * a)
    }

    /// The smallest `a ∈ [0, a_hi]` with `λ(a) = target`, or `None` when the series does not
    /// reach it there (a scan for the first sign change, then bisection).
    pub fn solve_load(&self, target: f64, a_hi: f64) -> Option<f64> {
        let h = |a: f64| self.load(a) - target;
        if h(0.0) == 0.0 {
            return Some(0.0);
        }
        const SCAN: usize = 64;
        let mut lo = 0.0;
        let mut hlo = h(0.0);
        for k in 1..=SCAN {
            let hi = a_hi * k as f64 / SCAN as f64;
            let hhi = h(hi);
            if hhi.is_nan() {
                return None;
            }
            if (hlo < 0.0) != (hhi < 0.0) || hhi == 0.0 {
                let (mut a, mut b, mut ha) = (lo, hi, hlo);
                for _ in 0..80 {
                    let mid = 0.5 * (a + b);
                    let hm = h(mid);
                    if (ha < 0.0) == (hm < 0.0) {
                        (a, ha) = (mid, hm);
                    } else {
                        b = mid;
                    }
                }
                return Some(0.5 * (a + b));
            }
            (lo, hlo) = (hi, hhi);
        }
        None
    }
}

/// A branch followed by continuation: one [`Series`] per step, from the unloaded state.
#[derive(Debug, Clone, PartialEq)]
pub struct Path {
    /// The steps; step `k` covers `a ∈ [0, ends[k]]` of its series.
    pub steps: Vec<Series>,
    /// Where each step's series was cut (its radius, or the target on the last).
    pub ends: Vec<f64>,
    /// Relative residual `‖g(ζ) − λf‖/‖λf‖` at the end of each step.
    pub residuals: Vec<f64>,
}

/// The scale `c = 1/|K₁⁻¹ f|` of the path parameter.
pub fn displacement_scale(model: &ReducedSvk, f: &[f64]) -> Result<f64, AnmError> {
    let r = model.r;
    let mut k = model.k1.clone();
    cholesky(&mut k, r).map_err(|pivot| AnmError::Unstable { lambda: 0.0, pivot })?;
    let mut u = f.to_vec();
    cholesky_solve(&k, r, &mut u);
    let n = dot(&u, &u).sqrt();
    if n.is_nan() || n <= 0.0 || !n.is_finite() {
        return Err(AnmError::Invalid("the reduced load is zero or not finite".into()));
    }
    Ok(1.0 / n)
}

/// Follows the branch of `g(ζ) = λ f` from `ζ = 0` to `λ = target` by continuation (see the
/// [module docs](self)).
pub fn continuation(model: &ReducedSvk, f: &[f64], target: f64, params: &AnmParams) -> Result<Path, AnmError> {
    let r = model.r;
    if !(target.is_finite() && target > 0.0) {
        return Err(AnmError::Invalid(format!("the target load factor must be positive (got {target})")));
    }
    if !(params.tolerance > 0.0 && params.tolerance < 1.0) {
        return Err(AnmError::Invalid("the ANM tolerance must be in (0, 1)".into()));
    }
    let scale = displacement_scale(model, f)?;
    let mut path = Path {
        steps: Vec::new(),
        ends: Vec::new(),
        residuals: Vec::new(),
    };
    let (mut zeta, mut lambda) = (vec![0.0; r], 0.0);
    let mut g = vec![0.0; r];
    let min_radius = 1e-9;
    while path.steps.len() < params.max_steps {
        let s = Series::expand(model, f, &zeta, lambda, params.order, scale, params.tolerance)?;
        if s.lambda[0] <= 0.0 || s.load(s.radius) <= lambda {
            return Err(AnmError::LimitPoint {
                lambda,
                slope: s.lambda[0],
            });
        }
        if s.radius < min_radius {
            return Err(AnmError::Stalled {
                lambda,
                radius: s.radius,
                steps: path.steps.len(),
            });
        }
        let radius = s.radius.min(1e6);
        let end = s.solve_load(target, radius);
        let a = end.unwrap_or(radius);
        lambda = s.eval(a, &mut zeta);
        if zeta.iter().any(|z| !z.is_finite()) || !lambda.is_finite() {
            return Err(AnmError::NotFinite { lambda: s.lambda0 });
        }
        model.force(&zeta, &mut g);
        let res: f64 = g.iter().zip(f).map(|(gi, fi)| (gi - lambda * fi).powi(2)).sum::<f64>().sqrt();
        path.residuals.push(res / (lambda.abs() * dot(f, f).sqrt()));
        path.steps.push(s);
        path.ends.push(a);
        if end.is_some() {
            return Ok(path);
        }
    }
    Err(AnmError::Stalled {
        lambda,
        radius: path.steps.last().map_or(0.0, |s| s.radius),
        steps: path.steps.len(),
    })
}

impl Path {
    /// The reduced state at load factor `lambda` (between 0 and the path's end) into `out`;
    /// `false` when the path does not reach it.
    pub fn at_load(&self, lambda: f64, out: &mut [f64]) -> bool {
        let last = self.steps.len().saturating_sub(1);
        for (k, (s, &end)) in self.steps.iter().zip(&self.ends).enumerate() {
            let top = s.load(end);
            if lambda <= top
                && let Some(a) = s.solve_load(lambda, end)
            {
                s.eval(a, out);
                return true;
            }
            // the last step ends on its target up to the bisection's round-off
            if k == last && (lambda - top).abs() <= 1e-12 * lambda.abs().max(1.0) {
                s.eval(end, out);
                return true;
            }
        }
        false
    }

    /// Load factor at the end of the path.
    pub fn end_load(&self) -> f64 {
        match (self.steps.last(), self.ends.last()) {
            (Some(s), Some(&a)) => s.load(a),
            _ => 0.0,
        }
    }
}

/// Reduced Newton–Raphson for `g(ζ) = λ f` (load steps of `1/steps`, relative tolerance
/// `tol`): the exact equilibrium of the reduced model, against which the ANM truncation is
/// measured apart from the POD error.
pub fn newton(model: &ReducedSvk, f: &[f64], lambda: f64, steps: usize, tol: f64) -> Result<Vec<f64>, AnmError> {
    let r = model.r;
    let mut zeta = vec![0.0; r];
    let (mut g, mut k) = (vec![0.0; r], vec![0.0; r * r]);
    let fnorm = dot(f, f).sqrt();
    for s in 1..=steps.max(1) {
        let l = lambda * s as f64 / steps.max(1) as f64;
        let mut converged = false;
        for _ in 0..50 {
            model.force(&zeta, &mut g);
            for (gi, fi) in g.iter_mut().zip(f) {
                *gi = l * fi - *gi;
            }
            if dot(&g, &g).sqrt() <= tol * l.abs() * fnorm {
                converged = true;
                break;
            }
            model.tangent(&zeta, &mut k);
            cholesky(&mut k, r).map_err(|pivot| AnmError::Unstable { lambda: l, pivot })?;
            cholesky_solve(&k, r, &mut g);
            for (z, d) in zeta.iter_mut().zip(&g) {
                *z += d;
            }
            if zeta.iter().any(|z| !z.is_finite()) {
                return Err(AnmError::NotFinite { lambda: l });
            }
        }
        if !converged {
            return Err(AnmError::Stalled {
                lambda: l,
                radius: 0.0,
                steps: s,
            });
        }
    }
    Ok(zeta)
}
