//! Sharded offline builds: the exact responses `U = K⁻¹ F_L` of the load states, solved in
//! shards on separate machines (`vademecum build --shard I/N`, a Kubernetes Indexed Job) and
//! merged into the bundle (`vademecum merge`), which is then the one
//! [`ModesFrom::Snapshots`](super::ModesFrom::Snapshots) builds in one process.
//!
//! The greedy PGD does not shard: each mode is a fixed point that corrects the modes before
//! it. The snapshots do: every column of `U` is one solve with the factorization, independent
//! of the others, and the truncated SVD of `U` (the recompression the PGD's modes go through
//! anyway) is the best basis of each size. Shard `i` of `n` solves whole blocks of columns
//! ([`shard_range`](super::shard_range)), in the blocks of a single-process pass, so
//! the merged `U` — and every mode, error and compliance computed from it — is the same to the
//! bit.
//!
//! A shard is written in the bundle container ([`crate::bundle`]: a manifest with the scene's
//! and the mesh's SHA-256, checksummed arrays), kind [`SHARD_KIND`], one array `U`
//! (`columns × n_free`), in `<out>/<organ>.shard-<i>-of-<n>`.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::bundle::{self, ArrayData, BundleError, Manifest};
use crate::scene::Scene;

/// The bundle kind of a shard.
pub const SHARD_KIND: &str = "pgd-snapshots-shard";

/// Which shard of how many (0-based: `index < count`, as Kubernetes' `JOB_COMPLETION_INDEX`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShardOf {
    /// This shard, `0..count`.
    pub index: usize,
    /// How many shards.
    pub count: usize,
}

impl std::str::FromStr for ShardOf {
    type Err = String;

    /// `I/N`, with `0 ≤ I < N ≤ 4096`.
    fn from_str(s: &str) -> Result<Self, String> {
        let (i, n) = s.split_once('/').ok_or_else(|| format!("'{s}' is not I/N (e.g. 0/3)"))?;
        let (index, count) = (
            i.trim().parse::<usize>().map_err(|_| format!("'{i}' is not a shard index"))?,
            n.trim().parse::<usize>().map_err(|_| format!("'{n}' is not a shard count"))?,
        );
        if !(1..=4096).contains(&count) || index >= count {
            return Err(format!("shard {index}/{count}: the index runs from 0 to N-1, N from 1 to 4096"));
        }
        Ok(Self { index, count })
    }
}

/// What a shard's manifest says of it (`info`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardInfo {
    /// Which shard.
    pub shard: ShardOf,
    /// Its load states, `start..end`.
    pub start: usize,
    /// One past its last load state.
    pub end: usize,
    /// Load states of the organ in all.
    pub load_states: usize,
    /// Free equations (rows of `U`).
    pub n_free: usize,
    /// The load footprint's radius the load states were made with (m).
    pub load_radius: f64,
}

/// Why shards cannot be merged.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    /// Reading or writing a shard failed.
    #[error(transparent)]
    Bundle(#[from] BundleError),
    /// Shards are missing.
    #[error("organ '{organ}': {found} of {count} shards in {dir} (missing: {missing}); run `vademecum build --shard I/{count}` for each")]
    Missing {
        /// The organ.
        organ: String,
        /// The folder searched.
        dir: PathBuf,
        /// Shards found.
        found: usize,
        /// Shards expected.
        count: usize,
        /// The missing indices.
        missing: String,
    },
    /// No shard at all.
    #[error("organ '{organ}': no shard in {dir} (<organ>.shard-I-of-N folders written by `vademecum build --shard`)")]
    None {
        /// The organ.
        organ: String,
        /// The folder searched.
        dir: PathBuf,
    },
    /// A shard does not belong with the others or with the scene.
    #[error("{path}: {why}")]
    Mismatch {
        /// The shard.
        path: PathBuf,
        /// What differs.
        why: String,
    },
}

/// The folder of shard `of` of organ `organ` in `out`.
pub fn shard_dir(out: &Path, organ: &str, of: ShardOf) -> PathBuf {
    out.join(format!("{organ}.shard-{}-of-{}", of.index, of.count))
}

