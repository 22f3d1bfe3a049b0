//! Every volume mesh in `../shared/data/meshes` stored as Gmsh (v1, v2) or VTK (`.vtu`,
//! legacy `.vtk`, ASCII and binary) reads with the node and cell counts its `SOURCES.md`
//! gives, and the mm-sized organs scale to metres from a scene.
//!
//! The data lives beside the repository, never in it. Set `VADEMECUM_SHARED` to its folder;
//! by default `../shared` next to the checkout is used. When it is absent, each test says it
//! is skipped and passes — except under CI (`CI` set), where it fails.

use crate::common;

use std::path::PathBuf;

use vademecum_engine::mesh::{self, CellKind};
use vademecum_engine::scene::Scene;

fn shared() -> Option<PathBuf> {
    common::shared_data().map(|d| d.join("data/meshes"))
}

/// (file, nodes, used nodes, cells, kind) from SOURCES.md.
const EXPECTED: &[(&str, usize, usize, usize, CellKind)] = &[
    ("sofa/liver.msh", 181, 181, 596, CellKind::Tet4),
    ("sofa/liver2.msh", 507, 507, 1493, CellKind::Tet4),
    ("sofa/volumetricTongue.vtu", 2238, 2238, 10980, CellKind::Tet4),
    ("sofa/cylinderPDMS12724Vol.vtk", 3668, 3668, 12724, CellKind::Tet4),
    ("sofa/truth_cylinder/cylinder_Hexa.msh", 5740, 5740, 4920, CellKind::Hex8),
    ("sofa_env/grasp_lift_touch/liver_volumetric.vtk", 98, 98, 273, CellKind::Tet4),
    (
        "sofa_env/grasp_lift_touch/gallbladder_volumetric.vtk",
        367,
        366,
        1063,
        CellKind::Tet4,
    ),
    ("sofa_env/tissue_manipulation/tissue_volumetric.msh", 145, 145, 348, CellKind::Tet4),
    ("sofa_env/tissue_retraction/tissue_volume.msh", 493, 493, 1432, CellKind::Tet4),
    ("derived/openhelp_liver_tet_h20.msh", 3463, 3463, 14335, CellKind::Tet4),
    ("derived/openhelp_liver_tet_h12.msh", 11573, 11573, 55625, CellKind::Tet4),
    ("derived/openhelp_kidney_left_tet_h6.msh", 1363, 1363, 5424, CellKind::Tet4),
    ("derived/openhelp_spleen_tet_h8.msh", 3317, 3317, 13955, CellKind::Tet4),
    ("derived/sofa_env_gallbladder_tet_h5.msh", 866, 866, 2859, CellKind::Tet4),
    ("derived/sofa_coeur1_heart_tet_h2.msh", 2754, 2754, 11919, CellKind::Tet4),
];

#[test]
fn every_shared_volume_mesh_reads_with_the_documented_counts() {
    let Some(dir) = shared() else { return };
    let mut failures = Vec::new();
    for &(file, nodes, used, cells, kind) in EXPECTED {
        match mesh::read(dir.join(file)) {
            Ok(m) => {
                let q = vademecum_engine::mesh::quality::summarize(&m);
                let got = (m.n_nodes(), q.used_nodes, m.n_cells(), m.kind);
                if got != (nodes, used, cells, kind) {
                    failures.push(format!("{file}: got {got:?}, SOURCES.md says {:?}", (nodes, used, cells, kind)));
                }
                if q.inverted != 0 || q.degenerate != 0 {
                    failures.push(format!(
                        "{file}: {} inverted, {} degenerate after reading",
                        q.inverted, q.degenerate
                    ));
                }
            }
            Err(e) => failures.push(format!("{file}: {e}")),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn mm_organ_scales_to_metres_from_a_scene() {
    let Some(dir) = shared() else { return };
    let file = dir.join("derived/openhelp_liver_tet_h20.msh");
    let text = format!(
        r#"[scene]
name = "liver"
[[organs]]
name = "liver"
density = 1060.0
[organs.mesh]
file = "{}"
scale = 0.001
[[organs.materials]]
model = "linear"
young = 160e3
poisson = 0.48
[organs.fixed]
half_space = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, -1.0] }}
[organs.accessible]
half_space = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
"#,
        file.display()
    );
    let scene = Scene::from_toml(&text, "liver.toml").unwrap();
    let m = scene.organ_mesh(0).unwrap();
    let (lo, hi) = m.bounding_box();
    // SOURCES.md: the OpenHELP liver is about 181 × 191 × 173 mm.
    for (k, want) in [(0, 0.181), (1, 0.191), (2, 0.173)] {
        let size = hi[k] - lo[k];
        assert!((size - want).abs() < 0.01, "axis {k}: {size} m, expected about {want} m");
    }
}

/// SOFA's gallbladder mesh lists 367 nodes and uses 366: the stray vertex is dropped on
/// reading, with a warning that says so, and the organ solves (it used to fail as singular).
#[test]
fn a_stray_vertex_is_dropped_with_a_warning_and_the_organ_solves() {
    let Some(dir) = shared() else { return };
    let file = dir.join("sofa_env/grasp_lift_touch/gallbladder_volumetric.vtk");
    let text = format!(
        r#"[scene]
name = "gallbladder"
[[organs]]
name = "gallbladder"
density = 1060.0
[organs.mesh]
file = "{}"
scale = 0.001
[[organs.materials]]
model = "linear"
young = 1500.0
poisson = 0.3
[organs.fixed]
half_space = {{ point = [0.0, 0.0, -0.01], normal = [0.0, 0.0, -1.0] }}
[organs.accessible]
half_space = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
[[organs.loads]]
kind = "gravity"
acceleration = [0.0, 0.0, -9.81]
"#,
        file.display()
    );
    let scene = Scene::from_toml(&text, "gallbladder.toml").unwrap();
    let m = scene.organ_model(0).unwrap();
    assert_eq!(m.mesh.n_nodes(), 366);
    assert!(
        m.warnings
            .iter()
            .any(|w| w.contains("1 node(s)") && w.contains("belong to no cell")),
        "{:?}",
        m.warnings
    );
    let sol = vademecum_engine::fem::linear_static::solve(&m.mesh, &m.materials, m.locking, &m.problem, &mut |_| {}).unwrap();
    assert!(sol.u.iter().all(|v| v.is_finite()) && sol.max_displacement > 0.0);
}
