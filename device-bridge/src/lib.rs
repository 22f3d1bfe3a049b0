//! The vademecum device bridge: the 1 kHz haptic loop beside the server, talking to the device
//! and, over iceoryx2 shared memory, to a session's tick thread.
//!
//! # Layout
//! - [`bridge_loop`]: the loop itself — read, send, receive, make safe, write, every period.
//! - [`guard`]: force safety (clamp, rate limit, watchdog fade) and input sanity (NaN,
//!   jumps, workspace).
//! - [`profile`]: per-device limits and the device ↔ organ frame map.
//! - [`device`]: drivers (simulated stylus, replay) and how to add a real one.
//! - [`link`]: the bridge's side of the channel; [`peer`]: the server's side, which a session's
//!   tick thread owns.
//! - [`timing`]: wait strategies (sleep, spin, hybrid) and real-time scheduling requests.
//! - [`trajectory`]: keyframed trajectories (the simulated hand; the server's scripted runs).
//!
//! [`cli`] is the command line of the binary `vademecum-bridge`, which wires these together; the server depends on this crate for
//! [`peer`] and for `vademecum bench haptic`. Never depends on the engine.
#![warn(missing_docs)]

pub mod bridge_loop;
pub mod cli;
pub mod device;
pub mod guard;
pub mod link;
pub mod peer;
pub mod presence;
pub mod profile;
pub mod tail;
pub mod timing;
pub mod trajectory;

pub use guard::{ForceSafetyEvent, safe_force};
