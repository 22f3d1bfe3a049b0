//! The POD–PGD integrator (seed 000 Alg. 4.2): each pseudo-time step projects the damage on
//! the POD basis, particularises the vademecum at the coefficients `ξ`, adds the increment and
//! updates the damage at the tearable points.
//!
//! # Two variants
//! - [`Variant::Simplified`], the seed's (h = 0, §4.5.3): `∆u = ds · Σ_i F_i Π_K G_K^i(ξ_K)`, the
//!   coefficients clamped to the vademecum's box (and reported when they leave it).
//! - [`Variant::Full`] (h ≠ 0: the seed's future work). The tangent `g C⁰ − (h/r) σ⁰⊗σ⁰` is not
//!   a function of a damage field alone: its second term depends on each loading point's
//!   stress. So the vademecum's modes serve as a Ritz basis `V` (orthonormalised), on which
//!   the affine secant part is exact and precomputed, `VᵀK(ξ)V = Σ_j ξ_j VᵀK_jV`, and the
//!   rank-one terms of the points that loaded at the last step are added at run time:
//!   `[VᵀK(ξ)V − Σ_p w_p (h_p/r_p)(Vᵀ B̄ᵀσ⁰_p)(Vᵀ B̄ᵀσ⁰_p)ᵀ] a = Vᵀb(ξ)`, `∆u = ds · V a`. Here `ξ` is
//!   not clamped (the operator is exact in `ξ`, nothing is tabulated) but still reported when
//!   it leaves the box, where the basis was not trained. If the bordered matrix is not
//!   positive definite (past a stress peak), the step uses the secant part alone (reported).
//!   The basis holds the modes of the pull along the load; the parts of a step across it
//!   come from their vademecums, as in the simplified variant.
//!
//! # Pulls in any direction
//! The vademecum holds, after the modes of the scene's load, those of the same nodes pulled
//! across it ([`super::model::TearModel::pull_load`], built unless `cross_pulls` is off): a
//! step of multipliers `ds = (ds₀, ds₁, ds₂)` adds `Σ_p ds_p Σ_{i ∈ p} a_i F_i`, exact in the
//! load for a given damage (the secant problem is linear in it). The damage basis is the
//! pull along the load's, as the seed's: a pull across damages other points, whose damage
//! the basis projects (`build::pull_errors` measures what that costs).
//!
//! # Only the tearable region each step
//! Damage needs the displacement at the tearable points' nodes only. A step therefore
//! updates the displacement on those dofs (the [`LocalDofs`], restricted copies of the modes)
//! and accumulates the step's modal amplitudes; [`OnlineTear::displacement`] rebuilds the whole
//! field from them when it is asked for (a frame, a recording, a test), exactly the sum of the
//! steps' increments. On the gallbladder this is 2,598 dofs against ~500.
//!
//! # Fast pulls
//! A step that raises some point's damage by more than `max_damage_increment` is redone in
//! 2, 4, … sub-steps, up to `max_substeps`; beyond that it is accepted and reported as too
//! fast. All buffers are allocated at construction: a step allocates nothing.

use std::sync::Arc;

use super::law::PointState;
use super::model::TearModel;
use super::pod::DamageBasis;
use super::points::Sym;
use super::vademecum::{AffineSystem, DamageVademecum};
use crate::dense;

/// Which integrator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// h = 0, the vademecum evaluated (the seed's).
    Simplified,
    /// h ≠ 0, the vademecum's modes as a Ritz basis with the tangent's rank-one terms.
    Full,
}

impl Variant {
    /// A short label.
    pub fn label(self) -> &'static str {
        match self {
            Self::Simplified => "POD–PGD, h = 0",
            Self::Full => "POD–PGD, h ≠ 0",
        }
    }
}

/// The vademecum's modes as an orthonormal Ritz basis with the reduced affine operator.
#[derive(Debug, Clone, PartialEq)]
pub struct RitzOperator {
    /// Basis size `m`.
    pub m: usize,
    /// `V`, row-major `n_free × m`.
    pub v: Vec<f64>,
    /// `VᵀK_jV`, each row-major `m × m`, `j = 0 … q`.
    pub k: Vec<Vec<f64>>,
    /// `Vᵀb_j`.
    pub b: Vec<Vec<f64>>,
}

