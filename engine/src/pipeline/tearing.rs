//! The grasper (seed 000 §4.6.2): jaws close on the tissue, the device pulls, the tissue
//! damages and tears; one step of the POD–PGD integrator ([`crate::damage::online`]) per tick.
//!
//! # The grasp sites
//! Each vademecum was built for one grasp: the nodes its load acts on and the direction `n̂`
//! of that load's resultant (the load increment of a unit step is that load), and — unless
//! built without them — for the same nodes pulled across it, along `t̂₁` and `t̂₂`
//! ([`TearModel::pull_frame`], [`TearModel::pull_load`]). The first is the scene's grasp (its
//! `[[organs.loads]]`, as the seed pulls one node); a scene may ask for more
//! (`[fidelity.tearing] grasp_sites`), spread over the tearable surface and pulled along its
//! outward normal ([`crate::damage::sites`]). The jaws take hold when they close
//! (`closure ≥ 0.5`) within `jaw_width` of a site's centre (the nearest, if several); the
//! position where they closed is the anchor.
//!
//! # One damage, several sites
//! Every site has its own integrator (its POD basis of the damage its pull causes, its
//! vademecum), but the tissue has one damage: the integration points' states. When the jaws
//! take hold at another site than the last one held, that site's integrator takes over the
//! states ([`OnlineTear::take_over`]) — the last grasp's load has faded to zero by then, so
//! the tissue is at rest. Damage is never lost: the states are the truth, rendered and checked
//! against the threshold; the site's POD projection of them only sets its stiffness, so
//! damage a site's basis cannot represent (far from it, made by another site's pull) softens
//! the tissue under the new grasp only as far as that basis sees it.
//!
//! # The pull
//! Each tick the device's motion from the anchor, in the pull's frame, is the target
//! `p = (max(0, ∆x·n̂), ∆x·t̂₁, ∆x·t̂₂)` (pushing along `−n̂` does nothing). The tissue follows
//! it by displacement control: with the grasp's displacements `w_p = (L_p·u)/|R|` (the
//! load-weighted means along each direction; `L_p` the patterns' unit loads, `R` the
//! resultant) and the grasp's compliance at the current damage `C_pq = ∂w_p/∂s_q` (from the
//! vademecum's coefficients: exact for the integrator's step while the damage does not
//! change), the load factors move by `ds = C⁻¹(p − w)`, scaled to at most [`MAX_LOAD_STEP`]
//! unit steps per tick, and never past the grasper's `max_force` (`|s|·|R| ≤ max_force`,
//! flagged `FORCE_SATURATED`). The force on the tool is the tissue's reaction
//! `−|R| Σ_p s_p t̂_p`. A bundle built without the cross pulls follows the motion along `n̂`
//! only. The step's damage growth is limited by the integrator's sub-steps
//! (`[fidelity.tearing] max_damage_increment`).
//!
//! # The error estimate of each force
//! While held, each force carries an estimate of its error against the full-order model
//! ([`TickState::force_error_n`]): `e(|s|₂)·(|s|₁/|s|₂)·|f|`, with `e` the bundle's
//! calibration ([`TearOffline::force_error_for`], built by
//! [`crate::damage::build::force_error_table`]): how far the reduced model's force for the
//! same grasp displacement is from the full model's on nine pulls from virgin tissue (along the
//! load, across it both ways, the four diagonals) and the same nine as second grasps (after a
//! first pull along the load, released), the largest up to that load level; the factor bounds
//! how the directions' errors add up in a mixed pull. To it each grasp adds, as the jaws take
//! hold, how far the tissue's damage lies outside what the site's basis sees
//! ([`OnlineTear::hold`]: the relative change of the grasp's stiffness that the damage the
//! basis misses makes, beyond virgin tissue's) — damage another site's pull made, or a pull
//! across the load, which the calibration never starts from. Past the calibrated levels, while
//! the force fades, and with a bundle built before the calibration the answer has none.
//! `vademecum study` measures how often the estimate bounds mixed pulls, first, second and
//! third grasps, and grasps after another site's pull.
//!
//! # Tearing, losing the grasp
//! When the damage of a cell of the tearable tissue reaches the scene's `torn` threshold
//! (default 0.8, as the seed: "levels of damage exceeding certain threshold indicate the full
//! rupture of the tissue … grasping is considered lost"), the grasp is lost (`TISSUE_TORN`)
//! and the tissue springs back. (A cell torn before the grasp — by another site's pull —
//! does not count: what loses the grasp is a point reaching the threshold while held.) The tear need not pass through the grasped nodes themselves —
//! on the gallbladder it runs through the fat a cell or two from them, where the pulled flap
//! meets the anchored layer; the vademecum's load stays on the grasped nodes, so past the
//! first torn cell its answers would describe a flap still attached. The load factor fades linearly to zero over [`FADE_TICKS`] ticks, so the force drops by at
//! most `1/FADE_TICKS` of its value per tick — gentler than the device bridge's watchdog,
//! which may drop a third per tick. Opening the jaws releases the same way (`RELEASED`). A
//! site torn while held cannot be taken again; the other sites can. Cells past the threshold stop rendering (the frame's
//! per-cell damage; the recording's `.pvd` leaves them out).
//!
//! # Under load
//! When the session's ticks come close to their deadline (the server's fidelity governor), the
//! effect steps its cheaper setting ([`Fidelity::Reduced`]): the simplified integrator on the
//! fallback modes the build chose and stored ([`crate::damage::online::TearFallback`]: the
//! fewest modes per pull pattern whose calibrated force error is within
//! [`crate::damage::build::FALLBACK_ERROR_GROWTH`] of all of them), from the state it holds —
//! the damage, the displacement and the load factors carry on, so the force does not jump;
//! the estimate of each force is then the fallback's calibration. A bundle without a fallback
//! (built before it, or already that small) keeps its modes; a scene on the full integrator
//! drops to the simplified one.
//!
//! # Frames
//! The tick publishes, through a lock-free triple buffer, the accumulated modal amplitudes
//! and the tearable cells' damage ([`TearPicture`]); the frame thread rebuilds the whole
//! displacement from them ([`TearOffline::displacement`]).

