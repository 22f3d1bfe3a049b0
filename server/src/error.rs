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

/// `message` as a client may read it: every quoted span (`…`, "…", '…': where readers quote
/// what they were given, a key, a value, a line) clipped to [`ECHO_CHARS`] characters as
/// [`clip`] does, and every absolute path on the server shown by its last component only
/// (`…/name`): a status never reveals the server's folders, nor echoes input unbounded.
pub fn for_client(message: &str) -> String {
    let chars: Vec<char> = message.chars().collect();
    let mut out = String::with_capacity(message.len().min(2048));
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let starts_word = i == 0 || matches!(chars[i - 1], ' ' | '(' | '[' | '=' | '\n' | '\t' | ',');
        if matches!(c, '`' | '"' | '\'') && (c != '\'' || starts_word) {
            // a quoted span: up to its closing quote on the same line
            if let Some(len) = chars[i + 1..].iter().take_while(|&&d| d != '\n').position(|&d| d == c) {
                let inner: String = chars[i + 1..i + 1 + len].iter().collect();
                out.push(c);
                out.push_str(&redact_paths(&clip(&inner)));
                out.push(c);
                i += len + 2;
                continue;
            }
        }
        if c == '/' && starts_word && chars.get(i + 1) != Some(&'/') {
            // an absolute path: up to the next blank or quote
            let len = chars[i..]
                .iter()
                .take_while(|d| !d.is_whitespace() && !matches!(d, '`' | '"' | '\'' | ')' | ']' | ','))
                .count();
            let path: String = chars[i..i + len].iter().collect();
            out.push_str(&redact_paths(&path));
            i += len;
            continue;
        }
        out.push(c);
        i += 1;
    }
    out
}

/// `text` with every absolute path in it (a token starting with `/` that names a folder
/// below the root) shown as `…/` and its last component.
fn redact_paths(text: &str) -> String {
    text.split(' ')
        .map(|t| {
            let trimmed = t.trim_end_matches([':', '.', ';']);
            match trimmed
                .strip_prefix('/')
                .filter(|r| !r.starts_with('/'))
                .and_then(|rest| rest.rsplit_once('/'))
            {
                Some((_, last)) => format!("…/{last}{}", &t[trimmed.len()..]),
                None => t.to_string(),
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// A message for a status: what a client may read ([`for_client`]), clipped to 1,024
/// characters.
fn bounded(message: String) -> String {
    let message = for_client(&message);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quoted_input_is_clipped_and_server_paths_are_hidden() {
        let key = "k".repeat(1000);
        let m = for_client(&format!("unknown field `{key}`, expected one of `a`, `b`"));
        assert!(m.len() < 200, "{m}");
        assert!(
            m.starts_with(&format!("unknown field `{}… (1000 bytes)`", "k".repeat(ECHO_CHARS))),
            "{m}"
        );
        assert!(m.ends_with("expected one of `a`, `b`"), "{m}");
        let m = for_client("cannot read mesh /srv/lab/meshes/liver.msh: No such file (os error 2)");
        assert_eq!(m, "cannot read mesh …/liver.msh: No such file (os error 2)");
        let m = for_client("cannot create \"/var/lib/vademecum/store/sha256\": Permission denied");
        assert_eq!(m, "cannot create \"…/sha256\": Permission denied");
        // what is no path stays: relative paths, URLs, ratios, apostrophes
        for plain in [
            "organ 'lobe': bundle organ/lobe.bundle is stale",
            "GET http://127.0.0.1:8000/sha256/ab/F.npy: 404",
            "1/3 N per step; the scene's loads",
        ] {
            assert_eq!(for_client(plain), plain);
        }
    }
}
