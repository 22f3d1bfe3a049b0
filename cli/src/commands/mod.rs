//! The subcommands, one file each.

mod bench;
mod bench_anm;
mod bench_corot;
mod bench_cube;
mod bench_cut;
mod bench_cut_session;
mod bench_effects;
mod bench_efg;
mod bench_haptic;
mod bench_load;
mod bench_load_chaos;
mod bench_load_client;
mod bench_pgd;
mod bench_session;
mod bench_tear;
mod build;
mod check;
mod drain;
mod frame_cost;
mod health;
mod inspect;
mod mesh_info;
mod publish;
mod run;
mod run_haptic;
mod scene;
mod scene_input;
mod serve;
mod solve;
mod study;
mod study_cut;
mod study_estimate;
mod study_lattice;
mod study_mesh;
mod study_meshless;
mod study_report;
mod study_tear;
mod tear_timing;

use std::path::Path;
use std::process::ExitCode;

use anyhow::{Context, bail};

use crate::cli::{BenchCommand, CheckCommand, Cli, Command, MeshCommand};

/// A credential file a user names (a TLS certificate or key, a CA bundle), read only if it is
/// a regular file of at most `MAX_CREDENTIAL_BYTES`.
fn credential(path: &Path) -> std::io::Result<Vec<u8>> {
    vademecum_engine::files::read_regular(path, vademecum_engine::files::MAX_CREDENTIAL_BYTES)
}

/// The bearer tokens of a tokens file (`serve --tokens-file`, `drain --tokens-file`): one per
/// line, blank lines and `#` comments skipped; an error when it holds none.
fn tokens_in_file(path: &Path) -> anyhow::Result<Vec<String>> {
    let text = vademecum_engine::files::read_regular_text(path, vademecum_engine::files::MAX_CREDENTIAL_BYTES)
        .with_context(|| format!("cannot read token file {}", path.display()))?;
    let tokens: Vec<String> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(String::from)
        .collect();
    if tokens.is_empty() {
        bail!("token file {} holds no token", path.display());
    }
    Ok(tokens)
}

/// The items of a comma-separated list (VADEMECUM_TOKENS, VADEMECUM_PEERS), blanks skipped.
fn comma_list(list: &str) -> Vec<String> {
    list.split(',').map(str::trim).filter(|t| !t.is_empty()).map(String::from).collect()
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Solve(a) => solve::run(a),
        Command::Build(a) => build::run(a),
        Command::Merge(a) => build::merge(a),
        Command::Inspect(a) => inspect::run(a),
        Command::Run(a) => run::run(a),
        Command::Serve(a) => serve::run(*a),
        Command::Health(a) => health::run(a),
        Command::Drain(a) => drain::run(a),
        Command::Publish(a) => publish::run(a),
        Command::Mesh(MeshCommand::Info(a)) => mesh_info::run(a),
        Command::Scene(c) => scene::run(c),
        Command::Check(CheckCommand::HardCases(a)) => check::hard_cases(a),
        Command::Study(a) => study::run(a),
        Command::Bench(BenchCommand::Fe(a)) => bench::run_fe(a),
        Command::Bench(BenchCommand::Pgd(a)) => bench_pgd::run(a),
        Command::Bench(BenchCommand::Session(a)) => bench_session::run(a),
        Command::Bench(BenchCommand::Load(a)) => bench_load::run(a),
        Command::Bench(BenchCommand::LoadClient(a)) => bench_load_chaos::run(a),
        Command::Bench(BenchCommand::Haptic(a)) => bench_haptic::run(a),
        Command::Bench(BenchCommand::Cube(a)) => bench_cube::run(a),
        Command::Bench(BenchCommand::Anm(a)) => bench_anm::run(a),
        Command::Bench(BenchCommand::Efg(a)) => bench_efg::run(a),
        Command::Bench(BenchCommand::Cut(a)) => bench_cut::run(a),
        Command::Bench(BenchCommand::Tear(a)) => bench_tear::run(a),
        Command::Bench(BenchCommand::Corot(a)) => bench_corot::run(a),
        Command::Bench(BenchCommand::Effects(a)) => bench_effects::run(a),
    }
}

/// A point or direction as `(x, y, z)` with `decimals` decimals.
pub fn vec3(v: [f64; 3], decimals: usize) -> String {
    format!("({:.d$}, {:.d$}, {:.d$})", v[0], v[1], v[2], d = decimals)
}
