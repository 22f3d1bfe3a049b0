//! An organ cut and deformed largely at once (issue 46, "Effects compose on one organ"): the
//! composed law a session serves against the full-order model that carries both effects.
//!
//! # The composed law
//! On an organ that deforms largely, a session scales the linear force by the stiffening `r`
//! of the organ's ANM-POD lattice, built on the uncut organ; once the organ is cut, the linear
//! force is the cut's, `f_cut = λ (C + ΔC_cut)⁻¹ δ`, and the composed force is `r f_cut`
//! ([`crate::pipeline::cutting::stiffened_cut`]): the nonlinear and the cut's corrections taken
//! as separable. Its estimate adds to the lattice's own the interaction term it assumes,
//! `|r − 1| |f_cut − f|` with `f` the uncut linear force at the same depth.
//!
//! # The full-order reference
//! Total Lagrangian St Venant–Kirchhoff Newton (the lattice's law, [`svk_laws`]) on the organ
//! cut by split nodes: every node the cut's enrichment cracks duplicated, the cells on its far
//! side moved to the copy ([`crate::xfem::identity::duplicated`]). For a cut lying on cell
//! faces this is the XFEM's own discontinuity (the linear XFEM equals it to solver precision,
//! `docs/cutting.md`), so it is the exact full-order model of the cut organ at large
//! deformations — the cut's faces free (they may open; contact between the lips, which a
//! closing cut would need, is not modelled, as in the reduced model). Each press is the
//! lattice's own load (its `max_force` along the uncut surface's inward normal over the
//! footprint's patch, taken [`PAST_THE_LATTICE`] times past it, [`NewtonLaw::along`]) on the
//! uncut and on the cut organ; the true ratio of the cut organ at each depth Newton reached
//! is the cut organ's nonlinear force over its own linear force at that depth.
//!
//! In force terms (relative to the exact linear force of the cut organ `f_cut`, the one the
//! reduced cut model serves to round-off): the composed law's error is `|r_served − r_cut|`,
//! the linear cut model's (no large deformations) `|1 − r_cut|`, and the large-deformation law
//! that ignores the cut `|r_served s − r_cut|`, with `s = f/f_cut` the cut's softening at
//! equal depth (`d_lin,cut / d_lin,uncut`).

use super::estimate::{LARGE_CUT, Sample};
use crate::fem::OrganModel;
use crate::fem::hyperelastic::LawMap;
use crate::mesh::boundary::Boundary;
use crate::rom::lattice_check::{NEIGHBOURS, PAST_THE_LATTICE, is_within_force};
use crate::rom::palpation::{AnmLattice, AnmLatticeParams, NewtonLaw, surface_normals, svk_laws};
use crate::rom::study::StudyError;
use crate::xfem::Enrichment;
use crate::xfem::identity::duplicated;

/// `model` cut by split nodes: every node `enr` enriches duplicated, the cells on the far side
/// of its plane on the copy (node `n + k` for the k-th enriched node, which keeps the node's
/// supports; loads and the accessible region stay on the originals), its boundary recomputed
/// (the cut's faces are free surface).
pub fn split_organ(model: &OrganModel, enr: &Enrichment) -> OrganModel {
    let (mesh, problem) = duplicated(&model.mesh, enr, &model.problem);
    OrganModel {
        name: model.name.clone(),
        boundary: Boundary::of(&mesh),
        materials: model.materials.clone(),
        laws: model.laws.clone(),
        locking: model.locking,
        warnings: Vec::new(),
        problem,
        named_regions: model.named_regions.clone(),
        accessible_nodes: model.accessible_nodes.clone(),
        mesh,
    }
}

/// One press beside the cut at one depth the full model reached (ratios: the nonlinear over
/// the linear force at equal depth).
#[derive(Debug, Clone, PartialEq)]
pub struct ComposedState {
    /// The surface node pressed.
    pub node: usize,
    /// Its reference position (m).
    pub point_m: [f64; 3],
    /// The depth the cut organ's full model reached (m).
    pub depth_m: f64,
    /// The load factor there (1: the lattice's `max_force`).
    pub lambda: f64,
    /// The ratio the session serves: the lattice's, of the uncut organ.
    pub served: f64,
    /// The lattice's own estimate of its ratio's error.
    pub lattice_estimate: f64,
    /// The estimate the session attaches (relative to the cut's linear force):
    /// `lattice_estimate + |served − 1| (softening − 1)`.
    pub estimate: f64,
    /// Whether the lattice extrapolated past a path it blends.
    pub beyond_range: bool,
    /// The cut organ's true ratio at this depth.
    pub truth: f64,
    /// The uncut organ's true ratio at this depth (interpolated between its Newton steps;
    /// `None` past the last).
    pub uncut_truth: Option<f64>,
    /// The cut's softening at equal depth, `f/f_cut = d_lin,cut / d_lin,uncut` (1: the cut does
    /// not reach this press).
    pub softening: f64,
}

impl ComposedState {
    /// The composed law's true error (relative to the cut's linear force).
    pub fn error(&self) -> f64 {
        (self.served - self.truth).abs()
    }

    /// The error of the linear cut model, which ignores the large deformations.
    pub fn linear_cut_error(&self) -> f64 {
        (1.0 - self.truth).abs()
    }

    /// The error of the large-deformation law that ignores the cut (`r f`).
    pub fn uncut_large_error(&self) -> f64 {
        (self.served * self.softening - self.truth).abs()
    }

