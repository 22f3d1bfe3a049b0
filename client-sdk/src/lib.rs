//! Async Rust client for vademecum servers.
//!
//! For now it wraps the `Info` service; sessions, interaction and frame subscription join it
//! with the server's session contract.
#![warn(missing_docs)]

use vademecum_proto::v1::{GetServerInfoRequest, ServerInfo, info_client::InfoClient};

/// Errors returned by the client.
#[derive(Debug, thiserror::Error)]
pub enum SdkError {
    /// The server address could not be parsed or reached.
    #[error("cannot connect to {addr}: {source}")]
    Connect {
        /// The address that was tried.
        addr: String,
        /// The transport error.
        source: tonic::transport::Error,
    },
    /// The server answered with an error status.
    #[error("server answered {}: {}", .0.code(), .0.message())]
    Status(#[from] tonic::Status),
}

/// A connection to a vademecum server.
#[derive(Debug, Clone)]
pub struct Client {
    info: InfoClient<tonic::transport::Channel>,
}

impl Client {
    /// Connects to `addr` (for example `http://127.0.0.1:50051`).
    pub async fn connect(addr: impl Into<String>) -> Result<Self, SdkError> {
        let addr = addr.into();
        let info = InfoClient::connect(addr.clone())
            .await
            .map_err(|source| SdkError::Connect { addr, source })?;
        Ok(Self { info })
    }

    /// Asks the server for its version and capabilities.
    pub async fn server_info(&mut self) -> Result<ServerInfo, SdkError> {
        Ok(self.info.get_server_info(GetServerInfoRequest {}).await?.into_inner())
    }
}
