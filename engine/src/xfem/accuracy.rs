//! The force a session serves on a cut organ against the full-order XFEM's, on the same mesh
//! and cut: what `vademecum study` sweeps and what `vademecum build --target-error` holds the
//! sliver rule to (seed 000 §3.2–3.3).
//!
//! A session's force on the cut organ is `(C(s) + ΔC)⁻¹ δ`: the vademecum's exact local
//! compliance `C(s)` (the uncut organ's) plus what the cut adds at the contact, `ΔC`
//! ([`super::reduced::CutView::added_compliance`]). The comparison: at up to [`CONTACTS`]
//! cracked surface nodes, for a unit imposed displacement along each axis, the force of
//! `C_uncut + ΔC` against the full XFEM's compliance there (three full solves per node).

use super::reduced::{Discontinuous, ReducedCut, RitzBasis};
use super::{Enrichment, Plane, XfemParams, system};
use crate::pgd::Vademecum;
use crate::scene::{OrganModel, Scene};

/// Cracked surface nodes where the force is compared.
pub const CONTACTS: usize = 4;

/// A 3×3 compliance (m/N).
pub type Compliance = [[f64; 3]; 3];

/// The cut cells of the scene's pre-planned cuts on organ 0 (each cell once), or without any,
/// the cells crossed by the plane through the organ's centre normal to y.
pub fn cut_cells(scene: &Scene, model: &OrganModel, params: &XfemParams) -> Result<Vec<(usize, Plane)>, String> {
    let cuts = scene.organ_cuts(0).map_err(|e| e.to_string())?;
    let mut cells: Vec<(usize, Plane)> = Vec::new();
    for cut in &cuts {
        for (c, p) in Enrichment::cut_cells(&model.mesh, cut, params).map_err(|e| e.to_string())? {
            if !cells.iter().any(|(d, _)| *d == c) {
                cells.push((c, p));
            }
        }
    }
    if cuts.is_empty() {
        let (lo, hi) = model.mesh.bounding_box();
        let plane = Plane {
            point: [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])],
            normal: [0.0, 1.0, 0.0],
        };
        cells = Enrichment::cells_crossed_by(&model.mesh, &plane);
    }
    Ok(cells)
}

/// Up to [`CONTACTS`] cracked nodes of `enr` on the organ's accessible surface, evenly spread
/// over the enrichment's order (any cracked node when none is accessible).
pub fn contact_nodes(model: &OrganModel, enr: &Enrichment) -> Vec<usize> {
    let free = |a: &usize| !(0..3).any(|i| model.problem.constrained[3 * a + i]);
    let mut pool: Vec<usize> = enr
        .nodes
        .iter()
        .copied()
        .filter(|a| free(a) && model.accessible_nodes.contains(a))
        .collect();
    if pool.is_empty() {
        pool = enr.nodes.iter().copied().filter(free).collect();
    }
    let n = pool.len().min(CONTACTS);
    (0..n).map(|k| pool[k * pool.len() / n.max(1)]).collect()
}

/// The compliance at `node` of the XFEM with enrichment `enr`: three full-order solves with a
/// unit force there.
pub fn full_compliance(model: &OrganModel, enr: &Enrichment, params: &XfemParams, node: usize) -> Result<Compliance, String> {
    let mut c = [[0.0; 3]; 3];
    for j in 0..3 {
        let mut problem = model.problem.clone();
        problem.forces.fill(0.0);
        problem.prescribed.fill(0.0);
        problem.forces[3 * node + j] = 1.0;
        let sol = system::solve(&model.mesh, &model.materials, model.locking, &problem, enr, params).map_err(|e| e.to_string())?;
        for (i, ci) in c.iter_mut().enumerate() {
            ci[j] = sol.u[3 * node + i];
        }
    }
    Ok(c)
}

/// The relative errors of the forces of compliance `c` against `full` for a unit imposed
/// displacement along each axis.
pub fn force_errors(c: &Compliance, full: &Compliance) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (j, o) in out.iter_mut().enumerate() {
        let mut d = [0.0; 3];
        d[j] = 1.0;
        let (f, g) = (Vademecum::contact_force(c, d), Vademecum::contact_force(full, d));
        let diff = (0..3).map(|i| (f[i] - g[i]).powi(2)).sum::<f64>().sqrt();
        *o = diff / g.iter().map(|x| x * x).sum::<f64>().sqrt().max(f64::MIN_POSITIVE);
    }
    out
}

/// The full XFEM the served forces are compared with: the scene's cut at its sliver rule,
/// its contact nodes, and their compliances cut and uncut.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// The nodes the cut cracks at the scene's sliver rule.
    pub enriched: Vec<usize>,
    /// The cracked surface nodes compared at ([`contact_nodes`]).
    pub contacts: Vec<usize>,
    /// The full XFEM's compliance at each, cut.
    pub full: Vec<Compliance>,
    /// And uncut (what the vademecum's exact local compliance is).
    pub uncut: Vec<Compliance>,
}

