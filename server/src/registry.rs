//! The session registry: every live session with its owner, and the cache of loaded bundles
//! shared read-only between sessions built on the same bundle.
//!
//! Shared state is a cheap-clone handle over `Arc<Shared>`. Its maps sit behind
//! `std::sync::Mutex`es: no `.await` ever happens while one is held, and no tick thread ever
//! takes them (sessions own their threads' data), so they never delay a force.

use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, Weak};

use vademecum_engine::bundle;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::bundle::store;
use vademecum_engine::scene::Scene;

use crate::auth::Caller;
use crate::config::ServerConfig;
use crate::error::{ServerError, clip};
use crate::session::{HapticConfig, Session, SessionError};
use vademecum_proto::shm::HapticChannel;

/// Where a session's scene comes from.
#[derive(Debug, Clone)]
pub enum SceneSource {
    /// TOML text.
    Inline(String),
    /// A path under the scene root.
    Path(String),
    /// A built-in scene.
    Builtin(String),
}

/// Where a session's bundles come from.
#[derive(Debug, Clone, Copy)]
pub enum BundleSource<'a> {
    /// `<organ>.bundle` in this folder under the bundle root.
    Dir(&'a str),
    /// Organ name → digest, from the content-addressed store (fetched into it when missing).
    Pinned(&'a HashMap<String, String>),
}

/// A live session and who owns it.
#[derive(Debug)]
pub struct Entry {
    /// The client that created it.
    pub owner: Caller,
    /// Its label.
    pub label: String,
    /// The session.
    pub session: Session,
    /// Interaction streams open on it now.
    pub interacting: AtomicU32,
    /// Viewer streams open on it now.
    pub viewers: AtomicU32,
    /// Flips to true when the session is closed: open streams end.
    pub closed: tokio::sync::watch::Sender<bool>,
}

/// Counts a stream on an [`Entry`] counter while alive.
#[derive(Debug)]
pub struct StreamGuard<'a>(&'a AtomicU32);

impl<'a> StreamGuard<'a> {
    /// Increments `c` until dropped.
    pub fn new(c: &'a AtomicU32) -> Self {
        c.fetch_add(1, Ordering::Relaxed);
        Self(c)
    }
}

impl Drop for StreamGuard<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::Relaxed);
    }
}

/// The kinds of stream a client holds open.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StreamKind {
    /// `Interaction.Interact`.
    Interact,
    /// `Viewing.Watch`.
    Watch,
}

impl StreamKind {
    fn name(self) -> &'static str {
        match self {
            StreamKind::Interact => "interaction",
            StreamKind::Watch => "viewer",
        }
    }
}

/// Open streams, per client and in all, by kind.
#[derive(Debug, Default)]
struct StreamCounts {
    per_client: HashMap<Caller, [u32; 2]>,
    total: [u32; 2],
}

/// A stream slot taken by [`Registry::open_stream`], given back when dropped.
#[derive(Debug)]
pub struct StreamPermit {
    shared: Arc<Shared>,
    owner: Caller,
    kind: StreamKind,
}

impl Drop for StreamPermit {
    fn drop(&mut self) {
        let mut c = self.shared.streams.lock().unwrap_or_else(|p| p.into_inner());
        let k = self.kind as usize;
        c.total[k] = c.total[k].saturating_sub(1);
        if let Some(n) = c.per_client.get_mut(&self.owner) {
            n[k] = n[k].saturating_sub(1);
            if *n == [0, 0] {
                c.per_client.remove(&self.owner);
            }
        }
    }
}

#[derive(Debug)]
struct Shared {
    config: ServerConfig,
    sessions: Mutex<HashMap<String, Arc<Entry>>>,
    streams: Mutex<StreamCounts>,
    bundles: Mutex<HashMap<PathBuf, Weak<LoadedBundle>>>,
    next: AtomicU64,
    /// Draining: no new session is created here (`Fleet.Drain`).
    draining: AtomicBool,
    /// The session count and draining, for whoever follows them (Agones).
    occupancy: tokio::sync::watch::Sender<Occupancy>,
    /// One lock per bundle digest being fetched: one fetch per digest at a time, the other
    /// sessions asking for it wait for it and take it from the store (single flight).
    fetching: Mutex<HashMap<String, Arc<Mutex<()>>>>,
    /// Haptic channel name → the client that first opened a session on it: a channel stays
    /// with that client for the server's life (a device bridge attached to it never drives
    /// another tenant's session).
    channels: Mutex<HashMap<String, Caller>>,
    /// Sessions being prepared now ([`ServerConfig::max_preparing`]).
    preparing: AtomicUsize,
}

