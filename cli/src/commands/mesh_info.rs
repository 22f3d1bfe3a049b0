//! `vademecum mesh info`: counts and quality of a mesh file.

use std::io::Write;
use std::process::ExitCode;

use anyhow::{Context, bail};
use vademecum_engine::mesh::{self, quality};

use crate::cli::MeshInfoArgs;

pub fn run(a: MeshInfoArgs) -> anyhow::Result<ExitCode> {
    if !(a.scale.is_finite() && a.scale > 0.0) {
        bail!("--scale must be a positive number (got {})", a.scale);
    }
    let mut m = mesh::read_unchecked(&a.file).with_context(|| format!("cannot read mesh {}", a.file.display()))?;
    m.scale(a.scale);
    let flipped = m.normalize_orientation();
    let q = quality::summarize(&m);
    let mut out = std::io::stdout().lock();
    if a.json {
        let mut v = serde_json::to_value(&q)?;
        v["file"] = serde_json::Value::String(a.file.display().to_string());
        v["orientation_flipped"] = serde_json::Value::Bool(flipped);
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
        writeln!(out, "{}", a.file.display())?;
        writeln!(out, "  cells        {} {}", q.cells, q.kind.name())?;
        writeln!(out, "  nodes        {} ({} used by cells)", q.nodes, q.used_nodes)?;
        writeln!(
            out,
            "  bounding box [{:.4e}, {:.4e}, {:.4e}] – [{:.4e}, {:.4e}, {:.4e}]",
            q.bbox_min[0], q.bbox_min[1], q.bbox_min[2], q.bbox_max[0], q.bbox_max[1], q.bbox_max[2]
        )?;
        writeln!(
            out,
            "  volume       total {:.6e}, cell min {:.3e}, max {:.3e}",
            q.volume_total, q.volume_min, q.volume_max
        )?;
        writeln!(
            out,
            "  aspect ratio max {:.2}, mean {:.2} (longest / shortest edge)",
            q.aspect_max, q.aspect_mean
        )?;
        if let (Some(min), Some(mean)) = (q.tet_quality_min, q.tet_quality_mean) {
            writeln!(out, "  tet quality  min {min:.3}, mean {mean:.3} (6√2·V/l_rms³; 1 = regular)")?;
        }
        if flipped {
            writeln!(
                out,
                "  orientation  every cell was negatively oriented; re-oriented (a convention difference)"
            )?;
        }
        writeln!(out, "  inverted     {}", q.inverted)?;
        writeln!(out, "  degenerate   {}", q.degenerate)?;
        let regions: Vec<String> = q
            .regions
            .iter()
            .map(|(t, n)| match m.group_names.get(t) {
                Some(name) => format!("{t} \"{name}\": {n}"),
                None => format!("{t}: {n}"),
            })
            .collect();
        writeln!(out, "  regions      {}", regions.join(", "))?;
        if !m.tagged_faces.is_empty() {
            let faces: Vec<String> = m
                .tagged_faces
                .iter()
                .map(|(t, f)| format!("{t}: {} tris, {} quads", f.triangles.len(), f.quads.len()))
                .collect();
            writeln!(out, "  tagged faces {}", faces.join(", "))?;
        }
    }
    Ok(if q.inverted > 0 || q.degenerate > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
