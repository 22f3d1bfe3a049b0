//! Async Rust client for vademecum servers: connect, create a session, stream tool states
//! and receive forces, watch displacement frames.
//!
//! ```no_run
//! # async fn demo() -> Result<(), vademecum_client::SdkError> {
//! use vademecum_client::{Client, SceneSpec, tool_at};
//! let client = Client::connect("http://127.0.0.1:50051").await?;
//! let session = client.create_session(SceneSpec::Builtin("organ".into()), "out/organ", "demo").await?;
//! let mut tools = session.interact().await?;
//! tools.send(tool_at(1, [0.0, 0.0, 0.045])).await?;
//! if let Some(r) = tools.next().await? {
//!     println!("force {:?}", r.force_n);
//! }
//! session.close().await?;
//! # Ok(()) }
//! ```
//!
//! # Layout
//! - [`Client`]: a connection (optionally with a bearer token); creates and finds sessions.
//! - [`Session`]: one session: [`Session::interact`] (a bidirectional stream of tool states
//!   and responses), [`Session::watch`] (frames), [`Session::watch_acked`] (frames with
//!   acknowledgements, for viewers that can be slower than their rate), statistics, close.
//! - [`SdkError`]: every failure, with a [`SdkError::kind`] to branch on.
#![warn(missing_docs)]

use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use tonic::Streaming;
use tonic::metadata::MetadataValue;
use tonic::service::Interceptor;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::Channel;
pub use vademecum_proto::v1 as pb;

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
    /// The token cannot be sent as metadata.
    #[error("the token contains characters that cannot be sent as metadata")]
    BadToken,
    /// The stream to the server is closed.
    #[error("the stream to the server is closed")]
    Closed,
    /// An interaction stream ended with tool states it sent unanswered (the session was
    /// closed, or the server stopped): `unanswered` is this client's own count, exact, where
    /// the server can count only the states that reached it.
    #[error("the session was closed: the last {unanswered} tool state(s) this stream sent were not answered ({})", .status.as_ref().map_or("the server ended the stream".to_string(), |s| format!("server: {}", s.message())))]
    Unanswered {
        /// Tool states sent on the stream and never answered.
        unanswered: u64,
        /// The server's ABORTED status, if it ended the stream with one.
        status: Option<tonic::Status>,
    },
}

/// What kind of failure an [`SdkError`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// Could not reach the server.
    Connect,
    /// No such session (or not yours).
    NotFound,
    /// The request was invalid.
    InvalidArgument,
    /// Missing or wrong token.
    Unauthenticated,
    /// A limit was reached (sessions, queue, message size).
    ResourceExhausted,
    /// A bundle is missing or stale.
    FailedPrecondition,
    /// The caller may not do this (e.g. name a file outside the server's roots).
    PermissionDenied,
    /// The session closed before answering every tool state sent.
    Aborted,
    /// Anything else.
    Other,
}

impl SdkError {
    /// The kind of failure.
    pub fn kind(&self) -> ErrorKind {
        match self {
            SdkError::Connect { .. } => ErrorKind::Connect,
            SdkError::Status(s) => match s.code() {
                tonic::Code::NotFound => ErrorKind::NotFound,
                tonic::Code::InvalidArgument => ErrorKind::InvalidArgument,
                tonic::Code::Unauthenticated => ErrorKind::Unauthenticated,
                tonic::Code::ResourceExhausted => ErrorKind::ResourceExhausted,
                tonic::Code::FailedPrecondition => ErrorKind::FailedPrecondition,
                tonic::Code::PermissionDenied => ErrorKind::PermissionDenied,
                tonic::Code::Aborted => ErrorKind::Aborted,
                _ => ErrorKind::Other,
            },
            SdkError::BadToken => ErrorKind::Unauthenticated,
            SdkError::Closed => ErrorKind::Other,
            SdkError::Unanswered { .. } => ErrorKind::Aborted,
        }
    }
}

