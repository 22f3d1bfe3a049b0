//! The brute-force parametric solution `U = K⁻¹ F_L` (one solve per load state, with the same
//! factorization) — the reference a vademecum is measured against — and error measures.

use std::time::Instant;

use super::build::{LoadVector, SeparatedSolution};
use crate::solve::Cholesky;

/// Columns solved together (a block of right-hand sides amortises the factor traversal).
const BLOCK: usize = 64;

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
    let n = chol.n();
    let p = loads.len();
    let mut block = vec![0.0; n * BLOCK.min(p.max(1))];
    for start in (0..p).step_by(BLOCK) {
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