impl RitzOperator {
    /// Orthonormalises the spatial modes of the vademecum's pull along the load (modified
    /// Gram–Schmidt, twice; modes dependent to 10⁻¹⁰ dropped) and reduces the affine system
    /// on them.
    pub fn new(vad: &DamageVademecum, sys: &AffineSystem) -> Self {
        let nf = vad.n_free;
        let along = vad.patterns[0];
        let mut cols: Vec<Vec<f64>> = Vec::new();
        let scale = (0..along).map(|i| norm(vad.mode(i))).fold(0.0, f64::max);
        for i in 0..along {
            let mut c = vad.mode(i).to_vec();
            for _ in 0..2 {
                for b in &cols {
                    let d: f64 = c.iter().zip(b).map(|(x, y)| x * y).sum();
                    c.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
                }
            }
            let n = norm(&c);
            if n > 1e-10 * scale {
                c.iter_mut().for_each(|x| *x /= n);
                cols.push(c);
            }
        }
        let m = cols.len();
        let mut v = vec![0.0; nf * m];
        for (j, c) in cols.iter().enumerate() {
            for (i, x) in c.iter().enumerate() {
                v[i * m + j] = *x;
            }
        }
        let mut kv = vec![0.0; nf];
        let k = sys
            .ops
            .iter()
            .map(|op| {
                let mut r = vec![0.0; m * m];
                for (j, cj) in cols.iter().enumerate() {
                    op.mul_vec(cj, &mut kv);
                    for (i, ci) in cols.iter().enumerate() {
                        r[i * m + j] = ci.iter().zip(&kv).map(|(a, b)| a * b).sum();
                    }
                }
                r
            })
            .collect();
        let reduce = |bj: &Vec<f64>| -> Vec<f64> { cols.iter().map(|c| c.iter().zip(bj).map(|(a, b)| a * b).sum()).collect() };
        let b = sys.rhs.iter().map(reduce).collect();
        Self { m, v, k, b }
    }
}

/// The dofs of the tearable points' nodes and the loaded dofs, with the vademecum's and the
/// Ritz basis' rows there.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalDofs {
    /// Full dof index of each local dof (sorted).
    pub dofs: Vec<usize>,
    /// Its equation (free) or `None` (constrained, prescribed).
    pub eqs: Vec<Option<usize>>,
    /// `F_i` restricted, row-major `n_modes × n_local`.
    pub modes: Vec<f64>,
    /// `V` restricted, row-major `n_local × m`.
    pub v: Vec<f64>,
}

impl LocalDofs {
    /// The local dofs of `model`'s tearable points.
    pub fn new(model: &TearModel, vad: &DamageVademecum, ritz: &RitzOperator) -> Self {
        let mut dofs: Vec<usize> = model
            .points
            .tearable
            .iter()
            .flat_map(|&p| {
                model
                    .mesh
                    .cell(model.points.cell[p])
                    .iter()
                    .flat_map(|&a| (0..3).map(move |i| 3 * a + i))
            })
            // every dof of the loaded nodes: the grasp's displacement, along and across
            .chain(
                (0..model.load.len())
                    .filter(|&d| model.load[d] != 0.0)
                    .flat_map(|d| (0..3).map(move |i| 3 * (d / 3) + i)),
            )
            .collect();
        dofs.sort_unstable();
        dofs.dedup();
        let eqs: Vec<Option<usize>> = dofs.iter().map(|&d| model.dofs.eq(d)).collect();
        let n = dofs.len();
        let mut modes = vec![0.0; vad.n_modes * n];
        for i in 0..vad.n_modes {
            let f = vad.mode(i);
            for (l, e) in eqs.iter().enumerate() {
                modes[i * n + l] = e.map_or(0.0, |e| f[e]);
            }
        }
        let r = ritz.m;
        let mut v = vec![0.0; n * r];
        for (l, e) in eqs.iter().enumerate() {
            if let Some(e) = e {
                v[l * r..(l + 1) * r].copy_from_slice(&ritz.v[e * r..(e + 1) * r]);
            }
        }
        Self { dofs, eqs, modes, v }
    }

    /// Number of local dofs.
    pub fn len(&self) -> usize {
        self.dofs.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.dofs.is_empty()
    }
}

fn norm(a: &[f64]) -> f64 {
    a.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Everything the online integrator reads: the model, the POD basis, the vademecum and its
/// Ritz form (built offline, shared by sessions).
#[derive(Debug, Clone)]
pub struct TearOffline {
    /// The problem.
    pub model: TearModel,
    /// The damage basis and its coefficient box.
    pub basis: DamageBasis,
    /// The vademecum over the coefficients.
    pub vademecum: DamageVademecum,
    /// The vademecum's modes as a Ritz basis.
    pub ritz: RitzOperator,
    /// The dofs a step updates.
    pub local: LocalDofs,
    /// The pull pattern of each vademecum mode (0: the scene's load; 1, 2: across it).
    pub mode_pattern: Vec<usize>,
    /// The calibrated error of the grasper's force ([`crate::damage::build::force_error_table`]):
    /// rows `[load level, relative error]`, levels increasing, errors non-decreasing. Empty:
    /// no estimate (a bundle built before it, or built without it).
    pub force_error: Vec<[f64; 2]>,
    /// The cheaper setting a session falls back to under load, when the build found one.
    pub fallback: Option<TearFallback>,
}

/// The cheaper setting of tearing a session falls back to under load (the server's fidelity
/// governor, [`crate::pipeline::Fidelity::Reduced`]): the first `modes[p]` modes of each pull
/// pattern `p`, stepped by the simplified integrator — exactly what
/// [`TearOffline::pattern_prefix`] of those modes steps, since a mode's coefficient is its own
/// factors' product — with that prefix's calibrated force error. Chosen by the build
/// ([`crate::damage::build::fallback_for`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TearFallback {
    /// Modes kept per pull pattern: at most the pattern's, fewer in all.
    pub modes: Vec<usize>,
    /// Their calibrated force error, as [`TearOffline::force_error`].
    pub force_error: Vec<[f64; 2]>,
}

