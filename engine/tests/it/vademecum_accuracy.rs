//! The default PGD build meets its accuracy target on the scenes the product ships: the
//! built-in organ and the OpenHELP liver of `../shared` (skipped when that folder is absent,
//! see `shared_meshes.rs`). Relative L2 error of the displacement field over all load
//! positions ≤ 1e-3 against the brute-force solution on the same mesh, with fewer bytes
//! than the full parametric solution.

use crate::common;

use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::scene::Scene;

fn default_build(scene: &Scene) -> offline::BuildReport {
    offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {})
        .unwrap()
        .report
}

fn check(r: &offline::BuildReport) {
    assert_eq!(r.tolerance, 1e-3, "the scene default target");
    assert!(r.target_met && r.error <= 1e-3, "error {:.3e} with {} modes", r.error, r.modes);
    assert!(r.modes < r.load_states, "{} modes for {} load states", r.modes, r.load_states);
    assert!(
        r.modes_bytes < r.full_bytes,
        "{} bytes of modes vs {} for the full solution",
        r.modes_bytes,
        r.full_bytes
    );
}

#[test]
fn builtin_organ_reaches_1e_3_at_the_default_tolerance() {
    let r = default_build(&Scene::builtin("organ").unwrap());
    check(&r);
}

#[test]
fn liver_reaches_1e_3_at_the_default_tolerance() {
    let Some(shared) = common::shared_data() else { return };
    let scene = common::shared_scene("liver_h20.toml", &shared);
    let r = default_build(&scene);
    assert_eq!((r.nodes, r.load_states), (3463, 501));
    check(&r);
}
