//! Palpation with a linear PGD vademecum (seed 000 ch. 2): a spherical tip pressing on each
//! organ's surface, tracked by a proxy that never lets go ([`crate::contact`]).
//!
//! Each tick, for every organ: the proxy follows the tip over the organ's whole surface (the
//! deepest contact wins), then the force on the tissue for the imposed surface displacement
//! `δ = −depth · n(s)` at the proxy s:
//!
//! - on the accessible surface (every node of the triangle loadable), `f = K(s)δ` with the
//!   contact stiffness of the tool's footprint ([`Vademecum::contact_stiffness`]): for a tip
//!   (probe, grasper) the load nodes' own stiffnesses `C(a ← a)⁻¹` (exact local blocks)
//!   interpolated over the triangle; for a blade's edge the blend `C(s)⁻¹`;
//! - where the surface reaches nodes the vademecum cannot load (the fixed face, the parts
//!   outside the accessible region), the organ lies on its rigid support: with λ the weight of
//!   the loadable nodes at s and s_L the point of their edge or vertex they span,
//!   `f = [λ K(s_L) + (1 − λ) k_w I] δ`, where the support stiffness `k_w` is the stiffest
//!   the organ gets at any loadable node (`max_a 1/λ_min(C(a))`). At λ = 1 this is the
//!   accessible law and at λ = 0 a wall, so the force is continuous everywhere on the surface.
//!
//! # Several tools on one organ
//! Each tool keeps its own proxy on every organ. When several tools touch the same organ in
//! one tick, their forces on the tissue are solved together ([`crate::pgd::coupled`]: each
//! keeps its own law's direction, the magnitudes solved from the compliances between the
//! loadable points `s_L,i`), and `f_i = λ_i g_i + (1 − λ_i) k_w δ_i` with `g_i` the solved
//! tissue force and `λ_i` the tool's share — pressing with one tool moves the tissue under the
//! other (a tool wholly on the support, `λ = 0`, takes no part). For one tool this is the law
//! above. A probe only pushes: a contact whose solution
//! would pull the tissue out (the others' press drew the surface away from under it) lets
//! go, and the rest are solved again. Where the contacts are not independent (two tools on
//! one spot: the system is singular) the shallower lets go and the deeper takes the load —
//! the limit of two tools coming together, where the split grows until one would pull.
//!
//! The force on the tool is the reaction `−f`. On an organ that deforms largely
//! (`effects.deformation = "large"`, or the organ's own `deformation`: each organ has its
//! model) the tissue's part is scaled by the organ's ANM-POD lattice
//! ([`crate::rom::palpation`]): the ratio of the nonlinear to the linear force at this depth,
//! blended over the four nearest lattice positions — `O(r · order)` per position, no
//! allocation; past the lattice's paths the ratio continues along their last tangent and the
//! tick is flagged `BEYOND_RANGE`. The linear model has no depth range: its force grows
//! linearly with depth until the pipeline saturates it at the probe's `max_force`.
//!
//! # The error estimate of each force
//! Every force comes with an estimate of its error against the full-order model of the same
//! mesh ([`TickState::force_error_n`]): for the linear law, the round-off of the exact local
//! compliances (`LINEAR_RELATIVE_ERROR · |f|`: the law is the full model's otherwise); with large
//! deformations, the lattice's [`Stiffening::error`] times the linear force — the nonlinear
//! correction's uncertainty growing with the distance to the nearest lattice position at the
//! rate the lattice's leave-one-out calibrated around each position
//! ([`AnmLattice::interpolation_rates`]), plus the
//! path's own error and, past the paths, the nonlinear correction growing at the rate it grew
//! along them. The support's share is
//! the model's wall and carries no error. With several tools on an organ, the compliances
//! between their contacts come from the modes (the exact local blocks only join neighbouring
//! nodes), whose field the build measured to a relative error ε
//! ([`LoadedBundle::modes_error`]): a block `C(i ← j)` is then off by up to about
//! `ε ‖C(s_L,j)‖` (the error relative to the field under the load at j), which moves tool
//! i's force by `ε λ_i ‖K(s_L,i)‖ Σ_{j≠i} ‖K(s_L,j)⁻¹‖ |g_j|` to first order — added to each
//! estimate; a bundle without that measure gives no estimate.
//! `vademecum study` checks the estimate against full Newton at nodes off the lattice.
//!
//! [`Stiffening::error`]: crate::rom::palpation::Stiffening::error
//! [`AnmLattice::interpolation_rates`]: crate::rom::palpation::AnmLattice::interpolation_rates

