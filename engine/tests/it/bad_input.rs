//! Bad input gets a clear error, never a panic: truncated or garbled meshes, inverted or
//! zero-volume cells, unknown scene keys, missing files, an empty or insufficient fixed region.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use vademecum_engine::fem::Locking;
use vademecum_engine::fem::assembly::MaterialMap;
use vademecum_engine::fem::linear_static::{self, StaticError, StaticProblem};
use vademecum_engine::material::LinearElastic;
use vademecum_engine::mesh::{self, MeshError, procedural};
use vademecum_engine::scene::Scene;

fn v2_text() -> String {
    let m = procedural::block_tet([0.0; 3], [0.1; 3], [2, 2, 2]);
    let mut s = format!("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n{}\n", m.n_nodes());
    for (i, p) in m.nodes.iter().enumerate() {
        s += &format!("{} {} {} {}\n", i + 1, p[0], p[1], p[2]);
    }
    s += &format!("$EndNodes\n$Elements\n{}\n", m.n_cells());
    for (i, c) in m.cells_iter().enumerate() {
        s += &format!("{} 4 2 1 1 {} {} {} {}\n", i + 1, c[0] + 1, c[1] + 1, c[2] + 1, c[3] + 1);
    }
    s + "$EndElements\n"
}

/// Parses `bytes` as a Gmsh file; must return (Ok or Err) without panicking.
fn parse_no_panic(bytes: &[u8]) -> Result<mesh::Mesh, MeshError> {
    catch_unwind(AssertUnwindSafe(|| mesh::gmsh::parse(bytes, Path::new("x.msh")))).expect("the Gmsh reader panicked")
}

#[test]
fn every_truncation_of_a_gmsh_file_is_an_error_not_a_panic() {
    let full = v2_text().into_bytes();
    assert!(parse_no_panic(&full).is_ok());
    let mut errors = 0;
    for cut in (0..full.len() - 1).step_by(7) {
        if parse_no_panic(&full[..cut]).is_err() {
            errors += 1;
        }
    }
    assert!(errors > 0);
    let e = parse_no_panic(&full[..full.len() / 2]).unwrap_err();
    assert!(e.to_string().contains("x.msh"), "message names the file: {e}");
}

#[test]
fn garbled_gmsh_is_an_error() {
    let text = v2_text().replace("$EndNodes", "$EndNodez");
    let e = parse_no_panic(text.as_bytes()).unwrap_err();
    assert!(e.to_string().contains("$EndNodes"), "{e}");
    let text = v2_text().replacen(" 4 2 1 1 ", " 4 2 1 1 banana ", 1);
    let e = parse_no_panic(text.as_bytes()).unwrap_err();
    assert!(e.to_string().contains("banana"), "{e}");
    let junk: Vec<u8> = (0..2000u32).map(|i| (i.wrapping_mul(2654435761u32) >> 24) as u8).collect();
    assert!(parse_no_panic(&junk).is_err());
    let e = parse_no_panic(b"$MeshFormat\n3.0 0 8\n$EndMeshFormat\n").unwrap_err();
    assert!(e.to_string().contains("not supported"), "{e}");
    // an element of a type Gmsh does not have is refused with its line (it was dropped: 95 of
    // 96 cells kept, and the scene checked)
    let text = v2_text();
    let line = text.lines().position(|l| l.starts_with("7 4 2 1 1 ")).unwrap() + 1;
    let e = parse_no_panic(text.replacen("\n7 4 2 1 1 ", "\n7 77 2 1 1 ", 1).as_bytes()).unwrap_err();
    assert!(
        e.to_string().contains(&format!("line {line}")) && e.to_string().contains("type 77"),
        "{e}"
    );
    // a second $Elements section (it doubled the cells) or $Nodes section is refused as such
    let elements = &text[text.find("$Elements").unwrap()..];
    let e = parse_no_panic(format!("{text}{elements}").as_bytes()).unwrap_err();
    assert!(e.to_string().contains("second $Elements"), "{e}");
    let nodes = &text[text.find("$Nodes").unwrap()..text.find("$Elements").unwrap()];
    let e = parse_no_panic(format!("{text}{nodes}").as_bytes()).unwrap_err();
    assert!(e.to_string().contains("second $Nodes"), "{e}");
}

