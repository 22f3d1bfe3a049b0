//! Recompression of a separated solution: `F Gᵀ = Q_F (R_F R_Gᵀ) Q_Gᵀ = Q_F (U Σ Vᵀ) Q_Gᵀ`,
//! keeping the leading singular triplets. The result has orthonormal spatial modes and is the
//! best approximation of `F Gᵀ` of its rank (Eckart–Young), so it never needs more modes than
//! the greedy PGD for the same error, and usually needs fewer.

use faer::Mat;

use super::build::SeparatedSolution;

/// Recompresses `sep`, keeping the smallest rank whose discarded singular values have a
/// relative Frobenius norm `√(Σ_{discarded} σ²/Σ σ²)` at most `tolerance`. `None` when `sep`
/// holds a non-finite value (the SVD would not converge on it).
pub fn recompress(sep: &SeparatedSolution, tolerance: f64) -> Option<SeparatedSolution> {
    let m = sep.modes;
    if m == 0 {
        return Some(sep.clone());
    }
    if !sep.f.iter().chain(&sep.g).all(|x| x.is_finite()) {
        return None;
    }
    let f = Mat::from_fn(sep.n, m, |i, k| sep.f[k * sep.n + i]);
    let g = Mat::from_fn(sep.p, m, |i, k| sep.g[k * sep.p + i]);
    let qf = f.qr();
    let qg = g.qr();
    let (q_f, r_f) = (qf.compute_thin_Q(), qf.thin_R().to_owned());
    let (q_g, r_g) = (qg.compute_thin_Q(), qg.thin_R().to_owned());
    let core = &r_f * r_g.transpose();
    let svd = core.thin_svd().ok()?;
    let sigma: Vec<f64> = (0..svd.S().dim()).map(|i| svd.S()[i]).collect();
    let total: f64 = sigma.iter().map(|s| s * s).sum();
    let mut keep = sigma.len();
    let mut tail = 0.0;
    while keep > 1 {
        let next = tail + sigma[keep - 1] * sigma[keep - 1];
        if total > 0.0 && (next / total).sqrt() > tolerance {
            break;
        }
        tail = next;
        keep -= 1;
    }
    let fu = &q_f * svd.U();
    let gv = &q_g * svd.V();
    let mut out = SeparatedSolution::empty(sep.n, sep.p);
    let mut r = vec![0.0; sep.n];
    let mut s = vec![0.0; sep.p];
    for k in 0..keep {
        for i in 0..sep.n {
            r[i] = fu[(i, k)];
        }
        for i in 0..sep.p {
            s[i] = gv[(i, k)] * sigma[k];
        }
        out.push(&r, &s);
    }
    Some(out)
}
