//! A frame recorder: watch a session's displacement frames and write them as a ParaView
//! time series (`<organ>.pvd` + one `.vtu` surface per frame).
//!
//! Writing a frame takes longer than a frame period on a slow disk, so the recorder uses the
//! acknowledged stream (`watch_acked`): it is sent the latest frame each time it is ready for
//! one, never a backlog of old ones.
//!
//! `cargo run -p vademecum-client --example record_frames -- SESSION_ID [http://127.0.0.1:50051] [OUT_DIR] [SECONDS] [RATE_HZ]`

use std::fmt::Write as _;
use std::path::Path;
use std::time::{Duration, Instant};

use vademecum_client::{Client, f32s};

/// Writes one triangulated surface with a point vector field as an ASCII `.vtu`.
fn write_vtu(path: &Path, positions: &[f32], triangles: &[u32], displacement: &[f32]) -> std::io::Result<()> {
    let (n, t) = (positions.len() / 3, triangles.len() / 3);
    let mut s = String::new();
    let _ = write!(
        s,
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{t}\">\n<Points>\n<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">\n"
    );
    for p in positions.chunks_exact(3) {
        let _ = writeln!(s, "{} {} {}", p[0], p[1], p[2]);
    }
    s.push_str("</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for c in triangles.chunks_exact(3) {
        let _ = writeln!(s, "{} {} {}", c[0], c[1], c[2]);
    }
    s.push_str("</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    for i in 0..t {
        let _ = write!(s, "{} ", 3 * (i + 1));
    }
    s.push_str("\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
    s.push_str(&"5 ".repeat(t));
    s.push_str("\n</DataArray>\n</Cells>\n<PointData Vectors=\"displacement\">\n<DataArray type=\"Float32\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">\n");
    for u in displacement.chunks_exact(3) {
        let _ = writeln!(s, "{} {} {}", u[0], u[1], u[2]);
    }
    s.push_str("</DataArray>\n</PointData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
    std::fs::write(path, s)
}

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let id = args
        .next()
        .ok_or("usage: record_frames SESSION_ID [ADDR] [OUT_DIR] [SECONDS] [RATE_HZ]")?;
    let addr = args.next().unwrap_or_else(|| "http://127.0.0.1:50051".into());
    let out = std::path::PathBuf::from(args.next().unwrap_or_else(|| "frames".into()));
    let seconds: f64 = args.next().map_or(Ok(5.0), |s| s.parse())?;
    let rate: f64 = args.next().map_or(Ok(30.0), |s| s.parse())?;
    let token = std::env::var("VADEMECUM_TOKEN").ok();
    let client = Client::connect_with_token(addr, token.as_deref()).await?;
    let session = client.session(&id).await?;
    let mut frames = session.watch_acked(rate, 0).await?;
    let first = frames.next().await?.ok_or("the server ended the stream")?;
    let geometry = first.geometry.ok_or("the first frame has no geometry")?;
    std::fs::create_dir_all(&out)?;
    let mut steps: Vec<String> = vec![String::new(); geometry.organs.len()];
    let until = Instant::now() + Duration::from_secs_f64(seconds);
    let mut count = 0;
    while Instant::now() < until {
        let Ok(Some(f)) = tokio::time::timeout(until - Instant::now(), frames.next())
            .await
            .unwrap_or(Ok(None))
        else {
            break;
        };
        if f.heartbeat {
            // nothing new since the last frame
            continue;
        }
        for (k, (mesh, d)) in geometry.organs.iter().zip(&f.organs).enumerate() {
            let file = format!("{}_{:06}.vtu", mesh.organ, f.seq);
            let tris: Vec<u32> = mesh
                .triangles
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            write_vtu(&out.join(&file), &f32s(&mesh.positions), &tris, &f32s(&d.displacements))?;
            let _ = writeln!(steps[k], "<DataSet timestep=\"{}\" part=\"0\" file=\"{file}\"/>", f.time_s);
        }
        count += 1;
    }
    for (mesh, s) in geometry.organs.iter().zip(&steps) {
        std::fs::write(
            out.join(format!("{}.pvd", mesh.organ)),
            format!("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"1.0\">\n<Collection>\n{s}</Collection>\n</VTKFile>\n"),
        )?;
    }
    println!("{count} frames written to {}", out.display());
    Ok(())
}
