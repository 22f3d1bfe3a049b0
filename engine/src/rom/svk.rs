//! The St Venant–Kirchhoff model in reduced coordinates, as exact polynomial tensors.
//!
//! # The method
//! With `u = Aζ` and `H = ∇₀u = Σ_i ζ_i H_i`, the Green strain is exactly quadratic in `ζ`:
//! `E = Σ_i ζ_i L_i + Σ_ij ζ_i ζ_j Q_ij`, with `L_i = sym H_i` and
//! `Q_ij = ¼ (H_iᵀ H_j + H_jᵀ H_i)` (seed 001 Eqs. 21–22: `γ_l` and `γ_nl`). St Venant–
//! Kirchhoff's energy `Ψ = λ/2 (tr E)² + μ E:E = ½ E:ℂ:E` (Eq. 23) is therefore a quartic
//! polynomial of `ζ`, and so is the reduced potential:
//!
//! `Π(ζ) = ½ K₁ζζ + ⅓ K₂ζζζ + ¼ K₃ζζζζ`,  `g(ζ) = ∂Π/∂ζ = Aᵀ f_int(Aζ)`,
//!
//! with fully symmetric tensors
//!
//! - `K₁_ij = ∫ L_i:ℂ:L_j` — the reduced linear stiffness `AᵀKA`;
//! - `K₂_ijk = R(i,jk) + R(j,ik) + R(k,ij)`, `R(i,jk) = ∫ L_i:ℂ:Q_jk`;
//! - `K₃_ijkl = ⅔ [P(ij,kl) + P(ik,jl) + P(il,jk)]`, `P(ij,kl) = ∫ Q_ij:ℂ:Q_kl`.
//!
//! They are built once, offline, in `O(N r⁴)`: every integrand is an inner product of
//! 7-component "features" of a symmetric tensor at an integration point
//! (`√(λ dV) tr T` and `√(2μ dV) T` in Mandel form), so `K₁`, `R` and `P` are blocks of one
//! Gram matrix, accumulated chunk by chunk with dense matrix products. Online, the internal
//! force, the tangent and every nonlinear term of the asymptotic expansion cost `O(r⁴)`
//! whatever the mesh size: this is what makes seed 001's `f_p^nl` (Eqs. 44–45) cheap without
//! evaluating anything on the full mesh.
//!
//! Only St Venant–Kirchhoff is polynomial in the displacement; the neo-Hookean and
//! Mooney–Rivlin laws are not (through `J^(−2/3)`), and are refused here.

use faer::Mat;

use super::pod::Pod;
use crate::fem::hyperelastic::{self, CellError, CellScratch, LawMap};
use crate::material::hyperelastic::Hyperelastic;
use crate::mesh::Mesh;

/// Why the reduced model could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReduceError {
    /// A cell's law is not St Venant–Kirchhoff.
    #[error(
        "cell {cell} is {law}: the reduced polynomial model needs St Venant-Kirchhoff (model = \"stvk\"); the other laws are not polynomial in the displacement"
    )]
    NotPolynomial {
        /// The cell.
        cell: usize,
        /// Its law.
        law: &'static str,
    },
    /// The basis does not match the mesh.
    #[error("the basis has vectors of {basis} entries, the mesh {mesh} degrees of freedom")]
    Shape {
        /// Basis vector length.
        basis: usize,
        /// `3 × nodes`.
        mesh: usize,
    },
    /// A reference cell is degenerate.
    #[error("cell {cell}: {source}")]
    Cell {
        /// The cell.
        cell: usize,
        /// Why.
        source: CellError,
    },
}

/// The reduced St Venant–Kirchhoff model (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq)]
pub struct ReducedSvk {
    /// Number of reduced coordinates `r`.
    pub r: usize,
    /// `K₁`, row-major `r × r`.
    pub k1: Vec<f64>,
    /// `K₂`, `[i][j][k]`, `r³`.
    pub k2: Vec<f64>,
    /// `K₃`, `[i][j][k][l]`, `r⁴`.
    pub k3: Vec<f64>,
}

/// Integration points per Gram chunk (bounds the memory to `7 · CHUNK · (r + r(r+1)/2)`).
const CHUNK: usize = 4096;

