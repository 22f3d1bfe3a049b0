//! One simulation tick: tool state in → contact → each effect the scene names, in a fixed
//! order → force out (see `DESIGN.md`, "The data path").
//!
//! A [`Pipeline`] is assembled once per session from the scene's `[effects]` and the loaded
//! vademecums; each [`Effect`] owns its state and its preallocated workspace, so a tick
//! allocates nothing, and a scene that names only palpation carries no cutting state, no
//! damage arrays and does no extra work per tick. Large deformations scale the palpation
//! force by the organ's ANM-POD lattice; cutting follows palpation as its own [`Effect`], and
//! tearing (the grasper) the same way.
//!
//! # Layout
//! - [`Effect`], [`ToolInput`], [`TickState`], [`Events`]: the contract between the tick
//!   driver (the server's tick thread) and the effects.
//! - [`palpation`]: the linear PGD deformation effect (a spherical tip tracked on the
//!   organ's surface by a proxy, force `f = C(s)⁻¹δ` from the vademecum).
//! - [`cutting`]: the scalpel (seed 000 §3.4): the cut's compliance added at the contact, the
//!   blade force split and cut criterion, and the cut thread that grows the cut beside the tick.
//! - [`tearing`]: the grasper (seed 000 §4.6.2): grasp, pull, one POD–PGD damage step per
//!   tick, the grasp lost when the tissue tears.

pub mod corotational;
pub mod cut_picture;
pub mod cutting;
pub mod palpation;
pub mod tearing;

use std::sync::Arc;

use crate::bundle::LoadedBundle;
use crate::scene::Scene;
use crate::scene::schema::{GLOBAL_FORCE_LIMIT_N, ToolSpec};

pub use cutting::{BladeForce, Cutting};
pub use palpation::Palpation;
pub use tearing::{GraspSite, TearPicture, TearPictures, Tearing};

/// Lowers the calling thread to the lowest CPU priority (nice 19; Linux, where the nice value
/// is per thread; elsewhere nothing): for the work beside the tick — a co-rotational
/// deformation, a recorder — so that the tick thread takes a core from it whenever it wakes.
pub fn lower_thread_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: setpriority only reads its arguments; `who = 0` is the calling thread
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 19);
    }
}

/// The kind of tool a tool state describes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ToolKind {
    /// A spherical-tip probe (palpation).
    #[default]
    Probe,
    /// A scalpel.
    Scalpel,
    /// A grasper.
    Grasper,
    /// A kind this version does not know (a wire value out of the enum).
    Other,
}

impl ToolKind {
    /// How the tool's load reaches the tissue: a blade's edge lies along the surface, every
    /// other tool presses with a tip (docs/contact.md, "Which stiffness is right").
    pub fn footprint(self) -> crate::pgd::Footprint {
        match self {
            Self::Scalpel => crate::pgd::Footprint::Edge,
            _ => crate::pgd::Footprint::Tip,
        }
    }
}

/// What the tick reads from the tool (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolInput {
    /// Which of the scene's tools this is: its index in the scene's `[[tools]]` list. Each
    /// index keeps its own contact from tick to tick, so several tools touch the organs at
    /// once ([`Pipeline::tick_tools`]); a session driven by one tool at a time uses 0 for all
    /// of them, as before tools had names.
    pub tool: usize,
    /// Tool kind.
    pub kind: ToolKind,
    /// Tip position in the organ's reference frame (m).
    pub position_m: [f64; 3],
    /// Tip velocity (m/s), for effects that depend on it.
    pub velocity_m_s: [f64; 3],
    /// Blade engagement or jaw closure, 0 (open) to 1 (closed).
    pub closure: f64,
    /// Tool orientation as a unit quaternion `[w, x, y, z]`. For a scalpel, the tool frame's
    /// y axis turned by it is the normal of the blade's plane.
    pub orientation: [f64; 4],
    /// A scalpel's blade is the segment from `position_m` (its tip) to this point (m), the
    /// other end of its cutting edge; other tools ignore it.
    pub blade_end_m: [f64; 3],
}

impl Default for ToolInput {
    /// Tool 0, a probe at the origin, at rest, open, with the identity orientation.
    fn default() -> Self {
        Self {
            tool: 0,
            kind: ToolKind::Probe,
            position_m: [0.0; 3],
            velocity_m_s: [0.0; 3],
            closure: 0.0,
            orientation: [1.0, 0.0, 0.0, 0.0],
            blade_end_m: [0.0; 3],
        }
    }
}

/// How far a quaternion's norm may stray from 1 (clients may send f32-normalised or slightly
/// drifted quaternions; anything farther is not an orientation).
pub const QUATERNION_NORM_TOLERANCE: f64 = 0.1;

/// The largest speed a tool state may carry (m/s): ten times a surgeon's fastest motion.
pub const MAX_TOOL_SPEED_M_S: f64 = 10.0;

impl ToolInput {
    /// Where the tool touches the organ: a probe's tip centre (`position_m`); a scalpel's, the
    /// middle of its cutting edge (from `position_m` to `blade_end_m`), the point of the blade
    /// that presses on the tissue.
    pub fn contact_point(&self) -> [f64; 3] {
        match self.kind {
            ToolKind::Scalpel => std::array::from_fn(|k| 0.5 * (self.position_m[k] + self.blade_end_m[k])),
            _ => self.position_m,
        }
    }

