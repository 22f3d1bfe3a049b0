//! The Helm chart of `deploy/k8s/` validated offline (no cluster on these machines): `helm lint
//! --strict` and `helm template` with each part on (the fleet, a device pod, Agones, the build
//! Jobs), the rendered manifests validated against the Kubernetes schemas
//! (`kubernetes-validate --strict`; an Agones GameServer's pod template as a Pod) and checked by
//! checkov with no failed check; then what the manifests say is run here, outside a cluster:
//! a fleet pod's command serves and its preStop hook drains it, and the build Jobs' commands
//! (the Indexed Job's index substituted) write the bundle. `.ci/run` installs helm,
//! kubernetes-validate and checkov; without them (outside CI) the tests say so and skip.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use serde_json::{Value, json};

/// An image digest, as a production install pins one (checkov wants it).
const DIGEST: &str = "sha256:0000000000000000000000000000000000000000000000000000000000000000";

fn chart() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/k8s/vademecum")
}

/// Whether `tool` runs (`args` asks its version); under CI a missing tool fails the test.
fn have(tool: &str, args: &[&str]) -> bool {
    let ok = Command::new(tool).args(args).output().is_ok_and(|o| o.status.success());
    if !ok {
        assert!(std::env::var_os("CI").is_none(), "{tool} is not installed (.ci/run installs it)");
        eprintln!("skipped: {tool} is not installed (.ci/run installs it)");
    }
    ok
}

/// Whether helm, kubernetes-validate, checkov and python3 with PyYAML are all there.
fn tools() -> bool {
    have("helm", &["version", "--short"])
        && have("kubernetes-validate", &["--version"])
        && have("checkov", &["--version"])
        && have("python3", &["-c", "import yaml"])
}

