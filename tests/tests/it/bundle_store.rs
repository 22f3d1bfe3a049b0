//! Bundles pinned by content: `vademecum publish` puts the built-in organ's bundle in a store
//! under the digest of its manifest; a server with `--bundle-store` serves a session asking
//! for that digest (CreateSession bundle_digests), fetches it from `--bundle-source` (a static
//! HTTP server here, as object storage would be) into its store when missing, and never serves
//! a bundle that hashes otherwise: tampered arrays or manifests, in the store or at the
//! source, are refused with FAILED_PRECONDITION and leave nothing behind.

use crate::util;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use vademecum_client::{Client, ErrorKind, SceneSpec, tool_at};

/// `vademecum publish --json` of the shared organ bundle into `store`: its digest.
fn publish(store: &Path) -> String {
    let o = util::vademecum(
        util::bundles(),
        &["publish", "organ/lobe.bundle", "--store", store.to_str().unwrap(), "--json"],
    );
    let digests: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    digests["lobe"].as_str().expect("the lobe's digest").to_string()
}

/// A static HTTP server on `dir` (python3's http.server), killed when dropped.
struct StaticHttp(Child, String);

impl StaticHttp {
    fn start(dir: &Path) -> Self {
        let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let child = Command::new("python3")
            .args(["-m", "http.server", &port.to_string(), "--bind", "127.0.0.1", "--directory"])
            .arg(dir)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("python3 runs");
        let until = Instant::now() + Duration::from_secs(20);
        while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(Instant::now() < until, "the static server did not start");
            std::thread::sleep(Duration::from_millis(50));
        }
        Self(child, format!("http://127.0.0.1:{port}"))
    }
}

impl Drop for StaticHttp {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).unwrap();
        }
    }
}

/// Creates a session on `url` pinned to `digest` and presses once: the error kind if refused.
async fn pinned(url: &str, organ: &str, digest: &str) -> Result<(), (ErrorKind, String)> {
    let client = Client::connect(url.to_string()).await.unwrap();
    let s = client
        .create_pinned_session(SceneSpec::Builtin("organ".into()), &[(organ, digest)], "pinned")
        .await
        .map_err(|e| (e.kind(), e.to_string()))?;
    let mut tools = s.interact().await.unwrap();
    tools.send(tool_at(0, [0.0, 0.0, 0.027])).await.unwrap();
    let r = tools.next().await.unwrap().expect("an answer");
    assert!(r.force_n.unwrap().z > 0.0, "pressing the lobe pushes back");
    s.close().await.unwrap();
    Ok(())
}