impl Reference {
    /// The reference of organ 0 of `scene` at `params`; `progress(done, total)` after each
    /// full solve triple. An error when the cut crosses no cell or cracks no free node.
    pub fn of(scene: &Scene, model: &OrganModel, params: &XfemParams, mut progress: impl FnMut(usize, usize)) -> Result<Self, String> {
        let cells = cut_cells(scene, model, params)?;
        if cells.is_empty() {
            return Err("the cut crosses no cell of organ 0".into());
        }
        let reference = Enrichment::from_cut_cells(&model.mesh, &cells, params).map_err(|e| e.to_string())?;
        let contacts = contact_nodes(model, &reference);
        if contacts.is_empty() {
            return Err("the cut cracks no node free to move".into());
        }
        let uncut_enr = Enrichment::from_cut_cells(&model.mesh, &[], params).map_err(|e| e.to_string())?;
        let (mut full, mut uncut) = (Vec::new(), Vec::new());
        for (k, &a) in contacts.iter().enumerate() {
            full.push(full_compliance(model, &reference, params, a)?);
            uncut.push(full_compliance(model, &uncut_enr, params, a)?);
            progress(k + 1, contacts.len());
        }
        Ok(Self {
            enriched: reference.nodes,
            contacts,
            full,
            uncut,
        })
    }

    /// The sorted relative errors of the forces `view` serves at the contact nodes (its
    /// `ΔC` added to the uncut compliance), against the full XFEM.
    pub fn errors(&self, view: &mut super::reduced::CutView) -> Vec<f64> {
        let mut errors: Vec<f64> = self
            .contacts
            .iter()
            .zip(self.uncut.iter().zip(&self.full))
            .flat_map(|(&a, (c0, cf))| {
                let added = view.added_compliance(&[a], &[1.0]);
                let c = std::array::from_fn(|i| std::array::from_fn(|j| c0[i][j] + added[i][j]));
                force_errors(&c, cf)
            })
            .collect();
        errors.sort_by(f64::total_cmp);
        errors
    }
}

/// What a sliver rule's local-fields model serves on the scene's cut: the nodes it enriches
/// and the sorted relative errors of its forces against `reference` (`None` when it enriches
/// exactly the reference's nodes: the same model).
pub fn local_fields_errors(
    scene: &Scene,
    model: &OrganModel,
    params: &XfemParams,
    reference: &Reference,
) -> Result<Option<(usize, Vec<f64>)>, String> {
    let cells = cut_cells(scene, model, params)?;
    if Enrichment::from_cut_cells(&model.mesh, &cells, params)
        .map_err(|e| e.to_string())?
        .nodes
        == reference.enriched
    {
        return Ok(None);
    }
    let mut r = ReducedCut::new(
        &model.mesh,
        &model.materials,
        model.locking,
        &model.problem,
        &[],
        0,
        RitzBasis::Srb,
        Discontinuous::LocalFields,
        params,
    )
    .map_err(|e| e.to_string())?;
    r.cut(&model.mesh, &cells).map_err(|e| e.to_string())?;
    let enriched = r.enrichment().len();
    Ok(Some((enriched, reference.errors(&mut r.view()))))
}

/// The sliver thresholds a target tries, cheapest first (more nodes left unenriched).
pub const TARGET_SLIVERS: [f64; 3] = [5e-2, 1e-2, 1e-3];

/// What `build --target-error` chose of the sliver rule ([`sliver_for_target`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SliverTarget {
    /// The target: the largest relative error of the served force at the contact nodes.
    pub error: f64,
    /// The sliver rule kept (the scene's when no larger one meets the target).
    pub sliver: f64,
    /// Each larger threshold tried, cheapest first: the threshold, the nodes it enriches and
    /// its largest error (thresholds enriching the scene's own nodes are left out).
    pub tried: Vec<(f64, usize, f64)>,
}

/// The largest sliver threshold of [`TARGET_SLIVERS`] above the scene's whose local-fields
/// force stays within `target` of the full XFEM at the scene's threshold — fewer enriched
/// nodes, a cheaper cut and tick —, or the scene's own (exact: the local fields are the full
/// XFEM's Schur complement).
pub fn sliver_for_target(
    scene: &Scene,
    model: &OrganModel,
    params: &XfemParams,
    target: f64,
    reference: &Reference,
) -> Result<SliverTarget, String> {
    let mut tried = Vec::new();
    for sliver in TARGET_SLIVERS.into_iter().filter(|&s| s > params.sliver) {
        let p = XfemParams { sliver, ..*params };
        let Some((enriched, errors)) = local_fields_errors(scene, model, &p, reference)? else {
            continue;
        };
        let worst = errors.last().copied().unwrap_or(f64::INFINITY);
        tried.push((sliver, enriched, worst));
        if worst <= target {
            return Ok(SliverTarget {
                error: target,
                sliver,
                tried,
            });
        }
    }
    Ok(SliverTarget {
        error: target,
        sliver: params.sliver,
        tried,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_force_error_is_zero_for_the_same_compliance_and_relative_otherwise() {
        let c = [[2.0, 0.1, 0.0], [0.1, 1.0, 0.0], [0.0, 0.0, 4.0]];
        assert_eq!(force_errors(&c, &c), [0.0; 3]);
        // twice as compliant along z: half the force along z, the same along x and y
        let mut soft = c;
        soft[2][2] = 8.0;
        let e = force_errors(&soft, &c);
        assert!(e[0] < 1e-15 && e[1] < 1e-15 && (e[2] - 0.5).abs() < 1e-12, "{e:?}");
    }
}
