//! Gmsh `.msh` reader: format versions 1 and 2 (ASCII and binary) by a small parser of our
//! own, version 4.1 (ASCII and binary) through the `mshio` crate.
//!
//! No maintained crate reads version 2, which is still what most tools and our reference
//! meshes write (`gmsh -format msh22`), so this module parses it; version 4.1 goes through
//! `mshio`, whose physical-name support we complete by reading `$PhysicalNames` (always text).
//!
//! What is kept: tetrahedra (type 4) or hexahedra (type 5) as the volume cells, with their
//! physical tag as the cell region; triangles (2) and quadrilaterals (3) that carry a
//! physical tag, as tagged boundary faces; the names of physical groups. Points and lines
//! are skipped. Higher-order or other volume cells are refused with a clear message.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use super::{CellKind, Mesh, MeshError, TaggedFaces, read_bytes};

/// Number of nodes of a Gmsh element type, for the types we may meet (None: unknown).
fn nodes_of_type(t: i32) -> Option<usize> {
    Some(match t {
        1 => 2,
        2 => 3,
        3 => 4,
        4 => 4,
        5 => 8,
        6 => 6,
        7 => 5,
        8 => 3,
        9 => 6,
        10 => 9,
        11 => 10,
        12 => 27,
        13 => 18,
        14 => 14,
        15 => 1,
        16 => 8,
        17 => 20,
        18 => 15,
        19 => 13,
        20 => 9,
        21 => 10,
        22 => 12,
        23 => 15,
        24 => 15,
        25 => 21,
        26 => 4,
        27 => 5,
        28 => 6,
        29 => 20,
        30 => 35,
        31 => 56,
        92 => 64,
        93 => 125,
        _ => return None,
    })
}

/// Whether a Gmsh element type is a 3D cell.
fn is_volume_type(t: i32) -> bool {
    matches!(t, 4..=7 | 11..=14 | 17..=19 | 29..=31 | 92 | 93)
}

/// Elements gathered from any version, before node tags are mapped to indices.
#[derive(Default)]
struct Collected {
    /// Node tag → coordinates, in file order.
    node_tags: Vec<u64>,
    nodes: Vec<[f64; 3]>,
    tets: Vec<([u64; 4], i32)>,
    hexes: Vec<([u64; 8], i32)>,
    tris: Vec<([u64; 3], i32)>,
    quads: Vec<([u64; 4], i32)>,
    /// Counts of other volume cell types (for the error message).
    other_volume: BTreeMap<i32, usize>,
    names: BTreeMap<i32, String>,
}

impl Collected {
    /// Keeps an element of Gmsh type `ty`; an element listing fewer nodes than its type
    /// has is an error (the message names the type and both counts).
    fn push_element(&mut self, ty: i32, phys: i32, nodes: &[u64]) -> Result<(), String> {
        if nodes_of_type(ty).is_none() {
            return Err(format!("an element has type {ty}, which is no Gmsh element type"));
        }
        let needs = match ty {
            2 => 3,
            3 | 4 => 4,
            5 => 8,
            _ => 0,
        };
        if nodes.len() < needs {
            let name = match ty {
                2 => "triangle",
                3 => "quadrangle",
                4 => "tetrahedron",
                _ => "hexahedron",
            };
            return Err(format!(
                "an element of type {ty} ({name}) lists {} node(s), a {name} has {needs}",
                nodes.len()
            ));
        }
        match ty {
            4 => self.tets.push(([nodes[0], nodes[1], nodes[2], nodes[3]], phys)),
            5 => {
                let mut a = [0u64; 8];
                a.copy_from_slice(&nodes[..8]);
                self.hexes.push((a, phys));
            }
            2 if phys != 0 => self.tris.push(([nodes[0], nodes[1], nodes[2]], phys)),
            3 if phys != 0 => self.quads.push(([nodes[0], nodes[1], nodes[2], nodes[3]], phys)),
            t if is_volume_type(t) => *self.other_volume.entry(t).or_default() += 1,
            _ => {}
        }
        Ok(())
    }