use std::sync::Arc;

use super::{Effect, Events, Fidelity, TickState, ToolInput, ToolKind};
#[cfg(doc)]
use crate::damage::model::TearModel;
use crate::damage::online::{OnlineTear, StepLimits, TearAmplitudes, TearOffline, Variant};

/// Most unit load steps the load factor moves by in one tick.
pub const MAX_LOAD_STEP: f64 = 0.25;

/// Ticks over which the force fades to zero when the grasp is lost or released.
pub const FADE_TICKS: u32 = 20;

/// Closure from which the jaws hold.
pub const JAWS_CLOSED: f64 = 0.5;

/// What the frame thread reads: the displacement's amplitudes and the cells' damage.
#[derive(Debug, Clone, PartialEq)]
pub struct TearPicture {
    /// Organ index in the scene.
    pub organ: usize,
    /// The grasp site whose vademecum the amplitudes are of (0: the scene's grasp).
    pub site: usize,
    /// The tick it shows (0: the rest state).
    pub tick: u64,
    /// The accumulated modal amplitudes (sized for the largest site's vademecum: the rest
    /// zero).
    pub amplitudes: TearAmplitudes,
    /// Damage of every cell of the organ's mesh: the largest of its integration points' (a
    /// cell is torn, and not rendered, once one of its points reaches the threshold, as the
    /// grasp is lost; 0 where nothing tears).
    pub cell_damage: Vec<f32>,
    /// The threshold past which a cell is torn (not rendered).
    pub torn: f32,
    /// Whether the jaws hold the tissue.
    pub grasped: bool,
    /// Energy dissipated so far (J).
    pub dissipated_j: f64,
}

