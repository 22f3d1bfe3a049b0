//! The scalpel cutting as it moves (seed 000 §3.4): the cut criterion on the blade force, the
//! surface the blade sweeps while it cuts, the cells it crosses, and the reduced model bordered
//! with their nodes.
//!
//! Each [`OnlineCut::step`] takes the blade's state and the force the tissue exerts on it. While
//! `|F∥|` exceeds the scalpel's `cut_force` the blade is cutting: its positions are recorded
//! (one every 5 % of a cell — the tolerance with which a cell counts as crossed — so that the
//! swept surface stays a few dozen facets per cell however slowly the blade moves), the surface swept since the last recorded position is added to the
//! cut, and every cell the cut has now crossed entirely is cut — its nodes cracked and the
//! reduced model's factor bordered ([`ReducedCut::cut`]). Below the threshold the blade only
//! rubs (friction): the stroke ends, and the next cut starts a new one. A blade whose edge lies
//! in an existing cut is reported (`in_cut`) and cuts nothing new there.
//!
//! This is the work a session does beside its tick thread: it allocates (the cut surface, new
//! rows of the factor) and enriching a node costs milliseconds (`BENCHMARKS.md`, "Cutting by
//! XFEM"); the tick itself only reads the model's contact compliance.

use super::blade::{Blade, ForceSplit};
use super::enrichment::{Enrichment, XfemParams};
use super::reduced::{ReducedCut, ReducedError};
use crate::geometry::cut::Cut;
use crate::mesh::Mesh;

/// The distance from `p` to `q`.
fn moved(p: [f64; 3], q: [f64; 3]) -> f64 {
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

/// What one step did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CutStep {
    /// The force on the blade, split along it.
    pub split: ForceSplit,
    /// Whether the criterion held (`|F∥| > cut_force`).
    pub cutting: bool,
    /// Cells cut by this step.
    pub new_cells: usize,
    /// Nodes cracked by this step.
    pub new_nodes: usize,
    /// Whether the blade's edge lies in a cut already made.
    pub in_cut: bool,
}

/// A scalpel cutting an organ through its reduced model.
#[derive(Debug, Clone)]
pub struct OnlineCut {
    model: ReducedCut,
    cut_force: f64,
    params: XfemParams,
    /// The positions recorded in the current stroke.
    stroke: Vec<([f64; 3], [f64; 3])>,
    /// Everything cut so far.
    cut: Option<Cut>,
    /// Smallest blade displacement recorded (m): the coverage tolerance of a typical cell, so
    /// that the recorded surface never lags the blade by more than a cell counts as cut with.
    min_step: f64,
    /// Centre and size of every cell, to find the cells near a new piece of cut.
    cells: Vec<([f64; 3], f64)>,
}

/// A scalpel's threshold that is not a positive force.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("the scalpel's cut_force must be a positive force (N), not {0}")]
pub struct BadCutForce(pub f64);

impl OnlineCut {
    /// A scalpel with threshold `cut_force` (N, positive) on `model`, the reduced model of
    /// `mesh`.
    pub fn new(mesh: &Mesh, model: ReducedCut, cut_force: f64, params: &XfemParams) -> Result<Self, BadCutForce> {
        if !(cut_force.is_finite() && cut_force > 0.0) {
            return Err(BadCutForce(cut_force));
        }
        let npc = mesh.kind.nodes_per_cell();
        let mut x = vec![[0.0; 3]; npc];
        let cells: Vec<([f64; 3], f64)> = (0..mesh.n_cells())
            .map(|c| {
                mesh.cell_coords(c, &mut x);
                let mut centre = [0.0; 3];
                for p in &x {
                    for i in 0..3 {
                        centre[i] += p[i] / npc as f64;
                    }
                }
                (centre, super::subcell::cell_size(&x))
            })
            .collect();
        let typical = cells.iter().map(|c| c.1).sum::<f64>() / cells.len().max(1) as f64;
        Ok(Self {
            model,
            cut_force,
            params: *params,
            stroke: Vec::new(),
            cut: None,
            min_step: params.coverage * typical,
            cells,
        })
    }