/// The relative error at load level `level` of a calibration `table` (rows `[level, error]`):
/// the envelope's value at the first calibrated level at or past `level` (an upper step, so
/// the estimate never interpolates downwards); `None` for an empty table or past its last
/// level (no full-order run went that far).
fn error_at(table: &[[f64; 2]], level: f64) -> Option<f64> {
    let last = table.last()?;
    if level.is_nan() || level > last[0] * (1.0 + 1e-9) {
        return None;
    }
    table.iter().find(|r| r[0] >= level * (1.0 - 1e-9)).map(|r| r[1])
}

/// The relative error of the grasper's force under the load factors `s` from a calibration
/// `table`: [`error_at`] `|s|₂` times `|s|₁ / |s|₂` (see [`TearOffline::force_error_for`]).
fn error_for(table: &[[f64; 2]], s: [f64; 3]) -> Option<f64> {
    let l2 = s.iter().map(|x| x * x).sum::<f64>().sqrt();
    let l1: f64 = s.iter().map(|x| x.abs()).sum();
    if l2.is_nan() || l2 <= 0.0 {
        return None;
    }
    error_at(table, l2).map(|e| e * l1 / l2)
}

impl TearOffline {
    /// The whole displacement field (m) into `out` (length `3 × nodes`) for the accumulated
    /// amplitudes `amp` (no allocation).
    pub fn displacement(&self, amp: &TearAmplitudes, out: &mut [f64]) {
        let m = &self.model;
        let (vad, ritz) = (&self.vademecum, &self.ritz);
        let r = ritz.m;
        let with_ritz = amp.ritz.iter().any(|&a| a != 0.0);
        for (d, o) in out.iter_mut().enumerate() {
            *o = match m.dofs.eq(d) {
                Some(_) if !with_ritz => 0.0,
                Some(e) => {
                    let row = &ritz.v[e * r..(e + 1) * r];
                    row.iter().zip(&amp.ritz).map(|(v, a)| v * a).sum()
                }
                None => amp.load * m.prescribed[d],
            };
        }
        // the vademecum's modes one at a time (each contiguous)
        for (i, &a) in amp.vad.iter().enumerate().take(vad.n_modes) {
            if a == 0.0 {
                continue;
            }
            let f = vad.mode(i);
            for (d, o) in out.iter_mut().enumerate() {
                if let Some(e) = m.dofs.eq(d) {
                    *o += a * f[e];
                }
            }
        }
    }

    /// Pull patterns the vademecum holds: 1 (along the scene's load only) or 3 (and across).
    pub fn patterns(&self) -> usize {
        self.vademecum.patterns.len()
    }

    /// Bytes of the modes, factors, Ritz operator and local rows (shared by sessions; the
    /// model's mesh and points not counted).
    pub fn memory_bytes(&self) -> usize {
        let v = &self.vademecum;
        let r = &self.ritz;
        let l = &self.local;
        8 * (v.spatial.len()
            + v.factors.len()
            + r.v.len()
            + r.k.iter().map(Vec::len).sum::<usize>()
            + r.b.iter().map(Vec::len).sum::<usize>()
            + l.modes.len()
            + l.v.len()
            + self.basis.pod.modes * self.model.points.tearable.len())
    }

    /// Assembles the offline data (computes the local dofs).
    pub fn new(model: TearModel, basis: DamageBasis, vademecum: DamageVademecum, ritz: RitzOperator) -> Self {
        let local = LocalDofs::new(&model, &vademecum, &ritz);
        let mode_pattern = vademecum.mode_patterns();
        Self {
            model,
            basis,
            vademecum,
            ritz,
            local,
            mode_pattern,
            force_error: Vec::new(),
            fallback: None,
        }
    }