/// Where the grasper can take hold of an organ, and which way the tissue is pulled: what a
/// client needs to know to grasp (sessions publish it in the grasper's tool description).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspSite {
    /// Organ index in the scene.
    pub organ: usize,
    /// The grasp's centre (m): the mean of the grasped nodes. The jaws take hold
    /// when they close within the grasper's `jaw_width` of it.
    pub centre_m: [f64; 3],
    /// The pull's direction `n̂` (unit): the scene's load's at the scene's grasp, the
    /// surface's outward normal at the others. The tissue follows the device in every
    /// direction, but the damage model was trained along it.
    pub pull_direction: [f64; 3],
}

/// The frame thread's end of the pictures.
pub type TearPictures = triple_buffer::Output<TearPicture>;

/// The grasp's phase.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    /// Jaws open or away from the grasp.
    Free,
    /// Holding, since the jaws closed at `anchor`.
    Held { anchor: [f64; 3] },
    /// Letting go: the load factors fade from `from` over [`FADE_TICKS`]; `k` ticks done.
    Fading { from: [f64; 3], k: u32 },
}

/// One grasp site: its integrator, and what the control reads of its vademecum.
struct Site {
    off: Arc<TearOffline>,
    online: OnlineTear,
    /// Per pull pattern (along the load, then across it): the loaded dofs and the unit load
    /// there (N).
    loads: Vec<Vec<(usize, f64)>>,
    /// `(L_p·F_i)/|R|`: how far mode `i` moves the grasp along pattern `p`'s direction,
    /// row-major `patterns × n_modes`.
    grasp_modes: Vec<f64>,
    /// `|R|` (N per unit step) and the pull's frame `[n̂, t̂₁, t̂₂]`.
    resultant_n: f64,
    frame: [[f64; 3]; 3],
    centre: [f64; 3],
    /// Compliance of the virgin tissue, `w` per unit step (m).
    virgin_compliance: f64,
    /// Torn while held: cannot be taken again.
    spent: bool,
}

impl Site {
    fn new(off: Arc<TearOffline>, variant: Variant, limits: StepLimits) -> Result<Self, TearingError> {
        let m = &off.model;
        let (_, centre, r) = m.grasp().ok_or(TearingError::NoGrasp)?;
        let resultant_n = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        let frame = m.pull_frame().ok_or(TearingError::NoGrasp)?;
        let loads: Vec<Vec<(usize, f64)>> = (0..off.patterns())
            .map(|p| m.pull_load(p).into_iter().enumerate().filter(|(_, f)| *f != 0.0).collect())
            .collect();
        let nm = off.vademecum.n_modes;
        let mut grasp_modes = vec![0.0; loads.len() * nm];
        for (p, l) in loads.iter().enumerate() {
            for i in 0..nm {
                let f = off.vademecum.mode(i);
                grasp_modes[p * nm + i] = l.iter().map(|&(d, x)| m.dofs.eq(d).map_or(0.0, |e| x * f[e])).sum::<f64>() / resultant_n;
            }
        }
        // the virgin compliance, from one unit step of a scratch integrator
        let mut scratch = OnlineTear::new(off.clone(), variant, limits);
        scratch.step(1.0);
        let w1 = loads[0].iter().map(|&(d, f)| f * scratch.local_u(d)).sum::<f64>() / resultant_n;
        if !(w1 > 0.0 && w1.is_finite()) {
            return Err(TearingError::Rigid(w1));
        }
        Ok(Self {
            online: OnlineTear::new(off.clone(), variant, limits),
            off,
            loads,
            grasp_modes,
            resultant_n,
            frame,
            centre,
            virgin_compliance: w1,
            spent: false,
        })
    }

    /// The grasp's displacement along each pull pattern's direction, `w_p = (L_p·u)/|R|` (m).
    fn grasp_displacement(&self) -> [f64; 3] {
        let mut w = [0.0; 3];
        for (p, l) in self.loads.iter().enumerate() {
            w[p] = l.iter().map(|&(d, f)| f * self.online.local_u(d)).sum::<f64>() / self.resultant_n;
        }
        w
    }

