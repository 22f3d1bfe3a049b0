//! Co-rotational cutting in a session (seed 003, `fidelity.cutting = "corotational_xfem"`):
//! the multi-rate coupling of the haptic tick with a co-rotational XFEM deformation advanced
//! at the frame rate.
//!
//! # Two rates
//! The tick (1 kHz) keeps the force of the cutting effect ([`super::cutting`]): the reduced
//! model's compliance at the contact plus the cut's, `C(s_L) + ΔC_cut(s_L)`. Beside it, the
//! frame thread advances the co-rotational XFEM of the organ as cut so far
//! ([`crate::xfem::corotational::Frames`]: one modified-Newton correction per frame with a
//! factor of the warped stiffness made on a factor thread from a recent state), under the
//! scene's own loads (`[[organs.loads]]`: gravity, a retractor holding a lip; ramped in over
//! the first [`RAMP_FRAMES`] frames) and the tick's latest tissue force at the contact. What
//! viewers and recordings draw is this deformation: the organ's surface, the walls of the cut
//! and the visual mesh, split along the cut and following each side
//! ([`crate::xfem::visual_split`], [`crate::xfem::visual::Embedding`]).
//!
//! # The coupling: a tangent correction of the compliance
//! Each frame with a contact also leaves the tick the difference, at the contact, between
//! the compliance of the co-rotational model's warped stiffness at its current state and at
//! rest (same mesh, same cut, same element):
//!
//! `ΔC_rot = Pᵀ K_w(d)⁻¹ P − Pᵀ K_0⁻¹ P`,
//!
//! `P` the contact's barycentric load distribution. The tick's force becomes
//! `f = λ (C + ΔC_cut + ΔC_rot)⁻¹ δ`: with no rotation (small strains) `ΔC_rot = 0` and the
//! force is the reduced model's exactly; where the tissue has turned (a flap lifted, the organ
//! pre-loaded by the scene) the local stiffness the hand feels is the one of the deformation
//! shown. A correction applies while the tick's contact triangle shares a node with the one it
//! was computed at; a corrected compliance whose symmetric part is not positive definite is
//! not used (counted).
//!
//! `K_w(d)` is the warped stiffness at the state the frame reached. The frame thread holds a
//! factor of it at an earlier state (the factor thread's, a frame or more behind, or frozen
//! under load); served from that factor alone the correction would be the compliance of that
//! older state — 2.6 % of itself off on a cantilever bent by more than 15°, and a lag that
//! grows with how fast the tissue moves. So the frame assembles `K_w(d)` and solves for the
//! three columns by conjugate gradients with the older factor as preconditioner
//! ([`deformed_compliance`], to 1e-8): the correction is the deformation's own, and what the
//! solve left is carried as its spread ([`Correction::spread`]). The cost: one assembly and a
//! few iterations per frame with a contact (on `liver_cut` the frames went from 8.3–8.6 to
//! 9.7–10.4 ms mean).
//!
//! # The error estimate of a corrected force
//! Against the co-rotational model at the deformation shown, the tick's force under the
//! blended correction is off by what the blend has still to move and by what the correction's
//! solve left: `|f − f_target| + max_± |f(ΔC_target ± spread) − f_target|`
//! ([`corrected_force_error`]), added to the cut's own ([`super::cutting::force_error`]).
//! `vademecum study` checks it by replaying a press frame by frame against a fresh factor at
//! each frame's state (`study::estimate::corotational_samples`).
//!
//! # The landing of a frame
//! A new correction would change the force at once, by `|f(ΔC_new) − f(ΔC_old)|` at the same
//! imposed displacement. The tick blends it in instead ([`Blend`]): linearly over
//! [`BLEND_TICKS`] ticks (a frame at 30 Hz), from the correction in effect when it landed, so
//! the force moves by a thirty-second of that step per tick. Both are measured by the tick in
//! [`super::cutting::CutStatus`]: the whole step of each landing (`landings`,
//! `landing_jump_max_un`, `landing_jump_sum_un`) and the largest step between two ticks while
//! blending (`blend_step_max_un`).
//!
//! The frame thread runs its parallel work (forces, factorization) in its own rayon pool of
//! [`pool_threads`] threads — one fewer than the machine's cores — so that it never takes
//! every core, and the pool, the factor thread and the frame thread of a co-rotational session
//! run at the lowest CPU priority ([`super::lower_thread_priority`]): the tick thread takes a core from them
//! as soon as it wakes.

