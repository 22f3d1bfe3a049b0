//! Hyperelastic laws for large deformations: the strain-energy density `W(C)`, the second
//! Piola–Kirchhoff stress `S = 2 ∂W/∂C` and the material tangent `ℂ = 4 ∂²W/∂C∂C`, in terms of
//! the right Cauchy–Green tensor `C = FᵀF`.
//!
//! - St Venant–Kirchhoff (seed 001): `W = λ/2 (tr E)² + μ E:E`, `E = (C − I)/2`, so
//!   `S = λ tr(E) I + 2μ E` and `ℂ = λ I⊗I + 2μ 𝕀`. Not polyconvex: it softens and loses
//!   stability in strong compression.
//! - Compressible neo-Hookean in the Abaqus form (seed 004):
//!   `W = μ/2 (J^(−2/3) I₁ − 3) + U(J)`, with `μ = E/2(1+ν)`, `K = E/3(1−2ν)`.
//! - Compressible Mooney–Rivlin in the Abaqus form:
//!   `W = C₁₀ (Ī₁ − 3) + C₀₁ (Ī₂ − 3) + U(J)`, `Ī₁ = J^(−2/3) I₁`, `Ī₂ = J^(−4/3) I₂`.
//!
//! The volumetric energy `U(J)` of the last two is chosen by [`VolumetricLaw`]: Abaqus's
//! `K/2 (J − 1)²` by default, SOFA's `K/2 (ln J)²`, or Simo & Taylor's
//! `K/4 (J² − 1 − 2 ln J)`; all have `U(1) = U'(1) = 0` and `U''(1) = K`, so they agree at
//! small strains and differ under large volume changes.
//!
//! The last two split into an isochoric part `W̄(C)` and a volumetric part `U(J)`; the
//! mean-dilatation element evaluates `U` once per cell on the cell's volume ratio (what keeps
//! it from locking as ν → ½), so [`Hyperelastic::response`] can leave `U` out
//! ([`Part::Isochoric`]) and [`Hyperelastic::volumetric`] gives `U, U', U''`.
//!
//! With `C⁻¹` written `B`, the derivatives used below are
//! `∂J/∂C = J/2 B`, `∂B_IJ/∂C_KL = −½ (B_IK B_JL + B_IL B_JK) =: −𝕀_B`,
//! `∂I₁/∂C = I`, `∂I₂/∂C = I₁ I − C`.

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use super::{LinearElastic, MaterialError};

/// Voigt order of symmetric tensors: `11, 22, 33, 23, 13, 12`.
pub const VOIGT: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)];

/// The volumetric energy `U(J)` of a law that splits (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VolumetricLaw {
    /// `U = K/2 (J − 1)²` (Abaqus; finite at J → 0, so it does not by itself forbid collapse).
    #[default]
    JMinus1,
    /// `U = K/2 (ln J)²` (SOFA's Mooney–Rivlin and neo-Hookean; grows without bound as J → 0,
    /// but is not convex for `J > e`).
    LnJ,
    /// `U = K/4 (J² − 1 − 2 ln J)` (Simo & Taylor 1991; convex, unbounded as J → 0 and J → ∞).
    SimoTaylor,
}

impl VolumetricLaw {
    /// `U(J)`, `U'(J)`, `U''(J)` for the bulk modulus `kappa`.
    pub fn eval(self, kappa: f64, j: f64) -> (f64, f64, f64) {
        match self {
            Self::JMinus1 => (0.5 * kappa * (j - 1.0).powi(2), kappa * (j - 1.0), kappa),
            Self::LnJ => {
                let l = j.ln();
                (0.5 * kappa * l * l, kappa * l / j, kappa * (1.0 - l) / (j * j))
            }
            Self::SimoTaylor => (
                0.25 * kappa * (j * j - 1.0 - 2.0 * j.ln()),
                0.5 * kappa * (j - 1.0 / j),
                0.5 * kappa * (1.0 + 1.0 / (j * j)),
            ),
        }
    }

    /// The formula, for reports.
    pub fn formula(self) -> &'static str {
        match self {
            Self::JMinus1 => "K/2 (J − 1)²",
            Self::LnJ => "K/2 (ln J)²",
            Self::SimoTaylor => "K/4 (J² − 1 − 2 ln J)",
        }
    }
}

