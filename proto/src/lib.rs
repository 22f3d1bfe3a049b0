//! Wire contracts of vademecum: the gRPC services generated from `proto/vademecum/**.proto`.
//!
//! # Layout
//! - [`v1`]: the `vademecum.v1` package: `Info` (server identity), `Sessions` (create, list,
//!   inspect, close), `Interaction` (bidirectional stream: tool states in, forces out) and
//!   `Viewing` (server stream of displacement frames).
//! - [`agones`]: the Agones SDK sidecar's contract, which `serve --agones` is a client of.
//! - [`shm`]: the `#[repr(C)]` samples of the 1 kHz haptic path over iceoryx2 shared memory
//!   (device bridge ⇄ session tick thread) and the services they travel on.
//!
//! Apart from opening the shared-memory services with one set of settings, this crate contains no logic: conversions to and from engine types live at the edges
//! (`server/src/convert.rs`, the client SDK).
#![warn(missing_docs)]

/// The `vademecum.v1` protobuf package.
#[allow(missing_docs, clippy::all)]
pub mod v1 {
    tonic::include_proto!("vademecum.v1");
}

pub mod shm;

/// The Agones SDK sidecar's gRPC contract (`proto/agones/`, from Agones 1.61, Apache-2.0):
/// what `vademecum serve --agones` calls to be a GameServer of a Fleet.
#[allow(missing_docs, clippy::all)]
pub mod agones {
    /// `agones.dev.sdk`: Ready, Allocate, Shutdown, Health, the GameServer.
    pub mod sdk {
        tonic::include_proto!("agones.dev.sdk");
    }
    /// `agones.dev.sdk.beta`: the Counters.
    pub mod beta {
        tonic::include_proto!("agones.dev.sdk.beta");
    }
}

/// The encoded file descriptor set of every `.proto` here, for gRPC server reflection.
pub const FILE_DESCRIPTOR_SET: &[u8] = tonic::include_file_descriptor_set!("vademecum_descriptor");

/// Name of the wire contract implemented by this crate.
pub const CONTRACT: &str = "vademecum.v1";
