//! The grasper (seed 000 §4.6.2): jaws close on the tissue, the device pulls, the tissue
//! damages and tears; one step of the POD–PGD integrator ([`crate::damage::online`]) per tick.
//!
//! # The grasp
//! The vademecum was built for the scene's grasp: the nodes its load (`[[organs.loads]]`)
//! acts on and the direction `n̂` of that load's resultant (the seed pulls one node; the load
//! increment of a unit step is that load). The jaws take hold when they close
//! (`closure ≥ 0.5`) within `jaw_width` of the grasp's centre; the position where they closed
//! is the anchor.
//!
//! # The pull
//! Each tick the device's pull is `p = max(0, (x − anchor)·n̂)`; the tissue follows it by
//! displacement control: with the grasp's displacement `w = (L·u)/|R|` (the load-weighted mean
//! along `n̂`; `L` the unit load, `R` its resultant) and the secant compliance `c = w/s` (at
//! rest, the virgin compliance measured when the session starts), the load factor moves by
//! `ds = (p − w)/c`, at most [`MAX_LOAD_STEP`] unit steps per tick and never past the grasper's
//! `max_force` (`s·|R| ≤ max_force`, flagged `FORCE_SATURATED`). The force on the tool is the
//! tissue's reaction `−s·R`. The step's damage growth is limited by the integrator's
//! sub-steps (`[fidelity.tearing] max_damage_increment`).
//!
//! # Tearing, losing the grasp
//! When the damage of a cell of the tearable tissue reaches the scene's `torn` threshold
//! (default 0.8, as the seed: "levels of damage exceeding certain threshold indicate the full
//! rupture of the tissue … grasping is considered lost"), the grasp is lost (`TISSUE_TORN`)
//! and the tissue springs back. The tear need not pass through the grasped nodes themselves —
//! on the gallbladder it runs through the fat a cell or two from them, where the pulled flap
//! meets the anchored layer; the vademecum's load stays on the grasped nodes, so past the
//! first torn cell its answers would describe a flap still attached. The load factor fades linearly to zero over [`FADE_TICKS`] ticks, so the force drops by at
//! most `1/FADE_TICKS` of its value per tick — gentler than the device bridge's watchdog,
//! which may drop a third per tick. Opening the jaws releases the same way (`RELEASED`). A
//! torn grasp cannot be taken again. Cells past the threshold stop rendering (the frame's
//! per-cell damage; the recording's `.pvd` leaves them out).
//!
//! # Frames
//! The tick publishes, through a lock-free triple buffer, the accumulated modal amplitudes
//! and the tearable cells' damage ([`TearPicture`]); the frame thread rebuilds the whole
//! displacement from them ([`TearOffline::displacement`]).

use std::sync::Arc;

use super::{Effect, Events, TickState, ToolInput, ToolKind};
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
    /// The tick it shows (0: the rest state).
    pub tick: u64,
    /// The accumulated modal amplitudes.
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
    /// The grasp's centre (m): the load-weighted mean of the grasped nodes. The jaws take hold
    /// when they close within the grasper's `jaw_width` of it.
    pub centre_m: [f64; 3],
    /// The pull's direction `n̂` (unit): the device's motion counts along it.
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
    /// Letting go: the load factor fades from `from` over [`FADE_TICKS`]; `k` ticks done.
    Fading { from: f64, k: u32 },
}

/// The tearing effect of one organ.
pub struct Tearing {
    organ: usize,
    online: OnlineTear,
    /// Loaded dofs and the unit load there (N).
    load: Vec<(usize, f64)>,
    /// `|R|` (N per unit step) and `n̂`.
    resultant_n: f64,
    direction: [f64; 3],
    centre: [f64; 3],
    jaw_width: f64,
    max_factor: f64,
    /// Compliance of the virgin tissue, `w` per unit step (m).
    virgin_compliance: f64,
    /// Tearable cells, with their points' range.
    cells: Vec<(usize, std::ops::Range<usize>)>,
    torn: f64,
    phase: Phase,
    torn_out: bool,
    s: f64,
    tick: u64,
    picture: triple_buffer::Input<TearPicture>,
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
}

impl Tearing {
    /// The effect for organ `organ`, on `off` (shared by sessions), with the grasper's jaw
    /// width and force limit. Also returns the frame thread's end of the pictures.
    pub fn new(
        organ: usize,
        off: Arc<TearOffline>,
        variant: Variant,
        limits: StepLimits,
        jaw_width: f64,
        max_force: f64,
    ) -> Result<(Self, TearPictures), TearingError> {
        let m = &off.model;
        let load: Vec<(usize, f64)> = m
            .load
            .iter()
            .enumerate()
            .filter(|(_, f)| **f != 0.0)
            .map(|(d, f)| (d, *f))
            .collect();
        let (_, centre, r) = m.grasp().ok_or(TearingError::NoGrasp)?;
        let resultant_n = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        if resultant_n <= 0.0 || !resultant_n.is_finite() {
            return Err(TearingError::NoGrasp);
        }
        let direction = r.map(|x| x / resultant_n);
        // the virgin compliance, from one unit step of a scratch integrator
        let mut scratch = OnlineTear::new(off.clone(), variant, limits);
        scratch.step(1.0);
        let w1 = load.iter().map(|&(d, f)| f * scratch.local_u(d)).sum::<f64>() / resultant_n;
        if !(w1 > 0.0 && w1.is_finite()) {
            return Err(TearingError::Rigid(w1));
        }
        let mut tearable_cell = vec![false; m.mesh.n_cells()];
        for &p in &m.points.tearable {
            tearable_cell[m.points.cell[p]] = true;
        }
        let cells: Vec<(usize, std::ops::Range<usize>)> = (0..m.mesh.n_cells())
            .filter(|&c| tearable_cell[c])
            .map(|c| (c, m.points.first[c]..m.points.first[c + 1]))
            .collect();
        let torn = m.torn.iter().copied().fold(f64::INFINITY, f64::min).min(1.0);
        let online = OnlineTear::new(off.clone(), variant, limits);
        let picture = TearPicture {
            organ,
            tick: 0,
            amplitudes: online.amplitudes().clone(),
            cell_damage: vec![0.0; m.mesh.n_cells()],
            torn: torn as f32,
            grasped: false,
            dissipated_j: 0.0,
        };
        let (input, output) = triple_buffer::triple_buffer(&picture);
        Ok((
            Self {
                organ,
                online,
                load,
                resultant_n,
                direction,
                centre,
                jaw_width,
                max_factor: max_force.max(0.0) / resultant_n,
                virgin_compliance: w1,
                cells,
                torn,
                phase: Phase::Free,
                torn_out: false,
                s: 0.0,
                tick: 0,
                picture: input,
            },
            output,
        ))
    }

