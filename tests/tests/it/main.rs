//! The end-to-end tests across processes, as modules of one test binary (one link instead of
//! one per file).
//! Run one module with `cargo test -p vademecum-tests --test it haptic::`.

mod util;

mod agones;
mod bundle_store;
mod composed;
mod cutting;
mod devices;
mod fleet;
mod haptic;
mod hardening;
mod load;
mod python;
mod server;
mod tearing;
mod web;
