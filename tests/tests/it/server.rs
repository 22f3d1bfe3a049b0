//! The server as a separate process, driven through the client SDK: interaction answers
//! every tool state in order with the engine's own force, viewers get frames at their rates
//! while interaction continues, bad requests get clear status codes and the other sessions
//! keep being served, tokens are enforced, metrics are exported.

use crate::util;

use std::sync::Arc;
use std::time::{Duration, Instant};

use vademecum_client::{Client, ErrorKind, SceneSpec, f32s, tool_at};
use vademecum_engine::bundle;
use vademecum_engine::pipeline::{Events, Pipeline, ToolInput};
use vademecum_engine::scene::Scene;

/// The built-in organ's probe path used by the tests: circles over the middle of the
/// accessible top surface (z ≈ 0.025 m there; probe radius 4 mm), pressing up to 5 mm deep
/// and lifting off again.
fn path(i: usize) -> [f64; 3] {
    let s = i as f64 * 1e-3;
    [
        0.02 * (3.0 * s).cos(),
        0.015 * (3.0 * s).sin(),
        0.030 - 0.006 * (5.0 * s).sin().abs(),
    ]
}

/// The engine's own answer for the same tool state, from the same bundle on disk.
fn direct(root: &std::path::Path) -> Pipeline {
    let scene = Scene::builtin("organ").unwrap();
    let b = Arc::new(bundle::load_bundle(&root.join("organ/lobe.bundle")).unwrap());
    Pipeline::for_scene(&scene, &[b]).unwrap()
}

#[test]
fn a_client_streams_5000_tool_states_and_gets_5000_engine_forces_in_order() {
    let server = util::Server::start(&[], &[]);
    let mut engine = direct(util::bundles());
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let session = client
            .create_session(SceneSpec::Builtin("organ".into()), "organ", "e2e")
            .await
            .unwrap();
        assert_eq!(session.info().effects, ["palpation"]);
        assert_eq!(session.info().organs, ["lobe"]);
        let mut tools = session.interact().await.unwrap();
        let n = 5000;
        let (mut received, mut touching) = (0usize, 0usize);
        // keep at most 200 in flight, as a frontend streaming at a steady rate would
        for i in 0..n + 200 {
            if i < n {
                let mut t = tool_at(i as u64, path(i));
                t.client_time_us = 3 * i as u64;
                tools.send(t).await.unwrap();
            }
            if i >= 200 {
                let r = tools.next().await.unwrap().expect("a response per tool state");
                assert_eq!(r.seq, received as u64, "responses out of order");
                assert_eq!(r.client_time_us, 3 * received as u64);
                let expected = engine.tick(&ToolInput {
                    position_m: path(received),
                    ..ToolInput::default()
                });
                let f = r.force_n.unwrap();
                assert_eq!([f.x, f.y, f.z], expected.force_n, "tool state {received}");
                // a session falling back under the machine's load flags its answers; the force
                // of linear palpation is the same at either fidelity
                assert_eq!(r.events & !Events::REDUCED_FIDELITY, expected.events.0);
                // every answer carries its error estimate: the engine's, 0 out of contact
                assert_eq!(r.force_error_n, expected.force_error_n, "tool state {received}");
                let e = r.force_error_n.expect("linear palpation estimates every force");
                assert!(e >= 0.0 && (r.events & Events::CONTACT != 0 || e == 0.0));
                assert!(r.server_answered_us >= r.server_received_us);
                touching += usize::from(r.events & Events::CONTACT != 0);
                received += 1;
            }
        }
        assert_eq!(received, n);
        assert!(touching > 500, "the path should touch the organ often ({touching} of {n})");
        tools.finish();
        assert!(tools.next().await.unwrap().is_none(), "the stream ends once everything is answered");
        let stats = session.close().await.unwrap();
        assert_eq!((stats.answered, stats.dropped, stats.rejected), (n as u64, 0, 0));
    });
}

