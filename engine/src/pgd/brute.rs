//! The brute-force parametric solution `U = K⁻¹ F_L` (one solve per load state, with the same
//! factorization) — the reference a vademecum is measured against — and error measures.

use std::time::Instant;

use super::build::{LoadVector, SeparatedSolution};
use crate::solve::Cholesky;

/// Columns solved together (a block of right-hand sides amortises the factor traversal).
pub const BLOCK: usize = 64;

/// The exact responses, `n × p` column-major, and the time taken (s).
pub fn solve_all(chol: &Cholesky, loads: &[LoadVector], on_progress: &mut dyn FnMut(usize)) -> (Vec<f64>, f64) {
    let clock = Instant::now();
    let n = chol.n();
    let mut u = vec![0.0; n * loads.len()];
    solve_blocks(chol, loads, &mut |start, block| {
        u[start * n..start * n + block.len()].copy_from_slice(block);
        on_progress(start + block.len() / n);
    });
    (u, clock.elapsed().as_secs_f64())
}

/// Solves for every load state in blocks of columns, handing each solved block
/// (`n × columns`, column-major, first column = load state `start`) to `visit`, so callers
/// can extract what they need without holding the whole solution.
pub fn solve_blocks(chol: &Cholesky, loads: &[LoadVector], visit: &mut dyn FnMut(usize, &[f64])) {
    solve_blocks_in(chol, loads, 0..loads.len(), visit);
}

/// [`solve_blocks`] over the load states `range` alone, in blocks starting at `range.start`
/// (a multiple of [`BLOCK`] gives the blocks, and so the bits, of the whole pass).
pub fn solve_blocks_in(chol: &Cholesky, loads: &[LoadVector], range: std::ops::Range<usize>, visit: &mut dyn FnMut(usize, &[f64])) {
    let n = chol.n();
    let p = range.end.min(loads.len());
    let mut block = vec![0.0; n * BLOCK.min(p.saturating_sub(range.start).max(1))];
    for start in (range.start..p).step_by(BLOCK) {
        let end = (start + BLOCK).min(p);
        let b = &mut block[..(end - start) * n];
        b.fill(0.0);
        for (c, q) in (start..end).enumerate() {
            for &(e, w) in &loads[q] {
                b[c * n + e] += w;
            }
        }
        chol.solve_many_in_place(b, end - start);
        visit(start, b);
    }
}

/// Relative Frobenius error `‖U − F Gᵀ‖ / ‖U‖` over all load states, using the first `modes`
/// modes.
pub fn relative_error(sep: &SeparatedSolution, exact: &[f64], modes: usize) -> f64 {
    let n = sep.n;
    let mut col = vec![0.0; n];
    let (mut num, mut den) = (0.0, 0.0);
    for q in 0..sep.p {
        sep.column(q, modes, &mut col);
        let e = &exact[q * n..(q + 1) * n];
        for (a, b) in col.iter().zip(e) {
            num += (a - b) * (a - b);
            den += b * b;
        }
    }
    if den == 0.0 { 0.0 } else { (num / den).sqrt() }
}

/// Relative error for every mode count from 1 to `sep.modes`, computed incrementally
/// (`out[k-1]` is the error with k modes).
pub fn error_curve(sep: &SeparatedSolution, exact: &[f64]) -> Vec<f64> {
    let n = sep.n;
    let mut errs2 = vec![0.0; sep.modes];
    let mut den = 0.0;
    let mut res = vec![0.0; n];
    for q in 0..sep.p {
        res.copy_from_slice(&exact[q * n..(q + 1) * n]);
        den += res.iter().map(|v| v * v).sum::<f64>();
        for k in 0..sep.modes {
            let w = sep.g[k * sep.p + q];
            if w != 0.0 {
                for (r, f) in res.iter_mut().zip(sep.f_mode(k)) {
                    *r -= w * f;
                }
            }
            errs2[k] += res.iter().map(|v| v * v).sum::<f64>();
        }
    }
    errs2.iter().map(|e| if den == 0.0 { 0.0 } else { (e / den).sqrt() }).collect()
}

/// The error of every prefix of a separated solution's modes against the exact solution,
/// accumulated block by block as the exact columns are solved, so the exact solution is never
/// held whole (memory: the modes plus one block).
///
/// With `c = Fᵀu_q`, `g = G(q, ·)` and the Gram matrix `M = FᵀF`, the error of the first k
/// modes on column q is `‖u_q‖² − 2 Σ_{i≤k} g_i c_i + Σ_{i,j≤k} g_i g_j M_ij`; the last sum
/// grows by `g_k (2 (L g)_k + M_kk g_k)` with L the strictly lower part of M. Both products
/// are taken for a whole block at once (matrix products), so the cost is that of two
/// `modes × columns` products per block.
#[derive(Debug, Clone)]
pub struct PrefixErrors {
    gram_lower: faer::Mat<f64>,
    gram_diag: Vec<f64>,
    err2: Vec<f64>,
    norm2: f64,
}

impl PrefixErrors {
    /// Prepares the accumulation for `sep`.
    pub fn new(sep: &SeparatedSolution) -> Self {
        let f = faer::MatRef::from_column_major_slice(&sep.f, sep.n, sep.modes);
        let gram = f.transpose() * f;
        let m = sep.modes;
        Self {
            gram_lower: faer::Mat::from_fn(m, m, |i, j| if j < i { gram[(i, j)] } else { 0.0 }),
            gram_diag: (0..m).map(|i| gram[(i, i)]).collect(),
            err2: vec![0.0; m],
            norm2: 0.0,
        }
    }

    /// Adds exact columns `start..start + c` (`block` is `n × c`, column-major).
    pub fn add_block(&mut self, sep: &SeparatedSolution, start: usize, block: &[f64]) {
        let (n, m) = (sep.n, sep.modes);
        let c = block.len() / n.max(1);
        let u = faer::MatRef::from_column_major_slice(block, n, c);
        let f = faer::MatRef::from_column_major_slice(&sep.f, n, m);
        let coef = f.transpose() * u;
        let g = faer::Mat::from_fn(m, c, |k, j| sep.g[k * sep.p + start + j]);
        let lg = &self.gram_lower * &g;
        for j in 0..c {
            let col = &block[j * n..(j + 1) * n];
            let un = col.iter().map(|x| x * x).sum::<f64>();
            self.norm2 += un;
            let (mut lin, mut quad) = (0.0, 0.0);
            for k in 0..m {
                let gk = g[(k, j)];
                lin += gk * coef[(k, j)];
                quad += gk * (2.0 * lg[(k, j)] + self.gram_diag[k] * gk);
                self.err2[k] += un - 2.0 * lin + quad;
            }
        }
    }

    /// Relative error of every prefix (`out[k-1]`: first k modes) over the columns added.
    pub fn curve(&self) -> Vec<f64> {
        self.err2
            .iter()
            .map(|e| if self.norm2 > 0.0 { (e.max(0.0) / self.norm2).sqrt() } else { 0.0 })
            .collect()
    }
}
