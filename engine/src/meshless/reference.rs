//! Seed 004's verification problems, built for the meshless solver (used by the tests and by
//! `vademecum bench efg`).

use super::efg::{EfgProblem, EfgSolution};
use super::grid::box_grid;
use super::mls::NodeCloud;
use crate::material::LinearElastic;
use crate::material::hyperelastic::Hyperelastic;

/// Seed 004 Table 3.2 (Abaqus, plane strain, 1,681 nodes) at 20 % stretch: strain energy (J per
/// metre of thickness) and reaction (N per metre).
pub const TABLE_3_2: (f64, f64) = (0.847, 77.64);

/// Influence radius of every node, in node spacings.
pub const SUPPORT: f64 = 2.2;

/// A pulled-block problem and which of its prescribed entries carry the pulling reaction.
#[derive(Debug, Clone)]
pub struct Pulled {
    /// The problem.
    pub problem: EfgProblem,
    /// For each prescribed entry: whether it is the pulled face's component along the pull.
    pub pulled: Vec<bool>,
}

impl Pulled {
    /// The reaction on the pulled face along the pull.
    pub fn force(&self, s: &EfgSolution) -> f64 {
        self.pulled.iter().zip(&s.reactions).filter(|(p, _)| **p).map(|(_, r)| r).sum()
    }
}

/// Seed 004 §3.3: a 0.1 m square of Abaqus neo-Hookean material (E = 3000 Pa, ν = `poisson`),
/// plane strain, `n × n` regularly spaced nodes and `(n−1)²` background cells integrated with
/// `q × q` points each (the seed uses `q = 1`; one point per cell leaves near-zero-energy modes
/// that make the relaxation need ~n² steps, `q = 2` removes them: `BENCHMARKS.md`); edge
/// x = 0 clamped, edge x = 0.1 m pulled by `stretch × 0.1` m in x with its y motion fixed.
pub fn square(n: usize, stretch: f64, poisson: f64, q: usize) -> Result<Pulled, crate::material::MaterialError> {
    let q = q.max(1);
    let n = n.max(2);
    let h = 0.1 / (n - 1) as f64;
    let pts: Vec<[f64; 3]> = (0..n * n).map(|q| [(q % n) as f64 * h, (q / n) as f64 * h, 0.0]).collect();
    let mut prescribed = Vec::new();
    let mut pulled = Vec::new();
    for (i, p) in pts.iter().enumerate() {
        let on = |x: f64| (p[0] - x).abs() < 1e-12;
        if on(0.0) || on(0.1) {
            let ux = if on(0.1) { 0.1 * stretch } else { 0.0 };
            prescribed.extend([(i, 0, ux), (i, 1, 0.0)]);
            pulled.extend([on(0.1), false]);
        }
    }
    Ok(Pulled {
        problem: EfgProblem {
            cloud: NodeCloud::new(2, pts.clone(), vec![SUPPORT * h; pts.len()]),
            points: box_grid(2, [0.0; 3], [0.1, 0.1, 0.0], [q * (n - 1), q * (n - 1), 1], |_| true),
            law: Hyperelastic::neo_hookean(&LinearElastic::new(3000.0, poisson)?),
            prescribed,
            loads: Vec::new(),
        },
        pulled,
    })
}

/// Seed 004 Table 5.2 (Abaqus, 17,576 nodes) at 20 % stretch: strain energy (J) and reaction (N).
pub const TABLE_5_2: (f64, f64) = (0.06477, 6.109);

