//! The PGD vademecum of the displacement increment over the POD coefficients of the damage
//! (seed 000 §4.5.2–4.5.4, the simplified model h = 0).
//!
//! # The parametric problem
//! With `g = Σ_K ξ_K υ_K` at the tearable points, the secant stiffness is affine in `ξ`:
//! `K(ξ) = K₀ + Σ_K ξ_K K_K` with `K_K = ∫ υ_K Bᵀ C⁰ B dΩ` over the tearable material (Eq. 4.21)
//! and `K₀` the stiffness of the material that never damages (the gallbladder of §4.6.2) and
//! of elastic supports. The right-hand side of a unit step is `b(ξ) = b₀ + Σ_K ξ_K b_K`: the
//! load increment, and `−K_fc(ξ) ∆ū` for prescribed displacement increments (affine too). The
//! vademecum is the separated solution of `K(ξ) ∆u(ξ) = b(ξ)` for every `ξ` of the box,
//! weakly in `ξ` (Eq. 4.16):
//! `∆u(x; ξ₁ … ξ_q) ≈ Σ_i F_i(x) Π_K G_K^i(ξ_K)` (Eq. 4.17).
//!
//! # The builder (greedy enrichment, alternating fixed point)
//! Each new mode `R(x) Π S_K(ξ_K)` is found by alternating directions: with the `S_K` known,
//! `R` solves the sparse system `[Σ_j c_j K_j] R = Σ_j e_j b_j − Σ_i Σ_j d_ij K_j F_i` (Eq. 4.20,
//! with `c_j, e_j, d_ij` products of one-dimensional integrals, `ξ_j` weighting the `j`-th);
//! with `R` and the other `S` known, `S_a` solves a one-dimensional problem (§4.5.4.2). The
//! one-dimensional functions are piecewise linear on a uniform grid of each `ξ_K` range,
//! integrated by the trapezoidal (nodal) rule, so that each `S_a` problem is diagonal: one
//! division per grid node. Each `S_K` is normalised, `R` carries the mode's amplitude;
//! enrichment stops when a new mode's amplitude falls below `tolerance` times the first
//! one's, or at `max_modes`. All `K_j` share one sparsity pattern and one symbolic
//! factorization.
//!
//! # Online
//! `∆u(ξ)` is `Σ_i F_i Π_K G_K^i(ξ_K)`, the `G` interpolated linearly between grid nodes: a
//! coefficient outside its range is clamped to it and reported (never extrapolated).

use std::time::Instant;

use super::model::TearModel;
use super::pod::DamageBasis;
use crate::fem::assembly::{SymmetricMatrix, add_springs};
use crate::solve::{Cholesky, SolveError};

/// `K(ξ) = K₀ + Σ ξ_K K_K`, `b(ξ) = b₀ + Σ ξ_K b_K` over the free dofs.
#[derive(Debug, Clone)]
pub struct AffineSystem {
    /// `K₀, K₁ … K_q`.
    pub ops: Vec<SymmetricMatrix>,
    /// `b₀, b₁ … b_q` (a unit step).
    pub rhs: Vec<Vec<f64>>,
}

impl AffineSystem {
    /// `K_j r` for each affine operator `K_j`.
    fn apply_each(&self, r: &[f64]) -> Vec<Vec<f64>> {
        self.ops
            .iter()
            .map(|o| {
                let mut v = vec![0.0; r.len()];
                o.mul_vec(r, &mut v);
                v
            })
            .collect()
    }

