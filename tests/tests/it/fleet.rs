//! A fleet on one machine stands in for the cluster (deploy/k8s/): three `vademecum serve`
//! processes that know each other. A client asks any of them for a session, is sent to the
//! least-loaded server by the SDK (which follows the redirect), streams the engine's forces
//! there, finds its sessions from any server of the fleet (and nobody else's), and keeps
//! streaming while another server drains; a draining server places new sessions on the
//! others, and `vademecum drain` waits for the sessions it holds to close.

use crate::util;

use std::process::Command;
use std::time::Duration;

use vademecum_client::{Client, ErrorKind, Interaction, SceneSpec, tool_at};
use vademecum_engine::pipeline::Pipeline;

/// `n` ports free on loopback now (held together while chosen, so they differ).
fn free_ports(n: usize) -> Vec<u16> {
    let held: Vec<_> = (0..n).map(|_| std::net::TcpListener::bind("127.0.0.1:0").unwrap()).collect();
    held.iter().map(|l| l.local_addr().unwrap().port()).collect()
}

/// Servers "a", "b", "c", each with the other two as peers, two sessions each at most.
fn fleet() -> (Vec<util::Server>, Vec<String>) {
    let ports = free_ports(3);
    let urls: Vec<String> = ports.iter().map(|p| format!("http://127.0.0.1:{p}")).collect();
    let servers = ["a", "b", "c"]
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let mut args = vec!["--name", name, "--advertise", &urls[i], "--max-sessions", "2"];
            for (j, u) in urls.iter().enumerate() {
                if j != i {
                    args.extend(["--peer", u.as_str()]);
                }
            }
            util::Server::start_at(&format!("127.0.0.1:{}", ports[i]), &args, &[("VADEMECUM_TOKENS", "t1,t2")])
        })
        .collect();
    (servers, urls)
}

/// `vademecum drain --addr URL args…` with the fleet's first token: (exit code, stdout).
fn drain(url: &str, args: &[&str]) -> (Option<i32>, String) {
    let o = Command::new(util::vademecum_bin())
        .args(["drain", "--addr", url])
        .args(args)
        .env("VADEMECUM_TOKENS", "t1,t2")
        .env_remove("VADEMECUM_TOKEN")
        .output()
        .expect("vademecum drain runs");
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    (o.status.code(), out + &String::from_utf8_lossy(&o.stderr))
}

/// The builtin organ's probe pressing 4 mm into the top of the lobe, then lifting, step `i`.
fn press(i: usize) -> [f64; 3] {
    let depth = 0.004 * (i as f64 * 0.02).sin().abs();
    [0.0, 0.0, 0.029 - depth]
}

/// Streams the press's states `from..from + n` and checks every answer, in order, against the
/// engine's force; returns how many touched.
async fn stream(tools: &mut Interaction, engine: &mut Pipeline, from: usize, n: usize) -> usize {
    let mut touching = 0;
    for i in from..from + n {
        tools.send(tool_at(i as u64, press(i))).await.unwrap();
        let r = tools.next().await.unwrap().expect("an answer per state");
        assert_eq!(r.seq, i as u64);
        let f = r.force_n.unwrap();
        let want = util::force_at(engine, press(i));
        assert_eq!([f.x, f.y, f.z], want, "state {i}");
        touching += usize::from(util::norm(want) > 0.0);
    }
    touching
}

