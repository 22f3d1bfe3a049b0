//! A tick of the effect pipeline allocates nothing: a counting allocator counts the
//! allocations of the test's thread over thousands of ticks that exercise every branch of the
//! palpation tick — approach, touch, deep press, sliding across edges and onto the support,
//! saturation, a tool appearing inside (the widening search), release, rejected input — for the
//! linear and the large-deformation (ANM-POD lattice) models.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Arc;

use vademecum_engine::bundle;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pipeline::{Events, Fidelity, Pipeline, ToolInput};
use vademecum_engine::scene::Scene;

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
    static FREES: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; only counts, on the calling thread.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(|c| c.get()) {
            COUNT.with(|n| n.set(n.get() + 1));
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if COUNTING.with(|c| c.get()) {
            FREES.with(|n| n.set(n.get() + 1));
        }
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn pipeline(scene: &Scene) -> Pipeline {
    let built = offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), scene, &built).unwrap();
    let b = Arc::new(bundle::load_bundle(dir.path()).unwrap());
    Pipeline::for_scene(scene, &[b]).unwrap()
}

/// The tool path: `n` points through every case, around `centre` with a body of `size`.
fn path(centre: [f64; 3], size: f64, top: f64, n: usize) -> Vec<ToolInput> {
    let mut out = Vec::with_capacity(n);
    let at = |p: [f64; 3]| ToolInput {
        position_m: p,
        ..ToolInput::default()
    };
    for i in 0..n {
        let u = i as f64 / n as f64;
        let p = match i % 10 {
            // a tool jumping to points inside and outside (acquisition, widening search)
            7 => [centre[0] + size * (u - 0.5), centre[1], centre[2]],
            // a NaN sample
            8 => [f64::NAN, 0.0, 0.0],
            // down from above to far below the surface, sliding sideways
            _ => [
                centre[0] + 0.8 * size * (u - 0.5),
                centre[1] + 0.3 * size * (7.0 * u).sin(),
                top + 0.01 - 0.05 * (13.0 * u).sin().abs(),
            ],
        };
        out.push(at(p));
    }
    out
}

fn allocations(p: &mut Pipeline, tools: &[ToolInput]) -> (u64, u32) {
    let mut seen = 0u32;
    COUNT.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    for t in tools {
        seen |= p.tick(t).events.0;
    }
    COUNTING.with(|c| c.set(false));
    (COUNT.with(|n| n.get()), seen)
}

#[test]
fn a_palpation_tick_allocates_nothing() {
    let text = vademecum_engine::scene::builtin("organ")
        .unwrap()
        .replace("radius = 0.004                       # m", "radius = 0.004\nmax_force = 10.0");
    let scene = Scene::from_toml(&text, "organ.toml").unwrap();
    let mut p = pipeline(&scene);
    let tools = path([0.0, 0.0, 0.01], 0.16, 0.04, 6000);
    let (n, seen) = allocations(&mut p, &tools);
    assert_eq!(n, 0, "{n} allocations in {} ticks", tools.len());
    // the path did go through the cases it is meant to
    for e in [Events::CONTACT, Events::REJECTED_INPUT, Events::FORCE_SATURATED] {
        assert!(seen & e != 0, "event {e} never happened");
    }
}

#[test]
fn a_large_deformation_palpation_tick_allocates_nothing() {
    // the built-in cornea, coarser and with a 3-position lattice (the allocation-free claim
    // does not depend on the sizes; `large_palpation.rs` uses the same reduction)
    let text = vademecum_engine::scene::builtin("cornea")
        .unwrap()
        .replace("divisions = [24, 24, 3]", "divisions = [12, 12, 2]")
        .replace("positions = 9", "positions = 3")
        .replace("load_steps = 6", "load_steps = 4");
    let scene = Scene::from_toml(&text, "cornea.toml").unwrap();
    let mut p = pipeline(&scene);
    let tools = path([0.0, 0.0, 0.001], 0.012, 0.0024, 4000);
    let (n, seen) = allocations(&mut p, &tools);
    assert_eq!(n, 0, "{n} allocations in {} ticks", tools.len());
    assert!(seen & Events::CONTACT != 0);
    assert!(seen & Events::BEYOND_RANGE != 0, "the path presses past the lattice's range");
}