/// Adds `authorization: Bearer <token>` to every call when a token is set.
#[derive(Debug, Clone, Default)]
pub struct Token(Option<MetadataValue<tonic::metadata::Ascii>>);

impl Interceptor for Token {
    fn call(&mut self, mut req: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        if let Some(v) = &self.0 {
            req.metadata_mut().insert("authorization", v.clone());
        }
        Ok(req)
    }
}

type Svc = InterceptedService<Channel, Token>;

/// Where a session's scene comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum SceneSpec {
    /// A built-in scene by name ("organ", …).
    Builtin(String),
    /// Scene TOML text.
    Toml(String),
    /// A scene file on the server, relative to its scene root.
    Path(String),
}

/// A connection to a vademecum server.
///
/// In a fleet (several servers routing sessions between them, `proto/vademecum/v1/fleet.proto`)
/// a server may answer that a session lives on another server (`SessionInfo.redirect`): the
/// [`Session`] handles returned here then talk to that server, with the same token and TLS
/// settings — the caller does nothing.
#[derive(Debug, Clone)]
pub struct Client {
    channel: Channel,
    token: Token,
    /// What connecting again elsewhere takes (a redirect).
    how: Reconnect,
}

/// The settings a [`Client`] was connected with, for following a redirect.
#[derive(Debug, Clone, Default)]
struct Reconnect {
    token: Option<String>,
    /// CA certificate of a TLS connection (the domain is the redirect's host).
    ca_pem: Option<Vec<u8>>,
}

/// The host of a URL like `https://host:port/…` (a TLS domain to check).
fn host_of(addr: &str) -> &str {
    let rest = addr.split_once("://").map_or(addr, |(_, r)| r);
    let end = rest.find([':', '/']).unwrap_or(rest.len());
    &rest[..end]
}

impl Client {
    /// Connects to `addr` (for example `http://127.0.0.1:50051`), with no token.
    pub async fn connect(addr: impl Into<String>) -> Result<Self, SdkError> {
        Self::connect_with_token(addr, None).await
    }

    /// Connects and presents `token` on every call.
    pub async fn connect_with_token(addr: impl Into<String>, token: Option<&str>) -> Result<Self, SdkError> {
        Self::connect_with(addr, token, None).await
    }

    /// Connects over TLS to `addr` (`https://…`), trusting the CA certificate `ca_pem` and
    /// checking that the server's certificate names `domain`; presents `token` if given.
    pub async fn connect_tls(addr: impl Into<String>, ca_pem: &[u8], domain: &str, token: Option<&str>) -> Result<Self, SdkError> {
        let tls = tonic::transport::ClientTlsConfig::new()
            .ca_certificate(tonic::transport::Certificate::from_pem(ca_pem))
            .domain_name(domain);
        let mut c = Self::connect_with(addr, token, Some(tls)).await?;
        c.how.ca_pem = Some(ca_pem.to_vec());
        Ok(c)
    }

    async fn connect_with(
        addr: impl Into<String>,
        token: Option<&str>,
        tls: Option<tonic::transport::ClientTlsConfig>,
    ) -> Result<Self, SdkError> {
        let addr = addr.into();
        let how = Reconnect {
            token: token.map(String::from),
            ca_pem: None,
        };
        let token = match token {
            Some(t) => Token(Some(format!("Bearer {t}").parse().map_err(|_| SdkError::BadToken)?)),
            None => Token(None),
        };
        let mut endpoint = Channel::from_shared(addr.clone()).map_err(|_| SdkError::Closed)?;
        if let Some(tls) = tls {
            endpoint = endpoint.tls_config(tls).map_err(|source| SdkError::Connect {
                addr: addr.clone(),
                source,
            })?;
        }
        let channel = endpoint.connect().await.map_err(|source| SdkError::Connect { addr, source })?;
        Ok(Self { channel, token, how })
    }