    /// The vademecum's coefficients at `xi` into `a` (length `n_modes`), as
    /// [`DamageVademecum::coefficients`]; `reduced` with a [`Self::fallback`]: those of its
    /// modes only, the others zero (and not evaluated). Returns whether some coefficient was
    /// clamped. No allocation.
    pub fn coefficients(&self, xi: &[f64], a: &mut [f64], reduced: bool) -> bool {
        let vad = &self.vademecum;
        let Some(fallback) = self.fallback.as_ref().filter(|_| reduced) else {
            return vad.coefficients(xi, a);
        };
        a.fill(0.0);
        let (mut first, mut clamped) = (0, false);
        for (&n, &keep) in vad.patterns.iter().zip(&fallback.modes) {
            clamped |= vad.coefficients_from(xi, first, &mut a[first..first + keep.min(n)]);
            first += n;
        }
        clamped
    }

    /// The first `keep[p]` modes of each pull pattern `p`
    /// ([`DamageVademecum::pattern_prefix`](super::vademecum::DamageVademecum::pattern_prefix))
    /// with a Ritz basis of their own on `sys` (the affine system of this model and basis,
    /// [`super::vademecum::AffineSystem::of`]); no force-error calibration (it needs the
    /// full-order runs: [`crate::damage::build::Calibration`]).
    pub fn pattern_prefix(&self, keep: &[usize], sys: &super::vademecum::AffineSystem) -> Self {
        let vad = self.vademecum.pattern_prefix(keep);
        let ritz = RitzOperator::new(&vad, sys);
        Self::new(self.model.clone(), self.basis.clone(), vad, ritz)
    }

    /// The relative error of the grasper's force at load level `level` (`|s|`, unit steps)
    /// from [`Self::force_error`]: the envelope's value at the first calibrated level at or
    /// past `level` (an upper step, so the estimate never interpolates downwards); `None`
    /// without a calibration or past its last level (no full-order run went that far).
    pub fn force_error_at(&self, level: f64) -> Option<f64> {
        error_at(&self.force_error, level)
    }

    /// The relative error of the grasper's force under the load factors `s` (along the load
    /// and across it): [`Self::force_error_at`] `|s|₂` times `|s|₁ / |s|₂`. The calibration
    /// pulls along each direction and the diagonals; where the response is linear the errors
    /// of a mixed pull superpose, `|Σ_p s_p ε_p| ≤ |s|₁ max_p |ε_p|`, a bound the factor (at most √3)
    /// keeps. `None` as [`Self::force_error_at`], and for no load.
    pub fn force_error_for(&self, s: [f64; 3]) -> Option<f64> {
        error_for(&self.force_error, s)
    }
}

/// Limits on how fast the damage may grow in one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepLimits {
    /// Largest damage increment of a (sub)step before it is split.
    pub max_damage_increment: f64,
    /// Most sub-steps (a power of two).
    pub max_substeps: u32,
}

impl Default for StepLimits {
    /// ΔD ≤ 0.1 per sub-step, at most 8 sub-steps.
    fn default() -> Self {
        Self {
            max_damage_increment: 0.1,
            max_substeps: 8,
        }
    }
}

/// What one online step did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OnlineStep {
    /// Some coefficient lay outside the vademecum's box.
    pub outside: bool,
    /// It was clamped to the box (simplified variant).
    pub clamped: bool,
    /// The bordered tangent was not positive definite; the secant part was used.
    pub secant_fallback: bool,
    /// Sub-steps taken.
    pub substeps: u32,
    /// Even the most sub-steps raised the damage faster than the limit.
    pub too_fast: bool,
    /// Energy dissipated in the step (J).
    pub dissipated: f64,
    /// Largest damage increment of a sub-step.
    pub max_damage_increment: f64,
}

/// Accumulated modal amplitudes, from which the whole displacement is rebuilt:
/// `u = Σ_i vad_i F_i + V ritz` on the free dofs, `load · ū` on the prescribed ones.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TearAmplitudes {
    /// `Σ ds·a_i` of the vademecum's modes.
    pub vad: Vec<f64>,
    /// `Σ ds·a` of the Ritz basis.
    pub ritz: Vec<f64>,
    /// `Σ ds₀`: the load factor reached along the scene's load (the prescribed part's).
    pub load: f64,
}

impl TearAmplitudes {
    /// Zero amplitudes for `off`.
    pub fn zero(off: &TearOffline) -> Self {
        Self {
            vad: vec![0.0; off.vademecum.n_modes],
            ritz: vec![0.0; off.ritz.m],
            load: 0.0,
        }
    }

    /// Copies `o` without allocating; `self` may be longer (amplitudes sized for the largest
    /// of several vademecums: the rest is zeroed).
    pub fn copy_from(&mut self, o: &Self) {
        self.vad[..o.vad.len()].copy_from_slice(&o.vad);
        self.vad[o.vad.len()..].fill(0.0);
        self.ritz[..o.ritz.len()].copy_from_slice(&o.ritz);
        self.ritz[o.ritz.len()..].fill(0.0);
        self.load = o.load;
    }
}