use std::sync::Arc;
use std::sync::mpsc;

use crate::fem::assembly::{MaterialMap, SymmetricMatrix};
use crate::fem::linear_static::StaticProblem;
use crate::mesh::Mesh;
use crate::solve::Cholesky;
use crate::xfem::XfemError;
use crate::xfem::corotational::{CorotationalError, CorotationalXfem, FrameReport, Frames};
use crate::xfem::enrichment::Enrichment;
use crate::xfem::visual::{Embedding, VisualError, VisualMesh};
use crate::xfem::visual_split::{self, VertexSide};

use super::Contact;
use super::cut_picture::CutPicture;

/// Frames over which the scene's loads are ramped in from rest.
pub const RAMP_FRAMES: u64 = 10;

/// What the frame thread leaves the tick: the compliance correction `ΔC_rot` at a contact
/// (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Correction {
    /// 0: none yet; then one more per frame that computed one.
    pub seq: u64,
    /// The contact triangle it was computed at.
    pub nodes: [usize; 3],
    /// `ΔC_rot` (m/N), symmetric.
    pub delta: [[f64; 3]; 3],
    /// A bound on how far `delta` may be from the deformation's compliance, entry by entry
    /// (m/N): what the solve left ([`deformed_compliance`]).
    pub spread: [[f64; 3]; 3],
}

impl Correction {
    /// Whether it applies to a contact on triangle `nodes` (module docs).
    pub fn applies_to(&self, nodes: &[usize; 3]) -> bool {
        self.seq > 0 && nodes.iter().any(|a| self.nodes.contains(a))
    }
}

/// The tick's end of the corrections.
pub type Corrections = triple_buffer::Output<Correction>;

/// Ticks over which the tick blends a new correction in (about one frame at 30 Hz).
pub const BLEND_TICKS: u32 = 32;

/// The correction the tick applies: each new one blended in from the one applied when it
/// landed, linearly over [`BLEND_TICKS`] ticks, so that a landing frame changes the force by a
/// thirty-second of its step per tick instead of all at once (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Blend {
    target: Correction,
    from: [[f64; 3]; 3],
    ticks: u32,
}

impl Blend {
    /// Takes the latest correction `latest` at a tick whose contact is on triangle `nodes`
    /// (`None`: no contact); returns whether it is new. The blend restarts from the correction
    /// in effect at that contact.
    pub fn land(&mut self, latest: Correction, nodes: Option<&[usize; 3]>) -> bool {
        if latest.seq == self.target.seq {
            self.ticks = self.ticks.saturating_add(1);
            return false;
        }
        self.from = nodes.and_then(|n| self.delta(n, self.ticks)).unwrap_or_default();
        self.target = latest;
        self.ticks = 0;
        true
    }

    /// `ΔC_rot` in effect at a contact on `nodes`, `ticks` ticks after the latest landed
    /// (`None`: none applies there).
    pub fn delta(&self, nodes: &[usize; 3], ticks: u32) -> Option<[[f64; 3]; 3]> {
        if !self.target.applies_to(nodes) {
            return None;
        }
        let a = (f64::from(ticks) / f64::from(BLEND_TICKS)).min(1.0);
        Some(std::array::from_fn(|i| {
            std::array::from_fn(|j| self.from[i][j] + a * (self.target.delta[i][j] - self.from[i][j]))
        }))
    }

    /// Ticks since the latest correction landed.
    pub fn ticks(&self) -> u32 {
        self.ticks
    }

    /// The latest correction, fully blended in (what the blend moves towards).
    pub fn target(&self) -> &Correction {
        &self.target
    }

    /// The correction in effect when the latest landed.
    pub fn from(&self) -> [[f64; 3]; 3] {
        self.from
    }
}

/// The contact's load distribution `P` on the free dofs of `model`: three columns of `nf`,
/// column `i` the unit force along axis `i` spread by the contact's weights.
fn load_columns(model: &CorotationalXfem, nf: usize, c: &Contact) -> Vec<f64> {
    let mut p = vec![0.0; 3 * nf];
    for i in 0..3 {
        for (&a, &w) in c.nodes.iter().zip(&c.weights) {
            if let Some(e) = model.free_index(3 * a + i) {
                p[i * nf + e] += w;
            }
        }
    }
    p
}

