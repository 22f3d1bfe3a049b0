//! A fleet of servers that route sessions between them (`proto/vademecum/v1/fleet.proto`).
//!
//! Sessions own in-memory state, so a fleet routes rather than balances. Every server of a
//! fleet is a front door: its `CreateSession` asks every peer for its load (`Fleet.GetLoad`,
//! concurrently, [`PEER_TIMEOUT`] each), places the session on the least-loaded server that
//! accepts one ([`placement_order`]), creates it there — forwarding the caller's own request
//! and bearer token, marked with [`FORWARDED`] so the peer creates it on itself — and answers
//! with `SessionInfo.redirect` naming the server that holds it. `GetSession`, `ListSessions`
//! and `CloseSession` reach the caller's sessions on whichever server holds them the same way.
//! A peer that does not answer is left out; a peer that refuses the session (full, draining,
//! or raced to its limit) passes it to the next.
//!
//! Nothing here is on a tick path: it runs in the Sessions service's request handlers.

use std::sync::Arc;
use std::time::Duration;

use tonic::metadata::MetadataMap;
use tonic::transport::{Certificate, Channel, ClientTlsConfig, Endpoint};
use tonic::{Code, Request, Status};
use vademecum_proto::v1 as pb;

/// The metadata key marking a call a front door forwarded to a peer: the peer answers from
/// itself alone (no second hop).
pub const FORWARDED: &str = "x-vademecum-forwarded";

/// How long a front door waits for a peer's load report.
pub const PEER_TIMEOUT: Duration = Duration::from_secs(1);

/// Settings of a server in a fleet.
#[derive(Debug, Clone)]
pub struct FleetConfig {
    /// This server's address as clients reach it (`--advertise`), put in redirects to it.
    pub advertise: String,
    /// The other servers' addresses as this server reaches them (`--peer`).
    pub peers: Vec<String>,
    /// CA certificate (PEM) that `https://` peers' certificates are checked against.
    pub peer_ca: Option<Vec<u8>>,
}

/// Whether `name` can name a server: 1 to 40 of `A-Z a-z 0-9 . _ -` (session ids start with
/// it, and a haptic channel named after a session id must stay a valid channel name).
pub fn valid_name(name: &str) -> bool {
    (1..=40).contains(&name.len()) && name.bytes().all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'))
}

/// One other server of the fleet.
#[derive(Debug, Clone)]
pub struct Peer {
    /// Its address as given.
    pub address: String,
    channel: Channel,
}

/// The peers of a server (lazily connected channels).
#[derive(Debug, Clone)]
pub struct Peers {
    peers: Arc<[Peer]>,
}

/// A server the front door may place a session on.
#[derive(Debug, Clone, PartialEq)]
pub enum Candidate {
    /// The front door itself.
    Local,
    /// Peer `i` of [`Peers::list`].
    Peer(usize),
}

impl Peers {
    /// Channels to `config.peers`; nothing is connected until first used.
    pub fn new(config: &FleetConfig) -> anyhow::Result<Self> {
        let mut peers = Vec::with_capacity(config.peers.len());
        for address in &config.peers {
            let mut endpoint = Endpoint::from_shared(address.clone())
                .map_err(|_| anyhow::anyhow!("--peer {address} is not a URL like http://host:50051"))?
                .connect_timeout(PEER_TIMEOUT)
                .tcp_nodelay(true);
            if address.starts_with("https://") {
                let mut tls = ClientTlsConfig::new();
                if let Some(ca) = &config.peer_ca {
                    tls = tls.ca_certificate(Certificate::from_pem(ca));
                }
                endpoint = endpoint
                    .tls_config(tls)
                    .map_err(|e| anyhow::anyhow!("--peer {address}: cannot set up TLS: {e}"))?;
            }
            peers.push(Peer {
                address: address.clone(),
                channel: endpoint.connect_lazy(),
            });
        }
        Ok(Self { peers: peers.into() })
    }

    /// The peers.
    pub fn list(&self) -> &[Peer] {
        &self.peers
    }

    /// Sessions client of peer `i`.
    pub fn sessions(&self, i: usize) -> pb::sessions_client::SessionsClient<Channel> {
        pb::sessions_client::SessionsClient::new(self.peers[i].channel.clone())
    }

    /// Every peer's load report, in peer order (`None`: no answer within [`PEER_TIMEOUT`], or
    /// an error), asked concurrently with the caller's metadata.
    pub async fn loads(&self, caller: &MetadataMap) -> Vec<Option<pb::ServerLoad>> {
        let mut asks = tokio::task::JoinSet::new();
        for (i, p) in self.peers.iter().enumerate() {
            let mut client = pb::fleet_client::FleetClient::new(p.channel.clone());
            let req = forwarded(pb::GetLoadRequest {}, caller);
            let address = p.address.clone();
            asks.spawn(async move {
                let load = match tokio::time::timeout(PEER_TIMEOUT, client.get_load(req)).await {
                    Ok(Ok(r)) => Some(r.into_inner()),
                    // not running (a fleet sized below its peer list): quietly left out
                    Ok(Err(s)) if s.code() == Code::Unavailable => {
                        tracing::debug!(peer = %address, status = %s, "a peer is not reachable");
                        None
                    }
                    Ok(Err(s)) => {
                        tracing::warn!(peer = %address, status = %s, "a peer refused its load report");
                        None
                    }
                    Err(_) => {
                        tracing::warn!(peer = %address, "a peer did not report its load in time");
                        None
                    }
                };
                (i, load)
            });
        }
        let mut out = vec![None; self.peers.len()];
        while let Some(done) = asks.join_next().await {
            if let Ok((i, load)) = done {
                out[i] = load;
            }
        }
        out
    }

