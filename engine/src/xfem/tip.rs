//! A cut that ends inside a cell: the crack-tip (branch-function) enrichment along the blade's
//! edge, in the full-order XFEM (issue 47; the candidate measured in `docs/cutting.md`, "Where
//! the cut ends").
//!
//! With the crack front shared ([`Front::Shared`]) a cut ends where the blade stopped when it
//! stops on cell faces, but a cell the blade has entered and not crossed is not cut at all: the
//! cut is rounded down to whole cells. Here the cell that holds the blade's edge — the *tip
//! cells* — carry the cut to the edge itself. Around the tip line (the blade's last edge, a
//! straight segment), with `x₁` the distance ahead of it in the cut's plane, `x₂` across the
//! plane and `r, θ` their polar coordinates (θ = ±π on the cut's two lips), the displacement is
//!
//! `u(x) = Σ_a N_a u_a + Σ_{I∈S} N_I H̃_I q_I + Σ_{J∈T} Σ_j N_J (F_j(x) − F_j(x_J)) b_Jj`
//!
//! (Moës, Dolbow and Belytschko 1999; the shift of Belytschko et al. 2001 keeps `u_a` the
//! displacement at node a): `S` the cracked nodes of the Heaviside enrichment (those whose
//! support the cut crosses entirely, [`Front::Shared`]), `T` the tip nodes — the nodes of the
//! tip cells, and with [`TipParams::radius`] every node that near the tip line (the geometric
//! enrichment of Laborde et al. 2005 and Béchet et al. 2005, whose rate does not degrade with
//! the mesh) — and `F_j` the branch functions:
//!
//! - [`Branch::Jump`]: `F₁ = √r sin(θ/2)` alone, the function that opens the cut up to the tip
//!   line and not past it (continuous ahead of the tip, a jump of `2√r` behind it);
//! - [`Branch::Full`]: the four functions `√r {sin(θ/2), cos(θ/2), sin(θ/2) sin θ,
//!   cos(θ/2) sin θ}`, which span the asymptotic field of a crack in linear elasticity.
//!
//! A cell with tip nodes is integrated on sub-tetrahedra on one side of every plane that crosses
//! it — the Heaviside planes, the cut's plane and the plane through the tip line across it — so
//! that every branch function is smooth on each. The integrand grows like `1/r` at the tip
//! line: a sub-tetrahedron with an edge or a vertex on it takes a rule collapsed onto that
//! edge or vertex, whose Jacobian vanishes like r there (the product is smooth; 4 × 4 × 4
//! Gauss–Legendre points); those near it are refined
//! [`TipParams::levels`] times; the rest take the degree-5 conical-product rule. The extended
//! stiffness is assembled as in [`super::system`]: the uncut stiffness for the standard block,
//! B̄'s one mean dilatation per hexahedron for every generalized function, the plain volumetric
//! term on tetrahedra. A blade that has reached the organ's surface is refused
//! ([`TipError::Through`]: the cut goes through, which the Heaviside enrichment solves). (The
//! averaged nodal pressure, pieces cut loose, the reduced and co-rotational models and sessions
//! do not take the tip enrichment yet.)

use std::sync::Arc;
use std::time::Instant;

use super::enrichment::{Enrichment, EnrichmentError, Front, XfemParams};
use super::subcell::{self, Plane, SubTet};
use super::system::{self, EnrichedVolumetric, XfemError};
use crate::fem::assembly::{self, DofMap, MaterialMap, SymmetricPattern};
use crate::fem::element::{self, ElementError, Locking};
use crate::fem::linear_static::StaticProblem;
use crate::geometry::cut::Cut;
use crate::geometry::vec3::{cross, dot, lerp, norm, sub};
use crate::mesh::{CellKind, Mesh, shape};

/// Which branch functions the tip nodes carry (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Branch {
    /// None: the Heaviside enrichment with the front shared, the tip rounded down to whole
    /// cells (for comparison; equals [`super::system::solve`] with [`Front::Shared`]).
    None,
    /// `√r sin(θ/2)`: the jump up to the tip line.
    Jump,
    /// The four functions of the crack's asymptotic field.
    Full,
}

impl Branch {
    /// How many functions each tip node carries.
    pub fn count(self) -> usize {
        match self {
            Self::None => 0,
            Self::Jump => 1,
            Self::Full => 4,
        }
    }
}

/// The settings of the tip enrichment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipParams {
    /// The branch functions.
    pub branch: Branch,
    /// Nodes closer than this to the tip line (m) carry the branch functions too (0: the tip
    /// cells' nodes only).
    pub radius: f64,
    /// How many times the sub-tetrahedra near the tip line but not touching it are refined
    /// (each refinement splits one into eight; those with a vertex or an edge on it take the
    /// singular rule instead). At 2 the 20° cut of issue 47's block at n = 10 is within
    /// 5·10⁻⁵ of its energy at 4.
    pub levels: usize,
}