#[test]
fn truncated_or_garbled_binary_gmsh_is_an_error() {
    // binary v4.1 through mshio, and binary v2, cut at every 13th byte
    let m = procedural::block_tet([0.0; 3], [0.1; 3], [1, 1, 1]);
    let mut f = b"$MeshFormat\n2.2 1 8\n".to_vec();
    f.extend_from_slice(&1i32.to_le_bytes());
    f.extend_from_slice(format!("\n$EndMeshFormat\n$Nodes\n{}\n", m.n_nodes()).as_bytes());
    for (i, p) in m.nodes.iter().enumerate() {
        f.extend_from_slice(&(i as i32 + 1).to_le_bytes());
        for x in p {
            f.extend_from_slice(&x.to_le_bytes());
        }
    }
    f.extend_from_slice(format!("\n$EndNodes\n$Elements\n{}\n", m.n_cells()).as_bytes());
    for v in [4i32, m.n_cells() as i32, 2] {
        f.extend_from_slice(&v.to_le_bytes());
    }
    for (i, c) in m.cells_iter().enumerate() {
        for v in [i as i32 + 1, 1, 1] {
            f.extend_from_slice(&v.to_le_bytes());
        }
        for n in c {
            f.extend_from_slice(&(*n as i32 + 1).to_le_bytes());
        }
    }
    f.extend_from_slice(b"\n$EndElements\n");
    assert!(parse_no_panic(&f).is_ok());
    for cut in (0..f.len() - 1).step_by(13) {
        let _ = parse_no_panic(&f[..cut]);
    }
    // a corrupt block header (negative count)
    let mut g = f.clone();
    let at = g.windows(9).position(|w| w == b"Elements\n").unwrap() + 9 + 2 + 4;
    g[at..at + 4].copy_from_slice(&(-5i32).to_le_bytes());
    assert!(parse_no_panic(&g).is_err());
    // v4.1 garbage after a valid header goes through mshio
    let mut h = b"$MeshFormat\n4.1 1 8\n".to_vec();
    h.extend_from_slice(&1i32.to_le_bytes());
    h.extend_from_slice(b"\n$EndMeshFormat\n$Nodes\n\x01\x02\x03");
    assert!(parse_no_panic(&h).is_err());
}

#[test]
fn truncated_or_garbled_vtu_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let m = procedural::block_hex([0.0; 3], [0.1; 3], [2, 2, 2]);
    let good = dir.path().join("g.vtu");
    mesh::vtk::write_vtu(&good, &m, &[], &[]).unwrap();
    let text = std::fs::read_to_string(&good).unwrap();
    for (name, bad) in [
        ("half.vtu", text[..text.len() / 2].to_string()),
        ("garbled.vtu", text.replace("<Points>", "<Poin ts>")),
        ("nan.vtu", text.replacen("0.0 0.0 0.0", "zero zero", 1)),
        (
            "outofrange.vtu",
            text.replacen("\n0 1 4 3 9 10 13 12\n", "\n0 1 4 3 9 10 13 999\n", 1),
        ),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, bad).unwrap();
        let r = catch_unwind(|| mesh::read(&p)).expect("the VTK reader panicked");
        let e = r.expect_err(name);
        assert!(e.to_string().contains(name), "{name}: message names the file: {e}");
    }
}

#[test]
fn missing_mesh_file_is_an_io_error() {
    let e = mesh::read("/nonexistent/organ.msh").unwrap_err();
    assert!(matches!(e, MeshError::Io { .. }), "{e}");
    assert!(e.to_string().contains("/nonexistent/organ.msh"));
    let e = mesh::read("organ.stl").unwrap_err();
    assert!(e.to_string().contains("unknown mesh format"), "{e}");
}