#[test]
fn a_session_gets_exactly_the_bundle_its_digest_names_from_the_store_or_the_source() {
    let tmp = tempfile::tempdir().unwrap();
    let store = tmp.path().join("store");
    let digest = publish(&store);
    assert_eq!(publish(&store), digest, "publishing again changes nothing");
    let hex = digest.strip_prefix("sha256:").unwrap();
    let rt = util::runtime();

    // from the store
    let s = util::Server::start(&["--bundle-store", store.to_str().unwrap()], &[]);
    rt.block_on(async {
        pinned(&s.url, "lobe", &digest).await.unwrap();
        let absent = format!("sha256:{}", "0".repeat(64));
        let (kind, msg) = pinned(&s.url, "lobe", &absent).await.unwrap_err();
        assert_eq!(kind, ErrorKind::FailedPrecondition, "{msg}");
        assert!(msg.contains("holds no bundle"), "{msg}");
        let (kind, msg) = pinned(&s.url, "lobe", "sha256:nope").await.unwrap_err();
        assert_eq!(kind, ErrorKind::InvalidArgument, "{msg}");
        let (kind, msg) = pinned(&s.url, "liver", &digest).await.unwrap_err();
        assert_eq!(kind, ErrorKind::InvalidArgument, "{msg}");
        assert!(msg.contains("not an organ of the scene"), "{msg}");
    });

    // a store whose copy was altered: refused (an array; then the manifest itself)
    let altered = tmp.path().join("altered");
    copy_dir(&store, &altered);
    let f = altered.join(format!("sha256/{hex}/F.npy"));
    let mut bytes = std::fs::read(&f).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&f, &bytes).unwrap();
    let a = util::Server::start(&["--bundle-store", altered.to_str().unwrap()], &[]);
    rt.block_on(async {
        let (kind, msg) = pinned(&a.url, "lobe", &digest).await.unwrap_err();
        assert_eq!(kind, ErrorKind::FailedPrecondition, "{msg}");
        assert!(
            msg.contains("checksum") || msg.contains("SHA-256") || msg.contains("sha256"),
            "{msg}"
        );
    });
    let m = altered.join(format!("sha256/{hex}/manifest.json"));
    let text = std::fs::read_to_string(&m).unwrap().replacen("\"scene\"", "\"scene\" ", 1);
    std::fs::write(&m, text).unwrap();
    rt.block_on(async {
        let (kind, msg) = pinned(&a.url, "lobe", &digest).await.unwrap_err();
        assert_eq!(kind, ErrorKind::FailedPrecondition, "{msg}");
    });

    // fetched from a source into an empty store, then served from it
    let source = StaticHttp::start(&store);
    let cache = tmp.path().join("cache");
    let c = util::Server::start(&["--bundle-store", cache.to_str().unwrap(), "--bundle-source", &source.1], &[]);
    rt.block_on(async { pinned(&c.url, "lobe", &digest).await.unwrap() });
    assert!(cache.join(format!("sha256/{hex}/manifest.json")).is_file());
    // clients asking a fresh server at once for a digest it must fetch: one fetch (single
    // flight), every one gets its session, nothing left beside the bundle
    let fresh = tmp.path().join("fresh");
    let f = util::Server::start(&["--bundle-store", fresh.to_str().unwrap(), "--bundle-source", &source.1], &[]);
    rt.block_on(async {
        let asks: Vec<_> = (0..4)
            .map(|_| {
                let (url, digest) = (f.url.clone(), digest.clone());
                tokio::spawn(async move { pinned(&url, "lobe", &digest).await })
            })
            .collect();
        for a in asks {
            a.await.unwrap().expect("every client of the new digest gets its session");
        }
    });
    let held: Vec<_> = std::fs::read_dir(fresh.join("sha256"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(held, [std::ffi::OsString::from(hex)], "one bundle, no fetch folder left");
    drop(source);
    rt.block_on(async { pinned(&c.url, "lobe", &digest).await.unwrap() });

    // a source that accepts and never answers: the fetch gives up at its deadline
    let hanging = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let hanging_url = format!("http://{}", hanging.local_addr().unwrap());
    let held_open = std::thread::spawn(move || {
        let mut open = Vec::new();
        while let Ok((s, _)) = hanging.accept() {
            open.push(s);
            if open.len() >= 4 {
                break;
            }
        }
        std::thread::sleep(Duration::from_secs(30));
    });
    let empty_h = tmp.path().join("empty_h");
    let h = util::Server::start(
        &[
            "--bundle-store",
            empty_h.to_str().unwrap(),
            "--bundle-source",
            &hanging_url,
            "--bundle-fetch-timeout",
            "1",
        ],
        &[],
    );
    rt.block_on(async {
        let (kind, msg) = pinned(&h.url, "lobe", &digest).await.unwrap_err();
        assert_eq!(kind, ErrorKind::FailedPrecondition, "{msg}");
        assert!(msg.contains("deadline"), "{msg}");
    });
    drop(held_open);

    // a source serving an altered copy: refused, nothing left in the store
    let bad_source = StaticHttp::start(&altered);
    let empty = tmp.path().join("empty");
    let d = util::Server::start(&["--bundle-store", empty.to_str().unwrap(), "--bundle-source", &bad_source.1], &[]);
    rt.block_on(async {
        let (kind, msg) = pinned(&d.url, "lobe", &digest).await.unwrap_err();
        assert_eq!(kind, ErrorKind::FailedPrecondition, "{msg}");
        assert!(msg.contains("not served") || msg.contains("hash"), "{msg}");
    });
    let left: Vec<_> = std::fs::read_dir(empty.join("sha256"))
        .map(|d| d.flatten().count())
        .into_iter()
        .collect();
    assert!(left.iter().all(|&n| n == 0), "a refused fetch leaves nothing: {left:?}");
    // a source whose arrays and manifest are right but whose scene text is not: refused at
    // the fetch, nothing left
    let rescened = tmp.path().join("rescened");
    copy_dir(&store, &rescened);
    let scene = rescened.join(format!("sha256/{hex}/scene.toml"));
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(&scene, format!("{text}\n# edited\n")).unwrap();
    let rescened_source = StaticHttp::start(&rescened);
    let empty2 = tmp.path().join("empty2");
    let e = util::Server::start(
        &["--bundle-store", empty2.to_str().unwrap(), "--bundle-source", &rescened_source.1],
        &[],
    );
    rt.block_on(async {
        let (kind, msg) = pinned(&e.url, "lobe", &digest).await.unwrap_err();
        assert_eq!(kind, ErrorKind::FailedPrecondition, "{msg}");
        assert!(msg.contains("scene.toml does not hash"), "{msg}");
    });
    assert_eq!(std::fs::read_dir(empty2.join("sha256")).map_or(0, |d| d.flatten().count()), 0);

    // a server without a store says so
    let plain = util::Server::start(&[], &[]);
    rt.block_on(async {
        let (kind, msg) = pinned(&plain.url, "lobe", &digest).await.unwrap_err();
        assert_eq!(kind, ErrorKind::FailedPrecondition, "{msg}");
        assert!(msg.contains("no bundle store"), "{msg}");
    });
}
