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

/// The scene `text` with each `(key, value)` of `edits` set
/// ([`vademecum_engine::scene::keys::with_keys`]: a path that leads nowhere fails the test).
pub fn with_keys(text: &str, edits: &[(&str, toml::Value)]) -> String {
    let values: Vec<String> = edits.iter().map(|(_, v)| v.to_string()).collect();
    let edits: Vec<(&str, &str)> = edits.iter().zip(&values).map(|((k, _), v)| (*k, v.as_str())).collect();
    vademecum_engine::scene::keys::with_keys(text, &edits).unwrap_or_else(|e| panic!("{e}"))
}

/// The smooth outward normal of the organ's contact surface at surface node `node`.
pub fn node_normal(b: &vademecum_engine::bundle::LoadedBundle, node: usize) -> [f64; 3] {
    use vademecum_engine::contact::{Surface, SurfacePoint};
    let surface = Surface::new(&b.nodes, b.surface.clone());
    let (t, a) = b
        .surface
        .iter()
        .enumerate()
        .find_map(|(t, tri)| tri.iter().position(|&n| n == node).map(|a| (t, a)))
        .expect("a surface node");
    let mut weights = [0.0; 3];
    weights[a] = 1.0;
    surface.normal_at(&SurfacePoint {
        triangle: t,
        weights,
        point: b.nodes[node],
    })
}
