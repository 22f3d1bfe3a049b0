//! A session in-process: every tool state is answered once, in order, with the force the
//! engine's pipeline computes for it; bad tool states get zero force and are counted; viewers
//! get monotonically numbered frames while interaction continues; a scene asking for an
//! effect this version does not simulate is refused.

use std::sync::Arc;
use std::time::{Duration, Instant};

use vademecum_engine::pgd::PgdParams;
use vademecum_engine::pgd::offline::{self, BuildOptions, LoadedBundle};
use vademecum_engine::pipeline::{Events, Pipeline, PipelineError, ToolInput};
use vademecum_engine::scene::Scene;
use vademecum_server::session::{Answer, Session, SessionConfig, SessionError, ToolCommand};

const SCENE: &str = r#"[scene]
name = "slab"

[[organs]]
name = "slab"
density = 1000.0

[organs.mesh]
builtin = "block"
size = [0.08, 0.04, 0.02]
divisions = [8, 4, 2]

[[organs.materials]]
model = "linear"
young = 5e3
poisson = 0.45

[organs.fixed]
box = { min = [0.0, 0.0, 0.0], max = [0.08, 0.04, 0.0] }

[organs.accessible]
half_space = { point = [0.0, 0.0, 0.02], normal = [0.0, 0.0, 1.0] }

[[tools]]
kind = "probe"
name = "probe"
radius = 0.006
"#;

fn slab() -> (Arc<Scene>, Vec<Arc<LoadedBundle>>, tempfile::TempDir) {
    let scene = Scene::from_toml(SCENE, "slab.toml").unwrap();
    let opts = BuildOptions {
        params: PgdParams {
            block: 16,
            ..PgdParams::default()
        },
        tolerance: 1e-3,
        recompress: true,
        load_radius: offline::probe_radius(&scene),
        large: None,
    };
    let built = offline::build_organ(&scene, 0, &opts, &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("slab.bundle");
    offline::write_bundle(&path, &scene, &built).unwrap();
    let b = Arc::new(offline::load_bundle(&path).unwrap());
    (Arc::new(scene), vec![b], dir)
}

/// A probe path sweeping over the slab's top face, pressing up to 3 mm into it.
fn tool(i: usize) -> ToolInput {
    let s = i as f64 / 500.0;
    ToolInput {
        position_m: [0.01 + 0.06 * (s * 0.7).fract(), 0.02, 0.02 + 0.006 - 0.003 * (s * 3.0).sin().abs()],
        ..ToolInput::default()
    }
}

fn recv(rx: &mut tokio::sync::mpsc::Receiver<Answer>) -> Answer {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        match rx.try_recv() {
            Ok(a) => return a,
            Err(tokio::sync::mpsc::error::TryRecvError::Empty) if Instant::now() < deadline => {
                std::thread::sleep(Duration::from_micros(200))
            }
            Err(e) => panic!("no answer: {e:?}"),
        }
    }
}

#[test]
fn every_tool_state_is_answered_in_order_with_the_pipelines_force() {
    let (scene, bundles, _dir) = slab();
    let session = Session::start("s1".into(), scene.clone(), bundles.clone(), SessionConfig::default()).unwrap();
    assert_eq!(session.effects(), ["palpation"]);
    let mut direct = Pipeline::for_scene(&scene, &bundles).unwrap();
    let (tx, mut rx) = tokio::sync::mpsc::channel(256);
    let n = 2000;
    let mut touching = 0;
    for i in 0..n {
        // keep at most 100 in flight, as a frontend streaming at a steady rate would
        let cmd = ToolCommand {
            input: tool(i),
            seq: i as u64,
            client_time_us: 7 * i as u64,
            received: Instant::now(),
            reply: tx.clone(),
        };
        session.submit(cmd).expect("queue has room");
        if i >= 100 {
            let a = recv(&mut rx);
            check(&a, i - 100, &mut direct, &mut touching);
        }
    }
    for i in n - 100..n {
        let a = recv(&mut rx);
        check(&a, i, &mut direct, &mut touching);
    }
    assert!(touching > n / 10, "the path should touch the slab often ({touching} of {n})");
    let stats = session.close();
    assert_eq!((stats.answered, stats.dropped, stats.rejected), (n as u64, 0, 0));
    assert!(stats.ticks > 0 && stats.work_us.count > 0);
}