/// Which law.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "snake_case")]
pub enum Hyperelastic {
    /// St Venant–Kirchhoff with Lamé parameters λ, μ (Pa).
    StVenantKirchhoff {
        /// λ (Pa).
        lambda: f64,
        /// μ (Pa).
        mu: f64,
    },
    /// Compressible neo-Hookean (Abaqus form) with shear modulus μ and bulk modulus K (Pa).
    NeoHookean {
        /// μ (Pa).
        mu: f64,
        /// K (Pa).
        kappa: f64,
        /// `U(J)`.
        #[serde(default)]
        volumetric: VolumetricLaw,
    },
    /// Compressible Mooney–Rivlin (Abaqus form): C₁₀, C₀₁ and the bulk modulus K (Pa);
    /// the initial shear modulus is `2 (C₁₀ + C₀₁)`.
    MooneyRivlin {
        /// C₁₀ (Pa).
        c10: f64,
        /// C₀₁ (Pa).
        c01: f64,
        /// K (Pa).
        kappa: f64,
        /// `U(J)`.
        #[serde(default)]
        volumetric: VolumetricLaw,
    },
}

/// Which part of the energy [`Hyperelastic::response`] evaluates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// All of it.
    Full,
    /// Only the isochoric part `W̄` (the volumetric `U(J)` is evaluated per cell by the
    /// mean-dilatation element). For St Venant–Kirchhoff, which does not split, all of it.
    Isochoric,
}

/// Energy density, stress and tangent at one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Response {
    /// `W` (J/m³ of reference volume).
    pub energy: f64,
    /// `S` in Voigt order (Pa), tensor components.
    pub stress: [f64; 6],
    /// `ℂ` in Voigt order (Pa), tensor components.
    pub tangent: [[f64; 6]; 6],
}

/// `A⊗B` in Voigt.
fn outer(a: &Matrix3<f64>, b: &Matrix3<f64>, s: f64, out: &mut [[f64; 6]; 6]) {
    for (p, &(i, j)) in VOIGT.iter().enumerate() {
        for (q, &(k, l)) in VOIGT.iter().enumerate() {
            out[p][q] += s * a[(i, j)] * b[(k, l)];
        }
    }
}

/// `𝕀_B`: `½ (B_IK B_JL + B_IL B_JK)` in Voigt (with `B = I` the symmetric identity).
fn sym_product(b: &Matrix3<f64>, s: f64, out: &mut [[f64; 6]; 6]) {
    for (p, &(i, j)) in VOIGT.iter().enumerate() {
        for (q, &(k, l)) in VOIGT.iter().enumerate() {
            out[p][q] += s * 0.5 * (b[(i, k)] * b[(j, l)] + b[(i, l)] * b[(j, k)]);
        }
    }
}

impl Response {
    /// `S` as a symmetric 3 × 3 matrix.
    pub fn stress_tensor(&self) -> Matrix3<f64> {
        let mut s = Matrix3::zeros();
        for (q, &(i, j)) in VOIGT.iter().enumerate() {
            s[(i, j)] = self.stress[q];
            s[(j, i)] = self.stress[q];
        }
        s
    }
}

fn voigt(m: &Matrix3<f64>) -> [f64; 6] {
    VOIGT.map(|(i, j)| m[(i, j)])
}

impl Hyperelastic {
    /// St Venant–Kirchhoff with the Lamé parameters of `E, ν`.
    pub fn svk(m: &LinearElastic) -> Self {
        Self::StVenantKirchhoff {
            lambda: m.lambda(),
            mu: m.shear(),
        }
    }

    /// Neo-Hookean with `μ = E/2(1+ν)`, `K = E/3(1−2ν)`.
    pub fn neo_hookean(m: &LinearElastic) -> Self {
        Self::NeoHookean {
            mu: m.shear(),
            kappa: m.bulk(),
            volumetric: VolumetricLaw::default(),
        }
    }