impl Default for TipParams {
    fn default() -> Self {
        Self {
            branch: Branch::Full,
            radius: 0.0,
            levels: 2,
        }
    }
}

/// Where the blade stopped: its edge inside the tissue, and the cut's plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipLine {
    /// One end of the edge.
    pub a: [f64; 3],
    /// The other end.
    pub b: [f64; 3],
    /// The normal of the cut's plane at the edge.
    pub normal: [f64; 3],
    /// A direction pointing ahead of the cut, into the tissue the blade has not reached (only
    /// its sense matters).
    pub forward: [f64; 3],
}

/// The tip line's frame: `e₁` ahead in the cut's plane, `e₂` its normal, `e₃` along the edge.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Frame {
    origin: [f64; 3],
    e: [[f64; 3]; 3],
    /// The edge's extent along `e₃`.
    along: [f64; 2],
}

fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let l = norm(v);
    (l.is_finite() && l > 0.0).then(|| v.map(|x| x / l))
}

impl Frame {
    fn new(t: &TipLine) -> Option<Self> {
        let e3 = unit(sub(t.b, t.a))?;
        let e2 = unit(sub(t.normal, e3.map(|v| v * dot(t.normal, e3))))?;
        let mut e1 = cross(e2, e3);
        if dot(e1, t.forward) < 0.0 {
            e1 = e1.map(|v| -v);
        }
        Some(Self {
            origin: t.a,
            e: [e1, e2, e3],
            along: [0.0, dot(sub(t.b, t.a), e3)],
        })
    }

    /// `(x₁, x₂, x₃)` of `x`.
    fn local(&self, x: [f64; 3]) -> [f64; 3] {
        let d = sub(x, self.origin);
        self.e.map(|e| dot(d, e))
    }

    /// Distance of `x` from the tip segment.
    fn distance(&self, x: [f64; 3]) -> f64 {
        let [x1, x2, x3] = self.local(x);
        let s = x3 - x3.clamp(self.along[0], self.along[1]);
        (x1 * x1 + x2 * x2 + s * s).sqrt()
    }

    /// The branch functions' values and gradients at `x` on the lip `positive` (the side of
    /// the cut's plane, which decides θ = ±π behind the tip).
    fn branch(&self, x: [f64; 3], positive: bool, values: &mut [f64; 4], grads: &mut [[f64; 3]; 4]) {
        let [x1, x2, _] = self.local(x);
        let x2 = if positive { x2.abs() } else { -x2.abs() };
        let r = (x1 * x1 + x2 * x2).sqrt();
        let th = x2.atan2(x1);
        let (s2, c2) = (0.5 * th).sin_cos();
        let (s, c) = th.sin_cos();
        let (s32, c32) = (1.5 * th).sin_cos();
        let sr = r.sqrt();
        *values = [sr * s2, sr * c2, sr * s2 * s, sr * c2 * s];
        if r == 0.0 {
            *grads = [[0.0; 3]; 4];
            return;
        }
        let h = 0.5 / sr;
        // (∂/∂x₁, ∂/∂x₂) of each (Moës et al. 1999)
        let d = [
            [-h * s2, h * c2],
            [h * c2, h * s2],
            [-h * s32 * s, h * (s2 + s32 * c)],
            [-h * c32 * s, h * (c2 + c32 * c)],
        ];
        for (g, d) in grads.iter_mut().zip(d) {
            *g = std::array::from_fn(|i| d[0] * self.e[0][i] + d[1] * self.e[1][i]);
        }
    }
}

/// The Heaviside and tip enrichment of a cut that ends inside a cell.
#[derive(Debug, Clone)]
pub struct TipEnrichment {
    /// The Heaviside part: cracked nodes, each with its plane and whether it lies on its
    /// positive side (the tip nodes left out).
    pub cracked: Vec<(usize, Plane, bool)>,
    /// The nodes carrying the branch functions.
    pub tip_nodes: Vec<usize>,
    /// The cells the tip line passes through.
    pub tip_cells: Vec<usize>,
    /// The branch functions.
    pub params: TipParams,
    frame: Frame,
}

/// Why a tip enrichment could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TipError {
    /// The cut itself.
    #[error(transparent)]
    Enrichment(#[from] EnrichmentError),
    /// The tip line is degenerate.
    #[error("the tip line needs two distinct ends and a normal across it")]
    Degenerate,
    /// No cell holds the tip line.
    #[error("the tip line passes through no cell of the mesh")]
    Outside,
    /// The tip line lies on the organ's surface, no material ahead of it.
    #[error(
        "the blade has reached the organ's surface (no tissue ahead of its edge): the cut goes right through; the tip enrichment is for a cut that ends inside — solve it with the Heaviside enrichment, which finds the pieces it frees"
    )]
    Through,
}