/// `Pᵀ X` of two sets of three columns of length `nf`, symmetrised.
fn gram(p: &[f64], x: &[f64], nf: usize) -> [[f64; 3]; 3] {
    let dot = |i: usize, j: usize| {
        p[i * nf..(i + 1) * nf]
            .iter()
            .zip(&x[j * nf..(j + 1) * nf])
            .map(|(a, b)| a * b)
            .sum::<f64>()
    };
    let m: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| dot(i, j)));
    std::array::from_fn(|i| std::array::from_fn(|j| 0.5 * (m[i][j] + m[j][i])))
}

/// The compliance `Pᵀ K⁻¹ P` at contact `c` (m/N) of the co-rotational model `model` whose
/// stiffness `factor` factors (`P` the contact's barycentric load distribution): the rest
/// stiffness gives its linear compliance.
pub fn contact_compliance(model: &CorotationalXfem, factor: &Cholesky, c: &Contact) -> [[f64; 3]; 3] {
    let nf = factor.n();
    let p = load_columns(model, nf, c);
    let mut x = p.clone();
    factor.solve_many_in_place(&mut x, 3);
    gram(&p, &x, nf)
}

/// Relative residual at which [`deformed_compliance`] stops.
pub const COMPLIANCE_TOLERANCE: f64 = 1e-8;

/// Most conjugate-gradient iterations per column of [`deformed_compliance`].
pub const COMPLIANCE_ITERATIONS: usize = 100;

/// The compliance `Pᵀ K⁻¹ P` at contact `c` of the co-rotational model at the deformation
/// shown, `K = k` its warped stiffness there, by conjugate gradients preconditioned by
/// `factor` — the factor thread's factor of the warped stiffness at an earlier state, a frame
/// or more behind — from that factor's solution, to [`COMPLIANCE_TOLERANCE`] (at most
/// [`COMPLIANCE_ITERATIONS`] per column). The factor alone would serve the compliance of the
/// state it was made at: a lag of a share of the correction while the tissue moves (2.6 % on
/// a cantilever bent by more than 15° with a frozen factor), which a few iterations remove.
/// Returns the compliance (symmetric) and its spread: with `r_j` the residual left in column
/// `j`, `|p_iᵀ(K⁻¹p_j − x_j)| ≤ √(p_iᵀK⁻¹p_i · r_jᵀK⁻¹r_j)` (Cauchy–Schwarz in the energy
/// inner product), `K⁻¹` taken as the preconditioner's in the bound — infinite for a column
/// the iterations did not bring to the tolerance. Allocates: the frame thread's work, not the
/// tick's.
pub fn deformed_compliance(
    model: &CorotationalXfem,
    k: &SymmetricMatrix,
    factor: &Cholesky,
    c: &Contact,
) -> ([[f64; 3]; 3], [[f64; 3]; 3], CorrectionSolve) {
    let nf = factor.n();
    let p = load_columns(model, nf, c);
    let mut x = p.clone();
    factor.solve_many_in_place(&mut x, 3);
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>();
    let (mut r, mut z, mut q, mut kq) = (vec![0.0; nf], vec![0.0; nf], vec![0.0; nf], vec![0.0; nf]);
    let mut energy = [0.0; 3];
    let mut solve = CorrectionSolve {
        iterations: 0,
        converged: true,
    };
    for j in 0..3 {
        let (pj, xj) = (&p[j * nf..(j + 1) * nf], &mut x[j * nf..(j + 1) * nf]);
        let scale = dot(pj, pj).sqrt();
        k.mul_vec(xj, &mut r);
        r.iter_mut().zip(pj).for_each(|(rv, pv)| *rv = pv - *rv);
        z.copy_from_slice(&r);
        factor.solve_in_place(&mut z);
        q.copy_from_slice(&z);
        let mut rz = dot(&r, &z);
        let mut converged = false;
        let mut iterations = 0;
        for _ in 0..COMPLIANCE_ITERATIONS {
            if dot(&r, &r).sqrt() <= COMPLIANCE_TOLERANCE * scale || rz <= 0.0 {
                converged = true;
                break;
            }
            iterations += 1;
            k.mul_vec(&q, &mut kq);
            let alpha = rz / dot(&q, &kq);
            xj.iter_mut().zip(&q).for_each(|(xv, qv)| *xv += alpha * qv);
            r.iter_mut().zip(&kq).for_each(|(rv, kv)| *rv -= alpha * kv);
            z.copy_from_slice(&r);
            factor.solve_in_place(&mut z);
            let next = dot(&r, &z);
            let beta = next / rz;
            rz = next;
            q.iter_mut().zip(&z).for_each(|(qv, zv)| *qv = zv + beta * *qv);
        }
        converged |= dot(&r, &r).sqrt() <= COMPLIANCE_TOLERANCE * scale;
        solve.iterations = solve.iterations.max(iterations);
        solve.converged &= converged;
        // a solve that did not converge leaves no bound: the force it shapes has no estimate
        energy[j] = if converged { rz.max(0.0) } else { f64::INFINITY };
    }
    let cw = gram(&p, &x, nf);
    let spread =
        std::array::from_fn(|i| std::array::from_fn(|j| (cw[i][i].abs() * energy[j]).sqrt().max((cw[j][j].abs() * energy[i]).sqrt())));
    (cw, spread, solve)
}

