//! The boundary surface of a volume mesh: every cell face that belongs to exactly one cell,
//! oriented outward, with the cell that owns it.

use std::collections::HashMap;

use super::{CellKind, Mesh};

/// Local faces of a positively oriented tetrahedron, outward normals by the right-hand rule.
pub const TET_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
/// Local faces of a positively oriented hexahedron (VTK order), outward normals.
pub const HEX_FACES: [[usize; 4]; 6] = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]];

/// One boundary face.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoundaryFace {
    /// The cell owning the face.
    pub cell: usize,
    /// The face's index among the cell's local faces ([`TET_FACES`] or [`HEX_FACES`]).
    pub local: u8,
    /// Node indices, outward orientation; only the first [`BoundaryFace::len`] are used.
    pub nodes: [usize; 4],
    /// 3 for a triangle, 4 for a quadrilateral.
    pub len: u8,
}

impl BoundaryFace {
    /// The face's node indices.
    pub fn node_slice(&self) -> &[usize] {
        &self.nodes[..self.len as usize]
    }
}

/// The boundary surface of a mesh.
#[derive(Debug, Clone, Default)]
pub struct Boundary {
    /// Boundary faces, in cell order.
    pub faces: Vec<BoundaryFace>,
}

impl Boundary {
    /// Extracts the faces that belong to exactly one cell.
    pub fn of(mesh: &Mesh) -> Self {
        let mut count: HashMap<[usize; 4], (u32, usize, u8)> = HashMap::with_capacity(mesh.n_cells() * 2);
        let mut push = |key: [usize; 4], cell: usize, local: u8| {
            count.entry(key).and_modify(|e| e.0 += 1).or_insert((1, cell, local));
        };
        for (c, cell) in mesh.cells_iter().enumerate() {
            match mesh.kind {
                CellKind::Tet4 => {
                    for (l, f) in TET_FACES.iter().enumerate() {
                        let mut k = [cell[f[0]], cell[f[1]], cell[f[2]], usize::MAX];
                        k.sort_unstable();
                        push(k, c, l as u8);
                    }
                }
                CellKind::Hex8 => {
                    for (l, f) in HEX_FACES.iter().enumerate() {
                        let mut k = [cell[f[0]], cell[f[1]], cell[f[2]], cell[f[3]]];
                        k.sort_unstable();
                        push(k, c, l as u8);
                    }
                }
            }
        }
        let mut faces: Vec<BoundaryFace> = count
            .into_values()
            .filter(|(n, _, _)| *n == 1)
            .map(|(_, cell, local)| {
                let nodes_of = mesh.cell(cell);
                match mesh.kind {
                    CellKind::Tet4 => {
                        let f = TET_FACES[local as usize];
                        BoundaryFace {
                            cell,
                            local,
                            nodes: [nodes_of[f[0]], nodes_of[f[1]], nodes_of[f[2]], usize::MAX],
                            len: 3,
                        }
                    }
                    CellKind::Hex8 => {
                        let f = HEX_FACES[local as usize];
                        BoundaryFace {
                            cell,
                            local,
                            nodes: [nodes_of[f[0]], nodes_of[f[1]], nodes_of[f[2]], nodes_of[f[3]]],
                            len: 4,
                        }
                    }
                }
            })
            .collect();
        faces.sort_unstable_by_key(|f| (f.cell, f.local));
        Boundary { faces }
    }

    /// Sorted, unique node indices on the boundary.
    pub fn nodes(&self) -> Vec<usize> {
        let mut v: Vec<usize> = self.faces.iter().flat_map(|f| f.node_slice().iter().copied()).collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The surface as triangles (quadrilaterals split along their 0–2 diagonal).
    pub fn triangles(&self) -> Vec<[usize; 3]> {
        let mut out = Vec::with_capacity(self.faces.len() * 2);
        for f in &self.faces {
            let n = f.nodes;
            out.push([n[0], n[1], n[2]]);
            if f.len == 4 {
                out.push([n[0], n[2], n[3]]);
            }
        }
        out
    }

    /// Total area of the boundary (m²).
    pub fn area(&self, mesh: &Mesh) -> f64 {
        self.triangles().iter().map(|t| triangle_area_normal(mesh, *t).0).sum()
    }
}

/// Area and unit normal of a triangle given by node indices.
pub fn triangle_area_normal(mesh: &Mesh, t: [usize; 3]) -> (f64, [f64; 3]) {
    let (a, b, c) = (mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]]);
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len == 0.0 {
        return (0.0, [0.0; 3]);
    }
    (0.5 * len, [n[0] / len, n[1] / len, n[2] / len])
}
