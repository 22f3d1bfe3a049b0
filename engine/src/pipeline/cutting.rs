//! Cutting in a session (seed 000 chapter 3, §3.4): the scalpel's blade force, the cut
//! criterion, and the tissue's compliance as the cut grows — with the cut itself computed
//! beside the tick, never in it.
//!
//! # What the tick does
//! Palpation, the stage before, leaves the contact of the tool's tip with the organ: the
//! imposed displacement `δ` at the loadable point `s_L`, the share `λ` of the tissue, and the
//! tissue force `f = λ C(s_L)⁻¹ δ` from the vademecum. Once the organ is cut, the cut adds the
//! compliance of its openings at the contact ([`CutView::added_compliance`]: with the seed's
//! local discontinuous fields, `ZᵀZ`, `Z = L_S⁻¹ W_pᵀ`), and the tissue force becomes
//!
//! `f = λ (C(s_L) + ΔC_cut(s_L))⁻¹ δ`,
//!
//! so the continuous part keeps the vademecum's exact local compliance (an uncut scene's
//! force is bit-for-bit palpation's) and the cut softens the tissue where it opens.
//!
//! For a scalpel (tool state with a blade: its tip `position_m`, the other end of its edge
//! `blade_end_m`, its orientation; the middle of the edge is where it presses on the tissue,
//! [`ToolInput::contact_point`]), the force on the blade splits into `F⊥` (normal to the
//! blade plane) and `F∥ = F_a + F_n` in it ([`Blade::split`]); `|F∥|` above the scalpel's
//! `cut_force` is the criterion. The tick reports the split, flags `CUT_STARTED` when the
//! criterion starts to hold, and hands the blade state with its force to the cut thread
//! through a bounded lock-free queue of [`SAMPLES`] states (no lock, no allocation, no
//! syscall; if the cut thread falls a whole queue behind, the oldest states are overwritten
//! and counted in [`CutStatus::overwritten`]), so that the cut follows the blade's whole path.
//!
//! # What the cut thread does
//! It runs [`OnlineCut::step`] on the latest blade state (the surface swept while the
//! criterion holds, the cells crossed entirely, their nodes cracked and the reduced model's
//! factor bordered: milliseconds per node, `BENCHMARKS.md`). When cells were cut it takes a
//! [`CutView`] of the model and offers it to the tick through a one-slot lock-free queue; the
//! tick swaps it in at its next start (`CUT_ADVANCED`) and returns the old view through a
//! second queue, so that the old one is freed on the cut thread, not the tick's. At most one
//! view is ever in flight, so the return queue is never full.
//!
//! The tick therefore sees each cut a few milliseconds after the blade made it (the time to
//! enrich its nodes), which a surgeon cannot feel; the forces of those ticks are the uncut
//! model's, which is what the tissue was before the cut.
//!
//! A headless run is deterministic instead ([`Effect::set_deterministic`]): the scalpel's
//! tick waits for the cut thread to finish its blade state, so the cut lands at the next
//! tick and the recording is the same on any load — the run slows down where a live session
//! would let the cut land late.
//!
//! # The error estimate of each force
//! With the seed's local fields the cut's compliance is the full XFEM's at the cut the tick
//! holds (the Schur complement of the cracked nodes), so the force keeps the linear law's
//! round-off estimate ([`super::palpation::LINEAR_RELATIVE_ERROR`]). With the bare enrichment
//! the estimate is the bundle's calibration: the largest relative error of the bare model's
//! force against the full XFEM's at the cracked surface nodes of the scene's cut
//! ([`crate::xfem::accuracy::bare_force_error`], `info.cut.bare_force_error`), times the
//! force ([`force_error`]). With a co-rotational correction in the force it adds what the
//! blend has still to move and what the correction's solve left
//! ([`super::corotational::corrected_force_error`]).
//!
//! A cutting scene cuts one organ: its cut organ ([`crate::scene::Scene::cut_organ`], the
//! first organ without a damage law, a linear one first), beside any others it palpates or
//! tears. When the cut organ deforms largely, palpation leaves the lattice's stiffening `r` of
//! the contact ([`super::Contact::stiffened`]) and the cut's force is scaled by it
//! ([`stiffened_cut`]: `f = r λ (C + ΔC_cut)⁻¹ δ`, with the interaction of the two
//! corrections added to the estimate). The blade's criterion
//! counts only the cut organ's reaction: a blade pressed on another organ pushes it and
//! cuts nothing. With several tools each tool's contact on the cut organ feels the cut.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_queue::ArrayQueue;

