//! The online vademecum: compliance, contact force and displacement field from the modes,
//! with no allocation after construction.
//!
//! A load state is a unit force in direction d spread over the tool's footprint around
//! surface node s (a patch of surface nodes with weights summing to one; a single node for a
//! point load). For it the displacement is
//! `u(x; s, d) = Σ_k F_k(x) G_k(s, d)`. The 3×3 compliance at s is the patch-averaged
//! displacement per unit force, `C_ij(s) = Σ_k F̄_k(s)_i G_k(s, j)` with
//! `F̄_k(s) = Σ_a w_a F_k(a)` over the patch (symmetric, by reciprocity), and a tool tip pressing the reference surface at s by
//! a penetration δ meets the force `f = C(s)⁻¹ δ` (the force that displaces s by δ). Inside a
//! surface triangle with barycentric weights w, both the load and the observation point are
//! interpolated — `F_k(s) = Σ_a w_a F_k(a)`, `G_k(s) = Σ_b w_b G_k(b)` — so the force varies
//! continuously as the tool slides across triangles.

use super::build::SeparatedSolution;
use crate::fem::assembly::DofMap;

/// Marker of a node that carries no load state.
const NOT_LOADABLE: u32 = u32::MAX;

/// Smallest accepted `|det C| / ‖C‖_F³` of a contact compliance (see [`Vademecum::contact_force`]).
const MIN_RELATIVE_DET: f64 = 1e-10;

/// Exact local compliances between neighbouring load nodes: for load node j, the 3×3 blocks
/// `C(b ← j)_{id}` = patch-averaged displacement i at load node b for a unit force in
/// direction d over j's patch, for every b sharing a surface triangle with j (and j itself).
///
/// The compliance under the tool is dominated by the local, singular part of the response —
/// exactly what a truncated set of modes captures worst (13 % error with 200 modes on the
/// built-in organ, against 1.2 % for the field: BENCHMARKS.md). Nine numbers per neighbour
/// pair make the haptic force exact at nodes and bilinear in between, while the modes keep
/// serving the displacement field.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalCompliance {
    /// Offsets into `nbr`/`c` per load node (length = load nodes + 1).
    pub ptr: Vec<usize>,
    /// Load-node index b of each block.
    pub nbr: Vec<usize>,
    /// The blocks `C(b ← j)`, row i = displacement component, column d = force direction.
    pub c: Vec<[[f64; 3]; 3]>,
}

impl LocalCompliance {
    /// The block `C(obs ← load)`, if the build computed it (each row's neighbours are sorted:
    /// checked by [`Vademecum::with_local`]).
    fn block(&self, obs: usize, load: usize) -> Option<&[[f64; 3]; 3]> {
        let (s, e) = (self.ptr[load], self.ptr[load + 1]);
        self.nbr[s..e].binary_search(&obs).ok().map(|k| &self.c[s + k])
    }
}

/// Why arrays do not make a vademecum ([`Vademecum::from_parts`], [`Vademecum::with_local`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum VademecumError {
    /// Not one load patch per load node.
    #[error("{patches} load patches for {nodes} load nodes")]
    PatchCount {
        /// Patches given.
        patches: usize,
        /// Load nodes given.
        nodes: usize,
    },
    /// A load patch is empty, names a node outside the mesh or has a non-finite weight.
    #[error("a load patch is empty, out of range or not finite")]
    BadPatch,
    /// The spatial modes have the wrong size.
    #[error("F has {found} values, expected {modes} modes × {dofs} dofs")]
    FSize {
        /// Values found.
        found: usize,
        /// Modes.
        modes: usize,
        /// Degrees of freedom.
        dofs: usize,
    },
    /// The parametric modes have the wrong size.
    #[error("G has {found} values, expected {modes} modes × {states} load states")]
    GSize {
        /// Values found.
        found: usize,
        /// Modes.
        modes: usize,
        /// Load states.
        states: usize,
    },
    /// A load node is not a node of the mesh.
    #[error("load node {node} is outside the mesh ({nodes} nodes)")]
    NodeOutside {
        /// The load node.
        node: usize,
        /// The mesh's nodes.
        nodes: usize,
    },
    /// A load node is listed twice.
    #[error("load node {0} is listed twice")]
    NodeTwice(usize),
    /// A mode holds a non-finite value.
    #[error("the modes contain non-finite values")]
    NonFinite,
    /// The local compliance's arrays do not fit together (or a row's neighbours are not in
    /// increasing order).
    #[error("local compliance arrays are inconsistent")]
    LocalInconsistent,
    /// The local compliance names a missing load node or holds a non-finite value.
    #[error("local compliance refers to a missing load node or is not finite")]
    LocalOutside,
}