#[test]
fn inverted_and_zero_volume_cells_are_rejected() {
    let mut m = procedural::block_tet([0.0; 3], [0.1; 3], [2, 2, 2]);
    let good = m.clone();
    m.cells.swap(4 * 5 + 1, 4 * 5 + 2); // invert cell 5 only
    let e = m.clone().check_cells().unwrap_err();
    assert!(matches!(e, MeshError::InvertedCells { count: 1, first: 5, .. }), "{e}");
    // a consistently mirrored mesh is a convention, not an error
    let mut all = good.clone();
    all.flip_orientation();
    all.check_cells().unwrap();
    assert_eq!(all.cells, good.cells);
    // zero volume: collapse a tetrahedron onto a face
    let mut z = good.clone();
    let c = z.cell(3).to_vec();
    z.nodes.push(z.nodes[c[0]]);
    let dup = z.nodes.len() - 1;
    z.cells[4 * 3 + 1] = dup;
    let e = z.check_cells().unwrap_err();
    assert!(matches!(e, MeshError::DegenerateCells { .. }), "{e}");
}

const GOOD_SCENE: &str = r#"[scene]
name = "s"

[[organs]]
name = "block"
density = 1000.0

[organs.mesh]
builtin = "block"
size = [0.1, 0.1, 0.1]
divisions = [2, 2, 2]

[[organs.materials]]
model = "linear"
young = 1e4
poisson = 0.3

[organs.fixed]
box = { min = [0.0, 0.0, 0.0], max = [0.0, 0.1, 0.1] }

[organs.accessible]
half_space = { point = [0.0, 0.0, 0.1], normal = [0.0, 0.0, 1.0] }
"#;

#[test]
fn unknown_scene_key_names_the_file_line_and_key() {
    Scene::from_toml(GOOD_SCENE, "s.toml").unwrap();
    let bad = GOOD_SCENE.replace("poisson = 0.3", "poisson = 0.3\npoison = 0.3");
    let e = Scene::from_toml(&bad, "s.toml").unwrap_err();
    assert_eq!(e.file, Path::new("s.toml"));
    assert_eq!(e.line, Some(17));
    let msg = e.to_string();
    assert!(msg.starts_with("s.toml:17:") && msg.contains("poison"), "{msg}");
}

#[test]
fn inconsistent_scene_settings_name_the_key_and_line() {
    let bad = GOOD_SCENE.replace("poisson = 0.3", "poisson = 0.5");
    let e = Scene::from_toml(&bad, "s.toml").unwrap_err();
    assert_eq!(e.key.as_deref(), Some("organs[0].materials[0].poisson"));
    assert_eq!(e.line, Some(16));
    let bad = GOOD_SCENE.to_string() + "\n[effects]\ncutting = true\n";
    let e = Scene::from_toml(&bad, "s.toml").unwrap_err();
    assert!(e.to_string().contains("scalpel"), "{e}");
    assert_eq!(e.key.as_deref(), Some("effects.cutting"));
    // at most four tools (a session moves them together), each name once
    let tools = |n: usize| {
        (0..n)
            .map(|i| format!("\n[[tools]]\nkind = \"probe\"\nname = \"p{i}\"\nradius = 0.004\n"))
            .collect::<String>()
    };
    Scene::from_toml(&(GOOD_SCENE.to_string() + &tools(4)), "s.toml").unwrap();
    let e = Scene::from_toml(&(GOOD_SCENE.to_string() + &tools(5)), "s.toml").unwrap_err();
    assert!(e.to_string().contains("5 tools") && e.to_string().contains("at most 4"), "{e}");
    assert_eq!(e.key.as_deref(), Some("tools"));
    let twice = GOOD_SCENE.to_string() + &tools(2).replace("p1", "p0");
    let e = Scene::from_toml(&twice, "s.toml").unwrap_err();
    assert!(e.to_string().contains("'p0' is used twice"), "{e}");
    let bad = GOOD_SCENE.replace("builtin = \"block\"", "builtin = \"block\"\nfile = \"x.msh\"");
    let e = Scene::from_toml(&bad, "s.toml").unwrap_err();
    assert!(e.to_string().contains("not both"), "{e}");
    // numeric settings are bounded to their documented range (a build asked for 2³¹
    // iterations per mode would never end)
    for (key, value) in [("max_iterations", "2147483648"), ("max_modes", "2000000"), ("block", "100000")] {
        let bad = GOOD_SCENE.to_string() + &format!("\n[fidelity.pgd]\n{key} = {value}\n");
        let e = Scene::from_toml(&bad, "s.toml").unwrap_err();
        assert_eq!(e.key.as_deref(), Some(format!("fidelity.pgd.{key}").as_str()), "{e}");
        assert!(e.to_string().contains("more than"), "{e}");
    }
}