use super::corotational::{BLEND_TICKS, Blend, Corrections};
pub use super::cut_picture::CutPicture;
use super::{Effect, Events, TickState, ToolInput, ToolKind};
use crate::bundle::LoadedBundle;
use crate::mesh::Mesh;
use crate::pgd::Vademecum;
use crate::xfem::blade::Blade;
use crate::xfem::online::OnlineCut;
use crate::xfem::partial::PartialSurface;
use crate::xfem::reduced::{CutView, Discontinuous};

/// The force on the blade split along it (N): `F⊥` normal to the blade plane, `F∥` in it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BladeForce {
    /// `F⊥`, normal to the blade plane (what presses the blade's flat).
    pub perpendicular_n: [f64; 3],
    /// `F∥ = F_a + F_n`, in the blade plane (friction below the scalpel's `cut_force`, the
    /// cut above it).
    pub parallel_n: [f64; 3],
    /// Whether `|F∥|` exceeds the scalpel's `cut_force` (the blade cuts).
    pub cutting: bool,
}

/// The cut as it stands, for recordings and viewers.
#[derive(Debug, Clone, Default)]
pub struct CutShape {
    /// The cells cut, each with the plane that crossed it.
    pub cells: Vec<(usize, crate::xfem::Plane)>,
    /// The triangles of the surface the blade swept while cutting (m, reference frame).
    pub triangles: Vec<[[f64; 3]; 3]>,
}

/// The surface the blade swept inside the cells it entered and has not cut yet (seed 003
/// §3.3; [`crate::xfem::partial`]): shown, never simulated, so the incision follows the blade
/// between the cuts of whole cells.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PartialCut {
    /// 0 before the blade first cut; one more per change.
    pub seq: u64,
    /// Its triangles (m, reference frame).
    pub triangles: Vec<[[f64; 3]; 3]>,
}

/// How often at most the cut thread redraws the partial cut while the blade moves (a frame
/// at 30 Hz); it redraws at once when cells are cut, and when the blade stops.
pub const PARTIAL_EVERY: Duration = Duration::from_millis(33);

/// What the cut thread publishes for everyone to read: relaxed atomics the tick reads (no
/// lock), and the cut's shape behind a mutex the tick never touches.
#[derive(Debug, Default)]
pub struct CutStatus {
    /// Bytes the cutting effect holds with the latest view the cut thread offered (0 before
    /// the first cut; see `Effect::memory_bytes`).
    pub memory_bytes: AtomicU64,
    /// Cells cut so far.
    pub cells: AtomicU64,
    /// Nodes cracked so far.
    pub nodes: AtomicU64,
    /// Blade states processed.
    pub steps: AtomicU64,
    /// Blade states the cut thread has finished with: stepped, their view offered to the tick
    /// and their pictures drawn (what a deterministic tick waits for).
    pub finished: AtomicU64,
    /// Steps that could not cut (a piece cut loose made the reduced system singular; the
    /// model stayed at its previous cut).
    pub refused: AtomicU64,
    /// Length of the blade path while cutting (µm, summed over strokes).
    pub path_um: AtomicU64,
    /// Whether the blade's edge lies in a cut already made.
    pub in_cut: AtomicBool,
    /// Blade states the cut thread never saw (it fell more than [`SAMPLES`] ticks behind).
    pub overwritten: AtomicU64,
    /// Co-rotational cutting ([`super::corotational`]): ticks whose force used the rotation
    /// correction `ΔC_rot`.
    pub corrected_ticks: AtomicU64,
    /// Corrections refused (the corrected compliance was not positive definite).
    pub refused_corrections: AtomicU64,
    /// New corrections that landed during a contact they applied to, and the step they made
    /// in the force at that tick (µN, largest and summed): the force discontinuity of the
    /// multi-rate coupling.
    pub landings: AtomicU64,
    /// The largest landing step (µN).
    pub landing_jump_max_un: AtomicU64,
    /// The landing steps summed (µN).
    pub landing_jump_sum_un: AtomicU64,
    /// The largest change of the force between two ticks while a correction is blended in
    /// (µN; [`super::corotational::Blend`]).
    pub blend_step_max_un: AtomicU64,
    /// The cut's shape (updated by the cut thread after each cut; never read by the tick).
    pub shape: std::sync::Mutex<CutShape>,
    /// The cut as viewers draw it (updated by the cut thread after each cut; read by the
    /// frame thread, never by the tick).
    pub picture: std::sync::Mutex<Option<Arc<CutPicture>>>,
    /// The swept surface in the cells the blade entered and has not cut (tetrahedral meshes;
    /// updated by the cut thread, read by the frame thread, never by the tick).
    pub partial: std::sync::Mutex<Arc<PartialCut>>,
}

