//! What a viewer draws of a cut at one revision ([`CutPicture`]): made by the cut thread,
//! read by the frame thread and by the co-rotational deformation, which is why it sits apart
//! from both the cutting effect and the deformation.

use std::sync::Arc;

use super::Contact;
use crate::mesh::Mesh;
use crate::xfem::reduced::{CutView, ReducedCut};
use crate::xfem::view::CutWalls;

/// The cut as a viewer draws it at one revision: the reduced model then, and the walls of the
/// opening ([`CutWalls`]). Given the contact of a tick, the displacement of the cut organ is
/// the vademecum's (the uncut tissue's) plus what the cut adds
/// ([`CutView::added_response`]): `W q` on every node's own side, and the opening `s q` on
/// the other side of a cracked node — so the two walls of the incision part.
#[derive(Debug, Clone)]
pub struct CutPicture {
    /// The organ cut (its index in the scene).
    pub organ: usize,
    /// 1 for the first cut, then one more per cut step that cut cells.
    pub revision: u64,
    /// The model at that revision.
    pub view: CutView,
    /// The walls of the opening.
    pub walls: CutWalls,
    /// The cut's enrichment at that revision (its cut cells and cracked nodes).
    pub enrichment: Arc<crate::xfem::enrichment::Enrichment>,
    /// The distinct mesh nodes of the walls, increasing.
    pub wall_nodes: Vec<usize>,
    /// Per wall vertex, its node's index in `wall_nodes`.
    wall_node_of: Vec<usize>,
    /// Per cracked node, the enriched unknowns of its opening ([`ReducedCut::opening_unknowns`]).
    unknowns: Vec<[Option<usize>; 3]>,
}

impl CutPicture {
    /// The picture of `model` (cutting `mesh`, of organ `organ`) at `revision`.
    pub fn new(organ: usize, revision: u64, mesh: &Mesh, model: &ReducedCut) -> Self {
        let walls = CutWalls::new(mesh, model.enrichment());
        let mut wall_nodes: Vec<usize> = walls.vertices.iter().map(|v| v.node).collect();
        wall_nodes.sort_unstable();
        wall_nodes.dedup();
        let wall_node_of = walls
            .vertices
            .iter()
            .map(|v| wall_nodes.binary_search(&v.node).unwrap_or(0))
            .collect();
        Self {
            organ,
            revision,
            view: model.view(),
            walls,
            enrichment: Arc::new(model.enrichment().clone()),
            wall_nodes,
            wall_node_of,
            unknowns: model.opening_unknowns(),
        }
    }

    /// The coefficients of what the cut adds to the response to the contact `c`'s tissue
    /// force (resized to the model's dimension).
    pub fn response(&self, c: &Contact, coeffs: &mut Vec<f64>) {
        coeffs.resize(self.view.dim(), 0.0);
        self.view.added_response(&c.nodes, &c.weights, c.tissue_force_n, coeffs);
    }

    /// Adds what the cut moves `nodes` by (own sides) to `out` (3 per node).
    pub fn add_to(&self, coeffs: &[f64], nodes: &[usize], out: &mut [f32]) {
        for (&a, o) in nodes.iter().zip(out.chunks_exact_mut(3)) {
            let u = self.view.added_displacement(coeffs, a);
            for i in 0..3 {
                o[i] += u[i] as f32;
            }
        }
    }

    /// The displacement of every wall vertex (3 per vertex, into `out`), from the uncut
    /// displacement of the wall nodes (`uncut`, 3 per node of `wall_nodes`).
    pub fn wall_displacements(&self, coeffs: &[f64], uncut: &[f64], out: &mut Vec<f32>) {
        let nb = self.view.dim() - self.view.enriched_unknowns();
        out.clear();
        for (v, &j) in self.walls.vertices.iter().zip(&self.wall_node_of) {
            let added = self.view.added_displacement(coeffs, v.node);
            for i in 0..3 {
                let mut u = uncut[3 * j + i] + added[i];
                if let Some((k, s)) = v.copy
                    && let Some(e) = self.unknowns[k][i]
                {
                    u += s * coeffs[nb + e];
                }
                out.push(u as f32);
            }
        }
    }
}
