//! What an attacker or a careless client tries, against the real server process: files
//! outside the server's roots, a server started open by accident, one tenant taking every
//! slot, secrets on the metrics page, unbounded input echoed back, tool kinds the scene does
//! not simulate, a session closed under a stream.

use crate::util;

use std::process::Command;

use vademecum_client::pb;
use vademecum_client::{Client, ErrorKind, SceneSpec, SdkError, tool_at};

/// The built-in organ scene with its procedural mesh replaced by a mesh file at `file`.
fn scene_with_mesh_file(file: &str) -> String {
    let text = vademecum_engine::scene::builtin("organ").unwrap();
    let start = text.find("[organs.mesh]").unwrap();
    let end = text.find("[[organs.materials]]").unwrap();
    format!("{}[organs.mesh]\nfile = \"{file}\"\n\n{}", &text[..start], &text[end..])
}

#[test]
fn inline_scenes_cannot_reach_files_outside_the_mesh_root_and_learn_nothing_of_them() {
    let server = util::Server::start(&["--no-paths"], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let mut messages = Vec::new();
        // a file that exists, one that does not, and relative escapes
        for file in ["/etc/passwd", "/no/such/file.msh", "../../../../etc/hostname", "organ/../../x.msh"] {
            let e = client
                .create_session(SceneSpec::Toml(scene_with_mesh_file(file)), "organ", "x")
                .await
                .unwrap_err();
            assert_eq!(e.kind(), ErrorKind::PermissionDenied, "{file}: {e}");
            messages.push(e.to_string());
        }
        // the same answer whether the file exists or not
        assert!(messages.windows(2).all(|w| w[0] == w[1]), "{messages:?}");
        assert!(
            !messages[0].contains("passwd") && messages[0].contains("mesh root"),
            "{}",
            messages[0]
        );
        // a mesh under the root is only refused for what it is (here: missing)
        let e = client
            .create_session(SceneSpec::Toml(scene_with_mesh_file("organ/missing.msh")), "organ", "x")
            .await
            .unwrap_err();
        assert_ne!(e.kind(), ErrorKind::PermissionDenied, "{e}");
        // the same for a visual mesh (co-rotational cutting)
        let corot = util::with_keys(
            vademecum_engine::scene::builtin("patch_cut").unwrap(),
            &[("fidelity.cutting", "\"corotational_xfem\"")],
        );
        for file in ["/etc/x.obj", "../../../../etc/x.obj"] {
            let text = util::with_keys(&corot, &[("organs[0].visual", &format!("{{ file = \"{file}\" }}"))]);
            let e = client.create_session(SceneSpec::Toml(text), "patch", "x").await.unwrap_err();
            assert_eq!(e.kind(), ErrorKind::PermissionDenied, "{file}: {e}");
            assert!(e.to_string().contains("visual.file") && !e.to_string().contains("etc"), "{e}");
        }
    });
}

#[test]
fn the_server_never_starts_open_by_accident() {
    let run = |args: &[&str], tokens: Option<&str>| {
        let mut c = Command::new(util::vademecum_bin());
        c.args(["serve", "--listen", "127.0.0.1:0"])
            .args(args)
            .env_remove("VADEMECUM_TOKENS");
        if let Some(t) = tokens {
            c.env("VADEMECUM_TOKENS", t);
        }
        c.output().unwrap()
    };
    for (args, tokens, why) in [
        (&[][..], Some(""), "holds no token"),
        (&[][..], Some(" , ,"), "holds no token"),
        (&[][..], None, "--no-auth"),
        (&["--no-auth"][..], Some("t"), "choose one"),
        (&["--no-auth", "--metrics", "0.0.0.0:0"][..], None, "--metrics-public"),
        // (not about auth: a contradiction in the flags is refused the same way)
        (
            &["--no-auth", "--device-workers", "1", "--haptic-wait", "hybrid"][..],
            None,
            "--haptic-wait event",
        ),
    ] {
        let o = run(args, tokens);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?} {tokens:?}: {err}");
        assert!(err.contains(why), "{args:?} {tokens:?}: {err}");
    }
}