    fn into_mesh(self, path: &Path) -> Result<Mesh, MeshError> {
        let err = |message: String| MeshError::Parse {
            path: path.to_path_buf(),
            message,
        };
        let mut index: HashMap<u64, usize> = HashMap::with_capacity(self.node_tags.len());
        for (i, &t) in self.node_tags.iter().enumerate() {
            if index.insert(t, i).is_some() {
                return Err(err(format!("node tag {t} is defined twice")));
            }
        }
        let map = |t: u64| {
            index.get(&t).copied().ok_or_else(|| {
                err(format!(
                    "an element refers to node tag {t}, which the $Nodes section does not define"
                ))
            })
        };
        if !self.other_volume.is_empty() {
            let list: Vec<String> = self.other_volume.iter().map(|(t, n)| format!("{n} of gmsh type {t}")).collect();
            return Err(MeshError::UnsupportedCells {
                path: path.to_path_buf(),
                message: format!(
                    "unsupported volume cells ({}); vademecum reads first-order tetrahedra and hexahedra only: re-mesh with `gmsh -3 -order 1`",
                    list.join(", ")
                ),
            });
        }
        let (kind, n_cells) = match (self.tets.is_empty(), self.hexes.is_empty()) {
            (false, true) => (CellKind::Tet4, self.tets.len()),
            (true, false) => (CellKind::Hex8, self.hexes.len()),
            (false, false) => {
                return Err(MeshError::UnsupportedCells {
                    path: path.to_path_buf(),
                    message: format!(
                        "the mesh mixes {} tetrahedra and {} hexahedra; vademecum needs one cell kind per mesh",
                        self.tets.len(),
                        self.hexes.len()
                    ),
                });
            }
            (true, true) => {
                return Err(MeshError::NoVolumeCells {
                    path: path.to_path_buf(),
                    found: format!(
                        "{} nodes, {} tagged triangles, {} tagged quads",
                        self.nodes.len(),
                        self.tris.len(),
                        self.quads.len()
                    ),
                });
            }
        };
        let mut cells = Vec::with_capacity(n_cells * kind.nodes_per_cell());
        let mut cell_region = Vec::with_capacity(n_cells);
        for (c, r) in &self.tets {
            for &t in c {
                cells.push(map(t)?);
            }
            cell_region.push(*r);
        }
        for (c, r) in &self.hexes {
            for &t in c {
                cells.push(map(t)?);
            }
            cell_region.push(*r);
        }
        let mut tagged_faces: BTreeMap<i32, TaggedFaces> = BTreeMap::new();
        for (f, r) in &self.tris {
            tagged_faces
                .entry(*r)
                .or_default()
                .triangles
                .push([map(f[0])?, map(f[1])?, map(f[2])?]);
        }
        for (f, r) in &self.quads {
            tagged_faces
                .entry(*r)
                .or_default()
                .quads
                .push([map(f[0])?, map(f[1])?, map(f[2])?, map(f[3])?]);
        }
        Ok(Mesh {
            nodes: self.nodes,
            kind,
            cells,
            cell_region,
            tagged_faces,
            group_names: self.names,
        })
    }
}

/// Reads a Gmsh file of format version 1, 2 or 4.1, ASCII or binary.
pub fn read(path: &Path) -> Result<Mesh, MeshError> {
    let bytes = read_bytes(path)?;
    parse(&bytes, path)
}

/// Parses Gmsh bytes (see [`read`]); `path` is only used in messages.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let err = |message: String| MeshError::Parse {
        path: path.to_path_buf(),
        message,
    };
    let start = bytes.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(bytes.len());
    let body = &bytes[start..];
    if body.starts_with(b"$NOD") {
        return parse_v1(body, path)?.into_mesh(path);
    }
    if !body.starts_with(b"$MeshFormat") {
        return Err(err(
            "not a Gmsh file: it does not start with $MeshFormat (or $NOD for version 1)".into()
        ));
    }
    let mut cur = Cursor::new(body);
    cur.line(); // $MeshFormat
    let header = cur.line().ok_or_else(|| err("truncated $MeshFormat section".into()))?;
    let fields: Vec<&str> = header.split_whitespace().collect();
    if fields.len() < 3 {
        return Err(err(format!(
            "malformed $MeshFormat line '{}' (expected 'version file-type data-size')",
            header.chars().take(64).collect::<String>()
        )));
    }
    let version: f64 = fields[0]
        .parse()
        .map_err(|_| err(format!("bad format version '{}'", fields[0].chars().take(16).collect::<String>())))?;
    let binary = match fields[1] {
        "0" => false,
        "1" => true,
        f => {
            return Err(err(format!(
                "bad file type '{}' in $MeshFormat (0: ASCII, 1: binary)",
                f.chars().take(16).collect::<String>()
            )));
        }
    };
    // the data size is sizeof(size_t) of the writer: 4 or 8 (checked here, before any
    // third-party parser sees the file)
    if !matches!(fields[2], "4" | "8") {
        return Err(err(format!(
            "bad data size '{}' in $MeshFormat (4 or 8)",
            fields[2].chars().take(24).collect::<String>()
        )));
    }
    if (2.0..3.0).contains(&version) {
        parse_v2(body, binary, path)?.into_mesh(path)
    } else if (4.1..4.2).contains(&version) {
        parse_v41(body, path)?.into_mesh(path)
    } else {
        Err(err(format!(
            "Gmsh format version {version} is not supported (read: 1, 2.x, 4.1); convert with `gmsh FILE -save -format msh22`"
        )))
    }
}

