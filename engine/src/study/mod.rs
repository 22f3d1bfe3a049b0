//! What accuracy costs: the samples `vademecum study` holds the served answers to. Each
//! effect's answer at contact states drawn over the organ against the full-order model of the
//! same mesh, with the error estimate a session attaches to it ([`estimate`]). Above the
//! pipeline (it replays the effects as a session serves them) and the offline build (it reads
//! the bundles); nothing below imports it.

pub mod estimate;
pub mod large_cut;
