//! Device drivers: where tool positions come from and where forces go.
//!
//! # Layout
//! - [`sim::SimStylus`]: a simulated stylus — a point mass held by a spring–damper "hand"
//!   that follows a scripted trajectory and is pushed back by the rendered force.
//! - [`replay::Replay`]: recorded device samples from CSV, replayed as they are (bad samples
//!   included, which the input guard then has to handle).
//! - [`NullDevice`]: a fixed position; the benchmark's null loop.
//!
//! # Adding a real device
//!
//! A driver implements [`Device`]: `read` returns the stylus position in the device's own
//! frame (m) at the tick, `write_force` hands the shaped force (N, device frame) to the
//! hardware, and `release` zeroes the force and lets go of the device. Register it in
//! `DeviceKind` in `main.rs` behind a cargo feature that links the vendor library, and give it
//! a [`DeviceProfile`](crate::profile::DeviceProfile) with the data-sheet limits. Sketches of
//! the calls for the common SDKs:
//!
//! - Force Dimension SDK (`libdhd`): `dhdOpen()` in `open`; `dhdGetPosition(&x, &y, &z)` in
//!   `read`; `dhdSetForce(fx, fy, fz)` in `write_force`; `dhdSetForce(0,0,0)` then `dhdClose()`
//!   in `release`. Frame: metres, same handedness.
//! - OpenHaptics HD API (3D Systems Touch): `hdInitDevice`, then inside
//!   `hdBeginFrame`/`hdEndFrame`: `hdGet(HD_CURRENT_POSITION)` (millimetres: divide by 1000)
//!   and `hdSet(HD_CURRENT_FORCE)`. Its own servo loop calls back at 1 kHz: run the bridge's
//!   tick from that callback instead of from our timer.
//! - libnifalcon (Novint Falcon): `FalconDevice::runIOLoop()` then `getPosition()` /
//!   `setForce()`; positions in metres with an offset of about 0.11 m along z.
//!
//! None of these libraries is packaged for the machines we build on, so no real driver ships
//! yet; the sim and replay drivers exercise the same code path.

pub mod replay;
pub mod sim;

/// What a device reports at one tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DeviceReading {
    /// Stylus position, device frame (m). May be non-finite: the input guard handles it.
    pub position_m: [f64; 3],
    /// Stylus velocity, device frame (m/s), if the device measures it.
    pub velocity_m_s: [f64; 3],
    /// Gripper closure, 0 to 1.
    pub closure: f64,
    /// Stylus orientation, unit quaternion `[w, x, y, z]` (all zeros: the device does not
    /// measure it; taken as the identity).
    pub orientation: [f64; 4],
    /// A scalpel's blade: the other end of its cutting edge, device frame (m); the position is
    /// its tip.
    pub blade_end_m: Option<[f64; 3]>,
}

/// Why a device failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DeviceError {
    /// The device could not be opened.
    #[error("cannot open the device: {0}")]
    Open(String),
    /// The device stopped answering.
    #[error("the device stopped answering: {0}")]
    Lost(String),
}

/// A haptic device driver (see the [module docs](self) for how to add one).
pub trait Device {
    /// Driver name, for reports.
    fn name(&self) -> &str;
    /// Reads the stylus at time `t_s` (seconds since the loop started, the tick's scheduled
    /// time). Called once per tick, before anything else.
    fn read(&mut self, t_s: f64) -> Result<DeviceReading, DeviceError>;
    /// Renders `force_n` (device frame) until the next call.
    fn write_force(&mut self, force_n: [f64; 3]);
    /// Whether the device has nothing more to play (a replay or a script reached its end).
    fn finished(&self, _t_s: f64) -> bool {
        false
    }
    /// Zeroes the force and lets go of the device (also on error paths).
    fn release(&mut self) {
        self.write_force([0.0; 3]);
    }
}

/// A device that stays at one position and ignores forces: the null loop of the benchmark.
#[derive(Debug, Clone, Default)]
pub struct NullDevice {
    /// The fixed position (m).
    pub position_m: [f64; 3],
}

impl Device for NullDevice {
    fn name(&self) -> &str {
        "null"
    }
    fn read(&mut self, _t_s: f64) -> Result<DeviceReading, DeviceError> {
        Ok(DeviceReading {
            position_m: self.position_m,
            ..DeviceReading::default()
        })
    }
    fn write_force(&mut self, _force_n: [f64; 3]) {}
}
