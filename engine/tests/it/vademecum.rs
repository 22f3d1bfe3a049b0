//! Building a vademecum into a bundle and loading it back: the online evaluator matches the
//! brute-force solution it was measured against, bundles round-trip exactly, and a damaged,
//! truncated, foreign or mismatched bundle is refused with a clear error.

use std::path::Path;

use vademecum_engine::bundle;
use vademecum_engine::bundle::BundleError;
use vademecum_engine::offline::{self, BuildOptions};
use vademecum_engine::pgd::{PgdParams, Vademecum};
use vademecum_engine::scene::Scene;

const SCENE: &str = r#"[scene]
name = "slab"

[[organs]]
name = "slab"
density = 1000.0

[organs.mesh]
builtin = "block"
size = [0.08, 0.04, 0.02]
divisions = [8, 4, 2]

[[organs.materials]]
model = "linear"
young = 5e3
poisson = 0.45

[organs.fixed]
box = { min = [0.0, 0.0, 0.0], max = [0.08, 0.04, 0.0] }

[organs.accessible]
half_space = { point = [0.0, 0.0, 0.02], normal = [0.0, 0.0, 1.0] }

[[tools]]
kind = "probe"
name = "probe"
radius = 0.012
"#;

fn built(max_modes: usize) -> (Scene, offline::Built) {
    let scene = Scene::from_toml(SCENE, "slab.toml").unwrap();
    let opts = BuildOptions {
        params: PgdParams {
            global_tolerance: 1e-10,
            enrichment_tolerance: 1e-6,
            max_modes,
            max_iterations: 60,
            block: 1,
        },
        tolerance: 1e-9,
        recompress: true,
        load_radius: offline::probe_radius(&scene),
        large: None,
        max_memory: None,
        tear_target_error: None,
        large_target_error: None,
        cut_target_error: None,
    };
    let b = offline::build_organ(&scene, 0, &opts, &mut |_| {}).unwrap();
    (scene, b)
}

#[test]
fn a_full_rank_vademecum_reproduces_the_brute_force_solution() {
    let (_, b) = built(400);
    let r = &b.report;
    assert_eq!(r.load_states, 3 * r.load_nodes);
    assert!(r.mean_patch_nodes > 1.0, "the probe footprint spans several nodes");
    let e = r.error;
    assert!(e < 1e-6, "error {e} with {} modes", r.modes);
    // the error curve falls
    for w in r.error_curve.windows(2) {
        assert!(w[1].1 <= w[0].1 * (1.0 + 1e-9));
    }
}

#[test]
fn compliance_is_symmetric_positive_definite_and_force_inverts_it() {
    let (_, b) = built(400);
    let v = &b.vademecum;
    for &n in v.load_nodes().iter().take(20) {
        let c = v.compliance([n, n, n], [1.0, 0.0, 0.0]).unwrap();
        for i in 0..3 {
            assert!(c[i][i] > 0.0);
            for j in 0..3 {
                // reciprocity: patch-averaged response is symmetric
                assert!(
                    (c[i][j] - c[j][i]).abs() < 1e-6 * c[i][i].max(c[j][j]),
                    "C not symmetric at node {n}: {c:?}"
                );
            }
        }
        let delta = [0.0, 0.0, -1e-3];
        let f = Vademecum::contact_force(&c, delta);
        for i in 0..3 {
            let back: f64 = (0..3).map(|j| c[i][j] * f[j]).sum();
            assert!((back - delta[i]).abs() < 1e-12, "C f != delta");
        }
        assert!(f[2] < 0.0, "pressing down needs a downward force on the tissue... got {f:?}");
    }
}

