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
        },
        pulled,
    })
}
