//! A content-addressed bundle store: each bundle in `<store>/sha256/<hex>/`, where `<hex>` is
//! the SHA-256 of its `manifest.json` — its digest, written `sha256:<hex>`. The manifest lists
//! the SHA-256 of every array and of the scene text, so the digest pins every byte a session
//! reads: a bundle is built once, published under its digest, and a server that is asked for
//! a digest serves that bundle or none ([`open`] refuses any other).
//!
//! Publishing copies into a hidden folder of the store, checks it, then renames it into place
//! (atomic on one file system), so a reader never sees half a bundle; publishing the same
//! bundle twice is a no-op.

use std::path::{Path, PathBuf};

use super::{BundleError, MANIFEST, read_manifest, read_regular, sha256_hex};

/// Largest manifest hashed (bytes), as [`read_manifest`] reads.
const MAX_MANIFEST_BYTES: u64 = 1 << 20;

/// A bundle digest that is not `sha256:<64 lower-case hex digits>` (the digest is quoted
/// clipped to 80 characters).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DigestError {
    /// It does not start with `sha256:`.
    #[error("bundle digest '{0}' does not start with 'sha256:'")]
    NoPrefix(String),
    /// What follows is not 64 lower-case hex digits.
    #[error("bundle digest '{0}' is not sha256: and 64 lower-case hex digits")]
    NotHex(String),
}

/// The hex SHA-256 of a digest written `sha256:<64 hex digits>` (lower case).
pub fn parse_digest(digest: &str) -> Result<&str, DigestError> {
    let hex = digest.strip_prefix("sha256:").ok_or_else(|| DigestError::NoPrefix(clip(digest)))?;
    if hex.len() != 64 || !hex.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b)) {
        return Err(DigestError::NotHex(clip(digest)));
    }
    Ok(hex)
}

fn clip(s: &str) -> String {
    s.chars().take(80).collect()
}

/// The digest of the bundle in `dir`: `sha256:` and the SHA-256 of its manifest file.
pub fn digest(dir: &Path) -> Result<String, BundleError> {
    let bytes = read_regular(&dir.join(MANIFEST), MAX_MANIFEST_BYTES)?;
    Ok(format!("sha256:{}", sha256_hex(&bytes)))
}

/// Where the bundle of digest `hex` lives in `store`.
pub fn path(store: &Path, hex: &str) -> PathBuf {
    store.join("sha256").join(hex)
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> BundleError + '_ {
    move |source| BundleError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Publishes the bundle in `dir` into `store` (after checking it whole: every checksum, as a
/// session would load it) and returns its digest.
pub fn publish(dir: &Path, store: &Path) -> Result<String, BundleError> {
    let manifest = read_manifest(dir)?;
    for name in manifest.arrays.keys() {
        super::read_array(dir, &manifest, name)?;
    }
    let digest = digest(dir)?;
    let hex = parse_digest(&digest).expect("a digest this module wrote");
    let target = path(store, hex);
    if target.join(MANIFEST).is_file() {
        return Ok(digest);
    }
    let parent = store.join("sha256");
    std::fs::create_dir_all(&parent).map_err(io(&parent))?;
    let incoming = parent.join(format!(".incoming-{hex}-{}", std::process::id()));
    if incoming.exists() {
        std::fs::remove_dir_all(&incoming).map_err(io(&incoming))?;
    }
    std::fs::create_dir(&incoming).map_err(io(&incoming))?;
    // the manifest last: a copy interrupted before it has none and is never read
    let mut files: Vec<String> = manifest.arrays.values().map(|e| e.file.clone()).collect();
    files.extend(["scene.toml".to_string(), MANIFEST.to_string()]);
    for f in &files {
        let from = dir.join(f);
        std::fs::copy(&from, incoming.join(f)).map_err(io(&from))?;
    }
    into_place(&incoming, &target, hex)?;
    Ok(digest)
}

/// Moves a complete bundle from `incoming` to `target` once its digest is `hex` (another
/// publisher may have put the same bundle there first: then `incoming` is dropped).
pub fn into_place(incoming: &Path, target: &Path, hex: &str) -> Result<(), BundleError> {
    let found = digest(incoming)?;
    if found != format!("sha256:{hex}") {
        let _ = std::fs::remove_dir_all(incoming);
        return Err(BundleError::Checksum {
            path: incoming.join(MANIFEST),
            expected: hex.to_string(),
            found: found.trim_start_matches("sha256:").to_string(),
        });
    }
    match std::fs::rename(incoming, target) {
        Ok(()) => Ok(()),
        Err(_) if target.join(MANIFEST).is_file() => {
            let _ = std::fs::remove_dir_all(incoming);
            Ok(())
        }
        Err(e) => Err(io(target)(e)),
    }
}

/// The bundle of digest `digest` in `store`, checked to be that bundle: its manifest hashes
/// to the digest (its arrays are checked against the manifest when loaded).
pub fn open(store: &Path, digest: &str) -> Result<PathBuf, BundleError> {
    let hex = parse_digest(digest).map_err(|e| BundleError::Malformed {
        path: store.to_path_buf(),
        message: e.to_string(),
    })?;
    let dir = path(store, hex);
    if !dir.join(MANIFEST).is_file() {
        return Err(BundleError::NotABundle {
            path: dir,
            why: format!("the store holds no bundle {digest}"),
        });
    }
    let found = self::digest(&dir)?;
    if found != digest {
        return Err(BundleError::Checksum {
            path: dir.join(MANIFEST),
            expected: hex.to_string(),
            found: found.trim_start_matches("sha256:").to_string(),
        });
    }
    Ok(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digests_are_sha256_and_64_lower_case_hex_digits() {
        let hex = "0123456789abcdef".repeat(4);
        assert_eq!(parse_digest(&format!("sha256:{hex}")), Ok(hex.as_str()));
        for bad in [
            hex.clone(),
            format!("sha256:{}", hex.to_uppercase()),
            format!("sha256:{}", &hex[1..]),
            "sha256:../../etc".into(),
        ] {
            assert!(parse_digest(&bad).is_err(), "{bad}");
        }
    }
}
