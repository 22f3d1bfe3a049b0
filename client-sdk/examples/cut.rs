//! A scripted cut through the SDK: create a session on the built-in `patch_cut` scene (the
//! patch of seed 000 §3.5.1), hold the scalpel upright across the patch's depth in the plane
//! x = 4 and press it down through the top cell row at 1 kHz, printing the force on the blade
//! split into its part normal to the blade (F⊥) and its part in the blade's plane (F∥, friction
//! below the scalpel's cut_force, cutting above it), and the cut's events.
//!
//! Run a server first (`vademecum build --builtin patch_cut && vademecum serve`), then:
//! `cargo run -p vademecum-client --example cut -- [http://127.0.0.1:50051] [BUNDLE_DIR] [SECONDS]`
//! (BUNDLE_DIR: where the scene's bundle sits under the server's bundle root, default
//! `out/patch_cut`).

use std::time::{Duration, Instant};

use vademecum_client::{Client, SceneSpec, pb, scalpel_at};

/// A quarter turn about z: the blade plane's normal is x (the plane x = 4).
const UPRIGHT: [f64; 4] = [std::f64::consts::FRAC_1_SQRT_2, 0.0, 0.0, -std::f64::consts::FRAC_1_SQRT_2];

fn norm(v: Option<&pb::Vec3>) -> f64 {
    v.map_or(0.0, |v| (v.x * v.x + v.y * v.y + v.z * v.z).sqrt())
}

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let addr = args.next().unwrap_or_else(|| "http://127.0.0.1:50051".into());
    let bundles = args.next().unwrap_or_else(|| "out/patch_cut".into());
    let seconds: f64 = args.next().map_or(Ok(3.0), |s| s.parse())?;
    let token = std::env::var("VADEMECUM_TOKEN").ok();
    let client = Client::connect_with_token(addr, token.as_deref()).await?;
    let session = client
        .create_session(SceneSpec::Builtin("patch_cut".into()), &bundles, "cut example")
        .await?;
    let scalpel = session
        .info()
        .tools
        .iter()
        .find(|t| t.kind == pb::ToolKind::Scalpel as i32)
        .ok_or("the scene has no scalpel")?
        .clone();
    println!(
        "session {} on '{}': effects {:?}; scalpel '{}' cuts above {} N",
        session.id(),
        session.info().scene,
        session.info().effects,
        scalpel.name,
        scalpel.cut_force_n
    );
    let mut tools = session.interact().await?;
    let start = Instant::now();
    let (mut i, mut strokes, mut advances) = (0u64, 0, 0);
    while start.elapsed().as_secs_f64() < seconds {
        let s = start.elapsed().as_secs_f64() / seconds;
        // from above the top (z = 5) down to z = 3.9 in the first 80 % of the time, then held
        let z = 5.1 - 1.2 * (s / 0.8).min(1.0);
        tools.send(scalpel_at(i, [4.0, -0.1, z], [4.0, 1.1, z], UPRIGHT)).await?;
        let r = tools.next().await?.ok_or("the server ended the stream")?;
        if r.events & pb::Event::CutStarted as u32 != 0 {
            strokes += 1;
            println!(
                "t = {:5.3} s  z = {z:.3} m  the blade starts cutting",
                start.elapsed().as_secs_f64()
            );
        }
        if r.events & pb::Event::CutAdvanced as u32 != 0 {
            advances += 1;
            println!("t = {:5.3} s  z = {z:.3} m  the cut advanced", start.elapsed().as_secs_f64());
        }
        if i % 250 == 0
            && let Some(b) = &r.blade
        {
            println!(
                "t = {:5.3} s  z = {z:.3} m  |F| = {:.3} N  |F⊥| = {:.3} N  |F∥| = {:.3} N{}",
                start.elapsed().as_secs_f64(),
                norm(r.force_n.as_ref()),
                norm(b.perpendicular_n.as_ref()),
                norm(b.parallel_n.as_ref()),
                if b.cutting { "  cutting" } else { "" }
            );
        }
        i += 1;
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    tools.finish();
    let stats = session.close().await?;
    println!(
        "{i} tool states answered; {strokes} cutting stroke(s), {advances} cut(s) reached the tick; server tick work p99 {:.1} µs",
        stats.tick_work_p99_us
    );
    Ok(())
}