/// Most tags a binary element may carry (Gmsh writes 2–4: physical, elementary, partitions).
const MAX_TAGS: i32 = 64;

/// A byte cursor that reads text lines and binary words.
struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn new(b: &'a [u8]) -> Self {
        Self { b, pos: 0 }
    }
    /// The 1-based number of the line last read (for messages; counts, so not per line).
    fn line_number(&self) -> usize {
        self.b[..self.pos.min(self.b.len())].iter().filter(|&&c| c == b'\n').count().max(1)
    }

    /// Next line as text, without its line ending; `None` at the end.
    fn line(&mut self) -> Option<&'a str> {
        if self.pos >= self.b.len() {
            return None;
        }
        let rest = &self.b[self.pos..];
        let end = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
        self.pos += (end + 1).min(rest.len());
        let line = &rest[..end];
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        std::str::from_utf8(line).ok().map(str::trim).or(Some("\u{fffd}"))
    }
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.b.get(self.pos..self.pos.checked_add(n)?)?;
        self.pos += n;
        Some(s)
    }
    fn i32(&mut self, swap: bool) -> Option<i32> {
        let a: [u8; 4] = self.take(4)?.try_into().ok()?;
        Some(if swap { i32::from_be_bytes(a) } else { i32::from_le_bytes(a) })
    }
    fn f64(&mut self, swap: bool) -> Option<f64> {
        let a: [u8; 8] = self.take(8)?.try_into().ok()?;
        Some(if swap { f64::from_be_bytes(a) } else { f64::from_le_bytes(a) })
    }
    /// Skips to the line after the next line equal to `marker`.
    fn skip_to(&mut self, marker: &str) -> bool {
        while let Some(l) = self.line() {
            if l == marker {
                return true;
            }
        }
        false
    }
}

fn parse_num<T: std::str::FromStr>(s: Option<&str>, what: &str, section: &str, path: &Path) -> Result<T, MeshError> {
    let s = s.ok_or_else(|| MeshError::Parse {
        path: path.to_path_buf(),
        message: format!("truncated {section} section: missing {what}"),
    })?;
    s.parse().map_err(|_| MeshError::Parse {
        path: path.to_path_buf(),
        message: format!("in {section}: expected {what}, found '{s}'"),
    })
}

fn parse_physical_names(cur: &mut Cursor<'_>, out: &mut BTreeMap<i32, String>, path: &Path) -> Result<(), MeshError> {
    let n: usize = parse_num(cur.line(), "the number of names", "$PhysicalNames", path)?;
    for _ in 0..n {
        let line = cur.line().unwrap_or("");
        let mut it = line.splitn(3, char::is_whitespace);
        let _dim = it.next();
        let tag: i32 = parse_num(it.next(), "a physical tag", "$PhysicalNames", path)?;
        let name = it.next().unwrap_or("").trim().trim_matches('"').to_string();
        out.insert(tag, name);
    }
    Ok(())
}

