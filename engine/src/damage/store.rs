//! The offline stage of tearing as a bundle stores it: the arrays of [`TearOffline`] that do
//! not come from the scene (the POD basis of the damage and its coefficient box, the
//! vademecum's spatial modes and one-dimensional factors, the Ritz operator). The model
//! (mesh, integration points, supports, loads) is rebuilt from the scene when a session
//! starts, and checked against the arrays' sizes. A grasp site other than the scene's
//! ([`super::sites`]) also stores its load, which replaces the scene's in the rebuilt model.

use super::model::TearModel;
use super::online::{RitzOperator, TearFallback, TearOffline};
use super::pod::DamageBasis;
use super::sites::SiteLoad;
use super::vademecum::{DamageVademecum, VademecumReport};
use crate::rom::pod::Pod;

/// The stored arrays (row-major, shapes in the field docs).
#[derive(Debug, Clone, PartialEq)]
pub struct TearArrays {
    /// POD vectors of the damage at the tearable points, `q × n_tearable`.
    pub pod_basis: Vec<f64>,
    /// Singular values of the snapshots (all of them, decreasing).
    pub singular_values: Vec<f64>,
    /// Energy fraction the kept vectors capture.
    pub captured: f64,
    /// The coefficient box, `q` each.
    pub lo: Vec<f64>,
    /// The coefficient box.
    pub hi: Vec<f64>,
    /// Grid nodes per coefficient.
    pub grid: usize,
    /// The vademecum's spatial modes, `n_modes × n_free`.
    pub spatial: Vec<f64>,
    /// Its factors, `n_modes × q × grid`.
    pub factors: Vec<f64>,
    /// The Ritz basis `V`, `n_free × m`.
    pub ritz_v: Vec<f64>,
    /// `VᵀK_jV`, `(q + 1) × m × m`.
    pub ritz_k: Vec<f64>,
    /// `Vᵀb_j`, `(q + 1) × m`.
    pub ritz_b: Vec<f64>,
    /// Modes of each pull pattern (`[n_modes]`, or along and the two across the load).
    pub patterns: Vec<usize>,
    /// Modes `n_modes`.
    pub n_modes: usize,
    /// Ritz size `m`.
    pub m: usize,
    /// The grasped nodes of a site other than the scene's grasp (empty: the scene's load).
    pub load_nodes: Vec<usize>,
    /// The force per unit step on each of them (N), `3 × load_nodes`.
    pub load_forces: Vec<f64>,
    /// [`TearOffline::force_error`], flattened (`[level, error]` pairs; empty: none).
    pub force_error: Vec<f64>,
    /// The fallback's modes per pull pattern ([`TearOffline::fallback`]; empty: none).
    pub fallback_modes: Vec<usize>,
    /// The fallback's calibrated force error, flattened as [`Self::force_error`].
    pub fallback_force_error: Vec<f64>,
}

impl TearOffline {
    /// The arrays a bundle stores.
    pub fn to_arrays(&self) -> TearArrays {
        let (b, v, r) = (&self.basis, &self.vademecum, &self.ritz);
        TearArrays {
            pod_basis: b.pod.basis.clone(),
            singular_values: b.pod.singular_values.clone(),
            captured: b.pod.captured,
            lo: b.lo.clone(),
            hi: b.hi.clone(),
            grid: v.grid,
            spatial: v.spatial.clone(),
            factors: v.factors.clone(),
            ritz_v: r.v.clone(),
            ritz_k: r.k.concat(),
            ritz_b: r.b.concat(),
            patterns: v.patterns.clone(),
            n_modes: v.n_modes,
            m: r.m,
            load_nodes: Vec::new(),
            load_forces: Vec::new(),
            force_error: self.force_error.concat(),
            fallback_modes: self.fallback.as_ref().map_or_else(Vec::new, |f| f.modes.clone()),
            fallback_force_error: self.fallback.as_ref().map_or_else(Vec::new, |f| f.force_error.concat()),
        }
    }

    /// [`Self::to_arrays`] of a grasp site other than the scene's: its load stored with it.
    pub fn to_site_arrays(&self, site: &SiteLoad) -> TearArrays {
        TearArrays {
            load_nodes: site.nodes.clone(),
            load_forces: site.nodes.iter().flat_map(|_| site.force).collect(),
            ..self.to_arrays()
        }
    }

