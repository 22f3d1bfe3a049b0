//! The wire contract is language-neutral: a Python client generated from the `.proto` files
//! with grpcio (in this test's own virtual environment) creates a session on a server
//! process and receives one force per tool state, in order; a malformed message gets a clear
//! status and the session goes on being served; a client process killed mid-stream is
//! noticed and released while other sessions keep being served; a viewer slower than its
//! frame rate sees fresh frames on the acknowledged stream (WatchAcked).
//!
//! Needs `python3` with `venv` and access to PyPI (grpcio, grpcio-tools), which `.ci/run`
//! checks for.

use crate::util;

use std::path::Path;
use std::process::Command;

const CLIENT: &str = r#"
import json, sys
import grpc
sys.path.insert(0, sys.argv[2])
from vademecum.v1 import session_pb2, session_pb2_grpc, interaction_pb2, interaction_pb2_grpc

channel = grpc.insecure_channel(sys.argv[1])
sessions = session_pb2_grpc.SessionsStub(channel)
info = sessions.CreateSession(session_pb2.CreateSessionRequest(builtin="organ", bundle_dir="organ", label="python"))

def tools():
    for i in range(200):
        z = 0.030 - 0.005 * (i % 100) / 100.0
        yield interaction_pb2.ToolState(
            session_id=info.session_id if i == 0 else "",
            seq=i,
            kind=interaction_pb2.TOOL_KIND_PROBE,
            position_m=interaction_pb2.Vec3(x=0.0, y=0.0, z=z),
        )

stub = interaction_pb2_grpc.InteractionStub(channel)
seqs, forces = [], []
for r in stub.Interact(tools()):
    seqs.append(r.seq)
    forces.append([r.force_n.x, r.force_n.y, r.force_n.z])
try:
    sessions.GetSession(session_pb2.GetSessionRequest(session_id="no-such-session"))
    missing = "OK"
except grpc.RpcError as e:
    missing = e.code().name
# a malformed message: bytes that are not a GetSessionRequest
raw = channel.unary_unary("/vademecum.v1.Sessions/GetSession", request_serializer=lambda b: b, response_deserializer=lambda b: b)
try:
    raw(b"\xff\xff\xff\xff")
    malformed = ["OK", ""]
except grpc.RpcError as e:
    malformed = [e.code().name, e.details()]
# and the session is still served afterwards
after = sessions.GetSession(session_pb2.GetSessionRequest(session_id=info.session_id)).stats.answered
sessions.CloseSession(session_pb2.CloseSessionRequest(session_id=info.session_id))
print(json.dumps({"effects": list(info.effects), "seqs": seqs, "forces": forces, "missing": missing, "malformed": malformed, "after": after}))
"#;

/// Streams tool states until killed, saying "streaming" once answers flow.
const FOREVER: &str = r#"
import sys, itertools
import grpc
sys.path.insert(0, sys.argv[2])
from vademecum.v1 import session_pb2, session_pb2_grpc, interaction_pb2, interaction_pb2_grpc
channel = grpc.insecure_channel(sys.argv[1])
info = session_pb2_grpc.SessionsStub(channel).CreateSession(session_pb2.CreateSessionRequest(builtin="organ", bundle_dir="organ"))
def tools():
    for i in itertools.count():
        yield interaction_pb2.ToolState(session_id=info.session_id, seq=i, position_m=interaction_pb2.Vec3(z=0.028))
for r in interaction_pb2_grpc.InteractionStub(channel).Interact(tools()):
    if r.seq == 20:
        print("streaming", info.session_id, flush=True)
"#;

/// Two slow viewers (each takes 250 ms over every message) of a session a probe is pressing,
/// one on WatchAcked and one on Watch, for argv[3] seconds: prints, per viewer, how many ticks
/// old each message was when the viewer got it (the session's latest tick is known from the
/// interaction stream's answers, about every 5 ms).
const SLOW_VIEWERS: &str = r#"
import json, queue, sys, threading, time
import grpc
sys.path.insert(0, sys.argv[2])
from vademecum.v1 import session_pb2, session_pb2_grpc, interaction_pb2, interaction_pb2_grpc, viewing_pb2, viewing_pb2_grpc