    /// The grasp's compliance at the current damage, `C_pq = ∂w_p/∂s_q` (m per unit step):
    /// `Σ_{i ∈ q} a_i (L_p·F_i)/|R|` with the vademecum's coefficients `a_i` at the current
    /// damage. The first `patterns × patterns` block is set.
    fn compliance(&mut self) -> [[f64; 3]; 3] {
        let n = self.loads.len();
        let nm = self.grasp_modes.len() / n;
        let a = self.online.refresh_coefficients();
        let mut c = [[0.0; 3]; 3];
        for p in 0..n {
            let row = &self.grasp_modes[p * nm..(p + 1) * nm];
            for (i, (&ai, &g)) in a.iter().zip(row).enumerate() {
                c[p][self.off.mode_pattern[i]] += ai * g;
            }
        }
        c
    }

    /// The load-factor step that brings the grasp's displacement `w` to `target`:
    /// `C⁻¹(target − w)` (a Newton step on the integrator's own incremental compliance, exact
    /// while the damage does not change), along the load alone with the virgin compliance if
    /// `C` is not positive definite.
    fn control(&mut self, target: [f64; 3], w: [f64; 3]) -> [f64; 3] {
        let n = self.loads.len();
        let c = self.compliance();
        let mut ds = [0.0; 3];
        let mut m = [0.0; 9];
        for p in 0..n {
            for q in 0..n {
                m[p * n + q] = 0.5 * (c[p][q] + c[q][p]);
            }
            ds[p] = target[p] - w[p];
        }
        if crate::dense::cholesky(&mut m[..n * n], n).is_ok() {
            crate::dense::cholesky_solve(&m[..n * n], n, &mut ds[..n]);
        } else {
            ds = [(target[0] - w[0]) / self.virgin_compliance, 0.0, 0.0];
        }
        if !ds.iter().all(|x| x.is_finite()) {
            ds = [0.0; 3];
        }
        // at most MAX_LOAD_STEP unit steps per tick, the direction kept
        let big = ds.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        if big > MAX_LOAD_STEP {
            ds.iter_mut().for_each(|x| *x *= MAX_LOAD_STEP / big);
        }
        ds
    }

    /// Where the jaws take hold of this site, and which way they pull.
    fn describe(&self, organ: usize) -> GraspSite {
        GraspSite {
            organ,
            centre_m: self.centre,
            pull_direction: self.frame[0],
        }
    }
}

/// The tearing effect of one organ.
pub struct Tearing {
    organ: usize,
    /// The grasp sites, the scene's first; they share one damage (module docs).
    sites: Vec<Site>,
    /// The site whose integrator holds the tissue's current state.
    active: usize,
    jaw_width: f64,
    max_force: f64,
    /// Tearable cells, with their points' range.
    cells: Vec<(usize, std::ops::Range<usize>)>,
    torn: f64,
    /// Tearable points at or past `torn` (counted when the grasp was taken, and since).
    torn_points: usize,
    phase: Phase,
    /// The load factors of the active site's pull patterns.
    s: [f64; 3],
    tick: u64,
    /// The grasper's last state, replayed on a tick that moves only other tools.
    last_grasper: Option<ToolInput>,
    picture: triple_buffer::Input<TearPicture>,
    /// Bytes of one picture (the buffer holds three).
    picture_bytes: usize,
}

/// A tearing effect could not be prepared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TearingError {
    /// The scene's load (the grasp) is zero or acts on no node.
    #[error("the tearable organ has no load to grasp by: add an [[organs.loads]] entry (the grasp and its pull direction)")]
    NoGrasp,
    /// Pulling the virgin tissue does not move the grasp along the pull.
    #[error("a unit pull does not move the grasped nodes along the pull (compliance {0:e} m): check the supports and the load")]
    Rigid(f64),
    /// The grasp sites' offline data are not of one model.
    #[error("the grasp sites' tearing data are not of one model (integration points {0} and {1})")]
    Mismatch(usize, usize),
}

