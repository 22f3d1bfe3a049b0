//! Mutation fuzzing of every reader a user or a client can feed: Gmsh (v1, v2 ASCII and
//! binary, v4.1), VTK (`.vtu`, legacy `.vtk`), scene TOML, and bundles (the `.npy` arrays and
//! the manifest, with their checksums forged so the parsers are reached). Each reader gets
//! thousands of mutants of the files in `tests/corpus/` (and of the built-in scenes and a
//! freshly written bundle) and must answer every one with a value or an error — never a panic.
//! The fuzzer's earlier findings each have a named test in `bad_input.rs` and `vademecum.rs`.

mod common;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use common::mutate::{Rng, mutate};
use vademecum_engine::mesh;
use vademecum_engine::pgd::PgdParams;
use vademecum_engine::pgd::offline::{self, BuildOptions};
use vademecum_engine::scene::Scene;

/// Mutants per corpus file: enough to reach every section of these small files many times
/// (a few seconds in all at the test profile's optimisation).
const MUTANTS: usize = 3000;

fn corpus(name: &str) -> Vec<u8> {
    std::fs::read(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/corpus").join(name)).unwrap()
}

/// Runs `read` on `MUTANTS` mutants of `seed_input`, failing with the reproducing seed and
/// mutant on a panic; returns how many were accepted.
fn fuzz(what: &str, seed_input: &[u8], seed: u64, mut read: impl FnMut(&[u8]) -> bool) -> usize {
    assert!(read(seed_input), "{what}: the corpus file itself must be accepted");
    let mut rng = Rng(seed);
    let mut accepted = 0;
    for i in 0..MUTANTS {
        let m = mutate(seed_input, &mut rng);
        match catch_unwind(AssertUnwindSafe(|| read(&m))) {
            Ok(ok) => accepted += usize::from(ok),
            Err(_) => {
                let path = std::env::temp_dir().join(format!("fuzz-{what}-{seed}-{i}"));
                let _ = std::fs::write(&path, &m);
                panic!("{what}: mutant {i} of seed {seed} panicked (saved to {})", path.display());
            }
        }
    }
    accepted
}

#[test]
fn gmsh_readers_never_panic() {
    for (file, seed) in [
        ("gmsh_v1.msh", 1),
        ("gmsh_v2.msh", 2),
        ("gmsh_v2_binary.msh", 3),
        ("gmsh_v41.msh", 4),
    ] {
        let n = fuzz(file, &corpus(file), seed, |b| mesh::gmsh::parse(b, Path::new(file)).is_ok());
        eprintln!("{file}: {n} of {MUTANTS} mutants accepted");
    }
}

#[test]
fn vtk_readers_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    for (file, seed) in [("tet.vtu", 5), ("tet.vtk", 6)] {
        let path = dir.path().join(file);
        let n = fuzz(file, &corpus(file), seed, |b| {
            std::fs::write(&path, b).unwrap();
            mesh::read(&path).is_ok()
        });
        eprintln!("{file}: {n} of {MUTANTS} mutants accepted");
    }
}

#[test]
fn scene_parsing_never_panics() {
    for (i, name) in vademecum_engine::scene::BUILTIN_NAMES.iter().enumerate() {
        let text = vademecum_engine::scene::builtin(name).unwrap();
        let n = fuzz(name, text.as_bytes(), 10 + i as u64, |b| {
            std::str::from_utf8(b).is_ok_and(|t| Scene::from_toml(t, "fuzz.toml").is_ok())
        });
        eprintln!("scene {name}: {n} of {MUTANTS} mutants accepted");
    }
}

/// Writes `bytes` as `file` of the bundle and forges its checksum in the manifest.
fn forge(dir: &Path, file: &str, bytes: &[u8]) {
    std::fs::write(dir.join(file), bytes).unwrap();
    let m = dir.join("manifest.json");
    let Ok(mut manifest) = serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(&m).unwrap()) else {
        return;
    };
    let name = file.trim_end_matches(".npy");
    if manifest["arrays"].get(name).is_some() {
        manifest["arrays"][name]["sha256"] = vademecum_engine::bundle::sha256_hex(bytes).into();
        std::fs::write(&m, serde_json::to_string_pretty(&manifest).unwrap()).unwrap();
    }
}

#[test]
fn bundle_loading_never_panics_even_with_forged_checksums() {
    let scene = Scene::builtin("patch").unwrap();
    let mut opts = BuildOptions::for_scene(&scene, true);
    opts.params = PgdParams {
        max_modes: 40,
        ..opts.params
    };
    let built = offline::build_organ(&scene, 0, &opts, &mut |_| {}).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("b");
    offline::write_bundle(&dir, &scene, &built).unwrap();
    let manifest = std::fs::read(dir.join("manifest.json")).unwrap();
    for (file, seed) in [("G.npy", 20), ("surface.npy", 21), ("load_nodes.npy", 22), ("manifest.json", 23)] {
        let good = std::fs::read(dir.join(file)).unwrap();
        let n = fuzz(file, &good, seed, |b| {
            std::fs::write(dir.join("manifest.json"), &manifest).unwrap();
            if file == "manifest.json" {
                std::fs::write(dir.join(file), b).unwrap();
            } else {
                forge(&dir, file, b);
            }
            let ok = offline::load_bundle(&dir).is_ok();
            std::fs::write(dir.join(file), &good).unwrap();
            ok
        });
        std::fs::write(dir.join("manifest.json"), &manifest).unwrap();
        eprintln!("bundle {file}: {n} of {MUTANTS} mutants accepted");
    }
}
