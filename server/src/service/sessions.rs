//! `vademecum.v1.Sessions`: create, list, inspect and close sessions.

use tonic::{Request, Response, Status};
use vademecum_proto::v1 as pb;

use crate::auth::caller;
use crate::convert;
use crate::error::ServerError;
use crate::registry::Registry;

/// The Sessions service.
#[derive(Debug, Clone)]
pub struct SessionsService {
    /// The sessions.
    pub registry: Registry,
}

#[tonic::async_trait]
impl pb::sessions_server::Sessions for SessionsService {
    async fn create_session(&self, req: Request<pb::CreateSessionRequest>) -> Result<Response<pb::SessionInfo>, Status> {
        let owner = caller(&req)?;
        let r = req.into_inner();
        let source = convert::scene_source(&r).map_err(ServerError::Invalid)?;
        let registry = self.registry.clone();
        // reading scenes, meshes and bundles is blocking work: keep it off the runtime
        let entry = tokio::task::spawn_blocking(move || {
            let haptic = r.haptic.then_some(r.haptic_channel.as_str());
            registry.create(owner, source, &r.bundle_dir, r.label, haptic)
        })
        .await
        .map_err(|_| ServerError::Internal("session creation was interrupted".into()))??;
        tracing::info!(session = entry.session.id(), scene = %entry.session.scene().spec.scene.name, "session created");
        Ok(Response::new(convert::session_info(&entry)))
    }

    async fn list_sessions(&self, req: Request<pb::ListSessionsRequest>) -> Result<Response<pb::ListSessionsResponse>, Status> {
        let owner = caller(&req)?;
        let sessions = self.registry.list(&owner).iter().map(|e| convert::session_info(e)).collect();
        Ok(Response::new(pb::ListSessionsResponse { sessions }))
    }

    async fn get_session(&self, req: Request<pb::GetSessionRequest>) -> Result<Response<pb::SessionInfo>, Status> {
        let owner = caller(&req)?;
        let e = self.registry.get(&owner, &req.get_ref().session_id)?;
        Ok(Response::new(convert::session_info(&e)))
    }

    async fn close_session(&self, req: Request<pb::CloseSessionRequest>) -> Result<Response<pb::CloseSessionResponse>, Status> {
        let owner = caller(&req)?;
        let e = self.registry.close(&owner, &req.get_ref().session_id)?;
        tracing::info!(session = e.session.id(), "session closed");
        let stats = convert::session_stats(&e);
        // the last reference to a session may be this one: dropping it waits for the
        // session's last tick, answers and frame, which belongs on a blocking thread, not on
        // a tokio worker that other sessions' streams run on
        tokio::task::spawn_blocking(move || drop(e));
        Ok(Response::new(pb::CloseSessionResponse { stats: Some(stats) }))
    }
}