#[test]
fn force_is_continuous_across_triangles_and_zero_for_bad_input() {
    let (_, b) = built(400);
    let v = &b.vademecum;
    let l = v.load_nodes();
    let (a, bb, c, d) = (l[0], l[1], l[2], l[3]);
    // A point on the edge a–b seen from two triangles (a, b, c) and (a, b, d) gets one compliance.
    let c1 = v.compliance([a, bb, c], [0.3, 0.7, 0.0]).unwrap();
    let c2 = v.compliance([bb, a, d], [0.7, 0.3, 0.0]).unwrap();
    for i in 0..3 {
        for j in 0..3 {
            assert!((c1[i][j] - c2[i][j]).abs() <= 1e-15 * c1[i][i].abs().max(1e-30) * 1e3);
        }
    }
    // and it tends to the vertex value as the point reaches the vertex
    let near = v.compliance([a, bb, c], [1.0 - 1e-9, 1e-9, 0.0]).unwrap();
    let at = v.compliance([a, a, a], [1.0, 0.0, 0.0]).unwrap();
    assert!((near[2][2] - at[2][2]).abs() < 1e-6 * at[2][2]);
    // bad input: NaN weights, NaN penetration, a node that is not loadable
    assert!(v.compliance([a, bb, c], [f64::NAN, 0.5, 0.5]).is_none());
    assert_eq!(Vademecum::contact_force(&at, [f64::NAN, 0.0, 0.0]), [0.0; 3]);
    let fixed_node = (0..v.n_nodes()).find(|&n| !v.is_loadable(n)).unwrap();
    assert!(v.compliance([fixed_node, a, bb], [1.0, 0.0, 0.0]).is_none());
    let mut coeffs = vec![1.0; v.modes()];
    assert!(!v.coefficients([fixed_node, a, bb], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], &mut coeffs));
    assert!(coeffs.iter().all(|c| *c == 0.0));
}

#[test]
fn field_of_a_unit_load_matches_the_node_compliance() {
    let (_, b) = built(400);
    let v = &b.vademecum;
    let n = v.load_nodes()[5];
    let mut coeffs = vec![0.0; v.modes()];
    assert!(v.coefficients([n, n, n], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], &mut coeffs));
    let mut u = vec![0.0; 3 * v.n_nodes()];
    v.field(&coeffs, &mut u);
    // patch average of u_z equals C_zz (the modes are full rank here)
    let (pn, pw) = &v.patches()[5];
    let avg: f64 = pn.iter().zip(pw).map(|(&a, &w)| w * u[3 * a + 2]).sum();
    let c = v.compliance([n, n, n], [1.0, 0.0, 0.0]).unwrap();
    assert!((avg - c[2][2]).abs() < 1e-6 * c[2][2]);
    let mut few = vec![0.0; 6];
    v.field_at(&coeffs, &[pn[0], pn[pn.len() - 1]], &mut few);
    assert_eq!(&few[..3], &u[3 * pn[0]..3 * pn[0] + 3]);
}

fn write(dir: &Path) -> (Scene, offline::Built) {
    let (scene, b) = built(60);
    offline::write_bundle(dir, &scene, &b).unwrap();
    (scene, b)
}

#[test]
fn bundles_round_trip_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("slab.bundle");
    let (scene, b) = write(&dir);
    let l = bundle::load_bundle(&dir).unwrap();
    assert_eq!(l.vademecum, b.vademecum);
    assert_eq!(l.nodes, b.model.mesh.nodes);
    bundle::check_matches(&dir, &l.manifest, &scene, &b.model.mesh).unwrap();
    assert_eq!(std::fs::read_to_string(dir.join("scene.toml")).unwrap(), SCENE);
    // the prefix a session's frames fall back to: the fewest modes of the build's error curve
    // that meet the error, none when every mode is needed or the bundle is that coarse already
    let curve = &b.report.error_curve;
    let (k, e) = curve[curve.len() / 2];
    assert_eq!(l.modes_for_error(e), Some(k), "{curve:?}");
    assert!(curve.iter().filter(|p| p.1 <= e).all(|p| p.0 >= k));
    assert_eq!(l.modes_for_error(0.0), None);
    assert_eq!(l.modes_for_error(1.0).map(|k| k >= 1), Some(true));
}

