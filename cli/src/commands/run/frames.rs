//! The frames of a headless run: each frame of the deterministic session's log written as one
//! surface `.vtu` per organ under `frames/` (the displacement as point data; with tearing the
//! damage as cell data, torn cells left out), the co-rotational cut's visual mesh and partial
//! cut when the session has them, and a `.pvd` series of each.

use std::path::{Path, PathBuf};

use vademecum_engine::mesh::vtk::{self, Field};
use vademecum_server::session::{Frame, SurfaceGeometry};

/// Writes a run's frames as they come, and their series at the end.
pub(super) struct FrameRecorder {
    frames_dir: PathBuf,
    names: Vec<String>,
    positions: Vec<Vec<[f64; 3]>>,
    triangles: Vec<Vec<usize>>,
    /// Each organ's series: (time, file under the recording folder).
    pub steps: Vec<Vec<(f64, String)>>,
    /// The damage at the last frame: largest, torn cells, energy dissipated (J).
    pub last_damage: Option<(f64, usize, f64)>,
    /// The visual mesh's series (co-rotational cutting), and its geometry at its revision.
    pub visual_steps: Vec<(f64, String)>,
    visual_geometry: Option<(u64, Vec<[f64; 3]>, Vec<usize>)>,
    /// The partial cut's series, and the frames that showed one.
    pub partial_steps: Vec<(f64, String)>,
    pub partial_frames: u64,
}

/// `f32` coordinates, three a point, as points.
fn points(xyz: &[f32]) -> Vec<[f64; 3]> {
    xyz.chunks_exact(3).map(|c| [c[0] as f64, c[1] as f64, c[2] as f64]).collect()
}

fn widen(x: &[f32]) -> Vec<f64> {
    x.iter().map(|&x| x as f64).collect()
}

/// Writes a surface with its displacement `u` (three a point) to `dir/file`.
fn write_displaced(
    dir: &Path,
    file: &str,
    positions: &[[f64; 3]],
    triangles: &[usize],
    u: &[f64],
    cells: &[Field<'_>],
) -> anyhow::Result<()> {
    let point_data = [Field {
        name: "displacement",
        components: 3,
        values: u,
    }];
    vtk::write_surface_vtu(&dir.join(file), positions, triangles, &point_data, cells)?;
    Ok(())
}

impl FrameRecorder {
    /// A recorder of the surfaces of `geometry` into `frames_dir`.
    pub fn new(geometry: &SurfaceGeometry, frames_dir: PathBuf) -> Self {
        Self {
            frames_dir,
            names: geometry.organs.iter().map(|o| o.name.clone()).collect(),
            positions: geometry.organs.iter().map(|o| points(&o.positions_m)).collect(),
            triangles: geometry
                .organs
                .iter()
                .map(|o| o.triangles.iter().map(|&i| i as usize).collect())
                .collect(),
            steps: vec![Vec::new(); geometry.organs.len()],
            last_damage: None,
            visual_steps: Vec::new(),
            visual_geometry: None,
            partial_steps: Vec::new(),
            partial_frames: 0,
        }
    }

    /// Writes `frame`'s files.
    pub fn write(&mut self, frame: &Frame) -> anyhow::Result<()> {
        self.write_organs(frame)?;
        self.write_visual(frame)?;
        self.write_partial(frame)
    }

    fn write_organs(&mut self, frame: &Frame) -> anyhow::Result<()> {
        for k in 0..self.names.len() {
            let file = format!("{}_{:05}.vtu", self.names[k], frame.seq);
            let u = widen(&frame.displacements_m[k]);
            let (positions, triangles) = (&self.positions[k], &self.triangles[k]);
            match &frame.damage[k] {
                None => write_displaced(&self.frames_dir, &file, positions, triangles, &u, &[])?,
                Some(d) => {
                    // torn cells are not drawn: their surface triangles are left out
                    let kept: Vec<usize> = (0..d.triangle_damage.len()).filter(|&t| d.triangle_damage[t] < d.torn).collect();
                    let tris: Vec<usize> = kept.iter().flat_map(|&t| triangles[3 * t..3 * t + 3].iter().copied()).collect();
                    let damage: Vec<f64> = kept.iter().map(|&t| f64::from(d.triangle_damage[t])).collect();
                    let cells = [Field {
                        name: "damage",
                        components: 1,
                        values: &damage,
                    }];
                    write_displaced(&self.frames_dir, &file, positions, &tris, &u, &cells)?;
                    self.last_damage = Some((
                        d.cell_damage.iter().copied().fold(0.0f32, f32::max).into(),
                        d.cell_damage.iter().filter(|&&x| x >= d.torn).count(),
                        d.dissipated_j,
                    ));
                }
            }
            self.steps[k].push((frame.time_s, format!("frames/{file}")));
        }
        Ok(())
    }

    /// The visual mesh of a co-rotational cut, its geometry read again at each new revision.
    fn write_visual(&mut self, frame: &Frame) -> anyhow::Result<()> {
        let Some(v) = &frame.visual else { return Ok(()) };
        if self.visual_geometry.as_ref().is_none_or(|g| g.0 != v.revision) {
            self.visual_geometry = Some((
                v.revision,
                points(&v.positions_m),
                v.triangles.iter().map(|&i| i as usize).collect(),
            ));
        }
        if let Some((_, positions, tris)) = &self.visual_geometry {
            let file = format!("{}_visual_{:05}.vtu", self.names[v.organ], frame.seq);
            write_displaced(&self.frames_dir, &file, positions, tris, &widen(&v.displacements_m), &[])?;
            self.visual_steps.push((frame.time_s, format!("frames/{file}")));
        }
        Ok(())
    }

    /// The partial cut: from its first appearance on, one file per frame (empty when the
    /// blade is in no cell it has not cut, so that ParaView does not keep the last one).
    fn write_partial(&mut self, frame: &Frame) -> anyhow::Result<()> {
        if frame.partial.is_none() && self.partial_steps.is_empty() {
            return Ok(());
        }
        let name = &self.names[frame.partial.as_ref().map_or(0, |p| p.organ)];
        let file = format!("{name}_partial_{:05}.vtu", frame.seq);
        let (positions, u) = match &frame.partial {
            Some(p) => {
                self.partial_frames += 1;
                (points(&p.positions_m), widen(&p.displacements_m))
            }
            None => (Vec::new(), Vec::new()),
        };
        let tris: Vec<usize> = (0..positions.len()).collect();
        write_displaced(&self.frames_dir, &file, &positions, &tris, &u, &[])?;
        self.partial_steps.push((frame.time_s, format!("frames/{file}")));
        Ok(())
    }

    /// Writes each organ's `.pvd` series into `record`.
    pub fn write_series(&self, record: &Path) -> anyhow::Result<()> {
        for (name, steps) in self.names.iter().zip(&self.steps) {
            vtk::write_pvd(&record.join(format!("{name}.pvd")), steps)?;
        }
        Ok(())
    }

    /// Writes the visual mesh's and the partial cut's series of the first organ into
    /// `record`, when there are: their paths.
    pub fn write_cut_series(&self, record: &Path) -> anyhow::Result<(Option<PathBuf>, Option<PathBuf>)> {
        let series = |what: &str, steps: &[(f64, String)]| -> anyhow::Result<Option<PathBuf>> {
            if steps.is_empty() {
                return Ok(None);
            }
            let path = record.join(format!("{}_{what}.pvd", self.names[0]));
            vtk::write_pvd(&path, steps)?;
            Ok(Some(path))
        };
        Ok((series("visual", &self.visual_steps)?, series("partial", &self.partial_steps)?))
    }
}
