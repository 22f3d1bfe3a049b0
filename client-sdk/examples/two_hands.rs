//! Two hands in one session through the SDK: the built-in organ with a second probe named
//! `left`; the left probe rests on the lobe while the right one (`probe`) presses in beside it,
//! each from a stream of its own, and the left probe's force is printed as the right one goes
//! in — pressing with one moves the tissue under the other.
//!
//! Build the two-probe scene's bundle and run a server first:
//!
//! ```text
//! vademecum scene show organ > two_probes.toml
//! printf '\n[[tools]]\nkind = "probe"\nname = "left"\nradius = 0.004\n' >> two_probes.toml
//! vademecum build two_probes.toml --out out/two_probes && vademecum serve
//! ```
//!
//! then `cargo run -p vademecum-client --example two_hands -- [http://127.0.0.1:50051] [two_probes.toml] [BUNDLE_DIR]`
//! (BUNDLE_DIR: where the bundle sits under the server's bundle root, default `out/two_probes`).

use vademecum_client::{Client, SceneSpec, named, tool_at};

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let addr = args.next().unwrap_or_else(|| "http://127.0.0.1:50051".into());
    let scene = std::fs::read_to_string(args.next().unwrap_or_else(|| "two_probes.toml".into()))?;
    let bundles = args.next().unwrap_or_else(|| "out/two_probes".into());
    let token = std::env::var("VADEMECUM_TOKEN").ok();
    let client = Client::connect_with_token(addr, token.as_deref()).await?;
    let session = client.create_session(SceneSpec::Toml(scene), &bundles, "two hands example").await?;
    let names: Vec<&str> = session.info().tools.iter().map(|t| t.name.as_str()).collect();
    println!("session {} with tools {names:?}", session.id());
    let (mut right, mut left) = (session.interact().await?, session.interact().await?);
    // the left probe rests 1.5 mm into the top of the lobe, 15 mm from its middle
    let at_left = [0.015, 0.0, 0.025 + 0.004 - 0.0015];
    for (seq, depth_mm) in [1.0, 1.5, 2.0, 2.5, 3.0, 3.5].into_iter().enumerate() {
        let seq = seq as u64;
        let at_right = [0.0, 0.0, 0.025 + 0.004 - 1e-3 * depth_mm];
        right.send(named("probe", tool_at(seq, at_right))).await?;
        let r = right.next().await?.ok_or("the server ended the stream")?;
        left.send(named("left", tool_at(seq, at_left))).await?;
        let l = left.next().await?.ok_or("the server ended the stream")?;
        let (fr, fl) = (r.force_n.unwrap_or_default(), l.force_n.unwrap_or_default());
        println!(
            "right probe {depth_mm:.1} mm in: right feels {:+.3} N up, the left one (held still) {:+.3} N up",
            fr.z, fl.z
        );
    }
    right.finish();
    left.finish();
    session.close().await?;
    Ok(())
}