#[test]
fn damaged_truncated_or_foreign_bundles_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("b");
    let (scene, b) = write(&dir);
    // one flipped byte in F.npy
    let f = dir.join("F.npy");
    let mut bytes = std::fs::read(&f).unwrap();
    let good = bytes.clone();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x40;
    std::fs::write(&f, &bytes).unwrap();
    let e = bundle::load_bundle(&dir).unwrap_err();
    assert!(matches!(e, BundleError::Checksum { .. }) && e.to_string().contains("F.npy"), "{e}");
    // truncated
    std::fs::write(&f, &good[..good.len() - 100]).unwrap();
    let e = bundle::load_bundle(&dir).unwrap_err();
    assert!(matches!(e, BundleError::Checksum { .. }), "{e}");
    std::fs::write(&f, &good).unwrap();
    bundle::load_bundle(&dir).unwrap();
    // another format version
    let m = dir.join("manifest.json");
    let text = std::fs::read_to_string(&m).unwrap();
    std::fs::write(
        &m,
        text.replacen(&format!("\"version\": {}", vademecum_engine::bundle::VERSION), "\"version\": 99", 1),
    )
    .unwrap();
    let e = bundle::load_bundle(&dir).unwrap_err();
    assert!(matches!(e, BundleError::Version { found: 99, .. }), "{e}");
    // not a bundle at all
    std::fs::write(&m, "{\"hello\": 1}").unwrap();
    assert!(matches!(bundle::load_bundle(&dir).unwrap_err(), BundleError::NotABundle { .. }));
    std::fs::remove_file(&m).unwrap();
    assert!(matches!(bundle::load_bundle(&dir).unwrap_err(), BundleError::NotABundle { .. }));
    // a bundle used with another scene or mesh
    std::fs::write(&m, text).unwrap();
    let l = bundle::load_bundle(&dir).unwrap();
    let other = Scene::from_toml(&SCENE.replace("divisions = [8, 4, 2]", "divisions = [8, 4, 3]"), "other.toml").unwrap();
    let other_mesh = other.organ_mesh(0).unwrap();
    let e = bundle::check_matches(&dir, &l.manifest, &other, &other_mesh).unwrap_err();
    assert!(matches!(e, BundleError::Mismatch { what: "scene", .. }), "{e}");
    let e = bundle::check_matches(&dir, &l.manifest, &scene, &other_mesh).unwrap_err();
    assert!(matches!(e, BundleError::Mismatch { what: "mesh", .. }), "{e}");
    // runtime settings, comments and layout build the same: the bundle serves them unrebuilt
    let runtime = format!(
        "# the fidelity fallback is a runtime setting\n{}\n[fidelity]\nfallback = \"off\"\n",
        SCENE.replace("name = \"slab\"\n\n", "name = \"slab\"\ndescription = \"a slab\"\n\n")
    );
    let runtime = Scene::from_toml(&runtime, "runtime.toml").unwrap();
    assert_ne!(runtime.source, scene.source);
    bundle::check_matches(&dir, &l.manifest, &runtime, &b.model.mesh).unwrap();
    // a fidelity setting that is built is no runtime setting
    let built = Scene::from_toml(&format!("{SCENE}\n[fidelity.pgd]\nmax_modes = 7\n"), "built.toml").unwrap();
    let e = bundle::check_matches(&dir, &l.manifest, &built, &b.model.mesh).unwrap_err();
    assert!(matches!(e, BundleError::Mismatch { what: "scene", .. }), "{e}");
    let _ = b;
}

/// Rewrites array `name`'s file with `bytes` and its manifest entry's checksum to match (what
/// an attacker, or a careless tool, can do).
fn forge(dir: &Path, name: &str, bytes: &[u8]) {
    let file = dir.join(format!("{name}.npy"));
    std::fs::write(&file, bytes).unwrap();
    let m = dir.join("manifest.json");
    let mut manifest: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&m).unwrap()).unwrap();
    manifest["arrays"][name]["sha256"] = vademecum_engine::bundle::sha256_hex(bytes).into();
    std::fs::write(&m, serde_json::to_string_pretty(&manifest).unwrap()).unwrap();
}