#[test]
fn the_contact_compliance_of_a_cut_organ_allocates_nothing() {
    use vademecum_engine::geometry::cut::Cut;
    use vademecum_engine::xfem::reduced::{Discontinuous, ReducedCut, RitzBasis};
    use vademecum_engine::xfem::{Enrichment, XfemParams};
    let scene = Scene::builtin("patch").unwrap();
    let built = offline::build_organ(&scene, 0, &BuildOptions::for_scene(&scene, true), &mut |_| {}).unwrap();
    let (m, v) = (&built.model, &built.vademecum);
    let params = XfemParams::default();
    let cut = Cut::swept(&[([2.0, -0.1, 5.1], [2.0, 1.1, 5.1]), ([2.0, -0.1, 3.0], [2.0, 1.1, 3.0])]).unwrap();
    let cells = Enrichment::cut_cells(&m.mesh, &cut, &params).unwrap();
    let top: Vec<usize> = (0..m.mesh.n_nodes()).filter(|&a| m.mesh.nodes[a][2] == 5.0).collect();
    // each variant with and without the contact table of the top nodes
    for (disc, table) in [Discontinuous::Bare, Discontinuous::LocalFields]
        .into_iter()
        .flat_map(|d| [(d, false), (d, true)])
    {
        let mut red = ReducedCut::new(
            &m.mesh,
            &m.materials,
            m.locking,
            &m.problem,
            v.f_raw(),
            v.modes(),
            RitzBasis::Srb,
            disc,
            &params,
        )
        .unwrap();
        if table {
            red.tabulate(&top);
        }
        red.cut(&m.mesh, &cells).unwrap();
        let mut trace = 0.0;
        COUNT.with(|n| n.set(0));
        COUNTING.with(|c| c.set(true));
        for i in 0..2000 {
            let a = top[i % top.len()];
            let b = top[(i + 1) % top.len()];
            let c = red.contact_compliance(&[a, b], &[0.7, 0.3]);
            trace += c[0][0] + c[1][1] + c[2][2];
        }
        COUNTING.with(|c| c.set(false));
        assert!(trace.is_finite() && trace > 0.0);
        assert_eq!(COUNT.with(|n| n.get()), 0, "{disc:?} (table {table}): the cut compliance allocated");
    }
}

/// The patch's scalpel with its edge across the patch's depth at height `z` in the plane
/// x = 4, upright (the plane's normal is x).
fn blade(z: f64) -> ToolInput {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    ToolInput {
        kind: vademecum_engine::pipeline::ToolKind::Scalpel,
        position_m: [4.0, -0.1, z],
        blade_end_m: [4.0, 1.1, z],
        orientation: [h, 0.0, 0.0, -h],
        ..ToolInput::default()
    }
}

