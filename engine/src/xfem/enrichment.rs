//! Which nodes a cut enriches, and with which plane.
//!
//! # From the blade to cut cells (seed 000 §3.4)
//! The blade sweeps a triangulated surface ([`Cut::swept`], shared with the meshless solver).
//! A cell is *cut* once the surface has crossed it entirely: the plane of the facet nearest to
//! the cell's centre separates the cell's nodes (some on each side, or a whole face on the plane)
//! and every point where that plane meets the cell's edges lies on the swept surface, to within
//! [`XfemParams::coverage`] of the cell's size. A cut therefore ends on cell boundaries, as in the
//! seed: no cut shorter than a cell.
//!
//! # Cracked nodes (§3.2.2)
//! A node of a cut cell is *cracked*: it carries a Heaviside enrichment whose discontinuity
//! is one plane — the plane of its nearest cut cell's facet — across the node's whole support
//! (the cells around it). Because the node's shape function vanishes on the boundary of its
//! support, the enriched function is continuous everywhere but on that plane, whatever the
//! neighbouring cells do: the cracking-node construction (Song & Belytschko 2009, Fig. 3.2 of
//! the seed), in which an arbitrary blade path is represented by one plane per cracked node at
//! its own angle θ. With [`XfemParams::node_centred`], each plane is moved to pass through its
//! node (the seed's node-centred cuts); then only nodes on the positive side of their plane are
//! cracked, so that one layer of planes represents the cut, not two.
//!
//! # Where the cut ends: the crack front ([`Front`])
//! A node's plane opens its whole support, so a node on the crack front — the edge of the cut
//! inside the tissue — would open the cells *ahead* of the blade as well: the opening would run
//! one ring of cells past where the blade stopped. With [`Front::Shared`] a node is cracked
//! only where its plane crosses no cell of its support that the cut has not crossed: the front
//! nodes stay shared by both sides, as in a split-node model (seed 003 §3.5), and a cut on cell
//! faces ends exactly where the blade did. [`Front::Cracked`] cracks every node of a cut cell
//! (seed 000 §3.4's rule), kept for comparison with the seeds' published results.
//!
//! # The sliver rule (conditioning)
//! When one side of a node's support is a tiny fraction of the support's volume, the enriched
//! function is nearly zero or nearly the negative of the node's own shape function, and the
//! stiffness becomes ill-conditioned (its condition number grows like the inverse of that
//! fraction). A node whose smaller side is below [`XfemParams::sliver`] (10⁻⁴ by default; the
//! volume-fraction rule of Daux et al. 2000 and Béchet et al. 2005) is not enriched: the sliver
//! stays attached to the other side. The dropped nodes are reported.

use super::subcell::{self, Plane};
use crate::geometry::cut::Cut;
use crate::mesh::{CellKind, Mesh, quality};

/// What a scene does with a piece of tissue the cuts have detached from every support.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Detached {
    /// Hold it in place with a soft elastic foundation (stiffness `E·h` per node), so it stays
    /// where it was cut and carries its own loads; reported.
    #[default]
    Hold,
    /// Remove it: its loads are dropped, it is held like [`Detached::Hold`] so the system stays
    /// regular, and it is flagged so viewers do not draw it.
    Remove,
}

/// Which nodes of the cut cells at the edge of a cut are cracked (module docs, "Where the cut
/// ends"); a scene's `fidelity.xfem.front`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Front {
    /// Every node of a cut cell, those on the crack front included (seed 000 §3.4): the
    /// opening reaches one ring of cells past the cut.
    #[default]
    Cracked,
    /// Only nodes whose plane crosses no uncut cell of their support: the crack front's nodes
    /// stay shared and the cut ends where the blade stopped (split-node, seed 003 §3.5).
    Shared,
}

/// Parameters of the XFEM discretisation of cuts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct XfemParams {
    /// The sliver rule's threshold: a node whose support has less than this fraction of its
    /// volume on one side of its plane is not enriched.
    pub sliver: f64,
    /// How far (as a fraction of the cell's size) a cell's cross-section may extend beyond the
    /// swept surface and the cell still count as cut.
    pub coverage: f64,
    /// Move each node's plane to pass through the node (the seed's node-centred cuts).
    pub node_centred: bool,
    /// What to do with detached pieces.
    pub detached: Detached,
    /// Whether the crack front's nodes are cracked or stay shared.
    pub front: Front,
}