/// Whether the origin lies in the convex hull of the 2D points `p` (within `tol`).
fn hull_holds_origin(p: &[[f64; 2]], tol: f64) -> bool {
    // the origin is outside iff some direction separates it: test the normals of every pair
    for (i, a) in p.iter().enumerate() {
        for b in &p[i + 1..] {
            let d = [b[0] - a[0], b[1] - a[1]];
            let nrm = [-d[1], d[0]];
            if nrm[0] == 0.0 && nrm[1] == 0.0 {
                continue;
            }
            let side = |q: &[f64; 2]| nrm[0] * (q[0] - a[0]) + nrm[1] * (q[1] - a[1]);
            let o = side(&[0.0, 0.0]);
            let (lo, hi) = p
                .iter()
                .map(side)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(v), h.max(v)));
            if o < lo - tol || o > hi + tol {
                return false;
            }
        }
    }
    true
}

impl TipEnrichment {
    /// The enrichment of the swept cut `cut` whose blade stopped at `tip`: the Heaviside
    /// enrichment with the front shared ([`Enrichment::from_cut`] with [`Front::Shared`]), the
    /// tip cells' nodes (and those within [`TipParams::radius`]) moved to the branch functions.
    pub fn new(mesh: &Mesh, cut: &Cut, tip: &TipLine, xfem: &XfemParams, params: TipParams) -> Result<Self, TipError> {
        let frame = Frame::new(tip).ok_or(TipError::Degenerate)?;
        let shared = XfemParams {
            front: Front::Shared,
            ..*xfem
        };
        let enr = Enrichment::from_cut(mesh, cut, &shared)?;
        let npc = mesh.kind.nodes_per_cell();
        let mut x = vec![[0.0; 3]; npc];
        let mut tip_cells = Vec::new();
        for c in 0..mesh.n_cells() {
            mesh.cell_coords(c, &mut x);
            let h = subcell::cell_size(&x);
            let local: Vec<[f64; 3]> = x.iter().map(|&p| frame.local(p)).collect();
            let (lo, hi) = local
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, u), p| (l.min(p[2]), u.max(p[2])));
            if hi < frame.along[0] - 1e-9 * h || lo > frame.along[1] + 1e-9 * h {
                continue;
            }
            let plane: Vec<[f64; 2]> = local.iter().map(|p| [p[0], p[1]]).collect();
            if hull_holds_origin(&plane, 1e-9 * h * h) {
                tip_cells.push(c);
            }
        }
        if tip_cells.is_empty() {
            return Err(TipError::Outside);
        }
        // a blade that reached the organ's surface leaves no material ahead of its edge in the
        // cells that hold it: the cut goes right through, and the branch functions would hang
        // the pieces it frees on that edge (a hinge, nearly singular) instead of finding them
        let ahead = Plane {
            point: frame.origin,
            normal: frame.e[0],
        };
        let (mut front, mut all) = (0.0, 0.0);
        for &c in &tip_cells {
            mesh.cell_coords(c, &mut x);
            let [pos, neg] = subcell::side_volumes(mesh.kind, &x, &ahead);
            front += pos;
            all += pos + neg;
        }
        if front <= 1e-9 * all {
            return Err(TipError::Through);
        }
        let mut is_tip = vec![false; mesh.n_nodes()];
        if params.branch != Branch::None {
            for &c in &tip_cells {
                for &a in mesh.cell(c) {
                    is_tip[a] = true;
                }
            }
            if params.radius > 0.0 {
                for (a, &p) in mesh.nodes.iter().enumerate() {
                    if frame.distance(p) < params.radius {
                        is_tip[a] = true;
                    }
                }
            }
        }
        let cracked = (0..enr.len())
            .filter(|&k| !is_tip[enr.nodes[k]])
            .map(|k| (enr.nodes[k], enr.planes[k], enr.own_positive[k]))
            .collect();
        Ok(Self {
            cracked,
            tip_nodes: (0..mesh.n_nodes()).filter(|&a| is_tip[a]).collect(),
            tip_cells,
            params,
            frame,
        })
    }

    /// Generalized nodes: `0..n` the mesh's, then one per cracked node, then
    /// [`Branch::count`] per tip node.
    fn generalized(&self, n: usize) -> usize {
        n + self.cracked.len() + self.params.branch.count() * self.tip_nodes.len()
    }
}