/// A linear PGD vademecum ready for online evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct Vademecum {
    n_nodes: usize,
    modes: usize,
    /// Loadable nodes, in load-state order (state `3j + d` is node `load_nodes[j]`, direction d).
    load_nodes: Vec<usize>,
    param_of_node: Vec<u32>,
    /// Spatial modes over all `3·n_nodes` degrees of freedom (zero on constrained ones),
    /// mode-major: `f[k·3n + 3·node + i]`.
    f: Vec<f64>,
    /// Parameter modes, mode-major: `g[k·P + 3j + d]`.
    g: Vec<f64>,
    /// The load patch of each loadable node: `(nodes, weights)`, weights summing to one.
    patches: Vec<(Vec<usize>, Vec<f64>)>,
    /// Per loadable node j, interleaved for contact: `fl[(j·modes + k)·3 + i] = F̄_k(node_j)_i`,
    /// the patch average of the spatial mode.
    fl: Vec<f64>,
    /// Same layout for G: `gl[(j·modes + k)·3 + d] = G_k(j, d)`.
    gl: Vec<f64>,
    /// Exact local compliances, when the build computed them.
    local: Option<LocalCompliance>,
}

/// How a tool's load reaches the tissue between the load nodes
/// ([`Vademecum::contact_stiffness`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Footprint {
    /// A tip smaller than the mesh (a probe's sphere): the load sits where the tip is, and the
    /// nodes' own stiffnesses are interpolated between them.
    #[default]
    Tip,
    /// An edge lying along the surface (a blade): the load spreads over the triangle as its
    /// shape functions spread it, and the blend of the nodes' blocks is exact for it.
    Edge,
}

impl Vademecum {
    /// Builds the online form of a separated solution over the free equations of `dofs`.
    pub fn from_separated(sep: &SeparatedSolution, dofs: &DofMap, load_nodes: &[usize], patches: &[(Vec<usize>, Vec<f64>)]) -> Self {
        let n_dofs = dofs.n_dofs();
        let n_nodes = n_dofs / 3;
        let m = sep.modes;
        let p = sep.p;
        assert_eq!(p, 3 * load_nodes.len(), "one load state per node and direction");
        let mut f = vec![0.0; m * n_dofs];
        for k in 0..m {
            let fk = sep.f_mode(k);
            for d in 0..n_dofs {
                if let Some(e) = dofs.eq(d) {
                    f[k * n_dofs + d] = fk[e];
                }
            }
        }
        Self::from_parts(n_nodes, m, load_nodes.to_vec(), patches.to_vec(), f, sep.g.clone()).expect("consistent by construction")
    }