#[test]
fn viewers_at_30_and_5_hz_get_numbered_frames_while_interaction_continues() {
    let server = util::Server::start(&[], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let session = client
            .create_session(SceneSpec::Builtin("organ".into()), "organ", "view")
            .await
            .unwrap();
        let watch = |rate: f64| {
            let s = session.clone();
            tokio::spawn(async move {
                let mut frames = s.watch(rate).await.unwrap();
                let first = frames.message().await.unwrap().unwrap();
                let g = first.geometry.expect("the first frame carries the geometry");
                let nodes = g.organs[0].node_count as usize;
                assert_eq!(f32s(&g.organs[0].positions).len(), 3 * nodes);
                let (mut seqs, mut moved, mut beats) = (Vec::new(), false, 0usize);
                let until = Instant::now() + Duration::from_secs(3);
                while Instant::now() < until {
                    let Ok(Ok(Some(f))) = tokio::time::timeout(Duration::from_secs(1), frames.message()).await else {
                        break;
                    };
                    if f.heartbeat {
                        // nothing new since frame f.seq: no displacements
                        assert!(f.organs.is_empty() && f.seq == seqs.last().copied().unwrap_or(0));
                        beats += 1;
                        continue;
                    }
                    assert_eq!(f32s(&f.organs[0].displacements).len(), 3 * nodes);
                    moved |= f32s(&f.organs[0].displacements).iter().any(|&u| u != 0.0);
                    seqs.push(f.seq);
                }
                (seqs, moved, beats)
            })
        };
        let viewers = [watch(30.0), watch(30.0), watch(5.0)];
        let mut tools = session.interact().await.unwrap();
        let start = Instant::now();
        let mut i = 0;
        while start.elapsed() < Duration::from_millis(3200) {
            tools.send(tool_at(i as u64, path(i))).await.unwrap();
            tools.next().await.unwrap().unwrap();
            i += 1;
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        let mut counts = Vec::new();
        for v in viewers {
            let (seqs, moved, beats) = v.await.unwrap();
            assert!(seqs.windows(2).all(|w| w[1] > w[0]), "frame numbers increase: {seqs:?}");
            // numbered per stream: consecutive unless this viewer itself fell behind
            assert_eq!(seqs.first(), Some(&1), "{seqs:?}");
            assert!(moved, "frames show the organ displaced under the probe");
            counts.push(seqs.len() + beats);
        }
        // rates (frames and heartbeats): behaviour, not timing — each 30 Hz viewer gets several
        // times what the 5 Hz one gets
        assert!(counts[0] >= 30 && counts[1] >= 30, "30 Hz viewers got {counts:?} messages in 3 s");
        assert!((5..=20).contains(&counts[2]), "the 5 Hz viewer got {} messages in 3 s", counts[2]);
        let stats = session.stats().await.unwrap();
        assert!(stats.frames > 0 && stats.answered as usize == i);
    });
}

#[test]
fn an_idle_session_sends_heartbeats_at_the_viewers_rate_from_the_start() {
    let server = util::Server::start(&[], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let session = client
            .create_session(SceneSpec::Builtin("organ".into()), "organ", "idle")
            .await
            .unwrap();
        let mut frames = session.watch(10.0).await.unwrap();
        assert!(frames.message().await.unwrap().unwrap().geometry.is_some());
        let mut ticks = Vec::new();
        for _ in 0..5 {
            let f = tokio::time::timeout(Duration::from_secs(2), frames.message())
                .await
                .expect("a message within 2 s although no tool state was sent")
                .unwrap()
                .unwrap();
            assert!(f.heartbeat && f.organs.is_empty() && f.seq == 0, "{f:?}");
            ticks.push(f.tick);
        }
        assert!(ticks.windows(2).all(|w| w[1] > w[0]), "the session's clock advances: {ticks:?}");
    });
}