#[test]
fn hostile_bundles_are_refused_even_with_matching_checksums() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("b");
    write(&dir);
    let f = dir.join("G.npy");
    let good = std::fs::read(&f).unwrap();
    let manifest = std::fs::read_to_string(dir.join("manifest.json")).unwrap();
    let restore = || {
        std::fs::write(&f, &good).unwrap();
        std::fs::write(dir.join("manifest.json"), &manifest).unwrap();
        bundle::load_bundle(&dir).unwrap();
    };
    let refused = |why: &str| {
        let e = bundle::load_bundle(&dir).unwrap_err();
        assert!(e.to_string().contains(why), "expected '{why}': {e}");
        e
    };
    // the header-length field shifted by 16 (the data moves into the header's padding):
    // it loaded, and changed the session's forces
    for shift in [16i32, -16, 1] {
        let mut b = good.clone();
        let len = u16::from_le_bytes([b[8], b[9]]) as i32 + shift;
        b[8..10].copy_from_slice(&(len as u16).to_le_bytes());
        forge(&dir, "G", &b);
        let e = refused("G.npy");
        assert!(matches!(e, BundleError::Malformed { .. }), "{e}");
        restore();
    }
    // Fortran order would be read transposed
    let mut b = good.clone();
    let (from, to) = (b"'fortran_order': False", b"'fortran_order': True ");
    let at = b.windows(from.len()).position(|w| w == from).unwrap();
    b[at..at + to.len()].copy_from_slice(to);
    forge(&dir, "G", &b);
    refused("Fortran");
    restore();
    // a header of nested braces (exponential in the old parser)
    let mut b = good.clone();
    let start = 10;
    let len = u16::from_le_bytes([b[8], b[9]]) as usize;
    let hostile = format!("{}{}", "{".repeat(13), " ".repeat(len - 14));
    b[start..start + len - 1].copy_from_slice(hostile.as_bytes());
    forge(&dir, "G", &b);
    refused("quoted string");
    restore();
    // a symbolic link to a device is never read
    #[cfg(unix)]
    {
        std::fs::remove_file(&f).unwrap();
        std::os::unix::fs::symlink("/dev/zero", &f).unwrap();
        refused("symbolic link");
        std::fs::remove_file(&f).unwrap();
        restore();
    }
    // a file larger than its entry allows is refused before it is read
    let mut big = good.clone();
    big.extend(std::iter::repeat_n(0u8, 1 << 16));
    forge(&dir, "G", &big);
    refused("allows");
    restore();
    // a manifest shape whose byte length is just below u64::MAX (the size bound on top of it
    // overflowed)
    let mut m: serde_json::Value = serde_json::from_str(&manifest).unwrap();
    m["arrays"]["G"]["shape"] = serde_json::json!([u64::MAX / 8]);
    std::fs::write(dir.join("manifest.json"), serde_json::to_string(&m).unwrap()).unwrap();
    refused("shape");
    restore();
    // a file name leaving the bundle
    let m = dir.join("manifest.json");
    std::fs::write(&m, manifest.replacen("\"file\": \"G.npy\"", "\"file\": \"../G.npy\"", 1)).unwrap();
    refused("plain file name");
    restore();
    // the scene is covered by the manifest: deleted, emptied or replaced, it is refused
    let scene = dir.join("scene.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::remove_file(&scene).unwrap();
    refused("scene.toml");
    std::fs::write(&scene, "").unwrap();
    assert!(matches!(bundle::load_bundle(&dir).unwrap_err(), BundleError::Checksum { .. }));
    std::fs::write(&scene, text.replace("young = 5e3", "young = 5e4")).unwrap();
    refused("checksum");
    std::fs::write(&scene, &text).unwrap();
    restore();
}

