//! Volume meshes of 4-node tetrahedra or 8-node hexahedra, their readers and writers,
//! boundary surfaces, node and face selections, quality measures, and built-in procedural
//! meshes that make the defaults need no files.
//!
//! # Layout
//! - [`Mesh`] (this file): nodes, cells of one kind, per-cell region tags, tagged boundary
//!   patches from the file, and the [`MeshError`] every reader returns.
//! - [`gmsh`]: Gmsh `.msh` v1/v2 (own parser, ASCII and binary) and v4.1 (through `mshio`).
//! - [`vtk`]: VTK `.vtu` and legacy `.vtk` (through `vtkio`), and the `.vtu`/`.pvd` writers.
//! - [`boundary`]: the boundary surface with the cell owning each face.
//! - [`select`]: node and face sets chosen by a [`select::Region`].
//! - [`quality`]: volumes, aspect ratios, inverted and degenerate cells.
//! - [`shape`]: the shape functions of both cell kinds, their gradients and Jacobians (what
//!   the quality measures and every element read).
//! - [`procedural`]: structured blocks (hex and tet) and an organ-like lobe.
//!
//! Node numbering of both cell kinds follows VTK (and Gmsh, which agrees for these two):
//! a tetrahedron `[0,1,2,3]` has positive volume when `(x1−x0)×(x2−x0)·(x3−x0) > 0`; a
//! hexahedron lists its bottom face `0,1,2,3` counter-clockwise seen from the top face
//! `4,5,6,7`, with node `i+4` above node `i`.

pub mod boundary;
pub mod gmsh;
pub mod procedural;
pub mod quality;
pub mod select;
pub mod shape;
pub mod vtk;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The kind of volume cell a mesh is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CellKind {
    /// 4-node linear tetrahedron.
    Tet4,
    /// 8-node trilinear hexahedron.
    Hex8,
}

impl CellKind {
    /// Number of nodes of one cell.
    pub const fn nodes_per_cell(self) -> usize {
        match self {
            CellKind::Tet4 => 4,
            CellKind::Hex8 => 8,
        }
    }

    /// The VTK cell type code (10 for tetrahedra, 12 for hexahedra).
    pub const fn vtk_type(self) -> u8 {
        match self {
            CellKind::Tet4 => 10,
            CellKind::Hex8 => 12,
        }
    }

    /// Human-readable name.
    pub const fn name(self) -> &'static str {
        match self {
            CellKind::Tet4 => "tet4",
            CellKind::Hex8 => "hex8",
        }
    }
}

/// A boundary patch tagged in the mesh file (a Gmsh physical surface): triangles or
/// quadrilaterals given by node indices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TaggedFaces {
    /// Triangles, as node indices.
    pub triangles: Vec<[usize; 3]>,
    /// Quadrilaterals, as node indices.
    pub quads: Vec<[usize; 4]>,
}

/// A volume mesh of a single cell kind.
///
/// Invariants (upheld by every constructor of this crate, checked by [`Mesh::check_structure`]):
/// every cell index is below [`Mesh::n_nodes`], `cells.len() == n_cells · nodes_per_cell`,
/// `cell_region.len() == n_cells`, every coordinate is finite.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Node coordinates (m once the scene's scale is applied).
    pub nodes: Vec<[f64; 3]>,
    /// The kind of every cell.
    pub kind: CellKind,
    /// Cell connectivity, flat: cell `c` is `cells[c·npc .. (c+1)·npc]`.
    pub cells: Vec<usize>,
    /// Region tag of every cell (the Gmsh physical tag; 0 when the file has none).
    pub cell_region: Vec<i32>,
    /// Boundary patches tagged in the file, by physical tag.
    pub tagged_faces: BTreeMap<i32, TaggedFaces>,
    /// Names of physical groups, by tag (from Gmsh `$PhysicalNames`).
    pub group_names: BTreeMap<i32, String>,
}

/// Errors of mesh reading, writing and checking.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("cannot read mesh {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The file extension is not one of the supported formats.
    #[error("{path}: unknown mesh format (expected .msh, .vtu or .vtk); convert it with gmsh or meshio")]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// The file is not a valid mesh of its format.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong, with the line or section where known.
        message: String,
    },
    /// The file holds no supported volume cells.
    #[error("{path}: no tetrahedra or hexahedra found ({found}); vademecum needs a volume mesh")]
    NoVolumeCells {
        /// The file.
        path: PathBuf,
        /// What was found instead.
        found: String,
    },
    /// The file mixes tetrahedra and hexahedra, or holds higher-order volume cells.
    #[error("{path}: {message}")]
    UnsupportedCells {
        /// The file.
        path: PathBuf,
        /// Which cells, and what to do about them.
        message: String,
    },
    /// A cell has non-positive volume (Jacobian determinant ≤ 0 somewhere inside it).
    #[error("{count} inverted cell(s) out of {total} (first: cell {first}, volume {volume:.3e}); fix the node order or the mesh")]
    InvertedCells {
        /// How many cells are inverted.
        count: usize,
        /// Number of cells.
        total: usize,
        /// Index of the first inverted cell.
        first: usize,
        /// Its signed volume.
        volume: f64,
    },
    /// A cell has (near-)zero volume relative to the mesh size.
    #[error("{count} degenerate (zero-volume) cell(s) out of {total} (first: cell {first}); remove or re-mesh them")]
    DegenerateCells {
        /// How many cells are degenerate.
        count: usize,
        /// Number of cells.
        total: usize,
        /// Index of the first one.
        first: usize,
    },
    /// A node index is out of range or a coordinate is not finite.
    #[error("invalid mesh data: {0}")]
    Invalid(String),
}