fn check(a: &Answer, i: usize, direct: &mut Pipeline, touching: &mut usize) {
    assert_eq!(a.seq, i as u64, "answers out of order");
    assert_eq!(a.client_time_us, 7 * i as u64);
    assert!(a.answered_us >= a.received_us);
    let expected = direct.tick(&tool(i));
    assert_eq!(
        a.state, expected,
        "tool state {i}: the session's answer differs from the pipeline's"
    );
    if a.state.events.has(Events::CONTACT) {
        *touching += 1;
        assert!(
            a.state.force_n[2] > 0.0,
            "pressing down, the tissue pushes the tool up: {:?}",
            a.state.force_n
        );
    }
}

#[test]
fn bad_tool_states_get_zero_force_and_are_counted() {
    let (scene, bundles, _dir) = slab();
    let session = Session::start("s2".into(), scene, bundles, SessionConfig::default()).unwrap();
    let (tx, mut rx) = tokio::sync::mpsc::channel(16);
    let bad = [
        ToolInput {
            position_m: [f64::NAN, 0.02, 0.02],
            ..ToolInput::default()
        },
        ToolInput {
            position_m: [0.04, 0.02, f64::INFINITY],
            ..ToolInput::default()
        },
        ToolInput {
            position_m: [0.04, 0.02, 0.021],
            closure: 7.0,
            ..ToolInput::default()
        },
    ];
    for (i, input) in bad.iter().enumerate() {
        session
            .submit(ToolCommand {
                input: *input,
                seq: i as u64,
                client_time_us: 0,
                received: Instant::now(),
                reply: tx.clone(),
            })
            .unwrap();
        let a = recv(&mut rx);
        assert_eq!(a.state.force_n, [0.0; 3]);
        assert!(a.state.events.has(Events::REJECTED_INPUT) && a.state.contact.is_none());
    }
    // and the session still answers good ones
    session
        .submit(ToolCommand {
            input: tool(0),
            seq: 9,
            client_time_us: 0,
            received: Instant::now(),
            reply: tx,
        })
        .unwrap();
    assert_eq!(recv(&mut rx).seq, 9);
    assert_eq!(session.close().rejected, 3);
}

#[test]
fn viewers_get_monotonically_numbered_frames_while_interaction_continues() {
    let (scene, bundles, _dir) = slab();
    let config = SessionConfig {
        frame_rate_hz: 60.0,
        ..SessionConfig::default()
    };
    let session = Session::start("s3".into(), scene, bundles, config).unwrap();
    let mut frames = session.subscribe_frames();
    let g = session.geometry().clone();
    assert_eq!(g.organs.len(), 1);
    assert_eq!(g.organs[0].positions_m.len(), 3 * g.organs[0].nodes.len());
    let (tx, mut rx) = tokio::sync::mpsc::channel(64);
    let (mut last_seq, mut seen, mut moved) = (0u64, 0usize, false);
    let start = Instant::now();
    let mut i = 0;
    while start.elapsed() < Duration::from_millis(1500) {
        let _ = session.submit(ToolCommand {
            input: tool(i),
            seq: i as u64,
            client_time_us: 0,
            received: Instant::now(),
            reply: tx.clone(),
        });
        i += 1;
        while rx.try_recv().is_ok() {}
        std::thread::sleep(Duration::from_millis(2));
        if frames.has_changed().unwrap() {
            let f = frames.borrow_and_update().clone();
            assert!(f.seq > last_seq, "frame {} after {last_seq}", f.seq);
            last_seq = f.seq;
            seen += 1;
            assert_eq!(f.displacements_m[0].len(), g.organs[0].positions_m.len());
            if f.contact.is_some() {
                moved |= f.displacements_m[0].iter().any(|&u| u != 0.0);
            }
        }
    }
    assert!(seen >= 5, "only {seen} frames in 1.5 s");
    assert!(moved, "frames in contact show the surface displaced");
}

#[test]
fn a_scene_asking_for_an_effect_not_simulated_yet_is_refused() {
    let (_, bundles, _dir) = slab();
    let cutting = format!(
        "{SCENE}\n[[tools]]\nkind = \"scalpel\"\nname = \"s\"\nblade_length = 0.01\ncut_force = 1.0\n\n[effects]\ncutting = true\n"
    );
    let scene = Arc::new(Scene::from_toml(&cutting, "cut.toml").unwrap());
    let e = Session::start("s4".into(), scene, bundles, SessionConfig::default()).unwrap_err();
    assert!(matches!(e, SessionError::Pipeline(PipelineError::Unsupported(_))), "{e}");
    assert!(e.to_string().contains("cutting"), "{e}");
}