#[test]
fn the_probe_feels_the_tissue_on_the_accessible_surface_and_the_support_below() {
    use std::sync::Arc;
    use vademecum_engine::pipeline::{Events, Pipeline, ToolInput};
    let (scene, b) = built(400);
    let dir = tempfile::tempdir().unwrap();
    offline::write_bundle(dir.path(), &scene, &b).unwrap();
    let bundle = Arc::new(bundle::load_bundle(dir.path()).unwrap());
    let r = 0.012;
    let fresh = || Pipeline::for_scene(&scene, std::slice::from_ref(&bundle)).unwrap();
    let at = |p: &mut Pipeline, tip: [f64; 3]| {
        p.tick(&ToolInput {
            position_m: tip,
            ..ToolInput::default()
        })
    };
    // pressing 1 mm into the top face (z = 0.02): the tool is pushed back up
    let mut p = fresh();
    let s = at(&mut p, [0.04, 0.02, 0.02 + r - 0.001]);
    let c = s.contact.expect("touching");
    assert!((c.depth_m - 0.001).abs() < 1e-12, "{}", c.depth_m);
    let f = s.force_n;
    assert!(
        f[2] > 0.0 && f[0].abs() < 0.2 * f[2] && f[1].abs() < 0.2 * f[2],
        "mostly along the normal: {f:?}"
    );
    // the tissue carries all of it on the accessible face
    for k in 0..3 {
        assert!((c.tissue_force_n[k] + f[k]).abs() <= 1e-12 * f[2]);
    }
    // the force is exactly the vademecum's C(s)⁻¹δ
    let comp = bundle.vademecum.compliance(c.nodes, c.weights).unwrap();
    let direct = Vademecum::contact_force(&comp, [0.0, 0.0, -0.001]);
    for k in 0..3 {
        assert!((direct[k] + f[k]).abs() <= 1e-9 * f[2], "{direct:?} vs {f:?}");
    }
    // deeper press, larger force
    let f2 = at(&mut p, [0.04, 0.02, 0.02 + r - 0.002]).force_n;
    assert!(f2[2] > f[2]);
    // sliding by small steps changes the force by small amounts (continuity)
    let mut prev = at(&mut p, [0.03, 0.013, 0.02 + r - 0.001]).force_n;
    for i in 1..=200 {
        let x = 0.03 + 0.02 * i as f64 / 200.0;
        let y = 0.013 + 0.014 * i as f64 / 200.0;
        let f = at(&mut p, [x, y, 0.02 + r - 0.001]).force_n;
        assert!(
            (f[2] - prev[2]).abs() < 0.1 * prev[2].abs(),
            "jump from {prev:?} to {f:?} at step {i}"
        );
        prev = f;
    }
    // far above: released, zero force; NaN: rejected, zero force
    assert_eq!(at(&mut p, [0.04, 0.02, 0.05]).force_n, [0.0; 3]);
    let s = at(&mut p, [f64::NAN, 0.02, 0.02]);
    assert!(s.events.has(Events::REJECTED_INPUT) && s.force_n == [0.0; 3]);
    // coming up from below the fixed bottom: the rigid support pushes the tool away, and the
    // tissue carries nothing
    let mut p = fresh();
    assert_eq!(at(&mut p, [0.04, 0.02, -0.05]).force_n, [0.0; 3]);
    let s = at(&mut p, [0.04, 0.02, -0.003 - r + 0.012]);
    let c = s.contact.expect("touching the support");
    assert!(s.force_n[2] < 0.0, "{:?}", s.force_n);
    assert_eq!(c.tissue_force_n, [0.0; 3]);
}