    /// The affine system of `model` over the damage basis.
    pub fn of(model: &TearModel, basis: &DamageBasis) -> Self {
        let nf = model.dofs.n_free();
        let mut index = vec![None; model.points.len()];
        for (i, &p) in model.points.tearable.iter().enumerate() {
            index[p] = Some(i);
        }
        let assemble = |coef: &dyn Fn(usize) -> f64, rhs: &mut Vec<f64>| {
            model.points.assemble(
                &model.mesh,
                &model.dofs,
                model.pattern.clone(),
                coef,
                |_| None,
                Some(&model.prescribed),
                rhs,
            )
        };
        let mut b0 = vec![0.0; nf];
        model.dofs.restrict(&model.load, &mut b0);
        let mut k0 = assemble(&|p| if index[p].is_some() { 0.0 } else { 1.0 }, &mut b0);
        add_springs(&mut k0, &model.dofs, &model.springs);
        let (mut ops, mut rhs) = (vec![k0], vec![b0]);
        for k in 0..basis.len() {
            let mode = basis.pod.mode(k);
            let mut bk = vec![0.0; nf];
            ops.push(assemble(&|p| index[p].map_or(0.0, |i| mode[i]), &mut bk));
            rhs.push(bk);
        }
        Self { ops, rhs }
    }

    /// Number of parameters `q`.
    pub fn q(&self) -> usize {
        self.ops.len() - 1
    }

    /// `K(ξ)`.
    pub fn matrix(&self, xi: &[f64]) -> SymmetricMatrix {
        let mut k = self.ops[0].clone();
        for (j, x) in xi.iter().enumerate() {
            for (v, o) in k.values.iter_mut().zip(&self.ops[j + 1].values) {
                *v += x * o;
            }
        }
        k
    }

    /// `b(ξ)`.
    pub fn load(&self, xi: &[f64]) -> Vec<f64> {
        let mut b = self.rhs[0].clone();
        for (j, x) in xi.iter().enumerate() {
            for (v, o) in b.iter_mut().zip(&self.rhs[j + 1]) {
                *v += x * o;
            }
        }
        b
    }

    /// The exact `∆u(ξ) = K(ξ)⁻¹ b(ξ)` (free dofs).
    pub fn solve(&self, xi: &[f64]) -> Result<Vec<f64>, SolveError> {
        let k = self.matrix(xi);
        let mut b = self.load(xi);
        Cholesky::factor(&k)?.solve_in_place(&mut b);
        Ok(b)
    }
}

/// Settings of the vademecum builder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VademecumSettings {
    /// Grid nodes along each coefficient's range.
    pub grid: usize,
    /// Stop when a new mode's amplitude is below this fraction of the first one's.
    pub tolerance: f64,
    /// Most modes.
    pub max_modes: usize,
    /// Alternating-direction iterations per mode.
    pub max_iterations: usize,
    /// A mode has converged when its spatial function changes by less than this (relative).
    pub fixed_point_tolerance: f64,
}

impl Default for VademecumSettings {
    /// 201 grid nodes per coefficient, amplitudes to 10⁻⁶ of the first mode's, at most 60 modes.
    fn default() -> Self {
        Self {
            grid: 201,
            tolerance: 1e-6,
            max_modes: 60,
            max_iterations: 40,
            fixed_point_tolerance: 1e-8,
        }
    }
}

/// The vademecum could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VademecumError {
    /// A spatial problem was not positive definite.
    #[error(
        "mode {mode}: the stiffness averaged over the coefficient box is not positive definite ({source}); the box holds damage fields with negative stiffness: lower the margin or add POD vectors"
    )]
    Solve {
        /// The mode being computed.
        mode: usize,
        /// Why.
        source: SolveError,
    },
    /// Bad settings.
    #[error("the vademecum needs at least 2 grid nodes, one mode and one iteration")]
    Settings,
}

/// What the build did.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct VademecumReport {
    /// Modes kept.
    pub modes: usize,
    /// Each mode's amplitude `‖F_i‖` (the `G` are normalised).
    pub amplitudes: Vec<f64>,
    /// Fixed-point iterations of each mode.
    pub iterations: Vec<usize>,
    /// Whether a one-dimensional problem met a non-positive coefficient (the stiffness is not
    /// positive at some grid node of the box).
    pub nonpositive: bool,
    /// Build time (s).
    pub seconds: f64,
}

