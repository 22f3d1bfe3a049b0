//! The server crate's integration tests (the `vademecum` binary's commands, charts, shards and
//! deployment recipes), as modules of one test binary. `session.rs` stays apart: it installs
//! its own counting global allocator.
//! Run one module with `cargo test -p vademecum-server --test it cli::`.

mod chart;
mod cli;
mod deploy;
mod shards;
