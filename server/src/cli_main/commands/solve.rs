//! `vademecum solve`: static linear solve of every organ of a scene.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use serde::Serialize;
use vademecum_engine::fem::Locking;
use vademecum_engine::fem::hyperelastic::Volumetric;
use vademecum_engine::fem::linear_static::{self, Timings};
use vademecum_engine::fem::nonlinear_static::{self, NewtonParams};
use vademecum_engine::mesh::vtk::{self, Field};
use vademecum_engine::scene::Scene;

use crate::cli_main::cli::{SceneSource, SolveArgs};
use crate::cli_main::progress::Stages;

/// The JSON summary of one organ (`--json`, and `summary.json`).
#[derive(Debug, Serialize)]
struct OrganSummary {
    name: String,
    cell_kind: &'static str,
    nodes: usize,
    cells: usize,
    dofs: usize,
    equations: usize,
    nonzeros_lower: usize,
    strain_energy_j: f64,
    max_displacement_m: f64,
    max_displacement_node: usize,
    max_von_mises_pa: f64,
    reaction_force_n: BTreeMap<String, [f64; 3]>,
    relative_residual: f64,
    solve_time_s: f64,
    timings: Timings,
    /// Newton–Raphson steps, iterations and cuts, for hyperelastic organs.
    #[serde(skip_serializing_if = "Option::is_none")]
    newton: Option<NewtonSummary>,
    output: PathBuf,
}

#[derive(Debug, Serialize)]
struct NewtonSummary {
    steps: usize,
    iterations: usize,
    cuts: usize,
}

#[derive(Debug, Serialize)]
struct Summary {
    scene: String,
    source: String,
    organs: Vec<OrganSummary>,
}

/// Loads the scene named by the arguments.
pub(crate) fn load_scene(source: &SceneSource) -> anyhow::Result<Scene> {
    Ok(match &source.scene {
        Some(p) => Scene::load(p)?,
        None => Scene::builtin(&source.builtin)?,
    })
}

pub fn run(a: SolveArgs) -> anyhow::Result<ExitCode> {
    let scene = load_scene(&a.source)?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&scene.spec.scene.name));
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create output folder {}", out.display()))?;
    let mut organs = Vec::new();
    for i in 0..scene.spec.organs.len() {
        let name = scene.spec.organs[i].name.clone();
        let progress = Stages::start(&name);
        progress.stage("building mesh and loads");
        let model = scene.organ_model(i)?;
        let (sol, newton) = match &model.laws {
            None => (
                linear_static::solve(&model.mesh, &model.materials, model.locking, &model.problem, &mut |s| {
                    progress.stage(s.label())
                })
                .with_context(|| format!("organ '{name}' could not be solved"))?,
                None,
            ),
            Some(laws) => {
                // large deformations: full integration only when the scene asks for no
                // locking treatment; otherwise the mean-dilatation element
                let volumetric = match model.locking {
                    Locking::None => Volumetric::PointWise,
                    Locking::Sri | Locking::Bbar => Volumetric::MeanDilatation,
                };
                progress.stage("Newton-Raphson, large deformations");
                let (sol, info) =
                    nonlinear_static::solve_static(&model.mesh, laws, volumetric, &model.problem, &NewtonParams::default(), |l| {
                        progress.stage(&format!("Newton-Raphson, load factor {l:.2}"))
                    })
                    .with_context(|| format!("organ '{name}' could not be solved"))?;
                (sol, Some(info))
            }
        };
        progress.stage("writing .vtu");
        let file = out.join(format!("{name}.vtu"));
        let vm_max = sol.von_mises.iter().copied().fold(0.0, f64::max);
        vtk::write_vtu(
            &file,
            &model.mesh,
            &[
                Field {
                    name: "displacement",
                    components: 3,
                    values: &sol.u,
                },
                Field {
                    name: "reaction",
                    components: 3,
                    values: &sol.reactions,
                },
            ],
            &[Field {
                name: "von_mises",
                components: 1,
                values: &sol.von_mises,
            }],
        )?;
        progress.finish();
        let reaction_force_n = model
            .named_regions
            .iter()
            .map(|(n, nodes)| (n.clone(), sol.reaction_sum(nodes)))
            .collect();
        organs.push(OrganSummary {
            name,
            cell_kind: model.mesh.kind.name(),
            nodes: model.mesh.n_nodes(),
            cells: model.mesh.n_cells(),
            dofs: model.mesh.n_dofs(),
            equations: sol.n_free,
            nonzeros_lower: sol.nnz,
            strain_energy_j: sol.strain_energy,
            max_displacement_m: sol.max_displacement,
            max_displacement_node: sol.max_displacement_node,
            max_von_mises_pa: vm_max,
            reaction_force_n,
            relative_residual: sol.residual,
            solve_time_s: sol.timings.total_s(),
            timings: sol.timings,
            newton: newton.map(|i| NewtonSummary {
                steps: i.steps,
                iterations: i.iterations,
                cuts: i.cuts,
            }),
            output: file,
        });
    }
    let summary = Summary {
        scene: scene.spec.scene.name.clone(),
        source: scene.origin.display().to_string(),
        organs,
    };
    let json = serde_json::to_string_pretty(&summary)?;
    std::fs::write(out.join("summary.json"), &json).with_context(|| format!("cannot write {}", out.join("summary.json").display()))?;
    let mut stdout = std::io::stdout().lock();
    if a.json {
        writeln!(stdout, "{json}")?;
    } else {
        writeln!(stdout, "scene '{}' ({})", summary.scene, summary.source)?;
        for o in &summary.organs {
            writeln!(
                stdout,
                "organ '{}': {} nodes, {} {} cells, {} equations",
                o.name, o.nodes, o.cells, o.cell_kind, o.equations
            )?;
            writeln!(stdout, "  strain energy      {:.6e} J", o.strain_energy_j)?;
            writeln!(
                stdout,
                "  max displacement   {:.6e} m at node {}",
                o.max_displacement_m, o.max_displacement_node
            )?;
            writeln!(stdout, "  max von Mises      {:.6e} Pa", o.max_von_mises_pa)?;
            for (r, f) in &o.reaction_force_n {
                writeln!(
                    stdout,
                    "  reaction '{r}'{:>width$} [{:+.6e}, {:+.6e}, {:+.6e}] N",
                    "",
                    f[0],
                    f[1],
                    f[2],
                    width = 8usize.saturating_sub(r.len())
                )?;
            }
            let t = &o.timings;
            writeln!(
                stdout,
                "  time               {:.3} s (assembly {:.3}, analysis {:.3}, factorization {:.3}, solve {:.3}, post {:.3})",
                o.solve_time_s, t.assembly_s, t.analysis_s, t.factorization_s, t.solve_s, t.post_s
            )?;
            if let Some(n) = &o.newton {
                writeln!(
                    stdout,
                    "  large deformations {} load steps, {} Newton iterations, {} step cuts",
                    n.steps, n.iterations, n.cuts
                )?;
            }
            writeln!(stdout, "  result             {}", o.output.display())?;
        }
        writeln!(
            stdout,
            "open the .vtu in ParaView; Filters > Warp By Vector on 'displacement' shows the deformed shape"
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
