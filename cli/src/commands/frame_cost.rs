//! What a viewer's frame costs a PGD vademecum: the surface displacement field of real
//! contacts, evaluated from the modes (measured by `vademecum study` at every prefix of the
//! modes and storage, and by `vademecum build` for the bundle it writes).

use anyhow::bail;
use vademecum_engine::pgd::Vademecum;
use vademecum_engine::pgd::vademecum::NodeMajorField;

use super::bench_pgd::{Rng, stat, time_n};

/// What a frame evaluates: the surface nodes, and the mode coefficients (f32, every mode) of
/// 64 real contacts — a unit force at random points of the loadable surface.
pub(super) struct Frames {
    /// The surface nodes a frame draws.
    pub(super) nodes: Vec<usize>,
    /// Each contact's mode coefficients.
    pub(super) coeffs: Vec<Vec<f32>>,
}

impl Frames {
    /// The frames of vademecum `v` on the boundary `surface`.
    pub(super) fn of(v: &Vademecum, surface: &[[usize; 3]]) -> anyhow::Result<Self> {
        let mut nodes: Vec<usize> = surface.iter().flatten().copied().collect();
        nodes.sort_unstable();
        nodes.dedup();
        let tris: Vec<[usize; 3]> = surface.iter().copied().filter(|t| t.iter().all(|&n| v.is_loadable(n))).collect();
        if tris.is_empty() {
            bail!("the bundle has no surface triangle whose three nodes are loadable");
        }
        let mut rng = Rng(0x005E_ED0F_57D4);
        let mut full = vec![0.0; v.modes()];
        let coeffs = (0..64)
            .map(|_| {
                let tri = tris[(rng.next_u64() % tris.len() as u64) as usize];
                let (u, w) = (rng.unit(), rng.unit());
                let (u, w) = if u + w > 1.0 { (1.0 - u, 1.0 - w) } else { (u, w) };
                v.coefficients(tri, [1.0 - u - w, u, w], [0.0, 0.0, -1.0], &mut full);
                full.iter().map(|&c| c as f32).collect()
            })
            .collect();
        Ok(Self { nodes, coeffs })
    }

    /// The p50 time (µs) of one frame's surface field with the first `modes` modes of `v`
    /// stored node-major in f32 (what a session's frames evaluate), over `repeat` frames.
    pub(super) fn p50_us(&self, v: &Vademecum, modes: usize, repeat: usize) -> f64 {
        self.timing(v, modes, repeat).0
    }

    /// [`Frames::p50_us`] with the p99 and a null loop's p50 timed in the same run (µs).
    pub(super) fn timing(&self, v: &Vademecum, modes: usize, repeat: usize) -> (f64, f64, f64) {
        let field = NodeMajorField::from_mode_major(v.f_raw(), v.n_nodes(), modes, &self.nodes);
        let mut out = vec![0.0f32; 3 * self.nodes.len()];
        let mut i = 0;
        let times = time_n(repeat, || {
            i = (i + 1) % self.coeffs.len();
            field.eval(&self.coeffs[i][..modes], &mut out);
            out[0] as f64
        });
        let (frame, null) = (stat("frame", times), stat("null", time_n(repeat, || 0.0)));
        (frame.p50_us, frame.p99_us, null.p50_us)
    }
}