/// Writes shard `info.shard` of organ `index` of `scene`: the columns `u` (`n_free` values per
/// load state of `info.start..info.end`).
pub fn write_shard(out: &Path, scene: &Scene, index: usize, info: &ShardInfo, u: &[f64]) -> Result<PathBuf, BundleError> {
    let organ = &scene.spec.organs[index].name;
    let mesh = scene.organ_mesh(index).map_err(|e| BundleError::Malformed {
        path: out.to_path_buf(),
        message: e.to_string(),
    })?;
    let dir = shard_dir(out, organ, info.shard);
    let info_json = serde_json::to_value(info).unwrap_or(serde_json::Value::Null);
    let manifest = Manifest::new(SHARD_KIND, scene, organ, &mesh, info_json);
    let shape = vec![(info.end - info.start) as u64, info.n_free as u64];
    bundle::write(&dir, manifest, &scene.source, &[("U", shape, ArrayData::F64(u))])?;
    Ok(dir)
}

/// The shard folders of organ `organ` in `out`, by index, with their count (`None`: none).
fn find(out: &Path, organ: &str) -> Result<Option<(usize, Vec<Option<PathBuf>>)>, ShardError> {
    let prefix = format!("{organ}.shard-");
    let mut found: Vec<(ShardOf, PathBuf)> = Vec::new();
    let entries = match std::fs::read_dir(out) {
        Ok(entries) => entries,
        // no folder yet: no shard in it (the merge says which command writes them)
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => {
            return Err(BundleError::Io {
                path: out.to_path_buf(),
                source,
            }
            .into());
        }
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(rest) = name.strip_prefix(&prefix) else { continue };
        let Some((i, n)) = rest.split_once("-of-") else { continue };
        if let Ok(of) = format!("{i}/{n}").parse::<ShardOf>() {
            found.push((of, e.path()));
        }
    }
    let Some(count) = found.iter().map(|(of, _)| of.count).max() else {
        return Ok(None);
    };
    if let Some((_, p)) = found.iter().find(|(of, _)| of.count != count) {
        return Err(ShardError::Mismatch {
            path: p.clone(),
            why: format!("a shard of another split than 1/{count} (remove the stale shards)"),
        });
    }
    let mut by_index = vec![None; count];
    for (of, p) in found {
        by_index[of.index] = Some(p);
    }
    Ok(Some((count, by_index)))
}

/// Whether every shard of organ `index` of `scene` is in `out` (each complete: a shard's
/// manifest is written last).
pub fn all_present(out: &Path, scene: &Scene, index: usize) -> bool {
    let organ = &scene.spec.organs[index].name;
    matches!(find(out, organ), Ok(Some((_, by_index))) if by_index.iter().all(|p| p.as_ref().is_some_and(|p| p.join(bundle::MANIFEST).is_file())))
}

