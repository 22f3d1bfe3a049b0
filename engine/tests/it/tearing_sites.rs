//! Grasping anywhere on the tearable tissue: the grasp sites beside the scene's
//! (`[fidelity.tearing] grasp_sites`, module `damage::sites`) spread over the accessible
//! tearable surface, each has its own offline stage stored in the bundle and as accurate
//! against its own full-order reference as the scene's, and the tissue keeps one damage
//! whichever site the jaws take.

use crate::common;
use std::sync::Arc;

use vademecum_engine::bundle;
use vademecum_engine::bundle::LoadedBundle;
use vademecum_engine::damage::build;
use vademecum_engine::damage::online::{OnlineTear, TearOffline, Variant};
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::tearing::FADE_TICKS;
use vademecum_engine::pipeline::{Events, Pipeline, TearPictures, TickState, ToolInput, ToolKind};
use vademecum_engine::scene::Scene;
use vademecum_engine::scene::tearing;

const JAW: f64 = 0.5;

/// A 3 × 3 × 1 slab of unit hexahedra (E = 5 Pa, the seed's cube material, Simó damage with
/// the seed's α = β = 0.4), its base fixed, its top accessible, grasped at the corner
/// (3, 3, 1) and pulled up by 0.05 N per step; `sites` grasp sites.
fn slab(sites: usize) -> Scene {
    tearing_slab(sites, 0.4, 0.4)
}

/// [`slab`] with Simó's `alpha`, `beta` (0.1, 0: the stiffness goes to zero, it tears).
fn tearing_slab(sites: usize, alpha: f64, beta: f64) -> Scene {
    let text = format!(
        r#"[scene]
name = "slab_tear"

[[organs]]
name = "slab"
density = 1.0

[organs.mesh]
builtin = "block"
origin = [0.0, 0.0, 0.0]
size = [3.0, 3.0, 1.0]
divisions = [3, 3, 1]
cell = "hex8"

[[organs.materials]]
model = "linear"
young = 5.0
poisson = 0.3
damage = {{ alpha = {alpha}, beta = {beta} }}

[organs.accessible]
half_space = {{ point = [0.0, 0.0, 1.0], normal = [0.0, 0.0, 1.0] }}

[organs.fixed]
box = {{ min = [0.0, 0.0, 0.0], max = [3.0, 3.0, 0.0] }}

[[organs.loads]]
kind = "point"
at = [3.0, 3.0, 1.0]
force = [0.0, 0.0, 0.05]

[[tools]]
kind = "grasper"
name = "grasper"
jaw_width = {JAW}
max_force = 2.0

[effects]
tearing = true

[fidelity]
locking = "none"

[fidelity.tearing]
schedule = [{{ steps = 10, scale = 1.0 }}]
pod_vectors = 3
grasp_sites = {sites}
"#
    );
    Scene::from_toml(&text, "slab.toml").unwrap()
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// The extra sites' centres and pull directions.
fn extra(scene: &Scene) -> Vec<([f64; 3], [f64; 3])> {
    let (model, _) = tearing::tear_model(scene, 0).unwrap();
    tearing::extra_sites(scene, 0, &model)
        .unwrap()
        .iter()
        .map(|s| {
            let mut c = [0.0; 3];
            for &n in &s.nodes {
                (0..3).for_each(|k| c[k] += model.mesh.nodes[n][k] / s.nodes.len() as f64);
            }
            let len = dist(s.force, [0.0; 3]);
            assert!((len * s.nodes.len() as f64 - 0.05).abs() < 1e-12, "the scene's resultant, shared");
            (c, s.force.map(|x| x / len))
        })
        .collect()
}

#[test]
fn the_sites_spread_over_the_tearable_surface_farthest_first() {
    // one more site: the top corner farthest from the scene's grasp, pulled off the corner
    let one = extra(&slab(2));
    assert_eq!(one.len(), 1);
    let (c, n) = one[0];
    assert!(dist(c, [0.0, 0.0, 1.0]) < 1e-12, "{c:?}");
    let out = [-1.0, -1.0, 1.0].map(|x: f64| x / 3f64.sqrt());
    assert!(dist(n, out) < 1e-9, "the outward normal at the corner: {n:?}");
    // as many as asked, at least a jaw width apart and from the scene's grasp, all on the top
    let scene = slab(6);
    let five = extra(&scene);
    assert_eq!(five.len(), 5);
    let centres: Vec<[f64; 3]> = std::iter::once([3.0, 3.0, 1.0]).chain(five.iter().map(|s| s.0)).collect();
    for (i, a) in centres.iter().enumerate() {
        assert!((a[2] - 1.0).abs() < 1e-12, "on the accessible top: {a:?}");
        for b in &centres[..i] {
            assert!(dist(*a, *b) >= JAW, "{a:?} and {b:?} closer than the jaws");
        }
    }
    // as many as it takes to cover the top: then every top node is within reach of a site,
    // and no more are made
    let all = extra(&slab(64));
    assert!(all.len() < 63, "{} sites for 16 top nodes", all.len());
    let reach: Vec<[f64; 3]> = std::iter::once([3.0, 3.0, 1.0]).chain(all.iter().map(|s| s.0)).collect();
    for x in 0..4 {
        for y in 0..4 {
            let p = [x as f64, y as f64, 1.0];
            assert!(reach.iter().any(|c| dist(*c, p) < JAW), "{p:?} out of every site's reach");
        }
    }
    // the seed's cube: its three other upper corners (the base slides: no candidate there)
    let cube = Scene::builtin("cube_tear").unwrap();
    let text = common::with_keys(&cube.source, &[("fidelity.tearing.grasp_sites", 8.into())]);
    let corners = extra(&Scene::from_toml(&text, "cube.toml").unwrap());
    assert_eq!(corners.len(), 3);
    for (c, _) in corners {
        assert!((c[2] - 1.0).abs() < 1e-12 && c[0].fract() == 0.0 && c[1].fract() == 0.0, "{c:?}");
    }
}

#[test]
fn a_scene_asking_for_no_site_or_too_many_is_refused_with_the_key() {
    let text = common::with_keys(&slab(2).source, &[("fidelity.tearing.grasp_sites", 0.into())]);
    let e = Scene::from_toml(&text, "slab.toml").unwrap_err().to_string();
    assert!(e.contains("grasp_sites"), "{e}");
    let text = common::with_keys(&slab(2).source, &[("fidelity.tearing.grasp_sites", 65.into())]);
    assert!(Scene::from_toml(&text, "slab.toml").is_err());
}

fn bundle(scene: &Scene) -> (Arc<LoadedBundle>, offline::Built) {
    let built = offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), scene, &built).unwrap();
    (Arc::new(bundle::load_bundle(dir.path()).unwrap()), built)
}