    /// The error of the composition alone: the uncut organ's exact ratio applied to the cut's
    /// force (no lattice error in it).
    pub fn composition_error(&self) -> Option<f64> {
        self.uncut_truth.map(|r| (r - self.truth).abs())
    }

    /// As a study sample ([`LARGE_CUT`], ratios).
    pub fn sample(&self) -> Sample {
        Sample {
            model: LARGE_CUT,
            point_m: self.point_m,
            depth_m: self.depth_m,
            beyond_range: self.beyond_range,
            within_force: is_within_force(self.lambda),
            served: self.served,
            truth: self.truth,
            error: self.error(),
            estimate: self.estimate,
        }
    }
}

/// The loadable surface nodes of `model` within one cell of the cut (sharing a cell with a
/// node `enr` enriches, or enriched), lattice positions excluded, at most `count` of them
/// spread evenly over that set (in node order).
pub fn nodes_beside(model: &OrganModel, enr: &Enrichment, lattice: &AnmLattice, count: usize) -> Vec<usize> {
    let normals = surface_normals(model);
    let mut near = vec![false; model.mesh.n_nodes()];
    for c in model.mesh.cells_iter() {
        if c.iter().any(|&a| enr.index(a).is_some()) {
            c.iter().for_each(|&a| near[a] = true);
        }
    }
    let positions: Vec<usize> = lattice.positions.iter().map(|p| p.node).collect();
    let pool: Vec<usize> = crate::rom::palpation::loadable_nodes(model, &normals)
        .into_iter()
        .filter(|&a| near[a] && !positions.contains(&a))
        .collect();
    if pool.len() <= count {
        return pool;
    }
    (0..count).map(|i| pool[i * pool.len() / count]).collect()
}

/// The composed law at `nodes` of `model` cut by `enr` (module docs): the lattice's ratio
/// against Newton on the cut organ at every depth it reached, with the uncut organ's law at
/// the same node. `progress(done, total)` after each node; nodes where Newton converges no
/// step on either organ are skipped.
pub fn composed_states(
    model: &OrganModel,
    enr: &Enrichment,
    lattice: &AnmLattice,
    params: &AnmLatticeParams,
    nodes: &[usize],
    mut progress: impl FnMut(usize, usize),
) -> Result<Vec<ComposedState>, StudyError> {
    let laws = svk_laws(model);
    let split = split_organ(model, enr);
    let split_laws = svk_laws(&split);
    let past = AnmLatticeParams {
        max_force: PAST_THE_LATTICE * lattice.max_force,
        load_steps: (PAST_THE_LATTICE * params.load_steps as f64).ceil() as usize,
        ..*params
    };
    let normals = surface_normals(model);
    let rates = lattice.interpolation_rates(NEIGHBOURS);
    let mut zeta = vec![0.0; lattice.max_modes()];
    let mut out = Vec::new();
    for (done, &node) in nodes.iter().enumerate() {
        let Some(inward) = crate::rom::unit(normals[node]).map(|n| n.map(|x| -x)) else {
            return Err(StudyError::Unsupported(format!("node {node} has no surface normal")));
        };
        let laws_of = |organ: &OrganModel, laws: &LawMap| match NewtonLaw::along(organ, laws, &past, node, inward) {
            Ok(law) => Ok(Some(law)),
            Err(StudyError::Newton(_)) => Ok(None),
            Err(e) => Err(e),
        };
        if let (Some(uncut), Some(cut)) = (laws_of(model, &laws)?, laws_of(&split, &split_laws)?) {
            let uncut_ratios: Vec<(f64, f64)> = uncut.ratios().map(|(_, d, r)| (d, r)).collect();
            let softening = cut.d_linear / uncut.d_linear;
            for (lambda, depth, truth) in cut.ratios() {
                let s = lattice.stiffness_ratio(cut.point, depth, NEIGHBOURS, &mut zeta);
                let lattice_estimate = s.error(&rates);
                out.push(ComposedState {
                    node,
                    point_m: cut.point,
                    depth_m: depth,
                    lambda,
                    served: s.ratio,
                    lattice_estimate,
                    estimate: lattice_estimate + (s.ratio - 1.0).abs() * (softening - 1.0).abs(),
                    beyond_range: s.extrapolated,
                    truth,
                    uncut_truth: interpolate(&uncut_ratios, depth),
                    softening,
                });
            }
        }
        progress(done + 1, nodes.len());
    }
    Ok(out)
}

/// The ratio at `depth` along `(depth, ratio)` points sorted by depth, linear between them and
/// from `(0, 1)` (no stiffening at zero depth); `None` past the last point.
fn interpolate(points: &[(f64, f64)], depth: f64) -> Option<f64> {
    let mut last = (0.0, 1.0);
    for &(d, r) in points {
        if depth <= d {
            let t = if d > last.0 { (depth - last.0) / (d - last.0) } else { 1.0 };
            return Some(last.1 + t * (r - last.1));
        }
        last = (d, r);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::interpolate;

    #[test]
    fn the_ratio_is_interpolated_from_no_stiffening_at_zero_depth_and_not_past_the_last_step() {
        let pts = [(1.0, 1.2), (2.0, 1.6)];
        assert_eq!(interpolate(&pts, 0.5), Some(1.1));
        assert!((interpolate(&pts, 1.5).unwrap() - 1.4).abs() < 1e-15);
        assert_eq!(interpolate(&pts, 2.0), Some(1.6));
        assert_eq!(interpolate(&pts, 2.5), None);
        assert_eq!(interpolate(&[], 0.1), None);
    }
}
