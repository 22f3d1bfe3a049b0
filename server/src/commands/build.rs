//! `vademecum build`: PGD vademecums of every organ of a scene, written as bundles.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use vademecum_engine::pgd::PgdParams;
use vademecum_engine::pgd::offline::{self, BuildOptions, BuildStage};

use crate::cli::BuildArgs;
use crate::commands::solve::load_scene;
use crate::progress::Stages;

/// Relative tolerance of the recompression, as a fraction of the scene's ε_R: small enough
/// that the kept modes lose no measurable accuracy (see BENCHMARKS.md).
const RECOMPRESS_FRACTION: f64 = 0.1;

pub fn run(a: BuildArgs) -> anyhow::Result<ExitCode> {
    let scene = load_scene(&a.source)?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&scene.spec.scene.name));
    let f = scene.spec.fidelity.pgd;
    let params = PgdParams {
        global_tolerance: f.global_tolerance,
        enrichment_tolerance: f.enrichment_tolerance,
        max_modes: f.max_modes,
        max_iterations: f.max_iterations,
    };
    let opts = BuildOptions {
        params,
        compare_brute_force: !a.no_reference,
        recompress: (!a.no_recompress).then_some(RECOMPRESS_FRACTION * f.global_tolerance),
        load_radius: offline::probe_radius(&scene),
    };
    let mut reports = Vec::new();
    let mut stdout = std::io::stdout().lock();
    for i in 0..scene.spec.organs.len() {
        let name = scene.spec.organs[i].name.clone();
        let bar = Stages::start(&format!("building '{name}'"));
        let built = offline::build_organ(&scene, i, &opts, &mut |s| match s {
            BuildStage::Assembly => bar.stage("assembling K"),
            BuildStage::Factorization => bar.stage("factoring K"),
            BuildStage::Mode(k, e) => bar.stage(&format!("mode {k}, energy {e:.2e} (stop below {:.1e})", f.global_tolerance)),
            BuildStage::BruteForce(done, total) => bar.stage(&format!("brute-force reference {done}/{total}")),
            BuildStage::Errors => bar.stage("measuring errors"),
        })
        .with_context(|| format!("cannot build organ '{name}'"))?;
        bar.stage("writing bundle");
        let dir = out.join(format!("{name}.bundle"));
        offline::write_bundle(&dir, &scene, &built).with_context(|| format!("cannot write bundle {}", dir.display()))?;
        bar.finish();
        let r = &built.report;
        if !a.json {
            writeln!(
                stdout,
                "organ '{}': {} nodes, {} equations, {} load states ({} accessible nodes)",
                r.organ, r.nodes, r.equations, r.load_states, r.load_nodes
            )?;
            writeln!(
                stdout,
                "  load footprint   radius {} m, {:.1} surface nodes per load on average",
                r.load_radius, r.mean_patch_nodes
            )?;
            let iters: usize = r.greedy.iterations.iter().sum();
            writeln!(
                stdout,
                "  PGD              {} modes, {} fixed-point iterations, {:.2} s{}",
                r.greedy.modes,
                iters,
                r.pgd_s,
                if r.greedy.converged {
                    ""
                } else {
                    " (stopped by max_modes before reaching the tolerance)"
                }
            )?;
            if r.recompressed {
                writeln!(stdout, "  recompressed     {} modes ({:.3} s)", r.modes, r.recompress_s)?;
            }
            writeln!(
                stdout,
                "  exact contact    {} local compliance blocks from one blocked pass over all load states ({:.2} s)",
                r.local_blocks, r.exact_pass_s
            )?;
            if let (Some(e), Some(t)) = (r.error, r.brute_force_s) {
                writeln!(
                    stdout,
                    "  error            {e:.3e} relative L2 vs brute force over all load states (greedy: {:.3e})",
                    r.error_greedy.unwrap_or(e)
                )?;
                writeln!(stdout, "  brute force      {t:.2} s for {} solves", r.load_states)?;
            }
            writeln!(stdout, "  assembly/factor  {:.3} s / {:.3} s", r.assembly_s, r.factorization_s)?;
            writeln!(
                stdout,
                "  size             {:.2} MB of modes vs {:.2} MB for the full parametric solution",
                r.modes_bytes as f64 / 1e6,
                r.full_bytes as f64 / 1e6
            )?;
            writeln!(stdout, "  bundle           {}", dir.display())?;
        }
        reports.push(built.report);
    }
    if a.json {
        writeln!(stdout, "{}", serde_json::to_string_pretty(&reports)?)?;
    }
    Ok(ExitCode::SUCCESS)
}
