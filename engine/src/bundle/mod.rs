//! Bundles: the on-disk form of a built vademecum. A bundle is a folder holding
//!
//! - `manifest.json` — format name and version, what was built (kind, organ, sizes), how
//!   (build report), from what (SHA-256 of the scene text and of the mesh), and for every
//!   array its file, shape, dtype and SHA-256;
//! - `scene.toml` — the scene it was built from, verbatim;
//! - one `.npy` file per array (NumPy-readable: `numpy.load("F.npy")`).
//!
//! Reading verifies every checksum (the scene's too), every `.npy` header strictly
//! ([`npy`]), shapes and the format version, and reads only regular files whose size fits
//! their manifest entry (no symbolic links, devices or oversized files), so a damaged,
//! truncated, foreign or hostile bundle is refused with a message naming the file, never
//! loaded half-way.
//!
//! [`store`]: bundles published under the SHA-256 of their manifest (content-addressed).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use npyz::WriterBuilder;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// The `format` field of every manifest.
pub const FORMAT: &str = "vademecum-bundle";
/// The manifest version this build writes.
///
/// - 1: the vademecum (modes, load patches, local compliances, the large-deformation
///   lattice).
/// - 2: adds what a cutting session needs that the modes do not give (`cut_basis`, for bare
///   enrichment). Version 1 bundles still load: they have none of it.
pub const VERSION: u32 = 2;
/// The oldest manifest version this build reads.
pub const OLDEST_VERSION: u32 = 1;
/// The manifest's file name.
pub const MANIFEST: &str = "manifest.json";

/// Largest manifest read (bytes).
const MAX_MANIFEST_BYTES: u64 = 1 << 20;

mod loaded;
pub mod npy;
pub mod store;

pub use loaded::{CutBasis, InfoError, KIND, LoadedBundle, check_matches, load_bundle};
pub(crate) use loaded::{TEAR_ARRAYS, tear_prefix};

/// Why a bundle could not be written or read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BundleError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The folder has no manifest, or the manifest is not a vademecum manifest.
    #[error("{path} is not a vademecum bundle ({why}); build one with `vademecum build <scene>`")]
    NotABundle {
        /// The folder or manifest.
        path: PathBuf,
        /// What is wrong.
        why: String,
    },
    /// The bundle was written by another format version.
    #[error("{path}: bundle format version {found}, this build reads versions 1 to {supported}; rebuild it with `vademecum build`")]
    Version {
        /// The manifest.
        path: PathBuf,
        /// Version found.
        found: u32,
        /// Version supported.
        supported: u32,
    },
    /// An array file does not match its checksum (damaged or edited).
    #[error("{path}: checksum mismatch (expected {expected}, found {found}); the bundle is damaged, rebuild it")]
    Checksum {
        /// The array file.
        path: PathBuf,
        /// SHA-256 in the manifest.
        expected: String,
        /// SHA-256 of the file.
        found: String,
    },
    /// An array is malformed (bad header, wrong shape or dtype, missing entry).
    #[error("{path}: {message}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The bundle was built for another scene or mesh than the one it is used with.
    #[error("bundle {path} was built from another {what} (bundle {expected}…, here {found}…); rebuild it for this scene")]
    Mismatch {
        /// The bundle folder.
        path: PathBuf,
        /// "scene" or "mesh".
        what: &'static str,
        /// Hash prefix recorded in the bundle.
        expected: String,
        /// Hash prefix of what it is used with.
        found: String,
    },
}

/// One array of a bundle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArrayEntry {
    /// File name inside the bundle.
    pub file: String,
    /// Shape (row-major).
    pub shape: Vec<u64>,
    /// NumPy dtype string (`<f8`, `<i8`).
    pub dtype: String,
    /// SHA-256 of the file, hex.
    pub sha256: String,
}

/// The manifest of a bundle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Always [`FORMAT`].
    pub format: String,
    /// Format version ([`VERSION`]).
    pub version: u32,
    /// What the bundle holds (`pgd-linear`).
    pub kind: String,
    /// The vademecum version that wrote it.
    pub created_by: String,
    /// Scene name.
    pub scene: String,
    /// Organ name.
    pub organ: String,
    /// SHA-256 of the scene text.
    pub scene_sha256: String,
    /// SHA-256 of the mesh (see [`mesh_hash`]).
    pub mesh_sha256: String,
    /// Kind-specific facts (sizes, build report), free-form JSON.
    pub info: serde_json::Value,
    /// The arrays, by name.
    pub arrays: BTreeMap<String, ArrayEntry>,
}

