//! Mutation fuzzing of every reader a user or a client can feed: Gmsh (v1, v2 ASCII and
//! binary, v4.1), VTK (`.vtu`, legacy `.vtk`), Wavefront OBJ (read, embedded and split as a
//! visual surface), scene TOML, bundles (the `.npy` arrays and the manifest, with their
//! checksums forged so the parsers are reached; the cutting and tearing arrays too, each bundle
//! that loads then driven by a session's pipeline) and the shards of a sharded build with their
//! merge. Each reader gets mutants of the files in `tests/corpus/` (and of the built-in scenes
//! and freshly written bundles and shards) and must answer every one with a value or an error —
//! never a panic.
//! The fuzzer's earlier findings each have a named test in `bad_input.rs` and `vademecum.rs`.

use crate::common;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use common::mutate::{Rng, mutate};
use vademecum_engine::bundle;
use vademecum_engine::mesh;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pgd::PgdParams;
use vademecum_engine::scene::Scene;

/// Mutants per corpus file: enough to reach every section of these small files many times
/// (a few seconds in all at the test profile's optimisation).
const MUTANTS: usize = 3000;

fn corpus(name: &str) -> Vec<u8> {
    std::fs::read(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/corpus").join(name)).unwrap()
}

/// Runs `read` on `MUTANTS` mutants of `seed_input`, failing with the reproducing seed and
/// mutant on a panic; returns how many were accepted.
fn fuzz(what: &str, seed_input: &[u8], seed: u64, read: impl FnMut(&[u8]) -> bool) -> usize {
    fuzz_n(what, seed_input, seed, MUTANTS, read)
}

/// [`fuzz`] with `n` mutants (fewer where each one runs a solve or a session).
fn fuzz_n(what: &str, seed_input: &[u8], seed: u64, n: usize, mut read: impl FnMut(&[u8]) -> bool) -> usize {
    assert!(read(seed_input), "{what}: the corpus file itself must be accepted");
    let mut rng = Rng(seed);
    let mut accepted = 0;
    for i in 0..n {
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
            let ok = bundle::load_bundle(&dir).is_ok();
            std::fs::write(dir.join(file), &good).unwrap();
            ok
        });
        std::fs::write(dir.join("manifest.json"), &manifest).unwrap();
        eprintln!("bundle {file}: {n} of {MUTANTS} mutants accepted");
    }
}

#[test]
fn obj_reading_embedding_and_splitting_never_panic() {
    use vademecum_engine::mesh::procedural;
    use vademecum_engine::xfem::visual::{Embedding, VisualMesh};
    use vademecum_engine::xfem::{Enrichment, Plane, visual_split};
    // a surface read is then embedded in a block of tetrahedra and split by a plane across it,
    // as a co-rotational cutting session does with a scene's visual mesh
    let mesh = procedural::block_tet([0.05; 3], [0.9; 3], [3, 3, 3]);
    let plane = Plane {
        point: [0.43, 0.5, 0.5],
        normal: [1.0, 0.0, 0.0],
    };
    let crossed: Vec<usize> = Enrichment::cells_crossed_by(&mesh, &plane).into_iter().map(|(c, _)| c).collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.obj");
    let n = fuzz("box.obj", &corpus("box.obj"), 7, |b| {
        std::fs::write(&path, b).unwrap();
        let Ok(v) = VisualMesh::load_obj(&path, 1.0) else { return false };
        let _ = v.edges();
        let _ = Embedding::new(&mesh, &v.vertices);
        let _ = visual_split::split(&v, &mesh, &plane, &crossed);
        true
    });
    eprintln!("box.obj: {n} of {MUTANTS} mutants accepted");
}