#[test]
fn every_site_is_stored_and_as_accurate_as_the_scenes_grasp() {
    let scene = slab(3);
    let (b, built) = bundle(&scene);
    assert_eq!(b.tear.len(), 3);
    assert_eq!(built.report.tear_sites.len(), 2);
    let (model, _) = tearing::tear_model(&scene, 0).unwrap();
    let (settings, limits) = tearing::settings(&scene);
    let sites = tearing::extra_sites(&scene, 0, &model).unwrap();
    for (k, arrays) in b.tear.iter().enumerate() {
        let stored = Arc::new(TearOffline::from_arrays(model.clone(), (**arrays).clone()).unwrap());
        // the stored stage is the built one: the site's load, and bit-identical steps
        let mut m = model.clone();
        if k > 0 {
            m.load = sites[k - 1].full(m.mesh.n_nodes());
        }
        assert_eq!(stored.model.load, m.load, "site {k}'s load");
        let (fresh, report, _) = build::build(m, &settings, |_, _| {}).unwrap();
        let mut a = OnlineTear::new(Arc::new(fresh), Variant::Simplified, limits);
        let mut c = OnlineTear::new(stored.clone(), Variant::Simplified, limits);
        for _ in 0..10 {
            a.step(1.0);
            c.step(1.0);
        }
        assert_eq!(a.displacement_vec(), c.displacement_vec(), "site {k}");
        // against the site's own full-order reference (h = 0), step by step: the POD–PGD
        // integrator's error is that of its vademecum (the seed's cube: 1e-4), not a site's
        let errors = build::pull_errors(&stored, [1.0, 0.0, 0.0]).unwrap();
        let worst = errors.iter().fold(0.0f64, |m, e| m.max(*e));
        println!(
            "site {k}: vademecum error {:.2e}, worst step error {worst:.2e}",
            report.vademecum_error
        );
        assert!(worst < 1e-2, "site {k}: {errors:?}");
        // and the site damages the tissue: its pull is not a rigid motion
        assert!(c.dissipated > 0.0, "site {k}");
    }
    // a manifest that lost a site's entry (its arrays still listed for the others) is
    // refused: it loaded one site fewer without a word
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), &scene, &built).unwrap();
    let mpath = dir.path().join("manifest.json");
    let mut m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&mpath).unwrap()).unwrap();
    m["arrays"].as_object_mut().unwrap().remove("tear2_meta");
    std::fs::write(&mpath, serde_json::to_string_pretty(&m).unwrap()).unwrap();
    let e = bundle::load_bundle(dir.path()).unwrap_err().to_string();
    assert!(e.contains("3 grasp site(s)") && e.contains("of 2") && e.contains("rebuild"), "{e}");
    // a site's stored load that does not fit the mesh is refused with a clear error
    let mut bad = (*b.tear[1]).clone();
    bad.load_nodes[0] = 1_000_000;
    let e = TearOffline::from_arrays(model, bad).unwrap_err();
    assert!(e.contains("grasp site") && e.contains("rebuild"), "{e}");
}

