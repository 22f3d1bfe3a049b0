//! Force safety and input sanity: what stands between the network and the device.
//!
//! Each tick, in this order:
//!
//! 1. [`InputGuard::admit`] — the device sample: a non-finite component holds the last good
//!    position; a position outside the workspace is clamped to it; a step faster than
//!    [`DeviceProfile::max_speed_m_s`] is shortened to that speed. Each case is counted, and
//!    the state sent to the server carries a flag.
//! 2. [`ForceGuard::shape`] — the force to render: non-finite → zero; longer than
//!    [`DeviceProfile::max_force_n`] → scaled to it; changing faster than
//!    [`DeviceProfile::max_force_rate_n_per_s`] → slewed at that rate.
//! 3. The watchdog ([`watchdog_scale`]) — when no fresh force arrived for a while, the force
//!    fades to zero: held for [`HOLD_TICKS`] tick (a late answer is normal on a busy host),
//!    then ramped down over [`FADE_TICKS`] ticks, so it is exactly zero
//!    `HOLD_TICKS + FADE_TICKS` = 4 ticks after the last fresh force: within the 5-tick
//!    budget of the design, and gentle enough (a few ms) not to kick the user's hand.
//!
//! After a fade, the rate limit also ramps a returning force up from zero, so a server that
//! comes back does not jolt the device.

use crate::profile::{DeviceProfile, Workspace};

/// Ticks a stale force is held at full strength.
pub const HOLD_TICKS: u32 = 1;
/// Ticks over which a stale force then fades to zero.
pub const FADE_TICKS: u32 = 3;

/// The watchdog's factor on the force, `age` ticks after the last fresh force (0: fresh).
pub fn watchdog_scale(age: u32) -> f64 {
    if age <= HOLD_TICKS {
        1.0
    } else {
        (1.0 - f64::from(age - HOLD_TICKS) / f64::from(FADE_TICKS)).max(0.0)
    }
}

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
    let norm = norm(force_n);
    if norm > max_n {
        let s = max_n / norm;
        return (force_n.map(|c| c * s), Some(ForceSafetyEvent::Clamped));
    }
    (force_n, None)
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// What [`InputGuard::admit`] did to a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct InputVerdict {
    /// A component was not finite: the last good position was kept.
    pub non_finite: bool,
    /// Outside the workspace: clamped to it.
    pub outside: bool,
    /// Faster than a hand: the step was shortened.
    pub jump: bool,
}

impl InputVerdict {
    /// Whether the sample was changed.
    pub fn adjusted(&self) -> bool {
        self.non_finite || self.outside || self.jump
    }
}

/// Sanity of device samples (step 1 of the [module docs](self)).
#[derive(Debug, Clone)]
pub struct InputGuard {
    workspace: Workspace,
    max_step_m: f64,
    last: Option<[f64; 3]>,
}

impl InputGuard {
    /// For `profile`, at a tick period of `dt_s` seconds.
    pub fn new(profile: &DeviceProfile, dt_s: f64) -> Self {
        Self {
            workspace: profile.workspace,
            max_step_m: profile.max_speed_m_s * dt_s,
            last: None,
        }
    }

    /// The admitted position (device frame) for a raw sample, and what was done to it.
    /// Before any good sample, a non-finite one is admitted as the workspace centre.
    pub fn admit(&mut self, raw_m: [f64; 3]) -> ([f64; 3], InputVerdict) {
        let mut v = InputVerdict::default();
        let mut p = if raw_m.iter().all(|c| c.is_finite()) {
            raw_m
        } else {
            v.non_finite = true;
            self.last
                .unwrap_or_else(|| [0, 1, 2].map(|k| 0.5 * (self.workspace.min_m[k] + self.workspace.max_m[k])))
        };
        if !self.workspace.contains(p) {
            v.outside = true;
            p = self.workspace.clamp(p);
        }
        if let Some(last) = self.last {
            let d = [p[0] - last[0], p[1] - last[1], p[2] - last[2]];
            let len = norm(d);
            if len > self.max_step_m {
                v.jump = true;
                let s = self.max_step_m / len;
                p = [0, 1, 2].map(|k| last[k] + s * d[k]);
            }
        }
        self.last = Some(p);
        (p, v)
    }
}

/// What [`ForceGuard::shape`] did to a force.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ForceVerdict {
    /// Non-finite: replaced by zero.
    pub non_finite: bool,
    /// Too long: scaled to the limit.
    pub clamped: bool,
    /// Changing too fast: slewed.
    pub rate_limited: bool,
}

