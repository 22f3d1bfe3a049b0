//! A scene pays only for the effects it names: a palpation scene's bundle holds no
//! large-deformation lattice, no cutting basis and no tearing arrays, and its session's
//! pipeline carries no cutting or tearing state and does no work for them; the same organ
//! naming large deformations, and a tearing scene, do hold theirs (so the checks can fail);
//! an organ cut while it deforms largely holds the lattice and the cut's state, nothing else.

use crate::common;

use std::path::Path;
use std::sync::Arc;

use vademecum_engine::bundle;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::Pipeline;
use vademecum_engine::scene::{self, Scene};

/// The scene built, written and loaded back as a session would; with the bundle's files.
fn bundle(scene: &Scene) -> (Arc<LoadedBundle>, Vec<String>, u64) {
    let built = offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), scene, &built).unwrap();
    let (files, bytes) = files(dir.path());
    (Arc::new(bundle::load_bundle(dir.path()).unwrap()), files, bytes)
}

fn files(dir: &Path) -> (Vec<String>, u64) {
    let mut names = Vec::new();
    let mut bytes = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        names.push(e.file_name().to_string_lossy().into_owned());
        bytes += e.metadata().unwrap().len();
    }
    names.sort();
    (names, bytes)
}

/// The built-in organ, coarse, with `model` and `deformation`.
fn organ(model: &str, deformation: &str) -> Scene {
    let large: toml::Table = toml::from_str("positions = 2\nload_steps = 2\nmodes = 3").unwrap();
    let text = common::with_keys(
        scene::builtin("organ").unwrap(),
        &[
            ("organs[0].mesh.divisions", vec![8, 5, 3].into()),
            ("organs[0].materials[0].model", model.into()),
            ("effects.deformation", deformation.into()),
            ("fidelity.large", large.into()),
        ],
    );
    Scene::from_toml(&text, "<organ>").unwrap()
}

const OTHER_EFFECTS: [&str; 4] = ["anm_", "cut_", "tear_", "tear1_"];

#[test]
fn a_palpation_scene_holds_nothing_for_the_effects_it_does_not_name() {
    let palpation = organ("linear", "linear");
    let (b, names, bytes) = bundle(&palpation);
    eprintln!("palpation bundle: {bytes} bytes, {names:?}");
    assert!(b.anm.is_none() && b.cut_basis.is_none() && b.tear.is_empty());
    for n in &names {
        assert!(!OTHER_EFFECTS.iter().any(|p| n.starts_with(p)), "a palpation bundle holds {n}");
    }
    let pipe = Pipeline::for_scene(&palpation, std::slice::from_ref(&b)).unwrap();
    assert_eq!(pipe.effect_names(), ["palpation"]);
    assert_eq!(pipe.memory_bytes().len(), 1);
    assert!(pipe.cut_status().is_none() && pipe.grasp_sites().is_empty() && pipe.tear_offline().is_empty());

    // the same organ naming large deformations holds its lattice, and only that more
    let large = organ("stvk", "large");
    let (bl, large_names, large_bytes) = bundle(&large);
    assert!(bl.anm.is_some() && bl.cut_basis.is_none() && bl.tear.is_empty());
    let extra: Vec<&String> = large_names.iter().filter(|n| !names.contains(n)).collect();
    assert!(!extra.is_empty() && extra.iter().all(|n| n.starts_with("anm_")), "{extra:?}");
    assert!(large_bytes > bytes);
}

#[test]
fn a_scene_cutting_an_organ_that_deforms_largely_holds_the_lattice_and_the_cut_and_nothing_for_tearing() {
    let text = Scene::builtin("large_cut").unwrap().source;
    let both = Scene::from_toml(&text, "<large_cut>").unwrap();
    let (b, names, _) = bundle(&both);
    assert!(b.anm.is_some() && b.tear.is_empty(), "{names:?}");
    assert!(names.iter().all(|n| !n.starts_with("tear")), "{names:?}");
    let pipe = Pipeline::for_scene(&both, std::slice::from_ref(&b)).unwrap();
    assert_eq!(pipe.effect_names(), ["palpation", "cutting"]);
    assert!(pipe.cut_status().is_some() && pipe.grasp_sites().is_empty() && pipe.tear_offline().is_empty());
    // the same organ linear and cut: the lattice's arrays are the whole difference
    let linear = Scene::from_toml(&common::with_keys(&text, &[("organs[0].deformation", "linear".into())]), "<linear>").unwrap();
    let (bl, linear_names, _) = bundle(&linear);
    assert!(bl.anm.is_none());
    let extra: Vec<&String> = names.iter().filter(|n| !linear_names.contains(n)).collect();
    assert!(!extra.is_empty() && extra.iter().all(|n| n.starts_with("anm_")), "{extra:?}");
    assert!(linear_names.iter().all(|n| names.contains(n)), "{linear_names:?} against {names:?}");
}

#[test]
fn a_tearing_scene_holds_its_tearing_arrays_and_state() {
    let scene = Scene::builtin("cube_tear").unwrap();
    let (b, names, _) = bundle(&scene);
    assert!(!b.tear.is_empty() && b.anm.is_none());
    assert!(names.iter().any(|n| n.starts_with("tear_")), "{names:?}");
    let pipe = Pipeline::for_scene(&scene, std::slice::from_ref(&b)).unwrap();
    assert!(pipe.effect_names().contains(&"tearing"), "{:?}", pipe.effect_names());
    assert!(!pipe.grasp_sites().is_empty());
}

#[test]
fn the_composition_scenes_add_one_effect_each_to_the_same_cornea_and_compose_two() {
    use vademecum_engine::scene::schema::DeformationModel;
    let load = |name: &str| {
        let path = common::repo_root().join(format!("scenes/effects/cornea_{name}.toml"));
        Scene::from_toml(&std::fs::read_to_string(&path).unwrap(), &path).unwrap()
    };
    let base = load("palpation");
    let fx = |s: &Scene| {
        let e = &s.spec.effects;
        (e.deformation == DeformationModel::Large, e.cutting, e.tearing)
    };
    assert_eq!(fx(&base), (false, false, false));
    assert_eq!(fx(&load("large")), (true, false, false));
    assert_eq!(fx(&load("cutting")), (false, true, false));
    assert_eq!(fx(&load("tearing")), (false, false, true));
    // and two composed on it
    assert_eq!(fx(&load("large_cutting")), (true, true, false));
    // the same organ: mesh, supports and accessible surface
    for name in ["large", "cutting", "tearing", "large_cutting"] {
        let s = load(name);
        assert_eq!(s.spec.organs[0].mesh, base.spec.organs[0].mesh, "{name}");
        assert_eq!(s.spec.organs[0].fixed, base.spec.organs[0].fixed, "{name}");
    }
}
