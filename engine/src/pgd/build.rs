//! The greedy PGD builder (seed 000, Alg. 2.1; see the [module docs](super)).

use std::time::Instant;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef};

use crate::fem::assembly::SymmetricMatrix;
use crate::solve::Cholesky;

/// Stopping criteria of the builder (the scene's `[fidelity.pgd]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PgdParams {
    /// ε_R: stop enriching when a new mode's energy is below this fraction of the first's.
    pub global_tolerance: f64,
    /// ε_F: stop the fixed point when `R Sᵀ` changes by less than this (relative). The modes
    /// are near-optimal long before the fixed point converges tightly (BENCHMARKS.md), so
    /// a loose value saves most of the build time.
    pub enrichment_tolerance: f64,
    /// Cap on modes.
    pub max_modes: usize,
    /// Cap on fixed-point iterations per mode.
    pub max_iterations: usize,
    /// Modes enriched together (1: Alg. 2.1 as published, one mode at a time).
    pub block: usize,
}

impl Default for PgdParams {
    /// ε_R = 1e-4, ε_F = 1e-8, 200 modes, 50 iterations (the scene defaults).
    fn default() -> Self {
        Self {
            global_tolerance: 1e-4,
            enrichment_tolerance: 1e-8,
            max_modes: 200,
            max_iterations: 50,
            block: 1,
        }
    }
}

/// A separated representation `U ≈ F Gᵀ`: `n` spatial values (free equations) by `p` load
/// states, with `modes` pairs. Both factors are stored column-major, one column per mode.
#[derive(Debug, Clone, PartialEq)]
pub struct SeparatedSolution {
    /// Spatial size (number of free equations).
    pub n: usize,
    /// Parameter size (number of load states).
    pub p: usize,
    /// Number of modes.
    pub modes: usize,
    /// Spatial modes `F_k`, `n × modes`, column-major.
    pub f: Vec<f64>,
    /// Parameter modes `G_k`, `p × modes`, column-major.
    pub g: Vec<f64>,
}

impl SeparatedSolution {
    /// An empty solution (no modes).
    pub fn empty(n: usize, p: usize) -> Self {
        Self {
            n,
            p,
            modes: 0,
            f: Vec::new(),
            g: Vec::new(),
        }
    }

    /// Spatial mode k.
    pub fn f_mode(&self, k: usize) -> &[f64] {
        &self.f[k * self.n..(k + 1) * self.n]
    }

    /// Parameter mode k.
    pub fn g_mode(&self, k: usize) -> &[f64] {
        &self.g[k * self.p..(k + 1) * self.p]
    }

    /// Appends a mode pair.
    pub fn push(&mut self, r: &[f64], s: &[f64]) {
        debug_assert_eq!((r.len(), s.len()), (self.n, self.p));
        self.f.extend_from_slice(r);
        self.g.extend_from_slice(s);
        self.modes += 1;
    }

    /// Keeps the first `modes` modes.
    pub fn truncate(&mut self, modes: usize) {
        let m = modes.min(self.modes);
        self.f.truncate(m * self.n);
        self.g.truncate(m * self.p);
        self.modes = m;
    }

    /// Column `q` of `F Gᵀ` (the response to load state q) into `out`, using the first
    /// `modes` modes.
    pub fn column(&self, q: usize, modes: usize, out: &mut [f64]) {
        out.fill(0.0);
        for k in 0..modes.min(self.modes) {
            let w = self.g[k * self.p + q];
            if w != 0.0 {
                for (o, fk) in out.iter_mut().zip(self.f_mode(k)) {
                    *o += w * fk;
                }
            }
        }
    }
}

/// What a build did.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PgdInfo {
    /// Modes computed.
    pub modes: usize,
    /// Fixed-point iterations of each mode.
    pub iterations: Vec<usize>,
    /// Energy of each mode relative to the first (the ε_R criterion).
    pub mode_energy: Vec<f64>,
    /// Whether the last mode met ε_R (false: stopped by the mode cap).
    pub converged: bool,
    /// Wall-clock time (s).
    pub time_s: f64,
    /// Linear solves with the factorization.
    pub solves: usize,
}

/// A load state as a sparse force vector over the free equations: `(equation, force)` pairs
/// (empty when every loaded degree of freedom is constrained: the response is then zero).
pub type LoadVector = Vec<(usize, f64)>;

