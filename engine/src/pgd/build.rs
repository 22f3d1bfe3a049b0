//! The greedy PGD builder (seed 000, Alg. 2.1; see the [module docs](super)).

use std::time::Instant;

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
}

impl Default for PgdParams {
    /// ε_R = 1e-4, ε_F = 1e-8, 200 modes, 50 iterations (the scene defaults).
    fn default() -> Self {
        Self {
            global_tolerance: 1e-4,
            enrichment_tolerance: 1e-8,
            max_modes: 200,
            max_iterations: 50,
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

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// A load state as a sparse force vector over the free equations: `(equation, force)` pairs
/// (empty when every loaded degree of freedom is constrained: the response is then zero).
pub type LoadVector = Vec<(usize, f64)>;

/// Builds the vademecum `U ≈ F Gᵀ` of `K U = F_L` by greedy enrichment, where column p of
/// `F_L` is `loads[p]`. `chol` must factor `k`. `on_mode(k, energy)` is called after each mode
/// (for progress displays).
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
    let mut r = vec![0.0; n];
    let mut r_old = vec![0.0; n];
    let mut kr = vec![0.0; n];
    let mut s = vec![0.0; p];
    let mut s_old = vec![0.0; p];
    let mut coef = vec![0.0; params.max_modes];
    let mut first_energy = 0.0;
    while sol.modes < params.max_modes {
        // Initial S: a smooth, non-zero guess that is not orthogonal to anything in general.
        for (q, v) in s.iter_mut().enumerate() {
            *v = 1.0 + 0.1 * ((q as f64) * 0.618).sin();
        }
        r.fill(0.0);
        let mut iters = 0;
        loop {
            iters += 1;
            r_old.copy_from_slice(&r);
            s_old.copy_from_slice(&s);
            let ss = dot(&s, &s);
            // R-step: R = [K⁻¹(F_L S) − Σ_i F_i (G_i·S)] / (S·S)
            r.fill(0.0);
            for (q, l) in loads.iter().enumerate() {
                for &(e, w) in l {
                    r[e] += w * s[q];
                }
            }
            chol.solve_in_place(&mut r);
            info.solves += 1;
            for i in 0..sol.modes {
                coef[i] = dot(sol.g_mode(i), &s);
            }
            for i in 0..sol.modes {
                let c = coef[i];
                for (rv, fv) in r.iter_mut().zip(sol.f_mode(i)) {
                    *rv -= c * fv;
                }
            }
            let rn = dot(&r, &r).sqrt();
            if rn == 0.0 || ss == 0.0 {
                break;
            }
            // keep R normalised; S carries the magnitude
            for v in r.iter_mut() {
                *v /= rn;
            }
            // S-step: S (RᵀKR) = F_Lᵀ R − Σ_i G_i (F_iᵀ K R)
            k.mul_vec(&r, &mut kr);
            let rkr = dot(&r, &kr);
            for i in 0..sol.modes {
                coef[i] = dot(sol.f_mode(i), &kr);
            }
            for (q, l) in loads.iter().enumerate() {
                let mut v: f64 = l.iter().map(|&(e, w)| w * r[e]).sum();
                for i in 0..sol.modes {
                    v -= coef[i] * sol.g[i * p + q];
                }
                s[q] = v / rkr;
            }
            // change of the rank-one product, relative (Frobenius)
            let (a2, b2) = (dot(&r, &r) * dot(&s, &s), dot(&r_old, &r_old) * dot(&s_old, &s_old));
            let ab = dot(&r, &r_old) * dot(&s, &s_old);
            let change = ((a2 + b2 - 2.0 * ab).max(0.0) / a2.max(f64::MIN_POSITIVE)).sqrt();
            if change < params.enrichment_tolerance || iters >= params.max_iterations {
                break;
            }
        }
        // mode energy ‖R‖_K ‖S‖
        k.mul_vec(&r, &mut kr);
        let energy = (dot(&r, &kr).max(0.0)).sqrt() * dot(&s, &s).sqrt();
        if sol.modes == 0 {
            first_energy = energy;
        }
        let rel = if first_energy > 0.0 { energy / first_energy } else { 0.0 };
        if energy == 0.0 || !energy.is_finite() {
            info.converged = true;
            break;
        }
        sol.push(&r, &s);
        info.iterations.push(iters);
        info.mode_energy.push(rel);
        on_mode(sol.modes, rel);
        if rel < params.global_tolerance {
            info.converged = true;
            break;
        }
    }
    info.modes = sol.modes;
    info.time_s = clock.elapsed().as_secs_f64();
    (sol, info)
}