    /// The client to reach a session at: this one, or a connection to the server a fleet's
    /// redirect names (same token and TLS settings).
    async fn follow(&self, info: &pb::SessionInfo) -> Result<Client, SdkError> {
        let Some(to) = info.redirect.as_ref().filter(|r| !r.address.is_empty()) else {
            return Ok(self.clone());
        };
        let token = self.how.token.as_deref();
        match &self.how.ca_pem {
            Some(ca) => Self::connect_tls(to.address.clone(), ca, host_of(&to.address), token).await,
            None => Self::connect_with(to.address.clone(), token, None).await,
        }
    }

    fn svc(&self) -> Svc {
        InterceptedService::new(self.channel.clone(), self.token.clone())
    }

    /// Asks the server for its version and capabilities.
    pub async fn server_info(&self) -> Result<pb::ServerInfo, SdkError> {
        let mut c = pb::info_client::InfoClient::new(self.svc());
        Ok(c.get_server_info(pb::GetServerInfoRequest {}).await?.into_inner())
    }

    /// Starts a session on `scene` with the bundles in `bundle_dir` (on the server,
    /// relative to its bundle root).
    pub async fn create_session(&self, scene: SceneSpec, bundle_dir: &str, label: &str) -> Result<Session, SdkError> {
        self.create(scene, bundle_dir, label, None).await
    }

    /// Starts a session with a shared-memory haptic channel for a device bridge on the
    /// server's host (`vademecum-bridge --session <channel>`). `channel` empty: the channel is
    /// named after the session id (see [`Session::info`]'s `haptic_channel`).
    pub async fn create_haptic_session(&self, scene: SceneSpec, bundle_dir: &str, label: &str, channel: &str) -> Result<Session, SdkError> {
        self.create(scene, bundle_dir, label, Some(channel)).await
    }

    /// Starts a session whose bundles are pinned by content: `digests` gives each organ's
    /// bundle digest (`sha256:…`, printed by `vademecum publish`); the server serves exactly
    /// those bundles from its bundle store (fetching them from its bundle source when
    /// missing) or refuses with FAILED_PRECONDITION.
    pub async fn create_pinned_session(&self, scene: SceneSpec, digests: &[(&str, &str)], label: &str) -> Result<Session, SdkError> {
        let digests = digests.iter().map(|(o, d)| (o.to_string(), d.to_string())).collect();
        self.create_with(scene, "", digests, label, None).await
    }

    async fn create(&self, scene: SceneSpec, bundle_dir: &str, label: &str, haptic: Option<&str>) -> Result<Session, SdkError> {
        self.create_with(scene, bundle_dir, Default::default(), label, haptic).await
    }

    async fn create_with(
        &self,
        scene: SceneSpec,
        bundle_dir: &str,
        bundle_digests: std::collections::HashMap<String, String>,
        label: &str,
        haptic: Option<&str>,
    ) -> Result<Session, SdkError> {
        use pb::create_session_request::Scene;
        let scene = match scene {
            SceneSpec::Builtin(b) => Scene::Builtin(b),
            SceneSpec::Toml(t) => Scene::SceneToml(t),
            SceneSpec::Path(p) => Scene::ScenePath(p),
        };
        let mut c = pb::sessions_client::SessionsClient::new(self.svc());
        let info = c
            .create_session(pb::CreateSessionRequest {
                scene: Some(scene),
                bundle_dir: bundle_dir.into(),
                label: label.into(),
                haptic: haptic.is_some(),
                haptic_channel: haptic.unwrap_or_default().into(),
                bundle_digests,
            })
            .await?
            .into_inner();
        Ok(Session {
            client: self.follow(&info).await?,
            info,
        })
    }