/// Column-major `n × c` view of a slice.
fn view(data: &[f64], n: usize, c: usize) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(data, n, c)
}

/// `F_L S`: the load matrix (sparse columns `loads`) times `S` (`p × c`), into `out` (`n × c`).
fn loads_times(loads: &[LoadVector], s: MatRef<'_, f64>, out: &mut [f64]) {
    let n = out.len() / s.ncols().max(1);
    for (j, col) in out.chunks_exact_mut(n.max(1)).enumerate() {
        for (q, l) in loads.iter().enumerate() {
            let w = s[(q, j)];
            if w != 0.0 {
                for &(e, f) in l {
                    col[e] += f * w;
                }
            }
        }
    }
}

/// `F_Lᵀ R` (`p × c`).
fn loads_transpose_times(loads: &[LoadVector], r: MatRef<'_, f64>) -> Mat<f64> {
    Mat::from_fn(loads.len(), r.ncols(), |q, j| loads[q].iter().map(|&(e, f)| f * r[(e, j)]).sum())
}

/// `‖A Bᵀ − C Dᵀ‖²_F` from the small Gram products (the columns of A, C live in one space,
/// those of B, D in another): `tr(AᵀA BᵀB) + tr(CᵀC DᵀD) − 2 tr(AᵀC DᵀB)`.
fn product_distance2(a: MatRef<'_, f64>, b: MatRef<'_, f64>, c: MatRef<'_, f64>, d: MatRef<'_, f64>) -> (f64, f64) {
    let tr = |x: Mat<f64>, y: Mat<f64>| -> f64 {
        (0..x.nrows())
            .map(|i| (0..x.ncols()).map(|j| x[(i, j)] * y[(j, i)]).sum::<f64>())
            .sum()
    };
    let ab = tr(a.transpose() * a, b.transpose() * b);
    let cd = tr(c.transpose() * c, d.transpose() * d);
    let cross = tr(a.transpose() * c, d.transpose() * b);
    ((ab + cd - 2.0 * cross).max(0.0), ab)
}

