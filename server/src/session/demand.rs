//! What the viewers of a session ask of its frame thread: frames at twice the highest rate any
//! of them watches at (so every viewer's tick finds a frame at most half its period old: two
//! clocks at one rate would drift into ticks that find none), never above the session's frame
//! rate — a session watched at 5 Hz does not compute 60 frames a second (a frame evaluates
//! every mode of the organ's vademecum on its surface: the largest CPU cost of a watched
//! session, `BENCHMARKS.md`, "bench load").

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Weak};
use std::time::Duration;

/// The rates viewers ask for.
#[derive(Debug, Default)]
pub struct FrameDemand {
    /// Each viewer's rate (Hz), by its id.
    rates: Mutex<Vec<(u64, f64)>>,
    next_id: AtomicU64,
    /// The highest rate asked, as `f64` bits (0: none asked).
    max_hz: AtomicU64,
}

/// A viewer's demand: withdrawn when dropped.
#[derive(Debug)]
pub struct DemandGuard {
    demand: Weak<FrameDemand>,
    id: u64,
}

impl FrameDemand {
    /// A viewer asks for frames at `rate_hz` (finite and positive; anything else asks
    /// nothing) until the guard is dropped.
    pub fn ask(self: &Arc<Self>, rate_hz: f64) -> DemandGuard {
        let id = self.next_id.fetch_add(1, Ordering::Relaxed);
        if rate_hz.is_finite() && rate_hz > 0.0 {
            self.update(|rates| rates.push((id, rate_hz)));
        }
        DemandGuard {
            demand: Arc::downgrade(self),
            id,
        }
    }

    fn update(&self, change: impl FnOnce(&mut Vec<(u64, f64)>)) {
        let mut rates = self.rates.lock().unwrap_or_else(|e| e.into_inner());
        change(&mut rates);
        let max = rates.iter().map(|r| r.1).fold(0.0, f64::max);
        self.max_hz.store(max.to_bits(), Ordering::Relaxed);
    }

    /// The highest rate asked (Hz; 0 when no viewer asks).
    pub fn max_hz(&self) -> f64 {
        f64::from_bits(self.max_hz.load(Ordering::Relaxed))
    }

    /// The frame interval: half the fastest viewer's period, never shorter than `fastest` (the
    /// session's frame rate); `fastest` when no viewer says (a subscriber without a demand).
    pub fn interval(&self, fastest: Duration) -> Duration {
        let hz = self.max_hz();
        if hz > 0.0 {
            Duration::from_secs_f64(0.5 / hz).max(fastest)
        } else {
            fastest
        }
    }
}

impl Drop for DemandGuard {
    fn drop(&mut self) {
        if let Some(d) = self.demand.upgrade() {
            let id = self.id;
            d.update(|rates| rates.retain(|r| r.0 != id));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_interval_follows_the_fastest_viewer_within_the_session_rate() {
        let d = Arc::new(FrameDemand::default());
        let fastest = Duration::from_secs_f64(1.0 / 60.0);
        assert_eq!(d.interval(fastest), fastest, "no demand: the session's rate");
        let slow = d.ask(5.0);
        assert_eq!(d.interval(fastest), Duration::from_secs_f64(0.1), "twice the viewer's rate");
        let normal = d.ask(20.0);
        assert_eq!(d.interval(fastest), Duration::from_secs_f64(1.0 / 40.0));
        let greedy = d.ask(1000.0);
        assert_eq!(d.interval(fastest), fastest, "never above the session's rate");
        let nothing = d.ask(f64::NAN);
        drop(greedy);
        assert_eq!(d.interval(fastest), Duration::from_secs_f64(1.0 / 40.0));
        drop((normal, nothing));
        assert_eq!(d.interval(fastest), Duration::from_secs_f64(0.1));
        drop(slow);
        assert_eq!((d.max_hz(), d.interval(fastest)), (0.0, fastest));
    }
}
