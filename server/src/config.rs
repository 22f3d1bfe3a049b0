//! Runtime settings of `vademecum serve`, with their defaults and why.

use std::path::PathBuf;

use crate::fleet::FleetConfig;
use crate::session::{FrameWorkersConfig, SchedulerConfig, SessionConfig};

/// Settings of a server.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// Scene files named by `scene_path` resolve under this folder; inline scenes resolve
    /// their relative mesh paths against it.
    pub scene_root: PathBuf,
    /// Every mesh file a client's scene names (inline or by path) must lie under this folder
    /// (after resolving `..` and symbolic links); anything else is PERMISSION_DENIED, without
    /// saying whether the file exists.
    pub mesh_root: PathBuf,
    /// Bundle folders named by `bundle_dir` resolve under this folder.
    pub bundle_root: PathBuf,
    /// The content-addressed bundle store (`<store>/sha256/<hex>/`) that sessions asking for
    /// bundles by digest are served from (`None`: such sessions are refused).
    pub bundle_store: Option<PathBuf>,
    /// Where bundles missing from the store are fetched from (an HTTP(S) base URL holding
    /// `sha256/<hex>/`; `None`: only what the store holds).
    pub bundle_source: Option<String>,
    /// How long and how much a fetch from [`Self::bundle_source`] may take.
    pub bundle_fetch: crate::bundle_fetch::FetchLimits,
    /// Whether clients may name server-side scene paths at all.
    pub allow_paths: bool,
    /// Most sessions at once (all clients together).
    pub max_sessions: usize,
    /// Most cells of an organ's built-in mesh in a client's scene (inline or by path), counted
    /// from its settings before any memory is spent on it (`RESOURCE_EXHAUSTED` beyond).
    pub max_scene_cells: usize,
    /// Most sessions being prepared (scenes, meshes, bundles read) at once; a `CreateSession`
    /// beyond it is refused with `RESOURCE_EXHAUSTED` (retry): a burst of large scenes never
    /// holds more than this many meshes in memory at once.
    pub max_preparing: usize,
    /// Most sessions one client (one bearer token) holds at once.
    pub client_sessions: usize,
    /// Most streams of each kind (interaction, viewer) open at once, all clients together.
    pub max_streams: u32,
    /// Most streams of each kind one client holds open at once.
    pub client_streams: u32,
    /// Highest frame rate a viewer gets (Hz); requests above it are capped.
    pub max_frame_rate_hz: f64,
    /// Largest message the server accepts (bytes): an inline scene is the largest thing a
    /// client sends; tool states are ~100 bytes.
    pub max_request_bytes: usize,
    /// Largest message the server sends (bytes): the geometry message of a large organ
    /// (positions and triangles of its surface).
    pub max_response_bytes: usize,
    /// TLS certificate chain and private key (PEM) for remote clients (`None`: plain
    /// HTTP/2, for loopback and trusted networks).
    pub tls: Option<(Vec<u8>, Vec<u8>)>,
    /// Bearer tokens accepted (`None`: no authentication; every client is "anonymous").
    pub tokens: Option<Vec<String>>,
    /// Origins (`https://host[:port]`) whose pages may call the gRPC-web port
    /// (`serve --web-origin`). Empty: any origin when the server has tokens (a bearer token is
    /// a header a page must be given, not an ambient credential), none but the viewer's own
    /// without them (`--no-auth`: any page on any site could otherwise list, create and close
    /// sessions on the lab's machine).
    pub web_origins: Vec<String>,
    /// How sessions tick.
    pub session: SessionConfig,
    /// The tick workers that tick the sessions (`workers = 0`: a thread per session), unless
    /// `session.ticking` names workers already; as many answer workers route their answers
    /// (unless `session.answering` names some). A haptic session is ticked by a device worker
    /// or has a thread of its own.
    pub tick_workers: SchedulerConfig,
    /// Device workers that tick the sessions driven by device bridges with the event wait,
    /// each blocked on many bridges' events at once (0: a thread per device session), unless
    /// `session.devices` names workers already.
    pub device_workers: usize,
    /// The frame workers that make the sessions' frames (`workers = 0`: a thread per session),
    /// unless `session.framing` names workers already.
    pub frame_workers: FrameWorkersConfig,
    /// This server's name: in a fleet, its session ids start with it and its load reports
    /// carry it (the host name by default).
    pub name: String,
    /// The fleet this server is a front door of (`None`: it serves its own sessions alone).
    pub fleet: Option<FleetConfig>,
    /// Run as an Agones GameServer (`--agones`).
    pub agones: bool,
    /// How a session driven by a device bridge waits for its states (`None`: the hybrid
    /// wait), unless `session.haptic` gives the whole haptic configuration.
    pub haptic_wait: Option<vademecum_bridge::timing::WaitStrategy>,
}

impl Default for ServerConfig {
    fn default() -> Self {
        Self {
            scene_root: PathBuf::from("."),
            mesh_root: PathBuf::from("."),
            bundle_root: PathBuf::from("."),
            allow_paths: true,
            bundle_store: None,
            bundle_source: None,
            bundle_fetch: crate::bundle_fetch::FetchLimits::default(),
            max_sessions: 16,
            // the OpenHELP liver has 10,000-odd cells: a client's scene of two million is
            // generous, and costs ~100 MB while prepared
            max_scene_cells: 2_000_000,
            max_preparing: 4,
            // a tenant cannot take every slot: a quarter of the sessions, a sixteenth of the
            // streams (a frontend and a few viewers per session)
            client_sessions: 4,
            max_streams: 256,
            client_streams: 16,
            max_frame_rate_hz: 60.0,
            max_request_bytes: 1 << 20,
            max_response_bytes: 64 << 20,
            tokens: None,
            web_origins: Vec::new(),
            tls: None,
            session: SessionConfig::default(),
            tick_workers: SchedulerConfig::default(),
            frame_workers: FrameWorkersConfig::default(),
            device_workers: 0,
            haptic_wait: None,
            name: "vademecum".into(),
            fleet: None,
            agones: false,
        }
    }
}