/// A session's pipeline on a loaded bundle, ticked `ticks` times by each of the scene's tools
/// pressing into the middle of the organ (a blade across it, a grasper closed): what a client
/// of a server hosting the bundle would drive. Panics are the fuzzer's to catch. Whether a
/// session could be made of it (a session checks the tearing arrays against its scene).
fn drive(scene: &Scene, bundle: vademecum_engine::bundle::LoadedBundle, ticks: usize) -> bool {
    use vademecum_engine::pipeline::{Pipeline, ToolInput, ToolKind};
    let Ok(mut p) = Pipeline::for_scene(scene, &[std::sync::Arc::new(bundle)]) else {
        return false;
    };
    let (lo, hi) = scene.organ_mesh(0).unwrap().bounding_box();
    let mid: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
    for kind in [ToolKind::Probe, ToolKind::Scalpel, ToolKind::Grasper] {
        for t in 0..ticks {
            // from above the organ to its middle
            let s = t as f64 / ticks as f64;
            let mut at = mid;
            at[2] = hi[2] + 0.01 - s * (hi[2] + 0.01 - mid[2]);
            let tool = ToolInput {
                kind,
                position_m: [lo[0] - 0.01, at[1], at[2]],
                blade_end_m: [hi[0] + 0.01, at[1], at[2]],
                closure: 1.0,
                ..ToolInput::default()
            };
            let tool = if kind == ToolKind::Scalpel {
                tool
            } else {
                ToolInput { position_m: at, ..tool }
            };
            let _ = p.tick(&tool);
        }
    }
    true
}

/// The bundles of cutting (`patch_cut`: the enriched basis, `cut_*` arrays) and tearing
/// (`cube_tear`: the damage bases and grasp sites, `tear*` arrays), each array mutated with its
/// checksum forged so the readers are reached: loading answers with a bundle or an error, and a
/// bundle that loads runs a session's pipeline (probe, blade, grasper) without a panic.
#[test]
fn cutting_and_tearing_bundles_never_panic_when_loaded_or_run() {
    /// Mutants per array: each one that loads also runs a session for a few hundred ticks.
    const PER_ARRAY: usize = 60;
    for (name, prefixes, seed) in [("patch_cut", &["cut", "local"][..], 30u64), ("cube_tear", &["tear"][..], 40)] {
        let scene = Scene::builtin(name).unwrap();
        let built = offline::build_organ(&scene, 0, &BuildOptions::for_scene(&scene, true), &mut |_| {}).unwrap();
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("b");
        offline::write_bundle(&dir, &scene, &built).unwrap();
        let manifest = std::fs::read(dir.join("manifest.json")).unwrap();
        let json: serde_json::Value = serde_json::from_slice(&manifest).unwrap();
        let arrays: Vec<String> = json["arrays"]
            .as_object()
            .unwrap()
            .keys()
            .filter(|k| prefixes.iter().any(|p| k.starts_with(p)))
            .cloned()
            .collect();
        assert!(!arrays.is_empty(), "{name}: no {prefixes:?} arrays in {:?}", json["arrays"]);
        for (i, array) in arrays.iter().enumerate() {
            let file = format!("{array}.npy");
            let good = std::fs::read(dir.join(&file)).unwrap();
            let n = fuzz_n(&file, &good, seed + i as u64, PER_ARRAY, |b| {
                std::fs::write(dir.join("manifest.json"), &manifest).unwrap();
                forge(&dir, &file, b);
                let loaded = bundle::load_bundle(&dir);
                std::fs::write(dir.join(&file), &good).unwrap();
                std::fs::write(dir.join("manifest.json"), &manifest).unwrap();
                loaded.is_ok_and(|bundle| drive(&scene, bundle, 100))
            });
            eprintln!("{name} {file}: {n} of {PER_ARRAY} mutants made a session that ran");
            // the same with its values poked (header kept), so that most load and run
            let mut rng = Rng(seed + 100 + i as u64);
            let mut ran = 0;
            for k in 0..PER_ARRAY {
                let b = common::mutate::poke_npy_values(&good, &mut rng);
                forge(&dir, &file, &b);
                let outcome = catch_unwind(AssertUnwindSafe(|| {
                    bundle::load_bundle(&dir).is_ok_and(|bundle| drive(&scene, bundle, 100))
                }));
                std::fs::write(dir.join(&file), &good).unwrap();
                std::fs::write(dir.join("manifest.json"), &manifest).unwrap();
                match outcome {
                    Ok(loaded) => ran += usize::from(loaded),
                    Err(_) => {
                        let path = std::env::temp_dir().join(format!("fuzz-{name}-{file}-poked-{k}"));
                        let _ = std::fs::write(&path, &b);
                        panic!("{name} {file}: poked mutant {k} panicked (saved to {})", path.display());
                    }
                }
            }
            eprintln!("{name} {file}: {ran} of {PER_ARRAY} poked mutants made a session that ran");
        }
    }
}