impl CutStatus {
    /// A copy of the cut's shape.
    pub fn shape(&self) -> CutShape {
        self.shape.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    /// The latest picture of the cut (`None` before the first cut).
    pub fn picture(&self) -> Option<Arc<CutPicture>> {
        self.picture.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    /// The latest partial cut ([`PartialCut`]).
    pub fn partial(&self) -> Arc<PartialCut> {
        self.partial.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

/// The blade state the tick hands to the cut thread.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct BladeSample {
    a: [f64; 3],
    b: [f64; 3],
    orientation: [f64; 4],
    /// The force the tissue exerts on the blade (N).
    force: [f64; 3],
    /// How far the tissue gave way at the contact (m): the imposed displacement.
    pushed: [f64; 3],
}

/// Bytes a cutting effect holds with the reduced model's view `view` ([`Effect::memory_bytes`]).
fn memory_bytes(view: &CutView) -> usize {
    view.shared_bytes() + 3 * view.own_bytes() + SAMPLES * std::mem::size_of::<BladeSample>()
}

/// How often the cut thread looks for new blade states.
const POLL: Duration = Duration::from_micros(500);

/// Blade states queued for the cut thread: a second of ticks at 1 kHz.
pub const SAMPLES: usize = 1024;

/// The cutting effect (module docs).
pub struct Cutting {
    organ: usize,
    bundle: Arc<LoadedBundle>,
    cut_force: f64,
    view: Box<CutView>,
    /// A view the return queue could not take (never, by the one-in-flight protocol; kept
    /// rather than freed on the tick thread).
    parked: Option<Box<CutView>>,
    samples: Arc<ArrayQueue<BladeSample>>,
    fresh: Arc<ArrayQueue<Box<CutView>>>,
    spent: Arc<ArrayQueue<Box<CutView>>>,
    status: Arc<CutStatus>,
    /// Whether the criterion held at the last scalpel tick.
    stroke: bool,
    stop: Arc<AtomicBool>,
    worker: Option<JoinHandle<()>>,
    /// Co-rotational cutting: the frame thread's corrections, and the blend of the latest in.
    corrections: Option<Corrections>,
    blend: Blend,
    /// The bare enrichment's calibrated relative force error ([`Self::with_bare_error`]).
    bare_error: Option<f64>,
    /// Whether each tick waits for the cut thread to finish the blade state of the tick
    /// before ([`Effect::set_deterministic`]), shared with the cut thread.
    deterministic: Arc<AtomicBool>,
    /// Blade states handed to the cut thread so far.
    handed: u64,
}

impl std::fmt::Debug for Cutting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cutting")
            .field("organ", &self.organ)
            .field("cut_force", &self.cut_force)
            .field("enriched_unknowns", &self.view.enriched_unknowns())
            .finish_non_exhaustive()
    }
}

impl Cutting {
    /// The effect for organ `organ` (its loaded bundle `bundle`, its mesh `mesh`), cutting
    /// the reduced model `online` (the scalpel's threshold is `online`'s); starts the cut
    /// thread.
    pub fn new(organ: usize, bundle: Arc<LoadedBundle>, mesh: Mesh, online: OnlineCut, cut_force: f64) -> Self {
        let view = Box::new(online.model().view());
        let samples = Arc::new(ArrayQueue::new(SAMPLES));
        let fresh = Arc::new(ArrayQueue::new(1));
        let spent = Arc::new(ArrayQueue::new(2));
        let status = Arc::new(CutStatus::default());
        let stop = Arc::new(AtomicBool::new(false));
        let deterministic = Arc::new(AtomicBool::new(false));
        let worker = CutThread {
            deterministic: deterministic.clone(),
            organ,
            online,
            shown: PartialSurface::new(&mesh),
            swept: Vec::new(),
            mesh,
            samples: samples.clone(),
            fresh: fresh.clone(),
            spent: spent.clone(),
            status: status.clone(),
            stop: stop.clone(),
        };
        let worker = std::thread::Builder::new()
            .name("cut".into())
            .spawn(move || worker.run())
            .expect("the OS can start a thread");
        Self {
            organ,
            bundle,
            cut_force,
            view,
            parked: None,
            samples,
            fresh,
            spent,
            status,
            stroke: false,
            stop,
            worker: Some(worker),
            corrections: None,
            blend: Blend::default(),
            bare_error: None,
            deterministic,
            handed: 0,
        }
    }