impl Default for XfemParams {
    fn default() -> Self {
        Self {
            sliver: 1e-4,
            coverage: 0.05,
            node_centred: false,
            detached: Detached::Hold,
            front: Front::Cracked,
        }
    }
}

/// Why a cut could not be turned into an enrichment.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EnrichmentError {
    /// The cut is two-dimensional.
    #[error("a cut through a volume mesh must be a 3D swept surface (got a {0}D cut)")]
    Dimension(usize),
    /// A cut cell index is out of range.
    #[error("cut cell {cell} is not in the mesh ({cells} cells)")]
    NoSuchCell {
        /// The cell.
        cell: usize,
        /// Cells in the mesh.
        cells: usize,
    },
    /// A plane's normal is not a finite unit vector.
    #[error("the plane of cut cell {cell} has no valid normal")]
    BadPlane {
        /// The cell.
        cell: usize,
    },
}

/// A node not enriched because of the sliver rule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DroppedNode {
    /// The node.
    pub node: usize,
    /// The smaller side's fraction of its support's volume.
    pub fraction: f64,
}

/// The enriched nodes of a cut, each with its plane.
#[derive(Debug, Clone, PartialEq)]
pub struct Enrichment {
    /// Cells the cut has crossed entirely, each with the plane that crossed it.
    pub cut_cells: Vec<(usize, Plane)>,
    /// Enriched nodes, in the order they were enriched (increasing within one cut).
    pub nodes: Vec<usize>,
    /// The plane of each enriched node.
    pub planes: Vec<Plane>,
    /// Whether each enriched node lies on the positive side of its plane (`H(φ_I(x_I))`; a node
    /// on its plane counts as negative).
    pub own_positive: Vec<bool>,
    /// Nodes left out by the sliver rule.
    pub dropped: Vec<DroppedNode>,
    /// Nodes of cut cells left shared because they lie on the crack front ([`Front::Shared`]),
    /// in increasing order.
    pub front: Vec<usize>,
    index: Vec<u32>,
}

const NONE: u32 = u32::MAX;

/// For every node, the cells containing it.
pub fn node_cells(mesh: &Mesh) -> Vec<Vec<usize>> {
    let mut out = vec![Vec::new(); mesh.n_nodes()];
    for (c, cell) in mesh.cells_iter().enumerate() {
        for &a in cell {
            out[a].push(c);
        }
    }
    out
}

impl Enrichment {
    /// No cut: nothing enriched.
    pub fn none(mesh: &Mesh) -> Self {
        Self {
            cut_cells: Vec::new(),
            nodes: Vec::new(),
            planes: Vec::new(),
            own_positive: Vec::new(),
            dropped: Vec::new(),
            front: Vec::new(),
            index: vec![NONE; mesh.n_nodes()],
        }
    }

    /// The cells a swept cut has crossed entirely (module docs), each with its facet's plane.
    pub fn cut_cells(mesh: &Mesh, cut: &Cut, params: &XfemParams) -> Result<Vec<(usize, Plane)>, EnrichmentError> {
        Self::cut_cells_among(mesh, cut, params, 0..mesh.n_cells())
    }

    /// [`cut_cells`](Self::cut_cells) among the cells `candidates` only (those near the part
    /// of the cut that just grew).
    pub fn cut_cells_among(
        mesh: &Mesh,
        cut: &Cut,
        params: &XfemParams,
        candidates: impl IntoIterator<Item = usize>,
    ) -> Result<Vec<(usize, Plane)>, EnrichmentError> {
        if cut.dim() != 3 {
            return Err(EnrichmentError::Dimension(cut.dim()));
        }
        let n = mesh.kind.nodes_per_cell();
        let mut x = vec![[0.0; 3]; n];
        let mut out = Vec::new();
        for c in candidates {
            mesh.cell_coords(c, &mut x);
            let h = subcell::cell_size(&x);
            let centre = x.iter().fold([0.0; 3], |s, p| {
                [s[0] + p[0] / n as f64, s[1] + p[1] / n as f64, s[2] + p[2] / n as f64]
            });
            let Some(facet) = cut
                .facets()
                .iter()
                .map(|f| (f.distance(centre), f))
                .filter(|(d, _)| *d <= h)
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map(|(_, f)| f)
            else {
                continue;
            };
            let plane = Plane {
                point: facet.vertices[0],
                normal: facet.normal,
            };
            if crossed(mesh.kind, &x, &plane, h, |p| cut.distance(p) <= params.coverage * h) {
                out.push((c, plane));
            }
        }
        Ok(out)
    }

