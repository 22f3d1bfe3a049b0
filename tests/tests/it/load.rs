//! `vademecum bench load` with device sessions, in a test binary of its own: it loads the
//! machine (a server, bridges, client processes), and the other end-to-end tests of the haptic
//! path must not run beside it (tests of one binary run in parallel).

use crate::util;

/// `vademecum bench load --haptic --device-workers 1`: device sessions on a device worker, driven by bridge processes among gRPC
/// sessions, one bridge killed with SIGKILL half way and restarted, a chaos client killed too;
/// the device sessions keep answering their bridges and every gRPC state is accounted for.
#[test]
fn bench_load_drives_device_sessions_through_bridges_and_survives_a_killed_bridge() {
    let dir = tempfile::tempdir().unwrap();
    let bridge = util::bridge_bin();
    let bundles = util::bundles().join("organ");
    let args = [
        "bench",
        "load",
        "--sessions",
        "3",
        "--haptic",
        "2",
        "--seconds",
        "4",
        "--rate",
        "200",
        "--window",
        "1",
        "--chaos-every",
        "1",
        "--chaos-clients",
        "1",
        "--device-workers",
        "1",
        "--bridge",
        bridge.to_str().unwrap(),
        "--bundles",
        bundles.to_str().unwrap(),
        "--json",
        "load.json",
    ];
    let o = util::vademecum(dir.path(), &args);
    assert!(o.status.success(), "stderr: {}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("load.json")).unwrap()).unwrap();
    let h = &r["haptic"];
    assert_eq!(h["sessions"].as_u64(), Some(2), "{r}");
    assert_eq!(h["wait"].as_str(), Some("event"), "{r}");
    assert_eq!(h["device_workers"].as_u64(), Some(1), "{r}");
    assert_eq!(h["bridge_answer_wake"].as_str(), Some("event"), "{r}");
    assert_eq!(h["bridge_kills"].as_u64(), Some(1), "{r}");
    // two sessions at 1 kHz for 4 s, less the killed bridge's restart: most states answered
    assert!(h["answered"].as_u64().unwrap() > 4000, "{r}");
    assert!(
        h["bridge_latency_p50_us_worst"].as_f64().unwrap() > 0.0,
        "the bridges reported: {r}"
    );
    let n = |k: &str| r[k].as_u64().unwrap_or_else(|| panic!("{k} in {r}"));
    assert_eq!(
        n("states_sent"),
        n("states_answered") + n("states_refused") + n("states_in_flight_at_kill") + n("states_lost"),
        "{r}"
    );
    assert_eq!((n("states_refused"), n("states_lost")), (0, 0), "{r}");
    assert!(
        r["windows"]
            .as_array()
            .unwrap()
            .iter()
            .all(|w| w["haptic_sessions_miss_pct"].is_number()),
        "{r}"
    );
}
