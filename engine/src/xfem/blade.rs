//! The scalpel's blade and the cut criterion (seed 000 §3.4, Fig. 3.3).
//!
//! The blade is a segment — its cutting edge from `a` to `b` — with an orientation: the unit
//! normal `n` of the blade's plane. The force the tissue exerts on the blade splits into
//!
//! `F = F⊥ + F∥ = F⊥ + F_a + F_n`,
//!
//! `F⊥ = (F·n) n` normal to the blade plane, `F_a` along the edge, `F_n` in the blade plane
//! across the edge (the cutting direction). Below the scalpel's `cut_force`, `|F∥|` is friction;
//! above it the cell the edge is in is cut, whole (the seed's simplification: no cut shorter
//! than a cell).

/// Why a blade state is not a blade.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum BladeError {
    /// A coordinate or a component of the orientation is NaN or infinite.
    #[error("the blade's end points or orientation are not finite")]
    NotFinite,
    /// The two end points coincide.
    #[error("the blade has zero length")]
    ZeroLength,
    /// The orientation's plane normal lies along the edge (no blade plane).
    #[error("the blade's orientation gives no plane through its edge")]
    NoPlane,
}

/// A blade: its cutting edge and the normal of its plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blade {
    /// One end of the edge (m).
    pub a: [f64; 3],
    /// The other end (m).
    pub b: [f64; 3],
    /// Unit edge direction `(b − a)/|b − a|`.
    pub axis: [f64; 3],
    /// Unit normal of the blade plane, orthogonal to the edge.
    pub normal: [f64; 3],
}

/// The force on the blade split along the blade (Fig. 3.3).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ForceSplit {
    /// `F⊥`, normal to the blade plane (N).
    pub perpendicular: [f64; 3],
    /// `F_a`, along the edge (N).
    pub axial: [f64; 3],
    /// `F_n`, in the blade plane across the edge (N).
    pub cutting: [f64; 3],
}

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

impl Blade {
    /// The blade with edge `a → b` whose plane normal is the tool frame's y axis turned by the
    /// unit quaternion `orientation` (`[w, x, y, z]`), made orthogonal to the edge.
    pub fn new(a: [f64; 3], b: [f64; 3], orientation: [f64; 4]) -> Result<Self, BladeError> {
        if !a.iter().chain(&b).chain(&orientation).all(|v| v.is_finite()) {
            return Err(BladeError::NotFinite);
        }
        let (va, vb) = (Vector3::from(a), Vector3::from(b));
        let e = vb - va;
        let size = va.norm().max(vb.norm()).max(1e-3);
        if e.norm() <= 1e-9 * size {
            return Err(BladeError::ZeroLength);
        }
        let axis = e.normalize();
        let [w, x, y, z] = orientation;
        let q = Quaternion::new(w, x, y, z);
        if q.norm() == 0.0 {
            return Err(BladeError::NoPlane);
        }
        let yaxis = UnitQuaternion::from_quaternion(q) * Vector3::y();
        let ortho = yaxis - axis * yaxis.dot(&axis);
        if ortho.norm() <= 1e-6 {
            return Err(BladeError::NoPlane);
        }
        Ok(Self {
            a,
            b,
            axis: axis.into(),
            normal: ortho.normalize().into(),
        })
    }

    /// Splits the force `f` on the blade (Fig. 3.3).
    pub fn split(&self, f: [f64; 3]) -> ForceSplit {
        let (f, n, t) = (Vector3::from(f), Vector3::from(self.normal), Vector3::from(self.axis));
        let perpendicular = n * f.dot(&n);
        let axial = t * f.dot(&t);
        ForceSplit {
            perpendicular: perpendicular.into(),
            axial: axial.into(),
            cutting: (f - perpendicular - axial).into(),
        }
    }
}

impl ForceSplit {
    /// `|F∥| = |F_a + F_n|`, the in-plane force the criterion compares with `cut_force`.
    pub fn in_plane(&self) -> f64 {
        (Vector3::from(self.axial) + Vector3::from(self.cutting)).norm()
    }

    /// The criterion of §3.4: whether the in-plane force exceeds `cut_force` (N). A non-finite
    /// force never cuts.
    pub fn cuts(&self, cut_force: f64) -> bool {
        let f = self.in_plane();
        f.is_finite() && f > cut_force
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_force_splits_into_three_orthogonal_parts_that_sum_back() {
        // edge along x, identity orientation: the blade plane is y = const (normal y)
        let blade = Blade::new([0.0; 3], [0.01, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]).unwrap();
        assert_eq!(blade.normal, [0.0, 1.0, 0.0]);
        let s = blade.split([0.3, -0.4, 1.2]);
        assert_eq!(s.perpendicular, [0.0, -0.4, 0.0]);
        assert_eq!(s.axial, [0.3, 0.0, 0.0]);
        assert_eq!(s.cutting, [0.0, 0.0, 1.2]);
        assert!((s.in_plane() - (0.09f64 + 1.44).sqrt()).abs() < 1e-15);
        assert!(s.cuts(1.0) && !s.cuts(1.3));
        // pressing the flat of the blade never cuts
        assert!(!blade.split([0.0, 50.0, 0.0]).cuts(1.0));
        assert!(!blade.split([f64::NAN, 0.0, 0.0]).cuts(1.0));
    }

    #[test]
    fn the_orientation_turns_the_blade_plane() {
        // a quarter turn about the edge (x): the plane normal goes from y to z
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let blade = Blade::new([0.0; 3], [1.0, 0.0, 0.0], [h, h, 0.0, 0.0]).unwrap();
        assert!((blade.normal[2] - 1.0).abs() < 1e-12 && blade.normal[1].abs() < 1e-12);
    }

    #[test]
    fn degenerate_blades_are_refused() {
        assert_eq!(Blade::new([0.0; 3], [0.0; 3], [1.0, 0.0, 0.0, 0.0]), Err(BladeError::ZeroLength));
        assert_eq!(
            Blade::new([f64::NAN, 0.0, 0.0], [1.0; 3], [1.0, 0.0, 0.0, 0.0]),
            Err(BladeError::NotFinite)
        );
        assert_eq!(Blade::new([0.0; 3], [1.0, 0.0, 0.0], [0.0; 4]), Err(BladeError::NoPlane));
        // the frame's y axis along the edge: no plane
        assert_eq!(
            Blade::new([0.0; 3], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.0]),
            Err(BladeError::NoPlane)
        );
    }
}