    /// The caller's sessions (in a fleet: on every server of it, each with its redirect).
    pub async fn list_sessions(&self) -> Result<Vec<pb::SessionInfo>, SdkError> {
        let mut c = pb::sessions_client::SessionsClient::new(self.svc());
        Ok(c.list_sessions(pb::ListSessionsRequest {}).await?.into_inner().sessions)
    }

    /// A handle on an existing session of the caller's.
    pub async fn session(&self, id: &str) -> Result<Session, SdkError> {
        let mut c = pb::sessions_client::SessionsClient::new(self.svc());
        let info = c.get_session(pb::GetSessionRequest { session_id: id.into() }).await?.into_inner();
        Ok(Session {
            client: self.follow(&info).await?,
            info,
        })
    }
}

/// One session on a server (the one that holds it, a fleet's redirect followed).
#[derive(Debug, Clone)]
pub struct Session {
    client: Client,
    info: pb::SessionInfo,
}

impl Session {
    /// The session id.
    pub fn id(&self) -> &str {
        &self.info.session_id
    }

    /// What the server said about it at creation.
    pub fn info(&self) -> &pb::SessionInfo {
        &self.info
    }

    /// The server the session lives on, when a fleet's front door redirected to it (`None`:
    /// the server the [`Client`] connected to).
    pub fn location(&self) -> Option<&pb::SessionLocation> {
        self.info.redirect.as_ref()
    }

    /// Live statistics.
    pub async fn stats(&self) -> Result<pb::SessionStats, SdkError> {
        let mut c = pb::sessions_client::SessionsClient::new(self.client.svc());
        let info = c
            .get_session(pb::GetSessionRequest {
                session_id: self.id().into(),
            })
            .await?
            .into_inner();
        Ok(info.stats.unwrap_or_default())
    }

    /// Opens an interaction stream on this session.
    pub async fn interact(&self) -> Result<Interaction, SdkError> {
        let (tx, rx) = mpsc::channel(1024);
        let mut c = pb::interaction_client::InteractionClient::new(self.client.svc());
        // the server needs the first message to know the session: queue it before opening
        let first_id = self.id().to_string();
        let responses_fut = async move { c.interact(ReceiverStream::new(rx)).await };
        let interaction = Interaction {
            session_id: first_id,
            tx: Some(tx),
            first_sent: false,
            sent: 0,
            answered: 0,
            pending: None,
        };
        Ok(interaction.with_responses(responses_fut))
    }

    /// Watches frames at `rate_hz` (0: the server's default, 30 Hz). The first frame
    /// carries the reference geometry.
    pub async fn watch(&self, rate_hz: f64) -> Result<Streaming<pb::Frame>, SdkError> {
        let mut c = pb::viewing_client::ViewingClient::new(self.client.svc()).max_decoding_message_size(256 << 20);
        Ok(c.watch(pb::WatchRequest {
            session_id: self.id().into(),
            rate_hz,
            window: 0,
        })
        .await?
        .into_inner())
    }

    /// Watches frames at `rate_hz` with acknowledgements ([`Viewer`]): the server keeps at
    /// most `window` messages unacknowledged (0: its default, 2), so a viewer slower than
    /// its rate gets the latest frame when it is ready, never a backlog. Call
    /// [`Viewer::next`], which acknowledges the previous message.
    pub async fn watch_acked(&self, rate_hz: f64, window: u32) -> Result<Viewer, SdkError> {
        let mut c = pb::viewing_client::ViewingClient::new(self.client.svc()).max_decoding_message_size(256 << 20);
        let (tx, rx) = mpsc::channel(4);
        let start = pb::ViewerControl {
            control: Some(pb::viewer_control::Control::Start(pb::WatchRequest {
                session_id: self.id().into(),
                rate_hz,
                window,
            })),
        };
        tx.send(start).await.map_err(|_| SdkError::Closed)?;
        let frames = c.watch_acked(ReceiverStream::new(rx)).await?.into_inner();
        Ok(Viewer { tx, frames, last: None })
    }