#[test]
fn bad_requests_get_clear_status_codes_and_other_sessions_keep_being_served() {
    let server = util::Server::start(&["--max-sessions", "2"], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let good = client.create_session(SceneSpec::Builtin("organ".into()), "organ", "good").await.unwrap();
        // unknown session
        let e = client.session("nope").await.unwrap_err();
        assert_eq!(e.kind(), ErrorKind::NotFound, "{e}");
        // no bundle there
        let e = client.create_session(SceneSpec::Builtin("organ".into()), "missing", "").await.unwrap_err();
        assert_eq!(e.kind(), ErrorKind::FailedPrecondition, "{e}");
        assert!(e.to_string().contains("lobe.bundle"), "{e}");
        // a bundle from another scene
        let e = client.create_session(SceneSpec::Builtin("patch".into()), "organ", "").await.unwrap_err();
        assert_eq!(e.kind(), ErrorKind::FailedPrecondition, "{e}");
        // malformed scene text: file, line and key in the message
        let e = client.create_session(SceneSpec::Toml("[scene]\nname = 3\n".into()), "organ", "").await.unwrap_err();
        assert_eq!(e.kind(), ErrorKind::InvalidArgument, "{e}");
        assert!(e.to_string().contains("inline.toml:2"), "{e}");
        // paths outside the roots
        let e = client.create_session(SceneSpec::Path("../x.toml".into()), "organ", "").await.unwrap_err();
        assert!(e.to_string().contains(".."), "{e}");
        // oversize message (an inline scene over the 1 MiB request limit)
        let e = client.create_session(SceneSpec::Toml("#".repeat(2 << 20)), "organ", "").await.unwrap_err();
        // tonic refuses it while decoding, before any handler runs
        assert!(
            matches!(e, vademecum_client::SdkError::Status(ref s) if matches!(s.code(), tonic::Code::OutOfRange | tonic::Code::ResourceExhausted)),
            "{e}"
        );
        // NaN poses are answered with zero force and counted, and the stream goes on
        let mut tools = good.interact().await.unwrap();
        tools.send(tool_at(0, [f64::NAN, 0.0, 0.05])).await.unwrap();
        let r = tools.next().await.unwrap().unwrap();
        let f = r.force_n.unwrap();
        assert_eq!((f.x, f.y, f.z), (0.0, 0.0, 0.0));
        assert!(r.events & Events::REJECTED_INPUT != 0);
        tools.send(tool_at(1, path(0))).await.unwrap();
        assert_eq!(tools.next().await.unwrap().unwrap().seq, 1);
        // a client killed mid-stream: its own connection, dropped with tool states in flight
        {
            let other = Client::connect(server.url.clone()).await.unwrap();
            let s = other.session(good.id()).await.unwrap();
            let mut t = s.interact().await.unwrap();
            for i in 0..100 {
                t.send(tool_at(i, path(i as usize))).await.unwrap();
            }
            t.next().await.unwrap();
        }
        // the session cap
        let _second = client.create_session(SceneSpec::Builtin("organ".into()), "organ", "second").await.unwrap();
        let e = client.create_session(SceneSpec::Builtin("organ".into()), "organ", "third").await.unwrap_err();
        assert_eq!(e.kind(), ErrorKind::ResourceExhausted, "{e}");
        // and the first session is still served
        for i in 2..50u64 {
            tools.send(tool_at(i, path(i as usize))).await.unwrap();
            assert_eq!(tools.next().await.unwrap().unwrap().seq, i);
        }
        let stats = good.stats().await.unwrap();
        assert_eq!(stats.rejected, 1);
    });
}

