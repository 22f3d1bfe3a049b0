//! Where else a grasper can take hold of a tearable organ: grasp sites spread over the
//! tearable tissue's accessible surface, each with its own unit load (and so its own offline
//! stage: a POD of the damage its pull causes, and a vademecum).
//!
//! The scene's load (`[[organs.loads]]`) is the first grasp, as the seed's (§4.6.2: one
//! grasping point). The others are chosen farthest first among the candidate nodes: on the
//! accessible surface, on a tearable cell, free (no component constrained, and no constrained
//! node within `jaw_width`: the jaws would hold anchored tissue), on the side the scene grasps
//! from (the outward normal within 60° of the scene's pull: pulled off the organ as the scene's
//! grasp is, not sideways off an edge). The next site is the candidate farthest from every
//! grasp chosen so far, until every candidate lies within `jaw_width` of a grasp or the
//! scene's number of sites is reached. So `n` sites cover as much of the tissue as `n` grasps
//! can, and each further site fills the largest gap left.
//!
//! A site grasps the candidates within `jaw_width / 2` of its centre node and pulls them along
//! the surface's outward normal there (the mean of the adjacent boundary faces' normals,
//! weighted by area): away from the organ, the way a surgeon lifts tissue off it. The load of
//! a unit step has the magnitude of the scene's load's resultant, shared equally by the
//! grasped nodes.

use super::model::TearModel;
use crate::mesh::boundary::{Boundary, triangle_area_normal};

/// One more grasp site: its nodes and the unit step's force on each of them.
#[derive(Debug, Clone, PartialEq)]
pub struct SiteLoad {
    /// The grasped nodes.
    pub nodes: Vec<usize>,
    /// The force each receives per unit step (N).
    pub force: [f64; 3],
}

impl SiteLoad {
    /// The load as a full-length vector (`3 × n_nodes`).
    pub fn full(&self, n_nodes: usize) -> Vec<f64> {
        let mut load = vec![0.0; 3 * n_nodes];
        for &n in &self.nodes {
            load[3 * n..3 * n + 3].copy_from_slice(&self.force);
        }
        load
    }
}

/// Cosine of the largest angle between a site's pull and the scene's (60°).
pub const SAME_SIDE: f64 = 0.5;

/// The candidate nodes of `model` for a grasp by jaws `jaw_width` wide: `accessible` nodes
/// on the boundary, on a tearable cell, with no constrained node within `jaw_width`, whose
/// outward normal lies within 60° of the scene's pull (sorted; empty without a load).
pub fn candidates(model: &TearModel, boundary: &Boundary, accessible: &[usize], jaw_width: f64) -> Vec<usize> {
    let n_nodes = model.mesh.n_nodes();
    let Some(frame) = model.pull_frame() else { return Vec::new() };
    let normals = outward_normals(model, boundary);
    let faces_the_pull = |n: usize| {
        let v = normals[n];
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        len > 0.0 && (v[0] * frame[0][0] + v[1] * frame[0][1] + v[2] * frame[0][2]) >= SAME_SIDE * len
    };
    let anchored: Vec<[f64; 3]> = (0..n_nodes)
        .filter(|&n| (0..3).any(|k| model.dofs.is_constrained(3 * n + k)))
        .map(|n| model.mesh.nodes[n])
        .collect();
    let free_around = |n: usize| {
        let p = model.mesh.nodes[n];
        anchored
            .iter()
            .all(|a| (0..3).map(|k| (a[k] - p[k]).powi(2)).sum::<f64>() >= jaw_width * jaw_width)
    };
    let mut on_tearable = vec![false; n_nodes];
    for &p in &model.points.tearable {
        for &n in model.mesh.cell(model.points.cell[p]) {
            on_tearable[n] = true;
        }
    }
    let mut on_boundary = vec![false; n_nodes];
    for n in boundary.nodes() {
        on_boundary[n] = true;
    }
    let mut out: Vec<usize> = accessible
        .iter()
        .copied()
        .filter(|&n| n < n_nodes && on_tearable[n] && on_boundary[n] && faces_the_pull(n) && free_around(n))
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// Up to `extra` more grasp sites on `model` beside the scene's (its load), farthest first
/// among `candidates`, at least `jaw_width` from each other and from the scene's grasp
/// (module docs). Empty when the model has no load or no candidate is far enough.
pub fn extra_sites(model: &TearModel, boundary: &Boundary, candidates: &[usize], jaw_width: f64, extra: usize) -> Vec<SiteLoad> {
    let Some((_, first, r)) = model.grasp() else { return Vec::new() };
    let magnitude = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    if !(magnitude > 0.0 && magnitude.is_finite() && jaw_width > 0.0) {
        return Vec::new();
    }
    let nodes = &model.mesh.nodes;
    let dist = |a: [f64; 3], b: [f64; 3]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    // each candidate's distance to the nearest grasp so far
    let mut nearest: Vec<f64> = candidates.iter().map(|&n| dist(nodes[n], first)).collect();
    let normals = outward_normals(model, boundary);
    let mut out = Vec::new();
    while out.len() < extra {
        // the farthest candidate (the first of equals: deterministic)
        let Some((i, &d)) = nearest.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0))) else {
            break;
        };
        if d < jaw_width {
            break;
        }
        let centre = nodes[candidates[i]];
        let normal = normals[candidates[i]];
        let len = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
        if len == 0.0 || !len.is_finite() {
            nearest[i] = 0.0; // a node without a surface direction cannot be pulled off
            continue;
        }
        let grasped: Vec<usize> = candidates
            .iter()
            .copied()
            .filter(|&n| dist(nodes[n], centre) <= 0.5 * jaw_width)
            .collect();
        let share = magnitude / grasped.len() as f64;
        out.push(SiteLoad {
            nodes: grasped,
            force: normal.map(|x| share * x / len),
        });
        for (k, &n) in candidates.iter().enumerate() {
            nearest[k] = nearest[k].min(dist(nodes[n], centre));
        }
    }
    out
}

/// Area-weighted outward normal at every node (zero off the boundary): each boundary face's
/// area times its normal, added to each of its nodes (a quadrilateral as a whole, so a
/// node's normal does not depend on the diagonal the face is split along).
fn outward_normals(model: &TearModel, boundary: &Boundary) -> Vec<[f64; 3]> {
    let mut normals = vec![[0.0; 3]; model.mesh.n_nodes()];
    for f in &boundary.faces {
        let v = f.node_slice();
        let mut an = [0.0; 3];
        for k in 1..v.len() - 1 {
            let (area, n) = triangle_area_normal(&model.mesh, [v[0], v[k], v[k + 1]]);
            (0..3).for_each(|i| an[i] += area * n[i]);
        }
        for &node in v {
            (0..3).for_each(|i| normals[node][i] += an[i]);
        }
    }
    normals
}