fn jaws(at: [f64; 3], closure: f64) -> ToolInput {
    ToolInput {
        kind: ToolKind::Grasper,
        position_m: at,
        closure,
        ..ToolInput::default()
    }
}

/// Takes hold at `at`, pulls `by` over `ticks` ticks, lets go and waits for the fade; returns
/// the events seen and the last force held.
fn grasp_pull_release(p: &mut Pipeline, at: [f64; 3], by: [f64; 3], ticks: u32) -> (Events, [f64; 3]) {
    let mut seen = Events::default();
    let s = p.tick(&jaws(at, 1.0));
    assert!(s.events.has(Events::GRASPED), "no grasp at {at:?}");
    let mut held = [0.0; 3];
    for k in 1..=ticks {
        let f = f64::from(k) / f64::from(ticks);
        let s: TickState = p.tick(&jaws(std::array::from_fn(|i| at[i] + f * by[i]), 1.0));
        seen.0 |= s.events.0;
        held = s.force_n;
    }
    for _ in 0..=FADE_TICKS {
        seen.0 |= p.tick(&jaws(at, 0.0)).events.0;
    }
    (seen, held)
}

fn damage(pictures: &mut TearPictures) -> (usize, Vec<f32>) {
    let p = pictures.read();
    (p.site, p.cell_damage.clone())
}

#[test]
fn the_jaws_take_any_site_and_the_tissue_keeps_one_damage() {
    let scene = slab(2);
    let (b, _) = bundle(&scene);
    let mut p = Pipeline::for_scene(&scene, &[b]).unwrap();
    let sites = p.grasp_sites().to_vec();
    assert_eq!(sites.len(), 2, "the scene's grasp and one more");
    assert!(dist(sites[0].centre_m, [3.0, 3.0, 1.0]) < 1e-12 && dist(sites[1].centre_m, [0.0, 0.0, 1.0]) < 1e-12);
    let mut pictures = p.take_tear_pictures().unwrap();
    // closing between the sites, out of both jaws' reach, takes nothing
    let s = p.tick(&jaws([1.5, 1.5, 1.0], 1.0));
    assert!(!s.events.has(Events::GRASPED) && s.force_n == [0.0; 3]);
    p.tick(&jaws([1.5, 1.5, 1.0], 0.0));

    // the far corner, pulled off the slab along its outward normal: the tissue there damages
    let (c1, n1) = (sites[1].centre_m, sites[1].pull_direction);
    let (seen, held) = grasp_pull_release(&mut p, c1, n1.map(|x| 0.3 * x), 300);
    assert!(seen.has(Events::TEARING) && seen.has(Events::RELEASED), "{seen:?}");
    assert!(
        (0..3).map(|k| held[k] * n1[k]).sum::<f64>() < 0.0,
        "the tissue pulls back: {held:?}"
    );
    let (site, after_far) = damage(&mut pictures);
    assert_eq!(site, 1);
    let (near_far, near_scene) = (0, 8); // the cells under (0, 0, 1) and (3, 3, 1)
    assert!(
        after_far[near_far] > 0.0 && after_far[near_far] > 2.0 * after_far[near_scene],
        "{after_far:?}"
    );

    // the scene's grasp takes over the same damage: nothing healed, nothing lost
    let s = p.tick(&jaws(sites[0].centre_m, 1.0));
    assert!(s.events.has(Events::GRASPED));
    let (site, taken) = damage(&mut pictures);
    assert_eq!(site, 0);
    assert_eq!(taken, after_far, "the damage at the grasp's change");
    p.tick(&jaws(sites[0].centre_m, 0.0));
    for _ in 0..=FADE_TICKS {
        p.tick(&jaws(sites[0].centre_m, 0.0));
    }
    // pulling there now damages the cell under it, and the far corner keeps its damage
    let (seen, _) = grasp_pull_release(&mut p, sites[0].centre_m, [0.0, 0.0, 0.3], 300);
    assert!(seen.has(Events::TEARING), "{seen:?}");
    let (_, after_both) = damage(&mut pictures);
    assert!(after_both[near_scene] > after_far[near_scene], "{after_both:?}");
    for (c, (now, before)) in after_both.iter().zip(&after_far).enumerate() {
        assert!(now >= before, "cell {c} healed from {before} to {now}");
    }
}