#[test]
fn tokens_are_required_and_sessions_are_private_to_their_token() {
    let server = util::Server::start(&[], &[("VADEMECUM_TOKENS", "alice-token,bob-token")]);
    let rt = util::runtime();
    rt.block_on(async {
        let anon = Client::connect(server.url.clone()).await.unwrap();
        assert_eq!(anon.list_sessions().await.unwrap_err().kind(), ErrorKind::Unauthenticated);
        let wrong = Client::connect_with_token(server.url.clone(), Some("mallory")).await.unwrap();
        assert_eq!(wrong.list_sessions().await.unwrap_err().kind(), ErrorKind::Unauthenticated);
        let alice = Client::connect_with_token(server.url.clone(), Some("alice-token")).await.unwrap();
        let bob = Client::connect_with_token(server.url.clone(), Some("bob-token")).await.unwrap();
        let s = alice
            .create_session(SceneSpec::Builtin("organ".into()), "organ", "a")
            .await
            .unwrap();
        assert_eq!(alice.list_sessions().await.unwrap().len(), 1);
        assert!(bob.list_sessions().await.unwrap().is_empty());
        assert_eq!(bob.session(s.id()).await.unwrap_err().kind(), ErrorKind::NotFound);
    });
}

#[test]
fn metrics_export_tick_latency_histograms_misses_and_clients() {
    let server = util::Server::start(&["--metrics", "127.0.0.1:0"], &[]);
    let rt = util::runtime();
    let (id, text) = rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let session = client
            .create_session(SceneSpec::Builtin("organ".into()), "organ", "m")
            .await
            .unwrap();
        let id = session.id().to_string();
        let mut tools = session.interact().await.unwrap();
        for i in 0..300u64 {
            tools.send(tool_at(i, path(i as usize))).await.unwrap();
            tools.next().await.unwrap().unwrap();
        }
        // scrape while the stream is open
        let addr = server.metrics.clone().expect("metrics address");
        let text = tokio::task::spawn_blocking(move || {
            use std::io::{Read, Write};
            let mut s = std::net::TcpStream::connect(addr).unwrap();
            s.write_all(b"GET /metrics HTTP/1.0\r\nHost: x\r\n\r\n").unwrap();
            let mut out = String::new();
            s.read_to_string(&mut out).unwrap();
            out
        })
        .await
        .unwrap();
        (id, text)
    });
    assert!(text.starts_with("HTTP/1.0 200") || text.starts_with("HTTP/1.1 200"), "{text}");
    assert!(text.contains("vademecum_sessions 1"), "{text}");
    // series are named by the session's ordinal and label, never by its id
    assert!(text.contains("label=\"m\""), "{text}");
    assert!(!text.contains(&id), "the session id is on the unauthenticated page: {text}");
    assert!(text.contains("vademecum_tick_work_seconds_bucket{session="), "{text}");
    assert!(text.contains("vademecum_deadline_misses_total{session="), "{text}");
    assert!(
        text.contains("vademecum_tick_worker_sessions{worker=\"0\"}") && text.contains("vademecum_tick_worker_utilisation{worker=\"0\"}"),
        "{text}"
    );
    assert!(
        text.contains("vademecum_frame_worker_sessions{worker=\"0\"}") && text.contains("vademecum_frame_worker_utilisation{worker=\"0\"}"),
        "{text}"
    );
    // a palpation session's memory by part, its effect's among them and nothing for effects
    // it does not have
    let memory: Vec<(&str, u64)> = text
        .lines()
        .filter(|l| l.starts_with("vademecum_session_memory_bytes{"))
        .filter_map(|l| {
            let part = l.split("part=\"").nth(1)?.split('"').next()?;
            Some((part, l.rsplit(' ').next()?.parse().ok()?))
        })
        .collect();
    let parts: Vec<&str> = memory.iter().map(|m| m.0).collect();
    assert_eq!(parts, ["effect:palpation", "queues", "histograms", "frames"], "{text}");
    assert!(memory.iter().all(|m| m.1 > 0), "{memory:?}");
    assert!(
        text.contains("vademecum_interacting_clients{session=") && text.contains("} 1"),
        "{text}"
    );
    let answers = text
        .lines()
        .find(|l| l.starts_with("vademecum_answers_total{"))
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|v| v.parse::<u64>().ok())
        .unwrap();
    assert_eq!(answers, 300);
}