    /// Closes the session; returns its final statistics.
    pub async fn close(self) -> Result<pb::SessionStats, SdkError> {
        let mut c = pb::sessions_client::SessionsClient::new(self.client.svc());
        Ok(c.close_session(pb::CloseSessionRequest {
            session_id: self.id().into(),
        })
        .await?
        .into_inner()
        .stats
        .unwrap_or_default())
    }
}

type ResponsesFuture = std::pin::Pin<Box<dyn Future<Output = Result<tonic::Response<Streaming<pb::ToolResponse>>, tonic::Status>> + Send>>;

/// A bidirectional stream of tool states and their responses.
pub struct Interaction {
    session_id: String,
    /// `None` once the client's side is finished.
    tx: Option<mpsc::Sender<pb::ToolState>>,
    first_sent: bool,
    /// Tool states handed to the stream.
    sent: u64,
    /// Responses received.
    answered: u64,
    pending: Option<PendingResponses>,
}

enum PendingResponses {
    Opening(ResponsesFuture),
    Open(Box<Streaming<pb::ToolResponse>>),
}

impl std::fmt::Debug for Interaction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Interaction").field("session_id", &self.session_id).finish()
    }
}

impl Interaction {
    fn with_responses(
        mut self,
        fut: impl Future<Output = Result<tonic::Response<Streaming<pb::ToolResponse>>, tonic::Status>> + Send + 'static,
    ) -> Self {
        self.pending = Some(PendingResponses::Opening(Box::pin(fut)));
        self
    }

    /// Sends a tool state (the session id is filled in on the first).
    pub async fn send(&mut self, mut state: pb::ToolState) -> Result<(), SdkError> {
        if !self.first_sent {
            state.session_id = self.session_id.clone();
            self.first_sent = true;
        }
        let tx = self.tx.as_ref().ok_or(SdkError::Closed)?;
        tx.send(state).await.map_err(|_| SdkError::Closed)?;
        self.sent += 1;
        Ok(())
    }

    /// Tool states sent on this stream that have not been answered yet.
    pub fn unanswered(&self) -> u64 {
        self.sent - self.answered
    }

    /// Ends the client's side of the stream: the server answers what was sent, then ends.
    pub fn finish(&mut self) {
        self.tx = None;
    }

    async fn stream(&mut self) -> Result<&mut Streaming<pb::ToolResponse>, SdkError> {
        if let Some(PendingResponses::Opening(_)) = &self.pending {
            let Some(PendingResponses::Opening(fut)) = self.pending.take() else {
                unreachable!()
            };
            let s = fut.await?.into_inner();
            self.pending = Some(PendingResponses::Open(Box::new(s)));
        }
        match &mut self.pending {
            Some(PendingResponses::Open(s)) => Ok(s),
            _ => Err(SdkError::Closed),
        }
    }

    /// The next response (`None` when the server ended the stream having answered every
    /// state sent). A stream that ends with states unanswered (the session was closed under
    /// it) fails with [`SdkError::Unanswered`], which counts them.
    pub async fn next(&mut self) -> Result<Option<pb::ToolResponse>, SdkError> {
        let m = self.stream().await?.message().await;
        let unanswered = self.unanswered();
        match m {
            Ok(Some(r)) => {
                self.answered += 1;
                Ok(Some(r))
            }
            Ok(None) if unanswered > 0 => Err(SdkError::Unanswered { unanswered, status: None }),
            Err(s) if s.code() == tonic::Code::Aborted && unanswered > 0 => Err(SdkError::Unanswered {
                unanswered,
                status: Some(s),
            }),
            Ok(None) => Ok(None),
            Err(s) => Err(s.into()),
        }
    }
}

/// A credit-based viewer stream ([`Session::watch_acked`]).
#[derive(Debug)]
pub struct Viewer {
    tx: mpsc::Sender<pb::ViewerControl>,
    frames: Streaming<pb::Frame>,
    /// The message returned last, acknowledged by the next call to [`Viewer::next`].
    last: Option<u64>,
}