/// Reads the shards of organ `index` of `scene` from `out` and assembles `U`
/// (`n_free × load states`, column-major), checking that they are all there, cover every load
/// state once, and were solved from this scene's text and this organ's mesh. Returns `U` and
/// the shard folders.
pub fn read_shards(out: &Path, scene: &Scene, index: usize) -> Result<(Vec<f64>, Vec<PathBuf>), ShardError> {
    let organ = scene.spec.organs[index].name.clone();
    let (count, by_index) = find(out, &organ)?.ok_or_else(|| ShardError::None {
        organ: organ.clone(),
        dir: out.to_path_buf(),
    })?;
    let missing: Vec<String> = (0..count).filter(|&i| by_index[i].is_none()).map(|i| i.to_string()).collect();
    if !missing.is_empty() {
        return Err(ShardError::Missing {
            organ,
            dir: out.to_path_buf(),
            found: count - missing.len(),
            count,
            missing: missing.join(", "),
        });
    }
    let mesh = scene.organ_mesh(index).map_err(|e| ShardError::Mismatch {
        path: out.to_path_buf(),
        why: e.to_string(),
    })?;
    let (scene_sha, mesh_sha) = (bundle::sha256_hex(scene.source.as_bytes()), bundle::mesh_hash(&mesh));
    let dirs: Vec<PathBuf> = by_index.into_iter().flatten().collect();
    let mut u = Vec::new();
    let mut first: Option<ShardInfo> = None;
    for (i, dir) in dirs.iter().enumerate() {
        let mismatch = |why: String| ShardError::Mismatch { path: dir.clone(), why };
        let m = bundle::read_manifest(dir)?;
        if m.kind != SHARD_KIND {
            return Err(mismatch(format!("a '{}' bundle, not a shard", m.kind)));
        }
        if m.scene_sha256 != scene_sha {
            return Err(mismatch("solved from another scene text (its scene.toml differs)".into()));
        }
        if m.mesh_sha256 != mesh_sha {
            return Err(mismatch(format!("solved on another mesh than organ '{organ}''s")));
        }
        let info: ShardInfo = serde_json::from_value(m.info.clone()).map_err(|e| mismatch(format!("unreadable shard info: {e}")))?;
        if info.shard != (ShardOf { index: i, count }) {
            return Err(mismatch(format!("says it is shard {}/{}", info.shard.index, info.shard.count)));
        }
        let at = first.as_ref().map_or(0, |_| u.len() / info.n_free.max(1));
        if let Some(f) = &first
            && (f.load_states, f.n_free, f.load_radius) != (info.load_states, info.n_free, info.load_radius)
        {
            return Err(mismatch(format!(
                "{} load states of {} equations (footprint {} m), shard 0 has {} of {} ({} m)",
                info.load_states, info.n_free, info.load_radius, f.load_states, f.n_free, f.load_radius
            )));
        }
        if info.start != at || info.end < info.start || info.end > info.load_states {
            return Err(mismatch(format!(
                "covers load states {}..{}, the shards before it end at {at}",
                info.start, info.end
            )));
        }
        let (shape, data) = bundle::read_f64(dir, &m, "U")?;
        if shape != [(info.end - info.start) as u64, info.n_free as u64] {
            return Err(mismatch(format!("U has shape {shape:?}")));
        }
        // a solve never gives a non-finite displacement: such a value is damage (the checksum
        // only says the file is as its manifest says), and it would poison the merge's SVD
        if let Some(k) = data.iter().position(|x| !x.is_finite()) {
            return Err(mismatch(format!(
                "U holds a non-finite value ({}) at load state {}, equation {}: solve this shard again",
                data[k],
                info.start + k / info.n_free.max(1),
                k % info.n_free.max(1)
            )));
        }
        u.extend_from_slice(&data);
        first.get_or_insert(info);
    }
    let info = first.expect("at least one shard");
    if u.len() != info.load_states * info.n_free {
        return Err(ShardError::Mismatch {
            path: dirs[count - 1].clone(),
            why: format!(
                "the shards cover {} of {} load states",
                u.len() / info.n_free.max(1),
                info.load_states
            ),
        });
    }
    Ok((u, dirs))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::offline::shard_range;

    #[test]
    fn shards_parse_as_zero_based_index_over_count() {
        assert_eq!("0/3".parse::<ShardOf>(), Ok(ShardOf { index: 0, count: 3 }));
        assert_eq!("2/3".parse::<ShardOf>(), Ok(ShardOf { index: 2, count: 3 }));
        for bad in ["3/3", "1", "a/3", "0/0", "-1/2", "0/5000"] {
            assert!(bad.parse::<ShardOf>().is_err(), "{bad}");
        }
    }

    #[test]
    fn shard_ranges_are_whole_blocks_that_cover_every_load_state_once() {
        for p in [1, 63, 64, 65, 927, 2000] {
            for n in 1..=7 {
                let mut next = 0;
                for i in 0..n {
                    let r = shard_range(p, i, n);
                    assert_eq!(r.start, next, "p {p}, {i}/{n}");
                    assert!(r.start.is_multiple_of(crate::pgd::brute::BLOCK) || r.start == p);
                    next = r.end;
                }
                assert_eq!(next, p, "p {p}, n {n}");
            }
        }
    }
}