    /// Whether every field is finite, the closure lies in [0, 1], the speed is at most
    /// [`MAX_TOOL_SPEED_M_S`] and the orientation's norm is within
    /// [`QUATERNION_NORM_TOLERANCE`] of 1.
    pub fn is_valid(&self) -> bool {
        let q2: f64 = self.orientation.iter().map(|x| x * x).sum();
        let v2: f64 = self.velocity_m_s.iter().map(|x| x * x).sum();
        self.position_m
            .iter()
            .chain(&self.velocity_m_s)
            .chain(&self.orientation)
            .chain(&self.blade_end_m)
            .all(|v| v.is_finite())
            && (0.0..=1.0).contains(&self.closure)
            && v2 <= MAX_TOOL_SPEED_M_S * MAX_TOOL_SPEED_M_S
            && (q2.sqrt() - 1.0).abs() <= QUATERNION_NORM_TOLERANCE
    }
}

/// Discrete happenings of a tick, as bit flags (no allocation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Events(pub u32);

impl Events {
    /// The tool touches the organ.
    pub const CONTACT: u32 = 1;
    /// The tool state was rejected (non-finite or out of range): zero force.
    pub const REJECTED_INPUT: u32 = 2;
    /// A cut advanced (cutting effect).
    pub const CUT_ADVANCED: u32 = 4;
    /// The tissue holding the grasp tore: the grasp is lost and the force fades (tearing
    /// effect).
    pub const TISSUE_TORN: u32 = 8;
    /// The contact is deeper than the model's precomputed range (the large-deformation
    /// lattice's paths): the force continues along the last computed stiffness.
    pub const BEYOND_RANGE: u32 = 16;
    /// The force reached the tool's `max_force` and was clamped to it (direction kept).
    pub const FORCE_SATURATED: u32 = 32;
    /// The force in the blade's plane rose above the scalpel's `cut_force`: a cutting stroke
    /// starts (cutting effect).
    pub const CUT_STARTED: u32 = 64;
    /// The blade's edge lies in a cut already made (cutting effect).
    pub const BLADE_IN_CUT: u32 = 128;
    /// The grasper's jaws took hold of the tissue (tearing effect).
    pub const GRASPED: u32 = 256;
    /// The pull raised the tissue's damage this tick (tearing effect).
    pub const TEARING: u32 = 512;
    /// The jaws opened on held tissue; the force fades (tearing effect).
    pub const RELEASED: u32 = 1024;
    /// The session runs at its reduced fidelity ([`Fidelity::Reduced`]): it fell back to a
    /// cheaper setting because its ticks came close to missing their deadline.
    pub const REDUCED_FIDELITY: u32 = 2048;

    /// The flags that mark a happening rather than a state (a cut advanced, a stroke started,
    /// the tissue tore, the jaws took or let go): a tick that answers no client still
    /// happened, so a session keeps these and reports them with its next answer. The others
    /// (contact, saturation, the blade in a cut, beyond range) describe the tick they come
    /// with and are never carried over.
    pub const ONE_SHOT: u32 = Self::CUT_ADVANCED | Self::TISSUE_TORN | Self::CUT_STARTED | Self::GRASPED | Self::TEARING | Self::RELEASED;

    /// Every flag with its name, in bit order (the names recordings write: [`Events::names`]).
    pub const NAMES: [(u32, &'static str); 12] = [
        (Self::CONTACT, "contact"),
        (Self::REJECTED_INPUT, "rejected_input"),
        (Self::CUT_ADVANCED, "cut_advanced"),
        (Self::TISSUE_TORN, "tissue_torn"),
        (Self::BEYOND_RANGE, "beyond_range"),
        (Self::FORCE_SATURATED, "force_saturated"),
        (Self::CUT_STARTED, "cut_started"),
        (Self::BLADE_IN_CUT, "blade_in_cut"),
        (Self::GRASPED, "grasped"),
        (Self::TEARING, "tearing"),
        (Self::RELEASED, "released"),
        (Self::REDUCED_FIDELITY, "reduced_fidelity"),
    ];

    /// Whether flag `f` is set.
    pub fn has(self, f: u32) -> bool {
        self.0 & f != 0
    }

    /// The names of the flags set, joined by `|` (`contact|grasped|tearing`; empty for none;
    /// an unnamed bit as its number), as recordings write them.
    pub fn names(self) -> String {
        let mut out: Vec<String> = Self::NAMES
            .iter()
            .filter(|(f, _)| self.has(*f))
            .map(|(_, n)| (*n).to_string())
            .collect();
        let known = Self::NAMES.iter().fold(0, |a, (f, _)| a | f);
        if self.0 & !known != 0 {
            out.push((self.0 & !known).to_string());
        }
        out.join("|")
    }
}

/// The contact of the tool with the organ, as the effects leave it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Contact {
    /// Organ index in the scene.
    pub organ: usize,
    /// Nodes of the surface triangle touched.
    pub nodes: [usize; 3],
    /// Barycentric weights of the contact point in it.
    pub weights: [f64; 3],
    /// Point on the reference surface where the tissue is loaded (m): the proxy, or, where
    /// the proxy touches nodes the vademecum cannot load, the nearest point of the loadable
    /// nodes (`nodes` and `weights` describe it).
    pub point_m: [f64; 3],
    /// The proxy: where the tool rests on the reference surface (m).
    pub proxy_m: [f64; 3],
    /// Penetration depth (m, positive): how far the tip's sphere reaches below the surface
    /// at the proxy, along the surface normal.
    pub depth_m: f64,
    /// The part of the force the deformable tissue carries at `point_m` (N, on the tissue;
    /// the rest goes into the rigid support).
    pub tissue_force_n: [f64; 3],
    /// The share λ of the contact the deformable tissue carries (0 to 1; the rest lies on
    /// the rigid support).
    pub loadable: f64,
    /// The displacement imposed on the tissue at `point_m`, `δ = −depth · n` (m).
    pub imposed_m: [f64; 3],
    /// On an organ that deforms largely, the lattice's stiffening of the tissue's part at this
    /// contact (`None` on a linear organ): the effects after palpation that change the linear
    /// force (cutting) scale theirs by it.
    pub stiffened: Option<Stiffened>,
}