#[test]
fn a_site_torn_while_held_is_spent_and_the_others_still_hold() {
    let scene = tearing_slab(2, 0.1, 0.0);
    let (b, _) = bundle(&scene);
    let mut p = Pipeline::for_scene(&scene, &[b]).unwrap();
    let sites = p.grasp_sites().to_vec();
    // pull the far corner until it tears
    let (c1, n1) = (sites[1].centre_m, sites[1].pull_direction);
    let s = p.tick(&jaws(c1, 1.0));
    assert!(s.events.has(Events::GRASPED));
    let mut torn = false;
    for k in 1..=3000 {
        let by = 3.0 * f64::from(k) / 3000.0;
        let s = p.tick(&jaws(std::array::from_fn(|i| c1[i] + by * n1[i]), 1.0));
        if s.events.has(Events::TISSUE_TORN) {
            torn = true;
            break;
        }
    }
    assert!(torn, "a 3 m pull tears α = 0.1, β = 0 tissue");
    for _ in 0..=FADE_TICKS {
        p.tick(&jaws(c1, 0.0));
    }
    // it cannot be taken again; the scene's grasp can, and its pull does not count the cells
    // torn before as a new tear
    assert!(!p.tick(&jaws(c1, 1.0)).events.has(Events::GRASPED));
    p.tick(&jaws(c1, 0.0));
    let s = p.tick(&jaws(sites[0].centre_m, 1.0));
    assert!(s.events.has(Events::GRASPED));
    let s = p.tick(&jaws([3.0, 3.0, 1.001], 1.0));
    assert!(
        !s.events.has(Events::TISSUE_TORN) && s.events.has(Events::CONTACT),
        "{:?}",
        s.events
    );
}

#[test]
fn on_the_gallbladder_the_sites_lie_on_the_fat_free_of_its_anchors_and_face_up() {
    // the fat is grasped from above (the scene pulls up) and anchored at its two ends
    let text = common::with_keys(
        &Scene::builtin("gallbladder_fat").unwrap().source,
        &[("fidelity.tearing.grasp_sites", 8.into())],
    );
    let scene = Scene::from_toml(&text, "<builtin:gallbladder_fat>").unwrap();
    let jaw = tearing::jaw_width(&scene).unwrap();
    let (model, _) = tearing::tear_model(&scene, 0).unwrap();
    let sites = tearing::extra_sites(&scene, 0, &model).unwrap();
    assert!(sites.len() >= 3, "{} sites", sites.len());
    let anchored: Vec<[f64; 3]> = (0..model.mesh.n_nodes())
        .filter(|&n| (0..3).any(|k| model.dofs.is_constrained(3 * n + k)))
        .map(|n| model.mesh.nodes[n])
        .collect();
    let mut fat_node = vec![false; model.mesh.n_nodes()];
    for &p in &model.points.tearable {
        model.mesh.cell(model.points.cell[p]).iter().for_each(|&n| fat_node[n] = true);
    }
    for s in &sites {
        let len = dist(s.force, [0.0; 3]);
        assert!(s.force[2] >= 0.5 * len, "pulled off the top, within 60° of up: {:?}", s.force);
        for &n in &s.nodes {
            assert!(fat_node[n], "node {n} is not on the fat");
            let near = anchored.iter().map(|a| dist(*a, model.mesh.nodes[n])).fold(f64::INFINITY, f64::min);
            assert!(near >= jaw, "node {n} is {near} m from an anchored node");
        }
    }
}