    /// Mooney–Rivlin with the small-strain moduli of `E, ν` and a share `c01_share` ∈ [0, 1)
    /// of the shear stiffness carried by the second invariant: `C₀₁ = share·μ/2`,
    /// `C₁₀ = (1 − share)·μ/2`.
    pub fn mooney_rivlin(m: &LinearElastic, c01_share: f64) -> Result<Self, MaterialError> {
        if !(0.0..1.0).contains(&c01_share) {
            return Err(MaterialError::Poisson(c01_share));
        }
        let mu = m.shear();
        Ok(Self::MooneyRivlin {
            c10: (1.0 - c01_share) * mu / 2.0,
            c01: c01_share * mu / 2.0,
            kappa: m.bulk(),
            volumetric: VolumetricLaw::default(),
        })
    }

    /// Whether the law splits into `W̄(C) + U(J)`.
    pub fn splits(&self) -> bool {
        !matches!(self, Self::StVenantKirchhoff { .. })
    }

    /// The same law with the volumetric energy `law` (no change for a law that does not split).
    pub fn with_volumetric(self, law: VolumetricLaw) -> Self {
        match self {
            Self::NeoHookean { mu, kappa, .. } => Self::NeoHookean {
                mu,
                kappa,
                volumetric: law,
            },
            Self::MooneyRivlin { c10, c01, kappa, .. } => Self::MooneyRivlin {
                c10,
                c01,
                kappa,
                volumetric: law,
            },
            svk @ Self::StVenantKirchhoff { .. } => svk,
        }
    }

    /// The volumetric part `U(J)` ([`VolumetricLaw`]) and its first two derivatives (zero for
    /// a law that does not split).
    pub fn volumetric(&self, j: f64) -> (f64, f64, f64) {
        match *self {
            Self::StVenantKirchhoff { .. } => (0.0, 0.0, 0.0),
            Self::NeoHookean { kappa, volumetric, .. } | Self::MooneyRivlin { kappa, volumetric, .. } => volumetric.eval(kappa, j),
        }
    }

    /// `W`, `S` and `ℂ` at `C`, or `None` when `det C ≤ 0` (an inverted point).
    pub fn response(&self, c: &Matrix3<f64>, part: Part) -> Option<Response> {
        let det = c.determinant();
        if det.is_nan() || det <= 0.0 {
            return None;
        }
        let id = Matrix3::identity();
        let mut t = [[0.0; 6]; 6];
        match *self {
            Self::StVenantKirchhoff { lambda, mu } => {
                let e = 0.5 * (c - id);
                let tr = e.trace();
                let s = lambda * tr * id + 2.0 * mu * e;
                outer(&id, &id, lambda, &mut t);
                sym_product(&id, 2.0 * mu, &mut t);
                Some(Response {
                    energy: 0.5 * lambda * tr * tr + mu * e.component_mul(&e).sum(),
                    stress: voigt(&s),
                    tangent: t,
                })
            }
            Self::NeoHookean { mu, .. } => {
                let b = c.try_inverse()?;
                let j = det.sqrt();
                let i1 = c.trace();
                let jm23 = j.powf(-2.0 / 3.0);
                let mut w = 0.5 * mu * (jm23 * i1 - 3.0);
                // S̄ = μ J^(−2/3) (I − I₁/3 B)
                let mut s = mu * jm23 * (id - i1 / 3.0 * b);
                // ℂ̄ = 2μ J^(−2/3) [−⅓ (I⊗B + B⊗I) + I₁/9 B⊗B + I₁/3 𝕀_B]
                let k = 2.0 * mu * jm23;
                outer(&id, &b, -k / 3.0, &mut t);
                outer(&b, &id, -k / 3.0, &mut t);
                outer(&b, &b, k * i1 / 9.0, &mut t);
                sym_product(&b, k * i1 / 3.0, &mut t);
                if part == Part::Full {
                    w += self.add_volumetric(j, &b, &mut s, &mut t);
                }
                Some(Response {
                    energy: w,
                    stress: voigt(&s),
                    tangent: t,
                })
            }
            Self::MooneyRivlin { c10, c01, .. } => {
                let b = c.try_inverse()?;
                let j = det.sqrt();
                let i1 = c.trace();
                let i2 = 0.5 * (i1 * i1 - (c * c).trace());
                let (jm23, jm43) = (j.powf(-2.0 / 3.0), j.powf(-4.0 / 3.0));
                let mut w = c10 * (jm23 * i1 - 3.0) + c01 * (jm43 * i2 - 3.0);
                // first invariant: the neo-Hookean terms with μ = 2 C₁₀
                let mut s = 2.0 * c10 * jm23 * (id - i1 / 3.0 * b);
                let k = 4.0 * c10 * jm23;
                outer(&id, &b, -k / 3.0, &mut t);
                outer(&b, &id, -k / 3.0, &mut t);
                outer(&b, &b, k * i1 / 9.0, &mut t);
                sym_product(&b, k * i1 / 3.0, &mut t);
                // second invariant: S₂ = 2C₀₁ J^(−4/3) [(I₁I − C) − ⅔ I₂ B]
                let a = i1 * id - c;
                s += 2.0 * c01 * jm43 * (a - 2.0 / 3.0 * i2 * b);
                // ℂ₂ = 4C₀₁ J^(−4/3) [−⅔ (A⊗B + B⊗A) + 4/9 I₂ B⊗B + I⊗I − 𝕀 + ⅔ I₂ 𝕀_B]
                let k2 = 4.0 * c01 * jm43;
                outer(&a, &b, -2.0 / 3.0 * k2, &mut t);
                outer(&b, &a, -2.0 / 3.0 * k2, &mut t);
                outer(&b, &b, 4.0 / 9.0 * k2 * i2, &mut t);
                outer(&id, &id, k2, &mut t);
                sym_product(&id, -k2, &mut t);
                sym_product(&b, 2.0 / 3.0 * k2 * i2, &mut t);
                if part == Part::Full {
                    w += self.add_volumetric(j, &b, &mut s, &mut t);
                }
                Some(Response {
                    energy: w,
                    stress: voigt(&s),
                    tangent: t,
                })
            }
        }
    }

