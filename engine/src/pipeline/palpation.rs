//! Palpation with a linear PGD vademecum (seed 000 ch. 2): a spherical tip pressing on each
//! organ's surface, tracked by a proxy that never lets go ([`crate::contact`]).
//!
//! Each tick, for every organ: the proxy follows the tip over the organ's whole surface (the
//! deepest contact wins), then the force on the tissue for the imposed surface displacement
//! `δ = −depth · n(s)` at the proxy s:
//!
//! - on the accessible surface (every node of the triangle loadable), `f = C(s)⁻¹δ` with the
//!   vademecum's compliance `C(s)` (exact local 3×3 blocks interpolated over the triangle);
//! - where the surface reaches nodes the vademecum cannot load (the fixed face, the parts
//!   outside the accessible region), the organ lies on its rigid support: with λ the weight of
//!   the loadable nodes at s and s_L the point of their edge or vertex they span,
//!   `f = [λ C(s_L)⁻¹ + (1 − λ) k_w I] δ`, where the support stiffness `k_w` is the stiffest
//!   the organ gets at any loadable node (`max_a 1/λ_min(C(a))`). At λ = 1 this is the
//!   accessible law and at λ = 0 a wall, so the force is continuous everywhere on the surface.
//!
//! The force on the tool is the reaction `−f`. With large deformations
//! (`effects.deformation = "large"`) the tissue's part is scaled by the organ's ANM-POD lattice
//! ([`crate::rom::palpation`]): the ratio of the nonlinear to the linear force at this depth,
//! blended over the four nearest lattice positions — `O(r · order)` per position, no
//! allocation; past the lattice's paths the ratio continues along their last tangent and the
//! tick is flagged `BEYOND_RANGE`. The linear model has no depth range: its force grows
//! linearly with depth until the pipeline saturates it at the probe's `max_force`.
//!
//! # The error estimate of each force
//! Every force comes with an estimate of its error against the full-order model of the same
//! mesh ([`TickState::force_error_n`]): for the linear law, the round-off of the exact local
//! compliances (`LINEAR_RELATIVE_ERROR · |f|`: the force is exact otherwise); with large
//! deformations, the lattice's [`Stiffening::error`] times the linear force — the nonlinear
//! correction's uncertainty growing with the distance to the nearest lattice position at the
//! rate the lattice's leave-one-out calibrated around each position
//! ([`AnmLattice::interpolation_rates`]), plus the
//! path's own error and, past the paths, the nonlinear correction growing at the rate it grew
//! along them. The support's share is
//! the model's wall and carries no error.
//! `vademecum study` checks the estimate against full Newton at nodes off the lattice.
//!
//! [`Stiffening::error`]: crate::rom::palpation::Stiffening::error
//! [`AnmLattice::interpolation_rates`]: crate::rom::palpation::AnmLattice::interpolation_rates

use std::sync::Arc;

use super::{Contact, Effect, Events, Fidelity, TickState, ToolInput};
use crate::bundle::LoadedBundle;
use crate::contact::{Bounds, Proxy, Surface, Touch};
use crate::pgd::Vademecum;

/// One organ as the probe sees it.
#[derive(Debug, Clone)]
struct Organ {
    bundle: Arc<LoadedBundle>,
    surface: Surface,
    bounds: Bounds,
    proxy: Proxy,
    /// The support stiffness `k_w` (N/m).
    wall_stiffness: f64,
    /// The lattice's interpolation rates for its four-position blend and for its nearest
    /// position alone (the reduced fidelity) (large deformations; empty otherwise).
    rates: [Vec<f64>; 2],
}

/// The linear-deformation effect over one vademecum per organ.
#[derive(Debug, Clone)]
pub struct Palpation {
    organs: Vec<Organ>,
    radius_m: f64,
    large: bool,
    scratch: Vec<f64>,
    /// Lattice positions blended: [`NEIGHBOURS`], or 1 at the reduced fidelity.
    neighbours: usize,
}

pub use crate::rom::lattice_check::NEIGHBOURS;

/// The relative error of the linear law's force against the full-order model: the round-off of
/// the exact local compliances (computed by a direct solve; `vademecum study` measures it, at
/// most 1e-11 on the organ, the cornea and the liver).
pub const LINEAR_RELATIVE_ERROR: f64 = 1e-9;

/// The stiffest the organ gets at a loadable node, `max_a 1/λ_min(C(a))` (N/m), 0 if no
/// node is loadable: the support stiffness `k_w`.
pub fn support_stiffness(v: &Vademecum) -> f64 {
    v.load_nodes()
        .iter()
        .filter_map(|&a| v.compliance([a, a, a], [1.0, 0.0, 0.0]))
        .filter_map(|c| {
            let m = nalgebra::Matrix3::from_fn(|i, j| 0.5 * (c[i][j] + c[j][i]));
            let low = m.symmetric_eigenvalues().min();
            (low.is_finite() && low > 0.0).then(|| 1.0 / low)
        })
        .fold(0.0, f64::max)
}

impl Organ {
    fn new(bundle: Arc<LoadedBundle>, large: bool) -> Self {
        let surface = Surface::new(&bundle.nodes, bundle.surface.clone());
        let bounds = Bounds::of(&bundle.nodes, &bundle.surface);
        let wall_stiffness = support_stiffness(&bundle.vademecum);
        let rates = match (&bundle.anm, large) {
            (Some(lattice), true) => [lattice.interpolation_rates(NEIGHBOURS), lattice.interpolation_rates(1)],
            _ => [Vec::new(), Vec::new()],
        };
        Self {
            bundle,
            surface,
            bounds,
            proxy: Proxy::default(),
            wall_stiffness,
            rates,
        }
    }