/// The large-deformation law at a contact: the ratio `r` of the nonlinear to the linear force
/// at its depth, from the organ's ANM-POD lattice ([`crate::rom::palpation::Stiffening`]), and
/// the ratio's estimated error (relative to the linear force).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stiffened {
    /// `r`: the tissue's force is `r` times the linear law's.
    pub ratio: f64,
    /// The estimated error of `r` (the lattice's interpolation and path errors; the linear
    /// law's round-off is not in it).
    pub ratio_error: f64,
}

/// What a tick produces, filled in by the effects in order. `Copy` and small: the tick
/// thread hands it to the viewers through a latest-value slot.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TickState {
    /// Force on the tool (N), the reaction of the tissue (opposite to the force the tool
    /// applies to it).
    pub force_n: [f64; 3],
    /// The contact, if the tool touches an organ.
    pub contact: Option<Contact>,
    /// Events of this tick.
    pub events: Events,
    /// The force on a scalpel's blade split along it (cutting scenes, scalpel ticks).
    pub blade: Option<BladeForce>,
    /// An estimate of the error of `force_n` against the full-order model of the same mesh
    /// (N), set by the effects that can tell (palpation, linear and large: see
    /// [`palpation`]; cutting with local fields; tearing while held, from the bundle's
    /// calibration); `None` when an effect that cannot shaped the force, or the input was
    /// rejected.
    pub force_error_n: Option<f64>,
    /// Where the tool was (the probe tip's centre, the scalpel's tip, the grasper's jaws; m):
    /// the input the tick answered. `None` when the input was rejected.
    pub tool_m: Option<[f64; 3]>,
}

/// The fidelity an effect runs at: its scene's settings, or the cheaper setting a session falls
/// back to under load (see the server's fidelity governor). A reduced setting is one the study
/// measures: large deformations blend the lattice's nearest position instead of four (a
/// quarter of the series evaluations, with an error estimate calibrated for it); tearing steps
/// the simplified integrator on the fewest modes whose calibrated force error stays within
/// 1.25× of all of them ([`crate::damage::online::TearFallback`]); the frames show a prefix
/// of the modes (the server's side).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Fidelity {
    /// The scene's settings.
    #[default]
    Full,
    /// The cheaper fallback.
    Reduced,
}

/// A simulated effect: one stage of the tick.
pub trait Effect: Send {
    /// Short name (`"palpation"`, …) for logs and metrics.
    fn name(&self) -> &'static str;
    /// Advances the effect by one tick for tool input `tool`, reading and updating `state`.
    /// Must not allocate, block or log.
    fn tick(&mut self, tool: &ToolInput, state: &mut TickState);
    /// Advances the effect by one tick for several tools at once, `tools[i]` reading and
    /// updating `states[i]` (equal lengths, at most [`MAX_TOOLS`], distinct
    /// [`ToolInput::tool`]). The default runs [`Effect::tick`] for each tool in turn: right for
    /// an effect whose tools do not feel each other; palpation overrides it to solve the
    /// contacts of every tool on an organ together. Must not allocate, block or log.
    fn tick_tools(&mut self, tools: &[ToolInput], states: &mut [TickState]) {
        for (tool, state) in tools.iter().zip(states.iter_mut()) {
            self.tick(tool, state);
        }
    }
    /// Bytes of the state this effect holds for its session ([`crate::memory`]): its own
    /// buffers, not the bundles it shares with other sessions.
    fn memory_bytes(&self) -> usize;
    /// Forgets the state carried from tick to tick (the contact proxy): the next tick starts
    /// as if the tool had just appeared.
    fn reset(&mut self) {}
    /// Runs the next ticks at `fidelity` (an effect with no cheaper setting ignores it). Must
    /// not allocate: the tick thread calls it.
    fn set_fidelity(&mut self, _fidelity: Fidelity) {}
    /// Makes the effect's work beside the tick land at ticks fixed by the tool's path alone
    /// (`true`: a headless run, reproducible on any load: the tick waits for that work) or
    /// as soon as it is done (`false`, the default: a live session, whose tick never waits).
    /// Called before the first tick.
    fn set_deterministic(&mut self, _deterministic: bool) {}
}

/// Why a pipeline could not be assembled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PipelineError {
    /// The scene names an effect this version cannot simulate yet.
    #[error("the scene asks for {0}, which this version of vademecum does not simulate yet")]
    Unsupported(&'static str),
    /// The number of bundles does not match the number of organs.
    #[error("the scene has {organs} organ(s) but {bundles} bundle(s) were given")]
    BundleCount {
        /// Organs in the scene.
        organs: usize,
        /// Bundles given.
        bundles: usize,
    },
    /// The scene asks for large deformations but a bundle has no lattice.
    #[error(
        "the scene asks for large deformations but the bundle of organ {organ} has no large-deformation lattice; rebuild it with `vademecum build`"
    )]
    NoLattice {
        /// The organ.
        organ: usize,
    },
    /// The scene has no probe tool to palpate with.
    #[error("the scene has no probe tool; add a [[tools]] entry with kind = \"probe\"")]
    NoProbe,
    /// A cutting scene has no scalpel.
    #[error("the scene asks for cutting but has no scalpel; add a [[tools]] entry with kind = \"scalpel\"")]
    NoScalpel,
    /// A tearing scene has no grasper.
    #[error("the scene asks for tearing but has no grasper; add a [[tools]] entry with kind = \"grasper\"")]
    NoGrasper,
    /// The tearing model could not be prepared.
    #[error("cannot prepare the tearing model of organ {organ}: {message}")]
    Tearing {
        /// The organ.
        organ: usize,
        /// What went wrong.
        message: String,
    },
    /// The cutting model of an organ could not be prepared.
    #[error("cannot prepare the cutting model of organ {organ}: {message}")]
    Cutting {
        /// The organ.
        organ: usize,
        /// What went wrong.
        message: String,
    },
}