    /// Every cell an unbounded `plane` crosses entirely (nodes on both sides, or a face on the
    /// plane), each with the plane: the cut cells of a cut through the whole organ.
    pub fn cells_crossed_by(mesh: &Mesh, plane: &Plane) -> Vec<(usize, Plane)> {
        let n = mesh.kind.nodes_per_cell();
        let mut x = vec![[0.0; 3]; n];
        (0..mesh.n_cells())
            .filter(|&c| {
                mesh.cell_coords(c, &mut x);
                crossed(mesh.kind, &x, plane, subcell::cell_size(&x), |_| true)
            })
            .map(|c| (c, *plane))
            .collect()
    }

    /// The enrichment of a swept cut.
    pub fn from_cut(mesh: &Mesh, cut: &Cut, params: &XfemParams) -> Result<Self, EnrichmentError> {
        let cells = Self::cut_cells(mesh, cut, params)?;
        Self::from_cut_cells(mesh, &cells, params)
    }

    /// The enrichment of a set of cut cells, each with the plane crossing it (module docs).
    pub fn from_cut_cells(mesh: &Mesh, cut_cells: &[(usize, Plane)], params: &XfemParams) -> Result<Self, EnrichmentError> {
        let n = mesh.kind.nodes_per_cell();
        let mut x = vec![[0.0; 3]; n];
        // each node takes the plane of its cut cell nearest to it
        let mut best: Vec<Option<(f64, Plane)>> = vec![None; mesh.n_nodes()];
        for &(c, plane) in cut_cells {
            if c >= mesh.n_cells() {
                return Err(EnrichmentError::NoSuchCell {
                    cell: c,
                    cells: mesh.n_cells(),
                });
            }
            let len = plane.normal.iter().map(|v| v * v).sum::<f64>().sqrt();
            if !(len - 1.0).abs().lt(&1e-6) || !plane.point.iter().all(|v| v.is_finite()) {
                return Err(EnrichmentError::BadPlane { cell: c });
            }
            for &a in mesh.cell(c) {
                let d = plane.phi(mesh.nodes[a]).abs();
                if best[a].is_none_or(|(b, _)| d < b) {
                    best[a] = Some((d, plane));
                }
            }
        }
        let around = node_cells(mesh);
        let mut is_cut = vec![false; mesh.n_cells()];
        for &(c, _) in cut_cells {
            is_cut[c] = true;
        }
        let mut out = Self::none(mesh);
        out.cut_cells = cut_cells.to_vec();
        for (a, b) in best.iter().enumerate() {
            let Some((_, plane)) = *b else { continue };
            let plane = if params.node_centred { plane.through(mesh.nodes[a]) } else { plane };
            let mut h: f64 = 0.0;
            let mut vols = [0.0; 2];
            // whether the plane opens a cell of the support the cut has not crossed
            let mut on_front = false;
            for &c in &around[a] {
                mesh.cell_coords(c, &mut x);
                let hc = subcell::cell_size(&x);
                h = h.max(hc);
                let [p, m] = subcell::side_volumes(mesh.kind, &x, &plane);
                vols[0] += p;
                vols[1] += m;
                on_front |= params.front == Front::Shared && !is_cut[c] && crossed(mesh.kind, &x, &plane, hc, |_| true);
            }
            let own_positive = subcell::snapped_phi(&plane, mesh.nodes[a], h) > 0.0;
            let fraction = vols[0].min(vols[1]) / (vols[0] + vols[1]);
            if fraction < params.sliver {
                out.dropped.push(DroppedNode { node: a, fraction });
                continue;
            }
            if on_front {
                out.front.push(a);
                continue;
            }
            out.index[a] = out.nodes.len() as u32;
            out.nodes.push(a);
            out.planes.push(plane);
            out.own_positive.push(own_positive);
        }
        if params.node_centred {
            out.keep_one_layer(mesh, cut_cells);
        }
        Ok(out)
    }

