//! `vademecum inspect`: what a bundle holds, after verifying it.

use std::io::Write;
use std::process::ExitCode;

use anyhow::Context;
use vademecum_engine::bundle;

use crate::cli::InspectArgs;

pub fn run(a: InspectArgs) -> anyhow::Result<ExitCode> {
    let b = bundle::load_bundle(&a.bundle).with_context(|| format!("cannot load bundle {}", a.bundle.display()))?;
    let m = &b.manifest;
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(m)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(out, "{}", a.bundle.display())?;
    writeln!(
        out,
        "  format       {} v{} ({}), written by {}",
        m.format, m.version, m.kind, m.created_by
    )?;
    writeln!(out, "  scene/organ  {} / {}", m.scene, m.organ)?;
    writeln!(out, "  scene hash   {}", m.scene_sha256)?;
    writeln!(out, "  mesh hash    {}", m.mesh_sha256)?;
    writeln!(out, "  mesh         {} nodes, {} surface triangles", b.nodes.len(), b.surface.len())?;
    writeln!(out, "  modes        {}", b.vademecum.modes())?;
    writeln!(
        out,
        "  load nodes   {} ({} load states)",
        b.vademecum.load_nodes().len(),
        3 * b.vademecum.load_nodes().len()
    )?;
    let info = &m.info;
    if let Some(e) = info.get("error").and_then(|v| v.as_f64()) {
        writeln!(out, "  error        {e:.3e} relative L2 vs brute force")?;
    }
    if let (Some(p), Some(bf)) = (
        info.get("pgd_s").and_then(|v| v.as_f64()),
        info.get("brute_force_s").and_then(|v| v.as_f64()),
    ) {
        writeln!(out, "  build time   PGD {p:.2} s, brute force {bf:.2} s")?;
    }
    if !b.tear.is_empty() {
        let modes: Vec<String> = b.tear.iter().map(|t| format!("{} POD × {} PGD", t.lo.len(), t.n_modes)).collect();
        writeln!(
            out,
            "  tearing      {} grasp site(s) (the scene's first): {}",
            b.tear.len(),
            modes.join(", ")
        )?;
    }
    writeln!(out, "  arrays (all checksums verified):")?;
    for (name, e) in &m.arrays {
        writeln!(out, "    {name:<11} {:<16} {:?} {}", e.file, e.shape, e.dtype)?;
    }
    Ok(ExitCode::SUCCESS)
}