use std::sync::Arc;

use super::{Contact, Effect, Events, Fidelity, MAX_TOOLS, Stiffened, TickState, ToolInput, ToolKind};
use crate::bundle::LoadedBundle;
use crate::contact::{Bounds, Proxy, Surface, Touch};
use crate::pgd::coupled::{CoupledError, coupled_forces};
use crate::pgd::{Footprint, Vademecum};

/// One organ as the probe sees it.
#[derive(Debug, Clone)]
struct Organ {
    bundle: Arc<LoadedBundle>,
    surface: Surface,
    bounds: Bounds,
    /// One proxy per tool ([`ToolInput::tool`]).
    proxies: Vec<Proxy>,
    /// The modes' measured field error ([`LoadedBundle::modes_error`]), for the coupling's
    /// share of the error estimate.
    modes_error: Option<f64>,
    /// The support stiffness `k_w` (N/m).
    wall_stiffness: f64,
    /// Whether this organ deforms largely: its contact force is scaled by its lattice.
    large: bool,
    /// The lattice's interpolation rates for its four-position blend and for its nearest
    /// position alone (the reduced fidelity) (large deformations; empty otherwise).
    rates: [Vec<f64>; 2],
}

/// The linear-deformation effect over one vademecum per organ.
#[derive(Debug, Clone)]
pub struct Palpation {
    organs: Vec<Organ>,
    /// Each tool's tip radius (m), by [`ToolInput::tool`].
    radii_m: Vec<f64>,
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
    fn new(bundle: Arc<LoadedBundle>, large: bool, tools: usize) -> Self {
        let surface = Surface::new(&bundle.nodes, bundle.surface.clone());
        let bounds = Bounds::of(&bundle.nodes, &bundle.surface);
        let wall_stiffness = support_stiffness(&bundle.vademecum);
        let rates = match (&bundle.anm, large) {
            (Some(lattice), true) => [lattice.interpolation_rates(NEIGHBOURS), lattice.interpolation_rates(1)],
            _ => [Vec::new(), Vec::new()],
        };
        Self {
            modes_error: bundle.modes_error(),
            bundle,
            surface,
            bounds,
            proxies: vec![Proxy::default(); tools],
            wall_stiffness,
            large,
            rates,
        }
    }

    /// The force on the tissue at the touch as if the tool (of `footprint`) were alone (before
    /// any large-deformation scaling), split into its loadable and support parts.
    fn forces(&self, t: &Touch, footprint: Footprint) -> Share {
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
            return Share {
                lambda: 0.0,
                weights: wl,
                tissue: [0.0; 3],
                wall,
                coupling: 0.0,
            };
        }
        let wl = wl.map(|x| x / lambda);
        let tissue = match v.contact_compliance(t.nodes, wl, footprint) {
            Some(c) => Vademecum::contact_force(&c, delta).map(|f| lambda * f),
            None => [0.0; 3],
        };
        Share {
            lambda,
            weights: wl,
            tissue,
            wall,
            coupling: 0.0,
        }
    }
}

/// One tool's force on the tissue at its touch (before any large-deformation scaling).
#[derive(Debug, Clone, Copy, Default)]
struct Share {
    /// The share λ of the contact on the loadable surface.
    lambda: f64,
    /// The weights of the loadable point s_L in the touched triangle.
    weights: [f64; 3],
    /// The loadable part of the force (N).
    tissue: [f64; 3],
    /// The support's part of the force (N).
    wall: [f64; 3],
    /// What an error of the compliances between the tools' contacts can move the loadable
    /// part by, per unit relative error (N): `λ_i ‖K(s_L,i)‖ Σ_{j≠i} ‖K(s_L,j)⁻¹‖ |g_j|`;
    /// zero for a tool alone.
    coupling: f64,
}