    /// Where clients reach peer `i`: its advertised address, or the one this server was given.
    pub fn location(&self, i: usize, load: Option<&pb::ServerLoad>) -> pb::SessionLocation {
        match load {
            Some(l) if !l.address.is_empty() => pb::SessionLocation {
                address: l.address.clone(),
                server: l.name.clone(),
            },
            _ => pb::SessionLocation {
                address: self.peers[i].address.clone(),
                server: load.map(|l| l.name.clone()).unwrap_or_default(),
            },
        }
    }
}

/// `message` as a request to a peer: the caller's `authorization` (every server of a fleet
/// accepts the same tokens) and the [`FORWARDED`] mark.
pub fn forwarded<T>(message: T, caller: &MetadataMap) -> Request<T> {
    let mut req = Request::new(message);
    if let Some(auth) = caller.get("authorization") {
        req.metadata_mut().insert("authorization", auth.clone());
    }
    req.metadata_mut()
        .insert(FORWARDED, tonic::metadata::MetadataValue::from_static("1"));
    req
}

/// Whether a request was forwarded by a front door (answer from this server alone).
pub fn is_forwarded(metadata: &MetadataMap) -> bool {
    metadata.contains_key(FORWARDED)
}

/// Whether a load report says a server takes a new session.
fn accepts(l: &pb::ServerLoad) -> bool {
    !l.draining && l.sessions < l.max_sessions
}

/// The order to try servers in for a new session: those that accept one (not draining, under
/// their session cap), least loaded first — by the fraction of their session cap in use, then
/// by their least-loaded tick worker's utilisation in steps of 5 % (finer differences are
/// noise) — the front door itself first among equals (no hop), then the peers in their given
/// order. A peer without a report is left out.
pub fn placement_order(local: &pb::ServerLoad, peers: &[Option<pb::ServerLoad>]) -> Vec<(Candidate, pb::ServerLoad)> {
    let mut c: Vec<(usize, Candidate, pb::ServerLoad)> = Vec::new();
    if accepts(local) {
        c.push((0, Candidate::Local, local.clone()));
    }
    for (i, l) in peers.iter().enumerate() {
        if let Some(l) = l.as_ref().filter(|l| accepts(l)) {
            c.push((i + 1, Candidate::Peer(i), l.clone()));
        }
    }
    let key = |l: &pb::ServerLoad| {
        let cap = l.sessions as f64 / l.max_sessions.max(1) as f64;
        let util = (l.tick_utilisation.clamp(0.0, 1.0) * 20.0).floor();
        (cap, util)
    };
    c.sort_by(|a, b| {
        key(&a.2)
            .partial_cmp(&key(&b.2))
            .unwrap_or(std::cmp::Ordering::Equal)
            .then(a.0.cmp(&b.0))
    });
    c.into_iter().map(|(_, cand, l)| (cand, l)).collect()
}

/// Whether a peer's refusal of a new session means "try the next server" (it is full,
/// draining, unreachable) rather than "the request is wrong everywhere".
pub fn try_next(status: &Status) -> bool {
    matches!(
        status.code(),
        Code::ResourceExhausted | Code::Unavailable | Code::DeadlineExceeded | Code::Cancelled | Code::Unknown
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(sessions: u32, max: u32, util: f64, draining: bool) -> pb::ServerLoad {
        pb::ServerLoad {
            sessions,
            max_sessions: max,
            tick_utilisation: util,
            draining,
            ..Default::default()
        }
    }

    fn order(local: pb::ServerLoad, peers: &[Option<pb::ServerLoad>]) -> Vec<Option<usize>> {
        placement_order(&local, peers)
            .into_iter()
            .map(|(c, _)| match c {
                Candidate::Local => None,
                Candidate::Peer(i) => Some(i),
            })
            .collect()
    }

    #[test]
    fn sessions_go_to_the_least_loaded_server_that_accepts_one() {
        // equal loads: the front door first, then the peers in order
        assert_eq!(
            order(
                load(0, 4, 0.0, false),
                &[Some(load(0, 4, 0.0, false)), Some(load(0, 4, 0.0, false))]
            ),
            [None, Some(0), Some(1)]
        );
        // the fraction of the cap in use counts first
        assert_eq!(
            order(
                load(1, 4, 0.0, false),
                &[Some(load(1, 8, 0.0, false)), Some(load(0, 4, 0.9, false))]
            ),
            [Some(1), Some(0), None]
        );
        // then the tick load, by 5 % steps (0.31 and 0.34 are equal, 0.5 is more)
        assert_eq!(
            order(
                load(1, 4, 0.5, false),
                &[Some(load(1, 4, 0.34, false)), Some(load(1, 4, 0.31, false))]
            ),
            [Some(0), Some(1), None]
        );
        // draining, full and silent servers are left out
        assert_eq!(
            order(
                load(0, 4, 0.0, true),
                &[Some(load(4, 4, 0.0, false)), None, Some(load(3, 4, 0.0, false))]
            ),
            [Some(2)]
        );
        assert!(order(load(2, 2, 0.0, false), &[]).is_empty());
    }

    #[test]
    fn server_names_are_checked() {
        assert!(valid_name("vademecum-2"));
        assert!(valid_name("lab.host_1"));
        assert!(!valid_name(""));
        assert!(!valid_name("a/b"));
        assert!(!valid_name(&"x".repeat(41)));
    }

    #[test]
    fn only_refusals_of_capacity_pass_a_session_on() {
        assert!(try_next(&Status::resource_exhausted("full")));
        assert!(try_next(&Status::unavailable("draining")));
        assert!(!try_next(&Status::invalid_argument("bad scene")));
        assert!(!try_next(&Status::failed_precondition("no bundle")));
        assert!(!try_next(&Status::unauthenticated("token")));
    }
}