    /// The same effect attaching the bundle's calibrated relative error of the bare
    /// enrichment's force (`info.cut.bare_force_error`) to its answers ([`force_error`]).
    pub fn with_bare_error(mut self, error: Option<f64>) -> Self {
        self.bare_error = error;
        self
    }

    /// The same effect taking the rotation correction of a co-rotational deformation
    /// ([`super::corotational`]) into its force.
    pub fn with_corrections(mut self, corrections: Corrections) -> Self {
        self.corrections = Some(corrections);
        self
    }

    /// What the cut thread has done so far.
    pub fn status(&self) -> Arc<CutStatus> {
        self.status.clone()
    }

    /// Enriched unknowns of the model the tick uses now.
    pub fn enriched_unknowns(&self) -> usize {
        self.view.enriched_unknowns()
    }

    /// Deterministic ticks only: waits until the cut thread has finished every blade state
    /// handed to it (spinning, then yielding; a cut thread that has ended is not waited for).
    /// The tick path of a live session never calls it.
    fn wait_for_cut_thread(&self) {
        let mut spins = 0u32;
        while self.status.finished.load(Ordering::Acquire) < self.handed {
            if self.worker.as_ref().is_none_or(|w| w.is_finished()) {
                return;
            }
            if spins < 1 << 10 {
                std::hint::spin_loop();
                spins += 1;
            } else {
                std::thread::yield_now();
            }
        }
    }

    /// Swaps in a model the cut thread finished; returns whether it did.
    fn take_fresh(&mut self) -> bool {
        if let Some(old) = self.parked.take()
            && let Err(old) = self.spent.push(old)
        {
            self.parked = Some(old);
        }
        let Some(new) = self.fresh.pop() else { return false };
        let old = std::mem::replace(&mut self.view, new);
        if let Err(old) = self.spent.push(old) {
            self.parked = Some(old);
        }
        true
    }