#[test]
fn tls_with_tokens_serves_remote_clients_and_refuses_plain_ones() {
    let certs = tempfile::tempdir().unwrap();
    let ck = rcgen::generate_simple_self_signed(vec!["localhost".to_string()]).unwrap();
    let (cert, key) = (certs.path().join("cert.pem"), certs.path().join("key.pem"));
    std::fs::write(&cert, ck.cert.pem()).unwrap();
    std::fs::write(&key, ck.signing_key.serialize_pem()).unwrap();
    let (c, k) = (cert.to_string_lossy().into_owned(), key.to_string_lossy().into_owned());
    let server = util::Server::start(&["--tls-cert", &c, "--tls-key", &k], &[("VADEMECUM_TOKENS", "t0k3n")]);
    let https = server.url.replace("http://127.0.0.1", "https://localhost");
    let rt = util::runtime();
    rt.block_on(async {
        let ca = ck.cert.pem();
        let client = Client::connect_tls(https.clone(), ca.as_bytes(), "localhost", Some("t0k3n"))
            .await
            .unwrap();
        let session = client
            .create_session(SceneSpec::Builtin("organ".into()), "organ", "tls")
            .await
            .unwrap();
        let mut tools = session.interact().await.unwrap();
        tools.send(tool_at(0, path(0))).await.unwrap();
        assert_eq!(tools.next().await.unwrap().unwrap().seq, 0);
        // the right CA but no token
        let anon = Client::connect_tls(https, ca.as_bytes(), "localhost", None).await.unwrap();
        assert_eq!(anon.list_sessions().await.unwrap_err().kind(), ErrorKind::Unauthenticated);
        // a plain-text client cannot talk to it
        let plain = match Client::connect(server.url.clone()).await {
            Ok(c) => c.list_sessions().await.map(|_| ()),
            Err(e) => Err(e),
        };
        assert!(plain.is_err(), "a plain HTTP/2 client must not get through");
    });
}