/// The full-order solution with the tip enrichment.
#[derive(Debug, Clone)]
pub struct TipSolution {
    /// Displacements of the mesh nodes (`3n`).
    pub u: Vec<f64>,
    /// The enriched degrees of freedom: the cracked nodes' jumps, then the tip nodes' branch
    /// amplitudes.
    pub q: Vec<f64>,
    /// Free degrees of freedom.
    pub n_free: usize,
    /// Relative residual of the solve.
    pub residual: f64,
    /// Wall time (s).
    pub seconds: f64,
}

/// An enriched function of the whole mesh, by its node: the Heaviside of a cracked node (its
/// plane, whether the node lies on its positive side), or branch function `j` of a tip node.
#[derive(Debug, Clone, Copy)]
enum Enriched {
    Heaviside(Plane, bool),
    Branch(usize),
}

/// What one of a cell's enriched generalized functions is, for its quadrature.
#[derive(Debug, Clone, Copy)]
enum Function {
    /// The Heaviside of a cracked node: its plane's index among the cell's planes, and the
    /// node's own side.
    Heaviside { plane: usize, own_positive: bool },
    /// Branch function `j` of a tip node, with its value at the node.
    Branch { j: usize, at_node: f64 },
}

/// Splits `t` into its eight children (the midpoints of its edges).
fn refine(t: &SubTet) -> [SubTet; 8] {
    let v = t.xi;
    let m = |a: usize, b: usize| lerp(v[a], v[b], 0.5);
    let (m01, m02, m03, m12, m13, m23) = (m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3));
    [
        [v[0], m01, m02, m03],
        [m01, v[1], m12, m13],
        [m02, m12, v[2], m23],
        [m03, m13, m23, v[3]],
        [m01, m02, m03, m13],
        [m01, m02, m12, m13],
        [m02, m03, m13, m23],
        [m02, m12, m13, m23],
    ]
    .map(|xi| SubTet { xi, sides: t.sides })
}

/// The 4-point Gauss–Legendre rule on [0, 1].
const GAUSS_4: [(f64, f64); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_93),
    (0.330_009_478_207_571_9, 0.326_072_577_431_273_07),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_07),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_93),
];

/// Calls `f(ξ, w)` at the points of a rule on sub-tetrahedron `t` whose vertices `on` lie on the
/// tip line, where the integrand grows like `1/r`: with two (an edge on the line) the tet is
/// swept between that edge and the opposite one, `ξ = (1 − u)(v₀ + v e₀₁) + u(v₂ + w e₂₃)`,
/// Jacobian `6V u(1 − u)`; with one (a vertex) it is collapsed onto it, Jacobian
/// `6V (1 − u)²(1 − v)` — either vanishes like r at the line and the product is smooth, then
/// 4 × 4 × 4 Gauss–Legendre points. Weights sum to the reference volume of `t`.
fn singular_rule(t: &SubTet, on: [bool; 4], mut f: impl FnMut([f64; 3], f64)) {
    let v = t.xi;
    let six_v = 6.0 * t.reference_volume();
    let singular: Vec<usize> = (0..4).filter(|&i| on[i]).collect();
    if singular.len() >= 2 {
        let (a, b) = (singular[0], singular[1]);
        let rest: Vec<usize> = (0..4).filter(|&i| i != a && i != b).collect();
        let (c, d) = (rest[0], rest[1]);
        for &(u, wu) in &GAUSS_4 {
            for &(s, ws) in &GAUSS_4 {
                for &(r, wr) in &GAUSS_4 {
                    let xi = lerp(lerp(v[a], v[b], s), lerp(v[c], v[d], r), u);
                    f(xi, wu * ws * wr * six_v * u * (1.0 - u));
                }
            }
        }
    } else {
        // collapsed onto vertex p: ξ = p + (1 − u)[e₁ + v(e₂ − e₁) ... ]
        let p = singular[0];
        let rest: Vec<usize> = (0..4).filter(|&i| i != p).collect();
        let (a, b, c) = (v[rest[0]], v[rest[1]], v[rest[2]]);
        for &(u, wu) in &GAUSS_4 {
            for &(s, ws) in &GAUSS_4 {
                for &(r, wr) in &GAUSS_4 {
                    // a point of the opposite face, then towards the vertex
                    let face = lerp(a, lerp(b, c, r), s);
                    let xi = lerp(v[p], face, 1.0 - u);
                    f(xi, wu * ws * wr * six_v * (1.0 - u) * (1.0 - u) * s);
                }
            }
        }
    }
}