#[test]
fn one_token_cannot_take_every_slot() {
    let server = util::Server::start(
        &["--client-sessions", "2", "--client-streams", "1"],
        &[("VADEMECUM_TOKENS", "alice,bob")],
    );
    let rt = util::runtime();
    rt.block_on(async {
        let alice = Client::connect_with_token(server.url.clone(), Some("alice")).await.unwrap();
        let bob = Client::connect_with_token(server.url.clone(), Some("bob")).await.unwrap();
        let organ = || SceneSpec::Builtin("organ".into());
        let a1 = alice.create_session(organ(), "organ", "a1").await.unwrap();
        let _a2 = alice.create_session(organ(), "organ", "a2").await.unwrap();
        let e = alice.create_session(organ(), "organ", "a3").await.unwrap_err();
        assert_eq!(e.kind(), ErrorKind::ResourceExhausted, "{e}");
        assert!(e.to_string().contains("quota"), "{e}");
        let b1 = bob.create_session(organ(), "organ", "b1").await.unwrap();
        // streams: one viewer each
        let _w = a1.watch(30.0).await.unwrap();
        let e = a1.watch(30.0).await.unwrap_err();
        assert_eq!(e.kind(), ErrorKind::ResourceExhausted, "{e}");
        let _wb = b1.watch(30.0).await.unwrap();
        // closing the stream gives the slot back
        drop(_w);
        let mut again = None;
        for _ in 0..50 {
            if let Ok(w) = a1.watch(30.0).await {
                again = Some(w);
                break;
            }
            tokio::time::sleep(std::time::Duration::from_millis(20)).await;
        }
        assert!(again.is_some(), "the viewer slot came back");
    });
}

/// A haptic channel stays with the client that first opened a session on it: once the lab's
/// session has ended, another client cannot open one there (the lab's bridge, still attached
/// to the channel, would drive it).
#[test]
fn a_haptic_channel_stays_with_the_client_that_opened_it() {
    let server = util::Server::start(&[], &[("VADEMECUM_TOKENS", "lab,tenant")]);
    let rt = util::runtime();
    rt.block_on(async {
        let lab = Client::connect_with_token(server.url.clone(), Some("lab")).await.unwrap();
        let tenant = Client::connect_with_token(server.url.clone(), Some("tenant")).await.unwrap();
        let organ = || SceneSpec::Builtin("organ".into());
        let channel = format!("lab-bench-{}", std::process::id());
        let s = lab.create_haptic_session(organ(), "organ", "lab", &channel).await.unwrap();
        s.close().await.unwrap();
        let e = tenant
            .create_haptic_session(organ(), "organ", "tenant", &channel)
            .await
            .err()
            .unwrap();
        assert_eq!(e.kind(), ErrorKind::PermissionDenied, "{e}");
        assert!(e.to_string().contains("belongs to another client"), "{e}");
        // the lab opens it again; the tenant has channels of its own
        lab.create_haptic_session(organ(), "organ", "lab", &channel)
            .await
            .unwrap()
            .close()
            .await
            .unwrap();
        let other = format!("{channel}-tenant");
        tenant
            .create_haptic_session(organ(), "organ", "tenant", &other)
            .await
            .unwrap()
            .close()
            .await
            .unwrap();
        // two hands: the lab's session on a scene with two probes holds each tool's channel too
        // (`CHANNEL.probe`, `CHANNEL.left`), so the lab's left-hand bridge never drives a tenant
        let hands = format!("lab-hands-{}", std::process::id());
        let two = || SceneSpec::Toml(util::two_probes().to_string());
        lab.create_haptic_session(two(), "two_probes", "lab", &hands)
            .await
            .unwrap()
            .close()
            .await
            .unwrap();
        let e = tenant
            .create_haptic_session(organ(), "organ", "tenant", &format!("{hands}.left"))
            .await
            .err()
            .unwrap();
        assert_eq!(e.kind(), ErrorKind::PermissionDenied, "{e}");
        assert!(e.to_string().contains(&format!("'{hands}.left' belongs to another client")), "{e}");
    });
}

/// A client's scene whose built-in mesh would be huge is refused from its settings, before
/// the server spends memory on it (it used to make the mesh, a gigabyte, then refuse).
#[test]
fn a_huge_inline_scene_is_refused_before_it_costs_anything() {
    let server = util::Server::start(&["--max-scene-cells", "100000"], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let text = util::with_keys(
            &vademecum_engine::scene::Scene::builtin("cantilever").unwrap().source,
            &[("organs[0].mesh.divisions", "[2000, 200, 40]")],
        );
        let e = client.create_session(SceneSpec::Toml(text), "organ", "huge").await.err().unwrap();
        assert_eq!(e.kind(), ErrorKind::ResourceExhausted, "{e}");
        assert!(e.to_string().contains("16000000 cells"), "{e}");
        // a built-in scene is the server's own: not counted against the cap
        client
            .create_session(SceneSpec::Builtin("organ".into()), "organ", "ok")
            .await
            .unwrap()
            .close()
            .await
            .unwrap();
    });
}

#[test]
fn unbounded_client_input_is_never_echoed_back() {
    let server = util::Server::start(&[], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        // a million bytes (under the 1 MiB request limit)
        let huge = "x".repeat(1_000_000);
        let e = client.session(&huge).await.unwrap_err();
        assert_eq!(e.kind(), ErrorKind::NotFound, "{}", &e.to_string()[..200.min(e.to_string().len())]);
        assert!(e.to_string().len() < 400, "{} bytes", e.to_string().len());
        // a scene with a 100 KB string value
        let bogus = format!("\"{}\"", "y".repeat(100_000));
        let text = util::with_keys(vademecum_engine::scene::builtin("organ").unwrap(), &[("scene.bogus", &bogus)]);
        let e = client.create_session(SceneSpec::Toml(text), "organ", "x").await.unwrap_err();
        assert_eq!(e.kind(), ErrorKind::InvalidArgument, "{}", &e.to_string()[..200]);
        assert!(e.to_string().len() < 2000, "{} bytes", e.to_string().len());
    });
}