    /// Assembles a vademecum from raw arrays (as stored in a bundle), checking their sizes.
    pub fn from_parts(
        n_nodes: usize,
        modes: usize,
        load_nodes: Vec<usize>,
        patches: Vec<(Vec<usize>, Vec<f64>)>,
        f: Vec<f64>,
        g: Vec<f64>,
    ) -> Result<Self, VademecumError> {
        let p = 3 * load_nodes.len();
        if patches.len() != load_nodes.len() {
            return Err(VademecumError::PatchCount {
                patches: patches.len(),
                nodes: load_nodes.len(),
            });
        }
        for (nodes, w) in &patches {
            if nodes.len() != w.len() || nodes.is_empty() || nodes.iter().any(|&n| n >= n_nodes) || w.iter().any(|x| !x.is_finite()) {
                return Err(VademecumError::BadPatch);
            }
        }
        if f.len() != modes * 3 * n_nodes {
            return Err(VademecumError::FSize {
                found: f.len(),
                modes,
                dofs: 3 * n_nodes,
            });
        }
        if g.len() != modes * p {
            return Err(VademecumError::GSize {
                found: g.len(),
                modes,
                states: p,
            });
        }
        let mut param_of_node = vec![NOT_LOADABLE; n_nodes];
        for (j, &n) in load_nodes.iter().enumerate() {
            if n >= n_nodes {
                return Err(VademecumError::NodeOutside { node: n, nodes: n_nodes });
            }
            if param_of_node[n] != NOT_LOADABLE {
                return Err(VademecumError::NodeTwice(n));
            }
            param_of_node[n] = j as u32;
        }
        if f.iter().chain(&g).any(|v| !v.is_finite()) {
            return Err(VademecumError::NonFinite);
        }
        let nl = load_nodes.len();
        let mut fl = vec![0.0; nl * modes * 3];
        let mut gl = vec![0.0; nl * modes * 3];
        for (j, (pn, pw)) in patches.iter().enumerate() {
            for k in 0..modes {
                for i in 0..3 {
                    fl[(j * modes + k) * 3 + i] = pn.iter().zip(pw).map(|(&a, &w)| w * f[k * 3 * n_nodes + 3 * a + i]).sum();
                    gl[(j * modes + k) * 3 + i] = g[k * p + 3 * j + i];
                }
            }
        }
        Ok(Self {
            n_nodes,
            modes,
            load_nodes,
            param_of_node,
            f,
            g,
            patches,
            fl,
            gl,
            local: None,
        })
    }

    /// Attaches exact local compliances (checked for size and finiteness).
    pub fn with_local(mut self, local: LocalCompliance) -> Result<Self, VademecumError> {
        let nl = self.load_nodes.len();
        if local.ptr.len() != nl + 1
            || local.ptr.windows(2).any(|w| w[1] < w[0])
            || local.ptr[nl] != local.nbr.len()
            || local.nbr.len() != local.c.len()
            || (0..nl).any(|j| local.nbr[local.ptr[j]..local.ptr[j + 1]].windows(2).any(|w| w[1] <= w[0]))
        {
            return Err(VademecumError::LocalInconsistent);
        }
        if local.nbr.iter().any(|&b| b >= nl) || local.c.iter().flatten().flatten().any(|v| !v.is_finite()) {
            return Err(VademecumError::LocalOutside);
        }
        self.local = Some(local);
        Ok(self)
    }

    /// The exact local compliances, if present.
    pub fn local(&self) -> Option<&LocalCompliance> {
        self.local.as_ref()
    }

    /// Number of mesh nodes.
    pub fn n_nodes(&self) -> usize {
        self.n_nodes
    }

    /// Number of modes.
    pub fn modes(&self) -> usize {
        self.modes
    }

    /// The loadable nodes, in load-state order.
    pub fn load_nodes(&self) -> &[usize] {
        &self.load_nodes
    }

    /// The load patch `(nodes, weights)` of each loadable node, in load-state order.
    pub fn patches(&self) -> &[(Vec<usize>, Vec<f64>)] {
        &self.patches
    }

    /// Raw spatial modes (mode-major over all dofs).
    pub fn f_raw(&self) -> &[f64] {
        &self.f
    }

    /// Raw parameter modes (mode-major over load states).
    pub fn g_raw(&self) -> &[f64] {
        &self.g
    }

    /// Whether a tool may load `node`.
    pub fn is_loadable(&self, node: usize) -> bool {
        self.param_of_node.get(node).is_some_and(|&p| p != NOT_LOADABLE)
    }

