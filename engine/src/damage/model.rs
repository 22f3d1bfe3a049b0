//! A tearing problem: an organ's mesh and supports, its integration points with their damage
//! laws, and the load (or prescribed displacement) increment each pseudo-time step applies
//! (seed 000 §4.3: "for each ∆t, the algorithm has to translate the force exerted by the
//! user to a value of ∆f").

use std::sync::Arc;

use super::law::{DEFAULT_TORN, PointState};
use super::points::{MaterialPoints, Sym};
use crate::fem::assembly::{DofMap, SymmetricMatrix, SymmetricPattern, add_springs};
use crate::mesh::Mesh;

/// A tearing problem, ready for the full-order reference ([`super::reference`]) or the
/// offline build of the POD–PGD integrator ([`super::vademecum`]).
#[derive(Debug, Clone)]
pub struct TearModel {
    /// The mesh (m).
    pub mesh: Mesh,
    /// Free and constrained degrees of freedom.
    pub dofs: DofMap,
    /// Pattern of the stiffness over the free dofs.
    pub pattern: Arc<SymmetricPattern>,
    /// Integration points with their laws.
    pub points: MaterialPoints,
    /// Springs to the ground (N/m per dof, full length; elastic foundations).
    pub springs: Vec<f64>,
    /// The force increment of a unit step (N, full length).
    pub load: Vec<f64>,
    /// The prescribed displacement increment of a unit step (m, full length; read on
    /// constrained dofs only).
    pub prescribed: Vec<f64>,
    /// The multiplier of `load` and `prescribed` at each step (the schedule).
    pub schedule: Vec<f64>,
    /// Damage past which each cell is torn (not rendered; `∞` for cells that never tear).
    pub torn: Vec<f64>,
}

impl TearModel {
    /// A model with the given points, constraints and unit increments; `schedule` defaults
    /// to nothing (set it before running), every cell torn at [`DEFAULT_TORN`].
    pub fn new(mesh: Mesh, points: MaterialPoints, constrained: &[bool], load: Vec<f64>, prescribed: Vec<f64>) -> Self {
        let dofs = DofMap::new(constrained);
        let pattern = Arc::new(SymmetricPattern::build(&mesh, &dofs));
        let springs = vec![0.0; 3 * mesh.n_nodes()];
        let torn = vec![DEFAULT_TORN; mesh.n_cells()];
        Self {
            mesh,
            dofs,
            pattern,
            points,
            springs,
            load,
            prescribed,
            schedule: Vec::new(),
            torn,
        }
    }

    /// The virgin state of every point.
    pub fn virgin(&self) -> Vec<PointState> {
        vec![PointState::VIRGIN; self.points.len()]
    }

    /// The stiffness `Σ_p w_p B̄ᵀ(g_p C⁰ − [tangent] (h_p/r_p) σ⁰_p⊗σ⁰_p)B̄ + springs`, and
    /// `−K_fc ū` of the prescribed values `ub` (full length, `None`: zero) added to `rhs`.
    /// With `tangent`, `sigma0[p]` is the undamaged stress of the points that loaded.
    pub fn stiffness(&self, state: &[PointState], tangent: Option<&[Sym]>, ub: Option<&[f64]>, rhs: &mut [f64]) -> SymmetricMatrix {
        let mut k = self.points.assemble(
            &self.mesh,
            &self.dofs,
            self.pattern.clone(),
            |p| state[p].g,
            |p| {
                let s = &state[p];
                match tangent {
                    Some(sig) if s.h > 0.0 && s.r > 0.0 => Some((s.h / s.r, sig[p])),
                    _ => None,
                }
            },
            ub,
            rhs,
        );
        add_springs(&mut k, &self.dofs, &self.springs);
        k
    }

    /// The equivalent strain and undamaged stress of every point at `u`.
    pub fn strains(&self, u: &[f64], phi: &mut [f64], sigma0: &mut [Sym]) {
        for p in 0..self.points.len() {
            let (f, s) = self.points.phi(&self.mesh, p, u);
            phi[p] = f;
            sigma0[p] = s;
        }
    }