impl Viewer {
    /// Acknowledges the message returned last (the caller is done with it) and waits for
    /// the next one; `None` when the session has closed.
    pub async fn next(&mut self) -> Result<Option<pb::Frame>, SdkError> {
        if let Some(m) = self.last.take() {
            let ack = pb::ViewerControl {
                control: Some(pb::viewer_control::Control::Ack(m)),
            };
            self.tx.send(ack).await.map_err(|_| SdkError::Closed)?;
        }
        let f = self.frames.message().await?;
        self.last = f.as_ref().map(|f| f.message);
        Ok(f)
    }
}

/// A probe tool state at `position_m` (m) with sequence number `seq`.
pub fn tool_at(seq: u64, position_m: [f64; 3]) -> pb::ToolState {
    pb::ToolState {
        seq,
        kind: pb::ToolKind::Probe as i32,
        position_m: Some(pb::Vec3 {
            x: position_m[0],
            y: position_m[1],
            z: position_m[2],
        }),
        ..Default::default()
    }
}

/// `state` moving the scene's tool named `tool` (`SessionInfo.tools`): a session moves its
/// named tools together — two hands, one stream each or both on one — and the contacts of
/// tools pressing one organ are solved together, so that pressing with one moves the tissue
/// under the other. Unnamed states move the session's one tool at a time.
pub fn named(tool: &str, state: pb::ToolState) -> pb::ToolState {
    pb::ToolState {
        tool: tool.into(),
        ..state
    }
}

/// A grasper tool state at `position_m` (m) with its jaws at `closure` (0 open, 1 closed) and
/// sequence number `seq`. The jaws take hold when they close (closure ≥ 0.5) within the
/// grasper's `jaw_width_m` of one of its `grasp_sites` (`SessionInfo.tools`); the tissue then
/// follows the tool's motion (pushing back along the site's `pull_direction` does nothing).
pub fn grasper_at(seq: u64, position_m: [f64; 3], closure: f64) -> pb::ToolState {
    pb::ToolState {
        kind: pb::ToolKind::Grasper as i32,
        closure,
        ..tool_at(seq, position_m)
    }
}

/// A scalpel tool state with sequence number `seq`: the blade's cutting edge from its tip
/// `tip_m` to `end_m` (m), turned by the unit quaternion `orientation` (`[w, x, y, z]`; the tool
/// frame's y axis turned by it is the normal of the blade's plane). The response's `blade`
/// splits the force along the blade; the blade cuts when its in-plane part exceeds the
/// scalpel's `cut_force_n` (`SessionInfo.tools`).
pub fn scalpel_at(seq: u64, tip_m: [f64; 3], end_m: [f64; 3], orientation: [f64; 4]) -> pb::ToolState {
    let v = |p: [f64; 3]| pb::Vec3 { x: p[0], y: p[1], z: p[2] };
    pb::ToolState {
        seq,
        kind: pb::ToolKind::Scalpel as i32,
        position_m: Some(v(tip_m)),
        blade_end_m: Some(v(end_m)),
        orientation: Some(pb::Quat {
            w: orientation[0],
            x: orientation[1],
            y: orientation[2],
            z: orientation[3],
        }),
        ..Default::default()
    }
}

/// Decodes packed little-endian u32 values (triangles of frames and cut walls).
pub fn u32s(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Decodes packed little-endian f32 values (frame positions and displacements).
pub fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_host_of_a_redirect_is_its_tls_domain() {
        assert_eq!(
            super::host_of("https://vademecum-2.vademecum.lab.svc:50051"),
            "vademecum-2.vademecum.lab.svc"
        );
        assert_eq!(super::host_of("http://10.0.0.7:50051/"), "10.0.0.7");
        assert_eq!(super::host_of("https://host"), "host");
    }
}