    /// One tool's part of a tick: the cut's compliance at its contact on the cut organ, and
    /// for a scalpel the blade's force split, the criterion and the blade state handed to the
    /// cut thread (module docs). `landed`: a co-rotational correction landed this tick.
    fn tool_tick(&mut self, tool: &ToolInput, state: &mut TickState, landed: bool) {
        let rotated = self.blend.target().seq > 0;
        // the cut's compliance at the contact, and the rotation's
        if (self.view.enriched_unknowns() > 0 || rotated)
            && let Some(c) = &mut state.contact
            && c.organ == self.organ
            && c.loadable > 0.0
            && let Some(cv) = self.bundle.vademecum.contact_compliance(c.nodes, c.weights, tool.kind.footprint())
        {
            let added = if self.view.enriched_unknowns() > 0 {
                self.view.added_compliance(&c.nodes, &c.weights)
            } else {
                [[0.0; 3]; 3]
            };
            let cut: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| cv[i][j] + added[i][j]));
            // the force with a rotation correction (None: it makes the compliance indefinite)
            let force = |delta: Option<[[f64; 3]; 3]>| -> Option<[f64; 3]> {
                let total = match delta {
                    None => cut,
                    Some(d) => std::array::from_fn(|i| std::array::from_fn(|j| cut[i][j] + d[i][j])),
                };
                positive_definite(&total).then(|| Vademecum::contact_force(&total, c.imposed_m).map(|f| c.loadable * f))
            };
            let uncorrected = || Vademecum::contact_force(&cut, c.imposed_m).map(|f| c.loadable * f);
            let ticks = self.blend.ticks();
            let now = self.blend.delta(&c.nodes, ticks);
            let tissue = match force(now) {
                Some(f) => {
                    if now.is_some() {
                        self.status.corrected_ticks.fetch_add(1, Ordering::Relaxed);
                    }
                    f
                }
                None => {
                    self.status.refused_corrections.fetch_add(1, Ordering::Relaxed);
                    uncorrected()
                }
            };
            // the multi-rate discontinuity: the whole step a landing correction would make,
            // and the step the blend makes from the tick before
            let size = |a: [f64; 3], b: [f64; 3]| ((0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt() * 1e6).round() as u64;
            if landed
                && now.is_some()
                && let (Some(from), Some(to)) = (force(Some(self.blend.from())), force(Some(self.blend.target().delta)))
            {
                let un = size(to, from);
                self.status.landings.fetch_add(1, Ordering::Relaxed);
                self.status.landing_jump_max_un.fetch_max(un, Ordering::Relaxed);
                self.status.landing_jump_sum_un.fetch_add(un, Ordering::Relaxed);
            }
            if ticks > 0
                && ticks <= BLEND_TICKS
                && now.is_some()
                && let Some(before) = force(self.blend.delta(&c.nodes, ticks - 1))
            {
                self.status.blend_step_max_un.fetch_max(size(tissue, before), Ordering::Relaxed);
            }
            // the module docs' estimate, and with a rotation correction in the force what the
            // blend has still to move and the correction's solve left
            let mut cut_error = force_error(self.view.discontinuous(), self.bare_error, tissue);
            // an organ that deforms largely: the lattice's stiffening scales the cut's force
            let tissue = match c.stiffened {
                Some(s) => {
                    let uncut = Vademecum::contact_force(&cv, c.imposed_m).map(|f| c.loadable * f);
                    let (f, error) = stiffened_cut(s, tissue, uncut);
                    cut_error = cut_error.map(|e| s.ratio * e + error);
                    f
                }
                None => tissue,
            };
            for k in 0..3 {
                state.force_n[k] += c.tissue_force_n[k] - tissue[k];
            }
            c.tissue_force_n = tissue;
            state.force_error_n = match now {
                None => cut_error,
                Some(_) => super::corotational::corrected_force_error(tissue, self.blend.target(), |d| force(Some(d)))
                    .zip(cut_error)
                    .map(|(a, b)| a + b),
            };
        }
        if tool.kind != ToolKind::Scalpel {
            return;
        }
        let Ok(blade) = Blade::new(tool.position_m, tool.blade_end_m, tool.orientation) else {
            return; // the pipeline refuses such states before any effect sees them
        };
        let split = blade.split(state.force_n);
        // only the cut organ's reaction can cut it: a blade pressing on another organ (the
        // fat beside the duct) pushes it, and its force reaches the cut thread as none
        let on_organ = state.contact.is_some_and(|c| c.organ == self.organ);
        let cutting = on_organ && split.cuts(self.cut_force);
        if cutting && !self.stroke {
            state.events.0 |= Events::CUT_STARTED;
        }
        self.stroke = cutting;
        if self.status.in_cut.load(Ordering::Relaxed) {
            state.events.0 |= Events::BLADE_IN_CUT;
        }
        state.blade = Some(BladeForce {
            perpendicular_n: split.perpendicular,
            parallel_n: std::array::from_fn(|k| split.axial[k] + split.cutting[k]),
            cutting,
        });
        let sample = BladeSample {
            a: tool.position_m,
            b: tool.blade_end_m,
            orientation: tool.orientation,
            force: if on_organ { state.force_n } else { [0.0; 3] },
            pushed: state.contact.filter(|_| on_organ).map_or([0.0; 3], |c| c.imposed_m),
        };
        if self.samples.force_push(sample).is_some() {
            self.status.overwritten.fetch_add(1, Ordering::Relaxed);
        }
        self.handed += 1;
        if self.deterministic.load(Ordering::Relaxed)
            && let Some(w) = &self.worker
        {
            // the cut of this blade state is made before the tick ends, however long it
            // takes: it lands at the next tick, and the frames of this one draw it
            w.thread().unpark();
            self.wait_for_cut_thread();
        }
    }
}

