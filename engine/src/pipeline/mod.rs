//! One simulation tick: tool state in → contact → each effect the scene names, in a fixed
//! order → force out (see `DESIGN.md`, "The data path").
//!
//! A [`Pipeline`] is assembled once per session from the scene's `[effects]` and the loaded
//! vademecums; each [`Effect`] owns its state and its preallocated workspace, so a tick
//! allocates nothing, and a scene that names only palpation carries no cutting state, no
//! damage arrays and does no extra work per tick. Large deformations scale the palpation
//! force by the organ's ANM-POD lattice; later effects (cutting, tearing) implement [`Effect`]
//! and are added in [`Pipeline::for_scene`] without touching the others.
//!
//! # Layout
//! - [`Effect`], [`ToolInput`], [`TickState`], [`Events`]: the contract between the tick
//!   driver (the server's tick thread) and the effects.
//! - [`palpation`]: the linear PGD deformation effect (contact of a spherical tip with the
//!   accessible surface, force `f = C(s)⁻¹δ` from the vademecum).

pub mod palpation;

use std::sync::Arc;

use crate::pgd::offline::LoadedBundle;
use crate::scene::Scene;
use crate::scene::schema::{DeformationModel, ToolSpec};

pub use palpation::Palpation;

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
}

/// What the tick reads from the tool (SI units).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ToolInput {
    /// Tool kind.
    pub kind: ToolKind,
    /// Tip position in the organ's reference frame (m).
    pub position_m: [f64; 3],
    /// Tip velocity (m/s), for effects that depend on it.
    pub velocity_m_s: [f64; 3],
    /// Blade engagement or jaw closure, 0 (open) to 1 (closed).
    pub closure: f64,
}

impl ToolInput {
    /// Whether every field is finite and the closure lies in [0, 1].
    pub fn is_valid(&self) -> bool {
        self.position_m.iter().chain(&self.velocity_m_s).all(|v| v.is_finite()) && (0.0..=1.0).contains(&self.closure)
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
    /// Tissue tore (tearing effect).
    pub const TISSUE_TORN: u32 = 8;

    /// Whether flag `f` is set.
    pub fn has(self, f: u32) -> bool {
        self.0 & f != 0
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
    /// Contact point on the reference surface (m).
    pub point_m: [f64; 3],
    /// Penetration depth (m, positive).
    pub depth_m: f64,
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
}

/// A simulated effect: one stage of the tick.
pub trait Effect: Send {
    /// Short name (`"palpation"`, …) for logs and metrics.
    fn name(&self) -> &'static str;
    /// Advances the effect by one tick for tool input `tool`, reading and updating `state`.
    /// Must not allocate, block or log.
    fn tick(&mut self, tool: &ToolInput, state: &mut TickState);
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
}

/// The effects of a session, in tick order.
pub struct Pipeline {
    effects: Vec<Box<dyn Effect>>,
}

impl std::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.effects.iter().map(|e| e.name())).finish()
    }
}

impl Pipeline {
    /// Assembles the effects `scene` names, over its organs' loaded bundles (one per organ,
    /// in scene order, shared read-only between sessions).
    pub fn for_scene(scene: &Scene, bundles: &[Arc<LoadedBundle>]) -> Result<Self, PipelineError> {
        let fx = &scene.spec.effects;
        if fx.cutting {
            return Err(PipelineError::Unsupported("cutting (effects.cutting = true)"));
        }
        if fx.tearing {
            return Err(PipelineError::Unsupported("tearing (effects.tearing = true)"));
        }
        if bundles.len() != scene.spec.organs.len() {
            return Err(PipelineError::BundleCount {
                organs: scene.spec.organs.len(),
                bundles: bundles.len(),
            });
        }
        let radius = scene
            .spec
            .tools
            .iter()
            .find_map(|t| match t {
                ToolSpec::Probe { radius, .. } => Some(*radius),
                _ => None,
            })
            .ok_or(PipelineError::NoProbe)?;
        let large = fx.deformation == DeformationModel::Large;
        if large && let Some(i) = bundles.iter().position(|b| b.anm.is_none()) {
            return Err(PipelineError::NoLattice { organ: i });
        }
        let effects: Vec<Box<dyn Effect>> = vec![Box::new(Palpation::new(bundles.to_vec(), radius, large))];
        Ok(Self { effects })
    }

    /// Names of the effects, in tick order.
    pub fn effect_names(&self) -> Vec<&'static str> {
        self.effects.iter().map(|e| e.name()).collect()
    }

    /// One tick: every effect in order. A non-finite or out-of-range tool state gives zero
    /// force and the `REJECTED_INPUT` event, and no effect sees it.
    pub fn tick(&mut self, tool: &ToolInput) -> TickState {
        let mut state = TickState::default();
        if !tool.is_valid() {
            state.events.0 |= Events::REJECTED_INPUT;
            return state;
        }
        for e in &mut self.effects {
            e.tick(tool, &mut state);
        }
        if !state.force_n.iter().all(|v| v.is_finite()) {
            state.force_n = [0.0; 3];
        }
        state
    }
}