/// Size limits count the cells a built-in mesh produces (six tetrahedra per cube), and a mesh
/// whose direct solve would not fit is refused before anything is assembled, with the figures.
#[test]
fn oversized_meshes_are_refused_with_their_size_before_any_allocation() {
    let tets = GOOD_SCENE.replace("divisions = [2, 2, 2]", "divisions = [256, 256, 256]\ncell = \"tet4\"");
    let e = Scene::from_toml(&tets, "s.toml").unwrap_err();
    assert!(e.to_string().contains("100663296 cells (6 per division cube)"), "{e}");
    assert_eq!(e.key.as_deref(), Some("organs[0].mesh.divisions"));
    let hexes = GOOD_SCENE.replace("divisions = [2, 2, 2]", "divisions = [60, 60, 60]");
    let scene = Scene::from_toml(&hexes, "s.toml").unwrap();
    let e = scene.organ_model_within(0, Some(1_000_000_000)).unwrap_err();
    assert!(
        e.to_string().contains("needs about") && e.to_string().contains("more than the 1.0 GB allowed"),
        "{e}"
    );
    assert!(scene.organ_model_within(0, Some(u64::MAX)).is_ok());
}

/// A misspelt support key is named, not lost in "no variant matched"; an elastic support
/// needs a positive stiffness.
#[test]
fn bad_supports_name_the_problem() {
    let supports = GOOD_SCENE.replace(
        "[organs.fixed]\nbox = { min = [0.0, 0.0, 0.0], max = [0.0, 0.1, 0.1] }",
        "[[organs.fixed]]\nregion = { box = { min = [0.0, 0.0, 0.0], max = [0.0, 0.1, 0.1] } }\ncomponent = [\"x\"]",
    );
    let e = Scene::from_toml(&supports, "s.toml").unwrap_err();
    assert!(e.to_string().contains("unknown field `component`"), "{e}");
    let e = Scene::from_toml(&supports.replace("component = [\"x\"]", "stiffness = -1.0"), "s.toml").unwrap_err();
    assert!(e.to_string().contains("`stiffness` must be positive"), "{e}");
    assert_eq!(e.key.as_deref(), Some("organs[0].fixed[0]"));
    Scene::from_toml(&supports.replace("component = [\"x\"]", "components = [\"x\", \"z\"]"), "s.toml").unwrap();
}