/// Builds the vademecum `U ≈ F Gᵀ` of `K U = F_L` by greedy enrichment, where column p of
/// `F_L` is `loads[p]`. `chol` must factor `k`. `on_mode(k, energy)` is called after each mode
/// (for progress displays).
///
/// Each enrichment adds a block of `b = params.block` modes at once (b = 1 is Alg. 2.1 as
/// published): the alternating fixed point runs on `R` (`n × b`) and `S` (`p × b`),
///
/// - R-step: `R = K⁻¹(F_L S) − F (Gᵀ S)`, one blocked solve of b right-hand sides, then R is
///   made K-orthonormal (`RᵀKR = I`; directions without energy are dropped, so the block
///   shrinks when the residual has lower rank);
/// - S-step (Galerkin, Eq. 2.22 with `RᵀKR = I`): `S = F_Lᵀ R − G (Fᵀ K R)`,
///
/// and the converged block is split into modes by an SVD of S (`S = Q Σ Wᵀ`: modes `R w_k`,
/// still K-orthonormal, with parameter functions `σ_k q_k`), pushed in decreasing energy
/// `σ_k = ‖F_k‖_K ‖G_k‖`. Blocks turn b single solves into one blocked solve and the
/// vector updates against the existing modes into matrix products, which is where the
/// single-mode builder spends its time once there are a few hundred modes.
pub fn build(
    k: &SymmetricMatrix,
    chol: &Cholesky,
    loads: &[LoadVector],
    params: &PgdParams,
    on_mode: &mut dyn FnMut(usize, f64),
) -> (SeparatedSolution, PgdInfo) {
    let clock = Instant::now();
    let n = k.pattern.n();
    let p = loads.len();
    let mut sol = SeparatedSolution::empty(n, p);
    let mut info = PgdInfo {
        modes: 0,
        iterations: Vec::new(),
        mode_energy: Vec::new(),
        converged: false,
        time_s: 0.0,
        solves: 0,
    };
    let mut first_energy = 0.0;
    'enrich: while sol.modes < params.max_modes && p > 0 && n > 0 {
        let b = params.block.max(1).min(params.max_modes - sol.modes).min(p);
        // Initial S: smooth, deterministic, linearly independent columns.
        let mut s = Mat::from_fn(p, b, |q, j| 1.0 + 0.1 * ((q as f64) * (0.618 + 0.37 * j as f64) + j as f64).sin());
        let mut r = Mat::<f64>::zeros(n, b);
        let mut r_old = Mat::<f64>::zeros(n, 0);
        let mut s_old = Mat::<f64>::zeros(p, 0);
        let mut iters = 0;
        loop {
            iters += 1;
            let c = s.ncols();
            // R-step
            let mut w = vec![0.0; n * c];
            loads_times(loads, s.as_ref(), &mut w);
            chol.solve_many_in_place(&mut w, c);
            info.solves += c;
            if sol.modes > 0 {
                let gs = view(&sol.g, p, sol.modes).transpose() * s.as_ref();
                let wm = MatMut::from_column_major_slice_mut(&mut w, n, c);
                matmul(
                    wm,
                    Accum::Add,
                    view(&sol.f, n, sol.modes),
                    &gs,
                    -1.0,
                    faer::get_global_parallelism(),
                );
            }
            // K-orthonormalise: R ← W V Λ^{-1/2} over the eigenpairs of WᵀKW with energy.
            let mut kw = vec![0.0; n * c];
            for (wc, kc) in w.chunks_exact(n).zip(kw.chunks_exact_mut(n)) {
                k.mul_vec(wc, kc);
            }
            let (w, kw) = (view(&w, n, c), view(&kw, n, c));
            let gram = w.transpose() * kw;
            let Ok(eig) = gram.self_adjoint_eigen(faer::Side::Lower) else {
                break;
            };
            let lambda: Vec<f64> = (0..c).map(|i| eig.S()[i]).collect();
            let top = lambda.iter().cloned().fold(0.0, f64::max);
            let keep: Vec<usize> = (0..c).rev().filter(|&i| lambda[i] > 1e-12 * top && lambda[i].is_finite()).collect();
            if keep.is_empty() || top.is_nan() || top <= 0.0 {
                // nothing left to represent
                info.converged = true;
                break 'enrich;
            }
            let t = Mat::from_fn(c, keep.len(), |i, j| eig.U()[(i, keep[j])] / lambda[keep[j]].sqrt());
            r = w * &t;
            let kr = kw * &t;
            // S-step (Galerkin)
            let mut s_new = loads_transpose_times(loads, r.as_ref());
            if sol.modes > 0 {
                let fkr = view(&sol.f, n, sol.modes).transpose() * &kr;
                s_new -= view(&sol.g, p, sol.modes) * &fkr;
            }
            s = s_new;
            let (change2, norm2) = if r_old.ncols() == 0 {
                (f64::INFINITY, 1.0)
            } else {
                product_distance2(r.as_ref(), s.as_ref(), r_old.as_ref(), s_old.as_ref())
            };
            let change = (change2 / norm2.max(f64::MIN_POSITIVE)).sqrt();
            if change < params.enrichment_tolerance || iters >= params.max_iterations {
                break;
            }
            r_old = r.clone();
            s_old = s.clone();
        }
        // Split the block into modes: S = Q Σ Wᵀ → F = R W (K-orthonormal), G = Q Σ.
        let Ok(svd) = s.thin_svd() else { break };
        let fw = &r * svd.V();
        for j in 0..svd.S().dim() {
            let sigma = svd.S()[j];
            if sol.modes == 0 {
                first_energy = sigma;
            }
            let rel = if first_energy > 0.0 { sigma / first_energy } else { 0.0 };
            if sigma == 0.0 || !sigma.is_finite() || rel < params.global_tolerance {
                info.converged = true;
                break 'enrich;
            }
            let fk: Vec<f64> = (0..n).map(|i| fw[(i, j)]).collect();
            let gk: Vec<f64> = (0..p).map(|q| svd.U()[(q, j)] * sigma).collect();
            sol.push(&fk, &gk);
            info.iterations.push(iters);
            info.mode_energy.push(rel);
            on_mode(sol.modes, rel);
            if sol.modes >= params.max_modes {
                break 'enrich;
            }
        }
    }
    info.modes = sol.modes;
    info.time_s = clock.elapsed().as_secs_f64();
    (sol, info)
}