/// The error estimate (N) of a force `f` a blended rotation correction shaped, against the
/// co-rotational model's tangent at the deformation shown: `|f − f_target| + max_± |f_± −
/// f_target|`, with `force(ΔC)` the force the tick serves under a correction `ΔC`,
/// `f_target = force(target.delta)` under the latest correction fully blended in and
/// `f_± = force(target.delta ± target.spread)` ([`Correction::spread`]; `None` where `force`
/// has none — the compliance is not positive definite —, and then so is the estimate). The
/// first term is what the blend has still to move; the second, what the correction's solve
/// left. No allocation (the tick's).
pub fn corrected_force_error(f: [f64; 3], target: &Correction, force: impl Fn([[f64; 3]; 3]) -> Option<[f64; 3]>) -> Option<f64> {
    let shifted =
        |sign: f64| -> [[f64; 3]; 3] { std::array::from_fn(|i| std::array::from_fn(|j| target.delta[i][j] + sign * target.spread[i][j])) };
    let (t, a, b) = (force(target.delta)?, force(shifted(1.0))?, force(shifted(-1.0))?);
    let dist = |u: [f64; 3], v: [f64; 3]| (0..3).map(|k| (u[k] - v[k]).powi(2)).sum::<f64>().sqrt();
    Some(dist(f, t) + dist(a, t).max(dist(b, t)))
}

/// Threads of the frame thread's pool: one fewer than the machine's cores (at least one).
pub fn pool_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get().saturating_sub(1).max(1))
}

