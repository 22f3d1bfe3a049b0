//! The vademecum device bridge: the 1 kHz haptic loop beside the server.
//!
//! This crate currently holds the force-safety primitives the loop is built on; the iceoryx2
//! transport and device drivers join it with the device-bridge work.
#![warn(missing_docs)]

/// Why a device force was altered before reaching the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ForceSafetyEvent {
    /// A component was NaN or infinite; zero force was sent instead.
    #[error("non-finite force replaced by zero")]
    NonFinite,
    /// The magnitude exceeded the device profile's limit and was scaled down.
    #[error("force magnitude clamped to the device limit")]
    Clamped,
}

/// Returns a force safe to send to a device whose limit is `max_n` newtons:
/// zero if any component is not finite, scaled to `max_n` if longer than that.
pub fn safe_force(force_n: [f64; 3], max_n: f64) -> ([f64; 3], Option<ForceSafetyEvent>) {
    if force_n.iter().any(|c| !c.is_finite()) || !max_n.is_finite() {
        return ([0.0; 3], Some(ForceSafetyEvent::NonFinite));
    }
    let norm = force_n.iter().map(|c| c * c).sum::<f64>().sqrt();
    if norm > max_n {
        let s = max_n / norm;
        return (force_n.map(|c| c * s), Some(ForceSafetyEvent::Clamped));
    }
    (force_n, None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_force_becomes_zero() {
        let (f, ev) = safe_force([f64::NAN, 1.0, 0.0], 5.0);
        assert_eq!(f, [0.0; 3]);
        assert_eq!(ev, Some(ForceSafetyEvent::NonFinite));
    }

    #[test]
    fn long_force_is_scaled_to_limit_keeping_direction() {
        let (f, ev) = safe_force([6.0, 8.0, 0.0], 5.0);
        assert!((f[0] - 3.0).abs() < 1e-12 && (f[1] - 4.0).abs() < 1e-12);
        assert_eq!(ev, Some(ForceSafetyEvent::Clamped));
    }

    #[test]
    fn force_within_limit_is_untouched() {
        assert_eq!(safe_force([1.0, 2.0, 2.0], 5.0), ([1.0, 2.0, 2.0], None));
    }
}
