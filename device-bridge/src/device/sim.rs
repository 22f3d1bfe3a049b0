//! A simulated stylus: the device a test or a demo can run without hardware.
//!
//! The stylus is a point of mass `m` coupled to the user's hand by a spring `k` and a damper
//! `c`; the hand follows a scripted [`Trajectory`] `x_h(t)`, and the tissue pushes the stylus
//! with the rendered force `F`:
//!
//! ```text
//! m ẍ = k (x_h − x) + c (ẋ_h − ẋ) + F
//! ```
//!
//! integrated by semi-implicit Euler at each read (`v += dt·a; x += dt·v`), with the force
//! written at the previous tick held over the step — as a real device's servo would. With the
//! defaults (m = 0.05 kg, k = 300 N/m, ζ = 0.7) the free stylus follows the hand with a lag of
//! a few milliseconds; `ω·dt ≈ 0.08` at 1 kHz, far inside the explicit limit of 2, and still
//! below it with a tissue stiffness of several kN/m added to `k`.
//!
//! The motion is a function of the tick times only (the scheduled times, not the wall
//! clock), so two runs with the same forces read the same positions.

use super::{Device, DeviceError, DeviceReading};
use crate::trajectory::Trajectory;

/// Parameters of the hand model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandModel {
    /// Stylus (effective device) mass (kg).
    pub mass_kg: f64,
    /// Hand–stylus coupling stiffness (N/m).
    pub stiffness_n_per_m: f64,
    /// Damping ratio of the coupling.
    pub damping_ratio: f64,
}

impl Default for HandModel {
    fn default() -> Self {
        Self {
            mass_kg: 0.05,
            stiffness_n_per_m: 300.0,
            damping_ratio: 0.7,
        }
    }
}

/// The simulated stylus (see the [module docs](self)).
#[derive(Debug, Clone)]
pub struct SimStylus {
    hand: Trajectory,
    model: HandModel,
    damping_n_s_per_m: f64,
    x: [f64; 3],
    v: [f64; 3],
    t_s: f64,
    force_n: [f64; 3],
}

impl SimStylus {
    /// A stylus at rest at the hand's first position.
    pub fn new(hand: Trajectory, model: HandModel) -> Self {
        let x = hand.at(0.0).position_m;
        let damping_n_s_per_m = 2.0 * model.damping_ratio * (model.stiffness_n_per_m * model.mass_kg).sqrt();
        Self {
            hand,
            model,
            damping_n_s_per_m,
            x,
            v: [0.0; 3],
            t_s: 0.0,
            force_n: [0.0; 3],
        }
    }

    /// The hand's trajectory.
    pub fn hand(&self) -> &Trajectory {
        &self.hand
    }
}

impl Device for SimStylus {
    fn name(&self) -> &str {
        "sim"
    }

    fn read(&mut self, t_s: f64) -> Result<DeviceReading, DeviceError> {
        let dt = t_s - self.t_s;
        if dt > 0.0 {
            let h = self.hand.at(t_s);
            let (k, c, m) = (self.model.stiffness_n_per_m, self.damping_n_s_per_m, self.model.mass_kg);
            for i in 0..3 {
                let a = (k * (h.position_m[i] - self.x[i]) + c * (h.velocity_m_s[i] - self.v[i]) + self.force_n[i]) / m;
                self.v[i] += dt * a;
                self.x[i] += dt * self.v[i];
            }
            self.t_s = t_s;
        }
        let h = self.hand.at(t_s);
        Ok(DeviceReading {
            position_m: self.x,
            velocity_m_s: self.v,
            closure: h.closure,
            // the blade rides on the stylus as the hand holds it
            orientation: h.blade.map_or([0.0; 4], |b| b.orientation),
            blade_end_m: h.blade.map(|b| std::array::from_fn(|k| self.x[k] + b.end_m[k] - h.position_m[k])),
        })
    }

    fn write_force(&mut self, force_n: [f64; 3]) {
        self.force_n = force_n;
    }

    fn finished(&self, t_s: f64) -> bool {
        t_s > self.hand.duration_s()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hand() -> Trajectory {
        Trajectory::new(vec![
            (0.0, [0.0; 3], 0.0),
            (1.0, [0.0, 0.0, -0.01], 0.0),
            (2.0, [0.0, 0.0, -0.01], 0.0),
        ])
        .unwrap()
    }

    #[test]
    fn a_free_stylus_follows_the_hand() {
        let mut s = SimStylus::new(hand(), HandModel::default());
        let mut r = DeviceReading::default();
        for i in 1..=2000 {
            r = s.read(i as f64 * 1e-3).unwrap();
        }
        assert!((r.position_m[2] + 0.01).abs() < 1e-5, "{:?}", r.position_m);
    }

    #[test]
    fn a_rendered_force_pushes_the_stylus_back_by_f_over_k() {
        let mut s = SimStylus::new(hand(), HandModel::default());
        s.write_force([0.0, 0.0, 1.5]); // the tissue pushes up with 1.5 N
        let mut r = DeviceReading::default();
        for i in 1..=3000 {
            r = s.read(i as f64 * 1e-3).unwrap();
        }
        // equilibrium: k (x_h − x) + F = 0 → x = x_h + F/k = −0.01 + 0.005
        assert!((r.position_m[2] + 0.005).abs() < 1e-5, "{:?}", r.position_m);
    }
}