    /// This enrichment with the cells `new_cells` cut as well, for a cut that progresses: the
    /// nodes already enriched keep their planes and their places, and the nodes of the new cut
    /// cells not enriched yet are appended (after the sliver rule) — so the enriched degrees of
    /// freedom of an online model only ever grow at the end.
    ///
    /// With [`Front::Shared`] the nodes are judged against every cut cell, old and new: a node
    /// that was on the front is cracked once the cells ahead of it are cut.
    pub fn extended(&self, mesh: &Mesh, new_cells: &[(usize, Plane)], params: &XfemParams) -> Result<Self, EnrichmentError> {
        let fresh = match params.front {
            Front::Cracked => Self::from_cut_cells(mesh, new_cells, params)?,
            Front::Shared => Self::from_cut_cells(mesh, &[&self.cut_cells[..], new_cells].concat(), params)?,
        };
        let mut out = self.clone();
        out.cut_cells.extend_from_slice(new_cells);
        out.front = fresh.front.iter().copied().filter(|&a| out.index(a).is_none()).collect();
        for (k, &a) in fresh.nodes.iter().enumerate() {
            if out.index(a).is_none() {
                out.index[a] = out.nodes.len() as u32;
                out.nodes.push(a);
                out.planes.push(fresh.planes[k]);
                out.own_positive.push(fresh.own_positive[k]);
            }
        }
        let dropped: Vec<DroppedNode> = fresh.dropped.iter().filter(|d| out.index(d.node).is_none()).copied().collect();
        match params.front {
            Front::Cracked => out.dropped.extend(dropped),
            // judged against every cut cell: the fresh list is the whole list
            Front::Shared => out.dropped = dropped,
        }
        Ok(out)
    }

    /// Node-centred planes: in each cut cell keep the cracked nodes on the positive side of
    /// the cell's plane (or on it), so that parallel planes through both layers of nodes do
    /// not cut a slab loose.
    fn keep_one_layer(&mut self, mesh: &Mesh, cut_cells: &[(usize, Plane)]) {
        let mut keep = vec![false; mesh.n_nodes()];
        for &(c, plane) in cut_cells {
            for &a in mesh.cell(c) {
                if plane.phi(mesh.nodes[a]) >= 0.0 {
                    keep[a] = true;
                }
            }
        }
        let old = std::mem::replace(self, Self::none(mesh));
        self.cut_cells = old.cut_cells;
        self.dropped = old.dropped;
        self.front = old.front;
        for (k, &a) in old.nodes.iter().enumerate() {
            if keep[a] {
                self.index[a] = self.nodes.len() as u32;
                self.nodes.push(a);
                self.planes.push(old.planes[k]);
                self.own_positive.push(false);
            }
        }
    }

    /// The enriched index of `node`, if it is enriched.
    #[inline]
    pub fn index(&self, node: usize) -> Option<usize> {
        let k = self.index[node];
        (k != NONE).then_some(k as usize)
    }

    /// Number of enriched nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether nothing is enriched.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The shifted Heaviside of enriched node `k` on the side `positive` of its plane:
    /// `H(φ) − H(φ(x_I))`, in {−1, 0, 1} (seed 003 Eq. 4–6).
    #[inline]
    pub fn shifted(&self, k: usize, positive: bool) -> f64 {
        f64::from(u8::from(positive)) - f64::from(u8::from(self.own_positive[k]))
    }
}

/// Whether `plane` crosses the cell entirely: the nodes are on both sides (or a face lies on
/// the plane) and every crossing point of the cell's edges satisfies `covered`.
fn crossed(kind: CellKind, x: &[[f64; 3]], plane: &Plane, h: f64, covered: impl Fn([f64; 3]) -> bool) -> bool {
    let phi: Vec<f64> = x.iter().map(|p| subcell::snapped_phi(plane, *p, h)).collect();
    let (pos, neg, zero) = phi.iter().fold((0, 0, 0), |(p, n, z), v| {
        if *v > 0.0 {
            (p + 1, n, z)
        } else if *v < 0.0 {
            (p, n + 1, z)
        } else {
            (p, n, z + 1)
        }
    });
    let face = if kind == CellKind::Tet4 { 3 } else { 4 };
    if !((pos > 0 && neg > 0) || zero >= face) {
        return false;
    }
    let zeros_covered = x.iter().zip(&phi).filter(|(_, v)| **v == 0.0).all(|(p, _)| covered(*p));
    zeros_covered
        && quality::edges(kind).iter().all(|&(a, b)| {
            if phi[a] * phi[b] >= 0.0 {
                return true;
            }
            let t = phi[a] / (phi[a] - phi[b]);
            let p = [
                x[a][0] + t * (x[b][0] - x[a][0]),
                x[a][1] + t * (x[b][1] - x[a][1]),
                x[a][2] + t * (x[b][2] - x[a][2]),
            ];
            covered(p)
        })
}