/// A version 2 `$Nodes` section's count and nodes (ASCII or binary) into `out`, through its
/// `$EndNodes`.
fn v2_nodes(cur: &mut Cursor<'_>, binary: bool, swap: bool, out: &mut Collected, path: &Path) -> Result<(), MeshError> {
    let err = |message: String| MeshError::Parse {
        path: path.to_path_buf(),
        message,
    };
    let n: usize = parse_num(cur.line(), "the number of nodes", "$Nodes", path)?;
    out.node_tags.reserve(n.min(1 << 24));
    out.nodes.reserve(n.min(1 << 24));
    for i in 0..n {
        if binary {
            let (t, x, y, z) = (cur.i32(swap), cur.f64(swap), cur.f64(swap), cur.f64(swap));
            match (t, x, y, z) {
                (Some(t), Some(x), Some(y), Some(z)) => {
                    out.node_tags.push(t as u64);
                    out.nodes.push([x, y, z]);
                }
                _ => return Err(err(format!("truncated $Nodes section: {i} of {n} nodes read"))),
            }
        } else {
            let line = cur
                .line()
                .ok_or_else(|| err(format!("truncated $Nodes section: {i} of {n} nodes read")))?;
            let mut it = line.split_whitespace();
            let t: u64 = parse_num(it.next(), "a node tag", "$Nodes", path)?;
            let x: f64 = parse_num(it.next(), "an x coordinate", "$Nodes", path)?;
            let y: f64 = parse_num(it.next(), "a y coordinate", "$Nodes", path)?;
            let z: f64 = parse_num(it.next(), "a z coordinate", "$Nodes", path)?;
            out.node_tags.push(t);
            out.nodes.push([x, y, z]);
        }
    }
    if binary {
        cur.line();
    }
    if cur.line() != Some("$EndNodes") {
        return Err(err(
            "the $Nodes section does not end with $EndNodes where its node count says".into()
        ));
    }
    Ok(())
}

/// A version 2 `$Elements` section's count and elements (ASCII, or binary blocks of one type)
/// into `out`, through its `$EndElements`.
fn v2_elements(cur: &mut Cursor<'_>, binary: bool, swap: bool, out: &mut Collected, path: &Path) -> Result<(), MeshError> {
    let err = |message: String| MeshError::Parse {
        path: path.to_path_buf(),
        message,
    };
    let n: usize = parse_num(cur.line(), "the number of elements", "$Elements", path)?;
    let mut tags = Vec::new();
    if binary {
        let mut read = 0usize;
        while read < n {
            let (ty, count, ntags) = match (cur.i32(swap), cur.i32(swap), cur.i32(swap)) {
                (Some(a), Some(b), Some(c)) => (a, b, c),
                _ => return Err(err(format!("truncated $Elements section: {read} of {n} elements read"))),
            };
            let nn = nodes_of_type(ty).ok_or_else(|| err(format!("unknown element type {ty} in binary $Elements")))?;
            if count <= 0 || !(0..=MAX_TAGS).contains(&ntags) || read + count as usize > n {
                return Err(err(format!(
                    "corrupt binary element block header (type {ty}, count {count}, tags {ntags})"
                )));
            }
            let mut nodes = vec![0u64; nn];
            for _ in 0..count {
                let _id = cur.i32(swap);
                tags.clear();
                for _ in 0..ntags {
                    tags.push(
                        cur.i32(swap)
                            .ok_or_else(|| err(format!("truncated $Elements section: {read} of {n} elements read")))?,
                    );
                }
                for v in nodes.iter_mut() {
                    *v = cur
                        .i32(swap)
                        .ok_or_else(|| err(format!("truncated $Elements section: {read} of {n} elements read")))?
                        as u64;
                }
                out.push_element(ty, tags.first().copied().unwrap_or(0), &nodes).map_err(err)?;
                read += 1;
            }
        }
        cur.line();
    } else {
        let mut nodes = Vec::new();
        for i in 0..n {
            let line = cur
                .line()
                .ok_or_else(|| err(format!("truncated $Elements section: {i} of {n} elements read")))?;
            let mut it = line.split_whitespace();
            let id: u64 = parse_num(it.next(), "an element id", "$Elements", path)?;
            let ty: i32 = parse_num(it.next(), "an element type", "$Elements", path)?;
            if nodes_of_type(ty).is_none() {
                return Err(err(format!(
                    "line {}: element {id} has type {ty}, which is no Gmsh element type",
                    cur.line_number()
                )));
            }
            let ntags: usize = parse_num(it.next(), "a tag count", "$Elements", path)?;
            tags.clear();
            for _ in 0..ntags {
                tags.push(parse_num::<i32>(it.next(), "an element tag", "$Elements", path)?);
            }
            nodes.clear();
            for v in it {
                nodes.push(parse_num::<u64>(Some(v), "a node tag", "$Elements", path)?);
            }
            if let Some(nn) = nodes_of_type(ty)
                && nodes.len() != nn
            {
                return Err(err(format!("element {i} of type {ty} lists {} nodes, expected {nn}", nodes.len())));
            }
            out.push_element(ty, tags.first().copied().unwrap_or(0), &nodes).map_err(err)?;
        }
    }
    if cur.line() != Some("$EndElements") {
        return Err(err(
            "the $Elements section does not end with $EndElements where its element count says".into(),
        ));
    }
    Ok(())
}

