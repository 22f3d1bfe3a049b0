//! The fidelity governor: when a session's ticks come close to missing their deadline, the
//! session falls back to the cheaper setting of its effects (engine `Fidelity::Reduced`: the
//! large-deformation law on the lattice's nearest position) and its frames to the fewest modes
//! that meet [`FALLBACK_FIELD_ERROR`] — both points of the study's front —, says so in every
//! answer (`EVENT_REDUCED_FIDELITY`) and in the metrics, and returns when the load falls.
//!
//! The pressure of a period is what of its budget was gone when its tick finished: how late
//! the tick started plus the work it did (both measured by the tick loop already). A period is
//! a close call when its pressure exceeds half the period. The session falls back when at
//! least [`FALL_BACK_SHARE`] of a window of [`WINDOW`] periods were close calls (sustained
//! load: a noisy VM's stray late wake-ups are well under it), and returns after a window of
//! [`CALM_WINDOW`] periods with at most [`RETURN_SHARE`] of them (2 s at 1 kHz: the load has
//! gone, not paused). The two shares differ so that a load near one threshold does not make
//! the session flap. Plain counters on the tick thread: no allocation, no lock, no clock read
//! of its own.

use std::time::Duration;

use vademecum_engine::pipeline::Fidelity;

/// The field error the frames fall back to (the relative L2 error of the displacement field
/// the build measured): 1 %, what `docs/accuracy.md` finds enough for a viewer.
pub const FALLBACK_FIELD_ERROR: f64 = 1e-2;

/// Periods per window of the fall-back decision (200 ms at 1 kHz).
pub const WINDOW: u32 = 200;

/// The share of close calls in a [`WINDOW`] that makes the session fall back.
pub const FALL_BACK_SHARE: f64 = 0.05;

/// Periods per window of the return decision (2 s at 1 kHz).
pub const CALM_WINDOW: u32 = 2000;

/// The largest share of close calls in a [`CALM_WINDOW`] with which the session returns.
pub const RETURN_SHARE: f64 = 0.01;

/// The governor of one session (see the [module docs](self)).
#[derive(Debug, Clone)]
pub struct Governor {
    enabled: bool,
    reduced: bool,
    /// Half the period (ns): a period over it is a close call.
    high_ns: u64,
    /// Periods seen in the current window, and the close calls among them.
    seen: u32,
    over: u32,
}

impl Governor {
    /// A governor for ticks of `period`, or one that never falls back (`enabled` false: the
    /// scene's `fidelity.fallback = "off"`).
    pub fn new(period: Duration, enabled: bool) -> Self {
        Self {
            enabled,
            reduced: false,
            high_ns: period.as_nanos() as u64 / 2,
            seen: 0,
            over: 0,
        }
    }

    /// Whether the session runs reduced.
    pub fn reduced(&self) -> bool {
        self.reduced
    }

    /// One period's pressure (ns: its tick's lateness plus its work); the new fidelity when it
    /// changes.
    pub fn observe(&mut self, pressure_ns: u64) -> Option<Fidelity> {
        if !self.enabled {
            return None;
        }
        self.seen += 1;
        self.over += u32::from(pressure_ns > self.high_ns);
        let (window, share) = if self.reduced {
            (CALM_WINDOW, RETURN_SHARE)
        } else {
            (WINDOW, FALL_BACK_SHARE)
        };
        let limit = (share * f64::from(window)) as u32;
        if !self.reduced && self.over >= limit {
            // no need to wait for the window's end: the share is reached
            self.reduced = true;
            (self.seen, self.over) = (0, 0);
            return Some(Fidelity::Reduced);
        }
        if self.seen < window {
            return None;
        }
        let calm = self.over <= limit;
        (self.seen, self.over) = (0, 0);
        if self.reduced && calm {
            self.reduced = false;
            return Some(Fidelity::Full);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn falls_back_under_sustained_close_calls_and_not_on_stray_ones() {
        let mut g = Governor::new(MS, true);
        let limit = (FALL_BACK_SHARE * f64::from(WINDOW)) as u32;
        // one close call short of the share in every window, for ever: noise, not load
        for i in 0..10 * WINDOW {
            let p = if i % WINDOW < limit - 1 { 900_000 } else { 20_000 };
            assert_eq!(g.observe(p), None, "period {i}");
        }
        assert!(!g.reduced());
        // the share within one window
        for _ in 0..limit - 1 {
            assert_eq!(g.observe(600_000), None);
        }
        assert_eq!(g.observe(20_000), None);
        assert_eq!(g.observe(800_000), Some(Fidelity::Reduced));
        assert!(g.reduced());
        // close calls while reduced change nothing
        assert_eq!(g.observe(900_000), None);
    }

    #[test]
    fn returns_after_a_calm_window_and_not_while_the_load_goes_on() {
        let mut g = Governor::new(MS, true);
        let limit = (FALL_BACK_SHARE * f64::from(WINDOW)) as u32;
        for _ in 0..limit {
            g.observe(2_000_000);
        }
        assert!(g.reduced());
        // a window with 2 % close calls: still loaded
        for i in 0..CALM_WINDOW {
            assert_eq!(g.observe(if i % 50 == 0 { 700_000 } else { 10_000 }), None);
        }
        assert!(g.reduced());
        // a window with 1 % (the share allowed): calm
        for i in 0..CALM_WINDOW - 1 {
            assert_eq!(g.observe(if i % 100 == 0 { 700_000 } else { 10_000 }), None);
        }
        assert_eq!(g.observe(10_000), Some(Fidelity::Full));
        assert!(!g.reduced());
        // and it can fall back again
        for _ in 0..limit - 1 {
            assert_eq!(g.observe(2_000_000), None);
        }
        assert_eq!(g.observe(2_000_000), Some(Fidelity::Reduced));
    }

    #[test]
    fn a_scene_that_turns_it_off_keeps_its_settings() {
        let mut g = Governor::new(MS, false);
        for _ in 0..10 * WINDOW {
            assert_eq!(g.observe(5_000_000), None);
        }
        assert!(!g.reduced());
    }
}