/// A preparation slot ([`ServerConfig::max_preparing`]), given back when dropped.
struct Preparing<'a>(&'a AtomicUsize);

impl<'a> Preparing<'a> {
    fn take(n: &'a AtomicUsize, max: usize) -> Result<Self, ServerError> {
        let taken = n.fetch_update(Ordering::AcqRel, Ordering::Acquire, |k| (k < max).then_some(k + 1));
        match taken {
            Ok(_) => Ok(Self(n)),
            Err(_) => Err(ServerError::Exhausted(format!(
                "{max} sessions are being prepared on this server now: retry in a moment"
            ))),
        }
    }
}

impl Drop for Preparing<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::AcqRel);
    }
}

/// How many sessions a server holds and whether it drains ([`Registry::occupancy`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Occupancy {
    /// Sessions held.
    pub sessions: u32,
    /// Draining: no new session here.
    pub draining: bool,
}

/// A cheap-clone handle on the registry.
#[derive(Debug, Clone)]
pub struct Registry {
    shared: Arc<Shared>,
}

/// A relative path with no `..`, no root and no prefix, joined under `root`.
fn under(root: &Path, rel: &str, what: &str) -> Result<PathBuf, ServerError> {
    let p = Path::new(rel);
    if p.components().any(|c| !matches!(c, Component::Normal(_) | Component::CurDir)) {
        return Err(ServerError::Denied(format!(
            "{what} '{}' must be a relative path inside the server's root, without '..'",
            clip(rel)
        )));
    }
    Ok(root.join(p))
}

/// `path` with `.` and `..` resolved by their names alone (no file system access), made
/// absolute against the current folder.
fn lexical(path: &Path) -> PathBuf {
    let abs = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    let mut out = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            c => out.push(c),
        }
    }
    out
}

/// Whether `path` lies under `root`: by name (`..` resolved) and, where it exists, after
/// following symbolic links too (a link inside the root pointing out of it is outside).
fn inside(root: &Path, path: &Path) -> bool {
    if !lexical(path).starts_with(lexical(root)) {
        return false;
    }
    match (path.canonicalize(), root.canonicalize()) {
        (Ok(p), Ok(r)) => p.starts_with(r),
        // not there (yet): judged by name; whatever reads it later finds nothing
        (Err(_), _) => true,
        (Ok(_), Err(_)) => false,
    }
}

impl Registry {
    /// An empty registry.
    pub fn new(config: ServerConfig) -> Self {
        Self {
            shared: Arc::new(Shared {
                config,
                sessions: Mutex::new(HashMap::new()),
                streams: Mutex::new(StreamCounts::default()),
                bundles: Mutex::new(HashMap::new()),
                next: AtomicU64::new(1),
                draining: AtomicBool::new(false),
                occupancy: tokio::sync::watch::channel(Occupancy::default()).0,
                fetching: Mutex::new(HashMap::new()),
                channels: Mutex::new(HashMap::new()),
                preparing: AtomicUsize::new(0),
            }),
        }
    }

    /// The server settings.
    pub fn config(&self) -> &ServerConfig {
        &self.shared.config
    }

    /// Takes a slot for a stream of `kind` opened by `owner`: RESOURCE_EXHAUSTED when the
    /// server holds its cap of such streams, or (with authentication) the client its quota.
    pub fn open_stream(&self, owner: &Caller, kind: StreamKind) -> Result<StreamPermit, ServerError> {
        let cfg = &self.shared.config;
        let k = kind as usize;
        let mut c = self.shared.streams.lock().unwrap_or_else(|p| p.into_inner());
        if c.total[k] >= cfg.max_streams {
            return Err(ServerError::Exhausted(format!(
                "the server has its maximum of {} {} streams open",
                cfg.max_streams,
                kind.name()
            )));
        }
        let mine = c.per_client.get(owner).map_or(0, |n| n[k]);
        if cfg.tokens.is_some() && mine >= cfg.client_streams {
            return Err(ServerError::Exhausted(format!(
                "this client has its quota of {} {} streams open; close one first",
                cfg.client_streams,
                kind.name()
            )));
        }
        c.total[k] += 1;
        c.per_client.entry(owner.clone()).or_default()[k] += 1;
        Ok(StreamPermit {
            shared: self.shared.clone(),
            owner: owner.clone(),
            kind,
        })
    }