impl Tearing {
    /// The effect for organ `organ`, on the offline data of its grasp sites `offs` (the
    /// scene's grasp first; shared by sessions), with the grasper's jaw width and force limit.
    /// Also returns the frame thread's end of the pictures.
    pub fn new(
        organ: usize,
        offs: Vec<Arc<TearOffline>>,
        variant: Variant,
        limits: StepLimits,
        jaw_width: f64,
        max_force: f64,
    ) -> Result<(Self, TearPictures), TearingError> {
        let first = offs.first().ok_or(TearingError::NoGrasp)?.clone();
        let m = &first.model;
        if let Some(o) = offs.iter().find(|o| o.model.points.len() != m.points.len()) {
            return Err(TearingError::Mismatch(m.points.len(), o.model.points.len()));
        }
        let sites = offs
            .into_iter()
            .map(|off| Site::new(off, variant, limits))
            .collect::<Result<Vec<_>, _>>()?;
        let mut tearable_cell = vec![false; m.mesh.n_cells()];
        for &p in &m.points.tearable {
            tearable_cell[m.points.cell[p]] = true;
        }
        let cells: Vec<(usize, std::ops::Range<usize>)> = (0..m.mesh.n_cells())
            .filter(|&c| tearable_cell[c])
            .map(|c| (c, m.points.first[c]..m.points.first[c + 1]))
            .collect();
        let torn = m.torn.iter().copied().fold(f64::INFINITY, f64::min).min(1.0);
        // the picture's amplitudes sized for the largest site, so switching never allocates
        let mut amplitudes = TearAmplitudes::zero(&first);
        for s in &sites {
            let a = s.online.amplitudes();
            amplitudes.vad.resize(amplitudes.vad.len().max(a.vad.len()), 0.0);
            amplitudes.ritz.resize(amplitudes.ritz.len().max(a.ritz.len()), 0.0);
        }
        let picture = TearPicture {
            organ,
            site: 0,
            tick: 0,
            amplitudes,
            cell_damage: vec![0.0; m.mesh.n_cells()],
            torn: torn as f32,
            grasped: false,
            dissipated_j: 0.0,
        };
        let picture_bytes = std::mem::size_of::<TearPicture>()
            + crate::memory::vec_bytes(&picture.amplitudes.vad)
            + crate::memory::vec_bytes(&picture.amplitudes.ritz)
            + crate::memory::vec_bytes(&picture.cell_damage);
        let (input, output) = triple_buffer::triple_buffer(&picture);
        Ok((
            Self {
                organ,
                sites,
                active: 0,
                jaw_width,
                max_force: max_force.max(0.0),
                cells,
                torn,
                torn_points: 0,
                phase: Phase::Free,
                s: [0.0; 3],
                tick: 0,
                last_grasper: None,
                picture: input,
                picture_bytes,
            },
            output,
        ))
    }

    /// Where the jaws take hold and which way they pull: the scene's grasp.
    pub fn site(&self) -> GraspSite {
        self.sites[0].describe(self.organ)
    }

    /// Every grasp site, the scene's first.
    pub fn sites(&self) -> Vec<GraspSite> {
        self.sites.iter().map(|s| s.describe(self.organ)).collect()
    }

    /// The integrator holding the tissue's current state (the last site grasped).
    pub fn online(&self) -> &OnlineTear {
        &self.sites[self.active].online
    }

    /// The nearest site not torn within `jaw_width` of `at`.
    fn site_at(&self, at: [f64; 3]) -> Option<usize> {
        let d2 = |c: [f64; 3]| (0..3).map(|k| (at[k] - c[k]).powi(2)).sum::<f64>();
        self.sites
            .iter()
            .enumerate()
            .filter(|(_, s)| !s.spent && d2(s.centre) <= self.jaw_width * self.jaw_width)
            .min_by(|a, b| d2(a.1.centre).total_cmp(&d2(b.1.centre)))
            .map(|(k, _)| k)
    }