    /// The compliance (m/N) at a surface point given by up to three nodes and barycentric
    /// weights; `None` if a node with non-zero weight is not loadable or the input is not
    /// finite. With exact local compliances (see [`LocalCompliance`]) it is
    /// `Σ_a Σ_b w_a w_b C(a ← b)` — exact at nodes, at most 9 blocks; otherwise it comes from
    /// the modes (about 18 multiply-adds per mode).
    pub fn compliance(&self, nodes: [usize; 3], weights: [f64; 3]) -> Option<[[f64; 3]; 3]> {
        let js = self.load_indices(nodes, weights)?;
        if let Some(local) = &self.local {
            // C(s) = Σ_a Σ_b w_a w_b C(a ← b): exact at nodes, bilinear inside the triangle.
            let mut c = [[0.0; 3]; 3];
            let mut complete = true;
            'pairs: for a in 0..3 {
                for b in 0..3 {
                    let w = weights[a] * weights[b];
                    if w == 0.0 {
                        continue;
                    }
                    match local.block(js[a], js[b]) {
                        Some(blk) => {
                            for i in 0..3 {
                                for d in 0..3 {
                                    c[i][d] += w * blk[i][d];
                                }
                            }
                        }
                        None => {
                            complete = false;
                            break 'pairs;
                        }
                    }
                }
            }
            if complete {
                return Some(c);
            }
        }
        self.modal_compliance(js, weights)
    }

    /// The contact stiffness (N/m) a tool with `footprint` meets at a surface point
    /// (docs/contact.md, "Which stiffness is right"):
    ///
    /// - [`Footprint::Tip`]: the nodes' own stiffnesses `K_a = C(a ← a)⁻¹` interpolated,
    ///   `K(s) = Σ_a w_a K_a` — exact at the nodes and, between them, closer to the stiffness
    ///   of a tip smaller than the mesh (measured under refinement) than the blend, and as
    ///   smooth as it;
    /// - [`Footprint::Edge`]: the blend's `C(s)⁻¹` ([`Vademecum::compliance`]), exact for the
    ///   load spread over the triangle by its shape functions — a blade's edge lying along the
    ///   surface across the mesh.
    ///
    /// `None` as for [`Vademecum::compliance`], or when a block is singular.
    pub fn contact_stiffness(&self, nodes: [usize; 3], weights: [f64; 3], footprint: Footprint) -> Option<[[f64; 3]; 3]> {
        let inverse = |c: [[f64; 3]; 3]| nalgebra::Matrix3::from_fn(|r, d| c[r][d]).try_inverse();
        let mut k = [[0.0; 3]; 3];
        match footprint {
            Footprint::Edge => {
                let inv = inverse(self.compliance(nodes, weights)?)?;
                k = std::array::from_fn(|i| std::array::from_fn(|d| inv[(i, d)]));
            }
            Footprint::Tip => {
                self.load_indices(nodes, weights)?;
                for a in 0..3 {
                    if weights[a] == 0.0 {
                        continue;
                    }
                    let inv = inverse(self.compliance([nodes[a]; 3], [1.0, 0.0, 0.0])?)?;
                    for i in 0..3 {
                        for d in 0..3 {
                            k[i][d] += weights[a] * inv[(i, d)];
                        }
                    }
                }
            }
        }
        Some(k)
    }

    /// The compliance a tool with `footprint` alone meets at a surface point: the inverse of
    /// its [`Vademecum::contact_stiffness`] (at a node, the node's own block for either).
    pub fn contact_compliance(&self, nodes: [usize; 3], weights: [f64; 3], footprint: Footprint) -> Option<[[f64; 3]; 3]> {
        if footprint == Footprint::Edge {
            return self.compliance(nodes, weights);
        }
        let k = self.contact_stiffness(nodes, weights, footprint)?;
        let c = nalgebra::Matrix3::from_fn(|r, d| k[r][d]).try_inverse()?;
        Some(std::array::from_fn(|r| std::array::from_fn(|d| c[(r, d)])))
    }

    /// The load-node index of each node of a surface point with non-zero weight (0 for the
    /// others); `None` if a weight is not finite or such a node is not loadable.
    fn load_indices(&self, nodes: [usize; 3], weights: [f64; 3]) -> Option<[usize; 3]> {
        if weights.iter().any(|w| !w.is_finite()) {
            return None;
        }
        let mut js = [0usize; 3];
        for a in 0..3 {
            if weights[a] != 0.0 {
                let p = *self.param_of_node.get(nodes[a])?;
                if p == NOT_LOADABLE {
                    return None;
                }
                js[a] = p as usize;
            }
        }
        Some(js)
    }

    /// The compliance from the modes alone (what [`Vademecum::compliance`] falls back to when
    /// a node pair has no exact block).
    fn modal_compliance(&self, js: [usize; 3], weights: [f64; 3]) -> Option<[[f64; 3]; 3]> {
        let m = self.modes;
        let mut c = [[0.0; 3]; 3];
        for k in 0..m {
            let (mut fk, mut gk) = ([0.0; 3], [0.0; 3]);
            for a in 0..3 {
                let w = weights[a];
                if w == 0.0 {
                    continue;
                }
                let at = (js[a] * m + k) * 3;
                for i in 0..3 {
                    fk[i] += w * self.fl[at + i];
                    gk[i] += w * self.gl[at + i];
                }
            }
            for i in 0..3 {
                for d in 0..3 {
                    c[i][d] += fk[i] * gk[d];
                }
            }
        }
        Some(c)
    }

    /// The compliance between two surface points (m/N), each given by up to three nodes and
    /// barycentric weights: the patch-averaged displacement at `obs` per unit force spread over
    /// `load`'s patch, `C(obs ← load) = Σ_a Σ_b w_a w_b C(a ← b)` — the block between two
    /// tools in contact, so that pressing with one moves the tissue under the other. Each node
    /// pair takes its exact local block where the build computed one (neighbouring load
    /// nodes: the singular part, which the modes capture worst) and `Σ_k F̄_k(a) G_k(b)` from
    /// the modes otherwise (far apart, the response is smooth and the modes hold it).
    /// `C(s ← s)` is [`Self::compliance`] where every pair has a block; by reciprocity
    /// `C(b ← a) = C(a ← b)ᵀ`. `None` if a node with non-zero weight is not loadable or the
    /// input is not finite.
    pub fn cross_compliance(&self, obs: ([usize; 3], [f64; 3]), load: ([usize; 3], [f64; 3])) -> Option<[[f64; 3]; 3]> {
        let (ja, jb) = (self.load_indices(obs.0, obs.1)?, self.load_indices(load.0, load.1)?);
        let (wa, wb) = (obs.1, load.1);
        let block = |a: usize, b: usize| self.local.as_ref().and_then(|l| l.block(ja[a], jb[b]));
        let pairs = || (0..9).map(|p| (p / 3, p % 3)).filter(|&(a, b)| wa[a] * wb[b] != 0.0);
        let local = pairs().filter(|&(a, b)| block(a, b).is_some()).count();
        let mut c = [[0.0; 3]; 3];
        if local == 0 {
            // far apart: the modes for every node pair at once,
            // (Σ_a w_a F̄_k(a)) (Σ_b w_b G_k(b))ᵀ summed over k — a third of the work of pair by pair
            for k in 0..self.modes {
                let (mut fk, mut gk) = ([0.0; 3], [0.0; 3]);
                for a in 0..3 {
                    let (fa, gb) = ((ja[a] * self.modes + k) * 3, (jb[a] * self.modes + k) * 3);
                    for i in 0..3 {
                        fk[i] += wa[a] * self.fl[fa + i];
                        gk[i] += wb[a] * self.gl[gb + i];
                    }
                }
                for i in 0..3 {
                    for d in 0..3 {
                        c[i][d] += fk[i] * gk[d];
                    }
                }
            }
            return Some(c);
        }
        for (a, b) in pairs() {
            let w = wa[a] * wb[b];
            let part = block(a, b).copied().unwrap_or_else(|| self.modal_block(ja[a], jb[b]));
            for i in 0..3 {
                for d in 0..3 {
                    c[i][d] += w * part[i][d];
                }
            }
        }
        Some(c)
    }

    /// The modes' compliance between two load states, `Σ_k F̄_k(a) G_k(b)ᵀ`.
    fn modal_block(&self, ja: usize, jb: usize) -> [[f64; 3]; 3] {
        let m = self.modes;
        let mut c = [[0.0; 3]; 3];
        for k in 0..m {
            let (fa, gb) = ((ja * m + k) * 3, (jb * m + k) * 3);
            for i in 0..3 {
                for d in 0..3 {
                    c[i][d] += self.fl[fa + i] * self.gl[gb + d];
                }
            }
        }
        c
    }

    /// The contact force (N) that displaces a surface point by `penetration` (m):
    /// `f = C⁻¹ δ`. Returns zero for a non-finite input or an ill-conditioned compliance:
    /// `|det C| ≤ 10⁻¹⁰ ‖C‖_F³` (relative, so independent of units and tissue stiffness; for
    /// eigenvalues 1, 1, ε the ratio is about ε/3, so condition numbers beyond about 3·10⁹
    /// are refused, where Cramer's rule in f64 would lose most digits).
    pub fn contact_force(c: &[[f64; 3]; 3], penetration: [f64; 3]) -> [f64; 3] {
        if penetration.iter().any(|v| !v.is_finite()) {
            return [0.0; 3];
        }
        let det = c[0][0] * (c[1][1] * c[2][2] - c[1][2] * c[2][1]) - c[0][1] * (c[1][0] * c[2][2] - c[1][2] * c[2][0])
            + c[0][2] * (c[1][0] * c[2][1] - c[1][1] * c[2][0]);
        let norm = c.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
        if !(det.is_finite() && norm.is_finite() && det.abs() > MIN_RELATIVE_DET * norm * norm * norm) {
            return [0.0; 3];
        }
        // Cramer's rule
        let mut f = [0.0; 3];
        for col in 0..3 {
            let mut m = *c;
            for r in 0..3 {
                m[r][col] = penetration[r];
            }
            let d = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
            f[col] = d / det;
        }
        if f.iter().all(|v| v.is_finite()) { f } else { [0.0; 3] }
    }

    /// Mode coefficients `c_k = Σ_b w_b Σ_d G_k(b, d) f_d` of the response to force `f` (N)
    /// applied at the surface point `(nodes, weights)`, into `coeffs` (length = modes).
    /// Returns false (and zeros) if the point is not loadable or the input is not finite.
    pub fn coefficients(&self, nodes: [usize; 3], weights: [f64; 3], force: [f64; 3], coeffs: &mut [f64]) -> bool {
        debug_assert_eq!(coeffs.len(), self.modes);
        coeffs.fill(0.0);
        if weights.iter().chain(&force).any(|v| !v.is_finite()) {
            return false;
        }
        let m = self.modes;
        for a in 0..3 {
            if weights[a] == 0.0 {
                continue;
            }
            let Some(&p) = self.param_of_node.get(nodes[a]) else {
                coeffs.fill(0.0);
                return false;
            };
            if p == NOT_LOADABLE {
                coeffs.fill(0.0);
                return false;
            }
            for (k, c) in coeffs.iter_mut().enumerate() {
                let at = (p as usize * m + k) * 3;
                *c += weights[a] * (self.gl[at] * force[0] + self.gl[at + 1] * force[1] + self.gl[at + 2] * force[2]);
            }
        }
        true
    }

    /// The displacement field `u = Σ_k c_k F_k` over all nodes (`out`: 3·n_nodes values).
    pub fn field(&self, coeffs: &[f64], out: &mut [f64]) {
        let nd = 3 * self.n_nodes;
        debug_assert_eq!(out.len(), nd);
        out.fill(0.0);
        for (k, &c) in coeffs.iter().enumerate() {
            if c != 0.0 {
                for (o, f) in out.iter_mut().zip(&self.f[k * nd..(k + 1) * nd]) {
                    *o += c * f;
                }
            }
        }
    }

    /// The displacement of selected nodes only (`out`: 3 values per node).
    pub fn field_at(&self, coeffs: &[f64], nodes: &[usize], out: &mut [f64]) {
        let nd = 3 * self.n_nodes;
        debug_assert_eq!(out.len(), 3 * nodes.len());
        out.fill(0.0);
        for (k, &c) in coeffs.iter().enumerate() {
            let fk = &self.f[k * nd..(k + 1) * nd];
            for (o, &n) in out.chunks_exact_mut(3).zip(nodes) {
                o[0] += c * fk[3 * n];
                o[1] += c * fk[3 * n + 1];
                o[2] += c * fk[3 * n + 2];
            }
        }
    }
}