#[test]
fn a_session_asked_of_any_server_is_placed_redirected_and_survives_a_drain_of_another() {
    let (mut servers, urls) = fleet();
    let mut engine = util::engine();
    let rt = util::runtime();
    rt.block_on(async {
        let scene = || SceneSpec::Builtin("organ".into());
        let a = Client::connect_with_token(urls[0].clone(), Some("t1")).await.unwrap();
        // all idle: the front door keeps the session (no hop)
        let first = a.create_session(scene(), "organ", "first").await.unwrap();
        assert!(first.location().is_none(), "{:?}", first.location());
        assert!(first.id().starts_with("a-"), "{}", first.id());
        // a holds one now: the next goes to the least-loaded, b (c is as idle; b comes first)
        let second = a.create_session(scene(), "organ", "second").await.unwrap();
        let at = second.location().expect("placed on a peer: redirected");
        assert_eq!((at.server.as_str(), at.address.as_str()), ("b", urls[1].as_str()));
        assert!(second.id().starts_with("b-"), "{}", second.id());

        // the SDK streams to b directly: every state answered in order, with the engine's force
        let mut tools = second.interact().await.unwrap();
        assert!(
            stream(&mut tools, &mut engine, 0, 200).await > 50,
            "the press should touch the lobe"
        );

        // any server finds the caller's sessions, with where they live; others see none
        let c = Client::connect_with_token(urls[2].clone(), Some("t1")).await.unwrap();
        let found = c.session(second.id()).await.unwrap();
        assert_eq!(found.location().map(|l| l.server.as_str()), Some("b"));
        let mut listed: Vec<_> = c
            .list_sessions()
            .await
            .unwrap()
            .into_iter()
            .map(|s| (s.label, s.redirect.map(|r| r.server)))
            .collect();
        listed.sort();
        assert_eq!(
            listed,
            [
                ("first".to_string(), Some("a".to_string())),
                ("second".to_string(), Some("b".to_string()))
            ]
        );
        let stranger = Client::connect_with_token(urls[2].clone(), Some("t2")).await.unwrap();
        assert!(stranger.list_sessions().await.unwrap().is_empty());
        assert_eq!(stranger.session(second.id()).await.unwrap_err().kind(), ErrorKind::NotFound);

        // c drains (it holds nothing: done at once; the token from the server's own file, as
        // the chart's preStop hook gives it); b's session streams on
        let tokens = tempfile::NamedTempFile::new().unwrap();
        std::fs::write(tokens.path(), "# the fleet's tokens\nt2\nt1\n").unwrap();
        let (code, out) = drain(&urls[2], &["--wait", "5", "--tokens-file", tokens.path().to_str().unwrap()]);
        assert_eq!(code, Some(0), "{out}");
        assert!(out.contains("holds no session"), "{out}");
        assert!(stream(&mut tools, &mut engine, 200, 200).await > 50);
        // a drains with a session of its own: --wait 0 says what is left, exit 1
        let (code, out) = drain(&urls[0], &["--wait", "0"]);
        assert_eq!(code, Some(1), "{out}");
        assert!(out.contains("1 sessions still running"), "{out}");
        // a and c drain: a new session asked of c lands on b, the only one taking sessions
        let third = c.create_session(scene(), "organ", "third").await.unwrap();
        assert_eq!(third.location().map(|l| l.server.as_str()), Some("b"));
        // b is full now (2), a and c drain: the fleet says so
        let full = c.create_session(scene(), "organ", "fourth").await.unwrap_err();
        assert_eq!(full.kind(), ErrorKind::ResourceExhausted, "{full}");
        // a drains until its session closes (closed through c, which does not hold it)
        let waiting = std::thread::spawn({
            let url = urls[0].clone();
            move || drain(&url, &["--wait", "60"])
        });
        tokio::time::sleep(Duration::from_millis(700)).await;
        c.session(first.id()).await.unwrap().close().await.unwrap();
        let (code, out) = tokio::task::spawn_blocking(move || waiting.join().unwrap()).await.unwrap();
        assert_eq!(code, Some(0), "{out}");
        assert!(out.contains("0 sessions running") && out.contains("holds no session"), "{out}");
        // a resumes and takes sessions again
        let (code, out) = drain(&urls[0], &["--resume"]);
        assert_eq!(code, Some(0), "{out}");
        let fifth = c.create_session(scene(), "organ", "fifth").await.unwrap();
        assert_eq!(fifth.location().map(|l| l.server.as_str()), Some("a"));

        // b's session streamed through it all
        assert!(stream(&mut tools, &mut engine, 400, 100).await > 20);
        tools.finish();
        assert!(tools.next().await.unwrap().is_none());
        let stats = second.close().await.unwrap();
        assert_eq!((stats.answered, stats.dropped), (500, 0));

        // c, idle and taking sessions again, dies: the fleet leaves it out and goes on
        let (code, out) = drain(&urls[2], &["--resume"]);
        assert_eq!(code, Some(0), "{out}");
        servers[2].kill();
        let sixth = a.create_session(scene(), "organ", "sixth").await.unwrap();
        assert_ne!(sixth.location().map(|l| l.server.as_str()), Some("c"));
        assert_eq!(a.list_sessions().await.unwrap().len(), 3, "fifth, third and sixth");
        // a haptic session stays on the server asked (its channel is on that host), even when
        // another is less loaded (b holds the third, a nothing now)
        let b = Client::connect_with_token(urls[1].clone(), Some("t1")).await.unwrap();
        fifth.close().await.unwrap();
        sixth.close().await.unwrap();
        let device = b
            .create_haptic_session(scene(), "organ", "device", &util::channel("fleet"))
            .await
            .unwrap();
        assert!(device.location().is_none() && device.id().starts_with("b-"), "{}", device.id());
        device.close().await.unwrap();
    });
}
