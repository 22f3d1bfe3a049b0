//! The command line's integration tests, as modules of one test binary: the `vademecum`
//! binary's commands (`cli`), shards and their merge (`shards`), and the deployment recipes
//! that run it (`chart`: the Helm chart; `deploy`: the systemd units and the Containerfile).
//! Run one module with `cargo test -p vademecum-cli --test it cli::`.

mod chart;
mod cli;
mod deploy;
mod shards;