#[test]
fn a_cutting_tick_allocates_and_frees_nothing_while_the_cut_grows() {
    // the patch of seed 000 §3.5.1, a scalpel pressed down through its top cell row: the cut
    // thread cuts two cells and the tick swaps the cut model in (the old one is freed on the
    // cut thread); counted on the tick's thread only
    let scene = Scene::builtin("patch_cut").unwrap();
    let mut p = pipeline(&scene);
    let tools: Vec<ToolInput> = (0..=1200).map(|i| blade(5.1 - 1.2 * i as f64 / 1200.0)).collect();
    let bad = ToolInput {
        blade_end_m: [f64::NAN; 3],
        ..blade(4.0)
    };
    let mut seen = 0u32;
    COUNT.with(|n| n.set(0));
    FREES.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    for t in &tools {
        seen |= p.tick(t).events.0;
        seen |= p.tick(&bad).events.0;
        // a tick a millisecond, as a session ticks (the cut thread's queue holds a second)
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    let start = std::time::Instant::now();
    while seen & Events::CUT_ADVANCED == 0 && start.elapsed().as_secs() < 10 {
        seen |= p.tick(&blade(3.9)).events.0;
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    for _ in 0..1000 {
        seen |= p.tick(&blade(4.5)).events.0;
    }
    COUNTING.with(|c| c.set(false));
    for e in [Events::CONTACT, Events::CUT_STARTED, Events::CUT_ADVANCED, Events::REJECTED_INPUT] {
        assert!(seen & e != 0, "event {e} never happened");
    }
    assert_eq!(COUNT.with(|n| n.get()), 0, "the cutting tick allocated");
    assert_eq!(FREES.with(|n| n.get()), 0, "the cutting tick freed memory");
}

#[test]
fn a_co_rotational_cutting_tick_allocates_and_frees_nothing_while_corrections_land() {
    use std::sync::Mutex;
    use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
    // the patch cut with co-rotational cutting (without its corner load, and a lower cut force:
    // pressed a metre into this 5 Pa patch the deformation softens the blade's force to
    // 0.3–0.4 N where the linear model gives more than 1 N): a frame thread advances the deformation under
    // the tick's contact every 20 ms and hands the tick its corrections, which the tick blends
    // in while the cut thread cuts; counted on the tick's thread only
    let text = Scene::builtin("patch_cut")
        .unwrap()
        .source
        .replace("force = [0.0, 0.0, -1.0]", "force = [0.0, 0.0, 0.0]")
        .replace("cut_force = 1.0", "cut_force = 0.2")
        .replace("[fidelity]\n", "[fidelity]\ncutting = \"corotational_xfem\"\n");
    let scene = Scene::from_toml(&text, "patch_cut_corot.toml").unwrap();
    let mut p = pipeline(&scene);
    let mut deformation = p.take_corotational().unwrap();
    let status = p.cut_status().unwrap();
    let contact = Arc::new(Mutex::new(None));
    let stop = Arc::new(AtomicBool::new(false));
    let frames = std::thread::spawn({
        let (contact, stop, status) = (contact.clone(), stop.clone(), status.clone());
        move || {
            while !stop.load(Relaxed) {
                let c = *contact.lock().unwrap();
                deformation.step_with_picture(status.picture().as_deref(), c.as_ref()).unwrap();
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
        }
    });
    let tools: Vec<ToolInput> = (0..=1200).map(|i| blade(5.1 - 1.2 * i as f64 / 1200.0)).collect();
    let mut seen = 0u32;
    COUNT.with(|n| n.set(0));
    FREES.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    for t in tools.iter().chain(std::iter::repeat_n(&blade(4.5), 500)) {
        let s = p.tick(t);
        seen |= s.events.0;
        *contact.lock().unwrap() = s.contact;
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    COUNTING.with(|c| c.set(false));
    stop.store(true, Relaxed);
    frames.join().unwrap();
    for e in [Events::CONTACT, Events::CUT_STARTED, Events::CUT_ADVANCED] {
        assert!(seen & e != 0, "event {e} never happened");
    }
    assert!(status.landings.load(Relaxed) > 0 && status.corrected_ticks.load(Relaxed) > 0);
    assert_eq!(COUNT.with(|n| n.get()), 0, "the co-rotational cutting tick allocated");
    assert_eq!(FREES.with(|n| n.get()), 0, "the co-rotational cutting tick freed memory");
}

#[test]
fn a_tearing_step_allocates_nothing() {
    use vademecum_engine::damage::build;
    use vademecum_engine::damage::online::{OnlineTear, StepLimits, Variant};
    use vademecum_engine::scene::tearing;
    // the seed's cube: steps, steps split into sub-steps (a fast pull), and rebuilding the
    // whole displacement field
    let scene = Scene::builtin("cube_tear").unwrap();
    let (model, _) = tearing::tear_model(&scene, 0).unwrap();
    let (settings, _) = tearing::settings(&scene);
    let (off, _, _) = build::build(model, &settings, |_, _| {}).unwrap();
    let off = Arc::new(off);
    let limits = StepLimits {
        max_damage_increment: 0.01,
        max_substeps: 8,
    };
    for variant in [Variant::Simplified, Variant::Full] {
        let mut online = OnlineTear::new(off.clone(), variant, limits);
        let mut u = vec![0.0; 3 * off.model.mesh.n_nodes()];
        let mut split = 0;
        COUNT.with(|n| n.set(0));
        COUNTING.with(|c| c.set(true));
        for k in 0..30 {
            let s = online.step(if k < 20 { 1.0 } else { -1.0 });
            split += (s.substeps > 1) as u32;
            online.displacement(&mut u);
        }
        COUNTING.with(|c| c.set(false));
        assert!(split > 0, "{variant:?}: some step was split");
        assert!(u.iter().all(|x| x.is_finite()));
        assert_eq!(COUNT.with(|n| n.get()), 0, "{variant:?}: a tearing step allocated");
    }
}

#[test]
fn a_grasper_tick_allocates_nothing() {
    use vademecum_engine::pipeline::ToolKind;
    // the seed's cube, softened (alpha = 0.1, beta = 0) so that it tears: grasp, pull until
    // the grasp is lost, the fade, a failed re-grasp, a release; counted on the tick's thread
    let text = Scene::builtin("cube_tear")
        .unwrap()
        .source
        .replace("alpha = 0.4, beta = 0.4", "alpha = 0.1, beta = 0.0")
        .replace("max_force = 1.0 ", "max_force = 5.0 ");
    let scene = Scene::from_toml(&text, "cube.toml").unwrap();
    let mut p = pipeline(&scene);
    let jaws = |dz: f64, closure: f64| ToolInput {
        kind: ToolKind::Grasper,
        position_m: [1.0, 1.0, 1.0 + dz],
        closure,
        ..ToolInput::default()
    };
    let mut seen = 0u32;
    COUNT.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    for k in 0..4000 {
        // the fidelity fallback comes and goes mid-pull (the tick thread switches it)
        if k % 1000 == 300 {
            p.set_fidelity(Fidelity::Reduced);
        }
        if k % 1000 == 700 {
            p.set_fidelity(Fidelity::Full);
        }
        seen |= p.tick(&jaws(0.8 * k as f64 / 4000.0, 1.0)).events.0;
    }
    for _ in 0..50 {
        seen |= p.tick(&jaws(0.0, 0.0)).events.0;
        seen |= p.tick(&jaws(0.0, 1.0)).events.0;
        seen |= p.tick(&jaws(f64::NAN, 1.0)).events.0;
    }
    COUNTING.with(|c| c.set(false));
    for e in [Events::GRASPED, Events::TEARING, Events::TISSUE_TORN, Events::REJECTED_INPUT] {
        assert!(seen & e != 0, "event {e} never happened");
    }
    assert_eq!(COUNT.with(|n| n.get()), 0, "the grasper's tick allocated");
}

#[test]
fn a_change_of_grasp_site_allocates_nothing() {
    use vademecum_engine::pipeline::ToolKind;
    // the seed's cube with a second grasp site (the upper corner opposite the scene's): pull
    // there, let go, take the scene's corner (its integrator takes over the damage), pull,
    // let go, and back; counted on the tick's thread
    let text = Scene::builtin("cube_tear")
        .unwrap()
        .source
        .replace("grasp_sites = 4 ", "grasp_sites = 2 ");
    let scene = Scene::from_toml(&text, "cube.toml").unwrap();
    let mut p = pipeline(&scene);
    let sites = p.grasp_sites().to_vec();
    assert_eq!(sites.len(), 2);
    let jaws = |site: usize, pull: f64, closure: f64| ToolInput {
        kind: ToolKind::Grasper,
        position_m: std::array::from_fn(|k| sites[site].centre_m[k] + pull * sites[site].pull_direction[k]),
        closure,
        ..ToolInput::default()
    };
    let mut grasps = 0;
    COUNT.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    for site in [1, 0, 1] {
        for k in 0..200 {
            grasps += p.tick(&jaws(site, 0.05 * f64::from(k) / 200.0, 1.0)).events.has(Events::GRASPED) as u32;
        }
        for _ in 0..30 {
            p.tick(&jaws(site, 0.0, 0.0));
        }
    }
    COUNTING.with(|c| c.set(false));
    assert_eq!(grasps, 3, "each site taken in turn");
    assert_eq!(COUNT.with(|n| n.get()), 0, "a change of grasp site allocated");
}

/// Two probes in one session (issue 46), ticked together over the palpation path: the
/// second probe follows the first at a fixed offset, so they press one organ together (the
/// coupled solve), apart, and one in free air, with rejected samples between.
#[test]
fn a_two_probe_tick_allocates_nothing() {
    let text = format!(
        "{}\n[[tools]]\nkind = \"probe\"\nname = \"left\"\nradius = 0.004\n",
        vademecum_engine::scene::builtin("organ").unwrap()
    );
    let scene = Scene::from_toml(&text, "organ.toml").unwrap();
    let mut p = pipeline(&scene);
    let first = path([0.0, 0.0, 0.01], 0.16, 0.04, 4000);
    let pairs: Vec<[ToolInput; 2]> = first
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let offset = [0.02 * (i as f64 * 0.01).cos(), 0.02, 0.0];
            [
                *a,
                ToolInput {
                    tool: 1,
                    position_m: [0, 1, 2].map(|k| a.position_m[k] + offset[k]),
                    ..*a
                },
            ]
        })
        .collect();
    let mut states = [Default::default(); 2];
    let mut both = 0;
    COUNT.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    for pair in &pairs {
        p.tick_tools(pair, &mut states);
        both += usize::from(states.iter().all(|s| s.events.has(Events::CONTACT)));
    }
    COUNTING.with(|c| c.set(false));
    let n = COUNT.with(|n| n.get());
    assert_eq!(n, 0, "{n} allocations in {} two-probe ticks", pairs.len());
    assert!(both > 100, "the probes pressed together in only {both} ticks");
}

#[test]
fn solving_several_contacts_together_allocates_nothing() {
    use vademecum_engine::pgd::coupled::coupled_forces;
    let scene = Scene::builtin("organ").unwrap();
    let built = offline::build_organ(&scene, 0, &BuildOptions::for_scene(&scene, true), &mut |_| {}).unwrap();
    let v = &built.vademecum;
    let loads = v.load_nodes();
    let points: Vec<([usize; 3], [f64; 3])> = (0..4).map(|k| ([loads[k * loads.len() / 4]; 3], [1.0, 0.0, 0.0])).collect();
    let normals = [[0.0, 0.0, 1.0]; 4];
    let penetrations = [[0.0, 0.0, -0.002]; 4];
    let mut forces = [[0.0; 3]; 4];
    COUNT.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    let mut solved = 0;
    for k in 0..1000 {
        let n = 1 + k % 4;
        solved += usize::from(
            coupled_forces(
                v,
                &points[..n],
                &[Default::default(); 4][..n],
                &normals[..n],
                &penetrations[..n],
                &mut forces[..n],
            )
            .is_ok(),
        );
    }
    COUNTING.with(|c| c.set(false));
    let n = COUNT.with(|n| n.get());
    assert_eq!(n, 0, "{n} allocations in 1000 solves");
    assert_eq!(solved, 1000, "every set of distinct load nodes solves");
}
