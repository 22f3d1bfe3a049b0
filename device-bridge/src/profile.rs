//! Device profiles: the physical limits the safety layer enforces for one kind of device, and
//! the mapping between the device's frame and the organ's.
//!
//! Limits of the real devices are taken from their data sheets, rounded down; the force-rate
//! limits are our conservative choice (a palpation force changes by a few N/s; contact onset
//! by tens). Every limit can be overridden on the command line.

/// An axis-aligned box (m), in the device's own frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Workspace {
    /// Lower corner (m).
    pub min_m: [f64; 3],
    /// Upper corner (m).
    pub max_m: [f64; 3],
}

impl Workspace {
    /// A box centred on the device origin with these half-extents (m).
    pub const fn centered(half_m: [f64; 3]) -> Self {
        Self {
            min_m: [-half_m[0], -half_m[1], -half_m[2]],
            max_m: half_m,
        }
    }

    /// Whether `p` lies inside (boundary included).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|k| p[k] >= self.min_m[k] && p[k] <= self.max_m[k])
    }

    /// The nearest point of the box.
    pub fn clamp(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|k| p[k].clamp(self.min_m[k], self.max_m[k]))
    }

    /// Whether the box is well formed (finite, min ≤ max).
    pub fn is_valid(&self) -> bool {
        (0..3).all(|k| self.min_m[k].is_finite() && self.max_m[k].is_finite() && self.min_m[k] <= self.max_m[k])
    }
}

/// The limits of one kind of device.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceProfile {
    /// Profile name (`sim`, `falcon`, `touch`, `omega3`).
    pub name: &'static str,
    /// Largest force magnitude sent to the device (N).
    pub max_force_n: f64,
    /// Largest change of the force per second (N/s): a step is slewed at this rate.
    pub max_force_rate_n_per_s: f64,
    /// Fastest a hand moves the stylus (m/s): a faster step is clamped to this speed.
    pub max_speed_m_s: f64,
    /// Where the stylus can be (device frame).
    pub workspace: Workspace,
}

impl DeviceProfile {
    /// The simulated stylus: a generous workspace (±0.5 m), 10 N, 1000 N/s, 2 m/s.
    pub const SIM: Self = Self {
        name: "sim",
        max_force_n: 10.0,
        max_force_rate_n_per_s: 1000.0,
        max_speed_m_s: 2.0,
        workspace: Workspace::centered([0.5, 0.5, 0.5]),
    };
    /// Novint Falcon: ~9 N peak, a 10 cm cube.
    pub const FALCON: Self = Self {
        name: "falcon",
        max_force_n: 8.0,
        max_force_rate_n_per_s: 500.0,
        max_speed_m_s: 2.0,
        workspace: Workspace::centered([0.05, 0.05, 0.05]),
    };
    /// 3D Systems Touch: 3.3 N peak, 160 × 120 × 70 mm.
    pub const TOUCH: Self = Self {
        name: "touch",
        max_force_n: 3.0,
        max_force_rate_n_per_s: 300.0,
        max_speed_m_s: 2.0,
        workspace: Workspace::centered([0.08, 0.06, 0.035]),
    };
    /// Force Dimension omega.3: 12 N continuous, ∅160 × 110 mm.
    pub const OMEGA3: Self = Self {
        name: "omega3",
        max_force_n: 12.0,
        max_force_rate_n_per_s: 800.0,
        max_speed_m_s: 2.0,
        workspace: Workspace::centered([0.08, 0.08, 0.055]),
    };

    /// Every built-in profile.
    pub const ALL: [&'static Self; 4] = [&Self::SIM, &Self::FALCON, &Self::TOUCH, &Self::OMEGA3];

    /// The built-in profile `name`.
    pub fn named(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|p| p.name == name).map(|p| (*p).clone())
    }

    /// Checks that every limit is finite and positive.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |v: f64, what: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{what} must be a positive number, got {v}"))
            }
        };
        pos(self.max_force_n, "the force limit (N)")?;
        pos(self.max_force_rate_n_per_s, "the force-rate limit (N/s)")?;
        pos(self.max_speed_m_s, "the speed limit (m/s)")?;
        if !self.workspace.is_valid() {
            return Err("the workspace must be a finite box with min <= max on every axis".into());
        }
        Ok(())
    }
}

/// The affine map from the device frame to the organ frame:
/// `x_organ = origin_m + scale · x_device`; forces go back unscaled (`force_scale` = 1) unless
/// asked otherwise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameMap {
    /// Where the device origin lies in the organ frame (m).
    pub origin_m: [f64; 3],
    /// Motion scaling (organ metres per device metre).
    pub scale: f64,
    /// Device newtons per organ newton.
    pub force_scale: f64,
}

impl Default for FrameMap {
    fn default() -> Self {
        Self {
            origin_m: [0.0; 3],
            scale: 1.0,
            force_scale: 1.0,
        }
    }
}

impl FrameMap {
    /// Device position → organ position.
    pub fn to_organ(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|k| self.origin_m[k] + self.scale * p[k])
    }

    /// Device velocity → organ velocity.
    pub fn velocity_to_organ(&self, v: [f64; 3]) -> [f64; 3] {
        v.map(|c| self.scale * c)
    }

    /// Organ force → device force.
    pub fn force_to_device(&self, f: [f64; 3]) -> [f64; 3] {
        f.map(|c| self.force_scale * c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_profiles_are_valid_and_found_by_name() {
        for p in DeviceProfile::ALL {
            p.validate().unwrap();
            assert_eq!(DeviceProfile::named(p.name).as_ref(), Some(p));
        }
        assert!(DeviceProfile::named("phantom-x").is_none());
    }

    #[test]
    fn workspace_clamps_to_the_nearest_point() {
        let w = Workspace::centered([0.05, 0.05, 0.05]);
        assert!(w.contains([0.05, 0.0, -0.05]));
        assert_eq!(w.clamp([0.2, -0.01, -3.0]), [0.05, -0.01, -0.05]);
    }

    #[test]
    fn bad_limits_are_refused() {
        let mut p = DeviceProfile::SIM.clone();
        p.max_force_n = f64::NAN;
        assert!(p.validate().unwrap_err().contains("force limit"));
    }
}
