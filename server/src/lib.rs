//! The vademecum server: sessions that simulate a scene in real time, and (next) the gRPC
//! services in front of them.
//!
//! # Layout
//! - [`session`]: a session — a scene, its loaded bundles shared read-only, the effect
//!   pipeline — and its threads: the real-time tick thread (1 kHz, owns the pipeline, never
//!   awaits, never takes a lock a request handler can hold) and the frame thread (displacement
//!   frames for viewers at display rate, through a latest-value slot). Scripted trajectories
//!   for headless runs, and tick statistics.
//!
//! The `vademecum` binary (`main.rs`, `cli.rs`, `commands/`) is a thin command line over this
//! library and the engine.

pub mod session;