impl Manifest {
    /// The manifest of a bundle of `kind` for organ `organ` of `scene` on `mesh`, written by
    /// this version, with no array yet (`bundle::write` adds them): the scene text and the mesh
    /// pinned by their SHA-256.
    pub fn new(kind: &str, scene: &crate::scene::Scene, organ: &str, mesh: &crate::mesh::Mesh, info: serde_json::Value) -> Self {
        Self {
            format: FORMAT.into(),
            version: VERSION,
            kind: kind.into(),
            created_by: format!("vademecum {}", env!("CARGO_PKG_VERSION")),
            scene: scene.spec.scene.name.clone(),
            organ: organ.into(),
            scene_sha256: sha256_hex(scene.source.as_bytes()),
            mesh_sha256: mesh_hash(mesh),
            info,
            arrays: Default::default(),
        }
    }
}

/// An array to write: f64, f32 or i64 data with a shape.
#[derive(Debug, Clone, Copy)]
pub enum ArrayData<'a> {
    /// Floating-point data.
    F64(&'a [f64]),
    /// Single-precision data (modes: their rounding, ~6e-8 relative, is far below any
    /// accuracy a vademecum is built to).
    F32(&'a [f32]),
    /// Integer data.
    I64(&'a [i64]),
}

/// Hex SHA-256 of bytes.
pub fn sha256_hex(bytes: &[u8]) -> String {
    let d = Sha256::digest(bytes);
    d.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 identifying a mesh: node coordinates (f64, little endian), cell kind and
/// connectivity (u64). Two meshes hash equal only if they are the same mesh in the same
/// units and numbering.
pub fn mesh_hash(mesh: &crate::mesh::Mesh) -> String {
    let mut h = Sha256::new();
    h.update(mesh.kind.name().as_bytes());
    for p in &mesh.nodes {
        for x in p {
            h.update(x.to_le_bytes());
        }
    }
    for c in &mesh.cells {
        h.update((*c as u64).to_le_bytes());
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> BundleError + '_ {
    move |source| BundleError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes a bundle to `dir`: every array as `.npy`, the scene text, and the manifest listing
/// their SHA-256 (written last: a bundle without its manifest is no bundle).
///
/// Written whole into a fresh folder beside `dir` first, every file created new (nothing is
/// written through a link, nor into a file that was there), then swapped in: the folder (or
/// link) at `dir` is renamed away, the new one renamed to `dir`, the old one removed (its
/// links removed, never followed). A rebuild therefore never writes into the old bundle's
/// files, wherever they point, and a reader sees the old bundle or the new one whole (or,
/// between the two renames, none).
pub fn write(
    dir: &Path,
    mut manifest: Manifest,
    scene_text: &str,
    arrays: &[(&str, Vec<u64>, ArrayData<'_>)],
) -> Result<Manifest, BundleError> {
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&parent).map_err(io(&parent))?;
    let name = dir
        .file_name()
        .map_or_else(|| "bundle".into(), |n| n.to_string_lossy().into_owned());
    let unique = format!(
        "{}-{}",
        std::process::id(),
        WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    );
    let fresh = parent.join(format!(".{name}.writing-{unique}"));
    std::fs::create_dir(&fresh).map_err(io(&fresh))?;
    let written = write_new(&fresh, &mut manifest, scene_text, arrays).and_then(|()| {
        let old = parent.join(format!(".{name}.old-{unique}"));
        let had_old = match std::fs::rename(dir, &old) {
            Ok(()) => true,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
            Err(e) => return Err(io(dir)(e)),
        };
        std::fs::rename(&fresh, dir).map_err(io(dir))?;
        if had_old {
            // a link is removed, never followed
            let gone = match std::fs::symlink_metadata(&old) {
                Ok(m) if m.is_dir() => std::fs::remove_dir_all(&old),
                _ => std::fs::remove_file(&old),
            };
            if let Err(e) = gone {
                tracing::warn!("cannot remove the replaced bundle {}: {e}", old.display());
            }
        }
        Ok(())
    });
    if written.is_err() {
        let _ = std::fs::remove_dir_all(&fresh);
    }
    written.map(|()| manifest)
}

/// Writes the files of a bundle into the new, empty folder `dir` (see [`write`]).
fn write_new(dir: &Path, manifest: &mut Manifest, scene_text: &str, arrays: &[(&str, Vec<u64>, ArrayData<'_>)]) -> Result<(), BundleError> {
    let create = |path: &Path, bytes: &[u8]| -> Result<(), BundleError> {
        use std::io::Write;
        std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
            .and_then(|mut f| f.write_all(bytes))
            .map_err(io(path))
    };
    manifest.arrays.clear();
    for (name, shape, data) in arrays {
        let file = format!("{name}.npy");
        let path = dir.join(&file);
        let mut buf = Vec::new();
        let dtype = match data {
            ArrayData::F64(v) => encode_npy(&mut buf, shape, v, &path, "<f8")?,
            ArrayData::F32(v) => encode_npy(&mut buf, shape, v, &path, "<f4")?,
            ArrayData::I64(v) => encode_npy(&mut buf, shape, v, &path, "<i8")?,
        };
        create(&path, &buf)?;
        manifest.arrays.insert(
            name.to_string(),
            ArrayEntry {
                file,
                shape: shape.clone(),
                dtype: dtype.into(),
                sha256: sha256_hex(&buf),
            },
        );
    }
    create(&dir.join("scene.toml"), scene_text.as_bytes())?;
    let path = dir.join(MANIFEST);
    let json = serde_json::to_string_pretty(&*manifest).map_err(|e| BundleError::Malformed {
        path: path.clone(),
        message: e.to_string(),
    })?;
    create(&path, json.as_bytes())
}

/// Encodes `data` as a `.npy` file of `shape` into `buf`, returning its dtype string.
fn encode_npy<T: npyz::Serialize + npyz::AutoSerialize + Copy>(
    buf: &mut Vec<u8>,
    shape: &[u64],
    data: &[T],
    path: &Path,
    dtype: &'static str,
) -> Result<&'static str, BundleError> {
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(shape)
        .writer(buf)
        .begin_nd()
        .map_err(io(path))?;
    w.extend(data.iter().copied()).map_err(io(path))?;
    w.finish().map_err(io(path))?;
    Ok(dtype)
}

/// Reads and checks a bundle's manifest (format and version), without loading arrays.
pub fn read_manifest(dir: &Path) -> Result<Manifest, BundleError> {
    let path = dir.join(MANIFEST);
    if !dir.is_dir() {
        return Err(BundleError::NotABundle {
            path: dir.to_path_buf(),
            why: "no such folder".into(),
        });
    }
    let text = read_regular(&path, MAX_MANIFEST_BYTES)
        .ok()
        .and_then(|b| String::from_utf8(b).ok())
        .ok_or_else(|| BundleError::NotABundle {
            path: dir.to_path_buf(),
            why: format!("no readable {MANIFEST} (a regular file of at most 1 MiB)"),
        })?;
    let raw: serde_json::Value = serde_json::from_str(&text).map_err(|e| BundleError::NotABundle {
        path: path.clone(),
        why: format!("invalid JSON: {e}"),
    })?;
    if raw.get("format").and_then(|f| f.as_str()) != Some(FORMAT) {
        return Err(BundleError::NotABundle {
            path: path.clone(),
            why: format!("its format is not \"{FORMAT}\""),
        });
    }
    let found = raw.get("version").and_then(|v| v.as_u64()).unwrap_or(0) as u32;
    if !(OLDEST_VERSION..=VERSION).contains(&found) {
        return Err(BundleError::Version {
            path,
            found,
            supported: VERSION,
        });
    }
    let manifest: Manifest = serde_json::from_value(raw).map_err(|e| BundleError::Malformed {
        path,
        message: format!("invalid manifest: {e}"),
    })?;
    read_scene(dir, &manifest)?;
    Ok(manifest)
}

/// A loaded array.
#[derive(Debug, Clone, PartialEq)]
pub enum Array {
    /// f64 data.
    F64(Vec<f64>),
    /// f32 data.
    F32(Vec<f32>),
    /// i64 data.
    I64(Vec<i64>),
}

/// Loads array `name` of a bundle, verifying its checksum, header, dtype and shape.
pub fn read_array(dir: &Path, manifest: &Manifest, name: &str) -> Result<(Vec<u64>, Array), BundleError> {
    let entry = manifest.arrays.get(name).ok_or_else(|| BundleError::Malformed {
        path: dir.join(MANIFEST),
        message: format!("the manifest lists no array '{name}'"),
    })?;
    let bad = |path: &Path, message: String| BundleError::Malformed {
        path: path.to_path_buf(),
        message,
    };
    let mut parts = Path::new(&entry.file).components();
    if !matches!((parts.next(), parts.next()), (Some(std::path::Component::Normal(_)), None)) {
        return Err(bad(
            &dir.join(MANIFEST),
            format!(
                "array '{name}' names the file '{}', which is not a plain file name in the bundle",
                entry.file
            ),
        ));
    }
    let path = dir.join(&entry.file);
    if npy::itemsize(&entry.dtype).is_none() {
        return Err(bad(&path, format!("unsupported dtype {}", entry.dtype)));
    }
    let data_len = npy::data_len(&entry.dtype, &entry.shape).ok_or_else(|| bad(&path, format!("shape {:?} is too large", entry.shape)))?;
    // the header (12 bytes of preamble at most, then the dict) comes on top of the data
    let bytes = read_verified(&path, data_len.saturating_add(npy::MAX_HEADER as u64 + 12), &entry.sha256)?;
    let header = npy::parse_header(&bytes).map_err(|e| bad(&path, format!("not a valid .npy file: {e}")))?;
    if header.descr != entry.dtype {
        return Err(bad(&path, format!("dtype {}, manifest says {}", header.descr, entry.dtype)));
    }
    if header.shape != entry.shape {
        return Err(bad(&path, format!("shape {:?}, manifest says {:?}", header.shape, entry.shape)));
    }
    let body = &bytes[header.data_offset..];
    if body.len() as u64 != data_len {
        return Err(bad(
            &path,
            format!(
                "{} data bytes for shape {:?} of {} (expected {data_len})",
                body.len(),
                header.shape,
                header.descr
            ),
        ));
    }
    let arr = match entry.dtype.as_str() {
        "<f8" => Array::F64(
            body.chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect(),
        ),
        "<f4" => Array::F32(
            body.chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
                .collect(),
        ),
        _ => Array::I64(
            body.chunks_exact(8)
                .map(|c| i64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect(),
        ),
    };
    Ok((header.shape, arr))
}

/// Reads a bundle file that must be a regular file (not a symbolic link, a device or a
/// folder) of at most `max` bytes, checking both before reading anything.
fn read_regular(path: &Path, max: u64) -> Result<Vec<u8>, BundleError> {
    let meta = std::fs::symlink_metadata(path).map_err(io(path))?;
    let bad = |message: String| BundleError::Malformed {
        path: path.to_path_buf(),
        message,
    };
    if meta.file_type().is_symlink() {
        return Err(bad(
            "is a symbolic link; bundle files must be regular files inside the bundle".into()
        ));
    }
    if !meta.is_file() {
        return Err(bad("is not a regular file".into()));
    }
    if meta.len() > max {
        return Err(bad(format!("{} bytes, more than the {max} its manifest entry allows", meta.len())));
    }
    let bytes = std::fs::read(path).map_err(io(path))?;
    if bytes.len() as u64 > max {
        return Err(bad("grew while being read".into()));
    }
    Ok(bytes)
}

/// [`read_regular`], then the SHA-256 of what was read checked against `sha256` (hex).
fn read_verified(path: &Path, max: u64, sha256: &str) -> Result<Vec<u8>, BundleError> {
    let bytes = read_regular(path, max)?;
    let found = sha256_hex(&bytes);
    if found != sha256 {
        return Err(BundleError::Checksum {
            path: path.to_path_buf(),
            expected: sha256.to_string(),
            found,
        });
    }
    Ok(bytes)
}

/// Largest scene text a bundle may carry (bytes), as the server's request limit.
const MAX_SCENE_BYTES: u64 = 1 << 20;

/// The bundle's `scene.toml`, checked against the manifest's `scene_sha256`.
pub fn read_scene(dir: &Path, manifest: &Manifest) -> Result<String, BundleError> {
    let path = dir.join("scene.toml");
    let bytes = read_verified(&path, MAX_SCENE_BYTES, &manifest.scene_sha256)?;
    String::from_utf8(bytes).map_err(|_| BundleError::Malformed {
        path,
        message: "is not UTF-8 text".into(),
    })
}

/// Loads a floating-point array as f64 (f32 data is widened exactly).
pub fn read_f64(dir: &Path, manifest: &Manifest, name: &str) -> Result<(Vec<u64>, Vec<f64>), BundleError> {
    match read_array(dir, manifest, name)? {
        (s, Array::F64(v)) => Ok((s, v)),
        (s, Array::F32(v)) => Ok((s, v.into_iter().map(f64::from).collect())),
        _ => Err(BundleError::Malformed {
            path: dir.join(name),
            message: format!("array '{name}' is not floating-point"),
        }),
    }
}

/// Loads an i64 array.
pub fn read_i64(dir: &Path, manifest: &Manifest, name: &str) -> Result<(Vec<u64>, Vec<i64>), BundleError> {
    match read_array(dir, manifest, name)? {
        (s, Array::I64(v)) => Ok((s, v)),
        _ => Err(BundleError::Malformed {
            path: dir.join(name),
            message: format!("array '{name}' is not i64"),
        }),
    }
}
