//! Built-in scenes parse and solve (and report their procedural divisions); the patch model
//! of seed 000 §3.5.1 solves, satisfies equilibrium and Clapeyron's theorem, and round-trips
//! through `.vtu`.

use vademecum_engine::fem::linear_static;
use vademecum_engine::mesh::{self, vtk};
use vademecum_engine::scene::{BUILTIN_NAMES, Scene};

#[test]
fn every_builtin_scene_solves_in_equilibrium() {
    for name in BUILTIN_NAMES {
        let s = Scene::builtin(name).unwrap();
        for i in 0..s.spec.organs.len() {
            let m = s.organ_model(i).unwrap();
            let sol = linear_static::solve(&m.mesh, &m.materials, m.locking, &m.problem, &mut |_| {}).unwrap();
            assert!(sol.residual < 1e-9, "{name}: residual {}", sol.residual);
            // Σ reactions + Σ external forces = 0 (no inertia)
            for k in 0..3 {
                let total: f64 = (0..m.mesh.n_nodes())
                    .map(|n| sol.reactions[3 * n + k] + m.problem.forces[3 * n + k])
                    .sum();
                // forces, or the reactions of prescribed displacements when there are none
                let scale = m
                    .problem
                    .forces
                    .iter()
                    .chain(&sol.reactions)
                    .map(|f| f.abs())
                    .sum::<f64>()
                    .max(1e-30);
                assert!(total.abs() < 1e-9 * scale, "{name}: force balance {k}: {total}");
            }
            assert!(sol.strain_energy > 0.0 && sol.max_displacement > 0.0);
        }
    }
}

#[test]
fn seed_patch_model_solves_and_round_trips_through_vtu() {
    let s = Scene::builtin("patch").unwrap();
    let m = s.organ_model(0).unwrap();
    assert_eq!((m.mesh.n_nodes(), m.mesh.n_cells()), (6 * 2 * 6, 25));
    let sol = linear_static::solve(&m.mesh, &m.materials, m.locking, &m.problem, &mut |_| {}).unwrap();
    // All prescribed displacements are zero, so U = ½ f·u (Clapeyron).
    let work: f64 = 0.5 * m.problem.forces.iter().zip(&sol.u).map(|(f, u)| f * u).sum::<f64>();
    assert!(
        (sol.strain_energy - work).abs() < 1e-10 * work,
        "U {} vs ½f·u {}",
        sol.strain_energy,
        work
    );
    // The loaded upper corner moves down.
    let loaded = (0..m.mesh.n_nodes()).find(|&n| m.mesh.nodes[n] == [5.0, 0.0, 5.0]).unwrap();
    assert!(sol.u[3 * loaded + 2] < 0.0);
    // Round trip.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("patch.vtu");
    vtk::write_vtu(
        &p,
        &m.mesh,
        &[vtk::Field {
            name: "displacement",
            components: 3,
            values: &sol.u,
        }],
        &[vtk::Field {
            name: "von_mises",
            components: 1,
            values: &sol.von_mises,
        }],
    )
    .unwrap();
    let back = mesh::read(&p).unwrap();
    assert_eq!((&back.nodes, &back.cells), (&m.mesh.nodes, &m.mesh.cells));
    assert_eq!(vtk::read_point_data(&p, "displacement").unwrap().unwrap(), sol.u);
}

#[test]
fn docs_scene_example_is_valid() {
    // docs/scene.md carries a complete example between the markers below; it must stay valid.
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/scene.md")).unwrap();
    let start = doc.find("<!-- example:start -->").expect("start marker");
    let end = doc.find("<!-- example:end -->").expect("end marker");
    let block = &doc[start..end];
    let toml_start = block.find("```toml\n").unwrap() + 8;
    let toml_end = block[toml_start..].find("```").unwrap() + toml_start;
    let s = Scene::from_toml(&block[toml_start..toml_end], "docs/scene.md").unwrap();
    let m = s.organ_model(0).unwrap();
    linear_static::solve(&m.mesh, &m.materials, m.locking, &m.problem, &mut |_| {}).unwrap();
}

#[test]
fn a_procedural_mesh_reports_the_divisions_it_is_generated_with() {
    let organ = Scene::builtin("organ").unwrap();
    assert_eq!(organ.spec.organs[0].mesh.effective_divisions(), Some([16, 10, 6]));
    // a block without divisions gets the generator's default, and the mesh has that many cells
    let text = Scene::builtin("stretch").unwrap().source.replace("divisions = [12, 12, 12]\n", "");
    let block = Scene::from_toml(&text, "block.toml").unwrap();
    let d = block.spec.organs[0].mesh.effective_divisions().unwrap();
    assert_eq!(block.organ_mesh(0).unwrap().n_cells(), d.iter().product::<usize>());
    // a mesh file has none
    let mut file = organ.spec.organs[0].mesh.clone();
    file.file = Some("liver.msh".into());
    assert_eq!(file.effective_divisions(), None);
}