/// Why a session's co-rotational deformation could not start or take a cut.
#[derive(Debug, thiserror::Error)]
pub enum DeformationError {
    /// Its thread pool could not start.
    #[error("cannot start the co-rotational pool: {0}")]
    Pool(#[from] rayon::ThreadPoolBuildError),
    /// Its factor thread could not start.
    #[error("cannot start the factor thread: {0}")]
    Thread(#[source] std::io::Error),
    /// The model of the cut or its factor could not be made.
    #[error(transparent)]
    Model(#[from] XfemError),
    /// The visual mesh (`split`: as split along the cut) cannot be embedded in the cells.
    #[error("the {}visual mesh cannot be embedded: {source}", if *split { "split " } else { "" })]
    Embedding {
        /// Whether it is the mesh split along the cut.
        split: bool,
        /// Why not.
        source: VisualError,
    },
}

/// The visual mesh as split along the cut at one revision, and its embedding.
#[derive(Debug, Clone)]
pub struct VisualSurface {
    /// The cut revision it was split for (0: uncut).
    pub revision: u64,
    /// Vertices (m, reference) and triangles, outward.
    pub mesh: Arc<VisualMesh>,
    /// Per vertex, which side of the cut it follows.
    pub side: Arc<[VertexSide]>,
    /// Why the surface is not split along the whole cut at this revision (a cut of several
    /// planes: split along its largest planar part only, or drawn unsplit), if it is not.
    pub unsplit: Option<String>,
    embedding: Embedding,
}

/// The co-rotational model at one cut revision.
struct State {
    revision: u64,
    enrichment: Arc<Enrichment>,
    frames: Frames,
    /// The warped stiffness at rest, `K_0`, for `ΔC_rot`.
    rest: Cholesky,
}

/// A factorization asked of the factor thread: the model, the state, the symbolic analysis.
type FactorJob = (
    Arc<CorotationalXfem>,
    Vec<f64>,
    Option<faer::sparse::linalg::solvers::SymbolicLlt<usize>>,
);

/// What one frame did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrameOutcome {
    /// The frame's report (`None`: no model, see [`CorotationalDeformation::failure`]).
    pub report: Option<FrameReport>,
    /// Whether the cut grew since the last frame (a new model, a new visual split).
    pub rebuilt: bool,
    /// Whether a factor from the factor thread was installed before this frame.
    pub installed: bool,
    /// Whether this frame refused a new cut (the model stays at its last one; see
    /// [`CorotationalDeformation::failure`]).
    pub refused_cut: bool,
    /// Pieces the cut so far has set loose from every support, held where they came loose by
    /// the model's soft foundation ([`CorotationalXfem::loose_pieces`]).
    pub held_pieces: usize,
    /// Whether the frame ran at the reduced fidelity: it asked the factor thread for no new
    /// factor ([`CorotationalDeformation::set_reduced`]).
    pub frozen: bool,
    /// The frame's correction solve ([`deformed_compliance`]), if it made a correction.
    pub correction: Option<CorrectionSolve>,
}

/// How a frame's correction solve went ([`deformed_compliance`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CorrectionSolve {
    /// Conjugate-gradient iterations of the slowest of the three columns.
    pub iterations: usize,
    /// Whether every column reached [`COMPLIANCE_TOLERANCE`].
    pub converged: bool,
}

/// The co-rotational deformation of a cut organ, advanced one frame at a time on the frame
/// thread (module docs).
pub struct CorotationalDeformation {
    organ: usize,
    mesh: Mesh,
    materials: MaterialMap,
    problem: StaticProblem,
    visual: Option<VisualMesh>,
    surface: Option<VisualSurface>,
    state: Option<State>,
    pool: Arc<rayon::ThreadPool>,
    jobs: mpsc::SyncSender<FactorJob>,
    factors: mpsc::Receiver<(Arc<CorotationalXfem>, Result<Cholesky, XfemError>)>,
    busy: bool,
    frames: u64,
    corrections: triple_buffer::Input<Correction>,
    correction_seq: u64,
    forces: Vec<f64>,
    prescribed: Vec<f64>,
    failure: Option<String>,
    held_pieces: usize,
    /// At the reduced fidelity: no new factor asked ([`Self::set_reduced`]).
    reduced: bool,
    /// Each frame installs the factor the frame before asked for ([`Self::set_deterministic`]).
    deterministic: bool,
    /// Factors the factor thread made and the frames installed.
    pub factors_installed: u64,
}

impl std::fmt::Debug for CorotationalDeformation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CorotationalDeformation")
            .field("organ", &self.organ)
            .field("revision", &self.revision())
            .field("frames", &self.frames)
            .finish_non_exhaustive()
    }
}

impl CorotationalDeformation {
    /// The deformation of organ `organ` (its `mesh`, `materials`, supports and loads
    /// `problem`), drawn on `visual` if given; returns it and the tick's end of the
    /// corrections. Starts the factor thread; builds the uncut model.
    pub fn new(
        organ: usize,
        mesh: Mesh,
        materials: MaterialMap,
        problem: StaticProblem,
        visual: Option<VisualMesh>,
    ) -> Result<(Self, Corrections), DeformationError> {
        let pool = Arc::new(
            rayon::ThreadPoolBuilder::new()
                .num_threads(pool_threads())
                .thread_name(|i| format!("corot-{i}"))
                .start_handler(|_| super::lower_thread_priority())
                .build()?,
        );
        let (jobs, job_rx) = mpsc::sync_channel::<FactorJob>(1);
        let (factor_tx, factors) = mpsc::channel();
        let factor_pool = pool.clone();
        std::thread::Builder::new()
            .name("corot-factor".into())
            .spawn(move || {
                super::lower_thread_priority();
                while let Ok((model, d, symbolic)) = job_rx.recv() {
                    let f = factor_pool.install(|| model.factor_at(&d, symbolic));
                    if factor_tx.send((model, f)).is_err() {
                        break;
                    }
                }
            })
            .map_err(DeformationError::Thread)?;
        let (corrections, output) = triple_buffer::triple_buffer(&Correction::default());
        let n = 3 * mesh.n_nodes();
        let surface = match &visual {
            Some(v) => Some(Self::unsplit_surface(&mesh, v, 0, None)?),
            None => None,
        };
        let mut me = Self {
            organ,
            materials,
            problem,
            visual,
            surface,
            state: None,
            pool,
            jobs,
            factors,
            busy: false,
            frames: 0,
            corrections,
            correction_seq: 0,
            forces: vec![0.0; n],
            prescribed: Vec::new(),
            failure: None,
            held_pieces: 0,
            reduced: false,
            deterministic: false,
            factors_installed: 0,
            mesh,
        };
        let none = Arc::new(Enrichment::none(&me.mesh));
        me.rebuild(0, none)?;
        Ok((me, output))
    }

