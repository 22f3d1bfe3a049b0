//! Every supported mesh format reads back what was written: Gmsh v1, v2 (ASCII and binary)
//! and v4.1 (ASCII and binary) with physical groups, legacy VTK (ASCII and big-endian
//! binary), and our own `.vtu` writer (mesh and fields, bit for bit).

use std::io::Write;
use std::path::Path;

use vademecum_engine::mesh::boundary::Boundary;
use vademecum_engine::mesh::vtk::{self, Field};
use vademecum_engine::mesh::{self, CellKind, Mesh, procedural};

/// A small tet block whose z = 0 boundary triangles form the physical surface 3 ("base"),
/// and whose cells form the physical volume 7 ("tissue").
fn sample() -> (Mesh, Vec<[usize; 3]>) {
    let m = procedural::block_tet([0.0; 3], [0.2, 0.1, 0.1], [4, 2, 2]);
    let b = Boundary::of(&m);
    let base: Vec<[usize; 3]> = b
        .faces
        .iter()
        .filter(|f| f.node_slice().iter().all(|&n| m.nodes[n][2] == 0.0))
        .map(|f| [f.nodes[0], f.nodes[1], f.nodes[2]])
        .collect();
    (m, base)
}

/// Node tags used in the v1/v2 files: sparse, to exercise the tag → index map.
fn tag(i: usize) -> usize {
    10 * i + 5
}

fn write_v2_ascii(path: &Path, m: &Mesh, base: &[[usize; 3]]) {
    let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n2 3 \"base\"\n3 7 \"tissue\"\n$EndPhysicalNames\n");
    s += &format!("$Nodes\n{}\n", m.n_nodes());
    for (i, p) in m.nodes.iter().enumerate() {
        s += &format!("{} {:?} {:?} {:?}\n", tag(i), p[0], p[1], p[2]);
    }
    s += &format!("$EndNodes\n$Elements\n{}\n", base.len() + m.n_cells() + 1);
    let mut id = 1;
    s += &format!("{id} 15 2 0 1 {}\n", tag(0)); // a point element, skipped
    for t in base {
        id += 1;
        s += &format!("{id} 2 2 3 1 {} {} {}\n", tag(t[0]), tag(t[1]), tag(t[2]));
    }
    for c in m.cells_iter() {
        id += 1;
        s += &format!("{id} 4 2 7 1 {} {} {} {}\n", tag(c[0]), tag(c[1]), tag(c[2]), tag(c[3]));
    }
    s += "$EndElements\n";
    std::fs::write(path, s).unwrap();
}

fn write_v2_binary(path: &Path, m: &Mesh, base: &[[usize; 3]]) {
    let mut f = Vec::new();
    f.extend_from_slice(b"$MeshFormat\n2.2 1 8\n");
    f.extend_from_slice(&1i32.to_le_bytes());
    f.extend_from_slice(b"\n$EndMeshFormat\n$PhysicalNames\n2\n2 3 \"base\"\n3 7 \"tissue\"\n$EndPhysicalNames\n");
    f.extend_from_slice(format!("$Nodes\n{}\n", m.n_nodes()).as_bytes());
    for (i, p) in m.nodes.iter().enumerate() {
        f.extend_from_slice(&(tag(i) as i32).to_le_bytes());
        for x in p {
            f.extend_from_slice(&x.to_le_bytes());
        }
    }
    f.extend_from_slice(format!("\n$EndNodes\n$Elements\n{}\n", base.len() + m.n_cells()).as_bytes());
    let mut id = 0i32;
    // block of triangles: header (type, count, ntags), then id, tags, nodes
    for v in [2i32, base.len() as i32, 2] {
        f.extend_from_slice(&v.to_le_bytes());
    }
    for t in base {
        id += 1;
        for v in [id, 3, 1] {
            f.extend_from_slice(&v.to_le_bytes());
        }
        for n in t {
            f.extend_from_slice(&(tag(*n) as i32).to_le_bytes());
        }
    }
    for v in [4i32, m.n_cells() as i32, 2] {
        f.extend_from_slice(&v.to_le_bytes());
    }
    for c in m.cells_iter() {
        id += 1;
        for v in [id, 7, 1] {
            f.extend_from_slice(&v.to_le_bytes());
        }
        for n in c {
            f.extend_from_slice(&(tag(*n) as i32).to_le_bytes());
        }
    }
    f.extend_from_slice(b"\n$EndElements\n");
    std::fs::write(path, f).unwrap();
}