/// The tools of one tick that touch the organ, and their forces solved together (module docs):
/// `shares[i]` of the tool `touches[i]` is replaced by the coupled one for every tool with a
/// loadable share on `organ`. A probe only pushes: where the solution would pull the tissue
/// out at a contact (`g_i · n_i > 0`: the others' press drew the surface away from under
/// it), the most pulling contact lets go — its tissue force is zero — and the rest are
/// solved again (an active set: at most one pass per tool). Two tools on one spot (a
/// singular system): the shallower lets go. Nothing changes when fewer than two tools touch.
fn couple(o: &Organ, organ: usize, tools: &[ToolInput], touches: &[Option<(usize, Touch)>], shares: &mut [Share]) {
    let mut members = [0usize; MAX_TOOLS];
    let mut points = [([0usize; 3], [0.0; 3]); MAX_TOOLS];
    let mut footprints = [Footprint::Tip; MAX_TOOLS];
    let mut penetrations = [[0.0; 3]; MAX_TOOLS];
    let mut normals = [[0.0; 3]; MAX_TOOLS];
    let mut k = 0;
    for (i, t) in touches.iter().enumerate() {
        if let Some((on, touch)) = t
            && *on == organ
            && shares[i].lambda > 0.0
        {
            members[k] = i;
            points[k] = (touch.nodes, shares[i].weights);
            footprints[k] = tools[i].kind.footprint();
            penetrations[k] = touch.penetration();
            normals[k] = touch.normal;
            k += 1;
        }
    }
    if k < 2 {
        return;
    }
    let v = &o.bundle.vademecum;
    let mut g = [[0.0; 3]; MAX_TOOLS];
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    // the active contacts first, in `members[..active]`, the released ones after
    let mut active = k;
    loop {
        let drop = match coupled_forces(
            v,
            &points[..active],
            &footprints[..active],
            &normals[..active],
            &penetrations[..active],
            &mut g[..active],
        ) {
            Ok(()) => (0..active)
                .map(|a| (a, dot(&g[a], &normals[a]) / dot(&g[a], &g[a]).sqrt().max(f64::MIN_POSITIVE)))
                .filter(|&(_, c)| c > 0.0)
                .max_by(|x, y| x.1.total_cmp(&y.1)),
            // two tools on one spot: the shallower lets go, the deeper takes the load — the
            // limit of two tools coming together, where the split grows until one would pull
            Err(CoupledError::Singular) => (0..active)
                .map(|a| (a, -dot(&penetrations[a], &penetrations[a])))
                .max_by(|x, y| x.1.total_cmp(&y.1)),
            Err(_) => return,
        };
        match drop {
            Some((a, _)) if active > 1 => {
                active -= 1;
                members.swap(a, active);
                points.swap(a, active);
                footprints.swap(a, active);
                penetrations.swap(a, active);
                normals.swap(a, active);
            }
            _ => break,
        }
    }
    // ‖K(s_L,i)⁻¹‖ and ‖K(s_L,i)‖ (Frobenius, bounding the spectral norms)
    let mut norms = [(0.0, 0.0); MAX_TOOLS];
    for ((n, p), f) in norms.iter_mut().zip(&points[..active]).zip(&footprints) {
        if let Some(k) = v.contact_stiffness(p.0, p.1, *f) {
            let m = nalgebra::Matrix3::from_fn(|r, d| k[r][d]);
            *n = (m.try_inverse().map_or(f64::INFINITY, |c| c.norm()), m.norm());
        }
    }
    let size = |f: &[f64; 3]| dot(f, f).sqrt();
    for (a, &i) in members[..k].iter().enumerate() {
        let s = &mut shares[i];
        if a >= active {
            // released: the surface left it
            s.tissue = [0.0; 3];
            s.coupling = 0.0;
            continue;
        }
        let others: f64 = (0..active).filter(|&b| b != a).map(|b| norms[b].0 * size(&g[b])).sum();
        s.coupling = s.lambda * norms[a].1 * others;
        s.tissue = g[a].map(|x| s.lambda * x);
    }
}

impl Palpation {
    /// Prepares the contact surfaces of `bundles` for one tool with a tip of radius
    /// `radius_m` (m); with `large`, every organ deforms largely and its bundle must carry a
    /// large-deformation lattice (checked by the pipeline).
    pub fn new(bundles: Vec<Arc<LoadedBundle>>, radius_m: f64, large: bool) -> Self {
        let large = vec![large; bundles.len()];
        Self::for_tools(bundles, vec![radius_m], &large)
    }

    /// [`Palpation::new`] for several tools, `radii_m[t]` the tip radius of tool `t`
    /// ([`ToolInput::tool`]; at most [`MAX_TOOLS`], at least one), each with its own proxy;
    /// `large[i]`: whether organ `i` deforms largely (one per bundle; a large organ's bundle
    /// must carry a lattice).
    pub fn for_tools(bundles: Vec<Arc<LoadedBundle>>, radii_m: Vec<f64>, large: &[bool]) -> Self {
        assert!((1..=MAX_TOOLS).contains(&radii_m.len()), "one to {MAX_TOOLS} tools");
        assert_eq!(large.len(), bundles.len(), "one deformation model per organ");
        let scratch = vec![
            0.0;
            bundles
                .iter()
                .filter_map(|b| b.anm.as_ref())
                .map(|l| l.max_modes())
                .max()
                .unwrap_or(0)
        ];
        let tools = radii_m.len();
        Self {
            organs: bundles.into_iter().zip(large).map(|(b, &l)| Organ::new(b, l, tools)).collect(),
            radii_m,
            scratch,
            neighbours: NEIGHBOURS,
        }
    }
}

