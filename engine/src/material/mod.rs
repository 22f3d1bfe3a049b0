//! Constitutive laws: linear elasticity here, the hyperelastic laws of large deformations in
//! [`hyperelastic`] (one type per law family, a single place to add a model).

pub mod hyperelastic;

use serde::{Deserialize, Serialize};

/// Why material parameters are unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MaterialError {
    /// Young's modulus must be positive and finite.
    #[error("young's modulus must be positive and finite (got {0} Pa)")]
    Young(f64),
    /// Poisson's ratio must lie in (−1, 0.5).
    #[error("poisson's ratio must lie in (-1, 0.5) (got {0}); use 0.49 or 0.499 for near-incompressible tissue")]
    Poisson(f64),
    /// Density must be positive and finite.
    #[error("density must be positive and finite (got {0} kg/m³)")]
    Density(f64),
}

/// Isotropic linear elasticity, `σ = λ tr(ε) I + 2 μ ε`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinearElastic {
    /// Young's modulus E (Pa).
    pub young: f64,
    /// Poisson's ratio ν (dimensionless, −1 < ν < 0.5).
    pub poisson: f64,
}

impl LinearElastic {
    /// Builds and validates a material.
    pub fn new(young: f64, poisson: f64) -> Result<Self, MaterialError> {
        let m = Self { young, poisson };
        m.validate()?;
        Ok(m)
    }

    /// Checks `E > 0` and `−1 < ν < 0.5`.
    pub fn validate(&self) -> Result<(), MaterialError> {
        if !(self.young.is_finite() && self.young > 0.0) {
            return Err(MaterialError::Young(self.young));
        }
        if !(self.poisson.is_finite() && self.poisson > -1.0 && self.poisson < 0.5) {
            return Err(MaterialError::Poisson(self.poisson));
        }
        Ok(())
    }

    /// Shear modulus `μ = E / 2(1+ν)` (Pa).
    pub fn shear(&self) -> f64 {
        self.young / (2.0 * (1.0 + self.poisson))
    }

    /// First Lamé parameter `λ = E ν / (1+ν)(1−2ν)` (Pa).
    pub fn lambda(&self) -> f64 {
        self.young * self.poisson / ((1.0 + self.poisson) * (1.0 - 2.0 * self.poisson))
    }

    /// Bulk modulus `κ = E / 3(1−2ν)` (Pa).
    pub fn bulk(&self) -> f64 {
        self.young / (3.0 * (1.0 - 2.0 * self.poisson))
    }
}

/// Checks a density (kg/m³).
pub fn validate_density(rho: f64) -> Result<(), MaterialError> {
    if rho.is_finite() && rho > 0.0 {
        Ok(())
    } else {
        Err(MaterialError::Density(rho))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lame_parameters_are_consistent() {
        let m = LinearElastic::new(160e3, 0.48).unwrap();
        assert!((m.lambda() + 2.0 / 3.0 * m.shear() - m.bulk()).abs() < 1e-9 * m.bulk());
    }

    #[test]
    fn bad_parameters_are_rejected() {
        assert_eq!(LinearElastic::new(-1.0, 0.3), Err(MaterialError::Young(-1.0)));
        assert_eq!(LinearElastic::new(1.0, 0.5), Err(MaterialError::Poisson(0.5)));
        assert!(LinearElastic::new(f64::NAN, 0.3).is_err());
    }
}