/// Seed 004 §5: the 0.1 m cube of the same material, `n³` nodes, `(n−1)³` cells with `q³`
/// points each; face y = 0 clamped, face y = 0.1 m pulled `stretch × 0.1` m in y with its x
/// and z motion fixed.
pub fn cube(n: usize, stretch: f64, poisson: f64, q: usize) -> Result<Pulled, crate::material::MaterialError> {
    let (n, q) = (n.max(2), q.max(1));
    let h = 0.1 / (n - 1) as f64;
    let pts: Vec<[f64; 3]> = (0..n * n * n)
        .map(|i| [(i % n) as f64 * h, ((i / n) % n) as f64 * h, (i / (n * n)) as f64 * h])
        .collect();
    let mut prescribed = Vec::new();
    let mut pulled = Vec::new();
    for (i, p) in pts.iter().enumerate() {
        let on = |y: f64| (p[1] - y).abs() < 1e-12;
        if on(0.0) || on(0.1) {
            let uy = if on(0.1) { 0.1 * stretch } else { 0.0 };
            prescribed.extend([(i, 0, 0.0), (i, 1, uy), (i, 2, 0.0)]);
            pulled.extend([false, on(0.1), false]);
        }
    }
    let c = q * (n - 1);
    Ok(Pulled {
        problem: EfgProblem {
            cloud: NodeCloud::new(3, pts.clone(), vec![SUPPORT * h; pts.len()]),
            points: box_grid(3, [0.0; 3], [0.1; 3], [c, c, c], |_| true),
            law: Hyperelastic::neo_hookean(&LinearElastic::new(3000.0, poisson)?),
            prescribed,
            loads: Vec::new(),
        },
        pulled,
    })
}

/// Seed 004 Fig. 4.8: the cutting path A–B–C–D, in the stretched configuration (m).
pub const FIG_4_8: [[f64; 2]; 4] = [[0.05, 0.09], [0.059, 0.082], [0.066, 0.075], [0.058, 0.052]];

/// Seed 004 Table 4.2 (Abaqus, pre-cut square, 7,813 nodes): strain energy (J per metre) and
/// reaction (N per metre) at the end of cutting.
pub const TABLE_4_2: (f64, f64) = (0.507, 46.91);

/// How the seed 004 §4.3 cutting experiment is set up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutSetup {
    /// Nodes per side of the regular grid.
    pub nodes: usize,
    /// Integration points per cell and axis (1 as in the seed, or 2).
    pub integration: usize,
    /// Start the cut from outside the body, extending A–B back through A beyond the top edge
    /// (A lies 0.05 mm below that edge); otherwise at A, leaving that thin ligament, which
    /// nodes on the edge still bridge.
    pub from_surface: bool,
    /// Add nodes at half the spacing within two spacings of the cut (seed Fig. 4.12), with
    /// integration cells refined there likewise.
    pub refined: bool,
}

impl Default for CutSetup {
    fn default() -> Self {
        Self {
            nodes: 41,
            integration: 2,
            from_surface: true,
            refined: false,
        }
    }
}

/// One stage of progressive cutting: the state relaxed after the cut reached `to`.
#[derive(Debug, Clone)]
pub struct CutStage {
    /// The end of the cut at this stage, stretched configuration (m).
    pub to: [f64; 2],
    /// Nodes split and inserted by this stage.
    pub nodes: super::cutting::CutNodes,
    /// The relaxed state.
    pub solution: EfgSolution,
    /// Reaction on the pulled edge (N per metre).
    pub force: f64,
    /// Nodes in the cloud.
    pub cloud_size: usize,
}

/// The seed 004 §4.3 experiment: the stretched square, then the cut A–B–C–D in three stages.
#[derive(Debug, Clone)]
pub struct CutStudy {
    /// The uncut, stretched state.
    pub uncut: EfgSolution,
    /// Its reaction (N per metre).
    pub uncut_force: f64,
    /// The path in the reference configuration (the first point on the top edge when the cut
    /// starts from the surface).
    pub reference_path: Vec<[f64; 2]>,
    /// The relaxed states after A–B, B–C and C–D (the last is the end of cutting).
    pub stages: Vec<CutStage>,
    /// The cloud at the end of cutting.
    pub cloud: NodeCloud,
}