    /// The organ (its index in the scene).
    pub fn organ(&self) -> usize {
        self.organ
    }

    /// Runs the next frames at the reduced fidelity (`reduced`: the session's ticks come
    /// close to their deadline) or the scene's: reduced, a frame asks the factor thread for no
    /// new factor of the warped stiffness — its corrections keep the last factor installed (a
    /// modified Newton with the tangent frozen; a frame whose correction would not lower the
    /// residual still factors itself, so the deformation still converges, more slowly when the
    /// tissue turns far), and the factorizations, most of the co-rotational work beside the
    /// tick (`BENCHMARKS.md`), stop taking CPU. A factor already asked for still lands.
    pub fn set_reduced(&mut self, reduced: bool) {
        self.reduced = reduced;
    }

    /// Makes each frame wait for the factor the frame before asked of the factor thread and
    /// install it (`true`: a headless run, whose deformation and corrections are then the same
    /// on any load), instead of installing a factor whenever one has landed (`false`, the
    /// default: a live session's frames never wait).
    pub fn set_deterministic(&mut self, deterministic: bool) {
        self.deterministic = deterministic;
    }

    /// The cut revision of the model (0: uncut).
    pub fn revision(&self) -> u64 {
        self.state.as_ref().map_or(0, |s| s.revision)
    }

    /// Frames advanced.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Why the model stopped at its revision (a cut it could not take: the model or its
    /// factor could not be made), if it did.
    pub fn failure(&self) -> Option<&str> {
        self.failure.as_deref()
    }

    /// The visual surface at the model's revision (`None`: the organ has none).
    pub fn visual(&self) -> Option<&VisualSurface> {
        self.surface.as_ref()
    }

    /// The generalized displacements: the mesh's nodes', then the enriched nodes' jumps.
    pub fn d(&self) -> &[f64] {
        self.state.as_ref().map_or(&[], |s| s.frames.d())
    }

    /// The enrichment of the model's cut.
    pub fn enrichment(&self) -> Option<&Enrichment> {
        self.state.as_ref().map(|s| &*s.enrichment)
    }

    fn unsplit_surface(mesh: &Mesh, visual: &VisualMesh, revision: u64, why: Option<String>) -> Result<VisualSurface, DeformationError> {
        let embedding = Embedding::new(mesh, &visual.vertices).map_err(|source| DeformationError::Embedding { split: false, source })?;
        Ok(VisualSurface {
            revision,
            side: vec![VertexSide::Own; visual.vertices.len()].into(),
            mesh: Arc::new(visual.clone()),
            unsplit: why,
            embedding,
        })
    }

    /// The visual mesh split along the cut `enr`: along its plane when it is one; along its
    /// largest planar part when it is several (strokes meeting), the rest drawn unsplit, each
    /// vertex following the side it lies on; wholly unsplit when no part is planar.
    fn split_surface(&self, revision: u64, enr: &Enrichment) -> Result<Option<VisualSurface>, DeformationError> {
        let Some(visual) = &self.visual else { return Ok(None) };
        let split_along = |plane: &crate::xfem::Plane, cut: &[(usize, crate::xfem::Plane)]| {
            let cells: Vec<usize> = cut.iter().map(|c| c.0).collect();
            visual_split::split(visual, &self.mesh, plane, &cells)
        };
        let whole = visual_split::cut_plane_of_cells(&self.mesh, &enr.cut_cells, visual_split::SESSION_PLANARITY)
            .and_then(|plane| plane.map(|p| split_along(&p, &enr.cut_cells)).transpose());
        let (split, why) = match whole {
            Ok(Some(s)) => (Some(s), None),
            Ok(None) => (None, None),
            Err(e) => {
                let part = visual_split::largest_planar_part(&self.mesh, &enr.cut_cells, visual_split::SESSION_PLANARITY)
                    .and_then(|(plane, group)| split_along(&plane, &group).ok().map(|s| (s, group.len())));
                match part {
                    Some((s, n)) => {
                        let why = format!(
                            "split along the largest planar part of the cut only ({n} of {} cut cells): {e}",
                            enr.cut_cells.len()
                        );
                        (Some(s), Some(why))
                    }
                    None => (None, Some(format!("drawn unsplit: {e}"))),
                }
            }
        };
        if let Some(w) = &why {
            tracing::warn!("the visual mesh is {w}");
        }
        let mut surface = match split {
            Some(s) => VisualSurface {
                revision,
                embedding: Embedding::new(&self.mesh, &s.surface.vertices)
                    .map_err(|source| DeformationError::Embedding { split: true, source })?
                    .with_sides(&s.side),
                mesh: Arc::new(s.surface),
                side: s.side.into(),
                unsplit: why,
            },
            None => Self::unsplit_surface(&self.mesh, visual, revision, why)?,
        };
        surface.embedding.follow_cut(&self.mesh, enr, &surface.mesh.vertices);
        Ok(Some(surface))
    }