#[test]
fn contact_compliance_is_exact_at_nodes_whatever_the_number_of_modes() {
    let (_, few) = built(3);
    let (_, many) = built(400);
    let (vf, vm) = (&few.vademecum, &many.vademecum);
    assert!(vf.local().is_some() && few.report.local_blocks > few.report.load_nodes);
    for &n in vf.load_nodes().iter().step_by(7) {
        let a = vf.compliance([n, n, n], [1.0, 0.0, 0.0]).unwrap();
        let b = vm.compliance([n, n, n], [1.0, 0.0, 0.0]).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((a[i][j] - b[i][j]).abs() <= 1e-9 * b[i][i], "node {n}: {a:?} vs {b:?}");
            }
        }
    }
    // and the full-rank modes agree with the exact local value
    let n = vm.load_nodes()[4];
    let exact = vm.compliance([n, n, n], [1.0, 0.0, 0.0]).unwrap();
    let mut coeffs = vec![0.0; vm.modes()];
    vm.coefficients([n, n, n], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], &mut coeffs);
    let mut u = vec![0.0; 3 * vm.n_nodes()];
    vm.field(&coeffs, &mut u);
    let (pn, pw) = &vm.patches()[4];
    let modal: f64 = pn.iter().zip(pw).map(|(&a, &w)| w * u[3 * a + 2]).sum();
    assert!((modal - exact[2][2]).abs() < 1e-6 * exact[2][2], "{modal} vs {}", exact[2][2]);
}

#[test]
fn node_major_f32_surface_field_matches_the_f64_field() {
    use vademecum_engine::pgd::vademecum::{NodeMajorField, QuantizedField};
    let (_, b) = built(60);
    let v = &b.vademecum;
    let surface = b.model.boundary.nodes();
    let nm = NodeMajorField::new(v, &surface);
    let n = v.load_nodes()[3];
    let mut coeffs = vec![0.0; v.modes()];
    v.coefficients([n, n, n], [1.0, 0.0, 0.0], [0.3, -0.2, -1.0], &mut coeffs);
    let mut full = vec![0.0; 3 * v.n_nodes()];
    v.field(&coeffs, &mut full);
    let c32: Vec<f32> = coeffs.iter().map(|&c| c as f32).collect();
    let mut out = vec![0.0f32; 3 * surface.len()];
    nm.eval(&c32, &mut out);
    let scale = full.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (j, &node) in surface.iter().enumerate() {
        for i in 0..3 {
            // f32 storage: relative error ~1e-7 per term, summed over the modes
            assert!((out[3 * j + i] as f64 - full[3 * node + i]).abs() < 1e-5 * scale, "node {node}");
        }
    }
    // a prefix of the modes (the frames' fallback under load) is the field of the first
    // modes alone: the same as zeroing the other coefficients; 0 means all of them
    let k = v.modes() / 3;
    let mut prefix = vec![0.0f32; out.len()];
    nm.eval_prefix(&c32, k, &mut prefix);
    let cut: Vec<f32> = c32.iter().enumerate().map(|(i, &c)| if i < k { c } else { 0.0 }).collect();
    let mut zeroed = vec![0.0f32; out.len()];
    nm.eval(&cut, &mut zeroed);
    for (a, b) in prefix.iter().zip(&zeroed) {
        assert!((a - b).abs() <= 1e-6 * scale as f32, "{a} vs {b}");
    }
    assert_ne!(prefix, out, "a third of the modes is a coarser field");
    nm.eval_prefix(&c32, 0, &mut prefix);
    assert_eq!(prefix, out);
    // i16 with a scale per mode: each term is off by at most half a quantum, |c_k| max|F_k| / 65534
    let q = QuantizedField::new(v, &surface, v.modes());
    assert_eq!(q.bytes() * 2, nm.bytes());
    let mut scaled = vec![0.0f32; q.modes()];
    q.eval(&c32, &mut scaled, &mut out);
    let nd = 3 * v.n_nodes();
    let bound: f64 = (0..v.modes())
        .map(|k| {
            let fmax = surface
                .iter()
                .flat_map(|&n| (0..3).map(move |i| v.f_raw()[k * nd + 3 * n + i].abs()))
                .fold(0.0, f64::max);
            coeffs[k].abs() * fmax / 65534.0
        })
        .sum();
    let mut worst = 0.0f64;
    for (j, &node) in surface.iter().enumerate() {
        for i in 0..3 {
            let e = (out[3 * j + i] as f64 - full[3 * node + i]).abs();
            worst = worst.max(e);
            assert!(e <= 1.01 * bound + 1e-5 * scale, "node {node}: {e} > {bound}");
        }
    }
    assert!(worst < 1e-3 * scale, "quantised field off by {worst} of {scale}");
}

