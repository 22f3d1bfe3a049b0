//! The deployment recipes of `deploy/`, validated offline: the systemd units of a lab
//! workstation parse cleanly (`systemd-analyze verify`, no warning) and keep what the real-time
//! path needs (deploy/README.md, "A lab workstation with systemd").

use std::path::Path;
use std::process::Command;

/// The unit files, by name.
fn units() -> Vec<(&'static str, String)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/systemd");
    ["vademecum.service", "vademecum-bridge@.service"]
        .into_iter()
        .map(|name| (name, std::fs::read_to_string(dir.join(name)).unwrap()))
        .collect()
}

/// The value of `key=` in a unit's text (the last one, as systemd takes it).
fn value<'a>(text: &'a str, key: &str) -> Option<&'a str> {
    text.lines()
        .rev()
        .find_map(|l| l.strip_prefix(key)?.strip_prefix('='))
        .map(str::trim)
}

#[test]
fn the_systemd_units_verify_without_a_warning() {
    if Command::new("systemd-analyze").arg("--version").output().is_err() {
        eprintln!("skipped: systemd-analyze is not installed");
        return;
    }
    // the binaries where the units expect them: any executable will do for `verify`, which
    // checks that ExecStart names one (the bridge's binary is another package's)
    let exe = env!("CARGO_BIN_EXE_vademecum");
    let dir = tempfile::tempdir().unwrap();
    let mut paths = Vec::new();
    for (name, text) in units() {
        let text = text
            .replace("/usr/local/bin/vademecum-bridge", exe)
            .replace("/usr/local/bin/vademecum", exe);
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        paths.push(path);
    }
    let o = Command::new("systemd-analyze").arg("verify").args(&paths).output().unwrap();
    let said = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success() && said.trim().is_empty(), "systemd-analyze verify: {said}");
}

#[test]
fn the_server_and_its_bridges_share_a_user_real_time_limits_and_tmp() {
    let units = units();
    let (server, bridge) = (&units[0].1, &units[1].1);
    // iceoryx2's files are 0600: one user and group for both
    for key in ["User", "Group"] {
        assert_eq!(value(server, key), Some("vademecum"), "{key}");
        assert_eq!(value(bridge, key), value(server, key), "{key}");
    }
    for text in [server, bridge] {
        // the loop and tick threads' SCHED_FIFO, the bridge's mlockall
        assert_eq!(value(text, "LimitRTPRIO"), Some("99"));
        assert_eq!(value(text, "LimitMEMLOCK"), Some("infinity"));
        // a private /tmp would hide iceoryx2's directory from the other unit; and nothing
        // may forbid real time
        assert_eq!(value(text, "PrivateTmp"), Some("no"));
        assert_eq!(value(text, "RestrictRealtime"), None);
        assert_eq!(value(text, "PrivateDevices"), None, "/dev/shm must stay shared");
    }
}