/// The spatial modes restricted to a set of nodes (the visual surface), in f32 and
/// node-major order — for each node, for each component, the `modes` values contiguous — so
/// evaluating the field there is one contiguous, vectorisable dot product per component and
/// reads `12·modes` bytes per node instead of streaming every mode over the whole mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeMajorField {
    nodes: Vec<usize>,
    modes: usize,
    /// `data[(j·3 + i)·modes + k] = F_k(nodes[j])_i`.
    data: Vec<f32>,
}

impl NodeMajorField {
    /// Copies the modes of `v` at `nodes`.
    pub fn new(v: &Vademecum, nodes: &[usize]) -> Self {
        Self::from_mode_major(&v.f, v.n_nodes, v.modes, nodes)
    }

    /// Builds from mode-major f64 modes over `n_nodes` nodes (`f[k·3n + 3·node + i]`).
    pub fn from_mode_major(f: &[f64], n_nodes: usize, modes: usize, nodes: &[usize]) -> Self {
        let nd = 3 * n_nodes;
        let mut data = vec![0.0f32; nodes.len() * 3 * modes];
        for (j, &n) in nodes.iter().enumerate() {
            for i in 0..3 {
                for k in 0..modes {
                    data[(j * 3 + i) * modes + k] = f[k * nd + 3 * n + i] as f32;
                }
            }
        }
        Self {
            nodes: nodes.to_vec(),
            modes,
            data,
        }
    }