/// Shaping of the forces sent to the device (steps 2–3 of the [module docs](self)).
#[derive(Debug, Clone)]
pub struct ForceGuard {
    max_n: f64,
    max_step_n: f64,
    last_n: [f64; 3],
}

impl ForceGuard {
    /// For `profile`, at a tick period of `dt_s` seconds.
    pub fn new(profile: &DeviceProfile, dt_s: f64) -> Self {
        Self {
            max_n: profile.max_force_n,
            max_step_n: profile.max_force_rate_n_per_s * dt_s,
            last_n: [0.0; 3],
        }
    }

    /// The force to write for a `target` force, scaled by the watchdog factor `scale`
    /// (1 when fresh; see [`watchdog_scale`]).
    pub fn shape(&mut self, target_n: [f64; 3], scale: f64) -> ([f64; 3], ForceVerdict) {
        let mut v = ForceVerdict::default();
        let (mut f, event) = safe_force(target_n, self.max_n);
        match event {
            Some(ForceSafetyEvent::NonFinite) => v.non_finite = true,
            Some(ForceSafetyEvent::Clamped) => v.clamped = true,
            None => {}
        }
        let d = [f[0] - self.last_n[0], f[1] - self.last_n[1], f[2] - self.last_n[2]];
        let len = norm(d);
        if len > self.max_step_n {
            v.rate_limited = true;
            let s = self.max_step_n / len;
            f = [0, 1, 2].map(|k| self.last_n[k] + s * d[k]);
        }
        let out = f.map(|c| c * scale);
        self.last_n = out;
        (out, v)
    }

    /// The last force written (N).
    pub fn last(&self) -> [f64; 3] {
        self.last_n
    }
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

    #[test]
    fn the_watchdog_holds_one_tick_then_reaches_zero_within_five() {
        assert_eq!(watchdog_scale(0), 1.0);
        assert_eq!(watchdog_scale(1), 1.0);
        assert!(watchdog_scale(2) < 1.0 && watchdog_scale(2) > watchdog_scale(3));
        assert_eq!(watchdog_scale(4), 0.0);
        assert_eq!(watchdog_scale(5), 0.0);
        assert_eq!(watchdog_scale(u32::MAX), 0.0);
    }

    #[test]
    fn a_force_step_is_slewed_and_never_exceeds_the_limit() {
        let p = DeviceProfile::SIM; // 10 N, 1000 N/s: 1 N per ms
        let mut g = ForceGuard::new(&p, 1e-3);
        let (f, v) = g.shape([0.0, 0.0, 50.0], 1.0);
        assert!(v.clamped && v.rate_limited);
        assert!((f[2] - 1.0).abs() < 1e-12, "{f:?}");
        let mut last = f[2];
        for _ in 0..20 {
            let (f, _) = g.shape([0.0, 0.0, 50.0], 1.0);
            assert!(f[2] - last <= 1.0 + 1e-12 && f[2] <= 10.0 + 1e-12);
            last = f[2];
        }
        assert!((last - 10.0).abs() < 1e-12);
        let (f, v) = g.shape([f64::INFINITY, 0.0, 0.0], 1.0);
        assert!(v.non_finite && f.iter().all(|c| c.is_finite()));
        assert!((f[2] - 9.0).abs() < 1e-12, "a non-finite force ramps down, it does not jump: {f:?}");
    }

    #[test]
    fn nan_jumps_and_excursions_are_held_shortened_and_clamped() {
        let p = DeviceProfile::FALCON; // ±5 cm, 2 m/s: 2 mm per ms
        let mut g = InputGuard::new(&p, 1e-3);
        let (x, v) = g.admit([0.01, 0.0, 0.0]);
        assert_eq!((x, v.adjusted()), ([0.01, 0.0, 0.0], false));
        let (x, v) = g.admit([f64::NAN, 0.0, 0.0]);
        assert!(v.non_finite && !v.jump && x == [0.01, 0.0, 0.0]);
        let (x, v) = g.admit([0.03, 0.0, 0.0]);
        assert!(v.jump && (x[0] - 0.012).abs() < 1e-12, "{x:?}");
        let (x, v) = g.admit([0.012, 0.3, 0.0]);
        assert!(v.outside && v.jump, "{v:?}");
        assert!((x[1] - 0.002).abs() < 1e-12, "{x:?}");
    }
}
