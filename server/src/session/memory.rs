//! What a session holds in memory of its own, by part: its effects' state, its queues, its
//! statistics' histograms, its frames. The loaded bundles (modes, lattices, tearing
//! vademecums, the surface modes frames evaluate) are shared by every session of a bundle and
//! belong to the bundle, not to a session. Figures are the buffers' capacities
//! ([`vademecum_engine::memory`]); `vademecum bench load` sets them beside the server's RSS.

use serde::Serialize;

use super::frames::{Frame, SurfaceGeometry};
use super::tick::Latest;
use super::{Answer, Command, StreamId};

/// A session's memory by part (bytes).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SessionMemory {
    /// `(part, bytes)`: `effect:<name>` per effect of the pipeline, then `queues`,
    /// `histograms`, `frames`.
    pub parts: Vec<(String, u64)>,
}

impl SessionMemory {
    /// All parts together.
    pub fn total(&self) -> u64 {
        self.parts.iter().map(|p| p.1).sum()
    }

    /// The parts of a session with these effects (`(name, bytes)`), a command queue of
    /// `queue` states, an answer ring of `ring` answers, histograms of `histograms` bytes
    /// ([`super::TickStats::histogram_bytes`]), and frames of `geometry`.
    pub(super) fn of(effects: &[(&'static str, usize)], queue: usize, ring: usize, histograms: usize, geometry: &SurfaceGeometry) -> Self {
        let mut parts: Vec<(String, u64)> = effects.iter().map(|(n, b)| (format!("effect:{n}"), *b as u64)).collect();
        // the command channel's slots, the answer ring's (each with its stamp), the triple
        // buffer of the latest state
        let queues = queue * std::mem::size_of::<Command>()
            + ring * (std::mem::size_of::<(StreamId, Answer)>() + std::mem::size_of::<usize>())
            + 3 * std::mem::size_of::<Latest>();
        parts.push(("queues".into(), queues as u64));
        parts.push(("histograms".into(), histograms as u64));
        // the surface geometry, the frame published and the one being made
        let surface: usize = geometry
            .organs
            .iter()
            .map(|o| {
                std::mem::size_of_val(&o.nodes[..])
                    + std::mem::size_of_val(&o.positions_m[..])
                    + std::mem::size_of_val(&o.triangles[..])
                    + o.accessible.len()
            })
            .sum();
        let frame = std::mem::size_of::<Frame>() + geometry.organs.iter().map(|o| 4 * o.positions_m.len()).sum::<usize>();
        parts.push(("frames".into(), (surface + 2 * frame) as u64));
        Self { parts }
    }

    /// Replaces the bytes of `part` (a part that grows as the session runs: a cut).
    pub(super) fn set(&mut self, part: &str, bytes: u64) {
        if let Some(p) = self.parts.iter_mut().find(|p| p.0 == part) {
            p.1 = bytes;
        }
    }
}
