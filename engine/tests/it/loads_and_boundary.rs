//! Boundary faces point outward and carry their owning cell; consistent loads integrate to
//! the right totals (traction × area, density × volume × g).

use vademecum_engine::fem::assembly::MaterialMap;
use vademecum_engine::fem::loads;
use vademecum_engine::material::LinearElastic;
use vademecum_engine::mesh::boundary::{Boundary, triangle_area_normal};
use vademecum_engine::mesh::select::Region;
use vademecum_engine::mesh::{Mesh, procedural, quality};

fn centroid(m: &Mesh, nodes: &[usize]) -> [f64; 3] {
    let mut c = [0.0; 3];
    for &n in nodes {
        for k in 0..3 {
            c[k] += m.nodes[n][k] / nodes.len() as f64;
        }
    }
    c
}

#[test]
fn boundary_faces_point_out_of_their_owning_cell() {
    for m in [
        procedural::block_hex([0.0; 3], [0.3, 0.2, 0.1], [3, 2, 2]),
        procedural::lobe(&Default::default()),
    ] {
        let b = Boundary::of(&m);
        assert!(!b.faces.is_empty());
        for f in &b.faces {
            let fc = centroid(&m, f.node_slice());
            let cc = centroid(&m, m.cell(f.cell));
            let (_, n) = triangle_area_normal(&m, [f.nodes[0], f.nodes[1], f.nodes[2]]);
            let out: f64 = (0..3).map(|k| (fc[k] - cc[k]) * n[k]).sum();
            assert!(out > 0.0, "face of cell {} points inward", f.cell);
            assert!(f.node_slice().iter().all(|n| m.cell(f.cell).contains(n)));
        }
    }
    // A closed surface has zero total vector area.
    let m = procedural::lobe(&Default::default());
    let b = Boundary::of(&m);
    let mut s = [0.0; 3];
    for t in b.triangles() {
        let (a, n) = triangle_area_normal(&m, t);
        for k in 0..3 {
            s[k] += a * n[k];
        }
    }
    assert!(s.iter().all(|v| v.abs() < 1e-12), "{s:?}");
}

#[test]
fn traction_integrates_to_traction_times_area() {
    for m in [
        procedural::block_hex([0.0; 3], [0.3, 0.2, 0.1], [3, 2, 2]),
        procedural::block_tet([0.0; 3], [0.3, 0.2, 0.1], [3, 2, 2]),
    ] {
        let b = Boundary::of(&m);
        let faces = Region::Box {
            min: [0.0, 0.0, 0.1],
            max: [0.3, 0.2, 0.1],
        }
        .faces(&m, &b)
        .unwrap();
        let mut f = vec![0.0; m.n_dofs()];
        let area = loads::add_traction(&mut f, &m, &b, &faces, [0.0, 10.0, -100.0]);
        assert!((area - 0.06).abs() < 1e-12, "top area {area}");
        let fz: f64 = (0..m.n_nodes()).map(|n| f[3 * n + 2]).sum();
        let fy: f64 = (0..m.n_nodes()).map(|n| f[3 * n + 1]).sum();
        assert!((fz + 6.0).abs() < 1e-12 && (fy - 0.6).abs() < 1e-12, "{fy} {fz}");
    }
}

#[test]
fn gravity_integrates_to_weight() {
    let m = procedural::lobe(&Default::default());
    let mat = MaterialMap::uniform(LinearElastic::new(1e4, 0.3).unwrap(), 1060.0, m.n_cells());
    let mut f = vec![0.0; m.n_dofs()];
    let mass = loads::add_body_force(&mut f, &m, &mat, [0.0, 0.0, -9.81]).unwrap();
    let v: f64 = quality::signed_volumes(&m).iter().sum();
    assert!((mass - 1060.0 * v).abs() < 1e-10 * mass);
    let fz: f64 = (0..m.n_nodes()).map(|n| f[3 * n + 2]).sum();
    assert!((fz + 9.81 * mass).abs() < 1e-10 * mass);
}

