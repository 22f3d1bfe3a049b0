//! What the online tearing step costs, timed the same way by `vademecum build` (the bundle's
//! tick figures) and by the tearing study.

use std::sync::Arc;
use std::time::Instant;

use vademecum_engine::damage::online::{OnlineTear, StepLimits, TearOffline, Variant};

/// The pull along the diagonal of the load and the two directions across it: a step with it
/// engages every pull pattern's modes (what the tick costs while the grasper pulls obliquely).
pub(crate) const EVERY_DIRECTION: [f64; 3] = [0.577_350_269_189_625_8; 3];

/// The online step's times (µs), at least `n` of them, over whole schedules of `off` from the
/// virgin state, each step pulling with the multipliers `mix` of the schedule's increment
/// (`[1, 0, 0]`: along the load; a mix of all three engages every pull pattern's modes).
pub(crate) fn step_times(off: &Arc<TearOffline>, variant: Variant, limits: StepLimits, mix: [f64; 3], n: usize) -> Vec<f64> {
    let mut times = Vec::with_capacity(n + off.model.schedule.len());
    while times.len() < n {
        let mut online = OnlineTear::new(off.clone(), variant, limits);
        for &ds in &off.model.schedule {
            let t = Instant::now();
            std::hint::black_box(online.step_pull(mix.map(|m| m * ds)));
            times.push(t.elapsed().as_secs_f64() * 1e6);
        }
        if off.model.schedule.is_empty() {
            break;
        }
    }
    times
}
