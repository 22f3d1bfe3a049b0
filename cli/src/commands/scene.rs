//! `vademecum scene show|check`.

use std::io::Write;
use std::process::ExitCode;

use anyhow::anyhow;
use vademecum_engine::fem::Locking;
use vademecum_engine::mesh::CellKind;
use vademecum_engine::scene::{self, Scene};

use crate::cli::SceneCommand;

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
                // the supports come first among the named regions, in the scene's order
                let supports: Vec<String> = s.spec.organs[i]
                    .fixed
                    .supports()
                    .iter()
                    .zip(&m.named_regions)
                    .map(|(sup, (name, nodes))| {
                        let held = sup
                            .components
                            .as_ref()
                            .map_or("x, y, z".to_string(), |c| c.iter().map(|a| a.name()).collect::<Vec<_>>().join(", "));
                        match sup.stiffness {
                            Some(k) => format!("{name}: {} nodes on a foundation of {k} Pa/m ({held})", nodes.len()),
                            None => format!("{name}: {} nodes ({held} held)", nodes.len()),
                        }
                    })
                    .collect();
                let element = match (m.mesh.kind, m.locking) {
                    (CellKind::Tet4, Locking::Nodal) => "nodal-pressure tetrahedra",
                    (CellKind::Tet4, _) => "plain tetrahedra",
                    (_, Locking::None) => "fully integrated hexahedra",
                    (_, Locking::Sri) => "hexahedra with selective reduced integration",
                    (_, _) => "mean-dilatation hexahedra",
                };
                writeln!(
                    out,
                    "organ '{}': {} nodes, {} cells ({element}), {} accessible surface nodes; supports: {}",
                    m.name,
                    m.mesh.n_nodes(),
                    m.mesh.n_cells(),
                    m.accessible_nodes.len(),
                    supports.join("; ")
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
