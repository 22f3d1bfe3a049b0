//! `vademecum scene show|check`.

use std::io::Write;
use std::process::ExitCode;

use anyhow::anyhow;
use vademecum_engine::scene::{self, Scene};

use crate::cli_main::cli::SceneCommand;

pub fn run(c: SceneCommand) -> anyhow::Result<ExitCode> {
    let mut out = std::io::stdout().lock();
    match c {
        SceneCommand::Show { name } => {
            let text = scene::builtin(&name)
                .ok_or_else(|| anyhow!("no built-in scene named '{name}' (known: {})", scene::BUILTIN_NAMES.join(", ")))?;
            write!(out, "{text}")?;
        }
        SceneCommand::Check { file } => {
            let s = Scene::load(&file)?;
            for i in 0..s.spec.organs.len() {
                let m = s.organ_model(i)?;
                writeln!(
                    out,
                    "organ '{}': {} nodes, {} cells, {} fixed nodes, {} accessible surface nodes",
                    m.name,
                    m.mesh.n_nodes(),
                    m.mesh.n_cells(),
                    m.named_regions[0].1.len(),
                    m.accessible_nodes.len()
                )?;
                for w in &m.warnings {
                    writeln!(out, "warning: {w}")?;
                }
            }
            writeln!(out, "{}: ok", file.display())?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
