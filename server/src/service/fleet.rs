//! `vademecum.v1.Fleet`: this server's load report, and draining.

use tonic::{Request, Response, Status};
use vademecum_proto::v1 as pb;

use crate::auth::caller;
use crate::registry::Registry;

/// The Fleet service.
#[derive(Debug, Clone)]
pub struct FleetService {
    /// The sessions.
    pub registry: Registry,
}

#[tonic::async_trait]
impl pb::fleet_server::Fleet for FleetService {
    async fn get_load(&self, req: Request<pb::GetLoadRequest>) -> Result<Response<pb::ServerLoad>, Status> {
        caller(&req)?;
        Ok(Response::new(self.registry.load()))
    }

    async fn drain(&self, req: Request<pb::DrainRequest>) -> Result<Response<pb::ServerLoad>, Status> {
        caller(&req)?;
        // only the server's own host: a pod's preStop hook, an operator on the host
        if !req.remote_addr().is_some_and(|a| a.ip().is_loopback()) {
            return Err(Status::permission_denied(
                "Drain is taken from the server's own host only (loopback): run `vademecum drain` there",
            ));
        }
        let resume = req.get_ref().resume;
        self.registry.set_draining(!resume);
        let load = self.registry.load();
        tracing::info!(
            sessions = load.sessions,
            "{}",
            if resume { "draining ended" } else { "draining: no new session" }
        );
        Ok(Response::new(load))
    }
}