fn write_v1(path: &Path, m: &Mesh, base: &[[usize; 3]]) {
    let mut s = format!("$NOD\n{}\n", m.n_nodes());
    for (i, p) in m.nodes.iter().enumerate() {
        s += &format!("{} {:?} {:?} {:?}\n", tag(i), p[0], p[1], p[2]);
    }
    s += &format!("$ENDNOD\n$ELM\n{}\n", base.len() + m.n_cells());
    let mut id = 0;
    for t in base {
        id += 1;
        s += &format!("{id} 2 3 1 3 {} {} {}\n", tag(t[0]), tag(t[1]), tag(t[2]));
    }
    for c in m.cells_iter() {
        id += 1;
        s += &format!("{id} 4 7 1 4 {} {} {} {}\n", tag(c[0]), tag(c[1]), tag(c[2]), tag(c[3]));
    }
    s += "$ENDELM\n";
    std::fs::write(path, s).unwrap();
}

/// Gmsh 4.1, with one surface entity (physical 3) and one volume entity (physical 7).
fn write_v41(path: &Path, m: &Mesh, base: &[[usize; 3]], binary: bool) {
    let n = m.n_nodes();
    let mut f: Vec<u8> = Vec::new();
    let (lo, hi) = m.bounding_box();
    if !binary {
        let mut s =
            String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n2 3 \"base\"\n3 7 \"tissue\"\n$EndPhysicalNames\n");
        s += "$Entities\n0 0 1 1\n";
        s += &format!("1 {} {} {} {} {} {} 1 3 0\n", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
        s += &format!("1 {} {} {} {} {} {} 1 7 1 1\n", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
        s += &format!("$EndEntities\n$Nodes\n1 {n} 1 {n}\n3 1 0 {n}\n");
        for i in 0..n {
            s += &format!("{}\n", i + 1);
        }
        for p in &m.nodes {
            s += &format!("{:?} {:?} {:?}\n", p[0], p[1], p[2]);
        }
        s += &format!(
            "$EndNodes\n$Elements\n2 {} 1 {}\n",
            base.len() + m.n_cells(),
            base.len() + m.n_cells()
        );
        s += &format!("2 1 2 {}\n", base.len());
        let mut id = 0;
        for t in base {
            id += 1;
            s += &format!("{id} {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        s += &format!("3 1 4 {}\n", m.n_cells());
        for c in m.cells_iter() {
            id += 1;
            s += &format!("{id} {} {} {} {}\n", c[0] + 1, c[1] + 1, c[2] + 1, c[3] + 1);
        }
        s += "$EndElements\n";
        f = s.into_bytes();
    } else {
        let sz = |f: &mut Vec<u8>, v: usize| f.extend_from_slice(&(v as u64).to_le_bytes());
        let int = |f: &mut Vec<u8>, v: i32| f.extend_from_slice(&v.to_le_bytes());
        let dbl = |f: &mut Vec<u8>, v: f64| f.extend_from_slice(&v.to_le_bytes());
        f.extend_from_slice(b"$MeshFormat\n4.1 1 8\n");
        int(&mut f, 1);
        f.extend_from_slice(b"\n$EndMeshFormat\n$PhysicalNames\n2\n2 3 \"base\"\n3 7 \"tissue\"\n$EndPhysicalNames\n$Entities\n");
        for v in [0, 0, 1, 1] {
            sz(&mut f, v);
        }
        // surface 1
        int(&mut f, 1);
        for v in [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]] {
            dbl(&mut f, v);
        }
        sz(&mut f, 1);
        int(&mut f, 3);
        sz(&mut f, 0);
        // volume 1
        int(&mut f, 1);
        for v in [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]] {
            dbl(&mut f, v);
        }
        sz(&mut f, 1);
        int(&mut f, 7);
        sz(&mut f, 1);
        int(&mut f, 1);
        f.extend_from_slice(b"\n$EndEntities\n$Nodes\n");
        for v in [1, n, 1, n] {
            sz(&mut f, v);
        }
        int(&mut f, 3);
        int(&mut f, 1);
        int(&mut f, 0);
        sz(&mut f, n);
        for i in 0..n {
            sz(&mut f, i + 1);
        }
        for p in &m.nodes {
            for x in p {
                dbl(&mut f, *x);
            }
        }
        f.extend_from_slice(b"\n$EndNodes\n$Elements\n");
        let ne = base.len() + m.n_cells();
        for v in [2, ne, 1, ne] {
            sz(&mut f, v);
        }
        int(&mut f, 2);
        int(&mut f, 1);
        int(&mut f, 2);
        sz(&mut f, base.len());
        let mut id = 0;
        for t in base {
            id += 1;
            sz(&mut f, id);
            for v in t {
                sz(&mut f, v + 1);
            }
        }
        int(&mut f, 3);
        int(&mut f, 1);
        int(&mut f, 4);
        sz(&mut f, m.n_cells());
        for c in m.cells_iter() {
            id += 1;
            sz(&mut f, id);
            for v in c {
                sz(&mut f, v + 1);
            }
        }
        f.extend_from_slice(b"\n$EndElements\n");
    }
    std::fs::File::create(path).unwrap().write_all(&f).unwrap();
}

fn check_same(read: &Mesh, m: &Mesh, base: &[[usize; 3]], with_names: bool) {
    assert_eq!(read.kind, CellKind::Tet4);
    assert_eq!(read.nodes, m.nodes, "coordinates must round-trip exactly");
    assert_eq!(read.cells, m.cells);
    assert!(read.cell_region.iter().all(|r| *r == 7), "volume physical tag");
    assert_eq!(read.tagged_faces.get(&3).map(|f| f.triangles.len()), Some(base.len()));
    if with_names {
        assert_eq!(read.group_names.get(&3).map(String::as_str), Some("base"));
        assert_eq!(read.group_tag("tissue"), Some(7));
    }
}

#[test]
fn gmsh_v2_ascii_and_binary_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let (m, base) = sample();
    let a = dir.path().join("a.msh");
    write_v2_ascii(&a, &m, &base);
    check_same(&mesh::read(&a).unwrap(), &m, &base, true);
    let b = dir.path().join("b.msh");
    write_v2_binary(&b, &m, &base);
    check_same(&mesh::read(&b).unwrap(), &m, &base, true);
}