/// `vademecum health`, the probe a container's HEALTHCHECK runs (its image has no shell): 0 when
/// the server serves, 1 for a service it does not know, 2 when nothing answers; no token needed.
#[test]
fn the_health_probe_says_whether_the_server_serves_by_its_exit_status() {
    let probe = |args: &[&str]| {
        let o = std::process::Command::new(util::vademecum_bin())
            .arg("health")
            .args(args)
            .output()
            .expect("vademecum runs");
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stdout).into_owned(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let mut server = util::Server::start(&[], &[("VADEMECUM_TOKENS", "t")]);
    let (code, out, _) = probe(&["--addr", &server.url]);
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("is serving"), "{out}");
    let (code, _, _) = probe(&["--addr", &server.url, "--service", "vademecum.v1.Interaction"]);
    assert_eq!(code, Some(0));
    let (code, out, _) = probe(&["--addr", &server.url, "--service", "no.such.Service"]);
    assert_eq!(code, Some(1), "{out}");
    assert!(out.contains("SERVICE_UNKNOWN"), "{out}");
    // nothing listening any more: an error, said, within the deadline
    let url = server.url.clone();
    server.kill();
    let (code, _, err) = probe(&["--addr", &url, "--timeout", "5"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("cannot connect") || err.contains("no answer"), "{err}");
    let (code, _, err) = probe(&["--addr", "not a url"]);
    assert_eq!(code, Some(2), "{err}");
}

#[test]
fn the_standard_health_service_and_reflection_describe_the_server() {
    use tonic_health::pb::{HealthCheckRequest, health_check_response::ServingStatus, health_client::HealthClient};
    use tonic_reflection::pb::v1::ServerReflectionRequest;
    use tonic_reflection::pb::v1::server_reflection_client::ServerReflectionClient;
    use tonic_reflection::pb::v1::server_reflection_request::MessageRequest;
    use tonic_reflection::pb::v1::server_reflection_response::MessageResponse;
    let server = util::Server::start(&[], &[("VADEMECUM_TOKENS", "t")]);
    let rt = util::runtime();
    rt.block_on(async {
        let channel = tonic::transport::Channel::from_shared(server.url.clone())
            .unwrap()
            .connect()
            .await
            .unwrap();
        // health and reflection answer without a token: orchestrators probe them
        let mut health = HealthClient::new(channel.clone());
        for service in [
            "",
            "vademecum.v1.Info",
            "vademecum.v1.Sessions",
            "vademecum.v1.Interaction",
            "vademecum.v1.Viewing",
        ] {
            let r = health
                .check(HealthCheckRequest { service: service.into() })
                .await
                .unwrap()
                .into_inner();
            assert_eq!(r.status, ServingStatus::Serving as i32, "{service}");
        }
        let mut reflection = ServerReflectionClient::new(channel);
        let req = ServerReflectionRequest {
            host: String::new(),
            message_request: Some(MessageRequest::ListServices(String::new())),
        };
        let mut responses = reflection
            .server_reflection_info(tokio_stream::iter(vec![req]))
            .await
            .unwrap()
            .into_inner();
        let r = responses.message().await.unwrap().unwrap();
        let Some(MessageResponse::ListServicesResponse(list)) = r.message_response else {
            panic!("not a service list: {r:?}");
        };
        let names: Vec<String> = list.service.into_iter().map(|s| s.name).collect();
        for s in [
            "vademecum.v1.Sessions",
            "vademecum.v1.Interaction",
            "vademecum.v1.Viewing",
            "vademecum.v1.Info",
        ] {
            assert!(names.iter().any(|n| n == s), "{s} missing from {names:?}");
        }
    });
}

/// A raw WatchAcked stream: the sender of controls and the frames.
async fn watch_acked(
    url: &str,
    first: vademecum_client::pb::ViewerControl,
) -> (
    tokio::sync::mpsc::Sender<vademecum_client::pb::ViewerControl>,
    Result<tonic::Streaming<vademecum_client::pb::Frame>, tonic::Status>,
) {
    use vademecum_client::pb;
    let channel = tonic::transport::Channel::from_shared(url.to_string())
        .unwrap()
        .connect()
        .await
        .unwrap();
    let mut c = pb::viewing_client::ViewingClient::new(channel).max_decoding_message_size(256 << 20);
    let (tx, rx) = tokio::sync::mpsc::channel(8);
    tx.send(first).await.unwrap();
    let frames = c
        .watch_acked(tokio_stream::wrappers::ReceiverStream::new(rx))
        .await
        .map(|r| r.into_inner());
    (tx, frames)
}

fn start(session_id: &str, rate_hz: f64, window: u32) -> vademecum_client::pb::ViewerControl {
    use vademecum_client::pb;
    pb::ViewerControl {
        control: Some(pb::viewer_control::Control::Start(pb::WatchRequest {
            session_id: session_id.into(),
            rate_hz,
            window,
        })),
    }
}

fn ack(m: u64) -> vademecum_client::pb::ViewerControl {
    use vademecum_client::pb;
    pb::ViewerControl {
        control: Some(pb::viewer_control::Control::Ack(m)),
    }
}

#[test]
fn an_acknowledged_viewer_never_has_more_than_its_window_in_flight() {
    let server = util::Server::start(&[], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let session = client
            .create_session(SceneSpec::Builtin("organ".into()), "organ", "acked")
            .await
            .unwrap();
        let quiet = Duration::from_millis(400);
        for window in [1u32, 3] {
            // 60 Hz: a message every 17 ms if the window allowed it
            let (tx, frames) = watch_acked(&server.url, start(session.id(), 60.0, window)).await;
            let mut frames = frames.unwrap();
            let g = frames.message().await.unwrap().unwrap();
            assert!(g.geometry.is_some() && g.message == 0);
            for m in 1..u64::from(window) {
                let f = frames.message().await.unwrap().unwrap();
                assert_eq!(f.message, m, "messages are numbered without gaps");
            }
            // the window is full: nothing more until an acknowledgement
            assert!(
                tokio::time::timeout(quiet, frames.message()).await.is_err(),
                "window {window}: a message beyond the window arrived"
            );
            tx.send(ack(0)).await.unwrap();
            let f = tokio::time::timeout(Duration::from_secs(2), frames.message())
                .await
                .expect("an acknowledgement makes room at once")
                .unwrap()
                .unwrap();
            assert_eq!(f.message, u64::from(window));
            assert!(tokio::time::timeout(quiet, frames.message()).await.is_err());
        }

        // the SDK's viewer acknowledges each message as it asks for the next
        let mut viewer = session.watch_acked(60.0, 1).await.unwrap();
        for m in 0..6 {
            let f = viewer.next().await.unwrap().unwrap();
            assert_eq!(f.message, m);
            assert_eq!(f.geometry.is_some(), m == 0);
        }

        // bad controls: clear statuses
        let (_tx, frames) = watch_acked(&server.url, ack(0)).await;
        assert_eq!(frames.unwrap_err().code(), tonic::Code::InvalidArgument);
        let (_tx, frames) = watch_acked(&server.url, start(session.id(), 30.0, 17)).await;
        let e = frames.unwrap_err();
        assert_eq!(e.code(), tonic::Code::InvalidArgument);
        assert!(e.message().contains("16"), "{}", e.message());
        // a rate too low to send anything (1e-300 Hz held a viewer slot and sent nothing) is
        // refused with the range, on both viewer calls
        for rate in [1e-300, 0.05, -1.0] {
            let (_tx, frames) = watch_acked(&server.url, start(session.id(), rate, 0)).await;
            let e = frames.unwrap_err();
            assert_eq!(e.code(), tonic::Code::InvalidArgument, "{rate} Hz: {e}");
            assert!(e.message().contains("0.1"), "{}", e.message());
            let e = session.watch(rate).await.unwrap_err();
            assert!(e.to_string().contains("0.1"), "{rate} Hz: {e}");
        }
        let (_tx, frames) = watch_acked(&server.url, start("no-such-session", 30.0, 0)).await;
        assert_eq!(frames.unwrap_err().code(), tonic::Code::NotFound);
        let (tx, frames) = watch_acked(&server.url, start(session.id(), 30.0, 0)).await;
        let mut frames = frames.unwrap();
        frames.message().await.unwrap().unwrap();
        tx.send(ack(1000)).await.unwrap();
        let e = loop {
            match frames.message().await {
                Ok(Some(_)) => continue, // the window's second message may come first
                Ok(None) => panic!("the stream ended without a status"),
                Err(e) => break e,
            }
        };
        assert_eq!(e.code(), tonic::Code::InvalidArgument);
        assert!(e.message().contains("ack 1000"), "{}", e.message());
    });
}

