//! Server errors and their single mapping to gRPC status codes.

use tonic::{Code, Status};

/// Why a request failed.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// The request is malformed or fails validation.
    #[error("{0}")]
    Invalid(String),
    /// No such session for this caller.
    #[error("no session '{0}' for this client")]
    UnknownSession(String),
    /// A server-side file is missing.
    #[error("{0}")]
    NotFound(String),
    /// A precondition does not hold (missing or stale bundle).
    #[error("{0}")]
    Precondition(String),
    /// A cap is reached.
    #[error("{0}")]
    Exhausted(String),
    /// The caller may not do this.
    #[error("{0}")]
    Denied(String),
    /// Something failed on the server's side.
    #[error("{0}")]
    Internal(String),
}

impl From<ServerError> for Status {
    fn from(e: ServerError) -> Self {
        let code = match &e {
            ServerError::Invalid(_) => Code::InvalidArgument,
            ServerError::UnknownSession(_) | ServerError::NotFound(_) => Code::NotFound,
            ServerError::Precondition(_) => Code::FailedPrecondition,
            ServerError::Exhausted(_) => Code::ResourceExhausted,
            ServerError::Denied(_) => Code::PermissionDenied,
            ServerError::Internal(_) => Code::Internal,
        };
        Status::new(code, e.to_string())
    }
}