    /// The offline data of `model` from stored arrays; an error says which array does not
    /// fit the model (a bundle built for another scene or mesh).
    pub fn from_arrays(mut model: TearModel, a: TearArrays) -> Result<Self, String> {
        if !a.load_nodes.is_empty() {
            let n_nodes = model.mesh.n_nodes();
            if a.load_forces.len() != 3 * a.load_nodes.len()
                || a.load_nodes.iter().any(|&n| n >= n_nodes)
                || !a.load_forces.iter().all(|f| f.is_finite())
            {
                return Err(format!(
                    "a grasp site's load ({} nodes, {} force components) does not fit the scene's mesh of {n_nodes} nodes; rebuild the bundle with `vademecum build`",
                    a.load_nodes.len(),
                    a.load_forces.len()
                ));
            }
            model.load = vec![0.0; 3 * n_nodes];
            for (&n, f) in a.load_nodes.iter().zip(a.load_forces.chunks_exact(3)) {
                model.load[3 * n..3 * n + 3].copy_from_slice(f);
            }
        }
        let q = a.lo.len();
        let (nt, nf) = (model.points.tearable.len(), model.dofs.n_free());
        let check = |name: &str, len: usize, want: usize| {
            if len == want {
                Ok(())
            } else {
                Err(format!(
                    "tearing array {name} holds {len} values where the scene's model needs {want}; rebuild the bundle with `vademecum build`"
                ))
            }
        };
        if q == 0 || a.grid < 2 || a.n_modes == 0 || a.m == 0 {
            return Err("tearing arrays are empty (no POD vector, grid or mode)".into());
        }
        check("hi", a.hi.len(), q)?;
        check("pod_basis", a.pod_basis.len(), q * nt)?;
        check("spatial", a.spatial.len(), a.n_modes * nf)?;
        check("factors", a.factors.len(), a.n_modes * q * a.grid)?;
        check("ritz_v", a.ritz_v.len(), nf * a.m)?;
        check("ritz_k", a.ritz_k.len(), (q + 1) * a.m * a.m)?;
        check("ritz_b", a.ritz_b.len(), (q + 1) * a.m)?;
        if !(a.patterns.len() == 1 || a.patterns.len() == 3) || a.patterns.iter().sum::<usize>() != a.n_modes {
            return Err(format!(
                "tearing pull patterns {:?} do not hold the {} modes in 1 or 3 patterns",
                a.patterns, a.n_modes
            ));
        }
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !(finite(&a.pod_basis)
            && finite(&a.singular_values)
            && finite(&a.lo)
            && finite(&a.hi)
            && finite(&a.spatial)
            && finite(&a.factors)
            && finite(&a.ritz_v)
            && finite(&a.ritz_k)
            && finite(&a.ritz_b))
            || a.lo.iter().zip(&a.hi).any(|(l, h)| l >= h)
        {
            return Err("tearing arrays hold non-finite values or an empty coefficient range".into());
        }
        let force_error = calibration_table("force_error", &a.force_error)?;
        let fallback = if a.fallback_modes.is_empty() {
            None
        } else {
            let fits = a.fallback_modes.len() == a.patterns.len()
                && a.fallback_modes.iter().zip(&a.patterns).all(|(&k, &n)| k >= 1 && k <= n)
                && a.fallback_modes.iter().sum::<usize>() < a.n_modes;
            if !fits {
                return Err(format!(
                    "tearing array fallback_modes {:?} is not fewer modes of the pull patterns {:?}; rebuild the bundle with `vademecum build`",
                    a.fallback_modes, a.patterns
                ));
            }
            Some(TearFallback {
                modes: a.fallback_modes,
                force_error: calibration_table("fallback_force_error", &a.fallback_force_error)?,
            })
        };
        let basis = DamageBasis {
            pod: Pod {
                n: nt,
                modes: q,
                basis: a.pod_basis,
                singular_values: a.singular_values,
                captured: a.captured,
            },
            lo: a.lo.clone(),
            hi: a.hi.clone(),
        };
        let vademecum = DamageVademecum {
            n_free: nf,
            q,
            grid: a.grid,
            lo: a.lo,
            hi: a.hi,
            n_modes: a.n_modes,
            spatial: a.spatial,
            factors: a.factors,
            patterns: a.patterns,
            report: VademecumReport {
                modes: a.n_modes,
                amplitudes: Vec::new(),
                iterations: Vec::new(),
                nonpositive: false,
                seconds: 0.0,
            },
        };
        let mm = a.m * a.m;
        let ritz = RitzOperator {
            m: a.m,
            v: a.ritz_v,
            k: a.ritz_k.chunks_exact(mm).map(<[f64]>::to_vec).collect(),
            b: a.ritz_b.chunks_exact(a.m).map(<[f64]>::to_vec).collect(),
        };
        let mut off = Self::new(model, basis, vademecum, ritz);
        off.force_error = force_error;
        off.fallback = fallback;
        Ok(off)
    }
}

/// A force-error calibration read from the flattened array `name`: `[level, error]` rows,
/// levels positive and increasing, errors finite, non-negative and non-decreasing.
fn calibration_table(name: &str, flat: &[f64]) -> Result<Vec<[f64; 2]>, String> {
    let table: Vec<[f64; 2]> = flat.chunks_exact(2).map(|r| [r[0], r[1]]).collect();
    let increasing = table.windows(2).all(|w| w[1][0] > w[0][0] && w[1][1] >= w[0][1]);
    if !flat.len().is_multiple_of(2)
        || !increasing
        || table
            .iter()
            .any(|r| !(r[0] > 0.0 && r[0].is_finite() && r[1] >= 0.0 && r[1].is_finite()))
    {
        return Err(format!(
            "tearing array {name} is not a table of increasing load levels and non-decreasing errors; rebuild the bundle with `vademecum build`"
        ));
    }
    Ok(table)
}
