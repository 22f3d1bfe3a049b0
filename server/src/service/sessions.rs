//! `vademecum.v1.Sessions`: create, list, inspect and close sessions — in a fleet, on
//! whichever server places or holds them ([`crate::fleet`]).

use tonic::metadata::MetadataMap;
use tonic::{Request, Response, Status};
use vademecum_proto::v1 as pb;

use crate::auth::{Caller, caller};
use crate::convert;
use crate::error::ServerError;
use crate::fleet::{self, Candidate, Peers};
use crate::registry::{BundleSource, Registry};

/// The Sessions service.
#[derive(Debug, Clone)]
pub struct SessionsService {
    /// The sessions.
    pub registry: Registry,
    /// The other servers of this server's fleet (`None`: not in a fleet).
    pub peers: Option<Peers>,
}

impl SessionsService {
    /// The peers to reach for a request that a front door did not forward already.
    fn fleet(&self, metadata: &MetadataMap) -> Option<&Peers> {
        self.peers.as_ref().filter(|_| !fleet::is_forwarded(metadata))
    }

    /// Where this server's own sessions live, for a front door to pass on: set on answers to
    /// forwarded requests (the server knows its advertised address and name best).
    fn here(&self, metadata: &MetadataMap) -> Option<pb::SessionLocation> {
        let cfg = self.registry.config();
        let fleet = cfg.fleet.as_ref().filter(|_| fleet::is_forwarded(metadata))?;
        Some(pb::SessionLocation {
            address: fleet.advertise.clone(),
            server: cfg.name.clone(),
        })
    }

    /// What this server says of one of its sessions.
    fn info(&self, e: &crate::registry::Entry, metadata: &MetadataMap) -> pb::SessionInfo {
        pb::SessionInfo {
            redirect: self.here(metadata),
            ..convert::session_info(e)
        }
    }

    /// Creates the session on this server.
    async fn create_here(&self, owner: Caller, r: pb::CreateSessionRequest) -> Result<pb::SessionInfo, Status> {
        let source = convert::scene_source(&r)?;
        let registry = self.registry.clone();
        // reading scenes, meshes and bundles is blocking work: keep it off the runtime
        let entry = tokio::task::spawn_blocking(move || {
            let haptic = r.haptic.then_some(r.haptic_channel.as_str());
            let bundles = match r.bundle_digests.is_empty() {
                true => BundleSource::Dir(&r.bundle_dir),
                false => BundleSource::Pinned(&r.bundle_digests),
            };
            registry.create(owner, source, bundles, r.label, haptic)
        })
        .await
        .map_err(|_| ServerError::Internal("session creation was interrupted".into()))??;
        tracing::info!(session = entry.session.id(), scene = %entry.session.scene().spec.scene.name, "session created");
        Ok(convert::session_info(&entry))
    }

    /// Places the session on the fleet's least-loaded server that takes it: this one, or a
    /// peer (the answer then carries the redirect). A server that refuses for want of room
    /// passes it to the next.
    async fn place(
        &self,
        peers: &Peers,
        owner: Caller,
        metadata: &MetadataMap,
        r: pb::CreateSessionRequest,
    ) -> Result<pb::SessionInfo, Status> {
        let loads = peers.loads(metadata).await;
        let mut refusals = Vec::new();
        for (candidate, load) in fleet::placement_order(&self.registry.load(), &loads) {
            let (answer, server) = match candidate {
                Candidate::Local => (
                    self.create_here(owner.clone(), r.clone()).await,
                    self.registry.config().name.clone(),
                ),
                Candidate::Peer(i) => {
                    let answer = peers.sessions(i).create_session(fleet::forwarded(r.clone(), metadata)).await;
                    let answer = answer.map(|a| {
                        let mut info = a.into_inner();
                        info.redirect.get_or_insert_with(|| peers.location(i, Some(&load)));
                        tracing::info!(session = %info.session_id, at = %peers.list()[i].address, "session placed on a peer");
                        info
                    });
                    (answer, peers.list()[i].address.clone())
                }
            };
            match answer {
                Err(s) if fleet::try_next(&s) => refusals.push(format!("{server}: {}", s.message())),
                other => return other,
            }
        }
        Err(Status::resource_exhausted(if refusals.is_empty() {
            "every server of the fleet is full or draining (or did not report its load)".to_string()
        } else {
            format!("no server of the fleet took the session: {}", refusals.join("; "))
        }))
    }