#[test]
fn a_tool_the_scene_does_not_simulate_ends_the_stream_naming_it() {
    let server = util::Server::start(&[], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let s = client
            .create_session(SceneSpec::Builtin("organ".into()), "organ", "k")
            .await
            .unwrap();
        let info = client.list_sessions().await.unwrap().remove(0);
        assert_eq!(info.tools.len(), 1);
        assert_eq!((info.tools[0].kind, info.tools[0].radius_m), (pb::ToolKind::Probe as i32, 0.004));
        assert!(info.tools[0].max_force_n > 0.0);
        let organ = &info.organ_info[0];
        assert!(organ.accessible_triangles > 0);
        assert!(organ.accessible_min_m.unwrap().z > organ.bounds_min_m.unwrap().z);
        for (kind, name) in [(pb::ToolKind::Scalpel as i32, "SCALPEL"), (99, "99")] {
            let mut tools = s.interact().await.unwrap();
            // a probe state is answered, then the scalpel ends the stream
            tools.send(tool_at(0, [0.0, 0.0, 0.05])).await.unwrap();
            assert_eq!(tools.next().await.unwrap().unwrap().seq, 0);
            let mut bad = tool_at(1, [0.0, 0.0, 0.05]);
            bad.kind = kind;
            tools.send(bad).await.unwrap();
            let e = tools.next().await.unwrap_err();
            assert_eq!(e.kind(), ErrorKind::InvalidArgument, "{e}");
            assert!(e.to_string().contains(name) && e.to_string().contains("'probe'"), "{e}");
        }
        // a NaN orientation is rejected like a NaN position: zero force, the stream goes on
        let mut tools = s.interact().await.unwrap();
        let mut st = tool_at(0, [0.0, 0.0, 0.02]);
        st.orientation = Some(pb::Quat {
            w: f64::NAN,
            x: 0.0,
            y: 0.0,
            z: 0.0,
        });
        tools.send(st).await.unwrap();
        let r = tools.next().await.unwrap().unwrap();
        assert!(r.events & pb::Event::RejectedInput as u32 != 0);
        tools.send(tool_at(1, [0.0, 0.0, 0.02])).await.unwrap();
        let r = tools.next().await.unwrap().unwrap();
        assert_eq!(r.events & pb::Event::RejectedInput as u32, 0);
    });
}

#[test]
fn closing_a_session_mid_stream_answers_or_fails_every_state() {
    let server = util::Server::start(&[], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let s = client
            .create_session(SceneSpec::Builtin("organ".into()), "organ", "c")
            .await
            .unwrap();
        let id = s.id().to_string();
        let mut tools = s.interact().await.unwrap();
        // the stream is open once its first state is answered
        tools.send(tool_at(0, [0.0, 0.0, 0.03])).await.unwrap();
        assert_eq!(tools.next().await.unwrap().unwrap().seq, 0);
        let sent = 4000u64;
        for i in 1..sent {
            tools.send(tool_at(i, [0.0, 0.0, 0.03])).await.unwrap();
        }
        client.session(&id).await.unwrap().close().await.unwrap();
        let mut answered = 1u64;
        let end = loop {
            match tools.next().await {
                Ok(Some(r)) => {
                    assert_eq!(r.seq, answered, "in order");
                    answered += 1;
                }
                Ok(None) => break None,
                Err(e) => break Some(e),
            }
        };
        if answered < sent {
            // the SDK counts exactly what this stream sent; the server, what reached it (on a
            // starved machine, states still in transit after its pause are not among them)
            let e = end.expect("the unanswered states are failed with a status");
            assert_eq!(e.kind(), ErrorKind::Aborted, "{e}");
            let SdkError::Unanswered { unanswered, status } = &e else {
                panic!("{e:?}")
            };
            assert_eq!(*unanswered, sent - answered, "{e}");
            assert!(e.to_string().contains(&format!("last {} tool state", sent - answered)), "{e}");
            if let Some(status) = status {
                let counted: u64 = status
                    .message()
                    .split("last ")
                    .nth(1)
                    .and_then(|t| t.split(' ').next())
                    .and_then(|n| n.parse().ok())
                    .unwrap_or_else(|| panic!("{}", status.message()));
                assert!(
                    (1..=sent - answered).contains(&counted),
                    "server counted {counted}, {} unanswered",
                    sent - answered
                );
            }
        } else {
            assert!(end.is_none(), "every state was answered, yet {end:?}");
        }
    });
}
