//! The gRPC services, one thin file each: validate and convert (`convert.rs`), call the
//! registry or the session, map errors (`error.rs`).

pub mod fleet;
pub mod info;
pub mod interaction;
pub mod sessions;
pub mod viewing;
