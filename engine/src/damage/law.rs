//! Isotropic damage laws of the strain-energy type (seed 000 §4.2.5; Simó 1987; Oliver 1996).
//!
//! # The model
//! The undamaged material stores `Ψ⁰(ε) = ½ ε : C⁰ : ε`. The equivalent strain is
//! `Φ = √(2Ψ⁰(ε))` (units √Pa), its history maximum `r = Φᵐ = max_{t≤T} Φ(t)` is the internal
//! variable, and the stress is `σ = g(r) ∂Ψ⁰/∂ε = g(r) σ⁰` with `g = 1 − D` (Eq. 4.2). Damage
//! grows only when `Φ = r` and loading; on unloading and reloading below `r` the material is
//! secant-elastic with modulus `g(r) C⁰`: **damage never heals**.
//!
//! # The consistent tangent (what the seed's text needs)
//! On a loading step `r = Φ(ε)`, so `dr/dε = ∂Φ/∂ε = σ⁰/Φ` (from `Φ² = ε:C⁰:ε`), and
//! `dσ/dε = g C⁰ + g′(r) σ⁰ ⊗ dr/dε = g C⁰ − (h/r) σ⁰ ⊗ σ⁰` with `h = −g′(r)`. This is the
//! seed's Eq. 4.11 (and the first case of Eq. 4.5). Alg. 4.1, line 5, prints `C = g C⁰ + h σ⁰⊗σ⁰`:
//! its sign is wrong and the `1/Φᵐ` is missing; the tangent is symmetric either way. On
//! unloading (`Φ < r`), `h` is zero and the tangent is the secant `g C⁰`. The test
//! `the_consistent_tangent_is_the_derivative_of_the_stress` checks this by finite differences.
//!
//! # The two forms
//! - [`DamageLaw::Simo`], the seed's law exactly (Eq. 4.3):
//!   `g(r) = β + (1 − β)(1 − e^{−r/α})/(r/α)`. Read carefully, it has **no damage threshold**
//!   (g < 1 for every r > 0) and **no stress peak** on a monotone path: in one dimension
//!   (`Φ = √E ε`) `σ = g E ε` has `dσ/dε = E[β + (1 − β) e^{−Φ/α}] > 0`, and with β = 0 the
//!   stress saturates at `α√E`. It cannot tear a specimen under displacement control; under
//!   force control, a load above `α√E` (β = 0) has no equilibrium of the law itself — with
//!   the residual floor below, Newton finds one on `residual · E` at a strain of order
//!   `σ / (residual · E)` (thousands), which the reference runs count
//!   (`StepResult::on_floor`) and the build reports.
//! - [`DamageLaw::Softening`], what tearing needs (Oliver et al. 1990, the exponential law):
//!   `g = 1` up to the threshold `r₀ = f_t/√E` (the uniaxial tensile strength `f_t`), then
//!   `g(r) = (r₀/r) e^{A(1 − r/r₀)}`: in uniaxial stress the stress peaks at `f_t` and decays
//!   exponentially. The dissipated energy per unit volume at full damage is
//!   `∫_{r₀}^{∞} (r²/2)(−g′) dr = r₀²(½ + 1/A)`. Regularised by the element size `l`
//!   (Bažant's crack band): `A` is chosen so that this equals `G_f / l`, whence the energy per
//!   unit crack area is the material's fracture energy `G_f` whatever the mesh
//!   ([`DamageLaw::softening`]).
//!
//! # Residual stiffness
//! `g` never goes below `residual` (default [`DEFAULT_RESIDUAL`]): a fully damaged region
//! (D → 1) keeps `residual · C⁰`, so the stiffness stays positive definite even when damage
//! isolates a piece. Past the point where the law would drop below it, `g` is frozen at the
//! residual and `h = 0` (no more dissipation).

use serde::{Deserialize, Serialize};

/// The residual fraction of stiffness a fully damaged material keeps by default: small
/// against any tissue contrast (fat at 10⁻⁴ of 0.5 MPa is 50 Pa, below the gallbladder's
/// 1.15 kPa), large enough that a Cholesky factor of a piece held by damaged cells only
/// keeps about eight digits.
pub const DEFAULT_RESIDUAL: f64 = 1e-4;

/// The damage at which a cell counts as torn by default (seed 000 §4.6.2: "say 0.8").
pub const DEFAULT_TORN: f64 = 0.8;