/// The matrix of a cell with enriched nodes over its generalized nodes (row-major, standard–
/// standard block zero: it is the uncut stiffness's) into `ke`; `funcs[j]` is the function of
/// generalized node `n + j`, of local node `local[j]`.
#[allow(clippy::too_many_arguments)]
fn cell_matrix(
    kind: CellKind,
    x: &[[f64; 3]],
    planes: &[Plane],
    cut_bit: usize,
    local: &[usize],
    funcs: &[Function],
    frame: &Frame,
    levels: usize,
    mu: f64,
    kappa: f64,
    volumetric: EnrichedVolumetric,
    ke: &mut Vec<f64>,
) -> Result<(), ElementError> {
    let n = kind.nodes_per_cell();
    let ng = n + funcs.len();
    ke.clear();
    ke.resize(9 * ng * ng, 0.0);
    let plain = volumetric == EnrichedVolumetric::Plain;
    let mut divergence = vec![[0.0; 3]; ng];
    let mut volume = 0.0;
    let (mut dn, mut grad) = ([[0.0; 3]; 8], [[0.0; 3]; 8]);
    let mut g = vec![[0.0; 3]; ng];
    let (mut fv, mut fg) = ([0.0; 4], [[0.0; 3]; 4]);
    let mut bad = None;
    let size = subcell::cell_size(x);
    let mut at_point = |xi: [f64; 3], w: f64, sides: u32| {
        subcell::reference_gradients(kind, xi, &mut dn);
        let det = shape::physical_gradients(x, &dn[..n], &mut grad[..n]);
        if det <= 0.0 {
            bad = Some(det);
            return;
        }
        let nv: [f64; 8] = match kind {
            CellKind::Hex8 => shape::hex_n(xi),
            CellKind::Tet4 => [1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2], 0.0, 0.0, 0.0, 0.0],
        };
        let p = subcell::map_point(kind, x, xi);
        frame.branch(p, sides >> cut_bit & 1 == 1, &mut fv, &mut fg);
        g[..n].copy_from_slice(&grad[..n]);
        for (k, f) in funcs.iter().enumerate() {
            let a = local[k];
            g[n + k] = match *f {
                Function::Heaviside { plane, own_positive } => {
                    let s = f64::from(u8::from(sides >> plane & 1 == 1)) - f64::from(u8::from(own_positive));
                    grad[a].map(|v| s * v)
                }
                Function::Branch { j, at_node } => std::array::from_fn(|i| grad[a][i] * (fv[j] - at_node) + nv[a] * fg[j][i]),
            };
        }
        let wd = w * det;
        volume += wd;
        element::add_terms(ke, ng, &g, wd, kappa, mu, plain, true);
        for (d, gp) in divergence.iter_mut().zip(&g) {
            for i in 0..3 {
                d[i] += wd * gp[i];
            }
        }
    };
    let mut stack: Vec<(SubTet, usize)> = subcell::split(kind, x, planes).into_iter().map(|t| (t, 0)).collect();
    while let Some((t, level)) = stack.pop() {
        let corners = t.xi.map(|xi| subcell::map_point(kind, x, xi));
        let on_tip = corners.map(|c| frame.distance(c) <= 1e-9 * size);
        if on_tip.iter().any(|&o| o) {
            // the tip line along an edge or through a vertex: a rule whose Jacobian vanishes
            // there, cancelling the integrand's 1/r
            singular_rule(&t, on_tip, |xi, w| at_point(xi, w, t.sides));
            continue;
        }
        let centre: [f64; 3] = std::array::from_fn(|i| 0.25 * corners.iter().map(|c| c[i]).sum::<f64>());
        let diameter = corners
            .iter()
            .enumerate()
            .flat_map(|(i, a)| corners[i + 1..].iter().map(move |b| norm(sub(*a, *b))))
            .fold(0.0, f64::max);
        if level < levels && frame.distance(centre) < diameter {
            stack.extend(refine(&t).into_iter().map(|c| (c, level + 1)));
            continue;
        }
        subcell::rich_quadrature(&t, |xi, w| at_point(xi, w, t.sides));
    }
    if let Some(det) = bad {
        return Err(ElementError::NonPositiveJacobian { det });
    }
    system::close_cell_matrix(ke, n, ng, &divergence, volume, kappa, mu, volumetric);
    Ok(())
}

