//! A scalpel session over gRPC, against the real server process: the session info describes
//! the scalpel, a blade pressed down through the patch of seed 000 §3.5.1 cuts it (the events
//! arrive in the stream and the response splits the blade force), the opened tissue pushes
//! back less, and bad blades are answered with zero force without ending the stream.

mod util;

use std::time::{Duration, Instant};

use vademecum_client::{Client, SceneSpec, pb, scalpel_at};

const H: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// A quarter turn about z: the blade plane's normal is x.
const UPRIGHT: [f64; 4] = [H, 0.0, 0.0, -H];

fn norm(v: Option<&pb::Vec3>) -> f64 {
    v.map_or(0.0, |v| (v.x * v.x + v.y * v.y + v.z * v.z).sqrt())
}

#[test]
fn a_scalpel_session_cuts_the_patch_over_grpc() {
    let server = util::Server::start(&[], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let s = client
            .create_session(SceneSpec::Builtin("patch_cut".into()), "patch_cut", "cut")
            .await
            .unwrap();
        assert_eq!(s.info().effects, vec!["palpation".to_string(), "cutting".to_string()]);
        let scalpel = &s.info().tools[0];
        assert_eq!(scalpel.kind, pb::ToolKind::Scalpel as i32);
        assert_eq!((scalpel.blade_length_m, scalpel.cut_force_n), (1.2, 1.0));
        assert!((scalpel.radius_m - 0.06).abs() < 1e-12 && scalpel.max_force_n > 0.0);
        let mut tools = s.interact().await.unwrap();
        let mut seq = 0;
        let mut events = 0;
        let mut press = async |z: f64, tools: &mut vademecum_client::Interaction| {
            tools.send(scalpel_at(seq, [4.0, -0.1, z], [4.0, 1.1, z], UPRIGHT)).await.unwrap();
            seq += 1;
            tools.next().await.unwrap().unwrap()
        };
        let mut before = 0.0;
        for i in 0..=600 {
            let z = 5.1 - 1.2 * i as f64 / 600.0;
            let r = press(z, &mut tools).await;
            events |= r.events;
            let b = r.blade.as_ref().expect("a scalpel's response splits the blade force");
            if (z - 4.5).abs() < 1e-3 {
                before = norm(r.force_n.as_ref());
                assert!(b.cutting && norm(b.parallel_n.as_ref()) > 1.0);
            }
        }
        assert!(events & pb::Event::CutStarted as u32 != 0, "events {events}");
        // the cut reaches the tick within a few milliseconds of the blade crossing the row
        let start = Instant::now();
        while events & pb::Event::CutAdvanced as u32 == 0 && start.elapsed() < Duration::from_secs(10) {
            events |= press(3.9, &mut tools).await.events;
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        assert!(events & pb::Event::CutAdvanced as u32 != 0, "events {events}");
        let after = norm(press(4.5, &mut tools).await.force_n.as_ref());
        assert!(after > 0.0 && after < 0.99 * before, "{after} N after the cut, {before} N before");
        // a zero-length blade: zero force, the stream goes on
        let bad = scalpel_at(10_000, [4.0, 0.5, 4.5], [4.0, 0.5, 4.5], UPRIGHT);
        tools.send(bad).await.unwrap();
        let r = tools.next().await.unwrap().unwrap();
        assert!(r.events & pb::Event::RejectedInput as u32 != 0 && norm(r.force_n.as_ref()) == 0.0);
        assert!(press(4.5, &mut tools).await.events & pb::Event::RejectedInput as u32 == 0);
        tools.finish();
        s.close().await.unwrap();
    });
}
