//! The `vademecum` command line: parse the arguments ([`cli`]), run the command
//! ([`commands`]), print errors once to stderr with their cause chain, and exit with 0
//! (success), 1 (finished, but a check failed) or 2 (error). A closed stdout pipe exits 0.
//!
//! This crate sits above the server library (`vademecum_server`: `serve` and `run` start its
//! sessions), the engine (`build`, `solve`, `study`, `check`), the client SDK (the load and
//! session benches drive a server over gRPC) and the device bridge (`run --haptic`, `bench
//! haptic`); nothing below imports it. Plots and progress bars live here only.

use std::process::ExitCode;

use clap::Parser;

pub mod cli;
pub mod commands;
mod plot;
mod progress;

/// The whole `vademecum` command line: parse, run, report errors, exit status (the binary
/// is this one call; the end-to-end tests build their own binary around it).
pub fn main_entry() -> ExitCode {
    let args = cli::Cli::parse();
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("VADEMECUM_LOG").unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .init();
    match commands::run(args) {
        Ok(code) => code,
        Err(err) => {
            if is_broken_pipe(&err) {
                return ExitCode::SUCCESS;
            }
            eprintln!("vademecum: {err}");
            for cause in err.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::from(2)
        }
    }
}

fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