/// A damage law `g(r) = 1 − D(r)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum DamageLaw {
    /// Seed 000 Eq. 4.3: `g = β + (1 − β)(1 − e^{−r/α})/(r/α)`.
    Simo {
        /// α (√Pa, the units of `Φ`), > 0.
        alpha: f64,
        /// β ∈ [0, 1]: the stiffness fraction left at infinite strain.
        beta: f64,
        /// Floor on `g`.
        residual: f64,
        /// The `r` past which `g` sits on its floor (`∞` when it never does), set by
        /// [`DamageLaw::simo`].
        r_floor: f64,
    },
    /// Threshold and exponential softening: `g = (r₀/r) e^{A(1 − r/r₀)}` above `r₀`.
    Softening {
        /// Threshold `r₀` (√Pa).
        r0: f64,
        /// Softening parameter `A` (> 0).
        a: f64,
        /// Floor on `g`.
        residual: f64,
        /// The `r` past which `g` sits on its floor, set by [`DamageLaw::softening`].
        r_floor: f64,
    },
}

/// A damage law's parameters are out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LawError {
    /// A parameter is outside its range.
    #[error("{key} = {value} is out of range: {why}")]
    Range {
        /// The parameter's scene key.
        key: &'static str,
        /// Its value.
        value: f64,
        /// The admissible range.
        why: &'static str,
    },
    /// The element is too large for the fracture energy: the regularised softening would snap back.
    #[error(
        "a cell of size {size:.3e} m is too large for fracture_energy = {fracture_energy} J/m² and strength = {strength} Pa: the softening would snap back (the cell must be smaller than 2·G_f·E/f_t² = {limit:.3e} m); refine the mesh, raise fracture_energy or lower strength"
    )]
    CellTooLarge {
        /// The cell size `l`.
        size: f64,
        /// The limit `2 G_f E / f_t²`.
        limit: f64,
        /// `G_f`.
        fracture_energy: f64,
        /// `f_t`.
        strength: f64,
    },
}

fn check(key: &'static str, value: f64, ok: bool, why: &'static str) -> Result<(), LawError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(LawError::Range { key, value, why })
    }
}

impl DamageLaw {
    /// The seed's law with its range checks.
    pub fn simo(alpha: f64, beta: f64, residual: f64) -> Result<Self, LawError> {
        check("alpha", alpha, alpha > 0.0, "must be > 0 (√Pa)")?;
        check("beta", beta, (0.0..=1.0).contains(&beta), "must be in [0, 1]")?;
        check("residual", residual, residual > 0.0 && residual < 1.0, "must be in (0, 1)")?;
        Ok(Self::Simo {
            alpha,
            beta,
            residual,
            r_floor: f64::INFINITY,
        }
        .with_floor())
    }

    /// The softening law for a material of Young's modulus `young`, tensile strength
    /// `strength` (Pa) and fracture energy `fracture_energy` (J/m²) in a cell of size `size`
    /// (m): `r₀ = f_t/√E`, and `A` from `r₀²(½ + 1/A) = G_f/l`.
    pub fn softening(young: f64, strength: f64, fracture_energy: f64, size: f64, residual: f64) -> Result<Self, LawError> {
        check("strength", strength, strength > 0.0, "must be > 0 (Pa)")?;
        check("fracture_energy", fracture_energy, fracture_energy > 0.0, "must be > 0 (J/m²)")?;
        check("residual", residual, residual > 0.0 && residual < 1.0, "must be in (0, 1)")?;
        let r0 = strength / young.sqrt();
        let limit = 2.0 * fracture_energy / (r0 * r0);
        let inv_a = fracture_energy / (size * r0 * r0) - 0.5;
        if !(size > 0.0 && inv_a > 1e-9 && size < limit) {
            return Err(LawError::CellTooLarge {
                size,
                limit,
                fracture_energy,
                strength,
            });
        }
        Ok(Self::Softening {
            r0,
            a: 1.0 / inv_a,
            residual,
            r_floor: f64::INFINITY,
        }
        .with_floor())
    }

    /// The floor on `g`.
    pub fn residual(&self) -> f64 {
        match *self {
            Self::Simo { residual, .. } | Self::Softening { residual, .. } => residual,
        }
    }

    /// `g` of the law itself (no floor) and `g′(r)`.
    fn raw(&self, r: f64) -> (f64, f64) {
        match *self {
            Self::Simo { alpha, beta, .. } => {
                let x = r / alpha;
                // (1 − e^{−x})/x and its derivative, by series near 0 (no cancellation)
                // (1 − e^{−x})/x and its derivative (e^{−x}(1 + x) − 1)/x², by series near 0
                // and through expm1 elsewhere (no cancellation either way)
                let (f, df) = if x < 1e-3 {
                    (
                        1.0 - x / 2.0 + x * x / 6.0 - x * x * x / 24.0,
                        -0.5 + x / 3.0 - x * x / 8.0 + x * x * x / 30.0,
                    )
                } else {
                    let em1 = (-x).exp_m1();
                    (-em1 / x, (em1 * (1.0 + x) + x) / (x * x))
                };
                (beta + (1.0 - beta) * f, (1.0 - beta) * df / alpha)
            }
            Self::Softening { r0, a, .. } => {
                if r <= r0 {
                    (1.0, 0.0)
                } else {
                    let g = (r0 / r) * (a * (1.0 - r / r0)).exp();
                    (g, -g * (1.0 / r + a / r0))
                }
            }
        }
    }