/// The Mandel features of a symmetric tensor given by its Voigt components
/// `[T11, T22, T33, T23, T13, T12]`: their dot product is `dV (λ trA trB + 2μ A:B)`.
fn features(t: [f64; 6], sl: f64, sm: f64, out: &mut [f64]) {
    let r2 = std::f64::consts::SQRT_2;
    out[0] = sl * (t[0] + t[1] + t[2]);
    out[1] = sm * t[0];
    out[2] = sm * t[1];
    out[3] = sm * t[2];
    out[4] = sm * r2 * t[3];
    out[5] = sm * r2 * t[4];
    out[6] = sm * r2 * t[5];
}

impl ReducedSvk {
    /// Builds the tensors of the St Venant–Kirchhoff `mesh` (every cell's law must be SVK) on
    /// the basis `pod` (which must vanish on constrained degrees of freedom).
    pub fn build(mesh: &Mesh, laws: &LawMap, pod: &Pod) -> Result<Self, ReduceError> {
        if pod.n != 3 * mesh.n_nodes() {
            return Err(ReduceError::Shape {
                basis: pod.n,
                mesh: 3 * mesh.n_nodes(),
            });
        }
        let r = pod.modes;
        let np = r * (r + 1) / 2;
        let mut pair = vec![0usize; r * r];
        {
            let mut p = 0;
            for i in 0..r {
                for j in i..r {
                    pair[i * r + j] = p;
                    pair[j * r + i] = p;
                    p += 1;
                }
            }
        }
        let cols = r + np;
        let n = mesh.kind.nodes_per_cell();
        let mut gram = Mat::<f64>::zeros(cols, cols);
        let mut chunk = Mat::<f64>::zeros(7 * CHUNK, cols);
        let mut rows = 0;
        let mut scratch = CellScratch::new(mesh.kind);
        let mut x = vec![[0.0; 3]; n];
        let mut h = vec![[[0.0; 3]; 3]; r];
        let mut feat = [0.0; 7];
        let flush = |chunk: &mut Mat<f64>, rows: &mut usize, gram: &mut Mat<f64>| {
            if *rows == 0 {
                return;
            }
            let block = chunk.as_ref().subrows(0, 7 * *rows);
            *gram += block.transpose() * block;
            *rows = 0;
        };
        for c in 0..mesh.n_cells() {
            let (lambda, mu) = match *laws.of(c) {
                Hyperelastic::StVenantKirchhoff { lambda, mu } => (lambda, mu),
                Hyperelastic::NeoHookean { .. } => {
                    return Err(ReduceError::NotPolynomial {
                        cell: c,
                        law: "neo-Hookean",
                    });
                }
                Hyperelastic::MooneyRivlin { .. } => {
                    return Err(ReduceError::NotPolynomial {
                        cell: c,
                        law: "Mooney-Rivlin",
                    });
                }
            };
            mesh.cell_coords(c, &mut x);
            let cell = mesh.cell(c);
            let mut points = Vec::with_capacity(8);
            hyperelastic::for_each_point(mesh.kind, &x, &mut scratch, |dv, g| points.push((dv, g.to_vec())))
                .map_err(|source| ReduceError::Cell { cell: c, source })?;
            for (dv, g) in points {
                // H_i[k][J] = Σ_a A_{(a,k), i} G_aJ
                for (i, hi) in h.iter_mut().enumerate() {
                    let mode = pod.mode(i);
                    *hi = [[0.0; 3]; 3];
                    for (a, ga) in g.iter().enumerate() {
                        for k in 0..3 {
                            let v = mode[3 * cell[a] + k];
                            for jj in 0..3 {
                                hi[k][jj] += v * ga[jj];
                            }
                        }
                    }
                }
                let (sl, sm) = ((lambda * dv).sqrt(), (2.0 * mu * dv).sqrt());
                let base = 7 * rows;
                let mut put = |col: usize, t: [f64; 6], chunk: &mut Mat<f64>| {
                    features(t, sl, sm, &mut feat);
                    for (q, &f) in feat.iter().enumerate() {
                        chunk[(base + q, col)] = f;
                    }
                };
                for (i, hi) in h.iter().enumerate() {
                    let s = |a: usize, b: usize| 0.5 * (hi[a][b] + hi[b][a]);
                    put(i, [s(0, 0), s(1, 1), s(2, 2), s(1, 2), s(0, 2), s(0, 1)], &mut chunk);
                }
                for i in 0..r {
                    for j in i..r {
                        // Q_ij[I][J] = ¼ Σ_k (H_i[k][I] H_j[k][J] + H_j[k][I] H_i[k][J])
                        let q = |a: usize, b: usize| 0.25 * (0..3).map(|k| h[i][k][a] * h[j][k][b] + h[j][k][a] * h[i][k][b]).sum::<f64>();
                        put(
                            r + pair[i * r + j],
                            [q(0, 0), q(1, 1), q(2, 2), q(1, 2), q(0, 2), q(0, 1)],
                            &mut chunk,
                        );
                    }
                }
                rows += 1;
                if rows == CHUNK {
                    flush(&mut chunk, &mut rows, &mut gram);
                }
            }
        }
        flush(&mut chunk, &mut rows, &mut gram);
        let k1 = (0..r * r).map(|e| gram[(e / r, e % r)]).collect();
        let rr = |i: usize, j: usize, k: usize| gram[(i, r + pair[j * r + k])];
        let mut k2 = vec![0.0; r * r * r];
        for i in 0..r {
            for j in 0..r {
                for k in 0..r {
                    k2[(i * r + j) * r + k] = rr(i, j, k) + rr(j, i, k) + rr(k, i, j);
                }
            }
        }
        let pp = |i: usize, j: usize, k: usize, l: usize| gram[(r + pair[i * r + j], r + pair[k * r + l])];
        let mut k3 = vec![0.0; r * r * r * r];
        for i in 0..r {
            for j in 0..r {
                for k in 0..r {
                    for l in 0..r {
                        k3[((i * r + j) * r + k) * r + l] = 2.0 / 3.0 * (pp(i, j, k, l) + pp(i, k, j, l) + pp(i, l, j, k));
                    }
                }
            }
        }
        Ok(Self { r, k1, k2, k3 })
    }