impl Drop for Cutting {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}

impl Effect for Cutting {
    fn name(&self) -> &'static str {
        "cutting"
    }

    /// The reduced cut model's view: the arrays its copies share once, and what each of the
    /// three copies in flight holds (the tick's, one on its way, the cut thread's), and the
    /// queue of blade states. Not counted: the cut thread's working model beyond its view
    /// (the enrichment and, with local fields, the uncut stiffness's factorization).
    fn memory_bytes(&self) -> usize {
        memory_bytes(&self.view)
    }

    fn tick(&mut self, tool: &ToolInput, state: &mut TickState) {
        self.tick_tools(std::slice::from_ref(tool), std::slice::from_mut(state));
    }

    /// Several tools at once (two hands): the cut thread's latest model is swapped in and the
    /// co-rotational correction lands once per tick (at the first contact on the cut organ),
    /// then each tool's contact on the cut organ feels the cut and a scalpel's blade is
    /// handed on (module docs). `CUT_ADVANCED` goes to the scalpel's answer (to
    /// every answer of a tick that moves no scalpel).
    fn tick_tools(&mut self, tools: &[ToolInput], states: &mut [TickState]) {
        let fresh = self.take_fresh();
        // the co-rotational deformation's latest correction (co-rotational cutting)
        let mut landed = false;
        if let Some(out) = &mut self.corrections {
            let organ = self.organ;
            let nodes = states
                .iter()
                .find_map(|s| s.contact.as_ref().filter(|c| c.organ == organ).map(|c| c.nodes));
            landed = self.blend.land(*out.read(), nodes.as_ref());
        }
        for (tool, state) in tools.iter().zip(states.iter_mut()) {
            self.tool_tick(tool, state, landed);
        }
        if fresh {
            let scalpel = tools.iter().any(|t| t.kind == ToolKind::Scalpel);
            for (tool, state) in tools.iter().zip(states.iter_mut()) {
                if !scalpel || tool.kind == ToolKind::Scalpel {
                    state.events.0 |= Events::CUT_ADVANCED;
                }
            }
        }
    }

    fn reset(&mut self) {
        self.stroke = false;
    }

    /// Deterministic: a scalpel's tick waits for the cut thread to finish its blade state
    /// (the cut stepped, its view offered, its pictures drawn), so each cut lands at the tick
    /// after the blade made it, whatever the machine's load (live sessions let it land when
    /// it is done, a few ticks later).
    fn set_deterministic(&mut self, deterministic: bool) {
        self.deterministic.store(deterministic, Ordering::Relaxed);
    }
}

/// The error estimate (N) of a force `f` served on the cut organ (module docs): the linear
/// law's round-off with local fields, the calibrated `bare_error` with the bare enrichment
/// (`None` without one: a bundle built before the calibration).
pub fn force_error(disc: Discontinuous, bare_error: Option<f64>, f: [f64; 3]) -> Option<f64> {
    let size = f.iter().map(|x| x * x).sum::<f64>().sqrt();
    match disc {
        Discontinuous::LocalFields => Some(super::palpation::LINEAR_RELATIVE_ERROR * size),
        Discontinuous::Bare => bare_error.map(|e| e * size),
    }
}