/// The effects of a session, in tick order.
pub struct Pipeline {
    effects: Vec<Box<dyn Effect>>,
    /// The force limit (N): the probe's `max_force`, or the global limit in a scene without
    /// a probe.
    max_force_n: f64,
    /// The scalpel's force limit (N): its `max_force`.
    scalpel_max_force_n: f64,
    /// Where tool positions are accepted: the organs' bounding box grown by
    /// [`WORKSPACE_MARGIN_M`].
    workspace: crate::contact::Bounds,
    /// Whether the scene palpates with a probe.
    probe: bool,
    /// The scalpel's blade length (m), in a cutting scene.
    blade_length_m: Option<f64>,
    /// What the cut thread has done (cutting scenes).
    cut_status: Option<Arc<cutting::CutStatus>>,
    /// The grasper's force limit (N), in a tearing scene.
    grasper_max_force_n: Option<f64>,
    /// The frame thread's end of the tearing pictures (taken once, by the session).
    tear_pictures: Option<TearPictures>,
    /// The tearing organ's offline data, one per grasp site (tearing scenes).
    tear_offline: Vec<Arc<crate::damage::online::TearOffline>>,
    /// Where the grasper takes hold (tearing scenes).
    grasp_sites: Vec<GraspSite>,
    /// The co-rotational deformation (co-rotational cutting; taken once, by the session's
    /// frame thread).
    corotational: Option<corotational::CorotationalDeformation>,
    /// The fidelity the effects run at.
    fidelity: Fidelity,
    /// How many tools the scene names (tool indices below it are accepted).
    tools: usize,
    /// Each of the scene's tools: its kind and force limit (N).
    tool_limits: Vec<(ToolKind, f64)>,
}

/// Most tools a scene names and a tick moves together ([`crate::scene::schema::MAX_TOOLS`]).
pub use crate::scene::schema::MAX_TOOLS;

// the contacts of every tool on one organ are solved together
const _: () = assert!(MAX_TOOLS <= crate::pgd::coupled::MAX_CONTACTS);

/// How far outside the organs' bounding box a tool position is still accepted (m); farther
/// positions are rejected as out of range (a device or client in the wrong units or frame).
pub const WORKSPACE_MARGIN_M: f64 = 1.0;

/// The scalpel's tip, for the contact, is a sphere of this fraction of its blade length.
pub const SCALPEL_TIP_FRACTION: f64 = 0.05;

/// The longest blade edge a scalpel state may carry, in blade lengths (farther: a device in
/// the wrong units or frame).
pub const MAX_BLADE_EDGE: f64 = 2.0;

impl std::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.effects.iter().map(|e| e.name())).finish()
    }
}

