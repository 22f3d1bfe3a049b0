//! What the commands that take a scene share: the scene the arguments name (a file or a
//! built-in), and the memory a solve or build may use.

use vademecum_engine::scene::Scene;

use crate::cli::SceneSource;

/// Loads the scene named by the arguments.
pub(crate) fn load_scene(source: &SceneSource) -> anyhow::Result<Scene> {
    Ok(match &source.scene {
        Some(p) => Scene::load(p)?,
        None => Scene::builtin(&source.builtin)?,
    })
}

/// The memory a solve may use (bytes): `--max-memory` (GB = 10⁹ bytes, refused unless
/// positive), else what the kernel says is available (`MemAvailable` of `/proc/meminfo`), else
/// no limit.
pub(crate) fn memory_limit(max_memory_gb: Option<f64>) -> anyhow::Result<Option<u64>> {
    match max_memory_gb {
        Some(gb) if gb.is_finite() && gb > 0.0 => Ok(Some((gb * 1e9) as u64)),
        Some(gb) => anyhow::bail!("--max-memory must be a positive number of GB, got {gb}"),
        None => Ok(std::fs::read_to_string("/proc/meminfo").ok().and_then(|t| mem_available(&t))),
    }
}

/// `MemAvailable` of a `/proc/meminfo` text, in bytes.
fn mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_memory_limit_is_the_option_or_what_meminfo_says() {
        let text = "MemTotal:        8000000 kB\nMemFree:          100000 kB\nMemAvailable:    6000000 kB\n";
        assert_eq!(mem_available(text), Some(6_000_000 * 1024));
        assert_eq!(mem_available("MemTotal: 1 kB\n"), None);
        assert_eq!(memory_limit(Some(2.5)).unwrap(), Some(2_500_000_000));
        assert!(memory_limit(Some(-1.0)).unwrap_err().to_string().contains("positive"));
        assert!(memory_limit(Some(f64::NAN)).is_err());
    }
}
