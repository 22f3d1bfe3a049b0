//! Two hands, two effects, two organs in one live session over gRPC (issue 46), against the
//! real server process: `scenes/effects/tear_and_cut.toml`. A client stream per hand — the
//! scalpel goes down the seed's patch while the grasper pulls a damageable cube beside it — and
//! each hand gets its own effect's answers: the patch is cut (EVENT_CUT_STARTED, then
//! EVENT_CUT_ADVANCED once the cut thread lands it), the cube tears (EVENT_GRASPED,
//! EVENT_TEARING, EVENT_TISSUE_TORN), neither hand sees the other's events, and one viewer's
//! frames carry the patch's cut walls and the cube's damage together.

use crate::util;

use std::time::{Duration, Instant};

use vademecum_client::{Client, SceneSpec, f32s, grasper_at, named, pb, scalpel_at};

const H: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// A quarter turn about z: the blade's plane is x = const.
const UPRIGHT: [f64; 4] = [H, 0.0, 0.0, -H];

const CUT_EVENTS: u32 = pb::Event::CutStarted as u32 | pb::Event::CutAdvanced as u32 | pb::Event::BladeInCut as u32;
const TEAR_EVENTS: u32 = pb::Event::Grasped as u32 | pb::Event::Tearing as u32 | pb::Event::TissueTorn as u32;

#[test]
fn a_scalpel_cuts_one_organ_while_a_grasper_tears_another_over_grpc() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/effects/tear_and_cut.toml")).unwrap();
    // the bundles of both organs, built by the command line beside the shared ones
    let dir = util::bundles();
    std::fs::write(dir.join("tear_and_cut.toml"), &text).unwrap();
    let built = util::vademecum(dir, &["build", "tear_and_cut.toml", "--out", "tear_and_cut"]);
    assert!(built.status.success(), "{}", String::from_utf8_lossy(&built.stderr));
    let server = util::Server::start(&[], &[]);
    let rt = util::runtime();
    rt.block_on(async {
        let client = Client::connect(server.url.clone()).await.unwrap();
        let s = client
            .create_session(SceneSpec::Toml(text), "tear_and_cut", "two hands, two effects")
            .await
            .unwrap();
        let info = s.info();
        assert!(
            info.effects.iter().any(|e| e == "cutting") && info.effects.iter().any(|e| e == "tearing"),
            "{:?}",
            info.effects
        );
        let names: Vec<&str> = info.tools.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(names, ["scalpel", "grasper"]);
        // the grasper's site is on the cube, organ 1
        assert_eq!(info.tools[1].grasp_sites[0].organ, 1);

        let (mut right, mut left) = (s.interact().await.unwrap(), s.interact().await.unwrap());
        let (mut seq, mut cut_seen, mut tear_seen) = (0u64, 0u32, 0u32);
        left.send(named("grasper", grasper_at(seq, [9.0, 1.0, 1.0], 1.0))).await.unwrap();
        tear_seen |= left.next().await.unwrap().unwrap().events;
        assert!(tear_seen & pb::Event::Grasped as u32 != 0, "events {tear_seen}");
        // the scalpel down x = 4 through the top row of the patch in 1,200 states, the
        // grasper pulling the cube's corner up 0.8 m in between
        for k in 1..=1200u32 {
            seq += 1;
            let z = 5.1 - 1.2 * f64::from(k) / 1200.0;
            right
                .send(named("scalpel", scalpel_at(seq, [4.0, -0.1, z], [4.0, 1.1, z], UPRIGHT)))
                .await
                .unwrap();
            cut_seen |= right.next().await.unwrap().unwrap().events;
            left.send(named(
                "grasper",
                grasper_at(seq, [9.0, 1.0, 1.0 + 0.8 * f64::from(k) / 1200.0], 1.0),
            ))
            .await
            .unwrap();
            tear_seen |= left.next().await.unwrap().unwrap().events;
            // a session ticks at 1 kHz: the cut thread follows the blade at that pace
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        // the blade held at the bottom until the cut thread's cut reaches the tick
        let start = Instant::now();
        while cut_seen & pb::Event::CutAdvanced as u32 == 0 {
            assert!(
                start.elapsed() < Duration::from_secs(20),
                "no cut reached the session: events {cut_seen:#b}"
            );
            seq += 1;
            right
                .send(named("scalpel", scalpel_at(seq, [4.0, -0.1, 3.9], [4.0, 1.1, 3.9], UPRIGHT)))
                .await
                .unwrap();
            cut_seen |= right.next().await.unwrap().unwrap().events;
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
        assert!(cut_seen & pb::Event::CutStarted as u32 != 0, "events {cut_seen:#b}");
        assert!(
            tear_seen & pb::Event::Tearing as u32 != 0 && tear_seen & pb::Event::TissueTorn as u32 != 0,
            "events {tear_seen:#b}"
        );
        assert_eq!(cut_seen & TEAR_EVENTS, 0, "the scalpel saw the grasp's events: {cut_seen:#b}");
        assert_eq!(tear_seen & CUT_EVENTS, 0, "the grasper saw the cut's events: {tear_seen:#b}");

        // one viewer sees both: the patch's cut walls and the cube's damage, torn
        let mut frames = s.watch(30.0).await.unwrap();
        let start = Instant::now();
        let f = loop {
            assert!(start.elapsed() < Duration::from_secs(20), "no frame carried the cut and the damage");
            let f = frames.message().await.unwrap().expect("the stream goes on");
            if f.organs.len() == 2 && f.organs[0].cut.is_some() && f.organs[1].damage.is_some() {
                break f;
            }
        };
        assert!(f.organs[0].damage.is_none() && f.organs[1].cut.is_none());
        let damage = f.organs[1].damage.as_ref().unwrap();
        let cells = f32s(&damage.cell_damage);
        assert!(
            cells.iter().any(|&d| d >= damage.torn),
            "the cube's cell is torn: {cells:?}, threshold {}",
            damage.torn
        );
        let walls = f.organs[0].cut.as_ref().unwrap();
        assert!(!walls.triangles.is_empty(), "the patch's cut has walls");
        drop(frames);
        right.finish();
        left.finish();
        s.close().await.unwrap();
    });
}
