//! `vademecum.v1.Info`: what this server is.

use tonic::{Request, Response, Status};
use vademecum_proto::v1 as pb;

/// The Info service.
#[derive(Debug, Default, Clone)]
pub struct InfoService;

#[tonic::async_trait]
impl pb::info_server::Info for InfoService {
    async fn get_server_info(&self, _: Request<pb::GetServerInfoRequest>) -> Result<Response<pb::ServerInfo>, Status> {
        Ok(Response::new(pb::ServerInfo {
            version: env!("CARGO_PKG_VERSION").into(),
            contract: vademecum_proto::CONTRACT.into(),
            effects: vec!["palpation".into()],
        }))
    }
}
