//! A cut made visible: the mesh with each enriched node split into its two sides, so that a
//! viewer (ParaView, the session's frames) draws the opening.
//!
//! Each enriched node gets a copy for its other side; a cell whose centre lies on a node's
//! other side uses the copy. The displacement of a copy is `u_I + s q_I` (the shifted
//! Heaviside `s` of that side). On a cut along cell faces the picture is exact (it is the
//! duplicated-node mesh of the identity check); inside cut cells the discontinuity is drawn
//! on the nearest cell faces.

use std::collections::HashMap;

use super::enrichment::Enrichment;
use super::system::XfemSolution;
use crate::mesh::boundary::{HEX_FACES, TET_FACES};
use crate::mesh::{CellKind, Mesh};

/// The split mesh of a cut, and how to carry fields onto it.
#[derive(Debug, Clone)]
pub struct SplitMesh {
    /// The mesh with the copies appended (node `n + k` is the other side of enriched node k).
    pub mesh: Mesh,
    n: usize,
}

impl SplitMesh {
    /// Splits `mesh` along the enrichment `enr`.
    pub fn new(mesh: &Mesh, enr: &Enrichment) -> Self {
        let n = mesh.n_nodes();
        let npc = mesh.kind.nodes_per_cell();
        let mut nodes = mesh.nodes.clone();
        nodes.extend(enr.nodes.iter().map(|&a| mesh.nodes[a]));
        let mut cells = Vec::with_capacity(mesh.cells.len());
        for c in mesh.cells_iter() {
            let mut centre = [0.0; 3];
            for &a in c {
                for i in 0..3 {
                    centre[i] += mesh.nodes[a][i] / npc as f64;
                }
            }
            cells.extend(c.iter().map(|&a| match enr.index(a) {
                Some(k) if (enr.planes[k].phi(centre) > 0.0) != enr.own_positive[k] => n + k,
                _ => a,
            }));
        }
        let mut split = mesh.clone();
        split.nodes = nodes;
        split.cells = cells;
        Self { mesh: split, n }
    }

    /// The displacement of every node of the split mesh: each node's own, and `u_I + s q_I` for
    /// each copy.
    pub fn displacement(&self, enr: &Enrichment, u: &[f64], q: &[f64]) -> Vec<f64> {
        let mut out = u[..3 * self.n].to_vec();
        for (k, &a) in enr.nodes.iter().enumerate() {
            let s = enr.shifted(k, !enr.own_positive[k]);
            out.extend((0..3).map(|i| u[3 * a + i] + s * q[3 * k + i]));
        }
        out
    }

    /// [`displacement`](Self::displacement) of a full-order solution.
    pub fn of_solution(&self, enr: &Enrichment, sol: &XfemSolution) -> Vec<f64> {
        self.displacement(enr, &sol.u, &sol.q)
    }

    /// A per-node field of the mesh (e.g. reactions) carried to the split mesh: copies take
    /// zero.
    pub fn extend_zero(&self, values: &[f64], components: usize) -> Vec<f64> {
        let mut out = values.to_vec();
        out.resize(self.mesh.nodes.len() * components, 0.0);
        out
    }
}

/// One vertex of a cut's walls: a mesh node on one side of the cut.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WallVertex {
    /// The mesh node.
    pub node: usize,
    /// `None` on the node's own side; on its other side (the copy of enriched node `k` in the
    /// [`SplitMesh`]), `(k, s)` with `s` the shifted Heaviside there: the vertex moves by
    /// `u_I + s q_I`.
    pub copy: Option<(usize, f64)>,
}

/// The walls of a cut, as a viewer draws them: every cell face across which the
/// [`SplitMesh`] separates two cells (the faces of the opening), once for each side, oriented
/// out of its own cell (into the opening), quadrilaterals split in two triangles. On a cut
/// along cell faces the walls are exactly the cut faces; inside cut cells they are the
/// nearest cell faces, as in the split mesh. At the cut's front, where a face is split at
/// some of its nodes only, both walls meet at the unsplit nodes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CutWalls {
    /// The vertices (each a node on one side).
    pub vertices: Vec<WallVertex>,
    /// Triangles as indices into `vertices`.
    pub triangles: Vec<[u32; 3]>,
}

impl CutWalls {
    /// The walls of the enrichment `enr` of `mesh`.
    pub fn new(mesh: &Mesh, enr: &Enrichment) -> Self {
        let split = SplitMesh::new(mesh, enr);
        let n = mesh.n_nodes();
        let npc = mesh.kind.nodes_per_cell();
        let faces: Vec<&[usize]> = match mesh.kind {
            CellKind::Tet4 => TET_FACES.iter().map(|f| &f[..]).collect(),
            CellKind::Hex8 => HEX_FACES.iter().map(|f| &f[..]).collect(),
        };
        // every face of a cell touching an enriched node, by its sorted nodes
        let mut seen: HashMap<Vec<usize>, Vec<usize>> = HashMap::new();
        let mut walls = Self::default();
        let mut vertex_of: HashMap<usize, u32> = HashMap::new();
        for (c, cell) in mesh.cells_iter().enumerate() {
            if cell.iter().all(|&a| enr.index(a).is_none()) {
                continue;
            }
            let split_cell = &split.mesh.cells[c * npc..(c + 1) * npc];
            for f in &faces {
                let face: Vec<usize> = f.iter().map(|&l| split_cell[l]).collect();
                let mut key: Vec<usize> = f.iter().map(|&l| cell[l]).collect();
                key.sort_unstable();
                let Some(other) = seen.remove(&key) else {
                    seen.insert(key, face);
                    continue;
                };
                let (mut a, mut b) = (face.clone(), other.clone());
                a.sort_unstable();
                b.sort_unstable();
                if a == b {
                    continue; // not split: an ordinary inner face
                }
                for side in [&face, &other] {
                    let ids: Vec<u32> = side
                        .iter()
                        .map(|&id| {
                            *vertex_of.entry(id).or_insert_with(|| {
                                walls.vertices.push(if id < n {
                                    WallVertex { node: id, copy: None }
                                } else {
                                    let k = id - n;
                                    WallVertex {
                                        node: enr.nodes[k],
                                        copy: Some((k, enr.shifted(k, !enr.own_positive[k]))),
                                    }
                                });
                                (walls.vertices.len() - 1) as u32
                            })
                        })
                        .collect();
                    for t in 1..ids.len() - 1 {
                        walls.triangles.push([ids[0], ids[t], ids[t + 1]]);
                    }
                }
            }
        }
        walls
    }

    /// Whether the cut has no walls yet.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }
}