    /// Makes site `k` the active one, taking over the tissue's damage (at rest: no load).
    fn activate(&mut self, k: usize) {
        if k == self.active {
            return;
        }
        let (a, b) = (k.min(self.active), k.max(self.active));
        let (lo, hi) = self.sites.split_at_mut(b);
        let (to, from) = if k < self.active {
            (&mut lo[a], &hi[0])
        } else {
            (&mut hi[0], &lo[a])
        };
        to.online.take_over(&from.online);
        self.active = k;
        self.s = [0.0; 3];
    }

    /// Moves the load factors to `target` (one integrator step), flagging growing damage.
    fn load_to(&mut self, target: [f64; 3], state: &mut TickState) {
        let ds: [f64; 3] = std::array::from_fn(|p| target[p] - self.s[p]);
        if ds.iter().any(|x| x.abs() > 1e-12) {
            let step = self.sites[self.active].online.step_pull(ds);
            self.s = target;
            if step.dissipated > 0.0 {
                state.events.0 |= Events::TEARING;
            }
        }
    }

    /// How many tearable points are at or past the threshold.
    fn count_torn(&self) -> usize {
        let online = self.online();
        let m = &online.offline().model;
        m.points.tearable.iter().filter(|&&p| online.state[p].damage() >= self.torn).count()
    }

    fn publish(&mut self) {
        let online = &self.sites[self.active].online;
        let (state, amplitudes) = (&online.state, online.amplitudes());
        let buf = self.picture.input_buffer_mut();
        buf.tick = self.tick;
        buf.site = self.active;
        buf.amplitudes.copy_from(amplitudes);
        for (c, range) in &self.cells {
            buf.cell_damage[*c] = range.clone().map(|p| state[p].damage()).fold(0.0, f64::max) as f32;
        }
        buf.grasped = matches!(self.phase, Phase::Held { .. });
        buf.dissipated_j = online.dissipated;
        self.picture.publish();
    }
}