/// The shards of a sharded build (`build --shard I/N`) mutated — their `U` arrays with the
/// checksum forged, and their manifests — are read and merged into a bundle or refused with an
/// error, never a panic (a NaN in `U` once panicked the SVD of the merge).
#[test]
fn shards_and_their_merge_never_panic() {
    use vademecum_engine::offline::ModesFrom;
    use vademecum_engine::offline::shard::{self, ShardInfo, ShardOf};
    const PER_FILE: usize = 150;
    let scene = Scene::builtin("patch").unwrap();
    let opts = BuildOptions::for_scene(&scene, true);
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path();
    let mut shard_dirs = Vec::new();
    for index in 0..2 {
        let of = ShardOf { index, count: 2 };
        let c = offline::solve_shard(&scene, 0, &opts, of, &mut |_| {}).unwrap();
        let info = ShardInfo {
            shard: of,
            start: c.range.start,
            end: c.range.end,
            load_states: c.load_states,
            n_free: c.n_free,
            load_radius: opts.load_radius,
        };
        shard_dirs.push(shard::write_shard(out, &scene, 0, &info, &c.u).unwrap());
    }
    let merge = || -> bool {
        let Ok((u, _)) = shard::read_shards(out, &scene, 0) else {
            return false;
        };
        offline::build_organ_from(&scene, 0, &opts, ModesFrom::Given(&u), &mut |_| {}).is_ok()
    };
    for (i, file) in ["U.npy", "manifest.json"].iter().enumerate() {
        let dir = &shard_dirs[1];
        let manifest = std::fs::read(dir.join("manifest.json")).unwrap();
        let good = std::fs::read(dir.join(file)).unwrap();
        let n = fuzz_n(file, &good, 50 + i as u64, PER_FILE, |b| {
            if *file == "manifest.json" {
                std::fs::write(dir.join(file), b).unwrap();
            } else {
                forge(dir, file, b);
            }
            let ok = merge();
            std::fs::write(dir.join(file), &good).unwrap();
            std::fs::write(dir.join("manifest.json"), &manifest).unwrap();
            ok
        });
        eprintln!("shard {file}: {n} of {PER_FILE} mutants merged");
    }
}

/// A tearing bundle holding one non-finite value in a float array (its checksum forged to
/// match, as damage or a hostile copy would) is refused when a session is made of it, with
/// what is wrong — not served as NaN forces that the tick would then zero. (The value-poking
/// fuzzer above found `tear_singular_values` accepted with a NaN.)
#[test]
fn a_tearing_bundle_with_a_non_finite_value_is_refused_when_a_session_is_made() {
    use vademecum_engine::pipeline::Pipeline;
    let scene = Scene::builtin("cube_tear").unwrap();
    let built = offline::build_organ(&scene, 0, &BuildOptions::for_scene(&scene, true), &mut |_| {}).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("b");
    offline::write_bundle(&dir, &scene, &built).unwrap();
    let manifest = std::fs::read(dir.join("manifest.json")).unwrap();
    let good = bundle::load_bundle(&dir).unwrap();
    assert!(Pipeline::for_scene(&scene, &[std::sync::Arc::new(good)]).is_ok());
    for array in [
        "tear_pod_basis",
        "tear_singular_values",
        "tear_spatial",
        "tear_factors",
        "tear_ritz_v",
        "tear_lo",
    ] {
        let file = format!("{array}.npy");
        let bytes = std::fs::read(dir.join(&file)).unwrap();
        // the first value after the header, in the array's own width
        let data = bytes.iter().position(|&b| b == b'\n').unwrap() + 1;
        let header = String::from_utf8_lossy(&bytes[..data]);
        let mut bad = bytes.clone();
        if header.contains("<f4") {
            bad[data..data + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        } else {
            assert!(header.contains("<f8"), "{array}: {header}");
            bad[data..data + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        }
        forge(&dir, &file, &bad);
        let refused = match bundle::load_bundle(&dir) {
            Err(e) => e.to_string(),
            Ok(b) => match Pipeline::for_scene(&scene, &[std::sync::Arc::new(b)]) {
                Err(e) => e.to_string(),
                Ok(_) => panic!("{array} with a NaN made a session"),
            },
        };
        assert!(
            refused.contains("non-finite") || refused.contains("not finite"),
            "{array}: {refused}"
        );
        std::fs::write(dir.join(&file), &bytes).unwrap();
        std::fs::write(dir.join("manifest.json"), &manifest).unwrap();
    }
}