/// The separated displacement increment `∆u(ξ) = Σ_i F_i Π_K G_K^i(ξ_K)` of a unit step.
#[derive(Debug, Clone, PartialEq)]
pub struct DamageVademecum {
    /// Free dofs.
    pub n_free: usize,
    /// Parameters `q`.
    pub q: usize,
    /// Grid nodes per parameter.
    pub grid: usize,
    /// Lower bounds.
    pub lo: Vec<f64>,
    /// Upper bounds.
    pub hi: Vec<f64>,
    /// Number of modes.
    pub n_modes: usize,
    /// `F_i`, mode-major (`n_modes × n_free`).
    pub spatial: Vec<f64>,
    /// `G_K^i` at the grid nodes, `[i][K][m]` flattened.
    pub factors: Vec<f64>,
    /// Modes of each pull pattern, in order (they sum to `n_modes`): the first for the
    /// scene's load, then one per cross pull ([`DamageVademecum::merge`]).
    pub patterns: Vec<usize>,
    /// The build report.
    pub report: VademecumReport,
}

/// Grid nodes and trapezoidal weights of one range.
fn grid_of(lo: f64, hi: f64, n: usize) -> (Vec<f64>, Vec<f64>) {
    let h = (hi - lo) / (n - 1) as f64;
    let x = (0..n).map(|m| lo + h * m as f64).collect();
    let w = (0..n).map(|m| if m == 0 || m == n - 1 { 0.5 * h } else { h }).collect();
    (x, w)
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The one-dimensional inner products `⟨S_k, T_k⟩` of every parameter `k`, plain and
/// weighted by `ξ_k`, from which the builder's products of Eq. 4.20 and §4.5.4.2 are taken.
struct Inners {
    plain: Vec<f64>,
    weighted: Vec<f64>,
}

impl Inners {
    /// `f(k, weighted)` for every parameter.
    fn of(q: usize, f: impl Fn(usize, bool) -> f64) -> Self {
        Self {
            plain: (0..q).map(|k| f(k, false)).collect(),
            weighted: (0..q).map(|k| f(k, true)).collect(),
        }
    }

    /// Parameter `k`'s pair again.
    fn set(&mut self, k: usize, f: impl Fn(bool) -> f64) {
        self.plain[k] = f(false);
        self.weighted[k] = f(true);
    }

    /// `Π_{k ≠ skip} ⟨S_k, T_k⟩`, the `k = j − 1` factor weighted by `ξ_k` (the term of
    /// operator `K_j`; `j = 0` weights none).
    fn product(&self, j: usize, skip: Option<usize>) -> f64 {
        (0..self.plain.len())
            .filter(|&k| Some(k) != skip)
            .map(|k| if k + 1 == j { self.weighted[k] } else { self.plain[k] })
            .product()
    }
}

/// The R-step's system (seed 000 Eq. 4.20) into `a` and the returned right-hand side: the
/// affine operators `sys.ops[j]` weighted by the products of the current factors' inner
/// products (`with_s`), the loads by those with 1 (`with_1`), less the earlier modes' `K_j F_i`
/// (`kf`) weighted by the factors' inner products with theirs (`with_g`).
fn r_step_system(
    sys: &AffineSystem,
    with_s: &Inners,
    with_1: &Inners,
    with_g: &[Inners],
    kf: &[Vec<Vec<f64>>],
    a: &mut SymmetricMatrix,
) -> Vec<f64> {
    let q = sys.q();
    let c: Vec<f64> = (0..=q).map(|j| with_s.product(j, None)).collect();
    a.values.iter_mut().for_each(|v| *v = 0.0);
    for (j, cj) in c.iter().enumerate() {
        for (v, o) in a.values.iter_mut().zip(&sys.ops[j].values) {
            *v += cj * o;
        }
    }
    let mut rhs = vec![0.0; sys.rhs[0].len()];
    for j in 0..=q {
        let e = with_1.product(j, None);
        for (v, b) in rhs.iter_mut().zip(&sys.rhs[j]) {
            *v += e * b;
        }
        for (i, wg) in with_g.iter().enumerate() {
            let d = wg.product(j, None);
            for (v, f) in rhs.iter_mut().zip(&kf[i][j]) {
                *v -= d * f;
            }
        }
    }
    rhs
}

/// Builds the vademecum of `sys` over the box `lo..hi`; `progress(mode, amplitude ratio)`
/// after each mode.
pub fn build(
    sys: &AffineSystem,
    lo: &[f64],
    hi: &[f64],
    s: &VademecumSettings,
    mut progress: impl FnMut(usize, f64),
) -> Result<DamageVademecum, VademecumError> {
    if s.grid < 2 || s.max_modes == 0 || s.max_iterations == 0 {
        return Err(VademecumError::Settings);
    }
    let t0 = Instant::now();
    let q = sys.q();
    let nf = sys.rhs[0].len();
    let ng = s.grid;
    let grids: Vec<(Vec<f64>, Vec<f64>)> = (0..q).map(|k| grid_of(lo[k], hi[k], ng)).collect();
    // ⟨a, b⟩ along parameter k, weighted by ξ_k when `xi`
    let inner = |k: usize, a: &[f64], b: &[f64], xi: bool| -> f64 {
        let (x, w) = &grids[k];
        (0..ng).map(|m| w[m] * a[m] * b[m] * if xi { x[m] } else { 1.0 }).sum()
    };
    let ones = vec![1.0; ng];
    let mut spatial: Vec<Vec<f64>> = Vec::new();
    let mut factors: Vec<Vec<Vec<f64>>> = Vec::new();
    // K_j F_i of the modes found
    let mut kf: Vec<Vec<Vec<f64>>> = Vec::new();
    let mut report = VademecumReport {
        modes: 0,
        amplitudes: Vec::new(),
        iterations: Vec::new(),
        nonpositive: false,
        seconds: 0.0,
    };
    let mut chol: Option<Cholesky> = None;
    let mut a = sys.ops[0].clone();
    let mut kr = vec![vec![0.0; nf]; q + 1];
    for mode in 0..s.max_modes {
        let mut sk: Vec<Vec<f64>> = (0..q)
            .map(|k| ones.iter().map(|v| v / inner(k, &ones, &ones, false).sqrt()).collect())
            .collect();
        let mut r = vec![0.0; nf];
        let mut its = 0;
        loop {
            its += 1;
            // the one-dimensional inner products of the S_k with themselves, with 1 and with
            // the earlier modes' factors, unweighted and weighted by ξ_k
            let mut with_s = Inners::of(q, |k, xi| inner(k, &sk[k], &sk[k], xi));
            let mut with_1 = Inners::of(q, |k, xi| inner(k, &sk[k], &ones, xi));
            let mut with_g: Vec<Inners> = factors.iter().map(|g| Inners::of(q, |k, xi| inner(k, &sk[k], &g[k], xi))).collect();
            // R-step (Eq. 4.20)
            let mut rhs = r_step_system(sys, &with_s, &with_1, &with_g, &kf, &mut a);
            match &mut chol {
                Some(ch) => ch.refactor(&a),
                None => Cholesky::factor(&a).map(|ch| chol = Some(ch)),
            }
            .map_err(|source| VademecumError::Solve { mode, source })?;
            chol.as_ref().expect("factored").solve_in_place(&mut rhs);
            let change = rhs.iter().zip(&r).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt();
            let norm = dot(&rhs, &rhs).sqrt();
            r = rhs;
            if its > 1 && change <= s.fixed_point_tolerance * norm || its >= s.max_iterations || norm == 0.0 {
                break;
            }
            // S-steps (§4.5.4.2): one division per grid node
            for (j, o) in sys.ops.iter().enumerate() {
                o.mul_vec(&r, &mut kr[j]);
            }
            let rkr: Vec<f64> = kr.iter().map(|v| dot(&r, v)).collect();
            let rb: Vec<f64> = sys.rhs.iter().map(|b| dot(&r, b)).collect();
            let rkf: Vec<Vec<f64>> = kf.iter().map(|kfi| kfi.iter().map(|v| dot(&r, v)).collect()).collect();
            for da in 0..q {
                // Π_{k≠a} ⟨S_k, T_k⟩ with ξ_j weighting parameter j − 1
                let (mut l0, mut l1, mut b0, mut b1) = (0.0, 0.0, 0.0, 0.0);
                for j in 0..=q {
                    let (pl, pb) = (rkr[j] * with_s.product(j, Some(da)), rb[j] * with_1.product(j, Some(da)));
                    if j == da + 1 {
                        l1 += pl;
                        b1 += pb;
                    } else {
                        l0 += pl;
                        b0 += pb;
                    }
                }
                let mut g0 = vec![0.0; factors.len()];
                let mut g1 = vec![0.0; factors.len()];
                for (i, wg) in with_g.iter().enumerate() {
                    for j in 0..=q {
                        let v = rkf[i][j] * wg.product(j, Some(da));
                        if j == da + 1 {
                            g1[i] += v;
                        } else {
                            g0[i] += v;
                        }
                    }
                }
                let x = &grids[da].0;
                let mut new = vec![0.0; ng];
                for m in 0..ng {
                    let lhs = l0 + l1 * x[m];
                    let mut rhs = b0 + b1 * x[m];
                    for (i, g) in factors.iter().enumerate() {
                        rhs -= (g0[i] + g1[i] * x[m]) * g[da][m];
                    }
                    if lhs > 0.0 {
                        new[m] = rhs / lhs;
                    } else {
                        report.nonpositive = true;
                    }
                }
                let n = inner(da, &new, &new, false).sqrt();
                if n > 0.0 {
                    new.iter_mut().for_each(|v| *v /= n);
                    sk[da] = new;
                    // the inner products along parameter da follow the new S_da
                    with_s.set(da, |xi| inner(da, &sk[da], &sk[da], xi));
                    with_1.set(da, |xi| inner(da, &sk[da], &ones, xi));
                    for (wg, g) in with_g.iter_mut().zip(&factors) {
                        wg.set(da, |xi| inner(da, &sk[da], &g[da], xi));
                    }
                }
            }
        }
        let amplitude = dot(&r, &r).sqrt();
        let first = report.amplitudes.first().copied().unwrap_or(amplitude);
        if amplitude == 0.0 || (mode > 0 && amplitude < s.tolerance * first) {
            break;
        }
        kf.push(sys.apply_each(&r));
        spatial.push(r);
        factors.push(sk);
        report.amplitudes.push(amplitude);
        report.iterations.push(its);
        progress(mode + 1, amplitude / first);
    }
    report.modes = spatial.len();
    report.seconds = t0.elapsed().as_secs_f64();
    Ok(DamageVademecum {
        n_free: nf,
        q,
        grid: ng,
        lo: lo.to_vec(),
        hi: hi.to_vec(),
        n_modes: spatial.len(),
        spatial: spatial.concat(),
        factors: factors.into_iter().flatten().flatten().collect(),
        patterns: vec![report.modes],
        report,
    })
}

impl DamageVademecum {
    /// One vademecum holding the modes of `parts` (one per pull pattern, built over the same
    /// box and grid) one after the other: `∆u = Σ_p ds_p Σ_{i ∈ p} F_i Π_K G_K^i(ξ_K)`. The
    /// report is the first part's, its amplitudes and iterations followed by the others'.
    pub fn merge(parts: Vec<DamageVademecum>) -> Self {
        let mut it = parts.into_iter();
        let mut out = it.next().expect("at least one vademecum");
        for v in it {
            debug_assert!(v.q == out.q && v.grid == out.grid && v.n_free == out.n_free);
            out.n_modes += v.n_modes;
            out.spatial.extend_from_slice(&v.spatial);
            out.factors.extend_from_slice(&v.factors);
            out.patterns.extend_from_slice(&v.patterns);
            out.report.modes += v.report.modes;
            out.report.amplitudes.extend_from_slice(&v.report.amplitudes);
            out.report.iterations.extend_from_slice(&v.report.iterations);
            out.report.nonpositive |= v.report.nonpositive;
            out.report.seconds += v.report.seconds;
        }
        out
    }

    /// The first `m` modes of the scene's pull pattern (all of them when it has fewer): the
    /// vademecum the greedy build would have stopped at after `m` modes — each mode is
    /// computed given the ones before it, none is revised after — with the pulls across the
    /// load left out. What `vademecum study` measures a smaller vademecum by.
    pub fn prefix(&self, m: usize) -> Self {
        self.pattern_prefix(&[m])
    }

    /// The first `keep[p]` modes of each pull pattern `p` (all of a pattern's when it has
    /// fewer; the patterns past `keep`'s length left out): each pattern's own greedy build
    /// stopped there. What `vademecum build --target-error` keeps when fewer modes meet it.
    pub fn pattern_prefix(&self, keep: &[usize]) -> Self {
        let per_mode = self.q * self.grid;
        let mut report = self.report.clone();
        let (mut spatial, mut factors, mut patterns) = (Vec::new(), Vec::new(), Vec::new());
        let (mut amplitudes, mut iterations) = (Vec::new(), Vec::new());
        let mut first = 0;
        for (p, &n) in self.patterns.iter().enumerate() {
            let m = keep.get(p).map_or(0, |&k| k.min(n));
            if p < keep.len() {
                let modes = first..first + m;
                spatial.extend_from_slice(&self.spatial[modes.start * self.n_free..modes.end * self.n_free]);
                factors.extend_from_slice(&self.factors[modes.start * per_mode..modes.end * per_mode]);
                amplitudes.extend(report.amplitudes.get(modes.clone()).unwrap_or(&[]));
                iterations.extend(report.iterations.get(modes).unwrap_or(&[]));
                patterns.push(m);
            }
            first += n;
        }
        let n_modes = patterns.iter().sum();
        report.modes = n_modes;
        report.amplitudes = amplitudes;
        report.iterations = iterations;
        Self {
            n_free: self.n_free,
            q: self.q,
            grid: self.grid,
            n_modes,
            spatial,
            factors,
            patterns,
            lo: self.lo.clone(),
            hi: self.hi.clone(),
            report,
        }
    }

    /// The pull pattern of each mode.
    pub fn mode_patterns(&self) -> Vec<usize> {
        self.patterns
            .iter()
            .enumerate()
            .flat_map(|(p, &n)| std::iter::repeat_n(p, n))
            .collect()
    }

    /// The products `a_i = Π_K G_K^i(ξ_K)` into `a` (length `n_modes`), each `ξ_K` clamped to
    /// its range. Returns whether some coefficient was clamped. No allocation.
    pub fn coefficients(&self, xi: &[f64], a: &mut [f64]) -> bool {
        self.coefficients_from(xi, 0, a)
    }

    /// [`Self::coefficients`] of the modes `first..first + a.len()` only, into `a`: a mode's
    /// coefficient is its own factors' product, whatever the other modes. No allocation.
    pub fn coefficients_from(&self, xi: &[f64], first: usize, a: &mut [f64]) -> bool {
        let mut clamped = false;
        a.fill(1.0);
        for k in 0..self.q {
            let t = (xi[k] - self.lo[k]) / (self.hi[k] - self.lo[k]) * (self.grid - 1) as f64;
            clamped |= !(0.0..=(self.grid - 1) as f64).contains(&t);
            let t = t.clamp(0.0, (self.grid - 1) as f64);
            let m = (t.floor() as usize).min(self.grid - 2);
            let f = t - m as f64;
            for (i, ai) in a.iter_mut().enumerate() {
                let g = &self.factors[((first + i) * self.q + k) * self.grid..][..self.grid];
                *ai *= (1.0 - f) * g[m] + f * g[m + 1];
            }
        }
        clamped
    }

    /// `∆u = Σ_i a_i F_i` (free dofs) into `out`.
    pub fn combine(&self, a: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (i, &ai) in a.iter().enumerate() {
            for (o, f) in out.iter_mut().zip(&self.spatial[i * self.n_free..(i + 1) * self.n_free]) {
                *o += ai * f;
            }
        }
    }

    /// Mode `i`'s spatial function `F_i`.
    pub fn mode(&self, i: usize) -> &[f64] {
        &self.spatial[i * self.n_free..(i + 1) * self.n_free]
    }
}
