//! Wire contracts of vademecum: the gRPC services generated from `proto/vademecum/**.proto`.
//!
//! # Layout
//! - [`v1`]: the `vademecum.v1` package (server information for now; sessions, interaction and
//!   viewing services join it as the server grows).
//!
//! This crate contains no logic: conversions to and from engine types live at the edges
//! (`server/src/convert.rs`, the client SDK).
#![warn(missing_docs)]

/// The `vademecum.v1` protobuf package.
#[allow(missing_docs, clippy::all)]
pub mod v1 {
    tonic::include_proto!("vademecum.v1");
}

/// Name of the wire contract implemented by this crate.
pub const CONTRACT: &str = "vademecum.v1";