    /// The model of the cut `enr` at `revision`, continuing from the current state.
    fn rebuild(&mut self, revision: u64, enr: Arc<Enrichment>) -> Result<(), DeformationError> {
        let mut model = self
            .pool
            .install(|| CorotationalXfem::new(&self.mesh, &self.materials, &self.problem, &enr))?;
        let d = match &self.state {
            Some(s) => model.carry_over(s.frames.d(), &s.enrichment, &enr),
            None => vec![0.0; model.n_dofs()],
        };
        // a piece cut loose is held where it came loose
        let held = model.loose_pieces().len();
        if held > self.held_pieces {
            for (copies, free) in &model.loose_pieces()[self.held_pieces..] {
                tracing::info!(
                    "the cut sets a piece of {} copies loose from every support (free: {}); it is held where it came loose",
                    copies.len(),
                    free.join(", ")
                );
            }
        }
        model.anchor_loose(&d, self.state.as_ref().map(|s| &**s.frames.model()));
        let model = Arc::new(model);
        let rest = self.pool.install(|| model.factor_at(&vec![0.0; model.n_dofs()], None))?;
        let surface = self.split_surface(revision, &enr)?;
        self.prescribed = model.prescribed().to_vec();
        self.held_pieces = held;
        self.state = Some(State {
            revision,
            enrichment: enr,
            frames: model.frames_from(d),
            rest,
        });
        if surface.is_some() {
            self.surface = surface;
        }
        self.busy = false; // a factor of the old model is dropped when it lands
        Ok(())
    }

    /// One frame of a session: [`Self::step`] with the cut of the cut thread's latest
    /// picture.
    pub fn step_with_picture(
        &mut self,
        picture: Option<&CutPicture>,
        contact: Option<&Contact>,
    ) -> Result<FrameOutcome, CorotationalError> {
        let cut = picture.filter(|p| p.organ == self.organ).map(|p| (p.revision, &p.enrichment));
        self.step(cut, contact)
    }