fn said(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// `helm template` of the chart in namespace "vademecum" with `sets` (and the digest).
fn render(sets: &[&str]) -> String {
    let mut cmd = Command::new("helm");
    cmd.args(["template", "vademecum"]).arg(chart()).args(["--namespace", "vademecum"]);
    for s in [format!("image.digest={DIGEST}")]
        .iter()
        .map(String::as_str)
        .chain(sets.iter().copied())
    {
        cmd.args(["--set", s]);
    }
    let o = cmd.output().unwrap();
    assert!(o.status.success(), "helm template {sets:?}: {}", said(&o));
    String::from_utf8(o.stdout).unwrap()
}

/// The documents of a YAML stream, as JSON (PyYAML: the chart's CI environment has it).
fn documents(yaml: &str) -> Vec<Value> {
    let mut p = Command::new("python3")
        .args([
            "-c",
            "import json, sys, yaml; print(json.dumps([d for d in yaml.safe_load_all(sys.stdin) if d]))",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    std::io::Write::write_all(&mut p.stdin.take().unwrap(), yaml.as_bytes()).unwrap();
    let o = p.wait_with_output().unwrap();
    assert!(o.status.success());
    serde_json::from_slice(&o.stdout).unwrap()
}

fn find<'a>(docs: &'a [Value], kind: &str, suffix: &str) -> &'a Value {
    docs.iter()
        .find(|d| d["kind"] == kind && d["metadata"]["name"].as_str().is_some_and(|n| n.ends_with(suffix)))
        .unwrap_or_else(|| panic!("no {kind} named *{suffix}"))
}

/// The value sets the chart is checked with: each part on.
const PARTS: [(&str, &[&str]); 5] = [
    ("fleet", &[]),
    ("source", &["bundles.source=https://bucket.example.invalid/store"]),
    ("device", &["device.enabled=true"]),
    ("agones", &["agones.enabled=true"]),
    ("build", &["build.enabled=true"]),
];

#[test]
fn the_chart_lints_and_renders_manifests_that_validate_and_pass_checkov() {
    if !tools() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (part, sets) in PARTS {
        let mut lint = Command::new("helm");
        lint.args(["lint", "--strict"]).arg(chart());
        for s in sets {
            lint.args(["--set", s]);
        }
        let o = lint.output().unwrap();
        assert!(
            o.status.success() && !said(&o).contains("[WARNING]"),
            "helm lint {part}: {}",
            said(&o)
        );
        let mut yaml = render(sets);
        // an Agones GameServer's pod template is a pod: validated and checked as one, beside
        // the rest (the Agones kinds themselves are custom resources the schemas do not hold)
        if part == "agones" {
            let docs = documents(&yaml);
            let template = &find(&docs, "Fleet", "vademecum")["spec"]["template"]["spec"]["template"];
            let pod = json!({
                "apiVersion": "v1",
                "kind": "Pod",
                "metadata": {"name": "gameserver", "namespace": "vademecum", "labels": template["metadata"]["labels"]},
                "spec": template["spec"],
            });
            yaml.push_str(&format!("\n---\n{pod}\n"));
        }
        let f = dir.path().join(format!("{part}.yaml"));
        std::fs::write(&f, &yaml).unwrap();
        let o = Command::new("kubernetes-validate")
            .args(["--strict", "--quiet"])
            .arg(&f)
            .output()
            .unwrap();
        let out = said(&o);
        let unknown_kinds_only = out
            .lines()
            .all(|l| l.trim().is_empty() || (l.contains("Couldn't find schema for kind") && l.contains("agones.dev")));
        assert!(o.status.success() && unknown_kinds_only, "kubernetes-validate {part}: {out}");
        let o = Command::new("checkov")
            .args(["--framework", "kubernetes", "--skip-download", "--compact", "--quiet", "-f"])
            .arg(&f)
            .output()
            .unwrap();
        assert!(o.status.success(), "checkov {part}: {}", said(&o));
    }
}

#[test]
fn an_agones_game_server_runs_the_server_with_agones_and_its_session_counter() {
    if !tools() {
        return;
    }
    let docs = documents(&render(&["agones.enabled=true", "fleet.maxSessionsPerPod=6"]));
    assert!(!docs.iter().any(|d| d["kind"] == "StatefulSet"), "Agones replaces the StatefulSet");
    let fleet = find(&docs, "Fleet", "vademecum");
    let gs = &fleet["spec"]["template"]["spec"];
    assert_eq!(gs["counters"]["sessions"], json!({"count": 0, "capacity": 6}));
    assert_eq!(gs["ports"][0]["containerPort"], 50051);
    let server = &gs["template"]["spec"]["containers"][0];
    let args: Vec<&str> = server["args"].as_array().unwrap().iter().filter_map(Value::as_str).collect();
    assert!(args.contains(&"--agones"), "{args:?}");
    let scaler = find(&docs, "FleetAutoscaler", "vademecum");
    assert_eq!(scaler["spec"]["policy"]["counter"]["key"], "sessions");
}

#[test]
fn a_device_pod_shares_memory_and_a_user_between_server_and_bridge() {
    if !tools() {
        return;
    }
    let docs = documents(&render(&["device.enabled=true", "device.channel=lab7"]));
    let pod = &find(&docs, "StatefulSet", "-device")["spec"]["template"]["spec"];
    let volumes = pod["volumes"].as_array().unwrap();
    for name in ["shm", "iceoryx2"] {
        let v = volumes.iter().find(|v| v["name"] == name).unwrap();
        assert_eq!(v["emptyDir"]["medium"], "Memory", "{name}");
    }
    let containers = pod["containers"].as_array().unwrap();
    assert_eq!(containers.len(), 2);
    for c in containers {
        let mounts: Vec<(&str, &str)> = c["volumeMounts"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| (m["name"].as_str().unwrap(), m["mountPath"].as_str().unwrap()))
            .collect();
        assert!(
            mounts.contains(&("shm", "/dev/shm")) && mounts.contains(&("iceoryx2", "/tmp/iceoryx2")),
            "{mounts:?}"
        );
        assert_eq!(
            (&c["securityContext"]["runAsUser"], &c["securityContext"]["runAsGroup"]),
            (&json!(65532), &json!(65532))
        );
    }
    let bridge = containers.iter().find(|c| c["name"] == "bridge").unwrap();
    assert_eq!(bridge["args"].as_array().unwrap()[0..2], [json!("--session"), json!("lab7")]);
    assert_eq!(pod["nodeSelector"]["vademecum.io/haptic-device"], "lab1");
}

/// A rendered container's command run here: `/var/lib/vademecum` and the token secret's mount
/// mapped into `root`, the pod's variables substituted.
fn local_args(args: &[Value], root: &Path, vars: &[(&str, &str)]) -> Vec<String> {
    args.iter()
        .map(|a| {
            let mut a = a.as_str().unwrap().to_string();
            for (k, v) in vars {
                a = a.replace(&format!("$({k})"), v);
            }
            a.replace("/var/lib/vademecum", &root.join("data").to_string_lossy())
                .replace("/var/run/secrets/vademecum", &root.join("secrets").to_string_lossy())
        })
        .collect()
}

#[test]
fn a_fleet_pod_knows_its_peers_serves_its_command_and_drains_in_its_pre_stop_hook() {
    if !tools() {
        return;
    }
    let docs = documents(&render(&["fleet.replicas=2", "fleet.maxReplicas=3", "fleet.drainSeconds=600"]));
    let set = find(&docs, "StatefulSet", "vademecum");
    let pod = &set["spec"]["template"]["spec"];
    let server = &pod["containers"][0];
    let env = server["env"].as_array().unwrap();
    let peers = env.iter().find(|e| e["name"] == "VADEMECUM_PEERS").unwrap()["value"]
        .as_str()
        .unwrap();
    let want: Vec<String> = (0..3)
        .map(|i| format!("http://vademecum-{i}.vademecum-pods.vademecum.svc.cluster.local:50051"))
        .collect();
    assert_eq!(peers.split(',').collect::<Vec<_>>(), want);
    // draining pods keep their DNS names (sessions stay reachable); a disruption budget
    let headless = find(&docs, "Service", "-pods");
    assert_eq!(headless["spec"]["publishNotReadyAddresses"], true);
    assert_eq!(find(&docs, "PodDisruptionBudget", "vademecum")["spec"]["maxUnavailable"], 1);
    // the preStop drain is bounded, and the grace period outlasts it
    let pre_stop = server["lifecycle"]["preStop"]["exec"]["command"].as_array().unwrap();
    let wait_at = pre_stop.iter().position(|a| a == "--wait").unwrap();
    assert_eq!(pre_stop[wait_at + 1], "600");
    assert!(pod["terminationGracePeriodSeconds"].as_u64().unwrap() > 600);

    // the server's command, run here: it serves (the peers' names do not resolve here: they
    // are left out) and takes a session; the preStop hook's command drains it
    let root = tempfile::tempdir().unwrap();
    for d in ["data/bundles/scenes", "data/bundles/meshes", "secrets"] {
        std::fs::create_dir_all(root.path().join(d)).unwrap();
    }
    std::fs::write(root.path().join("secrets/tokens"), "tok\n").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_vademecum"))
        .args(["build", "--method", "snapshots", "--out"])
        .arg(root.path().join("data/bundles"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", said(&o));
    let vars = [("POD_NAME", "vademecum-1"), ("POD_NAMESPACE", "vademecum")];
    let mut args = local_args(server["args"].as_array().unwrap(), root.path(), &vars);
    for a in args.iter_mut() {
        if a == "0.0.0.0:50051" || a == "0.0.0.0:9100" {
            *a = "127.0.0.1:0".into();
        }
    }
    args.retain(|a| a != "--metrics-public");
    let mut child = Command::new(env!("CARGO_BIN_EXE_vademecum"))
        .args(&args)
        .env("VADEMECUM_PEERS", peers)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let addr = loop {
        let line = lines.next().expect("the server prints its address").unwrap();
        if let Some(a) = line.strip_prefix("listening on ") {
            break a.to_string();
        }
    };
    // keep reading its output (a closed pipe would end it)
    std::thread::spawn(move || lines.for_each(drop));
    let url = format!("http://{addr}");
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    rt.block_on(async {
        let client = vademecum_client::Client::connect_with_token(url.clone(), Some("tok"))
            .await
            .unwrap();
        let s = client
            .create_session(vademecum_client::SceneSpec::Builtin("organ".into()), "", "pod")
            .await
            .expect("a session on the pod (its unreachable peers left out)");
        assert!(s.location().is_none() && s.id().starts_with("vademecum-1-"), "{}", s.id());
        s.close().await.unwrap();
    });
    let mut hook = local_args(pre_stop, root.path(), &vars);
    let at = hook.iter().position(|a| a == "--addr").unwrap();
    hook[at + 1] = url;
    assert_eq!(hook[0], "/usr/local/bin/vademecum");
    let o = Command::new(env!("CARGO_BIN_EXE_vademecum")).args(&hook[1..]).output().unwrap();
    let _ = child.kill();
    let _ = child.wait();
    assert!(o.status.success() && said(&o).contains("holds no session"), "preStop: {}", said(&o));
}

#[test]
fn the_build_jobs_commands_solve_their_shards_and_merge_them_into_the_bundle() {
    if !tools() {
        return;
    }
    let docs = documents(&render(&["build.enabled=true", "build.shards=2", "build.out=builds/organ"]));
    let shards = find(&docs, "Job", "-build-shards");
    assert_eq!(shards["spec"]["completionMode"], "Indexed");
    assert_eq!(shards["spec"]["completions"], 2);
    assert_eq!(shards["spec"]["backoffLimitPerIndex"], 2);
    assert_eq!(shards["spec"]["template"]["spec"]["restartPolicy"], "Never");
    let merge = find(&docs, "Job", "-build-merge");
    let root = tempfile::tempdir().unwrap();
    let shard_args = shards["spec"]["template"]["spec"]["containers"][0]["args"].as_array().unwrap();
    for k in ["0", "1"] {
        let args = local_args(shard_args, root.path(), &[("JOB_COMPLETION_INDEX", k)]);
        let o = Command::new(env!("CARGO_BIN_EXE_vademecum")).args(&args).output().unwrap();
        assert!(o.status.success(), "shard {k}: {}", said(&o));
    }
    let args = local_args(
        merge["spec"]["template"]["spec"]["containers"][0]["args"].as_array().unwrap(),
        root.path(),
        &[],
    );
    let o = Command::new(env!("CARGO_BIN_EXE_vademecum")).args(&args).output().unwrap();
    assert!(o.status.success(), "merge: {}", said(&o));
    let bundle = root.path().join("data/bundles/builds/organ/lobe.bundle");
    assert!(bundle.join("manifest.json").is_file(), "{}", said(&o));
    // and published in the store the servers read, under its digest
    let digest = vademecum_engine::bundle::store::digest(&bundle).unwrap();
    assert!(said(&o).contains(&format!("published lobe: {digest}")), "{}", said(&o));
    let store = root.path().join("data/bundles/store");
    assert!(vademecum_engine::bundle::store::open(&store, &digest).is_ok());
}