channel = grpc.insecure_channel(sys.argv[1])
sessions = session_pb2_grpc.SessionsStub(channel)
sid = sessions.CreateSession(session_pb2.CreateSessionRequest(builtin="organ", bundle_dir="organ", label="slow viewers")).session_id
seconds, process = float(sys.argv[3]), 0.25
latest = {"tick": 0}
stop = threading.Event()

def tools():
    i = 0
    while not stop.is_set():
        z = 0.030 - 0.004 * ((i % 200) / 200.0)
        yield interaction_pb2.ToolState(session_id=sid if i == 0 else "", seq=i, kind=interaction_pb2.TOOL_KIND_PROBE,
                                        position_m=interaction_pb2.Vec3(x=0.0, y=0.0, z=z))
        i += 1
        time.sleep(0.005)

def interact():
    for r in interaction_pb2_grpc.InteractionStub(channel).Interact(tools()):
        latest["tick"] = r.tick

viewing = viewing_pb2_grpc.ViewingStub(channel)
ages = {"acked": [], "plain": []}
messages = {"acked": [], "plain": []}

def take(name, f):
    if f.message > 0 and latest["tick"] > 0:
        ages[name].append(latest["tick"] - f.tick)
        messages[name].append(f.message)
    time.sleep(process)

def acked():
    acks = queue.Queue()
    def controls():
        yield viewing_pb2.ViewerControl(start=viewing_pb2.WatchRequest(session_id=sid, rate_hz=30))
        while True:
            m = acks.get()
            if m is None:
                return
            yield viewing_pb2.ViewerControl(ack=m)
    call = viewing.WatchAcked(controls())
    for f in call:
        take("acked", f)
        acks.put(f.message)
        if stop.is_set():
            break
    acks.put(None)
    call.cancel()

def plain():
    call = viewing.Watch(viewing_pb2.WatchRequest(session_id=sid, rate_hz=30))
    for f in call:
        take("plain", f)
        if stop.is_set():
            break
    call.cancel()

threading.Thread(target=interact, daemon=True).start()
viewers = [threading.Thread(target=acked), threading.Thread(target=plain)]
for v in viewers:
    v.start()
time.sleep(seconds)
stop.set()
for v in viewers:
    v.join()
sessions.CloseSession(session_pb2.CloseSessionRequest(session_id=sid))
print(json.dumps({"ages": ages, "messages": messages}))
"#;