    /// The nodes, in output order.
    pub fn nodes(&self) -> &[usize] {
        &self.nodes
    }

    /// Bytes of mode data read per evaluation.
    pub fn bytes(&self) -> usize {
        4 * self.data.len()
    }

    /// `out[3j + i] = Σ_k c_k F_k(nodes[j])_i` (`coeffs`: one f32 per mode).
    pub fn eval(&self, coeffs: &[f32], out: &mut [f32]) {
        debug_assert_eq!(coeffs.len(), self.modes);
        debug_assert_eq!(out.len(), 3 * self.nodes.len());
        eval_rows(&self.data, self.modes, coeffs, out);
    }

    /// [`NodeMajorField::eval`] with the first `prefix` modes only (all when `prefix` is 0 or
    /// at least the modes): the coarser field of a shorter vademecum, at `prefix / modes` of
    /// the multiply-adds (each row's tail is skipped).
    pub fn eval_prefix(&self, coeffs: &[f32], prefix: usize, out: &mut [f32]) {
        if prefix == 0 || prefix >= self.modes {
            return self.eval(coeffs, out);
        }
        debug_assert_eq!(out.len(), 3 * self.nodes.len());
        for (o, row) in out.iter_mut().zip(self.data.chunks_exact(self.modes)) {
            *o = dot(&row[..prefix], &coeffs[..prefix]);
        }
    }
}

