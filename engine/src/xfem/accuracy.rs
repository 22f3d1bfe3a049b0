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
use crate::fem::OrganModel;
use crate::geometry::cut::Cut;
use crate::pgd::Vademecum;

/// Cracked surface nodes where the force is compared.
pub const CONTACTS: usize = 4;

/// Why the served cut force could not be held against the full XFEM.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AccuracyError {
    /// The cut crosses no cell of the organ.
    #[error("the cut crosses no cell of the organ")]
    NoCutCell,
    /// The cut cracks no node that is free to move.
    #[error("the cut cracks no node free to move")]
    NoFreeCrackedNode,
    /// The cut's enrichment could not be made.
    #[error(transparent)]
    Enrichment(#[from] super::enrichment::EnrichmentError),
    /// A full-order XFEM solve failed.
    #[error(transparent)]
    Solve(#[from] super::system::XfemError),
    /// The session's reduced cut model could not be made or cut.
    #[error(transparent)]
    Reduced(#[from] super::reduced::ReducedError),
}

/// A 3×3 compliance (m/N).
pub type Compliance = [[f64; 3]; 3];

/// The cells of organ `model` crossed by its pre-planned `cuts` (a scene's
/// `organ_cuts`; each cell once), or without any, the cells crossed by
/// the plane through the organ's centre normal to y.
pub fn cut_cells(cuts: &[Cut], model: &OrganModel, params: &XfemParams) -> Result<Vec<(usize, Plane)>, AccuracyError> {
    let mut cells: Vec<(usize, Plane)> = Vec::new();
    for cut in cuts {
        for (c, p) in Enrichment::cut_cells(&model.mesh, cut, params)? {
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
    contact_nodes_up_to(model, enr, CONTACTS)
}

/// [`contact_nodes`], up to `most` of them.
pub fn contact_nodes_up_to(model: &OrganModel, enr: &Enrichment, most: usize) -> Vec<usize> {
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
    let n = pool.len().min(most);
    (0..n).map(|k| pool[k * pool.len() / n.max(1)]).collect()
}

/// The compliance at `node` of the XFEM with enrichment `enr`: three full-order solves with a
/// unit force there.
pub fn full_compliance(model: &OrganModel, enr: &Enrichment, params: &XfemParams, node: usize) -> Result<Compliance, AccuracyError> {
    patch_compliance(model, enr, params, &[node], &[1.0])
}

/// The compliance of the XFEM with enrichment `enr` at a load patch — `nodes` with `weights`
/// summing to one, as a session's contact spreads its force —: three full-order solves with
/// a unit force spread by the weights, the displacement read back with the same weights.
pub fn patch_compliance(
    model: &OrganModel,
    enr: &Enrichment,
    params: &XfemParams,
    nodes: &[usize],
    weights: &[f64],
) -> Result<Compliance, AccuracyError> {
    let mut c = [[0.0; 3]; 3];
    for j in 0..3 {
        let mut problem = model.problem.clone();
        problem.forces.fill(0.0);
        problem.prescribed.fill(0.0);
        for (&a, &w) in nodes.iter().zip(weights) {
            problem.forces[3 * a + j] += w;
        }
        let sol = system::solve(&model.mesh, &model.materials, model.locking, &problem, enr, params)?;
        for (i, ci) in c.iter_mut().enumerate() {
            ci[j] = nodes.iter().zip(weights).map(|(&a, &w)| w * sol.u[3 * a + i]).sum();
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
    /// The reference of organ `model` cut by `cuts` at `params`, at [`CONTACTS`] nodes;
    /// `progress(done, total)` after each full solve triple. An error when the cut crosses no
    /// cell or cracks no free node.
    pub fn of(cuts: &[Cut], model: &OrganModel, params: &XfemParams, progress: impl FnMut(usize, usize)) -> Result<Self, AccuracyError> {
        Self::at(cuts, model, params, CONTACTS, progress)
    }

    /// [`Self::of`] at up to `contacts` cracked surface nodes.
    pub fn at(
        cuts: &[Cut],
        model: &OrganModel,
        params: &XfemParams,
        contacts: usize,
        mut progress: impl FnMut(usize, usize),
    ) -> Result<Self, AccuracyError> {
        let cells = cut_cells(cuts, model, params)?;
        if cells.is_empty() {
            return Err(AccuracyError::NoCutCell);
        }
        let reference = Enrichment::from_cut_cells(&model.mesh, &cells, params)?;
        let contacts = contact_nodes_up_to(model, &reference, contacts);
        if contacts.is_empty() {
            return Err(AccuracyError::NoFreeCrackedNode);
        }
        let uncut_enr = Enrichment::from_cut_cells(&model.mesh, &[], params)?;
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
    cuts: &[Cut],
    model: &OrganModel,
    params: &XfemParams,
    reference: &Reference,
) -> Result<Option<(usize, Vec<f64>)>, AccuracyError> {
    let cells = cut_cells(cuts, model, params)?;
    if Enrichment::from_cut_cells(&model.mesh, &cells, params)?.nodes == reference.enriched {
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
    )?;
    r.cut(&model.mesh, &cells)?;
    let enriched = r.enrichment().len();
    Ok(Some((enriched, reference.errors(&mut r.view()))))
}

/// Patches the bare enrichment's force error is calibrated at ([`bare_force_error`]): this
/// many cracked surface nodes and as many centroids of the surface triangles around them.
pub const BARE_CONTACTS: usize = 12;

/// The calibration of the bare enrichment's force error that a build stores
/// (`info.cut.bare_force_error`): the session's bare model — the K-orthonormal Ritz basis `x`
/// (`size` directions of kind `basis`) the bundle stores — cut by the scene's cut, pressed by a
/// unit displacement along each axis at up to [`BARE_CONTACTS`] cracked surface nodes and at
/// the centroids of as many surface triangles touching a cracked node (spread evenly over
/// them), against the full XFEM: the largest `|f − f_full| / |f|` (relative to the force
/// served, as the session's estimate `e·|f|` is), and the forces compared. The cut is where
/// the bare enrichment is worst (the modes, responses of the uncut organ, cannot follow the
/// opening); `vademecum study` checks the calibration at random points of those triangles
/// ([`patch_samples`]). `progress(done, total)` after each patch.
#[allow(clippy::too_many_arguments)]
pub fn bare_force_error(
    cuts: &[Cut],
    model: &OrganModel,
    params: &XfemParams,
    basis: super::reduced::RitzBasis,
    x: std::sync::Arc<[f64]>,
    size: usize,
    progress: impl FnMut(usize, usize),
) -> Result<(f64, usize), AccuracyError> {
    let cells = cut_cells(cuts, model, params)?;
    let cut = Enrichment::from_cut_cells(&model.mesh, &cells, params)?;
    let tris = crack_triangles(model, &cut);
    let n = tris.len().min(BARE_CONTACTS);
    let patches: Vec<([usize; 3], [f64; 3])> = contact_nodes_up_to(model, &cut, BARE_CONTACTS)
        .into_iter()
        .map(|a| ([a, a, a], [1.0, 0.0, 0.0]))
        .chain((0..n).map(|k| (tris[k * tris.len() / n], [1.0 / 3.0; 3])))
        .collect();
    let mut r = ReducedCut::from_basis(
        &model.mesh,
        &model.materials,
        model.locking,
        &model.problem,
        basis,
        x,
        size,
        Discontinuous::Bare,
        params,
    )?;
    r.cut(&model.mesh, &cells)?;
    let samples = patch_forces(model, params, &cut, &mut r.view(), &patches, progress)?;
    let norm = |f: [f64; 3]| f.iter().map(|x| x * x).sum::<f64>().sqrt();
    let worst = samples
        .iter()
        .map(|p| norm(std::array::from_fn(|k| p.served[k] - p.truth[k])) / norm(p.served).max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max);
    Ok((worst, samples.len()))
}

/// The surface triangles of the organ, free to move, that touch a node `enr` cracks.
pub fn crack_triangles(model: &OrganModel, enr: &Enrichment) -> Vec<[usize; 3]> {
    let free = |a: usize| !(0..3).any(|i| model.problem.constrained[3 * a + i]);
    model
        .boundary
        .triangles()
        .into_iter()
        .filter(|t| t.iter().all(|&a| free(a)) && t.iter().any(|&a| enr.index(a).is_some()))
        .collect()
}

/// A contact on the cut organ ([`patch_forces`]): a unit imposed displacement along one axis
/// at a point of a surface triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchSample {
    /// The point (m).
    pub point_m: [f64; 3],
    /// The force a session serves (N per m imposed): `(C_uncut + ΔC)⁻¹ e_j`.
    pub served: [f64; 3],
    /// The full XFEM's for the same displacement.
    pub truth: [f64; 3],
}

/// At each patch (a triangle's nodes and the point's barycentric weights), pressed along the
/// three axes: the force of the uncut organ's exact compliance plus what `view` adds (a
/// session's model, already cut by the cut that cracks `cut`) against the full XFEM's with
/// `cut` (six full-order solves per patch, the load spread by the weights in both).
/// `progress(done, total)` after each patch.
pub fn patch_forces(
    model: &OrganModel,
    params: &XfemParams,
    cut: &Enrichment,
    view: &mut super::reduced::CutView,
    patches: &[([usize; 3], [f64; 3])],
    mut progress: impl FnMut(usize, usize),
) -> Result<Vec<PatchSample>, AccuracyError> {
    let uncut = Enrichment::from_cut_cells(&model.mesh, &[], params)?;
    let mut out = Vec::with_capacity(3 * patches.len());
    for (k, (t, w)) in patches.iter().enumerate() {
        let full = patch_compliance(model, cut, params, t, w)?;
        let c0 = patch_compliance(model, &uncut, params, t, w)?;
        let added = view.added_compliance(t, w);
        let served: Compliance = std::array::from_fn(|i| std::array::from_fn(|j| c0[i][j] + added[i][j]));
        let point_m = std::array::from_fn(|i| (0..3).map(|v| w[v] * model.mesh.nodes[t[v]][i]).sum());
        for j in 0..3 {
            let mut d = [0.0; 3];
            d[j] = 1.0;
            out.push(PatchSample {
                point_m,
                served: Vademecum::contact_force(&served, d),
                truth: Vademecum::contact_force(&full, d),
            });
        }
        progress(k + 1, patches.len());
    }
    Ok(out)
}

/// `count` random points of the surface triangles that touch a node the cut of the cells
/// `cells` (each with its plane) cracks ([`crack_triangles`]), each pressed along the three axes
/// ([`patch_forces`]): `view` is a session's model already cut by those cells at `params`.
pub fn patch_samples(
    model: &OrganModel,
    params: &XfemParams,
    cells: &[(usize, Plane)],
    view: &mut super::reduced::CutView,
    count: usize,
    progress: impl FnMut(usize, usize),
) -> Result<Vec<PatchSample>, AccuracyError> {
    let cut = Enrichment::from_cut_cells(&model.mesh, cells, params)?;
    let tris = crack_triangles(model, &cut);
    if tris.is_empty() {
        return Ok(Vec::new());
    }
    let mut rng = crate::rng::Rng(0x00C0_75A3_B1E5);
    let patches: Vec<([usize; 3], [f64; 3])> = (0..count)
        .map(|_| {
            let t = tris[(rng.next_u64() % tris.len() as u64) as usize];
            let (a, b) = (rng.unit(), rng.unit());
            let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
            (t, [1.0 - a - b, a, b])
        })
        .collect();
    patch_forces(model, params, &cut, view, &patches, progress)
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
    cuts: &[Cut],
    model: &OrganModel,
    params: &XfemParams,
    target: f64,
    reference: &Reference,
) -> Result<SliverTarget, AccuracyError> {
    let mut tried = Vec::new();
    for sliver in TARGET_SLIVERS.into_iter().filter(|&s| s > params.sliver) {
        let p = XfemParams { sliver, ..*params };
        let Some((enriched, errors)) = local_fields_errors(cuts, model, &p, reference)? else {
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