impl Mesh {
    /// Builds a mesh from nodes and flat connectivity, with every cell in region 0, and checks
    /// the structural invariants (not the cell volumes: see [`Mesh::check_cells`]).
    pub fn new(nodes: Vec<[f64; 3]>, kind: CellKind, cells: Vec<usize>) -> Result<Self, MeshError> {
        let n_cells = cells.len() / kind.nodes_per_cell();
        let mesh = Mesh {
            nodes,
            kind,
            cells,
            cell_region: vec![0; n_cells],
            tagged_faces: BTreeMap::new(),
            group_names: BTreeMap::new(),
        };
        mesh.check_structure()?;
        Ok(mesh)
    }

    /// Removes the nodes no cell uses (a stray vertex would leave three unknowns with no
    /// stiffness: a singular system), renumbering the rest in order; tagged faces that touch a
    /// removed node are dropped with it. Returns how many nodes were removed.
    pub fn drop_unused_nodes(&mut self) -> usize {
        let mut used = vec![false; self.nodes.len()];
        for &n in &self.cells {
            used[n] = true;
        }
        let unused = used.iter().filter(|u| !**u).count();
        if unused == 0 {
            return 0;
        }
        let mut new_index = vec![usize::MAX; self.nodes.len()];
        let mut nodes = Vec::with_capacity(self.nodes.len() - unused);
        for (n, x) in self.nodes.iter().enumerate() {
            if used[n] {
                new_index[n] = nodes.len();
                nodes.push(*x);
            }
        }
        self.nodes = nodes;
        for n in self.cells.iter_mut() {
            *n = new_index[*n];
        }
        for faces in self.tagged_faces.values_mut() {
            faces.triangles.retain(|t| t.iter().all(|&n| used[n]));
            faces.quads.retain(|q| q.iter().all(|&n| used[n]));
            for t in faces.triangles.iter_mut() {
                *t = t.map(|n| new_index[n]);
            }
            for q in faces.quads.iter_mut() {
                *q = q.map(|n| new_index[n]);
            }
        }
        unused
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        self.cell_region.len()
    }

    /// Number of degrees of freedom of a 3D displacement field (3 per node).
    pub fn n_dofs(&self) -> usize {
        3 * self.nodes.len()
    }

    /// The node indices of cell `c`.
    #[inline]
    pub fn cell(&self, c: usize) -> &[usize] {
        let n = self.kind.nodes_per_cell();
        &self.cells[c * n..(c + 1) * n]
    }

