//! Helpers shared by the engine's integration tests.
#![allow(dead_code)]

pub mod mutate;
pub mod two_sides;

use std::path::PathBuf;

use vademecum_engine::scene::Scene;

/// The repository's root.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The shared data folder (`VADEMECUM_SHARED`, else `../shared` beside the checkout), if it
/// holds the meshes. When it does not, a test says it is skipped — except under CI (`CI` set),
/// where the data must be there and its absence fails the test instead of passing silently.
pub fn shared_data() -> Option<PathBuf> {
    let dir = std::env::var_os("VADEMECUM_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join("../shared"));
    if dir.join("data/meshes").is_dir() {
        return Some(dir);
    }
    if std::env::var_os("CI").is_some() {
        panic!(
            "the shared data is not at {} but CI is set: CI must run with ../shared beside the checkout (or VADEMECUM_SHARED)",
            dir.display()
        );
    }
    eprintln!("skipped: shared data not found at {} (set VADEMECUM_SHARED)", dir.display());
    None
}

/// A scene of `scenes/` whose mesh path points into the shared data, rewritten to the shared
/// folder actually found.
pub fn shared_scene(file: &str, shared: &std::path::Path) -> Scene {
    let path = repo_root().join("scenes").join(file);
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text.replace("../../shared/", &format!("{}/", shared.display()));
    Scene::from_toml(&text, &path).unwrap()
}

/// The scene `text` with each `(key, value)` of `edits` set, the key a dotted path from the
/// root with array indices (`organs[0].mesh.divisions`, `fidelity.tearing.grasp_sites`,
/// `tools[0].max_force`; `tools[0]` replaces the whole element). The table holding the key
/// must exist (a test never edits a scene it misreads); the key itself may be new. Comments
/// and layout are not kept.
pub fn with_keys(text: &str, edits: &[(&str, toml::Value)]) -> String {
    let mut root: toml::Table = toml::from_str(text).expect("the scene is TOML");
    for (path, value) in edits {
        let mut segments: Vec<&str> = path.split('.').collect();
        let last = segments.pop().expect("a key");
        let mut table = &mut root;
        for seg in segments {
            let (name, index) = match seg.split_once('[') {
                Some((n, i)) => (n, Some(i.trim_end_matches(']').parse::<usize>().expect("an index"))),
                None => (seg, None),
            };
            let next = table
                .get_mut(name)
                .unwrap_or_else(|| panic!("the scene has no `{name}` on the way to `{path}`"));
            let next = match index {
                Some(i) => next
                    .as_array_mut()
                    .and_then(|a| a.get_mut(i))
                    .unwrap_or_else(|| panic!("the scene has no `{name}[{i}]` on the way to `{path}`")),
                None => next,
            };
            table = next.as_table_mut().unwrap_or_else(|| panic!("`{seg}` in `{path}` is no table"));
        }
        match last.split_once('[') {
            // an element of an array of tables, replaced whole
            Some((name, i)) => {
                let i: usize = i.trim_end_matches(']').parse().expect("an index");
                let slot = table
                    .get_mut(name)
                    .and_then(|a| a.as_array_mut())
                    .and_then(|a| a.get_mut(i))
                    .unwrap_or_else(|| panic!("the scene has no `{last}` to replace"));
                *slot = value.clone();
            }
            None => {
                table.insert(last.to_string(), value.clone());
            }
        }
    }
    toml::to_string(&root).expect("a table serialises")
}