/// Format version 2 (`2.x 0 8` ASCII, `2.x 1 8` binary).
fn parse_v2(bytes: &[u8], binary: bool, path: &Path) -> Result<Collected, MeshError> {
    let err = |message: String| MeshError::Parse {
        path: path.to_path_buf(),
        message,
    };
    let mut cur = Cursor::new(bytes);
    cur.line();
    cur.line();
    let mut swap = false;
    if binary {
        let one = cur.i32(false).ok_or_else(|| err("truncated binary endianness marker".into()))?;
        swap = match one {
            1 => false,
            0x0100_0000 => true,
            v => return Err(err(format!("bad binary endianness marker {v}"))),
        };
        cur.line();
    }
    let mut out = Collected::default();
    let (mut have_nodes, mut have_elements) = (false, false);
    while let Some(l) = cur.line() {
        match l {
            "$PhysicalNames" => parse_physical_names(&mut cur, &mut out.names, path)?,
            "$Nodes" => {
                if have_nodes {
                    return Err(err(format!("line {}: a second $Nodes section (a file has one)", cur.line_number())));
                }
                v2_nodes(&mut cur, binary, swap, &mut out, path)?;
                have_nodes = true;
            }
            "$Elements" => {
                if have_elements {
                    return Err(err(format!(
                        "line {}: a second $Elements section (a file has one)",
                        cur.line_number()
                    )));
                }
                v2_elements(&mut cur, binary, swap, &mut out, path)?;
                have_elements = true;
            }
            s if s.starts_with('$') && !s.starts_with("$End") => {
                let end = format!("$End{}", &s[1..]);
                if !cur.skip_to(&end) {
                    return Err(err(format!("section {s} has no {end}")));
                }
            }
            _ => {}
        }
    }
    if !have_nodes || !have_elements {
        return Err(err("missing $Nodes or $Elements section (truncated file?)".into()));
    }
    Ok(out)
}

/// Format version 1 (`$NOD` … `$ENDNOD`, `$ELM` … `$ENDELM`), ASCII only.
fn parse_v1(bytes: &[u8], path: &Path) -> Result<Collected, MeshError> {
    let err = |message: String| MeshError::Parse {
        path: path.to_path_buf(),
        message,
    };
    let mut cur = Cursor::new(bytes);
    let mut out = Collected::default();
    let (mut have_nodes, mut have_elements) = (false, false);
    while let Some(l) = cur.line() {
        match l {
            "$NOD" => {
                if have_nodes {
                    return Err(err(format!("line {}: a second $NOD section (a file has one)", cur.line_number())));
                }
                let n: usize = parse_num(cur.line(), "the number of nodes", "$NOD", path)?;
                for i in 0..n {
                    let line = cur
                        .line()
                        .ok_or_else(|| err(format!("truncated $NOD section: {i} of {n} nodes read")))?;
                    let mut it = line.split_whitespace();
                    let t: u64 = parse_num(it.next(), "a node number", "$NOD", path)?;
                    let x: f64 = parse_num(it.next(), "an x coordinate", "$NOD", path)?;
                    let y: f64 = parse_num(it.next(), "a y coordinate", "$NOD", path)?;
                    let z: f64 = parse_num(it.next(), "a z coordinate", "$NOD", path)?;
                    out.node_tags.push(t);
                    out.nodes.push([x, y, z]);
                }
                if cur.line() != Some("$ENDNOD") {
                    return Err(err("the $NOD section does not end with $ENDNOD".into()));
                }
                have_nodes = true;
            }
            "$ELM" => {
                if have_elements {
                    return Err(err(format!("line {}: a second $ELM section (a file has one)", cur.line_number())));
                }
                let n: usize = parse_num(cur.line(), "the number of elements", "$ELM", path)?;
                let mut nodes = Vec::new();
                for i in 0..n {
                    let line = cur
                        .line()
                        .ok_or_else(|| err(format!("truncated $ELM section: {i} of {n} elements read")))?;
                    let mut it = line.split_whitespace();
                    let id: u64 = parse_num(it.next(), "an element number", "$ELM", path)?;
                    let ty: i32 = parse_num(it.next(), "an element type", "$ELM", path)?;
                    if nodes_of_type(ty).is_none() {
                        return Err(err(format!(
                            "line {}: element {id} has type {ty}, which is no Gmsh element type",
                            cur.line_number()
                        )));
                    }
                    let phys: i32 = parse_num(it.next(), "a physical region", "$ELM", path)?;
                    let _elem: i32 = parse_num(it.next(), "an elementary region", "$ELM", path)?;
                    let nn: usize = parse_num(it.next(), "a node count", "$ELM", path)?;
                    nodes.clear();
                    for v in it {
                        nodes.push(parse_num::<u64>(Some(v), "a node number", "$ELM", path)?);
                    }
                    if nodes.len() != nn {
                        return Err(err(format!("element {i} lists {} nodes but declares {nn}", nodes.len())));
                    }
                    out.push_element(ty, phys, &nodes).map_err(err)?;
                }
                if cur.line() != Some("$ENDELM") {
                    return Err(err("the $ELM section does not end with $ENDELM".into()));
                }
                have_elements = true;
            }
            _ => {}
        }
    }
    if !have_nodes || !have_elements {
        return Err(err("missing $NOD or $ELM section (truncated file?)".into()));
    }
    Ok(out)
}