/// The cut's force on an organ that deforms largely, and what the composition adds to its error
/// estimate (N; `docs/large_deformation.md`, "Cutting an organ that deforms largely").
///
/// With `r` the stiffening the organ's lattice gives at the contact's point and depth (built
/// on the uncut organ), `f = λ C⁻¹δ` the uncut linear force and `f_cut = λ (C + ΔC_cut)⁻¹ δ`
/// the cut's, the composed force is
///
/// `f_large,cut = r f_cut = f + (f_cut − f) + (r − 1) f + (r − 1)(f_cut − f)`:
///
/// the linear force, the cut's correction, the nonlinear correction, and an interaction
/// term — the nonlinear and the cut's corrections taken as separable (the stiffening of the
/// cut organ at this depth is the uncut organ's). The error added is the lattice's on the
/// cut's force, `ε_r |f_cut|`, and the interaction term's own size, `|r − 1| |f_cut − f|`:
/// what the composition assumes, counted as unknown. Both vanish where they should — at
/// small depth (`r → 1`) and far from the cut (`f_cut → f`).
pub fn stiffened_cut(s: super::Stiffened, cut: [f64; 3], uncut: [f64; 3]) -> ([f64; 3], f64) {
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let interaction = (s.ratio - 1.0).abs() * norm(std::array::from_fn(|k| cut[k] - uncut[k]));
    (cut.map(|x| s.ratio * x), s.ratio_error * norm(cut) + interaction)
}

/// Whether the symmetric part of the 3×3 `m` is positive definite (its leading minors).
fn positive_definite(m: &[[f64; 3]; 3]) -> bool {
    let s: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| 0.5 * (m[i][j] + m[j][i])));
    let m2 = s[0][0] * s[1][1] - s[0][1] * s[1][0];
    let m3 = s[0][0] * (s[1][1] * s[2][2] - s[1][2] * s[2][1]) - s[0][1] * (s[1][0] * s[2][2] - s[1][2] * s[2][0])
        + s[0][2] * (s[1][0] * s[2][1] - s[1][1] * s[2][0]);
    s[0][0] > 0.0 && m2 > 0.0 && m3 > 0.0
}

/// The cut thread's state (module docs).
struct CutThread {
    organ: usize,
    online: OnlineCut,
    /// The partial cut's state (tetrahedral meshes).
    shown: Option<PartialSurface>,
    /// The swept triangles seen so far.
    swept: Vec<[[f64; 3]; 3]>,
    mesh: Mesh,
    samples: Arc<ArrayQueue<BladeSample>>,
    fresh: Arc<ArrayQueue<Box<CutView>>>,
    spent: Arc<ArrayQueue<Box<CutView>>>,
    status: Arc<CutStatus>,
    stop: Arc<AtomicBool>,
    /// [`Cutting::set_deterministic`]: every blade state is finished before the next is
    /// taken, its view offered and its partial cut drawn at once.
    deterministic: Arc<AtomicBool>,
}

impl CutThread {
    /// Offers the tick a view of the model if cells were cut since the last one offered
    /// and the tick has returned that one (`out`: a view offered and not yet returned).
    fn offer(&self, pending: &mut bool, out: &mut bool) {
        while self.spent.pop().is_some() {
            *out = false;
        }
        if *pending && !*out {
            let view = Box::new(self.online.model().view());
            self.status.memory_bytes.store(memory_bytes(&view) as u64, Ordering::Relaxed);
            if self.fresh.push(view).is_ok() {
                *out = true;
                *pending = false;
            }
        }
    }

    fn run(mut self) {
        let mut out = false; // a view offered and not yet returned
        let mut pending = false; // cells cut since the last view offered
        let mut prev: Option<[f64; 3]> = None;
        let mut path = 0.0;
        let mut revision = 0;
        let mut drawn = std::time::Instant::now();
        while !self.stop.load(Ordering::Relaxed) {
            self.offer(&mut pending, &mut out);
            let Some(s) = self.samples.pop() else {
                // the blade stopped: the partial cut as it stands
                self.draw_partial(&mut drawn, true);
                std::thread::park_timeout(POLL);
                continue;
            };
            self.take(&s, &mut prev, &mut path, &mut revision, &mut pending, &mut drawn);
            if self.deterministic.load(Ordering::Relaxed) {
                // the view of this blade state goes out before the tick is told it is done
                // (the tick returned the one before when it took it, before handing this
                // state over)
                self.offer(&mut pending, &mut out);
            }
            self.status.finished.fetch_add(1, Ordering::Release);
        }
    }