    /// Starts (`true`) or ends draining: a draining server creates no new session; the
    /// sessions it holds run on.
    pub fn set_draining(&self, draining: bool) {
        self.shared.draining.store(draining, Ordering::Relaxed);
        self.publish(self.sessions().len());
    }

    /// Follows the session count and draining: the receiver sees every change.
    pub fn occupancy(&self) -> tokio::sync::watch::Receiver<Occupancy> {
        self.shared.occupancy.subscribe()
    }

    /// Tells followers the server holds `sessions` now.
    fn publish(&self, sessions: usize) {
        self.shared.occupancy.send_replace(Occupancy {
            sessions: u32::try_from(sessions).unwrap_or(u32::MAX),
            draining: self.shared.draining.load(Ordering::Relaxed),
        });
    }

    /// This server's load report (`Fleet.GetLoad`).
    pub fn load(&self) -> vademecum_proto::v1::ServerLoad {
        let cfg = &self.shared.config;
        let streams = self.shared.streams.lock().unwrap_or_else(|p| p.into_inner()).total;
        let tick_utilisation = cfg
            .session
            .ticking
            .as_ref()
            .map_or(0.0, |t| t.utilisation().into_iter().fold(f64::INFINITY, f64::min))
            .min(1.0);
        vademecum_proto::v1::ServerLoad {
            name: cfg.name.clone(),
            address: cfg.fleet.as_ref().map(|f| f.advertise.clone()).unwrap_or_default(),
            sessions: u32::try_from(self.sessions().len()).unwrap_or(u32::MAX),
            max_sessions: u32::try_from(cfg.max_sessions).unwrap_or(u32::MAX),
            tick_utilisation: if tick_utilisation.is_finite() { tick_utilisation } else { 0.0 },
            draining: self.shared.draining.load(Ordering::Relaxed),
            streams: streams[0] + streams[1],
        }
    }

    /// Why `owner` may not add a session to `sessions`, if it may not: the server is draining,
    /// holds its maximum, or (with authentication) the client its quota.
    fn session_quota(&self, sessions: &HashMap<String, Arc<Entry>>, owner: &Caller) -> Result<(), ServerError> {
        let cfg = &self.shared.config;
        if self.shared.draining.load(Ordering::Relaxed) {
            return Err(ServerError::Unavailable(
                "this server is draining: it takes no new session (ask another server, or one of its fleet)".into(),
            ));
        }
        if sessions.len() >= cfg.max_sessions {
            return Err(ServerError::Exhausted(format!(
                "the server runs its maximum of {} sessions",
                cfg.max_sessions
            )));
        }
        let mine = sessions.values().filter(|e| &e.owner == owner).count();
        if cfg.tokens.is_some() && mine >= cfg.client_sessions {
            return Err(ServerError::Exhausted(format!(
                "this client has its quota of {} sessions; close one first",
                cfg.client_sessions
            )));
        }
        Ok(())
    }

    fn sessions(&self) -> std::sync::MutexGuard<'_, HashMap<String, Arc<Entry>>> {
        self.shared.sessions.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn load_scene(&self, source: &SceneSource) -> Result<Scene, ServerError> {
        let scene = self.parse_scene(source)?;
        if !matches!(source, SceneSource::Builtin(_)) {
            self.check_mesh_paths(&scene)?;
        }
        Ok(scene)
    }