    /// Contracts `K₂ + 3K₃(·,·,·,z)` into `out` (`r³`): the bilinear part of the expansion of
    /// `g` around `z` (with `z = 0`, `K₂` itself).
    pub fn bilinear_at(&self, z: &[f64], out: &mut [f64]) {
        out.copy_from_slice(&self.k2);
        self.k3_contract_add(z, 3.0, out);
    }

    /// `out += s · K₃(·,·,·,z)` (`r³`).
    pub fn k3_contract_add(&self, z: &[f64], s: f64, out: &mut [f64]) {
        for (o, row) in out.iter_mut().zip(self.k3.chunks_exact(self.r)) {
            *o += s * row.iter().zip(z).map(|(a, b)| a * b).sum::<f64>();
        }
    }

    /// Reduced internal force `g(ζ) = K₁ζ + K₂ζζ + K₃ζζζ` into `out`.
    pub fn force(&self, zeta: &[f64], out: &mut [f64]) {
        let r = self.r;
        let mut w = self.k2.clone();
        self.k3_contract_add(zeta, 1.0, &mut w);
        for m in 0..r {
            let mut s = 0.0;
            for i in 0..r {
                let wi: f64 = (0..r).map(|j| w[(m * r + i) * r + j] * zeta[j]).sum();
                s += (self.k1[m * r + i] + wi) * zeta[i];
            }
            out[m] = s;
        }
    }

    /// Reduced tangent `∂g/∂ζ = K₁ + 2K₂ζ + 3K₃ζζ` into `out` (row-major `r × r`).
    pub fn tangent(&self, zeta: &[f64], out: &mut [f64]) {
        let r = self.r;
        let mut w = self.k2.clone();
        for (o, k) in w.iter_mut().zip(&self.k2) {
            *o = 2.0 * k;
        }
        self.k3_contract_add(zeta, 3.0, &mut w);
        for m in 0..r {
            for i in 0..r {
                out[m * r + i] = self.k1[m * r + i] + (0..r).map(|j| w[(m * r + i) * r + j] * zeta[j]).sum::<f64>();
            }
        }
    }

    /// Reduced strain energy `Π(ζ)`.
    pub fn energy(&self, zeta: &[f64]) -> f64 {
        let r = self.r;
        // Π = ½ K₁ζζ + ⅓ K₂ζζζ + ¼ K₃ζζζζ, from the three homogeneous parts of g·ζ
        let mut w2 = vec![0.0; r * r * r];
        self.k3_contract_add(zeta, 1.0, &mut w2);
        let (mut e1, mut e2, mut e3) = (0.0, 0.0, 0.0);
        for m in 0..r {
            for i in 0..r {
                e1 += self.k1[m * r + i] * zeta[m] * zeta[i];
                for j in 0..r {
                    let z3 = zeta[m] * zeta[i] * zeta[j];
                    e2 += self.k2[(m * r + i) * r + j] * z3;
                    e3 += w2[(m * r + i) * r + j] * z3;
                }
            }
        }
        0.5 * e1 + e2 / 3.0 + 0.25 * e3
    }
}