impl Pipeline {
    /// Assembles the effects `scene` names, over its organs' loaded bundles (one per organ,
    /// in scene order, shared read-only between sessions).
    ///
    /// A cutting scene (`effects.cutting`, linear, a scalpel) also reads its cut organ's mesh
    /// ([`Scene::cut_organ`]) and prepares its reduced cutting model from the bundle's modes
    /// (seconds on a large organ: call it off any async runtime), and starts the cut thread.
    /// Effects compose on different organs: a scene may deform one organ largely (its own
    /// `deformation = "large"`), tear another (its grasper) and cut a third (its scalpel) in
    /// one session, each tool acting on the organ it touches ([`Scene::cut_organ`]); on one
    /// organ, cutting composes with large deformations (the cut's force scaled by the
    /// organ's lattice: [`cutting::stiffened_cut`]), and tearing with neither yet (scene
    /// validation refuses them).
    pub fn for_scene(scene: &Scene, bundles: &[Arc<LoadedBundle>]) -> Result<Self, PipelineError> {
        let fx = &scene.spec.effects;
        if bundles.len() != scene.spec.organs.len() {
            return Err(PipelineError::BundleCount {
                organs: scene.spec.organs.len(),
                bundles: bundles.len(),
            });
        }
        let probe = scene.spec.tools.iter().find_map(|t| match t {
            ToolSpec::Probe { radius, max_force, .. } => Some((*radius, *max_force)),
            _ => None,
        });
        let scalpel = scene.spec.scalpel();
        let grasper = scene.spec.tools.iter().find_map(|t| match t {
            ToolSpec::Grasper { jaw_width, max_force, .. } => Some((*jaw_width, *max_force)),
            _ => None,
        });
        // each organ's deformation; the organs cut or torn are linear (scene validation)
        let large: Vec<bool> = (0..bundles.len()).map(|i| scene.organ_large(i)).collect();
        if fx.tearing {
            if grasper.is_none() {
                return Err(PipelineError::NoGrasper);
            }
            if crate::scene::tearing::tearable_organ(scene).is_some_and(|i| large[i]) {
                return Err(PipelineError::Unsupported(
                    "tearing together with large deformations on one organ (a tearable organ with deformation = \"large\")",
                ));
            }
        }
        if fx.cutting {
            if scalpel.is_none() {
                return Err(PipelineError::NoScalpel);
            }
        } else if probe.is_none() && !fx.tearing {
            return Err(PipelineError::NoProbe);
        }
        if let Some(i) = (0..bundles.len()).find(|&i| large[i] && bundles[i].anm.is_none()) {
            return Err(PipelineError::NoLattice { organ: i });
        }
        let radius = match (probe, scalpel) {
            (Some((r, _)), _) => Some(r),
            (None, Some((blade, _))) if fx.cutting => Some(SCALPEL_TIP_FRACTION * blade),
            _ => None,
        };
        // a tearing scene without a probe palpates nothing: the grasper is its only tool
        let mut effects: Vec<Box<dyn Effect>> = match radius {
            Some(r) => vec![Box::new(Palpation::for_tools(
                bundles.to_vec(),
                tip_radii(&scene.spec.tools, r),
                &large,
            ))],
            None => Vec::new(),
        };
        let (mut tear_pictures, mut tear_offline, mut grasp_sites) = (None, Vec::new(), Vec::new());
        if fx.tearing
            && let Some((jaw_width, max_force)) = grasper
        {
            let (t, pictures, off) = tearing_effect(scene, bundles, jaw_width, max_force)?;
            tear_pictures = Some(pictures);
            tear_offline = off;
            grasp_sites = t.sites();
            effects.push(Box::new(t));
        }
        let (mut cut_status, mut corotational) = (None, None);
        if let (Some(organ), Some((_, cut_force))) = (scene.cut_organ(), scalpel) {
            let (c, deformation) = cutting_effect(scene, organ, &bundles[organ], cut_force)?;
            cut_status = Some(c.status());
            corotational = deformation;
            effects.push(Box::new(c));
        }
        let mut workspace = crate::contact::Bounds {
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
        };
        for b in bundles {
            let o = crate::contact::Bounds::of(&b.nodes, &b.surface);
            for k in 0..3 {
                workspace.min[k] = workspace.min[k].min(o.min[k] - WORKSPACE_MARGIN_M);
                workspace.max[k] = workspace.max[k].max(o.max[k] + WORKSPACE_MARGIN_M);
            }
        }
        Ok(Self {
            effects,
            max_force_n: probe.map_or(GLOBAL_FORCE_LIMIT_N, |p| p.1).clamp(0.0, GLOBAL_FORCE_LIMIT_N),
            scalpel_max_force_n: scene
                .spec
                .scalpel_max_force()
                .map_or(GLOBAL_FORCE_LIMIT_N, |f| f.clamp(0.0, GLOBAL_FORCE_LIMIT_N)),
            workspace,
            probe: probe.is_some(),
            blade_length_m: scalpel.filter(|_| fx.cutting).map(|s| s.0),
            cut_status,
            grasper_max_force_n: grasper.filter(|_| fx.tearing).map(|g| g.1.clamp(0.0, GLOBAL_FORCE_LIMIT_N)),
            tear_pictures,
            tear_offline,
            grasp_sites,
            corotational,
            fidelity: Fidelity::Full,
            tools: scene.spec.tools.len().max(1),
            tool_limits: scene.spec.tools.iter().map(tool_limit).collect(),
        })
    }

    /// Runs the next ticks at `fidelity` ([`Fidelity`]): every effect switches to its cheaper
    /// setting or back, and the ticks at [`Fidelity::Reduced`] carry
    /// [`Events::REDUCED_FIDELITY`]. No allocation: the tick thread calls it.
    pub fn set_fidelity(&mut self, fidelity: Fidelity) {
        if fidelity != self.fidelity {
            self.fidelity = fidelity;
            for e in &mut self.effects {
                e.set_fidelity(fidelity);
            }
        }
    }

    /// Makes every effect's work beside the tick land at ticks fixed by the tool's path
    /// alone, the tick waiting for it ([`Effect::set_deterministic`]): what a headless run
    /// needs to give the same recording on any load. Call before the first tick.
    pub fn set_deterministic(&mut self, deterministic: bool) {
        for e in &mut self.effects {
            e.set_deterministic(deterministic);
        }
    }

    /// The fidelity the effects run at.
    pub fn fidelity(&self) -> Fidelity {
        self.fidelity
    }

    /// The co-rotational deformation the frame thread advances (co-rotational cutting,
    /// `fidelity.cutting = "corotational_xfem"`; `None` once taken).
    pub fn take_corotational(&mut self) -> Option<corotational::CorotationalDeformation> {
        self.corotational.take()
    }

    /// Where the grasper takes hold and which way it pulls (tearing scenes; empty
    /// otherwise): the scene's grasp first.
    pub fn grasp_sites(&self) -> &[GraspSite] {
        &self.grasp_sites
    }

    /// The frame thread's end of the tearing pictures (tearing scenes; `None` once taken).
    pub fn take_tear_pictures(&mut self) -> Option<TearPictures> {
        self.tear_pictures.take()
    }

    /// The tearing organ's offline data (tearing scenes), one per grasp site, to rebuild
    /// displacements from a [`TearPicture`] (its `site`).
    pub fn tear_offline(&self) -> &[Arc<crate::damage::online::TearOffline>] {
        &self.tear_offline
    }

    /// What the cut thread has done so far (cutting scenes).
    pub fn cut_status(&self) -> Option<Arc<cutting::CutStatus>> {
        self.cut_status.clone()
    }