    /// One frame: takes the cut `(revision, enrichment)` if it is newer than the model's (a
    /// new model carrying the state over, the visual mesh split again), sets the loads (the
    /// scene's, ramped, and the tissue force of `contact`), installs a factor the factor
    /// thread finished and asks it for the next, advances the deformation one correction and
    /// publishes `ΔC_rot` at the contact for the tick.
    pub fn step(&mut self, cut: Option<(u64, &Arc<Enrichment>)>, contact: Option<&Contact>) -> Result<FrameOutcome, CorotationalError> {
        let mut outcome = FrameOutcome::default();
        // deterministic: the factor the frame before asked for, waited for (before a rebuild,
        // so that none of an old model is left in flight)
        let mut waited = (self.deterministic && self.busy).then(|| self.factors.recv().ok()).flatten();
        if let Some((revision, enr)) = cut.filter(|c| c.0 > self.revision())
            && self.failure.is_none()
        {
            match self.rebuild(revision, enr.clone()) {
                Ok(()) => outcome.rebuilt = true,
                Err(e) => {
                    tracing::warn!("the co-rotational model stays at cut revision {}: {e}", self.revision());
                    self.failure = Some(e.to_string());
                    outcome.refused_cut = true;
                }
            }
        }
        // a factor that landed (of the current model only)
        while let Some((model, factor)) = waited.take().or_else(|| self.factors.try_recv().ok()) {
            self.busy = false;
            if let (Some(s), Ok(f)) = (&mut self.state, factor)
                && Arc::ptr_eq(&model, s.frames.model())
            {
                s.frames.install(f);
                self.factors_installed += 1;
                outcome.installed = true;
            }
        }
        let Some(s) = &mut self.state else { return Ok(outcome) };
        // the loads: the scene's, ramped in, and the tool's
        self.frames += 1;
        let ramp = (self.frames as f64 / RAMP_FRAMES as f64).min(1.0);
        for (f, g) in self.forces.iter_mut().zip(&self.problem.forces) {
            *f = ramp * g;
        }
        if let Some(c) = contact.filter(|c| c.organ == self.organ) {
            for (&a, &w) in c.nodes.iter().zip(&c.weights) {
                for k in 0..3 {
                    self.forces[3 * a + k] += w * c.tissue_force_n[k];
                }
            }
        }
        s.frames.set_forces(&self.forces);
        let report = self.pool.install(|| s.frames.step(1.0, &self.prescribed))?;
        outcome.report = Some(report);
        outcome.held_pieces = self.held_pieces;
        outcome.frozen = self.reduced;
        if !self.busy && !self.reduced {
            let job = (s.frames.model().clone(), s.frames.d().to_vec(), s.frames.symbolic());
            self.busy = self.jobs.try_send(job).is_ok();
        }
        if let Some(c) = contact.filter(|c| c.organ == self.organ)
            && let Some((delta, spread, solve)) = self.rotation_compliance(c)
        {
            outcome.correction = Some(solve);
            self.correction_seq += 1;
            self.corrections.write(Correction {
                seq: self.correction_seq,
                nodes: c.nodes,
                delta,
                spread,
            });
        }
        Ok(outcome)
    }

    /// `ΔC_rot` at contact `c` (module docs) at the deformation shown
    /// ([`deformed_compliance`], the factor the frames hold its preconditioner), and its spread.
    #[allow(clippy::type_complexity)]
    fn rotation_compliance(&self, c: &Contact) -> Option<([[f64; 3]; 3], [[f64; 3]; 3], CorrectionSolve)> {
        let s = self.state.as_ref()?;
        let model = s.frames.model();
        let warped = s.frames.factor()?;
        let ((cw, spread, solve), c0) = self.pool.install(|| {
            let k = model.tangent(s.frames.d());
            (deformed_compliance(model, &k, warped, c), contact_compliance(model, &s.rest, c))
        });
        // both symmetric (`gram`)
        let delta: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| cw[i][j] - c0[i][j]));
        delta.iter().flatten().all(|v| v.is_finite()).then_some((delta, spread, solve))
    }

    /// The displacement (m) of mesh nodes `nodes` on their own side, 3 per node, into `out`.
    pub fn node_displacements(&self, nodes: &[usize], out: &mut [f32]) {
        let d = self.d();
        if d.is_empty() {
            return;
        }
        for (&a, o) in nodes.iter().zip(out.chunks_exact_mut(3)) {
            for k in 0..3 {
                o[k] = d[3 * a + k] as f32;
            }
        }
    }

    /// The embedding of `points` (e.g. the partial cut's vertices,
    /// [`super::cutting::PartialCut`]) in the organ's cells, each following the mean of the two
    /// sides of any cut near it: what [`Self::point_displacements`] evaluates.
    pub fn embed_points(&self, points: &[[f64; 3]]) -> Result<Embedding, VisualError> {
        let e = Embedding::new(&self.mesh, points)?;
        Ok(e.with_sides(&vec![VertexSide::Mean; points.len()]))
    }

    /// The displacement (m) of `points`, embedded by [`Self::embed_points`], 3 per point, into
    /// `out` (empty before the first frame).
    pub fn point_displacements(&self, embedding: &Embedding, points: &[[f64; 3]], out: &mut Vec<f64>) {
        out.clear();
        let Some(s) = &self.state else { return };
        out.resize(3 * points.len(), 0.0);
        embedding.displacements(&self.mesh, &s.enrichment, points, s.frames.d(), out);
    }

    /// The displacement (m) of every vertex of the visual surface, 3 per vertex, into `out`
    /// (empty without a visual mesh).
    pub fn visual_displacements(&self, out: &mut Vec<f64>) {
        out.clear();
        let (Some(v), Some(s)) = (&self.surface, &self.state) else { return };
        out.resize(3 * v.mesh.vertices.len(), 0.0);
        v.embedding
            .displacements(&self.mesh, &s.enrichment, &v.mesh.vertices, s.frames.d(), out);
    }
}
