//! Server errors and their single mapping to gRPC status codes.

use tonic::{Code, Status};

/// Why a request failed.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// The request is malformed or fails validation.
    #[error("{0}")]
    Invalid(String),
    /// No such session for this caller (the id as the client sent it; shown clipped).
    #[error("no session '{}' for this client", clip(.0))]
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
    /// The server takes no new session now (it is draining).
    #[error("{0}")]
    Unavailable(String),
    /// Something failed on the server's side.
    #[error("{0}")]
    Internal(String),
}

/// Most characters of client input echoed back in an error message.
pub const ECHO_CHARS: usize = 64;

/// `text` as it may be echoed to a client: at most [`ECHO_CHARS`] characters, control
/// characters replaced, and the full length said when clipped — client input is never
/// echoed unbounded (a status message travels in a size-limited HTTP/2 header).
pub fn clip(text: &str) -> String {
    let mut out: String = text
        .chars()
        .take(ECHO_CHARS)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    if text.chars().count() > ECHO_CHARS {
        out.push_str(&format!("… ({} bytes)", text.len()));
    }
    out
}

/// A message for a status: clipped to 1,024 characters (error texts from scene and mesh
/// readers can quote client input at length).
fn bounded(message: String) -> String {
    const MAX: usize = 1024;
    if message.chars().count() <= MAX {
        return message;
    }
    let mut m: String = message.chars().take(MAX).collect();
    m.push_str(&format!("… ({} bytes in all)", message.len()));
    m
}

impl From<ServerError> for Status {
    fn from(e: ServerError) -> Self {
        let code = match &e {
            ServerError::Invalid(_) => Code::InvalidArgument,
            ServerError::UnknownSession(_) | ServerError::NotFound(_) => Code::NotFound,
            ServerError::Precondition(_) => Code::FailedPrecondition,
            ServerError::Exhausted(_) => Code::ResourceExhausted,
            ServerError::Denied(_) => Code::PermissionDenied,
            ServerError::Unavailable(_) => Code::Unavailable,
            ServerError::Internal(_) => Code::Internal,
        };
        Status::new(code, bounded(e.to_string()))
    }
}