/// `kind = "pressure"` in a scene: an eighth of a cube held by rollers on its symmetry planes
/// (`displacement` loads holding one component each) under a pressure on its three outer
/// faces is in uniform hydrostatic compression, `ε = −p / 3K` along every axis.
#[test]
fn a_scene_pressure_compresses_a_cube_hydrostatically() {
    let text = r#"[scene]
name = "pressed"
[[organs]]
name = "cube"
density = 1000.0
[organs.mesh]
builtin = "block"
size = [0.1, 0.1, 0.1]
divisions = [3, 3, 3]
cell = "tet4"
[[organs.materials]]
model = "linear"
young = 3000.0
poisson = 0.3
[organs.fixed]
nodes = [0]
[organs.accessible]
half_space = { point = [0.0, 0.0, 0.1], normal = [0.0, 0.0, 1.0] }
[[organs.loads]]
kind = "displacement"
name = "x0"
region = { half_space = { point = [0.0, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] } }
x = 0.0
[[organs.loads]]
kind = "displacement"
name = "y0"
region = { half_space = { point = [0.0, 0.0, 0.0], normal = [0.0, -1.0, 0.0] } }
y = 0.0
[[organs.loads]]
kind = "displacement"
name = "z0"
region = { half_space = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, -1.0] } }
z = 0.0
[[organs.loads]]
kind = "pressure"
region = { half_space = { point = [0.1, 0.0, 0.0], normal = [1.0, 0.0, 0.0] } }
pressure = 50.0
[[organs.loads]]
kind = "pressure"
region = { half_space = { point = [0.0, 0.1, 0.0], normal = [0.0, 1.0, 0.0] } }
pressure = 50.0
[[organs.loads]]
kind = "pressure"
region = { half_space = { point = [0.0, 0.0, 0.1], normal = [0.0, 0.0, 1.0] } }
pressure = 50.0
"#;
    let scene = vademecum_engine::scene::Scene::from_toml(text, "pressed.toml").unwrap();
    let m = scene.organ_model(0).unwrap();
    let sol = vademecum_engine::fem::linear_static::solve(&m.mesh, &m.materials, m.locking, &m.problem, &mut |_| {}).unwrap();
    let mat = LinearElastic::new(3000.0, 0.3).unwrap();
    let eps = -50.0 / (3.0 * mat.bulk());
    for (n, x) in m.mesh.nodes.iter().enumerate() {
        for i in 0..3 {
            assert!(
                (sol.u[3 * n + i] - eps * x[i]).abs() < 1e-9,
                "node {n} component {i}: {} vs {}",
                sol.u[3 * n + i],
                eps * x[i]
            );
        }
    }
}

/// `[[organs.fixed]]` with chosen components and an elastic foundation: a block confined
/// laterally by rollers on its four sides, resting on a foundation of stiffness k (Pa/m) and
/// pressed by p on top, is in uniaxial strain: `u_z(z) = −p/k − p z / (λ + 2μ)` — exactly, for
/// linear elements. The foundation's reaction balances the load, reported under its name.
#[test]
fn rollers_and_an_elastic_foundation_give_the_exact_confined_compression() {
    let text = r#"[scene]
name = "confined"
[[organs]]
name = "block"
density = 1000.0
[organs.mesh]
builtin = "block"
size = [0.1, 0.1, 0.1]
divisions = [2, 2, 3]
[[organs.materials]]
model = "linear"
young = 3000.0
poisson = 0.3
[[organs.fixed]]
name = "sides x"
region = { box = { min = [0.0, -1.0, -1.0], max = [0.0, 1.0, 1.0] } }
components = ["x"]
[[organs.fixed]]
region = { box = { min = [0.1, -1.0, -1.0], max = [0.1, 1.0, 1.0] } }
components = ["x"]
[[organs.fixed]]
region = { box = { min = [-1.0, 0.0, -1.0], max = [1.0, 0.0, 1.0] } }
components = ["y"]
[[organs.fixed]]
region = { box = { min = [-1.0, 0.1, -1.0], max = [1.0, 0.1, 1.0] } }
components = ["y"]
[[organs.fixed]]
name = "bed"
region = { half_space = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, -1.0] } }
components = ["z"]
stiffness = 2e4
[organs.accessible]
half_space = { point = [0.0, 0.0, 0.1], normal = [0.0, 0.0, 1.0] }
[[organs.loads]]
kind = "pressure"
region = { half_space = { point = [0.0, 0.0, 0.1], normal = [0.0, 0.0, 1.0] } }
pressure = 30.0
"#;
    let scene = vademecum_engine::scene::Scene::from_toml(text, "confined.toml").unwrap();
    let m = scene.organ_model(0).unwrap();
    let names: Vec<&str> = m.named_regions.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["sides x", "fixed2", "fixed3", "fixed4", "bed"]);
    let sol = vademecum_engine::fem::linear_static::solve(&m.mesh, &m.materials, m.locking, &m.problem, &mut |_| {}).unwrap();
    let mat = LinearElastic::new(3000.0, 0.3).unwrap();
    let (p, k) = (30.0, 2e4);
    for (n, x) in m.mesh.nodes.iter().enumerate() {
        let exact = -p / k - p * x[2] / (mat.lambda() + 2.0 * mat.shear());
        assert!((sol.u[3 * n + 2] - exact).abs() < 1e-9, "node {n}: {} vs {exact}", sol.u[3 * n + 2]);
        assert!(sol.u[3 * n].abs() < 1e-12 && sol.u[3 * n + 1].abs() < 1e-12);
    }
    let bed = &m.named_regions[4].1;
    let reaction: f64 = bed.iter().map(|&n| sol.reactions[3 * n + 2]).sum();
    assert!((reaction - p * 0.01).abs() < 1e-9, "the bed carries {reaction} N of {} N", p * 0.01);
}