#[test]
fn gmsh_v1_reads() {
    let dir = tempfile::tempdir().unwrap();
    let (m, base) = sample();
    let p = dir.path().join("v1.msh");
    write_v1(&p, &m, &base);
    check_same(&mesh::read(&p).unwrap(), &m, &base, false);
}

#[test]
fn gmsh_v41_ascii_and_binary_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let (m, base) = sample();
    for binary in [false, true] {
        let p = dir.path().join(format!("v41_{binary}.msh"));
        write_v41(&p, &m, &base, binary);
        let r = mesh::read(&p).unwrap_or_else(|e| panic!("binary={binary}: {e}"));
        check_same(&r, &m, &base, true);
    }
}

#[test]
fn physical_groups_select_nodes_by_name() {
    use vademecum_engine::mesh::select::{GroupRef, Region};
    let dir = tempfile::tempdir().unwrap();
    let (m, base) = sample();
    let p = dir.path().join("a.msh");
    write_v2_ascii(&p, &m, &base);
    let r = mesh::read(&p).unwrap();
    let nodes = Region::Group(GroupRef::Name("base".into())).nodes(&r).unwrap();
    assert!(!nodes.is_empty() && nodes.iter().all(|&n| r.nodes[n][2] == 0.0));
    let plane = Region::Box {
        min: [0.0, 0.0, 0.0],
        max: [0.2, 0.1, 0.0],
    }
    .nodes(&r)
    .unwrap();
    assert_eq!(nodes, plane);
    let err = Region::Group(GroupRef::Name("nope".into())).nodes(&r).unwrap_err();
    assert!(err.to_string().contains("base"), "error lists the known groups: {err}");
}