    /// The peer holding the caller's session `id` and what it says of it, with its redirect.
    async fn find_on_peers(&self, peers: &Peers, metadata: &MetadataMap, id: &str) -> Option<(usize, pb::SessionInfo)> {
        for i in 0..peers.list().len() {
            let req = fleet::forwarded(pb::GetSessionRequest { session_id: id.into() }, metadata);
            if let Ok(Ok(r)) = tokio::time::timeout(fleet::PEER_TIMEOUT, peers.sessions(i).get_session(req)).await {
                let mut info = r.into_inner();
                info.redirect.get_or_insert_with(|| peers.location(i, None));
                return Some((i, info));
            }
        }
        None
    }
}

#[tonic::async_trait]
impl pb::sessions_server::Sessions for SessionsService {
    async fn create_session(&self, req: Request<pb::CreateSessionRequest>) -> Result<Response<pb::SessionInfo>, Status> {
        let owner = caller(&req)?;
        let (metadata, _, r) = req.into_parts();
        // a haptic session stays where it is asked for: its channel is shared memory on this
        // host, where the device bridge runs
        let info = match self.fleet(&metadata).filter(|_| !r.haptic) {
            Some(peers) => self.place(peers, owner, &metadata, r).await?,
            None => pb::SessionInfo {
                redirect: self.here(&metadata),
                ..self.create_here(owner, r).await?
            },
        };
        Ok(Response::new(info))
    }

    async fn list_sessions(&self, req: Request<pb::ListSessionsRequest>) -> Result<Response<pb::ListSessionsResponse>, Status> {
        let owner = caller(&req)?;
        let mut sessions: Vec<_> = self.registry.list(&owner).iter().map(|e| self.info(e, req.metadata())).collect();
        if let Some(peers) = self.fleet(req.metadata()) {
            for i in 0..peers.list().len() {
                let ask = fleet::forwarded(pb::ListSessionsRequest {}, req.metadata());
                match tokio::time::timeout(fleet::PEER_TIMEOUT, peers.sessions(i).list_sessions(ask)).await {
                    Ok(Ok(r)) => sessions.extend(r.into_inner().sessions.into_iter().map(|mut s| {
                        s.redirect.get_or_insert_with(|| peers.location(i, None));
                        s
                    })),
                    _ => tracing::warn!(peer = %peers.list()[i].address, "a peer did not list its sessions"),
                }
            }
        }
        Ok(Response::new(pb::ListSessionsResponse { sessions }))
    }

    async fn get_session(&self, req: Request<pb::GetSessionRequest>) -> Result<Response<pb::SessionInfo>, Status> {
        let owner = caller(&req)?;
        let id = &req.get_ref().session_id;
        match self.registry.get(&owner, id) {
            Ok(e) => Ok(Response::new(self.info(&e, req.metadata()))),
            Err(not_here) => match self.fleet(req.metadata()) {
                Some(peers) => match self.find_on_peers(peers, req.metadata(), id).await {
                    Some((_, info)) => Ok(Response::new(info)),
                    None => Err(not_here.into()),
                },
                None => Err(not_here.into()),
            },
        }
    }

    async fn close_session(&self, req: Request<pb::CloseSessionRequest>) -> Result<Response<pb::CloseSessionResponse>, Status> {
        let owner = caller(&req)?;
        let id = req.get_ref().session_id.clone();
        let e = match self.registry.close(&owner, &id) {
            Ok(e) => e,
            Err(not_here) => {
                let Some(peers) = self.fleet(req.metadata()) else {
                    return Err(not_here.into());
                };
                let Some((i, _)) = self.find_on_peers(peers, req.metadata(), &id).await else {
                    return Err(not_here.into());
                };
                let ask = fleet::forwarded(pb::CloseSessionRequest { session_id: id }, req.metadata());
                return peers.sessions(i).close_session(ask).await;
            }
        };
        tracing::info!(session = e.session.id(), "session closed");
        let stats = convert::session_stats(&e);
        // the last reference to a session may be this one: dropping it waits for the
        // session's last tick, answers and frame, which belongs on a blocking thread, not on
        // a tokio worker that other sessions' streams run on
        tokio::task::spawn_blocking(move || drop(e));
        Ok(Response::new(pb::CloseSessionResponse { stats: Some(stats) }))
    }
}