/// A `force` load's `distribution`: `equal` gives every node of the region the same share;
/// `surface` and `volume` integrate a uniform traction / density with the shape functions
/// (on a 2 × 2 face grid, a corner node carries 1/16 of the total, an edge node 2/16, the
/// centre 4/16). All three carry the whole force.
#[test]
fn force_distributions_share_the_total_as_documented() {
    let scene_with = |distribution: &str| {
        format!(
            r#"[scene]
name = "shared"
[[organs]]
name = "block"
density = 1000.0
[organs.mesh]
builtin = "block"
size = [0.1, 0.1, 0.1]
divisions = [2, 2, 2]
[[organs.materials]]
model = "linear"
young = 3000.0
poisson = 0.3
[organs.fixed]
half_space = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, -1.0] }}
[organs.accessible]
half_space = {{ point = [0.0, 0.0, 0.1], normal = [0.0, 0.0, 1.0] }}
[[organs.loads]]
kind = "force"
region = {{ half_space = {{ point = [0.0, 0.0, 0.1], normal = [0.0, 0.0, 1.0] }} }}
force = [0.0, 0.0, -1.6]
{distribution}
"#
        )
    };
    let share = |distribution: &str, at: [f64; 3]| -> (f64, f64) {
        let m = vademecum_engine::scene::Scene::from_toml(&scene_with(distribution), "s.toml")
            .unwrap()
            .organ_model(0)
            .unwrap();
        let f = &m.problem.forces;
        let node = m
            .mesh
            .nodes
            .iter()
            .position(|x| (0..3).all(|i| (x[i] - at[i]).abs() < 1e-12))
            .unwrap();
        (f[3 * node + 2], (0..m.mesh.n_nodes()).map(|n| f[3 * n + 2]).sum())
    };
    for d in ["", "distribution = \"equal\""] {
        let (c, total) = share(d, [0.05, 0.05, 0.1]);
        assert!((c + 1.6 / 9.0).abs() < 1e-12 && (total + 1.6).abs() < 1e-12, "{d}: {c} {total}");
    }
    let (centre, total) = share("distribution = \"surface\"", [0.05, 0.05, 0.1]);
    let (corner, _) = share("distribution = \"surface\"", [0.0, 0.0, 0.1]);
    assert!((centre + 0.4).abs() < 1e-12 && (corner + 0.1).abs() < 1e-12 && (total + 1.6).abs() < 1e-12);
    // the region holds only the top layer of nodes: no cell lies in it
    let e = vademecum_engine::scene::Scene::from_toml(&scene_with("distribution = \"volume\""), "s.toml")
        .unwrap()
        .organ_model(0)
        .unwrap_err();
    assert!(e.to_string().contains("no cell has all its nodes inside"), "{e}");
    let whole = scene_with("distribution = \"volume\"").replace(
        "region = { half_space = { point = [0.0, 0.0, 0.1]",
        "region = { half_space = { point = [0.0, 0.0, 0.0]",
    );
    let m = vademecum_engine::scene::Scene::from_toml(&whole, "s.toml")
        .unwrap()
        .organ_model(0)
        .unwrap();
    let total: f64 = (0..m.mesh.n_nodes()).map(|n| m.problem.forces[3 * n + 2]).sum();
    assert!((total + 1.6).abs() < 1e-12, "{total}");
}