    /// The force on the tissue at the touch (before any large-deformation scaling) and the
    /// loadable part of it: `(λ, s_L weights, force of the loadable part, force of the
    /// support part)`.
    fn forces(&self, t: &Touch) -> (f64, [f64; 3], [f64; 3], [f64; 3]) {
        let v = &self.bundle.vademecum;
        let delta = t.penetration();
        let w = t.at.weights;
        let mut lambda = 0.0;
        let mut wl = [0.0; 3];
        for a in 0..3 {
            if w[a] != 0.0 && v.is_loadable(t.nodes[a]) {
                wl[a] = w[a];
                lambda += w[a];
            }
        }
        let wall = delta.map(|d| (1.0 - lambda) * self.wall_stiffness * d);
        if lambda <= 0.0 {
            return (0.0, wl, [0.0; 3], wall);
        }
        let wl = wl.map(|x| x / lambda);
        let tissue = match v.compliance(t.nodes, wl) {
            Some(c) => Vademecum::contact_force(&c, delta).map(|f| lambda * f),
            None => [0.0; 3],
        };
        (lambda, wl, tissue, wall)
    }
}

impl Palpation {
    /// Prepares the contact surfaces of `bundles` for a tip of radius `radius_m` (m); with
    /// `large`, every bundle must carry a large-deformation lattice (checked by the pipeline).
    pub fn new(bundles: Vec<Arc<LoadedBundle>>, radius_m: f64, large: bool) -> Self {
        let scratch = vec![
            0.0;
            bundles
                .iter()
                .filter_map(|b| b.anm.as_ref())
                .map(|l| l.max_modes())
                .max()
                .unwrap_or(0)
        ];
        Self {
            organs: bundles.into_iter().map(|b| Organ::new(b, large)).collect(),
            radius_m,
            large,
            scratch,
            neighbours: NEIGHBOURS,
        }
    }
}

impl Effect for Palpation {
    fn name(&self) -> &'static str {
        "palpation"
    }

    /// Each organ's contact surface (triangles, their geometry, the search grid), the
    /// lattice's interpolation rates and the scratch of the lattice blend.
    fn memory_bytes(&self) -> usize {
        crate::memory::vec_bytes(&self.organs)
            + self
                .organs
                .iter()
                .map(|o| o.surface.heap_bytes() + o.rates.iter().map(crate::memory::vec_bytes).sum::<usize>())
                .sum::<usize>()
            + crate::memory::vec_bytes(&self.scratch)
    }

    fn tick(&mut self, tool: &ToolInput, state: &mut TickState) {
        if tool.kind == super::ToolKind::Grasper {
            // the grasper's effect is tearing's; it does not palpate
            return;
        }
        let mut best: Option<(usize, Touch)> = None;
        for (i, o) in self.organs.iter_mut().enumerate() {
            if let Some(t) = o.proxy.update(&o.surface, &o.bounds, tool.contact_point(), self.radius_m)
                && best.is_none_or(|(_, b)| t.depth > b.depth)
            {
                best = Some((i, t));
            }
        }
        let Some((organ, touch)) = best else {
            // no contact: no force, in the full model too
            state.force_error_n = Some(0.0);
            return;
        };
        let o = &self.organs[organ];
        let (lambda, wl, mut tissue, wall) = o.forces(&touch);
        // the loadable point s_L, where the tissue takes its part of the load
        let nodes = &o.bundle.nodes;
        let mut point = [0.0; 3];
        for (a, &w) in touch.nodes.iter().zip(&wl) {
            for k in 0..3 {
                point[k] += w * nodes[*a][k];
            }
        }
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let mut error = LINEAR_RELATIVE_ERROR * norm(tissue);
        if self.large
            && lambda > 0.0
            && let Some(lattice) = &o.bundle.anm
        {
            let s = lattice.stiffness_ratio(point, touch.depth, self.neighbours, &mut self.scratch);
            let rates = &o.rates[usize::from(self.neighbours == 1)];
            error = norm(tissue) * s.error(rates) + LINEAR_RELATIVE_ERROR * s.ratio * norm(tissue);
            tissue = tissue.map(|x| x * s.ratio);
            if s.extrapolated {
                state.events.0 |= Events::BEYOND_RANGE;
            }
        }
        state.force_error_n = Some(error);
        let f = [0, 1, 2].map(|k| tissue[k] + wall[k]);
        state.force_n = [state.force_n[0] - f[0], state.force_n[1] - f[1], state.force_n[2] - f[2]];
        state.contact = Some(Contact {
            organ,
            nodes: touch.nodes,
            weights: wl,
            point_m: if lambda > 0.0 { point } else { touch.at.point },
            proxy_m: touch.at.point,
            depth_m: touch.depth,
            tissue_force_n: tissue,
            loadable: lambda,
            imposed_m: touch.penetration(),
        });
        state.events.0 |= Events::CONTACT;
    }

    fn reset(&mut self) {
        for o in &mut self.organs {
            o.proxy.release();
        }
    }

    /// At [`Fidelity::Reduced`] the large-deformation law takes the lattice's nearest position
    /// alone (one series inversion instead of four); the linear law has no cheaper setting.
    fn set_fidelity(&mut self, fidelity: Fidelity) {
        self.neighbours = match fidelity {
            Fidelity::Full => NEIGHBOURS,
            Fidelity::Reduced => 1,
        };
    }
}