/// The spatial modes at a set of nodes, node-major like [`NodeMajorField`] but quantised to
/// i16 with one scale per mode (`F_k(x)_i ≈ s_k · q`, `s_k = max |F_k| / 32767`): half the
/// bytes of f32, for a relative rounding of at most `1/65534` of each mode's largest value.
/// The scales are folded into the coefficients (`c'_k = s_k c_k`), so the inner loop is one
/// widening multiply–add per value. The surface field is memory-bound (BENCHMARKS.md), so
/// halving the bytes halves its time.
#[derive(Debug, Clone, PartialEq)]
pub struct QuantizedField {
    nodes: Vec<usize>,
    modes: usize,
    scale: Vec<f32>,
    /// `data[(j·3 + i)·modes + k] = round(F_k(nodes[j])_i / s_k)`.
    data: Vec<i16>,
}

impl QuantizedField {
    /// Quantises the first `modes` modes of `v` at `nodes` (a prefix of the modes is a
    /// coarser field: the modes are ordered by decreasing singular value).
    pub fn new(v: &Vademecum, nodes: &[usize], modes: usize) -> Self {
        Self::from_mode_major(&v.f, v.n_nodes, modes.min(v.modes), nodes)
    }

    /// Builds from mode-major f64 modes over `n_nodes` nodes (`f[k·3n + 3·node + i]`).
    pub fn from_mode_major(f: &[f64], n_nodes: usize, modes: usize, nodes: &[usize]) -> Self {
        let nd = 3 * n_nodes;
        let scale: Vec<f32> = (0..modes)
            .map(|k| {
                let m = nodes
                    .iter()
                    .flat_map(|&n| (0..3).map(move |i| f[k * nd + 3 * n + i].abs()))
                    .fold(0.0, f64::max);
                (m / i16::MAX as f64) as f32
            })
            .collect();
        let mut data = vec![0i16; nodes.len() * 3 * modes];
        for (j, &n) in nodes.iter().enumerate() {
            for i in 0..3 {
                for k in 0..modes {
                    let s = scale[k] as f64;
                    data[(j * 3 + i) * modes + k] = if s > 0.0 { (f[k * nd + 3 * n + i] / s).round() as i16 } else { 0 };
                }
            }
        }
        Self {
            nodes: nodes.to_vec(),
            modes,
            scale,
            data,
        }
    }