impl Palpation {
    /// Moves `tool`'s proxy on every organ: the deepest contact, if any, and its organ.
    fn touch(&mut self, tool: &ToolInput) -> Option<(usize, Touch)> {
        let radius = *self.radii_m.get(tool.tool)?;
        let mut best: Option<(usize, Touch)> = None;
        for (i, o) in self.organs.iter_mut().enumerate() {
            let proxy = o.proxies.get_mut(tool.tool)?;
            if let Some(t) = proxy.update(&o.surface, &o.bounds, tool.contact_point(), radius)
                && best.is_none_or(|(_, b)| t.depth > b.depth)
            {
                best = Some((i, t));
            }
        }
        best
    }

    /// Writes one tool's contact into its tick state: the large-deformation scaling of the
    /// tissue's part, the force on the tool, the error estimate (module docs), the contact.
    fn render(&mut self, organ: usize, touch: &Touch, share: Share, state: &mut TickState) {
        let o = &self.organs[organ];
        let Share {
            lambda,
            weights: wl,
            mut tissue,
            wall,
            coupling,
        } = share;
        // the loadable point s_L, where the tissue takes its part of the load
        let nodes = &o.bundle.nodes;
        let mut point = [0.0; 3];
        for (a, &w) in touch.nodes.iter().zip(&wl) {
            for k in 0..3 {
                point[k] += w * nodes[*a][k];
            }
        }
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let mut scale = 1.0;
        let mut error = LINEAR_RELATIVE_ERROR * norm(tissue);
        let mut stiffened = None;
        if o.large
            && lambda > 0.0
            && let Some(lattice) = &o.bundle.anm
        {
            let s = lattice.stiffness_ratio(point, touch.depth, self.neighbours, &mut self.scratch);
            let rates = &o.rates[usize::from(self.neighbours == 1)];
            let ratio_error = s.error(rates);
            stiffened = Some(Stiffened {
                ratio: s.ratio,
                ratio_error,
            });
            error = norm(tissue) * ratio_error + LINEAR_RELATIVE_ERROR * s.ratio * norm(tissue);
            scale = s.ratio;
            tissue = tissue.map(|x| x * s.ratio);
            if s.extrapolated {
                state.events.0 |= Events::BEYOND_RANGE;
            }
        }
        state.force_error_n = match o.modes_error {
            _ if coupling == 0.0 => Some(error),
            Some(e) => Some(error + e * scale * coupling),
            None => None,
        };
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
            stiffened,
        });
        state.events.0 |= Events::CONTACT;
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
        self.tick_tools(std::slice::from_ref(tool), std::slice::from_mut(state));
    }

    /// Every tool's proxy moves on every organ (the deepest contact wins), then the forces of
    /// the tools touching one organ are solved together (module docs).
    fn tick_tools(&mut self, tools: &[ToolInput], states: &mut [TickState]) {
        let mut touches: [Option<(usize, Touch)>; MAX_TOOLS] = [None; MAX_TOOLS];
        for (i, tool) in tools.iter().enumerate() {
            // the grasper's effect is tearing's; it does not palpate
            if tool.kind != ToolKind::Grasper {
                touches[i] = self.touch(tool);
            }
        }
        let touches = &touches[..tools.len()];
        let mut shares = [Share::default(); MAX_TOOLS];
        for ((share, t), tool) in shares.iter_mut().zip(touches).zip(tools) {
            if let Some((organ, touch)) = t {
                *share = self.organs[*organ].forces(touch, tool.kind.footprint());
            }
        }
        for (organ, o) in self.organs.iter().enumerate() {
            couple(o, organ, tools, touches, &mut shares);
        }
        for (i, state) in states.iter_mut().enumerate() {
            if tools[i].kind == ToolKind::Grasper {
                continue;
            }
            match touches[i] {
                Some((organ, touch)) => self.render(organ, &touch, shares[i], state),
                // no contact: no force, in the full model too
                None => state.force_error_n = Some(0.0),
            }
        }
    }

    fn reset(&mut self) {
        for p in self.organs.iter_mut().flat_map(|o| o.proxies.iter_mut()) {
            p.release();
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
