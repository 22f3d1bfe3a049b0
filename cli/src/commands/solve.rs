//! `vademecum solve`: static linear solve of every organ of a scene.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use serde::Serialize;
use vademecum_engine::fem::OrganModel;
use vademecum_engine::fem::hyperelastic::Volumetric;
use vademecum_engine::fem::linear_static::{self, Timings};
use vademecum_engine::fem::nonlinear_static::{self, NewtonParams};
use vademecum_engine::fem::{assembly, element};
use vademecum_engine::geometry::cut::Cut;
use vademecum_engine::material::hyperelastic::Hyperelastic;
use vademecum_engine::mesh::Mesh;
use vademecum_engine::mesh::vtk::{self, Field};
use vademecum_engine::meshless::efg::AdrParams;
use vademecum_engine::meshless::organ::{self, OrganSettings};
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::schema::SolverKind;
use vademecum_engine::xfem::view::SplitMesh;
use vademecum_engine::xfem::{Detached, Enrichment, system};

use super::scene_input::load_scene;
use crate::cli::SolveArgs;
use crate::progress::Stages;

/// The JSON summary of one organ (`--json`, and `summary.json`).
#[derive(Debug, Serialize)]
pub(crate) struct OrganSummary {
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
    /// `fem` or `meshless`.
    solver: &'static str,
    /// The meshless solver's discretisation, relaxation and cuts.
    #[serde(skip_serializing_if = "Option::is_none")]
    meshless: Option<MeshlessSummary>,
    /// The full-order XFEM's cut, for linear organs with pre-planned cuts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) xfem: Option<XfemSummary>,
    pub(crate) output: PathBuf,
}

#[derive(Debug, Serialize)]
pub(crate) struct XfemSummary {
    cuts: usize,
    /// Cells the blade crossed entirely.
    cut_cells: usize,
    /// Cracked (enriched) nodes.
    enriched_nodes: usize,
    /// Nodes left out by the sliver rule.
    sliver_nodes: usize,
    /// Pieces no support held, and what was done with them.
    detached_pieces: usize,
    detached_action: &'static str,
    /// Largest jump between the two lips at a cracked node (m).
    pub(crate) max_opening_m: f64,
    /// Strain energy of the same organ uncut (J).
    uncut_strain_energy_j: f64,
}