/// Two hands (issue 46): the organ with a second probe, `left`, each probe moved by name from
/// a client stream of its own. Every answer is the engine's own for the two tools ticked
/// together (`Pipeline::tick_tools`, replayed here in the order the server saw the states);
/// the probe held still feels the other's press; frames list both tools; a name the scene
/// does not have ends the stream with INVALID_ARGUMENT.
#[test]
fn two_clients_each_move_one_probe_of_a_session_and_feel_each_other() {
    use vademecum_client::named;
    use vademecum_engine::pipeline::TickState;
    let text = util::two_probes().to_string();
    let dir = util::bundles();
    let scene = Scene::from_toml(&text, "two_probes.toml").unwrap();
    let b = Arc::new(bundle::load_bundle(&dir.join("two_probes/lobe.bundle")).unwrap());
    let mut engine = Pipeline::for_scene(&scene, &[b]).unwrap();
    let server = util::Server::start(&[], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let session = client
            .create_session(SceneSpec::Toml(text.clone()), "two_probes", "two hands")
            .await
            .unwrap();
        let names: Vec<&str> = session.info().tools.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(names, ["probe", "left"]);
        let (mut right, mut left) = (session.interact().await.unwrap(), session.interact().await.unwrap());
        // the left probe rests 1.5 mm into the top 15 mm from the middle; the right one
        // presses in at the middle, deeper and deeper
        let at_left = [0.015, 0.0, 0.025 + 0.004 - 0.0015];
        let input = |tool: usize, p: [f64; 3]| ToolInput {
            tool,
            position_m: p,
            ..ToolInput::default()
        };
        let mut held: [Option<ToolInput>; 2] = [None, None];
        // the engine's answer to `moved`, with the other tool at its last state (slot order)
        let mut replay = |moved: ToolInput, held: &mut [Option<ToolInput>; 2]| -> TickState {
            held[moved.tool] = Some(moved);
            let set: Vec<ToolInput> = held.iter().flatten().copied().collect();
            let mut states = vec![TickState::default(); set.len()];
            engine.tick_tools(&set, &mut states);
            states[set.iter().position(|t| t.tool == moved.tool).unwrap()]
        };
        let mut seq = 0;
        left.send(named("left", tool_at(seq, at_left))).await.unwrap();
        let alone = left.next().await.unwrap().unwrap().force_n.unwrap();
        let want = replay(input(1, at_left), &mut held);
        assert_eq!([alone.x, alone.y, alone.z], want.force_n);
        let mut felt = vec![alone.z];
        for depth in [0.5e-3, 1.0e-3, 1.5e-3, 2.0e-3] {
            seq += 1;
            let at_right = [0.0, 0.0, 0.025 + 0.004 - depth];
            right.send(named("probe", tool_at(seq, at_right))).await.unwrap();
            let r = right.next().await.unwrap().unwrap();
            let want = replay(input(0, at_right), &mut held);
            let f = r.force_n.unwrap();
            assert_eq!([f.x, f.y, f.z], want.force_n, "right probe {depth} m in");
            assert_eq!(r.force_error_n, want.force_error_n);
            left.send(named("left", tool_at(seq, at_left))).await.unwrap();
            let l = left.next().await.unwrap().unwrap();
            let want = replay(input(1, at_left), &mut held);
            let f = l.force_n.unwrap();
            assert_eq!([f.x, f.y, f.z], want.force_n, "left probe with the right {depth} m in");
            felt.push(f.z);
        }
        // held still, the left probe's push eases as the right one goes in (to nothing, when
        // the surface under it is drawn away)
        assert!(
            felt.windows(2).all(|w| w[1] <= w[0]) && felt[4] < felt[0] - 0.1,
            "left probe's force {felt:?} N"
        );
        let mut frames = session.watch(30.0).await.unwrap();
        assert!(frames.message().await.unwrap().unwrap().geometry.is_some());
        let f = loop {
            let f = frames.message().await.unwrap().unwrap();
            if !f.heartbeat {
                break f;
            }
        };
        let shown: Vec<&str> = f.tools.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(shown, ["probe", "left"], "{:?}", f.tools);
        assert!(f.tools[0].contact.is_some(), "the right probe presses");
        // a tool the scene does not name
        let mut stray = session.interact().await.unwrap();
        stray.send(named("third", tool_at(0, at_left))).await.unwrap();
        let e = stray.next().await.unwrap_err();
        assert_eq!(e.kind(), ErrorKind::InvalidArgument, "{e}");
        assert!(e.to_string().contains("no tool named 'third'"), "{e}");
        right.finish();
        left.finish();
        session.close().await.unwrap();
    });
}