    /// Refuses a scene naming a mesh file — simulation or visual — outside the mesh root
    /// (before anything reads it).
    fn check_mesh_paths(&self, scene: &Scene) -> Result<(), ServerError> {
        let root = &self.shared.config.mesh_root;
        for (i, organ) in scene.spec.organs.iter().enumerate() {
            let files = [
                ("mesh.file", organ.mesh.file.as_ref()),
                ("visual.file", organ.visual.as_ref().map(|v| &v.file)),
            ];
            for (key, file) in files {
                if let Some(file) = file
                    && !inside(root, &scene.resolve_path(file))
                {
                    return Err(ServerError::Denied(format!(
                        "organs[{i}].{key} is outside the server's mesh root: a client's scene may only name mesh files under it (or use a built-in mesh)"
                    )));
                }
            }
        }
        Ok(())
    }

    fn parse_scene(&self, source: &SceneSource) -> Result<Scene, ServerError> {
        let cfg = &self.shared.config;
        match source {
            SceneSource::Inline(text) => {
                Scene::from_toml(text, cfg.scene_root.join("inline.toml")).map_err(|e| ServerError::Invalid(e.to_string()))
            }
            SceneSource::Builtin(name) => Scene::builtin(name).map_err(|e| ServerError::Invalid(e.to_string())),
            SceneSource::Path(rel) => {
                if !cfg.allow_paths {
                    return Err(ServerError::Denied(
                        "this server does not accept scene paths; send the scene text".into(),
                    ));
                }
                let path = under(&cfg.scene_root, rel, "scene path")?;
                if !inside(&cfg.scene_root, &path) {
                    return Err(ServerError::Denied(
                        "the scene path leaves the server's scene root (through a symbolic link)".into(),
                    ));
                }
                if !path.is_file() {
                    return Err(ServerError::NotFound(format!("no scene file '{}' on the server", clip(rel))));
                }
                Scene::load(&path).map_err(|e| ServerError::Invalid(e.to_string()))
            }
        }
    }

    /// The folder of the bundle of `digest` in the store, fetched from the bundle source
    /// first if the store does not hold it; refused unless its manifest hashes to `digest`.
    fn pinned(&self, organ: &str, digest: &str) -> Result<PathBuf, ServerError> {
        let cfg = &self.shared.config;
        let hex = store::parse_digest(digest).map_err(|e| ServerError::Invalid(format!("bundle_digests[{}]: {e}", clip(organ))))?;
        let Some(dir) = &cfg.bundle_store else {
            return Err(ServerError::Precondition(
                "this server has no bundle store (serve --bundle-store): ask for bundles by bundle_dir".into(),
            ));
        };
        let held = |d: &Path| store::path(d, hex).join(vademecum_engine::bundle::MANIFEST).is_file();
        if !held(dir)
            && let Some(source) = &cfg.bundle_source
        {
            // single flight: the first asker fetches, the others wait for it, then find it held
            let flight = self
                .shared
                .fetching
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .entry(hex.to_string())
                .or_default()
                .clone();
            let fetched = {
                let _one = flight.lock().unwrap_or_else(|p| p.into_inner());
                if held(dir) {
                    Ok(())
                } else {
                    crate::bundle_fetch::fetch(source, hex, dir, cfg.bundle_fetch).map(drop)
                }
            };
            let mut fetching = self.shared.fetching.lock().unwrap_or_else(|p| p.into_inner());
            // the last one out forgets the digest (the map holds one, every waiter one)
            if Arc::strong_count(&flight) <= 2 {
                fetching.remove(hex);
            }
            drop(fetching);
            fetched.map_err(|e| ServerError::Precondition(format!("organ '{}': bundle {digest}: {e}", clip(organ))))?;
        }
        store::open(dir, digest).map_err(|e| ServerError::Precondition(format!("organ '{}': {e}", clip(organ))))
    }

    /// The loaded bundle at `path`, from the cache or from disk.
    fn bundle(&self, path: &Path) -> Result<Arc<LoadedBundle>, ServerError> {
        let key = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
        if let Some(b) = self
            .shared
            .bundles
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(&key)
            .and_then(Weak::upgrade)
        {
            return Ok(b);
        }
        let b = Arc::new(bundle::load_bundle(path).map_err(|e| ServerError::Precondition(e.to_string()))?);
        let mut cache = self.shared.bundles.lock().unwrap_or_else(|p| p.into_inner());
        cache.retain(|_, w| w.strong_count() > 0);
        cache.insert(key, Arc::downgrade(&b));
        Ok(b)
    }