    /// Iterates over the cells' node-index slices.
    pub fn cells_iter(&self) -> std::slice::ChunksExact<'_, usize> {
        self.cells.chunks_exact(self.kind.nodes_per_cell())
    }

    /// Copies the coordinates of cell `c`'s nodes into `out` (length = nodes per cell).
    #[inline]
    pub fn cell_coords(&self, c: usize, out: &mut [[f64; 3]]) {
        debug_assert_eq!(out.len(), self.kind.nodes_per_cell());
        for (o, &n) in out.iter_mut().zip(self.cell(c)) {
            *o = self.nodes[n];
        }
    }

    /// Axis-aligned bounding box `(min, max)`; zeros for an empty mesh.
    pub fn bounding_box(&self) -> ([f64; 3], [f64; 3]) {
        if self.nodes.is_empty() {
            return ([0.0; 3], [0.0; 3]);
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.nodes {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }

    /// Length of the bounding-box diagonal (the mesh's length scale).
    pub fn diameter(&self) -> f64 {
        let (lo, hi) = self.bounding_box();
        ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt()
    }

    /// Multiplies every coordinate by `factor` (for example 1e-3 to turn mm into m).
    pub fn scale(&mut self, factor: f64) {
        for p in &mut self.nodes {
            for x in p.iter_mut() {
                *x *= factor;
            }
        }
    }

    /// Translates every node by `offset`.
    pub fn translate(&mut self, offset: [f64; 3]) {
        for p in &mut self.nodes {
            for k in 0..3 {
                p[k] += offset[k];
            }
        }
    }

    /// Looks up a physical group by name or decimal tag.
    pub fn group_tag(&self, name_or_tag: &str) -> Option<i32> {
        if let Some((&t, _)) = self.group_names.iter().find(|(_, n)| n.as_str() == name_or_tag) {
            return Some(t);
        }
        let t: i32 = name_or_tag.parse().ok()?;
        let known = self.cell_region.contains(&t) || self.tagged_faces.contains_key(&t);
        known.then_some(t)
    }

    /// Checks the structural invariants: connectivity length, node indices, finite coordinates.
    pub fn check_structure(&self) -> Result<(), MeshError> {
        let npc = self.kind.nodes_per_cell();
        if !self.cells.len().is_multiple_of(npc) {
            return Err(MeshError::Invalid(format!(
                "connectivity length {} is not a multiple of {npc}",
                self.cells.len()
            )));
        }
        if self.cells.len() / npc != self.cell_region.len() {
            return Err(MeshError::Invalid(format!(
                "{} cells but {} region tags",
                self.cells.len() / npc,
                self.cell_region.len()
            )));
        }
        if let Some((i, &n)) = self.cells.iter().enumerate().find(|(_, n)| **n >= self.nodes.len()) {
            return Err(MeshError::Invalid(format!(
                "cell {} refers to node {n}, but the mesh has {} nodes",
                i / npc,
                self.nodes.len()
            )));
        }
        if let Some(i) = self.nodes.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
            return Err(MeshError::Invalid(format!("node {i} has a non-finite coordinate")));
        }
        Ok(())
    }

    /// Checks every cell's volume: consistently negatively oriented meshes are re-oriented
    /// (a convention difference, not an error); otherwise an inverted or degenerate cell is an
    /// error. Degenerate means a volume below `1e-12` of the mean cell volume.
    pub fn check_cells(&mut self) -> Result<(), MeshError> {
        let vols = quality::signed_volumes(self);
        let total = vols.len();
        if total == 0 {
            return Ok(());
        }
        let mean_abs = vols.iter().map(|v| v.abs()).sum::<f64>() / total as f64;
        let tiny = 1e-12 * mean_abs.max(f64::MIN_POSITIVE);
        let degenerate: Vec<usize> = (0..total).filter(|&c| vols[c].abs() <= tiny).collect();
        if let Some(&first) = degenerate.first() {
            return Err(MeshError::DegenerateCells {
                count: degenerate.len(),
                total,
                first,
            });
        }
        let negative = vols.iter().filter(|v| **v < 0.0).count();
        if negative == total {
            self.flip_orientation();
            return self.check_hex_jacobians();
        }
        if negative > 0 {
            let first = vols.iter().position(|v| *v < 0.0).unwrap_or(0);
            return Err(MeshError::InvertedCells {
                count: negative,
                total,
                first,
                volume: vols[first],
            });
        }
        self.check_hex_jacobians()
    }

    /// Hexahedra can have positive volume yet a negative Jacobian at a corner (a twisted cell).
    fn check_hex_jacobians(&self) -> Result<(), MeshError> {
        if self.kind != CellKind::Hex8 {
            return Ok(());
        }
        let bad: Vec<usize> = (0..self.n_cells())
            .filter(|&c| quality::min_corner_jacobian(self, c) <= 0.0)
            .collect();
        match bad.first() {
            None => Ok(()),
            Some(&first) => Err(MeshError::InvertedCells {
                count: bad.len(),
                total: self.n_cells(),
                first,
                volume: quality::signed_volumes(self)[first],
            }),
        }
    }

    /// Re-orients a mesh whose cells are all negatively oriented (another convention, not an
    /// error); returns whether it did.
    pub fn normalize_orientation(&mut self) -> bool {
        let vols = quality::signed_volumes(self);
        if !vols.is_empty() && vols.iter().all(|v| *v < 0.0) {
            self.flip_orientation();
            true
        } else {
            false
        }
    }

    /// Reverses the orientation of every cell (swaps two nodes of each tetrahedron; swaps the
    /// bottom and top faces of each hexahedron).
    pub fn flip_orientation(&mut self) {
        let npc = self.kind.nodes_per_cell();
        for cell in self.cells.chunks_exact_mut(npc) {
            match self.kind {
                CellKind::Tet4 => cell.swap(1, 2),
                CellKind::Hex8 => {
                    for i in 0..4 {
                        cell.swap(i, i + 4);
                    }
                }
            }
        }
    }
}

/// Reads a volume mesh, choosing the reader by extension (`.msh` → Gmsh, `.vtu`/`.vtk` → VTK),
/// and checks its cells (see [`Mesh::check_cells`]).
pub fn read(path: impl AsRef<Path>) -> Result<Mesh, MeshError> {
    let mut mesh = read_unchecked(path)?;
    mesh.check_cells()?;
    Ok(mesh)
}

/// Reads a volume mesh without checking cell volumes (for quality reports of bad meshes).
pub fn read_unchecked(path: impl AsRef<Path>) -> Result<Mesh, MeshError> {
    let path = path.as_ref();
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let mesh = match ext.as_deref() {
        Some("msh") => gmsh::read(path)?,
        Some("vtu") | Some("vtk") => vtk::read(path)?,
        _ => return Err(MeshError::UnknownFormat { path: path.to_path_buf() }),
    };
    mesh.check_structure()?;
    Ok(mesh)
}

/// Reads a file fully, mapping the error to [`MeshError::Io`].
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, MeshError> {
    crate::files::read_regular(path, crate::files::MAX_MESH_BYTES).map_err(|source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    })
}
