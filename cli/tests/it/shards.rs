//! Sharded offline builds (`vademecum build --shard I/N`, `vademecum merge`): the built-in
//! organ's bundle merged from 1, 2 and 3 shards is the single-process snapshot build's, to the
//! bit (modes, compliances, measured error), and as accurate as the greedy PGD's; merge refuses
//! missing, foreign and stale shards with a clear message and writes nothing.

use std::path::Path;
use std::process::{Command, Output};

use vademecum_engine::bundle;
use vademecum_engine::bundle::load_bundle;

fn vademecum(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vademecum"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("vademecum runs")
}

fn ok(args: &[&str], dir: &Path) -> String {
    let o = vademecum(args, dir);
    assert!(o.status.success(), "vademecum {args:?}: {}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The bundle's arrays, by name, as bytes (every array the bundle holds).
fn arrays(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let m = bundle::read_manifest(dir).unwrap();
    m.arrays
        .iter()
        .map(|(name, e)| (name.clone(), std::fs::read(dir.join(&e.file)).unwrap()))
        .collect()
}

fn info(dir: &Path) -> serde_json::Value {
    bundle::read_manifest(dir).unwrap().info
}

#[test]
fn a_sharded_build_merged_is_the_single_process_build_to_the_bit() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    ok(&["build", "--method", "snapshots", "--out", "single"], root);
    let single = root.join("single/lobe.bundle");
    let want = arrays(&single);
    for n in 1..=3 {
        let out = format!("s{n}");
        for i in 0..n {
            let said = ok(&["build", "--shard", &format!("{i}/{n}"), "--out", &out], root);
            assert!(said.contains(&format!("shard {i}/{n}")), "{said}");
        }
        let said = ok(&["merge", "--out", &out], root);
        assert!(said.contains("snapshots (merged)"), "{said}");
        let merged = root.join(&out).join("lobe.bundle");
        // every array — modes F and G, exact local compliances, patches — the same bytes
        let got = arrays(&merged);
        assert_eq!(got.len(), want.len());
        for ((name, a), (_, b)) in got.iter().zip(&want) {
            assert!(a == b, "{n} shards: array {name} differs from the single-process build's");
        }
        let (i, j) = (info(&merged), info(&single));
        assert_eq!(i["error"], j["error"], "{n} shards: the measured error");
        assert_eq!(i["modes"], j["modes"]);
        assert_eq!(i["error_curve"], j["error_curve"]);
        // the shards are gone once merged
        let left: Vec<_> = std::fs::read_dir(root.join(&out))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(left, ["lobe.bundle"], "{n} shards");
    }

    // as accurate as the greedy PGD's bundle: the same modes kept for the tolerance, the
    // same measured error (both are the truncated SVD of the same parametric solution; the
    // PGD's modes reach it to 1e-8), and the same displacement for a load anywhere
    ok(&["build", "--out", "pgd"], root);
    let pgd = root.join("pgd/lobe.bundle");
    let (p, s) = (info(&pgd), info(&single));
    assert_eq!(p["modes"], s["modes"]);
    let (ep, es) = (p["error"].as_f64().unwrap(), s["error"].as_f64().unwrap());
    assert!((ep - es).abs() < 1e-6 * es.max(1e-12) + 1e-9, "PGD {ep:e}, snapshots {es:e}");
    let (vp, vs) = (load_bundle(&pgd).unwrap(), load_bundle(&single).unwrap());
    let (vp, vs) = (&vp.vademecum, &vs.vademecum);
    let loads = vp.load_nodes();
    let field = |v: &vademecum_engine::pgd::Vademecum, node: usize, force: [f64; 3]| {
        let mut c = vec![0.0; v.modes()];
        assert!(v.coefficients([node; 3], [1.0, 0.0, 0.0], force, &mut c));
        let mut u = vec![0.0; 3 * v.n_nodes()];
        v.field(&c, &mut u);
        u
    };
    for (j, force) in [
        (0, [1.0, 0.0, 0.0]),
        (loads.len() / 2, [0.3, -0.5, 0.8]),
        (loads.len() - 1, [0.0, 0.0, -1.0]),
    ] {
        let (a, b) = (field(vp, loads[j], force), field(vs, loads[j], force));
        let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = a.iter().zip(&b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        // the same truncated SVD up to the PGD's 1e-8 and the modes' f32 rounding (6e-8;
        // measured: 1e-10)
        assert!(
            scale > 0.0 && diff <= 1e-7 * scale,
            "load node {j}: PGD and snapshots differ by {diff:e} (scale {scale:e})"
        );
    }
}

/// A shard can hold no load state: the patch has 36, one block of 64 columns, so of two shards
/// the first solves nothing. It still says how many equations the organ has, and the merge is
/// the single-process build (it once refused it: "shard 0 has 36 of 0").
#[test]
fn a_shard_with_no_load_state_merges() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    ok(&["build", "--builtin", "patch", "--method", "snapshots", "--out", "single"], root);
    for i in 0..2 {
        ok(&["build", "--builtin", "patch", "--shard", &format!("{i}/2"), "--out", "s"], root);
    }
    let said = ok(&["merge", "--builtin", "patch", "--out", "s"], root);
    assert!(said.contains("snapshots (merged)"), "{said}");
    let (got, want) = (arrays(&root.join("s/patch.bundle")), arrays(&root.join("single/patch.bundle")));
    assert_eq!(got.len(), want.len());
    for ((name, a), (_, b)) in got.iter().zip(&want) {
        assert!(a == b, "array {name} differs from the single-process build's");
    }
}

#[test]
fn merge_refuses_missing_foreign_and_stale_shards_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    // a folder no shard was written to yet (a merge Job that starts first, with no --wait)
    let o = vademecum(&["merge", "--out", "m"], root);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no shard in m") && err.contains("vademecum build --shard"), "{err}");
    ok(&["build", "--shard", "0/3", "--out", "m"], root);
    ok(&["build", "--shard", "2/3", "--out", "m"], root);
    let o = vademecum(&["merge", "--out", "m"], root);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("2 of 3 shards") && err.contains("missing: 1"), "{err}");
    assert!(!root.join("m/lobe.bundle").exists());
    // a shard of another split
    ok(&["build", "--shard", "1/2", "--out", "m"], root);
    let err = String::from_utf8_lossy(&vademecum(&["merge", "--out", "m"], root).stderr).into_owned();
    assert!(err.contains("another split"), "{err}");
    std::fs::remove_dir_all(root.join("m/lobe.shard-1-of-2")).unwrap();
    // a shard solved from another scene text
    let scene = ok(&["scene", "show", "organ"], root);
    std::fs::write(root.join("other.toml"), format!("{scene}\n# another text\n")).unwrap();
    ok(&["build", "other.toml", "--shard", "1/3", "--out", "m"], root);
    let err = String::from_utf8_lossy(&vademecum(&["merge", "--out", "m"], root).stderr).into_owned();
    assert!(err.contains("another scene text"), "{err}");
    std::fs::remove_dir_all(root.join("m/lobe.shard-1-of-3")).unwrap();
    // a shard whose U holds a NaN or an infinity, its checksum forged to match: refused with
    // where, never a panic in the merge's SVD
    ok(&["build", "--shard", "1/3", "--out", "m"], root);
    for poison in [f64::NAN, f64::INFINITY] {
        let shard = root.join("m/lobe.shard-1-of-3");
        let file = shard.join("U.npy");
        let mut bytes = std::fs::read(&file).unwrap();
        let at = bytes.len() - 8 * 17;
        bytes[at..at + 8].copy_from_slice(&poison.to_le_bytes());
        std::fs::write(&file, &bytes).unwrap();
        let mpath = shard.join(bundle::MANIFEST);
        let mut m: serde_json::Value = serde_json::from_slice(&std::fs::read(&mpath).unwrap()).unwrap();
        m["arrays"]["U"]["sha256"] = bundle::sha256_hex(&bytes).into();
        std::fs::write(&mpath, serde_json::to_vec_pretty(&m).unwrap()).unwrap();
        let o = vademecum(&["merge", "--out", "m"], root);
        assert!(
            matches!(o.status.code(), Some(1 | 2)),
            "refused, not panicked: {:?} {}",
            o.status.code(),
            String::from_utf8_lossy(&o.stderr)
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("non-finite") && err.contains("lobe.shard-1-of-3"), "{err}");
        assert!(!root.join("m/lobe.bundle").exists());
    }
    // scenes whose build does more than the linear vademecum refuse to shard
    let o = vademecum(&["build", "--builtin", "patch_cut", "--shard", "0/2", "--out", "c"], root);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("cutting") && err.contains("does not shard"), "{err}");
    // --wait gives up when a shard never comes
    let clock = std::time::Instant::now();
    std::fs::remove_dir_all(root.join("m/lobe.shard-1-of-3")).unwrap();
    let o = vademecum(&["merge", "--out", "m", "--wait", "1"], root);
    assert!(!o.status.success() && clock.elapsed().as_secs_f64() >= 1.0);
    assert!(String::from_utf8_lossy(&o.stderr).contains("waiting up to 1 s"));
}
