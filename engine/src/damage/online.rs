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
    /// Orthonormalises the vademecum's spatial modes (modified Gram–Schmidt, twice; modes
    /// dependent to 10⁻¹⁰ dropped) and reduces the affine system on them.
    pub fn new(vad: &DamageVademecum, sys: &AffineSystem) -> Self {
        let nf = vad.n_free;
        let mut cols: Vec<Vec<f64>> = Vec::new();
        let scale = (0..vad.n_modes).map(|i| norm(vad.mode(i))).fold(0.0, f64::max);
        for i in 0..vad.n_modes {
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
        let b = sys
            .rhs
            .iter()
            .map(|bj| cols.iter().map(|c| c.iter().zip(bj).map(|(a, b)| a * b).sum()).collect())
            .collect();
        Self { m, v, k, b }
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

/// The POD–PGD integrator's state.
#[derive(Debug, Clone)]
pub struct OnlineTear {
    off: Arc<TearOffline>,
    variant: Variant,
    limits: StepLimits,
    /// The damage state of every point.
    pub state: Vec<PointState>,
    /// The displacement (m, full length).
    pub u: Vec<f64>,
    sigma0: Vec<Sym>,
    saved_state: Vec<PointState>,
    saved_u: Vec<f64>,
    saved_sigma0: Vec<Sym>,
    g: Vec<f64>,
    xi: Vec<f64>,
    a: Vec<f64>,
    du: Vec<f64>,
    du_full: Vec<f64>,
    mat: Vec<f64>,
    rhs: Vec<f64>,
    y: Vec<f64>,
    bv: Vec<f64>,
    eqs: Vec<Option<usize>>,
    /// Energy dissipated so far (J).
    pub dissipated: f64,
}

impl OnlineTear {
    /// A virgin integrator.
    pub fn new(off: Arc<TearOffline>, variant: Variant, limits: StepLimits) -> Self {
        let m = &off.model;
        let (np, nd) = (m.points.len(), 3 * m.mesh.n_nodes());
        let nf = m.dofs.n_free();
        let q = off.basis.len();
        let r = off.ritz.m;
        let nodal = 3 * m.points.nodes_per_cell;
        Self {
            variant,
            limits,
            state: m.virgin(),
            u: vec![0.0; nd],
            sigma0: vec![[0.0; 6]; np],
            saved_state: m.virgin(),
            saved_u: vec![0.0; nd],
            saved_sigma0: vec![[0.0; 6]; np],
            g: vec![1.0; m.points.tearable.len()],
            xi: vec![0.0; q],
            a: vec![0.0; off.vademecum.n_modes.max(r)],
            du: vec![0.0; nf],
            du_full: vec![0.0; nd],
            mat: vec![0.0; r * r],
            rhs: vec![0.0; r],
            y: vec![0.0; r],
            bv: vec![0.0; nodal],
            eqs: vec![None; nodal],
            dissipated: 0.0,
            off,
        }
    }

    /// The offline data.
    pub fn offline(&self) -> &TearOffline {
        &self.off
    }

    /// The last POD coefficients.
    pub fn xi(&self) -> &[f64] {
        &self.xi
    }

    /// One pseudo-time step of multiplier `ds` of the model's unit increment (Alg. 4.2, lines
    /// 3–8), split into sub-steps while it damages too fast.
    pub fn step(&mut self, ds: f64) -> OnlineStep {
        self.saved_state.copy_from_slice(&self.state);
        self.saved_u.copy_from_slice(&self.u);
        self.saved_sigma0.copy_from_slice(&self.sigma0);
        let mut n = 1u32;
        loop {
            let mut out = OnlineStep {
                substeps: n,
                ..OnlineStep::default()
            };
            for _ in 0..n {
                let s = self.substep(ds / n as f64);
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
            self.sigma0.copy_from_slice(&self.saved_sigma0);
            n *= 2;
        }
    }

    fn substep(&mut self, ds: f64) -> OnlineStep {
        let off = Arc::clone(&self.off);
        let m = &off.model;
        let mut out = OnlineStep::default();
        for (gi, &p) in self.g.iter_mut().zip(&m.points.tearable) {
            *gi = self.state[p].g;
        }
        out.outside = off.basis.project(&self.g, &mut self.xi);
        match self.variant {
            Variant::Simplified => {
                let nm = off.vademecum.n_modes;
                out.clamped = off.vademecum.coefficients(&self.xi, &mut self.a[..nm]);
                off.vademecum.combine(&self.a[..nm], &mut self.du);
            }
            Variant::Full => {
                if !self.ritz_solve(&off, true) {
                    out.secant_fallback = true;
                    if !self.ritz_solve(&off, false) {
                        // not even the secant part is positive on the basis: the vademecum
                        let nm = off.vademecum.n_modes;
                        out.clamped = off.vademecum.coefficients(&self.xi, &mut self.a[..nm]);
                        off.vademecum.combine(&self.a[..nm], &mut self.du);
                    }
                }
            }
        }
        for (d, v) in self.du_full.iter_mut().enumerate() {
            *v = match m.dofs.eq(d) {
                Some(e) => ds * self.du[e],
                None => ds * m.prescribed[d],
            };
        }
        for (u, d) in self.u.iter_mut().zip(&self.du_full) {
            *u += d;
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

    /// The Ritz solve into `du`, with the loading points' rank-one terms when `tangent`.
    /// Returns whether the reduced matrix was positive definite.
    fn ritz_solve(&mut self, off: &TearOffline, tangent: bool) -> bool {
        let (ritz, m) = (&off.ritz, &off.model);
        let r = ritz.m;
        self.mat.copy_from_slice(&ritz.k[0]);
        self.rhs.copy_from_slice(&ritz.b[0]);
        for (k, &x) in self.xi.iter().enumerate() {
            for (a, b) in self.mat.iter_mut().zip(&ritz.k[k + 1]) {
                *a += x * b;
            }
            for (a, b) in self.rhs.iter_mut().zip(&ritz.b[k + 1]) {
                *a += x * b;
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
        self.du.fill(0.0);
        for (e, d) in self.du.iter_mut().enumerate() {
            let row = &ritz.v[e * r..(e + 1) * r];
            *d = row.iter().zip(&self.rhs).map(|(a, b)| a * b).sum();
        }
        true
    }
}
