//! VTK input through `vtkio` (XML `.vtu` and legacy `.vtk`, ASCII and binary), and our own
//! `.vtu`/`.pvd` writers so results open in ParaView.
//!
//! Reading keeps the tetrahedra (VTK type 10) or hexahedra (12) of an unstructured grid and
//! ignores lower-dimensional cells (some exporters list boundary triangles beside the volume).
//! Writing produces ASCII `.vtu` with point and cell data; floating-point values are printed
//! in Rust's shortest round-trip form, so a value read back is bit-identical.

use std::fmt::Write as _;
use std::path::Path;

use vtkio::model::{Attribute, DataSet, Piece, VertexNumbers};

use super::{CellKind, Mesh, MeshError};

/// Reads an unstructured grid from `.vtu` or legacy `.vtk`.
pub fn read(path: &Path) -> Result<Mesh, MeshError> {
    let err = |message: String| MeshError::Parse {
        path: path.to_path_buf(),
        message,
    };
    // vtkio reads the whole file; check existence first for a plain I/O error.
    std::fs::metadata(path).map_err(|source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let vtk = import(path)?;
    let pieces = match vtk.data {
        DataSet::UnstructuredGrid { pieces, .. } => pieces,
        other => {
            return Err(err(format!(
                "expected an unstructured grid, found a {} data set",
                data_set_name(&other)
            )));
        }
    };
    let mut nodes = Vec::new();
    let mut tets = Vec::new();
    let mut hexes = Vec::new();
    let mut other = 0usize;
    for piece in pieces {
        let piece = match piece {
            Piece::Inline(p) => *p,
            Piece::Loaded(_) | Piece::Source(..) => return Err(err("parallel (multi-file) VTK data sets are not supported".into())),
        };
        let base = nodes.len();
        let pts: Vec<f64> = piece.points.cast_into().ok_or_else(|| err("points are not numeric".into()))?;
        if !pts.len().is_multiple_of(3) {
            return Err(err(format!("{} point coordinates is not a multiple of 3", pts.len())));
        }
        nodes.extend(pts.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        let n_local = pts.len() / 3;
        let types = &piece.cells.types;
        let mut conn_of_cell = |c: usize, verts: &[u64]| -> Result<(), MeshError> {
            let ty = types
                .get(c)
                .map(|t| *t as u8)
                .ok_or_else(|| err(format!("cell {c} has no cell type")))?;
            let idx = |v: u64| -> Result<usize, MeshError> {
                let v = v as usize;
                if v >= n_local {
                    return Err(err(format!("cell {c} refers to point {v}, but the piece has {n_local} points")));
                }
                Ok(base + v)
            };
            match (ty, verts.len()) {
                (10, 4) => tets.push([idx(verts[0])?, idx(verts[1])?, idx(verts[2])?, idx(verts[3])?]),
                (12, 8) => {
                    let mut h = [0usize; 8];
                    for (k, v) in verts.iter().enumerate() {
                        h[k] = idx(*v)?;
                    }
                    hexes.push(h)
                }
                (10, n) | (12, n) => return Err(err(format!("cell {c} of type {ty} has {n} points"))),
                (t, _) if is_volume(t) => other += 1,
                _ => {}
            }
            Ok(())
        };
        match piece.cells.cell_verts {
            VertexNumbers::Legacy { num_cells, vertices } => {
                let mut at = 0usize;
                for c in 0..num_cells as usize {
                    let n = *vertices.get(at).ok_or_else(|| err(format!("cell list ends before cell {c}")))? as usize;
                    let slice = vertices
                        .get(at + 1..at + 1 + n)
                        .ok_or_else(|| err(format!("cell list ends inside cell {c}")))?;
                    let verts: Vec<u64> = slice.iter().map(|&v| v as u64).collect();
                    conn_of_cell(c, &verts)?;
                    at += 1 + n;
                }
            }
            VertexNumbers::XML { connectivity, offsets } => {
                let offs: &[u64] = if offsets.first() == Some(&0) && offsets.len() == types.len() + 1 {
                    &offsets[1..]
                } else {
                    &offsets
                };
                let mut start = 0u64;
                for (c, &end) in offs.iter().enumerate() {
                    let slice = connectivity
                        .get(start as usize..end as usize)
                        .ok_or_else(|| err(format!("cell {c}'s offsets ({start}..{end}) run past the connectivity array")))?;
                    conn_of_cell(c, slice)?;
                    start = end;
                }
            }
        }
    }
    if other > 0 {
        return Err(MeshError::UnsupportedCells {
            path: path.to_path_buf(),
            message: format!("{other} volume cell(s) other than linear tetrahedra or hexahedra; vademecum reads tet4 and hex8 only"),
        });
    }
    let (kind, cells) = match (tets.is_empty(), hexes.is_empty()) {
        (false, true) => (CellKind::Tet4, tets.concat()),
        (true, false) => (CellKind::Hex8, hexes.concat()),
        (false, false) => {
            return Err(MeshError::UnsupportedCells {
                path: path.to_path_buf(),
                message: format!(
                    "the mesh mixes {} tetrahedra and {} hexahedra; vademecum needs one cell kind per mesh",
                    tets.len(),
                    hexes.len()
                ),
            });
        }
        (true, true) => {
            return Err(MeshError::NoVolumeCells {
                path: path.to_path_buf(),
                found: format!("{} points and no tetrahedra or hexahedra", nodes.len()),
            });
        }
    };
    Mesh::new(nodes, kind, cells)
}

/// Reads a named point-data array (for example `displacement`) from a `.vtu` or `.vtk` file,
/// as a flat `f64` vector.
pub fn read_point_data(path: &Path, name: &str) -> Result<Option<Vec<f64>>, MeshError> {
    read_attribute(path, name, true)
}

/// Reads a named cell-data array from a `.vtu` or `.vtk` file, as a flat `f64` vector.
pub fn read_cell_data(path: &Path, name: &str) -> Result<Option<Vec<f64>>, MeshError> {
    read_attribute(path, name, false)
}

fn read_attribute(path: &Path, name: &str, point: bool) -> Result<Option<Vec<f64>>, MeshError> {
    let vtk = import(path)?;
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        return Ok(None);
    };
    for piece in pieces {
        let Piece::Inline(p) = piece else { continue };
        let attrs = if point { &p.data.point } else { &p.data.cell };
        for a in attrs {
            if let Attribute::DataArray(d) = a
                && d.name == name
            {
                return Ok(d.data.cast_into());
            }
        }
    }
    Ok(None)
}

/// A message a user understands for a `vtkio` error (whose text names the reader's internals,
/// e.g. `Parse error: Complete` or `DataArraySizeMismatch { … }`), with its gist clipped.
fn explain_vtkio(text: &str) -> String {
    let what = if text.contains("SizeMismatch") {
        "a data array holds another number of values than its header declares"
    } else if text.contains("Parse") || text.contains("parse") || text.contains("Complete") || text.contains("Incomplete") {
        "the file is malformed or truncated"
    } else if text.contains("Unsupported") || text.contains("unsupported") {
        "it uses a VTK feature this reader does not support"
    } else if text.contains("IO") || text.contains("Io") {
        "it could not be read"
    } else {
        "the VTK reader rejected it"
    };
    let gist: String = text.split_whitespace().collect::<Vec<_>>().join(" ").chars().take(120).collect();
    format!("invalid VTK file: {what} (reader detail: {gist})")
}

fn import(path: &Path) -> Result<vtkio::Vtk, MeshError> {
    crate::files::check_regular(path, crate::files::MAX_MESH_BYTES).map_err(|source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    // vtkio panics on a few malformed inputs; a malformed file must be an error, never a crash.
    let p = path.to_path_buf();
    let result = std::panic::catch_unwind(move || vtkio::Vtk::import(&p));
    match result {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(MeshError::Parse {
            path: path.to_path_buf(),
            message: explain_vtkio(&e.to_string()),
        }),
        Err(_) => Err(MeshError::Parse {
            path: path.to_path_buf(),
            message: "invalid VTK file (the VTK reader rejected its structure)".into(),
        }),
    }
}

fn is_volume(t: u8) -> bool {
    matches!(t, 10..=15 | 24..=27 | 29 | 32 | 33 | 42 | 71..=75)
}

fn data_set_name(d: &DataSet) -> &'static str {
    match d {
        DataSet::ImageData { .. } => "image",
        DataSet::StructuredGrid { .. } => "structured grid",
        DataSet::RectilinearGrid { .. } => "rectilinear grid",
        DataSet::UnstructuredGrid { .. } => "unstructured grid",
        DataSet::PolyData { .. } => "poly data (surface)",
        DataSet::Field { .. } => "field",
    }
}

/// A named array written beside the mesh: `components` values per point (or per cell).
#[derive(Debug, Clone, Copy)]
pub struct Field<'a> {
    /// Array name shown in ParaView.
    pub name: &'a str,
    /// Values per point or cell (1 for a scalar, 3 for a vector).
    pub components: usize,
    /// The values, flat, `components` per entity.
    pub values: &'a [f64],
}

