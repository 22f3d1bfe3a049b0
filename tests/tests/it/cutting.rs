//! A scalpel session over gRPC, against the real server process: the session info describes
//! the scalpel, a blade pressed down through the patch of seed 000 §3.5.1 cuts it (the events
//! arrive in the stream and the response splits the blade force), the opened tissue pushes
//! back less, a viewer's frames carry the walls of the opening, and bad blades are answered with zero force without ending the stream.

use crate::util;

use std::time::{Duration, Instant};

use vademecum_client::{Client, SceneSpec, f32s, pb, scalpel_at, u32s};

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
        // a viewer sees the cut: the walls of the opening, both sides, parting under the blade
        let mut frames = s.watch(30.0).await.unwrap();
        let geometry = frames.message().await.unwrap().unwrap();
        assert!(geometry.geometry.is_some());
        let start = Instant::now();
        let walls = loop {
            assert!(start.elapsed() < Duration::from_secs(20), "no frame carried the cut");
            press(4.5, &mut tools).await;
            let Ok(m) = tokio::time::timeout(Duration::from_millis(2), frames.message()).await else {
                continue;
            };
            let f = m.unwrap().expect("the stream goes on");
            if let Some(c) = f.organs.first().and_then(|o| o.cut.clone()) {
                break c;
            }
        };
        let n = walls.vertex_count as usize;
        let (pos, disp) = (f32s(&walls.positions), f32s(&walls.displacements));
        let tris = u32s(&walls.triangles);
        assert!(walls.revision >= 1 && n > 0 && !tris.is_empty());
        assert_eq!((pos.len(), disp.len(), walls.side.len(), tris.len() % 3), (3 * n, 3 * n, n, 0));
        assert!(tris.iter().all(|&t| (t as usize) < n) && disp.iter().all(|d| d.is_finite()));
        assert!(walls.side.contains(&0) && walls.side.contains(&1));
        // the cut lies in the plane x = 4; each cracked node has a vertex on each side, apart
        assert!(pos.chunks_exact(3).all(|p| (p[0] - 4.0).abs() < 1e-6));
        let mut opening = 0.0f32;
        for i in 0..n {
            for j in 0..n {
                if walls.side[i] == 0 && walls.side[j] == 1 && pos[3 * i..3 * i + 3] == pos[3 * j..3 * j + 3] {
                    let d = (0..3).map(|k| (disp[3 * i + k] - disp[3 * j + k]).powi(2)).sum::<f32>().sqrt();
                    opening = opening.max(d);
                }
            }
        }
        assert!(opening > 0.0, "the walls part under the blade");
        drop(frames);
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