    /// Where the jaws take hold and which way they pull.
    pub fn site(&self) -> GraspSite {
        GraspSite {
            organ: self.organ,
            centre_m: self.centre,
            pull_direction: self.direction,
        }
    }

    /// The grasp's displacement along the pull, `w = (L·u)/|R|` (m).
    fn grasp_displacement(&self) -> f64 {
        self.load.iter().map(|&(d, f)| f * self.online.local_u(d)).sum::<f64>() / self.resultant_n
    }

    /// Moves the load factor to `target` (one integrator step), flagging growing damage.
    fn load_to(&mut self, target: f64, state: &mut TickState) {
        let ds = target - self.s;
        if ds.abs() > 1e-12 {
            let step = self.online.step(ds);
            self.s = target;
            if step.dissipated > 0.0 {
                state.events.0 |= Events::TEARING;
            }
        }
    }

    /// The largest damage of the tearable points.
    fn worst_damage(&self) -> f64 {
        let m = &self.online.offline().model;
        m.points.tearable.iter().map(|&p| self.online.state[p].damage()).fold(0.0, f64::max)
    }

    fn publish(&mut self) {
        let (state, amplitudes) = (&self.online.state, self.online.amplitudes());
        let buf = self.picture.input_buffer_mut();
        buf.tick = self.tick;
        buf.amplitudes.copy_from(amplitudes);
        for (c, range) in &self.cells {
            buf.cell_damage[*c] = range.clone().map(|p| state[p].damage()).fold(0.0, f64::max) as f32;
        }
        buf.grasped = matches!(self.phase, Phase::Held { .. });
        buf.dissipated_j = self.online.dissipated;
        self.picture.publish();
    }
}

impl Effect for Tearing {
    fn name(&self) -> &'static str {
        "tearing"
    }

    fn tick(&mut self, tool: &ToolInput, state: &mut TickState) {
        self.tick += 1;
        let closed = tool.kind == ToolKind::Grasper && tool.closure >= JAWS_CLOSED;
        match self.phase {
            Phase::Free => {
                let d2: f64 = (0..3).map(|k| (tool.position_m[k] - self.centre[k]).powi(2)).sum();
                if closed && !self.torn_out && d2 <= self.jaw_width * self.jaw_width {
                    self.phase = Phase::Held { anchor: tool.position_m };
                    state.events.0 |= Events::GRASPED;
                }
            }
            Phase::Held { anchor } => {
                if !closed {
                    self.phase = Phase::Fading { from: self.s, k: 0 };
                    state.events.0 |= Events::RELEASED;
                } else {
                    let pull = (0..3)
                        .map(|k| (tool.position_m[k] - anchor[k]) * self.direction[k])
                        .sum::<f64>()
                        .max(0.0);
                    let w = self.grasp_displacement();
                    let c = if self.s > 1e-9 && w > 0.0 {
                        w / self.s
                    } else {
                        self.virgin_compliance
                    };
                    let ds = ((pull - w) / c).clamp(-MAX_LOAD_STEP, MAX_LOAD_STEP);
                    let mut target = (self.s + ds).max(0.0);
                    if target > self.max_factor {
                        target = self.max_factor;
                        state.events.0 |= Events::FORCE_SATURATED;
                    }
                    self.load_to(target, state);
                    if self.worst_damage() >= self.torn {
                        self.torn_out = true;
                        self.phase = Phase::Fading { from: self.s, k: 0 };
                        state.events.0 |= Events::TISSUE_TORN;
                    }
                }
            }
            Phase::Fading { from, k } => {
                let k = k + 1;
                let target = from * (1.0 - f64::from(k) / f64::from(FADE_TICKS)).max(0.0);
                self.load_to(target, state);
                self.phase = if k >= FADE_TICKS { Phase::Free } else { Phase::Fading { from, k } };
            }
        }
        if matches!(self.phase, Phase::Held { .. }) {
            state.events.0 |= Events::CONTACT;
        }
        let f = self.s * self.resultant_n;
        for k in 0..3 {
            state.force_n[k] -= f * self.direction[k];
        }
        self.publish();
    }

    fn reset(&mut self) {
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
