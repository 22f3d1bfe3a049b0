//! Optional bearer-token authentication: an interceptor that checks the `authorization`
//! metadata against the configured tokens and records who the caller is, so a client
//! reaches only its own sessions.

use std::sync::Arc;

use tonic::service::Interceptor;
use tonic::{Request, Status};

/// Who is calling: the token it presented, or "anonymous" when the server has no tokens.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Caller(pub Arc<str>);

/// Checks bearer tokens (or lets everyone in as "anonymous").
#[derive(Debug, Clone)]
pub struct Auth {
    tokens: Option<Arc<[String]>>,
}

impl Auth {
    /// Accepts these tokens (`None`: no authentication).
    pub fn new(tokens: Option<Vec<String>>) -> Self {
        Self {
            tokens: tokens.map(Into::into),
        }
    }
}

impl Interceptor for Auth {
    fn call(&mut self, mut req: Request<()>) -> Result<Request<()>, Status> {
        let caller = match &self.tokens {
            None => Caller(Arc::from("anonymous")),
            Some(tokens) => {
                let header = req.metadata().get("authorization").ok_or_else(|| {
                    Status::unauthenticated("this server requires a bearer token (metadata 'authorization: Bearer <token>')")
                })?;
                let value = header
                    .to_str()
                    .map_err(|_| Status::unauthenticated("the authorization metadata is not text"))?;
                let token = value
                    .strip_prefix("Bearer ")
                    .ok_or_else(|| Status::unauthenticated("the authorization metadata must read 'Bearer <token>'"))?;
                if !tokens.iter().any(|t| constant_time_eq(t.as_bytes(), token.as_bytes())) {
                    return Err(Status::unauthenticated("unknown token"));
                }
                Caller(Arc::from(token))
            }
        };
        req.extensions_mut().insert(caller);
        Ok(req)
    }
}

/// Compares without an early exit on the first differing byte.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The caller recorded by [`Auth`] (requests that did not pass it are refused).
pub fn caller<T>(req: &Request<T>) -> Result<Caller, Status> {
    req.extensions()
        .get::<Caller>()
        .cloned()
        .ok_or_else(|| Status::unauthenticated("request did not pass authentication"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_are_checked_and_the_caller_recorded() {
        let mut open = Auth::new(None);
        let r = open.call(Request::new(())).unwrap();
        assert_eq!(&*caller(&r).unwrap().0, "anonymous");
        let mut auth = Auth::new(Some(vec!["s3cret".into()]));
        assert_eq!(auth.call(Request::new(())).unwrap_err().code(), tonic::Code::Unauthenticated);
        let mut bad = Request::new(());
        bad.metadata_mut().insert("authorization", "Bearer nope".parse().unwrap());
        assert_eq!(auth.call(bad).unwrap_err().code(), tonic::Code::Unauthenticated);
        let mut good = Request::new(());
        good.metadata_mut().insert("authorization", "Bearer s3cret".parse().unwrap());
        let r = auth.call(good).unwrap();
        assert_eq!(&*caller(&r).unwrap().0, "s3cret");
    }
}