/// Solves the static `problem` on `mesh` cut as `enr` says by the full-order XFEM with the
/// tip enrichment (module docs). The averaged nodal pressure is refused; a blade that has
/// reached the organ's surface was refused when the enrichment was made ([`TipError::Through`]);
/// other pieces cut loose are not looked for.
pub fn solve(
    mesh: &Mesh,
    materials: &MaterialMap,
    locking: Locking,
    problem: &StaticProblem,
    enr: &TipEnrichment,
) -> Result<TipSolution, XfemError> {
    let clock = Instant::now();
    let volumetric = EnrichedVolumetric::of(mesh.kind, locking);
    if volumetric == EnrichedVolumetric::Nodal {
        return Err(XfemError::Unsupported("the tip enrichment with the averaged nodal pressure"));
    }
    let n = mesh.n_nodes();
    let npc = mesh.kind.nodes_per_cell();
    let ng = enr.generalized(n);
    let nf = enr.params.branch.count();
    // the enriched functions, generalized node n + i for functions[i], and each node's
    let mut of_node: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut functions: Vec<(usize, Enriched)> = Vec::new();
    for &(a, plane, own) in &enr.cracked {
        of_node[a].push(functions.len());
        functions.push((a, Enriched::Heaviside(plane, own)));
    }
    for &a in &enr.tip_nodes {
        for j in 0..nf {
            of_node[a].push(functions.len());
            functions.push((a, Enriched::Branch(j)));
        }
    }
    // constraints: an enriched dof is held where its node's is
    let mut constrained = problem.constrained.clone();
    let mut prescribed = problem.prescribed.clone();
    for &(a, _) in &functions {
        for i in 0..3 {
            constrained.push(problem.constrained[3 * a + i]);
            prescribed.push(0.0);
        }
    }
    let dofs = DofMap::new(&constrained);
    let cell_gen = |c: usize, out: &mut Vec<usize>| {
        out.clear();
        out.extend_from_slice(mesh.cell(c));
        for &a in mesh.cell(c) {
            out.extend(of_node[a].iter().map(|i| n + i));
        }
    };
    let mut adj = vec![Vec::new(); ng];
    let mut cell_g = Vec::new();
    for c in 0..mesh.n_cells() {
        cell_gen(c, &mut cell_g);
        for &a in &cell_g {
            adj[a].extend_from_slice(&cell_g);
        }
    }
    for l in adj.iter_mut() {
        l.sort_unstable();
        l.dedup();
    }
    let pattern = Arc::new(SymmetricPattern::from_adjacency(&adj, &dofs));
    let mut rhs = vec![0.0; dofs.n_free()];
    let mut k = assembly::assemble_stiffness(mesh, materials, locking, &dofs, pattern, &prescribed, &mut rhs)?;
    let mut x = vec![[0.0; 3]; npc];
    let (mut ke, mut eqs) = (Vec::new(), Vec::new());
    let tip_plane = enr.frame_plane();
    let across = Plane {
        point: enr.frame.origin,
        normal: enr.frame.e[0],
    };
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        if cell.iter().all(|&a| of_node[a].is_empty()) {
            continue;
        }
        mesh.cell_coords(c, &mut x);
        // the planes crossing the cell: the cracked nodes' (each once), then the cut's and the
        // one across the tip line
        let mut planes: Vec<Plane> = Vec::new();
        let (mut local, mut funcs) = (Vec::new(), Vec::new());
        let mut has_tip = false;
        for (la, &a) in cell.iter().enumerate() {
            for &fi in &of_node[a] {
                local.push(la);
                match functions[fi].1 {
                    Enriched::Heaviside(plane, own) => {
                        let p = planes.iter().position(|q| *q == plane).unwrap_or_else(|| {
                            planes.push(plane);
                            planes.len() - 1
                        });
                        funcs.push(Function::Heaviside {
                            plane: p,
                            own_positive: own,
                        });
                    }
                    Enriched::Branch(j) => {
                        has_tip = true;
                        let mut v = [0.0; 4];
                        enr.frame.branch(mesh.nodes[a], true, &mut v, &mut [[0.0; 3]; 4]);
                        funcs.push(Function::Branch { j, at_node: v[j] });
                    }
                }
            }
        }
        let cut_bit = planes.len();
        planes.push(tip_plane);
        if has_tip {
            planes.push(across);
        }
        let mat = materials.of(c);
        cell_matrix(
            mesh.kind,
            &x,
            &planes,
            cut_bit,
            &local,
            &funcs,
            &enr.frame,
            if has_tip { enr.params.levels } else { 0 },
            mat.shear(),
            mat.bulk(),
            volumetric,
            &mut ke,
        )
        .map_err(|source| assembly::AssemblyError { cell: c, source })?;
        cell_gen(c, &mut cell_g);
        eqs.clear();
        for &a in &cell_g {
            for i in 0..3 {
                eqs.push(dofs.eq(3 * a + i));
            }
        }
        assembly::scatter_cell(&mut k, &ke, &cell_g, &eqs, Some(&prescribed), &mut rhs);
    }
    assembly::add_springs(&mut k, &dofs, &{
        let mut s = problem.springs.clone();
        s.resize(3 * ng, 0.0);
        s
    });
    for (d, f) in problem.forces.iter().enumerate() {
        if let Some(e) = dofs.eq(d) {
            rhs[e] += f;
        }
    }
    let (u, q, residual) = system::factor_and_solve(&k, &rhs, &dofs, &prescribed, n)?;
    Ok(TipSolution {
        u,
        q,
        n_free: dofs.n_free(),
        residual,
        seconds: clock.elapsed().as_secs_f64(),
    })
}