    /// Updates the damage of every tearable point from `phi` (Alg. 4.1 lines 12–19); returns the
    /// energy dissipated (J) and the largest damage increment.
    pub fn update_damage(&self, state: &mut [PointState], phi: &[f64]) -> (f64, f64) {
        let (mut diss, mut dmax) = (0.0, 0.0f64);
        for &p in &self.points.tearable {
            let law = self.points.law[p].as_ref().expect("tearable points have a law");
            let g0 = state[p].g;
            diss += self.points.weight[p] * state[p].update(law, phi[p]);
            dmax = dmax.max(g0 - state[p].g);
        }
        (diss, dmax)
    }

    /// `g` of the tearable points (a damage snapshot).
    pub fn damage_field(&self, state: &[PointState]) -> Vec<f64> {
        self.points.tearable.iter().map(|&p| state[p].g).collect()
    }

    /// Each cell's damage (weighted mean of its points) and how many cells are torn.
    pub fn cell_damage(&self, state: &[PointState]) -> (Vec<f64>, usize) {
        let mut d = vec![0.0; self.mesh.n_cells()];
        self.points.cell_damage(state, &mut d);
        let torn = d.iter().zip(&self.torn).filter(|(x, t)| x >= t).count();
        (d, torn)
    }

    /// The pull's frame `[n̂, t̂₁, t̂₂]`: `n̂` the unit load's resultant direction, `t̂₁, t̂₂`
    /// completing a right-handed orthonormal frame (`t̂₁` from the axis least aligned with
    /// `n̂`). `None` when the load has no resultant.
    pub fn pull_frame(&self) -> Option<[[f64; 3]; 3]> {
        let (_, _, r) = self.grasp()?;
        let len = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        if !(len > 0.0 && len.is_finite()) {
            return None;
        }
        let n = r.map(|x| x / len);
        let k = (0..3).min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs())).expect("three axes");
        let mut t = [0.0; 3];
        t[k] = 1.0;
        let d = t[0] * n[0] + t[1] * n[1] + t[2] * n[2];
        let t = std::array::from_fn::<f64, 3, _>(|i| t[i] - d * n[i]);
        let tl = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        let t1 = t.map(|x| x / tl);
        let t2 = [
            n[1] * t1[2] - n[2] * t1[1],
            n[2] * t1[0] - n[0] * t1[2],
            n[0] * t1[1] - n[1] * t1[0],
        ];
        Some([n, t1, t2])
    }

    /// The unit force increment of pull pattern `p` (N, full length): `p = 0` the scene's
    /// load; `p = 1, 2` the same nodes pulled across it, each node's force along `n̂` turned to
    /// `t̂_p` (`f_a → (f_a·n̂) t̂_p`, the same resultant magnitude). Zero when there is no
    /// frame.
    pub fn pull_load(&self, p: usize) -> Vec<f64> {
        if p == 0 {
            return self.load.clone();
        }
        let mut out = vec![0.0; self.load.len()];
        if let Some(frame) = self.pull_frame() {
            let (n, t) = (frame[0], frame[p]);
            for (f, o) in self.load.chunks_exact(3).zip(out.chunks_exact_mut(3)) {
                let along = f[0] * n[0] + f[1] * n[1] + f[2] * n[2];
                for k in 0..3 {
                    o[k] = along * t[k];
                }
            }
        }
        out
    }

    /// The grasp of a session (`crate::pipeline::tearing`): the loaded nodes, their centre and
    /// the unit load's resultant (N per unit step). `None` when nothing is loaded.
    pub fn grasp(&self) -> Option<(Vec<usize>, [f64; 3], [f64; 3])> {
        let mut nodes: Vec<usize> = (0..self.load.len()).filter(|&d| self.load[d] != 0.0).map(|d| d / 3).collect();
        nodes.dedup();
        if nodes.is_empty() {
            return None;
        }
        let (mut r, mut centre) = ([0.0; 3], [0.0; 3]);
        for (d, f) in self.load.iter().enumerate() {
            r[d % 3] += f;
        }
        for &n in &nodes {
            for k in 0..3 {
                centre[k] += self.mesh.nodes[n][k] / nodes.len() as f64;
            }
        }
        Some((nodes, centre, r))
    }
}