    /// Names of the effects, in tick order.
    pub fn effect_names(&self) -> Vec<&'static str> {
        self.effects.iter().map(|e| e.name()).collect()
    }

    /// Bytes each effect holds for this session ([`Effect::memory_bytes`]), in tick order.
    pub fn memory_bytes(&self) -> Vec<(&'static str, usize)> {
        self.effects.iter().map(|e| (e.name(), e.memory_bytes())).collect()
    }

    /// The tool kinds this pipeline simulates (a palpation scene: the probe; a cutting
    /// scene: the scalpel, and the probe if it has one).
    pub fn accepts(&self, kind: ToolKind) -> bool {
        match kind {
            ToolKind::Probe => self.probe,
            ToolKind::Scalpel => self.blade_length_m.is_some(),
            ToolKind::Grasper => self.grasper_max_force_n.is_some(),
            ToolKind::Other => false,
        }
    }

    /// Whether a scalpel state's blade is one: finite, of positive length at most
    /// [`MAX_BLADE_EDGE`] blade lengths, its orientation giving a plane through its edge.
    fn blade_ok(&self, tool: &ToolInput) -> bool {
        let Some(len) = self.blade_length_m else { return false };
        let edge = (0..3)
            .map(|k| (tool.blade_end_m[k] - tool.position_m[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        edge <= MAX_BLADE_EDGE * len && crate::xfem::blade::Blade::new(tool.position_m, tool.blade_end_m, tool.orientation).is_ok()
    }

    /// Where tool positions are accepted (the organs' box grown by [`WORKSPACE_MARGIN_M`]).
    pub fn workspace(&self) -> crate::contact::Bounds {
        self.workspace
    }

    /// The largest force magnitude a probe tick returns (N): the probe's `max_force` (a
    /// scalpel's: the global limit).
    pub fn max_force_n(&self) -> f64 {
        self.max_force_n
    }

    /// Forgets every effect's tick-to-tick state (the contact proxy).
    pub fn reset(&mut self) {
        for e in &mut self.effects {
            e.reset();
        }
    }

    /// Whether the tick can take `tool`: a valid state ([`ToolInput::is_valid`]) of a kind
    /// the scene simulates, of one of its tools, inside [`Pipeline::workspace`], and for a
    /// scalpel a blade that is one (see [`Pipeline::tick`]).
    fn takes(&self, tool: &ToolInput) -> bool {
        tool.is_valid()
            && self.accepts(tool.kind)
            && tool.tool < self.tools
            && self.workspace.contains(tool.position_m, 0.0)
            && (tool.kind != ToolKind::Scalpel || self.blade_ok(tool))
    }

    /// One tick of one tool: every effect in order. A non-finite or out-of-range tool state (see
    /// [`ToolInput::is_valid`]; a position outside [`Pipeline::workspace`]), a tool kind
    /// the scene does not simulate or a tool index past the scene's tools gives zero force and
    /// the `REJECTED_INPUT` event, and
    /// no effect sees it (the contact carried from the last tick is kept). A force larger
    /// than the tool's `max_force` (probe or scalpel) is scaled down to it (direction kept) and flagged
    /// `FORCE_SATURATED`; a non-finite one becomes zero. A scalpel state whose blade is not
    /// one (zero length, longer than [`MAX_BLADE_EDGE`] blade lengths, no plane) is rejected
    /// the same way.
    pub fn tick(&mut self, tool: &ToolInput) -> TickState {
        let mut state = [TickState::default()];
        self.tick_tools(std::slice::from_ref(tool), &mut state);
        state[0]
    }

    /// One tick of several tools at once (two hands): `states[i]` answers `tools[i]`. Each
    /// tool is checked as [`Pipeline::tick`] checks one (a rejected state gets zero force and
    /// `REJECTED_INPUT`, and the others go on); the effects then see every accepted tool
    /// together, so the contacts of tools pressing one organ are solved together
    /// ([`Palpation`]): pressing with one moves the tissue under the other. Each force is
    /// limited by its own tool's `max_force`. At most [`MAX_TOOLS`] tools, each index once
    /// (a second state of the same tool in one tick is rejected). Allocates nothing.
    pub fn tick_tools(&mut self, tools: &[ToolInput], states: &mut [TickState]) {
        assert_eq!(tools.len(), states.len(), "one state per tool");
        let mut taken = [ToolInput::default(); MAX_TOOLS];
        let mut answers = [TickState::default(); MAX_TOOLS];
        let mut origin = [0usize; MAX_TOOLS];
        let mut n = 0;
        for (i, tool) in tools.iter().enumerate() {
            states[i] = TickState::default();
            let repeated = taken[..n].iter().any(|t| t.tool == tool.tool);
            if n == MAX_TOOLS || repeated || !self.takes(tool) {
                states[i].events.0 |= Events::REJECTED_INPUT;
                continue;
            }
            taken[n] = *tool;
            answers[n].tool_m = Some(tool.position_m);
            origin[n] = i;
            n += 1;
        }
        if n == 0 {
            return;
        }
        for e in &mut self.effects {
            e.tick_tools(&taken[..n], &mut answers[..n]);
        }
        for (j, mut state) in answers[..n].iter().copied().enumerate() {
            self.finish(&taken[j], &mut state);
            states[origin[j]] = state;
        }
    }

    /// The force limit of `tool` (N): its own `max_force` where the scene names it at its
    /// index with its kind, else the limit of the first tool of its kind.
    fn limit(&self, tool: &ToolInput) -> f64 {
        if let Some(&(kind, limit)) = self.tool_limits.get(tool.tool)
            && kind == tool.kind
        {
            return limit;
        }
        match tool.kind {
            ToolKind::Scalpel => self.scalpel_max_force_n,
            ToolKind::Grasper => self.grasper_max_force_n.unwrap_or(self.max_force_n),
            _ => self.max_force_n,
        }
    }

    /// The end of one tool's tick: the fidelity event, a non-finite force to zero, the force
    /// limited to the tool's ([`Pipeline::tick`]).
    fn finish(&self, tool: &ToolInput, state: &mut TickState) {
        if self.fidelity == Fidelity::Reduced {
            state.events.0 |= Events::REDUCED_FIDELITY;
        }
        if !state.force_n.iter().all(|v| v.is_finite()) {
            state.force_n = [0.0; 3];
        }
        let norm = state.force_n.iter().map(|x| x * x).sum::<f64>().sqrt();
        let limit = self.limit(tool);
        if norm > limit {
            let scale = limit / norm;
            state.force_n = state.force_n.map(|x| x * scale);
            if let Some(c) = &mut state.contact {
                c.tissue_force_n = c.tissue_force_n.map(|x| x * scale);
            }
            if let Some(b) = &mut state.blade {
                b.perpendicular_n = b.perpendicular_n.map(|x| x * scale);
                b.parallel_n = b.parallel_n.map(|x| x * scale);
            }
            state.events.0 |= Events::FORCE_SATURATED;
        }
    }
}

/// Each tool's contact radius (m), by its index in the scene: a probe's own tip radius, a
/// scalpel's tip ([`SCALPEL_TIP_FRACTION`] of its blade), whatever other tools the scene names
/// (a grasper does not palpate) `radius`. One entry for a scene without tools. Each tool
/// touches with its own tip whatever other tools the scene has: what `SessionInfo` tells
/// clients.
fn tip_radii(tools: &[ToolSpec], radius: f64) -> Vec<f64> {
    let radii: Vec<f64> = tools
        .iter()
        .take(MAX_TOOLS)
        .map(|t| match t {
            ToolSpec::Probe { radius, .. } => *radius,
            ToolSpec::Scalpel { blade_length, .. } => SCALPEL_TIP_FRACTION * blade_length,
            ToolSpec::Grasper { .. } => radius,
        })
        .collect();
    if radii.is_empty() { vec![radius] } else { radii }
}

/// A scene tool's kind and force limit (N), at most [`GLOBAL_FORCE_LIMIT_N`].
fn tool_limit(t: &ToolSpec) -> (ToolKind, f64) {
    let (kind, limit) = match t {
        ToolSpec::Probe { max_force, .. } => (ToolKind::Probe, *max_force),
        ToolSpec::Scalpel { max_force, .. } => (ToolKind::Scalpel, *max_force),
        ToolSpec::Grasper { max_force, .. } => (ToolKind::Grasper, *max_force),
    };
    (kind, limit.clamp(0.0, GLOBAL_FORCE_LIMIT_N))
}

/// The tearing effect of `scene`'s tearable organ: its model from the scene, the offline
/// arrays of every grasp site from its bundle (checked against the model), the scene's
/// variant and limits.
fn tearing_effect(
    scene: &Scene,
    bundles: &[Arc<LoadedBundle>],
    jaw_width: f64,
    max_force: f64,
) -> Result<(Tearing, TearPictures, Vec<Arc<crate::damage::online::TearOffline>>), PipelineError> {
    use crate::damage::online::TearOffline;
    use crate::scene::tearing;
    let Some(i) = tearing::tearable_organ(scene) else {
        return Err(PipelineError::Tearing {
            organ: 0,
            message: "no organ has a material with damage".into(),
        });
    };
    let fail = |message: String| PipelineError::Tearing { organ: i, message };
    if bundles[i].tear.is_empty() {
        return Err(fail(
            "its bundle holds no tearing vademecum (built before tearing existed, or for another scene); rebuild it with `vademecum build`"
                .into(),
        ));
    }
    let (model, _) = tearing::tear_model(scene, i).map_err(|e| fail(e.to_string()))?;
    let offs = bundles[i]
        .tear
        .iter()
        .enumerate()
        .map(|(k, arrays)| {
            TearOffline::from_arrays(model.clone(), (**arrays).clone())
                .map(Arc::new)
                .map_err(|e| fail(if k == 0 { e } else { format!("grasp site {k}: {e}") }))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let (_, limits) = tearing::settings(scene);
    let variant = scene.spec.fidelity.tearing.variant;
    let (t, pictures) = Tearing::new(i, offs.clone(), variant, limits, jaw_width, max_force).map_err(|e| fail(e.to_string()))?;
    Ok((t, pictures, offs))
}

/// Why a cutting session's reduced model could not be made ([`session_cut_model`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CutModelError {
    /// The bundle's mesh is not the scene's.
    #[error("the bundle was built for another mesh than the scene's; rebuild it with `vademecum build`")]
    OtherMesh,
    /// The bundle's build report holds a value the session cannot take.
    #[error(transparent)]
    Info(#[from] crate::bundle::InfoError),
    /// The reduced cut model could not be made.
    #[error(transparent)]
    Reduced(#[from] crate::xfem::reduced::ReducedError),
}

/// The reduced cut model a cutting session of organ 0 (`model`, the scene's organ model)
/// starts from, with the XFEM settings it cuts with: the scene's `fidelity.xfem` at the sliver
/// rule the bundle chose, the bare enrichment on the basis the bundle stores, keeping the
/// contact table of the vademecum's loadable nodes
/// ([`crate::xfem::reduced::ReducedCut::tabulate`]). Shared by the session and
/// `vademecum study`'s check of the per-answer estimate.
pub fn session_cut_model(
    scene: &Scene,
    model: &crate::fem::OrganModel,
    bundle: &LoadedBundle,
) -> Result<(crate::xfem::reduced::ReducedCut, crate::xfem::XfemParams), CutModelError> {
    let same = model.mesh.nodes.len() == bundle.nodes.len()
        && model.mesh.nodes.iter().zip(&bundle.nodes).all(|(p, q)| {
            let tol = 1e-9 * (1.0 + p.iter().chain(q).fold(0.0f64, |m, v| m.max(v.abs())));
            (0..3).all(|k| (p[k] - q[k]).abs() <= tol)
        });
    if !same {
        return Err(CutModelError::OtherMesh);
    }
    cut_model(scene, model, &bundle.vademecum, bundle.cut_basis.as_ref(), bundle.cut_sliver()?)
}

/// The XFEM settings a session of `scene` cuts with: the scene's `fidelity.xfem` at the sliver
/// rule `sliver` the build chose for a target (`None`: the scene's).
pub fn cut_params(scene: &Scene, sliver: Option<f64>) -> crate::xfem::XfemParams {
    let fx = &scene.spec.fidelity.xfem;
    crate::xfem::XfemParams {
        sliver: sliver.unwrap_or(fx.sliver),
        ..fx.params()
    }
}

/// [`session_cut_model`] from the parts of a bundle: the vademecum `v` of `model`, the Ritz
/// basis the build stored for the bare enrichment, the sliver rule it chose (`None`: the
/// scene's). What `vademecum build --target-tick-us` times before writing the bundle.
pub fn cut_model(
    scene: &Scene,
    model: &crate::fem::OrganModel,
    v: &crate::pgd::Vademecum,
    cut_basis: Option<&crate::bundle::CutBasis>,
    sliver: Option<f64>,
) -> Result<(crate::xfem::reduced::ReducedCut, crate::xfem::XfemParams), CutModelError> {
    use crate::xfem::reduced::{Discontinuous, ReducedCut};
    let fx = &scene.spec.fidelity.xfem;
    let params = cut_params(scene, sliver);
    let stored = cut_basis.filter(|b| b.basis == fx.basis);
    let mut reduced = match (fx.discontinuous, stored) {
        // the basis the build stored (bundle version 2)
        (Discontinuous::Bare, Some(b)) => ReducedCut::from_basis(
            &model.mesh,
            &model.materials,
            model.locking,
            &model.problem,
            b.basis,
            b.x.clone(), // shared, not copied
            b.size,
            Discontinuous::Bare,
            &params,
        ),
        (disc, _) => {
            // with local fields the tick adds the cut's compliance to the vademecum's own,
            // and the Ritz basis is not needed (ReducedCut::new); bare without a stored basis
            // (a version 1 bundle) computes it now
            let n_modes = match disc {
                Discontinuous::LocalFields => 0,
                Discontinuous::Bare => {
                    tracing::warn!(
                        "the bundle holds no Ritz basis for bare enrichment (built before bundle version 2): computing it now, which takes minutes for thousands of modes; rebuild the bundle to store it"
                    );
                    v.modes()
                }
            };
            ReducedCut::new(
                &model.mesh,
                &model.materials,
                model.locking,
                &model.problem,
                &v.f_raw()[..n_modes * 3 * model.mesh.n_nodes()],
                n_modes,
                fx.basis,
                disc,
                &params,
            )
        }
    }?;
    // the compliance at a contact in O(m) for every node the vademecum can load
    reduced.tabulate(v.load_nodes());
    Ok((reduced, params))
}

/// The cutting effect of organ `organ` of `scene`, its cut organ ([`Scene::cut_organ`];
/// module [`cutting`]): its mesh and model from the scene, checked against the bundle, the
/// reduced model on the bundle's modes; with co-rotational cutting, also the co-rotational
/// deformation coupled to it ([`corotational`]).
fn cutting_effect(
    scene: &Scene,
    organ: usize,
    bundle: &Arc<LoadedBundle>,
    cut_force: f64,
) -> Result<(Cutting, Option<corotational::CorotationalDeformation>), PipelineError> {
    use crate::xfem::online::OnlineCut;
    use crate::xfem::reduced::Discontinuous;
    let fail = |message: String| PipelineError::Cutting { organ, message };
    let model = scene.organ_model(organ).map_err(|e| fail(e.to_string()))?;
    let fx = &scene.spec.fidelity.xfem;
    let (reduced, params) = session_cut_model(scene, &model, bundle).map_err(|e| fail(e.to_string()))?;
    let online = OnlineCut::new(&model.mesh, reduced, cut_force, &params).map_err(|e| fail(e.to_string()))?;
    let bare_error = match fx.discontinuous {
        Discontinuous::Bare => bundle.cut_bare_force_error().map_err(|e| fail(e.to_string()))?,
        Discontinuous::LocalFields => None,
    };
    if scene.spec.fidelity.cutting != crate::scene::schema::CuttingModel::CorotationalXfem {
        return Ok((
            Cutting::new(organ, bundle.clone(), model.mesh, online, cut_force).with_bare_error(bare_error),
            None,
        ));
    }
    let visual = scene.organ_visual(organ).map_err(|e| fail(e.to_string()))?;
    let (deformation, corrections) =
        corotational::CorotationalDeformation::new(organ, model.mesh.clone(), model.materials, model.problem, visual)
            .map_err(|e| fail(e.to_string()))?;
    let cutting = Cutting::new(organ, bundle.clone(), model.mesh, online, cut_force)
        .with_bare_error(bare_error)
        .with_corrections(corrections);
    Ok((cutting, Some(deformation)))
}