    /// Creates a session (blocking: reads scenes, meshes and bundles; call it off the
    /// runtime with `spawn_blocking`).
    ///
    /// `haptic`: `None`, no haptic channel; `Some("")`, a channel named after the session id;
    /// `Some(name)`, that channel.
    pub fn create(
        &self,
        owner: Caller,
        source: SceneSource,
        bundles_from: BundleSource<'_>,
        label: String,
        haptic: Option<&str>,
    ) -> Result<Arc<Entry>, ServerError> {
        let cfg = &self.shared.config;
        if label.chars().count() > 64 {
            return Err(ServerError::Invalid("label is longer than 64 characters".into()));
        }
        self.session_quota(&self.sessions(), &owner)?;
        let _preparing = Preparing::take(&self.shared.preparing, cfg.max_preparing)?;
        let scene = Arc::new(self.load_scene(&source)?);
        if !matches!(source, SceneSource::Builtin(_)) {
            // what a client's scene costs, from its settings, before a byte is spent on it
            for i in 0..scene.spec.organs.len() {
                if let Some(cells) = scene.builtin_cells(i).filter(|&c| c > cfg.max_scene_cells) {
                    return Err(ServerError::Exhausted(format!(
                        "organ '{}': its built-in mesh would have {cells} cells, more than the {} this server prepares for a client's scene",
                        clip(&scene.spec.organs[i].name),
                        cfg.max_scene_cells
                    )));
                }
            }
        }
        let dir = match bundles_from {
            BundleSource::Dir(bundle_dir) => {
                let dir = under(&cfg.bundle_root, bundle_dir, "bundle folder")?;
                if !inside(&cfg.bundle_root, &dir) {
                    return Err(ServerError::Denied(
                        "the bundle folder leaves the server's bundle root (through a symbolic link)".into(),
                    ));
                }
                Some(dir)
            }
            BundleSource::Pinned(digests) => {
                let organs: Vec<&str> = scene.spec.organs.iter().map(|o| o.name.as_str()).collect();
                if let Some(other) = digests.keys().find(|k| !organs.contains(&k.as_str())) {
                    return Err(ServerError::Invalid(format!(
                        "bundle_digests names '{}', which is not an organ of the scene ({})",
                        clip(other),
                        organs.join(", ")
                    )));
                }
                None
            }
        };
        let mut bundles = Vec::new();
        for i in 0..scene.spec.organs.len() {
            let name = &scene.spec.organs[i].name;
            let path = match (&dir, bundles_from) {
                (Some(dir), _) => dir.join(format!("{name}.bundle")),
                (None, BundleSource::Pinned(digests)) => {
                    let digest = digests
                        .get(name)
                        .ok_or_else(|| ServerError::Invalid(format!("bundle_digests names no bundle for organ '{name}'")))?;
                    self.pinned(name, digest)?
                }
                (None, BundleSource::Dir(_)) => unreachable!("a folder is resolved above"),
            };
            let b = self.bundle(&path)?;
            let mesh = scene.organ_mesh(i).map_err(|e| ServerError::Invalid(e.to_string()))?;
            bundle::check_matches(&path, &b.manifest, &scene, &mesh).map_err(|e| ServerError::Precondition(e.to_string()))?;
            bundles.push(b);
        }
        let n = self.shared.next.fetch_add(1, Ordering::Relaxed);
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        // in a fleet, ids start with the server's name: unique across the fleet
        let id = match &cfg.fleet {
            Some(_) => format!("{}-s{n}-{nanos:08x}", cfg.name),
            None => format!("s{n}-{nanos:08x}"),
        };
        let mut session_cfg = cfg.session.clone();
        if let Some(name) = haptic {
            let name = if name.is_empty() { id.as_str() } else { name };
            let channel = HapticChannel::new(name).map_err(|e| ServerError::Invalid(e.to_string()))?;
            // the channel and, for a scene with several tools, each tool's (`CHANNEL.NAME`)
            let names = channel_names(&channel, &scene)?;
            {
                let mut owners = self.shared.channels.lock().unwrap_or_else(|p| p.into_inner());
                if let Some(taken) = names.iter().find(|n| owners.get(*n).is_some_and(|o| *o != owner)) {
                    return Err(ServerError::Denied(format!(
                        "haptic channel '{}' belongs to another client of this server (a channel stays with the client that first opened it, so that a device bridge attached to it never drives another client's session): pick another name",
                        clip(taken)
                    )));
                }
                for n in &names {
                    owners.entry(n.clone()).or_insert_with(|| owner.clone());
                }
            }
            if self.sessions().values().any(|e| {
                e.session
                    .config()
                    .haptic
                    .as_ref()
                    .and_then(|h| channel_names(&h.channel, e.session.scene()).ok())
                    .is_some_and(|theirs| theirs.iter().any(|n| names.contains(n)))
            }) {
                return Err(ServerError::Precondition(format!(
                    "haptic channel '{name}' is in use by another session of this server; close it or pick another name"
                )));
            }
            session_cfg.haptic = Some(match &cfg.session.haptic {
                Some(h) => HapticConfig { channel, ..h.clone() },
                None => HapticConfig {
                    wait: cfg.haptic_wait.unwrap_or_default(),
                    ..HapticConfig::new(channel)
                },
            });
        }
        let session = Session::start(id.clone(), scene, bundles, session_cfg).map_err(|e| match e {
            SessionError::Haptic { .. } => ServerError::Precondition(e.to_string()),
            SessionError::Pipeline(_) | SessionError::ToolChannel(_) | SessionError::Hand { .. } => ServerError::Invalid(e.to_string()),
            SessionError::Ticking(_) => ServerError::Exhausted(e.to_string()),
        })?;
        let entry = Arc::new(Entry {
            owner,
            label,
            session,
            interacting: AtomicU32::new(0),
            viewers: AtomicU32::new(0),
            closed: tokio::sync::watch::channel(false).0,
        });
        let mut sessions = self.sessions();
        self.session_quota(&sessions, &entry.owner)?;
        sessions.insert(id, entry.clone());
        self.publish(sessions.len());
        Ok(entry)
    }

