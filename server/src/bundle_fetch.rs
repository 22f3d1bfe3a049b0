//! Fetching a bundle by digest from a bundle source (`serve --bundle-source URL`: object
//! storage or any static HTTP(S) server holding a published store's `sha256/<hex>/` folders)
//! into the server's bundle store, checked before it is used: the manifest must hash to the
//! digest asked for, and every file to what the manifest says.
//!
//! A fetch is bounded: it ends by its deadline ([`FetchLimits::deadline`], the whole fetch,
//! every request included: a source that hangs holds a `CreateSession` no longer), reads at
//! most [`FetchLimits::max_bytes`] in all (what the manifest declares is checked against it
//! before a byte of an array is read), and streams every file to disk while hashing it (the
//! server's memory does not grow with a bundle's size). It writes into a folder of its own
//! that is renamed into the store once whole and checked; the registry lets one fetch run
//! per digest at a time (`Registry`: the other sessions asking for it wait for it).

use std::io::{Read, Write};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use sha2::{Digest, Sha256};
use vademecum_engine::bundle::{self, Manifest, store};

/// Largest manifest fetched (bytes), as a bundle's reader reads.
const MAX_MANIFEST: u64 = 1 << 20;
/// Largest scene text fetched (bytes).
const MAX_SCENE: u64 = 16 << 20;

/// How long and how much one fetch may take.
#[derive(Debug, Clone, Copy)]
pub struct FetchLimits {
    /// The whole fetch's deadline, from its first request.
    pub deadline: Duration,
    /// Bytes of one bundle, its files together.
    pub max_bytes: u64,
}

impl Default for FetchLimits {
    /// 120 s and 2 GiB (the largest mesh a reader takes: `engine::files::MAX_MESH_BYTES`).
    fn default() -> Self {
        Self {
            deadline: Duration::from_secs(120),
            max_bytes: 2 << 30,
        }
    }
}