/// Format version 4.1, through `mshio`, plus `$PhysicalNames` (text in both encodings).
fn parse_v41(bytes: &[u8], path: &Path) -> Result<Collected, MeshError> {
    let err = |message: String| MeshError::Parse {
        path: path.to_path_buf(),
        message,
    };
    // mshio can panic on hostile input: a malformed file must be an error, never a crash
    let parsed = std::panic::catch_unwind(|| mshio::parse_msh_bytes(bytes).map_err(|_| ()));
    let sections: Vec<&str> = ["$MeshFormat", "$PhysicalNames", "$Entities", "$Nodes", "$Elements"]
        .into_iter()
        .filter(|s| find(bytes, s.as_bytes()).is_some())
        .collect();
    let msh = match parsed {
        Ok(Ok(m)) => m,
        // mshio's own messages name its parser's internals ("Parse error: Complete"), not
        // the file's defect, so they are not passed on
        Ok(Err(_)) => {
            return Err(err(format!(
                "cannot read this Gmsh 4.1 file: a section is malformed or truncated (sections found: {}); check it with `gmsh FILE -check`",
                sections.join(", ")
            )));
        }
        Err(_) => {
            return Err(err(format!(
                "cannot read this Gmsh 4.1 file: its structure is inconsistent (sections found: {})",
                sections.join(", ")
            )));
        }
    };
    let mut out = Collected::default();
    // Physical names: a text section in both ASCII and binary files.
    if let Some(at) = find(bytes, b"$PhysicalNames") {
        let mut cur = Cursor::new(&bytes[at..]);
        cur.line();
        parse_physical_names(&mut cur, &mut out.names, path)?;
    }
    // Entity (dim, tag) → first physical tag.
    let mut phys: HashMap<(i32, i32), i32> = HashMap::new();
    if let Some(ent) = &msh.data.entities {
        for s in &ent.surfaces {
            if let Some(&p) = s.physical_tags.first() {
                phys.insert((2, s.tag), p);
            }
        }
        for v in &ent.volumes {
            if let Some(&p) = v.physical_tags.first() {
                phys.insert((3, v.tag), p);
            }
        }
    }
    let nodes = msh.data.nodes.as_ref().ok_or_else(|| err("no $Nodes section".into()))?;
    let mut next_tag = nodes.min_node_tag;
    for b in &nodes.node_blocks {
        match &b.node_tags {
            Some(map) => {
                let mut pairs: Vec<(u64, usize)> = map.iter().map(|(t, i)| (*t, *i)).collect();
                pairs.sort_by_key(|p| p.1);
                for (t, i) in pairs {
                    let n = &b.nodes[i];
                    out.node_tags.push(t);
                    out.nodes.push([n.x, n.y, n.z]);
                }
            }
            None => {
                // Dense numbering: tags run from min_node_tag in file order.
                for n in &b.nodes {
                    out.node_tags.push(next_tag);
                    out.nodes.push([n.x, n.y, n.z]);
                    next_tag += 1;
                }
            }
        }
    }
    let elements = msh.data.elements.as_ref().ok_or_else(|| err("no $Elements section".into()))?;
    for b in &elements.element_blocks {
        let ty = b.element_type as i32;
        let p = phys.get(&(b.entity_dim, b.entity_tag)).copied().unwrap_or(0);
        for e in &b.elements {
            if let Some(nn) = nodes_of_type(ty)
                && e.nodes.len() < nn
            {
                return Err(err(format!(
                    "element {} of type {ty} has {} nodes, expected {nn}",
                    e.element_tag,
                    e.nodes.len()
                )));
            }
            out.push_element(ty, p, &e.nodes).map_err(err)?;
        }
    }
    Ok(out)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}