/// The POD–PGD integrator's state.
#[derive(Debug, Clone)]
pub struct OnlineTear {
    off: Arc<TearOffline>,
    variant: Variant,
    limits: StepLimits,
    /// The damage state of every point.
    pub state: Vec<PointState>,
    /// The displacement, full length but current on the local dofs only.
    u: Vec<f64>,
    /// `Σ ds·a` of the vademecum's modes, of the Ritz basis, and `Σ ds` (the prescribed part).
    amplitudes: TearAmplitudes,
    sigma0: Vec<Sym>,
    saved_state: Vec<PointState>,
    saved_u: Vec<f64>,
    saved_amplitudes: TearAmplitudes,
    saved_sigma0: Vec<Sym>,
    g: Vec<f64>,
    xi: Vec<f64>,
    a: Vec<f64>,
    /// The vademecum's coefficients at the current damage ([`Self::refresh_coefficients`]).
    coef: Vec<f64>,
    du: Vec<f64>,
    mat: Vec<f64>,
    rhs: Vec<f64>,
    y: Vec<f64>,
    bv: Vec<f64>,
    eqs: Vec<Option<usize>>,
    /// Energy dissipated so far (J).
    pub dissipated: f64,
    /// Stepping the cheaper setting ([`Self::set_reduced`]).
    reduced: bool,
    /// How far the damage the grasp took hold of lies outside what the basis represents
    /// ([`Self::hold`]).
    inherited: f64,
    /// The same of virgin tissue, which the calibration's errors include.
    baseline: f64,
}

impl OnlineTear {
    /// Bytes of its state and working arrays (the offline data it reads are shared).
    pub fn heap_bytes(&self) -> usize {
        use crate::memory::vec_bytes;
        let amplitudes = |a: &TearAmplitudes| vec_bytes(&a.vad) + vec_bytes(&a.ritz);
        vec_bytes(&self.state)
            + vec_bytes(&self.u)
            + amplitudes(&self.amplitudes)
            + vec_bytes(&self.sigma0)
            + vec_bytes(&self.saved_state)
            + vec_bytes(&self.saved_u)
            + amplitudes(&self.saved_amplitudes)
            + vec_bytes(&self.saved_sigma0)
            + [
                &self.g, &self.xi, &self.a, &self.coef, &self.du, &self.mat, &self.rhs, &self.y, &self.bv,
            ]
            .into_iter()
            .map(vec_bytes)
            .sum::<usize>()
            + vec_bytes(&self.eqs)
    }

    /// A virgin integrator.
    pub fn new(off: Arc<TearOffline>, variant: Variant, limits: StepLimits) -> Self {
        let m = &off.model;
        let (np, nd) = (m.points.len(), 3 * m.mesh.n_nodes());
        let nf = m.dofs.n_free();
        let q = off.basis.len();
        let r = off.ritz.m;
        let nodal = 3 * m.points.nodes_per_cell;
        let amplitudes = TearAmplitudes::zero(&off);
        let mut this = Self {
            variant,
            limits,
            state: m.virgin(),
            u: vec![0.0; nd],
            sigma0: vec![[0.0; 6]; np],
            saved_state: m.virgin(),
            saved_u: vec![0.0; nd],
            saved_amplitudes: amplitudes.clone(),
            amplitudes,
            saved_sigma0: vec![[0.0; 6]; np],
            g: vec![1.0; m.points.tearable.len()],
            xi: vec![0.0; q],
            a: vec![0.0; off.vademecum.n_modes.max(r)],
            coef: vec![0.0; off.vademecum.n_modes],
            du: vec![0.0; nf.max(off.local.len())],
            mat: vec![0.0; r * r],
            rhs: vec![0.0; r],
            y: vec![0.0; r],
            bv: vec![0.0; nodal],
            eqs: vec![None; nodal],
            dissipated: 0.0,
            reduced: false,
            inherited: 0.0,
            baseline: 0.0,
            off,
        };
        this.baseline = this.unrepresented();
        this
    }

    /// Steps the cheaper setting from now on (`reduced`), or the scene's: the simplified
    /// integrator on the [`TearOffline::fallback`]'s modes (all the modes without one) — the
    /// state, the displacement and the amplitudes carry on, so the force does not jump; the
    /// modes left out keep what they accumulated and stop growing. No allocation.
    pub fn set_reduced(&mut self, reduced: bool) {
        self.reduced = reduced;
    }

    /// The relative error of the grasper's force under the load factors `s`: the calibration
    /// of the setting it steps ([`TearOffline::force_error_for`], or the fallback's while
    /// reduced: [`Self::set_reduced`]) plus the damage the grasp took hold of that the basis
    /// does not represent ([`Self::hold`]) — the calibration starts from virgin tissue or
    /// from damage the site's own pull along its load made, which the basis holds.
    pub fn force_error_for(&self, s: [f64; 3]) -> Option<f64> {
        let calibrated = match (&self.off.fallback, self.reduced) {
            (Some(f), true) => error_for(&f.force_error, s),
            _ => self.off.force_error_for(s),
        };
        calibrated.map(|e| e + self.inherited)
    }