    /// The caller's session `id`.
    pub fn get(&self, owner: &Caller, id: &str) -> Result<Arc<Entry>, ServerError> {
        match self.sessions().get(id) {
            Some(e) if &e.owner == owner => Ok(e.clone()),
            _ => Err(ServerError::UnknownSession(id.to_string())),
        }
    }

    /// The caller's sessions, by id.
    pub fn list(&self, owner: &Caller) -> Vec<Arc<Entry>> {
        let mut v: Vec<_> = self.sessions().values().filter(|e| &e.owner == owner).cloned().collect();
        v.sort_by(|a, b| a.session.id().cmp(b.session.id()));
        v
    }

    /// Every session (metrics).
    pub fn all(&self) -> Vec<Arc<Entry>> {
        let mut v: Vec<_> = self.sessions().values().cloned().collect();
        v.sort_by(|a, b| a.session.id().cmp(b.session.id()));
        v
    }

    /// Removes the caller's session `id`, stops its threads and ends its streams. The
    /// session's memory goes when its last stream lets go of it.
    pub fn close(&self, owner: &Caller, id: &str) -> Result<Arc<Entry>, ServerError> {
        let entry = self.get(owner, id)?;
        let mut sessions = self.sessions();
        sessions.remove(id);
        self.publish(sessions.len());
        drop(sessions);
        entry.session.stop();
        entry.closed.send_replace(true);
        Ok(entry)
    }

    /// Closes every session (shutdown).
    pub fn close_all(&self) {
        let all: Vec<_> = self.sessions().drain().map(|(_, e)| e).collect();
        self.publish(0);
        for e in all {
            e.session.stop();
            e.closed.send_replace(true);
        }
    }
}

/// The haptic channel names a session on `channel` answers or reserves: the channel itself and,
/// for a scene with several tools, each tool's ([`crate::session::tool_channels`]).
fn channel_names(channel: &HapticChannel, scene: &Scene) -> Result<Vec<String>, ServerError> {
    let mut names = vec![channel.name().to_string()];
    let tools = crate::session::tool_channels(channel, scene).map_err(|e| ServerError::Invalid(e.to_string()))?;
    names.extend(tools.into_iter().map(|(_, c)| c.name().to_string()).filter(|n| n != channel.name()));
    Ok(names)
}