/// The reference coordinates of physical point `p` in a cell of `kind` with nodes `x` (Newton
/// on the isoparametric map; `None` when it does not converge).
fn reference_point(kind: CellKind, x: &[[f64; 3]], p: [f64; 3]) -> Option<[f64; 3]> {
    let n = kind.nodes_per_cell();
    let mut xi = match kind {
        CellKind::Hex8 => [0.0; 3],
        CellKind::Tet4 => [0.25; 3],
    };
    let mut dn = [[0.0; 3]; 8];
    for _ in 0..50 {
        let r = sub(subcell::map_point(kind, x, xi), p);
        subcell::reference_gradients(kind, xi, &mut dn);
        let mut j = nalgebra::Matrix3::zeros();
        for (xa, da) in x.iter().zip(&dn[..n]) {
            for i in 0..3 {
                for k in 0..3 {
                    j[(i, k)] += xa[i] * da[k];
                }
            }
        }
        let step = j.lu().solve(&nalgebra::Vector3::from(r))?;
        for k in 0..3 {
            xi[k] -= step[k];
        }
        if step.norm() < 1e-14 {
            return Some(xi);
        }
    }
    None
}

impl TipEnrichment {
    /// The displacement of `sol` at physical point `p` of cell `c`, on the lip `positive` of
    /// the cut's plane where `p` lies on a cut (module docs' `u(x)`); `None` when `p` cannot be
    /// located in the cell.
    pub fn displacement(&self, mesh: &Mesh, sol: &TipSolution, c: usize, p: [f64; 3], positive: bool) -> Option<[f64; 3]> {
        let kind = mesh.kind;
        let npc = kind.nodes_per_cell();
        let mut x = vec![[0.0; 3]; npc];
        mesh.cell_coords(c, &mut x);
        let xi = reference_point(kind, &x, p)?;
        let nv: [f64; 8] = match kind {
            CellKind::Hex8 => shape::hex_n(xi),
            CellKind::Tet4 => [1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2], 0.0, 0.0, 0.0, 0.0],
        };
        let (mut fv, mut fa) = ([0.0; 4], [0.0; 4]);
        let mut dummy = [[0.0; 3]; 4];
        self.frame.branch(p, positive, &mut fv, &mut dummy);
        let nf = self.params.branch.count();
        let mut u = [0.0; 3];
        for (la, &a) in mesh.cell(c).iter().enumerate() {
            let w = nv[la];
            for i in 0..3 {
                u[i] += w * sol.u[3 * a + i];
            }
            if let Some(k) = self.cracked.iter().position(|t| t.0 == a) {
                let (_, plane, own) = self.cracked[k];
                let phi = plane.phi(p);
                let here = if phi.abs() < 1e-12 { positive } else { phi > 0.0 };
                let s = f64::from(u8::from(here)) - f64::from(u8::from(own));
                for i in 0..3 {
                    u[i] += w * s * sol.q[3 * k + i];
                }
            }
            if let Some(t) = self.tip_nodes.iter().position(|&b| b == a) {
                self.frame.branch(mesh.nodes[a], true, &mut fa, &mut dummy);
                for j in 0..nf {
                    let g = 3 * (self.cracked.len() + nf * t + j);
                    for i in 0..3 {
                        u[i] += w * (fv[j] - fa[j]) * sol.q[g + i];
                    }
                }
            }
        }
        Some(u)
    }

    /// The opening of the cut at `p` (on it, in cell `c`): the displacement of its positive lip
    /// less its negative lip's, along the cut plane's normal at the tip.
    pub fn opening(&self, mesh: &Mesh, sol: &TipSolution, c: usize, p: [f64; 3]) -> Option<f64> {
        let (up, um) = (
            self.displacement(mesh, sol, c, p, true)?,
            self.displacement(mesh, sol, c, p, false)?,
        );
        Some(dot(sub(up, um), self.frame.e[1]))
    }

    /// The cut's plane at the tip line.
    fn frame_plane(&self) -> Plane {
        Plane {
            point: self.frame.origin,
            normal: self.frame.e[1],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The branch functions' gradients are their values' derivatives (central differences),
    /// on both lips and ahead of the tip.
    #[test]
    fn branch_gradients_are_the_derivatives_of_the_values() {
        let frame = Frame::new(&TipLine {
            a: [0.1, 0.2, 0.0],
            b: [0.1, 0.2, 1.0],
            normal: [0.3, 1.0, 0.0],
            forward: [1.0, -0.3, 0.0],
        })
        .unwrap();
        let (mut v, mut g) = ([0.0; 4], [[0.0; 3]; 4]);
        let (mut vp, mut vm) = ([0.0; 4], [0.0; 4]);
        let mut dummy = [[0.0; 3]; 4];
        for (p, positive) in [
            ([0.13, 0.25, 0.5], true),
            ([0.05, 0.19, 0.2], false),
            ([0.2, 0.12, 0.7], false),
            ([0.02, 0.3, 0.1], true),
        ] {
            frame.branch(p, positive, &mut v, &mut g);
            for i in 0..3 {
                let h = 1e-7;
                let (mut a, mut b) = (p, p);
                a[i] += h;
                b[i] -= h;
                frame.branch(a, positive, &mut vp, &mut dummy);
                frame.branch(b, positive, &mut vm, &mut dummy);
                for j in 0..4 {
                    let fd = (vp[j] - vm[j]) / (2.0 * h);
                    assert!(
                        (fd - g[j][i]).abs() < 1e-6 * (1.0 + fd.abs()),
                        "F{j} ∂{i} at {p:?}: {fd} against {}",
                        g[j][i]
                    );
                }
            }
        }
        // F₁ jumps by 2√r across the lips behind the tip and not ahead of it
        let behind = [0.1 - 0.04 / 1.09f64.sqrt(), 0.2 + 0.012 / 1.09f64.sqrt(), 0.5];
        frame.branch(behind, true, &mut vp, &mut dummy);
        frame.branch(behind, false, &mut vm, &mut dummy);
        assert!((vp[0] - vm[0] - 2.0 * 0.04f64.sqrt()).abs() < 1e-12, "{} {}", vp[0], vm[0]);
        let ahead = [0.1 + 0.04 / 1.09f64.sqrt(), 0.2 - 0.012 / 1.09f64.sqrt(), 0.5];
        frame.branch(ahead, true, &mut vp, &mut dummy);
        frame.branch(ahead, false, &mut vm, &mut dummy);
        assert!((vp[0] - vm[0]).abs() < 1e-12);
    }

    /// The singular rules integrate polynomials like any rule (the volume, a quadratic), and
    /// `1/r` at the edge or the vertex they collapse onto to a few parts in a thousand.
    #[test]
    fn the_singular_rules_integrate_the_volume_and_one_over_r() {
        let t = SubTet {
            xi: [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            sides: 0,
        };
        let vol = t.reference_volume();
        for on in [[true, true, false, false], [true, false, false, false]] {
            let (mut v, mut q) = (0.0, 0.0);
            singular_rule(&t, on, |xi, w| {
                v += w;
                q += w * xi[0] * xi[1];
            });
            assert!((v - vol).abs() < 1e-14, "{on:?}: {v}");
            // ∫ xy over the tetrahedron x, y, z ≥ 0, x + y + z ≤ 1: 1/120
            assert!((q - 1.0 / 120.0).abs() < 1e-14, "{on:?}: {q}");
        }
        // ∫ 1/√(x² + y²) over it, r the distance from its edge on the z axis: π/4 − ... by the
        // polar form ∫₀^{π/2} ∫₀^{R(θ)} (1/r)(1 − r(cos θ + sin θ)) r dr dθ (R = 1/(cos + sin))
        // = ∫ R − R²(cos + sin)/2 dθ = ½ ∫ dθ/(cos θ + sin θ) = ½ · √2 · ln(1 + √2)
        let exact = 0.5 * std::f64::consts::SQRT_2 * (1.0 + std::f64::consts::SQRT_2).ln();
        let mut e = 0.0;
        singular_rule(&t, [true, true, false, false], |xi, w| {
            e += w / (xi[0] * xi[0] + xi[1] * xi[1]).sqrt()
        });
        assert!((e - exact).abs() < 3e-3 * exact, "{e} against {exact}");
    }

    #[test]
    fn the_refined_children_fill_their_parent() {
        let t = SubTet {
            xi: [[0.0, 0.0, 0.0], [1.0, 0.2, 0.0], [0.1, 0.9, 0.3], [0.2, 0.1, 1.1]],
            sides: 3,
        };
        let sum: f64 = refine(&t).iter().map(SubTet::reference_volume).sum();
        assert!((sum - t.reference_volume()).abs() < 1e-14);
        assert!(
            refine(&t)
                .iter()
                .all(|c| c.sides == 3 && (c.reference_volume() - t.reference_volume() / 8.0).abs() < 1e-14)
        );
    }
}