/// `volumetric` only applies to laws with a volumetric part, and the locking-free tetrahedron
/// only to tetrahedra.
#[test]
fn volumetric_and_locking_options_are_refused_where_they_do_not_apply() {
    let bad = GOOD_SCENE.replace("poisson = 0.3", "poisson = 0.3\nvolumetric = \"ln_j\"");
    let e = Scene::from_toml(&bad, "s.toml").unwrap_err();
    assert_eq!(e.key.as_deref(), Some("organs[0].materials[0].volumetric"), "{e}");
    let bad = GOOD_SCENE.to_string() + "\n[fidelity]\nlocking = \"nodal\"\n";
    let scene = Scene::from_toml(&bad, "s.toml").unwrap();
    let e = scene.organ_model(0).unwrap_err();
    assert!(e.to_string().contains("applies to tetrahedra"), "{e}");
    // the default on tetrahedra follows ν, with a warning for a plain element that will lock
    let tets = GOOD_SCENE.replace("divisions = [2, 2, 2]", "divisions = [2, 2, 2]\ncell = \"tet4\"");
    let m = Scene::from_toml(&tets.replace("poisson = 0.3", "poisson = 0.49"), "s.toml")
        .unwrap()
        .organ_model(0)
        .unwrap();
    assert_eq!(m.locking, vademecum_engine::fem::Locking::Nodal);
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    let plain = tets.replace("poisson = 0.3", "poisson = 0.49") + "\n[fidelity]\nlocking = \"none\"\n";
    let m = Scene::from_toml(&plain, "s.toml").unwrap().organ_model(0).unwrap();
    assert!(m.warnings.iter().any(|w| w.contains("lock")), "{:?}", m.warnings);
    let m = Scene::from_toml(&tets, "s.toml").unwrap().organ_model(0).unwrap();
    assert_eq!(m.locking, vademecum_engine::fem::Locking::None);
}

#[test]
fn missing_scene_and_mesh_files_are_clear_errors() {
    let e = Scene::load("/nonexistent/scene.toml").unwrap_err();
    assert!(
        e.to_string().contains("/nonexistent/scene.toml") && e.to_string().contains("cannot read"),
        "{e}"
    );
    let text = GOOD_SCENE.replace(
        "builtin = \"block\"\nsize = [0.1, 0.1, 0.1]\ndivisions = [2, 2, 2]",
        "file = \"missing.msh\"",
    );
    let s = Scene::from_toml(&text, "/tmp/dir/s.toml").unwrap();
    let e = s.organ_model(0).unwrap_err();
    assert_eq!(e.key.as_deref(), Some("organs[0].mesh.file"));
    assert!(
        e.to_string().contains("/tmp/dir/missing.msh"),
        "path is resolved next to the scene: {e}"
    );
}

#[test]
fn empty_fixed_region_is_rejected_before_solving() {
    let bad = GOOD_SCENE
        .replace("max = [0.0, 0.1, 0.1] }", "max = [-0.01, 0.1, 0.1] }")
        .replace("min = [0.0, 0.0, 0.0]", "min = [-0.02, 0.0, 0.0]");
    let s = Scene::from_toml(&bad, "s.toml").unwrap();
    let e = s.organ_model(0).unwrap_err();
    assert_eq!(e.key.as_deref(), Some("organs[0].fixed"));
    assert!(
        e.to_string().contains("selects no node") && e.to_string().contains("singular"),
        "{e}"
    );
}

#[test]
fn a_fixed_region_that_allows_rigid_motion_is_a_clear_solver_error() {
    let m = procedural::block_hex([0.0; 3], [0.1; 3], [2, 2, 2]);
    let mat = MaterialMap::uniform(LinearElastic::new(1e4, 0.3).unwrap(), 1000.0, m.n_cells());
    let mut p = StaticProblem::new(m.n_nodes());
    p.forces[3 * 26 + 2] = -1.0;
    let e = linear_static::solve(&m, &mat, Locking::Bbar, &p, &mut |_| {}).unwrap_err();
    assert_eq!(e, StaticError::NoConstraints);
    p.clamp(&[0]);
    let e = linear_static::solve(&m, &mat, Locking::Bbar, &p, &mut |_| {}).unwrap_err();
    match &e {
        StaticError::RigidMotion { free } => assert_eq!(free.len(), 3, "{e}"),
        other => panic!("expected RigidMotion, got {other}"),
    }
    assert!(e.to_string().contains("rotation"), "{e}");
}