    /// Records, as a grasp takes hold of the tissue at rest, how far its damage lies outside
    /// what the vademecum sees, as a relative error of the grasp's stiffness
    /// (`unrepresented`, below) beyond that of virgin tissue, which the calibration's errors
    /// already include: [`Self::force_error_for`] adds it. Zero up to the basis's truncation
    /// on virgin tissue or the damage the site's own pull along its load made (the
    /// snapshots'); it matters for damage another site's pull made, or a pull across the
    /// load. Returns it; no allocation.
    pub fn hold(&mut self) -> f64 {
        for (gi, &p) in self.g.iter_mut().zip(&self.off.model.points.tearable) {
            *gi = self.state[p].g;
        }
        self.inherited = (self.unrepresented() - self.baseline).max(0.0);
        self.inherited
    }

    /// The relative error of the grasp's stiffness that the damage `self.g` (the tearable
    /// points' stiffness factors) makes outside the basis. The vademecum's stiffness is affine
    /// in the basis's `g̃ = Σ ξ_K υ_K` at the projection of `g` clamped to the box, the full
    /// model's in `g` itself: `K(g) − K(g̃) = Σ_p (g_p − g̃_p) K_p`. For each pull pattern,
    /// with `u` the vademecum's response to a unit step of it at this damage and
    /// `e_p = w_p Φ_p(u)²` point `p`'s share of the strain energy, the grasp's stiffness
    /// along `u` differs by `ρ = Σ_p |g_p − g̃_p| e_p / Σ_p g̃_p e_p` (the Rayleigh quotient;
    /// the rest of the organ left out of the denominator, so larger than the change). The
    /// largest over the patterns. No allocation (the step's saved displacement is the
    /// scratch: a step sets it before use).
    fn unrepresented(&mut self) -> f64 {
        let off = Arc::clone(&self.off);
        let (m, basis, local) = (&off.model, &off.basis, &off.local);
        basis.project(&self.g, &mut self.xi);
        for (k, x) in self.xi.iter_mut().enumerate() {
            *x = x.clamp(basis.lo[k], basis.hi[k]);
        }
        let nm = off.vademecum.n_modes;
        off.coefficients(&self.xi, &mut self.coef[..nm], self.reduced);
        let nl = local.len();
        let mut worst: f64 = 0.0;
        for pattern in 0..off.patterns() {
            let u = &mut self.saved_u;
            for (l, &d) in local.dofs.iter().enumerate() {
                u[d] = match local.eqs[l] {
                    None if pattern == 0 => m.prescribed[d],
                    _ => 0.0,
                };
            }
            for i in (0..nm).filter(|&i| off.mode_pattern[i] == pattern) {
                let w = self.coef[i];
                for (l, f) in local.modes[i * nl..(i + 1) * nl].iter().enumerate() {
                    if local.eqs[l].is_some() {
                        u[local.dofs[l]] += w * f;
                    }
                }
            }
            let (mut changed, mut kept) = (0.0, 0.0);
            for (i, &p) in m.points.tearable.iter().enumerate() {
                let (phi, _) = m.points.phi(&m.mesh, p, u);
                let e = m.points.weight[p] * phi * phi;
                let lifted = basis.lift_at(&self.xi, i);
                changed += (self.g[i] - lifted).abs() * e;
                kept += lifted.max(0.0) * e;
            }
            if kept > 0.0 {
                worst = worst.max(changed / kept);
            }
        }
        worst
    }

    /// The last [`Self::hold`]'s `ρ` (zero before any).
    pub fn inherited(&self) -> f64 {
        self.inherited
    }

    /// Takes over the damage of `other` (an integrator of the same model with another
    /// vademecum: another grasp site) at rest: its points' states and dissipated energy, the
    /// displacement zero (the secant model's equilibrium under no load). Used when the grasp
    /// moves to another site once the last one's load has faded; no allocation.
    pub fn take_over(&mut self, other: &OnlineTear) {
        self.state.copy_from_slice(&other.state);
        self.dissipated = other.dissipated;
        self.u.fill(0.0);
        self.sigma0.fill([0.0; 6]);
        self.amplitudes.vad.fill(0.0);
        self.amplitudes.ritz.fill(0.0);
        self.amplitudes.load = 0.0;
    }

    /// The offline data.
    pub fn offline(&self) -> &TearOffline {
        &self.off
    }

    /// The whole displacement field (m) into `out` (length `3 × nodes`): the sum of the
    /// steps' increments, rebuilt from the accumulated modal amplitudes (no allocation).
    pub fn displacement(&self, out: &mut [f64]) {
        self.off.displacement(&self.amplitudes, out);
    }