/// Writes `mesh` as an ASCII `.vtu` with point and cell data. The cell region tag is always
/// written as the integer cell array `region`.
///
/// # Errors
/// [`MeshError::Invalid`] if a field's length does not match the mesh, [`MeshError::Io`] if
/// the file cannot be written.
pub fn write_vtu(path: &Path, mesh: &Mesh, point_data: &[Field<'_>], cell_data: &[Field<'_>]) -> Result<(), MeshError> {
    let regions: Vec<f64> = mesh.cell_region.iter().map(|&r| r as f64).collect();
    write_unstructured(
        path,
        &mesh.nodes,
        &mesh.cells,
        mesh.kind.nodes_per_cell(),
        mesh.kind.vtk_type(),
        Some(&regions),
        point_data,
        cell_data,
    )
}

/// Writes a triangulated surface as an ASCII `.vtu` (VTK triangles) with point and cell
/// (per triangle) data: `positions` (m) and `triangles` (3 node indices each).
pub fn write_surface_vtu(
    path: &Path,
    positions: &[[f64; 3]],
    triangles: &[usize],
    point_data: &[Field<'_>],
    cell_data: &[Field<'_>],
) -> Result<(), MeshError> {
    if !triangles.len().is_multiple_of(3) || triangles.iter().any(|&n| n >= positions.len()) {
        return Err(MeshError::Invalid("surface triangles must be triples of valid node indices".into()));
    }
    write_unstructured(path, positions, triangles, 3, 5, None, point_data, cell_data)
}

/// Writes a cloud of points as an ASCII `.vtu` (one VTK vertex per point) with point data —
/// e.g. a meshless solver's nodes, which a mesh cannot show once a cut has split them.
pub fn write_points_vtu(path: &Path, positions: &[[f64; 3]], point_data: &[Field<'_>]) -> Result<(), MeshError> {
    let cells: Vec<usize> = (0..positions.len()).collect();
    write_unstructured(path, positions, &cells, 1, 1, None, point_data, &[])
}

/// The `.vtu` writer behind [`write_vtu`], [`write_surface_vtu`] and [`write_points_vtu`]: cells of one type with
/// `npc` nodes each, flat in `cells`; `regions` (integers) becomes the `region` cell array.
#[allow(clippy::too_many_arguments)]
fn write_unstructured(
    path: &Path,
    nodes: &[[f64; 3]],
    cells: &[usize],
    npc: usize,
    vtk_type: u8,
    regions: Option<&[f64]>,
    point_data: &[Field<'_>],
    cell_data: &[Field<'_>],
) -> Result<(), MeshError> {
    let n_cells = cells.len() / npc.max(1);
    for (f, count, what) in point_data
        .iter()
        .map(|f| (f, nodes.len(), "point"))
        .chain(cell_data.iter().map(|f| (f, n_cells, "cell")))
    {
        if f.values.len() != f.components * count {
            return Err(MeshError::Invalid(format!(
                "{what} field '{}' has {} values, expected {}",
                f.name,
                f.values.len(),
                f.components * count
            )));
        }
    }
    let mut s = String::with_capacity(64 * (nodes.len() + n_cells));
    s.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n");
    let _ = writeln!(s, "<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">", nodes.len(), n_cells);
    s.push_str("<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n");
    for p in nodes {
        let _ = writeln!(s, "{:?} {:?} {:?}", p[0], p[1], p[2]);
    }
    s.push_str("</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for c in cells.chunks_exact(npc.max(1)) {
        let line: Vec<String> = c.iter().map(|n| n.to_string()).collect();
        s.push_str(&line.join(" "));
        s.push('\n');
    }
    s.push_str("</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    for c in 0..n_cells {
        let _ = write!(s, "{} ", (c + 1) * npc);
    }
    s.push_str("\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
    for _ in 0..n_cells {
        let _ = write!(s, "{vtk_type} ");
    }
    s.push_str("\n</DataArray>\n</Cells>\n<PointData>\n");
    for f in point_data {
        write_array(&mut s, f);
    }
    s.push_str("</PointData>\n<CellData>\n");
    if let Some(r) = regions {
        s.push_str("<DataArray type=\"Int32\" Name=\"region\" format=\"ascii\">\n");
        for x in r {
            let _ = write!(s, "{} ", *x as i64);
        }
        s.push_str("\n</DataArray>\n");
    }
    for f in cell_data {
        write_array(&mut s, f);
    }
    s.push_str("</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
    std::fs::write(path, s).map_err(|source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn write_array(s: &mut String, f: &Field<'_>) {
    let _ = writeln!(
        s,
        "<DataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{}\" format=\"ascii\">",
        xml_escape(f.name),
        f.components
    );
    for chunk in f.values.chunks(f.components.max(1)) {
        let line: Vec<String> = chunk.iter().map(|v| format!("{v:?}")).collect();
        s.push_str(&line.join(" "));
        s.push('\n');
    }
    s.push_str("</DataArray>\n");
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Writes a ParaView `.pvd` collection: one `(time, file)` entry per step, file paths
/// relative to the `.pvd`.
pub fn write_pvd(path: &Path, steps: &[(f64, String)]) -> Result<(), MeshError> {
    let mut s =
        String::from("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"1.0\" byte_order=\"LittleEndian\">\n<Collection>\n");
    for (t, file) in steps {
        let _ = writeln!(
            s,
            "<DataSet timestep=\"{t:?}\" group=\"\" part=\"0\" file=\"{}\"/>",
            xml_escape(file)
        );
    }
    s.push_str("</Collection>\n</VTKFile>\n");
    std::fs::write(path, s).map_err(|source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    })
}
