//! Fetching a bundle by digest from a bundle source (`serve --bundle-source URL`: object
//! storage or any static HTTP(S) server holding a published store's `sha256/<hex>/` folders)
//! into the server's bundle store, checked before it is used: the manifest must hash to the
//! digest asked for, and every file to what the manifest says.

use std::path::{Component, Path, PathBuf};

use vademecum_engine::bundle::{self, Manifest, store};

/// Largest manifest fetched (bytes), as a bundle's reader reads.
const MAX_MANIFEST: u64 = 1 << 20;
/// Largest scene text fetched (bytes).
const MAX_SCENE: u64 = 16 << 20;

/// GETs `url` into memory, at most `limit` bytes.
fn get(url: &str, limit: u64) -> Result<Vec<u8>, String> {
    let mut r = ureq::get(url).call().map_err(|e| format!("GET {url}: {e}"))?;
    r.body_mut()
        .with_config()
        .limit(limit)
        .read_to_vec()
        .map_err(|e| format!("GET {url}: {e}"))
}

/// A file name listed by a fetched manifest, refused unless it is a plain name (written into
/// the store: no path may leave the bundle's folder).
fn plain(name: &str) -> Result<&str, String> {
    let mut parts = Path::new(name).components();
    match (parts.next(), parts.next()) {
        (Some(Component::Normal(_)), None) => Ok(name),
        _ => Err(format!("the fetched manifest names the file '{name}', not a plain file name")),
    }
}

/// Fetches bundle `sha256:<hex>` from `source` into `store` and returns its folder there.
pub fn fetch(source: &str, hex: &str, store_dir: &Path) -> Result<PathBuf, String> {
    let base = format!("{}/sha256/{hex}", source.trim_end_matches('/'));
    let manifest_bytes = get(&format!("{base}/{}", bundle::MANIFEST), MAX_MANIFEST)?;
    let found = bundle::sha256_hex(&manifest_bytes);
    if found != hex {
        return Err(format!(
            "{base}/manifest.json hashes to sha256:{found}, not the sha256:{hex} asked for: not served"
        ));
    }
    let manifest: Manifest = serde_json::from_slice(&manifest_bytes).map_err(|e| format!("{base}/manifest.json: {e}"))?;
    let parent = store_dir.join("sha256");
    std::fs::create_dir_all(&parent).map_err(|e| format!("cannot create {}: {e}", parent.display()))?;
    let incoming = parent.join(format!(".fetching-{hex}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&incoming);
    std::fs::create_dir(&incoming).map_err(|e| format!("cannot create {}: {e}", incoming.display()))?;
    let fetched = (|| {
        for (name, entry) in &manifest.arrays {
            let file = plain(&entry.file)?;
            let size = bundle::npy::data_len(&entry.dtype, &entry.shape)
                .ok_or_else(|| format!("array {name}: shape {:?} is too large", entry.shape))?;
            let bytes = get(&format!("{base}/{file}"), size + bundle::npy::MAX_HEADER as u64 + 12)?;
            if bundle::sha256_hex(&bytes) != entry.sha256 {
                return Err(format!("{base}/{file} does not hash to what its manifest says"));
            }
            std::fs::write(incoming.join(file), bytes).map_err(|e| format!("cannot write {file}: {e}"))?;
        }
        let scene = get(&format!("{base}/scene.toml"), MAX_SCENE)?;
        if bundle::sha256_hex(&scene) != manifest.scene_sha256 {
            return Err(format!("{base}/scene.toml does not hash to what its manifest says"));
        }
        std::fs::write(incoming.join("scene.toml"), scene).map_err(|e| format!("cannot write scene.toml: {e}"))?;
        // the manifest last: a fetch interrupted before it leaves no bundle
        std::fs::write(incoming.join(bundle::MANIFEST), &manifest_bytes).map_err(|e| format!("cannot write the manifest: {e}"))?;
        store::into_place(&incoming, &store::path(store_dir, hex), hex).map_err(|e| e.to_string())
    })();
    if fetched.is_err() {
        let _ = std::fs::remove_dir_all(&incoming);
    }
    fetched?;
    tracing::info!(digest = %format!("sha256:{hex}"), from = %source, "bundle fetched into the store");
    Ok(store::path(store_dir, hex))
}