    /// The accumulated modal amplitudes (what a frame needs to rebuild the field).
    pub fn amplitudes(&self) -> &TearAmplitudes {
        &self.amplitudes
    }

    /// The current displacement of dof `d`, exact on the [`LocalDofs`] (the tearable region
    /// and the loaded dofs); elsewhere, see [`Self::displacement`].
    pub fn local_u(&self, d: usize) -> f64 {
        self.u[d]
    }

    /// Bytes of this integrator's own buffers (per session; the offline data is shared).
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        let f = size_of::<f64>();
        let states = 2 * self.state.len() * size_of::<PointState>() + 2 * self.sigma0.len() * size_of::<Sym>();
        let vectors = 2 * self.u.len()
            + 2 * (self.amplitudes.vad.len() + self.amplitudes.ritz.len())
            + self.g.len()
            + self.xi.len()
            + self.a.len()
            + self.coef.len()
            + self.du.len()
            + self.mat.len()
            + self.rhs.len()
            + self.y.len()
            + self.bv.len();
        states + f * vectors + self.eqs.len() * size_of::<Option<usize>>()
    }

    /// [`Self::displacement`] into a new vector.
    pub fn displacement_vec(&self) -> Vec<f64> {
        let mut u = vec![0.0; 3 * self.off.model.mesh.n_nodes()];
        self.displacement(&mut u);
        u
    }

    /// The last POD coefficients.
    pub fn xi(&self) -> &[f64] {
        &self.xi
    }

    /// One pseudo-time step of multiplier `ds` of the model's unit increment (Alg. 4.2, lines
    /// 3–8), split into sub-steps while it damages too fast.
    pub fn step(&mut self, ds: f64) -> OnlineStep {
        self.step_pull([ds, 0.0, 0.0])
    }

    /// One pseudo-time step of multipliers `ds` of the pull patterns' unit increments (the
    /// scene's load, then across it: [`TearModel::pull_load`]); the cross parts are ignored
    /// by a vademecum built without them ([`TearOffline::patterns`]). Sub-steps as
    /// [`Self::step`].
    pub fn step_pull(&mut self, ds: [f64; 3]) -> OnlineStep {
        self.saved_state.copy_from_slice(&self.state);
        self.saved_u.copy_from_slice(&self.u);
        self.saved_amplitudes.copy_from(&self.amplitudes);
        self.saved_sigma0.copy_from_slice(&self.sigma0);
        let mut n = 1u32;
        loop {
            let mut out = OnlineStep {
                substeps: n,
                ..OnlineStep::default()
            };
            for _ in 0..n {
                let s = self.substep(ds.map(|d| d / n as f64));
                out.outside |= s.outside;
                out.clamped |= s.clamped;
                out.secant_fallback |= s.secant_fallback;
                out.dissipated += s.dissipated;
                out.max_damage_increment = out.max_damage_increment.max(s.max_damage_increment);
            }
            if out.max_damage_increment <= self.limits.max_damage_increment {
                self.dissipated += out.dissipated;
                return out;
            }
            if 2 * n > self.limits.max_substeps {
                out.too_fast = true;
                self.dissipated += out.dissipated;
                return out;
            }
            self.state.copy_from_slice(&self.saved_state);
            self.u.copy_from_slice(&self.saved_u);
            self.amplitudes.copy_from(&self.saved_amplitudes);
            self.sigma0.copy_from_slice(&self.saved_sigma0);
            n *= 2;
        }
    }

    fn substep(&mut self, ds: [f64; 3]) -> OnlineStep {
        let off = Arc::clone(&self.off);
        let m = &off.model;
        let mut out = OnlineStep::default();
        for (gi, &p) in self.g.iter_mut().zip(&m.points.tearable) {
            *gi = self.state[p].g;
        }
        out.outside = off.basis.project(&self.g, &mut self.xi);
        let local = &off.local;
        let nl = local.len();
        // adds to ∆u on the local dofs the vademecum's modes from `first` on,
        // Σ_p ds_p Σ_{i ∈ p} a_i F_i (`a` then holds the coefficients)
        let vademecum = |this: &mut Self, out: &mut OnlineStep, first: usize| {
            let nm = off.vademecum.n_modes;
            out.clamped |= off.coefficients(&this.xi, &mut this.a[..nm], this.reduced);
            for (i, &ai) in this.a[..nm].iter().enumerate().skip(first) {
                let w = ds[off.mode_pattern[i]] * ai;
                if w == 0.0 {
                    continue; // a pattern this step does not pull (most steps pull along only)
                }
                this.amplitudes.vad[i] += w;
                for (o, f) in this.du[..nl].iter_mut().zip(&local.modes[i * nl..(i + 1) * nl]) {
                    *o += w * f;
                }
            }
        };
        match if self.reduced { Variant::Simplified } else { self.variant } {
            Variant::Simplified => {
                self.du[..nl].fill(0.0);
                vademecum(self, &mut out, 0);
            }
            Variant::Full => {
                let solved = self.ritz_solve(&off, ds[0], true) || {
                    out.secant_fallback = true;
                    self.ritz_solve(&off, ds[0], false)
                };
                if solved {
                    // ∆u on the local dofs, V a
                    let r = off.ritz.m;
                    for (l, o) in self.du[..nl].iter_mut().enumerate() {
                        let row = &local.v[l * r..(l + 1) * r];
                        *o = row.iter().zip(&self.a[..r]).map(|(v, a)| v * a).sum();
                    }
                    for (acc, a) in self.amplitudes.ritz.iter_mut().zip(&self.a[..r]) {
                        *acc += a;
                    }
                    // the pulls across the load: their vademecums (secant, h = 0)
                    if ds[1] != 0.0 || ds[2] != 0.0 {
                        vademecum(self, &mut out, off.vademecum.patterns[0]);
                    }
                } else {
                    // not even the secant part is positive on the basis: the vademecum
                    self.du[..nl].fill(0.0);
                    vademecum(self, &mut out, 0);
                }
            }
        }
        self.amplitudes.load += ds[0];
        for (l, &d) in local.dofs.iter().enumerate() {
            self.u[d] += match local.eqs[l] {
                Some(_) => self.du[l],
                None => ds[0] * m.prescribed[d],
            };
        }
        for &p in &m.points.tearable {
            let (phi, s) = m.points.phi(&m.mesh, p, &self.u);
            self.sigma0[p] = s;
            let law = m.points.law[p].as_ref().expect("tearable");
            let g0 = self.state[p].g;
            out.dissipated += m.points.weight[p] * self.state[p].update(law, phi);
            out.max_damage_increment = out.max_damage_increment.max(g0 - self.state[p].g);
        }
        out
    }

    /// The vademecum's coefficients `Π_K G_K^i(ξ_K)` at the current damage (its POD
    /// projection, clamped to the box), for the grasp's compliance: pattern `p`'s unit step
    /// moves the displacement by `Σ_{i ∈ p} coef_i F_i`. No allocation.
    pub fn refresh_coefficients(&mut self) -> &[f64] {
        let m = &self.off.model;
        for (gi, &p) in self.g.iter_mut().zip(&m.points.tearable) {
            *gi = self.state[p].g;
        }
        self.off.basis.project(&self.g, &mut self.xi);
        self.off.coefficients(&self.xi, &mut self.coef, self.reduced);
        &self.coef
    }

    /// The Ritz solve of the increment of the pull along the load (multiplier `ds0`) into
    /// `a[..m]`, with the loading points' rank-one terms when `tangent`. Returns whether the
    /// reduced matrix was positive definite.
    fn ritz_solve(&mut self, off: &TearOffline, ds0: f64, tangent: bool) -> bool {
        let (ritz, m) = (&off.ritz, &off.model);
        let r = ritz.m;
        self.mat.copy_from_slice(&ritz.k[0]);
        for (a, b) in self.rhs.iter_mut().zip(&ritz.b[0]) {
            *a = ds0 * b;
        }
        for (k, &x) in self.xi.iter().enumerate() {
            for (a, b) in self.mat.iter_mut().zip(&ritz.k[k + 1]) {
                *a += x * b;
            }
            for (a, b) in self.rhs.iter_mut().zip(&ritz.b[k + 1]) {
                *a += ds0 * x * b;
            }
        }
        if tangent {
            for &p in &m.points.tearable {
                let st = self.state[p];
                if st.h <= 0.0 || st.r <= 0.0 {
                    continue;
                }
                m.points.b_transpose(p, &self.sigma0[p], &mut self.bv);
                let cell = m.mesh.cell(m.points.cell[p]);
                for (a, &node) in cell.iter().enumerate() {
                    for i in 0..3 {
                        self.eqs[3 * a + i] = m.dofs.eq(3 * node + i);
                    }
                }
                self.y.fill(0.0);
                for (l, e) in self.eqs.iter().enumerate() {
                    if let Some(e) = e {
                        let row = &ritz.v[e * r..(e + 1) * r];
                        for (y, v) in self.y.iter_mut().zip(row) {
                            *y += self.bv[l] * v;
                        }
                    }
                }
                let c = m.points.weight[p] * st.h / st.r;
                for i in 0..r {
                    for j in 0..r {
                        self.mat[i * r + j] -= c * self.y[i] * self.y[j];
                    }
                }
            }
        }
        if dense::cholesky(&mut self.mat, r).is_err() {
            return false;
        }
        dense::cholesky_solve(&self.mat, r, &mut self.rhs);
        self.a[..r].copy_from_slice(&self.rhs);
        true
    }
}