    /// The reduced model, with the cut so far.
    pub fn model(&self) -> &ReducedCut {
        &self.model
    }

    /// The reduced model, mutable (the tick's contact compliance uses its workspace).
    pub fn model_mut(&mut self) -> &mut ReducedCut {
        &mut self.model
    }

    /// The surface cut so far, if any.
    pub fn cut(&self) -> Option<&Cut> {
        self.cut.as_ref()
    }

    /// One blade state with the force the tissue exerts on it (module docs). A failed
    /// enrichment (a piece cut loose, [`ReducedError::Singular`]) leaves the model at its
    /// previous cut.
    pub fn step(&mut self, mesh: &Mesh, blade: &Blade, force: [f64; 3]) -> Result<CutStep, ReducedError> {
        self.step_in_contact(mesh, blade, force, [0.0; 3])
    }

    /// [`step`](Self::step) for a blade pressed into the tissue, which gave way by `pushed`
    /// (m) at the contact: a stroke starts where the blade met the tissue, at the edge moved
    /// back by `pushed` (in the reference frame the tissue ahead of the blade was pushed, not
    /// cut, until the criterion held), and goes on with the blade's own positions.
    pub fn step_in_contact(&mut self, mesh: &Mesh, blade: &Blade, force: [f64; 3], pushed: [f64; 3]) -> Result<CutStep, ReducedError> {
        let split = blade.split(force);
        let mid = [
            0.5 * (blade.a[0] + blade.b[0]),
            0.5 * (blade.a[1] + blade.b[1]),
            0.5 * (blade.a[2] + blade.b[2]),
        ];
        let in_cut = self.cut.as_ref().is_some_and(|c| c.distance(mid) <= 1e-3 * self.min_step);
        let step = CutStep {
            split,
            cutting: split.cuts(self.cut_force),
            in_cut,
            ..CutStep::default()
        };
        if !step.cutting {
            self.stroke.clear();
            return Ok(step);
        }
        let here = (blade.a, blade.b);
        let Some(&last) = self.stroke.last() else {
            let back = |p: [f64; 3]| std::array::from_fn(|k| p[k] - pushed[k]);
            let entry = (back(blade.a), back(blade.b));
            self.stroke.push(entry);
            return self.sweep(mesh, entry, here, step);
        };
        self.sweep(mesh, last, here, step)
    }

    /// Adds the surface the edge swept from `last` to `here` to the cut and cuts the cells it
    /// has now crossed entirely.
    fn sweep(
        &mut self,
        mesh: &Mesh,
        last: ([f64; 3], [f64; 3]),
        here: ([f64; 3], [f64; 3]),
        mut step: CutStep,
    ) -> Result<CutStep, ReducedError> {
        if moved(last.0, here.0).max(moved(last.1, here.1)) < self.min_step {
            return Ok(step);
        }
        self.stroke.push(here);
        let Ok(piece) = Cut::swept(&[last, here]) else {
            return Ok(step); // the blade slid along itself: it swept no area
        };
        let total = match self.cut.take() {
            Some(c) => c.union(&piece).unwrap_or(c),
            None => piece.clone(),
        };
        // the cells near the new piece, tested against everything cut so far
        let near: Vec<usize> = self
            .cells
            .iter()
            .enumerate()
            .filter(|(_, (centre, size))| piece.distance(*centre) <= *size)
            .map(|(c, _)| c)
            .collect();
        let cells = Enrichment::cut_cells_among(mesh, &total, &self.params, near)?;
        self.cut = Some(total);
        let before = self.model.enrichment().cut_cells.len();
        let up = self.model.cut(mesh, &cells)?;
        step.new_cells = self.model.enrichment().cut_cells.len() - before;
        step.new_nodes = up.new_nodes.len();
        Ok(step)
    }
}