/// Why a bundle could not be fetched. Its message names the source's URL (the operator's,
/// not a client's input); a store error may name a folder of the server's, which a client sees
/// by its last component only (`error::for_client`).
#[derive(Debug, thiserror::Error)]
pub enum FetchError {
    /// The fetch ran past its deadline ([`FetchLimits::deadline`]).
    #[error("GET {url}: the fetch took longer than its {} s deadline", deadline.as_secs())]
    Late {
        /// The request under way.
        url: String,
        /// The whole fetch's deadline.
        deadline: Duration,
    },
    /// The source refused or failed a request, or its body could not be read.
    #[error("GET {url}: {reason}")]
    Get {
        /// The request.
        url: String,
        /// What the HTTP client said.
        reason: String,
    },
    /// A fetched file does not hash to what the digest or the manifest says.
    #[error("{url} {what}")]
    Mismatch {
        /// The file.
        url: String,
        /// How it differs.
        what: String,
    },
    /// The fetched manifest cannot be taken: not JSON, a file name that is not a plain name,
    /// an array too large to hold, more bytes than a fetch may read.
    #[error("{0}")]
    Manifest(String),
    /// The store could not take the bundle (a folder or a file could not be written).
    #[error("cannot {action} {what}: {source}")]
    Store {
        /// `create` or `write`.
        action: &'static str,
        /// A file name inside the bundle, or the store's folder.
        what: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The fetched bundle could not be moved into place.
    #[error(transparent)]
    Place(#[from] bundle::BundleError),
}

/// One fetch's client: its deadline and what it has left to read.
struct Fetch {
    agent: ureq::Agent,
    until: Instant,
    deadline: Duration,
    left: u64,
}

impl Fetch {
    fn new(limits: FetchLimits) -> Self {
        let agent: ureq::Agent = ureq::Agent::config_builder().timeout_global(Some(limits.deadline)).build().into();
        Self {
            agent,
            until: Instant::now() + limits.deadline,
            deadline: limits.deadline,
            left: limits.max_bytes,
        }
    }

    /// GETs `url`, at most `limit` bytes, into `out`; returns its SHA-256 (hex).
    fn get(&mut self, url: &str, limit: u64, out: &mut impl Write) -> Result<String, FetchError> {
        let late = || FetchError::Late {
            url: url.to_string(),
            deadline: self.deadline,
        };
        let failed = |reason: String| FetchError::Get {
            url: url.to_string(),
            reason,
        };
        let remaining = self.until.checked_duration_since(Instant::now()).ok_or_else(late)?;
        let limit = limit.min(self.left);
        let mut r = self
            .agent
            .get(url)
            .config()
            .timeout_global(Some(remaining))
            .build()
            .call()
            .map_err(|e| match e {
                ureq::Error::Timeout(_) => late(),
                e => failed(e.to_string()),
            })?;
        let mut body = r.body_mut().with_config().limit(limit).reader();
        let mut hash = Sha256::new();
        let mut buf = vec![0u8; 1 << 16];
        let mut read = 0u64;
        loop {
            let n = body.read(&mut buf).map_err(|e| {
                if Instant::now() >= self.until {
                    late()
                } else {
                    failed(e.to_string())
                }
            })?;
            if n == 0 {
                break;
            }
            read += n as u64;
            hash.update(&buf[..n]);
            out.write_all(&buf[..n]).map_err(|source| FetchError::Store {
                action: "write",
                what: format!("what {url} sent"),
                source,
            })?;
        }
        self.left -= read.min(self.left);
        Ok(format!("{:x}", hash.finalize()))
    }
}

/// A file name listed by a fetched manifest, refused unless it is a plain name (written into
/// the store: no path may leave the bundle's folder).
fn plain(name: &str) -> Result<&str, FetchError> {
    let mut parts = Path::new(name).components();
    match (parts.next(), parts.next()) {
        (Some(Component::Normal(_)), None) => Ok(name),
        _ => Err(FetchError::Manifest(format!(
            "the fetched manifest names the file '{name}', not a plain file name"
        ))),
    }
}

/// Creates `path` for writing, refusing anything already there (a link included).
fn create_new(path: &Path) -> Result<std::fs::File, FetchError> {
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(|source| write_error(path.file_name().unwrap_or_default().to_string_lossy().into_owned(), source))
}

/// `what` (a file of the bundle) could not be written.
fn write_error(what: String, source: std::io::Error) -> FetchError {
    FetchError::Store {
        action: "write",
        what,
        source,
    }
}

/// The folder `path` of the store could not be created.
fn create_error(path: &Path) -> impl FnOnce(std::io::Error) -> FetchError + '_ {
    move |source| FetchError::Store {
        action: "create",
        what: path.display().to_string(),
        source,
    }
}

/// The size of array `name` as its manifest entry declares it.
fn declared_size(name: &str, entry: &bundle::ArrayEntry) -> Result<u64, FetchError> {
    bundle::npy::data_len(&entry.dtype, &entry.shape)
        .ok_or_else(|| FetchError::Manifest(format!("array {name}: shape {:?} is too large", entry.shape)))
}

/// Fetches bundle `sha256:<hex>` from `source` into `store` within `limits` and returns its
/// folder there.
pub fn fetch(source: &str, hex: &str, store_dir: &Path, limits: FetchLimits) -> Result<PathBuf, FetchError> {
    let base = format!("{}/sha256/{hex}", source.trim_end_matches('/'));
    let mut f = Fetch::new(limits);
    let mut manifest_bytes = Vec::new();
    let found = f.get(&format!("{base}/{}", bundle::MANIFEST), MAX_MANIFEST, &mut manifest_bytes)?;
    if found != hex {
        return Err(FetchError::Mismatch {
            url: format!("{base}/manifest.json"),
            what: format!("hashes to sha256:{found}, not the sha256:{hex} asked for: not served"),
        });
    }
    let manifest: Manifest =
        serde_json::from_slice(&manifest_bytes).map_err(|e| FetchError::Manifest(format!("{base}/manifest.json: {e}")))?;
    // what the manifest declares, against the limit, before any array is read
    let mut declared = manifest_bytes.len() as u64;
    for (name, entry) in &manifest.arrays {
        declared = declared.saturating_add(declared_size(name, entry)?);
    }
    if declared > limits.max_bytes {
        return Err(FetchError::Manifest(format!(
            "{base}: the manifest declares {declared} bytes of arrays, more than the {} a fetch may read",
            limits.max_bytes
        )));
    }
    let parent = store_dir.join("sha256");
    std::fs::create_dir_all(&parent).map_err(create_error(&parent))?;
    // a folder of this fetch's own: no other fetch, in this process or another, writes there
    static FETCHES: AtomicU64 = AtomicU64::new(0);
    let incoming = parent.join(format!(
        ".fetching-{hex}-{}-{}",
        std::process::id(),
        FETCHES.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir(&incoming).map_err(create_error(&incoming))?;
    let mismatch = |url: String| FetchError::Mismatch {
        url,
        what: "does not hash to what its manifest says".into(),
    };
    let fetched = (|| {
        for (name, entry) in &manifest.arrays {
            let file = plain(&entry.file)?;
            let size = declared_size(name, entry)?;
            let mut out = std::io::BufWriter::new(create_new(&incoming.join(file))?);
            let sha = f.get(&format!("{base}/{file}"), size + bundle::npy::MAX_HEADER as u64 + 12, &mut out)?;
            out.flush().map_err(|e| write_error(file.to_string(), e))?;
            if sha != entry.sha256 {
                return Err(mismatch(format!("{base}/{file}")));
            }
        }
        let mut out = create_new(&incoming.join("scene.toml"))?;
        if f.get(&format!("{base}/scene.toml"), MAX_SCENE, &mut out)? != manifest.scene_sha256 {
            return Err(mismatch(format!("{base}/scene.toml")));
        }
        // the manifest last: a fetch interrupted before it leaves no bundle
        create_new(&incoming.join(bundle::MANIFEST))?
            .write_all(&manifest_bytes)
            .map_err(|e| write_error("the manifest".into(), e))?;
        Ok(store::into_place(&incoming, &store::path(store_dir, hex), hex)?)
    })();
    if fetched.is_err() {
        let _ = std::fs::remove_dir_all(&incoming);
    }
    fetched?;
    tracing::info!(digest = %format!("sha256:{hex}"), from = %source, "bundle fetched into the store");
    Ok(store::path(store_dir, hex))
}