impl Effect for Tearing {
    fn name(&self) -> &'static str {
        "tearing"
    }

    /// Each grasp site's integrator (damage state, displacement, working arrays) and pull
    /// patterns, the tearable cells, and the three pictures of the frame thread's buffer.
    fn memory_bytes(&self) -> usize {
        use crate::memory::vec_bytes;
        let sites: usize = self
            .sites
            .iter()
            .map(|s| s.online.heap_bytes() + vec_bytes(&s.loads) + s.loads.iter().map(vec_bytes).sum::<usize>() + vec_bytes(&s.grasp_modes))
            .sum();
        vec_bytes(&self.sites) + sites + vec_bytes(&self.cells) + 3 * self.picture_bytes
    }

    fn tick(&mut self, tool: &ToolInput, state: &mut TickState) {
        self.tick += 1;
        let closed = tool.kind == ToolKind::Grasper && tool.closure >= JAWS_CLOSED;
        match self.phase {
            Phase::Free => {
                if closed && let Some(k) = self.site_at(tool.position_m) {
                    self.activate(k);
                    self.sites[k].online.hold();
                    self.torn_points = self.count_torn(); // what was torn before this grasp
                    self.phase = Phase::Held { anchor: tool.position_m };
                    state.events.0 |= Events::GRASPED;
                }
            }
            Phase::Held { anchor } => {
                if !closed {
                    self.phase = Phase::Fading { from: self.s, k: 0 };
                    state.events.0 |= Events::RELEASED;
                } else {
                    let site = &mut self.sites[self.active];
                    // the pull from the anchor in the pull's frame: along the load (pushing
                    // does nothing) and across it
                    let dx: [f64; 3] = std::array::from_fn(|k| tool.position_m[k] - anchor[k]);
                    let mut pull = [0.0; 3];
                    for (p, t) in site.frame.iter().enumerate().take(site.loads.len()) {
                        pull[p] = dx[0] * t[0] + dx[1] * t[1] + dx[2] * t[2];
                    }
                    pull[0] = pull[0].max(0.0);
                    let w = site.grasp_displacement();
                    let ds = site.control(pull, w);
                    let max_factor = self.max_force / site.resultant_n;
                    let mut target: [f64; 3] = std::array::from_fn(|p| self.s[p] + ds[p]);
                    target[0] = target[0].max(0.0);
                    let size = target.iter().map(|x| x * x).sum::<f64>().sqrt();
                    if size > max_factor {
                        target.iter_mut().for_each(|x| *x *= max_factor / size);
                        state.events.0 |= Events::FORCE_SATURATED;
                    }
                    self.load_to(target, state);
                    let torn_points = self.count_torn();
                    if torn_points > self.torn_points {
                        self.torn_points = torn_points;
                        self.sites[self.active].spent = true;
                        self.phase = Phase::Fading { from: self.s, k: 0 };
                        state.events.0 |= Events::TISSUE_TORN;
                    }
                }
            }
            Phase::Fading { from, k } => {
                let k = k + 1;
                let target = from.map(|x| x * (1.0 - f64::from(k) / f64::from(FADE_TICKS)).max(0.0));
                self.load_to(target, state);
                self.phase = if k >= FADE_TICKS { Phase::Free } else { Phase::Fading { from, k } };
            }
        }
        if matches!(self.phase, Phase::Held { .. }) {
            state.events.0 |= Events::CONTACT;
        }
        // the tissue's reaction, −|R| Σ_p s_p t̂_p, with the calibrated relative error at its
        // load level while held (module docs); none while it fades (the force is then the
        // fade's, not the tissue's) or without a calibration
        let site = &self.sites[self.active];
        if self.s.iter().any(|&s| s != 0.0) {
            let level = self.s.iter().map(|x| x * x).sum::<f64>().sqrt();
            state.force_error_n = match self.phase {
                Phase::Held { .. } => site.online.force_error_for(self.s).map(|e| e * level * site.resultant_n),
                _ => None,
            };
        }
        for (s, t) in self.s.iter().zip(&site.frame) {
            for k in 0..3 {
                state.force_n[k] -= s * site.resultant_n * t[k];
            }
        }
        self.publish();
    }

    /// At [`Fidelity::Reduced`] every site's integrator steps its cheaper setting (the
    /// simplified integrator on the bundle's fallback modes, [`OnlineTear::set_reduced`]),
    /// from the state it holds: the force does not jump, and its estimate is the fallback's.
    fn set_fidelity(&mut self, fidelity: Fidelity) {
        for site in &mut self.sites {
            site.online.set_reduced(fidelity == Fidelity::Reduced);
        }
    }

    /// Several tools at once (two hands): the grasper's state drives the grasp — the first
    /// grasper state of the tick (one grasper per tearing scene in this version) — and only
    /// that state gets the tissue's reaction and the tearing events; the other tools (a probe,
    /// a scalpel on another organ) pass untouched. A tick without a grasper state replays
    /// the grasper's last one: a tool that sends nothing stays where it was, so a hold stays
    /// held (the pull's control goes on towards the same offset, exactly as if the grasper
    /// had sent its state again) and a fade goes on.
    fn tick_tools(&mut self, tools: &[ToolInput], states: &mut [TickState]) {
        match tools.iter().position(|t| t.kind == ToolKind::Grasper) {
            Some(g) => {
                self.last_grasper = Some(tools[g]);
                self.tick(&tools[g], &mut states[g]);
            }
            None => {
                let mut unseen = TickState::default();
                match self.last_grasper {
                    Some(last) => self.tick(&last, &mut unseen),
                    None => self.tick += 1,
                }
            }
        }
    }

    fn reset(&mut self) {
        self.last_grasper = None;
        // the tissue keeps its damage; the jaws start open
        if let Phase::Held { .. } = self.phase {
            self.phase = Phase::Fading { from: self.s, k: 0 };
        }
    }
}

impl Tearing {
    /// Organ index.
    pub fn organ(&self) -> usize {
        self.organ
    }
}