    /// Adds `U(J)`'s stress `J U' B` and tangent `J (U' + J U'') B⊗B − 2 J U' 𝕀_B`; returns `U`.
    fn add_volumetric(&self, j: f64, b: &Matrix3<f64>, s: &mut Matrix3<f64>, t: &mut [[f64; 6]; 6]) -> f64 {
        let (u, du, ddu) = self.volumetric(j);
        *s += j * du * b;
        outer(b, b, j * (du + j * ddu), t);
        sym_product(b, -2.0 * j * du, t);
        u
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn laws() -> Vec<Hyperelastic> {
        let m = LinearElastic::new(3000.0, 0.45).unwrap();
        vec![
            Hyperelastic::svk(&m),
            Hyperelastic::neo_hookean(&m),
            Hyperelastic::mooney_rivlin(&m, 0.3).unwrap(),
            Hyperelastic::neo_hookean(&m).with_volumetric(VolumetricLaw::LnJ),
            Hyperelastic::mooney_rivlin(&m, 0.3)
                .unwrap()
                .with_volumetric(VolumetricLaw::SimoTaylor),
        ]
    }

    #[test]
    fn volumetric_laws_agree_at_small_strains_and_their_derivatives_are_consistent() {
        let kappa = 1e5;
        for law in [VolumetricLaw::JMinus1, VolumetricLaw::LnJ, VolumetricLaw::SimoTaylor] {
            let (u, du, ddu) = law.eval(kappa, 1.0);
            assert!(u.abs() < 1e-12 && du.abs() < 1e-9 && (ddu - kappa).abs() < 1e-9, "{law:?}");
            for j in [0.5, 0.9, 1.3] {
                let h = 1e-6;
                let (_, d, dd) = law.eval(kappa, j);
                let fd1 = (law.eval(kappa, j + h).0 - law.eval(kappa, j - h).0) / (2.0 * h);
                let fd2 = (law.eval(kappa, j + h).1 - law.eval(kappa, j - h).1) / (2.0 * h);
                assert!((fd1 - d).abs() < 1e-6 * kappa, "{law:?} U' at {j}: {fd1} vs {d}");
                assert!((fd2 - dd).abs() < 1e-6 * kappa, "{law:?} U'' at {j}: {fd2} vs {dd}");
            }
        }
        // they differ under a large volume change
        let at = |l: VolumetricLaw| l.eval(kappa, 0.5).0;
        assert!(at(VolumetricLaw::LnJ) > at(VolumetricLaw::SimoTaylor) && at(VolumetricLaw::SimoTaylor) > at(VolumetricLaw::JMinus1));
    }

    fn some_c() -> Matrix3<f64> {
        let f = Matrix3::new(1.1, 0.05, -0.02, 0.03, 0.92, 0.04, -0.01, 0.06, 1.05);
        f.transpose() * f
    }

    /// Perturbs the symmetric `C` in Voigt component `q` by `h` (both off-diagonal entries for
    /// a shear component).
    fn perturb(c: &Matrix3<f64>, q: usize, h: f64) -> Matrix3<f64> {
        let (k, l) = VOIGT[q];
        let mut c = *c;
        c[(k, l)] += h;
        if k != l {
            c[(l, k)] += h;
        }
        c
    }

    #[test]
    fn stress_is_twice_the_derivative_of_the_energy() {
        let c = some_c();
        for law in laws() {
            for part in [Part::Full, Part::Isochoric] {
                let r = law.response(&c, part).unwrap();
                for q in 0..6 {
                    let h = 1e-6;
                    let wp = law.response(&perturb(&c, q, h), part).unwrap().energy;
                    let wm = law.response(&perturb(&c, q, -h), part).unwrap().energy;
                    // a shear perturbation moves two entries of C: dW = 2 ∂W/∂C_kl h
                    let mult = if VOIGT[q].0 == VOIGT[q].1 { 1.0 } else { 2.0 };
                    let fd = 2.0 * (wp - wm) / (2.0 * h) / mult;
                    assert!(
                        (fd - r.stress[q]).abs() < 1e-6 * (1.0 + r.stress[q].abs()),
                        "{law:?} {part:?} S[{q}]: {fd} vs {}",
                        r.stress[q]
                    );
                }
            }
        }
    }

    #[test]
    fn tangent_is_twice_the_derivative_of_the_stress() {
        let c = some_c();
        for law in laws() {
            for part in [Part::Full, Part::Isochoric] {
                let r = law.response(&c, part).unwrap();
                for q in 0..6 {
                    let h = 1e-6;
                    let sp = law.response(&perturb(&c, q, h), part).unwrap().stress;
                    let sm = law.response(&perturb(&c, q, -h), part).unwrap().stress;
                    let mult = if VOIGT[q].0 == VOIGT[q].1 { 1.0 } else { 2.0 };
                    for p in 0..6 {
                        let fd = 2.0 * (sp[p] - sm[p]) / (2.0 * h) / mult;
                        let scale = 1.0 + r.tangent[p][q].abs();
                        assert!(
                            (fd - r.tangent[p][q]).abs() < 1e-5 * scale,
                            "{law:?} {part:?} C[{p}][{q}]: {fd} vs {}",
                            r.tangent[p][q]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn at_rest_every_law_has_no_stress_and_the_linear_moduli() {
        let m = LinearElastic::new(3000.0, 0.45).unwrap();
        for law in laws() {
            let r = law.response(&Matrix3::identity(), Part::Full).unwrap();
            assert!(r.energy.abs() < 1e-12 && r.stress.iter().all(|s| s.abs() < 1e-9), "{law:?}");
            // ℂ at rest is the linear-elastic tensor: ℂ₁₁₁₁ = λ + 2μ, ℂ₁₁₂₂ = λ, ℂ₁₂₁₂ = μ
            let tol = 1e-9 * m.young;
            assert!((r.tangent[0][0] - (m.lambda() + 2.0 * m.shear())).abs() < tol, "{law:?}");
            assert!((r.tangent[0][1] - m.lambda()).abs() < tol, "{law:?}");
            assert!((r.tangent[5][5] - m.shear()).abs() < tol, "{law:?}");
        }
    }

    #[test]
    fn an_inverted_point_has_no_response() {
        let f = Matrix3::new(-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        // C = FᵀF is positive even for det F < 0; the element checks det F itself. A singular
        // C has no response.
        let c = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        for law in laws() {
            assert!(law.response(&(f.transpose() * f), Part::Full).is_some());
            assert!(law.response(&c, Part::Full).is_none(), "{law:?}");
        }
    }
}