#[test]
fn vtu_round_trips_mesh_and_fields_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    for m in [
        procedural::block_hex([0.0; 3], [0.3, 0.1, 0.2], [3, 2, 2]),
        procedural::lobe(&Default::default()),
    ] {
        let u: Vec<f64> = (0..m.n_dofs()).map(|i| (i as f64 * 0.37).sin() * 1e-3 / 3.0).collect();
        let vm: Vec<f64> = (0..m.n_cells()).map(|c| c as f64 / 7.0).collect();
        let p = dir.path().join("r.vtu");
        vtk::write_vtu(
            &p,
            &m,
            &[Field {
                name: "displacement",
                components: 3,
                values: &u,
            }],
            &[Field {
                name: "von_mises",
                components: 1,
                values: &vm,
            }],
        )
        .unwrap();
        let r = mesh::read(&p).unwrap();
        assert_eq!((r.kind, &r.nodes, &r.cells), (m.kind, &m.nodes, &m.cells));
        assert_eq!(vtk::read_point_data(&p, "displacement").unwrap().unwrap(), u);
        assert_eq!(vtk::read_cell_data(&p, "von_mises").unwrap().unwrap(), vm);
    }
}

#[test]
fn pvd_lists_its_steps() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("s.pvd");
    vtk::write_pvd(&p, &[(0.0, "a_0.vtu".into()), (0.5, "a_1.vtu".into())]).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.contains("timestep=\"0.5\"") && text.contains("file=\"a_1.vtu\""));
}

fn write_legacy_vtk(path: &Path, m: &Mesh, binary: bool) {
    let mut f: Vec<u8> = Vec::new();
    f.extend_from_slice(
        format!(
            "# vtk DataFile Version 3.0\ntest\n{}\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n",
            if binary { "BINARY" } else { "ASCII" },
            m.n_nodes()
        )
        .as_bytes(),
    );
    let npc = m.kind.nodes_per_cell();
    if binary {
        for p in &m.nodes {
            for x in p {
                f.extend_from_slice(&x.to_be_bytes());
            }
        }
        f.extend_from_slice(format!("\nCELLS {} {}\n", m.n_cells(), m.n_cells() * (npc + 1)).as_bytes());
        for c in m.cells_iter() {
            f.extend_from_slice(&(npc as i32).to_be_bytes());
            for &n in c {
                f.extend_from_slice(&(n as i32).to_be_bytes());
            }
        }
        f.extend_from_slice(format!("\nCELL_TYPES {}\n", m.n_cells()).as_bytes());
        for _ in 0..m.n_cells() {
            f.extend_from_slice(&(m.kind.vtk_type() as i32).to_be_bytes());
        }
        f.push(b'\n');
    } else {
        let mut s = String::new();
        for p in &m.nodes {
            s += &format!("{:?} {:?} {:?}\n", p[0], p[1], p[2]);
        }
        s += &format!("CELLS {} {}\n", m.n_cells(), m.n_cells() * (npc + 1));
        for c in m.cells_iter() {
            s += &format!("{npc} {}\n", c.iter().map(|n| n.to_string()).collect::<Vec<_>>().join(" "));
        }
        s += &format!("CELL_TYPES {}\n", m.n_cells());
        for _ in 0..m.n_cells() {
            s += &format!("{}\n", m.kind.vtk_type());
        }
        f.extend_from_slice(s.as_bytes());
    }
    std::fs::write(path, f).unwrap();
}

#[test]
fn legacy_vtk_ascii_and_binary_read() {
    let dir = tempfile::tempdir().unwrap();
    let m = procedural::block_hex([0.0; 3], [0.3, 0.1, 0.2], [3, 2, 2]);
    for binary in [false, true] {
        let p = dir.path().join(format!("l_{binary}.vtk"));
        write_legacy_vtk(&p, &m, binary);
        let r = mesh::read(&p).unwrap_or_else(|e| panic!("binary={binary}: {e}"));
        assert_eq!((r.kind, &r.nodes, &r.cells), (m.kind, &m.nodes, &m.cells));
    }
}