/// `vademecum build` keeps the fewest modes meeting the scene's target error, and says so.
#[test]
fn the_build_keeps_the_fewest_modes_meeting_the_target() {
    let scene = Scene::from_toml(SCENE, "slab.toml").unwrap();
    for tolerance in [1e-2, 1e-3] {
        let opts = BuildOptions {
            params: PgdParams {
                block: 16,
                ..PgdParams::default()
            },
            tolerance,
            recompress: true,
            load_radius: offline::probe_radius(&scene),
            large: None,
            max_memory: None,
            tear_target_error: None,
            large_target_error: None,
            cut_target_error: None,
        };
        let r = offline::build_organ(&scene, 0, &opts, &mut |_| {}).unwrap().report;
        assert!(r.target_met && r.error <= tolerance, "error {} for target {tolerance}", r.error);
        // one mode fewer would miss it: the curve entry before the kept count is above target
        let before = r.error_curve.iter().rfind(|(m, _)| *m < r.modes);
        if let Some(&(m, e)) = before {
            assert!(
                e > tolerance,
                "{m} modes already give {e} <= {tolerance}, yet {} were kept",
                r.modes
            );
        }
        assert!(r.modes <= r.load_states, "{} modes for {} states", r.modes, r.load_states);
    }
    // an unreachable target (mode cap) is reported, not hidden
    let opts = BuildOptions {
        params: PgdParams {
            max_modes: 5,
            ..PgdParams::default()
        },
        tolerance: 1e-6,
        recompress: true,
        load_radius: 0.0,
        large: None,
        max_memory: None,
        tear_target_error: None,
        large_target_error: None,
        cut_target_error: None,
    };
    let r = offline::build_organ(&scene, 0, &opts, &mut |_| {}).unwrap().report;
    assert!(!r.target_met && r.modes == 5 && r.error > 1e-6);
}

/// A rebuild writes a fresh folder and swaps it in: it never writes through a link planted in
/// the old bundle (an array file, or the bundle folder itself), nor leaves its working folder.
#[test]
fn rewriting_a_bundle_never_writes_through_links() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("slab.bundle");
    let (scene, b) = write(&dir);
    let outside = tmp.path().join("precious.txt");
    std::fs::write(&outside, "not a bundle's").unwrap();
    std::fs::remove_file(dir.join("F.npy")).unwrap();
    std::os::unix::fs::symlink(&outside, dir.join("F.npy")).unwrap();
    offline::write_bundle(&dir, &scene, &b).unwrap();
    assert_eq!(std::fs::read_to_string(&outside).unwrap(), "not a bundle's");
    assert!(std::fs::symlink_metadata(dir.join("F.npy")).unwrap().is_file());
    bundle::load_bundle(&dir).unwrap();
    // the bundle folder a link to another folder: the link is replaced, its target untouched
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    std::fs::write(elsewhere.join("keep.txt"), "kept").unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    std::os::unix::fs::symlink(&elsewhere, &dir).unwrap();
    offline::write_bundle(&dir, &scene, &b).unwrap();
    assert!(std::fs::symlink_metadata(&dir).unwrap().is_dir());
    let names: Vec<_> = std::fs::read_dir(&elsewhere).unwrap().flatten().map(|e| e.file_name()).collect();
    assert_eq!(names, [std::ffi::OsString::from("keep.txt")]);
    bundle::load_bundle(&dir).unwrap();
    // nothing but the bundle and what was there is left beside it
    let mut beside: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().flatten().map(|e| e.file_name()).collect();
    beside.sort();
    assert_eq!(beside, ["elsewhere", "precious.txt", "slab.bundle"].map(std::ffi::OsString::from));
}