    /// Modes used.
    pub fn modes(&self) -> usize {
        self.modes
    }

    /// Bytes of mode data read per evaluation.
    pub fn bytes(&self) -> usize {
        2 * self.data.len()
    }

    /// `out[3j + i] = Σ_k c_k F_k(nodes[j])_i` over the quantised modes; `scaled` is a
    /// workspace of `modes` values (no allocation).
    pub fn eval(&self, coeffs: &[f32], scaled: &mut [f32], out: &mut [f32]) {
        debug_assert!(coeffs.len() >= self.modes && scaled.len() == self.modes);
        debug_assert_eq!(out.len(), 3 * self.nodes.len());
        for ((c, &x), &s) in scaled.iter_mut().zip(coeffs).zip(&self.scale) {
            *c = x * s;
        }
        eval_rows(&self.data, self.modes, scaled, out);
    }
}

/// `out[r] = Σ_k data[r·modes + k] · c_k` for every row: node-major modes times
/// coefficients, with AVX2 + FMA when the CPU has them (chosen at run time; the i16 → f32
/// widening needs at least SSE4.1 to vectorise, and the x86-64 baseline has only SSE2).
fn eval_rows<T: Copy + Into<f32>>(data: &[T], modes: usize, c: &[f32], out: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports the features the function is compiled for.
        unsafe { eval_rows_avx2(data, modes, c, out) };
        return;
    }
    eval_rows_portable(data, modes, c, out);
}

#[inline(always)]
fn eval_rows_portable<T: Copy + Into<f32>>(data: &[T], modes: usize, c: &[f32], out: &mut [f32]) {
    for (o, row) in out.iter_mut().zip(data.chunks_exact(modes.max(1))) {
        *o = dot(row, c);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn eval_rows_avx2<T: Copy + Into<f32>>(data: &[T], modes: usize, c: &[f32], out: &mut [f32]) {
    eval_rows_portable(data, modes, c, out)
}

/// `Σ a_k b_k` (a in f32 or i16, widened), written with eight independent accumulators so
/// it vectorises.
#[inline(always)]
fn dot<T: Copy + Into<f32>>(a: &[T], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            acc[l] += x[l].into() * y[l];
        }
    }
    let mut s: f32 = acc.iter().sum();
    for (x, y) in ra.iter().zip(rb) {
        s += (*x).into() * y;
    }
    s
}
