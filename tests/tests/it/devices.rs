//! Device sessions sharing a device worker (`serve --device-workers`), in a test binary of its
//! own: three bridges and a server load the machine, and the other end-to-end tests of the
//! haptic path must not run beside it (tests of one binary run in parallel).

use crate::util;

use std::process::{Command, Stdio};

use util::{assert_forces_match_engine, bridge_bin, bundles, engine, read_trace};
use vademecum_engine::bundle::load_bundle;

/// Three device sessions on one device worker (`serve --device-workers 1`): the worker blocks
/// on the three bridges' events at once and answers each bridge's state with the engine's
/// force for that bridge's own position — no session answers another's bridge, none is
/// starved — while the bridges block on the server's `answered` event instead of polling.
#[test]
fn device_sessions_sharing_a_device_worker_each_answer_their_own_bridge() {
    use vademecum_client::{Client, SceneSpec};
    let dir = tempfile::tempdir().unwrap();
    let server = util::Server::start(&["--device-workers", "1"], &[]);
    let rt = util::runtime();
    let client = rt.block_on(Client::connect(server.url.clone())).unwrap();
    let bundle = load_bundle(&bundles().join("organ/lobe.bundle")).unwrap();
    let mut sessions = Vec::new();
    let mut bridges = Vec::new();
    for k in 0..3 {
        let session = rt
            .block_on(client.create_haptic_session(SceneSpec::Builtin("organ".into()), "organ", "", ""))
            .unwrap();
        // each bridge presses to its own depth: a force for another's position would show
        let script = dir.path().join(format!("hand{k}.csv"));
        vademecum_server::session::builtin_palpation(&bundle, 0.001 * k as f64, 0.004, 0.015)
            .unwrap()
            .write(&script)
            .unwrap();
        let trace = dir.path().join(format!("trace{k}.csv"));
        let child = Command::new(bridge_bin())
            .args(["--session", &session.info().session_id, "--device", "sim", "--no-realtime"])
            .args(["--wait", "sleep", "--answer-wake", "event", "--duration", "6", "--script"])
            .arg(&script)
            .arg("--record")
            .arg(&trace)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        sessions.push(session);
        bridges.push((child, trace));
    }
    // the device sessions tick on the device worker, not on threads of their own
    let threads = server.threads();
    assert!(threads.iter().any(|t| t == "device-worker-0"), "{threads:?}");
    assert!(!threads.iter().any(|t| t.starts_with("tick-s")), "{threads:?}");
    let mut engine = engine();
    for ((mut child, trace), session) in bridges.into_iter().zip(&sessions) {
        assert!(child.wait().unwrap().success());
        let rows = read_trace(&trace);
        let fresh = rows.iter().filter(|r| r.fresh).count();
        // plumbing, not timing: on a loaded machine many ticks may go stale
        assert!(fresh >= 1000, "{fresh} fresh forces of {} ticks", rows.len());
        let touching = assert_forces_match_engine(&rows, 0..rows.len(), &mut engine);
        assert!(touching >= 100, "the palpation presses: {touching} forces above 0.05 N");
        let stats = rt.block_on(session.stats()).unwrap();
        assert!(stats.haptic_answered as usize >= fresh, "{stats:?}");
    }
}