    /// `g(r) = 1 − D` with the residual floor.
    pub fn g(&self, r: f64) -> f64 {
        self.raw(r).0.max(self.residual())
    }

    /// `h(r) = −g′(r)` (Eq. 4.4), zero where `g` sits on its floor.
    pub fn h(&self, r: f64) -> f64 {
        let (g, dg) = self.raw(r);
        if g <= self.residual() { 0.0 } else { -dg }
    }

    /// The energy dissipated per unit volume while `r` grows from `from` to `to`, exact:
    /// `∫ Ψ⁰ dD = ∫ (s²/2)(−g′(s)) ds` (on a loading path `Ψ⁰ = r²/2`), integrated by parts to
    /// `[−s² g/2 + ∫ s g ds]`; nothing is dissipated past the residual floor.
    pub fn dissipation(&self, from: f64, to: f64) -> f64 {
        if to <= from {
            return 0.0;
        }
        let cap = match *self {
            Self::Simo { r_floor, .. } | Self::Softening { r_floor, .. } => r_floor,
        };
        let (a, b) = (from.min(cap), to.min(cap));
        self.primitive(b) - self.primitive(a)
    }

    /// `F(s) = −s² g(s)/2 + ∫ s g ds`, whose increments are the dissipation.
    fn primitive(&self, s: f64) -> f64 {
        let g = self.raw(s).0;
        match *self {
            Self::Simo { alpha, beta, .. } => {
                -0.5 * s * s * g + 0.5 * beta * s * s + (1.0 - beta) * alpha * (s + alpha * (-s / alpha).exp())
            }
            Self::Softening { r0, a, .. } => {
                if s <= r0 {
                    0.0
                } else {
                    -0.5 * s * s * g + 0.5 * r0 * r0 - (r0 * r0 / a) * ((a * (1.0 - s / r0)).exp() - 1.0)
                }
            }
        }
    }

    /// The law with its `r_floor` computed.
    fn with_floor(mut self) -> Self {
        let r = self.floor_r();
        match &mut self {
            Self::Simo { r_floor, .. } | Self::Softening { r_floor, .. } => *r_floor = r,
        }
        self
    }

    /// The `r` past which `g` sits on the residual floor (`∞` when it never does), by
    /// bisection (once, at construction).
    fn floor_r(&self) -> f64 {
        let res = self.residual();
        if self.raw(1e300).0 >= res {
            return f64::INFINITY;
        }
        // g decreases monotonically: bisection on a bracket found by doubling
        let mut hi = match *self {
            Self::Simo { alpha, .. } => alpha,
            Self::Softening { r0, .. } => r0,
        };
        while self.raw(hi).0 > res {
            hi *= 2.0;
        }
        let mut lo = 0.0;
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if self.raw(mid).0 > res {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi - lo <= 1e-15 * hi {
                break;
            }
        }
        hi
    }

    /// The threshold below which the material is undamaged (`0` for the seed's law).
    pub fn threshold(&self) -> f64 {
        match *self {
            Self::Simo { .. } => 0.0,
            Self::Softening { r0, .. } => r0,
        }
    }
}

/// The state of one material point: `r = Φᵐ` and what the law gives at it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointState {
    /// The history maximum of `Φ` (√Pa).
    pub r: f64,
    /// `g = 1 − D` at `r`.
    pub g: f64,
    /// `h = −g′(r)` if the last update was loading, else 0 (the seed's Alg. 4.1, lines 13–19).
    pub h: f64,
}

impl PointState {
    /// A virgin point: no damage.
    pub const VIRGIN: Self = Self { r: 0.0, g: 1.0, h: 0.0 };

    /// The state after a strain whose equivalent strain is `phi` (Alg. 4.1, lines 13–19):
    /// loading when `phi > r` (then `r = phi`, `g`, `h` from the law), otherwise `g` kept and
    /// `h = 0`. Returns the energy dissipated per unit volume.
    pub fn update(&mut self, law: &DamageLaw, phi: f64) -> f64 {
        if phi > self.r {
            let d = law.dissipation(self.r.max(law.threshold()), phi);
            self.r = phi;
            self.g = law.g(phi);
            self.h = law.h(phi);
            d
        } else {
            self.h = 0.0;
            0.0
        }
    }