#[derive(Debug, Serialize)]
struct MeshlessSummary {
    /// Nodes of the cloud (the mesh's, plus those the cuts added).
    cloud_nodes: usize,
    integration_points: usize,
    /// Relaxation steps of the last relaxation (after the last cut, if any).
    relaxation_steps: usize,
    /// Estimated absolute error of the displacements (m).
    error_estimate_m: f64,
    /// Restarts with heavier masses after an inverted transient.
    restarts: usize,
    threads: usize,
    /// Strain energy of the loaded organ before its cuts (J).
    #[serde(skip_serializing_if = "Option::is_none")]
    uncut_strain_energy_j: Option<f64>,
    cuts: usize,
    nodes_split: usize,
    nodes_inserted: usize,
    /// The node cloud (with both faces of the cuts), for organs with cuts.
    #[serde(skip_serializing_if = "Option::is_none")]
    cloud_output: Option<PathBuf>,
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

impl Summary {
    /// The summary as `solve` prints it.
    fn print(&self, out: &mut impl Write) -> std::io::Result<()> {
        writeln!(out, "scene '{}' ({})", self.scene, self.source)?;
        for o in &self.organs {
            writeln!(
                out,
                "organ '{}': {} nodes, {} {} cells, {} equations",
                o.name, o.nodes, o.cells, o.cell_kind, o.equations
            )?;
            writeln!(out, "  strain energy      {:.6e} J", o.strain_energy_j)?;
            writeln!(
                out,
                "  max displacement   {:.6e} m at node {}",
                o.max_displacement_m, o.max_displacement_node
            )?;
            writeln!(out, "  max von Mises      {:.6e} Pa", o.max_von_mises_pa)?;
            for (r, f) in &o.reaction_force_n {
                writeln!(
                    out,
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
                out,
                "  time               {:.3} s (assembly {:.3}, analysis {:.3}, factorization {:.3}, solve {:.3}, post {:.3})",
                o.solve_time_s, t.assembly_s, t.analysis_s, t.factorization_s, t.solve_s, t.post_s
            )?;
            if let Some(m) = &o.meshless {
                writeln!(
                    out,
                    "  meshless           {} cloud nodes, {} integration points, {} relaxation steps (error {:.1e} m), {} thread(s)",
                    m.cloud_nodes, m.integration_points, m.relaxation_steps, m.error_estimate_m, m.threads
                )?;
                if let Some(e) = m.uncut_strain_energy_j {
                    writeln!(
                        out,
                        "  cuts               {} ({} nodes split, {} inserted); strain energy before cutting {e:.6e} J",
                        m.cuts, m.nodes_split, m.nodes_inserted
                    )?;
                }
                if let Some(f) = &m.cloud_output {
                    writeln!(out, "  node cloud         {} (both faces of the cuts)", f.display())?;
                }
            }
            if let Some(x) = &o.xfem {
                writeln!(
                    out,
                    "  XFEM cut           {} cut(s): {} cells crossed, {} cracked nodes ({} left out by the sliver rule), largest opening {:.3e} m",
                    x.cuts, x.cut_cells, x.enriched_nodes, x.sliver_nodes, x.max_opening_m
                )?;
                writeln!(out, "  uncut              strain energy {:.6e} J", x.uncut_strain_energy_j)?;
                if x.detached_pieces > 0 {
                    writeln!(out, "  detached pieces    {} ({})", x.detached_pieces, x.detached_action)?;
                }
            }
            if let Some(n) = &o.newton {
                writeln!(
                    out,
                    "  large deformations {} load steps, {} Newton iterations, {} step cuts",
                    n.steps, n.iterations, n.cuts
                )?;
            }
            writeln!(out, "  result             {}", o.output.display())?;
        }
        writeln!(
            out,
            "open the .vtu in ParaView; Filters > Warp By Vector on 'displacement' shows the deformed shape"
        )?;
        Ok(())
    }
}

pub fn run(a: SolveArgs) -> anyhow::Result<ExitCode> {
    let scene = load_scene(&a.source)?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&scene.spec.scene.name));
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create output folder {}", out.display()))?;
    let max_memory = super::scene_input::memory_limit(a.max_memory)?;
    let mut organs = Vec::new();
    for i in 0..scene.spec.organs.len() {
        let name = scene.spec.organs[i].name.clone();
        let progress = Stages::start(&name);
        progress.stage("building mesh and loads");
        let model = scene.organ_model_within(i, (scene.spec.fidelity.solver == SolverKind::Fem).then_some(max_memory).flatten())?;
        for w in &model.warnings {
            progress.warn(w);
        }
        if scene.spec.effects.tearing && scene.spec.fidelity.solver == SolverKind::Fem {
            progress.warn(&format!(
                "a static solve does not tear: organ '{name}' is solved undamaged and linear, under the scene's loads; the tearing runs in `vademecum run --builtin NAME` (sessions) or `vademecum bench tear` (its references)"
            ));
        }
        if scene.spec.fidelity.solver == SolverKind::Meshless {
            organs.push(solve_meshless(&scene, i, &model, &out, &progress)?);
            progress.finish();
            continue;
        }
        let cuts = scene.organ_cuts(i)?;
        if !cuts.is_empty() {
            anyhow::ensure!(
                model.laws.is_none(),
                "organ '{name}': cuts in a hyperelastic organ are made by the meshless solver; set fidelity.solver = \"meshless\" (or use a linear material for XFEM)"
            );
            organs.push(solve_xfem(&scene, &model, &cuts, &out, &progress)?);
            progress.finish();
            continue;
        }
        let (sol, newton) = match &model.laws {
            None => (
                linear_static::solve(&model.mesh, &model.materials, model.locking, &model.problem, &mut |s| {
                    progress.stage(s.label())
                })
                .with_context(|| format!("organ '{name}' could not be solved"))?,
                None,
            ),
            Some(laws) => {
                let volumetric = Volumetric::for_locking(model.locking);
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
            solver: "fem",
            meshless: None,
            xfem: None,
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
        summary.print(&mut stdout)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// A linear organ with pre-planned cuts: the full-order XFEM (cracking nodes, seed 000 ch. 3),
/// written on the mesh split along the cut so that ParaView shows the opening.
fn solve_xfem(scene: &Scene, model: &OrganModel, cuts: &[Cut], out: &std::path::Path, progress: &Stages) -> anyhow::Result<OrganSummary> {
    let name = &model.name;
    let fx = scene.spec.fidelity.xfem;
    let params = fx.params();
    progress.stage("XFEM: cut cells and cracked nodes");
    let mut cut = cuts[0].clone();
    for c in &cuts[1..] {
        cut = cut.union(c)?;
    }
    let enr = Enrichment::from_cut(&model.mesh, &cut, &params).with_context(|| format!("organ '{name}': the cut"))?;
    if enr.is_empty() {
        progress.warn(&format!(
            "organ '{name}': the cuts cross no cell entirely (a cut ends on cell boundaries): nothing is cut"
        ));
    }
    solve_enriched(scene, model, &enr, cuts.len(), &out.join(format!("{name}.vtu")), progress)
}

/// The full-order XFEM solve of `model` under its loads with the enrichment `enr` (of `cuts`
/// cuts), written as the mesh split along the cut to `file`.
pub(crate) fn solve_enriched(
    scene: &Scene,
    model: &OrganModel,
    enr: &Enrichment,
    cuts: usize,
    file: &std::path::Path,
    progress: &Stages,
) -> anyhow::Result<OrganSummary> {
    let name = &model.name;
    let params = scene.spec.fidelity.xfem.params();
    let enr = enr.clone();
    progress.stage("XFEM: assembly and solve");
    let sol = system::solve(&model.mesh, &model.materials, model.locking, &model.problem, &enr, &params)
        .with_context(|| format!("organ '{name}' could not be solved with its cuts"))?;
    let solve_time_s = sol.seconds;
    progress.stage("uncut solve, for comparison");
    let uncut = linear_static::solve(&model.mesh, &model.materials, model.locking, &model.problem, &mut |_| {})
        .with_context(|| format!("organ '{name}' could not be solved uncut"))?;
    progress.stage("writing .vtu (split along the cut)");
    let split = SplitMesh::new(&model.mesh, &enr);
    let u = split.of_solution(&enr, &sol);
    let stresses = assembly::cell_stresses(&split.mesh, &model.materials, model.locking, &u)?;
    let von_mises: Vec<f64> = stresses.iter().map(|s| element::von_mises(*s)).collect();
    let f_int = assembly::internal_forces(&split.mesh, &model.materials, model.locking, &u)?;
    let forces = split.extend_zero(&model.problem.forces, 3);
    let n = model.mesh.n_nodes();
    let mut reactions = vec![0.0; 3 * n];
    for d in 0..3 * n {
        if model.problem.constrained[d] {
            reactions[d] = f_int[d] - forces[d];
        }
    }
    // the copies of held nodes carry their share of the reaction
    for (k, &a) in enr.nodes.iter().enumerate() {
        for i in 0..3 {
            if model.problem.constrained[3 * a + i] {
                reactions[3 * a + i] += f_int[3 * (n + k) + i] - forces[3 * (n + k) + i];
            }
        }
    }
    let file = file.to_path_buf();
    let side: Vec<f64> = (0..split.mesh.n_nodes()).map(|a| if a < n { 0.0 } else { 1.0 }).collect();
    // cells of detached pieces (the split mesh numbers its nodes as the pieces' copies)
    let mut in_piece = vec![0.0; split.mesh.n_nodes()];
    for p in &sol.detached {
        for &c in &p.copies {
            in_piece[c] = 1.0;
        }
    }
    let detached: Vec<f64> = split.mesh.cells_iter().map(|c| in_piece[c[0]]).collect();
    vtk::write_vtu(
        &file,
        &split.mesh,
        &[
            Field {
                name: "displacement",
                components: 3,
                values: &u,
            },
            Field {
                name: "reaction",
                components: 3,
                values: &split.extend_zero(&reactions, 3),
            },
            Field {
                name: "cut_lip_copy",
                components: 1,
                values: &side,
            },
        ],
        &[
            Field {
                name: "von_mises",
                components: 1,
                values: &von_mises,
            },
            Field {
                name: "detached",
                components: 1,
                values: &detached,
            },
        ],
    )?;
    let (mut max_d, mut max_node) = (0.0, 0);
    for a in 0..split.mesh.n_nodes() {
        let d = (0..3).map(|i| u[3 * a + i].powi(2)).sum::<f64>().sqrt();
        if d > max_d {
            (max_d, max_node) = (d, if a < n { a } else { enr.nodes[a - n] });
        }
    }
    let max_opening_m = (0..enr.len())
        .map(|k| (0..3).map(|i| sol.q[3 * k + i].powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    let reaction_force_n = model
        .named_regions
        .iter()
        .map(|(r, nodes)| (r.clone(), vademecum_engine::fem::node_sum(&reactions, nodes)))
        .collect();
    // ½ uᵀK u over the split mesh (both lips): the work of the loads and of the supports'
    // reactions alike, so a cut solved under a prescribed displacement has its energy too
    let strain_energy_j = 0.5 * u.iter().zip(&f_int).map(|(u, f)| u * f).sum::<f64>();
    Ok(OrganSummary {
        name: name.clone(),
        cell_kind: model.mesh.kind.name(),
        nodes: model.mesh.n_nodes(),
        cells: model.mesh.n_cells(),
        dofs: model.mesh.n_dofs() + 3 * enr.len(),
        equations: sol.n_free,
        nonzeros_lower: sol.nnz,
        strain_energy_j,
        max_displacement_m: max_d,
        max_displacement_node: max_node,
        max_von_mises_pa: von_mises.iter().copied().fold(0.0, f64::max),
        reaction_force_n,
        relative_residual: sol.residual,
        solve_time_s,
        timings: Timings {
            solve_s: solve_time_s,
            ..Timings::default()
        },
        newton: None,
        solver: "fem",
        meshless: None,
        xfem: Some(XfemSummary {
            cuts,
            cut_cells: enr.cut_cells.len(),
            enriched_nodes: enr.len(),
            sliver_nodes: enr.dropped.iter().filter(|d| d.fraction > 0.0).count(),
            detached_pieces: sol.detached.len(),
            detached_action: match params.detached {
                Detached::Hold => "held in place",
                Detached::Remove => "removed",
            },
            max_opening_m,
            uncut_strain_energy_j: uncut.strain_energy,
        }),
        output: file,
    })
}

/// `fidelity.solver = "meshless"`: the organ by EFG and adaptive dynamic relaxation (seed 004),
/// with its pre-planned cuts; the same summary and .vtu as the finite-element solve.
/// The organ's one hyperelastic law, or why the meshless solver cannot take the organ.
pub(crate) fn meshless_law(model: &OrganModel) -> anyhow::Result<Hyperelastic> {
    let name = &model.name;
    if model.problem.springs.iter().any(|&k| k != 0.0) || !model.problem.pressures.is_empty() {
        anyhow::bail!(
            "organ '{name}': the meshless solver takes rigid supports and forces; elastic foundations and pressures need the finite-element solver"
        );
    }
    match &model.laws {
        Some(laws) if laws.laws.len() == 1 => Ok(laws.laws[0]),
        Some(_) => anyhow::bail!("organ '{name}': the meshless solver takes one material per organ"),
        None => anyhow::bail!(
            "organ '{name}': the meshless solver is nonlinear; give the organ a hyperelastic material (neo_hookean, stvk or mooney_rivlin)"
        ),
    }
}

/// The scene's `[fidelity.meshless]` as the solver's settings.
pub(crate) fn meshless_settings(scene: &Scene) -> OrganSettings {
    let f = &scene.spec.fidelity.meshless;
    OrganSettings {
        support: f.support,
        integration: f.integration,
        params: AdrParams {
            tolerance: f.tolerance,
            loading_steps: f.loading_steps,
            max_steps: f.max_steps,
            ..AdrParams::default()
        },
    }
}

fn solve_meshless(
    scene: &Scene,
    index: usize,
    model: &OrganModel,
    out: &std::path::Path,
    progress: &Stages,
) -> anyhow::Result<OrganSummary> {
    let name = &model.name;
    let law = meshless_law(model)?;
    let settings = meshless_settings(scene);
    let cuts = scene.organ_cuts(index)?;
    let started = std::time::Instant::now();
    progress.stage("meshless: shape functions");
    let result = organ::solve(&model.mesh, law, &model.problem, &cuts, &settings, |stage, step, error| {
        let what = if stage == 0 {
            "loading".to_string()
        } else {
            format!("after cut {stage}")
        };
        progress.stage(&format!("meshless relaxation {what}: step {step}, error {error:.1e} m"));
    })
    .with_context(|| format!("organ '{name}' could not be solved by the meshless solver"))?;
    let solve_time_s = started.elapsed().as_secs_f64();
    progress.stage("writing .vtu");
    let sol = &result.solution;
    let mesh: &Mesh = &model.mesh;
    let reaction_force_n = model
        .named_regions
        .iter()
        .map(|(n, nodes)| (n.clone(), result.reaction_sum(nodes)))
        .collect();
    let (mut max_d, mut max_node) = (0.0, 0);
    for i in 0..mesh.n_nodes() {
        let d = (0..3).map(|k| result.displacement[3 * i + k].powi(2)).sum::<f64>().sqrt();
        if d > max_d {
            (max_d, max_node) = (d, i);
        }
    }
    let file = out.join(format!("{name}.vtu"));
    vtk::write_vtu(
        &file,
        mesh,
        &[
            Field {
                name: "displacement",
                components: 3,
                values: &result.displacement,
            },
            Field {
                name: "reaction",
                components: 3,
                values: &result.reactions,
            },
        ],
        &[Field {
            name: "von_mises",
            components: 1,
            values: &result.von_mises,
        }],
    )?;
    // with cuts, the mesh cannot show the opening: the node cloud, each node displaced by its
    // face's displacement, can (ParaView: Warp By Vector on 'displacement')
    let cloud_output = if cuts.is_empty() {
        None
    } else {
        let cloud_file = out.join(format!("{name}_nodes.vtu"));
        let sides = result.cloud.sides().unwrap_or(&[]);
        let cut = result.cloud.cut();
        let face: Vec<f64> = (0..result.cloud.len())
            .map(|i| match cut {
                Some(c) if c.distance(result.cloud.points()[i]) < 1e-9 * mesh.diameter() => sides.get(i).copied().unwrap_or(0.0),
                _ => 0.0,
            })
            .collect();
        vtk::write_points_vtu(
            &cloud_file,
            result.cloud.points(),
            &[
                Field {
                    name: "displacement",
                    components: 3,
                    values: &sol.displacement,
                },
                Field {
                    name: "face",
                    components: 1,
                    values: &face,
                },
            ],
        )?;
        Some(cloud_file)
    };
    let free = 3 * result.cloud.len() - result.prescribed;
    Ok(OrganSummary {
        name: name.clone(),
        cell_kind: mesh.kind.name(),
        nodes: mesh.n_nodes(),
        cells: mesh.n_cells(),
        dofs: 3 * result.cloud.len(),
        equations: free,
        nonzeros_lower: 0,
        strain_energy_j: sol.energy,
        max_displacement_m: max_d,
        max_displacement_node: max_node,
        max_von_mises_pa: result.von_mises.iter().copied().fold(0.0, f64::max),
        reaction_force_n,
        relative_residual: sol.residual,
        solve_time_s,
        timings: Timings {
            solve_s: solve_time_s,
            ..Timings::default()
        },
        newton: None,
        solver: "meshless",
        xfem: None,
        meshless: Some(MeshlessSummary {
            cloud_nodes: result.cloud.len(),
            integration_points: result.integration_points,
            relaxation_steps: sol.steps,
            error_estimate_m: sol.error,
            restarts: sol.restarts,
            threads: rayon::current_num_threads(),
            uncut_strain_energy_j: result.uncut.as_ref().map(|u| u.energy),
            cuts: cuts.len(),
            nodes_split: result.cut_nodes.split,
            nodes_inserted: result.cut_nodes.inserted,
            cloud_output,
        }),
        output: file,
    })
}