    /// Steps the cut with blade state `s`: the path cut so far (`prev`, `path`), the cut's
    /// shape and picture (`revision`) when cells were cut (`pending`: a view to offer), the
    /// partial cut (`drawn`).
    fn take(
        &mut self,
        s: &BladeSample,
        prev: &mut Option<[f64; 3]>,
        path: &mut f64,
        revision: &mut u64,
        pending: &mut bool,
        drawn: &mut std::time::Instant,
    ) {
        let Ok(blade) = Blade::new(s.a, s.b, s.orientation) else { return };
        self.status.steps.fetch_add(1, Ordering::Relaxed);
        let step = match self.online.step_in_contact(&self.mesh, &blade, s.force, s.pushed) {
            Ok(step) => step,
            Err(e) => {
                self.status.refused.fetch_add(1, Ordering::Relaxed);
                tracing::warn!("the cut could not advance: {e}");
                return;
            }
        };
        self.status.in_cut.store(step.in_cut, Ordering::Relaxed);
        if step.cutting {
            if let Some(p) = *prev {
                *path += (0..3).map(|k| (s.a[k] - p[k]).powi(2)).sum::<f64>().sqrt();
                self.status.path_um.store((*path * 1e6) as u64, Ordering::Relaxed);
            }
            *prev = Some(s.a);
        } else {
            *prev = None;
        }
        if step.new_cells > 0 {
            let e = self.online.model().enrichment();
            self.status.cells.store(e.cut_cells.len() as u64, Ordering::Relaxed);
            self.status.nodes.store(e.len() as u64, Ordering::Relaxed);
            let shape = CutShape {
                cells: e.cut_cells.clone(),
                triangles: self
                    .online
                    .cut()
                    .map(|c| c.facets().iter().map(|f| f.vertices).collect())
                    .unwrap_or_default(),
            };
            *self.status.shape.lock().unwrap_or_else(|p| p.into_inner()) = shape;
            *revision += 1;
            let picture = Arc::new(CutPicture::new(self.organ, *revision, &self.mesh, self.online.model()));
            // the old picture is freed here or on the frame thread, never on the tick's
            *self.status.picture.lock().unwrap_or_else(|p| p.into_inner()) = Some(picture);
            *pending = true;
        }
        // deterministic: drawn with every blade state that swept something new
        let now = step.new_cells > 0 || self.deterministic.load(Ordering::Relaxed);
        self.draw_partial(drawn, now);
    }

    /// Redraws the partial cut ([`PartialCut`]) when the blade swept something new since the
    /// last drawing, at once if `now`, otherwise at most every [`PARTIAL_EVERY`] (stamped in
    /// `drawn`).
    fn draw_partial(&mut self, drawn: &mut std::time::Instant, now: bool) {
        let Some(shown) = &mut self.shown else { return };
        let facets = self.online.cut().map_or(&[][..], |c| c.facets());
        if facets.len() == self.swept.len() || (!now && drawn.elapsed() < PARTIAL_EVERY) {
            return;
        }
        *drawn = std::time::Instant::now();
        if facets.len() < self.swept.len() {
            // a cut that started over (this thread's cut only grows)
            self.swept.clear();
            if let Some(fresh) = PartialSurface::new(&self.mesh) {
                *shown = fresh;
            }
        }
        let start = self.swept.len();
        self.swept.extend(facets[start..].iter().map(|f| f.vertices));
        let mut is_cut = vec![false; self.mesh.n_cells()];
        for &(c, _) in &self.online.model().enrichment().cut_cells {
            if let Some(x) = is_cut.get_mut(c) {
                *x = true;
            }
        }
        let triangles = shown.update(&self.mesh, &self.swept, |c| is_cut[c]);
        let mut slot = self.status.partial.lock().unwrap_or_else(|p| p.into_inner());
        let seq = slot.seq + 1;
        // the old one is freed here or on the frame thread, never on the tick's
        *slot = Arc::new(PartialCut { seq, triangles });
    }
}