/// Seed 004 §4.3: stretch the square by 20 %, then cut along [`FIG_4_8`] progressively
/// (A–B, B–C along nearly the same direction, C–D turning), relaxing after each cut. The path
/// is given on the stretched body: each point is traced back to the material point now there
/// ([`super::efg::pull_back`]), so the cut is a material line and the result compares with the
/// reference's pre-cut square stretched by the same amount. `progress(stage, step, error)`.
pub fn square_cut(
    setup: &CutSetup,
    params: &super::efg::AdrParams,
    mut progress: impl FnMut(usize, usize, f64),
) -> Result<CutStudy, super::efg::EfgError> {
    use super::cutting::cut_cloud;
    use super::efg::{EfgError, pull_back, relax, solve};
    use crate::geometry::cut::Cut;
    let pulled = square(setup.nodes, 0.2, 0.49, setup.integration).map_err(|e| EfgError::Diverged {
        step: 0,
        why: e.to_string(),
    })?;
    let uncut = solve(&pulled.problem, params, |s, e| progress(0, s, e))?;
    let uncut_force = pulled.force(&uncut);
    let cloud0 = &pulled.problem.cloud;
    let mut path = Vec::with_capacity(5);
    for p in FIG_4_8 {
        let x = pull_back(cloud0, &uncut.field, [p[0], p[1], 0.0]).ok_or(EfgError::Placement { x: p[0], y: p[1], z: 0.0 })?;
        path.push([x[0], x[1]]);
    }
    let h = 0.1 / (setup.nodes.max(2) - 1) as f64;
    if setup.from_surface {
        // one spacing beyond the edge: no line inside the body passes round the start
        let (a, b) = (path[0], path[1]);
        let t = (0.1 + h - a[1]) / (a[1] - b[1]);
        path.insert(0, [a[0] + t * (a[0] - b[0]), 0.1 + h]);
    }
    let inside = |x: [f64; 3]| (0.0..=0.1).contains(&x[0]) && (0.0..=0.1).contains(&x[1]);
    let mut problem = pulled.problem.clone();
    let mut field = uncut.field.clone();
    let mut spacing = h;
    if setup.refined {
        let whole = Cut::path(&path)?;
        let band = 2.0 * h;
        let fine = 0.5 * h;
        let mut points = cloud0.points().to_vec();
        let mut radius = cloud0.radii().to_vec();
        let m = (0.1 / fine).round() as usize;
        for j in 0..=m {
            for i in 0..=m {
                let x = [i as f64 * fine, j as f64 * fine, 0.0];
                if (i % 2 == 1 || j % 2 == 1) && whole.distance(x) < band {
                    let (u, _) = super::efg::deformation_at(cloud0, &uncut.field, x)?;
                    points.push(x);
                    radius.push(SUPPORT * fine);
                    field.extend_from_slice(&u[..2]);
                }
            }
        }
        problem.cloud = NodeCloud::new(2, points, radius);
        let c = setup.nodes - 1;
        problem.points = super::grid::refined_grid(2, [0.0; 3], [0.1, 0.1, 0.0], [c, c, 1], setup.integration, |x| {
            whole.distance(x) < band + h
        });
        spacing = fine;
    }
    // the stages end at B, C and D
    let first = if setup.from_surface { 2 } else { 1 };
    let mut stages = Vec::new();
    for (k, end) in (first..path.len()).enumerate() {
        let cut = Cut::path(&path[..=end])?;
        let (cloud, start, nodes) = cut_cloud(&problem.cloud, cut, &field, spacing, inside)?;
        problem.cloud = cloud;
        let solution = relax(&problem, params, &start, |s, e| progress(k + 1, s, e))?;
        field = solution.field.clone();
        stages.push(CutStage {
            to: FIG_4_8[end + 1 - first],
            nodes,
            force: pulled.force(&solution),
            cloud_size: problem.cloud.len(),
            solution,
        });
    }
    Ok(CutStudy {
        uncut,
        uncut_force,
        reference_path: path,
        stages,
        cloud: problem.cloud,
    })
}
