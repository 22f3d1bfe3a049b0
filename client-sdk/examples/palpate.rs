//! A scripted palpation through the SDK: create a session on the built-in organ, press the
//! probe into the middle of its upper surface and circle for a few seconds at 1 kHz, and
//! print the force along the way.
//!
//! Run a server first (`vademecum build --out out/organ && vademecum serve`), then:
//! `cargo run -p vademecum-client --example palpate -- [http://127.0.0.1:50051] [BUNDLE_DIR] [SECONDS]`
//! (BUNDLE_DIR: where the organ's bundle sits under the server's bundle root, default `out/organ`).

use std::time::{Duration, Instant};

use vademecum_client::{Client, SceneSpec, tool_at};

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let addr = args.next().unwrap_or_else(|| "http://127.0.0.1:50051".into());
    let bundles = args.next().unwrap_or_else(|| "out/organ".into());
    let seconds: f64 = args.next().map_or(Ok(3.0), |s| s.parse())?;
    let token = std::env::var("VADEMECUM_TOKEN").ok();
    let client = Client::connect_with_token(addr, token.as_deref()).await?;
    let session = client
        .create_session(SceneSpec::Builtin("organ".into()), &bundles, "palpate example")
        .await?;
    println!(
        "session {} on '{}': effects {:?}",
        session.id(),
        session.info().scene,
        session.info().effects
    );
    let mut tools = session.interact().await?;
    let start = Instant::now();
    let (mut peak, mut i) = (0.0f64, 0u64);
    while start.elapsed().as_secs_f64() < seconds {
        let s = start.elapsed().as_secs_f64();
        // circle over the top of the lobe (z ≈ 0.025 m), 4 mm probe, pressing up to 5 mm
        let p = [
            0.02 * (2.0 * s).cos(),
            0.015 * (2.0 * s).sin(),
            0.030 - 0.005 * (3.0 * s).sin().abs(),
        ];
        tools.send(tool_at(i, p)).await?;
        let r = tools.next().await?.ok_or("the server ended the stream")?;
        let f = r.force_n.unwrap_or_default();
        let mag = (f.x * f.x + f.y * f.y + f.z * f.z).sqrt();
        peak = peak.max(mag);
        if i % 250 == 0 {
            println!(
                "t = {s:5.2} s  tip z = {:.4} m  force = ({:+.3}, {:+.3}, {:+.3}) N",
                p[2], f.x, f.y, f.z
            );
        }
        i += 1;
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    tools.finish();
    let stats = session.close().await?;
    println!(
        "{i} tool states answered; peak force {peak:.3} N; server tick work p99 {:.1} µs",
        stats.tick_work_p99_us
    );
    Ok(())
}