#[test]
fn bad_meshless_settings_and_cuts_name_the_key() {
    let meshless = GOOD_SCENE.to_string() + "\n[fidelity]\nsolver = \"meshless\"\n";
    Scene::from_toml(&meshless, "s.toml").unwrap();
    for (setting, key) in [
        ("support = 0.5", "fidelity.meshless.support"),
        ("integration = 3", "fidelity.meshless.integration"),
        ("tolerance = -1e-7", "fidelity.meshless.tolerance"),
        ("loading_steps = 10\nmax_steps = 5", "fidelity.meshless.max_steps"),
    ] {
        let bad = format!("{meshless}\n[fidelity.meshless]\n{setting}\n");
        let e = Scene::from_toml(&bad, "s.toml").unwrap_err();
        assert_eq!(e.key.as_deref(), Some(key), "{setting}: {e}");
    }
    // a cut needs cutting on (and a scalpel), and blade positions that sweep an area
    let cut = "\n[[organs.cuts]]\nblade = [[[0.0, 0.05, 0.0], [0.0, 0.05, 0.1]], [[0.1, 0.05, 0.0], [0.1, 0.05, 0.1]]]\n";
    let with_cut = GOOD_SCENE.replace("[organs.fixed]", &format!("{cut}\n[organs.fixed]"));
    let e = Scene::from_toml(&(with_cut.clone() + "\n[fidelity]\nsolver = \"meshless\"\n"), "s.toml").unwrap_err();
    assert!(e.to_string().contains("effects.cutting = true"), "{e}");
    let tools = "\n[[tools]]\nkind = \"scalpel\"\nname = \"s\"\nblade_length = 0.02\ncut_force = 1.0\n\n[effects]\ncutting = true\n\n[fidelity]\nsolver = \"meshless\"\n";
    let ok = Scene::from_toml(&(with_cut.clone() + tools), "s.toml").unwrap();
    assert_eq!(ok.organ_cuts(0).unwrap().len(), 1);
    let flat = with_cut.replace("[[0.1, 0.05, 0.0], [0.1, 0.05, 0.1]]", "[[0.0, 0.05, 0.0], [0.0, 0.05, 0.1]]");
    let e = Scene::from_toml(&(flat + tools), "s.toml").unwrap_err();
    assert_eq!(e.key.as_deref(), Some("organs[0].cuts[0].blade"));
    assert!(e.to_string().contains("sweep no area"), "{e}");
    let nan = with_cut.replace("0.05, 0.1]]]", "nan, 0.1]]]");
    let e = Scene::from_toml(&(nan + tools), "s.toml").unwrap_err();
    assert!(e.to_string().contains("not finite"), "{e}");
}

#[test]
fn bad_large_deformation_lattice_settings_name_the_key() {
    let ok = GOOD_SCENE.to_string() + "\n[fidelity.large]\norder = 8\n";
    Scene::from_toml(&ok, "s.toml").unwrap();
    for (setting, key) in [
        ("order = 9", "fidelity.large.order"),
        ("order = 0", "fidelity.large.order"),
        ("load_steps = 0", "fidelity.large"),
        ("max_force = -1.0", "fidelity.large.max_force"),
        ("max_force = nan", "fidelity.large.max_force"),
    ] {
        let bad = format!("{GOOD_SCENE}\n[fidelity.large]\n{setting}\n");
        let e = Scene::from_toml(&bad, "s.toml").unwrap_err();
        assert_eq!(e.key.as_deref(), Some(key), "{setting}: {e}");
    }
}

/// Reproducers the fuzzer found: a Gmsh v1 tetrahedron listing 3 nodes and a hexahedron
/// listing 4 (the reader indexed past them), and a v4 header whose data size overflows
/// (mshio unwrapped the overflow).
#[test]
fn fuzzer_reproducers_for_gmsh_are_errors() {
    let v1 = |elements: &str| format!("$NOD\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$ENDNOD\n$ELM\n1\n{elements}\n$ENDELM\n");
    assert!(parse_no_panic(v1("1 4 1 1 4 1 2 3 4").as_bytes()).is_ok());
    let e = parse_no_panic(v1("1 4 1 1 3 1 2 3").as_bytes()).unwrap_err();
    assert!(e.to_string().contains("tetrahedron") && e.to_string().contains("x.msh"), "{e}");
    let e = parse_no_panic(v1("1 5 1 1 4 1 2 3 4").as_bytes()).unwrap_err();
    assert!(e.to_string().contains("hexahedron"), "{e}");
    let e = parse_no_panic(b"$MeshFormat\n4.1 0 18446744073709551616\n$EndMeshFormat\n").unwrap_err();
    assert!(e.to_string().contains("data size"), "{e}");
    let e = parse_no_panic(b"$MeshFormat\n4.1 7 8\n$EndMeshFormat\n").unwrap_err();
    assert!(e.to_string().contains("file type"), "{e}");
    // whatever mshio says, the message is ours and names the file
    let e = parse_no_panic(b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2 3\n").unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("x.msh") && text.contains("Gmsh 4.1") && !text.contains("Complete"),
        "{text}"
    );
}