    /// The damage `D = 1 − g`.
    pub fn damage(&self) -> f64 {
        1.0 - self.g
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn simo() -> DamageLaw {
        DamageLaw::simo(0.4, 0.1, 1e-6).unwrap()
    }

    #[test]
    fn the_seeds_law_starts_undamaged_and_tends_to_beta() {
        let l = simo();
        assert!((l.g(0.0) - 1.0).abs() < 1e-15);
        assert!((l.g(1e-9) - 1.0).abs() < 1e-8);
        assert!(l.g(1e-3) < 1.0, "no threshold: damage starts at any Φ > 0");
        assert!((l.g(1e9) - 0.1).abs() < 1e-8);
    }

    #[test]
    fn h_is_minus_the_derivative_of_g_on_both_sides_of_the_series_switch() {
        for law in [simo(), DamageLaw::softening(5.0, 1.0, 0.5, 0.1, 1e-6).unwrap()] {
            for r in [1e-5f64, 3.9e-4, 4.1e-4, 0.01, 0.3, 0.47, 0.5, 1.0, 3.0] {
                let e = 1e-7 * r.max(1e-3);
                let fd = -(law.g(r + e) - law.g(r - e)) / (2.0 * e);
                if law.threshold() > 0.0 && (r - law.threshold()).abs() < 2.0 * e {
                    continue;
                }
                assert!(
                    (law.h(r) - fd).abs() <= 1e-6 * (1.0 + fd.abs()),
                    "{law:?} r {r}: h {} fd {fd}",
                    law.h(r)
                );
            }
        }
    }

    #[test]
    fn the_seeds_h_is_eq_4_4() {
        let (alpha, beta): (f64, f64) = (0.4, 0.1);
        let l = simo();
        for r in [0.01f64, 0.3, 2.0] {
            let eq44 = (1.0 - beta) / (r * r) * (alpha - (-r / alpha).exp() * (alpha + r));
            assert!((l.h(r) - eq44).abs() < 1e-12 * eq44.abs().max(1.0));
        }
    }

    #[test]
    fn the_softening_law_dissipates_the_fracture_energy_over_the_cell() {
        let (e, ft, gf, l) = (5000.0, 100.0, 0.05, 0.01);
        let law = DamageLaw::softening(e, ft, gf, l, 1e-12).unwrap();
        let total = law.dissipation(0.0, 1e6);
        assert!((total - gf / l).abs() < 1e-6 * gf / l, "{total} vs {}", gf / l);
        // the same by quadrature of σ dε along uniaxial stress (Φ = √E ε)
        let (mut w, n) = (0.0, 200_000);
        let emax = 60.0 * ft / e;
        for k in 0..n {
            let eps = (k as f64 + 0.5) * emax / n as f64;
            w += law.g(e.sqrt() * eps) * e * eps * emax / n as f64;
        }
        assert!((w - gf / l).abs() < 1e-3 * gf / l, "quadrature {w}");
    }

    #[test]
    fn a_cell_too_large_for_the_fracture_energy_is_refused_with_the_limit() {
        let err = DamageLaw::softening(5000.0, 100.0, 2.0, 3.0, 1e-4).unwrap_err();
        assert!(err.to_string().contains("too large"), "{err}");
        assert!(matches!(
            DamageLaw::simo(-1.0, 0.1, 1e-4),
            Err(LawError::Range { key: "alpha", .. })
        ));
        assert!(matches!(DamageLaw::simo(0.4, 1.5, 1e-4), Err(LawError::Range { key: "beta", .. })));
    }

    #[test]
    fn damage_never_heals_and_unloading_sets_h_to_zero() {
        let law = simo();
        let mut p = PointState::VIRGIN;
        p.update(&law, 0.5);
        let g = p.g;
        assert!(p.h > 0.0);
        assert_eq!(p.update(&law, 0.2), 0.0);
        assert_eq!((p.g, p.h, p.r), (g, 0.0, 0.5));
        p.update(&law, 0.5);
        assert_eq!(p.g, g);
        p.update(&law, 0.6);
        assert!(p.g < g);
    }

    #[test]
    fn the_residual_floor_holds_and_stops_dissipation() {
        let law = DamageLaw::simo(0.4, 0.0, 1e-3).unwrap();
        assert_eq!(law.g(1e9), 1e-3);
        assert_eq!(law.h(1e9), 0.0);
        let cap = law.floor_r();
        assert!((law.raw(cap).0 - 1e-3).abs() < 1e-9);
        assert_eq!(law.dissipation(cap, 2.0 * cap), 0.0);
    }
}