fn run(cmd: &mut Command, what: &str) -> String {
    let o = cmd.output().unwrap_or_else(|e| panic!("{what}: cannot run: {e}"));
    assert!(
        o.status.success(),
        "{what} failed:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn a_python_grpcio_client_creates_a_session_and_receives_forces() {
    let venv = tempfile::tempdir().unwrap();
    let v = venv.path();
    run(Command::new("python3").args(["-m", "venv"]).arg(v.join("env")), "python3 -m venv");
    let py = v.join("env/bin/python");
    run(
        Command::new(&py).args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            "grpcio",
            "grpcio-tools",
        ]),
        "pip install grpcio grpcio-tools",
    );
    let proto = Path::new(env!("CARGO_MANIFEST_DIR")).join("../proto");
    let gen_dir = v.join("gen");
    std::fs::create_dir_all(&gen_dir).unwrap();
    let mut protoc = Command::new(&py);
    protoc
        .args(["-m", "grpc_tools.protoc", "-I"])
        .arg(&proto)
        .arg(format!("--python_out={}", gen_dir.display()))
        .arg(format!("--grpc_python_out={}", gen_dir.display()));
    for f in ["info", "session", "interaction", "viewing"] {
        protoc.arg(format!("vademecum/v1/{f}.proto"));
    }
    run(&mut protoc, "grpc_tools.protoc");
    let server = util::Server::start(&[], &[]);
    let addr = server.url.trim_start_matches("http://").to_string();
    std::fs::write(v.join("client.py"), CLIENT).unwrap();
    let out = run(
        Command::new(&py).arg(v.join("client.py")).arg(&addr).arg(&gen_dir),
        "the Python client",
    );
    let r: serde_json::Value = serde_json::from_str(out.trim()).expect("the client prints JSON");
    assert_eq!(r["effects"], serde_json::json!(["palpation"]));
    let seqs: Vec<u64> = r["seqs"].as_array().unwrap().iter().map(|s| s.as_u64().unwrap()).collect();
    assert_eq!(seqs, (0..200).collect::<Vec<_>>(), "one response per tool state, in order");
    let pressing = r["forces"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f[2].as_f64().unwrap() > 0.0)
        .count();
    assert!(
        pressing > 50,
        "the probe pressing into the top of the organ is pushed back up ({pressing} of 200)"
    );
    assert_eq!(r["missing"], "NOT_FOUND");
    // tonic refuses undecodable bytes before any handler runs, naming the decode failure
    assert_eq!(r["malformed"][0], "INTERNAL", "{}", r["malformed"]);
    assert!(r["malformed"][1].as_str().unwrap().contains("decode"), "{}", r["malformed"]);
    assert_eq!(r["after"], 200);

    // a client process killed mid-stream: the server notices, and keeps serving others
    std::fs::write(v.join("forever.py"), FOREVER).unwrap();
    let mut child = Command::new(&py)
        .arg(v.join("forever.py"))
        .arg(&addr)
        .arg(&gen_dir)
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(child.stdout.take().unwrap()), &mut line).unwrap();
    assert!(line.starts_with("streaming"), "{line}");
    child.kill().unwrap();
    child.wait().unwrap();
    let rt = util::runtime();
    rt.block_on(async {
        let client = vademecum_client::Client::connect(server.url.clone()).await.unwrap();
        let s = client
            .create_session(vademecum_client::SceneSpec::Builtin("organ".into()), "organ", "after the kill")
            .await
            .unwrap();
        let mut tools = s.interact().await.unwrap();
        for i in 0..100u64 {
            tools.send(vademecum_client::tool_at(i, [0.0, 0.0, 0.028])).await.unwrap();
            assert_eq!(tools.next().await.unwrap().unwrap().seq, i);
        }
        // the killed client's stream is gone from its session
        let killed = client.list_sessions().await.unwrap();
        let orphan = killed
            .iter()
            .find(|x| x.label.is_empty())
            .expect("the killed client's session is listed");
        let mut interacting = orphan.stats.as_ref().map_or(0, |s| s.interacting_clients);
        for _ in 0..100 {
            if interacting == 0 {
                break;
            }
            tokio::time::sleep(std::time::Duration::from_millis(50)).await;
            interacting = client
                .session(&orphan.session_id)
                .await
                .unwrap()
                .stats()
                .await
                .unwrap()
                .interacting_clients;
        }
        assert_eq!(interacting, 0, "the killed client's stream was released");
    });

    // a viewer slower than its rate: on WatchAcked every frame is fresh when it arrives
    std::fs::write(v.join("slow_viewers.py"), SLOW_VIEWERS).unwrap();
    let seconds = 8.0;
    let out = run(
        Command::new(&py)
            .arg(v.join("slow_viewers.py"))
            .arg(&addr)
            .arg(&gen_dir)
            .arg(seconds.to_string()),
        "the slow Python viewers",
    );
    let r: serde_json::Value = serde_json::from_str(out.trim()).expect("the viewers print JSON");
    let ints = |k: &str, w: &str| -> Vec<i64> { r[k][w].as_array().unwrap().iter().map(|x| x.as_i64().unwrap()).collect() };
    let (acked, plain) = (ints("ages", "acked"), ints("ages", "plain"));
    eprintln!(
        "slow viewers (250 ms per message, 30 Hz asked): WatchAcked {} messages, oldest {} ms; Watch {} messages, oldest {} ms",
        acked.len(),
        acked.iter().max().unwrap_or(&0),
        plain.len(),
        plain.iter().max().unwrap_or(&0)
    );
    // the viewer reads about 4 messages a second
    assert!(acked.len() as f64 >= 0.5 * seconds / 0.25, "{} messages", acked.len());
    // with the default window of 2, a message waits at most for the viewer to finish the
    // one before it (250 ms), plus one period (33 ms) and the loopback; 250 ms of slack for
    // a busy machine — far below the seconds a backlog builds up over 8 s
    let oldest = acked.iter().copied().max().unwrap();
    assert!(
        oldest <= 250 + 33 + 250,
        "a WatchAcked frame was {oldest} ms old when the viewer got it: {acked:?}"
    );
    // messages are numbered without gaps: none queued and lost on the way
    let numbers = ints("messages", "acked");
    assert!(
        numbers.windows(2).all(|w| w[1] == w[0] + 1),
        "WatchAcked numbers its messages 1, 2, 3, …: {numbers:?}"
    );
}