/// Every file a user names — a mesh (Gmsh, VTK), a scene, a visual surface — is read only if it
/// is a regular file: a FIFO (which would block the reader for ever), a device (which would
/// feed it without end), and links to either are refused at once, saying what they are. Each
/// call runs on a thread with a deadline, so a reader that blocks fails the test instead of
/// hanging it.
#[test]
fn special_files_named_as_meshes_scenes_or_surfaces_are_refused_at_once() {
    use vademecum_engine::xfem::visual::VisualMesh;
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status().expect("mkfifo runs");
    assert!(made.success());
    let mut specials = vec![(fifo.clone(), "FIFO")];
    for (device, what) in [("/dev/zero", "device"), ("/dev/null", "device")] {
        let link = dir.path().join(format!("link_to_{}", &device[5..]));
        std::os::unix::fs::symlink(device, &link).unwrap();
        specials.push((link, what));
    }
    for (special, what) in specials {
        for ext in ["msh", "vtu", "vtk", "toml", "obj"] {
            let named = dir
                .path()
                .join(format!("{}_{ext}.{ext}", special.file_name().unwrap().to_string_lossy()));
            std::os::unix::fs::symlink(&special, &named).unwrap();
            let (tx, rx) = std::sync::mpsc::channel();
            let path = named.clone();
            std::thread::spawn(move || {
                let e = match ext {
                    "toml" => Scene::load(&path).err().map(|e| e.to_string()),
                    "obj" => VisualMesh::load_obj(&path, 1.0).err().map(|e| e.to_string()),
                    _ => mesh::read(&path).err().map(|e| e.to_string()),
                };
                let _ = tx.send(e);
            });
            let e = rx
                .recv_timeout(std::time::Duration::from_secs(10))
                .unwrap_or_else(|_| panic!("reading the {what} {} as .{ext} blocked", named.display()))
                .unwrap_or_else(|| panic!("the {what} {} was read as a .{ext}", named.display()));
            assert!(e.contains(what) && e.contains("not a regular file"), ".{ext} of a {what}: {e}");
        }
    }
}

/// A load so large that what is made of the displacement overflows (gravity of 1e308 solved
/// with exit 0 and every figure infinite) is an error, as a non-finite displacement is; the
/// same scene at an ordinary load solves.
#[test]
fn a_solve_whose_figures_overflow_is_an_error() {
    for (g, finite) in [("-9.81", true), ("-1e308", false)] {
        let text = format!("{GOOD_SCENE}\n[[organs.loads]]\nkind = \"gravity\"\nacceleration = [0.0, 0.0, {g}]\n");
        let scene = Scene::from_toml(&text, "s.toml").unwrap();
        let m = scene.organ_model(0).unwrap();
        let r = linear_static::solve(&m.mesh, &m.materials, m.locking, &m.problem, &mut |_| {});
        match r {
            Ok(sol) => {
                assert!(finite, "gravity {g}: solved, energy {}", sol.strain_energy);
                assert!(sol.strain_energy.is_finite() && sol.strain_energy > 0.0);
            }
            Err(e) => {
                assert!(!finite, "gravity {g}: {e}");
                assert!(matches!(e, StaticError::NonFinite), "{e}");
            }
        }
    }
}
